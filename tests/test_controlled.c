/*
 * test_controlled.c - controlled sources (E, G) and ideal op-amps inside a
 * root adaptor.
 *
 * An output and its probe join one root, whose nodal equations they
 * stamp; the root is then active, so it is checked against other
 * solutions rather than for losslessness:
 *
 *   - closed forms, sample by sample: an inverting amplifier with an
 *     ideal op-amp gives exactly -R2/R1 times its input, a non-inverting
 *     one with a finite-gain E gives A / (1 + A R1 / (R1 + R2)), a G into
 *     a resistor gm R; each within 1e-12 of the input's peak (the root's
 *     LU rounding);
 *   - refsim, the extended-precision trapezoidal simulation of the same
 *     circuit (its own MNA stamps of E, G and op-amps), over a sine, noise
 *     and random steps at 48 and 192 kHz: a unity-gain Sallen-Key lowpass
 *     (an op-amp follower in a bridge of two R and two C), a gyrator (two
 *     G and a capacitor: a simulated inductor), the Tube Screamer clipping
 *     stage of netlists/tubescreamer.cir (E with open-loop gain 1e6, a
 *     diode pair in its feedback) and the same stage with an ideal op-amp
 *     and its drive pot a param.  Double voices below -200 dB (the
 *     discretisation is the same; what is left is rounding, amplified by
 *     the stages' gains), float voices below -100 dB;
 *   - param changes: the ideal stage's drive moved 12 times under noise,
 *     in the voice (set_param between blocks) and in refsim at the same
 *     samples, below -200 dB: the root's matrix is solved again with its
 *     op-amp's stamps;
 *   - an ideal op-amp against an E of growing gain: their difference
 *     falls as 1 / A;
 *   - each diagnostic, with its position.
 *
 * Run from the repository root: build/tests/test_controlled (after make).
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testlib.h"

#define MAXOUT 4
#define TOL_DOUBLE_DB (-200.0)
#define TOL_FLOAT_DB (-95.0) /* float eps (-144 dB) through closed-loop gains up to 65 (36 dB), and some */

typedef struct net {
    const char *name;
    const char *text; /* a .wdn, or NULL for path */
    const char *path;
    /* the largest open-loop gain of an E in it (0: none).  A root with a
     * gain A is conditioned about A times worse: its double solve keeps
     * about 16 eps A of relative accuracy, and refsim's Newton in long
     * double stops at 64 A ulps (so may reach its cap on a sample) */
    double gain;
} net;

static const net nets[] = {
    {"sallenkey",
     ".input in\nV1 x 0 in\nR1 x a 10k\nR2 a b 10k\nC1 a o 10n\nC2 b 0 4.7n\nopamp U1 o b o\nR3 o 0 10k\n"
     ".output o v(o)\n.output a v(a)\n",
     NULL, 0},
    {"gyrator",
     ".input in\nV1 x 0 in R=1k\nG1 0 y x 0 1m\nG2 x 0 y 0 1m\nC1 y 0 100n\nR2 y 0 1meg\n.output x v(x)\n"
     ".output y v(y)\n",
     NULL, 0},
    {"ts.cir", NULL, "netlists/tubescreamer.cir", 1e6},
    {"ts_e1k",
     ".input in\nV1 p 0 in\nE1 o 0 p n 1000\nR4 n a 4.7k\nC3 a 0 47n\nR6 o b 51k\nR7 b n 250k\nC4 o n 51p\n"
     ".model d914 diode Is=2.52n n=1.752\nD1 o n d914\nD2 n o d914\n.output o v(o)\n",
     NULL, 1e3},
    {"ts_ideal",
     ".input in\n.param drive 0.5 min=0 max=1\nV1 p 0 in\nopamp U1 o p n\nR4 n a 4.7k\nC3 a 0 47n\nR6 o b 51k\n"
     "pot Pd b w n R=500k pos={drive}\nC4 o n 51p\n.model d914 diode Is=2.52n n=1.752\nD1 o n d914\nD2 n o d914\n"
     ".output o v(o)\n",
     NULL, 0},
    {"pushpull",
     ".input in\nV1 s 0 in\nR0 s 0 1k\nE1 d 0 s 0 10\nRb d x 1k\nVp vcc 0 9\nVn vee 0 -9\n"
     ".model qn npn Is=1e-14 BF=200 BR=5\n.model qp pnp Is=2e-14 BF=150 BR=3 NF=1.1\nQ1 vcc x o qn\nQ2 vee x o qp\n"
     "RL o 0 100\nCL o 0 1u\n.output o v(o)\n.output x v(x)\n",
     NULL, 0},
    {"ts_asym",
     ".input in\nV1 p 0 in\nopamp U1 o p n\nR4 n a 4.7k\nC3 a 0 47n\nR6 o n 301k\nC4 o n 51p\n"
     ".model d914 diode Is=2.52n n=1.752\nD1 o m d914\nD2 m n d914\nD3 n o d914\n.output o v(o)\n.output m v(m)\n",
     NULL, 0},
};
#define NNETS ((int)(sizeof nets / sizeof nets[0]))

static const char *net_path(const net *t) {
    static char dir[64], path[256];
    if (t->path)
        return t->path;
    if (!dir[0])
        assert_int_equal(tl_temp_dir(dir, "ctl"), 0);
    char name[64];
    snprintf(name, sizeof name, "c_%s.wdn", t->name);
    snprintf(path, sizeof path, "%s", tl_write_file(dir, name, t->text));
    return path;
}

typedef enum { SINE, NOISE, STEPS, NDRIVES } drive_kind;
static const char *const drive_name[NDRIVES] = {"sine", "noise", "steps"};

/* Half a volt of sine or noise, or levels of up to a volt held 1 to 16
 * samples. */
static void make_drive(drive_kind d, double fs, long n, uint64_t seed, double *x) {
    static const tl_drive_kind kind[NDRIVES] = {TL_DRIVE_SINE, TL_DRIVE_NOISE, TL_DRIVE_STEPS};
    tl_drive(kind[d], d == STEPS ? 1 : 0.5, 16, fs, n, seed, x);
}

/* Largest |a - b| over the largest |b|, in dB (-400 for exact). */
static double err_db(const double *a, const double *b, long n) {
    double e = 0, p = 0;
    for (long k = 0; k < n; k++) {
        e = fmax(e, fabs(a[k] - b[k]));
        p = fmax(p, fabs(b[k]));
    }
    return e > 0 && p > 0 ? 20 * log10(e / p) : -400;
}

/* A param change: at frame `at`, param `id` to `v`. */
typedef struct change {
    long at;
    int id;
    double v;
} change;

/* The voice (blocks of 64, changes applied between blocks) and refsim
 * over x; the worst output's error in dB. */
static double run_pair(const Circuit *c, const wdv_class *cls, double fs, const double *x, long n,
                       const change *ch, int nch, long *capped) {
    void *st = tl_state_new(cls, fs);
    assert_non_null(st);
    refsim *rs = refsim_new(c, fs, NULL);
    assert_non_null(rs);
    assert_true(c->nouts <= MAXOUT);
    double **vo = tl_bufs_new(MAXOUT, n), **ro = tl_bufs_new(MAXOUT, n);
    assert_non_null(vo);
    assert_non_null(ro);
    double *op[MAXOUT], y[MAXOUT];
    int next = 0;
    for (long pos = 0; pos < n; pos += 64) {
        for (; next < nch && ch[next].at <= pos; next++)
            assert_int_equal(cls->set_param(st, ch[next].id, ch[next].v), 0);
        int b = n - pos < 64 ? (int)(n - pos) : 64;
        const double *ip[1] = {x + pos};
        for (int k = 0; k < c->nouts; k++)
            op[k] = vo[k] + pos;
        cls->process(st, ip, op, b);
    }
    next = 0;
    for (long k = 0; k < n; k++) {
        for (; next < nch && ch[next].at <= k; next++)
            refsim_set_param(rs, ch[next].id, ch[next].v);
        refsim_step(rs, &x[k], y);
        for (int j = 0; j < c->nouts; j++)
            ro[j][k] = y[j];
    }
    double db = -400;
    for (int j = 0; j < c->nouts; j++) {
        db = fmax(db, err_db(vo[j], ro[j], n));
        if (getenv("CTL_VERBOSE")) {
            long at = 0;
            for (long k = 0; k < n; k++)
                if (fabs(vo[j][k] - ro[j][k]) > fabs(vo[j][at] - ro[j][at]))
                    at = k;
            print_message("    %s: %.1f dB, worst at %ld: voice %.17g, refsim %.17g\n", c->outs[j].name,
                          err_db(vo[j], ro[j], n), at, vo[j][at], ro[j][at]);
        }
    }
    refsim_nl_info info;
    refsim_nl_stats(rs, &info);
    if (capped)
        *capped = info.unconverged;
    tl_bufs_free(vo, MAXOUT);
    tl_bufs_free(ro, MAXOUT);
    refsim_free(rs);
    tl_state_free(st);
    return db;
}

/* Each network, drive and rate, in double and float, against refsim. */
static void test_against_refsim(void **state) {
    (void)state;
    int failed = 0;
    double worst = -400, worst_f = -400;
    print_message("%-10s %-6s %7s %10s %10s %8s %5s\n", "network", "drive", "rate", "double dB", "float dB", "bound",
                  "capped");
    for (int t = 0; t < NNETS; t++) {
        const char *path = net_path(&nets[t]);
        tl_voice vd, vf;
        Circuit *c = tl_load_both(path, nets[t].name, &vd, &vf);
        static const double rates[] = {48000.0, 192000.0};
        for (int ri = 0; ri < 2; ri++)
            for (int d = 0; d < NDRIVES; d++) {
                double fs = rates[ri];
                long n = (long)(0.03 * fs);
                double *x = malloc(sizeof(double) * (size_t)n);
                assert_non_null(x);
                make_drive((drive_kind)d, fs, n, 0xc0deu + (uint64_t)(t * 16 + d), x);
                long miss = 0;
                double db = run_pair(c, vd.cls, fs, x, n, NULL, 0, &miss);
                double dbf = run_pair(c, vf.cls, fs, x, n, NULL, 0, NULL);
                free(x);
                double tol = fmax(TOL_DOUBLE_DB, 20 * log10(16 * DBL_EPSILON * nets[t].gain));
                bool bad = !(db <= tol) || !(dbf <= TOL_FLOAT_DB) || (miss && !nets[t].gain);
                print_message("%-10s %-6s %7.0f %10.1f %10.1f %8.1f %5ld%s\n", nets[t].name, drive_name[d], fs, db,
                              dbf, tol, miss, bad ? "  FAILED" : "");
                failed |= bad;
                worst = fmax(worst, db);
                worst_f = fmax(worst_f, dbf);
            }
        tl_voice_free(&vd);
        tl_voice_free(&vf);
    }
    print_message("worst: double %.1f dB, float %.1f dB\n", worst, worst_f);
    if (failed)
        fail_msg("a voice with controlled sources is off refsim");
}

/* The ideal stage's drive moved under noise, voice and refsim alike: with
 * its diode pair solved to 1e-12 as refsim solves it, TOL_DOUBLE_DB; with
 * the fast solver's table (its default), within -100 dB. */
static void test_param_changes(void **state) {
    (void)state;
    for (int fast = 0; fast < 2; fast++) {
        const char *path = net_path(&nets[4]);
        Circuit *c = wdc_load(path);
        assert_non_null(c);
        tl_voice v;
        assert_int_equal(tl_voice_build_args(path, 0, fast ? NULL : tl_exact_diodes, NULL, &v), 0);
        int id = tl_param_id(v.cls, "drive");
        assert_true(id >= 0);
        double fs = 48000;
        long n = 24000;
        double *x = malloc(sizeof(double) * (size_t)n);
        assert_non_null(x);
        make_drive(NOISE, fs, n, 0xd21e, x);
        change ch[12];
        tl_rng r;
        tl_rng_seed(&r, 7);
        for (int k = 0; k < 12; k++)
            ch[k] = (change){(long)(k + 1) * 1856, id, tl_rng_uniform(&r)}; /* 1856 = 29 blocks */
        long miss = 0;
        double db = run_pair(c, v.cls, fs, x, n, ch, 12, &miss);
        assert_int_equal(miss, 0);
        print_message("drive moved 12 times (%s): %.1f dB\n", fast ? "fast solver's table" : "diodes to 1e-12", db);
        assert_true(db <= (fast ? -100 : TOL_DOUBLE_DB));
        free(x);
        tl_voice_free(&v);
    }
}

/* Closed forms: what each amplifier's gain must be, sample by sample. */
static void test_closed_forms(void **state) {
    (void)state;
    static const struct {
        const char *name, *text;
        double gain;
    } amps[] = {
        {"inverting", ".input in\nV1 a 0 in\nR1 a n 10k\nR2 n o 47k\nopamp U1 o 0 n\n.output o v(o)\n", -4.7},
        {"noninv", ".input in\nV1 p 0 in\nE1 o 0 p n 1e5\nR1 n 0 1k\nR2 o n 10k\n.output o v(o)\n",
         1e5 / (1 + 1e5 / 11)},
        {"vccs", ".input in\nV1 a 0 in\nR1 a 0 1k\nG1 0 o a 0 2.5m\nRL o 0 4k\n.output o v(o)\n", 10.0},
        {"follower", ".input in\nV1 p 0 in R=10k\nopamp U1 o p o\nRL o 0 100\n.output o v(o)\n", 1.0},
    };
    char dir[64];
    assert_int_equal(tl_temp_dir(dir, "amps"), 0);
    for (size_t a = 0; a < sizeof amps / sizeof amps[0]; a++) {
        char name[64];
        snprintf(name, sizeof name, "%s.wdn", amps[a].name);
        tl_voice v;
        assert_int_equal(tl_voice_build(tl_write_file(dir, name, amps[a].text), 0, &v), 0);
        void *st = tl_state_new(v.cls, 48000);
        assert_non_null(st);
        double x[256], y[256], worst = 0;
        make_drive(NOISE, 48000, 256, 99 + a, x);
        const double *ip[1] = {x};
        double *op[1] = {y};
        v.cls->process(st, ip, op, 256);
        for (int k = 0; k < 256; k++)
            worst = fmax(worst, fabs(y[k] - amps[a].gain * x[k]));
        print_message("%-9s gain %.12g: worst |y - gain x| %.3g\n", amps[a].name, amps[a].gain, worst);
        assert_true(worst <= 1e-12 * fabs(amps[a].gain));
        tl_state_free(st);
        tl_voice_free(&v);
    }
    tl_remove_dir(dir);
}

/* An E of open-loop gain A in place of the ideal op-amp: the inverting
 * amplifier's gain is -(R2/R1) / (1 + (1 + R2/R1) / A), off the ideal by
 * about 5.7 / A; each voice gives its own exactly. */
static void test_gain_limit(void **state) {
    (void)state;
    char dir[64];
    assert_int_equal(tl_temp_dir(dir, "lim"), 0);
    for (int e = 2; e <= 8; e += 3) {
        double A = pow(10, e);
        char text[256];
        snprintf(text, sizeof text, ".input in\nV1 a 0 in\nR1 a n 10k\nR2 n o 47k\nE1 o 0 0 n %g\n.output o v(o)\n", A);
        tl_voice v;
        assert_int_equal(tl_voice_build(tl_write_file(dir, "lim.wdn", text), 0, &v), 0);
        void *st = tl_state_new(v.cls, 48000);
        double x = 1, y;
        const double *ip[1] = {&x};
        double *op[1] = {&y};
        v.cls->process(st, ip, op, 1);
        double want = -4.7 / (1 + 5.7 / A);
        print_message("A = 1e%d: gain %.15g (closed form %.15g, ideal -4.7)\n", e, y, want);
        assert_true(fabs(y - want) <= 1e-13 * 4.7 * fmax(1, A * 1e-6));
        assert_true(fabs(y + 4.7) <= 6 * 4.7 / A);
        tl_state_free(st);
        tl_voice_free(&v);
    }
    tl_remove_dir(dir);
}

/* Each diagnostic with its position. */
static void test_diagnostics(void **state) {
    (void)state;
    static const struct {
        const char *text, *want;
    } cases[] = {
        {".input in\nV1 a 0 in\nR1 a 0 1k\nE1 b 0 a a 2\nR2 b 0 1k\n",
         "t.wdn:4:1: error: controlled source 'E1' is controlled by the voltage between a node and itself"},
        {".input in\nV1 a 0 in\nR1 a b 1k\nopamp U1 0 a b\nR2 b 0 1k\n",
         "t.wdn:4:1: error: op-amp 'U1' has its output at ground"},
        {".input in\n.param g 2\nV1 a 0 in\nR1 a 0 1k\nE1 b 0 a 0 {g}\nR2 b 0 1k\n",
         "t.wdn:5:13: error: the gain of controlled source 'E1' must be a constant, not a param"},
        {".input in\nV1 a 0 in\nR1 a 0 1k\nG1 b 0 a 0\nR2 b 0 1k\n",
         "t.wdn:4:11: error: controlled source 'G1' needs a value after its nodes"},
        {".input in\nV1 a 0 in\nR1 a 0 1k\nE1 b c a 0 2\nE2 c 0 b c 1\n",
         "t.wdn:4:1: error: node 'b' meets only controlled sources and op-amps: give it a path to ground through "
         "other elements"},
    };
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        char *got = tl_first_report(cases[k].text, SOLVER_DEFAULT);
        print_message("%s\n", got);
        if (strcmp(got, cases[k].want))
            fail_msg("netlist:\n%s\nexpected: %s\n     got: %s", cases[k].text, cases[k].want, got);
        free(got);
    }
}

/* The Fuzz Face deck starts at its DC operating point: with its input
 * held at 0 its nodes stay where they start (within what the joint
 * solve's tolerance, times the pair's gain of about 300, leaves), where
 * from rest its capacitors would charge for a quarter of a second; and
 * its transistors are biased there (Q1's base at a junction's drop, Q2's
 * collector between the rails). */
static void test_operating_point(void **state) {
    (void)state;
    char dir[64];
    assert_int_equal(tl_temp_dir(dir, "op"), 0);
    FILE *f = fopen("netlists/fuzzface.cir", "r");
    assert_non_null(f);
    char text[4096] = "", line[512];
    while (fgets(line, sizeof line, f))
        if (strncmp(line, ".print", 6) && strncmp(line, ".end", 4))
            strcat(text, line);
    fclose(f);
    strcat(text, ".print tran v(b1) v(c1) v(c2) v(out)\n.end\n");
    tl_voice v;
    assert_int_equal(tl_voice_build(tl_write_file(dir, "ff.cir", text), 0, &v), 0);
    void *st = tl_state_new(v.cls, 48000);
    assert_non_null(st);
    enum { N = 4800 };
    static double x[N], y[4][N];
    const double *ip[1] = {x};
    double *op[4] = {y[0], y[1], y[2], y[3]};
    v.cls->process(st, ip, op, N);
    double drift = 0;
    for (int k = 0; k < 4; k++)
        for (int n = 0; n < N; n++)
            drift = fmax(drift, fabs(y[k][n] - y[k][0]));
    print_message("operating point: v(b1) %.6f, v(c1) %.6f, v(c2) %.6f, v(out) %.3g V; drift over 0.1 s %.3g V\n",
                  y[0][0], y[1][0], y[2][0], y[3][0], drift);
    assert_true(drift < 1e-4);
    assert_true(y[0][0] > 0.5 && y[0][0] < 0.7);
    assert_true(y[2][0] > 1 && y[2][0] < 8);
    assert_true(fabs(y[3][0]) < 1e-4);
    tl_state_free(st);
    tl_voice_free(&v);
    tl_remove_dir(dir);
}

/* The operating point's dense solve is bounded: a deck of more than 160
 * unknowns is not solved for it (the voice starts from rest, and the
 * compiler says so) rather than taking the cube of its size. */
static void test_operating_point_bounded(void **state) {
    (void)state;
    char dir[64];
    assert_int_equal(tl_temp_dir(dir, "opbig"), 0);
    char *text = malloc(1 << 16);
    assert_non_null(text);
    int len = sprintf(text, "long ladder\nV1 in 0 SIN(0 1 220)\nRin in n0 1k\n");
    for (int k = 0; k < 160; k++)
        len += sprintf(text + len, "R%d n%d n%d 100\nC%d n%d 0 1n\n", k + 1, k, k + 1, k + 1, k + 1);
    sprintf(text + len, "D1 n160 0 DM\n.model DM D(IS=1n N=1.7)\n.tran 20.8333u 0.01\n.print tran v(n160)\n.end\n");
    const char *path = tl_write_file(dir, "ladder.cir", text);
    char cmd[512], log[128];
    snprintf(log, sizeof log, "%s/log", dir);
    snprintf(cmd, sizeof cmd, "bin/wdc %s -o %s/v 2>%s", path, dir, log);
    assert_int_equal(tl_system(cmd), 0);
    FILE *f = fopen(log, "r");
    assert_non_null(f);
    char line[512];
    bool noted = false;
    while (fgets(line, sizeof line, f))
        noted |= strstr(line, "ladder.cir:2:1: note: the deck's DC operating point was not found: its voice starts "
                              "from rest") != NULL;
    fclose(f);
    assert_true(noted);
    free(text);
    tl_remove_dir(dir);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_closed_forms),
        cmocka_unit_test(test_gain_limit),
        cmocka_unit_test(test_diagnostics),
        cmocka_unit_test(test_against_refsim),
        cmocka_unit_test(test_param_changes),
        cmocka_unit_test(test_operating_point),
        cmocka_unit_test(test_operating_point_bounded),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
