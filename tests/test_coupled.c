/*
 * test_coupled.c - coupled inductors (K lines).
 *
 * Elaboration takes the inductors K lines join as the windings of one
 * core: a magnetising inductance across the first winding behind its
 * leakage, and an ideal transformer (E_XF) from it to each other winding
 * behind that winding's leakage.  Checked here:
 *
 *   - the inductance matrix, as an identity of the discretisation: with
 *     every winding driven by a current source, the trapezoidal rule gives
 *     v[n] + v[n-1] = (2/T) L (i[n] - i[n-1]) for the matrix L of self
 *     and mutual inductances M_ij = k_ij sqrt(L_i L_j), whatever elements
 *     realise it; held to 1e-11 of the largest voltage for a pair, a pair
 *     with k < 0, a perfectly coupled pair (k = 1, no leakage), three
 *     windings whose couplings are products c_i c_j with mixed signs, and
 *     three coupled by one K line (LTspice's form: every pair alike);
 *   - refsim, the extended-precision trapezoidal simulation of the same
 *     elaborated circuit with its own MNA stamp of the transformer, over a
 *     sine, noise and random steps at 48 and 192 kHz: a transformer into
 *     an RC load, three windings into resistive loads, a transformer
 *     feeding a diode bridge (the transformer and the four diodes at one
 *     root, solved jointly).  Double voices below -200 dB; float voices
 *     within 8 times the error that merely rounding refsim's state to
 *     float causes (its floor) or -100 dB, whichever is larger;
 *   - ngspice (tests/ref/coupled_tran.csv, made by
 *     tests/ref/coupled_ngspice.sh) on two decks read as written: a
 *     centre-tapped transformer (three windings, three K lines) and a
 *     pair with a negative coefficient, at 48 and 192 kHz, each vector
 *     below its bound and its error falling at least 12 times over the
 *     fourfold rate (second order: 16);
 *   - each diagnostic, with its position.
 *
 * Measured (ngspice 39), relative RMS error:
 *
 *     deck       vector  48 kHz    192 kHz   ratio
 *     xfmr_ct    v(b)    -63.6 dB  -88.4 dB  17.5
 *     xfmr_ct    v(c)    -63.6 dB  -88.4 dB  17.5
 *     xfmr_ct    i(l1)   -63.9 dB  -89.1 dB  18.2
 *     xfmr_neg   v(b)    -54.4 dB  -78.5 dB  16.1
 *     xfmr_neg   i(l2)   -49.0 dB  -73.2 dB  16.1
 *
 * (ngspice's own error, the difference between its 10 ns and 5 ns runs,
 * is below 3.1e-10 V and 2.4e-11 A.)
 *
 * Run from the repository root: build/tests/test_coupled (after make).
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

#define TOL_DOUBLE_DB (-200.0)
#define FLOAT_FACTOR 8.0
#define TOL_FLOAT_DB (-100.0)

static char dir[64];

static const char *write_net(const char *name, const char *text) {
    static char path[256];
    if (!dir[0])
        assert_int_equal(tl_temp_dir(dir, "coupled"), 0);
    char file[64];
    snprintf(file, sizeof file, "k_%s.wdn", name);
    snprintf(path, sizeof path, "%s", tl_write_file(dir, file, text));
    return path;
}

/* ---- the inductance matrix ---- */

typedef struct group {
    const char *name;
    int n;                 /* windings */
    double L[3];           /* self inductances, H */
    double k[3][3];        /* couplings (upper triangle) */
    int oneline;           /* one K line for all (equal) couplings, LTspice's form */
} group;

static const group groups[] = {
    {"pair", 2, {10e-3, 40e-3}, {{0, 0.9}}, 0},
    {"negative", 2, {1e-3, 2.5e-3}, {{0, -0.7}}, 0},
    {"perfect", 2, {4e-3, 1e-3}, {{0, 1}}, 0},
    /* c = 0.9, 0.8, 0.95 with signs +, -, +: k_01 = -0.72, k_02 = 0.855,
     * k_12 = -0.76 */
    {"three", 3, {10e-3, 2.5e-3, 3e-3}, {{0, -0.72, 0.855}, {0, 0, -0.76}}, 0},
    {"oneline", 3, {2e-3, 1e-3, 4e-3}, {{0, 0.95, 0.95}, {0, 0, 0.95}}, 1},
};

/* Each winding w driven by current source Iw from ground into its first
 * node, its second node grounded; outputs the windings' voltages. */
static char *group_netlist(const group *g) {
    static char text[2048];
    int len = 0;
    for (int w = 0; w < g->n; w++)
        len += snprintf(text + len, sizeof text - (size_t)len, ".input i%d\nI%d 0 a%d i%d\nL%d a%d 0 %.17g\n", w, w,
                        w, w, w, w, g->L[w]);
    int nk = 0;
    if (g->oneline)
        len += snprintf(text + len, sizeof text - (size_t)len, "K0 L0 L1 L2 %.17g\n", g->k[0][1]);
    for (int a = 0; a < g->n && !g->oneline; a++)
        for (int b = a + 1; b < g->n; b++)
            len += snprintf(text + len, sizeof text - (size_t)len, "K%d L%d L%d %.17g\n", nk++, a, b, g->k[a][b]);
    for (int w = 0; w < g->n; w++)
        len += snprintf(text + len, sizeof text - (size_t)len, ".output v%d v(a%d)\n", w, w);
    return text;
}

static void test_inductance_identity(void **state) {
    (void)state;
    const double fs = 48000, T = 1 / fs;
    const long n = 4800;
    for (size_t gi = 0; gi < sizeof groups / sizeof groups[0]; gi++) {
        const group *g = &groups[gi];
        const char *path = write_net(g->name, group_netlist(g));
        tl_voice v;
        if (tl_voice_build(path, 0, &v) != 0)
            fail_msg("%s: the voice could not be built", g->name);
        assert_int_equal(v.cls->n_inputs, g->n);
        double M[3][3];
        for (int a = 0; a < g->n; a++)
            for (int b = 0; b < g->n; b++)
                M[a][b] = a == b ? g->L[a] : (a < b ? g->k[a][b] : g->k[b][a]) * sqrt(g->L[a] * g->L[b]);
        double **in = tl_bufs_new(3, n), **out = tl_bufs_new(3, n);
        assert_non_null(in);
        assert_non_null(out);
        tl_rng r;
        tl_rng_seed(&r, 0x6b00u + gi);
        for (int w = 0; w < g->n; w++) { /* a smooth random current: held noise, filtered */
            double y = 0, hold = 0;
            for (long k = 0; k < n; k++) {
                if (k % 16 == 0)
                    hold = 0.01 * tl_rng_signed(&r);
                y += 0.05 * (hold - y);
                in[w][k] = y;
            }
        }
        void *st = tl_state_new(v.cls, fs);
        assert_non_null(st);
        const double *ip[3] = {in[0], in[1], in[2]};
        double *op[3] = {out[0], out[1], out[2]};
        v.cls->process(st, ip, op, (int)n);
        double worst = 0, peak = 0;
        for (long k = 0; k < n; k++)
            for (int a = 0; a < g->n; a++) {
                double want = 0, vp = k ? out[a][k - 1] : 0;
                for (int b = 0; b < g->n; b++)
                    want += 2 / T * M[a][b] * (in[b][k] - (k ? in[b][k - 1] : 0));
                worst = fmax(worst, fabs(out[a][k] + vp - want));
                peak = fmax(peak, fabs(out[a][k]));
            }
        print_message("%-9s %d windings: worst |v[n] + v[n-1] - (2/T) L di| %.3g of peak %.3g V (%.1f dB)\n",
                      g->name, g->n, worst, peak, 20 * log10(worst / peak));
        assert_true(peak > 1e-3);
        if (!(worst <= 1e-11 * peak))
            fail_msg("%s: the voice's inductance matrix is not the coupled one", g->name);
        tl_state_free(st);
        tl_bufs_free(in, 3);
        tl_bufs_free(out, 3);
        tl_voice_free(&v);
    }
}

/* ---- refsim ---- */

typedef struct net {
    const char *name;
    const char *text;
} net;

static const net nets[] = {
    {"xfmr",
     ".input in\nV1 x 0 in R=100\nL1 x 0 10m\nL2 b 0 40m\nK1 L1 L2 0.99\nRL b 0 1k\nC1 b 0 10n\n"
     ".output b v(b)\n.output i i(L1)\n"},
    {"xf3",
     ".input in\nV1 x 0 in R=50\nL1 x 0 10m\nL2 a c 2.5m\nL3 c b 3m\nK1 L1 L2 -0.72\nK2 L3 L1 0.855\nK3 L2 L3 -0.76\n"
     "Ra a 0 1k\nRc c 0 10\nRb b 0 2.2k\nCb b 0 47n\n.output a v(a)\n.output b v(b)\n.output i i(L3)\n"},
    {"xf_rect",
     ".input in\nV1 x 0 in R=10\nL1 x 0 100m\nL2 s t 25m\nK1 L1 L2 0.98\nRt t 0 1meg\n"
     ".model dr diode Is=7n n=1.8\nD1 s p dr\nD2 t p dr\nD3 0 s dr\nD4 0 t dr\nC1 p 0 10u\nRL p 0 1k\n"
     ".output p v(p)\n.output s v(s,t)\n"},
};
#define NNETS ((int)(sizeof nets / sizeof nets[0]))

static const struct {
    const char *name;
    tl_drive_kind kind;
} drives[] = {{"sine", TL_DRIVE_SINE}, {"noise", TL_DRIVE_NOISE}, {"steps", TL_DRIVE_STEPS}};
#define NDRIVES ((int)(sizeof drives / sizeof drives[0]))

/* The voice and refsim over x (and refsim with its state rounded to the
 * voice's precision): the worst output's relative RMS error and the
 * floor's, in dB. */
static void run_pair(const Circuit *c, const wdv_class *cls, double fs, const double *x, long n, double *db,
                     double *floor_db) {
    tl_run_opts o = {0};
    o.fs = fs;
    o.nframes = n;
    o.input = &x;
    o.with_floor = cls->precision;
    tl_run r;
    assert_int_equal(tl_run_side_by_side(c, cls, &o, &r), 0);
    assert_true(r.have_ref);
    *db = tl_db(tl_run_worst(&r, NULL));
    *floor_db = tl_db(tl_run_floor(&r));
    tl_run_free(&r);
}

static void test_against_refsim(void **state) {
    (void)state;
    int failed = 0;
    print_message("%-8s %-6s %7s %10s %10s %10s\n", "network", "drive", "rate", "double dB", "float dB", "floor dB");
    for (int t = 0; t < NNETS; t++) {
        const char *path = write_net(nets[t].name, nets[t].text);
        tl_voice vd, vf;
        Circuit *c = tl_load_both(path, nets[t].name, &vd, &vf);
        static const double rates[] = {48000.0, 192000.0};
        for (int ri = 0; ri < 2; ri++)
            for (int d = 0; d < NDRIVES; d++) {
                double fs = rates[ri], db, dbf, fl, fl64;
                long n = (long)(0.03 * fs);
                double *x = malloc(sizeof(double) * (size_t)n);
                assert_non_null(x);
                tl_drive(drives[d].kind, 5, 8, fs, n, 0x6b6bu + (uint64_t)(t * 16 + d), x);
                run_pair(c, vd.cls, fs, x, n, &db, &fl64);
                run_pair(c, vf.cls, fs, x, n, &dbf, &fl);
                free(x);
                double ftol = fmax(TOL_FLOAT_DB, fl + 20 * log10(FLOAT_FACTOR));
                bool bad = !(db <= TOL_DOUBLE_DB) || !(dbf <= ftol);
                print_message("%-8s %-6s %7.0f %10.1f %10.1f %10.1f%s\n", nets[t].name, drives[d].name, fs, db, dbf,
                              fl, bad ? "  FAILED" : "");
                failed |= bad;
            }
        tl_voice_free(&vd);
        tl_voice_free(&vf);
    }
    if (failed)
        fail_msg("a voice with coupled inductors is off refsim");
}

/* ---- ngspice ---- */

#define CSV_PATH "tests/ref/coupled_tran.csv"
#define FS_REF 48000.0
#define MAXVEC 3
#define MAXREF 241 /* 5 ms at 48 kHz */
#define MIN_RATIO 12.0

typedef struct deck {
    const char *name;
    int nvec;
    double seconds;
    double bound48[MAXVEC], bound192[MAXVEC]; /* dB */
} deck;

static const deck decks[] = {
    {"xfmr_ct", 3, 0.005, {-60.5, -60.5, -61}, {-85, -85, -85.5}},
    {"xfmr_neg", 2, 0.005, {-51.5, -46}, {-75.5, -70}},
};
#define NDECKS ((int)(sizeof decks / sizeof decks[0]))

static void test_against_ngspice(void **state) {
    (void)state;
    tl_tran ref[NDECKS];
    for (int d = 0; d < NDECKS; d++)
        ref[d] = (tl_tran){.name = decks[d].name, .nvec = decks[d].nvec};
    assert_int_equal(tl_tran_read(CSV_PATH, "sh tests/ref/coupled_ngspice.sh", FS_REF, ref, NDECKS), 0);
    if (!dir[0])
        assert_int_equal(tl_temp_dir(dir, "coupled"), 0);
    double **y48 = tl_bufs_new(MAXVEC, MAXREF), **y192 = tl_bufs_new(MAXVEC, MAXREF);
    assert_non_null(y48);
    assert_non_null(y192);
    int failed = 0;
    for (int d = 0; d < NDECKS; d++) {
        const deck *dk = &decks[d];
        long nref = ref[d].n;
        char path[128];
        snprintf(path, sizeof path, "tests/nets/%s.cir", dk->name);
        assert_int_equal(nref, lround(dk->seconds * FS_REF) + 1);
        assert_int_equal(tl_render_deck(path, dir, FS_REF, 1, dk->seconds, dk->nvec, y48, nref), 0);
        assert_int_equal(tl_render_deck(path, dir, FS_REF, 4, dk->seconds, dk->nvec, y192, nref), 0);
        for (int k = 0; k < dk->nvec; k++) {
            double e48 = rel_rms_error(y48[k], ref[d].v[k], nref), e192 = rel_rms_error(y192[k], ref[d].v[k], nref);
            bool bad = !(tl_db(e48) < dk->bound48[k]) || !(tl_db(e192) < dk->bound192[k]) || !(e48 / e192 >= MIN_RATIO);
            print_message("%-9s vector %d: 48 kHz %6.1f dB (bound %5.1f), 192 kHz %6.1f dB (bound %5.1f), ratio %5.2f "
                          "(second order: 16; asserted >= %g)%s\n",
                          dk->name, k, tl_db(e48), dk->bound48[k], tl_db(e192), dk->bound192[k], e48 / e192,
                          MIN_RATIO, bad ? "  FAILED" : "");
            failed |= bad;
        }
    }
    tl_bufs_free(y48, MAXVEC);
    tl_bufs_free(y192, MAXVEC);
    tl_tran_free(ref, NDECKS);
    if (failed)
        fail_msg("a deck with coupled inductors is off ngspice");
}

/* ---- diagnostics ---- */

static void expect_error(const char *text, const char *want) {
    char *got = tl_first_report(text, SOLVER_DEFAULT);
    assert_non_null(got);
    if (strcmp(got, want))
        fail_msg("for\n%s\nwanted: %s\ngot:    %s", text, want, got);
    free(got);
}

#define SRC ".input in\nV1 x 0 in R=10\n"

static void test_diagnostics(void **state) {
    (void)state;
    expect_error(SRC "L1 x 0 1m\nK1 L1 L9 0.9\nR2 x 0 1k\n",
                 "t.wdn:4:7: error: coupling 'K1' names 'L9', which is not an element of the netlist");
    expect_error(SRC "L1 x 0 1m\nR2 x 0 1k\nK1 L1 R2 0.9\n",
                 "t.wdn:5:7: error: coupling 'K1' names 'R2', which is a resistor, not an inductor");
    expect_error(SRC "L1 x 0 1m\nK1 L1 L1 0.9\nR2 x 0 1k\n",
                 "t.wdn:4:7: error: coupling 'K1' couples 'L1' with itself");
    expect_error(SRC "L1 x 0 1m\nL2 y 0 1m\nR2 y 0 1k\nK1 L1 L2 1.5\n",
                 "t.wdn:6:10: error: coupling 'K1' has coefficient 1.5: it must lie in [-1, 1] and not be 0");
    expect_error(SRC "L1 x 0 1m\nL2 y 0 1m\nR2 y 0 1k\nK1 L1 L2 0\n",
                 "t.wdn:6:10: error: coupling 'K1' has coefficient 0: it must lie in [-1, 1] and not be 0");
    expect_error(SRC ".param k 0.9\nL1 x 0 1m\nL2 y 0 1m\nR2 y 0 1k\nK1 L1 L2 {k}\n",
                 "t.wdn:7:11: error: the coefficient of coupling 'K1' must be a number (params are not known at "
                 "compile time)");
    expect_error(SRC ".param l 1m\nL1 x 0 {l}\nL2 y 0 1m\nR2 y 0 1k\nK1 L1 L2 0.9\n",
                 "t.wdn:7:4: error: coupled inductor 'L1' must have a constant inductance, not one that depends on "
                 "a param");
    expect_error(SRC "L1 x 0 1m\nL2 y 0 1m\nR2 y 0 1k\nK1 L1 1m 0.9\n",
                 "t.wdn:6:7: error: coupling 'K1' takes inductors' names, then one coefficient: '1m' is not an "
                 "inductor's name");
    expect_error(SRC "L1 x 0 1m\nL2 y 0 1m\nR2 y 0 1k\nK1 L1 0.9\n",
                 "t.wdn:6:4: error: coupling 'K1' needs the names of two inductors before its coefficient");
    expect_error(SRC "L1 x 0 1m\nL2 y 0 1m\nR2 y 0 1k\nK1 L1 L2\n",
                 "t.wdn:6:9: error: coupling 'K1' needs a coefficient after its inductors' names");
    expect_error(SRC "L1 x 0 1m\nL2 y 0 1m\nR2 y 0 1k\nK1 L1 L2 0.9\nK2 L2 L1 0.8\n",
                 "t.wdn:7:1: error: coupling 'K2' couples 'L2' and 'L1' again (after 'K1')");
    expect_error(SRC "L1 x 0 1m\nL2 y 0 1m\nL3 z 0 1m\nR2 y 0 1k\nR3 z 0 1k\nK1 L1 L2 0.9\nK2 L1 L3 0.9\n",
                 "t.wdn:8:1: error: 'L2' and 'L3' are coupled through others but no K line couples them: the "
                 "windings of one core need a coupling for each pair");
    expect_error(SRC "L1 x 0 1m\nL2 y 0 1m\nL3 z 0 1m\nR2 y 0 1k\nR3 z 0 1k\nK1 L1 L2 0.9\nK2 L1 L3 0.9\n"
                     "K3 L2 L3 -0.81\n",
                 "t.wdn:10:10: error: coupling 'K3' gives -0.81 where the group's other couplings give 0.81: the "
                 "couplings are not those of windings on one core (k_ij = c_i c_j)");
    expect_error(SRC "L1 x 0 1m\nL2 y 0 1m\nL3 z 0 1m\nR2 y 0 1k\nR3 z 0 1k\nK1 L1 L2 0.9\nK2 L1 L3 0.9\n"
                     "K3 L2 L3 0.5\n",
                 "t.wdn:8:1: error: the couplings of 'L1' with the other windings would need it coupled more than "
                 "perfectly (1.27279): they are not those of one core");
    expect_error(SRC "L1 x 0 1m\nL2 y 0 4m\nR2 y 0 1k\nK1 L1 L2 1\n.output i i(L2)\n",
                 "t.wdn:7:13: error: 'L2' is coupled perfectly (|k| = 1): no element carries its current alone, so "
                 "i(L2) cannot be read");
    expect_error(SRC "L1 x 0 1m\nL2 y 0 4m\nR2 y 0 1k\nK1 L1 L2 -1\n.output i i(L1)\n",
                 "t.wdn:7:13: error: 'L1' is coupled perfectly (|k| = 1): no element carries its current alone, so "
                 "i(L1) cannot be read");
    expect_error(SRC "L1 x 0 1m IC=1m\nL2 y 0 1m\nR2 y 0 1k\nK1 L1 L2 1\n",
                 "t.wdn:3:1: error: 'L1' is coupled perfectly (|k| = 1): no element carries its current alone, so "
                 "it cannot take an initial current");
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_inductance_identity),
        cmocka_unit_test(test_against_refsim),
        cmocka_unit_test(test_against_ngspice),
        cmocka_unit_test(test_diagnostics),
    };
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    if (dir[0])
        tl_remove_dir(dir);
    return rc;
}
