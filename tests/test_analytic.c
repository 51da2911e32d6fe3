/*
 * test_analytic.c - linear voices against their closed-form responses.
 *
 * (a) netlists/rc_lowpass.wdn, driven by a 1 V step.  The continuous
 *     response is 1 - exp(-t/RC).  The bilinear (trapezoidal) rule with
 *     a = T/(2RC) turns the network into
 *         y[n] = p y[n-1] + (a/(1+a)) (x[n] + x[n-1]),  p = (1-a)/(1+a),
 *     whose step response (x[-1] = 0, y[-1] = 0) is y[n] = 1 - p^n/(1+a).
 *     The voice must match that closed form within 1e-12, and its error
 *     against the continuous response may not exceed the closed form's
 *     (+1e-12).
 *
 * (b) netlists/rlc_series.wdn: v(out), the voltage across R2, for an
 *     input v(in) through a source resistance Rs, has
 *         H(s) = R2 / (Rs + R2 + sL + 1/(sC)).
 *     The DTFT of the voice's impulse response at w must equal H(s) at
 *     s = j (2/T) tan(w/2) within 1e-9 at 50 frequencies, and the peak of
 *     |H_d| must sit at the warped resonance (fs/pi) atan(pi f0/fs),
 *     f0 = 1/(2 pi sqrt(LC)), within the step of the frequency grid
 *     searched, while the unwarped f0 lies outside it.
 *
 * Element values are read from the netlists themselves (wdc_load and
 * elem_value at the params' defaults), so the test follows any edit of
 * the netlists.  Run from the repository root: build/tests/test_analytic.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include <complex.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testlib.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

#define RC_NETLIST "netlists/rc_lowpass.wdn"
#define RLC_NETLIST "netlists/rlc_series.wdn"
#define DEFAULT_FS 48000.0
#define DECAY_FLOOR 1e-15
#define MAX_SECONDS 60

/* ---- helpers ---- */

static const Elem *find_elem(const Circuit *c, const char *name)
{
    for (int k = 0; k < c->nelems; k++)
        if (strcmp(c->elems[k].name, name) == 0)
            return &c->elems[k];
    fail_msg("%s: no element %s", c->path, name);
    return NULL;
}

static int output_id(const wdv_class *cls, const char *name)
{
    int k = tl_output_id(cls, name);
    if (k < 0)
        fail_msg("voice %s has no output %s", cls->name, name);
    return k;
}

/* Renders nframes of output `oid` for input `x` (the voice's only input;
 * NULL: silence) into y. */
static int render_one(const wdv_class *cls, void *state, const double *x,
                      int oid, double *y, long nframes)
{
    int nout = cls->n_outputs;
    double **out = malloc((size_t)nout * sizeof *out);
    double *scratch = malloc((size_t)nframes * (size_t)nout * sizeof *scratch);
    if (!out || !scratch) {
        free(out);
        free(scratch);
        return -1;
    }
    for (int k = 0; k < nout; k++)
        out[k] = (k == oid) ? y : scratch + (size_t)k * (size_t)nframes;
    const double *in[1] = {x};
    wdrt_render(cls, state, in, out, nframes, 64);
    free(out);
    free(scratch);
    return 0;
}

static double rate_of(const Circuit *c)
{
    return c->rate > 0 ? c->rate : DEFAULT_FS;
}

/* ---- (a) RC step response ---- */

static void test_rc_step(void **st)
{
    (void)st;
    Circuit *c = wdc_load(RC_NETLIST);
    assert_non_null(c);
    double *pv = circuit_defaults(c);
    const Elem *r1 = find_elem(c, "R1");
    const Elem *c1 = find_elem(c, "C1");
    const Elem *v1 = find_elem(c, "V1");
    assert_int_equal(r1->kind, E_R);
    assert_int_equal(c1->kind, E_C);
    /* The closed form assumes an ideal source straight across R1-C1. */
    assert_int_equal(v1->kind, E_V);
    assert_null(v1->val);
    double R = elem_value(c, r1, pv);
    double C = elem_value(c, c1, pv);
    double fs = rate_of(c);
    double T = 1.0 / fs;
    double RC = R * C;
    double a = T / (2.0 * RC);
    double p = (1.0 - a) / (1.0 + a);

    tl_voice v;
    if (tl_voice_build(RC_NETLIST, 0, &v) != 0) {
        tl_voice_free(&v);
        fail_msg("could not build the voice of %s", RC_NETLIST);
    }
    assert_int_equal(v.cls->n_inputs, 1);
    int oid = output_id(v.cls, "out");
    void *state = tl_state_new(v.cls, fs);
    assert_non_null(state);

    /* 40 time constants: the response has settled to 1 within rounding. */
    long n = (long)ceil(40.0 * RC * fs) + 1;
    double *x = malloc((size_t)n * sizeof *x);
    double *y = malloc((size_t)n * sizeof *y);
    assert_non_null(x);
    assert_non_null(y);
    for (long i = 0; i < n; i++)
        x[i] = 1.0;
    assert_int_equal(render_one(v.cls, state, x, oid, y, n), 0);

    double max_disc = 0;   /* |voice - closed form| */
    double max_cont = 0;   /* |voice - continuous| */
    double max_bound = 0;  /* |closed form - continuous| */
    long at_cont = 0;
    for (long i = 0; i < n; i++) {
        double closed = 1.0 - pow(p, (double)i) / (1.0 + a);
        double cont = 1.0 - exp(-(double)i * T / RC);
        double e_disc = fabs(y[i] - closed);
        double e_cont = fabs(y[i] - cont);
        double bound = fabs(closed - cont);
        if (!(e_disc <= 1e-12))
            fail_msg("RC step, sample %ld: voice %.17g, bilinear closed form "
                     "%.17g (difference %.3g > 1e-12)",
                     i, y[i], closed, e_disc);
        if (!(e_cont <= bound + 1e-12))
            fail_msg("RC step, sample %ld: voice %.17g is %.3g from the "
                     "continuous response %.17g, beyond the closed form's "
                     "%.3g",
                     i, y[i], e_cont, cont, bound);
        if (e_disc > max_disc)
            max_disc = e_disc;
        if (e_cont > max_cont) {
            max_cont = e_cont;
            at_cont = i;
        }
        if (bound > max_bound)
            max_bound = bound;
    }
    print_message("RC step (R=%g ohm, C=%g F, RC=%g s, fs=%g Hz, %ld "
                  "samples):\n",
                  R, C, RC, fs, n);
    print_message("  max |voice - bilinear closed form| = %.3g (%.1f dB)\n",
                  max_disc, tl_db(max_disc));
    print_message("  max |voice - (1 - exp(-t/RC))|     = %.3g (%.1f dB) at "
                  "sample %ld\n",
                  max_cont, tl_db(max_cont), at_cont);
    print_message("  max |closed form - continuous|     = %.3g (%.1f dB)\n",
                  max_bound, tl_db(max_bound));

    free(x);
    free(y);
    tl_state_free(state);
    tl_voice_free(&v);
}

/* ---- (b) RLC frequency response and resonance ---- */

typedef struct rlc {
    double Rs, R2, L, C;
} rlc;

static double complex rlc_h(const rlc *k, double complex s)
{
    return k->R2 / (k->Rs + k->R2 + s * k->L + 1.0 / (s * k->C));
}

static void test_rlc_response(void **st)
{
    (void)st;
    Circuit *c = wdc_load(RLC_NETLIST);
    assert_non_null(c);
    double *pv = circuit_defaults(c);
    const Elem *v1 = find_elem(c, "V1");
    const Elem *l1 = find_elem(c, "L1");
    const Elem *c1 = find_elem(c, "C1");
    const Elem *r2 = find_elem(c, "R2");
    assert_int_equal(v1->kind, E_V);
    assert_non_null(v1->val); /* a resistive source: Rs */
    assert_int_equal(l1->kind, E_L);
    assert_int_equal(c1->kind, E_C);
    assert_int_equal(r2->kind, E_R);
    rlc k = {elem_value(c, v1, pv), elem_value(c, r2, pv),
             elem_value(c, l1, pv), elem_value(c, c1, pv)};
    double fs = rate_of(c);
    double T = 1.0 / fs;

    tl_voice v;
    if (tl_voice_build(RLC_NETLIST, 0, &v) != 0) {
        tl_voice_free(&v);
        fail_msg("could not build the voice of %s", RLC_NETLIST);
    }
    assert_int_equal(v.cls->n_inputs, 1);
    int oid = output_id(v.cls, "vr");
    void *state = tl_state_new(v.cls, fs);
    assert_non_null(state);
    long n = 0;
    double *h = tl_impulse_response(v.cls, state, oid, 64, DECAY_FLOOR,
                                    (long)(MAX_SECONDS * fs), &n);
    tl_state_free(state);
    if (!h)
        fail_msg("RLC: the impulse response is not finite or does not "
                 "decay below %g within %d s", DECAY_FLOOR, MAX_SECONDS);

    /* 50 frequencies, log-spaced from 20 Hz to 20 kHz. */
    double worst = 0, worst_rel = 0, worst_f = 0;
    for (int i = 0; i < 50; i++) {
        double f = 20.0 * pow(1000.0, i / 49.0);
        double w = 2.0 * M_PI * f / fs;
        double complex hd = tl_dtft(h, n, w);
        double complex ha = rlc_h(&k, I * (2.0 / T) * tan(w / 2.0));
        double err = cabs(hd - ha);
        if (!(err <= 1e-9)) {
            free(h);
            fail_msg("RLC at %.6g Hz: voice %.15g%+.15gj, H(j(2/T)tan(w/2)) "
                     "%.15g%+.15gj, |difference| %.3g > 1e-9",
                     f, creal(hd), cimag(hd), creal(ha), cimag(ha), err);
        }
        if (err > worst) {
            worst = err;
            worst_f = f;
        }
        if (err / cabs(ha) > worst_rel)
            worst_rel = err / cabs(ha);
    }
    print_message("RLC (Rs=%g, R2=%g ohm, L=%g H, C=%g F, fs=%g Hz, %ld-sample "
                  "impulse response): 50 frequencies, max |H_d - H| = %.3g "
                  "(%.1f dB) at %.6g Hz, max relative %.3g\n",
                  k.Rs, k.R2, k.L, k.C, fs, n, worst, tl_db(worst), worst_f,
                  worst_rel);

    /* The resonance: search |H_d| on a grid of step df spanning f0 +-10%,
     * anchored at a whole multiple of df (not at the expected answer).
     * For a peak with one maximum the true peak is within df of the
     * grid's best point. */
    double f0 = 1.0 / (2.0 * M_PI * sqrt(k.L * k.C));
    double fd0 = fs / M_PI * atan(M_PI * f0 / fs);
    const double df = 0.01;
    double lo = floor(0.9 * f0 / df) * df, hi = 1.1 * f0;
    double best = -1, fbest = 0;
    for (long j = 0;; j++) {
        double f = lo + (double)j * df;
        if (f > hi)
            break;
        double m = cabs(tl_dtft(h, n, 2.0 * M_PI * f / fs));
        if (m > best) {
            best = m;
            fbest = f;
        }
    }
    /* Golden-section refinement of the peak, for the report. */
    double ga = fbest - df, gb = fbest + df;
    const double gr = (sqrt(5.0) - 1.0) / 2.0;
    for (int it = 0; it < 60; it++) {
        double x1 = gb - gr * (gb - ga), x2 = ga + gr * (gb - ga);
        double m1 = cabs(tl_dtft(h, n, 2.0 * M_PI * x1 / fs));
        double m2 = cabs(tl_dtft(h, n, 2.0 * M_PI * x2 / fs));
        if (m1 > m2)
            gb = x2;
        else
            ga = x1;
    }
    double fref = 0.5 * (ga + gb);
    print_message("RLC resonance: analog f0 = %.6f Hz, warped "
                  "(fs/pi)atan(pi f0/fs) = %.6f Hz; measured peak of |H_d| "
                  "%.2f Hz on a %.2f Hz grid, %.6f Hz refined (|H_d| = %.9f, "
                  "R2/(Rs+R2) = %.9f)\n",
                  f0, fd0, fbest, df, fref, best, k.R2 / (k.Rs + k.R2));
    free(h);
    if (!(fabs(fbest - fd0) <= df))
        fail_msg("RLC: peak of |H_d| at %.4f Hz, expected the warped "
                 "resonance %.4f Hz within %.2f Hz",
                 fbest, fd0, df);
    /* The grid resolves the warping: the unwarped f0 is excluded. */
    if (fabs(f0 - fd0) > 2 * df)
        assert_true(fabs(fbest - f0) > df);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_rc_step),
        cmocka_unit_test(test_rlc_response),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
