/*
 * testlib.h - helpers shared by the cmocka tests.
 *
 * Building voices from netlists (through bin/wdc and the C compiler),
 * allocating their state, seeded random numbers, error measures, a
 * runner that drives a voice and the reference simulator (refsim.h) side
 * by side, impulse and frequency responses, reference data files, and
 * one cmocka test per netlist.  The benches (bench/) link it too.
 * Tests run from the repository root; $WDC overrides the path of the
 * compiler (default bin/wdc), and $WDC_KEEP=1 keeps the temporary build
 * directories.
 */
#ifndef TESTLIB_H
#define TESTLIB_H

#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>

#include "gen.h"
#include "refsim.h"
#include "wdrt.h"
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
/* The same, with the further arguments `extra` for bin/wdc (NULL-terminated,
 * at most TL_MAX_WDC_ARGS; NULL: none) after `--precision float`, and the
 * voice compiled with the C flags `cflags` (NULL: TL_VOICE_CFLAGS).  The
 * precision is single's: `extra` may not name one. */
int tl_voice_build_args(const char *netlist, int single, const char *const *extra,
                        const char *cflags, tl_voice *v);
/* Loads netlist text as "t.wdn" through the library (wdc_load_string)
 * with its diagnostics captured: the circuit, or NULL on an error; the
 * first line printed goes to *report (in the arena). */
Circuit *tl_netlist_load(const char *text, const char **report);
/* wdc arguments that solve diodes to 1e-12, as refsim does, rather than
 * to the fast solver's table bound. */
extern const char *const tl_exact_diodes[];
/* Loads the netlist at path (which refsim must simulate) and builds its
 * voice in double (*vd) and in float (*vf), diodes solved to --tol 1e-12
 * like the reference: the circuit, after a cmocka
 * failure naming `name` if any step fails. */
Circuit *tl_load_both(const char *path, const char *name, tl_voice *vd, tl_voice *vf);
/* Unloads the voice and removes its directory.  Directories of voices
 * never freed (a test that failed half-way) are removed at exit. */
void tl_voice_free(tl_voice *v);

/* The steps of tl_voice_build, for callers that make the directory
 * themselves or load the voice in another process than the one that
 * built it. */
#define TL_VOICE_CFLAGS "-O2 -Wall -Wextra -pedantic"
#define TL_MAX_WDC_ARGS 16
/* {"--energy", NULL}: the `extra` of a voice whose work() counts (without
 * it a voice's work() is NaN). */
extern const char *const tl_energy[];
/* Runs `bin/wdc NETLIST -o DIR EXTRA...` (wdrt_spawn) and compiles the one
 * NAME.c it wrote into DIR/NAME.so with `cflags` (NULL: TL_VOICE_CFLAGS).
 * Returns 0, or -1 after printing what failed. */
int tl_voice_make(const char *netlist, const char *dir, const char *const *extra,
                  const char *cflags);
/* Loads the voice tl_voice_make made in v->dir into v (name, lib, cls).
 * Returns 0, or -1 after printing what failed. */
int tl_voice_load(tl_voice *v);
/* The NAME of the one NAME.c in dir; returns 0, or -1 if there is not
 * exactly one. */
int tl_voice_name(const char *dir, char *name, size_t cap);
/* Removes what dir holds (folders within it too), then dir. */
void tl_remove_dir(const char *dir);
/* Makes a fresh folder /tmp/STEM.XXXXXX, its path into dir: 0, or -1. */
int tl_temp_dir(char dir[64], const char *stem);

/* Loads the scene text written to DIR/NAME: the scene, or NULL with its
 * error printed on stderr. */
wdrt_scene *tl_scene_load(const char *dir, const char *name, const char *text);
/* The error loading the scene text written to DIR/NAME gives, into err
 * (empty when it loads). */
void tl_scene_error(const char *dir, const char *name, const char *text, char *err, size_t len);

/* Writes text to DIR/NAME and returns that path (a static buffer, valid
 * until the next call); fails the current test if it cannot. */
const char *tl_write_file(const char *dir, const char *name, const char *text);
/* Runs cmd through the shell: its exit status, or -1 if a signal ended it. */
int tl_system(const char *cmd);

/* A zeroed, 64-byte aligned state for cls, initialised at fs. */
void *tl_state_new(const wdv_class *cls, double fs);
void tl_state_free(void *state);

/* Index of the output or param `name` of cls, or -1. */
int tl_output_id(const wdv_class *cls, const char *name);
int tl_param_id(const wdv_class *cls, const char *name);

/* ---- random numbers (xorshift64*) ---- */

typedef struct tl_rng {
    uint64_t s;
} tl_rng;

void tl_rng_seed(tl_rng *r, uint64_t seed);
uint64_t tl_rng_next(tl_rng *r);
double tl_rng_uniform(tl_rng *r); /* [0, 1) */
double tl_rng_signed(tl_rng *r);  /* [-1, 1) */
/* FNV-1a hash of a string: a seed that follows a name. */
uint64_t tl_hash_str(const char *s);

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

/* ---- buffers ---- */

/* n zeroed buffers of len + 1 doubles (and a NULL after them), or NULL if
 * memory runs out.  Free with tl_bufs_free(b, n). */
double **tl_bufs_new(int n, long len);
void tl_bufs_free(double **b, int n);

/* ---- frequency responses ---- */

/* Frames rendered at a time by tl_impulse_response. */
#define TL_IR_CHUNK 4800L

/* The response of output `oid` of an initialised instance (state) of cls
 * to a unit impulse at sample 0 on every input, rendered (wdrt_render, in
 * blocks of `block` frames) TL_IR_CHUNK frames at a time until a whole
 * chunk after the first stays below `decay_floor`.  Returns the response
 * (malloc'ed; its length in *n), or NULL if a sample is not finite, it has
 * not decayed within max_frames, or memory runs out. */
double *tl_impulse_response(const wdv_class *cls, void *state, int oid, int block,
                            double decay_floor, long max_frames, long *n);
/* sum_n h[n] e^{-j w n}; the phasor is recomputed exactly every 256
 * samples so its rounding drift stays near 256 ulps. */
double _Complex tl_dtft(const double *h, long n, double w);

/* ---- reference data ---- */

/* Reads the CSV file `path` (made by the command `regen`) line by line:
 * a first line starting with `header` (the column names; NULL: none),
 * empty lines and lines starting with '#' are skipped, and every other
 * line (with its newline) goes to row(line, path, lineno, ctx), which
 * returns 0, or -1 after printing what is wrong, which ends the reading.
 * Returns 0, or -1 if the file cannot be opened (a message names `regen`)
 * or row returned -1.  Lines longer than 510 characters are read in
 * pieces. */
int tl_read_csv(const char *path, const char *header, const char *regen,
                int (*row)(const char *line, const char *path, int lineno, void *ctx),
                void *ctx);

/* A cmocka group fixture (state): reference data and the voice compared
 * with it. */
typedef struct tl_fixture {
    tl_voice voice;
    void *data;                  /* zeroed, then filled by load */
    void (*release)(void *data); /* frees what load allocated, or NULL */
} tl_fixture;

/* Group setup: reads the data with load(data) into a zeroed block of
 * data_size bytes (load returns 0, or -1 after printing why and freeing
 * what it allocated), then builds the voice of netlist in double
 * precision; *state gets the tl_fixture.  Returns 0, or -1 (everything
 * released) if load fails or the voice cannot be built. */
int tl_fixture_setup(void **state, const char *netlist, size_t data_size,
                     int (*load)(void *data), void (*release)(void *data));
/* Group teardown of tl_fixture_setup. */
int tl_fixture_teardown(void **state);

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

/* The drives of the tests that compare voices with refsim: n samples at
 * rate fs into x, a 440 Hz sine of amplitude amp (TL_DRIVE_SINE),
 * uniform noise in [-amp, amp) (TL_DRIVE_NOISE), or random levels in
 * [-amp, amp) each held for 1 to `hold` samples (TL_DRIVE_STEPS); the
 * random ones drawn from `seed`. */
typedef enum { TL_DRIVE_SINE, TL_DRIVE_NOISE, TL_DRIVE_STEPS } tl_drive_kind;
void tl_drive(tl_drive_kind kind, double amp, int hold, double fs, long n, uint64_t seed, double *x);

/* ---- transients of SPICE decks against ngspice ---- */

#define TL_TRAN_MAXVEC 4

/* One deck's rows of a reference CSV, "deck,t,v1[,v2...]" (the header
 * line starting "deck"), as the scripts in tests/ref write them: its
 * vectors sampled at t = m / fs, m = 0, 1, ... */
typedef struct tl_tran {
    const char *name; /* set by the caller */
    int nvec;         /* set by the caller */
    long n;           /* rows read */
    double *v[TL_TRAN_MAXVEC];
} tl_tran;

/* Reads the rows of the ndecks decks (name and nvec set) from path, made
 * by the command regen, sampled at rate fs; every row must name one of
 * them, its times must run m / fs from 0 and it must hold nvec values.
 * Returns 0, or -1 after printing what is wrong (what was read freed). */
int tl_tran_read(const char *path, const char *regen, double fs, tl_tran *decks, int ndecks);
void tl_tran_free(tl_tran *decks, int ndecks);
/* Renders the deck at `path` with `bin/wdc PATH --render --csv --rate
 * fs*over --seconds` (a little over `seconds`) into dir and reads its
 * first nvec outputs: y[k][m] = output k at t = m / fs, m < nref.
 * Returns 0, or -1 after printing what failed. */
int tl_render_deck(const char *path, const char *dir, double fs, int over, double seconds, int nvec, double **y,
                   long nref);

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
    const double *const *input; /* or given: input[k][n] (NULL: signal's) */
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

struct CMUnitTest;
/* Runs the cmocka group `group`: "netlists_present" (tl_netlists finds at
 * least one), then the nfixed tests of `fixed` (NULL if none), then for
 * each netlist of tl_netlists a test named "GROUP PATH" that runs fn with
 * *state the netlist's path.  Returns the group's result (the number of
 * failed tests), or 1 if memory runs out. */
int tl_run_per_netlist(const char *group, void (*fn)(void **state),
                       const struct CMUnitTest *fixed, size_t nfixed);

/* ---- diagnostics ---- */

/* Runs the phases the command line runs (load, structure, emit into a
 * temporary directory) on netlist `text` named t.wdn until one reports;
 * returns the first line it printed (malloc'd), or "" if all succeeded. */
char *tl_first_report(const char *text, Solver solver);

#endif
