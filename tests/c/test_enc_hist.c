/* Tests of the encoder history: interpolation, wrap-around of the ring and of the clock. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include "enc_hist.h"

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

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_empty_and_one_sample),
        cmocka_unit_test(test_linear_interpolation),
        cmocka_unit_test(test_ring_wrap),
        cmocka_unit_test(test_clock_wrap),
        cmocka_unit_test(test_out_of_order_push_dropped),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
