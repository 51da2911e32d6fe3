/*
 * test_space.c - the spatial layer against the physics: the arrival time
 * of a sound at distance d, the Doppler shift of a passing source against
 * the retarded-time formula, the distance models, air absorption against
 * ISO 9613-1, constant power across the pan, walls that muffle, and the
 * four-point Lagrange reader's error.
 */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "space.h"
#include "testlib.h"

#define FS 48000.0

static tl_voice g_msd; /* a driven mass on a spring: an input f, an output vel */

static int setup(void **s) {
    (void)s;
    return tl_voice_build("netlists/msd.wdn", 0, &g_msd);
}

static tl_voice g_rc;

static int teardown(void **s) {
    (void)s;
    tl_voice_free(&g_msd);
    if (g_rc.cls)
        tl_voice_free(&g_rc);
    return 0;
}

typedef struct scene {
    wdrt_space_config sp;
    double src[3];
    int channels;
    const double *in; /* the voice's input */
    long n;
    /* a constant velocity from src (m/s), applied by moves every block */
    double vel[3];
} scene;

static scene base(const double *in, long n) {
    scene sc;
    memset(&sc, 0, sizeof sc);
    wdrt_engine_config ec = wdrt_engine_config_init(FS, 1, 0, NULL);
    sc.sp = ec.space;
    sc.sp.sources = 4;
    sc.sp.distance = WDRT_DISTANCE_NONE;
    sc.sp.air = 0;
    sc.channels = 1;
    sc.in = in;
    sc.n = n;
    return sc;
}

/* Renders a standing msd voice placed at sc->src (moving at sc->vel) and
 * heard by the listener of sc->sp. */
static double *render(const scene *sc) {
    wdrt_pool_config pc = wdrt_pool_config_init(g_msd.cls, 1);
    pc.owned = 1;
    pc.cost_ns = 1;
    pc.placed = 1;
    pc.hold = 1000; /* never sleeps: the tests measure steady tones */
    memcpy(pc.pos, sc->src, sizeof pc.pos);
    wdrt_engine_config ec = wdrt_engine_config_init(FS, sc->channels, 1, &pc);
    ec.space = sc->sp;
    wdrt_engine *e;
    assert_int_equal(wdrt_engine_init(&ec, NULL, &e), WDRT_OK);
    wdrt_voice v = wdrt_engine_voice(e, 0, 0);
    double *y = calloc((size_t)sc->n * (size_t)sc->channels + 1, sizeof(double));
    const long B = 64;
    for (long pos = 0; pos < sc->n; pos += B) {
        if (sc->vel[0] != 0 || sc->vel[1] != 0 || sc->vel[2] != 0) {
            double t = (double)(pos + B) / FS, p[3];
            for (int j = 0; j < 3; j++)
                p[j] = sc->src[j] + sc->vel[j] * t;
            assert_int_equal(wdrt_engine_move(e, (uint64_t)pos, v, p), WDRT_OK);
        }
        long k = sc->n - pos < B ? sc->n - pos : B;
        assert_int_equal(wdrt_engine_bind_input(e, v, 0, sc->in + pos), WDRT_OK);
        wdrt_engine_process(e, y + pos * sc->channels, (uint32_t)k);
    }
    wdrt_engine_uninit(e, NULL);
    return y;
}

/* The voice alone: what a source sounds like where it is. */
static double *direct(const double *in, long n) {
    void *st = tl_state_new(g_msd.cls, FS);
    double **o = tl_bufs_new(g_msd.cls->n_outputs, n);
    const double *ip[1] = {in};
    wdrt_render(g_msd.cls, st, ip, o, n, 64);
    double *y = malloc(sizeof(double) * (size_t)n);
    memcpy(y, o[0], sizeof(double) * (size_t)n);
    tl_bufs_free(o, g_msd.cls->n_outputs);
    tl_state_free(st);
    return y;
}

static double *sine(double f, long n) {
    double *x = malloc(sizeof(double) * (size_t)n);
    for (long i = 0; i < n; i++)
        x[i] = sin(2 * M_PI * f * i / FS);
    return x;
}

/* Amplitude and phase of x at f over [a, b), by correlation. */
static void tone(const double *x, long a, long b, double f, double *amp, double *ph) {
    double c = 0, s = 0;
    for (long i = a; i < b; i++) {
        c += x[i] * cos(2 * M_PI * f * i / FS);
        s += x[i] * sin(2 * M_PI * f * i / FS);
    }
    *amp = 2 * hypot(c, s) / (double)(b - a);
    *ph = atan2(s, c);
}

/* A source d metres away is heard d/c late (a steady tone's phase, to
 * 0.01 sample) and, with no distance model and no air, unchanged. */
static void test_arrival(void **s) {
    (void)s;
    const long n = 96000;
    const double f = 250;
    double *in = sine(f, n), *y0 = direct(in, n);
    const double dists[] = {1, 17.3, 100, 343};
    for (int i = 0; i < 4; i++) {
        scene sc = base(in, n);
        sc.src[1] = dists[i];
        double *y = render(&sc);
        /* the tone's phase over the last second, against the voice's over
         * the same stretch of its own time, whole samples taken off */
        double want = dists[i] / 343 * FS, a0, p0, a1, p1;
        long D = lround(want);
        tone(y0, 48000 - D, 96000 - D, f, &a0, &p0);
        tone(y, 48000, 96000, f, &a1, &p1);
        /* the phase gives the delay modulo a period of the tone */
        double lag = want + remainder((p1 - p0) / (2 * M_PI * f) * FS - want, FS / f);
        print_message("arrival at %5.1f m: delay %.5f samples, d/c %.5f samples: error %+.5f; gain %.7f\n", dists[i],
                      lag, want, lag - want, a1 / a0);
        assert_true(fabs(lag - want) < 0.01);
        assert_true(fabs(a1 / a0 - 1) < 1e-5);
        /* nothing arrives before d/c */
        long first = 0;
        while (first < n && y[first] == 0)
            first++;
        assert_true(first >= (long)floor(want) - 2);
        free(y);
    }
    free(in);
    free(y0);
}

/* A source passing at 30 m/s, 10 m off the listener's path: the frequency
 * heard follows f / (1 + v_r / c) at the retarded time, v_r the radial
 * velocity when the sound left. */
static void test_doppler(void **s) {
    (void)s;
    const long n = (long)(3 * FS);
    const double f = 440, v = 30, c = 343;
    double *in = sine(f, n);
    scene sc = base(in, n);
    sc.src[0] = -45;
    sc.src[1] = 10;
    sc.vel[0] = v;
    double *y = render(&sc);
    /* zero crossings, upward, interpolated */
    double worst = 0;
    int checked = 0;
    double last = -1;
    int count = 0;
    double t_start = 0;
    for (long i = (long)(0.5 * FS); i < n - 1; i++) {
        if (y[i] < 0 && y[i + 1] >= 0) {
            double t = (i + y[i] / (y[i] - y[i + 1])) / FS;
            if (last < 0) {
                t_start = t;
                count = 0;
            }
            last = t;
            if (++count == 21) { /* 20 periods */
                double fm = 20 / (t - t_start), tm = (t + t_start) / 2;
                /* retarded time: the source at x(te) = -45 + v te, c (tm - te) = |p(te)| */
                double te = tm;
                for (int it = 0; it < 50; it++) {
                    double x = -45 + v * te;
                    te = tm - hypot(x, 10) / c;
                }
                double x = -45 + v * te, vr = v * x / hypot(x, 10);
                double fw = f / (1 + vr / c);
                double err = fabs(fm / fw - 1);
                worst = fmax(worst, err);
                checked++;
                t_start = t;
                count = 1;
            }
        }
    }
    print_message("doppler: %d windows of 20 periods, from %.1f Hz to %.1f Hz; worst error %.4f %%\n", checked,
                  f / (1 - v / c), f / (1 + v / c), 100 * worst);
    assert_true(checked > 50);
    assert_true(worst < 1e-3);
    free(y);
    free(in);
}

/* A source that flies past faster than sound (twice its speed, or by a
 * jump of its position between two blocks) has no single retarded time:
 * what is heard stays finite and no louder than the source, and the
 * source is heard once it is slower again. */
static void test_supersonic(void **s) {
    (void)s;
    const long n = (long)(1 * FS);
    double *in = sine(440, n);
    double *y0 = direct(in, n), peak0 = 0;
    for (long i = 0; i < n; i++)
        peak0 = fmax(peak0, fabs(y0[i]));
    scene sc = base(in, n);
    sc.src[0] = -300;
    sc.src[1] = 2;
    sc.vel[0] = 2 * 343; /* through x = 0 at 0.44 s */
    double *y = render(&sc);
    double peak = 0;
    for (long i = 0; i < n; i++) {
        if (!isfinite(y[i]))
            fail_msg("sample %ld of a source at twice the speed of sound is %g", i, y[i]);
        peak = fmax(peak, fabs(y[i]));
    }
    assert_true(peak <= peak0 * (1 + 1e-9));
    free(y);
    /* jumps: 40 m towards the listener and back, every tenth block */
    wdrt_pool_config pc = wdrt_pool_config_init(g_msd.cls, 1);
    pc.owned = 1, pc.cost_ns = 1, pc.placed = 1, pc.hold = 1000;
    pc.pos[1] = 50;
    wdrt_engine_config ec = wdrt_engine_config_init(FS, 1, 1, &pc);
    ec.space = sc.sp;
    wdrt_engine *e;
    assert_int_equal(wdrt_engine_init(&ec, NULL, &e), WDRT_OK);
    wdrt_voice v = wdrt_engine_voice(e, 0, 0);
    y = calloc((size_t)n, sizeof(double));
    for (long pos = 0, b = 0; pos < n; pos += 64, b++) {
        if (b % 10 == 0) {
            double p[3] = {0, b % 20 ? 10 : 50, 0};
            assert_int_equal(wdrt_engine_move(e, (uint64_t)pos, v, p), WDRT_OK);
        }
        assert_int_equal(wdrt_engine_bind_input(e, v, 0, in + pos), WDRT_OK);
        wdrt_engine_process(e, y + pos, (uint32_t)(n - pos < 64 ? n - pos : 64));
    }
    wdrt_engine_uninit(e, NULL);
    double late = 0;
    for (long i = 0; i < n; i++) {
        if (!isfinite(y[i]))
            fail_msg("sample %ld of a source that jumps 40 m is %g", i, y[i]);
        late = i > n / 2 ? fmax(late, fabs(y[i])) : late;
    }
    assert_true(late > 0.1 * peak0);
    print_message("supersonic: peak %.3g against the source's %.3g; jumping: %.3g\n", peak, peak0, late);
    free(y);
    free(y0);
    free(in);
}

/* Each distance model against its formula, clamped at ref and max. */
/* The amplitude at f of what arrives over [a, b) against the voice's own
 * over the same stretch of its time (the delay taken off), so that both
 * see the same part of its start-up. */
static double arriving_gain(const double *y, const double *y0, long a, long b, double f, double delay) {
    long D = lround(delay);
    double a1, a0, ph;
    tone(y, a, b, f, &a1, &ph);
    tone(y0, a - D, b - D, f, &a0, &ph);
    return a1 / a0;
}

static void test_distance_models(void **s) {
    (void)s;
    const long n = 96000;
    double *in = sine(250, n), *y0 = direct(in, n);
    const wdrt_distance models[] = {WDRT_DISTANCE_INVERSE, WDRT_DISTANCE_LINEAR, WDRT_DISTANCE_EXPONENT};
    const double dists[] = {0.5, 2, 10, 40, 120};
    for (int m = 0; m < 3; m++)
        for (int i = 0; i < 5; i++) {
            scene sc = base(in, n);
            sc.sp.distance = models[m];
            sc.sp.ref = 1;
            sc.sp.max = 100;
            sc.sp.rolloff = 0.8;
            sc.src[0] = dists[i];
            double *y = render(&sc);
            double d = fmin(fmax(dists[i], 1), 100), want;
            double g = arriving_gain(y, y0, 48000, 96000, 250, dists[i] / 343 * FS);
            if (models[m] == WDRT_DISTANCE_INVERSE)
                want = 1 / (1 + 0.8 * (d - 1));
            else if (models[m] == WDRT_DISTANCE_LINEAR)
                want = 1 - 0.8 * (d - 1) / 99;
            else
                want = pow(d, -0.8);
            if (fabs(g - want) > 1e-4 * want + 1e-9)
                fail_msg("model %d at %g m: gain %.6f, formula %.6f", m, dists[i], g, want);
            free(y);
        }
    free(in);
    free(y0);
}

/* Air absorption over 100 m against ISO 9613-1 at 1, 4 and 8 kHz. */
static void test_air(void **s) {
    (void)s;
    const long n = 48000;
    const double fr[] = {1000, 4000, 8000}, iso[] = {0.47, 2.97, 10.5}; /* dB over 100 m, ISO 9613-1 tables */
    for (int i = 0; i < 3; i++) {
        assert_true(fabs(space_air_alpha(fr[i]) * 100 - iso[i]) < 0.05 * iso[i] + 0.02);
        double *in = sine(fr[i], n), *y0 = direct(in, n);
        scene sc = base(in, n);
        sc.sp.air = 1;
        sc.src[1] = 100;
        double *y = render(&sc);
        double db = -20 * log10(arriving_gain(y, y0, 24000, 48000, fr[i], 100 / 343.0 * FS));
        double want = space_air_alpha(fr[i]) * 100;
        print_message("air, 100 m, %5.0f Hz: %.2f dB, ISO 9613-1 %.2f dB\n", fr[i], db, want);
        assert_true(fabs(db - want) < 1.0);
        free(y);
        free(in);
        free(y0);
    }
}

/* Stereo: a source on a circle around the listener keeps its power, and
 * one on the right is louder on the right. */
static void test_pan(void **s) {
    (void)s;
    const long n = 12000;
    double *in = sine(250, n);
    double pw0 = -1;
    for (int k = 0; k < 8; k++) {
        scene sc = base(in, n);
        sc.channels = 2;
        double th = 2 * M_PI * k / 8;
        sc.src[0] = 5 * cos(th);
        sc.src[1] = 5 * sin(th);
        double *y = render(&sc);
        double l = 0, r = 0;
        for (long i = 6000; i < n; i++)
            l += y[2 * i] * y[2 * i], r += y[2 * i + 1] * y[2 * i + 1];
        if (pw0 < 0)
            pw0 = l + r;
        assert_true(fabs((l + r) / pw0 - 1) < 1e-3);
        if (k == 0)
            assert_true(r > 10 * l); /* +x is to the right of a listener facing +y */
        if (k == 4)
            assert_true(l > 10 * r);
        free(y);
    }
    free(in);
}

/* A wall between source and listener takes its loss off the low
 * frequencies and more off the high ones; beside the path it does nothing. */
static void test_wall(void **s) {
    (void)s;
    const long n = 24000;
    wdrt_wall w = {{-5, 5}, {5, 5}, 12};
    const double fr[] = {100, 4000};
    double g[2][2];
    for (int i = 0; i < 2; i++)
        for (int blocked = 0; blocked < 2; blocked++) {
            double *in = sine(fr[i], n);
            scene sc = base(in, n);
            sc.sp.nwalls = 1;
            sc.sp.walls = &w;
            sc.src[0] = blocked ? 0 : 20;
            sc.src[1] = 10;
            double *y = render(&sc);
            double a, ph;
            tone(y, 12000, 24000, fr[i], &a, &ph);
            g[i][blocked] = a;
            free(y);
            free(in);
        }
    double lo = 20 * log10(g[0][1] / g[0][0]), hi = 20 * log10(g[1][1] / g[1][0]);
    /* the unblocked source is farther off but no model is on: same level */
    print_message("wall of 12 dB: %.1f dB at 100 Hz, %.1f dB at 4 kHz\n", lo, hi);
    assert_true(fabs(lo + 12) < 0.5);
    assert_true(hi < lo - 6);
}

/* The four-point Lagrange reader: exact at whole samples, and its error
 * for a tone read halfway between samples (the worst place). */
static void test_lagrange(void **s) {
    (void)s;
    double buf[1024];
    for (int i = 0; i < 1024; i++)
        buf[i] = sin(0.3 * i) + 0.1 * i;
    for (int i = 4; i < 1000; i++)
        assert_true(space_read(buf, 1023, (double)i) == buf[i]);
    /* halfway, the weights are (-1, 9, 9, -1)/16: a tone comes out scaled
     * by 9/8 cos(w/2) - 1/8 cos(3w/2), in phase */
    const double fr[] = {1000, 5000, 10000, 16000};
    for (int k = 0; k < 4; k++) {
        double w = 2 * M_PI * fr[k] / FS, dev = 0, err = 0;
        double want = 9.0 / 8 * cos(w / 2) - 1.0 / 8 * cos(1.5 * w);
        for (int i = 0; i < 1024; i++)
            buf[i] = sin(w * i);
        for (int i = 10; i < 1000; i++) {
            double r = space_read(buf, 1023, i + 0.5), x = sin(w * (i + 0.5));
            dev = fmax(dev, fabs(r - want * x));
            err = fmax(err, fabs(r - x));
        }
        print_message("Lagrange, halfway between samples, %5.0f Hz at 48 kHz: error %.1f dB (closed form %.1f dB)\n",
                      fr[k], tl_db(err), tl_db(1 - want));
        assert_true(dev < 1e-12);
    }
}

/* ---- rooms, walls and ears: a short click from an RC low-pass ---- */

static double dist3_t(const double *a, const double *b) { return sqrt(pow(a[0] - b[0], 2) + pow(a[1] - b[1], 2) + pow(a[2] - b[2], 2)); }

typedef struct clickscene {
    double src[3], lis[3];
    int nwalls, nrooms, channels;
    const wdrt_wall *walls;
    const wdrt_room *rooms;
    const wdrt_hrtf *hrtf;
    long n;
} clickscene;

/* The RC low-pass driven by one unit sample at frame 0, placed at src. */
static double *click(const clickscene *cs) {
    if (!g_rc.cls)
        assert_int_equal(tl_voice_build("netlists/rc_lowpass.wdn", 0, &g_rc), 0);
    wdrt_pool_config pc = wdrt_pool_config_init(g_rc.cls, 1);
    pc.owned = 1;
    pc.cost_ns = 1;
    pc.placed = 1;
    memcpy(pc.pos, cs->src, sizeof pc.pos);
    int nch = cs->channels ? cs->channels : 1;
    wdrt_engine_config ec = wdrt_engine_config_init(FS, nch, 1, &pc);
    ec.space.sources = 2;
    ec.space.air = 0;
    ec.space.max = 100;
    memcpy(ec.space.listener, cs->lis, sizeof cs->lis);
    ec.space.nwalls = cs->nwalls;
    ec.space.walls = cs->walls;
    ec.space.nrooms = cs->nrooms;
    ec.space.rooms = cs->rooms;
    ec.space.hrtf = cs->hrtf;
    wdrt_engine *e;
    assert_int_equal(wdrt_engine_init(&ec, NULL, &e), WDRT_OK);
    wdrt_voice v = wdrt_engine_voice(e, 0, 0);
    double *in = calloc((size_t)cs->n, sizeof(double)), *y = calloc((size_t)cs->n * (size_t)nch, sizeof(double));
    in[0] = 1;
    for (long pos = 0; pos < cs->n; pos += 256) {
        long k = cs->n - pos < 256 ? cs->n - pos : 256;
        assert_int_equal(wdrt_engine_bind_input(e, v, 0, in + pos), WDRT_OK);
        wdrt_engine_process(e, y + pos * nch, (uint32_t)k);
    }
    wdrt_engine_uninit(e, NULL);
    free(in);
    return y;
}

static double energy(const double *y, long a, long b) {
    double s = 0;
    for (long i = a; i < b; i++)
        s += y[i] * y[i];
    return s;
}

/* The four obstacle cases of a source and a listener, two rooms side by
 * side (A: y 0..10, B: y 10..20) and a partition between them with a door
 * at x 0.5..1.5: the direct sound is muffled when the straight path is
 * blocked, and a room's reverb is heard whole inside it and through the
 * partition outside it.  (The rooms have no image sources here: the early
 * window holds the direct sound alone.) */
static void test_obstacles(void **s) {
    (void)s;
    const wdrt_room rooms[2] = {{{0, 0, 0, 10, 10, 4}, 1.0, 0.8, 0}, {{0, 10, 0, 10, 20, 4}, 1.0, 0.8, 0}};
    const wdrt_wall walls[3] = {{{0, 10}, {0.5, 10}, 20}, {{1.5, 10}, {10, 10}, 20}, {{4, 4}, {6, 4}, 20}};
    struct {
        const char *name;
        double src[3], lis[3];
        int blocked, same_room;
    } cases[4] = {
        {"no effect", {8, 7, 1.5}, {8, 2, 1.5}, 0, 1},   /* both in A, clear */
        {"obstruction", {5, 6, 1.5}, {5, 2, 1.5}, 1, 1}, /* both in A, the cabinet (wall 3) between */
        {"occlusion", {5, 15, 1.5}, {5, 5, 1.5}, 1, 0},  /* in B, through the partition */
        {"exclusion", {1, 15, 1.5}, {1, 5, 1.5}, 0, 0},  /* in B, seen through the door */
    };
    int fails = 0;
    for (int i = 0; i < 4; i++) {
        clickscene cs = {{0}, {0}, 3, 2, 1, walls, rooms, NULL, (long)FS};
        memcpy(cs.src, cases[i].src, sizeof cs.src);
        memcpy(cs.lis, cases[i].lis, sizeof cs.lis);
        double *y = click(&cs);
        /* the direct sound alone in a free field, and the reverb of the
         * source's room as heard from inside it */
        clickscene free_field = cs;
        free_field.nwalls = free_field.nrooms = 0;
        double *y0 = click(&free_field);
        clickscene open = cs;
        open.nwalls = 0;
        double d = dist3_t(cases[i].src, cases[i].lis);
        long a = (long)(d / 343 * FS) - 8, b = a + 96; /* 2 ms from the arrival: before any reverb */
        double direct = energy(y, a, b) / energy(y0, a, b);
        double late = energy(y, (long)(0.15 * FS), (long)(0.6 * FS));
        /* the reverb heard from inside the source's room */
        clickscene in = open;
        memcpy(in.lis, cases[i].src, sizeof in.lis);
        in.lis[0] += 1;
        double *yin = click(&in);
        double inside = energy(yin, (long)(0.15 * FS), (long)(0.6 * FS));
        print_message("%-12s direct %6.1f dB of the unblocked, reverb %6.1f dB of inside the room\n", cases[i].name,
                      10 * log10(direct), 10 * log10(late / inside));
        int ok = cases[i].blocked ? 10 * log10(direct) < -18 : fabs(10 * log10(direct)) < 0.1;
        ok &= cases[i].same_room ? fabs(10 * log10(late / inside)) < 3 /* elsewhere in the same field */
                                 : 10 * log10(late / inside) < -15;
        fails += !ok;
        free(y);
        free(y0);
        free(yin);
    }
    assert_int_equal(fails, 0);
}

/* Binaurally, a source on the left arrives earlier and louder at the left
 * ear, and the mirror on the right. */
static void test_binaural(void **s) {
    (void)s;
    char err[512];
    wdrt_hrtf *h = wdrt_hrtf_open(NULL, FS, err, sizeof err);
    if (!h)
        fail_msg("%s", err);
    for (int side = -1; side <= 1; side += 2) {
        clickscene cs = {{2.0 * side, 0, 0}, {0, 0, 0}, 0, 0, 2, NULL, NULL, h, 4800};
        double *y = click(&cs);
        long first[2] = {-1, -1};
        double en[2] = {0, 0}, pk = 0;
        for (long i = 0; i < cs.n * 2; i++)
            pk = fmax(pk, fabs(y[i]));
        for (long i = 0; i < cs.n; i++)
            for (int c = 0; c < 2; c++) {
                en[c] += y[2 * i + c] * y[2 * i + c];
                if (first[c] < 0 && fabs(y[2 * i + c]) > 0.1 * pk)
                    first[c] = i;
            }
        int near = side < 0 ? 0 : 1, far = 1 - near;
        print_message("binaural, source %s: near ear %.2f ms earlier, %.1f dB louder\n", side < 0 ? "left" : "right",
                      (first[far] - first[near]) / FS * 1e3, 10 * log10(en[near] / en[far]));
        assert_true(first[near] < first[far] && first[far] - first[near] > 0.3e-3 * FS);
        assert_true(en[near] > 2 * en[far]);
        free(y);
    }
    wdrt_hrtf_close(h);
}

/* Under a budget for one, of two placed voices sounding alike the far one
 * goes virtual: audibility is what arrives. */
static void test_far_goes_virtual(void **s) {
    (void)s;
    const long n = 48000;
    double *in = sine(250, n), *y0 = direct(in, n);
    for (int far = 0; far < 2; far++) {
        wdrt_pool_config pc[2];
        for (int i = 0; i < 2; i++) {
            pc[i] = wdrt_pool_config_init(g_msd.cls, 1);
            pc[i].owned = 1;
            pc[i].cost_ns = 100;
            pc[i].placed = 1;
            pc[i].hold = 1000;
            pc[i].pos[1] = i == far ? 400 : 3;
        }
        wdrt_engine_config ec = wdrt_engine_config_init(FS, 1, 2, pc);
        ec.space.sources = 4;
        ec.space.air = 0;
        ec.budget_ns = 150;
        wdrt_engine *e;
        assert_int_equal(wdrt_engine_init(&ec, NULL, &e), WDRT_OK);
        double *y = calloc((size_t)n, sizeof(double));
        for (long pos = 0; pos < n; pos += 64) {
            for (int i = 0; i < 2; i++)
                assert_int_equal(wdrt_engine_bind_input(e, wdrt_engine_voice(e, i, 0), 0, in + pos), WDRT_OK);
            wdrt_engine_process(e, y + pos, 64);
        }
        wdrt_engine_stats st;
        wdrt_engine_get_stats(e, &st);
        assert_int_equal((int)st.virtualized, 1);
        assert_int_equal(st.awake, 1);
        /* the one still computed is the near one: what is heard is it
         * alone, at 3 m (inverse distance from 1 m: a third) */
        double g = arriving_gain(y, y0, n / 2, n, 250, 3 / 343.0 * FS);
        assert_true(fabs(g - 1.0 / 3) < 1e-3);
        free(y);
        wdrt_engine_uninit(e, NULL);
        print_message("budget for one, voices at 3 m and 400 m (the far one %d): %d virtual, %d awake\n", far,
                      st.virtual_, st.awake);
    }
    free(in);
    free(y0);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_arrival), cmocka_unit_test(test_doppler), cmocka_unit_test(test_supersonic), cmocka_unit_test(test_distance_models),
        cmocka_unit_test(test_air),     cmocka_unit_test(test_pan),     cmocka_unit_test(test_wall),
        cmocka_unit_test(test_lagrange),  cmocka_unit_test(test_obstacles), cmocka_unit_test(test_binaural),
        cmocka_unit_test(test_far_goes_virtual),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
