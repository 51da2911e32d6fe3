/*
 * test_engine.c - the voice host of libwdrt: events at their exact frame
 * whatever the host's block lengths, sleep that changes nothing audible,
 * a budget that keeps the voices that matter most and fades the others,
 * ramped and stepped params, pools that steal, and the memory contract
 * (get_size / init_prealloc / alloc callbacks).
 */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "testlib.h"

#define FS 48000.0

static tl_voice g_mallet, g_piano, g_msd;

static int setup(void **s) {
    (void)s;
    if (tl_voice_build("netlists/mallet_plate.wdn", 0, &g_mallet) != 0)
        return -1;
    if (tl_voice_build("netlists/piano.wdn", 0, &g_piano) != 0)
        return -1;
    if (tl_voice_build("netlists/msd.wdn", 0, &g_msd) != 0)
        return -1;
    return 0;
}

static int teardown(void **s) {
    (void)s;
    tl_voice_free(&g_mallet);
    tl_voice_free(&g_piano);
    tl_voice_free(&g_msd);
    return 0;
}

static int ic_id(const wdv_class *c, const char *name) {
    for (int i = 0; i < c->n_ic_targets; i++)
        if (!strcmp(c->ic_targets[i].name, name))
            return i;
    return -1;
}

/* Renders n frames of an engine in host blocks of `hb` frames. */
static double *run(wdrt_engine *e, long n, int nch, int hb) {
    double *out = calloc((size_t)n * (size_t)nch + 1, sizeof(double));
    for (long pos = 0; pos < n; pos += hb) {
        long k = n - pos < hb ? n - pos : hb;
        wdrt_engine_process(e, out + pos * nch, (uint32_t)k);
    }
    return out;
}

/* Output `oid` of cls from the state init leaves, struck at frame 0 with
 * (ids, vals), rendered in blocks of `block`. */
static double *solo(const wdv_class *cls, int oid, long n, int nic, const int *ids, const double *vals, int block) {
    void *st = tl_state_new(cls, FS);
    if (nic)
        assert_int_equal(cls->set_ic(st, nic, ids, vals), 0);
    double **o = tl_bufs_new(cls->n_outputs, n);
    wdrt_render(cls, st, NULL, o, n, block);
    double *y = malloc(sizeof(double) * (size_t)n);
    memcpy(y, o[oid], sizeof(double) * (size_t)n);
    tl_bufs_free(o, cls->n_outputs);
    tl_state_free(st);
    return y;
}

static double peak(const double *x, long n) {
    double p = 0;
    for (long i = 0; i < n; i++)
        p = fabs(x[i]) > p ? fabs(x[i]) : p;
    return p;
}

/* A note played and struck at frame k (inside a block) sounds from frame
 * k exactly: silence before, then the voice's own render, bit for bit,
 * for host blocks of any length. */
static void test_play_at_frame(void **s) {
    (void)s;
    const wdv_class *c = g_mallet.cls;
    wdrt_pool_config pc = wdrt_pool_config_init(c, 4);
    pc.cost_ns = 1;
    wdrt_engine_config ec = wdrt_engine_config_init(FS, 1, 1, &pc);
    int ids[2] = {ic_id(c, "v(m)"), ic_id(c, "x(m)")};
    double vals[2] = {1.2, -0.4e-3};
    const long n = 9000, k = 1037;
    double *ref = solo(c, 0, n - k, 2, ids, vals, 4096);
    int blocks[] = {1, 37, 64, 100, 4096};
    for (int b = 0; b < 5; b++) {
        wdrt_engine *e;
        assert_int_equal(wdrt_engine_init(&ec, NULL, &e), WDRT_OK);
        wdrt_voice note;
        assert_int_equal(wdrt_engine_play(e, (uint64_t)k, 0, 1.0, 0, &note), WDRT_OK);
        assert_int_equal(wdrt_engine_strike(e, (uint64_t)k, note, 2, ids, vals), WDRT_OK);
        double *y = run(e, n, 1, blocks[b]);
        for (long i = 0; i < k; i++)
            assert_true(y[i] == 0);
        assert_true(y[k] != 0 || ref[0] == 0);
        for (long i = k; i < n; i++)
            if (y[i] != ref[i - k])
                fail_msg("host block %d: frame %ld: %.17g, voice alone %.17g", blocks[b], i, y[i], ref[i - k]);
        wdrt_engine_stats st;
        wdrt_engine_get_stats(e, &st);
        assert_int_equal((int)st.late, 0);
        assert_int_equal((int)st.events, 2);
        free(y);
        wdrt_engine_uninit(e, NULL);
    }
    free(ref);
}

/* An engine whose rate is too low for a voice's strings is refused
 * (WDRT_OUT_OF_TUNE) rather than made to play out of tune: the piano at
 * 2 kHz, not at 48 kHz; a voice without strings (msd) runs at 2 kHz. */
static void test_out_of_tune(void **s) {
    (void)s;
    const double rates[] = {2000, FS};
    for (int k = 0; k < 2; k++) {
        wdrt_pool_config pc[2] = {wdrt_pool_config_init(g_piano.cls, 2), wdrt_pool_config_init(g_msd.cls, 2)};
        pc[0].cost_ns = pc[1].cost_ns = 1;
        for (int n = 1; n <= 2; n++) {
            wdrt_engine_config ec = wdrt_engine_config_init(rates[k], 1, n, n == 1 ? pc + 1 : pc);
            wdrt_engine *e = NULL;
            wdrt_result r = wdrt_engine_init(&ec, NULL, &e);
            assert_int_equal(r, n == 2 && k == 0 ? WDRT_OUT_OF_TUNE : WDRT_OK);
            if (r == WDRT_OK)
                wdrt_engine_uninit(e, NULL);
        }
    }
    assert_string_equal(wdrt_result_str(WDRT_OUT_OF_TUNE),
                        "a voice's string, tube or delay line cannot be tuned at this rate");
}

/* A standing voice sleeps once quiet: nothing changes before its fade,
 * the difference stays 90 dB under the peak, and a strike on the sleeper
 * wakes it to continue as the voice that never slept. */
static void test_sleep(void **s) {
    (void)s;
    const wdv_class *c = g_mallet.cls;
    wdrt_pool_config pc = wdrt_pool_config_init(c, 1);
    pc.owned = 1;
    pc.cost_ns = 1;
    int ids[2] = {ic_id(c, "v(m)"), ic_id(c, "x(m)")};
    double vals[2] = {0.8, -0.3e-3};
    const long n = (long)(6 * FS), ks = (long)(4.5 * FS) + 11;
    double *y[2];
    wdrt_engine_stats st[2];
    for (int sl = 0; sl < 2; sl++) {
        wdrt_engine_config ec = wdrt_engine_config_init(FS, 1, 1, &pc);
        ec.sleep = sl;
        wdrt_engine *e;
        assert_int_equal(wdrt_engine_init(&ec, NULL, &e), WDRT_OK);
        assert_int_equal(wdrt_engine_strike(e, (uint64_t)ks, wdrt_engine_voice(e, 0, 0), 2, ids, vals), WDRT_OK);
        y[sl] = run(e, n, 1, 333);
        wdrt_engine_get_stats(e, &st[sl]);
        wdrt_engine_uninit(e, NULL);
    }
    print_message("sleeps %d wakes %d\n", (int)st[1].sleeps, (int)st[1].wakes);
    assert_int_equal((int)st[0].sleeps, 0);
    assert_true(st[1].sleeps >= 1 && st[1].wakes == 1);
    long first = tl_first_divergence(y[1], y[0], n, 0);
    assert_true(first > 0 && first < ks);
    double pk = peak(y[0], n), err = 0;
    for (long i = 0; i < n; i++)
        err = fmax(err, fabs(y[1][i] - y[0][i]));
    print_message("sleep: first change at %.3f s, largest difference %.1f dB of the peak\n", first / FS,
                  tl_db(err / pk));
    assert_true(err < pk * pow(10, -90 / 20.0));
    /* after the wake both carry the new strike */
    assert_true(peak(y[1] + ks, 4800) > pk * 0.1);
    free(y[0]);
    free(y[1]);
}

/* Ten notes struck at once with a budget for four: the four loudest
 * remain, computed exactly as alone; the others fade with no step larger
 * than their own. */
static void test_budget(void **s) {
    (void)s;
    const wdv_class *c = g_mallet.cls;
    wdrt_pool_config pc = wdrt_pool_config_init(c, 12);
    pc.cost_ns = 100;
    wdrt_engine_config ec = wdrt_engine_config_init(FS, 1, 1, &pc);
    ec.budget_ns = 450;
    wdrt_engine *e;
    assert_int_equal(wdrt_engine_init(&ec, NULL, &e), WDRT_OK);
    int ids[2] = {ic_id(c, "v(m)"), ic_id(c, "x(m)")};
    const long n = 4800, k = 100;
    /* speeds in a scrambled order: loudest are 3, 7, 1, 9 */
    const double speed[10] = {0.3, 1.6, 0.2, 2.0, 0.5, 0.1, 0.7, 1.8, 0.4, 1.4};
    double *alone[10], *sum_all = calloc((size_t)n, sizeof(double)), *sum_kept = calloc((size_t)n, sizeof(double));
    for (int i = 0; i < 10; i++) {
        double vals[2] = {speed[i], -0.2e-3};
        wdrt_voice note;
        assert_int_equal(wdrt_engine_play(e, (uint64_t)k, 0, 1.0, 0, &note), WDRT_OK);
        assert_int_equal(wdrt_engine_strike(e, (uint64_t)k, note, 2, ids, vals), WDRT_OK);
        alone[i] = solo(c, 0, n - k, 2, ids, vals, 4096);
        for (long j = k; j < n; j++) {
            sum_all[j] += alone[i][j - k];
            if (speed[i] >= 1.4)
                sum_kept[j] += alone[i][j - k];
        }
    }
    double *y = run(e, n, 1, 64);
    wdrt_engine_stats st;
    wdrt_engine_get_stats(e, &st);
    assert_int_equal(st.awake, 4);
    assert_int_equal((int)st.steals, 6);
    assert_true(st.cost_ns <= 450);
    /* after the fades, what sounds is the four loudest notes */
    long settled = k + 64 * 8;
    double pk = peak(sum_kept + settled, n - settled), err = 0;
    for (long j = settled; j < n; j++)
        err = fmax(err, fabs(y[j] - sum_kept[j]));
    print_message("budget: kept notes match their solo renders to %.1f dB\n", tl_db(err / pk));
    assert_true(err <= pk * 1e-12);
    /* the fade: the stolen part of the mix never steps more than the
     * stolen notes did on their own */
    double step_own = 0, step_faded = 0;
    for (long j = k + 1; j < n; j++) {
        double own = (sum_all[j] - sum_kept[j]) - (sum_all[j - 1] - sum_kept[j - 1]);
        double faded = (y[j] - sum_kept[j]) - (y[j - 1] - sum_kept[j - 1]);
        step_own = fmax(step_own, fabs(own));
        step_faded = fmax(step_faded, fabs(faded));
    }
    assert_true(step_faded <= step_own * (1 + 1e-9));
    for (int i = 0; i < 10; i++)
        free(alone[i]);
    free(sum_all);
    free(sum_kept);
    free(y);
    wdrt_engine_uninit(e, NULL);
}

/* A param the voice takes in steps (a string's pitch) acts at its frame;
 * one it does not (a damper) ramps over one block. */
static void test_param_ramp(void **s) {
    (void)s;
    const wdv_class *c = g_piano.cls;
    int f1 = tl_param_id(c, "f1"), d1 = tl_param_id(c, "dmp1");
    assert_true(f1 >= 0 && d1 >= 0);
    assert_true(c->params[f1].flags & WDV_PARAM_STEP);
    assert_false(c->params[d1].flags & WDV_PARAM_STEP);
    wdrt_pool_config pc = wdrt_pool_config_init(c, 1);
    pc.owned = 1;
    pc.cost_ns = 1;
    wdrt_engine_config ec = wdrt_engine_config_init(FS, 1, 1, &pc);
    wdrt_engine *e;
    assert_int_equal(wdrt_engine_init(&ec, NULL, &e), WDRT_OK);
    const long n = 4096, k = 1000 + 5;
    wdrt_voice v = wdrt_engine_voice(e, 0, 0);
    assert_int_equal(wdrt_engine_set(e, (uint64_t)k, v, d1, 50), WDRT_OK);
    double *y = run(e, n, 1, 256);
    /* the same by hand: the damper moved in 16 steps, 4 frames apart */
    void *st = tl_state_new(c, FS);
    double **o = tl_bufs_new(c->n_outputs, n);
    double from = c->get_param(st, d1);
    long pos = 0;
    for (int j = 1; j <= 16; j++) {
        long at = k + 4 * (j - 1);
        double *op[8];
        for (int q = 0; q < c->n_outputs; q++)
            op[q] = o[q] + pos;
        wdrt_render(c, st, NULL, op, at - pos, 64);
        pos = at;
        c->set_param(st, d1, j == 16 ? 50 : from + (50 - from) * j / 16);
    }
    double *op[8];
    for (int q = 0; q < c->n_outputs; q++)
        op[q] = o[q] + pos;
    wdrt_render(c, st, NULL, op, n - pos, 64);
    double pk = peak(o[0], n), err = 0;
    for (long i = 0; i < n; i++)
        err = fmax(err, fabs(y[i] - o[0][i]));
    print_message("ramp: engine against a hand-made ramp: %.1f dB\n", tl_db(err / pk));
    assert_true(err <= pk * 1e-12);
    assert_true(c->get_param(st, d1) == 50);
    tl_bufs_free(o, c->n_outputs);
    tl_state_free(st);
    free(y);
    wdrt_engine_uninit(e, NULL);
}

/* A pool of two playing three notes steals the quietest, fading it out on
 * a spare instance while the new note starts at its frame. */
static void test_pool_steal(void **s) {
    (void)s;
    const wdv_class *c = g_mallet.cls;
    wdrt_pool_config pc = wdrt_pool_config_init(c, 2);
    pc.cost_ns = 1;
    wdrt_engine_config ec = wdrt_engine_config_init(FS, 1, 1, &pc);
    wdrt_engine *e;
    assert_int_equal(wdrt_engine_init(&ec, NULL, &e), WDRT_OK);
    int ids[2] = {ic_id(c, "v(m)"), ic_id(c, "x(m)")};
    const double sp[3] = {1.5, 0.2, 1.0};
    const long at[3] = {0, 300, 2000}, n = 6000;
    double *expect = calloc((size_t)n, sizeof(double));
    for (int i = 0; i < 3; i++) {
        double vals[2] = {sp[i], -0.2e-3};
        wdrt_voice note;
        assert_int_equal(wdrt_engine_play(e, (uint64_t)at[i], 0, 1.0, 0, &note), WDRT_OK);
        assert_int_equal(wdrt_engine_strike(e, (uint64_t)at[i], note, 2, ids, vals), WDRT_OK);
        double *a = solo(c, 0, n - at[i], 2, ids, vals, 4096);
        for (long j = at[i]; j < n; j++)
            if (i != 1 || j < at[2])
                expect[j] += a[j - at[i]];
        free(a);
    }
    double *y = run(e, n, 1, 128);
    wdrt_engine_stats st;
    wdrt_engine_get_stats(e, &st);
    assert_int_equal((int)st.steals, 1);
    assert_int_equal((int)st.cuts, 0);
    /* identical before the steal's block and after its fade */
    for (long j = 0; j < 1984; j++)
        assert_true(y[j] == expect[j]);
    double pk = peak(expect, n), err = 0;
    for (long j = 2048 + 64; j < n; j++)
        err = fmax(err, fabs(y[j] - expect[j]));
    assert_true(err <= pk * 1e-12);
    free(expect);
    free(y);
    wdrt_engine_uninit(e, NULL);
}

/* get_size and init_prealloc place everything in the caller's memory; the
 * callbacks are used once each; bad configs are refused. */
static int g_allocs, g_frees;
static void *count_alloc(size_t n, void *u) {
    (void)u;
    g_allocs++;
    return malloc(n);
}
static void count_free(void *p, void *u) {
    (void)u;
    g_frees++;
    free(p);
}

static void test_memory(void **s) {
    (void)s;
    const wdv_class *c = g_mallet.cls;
    wdrt_pool_config pc = wdrt_pool_config_init(c, 3);
    pc.cost_ns = 1;
    wdrt_engine_config ec = wdrt_engine_config_init(FS, 2, 1, &pc);
    size_t sz = 0;
    assert_int_equal(wdrt_engine_get_size(&ec, &sz), WDRT_OK);
    assert_true(sz > 3 * c->state_size);
    unsigned char *mem = malloc(sz + 1);
    wdrt_engine *e;
    assert_int_equal(wdrt_engine_init_prealloc(&ec, mem + 1, &e), WDRT_OK);
    assert_true((unsigned char *)e >= mem + 1 && (unsigned char *)e < mem + 1 + sz);
    wdrt_engine_uninit(e, NULL);
    free(mem);
    wdrt_alloc_callbacks cb = {NULL, count_alloc, count_free};
    assert_int_equal(wdrt_engine_init(&ec, &cb, &e), WDRT_OK);
    double out[2 * 500];
    wdrt_engine_process(e, out, 500);
    wdrt_engine_uninit(e, &cb);
    assert_int_equal(g_allocs, 1);
    assert_int_equal(g_frees, 1);
    wdrt_engine_config bad = ec;
    bad.channels = 3;
    assert_int_equal(wdrt_engine_get_size(&bad, &sz), WDRT_INVALID_ARGS);
    bad = ec;
    bad.block = 0;
    assert_int_equal(wdrt_engine_init(&bad, NULL, &e), WDRT_INVALID_ARGS);
    wdrt_pool_config bp = pc;
    bp.output = 7;
    bad = wdrt_engine_config_init(FS, 1, 1, &bp);
    assert_int_equal(wdrt_engine_get_size(&bad, &sz), WDRT_INVALID_ARGS);
    /* events with bad arguments are refused */
    assert_int_equal(wdrt_engine_init(&ec, NULL, &e), WDRT_OK);
    assert_int_equal(wdrt_engine_set(e, 0, wdrt_engine_pool(e, 0), 99, 1), WDRT_INVALID_ARGS);
    assert_int_equal(wdrt_engine_set(e, 0, 12345, 0, 1), WDRT_INVALID_ARGS);
    assert_int_equal(wdrt_engine_play(e, 0, 1, 1, 0, NULL), WDRT_INVALID_ARGS);
    assert_int_equal(wdrt_engine_voice(e, 0, 0), 0); /* not owned */
    wdrt_engine_uninit(e, NULL);
}

/* Standing voices past the budget are made virtual, not stopped: the
 * quietest fades out, and comes back (fading in) once a louder one has
 * stopped and the budget has room. */
static void test_virtual(void **s) {
    (void)s;
    const wdv_class *c = g_mallet.cls;
    wdrt_pool_config pc[3];
    for (int i = 0; i < 3; i++) {
        pc[i] = wdrt_pool_config_init(c, 1);
        pc[i].owned = 1;
        pc[i].cost_ns = 100;
        pc[i].virtualize = 1;
    }
    wdrt_engine_config ec = wdrt_engine_config_init(FS, 1, 3, pc);
    ec.budget_ns = 250;
    wdrt_engine *e;
    assert_int_equal(wdrt_engine_init(&ec, NULL, &e), WDRT_OK);
    int ids[2] = {ic_id(c, "v(m)"), ic_id(c, "x(m)")};
    const double sp[3] = {1.5, 0.3, 1.0};
    for (int i = 0; i < 3; i++) {
        double vals[2] = {sp[i], -0.2e-3};
        assert_int_equal(wdrt_engine_strike(e, 0, wdrt_engine_voice(e, i, 0), 2, ids, vals), WDRT_OK);
    }
    double *y = run(e, 4800, 1, 64);
    wdrt_engine_stats st;
    wdrt_engine_get_stats(e, &st);
    assert_int_equal((int)st.virtualized, 1);
    assert_int_equal(st.virtual_, 1);
    assert_int_equal(st.awake, 2);
    assert_true(st.cost_ns <= 250);
    free(y);
    assert_int_equal(wdrt_engine_stop(e, 4800 + 10, wdrt_engine_voice(e, 0, 0)), WDRT_OK);
    y = run(e, 4800, 1, 64);
    wdrt_engine_get_stats(e, &st);
    assert_int_equal((int)st.revived, 1);
    assert_int_equal(st.virtual_, 0);
    assert_int_equal(st.awake, 2);
    /* it fades back in: no jump at the block it returns in */
    double step = 0, own = 0;
    for (long i = 1; i < 4800; i++)
        step = fmax(step, fabs(y[i] - y[i - 1]));
    for (long i = 1; i < 4800; i++)
        own = fmax(own, fabs(y[i]));
    assert_true(step < own);
    free(y);
    wdrt_engine_uninit(e, NULL);
}

/* More notes in one block than the pool holds: young notes are stolen
 * oldest first, their fades end, and once everything has rung down every
 * instance is free again (a stolen note's own events never revive it). */
static void test_chord_overflow(void **s) {
    (void)s;
    const wdv_class *c = g_mallet.cls;
    wdrt_pool_config pc = wdrt_pool_config_init(c, 4);
    pc.cost_ns = 1;
    wdrt_engine_config ec = wdrt_engine_config_init(FS, 1, 1, &pc);
    wdrt_engine *e;
    assert_int_equal(wdrt_engine_init(&ec, NULL, &e), WDRT_OK);
    int ids[2] = {ic_id(c, "v(m)"), ic_id(c, "x(m)")};
    for (int i = 0; i < 6; i++) {
        double vals[2] = {0.5 + 0.2 * i, -0.2e-3};
        wdrt_voice note;
        assert_int_equal(wdrt_engine_play(e, 10 + 2 * (uint64_t)i, 0, 1.0, 0, &note), WDRT_OK);
        assert_int_equal(wdrt_engine_set(e, 10 + 2 * (uint64_t)i, note, 0, 1.5), WDRT_OK);
        assert_int_equal(wdrt_engine_strike(e, 10 + 2 * (uint64_t)i, note, 2, ids, vals), WDRT_OK);
    }
    double *y = run(e, (long)(4 * FS), 1, 512);
    wdrt_engine_stats st;
    wdrt_engine_get_stats(e, &st);
    assert_int_equal((int)st.steals, 2);
    assert_int_equal((int)st.cuts, 0);
    assert_int_equal(st.awake, 0);
    assert_int_equal(st.free, 4);
    free(y);
    wdrt_engine_uninit(e, NULL);
}

/* A standing voice with an input sleeps while the input is silent and
 * wakes at the first frame it is not; at rest when it fell asleep, it
 * renders bit for bit what it renders never sleeping. */
static void test_input_wake(void **s) {
    (void)s;
    const wdv_class *c = g_msd.cls;
    wdrt_pool_config pc = wdrt_pool_config_init(c, 1);
    pc.owned = 1;
    pc.cost_ns = 1;
    wdrt_engine_config ec = wdrt_engine_config_init(FS, 1, 1, &pc);
    wdrt_engine *e;
    assert_int_equal(wdrt_engine_init(&ec, NULL, &e), WDRT_OK);
    const long n = 24000, k = 12345, hb = 500;
    double *in = calloc((size_t)n, sizeof(double)), *y = calloc((size_t)n, sizeof(double));
    for (long i = k; i < k + 40; i++)
        in[i] = 1.0;
    wdrt_voice v = wdrt_engine_voice(e, 0, 0);
    wdrt_engine_stats st;
    for (long pos = 0; pos < n; pos += hb) {
        if (pos == 6000) {
            wdrt_engine_get_stats(e, &st);
            assert_int_equal(st.asleep, 1); /* asleep well before the input */
        }
        assert_int_equal(wdrt_engine_bind_input(e, v, 0, in + pos), WDRT_OK);
        wdrt_engine_process(e, y + pos, (uint32_t)hb);
    }
    wdrt_engine_get_stats(e, &st);
    assert_true(st.sleeps >= 1 && st.wakes >= 1);
    void *vs = tl_state_new(c, FS);
    double **o = tl_bufs_new(c->n_outputs, n);
    const double *ip[1] = {in};
    wdrt_render(c, vs, ip, o, n, 64);
    for (long i = 0; i < n; i++)
        if (y[i] != o[0][i])
            fail_msg("frame %ld: %.17g, never asleep %.17g", i, y[i], o[0][i]);
    assert_true(y[k] != 0 && y[k - 1] == 0);
    assert_int_equal(wdrt_engine_bind_input(e, wdrt_engine_pool(e, 0), 0, in), WDRT_INVALID_ARGS);
    tl_bufs_free(o, c->n_outputs);
    tl_state_free(vs);
    free(in);
    free(y);
    wdrt_engine_uninit(e, NULL);
}

/* Costs measured at init (on scratch state) leave every voice as init
 * left it: two standing voices of different classes, the second muted,
 * render the first exactly as it renders alone. */
static void test_measured_cost(void **s) {
    (void)s;
    wdrt_pool_config pc[2] = {wdrt_pool_config_init(g_mallet.cls, 1), wdrt_pool_config_init(g_msd.cls, 1)};
    pc[0].owned = pc[1].owned = 1;
    pc[1].gain = 0;
    wdrt_engine_config ec = wdrt_engine_config_init(FS, 1, 2, pc);
    wdrt_engine *e;
    assert_int_equal(wdrt_engine_init(&ec, NULL, &e), WDRT_OK);
    assert_true(wdrt_engine_pool_cost(e, 0) > 0 && wdrt_engine_pool_cost(e, 1) > 0);
    const long n = 4000;
    double *y = run(e, n, 1, 128), *ref = solo(g_mallet.cls, 0, n, 0, NULL, NULL, 64);
    for (long i = 0; i < n; i++)
        if (y[i] != ref[i])
            fail_msg("frame %ld: %.17g, alone %.17g", i, y[i], ref[i]);
    free(y);
    free(ref);
    wdrt_engine_uninit(e, NULL);
}

/* A pool whose class has process_batch (wdc --batch) renders runs of its
 * voices that nothing acts on within a block in one process_batch call:
 * the mix is the one a process call per voice gives, bit for bit.  Twelve
 * mallets, struck at frames inside blocks and later than each other, some
 * with a param moved (a ramp) and set while they play, in host blocks of
 * several lengths; the same engine over the class without process_batch
 * is the reference. */
static void (*g_batch)(void *const *, int, const double *const *const *, double *const *const *, int);
static long g_lanes; /* lanes rendered through process_batch */
static void counting_batch(void *const *st, int n, const double *const *const *in, double *const *const *out,
                           int nframes) {
    g_lanes += n;
    g_batch(st, n, in, out, nframes);
}

static void test_batch_pool(void **s) {
    (void)s;
    static const char *const batch[] = {"--batch", NULL};
    tl_voice bv;
    assert_int_equal(tl_voice_build_args("netlists/mallet_plate.wdn", 0, batch, NULL, &bv), 0);
    assert_non_null(bv.cls->process_batch);
    wdv_class plain = *bv.cls, counted = *bv.cls;
    plain.process_batch = NULL;
    g_batch = bv.cls->process_batch;
    counted.process_batch = counting_batch;
    const wdv_class *cls[2] = {&counted, &plain};
    int ids[2] = {ic_id(bv.cls, "v(m)"), ic_id(bv.cls, "x(m)")};
    assert_true(ids[0] >= 0 && ids[1] >= 0);
    const long n = 12000;
    static const int hbs[] = {64, 100, 1000};
    for (int h = 0; h < 3; h++) {
        double *y[2];
        for (int c = 0; c < 2; c++) {
            wdrt_pool_config pc = wdrt_pool_config_init(cls[c], 12);
            pc.cost_ns = 1;
            wdrt_engine_config ec = wdrt_engine_config_init(FS, 2, 1, &pc);
            wdrt_engine *e;
            assert_int_equal(wdrt_engine_init(&ec, NULL, &e), WDRT_OK);
            for (int k = 0; k < 12; k++) {
                wdrt_voice note;
                uint64_t at = (uint64_t)(37 + 311 * k);
                double vals[2] = {0.5 + 0.1 * k, -0.3e-3};
                assert_int_equal(wdrt_engine_play(e, at, 0, 1.0 - 0.05 * k, 0, &note), WDRT_OK);
                assert_int_equal(wdrt_engine_strike(e, at, note, 2, ids, vals), WDRT_OK);
                if (k % 3 == 0 && cls[c]->n_params)
                    assert_int_equal(wdrt_engine_set(e, at + 2000, note, 0,
                                                     0.5 * (cls[c]->params[0].min + cls[c]->params[0].max)),
                                     WDRT_OK);
            }
            y[c] = run(e, n, 2, hbs[h]);
            wdrt_engine_uninit(e, NULL);
        }
        long differ = 0, lanes = g_lanes;
        g_lanes = 0;
        for (long i = 0; i < 2 * n; i++)
            differ += memcmp(&y[0][i], &y[1][i], sizeof(double)) != 0;
        print_message("pool of 12 mallets, host blocks of %d: %ld voice-blocks went through process_batch; "
                      "%ld of %ld mix samples differ from a process call per voice (peak %.3g)\n",
                      hbs[h], lanes, differ, 2 * n, peak(y[0], 2 * n));
        assert_true(peak(y[0], 2 * n) > 0);
        assert_true(lanes > 0);
        assert_int_equal(differ, 0);
        free(y[0]);
        free(y[1]);
    }
    tl_voice_free(&bv);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_play_at_frame),
        cmocka_unit_test(test_out_of_tune), cmocka_unit_test(test_sleep),     cmocka_unit_test(test_budget),
        cmocka_unit_test(test_param_ramp),    cmocka_unit_test(test_pool_steal), cmocka_unit_test(test_memory),
        cmocka_unit_test(test_virtual),     cmocka_unit_test(test_chord_overflow),
        cmocka_unit_test(test_input_wake),  cmocka_unit_test(test_measured_cost), cmocka_unit_test(test_batch_pool),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
