/*
 * test_treescene.c - timbre trees in scenes: params bound to motion read
 * against the paths they follow (distance, speed, travel, coordinates),
 * impacts whose impulse comes from a mass and a path, notes of pooled
 * trees, trees and their definitions from files, scene errors with their
 * positions, and the schematic that wdrt dot writes.
 *
 * A probe tree outputs a param plainly ((+ (* 0 t) p)), unplaced, so the
 * render is the param's value at every frame: the engine ramps a driven
 * param over each block in 16 steps toward the value the motion has a
 * block later, so a value that moves at rate r (units per second) is
 * within r * (block / 16) / fs of the path's, plus the curvature of the
 * quantity over a block.
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

#include "testlib.h"
#include "wdrt.h"

#define FS 48000.0
#define BLOCK 64

static char g_dir[64];

static int setup(void **s) {
    (void)s;
    return tl_temp_dir(g_dir, "wdrt-treescene");
}

static int teardown(void **s) {
    (void)s;
    tl_remove_dir(g_dir);
    return 0;
}

/* Renders scene text; returns the mono frames (caller frees). */
static double *render(const char *text, long *n) {
    wdrt_scene *s = tl_scene_load(g_dir, "s.wds", text);
    assert_non_null(s);
    assert_int_equal(wdrt_scene_nvoices(s), 0); /* trees need no netlists */
    double *y = NULL, rate;
    int nch;
    assert_int_equal(wdrt_scene_render(s, NULL, &y, n, &nch, &rate, NULL), WDRT_OK);
    assert_int_equal(nch, 1);
    wdrt_scene_free(s);
    return y;
}

static void load_error(const char *text, char *err, size_t len) { tl_scene_error(g_dir, "e.wds", text, err, len); }

static void test_distance_follows_path(void **st) {
    (void)st;
    /* the ball flies from (0 0 0) to (0 10 0) in 1 s: 10 m/s away from the listener at the origin */
    long n;
    double *y = render("(listener (pos 0 0 0)) (length 1.2) (sleep off)\n"
                       "(tree ball (* 0 t) (pos (path (0 0 0 0) (1 0 10 0))))\n"
                       "(tree probe (+ (* 0 t) d) (param d (distance ball listener)))\n",
                       &n);
    double tol = 10.0 * (BLOCK / 16) / FS * 1.0001, worst = 0;
    for (long i = 0; i < (long)FS; i++) {
        double want = 10.0 * (double)i / FS;
        worst = fmax(worst, fabs(y[i] - want));
    }
    printf("distance vs path: worst %.3g m (bound %.3g m)\n", worst, tol);
    assert_true(worst <= tol);
    assert_true(fabs(y[(long)(1.1 * FS)] - 10) < 1e-9); /* held at the path's end */
    free(y);
}

static void test_speed_and_travel(void **st) {
    (void)st;
    /* 10 m/s for 0.5 s, then 2 m/s for 0.5 s */
    long n;
    double *y = render("(length 1.2) (sleep off)\n"
                       "(tree pen (* 0 t) (pos (path (0 0 0 0) (0.5 5 0 0) (1 6 0 0))))\n"
                       "(tree sp (+ (* 0 t) v) (param v (speed pen)))\n",
                       &n);
    /* away from the corner (a block and the difference step) the speed is the segment's */
    long guard = 2 * BLOCK + 10;
    for (long i = guard; i < (long)(0.5 * FS) - guard; i += 97)
        assert_true(fabs(y[i] - 10) < 1e-6);
    for (long i = (long)(0.5 * FS) + guard; i < (long)FS - guard; i += 97)
        assert_true(fabs(y[i] - 2) < 1e-6);
    free(y);
    y = render("(length 1.2) (sleep off)\n"
               "(tree pen (* 0 t) (pos (path (0 0 0 0) (0.5 5 0 0) (1 6 0 0))))\n"
               "(tree tr (+ (* 0 t) s) (param s (travel pen)))\n",
               &n);
    double tol = 10.0 * (BLOCK / 16) / FS * 1.0001, worst = 0;
    for (long i = 0; i < (long)FS; i++) {
        double t = (double)i / FS, want = t < 0.5 ? 10 * t : 5 + 2 * (t - 0.5);
        /* near the corner the ramp toward the next block's value bends: one block of 10 m/s at most */
        double bound = fabs(t - 0.5) < 2.0 * BLOCK / FS ? 10.0 * BLOCK / FS : tol;
        worst = fmax(worst, fabs(y[i] - want) / bound);
    }
    printf("travel vs path: worst %.3g of its bound\n", worst);
    assert_true(worst <= 1);
    free(y);
}

static void test_coordinates(void **st) {
    (void)st;
    long n;
    double *y = render("(length 0.5) (sleep off)\n"
                       "(tree b (* 0 t) (pos (path (0 1 2 3) (0.5 1 2 -2))))\n"
                       "(tree zt (+ (* 0 t) z) (param z (z b)))\n",
                       &n);
    double tol = 10.0 * (BLOCK / 16) / FS * 1.0001;
    for (long i = 0; i < n; i += 7)
        assert_true(fabs(y[i] - (3 - 10.0 * (double)i / FS)) <= tol);
    free(y);
}

static void test_impact_impulse_from_path(void **st) {
    (void)st;
    /* falls at 3 m/s, leaves upward at 2 m/s: a jump of 5 m/s; 0.1 kg: 0.5 N s */
    long n;
    double *y = render("(length 1) (sleep off)\n"
                       "(tree ball (* 0 t) (pos (path (0 0 0 1.5) (0.5 0 0 0) (1 0 0 1))))\n"
                       "(tree hit (+ (* 0 t) j (* 1000 d)) (pool 2) (pos 0 0 0)\n"
                       "  (param j (impulse)) (param d (distance ball hit)))\n"
                       "(at 0.5 (impact ball hit (mass 0.1)))\n"
                       "(at 0.75 (impact ball hit (impulse 0.25)))\n",
                       &n);
    /* the hit is placed at the origin and the listener stands at the default
     * (0 0 0): it is heard as it sounds, delayed by d/c = 0 */
    long f = (long)(0.5 * FS);
    assert_true(fabs(y[f - 10]) < 1e-12); /* nothing before */
    double want = 0.5 + 1000 * 0.0;      /* the ball is at the drum when it lands */
    printf("impact from path: %.12f (want %.12f)\n", y[f + 100], want);
    assert_true(fabs(y[f + 100] - want) < 1e-6);
    /* the second note adds its own: 0.25, with the ball 0.5 m up */
    long g = (long)(0.75 * FS);
    assert_true(fabs(y[g + 100] - (0.5 + 0.25 + 1000 * 0.5)) < 1e-6);
    free(y);
}

static void test_note_sets(void **st) {
    (void)st;
    /* a play's set holds from the note's first frame (no ramp from the
     * default), and wins over the param's motion binding */
    long n;
    double *y = render("(length 0.3)\n"
                       "(tree n (+ (* 0 t) a (* 0 (env (0 1) (0.1 1) (0.1 0)))) (pool 2) (param a (impulse)))\n"
                       "(at 0.1 (play n (set a 0.42)))\n",
                       &n);
    long f = (long)llround(0.1 * FS);
    assert_true(fabs(y[f - 1]) < 1e-15);
    assert_true(fabs(y[f] - 0.42) < 1e-15);
    assert_true(fabs(y[f + 1000] - 0.42) < 1e-15);
    free(y);
}

static void test_sleeping_line_silent(void **st) {
    (void)st;
    /* a placed tree that ends and sleeps: its delay line drains to silence,
     * never replaying what it held a lap earlier */
    long n;
    double *y = render("(distance inverse (ref 1) (max 100) (rolloff 1))\n"
                       "(listener (pos 0 0 1.7) (facing 0 1 0))\n"
                       "(tree car (* (env (0 1) (0.5 1) (0.6 0)) (* 0.3 (sine (* 100 t)))) (pos 2 5 0.4))\n",
                       &n);
    double tail = 0;
    for (long i = (long)(0.62 * FS); i < n; i++)
        tail = fmax(tail, fabs(y[i]));
    printf("after the end: peak %.3g over %.3f s\n", tail, (double)n / FS - 0.62);
    assert_true(n > (long)(0.65 * FS));
    assert_true(tail < 1e-12); /* the air filter's tail dies away; the old lap was 0.036 */
    free(y);
}

static void test_tree_from_definitions(void **st) {
    (void)st;
    char dir[128];
    snprintf(dir, sizeof dir, "%s/lib", g_dir);
    char cmd[256];
    snprintf(cmd, sizeof cmd, "mkdir -p %s", dir);
    assert_int_equal(tl_system(cmd), 0);
    tl_write_file(dir, "level.tt", "; a constant level\n(tree level (params (v 0.25)) (+ (* 0 t) v))\n");
    tl_write_file(g_dir, "defs.tt", "(tree twice (params (x 1)) (+ (* 0 t) (* 2 x)))\n");
    long n;
    /* lib/NAME.tt found by itself; an include; params set by the scene and by use */
    double *y = render("(length 0.1) (sleep off)\n(include \"defs.tt\")\n"
                       "(tree a (use level) (param v 0.5))\n"
                       "(tree b (use twice (x 0.125)))\n",
                       &n);
    assert_true(fabs(y[100] - (0.5 + 0.25)) < 1e-12);
    free(y);
}

static void test_pool_notes(void **st) {
    (void)st;
    long n;
    double *y = render("(length 0.5)\n"
                       "(tree blip (* a (env (0 1) (0.1 1) (0.1 0))) (pool 3) (param a 1))\n"
                       "(at 0.1 (play blip (set a 0.5)))\n"
                       "(at 0.15 (play blip (set a 0.25)))\n",
                       &n);
    long f = (long)(0.12 * FS), g = (long)(0.17 * FS), h = (long)(0.3 * FS);
    assert_true(fabs(y[f] - 0.5) < 1e-12);
    assert_true(fabs(y[g] - 0.75) < 1e-12);
    assert_true(fabs(y[h]) < 1e-12);
    free(y);
}

static void test_scene_errors(void **st) {
    (void)st;
    char err[2048];
    load_error("(tree a (+ (* 0 t) lodness) (param loudness 1))\n", err, sizeof err);
    assert_non_null(strstr(err, "e.wds:1:20: error: unknown name 'lodness'; did you mean 'loudness'?"));
    load_error("(tree a (+ (* 0 t) d) (param d (distance bal listener)))\n(tree ball (* 0 t) (pos 0 0 0))\n", err,
               sizeof err);
    assert_non_null(strstr(err, "e.wds:1:42: error: unknown object 'bal'; did you mean 'ball'?"));
    load_error("(tree a (+ (* 0 t) d) (param d (speed b)))\n(tree b (* 0 t))\n", err, sizeof err);
    assert_non_null(strstr(err, "e.wds:1:39: error: 'b' has no position"));
    load_error("(tree a (* 0 t))\n(tree b (* 0 t) (pos 0 0 0))\n(at 1 (impact b a (impulse 1)))\n", err,
               sizeof err);
    assert_non_null(strstr(err, "e.wds:3:17: error: 'a' is not a tree with a (pool N)"));
    load_error("(tree a (sinee t))\n", err, sizeof err);
    assert_non_null(strstr(err, "e.wds:1:10: error: unknown function 'sinee'; did you mean 'sine'?"));
    load_error("(tree a (use nosuch))\n", err, sizeof err);
    assert_non_null(strstr(err, "e.wds:1:14: error: unknown tree 'nosuch'"));
    load_error("(tree a (* 0 t))\n(at 1 (play a))\n", err, sizeof err);
    assert_non_null(strstr(err, "e.wds:2:13: error: 'a' is a single voice"));
    load_error("(tree a (+ (* 0 t) p) (param p 1))\n(at 1 (set a q 2))\n", err, sizeof err);
    assert_non_null(strstr(err, "e.wds:2:14: error: unknown param 'q'"));
}

static void test_room_ambience(void **st) {
    (void)st;
    /* a constant ambience of 0.5 in a 10 m room; the listener walks out
     * through the open side y = 10 at 2.5 m/s and on: inside it hears the
     * ambience as it is, outside at the inverse distance to the room */
    long n;
    double *y = render("(length 4) (sleep off) (air off)\n"
                       "(listener (pos (path (0 5 5 1.7) (4 5 15 1.7))))\n"
                       "(room hall (box 0 0 0 10 10 4) (t60 0.5 0.4) (reflections 0)\n"
                       "  (ambient (+ 0.5 (* 0 t))))\n",
                       &n);
    for (double t = 0.1; t < 1.9; t += 0.05)
        assert_true(fabs(y[(long)(t * FS)] - 0.5) < 1e-12);
    /* the gain follows the listener a block behind at most: 2.5 m/s for a block */
    double worst = 0;
    for (double t = 2.5; t < 3.95; t += 0.01) {
        double d = 2.5 * (t - 2), want = 0.5 / d, step = 0.5 / (d * d) * 2.5 * 2 * BLOCK / FS;
        worst = fmax(worst, fabs(y[(long)(t * FS)] - want) / step);
    }
    printf("ambience outside the room: worst %.3g of its bound\n", worst);
    assert_true(worst <= 1);
    free(y);
}

static void test_dot(void **st) {
    (void)st;
    const char *path = tl_write_file(g_dir, "d.wds",
                                     "(tree ball (* 0 t) (pos (path (0 0 0 1) (1 0 0 0))))\n"
                                     "(tree drum (* l (sine (* 200 t))) (pool 2) (param l (impulse)) (pos 0 0 0))\n"
                                     "(tree mix (importance ((sine (* 300 t)) 0.67 lock) ((noise) 1)))\n"
                                     "(at 1 (impact ball drum (mass 0.1)))\n");
    char err[1024];
    wdrt_scene *s;
    wdrt_result r = wdrt_scene_load(path, &s, err, sizeof err);
    if (r != WDRT_OK)
        fprintf(stderr, "%s", err);
    assert_int_equal(r, WDRT_OK);
    char *buf = NULL;
    size_t len = 0;
    FILE *f = open_memstream(&buf, &len);
    wdrt_scene_dot(s, f);
    fclose(f);
    wdrt_scene_free(s);
    assert_non_null(strstr(buf, "digraph scene {"));
    assert_non_null(strstr(buf, "cluster_t1"));           /* the drum's expression */
    assert_non_null(strstr(buf, "label=\"importance\""));  /* the mix node */
    assert_non_null(strstr(buf, "label=\"w1 lock\""));     /* its locked weight */
    assert_non_null(strstr(buf, "1 impacts"));
    assert_non_null(strstr(buf, "-> space"));              /* placed: through propagation */
    assert_non_null(strstr(buf, "-> mix"));                /* the unplaced mix */
    assert_non_null(strstr(buf, "listener"));
    free(buf);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_distance_follows_path), cmocka_unit_test(test_speed_and_travel),
        cmocka_unit_test(test_coordinates),           cmocka_unit_test(test_impact_impulse_from_path),
        cmocka_unit_test(test_tree_from_definitions), cmocka_unit_test(test_pool_notes),
        cmocka_unit_test(test_note_sets),             cmocka_unit_test(test_sleeping_line_silent),
        cmocka_unit_test(test_scene_errors),          cmocka_unit_test(test_room_ambience),
        cmocka_unit_test(test_dot),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
