/*
 * test_hammer.c - the felt hammer voice against a converged ODE solution.
 *
 * tests/ref/hammer_ode.csv holds the felt force of netlists/hammer_bar.wdn
 * (hammer 8.7 g thrown at 2 m/s from 1 mm away at a bar of 30 g on a
 * 106.6 kN/m spring and a 0.5 N s/m damper, through a felt
 * F = 4.5e9 C^2.5 (1 + 0.1 dC/dt)) solved to near long-double precision:
 * peak force, its time, the start and end of the contact, and the force at
 * t = n/48000 s (tests/ref/hammer_ode.sh makes it).
 *
 * The voice renders the strike from its .ic (outputs force, vbar, xh) at
 * 48 kHz and at 96 kHz.  Asserted at each rate:
 *   - its largest force sample is within 1 % of the ODE's peak force;
 *   - its contact duration, the number of samples at which the felt is
 *     compressed (xh > xb) times 1/fs, is within one sample (1/fs) of
 *     the ODE's contact duration.  The force samples are not the measure:
 *     as the felt lets go, the last sample before the release may hold a
 *     small negative force (the step's average force is what the felt's
 *     stored energy can pay for, see templates/nl_passive.c.tmpl).
 * Reported besides: the number of samples with force > 0.
 * Reported besides: the peak's time, and the relative RMS error of the
 * force samples against the ODE's at the 48 kHz sample times.  The voice's
 * time axis is read off its xh output during the free flight
 * (xh = -1 mm + 2 m/s t): sample n of the voice is the state at
 * t = (n + d)/fs, with d found from it (d = 1: the .ic is the state before
 * sample 0).
 *
 * Measured: ODE peak 60.2702 N at 0.9577 ms, contact 0.5000 to 1.5627 ms
 * (1.0627 ms, 51.01 samples at 48 kHz); voice at 48 kHz 60.2161 N
 * (-0.090 %), 51 samples (1.0625 ms); at 96 kHz 60.2564 N (-0.023 %, a
 * quarter of the 48 kHz error: second order), 102 samples (1.0625 ms).
 * The sampled force is off by -56.0 dB (relative RMS) at 48 kHz and by
 * -68.0 dB at 96 kHz.
 *
 * Run from the repository root: build/tests/test_hammer (after make).
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

#define CSV_PATH "tests/ref/hammer_ode.csv"
#define NETLIST "netlists/hammer_bar.wdn"
#define FS_REF 48000.0
#define MAXREF 1024
#define PEAK_TOL 0.01
/* The voice renders this long: the whole contact and the span of the
 * ODE's samples (2 ms). */
#define SECONDS 2e-3
#define XH0 (-1e-3) /* the .ic of netlists/hammer_bar.wdn */
#define VH0 2.0

typedef struct ode_ref {
    double peak, t_peak, t_start, t_end, dur;
    double f[MAXREF]; /* force at t = n/48000 */
    int n;
} ode_ref;

typedef struct reading {
    ode_ref *o;
    int have; /* bit k: figure k read */
} reading;

static int read_row(const char *line, const char *path, int lineno, void *ctx)
{
    reading *rd = ctx;
    ode_ref *o = rd->o;
    if (!strncmp(line, "t_s,", 4))
        return 0;
    char key[64];
    double a, b;
    if (sscanf(line, "%63[a-z_N],%lf", key, &a) == 2) {
        const char *names[5] = {"peak_force_N", "peak_time_s",
                                "contact_start_s", "contact_end_s",
                                "contact_duration_s"};
        double *dst[5] = {&o->peak, &o->t_peak, &o->t_start, &o->t_end,
                          &o->dur};
        for (int k = 0; k < 5; k++)
            if (!strcmp(key, names[k])) {
                *dst[k] = a;
                rd->have |= 1 << k;
            }
        return 0;
    }
    if (sscanf(line, "%lf,%lf", &a, &b) != 2) {
        fprintf(stderr, "%s:%d: malformed row\n", path, lineno);
        return -1;
    }
    long m = lround(a * FS_REF);
    if (m != o->n || m >= MAXREF || fabs(a * FS_REF - (double)m) > 1e-6) {
        fprintf(stderr, "%s:%d: expected t = %d/48000\n", path, lineno,
                o->n);
        return -1;
    }
    o->f[o->n++] = b;
    return 0;
}

static int load_csv(void *data)
{
    const char *path = CSV_PATH;
    ode_ref *o = data;
    reading rd = {o, 0};
    if (tl_read_csv(path, NULL, "sh tests/ref/hammer_ode.sh", read_row, &rd) != 0)
        return -1;
    if (rd.have != 31 || o->n < 2) {
        fprintf(stderr, "%s: missing figures or samples\n", path);
        return -1;
    }
    return 0;
}

static int setup(void **st)
{
    return tl_fixture_setup(st, NETLIST, sizeof(ode_ref), load_csv, NULL);
}

static void check_rate(const tl_fixture *fx, int over)
{
    const wdv_class *cls = fx->voice.cls;
    const ode_ref *o = fx->data;
    double fs = FS_REF * over;
    int of = tl_output_id(cls, "force"), ox = tl_output_id(cls, "xh"), ob = tl_output_id(cls, "xb");
    if (of < 0 || ox < 0 || ob < 0)
        fail_msg("voice %s lacks output `force`, `xh` or `xb`", cls->name);
    long n = (long)ceil(SECONDS * fs) + 1;
    int nout = cls->n_outputs;
    double *buf = calloc((size_t)n * (size_t)nout, sizeof *buf);
    double **out = calloc((size_t)nout, sizeof *out);
    const double **in = calloc((size_t)cls->n_inputs + 1, sizeof *in);
    void *state = tl_state_new(cls, fs);
    if (!buf || !out || !in || !state)
        fail_msg("out of memory");
    for (int k = 0; k < nout; k++)
        out[k] = buf + (size_t)k * (size_t)n;
    wdrt_render(cls, state, in, out, n, 64);
    const double *f = out[of], *xh = out[ox], *xb = out[ob];

    /* the voice's time axis, from the free flight */
    double d = ((xh[0] - XH0) / VH0) * fs;
    long dn = lround(d);
    if (fabs(d - (double)dn) > 1e-6)
        fail_msg("fs=%g: xh[0] = %.17g is not on the free flight at a whole "
                 "sample", fs, xh[0]);

    long count = 0, pushing = 0, ipk = 0;
    for (long i = 0; i < n; i++) {
        if (!isfinite(f[i]))
            fail_msg("fs=%g: force[%ld] is not finite", fs, i);
        if (xh[i] > xb[i])
            count++;
        if (f[i] > 0)
            pushing++;
        if (f[i] > f[ipk])
            ipk = i;
    }
    double peak = f[ipk], dur = (double)count / fs;
    double perr = (peak - o->peak) / o->peak;

    /* the force at the ODE's sample times t = m/48000 = (i + dn)/fs */
    static double a[MAXREF], b[MAXREF];
    int nc = 0;
    for (int m = 0; m < o->n; m++) {
        long i = (long)m * over - dn;
        if (i >= 0 && i < n) {
            a[nc] = f[i];
            b[nc] = o->f[m];
            nc++;
        }
    }
    double rms = rel_rms_error(a, b, nc);

    print_message("fs=%6.0f Hz: peak %.6f N at t=%.4f ms (ODE %.6f N at "
                  "%.4f ms): %+.3f %%\n",
                  fs, peak, 1e3 * (double)(ipk + dn) / fs, o->peak,
                  1e3 * o->t_peak, 100 * perr);
    print_message("             contact %ld samples = %.4f ms (ODE %.4f ms = "
                  "%.3f samples, %.4f to %.4f ms): %+.3f samples; force > 0 "
                  "at %ld samples\n",
                  count, 1e3 * dur, 1e3 * o->dur, o->dur * fs,
                  1e3 * o->t_start, 1e3 * o->t_end, (dur - o->dur) * fs, pushing);
    print_message("             force at %d times n/48000: relative RMS error "
                  "%.3g (%.1f dB); sample n is t=(n%+ld)/fs\n",
                  nc, rms, tl_db(rms), dn);

    tl_state_free(state);
    free(buf);
    free(out);
    free(in);
    if (!(fabs(perr) <= PEAK_TOL))
        fail_msg("fs=%g: peak force %.6f N, ODE %.6f N: off by %.3f %% > "
                 "%g %%", fs, peak, o->peak, 100 * perr, 100 * PEAK_TOL);
    if (!(fabs(dur - o->dur) <= 1.0 / fs))
        fail_msg("fs=%g: contact lasts %ld samples = %.6f ms, the ODE's "
                 "%.6f ms: off by more than one sample", fs, count, 1e3 * dur,
                 1e3 * o->dur);
}

static void test_hammer_48k(void **st) { check_rate(*st, 1); }
static void test_hammer_96k(void **st) { check_rate(*st, 2); }

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_hammer_48k),
        cmocka_unit_test(test_hammer_96k),
    };
    return cmocka_run_group_tests(tests, setup, tl_fixture_teardown);
}
