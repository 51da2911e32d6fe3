/*
 * paramblock.c - what a param change costs the audio thread.
 *
 *     build/bench/paramblock NETLIST.wdn...
 *
 * Each voice is built as the tests build it (bin/wdc, then $CC -O2) and
 * run at 48 kHz in blocks of 64 frames from the state init leaves it in
 * (its .ic values applied: a struck instrument rings).  After 100
 * blocks, past the strike, its median block is timed over 400 blocks
 * without changes.  Then each param in turn
 * moves five times, between 31 % and 71 % of its range, 20 blocks apart:
 *
 *   inline    set_param, then the block after it (the voice does in that
 *             block whatever the change needs);
 *   prepared  prepare (wdv_class.prepare, untimed: a host runs it off the
 *             audio thread) of the new params, then set_param, install
 *             and the block after it, timed together.
 *
 * The worst of the five blocks is printed for each, with its ratio to
 * the median block: the least such worst of three rounds, so that a
 * round the machine took the thread away in does not count.  A voice without prepare prints the inline figure
 * twice.  A benchmark, not a test: nothing is asserted about times.
 */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "benchlib.h"
#include "../tests/testlib.h"

#define FS 48000.0
#define BLOCK 64
#define NMED 400
#define TRIALS 5
#define ROUNDS 3
#define GAP 20
#define WARM 100 /* blocks before timing: a struck voice has left its strike */

typedef struct Run {
    const wdv_class *c;
    void *st;
    double *in[8], *out[8];
} Run;

static double block(Run *r) {
    double t0 = bench_now();
    r->c->process(r->st, (const double *const *)r->in, r->out, BLOCK);
    return bench_now() - t0;
}

static int cmp(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

int main(int argc, char **argv) {
    if (argc < 2) {
        fprintf(stderr, "usage: %s NETLIST.wdn...\n", argv[0]);
        return 2;
    }
    bench_print_setup(TL_VOICE_CFLAGS);
    printf("%-18s %-10s %10s %12s %8s %12s %8s\n", "voice", "param", "median ns", "inline ns", "x", "prepared ns",
           "x");
    static double zeros[8][BLOCK], sink[8][BLOCK];
    for (int f = 1; f < argc; f++) {
        tl_voice v;
        char label[64];
        bench_label(argv[f], label, sizeof label);
        if (tl_voice_build(argv[f], 0, &v) != 0)
            return 1;
        const wdv_class *c = v.cls;
        Run r = {c, tl_state_new(c, FS), {0}, {0}};
        void *design = c->design_size ? malloc(c->design_size) : NULL;
        if (!r.st || (c->design_size && !design) || c->n_inputs > 8 || c->n_outputs > 8)
            return 1;
        for (int k = 0; k < 8; k++)
            r.in[k] = zeros[k], r.out[k] = sink[k];
        c->init(r.st, FS);
        for (int b = 0; b < WARM; b++)
            block(&r);
        double med[NMED];
        for (int b = 0; b < NMED; b++)
            med[b] = block(&r);
        qsort(med, NMED, sizeof med[0], cmp);
        double m = med[NMED / 2];
        if (!c->n_params)
            printf("%-18s %-10s %10.0f %12s %8s %12s %8s\n", label, "-", 1e9 * m, "-", "-", "-", "-");
        for (int i = 0; i < c->n_params; i++) {
            const wdv_param *pd = &c->params[i];
            double worst[2] = {INFINITY, INFINITY}, p[64];
            for (int round = 0; round < 2 * ROUNDS; round++) {
                int mode = round % 2;
                double w = 0;
                c->init(r.st, FS);
                for (int b = 0; b < WARM + NMED; b++)
                    block(&r);
                for (int t = 0; t < TRIALS; t++) {
                    double val = pd->min + (t % 2 ? 0.71 : 0.31) * (pd->max - pd->min);
                    double dt;
                    if (mode && c->prepare) {
                        for (int j = 0; j < c->n_params && j < 64; j++)
                            p[j] = c->get_param(r.st, j);
                        p[i] = val;
                        c->prepare(FS, p, design);
                        double t0 = bench_now();
                        c->set_param(r.st, i, val);
                        c->install(r.st, design);
                        c->process(r.st, (const double *const *)r.in, r.out, BLOCK);
                        dt = bench_now() - t0;
                    } else {
                        double t0 = bench_now();
                        c->set_param(r.st, i, val);
                        c->process(r.st, (const double *const *)r.in, r.out, BLOCK);
                        dt = bench_now() - t0;
                    }
                    w = fmax(w, dt);
                    for (int b = 0; b < GAP; b++)
                        block(&r);
                }
                worst[mode] = fmin(worst[mode], w);
            }
            printf("%-18s %-10s %10.0f %12.0f %8.1f %12.0f %8.1f\n", label, pd->name, 1e9 * m, 1e9 * worst[0],
                   worst[0] / m, 1e9 * worst[1], worst[1] / m);
        }
        free(design);
        tl_state_free(r.st);
        tl_voice_free(&v);
    }
    return 0;
}
