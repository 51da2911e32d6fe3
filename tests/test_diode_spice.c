/*
 * test_diode_spice.c - the diode clipper voice against ngspice's transient.
 *
 * tests/ref/diode_clipper_tran.csv holds v(out) of netlists/diode_clipper.wdn
 * driven from rest by v(in) = A sin(2 pi 440 t), A = 1 V and 10 V, over
 * 10 ms, sampled at t = m/48000 s; ngspice computed it with a 10 ns maximum
 * step at the temperature where its diode's kT/q equals the netlist's
 * Vt = 25.85 mV (tests/ref/diode_clipper_ngspice.sh makes it; its own error
 * is near 1e-8 V).
 *
 * The voice (default solver: Newton on the diode pair at the root) runs at
 * 48 kHz, 192 kHz and 384 kHz on the same sine, sampled at its own rate,
 * and its output at t = m/48000 is compared with the data: the error is
 * the relative RMS error over the 481 points, reported in dB.
 *
 * What the bilinear method predicts.  The voice is the trapezoidal rule
 * applied to C1 with the diodes solved exactly at each step, so its global
 * error is second order in T = 1/fs: a component of frequency f is
 * computed as if at f (1 + (2 pi f T)^2 / 12), so its relative error is
 * of order (f/fc) (2 pi f T)^2 / 12 below the corner fc = 1/(2 pi R1 C1) =
 * 7.23 kHz, and at most (2 pi fc T)^2 / 12 = 0.075 (-22.5 dB at 48 kHz)
 * for content near the corner.  Most of the output is the 440 Hz
 * fundamental and its low harmonics, so the whole error lies well under
 * that scale; it comes from the start (the sine's slope switches on at
 * t = 0 and excites the 22 us R1 C1 mode) and, at 10 V, from the knees
 * where the output enters and leaves clipping within a few microseconds.
 * Each fourfold increase of the rate should divide the error by 16 once
 * the step is short against those events.
 *
 * Measured (ngspice 39, the voice as of this test):
 *
 *     A      48 kHz      192 kHz     384 kHz    48k/192k   192k/384k
 *     1 V   -70.3 dB    -94.9 dB   -107.0 dB     17.1        4.01
 *    10 V   -45.7 dB    -64.9 dB    -77.1 dB      9.2        4.08
 *
 * (per doubling from 48 kHz up to 1.5 MHz the 10 V error falls 2.7, 3.4,
 * 4.1, 4.0, 4.0 times and reaches -101 dB: second order once the step is
 * under about 3 us, and the voice and ngspice converge to the same
 * waveform; at 48 kHz the 20.8 us step is longer than a knee, where the
 * error saturates at the knee's size instead of growing as T^2.)
 *
 * Asserted, with about 3 dB of margin on each measurement:
 *   - at 48 kHz the error is below -67 dB (A = 1 V) and -42 dB (A = 10 V),
 *     both far under the -22.5 dB corner scale above;
 *   - at 192 kHz it is below -92 dB and -62 dB: the voice is within 0.08 %
 *     RMS of ngspice;
 *   - from 48 to 192 kHz the error falls at least 12 times (1 V; second
 *     order predicts 16) or 7 times (10 V; pre-asymptotic at 48 kHz, see
 *     above), and from 192 to 384 kHz at least 3.5 times (4 predicted).
 *
 * The same deck ngspice ran, read by bin/wdc as a SPICE deck and rendered
 * with the sine its source names, meets the same bounds (test_deck_vs_ngspice).
 *
 * Run from the repository root: build/tests/test_diode_spice (after make).
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testlib.h"

#define CSV_PATH "tests/ref/diode_clipper_tran.csv"
#define NETLIST "netlists/diode_clipper.wdn"
#define FS_REF 48000.0
#define NREF 481 /* t = 0 .. 10 ms at 48 kHz */
#define F_SINE 440.0
#define NAMP 2

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

static const double amps[NAMP] = {1.0, 10.0};
/* Bounds on the relative RMS error, in dB, and on how fast it falls (see
 * the head comment). */
static const double bound48_db[NAMP] = {-67.0, -42.0};
static const double bound192_db[NAMP] = {-92.0, -62.0};
static const double min_ratio_48_192[NAMP] = {12.0, 7.0};
#define MIN_RATIO_192_384 3.5
#define NRATES 3

/* The data: v(out) at t = m/48000 for each amplitude. */
typedef struct refdata {
    double v[NAMP][NREF];
} refdata;

typedef struct reading {
    refdata *ref;
    int count[NAMP];
} reading;

static int read_row(const char *line, const char *path, int lineno, void *ctx)
{
    reading *rd = ctx;
    double a, t, v;
    if (sscanf(line, "%lf,%lf,%lf", &a, &t, &v) != 3) {
        fprintf(stderr, "%s:%d: malformed row\n", path, lineno);
        return -1;
    }
    int k = -1;
    for (int j = 0; j < NAMP; j++)
        if (a == amps[j])
            k = j;
    long m = lround(t * FS_REF);
    if (k < 0 || m < 0 || m >= NREF || fabs(t * FS_REF - (double)m) > 1e-9) {
        fprintf(stderr, "%s:%d: unexpected amplitude or time\n", path,
                lineno);
        return -1;
    }
    rd->ref->v[k][m] = v;
    rd->count[k]++;
    return 0;
}

static int load_csv(void *data)
{
    const char *path = CSV_PATH;
    reading rd = {data, {0, 0}};
    if (tl_read_csv(path, "amplitude", "sh tests/ref/diode_clipper_ngspice.sh",
                    read_row, &rd) != 0)
        return -1;
    for (int k = 0; k < NAMP; k++)
        if (rd.count[k] != NREF) {
            fprintf(stderr, "%s: %d rows for A=%g, expected %d\n", path,
                    rd.count[k], amps[k], NREF);
            return -1;
        }
    return 0;
}

static int setup(void **st)
{
    return tl_fixture_setup(st, NETLIST, sizeof(refdata), load_csv, NULL);
}

/* Runs the voice at fs = FS_REF * over on A sin(2 pi 440 n / fs) from
 * rest and returns in y[m] its output at n = m * over, m < NREF; returns
 * -1 if the output is not finite. */
static int run_voice(const wdv_class *cls, int oid, double amp, int over,
                     double *y)
{
    double fs = FS_REF * over;
    long n = (long)(NREF - 1) * over + 1;
    int nout = cls->n_outputs;
    double *in = malloc((size_t)n * sizeof *in);
    double *buf = malloc((size_t)n * (size_t)nout * sizeof *buf);
    double **out = malloc((size_t)nout * sizeof *out);
    const double *ins[1];
    void *state = tl_state_new(cls, fs);
    int ok = in && buf && out && state;
    if (ok) {
        for (long i = 0; i < n; i++)
            in[i] = amp * sin(2.0 * M_PI * F_SINE * (double)i / fs);
        for (int k = 0; k < nout; k++)
            out[k] = buf + (size_t)k * (size_t)n;
        ins[0] = in;
        wdrt_render(cls, state, ins, out, n, 256);
        for (long m = 0; m < NREF; m++) {
            y[m] = out[oid][m * over];
            if (!isfinite(y[m]))
                ok = 0;
        }
    }
    tl_state_free(state);
    free(in);
    free(buf);
    free(out);
    return ok ? 0 : -1;
}

static void test_diode_clipper_vs_ngspice(void **st)
{
    const tl_fixture *fx = *st;
    const refdata *ref = fx->data;
    const wdv_class *cls = fx->voice.cls;
    assert_int_equal(cls->n_inputs, 1);
    int oid = tl_output_id(cls, "out");
    if (oid < 0)
        fail_msg("voice %s has no output `out`", cls->name);

    static double y[NREF];
    const int over[NRATES] = {1, 4, 8};
    for (int k = 0; k < NAMP; k++) {
        double e[NRATES];
        for (int r = 0; r < NRATES; r++) {
            if (run_voice(cls, oid, amps[k], over[r], y) != 0)
                fail_msg("A=%g V at %g Hz: the output is not finite or memory "
                         "ran out", amps[k], FS_REF * over[r]);
            e[r] = rel_rms_error(y, ref->v[k], NREF);
            long worst = 0;
            for (long m = 0; m < NREF; m++)
                if (fabs(y[m] - ref->v[k][m]) >
                    fabs(y[worst] - ref->v[k][worst]))
                    worst = m;
            print_message("A=%4.1f V, fs=%6.0f Hz: relative RMS error %.4g "
                          "(%.1f dB); worst at t=%.4f ms: voice %.9f V, "
                          "ngspice %.9f V\n",
                          amps[k], FS_REF * over[r], e[r], tl_db(e[r]),
                          1e3 * (double)worst / FS_REF, y[worst],
                          ref->v[k][worst]);
        }
        double r1 = e[0] / e[1], r2 = e[1] / e[2];
        print_message("A=%4.1f V: error ratio 48k/192k %.2f (second order: 16; "
                      "asserted >= %g), 192k/384k %.2f (4; asserted >= %g)\n",
                      amps[k], r1, min_ratio_48_192[k], r2, MIN_RATIO_192_384);
        if (!(tl_db(e[0]) < bound48_db[k]))
            fail_msg("A=%g V: 48 kHz error %.1f dB, bound %.1f dB", amps[k],
                     tl_db(e[0]), bound48_db[k]);
        if (!(tl_db(e[1]) < bound192_db[k]))
            fail_msg("A=%g V: 192 kHz error %.1f dB, bound %.1f dB", amps[k],
                     tl_db(e[1]), bound192_db[k]);
        if (!(r1 >= min_ratio_48_192[k]))
            fail_msg("A=%g V: the error falls only %.2f times from 48 to "
                     "192 kHz (asserted >= %g; second order predicts 16)",
                     amps[k], r1, min_ratio_48_192[k]);
        if (!(r2 >= MIN_RATIO_192_384))
            fail_msg("A=%g V: the error falls only %.2f times from 192 to "
                     "384 kHz (asserted >= %g; second order predicts 4)",
                     amps[k], r2, MIN_RATIO_192_384);
    }
}

/* The deck ngspice ran (tests/ref/diode_clipper_ngspice.sh), as written:
 * its title, .options with the temperature that makes kT/q 25.85 mV, the
 * sine source, two facing diodes (taken as one pair), the model in
 * SPICE's form, and the .control block whose wrdata names the output.  bin/wdc reads it as a deck and renders it with the
 * sine its source names; the errors against ngspice are those of the
 * netlist above, to the bounds above. */
static void test_deck_vs_ngspice(void **st)
{
    const refdata *ref = ((const tl_fixture *)*st)->data;
    char dir[64];
    assert_int_equal(tl_temp_dir(dir, "wdc_deck"), 0);
    for (int k = 0; k < NAMP; k++) {
        char deck[2048], cmd[1024], path[256];
        snprintf(deck, sizeof deck,
                 "* diode clipper, netlists/diode_clipper.wdn, sine 440 Hz at %g V\n"
                 ".options TEMP=26.826895261366076 TNOM=26.826895261366076 RELTOL=1e-6 VNTOL=1e-9 "
                 "ABSTOL=1e-15 GMIN=1e-15\n"
                 "V1 in1 0 SIN(0 %g 440)\nR1 in1 out 2.2k\nC1 out 0 10n\n"
                 "D1 out 0 d1n4148\nD2 0 out d1n4148\n.model d1n4148 D(IS=2.52n N=1.752)\n"
                 ".control\nset numdgt=16\ntran 2.0833333333333333e-05 10m 0 1e-8\nwrdata clip.dat v(out)\n.endc\n"
                 ".end\n", amps[k], amps[k]);
        tl_write_file(dir, "clip.cir", deck);
        double e[2];
        for (int r = 0; r < 2; r++) {
            int over = r ? 4 : 1;
            snprintf(cmd, sizeof cmd, "bin/wdc %s/clip.cir --render %s/o.wav --csv %s/o.csv --rate %g "
                     "--seconds 0.01003 2>/dev/null", dir, dir, dir, FS_REF * over);
            assert_int_equal(tl_system(cmd), 0);
            snprintf(path, sizeof path, "%s/o.csv", dir);
            FILE *f = fopen(path, "r");
            assert_non_null(f);
            static double y[NREF];
            char line[256];
            long n = 0;
            while (fgets(line, sizeof line, f))
                if (n % over == 0 && n / over < NREF)
                    y[n++ / over] = atof(line);
                else
                    n++;
            fclose(f);
            assert_true(n >= (long)(NREF - 1) * over + 1);
            e[r] = rel_rms_error(y, ref->v[k], NREF);
            print_message("deck, A=%4.1f V, fs=%6.0f Hz: relative RMS error %.4g (%.1f dB)\n", amps[k],
                          FS_REF * over, e[r], tl_db(e[r]));
        }
        assert_true(tl_db(e[0]) < bound48_db[k]);
        assert_true(tl_db(e[1]) < bound192_db[k]);
        assert_true(e[0] / e[1] >= min_ratio_48_192[k]);
    }
    tl_remove_dir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_diode_clipper_vs_ngspice),
        cmocka_unit_test(test_deck_vs_ngspice),
    };
    return cmocka_run_group_tests(tests, setup, tl_fixture_teardown);
}
