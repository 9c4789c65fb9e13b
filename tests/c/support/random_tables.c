/* Random calibration tables: smooth positive B with |B'| < 1.5, strictly monotone f. */
#include "random_tables.h"

#include <math.h>

static double b_fn(double q, const void *ctx)
{
    const random_table_t *t = ctx;
    double b = t->b0;
    for (int k = 0; k < 3; k++)
        b += t->ba[k] * exp(-(q - t->bm[k]) * (q - t->bm[k]) / (2 * t->bs[k] * t->bs[k]));
    return b;
}

static double f_fn(double q, const void *ctx)
{
    const random_table_t *t = ctx;
    double f = t->g1 * q;
    for (int k = 0; k < 3; k++)
        f += t->fc[k] * tanh((q - t->fm[k]) / t->fs[k]);
    return t->f_sign * f;
}

size_t random_table_build(test_rng_t *r, fixture_blob_t *blob, ref_pwl_t *ref_b, ref_pwl_t *ref_f,
                          int f_sign)
{
    random_table_t t;
    t.b0 = test_rng_uniform(r, 0.05, 0.6);
    for (int k = 0; k < 3; k++) {
        t.bs[k] = test_rng_uniform(r, 0.4, 2.0);
        /* peak slope of a Gaussian bump is a / (s sqrt(e)): keep the sum below 1.5 */
        t.ba[k] = test_rng_uniform(r, 0.0, 0.5) * t.bs[k] * 1.6487 * 0.9;
        t.bm[k] = test_rng_uniform(r, -3.5, 3.5);
        t.fc[k] = test_rng_uniform(r, 0.0, 4.0);
        t.fm[k] = test_rng_uniform(r, -3.0, 3.0);
        t.fs[k] = test_rng_uniform(r, 0.3, 2.0);
    }
    t.g1 = test_rng_uniform(r, 2.0, 15.0);
    t.f_sign = f_sign;
    fixture_grid_t g = {.q0 = -4.0, .step_log2 = 12 + (int)(test_rng_u64(r) % 4), .n = 0,
                        .q_min = -4.5, .q_max = 4.5, .f_kind = PST_F_REMAIN, .generation = 1};
    g.n = (uint16_t)(8.0 * 65536.0 / (1 << g.step_log2) + 1.0); /* cover [-4, 4] */
    size_t len = fixture_build(blob, &g, b_fn, &t, f_fn, &t);
    ref_b->x0 = ref_f->x0 = g.q0;
    ref_b->h = ref_f->h = (1 << g.step_log2) / 65536.0;
    ref_b->n = ref_f->n = g.n;
    for (int i = 0; i < g.n; i++) {
        ref_b->y[i] = fixture_b(blob, i);
        ref_f->y[i] = fixture_f(blob, i);
    }
    return len;
}

void random_pi_build(test_rng_t *r, int n, double r_max, double w0_min, int sum_err_raw, int32_t *r_q16,
                     int32_t *w_q16, ref_pi_t *ref)
{
    /* Thresholds: sorted uniform draws, at least one raw unit apart. */
    r_q16[0] = 0;
    for (int i = 1; i < n; i++) {
        int32_t v = (int32_t)llround(test_rng_uniform(r, 0, r_max) * 65536.0);
        int k = i;
        while (k > 1 && r_q16[k - 1] > v) {
            r_q16[k] = r_q16[k - 1];
            k--;
        }
        r_q16[k] = v;
    }
    for (int i = 1; i < n; i++)
        if (r_q16[i] <= r_q16[i - 1])
            r_q16[i] = r_q16[i - 1] + 1;
    double w[32], sum = 0;
    w[0] = test_rng_uniform(r, w0_min, 1.0);
    for (int i = 1; i < n; i++)
        w[i] = test_rng_uniform(r, 0, 1) < 0.33 ? 0.0 : test_rng_uniform(r, 0, 1.0);
    for (int i = 1; i < n; i++)
        sum += w[i];
    /* Scale the others so that w_0 keeps its drawn share of the unit sum. */
    int64_t raw_sum = 0;
    w_q16[0] = (int32_t)llround(w[0] * 65536.0);
    for (int i = 1; i < n; i++) {
        w_q16[i] = sum > 0 ? (int32_t)llround(w[i] / sum * (1.0 - w[0]) * 65536.0) : 0;
        raw_sum += w_q16[i];
    }
    raw_sum += w_q16[0];
    int64_t target = 65536 + (sum_err_raw ? (int64_t)(test_rng_u64(r) % (2u * (uint64_t)sum_err_raw + 1u)) - sum_err_raw : 0);
    w_q16[0] += (int32_t)(target - raw_sum); /* w_0 absorbs the rounding: stays >= w0_min - 2^-8 */
    ref->n = n;
    for (int i = 0; i < n; i++) {
        ref->r[i] = r_q16[i] / 65536.0;
        ref->w[i] = w_q16[i] / 65536.0;
    }
}
