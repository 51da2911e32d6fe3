/*
 * test_waveguide.c - strings and tubes measured from what they render.
 *
 *   - tuning: the first partial of a string with rigid ends within 1 cent
 *     of f0 from 27.5 Hz to 4186 Hz at 44.1, 48 and 96 kHz;
 *   - harmonics: partials 1..4 of a lossy ideal string within 1 cent of
 *     n f0 up to 1318.5 Hz at the same rates;
 *   - stiffness: partials n = 1..12 (those below 0.4 fs) of stiff strings
 *     within 3 cents of n f0 sqrt((1 + B n^2) / (1 + B)), and how far past
 *     12 that holds;
 *   - decay: the first partial's t60 within 10 %, partials near fhf in
 *     t60hf within 25 %;
 *   - passivity of every loop filter (gain at most 1, lattice stable, the
 *     storage weights' inequality) over random designs;
 *   - tubes: first resonances of open-open and closed-open tubes within 5
 *     cents of c / (2 (L + 2 dL)) and c / (4 (L + dL)), dL = 0.6133 r
 *     (an unflanged open end), and the harmonic and odd patterns above;
 *   - a pitch glide without clicks.
 * Partials are measured with tests/partials.h.
 */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "partials.h"
#include "testlib.h"

#include "../templates/waveguide.c.tmpl"

/* ---- voices from netlist text ---- */

static int build_text(const char *text, tl_voice *v) {
    char path[] = "/tmp/wdc-wg-XXXXXX.wdn";
    int fd = mkstemps(path, 4);
    if (fd < 0)
        return -1;
    size_t n = strlen(text);
    int ok = write(fd, text, n) == (ssize_t)n;
    close(fd);
    int r = ok ? tl_voice_build(path, 0, v) : -1;
    unlink(path);
    return r;
}

/* Renders n frames of output `out` after an impulse of amp on every input
 * (at frame 0), from the state as it is. */
static double *render(const wdv_class *cls, void *st, long n, double amp, int out) {
    int ni = cls->n_inputs, no = cls->n_outputs;
    double **in = tl_bufs_new(ni > 0 ? ni : 1, 256), **o = tl_bufs_new(no, 256);
    double *y = malloc(sizeof(double) * (size_t)n);
    for (long k = 0; k < n; k += 256) {
        int m = n - k < 256 ? (int)(n - k) : 256;
        for (int i = 0; i < ni; i++)
            for (int j = 0; j < m; j++)
                in[i][j] = k + j == 0 ? amp : 0;
        cls->process(st, (const double *const *)in, o, m);
        memcpy(y + k, o[out], sizeof(double) * (size_t)m);
    }
    tl_bufs_free(in, ni > 0 ? ni : 1);
    tl_bufs_free(o, no);
    return y;
}

static const double rates[] = {44100, 48000, 96000};

/* ---- tuning ---- */

static const char *tune_net =
    ".voice tune\n.domain mechanical\n.input f\n"
    ".param f0 440 min=27.5 max=4200\n"
    "string S1 0 0 L=0.65 f0={f0} mu=1m t60=20 taps=p@0.1237,o@0.7093\n"
    "force F1 p 0 f\n.output v v(o)\n.end\n";

static void test_tuning(void **state) {
    (void)state;
    tl_voice v;
    assert_int_equal(build_text(tune_net, &v), 0);
    static const double f0s[] = {27.5, 41.2, 55, 110, 220, 261.63, 440, 880, 1760, 2637, 3520, 4186};
    double worst = 0;
    for (int r = 0; r < 3; r++) {
        printf("fs %6.0f:", rates[r]);
        for (size_t i = 0; i < sizeof f0s / sizeof f0s[0]; i++) {
            void *st = tl_state_new(v.cls, rates[r]);
            v.cls->set_param(st, tl_param_id(v.cls, "f0"), f0s[i]);
            long n = (long)(rates[r] * fmax(1.0, 60 / f0s[i]));
            double *y = render(v.cls, st, n, 1, 0);
            double f = pt_peak_freq(y, (size_t)n, rates[r], 0.97 * f0s[i], 1.03 * f0s[i]);
            double c = pt_cents(f, f0s[i]);
            printf(" %g:%+.4f", f0s[i], c);
            worst = fmax(worst, fabs(c));
            assert_true(fabs(c) < 1);
            free(y);
            tl_state_free(st);
        }
        printf(" cents\n");
    }
    printf("first partial: worst error %.4f cents over 27.5..4186 Hz at 44.1/48/96 kHz\n", worst);
    tl_voice_free(&v);
}

/* wdv_class.tuning: what the loops' designs promise, at the rate and
 * params in effect: within a cent at f0 = 440 Hz and 48 kHz (a few at
 * 880 Hz, where partial 12 lies at 10.6 kHz), tens of
 * cents at 8 kHz (its partials near 4 kHz); INFINITY for a loop too short
 * for its filters (f0 = 4200 Hz at 8 kHz), whether designed in process or
 * handed over by prepare and install, and finite again once f0 comes
 * down; INFINITY also for a low string at 1 MHz, longer than the lines
 * the voice holds (made for 192 kHz); NULL for a voice without strings or
 * tubes. */
/* The voice's tuning (at rate fs) once f0 (param id) is set to hz and a
 * block played. */
static double tuned(const wdv_class *c, void *st, double fs, int id, double hz) {
    c->set_param(st, id, hz);
    free(render(c, st, 64, 0, 0));
    printf("f0 %g Hz at %g Hz: %g cents\n", hz, fs, c->tuning(st));
    return c->tuning(st);
}

static void test_tuning_reported(void **state) {
    (void)state;
    tl_voice v, rc;
    assert_int_equal(build_text(tune_net, &v), 0);
    const wdv_class *c = v.cls;
    assert_non_null(c->tuning);
    int f0 = tl_param_id(c, "f0");
    void *st = tl_state_new(c, 48000);
    double t = c->tuning(st);
    printf("f0 440 Hz at 48 kHz: %.4f cents\n", t);
    assert_true(t >= 0 && t < 1);
    tl_state_free(st);
    st = tl_state_new(c, 8000);
    t = c->tuning(st);
    printf("f0 440 Hz at 8 kHz: %.4f cents (the partials near 4 kHz)\n", t);
    assert_true(t >= 0 && t < 100);
    assert_true(isinf(tuned(c, st, 8000, f0, 4200)));
    assert_true(tuned(c, st, 8000, f0, 110) < 100);
    tl_state_free(st);
    /* far above the rate its lines were made for (four times 48 kHz), a
     * low string's loop is longer than they hold; a high one still fits */
    st = tl_state_new(c, 1e6);
    assert_true(isinf(tuned(c, st, 1e6, f0, 27.5)));
    assert_true(tuned(c, st, 1e6, f0, 880) < 1);
    tl_state_free(st);
    /* a design made off the audio thread carries its error along: the
     * same as the one process makes */
    assert_non_null(c->prepare);
    void *design = calloc(1, c->design_size), *made = tl_state_new(c, 48000);
    st = tl_state_new(c, 48000);
    double p[8];
    for (int i = 0; i < c->n_params; i++)
        p[i] = c->get_param(st, i);
    for (int k = 0; k < 2; k++) {
        const double fs = k ? 8000 : 48000, to = k ? 4200 : 880;
        c->init(st, fs);
        c->init(made, fs);
        p[f0] = to;
        c->prepare(fs, p, design);
        c->install(made, design);
        c->set_param(made, f0, to);
        c->set_param(st, f0, to);
        free(render(c, made, 64, 0, 0));
        free(render(c, st, 64, 0, 0));
        printf("f0 %g Hz at %g Hz: %g cents designed in process, %g installed\n", to, fs, c->tuning(st),
               c->tuning(made));
        assert_true(c->tuning(made) == c->tuning(st));
        assert_true(k ? isinf(c->tuning(st)) : c->tuning(st) > 0 && c->tuning(st) < 10);
    }
    free(design);
    tl_state_free(made);
    tl_state_free(st);
    tl_voice_free(&v);
    assert_int_equal(tl_voice_build("netlists/rc_lowpass.wdn", 0, &rc), 0);
    assert_null(rc.cls->tuning);
    tl_voice_free(&rc);
}

/* A transmission line's delay (tests/nets/tline.wdn: 1 ms, its lines
 * made for 192 kHz, 255 samples) is held in whole samples: tuning gives
 * the error of that rounding in cents, 1200 |log2(D / (TD fs))| (0 at
 * 48 kHz, 3.93 at 44.1 kHz), and INFINITY where the delay cannot be held:
 * shorter than half a sample (400 Hz) or longer than its line (256 kHz). */
static void test_line_tuning(void **state) {
    (void)state;
    tl_voice v;
    assert_int_equal(tl_voice_build("tests/nets/tline.wdn", 0, &v), 0);
    const wdv_class *c = v.cls;
    assert_non_null(c->tuning);
    static const double rates[] = {48000, 44100, 1000, 7, 255000, 256000, 400, 1e6};
    for (int k = 0; k < 8; k++) {
        void *st = tl_state_new(c, rates[k]);
        const double t = 1e-3 * rates[k], d = floor(t + 0.5);
        const double want = t < 0.5 || d > 255 ? INFINITY : 1200 * fabs(log2(d / t));
        printf("1 ms at %g Hz: %g samples, %g cents (closed form %g)\n", rates[k], d, c->tuning(st), want);
        if (isinf(want))
            assert_true(isinf(c->tuning(st)));
        else
            assert_true(fabs(c->tuning(st) - want) <= 1e-12 * (1 + want));
        tl_state_free(st);
    }
    void *st = tl_state_new(c, 44100);
    assert_true(c->tuning(st) > 3.9 && c->tuning(st) < 3.95);
    tl_state_free(st);
    tl_voice_free(&v);
}

/* ---- harmonics of a lossy ideal string ----
 * The loss filter's phase delay falls with frequency; the tuning stage
 * offsets it.  Partials 1..4 within 1 cent of n f0 up to E6 (1318.5 Hz,
 * a guitar's highest fret) at every rate; the octave above is printed. */

static const char *harm_net =
    ".voice harm\n.domain mechanical\n.input f\n"
    ".param f0 440 min=27.5 max=4200\n"
    "string S1 0 0 L=0.65 f0={f0} mu=1.2m t60=3 t60hf=0.4 fhf=4k taps=p@0.2,o@0.8\n"
    "force F1 p 0 f\n.output v v(o)\n.end\n";

static void test_harmonics(void **state) {
    (void)state;
    tl_voice v;
    assert_int_equal(build_text(harm_net, &v), 0);
    static const double f0s[] = {27.5, 55, 110, 196, 329.63, 440, 659.26, 880, 987.77, 1174.7, 1318.5,
                                 1760, 2093, 2637};
    double worst = 0;
    for (int r = 0; r < 3; r++) {
        printf("fs %6.0f, worst of partials 1..4:", rates[r]);
        for (size_t i = 0; i < sizeof f0s / sizeof f0s[0]; i++) {
            double f0 = f0s[i];
            void *st = tl_state_new(v.cls, rates[r]);
            v.cls->set_param(st, tl_param_id(v.cls, "f0"), f0);
            long n = (long)(rates[r] * 2);
            double *y = render(v.cls, st, n, 1, 0);
            double w = 0;
            for (int k = 1; k <= 4; k++) {
                double f = pt_peak_freq(y, (size_t)n, rates[r], (k - 0.3) * f0, (k + 0.3) * f0);
                double c = fabs(pt_cents(f, k * f0));
                if (!(c <= w))
                    w = c; /* a missing partial (NAN) is the worst */
            }
            printf(" %g:%.3f", f0, w);
            if (f0 <= 1318.5) {
                worst = fmax(worst, w);
                if (!(w < 1))
                    fail_msg("f0 %g at %g Hz: a partial of 1..4 off by %.3f cents", f0, rates[r], w);
            }
            free(y);
            tl_state_free(st);
        }
        printf(" cents\n");
    }
    printf("partials 1..4: worst error %.3f cents over 27.5..1318.5 Hz at 44.1/48/96 kHz\n", worst);
    tl_voice_free(&v);
}

/* ---- stiffness ---- */

static double partial_freq(double f0, double B, int n) { return n * f0 * sqrt((1 + B * n * n) / (1 + B)); }

static void test_stiffness(void **state) {
    (void)state;
    static const double pairs[][2] = {{27.5, 2e-4}, {110, 2e-4}, {261.63, 4e-4}, {523.25, 8e-4},
                                      {1046.5, 2e-3}, {2093, 4e-3}, {4186, 1e-2}};
    for (size_t i = 0; i < sizeof pairs / sizeof pairs[0]; i++) {
        double f0 = pairs[i][0], B = pairs[i][1];
        char net[512];
        snprintf(net, sizeof net,
                 ".voice stiff\n.domain mechanical\n.input f\n"
                 "string S1 0 0 L=0.65 f0=%.17g mu=5m B=%.17g t60=20 taps=p@0.1237,o@0.7093\n"
                 "force F1 p 0 f\n.output v v(o)\n.end\n", f0, B);
        tl_voice v;
        assert_int_equal(build_text(net, &v), 0);
        for (int r = 0; r < 3; r++) {
            double fs = rates[r];
            void *st = tl_state_new(v.cls, fs);
            long n = (long)(fs * fmax(1.0, 60 / f0));
            double *y = render(v.cls, st, n, 1, 0);
            double worst = 0;
            int reach = 0, nmax = 0, absent = 0;
            for (int k = 1; k <= 60; k++) {
                double fk = partial_freq(f0, B, k);
                if (fk > 0.4 * fs)
                    break;
                double half = 0.3 * (partial_freq(f0, B, k + 1) - fk);
                double f = pt_peak_freq(y, (size_t)n, fs, fk - half, fk + half);
                double c = pt_cents(f, fk);
                nmax = k;
                if (isnan(f)) { /* a partial the strike or the pickup hardly reaches */
                    absent += k <= 12;
                    if (k == reach + 1)
                        reach = k;
                    continue;
                }
                if (k <= 12) {
                    worst = fmax(worst, fabs(c));
                    if (!(fabs(c) < 3))
                        fail_msg("f0 %g B %g at %g Hz: partial %d off by %.3f cents", f0, B, fs, k, c);
                }
                if (k == reach + 1 && fabs(c) < 3)
                    reach = k;
            }
            printf("f0 %7.2f B %.0e fs %5.0f: partials 1..%d worst %.3f cents (%d without a peak at the pickup); "
                   "within 3 cents up to n = %d (of %d below 0.4 fs)\n", f0, B, fs, nmax < 12 ? nmax : 12, worst,
                   absent, reach, nmax);
            assert_true(absent <= 1);
            free(y);
            tl_state_free(st);
        }
        tl_voice_free(&v);
    }
}

/* ---- decay ---- */

static void test_decay(void **state) {
    (void)state;
    static const double cases[][4] = {/* f0, t60, t60hf, fhf */
                                      {110, 3, 0.5, 3000},
                                      {220, 1.5, 0.3, 3000},
                                      {440, 4, 0.8, 5000}};
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        double f0 = cases[i][0], t60 = cases[i][1], t60hf = cases[i][2], fhf = cases[i][3];
        char net[512];
        snprintf(net, sizeof net,
                 ".voice decay\n.domain mechanical\n.input f\n"
                 "string S1 0 0 L=0.65 f0=%.17g mu=1m t60=%.17g t60hf=%.17g fhf=%.17g taps=p@0.1237,o@0.7093\n"
                 "force F1 p 0 f\n.output v v(o)\n.end\n", f0, t60, t60hf, fhf);
        tl_voice v;
        assert_int_equal(build_text(net, &v), 0);
        for (int r = 0; r < 3; r++) {
            double fs = rates[r];
            void *st = tl_state_new(v.cls, fs);
            long n = (long)(fs * t60 * 0.8);
            double *y = render(v.cls, st, n, 1, 0);
            double m1 = pt_t60(y, (size_t)n, fs, f0, f0 / 3, 3, 30);
            int kh = (int)floor(fhf / f0 + 0.5);
            double mh = pt_t60(y, (size_t)n, fs, kh * f0, f0 / 3, 3, 30);
            double e1 = m1 / t60 - 1, eh = mh / t60hf - 1;
            printf("f0 %g fs %5.0f: t60 %.3f s (want %.3f, %+.1f %%), partial %d at %.0f Hz: %.3f s (want %.3f at "
                   "fhf, %+.1f %%)\n", f0, fs, m1, t60, 100 * e1, kh, kh * f0, mh, t60hf, 100 * eh);
            assert_true(fabs(e1) < 0.10);
            assert_true(fabs(eh) < 0.25);
            free(y);
            tl_state_free(st);
        }
        tl_voice_free(&v);
    }
}

/* ---- passivity of the loop filters ---- */

static void test_filters_passive(void **state) {
    (void)state;
    tl_rng rng;
    tl_rng_seed(&rng, 41);
    int designs = 0;
    double gmax = 0, kmax = 0, slack = 0;
    for (int it = 0; it < 400; it++) {
        wg_spec s;
        memset(&s, 0, sizeof s);
        s.fs = rates[it % 3];
        s.f0 = 27.5 * pow(2, 7.3 * tl_rng_uniform(&rng));
        s.B = it % 4 ? 1e-5 * pow(10, 3.3 * tl_rng_uniform(&rng)) : 0;
        s.t60 = it % 5 ? 0.2 + 20 * tl_rng_uniform(&rng) : 0;
        s.t60hf = s.t60 * (0.05 + 1.2 * tl_rng_uniform(&rng));
        s.fhf = 1000 + 9000 * tl_rng_uniform(&rng);
        s.nu1 = it % 7 ? 1 : 0.5;
        s.rad = it % 3 ? 0 : 0.02 / 343.2 * tl_rng_uniform(&rng);
        s.nrad = s.rad > 0 ? 1 + it % 2 : 0;
        s.K = 1 + (int)(12 * tl_rng_uniform(&rng));
        s.nmin = 4;
        wg_loop l;
        if (wg_design(&s, &l) < 0)
            continue;
        designs++;
        for (int j = 0; j <= 512; j++) {
            double w = M_PI * j / 512;
            double lg = l.lb / sqrt(1 + 2 * l.la * cos(w) + l.la * l.la);
            double rg = (1 + l.ra) / sqrt(1 + 2 * l.ra * cos(w) + l.ra * l.ra);
            gmax = fmax(gmax, fmax(lg, rg));
            assert_true(lg <= 1 + 1e-12 && rg <= 1 + 1e-12);
        }
        for (int m = 0; m < s.K; m++) {
            kmax = fmax(kmax, fabs(l.k[m]));
            assert_true(fabs(l.k[m]) < 1);
            assert_true(fabs(l.k[m] * l.k[m] + l.c[m] * l.c[m] - 1) < 1e-12);
        }
        /* the one-poles' storage: x^2 - y^2 >= c (y^2 - y1^2) */
        for (int j = 0; j < 200; j++) {
            double x = tl_rng_signed(&rng), y1 = tl_rng_signed(&rng);
            double y = l.lb * x - l.la * y1, d = x * x - y * y - l.lc * (y * y - y1 * y1);
            slack = fmin(slack, d);
            assert_true(d >= -1e-12);
            y = (1 + l.ra) * x - l.ra * y1;
            d = x * x - y * y - l.rc * (y * y - y1 * y1);
            assert_true(d >= -1e-12);
        }
    }
    printf("%d loop designs: largest filter gain %.15f, largest lattice |k| %.6f, storage inequality slack %.2e\n",
           designs, gmax, kmax, slack);
    assert_true(designs > 300);
}

/* ---- tubes ---- */

static void test_tube(void **state) {
    (void)state;
    const double L = 0.6, r = 7.5e-3, c = 343.2, dL = 0.6133 * r;
    for (int closed = 0; closed < 2; closed++) {
        char net[512];
        snprintf(net, sizeof net,
                 ".voice bore\n.domain acoustic\n.input q\n"
                 "tube W1 0 0 L=%g r=%g ends=%s taps=p@0.1237,o@0.7093\n"
                 "I1 0 p q\n.output p v(o)\n.end\n", L, r, closed ? "closed,open" : "open");
        tl_voice v;
        assert_int_equal(build_text(net, &v), 0);
        double f1 = closed ? c / (4 * (L + dL)) : c / (2 * (L + 2 * dL));
        for (int ri = 0; ri < 3; ri++) {
            double fs = rates[ri];
            void *st = tl_state_new(v.cls, fs);
            long n = (long)(fs * 1.0);
            double *y = render(v.cls, st, n, 1e-6, 0);
            double m1 = pt_peak_freq(y, (size_t)n, fs, 0.9 * f1, 1.1 * f1);
            double c1 = pt_cents(m1, f1);
            /* the next resonance: 2 f1 (open-open) or 3 f1 (closed-open) */
            double f2 = (closed ? 3 : 2) * f1;
            double m2 = pt_peak_freq(y, (size_t)n, fs, 0.93 * f2, 1.07 * f2);
            printf("%s tube L %.2f m r %.1f mm at %5.0f Hz: first resonance %.3f Hz, want %.3f (%+.3f cents); "
                   "next %.3f Hz = %.4f f1\n", closed ? "closed-open" : "open-open", L, 1e3 * r, fs, m1, f1, c1, m2,
                   m2 / m1);
            assert_true(fabs(c1) < 5);
            assert_true(fabs(m2 / m1 - (closed ? 3 : 2)) < 0.03 * (closed ? 3 : 2));
            free(y);
            tl_state_free(st);
        }
        tl_voice_free(&v);
    }
}

/* ---- glide ---- */

/* A glide from 220 Hz to 330 Hz over half a second, in 64-sample control
 * blocks: the largest second difference of the output, against the same
 * string held at 220 Hz and at 330 Hz (a click is a spike far above
 * both). */
static void test_glide(void **state) {
    (void)state;
    tl_voice v;
    assert_int_equal(build_text(tune_net, &v), 0);
    const double fs = 48000;
    double peak[3] = {0, 0, 0};
    for (int mode = 0; mode < 3; mode++) {
        void *st = tl_state_new(v.cls, fs);
        int pid = tl_param_id(v.cls, "f0");
        v.cls->set_param(st, pid, mode == 2 ? 330 : 220);
        double *y = render(v.cls, st, 4800, 1, 0); /* 0.1 s of ringing */
        double **in = tl_bufs_new(1, 64), **o = tl_bufs_new(1, 64);
        double y1 = y[4798], y2 = y[4799], d2max = 0, amp = 0;
        for (int b = 0; b < 375; b++) { /* 0.5 s */
            if (mode == 0)
                v.cls->set_param(st, pid, 220 * pow(1.5, (b + 1) / 375.0));
            v.cls->process(st, (const double *const *)in, o, 64);
            for (int j = 0; j < 64; j++) {
                double d2 = o[0][j] - 2 * y2 + y1;
                d2max = fmax(d2max, fabs(d2));
                amp = fmax(amp, fabs(o[0][j]));
                y1 = y2, y2 = o[0][j];
            }
        }
        peak[mode] = d2max / amp;
        free(y);
        tl_bufs_free(in, 1);
        tl_bufs_free(o, 1);
        tl_state_free(st);
    }
    printf("largest second difference over peak amplitude: glide %.4f, held at 220 Hz %.4f, at 330 Hz %.4f\n",
           peak[0], peak[1], peak[2]);
    assert_true(peak[0] < 1.5 * fmax(peak[1], peak[2]));
    tl_voice_free(&v);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_filters_passive), cmocka_unit_test(test_tuning), cmocka_unit_test(test_tuning_reported), cmocka_unit_test(test_line_tuning),
        cmocka_unit_test(test_harmonics),
        cmocka_unit_test(test_stiffness),
        cmocka_unit_test(test_decay), cmocka_unit_test(test_tube), cmocka_unit_test(test_glide),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
