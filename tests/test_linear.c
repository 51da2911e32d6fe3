/*
 * test_linear.c - every example netlist, compiled to a voice, matches the
 * trapezoidal-rule nodal simulation of the same network (refsim) sample
 * for sample.
 *
 * Netlists with nonlinear elements are skipped (and say so).
 *
 * Each input is driven by seeded white noise and, in a second run, by a
 * unit step, for one second at 44.1, 48 and 96 kHz, with every param
 * moved to random values in its range three times during the run.  Every
 * output's relative RMS error against the reference is measured.
 *
 * The reference computes in extended precision, so the error is the
 * voice's own.  A correct voice still differs by the rounding of its
 * arithmetic, accumulated through the recursion and amplified where the
 * network is ill-conditioned: slow resonances, and above all x() probes,
 * which integrate velocity and so add up rounding like a random walk.
 * How much that is on a given run is measured, not guessed: the same
 * reference is run again with its state and coefficients rounded to the
 * voice's precision after every step (refsim_round_state), and its error
 * is the "floor" of that run.  An output passes if its error is below
 * the fixed tolerance (1e-12 for double voices, 1e-4 for float voices:
 * single-precision rounding, ~6e-8 per operation) or below FLOOR_FACTOR
 * times the floor; on these networks the floor alone reaches 1e-11
 * (double) and 7e-3 (float), and a correct voice lands within a few times
 * of it, while a wrong structure, coefficient or update shows errors many
 * orders of magnitude above it.  The summary lines count the runs above
 * the fixed tolerance and the runs that failed.
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

#define TOL_DOUBLE 1e-12
#define TOL_FLOAT 1e-4
#define FLOOR_FACTOR 20.0
#define SECONDS 1.0
#define NCHANGES 3

static const double rates[] = {48000.0, 44100.0, 96000.0};

/* What one precision's runs came to. */
typedef struct tally {
    double worst;     /* largest error */
    double floor;     /* largest floor */
    double ratio;     /* largest error / floor */
    int above;        /* runs with an error above the fixed tolerance */
    int failed;       /* runs above both the tolerance and the floor rule */
    int runs;
} tally;

/* One run of one voice against refsim; fails the test (after reporting
 * every output) if an output's error exceeds both tol and FLOOR_FACTOR
 * times the floor of the run. */
static void run_case(const Circuit *c, const wdv_class *cls, double fs,
                     tl_sigkind sig, uint64_t seed, double tol, int bits,
                     tally *t, int *failed) {
    const char *label = bits == 32 ? "float" : "double";
    const char *signame = sig == TL_STEP ? "step" : "noise";
    tl_rng r;
    tl_rng_seed(&r, seed);
    long N = (long)(fs * SECONDS);
    tl_change *ch = calloc((size_t)(NCHANGES * c->nparams) + 1, sizeof *ch);
    assert_non_null(ch);
    int nch = tl_random_changes(c, &r, N, NCHANGES, ch);
    tl_signal s;
    tl_signal_init(&s, sig, 1.0, 0, seed ^ 0x5eedull);
    tl_run_opts o = {0};
    o.fs = fs;
    o.nframes = N;
    o.signal = &s;
    o.changes = ch;
    o.nchanges = nch;
    o.with_floor = bits;
    tl_run run;
    int rc = tl_run_side_by_side(c, cls, &o, &run);
    if (rc != 0)
        free(ch);
    assert_int_equal(rc, 0);
    int which = 0;
    double worst = tl_run_worst(&run, &which);
    double fl = tl_run_floor(&run);
    double allowed = fmax(tol, FLOOR_FACTOR * fl);
    t->runs++;
    if (!(worst <= t->worst))
        t->worst = worst;
    if (fl > t->floor)
        t->floor = fl;
    if (fl > 0.0 && worst / fl > t->ratio)
        t->ratio = worst / fl;
    if (getenv("WDC_TEST_VERBOSE"))
        print_message("  %s %s %s %g Hz: error %.3g, floor %.3g\n", c->name, label,
                      signame, fs, worst, fl);
    if (!(worst < tol))
        t->above++;
    if (!(worst < allowed)) {
        *failed = 1;
        t->failed++;
        print_message("%s: %s voice, %s, %g Hz: output %s relative RMS error %.3g "
                      "(%.1f dB) exceeds %.0e and %g x the floor %.3g\n",
                      c->name, label, signame, fs, c->outs[which].name, worst,
                      tl_db(worst), tol, FLOOR_FACTOR, fl);
        for (int k = 0; k < run.nouts; k++)
            tl_run_report(&run, c, k, allowed);
        for (int k = 0; k < nch; k++)
            print_message("  param %s set to %.17g at n=%ld\n",
                          c->params[ch[k].param].name, ch[k].value, ch[k].at);
    }
    free(ch);
    tl_run_free(&run);
}

static void test_netlist(void **state) {
    const char *path = *state;
    Circuit *c = wdc_load(path);
    assert_non_null(c);
    bool linear = refsim_can_simulate(c);
    for (int i = 0; i < c->nelems; i++)
        linear = linear && c->elems[i].kind != E_NL;
    if (!linear) {
        print_message("%s: not a linear network the reference simulates (nonlinear elements are compared "
                      "in test_nonlinear): not compared here\n",
                      path);
        skip();
    }
    tl_voice vd, vf;
    int okd = tl_voice_build(path, 0, &vd);
    int okf = tl_voice_build(path, 1, &vf);
    if (okd != 0 || okf != 0) {
        tl_voice_free(&vd);
        tl_voice_free(&vf);
        fail_msg("%s: the voice could not be built", path);
    }
    tally td = {0}, tf = {0};
    int failed = 0;
    uint64_t seed = tl_hash_str(path);
    for (size_t ri = 0; ri < sizeof rates / sizeof rates[0]; ri++)
        for (int si = 0; si < 2; si++) {
            tl_sigkind sig = si ? TL_STEP : TL_NOISE;
            uint64_t sd = seed + 17 * ri + (uint64_t)si;
            run_case(c, vd.cls, rates[ri], sig, sd, TOL_DOUBLE, 64, &td, &failed);
            run_case(c, vf.cls, rates[ri], sig, sd, TOL_FLOAT, 32, &tf, &failed);
        }
    print_message("%-12s double: worst relative RMS error %.3g (%.1f dB), floor "
                  "%.3g, at most %.3g x the floor; of %d runs %d above %.0e, %d "
                  "failed\n",
                  c->name, td.worst, tl_db(td.worst), td.floor, td.ratio, td.runs,
                  td.above, TOL_DOUBLE, td.failed);
    print_message("%-12s float:  worst relative RMS error %.3g (%.1f dB), floor "
                  "%.3g, at most %.3g x the floor; of %d runs %d above %.0e, %d "
                  "failed\n",
                  c->name, tf.worst, tl_db(tf.worst), tf.floor, tf.ratio, tf.runs,
                  tf.above, TOL_FLOAT, tf.failed);
    tl_voice_free(&vd);
    tl_voice_free(&vf);
    if (failed)
        fail_msg("%s: the voice does not match the reference", path);
}

int main(void) { return tl_run_per_netlist("linear", test_netlist, NULL, 0); }
