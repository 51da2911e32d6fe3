/*
 * wdrt.h - libwdrt, the object runtime that wave-digital voices live in.
 *
 * The engine hosts pools of voices (compiled by wdc; see wdvoice.h), mixes
 * them to mono or stereo and renders them in blocks of any length.  It owns
 * all its memory from init on: one block, sized by get_size, laid out once
 * and never grown.  Each internal block runs in phases: events, then
 * sources, then the mix; timbre trees, surfaces, spatial layers and
 * complexes add their objects to these phases.
 *
 * Events (strike, set a param, play a note from a pool, stop, gain) name the
 * absolute frame at which they act and take effect at exactly that frame,
 * whatever the lengths of the blocks the host renders.  One control thread
 * (the producer) may post them while another thread processes: they travel
 * through a lock-free single-producer, single-consumer queue.
 *
 * The engine models no more than a scene needs:
 *   - sleep: a voice whose output has stayed below its quiet level for a
 *     while and whose stored energy has fallen below its floor (or stays
 *     put) fades out over one block and sleeps; a sleeping voice is not visited at all
 *     until an event wakes it.  A played note that falls asleep frees its
 *     instance.
 *   - budget: each pool's voices cost so many ns per sample (measured at
 *     init unless given).  Past the budget, the least important sounding
 *     voices (lowest priority, then quietest) are stolen with a one-block
 *     fade, or made virtual: they stop being computed and come back, with a
 *     fade-in, when the budget has room again and they are still audible.
 *
 * Units: frames and samples at the engine's rate (Hz), gains linear,
 * levels in the units of the voice's output times its gain, costs in ns per
 * sample, times in seconds.  No global state: everything lives in an
 * engine.  Functions say whether they may run on the audio thread.
 */
#ifndef WDRT_H
#define WDRT_H

#include <stddef.h>
#include <stdio.h>
#include <stdint.h>

#include "wdvoice.h"

typedef enum wdrt_result {
    WDRT_OK = 0,
    WDRT_ERROR = -1,         /* generic failure */
    WDRT_INVALID_ARGS = -2,
    WDRT_OUT_OF_MEMORY = -3,
    WDRT_TOOLCHAIN = -4,     /* the C compiler (or wdc) failed */
    WDRT_LOAD = -5,          /* dlopen/dlsym failed */
    WDRT_IO = -6,            /* file could not be read or written */
    WDRT_FORMAT = -7,        /* file is not in a readable format */
    WDRT_QUEUE_FULL = -8,    /* the event queue has no room: post again later */
    WDRT_SYNTAX = -9,        /* a scene or tree has an error (message given) */
    WDRT_OUT_OF_TUNE = -10,  /* a voice's string, tube or delay line cannot
                                be tuned at the rate (wdv_class.tuning) */
} wdrt_result;

/* A constant string describing r.  Real-time safe. */
const char *wdrt_result_str(wdrt_result r);

/* Where the runtime's memory comes from.  alloc returns `size` bytes
 * aligned to at least 16 bytes (NULL on failure); free takes what alloc
 * returned.  NULL callbacks mean malloc/free. */
typedef struct wdrt_alloc_callbacks {
    void *user;
    void *(*alloc)(size_t size, void *user);
    void (*free)(void *p, void *user);
} wdrt_alloc_callbacks;

/* ---- the engine ---------------------------------------------------- */

typedef struct wdrt_engine wdrt_engine;

/* A sounding thing events are addressed to: a standing voice of an owned
 * pool, a note played from a pool, or a whole pool (every voice in it, and
 * the param values later notes start from).  0 is no voice. */
typedef uint32_t wdrt_voice;

/* Most (id, value) pairs one strike carries. */
#define WDRT_STRIKE_MAX 16

/* ---- space ---- */

/* How loudness falls with distance d: OpenAL's clamped models, d taken
 * in [ref, max]: inverse ref/(ref + rolloff (d - ref)), linear
 * 1 - rolloff (d - ref)/(max - ref), exponent (d/ref)^-rolloff. */
typedef enum wdrt_distance {
    WDRT_DISTANCE_NONE,
    WDRT_DISTANCE_INVERSE,
    WDRT_DISTANCE_LINEAR,
    WDRT_DISTANCE_EXPONENT,
} wdrt_distance;

/* A partition: a vertical wall from (x, y) to (x, y), m, of any height;
 * what crosses it loses loss_db and is muffled. */
typedef struct wdrt_wall {
    double from[2], to[2];
    double loss_db;
} wdrt_wall;

/* A box room: image sources up to `order` (each a tap on a source's delay
 * line with its own delay, distance gain, wall filter and direction) for
 * the sources in it while the listener is in it too, and a reverb (a
 * feedback delay network) fed by the sources in it, heard fully inside
 * and, outside, through the walls between the listener and the room. */
typedef struct wdrt_room {
    double box[6];        /* x0 y0 z0 x1 y1 z1, m */
    double t60_low;       /* s at and below 500 Hz */
    double t60_high;      /* s at and above 4 kHz */
    int order;            /* image-source order, 0..3 */
} wdrt_room;

/* A head-related transfer function set for binaural output, loaded from
 * a SOFA file (AES69) through libmysofa and resampled to fs (Hz); NULL
 * sofa: Debian's MIT KEMAR set.  Shared by every source and engine that
 * names it; close it after them.  NULL on failure with "PATH: error: why"
 * in err.  Allocates and reads a file: not real-time safe. */
typedef struct wdrt_hrtf wdrt_hrtf;
wdrt_hrtf *wdrt_hrtf_open(const char *sofa, double fs, char *err, size_t errlen);
void wdrt_hrtf_close(wdrt_hrtf *h);

/* The spatial layer.  Placed voices (wdrt_pool_config.placed) are heard
 * through it: each feeds a delay line that the listener reads at the
 * retarded time (so arrival times and Doppler follow from the motion),
 * with the distance gain, air absorption, occlusion by walls and
 * constant-power panning by direction, or an HRTF for each ear.  Voices not placed are mixed as
 * they sound. */
typedef struct wdrt_space_config {
    int sources;          /* placed voices heard at once (delay lines); 0: none */
    double c;             /* speed of sound, m/s; default 343 */
    wdrt_distance distance;
    double ref, max, rolloff; /* m, m, factor: defaults 1, 1000, 1 */
    double max_delay;     /* s a delay line holds; default max/c, at most 3 */
    int air;              /* 1: air absorption (ISO 9613-1, 20 °C, 50 %) */
    double listener[3];   /* m: where the listener starts */
    double facing[3];     /* the direction it faces (z is up); default +y */
    int nwalls;
    const wdrt_wall *walls; /* copied at init */
    const wdrt_hrtf *hrtf;  /* binaural: heard through it (stereo output, left
                               and right ear); NULL: panned */
    int nrooms;
    const wdrt_room *rooms; /* copied at init */
} wdrt_space_config;

/* One pool of instances of a voice class. */
typedef struct wdrt_pool_config {
    const wdv_class *cls;
    int voices;       /* instances, sized at init (>= 1) */
    int owned;        /* 1: standing voices, addressed by wdrt_engine_voice
                         and awake from the start; 0: notes are played
                         from the pool with wdrt_engine_play */
    int output;       /* the voice output that is heard (index) */
    double gain;      /* linear gain of every voice of the pool */
    double pan;       /* stereo position, -1 left .. 1 right, constant power */
    int priority;     /* higher matters more when the budget is short */
    double cost_ns;   /* ns per sample of one voice; 0: measured at init */
    double quiet;     /* output level below which a voice may sleep
                         (absolute, after gain); default 1e-5 (-100 dB) */
    double floor_db;  /* stored energy below which a voice may sleep, in dB
                         of the energy it had after its last strike (or at
                         init); default -60 */
    double hold;      /* s the output must stay quiet before a voice may
                         sleep; default 0.1.  At its end the voice sleeps
                         if its energy is below the floor, or has moved by
                         less than the floor since the quiet began: energy
                         that stays put in a quiet voice (a hammer flying
                         off after its strike) is energy it never sounds */
    int virtualize;   /* past the budget: 1 made virtual, 0 stolen */
    int spares;       /* extra instances that carry the fade-out of a voice
                         stolen to play a new note; default 2 */
    const double *params; /* the params every voice starts with (n_params
                         values, copied at init), or NULL: the defaults */
    /* Sources the runtime builds (timbre trees, resonators, complexes)
     * are classes too; their shared data reaches each state through
     * bind(state, data), called once after init on the state every
     * instance is copied from (so it must hold only data that may be
     * copied: a pointer to data that outlives the engine, say).  NULL
     * for compiled voices. */
    void (*bind)(void *state, const void *data);
    const void *data;
    int placed;           /* 1: heard through the spatial layer */
    double pos[3];        /* m: where its voices start */
    int ambient;          /* 0, or 1 + the index of a room of the space config:
                             the pool (not placed) is that room's ambience,
                             heard as its reverb is: fully inside the room,
                             from outside at the distance to the room and
                             through the walls between */
} wdrt_pool_config;

/* Defaults for a pool of `voices` instances of cls, played as notes.
 * Real-time safe. */
wdrt_pool_config wdrt_pool_config_init(const wdv_class *cls, int voices);

typedef struct wdrt_engine_config {
    double rate;      /* sample rate, Hz */
    int channels;     /* 1 (mono) or 2 (stereo), interleaved */
    int block;        /* internal block, frames: the length of fades and
                         param ramps; default 64, at most 4096 */
    int queue;        /* events the control queue holds; default 4096 */
    int pending;      /* events waiting for their frame; default 4096 */
    double budget_ns; /* ns per sample all voices may cost; 0: no budget */
    int sleep;        /* 1: quiet voices sleep (default); 0: never */
    int npools;
    const wdrt_pool_config *pools;
    wdrt_space_config space;
    /* The excitations phase: called on the audio thread at the start of
     * every block, before the voices, with the block's first frame and
     * length (what bodies in contact and impacts excite, computed once
     * for all the sources they feed).  It sets wake[p] to 1 for each pool
     * p whose voices it excited: they wake from sleep.  Must be real-time
     * safe.  NULL: no such phase. */
    void (*excite)(void *user, uint64_t frame, int nframes, unsigned char *wake);
    void *excite_user;
} wdrt_engine_config;

/* Defaults: 64-frame blocks, queues of 4096, no budget, sleep on.
 * Real-time safe. */
wdrt_engine_config wdrt_engine_config_init(double rate, int channels,
                                           int npools,
                                           const wdrt_pool_config *pools);

/* Bytes an engine for cfg needs (at most 64 of them for alignment).
 * Not real-time safe when a pool's cost is measured (cost_ns 0) elsewhere;
 * this call itself only computes. */
wdrt_result wdrt_engine_get_size(const wdrt_engine_config *cfg, size_t *size);

/* Makes an engine in `mem` (get_size bytes, any alignment): initialises
 * every instance (the class's init, at the engine's rate) and measures
 * the cost of classes that have none given, by running a scratch instance
 * for about 10 ms.  WDRT_OUT_OF_TUNE if a voice's string, tube or delay
 * line cannot be tuned at the engine's rate (wdv_class.tuning), with the
 * pools' params: it would play out of tune.  Not real-time safe. */
wdrt_result wdrt_engine_init_prealloc(const wdrt_engine_config *cfg,
                                      void *mem, wdrt_engine **engine);
/* The same in memory from alloc (NULL: malloc).  Not real-time safe. */
wdrt_result wdrt_engine_init(const wdrt_engine_config *cfg,
                             const wdrt_alloc_callbacks *alloc,
                             wdrt_engine **engine);
/* Ends an engine; frees its memory when it came from wdrt_engine_init
 * (pass the same alloc).  Not real-time safe. */
void wdrt_engine_uninit(wdrt_engine *e, const wdrt_alloc_callbacks *alloc);

/* Renders nframes (any number) into out, interleaved channels, replacing
 * what was there.  Events due in these frames take effect at their frame.
 * Real-time safe: no allocation, locks, I/O or unbounded loops. */
void wdrt_engine_process(wdrt_engine *e, double *out, uint32_t nframes);

/* Frames rendered so far: the frame the next process call starts at.
 * Any thread. */
uint64_t wdrt_engine_time(const wdrt_engine *e);

/* Handles.  wdrt_engine_voice: standing voice `index` of owned pool
 * `pool`; wdrt_engine_pool: the whole pool.  0 for a bad index.  Any
 * thread. */
wdrt_voice wdrt_engine_voice(const wdrt_engine *e, int pool, int index);
wdrt_voice wdrt_engine_pool(const wdrt_engine *e, int pool);

/* Control: each posts an event that acts at absolute frame `frame` (a
 * frame already rendered means the start of the next block; such events
 * are counted late).  Only one thread may post, the producer; it may be
 * the thread that processes.  Events at one frame act in the order
 * posted.  Return WDRT_OK, WDRT_INVALID_ARGS, or WDRT_QUEUE_FULL (nothing
 * was posted).  Real-time safe (lock-free, no allocation). */

/* A strike: wdv_class.set_ic with the given targets (at most
 * WDRT_STRIKE_MAX); wakes the voice.  To a pool: every voice in it. */
wdrt_result wdrt_engine_strike(wdrt_engine *e, uint64_t frame, wdrt_voice v,
                               int n, const int *ids, const double *values);
/* Sets param `param`: ramped linearly over one block from the value it
 * has, or stepped when the voice flags the param WDV_PARAM_STEP.  To a
 * pool: every voice in it and every note played from it later. */
wdrt_result wdrt_engine_set(wdrt_engine *e, uint64_t frame, wdrt_voice v,
                            int param, double value);
/* Sets n params (at most WDRT_STRIKE_MAX) of a voice, a note or a pool
 * as wdrt_engine_set sets each, and makes in this call the heavy work
 * they need (wdv_class.prepare: the design of a string's or tube's loop),
 * which the voice takes at `frame` instead of doing it in the block that
 * renders it.  Not real-time safe: call it from the producer thread when
 * that thread may take milliseconds, never from the one that processes.
 * The design is made for the pool's params as posted with these values; a
 * voice whose own values of the params it depends on differ designs in its
 * block, as after wdrt_engine_set.  For a voice class without prepare it
 * is wdrt_engine_set of each.  WDRT_QUEUE_FULL (nothing posted) when the
 * queue cannot take the n + 1 events or every one of WDRT_DESIGN_SLOTS
 * designs is held by an event not yet rendered. */
wdrt_result wdrt_engine_set_prepared(wdrt_engine *e, uint64_t frame, wdrt_voice v,
                                     int n, const int *params, const double *values);
#define WDRT_DESIGN_SLOTS 32
/* The linear gain of a voice (or pool), ramped over one block. */
wdrt_result wdrt_engine_gain(wdrt_engine *e, uint64_t frame, wdrt_voice v,
                             double gain);
/* Plays a note from (not owned) pool `pool`: takes a free instance in the
 * state init left it in, with the pool's current params, and gives it
 * `gain` (linear) and `priority` (added to the pool's).  Follow it with
 * set and strike events to *note at the same frame.  A full pool steals
 * its least important voice, which fades out over one block on a spare
 * instance. */
wdrt_result wdrt_engine_play(wdrt_engine *e, uint64_t frame, int pool,
                             double gain, int priority, wdrt_voice *note);
/* Stops a voice, a note or every voice of a pool: fades out over one
 * block; a note frees its instance, a standing voice returns to the state
 * init left it in and sleeps. */
wdrt_result wdrt_engine_stop(wdrt_engine *e, uint64_t frame, wdrt_voice v);

/* Moves a placed voice (or every voice of a pool) to pos (m): it gets
 * there one block after `frame`, in a straight line, sample by sample; an
 * application that moves its objects once per block gets their paths
 * interpolated per sample. */
wdrt_result wdrt_engine_move(wdrt_engine *e, uint64_t frame, wdrt_voice v, const double pos[3]);
/* Moves the listener the same way, and turns it to face `facing` (NULL:
 * as it was). */
wdrt_result wdrt_engine_listen(wdrt_engine *e, uint64_t frame, const double pos[3], const double facing[3]);

/* Feeds input `k` of standing voice v from `samples` during the next
 * process call only: it must hold that call's nframes samples; bind again
 * before each call (unbound inputs are silent).  A voice whose input is
 * not silent is awake.  Call it from the thread that processes, between
 * process calls.  Real-time safe. */
wdrt_result wdrt_engine_bind_input(wdrt_engine *e, wdrt_voice v, int k,
                                   const double *samples);

typedef struct wdrt_engine_stats {
    uint64_t frames;     /* rendered so far */
    int awake;           /* voices computed in the last block */
    int fading;          /* of those, fading in or out */
    int asleep;          /* standing voices asleep */
    int virtual_;        /* voices made virtual */
    int free;            /* pool instances free to play */
    double cost_ns;      /* cost of the voices computed, ns per sample */
    double budget_ns;    /* the budget (0: none) */
    uint64_t events;     /* events that took effect */
    uint64_t late;       /* of those, after the frame they named */
    uint64_t dropped;    /* events to notes that had ended */
    uint64_t designs;    /* of the events, designs wdrt_engine_set_prepared made */
    uint64_t sleeps, wakes, steals, virtualized, revived;
    uint64_t cuts;       /* voices stolen with no spare to fade on */
    int sources;         /* delay lines in use (placed voices and sound in flight) */
    int rooms;           /* rooms whose reverb still rings */
    uint64_t unplaced;   /* placed voices that found no free delay line */
} wdrt_engine_stats;

/* Counters since init.  Call from the thread that processes, or when it
 * is not running.  Real-time safe. */
void wdrt_engine_get_stats(const wdrt_engine *e, wdrt_engine_stats *s);

/* The cost in ns per sample of one voice of `pool` (measured or given). */
double wdrt_engine_pool_cost(const wdrt_engine *e, int pool);

/* ---- bodies ------------------------------------------------------ */

/* Bodies that sound when they touch, after Menzies' acoustic scene
 * manager: modal resonators (or compiled voices with a force input),
 * surfaces with hardness, damping and a relief, and the contacts and
 * impacts between them, as a physics engine reports them.  A wdrt_bodies
 * is made with its bodies before the engine, hands the engine one pool
 * per resonator (a source like a voice: placed where its body is, asleep
 * when quiet) and runs in the engine's excitations phase.  A physics
 * thread posts impacts and contacts at the frames they happen through a
 * lock-free queue of its own.  See README, "Bodies". */
typedef struct wdrt_bodies wdrt_bodies;

typedef struct wdrt_mode {
    double f;     /* Hz */
    double t60;   /* s: its amplitude falls 60 dB in that time */
    double gain;  /* output units per N s of impulse */
} wdrt_mode;

typedef enum wdrt_relief { WDRT_RELIEF_NONE, WDRT_RELIEF_NOISE, WDRT_RELIEF_GRID, WDRT_RELIEF_SEGMENT } wdrt_relief;

/* How a surface's excitation is routed (Menzies' Figure 4): times
 * master, clipped to +-limit (N), then whole to its own body's resonator,
 * times other to the other body's, times direct to its own heard
 * unresonated (output units per N). */
typedef struct wdrt_gains {
    double master, other, direct, limit;
} wdrt_gains;

typedef struct wdrt_body {
    /* what rings: modes of its own, a compiled voice driven through one of
     * its inputs by the force (N), or the resonator of an earlier body */
    const wdrt_mode *modes;
    int nmodes;
    const wdv_class *voice;
    int input, output;    /* the voice's force input and heard output */
    int share;            /* -1, or the body whose resonator it rings */
    double mass;          /* kg */
    double hardness;      /* N/m: the surface's stiffness in contact */
    double damping;       /* 1/s: added to the resonators it touches */
    wdrt_relief relief;
    double relief_scale;  /* m: the relief's grain, grid spacing, or metres per sample */
    double relief_width;  /* m: a grid's bumps */
    const double *relief_samples; /* SEGMENT: an audio segment read as the relief */
    long relief_nsamples;         /* (copied; the config's relief_frames hold them) */
    wdrt_gains contact_gains, impact_gains; /* default 1, 0, 0, unlimited */
    double cutoff_roll;   /* Hz: a contact's low-pass when it rolls */
    double cutoff_slip;   /* Hz: when it slips at 1 m/s */
    double gain;          /* of what its resonator is heard at */
    double quiet;         /* level below which its resonator sleeps */
    int placed;
    double pos[3];        /* m */
} wdrt_body;

/* Defaults: 0.1 kg, hardness 1e7 N/m, no damping, a noise relief of
 * 0.1 mm grain, cutoffs 200 Hz rolling and 8 kHz slipping, gain 1, quiet
 * 1e-5, share -1, not placed. */
wdrt_body wdrt_body_init(void);

typedef struct wdrt_bodies_config {
    double rate;     /* Hz: the engine's */
    int max_bodies;  /* default 64 */
    int max_modes;   /* per resonator; default 64 */
    int contacts;    /* live at once, and the ids a caller may use; default 32 */
    int impacts;     /* sounding at once; default 64 */
    int queue;       /* events the physics queue holds; default 4096 */
    long relief_frames; /* samples of segment reliefs, all bodies together; default 0 */
    int active_modes;/* modes that may ring at once, all resonators together;
                        0: no limit.  A resonator struck while asleep gets
                        what is left (its loudest modes first; none: the
                        strike is refused); one that sounds keeps its
                        modes until it sleeps, so nothing is cut off */
} wdrt_bodies_config;

wdrt_bodies_config wdrt_bodies_config_init(double rate);

/* Makes an empty world (allocates: not real-time safe); add bodies, then
 * attach it to an engine config before the engine is made. */
wdrt_result wdrt_bodies_new(const wdrt_bodies_config *c, wdrt_bodies **out);
void wdrt_bodies_free(wdrt_bodies *b);
/* Adds a body; returns its index (0, 1, ...) or a negative wdrt_result. */
int wdrt_bodies_add(wdrt_bodies *b, const wdrt_body *body);
/* The pools its resonators need, in order; write them into an engine
 * config's pools from index first (wdrt_bodies_pools), and let it run the
 * excitations phase (wdrt_bodies_attach).  The wdrt_bodies must outlive
 * the engine. */
int wdrt_bodies_npools(const wdrt_bodies *b);
wdrt_result wdrt_bodies_pools(wdrt_bodies *b, wdrt_pool_config *pools, int first);
void wdrt_bodies_attach(wdrt_bodies *b, wdrt_engine_config *c);

/* From one thread (a physics engine's), events at absolute frames, in the
 * order of their frames (an event whose frame has passed acts at once).
 * An impact of bodies a and b: impulse J (N s), normal and tangential
 * speeds (m/s).  A contact `id` (0 .. contacts-1, the caller's name for
 * it) starts or takes new data: the speeds of the contact point over a's
 * and b's surfaces, the slip between them (m/s) and the normal force
 * (N); it lives until stopped.  WDRT_QUEUE_FULL: post again later.
 * Real-time safe (lock-free, no allocation). */
wdrt_result wdrt_bodies_impact(wdrt_bodies *b, uint64_t frame, int a, int c, double impulse, double vn,
                               double vt);
wdrt_result wdrt_bodies_contact(wdrt_bodies *b, uint64_t frame, int id, int a, int c, double v_a,
                                double v_b, double slip, double force);
wdrt_result wdrt_bodies_contact_stop(wdrt_bodies *b, uint64_t frame, int id);
/* Switches a body's sound on or off from that frame (what touches it then
 * is not heard from it). */
wdrt_result wdrt_bodies_enable(wdrt_bodies *b, uint64_t frame, int body, int on);

/* Counts since it was made: contacts and impacts in use and their
 * high-water marks, events refused (a full pool), resonators awake and
 * modes run in the last block.  Call from the audio thread or when it is
 * not running. */
typedef struct wdrt_bodies_stats {
    int contacts, contacts_hwm, impacts, impacts_hwm;
    uint64_t refused;    /* events a full pool or the mode limit refused */
    uint64_t lowered;    /* resonators struck with fewer modes than they have */
    int awake, modes;
} wdrt_bodies_stats;
void wdrt_bodies_get_stats(const wdrt_bodies *b, wdrt_bodies_stats *s);

/* ---- scenes (.wds) ------------------------------------------------- */

/* A scene read from a .wds file: objects and a timeline (see README).
 * Loading checks the syntax and the forms; binding each voice's class
 * checks the names of params and strike targets; rendering runs an
 * engine.  None of this is real-time safe. */
typedef struct wdrt_scene wdrt_scene;

/* Reads and checks a scene.  On an error returns WDRT_SYNTAX (or
 * WDRT_IO) and writes "FILE:LINE:COL: error: message" (with the line and
 * a caret) into err. */
wdrt_result wdrt_scene_load(const char *path, wdrt_scene **scene, char *err,
                            size_t errlen);
void wdrt_scene_free(wdrt_scene *s);

/* The voices the scene names: their count, and for each its name and
 * the netlist's path (relative paths resolved against the scene's
 * folder). */
int wdrt_scene_nvoices(const wdrt_scene *s);
/* The channels a render of the scene has, and its rate with o's override
 * (o may be NULL). */
int wdrt_scene_channels(const wdrt_scene *s);
/* Its (length) in seconds, or 0: until its last event has rung down. */
double wdrt_scene_length(const wdrt_scene *s);
struct wdrt_render_opts;
double wdrt_scene_rate(const wdrt_scene *s, const struct wdrt_render_opts *o);
const char *wdrt_scene_voice_name(const wdrt_scene *s, int i);
const char *wdrt_scene_voice_netlist(const wdrt_scene *s, int i);

/* Gives voice i its class; checks every param and strike target the scene
 * names for it (WDRT_SYNTAX with the position in err).  On success err
 * holds the warnings, if any ("FILE:LINE:COL: warning: ...": a param's
 * value past its range, which the voice holds at the bound), else "". */
wdrt_result wdrt_scene_bind(wdrt_scene *s, int i, const wdv_class *cls,
                            char *err, size_t errlen);

/* Writes the scene's sound network as a Graphviz digraph: its sources
 * (voices, trees with their expressions and mix nodes, complexes), the
 * events that play them, the rooms and walls they are heard through and
 * the listener.  Not real-time safe. */
void wdrt_scene_dot(const wdrt_scene *s, FILE *f);

/* Overrides of the scene's own settings for wdrt_scene_render; zero
 * fields keep the scene's. */
typedef struct wdrt_render_opts {
    double seconds;   /* length */
    double rate;      /* Hz */
    int nosleep;      /* 1: voices never sleep */
    double budget_ns; /* ns per sample */
    /* called every so often with the fraction done (0..1, or a negative
     * number of seconds when the end is not known) */
    void (*progress)(double done, void *user);
    void *user;
    /* when set, each run of frames is handed here as it is rendered
     * (interleaved, nch channels) and not kept, so a long render takes no
     * more memory than a short one: *frames is then NULL.  A non-zero
     * return stops the render (WDRT_IO). */
    int (*sink)(const double *frames, long nframes, int nch, void *user);
    void *sink_user;
} wdrt_render_opts;

/* Renders a bound scene into *frames (interleaved, *nch channels, malloc'ed;
 * the caller frees), or through o->sink, at *rate Hz; *nframes frames in
 * all.  Statistics of the engine in *stats when not NULL. */
wdrt_result wdrt_scene_render(const wdrt_scene *s, const wdrt_render_opts *o,
                              double **frames, long *nframes, int *nch,
                              double *rate, wdrt_engine_stats *stats);

/* ---- voices from files, and audio files ---------------------------- */

/* Nothing below is real-time safe: these functions compile, load,
 * allocate and do file I/O. */

/* A voice class loaded from a shared object. */
typedef struct wdrt_voice_lib {
    void *handle;            /* dlopen handle */
    const wdv_class *cls;    /* NAME_class in the object */
} wdrt_voice_lib;

/* Runs the program argv[0] (looked up in PATH unless the name has a
 * slash) with the NULL-terminated argument list argv, and waits for it to
 * end.  With out_fd < 0 the program writes to our stdout and stderr;
 * otherwise both its stdout and its stderr go to the file descriptor
 * out_fd (STDERR_FILENO: everything to our stderr).  *status (if not NULL)
 * gets its exit status, 128 + N if signal N ended it, or 127 if it could
 * not be started (with a message on its stderr).  Returns WDRT_OK once the
 * program has been waited for, whatever its status; WDRT_INVALID_ARGS, or
 * WDRT_ERROR if fork or waitpid failed.  Flushes all stdio streams first.
 * Forks and blocks until the program ends: not real-time safe. */
wdrt_result wdrt_spawn(char *const argv[], int out_fd, int *status);

/* Compiles the C file `csrc` into the shared object `so` with the compiler
 * `cc` (NULL: $CC, or "cc") and extra flags `cflags` (NULL: "-O2").  The
 * compiler's messages go to stderr.  Allocates; not real-time safe. */
wdrt_result wdrt_voice_compile(const char *csrc, const char *so,
                               const char *cc, const char *cflags);

/* Loads `so` and finds the class `NAME_class`. */
wdrt_result wdrt_voice_open(const char *so, const char *name,
                            wdrt_voice_lib *lib);
void wdrt_voice_close(wdrt_voice_lib *lib);

/* Writes nframes of nch interleaved channels as 32-bit float WAV at rate
 * fs (Hz). */
wdrt_result wdrt_wav_write(const char *path, int nch, double fs,
                           const double *frames, long nframes);

/* The same written as it comes: open, append runs of interleaved frames,
 * close (which completes the header; the file is whole only then), or
 * abort.  The frames go to a file beside path (wdrt_temp_beside) that
 * close puts in path's place, so until then, and after an abort or a
 * failure, a file at path is as it was.  A WAV's sizes are 32-bit: its
 * samples (4 bytes each) may take at most WDRT_WAV_MAX_BYTES, and an
 * append past it fails. */
#define WDRT_WAV_MAX_BYTES (0xFFFFFFFFull - 4096)
/* True if nframes of nch channels fit in a WAV file; the longest one of
 * nch channels at fs holds, in whole seconds. */
int wdrt_wav_fits(double nframes, int nch);
double wdrt_wav_max_seconds(int nch, double fs);
typedef struct wdrt_wav_out wdrt_wav_out;
wdrt_result wdrt_wav_open(const char *path, int nch, double fs, wdrt_wav_out **out);
wdrt_result wdrt_wav_append(wdrt_wav_out *w, const double *frames, long nframes);
wdrt_result wdrt_wav_close(wdrt_wav_out *w);
wdrt_result wdrt_wav_abort(wdrt_wav_out *w);

/* A new empty file beside path (path.HHHHHH, with the permissions of the
 * file it will replace, or those path would be made with), malloc'ed, to
 * write and then rename into place; NULL where path names a device, a
 * FIFO, a symbolic link (whose target is written) or a file this process
 * may not write, or none can be made: then
 * path is written itself.  wdrt_temp_settle renames tmp to path (keep)
 * or removes it (removing path itself, if it was written in place and
 * is a regular file: call it so only once something was written there),
 * frees tmp, and returns 0, or -1 (errno says why) if the file is not in
 * place. */
char *wdrt_temp_beside(const char *path);
int wdrt_temp_settle(char *tmp, const char *path, int keep);

/* Reads a WAV (any libsndfile format) as interleaved doubles; *frames is
 * malloc'ed and freed by the caller. */
wdrt_result wdrt_wav_read(const char *path, int *nch, double *fs,
                          double **frames, long *nframes);

/* Renders nframes of a voice instance into out[k] (one buffer per output)
 * from in[k] (one per input; NULL entries read silence), in blocks of at
 * most `block` frames. */
void wdrt_render(const wdv_class *cls, void *state, const double *const *in,
                 double *const *out, long nframes, int block);

#endif
