/* Tests of the table's physical plausibility against its instrument and the board's own limits
 * (common/ps_plaus.h, calib_load_guarded): each implausible case refused with its rule and numbers. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <math.h>
#include <string.h>
#include <cmocka.h>

#include "calib.h"
#include "ps_plaus.h"
#include "table_fixture.h"

/* The good table: travel [-4, 4] mm, B 0.4-0.9 mm, f a cubic of about +-59 deg (the calibrated
 * instrument); every case below edits one thing of it and lets pst_instrument_derive stamp the
 * header anew (the worst case: a forger who also rewrites the instrument block), unless it says
 * it keeps the honest header. */
typedef struct {
    double b_scale, b_const;     /* B = b_scale * bump + b_const */
    double f_scale, f_lin;       /* f = f_scale * cubic + f_lin * q */
    double f_jump, f_jump_at;    /* + f_jump for q >= f_jump_at */
} shape_t;

static const shape_t GOOD = {.b_scale = 1.0, .f_scale = 1.0, .f_jump_at = 1e9};

static double b_fn(double q, const void *ctx)
{
    const shape_t *s = ctx;
    return s->b_scale * (0.4 + 0.5 * exp(-q * q / 2.0)) + s->b_const;
}
static double f_fn(double q, const void *ctx)
{
    const shape_t *s = ctx;
    return s->f_scale * (10.0 * q + 0.3 * q * q * q) + s->f_lin * q + (q >= s->f_jump_at ? s->f_jump : 0.0);
}

static fixture_grid_t grid(double q_min, double q_max, int step_log2, uint16_t n)
{
    return (fixture_grid_t){.q0 = q_min, .step_log2 = step_log2, .n = n, .q_min = q_min, .q_max = q_max,
                            .f_kind = PST_F_REMAIN, .generation = 1};
}

static const fixture_grid_t GRID = {.q0 = -4.0, .step_log2 = 13, .n = 65, .q_min = -4.0, .q_max = 4.0,
                                    .f_kind = PST_F_REMAIN, .generation = 1};

static fixture_blob_t blob;
static calib_t cal;

/* The board of these tests: the default instrument, mm, +-20 mm, +-180 deg, play <= 5 mm. */
static const pst_limits_t BOARD = {.instrument_id = PST_INSTRUMENT_DEFAULT, .q_unit = PST_Q_UNIT_MM,
                                   .q_min_q16 = -20 * 65536, .q_max_q16 = 20 * 65536,
                                   .c_min_q16 = -180 * 65536, .c_max_q16 = 180 * 65536, .b_max_q16 = 5 * 65536};

static size_t build_v5(const fixture_grid_t *g, const shape_t *s)
{
    size_t n = fixture_build(&blob, g, b_fn, s, f_fn, s);
    assert_true(n > 0);
    n = fixture_with_instrument(&blob, PST_INSTRUMENT_DEFAULT, NULL);
    assert_true(n > 0);
    return n;
}

/* Multiply every entry of the blob's grid at header offset grid_at (offsetof(pst_header_t, b) or
 * f) by k and reseal the CRC: a forged table whose header stays honest. */
static void scale_entries(size_t grid_at, int32_t k)
{
    pst_grid_t gr;
    memcpy(&gr, blob.bytes + grid_at, sizeof gr);
    for (int i = 0; i < gr.n; i++) {
        int32_t v;
        memcpy(&v, blob.bytes + gr.offset + 4 * i, 4);
        v *= k;
        memcpy(blob.bytes + gr.offset + 4 * i, &v, 4);
    }
    fixture_reseal(&blob);
}

/* calib_load_guarded refuses with st (the same on the host: no board) and reports rule. */
static pst_plaus_report_t expect(size_t n, const pst_limits_t *board, calib_status_t st)
{
    pst_plaus_report_t rep;
    assert_int_equal(calib_load_guarded(&cal, blob.bytes, n, board, &rep), st);
    if (st != CALIB_OK && st >= CALIB_ERR_TRAVEL)
        assert_int_equal(calib_status_of_rule((pst_rule_t)rep.rule), st);
    assert_non_null(calib_status_str(st));
    return rep;
}

static void test_good_table_passes_host_and_board(void **state)
{
    (void)state;
    size_t n = build_v5(&GRID, &GOOD);
    pst_header_t hd;
    memcpy(&hd, blob.bytes, sizeof hd);
    assert_int_equal(hd.layout_version, 5);
    assert_int_equal(hd.header_size, sizeof(pst_header_v5_t));
    expect(n, NULL, CALIB_OK);
    expect(n, &BOARD, CALIB_OK);
    /* The derived instrument: twice the largest play, the angle range of f widened. */
    pst_header_v5_t h5;
    memcpy(&h5, blob.bytes, sizeof h5);
    assert_int_equal(h5.inst.id, PST_INSTRUMENT_DEFAULT);
    assert_true(h5.inst.b_max_q16 >= (int32_t)(1.79 * 65536) && h5.inst.b_max_q16 <= (int32_t)(1.81 * 65536));
    assert_true(h5.inst.c_min_q16 < -59 * 65536 && h5.inst.c_max_q16 > 59 * 65536);
}

static void test_b_against_travel(void **state)
{
    (void)state;
    /* B equal to the whole travel, and at 95 % of it: above travel / 2. */
    shape_t s = {.b_scale = 0.0, .b_const = 8.0, .f_scale = 1.0, .f_jump_at = 1e9};
    pst_plaus_report_t r = expect(build_v5(&GRID, &s), NULL, CALIB_ERR_INST_B_MAX);
    assert_int_equal(r.value, 8 * 65536);
    assert_int_equal(r.limit, 4 * 65536);
    s.b_const = 0.95 * 8.0;
    expect(build_v5(&GRID, &s), NULL, CALIB_ERR_INST_B_MAX);
    /* Ten times the calibrated play, header re-derived: the bump's slope alone is refused (|B'| = 3),
     * and a flat 9 mm play on the 8 mm travel is wider than it. */
    s = GOOD;
    s.b_scale = 10.0;
    expect(build_v5(&GRID, &s), NULL, CALIB_ERR_B_SLOPE);
    s = (shape_t){.b_const = 9.0, .f_scale = 1.0, .f_jump_at = 1e9};
    expect(build_v5(&GRID, &s), NULL, CALIB_ERR_B_TRAVEL);
    size_t n = build_v5(&GRID, &GOOD);
    /* Four times with the honest header kept (only the entries forged; 3.6 mm, within the travel
     * rules): the instrument's largest play is 1.8 mm. */
    scale_entries(offsetof(pst_header_t, b), 4);
    r = expect(n, NULL, CALIB_ERR_B_INST);
    assert_int_equal(r.index, 15); /* the first entry above 1.8 mm, q = -2.125 mm */
    assert_true(r.value > r.limit);
}

static void test_f_against_the_instrument(void **state)
{
    (void)state;
    /* f spanning 710 deg over the travel (+-355): one turn at most. */
    shape_t s = {.b_scale = 1.0, .f_scale = 0.0, .f_lin = 355.0 / 4.0, .f_jump_at = 1e9};
    pst_plaus_report_t r = expect(build_v5(&GRID, &s), NULL, CALIB_ERR_INST_C_RANGE);
    assert_true(r.value > 700 * 65536);
    /* f spanning 1 deg over the travel. */
    s.f_lin = 0.5 / 4.0;
    r = expect(build_v5(&GRID, &s), NULL, CALIB_ERR_C_SPAN);
    assert_int_equal(r.limit, PST_PLAUS_C_SPAN_MIN_INST_Q16);
    /* A 359 deg step inside f_remain on a motor in deg, 1 deg grid step (359 deg/deg passes the
     * absolute slope rule): one segment 64 times steeper than f's mean over the range. */
    fixture_grid_t g = grid(0.0, 64.0, 16, 65);
    s = (shape_t){.b_scale = 1.0, .f_lin = 0.01, .f_jump = 359.0, .f_jump_at = 32.0};
    size_t n = fixture_build(&blob, &g, b_fn, &s, f_fn, &s);
    pst_header_t hd;
    memcpy(&hd, blob.bytes, sizeof hd);
    hd.q_unit = PST_Q_UNIT_DEG;
    memcpy(blob.bytes, &hd, sizeof hd);
    fixture_reseal(&blob);
    calib_status_t v2 = calib_load(&cal, blob.bytes, n); /* a v2 table: no plausibility rule refuses it */
    assert_true(v2 == CALIB_OK || v2 < CALIB_ERR_TRAVEL);
    n = fixture_with_instrument(&blob, PST_INSTRUMENT_DEFAULT, NULL);
    r = expect(n, NULL, CALIB_ERR_INST_F_SLOPE);
    assert_true(r.value > r.limit);
    /* f scaled by 3 with the honest header kept: beyond the instrument's angle range. */
    n = build_v5(&GRID, &GOOD);
    scale_entries(offsetof(pst_header_t, f), 3);
    expect(n, NULL, CALIB_ERR_C_INST);
}

static void test_unit_mistake(void **state)
{
    (void)state;
    /* A session in micrometres calibrated as millimetres: 8000 "mm" of travel, 900 "mm" of play. */
    fixture_grid_t g = grid(-4000.0, 4000.0, 21, 256);
    shape_t s = {.b_scale = 0.0, .b_const = 600.0, .f_scale = 0.0, .f_lin = 59.2 / 4000.0, .f_jump_at = 1e9};
    pst_plaus_report_t r = expect(build_v5(&g, &s), NULL, CALIB_ERR_TRAVEL_UNIT);
    assert_int_equal(r.limit, PST_PLAUS_TRAVEL_MAX_MM_Q16);
}

static void test_board_binding_and_limits(void **state)
{
    (void)state;
    size_t n = build_v5(&GRID, &GOOD);
    pst_limits_t b = BOARD;
    b.instrument_id = 7;
    pst_plaus_report_t r = expect(n, &b, CALIB_ERR_BOARD_INSTRUMENT);
    assert_int_equal(r.value, PST_INSTRUMENT_DEFAULT);
    assert_int_equal(r.limit, 7);
    b = BOARD;
    b.q_unit = PST_Q_UNIT_DEG;
    expect(n, &b, CALIB_ERR_BOARD_UNIT);
    b = BOARD;
    b.q_max_q16 = 3 * 65536; /* the table's travel ends at 4 mm */
    r = expect(n, &b, CALIB_ERR_BOARD_TRAVEL);
    assert_int_equal(r.value, 4 * 65536);
    b = BOARD;
    b.c_min_q16 = -45 * 65536;
    expect(n, &b, CALIB_ERR_BOARD_ANGLE);
    b = BOARD;
    b.b_max_q16 = 65536; /* the table allows 1.8 mm of play */
    expect(n, &b, CALIB_ERR_BOARD_B);
    /* A table naming no instrument (layout 2) loads on the host, never on a board. */
    n = fixture_build(&blob, &GRID, b_fn, &GOOD, f_fn, &GOOD);
    expect(n, NULL, CALIB_OK);
    r = expect(n, &BOARD, CALIB_ERR_UNBOUND);
    assert_int_equal(r.value, 2);
    /* A refusal leaves the running calibration untouched. */
    n = build_v5(&GRID, &GOOD);
    assert_int_equal(calib_load_guarded(&cal, blob.bytes, n, &BOARD, NULL), CALIB_OK);
    static calib_t snap;
    memcpy(&snap, &cal, sizeof cal);
    b = BOARD;
    b.instrument_id = 2;
    assert_int_equal(calib_load_guarded(&cal, blob.bytes, n, &b, NULL), CALIB_ERR_BOARD_INSTRUMENT);
    assert_memory_equal(&cal, &snap, sizeof cal);
}

/* An f that rises by 1 raw over a whole unit somewhere (f^-1 steeper than Q16.16 holds): the
 * derived block marks its inverse slope unbounded (INT32_MAX) and the rules pass it; how flat f may
 * be is then the precision ceiling's to judge, as before the instrument block. */
static void test_inverse_slope_beyond_q16(void **state)
{
    (void)state;
    enum { N = 9 };
    int32_t b[N], f[N];
    for (int i = 0; i < N; i++) {
        b[i] = 65536 / 2;
        f[i] = i < 4 ? i * 10 * 65536 : (i == 4 ? 30 * 65536 + 1 : 31 * 65536 + (i - 5) * 10 * 65536);
    }
    pst_header_t hd;
    memset(&hd, 0, sizeof hd);
    hd.layout_version = 5;
    hd.q_unit = PST_Q_UNIT_DEG;
    hd.q_min_q16 = 0;
    hd.q_max_q16 = 8 * 65536;
    hd.b = (pst_grid_t){.x0_q16 = 0, .step_q16 = 65536, .n = N};
    hd.f = hd.b;
    f[4] = f[3] + 1;
    pst_instrument_t in;
    pst_instrument_derive(&hd, b, f, PST_INSTRUMENT_DEFAULT, &in);
    assert_int_equal(in.f_inv_slope_max_q16, INT32_MAX);
    pst_plaus_report_t rep;
    assert_int_equal(pst_plaus_check(&hd, &in, b, f, NULL, &rep), PST_RULE_OK);
    /* A bounded block is held to it: the flat segment breaks a finite bound. */
    in.f_inv_slope_max_q16 = 65536;
    assert_int_equal(pst_plaus_check(&hd, &in, b, f, NULL, &rep), PST_RULE_F_INV_SLOPE_INST);
    assert_int_equal(rep.index, 3);
}

static void test_generation_steps(void **state)
{
    (void)state;
    assert_true(pst_generation_ok(false, 0, 1));
    assert_true(pst_generation_ok(false, 0, PST_GENERATION_STEP_MAX));
    assert_false(pst_generation_ok(false, 0, 0));
    assert_false(pst_generation_ok(false, 0, 0xFFFFFFFFu)); /* what exhausted boards before */
    assert_true(pst_generation_ok(true, 5, 6));
    assert_false(pst_generation_ok(true, 5, 5));
    assert_false(pst_generation_ok(true, 5, 4));
    assert_false(pst_generation_ok(true, 5, 5 + PST_GENERATION_STEP_MAX + 1));
    assert_false(pst_generation_ok(true, 5, 0xFFFFFFFFu));
    assert_true(pst_generation_ok(true, 0xFFFFFFFEu, 0xFFFFFFFFu));
    for (uint32_t g = 0; g < 64; g++) /* nothing follows the last one, not even by wrapping */
        assert_false(pst_generation_ok(true, 0xFFFFFFFFu, g));
}

static void test_rule_names_and_codes(void **state)
{
    (void)state;
    for (int r = PST_RULE_TRAVEL; r < PST_RULE_COUNT; r++) {
        calib_status_t st = calib_status_of_rule((pst_rule_t)r);
        assert_true(st >= CALIB_ERR_TRAVEL && st <= CALIB_ERR_BOARD_B);
        assert_string_equal(calib_status_str(st), pst_rule_str((pst_rule_t)r));
    }
    assert_int_equal(calib_status_of_rule(PST_RULE_OK), CALIB_OK);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_good_table_passes_host_and_board),
        cmocka_unit_test(test_b_against_travel),
        cmocka_unit_test(test_f_against_the_instrument),
        cmocka_unit_test(test_unit_mistake),
        cmocka_unit_test(test_board_binding_and_limits),
        cmocka_unit_test(test_inverse_slope_beyond_q16),
        cmocka_unit_test(test_generation_steps),
        cmocka_unit_test(test_rule_names_and_codes),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
