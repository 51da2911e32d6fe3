/*
 * nlbench.c - speed against accuracy of the voices with nonlinear elements.
 *
 *     build/bench/nlbench [-t SECONDS] NETLIST.wdn...
 *
 * Of the netlists given, those with nonlinear elements (E_NL) are measured;
 * the others are passed over.  For each of them, each solver that applies
 * to its nonlinear elements (diodes: fast, newton, omega, and pwl with tables of
 * 64, 256, 1024 and 4096 points; curves given by points: their exact pwl
 * map; contacts alone: newton) and each rate of 48, 96 and 192 kHz:
 *
 *   - bin/wdc ($WDC overrides the path) emits the voice with --rate and the
 *     solver's flags into a temporary directory, from a copy of the netlist
 *     without its solver= keys so that the command line's choice applies;
 *     $CC (default cc) compiles it into a shared object with -O2
 *     -march=native, and the runtime loads it (wdrt_voice_open).
 *   - Speed: one instance renders blocks of 64 frames.  A voice with inputs
 *     gets a 440 Hz sine of amplitude 10 (V, or the input's unit) on every
 *     input; a voice without inputs is reset, which applies its .ic strike,
 *     every 20 ms.  After a warm-up of 0.05 s, the best of 3 runs of at
 *     least SECONDS (default 0.3) of wall time gives ns per sample.
 *   - Accuracy: a fresh instance renders 0.1 s (the sine at amplitude 1
 *     and at 10, or one strike), compared with two runs of refsim
 *     (tests/refsim.h) on the same input, when refsim can simulate the
 *     netlist:
 *       converged:  refsim at the same rate: the same trapezoidal equations
 *                   solved to convergence, so the error is the solver's;
 *       continuous: refsim at 64 times the rate, standing for the
 *                   continuous-time solution, compared at the voice's
 *                   sample instants: sample n of a run at rate fs is at time
 *                   n/fs, so voice sample n meets the fine run's sample
 *                   64 n.  Both runs start from the netlist's initial state
 *                   at time -1/fs (the voice's sample -1), the fine run
 *                   stepping 63 times before time 0, and the sine is
 *                   evaluated at the fine run's own instants (0 before
 *                   time 0).  The error includes the discretisation's.
 *     Each error is 20 log10 of the relative RMS error over the run,
 *     sqrt(sum (y - r)^2 / sum r^2) (the RMS of y if r is all zero), the
 *     worst over the voice's outputs; the output is named after the figure.
 *
 * Before a netlist is measured, all its voices are built and all its
 * reference runs computed, as many at a time as there are processors
 * (the references in memory shared with the processes that compute them);
 * the measurements then run one at a time.
 *
 * A benchmark, not a test: the exit status is non-zero only if a voice
 * could not be built or loaded, or produced a non-finite sample.
 */
#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>

#include "benchlib.h"
#include "gen.h"
#include "wdrt.h"
#include "wdvoice.h"
#include "../tests/refsim.h"
#include "../tests/testlib.h"

#define BLOCK 64
#define RUNS 3
#define WARMUP_S 0.05
#define ERR_S 0.1     /* seconds of signal in the accuracy runs */
#define STRIKE_S 0.02 /* frames between resets of a voice without inputs */
#define SINE_HZ 440.0
#define FINE 64       /* the continuous reference's rate over the voice's */
#define MAXIO 16
#define CFLAGS "-O2 -march=native"

static const double rates[] = {48000.0, 96000.0, 192000.0};
#define NRATES ((int)(sizeof rates / sizeof rates[0]))

/* The drives of the accuracy runs; the last one is the one timed. */
static const double amps[] = {1.0, 10.0};
#define NAMPS ((int)(sizeof amps / sizeof amps[0]))

typedef struct SolverCase {
    const char *label;
    const char *args[5];
} SolverCase;

static const SolverCase diode_cases[] = {
    {"fast", {"--solver", "fast", NULL}},
    {"newton", {"--solver", "newton", NULL}},
    {"omega", {"--solver", "omega", NULL}},
    {"pwl 64", {"--solver", "pwl", "--table", "64", NULL}},
    {"pwl 256", {"--solver", "pwl", "--table", "256", NULL}},
    {"pwl 1024", {"--solver", "pwl", "--table", "1024", NULL}},
    {"pwl 4096", {"--solver", "pwl", "--table", "4096", NULL}},
};
static const SolverCase curve_cases[] = {
    {"pwl", {"--solver", "pwl", NULL}},
};
static const SolverCase contact_cases[] = {
    {"newton", {"--solver", "newton", NULL}},
};

/* ---- the netlist ---- */

typedef struct NlKinds {
    int diodes, curves, contacts;
    int fixed; /* nonlinear elements that name their solver */
} NlKinds;

static NlKinds nl_kinds(const Circuit *c) {
    NlKinds k = {0, 0, 0, 0};
    for (int e = 0; e < c->nelems; e++) {
        const Elem *el = &c->elems[e];
        if (el->kind != E_NL || !el->nl)
            continue;
        if (el->nl->kind == NL_DIODE)
            k.diodes++;
        else if (el->nl->kind == NL_CURVE)
            k.curves++;
        else
            k.contacts++;
        if (el->nl->solver != SOLVER_DEFAULT && el->nl->kind == NL_DIODE)
            k.fixed++;
    }
    return k;
}

/* ---- voices ---- */

typedef struct Built {
    tl_voice v; /* v.dir: temporary directory; "" if it could not be made */
    int ok;     /* emitted and compiled */
} Built;

/* Makes the voice's directory with the netlist's text written into it
 * without its solver= keys.  Returns 0, or -1 after printing what failed. */
static int voice_dir(const char *text, Built *b) {
    memset(b, 0, sizeof *b);
    snprintf(b->v.dir, sizeof b->v.dir, "/tmp/wdc-nlbench-XXXXXX");
    if (!mkdtemp(b->v.dir)) {
        fprintf(stderr, "nlbench: mkdtemp: %s\n", strerror(errno));
        b->v.dir[0] = '\0';
        return -1;
    }
    char src[128];
    snprintf(src, sizeof src, "%s/netlist.wdn", b->v.dir);
    if (bench_drop_solver_keys(text, src) < 0) {
        fprintf(stderr, "nlbench: cannot write %s\n", src);
        return -1;
    }
    return 0;
}

/* Emits the voice in dir at rate fs with the solver's flags and compiles
 * it (tl_voice_make; $WDC overrides bin/wdc).  Returns 0, or -1 after
 * printing what failed. */
static int voice_make(const char *netlist, const char *dir, const SolverCase *sc, double fs) {
    char src[128], rate[32];
    snprintf(src, sizeof src, "%s/netlist.wdn", dir);
    snprintf(rate, sizeof rate, "%.0f", fs);
    const char *args[8];
    int n = 0;
    args[n++] = "--rate";
    args[n++] = rate;
    for (int k = 0; sc->args[k] && n < 7; k++)
        args[n++] = sc->args[k];
    args[n] = NULL;
    if (tl_voice_make(src, dir, args, CFLAGS) != 0) {
        fprintf(stderr, "nlbench: %s --rate %s, solver %s: the voice could not be built\n", netlist,
                rate, sc->label);
        return -1;
    }
    return 0;
}

/* ---- speed ---- */

typedef struct Timed {
    const wdv_class *cls;
    void *st;
    const double *drive; /* cycled on every input; NULL without inputs */
    long len;            /* frames of drive, or between resets */
    long pos;
    const double *in[MAXIO];
    double *out[MAXIO];
} Timed;

static void render_blocks(void *ctx, long nblocks) {
    Timed *v = ctx;
    const wdv_class *cls = v->cls;
    for (long b = 0; b < nblocks; b++) {
        if (v->drive) {
            for (int k = 0; k < cls->n_inputs; k++)
                v->in[k] = v->drive + v->pos;
        } else if (v->pos == 0) {
            cls->reset(v->st);
        }
        cls->process(v->st, v->in, v->out, BLOCK);
        v->pos += BLOCK;
        if (v->pos + BLOCK > v->len)
            v->pos = 0;
    }
}

/* ---- accuracy ---- */

/* sqrt(sum (a-b)^2 / sum b^2); the RMS of a if b is all zero. */
static double rel_rms(const double *a, const double *b, long n) {
    long double num = 0, den = 0;
    for (long k = 0; k < n; k++) {
        long double d = (long double)a[k] - b[k];
        num += d * d;
        den += (long double)b[k] * b[k];
    }
    if (den == 0)
        return n > 0 ? (double)sqrtl(num / n) : 0.0;
    return (double)sqrtl(num / den);
}

/* Renders nframes of a fresh instance at fs, every input driven by `in`
 * (NULL: no inputs).  Returns 0, or -1 if a sample is not finite. */
static int render_voice(const wdv_class *cls, double fs, const double *in, long nframes, double **out) {
    void *st = tl_state_new(cls, fs);
    if (!st)
        return -1;
    const double *ip[MAXIO];
    double *op[MAXIO];
    for (long pos = 0; pos < nframes; pos += BLOCK) {
        int n = nframes - pos < BLOCK ? (int)(nframes - pos) : BLOCK;
        for (int k = 0; k < cls->n_inputs; k++)
            ip[k] = in + pos;
        for (int k = 0; k < cls->n_outputs; k++)
            op[k] = out[k] + pos;
        cls->process(st, ip, op, n);
    }
    tl_state_free(st);
    for (int k = 0; k < cls->n_outputs; k++)
        for (long n = 0; n < nframes; n++)
            if (!isfinite(out[k][n]))
                return -1;
    return 0;
}

/* Runs refsim of c at fs * fine over nframes coarse samples, starting
 * fine - 1 steps before time 0 (so from the state at time -1/fs), every
 * input the sine of amplitude amp at the fine instants (0 before time 0);
 * out[k][n] gets output k at time n/fs.  The number of samples at which
 * Newton did not converge is added to *unconverged.  Returns 0, or -1. */
static int render_ref(const Circuit *c, double fs, int fine, double amp, long nframes, double **out,
                      long *unconverged) {
    double ffs = fs * fine;
    refsim *s = refsim_new(c, ffs, NULL);
    if (!s)
        return -1;
    double in[MAXIO], o[MAXIO];
    long total = nframes * fine + (fine - 1);
    for (long m = 0; m < total; m++) {
        long j = m - (fine - 1); /* fine sample index, 0 at time 0 */
        double x = j >= 0 ? amp * sin(2.0 * M_PI * SINE_HZ * (double)j / ffs) : 0.0;
        for (int k = 0; k < c->ninputs; k++)
            in[k] = x;
        refsim_step(s, in, o);
        if (j >= 0 && j % fine == 0)
            for (int k = 0; k < c->nouts; k++)
                out[k][j / fine] = o[k];
    }
    refsim_nl_info info;
    refsim_nl_stats(s, &info);
    *unconverged += info.unconverged;
    refsim_free(s);
    return 0;
}

/* ---- preparation: references and builds, in parallel ---- */

#define MAXCASES 7

/* Everything one netlist needs before the measurements: the voices of
 * every rate and solver, and the reference runs, in memory shared with
 * the processes that compute them. */
typedef struct Prep {
    const char *path;
    const Circuit *c;
    const SolverCase *cases;
    int ncases, ndrives, have_ref;
    Built built[NRATES][MAXCASES];
    /* [rate][drive][0: converged, 1: continuous]: output k at ref[...][k] */
    double *ref[NRATES][NAMPS][2][MAXIO];
    long *unconverged; /* shared, [rate][drive][2] */
    int *ref_ok;       /* shared, [rate][drive][2] */
    void *shared;
    size_t shared_size;
} Prep;

typedef struct Job {
    int kind; /* 0: a reference run, 1: a voice build */
    int r, d, w, s;
} Job;

static long err_frames(int r) { return (long)lround(ERR_S * rates[r]); }

static int slot(int r, int d, int w) { return (r * NAMPS + d) * 2 + w; }

static int do_job(Prep *p, const Job *j) {
    if (j->kind == 0) {
        int sl = slot(j->r, j->d, j->w);
        double amp = p->c->ninputs ? amps[j->d] : 0.0;
        if (render_ref(p->c, rates[j->r], j->w ? FINE : 1, amp, err_frames(j->r), p->ref[j->r][j->d][j->w],
                       &p->unconverged[sl]) != 0)
            return 1;
        p->ref_ok[sl] = 1;
        return 0;
    }
    return voice_make(p->path, p->built[j->r][j->s].v.dir, &p->cases[j->s], rates[j->r]) == 0 ? 0 : 1;
}

typedef struct JobList {
    Prep *p;
    const Job *jobs;
} JobList;

static int run_job(void *ctx, int k) {
    JobList *l = ctx;
    return do_job(l->p, &l->jobs[k]);
}

/* Makes the voices' directories and the shared buffers, then builds every
 * voice and computes every reference.  Returns 0, or -1 (out of memory). */
static int prepare(Prep *p, const char *text) {
    size_t doubles = 0;
    for (int r = 0; r < NRATES; r++)
        doubles += (size_t)NAMPS * 2 * (size_t)p->c->nouts * (size_t)err_frames(r);
    size_t nslots = NRATES * NAMPS * 2;
    p->shared_size = doubles * sizeof(double) + nslots * (sizeof(long) + sizeof(int));
    p->shared = mmap(NULL, p->shared_size, PROT_READ | PROT_WRITE, MAP_SHARED | MAP_ANONYMOUS, -1, 0);
    if (p->shared == MAP_FAILED) {
        p->shared = NULL;
        return -1;
    }
    double *at = p->shared;
    for (int r = 0; r < NRATES; r++)
        for (int d = 0; d < NAMPS; d++)
            for (int w = 0; w < 2; w++)
                for (int k = 0; k < p->c->nouts; k++) {
                    p->ref[r][d][w][k] = at;
                    at += err_frames(r);
                }
    p->unconverged = (long *)(void *)at;
    p->ref_ok = (int *)(void *)(p->unconverged + nslots);

    Job jobs[NRATES * NAMPS * 2 + NRATES * MAXCASES];
    int status[NRATES * NAMPS * 2 + NRATES * MAXCASES];
    int njobs = 0;
    /* the longest first */
    if (p->have_ref)
        for (int w = 1; w >= 0; w--)
            for (int r = NRATES - 1; r >= 0; r--)
                for (int d = 0; d < p->ndrives; d++)
                    jobs[njobs++] = (Job){0, r, d, w, 0};
    for (int r = 0; r < NRATES; r++)
        for (int s = 0; s < p->ncases; s++)
            if (voice_dir(text, &p->built[r][s]) == 0)
                jobs[njobs++] = (Job){1, r, 0, 0, s};
    JobList list = {p, jobs};
    bench_run_jobs(njobs, run_job, &list, status);
    for (int k = 0; k < njobs; k++)
        if (jobs[k].kind == 1)
            p->built[jobs[k].r][jobs[k].s].ok = status[k] == 0;
        else if (status[k] != 0)
            p->ref_ok[slot(jobs[k].r, jobs[k].d, jobs[k].w)] = 0;
    return 0;
}

static void prep_free(Prep *p) {
    for (int r = 0; r < NRATES; r++)
        for (int s = 0; s < p->ncases; s++)
            tl_voice_free(&p->built[r][s].v);
    if (p->shared)
        munmap(p->shared, p->shared_size);
    p->shared = NULL;
}

/* ---- the table ---- */

#define MAXNOTES 64
static char notes[MAXNOTES][256];
static int nnotes;
static int name_width = 14;

static void add_note(const char *fmt, const char *a, const char *b) {
    if (nnotes < MAXNOTES)
        snprintf(notes[nnotes++], sizeof notes[0], fmt, a, b);
}

static void fmt_db(char *buf, size_t cap, double e, const char *out) {
    if (!(e >= 0))
        snprintf(buf, cap, "nan");
    else if (e == 0)
        snprintf(buf, cap, "-inf %s", out);
    else
        snprintf(buf, cap, "%.1f %s", 20.0 * log10(e), out);
}

static void print_row(const char *net, const char *solver, double fs, const char *drive, const char *ns,
                      const char *conv, const char *cont) {
    printf("%-*s %-9s %6.0f  %-10s %9s  %-16s %s\n", name_width, net, solver, fs, drive, ns, conv, cont);
    fflush(stdout);
}

/* The worst relative RMS error over the outputs, and its output. */
static double worst(double **y, double *const *r, int nouts, long n, int *which) {
    double w = -1;
    *which = 0;
    for (int k = 0; k < nouts; k++) {
        double e = rel_rms(y[k], r[k], n);
        if (!(e <= w)) {
            w = e;
            *which = k;
        }
    }
    return w;
}

/* Measures one voice: its speed, then its accuracy on every drive, and
 * prints its rows.  Returns 0, or 1 if it failed. */
static int measure_voice(Prep *p, const char *label, int r, int s, double seconds) {
    const Circuit *c = p->c;
    const SolverCase *sc = &p->cases[s];
    double fs = rates[r];
    Built *b = &p->built[r][s];
    if (!b->ok || tl_voice_load(&b->v) != 0) {
        print_row(label, sc->label, fs, "-", "failed", "-", "-");
        return 1;
    }
    const wdv_class *cls = b->v.cls;
    if (cls->n_inputs != c->ninputs || cls->n_outputs != c->nouts) {
        fprintf(stderr, "nlbench: %s: the voice's ports differ from the netlist's\n", p->path);
        print_row(label, sc->label, fs, "-", "failed", "-", "-");
        return 1;
    }
    long N = err_frames(r);
    /* a voice with inputs cycles 1 s of the drive (a whole number of
     * periods); one without is reset every STRIKE_S */
    long len = (long)lround(c->ninputs ? fs : STRIKE_S * fs) / BLOCK * BLOCK;
    if (len < BLOCK)
        len = BLOCK;
    long dl = len > N ? len : N;
    double *drive[NAMPS] = {NULL};
    double **y = tl_bufs_new(c->nouts, N);
    int failed = 0, finite = 1;
    if (!y)
        goto oom;
    if (c->ninputs)
        for (int d = 0; d < p->ndrives; d++) {
            drive[d] = malloc(sizeof(double) * (size_t)dl);
            if (!drive[d])
                goto oom;
            for (long n = 0; n < dl; n++)
                drive[d][n] = amps[d] * sin(2.0 * M_PI * SINE_HZ * (double)n / fs);
        }

    /* speed, on the last drive */
    Timed tv = {0};
    tv.cls = cls;
    tv.st = tl_state_new(cls, fs);
    tv.drive = c->ninputs ? drive[p->ndrives - 1] : NULL;
    tv.len = len;
    for (int k = 0; k < c->nouts; k++)
        tv.out[k] = y[k];
    if (!tv.st)
        goto oom;
    double ns = bench_measure(render_blocks, &tv, BLOCK, RUNS, WARMUP_S, seconds);
    for (int k = 0; k < c->nouts; k++)
        for (int n = 0; n < BLOCK; n++)
            if (!isfinite(y[k][n]))
                finite = 0;
    tl_state_free(tv.st);

    /* accuracy, on every drive, the timed one first */
    for (int d = p->ndrives - 1; d >= 0; d--) {
        char dname[32], nsbuf[32], cv[64] = "n/a", ct[64] = "n/a";
        if (c->ninputs)
            snprintf(dname, sizeof dname, "sine %g %.8s", amps[d], cls->inputs[0].unit);
        else
            snprintf(dname, sizeof dname, "strike");
        if (d == p->ndrives - 1)
            snprintf(nsbuf, sizeof nsbuf, "%.1f", ns);
        else
            nsbuf[0] = '\0';
        if (render_voice(cls, fs, drive[d], N, y) != 0)
            finite = 0;
        if (p->ref_ok[slot(r, d, 0)]) {
            int w;
            double e = worst(y, p->ref[r][d][0], c->nouts, N, &w);
            fmt_db(cv, sizeof cv, e, c->outs[w].name);
        }
        if (p->ref_ok[slot(r, d, 1)]) {
            int w;
            double e = worst(y, p->ref[r][d][1], c->nouts, N, &w);
            fmt_db(ct, sizeof ct, e, c->outs[w].name);
        }
        print_row(label, sc->label, fs, dname, nsbuf, cv, ct);
    }
    if (!finite) {
        char what[128];
        snprintf(what, sizeof what, "%s at %.0f Hz", sc->label, fs);
        add_note("%s, %s: the voice produced a non-finite sample", label, what);
        failed = 1;
    }
    goto out;
oom:
    fprintf(stderr, "nlbench: out of memory\n");
    failed = 1;
out:
    for (int d = 0; d < NAMPS; d++)
        free(drive[d]);
    tl_bufs_free(y, c->nouts);
    return failed;
}

/* Benchmarks one netlist; returns 0, or 1 if a voice failed. */
static int bench_netlist(const char *path, double seconds) {
    Circuit *c = wdc_load(path);
    if (!c) {
        fprintf(stderr, "nlbench: %s: cannot load\n", path);
        return 1;
    }
    NlKinds kinds = nl_kinds(c);
    if (kinds.diodes + kinds.curves + kinds.contacts == 0)
        return 0;
    char label[64];
    bench_label(path, label, sizeof label);
    if (c->nwgs) { /* only contacts, solved by Newton; no reference simulates a string */
        add_note("%s: %s", label, "strings or tubes: its speed is in bench, its accuracy in tests/test_waveguide.c");
        return 0;
    }
    if (c->ninputs > MAXIO || c->nouts > MAXIO || c->nouts < 1) {
        add_note("%s: %s", label, "no outputs, or more than 16 inputs or outputs: not measured");
        return 0;
    }
    char *text = read_file(path, NULL);
    if (!text) {
        fprintf(stderr, "nlbench: cannot read %s\n", path);
        return 1;
    }
    if (strstr(text, ".include"))
        add_note("%s: %s", label, "includes other files, which the copy without solver= keys may not find");
    if (kinds.fixed)
        add_note("%s: %s", label, "the netlist names its diodes' solver; dropped, so that --solver applies");

    static Prep p;
    memset(&p, 0, sizeof p);
    p.path = path;
    p.c = c;
    if (kinds.diodes) {
        p.cases = diode_cases;
        p.ncases = (int)(sizeof diode_cases / sizeof diode_cases[0]);
    } else if (kinds.curves) {
        p.cases = curve_cases;
        p.ncases = 1;
    } else {
        p.cases = contact_cases;
        p.ncases = 1;
    }
    p.ndrives = c->ninputs ? NAMPS : 1;
    p.have_ref = refsim_can_simulate(c);
    if (!p.have_ref)
        add_note("%s: %s", label, "refsim cannot simulate it (refsim_can_simulate): no error figures");
    if (prepare(&p, text) != 0) {
        fprintf(stderr, "nlbench: out of memory\n");
        prep_free(&p);
        return 1;
    }
    for (int r = 0; r < NRATES && p.have_ref; r++)
        for (int d = 0; d < p.ndrives; d++)
            for (int w = 0; w < 2; w++) {
                char what[160];
                int sl = slot(r, d, w);
                const char *run = w ? "64x-rate" : "same-rate";
                if (!p.ref_ok[sl]) {
                    snprintf(what, sizeof what, "%.0f Hz: the %s reference could not be computed", rates[r], run);
                    add_note("%s at %s", label, what);
                } else if (p.unconverged[sl]) {
                    snprintf(what, sizeof what, "%.0f Hz, drive %d: the %s reference did not converge at %ld samples",
                             rates[r], d + 1, run, p.unconverged[sl]);
                    add_note("%s at %s", label, what);
                }
            }
    int failed = 0;
    for (int r = 0; r < NRATES; r++)
        for (int s = 0; s < p.ncases; s++)
            failed |= measure_voice(&p, label, r, s, seconds);
    prep_free(&p);
    return failed;
}

int main(int argc, char **argv) {
    double seconds = 0.3;
    int first = 1;
    if (argc > 2 && !strcmp(argv[1], "-t")) {
        seconds = atof(argv[2]);
        first = 3;
    }
    if (first >= argc || !(seconds > 0)) {
        fprintf(stderr, "usage: nlbench [-t SECONDS] NETLIST.wdn...\n");
        return 2;
    }
    for (int i = first; i < argc; i++) {
        char label[64];
        bench_label(argv[i], label, sizeof label);
        if ((int)strlen(label) > name_width)
            name_width = (int)strlen(label);
    }

    printf("wdc nonlinear benchmark: speed against accuracy of the voices with nonlinear elements\n");
    bench_print_setup(CFLAGS);
    printf("ns/sample: one voice, blocks of %d frames, best of %d runs of >= %.2g s after a %.2g s warm-up,\n"
           "  driven by a %.0f Hz sine of amplitude %g (V, or the input's unit) on every input; a voice\n"
           "  without inputs is reset (its .ic strike) every %.0f ms.\n",
           BLOCK, RUNS, seconds, WARMUP_S, SINE_HZ, amps[NAMPS - 1], STRIKE_S * 1e3);
    printf("dB: 20 log10 of the relative RMS error sqrt(sum (y - r)^2 / sum r^2) over %.2g s from a fresh\n"
           "  voice (one strike, or each sine), the worst over its outputs (named after the figure),\n"
           "  against refsim (tests/refsim.h) on the same input:\n"
           "  vs converged:  refsim at the same rate: the trapezoidal equations solved to convergence,\n"
           "                 so the error is the solver's own;\n"
           "  vs continuous: refsim at %d x the rate, standing for the continuous-time solution, at the\n"
           "                 voice's instants: sample n of a run at rate fs is at time n/fs, so voice\n"
           "                 sample n meets fine sample %d n.  Both start from the initial state at time\n"
           "                 -1/fs (the voice's sample -1), the fine run taking %d steps before time 0;\n"
           "                 the sine is evaluated at the fine instants, 0 before time 0.\n\n",
           ERR_S, FINE, FINE, FINE - 1);
    printf("%-*s %-9s %6s  %-10s %9s  %-16s %s\n", name_width, "netlist", "solver", "rate", "drive",
           "ns/sample", "dB vs converged", "dB vs continuous");
    char dashes[80];
    int nd = name_width < 79 ? name_width : 79;
    memset(dashes, '-', (size_t)nd);
    dashes[nd] = '\0';
    printf("%s %-9s %6s  %-10s %9s  %-16s %s\n", dashes, "---------", "------", "----------", "---------",
           "----------------", "----------------");
    fflush(stdout);

    int failed = 0;
    for (int i = first; i < argc; i++)
        failed |= bench_netlist(argv[i], seconds);
    if (nnotes) {
        printf("\n");
        for (int k = 0; k < nnotes; k++)
            printf("note: %s\n", notes[k]);
    }
    return failed;
}
