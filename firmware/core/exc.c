/* Excitation trajectory (section III-B): back-and-forth on a ramp, one set-point per tick. */
#include "exc.h"

#define Q32(x_q16) ((int64_t)(x_q16) * 65536) /* not << : x may be negative */

static int64_t min64(int64_t a, int64_t b) { return a < b ? a : b; }
static int64_t max64(int64_t a, int64_t b) { return a > b ? a : b; }

exc_status_t exc_pace_speed(int32_t b_low_q16, int32_t b_high_q16, uint32_t frame_period_us,
                            uint32_t tick_hz, int64_t *v_q32)
{
    if (b_low_q16 <= 0 || b_high_q16 < b_low_q16 || frame_period_us < 1000u || frame_period_us > 1000000u ||
        tick_hz == 0u || tick_hz > 1000000u)
        return EXC_ERR_PACE;
    /* v_q32 = b_low_q16 * 2^16 * 1e6 / (PACE * period_us * tick_hz). num < 2^51 and den < 2^42,
     * so the quotient and the remainder's scaled part each fit 64 bits. */
    const uint64_t num = (uint64_t)b_low_q16 * 1000000u;
    const uint64_t den = (uint64_t)EXC_PACE_FRAMES * frame_period_us * tick_hz;
    const uint64_t whole = num / den, rem = num % den;
    if (whole >= ((uint64_t)1 << 30))
        return EXC_ERR_SPEED; /* more than 2^14 units per tick: no trajectory takes that */
    const uint64_t v = (whole << 16) + (rem << 16) / den;
    if (v == 0u)
        return EXC_ERR_SPEED;
    *v_q32 = (int64_t)v;
    return EXC_OK;
}

exc_status_t exc_pace_config(exc_config_t *cfg, int32_t b_low_q16, int32_t b_high_q16,
                             uint32_t frame_period_us, uint32_t tick_hz)
{
    int64_t v_q32;
    exc_status_t st = exc_pace_speed(b_low_q16, b_high_q16, frame_period_us, tick_hz, &v_q32);
    if (st != EXC_OK)
        return st;
    exc_config_t c = *cfg;
    c.v_q32 = v_q32;
    exc_t probe;
    st = exc_init(&probe, &c);
    if (st != EXC_OK)
        return st;
    if ((int64_t)c.amplitude_q16 - c.advance_q16 <= b_high_q16)
        return EXC_ERR_PACE; /* the down leg would not take up the widest play */
    *cfg = c;
    return EXC_OK;
}

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
