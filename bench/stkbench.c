/*
 * stkbench.c - a plucked string of wdc beside STK's Plucked: speed and
 * tuning, in the same run.
 *
 *     build/bench/stkbench [PLUCK.wdn]      (default netlists/pluck.wdn)
 *
 * The netlist's contract: a force input `f` (N), a param `f0` (Hz, its
 * first partial) and an output `vel` (m/s, the string's velocity at a
 * pickup).  bin/wdc ($WDC overrides the path) emits its voice in double
 * precision, $CC (default cc) compiles it with -O2 and the runtime loads
 * it; STK's Plucked (libstk-dev, through bench/stkshim.cpp, compiled with
 * g++ -O2: its inner loop is inline in STK's headers) is made with a
 * lowest frequency of 50 Hz.  Both run at 48 kHz.  For f0 = 110, 440 and
 * 1760 Hz:
 *
 *   - Tuning: a fresh wdc instance with f0 set (set_param) gets 1 N for
 *     one sample, then zeros; a fresh Plucked gets noteOn(f0, 1.0).  Each
 *     renders 2 s; pt_peak_freq (tests/partials.h) finds the strongest
 *     peak within f0 * [0.9, 1.1], and pt_cents gives its error in cents
 *     from f0.
 *   - Speed: 10 s of audio in blocks of 256 frames, the string plucked
 *     again (the same impulse, or noteOn) every 2 s so that it keeps
 *     sounding; after one untimed run, the best of 5 timed runs gives ns
 *     per sample and the number of such voices one core renders in real
 *     time at 48 kHz, 1e9 / (ns * 48000).
 *
 * If the netlist does not build or lacks f, f0 or vel, a message says so
 * and only STK's rows are printed.  A benchmark, not a test: the exit
 * status is 0 unless the command line is wrong (2).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "benchlib.h"
#include "peers.h" /* stkshim.cpp */
#include "wdrt.h"
#include "wdvoice.h"
#include "../tests/testlib.h"

#include "../tests/partials.h"

#define FS 48000.0
#define BLOCK 256
#define TUNE_S 2.0   /* seconds rendered for the tuning */
#define TIMED_S 10.0 /* seconds of audio per timed run */
#define REPLUCK_S 2.0
#define RUNS 5
#define STK_LOWEST 50.0
#define VOICE_CFLAGS "-O2"

/* ---- the two voices behind one interface ---- */

typedef struct Wdc {
    const wdv_class *cls;
    void *st;
    int pid, oid;
    double f0;
    double *in, *zeros, *outs[16];
    long pos; /* frames since the last pluck */
} Wdc;

typedef struct Stk {
    struct stkp *p;
    double f0;
    double *buf;
    long pos;
} Stk;

/* Fresh instance at f0; returns 0, or -1. */
static int wdc_start(Wdc *w, double f0) {
    tl_state_free(w->st);
    w->st = tl_state_new(w->cls, FS);
    if (!w->st || w->cls->set_param(w->st, w->pid, f0) != 0)
        return -1;
    w->f0 = f0;
    w->pos = 0;
    return 0;
}

/* n <= BLOCK frames of output `vel` into y (NULL: the voice's buffer),
 * plucked (1 N for one sample) at frame 0 and every REPLUCK_S if
 * repluck. */
static void wdc_render(Wdc *w, double *y, int n, int repluck) {
    const double *in[16];
    double *out[16];
    long period = (long)(REPLUCK_S * FS);
    long at = (period - w->pos % period) % period; /* frames to the next pluck */
    memset(w->in, 0, sizeof(double) * BLOCK);
    if ((w->pos == 0 || repluck) && at < n)
        w->in[at] = 1.0;
    for (int k = 0; k < w->cls->n_inputs; k++)
        in[k] = k == 0 ? w->in : w->zeros;
    for (int k = 0; k < w->cls->n_outputs; k++)
        out[k] = w->outs[k];
    w->cls->process(w->st, in, out, n);
    if (y)
        memcpy(y, w->outs[w->oid], sizeof(double) * (size_t)n);
    w->pos += n;
}

static int stk_start(Stk *s, double f0) {
    stkp_free(s->p);
    s->p = stkp_new(STK_LOWEST, 1u);
    if (!s->p)
        return -1;
    stkp_note_on(s->p, f0, 1.0);
    s->f0 = f0;
    s->pos = 0;
    return 0;
}

static void stk_render(Stk *s, double *y, int n, int repluck) {
    long period = (long)(REPLUCK_S * FS);
    double *dst = y ? y : s->buf;
    long at = (period - s->pos % period) % period; /* frames to the next pluck */
    int done = 0;
    if (repluck && s->pos > 0 && at < n) {
        done = (int)at;
        stkp_tick(s->p, dst, done);
        stkp_note_on(s->p, s->f0, 1.0);
    }
    stkp_tick(s->p, dst + done, n - done);
    s->pos += n;
}

/* ---- measurements ---- */

typedef struct Side {
    int (*start)(void *v, double f0);
    void (*render)(void *v, double *y, int n, int repluck);
    void *v;
} Side;

static int side_wdc_start(void *v, double f0) { return wdc_start(v, f0); }
static void side_wdc_render(void *v, double *y, int n, int r) { wdc_render(v, y, n, r); }
static int side_stk_start(void *v, double f0) { return stk_start(v, f0); }
static void side_stk_render(void *v, double *y, int n, int r) { stk_render(v, y, n, r); }

typedef struct Row {
    int ok;
    double ns, cents, peak;
    int finite;
} Row;

static Row measure(const Side *s, double f0) {
    Row r = {0, NAN, NAN, NAN, 1};
    long n = (long)(TUNE_S * FS);
    double *y = malloc(sizeof(double) * (size_t)n);
    if (!y || s->start(s->v, f0) != 0) {
        free(y);
        return r;
    }
    for (long i = 0; i < n; i += BLOCK)
        s->render(s->v, y + i, (int)(n - i < BLOCK ? n - i : BLOCK), 0);
    for (long i = 0; i < n; i++)
        if (!isfinite(y[i]))
            r.finite = 0;
    if (r.finite) {
        r.peak = pt_peak_freq(y, (size_t)n, FS, 0.9 * f0, 1.1 * f0);
        r.cents = pt_cents(r.peak, f0);
    }
    free(y);

    long blocks = (long)(TIMED_S * FS) / BLOCK;
    double best = INFINITY;
    for (int run = 0; run <= RUNS; run++) { /* run 0: warm-up */
        if (s->start(s->v, f0) != 0)
            return r;
        double t0 = bench_now();
        for (long b = 0; b < blocks; b++)
            s->render(s->v, NULL, BLOCK, 1);
        double ns = (bench_now() - t0) * 1e9 / ((double)blocks * BLOCK);
        if (run > 0 && ns < best)
            best = ns;
    }
    r.ns = best;
    r.ok = 1;
    return r;
}

static void print_row(const char *voice, double f0, const Row *r) {
    if (!r->ok)
        printf("%-6s %8.0f %10s %18s %22s\n", voice, f0, "failed", "-", "-");
    else if (!r->finite)
        printf("%-6s %8.0f %10.2f %18.0f %22s\n", voice, f0, r->ns, 1e9 / (r->ns * FS),
               "non-finite output!");
    else
        printf("%-6s %8.0f %10.2f %18.0f %+22.3f\n", voice, f0, r->ns, 1e9 / (r->ns * FS),
               r->cents);
    fflush(stdout);
}

/* Builds and checks the wdc voice; returns 0, or -1 after saying why. */
static int wdc_open(const char *netlist, tl_voice *tv, Wdc *w) {
    if (tl_voice_build_args(netlist, 0, NULL, VOICE_CFLAGS, tv) != 0) {
        printf("wdc: %s: the voice could not be built (see above); only STK is measured\n",
               netlist);
        return -1;
    }
    w->cls = tv->cls;
    w->pid = tl_param_id(w->cls, "f0");
    w->oid = tl_output_id(w->cls, "vel");
    const char *why = NULL;
    if (w->cls->n_inputs < 1 || strcmp(w->cls->inputs[0].name, "f") != 0)
        why = "its first input is not `f`";
    else if (w->pid < 0)
        why = "it has no param `f0`";
    else if (w->oid < 0)
        why = "it has no output `vel`";
    else if (w->cls->n_inputs > 16 || w->cls->n_outputs > 16)
        why = "it has more than 16 inputs or outputs";
    if (why) {
        printf("wdc: %s: %s; only STK is measured\n", netlist, why);
        return -1;
    }
    int ok = (w->in = calloc(BLOCK, sizeof(double))) != NULL;
    ok &= (w->zeros = calloc(BLOCK, sizeof(double))) != NULL;
    for (int k = 0; k < w->cls->n_outputs; k++)
        ok &= (w->outs[k] = calloc(BLOCK, sizeof(double))) != NULL;
    if (!ok) {
        printf("wdc: out of memory; only STK is measured\n");
        return -1;
    }
    return 0;
}

static void wdc_close(Wdc *w) {
    free(w->in);
    free(w->zeros);
    for (int k = 0; k < 16; k++)
        free(w->outs[k]);
    tl_state_free(w->st);
    memset(w, 0, sizeof *w);
}

int main(int argc, char **argv) {
    const char *netlist = argc > 1 ? argv[1] : "netlists/pluck.wdn";
    if (argc > 2 || (argc == 2 && argv[1][0] == '-')) {
        fprintf(stderr, "usage: stkbench [PLUCK.wdn]\n");
        return 2;
    }
    static const double freqs[] = {110.0, 440.0, 1760.0};

    printf("plucked string: wdc (%s) against STK Plucked, at %.0f Hz\n", netlist, FS);
    printf("speed: %.0f s of audio in blocks of %d frames, plucked every %.0f s, best of %d runs\n",
           TIMED_S, BLOCK, REPLUCK_S, RUNS);
    printf("tuning: the strongest peak within f0 * [0.9, 1.1] of %.0f s after one pluck\n"
           "        (wdc: 1 N for one sample on `f`, output `vel`; STK: noteOn(f0, 1.0), lowest %.0f Hz)\n",
           TUNE_S, STK_LOWEST);
    printf("stk:    bench/stkshim.cpp built with g++ -O2 against libstk (STK's inner loop is inline)\n");
    bench_print_setup(VOICE_CFLAGS);
    fflush(stdout);

    tl_voice tv;
    memset(&tv, 0, sizeof tv);
    Wdc w;
    memset(&w, 0, sizeof w);
    int have_wdc = wdc_open(netlist, &tv, &w) == 0;
    if (!have_wdc)
        printf("\n");
    Stk s = {NULL, 0.0, malloc(sizeof(double) * BLOCK), 0};
    stkp_set_rate(FS);

    Side wside = {side_wdc_start, side_wdc_render, &w};
    Side sside = {side_stk_start, side_stk_render, &s};

    printf("%-6s %8s %10s %18s %22s\n", "voice", "f0(Hz)", "ns/sample", "voices/core@48k",
           "tuning error (cents)");
    printf("%-6s %8s %10s %18s %22s\n", "------", "--------", "----------", "------------------",
           "----------------------");
    fflush(stdout);
    for (size_t i = 0; i < sizeof freqs / sizeof freqs[0]; i++) {
        if (have_wdc) {
            Row r = measure(&wside, freqs[i]);
            print_row("wdc", freqs[i], &r);
        }
        Row r = s.buf ? measure(&sside, freqs[i]) : (Row){0, NAN, NAN, NAN, 1};
        print_row("stk", freqs[i], &r);
    }
    if (!have_wdc)
        printf("(no wdc rows: %s did not give a usable voice)\n", netlist);

    stkp_free(s.p);
    free(s.buf);
    wdc_close(&w);
    tl_voice_free(&tv);
    return 0;
}
