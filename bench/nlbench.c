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
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

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

/* Every voice is measured at each rate of bench_rates; the drives of
 * the accuracy runs are sines of the amplitudes bench_amps, the last
 * one the one timed. */

static const bench_solver diode_cases[] = {
    {"fast", {"--solver", "fast", NULL}},
    {"newton", {"--solver", "newton", NULL}},
    {"omega", {"--solver", "omega", NULL}},
    {"pwl 64", {"--solver", "pwl", "--table", "64", NULL}},
    {"pwl 256", {"--solver", "pwl", "--table", "256", NULL}},
    {"pwl 1024", {"--solver", "pwl", "--table", "1024", NULL}},
    {"pwl 4096", {"--solver", "pwl", "--table", "4096", NULL}},
};
static const bench_solver curve_cases[] = {
    {"pwl", {"--solver", "pwl", NULL}},
};
static const bench_solver contact_cases[] = {
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

/* ---- accuracy ---- */

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
    double in[BENCH_MAXIO], o[BENCH_MAXIO];
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
#define NSLOTS (BENCH_NRATES * BENCH_NAMPS * 2)

/* Everything one netlist needs before the measurements: the voices of
 * every rate and solver, and the reference runs, in memory shared with
 * the processes that compute them. */
typedef struct Prep {
    const char *path;
    const Circuit *c;
    const bench_solver *cases;
    int ncases, ndrives, have_ref;
    bench_built built[BENCH_NRATES * MAXCASES]; /* [rate * ncases + solver] */
    /* [slot(rate, drive, 0: converged or 1: continuous)] */
    bench_refs refs;
} Prep;

static long err_frames(int r) { return (long)lround(ERR_S * bench_rates[r]); }

static int slot(int r, int d, int w) { return (r * BENCH_NAMPS + d) * 2 + w; }

/* Computes reference run `run` (a slot) of the Prep ctx: 0 if done, else
 * 1. */
static int run_ref(void *ctx, int run) {
    Prep *p = ctx;
    int r = run / (BENCH_NAMPS * 2), d = run / 2 % BENCH_NAMPS, w = run % 2;
    double amp = p->c->ninputs ? bench_amps[d] : 0.0;
    return render_ref(p->c, bench_rates[r], w ? FINE : 1, amp, err_frames(r), bench_refs_out(&p->refs, run),
                      &p->refs.unconverged[run]) != 0;
}

/* Builds voice i of the Prep ctx: 0 if done, else 1. */
static int build_voice(void *ctx, int i) {
    Prep *p = ctx;
    const char *dir = p->built[i].v.dir;
    const bench_solver *sc = &p->cases[i % p->ncases];
    char src[128];
    snprintf(src, sizeof src, "%s/netlist.wdn", dir);
    int st = bench_voice_make("nlbench", p->path, src, dir, sc, bench_rates[i / p->ncases], BENCH_CFLAGS);
    return st == 0 ? 0 : 1;
}

/* Makes the voices' directories and the shared buffers, then builds every
 * voice and computes every reference.  Returns 0, or -1 (out of memory). */
static int prepare(Prep *p, const char *text) {
    long frames[NSLOTS];
    int runs[NSLOTS], nruns = 0;
    for (int sl = 0; sl < NSLOTS; sl++)
        frames[sl] = err_frames(sl / (BENCH_NAMPS * 2));
    if (bench_refs_new(&p->refs, NSLOTS, p->c->nouts, frames) != 0)
        return -1;
    /* the longest first */
    if (p->have_ref)
        for (int w = 1; w >= 0; w--)
            for (int r = BENCH_NRATES - 1; r >= 0; r--)
                for (int d = 0; d < p->ndrives; d++)
                    runs[nruns++] = slot(r, d, w);
    return bench_prepare("nlbench", text, p->built, BENCH_NRATES * p->ncases, build_voice, &p->refs, runs, nruns,
                         run_ref, p);
}

static void prep_free(Prep *p) {
    for (int i = 0; i < BENCH_NRATES * p->ncases; i++)
        tl_voice_free(&p->built[i].v);
    bench_refs_free(&p->refs);
}

/* ---- the table ---- */

static int name_width = 14;

static void print_row(const char *net, const char *solver, double fs, const char *drive, const char *ns,
                      const char *conv, const char *cont) {
    printf("%-*s %-9s %6.0f  %-10s %9s  %-16s %s\n", name_width, net, solver, fs, drive, ns, conv, cont);
    fflush(stdout);
}

/* Measures one voice: its speed, then its accuracy on every drive, and
 * prints its rows.  Returns 0, or 1 if it failed. */
static int measure_voice(Prep *p, const char *label, int r, int s, double seconds) {
    const Circuit *c = p->c;
    const bench_solver *sc = &p->cases[s];
    double fs = bench_rates[r];
    bench_built *b = &p->built[r * p->ncases + s];
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
    double *drive[BENCH_NAMPS] = {NULL};
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
                drive[d][n] = bench_amps[d] * sin(2.0 * M_PI * SINE_HZ * (double)n / fs);
        }

    /* every input of drive d reads in[d] */
    double *in[BENCH_NAMPS][BENCH_MAXIO];
    for (int d = 0; d < BENCH_NAMPS; d++)
        for (int k = 0; k < c->ninputs; k++)
            in[d][k] = drive[d];

    /* speed, on the last drive */
    double ns = bench_time_voice(cls, fs, c->ninputs ? in[p->ndrives - 1] : NULL, len, y, BLOCK, RUNS, WARMUP_S,
                                 seconds, &finite);
    if (ns < 0)
        goto oom;

    /* accuracy, on every drive, the timed one first */
    for (int d = p->ndrives - 1; d >= 0; d--) {
        char dname[32], nsbuf[32], err[2][64] = {"n/a", "n/a"};
        if (c->ninputs)
            snprintf(dname, sizeof dname, "sine %g %.8s", bench_amps[d], cls->inputs[0].unit);
        else
            snprintf(dname, sizeof dname, "strike");
        if (d == p->ndrives - 1)
            snprintf(nsbuf, sizeof nsbuf, "%.1f", ns);
        else
            nsbuf[0] = '\0';
        if (bench_render_voice(cls, fs, in[d], N, BLOCK, y, NULL) != 0)
            finite = 0;
        for (int w = 0; w < 2; w++) /* vs converged, vs continuous */
            if (p->refs.ok[slot(r, d, w)]) {
                int out;
                double e = bench_worst_error(y, bench_refs_out(&p->refs, slot(r, d, w)), c->nouts, N, &out);
                bench_fmt_db(err[w], sizeof err[w], e, c->outs[out].name);
            }
        print_row(label, sc->label, fs, dname, nsbuf, err[0], err[1]);
    }
    if (!finite) {
        bench_note("%s, %s at %.0f Hz: the voice produced a non-finite sample", label, sc->label, fs);
        failed = 1;
    }
    goto out;
oom:
    fprintf(stderr, "nlbench: out of memory\n");
    failed = 1;
out:
    for (int d = 0; d < BENCH_NAMPS; d++)
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
        bench_note("%s: strings or tubes: its speed is in bench, its accuracy in tests/test_waveguide.c", label);
        return 0;
    }
    if (c->ninputs > BENCH_MAXIO || c->nouts > BENCH_MAXIO || c->nouts < 1) {
        bench_note("%s: no outputs, or more than 16 inputs or outputs: not measured", label);
        return 0;
    }
    char *text = bench_read_netlist("nlbench", path, label);
    if (!text)
        return 1;
    if (kinds.fixed)
        bench_note("%s: the netlist names its diodes' solver; dropped, so that --solver applies", label);

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
    p.ndrives = c->ninputs ? BENCH_NAMPS : 1;
    p.have_ref = refsim_can_simulate(c);
    if (!p.have_ref)
        bench_note("%s: refsim cannot simulate it (refsim_can_simulate): no error figures", label);
    if (prepare(&p, text) != 0) {
        fprintf(stderr, "nlbench: out of memory\n");
        prep_free(&p);
        return 1;
    }
    for (int r = 0; r < BENCH_NRATES && p.have_ref; r++)
        for (int d = 0; d < p.ndrives; d++)
            for (int w = 0; w < 2; w++) {
                int sl = slot(r, d, w);
                const char *run = w ? "64x-rate" : "same-rate";
                if (!p.refs.ok[sl])
                    bench_note("%s at %.0f Hz: the %s reference could not be computed", label, bench_rates[r], run);
                else if (p.refs.unconverged[sl])
                    bench_note("%s at %.0f Hz, drive %d: the %s reference did not converge at %ld samples", label,
                               bench_rates[r], d + 1, run, p.refs.unconverged[sl]);
            }
    int failed = 0;
    for (int r = 0; r < BENCH_NRATES; r++)
        for (int s = 0; s < p.ncases; s++)
            failed |= measure_voice(&p, label, r, s, seconds);
    prep_free(&p);
    return failed;
}

int main(int argc, char **argv) {
    double seconds = 0.3;
    int first = bench_args(argc, argv, &seconds, &name_width, "nlbench [-t SECONDS] NETLIST.wdn...");

    printf("wdc nonlinear benchmark: speed against accuracy of the voices with nonlinear elements\n");
    bench_print_setup(BENCH_CFLAGS);
    printf("ns/sample: one voice, blocks of %d frames, best of %d runs of >= %.2g s after a %.2g s warm-up,\n"
           "  driven by a %.0f Hz sine of amplitude %g (V, or the input's unit) on every input; a voice\n"
           "  without inputs is reset (its .ic strike) every %.0f ms.\n",
           BLOCK, RUNS, seconds, WARMUP_S, SINE_HZ, bench_amps[BENCH_NAMPS - 1], STRIKE_S * 1e3);
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
    bench_dashes(dashes, sizeof dashes, name_width);
    printf("%s %-9s %6s  %-10s %9s  %-16s %s\n", dashes, "---------", "------", "----------", "---------",
           "----------------", "----------------");
    return bench_each(argc, argv, first, seconds, bench_netlist);
}
