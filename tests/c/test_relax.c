/* Tests of the travel-domain relaxation (firmware/core/relax.c, relax_build.c): the fixed-point
 * direct model and inverse against a double reference of the equations (written here from the
 * model of relax.h / host/playscope/relax.py, not from the fixed-point code), the round trip
 * inverse(direct(x)) = x within the measured bound, rate independence, the loader's v4 fields
 * (build, refusals, CRC seeded by version) and the relaxation wired into playop / comp. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <math.h>
#include <string.h>
#include <cmocka.h>

#include "calib.h"
#include "comp.h"
#include "playop.h"
#include "relax.h"
#include "table_fixture.h"
#include "test_rng.h"

#define X_MIN (-4 * 65536)
#define X_MAX (4 * 65536)
#define N_TICKS 20000

/* Double reference of relax.h's equations, in actuator units. */
typedef struct {
    double r, vp, kappa, lam;
    int started;
} ref_t;

static void ref_reset(ref_t *s, double kappa, double lam, double x0)
{
    s->r = x0;
    s->vp = x0;
    s->kappa = kappa;
    s->lam = lam;
    s->started = 1;
}

static void ref_update(ref_t *s, double x, double v)
{
    double g = fabs(v - s->vp) / s->lam, cap = 1.0 - s->kappa;
    s->r += (g > cap ? cap : g) * (x - s->r);
    s->vp = v;
}

static double ref_direct(ref_t *s, double x)
{
    double v = x + s->kappa * (s->r - x);
    ref_update(s, x, v);
    return v;
}

/* The board clamps the inverse's output to the range it was built for; so does the model. */
static double ref_inverse(ref_t *s, double v, double lo, double hi)
{
    double x = v + s->kappa / (1.0 - s->kappa) * (v - s->r);
    x = fmin(fmax(x, lo), hi);
    ref_update(s, x, v);
    return x;
}

/* A reversal-rich path in raw units: speed changes with probability 0.03 per tick (often its
 * sign), a jump now and then, clamped to [lo, hi]; never held (held inputs are a separate case). */
static int g_jumps = 1; /* the inverse's tests run smooth paths (a compensator's y* = f^-1(c*)) */

static int32_t walk(test_rng_t *r, double *x, double *v, double lo, double hi)
{
    if (test_rng_uniform(r, 0, 1) < 0.03)
        *v = test_rng_uniform(r, -0.01, 0.01) * 65536.0 * (test_rng_uniform(r, 0, 1) < 0.3 ? 10.0 : 1.0);
    double step = *v;
    if (g_jumps && test_rng_uniform(r, 0, 1) < 0.002)
        step += test_rng_uniform(r, -1.0, 1.0) * 65536.0;
    *x = fmin(fmax(*x + step, lo), hi);
    return (int32_t)llround(*x);
}

static const double KAPPAS[] = {0.1, 0.5, 0.9};
static const double LAMBDAS[] = {0.005, 0.2, 3.0};

static relax_params_t params(double kappa, double lam)
{
    relax_params_t p;
    assert_int_equal(relax_build((int32_t)lround(kappa * 65536), (int32_t)lround(lam * 65536), X_MIN, X_MAX, &p),
                     RELAX_OK);
    return p;
}

/* Direct model: the fixed point against the double reference on the same integer inputs
 * (paths with jumps). Measured worst: 14 raw (the output's rounding enters the gain through
 * |dv| / lambda; lambda = 0.005 units is 328 raw); held to 32. */
static void test_direct_vs_double(void **state)
{
    (void)state;
    int32_t worst = 0;
    for (size_t a = 0; a < 3; a++) {
        for (size_t b = 0; b < 3; b++) {
            relax_params_t p = params(KAPPAS[a], LAMBDAS[b]);
            double kappa = p.kappa_q16 / 65536.0, lam = p.lambda_q16 / 65536.0;
            test_rng_t rng;
            test_rng_seed(&rng, 11 + 3 * a + b);
            double x = 0, v = 0;
            relax_state_t s;
            relax_reset(&s, 0);
            ref_t ref;
            ref_reset(&ref, kappa, lam, 0.0);
            for (int k = 0; k < N_TICKS; k++) {
                int32_t xi = walk(&rng, &x, &v, X_MIN, X_MAX);
                int32_t out = relax_direct(&s, &p, xi);
                double want = ref_direct(&ref, xi / 65536.0) * 65536.0;
                int32_t e = (int32_t)ceil(fabs(out - want));
                worst = e > worst ? e : worst;
            }
        }
    }
    print_message("relax direct: worst |fixed - double| = %d raw\n", (int)worst);
    assert_true(worst <= 32);
}

/* Inverse against the double reference of the inverse on the same v inputs (the references
 * run their own state: the error is that of the whole recursion). Smooth paths, as a
 * compensator's y* = f^-1(c*). Measured worst: 1 raw for kappa <= 0.5, 10 raw at kappa = 0.9
 * (1 + m = 10 times the 1/2-raw read of r); held to 24. */
static void test_inverse_vs_double(void **state)
{
    (void)state;
    g_jumps = 0;
    int32_t worst = 0;
    for (size_t a = 0; a < 3; a++) {
        for (size_t b = 0; b < 3; b++) {
            relax_params_t p = params(KAPPAS[a], LAMBDAS[b]);
            double kappa = p.kappa_q16 / 65536.0, lam = p.lambda_q16 / 65536.0;
            test_rng_t rng;
            test_rng_seed(&rng, 101 + 3 * a + b);
            int32_t wc = 0;
            /* v within the middle of the range, so the clamp to [X_MIN, X_MAX] never acts. */
            double x = 0, v = 0;
            relax_state_t s;
            relax_reset(&s, 0);
            ref_t ref;
            ref_reset(&ref, kappa, lam, 0.0);
            for (int k = 0; k < N_TICKS; k++) {
                int32_t vi = walk(&rng, &x, &v, X_MIN / 4, X_MAX / 4);
                int32_t out = relax_inverse(&s, &p, vi);
                double want = ref_inverse(&ref, vi / 65536.0, X_MIN / 65536.0, X_MAX / 65536.0) * 65536.0;
                int32_t e = (int32_t)ceil(fabs(out - want));
                worst = e > worst ? e : worst;
                wc = e > wc ? e : wc;
            }
            print_message("  inverse kappa %.1f lambda %.3f: %d raw\n", KAPPAS[a], LAMBDAS[b], (int)wc);
        }
    }
    print_message("relax inverse: worst |fixed - double| = %d raw\n", (int)worst);
    assert_true(worst <= 24);
}

/* inverse(direct(x)) = x: the board's compensator undoes its own direct model. Per tick the
 * error is about (1/2)/(1 - kappa) + 1/2 raw plus the states' drift (contracting). Measured
 * worst: 1 raw (kappa 0.1), 2 raw (0.5), 22 raw (0.9); held to 4, 6 and 48. */
static void test_round_trip(void **state)
{
    (void)state;
    g_jumps = 0;
    for (size_t a = 0; a < 3; a++) {
        int32_t worst = 0;
        for (size_t b = 0; b < 3; b++) {
            relax_params_t p = params(KAPPAS[a], LAMBDAS[b]);
            test_rng_t rng;
            test_rng_seed(&rng, 1001 + 3 * a + b);
            int32_t wc = 0;
            double x = 0, v = 0;
            relax_state_t sd, si;
            relax_reset(&sd, 0);
            relax_reset(&si, 0);
            for (int k = 0; k < N_TICKS; k++) {
                int32_t xi = walk(&rng, &x, &v, X_MIN / 2, X_MAX / 2);
                int32_t back = relax_inverse(&si, &p, relax_direct(&sd, &p, xi));
                int32_t e = back > xi ? back - xi : xi - back;
                worst = e > worst ? e : worst;
                wc = e > wc ? e : wc;
            }
            print_message("  round trip kappa %.1f lambda %.3f: %d raw\n", KAPPAS[a], LAMBDAS[b], (int)wc);
        }
        print_message("relax round trip kappa %.1f: worst %d raw\n", KAPPAS[a], (int)worst);
        assert_true(worst <= (a == 0 ? 4 : a == 1 ? 6 : 48));
    }
}

/* Rate independence: one triangle path at two tick densities (1x, 8x). In the travel the
 * recursion is an Euler step of dr/ds = (x - r)/lambda, so the two agree to O(step/lambda)
 * of the creep kappa lambda: here within 2 % of it, while a time constant tuned to the slow
 * run would be 8 times off on the fast one. */
static void test_rate_independent(void **state)
{
    (void)state;
    const double lam = 0.5, kappa = 0.5;
    relax_params_t p = params(kappa, lam);
    double out[2][5];
    for (int d = 0; d < 2; d++) {
        const int per_unit = d == 0 ? 200 : 1600; /* ticks per actuator unit travelled */
        relax_state_t s;
        relax_reset(&s, 0);
        double x = 0;
        int idx = 0;
        const double turns[] = {2.0, -1.0, 1.5, -2.0, 0.5};
        for (int t = 0; t < 5; t++) {
            double dirn = turns[t] > x ? 1.0 : -1.0;
            int n = (int)lround(fabs(turns[t] - x) * per_unit);
            double x0 = x;
            int32_t o = 0;
            for (int k = 1; k <= n; k++)
                o = relax_direct(&s, &p, (int32_t)lround((x0 + dirn * k / (double)per_unit) * 65536));
            x = turns[t];
            out[d][idx++] = o / 65536.0;
        }
    }
    for (int i = 0; i < 5; i++)
        assert_true(fabs(out[0][i] - out[1][i]) <= 0.02 * kappa * lam);
}

static void test_build_refusals(void **state)
{
    (void)state;
    relax_params_t p;
    memset(&p, 0x5a, sizeof p);
    relax_params_t keep = p;
    assert_int_equal(relax_build(-1, 65536, X_MIN, X_MAX, &p), RELAX_ERR_KAPPA);
    assert_int_equal(relax_build(PST_RELAX_KAPPA_MAX_Q16 + 1, 65536, X_MIN, X_MAX, &p), RELAX_ERR_KAPPA);
    assert_int_equal(relax_build(30000, 0, X_MIN, X_MAX, &p), RELAX_ERR_LAMBDA);
    assert_int_equal(relax_build(0, 5, X_MIN, X_MAX, &p), RELAX_ERR_LAMBDA);
    assert_int_equal(relax_build(30000, 65536, -(1 << 30) - 1, X_MAX, &p), RELAX_ERR_RANGE);
    assert_memory_equal(&p, &keep, sizeof p);
    /* No relaxation: any range loads (a v1-v3 table's f grid is not held to +-2^30 here). */
    assert_int_equal(relax_build(0, 0, INT32_MIN, INT32_MAX, &p), RELAX_OK);
    assert_int_equal(p.kappa_q16, 0);
    /* The derived constants: m = kappa / (1 - kappa), 1/lambda. */
    assert_int_equal(relax_build(32768, 65536, X_MIN, X_MAX, &p), RELAX_OK);
    assert_int_equal(p.m_q24, 1 << 24);
    assert_true(p.inv_lam_q47 == ((uint64_t)1 << 31));
}

/* ---- through the loader: a v4 table, its refusals, and the chain in playop / comp ---- */
static double b_fn(double q, const void *c) { (void)c; return 0.3 + 0.02 * q; }
static double f_fn(double q, const void *c) { (void)c; return 10.0 * q + 0.5 * q * q * 0.1; }

static fixture_blob_t blob, blob_plain;
static calib_t cal, cal_plain;

static size_t base_table(fixture_blob_t *bl)
{
    fixture_grid_t g = {.q0 = -4.0, .step_log2 = 11, .n = 256, .q_min = -3.5, .q_max = 3.5,
                        .f_kind = PST_F_REMAIN, .generation = 1};
    static const int32_t r[2] = {0, 19661}, w[2] = {45875, 19661}; /* r = 0, 0.3; w = 0.7, 0.3 */
    return fixture_build_pi(bl, &g, b_fn, NULL, f_fn, NULL, 0, 2, r, w);
}

static void test_v4_table_loads(void **state)
{
    (void)state;
    assert_true(base_table(&blob_plain) > 0);
    assert_int_equal(calib_load(&cal_plain, blob_plain.bytes, sizeof blob_plain.bytes), CALIB_OK);
    assert_int_equal(cal_plain.relax.kappa_q16, 0);
    assert_true(base_table(&blob) > 0);
    size_t n = fixture_with_relax(&blob, 26214, 13107); /* kappa 0.4, lambda 0.2 */
    assert_int_equal(n, 80 + 4 * (256 + 256) + 8 * 2);
    pst_header_t hd;
    memcpy(&hd, blob.bytes, sizeof hd);
    assert_int_equal(hd.layout_version, 4);
    assert_int_equal(hd.header_size, 80);
    assert_int_equal(calib_load(&cal, blob.bytes, n), CALIB_OK);
    assert_int_equal(cal.relax.kappa_q16, 26214);
    assert_int_equal(cal.relax.lambda_q16, 13107);
    /* The relaxation raises the compensator's error bound by its inverse's gain. */
    assert_true(cal.comp_err_q16 > cal_plain.comp_err_q16);
    /* The CRC is seeded by the version: the same bytes called v3 fail their check. */
    fixture_blob_t edit = blob;
    uint16_t v3 = 3;
    memcpy(edit.bytes + offsetof(pst_header_t, layout_version), &v3, 2);
    calib_t untouched = cal;
    assert_int_equal(calib_load(&untouched, edit.bytes, n), CALIB_ERR_VERSION); /* 80-byte header is not v3's */
    uint16_t hs = 72;
    memcpy(edit.bytes + offsetof(pst_header_t, header_size), &hs, 2);
    assert_int_equal(calib_load(&untouched, edit.bytes, n), CALIB_ERR_CRC);
    assert_memory_equal(&untouched, &cal, sizeof cal);
}

static void test_v4_refusals(void **state)
{
    (void)state;
    const int32_t bad[][2] = {{PST_RELAX_KAPPA_MAX_Q16 + 1, 13107}, {-5, 13107}, {26214, 0}};
    for (size_t i = 0; i < 3; i++) {
        assert_true(base_table(&blob) > 0);
        assert_true(fixture_with_relax(&blob, 26214, 13107) > 0);
        pst_relax_t rx = {bad[i][0], bad[i][1]};
        memcpy(blob.bytes + offsetof(pst_header_v4_t, relax), &rx, sizeof rx);
        fixture_reseal(&blob);
        calib_t keep;
        memset(&keep, 0x33, sizeof keep);
        calib_t before = keep;
        assert_int_equal(calib_load(&keep, blob.bytes, sizeof blob.bytes), CALIB_ERR_RELAX);
        assert_memory_equal(&keep, &before, sizeof keep);
    }
    /* A v4 header that says kappa = 0 and lambda = 0 is the v3 model. */
    assert_true(base_table(&blob) > 0);
    assert_true(fixture_with_relax(&blob, 0, 0) > 0);
    assert_int_equal(calib_load(&cal, blob.bytes, sizeof blob.bytes), CALIB_OK);
    assert_int_equal(cal.relax.kappa_q16, 0);
}

/* playop on a v4 table = f(R[y]) with y the v2 twin's transition output (bit for bit), and
 * comp_step on it undoes the direct model: f(R[PI[z*]]) = c* within the bound. */
static void test_chain(void **state)
{
    (void)state;
    assert_true(base_table(&blob_plain) > 0);
    assert_int_equal(calib_load(&cal_plain, blob_plain.bytes, sizeof blob_plain.bytes), CALIB_OK);
    assert_true(base_table(&blob) > 0);
    assert_true(fixture_with_relax(&blob, 26214, 13107) > 0);
    assert_int_equal(calib_load(&cal, blob.bytes, sizeof blob.bytes), CALIB_OK);
    playop_t p4, p2;
    playop_reset(&p4, &cal, 0);
    playop_reset(&p2, &cal_plain, 0);
    relax_state_t rs;
    relax_reset(&rs, p2.pi.y_q16);
    test_rng_t rng;
    test_rng_seed(&rng, 7);
    double x = 0, v = 0;
    for (int k = 0; k < 5000; k++) {
        int32_t q = walk(&rng, &x, &v, -3.0 * 65536, 3.0 * 65536);
        int32_t c4 = playop_step(&p4, q);
        (void)playop_step(&p2, q);
        int32_t y = cal_plain.pi_dir.n ? p2.pi.y_q16 : p2.z_q16;
        int32_t want = lut_eval(&cal.f, relax_direct(&rs, &cal.relax, y));
        assert_int_equal(c4, want);
    }
    /* Compensator, then the direct model on its centre: the relaxation's inverse is undone. */
    comp_t cp;
    comp_reset(&cp, &cal, NULL, lut_eval(&cal.f, 0));
    relax_state_t rd;
    pi_state_t pd;
    int32_t y0 = lut_eval(&cal.f_inv, lut_eval(&cal.f, 0));
    relax_reset(&rd, y0);
    int32_t worst = 0;
    for (int k = 0; k < 5000; k++) {
        int32_t c = (int32_t)lround(20.0 * 65536 * sin(k * 0.002) * (1 + 0.3 * sin(k * 0.0007)));
        (void)comp_step(&cp, c);
        if (k == 0)
            pi_reset(&pd, &cal.pi_dir, cp.pi.y_q16);
        /* The direct model fed the compensator's centre (before its +-B/2) gives y again. */
        int32_t yc = pi_step(&pd, &cal.pi_dir, cp.pi.y_q16);
        int32_t got = lut_eval(&cal.f, relax_direct(&rd, &cal.relax, yc));
        int32_t e = got > c ? got - c : c - got;
        worst = k > 0 && e > worst ? e : worst;
    }
    print_message("comp on a v4 table: worst |f(R[PI[z*]]) - c*| = %d raw\n", (int)worst);
    /* |f'| <= 11 deg per unit on the grid: the centre's bound times it, plus f's rounding. */
    assert_true(worst <= 11 * (cal.comp_err_q16 + 2) + 2);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_direct_vs_double),
        cmocka_unit_test(test_inverse_vs_double),
        cmocka_unit_test(test_round_trip),
        cmocka_unit_test(test_rate_independent),
        cmocka_unit_test(test_build_refusals),
        cmocka_unit_test(test_v4_table_loads),
        cmocka_unit_test(test_v4_refusals),
        cmocka_unit_test(test_chain),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
