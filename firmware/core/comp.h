/* Inverse model: backlash compensator q*[k] from c*[k] (paper eqs. 4, 5 and 9), with the
 * inverse of the transition (table v2) between f^-1 and the play. */
#ifndef COMP_H
#define COMP_H

#include <stdbool.h>
#include <stdint.h>
#include "calib.h"

/* Limits of the optional transition smoothing, per control tick.
 * The backlash step at a reversal (a jump of B in q*) is replaced by a ramp whose
 * velocity and acceleration stay within these limits, as LinuxCNC ramps its backlash
 * correction; the nominal part f^-1(c*) and the slow change of B(q_c) along the way are
 * passed through untouched, so between reversals the step costs no 64-bit work. Q32.32 in actuator
 * units per tick (per tick^2) because a 20 kHz tick moves far less than one Q16 LSB of
 * acceleration. Zero velocity limit means no smoothing (the step of eq. 4 as written). */
typedef struct {
    int64_t v_max_q32;           /* actuator units per tick, Q32.32, 0..2^31 */
    int64_t a_max_q32;           /* actuator units per tick^2, Q32.32, 1..2^31 when v_max_q32 > 0 */
    int64_t far_q32;             /* INT64_MAX / a_max_q32: beyond it no braking is needed (derived) */
} comp_smoothing_t;

typedef struct {
    const calib_t *cal;
    comp_smoothing_t lim;
    int32_t c_prev_q16;          /* c*[k-1] */
    int8_t dir;                  /* sign of the last non-zero change of c*: +1, -1, 0 before any */
    int32_t off_q16;             /* backlash offset of eq. 4, dir * s_f * B(q_c) / 2, last tick */
    int64_t resid_q32;           /* part of the reversal step not yet applied (Q32.32); 0 when settled */
    int64_t resid_v_q32;         /* its rate, per tick */
    bool ramping;                /* resid or its rate non-zero: one flag for the per-tick test */
    int32_t q_ref_q16;           /* q*[k-1], for reading back */
    pi_state_t pi;               /* inverse transition operators (not reset, not read when cal->pi_inv.n = 0) */
    lut_cell_t f_inv_cell;       /* cell of cal->f_inv around the last c*, and of cal->b around */
    lut_cell_t b_cell;           /* the last q_c (lut_eval_cell): emptied by comp_reset */
    lut_cell_t tmap_inv_cell;    /* cell of cal->tmap_inv around the last u* (used only with a map) */
    relax_state_t relax;         /* inverse relaxation (v4; not read when cal->relax.kappa_q16 = 0) */
} comp_t;

/* Convert limits to per-tick Q32.32: v_q16 in actuator units/s, a_q16 in units/s^2
 * (both Q16.16, >= 0), tick_hz > 0. v_q16 = 0 disables smoothing. Limits are clamped
 * to 2^31 per tick (products stay in int64). The only way to make a comp_smoothing_t
 * with smoothing on, since far_q32 is derived here. Init time only
 * (64-bit divides; lives in comp_config.c so the per-tick object stays divide-free). */
comp_smoothing_t comp_smoothing_from_rates(int32_t v_q16, int32_t a_q16, uint32_t tick_hz);

/* Start from reference c0_q16 with no direction known: the offset is 0 (play centred)
 * until c* first moves, the transition's operators at rest. lim may be NULL for no smoothing.
 * Also after any change to the entries of cal (comp_step caches one cell of f^-1 and of B;
 * psa_set_table re-arms the loop, which resets). */
void comp_reset(comp_t *cp, const calib_t *cal, const comp_smoothing_t *lim, int32_t c0_q16);

/* Hot swap (psa_set_table during a pure-play compensation, neither table with operators or a
 * relaxation, whose states belong to their table): run cal from the next step with
 * the state kept (direction, offset, ramp); both cached cells are emptied, since they hold
 * the previous table's entries. O(1). */
void comp_rebind(comp_t *cp, const calib_t *cal);

/* The entries of cal->b changed under the compensator (an on-line B update published, or
 * stopped, b_online.h): B's cached cell is emptied (one word store: safe from outside an
 * interrupt-driven tick, whose next B lookup refills it from the new entries). O(1). */
void comp_b_changed(comp_t *cp);

/* One step of eq. 4: q*[k] for reference c*[k] (deg, Q16).
 *   y*  = f^-1(c*)                         (f_coarse^-1 of eq. 5 or f_remain^-1 of eq. 9)
 *   y*  = R^-1[y*]                         (table v4 with a relaxation only, relax.h; a held c*
 *                                           holds q*, skipping the inverse's settling of at most
 *                                           m times the last tick's travel)
 *   q_c = PI^-1[y*]                        (the transition's inverse, Krejci-Kuhnen; q_c = y*
 *                                           without operators, so n = 0 is eq. 4 bit for bit)
 *   q_c = g^-1(q_c)                        (table v3 with a threshold map only)
 *   q*  = q_c + dir * s_f * B(q_c) / 2      dir = sign(c*[k] - c*[k-1]), held when equal;
 *                                           s_f = sign(f'), which turns eq. 5 into eq. 9
 *                                           when f is decreasing
 * then the offset is ramped within the smoothing limits and q* saturated to
 * [q_min, q_max]. Integer-only, no divide; O(1) between reversals, O(n) at one.
 * Error of q_c against the exact inverse on the same table: f^-1's error times
 * sum |w'_i| (the inverse's Lipschitz constant) + cal->pi_inv_err_q16; with a map that
 * times max dz/du plus g^-1's own error: cal->comp_err_q16 in all cases. */
int32_t comp_step(comp_t *cp, int32_t c_ref_q16);

#ifndef PS_CDEF
/* comp_step's reversal and ramp (the offset jump joins the residual, which is ramped
 * within the limits): out of line, called by comp_step_inline only when c* reversed or a
 * ramp is pending. q_q16 = q* before it, off_q16 = this tick's offset. Internal. */
int32_t comp_smooth(comp_t *cp, int32_t q_q16, int32_t off_q16, bool reversed);

/* comp_step() inlined, for the control loop (psa_tick): the same code, so the same bits,
 * without the call and its register saves (bench/bench_firmware.sh). */
__attribute__((always_inline)) static inline int32_t comp_step_inline(comp_t *cp, int32_t c_ref_q16)
{
    const calib_t *cal = cp->cal;
    /* eq. 4: the branch follows the sign of the change of c*; held when c* is unchanged. */
    int8_t dir = cp->dir;
    if (c_ref_q16 != cp->c_prev_q16)
        dir = c_ref_q16 > cp->c_prev_q16 ? 1 : -1;
    else if (dir != 0 && !cp->ramping)
        /* c* held (a host slower than the tick) with no ramp pending: the last step had this
         * c*, this dir, the same q_c (the transition is rate-independent: an unchanged input
         * leaves it as it is) and no residual, so it returned exactly this q*; nothing in
         * the state would change. dir = 0: no step since comp_reset, whose q_ref is not
         * clamped to the travel, so that tick runs in full. */
        return cp->q_ref_q16;
    cp->c_prev_q16 = c_ref_q16;

    /* eqs. 5 / 9: centre from the inverse, half the width at the centre on the side the
     * play must be taken up. For a decreasing f, raising c means lowering q: the sign
     * flip (f_sign) is exactly the difference between eq. 5 and eq. 9. The sum fits
     * int32: calib_load checks the f grid widened by B_max / 2 does. */
    int32_t q_c = lut_eval_cell(&cal->f_inv, &cp->f_inv_cell, c_ref_q16);
    /* The pure play (eq. 4 as written) tests one byte; the other models their stages. */
    const uint8_t stages = cal->stages;
    if (stages != 0) {
        /* The relaxation's inverse (v4): the y the relaxation turns into y*; clamped to f's
         * grid, the range the transition's inverse was validated on. Called, not inlined:
         * inlined, its 64-bit temporaries cost the other models' ticks 7 instructions of
         * register saves (bench/bench_firmware.sh). */
        if (stages & CALIB_STAGE_RELAX)
            q_c = relax_inverse(&cp->relax, &cal->relax, q_c);
        /* The transition's inverse: the centre that the direct model maps to y* = f^-1(c*).
         * |q_c| <= 2^30 (pi_build bounds it), so q_c + B/2 still fits int32. */
        if (stages & CALIB_STAGE_PI)
            q_c = pi_step_inline(&cp->pi, &cal->pi_inv, q_c);
        /* With a threshold map (v3) the operators ran on u = g(z): z* = g^-1(u*), which lies
         * on the map's grid (calib_load checks it +- B_max/2 fits int32). */
        if (stages & CALIB_STAGE_TMAP)
            q_c = lut_eval_cell(&cal->tmap_inv, &cp->tmap_inv_cell, q_c);
    }
    int32_t off = (dir * cal->f_sign) * (lut_eval_cell(&cal->b, &cp->b_cell, q_c) >> 1);
    int32_t q = q_c + off;
    bool reversed = dir != cp->dir;
    if (reversed || cp->ramping)
        q = comp_smooth(cp, q, off, reversed);
    cp->dir = dir;
    cp->off_q16 = off;
    if (q < cal->q_min_q16)
        q = cal->q_min_q16;
    if (q > cal->q_max_q16)
        q = cal->q_max_q16;
    cp->q_ref_q16 = q;
    return q;
}
#endif

#endif /* COMP_H */
