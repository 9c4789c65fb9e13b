/* Tests of the direct model (eqs. 2, 3) against the paper's semantics and a double reference. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <math.h>
#include <cmocka.h>

#include "playop.h"
#include "random_tables.h"

#define Q16(x) ((int32_t)lround((x) * 65536.0))

static fixture_blob_t blob;
static calib_t cal;
static ref_pwl_t rb, rf;

static double b_const(double q, const void *ctx) { (void)q; (void)ctx; return 1.0; }
static double f_lin(double q, const void *ctx) { (void)ctx; return 10.0 * q; }

/* Constant B = 1, f = 10 q: the textbook play. After a reversal c holds for exactly B of
 * travel, then follows the other envelope f1/f2 = f(q -+ B/2) (eq. 2). */
static void test_constant_play_semantics(void **state)
{
    (void)state;
    fixture_grid_t g = {.q0 = -4, .step_log2 = 14, .n = 33, .q_min = -4, .q_max = 4, .f_kind = PST_F_COARSE};
    size_t len = fixture_build(&blob, &g, b_const, NULL, f_lin, NULL);
    assert_int_equal(calib_load(&cal, blob.bytes, len), CALIB_OK);
    playop_t p;
    playop_reset(&p, &cal, 0);
    int32_t c = 0;
    for (double q = 0; q <= 2.0 + 1e-9; q += 0.01)
        c = playop_step(&p, Q16(q));
    assert_in_range(c, Q16(15.0) - 2, Q16(15.0) + 2); /* f2(2) = f(2 - 0.5) */
    for (double q = 2.0; q >= 1.0 + 1e-9; q -= 0.01)
        assert_in_range(playop_step(&p, Q16(q)), Q16(15.0) - 2, Q16(15.0) + 2); /* dead band */
    c = playop_step(&p, Q16(0.5));
    assert_in_range(c, Q16(10.0) - 2, Q16(10.0) + 2); /* f1(0.5) = f(0.5 + 0.5) */
    /* Inside the band nothing moves, in either direction. */
    for (int k = 0; k < 50; k++)
        assert_int_equal(playop_step(&p, Q16(0.5 + 0.019 * (k % 7))), c);
}

/* Property: on random tables and random trajectories, within the documented bound of the
 * exact operator. The clamp is non-expansive, so the error does not accumulate. */
static void run_property(int f_sign, uint64_t seed)
{
    test_rng_t r;
    test_rng_seed(&r, seed);
    for (int trial = 0; trial < 40; trial++) {
        size_t len = random_table_build(&r, &blob, &rb, &rf, f_sign);
        assert_int_equal(calib_load(&cal, blob.bytes, len), CALIB_OK);
        double lip = 1.0 / (1.0 - ref_pwl_max_slope(&rb) / 2.0);
        double tol_z = cal.z_err_q16 + 0.5 * lip + 1.0;                 /* raw units */
        double tol_c = 0.5 + ref_pwl_max_slope(&rf) * tol_z + 1.0;      /* raw units */
        playop_t p;
        ref_play_t ref = {.b = &rb, .f = &rf, .z = 0.0};
        playop_reset(&p, &cal, 0);
        double q = 0, v = 0;
        double worst = 0;
        for (int k = 0; k < 3000; k++) {
            if (test_rng_uniform(&r, 0, 1) < 0.02)
                v = test_rng_uniform(&r, -0.03, 0.03); /* new speed, often a reversal */
            q = fmin(fmax(q + v, -3.0), 3.0);
            int32_t qq = Q16(q);
            double want = ref_play_step(&ref, qq / 65536.0) * 65536.0;
            double got = playop_step(&p, qq);
            worst = fmax(worst, fabs(got - want));
            assert_true(fabs(got - want) <= tol_c);
            assert_true(fabs(p.z_q16 - ref.z * 65536.0) <= tol_z);
        }
        (void)worst;
    }
}

static void test_property_increasing_f(void **state) { (void)state; run_property(1, 11); }
static void test_property_decreasing_f(void **state) { (void)state; run_property(-1, 12); }


/* With the transition (table v2, 1..16 operators): z from the play, y = PI[z], c = f(y),
 * against the same chain in double (ref_play_step, ref_pi_step). The PI is W-Lipschitz in
 * the sup norm of its input (W = sum w_i), so |y error| <= W tol_z + 1/2 and
 * |c error| <= 1/2 + |f'| |y error| + 1 raw (measured worst: 0.22 of that here, 0.56 over
 * 30 tables per sign). 15 tables per sign: the double reference's bisection is slow in
 * software on the M4 (tests/target). */
static void run_transition_property(int f_sign, uint64_t seed)
{
    test_rng_t r;
    test_rng_seed(&r, seed);
    double ratio = 0;
    for (int trial = 0; trial < 15; trial++) {
        random_table_build(&r, &blob, &rb, &rf, f_sign);
        int n = 1 + (int)(test_rng_u64(&r) % PST_MAX_OPS);
        int32_t rq[PST_MAX_OPS], wq[PST_MAX_OPS];
        ref_pi_t rpi;
        random_pi_build(&r, n, test_rng_uniform(&r, 0.05, 1.5), 0.05, 256, rq, wq, &rpi);
        size_t len = fixture_with_ops(&blob, 0, (uint16_t)n, rq, wq);
        assert_int_equal(calib_load(&cal, blob.bytes, len), CALIB_OK);
        double W = 0;
        for (int i = 0; i < n; i++)
            W += rpi.w[i];
        double lip = 1.0 / (1.0 - ref_pwl_max_slope(&rb) / 2.0);
        double tol_z = cal.z_err_q16 + 0.5 * lip + 1.0;
        double tol_y = W * tol_z + 0.5;
        double tol_c = 0.5 + ref_pwl_max_slope(&rf) * tol_y + 1.0;
        playop_t p;
        ref_play_t ref = {.b = &rb, .f = &rf, .z = 0.0};
        playop_reset(&p, &cal, 0);
        ref_pi_reset(&rpi, 0.0);
        double q = 0, v = 0;
        for (int k = 0; k < 3000; k++) {
            if (test_rng_uniform(&r, 0, 1) < 0.02)
                v = test_rng_uniform(&r, -0.03, 0.03);
            q = fmin(fmax(q + v, -3.0), 3.0);
            int32_t qq = Q16(q);
            (void)ref_play_step(&ref, qq / 65536.0);
            double y = ref_pi_step(&rpi, ref.z);
            double want = ref_pwl_eval(&rf, y) * 65536.0;
            double got = playop_step(&p, qq);
            ratio = fmax(ratio, fabs(got - want) / tol_c);
            assert_true(fabs(got - want) <= tol_c);
            assert_true(fabs(p.pi.y_q16 - y * 65536.0) <= tol_y);
        }
    }
    assert_true(ratio > 0.01);
}

static void test_transition_increasing_f(void **state) { (void)state; run_transition_property(1, 13); }
static void test_transition_decreasing_f(void **state) { (void)state; run_transition_property(-1, 14); }

/* The transition rounds the play's corner: after a reversal c holds for B, then starts at
 * slope w_0 f' and reaches full slope W f' once the play has travelled 2 r_{n-1} more. */
static void test_transition_shape(void **state)
{
    (void)state;
    fixture_grid_t g = {.q0 = -4, .step_log2 = 14, .n = 33, .q_min = -4, .q_max = 4, .f_kind = PST_F_COARSE};
    fixture_build(&blob, &g, b_const, NULL, f_lin, NULL);
    const int32_t rq[2] = {0, Q16(0.25)}, wq[2] = {Q16(0.5), Q16(0.5)};
    size_t len = fixture_with_ops(&blob, 0, 2, rq, wq);
    assert_int_equal(calib_load(&cal, blob.bytes, len), CALIB_OK);
    /* Raw tolerance: f' = 10 times the envelope tables' error on z, + rounding. */
    const int32_t tol = 10 * (cal.z_err_q16 + 1) + 2;
    playop_t p;
    playop_reset(&p, &cal, 0);
    for (double q = 0; q <= 2.0 + 1e-9; q += 0.01)
        (void)playop_step(&p, Q16(q));
    /* Going up long enough: y = z - 0.125 (the second operator lags by r_1 with weight 1/2). */
    int32_t c_top = playop_step(&p, Q16(2.0));
    assert_in_range(c_top, Q16(10 * (1.5 - 0.125)) - tol, Q16(10 * (1.5 - 0.125)) + tol);
    /* Down by B = 1: the play's dead band, nothing moves. */
    assert_int_equal(playop_step(&p, Q16(1.0)), c_top);
    /* Down 0.2 more (z moves 0.2, the second operator not yet, r_1 = 0.25 on each side):
     * slope w_0 = 1/2, so c falls by 10 * 0.5 * 0.2 = 1 deg. */
    assert_in_range(playop_step(&p, Q16(0.8)), c_top - Q16(1.0) - tol, c_top - Q16(1.0) + tol);
    /* Down 0.6 more: the second operator engaged after 0.5 of z travel: c falls by
     * 10 * (0.5 * 0.8 + 0.5 * 0.3) = 5.5 deg from c_top. */
    assert_in_range(playop_step(&p, Q16(0.2)), c_top - Q16(5.5) - tol, c_top - Q16(5.5) + tol);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_constant_play_semantics),
        cmocka_unit_test(test_property_increasing_f),
        cmocka_unit_test(test_property_decreasing_f),
        cmocka_unit_test(test_transition_increasing_f),
        cmocka_unit_test(test_transition_decreasing_f),
        cmocka_unit_test(test_transition_shape),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
