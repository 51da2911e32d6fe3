/*
 * test_energy.c - passivity and energy bookkeeping of every example voice.
 *
 * (a) After a 0.1 s noise burst the inputs fall silent; from then on the
 *     stored energy never rises from one sample to the next.
 * (b) Under random inputs for 1 s, the stored energy never exceeds the
 *     initial energy plus the work the sources have done.
 * (c) The voice's energy() and work() agree with the reference simulator's
 *     at every sample, also across param changes.
 * A netlist with nonzero initial conditions starts with nonzero energy,
 * equal to the reference's.  Netlists with nonlinear elements have no
 * reference: (a) and (b) still apply to them, (c) does not.
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

#define FS 48000.0
#define BURST 0.1
#define TOL_DECAY 1e-12   /* relative to the peak energy */
#define TOL_BOUND 1e-9    /* relative to the peak energy */
#define TOL_AGREE 1e-9    /* relative to the peak energy or work */

/* Whether some source has a constant nonzero drive (such a network is not
 * silent when its inputs are). */
static int has_constant_drive(const Circuit *c) {
    double *p = circuit_defaults(c);
    for (int e = 0; e < c->nelems; e++) {
        const Elem *el = &c->elems[e];
        if ((el->kind == E_V || el->kind == E_I) && el->input < 0 &&
            elem_drive(c, el, p) != 0.0)
            return 1;
    }
    return 0;
}

static int has_initial_conditions(const Circuit *c) {
    double *p = circuit_defaults(c);
    for (int e = 0; e < c->nelems; e++)
        if (c->elems[e].ic && expr_eval(c->elems[e].ic, p) != 0.0)
            return 1;
    return 0;
}

static double peak_of(const double *x, long n, double x0) {
    double m = fabs(x0);
    for (long k = 0; k < n; k++)
        if (fabs(x[k]) > m)
            m = fabs(x[k]);
    return m;
}

/* (c) on a finished run; returns the worst deviation relative to scale. */
static double check_agreement(const Circuit *c, const tl_run *r, const char *what,
                              int *failed) {
    long N = r->nframes;
    double scale = peak_of(r->renergy, N, r->renergy0);
    double wp = peak_of(r->rwork, N, 0.0);
    if (wp > scale)
        scale = wp;
    if (scale == 0.0)
        scale = 1.0;
    double worst = fabs(r->venergy0 - r->renergy0) / scale;
    long at = -1;
    const char *which = "energy";
    double wv = r->venergy0, wr = r->renergy0;
    if (fabs(r->vwork0) / scale > worst) {
        worst = fabs(r->vwork0) / scale;
        which = "work";
        wv = r->vwork0;
        wr = 0.0;
    }
    for (long n = 0; n < N; n++) {
        double de = fabs(r->venergy[n] - r->renergy[n]) / scale;
        double dw = fabs(r->vwork[n] - r->rwork[n]) / scale;
        if (de > worst) {
            worst = de;
            at = n;
            which = "energy";
            wv = r->venergy[n];
            wr = r->renergy[n];
        }
        if (dw > worst) {
            worst = dw;
            at = n;
            which = "work";
            wv = r->vwork[n];
            wr = r->rwork[n];
        }
    }
    if (!(worst <= TOL_AGREE)) {
        *failed = 1;
        long first = -1;
        for (long n = 0; n < N && first < 0; n++)
            if (!(fabs(r->venergy[n] - r->renergy[n]) <= TOL_AGREE * scale &&
                  fabs(r->vwork[n] - r->rwork[n]) <= TOL_AGREE * scale))
                first = n;
        print_message("%s (%s): voice %s %.17g, reference %.17g at n=%ld: off by "
                      "%.3g of the peak (limit %.0e)\n",
                      c->name, what, which, wv, wr, at, worst, TOL_AGREE);
        if (first >= 0)
            print_message("  first sample off: n=%ld, energy %.17g vs %.17g, work "
                          "%.17g vs %.17g\n",
                          first, r->venergy[first], r->renergy[first], r->vwork[first],
                          r->rwork[first]);
    }
    return worst;
}

static int run(const Circuit *c, const wdv_class *cls, tl_sigkind kind, long at,
               uint64_t seed, const tl_change *ch, int nch, tl_run *r) {
    tl_signal s;
    tl_signal_init(&s, kind, 1.0, at, seed);
    tl_run_opts o = {0};
    o.fs = FS;
    o.nframes = (long)FS;
    o.signal = &s;
    o.changes = ch;
    o.nchanges = nch;
    o.track_energy = 1;
    return tl_run_side_by_side(c, cls, &o, r);
}

static void test_netlist(void **state) {
    const char *path = *state;
    Circuit *c = wdc_load(path);
    assert_non_null(c);
    tl_voice v;
    if (tl_voice_build_args(path, 0, tl_energy, NULL, &v) != 0) {
        tl_voice_free(&v);
        fail_msg("%s: the voice could not be built", path);
    }
    uint64_t seed = tl_hash_str(path);
    int failed = 0;
    double agree = 0.0, a;
    tl_run r;

    /* (a) decay after a burst */
    long burst = (long)(BURST * FS);
    assert_int_equal(run(c, v.cls, TL_BURST, burst, seed, NULL, 0, &r), 0);
    long N = r.nframes;
    double peak = peak_of(r.venergy, N, r.venergy0);
    double worst_rise = 0.0;
    long rise_at = -1;
    if (has_constant_drive(c)) {
        print_message("%s: a source has a constant drive; (a) skipped\n", c->name);
    } else {
        /* samples n-1 and n both silent: n - 1 >= burst */
        for (long n = burst + 1; n < N; n++) {
            double rise = r.venergy[n] - r.venergy[n - 1];
            if (rise > worst_rise)
                worst_rise = rise;
            if (!(rise <= TOL_DECAY * peak + 1e-300) && rise_at < 0)
                rise_at = n;
        }
        if (rise_at >= 0) {
            failed = 1;
            print_message("%s: energy rises while silent: n=%ld: %.17g -> %.17g "
                          "(peak %.3g)\n",
                          c->name, rise_at, r.venergy[rise_at - 1], r.venergy[rise_at],
                          peak);
            if (r.have_ref)
                print_message("  reference: %.17g -> %.17g\n", r.renergy[rise_at - 1],
                              r.renergy[rise_at]);
        }
    }
    if (has_initial_conditions(c)) {
        if (!(r.venergy0 > 0.0)) {
            failed = 1;
            print_message("%s: has initial conditions but starts with energy %.17g\n",
                          c->name, r.venergy0);
        }
    }
    if (r.have_ref) {
        a = check_agreement(c, &r, "burst", &failed);
        if (a > agree)
            agree = a;
    }
    double worst_rise_rel = peak > 0.0 ? worst_rise / peak : 0.0;
    tl_run_free(&r);

    /* (b) energy bounded by work under noise */
    assert_int_equal(run(c, v.cls, TL_NOISE, 0, seed + 1, NULL, 0, &r), 0);
    N = r.nframes;
    peak = peak_of(r.venergy, N, r.venergy0);
    double worst_excess = -INFINITY;
    long excess_at = -1;
    for (long n = 0; n < N; n++) {
        double ex = r.venergy[n] - (r.vwork[n] + r.venergy0);
        if (ex > worst_excess)
            worst_excess = ex;
        if (!(ex <= TOL_BOUND * peak) && excess_at < 0)
            excess_at = n;
    }
    if (excess_at >= 0) {
        failed = 1;
        print_message("%s: energy exceeds initial energy plus work: n=%ld: energy "
                      "%.17g, work %.17g, initial %.17g (peak %.3g)\n",
                      c->name, excess_at, r.venergy[excess_at], r.vwork[excess_at],
                      r.venergy0, peak);
    }
    if (r.have_ref) {
        a = check_agreement(c, &r, "noise", &failed);
        if (a > agree)
            agree = a;
    }
    double excess_rel = peak > 0.0 ? worst_excess / peak : 0.0;
    tl_run_free(&r);

    /* (c) also across param changes */
    if (c->nparams > 0 && refsim_can_simulate(c)) {
        tl_rng rng;
        tl_rng_seed(&rng, seed + 2);
        tl_change *ch = calloc((size_t)(3 * c->nparams) + 1, sizeof *ch);
        assert_non_null(ch);
        int nch = tl_random_changes(c, &rng, (long)FS, 3, ch);
        int rc = run(c, v.cls, TL_NOISE, 0, seed + 3, ch, nch, &r);
        free(ch);
        assert_int_equal(rc, 0);
        a = check_agreement(c, &r, "noise, param changes", &failed);
        if (a > agree)
            agree = a;
        tl_run_free(&r);
    }

    if (refsim_can_simulate(c))
        print_message("%-12s largest rise while silent %.3g, largest (E - W - E0) "
                      "%.3g of the peak energy; energy/work vs reference %.3g\n",
                      c->name, worst_rise_rel, excess_rel, agree);
    else
        print_message("%-12s largest rise while silent %.3g, largest (E - W - E0) "
                      "%.3g of the peak energy; nonlinear: no reference\n",
                      c->name, worst_rise_rel, excess_rel);
    tl_voice_free(&v);
    if (failed)
        fail_msg("%s: energy check failed", path);
}

int main(void) { return tl_run_per_netlist("energy", test_netlist, NULL, 0); }
