/* Tests of the board-side protocol handler over the real codec, store and core. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <math.h>
#include <string.h>
#include <cmocka.h>

#include "ps_crc32.h"
#include "storage/pss_flash_sim.h"
#include "link/psl_link.h"
#include "table_fixture.h"

enum { SLOT = 4096 };

static uint8_t mem[2 * SLOT];
static pss_sim_t sim;
static psl_t L;
static uint8_t out[16384];
static size_t out_n;
static uint16_t seq;

typedef struct {
    uint8_t type;
    uint16_t seq;
    uint16_t len;
    uint8_t pl[PSP_MAX_PAYLOAD];
} resp_t;

static void wr(void *ctx, const uint8_t *f, size_t n)
{
    (void)ctx;
    assert_true(out_n + n <= sizeof out);
    memcpy(out + out_n, f, n);
    out_n += n;
}

/* Decode everything the board sent since the last call. */
static int take(resp_t *r, int max)
{
    psf_parser_t p;
    int k = 0;
    psf_parser_reset(&p);
    const uint8_t *d = out;
    size_t left = out_n;
    while (left > 0) {
        psf_result_t res;
        size_t used = psf_parser_push(&p, d, left, &res);
        d += used;
        left -= used;
        if (res == PSF_FRAME) {
            assert_true(k < max);
            r[k].type = p.hdr.type;
            r[k].seq = p.hdr.seq;
            r[k].len = p.hdr.len;
            memcpy(r[k].pl, psf_parser_payload(&p), p.hdr.len);
            k++;
        } else {
            assert_int_equal(res, PSF_NEED_MORE);
        }
    }
    out_n = 0;
    return k;
}

/* Send one request with sequence number s, expect exactly one answer. */
static resp_t req_seq(uint8_t type, uint16_t s, const void *pl, uint16_t len)
{
    uint8_t f[PSF_MAX_FRAME];
    size_t n = psf_encode(f, sizeof f, type, s, pl, len);
    assert_true(n > 0);
    psl_rx(&L, f, n);
    resp_t r[4];
    assert_int_equal(take(r, 4), 1);
    assert_int_equal(r[0].seq, s);
    return r[0];
}

static resp_t req(uint8_t type, const void *pl, uint16_t len)
{
    return req_seq(type, ++seq, pl, len);
}

static void expect_ok(resp_t r, uint8_t type)
{
    if (r.type == PSP_MSG_ERROR)
        fail_msg("type 0x%02x refused: code %u detail %u", type, psf_get_u16(r.pl), r.pl[3]);
    assert_int_equal(r.type, type | PSP_RESPONSE);
}

static void expect_err(resp_t r, uint16_t code)
{
    assert_int_equal(r.type, PSP_MSG_ERROR);
    assert_int_equal(r.len, sizeof(psp_error_t));
    assert_int_equal(psf_get_u16(r.pl), code);
}

static psp_info_t info(void)
{
    resp_t r = req_seq(PSP_MSG_INFO, 0, NULL, 0);
    expect_ok(r, PSP_MSG_INFO);
    psp_info_t i;
    memcpy(&i, r.pl, sizeof i);
    return i;
}

static void boot(void)
{
    psl_config_t cfg = psl_default_config(1000);
    psl_init(&L, &cfg, &sim.port, wr, NULL);
    out_n = 0;
    seq = info().last_seq; /* continue above the board's last accepted seq */
}

static double b_fn(double q, const void *ctx)
{
    (void)ctx;
    return 0.4 + 0.3 * exp(-q * q / 2.0);
}
static double f_fn(double q, const void *ctx)
{
    (void)ctx;
    return 10.0 * q + 0.3 * q * q * q;
}
static double f_bad(double q, const void *ctx)
{
    (void)ctx;
    return q * q;
}

static fixture_blob_t blob;

static size_t make_table(uint32_t gen, fixture_fn f)
{
    fixture_grid_t g = {.q0 = -4.0, .step_log2 = 13, .n = 65, .q_min = -4.0, .q_max = 4.0,
                        .f_kind = PST_F_REMAIN, .generation = gen};
    size_t n = fixture_build(&blob, &g, b_fn, NULL, f, NULL);
    /* Bound to the board's instrument (layout v5), as `playscope tables` writes it; a table the
     * loader refuses anyway (f_bad) is sent as built. */
    size_t n5 = fixture_with_instrument(&blob, PST_INSTRUMENT_DEFAULT, NULL);
    return n5 ? n5 : n;
}

static uint16_t up_session; /* token of the last BEGIN this test's host opened */

/* BEGIN: opens an upload session; returns its token (also kept in up_session). */
static uint16_t begin(size_t n, uint32_t crc)
{
    psp_table_begin_t b = {.total_size = (uint32_t)n, .crc32 = crc};
    resp_t r = req(PSP_MSG_TABLE_BEGIN, &b, sizeof b);
    expect_ok(r, PSP_MSG_TABLE_BEGIN);
    assert_int_equal(r.len, sizeof(psp_table_session_t));
    psp_table_session_t ss;
    memcpy(&ss, r.pl, sizeof ss);
    assert_true(ss.session != 0);
    assert_int_equal(ss.timeout_ms, L.cfg.upload_timeout_us / 1000u);
    up_session = ss.session;
    return ss.session;
}

/* BEGIN, chunks of PSP_CHUNK_MAX; returns the COMMIT answer. */
static resp_t upload(const uint8_t *t, size_t n)
{
    psp_table_begin_t b = {.total_size = (uint32_t)n, .crc32 = psf_get_u32(t + 12)};
    begin(n, b.crc32);
    for (size_t off = 0; off < n; off += PSP_CHUNK_MAX) {
        psp_table_chunk_t c = {.offset = (uint32_t)off, .session = up_session};
        c.len = (uint16_t)(n - off < PSP_CHUNK_MAX ? n - off : PSP_CHUNK_MAX);
        memcpy(c.data, t + off, c.len);
        c.chunk_crc32 = ps_crc32_update(0, c.data, c.len);
        expect_ok(req(PSP_MSG_TABLE_CHUNK, &c, (uint16_t)(12 + c.len)), PSP_MSG_TABLE_CHUNK);
    }
    psp_table_commit_t cm = {.crc32 = b.crc32, .session = up_session};
    return req(PSP_MSG_TABLE_COMMIT, &cm, sizeof cm);
}

/* Upload and commit generation 1 of make_table(f_fn), and load the same bytes into *ref on this
 * side (from ref_blob, a copy that outlives the call: calib_load reads entries in place): the
 * board's table, for a reference run of the core. Returns the table's size in bytes. */
static size_t commit_table1_with_reference(calib_t *ref, uint8_t *ref_blob)
{
    size_t n = make_table(1, f_fn);
    expect_ok(upload(blob.bytes, n), PSP_MSG_TABLE_COMMIT);
    memcpy(ref_blob, blob.bytes, n);
    assert_int_equal(calib_load(ref, ref_blob, n), CALIB_OK);
    return n;
}

static size_t read_back(uint8_t *dst, size_t n)
{
    size_t off = 0;
    for (;;) {
        psp_table_read_t r = {.offset = (uint32_t)off, .len = PSP_CHUNK_MAX};
        resp_t a = req(PSP_MSG_TABLE_READ, &r, sizeof r);
        expect_ok(a, PSP_MSG_TABLE_READ);
        psp_table_chunk_t c;
        memcpy(&c, a.pl, a.len);
        assert_int_equal(a.len, 12 + c.len);
        assert_int_equal(c.chunk_crc32, ps_crc32_update(0, c.data, c.len));
        if (c.len == 0)
            return off;
        assert_true(off + c.len <= n);
        memcpy(dst + off, c.data, c.len);
        off += c.len;
    }
}

static int setup(void **state)
{
    (void)state;
    pss_sim_init(&sim, mem, SLOT, 1);
    boot();
    return 0;
}

static void test_info_fresh(void **state)
{
    (void)state;
    psp_info_t i = info();
    assert_int_equal(i.proto_version, PSP_VERSION);
    assert_int_equal(i.table_layout_version, PST_LAYOUT_VERSION);
    assert_int_equal(i.active_slot, 0xFF);
    assert_int_equal(i.active_generation, 0);
    assert_int_equal(i.mode, PSP_MODE_IDLE);
}

static void test_upload_commit_readback_reboot(void **state)
{
    (void)state;
    size_t n = make_table(1, f_fn);
    resp_t r = upload(blob.bytes, n);
    expect_ok(r, PSP_MSG_TABLE_COMMIT);
    psp_info_t i;
    memcpy(&i, r.pl, sizeof i);
    assert_int_equal(i.active_generation, 1);
    assert_int_equal(i.active_crc32, psf_get_u32(blob.bytes + 12));
    assert_int_equal(i.active_slot, 0);
    uint8_t back[PST_MAX_TABLE_SIZE];
    assert_int_equal(read_back(back, sizeof back), n);
    assert_memory_equal(back, blob.bytes, n);
    boot();
    i = info();
    assert_int_equal(i.active_generation, 1);
    assert_int_equal(read_back(back, sizeof back), n);
    assert_memory_equal(back, blob.bytes, n);
    /* Second table goes to slot B. */
    n = make_table(2, f_fn);
    expect_ok(upload(blob.bytes, n), PSP_MSG_TABLE_COMMIT);
    assert_int_equal(info().active_slot, 1);
}

static void test_refusals_change_nothing(void **state)
{
    (void)state;
    size_t n = make_table(5, f_fn);
    expect_ok(upload(blob.bytes, n), PSP_MSG_TABLE_COMMIT);
    psp_info_t before = info();

    /* Not newer generation. */
    n = make_table(5, f_fn);
    resp_t r = upload(blob.bytes, n);
    expect_err(r, PSP_ERR_TABLE);
    assert_int_equal(r.pl[3], PSL_DETAIL_GENERATION);
    /* Refused by the loader: f not monotone. */
    n = make_table(6, f_bad);
    r = upload(blob.bytes, n);
    expect_err(r, PSP_ERR_TABLE);
    assert_int_equal(r.pl[3], CALIB_ERR_F_NOT_MONOTONE);
    /* Whole-table CRC in COMMIT differs from the announced one. */
    n = make_table(6, f_fn);
    /* A refused commit consumed its session: the next upload opens a new one. */
    psp_table_begin_t b = {.total_size = (uint32_t)n, .crc32 = psf_get_u32(blob.bytes + 12)};
    begin(n, b.crc32);
    psp_table_commit_t cm = {.crc32 = b.crc32 ^ 1, .session = up_session};
    expect_err(req(PSP_MSG_TABLE_COMMIT, &cm, sizeof cm), PSP_ERR_STATE); /* nothing uploaded */
    psp_table_chunk_t c = {.offset = 0, .len = 16, .session = up_session};
    memcpy(c.data, blob.bytes, 16);
    c.chunk_crc32 = ps_crc32_update(0, c.data, 16) ^ 1;
    expect_err(req(PSP_MSG_TABLE_CHUNK, &c, 12 + 16), PSP_ERR_CRC);
    c.chunk_crc32 ^= 1;
    c.offset = 32; /* a hole */
    expect_err(req(PSP_MSG_TABLE_CHUNK, &c, 12 + 16), PSP_ERR_RANGE);
    c.offset = 0;
    expect_err(req(PSP_MSG_TABLE_CHUNK, &c, 12 + 17), PSP_ERR_LENGTH);
    /* Oversized and undersized BEGIN. */
    psp_table_begin_t big = {.total_size = PST_MAX_TABLE_SIZE + 1};
    expect_err(req(PSP_MSG_TABLE_BEGIN, &big, sizeof big), PSP_ERR_RANGE);
    /* Unknown type, wrong length, wrong version, bad frame CRC, mode out of range. */
    expect_err(req(0x55, NULL, 0), PSP_ERR_TYPE);
    expect_err(req(PSP_MSG_SET_MODE, &cm, 2), PSP_ERR_LENGTH);
    psp_set_mode_t m = {.mode = 9};
    expect_err(req(PSP_MSG_SET_MODE, &m, sizeof m), PSP_ERR_RANGE);
    uint8_t f[PSF_MAX_FRAME];
    size_t fn = psf_encode(f, sizeof f, PSP_MSG_INFO, ++seq, NULL, 0);
    f[2] = 2;
    f[fn - 4] = 0; /* CRC now wrong too; fix it after the version edit */
    uint32_t crc = ps_crc32_update(0, f, fn - 4);
    memcpy(f + fn - 4, &crc, 4);
    psl_rx(&L, f, fn);
    resp_t rr[2];
    assert_int_equal(take(rr, 2), 1);
    expect_err(rr[0], PSP_ERR_VERSION);
    fn = psf_encode(f, sizeof f, PSP_MSG_SET_MODE, ++seq, &m, sizeof m);
    f[9] ^= 0x80;
    psl_rx(&L, f, fn);
    assert_int_equal(take(rr, 2), 1);
    expect_err(rr[0], PSP_ERR_CRC);

    psp_info_t after = info();
    assert_memory_equal(&before.active_generation, &after.active_generation, 8);
    assert_int_equal(after.active_slot, before.active_slot);
    assert_int_equal(after.mode, PSP_MODE_IDLE);
}

static void test_replay_and_order(void **state)
{
    (void)state;
    psp_set_mode_t ex = {.mode = PSP_MODE_EXCITATION}, idle = {.mode = PSP_MODE_IDLE};
    uint16_t s = (uint16_t)(seq + 10);
    expect_ok(req_seq(PSP_MSG_SET_MODE, s, &ex, sizeof ex), PSP_MSG_SET_MODE);
    expect_ok(req_seq(PSP_MSG_SET_MODE, (uint16_t)(s + 1), &idle, sizeof idle), PSP_MSG_SET_MODE);
    /* Replay of the first: refused, mode stays idle. */
    expect_err(req_seq(PSP_MSG_SET_MODE, s, &ex, sizeof ex), PSP_ERR_SEQ);
    expect_err(req_seq(PSP_MSG_SET_MODE, (uint16_t)(s - 5), &ex, sizeof ex), PSP_ERR_SEQ);
    expect_err(req_seq(PSP_MSG_SET_MODE, 0, &ex, sizeof ex), PSP_ERR_SEQ);
    expect_err(req_seq(PSP_MSG_SET_MODE, (uint16_t)(s + 1 + 0x8000), &ex, sizeof ex), PSP_ERR_SEQ);
    psp_info_t i = info();
    assert_int_equal(i.mode, PSP_MODE_IDLE);
    assert_int_equal(i.last_seq, (uint16_t)(s + 1));
    /* Wrap-around is newer. */
    L.last_seq = 0xFFFE;
    expect_ok(req_seq(PSP_MSG_SET_MODE, 0xFFFF, &idle, sizeof idle), PSP_MSG_SET_MODE);
    expect_ok(req_seq(PSP_MSG_SET_MODE, 1, &idle, sizeof idle), PSP_MSG_SET_MODE);
    seq = 1;
}

/* A commit during compensation is taken without stopping the loop (a host refresh during
 * use): the compensator carries its state onto the new table, bit for bit the
 * core's comp_step with its table switched. During an excitation it is refused and the upload
 * kept for a commit once idle. */
static void test_commit_during_compensation_not_excitation(void **state)
{
    (void)state;
    static calib_t cal1, cal2;
    static uint8_t blob1[PST_MAX_TABLE_SIZE];
    size_t n = commit_table1_with_reference(&cal1, blob1);
    psp_set_mode_t m = {.mode = PSP_MODE_COMPENSATION};
    expect_ok(req(PSP_MSG_SET_MODE, &m, sizeof m), PSP_MSG_SET_MODE);
    comp_t cp;
    psp_comp_req_t c = {0};
    for (int k = 0; k < 200; k++) {
        int32_t c_ref = (int32_t)(30.0 * sin(k * 0.05) * 65536.0);
        if (k == 0)
            comp_reset(&cp, &cal1, NULL, c_ref);
        if (k == 100) { /* mid-stroke: generation 2 committed while compensating */
            size_t n2 = make_table(2, f_fn);
            assert_int_equal(calib_load(&cal2, blob.bytes, n2), CALIB_OK);
            expect_ok(upload(blob.bytes, n2), PSP_MSG_TABLE_COMMIT);
            assert_int_equal(info().active_generation, 2);
            assert_int_equal(info().mode, PSP_MODE_COMPENSATION);
            comp_rebind(&cp, &cal2); /* the board's hot swap: state kept, cached cells emptied */
        }
        int32_t want = comp_step(&cp, c_ref);
        c.c_ref_q16 = c_ref;
        resp_t r = req(PSP_MSG_COMP_STEP, &c, sizeof c);
        expect_ok(r, PSP_MSG_COMP_STEP);
        assert_int_equal((int32_t)psf_get_u32(r.pl), want);
    }
    m.mode = PSP_MODE_IDLE;
    expect_ok(req(PSP_MSG_SET_MODE, &m, sizeof m), PSP_MSG_SET_MODE);
    m.mode = PSP_MODE_EXCITATION;
    expect_ok(req(PSP_MSG_SET_MODE, &m, sizeof m), PSP_MSG_SET_MODE);
    n = make_table(3, f_fn);
    expect_err(upload(blob.bytes, n), PSP_ERR_STATE);
    assert_int_equal(info().active_generation, 2);
    m.mode = PSP_MODE_IDLE;
    expect_ok(req(PSP_MSG_SET_MODE, &m, sizeof m), PSP_MSG_SET_MODE);
    psp_table_commit_t cm = {.crc32 = psf_get_u32(blob.bytes + 12), .session = up_session};
    expect_ok(req(PSP_MSG_TABLE_COMMIT, &cm, sizeof cm), PSP_MSG_TABLE_COMMIT); /* upload kept */
    assert_int_equal(info().active_generation, 3);
}

static void test_compensation_matches_core(void **state)
{
    (void)state;
    psp_comp_req_t c = {0};
    expect_err(req(PSP_MSG_COMP_STEP, &c, sizeof c), PSP_ERR_STATE); /* no table */
    psp_set_mode_t m = {.mode = PSP_MODE_COMPENSATION};
    expect_err(req(PSP_MSG_SET_MODE, &m, sizeof m), PSP_ERR_STATE);
    size_t n = make_table(1, f_fn);
    expect_ok(upload(blob.bytes, n), PSP_MSG_TABLE_COMMIT);
    expect_ok(req(PSP_MSG_SET_MODE, &m, sizeof m), PSP_MSG_SET_MODE);
    static calib_t cal;
    assert_int_equal(calib_load(&cal, blob.bytes, n), CALIB_OK);
    comp_t cp;
    for (int k = 0; k < 400; k++) {
        int32_t c_ref = (int32_t)(30.0 * sin(k * 0.05) * 65536.0);
        if (k == 0)
            comp_reset(&cp, &cal, NULL, c_ref);
        int32_t want = comp_step(&cp, c_ref);
        c.c_ref_q16 = c_ref;
        resp_t r = req(PSP_MSG_COMP_STEP, &c, sizeof c);
        expect_ok(r, PSP_MSG_COMP_STEP);
        assert_int_equal((int32_t)psf_get_u32(r.pl), want);
    }
    m.mode = PSP_MODE_PASSTHROUGH;
    expect_ok(req(PSP_MSG_SET_MODE, &m, sizeof m), PSP_MSG_SET_MODE);
    c.c_ref_q16 = 5 * 65536;
    resp_t r = req(PSP_MSG_COMP_STEP, &c, sizeof c);
    assert_int_equal((int32_t)psf_get_u32(r.pl), lut_eval(&cal.f_inv, c.c_ref_q16));
}

static void test_streaming(void **state)
{
    (void)state;
    psp_stream_ctl_t s = {.enable = 1, .decimation = 2};
    expect_ok(req(PSP_MSG_ENC_STREAM, &s, sizeof s), PSP_MSG_ENC_STREAM);
    for (uint32_t k = 0; k < 2 * PSP_ENC_SAMPLES_MAX; k++)
        psl_tick(&L, k * 1000u, (int32_t)k * 100);
    resp_t r[4];
    assert_int_equal(take(r, 4), 1);
    assert_int_equal(r[0].type, PSP_MSG_ENC_STREAM | PSP_RESPONSE);
    assert_int_equal(r[0].seq, 0);
    assert_int_equal(r[0].len, 4 + 8 * PSP_ENC_SAMPLES_MAX);
    psp_enc_samples_t b;
    memcpy(&b, r[0].pl, r[0].len);
    assert_int_equal(b.count, PSP_ENC_SAMPLES_MAX);
    assert_int_equal(b.s[1].t_us - b.s[0].t_us, 2000);
    assert_int_equal(b.s[29].q_q16, 58 * 100);
    s.enable = 1;
    s.decimation = 0;
    expect_err(req(PSP_MSG_ENC_STREAM, &s, sizeof s), PSP_ERR_RANGE);
}

/* The detector sees a reversal, a still marker, then motion: one B sample comes back. */
static void test_onset_over_the_link(void **state)
{
    (void)state;
    const uint32_t frame_us = 40000;
    /* Encoder: q ramps at 1 unit/s from t = 0; history every 1 ms. */
    for (uint32_t t = 0; t <= 2000000; t += 1000)
        psl_tick(&L, t, (int32_t)((int64_t)t * 65536 / 1000000));
    out_n = 0;
    psp_reversal_t rv = {.t1_us = 100000, .q1_q16 = (int32_t)(0.1 * 65536)};
    resp_t r = req(PSP_MSG_REVERSAL, &rv, sizeof rv);
    expect_ok(r, PSP_MSG_REVERSAL);
    assert_int_equal(r.len, 0);
    int got = 0;
    psp_b_sample_t bs;
    for (uint32_t t = 120000; t < 2000000 && !got; t += frame_us) {
        /* Marker still until 1.2 s (image clock), then moving 2 px per frame. */
        double u = 100.0 + (t > 1200000 ? (t - 1200000) / (double)frame_us * 2.0 : 0.0);
        psp_marker_obs_t m = {.t_us = t, .u_q16 = (int32_t)(u * 65536), .v_q16 = 50 * 65536, .valid = 1};
        r = req(PSP_MSG_MARKER_OBS, &m, sizeof m);
        expect_ok(r, PSP_MSG_MARKER_OBS);
        if (r.len == sizeof bs) {
            memcpy(&bs, r.pl, sizeof bs);
            got = 1;
        }
    }
    assert_true(got);
    assert_true(bs.reason == ONSET_OK || bs.reason == ONSET_OK_COARSE);
    assert_int_equal(bs.t1_us, 100000);
    assert_true(bs.b_q16 > 0);
    psp_marker_obs_t bad = {.kind = 7};
    expect_err(req(PSP_MSG_MARKER_OBS, &bad, sizeof bad), PSP_ERR_RANGE);
}

static psp_learn_state_t learn(uint8_t op)
{
    psp_learn_ctl_t c = {.op = op};
    resp_t r = req(PSP_MSG_LEARN, &c, sizeof c);
    expect_ok(r, PSP_MSG_LEARN);
    assert_int_equal(r.len, sizeof(psp_learn_state_t));
    psp_learn_state_t st;
    memcpy(&st, r.pl, sizeof st);
    return st;
}

/* On-line B update over the link (PSP_MSG_LEARN): during compensation a B
 * sample an observation completes is queued, not learnt in the request or the tick; the
 * background step learns it and publishes B (the compensator runs it from the next step);
 * the state reported matches an independent b_online run on the same table bit for bit (CRC
 * of the entries); a table committed while learning becomes the prior; stop restores the
 * flashed B. */
static void test_learn_during_compensation(void **state)
{
    (void)state;
    psp_learn_ctl_t bad = {.op = 3};
    expect_err(req(PSP_MSG_LEARN, &bad, sizeof bad), PSP_ERR_RANGE);
    psp_learn_ctl_t start = {.op = PSP_LEARN_START};
    expect_err(req(PSP_MSG_LEARN, &start, sizeof start), PSP_ERR_STATE); /* no table */
    static uint8_t blob1[PST_MAX_TABLE_SIZE];
    static calib_t ref;
    static b_online_t bo;
    size_t n = commit_table1_with_reference(&ref, blob1);
    const int32_t *flashed = ref.b.y_q16;
    b_online_config_t bc = b_online_default_config();
    assert_int_equal(b_online_init(&bo, &bc, &ref.b), B_ONLINE_OK);
    psp_set_mode_t m = {.mode = PSP_MODE_COMPENSATION};
    expect_ok(req(PSP_MSG_SET_MODE, &m, sizeof m), PSP_MSG_SET_MODE);

    psp_learn_state_t st = learn(PSP_LEARN_QUERY);
    assert_int_equal(st.on, 0);
    st = learn(PSP_LEARN_START);
    assert_int_equal(st.on, 1);
    assert_int_equal(st.n_grid, 65);
    assert_int_equal(st.samples, 0);
    assert_int_equal(st.b_crc32, ps_crc32_update(0, (const uint8_t *)flashed, 65 * 4));

    /* The onset of test_onset_over_the_link, now while compensating. */
    const uint32_t frame_us = 40000;
    for (uint32_t t = 0; t <= 2000000; t += 1000)
        psl_tick(&L, t, (int32_t)((int64_t)t * 65536 / 1000000));
    out_n = 0;
    psp_reversal_t rv = {.t1_us = 100000, .q1_q16 = (int32_t)(0.1 * 65536)};
    expect_ok(req(PSP_MSG_REVERSAL, &rv, sizeof rv), PSP_MSG_REVERSAL);
    psp_b_sample_t bs;
    int got = 0;
    for (uint32_t t = 120000; t < 2000000 && !got; t += frame_us) {
        double u = 100.0 + (t > 1200000 ? (t - 1200000) / (double)frame_us * 2.0 : 0.0);
        psp_marker_obs_t mo = {.t_us = t, .u_q16 = (int32_t)(u * 65536), .v_q16 = 50 * 65536, .valid = 1};
        resp_t r = req(PSP_MSG_MARKER_OBS, &mo, sizeof mo);
        expect_ok(r, PSP_MSG_MARKER_OBS);
        if (r.len == sizeof bs) {
            memcpy(&bs, r.pl, sizeof bs);
            got = 1;
        }
    }
    assert_true(got && bs.reason <= ONSET_OK_COARSE);
    st = learn(PSP_LEARN_QUERY);
    assert_int_equal(st.queued, 1);
    assert_int_equal(st.samples, 0); /* queued: nothing learnt in the request */
    int32_t b_before = lut_eval(&L.cal[L.active_buf].b, bs.q_mean_q16);

    assert_true(psl_background(&L));
    assert_false(psl_background(&L));
    b_online_sample(&bo, bs.q_mean_q16, bs.b_q16);
    st = learn(PSP_LEARN_QUERY);
    assert_int_equal(st.samples, 1);
    assert_int_equal(st.dropped, 0);
    assert_int_equal(st.b_crc32, ps_crc32_update(0, (const uint8_t *)b_online_entries(&bo), 65 * 4));
    assert_ptr_equal(L.cal[L.active_buf].b.y_q16, b_online_entries(&L.learn));
    assert_int_equal(L.loop.comp.b_cell.width, 0); /* the compensator's cached B cell dropped */
    int32_t b_after = lut_eval(&L.cal[L.active_buf].b, bs.q_mean_q16);
    /* b = 0.9 units here against the flashed ~0.55: the learnt B moves toward the sample. */
    assert_true(b_after > b_before && b_after < bs.b_q16);
    assert_int_equal(b_after, lut_eval(&ref.b, bs.q_mean_q16));

    /* Compensation steps now run the learnt B: the core on the reference table agrees. */
    comp_t cp;
    psp_comp_req_t c = {0};
    for (int k = 0; k < 50; k++) {
        int32_t c_ref = (int32_t)(10.0 * sin(k * 0.1) * 65536.0);
        if (k == 0)
            comp_reset(&cp, &ref, NULL, c_ref);
        c.c_ref_q16 = c_ref;
        resp_t r = req(PSP_MSG_COMP_STEP, &c, sizeof c);
        expect_ok(r, PSP_MSG_COMP_STEP);
        assert_int_equal((int32_t)psf_get_u32(r.pl), comp_step(&cp, c_ref));
    }

    /* A table committed while learning (the host's refresh): its B becomes the prior. */
    n = make_table(2, f_fn);
    expect_ok(upload(blob.bytes, n), PSP_MSG_TABLE_COMMIT);
    st = learn(PSP_LEARN_QUERY);
    assert_int_equal(st.on, 1);
    assert_int_equal(st.samples, 1);
    assert_ptr_equal(L.cal[L.active_buf].b.y_q16, b_online_entries(&L.learn));
    assert_int_equal(st.b_crc32, ps_crc32_update(0, (const uint8_t *)L.learn.prior_q16, 65 * 4));

    st = learn(PSP_LEARN_STOP);
    assert_int_equal(st.on, 0);
    assert_ptr_equal(L.cal[L.active_buf].b.y_q16, L.learn.prior_q16);
}

/* The offset and gain of f learnt with the update on: angle readings while compensating are
 * learnt on the request (nothing published there), each publish runs in psl_background, the
 * set-points then follow the core's compensator on a table whose f^-1 is the learner's (the
 * same learner run here on the same readings); a commit of the same f carries the map over;
 * stop restores the loader's f^-1. */
static void test_learn_f_during_compensation(void **state)
{
    (void)state;
    static uint8_t blob1[PST_MAX_TABLE_SIZE];
    static calib_t ref;
    static f_online_t fo;
    size_t n = commit_table1_with_reference(&ref, blob1);
    f_online_config_t fc = f_online_default_config();
    assert_int_equal(f_online_init(&fo, &fc, &ref.f, &ref.f_inv), F_ONLINE_OK);
    psp_set_mode_t m = {.mode = PSP_MODE_COMPENSATION};
    expect_ok(req(PSP_MSG_SET_MODE, &m, sizeof m), PSP_MSG_SET_MODE);
    (void)learn(PSP_LEARN_START);
    assert_true(L.learn_f_on);
    const calib_t *run = &L.cal[L.active_buf];
    psp_comp_req_t c = {0};
    int published = 0;
    for (int k = 0; k < 60; k++) {
        int32_t c_ref = (int32_t)((20.0 * sin(k * 0.1) + 3.0) * 65536.0);
        c.c_ref_q16 = c_ref;
        resp_t r = req(PSP_MSG_COMP_STEP, &c, sizeof c);
        expect_ok(r, PSP_MSG_COMP_STEP);
        int32_t x = lut_eval(&ref.f, lut_eval(&ref.f_inv, c_ref));
        int32_t read = (int32_t)(1.5 * 65536.0) + (int32_t)(((int64_t)x * 70000) >> 16); /* 1.5 + 1.068 x */
        psp_marker_obs_t mo = {.kind = 1, .t_us = 100000u + (uint32_t)k * 40000u, .u_q16 = read, .valid = 1};
        const int32_t *before = run->f_inv.y_q16;
        expect_ok(req(PSP_MSG_MARKER_OBS, &mo, sizeof mo), PSP_MSG_MARKER_OBS);
        assert_ptr_equal(run->f_inv.y_q16, before); /* learnt in the request, not published */
        bool due = f_online_step(&fo, x, read);
        assert_int_equal(psl_background(&L), due);
        assert_false(psl_background(&L));
        published += due;
        if (due) {
            assert_memory_equal(run->f_inv.y_q16, ref.f_inv.y_q16, run->f_inv.n * sizeof(int32_t));
            assert_int_equal(L.loop.comp.f_inv_cell.width, 0);
        }
    }
    assert_int_equal(published, 5);
    assert_true(L.learn_f.g_q16 > 69000 && L.learn_f.g_q16 < 71000);
    /* The core on a table carrying the same f^-1 gives the board's set-points. */
    comp_t cp;
    for (int k = 0; k < 30; k++) {
        int32_t c_ref = (int32_t)(15.0 * cos(k * 0.1) * 65536.0);
        if (k == 0)
            comp_reset(&cp, &ref, NULL, c_ref);
        c.c_ref_q16 = c_ref;
        if (k == 0)
            expect_ok(req(PSP_MSG_SET_MODE, &m, sizeof m), PSP_MSG_SET_MODE); /* re-armed at this c* too */
        resp_t r = req(PSP_MSG_COMP_STEP, &c, sizeof c);
        assert_int_equal((int32_t)psf_get_u32(r.pl), comp_step(&cp, c_ref));
    }
    /* A commit with the same f: the map carries over into the new table at once. */
    int32_t g = L.learn_f.g_q16;
    n = make_table(2, f_fn);
    expect_ok(upload(blob.bytes, n), PSP_MSG_TABLE_COMMIT);
    run = &L.cal[L.active_buf];
    assert_int_equal(L.learn_f.g_q16, g);
    assert_memory_equal(run->f_inv.y_q16, ref.f_inv.y_q16, run->f_inv.n * sizeof(int32_t));
    assert_ptr_not_equal(run->f_inv.y_q16, run->f_inv_buf);
    (void)learn(PSP_LEARN_STOP);
    assert_false(L.learn_f_on);
    assert_ptr_equal(run->f_inv.y_q16, run->f_inv_buf);
}

/* A power cut at every byte of a commit through the handler: reboot runs old or new. */
static void test_power_cut_via_handler(void **state)
{
    (void)state;
    static fixture_blob_t old_t, new_t;
    size_t on = make_table(3, f_fn);
    memcpy(&old_t, &blob, sizeof blob);
    expect_ok(upload(old_t.bytes, on), PSP_MSG_TABLE_COMMIT);
    static uint8_t base[2 * SLOT];
    memcpy(base, mem, sizeof mem);
    size_t nn = make_table(4, f_fn);
    memcpy(&new_t, &blob, sizeof blob);
    int n_old = 0, n_new = 0;
    const int64_t total = SLOT + (int64_t)nn + 24;
    /* Every byte near both ends, every 97th between (clamped so the last 40 are all cut). */
    for (int64_t cut = 0; cut <= total;
         cut = (cut < 40 || cut >= total - 40) ? cut + 1 : (cut + 97 < total - 40 ? cut + 97 : total - 40)) {
        memcpy(mem, base, sizeof mem);
        pss_sim_init(&sim, mem, SLOT, 0);
        boot();
        pss_sim_power_on(&sim, cut);
        resp_t r = upload(new_t.bytes, nn);
        if (cut < total)
            expect_err(r, PSP_ERR_FLASH);
        pss_sim_power_on(&sim, -1);
        boot();
        psp_info_t i = info();
        uint8_t back[PST_MAX_TABLE_SIZE];
        size_t n = read_back(back, sizeof back);
        if (i.active_generation == 4) {
            assert_int_equal(n, nn);
            assert_memory_equal(back, new_t.bytes, nn);
            n_new++;
        } else {
            assert_int_equal(i.active_generation, 3);
            assert_int_equal(n, on);
            assert_memory_equal(back, old_t.bytes, on);
            n_old++;
        }
    }
    assert_int_equal(n_new, 1);
    assert_true(n_old > 80);
}

/* One owner per upload: a second BEGIN, or a request carrying another token, is BUSY
 * until the owner commits, aborts or has been silent for upload_timeout_us. */
static void test_upload_session_one_owner(void **state)
{
    (void)state;
    size_t n = make_table(1, f_fn);
    uint32_t crc = psf_get_u32(blob.bytes + 12);
    psl_tick(&L, 1000000, 0);
    uint16_t a = begin(n, crc);
    psp_table_begin_t b = {.total_size = (uint32_t)n, .crc32 = crc};
    resp_t r = req(PSP_MSG_TABLE_BEGIN, &b, sizeof b);
    expect_err(r, PSP_ERR_BUSY);
    assert_int_equal(r.pl[3], 5); /* s until the session expires */
    psp_table_chunk_t c = {.offset = 0, .len = PSP_CHUNK_MAX, .session = (uint16_t)(a + 1)};
    memcpy(c.data, blob.bytes, c.len);
    c.chunk_crc32 = ps_crc32_update(0, c.data, c.len);
    expect_err(req(PSP_MSG_TABLE_CHUNK, &c, (uint16_t)(12 + c.len)), PSP_ERR_BUSY);
    psp_table_commit_t cm = {.crc32 = crc, .session = 0};
    expect_err(req(PSP_MSG_TABLE_COMMIT, &cm, sizeof cm), PSP_ERR_BUSY);
    psp_table_abort_t ab = {.session = (uint16_t)(a ^ 0x8000)};
    expect_err(req(PSP_MSG_TABLE_ABORT, &ab, sizeof ab), PSP_ERR_BUSY);
    /* The owner goes on; 2 s later the others are still told to wait, now 3 s. */
    c.session = a;
    expect_ok(req(PSP_MSG_TABLE_CHUNK, &c, (uint16_t)(12 + c.len)), PSP_MSG_TABLE_CHUNK);
    psl_tick(&L, 3000000, 0);
    r = req(PSP_MSG_TABLE_BEGIN, &b, sizeof b);
    expect_err(r, PSP_ERR_BUSY);
    assert_int_equal(r.pl[3], 3);
    /* Silent past the timeout: the session is free, the old token is dead. */
    psl_tick(&L, 8000001, 0);
    expect_err(req(PSP_MSG_TABLE_CHUNK, &c, (uint16_t)(12 + c.len)), PSP_ERR_STATE);
    uint16_t b2 = begin(n, crc);
    assert_true(b2 != a);
    /* Abort by the owner frees it at once. */
    ab.session = b2;
    expect_ok(req(PSP_MSG_TABLE_ABORT, &ab, sizeof ab), PSP_MSG_TABLE_ABORT);
    expect_err(req(PSP_MSG_TABLE_ABORT, &ab, sizeof ab), PSP_ERR_STATE);
    assert_int_equal(info().active_generation, 0);
    /* A whole upload by a third session goes in; after the commit BEGIN is free again. */
    expect_ok(upload(blob.bytes, n), PSP_MSG_TABLE_COMMIT);
    assert_int_equal(info().active_generation, 1);
    begin(n, crc);
}

/* A flash whose whole-record reads (one call longer than the store's verify chunks: the
 * handler's read-back) return one flipped bit while armed: the store's own verify passes,
 * the table CRC on what was read back does not. */
static int flaky_armed;
static int flaky_read(void *ctx, uint8_t slot, uint32_t off, uint8_t *o, uint32_t len)
{
    int r = sim.port.read(ctx, slot, off, o, len);
    if (flaky_armed && len > 64 && r == 0)
        o[len / 2] ^= 0x01;
    return r;
}

static void test_readback_mismatch_keeps_previous(void **state)
{
    (void)state;
    static pss_flash_t flaky;
    flaky = sim.port;
    flaky.read = flaky_read;
    psl_config_t cfg = psl_default_config(1000);
    flaky_armed = 0;
    psl_init(&L, &cfg, &flaky, wr, NULL);
    out_n = 0;
    seq = info().last_seq;
    static fixture_blob_t old_t;
    size_t on = make_table(1, f_fn);
    memcpy(&old_t, &blob, sizeof blob);
    expect_ok(upload(old_t.bytes, on), PSP_MSG_TABLE_COMMIT);
    size_t nn = make_table(2, f_fn);
    flaky_armed = 1;
    resp_t r = upload(blob.bytes, nn);
    flaky_armed = 0;
    expect_err(r, PSP_ERR_FLASH);
    assert_int_equal(r.pl[3], PSL_DETAIL_READBACK);
    psp_info_t i = info();
    assert_int_equal(i.active_generation, 1);
    assert_int_equal(i.active_slot, 0);
    uint8_t back[PST_MAX_TABLE_SIZE];
    assert_int_equal(read_back(back, sizeof back), on);
    assert_memory_equal(back, old_t.bytes, on);
    /* The refused slot was erased: a reboot runs the previous table too. */
    psl_init(&L, &cfg, &flaky, wr, NULL);
    out_n = 0;
    i = info();
    assert_int_equal(i.active_generation, 1);
    seq = i.last_seq;
    /* With a sound flash the same table goes in. */
    expect_ok(upload(blob.bytes, nn), PSP_MSG_TABLE_COMMIT);
    assert_int_equal(info().active_generation, 2);
}

/* The board guards its instrument: it answers its own limits (BOARD), refuses a table for
 * another instrument, in another unit, beyond its travel, or naming no instrument, and keeps
 * the running table. */
static void test_board_guards_its_instrument(void **state)
{
    (void)state;
    resp_t r = req_seq(PSP_MSG_BOARD, 0, NULL, 0);
    expect_ok(r, PSP_MSG_BOARD);
    assert_int_equal(r.len, sizeof(pst_limits_t));
    pst_limits_t lim;
    memcpy(&lim, r.pl, sizeof lim);
    assert_memory_equal(&lim, &L.cfg.limits, sizeof lim);
    size_t n = make_table(1, f_fn);
    expect_ok(upload(blob.bytes, n), PSP_MSG_TABLE_COMMIT);
    psp_info_t before = info();
    /* Another instrument. */
    n = make_table(2, f_fn);
    n = fixture_with_instrument(&blob, PST_INSTRUMENT_DEFAULT + 1, NULL);
    r = upload(blob.bytes, n);
    expect_err(r, PSP_ERR_TABLE);
    assert_int_equal(r.pl[3], CALIB_ERR_BOARD_INSTRUMENT);
    /* A table naming no instrument (layout 2). */
    fixture_grid_t g = {.q0 = -4.0, .step_log2 = 13, .n = 65, .q_min = -4.0, .q_max = 4.0,
                        .f_kind = PST_F_REMAIN, .generation = 2};
    n = fixture_build(&blob, &g, b_fn, NULL, f_fn, NULL);
    r = upload(blob.bytes, n);
    expect_err(r, PSP_ERR_TABLE);
    assert_int_equal(r.pl[3], CALIB_ERR_UNBOUND);
    /* Beyond the board's own travel, though plausible in itself. */
    boot();
    L.cfg.limits.q_max_q16 = 3 * PS_Q16_ONE;
    n = make_table(2, f_fn);
    r = upload(blob.bytes, n);
    expect_err(r, PSP_ERR_TABLE);
    assert_int_equal(r.pl[3], CALIB_ERR_BOARD_TRAVEL);
    psp_info_t after = info();
    assert_int_equal(after.active_generation, before.active_generation);
    assert_int_equal(after.active_crc32, before.active_crc32);
    /* A board configured for another instrument does not boot the table either. */
    psl_config_t cfg = psl_default_config(1000);
    cfg.limits.instrument_id = 9;
    psl_init(&L, &cfg, &sim.port, wr, NULL);
    out_n = 0;
    assert_int_equal(info().active_slot, PSS_NO_SLOT);
}

/* The generation counter: a commit may step it by 1..PST_GENERATION_STEP_MAX, so 0xFFFFFFFF sent
 * by a host is refused; a store an older firmware left at 0xFFFFFFFF takes no commit, and only
 * the physical path (psl_config_t.recover: the pin at boot) frees it. */
static void test_exhausted_generation_recovers_only_by_presence(void **state)
{
    (void)state;
    size_t n = make_table(1, f_fn);
    expect_ok(upload(blob.bytes, n), PSP_MSG_TABLE_COMMIT);
    n = make_table(0xFFFFFFFFu, f_fn);
    resp_t r = upload(blob.bytes, n);
    expect_err(r, PSP_ERR_TABLE);
    assert_int_equal(r.pl[3], PSL_DETAIL_GENERATION);
    n = make_table(1 + PST_GENERATION_STEP_MAX + 1, f_fn);
    expect_err(upload(blob.bytes, n), PSP_ERR_TABLE);
    n = make_table(1 + PST_GENERATION_STEP_MAX, f_fn);
    expect_ok(upload(blob.bytes, n), PSP_MSG_TABLE_COMMIT);
    /* What an older firmware let a host do: the store at the last generation. */
    n = make_table(0xFFFFFFFFu, f_fn);
    assert_int_equal(pss_commit(&L.store, 0xFFFFFFFFu, blob.bytes, (uint32_t)n), PSS_OK);
    boot();
    assert_int_equal(info().active_generation, 0xFFFFFFFFu);
    for (uint32_t gen = 0; gen < 4; gen++) { /* nothing follows it, wrapped or not */
        n = make_table(gen, f_fn);
        r = upload(blob.bytes, n);
        expect_err(r, PSP_ERR_TABLE);
        assert_int_equal(r.pl[3], PSL_DETAIL_GENERATION);
    }
    boot(); /* a reset alone changes nothing */
    assert_int_equal(info().active_generation, 0xFFFFFFFFu);
    psl_config_t cfg = psl_default_config(1000);
    cfg.recover = true; /* the recovery pin held at reset */
    psl_init(&L, &cfg, &sim.port, wr, NULL);
    out_n = 0;
    seq = info().last_seq;
    psp_info_t i = info();
    assert_int_equal(i.active_slot, PSS_NO_SLOT);
    assert_int_equal(i.active_generation, 0);
    n = make_table(1, f_fn);
    expect_ok(upload(blob.bytes, n), PSP_MSG_TABLE_COMMIT);
    boot();
    assert_int_equal(info().active_generation, 1);
}

static resp_t exc_config(psp_exc_config_t *m)
{
    return req(PSP_MSG_EXC_CONFIG, m, sizeof *m);
}

static int32_t run_excitation(uint32_t ticks)
{
    psp_set_mode_t md = {.mode = PSP_MODE_EXCITATION};
    expect_ok(req(PSP_MSG_SET_MODE, &md, sizeof md), PSP_MSG_SET_MODE);
    int32_t q = 0;
    for (uint32_t k = 1; k <= ticks; k++)
        q = psl_tick(&L, k * 1000u, q);
    md.mode = PSP_MODE_IDLE;
    expect_ok(req(PSP_MSG_SET_MODE, &md, sizeof md), PSP_MSG_SET_MODE);
    out_n = 0;
    return q;
}

/* The excitation set from the host (PSP_MSG_EXC_CONFIG), paced to the camera: the answer
 * carries the speed of the pacing rule (v = b_low / (EXC_PACE_FRAMES frame periods), here
 * computed in double), the board runs it, and the frame period reaches the onset detector.
 * A refused config (play wider than the swing's shorter leg; any config during an excitation)
 * changes nothing; a given speed is taken as is. */
static void test_exc_config_paces_the_excitation(void **state)
{
    (void)state;
    const double b_low = 0.25, T = 0.04, tick_hz = 1000.0;
    psp_exc_config_t m = {.q_start_q16 = 0, .q_end_q16 = 10 * 65536, .amplitude_q16 = 65536,
                          .advance_q16 = 65536 / 4, .v_q32 = 0, .b_low_q16 = (int32_t)(b_low * 65536),
                          .b_high_q16 = 65536 / 2, .frame_period_us = 40000, .return_sweep = 1};
    resp_t r = exc_config(&m);
    expect_ok(r, PSP_MSG_EXC_CONFIG);
    assert_int_equal(r.len, sizeof(psp_exc_config_t));
    psp_exc_config_t a;
    memcpy(&a, r.pl, sizeof a);
    const int64_t v_ref = (int64_t)floor(b_low / (EXC_PACE_FRAMES * T) / tick_hz * 4294967296.0);
    assert_int_equal(a.v_q32, v_ref);
    assert_int_equal(a.frame_period_us, 40000);
    assert_int_equal(L.loop.cfg.onset.frame_period_us, 40000);
    /* 0.5 s at 1.5625 units/s on the first (rising) leg: 0.78125 units. */
    int32_t q = run_excitation(500);
    assert_true(abs(q - (int32_t)(0.78125 * 65536)) <= 1);

    /* The widest play must fit the shorter leg (amplitude - advance = 0.75): 0.8 is refused. */
    psp_exc_config_t bad = m;
    bad.b_high_q16 = (int32_t)(0.8 * 65536);
    r = exc_config(&bad);
    expect_err(r, PSP_ERR_RANGE);
    assert_int_equal(r.pl[3], EXC_ERR_PACE);
    bad = m;
    bad.b_low_q16 = 0; /* pacing without a play range */
    expect_err(exc_config(&bad), PSP_ERR_RANGE);
    bad = m;
    bad.return_sweep = 2;
    expect_err(exc_config(&bad), PSP_ERR_RANGE);
    psp_set_mode_t md = {.mode = PSP_MODE_EXCITATION};
    expect_ok(req(PSP_MSG_SET_MODE, &md, sizeof md), PSP_MSG_SET_MODE);
    expect_err(exc_config(&m), PSP_ERR_STATE);
    md.mode = PSP_MODE_IDLE;
    expect_ok(req(PSP_MSG_SET_MODE, &md, sizeof md), PSP_MSG_SET_MODE);
    q = run_excitation(500); /* unchanged by the refusals */
    assert_true(abs(q - (int32_t)(0.78125 * 65536)) <= 1);

    /* A given speed (2 units/s) is run as is, pacing off. */
    m.v_q32 = (int64_t)(2.0 / tick_hz * 4294967296.0);
    r = exc_config(&m);
    expect_ok(r, PSP_MSG_EXC_CONFIG);
    memcpy(&a, r.pl, sizeof a);
    assert_int_equal(a.v_q32, m.v_q32);
    assert_int_equal(L.cfg.pace.b_high_q16, 0);
    q = run_excitation(250);
    assert_true(abs(q - 65536 / 2) <= 1);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup(test_info_fresh, setup),
        cmocka_unit_test_setup(test_upload_commit_readback_reboot, setup),
        cmocka_unit_test_setup(test_refusals_change_nothing, setup),
        cmocka_unit_test_setup(test_replay_and_order, setup),
        cmocka_unit_test_setup(test_commit_during_compensation_not_excitation, setup),
        cmocka_unit_test_setup(test_compensation_matches_core, setup),
        cmocka_unit_test_setup(test_streaming, setup),
        cmocka_unit_test_setup(test_onset_over_the_link, setup),
        cmocka_unit_test_setup(test_learn_during_compensation, setup),
        cmocka_unit_test_setup(test_learn_f_during_compensation, setup),
        cmocka_unit_test_setup(test_power_cut_via_handler, setup),
        cmocka_unit_test_setup(test_readback_mismatch_keeps_previous, setup),
        cmocka_unit_test_setup(test_upload_session_one_owner, setup),
        cmocka_unit_test_setup(test_exc_config_paces_the_excitation, setup),
        cmocka_unit_test_setup(test_board_guards_its_instrument, setup),
        cmocka_unit_test_setup(test_exhausted_generation_recovers_only_by_presence, setup),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
