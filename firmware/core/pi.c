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
    uint32_t sh = pp->w_frac;
    s->c = pp->n ? c + ((int64_t)1 << (sh - 1)) : 0;
    s->a = 0;
    s->x_q16 = x;
    s->dir = 0;
    s->m = 0;
    s->next_q16 = x;
    if (pp->n == 0) {
        s->y_q16 = x0_q16;
        return;
    }
    s->y_q16 = (int32_t)(s->c >> sh);
}

void pi_advance(pi_state_t *s, const pi_params_t *pp, int32_t x_q16, int8_t dir)
{
    uint32_t m = s->m;
    const uint32_t n = pp->n;
    int64_t c = s->c;
    int32_t a = s->a;
    if (dir != s->dir) {
        /* Reversal: the engaged operators stop where the last input left them,
         * p_i = x[k-1] - dir_old * r_i, and their share a * x[k-1] becomes constant. */
        const int32_t xp = s->x_q16;
        if (s->dir > 0)
            for (uint32_t i = 0; i < m; i++)
                s->p_q16[i] = xp - pp->r_q16[i];
        else
            for (uint32_t i = 0; i < m; i++)
                s->p_q16[i] = xp + pp->r_q16[i];
        c += (int64_t)a * xp;
        a = 0;
        m = 0;
        s->dir = dir;
    }
    /* Engage operators in threshold order while the input has reached their level
     * e_m = p_m + dir * r_m: from then on p_m = x - dir * r_m, so w_m p_m leaves c and
     * w_m joins a, with c -= w_m * e_m keeping the sum exact. e fits int32: pi_build keeps
     * every input range +- 2 r within +-2^30, and p within the input range +- r. */
    int32_t e = 0;
    if (dir > 0) {
        for (; m < n; m++) {
            e = s->p_q16[m] + pp->r_q16[m];
            if (x_q16 < e)
                break;
            a -= pp->w_neg[m];
            c += (int64_t)pp->w_neg[m] * e;
        }
    } else {
        for (; m < n; m++) {
            e = s->p_q16[m] - pp->r_q16[m];
            if (x_q16 > e)
                break;
            a -= pp->w_neg[m];
            c += (int64_t)pp->w_neg[m] * e;
        }
    }
    s->c = c;
    s->a = a;
    s->m = (uint8_t)m;
    s->next_q16 = m < n ? e : (dir > 0 ? INT32_MAX : INT32_MIN);
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
