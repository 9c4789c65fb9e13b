/* Tests of the frame codec: round trip, resync after garbage, CRC and length errors, shared vectors. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ps_frame.h"

typedef struct {
    int n;
    uint8_t type[8];
    uint16_t seq[8];
    uint16_t len[8];
    uint8_t payload[8][PSP_MAX_PAYLOAD];
    int errors[4]; /* counts by psf_result_t */
} sink_t;

/* Push bytes in pieces of `step` and record every frame or error. */
static void feed(psf_parser_t *p, sink_t *s, const uint8_t *d, size_t n, size_t step)
{
    size_t i = 0;
    while (i < n) {
        size_t piece = n - i < step ? n - i : step;
        const uint8_t *q = d + i;
        size_t left = piece;
        for (;;) {
            psf_result_t r;
            size_t used = psf_parser_push(p, q, left, &r);
            q += used;
            left -= used;
            if (r == PSF_FRAME) {
                assert_true(s->n < 8);
                s->type[s->n] = p->hdr.type;
                s->seq[s->n] = p->hdr.seq;
                s->len[s->n] = p->hdr.len;
                memcpy(s->payload[s->n], psf_parser_payload(p), p->hdr.len);
                s->n++;
            } else if (r != PSF_NEED_MORE) {
                s->errors[r]++;
            }
            if (left == 0 && r == PSF_NEED_MORE)
                break;
        }
        i += piece;
    }
}

static void test_round_trip_any_split(void **state)
{
    (void)state;
    uint8_t pl[PSP_MAX_PAYLOAD];
    for (int i = 0; i < PSP_MAX_PAYLOAD; i++)
        pl[i] = (uint8_t)(i * 7 + 1);
    uint8_t buf[3 * PSF_MAX_FRAME];
    size_t n = psf_encode(buf, sizeof buf, PSP_MSG_INFO, 1, NULL, 0);
    n += psf_encode(buf + n, sizeof buf - n, PSP_MSG_TABLE_CHUNK, 0xFFFF, pl, PSP_MAX_PAYLOAD);
    n += psf_encode(buf + n, sizeof buf - n, PSP_MSG_COMP_STEP, 3, pl, 4);
    assert_int_equal(n, 12 + 260 + 16);
    for (size_t step = 1; step <= n; step = step < 16 ? step + 1 : step * 2) {
        psf_parser_t p;
        sink_t s = {0};
        psf_parser_reset(&p);
        feed(&p, &s, buf, n, step);
        assert_int_equal(s.n, 3);
        assert_int_equal(s.type[0], PSP_MSG_INFO);
        assert_int_equal(s.len[0], 0);
        assert_int_equal(s.seq[1], 0xFFFF);
        assert_int_equal(s.len[1], PSP_MAX_PAYLOAD);
        assert_memory_equal(s.payload[1], pl, PSP_MAX_PAYLOAD);
        assert_int_equal(s.type[2], PSP_MSG_COMP_STEP);
        assert_int_equal(p.n_dropped_bytes, 0);
    }
}

static void test_encode_refuses_oversize(void **state)
{
    (void)state;
    uint8_t buf[400], pl[300] = {0};
    assert_int_equal(psf_encode(buf, sizeof buf, 1, 1, pl, PSP_MAX_PAYLOAD + 1), 0);
    assert_int_equal(psf_encode(buf, 20, 1, 1, pl, 9), 0); /* 21 bytes needed */
    assert_int_equal(psf_encode(buf, 21, 1, 1, pl, 9), 21);
}

static void test_garbage_then_frame(void **state)
{
    (void)state;
    uint8_t buf[64] = {0x00, 'P', 'P', 0x13, 'S', 'P'}; /* false syncs, a lone P at the end */
    uint32_t v = 0x12345678;
    size_t n = 6 + psf_encode(buf + 6, sizeof buf - 6, PSP_MSG_COMP_STEP, 9, &v, 4);
    psf_parser_t p;
    sink_t s = {0};
    psf_parser_reset(&p);
    feed(&p, &s, buf, n, 1);
    assert_int_equal(s.n, 1);
    assert_int_equal(s.seq[0], 9);
    assert_int_equal(p.n_dropped_bytes, 6);
}

static void test_bad_crc_then_good(void **state)
{
    (void)state;
    uint8_t buf[64];
    uint32_t v = 7;
    size_t a = psf_encode(buf, sizeof buf, PSP_MSG_COMP_STEP, 1, &v, 4);
    size_t b = psf_encode(buf + a, sizeof buf - a, PSP_MSG_COMP_STEP, 2, &v, 4);
    buf[9] ^= 0x40; /* payload bit flip in the first */
    psf_parser_t p;
    sink_t s = {0};
    psf_parser_reset(&p);
    feed(&p, &s, buf, a + b, a + b);
    assert_int_equal(s.errors[PSF_BAD_CRC], 1);
    assert_int_equal(s.n, 1);
    assert_int_equal(s.seq[0], 2);
}

static void test_oversized_length(void **state)
{
    (void)state;
    uint8_t buf[64] = {'P', 'S', 1, 1, 5, 0, 0xF9, 0x00}; /* len 249 */
    uint32_t v = 7;
    size_t n = 8 + psf_encode(buf + 8, sizeof buf - 8, PSP_MSG_COMP_STEP, 3, &v, 4);
    psf_parser_t p;
    sink_t s = {0};
    psf_parser_reset(&p);
    feed(&p, &s, buf, n, 5);
    assert_int_equal(s.errors[PSF_BAD_LENGTH], 1);
    assert_int_equal(s.n, 1);
    assert_int_equal(s.seq[0], 3);
}

/* A frame hidden inside a truncated one is found after the CRC of the outer one fails. */
static void test_frame_inside_truncated_frame(void **state)
{
    (void)state;
    uint8_t buf[128] = {'P', 'S', 1, 1, 1, 0, 20, 0}; /* announces 20 bytes, then a real frame */
    uint32_t v = 5;
    size_t n = 8 + psf_encode(buf + 8, sizeof buf - 8, PSP_MSG_COMP_STEP, 4, &v, 4);
    memset(buf + n, 0, 40); /* line noise completes the outer frame */
    n += 40;
    psf_parser_t p;
    sink_t s = {0};
    psf_parser_reset(&p);
    feed(&p, &s, buf, n, 3);
    assert_int_equal(s.errors[PSF_BAD_CRC], 1);
    assert_int_equal(s.n, 1);
    assert_int_equal(s.seq[0], 4);
}

static int hexval(int c)
{
    return c <= '9' ? c - '0' : (c | 0x20) - 'a' + 10;
}

static size_t unhex(const char *h, uint8_t *out)
{
    size_t n = 0;
    while (h[0] && h[1] && h[0] != ' ' && h[0] != '\n') {
        out[n++] = (uint8_t)(hexval(h[0]) << 4 | hexval(h[1]));
        h += 2;
    }
    return n;
}

/* The same file is run by tests/python/link/test_frame_vectors.py through the host. */
static void test_shared_vectors(void **state)
{
    (void)state;
    FILE *f = fopen(PS_LINK_VECTORS, "r");
    assert_non_null(f);
    char line[1200];
    int count = 0;
    while (fgets(line, sizeof line, f)) {
        if (line[0] == '#' || line[0] == '\n')
            continue;
        unsigned type, seq;
        char pl_hex[600], fr_hex[600];
        assert_int_equal(sscanf(line, "%x %x %599s %599s", &type, &seq, pl_hex, fr_hex), 4);
        uint8_t pl[PSP_MAX_PAYLOAD], want[PSF_MAX_FRAME], got[PSF_MAX_FRAME];
        size_t npl = strcmp(pl_hex, "-") == 0 ? 0 : unhex(pl_hex, pl);
        size_t nfr = unhex(fr_hex, want);
        size_t n = psf_encode(got, sizeof got, (uint8_t)type, (uint16_t)seq, pl, (uint16_t)npl);
        assert_int_equal(n, nfr);
        assert_memory_equal(got, want, n);
        psf_parser_t p;
        sink_t s = {0};
        psf_parser_reset(&p);
        feed(&p, &s, want, nfr, 1);
        assert_int_equal(s.n, 1);
        assert_int_equal(s.len[0], npl);
        count++;
    }
    fclose(f);
    assert_true(count >= 4);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_round_trip_any_split),
        cmocka_unit_test(test_encode_refuses_oversize),
        cmocka_unit_test(test_garbage_then_frame),
        cmocka_unit_test(test_bad_crc_then_good),
        cmocka_unit_test(test_oversized_length),
        cmocka_unit_test(test_frame_inside_truncated_frame),
        cmocka_unit_test(test_shared_vectors),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
