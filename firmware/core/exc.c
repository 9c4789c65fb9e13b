/* Excitation trajectory (section III-B): back-and-forth on a ramp, one set-point per tick. */
#include "exc.h"

#define Q32(x_q16) ((int64_t)(x_q16) * 65536) /* not << : x may be negative */

static int64_t min64(int64_t a, int64_t b) { return a < b ? a : b; }
static int64_t max64(int64_t a, int64_t b) { return a > b ? a : b; }

exc_status_t exc_init(exc_t *e, const exc_config_t *cfg)
{
    if (cfg->q_end_q16 <= cfg->q_start_q16)
        return EXC_ERR_RANGE;
    if (!(cfg->advance_q16 > 0 && cfg->amplitude_q16 > cfg->advance_q16))
        return EXC_ERR_SHAPE;
    /* One tick must not jump over a whole segment (the shortest is min(advance, A - advance)). */
    int64_t shortest = min64(Q32(cfg->advance_q16), Q32(cfg->amplitude_q16) - Q32(cfg->advance_q16));
    if (cfg->v_q32 <= 0 || cfg->v_q32 >= shortest)
        return EXC_ERR_SPEED;
    e->cfg = *cfg;
    e->q_q32 = Q32(cfg->q_start_q16);
    e->base_q32 = e->q_q32;
    e->dir = 1;
    e->sweep = 1;
    e->target_q32 = min64(e->base_q32 + Q32(cfg->amplitude_q16), Q32(cfg->q_end_q16));
    return EXC_OK;
}

/* At a turning point: choose the next one. Forward sweep: tops at min(low + A, q_end),
 * bottoms at low += advance; the top at q_end ends it. Return sweep mirrors it with
 * base = high, ending at q_start. Returns false when the trajectory is over. */
static bool next_turn(exc_t *e)
{
    const int64_t amp = Q32(e->cfg.amplitude_q16), adv = Q32(e->cfg.advance_q16);
    const int64_t qs = Q32(e->cfg.q_start_q16), qe = Q32(e->cfg.q_end_q16);
    if (e->sweep > 0) {
        if (e->dir > 0 && e->target_q32 == qe) {
            if (!e->cfg.return_sweep)
                return false;
            e->sweep = -1;
            e->base_q32 = qe;
            e->dir = -1;
            e->target_q32 = max64(qe - amp, qs);
        } else if (e->dir > 0) {
            e->dir = -1;
            e->base_q32 += adv;
            e->target_q32 = e->base_q32;
        } else {
            e->dir = 1;
            e->target_q32 = min64(e->base_q32 + amp, qe);
        }
    } else {
        if (e->dir < 0 && e->target_q32 == qs)
            return false;
        if (e->dir < 0) {
            e->dir = 1;
            e->base_q32 -= adv;
            e->target_q32 = e->base_q32;
        } else {
            e->dir = -1;
            e->target_q32 = max64(e->base_q32 - amp, qs);
        }
    }
    return true;
}

int32_t exc_step(exc_t *e, bool *reversal)
{
    *reversal = false;
    if (e->dir != 0) {
        e->q_q32 += e->dir > 0 ? e->cfg.v_q32 : -e->cfg.v_q32;
        bool reached = e->dir > 0 ? e->q_q32 >= e->target_q32 : e->q_q32 <= e->target_q32;
        if (reached) {
            e->q_q32 = e->target_q32;
            if (next_turn(e))
                *reversal = true;
            else
                e->dir = 0;
        }
    }
    /* Round to Q16. */
    return (int32_t)((e->q_q32 + (1 << 15)) >> 16);
}

bool exc_done(const exc_t *e)
{
    return e->dir == 0;
}
