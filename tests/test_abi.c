/*
 * test_abi.c - the voice ABI as a host sees it: descriptors and units,
 * param clamping and refusal, reset re-applying .ic, set_ic as a strike on
 * a running voice (one mass, and two on one node), energy of a thrown mass, work counted only in a voice
 * built with --energy (NaN without), and the float build.
 */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <string.h>

#include "testlib.h"

static int find_ic(const wdv_class *c, const char *name) {
    for (int i = 0; i < c->n_ic_targets; i++)
        if (!strcmp(c->ic_targets[i].name, name))
            return i;
    return -1;
}

static void test_descriptors(void **s) {
    (void)s;
    tl_voice v;
    assert_int_equal(tl_voice_build("netlists/msd.wdn", 0, &v), 0);
    const wdv_class *c = v.cls;
    assert_string_equal(c->name, "msd");
    assert_int_equal(c->abi_version, WDV_ABI_VERSION);
    assert_int_equal(c->precision, 64);
    assert_int_equal(c->n_inputs, 1);
    assert_string_equal(c->inputs[0].name, "f");
    assert_string_equal(c->inputs[0].unit, "N");
    assert_int_equal(c->n_outputs, 3);
    assert_string_equal(c->outputs[0].unit, "m/s");
    assert_string_equal(c->outputs[1].unit, "m");
    assert_string_equal(c->outputs[2].unit, "N");
    assert_int_equal(c->n_params, 2);
    assert_string_equal(c->params[0].name, "k");
    assert_string_equal(c->params[0].unit, "N/m");
    assert_true(c->params[0].def == 20e3 && c->params[0].min == 1e3 && c->params[0].max == 1e6);
    assert_true(find_ic(c, "v(x)") >= 0 && find_ic(c, "x(x)") >= 0);
    tl_voice_free(&v);
    assert_int_equal(tl_voice_build("netlists/msd.wdn", 1, &v), 0);
    assert_int_equal(v.cls->precision, 32);
    tl_voice_free(&v);
}

static void test_params(void **s) {
    (void)s;
    tl_voice v;
    assert_int_equal(tl_voice_build("netlists/msd.wdn", 0, &v), 0);
    const wdv_class *c = v.cls;
    void *st = tl_state_new(c, 48000);
    assert_true(c->get_param(st, 0) == 20e3);
    assert_int_equal(c->set_param(st, 0, 5e6), 0); /* clamped to max */
    assert_true(c->get_param(st, 0) == 1e6);
    assert_int_equal(c->set_param(st, 0, -3), 0); /* clamped to min */
    assert_true(c->get_param(st, 0) == 1e3);
    assert_int_equal(c->set_param(st, 2, 1), -1);
    assert_int_equal(c->set_param(st, -1, 1), -1);
    assert_int_equal(c->set_param(st, 1, NAN), -1);
    assert_true(c->get_param(st, 1) == 0.1);
    tl_state_free(st);
    tl_voice_free(&v);
}

/* A strike sets a mass's velocity on a running voice: the stored energy
 * becomes 1/2 m v^2 plus what the spring holds, and reset brings back the
 * netlist's own initial conditions. */
static void test_strike_and_reset(void **s) {
    (void)s;
    tl_voice v;
    assert_int_equal(tl_voice_build_args("netlists/triangle.wdn", 0, tl_energy, NULL, &v), 0);
    const wdv_class *c = v.cls;
    void *st = tl_state_new(c, 48000);
    assert_true(fabs(c->energy(st) - 0.5 * 25e-3 * 0.2 * 0.2) < 1e-15); /* .ic v(m3)=0.2 */
    double zero[64] = {0}, o[3][64];
    const double *in[1] = {zero};
    double *out[3] = {o[0], o[1], o[2]};
    for (int b = 0; b < 100; b++)
        c->process(st, in, out, 64);
    double before = c->energy(st);
    assert_true(before < 0.5 * 25e-3 * 0.04);
    int id = find_ic(c, "v(m1)");
    assert_true(id >= 0);
    double val = 1.5;
    assert_int_equal(c->set_ic(st, 1, &id, &val), 0);
    /* m1 (30 g) now moves at 1.5 m/s; the others keep their state */
    assert_true(c->energy(st) > 0.5 * 30e-3 * 1.5 * 1.5);
    c->process(st, in, out, 1);
    assert_true(fabs(o[0][0] - 1.5) < 0.05); /* v1 one sample after the strike */
    int bad = 99;
    assert_int_equal(c->set_ic(st, 1, &bad, &val), -1);
    c->reset(st);
    assert_true(fabs(c->energy(st) - 0.5 * 25e-3 * 0.2 * 0.2) < 1e-15);
    assert_true(c->work(st) == 0);
    tl_state_free(st);
    tl_voice_free(&v);
}

/* Two masses on one node (chain3's S3.M and Mextra) move together: a
 * strike of the node sets both, its current parts as their masses, and
 * the kinetic energy is that of the pair; its first sample carries on
 * from there. */
static void test_strike_parallel_masses(void **s) {
    (void)s;
    for (int single = 0; single < 2; single++) {
        tl_voice v;
        assert_int_equal(tl_voice_build("netlists/chain3.wdn", single, &v), 0);
        const wdv_class *c = v.cls;
        void *st = tl_state_new(c, 48000);
        int id = find_ic(c, "v(c)");
        assert_true(id >= 0);
        double val = 0.8;
        assert_int_equal(c->set_ic(st, 1, &id, &val), 0);
        double want = 0.5 * (15e-3 + 40e-3) * val * val, got = c->energy(st);
        printf("%s: v(c) = 0.8 m/s on 15 g + 40 g: energy %.17g J, %.3g off\n", single ? "float" : "double", got,
               fabs(got - want) / want);
        assert_true(fabs(got - want) <= (single ? 1e-6 : 1e-14) * want);
        double zero[1] = {0}, o[3][1];
        const double *in[1] = {zero};
        double *out[3] = {o[0], o[1], o[2]};
        c->process(st, in, out, 1);
        /* after one sample of 1/48000 s, x(c) has moved by about v T */
        assert_true(fabs(o[1][0] - val / 48000) < 0.01 * val / 48000);
        tl_state_free(st);
        tl_voice_free(&v);
    }
}

/* Without --energy a voice counts no work: its class has no work (NULL),
 * and what it renders is the same to the bit. */
static void test_work_only_with_energy(void **s) {
    (void)s;
    tl_voice v[2];
    assert_int_equal(tl_voice_build("netlists/msd.wdn", 0, &v[0]), 0);
    assert_int_equal(tl_voice_build_args("netlists/msd.wdn", 0, tl_energy, NULL, &v[1]), 0);
    assert_true(v[0].cls->state_size < v[1].cls->state_size);
    void *st[2];
    double o[2][3][64];
    for (int k = 0; k < 2; k++) {
        const wdv_class *c = v[k].cls;
        st[k] = tl_state_new(c, 48000);
        double f[64];
        for (int n = 0; n < 64; n++)
            f[n] = n < 8 ? 1.0 : 0.0;
        const double *in[1] = {f};
        double *out[3] = {o[k][0], o[k][1], o[k][2]};
        c->process(st[k], in, out, 64);
    }
    assert_null(v[0].cls->work);
    assert_true(v[1].cls->work(st[1]) > 0);
    assert_memory_equal(o[0], o[1], sizeof o[0]);
    assert_true(v[0].cls->energy(st[0]) == v[1].cls->energy(st[1]));
    for (int k = 0; k < 2; k++) {
        tl_state_free(st[k]);
        tl_voice_free(&v[k]);
    }
}

/* A param set before reset acts as in a fresh voice that was given it,
 * with or without a strike after the reset, to the bit: reset may leave
 * the coefficients to process when the cleared state reads none. */
static void test_param_then_reset(void **s) {
    (void)s;
    static const char *const nets[] = {"netlists/rc_lowpass.wdn", "netlists/msd.wdn", "netlists/tonestack.wdn",
                                          "netlists/triangle.wdn"};
    for (size_t k = 0; k < sizeof nets / sizeof nets[0]; k++)
        for (int strike = 0; strike < 2; strike++) {
            tl_voice v;
            assert_int_equal(tl_voice_build(nets[k], 0, &v), 0);
            const wdv_class *c = v.cls;
            void *a = tl_state_new(c, 48000), *b = tl_state_new(c, 48000);
            double x[128], o[2][8][128];
            for (int n = 0; n < 128; n++)
                x[n] = sin(0.05 * n) + (n % 7 == 0);
            const double *in[8];
            double *out[2][8];
            for (int j = 0; j < 8; j++)
                in[j] = x, out[0][j] = o[0][j], out[1][j] = o[1][j];
            assert_true(c->n_inputs <= 8 && c->n_outputs <= 8 && c->n_params > 0);
            c->process(a, in, out[0], 128);
            const double val = 0.5 * (c->params[0].min + c->params[0].max);
            assert_int_equal(c->set_param(a, 0, val), 0);
            c->reset(a);
            assert_int_equal(c->set_param(b, 0, val), 0);
            int id = 0;
            double w = 0.25;
            if (strike && c->n_ic_targets > 0) {
                assert_int_equal(c->set_ic(a, 1, &id, &w), 0);
                assert_int_equal(c->set_ic(b, 1, &id, &w), 0);
            }
            c->process(a, in, out[0], 128);
            c->process(b, in, out[1], 128);
            for (int j = 0; j < c->n_outputs; j++)
                assert_memory_equal(o[0][j], o[1][j], sizeof o[0][j]);
            assert_true(c->energy(a) == c->energy(b));
            tl_state_free(a);
            tl_state_free(b);
            tl_voice_free(&v);
        }
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_descriptors),
        cmocka_unit_test(test_params),
        cmocka_unit_test(test_strike_and_reset),
        cmocka_unit_test(test_strike_parallel_masses),
        cmocka_unit_test(test_work_only_with_energy),
        cmocka_unit_test(test_param_then_reset),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
