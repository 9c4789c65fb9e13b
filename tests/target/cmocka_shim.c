/* Runner and checks behind tests/target/cmocka.h: setjmp per test, cmocka-style report. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "cmocka.h"

enum outcome { OUTCOME_PASS = 0, OUTCOME_FAIL = 1, OUTCOME_SKIP = 2 };

/* newlib on Debian is built without C99 printf formats (%zu, %jd print literally): the
 * shim prints sizes as unsigned long and integers as long long. */

/* Where a failing check returns to; NULL outside a test, fixture or group fixture. */
static jmp_buf *active_jmp;

void print_message(const char *format, ...)
{
    va_list ap;
    va_start(ap, format);
    vprintf(format, ap);
    va_end(ap);
}

void print_error(const char *format, ...)
{
    va_list ap;
    va_start(ap, format);
    vprintf(format, ap);  /* one stream: stdout and stderr share the UART, keep the order */
    va_end(ap);
}

static void leave(enum outcome why, const char *file, int line) __attribute__((noreturn));
static void leave(enum outcome why, const char *file, int line)
{
    if (why == OUTCOME_FAIL) {
        print_error("%s:%d: error: Failure!\n", file, line);
    }
    if (active_jmp == NULL) {
        print_error("check outside a running test\n");
        fflush(stdout);
        exit(1);
    }
    longjmp(*active_jmp, (int)why);
}

void _cm_fail(const char *file, int line)
{
    leave(OUTCOME_FAIL, file, line);
}

void _cm_skip(const char *file, int line)
{
    leave(OUTCOME_SKIP, file, line);
}

void _cm_check(int ok, const char *expr, const char *file, int line)
{
    if (!ok) {
        print_error("%s\n", expr);
        leave(OUTCOME_FAIL, file, line);
    }
}

void _cm_int_cmp(LargestIntegralType a, LargestIntegralType b, int want_equal, const char *file, int line)
{
    if ((a == b) != (want_equal != 0)) {
        print_error("%lld (%#llx) %s %lld (%#llx)\n", (long long)a, (unsigned long long)a,
                    want_equal ? "!=" : "==", (long long)b, (unsigned long long)b);
        leave(OUTCOME_FAIL, file, line);
    }
}

void _cm_range(LargestIntegralType v, LargestIntegralType lo, LargestIntegralType hi, int want_in,
               const char *file, int line)
{
    int in = v >= lo && v <= hi;
    if (in != (want_in != 0)) {
        print_error("%llu is %sin range [%llu, %llu] (unsigned, as cmocka)\n", (unsigned long long)v,
                    in ? "" : "not ", (unsigned long long)lo, (unsigned long long)hi);
        leave(OUTCOME_FAIL, file, line);
    }
}

void _cm_set(LargestIntegralType v, const LargestIntegralType values[], size_t count, int want_in,
             const char *file, int line)
{
    int in = 0;
    for (size_t i = 0; i < count; i++) {
        in |= values[i] == v;
    }
    if (in != (want_in != 0)) {
        print_error("%llu is %sin the set\n", (unsigned long long)v, in ? "" : "not ");
        leave(OUTCOME_FAIL, file, line);
    }
}

void _cm_memory(const void *a, const void *b, size_t size, int want_equal, const char *file, int line)
{
    const uint8_t *pa = a;
    const uint8_t *pb = b;
    size_t first = size;
    for (size_t i = 0; i < size; i++) {
        if (pa[i] != pb[i]) {
            first = i;
            break;
        }
    }
    int equal = first == size;
    if (equal != (want_equal != 0)) {
        if (equal) {
            print_error("%lu bytes of %p and %p are the same\n", (unsigned long)size, a, b);
        } else {
            print_error("difference at offset %lu: 0x%02x != 0x%02x (%lu bytes compared)\n", (unsigned long)first,
                        pa[first], pb[first], (unsigned long)size);
        }
        leave(OUTCOME_FAIL, file, line);
    }
}

void _cm_string(const char *a, const char *b, int want_equal, const char *file, int line)
{
    int equal = a != NULL && b != NULL && strcmp(a, b) == 0;
    if (equal != (want_equal != 0)) {
        print_error("\"%s\" %s \"%s\"\n", a ? a : "(null)", want_equal ? "!=" : "==", b ? b : "(null)");
        leave(OUTCOME_FAIL, file, line);
    }
}

void _cm_return_code(intmax_t rc, intmax_t error, const char *expr, const char *file, int line)
{
    if (rc < 0) {
        print_error("%s < 0, errno(%lld)\n", expr, (long long)error);
        leave(OUTCOME_FAIL, file, line);
    }
}

void _cm_float(double a, double b, double eps, int want_equal, const char *file, int line)
{
    int equal = a == b || fabs(a - b) <= eps;
    if (equal != (want_equal != 0)) {
        print_error("%.9g %s %.9g (epsilon %.3g)\n", a, want_equal ? "!=" : "==", b, eps);
        leave(OUTCOME_FAIL, file, line);
    }
}

/* Run fn(state) with checks armed; returns the outcome. fixture: fn returns non-zero on failure. */
static enum outcome run_guarded(CMUnitTestFunction test, CMFixtureFunction fixture, void **state)
{
    jmp_buf here;
    jmp_buf *outer = active_jmp;
    volatile enum outcome result = OUTCOME_PASS;
    int why = setjmp(here);
    if (why == 0) {
        active_jmp = &here;
        if (test != NULL) {
            test(state);
        } else if (fixture(state) != 0) {
            result = OUTCOME_FAIL;
        }
    } else {
        result = (enum outcome)why;
    }
    active_jmp = outer;
    return result;
}

int _cmocka_run_group_tests(const char *group_name, const struct CMUnitTest *const tests, size_t num_tests,
                            CMFixtureFunction group_setup, CMFixtureFunction group_teardown)
{
    void *group_state = NULL;
    size_t passed = 0, failed = 0, skipped = 0, listed = 0;

    print_message("[==========] %s: Running %lu test(s).\n", group_name, (unsigned long)num_tests);
    if (group_setup != NULL && run_guarded(NULL, group_setup, &group_state) != OUTCOME_PASS) {
        print_error("[  ERROR   ] %s: group setup failed\n", group_name);
        fflush(stdout);
        return (int)num_tests;
    }

    /* Names of failed tests, listed again at the end as cmocka does; bounded, no heap. */
    enum { FAILED_LISTED_MAX = 64 };
    const char *failed_names[FAILED_LISTED_MAX];

    for (size_t i = 0; i < num_tests; i++) {
        const struct CMUnitTest *t = &tests[i];
        void *state = t->initial_state != NULL ? t->initial_state : group_state;
        enum outcome result = OUTCOME_PASS;

        print_message("[ RUN      ] %s\n", t->name);
        if (t->setup_func != NULL) {
            result = run_guarded(NULL, t->setup_func, &state);
        }
        if (result == OUTCOME_PASS) {
            result = run_guarded(t->test_func, NULL, &state);
            if (t->teardown_func != NULL) {
                enum outcome td = run_guarded(NULL, t->teardown_func, &state);
                if (td == OUTCOME_FAIL) {
                    result = OUTCOME_FAIL;
                }
            }
        }
        switch (result) {
        case OUTCOME_PASS:
            passed++;
            print_message("[       OK ] %s\n", t->name);
            break;
        case OUTCOME_SKIP:
            skipped++;
            print_message("[  SKIPPED ] %s\n", t->name);
            break;
        default:
            if (listed < FAILED_LISTED_MAX) {
                failed_names[listed++] = t->name;
            }
            failed++;
            print_error("[  FAILED  ] %s\n", t->name);
            break;
        }
    }

    if (group_teardown != NULL && run_guarded(NULL, group_teardown, &group_state) != OUTCOME_PASS) {
        print_error("[  ERROR   ] %s: group teardown failed\n", group_name);
        failed++;
    }

    print_message("[==========] %s: %lu test(s) run.\n", group_name, (unsigned long)num_tests);
    print_message("[  PASSED  ] %lu test(s).\n", (unsigned long)passed);
    if (skipped > 0) {
        print_message("[  SKIPPED ] %lu test(s).\n", (unsigned long)skipped);
    }
    if (failed > 0) {
        print_error("[  FAILED  ] %s: %lu test(s), listed below:\n", group_name, (unsigned long)failed);
        for (size_t i = 0; i < listed; i++) {
            print_error("[  FAILED  ] %s\n", failed_names[i]);
        }
    }
    fflush(stdout);
    return (int)failed;
}
