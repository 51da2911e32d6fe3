/*
 * test_instruments.c - struck and plucked instruments as a host plays them.
 *
 *   - idle contacts change nothing: a string with a hammer resting far
 *     from it renders bit for bit what the string without the hammer
 *     renders, and striking the hammer does change it;
 *   - random param jumps on every example never raise the stored energy;
 *   - passivity under random play on every instrument (strikes of random
 *     speed at random times, random input bursts): between strikes the
 *     stored energy stays within the energy after the strike plus the
 *     work of the inputs, and it never rises while the inputs are silent,
 *     contacts that close and let go included;
 *   - run-time re-targeting of a dulcimer hammer: the string it was moved
 *     to sounds, and the wave of a strike reaches the bridge as much
 *     earlier as the point it was moved to is nearer the bridge.
 */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>

#include <complex.h>
#include <glob.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testlib.h"

static void run(const wdv_class *cls, void *st, double **in, double **out, int n) {
    cls->process(st, (const double *const *)in, out, n);
}

/* ---- idle contacts ---- */

static void test_idle_contacts(void **state) {
    (void)state;
    const char *nets[2] = {"tests/nets/idle_without.wdn", "tests/nets/idle_with.wdn"};
    const long n = 48000;
    double *y[3];
    for (int k = 0; k < 3; k++) {
        tl_voice v;
        assert_int_equal(tl_voice_build(nets[k ? 1 : 0], 0, &v), 0);
        void *st = tl_state_new(v.cls, 48000);
        if (k == 2) { /* the hammer thrown at the string */
            int ids[2] = {-1, -1};
            for (int i = 0; i < v.cls->n_ic_targets; i++) {
                if (!strcmp(v.cls->ic_targets[i].name, "v(hm)"))
                    ids[0] = i;
                if (!strcmp(v.cls->ic_targets[i].name, "x(hm)"))
                    ids[1] = i;
            }
            double vals[2] = {3, -1e-3};
            assert_int_equal(v.cls->set_ic(st, 2, ids, vals), 0);
        }
        tl_signal sig;
        tl_signal_init(&sig, TL_NOISE, 0.01, 0, 7);
        double **in = tl_bufs_new(1, 64), **out = tl_bufs_new(v.cls->n_outputs, 64);
        y[k] = malloc(sizeof(double) * (size_t)n);
        for (long i = 0; i < n; i += 64) {
            for (int j = 0; j < 64; j++)
                in[0][j] = tl_signal_next(&sig, 0, i + j);
            run(v.cls, st, in, out, 64);
            memcpy(y[k] + i, out[0], sizeof(double) * 64);
        }
        tl_bufs_free(in, 1);
        tl_bufs_free(out, v.cls->n_outputs);
        tl_state_free(st);
        tl_voice_free(&v);
    }
    long diff = 0, struck = 0;
    for (long i = 0; i < n; i++) {
        diff += memcmp(&y[0][i], &y[1][i], sizeof(double)) != 0;
        struck += y[0][i] != y[2][i];
    }
    printf("idle hammer: %ld of %ld samples differ from the string alone; struck: %ld differ\n", diff, n, struck);
    assert_int_equal(diff, 0);
    assert_true(struck > n / 2);
    for (int k = 0; k < 3; k++)
        free(y[k]);
}

/* ---- param jumps ---- */

static void test_param_jumps(void **state) {
    (void)state;
    glob_t g;
    assert_int_equal(glob("netlists/*.wdn", 0, NULL, &g), 0);
    glob("tests/nets/*.wdn", GLOB_APPEND, NULL, &g);
    tl_rng rng;
    tl_rng_seed(&rng, 2024);
    int tried = 0;
    for (size_t f = 0; f < g.gl_pathc; f++) {
        tl_voice v;
        assert_int_equal(tl_voice_build(g.gl_pathv[f], 0, &v), 0);
        const wdv_class *cls = v.cls;
        if (cls->n_params == 0) {
            tl_voice_free(&v);
            continue;
        }
        void *st = tl_state_new(cls, 48000);
        int ni = cls->n_inputs > 0 ? cls->n_inputs : 1;
        double **in = tl_bufs_new(ni, 256), **out = tl_bufs_new(cls->n_outputs, 256);
        double worst = 0;
        int jumps = 0;
        for (int it = 0; it < 60; it++) {
            for (int i = 0; i < cls->n_inputs; i++)
                for (int j = 0; j < 256; j++)
                    in[i][j] = it % 3 == 0 ? tl_rng_signed(&rng) : 0;
            run(cls, st, in, out, 256);
            double E0 = cls->energy(st);
            for (int m = 0; m < 1 + it % 3; m++) {
                int id = (int)(tl_rng_uniform(&rng) * cls->n_params);
                const wdv_param *p = &cls->params[id];
                double lo = p->min > -1e300 ? p->min : p->def - 10 * (fabs(p->def) + 1);
                double hi = p->max < 1e300 ? p->max : p->def + 10 * (fabs(p->def) + 1);
                double u = tl_rng_uniform(&rng);
                double x = lo > 0 && hi / lo > 100 ? lo * pow(hi / lo, u) : lo + (hi - lo) * u;
                cls->set_param(st, id, x);
            }
            run(cls, st, in, out, 0); /* the change takes effect */
            double E1 = cls->energy(st);
            jumps++;
            if (E0 > 0)
                worst = fmax(worst, (E1 - E0) / E0);
            if (!(E1 <= E0 * (1 + 1e-12) + 1e-300))
                fail_msg("%s: a param jump raised the stored energy from %.17g to %.17g", g.gl_pathv[f], E0, E1);
        }
        printf("%-32s %d jumps, largest relative change %+.3e\n", g.gl_pathv[f], jumps, worst);
        tried++;
        tl_bufs_free(in, ni);
        tl_bufs_free(out, cls->n_outputs);
        tl_state_free(st);
        tl_voice_free(&v);
    }
    globfree(&g);
    assert_true(tried >= 6);
}

/* ---- passivity under play ---- */

/* The instruments: examples with a string or tube. */
static int is_instrument(const Circuit *c) { return c->nwgs > 0; }

static void play(const char *path, long nsamples) {
    Circuit *c = wdc_load(path);
    assert_non_null(c);
    tl_voice v;
    assert_int_equal(tl_voice_build_args(path, 0, tl_energy, NULL, &v), 0);
    const wdv_class *cls = v.cls;
    /* strike targets: v() and x() of each contact's first node */
    int hv[16], hx[16], nh = 0;
    for (int i = 0; i < c->nelems && nh < 16; i++) {
        const Elem *e = &c->elems[i];
        if (e->kind != E_NL || e->nl->kind != NL_CONTACT)
            continue;
        char nv[160], nx[160];
        snprintf(nv, sizeof nv, "v(%s)", c->nodes[e->n[0]]);
        snprintf(nx, sizeof nx, "x(%s)", c->nodes[e->n[0]]);
        hv[nh] = hx[nh] = -1;
        for (int k = 0; k < cls->n_ic_targets; k++) {
            if (!strcmp(cls->ic_targets[k].name, nv))
                hv[nh] = k;
            if (!strcmp(cls->ic_targets[k].name, nx))
                hx[nh] = k;
        }
        if (hv[nh] >= 0 && hx[nh] >= 0)
            nh++;
    }
    void *st = tl_state_new(cls, 48000);
    int ni = cls->n_inputs > 0 ? cls->n_inputs : 1;
    const int B = 32;
    double **in = tl_bufs_new(ni, B), **out = tl_bufs_new(cls->n_outputs, B);
    tl_rng rng;
    tl_rng_seed(&rng, tl_hash_str(path));
    double Eref = cls->energy(st), Wref = cls->work(st), Eprev = Eref, peak = Eref, over = 0, rise = 0;
    long strikes = 0, next_strike = 0, burst_end = 0;
    for (long n = 0; n < nsamples; n += B) {
        int silent = 1;
        if (n >= next_strike) {
            if (nh) {
                int h = (int)(tl_rng_uniform(&rng) * nh);
                int ids[2] = {hv[h], hx[h]};
                double vals[2] = {0.5 + 3.5 * tl_rng_uniform(&rng), -(0.2e-3 + 1e-3 * tl_rng_uniform(&rng))};
                assert_int_equal(cls->set_ic(st, 2, ids, vals), 0);
                strikes++;
            }
            if (cls->n_inputs)
                burst_end = n + (long)(48000 * 0.05 * tl_rng_uniform(&rng));
            Eref = cls->energy(st);
            Wref = cls->work(st);
            Eprev = Eref;
            next_strike = n + (long)(48000 * (0.1 + 0.6 * tl_rng_uniform(&rng)));
        }
        for (int i = 0; i < cls->n_inputs; i++)
            for (int j = 0; j < B; j++)
                in[i][j] = n < burst_end ? tl_rng_signed(&rng) : 0;
        /* the work of the last driven sample is counted in the sample after */
        silent = n >= burst_end + B;
        run(cls, st, in, out, B);
        double E = cls->energy(st), W = cls->work(st);
        peak = fmax(peak, E);
        over = fmax(over, (E - Eref - (W - Wref)) / peak);
        if (silent)
            rise = fmax(rise, (E - Eprev) / peak);
        if (!(E <= Eref + (W - Wref) + 1e-9 * peak))
            fail_msg("%s: at sample %ld the stored energy %.17g exceeds %.17g after the last strike plus the "
                     "work since, %.17g", path, n, E, Eref, W - Wref);
        if (silent && !(E <= Eprev + 1e-9 * peak))
            fail_msg("%s: at sample %ld the stored energy rose from %.17g to %.17g with the inputs silent", path,
                     n, Eprev, E);
        Eprev = E;
        for (int k = 0; k < cls->n_outputs; k++)
            assert_true(isfinite(out[k][B - 1]));
    }
    printf("%-28s %ld samples, %ld strikes: largest E - E_strike - W %.2e, largest rise while silent %.2e "
           "(of the peak energy)\n", path, nsamples, strikes, over, rise);
    tl_bufs_free(in, ni);
    tl_bufs_free(out, cls->n_outputs);
    tl_state_free(st);
    tl_voice_free(&v);
}

static void test_passivity_under_play(void **state) {
    (void)state;
    glob_t g;
    assert_int_equal(glob("netlists/*.wdn", 0, NULL, &g), 0);
    int n = 0;
    for (size_t f = 0; f < g.gl_pathc; f++) {
        Circuit *c = wdc_load(g.gl_pathv[f]);
        if (!c || !is_instrument(c))
            continue;
        play(g.gl_pathv[f], 10000000);
        n++;
    }
    globfree(&g);
    assert_true(n >= 5);
}

/* ---- dulcimer ---- */

/* The largest level within 2 % of f (the bridge moves partials a little). */
static double level(const double *y, long n, double f, double fs) {
    double m = 0;
    for (int k = -40; k <= 40; k++)
        m = fmax(m, cabs(tl_dtft(y, n, 2 * M_PI * f * (1 + 0.0005 * k) / fs)));
    return m;
}

static void test_dulcimer_retarget(void **state) {
    (void)state;
    tl_voice v;
    assert_int_equal(tl_voice_build("netlists/dulcimer.wdn", 0, &v), 0);
    const wdv_class *cls = v.cls;
    const double fs = 48000;
    static const double notes[] = {293.66, 329.63, 369.99, 392.00, 440.00, 493.88, 554.37, 587.33};
    int s1 = tl_param_id(cls, "s1"), x1 = tl_param_id(cls, "x1"), ids[2] = {-1, -1};
    for (int i = 0; i < cls->n_ic_targets; i++) {
        if (!strcmp(cls->ic_targets[i].name, "v(m1)"))
            ids[0] = i;
        if (!strcmp(cls->ic_targets[i].name, "x(m1)"))
            ids[1] = i;
    }
    assert_true(s1 >= 0 && x1 >= 0 && ids[0] >= 0 && ids[1] >= 0);
    void *st = tl_state_new(cls, fs);
    void *quiet = tl_state_new(cls, fs);
    const long n = 24000;
    double **in = tl_bufs_new(1, n), **out = tl_bufs_new(cls->n_outputs, n);
    double *y = malloc(sizeof(double) * (size_t)n), *force = malloc(sizeof(double) * (size_t)n);
    /* string 3 struck near its end, then string 7 near its end and in its
     * middle: each time the hammer is moved while in the air, and the
     * response to the strike is what the strike adds to the ringing */
    static const int target[] = {3, 7, 7};
    static const double at[] = {0.13, 0.13, 0.5};
    long onset[3];
    for (int k = 0; k < 3; k++) {
        cls->set_param(st, s1, target[k]);
        cls->set_param(st, x1, at[k]);
        run(cls, st, in, out, 64);
        memcpy(quiet, st, cls->state_size);
        double vals[2] = {2, -0.3e-3};
        assert_int_equal(cls->set_ic(st, 2, ids, vals), 0);
        run(cls, st, in, out, (int)n);
        memcpy(y, out[0], sizeof(double) * (size_t)n);
        memcpy(force, out[1], sizeof(double) * (size_t)n);
        run(cls, quiet, in, out, (int)n);
        for (long i = 0; i < n; i++)
            y[i] -= out[0][i];
        int best = 0;
        double lbest = 0;
        for (int s = 0; s < 8; s++) {
            double l = level(y, n, notes[s], fs);
            if (l > lbest)
                lbest = l, best = s;
        }
        double peak = 0;
        for (long i = 0; i < n; i++)
            peak = fmax(peak, fabs(y[i]));
        long touch = 0;
        while (touch < n && force[touch] == 0)
            touch++;
        for (onset[k] = 0; onset[k] < n && fabs(y[onset[k]]) < 1e-4 * peak; onset[k]++)
            ;
        onset[k] -= touch;
        printf("hammer 1 moved to string %d at %.2f: loudest string %d; the bridge moves %ld samples after the "
               "felt touches the string\n", target[k], at[k], best + 1, onset[k]);
        assert_int_equal(best + 1, target[k]);
    }
    /* string 7 runs from a rigid end (x = 0) to the bridge (x = 1): struck
     * at 0.5 rather than 0.13, the wave has 0.37 of its length less to go */
    double want = (0.5 - 0.13) * fs / (2 * notes[6]), got = (double)(onset[1] - onset[2]);
    printf("moving the point from 0.13 to 0.5 brings the bridge's response %.0f samples earlier (the string's "
           "travel time gives %.1f)\n", got, want);
    assert_true(fabs(got - want) <= 2);
    free(y);
    free(force);
    tl_bufs_free(in, 1);
    tl_bufs_free(out, cls->n_outputs);
    tl_state_free(st);
    tl_state_free(quiet);
    tl_voice_free(&v);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_idle_contacts),
        cmocka_unit_test(test_dulcimer_retarget),
        cmocka_unit_test(test_param_jumps),
        cmocka_unit_test(test_passivity_under_play),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
