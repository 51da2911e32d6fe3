/*
 * benchlib.h - what the benchmarks (bench.c, nlbench.c) share besides
 * tests/testlib.h: the clock and the timed runs, the header that names the
 * machine, and labels of netlists.
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

/* The netlist's file name without its directory and .wdn. */
void bench_label(const char *path, char *label, size_t cap);

#endif
