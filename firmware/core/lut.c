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

/* The miss path of lut_eval_cell: kept out of line (a cell is crossed every tens of ticks or
 * more), and it evaluates through the new cell, so a miss costs one lookup, not two. */
int32_t lut_eval_fill(const lut_t *lut, lut_cell_t *cell, int32_t x_q16)
{
    /* Saturated: no cell (the one held stays valid for its own range). x = x0 is cell 0's,
     * where the interpolation gives y[0] as the saturation does. */
    if (x_q16 < lut->x0_q16)
        return lut->y_q16[0];
    if (x_q16 >= lut->x_last_q16)
        return lut->y_q16[lut->n - 1];
    uint32_t s = lut->step_log2;
    uint32_t off = (uint32_t)x_q16 - (uint32_t)lut->x0_q16;
    uint32_t i = off >> s;
    int32_t frac = (int32_t)(off & lut->frac_mask);
    const int32_t *y = lut->y_q16 + i;
    int32_t dy = (int32_t)((uint32_t)y[1] - (uint32_t)y[0]);
    /* -2^(31-s) <= dy < 2^(31-s): then |dy * frac + half| < 2^31 for frac < 2^s, half =
     * 2^(s-1), and the 32-bit product is exact. Steeper cells are not cached. */
    if ((uint32_t)dy + (1u << (31u - s)) >= (1u << (32u - s))) {
        cell->width = 0;
        return lut_eval_inline(lut, x_q16);
    }
    cell->x_lo_q16 = (int32_t)((uint32_t)lut->x0_q16 + (i << s));
    cell->width = 1u << s;
    cell->y0_q16 = y[0];
    cell->dy_q16 = dy;
    return y[0] + ((dy * frac + lut->half) >> s);
}
