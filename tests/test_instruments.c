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
 *   - an idle contact's travel by chunks agrees with a hammer's stepped
 *     every frame (hung from a spring too weak to matter), contacts and
 *     all, on a string alone and on one a damper scatters on;
 *   - run-time re-targeting of a dulcimer hammer: the string it was moved
 *     to sounds, and the wave of a strike reaches the bridge as much
 *     earlier as the point it was moved to is nearer the bridge.
 */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdbool.h>
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

/* ---- skipped hammers ---- */

/* The ids of the targets v(NODE) and x(NODE), or -1. */
static void ic_ids(const wdv_class *cls, const char *node, int ids[2]) {
    char v[64], x[64];
    snprintf(v, sizeof v, "v(%s)", node);
    snprintf(x, sizeof x, "x(%s)", node);
    ids[0] = ids[1] = -1;
    for (int i = 0; i < cls->n_ic_targets; i++) {
        if (!strcmp(cls->ic_targets[i].name, v))
            ids[0] = i;
        if (!strcmp(cls->ic_targets[i].name, x))
            ids[1] = i;
    }
}

/* True if the voice's C text holds the loop that skips idle hammers. */
static bool skips(const tl_voice *v) {
    char path[256];
    snprintf(path, sizeof path, "%s/%s.c", v->dir, v->name);
    FILE *f = fopen(path, "r");
    assert_non_null(f);
    static char text[1 << 20];
    size_t n = fread(text, 1, sizeof text - 1, f);
    fclose(f);
    text[n] = '\0';
    return strstr(text, "the contacts are open") != NULL;
}

/* A play of a voice with hammers: strikes of each hammer in turn at
 * random speeds and gaps, param moves in between (the dulcimer's hammers
 * change strings, the piano's keys their pitch), strikes of any node
 * (whose settle reads the waves that last reached the idle taps), blocks
 * of random length.  Run by the voice that skips
 * idle hammers and by the one that computes them (--no-skip): every
 * output and the stored energy after every block are the same, bit for
 * bit, because while a contact is open its mass keeps its velocity and
 * its taps pass their waves untouched in both. */
static void skip_same(const char *net, const char *const *nodes, int nnodes, int single) {
    static const char *const noskip[] = {"--no-skip", NULL};
    tl_voice v[2];
    void *st[2];
    assert_int_equal(tl_voice_build_args(net, single, NULL, NULL, &v[0]), 0);
    assert_int_equal(tl_voice_build_args(net, single, noskip, NULL, &v[1]), 0);
    assert_true(skips(&v[0]));
    assert_false(skips(&v[1]));
    const wdv_class *cls = v[0].cls;
    for (int k = 0; k < 2; k++)
        st[k] = tl_state_new(v[k].cls, 48000);
    tl_rng r;
    tl_rng_seed(&r, tl_hash_str(net) + (uint64_t)single);
    double **in = tl_bufs_new(cls->n_inputs ? cls->n_inputs : 1, 128);
    double **out[2] = {tl_bufs_new(cls->n_outputs, 128), tl_bufs_new(cls->n_outputs, 128)};
    const long n = 72000;
    long differ = 0, strikes = 0, nonzero = 0;
    long next = 2400;
    for (long t = 0; t < n;) {
        int len = 1 + (int)(tl_rng_uniform(&r) * 127);
        if (t >= next) { /* strike a hammer, or move one */
            int h = (int)(tl_rng_uniform(&r) * nnodes), ids[2];
            ic_ids(cls, nodes[h], ids);
            double vals[2] = {1 + 3 * tl_rng_uniform(&r), -(0.2e-3 + 2e-3 * tl_rng_uniform(&r))};
            double u = tl_rng_uniform(&r);
            if (u < 0.2) { /* a strike elsewhere: its settle reads the waves that last reached the taps */
                int id = (int)(tl_rng_uniform(&r) * cls->n_ic_targets);
                double val = tl_rng_signed(&r) * (cls->ic_targets[id].name[0] == 'x' ? 1e-3 : 1.0);
                int ok = v[0].cls->set_ic(st[0], 1, &id, &val);
                assert_int_equal(v[1].cls->set_ic(st[1], 1, &id, &val), ok);
            } else if (cls->n_params && u < 0.5) {
                int p = (int)(tl_rng_uniform(&r) * cls->n_params);
                double x = cls->params[p].min + tl_rng_uniform(&r) * (cls->params[p].max - cls->params[p].min);
                for (int k = 0; k < 2; k++)
                    v[k].cls->set_param(st[k], p, x);
            } else {
                assert_true(ids[0] >= 0 && ids[1] >= 0);
                for (int k = 0; k < 2; k++)
                    assert_int_equal(v[k].cls->set_ic(st[k], 2, ids, vals), 0);
                strikes++;
            }
            next += 1200 + (long)(tl_rng_uniform(&r) * 6000);
        }
        for (int i = 0; i < cls->n_inputs; i++)
            for (int j = 0; j < len; j++)
                in[i][j] = 0;
        for (int k = 0; k < 2; k++)
            run(v[k].cls, st[k], in, out[k], len);
        for (int o = 0; o < cls->n_outputs; o++)
            for (int j = 0; j < len; j++) {
                differ += memcmp(&out[0][o][j], &out[1][o][j], sizeof(double)) != 0;
                nonzero += out[0][o][j] != 0;
            }
        double e0 = v[0].cls->energy(st[0]), e1 = v[1].cls->energy(st[1]);
        differ += memcmp(&e0, &e1, sizeof e0) != 0;
        t += len;
    }
    printf("%s (%s): %ld strikes; %ld output samples and energies differ between the voice that skips idle "
           "hammers and the one that does not\n", net, single ? "float" : "double", strikes, differ);
    assert_true(strikes > 3);
    assert_true(nonzero > n / 2);
    assert_int_equal(differ, 0);
    const int nout = cls->n_outputs;
    tl_bufs_free(in, cls->n_inputs ? cls->n_inputs : 1);
    for (int k = 0; k < 2; k++) {
        tl_bufs_free(out[k], nout);
        tl_state_free(st[k]);
        tl_voice_free(&v[k]);
    }
}

/* A stretch of 2^22 frames and more with every hammer in the air: the
 * lines' running sums are made anew on the way (at the same frame
 * skipping or not), and a hammer that drifts onto the string after it,
 * at 0.215 mm/s from 20 mm, sounds the same to the bit. */
static void skip_same_long(void) {
    static const char *const noskip[] = {"--no-skip", NULL};
    char dir[64], net[4096];
    assert_int_equal(tl_temp_dir(dir, "wdc_long"), 0);
    /* a string that rings on (t60 of ten minutes), struck at the start */
    snprintf(net, sizeof net, "%s",
             tl_write_file(dir, "ringing.wdn",
                           ".voice ringing\n.domain mechanical\n.ic v(h1)=3 x(h1)=-1.3m x(h2)=-2m v(h5)=0.215m x(h5)=-20m\n"
                           "string S 0 br L=0.62 f0=261.63 mu=6.8m B=4e-4 t60=600 taps=t1@0.12,t2@0.31,t5@0.5\n"
                           "mass MH1 h1 m=2.9m\ncontact H1 h1 t1 k=4.5e9 alpha=2.5 lambda=0.1\n"
                           "mass MH2 h2 m=2.9m\ncontact H2 h2 t2 k=4.5e9 alpha=2.5 lambda=0.1\n"
                           "mass MH5 h5 m=2.9m\ncontact H5 h5 t5 k=4.5e9 alpha=2.5 lambda=0.1\n"
                           "mass MB br m=0.3\nspring KB br 0 k=2meg\n.output bridge v(br)\n.output felt f(H5)\n.end\n"));
    tl_voice v[2];
    void *st[2];
    assert_int_equal(tl_voice_build_args(net, 0, NULL, NULL, &v[0]), 0);
    assert_int_equal(tl_voice_build_args(net, 0, noskip, NULL, &v[1]), 0);
    const wdv_class *cls = v[0].cls;
    for (int k = 0; k < 2; k++)
        st[k] = tl_state_new(v[k].cls, 48000);
    double **in = tl_bufs_new(1, 4096);
    double **out[2] = {tl_bufs_new(cls->n_outputs, 4096), tl_bufs_new(cls->n_outputs, 4096)};
    const long n = (1L << 22) + 240000;
    long differ = 0, touch = -1;
    for (long t = 0; t < n;) {
        int len = 4096;
        for (int k = 0; k < 2; k++)
            run(v[k].cls, st[k], in, out[k], len);
        for (int o = 0; o < cls->n_outputs; o++)
            for (int j = 0; j < len; j++)
                differ += memcmp(&out[0][o][j], &out[1][o][j], sizeof(double)) != 0;
        for (int j = 0; j < len && touch < 0; j++)
            if (out[1][1][j] != 0 && t + j > 48000)
                touch = t + j;
        t += len;
    }
    double e0 = v[0].cls->energy(st[0]), e1 = v[1].cls->energy(st[1]);
    printf("a string ringing %ld frames, a hammer drifting onto it at frame %ld: %ld output samples differ skipping "
           "or not, energies %s\n", n, touch, differ, memcmp(&e0, &e1, sizeof e0) ? "differ" : "the same");
    assert_true(touch > 1L << 22);
    assert_int_equal(differ, 0);
    assert_memory_equal(&e0, &e1, sizeof e0);
    const int nout = cls->n_outputs; /* cls goes with v[0] */
    tl_bufs_free(in, 1);
    for (int k = 0; k < 2; k++) {
        tl_bufs_free(out[k], nout);
        tl_state_free(st[k]);
        tl_voice_free(&v[k]);
    }
    tl_remove_dir(dir);
}

static void test_skip_exact(void **state) {
    (void)state;
    skip_same_long();
    static const char *const eight[] = {"h1", "h2", "h3", "h4", "h5", "h6", "h7", "h8"};
    static const char *const dulcimer[] = {"m1", "m2"};
    static const char *const mid[] = {"h1", "h2", "h3"};
    static const char *const piano[] = {"a1", "b1", "a2", "b2", "a3", "b3", "a4", "b4"};
    for (int single = 0; single < 2; single++) {
        skip_same("netlists/piano.wdn", piano, 8, single);
        skip_same("tests/nets/hammers_eight.wdn", eight, 8, single);
        skip_same("netlists/dulcimer.wdn", dulcimer, 2, single);
        skip_same("netlists/piano_mid.wdn", mid, 3, single);
    }
}

/* A hammer hung from a spring, or with a damper, moves while its contact
 * is open: it is computed every sample, never skipped. */
static void test_skip_only_idle(void **state) {
    (void)state;
    char dir[64];
    assert_int_equal(tl_temp_dir(dir, "wdc_skip"), 0);
    static const char *const extra[] = {"spring KR h1 0 k=50", "damper DR h1 0 c=0.01", "mass MX h1 m=1m"};
    for (int k = 0; k < 3; k++) {
        char text[2048];
        snprintf(text, sizeof text,
                 ".voice sprung\n.domain mechanical\n.ic v(h1)=3 x(h1)=-1m\n"
                 "string S 0 br L=0.62 f0=261.63 mu=6.8m t60=12 taps=t1@0.12\n"
                 "mass MH1 h1 m=2.9m\ncontact H1 h1 t1 k=4.5e9 alpha=2.5\n%s\n"
                 "mass MB br m=0.3\nspring KB br 0 k=2meg\n.output bridge v(br)\n.end\n", extra[k]);
        const char *net = tl_write_file(dir, "sprung.wdn", text);
        tl_voice v;
        assert_int_equal(tl_voice_build(net, 0, &v), 0);
        printf("hammer with '%s': %s\n", extra[k], skips(&v) ? "skipped while idle" : "computed every sample");
        assert_int_equal(skips(&v), k == 2); /* two masses hold their velocities too */
        tl_voice_free(&v);
    }
    tl_remove_dir(dir);
}

/* An idle contact's travel goes by chunks; a hammer hung from a spring
 * too weak to matter (its force below 1e-16 N here) is stepped every
 * frame instead.  Four hammers on a string: one thrown, two resting 0.05
 * mm and 0.5 mm from it (the string's swing reaches the nearer), one
 * coming at 0.2 m/s from 20 mm, which meets the string a tenth of a second
 * later; the first two struck again (a chunk cut at a strike, and where
 * they meet the string) while it comes.  The two voices agree to
 * rounding, contacts and all, in calls of random length.  A chunk's bound
 * that let a contact pass unseen, a sum or a cut that left out a wave,
 * would part them by orders of magnitude more. */
static void chunks_step(int damped) {
    char dir[64];
    assert_int_equal(tl_temp_dir(dir, "wdc_chunk"), 0);
    char net[2][4096];
    for (int k = 0; k < 2; k++) {
        char text[4096], hang[256] = "";
        for (int h = 1; k && h <= 4; h++) {
            size_t n = strlen(hang);
            snprintf(hang + n, sizeof hang - n, "spring KR%d h%d 0 k=1e-15\n", h, h);
        }
        snprintf(text, sizeof text,
                 ".voice chunk%d\n.domain mechanical\n"
                 ".ic v(h1)=3 x(h1)=-1m x(h2)=-0.05m x(h3)=-0.5m v(h4)=0.2 x(h4)=-20m\n"
                 "string S 0 br L=0.62 f0=261.63 mu=6.8m B=4e-4 t60=12 t60hf=1.2 fhf=5k "
                 "taps=t1@0.12,t2@0.31,t3@0.07,t4@0.5%s\n"
                 "mass MH1 h1 m=2.9m\ncontact H1 h1 t1 k=4.5e9 alpha=2.5 lambda=0.1\n"
                 "mass MH2 h2 m=2.9m\ncontact H2 h2 t2 k=4.5e9 alpha=2.5 lambda=0.1\n"
                 "mass MH3 h3 m=2.9m\ncontact H3 h3 t3 k=4.5e9 alpha=2.5 lambda=0.1\n"
                 "mass MH4 h4 m=2.9m\ncontact H4 h4 t4 k=4.5e9 alpha=2.5 lambda=0.1\n%s"
                 "%smass MB br m=0.3\nspring KB br 0 k=2meg\ndamper DB br 0 c=30\n"
                 ".output bridge v(br)\n.output felt1 f(H1)\n.output felt2 f(H2)\n.end\n",
                 k, damped ? ",d@0.93" : "", damped ? "damper DP d 0 c=0.5\n" : "", hang);
        snprintf(net[k], sizeof net[k], "%s", tl_write_file(dir, k ? "stepped.wdn" : "chunked.wdn", text));
    }
    tl_voice v[2];
    void *st[2];
    for (int k = 0; k < 2; k++) {
        assert_int_equal(tl_voice_build(net[k], 0, &v[k]), 0);
        assert_true(skips(&v[k]) == (k == 0));
        st[k] = tl_state_new(v[k].cls, 48000);
    }
    const wdv_class *cls = v[0].cls;
    tl_rng r;
    tl_rng_seed(&r, 11);
    double **in = tl_bufs_new(1, 128);
    double **out[2] = {tl_bufs_new(3, 128), tl_bufs_new(3, 128)};
    const long n = 96000;
    double num[3] = {0}, den[3] = {0};
    long touches[2] = {0};
    int was[2] = {0};
    for (long t = 0; t < n;) {
        int len = 1 + (int)(tl_rng_uniform(&r) * 127);
        if (t >= 2400 && t - len < 2400) { /* the thrown hammer again, and the one at 0.5 mm */
            for (int h = 1; h <= 3; h += 2) {
                char node[8];
                int ids[2];
                snprintf(node, sizeof node, "h%d", h);
                ic_ids(cls, node, ids);
                double vals[2] = {h == 1 ? 2.0 : 1.5, h == 1 ? -2e-3 : -0.5e-3};
                for (int k = 0; k < 2; k++)
                    assert_int_equal(v[k].cls->set_ic(st[k], 2, ids, vals), 0);
            }
        }
        for (int k = 0; k < 2; k++)
            run(v[k].cls, st[k], in, out[k], len);
        for (int j = 0; j < len; j++) {
            for (int o = 0; o < 3; o++) {
                double d = out[0][o][j] - out[1][o][j];
                num[o] += d * d, den[o] += out[1][o][j] * out[1][o][j];
            }
            for (int k = 0; k < 2; k++) { /* the resting felt's touches */
                int on = out[k][2][j] != 0;
                touches[k] += on && !was[k];
                was[k] = on;
            }
        }
        t += len;
    }
    double worst = 0;
    for (int o = 0; o < 3; o++) {
        double e = sqrt(num[o] / den[o]);
        printf("%s: chunked against stepped travel, output %d: relative RMS difference %.3g\n",
               damped ? "a damper on the string" : "a string alone", o, e);
        worst = e > worst ? e : worst;
        assert_true(den[o] > 0);
    }
    printf("the felt resting 0.05 mm from the string: %ld touches chunked, %ld stepped\n", touches[0], touches[1]);
    assert_true(touches[1] > 0);
    assert_int_equal(touches[0], touches[1]);
    assert_true(worst < 1e-6);
    tl_bufs_free(in, 1);
    for (int k = 0; k < 2; k++) {
        tl_bufs_free(out[k], 3);
        tl_state_free(st[k]);
        tl_voice_free(&v[k]);
    }
    tl_remove_dir(dir);
}

/* On a string alone its lines keep running sums; a damper that scatters
 * on it has the chunks sum the waves themselves. */
static void test_chunks_step(void **state) {
    (void)state;
    chunks_step(0);
    chunks_step(1);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_chunks_step),
        cmocka_unit_test(test_idle_contacts),
        cmocka_unit_test(test_skip_exact),
        cmocka_unit_test(test_skip_only_idle),
        cmocka_unit_test(test_dulcimer_retarget),
        cmocka_unit_test(test_param_jumps),
        cmocka_unit_test(test_passivity_under_play),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
