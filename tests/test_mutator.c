/*
 * test_mutator.c - nonlinear springs and capacitors written with a curve
 * (spring K x y curve=..., C NAME a b curve=...) reach their root through
 * a mutator the compiler puts in: each renders, sample for sample and bit
 * for bit, what the same network with an explicit mutator and nonlinear
 * resistor renders, and stores the same energy.
 */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testlib.h"

static void compare(const char *explicit_net, const char *inserted_net, double amp) {
    const long n = 48000;
    double *y[2], E[2];
    for (int k = 0; k < 2; k++) {
        tl_voice v;
        assert_int_equal(tl_voice_build(k ? inserted_net : explicit_net, 0, &v), 0);
        void *st = tl_state_new(v.cls, 48000);
        tl_signal sig;
        tl_signal_init(&sig, TL_NOISE, amp, 0, 99);
        double **in = tl_bufs_new(1, 64), **out = tl_bufs_new(v.cls->n_outputs, 64);
        y[k] = malloc(sizeof(double) * (size_t)n * 2);
        for (long i = 0; i < n; i += 64) {
            for (int j = 0; j < 64; j++)
                in[0][j] = tl_signal_next(&sig, 0, i + j);
            v.cls->process(st, (const double *const *)in, out, 64);
            memcpy(y[k] + 2 * i, out[0], sizeof(double) * 64);
            memcpy(y[k] + 2 * i + 64, out[1], sizeof(double) * 64);
        }
        E[k] = v.cls->energy(st);
        tl_bufs_free(in, 1);
        tl_bufs_free(out, v.cls->n_outputs);
        tl_state_free(st);
        tl_voice_free(&v);
    }
    long diff = 0;
    for (long i = 0; i < 2 * n; i++)
        diff += memcmp(&y[0][i], &y[1][i], sizeof(double)) != 0;
    printf("%s vs %s: %ld of %ld samples differ; energy %.17g and %.17g\n", explicit_net, inserted_net, diff,
           2 * n, E[0], E[1]);
    assert_int_equal(diff, 0);
    assert_true(E[0] == E[1]);
    free(y[0]);
    free(y[1]);
}

static void test_spring_curve(void **state) {
    (void)state;
    compare("netlists/stiffening_spring.wdn", "tests/nets/stiff_inserted.wdn", 2);
}

static void test_capacitor_curve(void **state) {
    (void)state;
    compare("tests/nets/nlcap.wdn", "tests/nets/nlcap_inserted.wdn", 3);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_spring_curve),
        cmocka_unit_test(test_capacitor_curve),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
