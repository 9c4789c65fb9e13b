/* Tests of the compensator (eqs. 4, 5, 9): against a double reference, as the inverse of the
 * direct model, with smoothing limits, and with saturation. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <math.h>
#include <stdlib.h>
#include <cmocka.h>

#include "comp.h"
#include "playop.h"
#include "random_tables.h"

#define Q16(x) ((int32_t)lround((x) * 65536.0))

static fixture_blob_t blob;
static calib_t cal;
static ref_pwl_t rb, rf;

/* A random reference trajectory c*[k] inside f's range, with frequent reversals and holds. */
static double next_c(test_rng_t *r, double c, double *v, double lo, double hi)
{
    double u = test_rng_uniform(r, 0, 1);
    if (u < 0.03)
        *v = test_rng_uniform(r, -0.3, 0.3);
    else if (u < 0.04)
        *v = 0;
    return fmin(fmax(c + *v, lo), hi);
}

static void run_vs_reference(int f_sign, uint64_t seed)
{
    test_rng_t r;
    test_rng_seed(&r, seed);
    for (int trial = 0; trial < 40; trial++) {
        size_t len = random_table_build(&r, &blob, &rb, &rf, f_sign);
        assert_int_equal(calib_load(&cal, blob.bytes, len), CALIB_OK);
        double lo = fmin(rf.y[0], rf.y[rf.n - 1]) + 1, hi = fmax(rf.y[0], rf.y[rf.n - 1]) - 1;
        /* |q* error| <= e_inv (1 + max|B'|/2) + rounding of B/2 and of the sum. */
        double tol = cal.f_inv_err_q16 * (1 + ref_pwl_max_slope(&rb) / 2) + 2.0;
        comp_t cp;
        double c = 0.5 * (lo + hi), v = 0;
        comp_reset(&cp, &cal, NULL, Q16(c));
        ref_comp_t ref = {.b = &rb, .f = &rf, .q_min = -4.5, .q_max = 4.5, .c_prev = Q16(c) / 65536.0};
        for (int k = 0; k < 2000; k++) {
            c = next_c(&r, c, &v, lo, hi);
            int32_t cq = Q16(c);
            double want = ref_comp_step(&ref, cq / 65536.0) * 65536.0;
            int32_t got = comp_step(&cp, cq);
            assert_true(fabs(got - want) <= tol);
        }
    }
}

static void test_vs_reference_eq5(void **state) { (void)state; run_vs_reference(1, 21); }
static void test_vs_reference_eq9(void **state) { (void)state; run_vs_reference(-1, 22); }

/* The inverse model cancels the direct one: playing q*[k] gives back c*[k] once c* has
 * moved, reversals included (the backlash is taken up in the same tick). */
static void run_round_trip(int f_sign, uint64_t seed)
{
    test_rng_t r;
    test_rng_seed(&r, seed);
    for (int trial = 0; trial < 30; trial++) {
        size_t len = random_table_build(&r, &blob, &rb, &rf, f_sign);
        assert_int_equal(calib_load(&cal, blob.bytes, len), CALIB_OK);
        double lo = fmin(rf.y[0], rf.y[rf.n - 1]) + 3, hi = fmax(rf.y[0], rf.y[rf.n - 1]) - 3;
        double tol = 2.0 + ref_pwl_max_slope(&rf) * (cal.f_inv_err_q16 * (1 + ref_pwl_max_slope(&rb) / 2) +
                                                     cal.z_err_q16 + 3.0);
        comp_t cp;
        playop_t p;
        double c = 0.5 * (lo + hi), v = 0.2;
        comp_reset(&cp, &cal, NULL, Q16(c));
        playop_reset(&p, &cal, lut_eval(&cal.f_inv, Q16(c)));
        int moved = 0, reversals = 0, prev_dir = 0;
        for (int k = 0; k < 2000; k++) {
            c = next_c(&r, c, &v, lo, hi);
            int32_t cq = Q16(c);
            int32_t q = comp_step(&cp, cq);
            int32_t got = playop_step(&p, q);
            if (cp.dir != 0) {
                moved = 1;
                reversals += prev_dir != 0 && cp.dir != prev_dir;
                prev_dir = cp.dir;
            }
            if (moved)
                assert_true(fabs((double)got - cq) <= tol);
        }
        assert_true(reversals > 5);
    }
}

static void test_round_trip_increasing(void **state) { (void)state; run_round_trip(1, 31); }
static void test_round_trip_decreasing(void **state) { (void)state; run_round_trip(-1, 32); }

static double b_const(double q, const void *ctx) { (void)q; (void)ctx; return 1.0; }
static double f_lin(double q, const void *ctx) { (void)ctx; return 10.0 * q; }

static void load_simple(void)
{
    fixture_grid_t g = {.q0 = -4, .step_log2 = 14, .n = 33, .q_min = -3, .q_max = 3, .f_kind = PST_F_COARSE};
    size_t len = fixture_build(&blob, &g, b_const, NULL, f_lin, NULL);
    assert_int_equal(calib_load(&cal, blob.bytes, len), CALIB_OK);
}

/* eq. 4 cases on a constant play: +B/2 rising, -B/2 falling, held when c* holds. */
static void test_eq4_cases(void **state)
{
    (void)state;
    load_simple();
    comp_t cp;
    comp_reset(&cp, &cal, NULL, 0);
    assert_int_equal(comp_step(&cp, 0), 0);                          /* no direction yet: centred */
    assert_in_range(comp_step(&cp, Q16(10)), Q16(1.5) - 1, Q16(1.5) + 1);  /* F2inv: 1 + 0.5 */
    assert_in_range(comp_step(&cp, Q16(10)), Q16(1.5) - 1, Q16(1.5) + 1);  /* held */
    assert_in_range(comp_step(&cp, Q16(9)), Q16(0.4) - 1, Q16(0.4) + 1);   /* F1inv: 0.9 - 0.5 */
    /* Saturation to the actuator travel [-3, 3]. */
    assert_int_equal(comp_step(&cp, Q16(-100)), Q16(-3));
    assert_int_equal(comp_step(&cp, Q16(100)), Q16(3));
}

/* Smoothing: the B step becomes a ramp within the velocity and acceleration limits and
 * lands exactly on the unsmoothed value. */
static void test_smoothing_limits(void **state)
{
    (void)state;
    load_simple();
    const uint32_t tick_hz = 1000;
    comp_smoothing_t lim = comp_smoothing_from_rates(Q16(5.0), Q16(200.0), tick_hz); /* 5 units/s, 200 units/s^2 */
    assert_true(lim.v_max_q32 > 0 && lim.a_max_q32 > 0);
    comp_t cp, raw;
    comp_reset(&cp, &cal, &lim, 0);
    comp_reset(&raw, &cal, NULL, 0);
    double c = 0;
    int64_t v_prev = 0;
    int ticks_to_land = -1;
    for (int k = 0; k < 3000; k++) {
        c += (k < 1000) ? 0.001 : -0.001; /* one reversal at k = 1000 */
        int32_t q = comp_step(&cp, Q16(c));
        int32_t q_raw = comp_step(&raw, Q16(c));
        int64_t v = cp.resid_v_q32;
        assert_true(llabs(v) <= lim.v_max_q32);
        if (v != 0)
            assert_true(llabs(v - v_prev) <= lim.a_max_q32);
        v_prev = v;
        if (k > 1000 && ticks_to_land < 0 && q == q_raw && v == 0)
            ticks_to_land = k - 1000;
    }
    /* From +0.5 to -0.5 (1 unit) at 5 units/s with 200 units/s^2: about 0.2 s + 0.025 s. */
    assert_in_range(ticks_to_land, 200, 260);
    assert_int_equal(comp_step(&cp, Q16(c)), comp_step(&raw, Q16(c)));
}

static void test_smoothing_disabled_by_zero_rate(void **state)
{
    (void)state;
    comp_smoothing_t lim = comp_smoothing_from_rates(0, Q16(100), 1000);
    assert_true(lim.v_max_q32 == 0);
    lim = comp_smoothing_from_rates(Q16(1), Q16(1), 0);
    assert_true(lim.v_max_q32 == 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_vs_reference_eq5),
        cmocka_unit_test(test_vs_reference_eq9),
        cmocka_unit_test(test_round_trip_increasing),
        cmocka_unit_test(test_round_trip_decreasing),
        cmocka_unit_test(test_eq4_cases),
        cmocka_unit_test(test_smoothing_limits),
        cmocka_unit_test(test_smoothing_disabled_by_zero_rate),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
