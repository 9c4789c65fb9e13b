/* Prandtl-Ishlinskii operator in fixed point: the smooth transition after the play
 * (docs/method.md, "Transition model"), its inverse, and their load-time derivation. */
#ifndef PI_H
#define PI_H

#include <stdint.h>
#include "ps_table.h"

/* A weighted sum of classical play operators, y = sum_i w_i P_{r_i}[x], with
 *   P_r[x][k] = min(x[k] + r, max(x[k] - r, P_r[x][k-1]))
 * (the classical play, Krasnosel'skii & Pokrovskii). The same engine runs the direct
 * transition (table thresholds and weights) and its inverse (Krejci & Kuhnen 2001: the
 * inverse of a PI operator is a PI operator with thresholds r' and weights w', some
 * negative), so both are bit-exact on host and board by construction. Built by pi_build(). */
typedef struct {
    uint8_t n;                   /* operators, 0..PST_MAX_OPS; 0: identity */
    uint8_t w_frac;              /* fractional bits s of w: 16 (direct), 16..30 (inverse) */
    int32_t r_q16[PST_MAX_OPS];  /* thresholds, actuator units Q16.16, r[0] = 0, non-decreasing */
    int32_t w[PST_MAX_OPS];      /* weights, Q(w_frac); every partial sum w[0]+..+w[i] is > 0 */
    int32_t w_neg[PST_MAX_OPS];  /* -w (|w| <= INT32_MAX), so an engagement is one multiply-accumulate */
    int32_t x_min_q16;           /* input range the loader validated: x +- 2 r stays in +-2^30 */
    int32_t x_max_q16;
} pi_params_t;

/* Operator states. Operators 0..m-1 are "engaged": they move with the input, so their
 * output is x - dir * r_i and is not stored (p_q16[i] is stale for i < m); the others
 * hold p_q16[i]. The engaged set is always such a prefix, because u_i + r_i and
 * r_i - u_i (u_i = p_i - x) are non-decreasing in i for any history from rest
 * (docs/method.md). Then y = (a * x + c) / 2^w_frac with c exact in int64, so between
 * reversals a tick costs one compare and one 32x32->64 multiply-accumulate whatever n. */
typedef struct {
    int32_t p_q16[PST_MAX_OPS];  /* outputs of the operators not engaged (i >= m) */
    int64_t c;                   /* sum_{i>=m} w_i p_i - dir * sum_{i<m} w_i r_i + 2^(w_frac-1)
                                    (the rounding constant rides along), Q(16 + w_frac) */
    int32_t a;                   /* sum_{i<m} w_i, Q(w_frac) */
    int32_t x_q16;               /* last input */
    int32_t y_q16;               /* last output */
    int32_t next_q16;            /* input level at which operator m engages (x >= it going up, <= going down) */
    int8_t dir;                  /* sign of the last input change; 0 at rest after a reset */
    uint8_t m;                   /* engaged operators */
} pi_state_t;

/* Why pi_build() refused an operator block (calib.c maps these to calib_status_t). */
typedef enum {
    PI_OK = 0,
    PI_ERR_COUNT,                /* n > PST_MAX_OPS */
    PI_ERR_R0,                   /* r[0] != 0 */
    PI_ERR_R_ORDER,              /* r not strictly increasing */
    PI_ERR_R_RANGE,              /* r[n-1] > q_max - q_min, or an input range +- 2 r (or 2 r') leaves +-2^30 */
    PI_ERR_W0,                   /* w[0] <= 0 */
    PI_ERR_W_NEGATIVE,           /* some w[i] < 0 */
    PI_ERR_W_SUM,                /* |sum w - 1| > 2^-8 (256 raw) */
    PI_ERR_INVERSE,              /* an inverse weight would overflow Q16.16 (w[0] <= 2 raw), or the
                                    inverse output could leave +-2^30 */
} pi_status_t;

/* Validate thresholds r_q16[n] and weights w_q16[n] (Q16.16, as in the table) and derive
 * the direct operator (*dir: input z in [z_min, z_max], the range of the play's centre)
 * and its inverse (*inv: input y in [y_min, y_max], the range of f^-1) by the inversion
 * formula of Krejci & Kuhnen 2001 (also Kuhnen 2003), with W_i = w_0 + ... + w_i:
 *   r'_i = W_i r_i - sum_{j<=i} w_j r_j          (rounded to Q16.16)
 *   w'_0 = 1 / w_0,  w'_i = 1/W_i - 1/W_{i-1}   (= -w_i / (W_i W_{i-1}); from the rounded
 *                                                partial sums 1/W_i in Q(s), s in 16..30 the
 *                                                largest that keeps 1/w_0 in int32)
 * span_q16 = q_max - q_min (> 0). *inv_err_q16 receives the worst-case |inverse - exact
 * inverse| in raw units (docs/method.md, "Error bound"); the direct operator's is 1/2 raw.
 * On refusal *dir, *inv and *inv_err_q16 are untouched. n = 0 gives two identities.
 * Init time only: 64-bit divides. */
pi_status_t pi_build(const int32_t *r_q16, const int32_t *w_q16, uint16_t n, int64_t span_q16,
                     int32_t z_min_q16, int32_t z_max_q16, int32_t y_min_q16, int32_t y_max_q16,
                     pi_params_t *dir, pi_params_t *inv, int32_t *inv_err_q16);

/* All operators at rest at x0 (p_i = x0, clamped to the validated input range): the
 * output is sum w_i x0. For the inverse this is the state consistent with a direct
 * operator at rest at x0 / sum w (the Krejci-Kuhnen initial-state relation with all p_j equal). */
void pi_reset(pi_state_t *s, const pi_params_t *pp, int32_t x0_q16);

/* One step: y = sum_i w_i P_{r_i}[x] (Q16.16), rounded half up from the exact int64
 * sum (error <= 1/2 raw against exact arithmetic with the same thresholds and weights).
 * x must lie in [pp->x_min_q16, pp->x_max_q16] (the callers' lookups guarantee it).
 * n = 0: returns x. Integer-only, no divide; O(1) between reversals, O(n) at one. */
int32_t pi_step(pi_state_t *s, const pi_params_t *pp, int32_t x_q16);

/* Out-of-line part of pi_step: a reversal (release the engaged operators at the last
 * input) and/or engagement of the next operators. Called by pi_step_inline only. */
void pi_advance(pi_state_t *s, const pi_params_t *pp, int32_t x_q16, int8_t dir);

/* The n operator outputs p_i (Q16.16), engaged ones included: for tests and diagnosis. */
void pi_outputs(const pi_state_t *s, const pi_params_t *pp, int32_t *p_q16);

#ifndef PS_CDEF
/* pi_step() inlined for comp_step and playop_step (same code, same bits). */
__attribute__((always_inline)) static inline int32_t pi_step_inline(pi_state_t *s, const pi_params_t *pp,
                                                                    int32_t x_q16)
{
    if (x_q16 == s->x_q16)
        return s->y_q16;
    int8_t d = x_q16 > s->x_q16 ? 1 : -1;
    if (d != s->dir || (d > 0 ? x_q16 >= s->next_q16 : x_q16 <= s->next_q16))
        pi_advance(s, pp, x_q16, d);
    s->x_q16 = x_q16;
    /* The sum fits int32 after the shift (pi_build bounds it), so the 64-bit shift by
     * s in 16..30 is done on the two halves, as lut_eval does. */
    uint32_t sh = pp->w_frac;
    int64_t acc = (int64_t)s->a * x_q16 + s->c; /* c holds the 1/2 for rounding half up */
    int32_t y = (int32_t)(((uint32_t)(acc >> 32) << (32u - sh)) | ((uint32_t)acc >> sh));
    s->y_q16 = y;
    return y;
}
#endif

#endif /* PI_H */
