/*
 * test_partials.c - the measures of partials.h on synthetic signals whose
 * answers are known.
 *
 * Every signal is a sum of partials a exp(-ln(1000) t / t60)
 * cos(2 pi f t + phase) from t = 0, plus uniform white noise; frequencies,
 * decays, amplitudes and phases are drawn from a seeded generator
 * (tl_rng), so every run sees the same signals.  "Noise N dB down" means
 * its RMS is N dB below the amplitude of the partial measured (of the
 * weakest one in a mixture).  Asserted:
 *   - pt_cents on exact ratios (octave, semitone, unison);
 *   - single sinusoids, f 27.5 Hz to 8 kHz (log-uniform), fs 44.1, 48 or
 *     96 kHz, t60 0.3 to 30 s, 40 periods to 1.5 s of signal, noise 80 dB
 *     down, a band of half-width max(3 % of f, 3 / t60 Hz) a little off
 *     centre: pt_peak_freq within 0.05 cent;
 *   - mixtures of up to 24 harmonic or inharmonic partials
 *     (k f0 sqrt(1 + B k^2), f0 27.5 Hz to 1 kHz, B 0 or 1e-6 to 1e-3),
 *     amplitudes spread over 40 dB, t60 falling with k down to 0.3 s,
 *     noise 80 dB below the weakest, 1 to 2 s: each partial at least 3 %
 *     and 12 / t60 Hz (the shortest t60 of the three) from its
 *     neighbours, measured in the band between the midpoints to them,
 *     within 0.05 cent; its t60 (bw half the distance to the nearer
 *     neighbour, fit 3 to 33 dB below the peak) within 2 % where the
 *     signal shows at least 13 dB of the fit range, NAN where it shows
 *     less than 7 dB;
 *   - a partial between two neighbours 3 % away, 40 dB stronger and
 *     decaying six times slower: frequency and t60 as above;
 *   - single partials with t60 0.05 to 30 s (and 20 periods or more
 *     within it), 300 periods or 45 dB of decay (whichever is longer) of
 *     signal, bw f/2: t60 within 2 %; signals shorter than the fit range:
 *     within 2 % if they show 13 dB or more of it, NAN if less than 7 dB;
 *   - signals of a million samples with a low partial that lasts (t60 10
 *     to 30 s) and high ones that die out within the first seconds (0.3 to
 *     3 s): frequency and t60 as above;
 *   - noiseless steady sinusoids: within 1e-4 cent (the bin is 2 to 60
 *     cents wide);
 *   - the strongest of two partials in one band is the one found;
 *   - NAN: silence, a band between the partials of a noiseless mixture,
 *     bands that make no sense, a kernel longer than the signal, a level
 *     that does not decay.
 * The worst errors are printed.  Measured: frequency 0.007 cent (single
 * sinusoids), 0.001 cent (mixtures, strong neighbours), 3e-6 cent
 * (steady); t60 0.035 % (single partials), 0.02 % (mixtures, neighbours);
 * about 3 s in all.  Eight other seeds with three to four times the
 * trials gave at worst 0.011 cent and 0.04 %.
 *
 * Run from the repository root: build/tests/test_partials (after make).
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

#include "partials.h"
#include "testlib.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

#define CENTS_TOL 0.05
#define T60_TOL 0.02
#define MAX_PARTIALS 24
/* Skip and span of the t60 fits (dB). */
#define SKIP_DB 3.0
#define SPAN_DB 30.0

static const double rates[] = {44100.0, 48000.0, 96000.0};

typedef struct partial {
    double f, a, t60, phase;
} partial;

/* A log-uniform number in [lo, hi). */
static double log_uniform(tl_rng *r, double lo, double hi)
{
    return lo * pow(hi / lo, tl_rng_uniform(r));
}

/* n samples at fs of the partials p[0..np) plus uniform white noise of
 * RMS noise_rms (malloc'ed; fails the test if memory runs out). */
static double *render(const partial *p, int np, double fs, size_t n, double noise_rms,
                      tl_rng *r)
{
    double *x = calloc(n, sizeof *x);
    if (!x)
        fail_msg("out of memory for %zu samples", n);
    for (int k = 0; k < np; k++) {
        /* z = a e^{(-d + j w) i + j phase}, stepped by multiplication and
         * recomputed exactly every 512 samples (error near 1e-13) */
        double w = 2.0 * M_PI * p[k].f / fs, d = log(1000.0) / (p[k].t60 * fs);
        double sr = exp(-d) * cos(w), si = exp(-d) * sin(w), zr = 0.0, zi = 0.0;
        for (size_t i = 0; i < n; i++) {
            if (i % 512 == 0) {
                double e = p[k].a * exp(-d * (double)i), ph = w * (double)i + p[k].phase;
                zr = e * cos(ph);
                zi = e * sin(ph);
            }
            x[i] += zr;
            double t = zr * sr - zi * si;
            zi = zr * si + zi * sr;
            zr = t;
        }
    }
    double u = noise_rms * sqrt(3.0); /* uniform in [-u, u) has RMS u/sqrt(3) */
    if (u > 0.0)
        for (size_t i = 0; i < n; i++)
            x[i] += u * tl_rng_signed(r);
    return x;
}

/* dB of the fit range (from SKIP_DB below the peak on) that a signal of n
 * samples shows of a partial decaying from sample 0, measured with
 * half-width bw: its level is seen from half a kernel in to half a kernel
 * before the end. */
static double shown_db(size_t n, double fs, double t60, double bw)
{
    double kernel = PT_LOBE / bw;
    return 60.0 * ((double)n / fs - kernel) / t60 - SKIP_DB;
}

/* Checks pt_t60 on partial p of x against the rules of shown_db; returns
 * the relative error (0 where NAN was expected or nothing is asserted). */
static double check_t60(const double *x, size_t n, double fs, const partial *p, double bw,
                        const char *what)
{
    double shown = shown_db(n, fs, p->t60, bw);
    double t = pt_t60(x, n, fs, p->f, bw, SKIP_DB, SPAN_DB);
    if (shown < 7.0) {
        if (!isnan(t))
            fail_msg("%s: f %.3f Hz, t60 %.4f s: %.1f dB shown, expected NAN, got %.5f", what,
                     p->f, p->t60, shown, t);
        return 0.0;
    }
    if (shown < 13.0)
        return 0.0;
    double err = fabs(t / p->t60 - 1.0);
    if (!(err < T60_TOL))
        fail_msg("%s: f %.3f Hz, t60 %.4f s (fs %.0f, %zu samples, bw %.2f Hz): "
                 "measured %.5f s, error %.3f %%",
                 what, p->f, p->t60, fs, n, bw, t, 100.0 * err);
    return err;
}

/* Checks pt_peak_freq on partial p of x in [lo, hi]; returns |cents|. */
static double check_freq(const double *x, size_t n, double fs, const partial *p, double lo,
                         double hi, const char *what)
{
    double f = pt_peak_freq(x, n, fs, lo, hi);
    double c = fabs(pt_cents(f, p->f));
    if (!(c < CENTS_TOL))
        fail_msg("%s: f %.4f Hz (a %.3g, t60 %.3f s, fs %.0f, %zu samples, band %.3f to "
                 "%.3f Hz): measured %.6f Hz, %.4f cent",
                 what, p->f, p->a, p->t60, fs, n, lo, hi, f, c);
    return c;
}

/* ---- tests ---- */

static void test_cents(void **state)
{
    (void)state;
    assert_true(fabs(pt_cents(880.0, 440.0) - 1200.0) < 1e-12);
    assert_true(fabs(pt_cents(220.0, 440.0) + 1200.0) < 1e-12);
    assert_true(fabs(pt_cents(440.0 * pow(2.0, 1.0 / 12.0), 440.0) - 100.0) < 1e-9);
    assert_true(pt_cents(27.5, 27.5) == 0.0);
}

static void test_single_freq(void **state)
{
    (void)state;
    tl_rng r;
    tl_rng_seed(&r, tl_hash_str("single_freq"));
    double worst = 0.0;
    for (int trial = 0; trial < 80; trial++) {
        double fs = rates[tl_rng_next(&r) % 3];
        partial p;
        p.f = log_uniform(&r, 27.5, 8000.0);
        p.a = log_uniform(&r, 0.01, 1.0);
        p.t60 = log_uniform(&r, 0.3, 30.0);
        p.phase = 2.0 * M_PI * tl_rng_uniform(&r);
        double dur = log_uniform(&r, 40.0 / p.f, fmax(1.5, 40.0 / p.f));
        size_t n = (size_t)(dur * fs);
        double *x = render(&p, 1, fs, n, 1e-4 * p.a, &r);
        double hw = fmax(0.03 * p.f, 3.0 / p.t60);
        double lo = p.f - hw * (1.0 + 0.25 * tl_rng_signed(&r));
        double hi = p.f + hw * (1.0 + 0.25 * tl_rng_signed(&r));
        worst = fmax(worst, check_freq(x, n, fs, &p, lo, hi, "single"));
        free(x);
    }
    print_message("single sinusoids: worst frequency error %.5f cent\n", worst);
}

/* A harmonic (B = 0) or inharmonic mixture of up to MAX_PARTIALS partials
 * below min(0.45 fs, 10 kHz). */
static int make_mixture(tl_rng *r, double fs, partial *p)
{
    double f0 = log_uniform(r, 27.5, 1000.0);
    double B = tl_rng_uniform(r) < 0.5 ? 0.0 : log_uniform(r, 1e-6, 1e-3);
    double t1 = log_uniform(r, 1.0, 20.0), c = tl_rng_uniform(r);
    int np = 0;
    for (int k = 1; k <= MAX_PARTIALS; k++) {
        double f = k * f0 * sqrt(1.0 + B * k * k);
        if (f > 0.45 * fs || f > 10000.0)
            break;
        p[np].f = f;
        p[np].a = pow(10.0, -2.0 * tl_rng_uniform(r)); /* 0 to -40 dB */
        p[np].t60 = fmax(0.3, t1 / (1.0 + c * k));
        p[np].phase = 2.0 * M_PI * tl_rng_uniform(r);
        np++;
    }
    return np;
}

static void test_mixtures(void **state)
{
    (void)state;
    tl_rng r;
    tl_rng_seed(&r, tl_hash_str("mixtures"));
    double worst_c = 0.0, worst_t = 0.0;
    int nf = 0, nt = 0;
    for (int trial = 0; trial < 8; trial++) {
        double fs = rates[tl_rng_next(&r) % 3];
        partial p[MAX_PARTIALS];
        int np = make_mixture(&r, fs, p);
        double amin = 1.0;
        for (int k = 0; k < np; k++)
            amin = fmin(amin, p[k].a);
        double dur = log_uniform(&r, 1.0, 2.0);
        size_t n = (size_t)(dur * fs);
        double *x = render(p, np, fs, n, 1e-4 * amin, &r);
        for (int k = 0; k < np; k++) {
            double below = k ? p[k - 1].f : 0.0;
            double above = k + 1 < np ? p[k + 1].f : 2.0 * p[k].f - below;
            double gap = fmin(p[k].f - below, above - p[k].f);
            double t60 = p[k].t60; /* the shortest t60 of it and its neighbours */
            if (k > 0)
                t60 = fmin(t60, p[k - 1].t60);
            if (k + 1 < np)
                t60 = fmin(t60, p[k + 1].t60);
            if (gap < 0.03 * p[k].f || gap * t60 < 12.0)
                continue;
            double lo = 0.5 * (below + p[k].f), hi = 0.5 * (p[k].f + above);
            worst_c = fmax(worst_c, check_freq(x, n, fs, &p[k], lo, hi, "mixture"));
            worst_t = fmax(worst_t, check_t60(x, n, fs, &p[k], 0.5 * gap, "mixture"));
            nf++;
            nt += shown_db(n, fs, p[k].t60, 0.5 * gap) >= 13.0;
        }
        free(x);
    }
    print_message("mixtures: %d frequencies, worst error %.5f cent; %d t60s, worst error "
                  "%.4f %%\n",
                  nf, worst_c, nt, 100.0 * worst_t);
    assert_true(nf > 50 && nt > 30);
}

static void test_strong_neighbours(void **state)
{
    (void)state;
    tl_rng r;
    tl_rng_seed(&r, tl_hash_str("strong_neighbours"));
    double worst_c = 0.0, worst_t = 0.0;
    for (int trial = 0; trial < 6; trial++) {
        double fs = rates[tl_rng_next(&r) % 3];
        double f = log_uniform(&r, 1000.0, 8000.0);
        partial p[3] = {
            {f, 0.01, 0.5, 2.0 * M_PI * tl_rng_uniform(&r)},
            {f / 1.03, 1.0, 3.0, 2.0 * M_PI * tl_rng_uniform(&r)},
            {f * 1.03, 1.0, 3.0, 2.0 * M_PI * tl_rng_uniform(&r)},
        };
        size_t n = (size_t)fs;
        double *x = render(p, 3, fs, n, 1e-6, &r);
        double lo = 0.5 * (p[0].f + p[1].f), hi = 0.5 * (p[0].f + p[2].f);
        worst_c = fmax(worst_c, check_freq(x, n, fs, &p[0], lo, hi, "neighbours"));
        worst_t = fmax(worst_t,
                       check_t60(x, n, fs, &p[0], 0.5 * (p[0].f - p[1].f), "neighbours"));
        free(x);
    }
    print_message("strong neighbours: worst errors %.5f cent, %.4f %%\n", worst_c,
                  100.0 * worst_t);
}

static void test_t60_single(void **state)
{
    (void)state;
    tl_rng r;
    tl_rng_seed(&r, tl_hash_str("t60_single"));
    double worst = 0.0;
    int nshort = 0;
    for (int trial = 0; trial < 60; trial++) {
        double fs = rates[tl_rng_next(&r) % 3];
        partial p;
        /* at least 20 periods within t60, so that a band of f/2 sees it */
        do {
            p.f = log_uniform(&r, 27.5, 8000.0);
            p.t60 = log_uniform(&r, 0.05, 30.0);
        } while (p.f * p.t60 < 20.0);
        p.a = log_uniform(&r, 0.01, 1.0);
        p.phase = 2.0 * M_PI * tl_rng_uniform(&r);
        double bw = 0.5 * p.f, kernel = PT_LOBE / bw;
        double dur = fmax(300.0 / p.f, 0.75 * p.t60) + kernel;
        if (trial % 3 == 2) {
            /* shorter than the fit range: 4 to 25 dB of it */
            dur = kernel + (SKIP_DB + log_uniform(&r, 4.0, 25.0)) * p.t60 / 60.0;
            nshort++;
        }
        size_t n = (size_t)(dur * fs);
        double *x = render(&p, 1, fs, n, 1e-4 * p.a, &r);
        worst = fmax(worst, check_t60(x, n, fs, &p, bw, "t60"));
        free(x);
    }
    print_message("single partials: worst t60 error %.4f %% (%d short signals)\n",
                  100.0 * worst, nshort);
}

/* Signals of a million samples (20.8 s at 48 kHz): a low partial that
 * lasts, and high ones that die out within the first second or three. */
static void test_long_signals(void **state)
{
    (void)state;
    tl_rng r;
    tl_rng_seed(&r, tl_hash_str("long_signals"));
    double fs = 48000.0, worst_c = 0.0, worst_t = 0.0;
    size_t n = 1000000;
    for (int trial = 0; trial < 2; trial++) {
        partial p[3] = {
            {log_uniform(&r, 40.0, 200.0), 1.0, log_uniform(&r, 10.0, 30.0), 1.0},
            {log_uniform(&r, 1000.0, 4000.0), 0.1, log_uniform(&r, 0.3, 1.0), 2.0},
            {log_uniform(&r, 5000.0, 8000.0), 0.03, log_uniform(&r, 0.3, 3.0), 3.0},
        };
        double *x = render(p, 3, fs, n, 1e-4 * 0.03, &r);
        for (int k = 0; k < 3; k++) {
            double hw = k ? 0.05 * p[k].f : 0.5 * p[k].f;
            worst_c = fmax(worst_c,
                           check_freq(x, n, fs, &p[k], p[k].f - hw, p[k].f + hw, "long"));
            worst_t = fmax(worst_t, check_t60(x, n, fs, &p[k], hw, "long"));
        }
        free(x);
    }
    print_message("long signals: worst errors %.5f cent, %.4f %%\n", worst_c, 100.0 * worst_t);
}

/* Noiseless steady sinusoids: the refinement goes far below the bin
 * spacing (1 Hz here, 2 to 60 cents), to the rounding of the sums. */
static void test_steady(void **state)
{
    (void)state;
    tl_rng r;
    tl_rng_seed(&r, tl_hash_str("steady"));
    double fs = 48000.0, worst = 0.0;
    size_t n = 48000;
    for (int trial = 0; trial < 20; trial++) {
        partial p = {log_uniform(&r, 27.5, 8000.0), 1.0, 1e12, 2.0 * M_PI * tl_rng_uniform(&r)};
        double *x = render(&p, 1, fs, n, 0.0, &r);
        double f = pt_peak_freq(x, n, fs, 0.9 * p.f, 1.1 * p.f);
        double c = fabs(pt_cents(f, p.f));
        if (!(c < 1e-4))
            fail_msg("steady: f %.6f Hz measured %.9f Hz, %.3g cent", p.f, f, c);
        worst = fmax(worst, c);
        free(x);
    }
    print_message("steady sinusoids: worst frequency error %.3g cent\n", worst);
}

static void test_strongest_in_band(void **state)
{
    (void)state;
    tl_rng r;
    tl_rng_seed(&r, tl_hash_str("strongest_in_band"));
    double fs = 48000.0;
    size_t n = 48000;
    partial p[2] = {{440.0, 0.3, 2.0, 0.1}, {523.0, 1.0, 1.0, 0.7}};
    double *x = render(p, 2, fs, n, 1e-6, &r);
    double f = pt_peak_freq(x, n, fs, 300.0, 700.0);
    assert_true(fabs(pt_cents(f, 523.0)) < CENTS_TOL);
    p[0].a = 3.0;
    free(x);
    x = render(p, 2, fs, n, 1e-6, &r);
    f = pt_peak_freq(x, n, fs, 300.0, 700.0);
    assert_true(fabs(pt_cents(f, 440.0)) < CENTS_TOL);
    free(x);
}

static void test_nan(void **state)
{
    (void)state;
    tl_rng r;
    tl_rng_seed(&r, tl_hash_str("nan"));
    double fs = 48000.0;
    size_t n = 48000;
    double *zero = calloc(n, sizeof *zero);
    assert_non_null(zero);
    assert_true(isnan(pt_peak_freq(zero, n, fs, 100.0, 200.0)));
    assert_true(isnan(pt_t60(zero, n, fs, 150.0, 20.0, SKIP_DB, SPAN_DB)));
    free(zero);

    /* noiseless harmonics of 200 Hz: nothing between them */
    partial p[8];
    for (int k = 0; k < 8; k++)
        p[k] = (partial){200.0 * (k + 1), 1.0 / (k + 1), 2.0, 0.3 * k};
    double *x = render(p, 8, fs, n, 0.0, &r);
    assert_true(isnan(pt_peak_freq(x, n, fs, 230.0, 370.0)));
    assert_true(isnan(pt_peak_freq(x, n, fs, 1650.0, 1750.0)));
    assert_true(isnan(pt_peak_freq(x, n, fs, 2000.0, 1000.0)));   /* f_lo > f_hi */
    assert_true(isnan(pt_peak_freq(x, n, fs, 30000.0, 40000.0))); /* above fs/2 */
    assert_true(isnan(pt_peak_freq(x, 15, fs, 100.0, 300.0)));    /* too short */
    /* ... while the partials themselves are found */
    assert_true(fabs(pt_cents(pt_peak_freq(x, n, fs, 300.0, 500.0), 400.0)) < CENTS_TOL);
    assert_true(isnan(pt_t60(x, n, fs, 400.0, 0.5, SKIP_DB, SPAN_DB))); /* kernel > n */
    assert_true(isnan(pt_t60(x, n, fs, 400.0, -1.0, SKIP_DB, SPAN_DB)));
    assert_true(isnan(pt_t60(x, n, fs, 0.0, 100.0, SKIP_DB, SPAN_DB)));
    free(x);

    /* a partial that does not decay (t60 1e6 s) */
    partial s = {1000.0, 1.0, 1e6, 0.0};
    x = render(&s, 1, fs, n, 1e-6, &r);
    assert_true(isnan(pt_t60(x, n, fs, 1000.0, 100.0, SKIP_DB, SPAN_DB)));
    assert_true(fabs(pt_cents(pt_peak_freq(x, n, fs, 900.0, 1100.0), 1000.0)) < 1e-4);
    free(x);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_cents),
        cmocka_unit_test(test_single_freq),
        cmocka_unit_test(test_mixtures),
        cmocka_unit_test(test_strong_neighbours),
        cmocka_unit_test(test_t60_single),
        cmocka_unit_test(test_long_signals),
        cmocka_unit_test(test_steady),
        cmocka_unit_test(test_strongest_in_band),
        cmocka_unit_test(test_nan),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
