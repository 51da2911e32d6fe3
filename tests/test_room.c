/*
 * test_room.c - the room module (runtime/room.h): image sources against
 * Allen and Berkley's formula written out here independently (and a few by
 * hand), the FDN's reverberation time at 500 Hz and 4 kHz measured by
 * Schroeder's backward integration, its losslessness with the absorption
 * filters bypassed, its calibrated level, stability and finiteness over a
 * fuzz of rooms, and no allocation at all while it runs (a counting
 * allocator stands in for malloc, as in test_storm.c).
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

#include "room.h"
#include "testlib.h"


#define PI 3.14159265358979323846

#include "countalloc.h"

/* ---- helpers ---- */

static room_config room(double x, double y, double z, double tlo, double thi, int order, double fs) {
    room_config c = {{0, 0, 0, x, y, z}, tlo, thi, order, 343.0, fs};
    return c;
}

/* An FDN for cfg in 16-aligned heap memory (free with free()). */
static room_fdn *fdn_new(const room_config *cfg) {
    size_t n = room_fdn_size(cfg);
    assert_true(n > 0);
    void *mem = NULL;
    assert_int_equal(posix_memalign(&mem, 16, n), 0);
    room_fdn *f = room_fdn_init(cfg, mem);
    assert_ptr_equal(f, mem);
    return f;
}

/* The impulse response of a fresh FDN for cfg, n samples per output. */
static void fdn_ir(const room_config *cfg, long n, double *l, double *r) {
    room_fdn *f = fdn_new(cfg);
    double *in = calloc((size_t)n, sizeof(double));
    in[0] = 1;
    memset(l, 0, sizeof(double) * (size_t)n);
    memset(r, 0, sizeof(double) * (size_t)n);
    room_fdn_process(f, in, l, r, (int)n);
    free(in);
    free(f);
}

/* Eyring's pressure reflection coefficient, from T60 = 24 ln10 V / (-c S ln beta^2). */
static double eyring(double V, double S, double c, double t60) {
    return exp(24 * log(10.0) * V / (c * S * t60) / -2);
}

/* ---- the reference image sources (Allen and Berkley, eq. 10-11) ---- */

typedef struct ref_image {
    double pos[3];
    int order;
} ref_image;

/* Every image of order 1..K: positions (1 - 2q) u + 2 n L per axis, from
 * the lower wall, q in {0, 1}, n in [-K, K]; order sum |n - q| + |n|. */
static int ref_images(const room_config *c, const double src[3], ref_image *out) {
    int K = c->order, w = 0;
    int n[3], q[3];
    for (n[0] = -K; n[0] <= K; n[0]++)
        for (n[1] = -K; n[1] <= K; n[1]++)
            for (n[2] = -K; n[2] <= K; n[2]++)
                for (int qq = 0; qq < 8; qq++) {
                    int ord = 0;
                    double p[3];
                    for (int a = 0; a < 3; a++) {
                        q[a] = qq >> a & 1;
                        ord += abs(n[a] - q[a]) + abs(n[a]);
                        double L = c->box[a + 3] - c->box[a];
                        p[a] = c->box[a] + (1 - 2 * q[a]) * (src[a] - c->box[a]) + 2 * n[a] * L;
                    }
                    if (ord == 0 || ord > K)
                        continue;
                    memcpy(out[w].pos, p, sizeof p);
                    out[w++].order = ord;
                }
    return w;
}

static int same_pos(const double *a, const double *b) {
    for (int k = 0; k < 3; k++)
        if (fabs(a[k] - b[k]) > 1e-9 * (1 + fabs(b[k])))
            return 0;
    return 1;
}

/* Index of an image at pos in im[0..n), or -1. */
static int find_image(const room_image *im, int n, const double pos[3]) {
    for (int i = 0; i < n; i++)
        if (same_pos(im[i].pos, pos))
            return i;
    return -1;
}

/* ---- geometry ---- */

static void test_geometry(void **s) {
    (void)s;
    room_config c = {{-1, 2, 0.5, 4, 6, 3.5}, 1, 1, 2, 343, 48000};
    assert_float_equal(room_volume(&c), 5 * 4 * 3, 1e-12);
    assert_float_equal(room_surface(&c), 2 * (20 + 12 + 15), 1e-12);
    double in[3] = {0, 3, 1}, edge[3] = {4, 2, 3.5}, out[3] = {4.001, 3, 1}, nan[3] = {0, NAN, 1};
    assert_true(room_contains(&c, in));
    assert_true(room_contains(&c, edge));
    assert_false(room_contains(&c, out));
    assert_false(room_contains(&c, nan));
    room_config bad = c;
    bad.box[4] = bad.box[1];
    assert_true(room_volume(&bad) == 0 && room_surface(&bad) == 0);
    /* the mixing time: (order + 1) mean free paths of travel */
    double mfp = 4 * 60.0 / 94.0;
    assert_float_equal(room_mixing_time(&c), 3 * mfp / 343, 1.0 / 48000);
}

/* ---- image sources ---- */

static void test_counts(void **s) {
    (void)s;
    static const int expect[7] = {0, 6, 24, 62, 128, 230, 376};
    static ref_image ref[13 * 13 * 13 * 8];
    static room_image im[400];
    double src[3] = {1, 2, 1.5};
    for (int k = 0; k <= ROOM_MAX_ORDER; k++) {
        room_config c = room(5, 4, 3, 1.2, 0.8, k, 48000);
        assert_int_equal(room_max_images(k), expect[k]);
        assert_int_equal(ref_images(&c, src, ref), expect[k]);
        assert_int_equal(room_images(&c, src, im, 400), expect[k]);
    }
    assert_int_equal(room_max_images(-1), 0);
    assert_int_equal(room_max_images(9), 376);
}

/* The six first-order images and eight second-order ones worked out by
 * hand for a source at (1, 2, 1.5) in a 5 x 4 x 3 box. */
static void test_by_hand(void **s) {
    (void)s;
    room_config c = room(5, 4, 3, 1.2, 0.8, 2, 48000);
    double src[3] = {1, 2, 1.5};
    room_image im[32];
    assert_int_equal(room_images(&c, src, im, 32), 24);
    double b_lo = eyring(60, 94, 343, 1.2), b_hi = eyring(60, 94, 343, 0.8);
    static const double first[6][3] = {{-1, 2, 1.5}, {9, 2, 1.5}, {1, -2, 1.5},
                                       {1, 6, 1.5},  {1, 2, -1.5}, {1, 2, 4.5}};
    static const double second[8][3] = {{-1, -2, 1.5}, {9, 6, 1.5}, {11, 2, 1.5}, {-9, 2, 1.5},
                                        {1, 10, 1.5},  {1, 2, 7.5}, {1, 2, -4.5}, {-1, 2, 4.5}};
    for (int k = 0; k < 6; k++) {
        int i = find_image(im, 24, first[k]);
        assert_true(i >= 0 && i < 6); /* first order comes first */
        assert_int_equal(im[i].reflections, 1);
        assert_float_equal(im[i].gain, b_lo, 1e-15);
        assert_float_equal(im[i].hf, b_hi, 1e-15);
    }
    for (int k = 0; k < 8; k++) {
        int i = find_image(im, 24, second[k]);
        assert_true(i >= 6);
        assert_int_equal(im[i].reflections, 2);
        assert_float_equal(im[i].gain, b_lo * b_lo, 1e-15);
        assert_float_equal(im[i].hf, b_hi * b_hi, 1e-15);
    }
    print_message("5x4x3, T60 1.2/0.8 s: wall reflection %.6f (500 Hz), %.6f (4 kHz)\n", b_lo, b_hi);
}

/* Every image of every order in rooms with offset corners and random
 * sources matches exactly one reference image: same position, order and
 * gains; and the order never decreases along the list. */
static void test_allen_berkley(void **s) {
    (void)s;
    static ref_image ref[13 * 13 * 13 * 8];
    static room_image im[400];
    tl_rng rng;
    tl_rng_seed(&rng, 1979);
    for (int t = 0; t < 30; t++) {
        room_config c;
        for (int a = 0; a < 3; a++) {
            c.box[a] = 20 * tl_rng_signed(&rng);
            c.box[a + 3] = c.box[a] + 0.5 + 30 * tl_rng_uniform(&rng);
        }
        c.t60_low = 0.1 + 3 * tl_rng_uniform(&rng);
        c.t60_high = 0.1 + 3 * tl_rng_uniform(&rng);
        c.order = t % (ROOM_MAX_ORDER + 1);
        c.c = 340 + 5 * tl_rng_uniform(&rng);
        c.fs = 48000;
        double src[3];
        for (int a = 0; a < 3; a++)
            src[a] = c.box[a] + (c.box[a + 3] - c.box[a]) * tl_rng_uniform(&rng);
        double V = room_volume(&c), S = room_surface(&c);
        double blo = eyring(V, S, c.c, c.t60_low), bhi = eyring(V, S, c.c, c.t60_high);
        int nref = ref_images(&c, src, ref);
        int n = room_images(&c, src, im, 400);
        assert_int_equal(n, nref);
        char used[400] = {0};
        for (int r = 0; r < nref; r++) {
            int i = find_image(im, n, ref[r].pos);
            assert_true(i >= 0 && !used[i]);
            used[i] = 1;
            assert_int_equal(im[i].reflections, ref[r].order);
            assert_float_equal(im[i].gain, pow(blo, ref[r].order), 1e-13);
            assert_float_equal(im[i].hf, pow(bhi, ref[r].order), 1e-13);
        }
        for (int i = 1; i < n; i++)
            assert_true(im[i].reflections >= im[i - 1].reflections);
    }
}

/* A short out keeps the lowest orders: the first max of the full list. */
static void test_truncated(void **s) {
    (void)s;
    room_config c = room(7, 5, 3, 1, 0.7, 4, 48000);
    double src[3] = {2, 1, 1};
    room_image all[128], some[40];
    assert_int_equal(room_images(&c, src, all, 128), 128);
    assert_int_equal(room_images(&c, src, some, 40), 40);
    for (int i = 0; i < 40; i++)
        assert_true(same_pos(some[i].pos, all[i].pos) && some[i].reflections == all[i].reflections);
    assert_int_equal(room_images(&c, src, NULL, 0), 0);
}

static void test_invalid(void **s) {
    (void)s;
    room_image im[8];
    double src[3] = {1, 1, 1}, outside[3] = {1, 1, 9};
    room_config ok = room(5, 4, 3, 1, 1, 1, 48000);
    assert_int_equal(room_images(&ok, outside, im, 8), WDRT_INVALID_ARGS);
    assert_int_equal(room_images(&ok, src, NULL, 8), WDRT_INVALID_ARGS);
    assert_int_equal(room_images(&ok, src, im, -1), WDRT_INVALID_ARGS);
    room_config bad[6] = {ok, ok, ok, ok, ok, ok};
    bad[0].box[3] = 0;
    bad[1].t60_low = 0.001;
    bad[2].t60_high = NAN;
    bad[3].order = 7;
    bad[4].c = 0;
    bad[5].box[2] = -INFINITY;
    for (int k = 0; k < 6; k++) {
        assert_int_equal(room_images(&bad[k], src, im, 8), WDRT_INVALID_ARGS);
        assert_int_equal(room_fdn_size(&bad[k]), 0);
        assert_float_equal(room_mixing_time(&bad[k]), 0, 0);
    }
    room_config slow = ok;
    slow.fs = 4000;
    assert_int_equal(room_fdn_size(&slow), 0);
    assert_int_equal(room_images(&slow, src, im, 8), 6); /* images do not need fs */
    void *mem = NULL;
    assert_int_equal(posix_memalign(&mem, 16, room_fdn_size(&ok) + 16), 0);
    assert_null(room_fdn_init(&ok, (char *)mem + 8));
    assert_null(room_fdn_init(&slow, mem));
    assert_null(room_fdn_init(&ok, NULL));
    free(mem);
}

/* The wall filter's gain is exact at the two bands, and falls back to
 * gain at DC and hf at Nyquist when one pole cannot bend that far. */
static double first_order_gain(double b0, double b1, double a1, double f, double fs) {
    double w = 2 * PI * f / fs;
    double nr = b0 + b1 * cos(w), ni = -b1 * sin(w), dr = 1 + a1 * cos(w), di = -a1 * sin(w);
    return sqrt((nr * nr + ni * ni) / (dr * dr + di * di));
}

static void test_wall_filter(void **s) {
    (void)s;
    static const double g[][2] = {{0.9, 0.8}, {0.53, 0.26}, {0.7, 0.75}, {1, 1}, {0.2, 0.01}};
    static const double fss[] = {44100, 48000, 96000};
    for (int f = 0; f < 3; f++)
        for (int k = 0; k < 4; k++) {
            double b0, b1, a1;
            room_wall_filter_coefs(g[k][0], g[k][1], fss[f], &b0, &b1, &a1);
            assert_float_equal(first_order_gain(b0, b1, a1, 500, fss[f]), g[k][0], 1e-12);
            assert_float_equal(first_order_gain(b0, b1, a1, 4000, fss[f]), g[k][1], 1e-12);
            assert_true(fabs(a1) < 1);
        }
    double b0, b1, a1;
    room_wall_filter_coefs(0.2, 0.01, 48000, &b0, &b1, &a1);
    assert_float_equal((b0 + b1) / (1 + a1), 0.2, 1e-12);
    assert_float_equal((b0 - b1) / (1 - a1), 0.01, 1e-12);
}

/* ---- the FDN: reverberation time ---- */

typedef struct biquad {
    double b0, b1, b2, a1, a2, x1, x2, y1, y2;
} biquad;

/* A band-pass of 0 dB peak at f0 (the audio EQ cookbook's). */
static biquad bandpass(double f0, double q, double fs) {
    double w = 2 * PI * f0 / fs, al = sin(w) / (2 * q), a0 = 1 + al;
    biquad b = {al / a0, 0, -al / a0, -2 * cos(w) / a0, (1 - al) / a0, 0, 0, 0, 0};
    return b;
}

static double biquad_run(biquad *b, double x) {
    double y = b->b0 * x + b->b1 * b->x1 + b->b2 * b->x2 - b->a1 * b->y1 - b->a2 * b->y2;
    b->x2 = b->x1, b->x1 = x, b->y2 = b->y1, b->y1 = y;
    return y;
}

/* T60, s, of the outputs l and r (n samples each) in the band around f0:
 * each through two band-passes of Q 2 (about 2/3 octave), their energies
 * summed (one output alone beats with its few modes in the band, a couple
 * of per cent), Schroeder's backward integral, and a least-squares line
 * through its -5 .. -35 dB part. */
static double band_t60(const double *l, const double *r, long n, double f0, double fs) {
    biquad bq[4];
    for (int k = 0; k < 4; k++)
        bq[k] = bandpass(f0, 2, fs);
    double *e = malloc(sizeof(double) * (size_t)n);
    for (long i = 0; i < n; i++) {
        double yl = biquad_run(&bq[1], biquad_run(&bq[0], l[i]));
        double yr = biquad_run(&bq[3], biquad_run(&bq[2], r[i]));
        e[i] = yl * yl + yr * yr;
    }
    for (long i = n - 2; i >= 0; i--)
        e[i] += e[i + 1];
    double sx = 0, sy = 0, sxx = 0, sxy = 0, m = 0;
    for (long i = 0; i < n; i++) {
        double db = 10 * log10(e[i] / e[0]);
        if (db > -5)
            continue;
        if (db < -35)
            break;
        double t = i / fs;
        sx += t, sy += db, sxx += t * t, sxy += t * db, m++;
    }
    free(e);
    double slope = (m * sxy - sx * sy) / (m * sxx - sx * sx);
    return -60 / slope;
}

static void test_t60(void **s) {
    (void)s;
    static const struct {
        double x, y, z, tlo, thi, fs;
        int order;
    } rooms[] = {
        {5, 4, 3, 1.2, 0.8, 48000, 2},      {20, 15, 8, 2.5, 1.5, 48000, 3},
        {3, 3, 2.5, 0.5, 0.4, 44100, 1},    {10, 7, 4, 1.8, 0.9, 96000, 6},
        {12, 9, 3.5, 0.9, 1.1, 48000, 0},
    };
    double worst = 0;
    for (size_t k = 0; k < sizeof rooms / sizeof rooms[0]; k++) {
        room_config c = room(rooms[k].x, rooms[k].y, rooms[k].z, rooms[k].tlo, rooms[k].thi, rooms[k].order,
                             rooms[k].fs);
        long n = (long)(1.5 * fmax(c.t60_low, c.t60_high) * c.fs);
        double *l = malloc(sizeof(double) * (size_t)n), *r = malloc(sizeof(double) * (size_t)n);
        fdn_ir(&c, n, l, r);
        double lo = band_t60(l, r, n, 500, c.fs), hi = band_t60(l, r, n, 4000, c.fs);
        double elo = lo / c.t60_low - 1, ehi = hi / c.t60_high - 1;
        print_message("%gx%gx%g m, fs %g: T60 %.3f s at 500 Hz (%+.1f %%), %.3f s at 4 kHz (%+.1f %%)\n",
                      rooms[k].x, rooms[k].y, rooms[k].z, c.fs, lo, 100 * elo, hi, 100 * ehi);
        worst = fmax(worst, fmax(fabs(elo), fabs(ehi)));
        assert_true(fabs(elo) < 0.05 && fabs(ehi) < 0.05);
        free(l);
        free(r);
    }
    print_message("worst T60 error %.1f %%\n", 100 * worst);
}

/* ---- the FDN: losslessness, level, decorrelation ---- */

/* With its filters bypassed the FDN only moves energy between cells and
 * through an orthogonal matrix: an impulse's energy stays 1 to rounding
 * over 10^6 samples.  Its outputs' mean square then is the calibrated
 * 4 pi c / (V fs). */
static void test_lossless(void **s) {
    (void)s;
    room_config c = room(5, 4, 3, 1.2, 0.8, 2, 48000);
    room_fdn *f = fdn_new(&c);
    room_fdn_bypass_filters(f);
    enum { B = 1000, BLOCKS = 1000 };
    double in[B] = {1}, l[B], r[B], worst = 0, ml = 0, mr = 0;
    for (int b = 0; b < BLOCKS; b++) {
        memset(l, 0, sizeof l);
        memset(r, 0, sizeof r);
        room_fdn_process(f, in, l, r, B);
        in[0] = 0;
        worst = fmax(worst, fabs(room_fdn_energy(f) - 1));
        for (int i = 0; i < B; i++)
            ml += l[i] * l[i], mr += r[i] * r[i];
    }
    double want = 4 * PI * c.c / (room_volume(&c) * c.fs);
    ml /= (double)B * BLOCKS;
    mr /= (double)B * BLOCKS;
    print_message("lossless: energy drift %.2e over 10^6 samples; level %.2f %.2f dB re 4 pi c/(V fs)\n", worst,
                  10 * log10(ml / want), 10 * log10(mr / want));
    assert_true(worst < 1e-12);
    assert_true(fabs(10 * log10(ml / want)) < 1 && fabs(10 * log10(mr / want)) < 1);
    free(f);
}

/* The two outputs of a lossy FDN are nearly uncorrelated. */
static void test_decorrelated(void **s) {
    (void)s;
    room_config c = room(8, 6, 3, 1.5, 1.0, 2, 48000);
    long n = 72000;
    double *l = malloc(sizeof(double) * (size_t)n), *r = malloc(sizeof(double) * (size_t)n);
    fdn_ir(&c, n, l, r);
    double lr = 0, ll = 0, rr = 0;
    for (long i = 0; i < n; i++)
        lr += l[i] * r[i], ll += l[i] * l[i], rr += r[i] * r[i];
    double rho = lr / sqrt(ll * rr);
    print_message("left/right correlation %.4f\n", rho);
    assert_true(fabs(rho) < 0.1);
    free(l);
    free(r);
}

static int gcd(int a, int b) {
    return b ? gcd(b, a % b) : a;
}

/* The lines are pairwise coprime and the first output comes at the mixing time. */
static void test_lines(void **s) {
    (void)s;
    room_config c = room(20, 15, 8, 2.5, 1.5, 3, 48000);
    room_fdn *f = fdn_new(&c);
    int len[ROOM_FDN_N];
    room_fdn_lengths(f, len);
    char buf[256];
    int w = 0;
    for (int i = 0; i < ROOM_FDN_N; i++) {
        w += snprintf(buf + w, sizeof buf - (size_t)w, " %d", len[i]);
        for (int j = 0; j < i; j++) {
            assert_int_equal(gcd(len[i], len[j]), 1);
        }
    }
    print_message("20x15x8 m lines:%s; mixing time %.1f ms\n", buf, 1000 * room_mixing_time(&c));
    free(f);
    long n = (long)(0.5 * c.fs);
    double *l = malloc(sizeof(double) * (size_t)n), *r = malloc(sizeof(double) * (size_t)n);
    fdn_ir(&c, n, l, r);
    long first = 0;
    while (first < n && l[first] == 0 && r[first] == 0)
        first++;
    assert_int_equal(first, lround(room_mixing_time(&c) * c.fs));
    free(l);
    free(r);
}

/* Any block lengths give the same samples; clear gives back a fresh FDN;
 * process adds into what the outputs held (here the reference itself, so
 * the sum is exactly twice it). */
static void test_blocks_clear(void **s) {
    (void)s;
    room_config c = room(6, 5, 3, 0.8, 0.5, 2, 48000);
    enum { N = 20000 };
    static double in[N], ref_l[N], ref_r[N], l[N], r[N];
    tl_rng rng;
    tl_rng_seed(&rng, 7);
    for (int i = 0; i < 3000; i++)
        in[i] = tl_rng_signed(&rng);
    room_fdn *f = fdn_new(&c);
    room_fdn_process(f, in, ref_l, ref_r, N);
    static const int blocks[] = {1, 37, 64, 4096};
    for (int b = 0; b < 4; b++) {
        room_fdn_clear(f);
        memcpy(l, ref_l, sizeof l);
        memcpy(r, ref_r, sizeof r);
        for (int p = 0; p < N; p += blocks[b]) {
            int k = N - p < blocks[b] ? N - p : blocks[b];
            room_fdn_process(f, in + p, l + p, r + p, k);
        }
        for (int i = 0; i < N; i++)
            if (l[i] != 2 * ref_l[i] || r[i] != 2 * ref_r[i])
                fail_msg("block %d, sample %d: %.17g %.17g, want %.17g %.17g", blocks[b], i, l[i], r[i],
                         2 * ref_l[i], 2 * ref_r[i]);
    }
    free(f);
}

/* ---- the FDN: stability, finiteness, no allocation ---- */

/* Random rooms, T60s down to 0.05 s (in any ratio), any order and rate:
 * images finite and within (0, 1]; a noise burst then silence gives
 * finite, never subnormal samples, and the stored energy falls at least
 * 40 dB in 2 T60: 120 dB at the bands, and 60 dB at DC and Nyquist, whose
 * T60s the design keeps within twice the bands' (unless the lines lose
 * many dB per pass, where little is left after a pass or two anyway). */
static void test_fuzz(void **s) {
    (void)s;
    static const double rates[] = {8000, 22050, 44100, 48000, 96000};
    static room_image im[400];
    enum { B = 256 };
    double in[B], l[B], r[B];
    tl_rng rng;
    tl_rng_seed(&rng, 31337);
    for (int t = 0; t < 60; t++) {
        room_config c;
        for (int a = 0; a < 3; a++) {
            c.box[a] = 100 * tl_rng_signed(&rng);
            c.box[a + 3] = c.box[a] + exp(log(0.2) + (log(60) - log(0.2)) * tl_rng_uniform(&rng));
        }
        c.t60_low = 0.05 + 2.5 * pow(tl_rng_uniform(&rng), 2);
        c.t60_high = t % 7 == 0 ? c.t60_low / (1 + 20 * tl_rng_uniform(&rng)) : 0.05 + 2.5 * pow(tl_rng_uniform(&rng), 2);
        c.t60_high = fmax(c.t60_high, 0.05);
        c.order = (int)(tl_rng_next(&rng) % (ROOM_MAX_ORDER + 1));
        c.c = 330 + 20 * tl_rng_uniform(&rng);
        c.fs = rates[tl_rng_next(&rng) % 5];
        double src[3];
        for (int a = 0; a < 3; a++)
            src[a] = c.box[a] + (c.box[a + 3] - c.box[a]) * tl_rng_uniform(&rng);
        int n = room_images(&c, src, im, 400);
        assert_int_equal(n, room_max_images(c.order));
        for (int i = 0; i < n; i++)
            assert_true(isfinite(im[i].pos[0] + im[i].pos[1] + im[i].pos[2]) && im[i].gain > 0 &&
                        im[i].gain <= 1 && im[i].hf > 0 && im[i].hf <= 1);
        room_fdn *f = fdn_new(&c);
        double tmax = fmax(c.t60_low, c.t60_high), peak = 0;
        long burst = (long)(0.05 * c.fs), total = burst + (long)((2 * tmax + room_mixing_time(&c)) * c.fs);
        for (long p = 0; p < total; p += B) {
            for (int i = 0; i < B; i++)
                in[i] = p + i < burst ? tl_rng_signed(&rng) : 0;
            memset(l, 0, sizeof l);
            memset(r, 0, sizeof r);
            room_fdn_process(f, in, l, r, B);
            for (int i = 0; i < B; i++)
                if (!isfinite(l[i]) || !isfinite(r[i]) || fpclassify(l[i]) == FP_SUBNORMAL ||
                    fpclassify(r[i]) == FP_SUBNORMAL)
                    fail_msg("room %d: sample %ld: %g %g", t, p + i, l[i], r[i]);
            if (p < burst + (long)(room_mixing_time(&c) * c.fs))
                peak = fmax(peak, room_fdn_energy(f));
        }
        double drop = 10 * log10(room_fdn_energy(f) / peak);
        if (!(drop < -40))
            fail_msg("room %d (%g x %g x %g, T60 %g/%g s, fs %g): energy fell only %.1f dB", t, c.box[3] - c.box[0],
                     c.box[4] - c.box[1], c.box[5] - c.box[2], c.t60_low, c.t60_high, c.fs, drop);
        free(f);
    }
}

/* room_fdn_process and room_images never call the allocator. */
static void test_no_alloc(void **s) {
    (void)s;
    room_config c = room(9, 7, 3.5, 1.4, 0.9, 6, 48000);
    room_fdn *f = fdn_new(&c);
    enum { B = 512 };
    double in[B], l[B] = {0}, r[B] = {0}, src[3] = {2, 3, 1};
    static room_image im[400];
    for (int i = 0; i < B; i++)
        in[i] = i % 97 == 0;
    ca_allocs = 0;
    ca_in_rt = 1;
    for (int b = 0; b < 200; b++) {
        room_fdn_process(f, in, l, r, B);
        src[0] += 0.01;
        assert_int_equal(room_images(&c, src, im, 400), 376);
    }
    ca_in_rt = 0;
    assert_int_equal(ca_allocs, 0);
#if CA_COUNTING
    ca_in_rt = 1; /* the counter counts */
    void *volatile p = malloc(16);
    ca_in_rt = 0;
    free(p);
    assert_int_equal(ca_allocs, 1);
#endif
    free(f);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_geometry),     cmocka_unit_test(test_counts),
        cmocka_unit_test(test_by_hand),      cmocka_unit_test(test_allen_berkley),
        cmocka_unit_test(test_truncated),    cmocka_unit_test(test_invalid),
        cmocka_unit_test(test_wall_filter),  cmocka_unit_test(test_t60),
        cmocka_unit_test(test_lossless),     cmocka_unit_test(test_decorrelated),
        cmocka_unit_test(test_lines),        cmocka_unit_test(test_blocks_clear),
        cmocka_unit_test(test_fuzz),         cmocka_unit_test(test_no_alloc),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
