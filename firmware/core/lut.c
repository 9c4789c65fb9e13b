/* Uniform-grid lookup: evaluation (per tick) and grid description. */
#include "lut.h"

lut_status_t lut_init(lut_t *lut, const int32_t *y_q16, uint16_t n, int32_t x0_q16, int32_t step_q16)
{
    if (n < 2)
        return LUT_ERR_SIZE;
    /* Power of two, 1..2^24 raw units: evaluation is then a shift, never a divide. */
    if (step_q16 <= 0 || step_q16 > (1 << 24) || (step_q16 & (step_q16 - 1)) != 0)
        return LUT_ERR_STEP;
    int64_t x_last = (int64_t)x0_q16 + (int64_t)(n - 1) * step_q16;
    if (x_last > INT32_MAX)
        return LUT_ERR_RANGE;
    uint8_t s = 0;
    while ((1 << s) != step_q16)
        s++;
    lut->y_q16 = y_q16;
    lut->x0_q16 = x0_q16;
    lut->x_last_q16 = (int32_t)x_last;
    lut->n = n;
    lut->step_log2 = s;
    return LUT_OK;
}

int32_t lut_eval(const lut_t *lut, int32_t x_q16)
{
    if (x_q16 <= lut->x0_q16)
        return lut->y_q16[0];
    if (x_q16 >= lut->x_last_q16)
        return lut->y_q16[lut->n - 1];
    /* 0 < off < (n-1) * step <= 2^31: fits uint32 even when x0 is negative. */
    uint32_t off = (uint32_t)x_q16 - (uint32_t)lut->x0_q16;
    uint32_t i = off >> lut->step_log2;
    uint32_t frac = off & ((1u << lut->step_log2) - 1u);
    int32_t y0 = lut->y_q16[i];
    int64_t dy = (int64_t)lut->y_q16[i + 1] - y0;
    /* Round half up: floor((dy * frac + step/2) / step), arithmetic shift of a signed value. */
    int64_t half = lut->step_log2 ? ((int64_t)1 << (lut->step_log2 - 1)) : 0;
    int64_t interp = (dy * (int64_t)frac + half) >> lut->step_log2;
    return (int32_t)(y0 + interp);
}
