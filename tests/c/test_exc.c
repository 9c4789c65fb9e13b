/* Tests of the excitation trajectory: turning points, constant speed, reversals, errors. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <cmocka.h>

#include "exc.h"

#define Q16(x) ((int32_t)((x) * 65536.0 + ((x) >= 0 ? 0.5 : -0.5)))

static exc_config_t base_cfg(void)
{
    exc_config_t c = {.q_start_q16 = Q16(-2.0), .q_end_q16 = Q16(2.0), .amplitude_q16 = Q16(1.0),
                      .advance_q16 = Q16(0.25), .v_q32 = (int64_t)1 << 26 /* 1/64 unit per tick */,
                      .return_sweep = false};
    return c;
}

static void test_config_errors(void **state)
{
    (void)state;
    exc_t e;
    exc_config_t c = base_cfg();
    c.q_end_q16 = c.q_start_q16;
    assert_int_equal(exc_init(&e, &c), EXC_ERR_RANGE);
    c = base_cfg();
    c.advance_q16 = c.amplitude_q16;
    assert_int_equal(exc_init(&e, &c), EXC_ERR_SHAPE);
    c = base_cfg();
    c.advance_q16 = 0;
    assert_int_equal(exc_init(&e, &c), EXC_ERR_SHAPE);
    c = base_cfg();
    c.v_q32 = 0;
    assert_int_equal(exc_init(&e, &c), EXC_ERR_SPEED);
    c = base_cfg();
    c.v_q32 = (int64_t)Q16(0.3) << 16; /* faster than the shortest segment per tick */
    assert_int_equal(exc_init(&e, &c), EXC_ERR_SPEED);
}

/* Run to the end, collecting turning points; check speed and monotone segments. */
static int run(exc_config_t c, int32_t *turns, int max_turns, int32_t *q_min, int32_t *q_max)
{
    exc_t e;
    assert_int_equal(exc_init(&e, &c), EXC_OK);
    int n = 0;
    int32_t prev = c.q_start_q16;
    *q_min = *q_max = prev;
    for (int k = 0; k < 1000000 && !exc_done(&e); k++) {
        bool rev;
        int32_t q = exc_step(&e, &rev);
        /* At most one tick of travel, never more. */
        assert_true(abs(q - prev) <= (int32_t)(c.v_q32 >> 16) + 1);
        if (q < *q_min) *q_min = q;
        if (q > *q_max) *q_max = q;
        if (rev) {
            assert_true(n < max_turns);
            turns[n++] = q;
        }
        prev = q;
    }
    assert_true(exc_done(&e));
    return n;
}

static void test_forward_sweep_turning_points(void **state)
{
    (void)state;
    int32_t t[64], lo, hi;
    int n = run(base_cfg(), t, 64, &lo, &hi);
    /* Tops at low + 1 and bottoms at low += 0.25 from -2: -1, -1.75, -0.75, -1.5, ... up to the top at 2. */
    assert_int_equal(t[0], Q16(-1.0));
    assert_int_equal(t[1], Q16(-1.75));
    assert_int_equal(t[2], Q16(-0.75));
    assert_int_equal(t[3], Q16(-1.5));
    /* Every back-and-forth pair: top - next bottom = A - advance = 0.75. */
    for (int i = 0; i + 1 < n - 1; i += 2)
        assert_int_equal(t[i] - t[i + 1], Q16(0.75));
    assert_int_equal(lo, Q16(-2.0));
    assert_int_equal(hi, Q16(2.0));
    assert_true(n >= 20);
}

static void test_return_sweep_mirrors(void **state)
{
    (void)state;
    exc_config_t c = base_cfg();
    c.return_sweep = true;
    int32_t t[128], lo, hi;
    int n = run(c, t, 128, &lo, &hi);
    int32_t tf[64];
    int nf = run(base_cfg(), tf, 64, &lo, &hi);
    assert_true(n > nf + 10);
    /* Same turning points up to the top at q_end, which is a reversal only when a return follows. */
    for (int i = 0; i < nf; i++)
        assert_int_equal(t[i], tf[i]);
    assert_int_equal(t[nf], Q16(2.0));
    assert_int_equal(t[nf + 1], Q16(1.0));   /* down by A from the top */
    assert_int_equal(t[nf + 2], Q16(1.75));  /* up to top - advance */
    assert_int_equal(lo, Q16(-2.0));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_config_errors),
        cmocka_unit_test(test_forward_sweep_turning_points),
        cmocka_unit_test(test_return_sweep_mirrors),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
