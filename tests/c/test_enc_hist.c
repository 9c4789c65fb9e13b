/* Tests of the encoder history: interpolation, wrap-around of the ring and of the clock. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <math.h>

#include "enc_hist.h"
#include "test_rng.h"

static enc_hist_t h;

static void test_empty_and_one_sample(void **state)
{
    (void)state;
    int32_t q;
    enc_hist_reset(&h);
    assert_int_equal(enc_hist_q_at(&h, 0, &q), ENC_HIST_EMPTY);
    enc_hist_push(&h, 100, 5);
    assert_int_equal(enc_hist_q_at(&h, 100, &q), ENC_HIST_EMPTY);
}

/* q(t) = 3 t + 7 sampled every 1000 us: interpolation is exact to 1/2 raw unit. */
static void test_linear_interpolation(void **state)
{
    (void)state;
    enc_hist_reset(&h);
    for (uint32_t k = 0; k < 100; k++)
        enc_hist_push(&h, 1000u * k, (int32_t)(3000 * k + 7));
    int32_t q;
    for (uint32_t t = 0; t <= 99000; t += 37) {
        assert_int_equal(enc_hist_q_at(&h, t, &q), ENC_HIST_OK);
        assert_in_range(q, (int32_t)(3 * t + 7) - 1, (int32_t)(3 * t + 7) + 1);
    }
    assert_int_equal(enc_hist_q_at(&h, 99001, &q), ENC_HIST_TOO_NEW);
}

/* After more than ENC_HIST_LEN pushes, times older than the oldest kept sample are refused. */
static void test_ring_wrap(void **state)
{
    (void)state;
    enc_hist_reset(&h);
    const uint32_t total = ENC_HIST_LEN * 3 + 17;
    for (uint32_t k = 0; k < total; k++)
        enc_hist_push(&h, 10u * k, (int32_t)k);
    int32_t q;
    uint32_t oldest = 10u * (total - ENC_HIST_LEN);
    assert_int_equal(enc_hist_q_at(&h, oldest - 1, &q), ENC_HIST_TOO_OLD);
    assert_int_equal(enc_hist_q_at(&h, oldest, &q), ENC_HIST_OK);
    assert_int_equal(q, (int32_t)(total - ENC_HIST_LEN));
    assert_int_equal(enc_hist_q_at(&h, 10u * (total - 1) - 5, &q), ENC_HIST_OK);
    assert_in_range(q, (int32_t)total - 2, (int32_t)total - 1);
}

/* The microsecond clock wraps at 2^32 (71.6 min); lookups across the wrap still work. */
static void test_clock_wrap(void **state)
{
    (void)state;
    enc_hist_reset(&h);
    uint32_t t0 = UINT32_MAX - 5000u;
    for (uint32_t k = 0; k < 20; k++)
        enc_hist_push(&h, t0 + 1000u * k, (int32_t)(1000 * k));
    int32_t q;
    assert_int_equal(enc_hist_q_at(&h, t0 + 7500u, &q), ENC_HIST_OK); /* past the wrap */
    assert_in_range(q, 7499, 7501);
    assert_int_equal(enc_hist_q_at(&h, t0 - 1u, &q), ENC_HIST_TOO_OLD);
}

static void test_out_of_order_push_dropped(void **state)
{
    (void)state;
    enc_hist_reset(&h);
    enc_hist_push(&h, 1000, 10);
    enc_hist_push(&h, 2000, 20);
    enc_hist_push(&h, 1500, 999); /* late sample: dropped, history stays sorted */
    enc_hist_push(&h, 3000, 30);
    int32_t q;
    assert_int_equal(enc_hist_q_at(&h, 2500, &q), ENC_HIST_OK);
    assert_int_equal(q, 25);
}

/* The push as the rule of enc_hist.h states it, written plainly (drop out of order, keep
 * at or after next_keep or when empty, else fold into the range), to check the fast path's
 * one-compare test against: same kept samples, spreads and live end, push by push. */
static void ref_push(enc_hist_t *r, uint32_t t_us, int32_t q)
{
    if (r->head != 0 && (int32_t)(t_us - r->last_t_us) < 0)
        return;
    r->last_t_us = t_us;
    r->last_q_q16 = q;
    r->lo_q16 = q < r->lo_q16 ? q : r->lo_q16;
    r->hi_q16 = q > r->hi_q16 ? q : r->hi_q16;
    if (r->head != 0 && (int32_t)(t_us - r->next_keep_us) < 0)
        return;
    if (r->head != 0) {
        uint32_t sp = (uint32_t)r->hi_q16 - (uint32_t)r->lo_q16;
        r->spread_q16[(r->head - 1u) % ENC_HIST_LEN] = (uint16_t)(sp > 0xFFFFu ? 0xFFFFu : sp);
    }
    r->t_us[r->head % ENC_HIST_LEN] = t_us;
    r->q_q16[r->head % ENC_HIST_LEN] = q;
    r->lo_q16 = r->hi_q16 = q;
    r->next_keep_us = t_us + r->keep_us;
    r->head++;
}

/* Compares the newest `depth` kept samples (all of them: ENC_HIST_LEN). */
static void assert_same_history(const enc_hist_t *a, const enc_hist_t *b, uint32_t depth)
{
    assert_int_equal(a->head, b->head);
    assert_int_equal(a->last_t_us, b->last_t_us);
    assert_int_equal(a->last_q_q16, b->last_q_q16);
    if (a->head == 0)
        return;
    assert_int_equal(a->lo_q16, b->lo_q16);
    assert_int_equal(a->hi_q16, b->hi_q16);
    assert_int_equal(a->next_keep_us, b->next_keep_us);
    uint32_t n = a->head < depth ? a->head : depth;
    for (uint32_t i = 0; i < n; i++) {
        uint32_t k = (a->head - 1u - i) % ENC_HIST_LEN;
        assert_int_equal(a->t_us[k], b->t_us[k]);
        assert_int_equal(a->q_q16[k], b->q_q16[k]);
        if (i > 0) /* the newest sample's interval is still open */
            assert_int_equal(a->spread_q16[k], b->spread_q16[k]);
    }
}

/* enc_hist_push equals the plain rule on ticks with jitter, repeated and late times, time
 * jumps, the clock wrapping past 2^32, resets mid-stream, and spacings 0 (keep all), 1 us
 * and 2.23 ms (the default at 20 kHz). */
static void test_push_equals_plain_rule(void **state)
{
    (void)state;
    static enc_hist_t ref;
    test_rng_t r;
    test_rng_seed(&r, 5);
    const uint32_t spans[] = {0u, 511u, 1140000u};
    for (int si = 0; si < 3; si++) {
        enc_hist_set_span(&h, spans[si]);
        enc_hist_set_span(&ref, spans[si]);
        uint32_t t = 0xFFFFFFFFu - 20000u * (uint32_t)si; /* wraps within the run */
        int32_t q = 0;
        for (int k = 0; k < 60000; k++) {
            uint64_t u = test_rng_u64(&r);
            switch (u % 64) {
            case 0: t -= (uint32_t)(u >> 8) % 400u; break;          /* late sample */
            case 1: t += (uint32_t)(u >> 8) % 100000u; break;       /* gap in the ticks */
            case 2: break;                                          /* same time again */
            case 3:
                if (k % 7 == 0) { enc_hist_reset(&h); enc_hist_reset(&ref); }
                break;
            default: t += 50u - 2u + (uint32_t)(u >> 8) % 5u;       /* 20 kHz with jitter */
            }
            q += (int32_t)((u >> 20) % 2001u) - 1000;
            enc_hist_push(&h, t, q);
            ref_push(&ref, t, q);
            assert_same_history(&h, &ref, k % 256 == 0 ? ENC_HIST_LEN : 2u);
        }
    }
}

/* Decimated history at 20 kHz: a sample kept every keep_us; lookups at every pushed time
 * of the last span are within the reported bound of the pushed value (the bound is exact,
 * so this must hold for all of them), and the span asked for is covered. The signal is a
 * noisy back-and-forth motion, so the bound is exercised at reversals and with jitter. */
/* The pushed signal, regenerated sample by sample (too long to keep on the M4 target). */
typedef struct {
    test_rng_t r;
    double q, v;
} walk_t;

static void walk_init(walk_t *w)
{
    test_rng_seed(&w->r, 11);
    w->q = 0;
    w->v = 5.0 / 20000; /* 5 mm/s at 20 kHz, reversing every 0.3 s */
}

static int32_t walk_next(walk_t *w, int k)
{
    if (k % 6000 == 0)
        w->v = -w->v;
    w->q += w->v;
    return (int32_t)lround((w->q + 0.0005 * test_rng_normal(&w->r)) * 65536.0);
}

static void test_decimated_bound_exact_and_span_covered(void **state)
{
    (void)state;
    enum { TICK_US = 50, N_TICKS = 60000 }; /* 3 s at 20 kHz */
    const uint32_t span_us = 1140000;       /* the default onset config's history span */
    enc_hist_set_span(&h, span_us);
    assert_int_equal(h.keep_us, (span_us + ENC_HIST_LEN - 2) / (ENC_HIST_LEN - 1));
    walk_t w;
    walk_init(&w);
    uint32_t t0 = UINT32_MAX - 1000000u;    /* and across the clock wrap */
    for (int k = 0; k < N_TICKS; k++)
        enc_hist_push(&h, t0 + (uint32_t)k * TICK_US, walk_next(&w, k));
    uint32_t t_last = t0 + (uint32_t)(N_TICKS - 1) * TICK_US;
    int32_t qa;
    uint32_t bound, bound_max = 0;
    int n_nonzero = 0, first = N_TICKS - 1 - (int)(span_us / TICK_US);
    walk_init(&w);
    for (int k = 0; k < N_TICKS; k++) {
        int32_t q_true = walk_next(&w, k);
        if (k < first)
            continue;
        assert_int_equal(enc_hist_q_at_bound(&h, t0 + (uint32_t)k * TICK_US, &qa, &bound), ENC_HIST_OK);
        int64_t d = (int64_t)qa - q_true;
        assert_true((d < 0 ? -d : d) <= (int64_t)bound);
        bound_max = bound > bound_max ? bound : bound_max;
        n_nonzero += bound > 0;
    }
    /* Not a vacuous bound: it is non-zero between kept samples and about one spacing of travel. */
    print_message("keep %lu us, largest bound %.4f mm\n", (unsigned long)h.keep_us, bound_max / 65536.0);
    assert_true(n_nonzero > 0);
    /* 2.23 ms of travel at 5 mm/s (0.011 mm) plus the jitter range (~0.004 mm); measured 0.0137. */
    assert_true(bound_max < 65536 / 50);
    assert_int_equal(enc_hist_q_at(&h, t_last - span_us, &qa), ENC_HIST_OK);
    assert_int_equal(enc_hist_q_at(&h, t_last + 1u, &qa), ENC_HIST_TOO_NEW);
    /* Kept samples are at most keep_us + one tick apart: the ring reaches no further back. */
    assert_int_equal(enc_hist_q_at(&h, t_last - ENC_HIST_LEN * (h.keep_us + TICK_US), &qa), ENC_HIST_TOO_OLD);
    enc_hist_set_span(&h, 0); /* back to every push for the other tests */
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_empty_and_one_sample),
        cmocka_unit_test(test_linear_interpolation),
        cmocka_unit_test(test_ring_wrap),
        cmocka_unit_test(test_clock_wrap),
        cmocka_unit_test(test_out_of_order_push_dropped),
        cmocka_unit_test(test_push_equals_plain_rule),
        cmocka_unit_test(test_decimated_bound_exact_and_span_covered),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
