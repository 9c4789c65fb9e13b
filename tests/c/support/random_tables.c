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
