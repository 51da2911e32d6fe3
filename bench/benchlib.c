/* benchlib.c - helpers shared by the benchmarks (see benchlib.h). */
#include "benchlib.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

double bench_now(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

double bench_measure(void (*render)(void *ctx, long nblocks), void *ctx, int block, int runs,
                     double warmup, double seconds) {
    long done = 0;
    double t0 = bench_now(), t;
    do {
        render(ctx, 16);
        done += 16;
        t = bench_now();
    } while (t - t0 < warmup);
    /* about 5 ms of work between clock reads */
    long batch = (long)((double)done / (t - t0) * 0.005);
    if (batch < 1)
        batch = 1;
    double best = INFINITY;
    for (int run = 0; run < runs; run++) {
        long blocks = 0;
        double start = bench_now(), el;
        do {
            render(ctx, batch);
            blocks += batch;
            el = bench_now() - start;
        } while (el < seconds);
        double ns = el * 1e9 / ((double)blocks * block);
        if (ns < best)
            best = ns;
    }
    return best;
}

/* First line of `cmd`'s output, or "?" */
static void first_line(const char *cmd, char *buf, size_t cap) {
    snprintf(buf, cap, "?");
    FILE *p = popen(cmd, "r");
    if (!p)
        return;
    if (fgets(buf, (int)cap, p))
        buf[strcspn(buf, "\n")] = '\0';
    else
        snprintf(buf, cap, "?");
    pclose(p);
}

void bench_cpu_model(char *buf, size_t cap) {
    snprintf(buf, cap, "?");
    FILE *f = fopen("/proc/cpuinfo", "r");
    if (!f)
        return;
    char line[512];
    while (fgets(line, sizeof line, f)) {
        if (!strncmp(line, "model name", 10)) {
            char *c = strchr(line, ':');
            if (c) {
                c++;
                while (*c == ' ' || *c == '\t')
                    c++;
                c[strcspn(c, "\n")] = '\0';
                snprintf(buf, cap, "%s", c);
            }
            break;
        }
    }
    fclose(f);
}

void bench_print_setup(const char *cflags) {
    const char *cc = getenv("CC");
    if (!cc || !*cc)
        cc = "cc";
    char version[256], cpu[256], cmd[512];
    snprintf(cmd, sizeof cmd, "%s --version 2>/dev/null", cc);
    first_line(cmd, version, sizeof version);
    bench_cpu_model(cpu, sizeof cpu);
    printf("compiler: %s (%s)\n", cc, version);
    printf("flags:    -std=c99 -shared -fPIC %s ... -lm\n", cflags);
    printf("cpu:      %s\n\n", cpu);
}

void bench_label(const char *path, char *label, size_t cap) {
    const char *s = strrchr(path, '/');
    snprintf(label, cap, "%s", s ? s + 1 : path);
    char *dot = strrchr(label, '.');
    if (dot && !strcmp(dot, ".wdn"))
        *dot = '\0';
}
