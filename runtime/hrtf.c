/*
 * hrtf.c - the binaural renderer: SOFA loading through libmysofa,
 * onset-aligned filters and ear delays, the direction grid, and the
 * crossfading FIR of each source.  The model is described in hrtf.h.
 */
#include "hrtf.h"

#include <assert.h>
#include <math.h>
#include <mysofa.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

#define WINDOW_S 5.33e-3   /* filter length after its start (see hrtf.h) */
#define FADE_S 1e-3        /* half-Hann fade-out at the filter's end */
#define PRE_S 0.2e-3       /* kept before an onset */
#define ONSET 0.1          /* onset: first sample reaching this fraction of the peak */
#define MAX_DELAY_S 0.05   /* ear delays may differ by this much: bounds a source's history */
#define FAR 0.99           /* measurements used: those this near the largest distance */
#define STEP (2.5 * M_PI / 180) /* grid spacing, radians, azimuth and elevation */
#define NAZ 144            /* azimuths: 360 / 2.5 */
#define NEL 73             /* elevations -90..90: 180 / 2.5 + 1 */
#define NEAR 3             /* measurements blended per grid point */
#define CHUNK 128          /* frames rendered at a time: bounds the stack's scratch */

typedef struct cell {
    int m[NEAR];      /* measurements blended, nearest first; -1: none */
    double w[NEAR];   /* their weights, summing to 1 */
} cell;

struct hrtf {
    double fs;        /* Hz */
    int len;          /* taps per filter */
    int dmax;         /* largest ear delay, samples */
    int nmeas;        /* measurements */
    double *ir;       /* [nmeas][2][len] aligned filters, left ear first */
    double *delay;    /* [nmeas][2] ear delays, samples (fractional when the file's are) */
    cell *grid;       /* [NEL][NAZ], elevation -90 first, azimuth -180 first */
};

struct hrtf_src {
    int len;          /* taps (the set's) */
    int hist;         /* past samples kept: len - 1 + the set's dmax */
    int cell;         /* grid point of the current filter; -1: none yet */
    int cur;          /* slot of the current filter, 0 or 1 */
    int delay[2][2];  /* [slot][ear] delays, samples */
    double mem[];     /* [2][2][len] the slots' taps, then hist + CHUNK samples */
};

/* ---- errors ---- */

#if defined(__GNUC__)
__attribute__((format(printf, 4, 5)))
#endif
static void *fail(char *err, size_t errlen, const char *path, const char *fmt, ...) {
    if (err && errlen) {
        int k = snprintf(err, errlen, "%s: error: ", path);
        if (k >= 0 && (size_t)k < errlen) {
            va_list ap;
            va_start(ap, fmt);
            vsnprintf(err + k, errlen - (size_t)k, fmt, ap);
            va_end(ap);
        }
    }
    return NULL;
}

/* libmysofa's error codes, in words.  Its loader gives errno when the
 * file cannot be opened, so small positive codes are errno values. */
static void *fail_mysofa(char *err, size_t errlen, const char *path, int code) {
    switch (code) {
    case MYSOFA_INVALID_FORMAT:
        return fail(err, errlen, path, "not a SOFA file\n");
    case MYSOFA_UNSUPPORTED_FORMAT:
        return fail(err, errlen, path, "a SOFA file libmysofa cannot read\n");
    case MYSOFA_NO_MEMORY:
        return fail(err, errlen, path, "out of memory\n");
    case MYSOFA_READ_ERROR:
        return fail(err, errlen, path, "cannot read: read error\n");
    default:
        if (code > 0 && code < MYSOFA_INVALID_FORMAT)
            return fail(err, errlen, path, "cannot read: %s\n", strerror(code));
        return fail(err, errlen, path, "not a set of head-related impulse responses libmysofa accepts (code %d)\n",
                    code);
    }
}

/* ---- loading ---- */

/* The arrays this file reads have the sizes its dimensions give (what
 * mysofa_check leaves unsaid: indexing depends on it). */
static int shaped(const struct MYSOFA_HRTF *mh) {
    return mh->R == 2 && mh->M > 0 && mh->N > 0 && mh->C == 3 && mh->DataSamplingRate.elements == 1 &&
           mh->SourcePosition.elements == 3 * mh->M && mh->DataIR.elements == 2 * mh->M * mh->N;
}

/* Reads, checks, resamples to fs, normalises and converts to cartesian:
 * what mysofa_open does, less the lookup structures (we build our own)
 * and keeping the file's own rate, which its delays are counted in. */
static struct MYSOFA_HRTF *load(const char *path, double fs, double *fs_file, char *err, size_t errlen) {
    int e = MYSOFA_OK;
    struct MYSOFA_HRTF *mh = mysofa_load(path, &e);
    if (!mh)
        return fail_mysofa(err, errlen, path, e);
    e = mysofa_check(mh);
    if (e == MYSOFA_OK && !shaped(mh))
        e = MYSOFA_INVALID_DIMENSIONS;
    if (e == MYSOFA_OK) {
        *fs_file = mh->DataSamplingRate.values[0];
        e = mysofa_resample(mh, (float)fs);
    }
    if (e != MYSOFA_OK) {
        mysofa_free(mh);
        return fail_mysofa(err, errlen, path, e);
    }
    mysofa_loudness(mh);
    mysofa_tocartesian(mh);
    return mh;
}

/* Index of the first sample of x[0..n) reaching ONSET of its peak. */
static int onset(const float *x, int n) {
    float pk = 0;
    for (int i = 0; i < n; i++)
        pk = fabsf(x[i]) > pk ? fabsf(x[i]) : pk;
    int o = 0;
    while (o < n && fabsf(x[o]) < (float)ONSET * pk)
        o++;
    return o < n ? o : 0;
}

/* The file's delay of response f (measurement f / 2, ear f % 2), in
 * samples at fs: AES69 stores samples at the file's rate, one pair for
 * all measurements or one per measurement. */
static double file_delay(const struct MYSOFA_HRTF *mh, int f, double ratio) {
    const struct MYSOFA_ARRAY *d = &mh->DataDelay;
    double v = 0;
    if (d->elements == 2 * mh->M)
        v = d->values[f];
    else if (d->elements == 2)
        v = d->values[f % 2];
    return isfinite(v) && v > 0 ? v * ratio : 0;
}

/* Copies response x (n samples) into the filter a (len taps) from pre
 * samples before onset o, with the fade-out. */
static void align(const float *x, int n, int o, int pre, double *a, int len, int fade) {
    for (int k = 0; k < len; k++) {
        int i = o - pre + k;
        double g = 1;
        if (k >= len - fade)
            g = 0.5 + 0.5 * cos(M_PI * (k - (len - fade) + 1) / (fade + 1));
        a[k] = i >= 0 && i < n ? x[i] * g : 0;
    }
}

/* Filters and delays of every response; the delay common to all is
 * removed.  Returns 0, or -1 if memory runs out. */
static int take_filters(hrtf *h, const struct MYSOFA_HRTF *mh, double fs_file) {
    int n = (int)mh->N, pre = (int)lround(PRE_S * h->fs), nf = 2 * h->nmeas;
    int len = (int)ceil(WINDOW_S * h->fs);
    len = len < n + pre ? len : n + pre;
    h->len = (len + 3) & ~3; /* whole vectors in the FIR's loops */
    h->ir = malloc(sizeof(double) * (size_t)nf * (size_t)h->len);
    h->delay = malloc(sizeof(double) * (size_t)nf);
    if (!h->ir || !h->delay)
        return -1;
    double dmin = INFINITY;
    for (int f = 0; f < nf; f++) {
        const float *x = mh->DataIR.values + (size_t)f * (size_t)n;
        int o = onset(x, n);
        align(x, n, o, pre, h->ir + (size_t)f * (size_t)h->len, h->len, (int)lround(FADE_S * h->fs));
        h->delay[f] = o + file_delay(mh, f, h->fs / fs_file);
        dmin = h->delay[f] < dmin ? h->delay[f] : dmin;
    }
    double dmax = 0;
    for (int f = 0; f < nf; f++) {
        h->delay[f] -= dmin;
        dmax = h->delay[f] > dmax ? h->delay[f] : dmax;
    }
    h->dmax = (int)lround(dmax); /* a weighted mean of delays rounds to at most this */
    return 0;
}

/* The listener-frame direction of grid point (ie, ia), in SOFA's frame
 * (x ahead, y left, z up). */
static void grid_dir(int ie, int ia, double u[3]) {
    double el = (ie - (NEL - 1) / 2) * STEP, az = (ia - NAZ / 2) * STEP; /* az: from ahead toward the right */
    double right = sin(az) * cos(el), ahead = cos(az) * cos(el);
    u[0] = ahead;
    u[1] = -right;
    u[2] = sin(el);
}

static double radius(const float *p) {
    return sqrt((double)p[0] * p[0] + (double)p[1] * p[1] + (double)p[2] * p[2]);
}

/* Unit directions of the measurements at the largest distance; others
 * (nearer, or without a position) get NAN.  Returns NULL if memory runs
 * out. */
static double *directions(const struct MYSOFA_HRTF *mh) {
    int m = (int)mh->M;
    const float *p = mh->SourcePosition.values;
    double *u = malloc(sizeof(double) * 3 * (size_t)m), rmax = 0;
    if (!u)
        return NULL;
    for (int i = 0; i < m; i++)
        rmax = fmax(rmax, radius(p + 3 * i));
    for (int i = 0; i < m; i++) {
        double r = radius(p + 3 * i);
        for (int c = 0; c < 3; c++)
            u[3 * i + c] = r > 1e-9 && r >= FAR * rmax ? p[3 * i + c] / r : NAN;
    }
    return u;
}

/* The NEAR measurements nearest to v (chord distances into d, ascending;
 * index -1 where there are fewer) and the distance of the next one, or 2
 * (the sphere's diameter) if there is none. */
static double nearest(const double *u, int m, const double v[3], int idx[NEAR], double d[NEAR]) {
    double best[NEAR + 1];
    int bi[NEAR + 1];
    for (int j = 0; j <= NEAR; j++)
        best[j] = INFINITY, bi[j] = -1;
    for (int i = 0; i < m; i++) {
        double dx = u[3 * i] - v[0], dy = u[3 * i + 1] - v[1], dz = u[3 * i + 2] - v[2];
        double q = dx * dx + dy * dy + dz * dz; /* NAN for unused: never less */
        int j = NEAR + 1;
        while (j > 0 && q < best[j - 1])
            j--;
        if (j > NEAR)
            continue;
        memmove(best + j + 1, best + j, sizeof(double) * (size_t)(NEAR - j));
        memmove(bi + j + 1, bi + j, sizeof(int) * (size_t)(NEAR - j));
        best[j] = q, bi[j] = i;
    }
    for (int j = 0; j < NEAR; j++)
        idx[j] = bi[j], d[j] = sqrt(best[j]);
    return bi[NEAR] >= 0 ? sqrt(best[NEAR]) : 2.0 + 1e-9;
}

/* Franke and Nielson's modified Shepard weights ((R - d) / (R d))^2,
 * R the distance of the first measurement left out: 1 on a measurement,
 * 0 for one as far as R. */
static void weights(cell *c, const int idx[NEAR], const double d[NEAR], double r) {
    double sum = 0;
    for (int j = 0; j < NEAR; j++) {
        c->m[j] = idx[j];
        c->w[j] = 0;
        if (idx[j] < 0)
            continue;
        if (d[0] < 1e-6) { /* on a measurement */
            c->w[j] = j == 0;
        } else {
            double t = (r - d[j]) / (r * d[j]);
            c->w[j] = t > 0 ? t * t : 0;
        }
        sum += c->w[j];
    }
    for (int j = 0; j < NEAR; j++)
        c->w[j] = sum > 0 ? c->w[j] / sum : (idx[j] >= 0 ? 1.0 / NEAR : 0); /* all equidistant: even */
}

/* The grid: every point's measurements and weights.  Returns 0, or -1 if
 * memory runs out or no measurement has a position. */
static int build_grid(hrtf *h, const struct MYSOFA_HRTF *mh) {
    double *u = directions(mh);
    h->grid = malloc(sizeof(cell) * NEL * NAZ);
    if (!u || !h->grid) {
        free(u);
        return -1;
    }
    for (int ie = 0; ie < NEL; ie++) {
        for (int ia = 0; ia < NAZ; ia++) {
            double v[3], d[NEAR];
            int idx[NEAR];
            grid_dir(ie, ia, v);
            double r = nearest(u, h->nmeas, v, idx, d);
            weights(&h->grid[ie * NAZ + ia], idx, d, r);
        }
    }
    free(u);
    return h->grid[0].m[0] >= 0 ? 0 : -1;
}

hrtf *hrtf_open(const char *sofa, double fs, char *err, size_t errlen) {
    const char *path = sofa ? sofa : HRTF_DEFAULT_SOFA;
    if (!(fs >= 8000 && fs <= 768000))
        return fail(err, errlen, path, "sample rate %g Hz out of range (8000 to 768000)\n", fs);
    double fs_file = fs;
    struct MYSOFA_HRTF *mh = load(path, fs, &fs_file, err, errlen);
    if (!mh)
        return NULL;
    hrtf *h = calloc(1, sizeof *h);
    const char *why = "out of memory\n";
    if (h) {
        h->fs = fs;
        h->nmeas = (int)mh->M;
        if (take_filters(h, mh, fs_file) == 0) {
            why = h->dmax <= MAX_DELAY_S * fs ? NULL : "its ear delays differ by more than 50 ms\n";
            if (!why && build_grid(h, mh) != 0)
                why = h->grid ? "no measurement has a position\n" : "out of memory\n";
        }
    }
    mysofa_free(mh);
    if (why) {
        hrtf_close(h);
        return fail(err, errlen, path, "%s", why);
    }
    return h;
}

void hrtf_close(hrtf *h) {
    if (!h)
        return;
    free(h->ir);
    free(h->delay);
    free(h->grid);
    free(h);
}

int hrtf_length(const hrtf *h) {
    assert(h);
    return h->len;
}

/* ---- sources ---- */

size_t hrtf_src_size(const hrtf *h) {
    size_t doubles = 4 * (size_t)h->len + (size_t)(h->len - 1 + h->dmax) + CHUNK;
    return sizeof(hrtf_src) + sizeof(double) * doubles;
}

static double *taps(hrtf_src *s, int slot) {
    return s->mem + 2 * (size_t)s->len * (size_t)slot;
}

static double *history(hrtf_src *s) {
    return s->mem + 4 * (size_t)s->len;
}

hrtf_src *hrtf_src_init(const hrtf *h, void *mem) {
    if (!h || !mem)
        return NULL;
    assert((uintptr_t)mem % 16 == 0);
    hrtf_src *s = mem;
    s->len = h->len;
    s->hist = h->len - 1 + h->dmax;
    hrtf_src_clear(s);
    return s;
}

void hrtf_src_clear(hrtf_src *s) {
    s->cell = -1;
    s->cur = 0;
    memset(s->delay, 0, sizeof s->delay);
    memset(history(s), 0, sizeof(double) * (size_t)(s->hist + CHUNK));
}

/* The grid point nearest to direction d (listener frame). */
static int cell_of(const double d[3]) {
    double x = d[0], y = d[1], z = d[2];
    if (!(x * x + y * y + z * z > 1e-24)) /* zero, or NaN: ahead */
        x = 0, y = 1, z = 0;
    long ia = lround(atan2(x, y) / STEP) + NAZ / 2;
    long ie = lround(atan2(z, hypot(x, y)) / STEP) + (NEL - 1) / 2;
    ia = ia >= NAZ ? ia - NAZ : ia; /* +180 degrees is -180 */
    ie = ie < 0 ? 0 : ie >= NEL ? NEL - 1 : ie;
    return (int)(ie * NAZ + ia);
}

/* The filter of grid point c into t (left taps, then right) and its ear
 * delays: the weighted sum of its measurements'. */
static void make_filter(const hrtf *h, const cell *c, double *t, int delay[2]) {
    size_t n = 2 * (size_t)h->len;
    double d[2] = {0, 0};
    memset(t, 0, sizeof(double) * n);
    for (int j = 0; j < NEAR; j++) {
        if (c->m[j] < 0 || c->w[j] == 0)
            continue;
        const double *a = h->ir + (size_t)c->m[j] * n, w = c->w[j];
        for (size_t k = 0; k < n; k++)
            t[k] += w * a[k];
        d[0] += w * h->delay[2 * c->m[j]];
        d[1] += w * h->delay[2 * c->m[j] + 1];
    }
    for (int e = 0; e < 2; e++) {
        long r = lround(d[e]);
        delay[e] = (int)(r < 0 ? 0 : r > h->dmax ? h->dmax : r);
    }
}

/* y[i] += sum_k a[k] x[i - delay - k] for i < m, x pointing at the chunk's
 * first sample inside the history.  Each output sums its products from
 * zero in the order of k, whichever path computes it, so a render does
 * not depend on how the host cuts its blocks.  With SSE2 (every x86-64),
 * eight outputs at a time share each tap in four vector accumulators:
 * two to three times the speed of the scalar loop, which gcc does not
 * vectorise at -O2. */
static void fir(const double *x, const double *a, int len, int delay, int m, double *restrict y) {
    const double *p = x - delay;
    int i = 0;
#if defined(__SSE2__)
    for (; i + 8 <= m; i += 8) {
        __m128d s0 = _mm_setzero_pd(), s1 = s0, s2 = s0, s3 = s0;
        for (int k = 0; k < len; k++) {
            __m128d ak = _mm_set1_pd(a[k]);
            const double *q = p + i - k;
            s0 = _mm_add_pd(s0, _mm_mul_pd(ak, _mm_loadu_pd(q)));
            s1 = _mm_add_pd(s1, _mm_mul_pd(ak, _mm_loadu_pd(q + 2)));
            s2 = _mm_add_pd(s2, _mm_mul_pd(ak, _mm_loadu_pd(q + 4)));
            s3 = _mm_add_pd(s3, _mm_mul_pd(ak, _mm_loadu_pd(q + 6)));
        }
        _mm_storeu_pd(y + i, _mm_add_pd(_mm_loadu_pd(y + i), s0));
        _mm_storeu_pd(y + i + 2, _mm_add_pd(_mm_loadu_pd(y + i + 2), s1));
        _mm_storeu_pd(y + i + 4, _mm_add_pd(_mm_loadu_pd(y + i + 4), s2));
        _mm_storeu_pd(y + i + 6, _mm_add_pd(_mm_loadu_pd(y + i + 6), s3));
    }
#endif
    for (; i < m; i++) {
        double acc = 0;
        for (int k = 0; k < len; k++)
            acc += a[k] * p[i - k];
        y[i] += acc;
    }
}

/* Both ears of filter `slot` over the chunk: yl, yr (zeroed here). */
static void render(hrtf_src *s, int slot, const double *x, int m, double *yl, double *yr) {
    const double *t = taps(s, slot);
    memset(yl, 0, sizeof(double) * (size_t)m);
    memset(yr, 0, sizeof(double) * (size_t)m);
    fir(x, t, s->len, s->delay[slot][0], m, yl);
    fir(x, t + s->len, s->len, s->delay[slot][1], m, yr);
}

/* One chunk of m frames, frames pos.. of a block of n; `from` is the
 * slot faded out over the block, or -1. */
static void chunk(hrtf_src *s, const double *in, double *out_l, double *out_r, int m, int from, int pos, int n) {
    double yl[CHUNK], yr[CHUNK], zl[CHUNK], zr[CHUNK];
    double *hist = history(s), *x = hist + s->hist;
    memcpy(x, in, sizeof(double) * (size_t)m); /* before any output: `in` may be an output */
    render(s, s->cur, x, m, yl, yr);
    if (from >= 0) {
        render(s, from, x, m, zl, zr);
        for (int i = 0; i < m; i++) {
            double w = (double)(pos + i + 1) / n;
            yl[i] = zl[i] + w * (yl[i] - zl[i]);
            yr[i] = zr[i] + w * (yr[i] - zr[i]);
        }
    }
    for (int i = 0; i < m; i++) {
        out_l[i] += yl[i];
        out_r[i] += yr[i];
    }
    memmove(hist, hist + m, sizeof(double) * (size_t)s->hist);
}

void hrtf_src_process(const hrtf *h, hrtf_src *s, const double dir[3], const double *in, double *out_l,
                      double *out_r, int n) {
    assert(h && s && dir && in && out_l && out_r);
    assert(s->len == h->len && s->hist == h->len - 1 + h->dmax);
    if (n <= 0)
        return;
    int c = cell_of(dir), from = -1;
    if (c != s->cell) {
        if (s->cell >= 0) { /* fade from the current slot into the other */
            from = s->cur;
            s->cur = 1 - s->cur;
        }
        make_filter(h, &h->grid[c], taps(s, s->cur), s->delay[s->cur]);
        s->cell = c;
    }
    for (int pos = 0; pos < n; pos += CHUNK) {
        int m = n - pos < CHUNK ? n - pos : CHUNK;
        chunk(s, in + pos, out_l + pos, out_r + pos, m, from, pos, n);
    }
}
