/* Travel-domain relaxation (rate-independent creep, table v4) in fixed point: the direct
 * model and its inverse as per-tick recursions (docs/method.md, "Travel-domain relaxation";
 * the double reference is host/playscope/relax.py). */
#ifndef RELAX_H
#define RELAX_H

#include <stdint.h>
#include "ps_table.h"

/* A Dahl / Duhem-type relaxation over the travel (Dahl, AIAA J. 1976): with input x
 * (actuator units) per tick k,
 *   v[k] = x[k] + kappa (r[k-1] - x[k])                               (direct, output v)
 *   r[k] = r[k-1] + g[k] (x[k] - r[k-1]),  g[k] = min(|v[k] - v[k-1]| / lambda, 1 - kappa)
 * and the inverse, explicit because v reads the state before the update and the gain reads
 * the travel of v, which the inverse is given:
 *   x[k] = v[k] + m (v[k] - r[k-1]),  m = kappa / (1 - kappa)         (then the same update)
 * Why the travel of v, not of x: with g from |dx| the inverse's errors obey
 * e[k] = (1 - m) e[k-1] + m e[k-2] (roots 1 and -m), which rings and diverges for kappa >= 1/2;
 * with g from |dv| (a known input) they contract by 1 - g / (1 - kappa) per tick. In steady
 * motion dv = dx, so lambda keeps its meaning. The cap 1 - kappa keeps that factor >= 0 (a jump
 * moves r at most 1 - kappa of the way). At the tick rate it never acts.
 * Fixed point: x, v in Q16.16; r kept in Q32 (r_q32 = r * 2^32, int64) so the small per-tick
 * increments do not round away; g in Q31; m in Q24; 1/lambda as 2^47 / lambda_q16 (so
 * g_q31 = |dv| * inv_lam >> 16). The loader derives m and 1/lambda (the only divides); a tick
 * is compares, shifts and 32x32->64 / 64x32 multiplies. */
typedef struct {
    int32_t kappa_q16;           /* 0: no relaxation (the step functions are not called) */
    int32_t lambda_q16;          /* travel constant, actuator units, >= 1 raw */
    int32_t m_q24;               /* kappa / (1 - kappa), Q8.24, rounded (<= 9 for kappa <= 0.9) */
    uint64_t inv_lam_q47;        /* floor(2^47 / lambda_q16) */
    int32_t g_max_q31;           /* the gain's cap 1 - kappa, Q31 */
    int32_t x_min_q16;           /* the inverse's output is clamped to [x_min, x_max]: the input range */
    int32_t x_max_q16;           /* the loader validated for what follows it (f's grid) */
} relax_params_t;

typedef struct {
    int64_t r_q32;               /* relaxed state, actuator units * 2^32 */
    int32_t v_prev_q16;          /* last output of the direct model (input of the inverse) */
} relax_state_t;

/* Why relax_build() refused a table's relaxation fields. */
typedef enum {
    RELAX_OK = 0,
    RELAX_ERR_KAPPA,             /* kappa_q16 outside 0..PST_RELAX_KAPPA_MAX_Q16 */
    RELAX_ERR_LAMBDA,            /* lambda_q16 < 1 with kappa != 0, or != 0 with kappa = 0 */
    RELAX_ERR_RANGE,             /* input range beyond +-2^30 or empty */
} relax_status_t;

/* Validate (kappa_q16, lambda_q16) of a v4 table and derive *out for inputs in [x_min, x_max]
 * (both within +-2^30 when kappa != 0). kappa = 0 with lambda = 0: no relaxation (out->kappa_q16 = 0). Init time
 * (64-bit divides). Writes *out only on RELAX_OK. */
relax_status_t relax_build(int32_t kappa_q16, int32_t lambda_q16, int32_t x_min_q16, int32_t x_max_q16,
                           relax_params_t *out);

/* At rest at x0: r = x0 = v0, no travel yet. */
void relax_reset(relax_state_t *s, int32_t x0_q16);

/* One tick of the direct model: v[k] for x[k] (x within the build range). */
int32_t relax_direct(relax_state_t *s, const relax_params_t *rp, int32_t x_q16);

/* One tick of the inverse: x[k] with relax_direct(x[k]) = v[k] (to the rounding bound of
 * docs/firmware.md), clamped to [x_min, x_max]; v within the build range. */
int32_t relax_inverse(relax_state_t *s, const relax_params_t *rp, int32_t v_q16);

#ifndef PS_CDEF
/* The state update shared by both directions: g = min(|v - v_prev| / lambda, 1 - kappa)
 * without a divide (compare with lambda first, so |dv| * inv_lam < 2^47), r += g (x - r).
 * x, v, r16 within the build range (+-2^30), so every difference fits int32 and the products
 * are single 32x32->64 multiplies (the board's tick is 32-bit wherever it can be). */
__attribute__((always_inline)) static inline void relax_update_inline(relax_state_t *s, const relax_params_t *rp,
                                                                       int32_t x_q16, int32_t v_q16, int32_t r16)
{
    /* In 64 bits: v - v_prev overflowed int32 on a fuzzed table (UBSan, fuzz_table, 2026-11-24). */
    int64_t dv = (int64_t)v_q16 - s->v_prev_q16;
    if (dv == 0)
        return;                  /* no travel, no relaxation: the recursion is rate-independent */
    s->v_prev_q16 = v_q16;
    uint64_t adv = (uint64_t)(dv < 0 ? -dv : dv);
    int32_t g_q31 = rp->g_max_q31;                                  /* the cap 1 - kappa */
    if (adv < (uint64_t)(uint32_t)rp->lambda_q16) {
        uint32_t g = (uint32_t)(((uint64_t)adv * rp->inv_lam_q47) >> 16); /* < 2^31 */
        g_q31 = (int32_t)g < g_q31 ? (int32_t)g : g_q31;
    }
    s->r_q32 += (((int64_t)x_q16 - r16) * g_q31 + (1 << 14)) >> 15; /* Q47 -> Q32 */
}

__attribute__((always_inline)) static inline int32_t relax_direct_inline(relax_state_t *s, const relax_params_t *rp,
                                                                          int32_t x_q16)
{
    int32_t r16 = (int32_t)((s->r_q32 + (1 << 15)) >> 16);
    /* In 64 bits and saturated: r16 - x_q16 overflowed int32 on a fuzzed table (UBSan, fuzz_table);
     * in range the result is the same. */
    int64_t v64 = (int64_t)x_q16 + (((int64_t)rp->kappa_q16 * ((int64_t)r16 - x_q16) + (1 << 15)) >> 16);
    int32_t v = v64 > INT32_MAX ? INT32_MAX : (v64 < INT32_MIN ? INT32_MIN : (int32_t)v64);
    relax_update_inline(s, rp, x_q16, v, r16);
    return v;
}

__attribute__((always_inline)) static inline int32_t relax_inverse_inline(relax_state_t *s, const relax_params_t *rp,
                                                                           int32_t v_q16)
{
    int32_t r16 = (int32_t)((s->r_q32 + (1 << 15)) >> 16);
    /* m (v - r) up to 9 x 2^31: the correction is clamped in 64 bits, once. */
    int64_t x = v_q16 + (((int64_t)rp->m_q24 * (v_q16 - r16) + (1 << 23)) >> 24);
    int32_t xc = x < rp->x_min_q16 ? rp->x_min_q16 : (x > rp->x_max_q16 ? rp->x_max_q16 : (int32_t)x);
    relax_update_inline(s, rp, xc, v_q16, r16);
    return xc;
}
#endif

#endif /* RELAX_H */
