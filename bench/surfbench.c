/*
 * surfbench.c - what bodies (wdrt.h, "bodies"; runtime/surf.h) cost: one
 * body rung by a contact, a thousand bodies of which ten are struck, a
 * sleeping body, and the world's cost per mode and per generator.
 *
 *     build/bench/surfbench [SECTION]
 *
 * Every engine runs at 48 kHz, mono, in grid blocks of 64 frames with
 * process calls of 64 frames; its bodies come from a wdrt_bodies
 * (wdrt_bodies_pools, wdrt_bodies_attach; max_modes 15, or 64 in section
 * 4).  "World alone" is a surf_world made as wdrt_bodies makes its own
 * (the same config, resonators, surfaces and seed, block 64), run by
 * surf_process in calls of 64 frames into its own mix.  A modal body has
 * 15 modes: from a fixed-seed generator, F_k = f0 (k + 1)^1.15 (+-1.5 %),
 * f0 in 150..500 Hz, T60_k = T0 / (1 + 0.25 k), T0 in 0.8..2 s, gain_k
 * (0.5..1) / (k + 1)^0.7; 0.1 kg, hardness 1e7 N/m, a noise relief of
 * 0.1 mm grain.  The floor is a body of one mode (90 Hz, T60 0.1 s), gain
 * 0, immovable, hardness 1e8 N/m, and switched off from frame 0
 * (wdrt_bodies_enable, surf_body_enable): it is struck and touched, its
 * surface sets the pulses' widths, but its own generators are silent and
 * its resonator never wakes.
 *
 *   1. One active body: the 15-mode body rolling on the floor in one live
 *      contact (1 N, rolling at 0.3 m/s and slipping at 0.3 m/s: the
 *      body's generator reads its noise relief at 0.3 m/s through a
 *      2540 Hz low-pass), through the engine with sleep off, and the
 *      same world alone.  The engine's first second must equal the world
 *      alone's (the floor's gain is 0): its largest difference relative
 *      to the peak is printed.  Its share of one core at 48 kHz is
 *      ns/sample x 48000 / 1e9; Menzies reports about 1 % of a 600 MHz
 *      Pentium III for such a body.
 *   2. A thousand bodies, ten struck: an engine (sleep on, hold 0.1 s) of
 *      1000 bodies: the floor (body 0), ten modal bodies (1..10) each
 *      struck against the floor every 50 ms (body i at frame
 *      240 (i - 1) + 2400 k: 200 impacts a second, impulse 2..10 mN s,
 *      normal speed 0.5..1.5 m/s, tangential 0.05..0.3 m/s, so each has a
 *      skid of a few ms; a hash of (i, k) picks them), and 989 more modal
 *      bodies that are never struck (1000 in all with the floor: each
 *      resonator is an engine pool, and an engine holds at most 1000
 *      pools); against an engine of only the floor and those ten.  The
 *      impacts of a block are posted (wdrt_bodies_impact) before its
 *      process call, inside the timing.  Both render their first 1 s
 *      untimed (the 989 fall asleep after the hold); their renders must
 *      be equal bit for bit (the ten and the floor have the same indices,
 *      so the same surfaces and seeds, in both).
 *   3. A sleeping body: those 1000 bodies, the 999 modal ones each struck
 *      once (at frame 10 i, 5 mN s) and left to ring down until every
 *      resonator and every voice is asleep; then nothing is struck.  The
 *      cost of a sleeper is the engine's ns/sample / 1000; the same for a
 *      world alone of those bodies (never struck: asleep from the start),
 *      and the engine with only the floor and one body asleep, for the
 *      fixed cost of a block.
 *   4. The world's unit costs (world alone): 64 resonators of 15 modes
 *      and 16 of 64 modes, each rung once by an impact (no skid) and
 *      ringing on (quiet 0: they never sleep), ns / modes run: ns per
 *      mode-sample; 32 contacts like section 1's, each on a body whose
 *      resonator runs no mode (surf_resonator_set_active_modes 0), less
 *      the same world with no contact, / 32: ns per generator-sample (the
 *      needle on the noise relief, the low-pass, the force ramp and the
 *      routing into a resonator's input).  surf.h costs a generator as
 *      SURF_GEN_COST modes.
 *
 * Times are wall time on the monotonic clock around the whole loop
 * (posting the events, the process call, a scan of the output for its
 * peak and non-finite values).  The cases of a section take turns, their
 * order rotating, each a bench_measure of one run of >= SPAN s after WARM
 * s untimed; the best of RUNS counts.  The runtime is built with the
 * Makefile's CFLAGS.  A benchmark, not a test: nothing is asserted about
 * times.  The exit status is 1 if an engine or world could not be made
 * or refused an event, or a render was not finite or was silent where it
 * should sound (or 2 on a bad argument).
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "benchlib.h"
#include "surf.h"
#include "wdrt.h"
#include "../tests/testlib.h"

#define FS 48000.0
#define BLOCK 64     /* grid block, process call and world block, frames */
#define NMODES 15    /* modes of a body */
#define NBODIES 1000 /* bodies of sections 2 and 3, the floor counted */
#define NSTRUCK 10   /* of them struck in section 2 */
#define PERIOD 2400  /* frames between the strikes of a body: 50 ms */
#define STAGGER 240  /* frames between the strikes of successive bodies */
#define RUNS 7
#define SPAN 0.3  /* s of wall time per run */
#define WARM 0.05 /* s untimed before each run */
#define FIRST 1.0 /* s rendered untimed, compared, before the runs */
#define GENS 32   /* contacts of section 4 */

static long frames_of(double s) { return (long)floor(s * FS + 0.5); }

static void fail(const char *what, int r) {
    fprintf(stderr, "surfbench: %s: %s\n", what, wdrt_result_str((wdrt_result)r));
    exit(1);
}

static void ok(int r, const char *what) {
    if (r < 0)
        fail(what, r);
}

static void *xcalloc(size_t n, size_t size) {
    void *p = calloc(n ? n : 1, size);
    if (!p) {
        fprintf(stderr, "surfbench: out of memory\n");
        exit(1);
    }
    return p;
}

/* splitmix64's finaliser: the strikes' data from (body, strike). */
static uint64_t mix64(uint64_t x) {
    x += 0x9e3779b97f4a7c15ull;
    x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
    x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
    return x ^ (x >> 31);
}

static double unit(uint64_t h) { return (double)(h >> 11) / 9007199254740992.0; }

/* ---- the bodies ---- */

typedef struct bodyset {
    int n;           /* bodies: the floor, then modal bodies */
    wdrt_body *b;
    wdrt_mode *modes; /* [n][max modes] */
    int max_modes;
} bodyset;

static const wdrt_mode g_floor_mode = {90, 0.1, 1};

/* n modes of a body from rng: f0 in lo..hi Hz. */
static void spectrum(tl_rng *rng, wdrt_mode *m, int n, double lo, double hi) {
    double f0 = lo + (hi - lo) * tl_rng_uniform(rng), T0 = 0.8 + 1.2 * tl_rng_uniform(rng);
    for (int k = 0; k < n; k++) {
        m[k].f = f0 * pow(k + 1, 1.15) * (1 + 0.03 * (tl_rng_uniform(rng) - 0.5));
        m[k].t60 = T0 / (1 + 0.25 * k);
        m[k].gain = (0.5 + 0.5 * tl_rng_uniform(rng)) / pow(k + 1, 0.7);
    }
}

/* The floor and nmodal bodies of `modes` modes each (f0 in lo..hi Hz). */
static void bodyset_make(bodyset *s, int nmodal, int modes, double lo, double hi, uint64_t seed) {
    s->n = 1 + nmodal;
    s->max_modes = modes;
    s->b = xcalloc((size_t)s->n, sizeof *s->b);
    s->modes = xcalloc((size_t)s->n * (size_t)modes, sizeof *s->modes);
    tl_rng rng;
    tl_rng_seed(&rng, seed);
    s->b[0] = wdrt_body_init();
    s->b[0].modes = &g_floor_mode;
    s->b[0].nmodes = 1;
    s->b[0].mass = INFINITY;
    s->b[0].hardness = 1e8;
    s->b[0].gain = 0; /* and switched off: floor_off */
    for (int i = 1; i < s->n; i++) {
        wdrt_mode *m = s->modes + (size_t)i * (size_t)modes;
        spectrum(&rng, m, modes, lo, hi);
        s->b[i] = wdrt_body_init();
        s->b[i].modes = m;
        s->b[i].nmodes = modes;
    }
}

static void bodyset_free(bodyset *s) {
    free(s->b);
    free(s->modes);
}

static wdrt_bodies_config bodies_config(int nbodies, int max_modes) {
    wdrt_bodies_config bc = wdrt_bodies_config_init(FS);
    bc.max_bodies = nbodies;
    bc.max_modes = max_modes;
    return bc;
}

/* An engine of the first n bodies of s: *h gets its wdrt_bodies. */
static wdrt_engine *bodies_engine(const bodyset *s, int n, int sleep, wdrt_bodies **hp) {
    wdrt_bodies_config bc = bodies_config(n, s->max_modes);
    wdrt_bodies *h;
    ok(wdrt_bodies_new(&bc, &h), "wdrt_bodies_new");
    for (int i = 0; i < n; i++)
        if (wdrt_bodies_add(h, &s->b[i]) != i)
            fail("wdrt_bodies_add", WDRT_ERROR);
    int np = wdrt_bodies_npools(h);
    wdrt_pool_config *pc = xcalloc((size_t)np, sizeof *pc);
    ok(wdrt_bodies_pools(h, pc, 0), "wdrt_bodies_pools");
    wdrt_engine_config ec = wdrt_engine_config_init(FS, 1, np, pc);
    ec.block = BLOCK;
    ec.sleep = sleep;
    wdrt_bodies_attach(h, &ec);
    wdrt_engine *e;
    ok(wdrt_engine_init(&ec, NULL, &e), "wdrt_engine_init");
    ok(wdrt_bodies_enable(h, 0, 0, 0), "wdrt_bodies_enable"); /* the floor */
    free(pc);
    *hp = h;
    return e;
}

/* A world of the first n bodies of s made as wdrt_bodies makes its own
 * (bodies.c): the same config, resonators, surfaces, bodies and seed. */
static surf_world *bodies_world(const bodyset *s, int n) {
    wdrt_bodies_config bc = bodies_config(n, s->max_modes);
    surf_config sc = surf_config_init(FS);
    sc.block = BLOCK;
    sc.max_bodies = sc.max_resonators = sc.max_surfaces = bc.max_bodies;
    sc.max_modes = bc.max_modes;
    sc.max_pickups = 1;
    sc.max_contacts = bc.contacts;
    sc.max_impacts = bc.impacts;
    surf_world *w;
    ok(surf_init(&sc, NULL, &w), "surf_init");
    surf_mode *m = xcalloc((size_t)s->max_modes, sizeof *m);
    for (int i = 0; i < n; i++) {
        const wdrt_body *b = &s->b[i];
        for (int k = 0; k < b->nmodes; k++)
            m[k].f = b->modes[k].f, m[k].t60 = b->modes[k].t60, m[k].gain[0] = b->modes[k].gain;
        surf_resonator_desc rd = surf_resonator_desc_init();
        rd.modes = m, rd.nmodes = b->nmodes, rd.npickups = 1, rd.quiet = b->quiet;
        int r = surf_add_resonator(w, &rd);
        ok(r, "surf_add_resonator");
        surf_surface_desc sd = surf_surface_desc_init();
        sd.hardness = b->hardness;
        sd.damping = b->damping;
        sd.relief.kind = b->relief == WDRT_RELIEF_GRID ? SURF_RELIEF_GRID
                         : b->relief == WDRT_RELIEF_NONE ? SURF_RELIEF_NONE
                                                         : SURF_RELIEF_NOISE;
        sd.relief.scale = b->relief_scale;
        sd.relief.width = b->relief_width;
        sd.contact = (surf_gains){b->contact_gains.master, b->contact_gains.other, b->contact_gains.direct,
                                  b->contact_gains.limit};
        sd.impact = (surf_gains){b->impact_gains.master, b->impact_gains.other, b->impact_gains.direct,
                                 b->impact_gains.limit};
        sd.cutoff_roll = b->cutoff_roll;
        sd.cutoff_slip = b->cutoff_slip;
        int sf = surf_add_surface(w, &sd);
        ok(sf, "surf_add_surface");
        surf_body_desc bd = {r, sf, b->mass};
        if (surf_add_body(w, &bd) != i)
            fail("surf_add_body", WDRT_ERROR);
    }
    free(m);
    ok(surf_body_enable(w, 0, 0), "surf_body_enable"); /* the floor */
    return w;
}

/* ---- the runs ---- */

typedef struct runner {
    wdrt_engine *e;   /* an engine, or */
    surf_world *w;    /* a world alone */
    wdrt_bodies *h;
    int strike;       /* 1: bodies 1..NSTRUCK struck every PERIOD frames */
    uint64_t t;       /* frames rendered */
    double *rec;      /* when not NULL: the output is written here from frame 0 */
    long nrec;
    double peak, best;
    int finite;
    int refused;      /* an event was refused */
} runner;

static void runner_init(runner *r, wdrt_engine *e, wdrt_bodies *h, surf_world *w) {
    memset(r, 0, sizeof *r);
    r->e = e, r->h = h, r->w = w;
    r->finite = 1;
    r->best = INFINITY;
}

/* Section 2's strikes in frames [t, t + BLOCK), in the order of their frames. */
static void post_strikes(runner *r) {
    for (int i = 1; i <= NSTRUCK; i++) {
        int64_t off = (int64_t)(i - 1) * STAGGER, t = (int64_t)r->t;
        int64_t k = t <= off ? 0 : (t - off + PERIOD - 1) / PERIOD;
        int64_t f = off + k * PERIOD;
        if (f >= t + BLOCK)
            continue;
        uint64_t x = mix64(((uint64_t)i << 40) ^ (uint64_t)k ^ 0x5B0D1E5ull);
        double J = 0.002 + 0.008 * unit(x), vn = 0.5 + unit(mix64(x)), vt = 0.05 + 0.25 * unit(mix64(x + 1));
        if (wdrt_bodies_impact(r->h, (uint64_t)f, i, 0, J, vn, vt) != WDRT_OK)
            r->refused = 1;
    }
}

static void render_blocks(void *ctx, long nblocks) {
    runner *r = ctx;
    double out[BLOCK], pk = r->peak;
    int finite = 1;
    for (long b = 0; b < nblocks; b++) {
        double *o = out;
        if (r->rec && (long)r->t + BLOCK <= r->nrec)
            o = r->rec + r->t;
        if (r->e) {
            if (r->strike)
                post_strikes(r);
            wdrt_engine_process(r->e, o, BLOCK);
        } else {
            surf_process(r->w, o, BLOCK);
        }
        for (int j = 0; j < BLOCK; j++) {
            finite &= isfinite(o[j]) != 0;
            pk = fabs(o[j]) > pk ? fabs(o[j]) : pk;
        }
        r->t += BLOCK;
    }
    r->peak = pk;
    r->finite &= finite;
}

/* Renders the first n frames of r (a multiple of BLOCK) into rec. */
static void render_first(runner *r, long n, double *rec) {
    if (r->t != 0)
        fail("render_first", WDRT_ERROR);
    r->rec = rec, r->nrec = n;
    render_blocks(r, n / BLOCK);
    r->rec = NULL;
}

/* The runners take turns, their order rotating; each keeps its best run. */
static void rounds(runner **rs, int n) {
    for (int round = 0; round < RUNS; round++)
        for (int j = 0; j < n; j++) {
            runner *r = rs[(j + round) % n];
            double ns = bench_measure(render_blocks, r, BLOCK, 1, WARM, SPAN);
            r->best = ns < r->best ? ns : r->best;
        }
}

/* The largest |a - b| relative to b's peak (0: equal; INFINITY if b is silent). */
static double rel_diff(const double *a, const double *b, long n) {
    double d = 0, pk = 0;
    for (long i = 0; i < n; i++) {
        d = fmax(d, fabs(a[i] - b[i]));
        pk = fmax(pk, fabs(b[i]));
    }
    return pk > 0 ? d / pk : d > 0 ? INFINITY : 0;
}

static long first_diff(const double *a, const double *b, long n) {
    for (long i = 0; i < n; i++)
        if (memcmp(&a[i], &b[i], sizeof(double)))
            return i;
    return -1;
}

static int g_failed;

static void check(int good, const char *what) {
    if (!good) {
        fprintf(stderr, "surfbench: %s\n", what);
        g_failed = 1;
    }
}

/* ---- the table ---- */

static void header(void) {
    printf("   %-54s %6s %9s %10s  %s\n", "case", "awake", "ns/sample", "figure", "of what");
    printf("   %-54s %6s %9s %10s  %s\n", "------------------------------------------------------", "------",
           "---------", "----------", "------------------------------------------");
}

static void row(const char *num, const char *label, int awake, double ns, const char *fig, const char *what) {
    printf("%-2s %-54s %6d %9.1f %10s  %s\n", num, label, awake, ns, fig, what);
    fflush(stdout);
}

/* ---- 1. one active body ---- */

typedef struct one_result {
    double engine, world, diff, peak;
    int awake_e, awake_w, gens;
} one_result;

static void one_body(one_result *res) {
    bodyset s;
    bodyset_make(&s, 1, NMODES, 150, 500, 0x0B0D1ull);
    wdrt_bodies *h;
    wdrt_engine *e = bodies_engine(&s, 2, 0, &h);
    surf_contact_data d = surf_contact_rolling(0.3, 0.3, 1.0);
    ok(wdrt_bodies_contact(h, 0, 0, 1, 0, d.v_a, d.v_b, d.slip, d.force), "wdrt_bodies_contact");
    surf_world *w = bodies_world(&s, 2);
    surf_contact id;
    ok(surf_contact_start(w, 1, 0, &d, &id), "surf_contact_start");
    runner re, rw;
    runner_init(&re, e, h, NULL);
    runner_init(&rw, NULL, NULL, w);
    long n = frames_of(FIRST) / BLOCK * BLOCK;
    double *ye = xcalloc((size_t)n, sizeof *ye), *yw = xcalloc((size_t)n, sizeof *yw);
    render_first(&re, n, ye);
    render_first(&rw, n, yw);
    res->diff = rel_diff(ye, yw, n);
    runner *rs[2] = {&re, &rw};
    rounds(rs, 2);
    res->engine = re.best, res->world = rw.best;
    res->peak = rw.peak;
    wdrt_engine_stats st;
    wdrt_engine_get_stats(e, &st);
    res->awake_e = st.awake;
    surf_stats ss;
    surf_get_stats(w, &ss);
    res->awake_w = ss.resonators_awake;
    res->gens = ss.generators;
    check(re.finite && rw.finite, "1: a render was not finite");
    check(re.peak > 1e-6 && rw.peak > 1e-6, "1: the body was silent");
    check(res->diff <= 1e-12, "1: the engine's render is not the world's");
    check(ss.resonators_awake == 1 && ss.generators == 1, "1: not one resonator and one generator running");
    free(ye);
    free(yw);
    wdrt_engine_uninit(e, NULL);
    wdrt_bodies_free(h);
    surf_uninit(w, NULL);
    bodyset_free(&s);
}

/* ---- 2. a thousand bodies, ten struck ---- */

typedef struct many_result {
    double ns[2], mb[2], init[2];
    int awake[2], asleep[2], res_awake[2], modes[2];
    long diff;
    double peak;
    uint64_t refused;
} many_result;

static void many(const bodyset *s, many_result *res) {
    int nb[2] = {1 + NSTRUCK, s->n};
    runner r[2];
    wdrt_engine *e[2];
    wdrt_bodies *h[2];
    long n = frames_of(FIRST) / BLOCK * BLOCK;
    double *y[2];
    for (int k = 0; k < 2; k++) {
        double t0 = bench_now();
        e[k] = bodies_engine(s, nb[k], 1, &h[k]);
        res->init[k] = bench_now() - t0;
        runner_init(&r[k], e[k], h[k], NULL);
        r[k].strike = 1;
        y[k] = xcalloc((size_t)n, sizeof *y[k]);
        render_first(&r[k], n, y[k]);
    }
    res->diff = first_diff(y[1], y[0], n);
    res->peak = r[0].peak;
    runner *rs[2] = {&r[0], &r[1]};
    rounds(rs, 2);
    for (int k = 0; k < 2; k++) {
        res->ns[k] = r[k].best;
        wdrt_engine_stats st;
        wdrt_engine_get_stats(e[k], &st);
        res->awake[k] = st.awake, res->asleep[k] = st.asleep;
        wdrt_bodies_stats bs;
        wdrt_bodies_get_stats(h[k], &bs);
        res->res_awake[k] = bs.awake, res->modes[k] = bs.modes;
        res->refused += bs.refused + (uint64_t)r[k].refused;
        check(r[k].finite, "2: a render was not finite");
        check(r[k].peak > 1e-6, "2: the struck bodies were silent");
        wdrt_engine_uninit(e[k], NULL);
        wdrt_bodies_free(h[k]);
        free(y[k]);
    }
    check(res->refused == 0, "2: an impact was refused");
    check(res->diff < 0, "2: the 1000 bodies' render is not the 10's");
}

/* ---- 3. sleeping bodies ---- */

typedef struct sleep_result {
    double engine, world, two, ring_s, wall_s, peak;
    int awake, asleep, res_awake;
} sleep_result;

static void sleepers(const bodyset *s, sleep_result *res) {
    wdrt_bodies *h, *h2;
    wdrt_engine *e = bodies_engine(s, s->n, 1, &h);
    for (int i = 1; i < s->n; i++)
        ok(wdrt_bodies_impact(h, (uint64_t)(10 * (i - 1)), i, 0, 0.005, 1.0, 0.1), "wdrt_bodies_impact");
    runner re, rw, r2;
    runner_init(&re, e, h, NULL);
    /* ring down: until every resonator and every voice sleeps (at most 10 s) */
    double t0 = bench_now();
    for (;;) {
        render_blocks(&re, 16);
        wdrt_bodies_stats bs;
        wdrt_engine_stats st;
        wdrt_bodies_get_stats(h, &bs);
        wdrt_engine_get_stats(e, &st);
        if ((bs.awake == 0 && st.awake == 0) || re.t >= (uint64_t)frames_of(10))
            break;
    }
    res->wall_s = bench_now() - t0;
    res->ring_s = (double)re.t / FS;
    res->peak = re.peak;
    check(re.peak > 1e-6, "3: the strikes were silent");
    wdrt_bodies_stats bs;
    wdrt_bodies_get_stats(h, &bs);
    check(bs.refused == 0, "3: an impact was refused");
    re.peak = 0;
    surf_world *w = bodies_world(s, s->n);
    runner_init(&rw, NULL, NULL, w);
    wdrt_engine *e2 = bodies_engine(s, 2, 1, &h2);
    runner_init(&r2, e2, h2, NULL);
    render_blocks(&r2, (long)(frames_of(0.5) / BLOCK)); /* its two voices fall asleep */
    runner *rs[3] = {&re, &rw, &r2};
    rounds(rs, 3);
    res->engine = re.best, res->world = rw.best, res->two = r2.best;
    wdrt_engine_stats st;
    wdrt_engine_get_stats(e, &st);
    res->awake = st.awake, res->asleep = st.asleep;
    wdrt_bodies_get_stats(h, &bs);
    res->res_awake = bs.awake;
    wdrt_engine_get_stats(e2, &st);
    check(st.awake == 0, "3: the two bodies' engine is not asleep");
    check(re.finite && rw.finite && r2.finite, "3: a render was not finite");
    check(res->awake == 0 && res->res_awake == 0, "3: not every body fell asleep");
    check(re.peak == 0 && rw.peak == 0 && r2.peak == 0, "3: sleeping bodies made a sound");
    wdrt_engine_uninit(e, NULL);
    wdrt_bodies_free(h);
    wdrt_engine_uninit(e2, NULL);
    wdrt_bodies_free(h2);
    surf_uninit(w, NULL);
}

/* ---- 4. the world's unit costs ---- */

typedef struct unit_result {
    double ns[2], per_mode[2];
    int modes[2], nres[2];
    double gen_ns, base_ns, per_gen;
    int gens;
} unit_result;

/* A world of the floor and nres bodies of m modes, each struck once at
 * frame 0 and ringing on. */
static surf_world *ringing(bodyset *s, int nres, int m, double lo, double hi) {
    bodyset_make(s, nres, m, lo, hi, 0x40DE5ull + (uint64_t)m);
    for (int i = 1; i < s->n; i++)
        s->b[i].quiet = 0; /* never sleeps */
    surf_world *w = bodies_world(s, s->n);
    ok(surf_resonator_set_active_modes(w, 0, 0), "set_active_modes");
    for (int i = 1; i < s->n; i++) {
        surf_impact_data d = {0.005, 1.0, 0};
        ok(surf_impact(w, 0, i, 0, &d), "surf_impact");
    }
    return w;
}

static void units(unit_result *res) {
    static const int nres[2] = {64, 16}, nm[2] = {NMODES, 64};
    static const double lo[2] = {150, 100}, hi[2] = {500, 180};
    bodyset s[3];
    surf_world *w[4];
    runner r[4];
    for (int k = 0; k < 2; k++) {
        w[k] = ringing(&s[k], nres[k], nm[k], lo[k], hi[k]);
        runner_init(&r[k], NULL, NULL, w[k]);
        render_blocks(&r[k], 64); /* the pulses are over */
    }
    /* GENS contacts like section 1's, on bodies whose resonators run no
     * mode (one mode while they are checked); and the same world without */
    bodyset_make(&s[2], GENS, 1, 150, 500, 0x6E45ull);
    for (int i = 1; i < s[2].n; i++)
        s[2].b[i].quiet = 0;
    for (int k = 2; k < 4; k++) {
        w[k] = bodies_world(&s[2], s[2].n);
        ok(surf_resonator_set_active_modes(w[k], 0, 0), "set_active_modes");
        runner_init(&r[k], NULL, NULL, w[k]);
    }
    surf_contact_data d = surf_contact_rolling(0.3, 0.3, 1.0);
    for (int i = 1; i < s[2].n; i++) {
        surf_contact id;
        ok(surf_contact_start(w[2], i, 0, &d, &id), "surf_contact_start");
    }
    render_blocks(&r[2], 64); /* the check: they sound through one mode each */
    check(r[2].peak > 1e-6, "4: the generators were silent");
    for (int i = 1; i < s[2].n; i++)
        ok(surf_resonator_set_active_modes(w[2], i, 0), "set_active_modes");
    render_blocks(&r[2], 1);
    surf_stats ss;
    surf_get_stats(w[2], &ss);
    res->gens = ss.generators;
    check(ss.generators == GENS && ss.modes == 0, "4: not the generators alone running");
    runner *rs[4] = {&r[0], &r[1], &r[2], &r[3]};
    rounds(rs, 4);
    for (int k = 0; k < 2; k++) {
        surf_get_stats(w[k], &ss);
        res->ns[k] = r[k].best;
        res->modes[k] = ss.modes;
        res->nres[k] = ss.resonators_awake;
        res->per_mode[k] = r[k].best / ss.modes;
        check(r[k].finite && r[k].peak > 1e-6, "4: the ringing resonators were silent or not finite");
        check(ss.resonators_awake == nres[k], "4: a ringing resonator fell asleep");
    }
    res->gen_ns = r[2].best, res->base_ns = r[3].best;
    res->per_gen = (r[2].best - r[3].best) / GENS;
    check(r[2].finite && r[3].finite, "4: a render was not finite");
    for (int k = 0; k < 4; k++)
        surf_uninit(w[k], NULL);
    for (int k = 0; k < 3; k++)
        bodyset_free(&s[k]);
}

/* ---- main ---- */

int main(int argc, char **argv) {
    int only = 0;
    if (argc > 2 || (argc == 2 && !((only = atoi(argv[1])) >= 1 && only <= 4))) {
        fprintf(stderr, "usage: surfbench [1-4]\n");
        return 2;
    }
    double t_start = bench_now();
    char cpu[256], fig[32], what[160];
    bench_cpu_model(cpu, sizeof cpu);
    printf("wdrt bodies benchmark: %.0f Hz, mono, process calls of %d frames (the engine's grid block and the\n"
           "world's block); bodies of %d modes; wall time of the whole loop (events, process, a scan of the\n"
           "output), best of %d runs of >= %.2g s after %.2g s untimed, the cases of a section taking turns;\n"
           "the runtime built with the Makefile's CFLAGS\n"
           "cpu: %s\n\n",
           FS, BLOCK, NMODES, RUNS, SPAN, WARM, cpu);
    header();

    one_result one;
    memset(&one, 0, sizeof one);
    if (!only || only == 1) {
        one_body(&one);
        double share = one.engine * FS / 1e9;
        snprintf(fig, sizeof fig, "%.3f %%", 100 * share);
        row("1", "one 15-mode body, one live contact (engine, no sleep)", one.awake_e, one.engine, fig,
            "of one core at 48 kHz (Menzies: ~1 % of a P-III 600)");
        snprintf(fig, sizeof fig, "%.3f %%", 100 * one.world * FS / 1e9);
        row("", "the same, world alone (surf_process)", one.awake_w, one.world, fig, "of one core at 48 kHz");
        snprintf(what, sizeof what, "engine / world alone; renders differ by %.1e of the peak", one.diff);
        snprintf(fig, sizeof fig, "%.2fx", one.engine / one.world);
        row("", "  the engine's share", one.awake_e, one.engine - one.world, fig, what);
    }

    bodyset big;
    int made = 0;
    many_result mr;
    memset(&mr, 0, sizeof mr);
    if (!only || only == 2 || only == 3) {
        bodyset_make(&big, NBODIES - 1, NMODES, 150, 500, 0x50F7ull);
        made = 1;
    }
    if (!only || only == 2) {
        many(&big, &mr);
        snprintf(what, sizeof what, "(%d resonators awake, %d modes)", mr.res_awake[0], mr.modes[0]);
        row("2", "floor + 10 bodies, struck every 50 ms (engine)", mr.awake[0], mr.ns[0], "-", what);
        snprintf(fig, sizeof fig, "%.2fx", mr.ns[1] / mr.ns[0]);
        snprintf(what, sizeof what, "of the 10 alone (aim <= 1.2x); %d asleep; renders equal: %s", mr.asleep[1],
                 mr.diff < 0 ? "yes" : "NO");
        row("", "1000 bodies, the same 10 struck (engine)", mr.awake[1], mr.ns[1], fig, what);
        snprintf(fig, sizeof fig, "%.3f", (mr.ns[1] - mr.ns[0]) / (NBODIES - NSTRUCK - 1));
        row("", "  the 989 never touched", 0, mr.ns[1] - mr.ns[0], fig, "ns per body and sample");
    }

    sleep_result sl;
    memset(&sl, 0, sizeof sl);
    if (!only || only == 3) {
        sleepers(&big, &sl);
        snprintf(fig, sizeof fig, "%.3f", sl.engine / NBODIES);
        snprintf(what, sizeof what, "ns per sleeping body and sample (%d asleep)", sl.asleep);
        row("3", "1000 bodies asleep (engine)", sl.awake, sl.engine, fig, what);
        snprintf(fig, sizeof fig, "%.3f", sl.world / NBODIES);
        row("", "the same, world alone (surf_process)", 0, sl.world, fig, "ns per sleeping resonator and sample");
        row("", "floor + 1 body asleep (engine): the fixed cost", 0, sl.two, "-", "");
        snprintf(fig, sizeof fig, "%.3f", (sl.engine - sl.two) / (NBODIES - 2));
        row("", "  the 998 more (engine)", 0, sl.engine - sl.two, fig, "ns per sleeping body and sample");
    }
    if (made)
        bodyset_free(&big);

    unit_result un;
    memset(&un, 0, sizeof un);
    if (!only || only == 4) {
        units(&un);
        for (int k = 0; k < 2; k++) {
            char label[64];
            snprintf(label, sizeof label, "%d resonators x %d modes ringing (world alone)", un.nres[k],
                     un.modes[k] / (un.nres[k] ? un.nres[k] : 1));
            snprintf(fig, sizeof fig, "%.3f", un.per_mode[k]);
            row(k ? "" : "4", label, un.nres[k], un.ns[k], fig, "ns per mode-sample");
        }
        snprintf(fig, sizeof fig, "%.2f", un.per_gen);
        snprintf(what, sizeof what, "ns per generator-sample: %.1f modes (SURF_GEN_COST %.0f)",
                 un.per_gen / un.per_mode[0], SURF_GEN_COST);
        row("", "32 contacts, resonators of 0 modes (world alone)", GENS, un.gen_ns, fig, what);
        row("", "  the same world, no contact", 0, un.base_ns, "-", "");
    }

    printf("\nawake: voices computed in the last block (engine), or resonators (world alone)\n");
    if (!only || only == 1)
        printf("1: the body rolling on the floor: 1 N, 0.3 m/s over its noise relief, low-pass at %.0f Hz;\n"
               "   %d generator; peak %.3g\n",
               200 + (8000 - 200) * 0.3, one.gens, one.peak);
    if (!only || only == 2)
        printf("2: %d impacts a second; made in %.2f s and %.2f s; the first %.0f s of both rendered untimed and\n"
               "   compared%s\n",
               NSTRUCK * (int)(FS / PERIOD), mr.init[0], mr.init[1], FIRST, mr.diff < 0 ? " (equal bit for bit)" : "");
    if (!only || only == 3)
        printf("3: the 999 struck once within %.2f s, all asleep %.1f s later (%.1f s of wall time to get there);\n"
               "   peak %.3g\n",
               10.0 * (NBODIES - 2) / FS, sl.ring_s, sl.wall_s, sl.peak);
    printf("(%.0f s)\n", bench_now() - t_start);
    return g_failed;
}
