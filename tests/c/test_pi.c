/* Tests of the transition operator (firmware/core/pi.c, pi_build.c): the incremental
 * engine against the textbook clamp-every-operator loop (bit for bit), the direct and
 * inverse operators against an independent double reference (tests/c/support/ref_model.c,
 * Krejci-Kuhnen inverse written from the published formula) within the documented error
 * bound (docs/method.md, "Error bound"), round trips, and the semigroup P_a o P_b = P_{a+b}. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <math.h>
#include <string.h>
#include <cmocka.h>

#include "pi.h"
#include "random_tables.h"

/* Inputs of the operators in these tests: [-4, 4] actuator units (as the tables' grids). */
#define X_MIN (-4 * 65536)
#define X_MAX (4 * 65536)

/* A reversal-rich reference: a random walk whose speed changes (often sign) with
 * probability 0.05 per tick, holds now and then, and jumps by up to 1.5 units now and
 * then (so several operators engage in one tick), clamped to [lo, hi] (raw). */
typedef struct {
    double x, v;
} walk_t;

static int32_t walk_next(test_rng_t *r, walk_t *w, double lo, double hi)
{
    double u = test_rng_uniform(r, 0, 1);
    if (u < 0.05)
        w->v = test_rng_uniform(r, -0.02, 0.02) * 65536.0 * (test_rng_uniform(r, 0, 1) < 0.3 ? 10.0 : 1.0);
    else if (u < 0.06)
        w->v = 0;
    double step = w->v;
    if (test_rng_uniform(r, 0, 1) < 0.003)
        step += test_rng_uniform(r, -1.5, 1.5) * 65536.0;
    w->x = fmin(fmax(w->x + step, lo), hi);
    return (int32_t)llround(w->x);
}

/* Textbook integer PI on the same parameters: every operator clamped every step, the
 * int64 sum rounded half up. The engine must equal it bit for bit. */
typedef struct {
    int32_t p[PST_MAX_OPS];
} int_pi_t;

static int32_t int_pi_step(int_pi_t *s, const pi_params_t *pp, int32_t x)
{
    int64_t acc = 0;
    for (int i = 0; i < pp->n; i++) {
        int64_t lo = (int64_t)x - pp->r_q16[i], hi = (int64_t)x + pp->r_q16[i];
        int64_t p = s->p[i] < lo ? lo : (s->p[i] > hi ? hi : s->p[i]);
        s->p[i] = (int32_t)p;
        acc += (int64_t)pp->w[i] * p;
    }
    acc += (int64_t)1 << (pp->w_frac - 1);
    return (int32_t)(acc >> pp->w_frac); /* floor: arithmetic shift (gcc, arm-none-eabi-gcc) */
}

static void build(test_rng_t *r, int n, double r_max, double w0_min, int sum_err, pi_params_t *dir,
                  pi_params_t *inv, int32_t *inv_err, ref_pi_t *ref)
{
    int32_t rq[PST_MAX_OPS], wq[PST_MAX_OPS];
    random_pi_build(r, n, r_max, w0_min, sum_err, rq, wq, ref);
    assert_int_equal(pi_build(rq, wq, (uint16_t)n, 8 * 65536, X_MIN, X_MAX, X_MIN, X_MAX, dir, inv, inv_err), PI_OK);
}

/* The incremental engine (engaged prefix, exact int64 bookkeeping) is the textbook
 * operator bit for bit, states included, for the direct and the inverse weights. */
static void test_engine_equals_textbook(void **state)
{
    (void)state;
    test_rng_t r;
    test_rng_seed(&r, 901);
    for (int trial = 0; trial < 60; trial++) {
        int n = 1 + (int)(test_rng_u64(&r) % PST_MAX_OPS);
        pi_params_t dir, inv;
        int32_t err;
        ref_pi_t ref;
        build(&r, n, test_rng_uniform(&r, 0.01, 2.0), 0.05, 256, &dir, &inv, &err, &ref);
        const pi_params_t *pps[2] = {&dir, &inv};
        for (int side = 0; side < 2; side++) {
            const pi_params_t *pp = pps[side];
            pi_state_t s;
            int_pi_t t;
            walk_t w = {test_rng_uniform(&r, -2, 2) * 65536.0, 0};
            int32_t x0 = (int32_t)llround(w.x);
            pi_reset(&s, pp, x0);
            for (int i = 0; i < n; i++)
                t.p[i] = x0;
            for (int k = 0; k < 4000; k++) {
                int32_t x = walk_next(&r, &w, X_MIN, X_MAX);
                int32_t want = int_pi_step(&t, pp, x);
                assert_int_equal(pi_step(&s, pp, x), want);
                int32_t p[PST_MAX_OPS];
                pi_outputs(&s, pp, p);
                assert_memory_equal(p, t.p, 4u * (unsigned)n);
            }
        }
    }
}

/* Direct operator against exact arithmetic on the same thresholds and weights: only the
 * final rounding differs, so |error| <= 1/2 raw (measured: 0.5 raw, the bound is tight). */
static void test_direct_vs_double(void **state)
{
    (void)state;
    test_rng_t r;
    test_rng_seed(&r, 902);
    double worst = 0;
    for (int trial = 0; trial < 60; trial++) {
        int n = 1 + (int)(test_rng_u64(&r) % PST_MAX_OPS);
        pi_params_t dir, inv;
        int32_t err;
        ref_pi_t ref;
        build(&r, n, test_rng_uniform(&r, 0.01, 2.0), 0.05, 256, &dir, &inv, &err, &ref);
        pi_state_t s;
        walk_t w = {0, 0};
        pi_reset(&s, &dir, 0);
        ref_pi_reset(&ref, 0);
        for (int k = 0; k < 4000; k++) {
            int32_t x = walk_next(&r, &w, X_MIN, X_MAX);
            double want = ref_pi_step(&ref, x / 65536.0) * 65536.0;
            double e = fabs(pi_step(&s, &dir, x) - want);
            worst = fmax(worst, e);
            assert_true(e <= 0.5 + 1e-6);
        }
    }
    assert_true(worst > 0.25); /* the check is live: rounding is seen */
}

/* The bound of docs/method.md ("Error bound"), computed here from the exact inverse
 * weights (raw units): 1/2 + 1/2 sum|w'_i| (rounded thresholds, with the weights' own
 * rounding of n 2^-s added) + 2^-(s+1) (|y|max + 2 r'max + 1) (rounded partial sums). */
static double inverse_bound(const ref_pi_t *inv, int w_frac, double y_abs_raw)
{
    double sw = 0;
    for (int i = 0; i < inv->n; i++)
        sw += fabs(inv->w[i]);
    sw += inv->n * ldexp(1.0, -w_frac);
    double r_max = inv->r[inv->n - 1] * 65536.0;
    return 0.5 + 0.5 * sw + ldexp(y_abs_raw + 2 * r_max + 2, -(w_frac + 1));
}

/* Inverse operator against the exact Krejci-Kuhnen inverse in double, on random valid
 * weight sets (w_0 down to 0.02, sums off 1 by up to 2^-8) and reversal-rich inputs.
 * Measured worst: 2.3 raw, half of that trial's bound (the bound is dominated by
 * 1/2 sum|w'|, about 1/w_0). */
static void test_inverse_vs_double(void **state)
{
    (void)state;
    test_rng_t r;
    test_rng_seed(&r, 903);
    double worst = 0, worst_ratio = 0;
    for (int trial = 0; trial < 80; trial++) {
        int n = 1 + (int)(test_rng_u64(&r) % PST_MAX_OPS);
        pi_params_t dir, inv;
        int32_t err;
        ref_pi_t ref, rinv;
        build(&r, n, test_rng_uniform(&r, 0.01, 2.0), trial % 4 == 0 ? 0.02 : 0.2, 256, &dir, &inv, &err, &ref);
        ref_pi_inverse(&ref, &rinv);
        double bound = inverse_bound(&rinv, inv.w_frac, 4 * 65536.0);
        /* The loader's own bound is at least what is measured and at most this one (+1 for its ceiling). */
        assert_true(err <= bound + 1.0);
        pi_state_t s;
        walk_t w = {test_rng_uniform(&r, -2, 2) * 65536.0, 0};
        int32_t y0 = (int32_t)llround(w.x);
        pi_reset(&s, &inv, y0);
        ref_pi_reset(&rinv, y0 / 65536.0);
        double trial_worst = 0;
        for (int k = 0; k < 4000; k++) {
            int32_t y = walk_next(&r, &w, X_MIN, X_MAX);
            double want = ref_pi_step(&rinv, y / 65536.0) * 65536.0;
            double e = fabs(pi_step(&s, &inv, y) - want);
            trial_worst = fmax(trial_worst, e);
            assert_true(e <= bound);
            assert_true(e <= err);
        }
        worst = fmax(worst, trial_worst);
        worst_ratio = fmax(worst_ratio, trial_worst / bound);
    }
    /* Live check: the error is seen, and the bound is not loose by orders of magnitude. */
    assert_true(worst >= 0.5 && worst_ratio > 0.2);
}

/* direct(inverse(y)) = y up to W * E_inv + 1/2 raw (the direct operator is W-Lipschitz in
 * the sup norm of its input history, W = sum w_i), starting both at rest consistently:
 * the direct one at the inverse's initial output. Measured worst: 5 raw. */
static void test_round_trip_direct_of_inverse(void **state)
{
    (void)state;
    test_rng_t r;
    test_rng_seed(&r, 904);
    double worst = 0;
    for (int trial = 0; trial < 80; trial++) {
        int n = 1 + (int)(test_rng_u64(&r) % PST_MAX_OPS);
        pi_params_t dir, inv;
        int32_t err;
        ref_pi_t ref;
        build(&r, n, test_rng_uniform(&r, 0.01, 2.0), 0.05, 256, &dir, &inv, &err, &ref);
        double W = 0;
        for (int i = 0; i < n; i++)
            W += ref.w[i];
        double tol = W * err + 0.5;
        pi_state_t si, sd;
        walk_t w = {test_rng_uniform(&r, -2, 2) * 65536.0, 0};
        int32_t y0 = (int32_t)llround(w.x);
        pi_reset(&si, &inv, y0);
        pi_reset(&sd, &dir, si.y_q16);
        for (int k = 0; k < 4000; k++) {
            /* Keep y* where the inverse's output stays on the direct operator's input range. */
            int32_t y = walk_next(&r, &w, 3 * X_MIN / 8, 3 * X_MAX / 8);
            int32_t z = pi_step(&si, &inv, y);
            int32_t back = pi_step(&sd, &dir, z);
            double e = fabs((double)back - y);
            worst = fmax(worst, e);
            assert_true(e <= tol);
        }
    }
    assert_true(worst >= 0.5);
}

/* One operator of weight 1 (n = 1) is the identity both ways, bit for bit. */
static void test_single_operator_is_identity(void **state)
{
    (void)state;
    const int32_t r0 = 0, w0 = 65536;
    pi_params_t dir, inv;
    int32_t err;
    assert_int_equal(pi_build(&r0, &w0, 1, 8 * 65536, X_MIN, X_MAX, X_MIN, X_MAX, &dir, &inv, &err), PI_OK);
    assert_int_equal(inv.w[0], 1 << inv.w_frac);
    assert_int_equal(inv.r_q16[0], 0);
    pi_state_t sd, si;
    pi_reset(&sd, &dir, 12345);
    pi_reset(&si, &inv, 12345);
    assert_int_equal(sd.y_q16, 12345);
    assert_int_equal(si.y_q16, 12345);
    test_rng_t r;
    test_rng_seed(&r, 905);
    walk_t w = {12345, 0};
    for (int k = 0; k < 5000; k++) {
        int32_t x = walk_next(&r, &w, X_MIN, X_MAX);
        assert_int_equal(pi_step(&sd, &dir, x), x);
        assert_int_equal(pi_step(&si, &inv, x), x);
    }
    /* n = 0: identities as well. */
    assert_int_equal(pi_build(NULL, NULL, 0, 8 * 65536, X_MIN, X_MAX, X_MIN, X_MAX, &dir, &inv, &err), PI_OK);
    assert_int_equal(pi_step(&sd, &dir, -777), -777);
}

/* Semigroup of the play (docs/method.md): a play of half-width b followed by one of a is
 * the play of a + b, from rest, bit for bit. This is what lets the transition follow the
 * onset-measured play: its thresholds add to B/2. */
static void test_play_composition(void **state)
{
    (void)state;
    test_rng_t r;
    test_rng_seed(&r, 906);
    for (int trial = 0; trial < 40; trial++) {
        int32_t a = (int32_t)(test_rng_u64(&r) % 65536), b = (int32_t)(test_rng_u64(&r) % 65536);
        pi_params_t pa = {.n = 1, .w_frac = 16, .r_q16 = {a}, .w = {65536}, .x_min_q16 = X_MIN - 65536,
                          .x_max_q16 = X_MAX + 65536};
        pi_params_t pb = pa, pab = pa;
        pb.r_q16[0] = b;
        pab.r_q16[0] = a + b;
        pi_state_t sa, sb, sab;
        walk_t w = {0, 0};
        pi_reset(&sa, &pa, 0);
        pi_reset(&sb, &pb, 0);
        pi_reset(&sab, &pab, 0);
        for (int k = 0; k < 3000; k++) {
            int32_t x = walk_next(&r, &w, X_MIN, X_MAX);
            assert_int_equal(pi_step(&sa, &pa, pi_step(&sb, &pb, x)), pi_step(&sab, &pab, x));
        }
    }
}

/* The loader's derivation against the published formula (double): thresholds within 1/2
 * raw, partial sums of the weights within 2^-(s+1). */
static void test_inverse_parameters(void **state)
{
    (void)state;
    test_rng_t r;
    test_rng_seed(&r, 907);
    for (int trial = 0; trial < 200; trial++) {
        int n = 1 + (int)(test_rng_u64(&r) % PST_MAX_OPS);
        pi_params_t dir, inv;
        int32_t err;
        ref_pi_t ref, rinv;
        build(&r, n, test_rng_uniform(&r, 0.01, 2.0), 0.02, 256, &dir, &inv, &err, &ref);
        ref_pi_inverse(&ref, &rinv);
        double cum = 0, cum_ref = 0;
        for (int i = 0; i < n; i++) {
            assert_true(fabs(inv.r_q16[i] - rinv.r[i] * 65536.0) <= 0.5 + 1e-6);
            cum += inv.w[i];
            cum_ref += rinv.w[i];
            assert_true(fabs(cum - ldexp(cum_ref, inv.w_frac)) <= 0.5 + 1e-3);
        }
        assert_true(inv.w_frac >= 16 && inv.w_frac <= 30);
    }
}


/* The range refusals that only huge tables reach (test_calib covers the others): an input
 * range +- 2 r beyond +-2^30 raw, and an inverse whose output bound S |y| + sum |w'_i| r'_i
 * passes 2^30 (small w_0, large thresholds, inputs near the limit). Nothing is written. */
static void test_build_range_refusals(void **state)
{
    (void)state;
    pi_params_t dir, inv, d0, i0;
    memset(&d0, 0x5A, sizeof d0);
    memset(&i0, 0x5A, sizeof i0);
    dir = d0;
    inv = i0;
    int32_t err = -7;
    const int32_t lim = (1 << 30) - (1 << 24);
    const int32_t w[2] = {655, 65536 - 655};
    int32_t r[2] = {0, 1 << 28};
    /* z range +- 2 r_1 = +-2^29 + 1000 fits; the inverse's output does not. */
    assert_int_equal(pi_build(r, w, 2, (int64_t)1 << 31, -1000, 1000, -lim, lim, &dir, &inv, &err), PI_ERR_INVERSE);
    /* The same with a z range that +- 2 r_1 pushes past 2^30. */
    assert_int_equal(pi_build(r, w, 2, (int64_t)1 << 31, -(1 << 29) - 1, 1000, -lim, lim, &dir, &inv, &err),
                     PI_ERR_R_RANGE);
    assert_memory_equal(&dir, &d0, sizeof d0);
    assert_memory_equal(&inv, &i0, sizeof i0);
    assert_int_equal(err, -7);
    /* Smaller thresholds: the bound fits and the block is accepted. */
    r[1] = 1 << 20;
    assert_int_equal(pi_build(r, w, 2, (int64_t)1 << 31, -1000, 1000, -lim, lim, &dir, &inv, &err), PI_OK);
    assert_int_equal(inv.w_frac, 24); /* 1/w_0 = 100 needs 7 integer bits */
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_engine_equals_textbook),
        cmocka_unit_test(test_direct_vs_double),
        cmocka_unit_test(test_inverse_vs_double),
        cmocka_unit_test(test_round_trip_direct_of_inverse),
        cmocka_unit_test(test_single_operator_is_identity),
        cmocka_unit_test(test_play_composition),
        cmocka_unit_test(test_inverse_parameters),
        cmocka_unit_test(test_build_range_refusals),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
