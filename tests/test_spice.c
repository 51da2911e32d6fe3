/*
 * test_spice.c - the tone stack voice against ngspice's AC analysis.
 *
 * tests/ref/tonestack_ac.csv holds v(out) of netlists/tonestack.wdn for an
 * ideal 1 V AC input at three pot settings, computed by ngspice
 * (tests/ref/tonestack_ngspice.sh makes it).  The voice is a bilinear
 * discretisation of the same linear network, so its frequency response at
 * the digital frequency
 *
 *     f_d = (fs/pi) * atan(pi * f / fs)
 *
 * equals the analog response at f exactly.  The test renders the voice's
 * impulse response at 48 kHz until it has decayed below 1e-15, evaluates
 * its DTFT at f_d for every row of the data and requires a relative error
 * under 1e-6 (what is left is the data's printed precision and ngspice's
 * own accuracy).  It also reports the plain, unwarped error of the voice's
 * response at f against the analog one at f, in dB, at 1, 5, 10 and
 * 15 kHz: the frequency warping of the bilinear transform.
 *
 * Run from the repository root: build/tests/test_spice (after make).
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

#define CSV_PATH "tests/ref/tonestack_ac.csv"
#define NETLIST "netlists/tonestack.wdn"
#define FS 48000.0
#define NSETTINGS 3
#define REL_TOL 1e-6
/* The impulse response counts as decayed once a whole block of it stays
 * below this (the input impulse has height 1 V). */
#define DECAY_FLOOR 1e-15
#define BLOCK 4800L
#define MAX_SECONDS 120

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

typedef struct row {
    int set;
    double treble, bass, mid;
    double f;  /* analog frequency, Hz */
    double complex h;
} row;

typedef struct fixture {
    row *rows;
    int nrows;
    tl_voice voice;
    int built;
} fixture;

static int load_csv(const char *path, row **rows_out, int *n_out)
{
    FILE *f = fopen(path, "r");
    if (!f) {
        fprintf(stderr, "test_spice: cannot open %s (run from the "
                        "repository root; regenerate with "
                        "sh tests/ref/tonestack_ngspice.sh)\n", path);
        return -1;
    }
    int cap = 1024, n = 0, lineno = 0;
    row *rows = malloc((size_t)cap * sizeof *rows);
    char line[512];
    while (rows && fgets(line, sizeof line, f)) {
        lineno++;
        if (lineno == 1 && strncmp(line, "setting_index", 13) == 0)
            continue;
        if (line[0] == '\n' || line[0] == '#')
            continue;
        row r;
        double re, im;
        if (sscanf(line, "%d,%lf,%lf,%lf,%lf,%lf,%lf", &r.set, &r.treble,
                   &r.bass, &r.mid, &r.f, &re, &im) != 7) {
            fprintf(stderr, "%s:%d: malformed row\n", path, lineno);
            free(rows);
            fclose(f);
            return -1;
        }
        r.h = re + I * im;
        if (n == cap) {
            cap *= 2;
            row *p = realloc(rows, (size_t)cap * sizeof *rows);
            if (!p) {
                free(rows);
                rows = NULL;
                break;
            }
            rows = p;
        }
        rows[n++] = r;
    }
    fclose(f);
    if (!rows)
        return -1;
    *rows_out = rows;
    *n_out = n;
    return 0;
}

static int setup(void **st)
{
    fixture *fx = calloc(1, sizeof *fx);
    if (!fx)
        return -1;
    if (load_csv(CSV_PATH, &fx->rows, &fx->nrows) != 0) {
        free(fx);
        return -1;
    }
    if (tl_voice_build(NETLIST, 0, &fx->voice) != 0) {
        tl_voice_free(&fx->voice);
        free(fx->rows);
        free(fx);
        return -1;
    }
    fx->built = 1;
    *st = fx;
    return 0;
}

static int teardown(void **st)
{
    fixture *fx = *st;
    if (fx) {
        if (fx->built)
            tl_voice_free(&fx->voice);
        free(fx->rows);
        free(fx);
    }
    return 0;
}

static int param_id(const wdv_class *cls, const char *name)
{
    for (int k = 0; k < cls->n_params; k++)
        if (strcmp(cls->params[k].name, name) == 0)
            return k;
    return -1;
}

static int output_id(const wdv_class *cls, const char *name)
{
    for (int k = 0; k < cls->n_outputs; k++)
        if (strcmp(cls->outputs[k].name, name) == 0)
            return k;
    return -1;
}

/* Renders the response of output `oid` to a unit impulse at sample 0 until
 * a whole block stays under DECAY_FLOOR; returns the malloc'ed response
 * and its length in *n, or NULL if it does not decay in MAX_SECONDS. */
static double *impulse_response(const wdv_class *cls, void *state, int oid,
                                long *n)
{
    int nout = cls->n_outputs;
    long cap = 16 * BLOCK, len = 0;
    double *h = malloc((size_t)cap * sizeof *h);
    double *scratch = malloc((size_t)BLOCK * (size_t)nout * sizeof *scratch);
    double **out = malloc((size_t)nout * sizeof *out);
    double *imp = calloc((size_t)BLOCK, sizeof *imp);
    const double **in = calloc((size_t)(cls->n_inputs > 0 ? cls->n_inputs : 1),
                               sizeof *in);
    if (!h || !scratch || !out || !imp || !in)
        goto fail;
    imp[0] = 1.0;
    for (;;) {
        if (len + BLOCK > cap) {
            cap *= 2;
            double *p = realloc(h, (size_t)cap * sizeof *h);
            if (!p)
                goto fail;
            h = p;
        }
        for (int k = 0; k < nout; k++)
            out[k] = (k == oid) ? h + len : scratch + (size_t)k * BLOCK;
        for (int k = 0; k < cls->n_inputs; k++)
            in[k] = (len == 0) ? imp : NULL;
        wdrt_render(cls, state, in, out, BLOCK, 256);
        double peak = 0;
        for (long i = len; i < len + BLOCK; i++) {
            if (!isfinite(h[i]))
                goto fail;
            if (fabs(h[i]) > peak)
                peak = fabs(h[i]);
        }
        len += BLOCK;
        if (len > BLOCK && peak < DECAY_FLOOR)
            break;
        if (len >= (long)(MAX_SECONDS * FS))
            goto fail;
    }
    free(scratch);
    free(out);
    free(imp);
    free(in);
    *n = len;
    return h;
fail:
    free(h);
    free(scratch);
    free(out);
    free(imp);
    free(in);
    return NULL;
}

/* sum_n h[n] e^{-j w n}; the phasor is recomputed exactly every 256
 * samples so its rounding drift stays near 256 ulps. */
static double complex dtft(const double *h, long n, double w)
{
    double complex acc = 0;
    const double complex step = cexp(-I * w);
    for (long k0 = 0; k0 < n; k0 += 256) {
        long k1 = k0 + 256 < n ? k0 + 256 : n;
        double complex z = cexp(-I * (w * (double)k0));
        double complex part = 0;
        for (long k = k0; k < k1; k++) {
            part += h[k] * z;
            z *= step;
        }
        acc += part;
    }
    return acc;
}

/* The digital frequency (Hz) the bilinear transform maps to analog f. */
static double warp(double f, double fs)
{
    return fs / M_PI * atan(M_PI * f / fs);
}

static void test_tonestack_vs_ngspice(void **st)
{
    fixture *fx = *st;
    const wdv_class *cls = fx->voice.cls;
    const char *pname[3] = {"treble", "bass", "mid"};
    int pid[3];
    for (int k = 0; k < 3; k++) {
        pid[k] = param_id(cls, pname[k]);
        if (pid[k] < 0)
            fail_msg("voice %s has no param %s", cls->name, pname[k]);
    }
    int oid = output_id(cls, "out");
    if (oid < 0)
        fail_msg("voice %s has no output `out`", cls->name);
    assert_true(cls->n_inputs == 1);

    int checked = 0;
    double worst_all = 0;
    for (int s = 0; s < NSETTINGS; s++) {
        /* The pot positions come from the data. */
        const row *first = NULL;
        for (int i = 0; i < fx->nrows && !first; i++)
            if (fx->rows[i].set == s)
                first = &fx->rows[i];
        if (!first)
            fail_msg("%s: no rows for setting %d", CSV_PATH, s);
        double pv[3] = {first->treble, first->bass, first->mid};

        void *state = tl_state_new(cls, FS);
        assert_non_null(state);
        for (int k = 0; k < 3; k++) {
            assert_int_equal(cls->set_param(state, pid[k], pv[k]), 0);
            assert_true(fabs(cls->get_param(state, pid[k]) - pv[k]) <= 1e-15);
        }
        cls->reset(state);

        long n = 0;
        double *h = impulse_response(cls, state, oid, &n);
        tl_state_free(state);
        if (!h)
            fail_msg("setting %d (treble=%g bass=%g mid=%g): the impulse "
                     "response is not finite or does not decay below %g "
                     "within %d s",
                     s, pv[0], pv[1], pv[2], DECAY_FLOOR, MAX_SECONDS);

        double worst = 0, worst_f = 0;
        int nrows = 0;
        for (int i = 0; i < fx->nrows; i++) {
            const row *r = &fx->rows[i];
            if (r->set != s)
                continue;
            double w = 2.0 * M_PI * warp(r->f, FS) / FS;
            double complex hd = dtft(h, n, w);
            double err = cabs(hd - r->h) / cabs(r->h);
            if (!(err < REL_TOL)) {
                free(h);
                fail_msg("setting %d (treble=%g bass=%g mid=%g), f=%.9g Hz "
                         "(f_d=%.9g Hz): voice %.12g%+.12gj, ngspice "
                         "%.12g%+.12gj, relative error %.3g > %g",
                         s, pv[0], pv[1], pv[2], r->f, warp(r->f, FS),
                         creal(hd), cimag(hd), creal(r->h), cimag(r->h), err,
                         REL_TOL);
            }
            if (err > worst) {
                worst = err;
                worst_f = r->f;
            }
            nrows++;
            checked++;
        }
        print_message("setting %d (treble=%g bass=%g mid=%g): %ld-sample "
                      "impulse response, %d frequencies, worst relative "
                      "error %.3g (%.1f dB) at %.6g Hz\n",
                      s, pv[0], pv[1], pv[2], n, nrows, worst, tl_db(worst),
                      worst_f);
        if (worst > worst_all)
            worst_all = worst;

        /* The warping error: the voice's response at f itself. */
        const double fw[4] = {1000, 5000, 10000, 15000};
        for (int j = 0; j < 4; j++) {
            const row *r = NULL;
            for (int i = 0; i < fx->nrows && !r; i++)
                if (fx->rows[i].set == s && fx->rows[i].f == fw[j])
                    r = &fx->rows[i];
            if (!r) {
                print_message("  no row at exactly %g Hz in %s\n", fw[j],
                              CSV_PATH);
                continue;
            }
            double complex hd = dtft(h, n, 2.0 * M_PI * fw[j] / FS);
            double dmag = tl_db(cabs(hd)) - tl_db(cabs(r->h));
            double dph = carg(hd / r->h) * 180.0 / M_PI;
            double rel = cabs(hd - r->h) / cabs(r->h);
            print_message("  unwarped at %5.0f Hz: |H_d| - |H| = %+.4f dB, "
                          "phase %+.4f deg, |H_d - H|/|H| = %.1f dB\n",
                          fw[j], dmag, dph, tl_db(rel));
        }
        free(h);
    }
    assert_true(checked >= 450);
    print_message("%d rows within %g; worst relative error %.3g\n", checked,
                  REL_TOL, worst_all);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_tonestack_vs_ngspice),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
