/*
 * test_surf.c - surfaces, contacts, impacts and modal resonators
 * (runtime/surf.h), measured from renders against the laws the header
 * states: mode frequencies (spectral peaks) and T60s (band-passed decay)
 * and the resonator's response against its closed form; the impact pulse's
 * width against pi sqrt(m/k) with k = (1/g1 + 1/g2)^-1 (its second moment)
 * and its integral against the impulse; harder pairs brighter (spectral
 * centroid); skid lengths against min(|vt|/decel, 2 h/|vn|) and their
 * clamps; the contact's low-pass corner (-3 dB of its output's spectrum
 * over a white relief) against the slip law, and its force scaling; contact
 * damping accumulating, capped and lifted (decay rates of a single mode,
 * from the log of its energy); pools refusing cleanly with their counts
 * kept; sleep changing nothing before its fade, and waking; a resonator
 * shared by two bodies summing them (linearity); the loudest modes kept
 * under a limit; quiet contacts costing nothing; the .modes reader and its
 * errors; no allocation in the real-time calls.  Measured figures are
 * printed so they can be quoted.
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
#include "surf.h"
#include "testlib.h"

#include "countalloc.h"

#define PI 3.14159265358979323846
#define FS 48000.0
#define LN1000 6.90775527898213705205

static char g_dir[64];

static int setup(void **s) {
    (void)s;
    return tl_temp_dir(g_dir, "wdrt-surf");
}

static int teardown(void **s) {
    (void)s;
    tl_remove_dir(g_dir);
    return 0;
}

/* ---- building worlds ---- */

static surf_world *world_new(const surf_config *c) {
    surf_world *w = NULL;
    assert_int_equal(surf_init(c, NULL, &w), WDRT_OK);
    assert_non_null(w);
    return w;
}

/* A resonator of n modes (one pickup) with quiet level `quiet`. */
static int add_res(surf_world *w, const surf_mode *m, int n, double quiet) {
    surf_resonator_desc d = surf_resonator_desc_init();
    d.modes = m;
    d.nmodes = n;
    d.quiet = quiet;
    int r = surf_add_resonator(w, &d);
    assert_true(r >= 0);
    return r;
}

/* A smooth surface of the given hardness that makes no skid; its
 * generators route `direct` to the direct channel, contacts and impacts
 * alike. */
static surf_surface_desc smooth(double hardness, double direct) {
    surf_surface_desc d = surf_surface_desc_init();
    d.hardness = hardness;
    d.relief.kind = SURF_RELIEF_NONE;
    d.skid_gain = 0;
    d.contact.direct = d.impact.direct = direct;
    return d;
}

static int add_surf(surf_world *w, const surf_surface_desc *d) {
    int s = surf_add_surface(w, d);
    assert_true(s >= 0);
    return s;
}

static int add_body(surf_world *w, int res, int surf, double mass) {
    surf_body_desc d = {res, surf, mass};
    int b = surf_add_body(w, &d);
    assert_true(b >= 0);
    return b;
}

static surf_mode mode(double f, double t60, double g) {
    surf_mode m;
    memset(&m, 0, sizeof m);
    m.f = f, m.t60 = t60, m.gain[0] = g;
    return m;
}

static void impact(surf_world *w, long offset, int a, int b, double J, double vn, double vt) {
    surf_impact_data d = {J, vn, vt};
    assert_int_equal(surf_impact(w, offset, a, b, &d), WDRT_OK);
}

/* Renders n frames in calls of `chunk` frames: the mix into mix (if not
 * NULL), channel ch of resonator res into out (if not NULL; zeros while
 * that channel is silent). */
static void render(surf_world *w, long n, int chunk, double *mix, int res, int ch, double *out) {
    for (long t = 0; t < n;) {
        int want = (int)(n - t < chunk ? n - t : chunk);
        assert_int_equal(surf_process(w, mix ? mix + t : NULL, want), want);
        if (out) {
            const double *x = surf_output(w, res, ch);
            for (int j = 0; j < want; j++)
                out[t + j] = x ? x[j] : 0;
        }
        t += want;
    }
}

static double *zeros(long n) {
    double *x = calloc((size_t)n, sizeof *x);
    assert_non_null(x);
    return x;
}

/* ---- measures ---- */

/* In-place radix-2 FFT of re + i im (n a power of two). */
static void fft(double *re, double *im, long n) {
    for (long i = 1, j = 0; i < n; i++) {
        long bit = n >> 1;
        for (; j & bit; bit >>= 1)
            j ^= bit;
        j ^= bit;
        if (i < j) {
            double t = re[i];
            re[i] = re[j], re[j] = t;
            t = im[i], im[i] = im[j], im[j] = t;
        }
    }
    double *tc = zeros(n / 2 + 1), *ts = zeros(n / 2 + 1);
    for (long k = 0; k < n / 2; k++)
        tc[k] = cos(-2 * PI * (double)k / (double)n), ts[k] = sin(-2 * PI * (double)k / (double)n);
    for (long len = 2; len <= n; len <<= 1) {
        for (long i = 0; i < n; i += len)
            for (long k = 0; k < len / 2; k++) {
                double c = tc[k * (n / len)], s = ts[k * (n / len)];
                double *ur = &re[i + k], *ui = &im[i + k], *vr = &re[i + k + len / 2], *vi = &im[i + k + len / 2];
                double tr = *vr * c - *vi * s, ti = *vr * s + *vi * c;
                *vr = *ur - tr, *vi = *ui - ti;
                *ur += tr, *ui += ti;
            }
    }
    free(tc), free(ts);
}

/* Welch's estimate of x[0..n)'s power per bin (nfft/2 + 1 bins, Hann
 * windows overlapping by half), scaled so white noise of variance v reads v
 * in every bin. */
static void welch(const double *x, long n, long nfft, double *psd) {
    double *re = zeros(nfft), *im = zeros(nfft), w2 = 0;
    for (long i = 0; i < nfft; i++) {
        double w = 0.5 - 0.5 * cos(2 * PI * (double)i / (double)nfft);
        w2 += w * w;
    }
    memset(psd, 0, (size_t)(nfft / 2 + 1) * sizeof *psd);
    long segs = 0;
    for (long s = 0; s + nfft <= n; s += nfft / 2, segs++) {
        for (long i = 0; i < nfft; i++) {
            re[i] = x[s + i] * (0.5 - 0.5 * cos(2 * PI * (double)i / (double)nfft));
            im[i] = 0;
        }
        fft(re, im, nfft);
        for (long k = 0; k <= nfft / 2; k++)
            psd[k] += (re[k] * re[k] + im[k] * im[k]) / w2;
    }
    for (long k = 0; k <= nfft / 2; k++)
        psd[k] /= (double)segs;
    free(re), free(im);
}

/* The frequency (Hz) where psd, smoothed over 2 h + 1 bins, first falls
 * below `level` above bin k0, interpolated linearly in dB. */
static double crossing(const double *psd, long nfft, double fs, long k0, int h, double level) {
    long nb = nfft / 2 + 1;
    double prev = NAN;
    for (long k = k0; k + h < nb; k++) {
        double s = 0;
        for (long j = k - h; j <= k + h; j++)
            s += psd[j];
        s /= 2 * h + 1;
        if (s < level && k > k0) {
            double a = 10 * log10(prev / level), b = 10 * log10(s / level);
            return ((double)(k - 1) + a / (a - b)) * fs / (double)nfft;
        }
        prev = s;
    }
    return NAN;
}

/* Spectral centroid (Hz) of x[0..n) (n a power of two). */
static double centroid(const double *x, long n, double fs) {
    double *re = zeros(n), *im = zeros(n), num = 0, den = 0;
    memcpy(re, x, (size_t)n * sizeof *re);
    fft(re, im, n);
    for (long k = 0; k <= n / 2; k++) {
        double p = re[k] * re[k] + im[k] * im[k];
        num += p * (double)k * fs / (double)n;
        den += p;
    }
    free(re), free(im);
    return num / den;
}

/* The decay rate (1/s) of one exponentially decaying sinusoid in x[a..b):
 * for x[n] = A r^n sin(w n + phi), x[n]^2 - x[n-1] x[n+1] = A^2 sin^2(w)
 * r^(2n) exactly, so the slope of its log is 2 ln r = -2 sigma / fs (a
 * least-squares line). */
static double decay_rate(const double *x, long a, long b, double fs) {
    double sn = 0, st = 0, stt = 0, sy = 0, sty = 0;
    for (long n = a + 1; n + 1 < b; n++) {
        double e = x[n] * x[n] - x[n - 1] * x[n + 1];
        if (!(e > 0))
            continue;
        double t = (double)n / fs, y = log(e);
        sn += 1, st += t, stt += t * t, sy += y, sty += t * y;
    }
    double slope = (sn * sty - st * sy) / (sn * stt - st * st);
    return -slope / 2;
}

/* The pulse's length tau (samples) from its second moment: a half-sine of
 * length tau has variance tau^2 (1/4 - 2/pi^2); sampling as means over
 * samples adds 1/12 (Sheppard's correction), taken off. */
static double pulse_tau(const double *x, long n) {
    double s0 = 0, s1 = 0, s2 = 0;
    for (long i = 0; i < n; i++) {
        double t = (double)i + 0.5;
        s0 += x[i], s1 += t * x[i], s2 += t * t * x[i];
    }
    double m = s1 / s0, var = s2 / s0 - m * m - 1.0 / 12;
    return sqrt(var / (0.25 - 2 / (PI * PI)));
}

static long last_nonzero(const double *x, long n) {
    long L = -1;
    for (long i = 0; i < n; i++)
        if (x[i] != 0)
            L = i;
    return L;
}

/* ---- modal resonators ---- */

static const char g_bar[] = "; a test bar: F T60 GAIN\n"
                            "220     2.0   1.0    ; fundamental\n"
                            "347.5   1.5   0.8\n"
                            "\n"
                            "611.0   1.0   -0.6\n"
                            "1234.5  0.8   0.5\n"
                            "2900    0.5   0.4\n"
                            "6100    0.3   0.3\n"
                            "30000   0.1   1.0    ; above fs/2 at 48 kHz: left out\n";

/* A resonator from a .modes file struck by an impulse: its render against
 * the closed form sum g J e^{-s t} sin(2 pi F t), the frequencies of its
 * spectral peaks within 0.1 %, the T60s of its band-passed modes within 3 %. */
static void test_modes_ring_true(void **s) {
    (void)s;
    surf_mode m[8];
    int np = -1;
    char err[512];
    const char *path = tl_write_file(g_dir, "bar.modes", g_bar);
    int n = surf_modes_read(path, m, 8, &np, err, sizeof err);
    assert_int_equal(n, 7);
    assert_int_equal(np, 1);
    surf_config c = surf_config_init(FS);
    c.max_modes = 8;
    surf_world *w = world_new(&c);
    int r = add_res(w, m, n, 0), r0 = add_res(w, NULL, 0, 0);
    assert_int_equal(surf_resonator_modes(w, r), 6);
    surf_surface_desc sd = smooth(INFINITY, 0);
    int sf = add_surf(w, &sd);
    int bar = add_body(w, r, sf, 0.2), floor = add_body(w, r0, sf, INFINITY);
    const double J = 0.01;
    impact(w, 0, bar, floor, J, 1, 0);
    long N = (long)(3 * FS);
    double *x = zeros(N);
    render(w, N, 256, NULL, r, 0, x);
    double worst = 0;
    for (long i = 0; i < 4800; i++) {
        double y = 0, t = (double)i / FS;
        for (int k = 0; k < 6; k++)
            y += m[k].gain[0] * J * exp(-LN1000 / m[k].t60 * t) * sin(2 * PI * m[k].f * t);
        worst = fmax(worst, fabs(x[i] - y));
    }
    printf("  closed form: worst error %.3g (peak ~%.3g) over the first 0.1 s\n", worst, J * 3.6);
    assert_true(worst < 1e-12);
    for (int k = 0; k < 6; k++) {
        double f = pt_peak_freq(x, (size_t)N, FS, 0.97 * m[k].f, 1.03 * m[k].f);
        double bw = m[k].f < 1000 ? 50 : 100;
        double t60 = pt_t60(x, (size_t)N, FS, m[k].f, bw, 3, 30);
        double ef = (f - m[k].f) / m[k].f, et = (t60 - m[k].t60) / m[k].t60;
        printf("  mode %7.1f Hz T60 %.2f s: peak %.4f Hz (error %+.2e), T60 %.5f s (error %+.3f %%)\n", m[k].f,
               m[k].t60, f, ef, t60, 100 * et);
        assert_true(fabs(ef) < 1e-3);
        assert_true(fabs(et) < 0.03);
    }
    free(x);
    surf_uninit(w, NULL);
}

/* A single mode's decay rate measured exactly (the log of its energy)
 * at three rates: s = ln 1000 / T60 whatever fs. */
static void test_mode_decay_exact(void **s) {
    (void)s;
    const double rates[] = {22050, 48000, 96000};
    for (int q = 0; q < 3; q++) {
        surf_config c = surf_config_init(rates[q]);
        surf_world *w = world_new(&c);
        surf_mode m = mode(777, 0.7, 1);
        int r = add_res(w, &m, 1, 0), r0 = add_res(w, NULL, 0, 0);
        surf_surface_desc sd = smooth(INFINITY, 0);
        int sf = add_surf(w, &sd);
        int a = add_body(w, r, sf, 1), b = add_body(w, r0, sf, INFINITY);
        impact(w, 0, a, b, 1, 1, 0);
        long N = (long)rates[q];
        double *x = zeros(N);
        render(w, N, 256, NULL, r, 0, x);
        double sig = decay_rate(x, 10, N, rates[q]), t60 = LN1000 / sig;
        printf("  %6.0f Hz: T60 %.9f s (error %+.2e)\n", rates[q], t60, (t60 - 0.7) / 0.7);
        assert_true(fabs(t60 - 0.7) / 0.7 < 1e-6);
        free(x);
        surf_uninit(w, NULL);
    }
}

static void expect_error(const char *text, int max, const char *want) {
    surf_mode m[4];
    char err[512];
    int np;
    int n = surf_modes_parse("t.modes", text, strlen(text), max ? m : NULL, max, &np, err, sizeof err);
    if (n != -1 || strncmp(err, want, strlen(want)) != 0 || !strchr(err, '^'))
        print_error("text %s\n got %d: %s\n want %s\n", text, n, err, want);
    assert_int_equal(n, -1);
    assert_true(strncmp(err, want, strlen(want)) == 0);
    assert_non_null(strchr(err, '^'));
}

/* The reader: comments, blank lines, CRLF, several gains, counting
 * without storing; every error at its line and column, with the line and
 * a caret. */
static void test_modes_reader(void **s) {
    (void)s;
    surf_mode m[4];
    char err[512];
    int np = 0;
    const char *ok = "  ; only words\r\n100 1 0.5 -0.25\r\n\r\n 2e3\t0.5 1 2 ; two pickups\n";
    assert_int_equal(surf_modes_parse("ok.modes", ok, strlen(ok), m, 4, &np, err, sizeof err), 2);
    assert_int_equal(np, 2);
    assert_true(m[1].f == 2000 && m[1].t60 == 0.5 && m[0].gain[1] == -0.25 && m[1].gain[1] == 2);
    assert_int_equal(surf_modes_parse("ok.modes", ok, strlen(ok), NULL, 0, &np, err, sizeof err), 2);
    assert_int_equal(surf_modes_parse("e.modes", "; none\n\n", 8, m, 4, &np, err, sizeof err), 0);
    assert_int_equal(np, 0);
    expect_error("220 1 0.5\n440 x 0.2\n", 4, "t.modes:2:5: error: expected a number, found 'x'");
    expect_error("220 1 nan\n", 4, "t.modes:1:7: error: expected a number, found 'nan'");
    expect_error("220 0 1\n", 4, "t.modes:1:5: error: the T60 must be positive (s)");
    expect_error("  -3 1 1\n", 4, "t.modes:1:3: error: the frequency must be positive (Hz)");
    expect_error("100 1 1 2\n\n200 1 1\n", 4, "t.modes:3:7: error: expected 2 gains, as on line 1, found 1");
    expect_error("100 1\n", 4, "t.modes:1:1: error: a mode needs a frequency, a T60 and at least one gain");
    expect_error("1 1 1 2 3 4 5 6 7 8 9\n", 4, "t.modes:1:21: error: too many gains: at most 8 pickups");
    expect_error("1 1 1\n2 1 1\n3 1 1\n4 1 1\n5 1 1\n", 4, "t.modes:5:1: error: more than 4 modes");
    expect_error("1 1 1;\n2 1 1x\n", 4, "t.modes:2:5: error: expected a number, found '1x'");
    int r = surf_modes_read("/nonexistent/x.modes", m, 4, &np, err, sizeof err);
    assert_int_equal(r, -1);
    assert_non_null(strstr(err, "/nonexistent/x.modes: error: cannot read: "));
    printf("  e.g. %s", err);
    expect_error("100 1 1\n200 -1 1\n", 4, "t.modes:2:5: error");
    (void)surf_modes_parse("t.modes", "100 1 1\n200 -1 1\n", 18, m, 4, &np, err, sizeof err);
    printf("  e.g. %s", err);
}

/* ---- impacts ---- */

/* A world of two bodies with their own empty resonators, the direct
 * channel of each hearing its surface's excitation as it is. */
typedef struct pair {
    surf_world *w;
    int ra, rb, a, b;
} pair;

static pair pair_new(const surf_surface_desc *sa, const surf_surface_desc *sb, double ma, double mb, int block) {
    surf_config c = surf_config_init(FS);
    c.block = block;
    c.relief_frames = 1 << 19;
    pair p;
    p.w = world_new(&c);
    p.ra = add_res(p.w, NULL, 0, 0);
    p.rb = add_res(p.w, NULL, 0, 0);
    int s1 = add_surf(p.w, sa), s2 = add_surf(p.w, sb);
    p.a = add_body(p.w, p.ra, s1, ma);
    p.b = add_body(p.w, p.rb, s2, mb);
    return p;
}

/* The pulse's width against pi sqrt(m/k), k = (1/ga + 1/gb)^-1,
 * m = (1/ma + 1/mb)^-1, from its second moment. */
static void test_pulse_width(void **s) {
    (void)s;
    const struct {
        double ga, gb, ma, mb;
    } cases[] = {{1e6, 1e6, 0.1, INFINITY}, {1e6, 3e6, 0.05, 0.05}, {1e7, INFINITY, 0.2, 0.3},
                 {2e5, 1e8, 1, INFINITY},   {5e7, 5e7, 0.01, 0.02}};
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        surf_surface_desc sa = smooth(cases[i].ga, 1), sb = smooth(cases[i].gb, 1);
        pair p = pair_new(&sa, &sb, cases[i].ma, cases[i].mb, 256);
        double k = 1 / (1 / cases[i].ga + 1 / cases[i].gb), m = 1 / (1 / cases[i].ma + 1 / cases[i].mb);
        double tau = PI * sqrt(m / k);
        assert_true(fabs(surf_pulse_width(p.w, p.a, p.b) - tau) <= 1e-15 * tau);
        impact(p.w, 37, p.a, p.b, 0.02, 1, 0);
        long N = 2048;
        double *x = zeros(N), *y = zeros(N);
        render(p.w, N, 256, NULL, p.ra, SURF_DIRECT, x);
        double got = pulse_tau(x + 37, N - 37) / FS;
        long L = last_nonzero(x, N) - 37 + 1;
        printf("  k %.3g N/m, m %.3g kg: tau %.5f ms, measured %.5f ms (error %+.2e), %ld samples\n", k, m,
               1e3 * tau, 1e3 * got, (got - tau) / tau, L);
        /* Sheppard's correction is exact only in the limit of many samples */
        assert_true(fabs(got - tau) / tau < (tau * FS > 10 ? 1e-4 : 1e-2));
        assert_int_equal(L, (long)ceil(tau * FS));
        free(x), free(y);
        surf_uninit(p.w, NULL);
    }
}

/* The pulse's integral is the impulse, for pulses from a fraction of a
 * sample to several blocks, at offsets across block boundaries, in calls
 * of odd lengths. */
static void test_pulse_integral(void **s) {
    (void)s;
    const double J[] = {1e-4, 0.01, 3};
    const double gam[] = {INFINITY, 1e9, 3e7, 1e6, 1e4};
    const long off[] = {0, 99, 255, 256, 1000};
    double worst = 0;
    for (int i = 0; i < 3; i++)
        for (int g = 0; g < 5; g++) {
            surf_surface_desc sd = smooth(gam[g], 1);
            pair p = pair_new(&sd, &sd, 0.05, INFINITY, 256);
            double T = surf_pulse_width(p.w, p.a, p.b) * FS;
            long N = 1000 + (long)T + 300;
            double *x = zeros(N);
            impact(p.w, off[(i + g) % 5], p.a, p.b, J[i], 1, 0);
            render(p.w, N, 100, NULL, p.ra, SURF_DIRECT, x);
            double sum = 0;
            for (long k = 0; k < N; k++)
                sum += x[k];
            double e = fabs(sum / FS - J[i]) / J[i];
            worst = fmax(worst, e);
            if (e > 1e-12)
                print_error("J %g T %g samples: integral %.17g\n", J[i], T, sum / FS);
            assert_true(e <= 1e-12);
            free(x);
            surf_uninit(p.w, NULL);
        }
    printf("  pulse integral vs impulse: worst relative error %.2e over 15 pulses of 0 to %.0f samples\n", worst,
           PI * sqrt(0.05 / 5e3) * FS);
}

/* A harder pair sounds brighter: the same blow through a resonator of 40
 * equal modes from 150 Hz to 15 kHz, soft (k = 1e5 N/m) and hard (1e7). */
static void test_harder_brighter(void **s) {
    (void)s;
    surf_mode m[40];
    for (int k = 0; k < 40; k++)
        m[k] = mode(150 * pow(100, k / 39.0), 0.3, 1);
    double cen[2], tau[2];
    for (int h = 0; h < 2; h++) {
        surf_config c = surf_config_init(FS);
        c.max_modes = 40;
        surf_world *w = world_new(&c);
        int r = add_res(w, m, 40, 0), r0 = add_res(w, NULL, 0, 0);
        surf_surface_desc sd = smooth(h ? 2e7 : 2e5, 0);
        int sf = add_surf(w, &sd);
        int a = add_body(w, r, sf, 0.05), b = add_body(w, r0, sf, INFINITY);
        tau[h] = surf_pulse_width(w, a, b);
        impact(w, 0, a, b, 0.01, 1, 0);
        long N = 16384;
        double *x = zeros(N);
        render(w, N, 256, NULL, r, 0, x);
        cen[h] = centroid(x, N, FS);
        free(x);
        surf_uninit(w, NULL);
    }
    printf("  centroid: soft (tau %.3f ms) %.0f Hz, hard (tau %.3f ms) %.0f Hz\n", 1e3 * tau[0], cen[0],
           1e3 * tau[1], cen[1]);
    assert_true(cen[1] > 2 * cen[0]);
}

/* Skids: the last sound of a skid against T = min(|vt|/decel, 2 h/|vn|),
 * clamped to [min, max], to the sample (the skid's force falls linearly to
 * zero at T). */
static void test_skid_length(void **s) {
    (void)s;
    const struct {
        double decel, h, tmin, tmax, vn, vt, want;
    } cases[] = {
        {20, 0, 0, 0.2, 1, 0.5, 0.025},       {20, 0, 0, 0.2, 1, 1, 0.05},
        {20, 0, 0, 0.2, 1, 2, 0.1},           {20, 0, 0, 0.2, 1, 10, 0.2},          /* clamped */
        {0, 1e-3, 0, 0.2, 0.1, 1, 0.02},      {0, 1e-3, 0, 0.2, 0.02, 1, 0.1},      /* grazing: longer */
        {0, 1e-3, 0, 0.2, 1, 1, 0.002},       {20, 1e-3, 0, 0.2, 0.02, 1, 0.05},    /* both: the shorter */
        {20, 1e-3, 0.01, 0.2, 1, 1, 0.01},    {0, 0, 0.01, 0.15, 1, 1, 0.15},       /* min; neither: max */
        {20, 1e-3, 0, 0.2, 1, 0, 0},                                                 /* no slide, no skid */
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        surf_surface_desc sa = smooth(INFINITY, 1), sb = smooth(INFINITY, 1);
        sa.relief.kind = SURF_RELIEF_NOISE;
        sa.skid_gain = 1;
        sa.skid_decel = cases[i].decel;
        sa.skid_thickness = cases[i].h;
        sa.skid_min = cases[i].tmin;
        sa.skid_max = cases[i].tmax;
        pair p = pair_new(&sa, &sb, 0.1, INFINITY, 256);
        surf_impact_data d = {0.01, cases[i].vn, cases[i].vt};
        double T = surf_skid_time(p.w, 0, &d);
        assert_true(fabs(T - cases[i].want) < 1e-12);
        impact(p.w, 0, p.a, p.b, 0.01, cases[i].vn, cases[i].vt);
        long N = (long)(0.3 * FS);
        double *x = zeros(N);
        render(p.w, N, 256, NULL, p.ra, SURF_DIRECT, x);
        long L = last_nonzero(x, N) + 1;
        long want = T > 0 ? (long)ceil(T * FS) : 1; /* the pulse alone is one sample */
        printf("  vn %4.2f vt %4.1f decel %2.0f h %.0e [%.2f, %.2f]: T %.4f s, sound ends at %.5f s\n",
               cases[i].vn, cases[i].vt, cases[i].decel, cases[i].h, cases[i].tmin, cases[i].tmax, T, L / FS);
        assert_int_equal(L, want);
        surf_stats st;
        surf_get_stats(p.w, &st);
        assert_int_equal(st.impacts_in_use, 0);
        free(x);
        surf_uninit(p.w, NULL);
    }
}

/* ---- contacts ---- */

/* A surface whose contacts low-pass at 437.25 Hz rolling and 2911.6 Hz
 * at 1 m/s of slip (not whole hertz, so the probes never land on them),
 * read at one relief point per sample (scale 1/1024 m at FS/1024 m/s),
 * heard directly. */
static surf_surface_desc corner_surface(surf_relief_kind kind, const double *seg, long ns) {
    surf_surface_desc d = smooth(1e7, 1);
    d.relief.kind = kind;
    d.relief.samples = seg;
    d.relief.nsamples = ns;
    d.relief.scale = 1.0 / 1024;
    d.cutoff_roll = 437.25;
    d.cutoff_slip = 2911.6;
    d.slip_ref = 1;
    return d;
}

#define VREAD (FS / 1024) /* 46.875 m/s: one point per sample */

/* The contact generator's gain |H(f)| at slip `slip` for a whole number f
 * of Hz: a segment relief holding a sine of f Hz as read (whole periods
 * over its fs points, so it loops seamlessly), the output's amplitude over
 * the second after 0.2 s (its projection on e^{-i w n} over whole
 * periods), per newton of force. */
static double probe_gain(double slip, long f) {
    long ns = (long)FS, N = (long)(1.2 * FS), n0 = (long)(0.2 * FS);
    double *seg = zeros(ns), *x = zeros(N), re = 0, im = 0, F = 0.25;
    for (long i = 0; i < ns; i++)
        seg[i] = sin(2 * PI * (double)(f * i % ns) / FS);
    surf_surface_desc sa = corner_surface(SURF_RELIEF_SEGMENT, seg, ns), sb = smooth(1e7, 1);
    pair p = pair_new(&sa, &sb, 1, INFINITY, 256);
    surf_contact id = 0;
    surf_contact_data d = {VREAD, 0, slip, F};
    assert_int_equal(surf_contact_start(p.w, p.a, p.b, &d, &id), WDRT_OK);
    render(p.w, N, 256, NULL, p.ra, SURF_DIRECT, x);
    for (long i = n0; i < N; i++) {
        double ph = 2 * PI * (double)(f * i % ns) / FS;
        re += x[i] * cos(ph), im -= x[i] * sin(ph);
    }
    surf_uninit(p.w, NULL);
    free(seg), free(x);
    return 2 * hypot(re, im) / (double)(N - n0) / F;
}

/* The -3 dB point of the generator at slip `slip`: bisection over whole
 * frequencies in [lo, hi], then the crossing interpolated in dB between
 * the last two. */
static double probe_corner(double slip, long lo, long hi) {
    double glo = probe_gain(slip, lo), ghi = probe_gain(slip, hi), half = sqrt(0.5);
    assert_true(glo > half && ghi < half);
    while (hi - lo > 1) {
        long mid = (lo + hi) / 2;
        double g = probe_gain(slip, mid);
        if (g > half)
            lo = mid, glo = g;
        else
            hi = mid, ghi = g;
    }
    double a = 20 * log10(glo / half), b = 20 * log10(ghi / half);
    return (double)lo + a / (a - b);
}

/* The contact's low-pass corner against the slip law fc = f_roll +
 * (f_slip - f_roll) |slip| / slip_ref (437.25 Hz rolling, 2911.6 Hz at 1 m/s):
 * measured with sines written into the relief (the -3 dB point of the
 * generator's gain, found to a fraction of a hertz), and in the spectrum
 * of the output over a white relief (Welch; noise-limited to about 2 %).
 * And the output scales with the normal force, exactly. */
static void test_contact_cutoff(void **s) {
    (void)s;
    const double slips[] = {0, 0.5, 1, 2, 4.9};
    long N = (long)(8 * FS), nfft = 4096;
    double *x = zeros(N), *psd = zeros(nfft / 2 + 1);
    surf_surface_desc sa = corner_surface(SURF_RELIEF_NOISE, NULL, 0), sb = smooth(1e7, 1);
    for (int q = 0; q < 5; q++) {
        double want = fmin(437.25 + 2474.35 * slips[q], 0.45 * FS);
        pair p = pair_new(&sa, &sb, 1, INFINITY, 256);
        double fc = surf_contact_cutoff(p.w, 0, slips[q]);
        assert_true(fabs(fc - want) < 1e-9);
        const double F = 0.5;
        surf_contact id = 0;
        surf_contact_data d = {VREAD, 0, slips[q], F};
        assert_int_equal(surf_contact_start(p.w, p.a, p.b, &d, &id), WDRT_OK);
        render(p.w, N, 256, NULL, p.ra, SURF_DIRECT, x);
        welch(x + 256, N - 256, nfft, psd);
        double white = crossing(psd, nfft, FS, 5, 4, 0.5 * F * F / 3); /* uniform [-1, 1): variance 1/3 */
        surf_uninit(p.w, NULL);
        double sine = probe_corner(slips[q], (long)(fc / 2), (long)fmin(2 * fc, 0.49 * FS));
        printf("  slip %.1f m/s: cutoff %8.2f Hz; -3 dB measured with sines at %8.2f Hz (error %+.1e), "
               "in the white spectrum at %7.1f Hz (error %+.2f %%)\n",
               slips[q], fc, sine, (sine - fc) / fc, white, 100 * (white - fc) / fc);
        assert_true(fabs(sine - fc) / fc < 1e-5); /* interpolation between whole hertz */
        assert_true(fabs(white - fc) / fc < 0.05);
    }
    /* twice the force: exactly twice the sound; alive until stopped */
    long M = (long)FS;
    double *y = zeros(M), *z = zeros(M);
    for (int k = 1; k <= 2; k++) {
        pair p = pair_new(&sa, &sb, 1, INFINITY, 256);
        surf_contact id = 0;
        surf_contact_data d = {VREAD, 0, 0.7, k * 0.3};
        assert_int_equal(surf_contact_start(p.w, p.a, p.b, &d, &id), WDRT_OK);
        render(p.w, M, 100, NULL, p.ra, SURF_DIRECT, k == 1 ? y : z);
        assert_int_equal(surf_contact_stop(p.w, id), WDRT_OK);
        assert_int_equal(surf_contact_update(p.w, id, &d), WDRT_INVALID_ARGS); /* stale */
        surf_stats st;
        surf_get_stats(p.w, &st);
        assert_int_equal(st.contacts_in_use, 1); /* fading */
        double tail[256];
        render(p.w, 256, 256, NULL, p.ra, SURF_DIRECT, tail);
        assert_true(tail[255] == 0 && fabs(tail[0]) > 0);
        surf_get_stats(p.w, &st);
        assert_int_equal(st.contacts_in_use, 0);
        assert_int_equal(st.contacts_hwm, 1);
        render(p.w, 256, 256, NULL, p.ra, SURF_DIRECT, tail);
        assert_null(surf_output(p.w, p.ra, SURF_DIRECT));
        surf_uninit(p.w, NULL);
    }
    double rms = 0;
    for (long i = 0; i < M; i++) {
        assert_true(z[i] == 2 * y[i]);
        rms += y[i] * y[i] / (double)M;
    }
    printf("  force x2: output exactly x2 over %ld samples (rms at 0.3 N: %.4f N)\n", M, sqrt(rms));
    free(x), free(psd), free(y), free(z);
}

/* The needle reads at the speed it is given: a grid of bumps every 1 mm
 * read at 0.44 and 0.66 m/s is heard at 440 and 660 Hz. */
static void test_relief_speed(void **s) {
    (void)s;
    const double v[2] = {0.44, 0.66};
    for (int q = 0; q < 2; q++) {
        surf_surface_desc sa = smooth(1e7, 1), sb = smooth(1e7, 1);
        sa.relief.kind = SURF_RELIEF_GRID;
        sa.relief.scale = 1e-3;
        sa.relief.width = 3e-4;
        sa.cutoff_roll = sa.cutoff_slip = 15000;
        pair p = pair_new(&sa, &sb, 1, INFINITY, 256);
        surf_contact id = 0;
        surf_contact_data d = surf_contact_rolling(v[q], 0.1, 1);
        assert_int_equal(surf_contact_start(p.w, p.a, p.b, &d, &id), WDRT_OK);
        long N = (long)FS;
        double *x = zeros(N);
        render(p.w, N, 256, NULL, p.ra, SURF_DIRECT, x);
        double f = pt_peak_freq(x + 256, (size_t)(N - 256), FS, 300, 1000), want = v[q] / 1e-3;
        printf("  grid of 1 mm at %.2f m/s: fundamental %.4f Hz (want %.0f, error %+.1e)\n", v[q], f, want,
               (f - want) / want);
        assert_true(fabs(f - want) / want < 1e-4);
        free(x);
        surf_uninit(p.w, NULL);
    }
}

/* The gains of Menzies' Figure 4: master then direct reach the direct
 * channel, the limit clips after the master, `other` sends a surface's
 * excitation to the other body's resonator as well. */
static void test_routing(void **s) {
    (void)s;
    surf_mode m = mode(1000, 0.5, 1);
    long N = 4096;
    double *x[4], *dir[4], peak = 0;
    for (int c = 0; c < 4; c++) {
        surf_config cfg = surf_config_init(FS);
        surf_world *w = world_new(&cfg);
        int ra = add_res(w, &m, 1, 0), rb = add_res(w, NULL, 0, 0);
        surf_surface_desc sa = smooth(1e6, 1), sb = smooth(1e6, 0);
        if (c == 1)
            sa.impact.master = 0.5, sa.impact.direct = 2;
        if (c == 2)
            sa.impact.limit = 5;
        if (c == 3)
            sb.impact.other = 0.25;
        int A = add_body(w, ra, add_surf(w, &sa), 0.1), B = add_body(w, rb, add_surf(w, &sb), INFINITY);
        impact(w, 0, A, B, 0.01, 1, 0);
        x[c] = zeros(N), dir[c] = zeros(N);
        render(w, N, 256, NULL, ra, 0, x[c]);
        surf_uninit(w, NULL);
        w = world_new(&cfg);
        ra = add_res(w, &m, 1, 0), rb = add_res(w, NULL, 0, 0);
        A = add_body(w, ra, add_surf(w, &sa), 0.1), B = add_body(w, rb, add_surf(w, &sb), INFINITY);
        impact(w, 0, A, B, 0.01, 1, 0);
        render(w, N, 256, NULL, ra, SURF_DIRECT, dir[c]);
        surf_uninit(w, NULL);
    }
    double worst = 0, top = 0;
    for (long i = 0; i < N; i++) {
        peak = fmax(peak, dir[0][i]);
        top = fmax(top, dir[2][i]);
        assert_true(dir[1][i] == dir[0][i]); /* 2 (0.5 e) = e */
        assert_true(dir[2][i] == fmin(dir[0][i], 5));
        worst = fmax(worst, fabs(x[3][i] - 1.25 * x[0][i]));
    }
    printf("  master 0.5, direct 2: as master 1, direct 1; limit 5 N: peak %.2f N clipped to %.2f N; "
           "other 0.25: %.2e from 1.25 times\n",
           peak, top, worst);
    assert_true(top == 5 && peak > 10);
    assert_true(worst < 1e-15);
    for (int c = 0; c < 4; c++)
        free(x[c]), free(dir[c]);
}

/* Quiet contacts cost nothing: no force or no speed, no generator; a
 * disabled body's generator falls silent; each surface reads its own
 * relief at its own speed. */
static void test_contact_quiet(void **s) {
    (void)s;
    surf_surface_desc sa = smooth(1e7, 1), sb = smooth(1e7, 1);
    sa.relief.kind = sb.relief.kind = SURF_RELIEF_NOISE;
    pair p = pair_new(&sa, &sb, 1, 1, 256);
    surf_stats st;
    surf_contact id = 0;
    surf_contact_data d = surf_contact_rolling(0.3, 0, 0); /* no force */
    assert_int_equal(surf_contact_start(p.w, p.a, p.b, &d, &id), WDRT_OK);
    double buf[256];
    render(p.w, 256, 256, NULL, p.ra, SURF_DIRECT, buf);
    surf_get_stats(p.w, &st);
    assert_int_equal(st.generators, 0);
    assert_true(st.cost == 0);
    assert_null(surf_output(p.w, p.ra, SURF_DIRECT));
    d = surf_contact_rolling(0, 0.4, 2); /* a point sliding: a reads at 0, b at 0.4 */
    assert_int_equal(surf_contact_update(p.w, id, &d), WDRT_OK);
    render(p.w, 256, 256, NULL, p.ra, SURF_DIRECT, buf);
    surf_get_stats(p.w, &st);
    assert_int_equal(st.generators, 1);
    assert_null(surf_output(p.w, p.ra, SURF_DIRECT));
    assert_non_null(surf_output(p.w, p.rb, SURF_DIRECT));
    d = surf_contact_rolling(0.3, 0.4, 2); /* rolling and slipping: both */
    assert_int_equal(surf_contact_update(p.w, id, &d), WDRT_OK);
    render(p.w, 256, 256, NULL, p.ra, SURF_DIRECT, buf);
    surf_get_stats(p.w, &st);
    assert_int_equal(st.generators, 2);
    assert_true(st.cost == 2 * SURF_GEN_COST);
    assert_int_equal(surf_body_enable(p.w, p.b, 0), WDRT_OK);
    render(p.w, 256, 256, NULL, p.rb, SURF_DIRECT, buf); /* b fades */
    assert_true(buf[255] == 0);
    render(p.w, 256, 256, NULL, p.rb, SURF_DIRECT, buf);
    surf_get_stats(p.w, &st);
    assert_int_equal(st.generators, 1);
    assert_null(surf_output(p.w, p.rb, SURF_DIRECT));
    printf("  silent contact: 0 generators; sliding point: 1; rolling and slipping: 2; b disabled: 1\n");
    surf_uninit(p.w, NULL);
}

/* ---- contact damping ---- */

/* A struck mode (T60 1 s) while surfaces of damping 5 /s touch its body
 * one by one (cap 12 /s), then part: its decay rate in each interval, and
 * the other side's resonator damped by the first body's surface. */
static void test_damping(void **s) {
    (void)s;
    surf_config c = surf_config_init(FS);
    surf_world *w = world_new(&c);
    surf_mode ma = mode(440, 1, 1), mb = mode(660, 1, 1);
    int ra = add_res(w, &ma, 1, 0), rb = add_res(w, &mb, 1, 0), r0 = add_res(w, NULL, 0, 0);
    surf_resonator_set_max_damping(w, ra, 12);
    surf_surface_desc sa = smooth(1e8, 0), so = smooth(1e8, 0), sf = smooth(1e8, 0);
    sa.damping = 2;
    so.damping = 5;
    int A = add_body(w, ra, add_surf(w, &sa), 0.1);
    int so_i = add_surf(w, &so);
    int B = add_body(w, rb, so_i, 0.1), C = add_body(w, r0, so_i, 0.1), D = add_body(w, r0, so_i, 0.1);
    int F = add_body(w, r0, add_surf(w, &sf), INFINITY);
    impact(w, 0, A, F, 0.01, 1, 0);
    impact(w, 0, B, F, 0.01, 1, 0);
    long seg = (long)(0.3 * FS), N = 5 * seg;
    double *x = zeros(N), *y = zeros(N);
    surf_contact id[3] = {0, 0, 0};
    surf_contact_data still = {0, 0, 0, 1}; /* touching, not moving: silent */
    const double s0 = LN1000;
    const double want[5] = {s0, s0 + 5, s0 + 10, s0 + 12, s0};
    int others[3] = {B, C, D};
    for (int k = 0; k < 5; k++) {
        if (k >= 1 && k <= 3)
            assert_int_equal(surf_contact_start(w, A, others[k - 1], &still, &id[k - 1]), WDRT_OK);
        if (k == 4)
            for (int i = 0; i < 3; i++)
                assert_int_equal(surf_contact_stop(w, id[i]), WDRT_OK);
        for (long t = 0; t < seg;) {
            int n = surf_process(w, NULL, (int)(seg - t < 256 ? seg - t : 256));
            const double *o = surf_output(w, ra, 0), *ob = surf_output(w, rb, 0);
            for (int j = 0; j < n; j++)
                x[k * seg + t + j] = o[j], y[k * seg + t + j] = ob[j];
            t += n;
        }
        double sig = decay_rate(x, k * seg + 960, (k + 1) * seg, FS);
        double sigb = decay_rate(y, k * seg + 960, (k + 1) * seg, FS);
        double wantb = s0 + (k >= 1 && k <= 3 ? 2 : 0);
        printf("  %d surface%s touching: decay %.4f /s (want %.4f, error %+.1e), D %.1f /s; other side %.4f /s "
               "(want %.4f)\n",
               k == 4 ? 0 : k, k == 1 ? "" : "s", sig, want[k], (sig - want[k]) / want[k],
               surf_resonator_damping(w, ra), sigb, wantb);
        assert_true(fabs(sig - want[k]) / want[k] < 1e-6);
        assert_true(fabs(sigb - wantb) / wantb < 1e-6);
    }
    free(x), free(y);
    surf_uninit(w, NULL);
}

/* ---- pools ---- */

static void test_pools(void **s) {
    (void)s;
    surf_config c = surf_config_init(FS);
    c.max_contacts = 3;
    c.max_impacts = 2;
    surf_world *w = world_new(&c);
    surf_mode m = mode(300, 0.05, 1);
    int r = add_res(w, &m, 1, 1e-6);
    surf_surface_desc sd = surf_surface_desc_init();
    int sf = add_surf(w, &sd);
    int b[4];
    for (int i = 0; i < 4; i++)
        b[i] = add_body(w, r, sf, 0.1);
    surf_stats st;
    surf_contact id[4] = {0, 0, 0, 0};
    surf_contact_data d = surf_contact_rolling(0, 0.5, 1);
    for (int i = 0; i < 3; i++)
        assert_int_equal(surf_contact_start(w, b[i], b[i + 1], &d, &id[i]), WDRT_OK);
    assert_int_equal(surf_contact_start(w, b[0], b[3], &d, &id[3]), SURF_POOL_FULL);
    assert_int_equal(id[3], 0);
    surf_get_stats(w, &st);
    assert_int_equal(st.contacts_in_use, 3);
    assert_int_equal(st.contacts_hwm, 3);
    /* a silent contact returns its slot at once; its id goes stale */
    assert_int_equal(surf_contact_stop(w, id[1]), WDRT_OK);
    assert_int_equal(surf_contact_stop(w, id[1]), WDRT_INVALID_ARGS);
    surf_get_stats(w, &st);
    assert_int_equal(st.contacts_in_use, 2);
    assert_int_equal(st.contacts_hwm, 3);
    assert_int_equal(surf_contact_start(w, b[0], b[3], &d, &id[3]), WDRT_OK);
    assert_true(id[3] != id[1]); /* same slot, new identity */
    assert_int_equal(surf_contact_update(w, id[1], &d), WDRT_INVALID_ARGS);
    assert_int_equal(surf_contact_update(w, id[3], &d), WDRT_OK);
    render(w, 512, 256, NULL, 0, 0, NULL);
    /* a sounding contact keeps its slot through its fade */
    assert_int_equal(surf_contact_stop(w, id[0]), WDRT_OK);
    surf_get_stats(w, &st);
    assert_int_equal(st.contacts_in_use, 3);
    assert_int_equal(surf_contact_start(w, b[0], b[2], &d, &id[1]), SURF_POOL_FULL);
    render(w, 100, 256, NULL, 0, 0, NULL);
    surf_get_stats(w, &st);
    assert_int_equal(st.contacts_in_use, 2);
    /* impacts */
    assert_int_equal(surf_impact(w, 10, b[0], b[1], &(surf_impact_data){0.01, 1, 0.2}), WDRT_OK);
    assert_int_equal(surf_impact(w, 300, b[2], b[1], &(surf_impact_data){0.01, 1, 0.2}), WDRT_OK);
    assert_int_equal(surf_impact(w, 0, b[2], b[3], &(surf_impact_data){0.01, 1, 0.2}), SURF_POOL_FULL);
    assert_int_equal(surf_impact(w, 0, b[2], b[3], &(surf_impact_data){0, 1, 0.2}), WDRT_OK); /* no slot */
    surf_get_stats(w, &st);
    assert_int_equal(st.impacts_in_use, 2);
    assert_int_equal(st.impacts_hwm, 2);
    surf_impact_data id2 = {0.01, 1, 0.2};
    long T = 300 + (long)fmax(ceil(surf_skid_time(w, sf, &id2) * FS), ceil(surf_pulse_width(w, b[2], b[1]) * FS));
    render(w, T - 1, 256, NULL, 0, 0, NULL);
    surf_get_stats(w, &st);
    assert_int_equal(st.impacts_in_use, 1); /* the later one: one sample left */
    render(w, 1, 256, NULL, 0, 0, NULL);
    surf_get_stats(w, &st);
    assert_int_equal(st.impacts_in_use, 0);
    assert_int_equal(st.impacts_hwm, 2);
    assert_int_equal(surf_impact(w, 0, b[2], b[3], &(surf_impact_data){0.01, 1, 0.2}), WDRT_OK);
    printf("  contacts: 3 of 3, a 4th refused (%s); impacts: 2 of 2, a 3rd refused; marks kept\n",
           wdrt_result_str(SURF_POOL_FULL));
    surf_uninit(w, NULL);
}

/* Bad configurations, set-up and calls are refused. */
static void test_invalid(void **s) {
    (void)s;
    size_t size;
    surf_config c = surf_config_init(FS);
    assert_int_equal(surf_get_size(&c, &size), WDRT_OK);
    surf_config bad = c;
    bad.fs = 1000;
    assert_int_equal(surf_get_size(&bad, &size), WDRT_INVALID_ARGS);
    bad = c, bad.max_pickups = 9;
    assert_int_equal(surf_get_size(&bad, &size), WDRT_INVALID_ARGS);
    bad = c, bad.block = 0;
    assert_int_equal(surf_get_size(&bad, &size), WDRT_INVALID_ARGS);
    bad = c, bad.quiet_speed = NAN;
    assert_int_equal(surf_get_size(&bad, &size), WDRT_INVALID_ARGS);
    void *mem = NULL;
    assert_int_equal(posix_memalign(&mem, 16, size + 16), 0);
    surf_world *w = NULL;
    assert_int_equal(surf_init_prealloc(&c, (char *)mem + 8, &w), WDRT_INVALID_ARGS);
    assert_int_equal(surf_init_prealloc(&c, mem, &w), WDRT_OK);
    surf_mode m[2] = {mode(100, 1, 1), mode(200, -1, 1)};
    surf_resonator_desc rd = surf_resonator_desc_init();
    rd.modes = m, rd.nmodes = 2;
    assert_int_equal(surf_add_resonator(w, &rd), WDRT_INVALID_ARGS);
    rd.nmodes = 1, rd.npickups = 3;
    assert_int_equal(surf_add_resonator(w, &rd), WDRT_INVALID_ARGS);
    rd.npickups = 1;
    assert_int_equal(surf_add_resonator(w, &rd), 0);
    surf_surface_desc sd = surf_surface_desc_init();
    sd.hardness = 0;
    assert_int_equal(surf_add_surface(w, &sd), WDRT_INVALID_ARGS);
    sd = surf_surface_desc_init(), sd.relief.kind = SURF_RELIEF_SEGMENT; /* no samples */
    assert_int_equal(surf_add_surface(w, &sd), WDRT_INVALID_ARGS);
    double samp[4] = {1, 2, 3, 4};
    sd.relief.samples = samp, sd.relief.nsamples = 4;
    assert_int_equal(surf_add_surface(w, &sd), SURF_POOL_FULL); /* relief_frames 0 */
    sd = surf_surface_desc_init(), sd.skid_max = -1;
    assert_int_equal(surf_add_surface(w, &sd), WDRT_INVALID_ARGS);
    sd = surf_surface_desc_init();
    assert_int_equal(surf_add_surface(w, &sd), 0);
    surf_body_desc bd = {0, 1, 1};
    assert_int_equal(surf_add_body(w, &bd), WDRT_INVALID_ARGS);
    bd.surface = 0, bd.mass = 0;
    assert_int_equal(surf_add_body(w, &bd), WDRT_INVALID_ARGS);
    bd.mass = INFINITY;
    assert_int_equal(surf_add_body(w, &bd), 0);
    assert_int_equal(surf_add_body(w, &bd), 1);
    surf_impact_data id = {0.01, 1, 0};
    assert_int_equal(surf_impact(w, 0, 0, 1, &id), WDRT_INVALID_ARGS); /* both immovable */
    bd.mass = 1;
    assert_int_equal(surf_add_body(w, &bd), 2);
    assert_int_equal(surf_impact(w, -1, 0, 2, &id), WDRT_INVALID_ARGS);
    assert_int_equal(surf_impact(w, 0, 2, 2, &id), WDRT_INVALID_ARGS);
    id.impulse = -1;
    assert_int_equal(surf_impact(w, 0, 0, 2, &id), WDRT_INVALID_ARGS);
    surf_contact cid = 0;
    surf_contact_data cd = {1, 1, NAN, 1};
    assert_int_equal(surf_contact_start(w, 0, 2, &cd, &cid), WDRT_INVALID_ARGS);
    cd.slip = 0, cd.force = -1;
    assert_int_equal(surf_contact_start(w, 0, 2, &cd, &cid), WDRT_INVALID_ARGS);
    assert_int_equal(surf_contact_stop(w, 0), WDRT_INVALID_ARGS);
    assert_int_equal(surf_contact_stop(w, 0x10001), WDRT_INVALID_ARGS);
    assert_int_equal(surf_resonator_set_quiet(w, 5, 0), WDRT_INVALID_ARGS);
    assert_int_equal(surf_body_enable(w, 9, 1), WDRT_INVALID_ARGS);
    assert_null(surf_output(w, 0, 1));
    assert_int_equal(surf_process(w, NULL, 0), 0);
    assert_int_equal(surf_process(w, NULL, 100000), 256);
    free(mem);
}

/* ---- economy ---- */

/* Sleep changes nothing before its fade: a resonator with a quiet level
 * against the same without (quiet 0), bit for bit up to the fade, the fade
 * exactly the other's output times the ramp, silence and no cost after;
 * then an impact wakes it, and it sounds as a fresh world does. */
static void test_sleep_wake(void **s) {
    (void)s;
    surf_mode m[3] = {mode(500, 0.5, 1), mode(800, 0.4, 0.7), mode(1300, 0.3, 0.5)};
    surf_world *w[3];
    int r[3], a[3], f[3];
    const double quiet = 1e-4;
    for (int i = 0; i < 3; i++) {
        surf_config c = surf_config_init(FS);
        w[i] = world_new(&c);
        r[i] = add_res(w[i], m, 3, i == 1 ? 0 : quiet);
        int r0 = add_res(w[i], NULL, 0, quiet);
        surf_surface_desc sd = surf_surface_desc_init(); /* a skid too */
        sd.impact.direct = 0.001;
        int sf = add_surf(w[i], &sd);
        a[i] = add_body(w[i], r[i], sf, 0.05);
        f[i] = add_body(w[i], r0, sf, INFINITY);
    }
    impact(w[0], 10, a[0], f[0], 0.01, 1, 0.3);
    impact(w[1], 10, a[1], f[1], 0.01, 1, 0.3);
    const int B = 256;
    long nb = (long)(1.5 * FS) / B, fade = -1;
    double x[B], y[B], e_prev = 0, e_before = 0;
    for (long k = 0; k < nb; k++) {
        assert_int_equal(surf_process(w[0], NULL, B), B);
        const double *o = surf_output(w[0], r[0], 0);
        render(w[1], B, B, NULL, r[1], 0, y);
        render(w[2], B, B, NULL, r[2], 0, NULL); /* the fresh world keeps time */
        double e = surf_resonator_energy(w[1], r[1]);
        if (fade < 0 && o && memcmp(o, y, sizeof y) != 0) {
            fade = k;
            e_before = e_prev;
            for (int j = 0; j < B; j++)
                assert_true(o[j] == y[j] * fmax(1 - (j + 1.0) / B, 0));
        } else if (fade < 0) {
            assert_non_null(o);
            assert_memory_equal(o, y, sizeof y);
        } else
            assert_null(o);
        if (fade < 0)
            e_prev = e;
    }
    assert_true(fade > 0);
    surf_stats st;
    surf_get_stats(w[0], &st);
    assert_int_equal(st.resonators_awake, 0);
    assert_int_equal(st.modes, 0);
    assert_int_equal(surf_resonator_awake(w[0], r[0]), 0);
    printf("  sleeps after %.3f s (energy %.3g < quiet %.0e at the block before its fade), identical before\n",
           fade * B / FS, e_before, quiet);
    assert_true(e_before < quiet);
    /* wake: an impact on the sleeper and on a world that never rang */
    impact(w[0], 77, a[0], f[0], 0.02, 0.5, 0.5);
    impact(w[2], 77, a[2], f[2], 0.02, 0.5, 0.5);
    for (int k = 0; k < 40; k++) {
        render(w[0], B, B, NULL, r[0], 0, x);
        render(w[2], B, B, NULL, r[2], 0, y);
        assert_memory_equal(x, y, sizeof x);
    }
    assert_int_equal(surf_resonator_awake(w[0], r[0]), 1);
    surf_get_stats(w[0], &st);
    assert_int_equal(st.modes, 3);
    printf("  woken by an impact: identical to a fresh resonator's response\n");
    for (int i = 0; i < 3; i++)
        surf_uninit(w[i], NULL);
}

/* A resonator shared by two bodies (marbles in a jar) sums what they
 * bring: two impacts (with skids) through two bodies = the sum of each
 * alone. */
static void test_shared_linear(void **s) {
    (void)s;
    surf_mode m[3] = {mode(2100, 0.4, 1), mode(5300, 0.25, 0.6), mode(9100, 0.15, 0.3)};
    surf_mode mf[2] = {mode(180, 0.6, 0.2), mode(410, 0.5, 0.1)};
    long N = (long)(0.5 * FS);
    double *mix[3], *res[3];
    surf_stats st;
    for (int i = 0; i < 3; i++) {
        surf_config c = surf_config_init(FS);
        surf_world *w = world_new(&c);
        int r = add_res(w, m, 3, 0), rf = add_res(w, mf, 2, 0);
        surf_surface_desc glass = surf_surface_desc_init(), wood = surf_surface_desc_init();
        glass.hardness = 5e7, wood.hardness = 1e6;
        glass.impact.other = 0.3;
        int sg = add_surf(w, &glass), sw = add_surf(w, &wood);
        int m1 = add_body(w, r, sg, 0.005), m2 = add_body(w, r, sg, 0.005), fl = add_body(w, rf, sw, INFINITY);
        if (i != 1)
            impact(w, 100, m1, fl, 0.004, 0.8, 0.3);
        if (i != 0)
            impact(w, 700, m2, fl, 0.006, 1, 0.5);
        mix[i] = zeros(N), res[i] = zeros(N);
        render(w, N, 256, mix[i], r, 0, res[i]);
        if (i == 2) {
            render(w, 256, 256, NULL, r, 0, NULL);
            surf_get_stats(w, &st);
        }
        surf_uninit(w, NULL);
    }
    double worst = 0, peak = 0, wr = 0;
    for (long k = 0; k < N; k++) {
        peak = fmax(peak, fabs(mix[2][k]));
        worst = fmax(worst, fabs(mix[2][k] - mix[0][k] - mix[1][k]));
        wr = fmax(wr, fabs(res[2][k] - res[0][k] - res[1][k]));
    }
    printf("  both = one + other: worst difference %.2e (mix), %.2e (shared resonator), peak %.3g\n", worst, wr,
           peak);
    assert_true(worst <= 1e-12 * peak && wr <= 1e-12 * peak);
    assert_int_equal(st.resonators_awake, 2); /* the shared one counts once */
    assert_int_equal(st.modes, 5);
    for (int i = 0; i < 3; i++)
        free(mix[i]), free(res[i]);
}

/* Under a limit of active modes the quietest go first: 2 of 4 (listed out
 * of order) sound exactly as a resonator of the 2 loudest; the cost counts
 * them. */
static void test_active_modes(void **s) {
    (void)s;
    surf_mode all[4] = {mode(1500, 0.5, 0.25), mode(400, 0.5, 1), mode(2600, 0.5, 0.1), mode(900, 0.5, 0.5)};
    surf_mode two[2] = {mode(400, 0.5, 1), mode(900, 0.5, 0.5)};
    long N = 8192;
    double *x[2];
    surf_stats st[2];
    for (int i = 0; i < 2; i++) {
        surf_config c = surf_config_init(FS);
        surf_world *w = world_new(&c);
        int r = i ? add_res(w, two, 2, 0) : add_res(w, all, 4, 0), r0 = add_res(w, NULL, 0, 0);
        if (!i)
            assert_int_equal(surf_resonator_set_active_modes(w, r, 2), WDRT_OK);
        surf_surface_desc sd = smooth(1e8, 0);
        int sf = add_surf(w, &sd);
        int a = add_body(w, r, sf, 0.1), b = add_body(w, r0, sf, INFINITY);
        impact(w, 0, a, b, 0.01, 1, 0);
        x[i] = zeros(N);
        render(w, N, 256, NULL, r, 0, x[i]);
        surf_get_stats(w, &st[i]);
        surf_uninit(w, NULL);
    }
    assert_memory_equal(x[0], x[1], (size_t)N * sizeof(double));
    assert_int_equal(st[0].modes, 2);
    assert_true(st[0].cost == 2);
    printf("  2 active of 4: identical to the 2 loudest; cost %.0f modes per sample\n", st[0].cost);
    free(x[0]), free(x[1]);
}

/* Nothing allocates in the real-time calls: impacts, contacts started,
 * updated and stopped, enables, limits and processing. */
static void test_no_alloc(void **s) {
    (void)s;
    surf_config c = surf_config_init(FS);
    c.relief_frames = 1000;
    surf_world *w = world_new(&c);
    surf_mode m[4] = {mode(300, 1, 1), mode(700, 0.5, 1), mode(1900, 0.3, 1), mode(5000, 0.2, 1)};
    int r = add_res(w, m, 4, 1e-5), r2 = add_res(w, m, 2, 1e-5);
    surf_surface_desc s1 = surf_surface_desc_init(), s2 = surf_surface_desc_init(), s3 = surf_surface_desc_init();
    double seg[1000];
    for (int i = 0; i < 1000; i++)
        seg[i] = sin(i * 0.37) + 0.3 * sin(i * 1.91);
    s2.relief.kind = SURF_RELIEF_GRID, s2.relief.scale = 1e-3, s2.relief.width = 3e-4;
    s3.relief.kind = SURF_RELIEF_SEGMENT, s3.relief.samples = seg, s3.relief.nsamples = 1000;
    s1.contact.direct = s2.impact.other = s3.contact.other = 0.5;
    int a = add_body(w, r, add_surf(w, &s1), 0.1), b = add_body(w, r2, add_surf(w, &s2), 0.2);
    int f = add_body(w, r2, add_surf(w, &s3), INFINITY);
    double mix[256];
    ca_allocs = 0;
    ca_in_rt = 1;
    surf_contact id = 0, id2 = 0;
    surf_contact_data d = surf_contact_rolling(0.2, 0.3, 1);
    assert_int_equal(surf_contact_start(w, a, f, &d, &id), WDRT_OK);
    assert_int_equal(surf_contact_start(w, b, f, &d, &id2), WDRT_OK);
    for (int k = 0; k < 400; k++) {
        if (k % 7 == 0)
            impact(w, k % 300, k % 2 ? a : b, f, 0.001 * (1 + k % 5), 1, 0.4);
        d.slip = 0.5 + 0.4 * sin(k * 0.1);
        d.force = k % 50 < 40 ? 1 : 0;
        assert_int_equal(surf_contact_update(w, id, &d), WDRT_OK);
        if (k == 100)
            surf_body_enable(w, b, 0);
        if (k == 150)
            surf_body_enable(w, b, 1), surf_resonator_set_active_modes(w, r, 3);
        if (k == 300)
            surf_contact_stop(w, id2);
        surf_process(w, mix, k % 3 ? 256 : 77);
    }
    surf_stats st;
    surf_get_stats(w, &st);
    surf_reset(w);
    ca_in_rt = 0;
    assert_int_equal(ca_allocs, 0);
    printf("  400 blocks of contacts and impacts: %ld allocations (peak impacts %d)\n", ca_allocs, st.impacts_hwm);
    surf_uninit(w, NULL);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_modes_ring_true), cmocka_unit_test(test_mode_decay_exact),
        cmocka_unit_test(test_modes_reader),    cmocka_unit_test(test_pulse_width),
        cmocka_unit_test(test_pulse_integral),  cmocka_unit_test(test_harder_brighter),
        cmocka_unit_test(test_skid_length),     cmocka_unit_test(test_contact_cutoff),
        cmocka_unit_test(test_relief_speed),    cmocka_unit_test(test_routing),
        cmocka_unit_test(test_contact_quiet),   cmocka_unit_test(test_damping),
        cmocka_unit_test(test_pools),           cmocka_unit_test(test_invalid),
        cmocka_unit_test(test_sleep_wake),      cmocka_unit_test(test_shared_linear),
        cmocka_unit_test(test_active_modes),    cmocka_unit_test(test_no_alloc),
        cmocka_unit_test(ca_test_counter_counts),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
