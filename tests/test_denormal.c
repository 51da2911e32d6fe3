/*
 * test_denormal.c - voices never compute with subnormal numbers: after an
 * impulse (or their .ic strike), every example voice rings down through a
 * minute of silence, in double and in float, and no output sample may be
 * subnormal.  States are flushed below 1e-30 at block ends, far above the
 * subnormal range of either precision.
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

static long subnormals(const wdv_class *cls, long *first) {
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
    *first = -1;
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
        long first, n = subnormals(v.cls, &first);
        tl_voice_free(&v);
        if (n)
            fail_msg("%s (%s): %ld subnormal output samples, the first at n=%ld", path, single ? "float" : "double",
                     n, first);
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
    free(tests);
    tl_netlists_free(paths, n);
    return rc;
}
