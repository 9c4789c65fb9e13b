/* Minimal cmocka-compatible unit-test API for bare-metal targets (no cmocka port for the M4). */
#ifndef PS_TARGET_CMOCKA_H
#define PS_TARGET_CMOCKA_H

/* Covers the subset of cmocka 1.1 that tests/c uses: test tables with fixtures, group
 * runs, the assert_* family, fail, skip, print_message and test_malloc. Semantics follow
 * cmocka's so a test behaves the same on the desktop (real cmocka) and on the target:
 * integers are compared after a cast to LargestIntegralType (uintmax_t), so
 * assert_in_range compares unsigned, as cmocka does. A failed check longjmps out of the
 * test; the group returns the number of failed tests, which main returns as the exit
 * status. No mocks (will_return/expect_*) and no leak checking. */

#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>

#ifndef LargestIntegralType
#define LargestIntegralType uintmax_t
#endif

typedef void (*CMUnitTestFunction)(void **state);
typedef int (*CMFixtureFunction)(void **state);

struct CMUnitTest {
    const char *name;
    CMUnitTestFunction test_func;
    CMFixtureFunction setup_func;
    CMFixtureFunction teardown_func;
    void *initial_state;
};

#define cmocka_unit_test(f) {#f, f, NULL, NULL, NULL}
#define cmocka_unit_test_setup(f, setup) {#f, f, setup, NULL, NULL}
#define cmocka_unit_test_teardown(f, teardown) {#f, f, NULL, teardown, NULL}
#define cmocka_unit_test_setup_teardown(f, setup, teardown) {#f, f, setup, teardown, NULL}
#define cmocka_unit_test_prestate(f, state) {#f, f, NULL, NULL, state}
#define cmocka_unit_test_prestate_setup_teardown(f, setup, teardown, state) {#f, f, setup, teardown, state}

#define cmocka_run_group_tests(group_tests, group_setup, group_teardown)                        \
    _cmocka_run_group_tests(#group_tests, group_tests, sizeof(group_tests) / sizeof((group_tests)[0]), \
                            group_setup, group_teardown)
#define cmocka_run_group_tests_name(group_name, group_tests, group_setup, group_teardown)       \
    _cmocka_run_group_tests(group_name, group_tests, sizeof(group_tests) / sizeof((group_tests)[0]), \
                            group_setup, group_teardown)

#define cast_to_largest_integral_type(v) ((LargestIntegralType)(v))
#define cast_ptr_to_largest_integral_type(p) ((LargestIntegralType)(uintptr_t)(p))

#define assert_true(c) _cm_check(!!(c), #c, __FILE__, __LINE__)
#define assert_false(c) _cm_check(!(c), "!(" #c ")", __FILE__, __LINE__)
#define assert_int_equal(a, b) \
    _cm_int_cmp(cast_to_largest_integral_type(a), cast_to_largest_integral_type(b), 1, __FILE__, __LINE__)
#define assert_int_not_equal(a, b) \
    _cm_int_cmp(cast_to_largest_integral_type(a), cast_to_largest_integral_type(b), 0, __FILE__, __LINE__)
#define assert_in_range(v, lo, hi)                                                            \
    _cm_range(cast_to_largest_integral_type(v), cast_to_largest_integral_type(lo),            \
              cast_to_largest_integral_type(hi), 1, __FILE__, __LINE__)
#define assert_not_in_range(v, lo, hi)                                                        \
    _cm_range(cast_to_largest_integral_type(v), cast_to_largest_integral_type(lo),            \
              cast_to_largest_integral_type(hi), 0, __FILE__, __LINE__)
#define assert_in_set(v, values, count) \
    _cm_set(cast_to_largest_integral_type(v), values, count, 1, __FILE__, __LINE__)
#define assert_not_in_set(v, values, count) \
    _cm_set(cast_to_largest_integral_type(v), values, count, 0, __FILE__, __LINE__)
#define assert_null(p) _cm_check((p) == NULL, #p " == NULL", __FILE__, __LINE__)
#define assert_non_null(p) _cm_check((p) != NULL, #p " != NULL", __FILE__, __LINE__)
#define assert_ptr_equal(a, b) \
    _cm_int_cmp(cast_ptr_to_largest_integral_type(a), cast_ptr_to_largest_integral_type(b), 1, __FILE__, __LINE__)
#define assert_ptr_not_equal(a, b) \
    _cm_int_cmp(cast_ptr_to_largest_integral_type(a), cast_ptr_to_largest_integral_type(b), 0, __FILE__, __LINE__)
#define assert_memory_equal(a, b, size) _cm_memory(a, b, size, 1, __FILE__, __LINE__)
#define assert_memory_not_equal(a, b, size) _cm_memory(a, b, size, 0, __FILE__, __LINE__)
#define assert_string_equal(a, b) _cm_string(a, b, 1, __FILE__, __LINE__)
#define assert_string_not_equal(a, b) _cm_string(a, b, 0, __FILE__, __LINE__)
#define assert_return_code(rc, error) _cm_return_code((intmax_t)(rc), (intmax_t)(error), #rc, __FILE__, __LINE__)
#define assert_float_equal(a, b, eps) _cm_float((double)(a), (double)(b), (double)(eps), 1, __FILE__, __LINE__)
#define assert_float_not_equal(a, b, eps) _cm_float((double)(a), (double)(b), (double)(eps), 0, __FILE__, __LINE__)
#define assert_double_equal(a, b, eps) assert_float_equal(a, b, eps)
#define assert_double_not_equal(a, b, eps) assert_float_not_equal(a, b, eps)

#define fail() _cm_fail(__FILE__, __LINE__)
#define fail_msg(...) (print_error("ERROR: " __VA_ARGS__), print_error("\n"), _cm_fail(__FILE__, __LINE__))
#define skip() _cm_skip(__FILE__, __LINE__)

#define test_malloc(size) malloc(size)
#define test_calloc(n, size) calloc(n, size)
#define test_realloc(p, size) realloc(p, size)
#define test_free(p) free(p)

int _cmocka_run_group_tests(const char *group_name, const struct CMUnitTest *const tests, size_t num_tests,
                            CMFixtureFunction group_setup, CMFixtureFunction group_teardown);

void print_message(const char *format, ...) __attribute__((format(printf, 1, 2)));
void print_error(const char *format, ...) __attribute__((format(printf, 1, 2)));

void _cm_check(int ok, const char *expr, const char *file, int line);
void _cm_int_cmp(LargestIntegralType a, LargestIntegralType b, int want_equal, const char *file, int line);
void _cm_range(LargestIntegralType v, LargestIntegralType lo, LargestIntegralType hi, int want_in,
               const char *file, int line);
void _cm_set(LargestIntegralType v, const LargestIntegralType values[], size_t count, int want_in,
             const char *file, int line);
void _cm_memory(const void *a, const void *b, size_t size, int want_equal, const char *file, int line);
void _cm_string(const char *a, const char *b, int want_equal, const char *file, int line);
void _cm_return_code(intmax_t rc, intmax_t error, const char *expr, const char *file, int line);
void _cm_float(double a, double b, double eps, int want_equal, const char *file, int line);
void _cm_fail(const char *file, int line) __attribute__((noreturn));
void _cm_skip(const char *file, int line) __attribute__((noreturn));

#endif /* PS_TARGET_CMOCKA_H */
