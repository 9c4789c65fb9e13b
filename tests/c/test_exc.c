/* Tests of the excitation trajectory: turning points, constant speed, reversals, errors, and the
 * pacing rule that sets the swing speed from the camera's frame period and the expected play. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <cmocka.h>
#include <math.h>

#include "exc.h"

#define Q16(x) ((int32_t)((x) * 65536.0 + ((x) >= 0 ? 0.5 : -0.5)))

static exc_config_t base_cfg(void)
{
    exc_config_t c = {.q_start_q16 = Q16(-2.0), .q_end_q16 = Q16(2.0), .amplitude_q16 = Q16(1.0),
                      .advance_q16 = Q16(0.25), .v_q32 = (int64_t)1 << 26 /* 1/64 unit per tick */,
                      .return_sweep = false};
    return c;
}

static void test_config_errors(void **state)
{
    (void)state;
    exc_t e;
    exc_config_t c = base_cfg();
    c.q_end_q16 = c.q_start_q16;
    assert_int_equal(exc_init(&e, &c), EXC_ERR_RANGE);
    c = base_cfg();
    c.advance_q16 = c.amplitude_q16;
    assert_int_equal(exc_init(&e, &c), EXC_ERR_SHAPE);
    c = base_cfg();
    c.advance_q16 = 0;
    assert_int_equal(exc_init(&e, &c), EXC_ERR_SHAPE);
    c = base_cfg();
    c.v_q32 = 0;
    assert_int_equal(exc_init(&e, &c), EXC_ERR_SPEED);
    c = base_cfg();
    c.v_q32 = (int64_t)Q16(0.3) << 16; /* faster than the shortest segment per tick */
    assert_int_equal(exc_init(&e, &c), EXC_ERR_SPEED);
}

/* Run to the end, collecting turning points; check speed and monotone segments. */
static int run(exc_config_t c, int32_t *turns, int max_turns, int32_t *q_min, int32_t *q_max)
{
    exc_t e;
    assert_int_equal(exc_init(&e, &c), EXC_OK);
    int n = 0;
    int32_t prev = c.q_start_q16;
    *q_min = *q_max = prev;
    for (int k = 0; k < 1000000 && !exc_done(&e); k++) {
        bool rev;
        int32_t q = exc_step(&e, &rev);
        /* At most one tick of travel, never more. */
        assert_true(abs(q - prev) <= (int32_t)(c.v_q32 >> 16) + 1);
        if (q < *q_min) *q_min = q;
        if (q > *q_max) *q_max = q;
        if (rev) {
            assert_true(n < max_turns);
            turns[n++] = q;
        }
        prev = q;
    }
    assert_true(exc_done(&e));
    return n;
}

static void test_forward_sweep_turning_points(void **state)
{
    (void)state;
    int32_t t[64], lo, hi;
    int n = run(base_cfg(), t, 64, &lo, &hi);
    /* Tops at low + 1 and bottoms at low += 0.25 from -2: -1, -1.75, -0.75, -1.5, ... up to the top at 2. */
    assert_int_equal(t[0], Q16(-1.0));
    assert_int_equal(t[1], Q16(-1.75));
    assert_int_equal(t[2], Q16(-0.75));
    assert_int_equal(t[3], Q16(-1.5));
    /* Every back-and-forth pair: top - next bottom = A - advance = 0.75. */
    for (int i = 0; i + 1 < n - 1; i += 2)
        assert_int_equal(t[i] - t[i + 1], Q16(0.75));
    assert_int_equal(lo, Q16(-2.0));
    assert_int_equal(hi, Q16(2.0));
    assert_true(n >= 20);
}

static void test_return_sweep_mirrors(void **state)
{
    (void)state;
    exc_config_t c = base_cfg();
    c.return_sweep = true;
    int32_t t[128], lo, hi;
    int n = run(c, t, 128, &lo, &hi);
    int32_t tf[64];
    int nf = run(base_cfg(), tf, 64, &lo, &hi);
    assert_true(n > nf + 10);
    /* Same turning points up to the top at q_end, which is a reversal only when a return follows. */
    for (int i = 0; i < nf; i++)
        assert_int_equal(t[i], tf[i]);
    assert_int_equal(t[nf], Q16(2.0));
    assert_int_equal(t[nf + 1], Q16(1.0));   /* down by A from the top */
    assert_int_equal(t[nf + 2], Q16(1.75));  /* up to top - advance */
    assert_int_equal(lo, Q16(-2.0));
}

/* The pacing rule against its double-precision statement v = b_low fps / EXC_PACE_FRAMES
 * (units/s), over camera rates 25..240 fps, plays 0.05..2 units and control rates. */
static void test_pace_speed_matches_rule(void **state)
{
    (void)state;
    const double fps[] = {25.0, 30.0, 29.97, 60.0, 240.0};
    const double b[] = {0.05, 0.12, 0.35, 2.0};
    const uint32_t ticks[] = {500u, 1000u, 20000u};
    for (unsigned i = 0; i < sizeof fps / sizeof fps[0]; i++)
        for (unsigned j = 0; j < sizeof b / sizeof b[0]; j++)
            for (unsigned k = 0; k < sizeof ticks / sizeof ticks[0]; k++) {
                uint32_t period_us = (uint32_t)(1e6 / fps[i] + 0.5);
                int32_t b_q16 = Q16(b[j]);
                int64_t v = -1;
                assert_int_equal(exc_pace_speed(b_q16, b_q16 * 2, period_us, ticks[k], &v), EXC_OK);
                double ref = b_q16 / 65536.0 / (EXC_PACE_FRAMES * period_us * 1e-6) / ticks[k] * 4294967296.0;
                assert_true(v <= (int64_t)ceil(ref) && v >= (int64_t)floor(ref) - 1); /* rounded down */
                /* Against the nominal frame rate: the period's rounding to 1 us is all that differs. */
                double v_units_s = (double)v / 4294967296.0 * ticks[k];
                double want = b_q16 / 65536.0 * fps[i] / EXC_PACE_FRAMES; /* the play as given, Q16 */
                assert_true(fabs(v_units_s - want) <= want * (0.5 / period_us + 1e-9) + 2.0 * ticks[k] / 4294967296.0);
            }
}

/* Independent of the formula: on the trajectory itself, after a reversal the set-point needs
 * at least EXC_PACE_FRAMES frame periods (and barely more) to travel b_low. */
static void test_paced_trajectory_takes_up_play_over_frames(void **state)
{
    (void)state;
    const uint32_t tick_hz = 1000u, period_us = 40000u; /* 25 fps */
    const int32_t b_low = Q16(0.12), b_high = Q16(0.30);
    exc_config_t c = {.q_start_q16 = Q16(-1.0), .q_end_q16 = Q16(1.0), .amplitude_q16 = Q16(0.6),
                      .advance_q16 = Q16(0.2), .v_q32 = 0, .return_sweep = false};
    assert_int_equal(exc_pace_config(&c, b_low, b_high, period_us, tick_hz), EXC_OK);
    exc_t e;
    assert_int_equal(exc_init(&e, &c), EXC_OK);
    bool rev = false;
    int32_t q_rev = 0;
    int k = 0;
    for (; k < 100000 && !rev; k++)
        q_rev = exc_step(&e, &rev);
    assert_true(rev);
    int ticks = 0;
    int32_t q = q_rev;
    while (abs(q - q_rev) < b_low) {
        bool r2;
        q = exc_step(&e, &r2);
        ticks++;
    }
    double frames = ticks * (1e6 / tick_hz) / period_us;
    assert_true(frames >= EXC_PACE_FRAMES);
    assert_true(frames <= EXC_PACE_FRAMES * 1.01);
}

static void test_pace_refusals(void **state)
{
    (void)state;
    int64_t v = 12345;
    const int32_t b = Q16(0.2);
    assert_int_equal(exc_pace_speed(0, b, 40000u, 1000u, &v), EXC_ERR_PACE);        /* no play */
    assert_int_equal(exc_pace_speed(-b, b, 40000u, 1000u, &v), EXC_ERR_PACE);
    assert_int_equal(exc_pace_speed(b, b - 1, 40000u, 1000u, &v), EXC_ERR_PACE);    /* high < low */
    assert_int_equal(exc_pace_speed(b, b, 0u, 1000u, &v), EXC_ERR_PACE);            /* no camera */
    assert_int_equal(exc_pace_speed(b, b, 999u, 1000u, &v), EXC_ERR_PACE);          /* > 1000 fps */
    assert_int_equal(exc_pace_speed(b, b, 1000001u, 1000u, &v), EXC_ERR_PACE);      /* < 1 fps */
    assert_int_equal(exc_pace_speed(b, b, 40000u, 0u, &v), EXC_ERR_PACE);           /* no tick */
    assert_int_equal(exc_pace_speed(b, b, 40000u, 1000001u, &v), EXC_ERR_PACE);
    assert_int_equal(exc_pace_speed(1, 1, 1000000u, 1000000u, &v), EXC_ERR_SPEED);  /* below 1 LSB */
    assert_int_equal(exc_pace_speed(INT32_MAX, INT32_MAX, 1000u, 1u, &v), EXC_ERR_SPEED); /* overflow */
    assert_true(v == 12345); /* untouched on every refusal */
    /* Edges accepted. */
    assert_int_equal(exc_pace_speed(b, b, 1000u, 1000000u, &v), EXC_OK);
    assert_int_equal(exc_pace_speed(b, b, 1000000u, 1u, &v), EXC_OK);

    /* The down leg (amplitude - advance) must exceed the widest play; cfg untouched on refusal. */
    exc_config_t c = base_cfg(); /* leg 0.75 */
    exc_config_t before = c;
    assert_int_equal(exc_pace_config(&c, Q16(0.1), Q16(0.75), 40000u, 1000u), EXC_ERR_PACE);
    assert_memory_equal(&c, &before, sizeof c);
    assert_int_equal(exc_pace_config(&c, Q16(0.1), Q16(0.1), 0u, 1000u), EXC_ERR_PACE);
    assert_memory_equal(&c, &before, sizeof c);
    c.q_end_q16 = c.q_start_q16; /* exc_init's own checks still apply */
    assert_int_equal(exc_pace_config(&c, Q16(0.1), Q16(0.5), 40000u, 1000u), EXC_ERR_RANGE);
    c = base_cfg();
    assert_int_equal(exc_pace_config(&c, Q16(0.1), Q16(0.74), 40000u, 1000u), EXC_OK);
    assert_int_equal(exc_pace_speed(Q16(0.1), Q16(0.74), 40000u, 1000u, &v), EXC_OK);
    assert_true(c.v_q32 == v);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_config_errors),
        cmocka_unit_test(test_forward_sweep_turning_points),
        cmocka_unit_test(test_return_sweep_mirrors),
        cmocka_unit_test(test_pace_speed_matches_rule),
        cmocka_unit_test(test_paced_trajectory_takes_up_play_over_frames),
        cmocka_unit_test(test_pace_refusals),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
