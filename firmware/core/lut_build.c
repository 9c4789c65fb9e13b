/* Load-time construction of inverse lookup tables (f^-1 and the reindexed envelopes of eq. 2). */
#include <stddef.h>
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

/* Entry j of the inverse of src on the grid y_lo + j 2^s (saturated at y_hi, as lut_eval
 * saturates): the x where the source segment holding that y reaches it. *seg is the index
 * of the segment, in ascending-y order, where the search starts; it only moves forward, so
 * calls with non-decreasing j walk the source once. */
static int32_t inverse_entry(const lut_t *src, int sgn, int32_t y_lo, int32_t y_hi, uint8_t s,
                             uint16_t j, uint16_t *seg)
{
    const uint16_t n = src->n;
    const int32_t *g = src->y_q16;
    int64_t yj = (int64_t)y_lo + ((int64_t)j << s);
    if (yj > y_hi)
        yj = y_hi; /* the last grid point may overshoot: saturate as lut_eval does */
    for (;;) {
        /* Source index of the upper-y end of ascending-y segment *seg. */
        uint16_t b = sgn > 0 ? (uint16_t)(*seg + 1) : (uint16_t)(n - 2 - *seg);
        if (yj <= g[b] || *seg + 2 >= n)
            break;
        (*seg)++;
    }
    uint16_t k = sgn > 0 ? *seg : (uint16_t)(n - 2 - *seg); /* segment k..k+1 in source order */
    int32_t xk = (int32_t)(src->x0_q16 + (int64_t)k * ((int64_t)1 << src->step_log2));
    return segment_solve(xk, (int64_t)1 << src->step_log2, g[k], g[k + 1], (int32_t)yj);
}

lut_status_t lut_inverse_error(const lut_t *src, uint16_t cap, int32_t *err_q16)
{
    const uint16_t n = src->n;
    const int32_t *g = src->y_q16;
    int sgn;
    int32_t y_lo, y_hi;
    uint8_t s;
    uint16_t m;
    lut_status_t st = inverse_plan(src, cap, &sgn, &y_lo, &y_hi, &s, &m);
    if (st != LUT_OK)
        return st;

    /* The error is piecewise linear between the breakpoints of g and the grid points of the
     * inverse, so its maximum sits on one of them; grid points carry only rounding. At each
     * breakpoint (ascending y) lut_eval reads only the two entries around it, so they are
     * computed on the fly and nothing is stored: the loader can check a table before it
     * writes anything. */
    uint16_t seg_lo = 0, seg_hi = 0;
    int64_t worst = 0;
    for (uint16_t t = 0; t < n; t++) {
        uint16_t i = sgn > 0 ? t : (uint16_t)(n - 1 - t);
        uint32_t j = (uint32_t)(((int64_t)g[i] - y_lo) >> s);
        if (j > (uint32_t)m - 2u)
            j = (uint32_t)m - 2u; /* g[i] on the last grid point: lut_eval returns entry m-1 */
        int32_t two[2];
        two[0] = inverse_entry(src, sgn, y_lo, y_hi, s, (uint16_t)j, &seg_lo);
        two[1] = inverse_entry(src, sgn, y_lo, y_hi, s, (uint16_t)(j + 1), &seg_hi);
        lut_t cell;
        st = lut_init(&cell, two, 2, (int32_t)((int64_t)y_lo + ((int64_t)j << s)), (int32_t)1 << s);
        if (st != LUT_OK)
            return st;
        int64_t xi = src->x0_q16 + ((int64_t)i << src->step_log2);
        int64_t e = (int64_t)lut_eval(&cell, g[i]) - xi;
        if (e < 0)
            e = -e;
        if (e > worst)
            worst = e;
    }
    /* +1 raw unit: rounding of the entries (1/2) plus rounding inside lut_eval (1/2). */
    worst += 1;
    *err_q16 = worst > INT32_MAX ? INT32_MAX : (int32_t)worst;
    return LUT_OK;
}

lut_status_t lut_build_inverse(const lut_t *src, int32_t *out_y_q16, uint16_t cap, lut_t *out,
                               int32_t *err_q16)
{
    int sgn;
    int32_t y_lo, y_hi;
    uint8_t s;
    uint16_t m;
    int32_t err = 0;
    lut_status_t st = inverse_plan(src, cap, &sgn, &y_lo, &y_hi, &s, &m);
    if (st == LUT_OK && err_q16 != NULL)
        st = lut_inverse_error(src, cap, &err);
    if (st != LUT_OK)
        return st;

    /* Walk the grid and the source segments together: both are monotone in y. */
    uint16_t seg = 0;
    for (uint16_t j = 0; j < m; j++)
        out_y_q16[j] = inverse_entry(src, sgn, y_lo, y_hi, s, j, &seg);
    st = lut_init(out, out_y_q16, m, y_lo, (int32_t)1 << s);
    if (st != LUT_OK)
        return st;
    if (err_q16 != NULL)
        *err_q16 = err;
    return LUT_OK;
}
