/* Tests of f_online.c (on-line offset and gain of f) against an independent double-precision
 * weighted least squares written here, and of its publication into f^-1. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "calib.h"
#include "f_online.h"
#include "lut.h"
#include "psa_loop.h"
#include "table_fixture.h"
#include "test_rng.h"

static double b_const(double q, const void *ctx)
{
    (void)q;
    (void)ctx;
    return 0.4;
}

/* A curved, increasing f (deg) over q in [-4, 4]: 20 q + 2 q^2 / 4 keeps f' > 0. */
static double f_curved(double q, const void *ctx)
{
    (void)ctx;
    return 20.0 * q + 0.5 * q * q + 3.0;
}

static double f_falling(double q, const void *ctx)
{
    (void)ctx;
    return -15.0 * q + 0.3 * q * q;
}

static fixture_blob_t blob;
static calib_t cal;
static f_online_t fo; /* one learner for every test: the M4 build's RAM holds one */

static void load(fixture_fn f)
{
    fixture_grid_t g = {.q0 = -4, .step_log2 = 13, .n = 65, .q_min = -3.5, .q_max = 3.5, .f_kind = PST_F_REMAIN};
    size_t len = fixture_build(&blob, &g, b_const, NULL, f, NULL);
    assert_int_equal(calib_load(&cal, blob.bytes, len), CALIB_OK);
}

/* Double reference: the weighted least-squares criterion of f_online.c solved directly,
 * weights lambda^(n-i), prior_var (g - 1)^2, g clamped, no fixed point. */
typedef struct {
    double lam, prior, w, sx, sc, sxx, sxc;
} ref_t;

static void ref_sample(ref_t *r, double x, double c)
{
    r->w = r->lam * r->w + 1;
    r->sx = r->lam * r->sx + x;
    r->sc = r->lam * r->sc + c;
    r->sxx = r->lam * r->sxx + x * x;
    r->sxc = r->lam * r->sxc + x * c;
}

static void ref_solve(const ref_t *r, double *a, double *g)
{
    double mx = r->sx / r->w, mc = r->sc / r->w;
    double cxx = r->sxx - r->w * mx * mx, cxc = r->sxc - r->w * mx * mc;
    *g = fmin(fmax((cxc + r->prior) / (cxx + r->prior), 0.5), 2.0);
    *a = mc - *g * mx;
}

static void test_config_errors(void **state)
{
    (void)state;
    load(f_curved);
    f_online_config_t c = f_online_default_config();
    f_online_config_t bad = c;
    bad.mem_log2 = 0;
    assert_int_equal(f_online_init(&fo, &bad, &cal.f, &cal.f_inv), F_ONLINE_ERR_CONFIG);
    bad = c;
    bad.mem_log2 = F_ONLINE_MEM_LOG2_MAX + 1;
    assert_int_equal(f_online_init(&fo, &bad, &cal.f, &cal.f_inv), F_ONLINE_ERR_CONFIG);
    bad = c;
    bad.publish_every = 0;
    assert_int_equal(f_online_init(&fo, &bad, &cal.f, &cal.f_inv), F_ONLINE_ERR_CONFIG);
    bad = c;
    bad.prior_var_q16 = 0;
    assert_int_equal(f_online_init(&fo, &bad, &cal.f, &cal.f_inv), F_ONLINE_ERR_CONFIG);
    bad = c;
    bad.g_min_q16 = 65536 + 1;
    assert_int_equal(f_online_init(&fo, &bad, &cal.f, &cal.f_inv), F_ONLINE_ERR_CONFIG);
    /* A flat f cannot be inverted. */
    static int32_t flat[4] = {65536, 65536, 131072, 196608};
    lut_t lf;
    assert_int_equal(lut_init(&lf, flat, 4, 0, 65536), LUT_OK);
    assert_int_equal(f_online_init(&fo, &c, &lf, &cal.f_inv), F_ONLINE_ERR_TABLE);
    assert_int_equal(f_online_init(&fo, &c, &cal.f, &cal.f_inv), F_ONLINE_OK);
}

/* The identity map (no reading yet, or readings that say a = 0, g = 1) rewrites the loader's
 * f^-1 bit for bit, for an increasing and a decreasing f. */
static void test_identity_is_the_loaders_inverse(void **state)
{
    (void)state;
    static int32_t loader[CALIB_DERIVED_MAX];
    fixture_fn fns[2] = {f_curved, f_falling};
    for (int k = 0; k < 2; k++) {
        load(fns[k]);
        memcpy(loader, cal.f_inv.y_q16, cal.f_inv.n * sizeof(int32_t));
        f_online_config_t c = f_online_default_config();
        assert_int_equal(f_online_init(&fo, &c, &cal.f, &cal.f_inv), F_ONLINE_OK);
        f_online_publish(&fo); /* no reading: a = 0, g = 1 */
        assert_int_equal(fo.a_q16, 0);
        assert_int_equal(fo.g_q16, 65536);
        assert_ptr_not_equal(cal.f_inv.y_q16, cal.f_inv_buf);
        assert_memory_equal(cal.f_inv.y_q16, loader, cal.f_inv.n * sizeof(int32_t));
    }
}

/* Readings c = a + g x + noise: the published (a, g) is the double reference's within a few
 * few 1e-5 (g) and 1e-4 deg (a): the fixed point's rounding, with forgetting, prior and the clamp; every publish. */
static void test_matches_double_reference(void **state)
{
    (void)state;
    load(f_curved);
    f_online_config_t c = f_online_default_config();
    c.mem_log2 = 6;
    c.publish_every = 5;
    c.prior_var_q16 = 30 * 65536;
    assert_int_equal(f_online_init(&fo, &c, &cal.f, &cal.f_inv), F_ONLINE_OK);
    ref_t r = {.lam = 1.0 - ldexp(1.0, -6), .prior = 30.0};
    double ref0 = fo.ref_q16 / 65536.0;
    test_rng_t rng;
    test_rng_seed(&rng, 7);
    double worst_a = 0, worst_g = 0;
    for (int i = 0; i < 600; i++) {
        /* a drift that changes half-way (forgetting must follow it), and g = 2.5 clamped */
        double a_t = i < 300 ? 4.0 : -2.5, g_t = i < 300 ? 1.08 : (i < 450 ? 0.93 : 2.5);
        double x = 40.0 * sin(0.05 * i) + 5.0;
        double cc = a_t + g_t * x + 0.3 * test_rng_normal(&rng);
        int32_t xq = (int32_t)lround(x * 65536.0), cq = (int32_t)lround(cc * 65536.0);
        ref_sample(&r, xq / 65536.0 - ref0, cq / 65536.0 - ref0);
        if (f_online_step(&fo, xq, cq)) {
            double a, g;
            ref_solve(&r, &a, &g);
            a += ref0 * (1 - g);
            worst_a = fmax(worst_a, fabs(fo.a_q16 / 65536.0 - a));
            worst_g = fmax(worst_g, fabs(fo.g_q16 / 65536.0 - g));
            if (i > 250 && i < 300) {
                assert_true(fabs(g - 1.08) < 0.02);
                assert_true(fabs(a - 4.0) < 1.0);
            }
        }
    }
    assert_int_equal(fo.publishes, 120);
    assert_int_equal(fo.g_q16, 2 * 65536); /* the clamp */
    printf("worst |a - ref| %.2e deg, |g - ref| %.2e\n", worst_a, worst_g);
    assert_true(worst_a < 1e-3);
    assert_true(worst_g < 3e-5);
}

/* The published f^-1 is the inverse of a + g f: c -> q with a + g f(q) = c, within the
 * loader's own f^-1 error bound plus the rounding of u = (c - a) / g (times max |1/f'|). */
static void test_published_table_inverts_the_corrected_f(void **state)
{
    (void)state;
    fixture_fn fns[2] = {f_curved, f_falling};
    for (int k = 0; k < 2; k++) {
        load(fns[k]);
        f_online_config_t c = f_online_default_config();
        c.publish_every = 1;
        assert_int_equal(f_online_init(&fo, &c, &cal.f, &cal.f_inv), F_ONLINE_OK);
        for (int i = 0; i < 200; i++) {
            double x = 50.0 * sin(0.1 * i);
            (void)f_online_step(&fo, (int32_t)lround(x * 65536.0), (int32_t)lround((1.5 + 1.1 * x) * 65536.0));
        }
        double a = fo.a_q16 / 65536.0, g = fo.g_q16 / 65536.0;
        assert_true(fabs(g - 1.1) < 1e-3 && fabs(a - 1.5) < 1e-2);
        double worst = 0;
        for (int i = 0; i < 64; i++) {
            for (int s = 0; s < 8; s++) {
                double q = -4.0 + (i + s / 8.0) * 0.125;
                double cq = a + g * (lut_eval(&cal.f, (int32_t)lround(q * 65536.0)) / 65536.0);
                double qb = lut_eval(&cal.f_inv, (int32_t)lround(cq * 65536.0)) / 65536.0;
                if (cq > cal.f_inv.x0_q16 / 65536.0 && cq < cal.f_inv.x_last_q16 / 65536.0)
                    worst = fmax(worst, fabs(qb - q));
            }
        }
        /* + 2 raw: the rounding of u = (c - a) / g (|1/f'| < 1 raw per raw here) and of the probe */
        double bound = (cal.f_inv_err_q16 + 2) / 65536.0;
        printf("worst |f^-1(a + g f(q)) - q| %.2e (bound %.2e)\n", worst, bound);
        assert_true(worst > 0);
        assert_true(worst <= bound);
    }
}

/* Publication (A/B): a publish writes the copy the table does not point to and then moves the
 * pointer; the copy a preempted tick was reading stays complete and unchanged. Stop points
 * the table back at the loader's entries. */
static void test_publish_writes_the_other_copy(void **state)
{
    (void)state;
    load(f_curved);
    static int32_t before[CALIB_DERIVED_MAX];
    f_online_config_t c = f_online_default_config();
    c.publish_every = 3;
    assert_int_equal(f_online_init(&fo, &c, &cal.f, &cal.f_inv), F_ONLINE_OK);
    const size_t sz = cal.f_inv.n * sizeof(int32_t);
    for (int k = 0; k < 30; k++) {
        const int32_t *old = cal.f_inv.y_q16;
        memcpy(before, old, sz);
        bool pub = f_online_step(&fo, (int32_t)(k * 3 * 65536), (int32_t)((k * 3 + 2) * 65536 + k * 1000));
        assert_int_equal(pub, (k + 1) % 3 == 0);
        assert_memory_equal(old, before, sz); /* the copy read before is untouched */
        if (pub)
            assert_true(cal.f_inv.y_q16 != old);
        else
            assert_ptr_equal(cal.f_inv.y_q16, old);
    }
    f_online_stop(&fo);
    assert_ptr_equal(cal.f_inv.y_q16, cal.f_inv_buf);
}

/* A commit that keeps f (a new B) carries the map over into the new table at once; a commit
 * with another f restarts learning on it and leaves its loader's f^-1 running. */
static void test_rebind(void **state)
{
    (void)state;
    load(f_curved);
    static calib_t cal2, cal3;
    static fixture_blob_t blob2, blob3;
    f_online_config_t c = f_online_default_config();
    c.publish_every = 4;
    assert_int_equal(f_online_init(&fo, &c, &cal.f, &cal.f_inv), F_ONLINE_OK);
    for (int k = 0; k < 40; k++)
        (void)f_online_step(&fo, (int32_t)(k * 65536), (int32_t)((k + 3) * 65536));
    int32_t a = fo.a_q16, g = fo.g_q16;
    int64_t sw = fo.s_w;
    memcpy(&blob2, &blob, sizeof blob2);
    assert_int_equal(calib_load(&cal2, blob2.bytes, sizeof blob2.bytes), CALIB_OK);
    assert_int_equal(f_online_rebind(&fo, &cal2.f, &cal2.f_inv), F_ONLINE_OK);
    assert_int_equal(fo.a_q16, a);
    assert_int_equal(fo.g_q16, g);
    assert_true(fo.s_w == sw);
    assert_memory_equal(cal2.f_inv.y_q16, cal.f_inv.y_q16, cal.f_inv.n * sizeof(int32_t));
    assert_ptr_not_equal(cal2.f_inv.y_q16, cal.f_inv.y_q16);
    /* another f */
    fixture_grid_t gr = {.q0 = -4, .step_log2 = 13, .n = 65, .q_min = -3.5, .q_max = 3.5, .f_kind = PST_F_REMAIN};
    size_t len = fixture_build(&blob3, &gr, b_const, NULL, f_falling, NULL);
    assert_int_equal(calib_load(&cal3, blob3.bytes, len), CALIB_OK);
    assert_int_equal(f_online_rebind(&fo, &cal3.f, &cal3.f_inv), F_ONLINE_OK);
    assert_int_equal(fo.samples, 0);
    assert_int_equal(fo.g_q16, 65536);
    assert_ptr_equal(cal3.f_inv.y_q16, cal3.f_inv_buf);
}

/* The loop's hook, closed loop: the board compensates a reference c* while its plant reads
 * c = a_t + g_t f(y*) (an offset and a gain the flashed f does not have). Each reading is
 * learnt on the observation call against f(f^-1(c*)); publishes run in psa_background only;
 * once learnt, the tip the compensator aims at is c* again. */
static void test_loop_hook_closes_the_loop(void **state)
{
    (void)state;
    load(f_curved);
    static psa_loop_t lp;
    psa_config_t pc;
    memset(&pc, 0, sizeof pc);
    pc.onset = onset_default_config();
    psa_init(&lp, &pc);
    assert_true(psa_set_table(&lp, &cal));
    assert_true(psa_set_mode(&lp, PSA_MODE_COMPENSATION));
    f_online_config_t c = f_online_default_config();
    c.publish_every = 8;
    assert_int_equal(f_online_init(&fo, &c, &cal.f, &cal.f_inv), F_ONLINE_OK);
    psa_set_f_learning(&lp, &fo);
    const double a_t = 2.0, g_t = 1.07;
    onset_event_t ev;
    int32_t x;
    assert_false(psa_f_regressor(&lp, true, &x)); /* no reference yet */
    double worst_first = 0, worst_last = 0;
    for (int k = 0; k < 400; k++) {
        int32_t c_ref = (int32_t)lround((30.0 * sin(0.03 * k) + 5.0) * 65536.0);
        (void)psa_set_reference(&lp, c_ref);
        double y = lut_eval(&cal.f_inv, c_ref) / 65536.0; /* the centre the compensator aims at */
        double tip = a_t + g_t * lut_eval(&cal.f, (int32_t)lround(y * 65536.0)) / 65536.0;
        double err = fabs(tip - c_ref / 65536.0);
        if (k < 8)
            worst_first = fmax(worst_first, err);
        if (k >= 300)
            worst_last = fmax(worst_last, err);
        const int32_t *before = cal.f_inv.y_q16;
        (void)psa_observe_deg(&lp, (uint32_t)k * 40000u, (int32_t)lround(tip * 65536.0), true, &ev);
        assert_ptr_equal(cal.f_inv.y_q16, before); /* nothing published on the observation */
        bool due = (k + 1) % 8 == 0;
        assert_int_equal(lp.f_publish_due, due);
        assert_int_equal(psa_background(&lp), due);
        if (due)
            assert_int_equal(lp.comp.f_inv_cell.width, 0);
    }
    printf("tip - c*: first readings %.3f deg, after learning %.4f deg\n", worst_first, worst_last);
    assert_true(worst_first > 1.0);
    assert_true(worst_last < 0.01);
    assert_true(fabs(fo.g_q16 / 65536.0 - g_t) < 1e-3);
    /* An invalid reading, or one outside compensation, is not learnt. */
    uint32_t n = fo.samples;
    (void)psa_observe_deg(&lp, 1u << 30, 0, false, &ev);
    assert_int_equal(fo.samples, n);
    psa_set_f_learning(&lp, NULL);
    assert_false(psa_background(&lp));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_config_errors),
        cmocka_unit_test(test_identity_is_the_loaders_inverse),
        cmocka_unit_test(test_matches_double_reference),
        cmocka_unit_test(test_published_table_inverts_the_corrected_f),
        cmocka_unit_test(test_publish_writes_the_other_copy),
        cmocka_unit_test(test_rebind),
        cmocka_unit_test(test_loop_hook_closes_the_loop),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
