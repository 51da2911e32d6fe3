/*
 * tt_evolve.h - genetic exploration of timbre trees, `wdrt evolve`
 * (DESIGN §6.3).  Internal to libwdrt: not part of the public API.
 *
 * A population of mutants of a seed tree is rendered and scored, either
 * by ratings a listener writes or by a spectral distance to a target
 * WAV; parents are drawn by their scores, the best is kept (elitism),
 * and the rest of the next generation are their mutants:
 *
 *   perturb   a constant (a number, or an env value) times a log-normal
 *             factor, or plus a normal step when it lies near 0
 *   replace   a subtree by a small random one
 *   wrap      a subtree in a function (a gain, a waveform, a filter, a
 *             resonator, a decay, a ring modulator, an echo, ...)
 *   change    a function into another of its kind (+ - * / pow min max;
 *             exp log sqrt abs sin cos floor tanh damp; sine saw square
 *             triangle and the shape of osc; lowpass highpass bandpass)
 *   hoist     a node into one of its arguments
 *   cross     a subtree of one parent into a copy of another
 *
 * Every mutant keeps the seed's params and is checked (tt_check) against
 * them; mutants that do not check, are deeper or larger than the limits,
 * or render to non-finite or silent sound are discarded and made again.
 * Nothing made here is a sample or a voice node (a parent's are kept).
 * Randomness is a PRNG of its own (xoshiro256**, seeded by splitmix64),
 * so a seed makes a run repeatable bit for bit.
 *
 * The spectral distance (tt_evo_spectra): short-time power spectra
 * (Blackman-Harris windows of about 50 ms or more, a power of two, half
 * overlapping; their side lobes lie under the floor), pooled into bands
 * 1/24 octave wide from 20 Hz to min(0.475 fs, 20 kHz), smoothed over
 * log frequency by Gaussians of 0, 1/12, 1/3 and 1 octave (one spectrum
 * per scale), each in dB above a floor 60 dB under the target's loudest
 * band; the distance is the mean absolute dB difference over scales,
 * frames and bands.  The fine scales see timbre and tuning to a fraction
 * of a band; the coarse ones still overlap when partials are far apart,
 * so a mistuned tree has a slope towards the target's pitch.  (Naive
 * saw, square and triangle waves alias, and their aliases move
 * erratically with pitch: the slope is rougher for them than for sines
 * and band-limited oscillators.)
 *
 * Memory: everything is malloc'ed and freed by its free function;
 * nothing is global.  None of it is real-time safe.
 */
#ifndef WDRT_TT_EVOLVE_H
#define WDRT_TT_EVOLVE_H

#include <stdint.h>

#include "tt.h"

/* `wdrt evolve ...`: argv[0] is "evolve".  Prints --help; returns the
 * exit status: 0 ok, 1 input error, 2 usage error, 3 internal error. */
TT_HIDDEN int tt_evolve_main(int argc, char **argv);

/* ---- random numbers ---- */

typedef struct tt_evo_rng {
    uint64_t s[4]; /* xoshiro256** state */
} tt_evo_rng;

TT_HIDDEN void tt_evo_rng_seed(tt_evo_rng *r, uint64_t seed);
TT_HIDDEN uint64_t tt_evo_rng_next(tt_evo_rng *r);
TT_HIDDEN double tt_evo_rng_uniform(tt_evo_rng *r); /* [0, 1) */
TT_HIDDEN double tt_evo_rng_normal(tt_evo_rng *r);  /* mean 0, deviation 1 */

/* ---- mutations ---- */

typedef enum tt_mutation {
    TT_MUT_ANY = -1, /* one drawn at random (weights in tt_evolve.c) */
    TT_MUT_PERTURB,
    TT_MUT_REPLACE,
    TT_MUT_WRAP,
    TT_MUT_CHANGE,
    TT_MUT_HOIST,
    TT_MUT_CROSS,
    TT_NMUT
} tt_mutation;

typedef struct tt_evo_limits {
    int max_depth; /* tt_node_depth of a mutant's root */
    int max_nodes; /* tt_node_count of a mutant's root */
} tt_evo_limits;

/* The default limits for mutants of seed: depth at most the seed's + 4,
 * nodes at most twice the seed's + 40 (never beyond TT_MAX_DEPTH and
 * TT_MAX_NODES). */
TT_HIDDEN tt_evo_limits tt_evo_default_limits(const tt_tree *seed);

/* A mutant of a (checked, with the seed's params) by mutation `kind`
 * (cross: a subtree of b into a copy of a; b NULL: of a itself): a new
 * tree, checked (tt_check passed) and within lim.  Tries a few times;
 * NULL if none came out (a tree without constants cannot be perturbed)
 * or memory ran out. */
TT_HIDDEN tt_tree *tt_evo_mutate(const tt_tree *a, const tt_tree *b, tt_mutation kind, const tt_evo_limits *lim,
                                 tt_evo_rng *r);

/* ---- spectral distance ---- */

typedef struct tt_evo_spectra tt_evo_spectra;

/* Analyses the target x[n] at rate fs (Hz).  NULL: out of memory. */
TT_HIDDEN tt_evo_spectra *tt_evo_spectra_new(const double *x, long n, double fs);
TT_HIDDEN void tt_evo_spectra_free(tt_evo_spectra *s);
/* The distance (mean dB difference, >= 0) of y[n] to the target; y is
 * cut or padded with silence to the target's length.  HUGE_VAL if memory
 * runs out. */
TT_HIDDEN double tt_evo_distance(tt_evo_spectra *s, const double *y, long n);

/* In-place complex FFT of re[n], im[n], n a power of two (forward,
 * sum x[k] e^{-2 pi i j k / n}).  Returns 0, or -1 if n is not a power of
 * two or memory runs out. */
TT_HIDDEN int tt_evo_fft(double *re, double *im, int n);

#endif
