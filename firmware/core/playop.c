/* Direct model: play operator with position-dependent width (eq. 3 in actuator space). */
#include "playop.h"

void playop_reset(playop_t *p, const calib_t *cal, int32_t z0_q16)
{
    p->cal = cal;
    p->z_q16 = z0_q16;
    /* With a threshold map the operators start at rest at u0 = g(z0). */
    const int32_t u0 = cal->tmap.n != 0 ? lut_eval(&cal->tmap, z0_q16) : z0_q16;
    pi_reset(&p->pi, &cal->pi_dir, u0);
    relax_reset(&p->relax, cal->pi_dir.n != 0 ? p->pi.y_q16 : u0);
}

int32_t playop_step(playop_t *p, int32_t q_q16)
{
    /* The band of centres compatible with q: [z_up(q), z_down(q)] (eq. 2 reindexed).
     * Inside it the play absorbs the motion; outside, q drags the centre to the edge. */
    int32_t lo = lut_eval_inline(&p->cal->z_up, q_q16);
    int32_t hi = lut_eval_inline(&p->cal->z_down, q_q16);
    int32_t z = p->z_q16;
    if (z < lo)
        z = lo;
    else if (z > hi)
        z = hi;
    p->z_q16 = z;
    /* The transition after the play is taken up: y = PI[u] (identity without operators),
     * u = g(z) with a threshold map (v3: thresholds proportional to B), else u = z. */
    int32_t y = z;
    if (p->cal->tmap.n != 0)
        y = lut_eval_inline(&p->cal->tmap, z);
    if (p->cal->pi_dir.n != 0)
        y = pi_step_inline(&p->pi, &p->cal->pi_dir, y);
    /* The travel-domain relaxation (v4) on the transition's output, before f. */
    if (p->cal->relax.kappa_q16 != 0)
        y = relax_direct_inline(&p->relax, &p->cal->relax, y);
    return lut_eval_inline(&p->cal->f, y);
}
