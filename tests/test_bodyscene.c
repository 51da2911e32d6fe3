/*
 * test_bodyscene.c - bodies in scenes (surf.h through scene.c and the
 * engine's excitations phase): an impact heard at its frame and as the
 * world alone makes it, a resonator that sleeps and wakes exactly as a
 * fresh one, bodies sharing a resonator, a placed body heard d/c late,
 * contacts with curves, and the errors of the body forms.
 */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "countalloc.h"
#include "surf.h"
#include "testlib.h"
#include "wdrt.h"

#define FS 48000.0

static char g_dir[64];

static int setup(void **s) {
    (void)s;
    return tl_temp_dir(g_dir, "wdrt-bodyscene");
}

static int teardown(void **s) {
    (void)s;
    tl_remove_dir(g_dir);
    return 0;
}

static double *render(const char *text, long *n, wdrt_engine_stats *st) {
    wdrt_scene *s = tl_scene_load(g_dir, "s.wds", text);
    assert_non_null(s);
    double *y = NULL, rate;
    int nch;
    assert_int_equal(wdrt_scene_render(s, NULL, &y, n, &nch, &rate, st), WDRT_OK);
    assert_int_equal(nch, 1);
    wdrt_scene_free(s);
    return y;
}

static void load_error(const char *text, char *err, size_t len) { tl_scene_error(g_dir, "e.wds", text, err, len); }

/* The same impact through a world of its own, frame by frame. */
static void world_alone(double *y, long n, long at) {
    surf_config cfg = surf_config_init(FS);
    cfg.block = 64;
    surf_world *w;
    assert_int_equal(surf_init(&cfg, NULL, &w), WDRT_OK);
    surf_mode m[2] = {{440, 0.5, {1}}, {1250, 0.3, {0.5}}};
    surf_resonator_desc rd = surf_resonator_desc_init();
    rd.modes = m, rd.nmodes = 2, rd.quiet = 1e-5;
    assert_int_equal(surf_add_resonator(w, &rd), 0);
    surf_mode f[1] = {{90, 0.1, {1}}};
    rd.modes = f, rd.nmodes = 1;
    assert_int_equal(surf_add_resonator(w, &rd), 1);
    surf_surface_desc sd = surf_surface_desc_init();
    sd.relief.kind = SURF_RELIEF_NOISE, sd.relief.scale = 1e-4;
    sd.hardness = 1e6;
    assert_int_equal(surf_add_surface(w, &sd), 0);
    sd.hardness = 1e8;
    assert_int_equal(surf_add_surface(w, &sd), 1);
    surf_body_desc b0 = {0, 0, 0.05}, b1 = {1, 1, 5};
    assert_int_equal(surf_add_body(w, &b0), 0);
    assert_int_equal(surf_add_body(w, &b1), 1);
    surf_impact_data hit = {0.01, 0, 0};
    for (long i = 0; i < n; i += 64) {
        if (i == at)
            surf_impact(w, 0, 0, 1, &hit);
        int m2 = surf_process(w, NULL, (int)(n - i < 64 ? n - i : 64));
        const double *o = surf_output(w, 0, 0);
        for (int k = 0; k < m2; k++)
            y[i + k] = o ? o[k] : 0;
    }
    surf_uninit(w, NULL);
}

static const char *two_bodies = "(length 1) (sleep off)\n"
                                "(body bell (modes (440 0.5 1) (1250 0.3 0.5)) (mass 0.05) (hardness 1e6) (quiet -100))\n"
                                "(body floor (modes (90 0.1 1)) (mass 5) (hardness 1e8) (gain 0) (quiet -100))\n";

static void test_impact_as_world_alone(void **st) {
    (void)st;
    char text[1024];
    snprintf(text, sizeof text, "%s(at %.10f (impact bell floor (impulse 0.01)))\n", two_bodies, 6400 / FS);
    long n;
    double *y = render(text, &n, NULL);
    double *z = calloc((size_t)n, sizeof *z);
    world_alone(z, n, 6400);
    double err = 0, pk = 0;
    for (long i = 0; i < n; i++)
        err = fmax(err, fabs(y[i] - z[i])), pk = fmax(pk, fabs(z[i]));
    printf("impact in a scene vs the world alone: %.3g of peak %.3g\n", err, pk);
    assert_true(pk > 1e-4);
    assert_true(err <= 1e-12 * pk);
    for (long i = 0; i < 6400; i++)
        assert_true(y[i] == 0); /* nothing before its frame */
    assert_true(y[6401] != 0);
    free(y);
    free(z);
}

static void test_sleep_and_wake(void **st) {
    (void)st;
    /* struck at 0.1 s and again at 1.6 s: between, it falls quiet and
     * sleeps; after the second strike it sounds as if only that one had
     * happened (the first's tail is 10^-21 by then) */
    long n, m;
    wdrt_engine_stats s1, s2;
    double *a = render("(length 2.2)\n"
                       "(body bell (modes (440 0.2 1)) (mass 0.05) (hardness 1e6) (quiet -60))\n"
                       "(body floor (modes (90 0.1 1)) (mass 5) (hardness 1e8) (gain 0))\n"
                       "(at 0.1 (impact bell floor (impulse 0.01)))\n"
                       "(at 1.6 (impact bell floor (impulse 0.01)))\n",
                       &n, &s1);
    double *b = render("(length 2.2)\n"
                       "(body bell (modes (440 0.2 1)) (mass 0.05) (hardness 1e6) (quiet -60))\n"
                       "(body floor (modes (90 0.1 1)) (mass 5) (hardness 1e8) (gain 0))\n"
                       "(at 1.6 (impact bell floor (impulse 0.01)))\n",
                       &m, &s2);
    assert_int_equal(n, m);
    assert_true(s1.sleeps >= 1 && s1.wakes >= 1);
    double err = 0, pk = 0;
    for (long i = (long)(1.6 * FS); i < n; i++)
        err = fmax(err, fabs(a[i] - b[i])), pk = fmax(pk, fabs(b[i]));
    printf("after a sleep: %.3g of peak %.3g (%llu sleeps, %llu wakes)\n", err, pk, (unsigned long long)s1.sleeps,
           (unsigned long long)s1.wakes);
    assert_true(pk > 1e-4 && err <= 1e-12 * pk);
    double mid = 0;
    for (long i = (long)(1.2 * FS); i < (long)(1.6 * FS); i++)
        mid = fmax(mid, fabs(a[i]));
    assert_true(mid == 0); /* asleep: silent, not computed */
    free(a);
    free(b);
}

static void test_shared_resonator(void **st) {
    (void)st;
    /* two marbles ringing one jar: the render of both impacts is the sum
     * of each alone (the world is linear in its excitations) */
    const char *head = "(length 0.6) (sleep off)\n"
                       "(body jar (modes (820 0.8 1) (1910 0.5 0.6)) (mass 0.4) (hardness 1e8) (quiet -200))\n"
                       "(body m1 (share jar) (mass 0.005) (hardness 5e8) (relief none))\n"
                       "(body m2 (share jar) (mass 0.008) (hardness 2e8) (relief none))\n";
    char t[1024];
    long n;
    snprintf(t, sizeof t, "%s(at 0.1 (impact m1 jar (impulse 0.002)))\n(at 0.23 (impact m2 jar (impulse 0.003)))\n", head);
    double *ab = render(t, &n, NULL);
    snprintf(t, sizeof t, "%s(at 0.1 (impact m1 jar (impulse 0.002)))\n", head);
    double *a = render(t, &n, NULL);
    snprintf(t, sizeof t, "%s(at 0.23 (impact m2 jar (impulse 0.003)))\n", head);
    double *b = render(t, &n, NULL);
    double err = 0, pk = 0;
    for (long i = 0; i < n; i++)
        err = fmax(err, fabs(ab[i] - a[i] - b[i])), pk = fmax(pk, fabs(ab[i]));
    printf("shared jar: sum of each alone to %.3g of peak %.3g\n", err, pk);
    assert_true(pk > 1e-5 && err <= 1e-12 * pk);
    free(ab);
    free(a);
    free(b);
}

static void test_placed_body(void **st) {
    (void)st;
    /* a body 34.3 m away is heard 0.1 s late, as it sounds (no distance
     * model, no air) */
    long n, m;
    double *a = render("(length 0.6) (sleep off) (distance none) (air off) (listener (pos 0 0 0))\n"
                       "(body bell (modes (440 0.5 1)) (mass 0.05) (hardness 1e6) (pos 0 34.3 0))\n"
                       "(body floor (modes (90 0.1 1)) (mass 5) (gain 0))\n"
                       "(at 0.1 (impact bell floor (impulse 0.01)))\n",
                       &n, NULL);
    double *b = render("(length 0.6) (sleep off)\n"
                       "(body bell (modes (440 0.5 1)) (mass 0.05) (hardness 1e6))\n"
                       "(body floor (modes (90 0.1 1)) (mass 5) (gain 0))\n"
                       "(at 0.1 (impact bell floor (impulse 0.01)))\n",
                       &m, NULL);
    long d = (long)llround(34.3 / 343 * FS);
    double err = 0, pk = 0;
    for (long i = d; i < n; i++)
        err = fmax(err, fabs(a[i] - b[i - d])), pk = fmax(pk, fabs(b[i - d]));
    printf("placed body: %ld frames late, %.3g of peak %.3g\n", d, err, pk);
    assert_true(err <= 1e-9 * pk);
    free(a);
    free(b);
}

static void test_contact_curves(void **st) {
    (void)st;
    /* a contact sounds while it lasts and its sound follows its force: the
     * puck slides (no rolling), so its needle reads the table's relief at
     * the slip speed and the table rings */
    long n;
    double *y = render("(length 1.5) (sleep off)\n"
                       "(body puck (modes (700 0.05 1)) (mass 0.2) (gain 0))\n"
                       "(body table (modes (150 0.05 1) (900 0.05 1)) (mass 20) (relief noise 0.0001))\n"
                       "(at 0.2 (contact puck table (force (curve (0 0) (0.5 1) (1 0))) (slip 0.5) (until 1.2)))\n",
                       &n, NULL);
    double before = 0, peak = 0, after = 0, rise = 0;
    for (long i = 0; i < (long)(0.2 * FS); i++)
        before = fmax(before, fabs(y[i]));
    for (long i = (long)(0.6 * FS); i < (long)(0.8 * FS); i++)
        peak = fmax(peak, fabs(y[i]));
    for (long i = (long)(0.25 * FS); i < (long)(0.3 * FS); i++)
        rise = fmax(rise, fabs(y[i]));
    for (long i = (long)(1.45 * FS); i < n; i++)
        after = fmax(after, fabs(y[i]));
    printf("contact: before %.3g, at 0.05 s %.3g, at its strongest %.3g, after %.3g\n", before, rise, peak, after);
    assert_true(before == 0);
    assert_true(peak > 1e-6);
    assert_true(rise < 0.5 * peak);   /* the force is a tenth of its top there */
    assert_true(after < 1e-3 * peak); /* ended: rung down (T60 0.05 s) */
    free(y);
}

static void test_body_errors(void **st) {
    (void)st;
    char err[2048];
    load_error("(body a (mass 1))\n", err, sizeof err);
    assert_non_null(strstr(err, "e.wds:1:7: error: body a needs its (modes ...), a (voice \"file.wdn\") or (share BODY)"));
    load_error("(body a (modes (440 0.5 1)))\n(body b (share c))\n", err, sizeof err);
    assert_non_null(strstr(err, "e.wds:2:16: error: unknown body 'c'"));
    load_error("(body a (modes (440 -1 1)))\n", err, sizeof err);
    assert_non_null(strstr(err, "e.wds:1:16: error: a mode has"));
    load_error("(body a (modes (440 1 1)))\n(body b (modes (40 1 1)))\n(at 1 (contact a b (force 1)))\n", err,
               sizeof err);
    assert_non_null(strstr(err, "e.wds:3:7: error: a contact needs its (force F) and (until T)"));
    load_error("(body a (modes (440 1 1)))\n(body b (modes (40 1 1)))\n(at 1 (impact a b))\n", err, sizeof err);
    assert_non_null(strstr(err, "e.wds:3:7: error: an impact between bodies needs its (impulse J)"));
    /* a number past a bound is told the bound, not only the lower one */
    load_error("(body a (modes (440 1 1)))\n(body b (modes (40 1 1)))\n(at 1 (impact a b (impulse 1e300)))\n", err,
               sizeof err);
    assert_non_null(strstr(err, "e.wds:3:28: error: an impulse is in N s, 0 or more and below 10^6"));
    load_error("(body a (modes (440 1 1)) (relief bumpy 1))\n", err, sizeof err);
    assert_non_null(strstr(err, "e.wds:1:35: error: unknown relief 'bumpy'"));
}

static void test_voice_body(void **st) {
    (void)st;
    /* the textbook oscillator (netlists/msd.wdn, 71.2 Hz) rung through its
     * force input by an impact: silent before, ringing after at its own
     * frequency, asleep once it has died away */
    tl_voice v;
    assert_int_equal(tl_voice_build("netlists/msd.wdn", 0, &v), 0);
    char text[1024];
    char cwd[512];
    assert_non_null(getcwd(cwd, sizeof cwd));
    snprintf(text, sizeof text,
             "(body mass (voice \"%s/netlists/msd.wdn\") (input f) (output vel) (mass 0.1) (hardness 1e6))\n"
             "(body hammer (modes (3000 0.01 1)) (mass 0.02) (hardness 1e6) (gain 0))\n"
             "(at 0.1 (impact hammer mass (impulse 0.01)))\n",
             cwd);
    const char *path = tl_write_file(g_dir, "v.wds", text);
    char err[2048] = "";
    wdrt_scene *s;
    assert_int_equal(wdrt_scene_load(path, &s, err, sizeof err), WDRT_OK);
    assert_int_equal(wdrt_scene_nvoices(s), 1);
    assert_string_equal(wdrt_scene_voice_name(s, 0), "mass");
    assert_int_equal(wdrt_scene_bind(s, 0, v.cls, err, sizeof err), WDRT_OK);
    double *y, rate;
    long n;
    int nch;
    wdrt_engine_stats es;
    assert_int_equal(wdrt_scene_render(s, NULL, &y, &n, &nch, &rate, &es), WDRT_OK);
    long f = (long)(0.1 * FS);
    double before = 0, pk = 0;
    for (long i = 0; i < f; i++)
        before = fmax(before, fabs(y[i]));
    /* zero crossings over 0.2 s after the strike: 71.2 Hz */
    int zc = 0;
    for (long i = f + 100; i < f + 100 + (long)(0.2 * FS); i++) {
        zc += (y[i] > 0) != (y[i - 1] > 0);
        pk = fmax(pk, fabs(y[i]));
    }
    printf("voice body: before %.3g, peak %.3g, %d crossings in 0.2 s (71.2 Hz: %.1f), %.2f s long, %llu sleeps\n",
           before, pk, zc, 2 * 71.2 * 0.2, n / FS, (unsigned long long)es.sleeps);
    assert_true(before == 0);
    assert_true(pk > 1e-6);
    assert_true(abs(zc - (int)lround(2 * 71.2 * 0.2)) <= 1);
    assert_true(es.sleeps >= 1 && n < (long)(20 * FS)); /* it rang down and the scene ended */
    free(y);
    /* a voice without that input */
    snprintf(text, sizeof text, "(body mass (voice \"%s/netlists/msd.wdn\") (input g))\n", cwd);
    path = tl_write_file(g_dir, "w.wds", text);
    wdrt_scene *s2;
    assert_int_equal(wdrt_scene_load(path, &s2, err, sizeof err), WDRT_OK);
    assert_int_equal(wdrt_scene_bind(s2, 0, v.cls, err, sizeof err), WDRT_SYNTAX);
    assert_non_null(strstr(err, "w.wds:1:"));
    assert_non_null(strstr(err, "unknown input 'g'; did you mean 'f'?"));
    wdrt_scene_free(s2);
    wdrt_scene_free(s);
    tl_voice_free(&v);
}

static void test_c_api(void **st) {
    (void)st;
    /* the bodies of the first test through the public API, driven as a
     * physics thread would: the same sound, sample for sample, as the
     * world alone; nothing allocated while the engine processes */
    wdrt_bodies_config bc = wdrt_bodies_config_init(FS);
    bc.queue = 4;
    wdrt_bodies *h;
    assert_int_equal(wdrt_bodies_new(&bc, &h), WDRT_OK);
    wdrt_mode bm[2] = {{440, 0.5, 1}, {1250, 0.3, 0.5}}, fm[1] = {{90, 0.1, 1}};
    wdrt_body b = wdrt_body_init();
    b.modes = bm, b.nmodes = 2, b.mass = 0.05, b.hardness = 1e6, b.quiet = 1e-5;
    assert_int_equal(wdrt_bodies_add(h, &b), 0);
    b.modes = fm, b.nmodes = 1, b.mass = 5, b.hardness = 1e8, b.gain = 0;
    assert_int_equal(wdrt_bodies_add(h, &b), 1);
    b.share = 0, b.nmodes = 0; /* a third body on the first's resonator: no pool of its own */
    assert_int_equal(wdrt_bodies_add(h, &b), 2);
    b.share = 7;
    assert_int_equal(wdrt_bodies_add(h, &b), WDRT_INVALID_ARGS);
    assert_int_equal(wdrt_bodies_npools(h), 2);
    wdrt_pool_config pc[2];
    assert_int_equal(wdrt_bodies_pools(h, pc, 0), WDRT_OK);
    wdrt_engine_config ec = wdrt_engine_config_init(FS, 1, 2, pc);
    ec.sleep = 0;
    wdrt_bodies_attach(h, &ec);
    wdrt_engine *e;
    assert_int_equal(wdrt_engine_init(&ec, NULL, &e), WDRT_OK);
    assert_int_equal(wdrt_bodies_impact(h, 6400, 0, 1, 0.01, 0, 0), WDRT_OK);
    assert_int_equal(wdrt_bodies_impact(h, 6400, 0, 0, 0.01, 0, 0), WDRT_INVALID_ARGS);
    assert_int_equal(wdrt_bodies_contact(h, 0, 99, 0, 1, 0, 0, 0, 1), WDRT_INVALID_ARGS);
    for (int i = 0; i < 3; i++) /* the queue of 4 fills */
        assert_int_equal(wdrt_bodies_contact_stop(h, 30000, 0), WDRT_OK);
    assert_int_equal(wdrt_bodies_contact_stop(h, 30000, 0), WDRT_QUEUE_FULL);
    long n = (long)FS;
    double *y = calloc((size_t)n, sizeof *y), *z = calloc((size_t)n, sizeof *z);
    ca_allocs = 0;
    for (long i = 0; i < n; i += 333) {
        ca_in_rt = 1;
        wdrt_engine_process(e, y + i, (uint32_t)(n - i < 333 ? n - i : 333));
        ca_in_rt = 0;
    }
    assert_int_equal(ca_allocs, 0);
    world_alone(z, n, 6400);
    double err = 0, pk = 0;
    for (long i = 0; i < n; i++)
        err = fmax(err, fabs(y[i] - z[i])), pk = fmax(pk, fabs(z[i]));
    wdrt_bodies_stats s;
    wdrt_bodies_get_stats(h, &s);
    printf("C API: %.3g of peak %.3g; impacts high-water %d, refused %llu\n", err, pk, s.impacts_hwm,
           (unsigned long long)s.refused);
    assert_true(pk > 1e-4 && err <= 1e-12 * pk);
    assert_int_equal(s.impacts_hwm, 1);
    wdrt_engine_uninit(e, NULL);
    wdrt_bodies_free(h);
    free(y);
    free(z);
}

static void test_mode_limit(void **st) {
    (void)st;
    /* two bells of ten modes each under a limit of twelve: the first is
     * struck and rings all ten; the second, struck while it rings, gets
     * the two left (its loudest); once the first has slept the second,
     * struck again, rings all ten.  Nothing sounding is cut off. */
    wdrt_mode m[10];
    for (int k = 0; k < 10; k++)
        m[k].f = 300 * (k + 1) * (1 + 0.01 * k), m[k].t60 = 0.4, m[k].gain = 1.0 / (k + 1);
    double *y[2];
    long n = (long)(2.5 * FS);
    for (int lim = 0; lim < 2; lim++) {
        wdrt_bodies_config bc = wdrt_bodies_config_init(FS);
        bc.active_modes = lim ? 12 : 0;
        wdrt_bodies *h;
        assert_int_equal(wdrt_bodies_new(&bc, &h), WDRT_OK);
        wdrt_body b = wdrt_body_init();
        b.modes = m, b.nmodes = 10, b.hardness = 1e6, b.quiet = 1e-4;
        assert_int_equal(wdrt_bodies_add(h, &b), 0);
        assert_int_equal(wdrt_bodies_add(h, &b), 1);
        b.gain = 0, b.nmodes = 1;
        assert_int_equal(wdrt_bodies_add(h, &b), 2);
        wdrt_pool_config pc[3];
        wdrt_bodies_pools(h, pc, 0);
        wdrt_engine_config ec = wdrt_engine_config_init(FS, 1, 3, pc);
        wdrt_bodies_attach(h, &ec);
        wdrt_engine *e;
        assert_int_equal(wdrt_engine_init(&ec, NULL, &e), WDRT_OK);
        wdrt_bodies_impact(h, 4800, 0, 2, 0.01, 0, 0);
        wdrt_bodies_impact(h, 9600, 1, 2, 0.01, 0, 0);
        wdrt_bodies_impact(h, (uint64_t)(2.0 * FS), 1, 2, 0.01, 0, 0);
        y[lim] = calloc((size_t)n, sizeof(double));
        for (long i = 0; i < n; i += 64)
            wdrt_engine_process(e, y[lim] + i, (uint32_t)(n - i < 64 ? n - i : 64));
        wdrt_bodies_stats s;
        wdrt_bodies_get_stats(h, &s);
        if (lim) {
            printf("mode limit: %llu lowered, %llu refused\n", (unsigned long long)s.lowered,
                   (unsigned long long)s.refused);
            assert_int_equal(s.lowered, 1);
            assert_int_equal(s.refused, 0);
        }
        wdrt_engine_uninit(e, NULL);
        wdrt_bodies_free(h);
    }
    /* until the second strike the two are the same; after it, the limited
     * one lacks the second bell's eight quietest modes; after the third,
     * the same again */
    double d1 = 0, d2 = 0, d3 = 0, pk = 0;
    for (long i = 0; i < n; i++) {
        double d = fabs(y[0][i] - y[1][i]);
        pk = fmax(pk, fabs(y[0][i]));
        if (i < 9600)
            d1 = fmax(d1, d);
        else if (i < (long)(1.9 * FS))
            d2 = fmax(d2, d);
        else if (i > (long)(2.0 * FS))
            d3 = fmax(d3, d);
    }
    printf("mode limit: before %.3g, while lowered %.3g (%.1f dB re peak), after %.3g\n", d1, d2,
           20 * log10(d2 / pk), d3);
    assert_true(d1 == 0);
    assert_true(d2 > 1e-4 * pk && d2 < 0.5 * pk);
    assert_true(d3 <= 1e-12 * pk);
    free(y[0]);
    free(y[1]);
}

static void test_gains_segment_enable(void **st) {
    (void)st;
    /* Figure 4's direct gain: an impact's pulse heard unresonated sums to
     * direct x J x fs (its samples hold the mean force over each) */
    long n;
    double *y = render("(length 0.2) (sleep off)\n"
                       "(body a (modes (440 0.5 0)) (mass 0.05) (hardness 1e6) (gains impact 1 0 0.5 1e9))\n"
                       "(body b (modes (90 0.1 1)) (mass 5) (gain 0))\n"
                       "(at 0.01 (impact a b (impulse 0.002)))\n",
                       &n, NULL);
    double sum = 0;
    for (long i = 0; i < n; i++)
        sum += y[i];
    printf("direct gain: sum %.12g, want %.12g\n", sum, 0.5 * 0.002 * FS);
    assert_true(fabs(sum - 0.5 * 0.002 * FS) < 1e-9 * 0.5 * 0.002 * FS);
    free(y);
    /* an audio segment as a relief: a sine of 100 samples a period, one
     * sample every 0.01 mm, read at 0.5 m/s: 500 Hz */
    double seg[1000];
    for (int i = 0; i < 1000; i++)
        seg[i] = sin(2 * M_PI * i / 100.0);
    char wav[256];
    snprintf(wav, sizeof wav, "%s/seg.wav", g_dir);
    assert_int_equal(wdrt_wav_write(wav, 1, 48000, seg, 1000), WDRT_OK);
    y = render("(length 0.5) (sleep off)\n"
               "(body puck (modes (700 0.05 1)) (mass 0.2) (gain 0) (relief none))\n"
               "(body table (modes (10 0.05 0)) (mass 20) (relief \"seg.wav\" 0.00001) (slip 20000) (roll 20000)\n"
               "  (gains contact 1 0 1 1e9))\n"
               "(at 0.0 (contact puck table (force 1) (slip 0.5) (until 0.5)))\n",
               &n, NULL);
    int zc = 0;
    for (long i = (long)(0.1 * FS); i < (long)(0.4 * FS); i++)
        zc += (y[i] > 0) != (y[i - 1] > 0);
    printf("segment relief: %d crossings in 0.3 s (500 Hz: 300)\n", zc);
    assert_true(abs(zc - 300) <= 2);
    free(y);
    /* a body switched off is not heard (the C API) */
    wdrt_bodies_config bc = wdrt_bodies_config_init(FS);
    wdrt_bodies *h;
    assert_int_equal(wdrt_bodies_new(&bc, &h), WDRT_OK);
    wdrt_mode m1[1] = {{440, 0.5, 1}}, m2[1] = {{90, 0.1, 0}};
    wdrt_body b = wdrt_body_init();
    b.modes = m1, b.nmodes = 1;
    assert_int_equal(wdrt_bodies_add(h, &b), 0);
    b.modes = m2;
    assert_int_equal(wdrt_bodies_add(h, &b), 1);
    wdrt_pool_config pc[2];
    wdrt_bodies_pools(h, pc, 0);
    wdrt_engine_config ec = wdrt_engine_config_init(FS, 1, 2, pc);
    wdrt_bodies_attach(h, &ec);
    wdrt_engine *e;
    assert_int_equal(wdrt_engine_init(&ec, NULL, &e), WDRT_OK);
    assert_int_equal(wdrt_bodies_enable(h, 0, 0, 0), WDRT_OK);
    assert_int_equal(wdrt_bodies_impact(h, 100, 0, 1, 0.01, 0, 0), WDRT_OK);
    assert_int_equal(wdrt_bodies_enable(h, 9600, 0, 1), WDRT_OK);
    assert_int_equal(wdrt_bodies_impact(h, 9700, 0, 1, 0.01, 0, 0), WDRT_OK);
    double out[12000];
    for (long i = 0; i < 12000; i += 64)
        wdrt_engine_process(e, out + i, (uint32_t)(12000 - i < 64 ? 12000 - i : 64));
    double off = 0, on = 0;
    for (long i = 0; i < 9600; i++)
        off = fmax(off, fabs(out[i]));
    for (long i = 9700; i < 12000; i++)
        on = fmax(on, fabs(out[i]));
    printf("enable: off %.3g, on %.3g\n", off, on);
    assert_true(off == 0 && on > 1e-4);
    wdrt_engine_uninit(e, NULL);
    wdrt_bodies_free(h);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_impact_as_world_alone), cmocka_unit_test(test_sleep_and_wake),
        cmocka_unit_test(test_shared_resonator),      cmocka_unit_test(test_placed_body),
        cmocka_unit_test(test_contact_curves),        cmocka_unit_test(test_body_errors),
        cmocka_unit_test(test_voice_body),            cmocka_unit_test(test_c_api),
        cmocka_unit_test(test_mode_limit),            cmocka_unit_test(test_gains_segment_enable),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
