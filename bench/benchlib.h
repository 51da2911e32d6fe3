/*
 * benchlib.h - what the benchmarks (bench.c, nlbench.c, chart.c, ...)
 * share besides tests/testlib.h: the clock and the timed runs, the header
 * that names the machine, labels of netlists, netlists stripped of their
 * solver choices, and jobs run in parallel processes.
 */
#ifndef BENCHLIB_H
#define BENCHLIB_H

#include <stddef.h>

/* Seconds on the monotonic clock. */
double bench_now(void);

/* Best ns per sample over `runs` runs of at least `seconds` of wall time
 * each, render(ctx, nblocks) rendering nblocks blocks of `block` frames:
 * first a warm-up of `warmup` seconds, which also sizes the batches
 * between clock reads (about 5 ms of work each). */
double bench_measure(void (*render)(void *ctx, long nblocks), void *ctx, int block, int runs,
                     double warmup, double seconds);

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

/* Writes the netlist `text` to `path` with every solver=VALUE key dropped
 * from the code of its lines (comments are kept as they are), so that the
 * command line's --solver applies to every nonlinear element.  Returns
 * the number of keys dropped, or -1 if the file cannot be written. */
int bench_drop_solver_keys(const char *text, const char *path);

/* Runs job(ctx, k) for k = 0 .. njobs-1, each in a child process, as many
 * at a time as there are processors (at most 16); status[k] gets job k's
 * return value (0: done; a child that did not exit normally gives 1).
 * Jobs share nothing with the caller but files and memory mapped
 * MAP_SHARED before the call. */
void bench_run_jobs(int njobs, int (*job)(void *ctx, int k), void *ctx, int *status);

#endif
