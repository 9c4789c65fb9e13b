/* Tests of lut.c / lut_build.c against double-precision interpolation and exact inverses. */
#include <setjmp.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <math.h>
#include <string.h>
#include <cmocka.h>

#include "lut.h"
#include "ref_model.h"
#include "test_rng.h"

#define N_MAX 256

static double ref_interp_raw(const int32_t *y, int n, int32_t x0, int s, int32_t x)
{
    ref_pwl_t p;
    p.x0 = x0;
    p.h = (double)(1 << s);
    p.n = n;
    for (int i = 0; i < n; i++)
        p.y[i] = y[i];
    return ref_pwl_eval(&p, (double)x);
}

static void test_init_errors(void **state)
{
    (void)state;
    int32_t y[4] = {0, 1, 2, 3};
    lut_t l;
    assert_int_equal(lut_init(&l, y, 1, 0, 65536), LUT_ERR_SIZE);
    assert_int_equal(lut_init(&l, y, 4, 0, 3), LUT_ERR_STEP);
    assert_int_equal(lut_init(&l, y, 4, 0, 1), LUT_ERR_STEP); /* 1 raw unit: below the 2-unit minimum */
    assert_int_equal(lut_init(&l, y, 4, 0, 0), LUT_ERR_STEP);
    assert_int_equal(lut_init(&l, y, 4, 0, -4), LUT_ERR_STEP);
    assert_int_equal(lut_init(&l, y, 4, 0, 1 << 25), LUT_ERR_STEP);
    assert_int_equal(lut_init(&l, y, 4, INT32_MAX - 10, 1 << 4), LUT_ERR_RANGE);
    assert_int_equal(lut_init(&l, y, 4, -5 * 65536, 1 << 16), LUT_OK);
    assert_int_equal(l.step_log2, 16);
    assert_int_equal(l.x_last_q16, -2 * 65536);
}

/* Property: within 1/2 LSB of exact linear interpolation of the entries, any grid. */
static void test_eval_matches_double_interpolation(void **state)
{
    (void)state;
    test_rng_t r;
    test_rng_seed(&r, 1);
    static int32_t y[N_MAX];
    for (int trial = 0; trial < 200; trial++) {
        int n = 2 + (int)(test_rng_u64(&r) % (N_MAX - 1));
        int s = 1 + (int)(test_rng_u64(&r) % 20);
        int32_t x0 = (int32_t)test_rng_uniform(&r, -1e9, 1e9 - (double)n * (1 << s));
        for (int i = 0; i < n; i++)
            y[i] = (int32_t)test_rng_uniform(&r, -1e9, 1e9);
        lut_t l;
        assert_int_equal(lut_init(&l, y, (uint16_t)n, x0, 1 << s), LUT_OK);
        for (int k = 0; k < 200; k++) {
            int32_t x = (int32_t)test_rng_uniform(&r, x0 - 1000.0, x0 + (double)n * (1 << s) + 1000.0);
            double want = ref_interp_raw(y, n, x0, s, x);
            double got = lut_eval(&l, x);
            assert_true(fabs(got - want) <= 0.5 + 1e-6);
        }
    }
}

static void test_eval_saturates_and_hits_entries(void **state)
{
    (void)state;
    int32_t y[3] = {100, -50, 7};
    lut_t l;
    assert_int_equal(lut_init(&l, y, 3, -65536, 65536), LUT_OK);
    assert_int_equal(lut_eval(&l, INT32_MIN), 100);
    assert_int_equal(lut_eval(&l, INT32_MAX), 7);
    assert_int_equal(lut_eval(&l, -65536), 100);
    assert_int_equal(lut_eval(&l, 0), -50);
    assert_int_equal(lut_eval(&l, 65536), 7);
    assert_int_equal(lut_eval(&l, -32768), 25); /* halfway between 100 and -50 */
}

/* lut_eval_cell equals lut_eval bit for bit along walks that creep (hits), cross cells,
 * jump, sit on x0 and x_last and leave the grid, on tables whose cells are partly too steep
 * for the 32-bit hit (|dy| >= 2^(31-s): never cached) and partly not; every step of the
 * shifts 1..24 is covered. Also checks the cache is used: a creeping walk on gentle cells
 * mostly hits, and a steep cell is never held. */
static void test_eval_cell_equals_eval(void **state)
{
    (void)state;
    test_rng_t r;
    test_rng_seed(&r, 11);
    static int32_t y[N_MAX];
    uint64_t hits = 0, calls = 0;
    for (int trial = 0; trial < 400; trial++) {
        int n = 2 + (int)(test_rng_u64(&r) % (N_MAX - 1));
        int s = 1 + trial % 24;
        double span = (double)(n - 1) * (double)(1 << s);
        int32_t x0 = (int32_t)test_rng_uniform(&r, -1.5e9, 1.5e9 - span);
        /* gentle slopes (cacheable) and, on a third of the tables, a steep cell here and there */
        double lim = ldexp(1.0, 31 - s);
        y[0] = (int32_t)test_rng_uniform(&r, -1e8, 1e8);
        for (int i = 1; i < n; i++) {
            double d = (trial % 3 == 0 && test_rng_u64(&r) % 5 == 0)
                           ? test_rng_uniform(&r, lim, fmin(2.0 * lim, 1e9)) * ((test_rng_u64(&r) & 1) ? 1 : -1)
                           : test_rng_uniform(&r, -0.9 * lim, 0.9 * lim);
            double v = (double)y[i - 1] + d;
            if (v > 2e9 || v < -2e9)
                v = (double)y[i - 1] - d;
            y[i] = (int32_t)v;
        }
        lut_t l;
        assert_int_equal(lut_init(&l, y, (uint16_t)n, x0, 1 << s), LUT_OK);
        lut_cell_t cell;
        memset(&cell, 0, sizeof cell);
        double x = x0 + test_rng_uniform(&r, 0.0, span);
        for (int k = 0; k < 600; k++) {
            int32_t xi;
            bool creep = false;
            switch (test_rng_u64(&r) % 16) {
            case 0: xi = l.x0_q16; break;
            case 1: xi = l.x_last_q16; break;
            case 2: xi = (int32_t)test_rng_uniform(&r, x0 - 4.0 * (1 << s), x0 + span + 4.0 * (1 << s)); break;
            case 3: xi = (test_rng_u64(&r) & 1) ? INT32_MIN : INT32_MAX; break;
            default: /* creep a fraction of a cell, as a 20 kHz reference does */
                x += test_rng_uniform(&r, -0.2, 0.2) * (1 << s);
                x = fmax(x0 - 2.0 * (1 << s), fmin(x0 + span + 2.0 * (1 << s), x));
                xi = (int32_t)fmax(INT32_MIN, fmin(INT32_MAX, x));
                creep = trial % 3 != 0 && x >= x0 && x < x0 + span;
            }
            int32_t want = lut_eval(&l, xi);
            if (creep) { /* gentle table, inside the grid */
                hits += (uint32_t)xi - (uint32_t)cell.x_lo_q16 < cell.width;
                calls++;
            }
            assert_int_equal(lut_eval_cell(&l, &cell, xi), want);
            if (cell.width != 0) { /* a held cell is a gentle one of this grid */
                assert_int_equal(cell.width, 1u << s);
                assert_true(cell.x_lo_q16 >= l.x0_q16 && cell.x_lo_q16 < l.x_last_q16);
                assert_int_equal(((uint32_t)cell.x_lo_q16 - (uint32_t)l.x0_q16) & (cell.width - 1u), 0);
                assert_true(fabs((double)cell.dy_q16) < lim);
            }
        }
    }
    /* creeping 0.1 cell per call on average inside a gentle table: most calls hit (a quarter
     * of the calls before them jump; measured 0.78) */
    assert_true((double)hits / (double)calls > 0.6);
}

/* Property: the built inverse stays within its own reported bound of the exact inverse,
 * and the bound is not loose by more than the rounding it adds. */
static void check_inverse(test_rng_t *r, int increasing)
{
    static int32_t g[N_MAX], inv[512];
    int n = 2 + (int)(test_rng_u64(r) % 200);
    int s = 8 + (int)(test_rng_u64(r) % 10);
    int32_t x0 = (int32_t)test_rng_uniform(r, -5e6, 5e6);
    double acc = test_rng_uniform(r, -1e6, 1e6);
    for (int i = 0; i < n; i++) {
        g[increasing ? i : n - 1 - i] = (int32_t)acc;
        acc += 1.0 + test_rng_uniform(r, 0, 1) * test_rng_uniform(r, 0, 3e5); /* strictly increasing */
    }
    lut_t src, out;
    assert_int_equal(lut_init(&src, g, (uint16_t)n, x0, 1 << s), LUT_OK);
    uint16_t cap = (uint16_t)(8 + test_rng_u64(r) % 505);
    int32_t err = -1;
    assert_int_equal(lut_build_inverse(&src, inv, cap, &out, &err), LUT_OK);
    assert_true(out.n <= cap);
    assert_true(err >= 1);
    ref_pwl_t p = {.x0 = x0, .h = (double)(1 << s), .n = n};
    for (int i = 0; i < n; i++)
        p.y[i] = g[i];
    double worst = 0;
    for (int k = 0; k < 2000; k++) {
        double yv = test_rng_uniform(r, fmin(g[0], g[n - 1]), fmax(g[0], g[n - 1]));
        int32_t yq = (int32_t)yv;
        double e = fabs(lut_eval(&out, yq) - ref_pwl_inverse(&p, yq));
        worst = fmax(worst, e);
        assert_true(e <= err + 1e-6);
    }
    for (int i = 0; i < n; i++) /* at breakpoints the bound is attained or nearly */
        worst = fmax(worst, fabs(lut_eval(&out, g[i]) - ref_pwl_inverse(&p, g[i])));
    assert_true(worst >= err - 1.5);
}

static void test_inverse_property(void **state)
{
    (void)state;
    test_rng_t r;
    test_rng_seed(&r, 2);
    for (int trial = 0; trial < 150; trial++)
        check_inverse(&r, trial & 1);
}

static void test_inverse_exact_for_linear(void **state)
{
    (void)state;
    /* g(x) = 2x on a grid of step 1.0: the inverse x = y/2 is linear, so the table is exact. */
    int32_t g[11], inv[64];
    for (int i = 0; i < 11; i++)
        g[i] = 2 * 65536 * i;
    lut_t src, out;
    int32_t err;
    assert_int_equal(lut_init(&src, g, 11, 0, 65536), LUT_OK);
    assert_int_equal(lut_build_inverse(&src, inv, 64, &out, &err), LUT_OK);
    assert_true(err <= 1);
    assert_int_equal(lut_eval(&out, 3 * 65536), 98304); /* 1.5 */
    assert_int_equal(lut_eval(&out, -65536), 0);        /* saturated */
    assert_int_equal(lut_eval(&out, 100 * 65536), 10 * 65536);
}

static void test_inverse_refuses_non_monotone(void **state)
{
    (void)state;
    int32_t g_flat[4] = {0, 10, 10, 20};
    int32_t g_bump[4] = {0, 10, 5, 20};
    int32_t inv[16];
    for (int i = 0; i < 16; i++)
        inv[i] = 0x5A5A5A5A;
    lut_t src, out;
    memset(&out, 0xA5, sizeof out);
    lut_t before = out;
    int32_t err = 42;
    assert_int_equal(lut_init(&src, g_flat, 4, 0, 65536), LUT_OK);
    assert_int_equal(lut_build_inverse(&src, inv, 16, &out, &err), LUT_ERR_NOT_MONOTONE);
    assert_int_equal(lut_check_inverse(&src, 16), LUT_ERR_NOT_MONOTONE);
    assert_int_equal(lut_init(&src, g_bump, 4, 0, 65536), LUT_OK);
    assert_int_equal(lut_build_inverse(&src, inv, 16, &out, &err), LUT_ERR_NOT_MONOTONE);
    /* Nothing written on refusal. */
    assert_memory_equal(&out, &before, sizeof out);
    assert_int_equal(err, 42);
    for (int i = 0; i < 16; i++)
        assert_int_equal(inv[i], 0x5A5A5A5A);
    assert_int_equal(lut_build_inverse(&src, inv, 1, &out, &err), LUT_ERR_SIZE);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_init_errors),
        cmocka_unit_test(test_eval_matches_double_interpolation),
        cmocka_unit_test(test_eval_saturates_and_hits_entries),
        cmocka_unit_test(test_eval_cell_equals_eval),
        cmocka_unit_test(test_inverse_property),
        cmocka_unit_test(test_inverse_exact_for_linear),
        cmocka_unit_test(test_inverse_refuses_non_monotone),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
