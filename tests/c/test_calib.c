/* Tests of the table loader: acceptance, every refusal, and that a refusal changes nothing. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <math.h>
#include <string.h>
#include <cmocka.h>

#include "calib.h"
#include "ref_model.h"
#include "table_fixture.h"

static double b_bump(double q, const void *ctx)
{
    (void)ctx; /* wider near the straight configuration, as in the paper's Fig. 8 */
    return 0.4 + 0.5 * exp(-q * q / 2.0);
}
static double f_cubic(double q, const void *ctx)
{
    (void)ctx;
    return 10.0 * q + 0.3 * q * q * q;
}
static double f_decreasing(double q, const void *ctx)
{
    (void)ctx;
    return -12.0 * q;
}
static double f_not_monotone(double q, const void *ctx)
{
    (void)ctx;
    return q * q;
}
static double b_steep(double q, const void *ctx)
{
    (void)ctx;
    return q > 0 ? 3.0 * q : 0.0; /* dB/dq = 3 > 2 */
}

static const fixture_grid_t GRID = {.q0 = -4.0, .step_log2 = 13, .n = 65, .q_min = -4.0, .q_max = 4.0,
                                    .f_kind = PST_F_REMAIN, .generation = 7};

static fixture_blob_t blob;
static calib_t cal, snapshot;

static size_t build(fixture_fn b, fixture_fn f)
{
    return fixture_build(&blob, &GRID, b, NULL, f, NULL);
}

/* Load expecting refusal st, and check the target was not touched. */
static void expect_refused(size_t len, calib_status_t st)
{
    memset(&cal, 0x3C, sizeof cal);
    memcpy(&snapshot, &cal, sizeof cal);
    assert_int_equal(calib_load(&cal, blob.bytes, len), st);
    assert_memory_equal(&cal, &snapshot, sizeof cal);
    assert_non_null(calib_status_str(st));
}

static void test_valid_table_loads(void **state)
{
    (void)state;
    size_t len = build(b_bump, f_cubic);
    assert_int_equal(len, 60 + 8 * 65);
    assert_int_equal(calib_load(&cal, blob.bytes, len), CALIB_OK);
    assert_int_equal(cal.generation, 7);
    assert_int_equal(cal.f_sign, 1);
    assert_int_equal(cal.f_kind, PST_F_REMAIN);
    assert_int_equal(cal.q_min_q16, -4 * 65536);
    /* The derived inverse reproduces q from f(q) within its reported bound. */
    assert_true(cal.f_inv_err_q16 >= 1 && cal.f_inv_err_q16 < 65536 / 100);
    for (double q = -3.9; q < 3.9; q += 0.01) {
        int32_t c = lut_eval(&cal.f, (int32_t)lround(q * 65536));
        int32_t qb = lut_eval(&cal.f_inv, c);
        assert_true(fabs(qb / 65536.0 - q) <= (cal.f_inv_err_q16 + 2) / 65536.0 + 1.0 / 65536);
    }
}

static void test_decreasing_f_loads_with_negative_sign(void **state)
{
    (void)state;
    size_t len = build(b_bump, f_decreasing);
    assert_int_equal(calib_load(&cal, blob.bytes, len), CALIB_OK);
    assert_int_equal(cal.f_sign, -1);
}

static void test_size_magic_version(void **state)
{
    (void)state;
    size_t len = build(b_bump, f_cubic);
    expect_refused(0, CALIB_ERR_SIZE);
    expect_refused(59, CALIB_ERR_SIZE);
    expect_refused(len - 1, CALIB_ERR_SIZE); /* truncated upload */
    assert_int_equal(calib_load(&cal, NULL, len), CALIB_ERR_SIZE);

    blob.bytes[0] ^= 0xFF;
    expect_refused(len, CALIB_ERR_MAGIC);
    blob.bytes[0] ^= 0xFF;

    pst_header_t hd;
    memcpy(&hd, blob.bytes, sizeof hd);
    hd.layout_version = PST_LAYOUT_VERSION + 1;
    memcpy(blob.bytes, &hd, sizeof hd);
    fixture_reseal(&blob);
    expect_refused(len, CALIB_ERR_VERSION);
    hd.layout_version = 0;
    memcpy(blob.bytes, &hd, sizeof hd);
    fixture_reseal(&blob);
    expect_refused(len, CALIB_ERR_VERSION);
}

/* Every single-bit flip anywhere in the table is caught by the CRC (or an earlier check). */
static void test_every_bit_flip_refused(void **state)
{
    (void)state;
    size_t len = build(b_bump, f_cubic);
    for (size_t i = 0; i < len; i++) {
        for (int bit = 0; bit < 8; bit += 3) {
            blob.bytes[i] ^= (uint8_t)(1u << bit);
            calib_status_t st = calib_load(&cal, blob.bytes, len);
            assert_int_not_equal(st, CALIB_OK);
            blob.bytes[i] ^= (uint8_t)(1u << bit);
        }
    }
    assert_int_equal(calib_load(&cal, blob.bytes, len), CALIB_OK);
}

/* A table written under another layout version fails its CRC: the version is the seed. */
static void test_crc_seeded_with_layout_version(void **state)
{
    (void)state;
    size_t len = build(b_bump, f_cubic);
    pst_header_t hd;
    memcpy(&hd, blob.bytes, sizeof hd);
    assert_int_equal(hd.crc32, calib_table_crc(blob.bytes, (uint32_t)len));
    hd.crc32 = 0;
    memcpy(blob.bytes, &hd, sizeof hd);
    /* Plain zlib-style CRC with seed 0 is not what the loader accepts. */
    extern uint32_t ps_crc32_update(uint32_t, const void *, size_t);
    hd.crc32 = ps_crc32_update(0, blob.bytes, len);
    memcpy(blob.bytes, &hd, sizeof hd);
    expect_refused(len, CALIB_ERR_CRC);
}

static void edit_header(void (*edit)(pst_header_t *))
{
    pst_header_t hd;
    memcpy(&hd, blob.bytes, sizeof hd);
    edit(&hd);
    memcpy(blob.bytes, &hd, sizeof hd);
    fixture_reseal(&blob);
}
static void e_frac(pst_header_t *h) { h->q_frac_bits = 15; }
static void e_unit(pst_header_t *h) { h->q_unit = 9; }
static void e_v1_with_ops(pst_header_t *h) { h->layout_version = 1; h->pi.n = 1; }
static void e_v1_with_offset(pst_header_t *h) { h->layout_version = 1; h->pi.offset = 64; }
static void e_qrange(pst_header_t *h) { h->q_max_q16 = h->q_min_q16; }
static void e_n(pst_header_t *h) { h->b.n = 1; }
static void e_nbig(pst_header_t *h) { h->f.n = PST_MAX_ENTRIES + 1; }
static void e_step(pst_header_t *h) { h->f.step_q16 = 3000; }
static void e_offset(pst_header_t *h) { h->f.offset = (uint16_t)(h->total_size - 8); }
static void e_misaligned(pst_header_t *h) { h->b.offset += 2; }
static void e_overlap_header(pst_header_t *h) { h->b.offset = 8; }

static void test_header_refusals(void **state)
{
    (void)state;
    struct { void (*edit)(pst_header_t *); calib_status_t st; } cases[] = {
        {e_frac, CALIB_ERR_FORMAT}, {e_unit, CALIB_ERR_FORMAT}, {e_v1_with_ops, CALIB_ERR_FORMAT},
        {e_v1_with_offset, CALIB_ERR_FORMAT},
        {e_qrange, CALIB_ERR_Q_RANGE}, {e_n, CALIB_ERR_GRID}, {e_nbig, CALIB_ERR_GRID},
        {e_step, CALIB_ERR_GRID}, {e_offset, CALIB_ERR_GRID}, {e_misaligned, CALIB_ERR_GRID},
        {e_overlap_header, CALIB_ERR_GRID},
    };
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        size_t len = build(b_bump, f_cubic);
        edit_header(cases[k].edit);
        expect_refused(len, cases[k].st);
    }
}

static void test_content_refusals(void **state)
{
    (void)state;
    size_t len = build(b_bump, f_not_monotone);
    expect_refused(len, CALIB_ERR_F_NOT_MONOTONE);
    len = build(b_steep, f_cubic);
    expect_refused(len, CALIB_ERR_B_SLOPE);
    len = build(b_bump, f_cubic);
    int32_t neg = -1; /* every width just below zero: no slope problem, only the sign */
    for (int i = 0; i < GRID.n; i++)
        memcpy(blob.bytes + 60 + 4 * i, &neg, 4);
    fixture_reseal(&blob);
    expect_refused(len, CALIB_ERR_B_NEGATIVE);
}

/* A refused upload leaves a running calibration exactly as it was. */
static void test_refusal_keeps_last_good_table(void **state)
{
    (void)state;
    static fixture_blob_t good;
    size_t len = fixture_build(&good, &GRID, b_bump, NULL, f_cubic, NULL);
    assert_int_equal(calib_load(&cal, good.bytes, len), CALIB_OK);
    memcpy(&snapshot, &cal, sizeof cal);
    size_t bad_len = build(b_bump, f_not_monotone);
    assert_int_equal(calib_load(&cal, blob.bytes, bad_len), CALIB_ERR_F_NOT_MONOTONE);
    assert_memory_equal(&cal, &snapshot, sizeof cal);
    assert_int_equal(lut_eval(&cal.f, 65536), (int32_t)lround(10.3 * 65536));
}

/* ---- Layout v2: the transition's operator block (pst_pi_t). ---- */

/* A valid 4-operator block over the GRID's travel (8 units): thresholds spread up to
 * 1.2 units, weights summing to exactly 1. */
static const int32_t R4[4] = {0, 13107, 39321, 78643};      /* 0, 0.2, 0.6, 1.2 */
static const int32_t W4[4] = {26214, 19661, 13107, 6554};   /* 0.4, 0.3, 0.2, 0.1 */

static size_t build_pi(uint16_t version, uint16_t n, const int32_t *r, const int32_t *w)
{
    return fixture_build_pi(&blob, &GRID, b_bump, NULL, f_cubic, NULL, version, n, r, w);
}

static void test_v2_table_with_operators_loads(void **state)
{
    (void)state;
    size_t len = build_pi(0, 4, R4, W4);
    assert_int_equal(len, 60 + 8 * 65 + 8 * 4);
    pst_header_t hd;
    memcpy(&hd, blob.bytes, sizeof hd);
    assert_int_equal(hd.layout_version, 2);
    assert_int_equal(hd.pi.n, 4);
    assert_int_equal(hd.pi.offset, 60 + 8 * 65);
    assert_int_equal(calib_load(&cal, blob.bytes, len), CALIB_OK);
    assert_int_equal(cal.pi_dir.n, 4);
    assert_int_equal(cal.pi_inv.n, 4);
    assert_memory_equal(cal.pi_dir.r_q16, R4, sizeof R4);
    assert_memory_equal(cal.pi_dir.w, W4, sizeof W4);
    assert_int_equal(cal.pi_dir.w_frac, 16);
    /* 1/w_0 = 2.5 < 2: the loader keeps 29 fractional bits for the inverse weights. */
    assert_int_equal(cal.pi_inv.w_frac, 29);
    /* 1/2 + 1/2 sum|w'| (sum|w'| = 2/w_0 - 1/W = 4) + a few 2^-30 raw: 2.5, ceiled to 3. */
    assert_int_equal(cal.pi_inv_err_q16, 3);
    /* The operator block is copied (the grids are read in place): editing it in the blob
     * afterwards changes nothing loaded. */
    memset(blob.bytes + hd.pi.offset, 0x7F, 32);
    assert_memory_equal(cal.pi_dir.r_q16, R4, sizeof R4);
    assert_int_equal(cal.pi_inv.r_q16[0], 0);
}

/* v1 tables (pi all zero, CRC seeded with 1) and v2 tables without operators load as the
 * pure play: no operators on either side. */
static void test_v1_and_empty_v2_load_as_pure_play(void **state)
{
    (void)state;
    size_t len = build_pi(1, 0, NULL, NULL);
    pst_header_t hd;
    memcpy(&hd, blob.bytes, sizeof hd);
    assert_int_equal(hd.layout_version, 1);
    assert_int_equal(hd.pi.n, 0);
    assert_int_equal(hd.pi.offset, 0);
    extern uint32_t ps_crc32_update(uint32_t, const void *, size_t);
    pst_header_t z = hd;
    z.crc32 = 0;
    static uint8_t copy[PST_MAX_TABLE_SIZE];
    memcpy(copy, blob.bytes, len);
    memcpy(copy, &z, sizeof z);
    assert_int_equal(hd.crc32, ps_crc32_update(1, copy, len)); /* seed = the table's own version */
    assert_int_equal(calib_load(&cal, blob.bytes, len), CALIB_OK);
    assert_int_equal(cal.pi_dir.n, 0);
    assert_int_equal(cal.pi_inv.n, 0);
    len = build_pi(2, 0, NULL, NULL);
    assert_int_equal(calib_load(&cal, blob.bytes, len), CALIB_OK);
    assert_int_equal(cal.pi_dir.n, 0);
    /* The writer refuses operators in a v1 table, a 17th operator and an unknown version. */
    assert_int_equal(build_pi(1, 4, R4, W4), 0);
    static int32_t r17[17], w17[17];
    assert_int_equal(build_pi(2, 17, r17, w17), 0);
    assert_int_equal(build_pi(PST_LAYOUT_VERSION + 1, 0, NULL, NULL), 0);
}

static void edit_pi(void (*edit)(pst_header_t *))
{
    edit_header(edit);
}
static void e_pi_count(pst_header_t *h) { h->pi.n = PST_MAX_OPS + 1; }
static void e_pi_misaligned(pst_header_t *h) { h->pi.offset += 2; }
static void e_pi_in_header(pst_header_t *h) { h->pi.offset = 8; }
static void e_pi_in_f_grid(pst_header_t *h) { h->pi.offset = (uint16_t)(h->f.offset + 4); }
static void e_pi_beyond_end(pst_header_t *h) { h->pi.offset = (uint16_t)(h->pi.offset + 4); }
static void e_pi_offset_without_ops(pst_header_t *h) { h->pi.n = 0; }

static void test_pi_layout_refusals(void **state)
{
    (void)state;
    struct { void (*edit)(pst_header_t *); calib_status_t st; } cases[] = {
        {e_pi_count, CALIB_ERR_PI_COUNT}, {e_pi_misaligned, CALIB_ERR_PI_LAYOUT},
        {e_pi_in_header, CALIB_ERR_PI_LAYOUT}, {e_pi_in_f_grid, CALIB_ERR_PI_LAYOUT},
        {e_pi_beyond_end, CALIB_ERR_PI_LAYOUT}, {e_pi_offset_without_ops, CALIB_ERR_PI_LAYOUT},
    };
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        size_t len = build_pi(0, 4, R4, W4);
        edit_pi(cases[k].edit);
        expect_refused(len, cases[k].st);
    }
}

static double b_const(double q, const void *ctx)
{
    (void)q;
    return *(const double *)ctx;
}

/* The precision ceiling: with a constant play (envelope errors 1 raw) the f^-1 table's
 * error e binds, so B = 16 e raw loads and B = 16 (e - 1) raw is refused, untouched. */
static void test_precision_ceiling(void **state)
{
    (void)state;
    double b = 1.0;
    size_t len = fixture_build(&blob, &GRID, b_const, &b, f_cubic, NULL);
    assert_int_equal(calib_load(&cal, blob.bytes, len), CALIB_OK);
    const int32_t e = cal.f_inv_err_q16;
    assert_true(e > CALIB_PRECISION_FLOOR_Q16 + 1); /* measured 165 raw on this grid */
    assert_true(cal.z_err_q16 < e && cal.pi_inv_err_q16 < e);
    assert_int_equal(cal.precision_ceiling_q16, 65536 / CALIB_PRECISION_B_DIV);

    b = (double)(CALIB_PRECISION_B_DIV * e) / 65536.0;
    len = fixture_build(&blob, &GRID, b_const, &b, f_cubic, NULL);
    assert_int_equal(calib_load(&cal, blob.bytes, len), CALIB_OK);
    assert_int_equal(cal.precision_ceiling_q16, e);
    b = (double)(CALIB_PRECISION_B_DIV * (e - 1)) / 65536.0;
    len = fixture_build(&blob, &GRID, b_const, &b, f_cubic, NULL);
    expect_refused(len, CALIB_ERR_PRECISION);
    /* The floor: a play too small to set a ceiling above the rounding of chained lookups. */
    assert_int_equal(calib_precision_ceiling_q16(0), CALIB_PRECISION_FLOOR_Q16);
    assert_int_equal(calib_precision_ceiling_q16(CALIB_PRECISION_B_DIV * 1000), 1000);
}

/* Every malformed operator block, each with its own reason code; the boundary cases
 * next to each refusal load. */
static void test_pi_content_refusals(void **state)
{
    (void)state;
    const int32_t span = 8 * 65536; /* q_max - q_min of GRID */
    struct {
        int32_t r[4], w[4];
        calib_status_t st;
    } cases[] = {
        {{1, 13107, 39321, 78643}, {26214, 19661, 13107, 6554}, CALIB_ERR_PI_R0},
        {{0, 13107, 13107, 78643}, {26214, 19661, 13107, 6554}, CALIB_ERR_PI_R_ORDER},
        {{0, 39321, 13107, 78643}, {26214, 19661, 13107, 6554}, CALIB_ERR_PI_R_ORDER},
        {{0, 13107, 39321, span + 1}, {26214, 19661, 13107, 6554}, CALIB_ERR_PI_R_RANGE},
        {{0, 13107, 39321, span}, {26214, 19661, 13107, 6554}, CALIB_OK},
        {{0, 13107, 39321, 78643}, {0, 32768, 26214, 6554}, CALIB_ERR_PI_W0},
        {{0, 13107, 39321, 78643}, {-1, 32769, 26214, 6554}, CALIB_ERR_PI_W0},
        {{0, 13107, 39321, 78643}, {26214, 19661, 19661, -1}, CALIB_ERR_PI_W_NEGATIVE},
        {{0, 13107, 39321, 78643}, {26214, 19661, 13107, 6554 + 257}, CALIB_ERR_PI_W_SUM},
        {{0, 13107, 39321, 78643}, {26214, 19661, 13107, 6554 - 257}, CALIB_ERR_PI_W_SUM},
        {{0, 13107, 39321, 78643}, {26214, 19661, 13107, 6554 + 256}, CALIB_OK},
        {{0, 13107, 39321, 78643}, {26214, 19661, 13107, 6554 - 256}, CALIB_OK},
        /* 1/w_0 = 32768 does not fit Q16.16; 1/w_0 = 21845.3 does, but its inverse error
         * (about 1/w_0 raw) is far above the precision ceiling (B_max / 16 = 3686 raw). */
        {{0, 13107, 39321, 78643}, {2, 26214, 26214, 13106}, CALIB_ERR_PI_INVERSE},
        {{0, 13107, 39321, 78643}, {3, 26214, 26214, 13105}, CALIB_ERR_PRECISION},
        {{0, 13107, 39321, 78643}, {6554, 26214, 26214, 6554}, CALIB_OK},
    };
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        size_t len = build_pi(0, 4, cases[k].r, cases[k].w);
        assert_true(len > 0);
        if (cases[k].st == CALIB_OK)
            assert_int_equal(calib_load(&cal, blob.bytes, len), CALIB_OK);
        else
            expect_refused(len, cases[k].st);
    }
    /* A 16-operator block loads; thresholds may not make a grid +- r leave +-2^30. */
    int32_t r16[16], w16[16];
    for (int i = 0; i < 16; i++) {
        r16[i] = i * 8192;
        w16[i] = 4096;
    }
    size_t len = build_pi(0, 16, r16, w16);
    assert_int_equal(calib_load(&cal, blob.bytes, len), CALIB_OK);
    assert_int_equal(cal.pi_inv.n, 16);
}

/* A refused operator block leaves the running table (with its operators) as it was. */
static void test_pi_refusal_keeps_last_good_table(void **state)
{
    (void)state;
    static fixture_blob_t good;
    size_t len = fixture_build_pi(&good, &GRID, b_bump, NULL, f_cubic, NULL, 0, 4, R4, W4);
    assert_int_equal(calib_load(&cal, good.bytes, len), CALIB_OK);
    memcpy(&snapshot, &cal, sizeof cal);
    const int32_t bad_w[4] = {26214, 19661, 19661, -1};
    size_t bad_len = build_pi(0, 4, R4, bad_w);
    assert_int_equal(calib_load(&cal, blob.bytes, bad_len), CALIB_ERR_PI_W_NEGATIVE);
    assert_memory_equal(&cal, &snapshot, sizeof cal);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_valid_table_loads),
        cmocka_unit_test(test_decreasing_f_loads_with_negative_sign),
        cmocka_unit_test(test_size_magic_version),
        cmocka_unit_test(test_every_bit_flip_refused),
        cmocka_unit_test(test_crc_seeded_with_layout_version),
        cmocka_unit_test(test_header_refusals),
        cmocka_unit_test(test_content_refusals),
        cmocka_unit_test(test_refusal_keeps_last_good_table),
        cmocka_unit_test(test_v2_table_with_operators_loads),
        cmocka_unit_test(test_v1_and_empty_v2_load_as_pure_play),
        cmocka_unit_test(test_pi_layout_refusals),
        cmocka_unit_test(test_pi_content_refusals),
        cmocka_unit_test(test_precision_ceiling),
        cmocka_unit_test(test_pi_refusal_keeps_last_good_table),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
