/*
 * rtbench.c - the economy of the engine (libwdrt): what voices that do not
 * sound cost, and what a played piano costs.
 *
 *     build/bench/rtbench
 *
 * Three voices are built as bench.c builds them (bin/wdc, then $CC with
 * -O2 -march=native): scenes/piano_key.wdn, netlists/mallet_plate.wdn and
 * netlists/hammer_bar.wdn.  Engines run at 48 kHz in grid blocks of 64
 * frames; the host renders in process calls of 256 frames (the piano: 64,
 * to sample the stats every block), on this one thread.  Times are wall
 * time on the monotonic clock around process calls only (set-up and
 * posting the events are not timed); a measurement is the best of several
 * runs, the runs of the engines compared taking turns.
 *
 *   1. Scene economy: 1000 standing voices in 370 owned pools (300
 *      piano_key pools of one voice on the 88 pitches, 40 mallet_plate
 *      pools of 10 with their own hardness, 30 hammer_bar pools of 10),
 *      stereo with a pan per pool.  The mallets and hammers start with
 *      their striker at rest (a strike of speed 0 to every such pool at
 *      frame 0), so the 990 voices that are not played are quiet from the
 *      start and fall asleep after the pools' hold (0.1 s).  Ten of them
 *      (4 piano keys, 3 mallets, 3 hammers) are struck every 0.5 s at
 *      speeds that vary.  An engine holding only those ten, in pools of
 *      one with the same settings and in the same order, gets the same
 *      events.  After 1 s rendered untimed, each renders 7 spans of 5 s;
 *      the best span gives ns per sample.  The renders must be equal bit
 *      for bit: a sleeping voice is not visited, and the ten are rendered
 *      and mixed in the same order.
 *   2. Cost of a sleeping voice: engines with N = 0, 1000, 10000 and
 *      100000 mallet_plate standing voices (pools of 200, hold 0), made
 *      quiet at frame 0 and asleep after two blocks, and one more mallet
 *      struck every 0.5 s; best of 7 spans of 10 s.  The cost of a sleeper
 *      is (t_N - t_0) / N per sample.
 *   3. The 88-key piano: a pool of 32 piano_key notes (2 spares for the
 *      fade-outs of stolen notes, cost measured at init, gain 20, centre),
 *      every key from A0 (27.5 Hz) to C8 (4186 Hz, 12-TET) played once
 *      within 30 s as three diminished-seventh arpeggios over the whole
 *      keyboard (up from A0, down from A#7, up from B0), one note every
 *      0.34 s with a little timing jitter, hammer speeds that swell with
 *      each sweep (0.5 to 5 m/s); each note is wdrt_engine_play, a set of
 *      f0 and a strike of both hammers.  Rendered to 35 s with the
 *      sustain pedal changed between the sweeps (the dampers, dmp = 50,
 *      fall on the notes of a sweep 50 ms after the next one begins; the
 *      last sweep rings out), and again with the pedal held throughout.
 *      Best of 3 renders from a fresh engine, each process call timed on
 *      its own (with a wdrt_engine_get_stats after it, which gives the
 *      peak and mean awake voices): the longest call, and how many took
 *      longer than the 1.33 ms of audio they render, show what a note-on
 *      costs the audio thread.
 *   4. For context, one piano_key voice struck every second (2 m/s):
 *      alone through wdrt_render in blocks of 64, and as the one standing
 *      voice of a mono engine at gain 1 (whose output must equal it bit
 *      for bit); best of 7 spans of 10 s.  Then each key of the piano's
 *      score alone, from a copy of a state as init leaves it (as a pool
 *      starts a note): the time of its note-on (set_param of f0, which
 *      redesigns the strings' loops, and set_ic), and ns per sample over
 *      the 2 s after it; best of 2.
 *   5. Pools in lanes: a pool of 64 mallet_plate standing voices, every
 *      one struck at frame 0 and again every 0.5 s (at speeds that vary
 *      from voice to voice), mono; the class as built (with --batch: the
 *      engine renders runs of eight voices through process_batch) and the
 *      same class without process_batch (a process call per voice).  Best
 *      of 5 spans of 5 s each, taking turns; ns per voice-sample, and the
 *      two renders must be equal bit for bit.
 *
 * The voices are built with --batch (their process is the same without).
 *
 * A benchmark, not a test: nothing is asserted about times.  The exit
 * status is non-zero only if a voice could not be built, an engine could
 * not be made or refused an event, or a render was not finite.
 */
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "benchlib.h"
#include "wdrt.h"
#include "wdvoice.h"
#include "../tests/testlib.h"

#define FS 48000.0
#define BLOCK 64 /* the engines' grid block */
#define HOST 256 /* frames per process call */
#define CFLAGS BENCH_CFLAGS

static long frames_of(double seconds) { return (long)floor(seconds * FS + 0.5); }

/* ---- the voices ---- */

enum { PIANO, MALLET, HAMMER, NKIND };
static const char *const g_netlist[NKIND] = {"scenes/piano_key.wdn", "netlists/mallet_plate.wdn",
                                             "netlists/hammer_bar.wdn"};
static const char *const g_output[NKIND] = {"bridge", "v1", "vbar"}; /* the output heard */
static const double g_gain[NKIND] = {20, 0.5, 0.3};
static tl_voice g_voice[NKIND];
static const wdv_class *g_cls[NKIND];
static int g_out[NKIND];
static int g_ic[NKIND][4]; /* strike targets: speed and gap of each hammer */
static int g_nic[NKIND];
static int g_f0, g_dmp, g_hard; /* params */

static void fatal(const char *what, wdrt_result r) {
    fprintf(stderr, "rtbench: %s: %s\n", what, wdrt_result_str(r));
    exit(1);
}

static void ok(wdrt_result r, const char *what) {
    if (r != WDRT_OK)
        fatal(what, r);
}

static int ic_id(const wdv_class *c, const char *name) {
    for (int i = 0; i < c->n_ic_targets; i++)
        if (!strcmp(c->ic_targets[i].name, name))
            return i;
    fprintf(stderr, "rtbench: %s has no strike target %s\n", c->name, name);
    exit(1);
}

static void build_voices(void) {
    static const char *const ics[NKIND][4] = {
        {"v(h1)", "x(h1)", "v(h2)", "x(h2)"}, {"v(m)", "x(m)", NULL, NULL}, {"v(h)", "x(h)", NULL, NULL}};
    for (int k = 0; k < NKIND; k++) {
        static const char *const batch[] = {"--batch", NULL};
        if (tl_voice_build_args(g_netlist[k], 0, batch, CFLAGS, &g_voice[k]) != 0)
            exit(1);
        g_cls[k] = g_voice[k].cls;
        g_out[k] = tl_output_id(g_cls[k], g_output[k]);
        if (g_out[k] < 0) {
            fprintf(stderr, "rtbench: %s has no output %s\n", g_cls[k]->name, g_output[k]);
            exit(1);
        }
        for (g_nic[k] = 0; g_nic[k] < 4 && ics[k][g_nic[k]]; g_nic[k]++)
            g_ic[k][g_nic[k]] = ic_id(g_cls[k], ics[k][g_nic[k]]);
    }
    g_f0 = tl_param_id(g_cls[PIANO], "f0");
    g_dmp = tl_param_id(g_cls[PIANO], "dmp");
    g_hard = tl_param_id(g_cls[MALLET], "hard");
    if (g_f0 < 0 || g_dmp < 0 || g_hard < 0) {
        fprintf(stderr, "rtbench: a param (f0, dmp, hard) is missing\n");
        exit(1);
    }
}

/* The values of a strike of `kind` at hammer speed `speed` (m/s). */
static void strike_vals(int kind, double speed, double *vals) {
    double gap = kind == MALLET ? -0.5e-3 : -1e-3;
    for (int j = 0; j < g_nic[kind]; j += 2)
        vals[j] = speed, vals[j + 1] = gap;
}

static void strike(wdrt_engine *e, long frame, wdrt_voice v, int kind, double speed) {
    double vals[4];
    strike_vals(kind, speed, vals);
    ok(wdrt_engine_strike(e, (uint64_t)frame, v, g_nic[kind], g_ic[kind], vals), "strike");
}

static wdrt_pool_config pool_of(int kind, int voices, int owned) {
    wdrt_pool_config p = wdrt_pool_config_init(g_cls[kind], voices);
    p.owned = owned;
    p.output = g_out[kind];
    p.gain = g_gain[kind];
    return p;
}

/* An engine of npools pools; *mb gets its size in MB and *init_s the
 * seconds its init took (when not NULL). */
static wdrt_engine *make_engine(int nch, int npools, const wdrt_pool_config *pc, double *mb, double *init_s) {
    wdrt_engine_config ec = wdrt_engine_config_init(FS, nch, npools, pc);
    ec.block = BLOCK;
    size_t sz = 0;
    ok(wdrt_engine_get_size(&ec, &sz), "engine size");
    wdrt_engine *e;
    double t0 = bench_now();
    ok(wdrt_engine_init(&ec, NULL, &e), "engine init");
    if (init_s)
        *init_s = bench_now() - t0;
    if (mb)
        *mb = (double)sz / 1e6;
    return e;
}

/* Renders n frames of e into out (n * nch doubles) in calls of hb. */
static void render(wdrt_engine *e, double *out, long n, int nch, int hb) {
    for (long pos = 0; pos < n; pos += hb) {
        long k = n - pos < hb ? n - pos : hb;
        wdrt_engine_process(e, out + pos * nch, (uint32_t)k);
    }
}

/* Zeroed doubles, their pages touched before any timing. */
static double *buf(size_t n) {
    double *b = malloc(sizeof(double) * (n ? n : 1));
    if (!b) {
        fprintf(stderr, "rtbench: out of memory\n");
        exit(1);
    }
    memset(b, 0, sizeof(double) * (n ? n : 1));
    return b;
}

static int all_finite(const double *x, size_t n) {
    for (size_t i = 0; i < n; i++)
        if (!isfinite(x[i]))
            return 0;
    return 1;
}

/* First index where a and b differ in bits, or -1. */
static long first_diff(const double *a, const double *b, size_t n) {
    for (size_t i = 0; i < n; i++)
        if (memcmp(&a[i], &b[i], sizeof(double)))
            return (long)i;
    return -1;
}

/* ---- 1. scene economy ---- */

#define SC_PIANOS 300   /* pools of one piano_key */
#define SC_MALLETS 40   /* pools of SC_EACH mallet_plate */
#define SC_HAMMERS 30   /* pools of SC_EACH hammer_bar */
#define SC_EACH 10
#define SC_POOLS (SC_PIANOS + SC_MALLETS + SC_HAMMERS)
#define SC_VOICES (SC_PIANOS + (SC_MALLETS + SC_HAMMERS) * SC_EACH)
#define SC_SOUNDING 10
#define SC_WARM 1.0
#define SC_SPAN 5.0
#define SC_RUNS 7
#define SC_PERIOD 0.5
#define SC_MAXEV 1024

typedef struct slot {
    int pool, index;
} slot;

/* the ten that sound, in the order of their pools */
static const slot g_sounding[SC_SOUNDING] = {
    {37, 0},
    {101, 0},
    {164, 0},
    {230, 0},
    {SC_PIANOS + 5, 3},
    {SC_PIANOS + 18, 7},
    {SC_PIANOS + 31, 0},
    {SC_PIANOS + SC_MALLETS + 4, 5},
    {SC_PIANOS + SC_MALLETS + 12, 9},
    {SC_PIANOS + SC_MALLETS + 26, 2},
};

typedef struct hit {
    long frame;
    int who; /* index into g_sounding */
    double speed;
} hit;

static int pool_kind(int p) { return p < SC_PIANOS ? PIANO : p < SC_PIANOS + SC_MALLETS ? MALLET : HAMMER; }

typedef struct scene_result {
    double ns[2], mb[2], init[2], first[2]; /* first: the first process call, s */
    int voices[2], asleep[2], awake[2];
    long diff_timed, diff_warm;
    int finite;
} scene_result;

static void scene(scene_result *res) {
    static wdrt_pool_config full[SC_POOLS], small[SC_SOUNDING];
    static double par[SC_POOLS][2];
    tl_rng rng;
    tl_rng_seed(&rng, 0x5CE9Eull);
    for (int p = 0; p < SC_POOLS; p++) {
        int kind = pool_kind(p);
        full[p] = pool_of(kind, kind == PIANO ? 1 : SC_EACH, 1);
        full[p].pan = 1.6 * tl_rng_uniform(&rng) - 0.8;
        full[p].cost_ns = 50; /* only the budget reads it, and there is none */
        if (kind == PIANO) {
            par[p][g_f0] = 27.5 * pow(2, (double)((p * 41) % 88) / 12);
            par[p][g_dmp] = 1e-6;
            full[p].params = par[p];
        } else if (kind == MALLET) {
            par[p][g_hard] = 0.3 + 3 * tl_rng_uniform(&rng);
            full[p].params = par[p];
        }
    }
    for (int s = 0; s < SC_SOUNDING; s++) {
        small[s] = full[g_sounding[s].pool];
        small[s].voices = 1;
    }
    /* the strikes, the same for both */
    static hit hits[SC_MAXEV];
    int nhits = 0;
    double total = SC_WARM + SC_RUNS * SC_SPAN;
    for (int s = 0; s < SC_SOUNDING; s++)
        for (double t = 0.02 + 0.05 * s; t < total && nhits < SC_MAXEV; t += SC_PERIOD) {
            int kind = pool_kind(g_sounding[s].pool);
            double lo = kind == PIANO ? 0.7 : 0.5, hi = kind == PIANO ? 3.0 : 2.0;
            hits[nhits].frame = frames_of(t);
            hits[nhits].who = s;
            hits[nhits++].speed = lo + (hi - lo) * tl_rng_uniform(&rng);
        }

    wdrt_engine *e[2];
    e[0] = make_engine(2, SC_SOUNDING, small, &res->mb[0], &res->init[0]);
    e[1] = make_engine(2, SC_POOLS, full, &res->mb[1], &res->init[1]);
    res->voices[0] = SC_SOUNDING;
    res->voices[1] = SC_VOICES;
    /* strikers at rest at frame 0, then the ten struck */
    for (int s = 0; s < SC_SOUNDING; s++)
        if (pool_kind(g_sounding[s].pool) != PIANO)
            strike(e[0], 0, wdrt_engine_pool(e[0], s), pool_kind(g_sounding[s].pool), 0);
    for (int p = 0; p < SC_POOLS; p++)
        if (pool_kind(p) != PIANO)
            strike(e[1], 0, wdrt_engine_pool(e[1], p), pool_kind(p), 0);
    for (int i = 0; i < nhits; i++) {
        const slot *sl = &g_sounding[hits[i].who];
        int kind = pool_kind(sl->pool);
        strike(e[0], hits[i].frame, wdrt_engine_voice(e[0], hits[i].who, 0), kind, hits[i].speed);
        strike(e[1], hits[i].frame, wdrt_engine_voice(e[1], sl->pool, sl->index), kind, hits[i].speed);
    }

    long nw = frames_of(SC_WARM), ns = frames_of(SC_SPAN);
    double *warm[2], *out[2];
    for (int k = 0; k < 2; k++) {
        warm[k] = buf((size_t)nw * 2);
        out[k] = buf((size_t)ns * 2 * SC_RUNS);
        double t0 = bench_now();
        render(e[k], warm[k], HOST, 2, HOST);
        res->first[k] = bench_now() - t0;
        render(e[k], warm[k] + 2 * HOST, nw - HOST, 2, HOST);
        wdrt_engine_stats st;
        wdrt_engine_get_stats(e[k], &st);
        res->asleep[k] = st.asleep;
        res->awake[k] = st.awake;
        res->ns[k] = INFINITY;
    }
    for (int r = 0; r < SC_RUNS; r++)
        for (int j = 0; j < 2; j++) {
            int k = (r & 1) ? 1 - j : j;
            double t0 = bench_now();
            render(e[k], out[k] + (size_t)r * (size_t)ns * 2, ns, 2, HOST);
            double dt = bench_now() - t0;
            if (dt * 1e9 / (double)ns < res->ns[k])
                res->ns[k] = dt * 1e9 / (double)ns;
        }
    size_t nt = (size_t)ns * 2 * SC_RUNS;
    res->diff_timed = first_diff(out[1], out[0], nt);
    res->diff_warm = first_diff(warm[1], warm[0], (size_t)nw * 2);
    res->finite = all_finite(out[0], nt) && all_finite(out[1], nt);
    for (int k = 0; k < 2; k++) {
        free(warm[k]);
        free(out[k]);
        wdrt_engine_uninit(e[k], NULL);
    }
}

/* ---- 2. the cost of a sleeping voice ---- */

#define SL_EACH 200 /* sleepers per pool */
#define SL_SPAN 10.0
#define SL_RUNS 7
#define SL_WARM 0.1
#define SL_NCASE 4
static const int g_nsleep[SL_NCASE] = {0, 1000, 10000, 100000};

typedef struct sleep_result {
    double ns[SL_NCASE], mb[SL_NCASE];
    int asleep[SL_NCASE];
    int same; /* every render equals N = 0's */
    int finite;
} sleep_result;

static void sleepers(sleep_result *res) {
    wdrt_engine *e[SL_NCASE];
    long nw = frames_of(SL_WARM), ns = frames_of(SL_SPAN);
    double *out[SL_NCASE];
    tl_rng rng;
    double speed[64];
    tl_rng_seed(&rng, 0x51EE9ull);
    for (int i = 0; i < 64; i++)
        speed[i] = 0.5 + 1.5 * tl_rng_uniform(&rng);
    double total = SL_WARM + SL_RUNS * SL_SPAN;
    for (int c = 0; c < SL_NCASE; c++) {
        int npools = 1 + g_nsleep[c] / SL_EACH;
        wdrt_pool_config *pc = calloc((size_t)npools, sizeof *pc);
        if (!pc)
            fatal("pools", WDRT_OUT_OF_MEMORY);
        for (int p = 0; p < npools; p++) {
            pc[p] = pool_of(MALLET, p ? SL_EACH : 1, 1);
            pc[p].cost_ns = 50;
            if (p)
                pc[p].hold = 0;
        }
        e[c] = make_engine(1, npools, pc, &res->mb[c], NULL);
        free(pc);
        for (int p = 1; p < npools; p++)
            strike(e[c], 0, wdrt_engine_pool(e[c], p), MALLET, 0);
        int i = 0;
        for (double t = 0.01; t < total; t += 0.5, i++)
            strike(e[c], frames_of(t), wdrt_engine_voice(e[c], 0, 0), MALLET, speed[i % 64]);
        double *w = buf((size_t)nw);
        render(e[c], w, nw, 1, HOST);
        free(w);
        wdrt_engine_stats st;
        wdrt_engine_get_stats(e[c], &st);
        res->asleep[c] = st.asleep;
        res->ns[c] = INFINITY;
        out[c] = buf((size_t)ns);
    }
    res->same = res->finite = 1;
    for (int r = 0; r < SL_RUNS; r++) {
        for (int j = 0; j < SL_NCASE; j++) {
            int c = (r & 1) ? SL_NCASE - 1 - j : j;
            double t0 = bench_now();
            render(e[c], out[c], ns, 1, HOST);
            double dt = bench_now() - t0;
            if (dt * 1e9 / (double)ns < res->ns[c])
                res->ns[c] = dt * 1e9 / (double)ns;
        }
        for (int c = 0; c < SL_NCASE; c++) {
            if (first_diff(out[c], out[0], (size_t)ns) >= 0)
                res->same = 0;
            if (!all_finite(out[c], (size_t)ns))
                res->finite = 0;
        }
    }
    for (int c = 0; c < SL_NCASE; c++) {
        free(out[c]);
        wdrt_engine_uninit(e[c], NULL);
    }
}

/* ---- 3. the 88-key piano ---- */

#define PN_KEYS 88
#define PN_POOL 32
#define PN_RUNS 3
#define PN_LEN 35.0
#define PN_CALL 64 /* frames per process call: stats every block */

typedef struct piano_result {
    double wall, peak, mean_awake;
    double worst;    /* the longest process call, s */
    int over;        /* process calls that took longer than the frames they rendered */
    double wall_on;  /* time of the calls in which a note starts, s */
    int calls_on, over_on;
    double ns_other; /* ns per awake voice and sample in the other calls */
    int peak_awake, finite, same;
    uint64_t hash;   /* of the render */
    double pool_cost;
    wdrt_engine_stats st;
} piano_result;

typedef struct note {
    long frame;
    int key;
    double speed;
} note;

/* Three diminished-seventh arpeggios over the keyboard: up from A0 (keys
 * 0, 3, ... 87), down from A#7 (85 ... 1), up from B0 (2 ... 86); one
 * note every 0.34 s with up to 8 ms of jitter, speeds swelling with each
 * sweep.  *sweep_start gets the index of each sweep's first note. */
static void piano_score(note *score, int *sweep_start) {
    tl_rng rng;
    tl_rng_seed(&rng, 0x88ull);
    int n = 0;
    for (int s = 0; s < 3; s++) {
        sweep_start[s] = n;
        int first = s == 0 ? 0 : s == 1 ? 85 : 2, step = s == 1 ? -3 : 3;
        int count = s == 0 ? 30 : 29;
        for (int j = 0; j < count; j++, n++) {
            double u = (double)j / (count - 1);
            double swell = s == 1 ? 4.2 - 3.2 * u : 0.8 + 3.4 * u;
            double v = swell * (0.85 + 0.3 * tl_rng_uniform(&rng));
            score[n].key = first + step * j;
            score[n].speed = v < 0.5 ? 0.5 : v > 5 ? 5 : v;
            score[n].frame = frames_of(0.1 + 0.34 * n + 0.008 * tl_rng_signed(&rng));
        }
    }
    sweep_start[3] = n;
}

/* "A0", "C#4"... for key k of 88 (0: A0) */
static void key_name(int k, char *buf, size_t cap) {
    static const char *const nm[12] = {"C", "C#", "D", "D#", "E", "F", "F#", "G", "G#", "A", "A#", "B"};
    snprintf(buf, cap, "%s%d", nm[(k + 9) % 12], (k + 9) / 12);
}

static uint64_t fnv(uint64_t h, const void *p, size_t n) {
    const unsigned char *c = p;
    for (size_t i = 0; i < n; i++)
        h = (h ^ c[i]) * 0x100000001B3ull;
    return h;
}

/* Posts the notes of the score (play, f0, strike) and the dampers of the
 * pedal changes that fall before frame `to`, from *next_note and
 * *next_damp on: f0 through wdrt_engine_set_prepared when `prepared` (the
 * strings' loops designed here, on the producer's side). */
static void piano_post(wdrt_engine *e, const note *score, const int *sweep, int pedal_changes, int prepared, long to,
                       wdrt_voice *notes, int *next_note, int *next_damp) {
    for (;;) {
        long fd = LONG_MAX; /* the dampers of a sweep fall 50 ms after the next one begins */
        if (pedal_changes && *next_damp < sweep[2])
            fd = score[sweep[*next_damp >= sweep[1] ? 2 : 1]].frame + frames_of(0.05);
        long fn = *next_note < PN_KEYS ? score[*next_note].frame : LONG_MAX;
        if (fn < to && fn <= fd) {
            int i = (*next_note)++;
            long f = score[i].frame;
            double f0 = 27.5 * pow(2, score[i].key / 12.0);
            ok(wdrt_engine_play(e, (uint64_t)f, 0, 1.0, 0, &notes[i]), "play");
            if (prepared)
                ok(wdrt_engine_set_prepared(e, (uint64_t)f, notes[i], 1, &g_f0, &f0), "set f0");
            else
                ok(wdrt_engine_set(e, (uint64_t)f, notes[i], g_f0, f0), "set f0");
            strike(e, f, notes[i], PIANO, score[i].speed);
        } else if (fd < to && *next_note > *next_damp) {
            ok(wdrt_engine_set(e, (uint64_t)fd, notes[*next_damp], g_dmp, 50), "set dmp");
            ++*next_damp;
        } else {
            return;
        }
    }
}

static void piano(int pedal_changes, int prepared, piano_result *res) {
    note score[PN_KEYS];
    int sweep[4];
    piano_score(score, sweep);
    wdrt_pool_config pc = pool_of(PIANO, PN_POOL, 0);
    res->wall = INFINITY;
    res->same = res->finite = 1;
    uint64_t hash0 = 0;
    for (int r = 0; r < PN_RUNS; r++) {
        wdrt_engine *e = make_engine(2, 1, &pc, NULL, NULL);
        res->pool_cost = wdrt_engine_pool_cost(e, 0);
        wdrt_voice notes[PN_KEYS];
        int next_note = 0, next_damp = 0;
        long n = frames_of(PN_LEN);
        double out[2 * PN_CALL], peak = 0, awake_sum = 0, awake_other = 0;
        int peak_awake = 0, finite = 1, on = 0; /* on: the next note of the score */
        long calls = 0;
        uint64_t hash = 0xCBF29CE484222325ull;
        double wall = 0, worst = 0, wall_on = 0;
        int over = 0, over_on = 0, calls_on = 0;
        for (long pos = 0; pos < n; pos += PN_CALL, calls++) {
            uint32_t k = (uint32_t)(n - pos < PN_CALL ? n - pos : PN_CALL);
            int has_on = 0; /* a note starts in this call */
            while (on < PN_KEYS && score[on].frame < pos + (long)k)
                has_on = 1, on++;
            /* the producer, untimed: what falls before the end of the next call */
            piano_post(e, score, sweep, pedal_changes, prepared, pos + k + PN_CALL, notes, &next_note, &next_damp);
            double t0 = bench_now();
            wdrt_engine_process(e, out, k);
            wdrt_engine_stats st;
            wdrt_engine_get_stats(e, &st);
            double dt = bench_now() - t0;
            wall += dt;
            worst = dt > worst ? dt : worst;
            over += dt > k / FS;
            if (has_on) {
                wall_on += dt;
                calls_on++;
                over_on += dt > k / FS;
            } else {
                awake_other += st.awake * (double)k;
            }
            if (st.awake > peak_awake)
                peak_awake = st.awake;
            awake_sum += st.awake;
            for (uint32_t j = 0; j < 2 * k; j++) {
                finite &= isfinite(out[j]) != 0;
                peak = fabs(out[j]) > peak ? fabs(out[j]) : peak;
            }
            hash = fnv(hash, out, sizeof(double) * 2 * k);
        }
        res->hash = hash;
        if (r == 0)
            hash0 = hash;
        else if (hash != hash0)
            res->same = 0;
        res->finite &= finite;
        if (wall < res->wall) {
            res->wall = wall, res->worst = worst, res->over = over;
            res->wall_on = wall_on, res->calls_on = calls_on, res->over_on = over_on;
            res->ns_other = awake_other > 0 ? (wall - wall_on) * 1e9 / awake_other : 0;
        }
        res->peak = peak;
        res->peak_awake = peak_awake;
        res->mean_awake = awake_sum / (double)calls;
        wdrt_engine_get_stats(e, &res->st);
        wdrt_engine_uninit(e, NULL);
    }
}

/* ---- 4. one piano_key voice: alone and in an engine ---- */

#define ONE_SPAN 10.0
#define ONE_RUNS 7

#define KEY_LEN 2.0
#define KEY_RUNS 2

typedef struct one_result {
    double alone, engine, est;
    double key_mean, key_min, key_max; /* the 88 keys alone */
    double on_mean, on_max, on_sum;    /* their set of f0 and strike, s */
    int on_max_key;
    int same, finite;
} one_result;

static void one_voice(one_result *res) {
    const wdv_class *c = g_cls[PIANO];
    void *st = tl_state_new(c, FS);
    if (!st)
        fatal("state", WDRT_OUT_OF_MEMORY);
    wdrt_pool_config pc = pool_of(PIANO, 1, 1);
    pc.gain = 1;
    wdrt_engine *e = make_engine(1, 1, &pc, NULL, NULL);
    res->est = wdrt_engine_pool_cost(e, 0);
    long ns = frames_of(ONE_SPAN), every = frames_of(1.0);
    for (long f = 0; f < ns * ONE_RUNS; f += every)
        strike(e, f, wdrt_engine_voice(e, 0, 0), PIANO, 2.0);
    double vals[4];
    strike_vals(PIANO, 2.0, vals);
    double **o = tl_bufs_new(c->n_outputs, ns);
    double *y = buf((size_t)ns);
    if (!o)
        fatal("buffers", WDRT_OUT_OF_MEMORY);
    for (int k = 0; k < c->n_outputs; k++)
        memset(o[k], 0, sizeof(double) * (size_t)ns);
    res->alone = res->engine = INFINITY;
    res->same = res->finite = 1;
    long t = 0; /* the voice alone's frame */
    for (int r = 0; r < ONE_RUNS; r++) {
        for (int j = 0; j < 2; j++) {
            int which = (r & 1) ? 1 - j : j;
            double t0 = bench_now();
            if (which == 0) {
                for (long pos = 0; pos < ns; pos += BLOCK, t += BLOCK) {
                    double *op[16];
                    if (t % every == 0)
                        c->set_ic(st, g_nic[PIANO], g_ic[PIANO], vals);
                    for (int k = 0; k < c->n_outputs && k < 16; k++)
                        op[k] = o[k] + pos;
                    wdrt_render(c, st, NULL, op, ns - pos < BLOCK ? ns - pos : BLOCK, BLOCK);
                }
            } else {
                render(e, y, ns, 1, HOST);
            }
            double dt = (bench_now() - t0) * 1e9 / (double)ns;
            double *best = which ? &res->engine : &res->alone;
            if (dt < *best)
                *best = dt;
        }
        if (first_diff(y, o[g_out[PIANO]], (size_t)ns) >= 0)
            res->same = 0;
        if (!all_finite(y, (size_t)ns))
            res->finite = 0;
    }
    free(y);
    tl_bufs_free(o, c->n_outputs);
    tl_state_free(st);
    wdrt_engine_uninit(e, NULL);

    /* each key of the score alone, struck at its speed: 2 s from the strike */
    note score[PN_KEYS];
    int sweep[4];
    piano_score(score, sweep);
    long nk = frames_of(KEY_LEN);
    double **ko = tl_bufs_new(c->n_outputs, nk), sum = 0;
    if (!ko)
        fatal("buffers", WDRT_OUT_OF_MEMORY);
    for (int k = 0; k < c->n_outputs; k++)
        memset(ko[k], 0, sizeof(double) * (size_t)nk);
    /* a state as init leaves it (f0 at its default), copied for each note
     * as the engine's pools copy theirs */
    void *tmpl = tl_state_new(c, FS), *ks = tl_state_new(c, FS);
    if (!tmpl || !ks)
        fatal("state", WDRT_OUT_OF_MEMORY);
    res->key_min = INFINITY, res->key_max = 0, res->on_max = 0;
    double on_sum = 0;
    for (int i = 0; i < PN_KEYS; i++) {
        double best = INFINITY, on = INFINITY;
        for (int r = 0; r < KEY_RUNS; r++) {
            memcpy(ks, tmpl, c->state_size);
            strike_vals(PIANO, score[i].speed, vals);
            double t0 = bench_now();
            c->set_param(ks, g_f0, 27.5 * pow(2, score[i].key / 12.0));
            c->set_ic(ks, g_nic[PIANO], g_ic[PIANO], vals);
            double t1 = bench_now();
            wdrt_render(c, ks, NULL, ko, nk, BLOCK);
            double dt = (bench_now() - t1) * 1e9 / (double)nk;
            best = dt < best ? dt : best;
            on = t1 - t0 < on ? t1 - t0 : on;
            res->finite &= all_finite(ko[g_out[PIANO]], (size_t)nk);
        }
        sum += best;
        on_sum += on;
        res->key_min = best < res->key_min ? best : res->key_min;
        res->key_max = best > res->key_max ? best : res->key_max;
        if (on > res->on_max)
            res->on_max = on, res->on_max_key = score[i].key;
    }
    res->key_mean = sum / PN_KEYS;
    res->on_mean = on_sum / PN_KEYS;
    res->on_sum = on_sum;
    tl_state_free(tmpl);
    tl_state_free(ks);
    tl_bufs_free(ko, c->n_outputs);
}

/* ---- 5. pools in lanes ---- */

#define LN_VOICES 64
#define LN_SPAN 5.0
#define LN_RUNS 5

typedef struct lanes_result {
    double ns[2]; /* per voice-sample: process_batch, a process call each */
    int same, finite;
} lanes_result;

static void lanes(lanes_result *res) {
    wdv_class plain = *g_cls[MALLET];
    plain.process_batch = NULL;
    const wdv_class *cls[2] = {g_cls[MALLET], &plain};
    long ns = frames_of(LN_SPAN), every = frames_of(0.5);
    wdrt_engine *e[2];
    double *y[2];
    for (int k = 0; k < 2; k++) {
        wdrt_pool_config pc = pool_of(MALLET, LN_VOICES, 1);
        pc.cls = cls[k];
        e[k] = make_engine(1, 1, &pc, NULL, NULL);
        for (long f = 0; f < ns * LN_RUNS; f += every)
            for (int v = 0; v < LN_VOICES; v++)
                strike(e[k], f, wdrt_engine_voice(e[k], 0, v), MALLET, 0.5 + 0.05 * ((v * 7 + f / every) % 40));
        y[k] = buf((size_t)ns);
        res->ns[k] = INFINITY;
    }
    res->same = res->finite = 1;
    for (int r = 0; r < LN_RUNS; r++) {
        for (int j = 0; j < 2; j++) {
            int k = (r & 1) ? 1 - j : j;
            double t0 = bench_now();
            render(e[k], y[k], ns, 1, HOST);
            double dt = (bench_now() - t0) * 1e9 / ((double)ns * LN_VOICES);
            res->ns[k] = dt < res->ns[k] ? dt : res->ns[k];
            res->finite &= all_finite(y[k], (size_t)ns);
        }
        if (first_diff(y[0], y[1], (size_t)ns) >= 0)
            res->same = 0;
    }
    for (int k = 0; k < 2; k++) {
        free(y[k]);
        wdrt_engine_uninit(e[k], NULL);
    }
}

/* ---- the report ---- */

static const char *yes(int b) { return b ? "yes" : "NO"; }

int main(int argc, char **argv) {
    (void)argv;
    if (argc > 1) {
        fprintf(stderr, "usage: rtbench\n");
        return 2;
    }
    build_voices();
    printf("wdrt engine benchmark: %.0f Hz, grid blocks of %d frames, process calls of %d frames (the piano: %d),\n"
           "one thread; wall time of process calls only, best of several runs\n",
           FS, BLOCK, HOST, PN_CALL);
    bench_print_setup(CFLAGS);
    int failed = 0;
    char cell[3][32];

    scene_result sc;
    scene(&sc);
    printf("1. Scene economy: %d standing voices in %d pools (%d piano_key, %d mallet_plate, %d hammer_bar),\n"
           "   %d of them struck every %.1f s; stereo; best of %d spans of %.0f s after %.0f s untimed\n",
           SC_VOICES, SC_POOLS, SC_PIANOS, SC_MALLETS * SC_EACH, SC_HAMMERS * SC_EACH, SC_SOUNDING, SC_PERIOD,
           SC_RUNS, SC_SPAN, SC_WARM);
    printf("   %-22s %6s %6s %6s %9s %7s %9s %9s %6s\n", "engine", "voices", "awake", "asleep", "memory MB",
           "init s", "1st call", "ns/sample", "ratio");
    printf("   %-22s %6s %6s %6s %9s %7s %9s %9s %6s\n", "----------------------", "------", "------", "------",
           "---------", "-------", "---------", "---------", "------");
    const char *names[2] = {"only the 10 that sound", "the whole scene"};
    for (int k = 0; k < 2; k++)
        printf("   %-22s %6d %6d %6d %9.1f %7.2f %8.3fs %9.1f %6.3f\n", names[k], sc.voices[k], sc.awake[k],
               sc.asleep[k], sc.mb[k], sc.init[k], sc.first[k], sc.ns[k], sc.ns[k] / sc.ns[0]);
    printf("   (awake and asleep when the timing starts; 1st call: the first process call, %d frames)\n", HOST);
    printf("   whole scene / only the 10: %.3fx (target <= 1.2x)\n", sc.ns[1] / sc.ns[0]);
    printf("   renders equal bit for bit: timed spans %s", yes(sc.diff_timed < 0));
    if (sc.diff_timed >= 0)
        printf(" (first difference at sample %ld)", sc.diff_timed);
    printf(", the untimed first %.0f s too: %s%s\n\n", SC_WARM, yes(sc.diff_warm < 0),
           sc.finite ? "" : "  (non-finite output!)");
    failed |= !sc.finite;
    fflush(stdout);

    sleep_result sl;
    sleepers(&sl);
    printf("2. Cost of a sleeping voice: N mallet_plate standing voices asleep (pools of %d), one more struck\n"
           "   every 0.5 s; mono; best of %d spans of %.0f s\n",
           SL_EACH, SL_RUNS, SL_SPAN);
    printf("   %7s %7s %10s %10s %22s\n", "N", "asleep", "memory MB", "ns/sample", "ns/sample per sleeper");
    printf("   %7s %7s %10s %10s %22s\n", "-------", "-------", "----------", "----------",
           "----------------------");
    for (int c = 0; c < SL_NCASE; c++) {
        printf("   %7d %7d %10.1f %10.2f ", g_nsleep[c], sl.asleep[c], sl.mb[c], sl.ns[c]);
        if (g_nsleep[c])
            printf("%22.5f\n", (sl.ns[c] - sl.ns[0]) / g_nsleep[c]);
        else
            printf("%22s\n", "-");
    }
    printf("   (target <= 0.3 ns per sample per sleeper); every render equals N = 0's bit for bit: %s%s\n\n",
           yes(sl.same), sl.finite ? "" : "  (non-finite output!)");
    failed |= !sl.finite;
    fflush(stdout);

    piano_result pn[3];
    piano(1, 0, &pn[0]);
    piano(0, 0, &pn[1]);
    piano(1, 1, &pn[2]);
    printf("3. The 88-key piano: a pool of %d piano_key notes (+2 spares), each key A0..C8 played once in 30 s\n"
           "   (three diminished-seventh arpeggios, speeds 0.5..5 m/s), rendered to %.0f s; stereo; best of %d\n",
           PN_POOL, PN_LEN, PN_RUNS);
    printf("   %-44s %17s %17s %17s\n", "sustain pedal", "changed per sweep", "held throughout", "changed, prepared");
    printf("   %-44s %17s %17s %17s\n", "--------------------------------------------", "-----------------",
           "-----------------", "-----------------");
#define ROW(label, fmt, expr)                                                                                      \
    do {                                                                                                           \
        printf("   %-44s", label);                                                                                \
        for (int k = 0; k < 3; k++) {                                                                              \
            const piano_result *p = &pn[k];                                                                        \
            (void)p;                                                                                               \
            printf(" %17" fmt, expr);                                                                              \
        }                                                                                                          \
        printf("\n");                                                                                              \
    } while (0)
    ROW("wall time of the 35 s, s", ".3f", p->wall);
    ROW("times real time", ".1f", PN_LEN / p->wall);
    ROW("longest process call (64 frames: 1.33 ms), ms", ".2f", p->worst * 1e3);
    ROW("process calls longer than their frames", "d", p->over);
    ROW("peak awake voices", "d", p->peak_awake);
    ROW("mean awake voices", ".1f", p->mean_awake);
    ROW("ns per awake voice and sample", ".1f", p->wall * 1e9 / (p->mean_awake * FS * PN_LEN));
    ROW("process calls in which notes start", "d", p->calls_on);
    ROW("  their time, s", ".3f", p->wall_on);
    ROW("  of them longer than their frames", "d", p->over_on);
    ROW("ns per awake voice and sample, other calls", ".1f", p->ns_other);
    ROW("events (late)", "s", (snprintf(cell[k], sizeof cell[k], "%d (%d)", (int)p->st.events, (int)p->st.late), cell[k]));
    ROW("dropped (to notes that had ended)", "d", (int)p->st.dropped);
    ROW("notes ended asleep", "d", (int)p->st.sleeps);
    ROW("notes stolen (cut with no spare)", "s", (snprintf(cell[k], sizeof cell[k], "%d (%d)", (int)p->st.steals, (int)p->st.cuts), cell[k]));
    ROW("peak output level", ".3f", p->peak);
    ROW("the same render in every run", "s", yes(p->same));
#undef ROW
    printf("   changed, prepared: f0 set with wdrt_engine_set_prepared, the loops designed by the producer (untimed);\n"
           "   the same render as with wdrt_engine_set, bit for bit: %s\n", yes(pn[2].hash == pn[0].hash));
    printf("   the pool's cost as measured at init: %.1f ns/sample\n\n", pn[0].pool_cost);
    if (pn[2].hash != pn[0].hash)
        failed = 1;
    for (int k = 0; k < 3; k++)
        if (!pn[k].finite) {
            printf("   (non-finite output!)\n");
            failed = 1;
        }
    fflush(stdout);

    one_result one;
    one_voice(&one);
    printf("4. One piano_key voice struck every second at 2 m/s: best of %d spans of %.0f s\n", ONE_RUNS, ONE_SPAN);
    printf("   %-38s %10s\n", "", "ns/sample");
    printf("   %-38s %10.1f\n", "alone (wdrt_render, blocks of 64)", one.alone);
    printf("   %-38s %10.1f\n", "the one standing voice of an engine", one.engine);
    printf("   engine overhead: %+.1f ns/sample (%+.1f%%); outputs equal bit for bit: %s\n", one.engine - one.alone,
           100 * (one.engine / one.alone - 1), yes(one.same));
    printf("   the engine's own estimate (measured at init, from the quiet state): %.1f ns/sample\n", one.est);
    printf("   the 88 keys of the score alone, %.0f s from the strike each: mean %.1f ns/sample (%.1f .. %.1f)%s\n",
           KEY_LEN, one.key_mean, one.key_min, one.key_max, one.finite ? "" : "  (non-finite output!)");
    char kn[24];
    key_name(one.on_max_key, kn, sizeof kn);
    printf("   a note-on of those keys (set f0, then the strike, from the state init leaves): mean %.2f ms,\n"
           "   longest %.2f ms (%s), %.2f s for all 88\n\n",
           one.on_mean * 1e3, one.on_max * 1e3, kn, one.on_sum);
    failed |= !one.finite;

    lanes_result ln;
    lanes(&ln);
    printf("5. Pools in lanes: %d mallet_plate standing voices, all struck every 0.5 s; mono; best of %d spans of "
           "%.0f s\n", LN_VOICES, LN_RUNS, LN_SPAN);
    printf("   %-44s %10s\n", "", "ns per voice-sample");
    printf("   %-44s %10.1f\n", "runs of 8 voices through process_batch", ln.ns[0]);
    printf("   %-44s %10.1f\n", "a process call per voice", ln.ns[1]);
    printf("   ratio %.2fx; renders equal bit for bit: %s%s\n\n", ln.ns[1] / ln.ns[0], yes(ln.same),
           ln.finite ? "" : "  (non-finite output!)");
    failed |= !ln.finite || !ln.same;

    for (int k = 0; k < NKIND; k++)
        tl_voice_free(&g_voice[k]);
    return failed;
}
