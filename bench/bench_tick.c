/* Built-in demonstration table and the per-tick control chain used by the demo image and the benches. */
#include "bench_tick.h"

#include <string.h>

#include "ps_fixed.h"
#include "ps_table.h"
#include "table_write.h"

enum {
    DEMO_N = 33,                 /* grid entries, q = -16 .. +16 mm */
    DEMO_X0_Q16 = -16 * PS_Q16_ONE,
    DEMO_STEP_Q16 = PS_Q16_ONE,  /* 1 mm, a power of two in raw units */
    DEMO_C_AMPL_Q16 = 30 * PS_Q16_ONE, /* reference triangle +-30 deg ... */
    DEMO_C_PERIOD_MS = 2000,     /* ... with a 2 s period */
};

/* The table blob, 4-aligned because calib_load reads the entries in place. */
static union {
    uint32_t align;
    uint8_t bytes[PST_MAX_TABLE_SIZE];
} demo_table;
static size_t demo_table_size;

/* B(q) = 1.5 mm + 0.02 q (|B'| well below 2), f(q) = 3 deg/mm q + 0.04 q^2 (f' >= 1.7 > 0
 * on the grid, so strictly increasing): small, plausible, and exercises both tables. */
static void demo_table_build(void)
{
    int32_t b_q16[DEMO_N], f_q16[DEMO_N];
    for (int i = 0; i < DEMO_N; i++) {
        int32_t q_mm = i - 16;
        b_q16[i] = 3 * PS_Q16_ONE / 2 + q_mm * (PS_Q16_ONE / 50);
        f_q16[i] = 3 * q_mm * PS_Q16_ONE + q_mm * q_mm * (PS_Q16_ONE / 25);
    }
    pst_header_t h;
    memset(&h, 0, sizeof h);
    h.generation = 1;
    h.q_unit = PST_Q_UNIT_MM;
    h.f_kind = PST_F_COARSE;
    h.q_min_q16 = DEMO_X0_Q16;
    h.q_max_q16 = DEMO_X0_Q16 + (DEMO_N - 1) * DEMO_STEP_Q16;
    h.b = (pst_grid_t){.x0_q16 = DEMO_X0_Q16, .step_q16 = DEMO_STEP_Q16, .n = DEMO_N};
    h.f = h.b;
    demo_table_size = table_write(demo_table.bytes, sizeof demo_table.bytes, &h, b_q16, f_q16, NULL, NULL);
}

int ctl_loop_init(ctl_loop_t *l, uint32_t tick_hz)
{
    demo_table_build();
    calib_status_t st = calib_load(&l->cal, demo_table.bytes, demo_table_size);
    if (st != CALIB_OK) {
        return (int)st;
    }
    onset_config_t oc = onset_default_config();
    onset_init(&l->onset, &oc);
    /* Offset ramp limited to 200 mm/s and 20000 mm/s^2: a 1.5 mm step takes ~17 ms. */
    comp_smoothing_t lim = comp_smoothing_from_rates(200 * PS_Q16_ONE, 20000 * PS_Q16_ONE, tick_hz);
    comp_reset(&l->comp, &l->cal, &lim, 0);
    l->c_ref_q16 = 0;
    /* 4 amplitudes per period: step = 4 A / (period * tick_hz); computed once, here. */
    uint32_t ticks_per_period = tick_hz / 1000u * DEMO_C_PERIOD_MS;  /* tick_hz: whole kHz */
    l->c_step_q16 = (int32_t)(4u * (uint32_t)DEMO_C_AMPL_Q16 / ticks_per_period);
    l->q_meas_q16 = 0;
    l->reversals = 0;
    l->onset_events = 0;
    return CALIB_OK;
}

int32_t ctl_loop_tick(ctl_loop_t *l, uint32_t t_us)
{
    onset_event_t ev;
    if (onset_tick(&l->onset, t_us, l->q_meas_q16, &ev)) {
        l->onset_events++;
    }
    int32_t c_next = l->c_ref_q16 + l->c_step_q16;
    if (c_next > DEMO_C_AMPL_Q16 || c_next < -DEMO_C_AMPL_Q16) {
        /* A commanded reversal, as the excitation would report it to the onset detector. */
        l->c_step_q16 = -l->c_step_q16;
        c_next = l->c_ref_q16 + l->c_step_q16;
        l->reversals++;
        if (onset_reversal(&l->onset, t_us, l->q_meas_q16, &ev)) {
            l->onset_events++;
        }
    }
    l->c_ref_q16 = c_next;
    int32_t q_ref_q16 = comp_step(&l->comp, c_next);
    l->q_meas_q16 = q_ref_q16;
    return q_ref_q16;
}
