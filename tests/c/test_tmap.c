/* Tests of the threshold map (table layout v3, docs/firmware.md "Threshold map"): the direct
 * model z = play(q; B), u = g(z), y = PI[u], c = f(y) and the compensator y* = f^-1(c*),
 * u* = PI^-1[y*], z* = g^-1(u*), q* = z* + dir s_f B(z*)/2 against a double reference
 * written here from those formulas (tests/c/support/ref_model.c for the play, the PI
 * operator and piecewise-linear functions; nothing of firmware/core), the round trip, the
 * loader's refusals, and v1/v2 tables unchanged. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "comp.h"
#include "playop.h"
#include "random_tables.h"
#include "table_write.h"

#define Q16(x) ((int32_t)lround((x) * 65536.0))

enum {
    GRID_LOG2 = 12,              /* B and f: step 1/16 over [-4, 4] */
    GRID_N = 129,
    MAP_LOG2 = 12,               /* g: step 1/16 over [-5, 5], covering B's grid */
    MAP_N = 161,
};

static fixture_blob_t blob;
static calib_t cal, cal2;
static ref_pwl_t rb, rf, rg;     /* double copies of the table's B, f and g entries */
static int32_t map_q16[MAP_N];

/* B varies 2x over the travel: 0.3 at the centre, 0.6 at the ends. */
static double b_fn(double q, const void *ctx)
{
    (void)ctx;
    return 0.3 + 0.3 * (q / 4) * (q / 4);
}

static double f_fn(double q, const void *ctx)
{
    return *(const int *)ctx * (10 * q + 0.3 * q * q * q);
}

/* g(z) = integral_0^z b_ref / B(s) ds (B held at its end value beyond [-4, 4]), b_ref such
 * that g(+-4) = +-4: u spans the same range as z there, so f's grid covers y. Simpson rule
 * on 64 panels per unit: far below one LSB. */
static double inv_b(double s)
{
    return 1.0 / b_fn(fmin(fmax(s, -4.0), 4.0), NULL);
}

static double integral_inv_b(double z)
{
    int m = 2 * (int)ceil(fabs(z) * 32) + 2;
    double h = z / m, acc = inv_b(0) + inv_b(z);
    for (int i = 1; i < m; i++)
        acc += (i & 1 ? 4 : 2) * inv_b(i * h);
    return acc * h / 3;
}

static void build_map(void)
{
    double b_ref = 4.0 / integral_inv_b(4.0);
    rg.x0 = -5.0;
    rg.h = (1 << MAP_LOG2) / 65536.0;
    rg.n = MAP_N;
    for (int i = 0; i < MAP_N; i++) {
        map_q16[i] = Q16(b_ref * integral_inv_b(rg.x0 + i * rg.h));
        rg.y[i] = map_q16[i] / 65536.0;
    }
}

/* The v2 table (B, f, n operators) and, when map is set, the same as v3 with the map. */
static size_t build(int f_sign, int n, const int32_t *rq, const int32_t *wq, int map)
{
    static int sign;
    sign = f_sign;
    fixture_grid_t g = {.q0 = -4.0, .step_log2 = GRID_LOG2, .n = GRID_N, .q_min = -4.5, .q_max = 4.5,
                        .f_kind = PST_F_REMAIN, .generation = 7};
    size_t len = fixture_build_pi(&blob, &g, b_fn, NULL, f_fn, &sign, 0, (uint16_t)n, rq, wq);
    rb.x0 = rf.x0 = -4.0;
    rb.h = rf.h = (1 << GRID_LOG2) / 65536.0;
    rb.n = rf.n = GRID_N;
    for (int i = 0; i < GRID_N; i++) {
        rb.y[i] = fixture_b(&blob, i);
        rf.y[i] = fixture_f(&blob, i);
    }
    if (map) {
        build_map();
        len = fixture_with_tmap(&blob, Q16(-5.0), 1 << MAP_LOG2, MAP_N, map_q16);
    }
    return len;
}

static double next_v(test_rng_t *r, double v, double amp)
{
    double u = test_rng_uniform(r, 0, 1);
    if (u < 0.03)
        return test_rng_uniform(r, -amp, amp);
    if (u < 0.04)
        return 0;
    return v;
}

static double pwl_max_slope(const ref_pwl_t *p)
{
    return ref_pwl_max_slope(p);
}

/* --------------------------------------------------------------------------- direct model */

/* playop_step with the map against z = play(q), u = g(z), y = PI[u], c = f(y) in double.
 * Bound: |f'| (W (g' z_err + 1/2) + 1/2) + 1/2 raw (z_err: the reindexing tables' error,
 * g' and W = sum w the Lipschitz constants of g and PI, each lookup/sum rounds by 1/2). */
static void run_direct(int f_sign, uint64_t seed)
{
    test_rng_t r;
    test_rng_seed(&r, seed);
    double worst = 0, ratio = 0;
    for (int trial = 0; trial < 8; trial++) {
        int n = 1 + (int)(test_rng_u64(&r) % PST_MAX_OPS);
        int32_t rq[PST_MAX_OPS], wq[PST_MAX_OPS];
        ref_pi_t dir;
        random_pi_build(&r, n, test_rng_uniform(&r, 0.05, 1.0), 0.1, 256, rq, wq, &dir);
        size_t len = build(f_sign, n, rq, wq, 1);
        assert_int_equal(calib_load(&cal, blob.bytes, len), CALIB_OK);
        assert_int_equal(cal.tmap.n, MAP_N);
        double W = 0;
        for (int i = 0; i < n; i++)
            W += dir.w[i];
        double tol = 1.0 + pwl_max_slope(&rf) * (W * (pwl_max_slope(&rg) * cal.z_err_q16 + 0.5) + 0.5) + 0.5;
        double q = test_rng_uniform(&r, -3, 3), v = 0.02;
        playop_t p;
        playop_reset(&p, &cal, Q16(q));
        ref_play_t rp = {.b = &rb, .f = &rf, .z = Q16(q) / 65536.0};
        ref_pi_reset(&dir, ref_pwl_eval(&rg, rp.z));
        for (int k = 0; k < 2500; k++) {
            v = next_v(&r, v, 0.05);
            q = fmin(fmax(q + v, -4.4), 4.4);
            int32_t qq = Q16(q);
            (void)ref_play_step(&rp, qq / 65536.0); /* moves the centre rp.z (returns f(z)) */
            double z = rp.z;
            double want = ref_pwl_eval(&rf, ref_pi_step(&dir, ref_pwl_eval(&rg, z))) * 65536.0;
            int32_t got = playop_step(&p, qq);
            double e = fabs(got - want);
            worst = fmax(worst, e);
            ratio = fmax(ratio, e / tol);
            assert_true(e <= tol);
        }
    }
    printf("tmap direct (f_sign %+d): worst %.2f raw, %.2f of the bound\n", f_sign, worst, ratio);
    assert_true(worst >= 0.5); /* live: the fixed-point error is seen */
    assert_true(worst <= 100); /* measured 31 / 34 raw (5e-4 deg) */
}

static void test_direct_vs_reference_increasing(void **state) { (void)state; run_direct(1, 51); }
static void test_direct_vs_reference_decreasing(void **state) { (void)state; run_direct(-1, 52); }

/* --------------------------------------------------------------------------- compensator */

typedef struct {
    double c_prev;
    int dir;
    ref_pi_t inv;
} ref_comp_map_t;

/* y* = f^-1(c*), u* = PI^-1[y*], z* = g^-1(u*), q* = z* + dir s_f B(z*)/2, saturated. */
static double ref_comp_map_step(ref_comp_map_t *rc, double c_ref)
{
    if (c_ref > rc->c_prev)
        rc->dir = 1;
    else if (c_ref < rc->c_prev)
        rc->dir = -1;
    rc->c_prev = c_ref;
    double y = ref_pwl_inverse(&rf, c_ref);
    double u = rc->inv.n ? ref_pi_step(&rc->inv, y) : y;
    double z = ref_pwl_inverse(&rg, u);
    int sf = rf.y[rf.n - 1] > rf.y[0] ? 1 : -1;
    double q = z + rc->dir * sf * ref_pwl_eval(&rb, z) / 2;
    return fmin(fmax(q, -4.5), 4.5);
}

/* comp_step with the map against the chain above: |q* error| <= comp_err (1 + max|B'|/2)
 * + 2 raw, comp_err = L (e_f sum|w'| + E_inv) + e_g^-1 the loader's bound. */
static void run_comp(int f_sign, uint64_t seed)
{
    test_rng_t r;
    test_rng_seed(&r, seed);
    double worst = 0, ratio = 0;
    for (int trial = 0; trial < 8; trial++) {
        int n = (int)(test_rng_u64(&r) % (PST_MAX_OPS + 1)); /* 0: the map alone */
        int32_t rq[PST_MAX_OPS], wq[PST_MAX_OPS];
        ref_pi_t dir = {0};
        ref_comp_map_t ref = {0};
        if (n) {
            random_pi_build(&r, n, test_rng_uniform(&r, 0.05, 1.0), 0.1, 256, rq, wq, &dir);
            ref_pi_inverse(&dir, &ref.inv);
        }
        size_t len = build(f_sign, n, n ? rq : NULL, n ? wq : NULL, 1);
        assert_int_equal(calib_load(&cal, blob.bytes, len), CALIB_OK);
        double tol = cal.comp_err_q16 * (1 + ref_pwl_max_slope(&rb) / 2) + 2.0;
        double lo = fmin(rf.y[0], rf.y[rf.n - 1]) + 1, hi = fmax(rf.y[0], rf.y[rf.n - 1]) - 1;
        double c = test_rng_uniform(&r, lo, hi), v = 0;
        comp_t cp;
        comp_reset(&cp, &cal, NULL, Q16(c));
        ref.c_prev = Q16(c) / 65536.0;
        if (n)
            ref_pi_reset(&ref.inv, ref_pwl_inverse(&rf, ref.c_prev));
        for (int k = 0; k < 2500; k++) {
            v = next_v(&r, v, 0.4);
            c = fmin(fmax(c + v, lo), hi);
            int32_t cq = Q16(c);
            double want = ref_comp_map_step(&ref, cq / 65536.0) * 65536.0;
            int32_t got = comp_step(&cp, cq);
            double e = fabs(got - want);
            worst = fmax(worst, e);
            ratio = fmax(ratio, e / tol);
            assert_true(e <= tol);
        }
    }
    printf("tmap comp (f_sign %+d): worst %.2f raw, %.2f of the bound (last comp_err %d raw, L %.3f)\n", f_sign,
           worst, ratio, (int)cal.comp_err_q16, cal.tmap_inv_lip_q16 / 65536.0);
    assert_true(worst >= 0.5);
    assert_true(worst <= 80); /* measured 26 raw (4e-4 units); the loader's bound is far looser */
}

static void test_comp_vs_reference_eq5(void **state) { (void)state; run_comp(1, 53); }
static void test_comp_vs_reference_eq9(void **state) { (void)state; run_comp(-1, 54); }

/* playop_step(comp_step(c*)) = c* once c* has moved, reversals included, within
 * 2 + |f'| (e_f + W (E_inv + g' (e_g^-1 + e_z + 3) + 1)) raw. */
enum { RT_MEASURED = 124 }; /* raw deg, worst of the two round-trip runs (124 / 104 raw = 2e-3 deg) */
static void run_round_trip(int f_sign, uint64_t seed)
{
    test_rng_t r;
    test_rng_seed(&r, seed);
    double worst = 0, worst_raw = 0;
    for (int trial = 0; trial < 8; trial++) {
        int n = 1 + (int)(test_rng_u64(&r) % PST_MAX_OPS);
        int32_t rq[PST_MAX_OPS], wq[PST_MAX_OPS];
        ref_pi_t dir;
        random_pi_build(&r, n, test_rng_uniform(&r, 0.05, 0.5), 0.1, 256, rq, wq, &dir);
        size_t len = build(f_sign, n, rq, wq, 1);
        assert_int_equal(calib_load(&cal, blob.bytes, len), CALIB_OK);
        double W = 0;
        for (int i = 0; i < n; i++)
            W += dir.w[i];
        /* y* within +-2.5: u* within r' of it, z* = g^-1(u*) inside B's grid and q* inside
         * the travel, so no saturation breaks the identity. */
        double ca = ref_pwl_eval(&rf, -2.5), cb = ref_pwl_eval(&rf, 2.5);
        double lo = fmin(ca, cb), hi = fmax(ca, cb);
        double tol = 2.0 + ref_pwl_max_slope(&rf) *
                               (cal.f_inv_err_q16 +
                                W * (cal.pi_inv_err_q16 +
                                     pwl_max_slope(&rg) * (cal.tmap_inv_err_q16 + cal.z_err_q16 + 3.0) + 1.0));
        comp_t cp;
        playop_t p;
        double c = 0.5 * (lo + hi), v = 0.2;
        comp_reset(&cp, &cal, NULL, Q16(c));
        playop_reset(&p, &cal, cp.q_ref_q16);
        int moved = 0;
        for (int k = 0; k < 2500; k++) {
            v = next_v(&r, v, 0.4);
            c = fmin(fmax(c + v, lo), hi);
            int32_t cq = Q16(c);
            int32_t got = playop_step(&p, comp_step(&cp, cq));
            moved |= cp.dir != 0;
            if (moved) {
                worst = fmax(worst, fabs((double)got - cq) / tol);
                worst_raw = fmax(worst_raw, fabs((double)got - cq));
                assert_true(fabs((double)got - cq) <= tol);
            }
        }
    }
    printf("tmap round trip (f_sign %+d): worst %.2f raw, %.3f of the bound\n", f_sign, worst_raw, worst);
    assert_true(worst_raw <= 3 * RT_MEASURED);
}

static void test_round_trip_increasing(void **state) { (void)state; run_round_trip(1, 55); }
static void test_round_trip_decreasing(void **state) { (void)state; run_round_trip(-1, 56); }

/* --------------------------------------------------------------------------- layout */

static const int32_t R4[4] = {0, 6554, 13107, 26214};     /* 0, 0.1, 0.2, 0.4 */
static const int32_t W4[4] = {32768, 16384, 8192, 8192};  /* 0.5, 0.25, 0.125, 0.125 */

static pst_header_v3_t header3(void)
{
    pst_header_v3_t h;
    memcpy(&h, blob.bytes, sizeof h);
    return h;
}

static void put_header3(const pst_header_v3_t *h)
{
    memcpy(blob.bytes, h, sizeof *h);
    fixture_reseal(&blob);
}

/* The writer lays out v3 only with a map; without one it is the v2 table byte for byte. */
static void test_layout_v3(void **state)
{
    (void)state;
    size_t len2 = build(1, 4, R4, W4, 0);
    pst_header_t h2;
    memcpy(&h2, blob.bytes, sizeof h2);
    assert_int_equal(h2.layout_version, 2);
    assert_int_equal(h2.header_size, 60);
    static uint8_t v2[PST_MAX_TABLE_SIZE];
    memcpy(v2, blob.bytes, len2);
    /* table_write_map without a map = table_write. */
    static uint8_t again[PST_MAX_TABLE_SIZE];
    static int32_t bb[GRID_N], ff[GRID_N];
    memcpy(bb, blob.bytes + h2.b.offset, sizeof bb);
    memcpy(ff, blob.bytes + h2.f.offset, sizeof ff);
    pst_header_t hin = h2;
    hin.layout_version = 0;
    pst_grid_t none = {0};
    assert_int_equal(table_write_map(again, sizeof again, &hin, bb, ff, R4, W4, &none, NULL), len2);
    assert_memory_equal(again, v2, len2);
    assert_int_equal(table_write_map(again, sizeof again, &hin, bb, ff, R4, W4, NULL, NULL), len2);
    assert_memory_equal(again, v2, len2);

    size_t len3 = build(1, 4, R4, W4, 1);
    pst_header_v3_t h3 = header3();
    assert_int_equal(h3.base.layout_version, 3);
    assert_int_equal(h3.base.header_size, sizeof(pst_header_v3_t));
    assert_int_equal(len3, len2 + 12 + 4 * MAP_N);
    assert_int_equal(h3.base.b.offset, 72);
    assert_int_equal(h3.tmap.offset, h3.base.pi.offset + 8 * 4);
    assert_int_equal(h3.tmap.n, MAP_N);
    assert_int_equal(h3.base.crc32, calib_table_crc(blob.bytes, (uint32_t)len3));
    assert_int_equal(calib_load(&cal, blob.bytes, len3), CALIB_OK);
    assert_int_equal(cal.tmap.n, MAP_N);
    assert_true(cal.tmap_inv.n >= 2);
    assert_true(cal.tmap_inv_err_q16 >= 1);
    /* L = max dz/du = max B / b_ref: between 1 and 2 for this B. */
    assert_true(cal.tmap_inv_lip_q16 > 65536 && cal.tmap_inv_lip_q16 < 2 * 65536);
    assert_true(cal.comp_err_q16 <= cal.precision_ceiling_q16);
    /* A map with version 1 or 2 is refused by the writer; so is a map of 257 entries. */
    pst_grid_t tm = {.x0_q16 = Q16(-5.0), .step_q16 = 1 << MAP_LOG2, .n = MAP_N};
    hin.layout_version = 2;
    assert_int_equal(table_write_map(again, sizeof again, &hin, bb, ff, R4, W4, &tm, map_q16), 0);
    hin.layout_version = 0;
    tm.n = PST_MAX_ENTRIES + 1;
    assert_int_equal(table_write_map(again, sizeof again, &hin, bb, ff, R4, W4, &tm, map_q16), 0);
    /* A v3 table without a map loads as the v2 table. */
    build(1, 4, R4, W4, 0);
    size_t len30 = fixture_with_tmap(&blob, 0, 0, 0, NULL);
    assert_int_equal(len30, len2 + 12);
    assert_int_equal(calib_load(&cal, blob.bytes, len30), CALIB_OK);
    assert_int_equal(cal.tmap.n, 0);
    assert_int_equal(cal.tmap_inv.n, 0);
}

/* Without a map (v2, and v3 with n = 0) the direct model and the compensator are bit for bit
 * those of the v2 table; a v2 table leaves the map fields empty. */
static void test_no_map_bit_for_bit(void **state)
{
    (void)state;
    for (int n = 0; n <= 4; n += 4) {
        size_t len = build(1, n, n ? R4 : NULL, n ? W4 : NULL, 0);
        assert_int_equal(calib_load(&cal, blob.bytes, len), CALIB_OK);
        assert_int_equal(cal.tmap.n, 0);
        assert_int_equal(cal.tmap_inv_lip_q16, 65536);
        static fixture_blob_t keep; /* cal reads its entries in place: keep them */
        keep = blob;
        assert_int_equal(calib_load(&cal, keep.bytes, len), CALIB_OK);
        size_t len3 = fixture_with_tmap(&blob, 0, 0, 0, NULL);
        assert_int_equal(calib_load(&cal2, blob.bytes, len3), CALIB_OK);
        playop_t a, b;
        comp_t ca, cb;
        playop_reset(&a, &cal, Q16(0.3));
        playop_reset(&b, &cal2, Q16(0.3));
        comp_reset(&ca, &cal, NULL, Q16(1.0));
        comp_reset(&cb, &cal2, NULL, Q16(1.0));
        test_rng_t r;
        test_rng_seed(&r, 57);
        double q = 0, v = 0.03;
        for (int k = 0; k < 3000; k++) {
            v = next_v(&r, v, 0.06);
            q = fmin(fmax(q + v, -4.4), 4.4);
            assert_int_equal(playop_step(&a, Q16(q)), playop_step(&b, Q16(q)));
            assert_int_equal(comp_step(&ca, Q16(8 * q)), comp_step(&cb, Q16(8 * q)));
        }
    }
}

/* Each refusal returns its code and leaves the loaded table as it was. */
typedef void (*edit_fn)(void);

static void e_not_monotone(void) { map_q16[80] = map_q16[79]; }
static void e_decreasing(void) { for (int i = 0; i < MAP_N; i++) map_q16[i] = -map_q16[i]; }
static void e_overflow(void) { for (int i = 0; i < MAP_N; i++) map_q16[i] += (1 << 30) - Q16(4.0); }
static void e_overflow_low(void) { for (int i = 0; i < MAP_N; i++) map_q16[i] -= (1 << 30); }
/* A flat stretch (1 raw over a step): g^-1's slope 4096, its error bound far above B/16. */
static void e_flat(void) { for (int i = 81; i < MAP_N; i++) map_q16[i] = map_q16[80] + (i - 80); }

static void h_step(pst_header_v3_t *h) { h->tmap.step_q16 = 3000; }
static void h_count(pst_header_v3_t *h) { h->tmap.n = 1; }
static void h_count_big(pst_header_v3_t *h) { h->tmap.n = PST_MAX_ENTRIES + 1; }
static void h_misaligned(pst_header_v3_t *h) { h->tmap.offset += 2; }
static void h_in_header(pst_header_v3_t *h) { h->tmap.offset = 64; }
static void h_on_b(pst_header_v3_t *h) { h->tmap.offset = h->base.b.offset; }
static void h_on_ops(pst_header_v3_t *h) { h->tmap.offset = h->base.pi.offset; h->tmap.n = 8; }
static void h_beyond(pst_header_v3_t *h) { h->tmap.offset += 4; }
static void h_not_covering(pst_header_v3_t *h) { h->tmap.x0_q16 = Q16(-3.5); }
static void h_offset_without_map(pst_header_v3_t *h) { h->tmap.n = 0; }
static void h_v2_with_map(pst_header_v3_t *h) { h->base.layout_version = 2; }
static void h_v3_short_header(pst_header_v3_t *h) { h->base.header_size = 60; }
static void h_range_z(pst_header_v3_t *h) { h->tmap.x0_q16 = INT32_MAX - (MAP_N - 1) * (1 << MAP_LOG2) - 4; }

static void test_refusals_keep_the_table(void **state)
{
    (void)state;
    static const struct {
        edit_fn edit;
        calib_status_t st;
    } entries[] = {
        {e_not_monotone, CALIB_ERR_TMAP_MONOTONE}, {e_decreasing, CALIB_ERR_TMAP_MONOTONE},
        {e_overflow, CALIB_ERR_TMAP_RANGE},        {e_overflow_low, CALIB_ERR_TMAP_RANGE},
        {e_flat, CALIB_ERR_PRECISION},
    };
    static const struct {
        void (*edit)(pst_header_v3_t *);
        calib_status_t st;
    } headers[] = {
        {h_step, CALIB_ERR_TMAP_GRID},        {h_count, CALIB_ERR_TMAP_GRID},
        {h_count_big, CALIB_ERR_TMAP_GRID},   {h_misaligned, CALIB_ERR_TMAP_GRID},
        {h_in_header, CALIB_ERR_TMAP_GRID},   {h_on_b, CALIB_ERR_TMAP_GRID},
        {h_on_ops, CALIB_ERR_TMAP_GRID},      {h_beyond, CALIB_ERR_TMAP_GRID},
        {h_not_covering, CALIB_ERR_TMAP_GRID}, {h_offset_without_map, CALIB_ERR_TMAP_GRID},
        {h_v2_with_map, CALIB_ERR_VERSION},   {h_v3_short_header, CALIB_ERR_VERSION},
        {h_range_z, CALIB_ERR_TMAP_GRID},
    };
    /* The last good table: a v3 table with a map. */
    static fixture_blob_t good;
    size_t len = build(1, 4, R4, W4, 1);
    good = blob;
    assert_int_equal(calib_load(&cal, good.bytes, len), CALIB_OK);
    static calib_t before;
    memcpy(&before, &cal, sizeof cal);
    for (size_t i = 0; i < sizeof entries / sizeof entries[0]; i++) {
        build(1, 4, R4, W4, 0);
        build_map();
        entries[i].edit();
        size_t l = fixture_with_tmap(&blob, Q16(-5.0), 1 << MAP_LOG2, MAP_N, map_q16);
        assert_true(l > 0);
        calib_status_t st = calib_load(&cal, blob.bytes, l);
        if (st != entries[i].st)
            printf("entry edit %zu: got %d (%s)\n", i, st, calib_status_str(st));
        assert_int_equal(st, entries[i].st);
        assert_memory_equal(&cal, &before, sizeof cal);
    }
    for (size_t i = 0; i < sizeof headers / sizeof headers[0]; i++) {
        blob = good;
        pst_header_v3_t h = header3();
        headers[i].edit(&h);
        put_header3(&h);
        calib_status_t st = calib_load(&cal, blob.bytes, len);
        if (st != headers[i].st)
            printf("header edit %zu: got %d (%s)\n", i, st, calib_status_str(st));
        assert_int_equal(st, headers[i].st);
        assert_memory_equal(&cal, &before, sizeof cal);
    }
    /* A corrupted map entry without a new CRC: the CRC refuses it. */
    blob = good;
    blob.bytes[header3().tmap.offset + 4 * 40] ^= 0x10;
    assert_int_equal(calib_load(&cal, blob.bytes, len), CALIB_ERR_CRC);
    assert_memory_equal(&cal, &before, sizeof cal);
    /* Thresholds whose u range +- 2 r leaves +-2^30: the operators' input is u now. */
    build(1, 4, R4, W4, 0);
    build_map();
    for (int i = 0; i < MAP_N; i++)
        map_q16[i] += (1 << 30) - Q16(5.5); /* u up to 2^30 - 1.5 units, 2 r_max = 0.8 */
    static const int32_t R4w[4] = {0, 6554, 13107, Q16(1.0)};
    size_t l = fixture_with_ops(&blob, 0, 4, R4w, W4);
    l = fixture_with_tmap(&blob, Q16(-5.0), 1 << MAP_LOG2, MAP_N, map_q16);
    assert_int_equal(calib_load(&cal, blob.bytes, l), CALIB_ERR_PI_R_RANGE);
    assert_memory_equal(&cal, &before, sizeof cal);
    assert_string_equal(calib_status_str(CALIB_ERR_TMAP_MONOTONE), "threshold map not strictly increasing");
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_layout_v3),
        cmocka_unit_test(test_no_map_bit_for_bit),
        cmocka_unit_test(test_refusals_keep_the_table),
        cmocka_unit_test(test_direct_vs_reference_increasing),
        cmocka_unit_test(test_direct_vs_reference_decreasing),
        cmocka_unit_test(test_comp_vs_reference_eq5),
        cmocka_unit_test(test_comp_vs_reference_eq9),
        cmocka_unit_test(test_round_trip_increasing),
        cmocka_unit_test(test_round_trip_decreasing),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
