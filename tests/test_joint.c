/*
 * test_joint.c - nonlinear elements coupled with no delay between them,
 * solved jointly at their root (templates/nl_joint.c.tmpl).
 *
 * Each network below holds two to four diodes, pairs or curves that
 * share one root: an asymmetric clipper (two diodes in series facing a
 * third), two facing diodes with different laws, a bridge rectifier into
 * a smoothing capacitor whose load floats, a diode in series with a
 * curve, a pair beside a diode, a clipper whose diodes carry a param, and
 * the example decks netlists/clipper_asym.cir and netlists/bridge.cir
 * (driven through their sources' inputs).  Each is driven at 48
 * and 192 kHz by sines of 1 V and 10 V, 1 V white noise and random steps
 * up to 10 V (held 1 to 8 samples: diodes switch between conduction and
 * reverse from one sample to the next), and compared with refsim
 * (tests/refsim.h), which solves the whole trapezoidal nodal system with
 * the exact laws by damped Newton to 1e-13 in long double: the same
 * discretisation, solved independently.
 *   - double voices: every output within JOINT_TOL_DB = -200 dB of the
 *     reference (largest error over the reference's peak);
 *   - float voices: within FLOAT_FACTOR times what rounding the
 *     reference's state to float alone costs on the same run;
 *   - no sample stops at the iteration cap (wdv_class.solve_stats; the
 *     table gives the double voice's Newton steps a solve),
 *     and a voice compiled with --maxit 1 does count the samples it
 *     could not finish, and wdc --render warns of them.
 * The refusals: a contact coupled to a diode (it stores energy and is
 * solved alone), and more than WD_JOINT_MAX nonlinear elements at a root.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testlib.h"
#include "refsim.h"

#define JOINT_TOL_DB (-200.0)
#define FLOAT_FACTOR 64.0
#define MAXOUT 4

typedef struct net {
    const char *name;
    const char *text;
    /* nodes only diodes tie to the rest (the bridge's load, floating
     * while all four block): refsim's Newton cannot pin their common
     * potential, which leakage alone decides, and may stop at its cap
     * there; the outputs do not see it */
    int floating;
    const char *path; /* an example deck instead of text */
    /* its float voice is not held to the float floor: the bridge deck's
     * reservoir (470u at 10 V) loses about 1e-5 of its charge a sample at
     * 192 kHz, close to float's resolution, so any float voice of it is
     * off by about -40 dB however it solves its diodes (refsim's rounded
     * state shows as much at 48 kHz); its double voice is held to
     * JOINT_TOL_DB as the others are */
    int float_limited;
} net;

static const net nets[] = {
    {"asym",
     ".input in\nV1 b 0 in R=2.2k\nC1 b 0 10n\n.model dm diode Is=2.52n n=1.752\n.model dn diode Is=1n\n"
     "D1 b c dm\nD2 c 0 dm\nD3 0 b dn\n.output o v(b)\n.output m v(c)\n", 0, NULL, 0},
    {"facing",
     ".input in\nV1 b 0 in R=1k\nC1 b 0 47n\n.model da diode Is=2.52n n=1.752\n.model db diode Is=10f n=1.2\n"
     "D1 b 0 da\nD2 0 b db\n.output o v(b)\n", 0, NULL, 0},
    {"bridge",
     ".input in\nV1 a 0 in R=10\nR2 a x 1\n.model dr diode Is=14n n=1.9\n"
     "D1 x p dr\nD2 0 p dr\nD3 n x dr\nD4 n 0 dr\nC1 p n 100u\nRL p n 1k\n"
     ".output dc v(p,n)\n.output iin i(V1)\n",
     1, NULL, 0},
    {"curve",
     ".input in\nV1 b 0 in R=1k\nC1 b 0 22n\n.model ds diode Is=1p n=1.5\n"
     "D1 b c ds\nnlres N1 c 0 curve=(-2:-0.004 -0.5:-0.0002 0:0 0.3:0.0001 1:0.003 3:0.02)\n"
     "R3 c 0 100k\n.output o v(b)\n.output m v(c)\n", 0, NULL, 0},
    {"pairdiode",
     ".input in\nV1 b 0 in R=4.7k\nC1 b 0 4.7n\n.model dp diode Is=2.52n n=1.752 pair=1\n.model dq diode Is=5n n=2\n"
     "D1 b 0 dp\nR2 b c 1k\nD2 c 0 dq\nC2 c 0 1n\nD3 b c dq\n.output o v(b)\n.output q v(c)\n", 0, NULL, 0},
    {"param",
     ".input in\n.param is 2.52n min=1p max=1u\n.param rs 2.2k min=100 max=100k\nV1 b 0 in R={rs}\nC1 b 0 10n\n"
     ".model dm diode Is={is} n=1.752\n.model dn diode Is=1n\nD1 b c dm\nD2 c 0 dm\nD3 0 b dn\n.output o v(b)\n", 0, NULL, 0},
    {"asym.cir", NULL, 0, "netlists/clipper_asym.cir", 0},
    {"bridge.cir", NULL, 1, "netlists/bridge.cir", 1},
};
#define NNETS ((int)(sizeof nets / sizeof nets[0]))

typedef enum { SINE1, SINE10, NOISE1, STEPS10, NDRIVES } drive_kind;
static const char *const drive_name[NDRIVES] = {"sine 1 V", "sine 10 V", "noise 1 V", "steps 10 V"};

static void make_drive(drive_kind d, double fs, long n, uint64_t seed, double *x) {
    static const tl_drive_kind kind[NDRIVES] = {TL_DRIVE_SINE, TL_DRIVE_SINE, TL_DRIVE_NOISE, TL_DRIVE_STEPS};
    static const double amp[NDRIVES] = {1, 10, 1, 10};
    tl_drive(kind[d], amp[d], 8, fs, n, seed, x);
}

static const char *write_net(const net *t, char *path, size_t cap) {
    static char dir[64];
    if (t->path) {
        snprintf(path, cap, "%s", t->path);
        return path;
    }
    if (!dir[0])
        assert_int_equal(tl_temp_dir(dir, "joint"), 0);
    char name[64];
    snprintf(name, sizeof name, "j_%s.wdn", t->name);
    snprintf(path, cap, "%s", tl_write_file(dir, name, t->text));
    return path;
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

/* Runs voice and refsim (and refsim with its state rounded to the voice's
 * precision) over the drive; out: the worst error in dB over the outputs,
 * and the rounded reference's (the floor). */
static void run_pair(const Circuit *c, const wdv_class *cls, double fs, const double *x, long n, int floating,
                     double *db, double *floor_db, unsigned long *miss, double *steps) {
    void *st = tl_state_new(cls, fs);
    assert_non_null(st);
    refsim *rs = refsim_new(c, fs, NULL), *rf = refsim_new(c, fs, NULL);
    assert_non_null(rs);
    assert_non_null(rf);
    refsim_round_state(rf, cls->precision);
    double **vo = tl_bufs_new(MAXOUT, n), **ro = tl_bufs_new(MAXOUT, n), **fo = tl_bufs_new(MAXOUT, n);
    assert_non_null(vo);
    assert_non_null(ro);
    assert_non_null(fo);
    double y[MAXOUT], yr[MAXOUT];
    double *op[MAXOUT];
    for (long pos = 0; pos < n; pos += 64) {
        int b = n - pos < 64 ? (int)(n - pos) : 64;
        const double *ip[1] = {x + pos};
        for (int k = 0; k < c->nouts; k++)
            op[k] = vo[k] + pos;
        cls->process(st, ip, op, b);
    }
    for (long k = 0; k < n; k++) {
        refsim_step(rs, &x[k], y);
        refsim_step(rf, &x[k], yr);
        for (int j = 0; j < c->nouts; j++) {
            ro[j][k] = y[j];
            fo[j][k] = yr[j];
        }
    }
    *db = *floor_db = -400;
    for (int j = 0; j < c->nouts; j++) {
        if (getenv("JOINT_VERBOSE")) {
            long at = 0;
            for (long k = 0; k < n; k++)
                if (fabs(vo[j][k] - ro[j][k]) > fabs(vo[j][at] - ro[j][at]))
                    at = k;
            print_message("    %s: %.1f dB at %ld: voice %.17g ref %.17g (o: %.17g %.17g)\n", c->outs[j].name,
                          err_db(vo[j], ro[j], n), at, vo[j][at], ro[j][at], vo[0][at], ro[0][at]);
        }
        *db = fmax(*db, err_db(vo[j], ro[j], n));
        *floor_db = fmax(*floor_db, err_db(fo[j], ro[j], n));
    }
    assert_non_null(cls->solve_stats);
    unsigned long js[WDV_SOLVE_N];
    cls->solve_stats(st, js);
    *miss = js[WDV_SOLVE_CAPPED];
    if (steps)
        *steps = (double)js[WDV_SOLVE_STEPS] / (double)js[WDV_SOLVE_SOLVES];
    assert_true(js[WDV_SOLVE_SOLVES] == (unsigned long)n);
    refsim_nl_info info;
    refsim_nl_stats(rs, &info);
    if (info.unconverged && !floating)
        fail_msg("the reference stopped at its cap at %ld of %ld samples", info.unconverged, info.steps);
    tl_bufs_free(vo, MAXOUT);
    tl_bufs_free(ro, MAXOUT);
    tl_bufs_free(fo, MAXOUT);
    refsim_free(rs);
    refsim_free(rf);
    tl_state_free(st);
}

/* Every network, drive and rate, in double and float, against refsim. */
static void test_joint_accuracy(void **state) {
    (void)state;
    int failed = 0;
    double worst = -400, worst_f = -400;
    print_message("%-10s %-11s %7s %10s %10s %10s %10s %6s\n", "network", "drive", "rate", "double dB", "floor",
                  "float dB", "floor", "steps");
    for (int t = 0; t < NNETS; t++) {
        char path[256];
        write_net(&nets[t], path, sizeof path);
        tl_voice vd, vf;
        Circuit *c = tl_load_both(path, nets[t].name, &vd, &vf);
        static const double rates[] = {48000.0, 192000.0};
        for (int ri = 0; ri < 2; ri++)
            for (int d = 0; d < NDRIVES; d++) {
                double fs = rates[ri];
                long n = (long)(0.05 * fs);
                double *x = malloc(sizeof(double) * (size_t)n);
                assert_non_null(x);
                make_drive((drive_kind)d, fs, n, 0x5eedu + (uint64_t)(t * 16 + d), x);
                double db, dbf, floor_db, floor_d, steps;
                unsigned long miss, missf;
                run_pair(c, vd.cls, fs, x, n, nets[t].floating, &db, &floor_d, &miss, &steps);
                run_pair(c, vf.cls, fs, x, n, nets[t].floating, &dbf, &floor_db, &missf, NULL);
                free(x);
                bool bad = !(db <= JOINT_TOL_DB) || miss || missf ||
                           (!nets[t].float_limited && !(dbf <= fmax(floor_db + 20 * log10(FLOAT_FACTOR), -400)));
                print_message("%-10s %-11s %7.0f %10.1f %10.1f %10.1f %10.1f %6.2f%s\n", nets[t].name, drive_name[d],
                              fs, db, floor_d, dbf, floor_db, steps, bad ? "  FAILED" : "");
                if (miss || missf)
                    print_message("  %lu (double) and %lu (float) samples stopped at the cap\n", miss, missf);
                failed |= bad;
                worst = fmax(worst, db);
                if (!nets[t].float_limited)
                    worst_f = fmax(worst_f, dbf - floor_db);
            }
        tl_voice_free(&vd);
        tl_voice_free(&vf);
    }
    print_message("worst: double %.1f dB; float %.1f dB above its floor\n", worst, worst_f);
    if (failed)
        fail_msg("a joint solve is off the converged reference");
}

/* Param changes between blocks: the param clipper's diode law and source
 * resistance change at random moments; the voice follows refsim. */
static void test_joint_params(void **state) {
    (void)state;
    char path[256];
    write_net(&nets[5], path, sizeof path); /* param */
    Circuit *c = wdc_load(path);
    assert_non_null(c);
    tl_voice v;
    assert_int_equal(tl_voice_build(path, 0, &v), 0);
    tl_rng r;
    tl_rng_seed(&r, 77);
    tl_change ch[8 * 2];
    int nch = tl_random_changes(c, &r, 24000, 8, ch);
    tl_signal sig;
    tl_signal_init(&sig, TL_NOISE, 8.0, 0, 99);
    tl_run_opts o = {0};
    o.fs = 48000;
    o.nframes = 24000;
    o.signal = &sig;
    o.changes = ch;
    o.nchanges = nch;
    tl_run run;
    assert_int_equal(tl_run_side_by_side(c, v.cls, &o, &run), 0);
    double db = -400;
    for (int k = 0; k < run.nouts; k++)
        db = fmax(db, err_db(run.voice[k], run.ref[k], run.nframes));
    print_message("param clipper, %d changes under 8 V noise: %.1f dB\n", nch, db);
    if (!(db <= JOINT_TOL_DB)) {
        for (int k = 0; k < nch; k++)
            print_message("  change at %ld: param %d = %g\n", ch[k].at, ch[k].param, ch[k].value);
        tl_run_report(&run, c, 0, 1e-10);
    }
    tl_run_free(&run);
    tl_voice_free(&v);
    assert_true(db <= JOINT_TOL_DB);
}

/* A cap too low to converge is counted, and a render says so. */
static void test_joint_cap(void **state) {
    (void)state;
    char path[256];
    write_net(&nets[0], path, sizeof path);
    tl_voice v;
    static const char *const one[] = {"--maxit", "1", NULL};
    assert_int_equal(tl_voice_build_args(path, 0, one, NULL, &v), 0);
    void *st = tl_state_new(v.cls, 48000);
    assert_non_null(st);
    double x[256], y[2];
    make_drive(STEPS10, 48000, 256, 1, x);
    for (int k = 0; k < 256; k++) {
        const double *ip[1] = {&x[k]};
        double *op[2] = {&y[0], &y[1]};
        v.cls->process(st, ip, op, 1);
    }
    unsigned long js[WDV_SOLVE_N];
    v.cls->solve_stats(st, js);
    print_message("--maxit 1: %lu of %lu solves stopped at the cap, %lu steps\n", js[WDV_SOLVE_CAPPED],
                  js[WDV_SOLVE_SOLVES], js[WDV_SOLVE_STEPS]);
    assert_true(js[WDV_SOLVE_SOLVES] == 256 && js[WDV_SOLVE_CAPPED] > 0 && js[WDV_SOLVE_CAPPED] <= 256);
    assert_true(js[WDV_SOLVE_STEPS] <= 256);
    v.cls->reset(st);
    v.cls->solve_stats(st, js);
    assert_true(js[0] == 0 && js[1] == 0 && js[2] == 0);
    tl_state_free(st);
    tl_voice_free(&v);
    char cmd[1024];
    snprintf(cmd, sizeof cmd, "bin/wdc '%s' --maxit 1 --render /tmp/joint_cap_$$.wav --input noise:10 --seconds 0.01 "
             "2>&1 | grep -q 'joint solves of the nonlinear elements stopped at the cap of 1 iterations'; r=$?; "
             "rm -f /tmp/joint_cap_$$.wav; exit $r", path);
    assert_int_equal(tl_system(cmd), 0);
}

/* What cannot share a root, refused at its line. */
static void test_joint_refusals(void **state) {
    (void)state;
    char *got = tl_first_report(".domain mechanical\n.input f\nforce F1 a 0 f\nmass M1 a m=10m\n"
                                "contact K1 a b k=1e6 alpha=1.5\nmass M2 b m=20m\nspring S2 b 0 k=1k\n"
                                "nlres N1 a b curve=(-1:-1 1:1)\n.output o v(a)\n",
                                SOLVER_DEFAULT);
    print_message("%s\n", got);
    assert_non_null(strstr(got, "is coupled to"));
    assert_non_null(strstr(got, "stores energy and is solved alone"));
    free(got);
    char text[2048] = ".input in\nV1 a 0 in R=1k\n.model dd diode Is=1n\n";
    for (int k = 0; k < WD_JOINT_MAX + 1; k++) {
        char line[64];
        snprintf(line, sizeof line, "D%d a %s dd\nR%d %s 0 1k\n", k, k ? "0" : "b", k, "b");
        strcat(text, line);
    }
    strcat(text, ".output o v(a)\n");
    got = tl_first_report(text, SOLVER_DEFAULT);
    print_message("%s\n", got);
    assert_non_null(strstr(got, "at most 8 are solved jointly"));
    free(got);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_joint_accuracy),
        cmocka_unit_test(test_joint_params),
        cmocka_unit_test(test_joint_cap),
        cmocka_unit_test(test_joint_refusals),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
