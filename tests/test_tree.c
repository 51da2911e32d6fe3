/*
 * test_tree.c - timbre trees (runtime/tt.h) against their definitions:
 * the drum of Hahn et al. and an FM siren against their closed forms
 * (-120 dB), broadcasting and widths, rvector, the waveforms and the
 * band-limited oscillator (aliasing against the naive waveform), the
 * integral, env, delay, the RBJ filters against their prewarped analog
 * prototypes, the resonator's impulse response and T60, samples (replay
 * rate, channels, Catmull-Rom), energetic replay (pitch, spectral purity,
 * tempo), the importance weights of Tong and Wong and their inversion,
 * sputter, the reader's errors with their positions, the reader fuzzed,
 * and a class that allocates nothing while it runs.
 *
 * Every measured error is printed ("tree: ..." lines) so it can be quoted.
 * Tolerances come from the method: rounding bounds of the recurrences and
 * accumulations, the stated requirement (-120 dB, -80 dB), or the
 * aliasing a polyBLEP-style correction removes (derived in the comments).
 */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>

#include <complex.h>
#include <float.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "countalloc.h"
#include "partials.h"
#include "testlib.h"
#include "tt.h"

#define FS 48000.0
#define EPS DBL_EPSILON
static const long double PI_L = 3.141592653589793238462643383279502884L;

static char g_dir[64];

static int setup(void **s) {
    (void)s;
    return tl_temp_dir(g_dir, "wdrt-tree");
}

static int teardown(void **s) {
    (void)s;
    tl_remove_dir(g_dir);
    return 0;
}

/* ---- helpers ---- */

static void report(const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    printf("tree: ");
    vprintf(fmt, ap);
    printf("\n");
    fflush(stdout);
    va_end(ap);
}

static double db(double x) { return x > 0 ? 20.0 * log10(x) : -400.0; }

/* The file of `text` (a bare expression, or definitions: read as the file
 * g_dir/t.tt), failing the test on an error. */
static tt_file *read_text(const char *text) {
    char err[2048] = "", path[256];
    snprintf(path, sizeof path, "%s/t.tt", g_dir);
    tt_file *f = tt_file_read(path, text, strlen(text), err, sizeof err);
    if (!f)
        fail_msg("reading %s: %s", text, err);
    return f;
}

static tt_prog *compile_text(const char *text) {
    char err[2048] = "";
    tt_file *f = read_text(text);
    tt_prog *p = tt_compile(tt_file_tree(f, -1), err, sizeof err);
    if (!p)
        fail_msg("compiling %s: %s", text, err);
    tt_file_free(f);
    return p;
}

/* n samples of the file's last tree at fs with params (NULL: defaults). */
static double *render_p(const char *text, double fs, long n, const double *params) {
    char err[2048] = "";
    tt_prog *p = compile_text(text);
    double *y = malloc(sizeof *y * (size_t)(n + 1));
    assert_non_null(y);
    if (tt_render(p, fs, params, y, n, err, sizeof err) != 0)
        fail_msg("rendering %s: %s", text, err);
    tt_prog_free(p);
    return y;
}

static double *render(const char *text, double fs, long n) { return render_p(text, fs, n, NULL); }

/* A render's sink that keeps its frames, up to cap, in runs of at most 4096. */
typedef struct sunk {
    double *y;
    long n, cap;
    int runs;
} sunk;

static int sink_runs(const double *y, long n, void *user) {
    sunk *k = user;
    if (n > 4096 || k->n + n > k->cap)
        return 1;
    memcpy(k->y + k->n, y, sizeof *y * (size_t)n);
    k->n += n;
    k->runs++;
    return 0;
}

/* The value of a constant tree (its first sample). */
static double value_of(const char *text) {
    double *y = render(text, FS, 1), v = y[0];
    free(y);
    return v;
}

static double peak(const double *x, long n) {
    double m = 0;
    for (long i = 0; i < n; i++)
        m = fmax(m, fabs(x[i]));
    return m;
}

static double max_diff(const double *a, const double *b, long n) {
    double m = 0;
    for (long i = 0; i < n; i++)
        m = fmax(m, fabs(a[i] - b[i]));
    return m;
}

/* max |y - ref| relative to the peak of ref, in dB */
static double rel_err_db(const double *y, const double *ref, long n) { return db(max_diff(y, ref, n) / peak(ref, n)); }

/* A class of p at fs with a 64-byte aligned zeroed state (not yet
 * initialised). */
typedef struct klass {
    tt_class c;
    void *st;
    size_t size;
} klass;

static void klass_make(klass *k, const tt_prog *p, double fs) {
    char err[1024] = "";
    memset(k, 0, sizeof *k);
    if (tt_class_init(&k->c, p, fs, err, sizeof err) != 0)
        fail_msg("tt_class_init: %s", err);
    assert_int_equal(k->c.cls.n_inputs, 0);
    assert_int_equal(k->c.cls.n_outputs, 1);
    k->size = (k->c.cls.state_size + 63) / 64 * 64;
    k->st = NULL;
    assert_int_equal(posix_memalign(&k->st, 64, k->size ? k->size : 64), 0);
    memset(k->st, 0, k->size);
}

static void klass_start(klass *k, double fs) {
    k->c.cls.init(k->st, fs);
    tt_class_bind(k->st, &k->c);
}

static void klass_free(klass *k) {
    free(k->st);
    tt_class_uninit(&k->c);
}

/* n samples of the class in host blocks of the given lengths (cycled). */
static void klass_run(klass *k, double *y, long n, const int *blocks, int nb) {
    for (long pos = 0, b = 0; pos < n; b++) {
        long len = blocks[b % nb];
        if (len > n - pos)
            len = n - pos;
        double *out[1] = {y + pos};
        k->c.cls.process(k->st, NULL, out, (int)len);
        pos += len;
    }
}

/* "LINE:COL" of the `occ`-th (from 0) occurrence of needle in text. */
static const char *pos_of(const char *text, const char *needle, int occ) {
    static char buf[32];
    const char *at = strstr(text, needle);
    for (int i = 0; i < occ && at; i++)
        at = strstr(at + 1, needle);
    if (!at)
        fail_msg("'%s' is not in '%s'", needle, text);
    int line = 1, col = 1;
    for (const char *c = text; c < at; c++)
        if (*c == '\n')
            line++, col = 1;
        else
            col++;
    snprintf(buf, sizeof buf, "%d:%d", line, col);
    return buf;
}

/* sin(2 pi x) for x in cycles, reduced first so large phases stay exact */
static long double sin_cyc(long double x) { return sinl(2 * PI_L * (x - floorl(x))); }

/* Catmull-Rom at position p of x[0..len) (0 outside). */
static double cr_at(const double *x, long len, double p) {
    double m = floor(p), u = p - m, v[4];
    for (int j = 0; j < 4; j++) {
        long k = (long)m - 1 + j;
        v[j] = k >= 0 && k < len ? x[k] : 0.0;
    }
    double w0 = (-u * u * u + 2 * u * u - u) / 2, w1 = (3 * u * u * u - 5 * u * u + 2) / 2,
           w2 = (-3 * u * u * u + 4 * u * u + u) / 2, w3 = (u * u * u - u * u) / 2;
    return w0 * v[0] + w1 * v[1] + w2 * v[2] + w3 * v[3];
}

/* ---- closed forms: the drum and the siren ---- */

static const char g_drum[] = "(tree drum (params (loudness 1) (damping 0.0005))\n"
                             "  (* loudness (combine (* (sine (* (rvector 200 20 10000) t))\n"
                             "                          (damp (* (rvector 200 20 10000) (* damping t)))))))\n";

static void drum_ref(double *ref, long n, double fs, double loudness, double damping) {
    double f[20];
    for (int i = 0; i < 20; i++)
        f[i] = 200 + (10000 - 200) * tt_rvector_u(20, i);
    for (long k = 0; k < n; k++) {
        long double t = (long double)k / fs, s = 0;
        for (int i = 0; i < 20; i++)
            s += sin_cyc(f[i] * t) * expl(-(long double)f[i] * (damping * t));
        ref[k] = (double)(loudness * s);
    }
}

/* The drum agrees with loudness * sum sin(2 pi f_i t) exp(-f_i damping t)
 * to better than -120 dB of its peak over 2.5 s: with its defaults, with
 * params given to tt_render, through a class run in odd host blocks with
 * set_param, and through (use drum ...). */
static void test_drum(void **s) {
    (void)s;
    const long n = (long)(2.5 * FS);
    double *ref = malloc(sizeof *ref * (size_t)n), *y;
    drum_ref(ref, n, FS, 1, 0.0005);
    y = render(g_drum, FS, n);
    double e1 = rel_err_db(y, ref, n);
    free(y);
    report("drum (defaults), 2.5 s: max error %.1f dB re peak", e1);
    assert_true(e1 < -120);

    double params[2] = {0.8, 0.0003};
    drum_ref(ref, n, FS, 0.8, 0.0003);
    y = render_p(g_drum, FS, n, params);
    double e2 = rel_err_db(y, ref, n);
    report("drum (loudness 0.8, damping 0.0003), tt_render: max error %.1f dB re peak", e2);
    assert_true(e2 < -120);

    /* a class, host blocks that are not multiples of TT_BLOCK */
    tt_prog *p = compile_text(g_drum);
    klass k;
    klass_make(&k, p, FS);
    assert_int_equal(k.c.cls.n_params, 2);
    assert_string_equal(k.c.cls.params[0].name, "loudness");
    assert_string_equal(k.c.cls.params[1].name, "damping");
    klass_start(&k, FS);
    assert_int_equal(k.c.cls.set_param(k.st, 0, 0.8), 0);
    assert_int_equal(k.c.cls.set_param(k.st, 1, 0.0003), 0);
    double *z = malloc(sizeof *z * (size_t)n);
    static const int blocks[] = {1, 37, 64, 100, 333, 7, 1000, 65, 63};
    klass_run(&k, z, n, blocks, 9);
    double e3 = rel_err_db(z, ref, n);
    report("drum through a class in host blocks of 1..1000 frames: max error %.1f dB re peak; "
           "%.1f dB from tt_render's",
           e3, db(max_diff(z, y, n) / peak(ref, n)));
    assert_true(e3 < -120);
    klass_free(&k);
    tt_prog_free(p);
    free(y), free(z);

    /* use, with a param given as an expression */
    char text[1024];
    snprintf(text, sizeof text, "%s(use drum (loudness (* 0.25 2)) (damping 0.0003))", g_drum);
    drum_ref(ref, n, FS, 0.5, 0.0003);
    y = render(text, FS, n);
    double e4 = rel_err_db(y, ref, n);
    report("(use drum (loudness (* 0.25 2)) (damping 0.0003)): max error %.1f dB re peak", e4);
    assert_true(e4 < -120);
    free(y), free(ref);
}

/* 0.5 sin(2 pi (600 t + 3 sin(2 pi 0.7 t))) to -120 dB over 3 s. */
static void test_siren(void **s) {
    (void)s;
    const long n = (long)(3 * FS);
    double *y = render("(* 0.5 (sine (+ (* 600 t) (* 3 (sine (* 0.7 t))))))", FS, n);
    double *ref = malloc(sizeof *ref * (size_t)n);
    for (long k = 0; k < n; k++) {
        long double t = (long double)k / FS;
        ref[k] = (double)(0.5L * sin_cyc(600 * t + 3 * sin_cyc(0.7L * t)));
    }
    double e = rel_err_db(y, ref, n);
    report("FM siren, 3 s: max error %.1f dB re peak", e);
    assert_true(e < -120);
    free(y), free(ref);
}

/* ---- widths, rates, rvector ---- */

static void test_broadcast(void **s) {
    (void)s;
    /* a scalar over a vector; vectors elementwise; combine; nesting */
    assert_float_equal(value_of("(combine (vector 1 2 3))"), 6, 0);
    assert_float_equal(value_of("(combine (+ 1 (vector 1 2 3)))"), 9, 0);
    assert_float_equal(value_of("(combine (* (vector 1 2 3) (vector 4 5 6)))"), 32, 0);
    assert_float_equal(value_of("(combine (- (vector 1 2 3) 1))"), 3, 0);
    assert_float_equal(value_of("(combine (max 2 (vector 1 2 3) (vector 0 0 5)))"), 9, 0);
    assert_float_equal(value_of("(combine (vector (vector 1 2) 3))"), 6, 0);
    assert_float_equal(value_of("(combine (* (vector (vector 1 2) 3) (vector 1 10 100)))"), 321, 0);

    /* widths and rates as tt_check sets them */
    tt_file *f = read_text("(combine (vector (vector 1 2) 3))");
    const tt_node *r = tt_file_tree(f, -1)->root;
    assert_int_equal(r->op, TT_COMBINE);
    assert_int_equal(r->width, 1);
    assert_int_equal(r->a[0]->width, 3);
    assert_int_equal(r->a[0]->a[0]->width, 2);
    assert_int_equal(r->rate, TT_CONST);
    tt_file_free(f);
    f = read_text("(tree x (params (g 1)) (+ (* g 2) (sine (* 440 t))))");
    r = tt_file_tree(f, -1)->root;
    assert_int_equal(r->rate, TT_AUDIO);
    assert_int_equal(r->a[0]->rate, TT_CONTROL);
    tt_file_free(f);
    f = read_text("(combine (rvector 200 20 10000))");
    assert_int_equal(tt_file_tree(f, -1)->root->a[0]->width, 20);
    tt_file_free(f);

    /* trees a program builds are checked the same way */
    char err[2048] = "";
    tt_tree *t = calloc(1, sizeof *t);
    t->name = strdup("");
    tt_node *add = tt_node_new(TT_ADD, 2), *v3 = tt_node_new(TT_VECTOR, 3), *v5 = tt_node_new(TT_VECTOR, 5);
    for (int i = 0; i < 3; i++)
        v3->a[i] = tt_node_new(TT_NUM, 0), v3->a[i]->v = i + 1;
    for (int i = 0; i < 5; i++)
        v5->a[i] = tt_node_new(TT_NUM, 0), v5->a[i]->v = i + 1;
    add->a[0] = v3, add->a[1] = v5;
    t->root = tt_node_new(TT_COMBINE, 1);
    t->root->a[0] = add;
    assert_int_equal(tt_check(t, err, sizeof err), -1);
    if (strncmp(err, "tree: error: ", 13) != 0)
        fail_msg("expected \"tree: error: ...\", got \"%s\"", err);
    /* the same tree with equal widths checks, compiles and sums */
    tt_node_free(add->a[1]);
    add->a[1] = tt_node_new(TT_NUM, 0), add->a[1]->v = 10;
    assert_int_equal(tt_check(t, err, sizeof err), 0);
    assert_int_equal(add->width, 3);
    tt_prog *p = tt_compile(t, err, sizeof err);
    if (!p)
        fail_msg("tt_compile: %s", err);
    double y[3];
    assert_int_equal(tt_render(p, FS, NULL, y, 3, err, sizeof err), 0);
    assert_float_equal(y[2], 36, 0);
    tt_prog_free(p);
    tt_tree_free(t);
}

/* Widths 3 and 5 do not mix: an error at the argument that does not fit,
 * the second vector at 3:6. */
static void test_width_error(void **s) {
    (void)s;
    static const char bad[] = "(combine\n  (+ (vector 1 2 3)\n     (vector 1 2 3 4 5)))";
    char err[2048] = "";
    tt_file *f = tt_file_from_string(bad, err, sizeof err);
    assert_null(f);
    report("widths 3 and 5: \"%.*s\"", (int)strcspn(err, "\n"), err);
    assert_non_null(strstr(err, ": error: "));
    if (!strstr(err, "3:6: error: a vector of 5 where + takes vectors of 3"))
        fail_msg("expected the error at 3:6 (the vector of 5), got \"%s\"", err);
}

/* rvector: values in [LO, HI), stratified, the same for the same N on
 * every call and in every program; (rvector LO N HI) element i is
 * LO + (HI - LO) u(N, i). */
static void test_rvector(void **s) {
    (void)s;
    static const int ns[] = {1, 2, 3, 7, 20, 64, 1000, TT_MAX_WIDTH};
    for (size_t j = 0; j < sizeof ns / sizeof *ns; j++) {
        int n = ns[j];
        double mean = 0;
        for (int i = 0; i < n; i++) {
            double u = tt_rvector_u(n, i);
            assert_true(u >= 0 && u < 1);
            if (!(u >= (double)i / n && u < (double)(i + 1) / n))
                fail_msg("tt_rvector_u(%d, %d) = %.17g is not in its cell [%g, %g)", n, i, u, (double)i / n,
                         (double)(i + 1) / n);
            assert_true(u == tt_rvector_u(n, i));
            mean += u / n;
        }
        if (n >= 64) /* pseudo-random within the cells: the mean is near 1/2 */
            assert_true(fabs(mean - 0.5) < 1.0 / n);
    }
    /* not the cell centres: pseudo-random positions */
    int centred = 0;
    for (int i = 0; i < 20; i++)
        centred += fabs(tt_rvector_u(20, i) - (i + 0.5) / 20) < 1e-9;
    assert_true(centred < 20);

    /* element i of the tree's rvector, picked with a one-hot vector */
    for (int i = 0; i < 5; i++) {
        char text[256];
        snprintf(text, sizeof text, "(combine (* (rvector -3 5 7) (vector %d %d %d %d %d)))", i == 0, i == 1, i == 2,
                 i == 3, i == 4);
        double want = -3 + (7 - -3) * tt_rvector_u(5, i), got = value_of(text);
        if (fabs(got - want) > 4 * EPS * 7)
            fail_msg("element %d of (rvector -3 5 7): %.17g, want %.17g", i, got, want);
        assert_true(got >= -3 + 10.0 * i / 5 && got < -3 + 10.0 * (i + 1) / 5);
    }
    double a = value_of("(combine (rvector 0 7 1))"), b = value_of("(combine (rvector 0 7 1))");
    assert_true(a == b);
}

/* ---- waveforms and the oscillator ---- */

/* (sine X) (saw X) (square X) (triangle X) (damp X) of a phase in cycles,
 * against their definitions over phases that include the corners. */
static void test_waves(void **s) {
    (void)s;
    const long n = 4800;
    /* X = 37.5 t - 3.3: phases from -3.3 on, 0.00078125 cycles a sample */
    double *sn = render("(sine (- (* 37.5 t) 3.3))", FS, n), *sw = render("(saw (- (* 37.5 t) 3.3))", FS, n),
           *sq = render("(square (- (* 37.5 t) 3.3))", FS, n), *tr = render("(triangle (- (* 37.5 t) 3.3))", FS, n),
           *dm = render("(damp (* 3 t))", FS, n);
    double es = 0, ew = 0, et = 0, ed = 0;
    long sq_bad = 0;
    for (long k = 0; k < n; k++) {
        double x = 37.5 * k / FS - 3.3, fr = x - floor(x), fr2 = (x + 0.5) - floor(x + 0.5),
               fr4 = (x + 0.25) - floor(x + 0.25);
        es = fmax(es, fabs(sn[k] - sin(2 * M_PI * x)));
        double wref = 2 * fr2 - 1;
        /* near the jump of the saw (and of the square) the phase's rounding
         * may put a sample on either side: skip samples within 1e-9 cycles */
        if (fabs(fr2) > 1e-9 && fabs(fr2 - 1) > 1e-9)
            ew = fmax(ew, fabs(sw[k] - wref));
        if (fabs(fr) > 1e-9 && fabs(fr - 0.5) > 1e-9 && fabs(fr - 1) > 1e-9)
            sq_bad += sq[k] != (fr < 0.5 ? 1.0 : -1.0);
        et = fmax(et, fabs(tr[k] - (1 - 4 * fabs(fr4 - 0.5))));
        ed = fmax(ed, fabs(dm[k] - exp(-3.0 * k / FS)));
    }
    report("waveforms: sine %.1f dB, saw %.1f dB, triangle %.1f dB, damp %.1f dB max error; square %ld wrong",
           db(es), db(ew), db(et), db(ed), sq_bad);
    /* phases up to ~4 cycles: 1e-12 is hundreds of rounding errors */
    assert_true(es < 1e-12 && ew < 1e-12 && et < 1e-12 && ed < 1e-12);
    assert_int_equal(sq_bad, 0);
    assert_float_equal(sw[(long)(3.3 / 37.5 * FS)], 0, 1e-12); /* saw(0) = 0, rising */
    free(sn), free(sw), free(sq), free(tr), free(dm);
}

/* (osc F): p_0 = 0, p_{n+1} = p_n + F_n/fs, sin(2 pi p_n).  Wrapped to
 * [0, 1), each step rounds the phase by at most 2^-53 cycles, so after n
 * steps the error is at most 2 pi n 2^-53 (3.3e-11 for a second); an
 * input F with errors dF adds 2 pi sum dF/fs. */
static void test_osc_sine(void **s) {
    (void)s;
    const long n = (long)FS;
    double *y = render("(osc 440)", FS, n), *z = render("(sine (* 440 t))", FS, n);
    double *ref = malloc(sizeof *ref * (size_t)n);
    for (long k = 0; k < n; k++)
        ref[k] = (double)sin_cyc(440.0L * k / FS);
    double bound = 2 * M_PI * n * 0x1p-53 + 8 * EPS;
    double e = max_diff(y, ref, n), ez = max_diff(y, z, n);
    report("(osc 440), 1 s: %.3g (%.1f dB) from sin(2 pi 440 t), %.3g from (sine (* 440 t)); bound %.3g", e, db(e),
           ez, bound);
    assert_true(e <= bound);
    assert_true(ez <= bound + 1e-12);
    free(y), free(z);

    /* a moving frequency: the phase is the running sum of F/fs */
    y = render("(osc (+ 440 (* 100 (sine (* 2 t)))))", FS, n);
    long double p = 0;
    for (long k = 0; k < n; k++) {
        ref[k] = (double)sin_cyc(p);
        p += (440 + 100 * sin_cyc(2.0L * k / FS)) / FS;
    }
    /* F's own error (the tree's sine, ~1e-13 relative) summed over a second */
    bound = 2 * M_PI * (n * 0x1p-52 + 1.0 * 1e-12 * 540) + 8 * EPS;
    e = max_diff(y, ref, n);
    report("(osc (+ 440 (* 100 (sine (* 2 t))))), 1 s: %.3g (%.1f dB) from the phase sum; bound %.3g", e, db(e),
           bound);
    assert_true(e <= bound);
    free(y), free(ref);
}

/* The spectrum of a signal of period P = 480 samples (f = 3700 Hz at
 * 48 kHz: 37 cycles in 480 samples, every component on a multiple of
 * 100 Hz), from n samples starting at `skip`: the periods are averaged,
 * then a 480-point DFT.  Energy in harmonic bins (multiples of 37), in
 * non-harmonic bins (aliases, DC excluded), and in non-harmonic bins below
 * the fundamental; the fundamental's amplitude and phase (of sin). */
typedef struct spec {
    double harm, alias, alias_low, amp, phase;
} spec;

static spec periodic_spectrum(const double *x, long skip, long periods) {
    enum { P = 480, H = 37 };
    double avg[P] = {0};
    for (long q = 0; q < periods; q++)
        for (int k = 0; k < P; k++)
            avg[k] += x[skip + q * P + k] / (double)periods;
    spec sp = {0};
    for (int j = 1; j <= P / 2; j++) {
        double re = 0, im = 0;
        for (int k = 0; k < P; k++)
            re += avg[k] * cos(2 * M_PI * j * k / P), im -= avg[k] * sin(2 * M_PI * j * k / P);
        double e = re * re + im * im;
        if (j % H == 0)
            sp.harm += e;
        else
            sp.alias += e, sp.alias_low += j < H ? e : 0;
        if (j == H) /* x = amp sin(w n + phase): X_j = amp P/2 e^{j(phase - pi/2)} */
            sp.amp = 2 * hypot(re, im) / P, sp.phase = atan2(im, re) + M_PI / 2;
    }
    return sp;
}

/* (osc 3700 saw|square|triangle) against the naive (saw (* 3700 t)) etc.
 * The naive waveforms alias badly at 3.7 kHz.  A two-point polyBLEP (and
 * polyBLAMP for the triangle), simulated over this same measure, removes
 * 16.3 dB (saw), 14.9 dB (square) and 11.5 dB (triangle) of the total
 * aliased energy, most of which lies near Nyquist where a two-sample
 * correction cannot reach, and 48 to 69 dB of the aliases below the
 * fundamental.  So a polyBLEP-style oscillator is asserted to remove at
 * least 12 dB (saw, square) or 8 dB (triangle) of the total and 30 dB
 * below the fundamental; the 20 dB of total asked for is printed as
 * information (a two-point polyBLEP does not reach it at 3.7 kHz).  The
 * fundamental keeps the ideal waveform's amplitude (within 0.5 dB:
 * polyBLEP costs 0.17 dB here) and phase. */
static void test_osc_bandlimited(void **s) {
    (void)s;
    enum { P = 480, PERIODS = 100, SKIP = 10 * P };
    const long n = SKIP + PERIODS * P;
    static const struct {
        const char *shape;
        double min_total, amp;
    } shapes[] = {
        {"saw", 12, 2 / M_PI},
        {"square", 12, 4 / M_PI},
        {"triangle", 8, 8 / (M_PI * M_PI)},
    };
    for (int i = 0; i < 3; i++) {
        char a[128], b[128];
        snprintf(a, sizeof a, "(osc 3700 %s)", shapes[i].shape);
        snprintf(b, sizeof b, "(%s (* 3700 t))", shapes[i].shape);
        double *y = render(a, FS, n), *z = render(b, FS, n);
        spec sy = periodic_spectrum(y, SKIP, PERIODS), sz = periodic_spectrum(z, SKIP, PERIODS);
        double total = 10 * log10(sz.alias / sy.alias), low = 10 * log10(sz.alias_low / sy.alias_low);
        double dphase = remainder(sy.phase, 2 * M_PI);
        report("(osc 3700 %s): aliasing %.1f dB re harmonics (naive %.1f dB): %.1f dB less in all, %.1f dB less "
               "below the fundamental%s; fundamental %.2f dB re ideal, phase %.4f rad; max %.3g from the naive",
               shapes[i].shape, 10 * log10(sy.alias / sy.harm), 10 * log10(sz.alias / sz.harm), total, low,
               total >= 20 ? "" : " (below the 20 dB asked for)", db(sy.amp / shapes[i].amp), dphase,
               max_diff(y, z, n));
        assert_true(total >= shapes[i].min_total);
        assert_true(low >= 30);
        assert_true(fabs(db(sy.amp / shapes[i].amp)) < 0.5);
        assert_true(fabs(dphase) < 0.02);
        for (long k = 0; k < n; k++)
            assert_true(fabs(y[k]) < 1.5);
        free(y), free(z);
    }
}

/* ---- integral, env ---- */

/* Trapezoid sums: each of the n steps rounds by at most an ulp of the
 * running value, so the error is at most 2 n 2^-52 max|y| (the factor 2
 * for the rounding of the increment). */
static void test_integral(void **s) {
    (void)s;
    const long n = (long)FS;
    double *y = render("(integral 2)", FS, n);
    double e = 0, bound = 2 * n * 0x1p-52 * 2.0;
    for (long k = 0; k < n; k++)
        e = fmax(e, fabs(y[k] - (double)(2.0L * k / FS)));
    report("(integral 2), 1 s: max error %.3g from 2t (bound %.3g)", e, bound);
    assert_true(y[0] == 0);
    assert_true(e <= bound);
    free(y);

    y = render("(integral t)", FS, n);
    e = 0, bound = 2 * n * 0x1p-52 * 0.5;
    for (long k = 0; k < n; k++) {
        long double t = (long double)k / FS;
        e = fmax(e, fabs(y[k] - (double)(t * t / 2)));
    }
    report("(integral t), 1 s: max error %.3g from t^2/2 (bound %.3g)", e, bound);
    assert_true(y[0] == 0);
    assert_true(e <= bound);
    free(y);

    /* an audio input: the trapezoid rule on the very samples of the input
     * (the rectangle rule would be ~x/(2 fs) ~ 1e-5 away) */
    double *x = render("(sine (* 100 t))", FS, n);
    y = render("(integral (sine (* 100 t)))", FS, n);
    long double acc = 0;
    e = 0;
    double ymax = 1 / (100 * M_PI);
    for (long k = 0; k < n; k++) {
        if (k > 0)
            acc += ((long double)x[k - 1] + x[k]) / (2 * FS);
        e = fmax(e, fabs(y[k] - (double)acc));
    }
    bound = 2 * n * 0x1p-52 * ymax;
    report("(integral (sine (* 100 t))), 1 s: max error %.3g (%.1f dB re peak) from the trapezoid sum (bound %.3g)",
           e, db(e / ymax), bound);
    assert_true(e <= bound);
    free(x), free(y);
}

/* Linear between keys in t, the first value before the first key, the
 * last after the last.  An env that steps its ramp sample by sample
 * accumulates at most n ulps: bound n 2^-52 max|V|. */
static void test_env(void **s) {
    (void)s;
    static const double key[][2] = {{0.1, 1}, {0.3, -1}, {0.5, 0.5}, {0.75, 0.25}};
    const long n = (long)FS;
    double *y = render("(env (0.1 1) (0.3 -1) (0.5 0.5) (0.75 0.25))", FS, n);
    double e = 0, bound = n * 0x1p-52 * 1.0 + 4 * EPS;
    for (long k = 0; k < n; k++) {
        double t = k / FS, want;
        if (t <= key[0][0])
            want = key[0][1];
        else if (t >= key[3][0])
            want = key[3][1];
        else {
            int i = 0;
            while (t > key[i + 1][0])
                i++;
            want = key[i][1] + (key[i + 1][1] - key[i][1]) * (t - key[i][0]) / (key[i + 1][0] - key[i][0]);
        }
        e = fmax(e, fabs(y[k] - want));
    }
    report("env of 4 keys, 1 s: max error %.3g (bound %.3g)", e, bound);
    assert_true(e <= bound);
    free(y);

    /* (env (0 0) (1 1)) is t over its second */
    y = render("(env (0 0) (1 1))", FS, n);
    e = 0;
    for (long k = 0; k < n; k++)
        e = fmax(e, fabs(y[k] - k / FS));
    report("(env (0 0) (1 1)) against t: max error %.3g", e);
    assert_true(e <= bound);
    free(y);

    /* an env that ends at 0 ends the tree: silent from then on */
    tt_prog *p = compile_text("(* (sine (* 440 t)) (env (0 1) (0.5 0)))");
    double end = tt_prog_end(p);
    report("tt_prog_end of a sine under (env (0 1) (0.5 0)): %.17g s", end);
    assert_true(end >= 0.5 && end <= 0.5 + 1e-9);
    char err[256];
    y = malloc(sizeof *y * (size_t)n);
    assert_int_equal(tt_render(p, FS, NULL, y, n, err, sizeof err), 0);
    for (long k = (long)(0.5 * FS); k < n; k++)
        assert_true(y[k] == 0);
    free(y);
    tt_prog_free(p);
    p = compile_text("(sine (* 440 t))");
    assert_true(tt_prog_end(p) == HUGE_VAL);
    /* rendered through a sink: the same frames, in runs of at most 4096,
     * none kept; a sink that fails stops the render */
    double *whole = malloc(sizeof *whole * 10000), *runs = malloc(sizeof *runs * 10000);
    assert_int_equal(tt_render(p, FS, NULL, whole, 10000, err, sizeof err), 0);
    sunk k = {runs, 0, 10000, 0};
    assert_int_equal(tt_render_to(p, FS, NULL, 10000, sink_runs, &k, err, sizeof err), 0);
    assert_int_equal(k.n, 10000);
    assert_int_equal(k.runs, 3);
    assert_memory_equal(whole, runs, sizeof *runs * 10000);
    k.n = 0, k.cap = 5000;
    assert_int_equal(tt_render_to(p, FS, NULL, 10000, sink_runs, &k, err, sizeof err), -1);
    free(whole);
    free(runs);
    tt_prog_free(p);
}

/* ---- delay ---- */

/* y_n = x_{n - S fs}, 0 before: integer delays exactly; fractional and
 * moving delays by Catmull-Rom at position n - S fs.  The position's own
 * rounding (an ulp of n, ~7e-12 samples at n = 48000) times the largest
 * slope of the interpolated input, plus the interpolation's rounding
 * (16 eps max|x|), bounds the error of fractional delays. */
static void test_delay(void **s) {
    (void)s;
    const long n = (long)FS;
    static const char x_text[] = "(+ (sine (* 440 t)) (* 0.5 (saw (* 1234.5 t))))";
    double *x = render(x_text, FS, n), xmax = peak(x, n);
    static const struct {
        const char *s;
        double d; /* S fs */
    } ds[] = {{"0.01", 480}, {"0.015625", 750}, {"0", 0}};
    char text[512];
    for (int i = 0; i < 3; i++) {
        snprintf(text, sizeof text, "(delay %s %s)", x_text, ds[i].s);
        double *y = render(text, FS, n), e = 0;
        long d = (long)ds[i].d;
        for (long k = 0; k < n; k++)
            e = fmax(e, fabs(y[k] - (k >= d ? x[k - d] : 0.0)));
        report("(delay X %s): max difference %.3g from x[n - %ld] (exact asked)", ds[i].s, e, d);
        assert_true(e == 0);
        free(y);
    }

    /* fractional: 480.25 and 480.5 samples */
    double slope = 0;
    for (long k = 1; k < n; k++)
        slope = fmax(slope, fabs(x[k] - x[k - 1]));
    slope *= 1.5; /* the interpolant's slope: Catmull-Rom's tangents overshoot a step */
    double bound = slope * (n * EPS + 1000 * EPS) + 16 * EPS * xmax;
    static const double fr[] = {480.25, 480.5};
    for (int i = 0; i < 2; i++) {
        snprintf(text, sizeof text, "(delay %s %.17g)", x_text, fr[i] / FS);
        double *y = render(text, FS, n), e = 0;
        for (long k = 0; k < n; k++)
            e = fmax(e, fabs(y[k] - cr_at(x, n, k - fr[i])));
        report("(delay X %g/fs): max error %.3g from Catmull-Rom (bound %.3g)", fr[i], e, bound);
        assert_true(e <= bound);
        free(y);
    }

    /* a moving delay, with its maximum */
    double *S = render("(+ 0.01 (* 0.002 (sine (* 3 t))))", FS, n);
    double *y = render("(delay (+ (sine (* 440 t)) (* 0.5 (saw (* 1234.5 t)))) (+ 0.01 (* 0.002 (sine (* 3 t)))) 0.02)",
                       FS, n);
    double e = 0;
    for (long k = 0; k < n; k++)
        e = fmax(e, fabs(y[k] - cr_at(x, n, k - S[k] * FS)));
    bound += slope * 1e-13 * 0.012 * FS; /* S's own error, ~1e-13 relative */
    report("moving delay 10 +- 2 ms: max error %.3g from Catmull-Rom at n - S fs (bound %.3g)", e, bound);
    assert_true(e <= bound);
    free(y), free(S), free(x);
}

/* ---- filters ---- */

/* The RBJ biquads' digital magnitude at w is the analog prototype's at
 * W = tan(w/2)/tan(w0/2).  Measured as the DTFT of a 2 s impulse response
 * (the slowest pole here, 50 Hz at Q 5, has fallen by e^-62 by then).
 * What is left is rounding: the recurrence's (its noise gain times eps,
 * ~1e-11 for the slowest filter) and the DTFT's (tl_dtft's phasor drifts
 * by ~256 ulps: ~1e-13 of sum|h|).  Asserted: 1e-8 of the peak gain. */
static double analog_mag(int kind, double W, double Q) {
    double complex d = 1 - W * W + I * W / Q;
    double num = kind == 0 ? 1 : kind == 1 ? W * W : W / Q;
    return num / cabs(d);
}

static void test_filters(void **s) {
    (void)s;
    static const char *const names[] = {"lowpass", "highpass", "bandpass"};
    static const struct {
        double f, q; /* q 0: not given (1/sqrt 2) */
    } cases[] = {{1000, 0}, {50, 5}, {10000, 0.5}, {3000, 2}};
    const long n = (long)(2 * FS);
    double worst = -400;
    for (int kind = 0; kind < 3; kind++)
        for (size_t c = 0; c < sizeof cases / sizeof *cases; c++) {
            char text[256];
            double q = cases[c].q ? cases[c].q : 1 / sqrt(2.0);
            if (cases[c].q)
                snprintf(text, sizeof text, "(%s (max 0 (- 1 (* fs t))) %g %g)", names[kind], cases[c].f, cases[c].q);
            else
                snprintf(text, sizeof text, "(%s (max 0 (- 1 (* fs t))) %g)", names[kind], cases[c].f);
            double *h = render(text, FS, n);
            /* the peak gain: 1, or Q / sqrt(1 - 1/(4 Q^2)) for a resonant lowpass or highpass */
            double w0 = 2 * M_PI * cases[c].f / FS, e = 0;
            double ref_peak = kind == 2 || q <= 1 / sqrt(2.0) ? 1 : q / sqrt(1 - 1 / (4 * q * q));
            for (int j = 0; j <= 40; j++) {
                /* 10 Hz to 23.9 kHz, log spaced, and the corner itself */
                double f = j == 40 ? cases[c].f : 10 * pow(2390, j / 39.0), w = 2 * M_PI * f / FS;
                double W = tan(w / 2) / tan(w0 / 2), want = analog_mag(kind, W, q);
                double got = cabs(tl_dtft(h, n, w));
                e = fmax(e, fabs(got - want) / ref_peak);
            }
            report("(%s IMPULSE %g) Q %.4g: max magnitude error %.1f dB re peak", names[kind], cases[c].f, q, db(e));
            worst = fmax(worst, db(e));
            assert_true(e < 1e-8);
            free(h);
        }
    report("filters: worst magnitude error %.1f dB re peak (bound -160 dB)", worst);
}

/* ---- reson ---- */

/* Impulse response r^n sin(theta (n + 1)), theta = 2 pi F/fs,
 * r = 10^(-3/(T60 fs)).  Rounding: each step injects ~2 eps that the
 * resonance sums up to 1/((1 - r) sin theta) times, and cos theta's
 * rounding moves the frequency by eps/sin theta, a phase error growing
 * as n.  The decay is read from E_n = y_n^2 - y_{n-1} y_{n+1}, which for
 * a damped sinusoid is A^2 r^{2n} sin^2 theta exactly: over T60 it falls
 * by exactly 60 dB. */
static void test_reson(void **s) {
    (void)s;
    const double F = 440, T60 = 0.5;
    const long n = (long)(2 * T60 * FS);
    double *y = render("(reson (max 0 (- 1 (* fs t))) 440 0.5)", FS, n);
    long double th = 2 * PI_L * F / FS, r = powl(10, -3 / (T60 * FS));
    double e = 0;
    for (long k = 0; k < n; k++)
        e = fmax(e, fabs(y[k] - (double)(powl(r, k) * sinl(th * (k + 1)))));
    double sth = sin((double)th);
    double bound = 4 * EPS / ((1 - (double)r) * sth) + 2 * EPS / sth * n;
    report("(reson IMPULSE 440 0.5), 1 s: max error %.3g (%.1f dB re 1) from r^n sin(theta (n+1)) (bound %.3g)", e,
           db(e), bound);
    assert_true(e <= bound);

    long a = 100, b = a + (long)(T60 * FS);
    double Ea = y[a] * y[a] - y[a - 1] * y[a + 1], Eb = y[b] * y[b] - y[b - 1] * y[b + 1];
    double fall = 10 * log10(Eb / Ea);
    report("reson: the envelope falls %.9f dB in T60", fall);
    assert_true(fabs(fall + 60) < 1e-6);
    free(y);
}

/* ---- samples ---- */

static const char *wav(const char *name, int nch, double rate, const double *x, long n) {
    static char path[256];
    snprintf(path, sizeof path, "%s/%s", g_dir, name);
    assert_int_equal(wdrt_wav_write(path, nch, rate, x, n), WDRT_OK);
    return path;
}

/* Channels averaged; Catmull-Rom exact on quadratics; its kernel; 0 past
 * the end, and tt_prog_end no earlier than the last sound. */
static void test_sample_interp(void **s) {
    (void)s;
    enum { L = 64 };
    /* a quadratic in n, exact in float, split over two channels around it */
    double st[2 * L], q[L];
    for (int k = 0; k < L; k++) {
        q[k] = (3.0 * k * k - 40.0 * k + 7) / 1024;
        st[2 * k] = q[k] + (k % 2 ? 0.5 : -0.5);
        st[2 * k + 1] = q[k] - (k % 2 ? 0.5 : -0.5);
    }
    char text[512];
    snprintf(text, sizeof text, "(sample \"%s\" 0.25)", wav("q.wav", 2, FS, st, L));
    const long n = 4 * L + 64;
    double *y = render(text, FS, n), e = 0, qmax = 0;
    for (long k = 4; k <= 4 * (L - 2); k++) { /* positions 1 .. L-2: all four points inside */
        long double p = k / 4.0L, want = (3 * p * p - 40 * p + 7) / 1024;
        e = fmax(e, fabs(y[k] - (double)want));
        qmax = fmax(qmax, fabs((double)want));
    }
    report("sample of a quadratic (stereo, averaged) at rate 0.25: max error %.3g (%.1f dB re peak)", e,
           db(e / qmax));
    assert_true(e <= 16 * EPS * qmax);
    for (long k = 4 * (L + 1); k < n; k++)
        assert_true(y[k] == 0);
    free(y);

    /* an impulse: the Catmull-Rom kernel, at quarter positions */
    double imp[32] = {0};
    imp[10] = 1;
    snprintf(text, sizeof text, "(sample \"%s\" 0.25)", wav("i.wav", 1, FS, imp, 32));
    tt_prog *pr = compile_text(text);
    double end = tt_prog_end(pr);
    y = malloc(sizeof *y * 400);
    char err[512];
    assert_int_equal(tt_render(pr, FS, NULL, y, 400, err, sizeof err), 0);
    static const struct {
        long n;
        double v;
    } kv[] = {{40, 1},         {38, 0.5625},     {42, 0.5625},     {34, -0.0625},   {46, -0.0625},
              {41, 0.8671875}, {37, 0.2265625},  {33, -0.0234375}, {45, -0.0703125}, {36, 0},
              {44, 0},         {30, 0},          {50, 0}};
    for (size_t i = 0; i < sizeof kv / sizeof *kv; i++)
        if (fabs(y[kv[i].n] - kv[i].v) > 4 * EPS)
            fail_msg("sample of an impulse at position %g: %.17g, Catmull-Rom gives %.17g", kv[i].n / 4.0, y[kv[i].n],
                     kv[i].v);
    e = 0;
    for (long k = 0; k < 400; k++)
        e = fmax(e, fabs(y[k] - cr_at(imp, 32, k / 4.0)));
    report("sample of an impulse at rate 0.25: max error %.3g from the Catmull-Rom kernel", e);
    assert_true(e <= 4 * EPS);
    long last = -1;
    for (long k = 0; k < 400; k++)
        if (y[k] != 0)
            last = k;
    free(y);
    tt_prog_free(pr);

    /* a file that cannot be read fails the compilation, with a message */
    snprintf(text, sizeof text, "(sample \"%s/nowhere.wav\")", g_dir);
    tt_file *f = tt_file_from_string(text, err, sizeof err);
    if (f) {
        err[0] = 0;
        assert_null(tt_compile(tt_file_tree(f, -1), err, sizeof err));
        tt_file_free(f);
    }
    report("a missing sample file: \"%.*s\"", (int)strcspn(err, "\n"), err);
    assert_true(strstr(err, "nowhere.wav") != NULL);

    /* a sample that ends ends the tree: tt_prog_end is finite, no earlier
     * than the last sound (sample `last`) and within the file's replay */
    snprintf(text, sizeof text, "(sample \"%s/i.wav\")", g_dir);
    pr = compile_text(text);
    double end1 = tt_prog_end(pr);
    tt_prog_free(pr);
    report("tt_prog_end of (sample \"i.wav\" 0.25): %.6g s (its last sound at %.6g s); of (sample \"i.wav\"): %.6g s",
           end, last / FS, end1);
    assert_true(isfinite(end) && isfinite(end1));
    assert_true(end >= last / FS && end <= 400 / FS);
}

/* A 1 kHz sine recorded at 44.1 kHz, replayed at 48 kHz at RATE 1.5: a
 * 1500 Hz sine (pt_peak_freq), and sample by sample Catmull-Rom at
 * p = n 1.5 44100/48000.  Summing that step in double may drift by half
 * an ulp of p a step (p < 88200: 7.3e-12) against n times the step, times
 * the largest slope. */
static void test_sample_rate(void **s) {
    (void)s;
    const long L = 2 * 44100;
    double *x = malloc(sizeof *x * (size_t)L);
    for (long k = 0; k < L; k++)
        x[k] = (float)sin(2 * M_PI * 1000.0 * k / 44100);
    char text[512];
    snprintf(text, sizeof text, "(sample \"%s\" 1.5)", wav("s.wav", 1, 44100, x, L));
    const long n = 60000;
    double *y = render(text, FS, n);
    double f = pt_peak_freq(y, (size_t)n, FS, 1000, 2000);
    report("1 kHz at 44.1 kHz replayed at 48 kHz, rate 1.5: %.6f Hz (%.4f cents from 1500)", f, pt_cents(f, 1500));
    assert_true(fabs(pt_cents(f, 1500)) < 0.05);
    const double inc = 1.5 * 44100 / 48000;
    /* half an ulp of p (< 2^17) a step, times the slope (2 pi 1000/44100
     * per sample, Catmull-Rom's overshoot of a sine well under 10 %) */
    double e = 0, bound = n * 0.5 * 0x1p-36 * (2 * M_PI * 1000 / 44100 * 1.1) + 16 * EPS;
    for (long k = 0; k < n; k++)
        e = fmax(e, fabs(y[k] - cr_at(x, L, (double)((long double)k * inc))));
    report("... max error %.3g from Catmull-Rom at n x %.6f (bound %.3g)", e, inc, bound);
    assert_true(e <= bound);
    free(x), free(y);
}

/* Relative paths of a .tt file's samples are the file's directory's. */
static void test_sample_relative(void **s) {
    (void)s;
    double x[4] = {0.25, 0.5, 0.75, 1};
    wav("r.wav", 1, FS, x, 4);
    char path[256], err[1024] = "";
    const char *tt = tl_write_file(g_dir, "r.tt", "(sample \"r.wav\")\n");
    snprintf(path, sizeof path, "%s", tt);
    char *cwd = getcwd(NULL, 0);
    assert_int_equal(chdir("/"), 0);
    tt_file *f = tt_file_read(path, NULL, 0, err, sizeof err);
    tt_prog *p = f ? tt_compile(tt_file_tree(f, -1), err, sizeof err) : NULL;
    assert_int_equal(chdir(cwd), 0);
    free(cwd);
    if (!p)
        fail_msg("(sample \"r.wav\") in %s: %s", path, err);
    double y[4];
    assert_int_equal(tt_render(p, FS, NULL, y, 4, err, sizeof err), 0);
    assert_float_equal(y[1], 0.5, 1e-15);
    tt_prog_free(p);
    tt_file_free(f);
}

/* ---- energetic ---- */

static void fft(double complex *a, int n) {
    for (int i = 1, j = 0; i < n; i++) {
        int bit = n >> 1;
        for (; j & bit; bit >>= 1)
            j ^= bit;
        j ^= bit;
        if (i < j) {
            double complex t = a[i];
            a[i] = a[j], a[j] = t;
        }
    }
    for (int len = 2; len <= n; len <<= 1) {
        for (int i = 0; i < n; i += len)
            for (int k = 0; k < len / 2; k++) {
                double complex w = cexp(-2 * M_PI * I * k / len), u = a[i + k], v = a[i + k + len / 2] * w;
                a[i + k] = u + v, a[i + k + len / 2] = u - v;
            }
    }
}

/* X replayed at SPEED: a sine of SPEED times X's frequency to 0.01 %,
 * and all that is not that sine (fitted by least squares in amplitude,
 * phase and offset over 1 s after the first 10 ms, and subtracted) below
 * -80 dB of it: the images of the resampling, and, in the third case, a
 * 12 kHz component of X that a speed of 3 would carry to 36 kHz, above
 * Nyquist (it must be filtered out, not folded to 12 kHz).  The largest
 * single spur of a Blackman-Harris (4-term, sidelobes -92 dB) spectrum is
 * printed with it. */
static void test_energetic_pure(void **s) {
    (void)s;
    static const struct {
        const char *text;
        double fout;
    } cases[] = {
        {"(energetic (sine (* 1000 t)) 1.7)", 1700},
        {"(energetic (sine (* 1000 t)) 0.6)", 600},
        {"(energetic (+ (sine (* 1000 t)) (sine (* 12000 t))) 3)", 3000},
    };
    for (int ci = 0; ci < 3; ci++) {
        const double fout = cases[ci].fout;
        const long skip = (long)(0.01 * FS), m = (long)FS, n = skip + m;
        double *y = render(cases[ci].text, FS, n), *x = y + skip;
        double f = pt_peak_freq(x, (size_t)m, FS, 0.8 * fout, 1.2 * fout);
        double rel = (f - fout) / fout;

        /* least squares: x ~ a sin + b cos + c at fout */
        double A[3][3] = {{0}}, B[3] = {0}, w = 2 * M_PI * fout / FS;
        for (long k = 0; k < m; k++) {
            double v[3] = {sin(w * (k + skip)), cos(w * (k + skip)), 1};
            for (int i = 0; i < 3; i++) {
                B[i] += v[i] * x[k];
                for (int j = 0; j < 3; j++)
                    A[i][j] += v[i] * v[j];
            }
        }
        for (int i = 0; i < 3; i++) /* Gauss-Jordan, the matrix is nearly diagonal */
            for (int j = 0; j < 3; j++)
                if (j != i) {
                    double r = A[j][i] / A[i][i];
                    for (int c = 0; c < 3; c++)
                        A[j][c] -= r * A[i][c];
                    B[j] -= r * B[i];
                }
        double a = B[0] / A[0][0], b = B[1] / A[1][1], c = B[2] / A[2][2], es = 0, er = 0;
        for (long k = 0; k < m; k++) {
            double fit = a * sin(w * (k + skip)) + b * cos(w * (k + skip)) + c;
            es += fit * fit, er += (x[k] - fit) * (x[k] - fit);
        }
        double resid = 10 * log10(er / es);

        /* the largest spur, Blackman-Harris 4-term over 32768 samples */
        enum { N = 32768 };
        double complex *z = malloc(sizeof *z * N);
        for (int k = 0; k < N; k++) {
            double u = 2 * M_PI * k / (N - 1);
            double win = 0.35875 - 0.48829 * cos(u) + 0.14128 * cos(2 * u) - 0.01168 * cos(3 * u);
            z[k] = x[k] * win;
        }
        fft(z, N);
        int kp = (int)lround(fout * N / FS);
        double pk = 0, spur = 0;
        int ks = 0;
        for (int k = 0; k <= N / 2; k++)
            pk = fmax(pk, cabs(z[k]));
        for (int k = 0; k <= N / 2; k++)
            if (abs(k - kp) > 20 && cabs(z[k]) > spur) /* beyond the window's -92 dB sidelobes near the line */
                spur = cabs(z[k]), ks = k;
        free(z);
        report("%s: %.6f Hz (%.2g %% from %g); amplitude %.6f; all else %.1f dB re the sine (fit and subtract); "
               "largest spur %.1f dB at %.0f Hz (30 Hz or more away)",
               cases[ci].text, f, 100 * rel, fout, hypot(a, b), resid, db(spur / pk), ks * FS / N);
        assert_true(fabs(rel) < 1e-4);
        assert_true(fabs(hypot(a, b) - 1) < 0.01);
        assert_true(resid < -80);
        free(y);
    }
}

/* Pitch and tempo together: (energetic (env (0 0) (1 1)) 2) is the ramp
 * 2t, reaching 1 at t = 0.5 and staying.  The resampler's kernel smooths
 * the ramp's corner over its width; 1e-3 (a millisecond of the ramp) is
 * asserted. */
static void test_energetic_tempo(void **s) {
    (void)s;
    const long n = (long)(0.7 * FS);
    double *y = render("(energetic (env (0 0) (1 1)) 2)", FS, n), e = 0;
    for (long k = (long)(0.01 * FS); k < n; k++) {
        double t = k / FS;
        if (fabs(t - 0.5) < 0.001)
            continue;
        e = fmax(e, fabs(y[k] - fmin(1, 2 * t)));
    }
    long half = (long)(0.5 * FS);
    report("(energetic (env (0 0) (1 1)) 2): %.6f at t = 0.5; max error %.3g from min(1, 2t) away from the corner",
           y[half], e);
    assert_true(fabs(y[half] - 1) < 1e-3);
    assert_true(e < 1e-3);
    free(y);
}

/* ---- importance ---- */

/* The rules, written out: locked entries keep W, clamped in order to what
 * remains; free ones share the rest in proportion to W (equally if all are
 * 0); with none free, the rest goes to the last entry. */
static void importance_ref(int n, const double *w, const double *locked, double *out) {
    double rem = 1, sum = 0;
    int nfree = 0;
    for (int i = 0; i < n; i++)
        if (locked[i]) {
            out[i] = fmin(fmax(w[i], 0), rem);
            rem -= out[i];
        } else
            nfree++, sum += w[i];
    for (int i = 0; i < n; i++)
        if (!locked[i])
            out[i] = sum > 0 ? rem * w[i] / sum : rem / nfree;
    if (!nfree)
        out[n - 1] += rem;
}

static void test_importance(void **s) {
    (void)s;
    /* the paper's example */
    double w[4] = {0.67, 0.2, 0.1, 1}, lk[4] = {1, 1, 1, 0}, out[4];
    tt_importance(4, w, lk, out);
    report("importance, the paper's example: %.17g %.17g %.17g %.17g", out[0], out[1], out[2], out[3]);
    assert_float_equal(out[0], 0.67, 2 * EPS);
    assert_float_equal(out[1], 0.20, 2 * EPS);
    assert_float_equal(out[2], 0.10, 2 * EPS);
    assert_float_equal(out[3], 0.03, 4 * EPS);
    double y = value_of("(importance (1 0.67 lock) (10 0.2 lock) (100 0.1 lock) (1000 1))");
    report("(importance (1 0.67 lock) (10 0.2 lock) (100 0.1 lock) (1000 1)) = %.17g (42.67: %.3g off)", y,
           y - 42.67);
    assert_float_equal(y, 42.67, 1000 * 8 * EPS);

    /* clamping, equal shares, no free entry */
    double w2[3] = {0.7, 0.5, 0}, l2[3] = {1, 1, 0};
    tt_importance(3, w2, l2, out);
    assert_float_equal(out[0], 0.7, 2 * EPS), assert_float_equal(out[1], 0.3, 2 * EPS);
    assert_float_equal(out[2], 0, 2 * EPS);
    double w3[3] = {0.4, 0, 0}, l3[3] = {1, 0, 0};
    tt_importance(3, w3, l3, out);
    assert_float_equal(out[1], 0.3, 2 * EPS), assert_float_equal(out[2], 0.3, 2 * EPS);
    double w4[2] = {0.2, 0.3}, l4[2] = {1, 1};
    tt_importance(2, w4, l4, out);
    assert_float_equal(out[0], 0.2, 2 * EPS), assert_float_equal(out[1], 0.8, 2 * EPS);
    assert_float_equal(value_of("(importance (1 0.2 lock) (2 0.3 lock))"), 0.2 + 1.6, 8 * EPS);
    assert_float_equal(value_of("(importance (1 1) (2 3))"), 0.25 + 1.5, 8 * EPS);

    /* random weights and locks: sums of one, the rules */
    tl_rng r;
    tl_rng_seed(&r, 0x1a9e);
    double worst = 0, worst_sum = 0;
    for (int it = 0; it < 20000; it++) {
        int n = 1 + (int)(tl_rng_next(&r) % 8);
        double W[8], L[8], o[8], ref[8], sum = 0;
        for (int i = 0; i < n; i++) {
            L[i] = tl_rng_next(&r) % 3 == 0;
            W[i] = tl_rng_next(&r) % 5 == 0 ? 0 : (L[i] ? 0.6 : 2) * tl_rng_uniform(&r);
        }
        tt_importance(n, W, L, o);
        importance_ref(n, W, L, ref);
        for (int i = 0; i < n; i++) {
            sum += o[i];
            worst = fmax(worst, fabs(o[i] - ref[i]));
            if (!(o[i] >= 0))
                fail_msg("iteration %d: weight %d is %g", it, i, o[i]);
        }
        worst_sum = fmax(worst_sum, fabs(sum - 1));
    }
    report("importance, 20000 random cases: sums within %.3g of 1, weights within %.3g of the rules", worst_sum,
           worst);
    assert_true(worst_sum <= 16 * EPS);
    assert_true(worst <= 16 * EPS);
}

/* Before T0 the importance weights, after T0 + TIME the reversed ones, a
 * raised cosine (1 - cos(pi (t - T0)/TIME))/2 between, monotone. */
static void test_inverse_importance(void **s) {
    (void)s;
    const long n = (long)(2 * FS);
    double *y = render("(inverse-importance 1 (from 0.5) (1 0.67 lock) (10 0.2 lock) (100 0.1 lock) (1000 1))", FS, n);
    const double A = 42.67, B = 0.03 * 1 + 0.1 * 10 + 0.2 * 100 + 0.67 * 1000;
    double ea = 0, eb = 0, eshape = 0;
    long back = 0;
    for (long k = 0; k < n; k++) {
        double t = k / FS;
        if (t <= 0.5)
            ea = fmax(ea, fabs(y[k] - A));
        else if (t >= 1.5)
            eb = fmax(eb, fabs(y[k] - B));
        else {
            double c = (1 - cos(M_PI * (t - 0.5) / 1)) / 2;
            eshape = fmax(eshape, fabs(y[k] - (A + (B - A) * c)) / (B - A));
        }
        if (k && y[k] < y[k - 1])
            back++;
    }
    report("inverse-importance: %.3g from 42.67 before, %.3g from 691.03 after, %ld steps back; "
           "%.3g (%.1f dB) of the swing from the raised cosine",
           ea, eb, back, eshape, db(eshape));
    assert_true(ea < 1e-12 && eb < 1e-11);
    assert_int_equal(back, 0);
    assert_true(eshape < 1e-9);
    free(y);

    /* from 0 when (from ...) is left out */
    y = render("(inverse-importance 0.5 (1 0.25 lock) (2 0))", FS, (long)FS);
    report("(inverse-importance 0.5 (1 0.25 lock) (2 0)): %.17g at 0, %.17g at 0.25 s, %.17g at 0.5 s", y[0],
           y[(long)(0.25 * FS)], y[(long)(0.5 * FS)]);
    assert_float_equal(y[0], 1.75, 8 * EPS);
    assert_float_equal(y[(long)(0.25 * FS)], 1.5, 1e-9);
    assert_float_equal(y[(long)(0.5 * FS)], 1.25, 8 * EPS);
    assert_float_equal(y[(long)FS - 1], 1.25, 8 * EPS);
    free(y);
}

/* ---- sputter ---- */

/* The envelope of rate f(t) = F0 (F1/F0)^(min(t, DUR)/DUR), phase
 * phi = integral of f from 0: frac(phi) rising linearly over a fraction
 * a = min(0.5, 0.002 f) of the cycle, falling linearly after. */
static double sputter_phase(double t, double F0, double F1, double dur) {
    double r = F1 / F0, L = log(r);
    double tt = fmin(t, dur);
    double ph = F0 * dur / L * (pow(r, tt / dur) - 1);
    return ph + (t > dur ? F1 * (t - dur) : 0);
}

static void test_sputter(void **s) {
    (void)s;
    static const double cs[][3] = {{40, 5, 2}, {400, 100, 1}};
    for (int c = 0; c < 2; c++) {
        double F0 = cs[c][0], F1 = cs[c][1], dur = cs[c][2];
        char text[256];
        snprintf(text, sizeof text, "(sputter 1 %g %g %g)", F0, F1, dur);
        const long n = (long)((dur + 0.5) * FS), nd = (long)(dur * FS);
        double *y = render(text, FS, n);
        /* cycles over DUR: maxima of the envelope */
        long maxima = 0;
        for (long k = 1; k + 1 < nd; k++)
            maxima += y[k] > y[k - 1] && y[k] >= y[k + 1];
        double r = F1 / F0, want = F0 * dur * (r - 1) / log(r);
        /* steps: at most the steeper slope a sample, f/(fs min(a, 1 - a)) */
        double step = 0, bound = 0;
        for (long k = 1; k < n; k++)
            step = fmax(step, fabs(y[k] - y[k - 1]));
        for (double f = fmin(F0, F1); f <= fmax(F0, F1); f *= 1.001) {
            double a = fmin(0.5, 0.002 * f);
            bound = fmax(bound, f / (FS * fmin(a, 1 - a)));
        }
        /* and a = 0.002 f moves by |f'|/(f fs) of itself a sample,
         * ln(F0/F1)/(DUR fs), which moves frac/a by as much */
        double drift = log(F0 / F1) / (dur * FS);
        bound = bound * (1 + 2 * drift) + 2 * drift;
        /* the shape: the phase's discretisation (at most (F0 - F1)/(2 fs)
         * cycles by the rectangle rule) times the steepest slope, 1/a */
        double e = 0, amin = fmin(0.5, 0.002 * fmin(F0, F1));
        double ebound = (fabs(F0 - F1) / (2 * FS) + 1e-9) / amin * 1.01 + 1e-9;
        for (long k = 0; k < n; k++) {
            double t = k / FS, ph = sputter_phase(t, F0, F1, dur), fr = ph - floor(ph);
            double f = F0 * pow(r, fmin(t, dur) / dur), a = fmin(0.5, 0.002 * f);
            double want_y = fr < a ? fr / a : (1 - fr) / (1 - a);
            e = fmax(e, fabs(y[k] - want_y));
        }
        report("(sputter 1 %g %g %g): %ld maxima over DUR for %.2f cycles; largest step %.7f (bound %.7f); shape "
               "within %.3g (bound %.3g)",
               F0, F1, dur, maxima, want, step, bound, e, ebound);
        assert_true(fabs(maxima - want) <= 1);
        assert_true(step <= bound);
        assert_true(e <= ebound);
        assert_true(y[0] == 0);
        free(y);
    }
    /* X times the envelope */
    const long n = (long)FS;
    double *a = render("(sputter (sine (* 440 t)) 40 5 2)", FS, n), *b = render("(sine (* 440 t))", FS, n),
           *c = render("(sputter 1 40 5 2)", FS, n), e = 0;
    for (long k = 0; k < n; k++)
        e = fmax(e, fabs(a[k] - b[k] * c[k]));
    report("(sputter X ...) against X times (sputter 1 ...): %.3g", e);
    assert_true(e <= 4 * EPS);
    free(a), free(b), free(c);
}

/* ---- errors ---- */

typedef struct bad {
    const char *text;
    const char *at;     /* the text at the error's position */
    int occ;            /* which occurrence of `at` */
    const char *msg;    /* a part of the message */
} bad;

static const bad g_errors[] = {
    {"(tree drum (params (loudness 1) (damping 0.5))\n  (* lodness (sine (* 440 t))))", "lodness", 0,
     "'lodness'; did you mean 'loudness'?"},
    {"(* 2 (lowpas (noise) 1000))", "lowpas", 0, "'lowpas'; did you mean 'lowpass'?"},
    {"(osc 440 sqare)", "sqare", 0, "'sqare'; did you mean 'square'?"},
    {"(tree d (params (loudness 1)) (* loudness (sine (* 440 t))))\n(use d (lodness 2))", "lodness", 0,
     "'lodness'; did you mean 'loudness'?"},
    {"(+ 1\n   (sine 1 2))", "(sine", 0, "sine"},
    {"(+ 1 (lowpass (noise)))", "(lowpass", 0, "lowpass"},
    {"(* \"abc\" 2)", "\"abc\"", 0, ""},
    {"(combine (rvector 1 2.5 3))", "2.5", 0, ""},
    {"(env (0 0) (1 1)\n     (0.5 2))", "0.5", 0, ""},
};

/* Each error at its position, FILE:LINE:COL: error: ..., with the nearest
 * name where a name is unknown. */
static void test_errors(void **s) {
    (void)s;
    char path[256];
    snprintf(path, sizeof path, "%s/e.tt", g_dir);
    for (size_t i = 0; i < sizeof g_errors / sizeof *g_errors; i++) {
        const bad *b = &g_errors[i];
        char err[2048] = "", want[512];
        tt_file *f = tt_file_read(path, b->text, strlen(b->text), err, sizeof err);
        if (f) {
            tt_file_free(f);
            fail_msg("\"%s\" read without an error", b->text);
        }
        snprintf(want, sizeof want, "%s:%s: error: ", path, pos_of(b->text, b->at, b->occ));
        const char *msg = strncmp(err, path, strlen(path)) ? err : err + strlen(path) + 1;
        report("error: %.*s", (int)strcspn(msg, "\n"), msg);
        if (strncmp(err, want, strlen(want)) != 0)
            fail_msg("for \"%s\" expected \"%s...\", got \"%s\"", b->text, want, err);
        if (!strstr(err, b->msg))
            fail_msg("for \"%s\" expected \"%s\" in \"%s\"", b->text, b->msg, err);
        if (strstr(b->msg, "did you mean") && !strstr(b->text, "(use") && !strstr(err, "unknown"))
            fail_msg("expected \"unknown\" in \"%s\"", err);
    }
}

/* ---- the reader fuzzed ---- */

static int valid_error(const char *path, const char *err) {
    size_t n = strlen(path);
    if (strncmp(err, path, n) != 0 || err[n] != ':')
        return 0;
    int line, col;
    char word[16];
    return sscanf(err + n + 1, "%d:%d: %15s", &line, &col, word) == 3 && line >= 1 && col >= 1 &&
           !strcmp(word, "error:");
}

/* Prints a tree (a definition if it has params) and reads it back: the
 * same text again. */
static void round_trip(const tt_tree *t, long it) {
    char *a = NULL, *b = NULL, err[2048] = "", path[256];
    size_t na = 0, nb = 0;
    FILE *m = open_memstream(&a, &na);
    if (t->nparams)
        tt_print_tree(m, t);
    else
        tt_print(m, t->root);
    fclose(m);
    snprintf(path, sizeof path, "%s/rt.tt", g_dir);
    tt_file *f = tt_file_read(path, a, na, err, sizeof err);
    if (!f)
        fail_msg("iteration %ld: the printed tree does not read back: %s\n%s", it, err, a);
    m = open_memstream(&b, &nb);
    if (t->nparams)
        tt_print_tree(m, tt_file_tree(f, -1));
    else
        tt_print(m, tt_file_tree(f, -1)->root);
    fclose(m);
    if (strcmp(a, b) != 0)
        fail_msg("iteration %ld: printed\n%s\nread back and printed\n%s", it, a, b);
    tt_file_free(f);
    free(a), free(b);
}

static void fuzz(long iters, uint64_t seed) {
    char seeds[8][1024];
    int ns = 0;
    snprintf(seeds[ns++], 1024, "%s(use drum (loudness 0.5))", g_drum);
    snprintf(seeds[ns++], 1024,
             "(tree siren (params (depth 3 0 10)) (* 0.5 (sine (+ (* 600 t) (* depth (sine (* 0.7 t)))))))\n"
             "(lowpass (use siren (depth 2)) 2000 0.9)");
    snprintf(seeds[ns++], 1024,
             "(importance ((osc 220 saw) 0.5 lock) ((osc 330 square) 0.2) ((noise) 0.1) ((pnoise (* 30 t)) 0))");
    snprintf(seeds[ns++], 1024, "(sputter (energetic (reson (env (0 1) (0.001 0)) 440 0.3) 1.5) 30 5 1)");
    snprintf(seeds[ns++], 1024,
             "(inverse-importance 0.5 (from 0.1) ((delay (sine (* 440 t)) 0.01) 1) ((bandpass (noise) 1000 4) 1 "
             "lock)\n  ((integral (square (* 3 t))) 0.2))");
    snprintf(seeds[ns++], 1024,
             "(combine (* (vector 1 2 (min 1 2 3)) (rvector 0.1 3 0.9) (tanh (abs (triangle (* 220 t))))))");
    snprintf(seeds[ns++], 1024, "(* (sample \"q.wav\" 1.5) (highpass (osc (+ 100 (* fs 0.001)) triangle) 300))");
    snprintf(seeds[ns++], 1024,
             "; a comment\n(tree a (params (x 1)) (* x (highpass (saw (* 110 t)) 500)))\n"
             "(+ (use a (x 0.3)) (delay (use a) (+ 0.01 (* 0.005 (sin t))) 0.02)\n"
             "   (pow 2 (floor (log (sqrt (exp 1))))) (/ (cos t) 2) (damp t))");
    double q[16];
    for (int k = 0; k < 16; k++)
        q[k] = k / 16.0;
    wav("q.wav", 1, FS, q, 16);

    tl_rng r;
    tl_rng_seed(&r, seed);
    const char *alphabet = "()\"; \n0123456789.-+*/etsinawvcomplrqdux";
    char path[PATH_MAX];
    snprintf(path, sizeof path, "%s/f.tt", g_dir);
    long ok = 0, errs = 0, cerrs = 0, unplaced = 0, finite = 0;
    char first_unplaced[512] = "", kinds[4][128];
    int nkinds = 0;
    double y[128];
    for (long it = 0; it < iters; it++) {
        const char *text = seeds[tl_rng_next(&r) % (uint64_t)ns];
        char buf[2048], err[4096] = "";
        size_t n = strlen(text);
        memcpy(buf, text, n);
        for (int m = 0, muts = 1 + (int)(tl_rng_next(&r) % 4); m < muts; m++) {
            size_t at = n ? tl_rng_next(&r) % n : 0;
            int op = (int)(tl_rng_next(&r) % 8);
            if (op >= 5 && n > 0) { /* a digit for a digit: numbers change, the tree mostly stays valid */
                size_t k = at;
                while (k < n && (buf[k] < '0' || buf[k] > '9'))
                    k++;
                if (k < n)
                    buf[k] = (char)('0' + tl_rng_next(&r) % 10);
                continue;
            }
            char c = tl_rng_next(&r) % 8 == 0 ? (char)(tl_rng_next(&r) % 256)
                                              : alphabet[tl_rng_next(&r) % strlen(alphabet)];
            size_t len = 1 + tl_rng_next(&r) % 12;
            if (op == 0 && n + 1 < sizeof buf)
                memmove(buf + at + 1, buf + at, n - at), buf[at] = c, n++;
            else if (op == 1 && n > 0)
                memmove(buf + at, buf + at + 1, n - at - 1), n--;
            else if (op == 2 && n > 0)
                buf[at] = c;
            else if (op == 3 && at + len <= n && n + len < sizeof buf) /* duplicate a run */
                memmove(buf + at + len, buf + at, n - at), n += len;
            else
                n = at; /* cut the rest */
        }
        tt_file *f = tt_file_read(path, buf, n, err, sizeof err);
        if (!f) {
            /* a message naming the file but no position: counted, the
             * fuzzing goes on, the test fails at the end */
            size_t np = strlen(path);
            if (!valid_error(path, err) && !strncmp(err, path, np) && !strncmp(err + np, ": error: ", 9)) {
                if (!unplaced++)
                    snprintf(first_unplaced, sizeof first_unplaced, "iteration %ld: \"%.*s\" for \"%.*s\"", it,
                             (int)strcspn(err, "\n"), err, (int)(n < 200 ? n : 200), buf);
                const char *kind = err + np + 9;
                int known = 0;
                for (int i = 0; i < nkinds; i++)
                    known |= !strncmp(kinds[i], kind, strcspn(kind, ":\n"));
                if (!known && nkinds < 4)
                    snprintf(kinds[nkinds++], sizeof kinds[0], "%.*s", (int)strcspn(kind, ":\n"), kind);
            } else if (!valid_error(path, err))
                fail_msg("iteration %ld: bad message \"%s\" for\n%.*s", it, err, (int)n, buf);
            errs++;
            continue;
        }
        const tt_tree *t = tt_file_tree(f, -1);
        if (t) {
            round_trip(t, it);
            err[0] = 0;
            tt_prog *p = tt_compile(t, err, sizeof err);
            if (p) {
                assert_int_equal(tt_render(p, FS, NULL, y, 128, err, sizeof err), 0);
                int fin = 1;
                for (int k = 0; k < 128; k++)
                    fin &= isfinite(y[k]) != 0;
                finite += fin;
                tt_prog_free(p);
                ok++;
            } else {
                if (!err[0])
                    fail_msg("iteration %ld: tt_compile failed without a message", it);
                cerrs++;
            }
        }
        tt_file_free(f);
    }
    report("fuzz: %ld trees rendered (%ld finite throughout), %ld read errors (%ld without a position), %ld compile "
           "errors",
           ok, finite, errs, unplaced, cerrs);
    for (int i = 0; i < nkinds; i++)
        report("fuzz: a message without a position: \"%s\"", kinds[i]);
    if (unplaced)
        fail_msg("%ld read errors without a position, the first: %s", unplaced, first_unplaced);
}

/* WDRT_FUZZ_SEED, mixed into the fuzzer's own seed (0 without it). */
static uint64_t fuzz_seed(void) {
    const char *e = getenv("WDRT_FUZZ_SEED");
    return e ? strtoull(e, NULL, 0) : 0;
}

static void test_fuzz(void **s) {
    (void)s;
    const char *e = getenv("WDRT_FUZZ_ITERS");
    fuzz(e ? atol(e) : 5000, 0x7ee5 ^ fuzz_seed());
}

/* ---- real time ---- */

/* A class of a tree with every stateful node: its init, bind, set_param
 * and process allocate nothing, whatever the host's block lengths. */
static void test_no_alloc(void **s) {
    (void)s;
    double x[100];
    for (int k = 0; k < 100; k++)
        x[k] = sin(k * 0.3);
    char text[4096];
    snprintf(text, sizeof text,
             "(tree rt (params (g 0.5 0 1) (f 440 20 4000))\n"
             "  (* g (+ (osc f saw) (osc (* 1.5 f) triangle) (osc 300 square) (osc 200) (noise) (pnoise (* 20 t))\n"
             "     (sample \"%s\" 1.3) (integral (square (* 2 t))) (env (0 0) (0.01 1) (0.5 0.2))\n"
             "     (delay (sine (* f t)) 0.0123) (delay (noise) (+ 0.01 (* 0.005 (sine (* 2 t)))) 0.02)\n"
             "     (lowpass (noise) f 2) (highpass (noise) 2000) (bandpass (noise) f) (reson (noise) f 0.2)\n"
             "     (importance ((sine (* 300 t)) 0.3 lock) ((noise) 1))\n"
             "     (inverse-importance 0.2 (from 0.05) (1 0.3 lock) (2 1))\n"
             "     (energetic (sine (* 500 t)) 1.3) (sputter (noise) 30 5 0.5)\n"
             "     (combine (* (rvector 0.1 8 0.2) (sine (* (rvector 100 8 2000) t)))))))\n",
             wav("rt.wav", 1, 22050, x, 100));
    tt_prog *p = compile_text(text);
    /* tt_class_init is set-up (it has an uninit): its allocations are
     * printed, not asserted */
    long before = ca_allocs;
    char err[256];
    tt_class probe;
    ca_in_rt = 1;
    int rc = tt_class_init(&probe, p, FS, err, sizeof err);
    ca_in_rt = 0;
    long class_init_allocs = ca_allocs - before;
    assert_int_equal(rc, 0);
    tt_class_uninit(&probe);
    klass k;
    klass_make(&k, p, FS);
    const long n = (long)(0.6 * FS);
    double *y = malloc(sizeof *y * (size_t)n);
    static const int blocks[] = {1, 7, 64, 100, 333, 1000, 65};
    ca_allocs = 0;
    ca_in_rt = 1;
    klass_start(&k, FS);
    for (long pos = 0, b = 0; pos < n; b++) {
        long len = blocks[b % 7] < n - pos ? blocks[b % 7] : n - pos;
        double *out[1] = {y + pos};
        if (b % 5 == 3) {
            k.c.cls.set_param(k.st, 0, 0.3 + 0.1 * (b % 3));
            k.c.cls.set_param(k.st, 1, 200 + 37.0 * (double)(b % 11));
        }
        k.c.cls.process(k.st, NULL, out, (int)len);
        pos += len;
    }
    assert_non_null(k.c.cls.reset);
    k.c.cls.reset(k.st);
    double *out[1] = {y};
    k.c.cls.process(k.st, NULL, out, 64);
    ca_in_rt = 0;
    long allocs = ca_allocs;
    long bad = 0;
    for (long i = 0; i < n; i++)
        bad += !isfinite(y[i]);
    report("real time: %ld allocations in init, bind, set_param, process and reset (tt_class_init: %ld, set-up)%s",
           allocs, class_init_allocs, CA_COUNTING ? "" : " (not counted under a sanitizer)");
    assert_int_equal(allocs, 0);
    assert_int_equal(bad, 0);
    free(y);
    klass_free(&k);
    tt_prog_free(p);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(ca_test_counter_counts),
        cmocka_unit_test(test_drum),
        cmocka_unit_test(test_siren),
        cmocka_unit_test(test_broadcast),
        cmocka_unit_test(test_width_error),
        cmocka_unit_test(test_rvector),
        cmocka_unit_test(test_waves),
        cmocka_unit_test(test_osc_sine),
        cmocka_unit_test(test_osc_bandlimited),
        cmocka_unit_test(test_integral),
        cmocka_unit_test(test_env),
        cmocka_unit_test(test_delay),
        cmocka_unit_test(test_filters),
        cmocka_unit_test(test_reson),
        cmocka_unit_test(test_sample_interp),
        cmocka_unit_test(test_sample_rate),
        cmocka_unit_test(test_sample_relative),
        cmocka_unit_test(test_energetic_pure),
        cmocka_unit_test(test_energetic_tempo),
        cmocka_unit_test(test_importance),
        cmocka_unit_test(test_inverse_importance),
        cmocka_unit_test(test_sputter),
        cmocka_unit_test(test_errors),
        cmocka_unit_test(test_fuzz),
        cmocka_unit_test(test_no_alloc),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
