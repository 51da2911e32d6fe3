/* partials.c - tuning and decay of the partials of a rendered sound (see
 * partials.h). */
#include "partials.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

/* Phasors stepped by multiplication are recomputed exactly this often. */
#define PT_RESYNC 256

/* ---- Kaiser windows ---- */

/* Modified Bessel function of the first kind, order 0 (power series; all
 * terms positive, so it is accurate to rounding for the x used here). */
static double pt_i0(double x) {
    static const double inv[] = {
        0,          1,          1.0 / 4,    1.0 / 9,    1.0 / 16,   1.0 / 25,
        1.0 / 36,   1.0 / 49,   1.0 / 64,   1.0 / 81,   1.0 / 100,  1.0 / 121,
        1.0 / 144,  1.0 / 169,  1.0 / 196,  1.0 / 225,  1.0 / 256,  1.0 / 289,
        1.0 / 324,  1.0 / 361,  1.0 / 400,  1.0 / 441,  1.0 / 484,  1.0 / 529,
        1.0 / 576,  1.0 / 625,  1.0 / 676,  1.0 / 729,  1.0 / 784,  1.0 / 841,
        1.0 / 900,  1.0 / 961,  1.0 / 1024, 1.0 / 1089, 1.0 / 1156, 1.0 / 1225,
        1.0 / 1296, 1.0 / 1369, 1.0 / 1444, 1.0 / 1521, 1.0 / 1600,
    };
    double q = 0.25 * x * x, term = 1.0, sum = 1.0;
    for (int k = 1; k < 500; k++) {
        term *= k < (int)(sizeof inv / sizeof inv[0]) ? q * inv[k] : q / ((double)k * k);
        sum += term;
        if (term < 1e-17 * sum)
            break;
    }
    return sum;
}

/* Points of the table pt_kaiser interpolates long windows from. */
#define PT_KTAB 2048

/* w[0..m) = the Kaiser window of length m (m >= 2), peak 1 in the middle
 * and exactly symmetric: w[i] == w[m-1-i].  Long windows interpolate
 * I0(beta u) in u = sqrt(1 - r^2) from a table (cubic, relative error
 * below 1e-9, far under the sidelobes). */
static void pt_kaiser(double *w, size_t m, double beta) {
    double norm = 1.0 / pt_i0(beta);
    double half = 0.5 * (double)(m - 1);
    size_t nh = (m + 1) / 2;
    if (nh <= PT_KTAB) {
        for (size_t i = 0; i < nh; i++) {
            double r = ((double)i - half) / half;
            w[i] = w[m - 1 - i] = pt_i0(beta * sqrt(fmax(0.0, 1.0 - r * r))) * norm;
        }
        return;
    }
    /* tab[j] = I0(beta (j - 1) / PT_KTAB) / I0(beta), j in [0, PT_KTAB + 2] */
    double tab[PT_KTAB + 3];
    for (int j = 0; j < PT_KTAB + 3; j++)
        tab[j] = pt_i0(beta * (double)(j - 1) / PT_KTAB) * norm;
    for (size_t i = 0; i < nh; i++) {
        double r = ((double)i - half) / half;
        double u = sqrt(fmax(0.0, 1.0 - r * r)) * PT_KTAB;
        int j = (int)u;
        if (j > PT_KTAB - 1)
            j = PT_KTAB - 1;
        double t = u - (double)j;
        const double *p = tab + j; /* values at j-1, j, j+1, j+2 */
        double v = -t * (t - 1.0) * (t - 2.0) / 6.0 * p[0] +
                   (t + 1.0) * (t - 1.0) * (t - 2.0) / 2.0 * p[1] -
                   (t + 1.0) * t * (t - 2.0) / 2.0 * p[2] + (t + 1.0) * t * (t - 1.0) / 6.0 * p[3];
        w[i] = w[m - 1 - i] = v;
    }
}

/* Odd length of a Kaiser kernel whose first spectral null is at most bw
 * Hz from its centre, or 0 if it would exceed n samples. */
static size_t pt_kernel_len(double fs, double bw, size_t n) {
    double m = ceil(PT_LOBE * fs / bw);
    if (!(m <= (double)n))
        return 0;
    size_t k = (size_t)m;
    if (k < 3)
        k = 3;
    if (k % 2 == 0)
        k++;
    return k <= n ? k : 0;
}

/* ---- band levels over time ---- */

/* A demodulating kernel: c[s] = h[s] exp(-j w s), h a Kaiser window of
 * length m with sum 1. */
typedef struct pt_kernel {
    size_t m;
    double *re, *im;
} pt_kernel;

static int pt_kernel_make(pt_kernel *k, size_t m, double w) {
    k->m = m;
    k->re = malloc(m * sizeof *k->re);
    k->im = malloc(m * sizeof *k->im);
    if (!k->re || !k->im) {
        free(k->re);
        free(k->im);
        return -1;
    }
    pt_kaiser(k->re, m, PT_BETA);
    double sum = 0.0;
    for (size_t s = 0; s < m; s++)
        sum += k->re[s];
    for (size_t s = 0; s < m; s++) {
        double h = k->re[s] / sum, ph = w * (double)s;
        k->re[s] = h * cos(ph);
        k->im[s] = -h * sin(ph);
    }
    return 0;
}

static void pt_kernel_free(pt_kernel *k) {
    free(k->re);
    free(k->im);
}

/* Level (dB) of the band of kernel k applied at x[start .. start + m). */
static double pt_level_at(const pt_kernel *k, const double *x, size_t start) {
    double re = 0.0, im = 0.0;
    const double *p = x + start;
    for (size_t s = 0; s < k->m; s++) {
        re += k->re[s] * p[s];
        im += k->im[s] * p[s];
    }
    double a = hypot(re, im);
    return a > 0.0 ? 20.0 * log10(a) : -1000.0;
}

/* Levels at the starts from, from + hop, ... <= to (at least one); the
 * count in *count.  NULL if memory runs out. */
static double *pt_levels(const pt_kernel *k, const double *x, size_t from, size_t to,
                         size_t hop, size_t *count) {
    size_t c = (to - from) / hop + 1;
    double *db = malloc(c * sizeof *db);
    if (!db)
        return NULL;
    for (size_t i = 0; i < c; i++)
        db[i] = pt_level_at(k, x, from + i * hop);
    *count = c;
    return db;
}

/* ---- t60 ---- */

/* Index of the maximum of db[0..c). */
static size_t pt_argmax(const double *db, size_t c) {
    size_t p = 0;
    for (size_t i = 1; i < c; i++)
        if (db[i] > db[p])
            p = i;
    return p;
}

/* First i in [from, c) with db[i] <= level, or c. */
static size_t pt_first_below(const double *db, size_t c, size_t from, double level) {
    size_t i = from;
    while (i < c && db[i] > level)
        i++;
    return i;
}

double pt_t60(const double *x, size_t n, double fs, double f, double bw, double skip_db,
              double span_db) {
    if (!x || !(fs > 0.0) || !(f > 0.0) || !(bw > 0.0) || !(span_db > 0.0) ||
        !(skip_db >= 0.0))
        return NAN;
    size_t m = pt_kernel_len(fs, bw, n);
    if (!m)
        return NAN;
    pt_kernel k;
    if (pt_kernel_make(&k, m, 2.0 * M_PI * f / fs) != 0)
        return NAN;
    double result = NAN;
    size_t last = n - m; /* last start with the kernel inside the signal */

    /* coarse pass: where the peak and the fit range lie */
    size_t hop0 = m / 8 ? m / 8 : 1, c0;
    double *db0 = pt_levels(&k, x, 0, last, hop0, &c0);
    if (!db0)
        goto out;
    size_t p = pt_argmax(db0, c0);
    double peak = db0[p];
    size_t i1 = pt_first_below(db0, c0, p, peak - skip_db);
    size_t i2 = i1 < c0 ? pt_first_below(db0, c0, i1, peak - skip_db - span_db) : c0;
    if (i2 == c0)
        i2 = c0 - 1;
    free(db0);
    if (i1 >= c0)
        goto out;

    /* fine pass: about 256 levels over the fit range, from just before the
     * peak on (a hop of at least m/64 bounds the work by 64 n) */
    size_t s1 = p ? (p - 1) * hop0 : 0, s2 = i2 * hop0 + hop0;
    if (s2 > last)
        s2 = last;
    size_t hop = (i2 * hop0 - i1 * hop0) / 256;
    if (hop < m / 64)
        hop = m / 64;
    if (hop < 1)
        hop = 1;
    size_t c;
    double *db = pt_levels(&k, x, s1, s2, hop, &c);
    if (!db)
        goto out;
    size_t pf = pt_argmax(db, c);
    if (db[pf] > peak)
        peak = db[pf];
    size_t j1 = pt_first_below(db, c, pf, peak - skip_db);
    size_t j2 = j1 < c ? pt_first_below(db, c, j1, peak - skip_db - span_db) : c;
    int reached = j2 < c;
    if (!reached)
        j2 = c - 1;
    if (j1 < c && j2 >= j1 + 2) {
        /* least-squares line through (time, level), time centred */
        double tm = 0.5 * (double)(j1 + j2), sty = 0.0, stt = 0.0;
        for (size_t i = j1; i <= j2; i++) {
            double t = (double)i - tm;
            sty += t * db[i];
            stt += t * t;
        }
        double slope = sty / stt * fs / (double)hop; /* dB per second */
        double covered = -slope * (double)((j2 - j1) * hop) / fs;
        if (slope < 0.0 && (reached || covered >= 10.0))
            result = -60.0 / slope;
    }
    free(db);
out:
    pt_kernel_free(&k);
    return result;
}

/* ---- FFT ---- */

/* A table of cos(2 pi k / n) for k in [0, n/4], n a power of two >= 8;
 * it serves every FFT of n points or fewer. */
typedef struct pt_costab {
    size_t n;
    double *c;
} pt_costab;

static int pt_costab_make(pt_costab *t, size_t n) {
    t->n = n;
    t->c = malloc((n / 4 + 1) * sizeof *t->c);
    if (!t->c)
        return -1;
    /* cos(a + b) = cos a cos b - sin a sin b, a a multiple of 64 steps:
     * within a few ulps, with few calls of cos and sin */
    double d = 2.0 * M_PI / (double)n, cb[64], sb[64];
    for (size_t b = 0; b < 64; b++) {
        cb[b] = cos(d * (double)b);
        sb[b] = sin(d * (double)b);
    }
    for (size_t a = 0; a <= n / 4; a += 64) {
        double ca = cos(d * (double)a), sa = sin(d * (double)a);
        for (size_t b = 0; b < 64 && a + b <= n / 4; b++)
            t->c[a + b] = ca * cb[b] - sa * sb[b];
    }
    return 0;
}

/* e^{-j 2 pi k / n} for k in [0, n/2], n <= t->n a power of two. */
static void pt_twiddle(const pt_costab *t, size_t n, size_t k, double *re, double *im) {
    size_t q = n / 4, st = t->n / n;
    const double *c = t->c;
    if (k <= q) {
        *re = c[k * st];
        *im = -c[(q - k) * st];
    } else {
        *re = -c[(2 * q - k) * st];
        *im = -c[(k - q) * st];
    }
}

/* The power spectrum |Y[k]|^2, k in [0, n/2], of the real y[0..n) (n a
 * power of two >= 8): a complex FFT of n/2 points of the even and odd
 * samples, then split.  y is overwritten; p has n/2 + 1 entries.
 * Returns 0, or -1 if memory runs out. */
static int pt_power_spectrum(double *y, size_t n, double *p, const pt_costab *c) {
    size_t m = n / 2;
    double *wr = malloc(m * sizeof *wr);
    double *wi = malloc(m * sizeof *wi);
    double *re = malloc(m * sizeof *re);
    double *im = malloc(m * sizeof *im);
    if (!wr || !wi || !re || !im) {
        free(wr);
        free(wi);
        free(re);
        free(im);
        return -1;
    }
    /* twiddles of the stage of half-size h at wr[h + i], wi[h + i], i < h */
    for (size_t h = 1; h < m; h <<= 1)
        for (size_t i = 0; i < h; i++)
            pt_twiddle(c, n, i * (n / (2 * h)), &wr[h + i], &wi[h + i]);
    /* bit-reversed load of z[k] = y[2k] + j y[2k+1] */
    for (size_t i = 0, j = 0; i < m; i++) {
        re[j] = y[2 * i];
        im[j] = y[2 * i + 1];
        size_t bit = m >> 1;
        for (; j & bit; bit >>= 1)
            j ^= bit;
        j ^= bit;
    }
    for (size_t h = 1; h < m; h <<= 1) {
        const double *tr0 = wr + h, *ti0 = wi + h;
        for (size_t s = 0; s < m; s += 2 * h) {
            double *ra = re + s, *ia = im + s, *rb = ra + h, *ib = ia + h;
            for (size_t i = 0; i < h; i++) {
                double tr = rb[i] * tr0[i] - ib[i] * ti0[i];
                double ti = rb[i] * ti0[i] + ib[i] * tr0[i];
                rb[i] = ra[i] - tr;
                ib[i] = ia[i] - ti;
                ra[i] += tr;
                ia[i] += ti;
            }
        }
    }
    /* Y[k] = E[k] + e^{-j 2 pi k / n} O[k], E and O the halves of Z */
    for (size_t k = 0; k <= m; k++) {
        size_t k1 = k % m, k2 = (m - k) % m;
        double er = 0.5 * (re[k1] + re[k2]), ei = 0.5 * (im[k1] - im[k2]);
        double or_ = 0.5 * (im[k1] + im[k2]), oi = -0.5 * (re[k1] - re[k2]);
        double tr, ti;
        pt_twiddle(c, n, k, &tr, &ti);
        double yr = er + tr * or_ - ti * oi, yi = ei + tr * oi + ti * or_;
        p[k] = yr * yr + yi * yi;
    }
    free(wr);
    free(wi);
    free(re);
    free(im);
    return 0;
}

/* ---- peak frequency ---- */

/* |sum_i y[i] exp(-j w (i - c))|^2 (c the centre of y[0..L)) and its first
 * two derivatives in w. */
static void pt_power(const double *y, size_t L, double w, double *p, double *d1, double *d2) {
    double c = 0.5 * (double)(L - 1);
    double s0r = 0, s0i = 0, s1r = 0, s1i = 0, s2r = 0, s2i = 0;
    double sr = cos(w), si = -sin(w);
    double er = 0, ei = 0;
    for (size_t i = 0; i < L; i++) {
        double t = (double)i - c;
        if (i % PT_RESYNC == 0) {
            er = cos(w * t);
            ei = -sin(w * t);
        }
        double vr = y[i] * er, vi = y[i] * ei;
        s0r += vr;
        s0i += vi;
        s1r += t * vr;
        s1i += t * vi;
        s2r += t * t * vr;
        s2i += t * t * vi;
        double nr = er * sr - ei * si;
        ei = er * si + ei * sr;
        er = nr;
    }
    /* X = S0, X' = -j S1, X'' = -S2 */
    *p = s0r * s0r + s0i * s0i;
    *d1 = 2.0 * (s0r * s1i - s0i * s1r);
    *d2 = 2.0 * (s1r * s1r + s1i * s1i - (s0r * s2r + s0i * s2i));
}

/* The maximum of |DTFT|^2 of y[0..L) near w0 (rad/sample), within `width`
 * either side: Newton's method, or golden-section search where the power
 * is not concave. */
static double pt_refine(const double *y, size_t L, double w0, double width) {
    double w = w0, p, d1, d2;
    for (int it = 0; it < 40; it++) {
        pt_power(y, L, w, &p, &d1, &d2);
        if (!(d2 < 0.0))
            break;
        double step = -d1 / d2;
        if (!(fabs(w + step - w0) <= width))
            break;
        w += step;
        if (fabs(step) < 1e-9 * width)
            return w;
    }
    /* golden section on [w0 - width, w0 + width] */
    const double g = 0.5 * (sqrt(5.0) - 1.0);
    double a = w0 - width, b = w0 + width;
    double x1 = b - g * (b - a), x2 = a + g * (b - a), p1, p2;
    pt_power(y, L, x1, &p1, &d1, &d2);
    pt_power(y, L, x2, &p2, &d1, &d2);
    while (b - a > 1e-9 * width) {
        if (p1 < p2) {
            a = x1;
            x1 = x2;
            p1 = p2;
            x2 = a + g * (b - a);
            pt_power(y, L, x2, &p2, &d1, &d2);
        } else {
            b = x2;
            x2 = x1;
            p2 = p1;
            x1 = b - g * (b - a);
            pt_power(y, L, x1, &p1, &d1, &d2);
        }
    }
    return 0.5 * (a + b);
}

/* A local maximum of the power spectrum: bin k, power p. */
typedef struct pt_cand {
    double p;
    size_t k;
} pt_cand;

/* qsort order: strongest first. */
static int pt_cand_cmp(const void *a, const void *b) {
    double pa = ((const pt_cand *)a)->p, pb = ((const pt_cand *)b)->p;
    return (pa < pb) - (pa > pb);
}

/* The Kaiser-windowed x[0..L) and its power spectrum zero-padded to the
 * next power of two N >= L, with the local maxima in the band that are no
 * more than PT_FLOOR_DB below the strongest bin, strongest first. */
typedef struct pt_spec {
    size_t L, N;
    double *y;  /* [L] windowed signal */
    double *pw; /* [N] power in [0 .. N/2] */
    double wsq; /* sum of the squared window */
    pt_cand *cand;
    size_t ncand;
    double edge; /* the larger power at the two ends of the band */
} pt_spec;

static void pt_spec_free(pt_spec *s) {
    free(s->y);
    free(s->pw);
    free(s->cand);
    s->y = s->pw = NULL;
    s->cand = NULL;
}

static int pt_spec_make(pt_spec *s, const double *x, size_t L, double fs, double f_lo,
                        double f_hi, const pt_costab *c) {
    size_t N = 8;
    while (N < L)
        N <<= 1;
    s->L = L;
    s->N = N;
    s->ncand = 0;
    s->edge = 0.0;
    s->y = malloc(L * sizeof *s->y);
    s->pw = malloc((N / 2 + 1) * sizeof *s->pw);
    s->cand = NULL;
    double *buf = calloc(N, sizeof *buf);
    if (!s->y || !s->pw || !buf)
        goto fail;
    pt_kaiser(s->y, L, PT_BETA);
    s->wsq = 0.0;
    for (size_t i = 0; i < L; i++) {
        s->wsq += s->y[i] * s->y[i];
        s->y[i] *= x[i];
        buf[i] = s->y[i];
    }
    if (pt_power_spectrum(buf, N, s->pw, c) != 0)
        goto fail;
    free(buf);
    buf = NULL;
    size_t h = N / 2;
    const double *pw = s->pw;
    double pmax = 0.0;
    for (size_t k = 0; k <= h; k++)
        pmax = fmax(pmax, pw[k]);
    double thresh = pmax * pow(10.0, -0.1 * PT_FLOOR_DB);
    double klo = fmax(ceil(f_lo * (double)N / fs), 1.0);
    double khi = fmin(floor(f_hi * (double)N / fs), (double)(h - 1));
    if (!(klo <= khi) || !(pmax > 0.0))
        return 0;
    /* the bins at or just outside the ends of the band */
    double elo = fmax(floor(f_lo * (double)N / fs), 0.0);
    double ehi = fmin(ceil(f_hi * (double)N / fs), (double)h);
    s->edge = fmax(pw[(size_t)elo], pw[(size_t)ehi]);
    s->cand = malloc(((size_t)(khi - klo) + 1) * sizeof *s->cand);
    if (!s->cand)
        goto fail;
    for (size_t k = (size_t)klo; k <= (size_t)khi; k++)
        if (pw[k] > pw[k - 1] && pw[k] >= pw[k + 1] && pw[k] > thresh) {
            s->cand[s->ncand].p = pw[k];
            s->cand[s->ncand].k = k;
            s->ncand++;
        }
    qsort(s->cand, s->ncand, sizeof *s->cand, pt_cand_cmp);
    return 0;
fail:
    free(buf);
    pt_spec_free(s);
    return -1;
}

/* A peak counts in the choice of the window only where it stands this
 * much (power ratio) above both ends of the band, if it does for some
 * window. */
#define PT_EDGE 4.0
/* pt_peak_freq tries windows of n, n/2, n/4, ... samples and takes the
 * longest whose peak is at most PT_SCAN_DB less clear of the noise than
 * the best one's. */
#define PT_SCAN_DB 3.0

double pt_peak_freq(const double *x, size_t n, double fs, double f_lo, double f_hi) {
    if (!x || n < 16 || !(fs > 0.0) || !(f_lo < f_hi) || !(f_hi > 0.0) ||
        !(f_lo < 0.5 * fs))
        return NAN;
    f_lo = fmax(f_lo, 0.0);
    f_hi = fmin(f_hi, 0.5 * fs);
    size_t ntop = 8;
    while (ntop < n)
        ntop <<= 1;
    pt_costab tab;
    if (pt_costab_make(&tab, ntop) != 0)
        return NAN;
    double result = NAN;

    /* Window lengths n, n/2, ... down to 8 periods of the band's centre
     * and to PT_LOBE / (2 hw) seconds, where the main lobe spans twice the
     * band's half-width hw either side.  q: power of the strongest peak over the power the
     * window lets through from white noise; qe: the same where that peak
     * stands PT_EDGE above both ends of the band, 0 elsewhere. */
    double lmin = fmax(16.0, 16.0 * fs / (f_lo + f_hi));
    lmin = fmin((double)n, fmax(lmin, 0.5 * PT_LOBE * fs / (0.5 * (f_hi - f_lo))));
    pt_spec spec[64];
    size_t nl = 0;
    double q[64], qe[64];
    for (double Lf = (double)n; nl < 64; Lf *= 0.5) {
        if (nl > 0 && Lf < lmin) {
            /* lmin itself closes the list */
            if ((double)spec[nl - 1].L <= lmin * 1.01)
                break;
            Lf = lmin;
        }
        pt_spec *s = &spec[nl];
        if (pt_spec_make(s, x, (size_t)Lf, fs, f_lo, f_hi, &tab) != 0)
            goto out;
        q[nl] = s->ncand ? s->cand[0].p / s->wsq : 0.0;
        qe[nl] = s->ncand && s->cand[0].p >= PT_EDGE * s->edge ? q[nl] : 0.0;
        nl++;
    }
    /* the longest window within PT_SCAN_DB of the best, by qe if any */
    double qmax = 0.0;
    for (size_t j = 0; j < nl; j++)
        qmax = fmax(qmax, qe[j]);
    if (qmax > 0.0)
        memcpy(q, qe, sizeof q);
    else
        for (size_t j = 0; j < nl; j++)
            qmax = fmax(qmax, q[j]);
    if (!(qmax > 0.0))
        goto out;
    size_t pick = 0;
    while (q[pick] < qmax * pow(10.0, -0.1 * PT_SCAN_DB))
        pick++;

    const pt_spec *s = &spec[pick];
    const double *pw = s->pw;
    double bin = 2.0 * M_PI / (double)s->N;
    for (size_t c = 0; c < s->ncand && c < 8; c++) {
        size_t k = s->cand[c].k;
        /* vertex of the parabola through the log powers around bin k */
        double a = log(fmax(pw[k - 1], DBL_MIN)), b = log(pw[k]);
        double d = log(fmax(pw[k + 1], DBL_MIN));
        double den = a - 2.0 * b + d, delta = den < 0.0 ? 0.5 * (a - d) / den : 0.0;
        if (!(fabs(delta) <= 1.0))
            delta = 0.0;
        double w = pt_refine(s->y, s->L, ((double)k + delta) * bin, 2.0 * bin);
        double f = w * fs / (2.0 * M_PI);
        if (f >= f_lo && f <= f_hi) {
            result = f;
            break;
        }
    }
out:
    for (size_t j = 0; j < nl; j++)
        pt_spec_free(&spec[j]);
    free(tab.c);
    return result;
}

double pt_cents(double f, double ref) { return 1200.0 * log2(f / ref); }
