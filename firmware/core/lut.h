/* Uniform-grid lookup tables with linear interpolation, and their numerical inverses. */
#ifndef LUT_H
#define LUT_H

#include <stdint.h>

/* y(x) sampled at x_i = x0 + i * 2^step_log2 (raw Q16.16 units), i = 0..n-1.
 * The grid step is a power of two so that evaluation shifts and masks: no divide.
 * Entries are not owned (flash, a table blob, or a calib_t buffer). */
typedef struct {
    const int32_t *y_q16;        /* n entries, Q16.16 */
    int32_t x0_q16;              /* abscissa of y_q16[0] */
    int32_t x_last_q16;          /* abscissa of y_q16[n-1] (cached) */
    uint32_t frac_mask;          /* step - 1 (cached) */
    int32_t half;                /* step / 2, for rounding (cached) */
    uint16_t n;                  /* >= 2 */
    uint8_t step_log2;           /* step = 1 << step_log2 raw units, 1..24 */
} lut_t;

/* Status of lut_init() and lut_build_inverse(). */
typedef enum {
    LUT_OK = 0,
    LUT_ERR_SIZE,                /* n < 2, or n above the capacity given */
    LUT_ERR_STEP,                /* step not a power of two in 2..2^24 raw units */
    LUT_ERR_RANGE,               /* grid does not fit int32 Q16.16, or two neighbours differ by 2^31 or more */
    LUT_ERR_NOT_MONOTONE,        /* inverse asked of a function that is not strictly monotone */
} lut_status_t;

/* Describe entries y_q16[0..n-1] on the grid x0_q16 + i * step_q16.
 * Errors: LUT_ERR_SIZE (n < 2), LUT_ERR_STEP (step not 2^k, 2 <= step <= 2^24),
 * LUT_ERR_RANGE (x0 + (n-1)*step overflows int32, or |y[i+1] - y[i]| >= 2^31, which
 * lets lut_eval use one 32x32->64 multiply). O(n), not per tick. */
lut_status_t lut_init(lut_t *lut, const int32_t *y_q16, uint16_t n, int32_t x0_q16, int32_t step_q16);

/* y(x) by linear interpolation between the two neighbouring entries, saturating to
 * y_q16[0] below x0 and to y_q16[n-1] above the last abscissa.
 * Bound: |lut_eval(x) - L(x)| <= 1/2 LSB (2^-17) where L is the exact piecewise-linear
 * interpolant of the entries (round half up of the exact product; no index error since
 * the step is a power of two). O(1), integer-only, per tick. */
int32_t lut_eval(const lut_t *lut, int32_t x_q16);

#ifndef PS_CDEF
/* lut_eval() inlined, for the per-tick modules: same code, so the same bits, without the
 * call, which is a quarter of its cost on the Cortex-M4 (bench/bench_firmware.sh). */
__attribute__((always_inline)) static inline int32_t lut_eval_inline(const lut_t *lut, int32_t x_q16)
{
    if (x_q16 <= lut->x0_q16)
        return lut->y_q16[0];
    if (x_q16 >= lut->x_last_q16)
        return lut->y_q16[lut->n - 1];
    /* 0 < off < (n-1) * step <= 2^31: fits uint32 even when x0 is negative. */
    uint32_t off = (uint32_t)x_q16 - (uint32_t)lut->x0_q16;
    const int32_t *y = lut->y_q16 + (off >> lut->step_log2);
    int32_t frac = (int32_t)(off & lut->frac_mask);
    /* One 32x32->64 multiply-accumulate (SMLAL; lut_init guarantees dy fits int32),
     * rounding half up, then the 64-bit arithmetic shift by s in 1..24 done on the two
     * halves: the quotient fits int32, so hi << (32 - s) | lo >> s is exact. */
    int32_t dy = (int32_t)((uint32_t)y[1] - (uint32_t)y[0]);
    int64_t p = (int64_t)dy * frac + lut->half;
    uint32_t s = lut->step_log2;
    uint32_t quot = ((uint32_t)(p >> 32) << (32u - s)) | ((uint32_t)p >> s);
    return y[0] + (int32_t)quot;
}
#endif

/* One interpolation cell of a table, kept between calls by a per-tick caller whose abscissa
 * moves slowly (the compensator: at 20 kHz c* and q_c stay in one cell for tens to thousands
 * of ticks). A hit skips the range checks, the index and the two entry loads, and uses a
 * 32-bit multiply: the cell is only filled when |dy| < 2^(31 - s), for which dy * frac + half
 * fits int32, so the result is lut_eval()'s bit for bit (the same exact p, shifted). */
typedef struct {
    int32_t x_lo_q16;            /* abscissa of the cell's left entry */
    uint32_t width;              /* the table's step when filled; 0: empty, nothing hits */
    int32_t y0_q16;              /* left entry */
    int32_t dy_q16;              /* right entry - left entry */
} lut_cell_t;

/* lut_eval(lut, x) through cell (zeroed = empty; empty it when lut changes): equal to
 * lut_eval() for every x and every cell content this function left. On a miss the cell
 * is refilled around x when x is inside the grid and the cell qualifies (see lut_cell_t).
 * O(1), integer-only, no divide, per tick. */
int32_t lut_eval_fill(const lut_t *lut, lut_cell_t *cell, int32_t x_q16);

#ifndef PS_CDEF
__attribute__((always_inline)) static inline int32_t lut_eval_cell(const lut_t *lut, lut_cell_t *cell,
                                                                    int32_t x_q16)
{
    /* x_lo <= x < x_lo + width in one unsigned compare. The filled cell lies inside
     * [x0, x_last], where lut_eval interpolates in that same cell (at x = x0, cell 0 gives
     * y0 + (half >> s) = y0, as lut_eval's saturation does). */
    uint32_t off = (uint32_t)x_q16 - (uint32_t)cell->x_lo_q16;
    if (__builtin_expect(off < cell->width, 1))
        return cell->y0_q16 + ((cell->dy_q16 * (int32_t)off + lut->half) >> lut->step_log2);
    return lut_eval_fill(lut, cell, x_q16);
}
#endif

/* Build the table of the inverse x = g^-1(y) of the piecewise-linear g given by src,
 * on a uniform y grid whose power-of-two step is the smallest that covers
 * [min g, max g] in at most cap entries; entries go to out_y_q16[0..cap-1].
 * g must be strictly monotone (increasing or decreasing), else LUT_ERR_NOT_MONOTONE
 * and nothing is written (out_y_q16 included). On success *err_q16 receives the exact worst-case error of
 * lut_eval(out, .) against the exact inverse of g over g's range, in raw units: the
 * error is piecewise linear between breakpoints of g and grid points of out, so its
 * maximum is found by evaluating at every breakpoint (plus the 1/2 LSB of lut_eval);
 * err_q16 may be NULL when the caller has it already (lut_inverse_error()).
 * O(n + cap), uses 64-bit divides: load time only, never per tick. */
/* The exact worst-case error *err_q16 that lut_build_inverse() would report for src (same
 * checks, same value), computed without storing the inverse: the loader checks a table's
 * precision before it writes anything. O(n), 64-bit divides: load time only. */
lut_status_t lut_inverse_error(const lut_t *src, uint16_t cap, int32_t *err_q16);

/* The checks of lut_build_inverse() alone, writing nothing: LUT_OK if it would succeed. */
lut_status_t lut_check_inverse(const lut_t *src, uint16_t cap);

lut_status_t lut_build_inverse(const lut_t *src, int32_t *out_y_q16, uint16_t cap, lut_t *out,
                               int32_t *err_q16);

#endif /* LUT_H */
