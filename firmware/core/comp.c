/* Inverse model: backlash compensator (eqs. 4, 5, 9) with optional rate-limited transitions. */
#include "comp.h"


void comp_reset(comp_t *cp, const calib_t *cal, const comp_smoothing_t *lim, int32_t c0_q16)
{
    /* Empty the cells (cal may be another table, or new entries); f^-1's is filled at c0
     * below, so the first step after a reset (a table commit, in the loop) hits it. */
    cp->f_inv_cell.width = 0;
    cp->b_cell.width = 0;
    cp->tmap_inv_cell.width = 0;
    cp->cal = cal;
    static const comp_smoothing_t none = {0, 0, 0};
    cp->lim = (lim && lim->v_max_q32 > 0 && lim->a_max_q32 > 0) ? *lim : none;
    cp->c_prev_q16 = c0_q16;
    cp->dir = 0;
    cp->off_q16 = 0;
    cp->resid_q32 = 0;
    cp->resid_v_q32 = 0;
    cp->ramping = false;
    cp->q_ref_q16 = lut_eval_fill(&cal->f_inv, &cp->f_inv_cell, c0_q16);
    relax_reset(&cp->relax, cp->q_ref_q16); /* at rest: R^-1 of y0 is y0 */
    /* Without operators comp_step never reads cp->pi: skip its reset (it clears all 16
     * operator slots, ~70 instructions on the tick that arms the compensator). */
    if (cal->pi_inv.n != 0) {
        pi_reset(&cp->pi, &cal->pi_inv, cp->q_ref_q16);
        cp->q_ref_q16 = cp->pi.y_q16;
    }
    if (cal->tmap.n != 0)
        cp->q_ref_q16 = lut_eval_fill(&cal->tmap_inv, &cp->tmap_inv_cell, cp->q_ref_q16);
}

void comp_rebind(comp_t *cp, const calib_t *cal)
{
    cp->f_inv_cell.width = 0;
    cp->b_cell.width = 0;
    cp->tmap_inv_cell.width = 0;
    cp->cal = cal;
}

void comp_b_changed(comp_t *cp)
{
    *(volatile uint32_t *)&cp->b_cell.width = 0;
}

/* Bring the residual r to 0 with |v| <= v_max and |dv| <= a_max per tick: accelerate
 * while the distance left still allows stopping (v^2 / 2 <= a |r|, compared without a
 * divide), brake otherwise, creep at a_max per tick at worst, and land exactly on 0 (the
 * landing tick is the only one whose speed change may exceed a_max). */
static void ramp(comp_t *cp)
{
    const comp_smoothing_t *lim = &cp->lim;
    int64_t r = cp->resid_q32;
    int sgn = r < 0 ? 1 : -1;                             /* direction of travel toward 0 */
    int64_t dist = r < 0 ? -r : r;
    int64_t w = sgn > 0 ? cp->resid_v_q32 : -cp->resid_v_q32; /* speed toward 0; < 0 moving away */
    int64_t w1 = w + lim->a_max_q32;
    if (w1 > lim->v_max_q32)
        w1 = lim->v_max_q32;
    if (w1 > 0 && w1 < dist) {
        int64_t rem = dist - w1;
        /* w1 <= 2^31 so w1^2 fits; a * rem fits because rem < far = INT64_MAX / a. */
        if (rem < lim->far_q32 && ((w1 * w1) >> 1) > lim->a_max_q32 * rem) {
            w1 = w - lim->a_max_q32;
            if (w1 < lim->a_max_q32)
                w1 = lim->a_max_q32;
        }
    }
    if (w1 >= dist) {
        cp->resid_q32 = 0;
        cp->resid_v_q32 = 0;
        return;
    }
    cp->resid_v_q32 = sgn > 0 ? w1 : -w1;
    cp->resid_q32 += cp->resid_v_q32;
}

/* Reversal step and its ramp: kept out of line so the common tick (no reversal, ramp
 * idle) stays 32-bit and saves no extra registers. Returns q* with the residual applied. */
__attribute__((noinline)) int32_t comp_smooth(comp_t *cp, int32_t q_q16, int32_t off_q16, bool reversed)
{
    if (cp->lim.v_max_q32 <= 0)
        return q_q16;
    /* The jump of the offset at a reversal joins the residual still to be ramped away;
     * the slow change of B(q_c) between reversals does not. */
    if (reversed)
        cp->resid_q32 += ((int64_t)cp->off_q16 - off_q16) * 65536; /* not << : may be negative */
    ramp(cp);
    cp->ramping = cp->resid_q32 != 0 || cp->resid_v_q32 != 0;
    int64_t q = (int64_t)q_q16 + ((cp->resid_q32 + (1 << 15)) >> 16); /* round Q32 to Q16 */
    return q > INT32_MAX ? INT32_MAX : (q < INT32_MIN ? INT32_MIN : (int32_t)q);
}

/* comp_step_inline (comp.h), called: the host (cffi) and the tests step through here. */
int32_t comp_step(comp_t *cp, int32_t c_ref_q16)
{
    return comp_step_inline(cp, c_ref_q16);
}
