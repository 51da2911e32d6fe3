/*
 * deckbench.c - the example SPICE decks' voices: speed, the Newton steps
 * of their joint solves, and accuracy, beside the single-diode solvers
 * of a diode pair.
 *
 *     build/bench/deckbench [-t SECONDS] NETLIST...
 *
 * (`make bench` gives it every deck in netlists/ and diode_clipper.wdn.)
 * For each netlist and each rate of 48, 96 and 192 kHz:
 *
 *   - bin/wdc ($WDC overrides the path) emits the voice with --rate into
 *     a temporary directory and $CC (default cc) compiles it into a
 *     shared object with -O2 -march=native, as tl_voice_build_args does;
 *     the runtime loads it.  A SPICE deck is built once per rate, its
 *     solver column "joint" if the voice has joint solves (solve_stats),
 *     else "default" (--solver does not apply to jointly solved roots).
 *     Any other netlist with diodes is built once per single-diode
 *     solver (--solver newton, omega, fast, and pwl with a table of 4096
 *     points), from a copy without its solver= keys so that the command
 *     line's choice applies, as nlbench does.
 *   - Drive: an input that one of the deck's sources drives gets that
 *     source's time function (SIN, PULSE, PWL, EXP) at the sample
 *     instants n/fs, as `wdc --render` without --input drives it; any
 *     other input a 440 Hz sine of amplitude 1 (V, or the input's unit),
 *     and, for a netlist that is not a deck, of amplitude 10 too: a row
 *     per drive.
 *   - Speed: one instance renders blocks of 64 frames of the drive, 1 s
 *     of it precomputed and cycled.  After a warm-up of 0.05 s, the best
 *     of 3 runs of at least SECONDS (default 0.3) of wall time gives ns
 *     per sample.
 *   - Newton steps: a fresh instance renders 0.1 s; a voice with joint
 *     solves (wdv_class.solve_stats) then gives its solves, their Newton
 *     steps and those stopped at the iteration cap (--maxit, 50): the
 *     steps per solve (their mean: the most one solve took is not
 *     counted by the voice), the solves per sample and the capped solves.
 *     A single-diode solver counts none ("-").
 *   - Accuracy: the same 0.1 s against refsim (tests/refsim.h) at the same
 *     rate on the same input: the same trapezoidal equations solved to
 *     convergence, so the error is the voice's solver's own.  A deck
 *     (not .tran ... UIC) with nonlinear elements or controlled sources
 *     starts from its DC operating point, which the compiler finds
 *     (gen/emit.c, dcop_nonlinear); refsim is started there too
 *     (refsim_start_at), the point found the same way: dcop_solve at the
 *     default params, each source at its constant drive or its time
 *     function's value at time 0.  The error is 20 log10 of the relative
 *     RMS error over the run, sqrt(sum (y - r)^2 / sum r^2) (the RMS of y
 *     if r is all zero), the worst over the voice's outputs (named after
 *     the figure); |y0 - r0| is the largest difference of the first
 *     sample over the outputs, which shows whether both start from the
 *     same point.
 *
 * Before a netlist is measured, all its voices are built and all its
 * reference runs computed, as many at a time as there are processors
 * (the references in memory shared with the processes that compute
 * them); the measurements then run one at a time.
 *
 * A benchmark, not a test: the exit status is non-zero only if a voice
 * could not be built or loaded, or produced a non-finite sample.
 */
#include <fcntl.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "benchlib.h"
#include "gen.h"
#include "wdrt.h"
#include "wdvoice.h"
#include "../tests/refsim.h"
#include "../tests/testlib.h"

#define BLOCK 64
#define RUNS 3
#define WARMUP_S 0.05
#define TIMED_S 1.0   /* seconds of drive the timed runs cycle */
#define ERR_S 0.1     /* seconds of signal in the accuracy runs */
#define SINE_HZ 440.0

/* Every voice is measured at each rate of bench_rates.  An input no
 * source of a deck drives gets a sine of the amplitudes bench_amps: a
 * netlist that is not a deck both, a deck the first. */

static const bench_solver diode_cases[] = {
    {"newton", {"--solver", "newton", NULL}},
    {"omega", {"--solver", "omega", NULL}},
    {"fast", {"--solver", "fast", NULL}},
    {"pwl 4096", {"--solver", "pwl", "--table", "4096", NULL}},
};
/* a deck, or a netlist without diodes: as it is (the label is the
 * voice's: "joint" or "default") */
static const bench_solver plain_case = {"default", {NULL}};

#define MAXCASES ((int)(sizeof diode_cases / sizeof diode_cases[0]))

/* ---- the netlist ---- */

static int count_kind(const Circuit *c, int (*is)(const Elem *)) {
    int n = 0;
    for (int e = 0; e < c->nelems; e++)
        n += is(&c->elems[e]) != 0;
    return n;
}

static int is_diode(const Elem *e) { return e->kind == E_NL && e->nl && e->nl->kind == NL_DIODE; }
static int is_nonlinear(const Elem *e) { return e->kind == E_NL; }
static int is_controlled(const Elem *e) { return ELEM_CONTROLLED(e->kind); }
static int is_reactance(const Elem *e) { return e->kind == E_C || e->kind == E_L; }
static int is_line(const Elem *e) { return e->kind == E_W || e->kind == E_S; }

/* Whether the voice starts from the operating point dcop_solve finds, as
 * gen/emit.c's dcop_nonlinear decides it: a deck without UIC, with
 * reactances to hold it and nonlinear elements or controlled sources,
 * without lines or waveguides. */
static int starts_at_dcop(const Circuit *c) {
    return c->deck && !c->uic && count_kind(c, is_reactance) &&
           (count_kind(c, is_nonlinear) || count_kind(c, is_controlled)) && !c->nwgs && !count_kind(c, is_line);
}

/* The deck's DC operating point as the compiler finds it (dcop_nonlinear):
 * dcop_solve at the default params with each source at its constant
 * drive, or its time function's first value when an input drives it.
 * nodev[nnodes], cur[nelems].  Returns 1 if found and not rest, 0 if
 * rest, -1 if not found.  cur of an input-driven current source, which
 * dcop_solve leaves at 0, is filled with its whole current (drive + v/R),
 * as refsim_start_at takes it. */
static int deck_dcop(const Circuit *c, double *nodev, double *cur) {
    double *p = circuit_defaults(c), *drive = dcop_drives(c, p);
    int found = dcop_solve(c, p, drive, nodev, cur);
    int rest = 1;
    for (int n = 0; found && n < c->nnodes; n++)
        rest &= nodev[n] == 0;
    for (int i = 0; found && i < c->nelems; i++)
        rest &= cur[i] == 0;
    for (int i = 0; found && i < c->nelems; i++) {
        const Elem *e = &c->elems[i];
        if (e->kind == E_I && e->input >= 0) {
            double v = nodev[e->n[0]] - nodev[e->n[1]];
            cur[i] = drive[i] + (e->val ? v / elem_value(c, e, p) : 0.0);
        }
    }
    return !found ? -1 : rest ? 0 : 1;
}

/* ---- accuracy ---- */

/* Runs refsim of c at fs over nframes samples, from the operating point
 * (nodev, cur) when nodev != NULL, input k driven by in[k]; out[k][n]
 * gets output k at sample n.  The samples at which Newton did not
 * converge go to *unconverged.  Returns 0, or -1. */
static int render_ref(const Circuit *c, double fs, const double *nodev, const double *cur, double *const *in,
                      long nframes, double **out, long *unconverged) {
    refsim *s = refsim_new(c, fs, NULL);
    if (!s)
        return -1;
    if (nodev)
        refsim_start_at(s, nodev, cur);
    double x[BENCH_MAXIO], o[BENCH_MAXIO];
    for (long n = 0; n < nframes; n++) {
        for (int k = 0; k < c->ninputs; k++)
            x[k] = in[k][n];
        refsim_step(s, x, o);
        for (int k = 0; k < c->nouts; k++)
            out[k][n] = o[k];
    }
    refsim_nl_info info;
    refsim_nl_stats(s, &info);
    *unconverged = info.unconverged;
    refsim_free(s);
    return 0;
}

/* ---- preparation: drives, references and builds, in parallel ---- */

/* Everything one netlist needs before the measurements: the drives, the
 * voices of every rate and solver, and the reference runs, in memory
 * shared with the processes that compute them. */
typedef struct Prep {
    const char *path;
    const Circuit *c;
    const bench_solver *cases;
    int ncases, ndrives, have_ref;
    const double *op_nodev, *op_cur;            /* the operating point refsim starts at, or NULL */
    bench_built built[BENCH_NRATES * MAXCASES]; /* [rate * ncases + solver] */
    long dlen[BENCH_NRATES];                    /* frames of each drive: the longer of TIMED_S and ERR_S */
    double *drive[BENCH_NRATES][BENCH_NAMPS][BENCH_MAXIO]; /* [rate][drive][input] */
    bench_refs refs;                                       /* [slot(rate, drive)] */
} Prep;

static long err_frames(int r) { return (long)lround(ERR_S * bench_rates[r]); }

/* frames the timed runs cycle: a whole number of blocks */
static long timed_frames(int r) {
    long len = (long)lround(TIMED_S * bench_rates[r]) / BLOCK * BLOCK;
    return len < BLOCK ? BLOCK : len;
}

static int slot(int r, int d) { return r * BENCH_NAMPS + d; }

/* Computes reference run `run` (a slot) of the Prep ctx: 0 if done, else
 * 1. */
static int run_ref(void *ctx, int run) {
    Prep *p = ctx;
    int r = run / BENCH_NAMPS, d = run % BENCH_NAMPS;
    return render_ref(p->c, bench_rates[r], p->op_nodev, p->op_cur, p->drive[r][d], err_frames(r),
                      bench_refs_out(&p->refs, run), &p->refs.unconverged[run]) != 0;
}

/* Builds voice i of the Prep ctx, what wdc prints going to a log shown
 * only if the build fails: 0 if done, else 1. */
static int build_voice(void *ctx, int i) {
    Prep *p = ctx;
    const char *dir = p->built[i].v.dir;
    char src[128], log[128];
    if (p->c->deck)
        snprintf(src, sizeof src, "%s", p->path);
    else
        snprintf(src, sizeof src, "%s/netlist.wdn", dir);
    /* what wdc notes (the parent's load printed it once) goes to a log,
     * shown only if the build fails */
    snprintf(log, sizeof log, "%s/build.log", dir);
    fflush(stderr);
    int saved = dup(2), fd = open(log, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (saved >= 0 && fd >= 0)
        dup2(fd, 2);
    const bench_solver *sc = &p->cases[i % p->ncases];
    int st = bench_voice_make("deckbench", p->path, src, dir, sc, bench_rates[i / p->ncases], BENCH_CFLAGS);
    fflush(stderr);
    if (saved >= 0 && fd >= 0)
        dup2(saved, 2);
    if (fd >= 0)
        close(fd);
    if (saved >= 0)
        close(saved);
    if (st != 0) {
        char *text = read_file(log, NULL);
        if (text)
            fputs(text, stderr);
    }
    return st == 0 ? 0 : 1;
}

/* Input k's drive d at rate fs over n frames: the deck's source's time
 * function, or the sine. */
static void fill_drive(const Circuit *c, int k, int d, double fs, double *x, long n) {
    const SrcFn *f = c->input_fn ? c->input_fn[k] : NULL;
    for (long i = 0; i < n; i++)
        x[i] = f ? srcfn_at(f, (double)i / fs, 1 / fs) : bench_amps[d] * sin(2.0 * M_PI * SINE_HZ * (double)i / fs);
}

/* Computes the drives, makes the voices' directories and the shared
 * buffers, then builds every voice and computes every reference.
 * Returns 0, or -1 (out of memory). */
static int prepare(Prep *p, const char *text) {
    const Circuit *c = p->c;
    for (int r = 0; r < BENCH_NRATES; r++) {
        long t = timed_frames(r), e = err_frames(r);
        p->dlen[r] = t > e ? t : e;
        for (int d = 0; d < p->ndrives; d++)
            for (int k = 0; k < c->ninputs; k++) {
                p->drive[r][d][k] = malloc(sizeof(double) * (size_t)p->dlen[r]);
                if (!p->drive[r][d][k])
                    return -1;
                fill_drive(c, k, d, bench_rates[r], p->drive[r][d][k], p->dlen[r]);
            }
    }
    long frames[BENCH_NRATES * BENCH_NAMPS];
    int runs[BENCH_NRATES * BENCH_NAMPS], nruns = 0;
    for (int sl = 0; sl < BENCH_NRATES * BENCH_NAMPS; sl++)
        frames[sl] = err_frames(sl / BENCH_NAMPS);
    if (bench_refs_new(&p->refs, BENCH_NRATES * BENCH_NAMPS, c->nouts, frames) != 0)
        return -1;
    /* the longest first */
    if (p->have_ref)
        for (int r = BENCH_NRATES - 1; r >= 0; r--)
            for (int d = 0; d < p->ndrives; d++)
                runs[nruns++] = slot(r, d);
    return bench_prepare("deckbench", c->deck ? NULL : text, p->built, BENCH_NRATES * p->ncases, build_voice, &p->refs,
                         runs, nruns, run_ref, p);
}

static void prep_free(Prep *p) {
    for (int i = 0; i < BENCH_NRATES * p->ncases; i++)
        tl_voice_free(&p->built[i].v);
    for (int r = 0; r < BENCH_NRATES; r++)
        for (int d = 0; d < BENCH_NAMPS; d++)
            for (int k = 0; k < BENCH_MAXIO; k++)
                free(p->drive[r][d][k]);
    bench_refs_free(&p->refs);
}

/* ---- the table ---- */

static int name_width = 14;

#define ROW "%-*s %-9s %6s  %-10s %9s  %11s %13s %6s  %-9s %s\n"

static void print_row(const char *net, const char *solver, double fs, const char *drive, const char *ns,
                      const char *steps, const char *solves, const char *capped, const char *first,
                      const char *conv) {
    char rate[16];
    snprintf(rate, sizeof rate, "%.0f", fs);
    printf(ROW, name_width, net, solver, rate, drive, ns, steps, solves, capped, first, conv);
    fflush(stdout);
}

/* The name of drive d: the deck's sources' time functions, the sine, or
 * both. */
static void drive_name(const Circuit *c, const wdv_class *cls, int d, char *buf, size_t cap) {
    int fn = 0;
    char kind = 0;
    for (int k = 0; k < c->ninputs; k++)
        if (c->input_fn && c->input_fn[k]) {
            char kk = c->input_fn[k]->kind;
            kind = fn == 0 || kind == kk ? kk : '?';
            fn++;
        }
    const char *what = kind == 's' ? "SIN" : kind == 'p' ? "PULSE" : kind == 'w' ? "PWL" : kind == 'e' ? "EXP"
                     : kind == 'd' ? "DC" : "sources";
    if (c->ninputs == 0)
        snprintf(buf, cap, "none");
    else if (fn == c->ninputs)
        snprintf(buf, cap, "deck %s", what);
    else if (fn)
        snprintf(buf, cap, "deck+sine %g", bench_amps[d]);
    else
        snprintf(buf, cap, "sine %g %.4s", bench_amps[d], cls->inputs[0].unit);
}

/* Measures one voice on every drive: its speed, its joint solves and its
 * accuracy, and prints its rows.  Returns 0, or 1 if it failed. */
static int measure_voice(Prep *p, const char *label, int r, int s, double seconds) {
    const Circuit *c = p->c;
    double fs = bench_rates[r];
    bench_built *b = &p->built[r * p->ncases + s];
    const char *solver = p->cases[s].label;
    if (!b->ok || tl_voice_load(&b->v) != 0) {
        print_row(label, solver, fs, "-", "failed", "-", "-", "-", "-", "-");
        return 1;
    }
    const wdv_class *cls = b->v.cls;
    if (c->deck || p->cases == &plain_case)
        solver = cls->solve_stats ? "joint" : "default";
    if (cls->n_inputs != c->ninputs || cls->n_outputs != c->nouts) {
        fprintf(stderr, "deckbench: %s: the voice's ports differ from the netlist's\n", p->path);
        print_row(label, solver, fs, "-", "failed", "-", "-", "-", "-", "-");
        return 1;
    }
    long N = err_frames(r);
    double **y = tl_bufs_new(c->nouts, p->dlen[r] > N ? p->dlen[r] : N);
    int failed = 0, finite = 1;
    if (!y) {
        fprintf(stderr, "deckbench: out of memory\n");
        return 1;
    }
    for (int d = 0; d < p->ndrives; d++) {
        char dname[32], nsbuf[32], steps[32] = "-", solves[32] = "-", capped[32] = "-", first[32] = "n/a",
                                   cv[64] = "n/a";
        drive_name(c, cls, d, dname, sizeof dname);

        /* speed */
        double ns = bench_time_voice(cls, fs, p->drive[r][d], timed_frames(r), y, BLOCK, RUNS, WARMUP_S, seconds,
                                     &finite);
        if (ns < 0) {
            fprintf(stderr, "deckbench: out of memory\n");
            failed = 1;
            break;
        }
        snprintf(nsbuf, sizeof nsbuf, "%.1f", ns);

        /* the joint solves and the accuracy, from a fresh instance */
        unsigned long st[WDV_SOLVE_N];
        if (bench_render_voice(cls, fs, p->drive[r][d], N, BLOCK, y, st) != 0)
            finite = 0;
        if (cls->solve_stats) {
            snprintf(steps, sizeof steps, "%.2f", st[WDV_SOLVE_SOLVES] ? (double)st[WDV_SOLVE_STEPS] / (double)st[WDV_SOLVE_SOLVES] : 0.0);
            snprintf(solves, sizeof solves, "%.2f", (double)st[WDV_SOLVE_SOLVES] / (double)N);
            snprintf(capped, sizeof capped, "%lu", st[WDV_SOLVE_CAPPED]);
        }
        if (p->refs.ok[slot(r, d)]) {
            int w;
            double *const *ref = bench_refs_out(&p->refs, slot(r, d));
            double e = bench_worst_error(y, ref, c->nouts, N, &w), d0 = 0;
            bench_fmt_db(cv, sizeof cv, e, c->outs[w].name);
            for (int k = 0; k < c->nouts; k++)
                if (!(fabs(y[k][0] - ref[k][0]) <= d0))
                    d0 = fabs(y[k][0] - ref[k][0]);
            snprintf(first, sizeof first, "%.1e", d0);
        }
        print_row(label, solver, fs, dname, nsbuf, steps, solves, capped, first, cv);
    }
    if (!finite) {
        bench_note("%s, %s at %.0f Hz: the voice produced a non-finite sample", label, solver, fs);
        failed = 1;
    }
    tl_bufs_free(y, c->nouts);
    return failed;
}

/* Benchmarks one netlist; returns 0, or 1 if a voice failed. */
static int bench_netlist(const char *path, double seconds) {
    Circuit *c = wdc_load(path);
    char label[64];
    bench_label(path, label, sizeof label);
    if (!c) {
        fprintf(stderr, "deckbench: %s: cannot load\n", path);
        print_row(label, "-", 0, "-", "failed", "-", "-", "-", "-", "-");
        return 1;
    }
    if (c->ninputs > BENCH_MAXIO || c->nouts > BENCH_MAXIO || c->nouts < 1) {
        bench_note("%s: no outputs, or more than 16 inputs or outputs: not measured", label);
        return 0;
    }
    char *text = NULL;
    if (!c->deck && !(text = bench_read_netlist("deckbench", path, label)))
        return 1;

    static Prep p;
    memset(&p, 0, sizeof p);
    p.path = path;
    p.c = c;
    if (!c->deck && count_kind(c, is_diode)) {
        p.cases = diode_cases;
        p.ncases = MAXCASES;
    } else {
        p.cases = &plain_case;
        p.ncases = 1;
    }
    p.ndrives = c->deck ? 1 : BENCH_NAMPS;
    for (int k = 0; k < c->ninputs; k++)
        if (!c->deck && c->input_fn && c->input_fn[k]) /* --spice read as a deck; otherwise none */
            p.ndrives = 1;
    p.have_ref = refsim_can_simulate(c);
    if (!p.have_ref)
        bench_note("%s: refsim cannot simulate it (refsim_can_simulate): no error figures", label);

    /* where refsim starts: the voice's operating point, if it has one */
    double *nodev = malloc(sizeof(double) * ((size_t)c->nnodes + 1));
    double *cur = malloc(sizeof(double) * ((size_t)c->nelems + 1));
    if (!nodev || !cur) {
        fprintf(stderr, "deckbench: out of memory\n");
        free(nodev);
        free(cur);
        return 1;
    }
    if (starts_at_dcop(c) && p.have_ref) {
        int at = deck_dcop(c, nodev, cur);
        if (at > 0) {
            p.op_nodev = nodev;
            p.op_cur = cur;
            bench_note("%s: starts from its DC operating point; refsim starts there too", label);
        } else if (at == 0) {
            bench_note("%s: its DC operating point is rest: the voice and refsim start there", label);
        } else {
            bench_note("%s: the DC operating point was not found: the voice starts from rest, refsim from its "
                       "initial state",
                       label);
        }
    } else if (c->deck && !c->uic && !count_kind(c, is_nonlinear) && !count_kind(c, is_controlled) &&
               count_kind(c, is_reactance)) {
        bench_note("%s: a linear deck starts from its DC operating point, refsim from its own initial state: the "
                   "figures include the difference",
                   label);
    } else if (c->deck && c->uic) {
        bench_note("%s: .tran ... UIC: the voice and refsim start from its .ic", label);
    }

    int failed = 0;
    if (prepare(&p, text) != 0) {
        fprintf(stderr, "deckbench: out of memory\n");
        failed = 1;
    }
    for (int r = 0; r < BENCH_NRATES && p.have_ref && !failed; r++)
        for (int d = 0; d < p.ndrives; d++) {
            int sl = slot(r, d);
            if (!p.refs.ok[sl])
                bench_note("%s at %.0f Hz: the reference could not be computed", label, bench_rates[r]);
            else if (p.refs.unconverged[sl])
                bench_note("%s at %.0f Hz, drive %d: the reference did not converge at %ld samples", label,
                           bench_rates[r], d + 1, p.refs.unconverged[sl]);
        }
    for (int r = 0; r < BENCH_NRATES && !failed; r++)
        for (int s = 0; s < p.ncases; s++)
            failed |= measure_voice(&p, label, r, s, seconds);
    prep_free(&p);
    free(nodev);
    free(cur);
    return failed;
}

int main(int argc, char **argv) {
    double seconds = 0.3;
    int first = bench_args(argc, argv, &seconds, &name_width, "deckbench [-t SECONDS] NETLIST...");

    printf("wdc deck benchmark: the SPICE decks' voices, their joint solves' Newton steps, and the\n"
           "single-diode solvers of a diode pair\n");
    bench_print_setup(BENCH_CFLAGS);
    printf("ns/sample: one voice, blocks of %d frames, best of %d runs of >= %.2g s after a %.2g s warm-up,\n"
           "  cycling %.2g s of its drive: an input a deck's source drives gets the source's time function\n"
           "  (as wdc --render without --input), any other a %.0f Hz sine of amplitude %g (V, or the\n"
           "  input's unit), and %g too for a netlist that is not a deck.\n",
           BLOCK, RUNS, seconds, WARMUP_S, TIMED_S, SINE_HZ, bench_amps[0], bench_amps[1]);
    printf("steps/solve, solves/sample, capped: a fresh voice's joint solves over %.2g s (solve_stats):\n"
           "  Newton steps per solve (the mean), solves per sample, solves stopped at the iteration cap;\n"
           "  -: no joint solve (a single-diode solver).\n",
           ERR_S);
    printf("dB vs converged: 20 log10 of the relative RMS error sqrt(sum (y - r)^2 / sum r^2) over the same\n"
           "  %.2g s, the worst over the outputs (named after the figure), against refsim (tests/refsim.h)\n"
           "  at the same rate on the same input: the trapezoidal equations solved to convergence, so the\n"
           "  error is the solver's own; from the deck's DC operating point where its voice starts there\n"
           "  (refsim_start_at).  |y0-r0|: the largest difference at the first sample.\n\n",
           ERR_S);
    printf(ROW, name_width, "netlist", "solver", "rate", "drive", "ns/sample", "steps/solve", "solves/sample",
           "capped", "|y0-r0|", "dB vs converged");
    char dashes[80];
    bench_dashes(dashes, sizeof dashes, name_width);
    printf(ROW, name_width, dashes, "---------", "------", "----------", "---------", "-----------",
           "-------------", "------", "---------", "----------------");
    return bench_each(argc, argv, first, seconds, bench_netlist);
}
