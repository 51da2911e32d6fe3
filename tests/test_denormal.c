/*
 * test_denormal.c - voices never compute with subnormal numbers: after an
 * impulse (or their .ic strike), every example voice rings down through a
 * minute of silence, in double and in float, and no output sample may be
 * subnormal.  States are flushed below 1e-30 at block ends, far above the
 * subnormal range of either precision.  A string damped hard
 * (tests/nets/damped_string.wdn, 1200 dB a second) would reach the
 * subnormals within the minute if its loop did not flush the waves it
 * carries: its output is exactly 0 from two seconds on.
 */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "testlib.h"

#define FS 48000.0
#define SECONDS 60
#define BLOCK 64

static long subnormals(const wdv_class *cls, long *first, long *last) {
    void *st = tl_state_new(cls, FS);
    double in[8][BLOCK] = {{0}}, out[16][BLOCK];
    const double *ip[8];
    double *op[16];
    for (int k = 0; k < 8; k++)
        ip[k] = in[k];
    for (int k = 0; k < 16; k++)
        op[k] = out[k];
    for (int k = 0; k < cls->n_inputs && k < 8; k++)
        in[k][0] = 1;
    long count = 0;
    *first = -1, *last = -1;
    for (long b = 0; b < (long)(SECONDS * FS) / BLOCK; b++) {
        cls->process(st, ip, op, BLOCK);
        for (int k = 0; k < cls->n_inputs && k < 8; k++)
            in[k][0] = 0;
        for (int k = 0; k < cls->n_outputs && k < 16; k++)
            for (int n = 0; n < BLOCK; n++)
                if (fpclassify(out[k][n]) == FP_SUBNORMAL || (cls->precision == 32 && out[k][n] != 0 &&
                                                              fabs(out[k][n]) < 1.17549435e-38)) {
                    if (*first < 0)
                        *first = b * BLOCK + n;
                    count++;
                }
        for (int k = 0; k < cls->n_outputs && k < 16; k++)
            for (int n = 0; n < BLOCK; n++)
                if (out[k][n] != 0)
                    *last = b * BLOCK + n;
    }
    tl_state_free(st);
    return count;
}

static void test_netlist(void **state) {
    const char *path = *state;
    for (int single = 0; single < 2; single++) {
        tl_voice v;
        if (tl_voice_build(path, single, &v) != 0)
            fail_msg("%s: the voice could not be built", path);
        long first, last, n = subnormals(v.cls, &first, &last);
        tl_voice_free(&v);
        if (n)
            fail_msg("%s (%s): %ld subnormal output samples, the first at n=%ld", path, single ? "float" : "double",
                     n, first);
    }
}

static void test_damped_string(void **state) {
    (void)state;
    for (int single = 0; single < 2; single++) {
        tl_voice v;
        if (tl_voice_build("tests/nets/damped_string.wdn", single, &v) != 0)
            fail_msg("damped_string: the voice could not be built");
        long first, last, n = subnormals(v.cls, &first, &last);
        tl_voice_free(&v);
        printf("damped_string (%s): %ld subnormal output samples, the last non-zero at %.3f s\n",
               single ? "float" : "double", n, (double)last / FS);
        assert_int_equal(n, 0);
        assert_true(last >= 0 && last < 2 * FS);
    }
}

int main(void) {
    int n = 0;
    char **paths = tl_netlists(&n);
    struct CMUnitTest *tests = calloc((size_t)n + 1, sizeof *tests);
    for (int k = 0; k < n; k++) {
        tests[k].name = paths[k];
        tests[k].test_func = test_netlist;
        tests[k].initial_state = paths[k];
    }
    int rc = _cmocka_run_group_tests("denormal", tests, (size_t)n, NULL, NULL);
    const struct CMUnitTest fixed[] = {cmocka_unit_test(test_damped_string)};
    rc |= cmocka_run_group_tests_name("denormal (fixed)", fixed, NULL, NULL);
    free(tests);
    tl_netlists_free(paths, n);
    return rc;
}
