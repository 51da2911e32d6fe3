/*
 * benchlib.h - what the benchmarks (bench.c, nlbench.c, deckbench.c,
 * chart.c, ...) share besides tests/testlib.h: the clock and the timed
 * runs, the command line, the header that names the machine, labels of
 * netlists, the tables' rules and notes, error figures, netlists
 * stripped of their solver choices, voices built per rate and solver,
 * timed and rendered, and jobs run in parallel processes, with the
 * reference runs they compute into shared memory.
 */
#ifndef BENCHLIB_H
#define BENCHLIB_H

#include <stddef.h>

#include "../tests/testlib.h"

/* Lets the compiler check a printf-like function's format (argument f)
 * against its arguments (from a on). */
#if defined(__GNUC__)
#define BENCH_PRINTF(f, a) __attribute__((format(printf, f, a)))
#else
#define BENCH_PRINTF(f, a)
#endif

/* ---- the conditions nlbench and deckbench measure under (the same,
 * so that their figures compare) ---- */

/* The most inputs, and the most outputs, of a voice they measure, and
 * of one bench_time_voice and bench_render_voice take. */
#define BENCH_MAXIO 16
/* The flags the voices are compiled with. */
#define BENCH_CFLAGS "-O3 -march=native"
/* The rates, in Hz: 48, 96 and 192 kHz. */
#define BENCH_NRATES 3
extern const double bench_rates[BENCH_NRATES];
/* The amplitudes of the sine that drives an input (V, or the input's
 * unit): 1 and 10. */
#define BENCH_NAMPS 2
extern const double bench_amps[BENCH_NAMPS];

/* ---- the clock and the command line ---- */

/* Seconds on the monotonic clock. */
double bench_now(void);

/* Best ns per sample over `runs` runs of at least `seconds` of wall time
 * each, render(ctx, nblocks) rendering nblocks blocks of `block` frames:
 * first a warm-up of `warmup` seconds, which also sizes the batches
 * between clock reads (about 5 ms of work each). */
double bench_measure(void (*render)(void *ctx, long nblocks), void *ctx, int block, int runs,
                     double warmup, double seconds);

/* Reads the command line `PROG [-t SECONDS] ARG...`: *seconds gets
 * SECONDS (it keeps its value, the default, without -t), and unless
 * width is NULL, *width is raised to the length of the longest label
 * (bench_label) of the ARGs.  Returns the index in argv of the first
 * ARG; if there is none or SECONDS is not positive, prints "usage:
 * `usage`" on stderr and exits with status 2. */
int bench_args(int argc, char **argv, double *seconds, int *width, const char *usage);

/* Runs one(argv[i], seconds) for each i from first to argc-1, after
 * flushing stdout (the table's head), then prints the notes
 * (bench_print_notes).  Returns the bitwise or of what the calls
 * returned. */
int bench_each(int argc, char **argv, int first, double seconds, int (*one)(const char *path, double seconds));

/* ---- the tables ---- */

/* Prints the compiler the voices are built with ($CC, default cc) and its
 * first --version line, the flags `cflags`, and the CPU's model name,
 * then an empty line. */
void bench_print_setup(const char *cflags);
/* The CPU's model name from /proc/cpuinfo into buf, or "?". */
void bench_cpu_model(char *buf, size_t cap);
/* The first line `cmd` (a shell command) prints into buf, or "?". */
void bench_first_line(const char *cmd, char *buf, size_t cap);

/* The netlist's file name without its directory and .wdn. */
void bench_label(const char *path, char *label, size_t cap);
/* Writes n dashes into buf, at most cap - 1 of them, and a '\0': the
 * rule under a table's column n wide. */
void bench_dashes(char *buf, size_t cap, int n);

/* Keeps a note, printf's fmt with its arguments, for bench_print_notes:
 * at most 64 notes of 255 characters (longer ones are cut, further ones
 * dropped). */
void bench_note(const char *fmt, ...) BENCH_PRINTF(1, 2);
/* Prints an empty line and then every note kept, each as "note: TEXT" on
 * a line of its own; nothing if there is none. */
void bench_print_notes(void);

/* ---- error figures ---- */

/* The relative RMS error of a against b over n samples,
 * sqrt(sum (a - b)^2 / sum b^2), summed in long double; the RMS of a if
 * b is all zero, 0 if n is 0. */
double bench_rel_rms(const double *a, const double *b, long n);
/* The worst bench_rel_rms of y[k] against r[k] over n samples for the
 * outputs k = 0 .. nouts-1 (a NaN is the worst); *which gets that
 * output.  Returns -1, with *which 0, if nouts is 0. */
double bench_worst_error(double *const *y, double *const *r, int nouts, long n, int *which);
/* Writes the error e of output `out` into buf in dB, "20 log10(e) OUT"
 * with one decimal: "-inf OUT" if e is 0, "nan" if e is negative or not
 * a number. */
void bench_fmt_db(char *buf, size_t cap, double e, const char *out);

/* ---- voices ---- */

/* Writes the netlist `text` to `path` with every solver=VALUE key dropped
 * from the code of its lines (comments are kept as they are), so that the
 * command line's --solver applies to every nonlinear element.  Returns
 * the number of keys dropped, or -1 if the file cannot be written. */
int bench_drop_solver_keys(const char *text, const char *path);
/* Reads the netlist file at path, to be copied by bench_voice_dir:
 * returns its text (in the compiler's arena: not to be freed), or NULL after printing "PROG: cannot
 * read PATH" on stderr.  If the netlist includes other files, notes
 * (bench_note) under its label that the copy may not find them. */
char *bench_read_netlist(const char *prog, const char *path, const char *label);

/* A way to build a voice: the label of its rows, and its flags for wdc
 * (at most 4, NULL-terminated). */
typedef struct bench_solver {
    const char *label;
    const char *args[5];
} bench_solver;

/* Makes a fresh directory /tmp/wdc-PROG-XXXXXX, its path into dir (cap
 * bytes), for a voice; if text is not NULL, writes the netlist `text`
 * into it as netlist.wdn without its solver= keys
 * (bench_drop_solver_keys).  Returns 0, or -1 after printing on stderr
 * what failed, prefixed "PROG: "; dir is "" if it could not be made. */
int bench_voice_dir(const char *prog, const char *text, char *dir, size_t cap);
/* Emits the voice of the netlist file src into dir with `--rate FS` and
 * the solver's flags, and compiles it with cflags (tl_voice_make; $WDC
 * overrides bin/wdc); `netlist` names it in the message.  Returns 0, or
 * -1 after printing on stderr "PROG: NETLIST --rate FS, solver LABEL: the
 * voice could not be built". */
int bench_voice_make(const char *prog, const char *netlist, const char *src, const char *dir, const bench_solver *sc,
                     double fs, const char *cflags);

/* Times a fresh instance of the voice cls at rate fs: the best ns per
 * sample of bench_measure (runs, warmup, seconds) over process calls of
 * `block` frames.  Input k reads drive[k], len frames (a whole number of
 * blocks, at least one) cycled; with drive NULL the instance is reset
 * (cls->reset) every len frames instead.  Every block's outputs go to
 * out[k][0 .. block-1]; *finite is set to 0 if the last one holds a
 * sample that is not finite (and left as it is otherwise).  Returns the
 * ns per sample, or -1 if the instance could not be made or the voice has
 * more than BENCH_MAXIO inputs or outputs. */
double bench_time_voice(const wdv_class *cls, double fs, double *const *drive, long len, double **out, int block,
                        int runs, double warmup, double seconds, int *finite);
/* Renders nframes by a fresh instance of the voice cls at rate fs, in
 * process calls of `block` frames (the last may be shorter), input k
 * reading in[k] (in may be NULL without inputs), output k written to
 * out[k].  Unless stats is NULL, stats[0 .. WDV_SOLVE_N-1] gets the
 * joint solves' counts (cls->solve_stats; all 0 without them).  Returns
 * 0, or -1 if the instance could not be made, the voice has more than
 * BENCH_MAXIO inputs or outputs, or a sample is not finite. */
int bench_render_voice(const wdv_class *cls, double fs, double *const *in, long nframes, int block, double **out,
                       unsigned long *stats);

/* ---- jobs in parallel ---- */

/* Runs job(ctx, k) for k = 0 .. njobs-1, each in a child process, as many
 * at a time as there are processors (at most 16); status[k] gets job k's
 * return value (0: done; a child that did not exit normally gives 1).
 * Jobs share nothing with the caller but files and memory mapped
 * MAP_SHARED before the call. */
void bench_run_jobs(int njobs, int (*job)(void *ctx, int k), void *ctx, int *status);

/* The reference runs of one netlist, in zeroed memory mapped MAP_SHARED,
 * which the processes of bench_run_jobs compute into: nruns runs of nouts
 * outputs each (bench_refs_out), whether each was computed (ok[run], set
 * by bench_prepare), and the samples at which its simulation did not
 * converge (unconverged[run], for the run to set). */
typedef struct bench_refs {
    int nruns, nouts;
    double **out; /* out[run * nouts + k]: output k of the run; the mapping's start */
    long *unconverged;
    int *ok;
    size_t size; /* bytes mapped */
} bench_refs;

/* Maps the memory of nruns reference runs of nouts outputs, run k
 * frames[k] samples long, into refs.  Returns 0, or -1 if it cannot be
 * had (refs then maps nothing). */
int bench_refs_new(bench_refs *refs, int nruns, int nouts, const long *frames);
/* The nouts outputs of reference run `run`. */
double **bench_refs_out(const bench_refs *refs, int run);
/* Unmaps the memory of refs, if it maps any. */
void bench_refs_free(bench_refs *refs);

/* A voice built into its directory (v.dir: a temporary directory, "" if
 * it could not be made), and whether it was emitted and compiled. */
typedef struct bench_built {
    tl_voice v;
    int ok;
} bench_built;

/* Clears built[0 .. nbuilt-1] and makes each one's directory
 * (bench_voice_dir with prog and text), then runs in parallel
 * (bench_run_jobs) the reference runs ref(ctx, runs[k]) for k = 0 ..
 * nruns-1, in that order (the longest first is best), and the builds
 * build(ctx, i) of the voices whose directory was made; each returns 0
 * if done.  built[i].ok gets whether build i was done, refs->ok[run]
 * whether ref(ctx, run) was.  Returns 0, or -1 if out of memory (then
 * nothing is run). */
int bench_prepare(const char *prog, const char *text, bench_built *built, int nbuilt, int (*build)(void *ctx, int i),
                  bench_refs *refs, const int *runs, int nruns, int (*ref)(void *ctx, int run), void *ctx);

#endif
