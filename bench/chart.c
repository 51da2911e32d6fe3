/*
 * chart.c - speed against accuracy of our voices and of their peers,
 * measured in one run: the data `make chart` draws (bench/chart.gp).
 *
 *     build/bench/chart [-t SECONDS] [-o OUT.csv]
 *
 * Every point runs at 48, 96 and 192 kHz.
 *
 * Circuits: netlists/rc_lowpass.wdn, netlists/diode_clipper.wdn (an
 * antiparallel pair) and netlists/diode_single.wdn (one diode).
 *   - Ours: each in double and in float precision, each diode voice with
 *     --solver fast, newton, omega and pwl (its default table, 256 points).
 *     bin/wdc ($WDC overrides the path) emits the voice with --rate and
 *     the solver into a temporary directory, from a copy of the netlist
 *     without its solver= keys, and $CC (default cc) compiles it with
 *     -std=c99 -shared -fPIC -O3 -march=native; the runtime loads it.
 *     Each circuit again in double with the default solver and --batch: 8 instances
 *     rendered together by process_batch (solver "fast x8", "linear x8"),
 *     timed per voice-sample, its accuracy that of lane 0.
 *   - Faust: bench/faust/rc_lowpass.dsp and diode_clipper.dsp, on
 *     wdmodels.lib, made C by `faust -lang c` (float) and `-lang c
 *     -double`, compiled with the voices' flags (-std=c99 -fPIC -O3
 *     -march=native).
 *     The clipper's output lags its input by one sample (its source is a
 *     leaf of the tree): that sample is taken out before its error is
 *     measured.
 *   - By hand: bench/handrc.c (the bilinear transform) and
 *     bench/handclip.c (the trapezoidal rule solved by Newton's method)
 *     for both clippers, in double, compiled likewise.
 * Strings: ours netlists/pluck.wdn in double and in float, and STK's
 * Plucked (bench/stkshim.cpp, g++ -O2; STK computes in double).
 *
 * Speed: one instance renders blocks of 64 frames; bench_measure gives
 * the best of 5 runs of at least SECONDS (default 0.1) of wall time after
 * a warm-up of 0.05 s, in ns per sample.  A circuit gets a 440 Hz sine of
 * 10 V, 1 s of it cycled; a string at f0 = 440 Hz is plucked every second
 * (ours: 1 N on its force input for one sample; STK: noteOn(f0, 1)).
 *
 * Accuracy of a circuit: a fresh instance renders 0.1 s of a 440 Hz sine
 * of 1 V and of 10 V (sample n at time n/fs, 0 before time 0), and its
 * output v(out) is compared with refsim (tests/refsim.h) on the same
 * netlist and input, run at 12.288 MHz (64 times 192 kHz; 128 and 256
 * times the lower rates): the trapezoidal equations solved to convergence
 * on that grid, standing for the continuous-time solution, taken at the
 * voice's instants (as nlbench's "continuous"; its own discretisation
 * error is at least 72 dB below a run at the voice's rate).  The circuits
 * rest until the sine starts, so every run starts at time 0 from the
 * netlist's initial state.  The error is 20 log10 of the relative RMS
 * error sqrt(sum (y - r)^2 / sum r^2).  The same measure against refsim at
 * the voice's own rate (the trapezoidal equations solved to convergence,
 * which the RC voices solve exactly) is the solver's own error: it goes
 * in the last column.
 *
 * Accuracy of a string: a fresh instance plucked once renders 2 s at
 * f0 = 110, 440 and 1760 Hz; pt_peak_freq (tests/partials.h) finds
 * partial n = 1..4 within (n +- 0.3) f0, and the error is the worst
 * |cents| from n f0 over all of them (the netlist's string is ideal:
 * harmonic partials; pt_peak_freq's own error is below 0.05 cent).
 *
 * Each point is printed as it is measured; the CSV (default
 * out/chart.csv) has one row per point and drive:
 *
 *   name,family,model,solver,rate,precision,ns_per_sample,error_db,
 *   error_cents,reference,impl,drive,solver_error_db
 *
 * family is ours or peer, impl wdc, faust, hand or stk; a string's
 * error is in error_cents and a circuit's in error_db (the other empty).
 *
 * Before the measurements, every voice is emitted, then those whose C
 * differs are compiled (a voice the compiler emits the same at every rate
 * is compiled once) while every reference run is computed, as many at a
 * time as there are processors; the measurements then run one at a time.
 *
 * A benchmark, not a test: the exit status is non-zero if a voice could
 * not be built or loaded, a point produced a non-finite sample, or the
 * CSV could not be written.
 */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>

#include "benchlib.h"
#include "gen.h"
#include "peers.h"
#include "wdrt.h"
#include "wdvoice.h"
#include "../tests/partials.h"
#include "../tests/refsim.h"
#include "../tests/testlib.h"

#define BLOCK 64
#define RUNS 5
#define WARMUP_S 0.05
#define ERR_S 0.1 /* seconds of signal in a circuit's accuracy runs */
#define SINE_HZ 440.0
#define REF_HZ (64 * 192000.0) /* the rate of the reference run */
#define TUNE_S 2.0
#define NPARTIALS 4
#define PLUCK_F0 440.0 /* the string timed */
#define REPLUCK_S 1.0
#define STK_LOWEST 50.0
#define MAXIO 16
#define CFLAGS "-O3 -march=native"

static const double rates[] = {48000.0, 96000.0, 192000.0};
#define NRATES 3
static const double amps[] = {1.0, 10.0}; /* the drives; the last is timed */
#define NAMPS 2
static const double tune_f0[] = {110.0, 440.0, 1760.0};
#define NTUNE 3

typedef struct SolverCase {
    const char *name;
    const char *args[3];
} SolverCase;

static const SolverCase diode_solvers[] = {
    {"fast", {"--solver", "fast", NULL}},
    {"newton", {"--solver", "newton", NULL}},
    {"omega", {"--solver", "omega", NULL}},
    {"pwl", {"--solver", "pwl", NULL}},
};
#define NSOLVERS 4

/* ---- the circuits ---- */

typedef struct Circ {
    const char *model, *netlist;
    int diodes;                   /* 0: linear; 1: one diode; 2: a pair */
    double r, c, is, nvt;         /* the netlist's values, for the hand peers */
    const faust_peer *faust[2];   /* [0] double, [1] float; NULL: none */
    int faust_lag;                /* samples Faust's output lags the input */
    Circuit *cir;
    char dir[64];                 /* a temporary folder holding src */
    char src[128];                /* the netlist without its solver= keys */
    int out;                      /* index of v(out) among its outputs */
    /* v(out) of refsim: [rate][drive][0: at the rate, 1: at REF_HZ] */
    double *ref[NRATES][NAMPS][2];
    int *ref_ok;                  /* shared, [rate][drive][2] */
} Circ;

static Circ circs[] = {
    {.model = "rc_lowpass", .netlist = "netlists/rc_lowpass.wdn", .r = 1e3, .c = 100e-9,
     .faust = {&faust_rc_lowpass_d, &faust_rc_lowpass_f}},
    {.model = "diode_clipper", .netlist = "netlists/diode_clipper.wdn", .diodes = 2, .r = 2.2e3, .c = 10e-9,
     .is = 2.52e-9, .nvt = 1.752 * 25.85e-3, .faust = {&faust_diode_clipper_d, &faust_diode_clipper_f},
     .faust_lag = 1},
    {.model = "diode_single", .netlist = "netlists/diode_single.wdn", .diodes = 1, .r = 1e3, .c = 22e-9,
     .is = 2.52e-9, .nvt = 1.752 * 25.85e-3},
};
#define NCIRCS ((int)(sizeof circs / sizeof circs[0]))

static const char *pluck_netlist = "netlists/pluck.wdn";

static long err_frames(int r) { return (long)lround(ERR_S * rates[r]); }

static int ref_slot(int r, int d, int w) { return (r * NAMPS + d) * 2 + w; }

/* ---- the points ---- */

typedef enum { K_VOICE, K_FAUST, K_HANDRC, K_HANDCLIP, K_STRING, K_STK } PointKind;

typedef struct Point {
    PointKind kind;
    int circ;         /* index into circs; -1 for strings */
    int rate, single; /* index into rates; float precision */
    int solver;       /* index into diode_solvers; -1: none */
    int lanes;        /* K_VOICE: 0, or LANES instances timed through process_batch */
    tl_voice v;       /* K_VOICE, K_STRING: v.dir "" until made */
    int emitted, built;
    int twin;         /* an earlier point whose voice's C is the same, or -1 */
    char name[64];
    /* results */
    int ok, finite;
    double ns;
    double err[NAMPS], solver_err[NAMPS]; /* relative RMS; -1: none */
    double cents;                         /* worst |cents|; NAN: none */
} Point;

#define MAXPOINTS 128
#define LANES 8 /* instances of a batched point */
static Point points[MAXPOINTS];
static int npoints;

static const char *impl_name(PointKind k) {
    switch (k) {
    case K_VOICE:
    case K_STRING:
        return "wdc";
    case K_FAUST:
        return "faust";
    case K_HANDRC:
    case K_HANDCLIP:
        return "hand";
    case K_STK:
        return "stk";
    }
    return "?";
}

static const char *solver_name(const Point *p) {
    if (p->lanes)
        return p->solver >= 0 ? "fast x8" : "linear x8";
    if (p->solver >= 0)
        return diode_solvers[p->solver].name;
    if (p->kind == K_FAUST && circs[p->circ].diodes)
        return "lambert-w";
    if (p->kind == K_HANDCLIP)
        return "newton";
    return "linear";
}

static const char *model_name(const Point *p) { return p->circ >= 0 ? circs[p->circ].model : "pluck"; }

static Point *add_point(PointKind kind, int circ, int r, int single, int solver) {
    if (npoints == MAXPOINTS)
        return NULL;
    Point *p = &points[npoints++];
    memset(p, 0, sizeof *p);
    p->kind = kind;
    p->circ = circ;
    p->rate = r;
    p->single = single;
    p->solver = solver;
    p->cents = NAN;
    for (int d = 0; d < NAMPS; d++)
        p->err[d] = p->solver_err[d] = -1;
    snprintf(p->name, sizeof p->name, "%s %s%s%s %.0fk %s", impl_name(kind), model_name(p),
             solver >= 0 ? " " : "", solver >= 0 ? diode_solvers[solver].name : "", rates[r] / 1e3,
             single ? "float" : "double");
    return p;
}

static void list_points(void) {
    for (int r = 0; r < NRATES; r++) {
        for (int ci = 0; ci < NCIRCS; ci++) {
            const Circ *c = &circs[ci];
            for (int single = 0; single < 2; single++) {
                if (!c->diodes)
                    add_point(K_VOICE, ci, r, single, -1);
                for (int s = 0; c->diodes && s < NSOLVERS; s++)
                    add_point(K_VOICE, ci, r, single, s);
            }
            /* batched, in double, with the default solver */
            Point *b = add_point(K_VOICE, ci, r, 0, c->diodes ? 0 : -1);
            if (b) {
                b->lanes = LANES;
                snprintf(b->name + strlen(b->name), sizeof b->name - strlen(b->name), " x%d", LANES);
            }
            for (int single = 0; single < 2; single++)
                if (c->faust[single])
                    add_point(K_FAUST, ci, r, single, -1);
            add_point(c->diodes ? K_HANDCLIP : K_HANDRC, ci, r, 0, -1);
        }
        add_point(K_STRING, -1, r, 0, -1);
        add_point(K_STRING, -1, r, 1, -1);
        add_point(K_STK, -1, r, 0, -1);
    }
}

/* ---- preparation: voices and references, in parallel ---- */

/* Makes the point's voice directory.  Returns 0, or -1 after printing
 * why. */
static int voice_dir(Point *p) {
    if (tl_temp_dir(p->v.dir, "wdc-chart") != 0) {
        fprintf(stderr, "chart: cannot make a temporary folder: %s\n", strerror(errno));
        p->v.dir[0] = '\0';
        return -1;
    }
    return 0;
}

/* Emits the point's voice into its directory: bin/wdc ($WDC overrides
 * the path) with --rate, the precision and the solver.  Returns 0, or -1
 * after printing why. */
static int voice_emit(const Point *p) {
    const char *wdc = getenv("WDC");
    if (!wdc || !*wdc)
        wdc = "bin/wdc";
    char rate[32];
    snprintf(rate, sizeof rate, "%.0f", rates[p->rate]);
    char *argv[16];
    int n = 0;
    argv[n++] = (char *)wdc;
    argv[n++] = p->kind == K_STRING ? (char *)pluck_netlist : circs[p->circ].src;
    argv[n++] = "-o";
    argv[n++] = (char *)p->v.dir;
    argv[n++] = "--rate";
    argv[n++] = rate;
    if (p->single) {
        argv[n++] = "--precision";
        argv[n++] = "float";
    }
    for (int k = 0; p->solver >= 0 && diode_solvers[p->solver].args[k]; k++)
        argv[n++] = (char *)diode_solvers[p->solver].args[k];
    if (p->lanes)
        argv[n++] = "--batch";
    argv[n] = NULL;
    int st = -1;
    if (wdrt_spawn(argv, -1, &st) != WDRT_OK || st != 0) {
        fprintf(stderr, "chart: %s: %s failed (exit status %d)\n", p->name, wdc, st);
        return -1;
    }
    return 0;
}

/* The paths of the one NAME.c in the point's directory and of its
 * NAME.so.  Returns 0, or -1. */
static int voice_paths(const Point *p, char csrc[256], char so[256]) {
    char name[128];
    if (tl_voice_name(p->v.dir, name, sizeof name) != 0)
        return -1;
    snprintf(csrc, 256, "%s/%s.c", p->v.dir, name);
    snprintf(so, 256, "%s/%s.so", p->v.dir, name);
    return 0;
}

/* Compiles the point's emitted voice with $CC (default cc) -std=c99
 * -shared -fPIC CFLAGS.  Returns 0, or -1 after printing why. */
static int voice_compile(const Point *p) {
    char csrc[256], so[256];
    if (voice_paths(p, csrc, so) != 0) {
        fprintf(stderr, "chart: %s: no voice source in %s\n", p->name, p->v.dir);
        return -1;
    }
    wdrt_result r = wdrt_voice_compile(csrc, so, NULL, CFLAGS);
    if (r != WDRT_OK) {
        fprintf(stderr, "chart: %s: compiling %s: %s\n", p->name, csrc, wdrt_result_str(r));
        return -1;
    }
    return 0;
}

/* Points each voice whose emitted C is the same as an earlier one's (the
 * same netlist, solver and precision at another rate, where the compiler
 * bakes nothing of the rate in) at that one: it is compiled once. */
static void find_twins(void) {
    static char *text[MAXPOINTS]; /* the emitted sources, in the compiler's arena: not freed */
    for (int k = 0; k < npoints; k++) {
        Point *p = &points[k];
        char csrc[256], so[256];
        text[k] = p->emitted && voice_paths(p, csrc, so) == 0 ? read_file(csrc, NULL) : NULL;
        p->twin = -1;
        for (int j = 0; j < k && text[k]; j++)
            if (text[j] && points[j].twin < 0 && !strcmp(text[j], text[k])) {
                p->twin = j;
                break;
            }
    }
}

/* Copies the file src to dst.  Returns 0, or -1. */
static int copy_file(const char *src, const char *dst) {
    FILE *in = fopen(src, "rb");
    FILE *out = in ? fopen(dst, "wb") : NULL;
    int ok = in && out;
    char buf[65536];
    size_t n;
    while (ok && (n = fread(buf, 1, sizeof buf, in)) > 0)
        ok = fwrite(buf, 1, n, out) == n;
    if (in && ferror(in))
        ok = 0;
    if (in)
        fclose(in);
    if (out && fclose(out) != 0)
        ok = 0;
    return ok ? 0 : -1;
}

/* Runs refsim of c at rate ffs from rest for ERR_S, every input the sine
 * of amplitude amp (sample j at time j/ffs); y[r], where not NULL, gets
 * output `out` at the instants of rates[r] (ffs a whole multiple of it).
 * Returns 0, or -1 if it cannot run or Newton did not converge at some
 * sample. */
static int render_ref(const Circuit *c, int out, double ffs, double amp, double *y[NRATES]) {
    refsim *s = refsim_new(c, ffs, NULL);
    if (!s)
        return -1;
    long step[NRATES];
    for (int r = 0; r < NRATES; r++)
        step[r] = lround(ffs / rates[r]);
    double in[MAXIO], o[MAXIO];
    long total = lround(ERR_S * ffs);
    for (long j = 0; j < total; j++) {
        double x = amp * sin(2.0 * M_PI * SINE_HZ * (double)j / ffs);
        for (int k = 0; k < c->ninputs; k++)
            in[k] = x;
        refsim_step(s, in, o);
        for (int r = 0; r < NRATES; r++)
            if (y[r] && j % step[r] == 0 && j / step[r] < err_frames(r))
                y[r][j / step[r]] = o[out];
    }
    refsim_nl_info info;
    refsim_nl_stats(s, &info);
    refsim_free(s);
    return info.unconverged ? -1 : 0;
}

typedef enum { J_EMIT, J_COMPILE, J_REF } JobKind;

typedef struct Job {
    JobKind kind;
    int point;         /* J_EMIT, J_COMPILE */
    int circ, r, d, w; /* J_REF: circuit, rate, drive, 0 at the rate or 1 at REF_HZ */
} Job;

#define MAXJOBS (MAXPOINTS + NCIRCS * NRATES * NAMPS * 2)
static Job jobs[MAXJOBS];
static int status[MAXJOBS];

static int do_job(void *ctx, int k) {
    (void)ctx;
    const Job *j = &jobs[k];
    if (j->kind == J_EMIT)
        return voice_emit(&points[j->point]) == 0 ? 0 : 1;
    if (j->kind == J_COMPILE)
        return voice_compile(&points[j->point]) == 0 ? 0 : 1;
    Circ *c = &circs[j->circ];
    double *y[NRATES] = {NULL};
    for (int r = 0; r < NRATES; r++)
        if (j->w || r == j->r)
            y[r] = c->ref[r][j->d][j->w];
    if (render_ref(c->cir, c->out, j->w ? REF_HZ : rates[j->r], amps[j->d], y) != 0)
        return 1;
    for (int r = 0; r < NRATES; r++)
        if (y[r])
            c->ref_ok[ref_slot(r, j->d, j->w)] = 1;
    return 0;
}

/* Loads the circuits and maps their reference buffers.  Returns 0, or -1
 * after printing why. */
static int load_circuits(void) {
    for (int ci = 0; ci < NCIRCS; ci++) {
        Circ *c = &circs[ci];
        c->cir = wdc_load(c->netlist);
        char *text = c->cir ? read_file(c->netlist, NULL) : NULL;
        if (!text) {
            fprintf(stderr, "chart: %s: cannot load\n", c->netlist);
            return -1;
        }
        int made = tl_temp_dir(c->dir, "wdc-chart") == 0;
        snprintf(c->src, sizeof c->src, "%s/%s.wdn", c->dir, c->model);
        if (!made || bench_drop_solver_keys(text, c->src) < 0) { /* text: the compiler's arena's */
            fprintf(stderr, "chart: cannot write %s\n", c->src);
            return -1;
        }
        c->out = -1;
        for (int k = 0; k < c->cir->nouts; k++)
            if (!strcmp(c->cir->outs[k].name, "out"))
                c->out = k;
        if (c->out < 0 || c->cir->ninputs != 1 || !refsim_can_simulate(c->cir)) {
            fprintf(stderr, "chart: %s: needs one input, an output `out` and refsim\n", c->netlist);
            return -1;
        }
        size_t doubles = 0;
        for (int r = 0; r < NRATES; r++)
            doubles += (size_t)NAMPS * 2 * (size_t)err_frames(r);
        size_t size = doubles * sizeof(double) + NRATES * NAMPS * 2 * sizeof(int);
        void *mem = mmap(NULL, size, PROT_READ | PROT_WRITE, MAP_SHARED | MAP_ANONYMOUS, -1, 0);
        if (mem == MAP_FAILED) {
            fprintf(stderr, "chart: out of memory\n");
            return -1;
        }
        double *at = mem;
        for (int r = 0; r < NRATES; r++)
            for (int d = 0; d < NAMPS; d++)
                for (int w = 0; w < 2; w++) {
                    c->ref[r][d][w] = at;
                    at += err_frames(r);
                }
        c->ref_ok = (int *)(void *)at;
    }
    return 0;
}

/* Removes the circuits' folders of netlists without solver= keys. */
static void remove_circuit_dirs(void) {
    for (int ci = 0; ci < NCIRCS; ci++)
        if (circs[ci].dir[0]) {
            tl_remove_dir(circs[ci].dir);
            circs[ci].dir[0] = '\0';
        }
}

/* Emits every voice, then compiles the distinct ones while it computes
 * every reference run (the longest first); a voice whose C is the same as
 * another's gets a copy of that one's shared object. */
static void prepare(void) {
    double t0 = bench_now();
    int njobs = 0;
    for (int k = 0; k < npoints; k++)
        if ((points[k].kind == K_VOICE || points[k].kind == K_STRING) && voice_dir(&points[k]) == 0)
            jobs[njobs++] = (Job){J_EMIT, k, 0, 0, 0, 0};
    int nemit = njobs;
    bench_run_jobs(njobs, do_job, NULL, status);
    for (int k = 0; k < njobs; k++)
        points[jobs[k].point].emitted = status[k] == 0;
    find_twins();

    njobs = 0;
    for (int ci = 0; ci < NCIRCS; ci++)
        for (int d = 0; d < NAMPS; d++)
            jobs[njobs++] = (Job){J_REF, -1, ci, 0, d, 1};
    for (int r = NRATES - 1; r >= 0; r--)
        for (int ci = 0; ci < NCIRCS; ci++)
            for (int d = 0; d < NAMPS; d++)
                jobs[njobs++] = (Job){J_REF, -1, ci, r, d, 0};
    int nrefs = njobs;
    for (int k = 0; k < npoints; k++)
        if (points[k].emitted && points[k].twin < 0)
            jobs[njobs++] = (Job){J_COMPILE, k, 0, 0, 0, 0};
    printf("preparing: %d voices emitted, %d distinct ones to compile, %d reference runs\n", nemit,
           njobs - nrefs, nrefs);
    fflush(stdout);
    bench_run_jobs(njobs, do_job, NULL, status);
    for (int k = nrefs; k < njobs; k++)
        points[jobs[k].point].built = status[k] == 0;
    for (int k = 0; k < npoints; k++) {
        Point *p = &points[k];
        char c1[256], so1[256], c2[256], so2[256];
        if (p->emitted && p->twin >= 0 && points[p->twin].built &&
            voice_paths(&points[p->twin], c1, so1) == 0 && voice_paths(p, c2, so2) == 0)
            p->built = copy_file(so1, so2) == 0;
    }
    printf("prepared in %.1f s\n\n", bench_now() - t0);
}

/* ---- circuits: one interface over voices and peers ---- */

typedef struct Runner Runner;
struct Runner {
    void (*run)(Runner *r, const double *in, double *out, int n); /* n <= BLOCK */
    const Point *p;
    const wdv_class *cls;
    void *st;
    void *lane[LANES]; /* a batched point's instances */
    int oid;
    const double *ins[MAXIO];
    double *outs[MAXIO];
    double *scratch[MAXIO]; /* the voice's other outputs */
    const faust_peer *fp;
    void *dsp;
    handrc rc;
    handclip clip;
};

static void run_voice(Runner *r, const double *in, double *out, int n) {
    for (int k = 0; k < r->cls->n_inputs; k++)
        r->ins[k] = in;
    r->outs[r->oid] = out;
    r->cls->process(r->st, r->ins, r->outs, n);
}

/* LANES instances by process_batch, each with the same drive; lane 0's
 * output goes to out */
static void run_lanes(Runner *r, const double *in, double *out, int n) {
    const double *const *ip[LANES];
    double *const *op[LANES];
    for (int k = 0; k < r->cls->n_inputs; k++)
        r->ins[k] = in;
    for (int l = 0; l < LANES; l++) {
        ip[l] = r->ins;
        op[l] = r->outs;
    }
    r->cls->process_batch(r->lane, LANES, ip, op, n);
    memcpy(out, r->outs[r->oid], sizeof(double) * (size_t)n);
}

static void run_faust(Runner *r, const double *in, double *out, int n) {
    double *ip = (double *)in; /* Faust reads its inputs only */
    r->fp->compute(r->dsp, n, &ip, &out);
}

static void run_handrc(Runner *r, const double *in, double *out, int n) {
    handrc_process(&r->rc, in, out, n);
}

static void run_handclip(Runner *r, const double *in, double *out, int n) {
    handclip_process(&r->clip, in, out, n);
}

/* A fresh instance of the point's circuit at its rate.  Returns 0, or -1. */
static int runner_start(Runner *r) {
    const Point *p = r->p;
    const Circ *c = &circs[p->circ];
    double fs = rates[p->rate];
    switch (p->kind) {
    case K_VOICE:
        tl_state_free(r->st);
        r->st = tl_state_new(r->cls, fs);
        r->run = p->lanes ? run_lanes : run_voice; /* a batch's accuracy is its lane 0's */
        for (int l = 0; l < LANES; l++)
            tl_state_free(r->lane[l]);
        memset(r->lane, 0, sizeof r->lane);
        for (int l = 0; p->lanes && l < LANES; l++)
            if (!(r->lane[l] = tl_state_new(r->cls, fs)))
                return -1;
        return r->st ? 0 : -1;
    case K_FAUST:
        if (!r->dsp)
            r->dsp = r->fp->new_dsp();
        if (!r->dsp)
            return -1;
        r->fp->init(r->dsp, (int)fs);
        r->run = run_faust;
        return 0;
    case K_HANDRC:
        handrc_init(&r->rc, c->r, c->c, fs);
        r->run = run_handrc;
        return 0;
    case K_HANDCLIP:
        handclip_init(&r->clip, c->r, c->c, c->is, c->nvt, c->diodes == 2, fs);
        r->run = run_handclip;
        return 0;
    default:
        return -1;
    }
}

/* Opens the point's implementation.  Returns 0, or -1 after printing why. */
static int runner_open(Runner *r, Point *p) {
    memset(r, 0, sizeof *r);
    r->p = p;
    if (p->kind == K_FAUST)
        r->fp = circs[p->circ].faust[p->single];
    if (p->kind != K_VOICE)
        return 0;
    if (!p->built || tl_voice_load(&p->v) != 0)
        return -1;
    r->cls = p->v.cls;
    const Circuit *c = circs[p->circ].cir;
    if (r->cls->n_inputs != c->ninputs || r->cls->n_outputs != c->nouts || c->nouts > MAXIO) {
        fprintf(stderr, "chart: %s: the voice's ports differ from the netlist's\n", p->name);
        return -1;
    }
    r->oid = circs[p->circ].out;
    for (int k = 0; k < r->cls->n_outputs; k++) {
        r->scratch[k] = calloc(BLOCK, sizeof(double));
        if (!r->scratch[k])
            return -1;
        r->outs[k] = r->scratch[k];
    }
    return 0;
}

static void runner_close(Runner *r) {
    tl_state_free(r->st);
    for (int l = 0; l < LANES; l++)
        tl_state_free(r->lane[l]);
    if (r->dsp)
        r->fp->delete_dsp(r->dsp);
    for (int k = 0; k < MAXIO; k++)
        free(r->scratch[k]);
    memset(r, 0, sizeof *r);
}

typedef struct Timed {
    Runner *r;
    const double *drive;
    long len, pos;
    double out[BLOCK];
} Timed;

static void render_circuit(void *ctx, long nblocks) {
    Timed *t = ctx;
    for (long b = 0; b < nblocks; b++) {
        t->r->run(t->r, t->drive + t->pos, t->out, BLOCK);
        t->pos += BLOCK;
        if (t->pos + BLOCK > t->len)
            t->pos = 0;
    }
}

static int all_finite(const double *y, long n) {
    for (long k = 0; k < n; k++)
        if (!isfinite(y[k]))
            return 0;
    return 1;
}

/* Renders n frames of `in` from a fresh instance into y.  Returns 0, or
 * -1 if it cannot start. */
static int render_fresh(Runner *r, const double *in, double *y, long n) {
    if (runner_start(r) != 0)
        return -1;
    for (long pos = 0; pos < n; pos += BLOCK)
        r->run(r, in + pos, y + pos, n - pos < BLOCK ? (int)(n - pos) : BLOCK);
    return 0;
}

static void measure_circuit(Point *p, double seconds) {
    Runner r;
    double fs = rates[p->rate];
    Circ *c = &circs[p->circ];
    long N = err_frames(p->rate);
    long lag = p->kind == K_FAUST ? c->faust_lag : 0; /* taken out before comparing */
    long len = (long)fs / BLOCK * BLOCK; /* 1 s of the drive, 440 whole periods */
    long dl = len > N + lag ? len : N + lag;
    double *drive[NAMPS] = {NULL}, *y = malloc(sizeof(double) * (size_t)(N + lag));
    if (runner_open(&r, p) != 0 || !y)
        goto out;
    for (int d = 0; d < NAMPS; d++) {
        drive[d] = malloc(sizeof(double) * (size_t)dl);
        if (!drive[d])
            goto out;
        for (long n = 0; n < dl; n++)
            drive[d][n] = amps[d] * sin(2.0 * M_PI * SINE_HZ * (double)n / fs);
    }
    Timed t = {&r, drive[NAMPS - 1], len, 0, {0}};
    if (runner_start(&r) != 0)
        goto out;
    /* a batch: ns per voice-sample */
    p->ns = bench_measure(render_circuit, &t, p->lanes ? BLOCK * p->lanes : BLOCK, RUNS, WARMUP_S, seconds);
    p->finite = all_finite(t.out, BLOCK);
    for (int d = 0; d < NAMPS; d++) {
        if (render_fresh(&r, drive[d], y, N + lag) != 0)
            goto out;
        p->finite &= all_finite(y, N + lag);
        if (c->ref_ok[ref_slot(p->rate, d, 1)])
            p->err[d] = rel_rms_error(y + lag, c->ref[p->rate][d][1], N);
        if (c->ref_ok[ref_slot(p->rate, d, 0)])
            p->solver_err[d] = rel_rms_error(y + lag, c->ref[p->rate][d][0], N);
    }
    if (p->kind == K_HANDCLIP && r.clip.maxed)
        printf("  (%s: Newton's iteration hit its cap at %ld samples)\n", p->name, r.clip.maxed);
    p->ok = 1;
out:
    for (int d = 0; d < NAMPS; d++)
        free(drive[d]);
    free(y);
    runner_close(&r);
}

/* ---- strings: our plucked string and STK's ---- */

typedef struct Pluck {
    const Point *p;
    const wdv_class *cls;
    void *st;
    int pid, oid;
    struct stkp *stk;
    double f0, fs;
    long pos; /* frames since the first pluck */
    double in[BLOCK], zeros[BLOCK];
    double *outs[MAXIO];
    double *scratch[MAXIO]; /* the voice's other outputs */
    double out[BLOCK];
} Pluck;

/* A fresh string at f0, plucked at its first frame.  Returns 0, or -1. */
static int pluck_start(Pluck *s, double f0) {
    s->f0 = f0;
    s->pos = 0;
    if (s->p->kind == K_STK) {
        stkp_free(s->stk);
        stkp_set_rate(s->fs);
        s->stk = stkp_new(STK_LOWEST, 1u);
        if (!s->stk)
            return -1;
        stkp_note_on(s->stk, f0, 1.0);
        return 0;
    }
    tl_state_free(s->st);
    s->st = tl_state_new(s->cls, s->fs);
    return s->st && s->cls->set_param(s->st, s->pid, f0) == 0 ? 0 : -1;
}

/* n <= BLOCK frames of the string into y, plucked again every REPLUCK_S
 * if repluck. */
static void pluck_render(Pluck *s, double *y, int n, int repluck) {
    long period = (long)(REPLUCK_S * s->fs);
    long at = (period - s->pos % period) % period; /* frames to the next pluck */
    int pluck = (s->pos == 0 || repluck) && at < n;
    if (s->p->kind == K_STK) {
        int done = 0;
        if (pluck && s->pos > 0) {
            done = (int)at;
            stkp_tick(s->stk, y, done);
            stkp_note_on(s->stk, s->f0, 1.0);
        }
        stkp_tick(s->stk, y + done, n - done);
    } else {
        const double *in[MAXIO] = {NULL};
        if (pluck)
            s->in[at] = 1.0; /* N, for one sample */
        for (int k = 0; k < s->cls->n_inputs; k++)
            in[k] = k == 0 ? s->in : s->zeros;
        s->outs[s->oid] = y;
        s->cls->process(s->st, in, s->outs, n);
        if (pluck)
            s->in[at] = 0.0;
    }
    s->pos += n;
}

static void render_string(void *ctx, long nblocks) {
    Pluck *s = ctx;
    for (long b = 0; b < nblocks; b++)
        pluck_render(s, s->out, BLOCK, 1);
}

/* Opens our string's voice: input f, param f0, output vel.  Returns 0,
 * or -1 after printing why. */
static int pluck_open(Pluck *s, Point *p) {
    if (!p->built || tl_voice_load(&p->v) != 0)
        return -1;
    s->cls = p->v.cls;
    s->pid = tl_param_id(s->cls, "f0");
    s->oid = tl_output_id(s->cls, "vel");
    if (s->cls->n_inputs < 1 || strcmp(s->cls->inputs[0].name, "f") != 0 || s->pid < 0 || s->oid < 0 ||
        s->cls->n_inputs > MAXIO || s->cls->n_outputs > MAXIO) {
        fprintf(stderr, "chart: %s: needs an input f, a param f0 and an output vel\n", pluck_netlist);
        return -1;
    }
    for (int k = 0; k < s->cls->n_outputs; k++)
        if (!(s->outs[k] = s->scratch[k] = calloc(BLOCK, sizeof(double))))
            return -1;
    return 0;
}

/* The worst |cents| of partials 1..NPARTIALS after one pluck at f0. */
static double tuning(Pluck *s, double f0, double *y, long n, int *finite) {
    if (pluck_start(s, f0) != 0)
        return NAN;
    for (long i = 0; i < n; i += BLOCK)
        pluck_render(s, y + i, (int)(n - i < BLOCK ? n - i : BLOCK), 0);
    if (!all_finite(y, n)) {
        *finite = 0;
        return NAN;
    }
    double worst = 0;
    for (int k = 1; k <= NPARTIALS; k++) {
        double f = pt_peak_freq(y, (size_t)n, s->fs, (k - 0.3) * f0, (k + 0.3) * f0);
        double e = fabs(pt_cents(f, k * f0));
        if (!(e <= worst))
            worst = e; /* a missing partial (NAN) is the worst */
    }
    return worst;
}

static void measure_string(Point *p, double seconds) {
    Pluck *s = calloc(1, sizeof *s);
    long n = (long)(TUNE_S * rates[p->rate]);
    double *y = malloc(sizeof(double) * (size_t)n);
    if (!s || !y)
        goto out;
    s->p = p;
    s->fs = rates[p->rate];
    if (p->kind == K_STRING && pluck_open(s, p) != 0)
        goto out;
    p->finite = 1;
    p->cents = 0;
    for (int k = 0; k < NTUNE; k++) {
        double e = tuning(s, tune_f0[k], y, n, &p->finite);
        if (!(e <= p->cents))
            p->cents = e;
    }
    if (pluck_start(s, PLUCK_F0) != 0)
        goto out;
    p->ns = bench_measure(render_string, s, BLOCK, RUNS, WARMUP_S, seconds);
    p->finite &= all_finite(s->out, BLOCK);
    p->ok = 1;
out:
    if (s) {
        tl_state_free(s->st);
        stkp_free(s->stk);
        for (int k = 0; k < MAXIO; k++)
            free(s->scratch[k]);
    }
    free(s);
    free(y);
}

/* ---- output ---- */

static const char *circuit_ref = "refsim at 12.288 MHz (converged trapezoidal)";
static const char *string_ref = "n f0 for n = 1..4 and f0 = 110/440/1760 Hz";

static void fmt_db(char *buf, size_t cap, double e) {
    if (e < 0 || !isfinite(e))
        snprintf(buf, cap, "-");
    else
        snprintf(buf, cap, "%.1f", tl_db(e));
}

static void print_header(void) {
    printf("%-34s %10s  %-22s %-22s\n", "point", "ns/sample", "error 1 V (solver)", "error 10 V (solver)");
    printf("%-34s %10s  %-22s %-22s\n", "----------------------------------", "----------",
           "----------------------", "----------------------");
}

static void print_point(const Point *p) {
    if (!p->ok) {
        printf("%-34s %10s\n", p->name, "failed");
    } else if (p->circ < 0) {
        printf("%-34s %10.2f  %.3f cents (worst partial)%s\n", p->name, p->ns, p->cents,
               p->finite ? "" : "  non-finite output!");
    } else {
        char e[NAMPS][80];
        for (int d = 0; d < NAMPS; d++) {
            char a[32], b[32];
            fmt_db(a, sizeof a, p->err[d]);
            fmt_db(b, sizeof b, p->solver_err[d]);
            snprintf(e[d], sizeof e[d], "%s dB (%s)", a, b);
        }
        printf("%-34s %10.2f  %-22s %-22s%s\n", p->name, p->ns, e[0], e[1],
               p->finite ? "" : "  non-finite output!");
    }
    fflush(stdout);
}

static void csv_row(FILE *f, const Point *p, const char *drive, double err, double serr) {
    char e[32] = "", s[32] = "", cents[32] = "";
    if (p->circ >= 0) {
        if (err >= 0)
            snprintf(e, sizeof e, "%.2f", tl_db(err));
        if (serr >= 0)
            snprintf(s, sizeof s, "%.2f", tl_db(serr));
    } else if (isfinite(p->cents)) {
        snprintf(cents, sizeof cents, "%.4g", p->cents);
    }
    const char *family = p->kind == K_VOICE || p->kind == K_STRING ? "ours" : "peer";
    const char *ref = p->circ >= 0 ? circuit_ref : string_ref;
    fprintf(f, "%s,%s,%s,%s,%.0f,%s,%.3f,%s,%s,%s,%s,%s,%s\n", p->name, family, model_name(p), solver_name(p),
            rates[p->rate], p->single ? "float" : "double", p->ns, e, cents, ref, impl_name(p->kind), drive, s);
}

static int write_csv(const char *path) {
    FILE *f = fopen(path, "w");
    if (!f) {
        fprintf(stderr, "chart: cannot write %s: %s\n", path, strerror(errno));
        return -1;
    }
    fprintf(f, "name,family,model,solver,rate,precision,ns_per_sample,error_db,error_cents,reference,impl,"
               "drive,solver_error_db\n");
    for (int k = 0; k < npoints; k++) {
        const Point *p = &points[k];
        if (!p->ok || !p->finite)
            continue;
        if (p->circ < 0) {
            csv_row(f, p, "pluck", 0, 0);
            continue;
        }
        for (int d = 0; d < NAMPS; d++) {
            char drive[32];
            snprintf(drive, sizeof drive, "sine %g V", amps[d]);
            csv_row(f, p, drive, p->err[d], p->solver_err[d]);
        }
    }
    return fclose(f) == 0 ? 0 : -1;
}

int main(int argc, char **argv) {
    double seconds = 0.1;
    const char *csv = "out/chart.csv";
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "-t") && i + 1 < argc)
            seconds = atof(argv[++i]);
        else if (!strcmp(argv[i], "-o") && i + 1 < argc)
            csv = argv[++i];
        else
            seconds = -1;
    }
    if (!(seconds > 0)) {
        fprintf(stderr, "usage: chart [-t SECONDS] [-o OUT.csv]\n");
        return 2;
    }
    printf("wdc chart: speed against accuracy of our voices and their peers, in one run\n");
    char faust[256];
    bench_first_line("faust --version 2>/dev/null", faust, sizeof faust);
    printf("peers:    %s wdmodels.lib (faust -lang c; -double for double) and C by hand, compiled\n"
           "          by the Makefile with the voices' flags; STK's Plucked (libstk) through g++ -O2\n",
           faust);
    bench_print_setup(CFLAGS);
    printf("ns/sample: one instance, blocks of %d frames, best of %d runs of >= %.2g s after %.2g s;\n"
           "  circuits driven by a %.0f Hz sine of %g V, strings at f0 = %.0f Hz plucked every %.0f s.\n",
           BLOCK, RUNS, seconds, WARMUP_S, SINE_HZ, amps[NAMPS - 1], PLUCK_F0, REPLUCK_S);
    printf("circuits: dB of the relative RMS error of v(out) over %.2g s of a %.0f Hz sine against\n"
           "  %s; in brackets against refsim at the same rate (the solver's own error).\n",
           ERR_S, SINE_HZ, circuit_ref);
    printf("strings:  the worst tuning error in cents of partials n = 1..%d, %s.\n\n", NPARTIALS,
           "f0 = 110, 440 and 1760 Hz");
    fflush(stdout);

    int loaded = load_circuits() == 0;
    if (loaded) {
        list_points();
        prepare();
    }
    remove_circuit_dirs();
    if (!loaded)
        return 1;
    print_header();
    int failed = 0;
    double t0 = bench_now();
    for (int k = 0; k < npoints; k++) {
        Point *p = &points[k];
        if (p->circ >= 0)
            measure_circuit(p, seconds);
        else
            measure_string(p, seconds);
        print_point(p);
        failed |= !p->ok || !p->finite;
        tl_voice_free(&p->v);
    }
    printf("\nmeasured %d points in %.1f s\n", npoints, bench_now() - t0);
    if (write_csv(csv) != 0)
        return 1;
    printf("wrote %s\n", csv);
    return failed;
}
