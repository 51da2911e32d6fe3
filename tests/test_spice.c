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
/* The impulse response counts as decayed once a whole chunk of it stays
 * below this (the input impulse has height 1 V). */
#define DECAY_FLOOR 1e-15
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

/* The rows of the data. */
typedef struct table {
    row *rows;
    int n, cap;
} table;

static int read_row(const char *line, const char *path, int lineno, void *ctx)
{
    table *t = ctx;
    row r;
    double re, im;
    if (sscanf(line, "%d,%lf,%lf,%lf,%lf,%lf,%lf", &r.set, &r.treble,
               &r.bass, &r.mid, &r.f, &re, &im) != 7) {
        fprintf(stderr, "%s:%d: malformed row\n", path, lineno);
        return -1;
    }
    r.h = re + I * im;
    if (t->n == t->cap) {
        row *p = realloc(t->rows, (size_t)t->cap * 2 * sizeof *t->rows);
        if (!p)
            return -1;
        t->rows = p;
        t->cap *= 2;
    }
    t->rows[t->n++] = r;
    return 0;
}

static int load_csv(void *data)
{
    table *t = data;
    t->cap = 1024;
    t->rows = malloc((size_t)t->cap * sizeof *t->rows);
    if (!t->rows ||
        tl_read_csv(CSV_PATH, "setting_index", "sh tests/ref/tonestack_ngspice.sh",
                    read_row, t) != 0) {
        free(t->rows);
        return -1;
    }
    return 0;
}

static void free_rows(void *data)
{
    free(((table *)data)->rows);
}

static int setup(void **st)
{
    return tl_fixture_setup(st, NETLIST, sizeof(table), load_csv, free_rows);
}

/* The digital frequency (Hz) the bilinear transform maps to analog f. */
static double warp(double f, double fs)
{
    return fs / M_PI * atan(M_PI * f / fs);
}

static void test_tonestack_vs_ngspice(void **st)
{
    const tl_fixture *fx = *st;
    const table *tb = fx->data;
    const wdv_class *cls = fx->voice.cls;
    const char *pname[3] = {"treble", "bass", "mid"};
    int pid[3];
    for (int k = 0; k < 3; k++) {
        pid[k] = tl_param_id(cls, pname[k]);
        if (pid[k] < 0)
            fail_msg("voice %s has no param %s", cls->name, pname[k]);
    }
    int oid = tl_output_id(cls, "out");
    if (oid < 0)
        fail_msg("voice %s has no output `out`", cls->name);
    assert_true(cls->n_inputs == 1);

    int checked = 0;
    double worst_all = 0;
    for (int s = 0; s < NSETTINGS; s++) {
        /* The pot positions come from the data. */
        const row *first = NULL;
        for (int i = 0; i < tb->n && !first; i++)
            if (tb->rows[i].set == s)
                first = &tb->rows[i];
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
        double *h = tl_impulse_response(cls, state, oid, 256, DECAY_FLOOR,
                                        (long)(MAX_SECONDS * FS), &n);
        tl_state_free(state);
        if (!h)
            fail_msg("setting %d (treble=%g bass=%g mid=%g): the impulse "
                     "response is not finite or does not decay below %g "
                     "within %d s",
                     s, pv[0], pv[1], pv[2], DECAY_FLOOR, MAX_SECONDS);

        double worst = 0, worst_f = 0;
        int nrows = 0;
        for (int i = 0; i < tb->n; i++) {
            const row *r = &tb->rows[i];
            if (r->set != s)
                continue;
            double w = 2.0 * M_PI * warp(r->f, FS) / FS;
            double complex hd = tl_dtft(h, n, w);
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
            for (int i = 0; i < tb->n && !r; i++)
                if (tb->rows[i].set == s && tb->rows[i].f == fw[j])
                    r = &tb->rows[i];
            if (!r) {
                print_message("  no row at exactly %g Hz in %s\n", fw[j],
                              CSV_PATH);
                continue;
            }
            double complex hd = tl_dtft(h, n, 2.0 * M_PI * fw[j] / FS);
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
    return cmocka_run_group_tests(tests, setup, tl_fixture_teardown);
}
