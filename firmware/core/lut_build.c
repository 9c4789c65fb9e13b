/* Load-time construction of inverse lookup tables (f^-1 and the reindexed envelopes of eq. 2). */
#include "lut.h"

/* x at which the segment (x0, y0)-(x0 + h, y1) reaches y, rounded to nearest.
 * y lies between y0 and y1 and y1 != y0. */
static int32_t segment_solve(int32_t x0, int64_t h, int32_t y0, int32_t y1, int32_t y)
{
    int64_t num = ((int64_t)y - y0) * h;
    int64_t den = (int64_t)y1 - y0;
    if (den < 0) {
        num = -num;
        den = -den;
    }
    /* num >= 0 because y lies on the segment's side of y0. */
    return (int32_t)(x0 + (num + den / 2) / den);
}

/* Check g is strictly monotone and find the inverse grid: y range, step 2^s, m entries. */
static lut_status_t inverse_plan(const lut_t *src, uint16_t cap, int *sgn, int32_t *y_lo,
                                 int32_t *y_hi, uint8_t *s_out, uint16_t *m_out)
{
    const uint16_t n = src->n;
    const int32_t *g = src->y_q16;
    if (cap < 2)
        return LUT_ERR_SIZE;
    *sgn = (g[1] > g[0]) ? 1 : -1;
    for (uint16_t i = 0; i + 1 < n; i++) {
        int64_t d = (int64_t)g[i + 1] - g[i];
        if (d == 0 || (d > 0) != (*sgn > 0))
            return LUT_ERR_NOT_MONOTONE;
    }
    *y_lo = *sgn > 0 ? g[0] : g[n - 1];
    *y_hi = *sgn > 0 ? g[n - 1] : g[0];
    uint64_t span = (uint64_t)((int64_t)*y_hi - *y_lo);
    /* Smallest power-of-two step (>= 2 raw units, as lut_init asks) with
     * ceil(span / step) + 1 <= cap. */
    uint8_t s = 1;
    while (((span + ((1ull << s) - 1)) >> s) + 1 > cap) {
        if (++s > 24)
            return LUT_ERR_STEP;
    }
    uint16_t m = (uint16_t)(((span + ((1ull << s) - 1)) >> s) + 1);
    if ((int64_t)*y_lo + ((int64_t)(m - 1) << s) > INT32_MAX)
        return LUT_ERR_RANGE;
    *s_out = s;
    *m_out = m;
    return LUT_OK;
}

lut_status_t lut_check_inverse(const lut_t *src, uint16_t cap)
{
    int sgn;
    int32_t y_lo, y_hi;
    uint8_t s;
    uint16_t m;
    return inverse_plan(src, cap, &sgn, &y_lo, &y_hi, &s, &m);
}

lut_status_t lut_build_inverse(const lut_t *src, int32_t *out_y_q16, uint16_t cap, lut_t *out,
                               int32_t *err_q16)
{
    const uint16_t n = src->n;
    const int32_t *g = src->y_q16;
    const int64_t h = (int64_t)1 << src->step_log2;
    int sgn;
    int32_t y_lo, y_hi;
    uint8_t s;
    uint16_t m;
    lut_status_t st = inverse_plan(src, cap, &sgn, &y_lo, &y_hi, &s, &m);
    if (st != LUT_OK)
        return st;

    /* Walk the grid and the source segments together: both are monotone in y. */
    uint16_t seg = 0; /* index k of the segment between source samples k and k+1, in ascending-y order */
    for (uint16_t j = 0; j < m; j++) {
        int64_t yj = (int64_t)y_lo + ((int64_t)j << s);
        if (yj > y_hi)
            yj = y_hi; /* the last grid point may overshoot: saturate as lut_eval does */
        for (;;) {
            /* Source index of the upper-y end of ascending-y segment seg. */
            uint16_t b = sgn > 0 ? (uint16_t)(seg + 1) : (uint16_t)(n - 2 - seg);
            if (yj <= g[b] || seg + 2 >= n)
                break;
            seg++;
        }
        uint16_t k = sgn > 0 ? seg : (uint16_t)(n - 2 - seg); /* segment k..k+1 in source order */
        int32_t xk = (int32_t)(src->x0_q16 + (int64_t)k * h);
        out_y_q16[j] = segment_solve(xk, h, g[k], g[k + 1], (int32_t)yj);
    }
    lut_t tmp;
    st = lut_init(&tmp, out_y_q16, m, y_lo, (int32_t)1 << s);
    if (st != LUT_OK)
        return st;

    /* Exact worst case: the error is piecewise linear between the breakpoints of g and
     * the grid points of the inverse, so its maximum sits on one of them. Grid points
     * carry only rounding; evaluate at every breakpoint. */
    int64_t worst = 0;
    for (uint16_t i = 0; i < n; i++) {
        int64_t xi = src->x0_q16 + (int64_t)i * h;
        int64_t e = (int64_t)lut_eval(&tmp, g[i]) - xi;
        if (e < 0)
            e = -e;
        if (e > worst)
            worst = e;
    }
    /* +1 raw unit: rounding of the entries (1/2) plus rounding inside lut_eval (1/2). */
    worst += 1;
    *out = tmp;
    *err_q16 = worst > INT32_MAX ? INT32_MAX : (int32_t)worst;
    return LUT_OK;
}
