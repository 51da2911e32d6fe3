/*
 * bench.c - speed of the emitted voices.
 *
 *     build/bench/bench [-t SECONDS] NETLIST.wdn...
 *
 * For each netlist, in double and in float precision: bin/wdc ($WDC
 * overrides the path) emits the voice into a temporary directory, $CC
 * (default cc) compiles it into a shared object with -O2 -march=native,
 * and the runtime loads it (wdrt_voice_open).  One instance at 48 kHz
 * then renders white noise on every input in blocks of 64 frames: a
 * warm-up of 0.2 s, then 5 timed runs of at least SECONDS (default 0.5)
 * of wall time each.  The best run gives ns per sample and the number of
 * such voices one core renders in real time at 48 kHz.  A voice that
 * skips idle hammers is measured again as `wdc --no-skip` emits it.
 * The voice is built with --batch (its process is the same as without).
 * Then LANES (8) instances, each on its own stretch of the noise, render
 * by one process call each and together by process_batch: ns per
 * voice-sample of each (the time over 8 times the frames), and how many
 * times cheaper the batch is.  (Eight instances of a voice with long
 * delay lines no longer share the cache one instance has to itself.)
 *
 * A benchmark, not a test: the exit status is non-zero only if a voice
 * could not be built or loaded, or produced a non-finite sample.
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "benchlib.h"
#include "wdrt.h"
#include "wdvoice.h"
#include "../tests/testlib.h"

#define FS 48000.0
#define BLOCK 64
#define NOISE_LEN 8192 /* frames of noise per input, cycled */
#define RUNS 5
#define WARMUP_S 0.2
#define CFLAGS BENCH_CFLAGS

/* ---- the measurement ---- */

#define LANES 8

/* LANES instances of one voice, rendered by process_batch. */
typedef struct Batch {
    const wdv_class *cls;
    void *st[LANES];
    double **noise;           /* the single voice's noise, read at each lane's own offset */
    double *outbuf[LANES][16];
    const double *in[LANES][16];
    const double *const *inl[LANES];
    double *const *outl[LANES];
    long pos;
} Batch;

/* Renders nblocks by process_batch (batched) or a process call per
 * instance, each lane reading the noise at its own offset. */
static void render_lanes(Batch *b, long nblocks, int batched) {
    const wdv_class *cls = b->cls;
    for (long k = 0; k < nblocks; k++) {
        for (int l = 0; l < LANES; l++) {
            for (int i = 0; i < cls->n_inputs; i++)
                b->in[l][i] = b->noise[i] + (b->pos + 977 * l) % (NOISE_LEN - BLOCK);
            if (!batched)
                cls->process(b->st[l], b->inl[l], b->outl[l], BLOCK);
        }
        if (batched)
            cls->process_batch(b->st, LANES, b->inl, b->outl, BLOCK);
        b->pos += BLOCK;
        if (b->pos + BLOCK > NOISE_LEN)
            b->pos = 0;
    }
}

static void render_each(void *ctx, long nblocks) { render_lanes(ctx, nblocks, 0); }
static void render_batch(void *ctx, long nblocks) { render_lanes(ctx, nblocks, 1); }

/* uniform white noise in [-1, 1) (xorshift64*) */
static double noise_sample(uint64_t *s) {
    uint64_t x = *s;
    x ^= x >> 12;
    x ^= x << 25;
    x ^= x >> 27;
    *s = x;
    return (double)((x * 0x2545F4914F6CDD1Dull) >> 11) * (2.0 / 9007199254740992.0) - 1.0;
}

typedef struct Result {
    double ns, each_ns, batch_ns; /* per voice-sample of LANES voices: by process, by process_batch */
    size_t state_size;
    int ok, finite, skips;
} Result;

/* True if the voice built in tv skips idle hammers (wdc's loop for them). */
static int skips(const tl_voice *tv) {
    char path[256], line[512];
    snprintf(path, sizeof path, "%s/%s.c", tv->dir, tv->name);
    FILE *f = fopen(path, "r");
    int found = 0;
    while (f && !found && fgets(line, sizeof line, f))
        found = strstr(line, "the contacts are open") != NULL;
    if (f)
        fclose(f);
    return found;
}

static Result bench_one(const char *netlist, int single, double seconds, const char *const *extra) {
    Result res = {0};
    tl_voice tv;
    const wdv_class *cls = NULL;
    double *noise[16] = {NULL}, *outbuf[16] = {NULL}; /* per input, per output */
    const char *args[4] = {"--batch", NULL, NULL, NULL};
    for (int k = 0; extra && extra[k] && k < 2; k++)
        args[k + 1] = extra[k];
    if (tl_voice_build_args(netlist, single, args, CFLAGS, &tv) != 0)
        goto out;
    res.skips = skips(&tv);
    cls = tv.cls;
    if (cls->n_inputs > 16 || cls->n_outputs > 16) {
        fprintf(stderr, "bench: %s: more than 16 inputs or outputs\n", netlist);
        goto out;
    }
    uint64_t seed = 0x9E3779B97F4A7C15ull;
    for (int k = 0; k < cls->n_inputs; k++) {
        noise[k] = malloc(sizeof(double) * NOISE_LEN);
        if (!noise[k])
            goto out;
        for (long n = 0; n < NOISE_LEN; n++)
            noise[k][n] = noise_sample(&seed);
    }
    for (int k = 0; k < cls->n_outputs; k++) {
        outbuf[k] = calloc(BLOCK, sizeof(double));
        if (!outbuf[k])
            goto out;
    }
    int finite = 1;
    res.ns = bench_time_voice(cls, FS, noise, NOISE_LEN, outbuf, BLOCK, RUNS, WARMUP_S, seconds, &finite);
    if (res.ns < 0)
        goto out;
    Batch b = {.cls = cls, .noise = noise};
    int bok = cls->process_batch != NULL;
    for (int l = 0; l < LANES && bok; l++) {
        b.st[l] = tl_state_new(cls, FS);
        bok = b.st[l] != NULL;
        for (int k = 0; k < cls->n_outputs && bok; k++)
            bok = (b.outbuf[l][k] = calloc(BLOCK, sizeof(double))) != NULL;
        b.inl[l] = b.in[l];
        b.outl[l] = b.outbuf[l];
    }
    res.each_ns = bok ? bench_measure(render_each, &b, BLOCK * LANES, RUNS, WARMUP_S, seconds) : NAN;
    res.batch_ns = bok ? bench_measure(render_batch, &b, BLOCK * LANES, RUNS, WARMUP_S, seconds) : NAN;
    for (int l = 0; l < LANES; l++) {
        for (int k = 0; k < cls->n_outputs; k++) {
            for (int n = 0; n < BLOCK && b.outbuf[l][k]; n++)
                if (!isfinite(b.outbuf[l][k][n]))
                    bok = 0;
            free(b.outbuf[l][k]);
        }
        tl_state_free(b.st[l]);
    }
    res.state_size = cls->state_size;
    res.finite = bok && finite;
    res.ok = 1;
out:
    for (int k = 0; k < 16; k++) {
        free(noise[k]);
        free(outbuf[k]);
    }
    tl_voice_free(&tv);
    return res;
}

int main(int argc, char **argv) {
    double seconds = 0.5;
    int first = bench_args(argc, argv, &seconds, NULL, "bench [-t SECONDS] NETLIST.wdn...");
    printf("wdc voice benchmark: one voice at %.0f Hz, white noise on every input, blocks of %d frames,\n"
           "best of %d runs of >= %.2g s after a %.2g s warm-up\n",
           FS, BLOCK, RUNS, seconds, WARMUP_S);
    printf("a row 'NAME -' is the voice above it without skipping its idle hammers (wdc --no-skip)\n");
    printf("8 each, 8 batched: ns per voice-sample of %d instances rendered by a process call each and by\n"
           "process_batch; ratio: the first over the second\n", LANES);
    bench_print_setup(CFLAGS);
    printf("%-16s %-9s %10s %10s %18s %10s %10s %8s\n", "netlist", "precision", "state B", "ns/sample",
           "voices/core@48k", "8 each", "8 batched", "ratio");
    printf("%-16s %-9s %10s %10s %18s %10s %10s %8s\n", "----------------", "---------", "----------", "----------",
           "------------------", "----------", "----------", "--------");
    fflush(stdout);

    int failed = 0;
    for (int i = first; i < argc; i++) {
        for (int single = 0; single < 2; single++) {
            char label[64];
            bench_label(argv[i], label, sizeof label);
            static const char *const noskip[] = {"--no-skip", NULL};
            Result r = bench_one(argv[i], single, seconds, NULL);
            for (int pass = 0; pass < 2; pass++) {
                if (pass) {
                    if (!r.ok || !r.skips)
                        break;
                    r = bench_one(argv[i], single, seconds, noskip);
                    char base[64];
                    snprintf(base, sizeof base, "%s", label);
                    snprintf(label, sizeof label, "%.14s -", base);
                }
                if (!r.ok) {
                    printf("%-16s %-9s %10s %10s %18s\n", label, single ? "float" : "double", "-", "failed", "-");
                    failed = 1;
                } else {
                    printf("%-16s %-9s %10zu %10.2f %18.0f %10.2f %10.2f %7.2fx%s\n", label,
                           single ? "float" : "double", r.state_size, r.ns, 1e9 / (r.ns * FS), r.each_ns, r.batch_ns,
                           r.each_ns / r.batch_ns, r.finite ? "" : "  (non-finite output!)");
                    if (!r.finite)
                        failed = 1;
                }
                fflush(stdout);
            }
        }
    }
    return failed;
}
