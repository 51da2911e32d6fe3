/*
 * testlib.h - helpers shared by the cmocka tests.
 *
 * Building voices from netlists (through bin/wdc and the C compiler),
 * allocating their state, seeded random numbers, error measures, and a
 * runner that drives a voice and the reference simulator (refsim.h) side
 * by side.  Tests run from the repository root; $WDC overrides the path
 * of the compiler (default bin/wdc), and $WDC_KEEP=1 keeps the temporary
 * build directories.
 */
#ifndef TESTLIB_H
#define TESTLIB_H

#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>

#include "gen.h"
#include "refsim.h"
#include "wdrt_host.h"
#include "wdvoice.h"

/* ---- voices ---- */

typedef struct tl_voice {
    char dir[64];            /* temporary build directory */
    char name[128];          /* voice name (the emitted NAME.c) */
    wdrt_voice_lib lib;
    const wdv_class *cls;
} tl_voice;

/* Emits the voice of `netlist` with bin/wdc into a fresh directory under
 * /tmp (`--precision float` when single), compiles it into a shared object
 * and loads it.  Returns 0, or -1 after printing what failed. */
int tl_voice_build(const char *netlist, int single, tl_voice *v);
/* Unloads the voice and removes its directory.  Directories of voices
 * never freed (a test that failed half-way) are removed at exit. */
void tl_voice_free(tl_voice *v);

/* A zeroed, 64-byte aligned state for cls, initialised at fs. */
void *tl_state_new(const wdv_class *cls, double fs);
void tl_state_free(void *state);

/* ---- random numbers (xorshift64*) ---- */

typedef struct tl_rng {
    uint64_t s;
} tl_rng;

void tl_rng_seed(tl_rng *r, uint64_t seed);
uint64_t tl_rng_next(tl_rng *r);
double tl_rng_uniform(tl_rng *r); /* [0, 1) */
double tl_rng_signed(tl_rng *r);  /* [-1, 1) */

/* ---- measures ---- */

/* sqrt(sum (a-b)^2 / sum b^2); if b is all zero, the RMS of a. */
double rel_rms_error(const double *a, const double *b, long n);
/* 20 log10(x), -400 for 0. */
double tl_db(double x);
/* First index where |a - b| > tol * max|b| (tol * 1 if b is all zero),
 * or -1. */
long tl_first_divergence(const double *a, const double *b, long n, double tol);

/* Fails the current test (cmocka) if |a[k] - b[k]| > tol for some k,
 * naming the first such k and both values. */
#define assert_buf_near(a, b, n, tol) \
    tl_assert_buf_near_((a), (b), (n), (tol), __FILE__, __LINE__)
void tl_assert_buf_near_(const double *a, const double *b, long n, double tol,
                         const char *file, int line);

/* ---- input signals ---- */

typedef enum {
    TL_SILENCE,
    TL_NOISE,   /* uniform white noise in [-amp, amp) */
    TL_STEP,    /* 0 before `at`, amp from `at` on */
    TL_BURST,   /* noise for n < at, then silence */
    TL_IMPULSE, /* amp at n == at */
} tl_sigkind;

#define TL_MAX_INPUTS 16

/* A generator of one signal per input; each input draws from its own
 * random stream, seeded from `seed` and the input's index. */
typedef struct tl_signal {
    tl_sigkind kind;
    double amp;
    long at;
    uint64_t seed;
    tl_rng rng[TL_MAX_INPUTS];
    long next[TL_MAX_INPUTS]; /* next sample index per input */
} tl_signal;

void tl_signal_init(tl_signal *s, tl_sigkind kind, double amp, long at,
                    uint64_t seed);
/* Sample n of input k; for each input, n must run 0, 1, 2, ... */
double tl_signal_next(tl_signal *s, int input, long n);

/* ---- parameter changes ---- */

typedef struct tl_change {
    long at;     /* sample index at which the new value takes effect */
    int param;
    double value;
} tl_change;

/* Fills `out` (room for nchanges * c->nparams entries) with `nchanges`
 * moments spread over (0, nframes), rounded to multiples of 64, at each
 * of which every param gets a random value in its [min, max] (log-uniform
 * for positive ranges spanning a decade or more).  Returns the count. */
int tl_random_changes(const Circuit *c, tl_rng *r, long nframes, int nchanges,
                      tl_change *out);

/* ---- voice and reference side by side ---- */

typedef struct tl_run_opts {
    double fs;
    long nframes;
    tl_signal *signal;        /* inputs; NULL: silence */
    const tl_change *changes; /* sorted by at */
    int nchanges;
    int block;                /* frames per process call; 0: 64 */
    int track_energy;         /* record energy and work after every sample */
    const double *params0;    /* params before sample 0 (NULL: defaults) */
    int with_floor;           /* 64 or 32: also run a refsim with its state
                                 rounded to double or float
                                 (refsim_round_state); 0: not */
} tl_run_opts;

typedef struct tl_run {
    long nframes;
    int nouts;
    double **voice;    /* [nouts][nframes] outputs of the voice */
    double **ref;      /* [nouts][nframes] outputs of refsim */
    double **floor;    /* [nouts][nframes] with_floor: the rounded refsim */
    double **in;       /* [ninputs][nframes] the inputs used */
    int ninputs;
    int have_ref;      /* the reference ran (c is linear) */
    /* With track_energy: after sample n, [nframes]; and before sample 0. */
    double *venergy, *vwork, *renergy, *rwork;
    double venergy0, renergy0, vwork0, rwork0;
} tl_run;

/* Runs a fresh instance of cls (initialised at o->fs) and a refsim of c
 * over o->nframes samples: blocks of o->block frames, cut also where a
 * change falls, each change applied to both before the sample it names.
 * The voice's outputs are ordered as c->outs.  A circuit refsim cannot
 * simulate (a transmission line) runs the voice alone (have_ref = 0,
 * reference buffers zero).  Returns 0, or -1 (message printed) if the two
 * do not have the same ports or memory runs out. */
int tl_run_side_by_side(const Circuit *c, const wdv_class *cls,
                        const tl_run_opts *o, tl_run *r);
void tl_run_free(tl_run *r);
/* Worst relative RMS error over the outputs of a run; *which gets the
 * output index if not NULL. */
double tl_run_worst(const tl_run *r, int *which);
/* Worst relative RMS error of the rounded refsim (with_floor) against
 * refsim: what the precision alone costs on this run. */
double tl_run_floor(const tl_run *r);
/* Prints the first diverging sample of output k (threshold tol relative
 * to the reference's peak) with both values, through print_message. */
void tl_run_report(const tl_run *r, const Circuit *c, int k, double tol);

/* ---- netlists ---- */

/* Paths of netlists/ *.wdn, sorted; *n gets the count.  Free with
 * tl_netlists_free. */
char **tl_netlists(int *n);
void tl_netlists_free(char **v, int n);

#endif
