/*
 * test_scene.c - scenes (.wds): a scene with one voice renders bit for bit
 * what `wdc --render --events` renders (a param that redesigns the
 * voice posted with its design); bin/wdrt compiles and caches
 * voices (also with two renders at once); a scene without length lasts
 * until it has rung down; curves drive gains; every scene error with its
 * position; and the reader fuzzed.
 */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>

#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "testlib.h"

static tl_voice g_pm, g_mallet;

/* A render's sink that keeps the frames of a mono scene, up to cap. */
typedef struct collected {
    double *y;
    long n, cap;
    int runs;
} collected;

static int collect(const double *frames, long n, int nch, void *user) {
    collected *c = user;
    if (nch != 1 || c->n + n > c->cap)
        return 1;
    memcpy(c->y + c->n, frames, sizeof(double) * (size_t)n);
    c->n += n;
    c->runs++;
    return 0;
}
static char g_dir[64], g_cwd[PATH_MAX];

static int setup(void **s) {
    (void)s;
    if (!getcwd(g_cwd, sizeof g_cwd))
        return -1;
    strcpy(g_dir, "/tmp/wdrt-scene.XXXXXX");
    if (!mkdtemp(g_dir))
        return -1;
    if (tl_voice_build("netlists/piano_mid.wdn", 0, &g_pm) != 0)
        return -1;
    return tl_voice_build("netlists/mallet_plate.wdn", 0, &g_mallet);
}

static int teardown(void **s) {
    (void)s;
    tl_voice_free(&g_pm);
    tl_voice_free(&g_mallet);
    char cmd[256];
    snprintf(cmd, sizeof cmd, "rm -rf %s", g_dir);
    return system(cmd) == 0 ? 0 : -1;
}

static const char *write_file(const char *name, const char *text) { return tl_write_file(g_dir, name, text); }


/* A scene with piano_mid struck three times, one param stepped, against
 * the same events through wdc --render --events --csv (17 digits: every
 * double exactly). */
static void test_matches_wdc(void **s) {
    (void)s;
    char text[8192];
    snprintf(text, sizeof text,
             "; piano_mid struck three times\n"
             "(rate 48k) (length 1.5)\n"
             "(voice p \"%s/netlists/piano_mid.wdn\")\n"
             "(at 0.3 (strike p (v h1 2) (x h1 -1m) (v h2 2) (x h2 -1m) (v h3 2) (x h3 -1m)))\n"
             "(at 0.61 (set p hit 0.2) (set p detune 2))\n"
             "(at 0.9001 (strike p (v h2 4.5) (x h2 -1m)))\n",
             g_cwd);
    const char *scene = strdup(write_file("a.wds", text));
    write_file("a.events", "0.3 ic v(h1)=2 x(h1)=-1m v(h2)=2 x(h2)=-1m v(h3)=2 x(h3)=-1m\n"
                           "0.61 set hit 0.2\n0.61 set detune 2\n0.9001 ic v(h2)=4.5 x(h2)=-1m\n");
    char cmd[8 * PATH_MAX];
    snprintf(cmd, sizeof cmd,
             "bin/wdc netlists/piano_mid.wdn -o %s/v --render %s/b.wav --csv %s/b.csv --events %s/a.events "
             "--seconds 1.5 >/dev/null",
             g_dir, g_dir, g_dir, g_dir);
    assert_int_equal(tl_system(cmd), 0);
    char err[2048] = "";
    wdrt_scene *sc;
    assert_int_equal(wdrt_scene_load(scene, &sc, err, sizeof err), WDRT_OK);
    assert_int_equal(wdrt_scene_nvoices(sc), 1);
    assert_int_equal(wdrt_scene_bind(sc, 0, g_pm.cls, err, sizeof err), WDRT_OK);
    double *y, rate;
    long n;
    int nch;
    wdrt_engine_stats st;
    wdrt_render_opts o = {0};
    o.nosleep = 1;
    assert_int_equal(wdrt_scene_render(sc, &o, &y, &n, &nch, &rate, &st), WDRT_OK);
    assert_int_equal(n, 72000);
    assert_int_equal(nch, 1);
    assert_true(rate == 48000);
    /* two strikes, two sets, one design: detune moves the strings' loops
     * (WDV_PARAM_DESIGN), so the scene posts it with the design made on
     * its own thread (wdrt_engine_set_prepared: the set and the design's
     * install); hit only moves the hammers' taps, a plain set at its
     * frame (WDV_PARAM_STEP).  The render is still bit for bit wdc's,
     * which designs in the block */
    assert_int_equal((int)st.events, 5);
    assert_int_equal((int)st.designs, 1);
    char csv[PATH_MAX];
    snprintf(csv, sizeof csv, "%s/b.csv", g_dir);
    FILE *f = fopen(csv, "r");
    assert_non_null(f);
    long i = 0, differ = 0;
    double a, b;
    while (fscanf(f, "%lf,%lf", &a, &b) == 2) {
        assert_true(i < n);
        differ += y[i] != a;
        i++;
    }
    fclose(f);
    assert_int_equal(i, n);
    assert_int_equal(differ, 0);
    /* with sleep on (the default) too: piano_mid never falls quiet here */
    free(y);
    assert_int_equal(wdrt_scene_render(sc, NULL, &y, &n, &nch, &rate, &st), WDRT_OK);
    assert_int_equal((int)st.sleeps, 0);
    /* through a sink the same frames come, bit for bit, in runs, and none
     * is kept; a sink that fails stops the render */
    collected c = {calloc((size_t)n + 1, sizeof(double)), 0, n, 0};
    assert_non_null(c.y);
    wdrt_render_opts so = {0};
    so.sink = collect;
    so.sink_user = &c;
    double *none = (double *)1;
    long ns;
    assert_int_equal(wdrt_scene_render(sc, &so, &none, &ns, &nch, &rate, &st), WDRT_OK);
    assert_null(none);
    assert_int_equal(ns, n);
    assert_int_equal(c.n, n);
    assert_true(c.runs > 1);
    assert_memory_equal(c.y, y, sizeof(double) * (size_t)n);
    c.n = 0, c.cap = 1000; /* fails past its room */
    assert_int_equal(wdrt_scene_render(sc, &so, &none, &ns, &nch, &rate, &st), WDRT_IO);
    free(c.y);
    free(y);
    wdrt_scene_free(sc);
    free((void *)scene);
}

/* bin/wdrt: two renders at once into an empty cache both succeed and
 * agree; the second render of the scene finds the voice cached. */
static void test_cli_cache(void **s) {
    (void)s;
    char text[8192];
    snprintf(text, sizeof text,
             "(length 0.5) (output stereo)\n"
             "(voice m \"%s/netlists/mallet_plate.wdn\" (pool 4) (pan -0.5))\n"
             "(at 0.1 (play m (strike (v m 1) (x m -0.2m))))\n"
             "(at 0.2 (play m (gain 0.5) (set hard 2) (strike (v m 2) (x m -0.2m))))\n",
             g_cwd);
    write_file("c.wds", text);
    char cmd[8 * PATH_MAX];
    snprintf(cmd, sizeof cmd,
             "export WDRT_CACHE=%s/cache; bin/wdrt render %s/c.wds -o %s/c1.wav --quiet & "
             "bin/wdrt render %s/c.wds -o %s/c2.wav --quiet; r=$?; wait $!; exit $(( r + $? ))",
             g_dir, g_dir, g_dir, g_dir, g_dir);
    assert_int_equal(tl_system(cmd), 0);
    snprintf(cmd, sizeof cmd, "cmp -s %s/c1.wav %s/c2.wav", g_dir, g_dir);
    assert_int_equal(tl_system(cmd), 0);
    snprintf(cmd, sizeof cmd, "test $(ls %s/cache | grep -vc tmp) -eq 1", g_dir);
    assert_int_equal(tl_system(cmd), 0);
    int nch;
    double fs, *fr;
    long nf;
    snprintf(cmd, sizeof cmd, "%s/c1.wav", g_dir);
    assert_int_equal(wdrt_wav_read(cmd, &nch, &fs, &fr, &nf), WDRT_OK);
    assert_int_equal(nch, 2);
    assert_int_equal(nf, 24000);
    /* panned left: the left channel louder; silent before the first note */
    double l = 0, r = 0;
    for (long i = 0; i < nf; i++) {
        if (i < 4800)
            assert_true(fr[2 * i] == 0 && fr[2 * i + 1] == 0);
        l += fr[2 * i] * fr[2 * i], r += fr[2 * i + 1] * fr[2 * i + 1];
    }
    assert_true(l > 2 * r && r > 0);
    free(fr);
    /* errors: a missing netlist, a bad option, a scene error */
    snprintf(cmd, sizeof cmd, "bin/wdrt render %s/c.wds --frobnicate 2>/dev/null", g_dir);
    assert_int_equal(tl_system(cmd), 2);
    /* a usage error prints the error and the synopsis, not the whole help */
    snprintf(cmd, sizeof cmd, "bin/wdrt render %s/c.wds --frobnicate 2>&1 | grep -q \"unknown option '--frobnicate'\"",
             g_dir);
    assert_int_equal(tl_system(cmd), 0);
    snprintf(cmd, sizeof cmd, "bin/wdrt render %s/c.wds --frobnicate 2>&1 | grep -q '^usage: wdrt render'", g_dir);
    assert_int_equal(tl_system(cmd), 0);
    snprintf(cmd, sizeof cmd, "bin/wdrt render %s/c.wds --frobnicate 2>&1 | grep -q '^exit status'", g_dir);
    assert_int_equal(tl_system(cmd), 1);
    write_file("bad.wds", "(voice m \"nowhere.wdn\")\n");
    snprintf(cmd, sizeof cmd, "WDRT_CACHE=%s/cache bin/wdrt render %s/bad.wds -o %s/x.wav 2>/dev/null", g_dir,
             g_dir, g_dir);
    assert_int_equal(tl_system(cmd), 1);
    assert_int_equal(tl_system("bin/wdrt --help >/dev/null"), 0);
    /* a device or a FIFO is refused at once, for each reader (timeout: 124) */
    assert_int_equal(tl_system("timeout 60 bin/wdrt render /dev/zero 2>/dev/null"), 1);
    assert_int_equal(tl_system("timeout 60 bin/wdrt tree /dev/zero 2>/dev/null"), 1);
    assert_int_equal(tl_system("timeout 60 bin/wdrt complex /dev/zero 2>/dev/null"), 1);
    /* lengths past a day, or past what a WAV file holds, are refused before rendering */
    write_file("len.wds", "(body b (modes (440 1 1)) (mass 1) (pos 0 0 0))\n");
    snprintf(cmd, sizeof cmd, "bin/wdrt render %s/len.wds -o %s/x.wav --seconds 1e30 2>/dev/null", g_dir, g_dir);
    assert_int_equal(tl_system(cmd), 2);
    snprintf(cmd, sizeof cmd, "bin/wdrt render %s/len.wds -o %s/x.wav --seconds 30000 2>&1 | grep -q "
             "'too long for a WAV file, which holds at most 4 GiB: 22369 s of 1 channel at 48000 Hz'", g_dir, g_dir);
    assert_int_equal(tl_system(cmd), 0);
    snprintf(cmd, sizeof cmd, "test ! -e %s/x.wav", g_dir);
    assert_int_equal(tl_system(cmd), 0);
    assert_int_equal(tl_system("bin/wdrt tree '(sin 1)' -o /dev/null --seconds 50000 2>/dev/null"), 2);
    write_file("dev.wds", "(body b (modes \"/dev/zero\") (mass 1) (pos 0 0 0))\n");
    snprintf(cmd, sizeof cmd, "timeout 60 bin/wdrt render %s/dev.wds -o %s/x.wav 2>&1 | grep -q "
             "\"cannot read the modes '/dev/zero': not a regular file\"", g_dir, g_dir);
    assert_int_equal(tl_system(cmd), 0);
}

/* A string too short for its filters at the scene's rate is an error at
 * the string (wdc --check --rate, once per rate for a cached voice); at
 * 4 kHz a 3 kHz string rendered detuned without a word. */
static void test_cli_rate_for_strings(void **s) {
    (void)s;
    write_file("hi.wdn", ".voice hi\n.domain mechanical\n.input f\n"
                         "string S1 0 0 L=0.3 f0=3000 mu=1m t60=1 taps=p@0.2,o@0.8\nforce F1 p 0 f\n"
                         ".output vel v(o)\n.end\n");
    write_file("lo.wds", "(rate 4000) (length 0.05)\n(voice h \"hi.wdn\")\n");
    write_file("ok.wds", "(rate 48000) (length 0.05)\n(voice h \"hi.wdn\")\n");
    char cmd[8 * PATH_MAX];
    for (int k = 0; k < 2; k++) { /* the second time from the cache */
        snprintf(cmd, sizeof cmd, "WDRT_CACHE=%s/cache bin/wdrt render %s/lo.wds -o %s/x.wav 2>&1 | grep -q "
                 "\"hi.wdn:4:8: error: string 'S1' is too short for its filters at 4000 Hz: its loop holds 1.33 "
                 "samples\"", g_dir, g_dir, g_dir);
        assert_int_equal(tl_system(cmd), 0);
        snprintf(cmd, sizeof cmd, "WDRT_CACHE=%s/cache bin/wdrt render %s/lo.wds -o %s/x.wav 2>/dev/null", g_dir,
                 g_dir, g_dir);
        assert_int_equal(tl_system(cmd), 1);
        snprintf(cmd, sizeof cmd, "WDRT_CACHE=%s/cache bin/wdrt render %s/ok.wds -o %s/x.wav --quiet", g_dir, g_dir,
                 g_dir);
        assert_int_equal(tl_system(cmd), 0);
    }
    /* and a tree's voice node at the tree's rate */
    write_file("hi.tt", "(* 0.1 (voice \"hi.wdn\" (in (noise))))\n");
    snprintf(cmd, sizeof cmd, "WDRT_CACHE=%s/cache bin/wdrt tree %s/hi.tt --rate 4000 -o %s/x.wav 2>/dev/null", g_dir,
             g_dir, g_dir);
    assert_int_equal(tl_system(cmd), 1);
}

/* A param event that raises a string's pitch past what the scene's rate
 * can tune is an error at the param (the voice's tuning, checked before
 * the render), where it played out of tune: f0 = 3000 at 8 kHz, with the
 * same voice at f0 = 1000 fine; at 48 kHz both play. */
static void test_cli_pitch_for_rate(void **s) {
    (void)s;
    write_file("pf.wdn", ".voice pf\n.domain mechanical\n.input f\n.param f0 1000 min=20 max=5000 unit=Hz\n"
                         "string S1 0 0 L=0.3 f0={f0} mu=1m t60=1 taps=p@0.2,o@0.8\nforce F1 p 0 f\n"
                         ".output vel v(o)\n.end\n");
    write_file("pf8.wds", "(rate 8000) (length 0.05)\n(voice h \"pf.wdn\" (pool 2))\n"
                          "(at 0.01 (play h (set f0 1000)))\n(at 0.02 (play h (set f0 3000)))\n");
    write_file("pf48.wds", "(rate 48000) (length 0.05)\n(voice h \"pf.wdn\" (pool 2))\n"
                           "(at 0.01 (play h (set f0 1000)))\n(at 0.02 (play h (set f0 3000)))\n");
    char cmd[8 * PATH_MAX];
    snprintf(cmd, sizeof cmd, "WDRT_CACHE=%s/cache bin/wdrt render %s/pf8.wds -o %s/x.wav 2>/dev/null", g_dir, g_dir,
             g_dir);
    assert_int_equal(tl_system(cmd), 1);
    snprintf(cmd, sizeof cmd, "WDRT_CACHE=%s/cache bin/wdrt render %s/pf8.wds -o %s/x.wav 2>&1 | grep -q "
             "\"pf8.wds:4:23: error: with f0 = 3000, a string or tube of voice h cannot be tuned at 8000 Hz: its "
             "loop is too short for its filters there, and would play out of tune (lower it, or raise the rate)\"",
             g_dir, g_dir, g_dir);
    assert_int_equal(tl_system(cmd), 0);
    snprintf(cmd, sizeof cmd, "WDRT_CACHE=%s/cache bin/wdrt render %s/pf8.wds -o %s/x.wav 2>&1 | grep -q "
             "'f0 = 1000'", g_dir, g_dir, g_dir);
    assert_int_equal(tl_system(cmd), 1);
    snprintf(cmd, sizeof cmd, "WDRT_CACHE=%s/cache bin/wdrt render %s/pf48.wds -o %s/x.wav --quiet", g_dir, g_dir,
             g_dir);
    assert_int_equal(tl_system(cmd), 0);
}

/* Without (length), a scene lasts until its last event has rung down:
 * past the last event, ending in silence, and soon after it falls quiet. */
static void test_rings_down(void **s) {
    (void)s;
    char text[8192];
    snprintf(text, sizeof text,
             "(voice m \"%s/netlists/mallet_plate.wdn\" (pool 2))\n"
             "(at 0.25 (play m (strike (v m 1.5) (x m -0.2m))))\n",
             g_cwd);
    const char *scene = write_file("r.wds", text);
    char err[2048];
    wdrt_scene *sc;
    assert_int_equal(wdrt_scene_load(scene, &sc, err, sizeof err), WDRT_OK);
    assert_int_equal(wdrt_scene_bind(sc, 0, g_mallet.cls, err, sizeof err), WDRT_OK);
    double *y, rate;
    long n;
    int nch;
    assert_int_equal(wdrt_scene_render(sc, NULL, &y, &n, &nch, &rate, NULL), WDRT_OK);
    print_message("rings down: %.2f s\n", n / rate);
    assert_true(n > 12000 + 4800 && n < 48000 * 10);
    double tail = 0, pk = 0;
    for (long i = 0; i < n; i++) {
        pk = fmax(pk, fabs(y[i]));
        if (i > n - 4800)
            tail = fmax(tail, fabs(y[i]));
    }
    assert_true(tail < 1e-5 && pk > 1e-2);
    assert_true(y[n - 1] == 0);
    free(y);
    wdrt_scene_free(sc);
}

/* A gain curve on a standing voice: the output is the voice's own render
 * times the curve, linear between keys. */
static void test_gain_curve(void **s) {
    (void)s;
    char text[8192];
    snprintf(text, sizeof text,
             "(length 0.5) (sleep off)\n"
             "(voice m \"%s/netlists/mallet_plate.wdn\" (gain (curve (0 1) (0.1 1) (0.3 0.25))))\n",
             g_cwd);
    const char *scene = write_file("g.wds", text);
    char err[2048];
    wdrt_scene *sc;
    assert_int_equal(wdrt_scene_load(scene, &sc, err, sizeof err), WDRT_OK);
    assert_int_equal(wdrt_scene_bind(sc, 0, g_mallet.cls, err, sizeof err), WDRT_OK);
    double *y, rate;
    long n;
    int nch;
    assert_int_equal(wdrt_scene_render(sc, NULL, &y, &n, &nch, &rate, NULL), WDRT_OK);
    const wdv_class *c = g_mallet.cls;
    void *st = tl_state_new(c, 48000);
    double **o = tl_bufs_new(c->n_outputs, n);
    wdrt_render(c, st, NULL, o, n, 64);
    double pk = 0, err2 = 0;
    for (long i = 0; i < n; i++) {
        double t = i / 48000.0, g = t < 0.1 ? 1 : t > 0.3 ? 0.25 : 1 - 0.75 * (t - 0.1) / 0.2;
        pk = fmax(pk, fabs(o[0][i]));
        err2 = fmax(err2, fabs(y[i] - g * o[0][i]));
    }
    print_message("gain curve: %.1f dB against the curve applied sample by sample\n", tl_db(err2 / pk));
    /* the gain moves in linear ramps between block frames: its error
     * against the exact curve is below one block's rounding of the key
     * times (key at 0.1 s = frame 4800 = 75 blocks: on the grid) */
    assert_true(err2 <= 1e-12 * pk);
    tl_bufs_free(o, c->n_outputs);
    tl_state_free(st);
    free(y);
    wdrt_scene_free(sc);
}

/* A complex placed 343 m away with no distance model and no air is heard
 * as it sounds, exactly one second (48000 frames) late. */
static void test_placed_complex(void **s) {
    (void)s;
    double *y[2];
    long n[2];
    for (int placed = 0; placed < 2; placed++) {
        char text[8192];
        snprintf(text, sizeof text,
                 "(distance none) (air off)\n"
                 "(complex k \"%s/scenes/sphere.cx\" (tempo 4)%s)\n",
                 g_cwd, placed ? " (pos 0 343 0)" : "");
        const char *scene = write_file("k.wds", text);
        char err[2048];
        wdrt_scene *sc;
        assert_int_equal(wdrt_scene_load(scene, &sc, err, sizeof err), WDRT_OK);
        double rate;
        int nch;
        assert_int_equal(wdrt_scene_render(sc, NULL, &y[placed], &n[placed], &nch, &rate, NULL), WDRT_OK);
        assert_int_equal(nch, 1);
        wdrt_scene_free(sc);
    }
    assert_true(n[1] >= n[0] + 48000 - 64);
    long differ = 0;
    for (long i = 0; i < n[0]; i++)
        differ += y[1][i + 48000] != y[0][i];
    for (long i = 0; i < 48000; i++)
        differ += y[1][i] != 0;
    assert_int_equal(differ, 0);
    free(y[0]);
    free(y[1]);
}

/* ---- errors ---- */

typedef struct bad {
    const char *text;
    const char *msg; /* the first line after "PATH:" */
} bad;

static const bad g_load_errors[] = {
    {"(rate 48k) (voyce p \"x.wdn\")", "1:13: error: unknown form 'voyce'; did you mean 'voice'?"},
    {"(rate)", "1:1: error: expected (rate HZ)"},
    {"(rate \"fast\")", "1:7: error: expected a number, found a string"},
    {"(rate 10)", "1:7: error: a rate must lie between 1 kHz and 768 kHz"},
    {"(length -1)", "1:9: error: a length must be positive and at most a day"},
    {"(output quad)", "1:9: error: expected mono, stereo or binaural"},
    {"(voice m \"x.wdn\" (pool 2))\n(at 0.1 (play m (gain 1e300)))",
     "2:23: error: a gain is a factor of at most 10^6 (+120 dB) in size"},
    {"(voice m \"x.wdn\")\n(at 0.1 (gain m (curve (0 1) (1 1e7))))",
     "2:33: error: a gain is a factor of at most 10^6 (+120 dB) in size"},
    {"(voice m \"x.wdn\" (gain -3e6))", "1:24: error: a gain is a factor of at most 10^6 (+120 dB) in size"},
    {"(output binaural \"nowhere.sofa\")", "1:18: error: cannot read the HRTF file"},
    {"(room r (box 0 0 0 1 1 1) (reflections 1))", "1:1: error: a room needs its (box ...) and its (t60 LOW HIGH)"},
    {"(room r (box 0 0 0 1 -1 1) (t60 1 1))", "1:9: error: a box runs from its lower corner to its upper one, within 10 km"},
    {"(room r (box 0 0 0 1 1 1) (t60 1 1) (reflections 5))", "1:50: error: reflections of order 0 to 3"},
    {"(voice p \"x.wdn\")\n(voice p \"y.wdn\")", "2:8: error: a voice named 'p' is already in the scene"},
    {"(voice p x.wdn)", "1:10: error: expected the netlist's file name in double quotes, found a symbol"},
    {"(voice p \"x.wdn\" (pool 0))", "1:24: error: a pool holds 1 to 100000 voices"},
    {"(voice p \"x.wdn\" (pan 2))", "1:23: error: pan lies between -1 (left) and 1 (right)"},
    {"(voice p \"x.wdn\" (gian 2))", "1:19: error: unknown property 'gian'; did you mean 'gain'?"},
    {"(voice p \"x.wdn\")\n(at 1 (strike q (v h 1)))", "2:15: error: unknown voice 'q'; did you mean 'p'?"},
    {"(voice p \"x.wdn\")\n(at -1 (stop p))", "2:5: error: an event's time is in seconds from the start, at most a day"},
    {"(voice p \"x.wdn\")\n(at 1 (strike p (w h 1)))", "2:17: error: expected (v NODE VALUE) or (x NODE VALUE)"},
    {"(voice p \"x.wdn\")\n(at 1 (strike p))", "2:7: error: a strike needs at least one (v NODE VALUE) or (x NODE VALUE)"},
    {"(voice p \"x.wdn\")\n(at 1 (play p (strike (v h 1))))",
     "2:13: error: 'p' is a single voice: play takes a voice with (pool N)"},
    {"(voice p \"x.wdn\" (pool 3))\n(at 1 (play p (set f0 (curve (0 1) (1 2)))))",
     "2:23: error: a curve is not allowed here"},
    {"(voice p \"x.wdn\")\n(at 1 (set p g (curve (0 1) (0.5 2) (0.2 3))))",
     "2:38: error: keys of a curve must come in time order"},
    {"(voice p \"x.wdn\")\n(at 1 (strik p))", "2:8: error: unknown event 'strik'; did you mean 'strike'?"},
    {"(voice p \"x.wdn\")\n(at 1 (stop p p))", "2:7: error: expected (stop NAME)"},
    {"(voice p \"x.wdn\" (pos 0 1))", "1:18: error: expected (pos X Y Z) or (pos (path (TIME X Y Z)...))"},
    {"(voice p \"x.wdn\" (pos (path (0 1 2 3) (1 1 2))))", "1:39: error: expected a key (TIME X Y Z)"},
    {"(voice p \"x.wdn\" (pos (path (1 0 0 0) (0.5 1 2 3))))", "1:40: error: keys of a path must come in time order"},
    {"(distance inverso)", "1:11: error: unknown distance model 'inverso'; did you mean 'inverse'?"},
    {"(distance linear (ref 10) (max 5))", "1:1: error: the maximum distance must be beyond the reference distance"},
    {"(distance linear (reff 10))", "1:18: error: expected (ref M), (max M) or (rolloff R)"},
    {"(distance linear (ref 0))", "1:23: error: a distance is in m, above 0 and at most 10^6"},
    {"(distance linear (rolloff 200))", "1:27: error: a rolloff lies between 0 and 100"},
    {"(c 0)", "1:4: error: the speed of sound lies between 1 and 100000 m/s"},
    {"(air maybe)", "1:6: error: expected on or off"},
    {"(listener (facing 0 0 1))", "1:11: error: a listener faces some way across the ground (x or y not 0)"},
    {"(wall w (from 0 0) (to 1 1))", "1:1: error: expected (wall NAME (from X Y) (to X Y) (loss DB))"},
    {"(wall w (from 0 0) (to 1) (loss 3))", "1:20: error: expected (to X Y)"},
    {"(budget 0)", "1:9: error: a budget is a share of one core (0.5 = half), above 0 and at most 64"},
    {"42", "1:1: error: expected a form such as (voice ...) or (at ...)"},
    {"(voice p \"x.wdn\"", "1:17: error: expected ')' to close '(' at 1:1"}, /* the reader's */
};

static void check_error(const char *path, const char *err, const char *msg) {
    char want[4096 + 1024];
    snprintf(want, sizeof want, "%s:%s", path, msg);
    if (strncmp(err, want, strlen(want)) != 0)
        fail_msg("expected \"%s\", got \"%s\"", want, err);
}

static void test_load_errors(void **s) {
    (void)s;
    for (size_t i = 0; i < sizeof g_load_errors / sizeof *g_load_errors; i++) {
        const char *path = strdup(write_file("e.wds", g_load_errors[i].text));
        char err[2048] = "";
        wdrt_scene *sc = NULL;
        assert_int_equal(wdrt_scene_load(path, &sc, err, sizeof err), WDRT_SYNTAX);
        assert_null(sc);
        check_error(path, err, g_load_errors[i].msg);
        /* the source line and a caret follow */
        assert_non_null(strchr(err, '^'));
        free((void *)path);
    }
    /* a file that is not an HRTF is an error at its name when the scene is
     * read (rendering it freed a pointer never allocated) */
    const char *path = strdup(write_file("e.wds", "(output binaural \"e.wds\") (rate 96k)\n"));
    char err[2048] = "";
    wdrt_scene *sc = NULL;
    assert_int_equal(wdrt_scene_load(path, &sc, err, sizeof err), WDRT_SYNTAX);
    check_error(path, err, "1:18: error: cannot use the HRTF file '");
    assert_non_null(strstr(err, "e.wds': not a SOFA file\n"));
    free((void *)path);
}

/* A binaural scene renders through the HRTF it read when it was loaded,
 * at its own rate, and through one read at the rate asked for otherwise:
 * both ears hear the strike, in the same place in time. */
static void test_binaural_rates(void **s) {
    (void)s;
    const char *path = strdup(write_file("bin.wds", "(output binaural)\n(voice m \"x.wdn\" (pos 1 2 1.7))\n"
                                                    "(at 0.001 (strike m (v m 1) (x m -0.2m)))\n"));
    char err[2048] = "";
    wdrt_scene *sc = NULL;
    assert_int_equal(wdrt_scene_load(path, &sc, err, sizeof err), WDRT_OK);
    assert_int_equal(wdrt_scene_bind(sc, 0, g_mallet.cls, err, sizeof err), WDRT_OK);
    double first[2] = {0, 0};
    for (int k = 0; k < 2; k++) {
        wdrt_render_opts o = {0};
        o.seconds = 0.05;
        o.rate = k ? 96000 : 0;
        double *y, rate;
        long nf;
        int nch;
        assert_int_equal(wdrt_scene_render(sc, &o, &y, &nf, &nch, &rate, NULL), WDRT_OK);
        assert_int_equal(nch, 2);
        assert_true(rate == (k ? 96000 : 48000));
        double e[2] = {0, 0};
        long onset = -1;
        for (long i = 0; i < nf * 2; i++) {
            assert_true(isfinite(y[i]));
            e[i % 2] += y[i] * y[i];
            if (onset < 0 && fabs(y[i]) > 1e-6)
                onset = i / 2;
        }
        assert_true(e[0] > 0 && e[1] > 0 && e[1] > e[0]); /* the source is to the right */
        first[k] = (double)onset / rate;
        free(y);
    }
    /* the sound leaves at 1 ms and travels 2.2 m at 343 m/s: 7.5 ms; the
     * ears' delays differ by under a millisecond */
    assert_true(fabs(first[0] - first[1]) < 1e-3);
    assert_true(first[0] > 0.007 && first[0] < 0.010);
    wdrt_scene_free(sc);
    free((void *)path);
}

static const bad g_bind_errors[] = {
    {"(voice m \"x.wdn\" (param hrad 2))", "1:25: error: unknown param 'hrad'; did you mean 'hard'?"},
    {"(voice m \"x.wdn\" (output v3))", "1:26: error: unknown output 'v3'; did you mean 'v1'?"},
    {"(voice m \"x.wdn\")\n(at 1 (set m hardness 2))", "2:14: error: unknown param 'hardness'"},
    {"(voice m \"x.wdn\")\n(at 1 (strike m (v m 1) (x q 1)))",
     "2:25: error: unknown strike target 'x(q)'"},
    {"(voice m \"x.wdn\" (pool 2))\n(at 1 (play m (set hrd 1)))", "2:20: error: unknown param 'hrd'; did you mean 'hard'?"},
};

static void test_bind_errors(void **s) {
    (void)s;
    for (size_t i = 0; i < sizeof g_bind_errors / sizeof *g_bind_errors; i++) {
        const char *path = strdup(write_file("b.wds", g_bind_errors[i].text));
        char err[2048] = "";
        wdrt_scene *sc = NULL;
        assert_int_equal(wdrt_scene_load(path, &sc, err, sizeof err), WDRT_OK);
        assert_int_equal(wdrt_scene_bind(sc, 0, g_mallet.cls, err, sizeof err), WDRT_SYNTAX);
        check_error(path, err, g_bind_errors[i].msg);
        wdrt_scene_free(sc);
        free((void *)path);
    }
}

/* A param's value past its range binds, with a warning at each place
 * (the voice holds it at the bound); one within it, or a curve, none. */
static void test_bind_warnings(void **s) {
    (void)s;
    const char *path = strdup(write_file("w.wds", "(voice m \"x.wdn\" (param hard 1e9))\n"
                                                  "(at 1 (set m hard 0.01))\n(at 2 (set m hard 2))\n"
                                                  "(at 3 (set m hard (curve (0 1) (1 20))))\n"));
    char err[2048] = "x";
    wdrt_scene *sc = NULL;
    assert_int_equal(wdrt_scene_load(path, &sc, err, sizeof err), WDRT_OK);
    assert_int_equal(wdrt_scene_bind(sc, 0, g_mallet.cls, err, sizeof err), WDRT_OK);
    char want[4096];
    snprintf(want, sizeof want,
             "%s:1:25: warning: hard = 1e+09 lies outside its range [0.1, 10]: the voice holds it at 10\n"
             "  (voice m \"x.wdn\" (param hard 1e9))\n"
             "                          ^\n"
             "%s:2:14: warning: hard = 0.01 lies outside its range [0.1, 10]: the voice holds it at 0.1\n"
             "  (at 1 (set m hard 0.01))\n"
             "               ^\n", path, path);
    assert_string_equal(err, want);
    wdrt_scene_free(sc);
    free((void *)path);
    /* a voice with inputs, which nothing in a scene drives: one that can
     * be struck, and one that cannot and so stays silent */
    static const char *const nets[2] = {"netlists/rc_lowpass.wdn", "netlists/tonestack.wdn"};
    static const char *const says[2] = {": it sounds only when struck", ", and it has nothing to strike: it stays silent"};
    for (int k = 0; k < 2; k++) {
        tl_voice v;
        assert_int_equal(tl_voice_build(nets[k], 0, &v), 0);
        path = strdup(write_file("in.wds", "(length 0.1)\n(voice fx \"x.wdn\")\n"));
        assert_int_equal(wdrt_scene_load(path, &sc, err, sizeof err), WDRT_OK);
        assert_int_equal(wdrt_scene_bind(sc, 0, v.cls, err, sizeof err), WDRT_OK);
        snprintf(want, sizeof want, "%s:2:8: warning: nothing in a scene drives the input 'in' of voice %s%s\n", path,
                 v.cls->name, says[k]);
        assert_non_null(strstr(err, want));
        wdrt_scene_free(sc);
        free((void *)path);
        tl_voice_free(&v);
    }
}

/* ---- fuzz ---- */

static const char *const g_seeds[] = {
    "(rate 48k) (length 2) (output stereo) (budget 0.5)\n"
    "(voice m \"x.wdn\" (pool 8) (param hard 2) (gain 0.5) (pan -0.3) (priority 2) (quiet -90))\n"
    "(voice s \"x.wdn\" (output v2) (gain (curve (0 0) (1 1))))\n"
    "(at 0.1 (play m (gain 0.7) (set hard 3) (strike (v m 1.2) (x m -0.3m))))\n"
    "(at 0.5 (strike s (v m 1) (x m -1m)) (set m hard (curve (0 1) (0.5 4))))\n"
    "(at 0.75 (gain s 0.3) (stop m))\n",
    "; comment\n(voice a \"y.wdn\")(at 0 (strike a (v m 1)))(at 1e-3 (set a hard 1k))",
    "(output stereo) (c 340) (distance linear (ref 1) (max 50) (rolloff 0.5)) (air on)\n"
    "(listener (pos (path (0 0 0 1.7) (0.02 1 0 1.7))) (facing 0 1 0))\n"
    "(wall w (from -3 2) (to 3 2) (loss 12))\n"
    "(voice m \"x.wdn\" (pool 2) (pos 0 5 1))\n"
    "(voice s \"x.wdn\" (pos (path (0 -5 3 1) (0.02 5 3 1))))\n"
    "(at 0.001 (play m (strike (v m 1) (x m -0.2m))))\n",
    "(room r (box -5 -5 0 5 5 3) (t60 0.5 0.3) (ambient (* 0.01 (noise))))\n"
    "(tree s (* g (osc (+ 200 (* 50 (sine (* 3 t)))) saw)) (param g (distance b listener)) (pos 1 2 1))\n"
    "(tree b (* 0 t) (pos (path (0 0 0 0) (0.02 1 1 0))))\n"
    "(tree n (* j (env (0 1) (0.01 0))) (pool 2) (param j (impulse)))\n"
    "(at 0.001 (impact b n (mass 0.1)))\n(at 0.005 (play n (set j 0.2)))\n",
    "(body a (modes (440 0.5 1) (900 0.3 0.5)) (mass 0.05) (relief grid 0.001 0.0005) (pos 0 2 1))\n"
    "(body b (modes (90 0.1 1)) (mass 5) (hardness 1e8))\n(body c (share a))\n"
    "(at 0.001 (impact a b (impulse 0.01) (speed 1 0.2)))\n"
    "(at 0.002 (contact c b (force (curve (0 0) (0.01 1))) (slip 0.3) (roll 0.1) (until 0.015)))\n",
};
#define NSEEDS ((int)(sizeof g_seeds / sizeof *g_seeds))

static int valid_error(const char *path, const char *err) {
    size_t n = strlen(path);
    if (strncmp(err, path, n) != 0 || err[n] != ':')
        return 0;
    int line, col;
    char word[16];
    return sscanf(err + n + 1, "%d:%d: %15s", &line, &col, word) == 3 && line >= 1 && col >= 1 &&
           !strcmp(word, "error:");
}

/* Mutated scenes: each loads, binds and renders a little, or gives a
 * positioned error; nothing crashes or hangs. */
static void fuzz(long iters, uint64_t seed) {
    tl_rng r;
    tl_rng_seed(&r, seed);
    const char *alphabet = "()\"; \n0123456789.-+ekmuvxsetplaygainstrikecurvepool";
    char path[PATH_MAX];
    snprintf(path, sizeof path, "%s/f.wds", g_dir);
    long ok = 0, errs = 0;
    for (long it = 0; it < iters; it++) {
        const char *seedtext = g_seeds[tl_rng_next(&r) % NSEEDS];
        char buf[4096];
        size_t n = strlen(seedtext);
        memcpy(buf, seedtext, n);
        int muts = 1 + (int)(tl_rng_next(&r) % 6);
        for (int m = 0; m < muts; m++) {
            size_t at = n ? tl_rng_next(&r) % n : 0;
            int op = (int)(tl_rng_next(&r) % 4);
            char c = tl_rng_next(&r) % 8 == 0 ? (char)(tl_rng_next(&r) % 256)
                                              : alphabet[tl_rng_next(&r) % strlen(alphabet)];
            if (op == 0 && n + 1 < sizeof buf) {
                memmove(buf + at + 1, buf + at, n - at);
                buf[at] = c, n++;
            } else if (op == 1 && n > 0) {
                memmove(buf + at, buf + at + 1, n - at - 1), n--;
            } else if (op == 2 && n > 0) {
                buf[at] = c;
            } else {
                n = at;
            }
        }
        FILE *f = fopen(path, "wb");
        fwrite(buf, 1, n, f);
        fclose(f);
        char err[4096] = "";
        wdrt_scene *sc = NULL;
        wdrt_result res = wdrt_scene_load(path, &sc, err, sizeof err);
        if (res != WDRT_OK) {
            if (!valid_error(path, err))
                fail_msg("iteration %ld: bad message \"%s\"", it, err);
            errs++;
            continue;
        }
        int bound = 1;
        for (int i = 0; i < wdrt_scene_nvoices(sc) && bound; i++)
            if (wdrt_scene_bind(sc, i, g_mallet.cls, err, sizeof err) != WDRT_OK) {
                if (!valid_error(path, err))
                    fail_msg("iteration %ld: bad message \"%s\"", it, err);
                bound = 0;
            }
        if (bound) {
            wdrt_render_opts o = {0};
            o.seconds = 0.02;
            double *y, rate;
            long nf;
            int nch;
            assert_int_equal(wdrt_scene_render(sc, &o, &y, &nf, &nch, &rate, NULL), WDRT_OK);
            for (long i = 0; i < nf * nch; i++)
                if (!isfinite(y[i]))
                    fail_msg("iteration %ld: sample %ld is not finite; the scene:\n%.*s", it, i, (int)n, buf);
            free(y);
            ok++;
        } else {
            errs++;
        }
        wdrt_scene_free(sc);
    }
    print_message("fuzz: %ld scenes rendered, %ld errors reported\n", ok, errs);
}

/* WDRT_FUZZ_SEED, mixed into the fuzzer's own seed (0 without it). */
static uint64_t fuzz_seed(void) {
    const char *e = getenv("WDRT_FUZZ_SEED");
    return e ? strtoull(e, NULL, 0) : 0;
}

static void test_fuzz(void **s) {
    (void)s;
    const char *e = getenv("WDRT_FUZZ_ITERS");
    fuzz(e ? atol(e) : 1500, 0x5ce4e ^ fuzz_seed());
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_matches_wdc), cmocka_unit_test(test_cli_cache), cmocka_unit_test(test_cli_rate_for_strings),
        cmocka_unit_test(test_cli_pitch_for_rate),   cmocka_unit_test(test_rings_down),
        cmocka_unit_test(test_gain_curve),  cmocka_unit_test(test_load_errors), cmocka_unit_test(test_bind_errors),
        cmocka_unit_test(test_bind_warnings), cmocka_unit_test(test_binaural_rates),
        cmocka_unit_test(test_fuzz),        cmocka_unit_test(test_placed_complex),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
