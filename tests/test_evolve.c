/*
 * test_evolve.c - genetic exploration of timbre trees (runtime/tt_evolve.h,
 * `wdrt evolve`): mutations stay well-typed, within their limits, with the
 * seed's params and no new samples or voices, and read back from their
 * text; the spectral distance grows with mistuning; a seed repeats a run
 * and another seed does not; target mode brings a mistuned sine within
 * 1 % of the target's pitch, for three seeds; rating mode writes the
 * files it names and keeps the best rated; bad command lines, seeds and
 * ratings are refused with their exit status and message.
 */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>

#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "testlib.h"
#include "tt.h"
#include "tt_evolve.h"

static char g_dir[64];

static int setup(void **s) {
    (void)s;
    return tl_temp_dir(g_dir, "wdrt-evolve");
}

static int teardown(void **s) {
    (void)s;
    tl_remove_dir(g_dir);
    return 0;
}

/* g_dir/name, in a static buffer of its own (one per slot). */
static const char *in_dir(int slot, const char *fmt, ...) {
    static char buf[8][512];
    int m = snprintf(buf[slot], sizeof buf[slot], "%s/", g_dir);
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf[slot] + m, sizeof buf[slot] - (size_t)m, fmt, ap);
    va_end(ap);
    return buf[slot];
}

static char *slurp(const char *path) {
    FILE *f = fopen(path, "rb");
    if (!f)
        return NULL;
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    char *s = malloc((size_t)n + 1);
    if (s && fread(s, 1, (size_t)n, f) != (size_t)n) {
        free(s);
        s = NULL;
    }
    if (s)
        s[n] = 0;
    fclose(f);
    return s;
}

static int exists(const char *path) {
    struct stat st;
    return stat(path, &st) == 0;
}

/* ---- running the command ---- */

typedef struct outcome {
    int status;
    char *out, *err; /* what it printed (malloc'ed) */
} outcome;

static void outcome_free(outcome *o) {
    free(o->out);
    free(o->err);
}

/* Runs tt_evolve_main on the NULL-terminated arguments after "evolve",
 * with stdout and stderr caught in files; stdin is /dev/null. */
static outcome evolve(const char *first, ...) {
    char *argv[64];
    int argc = 0;
    argv[argc++] = "evolve";
    va_list ap;
    va_start(ap, first);
    for (const char *a = first; a && argc < 63; a = va_arg(ap, const char *))
        argv[argc++] = (char *)a;
    va_end(ap);
    argv[argc] = NULL;
    const char *fo = in_dir(6, "stdout.txt"), *fe = in_dir(7, "stderr.txt");
    fflush(stdout), fflush(stderr);
    int so = dup(1), se = dup(2), si = dup(0);
    int o = open(fo, O_WRONLY | O_CREAT | O_TRUNC, 0644), e = open(fe, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    int nul = open("/dev/null", O_RDONLY);
    assert_true(so >= 0 && se >= 0 && si >= 0 && o >= 0 && e >= 0 && nul >= 0);
    dup2(o, 1), dup2(e, 2), dup2(nul, 0);
    outcome r;
    r.status = tt_evolve_main(argc, argv);
    fflush(stdout), fflush(stderr);
    clearerr(stdin);
    dup2(so, 1), dup2(se, 2), dup2(si, 0);
    close(so), close(se), close(si), close(o), close(e), close(nul);
    r.out = slurp(fo);
    r.err = slurp(fe);
    assert_non_null(r.out);
    assert_non_null(r.err);
    return r;
}

/* The last line of text (a copy, without its newline). */
static char *last_line(const char *text) {
    size_t n = strlen(text);
    while (n && text[n - 1] == '\n')
        n--;
    size_t b = n;
    while (b && text[b - 1] != '\n')
        b--;
    char *l = malloc(n - b + 1);
    memcpy(l, text + b, n - b);
    l[n - b] = 0;
    return l;
}

/* ---- sounds ---- */

/* n frames of the tree t at fs (malloc'ed). */
static double *render_tree(const tt_tree *t, double fs, long n) {
    char err[1024];
    tt_prog *p = tt_compile(t, err, sizeof err);
    if (!p)
        fail_msg("%s", err);
    double *y = malloc(sizeof *y * (size_t)n);
    if (tt_render(p, fs, NULL, y, n, err, sizeof err))
        fail_msg("%s", err);
    tt_prog_free(p);
    return y;
}

/* The last tree of the file at path (or of the expression text). */
static tt_file *read_tree(const char *path, const char *text) {
    char err[2048];
    tt_file *f = path ? tt_file_read(path, NULL, 0, err, sizeof err) : tt_file_from_string(text, err, sizeof err);
    if (!f)
        fail_msg("%s", err);
    return f;
}

static void write_wav_of(const char *expr, double fs, long n, const char *path) {
    tt_file *f = read_tree(NULL, expr);
    double *y = render_tree(tt_file_tree(f, -1), fs, n);
    assert_int_equal(wdrt_wav_write(path, 1, fs, y, n), WDRT_OK);
    free(y);
    tt_file_free(f);
}

/* The frequency of the strongest partial of y[n]: the peak of a Hann-
 * windowed spectrum padded 4 times, refined by a parabola through the
 * log magnitudes around it. */
static double strongest(const double *y, long n, double fs) {
    int m = 1;
    while (m < 4 * n)
        m *= 2;
    double *re = calloc((size_t)m, sizeof *re), *im = calloc((size_t)m, sizeof *im);
    for (long i = 0; i < n; i++)
        re[i] = y[i] * (0.5 - 0.5 * cos(2 * M_PI * i / n));
    assert_int_equal(tt_evo_fft(re, im, m), 0);
    int k = 1;
    for (int i = 1; i < m / 2; i++) {
        re[i] = log(re[i] * re[i] + im[i] * im[i] + 1e-300);
        if (i > 1 && re[i - 1] > re[k])
            k = i - 1;
    }
    double a = re[k - 1], b = re[k], c = re[k + 1], d = 0.5 * (a - c) / (a - 2 * b + c);
    free(re), free(im);
    return (k + d) * fs / m;
}

/* ---- random numbers and the FFT ---- */

static void test_rng(void **s) {
    (void)s;
    tt_evo_rng a, b, c;
    tt_evo_rng_seed(&a, 42), tt_evo_rng_seed(&b, 42), tt_evo_rng_seed(&c, 43);
    int same = 0;
    double sum = 0, sq = 0;
    for (int i = 0; i < 10000; i++) {
        uint64_t x = tt_evo_rng_next(&a);
        assert_true(x == tt_evo_rng_next(&b));
        same += x == tt_evo_rng_next(&c);
        double u = tt_evo_rng_uniform(&a), z = tt_evo_rng_normal(&a);
        assert_true(u >= 0 && u < 1);
        tt_evo_rng_uniform(&b), tt_evo_rng_normal(&b), tt_evo_rng_uniform(&c), tt_evo_rng_normal(&c);
        sum += z, sq += z * z;
    }
    assert_int_equal(same, 0);
    assert_true(fabs(sum / 10000) < 0.05 && fabs(sq / 10000 - 1) < 0.05);
}

static void test_fft(void **s) {
    (void)s;
    enum { N = 256 };
    double re[N], im[N];
    tl_rng r;
    tl_rng_seed(&r, 5);
    double x[N], y[N];
    for (int i = 0; i < N; i++)
        re[i] = x[i] = tl_rng_signed(&r), im[i] = y[i] = tl_rng_signed(&r);
    assert_int_equal(tt_evo_fft(re, im, N), 0);
    for (int k = 0; k < N; k += 17) {
        double sr = 0, si = 0;
        for (int i = 0; i < N; i++) {
            double w = -2 * M_PI * (double)k * i / N;
            sr += x[i] * cos(w) - y[i] * sin(w), si += x[i] * sin(w) + y[i] * cos(w);
        }
        assert_float_equal(re[k], sr, 1e-10);
        assert_float_equal(im[k], si, 1e-10);
    }
    assert_int_equal(tt_evo_fft(re, im, 100), -1);
}

/* The distance is 0 to itself and grows as a sine is mistuned further,
 * from 1 % to an octave: the slope a search follows. */
static void test_distance_slope(void **s) {
    (void)s;
    double fs = 16000;
    long n = 8000;
    double *x = malloc(sizeof *x * n), *y = malloc(sizeof *y * n);
    for (long i = 0; i < n; i++)
        x[i] = 0.5 * sin(2 * M_PI * 440 * i / fs);
    tt_evo_spectra *sp = tt_evo_spectra_new(x, n, fs);
    assert_non_null(sp);
    assert_true(tt_evo_distance(sp, x, n) < 1e-9);
    double last = 0;
    static const double ratio[] = {1.01, 1.03, 1.1, 1.2, 1.4, 2};
    for (int k = 0; k < 6; k++)
        for (int dir = -1; dir <= 1; dir += 2) {
            double f = 440 * pow(ratio[k], dir);
            for (long i = 0; i < n; i++)
                y[i] = 0.5 * sin(2 * M_PI * f * i / fs);
            double d = tt_evo_distance(sp, y, n);
            if (dir > 0) {
                assert_true(d > last);
                last = d;
            }
            assert_true(d > 0.1);
        }
    for (long i = 0; i < n; i++)
        y[i] = 0;
    assert_true(tt_evo_distance(sp, y, n) > last); /* silence is worse than any tone */
    tt_evo_spectra_free(sp);
    free(x), free(y);
}

/* ---- mutations ---- */

static const tt_node *find_sample(const tt_node *x) {
    if (x->op == TT_SAMPLE)
        return x;
    for (int i = 0; i < x->n; i++)
        if (find_sample(x->a[i]))
            return find_sample(x->a[i]);
    return NULL;
}

/* Every sample node of x names a file that a sample of the seed names;
 * params are the seed's. */
static void check_nodes(const tt_node *x, const tt_tree *seed, const char *sample) {
    if (x->op == TT_SAMPLE)
        assert_string_equal(x->s, sample);
    if (x->op == TT_PARAM) {
        assert_true(x->v >= 0 && x->v < seed->nparams);
        assert_string_equal(x->s, seed->pname[(int)x->v]);
    }
    assert_true(x->op != TT_VOICE);
    for (int i = 0; i < x->n; i++)
        check_nodes(x->a[i], seed, sample);
}

static void check_mutant(const tt_tree *m, const tt_tree *seed, const tt_evo_limits *lim, const char *sample) {
    assert_true(tt_node_depth(m->root) <= lim->max_depth);
    assert_true(tt_node_count(m->root) <= lim->max_nodes);
    assert_int_equal(m->nparams, seed->nparams);
    for (int i = 0; i < seed->nparams; i++) {
        assert_string_equal(m->pname[i], seed->pname[i]);
        assert_true(m->pdef[i] == seed->pdef[i]);
    }
    check_nodes(m->root, seed, sample);
    /* checks again, and its text reads back to a tree that checks */
    tt_tree *c = tt_tree_clone(m);
    char err[1024];
    if (tt_check(c, err, sizeof err))
        fail_msg("a mutant does not check: %s", err);
    tt_tree_free(c);
    char *text = NULL;
    size_t len = 0;
    FILE *f = open_memstream(&text, &len);
    tt_print_tree(f, m);
    fclose(f);
    tt_file *back = tt_file_read(in_dir(0, "mutant.tt"), text, len, err, sizeof err);
    if (!back)
        fail_msg("a mutant does not read back: %s\n%s", err, text);
    tt_file_free(back);
    free(text);
}

static void test_mutations(void **s) {
    (void)s;
    double tone[800];
    for (int i = 0; i < 800; i++)
        tone[i] = sin(i * 0.3);
    assert_int_equal(wdrt_wav_write(in_dir(0, "tone.wav"), 1, 8000, tone, 800), WDRT_OK);
    static const char *const seeds[] = {
        "(* 0.5 (sine (* 370 t)))",
        "(tree bell (params (f 440) (decay 3 0.1 10)) (* (env (0 0) (0.01 1) (2 0)) (reson (noise) f decay)))",
        "(tree buzz (params (f 110)) (lowpass (saw (* f t)) (* 8 f) 2))",
        "(combine (* 0.1 (sine (* (rvector 200 5 800) t))))",
        "(importance ((sine (* 220 t)) 1) ((osc 330 square) 2 lock))",
        "(+ (* 0.3 (sample \"tone.wav\")) (delay (* 0.1 (triangle (* 2 t))) 0.01))",
    };
    tt_evo_rng r;
    tt_evo_rng_seed(&r, 2024);
    int made[TT_NMUT] = {0}, tried[TT_NMUT] = {0}, total = 0;
    for (int k = 0; k < 6; k++) {
        char name[32];
        snprintf(name, sizeof name, "seed%d.tt", k);
        tt_file *f = read_tree(tl_write_file(g_dir, name, seeds[k]), NULL);
        const tt_tree *seed = tt_file_tree(f, -1);
        tt_evo_limits lim = tt_evo_default_limits(seed);
        assert_int_equal(lim.max_depth, tt_node_depth(seed->root) + 4);
        const tt_node *smp = find_sample(seed->root);
        const char *sample = smp ? smp->s : "";
        /* a pool of 6, each step replacing a random member by a mutant of
           it (crossed with another member) */
        tt_tree *pool[6];
        for (int i = 0; i < 6; i++)
            pool[i] = tt_tree_clone(seed);
        for (int it = 0; it < 400; it++) {
            int a = (int)(tt_evo_rng_uniform(&r) * 6), b = (int)(tt_evo_rng_uniform(&r) * 6);
            tt_mutation kind = it % 2 ? TT_MUT_ANY : (tt_mutation)(it / 2 % TT_NMUT);
            tt_tree *m = tt_evo_mutate(pool[a], pool[b], kind, &lim, &r);
            if (kind != TT_MUT_ANY)
                tried[kind]++;
            if (!m)
                continue;
            if (kind != TT_MUT_ANY)
                made[kind]++;
            total++;
            check_mutant(m, seed, &lim, sample);
            tt_tree_free(pool[a]);
            pool[a] = m;
        }
        for (int i = 0; i < 6; i++)
            tt_tree_free(pool[i]);
        tt_file_free(f);
    }
    print_message("mutations: %d of 2400 made\n", total);
    assert_true(total > 2300);
    for (int k = 0; k < TT_NMUT; k++)
        assert_true(made[k] > tried[k] * 9 / 10);
}

/* A tree without numbers cannot be perturbed; a tight depth limit is
 * kept. */
static void test_mutation_limits(void **s) {
    (void)s;
    tt_file *f = read_tree(NULL, "(saw (* fs t))");
    const tt_tree *seed = tt_file_tree(f, -1);
    tt_evo_rng r;
    tt_evo_rng_seed(&r, 1);
    tt_evo_limits lim = tt_evo_default_limits(seed);
    assert_null(tt_evo_mutate(seed, NULL, TT_MUT_PERTURB, &lim, &r));
    lim.max_depth = tt_node_depth(seed->root);
    for (int i = 0; i < 200; i++) {
        tt_tree *m = tt_evo_mutate(seed, seed, TT_MUT_ANY, &lim, &r);
        if (m)
            assert_true(tt_node_depth(m->root) <= lim.max_depth);
        tt_tree_free(m);
    }
    tt_file_free(f);
}

/* ---- target mode ---- */

/* A 440 Hz target (fs, n frames) and a seed 3 semitones flat. */
static void mistuned(double fs, long n) {
    write_wav_of("(* 0.5 (sine (* 440 t)))", fs, n, in_dir(0, "a440.wav"));
    tl_write_file(g_dir, "flat.tt", "; a sine, three semitones flat\n(* 0.5 (sine (* 370 t)))\n");
}

static void test_repeatable(void **s) {
    (void)s;
    mistuned(8000, 2000);
    char *best[3], *line[3];
    static const char *const seeds[] = {"7", "7", "8"};
    for (int k = 0; k < 3; k++) {
        const char *dir = in_dir(2, "rep%d", k);
        outcome o = evolve(in_dir(1, "flat.tt"), "--target", in_dir(0, "a440.wav"), "--population", "8",
                           "--generations", "4", "--seed", seeds[k], "-o", dir, "--quiet", NULL);
        if (o.status)
            fail_msg("status %d: %s", o.status, o.err);
        assert_string_equal(o.err, "");
        best[k] = slurp(in_dir(3, "rep%d/best.tt", k));
        assert_non_null(best[k]);
        line[k] = last_line(o.out);
        outcome_free(&o);
    }
    assert_string_equal(best[0], best[1]);
    assert_string_equal(line[0], line[1]);
    assert_string_not_equal(best[0], best[2]);
    assert_string_not_equal(line[0], line[2]);
    for (int g = 0; g < 4; g++) {
        char *a = slurp(in_dir(3, "rep0/gen-%03d-best.tt", g)), *b = slurp(in_dir(4, "rep1/gen-%03d-best.tt", g));
        assert_non_null(a);
        assert_non_null(b);
        assert_string_equal(a, b);
        free(a), free(b);
    }
    for (int k = 0; k < 3; k++)
        free(best[k]), free(line[k]);
}

/* The acceptance test: from 370 Hz to within 1 % of a 440 Hz
 * target, in 40 generations of 20, for three seeds (98 seeds of 100
 * tried, 100 to 199, got there). */
static void test_finds_pitch(void **s) {
    (void)s;
    double fs = 16000;
    long n = 8000;
    mistuned(fs, n);
    static const char *const seeds[] = {"1", "2", "3"};
    for (int k = 0; k < 3; k++) {
        const char *dir = in_dir(2, "pitch%d", k);
        outcome o = evolve(in_dir(1, "flat.tt"), "--target", in_dir(0, "a440.wav"), "--population", "20",
                           "--generations", "40", "--seed", seeds[k], "-o", dir, "--quiet", NULL);
        if (o.status)
            fail_msg("status %d: %s", o.status, o.err);
        tt_file *f = read_tree(in_dir(3, "pitch%d/best.tt", k), NULL);
        double *y = render_tree(tt_file_tree(f, -1), fs, n);
        double f0 = strongest(y, n, fs);
        free(y);
        tt_file_free(f);
        /* the expression printed last renders the same */
        char *line = last_line(o.out);
        f = read_tree(NULL, line);
        y = render_tree(tt_file_tree(f, -1), fs, n);
        double f1 = strongest(y, n, fs);
        free(y);
        tt_file_free(f);
        print_message("seed %s: %.2f Hz: %s\n", seeds[k], f0, line);
        assert_float_equal(f1, f0, 1e-6);
        assert_true(fabs(f0 / 440 - 1) < 0.01);
        free(line);
        outcome_free(&o);
    }
}

/* ---- rating mode ---- */

/* Parents are drawn in proportion to the ratings, however large: ratings
 * of 1e308 (whose sum overflows) breed what ratings of 1 breed. */
static void test_huge_ratings(void **s) {
    (void)s;
    char seed[600], r1[600], rh[600];
    snprintf(seed, sizeof seed, "%s", tl_write_file(g_dir, "hum.tt", "(* 0.3 (saw (* 220 t)))\n"));
    /* (and a byte-order mark, as editors on Windows write, is read) */
    snprintf(r1, sizeof r1, "%s", tl_write_file(g_dir, "r1.txt", "\xef\xbb\xbf" "1 1 1 1 1 1\r\n1 1 1 1 1 1\r\n"));
    snprintf(rh, sizeof rh, "%s", tl_write_file(g_dir, "rh.txt", "1e308 1e308 1e308 1e308 1e308 1e308\n"
                                                                 "1e308 1e308 1e308 1e308 1e308 1e308\n"));
    for (int k = 0; k < 2; k++) {
        outcome o = evolve(seed, "--ratings", k ? rh : r1, "--population", "6", "--generations", "2", "--seconds",
                           "0.05", "--rate", "8000", "--seed", "5", "-o", in_dir(2, "huge%d", k), "--quiet", NULL);
        if (o.status)
            fail_msg("status %d: %s", o.status, o.err);
        outcome_free(&o);
    }
    for (int i = 0; i < 6; i++) {
        char *a = slurp(in_dir(3, "huge0/gen-001/ind-%02d.tt", i)), *b = slurp(in_dir(4, "huge1/gen-001/ind-%02d.tt", i));
        assert_string_equal(a, b);
        free(a);
        free(b);
    }
}

static void test_ratings(void **s) {
    (void)s;
    char seed[600], ratings[600];
    snprintf(seed, sizeof seed, "%s", tl_write_file(g_dir, "buzz.tt", "(tree buzz (params (f 220) (a 0.3)) (* a (saw (* f t))))\n"));
    snprintf(ratings, sizeof ratings, "%s",
             tl_write_file(g_dir, "ratings.txt", "# two generations of four\n1 5 2 0\n\n3, 1, 0.5, 9\n"));
    const char *dir = in_dir(2, "rated");
    outcome o = evolve(seed, "--ratings", ratings, "--population", "4", "--generations", "2", "--seconds", "0.1",
                       "--rate", "8000", "--seed", "11", "-o", dir, "--quiet", NULL);
    if (o.status)
        fail_msg("status %d: %s", o.status, o.err);
    for (int g = 0; g < 2; g++)
        for (int i = 0; i < 4; i++) {
            int nch;
            double fs, *y;
            long n;
            assert_true(exists(in_dir(3, "rated/gen-%03d/ind-%02d.tt", g, i)));
            assert_int_equal(wdrt_wav_read(in_dir(3, "rated/gen-%03d/ind-%02d.wav", g, i), &nch, &fs, &y, &n),
                             WDRT_OK);
            assert_int_equal(nch, 1);
            assert_int_equal(n, 800);
            assert_true(fs == 8000);
            free(y);
            /* each keeps the seed's params */
            tt_file *f = read_tree(in_dir(3, "rated/gen-%03d/ind-%02d.tt", g, i), NULL);
            const tt_tree *t = tt_file_tree(f, -1);
            assert_int_equal(t->nparams, 2);
            assert_string_equal(t->pname[0], "f");
            assert_string_equal(t->pname[1], "a");
            assert_true(t->pdef[0] == 220 && t->pdef[1] == 0.3);
            tt_file_free(f);
        }
    assert_true(exists(in_dir(3, "rated/best.wav")));
    /* the seed is individual 0 of generation 0; the best rated (1, 5 for
       generation 0) is kept as individual 0 of generation 1 and is
       generation 0's best; generation 1's best (9) is the run's */
    char *seed_text = slurp(in_dir(3, "rated/gen-000/ind-00.tt"));
    assert_non_null(strstr(seed_text, "(* a (saw (* f t)))"));
    char *a = slurp(in_dir(3, "rated/gen-000/ind-01.tt")), *b = slurp(in_dir(4, "rated/gen-001/ind-00.tt"));
    char *c = slurp(in_dir(5, "rated/gen-000-best.tt"));
    assert_string_equal(a, b);
    assert_string_equal(a, c);
    free(a), free(b), free(c);
    a = slurp(in_dir(3, "rated/gen-001/ind-03.tt")), b = slurp(in_dir(4, "rated/gen-001-best.tt"));
    c = slurp(in_dir(5, "rated/best.tt"));
    assert_string_equal(a, b);
    assert_string_equal(a, c);
    free(a), free(b), free(c), free(seed_text);
    /* the expression printed last has its params at their defaults */
    char *line = last_line(o.out);
    tt_file_free(read_tree(NULL, line)); /* `f` or `a` left in it would be unknown names */
    free(line);
    outcome_free(&o);

    /* a ratings file that runs out, or a line with the wrong count */
    o = evolve(seed, "--ratings", ratings, "--population", "4", "--generations", "3", "--seconds", "0.1", "--rate",
               "8000", "--seed", "1", "-o", dir, "--quiet", NULL);
    assert_int_equal(o.status, 1);
    assert_non_null(strstr(o.err, "no ratings for generation 2"));
    outcome_free(&o);
    const char *bad = tl_write_file(g_dir, "bad-ratings.txt", "1 2 3\n");
    o = evolve(seed, "--ratings", bad, "--population", "4", "--seconds", "0.1", "--seed", "1", "-o", dir, "--quiet",
               NULL);
    assert_int_equal(o.status, 1);
    char want[600];
    snprintf(want, sizeof want, "%s:1:1: error: 3 ratings where the generation has 4", bad);
    assert_non_null(strstr(o.err, want));
    outcome_free(&o);
    bad = tl_write_file(g_dir, "bad-ratings.txt", "1 2 x 3\n");
    o = evolve(seed, "--ratings", bad, "--population", "4", "--seconds", "0.1", "--seed", "1", "-o", dir, "--quiet",
               NULL);
    assert_int_equal(o.status, 1);
    snprintf(want, sizeof want, "%s:1:5: error: a rating is a number >= 0", bad);
    assert_non_null(strstr(o.err, want));
    outcome_free(&o);
    /* a NUL byte, which cut the line short and left the rest unread */
    bad = tl_write_file(g_dir, "nul-ratings.txt", "1 2 3 4\n");
    FILE *nf = fopen(bad, "a");
    assert_non_null(nf);
    fwrite("1 2\0 3 4\n", 1, 9, nf);
    fclose(nf);
    o = evolve(seed, "--ratings", bad, "--population", "4", "--generations", "2", "--seconds", "0.1", "--seed", "1",
               "-o", dir, "--quiet", NULL);
    assert_int_equal(o.status, 1);
    snprintf(want, sizeof want, "%s:2:4: error: the line contains a NUL byte", bad);
    assert_non_null(strstr(o.err, want));
    outcome_free(&o);
    /* no ratings file: standard input, here empty */
    o = evolve(seed, "--population", "4", "--seconds", "0.1", "--seed", "1", "-o", dir, "--quiet", NULL);
    assert_int_equal(o.status, 1);
    assert_non_null(strstr(o.err, "<stdin>: error: no ratings for generation 0"));
    outcome_free(&o);
}

/* A seed's samples are named by paths the written trees read from their
 * own folder. */
static void test_sample_paths(void **s) {
    (void)s;
    double tone[4000];
    for (int i = 0; i < 4000; i++)
        tone[i] = 0.5 * sin(i * 0.2);
    assert_int_equal(wdrt_wav_write(in_dir(0, "tone.wav"), 1, 8000, tone, 4000), WDRT_OK);
    tl_write_file(g_dir, "sampled.tt", "(* 0.5 (sample \"tone.wav\"))\n");
    tl_write_file(g_dir, "r4.txt", "1 2 3 4\n4 3 2 1\n");
    /* run from g_dir with relative paths: the reader keeps them relative */
    char cwd[600];
    assert_non_null(getcwd(cwd, sizeof cwd));
    assert_int_equal(chdir(g_dir), 0);
    outcome o = evolve("sampled.tt", "--ratings", "r4.txt", "--population", "4", "--generations", "2", "--seconds",
                       "0.2", "--rate", "8000", "--seed", "3", "-o", "sampled/deeper", "--quiet", NULL);
    assert_int_equal(chdir(cwd), 0);
    if (o.status)
        fail_msg("status %d: %s", o.status, o.err);
    tt_file_free(read_tree(in_dir(3, "sampled/deeper/best.tt"), NULL));
    tt_file_free(read_tree(in_dir(3, "sampled/deeper/gen-000/ind-00.tt"), NULL));
    char *line = last_line(o.out);
    tt_file_free(read_tree(NULL, line));
    free(line);
    outcome_free(&o);
}

/* ---- bad command lines and seeds ---- */

static void expect(int status, const char *needle, const char *first, ...) {
    char *argv[32];
    int argc = 0;
    va_list ap;
    va_start(ap, first);
    for (const char *a = first; a && argc < 30; a = va_arg(ap, const char *))
        argv[argc++] = (char *)a;
    va_end(ap);
    for (int i = argc; i < 32; i++)
        argv[i] = NULL;
    outcome o = evolve(argv[0], argv[1], argv[2], argv[3], argv[4], argv[5], argv[6], argv[7], NULL);
    if (o.status != status || !strstr(status ? o.err : o.out, needle))
        fail_msg("%s ...: status %d (want %d), stderr:\n%s", first ? first : "(none)", o.status, status, o.err);
    outcome_free(&o);
}

static void test_command_line(void **s) {
    (void)s;
    char seed[600];
    snprintf(seed, sizeof seed, "%s", tl_write_file(g_dir, "ok.tt", "(* 0.5 (sine (* 370 t)))\n"));
    const char *dir = in_dir(2, "cli");
    expect(0, "usage: wdrt evolve SEED.tt", "--help", NULL);
    expect(2, "error: evolve needs a seed tree", NULL);
    expect(2, "unknown option '--frobnicate'", seed, "--frobnicate", NULL);
    expect(2, "--population takes a whole number from 2", seed, "--population", "0", NULL);
    expect(2, "--population takes a whole number from 2", seed, "--population", "x", NULL);
    expect(2, "--generations takes a whole number", seed, "--generations", NULL);
    expect(2, "--seed takes a whole number", seed, "--seed", "-1", NULL);
    expect(2, "--rate takes a number from 1000", seed, "--rate", "10", NULL);
    expect(2, "--seconds takes", seed, "--seconds", "0", NULL);
    expect(2, "one seed at a time", seed, seed, NULL);
    expect(2, "--ratings or --target, not both", seed, "--ratings", "r.txt", "--target", "t.wav", NULL);
    expect(2, "--depth 1 is less than the seed's depth, 4", seed, "--depth", "1", "--quiet", "-o", dir, NULL);
    /* the seed's errors are the reader's, at FILE:LINE:COL */
    const char *bad = tl_write_file(g_dir, "bad.tt", "; a bad seed\n(* 0.5 (sine (* 370 t))\n");
    char want[600];
    snprintf(want, sizeof want, "%s:2:24: error: expected ')'", bad);
    expect(1, want, bad, "--quiet", "-o", dir, NULL);
    bad = tl_write_file(g_dir, "bad2.tt", "(* 0.5\n   (sinus (* 370 t)))\n");
    snprintf(want, sizeof want, "%s:2:5: error:", bad);
    expect(1, want, bad, "--quiet", "-o", dir, NULL);
    expect(1, "cannot read", in_dir(0, "missing.tt"), "--quiet", "-o", dir, NULL);
    expect(1, "cannot read the target 'missing.wav'", seed, "--target", "missing.wav", "--quiet", "-o", dir, NULL);
    /* a target of NaN, of silence or at a rate no render takes is refused, not evolved towards */
    double y[4800];
    for (int i = 0; i < 4800; i++)
        y[i] = 0.25 * sin(0.05 * i);
    const char *sil = in_dir(0, "silent.wav"), *slow = in_dir(1, "slow.wav"), *nan_ = in_dir(4, "nan.wav");
    assert_int_equal(wdrt_wav_write(slow, 1, 500, y, 4800), WDRT_OK);
    expect(1, "/slow.wav' is at 500 Hz; a target's rate lies between 1000 and 768000 Hz", seed, "--target", slow,
           "--quiet", "-o", dir, NULL);
    y[4000] = NAN;
    assert_int_equal(wdrt_wav_write(nan_, 1, 8000, y, 4800), WDRT_OK);
    expect(1, "nan.wav: the sample at frame 4000, channel 1, is not a number", seed, "--target", nan_, "--quiet",
           "-o", dir, NULL);
    memset(y, 0, sizeof y);
    assert_int_equal(wdrt_wav_write(sil, 1, 8000, y, 4800), WDRT_OK);
    expect(1, "/silent.wav' is silent: there is nothing to evolve towards", seed, "--target", sil, "--quiet", "-o",
           dir, NULL);
    expect(1, "cannot read 'missing.txt'", seed, "--ratings", "missing.txt", "--quiet", "-o", dir, NULL);
    /* voice nodes are refused where they are written */
    tl_write_file(g_dir, "v.wdn", "* a netlist (the reader only reads it)\n");
    bad = tl_write_file(g_dir, "voice.tt", "(* 0.5 (voice \"v.wdn\" (in (noise))))\n");
    snprintf(want, sizeof want, "%s:1:8: error: evolve does not take voice nodes", bad);
    expect(1, want, bad, "--quiet", "-o", dir, NULL);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_rng),           cmocka_unit_test(test_fft),
        cmocka_unit_test(test_distance_slope), cmocka_unit_test(test_mutations),
        cmocka_unit_test(test_mutation_limits), cmocka_unit_test(test_repeatable),
        cmocka_unit_test(test_finds_pitch),   cmocka_unit_test(test_ratings), cmocka_unit_test(test_huge_ratings),
        cmocka_unit_test(test_sample_paths),
        cmocka_unit_test(test_command_line),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
