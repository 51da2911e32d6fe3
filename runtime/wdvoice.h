/*
 * wdvoice.h - the voice ABI shared by voices emitted by wdc and their hosts.
 *
 * A voice is a compiled wave-digital model of one physical system.  The host
 * owns all memory: it allocates `state_size` bytes (aligned for double), then
 * calls init(state, fs).  A voice never allocates, locks or does I/O.
 *
 * Audio buffers are double precision on both sides of the ABI, whatever the
 * precision the voice computes in (`precision` is 32 or 64 bits); a float
 * voice converts at its edges.  Units are SI, reported per port and param:
 * the electrical domain speaks in V, A, ohm; the mechanical one in m/s, N, m.
 *
 * This header holds types only.
 */
#ifndef WDVOICE_H
#define WDVOICE_H

#include <stddef.h>

#define WDV_ABI_VERSION 8

/* One audio input or output. */
typedef struct wdv_port {
    const char *name; /* as in the netlist (.input NAME / .output NAME) */
    const char *unit; /* SI unit of the signal, e.g. "V", "m/s", "N" */
} wdv_port;

/* One control-rate parameter. */
typedef struct wdv_param {
    const char *name; /* as in .param */
    const char *unit; /* unit= of the .param line, or "" */
    double def;       /* default value */
    double min;       /* set_param clamps to [min, max] */
    double max;
    unsigned flags;   /* WDV_PARAM_* */
} wdv_param;

/* The voice takes a step of this param as it comes: a host sets it at the
 * frame it names instead of ramping it (a change that redesigns part of the
 * voice, such as a waveguide's loop, where a ramp would only cost). */
#define WDV_PARAM_STEP 1u
/* A change of this param redesigns part of the voice (a string's or tube's
 * loop): wdv_class.prepare makes that design off the audio thread.  Such
 * a param is also WDV_PARAM_STEP. */
#define WDV_PARAM_DESIGN 2u

/* One initial-condition target: the velocity (or voltage) of a node, or
 * the displacement (or flux) of a node relative to ground.  A voice lists
 * only the targets that set something: v(node) of a node with a capacitor
 * (mass) to ground; x(node) of one with an inductor (spring) to ground, a
 * contact, or a displacement probe. */
typedef struct wdv_ic_target {
    const char *name; /* "v(node)" or "x(node)" */
    const char *unit;
} wdv_ic_target;

/* The entries of wdv_class.solve_stats. */
enum { WDV_SOLVE_SOLVES, WDV_SOLVE_STEPS, WDV_SOLVE_CAPPED, WDV_SOLVE_N };

typedef struct wdv_class {
    const char *name;   /* voice name: the C prefix of its symbols */
    int abi_version;    /* WDV_ABI_VERSION at emission */
    int precision;      /* 64: computes in double, 32: in float */
    size_t state_size;  /* bytes the host allocates for one instance */
    int n_inputs;
    int n_outputs;
    int n_params;
    int n_ic_targets;
    const wdv_port *inputs;
    const wdv_port *outputs;
    const wdv_param *params;
    const wdv_ic_target *ic_targets;

    /* Sets the sample rate (Hz), params to their defaults, and resets.
     * Real-time safe, but meant for set-up. */
    void (*init)(void *state, double fs);
    /* Clears all signal state and applies the netlist's .ic values.
     * Real-time safe. */
    void (*reset)(void *state);
    /* Sets param `id` (clamped to its range); coefficients are recomputed
     * at the start of the next process call, only those it affects.
     * Returns 0, or -1 for an unknown id.  Real-time safe. */
    int (*set_param)(void *state, int id, double value);
    double (*get_param)(const void *state, int id);
    /* Renders nframes: in[k][n] for input k, out[k][n] for output k.
     * Real-time safe: no allocation, no locks, no I/O, bounded time. */
    void (*process)(void *state, const double *const *in, double *const *out,
                    int nframes);
    /* Energy stored in the reactances now, in J (or its electrical analog). */
    double (*energy)(const void *state);
    /* Work done on the network by its sources since reset, in J.  Counted
     * only by a voice compiled with `wdc --energy`; any other voice's
     * process does no such accounting and this is NULL. */
    double (*work)(const void *state);
    /* A strike: sets the named initial conditions (ids into ic_targets)
     * on top of the present state; reactances the targets do not touch keep
     * their Kirchhoff state.  Returns 0, or -1 if an id is out of range or
     * a value not a number (checked before anything is set) or the
     * conditions cannot all hold.  Real-time safe (bounded solve). */
    int (*set_ic)(void *state, int n, const int *ids, const double *values);

    /* The heavy part of a param change (the design of a waveguide's loop
     * takes milliseconds), for hosts that keep it off the audio thread.
     * prepare computes, on any thread and touching no state, what the
     * params p (n_params values, clamped as set_param clamps them) call
     * for at rate fs, into `design` (design_size bytes).  install hands it
     * to a state on the audio thread, in bounded time; the process call
     * that follows the set_param calls of those values then takes it
     * instead of designing in its first block.  Without them a change
     * works the same, in that block.  The params it concerns carry
     * WDV_PARAM_DESIGN.  design_size 0, prepare and install NULL: the voice
     * has no such work. */
    size_t design_size;
    void (*prepare)(double fs, const double *params, void *design);
    void (*install)(void *state, const void *design);
    /* Renders nframes for n instances of this class at once: states[l],
     * in[l][k][i] and out[l][k][i] are instance l's, as process takes them
     * (the states distinct).  Each instance's samples are computed as
     * process computes them, bit for bit, side by side with the others', so
     * that one instance's wait for its last result is filled with the
     * others' work.  Real-time safe.  NULL (a voice built without
     * `wdc --batch`): the host calls process for each instance. */
    void (*process_batch)(void *const *states, int n, const double *const *const *in,
                          double *const *const *out, int nframes);
    /* How the joint solves (nonlinear elements coupled with no delay
     * between them, WDV_SOLVE_*) have gone since reset: the solves, the
     * Newton steps they took, and those that stopped at the iteration cap
     * (wdc --maxit) before they converged, whose samples come from their
     * last iterate.  NULL: the voice has no joint solve. */
    void (*solve_stats)(const void *state, unsigned long stats[WDV_SOLVE_N]);
    /* How far its strings and tubes are from the pitches they are tuned
     * to: the largest error of the first twelve partials of any of them,
     * in cents, as their loops are designed at the rate and params in
     * effect (those of init, or of the last process call), and of its
     * delay lines (transmission lines) from their delays, each held in
     * whole samples (1200 |log2(D / (TD fs))| cents).  INFINITY where a
     * loop or delay cannot be held at that rate: a loop too short for its
     * filters (its f0 too high for the rate), a delay shorter than half a
     * sample, or, at a rate far above the one the voice was compiled for,
     * either longer than its lines hold.  That voice plays out of tune,
     * and a host should say so or choose another rate.  NULL: the voice
     * has no string, tube or delay line. */
    double (*tuning)(const void *state);
} wdv_class;

#endif
