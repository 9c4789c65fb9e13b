/* Init-time conversion of the compensator's smoothing limits to per-tick units (divides). */
#include "comp.h"

static int64_t clamp_rate(int64_t r)
{
    const int64_t cap = (int64_t)1 << 31;
    return r < 1 ? 1 : (r > cap ? cap : r);
}

comp_smoothing_t comp_smoothing_from_rates(int32_t v_q16, int32_t a_q16, uint32_t tick_hz)
{
    comp_smoothing_t lim = {0, 0, 0};
    if (v_q16 <= 0 || tick_hz == 0)
        return lim;
    /* units/s (Q16) -> units/tick (Q32): * 2^16 / f;  units/s^2 -> units/tick^2: * 2^16 / f^2. */
    int64_t f = (int64_t)tick_hz;
    lim.v_max_q32 = clamp_rate(((int64_t)v_q16 << 16) / f);
    lim.a_max_q32 = clamp_rate((((int64_t)(a_q16 > 0 ? a_q16 : 0) << 16) / f) / f);
    lim.far_q32 = INT64_MAX / lim.a_max_q32;
    return lim;
}
