/*
 * surf.h - bodies that sound when they touch: modal resonators, surfaces,
 * and the contacts and impacts between them, after Menzies' acoustic scene
 * manager ("Scene management for modelled audio objects in interactive
 * worlds") and van den Doel's contact models.  Internal to libwdrt: not
 * part of the public API.
 *
 * The objects.  A world holds, in one block of caller memory laid out at
 * init, resonators, surfaces, bodies, and two pools: contacts and impacts.
 * A body joins a resonator (what rings) and a surface (what touching it is
 * like) and has a mass.  Several bodies may share one resonator (marbles in
 * a jar: one state rings for all of them) and one surface.  A physics
 * engine drives the world as Menzies' controller does: it starts a contact
 * when two bodies begin to touch, updates it every step with the speeds and
 * the normal force, and stops it when they part; it reports each impact
 * once, which then plays out and ends itself.
 *
 * Modal resonators.  Mode k has a frequency F_k (Hz), a decay time T60_k
 * (s: its amplitude falls 60 dB in that time) and a gain g_kp per pickup p
 * (an output of the resonator; the product of the excitation point's and
 * the pickup's mode shapes).  Each mode is a complex one-pole
 *
 *     y_k[n] = c_k y_k[n-1] + x[n],   c_k = r_k e^{i w_k},
 *     w_k = 2 pi F_k / fs,   r_k = exp(-(s_k + D) / fs),   s_k = ln(1000) / T60_k,
 *
 * driven by x[n] = f[n] / fs, the impulse (N s) the force f (N) delivers
 * during sample n, and pickup p hears sum_k g_kp Im y_k[n].  An impulse J
 * at t = 0 thus rings as g_kp J e^{-s_k t} sin(2 pi F_k t): a gain is
 * output units per N s, and frequencies and decays are exact (impulse
 * invariance), independent of the rate.  D (1/s) is the contact damping
 * below, added to every mode's decay rate.  Modes at or above fs/2 are left
 * out.  The modes are kept in order of loudness, g^2 T60 (g^2 summed over
 * the pickups; a mode's energy is g^2 J^2 T60 / (4 ln 1000)), so that a
 * limit on active modes drops the quietest first.  Modes come from a list
 * or from a `.modes` file (surf_modes_parse, below).
 *
 * Surfaces and the routing of Menzies' Figure 4.  A surface has a hardness
 * gamma (a stiffness, N/m; larger is harder, INFINITY is rigid), a contact
 * damping (1/s, added to the resonators of the bodies it touches), a relief
 * (below), the settings of its generators, and two sets of gains, one for
 * contacts and one for impacts.  In every contact and impact each of the two
 * surfaces runs its own generator; the excitation e (N) of surface i's
 * generator is scaled by its `master` gain, clipped to +-`limit` (the
 * post-master limit, N), and then goes
 *   - whole to the resonator of body i (its own),
 *   - times `other` to the resonator of the other body,
 *   - times `direct` (output units per N) to the direct channel of body
 *     i's resonator: heard as it is, unresonated.
 * By default a body hears only its own surface's generators (other 0,
 * direct 0).  The impact pulse is in both surfaces' excitations, so
 * raising `other` makes each resonator hear it twice.
 *
 * Reliefs.  A generator reads its surface's relief like a gramophone needle:
 * a position advances by the speed of the contact point over that surface
 * (m/s) and the relief's value there (dimensionless, zero mean) is sampled,
 * linearly interpolated between the relief's points.  Kinds: none (smooth,
 * silent); noise (a random value every `scale` m: the grain); grid (a
 * raised-cosine bump `width` m wide every `scale` m, its mean removed); an
 * audio segment (one sample every `scale` m, looped, its mean removed;
 * copied into the world).  Reading is point sampling: a relief read faster
 * than one point per sample aliases.  Each generator starts at a point of
 * its relief picked by a hash of the world's seed, the surface, the other
 * body and the frame it starts at (a grid: at the start of a bump), so the
 * same event always sounds the same and different events differ.
 *
 * Contacts (van den Doel; Menzies' segment contact generator).  Surface i's
 * generator reads its relief at v_i, low-passes it and scales it by the
 * normal force F:
 *
 *     e_i = F * LP_fc(relief_i(x_i)),   fc = f_roll + (f_slip - f_roll) |slip| / slip_ref,
 *
 * fc clamped to [1 Hz, 0.45 fs].  The low-pass is a two-pole Butterworth
 * (a trapezoidal state-variable filter, prewarped: -3 dB at exactly fc,
 * well-behaved when fc moves).  So the cutoff falls as the slip slows and
 * reaches f_roll when the surfaces roll without slipping.  A generator
 * whose force is below the world's quiet_force or whose read speed is
 * below quiet_speed is quiet: its force ramps to 0 and it then costs
 * nothing until it sounds again.  Updates take effect at the next block,
 * the force ramping linearly across it.  A contact lives until stopped.
 *
 * Impacts (Menzies' segment impact generator).  Two bodies of masses m_a,
 * m_b (kg; INFINITY for immovable) meet with impulse J (N s).  The contact
 * is a linear spring of the combined stiffness
 *
 *     k = (gamma_a^-1 + gamma_b^-1)^-1,
 *
 * on which the effective mass m = (m_a^-1 + m_b^-1)^-1 stays for half a
 * period: a half-sine force pulse
 *
 *     f(t) = (pi J / (2 tau)) sin(pi t / tau),   0 <= t <= tau,   tau = pi sqrt(m / k),
 *
 * whose integral is J (sample n carries the mean of f over the sample, so
 * the samples sum to exactly J fs, however short tau is).  Harder pairs
 * make shorter pulses and brighter sounds; the impulse sets the size.
 * Each surface adds a skid (Menzies' skid, a short contact of its own
 * generator): the bodies slide at the tangential speed vt, decelerated
 * uniformly to rest, while their normal force falls from
 * skid_ratio * J (N) to zero, for
 *
 *     T = min(|vt| / skid_decel, 2 skid_thickness / |vn|), clamped to [skid_min, skid_max]
 *
 * (s): until friction stops the slide (a faster spin skids longer), or
 * until the bodies leave a layer skid_thickness deep at the normal speed
 * vn (grazing blows skid longer than head-on ones).  A setting of 0 leaves
 * its term out (both out: T = skid_max).  No skid when vt = 0.  Over the
 * skid the slip, the read speed and the force fall linearly to zero, so
 * the cutoff falls with them; the skid's excitation is skid_gain times
 * that contact's.  An impact ends itself after its pulse and skids.
 *
 * Contact damping (Menzies 4.5).  While a contact lives (started, not yet
 * stopped), each body's resonator is damped by the other body's surface's
 * damping: the resonator's D is the sum over its live contacts, capped at
 * its max_damping, and falls back as contacts stop.  D is applied at each
 * block's start.  Impacts do not damp.
 *
 * Economy.  A resonator that had no input during a block and whose mode
 * energy sqrt(sum_k |y_k|^2 sum_p g_kp^2) (output units) is below its quiet
 * level fades out over the next block (cfg.block frames, across calls)
 * and sleeps: its state is cleared and it costs nothing until an input
 * wakes it.  Up to its fade its output is exactly what it would be without
 * the sleep logic.  Quiet generators cost nothing.  surf_get_stats reports
 * the modes and generators computed in the last block and a cost in mode
 * units (a mode costs 1 per sample, a generator SURF_GEN_COST), which a
 * budget multiplies by its measured time per mode-sample.
 *
 * Time.  Impacts name a frame offset from the start of the next process
 * call (any offset: later ones wait); contact starts, updates and stops
 * take effect at the start of the next call.  Process calls may have any
 * length up to cfg.block.
 *
 * Units: frequencies Hz, times s, T60 s, damping (decay rates) 1/s,
 * stiffness N/m, masses kg, speeds m/s, forces N, impulses N s, lengths m,
 * gains linear (resonator gains in output units per N s, direct gains in
 * output units per N).  No global state: everything lives in a world, and
 * a world may be used by one thread at a time.  Functions say whether they
 * may run on the audio thread.
 */
#ifndef WDRT_SURF_H
#define WDRT_SURF_H

#include <stddef.h>
#include <stdint.h>

#include "wdrt.h"

#if defined(__GNUC__)
#define SURF_HIDDEN __attribute__((visibility("hidden")))
#else
#define SURF_HIDDEN
#endif

#define SURF_MAX_PICKUPS 8      /* outputs of one resonator, at most */
#define SURF_MAX_BLOCK 8192     /* frames of one process call, at most */
#define SURF_MAX_POOL 65535     /* contacts (and impacts) a world may hold */
#define SURF_FS_MIN 8000.0      /* Hz */
#define SURF_FS_MAX 768000.0    /* Hz */
#define SURF_DIRECT (-1)        /* surf_output's channel of the direct sound */
#define SURF_GEN_COST 7.0       /* a generator's cost per sample, in modes (measured by bench/surfbench: ~12 vs ~1.7 ns) */
#define SURF_POOL_FULL WDRT_OUT_OF_MEMORY /* a pool has no free slot */

typedef struct surf_world surf_world; /* opaque */

/* ---- the world ---- */

typedef struct surf_config {
    double fs;           /* Hz, in [SURF_FS_MIN, SURF_FS_MAX] */
    int block;           /* frames per process call at most; also the fade length */
    int max_bodies;      /* >= 0 each */
    int max_resonators;
    int max_surfaces;
    int max_modes;       /* per resonator */
    int max_pickups;     /* per resonator, 1..SURF_MAX_PICKUPS */
    int max_contacts;    /* pool sizes, 0..SURF_MAX_POOL */
    int max_impacts;
    long relief_frames;  /* samples of segment reliefs, all surfaces together */
    double quiet_force;  /* N: a generator with less force is quiet */
    double quiet_speed;  /* m/s: a generator reading slower is quiet */
    uint32_t seed;       /* of the reliefs' start points and noise */
} surf_config;

/* Defaults at rate fs: block 256, 64 bodies and resonators, 16 surfaces,
 * 32 modes of 2 pickups, 32 contacts, 64 impacts, no segment frames,
 * quiet_force 1e-6 N, quiet_speed 1e-5 m/s, seed 1.  Real-time safe. */
SURF_HIDDEN surf_config surf_config_init(double fs);

/* Bytes a world for cfg needs, into *size.  WDRT_INVALID_ARGS for a bad
 * cfg (a field out of its range, a NaN), or WDRT_OUT_OF_MEMORY if the size
 * would overflow.  Computes only: real-time safe. */
SURF_HIDDEN wdrt_result surf_get_size(const surf_config *cfg, size_t *size);

/* Makes an empty, silent world for cfg in mem (surf_get_size bytes,
 * 16-byte aligned) and returns it in *w.  WDRT_INVALID_ARGS for a bad cfg,
 * NULL or misaligned mem.  No allocation, but it clears every byte: not for
 * the audio thread. */
SURF_HIDDEN wdrt_result surf_init_prealloc(const surf_config *cfg, void *mem, surf_world **w);

/* The same in memory from alloc (NULL: malloc).  Allocates: not real-time
 * safe.  surf_uninit frees it (pass the same alloc). */
SURF_HIDDEN wdrt_result surf_init(const surf_config *cfg, const wdrt_alloc_callbacks *alloc,
                                  surf_world **w);
SURF_HIDDEN void surf_uninit(surf_world *w, const wdrt_alloc_callbacks *alloc);

/* Silences the world: every contact and impact ends (pools empty, high-water
 * marks 0), every resonator asleep and undamped, time back to frame 0; the
 * resonators, surfaces and bodies stay.  No allocation; O(size of the
 * world's state): real-time safe only where that fits. */
SURF_HIDDEN void surf_reset(surf_world *w);

/* ---- set-up: resonators, surfaces, bodies ---- */

typedef struct surf_mode {
    double f;                       /* Hz, > 0 */
    double t60;                     /* s, > 0 */
    double gain[SURF_MAX_PICKUPS];  /* per pickup, output units per N s */
} surf_mode;

typedef struct surf_resonator_desc {
    const surf_mode *modes; /* nmodes of them (any order); NULL if none */
    int nmodes;             /* 0..cfg.max_modes, counting those left out at fs/2 */
    int npickups;           /* 1..cfg.max_pickups: gain[0..npickups) are used */
    double quiet;           /* output units: sleeps below it; 0 never sleeps */
    double max_damping;     /* 1/s: the most contact damping it takes */
} surf_resonator_desc;

/* Defaults: no modes, 1 pickup, quiet 1e-6, max_damping 100 /s.
 * Real-time safe. */
SURF_HIDDEN surf_resonator_desc surf_resonator_desc_init(void);

/* Adds a modal resonator; returns its index (0, 1, ...) or
 * WDRT_INVALID_ARGS (a bad field, a mode with f or t60 not positive and
 * finite or a gain not finite, more modes than cfg.max_modes), or
 * SURF_POOL_FULL when cfg.max_resonators are in use.  Modes at or above
 * fs/2 are left out (surf_resonator_modes tells how many stay).  No
 * allocation; O(modes^2): call at set-up, off the audio thread. */
SURF_HIDDEN int surf_add_resonator(surf_world *w, const surf_resonator_desc *d);

/* Adds a resonator that rings outside the world (a compiled voice with a
 * force input, say): it has no modes; its channel 0 (surf_output) is the
 * force, N, that its bodies' surfaces excite it with in each frame of the
 * last block, or NULL when none did.  It never sleeps or is awake in the
 * world: the voice it feeds does.  Returns its index, or as
 * surf_add_resonator.  Not for the audio thread. */
SURF_HIDDEN int surf_add_external(surf_world *w);

typedef enum surf_relief_kind {
    SURF_RELIEF_NONE,    /* smooth: reads 0 */
    SURF_RELIEF_NOISE,   /* a random value in [-amp, amp] every scale m */
    SURF_RELIEF_GRID,    /* a bump every scale m, width m wide */
    SURF_RELIEF_SEGMENT, /* samples[i] at i * scale m, looped */
} surf_relief_kind;

typedef struct surf_relief {
    surf_relief_kind kind;
    double scale;           /* m: grain, grid spacing, or metres per sample; > 0 */
    double width;           /* m: the grid's bumps, in (0, scale] */
    double amp;             /* scales the values (dimensionless) */
    const double *samples;  /* SEGMENT: copied at surf_add_surface */
    long nsamples;          /* SEGMENT: >= 2 */
} surf_relief;

typedef struct surf_gains {
    double master; /* scales the generator's excitation */
    double other;  /* to the other body's resonator */
    double direct; /* to the own resonator's direct channel, output units per N */
    double limit;  /* N: the excitation after master is clipped to +-limit (> 0) */
} surf_gains;

typedef struct surf_surface_desc {
    double hardness;         /* N/m, > 0; INFINITY: rigid */
    double damping;          /* 1/s, >= 0: added to the resonators it touches */
    surf_gains contact;      /* the routing of its contact generators */
    surf_gains impact;       /* and of its impact generators (pulse and skid) */
    surf_relief relief;
    double cutoff_roll;      /* Hz: the low-pass at zero slip (rolling) */
    double cutoff_slip;      /* Hz: at slip_ref */
    double slip_ref;         /* m/s, > 0 */
    double skid_gain;        /* the skid's excitation, relative to a contact's */
    double skid_ratio;       /* 1/s: the skid's starting force per unit impulse */
    double skid_decel;       /* m/s^2: deceleration of the slide; 0: no such term */
    double skid_thickness;   /* m: depth of the collision layer; 0: no such term */
    double skid_min;         /* s: shortest skid */
    double skid_max;         /* s: longest skid (>= skid_min) */
} surf_surface_desc;

/* Defaults: hardness 1e7 N/m, damping 0, gains master 1, other 0, direct
 * 0, limit INFINITY; noise relief of 0.1 mm grain and amp 1; cutoffs 200 Hz
 * rolling and 4 kHz at 1 m/s; skid gain 1, ratio 100 /s, decel 20 m/s^2,
 * thickness 1 mm, from 0 to 0.2 s.  Real-time safe. */
SURF_HIDDEN surf_surface_desc surf_surface_desc_init(void);

/* Adds a surface (a segment relief's samples are copied, mean removed);
 * returns its index or WDRT_INVALID_ARGS (a field out of range or not
 * finite where it must be), or SURF_POOL_FULL (cfg.max_surfaces in use, or
 * not enough relief_frames left).  No allocation: call at set-up, off the
 * audio thread. */
SURF_HIDDEN int surf_add_surface(surf_world *w, const surf_surface_desc *d);

typedef struct surf_body_desc {
    int resonator; /* index from surf_add_resonator */
    int surface;   /* index from surf_add_surface */
    double mass;   /* kg, > 0; INFINITY: immovable */
} surf_body_desc;

/* Adds a body, enabled; returns its index or WDRT_INVALID_ARGS, or
 * SURF_POOL_FULL (cfg.max_bodies in use).  No allocation: call at set-up,
 * off the audio thread. */
SURF_HIDDEN int surf_add_body(surf_world *w, const surf_body_desc *d);

/* ---- real-time control ---- */

/* Switches a body's sound on or off (Menzies' bodyEnable/Disable): a
 * disabled body's generators are silent, nothing reaches its resonator
 * through it, and its contacts damp nothing.  Takes effect at the next
 * block.  WDRT_INVALID_ARGS for a bad index.  Real-time safe. */
SURF_HIDDEN wdrt_result surf_body_enable(surf_world *w, int body, int on);

/* How many of the resonator's modes run, the loudest first (level of
 * detail); n is clamped to [0, its modes].  Modes turned off are cleared
 * at once.  WDRT_INVALID_ARGS for a bad index.  Real-time safe. */
SURF_HIDDEN wdrt_result surf_resonator_set_active_modes(surf_world *w, int res, int n);
/* Its quiet level (output units, >= 0; 0: never sleeps).  Real-time safe. */
SURF_HIDDEN wdrt_result surf_resonator_set_quiet(surf_world *w, int res, double quiet);
/* Its cap on accumulated contact damping (1/s, >= 0).  Real-time safe. */
SURF_HIDDEN wdrt_result surf_resonator_set_max_damping(surf_world *w, int res, double d);
/* Forces it quiet (Menzies' resMakeQuiet): it fades out over the next
 * block and sleeps, unless an input arrives in that block.  Real-time
 * safe. */
SURF_HIDDEN wdrt_result surf_resonator_make_quiet(surf_world *w, int res);

/* ---- contacts ---- */

/* A contact's identity: valid from surf_contact_start until
 * surf_contact_stop; 0 is none.  A stale id is refused, never confused
 * with the contact that took its slot later. */
typedef uint32_t surf_contact;

/* What a physics step knows about a contact (Menzies' contactDynamicData).
 * Only magnitudes of speeds count. */
typedef struct surf_contact_data {
    double v_a;   /* m/s: speed of the contact point over body a's surface */
    double v_b;   /* m/s: over body b's surface */
    double slip;  /* m/s: speed of body a relative to body b at the contact */
    double force; /* N, >= 0: the normal force */
} surf_contact_data;

/* The data of body a rolling at `roll` m/s (the contact moves over a's
 * surface at that speed) and slipping at `slip` m/s over body b, whose
 * surface the contact then crosses at roll + |slip|.  A point sliding over
 * a surface is roll = 0; a wheel rolling freely, slip = 0.  Real-time safe. */
static inline surf_contact_data surf_contact_rolling(double roll, double slip, double force) {
    surf_contact_data d;
    d.v_a = roll < 0 ? -roll : roll;
    d.slip = slip < 0 ? -slip : slip;
    d.v_b = d.v_a + d.slip;
    d.force = force;
    return d;
}

/* Starts a contact between bodies a and b (distinct) with data d; *id
 * gets its identity (unchanged on failure).  WDRT_INVALID_ARGS for bad
 * bodies or data (not finite, a negative force), SURF_POOL_FULL when the
 * pool has no free slot.  Real-time safe. */
SURF_HIDDEN wdrt_result surf_contact_start(surf_world *w, int a, int b, const surf_contact_data *d,
                                           surf_contact *id);
/* New data for a live contact, effective at the next block.
 * WDRT_INVALID_ARGS for a stale id or bad data.  Real-time safe. */
SURF_HIDDEN wdrt_result surf_contact_update(surf_world *w, surf_contact id, const surf_contact_data *d);
/* Stops a contact: its damping lifts at the next block, its sound fades
 * out over that block, and its slot returns to the pool after it (at once
 * if it is silent).  The id is stale from now on.  WDRT_INVALID_ARGS for a
 * stale id.  Real-time safe. */
SURF_HIDDEN wdrt_result surf_contact_stop(surf_world *w, surf_contact id);

/* ---- impacts ---- */

/* What a physics step knows about an impact (Menzies' impactDynamicData). */
typedef struct surf_impact_data {
    double impulse; /* N s, >= 0: J */
    double vn;      /* m/s: relative normal speed at the impact */
    double vt;      /* m/s: relative tangential speed at the impact */
} surf_impact_data;

/* An impact of bodies a and b (distinct; not both immovable) at `offset`
 * frames (>= 0) after the start of the next process call.  WDRT_INVALID_ARGS
 * for bad bodies or data, SURF_POOL_FULL when the pool has no free slot.
 * An impulse of 0 makes no sound and takes no slot.  Real-time safe. */
SURF_HIDDEN wdrt_result surf_impact(surf_world *w, long offset, int a, int b, const surf_impact_data *d);

/* The pulse length tau (s) an impact of these two bodies has: pi sqrt(m/k)
 * above; 0 for rigid pairs, NAN for bad bodies.  Real-time safe. */
SURF_HIDDEN double surf_pulse_width(const surf_world *w, int a, int b);
/* The skid time T (s) of surface `surface` in an impact with data d (0: no
 * skid), as above; NAN for a bad surface.  Real-time safe. */
SURF_HIDDEN double surf_skid_time(const surf_world *w, int surface, const surf_impact_data *d);
/* The cutoff (Hz) of surface `surface`'s generators at slip speed `slip`.
 * Real-time safe. */
SURF_HIDDEN double surf_contact_cutoff(const surf_world *w, int surface, double slip);

/* ---- processing ---- */

/* Runs n = min(nframes, cfg.block) frames (nframes >= 0) in Menzies'
 * phases: the contact damping of the block, the generators of contacts and
 * impacts (excitations into the resonators' inputs), then the resonators.  If mix is not
 * NULL, mix[0..n) gets the sum of every resonator's every channel (pickups
 * and direct).  Returns n.  Real-time safe: no allocation, locks or I/O;
 * O(n (active modes + sounding generators) + contacts + impacts +
 * resonators). */
SURF_HIDDEN int surf_process(surf_world *w, double *mix, int nframes);

/* Channel `ch` of resonator `res` over the frames of the last process call:
 * pickup 0..npickups-1, or SURF_DIRECT.  NULL when that channel was silent
 * (a sleeping resonator, no direct sound) or for a bad index.  Valid until
 * the next process call.  Real-time safe. */
SURF_HIDDEN const double *surf_output(const surf_world *w, int res, int ch);

typedef struct surf_stats {
    int contacts_in_use;  /* slots taken, including contacts fading after a stop */
    int contacts_hwm;     /* the most ever in use at once (since init or reset) */
    int impacts_in_use;
    int impacts_hwm;
    int generators;       /* generators computed in the last block */
    int resonators_awake; /* resonators computed in the last block */
    int modes;            /* modes computed in the last block */
    double cost;          /* modes + SURF_GEN_COST generators: per sample, in modes */
} surf_stats;

/* The world's counts.  Real-time safe. */
SURF_HIDDEN void surf_get_stats(const surf_world *w, surf_stats *s);

/* A resonator's state: whether it is awake (fading counts as awake), its
 * mode energy (as above, output units), its applied contact damping D
 * (1/s), and how many modes it keeps (after fs/2).  Negative or NAN for a
 * bad index.  Real-time safe. */
SURF_HIDDEN int surf_resonator_awake(const surf_world *w, int res);
SURF_HIDDEN double surf_resonator_energy(const surf_world *w, int res);
SURF_HIDDEN double surf_resonator_damping(const surf_world *w, int res);
SURF_HIDDEN int surf_resonator_modes(const surf_world *w, int res);

/* The frame the next process call starts at.  Real-time safe. */
SURF_HIDDEN int64_t surf_frame(const surf_world *w);

/* ---- .modes files (surf_modes.c) ---- */

/* Reads modes from `text` (len bytes, need not end in NUL) of the file
 * `path` (for messages).  The format: one mode per line,
 *
 *     F T60 GAIN [GAIN...]     ; a comment
 *
 * F in Hz (> 0), T60 in s (> 0), one gain per pickup (at most
 * SURF_MAX_PICKUPS, the same number on every line); numbers as C writes
 * them; `;` starts a comment to the end of the line; blank lines are
 * skipped.  Writes at most max modes to `modes` (NULL: only counts and
 * checks) and the gains per line to *npickups (0 for a file without
 * modes).  Returns the number of modes, or -1 with
 * "PATH:LINE:COL: error: MESSAGE", the line and a caret in err (more
 * than max modes is an error).  No allocation. */
SURF_HIDDEN int surf_modes_parse(const char *path, const char *text, size_t len, surf_mode *modes,
                                 int max, int *npickups, char *err, size_t errlen);
/* The same from the file itself ("PATH: error: cannot read: ..." when it
 * cannot be read).  Allocates and reads a file: not real-time safe. */
SURF_HIDDEN int surf_modes_read(const char *path, surf_mode *modes, int max, int *npickups, char *err,
                                size_t errlen);

#endif
