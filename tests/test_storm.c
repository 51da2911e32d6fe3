/*
 * test_storm.c - events posted from a second thread while the engine
 * processes: 10^5 strikes, sets, plays and stops, none lost, none late,
 * the render the same bit for bit as with every event posted up front,
 * and no allocation at all inside wdrt_engine_process (a counting
 * allocator stands in for malloc), with the notes heard through the
 * spatial layer: moving, in a room with reflections, binaurally.  The Makefile also builds this file
 * with ThreadSanitizer (test_storm_tsan), which checks the queue; TSan
 * has its own malloc, so that build leaves the counting allocator out.
 */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <pthread.h>
#include <sched.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testlib.h"


#define FS 48000.0
#define NEV 100000
#define EVERY 3   /* frames between events */
#define HOST 256  /* frames per process call */

#include "countalloc.h"

static void process(wdrt_engine *e, double *out, uint32_t n) {
    ca_in_rt = 1;
    wdrt_engine_process(e, out, n);
    ca_in_rt = 0;
}

/* ---- the storm ---- */

static tl_voice g_v;
static int g_ids[2];
static wdrt_hrtf *g_hrtf;

static int setup(void **s) {
    (void)s;
    if (tl_voice_build("netlists/mallet_plate.wdn", 0, &g_v) != 0)
        return -1;
    char err[512];
    if (!(g_hrtf = wdrt_hrtf_open(NULL, FS, err, sizeof err))) {
        fputs(err, stderr);
        return -1;
    }
    for (int i = 0; i < g_v.cls->n_ic_targets; i++) {
        if (!strcmp(g_v.cls->ic_targets[i].name, "v(m)"))
            g_ids[0] = i;
        if (!strcmp(g_v.cls->ic_targets[i].name, "x(m)"))
            g_ids[1] = i;
    }
    return 0;
}

static int teardown(void **s) {
    (void)s;
    tl_voice_free(&g_v);
    wdrt_hrtf_close(g_hrtf);
    return 0;
}

static wdrt_engine *make_engine(void) {
    static wdrt_pool_config pc[2];
    pc[0] = wdrt_pool_config_init(g_v.cls, 1);
    pc[0].owned = 1;
    pc[0].cost_ns = 1;
    pc[1] = wdrt_pool_config_init(g_v.cls, 16);
    pc[1].cost_ns = 1;
    pc[1].gain = 0.5;
    pc[1].placed = 1; /* the notes are heard through the spatial layer */
    pc[1].pos[1] = 3;
    wdrt_engine_config ec = wdrt_engine_config_init(FS, 2, 2, pc);
    ec.space.sources = 8;
    ec.space.max = 100;
    /* the notes sound in a room, with reflections, heard binaurally */
    static const wdrt_room room = {{-10, -10, -2, 10, 10, 6}, 0.8, 0.5, 2};
    ec.space.nrooms = 1;
    ec.space.rooms = &room;
    ec.space.hrtf = g_hrtf;
    ec.queue = 1024;
    ec.pending = 1024;
    wdrt_engine *e;
    assert_int_equal(wdrt_engine_init(&ec, NULL, &e), WDRT_OK);
    return e;
}

/* Event i of the storm, posted at its frame; spins while the queue is
 * full.  Returns the frame. */
static uint64_t post(wdrt_engine *e, int i, int spin) {
    uint64_t f = 1000 + (uint64_t)i * EVERY;
    wdrt_voice owned = wdrt_engine_voice(e, 0, 0);
    double v[2] = {0.2 + 0.1 * (i % 13), -0.2e-3};
    static __thread wdrt_voice last;
    wdrt_result r;
    do {
        switch (i % 5) {
        case 0: r = wdrt_engine_set(e, f, owned, 0, 0.5 + (i % 7)); break;
        case 1: r = wdrt_engine_strike(e, f, owned, 2, g_ids, v); break;
        case 2: r = wdrt_engine_play(e, f, 1, 1.0, 0, &last); break;
        case 3: r = wdrt_engine_strike(e, f, last, 2, g_ids, v); break;
        default:
            if (i % 10 == 4)
                r = wdrt_engine_stop(e, f, last);
            else if (i % 20 == 9)
                r = wdrt_engine_move(e, f, last, (double[3]){(i % 7) - 3.0, 2.0 + (i % 5), 0});
            else if (i % 20 == 19)
                r = wdrt_engine_listen(e, f, (double[3]){0, (i % 3) - 1.0, 0}, NULL);
            else
                r = wdrt_engine_gain(e, f, owned, 0.5 + (i % 3));
            break;
        }
        if (r == WDRT_QUEUE_FULL && spin)
            sched_yield();
    } while (r == WDRT_QUEUE_FULL && spin);
    assert_int_equal(r, WDRT_OK);
    return f;
}

typedef struct producer {
    wdrt_engine *e;
    uint64_t posted; /* frames before which every event is posted (atomic) */
} producer;

static void *produce(void *arg) {
    producer *p = arg;
    for (int i = 0; i < NEV; i++) {
        uint64_t f = post(p->e, i, 1);
        __atomic_store_n(&p->posted, f, __ATOMIC_RELEASE);
    }
    __atomic_store_n(&p->posted, UINT64_MAX, __ATOMIC_RELEASE);
    return NULL;
}

static const long N = 1000 + (long)NEV * EVERY + 4800;

static void test_storm(void **s) {
    (void)s;
    /* the reference: one thread, posting as the render goes */
    wdrt_engine *e = make_engine();
    double *ref = calloc((size_t)N * 2, sizeof(double));
    int next = 0;
    for (long pos = 0; pos < N; pos += HOST) {
        uint32_t n = (uint32_t)(N - pos < HOST ? N - pos : HOST);
        while (next < NEV && 1000 + (uint64_t)next * EVERY < (uint64_t)(pos + n))
            post(e, next++, 0);
        process(e, ref + pos * 2, n);
    }
    wdrt_engine_stats st;
    wdrt_engine_get_stats(e, &st);
    assert_int_equal((int)st.events, NEV);
    assert_int_equal((int)st.late, 0);
    wdrt_engine_uninit(e, NULL);

    /* the storm: a producer thread, the audio thread waiting only for
     * the events of the block it is about to render */
    e = make_engine();
    producer p = {e, 0};
    double *out = calloc((size_t)N * 2, sizeof(double));
    ca_allocs = 0;
    pthread_t th;
    assert_int_equal(pthread_create(&th, NULL, produce, &p), 0);
    for (long pos = 0; pos < N; pos += HOST) {
        uint32_t n = (uint32_t)(N - pos < HOST ? N - pos : HOST);
        while (__atomic_load_n(&p.posted, __ATOMIC_ACQUIRE) < (uint64_t)(pos + n) &&
               __atomic_load_n(&p.posted, __ATOMIC_ACQUIRE) != UINT64_MAX)
            sched_yield();
        process(e, out + pos * 2, n);
    }
    pthread_join(th, NULL);
    wdrt_engine_get_stats(e, &st);
    print_message("storm: %llu events, %llu late, %llu to ended notes, %llu steals; %ld allocations in process\n",
                  (unsigned long long)st.events, (unsigned long long)st.late, (unsigned long long)st.dropped,
                  (unsigned long long)st.steals, ca_allocs);
    assert_int_equal((int)st.events, NEV);
    assert_int_equal((int)st.late, 0);
    assert_int_equal(ca_allocs, 0);
    long diff = 0;
    for (long i = 0; i < N * 2; i++)
        diff += out[i] != ref[i];
    assert_int_equal(diff, 0);
    double pk = 0;
    for (long i = 0; i < N * 2; i++)
        pk = fmax(pk, fabs(out[i]));
    assert_true(pk > 1e-3 && isfinite(pk));
    free(out);
    free(ref);
    wdrt_engine_uninit(e, NULL);
}


/* ---- bodies: a physics thread ---- */

#define NHIT 20000
#define HIT_EVERY 7

/* Bodies on a shared resonator, placed; event i: an impact, or a
 * contact's start, update or stop (ids 0..3). */
static wdrt_engine *make_bodies(wdrt_bodies **hb) {
    wdrt_bodies_config bc = wdrt_bodies_config_init(FS);
    bc.queue = 256;
    bc.contacts = 4;
    assert_int_equal(wdrt_bodies_new(&bc, hb), WDRT_OK);
    static const wdrt_mode jar[3] = {{820, 0.3, 1}, {1910, 0.2, 0.6}, {3300, 0.1, 0.4}};
    static const wdrt_mode floor_[2] = {{120, 0.2, 1}, {300, 0.1, 0.5}};
    wdrt_body b = wdrt_body_init();
    b.modes = jar, b.nmodes = 3, b.placed = 1, b.pos[1] = 2;
    assert_int_equal(wdrt_bodies_add(*hb, &b), 0);
    b.modes = floor_, b.nmodes = 2, b.pos[0] = 1;
    assert_int_equal(wdrt_bodies_add(*hb, &b), 1);
    b.nmodes = 0, b.share = 0;
    for (int i = 2; i < 6; i++)
        assert_int_equal(wdrt_bodies_add(*hb, &b), i);
    static wdrt_pool_config pc[2];
    assert_int_equal(wdrt_bodies_pools(*hb, pc, 0), WDRT_OK);
    wdrt_engine_config ec = wdrt_engine_config_init(FS, 2, 2, pc);
    ec.space.sources = 4;
    wdrt_bodies_attach(*hb, &ec);
    wdrt_engine *e;
    assert_int_equal(wdrt_engine_init(&ec, NULL, &e), WDRT_OK);
    return e;
}

static uint64_t post_hit(wdrt_bodies *h, int i, int spin) {
    uint64_t f = 500 + (uint64_t)i * HIT_EVERY;
    wdrt_result r;
    do {
        int id = i % 4, a = 2 + id;
        switch (i % 6) {
        case 0:
        case 3: r = wdrt_bodies_impact(h, f, a, i % 2, 0.001 + 0.0001 * (i % 9), 0.5, 0.1 * (i % 3)); break;
        case 1: r = wdrt_bodies_contact(h, f, id, a, 1, 0.1, 0.3, 0.2, 0.5 + (i % 5)); break;
        case 2: r = wdrt_bodies_contact(h, f, id, a, 1, 0.2, 0.5, 0.3, 0.2); break;
        case 4: r = wdrt_bodies_contact_stop(h, f, id); break;
        default: r = wdrt_bodies_enable(h, f, a, i % 12 != 5); break;
        }
        if (r == WDRT_QUEUE_FULL && spin)
            sched_yield();
    } while (r == WDRT_QUEUE_FULL && spin);
    assert_int_equal(r, WDRT_OK);
    return f;
}

typedef struct hproducer {
    wdrt_bodies *h;
    uint64_t posted;
} hproducer;

static void *produce_hits(void *arg) {
    hproducer *p = arg;
    for (int i = 0; i < NHIT; i++) {
        uint64_t f = post_hit(p->h, i, 1);
        __atomic_store_n(&p->posted, f, __ATOMIC_RELEASE);
    }
    __atomic_store_n(&p->posted, UINT64_MAX, __ATOMIC_RELEASE);
    return NULL;
}

static void test_bodies_storm(void **s) {
    (void)s;
    const long M = 500 + (long)NHIT * HIT_EVERY + 4800;
    wdrt_bodies *h;
    wdrt_engine *e = make_bodies(&h);
    double *ref = calloc((size_t)M * 2, sizeof(double));
    int next = 0;
    for (long pos = 0; pos < M; pos += HOST) {
        uint32_t n = (uint32_t)(M - pos < HOST ? M - pos : HOST);
        while (next < NHIT && 500 + (uint64_t)next * HIT_EVERY < (uint64_t)(pos + n))
            post_hit(h, next++, 0);
        process(e, ref + pos * 2, n);
    }
    wdrt_engine_uninit(e, NULL);
    wdrt_bodies_free(h);
    e = make_bodies(&h);
    hproducer p = {h, 0};
    double *out = calloc((size_t)M * 2, sizeof(double));
    ca_allocs = 0;
    pthread_t th;
    assert_int_equal(pthread_create(&th, NULL, produce_hits, &p), 0);
    for (long pos = 0; pos < M; pos += HOST) {
        uint32_t n = (uint32_t)(M - pos < HOST ? M - pos : HOST);
        while (__atomic_load_n(&p.posted, __ATOMIC_ACQUIRE) < (uint64_t)(pos + n) &&
               __atomic_load_n(&p.posted, __ATOMIC_ACQUIRE) != UINT64_MAX)
            sched_yield();
        process(e, out + pos * 2, n);
    }
    pthread_join(th, NULL);
    wdrt_bodies_stats bs;
    wdrt_bodies_get_stats(h, &bs);
    long diff = 0;
    double pk = 0;
    for (long i = 0; i < M * 2; i++)
        diff += out[i] != ref[i], pk = fmax(pk, fabs(out[i]));
    print_message("bodies storm: %d events, contacts high-water %d, impacts high-water %d, %llu refused, %ld "
                  "allocations in process, %ld samples differ, peak %.3g\n",
                  NHIT, bs.contacts_hwm, bs.impacts_hwm, (unsigned long long)bs.refused, ca_allocs, diff, pk);
    assert_int_equal(ca_allocs, 0);
    assert_int_equal(diff, 0);
    assert_true(pk > 1e-4 && isfinite(pk));
    free(out);
    free(ref);
    wdrt_engine_uninit(e, NULL);
    wdrt_bodies_free(h);
}

int main(void) {
    const struct CMUnitTest tests[] = {cmocka_unit_test(ca_test_counter_counts), cmocka_unit_test(test_storm),
                                       cmocka_unit_test(test_bodies_storm)};
    return cmocka_run_group_tests(tests, setup, teardown);
}
