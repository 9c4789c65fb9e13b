/* Self-test of the bare-metal cmocka shim: passing checks pass, failing ones are counted. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

static int setup_count;

static int setup_state(void **state)
{
    static int value = 42;
    *state = &value;
    setup_count++;
    return 0;
}

static int teardown_state(void **state)
{
    *(int *)*state = 42;
    return 0;
}

static void test_passing_checks(void **state)
{
    (void)state;
    const uint8_t a[3] = {1, 2, 3}, b[3] = {1, 2, 3};
    assert_true(1 + 1 == 2);
    assert_false(0);
    assert_int_equal(-5, -5);
    assert_int_not_equal(-5, 5);
    assert_in_range(7, 1, 10);
    assert_not_in_range(11, 1, 10);
    assert_null(NULL);
    assert_non_null(a);
    assert_memory_equal(a, b, sizeof a);
    assert_string_equal("abc", "abc");
    assert_string_not_equal("abc", "abd");
    assert_return_code(0, 0);
    assert_float_equal(sqrt(2.0), 1.41421356, 1e-8);
    /* Reference maths in double and libm, as the core tests use, on the FPU-less-double M4. */
    volatile double x = 0.5;
    assert_float_equal(sin(x) * sin(x) + cos(x) * cos(x), 1.0, 1e-12);
    assert_int_equal((int64_t)llround(1e10 / 3.0), 3333333333LL);
}

static void test_state_from_setup(void **state)
{
    assert_int_equal(*(int *)*state, 42);
    *(int *)*state = 7;  /* teardown puts it back */
}

static void test_heap_and_stack(void **state)
{
    (void)state;
    /* A calib_t-sized object on the stack and on the heap, as tests may allocate them. */
    volatile uint8_t big[16 * 1024];
    memset((void *)big, 0x5A, sizeof big);
    assert_int_equal(big[sizeof big - 1], 0x5A);
    uint8_t *p = test_malloc(32 * 1024);
    assert_non_null(p);
    memset(p, 1, 32 * 1024);
    test_free(p);
}

static void test_skipped(void **state)
{
    (void)state;
    skip();
}

/* The following three must fail: the group returns 3 and main maps exactly 3 to success. */
static void test_expected_fail_int(void **state)
{
    (void)state;
    assert_int_equal(1, 2);
}

static void test_expected_fail_range(void **state)
{
    (void)state;
    assert_in_range(-1, -10, 10);  /* unsigned comparison, as in cmocka: -1 is huge */
}

static void test_expected_fail_msg(void **state)
{
    (void)state;
    fail_msg("expected failure %d", 3);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_passing_checks),
        cmocka_unit_test_setup_teardown(test_state_from_setup, setup_state, teardown_state),
        cmocka_unit_test_setup_teardown(test_state_from_setup, setup_state, teardown_state),
        cmocka_unit_test(test_heap_and_stack),
        cmocka_unit_test(test_skipped),
        cmocka_unit_test(test_expected_fail_int),
        cmocka_unit_test(test_expected_fail_range),
        cmocka_unit_test(test_expected_fail_msg),
    };
    int failed = cmocka_run_group_tests(tests, NULL, NULL);
    print_message("selftest: %d failed (3 expected), setup ran %d times (2 expected)\n", failed, setup_count);
    return failed == 3 && setup_count == 2 ? 0 : 1;
}
