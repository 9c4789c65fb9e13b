/* Prandtl-Ishlinskii operator, per tick: reset, step, reversal and engagement (no divide). */
#include "pi.h"

void pi_reset(pi_state_t *s, const pi_params_t *pp, int32_t x0_q16)
{
    int32_t x = x0_q16 < pp->x_min_q16 ? pp->x_min_q16 : (x0_q16 > pp->x_max_q16 ? pp->x_max_q16 : x0_q16);
    int64_t c = 0;
    for (uint8_t i = 0; i < pp->n; i++) {
        s->p_q16[i] = x;
        c += (int64_t)pp->w[i] * x;
    }
    for (uint8_t i = pp->n; i < PST_MAX_OPS; i++)
        s->p_q16[i] = 0;
    s->c = c;
    s->a = 0;
    s->x_q16 = x;
    s->dir = 0;
    s->m = 0;
    s->next_q16 = x;
    if (pp->n == 0) {
        s->y_q16 = x0_q16;
        return;
    }
    uint32_t sh = pp->w_frac;
    s->y_q16 = (int32_t)((c + ((int64_t)1 << (sh - 1))) >> sh);
}

void pi_advance(pi_state_t *s, const pi_params_t *pp, int32_t x_q16, int8_t dir)
{
    uint8_t m = s->m;
    const uint8_t n = pp->n;
    if (dir != s->dir) {
        /* Reversal: the engaged operators stop where the last input left them,
         * p_i = x[k-1] - dir_old * r_i, and their share a * x[k-1] becomes constant. */
        const int32_t xp = s->x_q16;
        for (uint8_t i = 0; i < m; i++)
            s->p_q16[i] = s->dir > 0 ? xp - pp->r_q16[i] : xp + pp->r_q16[i];
        s->c += (int64_t)s->a * xp;
        s->a = 0;
        m = 0;
        s->dir = dir;
    }
    /* Engage operators in threshold order while the input has reached their level
     * e_m = p_m + dir * r_m: from then on p_m = x - dir * r_m, so w_m p_m leaves c and
     * w_m joins a, with c -= w_m * e_m keeping the sum exact. */
    int64_t e = 0;
    while (m < n) {
        e = dir > 0 ? (int64_t)s->p_q16[m] + pp->r_q16[m] : (int64_t)s->p_q16[m] - pp->r_q16[m];
        if (dir > 0 ? x_q16 < e : x_q16 > e)
            break;
        s->a += pp->w[m];
        s->c -= (int64_t)pp->w[m] * e;
        m++;
    }
    s->m = m;
    /* e of a non-engaged operator lies within +-2^31 - 1: p and r are within +-2^30. */
    s->next_q16 = m < n ? (int32_t)e : (dir > 0 ? INT32_MAX : INT32_MIN);
}

int32_t pi_step(pi_state_t *s, const pi_params_t *pp, int32_t x_q16)
{
    if (pp->n == 0)
        return x_q16;
    return pi_step_inline(s, pp, x_q16);
}

void pi_outputs(const pi_state_t *s, const pi_params_t *pp, int32_t *p_q16)
{
    for (uint8_t i = 0; i < pp->n; i++)
        p_q16[i] = i >= s->m ? s->p_q16[i] : (s->dir > 0 ? s->x_q16 - pp->r_q16[i] : s->x_q16 + pp->r_q16[i]);
}
