/* Tests of the production control loop (firmware/app/psa_loop.h): the compensation it runs is the
 * core's comp_reset/comp_step bit for bit, modes and table commits behave as documented, the
 * encoder reaches the onset history and commanded reversals reach the onset detector. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include "ps_fixed.h"
#include "ps_table.h"
#include "psa_builtin_table.h"
#include "lut.h"
#include "psa_loop.h"

static union {
    uint32_t align;
    uint8_t bytes[PST_MAX_TABLE_SIZE];
} blob;
static calib_t cal;
static psa_loop_t loop;
static comp_t ref;

static psa_config_t config(bool smooth)
{
    psa_config_t c = {.onset = onset_default_config(), .smooth = smooth};
    c.lim = comp_smoothing_from_rates(200 * PS_Q16_ONE, 20000 * PS_Q16_ONE, 20000);
    c.exc = (exc_config_t){.amplitude_q16 = PS_Q16_ONE, .advance_q16 = PS_Q16_ONE / 4,
                           .v_q32 = (int64_t)(((uint64_t)10 << 32) / 20000), .return_sweep = true};
    return c;
}

static int setup(void **state)
{
    (void)state;
    size_t n = psa_builtin_table(blob.bytes, sizeof blob.bytes);
    assert_true(n > 0);
    assert_int_equal(calib_load(&cal, blob.bytes, n), CALIB_OK);
    return 0;
}

/* c* of a zig-zag with held stretches: reversals, holds and a ramp, deg Q16. */
static int32_t c_of(int k)
{
    int p = k % 400;
    int32_t tri = (p < 200 ? p : 400 - p) * (PS_Q16_ONE / 8) - 12 * PS_Q16_ONE;
    return (k / 50) % 7 == 3 ? (int32_t)(tri & ~0xFFFF) : tri; /* some ticks hold */
}

/* Ticks without a reference hold q* and keep the compensator armed; from the first c* on,
 * psa_tick is comp_reset(c*_0) then comp_step, bit for bit, with and without smoothing. */
static void test_compensation_is_the_core_bit_for_bit(void **state)
{
    (void)state;
    for (int smooth = 0; smooth < 2; smooth++) {
        psa_config_t c = config(smooth);
        psa_init(&loop, &c);
        assert_true(psa_set_table(&loop, &cal));
        assert_true(psa_set_mode(&loop, PSA_MODE_COMPENSATION));
        onset_event_t ev;
        bool ready;
        for (int k = 0; k < 5; k++)
            assert_int_equal(psa_tick(&loop, 50u * (uint32_t)k, PSA_NO_REFERENCE, 0, &ev, &ready), 0);
        assert_true(loop.comp_armed);
        comp_reset(&ref, &cal, smooth ? &c.lim : NULL, c_of(0));
        for (int k = 0; k < 4000; k++) {
            int32_t want = comp_step(&ref, c_of(k));
            int32_t got = psa_tick(&loop, 250u + 50u * (uint32_t)k, c_of(k), want, &ev, &ready);
            assert_int_equal(got, want);
            assert_false(ready);
        }
    }
}

/* A host-driven set-point (PSP_MSG_COMP_STEP) steps at once; the ticks after it hold it. */
static void test_set_reference_then_ticks_hold(void **state)
{
    (void)state;
    psa_config_t c = config(false);
    psa_init(&loop, &c);
    assert_int_equal(psa_set_reference(&loop, PS_Q16_ONE), INT32_MIN); /* idle: refused */
    assert_true(psa_set_table(&loop, &cal));
    assert_true(psa_set_mode(&loop, PSA_MODE_COMPENSATION));
    comp_reset(&ref, &cal, NULL, 5 * PS_Q16_ONE);
    int32_t c_seq[] = {5 * PS_Q16_ONE, 7 * PS_Q16_ONE, 6 * PS_Q16_ONE, -3 * PS_Q16_ONE};
    onset_event_t ev;
    bool ready;
    uint32_t t = 0;
    for (unsigned i = 0; i < sizeof c_seq / sizeof c_seq[0]; i++) {
        int32_t want = comp_step(&ref, c_seq[i]);
        assert_int_equal(psa_set_reference(&loop, c_seq[i]), want);
        for (int k = 0; k < 20; k++)
            assert_int_equal(psa_tick(&loop, t += 50, loop.c_ref_q16, want, &ev, &ready), want);
    }
}

/* Compensation and passthrough need a table; passthrough is f^-1 clamped to the travel;
 * unknown modes are refused and change nothing; dropping the table stops the loop. */
static void test_modes_and_tables(void **state)
{
    (void)state;
    psa_config_t c = config(false);
    psa_init(&loop, &c);
    assert_false(psa_set_mode(&loop, PSA_MODE_COMPENSATION));
    assert_false(psa_set_mode(&loop, PSA_MODE_PASSTHROUGH));
    assert_false(psa_set_mode(&loop, (psa_mode_t)7));
    assert_int_equal(loop.mode, PSA_MODE_IDLE);
    assert_true(psa_set_table(&loop, &cal));
    assert_true(psa_set_mode(&loop, PSA_MODE_PASSTHROUGH));
    onset_event_t ev;
    bool ready;
    int32_t c0 = 20 * PS_Q16_ONE;
    assert_int_equal(psa_tick(&loop, 50, c0, 0, &ev, &ready), lut_eval(&cal.f_inv, c0));
    assert_int_equal(psa_tick(&loop, 100, 2000 * PS_Q16_ONE, 0, &ev, &ready), cal.q_max_q16);
    assert_int_equal(psa_tick(&loop, 150, -2000 * PS_Q16_ONE, 0, &ev, &ready), cal.q_min_q16);
    assert_true(psa_set_table(&loop, NULL));
    assert_int_equal(loop.mode, PSA_MODE_IDLE);
    assert_int_equal(psa_tick(&loop, 200, c0, 0, &ev, &ready), cal.q_min_q16); /* held */
}

/* Excitation: set-points follow exc_step over the table's range, every turning point is a
 * reversal for the onset detector (with no frames the next one supersedes it), a table
 * commit is refused meanwhile, and the loop goes idle when the trajectory ends. */
static void test_excitation_feeds_the_detector(void **state)
{
    (void)state;
    psa_config_t c = config(false);
    psa_init(&loop, &c);
    assert_true(psa_set_table(&loop, &cal));
    assert_true(psa_set_mode(&loop, PSA_MODE_EXCITATION));
    assert_false(psa_set_table(&loop, &cal));
    exc_t e;
    exc_config_t ec = c.exc;
    ec.q_start_q16 = cal.q_min_q16;
    ec.q_end_q16 = cal.q_max_q16;
    assert_int_equal(exc_init(&e, &ec), EXC_OK);
    onset_event_t ev;
    bool ready;
    int reversals = 0, superseded = 0;
    uint32_t t = 0;
    for (int k = 0; k < 40000000 && loop.mode == PSA_MODE_EXCITATION; k++) {
        bool rev;
        int32_t want = exc_step(&e, &rev);
        int32_t q = psa_tick(&loop, t += 50, PSA_NO_REFERENCE, want, &ev, &ready);
        assert_int_equal(q, want);
        reversals += rev;
        if (rev)
            assert_int_equal(loop.onset.t1_us, t);
        if (ready) {
            assert_int_equal(ev.reason, ONSET_ERR_REVERSAL);
            superseded++;
        }
    }
    assert_int_equal(loop.mode, PSA_MODE_IDLE);
    assert_true(reversals > 100);
    assert_int_equal(superseded, reversals - 1);
    /* The encoder samples of every tick went into the history. */
    int32_t qh;
    assert_int_equal(enc_hist_q_at(&loop.onset.hist, t, &qh), ENC_HIST_OK);
    assert_int_equal(qh, loop.q_ref_q16);
}

/* A table committed during compensation (a host refresh during use): the loop
 * carries on bit for bit as the core's compensator that keeps its state and switches table;
 * a re-armed one (no direction known) would step q* by B/2 (checked to differ). */
static calib_t cal2;
static b_online_t bo2;

/* With pacing on, the excitation's speed is the pacing rule's for the detector's frame period
 * (not cfg.exc's), and an invalid frame period or B range refuses the mode, nothing changed. */
static void test_excitation_paced_to_the_camera(void **state)
{
    (void)state;
    psa_config_t c = config(false);
    c.pace = (exc_pace_t){.b_low_q16 = PS_Q16_ONE / 8, .b_high_q16 = PS_Q16_ONE / 2, .tick_hz = 20000u};
    psa_init(&loop, &c);
    assert_true(psa_set_table(&loop, &cal));
    assert_true(psa_set_mode(&loop, PSA_MODE_EXCITATION));
    int64_t v = 0;
    assert_int_equal(exc_pace_speed(c.pace.b_low_q16, c.pace.b_high_q16, c.onset.frame_period_us, 20000u, &v),
                     EXC_OK);
    assert_true(loop.exc.cfg.v_q32 == v);
    assert_true(v != c.exc.v_q32);

    c.onset.frame_period_us = 0; /* no camera rate: refused, still idle */
    psa_init(&loop, &c);
    assert_true(psa_set_table(&loop, &cal));
    assert_false(psa_set_mode(&loop, PSA_MODE_EXCITATION));
    assert_int_equal(loop.mode, PSA_MODE_IDLE);
    c = config(false);
    c.pace = (exc_pace_t){.b_low_q16 = PS_Q16_ONE / 2, .b_high_q16 = PS_Q16_ONE / 8, .tick_hz = 20000u};
    psa_init(&loop, &c);
    assert_true(psa_set_table(&loop, &cal));
    assert_false(psa_set_mode(&loop, PSA_MODE_EXCITATION)); /* b_low > b_high */
    c.pace = (exc_pace_t){.b_low_q16 = PS_Q16_ONE / 8, .b_high_q16 = PS_Q16_ONE, .tick_hz = 20000u};
    psa_init(&loop, &c);
    assert_true(psa_set_table(&loop, &cal));
    assert_false(psa_set_mode(&loop, PSA_MODE_EXCITATION)); /* the 0.75 down leg cannot take up 1 */
    assert_int_equal(loop.mode, PSA_MODE_IDLE);
}

static void test_hot_swap_keeps_the_compensator_state(void **state)
{
    (void)state;
    size_t n = psa_builtin_table(blob.bytes, sizeof blob.bytes);
    assert_int_equal(calib_load(&cal2, blob.bytes, n), CALIB_OK);
    /* the new table: the built-in B learnt 0.2 units wider (b_online on cal2's B) */
    b_online_config_t bc = b_online_default_config();
    assert_int_equal(b_online_init(&bo2, &bc, &cal2.b), B_ONLINE_OK);
    for (int k = 0; k < 64; k++) {
        int32_t q = cal2.q_min_q16 + (int32_t)(((int64_t)(cal2.q_max_q16 - cal2.q_min_q16) * (k % 16)) / 15);
        b_online_sample(&bo2, q, lut_eval(&cal.b, q) + PS_Q16_ONE / 5);
    }
    for (int smooth = 0; smooth < 2; smooth++) {
        psa_config_t c = config(smooth);
        psa_init(&loop, &c);
        assert_true(psa_set_table(&loop, &cal));
        assert_true(psa_set_mode(&loop, PSA_MODE_COMPENSATION));
        onset_event_t ev;
        bool ready;
        comp_reset(&ref, &cal, smooth ? &c.lim : NULL, c_of(0));
        comp_t rearmed;
        int differs = 0;
        for (int k = 0; k < 4000; k++) {
            if (k == 1777) { /* mid-stroke: c* moving, direction known */
                assert_true(psa_set_table(&loop, &cal2));
                assert_false(loop.comp_armed);
                comp_rebind(&ref, &cal2); /* state kept, cached cells of the old table emptied */
                comp_reset(&rearmed, &cal2, smooth ? &c.lim : NULL, c_of(k));
            }
            int32_t want = comp_step(&ref, c_of(k));
            int32_t got = psa_tick(&loop, 50u * (uint32_t)k, c_of(k), want, &ev, &ready);
            assert_int_equal(got, want);
            if (k >= 1777 && k < 1780)
                differs += comp_step(&rearmed, c_of(k)) != want;
        }
        assert_true(differs > 0);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_compensation_is_the_core_bit_for_bit),
        cmocka_unit_test(test_set_reference_then_ticks_hold),
        cmocka_unit_test(test_modes_and_tables),
        cmocka_unit_test(test_excitation_feeds_the_detector),
        cmocka_unit_test(test_excitation_paced_to_the_camera),
        cmocka_unit_test(test_hot_swap_keeps_the_compensator_state),
    };
    return cmocka_run_group_tests(tests, setup, NULL);
}
