/*
 * test_prepare.c - the heavy part of a param change made off the audio
 * thread: wdv_class.prepare and install.
 *
 * netlists/piano_mid.wdn detunes two of its three strings with `detune`,
 * which redesigns their loops.  A voice given the design prepare made for
 * its new params must sound the same, bit for bit, as one that designs in
 * its own block; the design it was handed must be the one it runs (a
 * design altered on purpose changes the sound), a design made for other
 * params must be ignored, prepare must depend on nothing but its
 * arguments (clamping as set_param clamps), and set_param, install and
 * process allocate nothing.  A voice whose loops no param moves has no
 * prepare at all.  The engine's wdrt_engine_set_prepared plays the same
 * notes as wdrt_engine_set, bit for bit, and gives its design slots back,
 * also from a producer thread of its own while another renders (built
 * with ThreadSanitizer too: build/tests/test_prepare_tsan).
 */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <pthread.h>
#include <sched.h>
#include <stdlib.h>
#include <string.h>

#include "countalloc.h"
#include "testlib.h"

#define FS 48000.0
#define BLOCK 64
#define BLOCKS 200 /* 0.27 s after the change */

static tl_voice g_pm;

static int setup(void **s) {
    (void)s;
    return tl_voice_build("netlists/piano_mid.wdn", 0, &g_pm);
}

static int teardown(void **s) {
    (void)s;
    tl_voice_free(&g_pm);
    return 0;
}

static int param_id(const wdv_class *c, const char *name) {
    int id = tl_param_id(c, name);
    assert_true(id >= 0);
    return id;
}

/* Renders BLOCKS blocks of output 0 into y after 20 blocks from init and
 * a change of param `id` to `value`, handed a design first when `design`
 * is not NULL. */
static void run(const wdv_class *c, int id, double value, const void *design, double *y) {
    void *st = tl_state_new(c, FS);
    double out[4][BLOCK], *o[4] = {out[0], out[1], out[2], out[3]};
    assert_true(c->n_outputs <= 4 && c->n_inputs == 0);
    for (int b = 0; b < 20; b++)
        c->process(st, NULL, o, BLOCK);
    ca_in_rt = 1;
    c->set_param(st, id, value);
    if (design)
        c->install(st, design);
    for (int b = 0; b < BLOCKS; b++) {
        c->process(st, NULL, o, BLOCK);
        memcpy(y + b * BLOCK, out[0], sizeof out[0]);
    }
    ca_in_rt = 0;
    tl_state_free(st);
}

static void params_with(const wdv_class *c, int id, double value, double *p) {
    for (int i = 0; i < c->n_params; i++)
        p[i] = c->params[i].def;
    p[id] = value;
}

static void test_prepared_is_inline(void **s) {
    (void)s;
    const wdv_class *c = g_pm.cls;
    assert_non_null(c->prepare);
    assert_non_null(c->install);
    assert_true(c->design_size > 0);
    int id = param_id(c, "detune");
    assert_true(c->params[id].flags & WDV_PARAM_STEP);
    assert_true(c->params[id].flags & WDV_PARAM_DESIGN);
    /* hit moves the hammers' taps: a step, but the loops keep their design */
    assert_true(c->params[param_id(c, "hit")].flags & WDV_PARAM_STEP);
    assert_false(c->params[param_id(c, "hit")].flags & WDV_PARAM_DESIGN);
    double p[64], *a = malloc(sizeof(double) * BLOCKS * BLOCK), *b = malloc(sizeof(double) * BLOCKS * BLOCK);
    void *d = malloc(c->design_size);
    long before = ca_allocs;
    for (int k = 0; k < 3; k++) {
        double value = k == 0 ? 4.0 : k == 1 ? 0.0 : 9.5;
        params_with(c, id, value, p);
        c->prepare(FS, p, d);
        run(c, id, value, NULL, a);
        run(c, id, value, d, b);
        double peak = 0;
        for (int n = 0; n < BLOCKS * BLOCK; n++) {
            peak = fmax(peak, fabs(a[n]));
            if (memcmp(&a[n], &b[n], sizeof a[n]))
                fail_msg("detune %g: sample %d differs: %.17g inline, %.17g prepared", value, n, a[n], b[n]);
        }
        assert_true(peak > 1e-6); /* the strings ring */
    }
    assert_int_equal(ca_allocs, before);
    free(d);
    free(a);
    free(b);
}

/* The design handed over is the one that runs: an altered one (the loss
 * filter of every loop turned down) changes the sound; one made for
 * other params is not taken. */
static void test_install_is_taken(void **s) {
    (void)s;
    const wdv_class *c = g_pm.cls;
    int id = param_id(c, "detune");
    double p[64], *a = malloc(sizeof(double) * BLOCKS * BLOCK), *b = malloc(sizeof(double) * BLOCKS * BLOCK);
    double *d = malloc(c->design_size);
    params_with(c, id, 4.0, p);
    c->prepare(FS, p, d);
    /* a record per waveguide: its spec (11 doubles), whole samples,
     * stages, then the loss filter's b */
    size_t nrec = c->design_size / sizeof(double) / 3;
    for (int w = 0; w < 3; w++)
        d[w * nrec + 11 + 2] *= 0.5;
    run(c, id, 4.0, NULL, a);
    run(c, id, 4.0, d, b);
    double diff = 0;
    for (int n = 0; n < BLOCKS * BLOCK; n++)
        diff = fmax(diff, fabs(a[n] - b[n]));
    assert_true(diff > 1e-6);
    /* made for detune 3, installed with detune 4: designed inline */
    params_with(c, id, 3.0, p);
    c->prepare(FS, p, d);
    run(c, id, 4.0, d, b);
    assert_memory_equal(a, b, sizeof(double) * BLOCKS * BLOCK);
    free(d);
    free(a);
    free(b);
}

/* prepare reads its arguments alone and clamps as set_param does: out of
 * range to the range, NaN to the default. */
static void test_prepare_is_pure(void **s) {
    (void)s;
    const wdv_class *c = g_pm.cls;
    int id = param_id(c, "detune");
    double p[64];
    unsigned char *d1 = malloc(c->design_size), *d2 = malloc(c->design_size);
    params_with(c, id, 10.0, p);
    c->prepare(FS, p, d1);
    params_with(c, id, 1e9, p);
    c->prepare(FS, p, d2);
    assert_memory_equal(d1, d2, c->design_size);
    params_with(c, id, c->params[id].def, p);
    c->prepare(FS, p, d1);
    params_with(c, id, NAN, p);
    c->prepare(FS, p, d2);
    assert_memory_equal(d1, d2, c->design_size);
    /* another rate, another design */
    c->prepare(96000, p, d2);
    assert_true(memcmp(d1, d2, c->design_size) != 0);
    free(d1);
    free(d2);
}

/* Voices without loops need no prepare; the plucked string, whose f0
 * is a param, has one loop to design. */
static void test_which(void **s) {
    (void)s;
    static const char *const nets[] = {"netlists/rc_lowpass.wdn", "netlists/msd.wdn", "netlists/pluck.wdn"};
    for (int k = 0; k < 3; k++) {
        tl_voice v;
        assert_int_equal(tl_voice_build(nets[k], 0, &v), 0);
        if (k < 2) {
            assert_int_equal(v.cls->design_size, 0);
            assert_null(v.cls->prepare);
            assert_null(v.cls->install);
        } else {
            assert_non_null(v.cls->prepare);
            assert_int_equal(v.cls->design_size, g_pm.cls->design_size / 3);
            assert_true(v.cls->params[tl_param_id(v.cls, "f0")].flags & WDV_PARAM_STEP);
        }
        tl_voice_free(&v);
    }
}

/* Notes of piano_mid, each detuned its own way as it is played, and the
 * pool detuned half-way: wdrt_engine_set_prepared against
 * wdrt_engine_set, more notes than the engine has design slots. */
static double *engine_run(int prepared, long n, int spans) {
    const wdv_class *c = g_pm.cls;
    wdrt_pool_config pc = wdrt_pool_config_init(c, 4);
    pc.cost_ns = 1;
    wdrt_engine_config ec = wdrt_engine_config_init(FS, 1, 1, &pc);
    wdrt_engine *e;
    assert_int_equal(wdrt_engine_init(&ec, NULL, &e), WDRT_OK);
    int id = param_id(c, "detune");
    double *y = malloc(sizeof(double) * (size_t)n);
    const int notes = 3 * WDRT_DESIGN_SLOTS / 2;
    long at = 0;
    for (int k = 0; k < notes; k++) {
        uint64_t frame = (uint64_t)(k * (n - 4096) / notes + 17 * (k % 3));
        if (k == notes / 2) { /* the pool: notes to come start from it */
            double d = 7.25;
            if (prepared)
                assert_int_equal(wdrt_engine_set_prepared(e, frame, wdrt_engine_pool(e, 0), 1, &id, &d), WDRT_OK);
            else
                assert_int_equal(wdrt_engine_set(e, frame, wdrt_engine_pool(e, 0), id, d), WDRT_OK);
            continue;
        }
        wdrt_voice note;
        assert_int_equal(wdrt_engine_play(e, frame, 0, 1.0, 0, &note), WDRT_OK);
        double d = 0.5 + 0.37 * k;
        d -= 10 * floor(d / 10);
        if (k % 4 != 3 && prepared) /* every fourth note keeps the pool's detune */
            assert_int_equal(wdrt_engine_set_prepared(e, frame, note, 1, &id, &d), WDRT_OK);
        else if (k % 4 != 3)
            assert_int_equal(wdrt_engine_set(e, frame, note, id, d), WDRT_OK);
        /* render up to the note just posted (the producer runs ahead by
         * one), or in spans of `spans` frames */
        long to = spans ? at + spans * (((long)frame - at) / spans) : (long)frame;
        if (to > at) {
            wdrt_engine_process(e, y + at, (uint32_t)(to - at));
            at = to;
        }
    }
    wdrt_engine_process(e, y + at, (uint32_t)(n - at));
    wdrt_engine_stats st;
    wdrt_engine_get_stats(e, &st);
    assert_int_equal((int)st.late, 0);
    wdrt_engine_uninit(e, NULL);
    return y;
}

/* A full pool steals a note: the stolen one fades out from the frame of
 * the note that takes its instance, whatever spans the host renders in
 * (the fade once began where the host's call did).  The same notes in
 * spans of 37 and of 4096 frames: equal to rounding (the order in which
 * voices are summed may differ). */
static void test_steal_any_spans(void **s) {
    (void)s;
    const long n = 48000;
    double *a = engine_run(0, n, 0), *b = engine_run(0, n, 37), *c = engine_run(0, n, 4096), peak = 0, e = 0;
    for (long i = 0; i < n; i++) {
        peak = fmax(peak, fabs(a[i]));
        e = fmax(e, fmax(fabs(a[i] - b[i]), fabs(a[i] - c[i])));
    }
    print_message("steals in spans of 37 and 4096 frames: %.3g of the peak from spans up to each note\n", e / peak);
    assert_true(peak > 1e-6);
    assert_true(e <= 1e-12 * peak);
    free(a);
    free(b);
    free(c);
}

static void test_engine_prepared(void **s) {
    (void)s;
    const long n = 48000;
    double *a = engine_run(0, n, 0), *b = engine_run(1, n, 0), peak = 0;
    for (long i = 0; i < n; i++) {
        peak = fmax(peak, fabs(a[i]));
        if (memcmp(&a[i], &b[i], sizeof a[i]))
            fail_msg("frame %ld: %.17g with set, %.17g with set_prepared", i, a[i], b[i]);
    }
    assert_true(peak > 1e-6);
    free(a);
    free(b);
}

/* The same notes posted by a producer thread, designs made there, while
 * this thread renders each span as soon as the notes that start in it
 * are posted: the render of test_engine_prepared, bit for bit. */
typedef struct Producer {
    wdrt_engine *e;
    int id, notes, posted, failed; /* posted, failed: atomic */
    long n;
} Producer;

static uint64_t note_frame(int k, int notes, long n) { return (uint64_t)(k * (n - 4096) / notes + 17 * (k % 3)); }

static void *produce(void *arg) {
    Producer *p = arg;
    for (int k = 0; k < p->notes; k++) {
        uint64_t frame = note_frame(k, p->notes, p->n);
        double d = k == p->notes / 2 ? 7.25 : 0.5 + 0.37 * k;
        d -= 10 * floor(d / 10);
        wdrt_voice v = wdrt_engine_pool(p->e, 0);
        wdrt_result r = WDRT_OK;
        if (k != p->notes / 2)
            r = wdrt_engine_play(p->e, frame, 0, 1.0, 0, &v);
        for (int tries = 0; r == WDRT_OK && (k == p->notes / 2 || k % 4 != 3); tries++) {
            r = wdrt_engine_set_prepared(p->e, frame, v, 1, &p->id, &d);
            if (r != WDRT_QUEUE_FULL || tries > 10000000)
                break;
            sched_yield(); /* every slot waits for its frame: the renderer frees them */
        }
        if (r != WDRT_OK) {
            __atomic_store_n(&p->failed, 1, __ATOMIC_RELEASE);
            return NULL;
        }
        __atomic_store_n(&p->posted, k + 1, __ATOMIC_RELEASE);
    }
    return NULL;
}

static void test_engine_threads(void **s) {
    (void)s;
    const long n = 48000;
    const wdv_class *c = g_pm.cls;
    wdrt_pool_config pc = wdrt_pool_config_init(c, 4);
    pc.cost_ns = 1;
    wdrt_engine_config ec = wdrt_engine_config_init(FS, 1, 1, &pc);
    Producer p = {NULL, param_id(c, "detune"), 3 * WDRT_DESIGN_SLOTS / 2, 0, 0, n};
    assert_int_equal(wdrt_engine_init(&ec, NULL, &p.e), WDRT_OK);
    double *a = engine_run(1, n, 0), *b = malloc(sizeof(double) * (size_t)n);
    pthread_t th;
    assert_int_equal(pthread_create(&th, NULL, produce, &p), 0);
    long at = 0;
    for (int k = 0; k <= p.notes; k++) {
        /* render up to the next note's frame once the notes before it are posted */
        long to = k < p.notes ? (long)note_frame(k, p.notes, n) : n;
        while (k < p.notes && __atomic_load_n(&p.posted, __ATOMIC_ACQUIRE) < k && !__atomic_load_n(&p.failed, __ATOMIC_ACQUIRE))
            sched_yield();
        if (to > at) {
            wdrt_engine_process(p.e, b + at, (uint32_t)(to - at));
            at = to;
        }
        while (k < p.notes && __atomic_load_n(&p.posted, __ATOMIC_ACQUIRE) < k + 1 &&
               !__atomic_load_n(&p.failed, __ATOMIC_ACQUIRE))
            sched_yield();
        if (__atomic_load_n(&p.failed, __ATOMIC_ACQUIRE))
            break;
    }
    pthread_join(th, NULL);
    assert_int_equal(p.posted, p.notes);
    wdrt_engine_stats st;
    wdrt_engine_get_stats(p.e, &st);
    assert_int_equal((int)st.late, 0);
    assert_memory_equal(a, b, sizeof(double) * (size_t)n);
    wdrt_engine_uninit(p.e, NULL);
    free(a);
    free(b);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_prepared_is_inline),
        cmocka_unit_test(test_install_is_taken),
        cmocka_unit_test(test_prepare_is_pure),
        cmocka_unit_test(test_which),
        cmocka_unit_test(test_engine_prepared),
        cmocka_unit_test(test_steal_any_spans),
        cmocka_unit_test(test_engine_threads),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
