/* Tests of b_online.c (on-line B update, RLS with forgetting) against an independent
 * double-precision RLS written here in plain matrix form, and of its bounds. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "b_online.h"
#include "lut.h"
#include "psa_loop.h"
#include "test_rng.h"

#define NG 33          /* grid entries: 0..4 mm at 0.125 mm (step 2^13 raw) */
#define STEP_LOG2 13
#define NMAX B_ONLINE_MAX_NODES

static int32_t prior[NG];

static void make_prior(void)
{
    for (int j = 0; j < NG; j++) {
        double q = j * 0.125;
        prior[j] = (int32_t)lround((0.6 + 0.1 * sin(q)) * 65536.0);
    }
}

/* Double reference: textbook RLS with forgetting, P kept as a full matrix and the
 * forgetting written as D (P - g g'/s) D; nodes every `stride` grid entries. */
typedef struct {
    int n, stride;
    double lam, p0, x0, h;       /* h: node spacing, mm */
    double th[NMAX], P[NMAX][NMAX];
} ref_rls_t;

static void ref_init(ref_rls_t *r, int n_nodes, int stride, double lam, double p0)
{
    memset(r, 0, sizeof *r);
    r->n = n_nodes;
    r->stride = stride;
    r->lam = lam;
    r->p0 = p0;
    r->h = stride * ldexp(1.0, STEP_LOG2) / 65536.0;
    for (int i = 0; i < n_nodes; i++)
        r->P[i][i] = p0;
}

static double ref_prior(double q)
{
    double h = ldexp(1.0, STEP_LOG2) / 65536.0;
    double x = fmin(fmax(q / h, 0.0), NG - 1.0);
    int j = (int)floor(x);
    if (j >= NG - 1)
        return prior[NG - 1] / 65536.0;
    return (prior[j] + (prior[j + 1] - prior[j]) * (x - j)) / 65536.0;
}

static void ref_sample(ref_rls_t *r, double q, double b)
{
    double phi[NMAX] = {0}, g[NMAX], k[NMAX];
    double x = fmin(fmax(q / r->h, 0.0), r->n - 1.0);
    int i = (int)floor(x);
    if (i >= r->n - 1)
        i = r->n - 2;
    phi[i] = 1.0 - (x - i);
    phi[i + 1] = x - i;
    double s = r->lam, pred = 0;
    for (int a = 0; a < r->n; a++) {
        g[a] = 0;
        for (int c = 0; c < r->n; c++)
            g[a] += r->P[a][c] * phi[c];
        pred += phi[a] * r->th[a];
    }
    for (int a = 0; a < r->n; a++)
        s += phi[a] * g[a];
    double e = b - ref_prior(q) - pred;
    double d[NMAX];
    for (int a = 0; a < r->n; a++) {
        k[a] = g[a] / s;
        r->th[a] += k[a] * e;
    }
    for (int a = 0; a < r->n; a++)
        for (int c = 0; c < r->n; c++)
            r->P[a][c] -= g[a] * g[c] / s;
    for (int a = 0; a < r->n; a++)
        d[a] = r->P[a][a] / r->lam <= r->p0 ? 1.0 / sqrt(r->lam) : 1.0;
    for (int a = 0; a < r->n; a++)
        for (int c = 0; c < r->n; c++)
            r->P[a][c] *= d[a] * d[c];
}

/* The written grid by definition: max(prior + correction, 0), then the largest function
 * below it with slope <= L: min over i of (b_i + L |i - j| h_grid). O(n^2). */
static void ref_grid(const ref_rls_t *r, double L, double out[NG])
{
    double h = ldexp(1.0, STEP_LOG2) / 65536.0, raw[NG];
    for (int j = 0; j < NG; j++) {
        double x = (double)j / r->stride;
        int i = (int)floor(x);
        double corr = i >= r->n - 1 ? r->th[r->n - 1] : r->th[i] + (r->th[i + 1] - r->th[i]) * (x - i);
        raw[j] = fmax(prior[j] / 65536.0 + corr, 0.0);
    }
    for (int j = 0; j < NG; j++) {
        double m = INFINITY;
        for (int i = 0; i < NG; i++)
            m = fmin(m, raw[i] + L * fabs((double)(i - j)) * h);
        out[j] = m;
    }
}

static void setup_lut(lut_t *l)
{
    make_prior();
    assert_int_equal(lut_init(l, prior, NG, 0, 1 << STEP_LOG2), LUT_OK);
}

static void test_config_and_grid_errors(void **state)
{
    (void)state;
    lut_t l;
    setup_lut(&l);
    static b_online_t bo;
    b_online_config_t c = b_online_default_config();
    c.lambda_q30 = (1 << 29) - 1;
    assert_int_equal(b_online_init(&bo, &c, &l), B_ONLINE_ERR_CONFIG);
    c = b_online_default_config();
    c.p0_q30 = 0;
    assert_int_equal(b_online_init(&bo, &c, &l), B_ONLINE_ERR_CONFIG);
    c = b_online_default_config();
    c.slope_max_q16 = 0;
    assert_int_equal(b_online_init(&bo, &c, &l), B_ONLINE_ERR_CONFIG);
    assert_ptr_equal(l.y_q16, prior); /* refused: the lut still reads the flashed entries */
    c = b_online_default_config();
    assert_int_equal(b_online_init(&bo, &c, &l), B_ONLINE_OK);
    assert_ptr_equal(l.y_q16, b_online_entries(&bo));
    assert_int_equal(bo.n_nodes, 9); /* 33 entries: every 2nd gives 17 > 16 nodes, so every 4th */
    assert_int_equal(bo.node_log2, 2);
}

/* The fixed-point RLS follows the double reference over 300 noisy samples of a drifted B. */
static void test_matches_double_reference(void **state)
{
    (void)state;
    test_rng_t rng;
    test_rng_seed(&rng, 7);
    for (int trial = 0; trial < 6; trial++) {
        lut_t l;
        setup_lut(&l);
        static b_online_t bo;
        b_online_config_t c = b_online_default_config();
        double lam = trial < 3 ? 0.875 : 0.97, p0 = trial % 3 == 0 ? 1.0 : trial % 3 == 1 ? 0.25 : 0.6;
        c.lambda_q30 = (int32_t)lround(lam * 1073741824.0);
        c.p0_q30 = (int32_t)lround(p0 * 1073741824.0);
        assert_int_equal(b_online_init(&bo, &c, &l), B_ONLINE_OK);
        ref_rls_t r;
        ref_init(&r, bo.n_nodes, 1 << bo.node_log2, c.lambda_q30 / 1073741824.0, c.p0_q30 / 1073741824.0);
        double max_th = 0, max_b = 0, max_p = 0;
        for (int k = 0; k < 300; k++) {
            /* visits concentrate on 0..2.5 mm, so nodes beyond see few samples (cap exercised) */
            double q = test_rng_uniform(&rng, -0.2, 2.5);
            double b_true = 0.6 + 0.1 * sin(q) + 0.15 + 0.05 * q + (k > 150 ? 0.1 : 0.0);
            int32_t q_raw = (int32_t)lround(q * 65536.0);
            int32_t b_raw = (int32_t)lround((b_true + 0.02 * test_rng_normal(&rng)) * 65536.0);
            b_online_sample(&bo, q_raw, b_raw);
            ref_sample(&r, q_raw / 65536.0, b_raw / 65536.0);
            for (int i = 0; i < bo.n_nodes; i++) {
                max_th = fmax(max_th, fabs(bo.theta_q16[i] / 65536.0 - r.th[i]));
                for (int j = 0; j < bo.n_nodes; j++)
                    max_p = fmax(max_p, fabs(bo.p_q30[i][j] / 1073741824.0 - r.P[i][j]));
                assert_true(bo.p_q30[i][i] <= c.p0_q30);   /* the cap */
                assert_int_equal(bo.p_q30[i][(i + 3) % bo.n_nodes], bo.p_q30[(i + 3) % bo.n_nodes][i]);
            }
        }
        if (getenv("B_ONLINE_PRINT"))
            printf("trial %d: max |dtheta| %.3g mm, |dP| %.3g, ", trial, max_th, max_p);
        double grid[NG];
        ref_grid(&r, 1.5, grid);
        for (int j = 0; j < NG; j++)
            max_b = fmax(max_b, fabs(b_online_entries(&bo)[j] / 65536.0 - grid[j]));
        if (getenv("B_ONLINE_PRINT"))
            printf("|dB| %.3g mm, B(1.25) err %.3g\n", max_b, lut_eval(&l, 81920) / 65536.0 - (0.6 + 0.1 * sin(1.25) + 0.25 + 0.0625));
        /* Measured (6 trials): theta within 7.5e-5 mm (5 LSB of Q16 after 300 samples), P
         * within 2.0e-8, the written grid within 5.3e-5 mm. */
        assert_true(max_th < 2e-4);
        assert_true(max_p < 6e-8);
        assert_true(max_b < 1.5e-4);
        /* and the learnt B is close to the truth where samples landed (0.02 mm noise, tau 8-33;
         * measured at most 0.007 mm off at q = 1.25 mm) */
        double q = 1.25, truth = 0.6 + 0.1 * sin(q) + 0.25 + 0.05 * q;
        assert_true(fabs(lut_eval(&l, (int32_t)lround(q * 65536.0)) / 65536.0 - truth) < 0.03);
    }
}

/* Bounds: a huge sample and a negative one leave B >= 0 and |B'| <= 1.5 on the whole grid,
 * and the running lut evaluates the RAM copy. */
static void test_bounds(void **state)
{
    (void)state;
    lut_t l;
    setup_lut(&l);
    static b_online_t bo;
    b_online_config_t c = b_online_default_config();
    assert_int_equal(b_online_init(&bo, &c, &l), B_ONLINE_OK);
    int32_t before = lut_eval(&l, 2 * 65536);
    b_online_sample(&bo, 2 * 65536, 10 * 65536);
    assert_true(lut_eval(&l, 2 * 65536) > before + 65536 / 4); /* the lut runs the learnt grid */
    int64_t lip = (int64_t)c.slope_max_q16 << STEP_LOG2 >> 16;
    for (int j = 0; j + 1 < NG; j++)
        assert_true(llabs((long long)b_online_entries(&bo)[j + 1] - b_online_entries(&bo)[j]) <= lip);
    for (int k = 0; k < 40; k++)
        b_online_sample(&bo, 65536, -5 * 65536);
    for (int j = 0; j < NG; j++)
        assert_true(b_online_entries(&bo)[j] >= 0);
    assert_int_equal(b_online_entries(&bo)[8], 0); /* at q = 1 mm the samples say 0 (floored) */
    for (int j = 0; j + 1 < NG; j++)
        assert_true(llabs((long long)b_online_entries(&bo)[j + 1] - b_online_entries(&bo)[j]) <= lip);
    assert_int_equal(prior[16], (int32_t)lround((0.6 + 0.1 * sin(2.0)) * 65536.0)); /* prior untouched */
}

/* A node no sample reaches keeps its prior (theta = 0 is only moved through the covariance
 * with visited nodes) and its variance stays at p0 instead of winding up. */
static void test_no_windup(void **state)
{
    (void)state;
    lut_t l;
    setup_lut(&l);
    static b_online_t bo;
    b_online_config_t c = b_online_default_config();
    assert_int_equal(b_online_init(&bo, &c, &l), B_ONLINE_OK);
    for (int k = 0; k < 500; k++)
        b_online_sample(&bo, 65536 / 2, prior[4] + 65536 / 10);
    int last = bo.n_nodes - 1;
    assert_int_equal(bo.p_q30[last][last], c.p0_q30);
    assert_int_equal(bo.theta_q16[last], 0);
    /* q = 0.5 mm is node 1 (nodes every 0.5 mm): it converged to the 0.1 mm offset (measured: 1 LSB) */
    assert_true(abs(bo.theta_q16[1] - 65536 / 10) <= 4);
}

/* The loop hook: an angle reading that completes an onset is learnt; none else is. */
static void test_loop_hook(void **state)
{
    (void)state;
    lut_t l;
    setup_lut(&l);
    static b_online_t bo;
    static psa_loop_t lp;
    b_online_config_t c = b_online_default_config();
    assert_int_equal(b_online_init(&bo, &c, &l), B_ONLINE_OK);
    psa_config_t pc;
    memset(&pc, 0, sizeof pc);
    pc.onset = onset_default_config();
    pc.onset.threshold_q16 = 65536 / 10;
    pc.onset.jump_ratio_q8 = 0;
    pc.onset.t_delay_us = 0;
    psa_init(&lp, &pc);
    psa_set_learning(&lp, &bo);
    onset_event_t ev;
    bool ready;
    /* encoder: down to q = 1 mm by t = 1 s, then up at 1 mm/s; the tip moves once q > 1.8 mm. */
    uint32_t frame = 40000;
    int samples = 0;
    for (uint32_t t = 0; t <= 3000000; t += 1000) {
        double q = t < 1000000 ? 2.0 - t * 1e-6 : 1.0 + (t - 1000000) * 1e-6;
        (void)psa_tick(&lp, t, PSA_NO_REFERENCE, (int32_t)lround(q * 65536.0), &ev, &ready);
        if (t == 1000000)
            (void)psa_reversal(&lp, t, (int32_t)lround(q * 65536.0), &ev);
        if (t % frame == 0) {
            double cdeg = t > 1000000 && q > 1.8 ? 10.0 * (q - 1.8) : 0.0;
            if (psa_observe_deg(&lp, t, (int32_t)lround(cdeg * 65536.0), true, &ev) && ev.reason <= ONSET_OK_COARSE)
                samples++;
        }
    }
    assert_int_equal(samples, 1);
    assert_int_equal(bo.samples, 1);
    assert_true(fabs(ev.b_q16 / 65536.0 - 0.8) < 0.05);
    psa_set_learning(&lp, NULL);
    assert_ptr_equal(lp.learn, NULL);
}

/* Publication (A/B): a sample is written into the copy the table does not point to, then the
 * table's pointer moves to it; the copy a preempted tick was reading is left complete and
 * unchanged. Stop points the table back at the flashed entries. */
static void test_sample_publishes_a_complete_copy(void **state)
{
    (void)state;
    lut_t l;
    setup_lut(&l);
    static b_online_t bo;
    static int32_t before[NG];
    b_online_config_t c = b_online_default_config();
    assert_int_equal(b_online_init(&bo, &c, &l), B_ONLINE_OK);
    for (int k = 0; k < 5; k++) {
        const int32_t *old = l.y_q16;
        memcpy(before, old, sizeof before);
        b_online_sample(&bo, (k % 7) * 65536 / 2, prior[(k % 7) * 4] + 65536 / 8);
        assert_true(l.y_q16 != old);
        assert_ptr_equal(l.y_q16, b_online_entries(&bo));
        assert_memory_equal(old, before, sizeof before); /* the copy read before is untouched */
        assert_true(memcmp(l.y_q16, before, sizeof before) != 0);
    }
    b_online_stop(&bo);
    assert_ptr_equal(l.y_q16, prior);
}

/* Rebind onto a table that carries the learnt B: the running B is unchanged (bit for bit, the
 * learnt grid already satisfies the bounds), theta is 0, P kept; another grid is refused. */
static void test_rebind_keeps_the_learnt_b(void **state)
{
    (void)state;
    lut_t l;
    setup_lut(&l);
    static b_online_t bo;
    static int32_t flashed[NG];
    b_online_config_t c = b_online_default_config();
    assert_int_equal(b_online_init(&bo, &c, &l), B_ONLINE_OK);
    for (int k = 0; k < 20; k++)
        b_online_sample(&bo, (k % 7) * 65536 / 2, prior[(k % 7) * 4] + 65536 / 8);
    memcpy(flashed, b_online_entries(&bo), sizeof flashed);
    int32_t p11 = bo.p_q30[1][1], p12 = bo.p_q30[1][2];
    lut_t l2, l3;
    assert_int_equal(lut_init(&l2, flashed, NG, 0, 1 << STEP_LOG2), LUT_OK);
    assert_int_equal(lut_init(&l3, flashed, NG, 65536, 1 << STEP_LOG2), LUT_OK);
    assert_int_equal(b_online_rebind(&bo, &l3), B_ONLINE_ERR_GRID);
    assert_ptr_equal(l3.y_q16, flashed);
    assert_int_equal(b_online_rebind(&bo, &l2), B_ONLINE_OK);
    assert_ptr_equal(l2.y_q16, b_online_entries(&bo));
    assert_memory_equal(b_online_entries(&bo), flashed, sizeof flashed);
    assert_int_equal(bo.theta_q16[1], 0);
    assert_int_equal(bo.p_q30[1][1], p11);
    assert_int_equal(bo.p_q30[1][2], p12);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_config_and_grid_errors),
        cmocka_unit_test(test_matches_double_reference),
        cmocka_unit_test(test_bounds),
        cmocka_unit_test(test_no_windup),
        cmocka_unit_test(test_loop_hook),
        cmocka_unit_test(test_rebind_keeps_the_learnt_b),
        cmocka_unit_test(test_sample_publishes_a_complete_copy),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
