/* Uniform-grid lookup: evaluation (per tick) and grid description. */
#include "lut.h"

lut_status_t lut_init(lut_t *lut, const int32_t *y_q16, uint16_t n, int32_t x0_q16, int32_t step_q16)
{
    if (n < 2)
        return LUT_ERR_SIZE;
    /* Power of two, 1..2^24 raw units: evaluation is then a shift, never a divide. */
    if (step_q16 < 2 || step_q16 > (1 << 24) || (step_q16 & (step_q16 - 1)) != 0)
        return LUT_ERR_STEP;
    int64_t x_last = (int64_t)x0_q16 + (int64_t)(n - 1) * step_q16;
    if (x_last > INT32_MAX)
        return LUT_ERR_RANGE;
    for (uint16_t i = 0; i + 1 < n; i++) {
        int64_t d = (int64_t)y_q16[i + 1] - y_q16[i];
        if (d > INT32_MAX || d < -INT32_MAX)
            return LUT_ERR_RANGE;
    }
    uint8_t s = 0;
    while ((1 << s) != step_q16)
        s++;
    lut->y_q16 = y_q16;
    lut->x0_q16 = x0_q16;
    lut->x_last_q16 = (int32_t)x_last;
    lut->frac_mask = (uint32_t)step_q16 - 1u;
    lut->half = step_q16 >> 1;
    lut->n = n;
    lut->step_log2 = s;
    return LUT_OK;
}

int32_t lut_eval(const lut_t *lut, int32_t x_q16)
{
    return lut_eval_inline(lut, x_q16);
}
