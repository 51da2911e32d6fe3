/*
 * spacebench.c - what the engine's spatial layer (libwdrt) costs per
 * moving source, and OpenAL Soft doing the same work in the same run.
 *
 *     build/bench/spacebench
 *
 * The voice is netlists/rc_lowpass.wdn, built as bench.c builds voices
 * (bin/wdc, then $CC with -O2 -march=native), driven by white noise bound
 * to its input with wdrt_engine_bind_input before every process call.
 * Every engine runs at 48 kHz, stereo, in grid blocks of 64 frames with
 * process calls of 64 frames, sleep off, and holds NSRC standing voices
 * (one owned pool each, cost given so nothing is measured at init).  The
 * listener stands at (10, 7.5, 1.7) m facing +y; voice i goes round its
 * own horizontal circle about the listener (radius 2..6 m, height
 * 1.2..2.5 m, 0.2..0.8 turns per second either way, so 2.5..30 m/s),
 * moved with wdrt_engine_move every block to where it is one block later.
 * Distance model inverse (ref 1 m, max 100 m, rolloff 1), c = 343 m/s.
 *
 * The engines, each timed over the same loop (moves and input binding
 * included, since they are part of the work of a moving source):
 *   0  the voices not placed (panned by their pool): their own cost;
 *   a  placed, direct path only, air absorption off;
 *   b  placed, direct path and air absorption;
 *   c  as a, inside a 20 x 15 x 8 m room (T60 1.2 s low, 0.8 s high) with
 *      image sources up to order 2 (24 images per source) and its reverb;
 *   d  as 0 (the voices not placed), with a spatial layer of one unused
 *      delay line and R rooms like c's (order 0) far from the listener:
 *      their reverbs run unfed and unheard, which is what a room's FDN
 *      costs whether or not anything sounds in it;
 *   e  as a, binaural (wdrt_hrtf_open(NULL, ...): Debian's MIT KEMAR).
 * ns per source and sample is (t_case - t_0) / (NSRC frames): the voices'
 * own cost is taken off.  For c the extra over a is (t_c - t_a - the FDN
 * of one room, from d) / (NSRC frames); for d the cost per room is
 * (t_d - t_0) / (R frames).  Sources in real time on one core:
 * 1e9 / (48000 ns per source), the voices' own cost and the rest of the
 * engine not counted.
 *
 * OpenAL Soft, in the same run and in the same rounds: a loopback device
 * (ALC_SOFT_loopback) per case rendering float stereo at 48 kHz with
 * alcRenderSamplesSOFT in calls of 64 frames, HRTF off or on through the
 * context's attributes (ALC_HRTF_SOFT; its status is read back), NSRC
 * sources playing a looping second of white noise (mono float), each on
 * the same circle as ours (mapped to OpenAL's axes: x right, y up, -z
 * ahead), moved with alSource3f AL_POSITION and AL_VELOCITY (OpenAL's
 * Doppler follows the velocity) every 64 frames, the same distance
 * model, against the same device with no sources.  If anything about
 * OpenAL fails, the reason is printed and our figures still are.
 *
 * Times are wall time on the monotonic clock; each case renders RUNS
 * spans of SPAN s after WARM s untimed, the cases taking turns in every
 * round (their order rotating), and the best span counts.  A benchmark,
 * not a test: nothing is asserted about times.  The exit status is
 * non-zero only if the voice could not be built, an engine could not be
 * made or refused an event, or a render was not finite.
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define AL_ALEXT_PROTOTYPES
#include <AL/al.h>
#include <AL/alc.h>
#include <AL/alext.h>

#include "benchlib.h"
#include "wdrt.h"
#include "wdvoice.h"
#include "../tests/testlib.h"

#define FS 48000.0
#define BLOCK 64 /* grid block, process call and move period, frames */
#define NSRC 32  /* moving sources */
#define NROOMS 8 /* rooms far away in case d */
#define SPAN 1.5 /* s of audio per timed span */
#define RUNS 8
#define WARM 0.25
#define NOISE 48000 /* frames of noise (a multiple of BLOCK) */
#define CFLAGS BENCH_CFLAGS

static const double g_lis[3] = {10, 7.5, 1.7};
static const wdrt_room g_room = {{0, 0, 0, 20, 15, 8}, 1.2, 0.8, 2};
#define ROOM_IMAGES 24 /* images of order 1 and 2 in a box: 6 + 18 */

static tl_voice g_voice;
static int g_out;
static double g_noise[NOISE];
static float g_fnoise[NOISE];

static void fatal(const char *what, wdrt_result r) {
    fprintf(stderr, "spacebench: %s: %s\n", what, wdrt_result_str(r));
    exit(1);
}

/* ---- the circles ---- */

typedef struct orbit {
    double r, w, ph, z; /* m, rad/s, rad, m */
} orbit;
static orbit g_orbit[NSRC];

static void orbits(void) {
    tl_rng rng;
    tl_rng_seed(&rng, 0x5BACEull);
    for (int i = 0; i < NSRC; i++) {
        orbit *o = &g_orbit[i];
        o->r = 2 + 4 * (double)i / (NSRC - 1);
        o->w = 2 * M_PI * (0.2 + 0.6 * tl_rng_uniform(&rng)) * (i & 1 ? -1 : 1);
        o->ph = 2 * M_PI * tl_rng_uniform(&rng);
        o->z = 1.2 + 1.3 * tl_rng_uniform(&rng);
    }
}

/* Where source i is at t s (our axes), and its velocity (m/s). */
static void orbit_at(int i, double t, double p[3], double v[3]) {
    const orbit *o = &g_orbit[i];
    double a = o->ph + o->w * t;
    p[0] = g_lis[0] + o->r * cos(a);
    p[1] = g_lis[1] + o->r * sin(a);
    p[2] = o->z;
    v[0] = -o->r * o->w * sin(a);
    v[1] = o->r * o->w * cos(a);
    v[2] = 0;
}

/* ---- our engines ---- */

enum { C_NONE, C_DIRECT, C_AIR, C_ROOM, C_ROOMS, C_EARS, NCASE };

typedef struct wcase {
    const char *label;
    wdrt_engine *e;
    int placed;
    wdrt_voice v[NSRC];
    uint64_t t; /* frames rendered */
    double best; /* s per span */
    int finite, sources;
    uint64_t unplaced;
    double peak;
} wcase;

static void make_case(wcase *c, int kind, const wdrt_hrtf *h) {
    wdrt_pool_config pc[NSRC];
    for (int i = 0; i < NSRC; i++) {
        double vel[3];
        pc[i] = wdrt_pool_config_init(g_voice.cls, 1);
        pc[i].owned = 1;
        pc[i].output = g_out;
        pc[i].gain = 0.5;
        pc[i].cost_ns = 1; /* not measured: there is no budget */
        pc[i].hold = 1000;
        pc[i].pan = -0.8 + 1.6 * (double)i / (NSRC - 1);
        pc[i].placed = kind != C_NONE && kind != C_ROOMS;
        orbit_at(i, 0, pc[i].pos, vel);
    }
    wdrt_engine_config ec = wdrt_engine_config_init(FS, 2, NSRC, pc);
    ec.block = BLOCK;
    ec.sleep = 0;
    wdrt_room far[NROOMS];
    if (kind != C_NONE) {
        ec.space.sources = kind == C_ROOMS ? 1 : NSRC;
        ec.space.distance = WDRT_DISTANCE_INVERSE;
        ec.space.ref = 1;
        ec.space.max = 100;
        ec.space.rolloff = 1;
        ec.space.air = kind == C_AIR;
        memcpy(ec.space.listener, g_lis, sizeof g_lis);
        if (kind == C_ROOM) {
            ec.space.nrooms = 1;
            ec.space.rooms = &g_room;
        } else if (kind == C_ROOMS) {
            for (int k = 0; k < NROOMS; k++) {
                far[k] = g_room;
                far[k].order = 0;
                far[k].box[0] += 60 + 30 * k;
                far[k].box[3] += 60 + 30 * k;
            }
            ec.space.nrooms = NROOMS;
            ec.space.rooms = far;
        }
        if (kind == C_EARS)
            ec.space.hrtf = h;
    }
    wdrt_result r = wdrt_engine_init(&ec, NULL, &c->e);
    if (r != WDRT_OK)
        fatal(c->label, r);
    c->placed = kind != C_NONE && kind != C_ROOMS;
    for (int i = 0; i < NSRC; i++)
        c->v[i] = wdrt_engine_voice(c->e, i, 0);
    c->t = 0;
    c->best = INFINITY;
    c->finite = 1;
    c->peak = 0;
}

/* Renders n frames (a multiple of BLOCK) of c: moves, inputs, process. */
static void run_case(wcase *c, long n) {
    static double out[2 * BLOCK];
    int finite = 1;
    double pk = c->peak;
    for (long f = 0; f < n; f += BLOCK) {
        uint64_t now = c->t;
        if (c->placed)
            for (int i = 0; i < NSRC; i++) {
                double p[3], vel[3];
                orbit_at(i, (double)(now + BLOCK) / FS, p, vel);
                if (wdrt_engine_move(c->e, now, c->v[i], p) != WDRT_OK)
                    fatal("move", WDRT_ERROR);
            }
        for (int i = 0; i < NSRC; i++) {
            uint64_t off = ((now / BLOCK + (uint64_t)i * 37) % (NOISE / BLOCK)) * BLOCK;
            wdrt_engine_bind_input(c->e, c->v[i], 0, g_noise + off);
        }
        wdrt_engine_process(c->e, out, BLOCK);
        for (int j = 0; j < 2 * BLOCK; j++) {
            finite &= isfinite(out[j]) != 0;
            pk = fabs(out[j]) > pk ? fabs(out[j]) : pk;
        }
        c->t += BLOCK;
    }
    c->finite &= finite;
    c->peak = pk;
}

/* ---- OpenAL Soft ---- */

enum { A_PAN0, A_PAN, A_HRTF0, A_HRTF, NALCASE };

typedef struct alcase {
    const char *label;
    ALCdevice *dev;
    ALCcontext *ctx;
    ALuint buf, src[NSRC];
    int nsrc, hrtf, ok;
    uint64_t t;
    double best, peak;
    int finite;
    char why[256]; /* when !ok */
} alcase;

static char g_alversion[128], g_alrenderer[128], g_alresampler[64], g_alhrtfname[128];

/* OpenAL's axes from ours: x right, y up, -z ahead. */
static void to_al(const double p[3], ALfloat q[3]) {
    q[0] = (ALfloat)p[0];
    q[1] = (ALfloat)p[2];
    q[2] = (ALfloat)-p[1];
}

static int al_failed(alcase *a, const char *what) {
    ALenum err = alGetError();
    if (err == AL_NO_ERROR)
        return 0;
    snprintf(a->why, sizeof a->why, "%s: AL error 0x%04x", what, (unsigned)err);
    a->ok = 0;
    return 1;
}

static void al_close(alcase *a) {
    if (a->ctx) {
        alcMakeContextCurrent(a->ctx);
        if (a->nsrc) {
            alSourceStopv(a->nsrc, a->src);
            alDeleteSources(a->nsrc, a->src);
        }
        if (a->buf)
            alDeleteBuffers(1, &a->buf);
        alcMakeContextCurrent(NULL);
        alcDestroyContext(a->ctx);
        a->ctx = NULL;
    }
    if (a->dev) {
        alcCloseDevice(a->dev);
        a->dev = NULL;
    }
}

static const char *hrtf_status(ALCint st) {
    switch (st) {
    case ALC_HRTF_DISABLED_SOFT: return "disabled";
    case ALC_HRTF_ENABLED_SOFT: return "enabled";
    case ALC_HRTF_DENIED_SOFT: return "denied";
    case ALC_HRTF_REQUIRED_SOFT: return "required";
    case ALC_HRTF_HEADPHONES_DETECTED_SOFT: return "headphones detected";
    case ALC_HRTF_UNSUPPORTED_FORMAT_SOFT: return "unsupported format";
    default: return "unknown";
    }
}

/* A loopback device and context for a, its sources playing; a->ok, or the
 * reason in a->why. */
static void al_open(alcase *a, int nsrc, int hrtf) {
    a->ok = 0;
    a->nsrc = 0;
    a->hrtf = hrtf;
    a->best = INFINITY;
    a->finite = 1;
    a->peak = 0;
    a->t = 0;
    if (!alcIsExtensionPresent(NULL, "ALC_SOFT_loopback")) {
        snprintf(a->why, sizeof a->why, "ALC_SOFT_loopback is not supported");
        return;
    }
    a->dev = alcLoopbackOpenDeviceSOFT(NULL);
    if (!a->dev) {
        snprintf(a->why, sizeof a->why, "alcLoopbackOpenDeviceSOFT failed");
        return;
    }
    if (!alcIsRenderFormatSupportedSOFT(a->dev, (ALCsizei)FS, ALC_STEREO_SOFT, ALC_FLOAT_SOFT)) {
        snprintf(a->why, sizeof a->why, "float stereo at 48 kHz is not a supported loopback format");
        al_close(a);
        return;
    }
    int has_hrtf = alcIsExtensionPresent(a->dev, "ALC_SOFT_HRTF");
    if (hrtf && !has_hrtf) {
        snprintf(a->why, sizeof a->why, "ALC_SOFT_HRTF is not supported");
        al_close(a);
        return;
    }
    ALCint attrs[16], n = 0;
    attrs[n++] = ALC_FREQUENCY, attrs[n++] = (ALCint)FS;
    attrs[n++] = ALC_FORMAT_CHANNELS_SOFT, attrs[n++] = ALC_STEREO_SOFT;
    attrs[n++] = ALC_FORMAT_TYPE_SOFT, attrs[n++] = ALC_FLOAT_SOFT;
    attrs[n++] = ALC_MONO_SOURCES, attrs[n++] = NSRC + 4;
    if (has_hrtf)
        attrs[n++] = ALC_HRTF_SOFT, attrs[n++] = hrtf ? ALC_TRUE : ALC_FALSE;
    attrs[n++] = 0;
    a->ctx = alcCreateContext(a->dev, attrs);
    if (!a->ctx || !alcMakeContextCurrent(a->ctx)) {
        snprintf(a->why, sizeof a->why, "alcCreateContext failed: ALC error 0x%04x",
                 (unsigned)alcGetError(a->dev));
        al_close(a);
        return;
    }
    if (has_hrtf) {
        ALCint st = ALC_HRTF_DISABLED_SOFT;
        alcGetIntegerv(a->dev, ALC_HRTF_STATUS_SOFT, 1, &st);
        int on = st == ALC_HRTF_ENABLED_SOFT || st == ALC_HRTF_REQUIRED_SOFT ||
                 st == ALC_HRTF_HEADPHONES_DETECTED_SOFT;
        if (hrtf && !on) {
            ALCint nspec = 0;
            alcGetIntegerv(a->dev, ALC_NUM_HRTF_SPECIFIERS_SOFT, 1, &nspec);
            snprintf(a->why, sizeof a->why,
                     "HRTF could not be enabled with the installed data (status: %s; %d HRTF data sets found)",
                     hrtf_status(st), (int)nspec);
            al_close(a);
            return;
        }
        if (!hrtf && on) {
            snprintf(a->why, sizeof a->why, "HRTF could not be turned off (status: %s)", hrtf_status(st));
            al_close(a);
            return;
        }
        if (hrtf) {
            const ALCchar *name = alcGetString(a->dev, ALC_HRTF_SPECIFIER_SOFT);
            snprintf(g_alhrtfname, sizeof g_alhrtfname, "%s", name ? name : "?");
        }
    }
    const ALchar *ver = alGetString(AL_VERSION), *ren = alGetString(AL_RENDERER);
    snprintf(g_alversion, sizeof g_alversion, "%s", ver ? ver : "?");
    snprintf(g_alrenderer, sizeof g_alrenderer, "%s", ren ? ren : "?");
    if (alIsExtensionPresent("AL_SOFT_source_resampler")) {
        const ALchar *rs = alGetStringiSOFT(AL_RESAMPLER_NAME_SOFT, alGetInteger(AL_DEFAULT_RESAMPLER_SOFT));
        snprintf(g_alresampler, sizeof g_alresampler, "%s", rs ? rs : "?");
    }
    alGetError();
    alDistanceModel(AL_INVERSE_DISTANCE_CLAMPED);
    alSpeedOfSound(343);
    ALfloat L[3];
    to_al(g_lis, L);
    alListener3f(AL_POSITION, L[0], L[1], L[2]);
    ALfloat ori[6] = {0, 0, -1, 0, 1, 0};
    alListenerfv(AL_ORIENTATION, ori);
    if (al_failed(a, "listener"))
        goto fail;
    ALenum fmt = alIsExtensionPresent("AL_EXT_FLOAT32") ? AL_FORMAT_MONO_FLOAT32 : 0;
    alGenBuffers(1, &a->buf);
    if (fmt)
        alBufferData(a->buf, fmt, g_fnoise, (ALsizei)sizeof g_fnoise, (ALsizei)FS);
    else {
        static short s16[NOISE];
        for (int i = 0; i < NOISE; i++)
            s16[i] = (short)lrint(g_fnoise[i] * 32767);
        alBufferData(a->buf, AL_FORMAT_MONO16, s16, (ALsizei)sizeof s16, (ALsizei)FS);
    }
    if (al_failed(a, "buffer"))
        goto fail;
    if (nsrc) {
        alGenSources(nsrc, a->src);
        if (al_failed(a, "alGenSources"))
            goto fail;
        a->nsrc = nsrc;
        for (int i = 0; i < nsrc; i++) {
            double p[3], v[3];
            ALfloat q[3], w[3];
            orbit_at(i, 0, p, v);
            to_al(p, q);
            to_al(v, w);
            alSourcei(a->src[i], AL_BUFFER, (ALint)a->buf);
            alSourcei(a->src[i], AL_LOOPING, AL_TRUE);
            alSourcef(a->src[i], AL_GAIN, 0.5f);
            alSourcef(a->src[i], AL_REFERENCE_DISTANCE, 1);
            alSourcef(a->src[i], AL_MAX_DISTANCE, 100);
            alSourcef(a->src[i], AL_ROLLOFF_FACTOR, 1);
            alSource3f(a->src[i], AL_POSITION, q[0], q[1], q[2]);
            alSource3f(a->src[i], AL_VELOCITY, w[0], w[1], w[2]);
            alSourcei(a->src[i], AL_SAMPLE_OFFSET, (i * 7919) % NOISE);
        }
        alSourcePlayv(nsrc, a->src);
        if (al_failed(a, "sources"))
            goto fail;
    }
    a->ok = 1;
    return;
fail:
    al_close(a);
}

static void run_al(alcase *a, long n) {
    static float out[2 * BLOCK];
    alcMakeContextCurrent(a->ctx);
    int finite = 1;
    double pk = a->peak;
    for (long f = 0; f < n; f += BLOCK) {
        for (int i = 0; i < a->nsrc; i++) {
            double p[3], v[3];
            ALfloat q[3], w[3];
            orbit_at(i, (double)(a->t + BLOCK) / FS, p, v);
            to_al(p, q);
            to_al(v, w);
            alSource3f(a->src[i], AL_POSITION, q[0], q[1], q[2]);
            alSource3f(a->src[i], AL_VELOCITY, w[0], w[1], w[2]);
        }
        alcRenderSamplesSOFT(a->dev, out, BLOCK);
        for (int j = 0; j < 2 * BLOCK; j++) {
            finite &= isfinite(out[j]) != 0;
            pk = fabs(out[j]) > pk ? fabs(out[j]) : pk;
        }
        a->t += BLOCK;
    }
    a->finite &= finite;
    a->peak = pk;
}

/* ---- the report ---- */

static double per_source(double t, double t0, long frames) { return (t - t0) * 1e9 / ((double)NSRC * (double)frames); }

static void row(const char *label, double engine_ns, double src_ns, const char *extra) {
    printf("   %-46s %9.1f %9.1f %9s %9.0f\n", label, engine_ns, src_ns, extra, 1e9 / (FS * src_ns));
}

int main(int argc, char **argv) {
    (void)argv;
    if (argc > 1) {
        fprintf(stderr, "usage: spacebench\n");
        return 2;
    }
    double t_start = bench_now();
    if (tl_voice_build_args("netlists/rc_lowpass.wdn", 0, NULL, CFLAGS, &g_voice) != 0)
        return 1;
    g_out = tl_output_id(g_voice.cls, "out");
    if (g_out < 0) {
        fprintf(stderr, "spacebench: rc_lowpass has no output out\n");
        return 1;
    }
    tl_rng rng;
    tl_rng_seed(&rng, 0x401ull);
    for (int i = 0; i < NOISE; i++) {
        g_noise[i] = tl_rng_signed(&rng);
        g_fnoise[i] = (float)g_noise[i];
    }
    orbits();

    printf("wdrt spatial layer benchmark: %.0f Hz, stereo, %d moving sources (rc_lowpass driven by white noise,\n"
           "each on its own circle 2..6 m about the listener at 2.5..30 m/s, moved every %d-frame block),\n"
           "process calls of %d frames; wall time of the whole loop (moves, input binding, process), best of %d\n"
           "spans of %.1f s after %.2f s untimed, the cases taking turns\n",
           FS, NSRC, BLOCK, BLOCK, RUNS, SPAN, WARM);
    bench_print_setup(CFLAGS);
    fflush(stdout);

    char err[512];
    wdrt_hrtf *h = wdrt_hrtf_open(NULL, FS, err, sizeof err);
    static const char *const labels[NCASE] = {
        "0  voices not placed (their own cost)", "a  direct path, air off", "b  direct path + air absorption",
        "c  in a 20x15x8 m room, images to order 2", "d  0 + 8 rooms far away (reverbs unfed)",
        "e  binaural (MIT KEMAR HRTF), air off"};
    wcase wc[NCASE];
    int nw = 0;
    for (int k = 0; k < NCASE; k++) {
        memset(&wc[k], 0, sizeof wc[k]);
        wc[k].label = labels[k];
        if (k == C_EARS && !h) {
            printf("   (binaural case skipped: %s)\n", err);
            continue;
        }
        make_case(&wc[k], k, h);
        nw = k + 1;
    }

    static const char *const allabels[NALCASE] = {"no sources, HRTF off", "panned", "no sources, HRTF on",
                                                  "HRTF"};
    alcase al[NALCASE];
    for (int k = 0; k < NALCASE; k++) {
        memset(&al[k], 0, sizeof al[k]);
        al[k].label = allabels[k];
        al_open(&al[k], (k == A_PAN || k == A_HRTF) ? NSRC : 0, k >= A_HRTF0);
    }

    long warm = (long)(WARM * FS) / BLOCK * BLOCK, span = (long)(SPAN * FS) / BLOCK * BLOCK;
    for (int k = 0; k < nw; k++)
        if (wc[k].e)
            run_case(&wc[k], warm);
    for (int k = 0; k < NALCASE; k++)
        if (al[k].ok)
            run_al(&al[k], warm);
    /* rounds: every case once, the order rotating */
    int total = NCASE + NALCASE;
    for (int r = 0; r < RUNS; r++)
        for (int j = 0; j < total; j++) {
            int k = (j + r * 3) % total;
            double t0 = bench_now(), dt;
            if (k < NCASE) {
                if (!wc[k].e)
                    continue;
                run_case(&wc[k], span);
                dt = bench_now() - t0;
                wc[k].best = dt < wc[k].best ? dt : wc[k].best;
            } else {
                alcase *a = &al[k - NCASE];
                if (!a->ok)
                    continue;
                run_al(a, span);
                dt = bench_now() - t0;
                a->best = dt < a->best ? dt : a->best;
            }
        }
    int failed = 0;
    for (int k = 0; k < NCASE; k++)
        if (wc[k].e) {
            wdrt_engine_stats st;
            wdrt_engine_get_stats(wc[k].e, &st);
            wc[k].sources = st.sources;
            wc[k].unplaced = st.unplaced;
            failed |= !wc[k].finite;
        }

    /* ns per sample of each engine, and per source */
    double ns[NCASE];
    for (int k = 0; k < NCASE; k++)
        ns[k] = wc[k].e ? wc[k].best * 1e9 / (double)span : NAN;
    double src[NCASE];
    for (int k = 0; k < NCASE; k++)
        src[k] = per_source(wc[k].best, wc[C_NONE].best, span);
    double fdn = (ns[C_ROOMS] - ns[C_NONE]) / NROOMS;
    double room_extra = (ns[C_ROOM] - ns[C_DIRECT] - fdn) / NSRC;

    printf("   %-46s %9s %9s %9s %9s\n", "", "engine", "spatial", "over (a)", "sources");
    printf("   %-46s %9s %9s %9s %9s\n", "case", "ns/sample", "ns/src/s", "ns/src/s", "real time");
    printf("   %-46s %9s %9s %9s %9s\n", "----------------------------------------------", "---------",
           "---------", "---------", "---------");
    printf("   %-46s %9.1f %9s %9s %9s\n", wc[C_NONE].label, ns[C_NONE], "-", "-", "-");
    char cell[32];
    row(wc[C_DIRECT].label, ns[C_DIRECT], src[C_DIRECT], "-");
    snprintf(cell, sizeof cell, "%+.1f", src[C_AIR] - src[C_DIRECT]);
    row(wc[C_AIR].label, ns[C_AIR], src[C_AIR], cell);
    snprintf(cell, sizeof cell, "%+.1f", room_extra);
    row(wc[C_ROOM].label, ns[C_ROOM], src[C_ROOM], cell);
    printf("   %-46s %9.1f %9s %9s %9s\n", wc[C_ROOMS].label, ns[C_ROOMS], "-", "-", "-");
    if (wc[C_EARS].e) {
        snprintf(cell, sizeof cell, "%+.1f", src[C_EARS] - src[C_DIRECT]);
        row(wc[C_EARS].label, ns[C_EARS], src[C_EARS], cell);
    }
    printf("   (d) the reverb (a 16-line FDN) of one room: %.1f ns per room and sample ((d - 0) / %d): unfed, it sleeps once rung down\n",
           fdn, NROOMS);
    printf("   (c) over (a): the %d image sources of a source, the room's reverb taken off: %.1f ns per source\n"
           "       and sample, %.2f ns per image; (c)'s spatial column holds its share of the reverb (1/%d)\n",
           ROOM_IMAGES, room_extra, room_extra / ROOM_IMAGES, NSRC);
    printf("   delay lines in use at the end:");
    for (int k = C_DIRECT; k < NCASE; k++)
        if (wc[k].e && k != C_ROOMS)
            printf(" %c %d%s", "0abcde"[k], wc[k].sources, wc[k].unplaced ? " (some unplaced!)" : "");
    printf(" (of %d); every render finite: %s\n", NSRC, failed ? "NO" : "yes");
    printf("   sources in real time: 1e9 / (48000 x spatial ns per source), one core, the voices' own cost\n"
           "   and the rest of the engine not counted\n\n");
    fflush(stdout);

    /* OpenAL Soft */
    printf("OpenAL Soft, same run: %s, %s; loopback device, float stereo at 48 kHz, calls of %d frames;\n"
           "%d sources looping 1 s of mono float noise on the same circles, AL_POSITION and AL_VELOCITY\n"
           "(Doppler) set every %d frames; inverse distance clamped (ref 1, max 100); resampler %s\n",
           g_alversion[0] ? g_alversion : "version ?", g_alrenderer[0] ? g_alrenderer : "?", BLOCK, NSRC, BLOCK,
           g_alresampler[0] ? g_alresampler : "?");
    printf("   %-46s %9s %9s %9s %9s\n", "case", "ns/sample", "ns/src/s", "ours", "real time");
    printf("   %-46s %9s %9s %9s %9s\n", "----------------------------------------------", "---------",
           "---------", "---------", "---------");
    for (int k = 0; k < NALCASE; k++) {
        alcase *a = &al[k];
        char lab[256];
        snprintf(lab, sizeof lab, "%s%s%s%s", a->label, k == A_HRTF && g_alhrtfname[0] ? " (" : "",
                 k == A_HRTF ? g_alhrtfname : "", k == A_HRTF && g_alhrtfname[0] ? ")" : "");
        if (!a->ok) {
            printf("   %-46s not measured: %s\n", lab, a->why);
            continue;
        }
        double a_ns = a->best * 1e9 / (double)span;
        if (!a->nsrc) {
            printf("   %-46s %9.1f %9s %9s %9s\n", lab, a_ns, "-", "-", "-");
            continue;
        }
        const alcase *z = &al[k - 1];
        if (!z->ok) {
            printf("   %-46s %9.1f %9s (no baseline)\n", lab, a_ns, "?");
            continue;
        }
        double s = per_source(a->best, z->best, span);
        int ours = k == A_PAN ? C_DIRECT : C_EARS;
        char r[32] = "-";
        if (wc[ours].e)
            snprintf(r, sizeof r, "%.2fx", src[ours] / s);
        printf("   %-46s %9.1f %9.1f %9s %9.0f\n", lab, a_ns, s, r, 1e9 / (FS * s));
        if (!a->finite || a->peak == 0)
            printf("   (%s: the output was %s)\n", lab, !a->finite ? "not finite" : "silent");
    }
    printf("   ns/src/s: (t_N - t_0) / (%d frames) against the same device with no sources; ours: our (a) or\n"
           "   (e) over it.  OpenAL Soft mixes in float, ours in double; its Doppler is a pitch from the\n"
           "   velocity through its resampler, ours the retarded time (solved 3 times a block, a parabola between) read from a\n"
           "   delay line by 4-point Lagrange; our HRTF filters are 256 taps per ear\n\n",
           NSRC);

    for (int k = 0; k < NALCASE; k++)
        al_close(&al[k]);
    for (int k = 0; k < NCASE; k++)
        if (wc[k].e)
            wdrt_engine_uninit(wc[k].e, NULL);
    wdrt_hrtf_close(h);
    tl_voice_free(&g_voice);
    printf("(%.0f s)\n", bench_now() - t_start);
    return failed;
}
