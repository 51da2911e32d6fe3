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
#define CFLAGS "-O2 -march=native"

/* ---- the measurement ---- */

typedef struct Voice {
    const wdv_class *cls;
    void *st;
    double *noise[16];
    double *outbuf[16];
    const double *in[16];
    double *out[16];
    long pos; /* frame offset into the noise */
} Voice;

static void render_blocks(void *ctx, long nblocks) {
    Voice *v = ctx;
    const wdv_class *cls = v->cls;
    for (long b = 0; b < nblocks; b++) {
        for (int k = 0; k < cls->n_inputs; k++)
            v->in[k] = v->noise[k] + v->pos;
        cls->process(v->st, v->in, v->out, BLOCK);
        v->pos += BLOCK;
        if (v->pos + BLOCK > NOISE_LEN)
            v->pos = 0;
    }
}

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
    double ns;
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
    Voice v = {0};
    if (tl_voice_build_args(netlist, single, extra, CFLAGS, &tv) != 0)
        goto out;
    res.skips = skips(&tv);
    v.cls = tv.cls;
    if (v.cls->n_inputs > 16 || v.cls->n_outputs > 16) {
        fprintf(stderr, "bench: %s: more than 16 inputs or outputs\n", netlist);
        goto out;
    }
    v.st = tl_state_new(v.cls, FS);
    if (!v.st)
        goto out;
    uint64_t seed = 0x9E3779B97F4A7C15ull;
    for (int k = 0; k < v.cls->n_inputs; k++) {
        v.noise[k] = malloc(sizeof(double) * NOISE_LEN);
        if (!v.noise[k])
            goto out;
        for (long n = 0; n < NOISE_LEN; n++)
            v.noise[k][n] = noise_sample(&seed);
    }
    for (int k = 0; k < v.cls->n_outputs; k++) {
        v.outbuf[k] = calloc(BLOCK, sizeof(double));
        if (!v.outbuf[k])
            goto out;
        v.out[k] = v.outbuf[k];
    }
    res.ns = bench_measure(render_blocks, &v, BLOCK, RUNS, WARMUP_S, seconds);
    res.state_size = v.cls->state_size;
    res.finite = 1;
    for (int k = 0; k < v.cls->n_outputs; k++)
        for (int n = 0; n < BLOCK; n++)
            if (!isfinite(v.outbuf[k][n]))
                res.finite = 0;
    res.ok = 1;
out:
    for (int k = 0; k < 16; k++) {
        free(v.noise[k]);
        free(v.outbuf[k]);
    }
    tl_state_free(v.st);
    tl_voice_free(&tv);
    return res;
}

int main(int argc, char **argv) {
    double seconds = 0.5;
    int first = 1;
    if (argc > 2 && !strcmp(argv[1], "-t")) {
        seconds = atof(argv[2]);
        first = 3;
    }
    if (first >= argc || !(seconds > 0)) {
        fprintf(stderr, "usage: bench [-t SECONDS] NETLIST.wdn...\n");
        return 2;
    }
    printf("wdc voice benchmark: one voice at %.0f Hz, white noise on every input, blocks of %d frames,\n"
           "best of %d runs of >= %.2g s after a %.2g s warm-up\n",
           FS, BLOCK, RUNS, seconds, WARMUP_S);
    printf("a row 'NAME -' is the voice above it without skipping its idle hammers (wdc --no-skip)\n");
    bench_print_setup(CFLAGS);
    printf("%-16s %-9s %10s %10s %18s\n", "netlist", "precision", "state B", "ns/sample", "voices/core@48k");
    printf("%-16s %-9s %10s %10s %18s\n", "----------------", "---------", "----------", "----------",
           "------------------");
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
                    printf("%-16s %-9s %10zu %10.2f %18.0f%s\n", label, single ? "float" : "double", r.state_size,
                           r.ns, 1e9 / (r.ns * FS), r.finite ? "" : "  (non-finite output!)");
                    if (!r.finite)
                        failed = 1;
                }
                fflush(stdout);
            }
        }
    }
    return failed;
}
