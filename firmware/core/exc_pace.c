/* Excitation pacing (section III-B, section V-D): the swing speed that lets the camera see the
 * play taken up over EXC_PACE_FRAMES frames. Configuration time only, never in the tick, so
 * it may divide in 64 bits (kept out of the per-tick exc.c, which check-tick-objects.sh holds
 * to hardware divides only). */
#include "exc.h"

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
