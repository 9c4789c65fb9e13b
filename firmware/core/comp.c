/* Inverse model: backlash compensator (eqs. 4, 5, 9) with optional rate-limited transitions. */
#include "comp.h"

void comp_reset(comp_t *cp, const calib_t *cal, const comp_smoothing_t *lim, int32_t c0_q16)
{
    cp->cal = cal;
    static const comp_smoothing_t none = {0, 0, 0};
    cp->lim = (lim && lim->v_max_q32 > 0 && lim->a_max_q32 > 0) ? *lim : none;
    cp->c_prev_q16 = c0_q16;
    cp->dir = 0;
    cp->off_q32 = 0;
    cp->off_v_q32 = 0;
    cp->q_ref_q16 = lut_eval(&cal->f_inv, c0_q16);
}

/* Move off toward target with |v| <= v_max and |dv| <= a_max per tick: accelerate while
 * the distance left still allows stopping (v^2 / 2 <= a * d, compared without a divide),
 * brake otherwise, creep at a_max per tick at worst, and land exactly on the target
 * (the landing tick is the only one whose speed change may exceed a_max). */
static void ramp(comp_t *cp, int64_t target_q32)
{
    const comp_smoothing_t *lim = &cp->lim;
    int64_t d = target_q32 - cp->off_q32;
    if (d == 0 && cp->off_v_q32 == 0)
        return;
    int sgn = d < 0 ? -1 : 1;
    int64_t dist = d < 0 ? -d : d;
    int64_t w = sgn > 0 ? cp->off_v_q32 : -cp->off_v_q32; /* speed toward the target; < 0 moving away */
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
        cp->off_q32 = target_q32;
        cp->off_v_q32 = 0;
        return;
    }
    cp->off_v_q32 = sgn > 0 ? w1 : -w1;
    cp->off_q32 += cp->off_v_q32;
}

int32_t comp_step(comp_t *cp, int32_t c_ref_q16)
{
    const calib_t *cal = cp->cal;
    /* eq. 4: the branch follows the sign of the change of c*; held when c* is unchanged. */
    if (c_ref_q16 > cp->c_prev_q16)
        cp->dir = 1;
    else if (c_ref_q16 < cp->c_prev_q16)
        cp->dir = -1;
    cp->c_prev_q16 = c_ref_q16;

    /* eqs. 5 / 9: centre from the inverse, half the width at the centre on the side the
     * play must be taken up. For a decreasing f, raising c means lowering q: the sign
     * flip is exactly the difference between eq. 5 and eq. 9. */
    int32_t q_c = lut_eval(&cal->f_inv, c_ref_q16);
    int32_t half_b = lut_eval(&cal->b, q_c) >> 1;
    int32_t off_target = cp->dir * cal->f_sign * half_b;
    int64_t target_q32 = (int64_t)off_target * 65536; /* not << : off_target may be negative */

    if (cp->lim.v_max_q32 > 0)
        ramp(cp, target_q32);
    else
        cp->off_q32 = target_q32;

    /* Round the Q32 offset to Q16 (add half an LSB, arithmetic shift). */
    int64_t q = (int64_t)q_c + ((cp->off_q32 + (1 << 15)) >> 16);
    if (q < cal->q_min_q16)
        q = cal->q_min_q16;
    if (q > cal->q_max_q16)
        q = cal->q_max_q16;
    cp->q_ref_q16 = (int32_t)q;
    return (int32_t)q;
}
