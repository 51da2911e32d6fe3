/*
 * test_joint_spice.c - the example decks in netlists/ against
 * ngspice's transient.
 *
 * tests/ref/joint_tran.csv (tests/ref/joint_ngspice.sh makes it) holds
 * ngspice's transient of netlists/clipper_asym.cir (v(out), and v(mid)
 * between its two diodes in series), of netlists/tubescreamer.cir
 * (v(out), and v(n) at the op-amp's inverting input) and of
 * netlists/fuzzface.cir (v(out), and v(c2) at Q2's collector) and of
 * netlists/bigmuff.cir (v(out), and v(c) at its collector) and of
 * netlists/bridge.cir (v(o), the ripple taken off the rail, and v(p), the
 * rail) and of netlists/clipper_sym.cir (v(out); its diode pair has one
 * closed form, and ngspice runs its model with IS and N only, the keys the
 * voice takes) over 20 ms from each deck's DC operating point (rest for the
 * clippers and the bridge, whose reservoir then charges), sampled
 * at t = m/48000 s, with a 10 ns maximum step (its own error, which the
 * script prints, is below 4e-10 V for the clipper, 1.2e-8 V for the Tube
 * Screamer, whose 51 pF feedback ngspice steps less finely, 8.7e-7 V on
 * the Fuzz Face's 6 V swings, 1.5e-9 V for the Big Muff stage and 2e-9 V
 * for the bridge).
 *
 * The deck is read by bin/wdc as written (with a .print naming those
 * vectors) and rendered with its own sine source at 48 kHz and 192 kHz;
 * its samples at t = m/48000 are compared with the data, vector by
 * vector, as a relative RMS error in dB.
 *
 * What the method predicts.  The voice is the trapezoidal rule with its
 * diodes solved exactly at each step, so its error is second order in the
 * step: four times the rate should divide it by about 16 once the step is
 * short against what happens in the waveform (the knees where the output
 * enters and leaves clipping, and the R1 C1 mode the sine's start
 * excites).
 *
 * The Tube Screamer's feedback (51 pF across 301 kOhm) has its pole at
 * 10.4 kHz, where a 48 kHz step is not short (omega T = 1.4): its error
 * falls 3.2, 3.5, 3.9 and 4.0 times from one doubling of the rate to the
 * next between 48 and 768 kHz, so its ratio is taken from 96 to 384 kHz.
 *
 * Measured (ngspice 39), relative RMS error:
 *
 *     deck          vector   48 kHz     192 kHz    ratio
 *     clipper_asym  v(out)   -78.6 dB   -103.3 dB  17.2 (48 to 192 kHz)
 *     clipper_asym  v(mid)   -78.6 dB   -103.3 dB  17.2
 *     tubescreamer  v(out)   -52.3 dB    -73.2 dB  13.4 (96 to 384 kHz)
 *     tubescreamer  v(n)    -165.4 dB   -186.3 dB  13.4
 *     fuzzface      v(out)   -55.9 dB    -86.6 dB  34.5 (48 to 192 kHz)
 *     fuzzface      v(c2)    -61.0 dB    -92.9 dB  39.4
 *     bigmuff       v(out)   -60.6 dB    -84.7 dB  16.0
 *     bigmuff       v(c)     -66.4 dB    -90.5 dB  16.0
 *     bridge        v(o)    -103.9 dB   -128.0 dB  16.0
 *     bridge        v(p)    -109.3 dB   -133.4 dB  16.0
 *     clipper_sym   v(out)   -74.4 dB    -99.0 dB  17.1
 *
 * (The Fuzz Face's error falls 9.2, then 3.7 times from 48 to 96 to 192
 * kHz; past that ngspice's own error, about -95 dB, is as large.  Its
 * first sample, the operating point the compiler found, is v(c2) =
 * 3.2859302 V against ngspice's 3.2859314 V; the Big Muff stage's v(c)
 * 0.8798188 V against 0.8798200 V, and its error falls 4.0 times a
 * doubling from 48 to 384 kHz.)
 *
 * (v(n) follows v(in) within v(out) / 1e6, the E's open-loop gain.)
 *
 * (v(mid) is half of v(out) here, both diodes in series having one law:
 * the joint solve splits their voltage evenly, as ngspice does.)
 *
 * Asserted, with about 3 dB of margin: each vector below its bound at 48
 * and 192 kHz, and the error falling at least 12 times over a fourfold
 * rate (second order: 16).
 *
 * Run from the repository root: build/tests/test_joint_spice (after make).
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testlib.h"

#define CSV_PATH "tests/ref/joint_tran.csv"
#define FS_REF 48000.0
#define MAXVEC 2
#define MAXREF 961 /* 20 ms at 48 kHz */
#define MIN_RATIO 12.0

typedef struct deck {
    const char *name;
    const char *vectors; /* the .print line's vectors, as the CSV's columns */
    int nvec;
    double seconds;
    double bound48[MAXVEC], bound192[MAXVEC]; /* dB */
    /* the rates (times 48 kHz) the convergence ratio is taken between:
     * four times apart, where the step is short against the waveform */
    int conv[2];
} deck;

static const deck decks[] = {
    {"clipper_asym", "v(out) v(mid)", 2, 0.02, {-75.5, -75.5}, {-100, -100}, {1, 4}},
    {"tubescreamer", "v(out) v(n)", 2, 0.02, {-49.5, -162.5}, {-70.5, -183.5}, {2, 8}},
    {"fuzzface", "v(out) v(c2)", 2, 0.02, {-53, -58}, {-83.5, -90}, {1, 4}},
    {"bigmuff", "v(out) v(c)", 2, 0.02, {-57.5, -63.5}, {-81.5, -87.5}, {1, 4}},
    {"bridge", "v(o) v(p)", 2, 0.02, {-101, -106.5}, {-125, -130.5}, {1, 4}},
    {"clipper_sym", "v(out)", 1, 0.02, {-71.5}, {-96}, {1, 4}},
};
#define NDECKS ((int)(sizeof decks / sizeof decks[0]))

static tl_tran ref[NDECKS];

static int setup(void **st) {
    (void)st;
    for (int d = 0; d < NDECKS; d++)
        ref[d] = (tl_tran){.name = decks[d].name, .nvec = decks[d].nvec};
    if (tl_tran_read(CSV_PATH, "sh tests/ref/joint_ngspice.sh", FS_REF, ref, NDECKS) != 0)
        return -1;
    for (int d = 0; d < NDECKS; d++)
        if (ref[d].n != lround(decks[d].seconds * FS_REF) + 1) {
            fprintf(stderr, "%s: %ld rows for %s\n", CSV_PATH, ref[d].n, decks[d].name);
            tl_tran_free(ref, NDECKS);
            return -1;
        }
    return 0;
}

static int teardown(void **st) {
    (void)st;
    tl_tran_free(ref, NDECKS);
    return 0;
}

/* The deck netlists/NAME.cir with its IC= values, its .print lines and a
 * UIC left out, and a .print of the vectors, into dir/NAME.cir. */
static void write_variant(const char *dir, const deck *dk) {
    char path[256], line[1024];
    snprintf(path, sizeof path, "netlists/%s.cir", dk->name);
    FILE *f = fopen(path, "r");
    assert_non_null(f);
    size_t cap = 1 << 16, len = 0;
    char *text = malloc(cap);
    assert_non_null(text);
    text[0] = 0;
    while (fgets(line, sizeof line, f)) {
        if (!strncmp(line, ".print", 6) || !strncmp(line, ".end", 4))
            continue;
        char out[1024] = "", *save = NULL, *tok = strtok_r(line, " \n", &save);
        for (; tok; tok = strtok_r(NULL, " \n", &save))
            if (strncmp(tok, "IC=", 3) && strcmp(tok, "UIC")) {
                strcat(out, *out ? " " : "");
                strcat(out, tok);
            }
        len += (size_t)snprintf(text + len, cap - len, "%s\n", out);
    }
    fclose(f);
    snprintf(text + len, cap - len, ".print tran %s\n.end\n", dk->vectors);
    snprintf(path, sizeof path, "%s.cir", dk->name);
    tl_write_file(dir, path, text);
    free(text);
}

/* Renders the variant at fs = FS_REF * over; y[k][m]: vector k at
 * t = m / FS_REF. */
static void render(const char *dir, const deck *dk, int over, double **y, long nref) {
    char path[256];
    snprintf(path, sizeof path, "%s/%s.cir", dir, dk->name);
    assert_int_equal(tl_render_deck(path, dir, FS_REF, over, dk->seconds, dk->nvec, y, nref), 0);
}

/* Word k of s (space-separated) into buf. */
static const char *word(const char *s, int k, char buf[64]) {
    for (; k > 0 && s; k--)
        s = strchr(s, ' ') ? strchr(s, ' ') + 1 : NULL;
    snprintf(buf, 64, "%.*s", s ? (int)strcspn(s, " ") : 0, s ? s : "");
    return buf;
}

static void test_decks_vs_ngspice(void **st) {
    (void)st;
    double **y[4];
    for (int r = 0; r < 4; r++)
        assert_non_null(y[r] = tl_bufs_new(MAXVEC, MAXREF));
    char dir[64];
    assert_int_equal(tl_temp_dir(dir, "joint_spice"), 0);
    int failed = 0;
    for (int d = 0; d < NDECKS; d++) {
        const deck *dk = &decks[d];
        long nref = ref[d].n;
        write_variant(dir, dk);
        render(dir, dk, 1, y[0], nref);
        render(dir, dk, 4, y[1], nref);
        bool own = dk->conv[0] != 1 || dk->conv[1] != 4;
        if (own) {
            render(dir, dk, dk->conv[0], y[2], nref);
            render(dir, dk, dk->conv[1], y[3], nref);
        }
        for (int k = 0; k < dk->nvec; k++) {
            char name[64];
            double e48 = rel_rms_error(y[0][k], ref[d].v[k], nref), e192 = rel_rms_error(y[1][k], ref[d].v[k], nref);
            double ratio = own ? rel_rms_error(y[2][k], ref[d].v[k], nref) / rel_rms_error(y[3][k], ref[d].v[k], nref)
                               : e48 / e192;
            bool bad = !(tl_db(e48) < dk->bound48[k]) || !(tl_db(e192) < dk->bound192[k]) || !(ratio >= MIN_RATIO);
            print_message("%-13s %-7s 48 kHz %7.1f dB (bound %5.1f), 192 kHz %7.1f dB (bound %5.1f), ratio %6.2f "
                          "from %d to %d kHz (second order: 16; asserted >= %g)%s\n",
                          dk->name, word(dk->vectors, k, name), tl_db(e48), dk->bound48[k], tl_db(e192),
                          dk->bound192[k], ratio, 48 * dk->conv[0], 48 * dk->conv[1], MIN_RATIO, bad ? "  FAILED" : "");
            failed |= bad;
        }
    }
    tl_remove_dir(dir);
    for (int r = 0; r < 4; r++)
        tl_bufs_free(y[r], MAXVEC);
    if (failed)
        fail_msg("a deck is off ngspice");
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_decks_vs_ngspice),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
