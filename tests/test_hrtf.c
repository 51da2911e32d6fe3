/*
 * test_hrtf.c - the binaural renderer (runtime/hrtf.h) on the MIT KEMAR
 * set: a source on one side reaches that ear first, by an interaural
 * time difference of 0.5-0.8 ms, and louder; a source in the median plane
 * reaches both ears alike; the ITD grows with azimuth; at a measured
 * direction the rendered responses are libmysofa's own, delays included;
 * a source that moves every block never clicks (and the same moves
 * without the crossfade do); renders do not depend on the host's blocks;
 * white noise keeps its energy within a few dB in every direction; errors
 * name the file; and hrtf_src_process allocates nothing (a counting
 * allocator stands in for malloc).
 */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>

#include <limits.h>
#include <math.h>
#include <mysofa.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "hrtf.h"
#include "testlib.h"

/* Sanitizers bring their own malloc: those builds leave the counting
 * allocator out. */

#define FS 48000.0
#define BLOCK 64
#define DEG (M_PI / 180)

#include "countalloc.h"

/* ---- helpers ---- */

static hrtf *g_h; /* the default set at FS, for the whole group */

static int setup(void **s) {
    (void)s;
    char err[512];
    g_h = hrtf_open(HRTF_DEFAULT_SOFA, FS, err, sizeof err);
    if (!g_h)
        print_error("%s", err);
    return g_h ? 0 : -1;
}

static int teardown(void **s) {
    (void)s;
    hrtf_close(g_h);
    return 0;
}

static hrtf_src *src_new(const hrtf *h) {
    void *mem = NULL;
    assert_int_equal(posix_memalign(&mem, 16, hrtf_src_size(h)), 0);
    hrtf_src *s = hrtf_src_init(h, mem);
    assert_ptr_equal(s, mem);
    return s;
}

/* The listener-frame unit vector at azimuth az (from ahead toward the
 * right) and elevation el, radians. */
static void dir_at(double az, double el, double d[3]) {
    d[0] = sin(az) * cos(el);
    d[1] = cos(az) * cos(el);
    d[2] = sin(el);
}

/* Renders in[0..n) through a fresh source of g_h in blocks of `block`,
 * block k heard from dirs[k] (or dirs[0] for every block if !moving),
 * into l and r (zeroed here). */
static void render(double (*dirs)[3], int moving, const double *in, long n, int block, double *l, double *r) {
    hrtf_src *s = src_new(g_h);
    memset(l, 0, sizeof(double) * (size_t)n);
    memset(r, 0, sizeof(double) * (size_t)n);
    for (long pos = 0, k = 0; pos < n; pos += block, k++) {
        int m = n - pos < block ? (int)(n - pos) : block;
        hrtf_src_process(g_h, s, dirs[moving ? k : 0], in + pos, l + pos, r + pos, m);
    }
    free(s);
}

static double energy(const double *x, long n) {
    double e = 0;
    for (long i = 0; i < n; i++)
        e += x[i] * x[i];
    return e;
}

/* First sample reaching a tenth of the peak. */
static long onset(const double *x, long n) {
    double pk = 0;
    for (long i = 0; i < n; i++)
        pk = fmax(pk, fabs(x[i]));
    for (long i = 0; i < n; i++)
        if (fabs(x[i]) >= 0.1 * pk)
            return i;
    return -1;
}

#define IRN 1024 /* longer than any response: 256 taps after a delay of at most ~35 */

/* The impulse responses of direction d: ITD (samples by which the left
 * ear leads) and ILD (dB by which it is louder). */
static void itd_ild(const double d[3], double *itd, double *ild) {
    double in[IRN] = {1}, l[IRN], r[IRN], dirs[1][3] = {{d[0], d[1], d[2]}};
    render(dirs, 0, in, IRN, BLOCK, l, r);
    *itd = (double)(onset(r, IRN) - onset(l, IRN));
    *ild = 10 * log10(energy(l, IRN) / energy(r, IRN));
}

static double max_step(const double *x, long from, long n) {
    double m = 0;
    for (long i = from + 1; i < n; i++)
        m = fmax(m, fabs(x[i] - x[i - 1]));
    return m;
}

/* ---- tests ---- */

/* A missing file, a file that is not SOFA and a bad rate: NULL, with
 * "PATH: error: WHY". */
static void test_errors(void **s) {
    (void)s;
    char err[512];
    assert_null(hrtf_open("/nonexistent/dir/head.sofa", FS, err, sizeof err));
    print_message("%s", err);
    assert_non_null(strstr(err, "/nonexistent/dir/head.sofa: error: cannot read: "));
    assert_non_null(strstr(err, "No such file"));
    assert_null(hrtf_open("Makefile", FS, err, sizeof err));
    print_message("%s", err);
    assert_int_equal(strncmp(err, "Makefile: error: ", 17), 0);
    assert_null(hrtf_open(NULL, 0, err, sizeof err));
    print_message("%s", err);
    assert_int_equal(strncmp(err, HRTF_DEFAULT_SOFA ": error: sample rate 0 Hz out of range", 40), 0);
    assert_null(hrtf_open("/nonexistent/dir/head.sofa", FS, NULL, 0));
    assert_null(hrtf_src_init(NULL, err));
}

/* 5.33 ms of taps at either rate; NULL opens the default file. */
static void test_length(void **s) {
    (void)s;
    assert_int_equal(hrtf_length(g_h), 256);
    print_message("48 kHz: %d taps, %zu bytes per source\n", hrtf_length(g_h), hrtf_src_size(g_h));
    assert_true(hrtf_src_size(g_h) < 32768);
    hrtf *h = hrtf_open(NULL, 44100, NULL, 0); /* the file's own rate: no resampling */
    assert_non_null(h);
    assert_int_equal(hrtf_length(h), 236);
    hrtf_close(h);
}

/* Left: the left ear leads by 0.5-0.8 ms and is louder; right: the
 * mirror, the same to a sample and a tenth of a dB (KEMAR is
 * symmetric). */
static void test_sides(void **s) {
    (void)s;
    double left[3] = {-1, 0, 0}, right[3] = {1, 0, 0}, itd_l, ild_l, itd_r, ild_r;
    itd_ild(left, &itd_l, &ild_l);
    itd_ild(right, &itd_r, &ild_r);
    print_message("left:  ITD %.3f ms (%g samples), ILD %.1f dB\n", itd_l / FS * 1e3, itd_l, ild_l);
    print_message("right: ITD %.3f ms (%g samples), ILD %.1f dB\n", itd_r / FS * 1e3, itd_r, ild_r);
    assert_true(itd_l / FS >= 0.5e-3 && itd_l / FS <= 0.8e-3);
    assert_true(ild_l > 6);
    assert_true(-itd_r / FS >= 0.5e-3 && -itd_r / FS <= 0.8e-3);
    assert_true(ild_r < -6);
    assert_true(fabs(itd_l + itd_r) <= 1 && fabs(ild_l + ild_r) < 0.1);
}

/* Ahead, behind and above (the median plane): both ears alike. */
static void test_median_plane(void **s) {
    (void)s;
    double dirs[3][3] = {{0, 1, 0}, {0, -1, 0}, {0, 0, 1}};
    for (int i = 0; i < 3; i++) {
        double itd, ild;
        itd_ild(dirs[i], &itd, &ild);
        print_message("(%g %g %g): ITD %g samples, ILD %.2f dB\n", dirs[i][0], dirs[i][1], dirs[i][2], itd, ild);
        assert_true(fabs(itd) <= 1);
        assert_true(fabs(ild) < 1);
    }
}

/* From ahead to 80 degrees right the ITD grows (by the blend of the
 * grid, every degree; a dip of one sample is the rounding of a delay). */
static void test_itd_grows(void **s) {
    (void)s;
    double top = 0;
    for (int deg = 0; deg <= 80; deg++) {
        double d[3], itd, ild;
        dir_at(deg * DEG, 0, d);
        itd_ild(d, &itd, &ild);
        double lead = 0 - itd; /* the right ear's lead (0 - x: never -0) */
        if (deg % 10 == 0)
            print_message("azimuth %2d: ITD %.3f ms, ILD %.1f dB\n", deg, lead / FS * 1e3, 0 - ild);
        assert_true(lead >= top - 1);
        top = fmax(top, lead);
    }
    assert_true(top / FS > 0.5e-3);
}

/* At a measured direction the rendered responses are the measurement
 * (libmysofa's, at the same rate and loudness) over the unfaded window:
 * the same samples, the same ITD, and the same common lag everywhere. */
static void test_matches_measurement(void **s) {
    (void)s;
    int len = 0, err = 0;
    struct MYSOFA_EASY *e = mysofa_open(HRTF_DEFAULT_SOFA, (float)FS, &len, &err);
    assert_non_null(e);
    float *ml = malloc(sizeof(float) * (size_t)len), *mr = malloc(sizeof(float) * (size_t)len), dl, dr;
    double dirs[6][3], in[IRN] = {1}, l[IRN], r[IRN];
    dir_at(0, 0, dirs[0]);
    dir_at(-90 * DEG, 0, dirs[1]);
    dir_at(90 * DEG, 0, dirs[2]);
    dir_at(180 * DEG, 0, dirs[3]);
    dir_at(45 * DEG, 0, dirs[4]);
    dir_at(0, 30 * DEG, dirs[5]);
    long lag0 = LONG_MIN;
    for (int k = 0; k < 6; k++) {
        const double *d = dirs[k];
        mysofa_getfilter_float_nointerp(e, (float)d[1], (float)-d[0], (float)d[2], ml, mr, &dl, &dr);
        render(dirs + k, 0, in, IRN, BLOCK, l, r);
        for (int ear = 0; ear < 2; ear++) {
            const double *y = ear ? r : l;
            const float *m = ear ? mr : ml;
            long start = 0, lag;
            while (y[start] == 0)
                start++;
            /* the lag that lines the ear's first sample up with the measurement's */
            double best = INFINITY, mpk = 0;
            for (int i = 0; i < len; i++)
                mpk = fmax(mpk, fabs(m[i]));
            long bestlag = 0;
            for (lag = -start; lag < len - start - 200; lag++) {
                double err2 = 0;
                for (long j = 0; j < 200; j++)
                    err2 += pow(y[start + j] - m[start + lag + j], 2);
                if (err2 < best)
                    best = err2, bestlag = lag;
            }
            double worst = 0;
            for (long j = 0; j < hrtf_length(g_h) - 48 && start + bestlag + j < len; j++)
                worst = fmax(worst, fabs(y[start + j] - m[start + bestlag + j]));
            print_message("(%5.2f %5.2f %5.2f) ear %d: starts at %ld, lag %ld, max error %.1e of peak\n", d[0], d[1],
                          d[2], ear, start, bestlag, worst / mpk);
            assert_true(worst < 1e-6 * mpk);
            assert_true(lag0 == LONG_MIN || bestlag == lag0);
            lag0 = bestlag;
        }
    }
    free(ml);
    free(mr);
    mysofa_close(e);
}

/* A 1 kHz tone whose source jumps 15 degrees every block: the largest
 * step between samples stays within 1.2 times that of the tone rendered
 * at any fixed direction it visits; splicing those fixed renders block
 * by block (the same moves without the crossfade) clicks. */
static void test_no_click(void **s) {
    (void)s;
    enum { NDIR = 24, N = 8 * NDIR * BLOCK, WARM = 512 };
    double(*dirs)[3] = malloc(sizeof(double[3]) * (N / BLOCK));
    double *in = malloc(sizeof(double) * N), *l = malloc(sizeof(double) * N), *r = malloc(sizeof(double) * N);
    double *fl = malloc(sizeof(double) * N), *fr = malloc(sizeof(double) * N);
    double *hl = malloc(sizeof(double) * N), *hr = malloc(sizeof(double) * N);
    for (long i = 0; i < N; i++)
        in[i] = 0.5 * sin(2 * M_PI * 1000 * i / FS);
    for (int k = 0; k < N / BLOCK; k++)
        dir_at((k % NDIR) * 15 * DEG, 0, dirs[k]);
    double fixed = 0;
    for (int j = 0; j < NDIR; j++) {
        render(dirs + j, 0, in, N, BLOCK, fl, fr);
        fixed = fmax(fixed, fmax(max_step(fl, WARM, N), max_step(fr, WARM, N)));
        for (int k = j; k < N / BLOCK; k += NDIR) {
            memcpy(hl + k * BLOCK, fl + k * BLOCK, sizeof(double) * BLOCK);
            memcpy(hr + k * BLOCK, fr + k * BLOCK, sizeof(double) * BLOCK);
        }
    }
    render(dirs, 1, in, N, BLOCK, l, r);
    double moving = fmax(max_step(l, WARM, N), max_step(r, WARM, N));
    double hard = fmax(max_step(hl, WARM, N), max_step(hr, WARM, N));
    print_message("largest step: fixed %.4f, moving %.4f (%.2fx), spliced %.4f (%.2fx)\n", fixed, moving,
                  moving / fixed, hard, hard / fixed);
    assert_true(moving <= 1.2 * fixed);
    assert_true(hard >= 2 * fixed);
    free(dirs);
    free(in), free(l), free(r), free(fl), free(fr), free(hl), free(hr);
}

/* The same noise at a fixed direction in host blocks of 4096, 64, 37 and
 * 1 frames: the same render bit for bit.  A direction of any length is
 * its unit vector's; zero and NaN are ahead.  Output is added to what is
 * there, and `in` may be an output. */
static void test_blocks(void **s) {
    (void)s;
    enum { N = 6000 };
    double *in = malloc(sizeof(double) * N), *l0 = malloc(sizeof(double) * N), *r0 = malloc(sizeof(double) * N);
    double *l = malloc(sizeof(double) * N), *r = malloc(sizeof(double) * N);
    tl_rng g;
    tl_rng_seed(&g, 7);
    for (int i = 0; i < N; i++)
        in[i] = tl_rng_signed(&g);
    double d[1][3] = {{0.3, 0.8, 0.2}}, d2[1][3] = {{0.6, 1.6, 0.4}};
    render(d, 0, in, N, 4096, l0, r0);
    int blocks[] = {64, 37, 1};
    for (int b = 0; b < 3; b++) {
        render(d, 0, in, N, blocks[b], l, r);
        assert_buf_near(l, l0, N, 0);
        assert_buf_near(r, r0, N, 0);
    }
    render(d2, 0, in, N, 64, l, r);
    assert_buf_near(l, l0, N, 0);
    double ahead[1][3] = {{0, 1, 0}}, odd[2][3] = {{0, 0, 0}, {NAN, 1, 0}};
    render(ahead, 0, in, N, 64, l0, r0);
    for (int k = 0; k < 2; k++) {
        render(odd + k, 0, in, N, 64, l, r);
        assert_buf_near(l, l0, N, 0);
    }
    hrtf_src *src = src_new(g_h); /* in place: in is out_l, which holds the input */
    memcpy(l, in, sizeof(double) * N);
    for (int i = 0; i < N; i++)
        r[i] = 0.25;
    for (int pos = 0; pos < N; pos += 100)
        hrtf_src_process(g_h, src, ahead[0], l + pos, l + pos, r + pos, 100);
    for (int i = 0; i < N; i++)
        l[i] -= in[i], r[i] -= 0.25;
    assert_buf_near(l, l0, N, 1e-12);
    assert_buf_near(r, r0, N, 1e-12);
    free(src);
    free(in), free(l0), free(r0), free(l), free(r);
}

/* White noise from 26 directions (the faces, edges and corners of a
 * cube): the two ears' energy stays within 4 dB of its mean over them. */
static void test_energy(void **s) {
    (void)s;
    enum { N = 48000 };
    double *in = malloc(sizeof(double) * N), *l = malloc(sizeof(double) * N), *r = malloc(sizeof(double) * N);
    tl_rng g;
    tl_rng_seed(&g, 11);
    for (int i = 0; i < N; i++)
        in[i] = tl_rng_signed(&g);
    double db[26], mean = 0, lo = INFINITY, hi = -INFINITY;
    int n = 0;
    for (int x = -1; x <= 1; x++)
        for (int y = -1; y <= 1; y++)
            for (int z = -1; z <= 1; z++) {
                if (!x && !y && !z)
                    continue;
                double d[1][3] = {{x, y, z}};
                render(d, 0, in, N, BLOCK, l, r);
                db[n] = 10 * log10((energy(l, N) + energy(r, N)) / energy(in, N));
                mean += db[n] / 26, lo = fmin(lo, db[n]), hi = fmax(hi, db[n]);
                n++;
            }
    print_message("gain of both ears over 26 directions: %.1f to %.1f dB, mean %.1f dB\n", lo, hi, mean);
    for (int i = 0; i < 26; i++)
        assert_true(fabs(db[i] - mean) < 4);
    free(in), free(l), free(r);
}


/* init, process (a source turning every block, blocks of every length
 * up to 4096) and clear allocate nothing.  Prints the cost per source
 * and sample, steady and crossfading every block. */
static void test_no_alloc(void **s) {
    (void)s;
    if (!CA_COUNTING)
        skip();
    enum { N = 96000 };
    double *in = malloc(sizeof(double) * N), *l = calloc(N, sizeof(double)), *r = calloc(N, sizeof(double));
    void *mem = NULL;
    assert_int_equal(posix_memalign(&mem, 16, hrtf_src_size(g_h)), 0);
    for (int i = 0; i < N; i++)
        in[i] = sin(0.05 * i);
    double ns[2];
    ca_allocs = 0;
    ca_in_rt = 1;
    hrtf_src *src = hrtf_src_init(g_h, mem);
    for (int turning = 0; turning < 2; turning++) {
        clock_t t0 = clock();
        for (int pos = 0, k = 0; pos + BLOCK <= N; pos += BLOCK, k++) {
            double d[3];
            dir_at(turning ? k * 7 * DEG : 0.3, 0.1, d);
            hrtf_src_process(g_h, src, d, in + pos, l + pos, r + pos, BLOCK);
        }
        ns[turning] = (double)(clock() - t0) / CLOCKS_PER_SEC / N * 1e9;
    }
    for (int n = 1, pos = 0; pos + n <= N && n <= 4096; pos += n, n = n * 3 + 1) {
        double d[3] = {sin(n), cos(n), 0.1};
        hrtf_src_process(g_h, src, d, in + pos, l + pos, r + pos, n);
    }
    hrtf_src_clear(src);
    ca_in_rt = 0;
    print_message("%ld allocations; %.0f ns per sample steady, %.0f crossfading every block of %d\n", ca_allocs,
                  ns[0], ns[1], BLOCK);
    assert_int_equal(ca_allocs, 0);
    free(mem);
    free(in), free(l), free(r);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_errors),         cmocka_unit_test(test_length),
        cmocka_unit_test(test_sides),          cmocka_unit_test(test_median_plane),
        cmocka_unit_test(test_itd_grows),      cmocka_unit_test(test_matches_measurement),
        cmocka_unit_test(test_no_click),       cmocka_unit_test(test_blocks),
        cmocka_unit_test(test_energy),         cmocka_unit_test(ca_test_counter_counts),
        cmocka_unit_test(test_no_alloc),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
