/*
 * test_nonlinear.c - voices with nonlinear elements: accuracy against a
 * converged implicit solve of the same discretisation, passivity, and
 * stability where simpler methods fail.
 *
 * 1. Diode clippers (netlists/diode_clipper.wdn: an antiparallel pair;
 *    netlists/diode_single.wdn: one diode), each compiled with every
 *    solver (fast, newton, omega, pwl with 256 and with 4096 table points),
 *    driven at 48 kHz for 0.2 s by a 440 Hz sine of 1 V and of 10 V and
 *    by 1 V white noise, against refsim (tests/refsim.h), which solves the
 *    trapezoidal nodal equations with the exact diode law by damped
 *    Newton to 1e-13 in long double.
 *    - fast, newton and omega solve the same discrete equations as the
 *      reference, to their own tolerance (1e-12 relative step): every
 *      output's relative RMS error must stay below TOL_SOLVER = 1e-9.
 *    - pwl replaces the diode law by its chords through table points
 *      spaced h = 2 vmax / (N - 1) apart (vmax = n Vt ln(1 + 1 A / Is)),
 *      and the voice then solves the trapezoidal equations of that
 *      piecewise-linear diode exactly.  The bound asserted follows
 *      (pwl_bounds below):
 *      local error: on a chord of an exponential the current is too large
 *        by at most delta = (h / (n Vt))^2 / 8 * exp(h / (n Vt)) of the
 *        exponential part of the current (its second derivative over the
 *        segment times h^2 / 8).  Where the load line v + Rp i = A (Rp:
 *        the resistance the network presents to the diode, A the wave it
 *        sends) crosses the law, v moves by that current error over the
 *        slope g + 1/Rp, so by l <= delta * n Vt, in both conduction and
 *        reverse (g is the same exponential over n Vt).
 *      carried: the network is a resistive source R and a capacitor C
 *        (trapezoidal conductance Gc = 2 C fs) on the diode's node, so
 *        A = Rp (Gr e + h) with the capacitor's history h, and
 *        h[n+1] = 2 Gc v[n] - h[n].  An error then evolves as
 *        dh[n+1] = (2 gc V' - 1) dh[n] + 2 Gc l[n], with gc = Gc Rp and
 *        V' = dv/dA = 1 / (1 + Rp g) between V'min (at the largest |v|
 *        of the run) and 1, so |dh| <= 2 Gc l K with
 *        K = 1 / min(2 - 2 gc, 2 gc V'min), and
 *        |dv| <= (1 + 2 gc K) delta n Vt,
 *        |di| <= 2 delta (i_peak + 2 Is) + 2 Gc K delta n Vt
 *      (the chord's own current error, and the slope g times the carried
 *      voltage error, which g V' Rp <= 1 caps).  Beyond the table's ends,
 *      reached here only on the reverse side of the single diode, the
 *      extended end chord is off by less than 1e-14 A, which moves v by
 *      less than 1e-11 V: negligible against these bounds.
 *    A table of the errors in dB (relative RMS) per netlist, solver and
 *    drive is printed, with the largest errors and their bounds.
 *    A fourth drive, the random steps of the passivity runs (uniform in
 *    [-10, 10] V, held 1 to 8 samples), is added to the three sines and
 *    noise: it makes the diode switch hard between conduction and
 *    reverse from one sample to the next.
 * 2. The felt hammer thrown at a bar and the mallet on a two-mass plate
 *    against refsim at 48 kHz and at 8 kHz: the voice's contact is solved
 *    by bracketed Newton to its tolerance, so again TOL_SOLVER.  The other
 *    nonlinear examples and test networks refsim simulates (reactances
 *    made by mutators) run under 1 (V, N) white noise for 0.5 s against
 *    TOL_SOLVER or FLOOR_FACTOR times the error that rounding the
 *    reference's state to double alone causes, whichever is larger.
 * 3. Passivity.  Every nonlinear example with an input is driven by the
 *    random steps for 10^7 samples as written (its own solver) and for
 *    10^6 with each solver: at every sample energy() <= work() + E(0) +
 *    PASS_TOL times the largest energy so far.  Then the input is silent
 *    for 0.1 s and the energy never rises (DECAY_TOL); and a fresh voice
 *    left silent from its initial state may not gain more than PASS_TOL
 *    of the driven run's peak energy (a network at rest stays at rest).
 *    The hammer and the mallet have no input: over a second at 48 kHz
 *    and at 8 kHz their energy never rises from one sample to the next
 *    (DECAY_TOL of the initial energy), never exceeds the initial energy,
 *    and starts at the thrown mass's m v^2 / 2 (to 1e-12); where it
 *    rises, the reference's energy at the same samples is printed beside
 *    it.
 * 4. Stability where methods fail.  The hammer-and-bar system with a felt
 *    100 times stiffer (k = 4.5e11, alpha = 2.5, written to a temporary
 *    netlist) is simulated at 8 kHz and 48 kHz for 0.2 s (a) by forward
 *    Euler and (b) by the trapezoidal rule with the contact force taken
 *    from the previous sample (a unit delay in the delay-free loop), with
 *    the same masses, spring, damper and contact law.  Both must blow up
 *    or gain energy: the energy (kinetic, spring and contact potential)
 *    peaks above INSTABLE_GAIN = 1.2 times the thrown mass's kinetic
 *    energy, or turns non-finite.  The wave-digital voice of the same
 *    netlist, initialised at the same rates, must stay finite and never
 *    hold more energy than it started with (to 1e-12); it must also still
 *    match refsim to TOL_SOLVER.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>
#include <float.h>
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "testlib.h"

#include "../templates/nl_wright.c.tmpl"
#include "../templates/nl_fast.c.tmpl"
#include "../templates/nl_fast_table.c.tmpl"

#define FS 48000.0
#define SECONDS 0.2
#define TOL_SOLVER 1e-9
#define PASS_SAMPLES 10000000L
#define PASS_SAMPLES_OTHER 1000000L
#define PASS_TOL 1e-12
#define DECAY_TOL 1e-12
#define INSTABLE_GAIN 1.2
#define MAXOUT 8

/* ---- temporary netlists ---- */

/* Files this test made, removed at exit. */
#define MAX_TEMP 128
static char temp_paths[MAX_TEMP][96];

static void remove_temps(void) {
    const char *keep = getenv("WDC_KEEP");
    if (keep && *keep == '1')
        return;
    for (int k = MAX_TEMP - 1; k >= 0; k--)
        if (temp_paths[k][0]) {
            remove(temp_paths[k]);
            temp_paths[k][0] = '\0';
        }
}

static void track_temp(const char *path) {
    static int registered;
    if (!registered) {
        atexit(remove_temps);
        registered = 1;
    }
    for (int k = 0; k < MAX_TEMP; k++)
        if (!temp_paths[k][0]) {
            snprintf(temp_paths[k], sizeof temp_paths[k], "%s", path);
            return;
        }
}

/* Writes the text of `src` with the first occurrence of `find` replaced
 * by `repl` to a fresh file under /tmp, whose name goes to out.  Returns
 * 0, or -1 if `find` does not occur or a file operation fails. */
static int write_variant(const char *src, const char *find, const char *repl, char *out,
                         size_t cap) {
    size_t len = 0;
    char *text = read_file(src, &len);
    if (!text)
        return -1;
    const char *at = strstr(text, find);
    if (!at)
        return -1;
    snprintf(out, cap, "/tmp/wdc-nl-XXXXXX.wdn");
    int fd = mkstemps(out, 4);
    if (fd < 0)
        return -1;
    track_temp(out);
    FILE *f = fdopen(fd, "w");
    if (!f) {
        close(fd);
        return -1;
    }
    fwrite(text, 1, (size_t)(at - text), f);
    fputs(repl, f);
    fputs(at + strlen(find), f);
    return fclose(f) == 0 ? 0 : -1;
}

/* ---- runs ---- */

/* tl_bufs_new, failing the test if memory runs out. */
static double **bufs_new(int n, long len) {
    double **b = tl_bufs_new(n, len);
    assert_non_null(b);
    return b;
}

/* Renders nframes of a fresh instance at fs, with one input (or none). */
static void run_voice(const wdv_class *cls, double fs, const double *in, long nframes,
                      double **out) {
    void *st = tl_state_new(cls, fs);
    assert_non_null(st);
    double *op[MAXOUT];
    const double *ip[1];
    for (long pos = 0; pos < nframes; pos += 64) {
        int n = nframes - pos < 64 ? (int)(nframes - pos) : 64;
        ip[0] = in ? in + pos : NULL;
        for (int k = 0; k < cls->n_outputs && k < MAXOUT; k++)
            op[k] = out[k] + pos;
        cls->process(st, ip, op, n);
    }
    tl_state_free(st);
}

/* Runs refsim of c at fs over nframes, with one input (or none). */
static void run_ref(const Circuit *c, double fs, const double *in, long nframes,
                    double **out, refsim_nl_info *info) {
    refsim *s = refsim_new(c, fs, NULL);
    assert_non_null(s);
    double o[MAXOUT], x[1];
    for (long n = 0; n < nframes; n++) {
        x[0] = in ? in[n] : 0.0;
        refsim_step(s, x, o);
        for (int k = 0; k < c->nouts && k < MAXOUT; k++)
            out[k][n] = o[k];
    }
    refsim_nl_stats(s, info);
    refsim_free(s);
}

static double max_abs(const double *x, long n) {
    double m = 0.0;
    for (long k = 0; k < n; k++)
        if (fabs(x[k]) > m)
            m = fabs(x[k]);
    return m;
}

static double max_abs_diff(const double *a, const double *b, long n, long *at) {
    double m = 0.0;
    *at = 0;
    for (long k = 0; k < n; k++) {
        double d = fabs(a[k] - b[k]);
        if (!(d <= m)) {
            m = d;
            *at = k;
        }
    }
    return m;
}

/* ---- 1. diode clippers, every solver ---- */

/* The random input of the passivity runs: uniform in [-10, 10] V, each
 * value held for 1 to 8 samples. */
typedef struct steps {
    tl_rng r;
    double x;
    long hold;
} steps;

static void steps_init(steps *g, uint64_t seed) {
    tl_rng_seed(&g->r, seed);
    g->x = 0.0;
    g->hold = 0;
}

static double steps_next(steps *g) {
    if (g->hold-- <= 0) {
        g->x = 10.0 * tl_rng_signed(&g->r);
        g->hold = (long)(tl_rng_next(&g->r) % 8);
    }
    return g->x;
}

typedef enum { DRIVE_SINE1, DRIVE_SINE10, DRIVE_NOISE1, DRIVE_STEPS10, NDRIVES } drive_kind;
static const char *drive_name[NDRIVES] = {"sine 1 V", "sine 10 V", "noise 1 V",
                                          "steps 10 V"};

static void make_drive(drive_kind d, double fs, long n, double *x) {
    tl_rng r;
    steps g;
    tl_rng_seed(&r, 0x440ull);
    steps_init(&g, 0x440ull);
    for (long k = 0; k < n; k++) {
        double t = (double)k / fs;
        switch (d) {
        case DRIVE_SINE1:
            x[k] = sin(2.0 * M_PI * 440.0 * t);
            break;
        case DRIVE_SINE10:
            x[k] = 10.0 * sin(2.0 * M_PI * 440.0 * t);
            break;
        case DRIVE_NOISE1:
            x[k] = tl_rng_signed(&r);
            break;
        default:
            x[k] = steps_next(&g);
            break;
        }
    }
}

typedef struct solver_case {
    const char *label;
    const char *args[8];
    int table; /* pwl: table points; -1: fast's table bound; 0: an iterative solver */
} solver_case;

/* --energy: the passivity checks read work() */
static const solver_case solvers[] = {
    {"fast", {"--solver", "fast", "--energy", NULL}, -1},
    {"fast tol", {"--solver", "fast", "--tol", "1e-12", "--energy", NULL}, 0},
    {"newton", {"--solver", "newton", "--energy", NULL}, 0},
    {"omega", {"--solver", "omega", "--energy", NULL}, 0},
    {"pwl 256", {"--solver", "pwl", "--table", "256", "--energy", NULL}, 256},
    {"pwl 4096", {"--solver", "pwl", "--table", "4096", "--energy", NULL}, 4096},
};
#define NSOLVERS ((int)(sizeof solvers / sizeof solvers[0]))

/* The diode of a clipper: its element and law. */
typedef struct diode_info {
    int elem;
    double Is, nVt;
    int pair;
} diode_info;

static diode_info find_diode(const Circuit *c) {
    diode_info d = {-1, 0, 0, 0};
    double *p = circuit_defaults(c);
    for (int e = 0; e < c->nelems; e++) {
        const Elem *el = &c->elems[e];
        if (el->kind == E_NL && el->nl->kind == NL_DIODE) {
            d.elem = e;
            d.Is = expr_eval(el->nl->Is, p);
            d.nVt = expr_eval(el->nl->n, p) * expr_eval(el->nl->Vt, p);
            d.pair = el->nl->pair;
        }
    }
    return d;
}

/* delta of the header comment for a table of `points` points. */
static double pwl_delta(const diode_info *d, int points) {
    double vmax = d->nVt * log(1.0 + 1.0 / d->Is);
    double h = 2.0 * vmax / (points - 1);
    double u = h / d->nVt;
    return u * u / 8.0 * exp(u);
}

/* The network around the diode of a clipper: one resistor (the source's
 * series resistance) and one capacitor across the diode. */
typedef struct clipper_net {
    double R, C;
} clipper_net;

static clipper_net clipper_of(const Circuit *c) {
    clipper_net k = {0, 0};
    double *p = circuit_defaults(c);
    int nr = 0, nc = 0;
    for (int e = 0; e < c->nelems; e++) {
        const Elem *el = &c->elems[e];
        if (el->kind == E_R) {
            k.R = elem_value(c, el, p);
            nr++;
        } else if (el->kind == E_C) {
            k.C = elem_value(c, el, p);
            nc++;
        } else if (el->kind == E_V && el->val) {
            k.R = elem_value(c, el, p);
            nr++;
        }
    }
    assert_int_equal(nr, 1);
    assert_int_equal(nc, 1);
    return k;
}

/* Slope of the diode law at voltage v. */
static double diode_slope(const diode_info *d, double v) {
    return d->pair ? 2.0 * d->Is * cosh(v / d->nVt) / d->nVt
                   : d->Is * exp(v / d->nVt) / d->nVt;
}

/* The bounds of the header comment on the largest voltage and current
 * errors of a pwl voice with `points` table points, for a run whose
 * diode voltages stay within [vlo, vhi] and whose current peaks at
 * ipeak. */
/* The carried error's factor K and the network's Gc and Rp of the header
 * comment, for a run whose diode voltages stay within [vlo, vhi]. */
static double carry_factor(const diode_info *d, const clipper_net *k, double fs, double vlo, double vhi, double *Gc,
                           double *Rp) {
    *Gc = 2.0 * k->C * fs, *Rp = 1.0 / (*Gc + 1.0 / k->R);
    double gc = *Gc * *Rp;
    double g = fmax(diode_slope(d, vlo), diode_slope(d, vhi));
    double Vmin = 1.0 / (1.0 + *Rp * g);
    return 1.0 / fmin(2.0 - 2.0 * gc, 2.0 * gc * Vmin);
}

static void pwl_bounds(const diode_info *d, const clipper_net *k, double fs, int points,
                       double vlo, double vhi, double ipeak, double *bv, double *bi) {
    double delta = pwl_delta(d, points), Gc, Rp;
    double K = carry_factor(d, k, fs, vlo, vhi, &Gc, &Rp);
    *bv = (1.0 + 2.0 * Gc * Rp * K) * delta * d->nVt;
    *bi = 2.0 * delta * (ipeak + 2.0 * d->Is) + 2.0 * Gc * K * delta * d->nVt;
}

/* The same for the fast solver's table, whose local error is in v itself,
 * l <= FAST_BOUND (|v| + n Vt): carried as above, |dv| <= (1 + 2 gc K) l;
 * the current, (A - v) / Rp with A off by Rp |dh|, by 2 Gc K l + |dv| / Rp. */
static void fast_bounds(const diode_info *d, const clipper_net *k, double fs, double vlo, double vhi, double *bv,
                        double *bi) {
    double Gc, Rp;
    double K = carry_factor(d, k, fs, vlo, vhi, &Gc, &Rp);
    double l = FAST_BOUND * (fmax(fabs(vlo), fabs(vhi)) + d->nVt);
    *bv = (1.0 + 2.0 * Gc * Rp * K) * l;
    *bi = 2.0 * Gc * K * l + *bv / Rp;
}

/* A copy of the netlist with any solver= key dropped, so that the command
 * line's --solver applies. */
static void solver_free_variant(const char *path, char *out, size_t cap) {
    if (write_variant(path, " solver=omega", "", out, cap) != 0)
        snprintf(out, cap, "%s", path);
}

static void diode_solvers(const char *path) {
    char var[96];
    solver_free_variant(path, var, sizeof var);
    Circuit *c = wdc_load(var);
    assert_non_null(c);
    assert_int_equal(c->ninputs, 1);
    assert_true(c->nouts <= MAXOUT);
    diode_info di = find_diode(c);
    assert_true(di.elem >= 0);
    clipper_net net = clipper_of(c);
    int vout = -1, iout = -1;
    for (int k = 0; k < c->nouts; k++) {
        if (c->outs[k].kind == PR_V && vout < 0)
            vout = k;
        if (c->outs[k].kind == PR_I && c->outs[k].elem == di.elem)
            iout = k;
    }
    assert_true(vout >= 0 && iout >= 0);
    long N = (long)(FS * SECONDS);
    double *in = calloc((size_t)N, sizeof(double));
    assert_non_null(in);
    double **ref[NDRIVES];
    refsim_nl_info info[NDRIVES];
    for (int d = 0; d < NDRIVES; d++) {
        make_drive((drive_kind)d, FS, N, in);
        ref[d] = bufs_new(c->nouts, N);
        run_ref(c, FS, in, N, ref[d], &info[d]);
        assert_int_equal(info[d].unconverged, 0);
    }
    for (int d = 0; d < NDRIVES; d++)
        print_message("%s, %s: the reference took %.2f Newton iterations per sample, at "
                      "most %d\n",
                      c->name, drive_name[d], (double)info[d].iters / N, info[d].maxit);
    print_message("%-14s %-9s %-10s %9s %9s %10s %10s %10s %10s\n", c->name, "solver",
                  "drive", "v dB", "i dB", "max|dv| V", "bound", "max|di| A", "bound");
    double **out = bufs_new(c->nouts, N);
    int failed = 0;
    for (int s = 0; s < NSOLVERS; s++) {
        tl_voice v;
        if (tl_voice_build_args(var, 0, solvers[s].args, NULL, &v) != 0) {
            tl_voice_free(&v);
            fail_msg("%s: the voice could not be built with --solver %s", path,
                     solvers[s].label);
        }
        for (int d = 0; d < NDRIVES; d++) {
            make_drive((drive_kind)d, FS, N, in);
            run_voice(v.cls, FS, in, N, out);
            double ev = rel_rms_error(out[vout], ref[d][vout], N);
            double ei = rel_rms_error(out[iout], ref[d][iout], N);
            long atv, ati;
            double dv = max_abs_diff(out[vout], ref[d][vout], N, &atv);
            double dI = max_abs_diff(out[iout], ref[d][iout], N, &ati);
            double bound_v = 0.0, bound_i = 0.0;
            int ok;
            if (solvers[s].table) {
                double vlo = INFINITY, vhi = -INFINITY;
                for (long n = 0; n < N; n++) {
                    vlo = fmin(vlo, fmin(out[vout][n], ref[d][vout][n]));
                    vhi = fmax(vhi, fmax(out[vout][n], ref[d][vout][n]));
                }
                if (solvers[s].table < 0)
                    fast_bounds(&di, &net, FS, vlo, vhi, &bound_v, &bound_i);
                else
                    pwl_bounds(&di, &net, FS, solvers[s].table, vlo, vhi,
                               max_abs(ref[d][iout], N), &bound_v, &bound_i);
                ok = dv <= bound_v && dI <= bound_i;
            } else {
                ok = ev < TOL_SOLVER && ei < TOL_SOLVER;
            }
            if (solvers[s].table)
                print_message("%-14s %-9s %-10s %9.1f %9.1f %10.3g %10.3g %10.3g %10.3g\n", "",
                              solvers[s].label, drive_name[d], tl_db(ev), tl_db(ei), dv,
                              bound_v, dI, bound_i);
            else
                print_message("%-14s %-9s %-10s %9.1f %9.1f %10.3g %10s %10.3g %10s\n", "",
                              solvers[s].label, drive_name[d], tl_db(ev), tl_db(ei), dv,
                              "", dI, "");
            if (!ok) {
                failed = 1;
                print_message("%s, %s, %s: FAILED: v relative RMS %.3g, i relative RMS "
                              "%.3g; largest |dv| %.3g V at n=%ld (voice %.17g, reference "
                              "%.17g), largest |di| %.3g A at n=%ld (voice %.17g, "
                              "reference %.17g)\n",
                              c->name, solvers[s].label, drive_name[d], ev, ei, dv, atv,
                              out[vout][atv], ref[d][vout][atv], dI, ati, out[iout][ati],
                              ref[d][iout][ati]);
            }
        }
        tl_voice_free(&v);
    }
    for (int d = 0; d < NDRIVES; d++)
        tl_bufs_free(ref[d], c->nouts);
    tl_bufs_free(out, c->nouts);
    free(in);
    if (failed)
        fail_msg("%s: a solver's voice is off the converged reference", path);
}

static void test_diode_clipper(void **state) {
    (void)state;
    diode_solvers("netlists/diode_clipper.wdn");
}

static void test_diode_single(void **state) {
    (void)state;
    diode_solvers("netlists/diode_single.wdn");
}

/* One diode blocking hard (netlists/diode_single.wdn, every solver): a
 * step of -100 V, -3 kV, then +3 kV and back to -3 kV through R1 = 1 kOhm
 * into C1 = 22 nF.  Reverse, the closed form's omega(x) underflows for x
 * below -745 (ln w = x there); the diode then passes -Is and the output
 * settles at the step plus R1 Is.  Every sample finite; 2 ms (90 time
 * constants) after each reverse step the output within 1e-12 of
 * A + R1 Is relative to A, and the diode's current, which the voice takes
 * from waves of about A, within 16 ulp of A / R1 of -Is. */
static void test_diode_reverse(void **state) {
    (void)state;
    static const char *const solvers[] = {"fast", "newton", "omega", "pwl"};
    static const double steps[] = {-100, -3000, 3000, -3000};
    const double R = 1000, Is = 2.52e-9;
    for (int k = 0; k < 4; k++) {
        const char *args[] = {"--solver", solvers[k], NULL};
        tl_voice v;
        if (tl_voice_build_args("netlists/diode_single.wdn", 0, args, NULL, &v) != 0)
            fail_msg("diode_single --solver %s: the voice could not be built", solvers[k]);
        assert_int_equal(v.cls->n_inputs, 1);
        assert_int_equal(v.cls->n_outputs, 2);
        void *st = tl_state_new(v.cls, 48000);
        assert_non_null(st);
        enum { N = 96 }; /* 2 ms */
        double in[N], out[N], id[N], worst = 0;
        long bad = 0;
        for (int j = 0; j < 4; j++) {
            for (int n = 0; n < N; n++)
                in[n] = steps[j];
            const double *ip[1] = {in};
            double *op[2] = {out, id};
            v.cls->process(st, ip, op, N);
            for (int n = 0; n < N; n++)
                bad += !isfinite(out[n]) || !isfinite(id[n]);
            if (steps[j] < 0) {
                double e = fabs(out[N - 1] - (steps[j] + R * Is)) / -steps[j], ti = 16 * DBL_EPSILON * -steps[j] / R;
                worst = e > worst ? e : worst;
                if (!(e <= 1e-12) || !(fabs(id[N - 1] + Is) <= ti))
                    print_error("--solver %s, %g V: out %.17g (want %.17g), id %.17g (want %.17g)\n", solvers[k],
                                steps[j], out[N - 1], steps[j] + R * Is, id[N - 1], -Is);
                assert_true(e <= 1e-12);
                assert_true(fabs(id[N - 1] + Is) <= ti);
            }
        }
        printf("diode_single --solver %-6s blocking 100 V and 3 kV: %ld samples not finite, worst settling error "
               "%.2g\n", solvers[k], bad, worst);
        assert_int_equal(bad, 0);
        tl_state_free(st);
        tl_voice_free(&v);
    }
}

/* ---- 1b. the fast solver across its range ---- */

/* diode_fast (templates/nl_fast.c.tmpl), sample by sample: c = R Is / nVt
 * log-uniform in [1e-14, 10], nVt in [0.02, 0.1] V, incident waves a of
 * either sign with |a| / nVt log-uniform in [1e-6, 2000] (past the table
 * for every c), one diode and pairs.  The exact root comes from
 * bracketed Newton in long double.  With the table alone (tol
 * FAST_BOUND) every v must lie within FAST_BOUND (|v| + nVt) of it; with
 * tol 1e-12 (Halley steps), within 1e-12 (|v| + nVt) and 8 ulp of v.  A
 * wave of 0 (or -0) must get exactly 0 back. */
static long double exact_x(long double al, long double c, int pair) {
    if (pair && al < 0)
        return -exact_x(-al, c, pair);
    /* x >= 0 solves c e^x <= al + c, so x <= ln(1 + al / c) */
    long double lo = al < 0 ? al : 0, hi = al > 0 ? fminl(al, log1pl(al / c)) : 0, x = 0.5L * (lo + hi);
    for (int it = 0; it < 600; it++) {
        long double E = expl(x), f = x + c * (pair ? E - 1 / E : E - 1) - al, f1 = 1 + c * (pair ? E + 1 / E : E);
        if (f > 0)
            hi = x;
        else
            lo = x;
        long double xn = x - f / f1;
        if (!(xn > lo && xn < hi))
            xn = 0.5L * (lo + hi);
        if (fabsl(xn - x) <= 1e-19L * (fabsl(x) + 1) || hi - lo <= 1e-19L * (fabsl(x) + 1))
            return xn;
        x = xn;
    }
    return x;
}

static void test_fast_bound(void **state) {
    (void)state;
    static double om[OM_SIZE];
    omega_table(om);
    tl_rng r;
    tl_rng_seed(&r, 0x9e3779b97f4a7c15ull);
#define UNIT() tl_rng_uniform(&r)
    double worst[2] = {0, 0};
    int bad = 0;
    for (int n = 0; n < 400000; n++) {
        double c = pow(10, -14 + 15 * UNIT()), nVt = 0.02 + 0.08 * UNIT(), Is = c * nVt, R = 1;
        double al = pow(10, -6 + 9.3 * UNIT()) * (UNIT() < 0.5 ? -1 : 1), a = al * nVt;
        int pair = n & 1, exact = (n >> 1) & 1;
        double k[6];
        fast_setup(k, R, Is, nVt, pair, om);
        double v = diode_fast(a, pair, k[0], k[1], k[2], k[3], k[4], k[5], om, exact ? 1e-12 : FAST_BOUND, 50);
        double v0 = diode_fast(n & 4 ? 0.0 : -0.0, pair, k[0], k[1], k[2], k[3], k[4], k[5], om,
                               exact ? 1e-12 : FAST_BOUND, 50);
        if (v0 != 0 && bad++ < 10) /* a silent wave gets exactly 0 back */
            print_message("c %.3g nVt %.3g pair %d tol %s: v(0) = %.3g\n", c, nVt, pair, exact ? "1e-12" : "FAST_BOUND", v0);
        double vx = (double)(nVt * exact_x(a / nVt, (long double)R * Is / nVt, pair));
        double e = fabs(v - vx) / (fabs(vx) + nVt), lim = exact ? 1e-12 + 8 * DBL_EPSILON * fabs(vx) / (fabs(vx) + nVt)
                                                                  : FAST_BOUND;
        worst[exact] = fmax(worst[exact], e);
        if (!(e <= lim) && bad++ < 10)
            print_message("c %.3g nVt %.3g a %.17g pair %d tol %s: v %.17g, exact %.17g (%.3g of |v| + nVt)\n", c, nVt,
                          a, pair, exact ? "1e-12" : "FAST_BOUND", v, vx, e);
    }
#undef UNIT
    print_message("fast, 400000 samples: worst error over |v| + nVt %.3g with the table (bound %.0e), %.3g with "
                  "tol 1e-12\n", worst[0], FAST_BOUND, worst[1]);
    assert_int_equal(bad, 0);
}

/* The clippers with the fast solver, double and float, at 8, 48 and 192
 * kHz: a silent input gives exactly 0 on every output, sample after
 * sample (the tables' value at a = 0 is taken out). */
static void test_fast_silence(void **state) {
    (void)state;
    static const char *const nets[] = {"netlists/diode_clipper.wdn", "netlists/diode_single.wdn"};
    static const double rates[] = {8000.0, 48000.0, 192000.0};
    static const char *const args[] = {"--solver", "fast", NULL};
    const long N = 4800;
    double *in = calloc((size_t)N, sizeof(double));
    assert_non_null(in);
    for (int k = 0; k < 2; k++)
        for (int single = 0; single < 2; single++) {
            char var[96];
            solver_free_variant(nets[k], var, sizeof var);
            tl_voice v;
            assert_int_equal(tl_voice_build_args(var, single, args, NULL, &v), 0);
            for (int r = 0; r < 3; r++) {
                double **out = bufs_new(v.cls->n_outputs, N);
                run_voice(v.cls, rates[r], in, N, out);
                for (int o = 0; o < v.cls->n_outputs; o++)
                    for (long n = 0; n < N; n++)
                        if (out[o][n] != 0)
                            fail_msg("%s (%s) at %.0f Hz: output %d is %g at sample %ld of silence", nets[k],
                                     single ? "float" : "double", rates[r], o, out[o][n], n);
                tl_bufs_free(out, v.cls->n_outputs);
            }
            tl_voice_free(&v);
        }
    free(in);
}

/* The voice with --tol 1e-12 (Halley steps after the table) across the
 * range: the table over y = ln c + |a| / nVt + c, Halley from the
 * asymptote past it, and pairs whose c passes FAST_CMAX.  Single diodes
 * and pairs whose c runs from 1e-11 to about
 * 10, at 8, 48 and 192 kHz, driven by 440 Hz sines of 1 mV to 1 kV (the
 * largest reaching past the table on both sides) and the random steps,
 * must match refsim like the other exact solvers, to TOL_SOLVER.  The
 * current is read from the waves, (a - b) / 2Rp, so it loses the digits
 * of v that a diode far below its knee leaves unused (|v| >> Rp |i|):
 * where its relative error passes TOL_SOLVER, every sample's must stay
 * within 64 ulp of the largest |v| over Rp. */
typedef struct fast_case {
    double R, C;
    const char *Is, *n;
} fast_case;

static void test_fast_range(void **state) {
    (void)state;
    static const fast_case cases[] = {
        {10, 1e-6, "10f", "1"},         /* c about 4e-12 */
        {2.2e3, 1e-8, "2.52n", "1.752"}, /* the clipper's own */
        {1e6, 1e-9, "1u", "2"},          /* c about 0.2 at 48 kHz */
        {1e6, 1e-11, "1u", "2"},         /* c about 10 */
    };
    static const double rates[] = {8000.0, 48000.0, 192000.0};
    static const double amps[] = {1e-3, 1.0, 10.0, 1e3, 0.0}; /* 0: the random steps */
    int failed = 0;
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++)
        for (int pair = 0; pair < 2; pair++) {
            char path[96] = "/tmp/wdc-fast-XXXXXX.wdn";
            int fd = mkstemps(path, 4);
            assert_true(fd >= 0);
            track_temp(path);
            FILE *f = fdopen(fd, "w");
            assert_non_null(f);
            fprintf(f, ".voice fastcase\n.input in\n.model dd D Is=%s n=%s Vt=25.85m pair=%d\n"
                       "V1 in 0 in\nR1 in out %.17g\nC1 out 0 %.17g\nD1 out 0 dd\n"
                       ".output out v(out)\n.output id i(D1)\n.end\n",
                    cases[k].Is, cases[k].n, pair, cases[k].R, cases[k].C);
            assert_int_equal(fclose(f), 0);
            Circuit *c = wdc_load(path);
            assert_non_null(c);
            tl_voice v;
            static const char *const args[] = {"--solver", "fast", "--tol", "1e-12", NULL};
            if (tl_voice_build_args(path, 0, args, NULL, &v) != 0) {
                tl_voice_free(&v);
                fail_msg("%s: the voice could not be built", path);
            }
            double worst = 0;
            for (int ri = 0; ri < 3; ri++) {
                double fs = rates[ri], Rp = 1.0 / (1.0 / cases[k].R + 2.0 * cases[k].C * fs);
                long N = (long)(fs * 0.05);
                double *in = calloc((size_t)N, sizeof(double));
                assert_non_null(in);
                double **ref = bufs_new(c->nouts, N), **out = bufs_new(c->nouts, N);
                for (size_t ai = 0; ai < sizeof amps / sizeof amps[0]; ai++) {
                    steps g;
                    steps_init(&g, 0x5eedull + ai);
                    for (long n = 0; n < N; n++)
                        in[n] = amps[ai] > 0 ? amps[ai] * sin(2.0 * M_PI * 440.0 * (double)n / fs)
                                             : steps_next(&g);
                    refsim_nl_info info;
                    run_ref(c, fs, in, N, ref, &info);
                    assert_int_equal(info.unconverged, 0);
                    run_voice(v.cls, fs, in, N, out);
                    for (int o = 0; o < c->nouts; o++) {
                        double e = rel_rms_error(out[o], ref[o], N);
                        long at;
                        bool ok = e < TOL_SOLVER;
                        if (!ok && c->outs[o].kind == PR_I)
                            ok = max_abs_diff(out[o], ref[o], N, &at) <= 64 * DBL_EPSILON * max_abs(ref[0], N) / Rp; /* ref[0]: v(out) */
                        else
                            worst = fmax(worst, e);
                        if (!ok) {
                            failed = 1;
                            print_message("R=%g C=%g Is=%s n=%s pair=%d, %.0f Hz, amplitude %g: %s is "
                                          "%.3g (relative RMS) off the converged reference\n",
                                          cases[k].R, cases[k].C, cases[k].Is, cases[k].n, pair, fs,
                                          amps[ai], c->outs[o].name, e);
                        }
                    }
                }
                tl_bufs_free(ref, c->nouts);
                tl_bufs_free(out, c->nouts);
                free(in);
            }
            print_message("fast: R=%-6g C=%-6g Is=%-5s n=%-5s pair=%d: worst %.1f dB over rates and drives\n",
                          cases[k].R, cases[k].C, cases[k].Is, cases[k].n, pair, tl_db(worst));
            tl_voice_free(&v);
        }
    if (failed)
        fail_msg("the fast solver is off the converged reference");
}

/* ---- 2. contacts against the reference ---- */

/* Returns 0, or -1 after reporting. */
static int contact_vs_ref(const char *path, const char *label) {
    Circuit *c = wdc_load(path);
    assert_non_null(c);
    assert_true(c->nouts <= MAXOUT);
    tl_voice v;
    if (tl_voice_build_args(path, 0, NULL, NULL, &v) != 0) {
        tl_voice_free(&v);
        fail_msg("%s: the voice could not be built", path);
    }
    int failed = 0;
    static const double rates[] = {48000.0, 8000.0};
    for (int ri = 0; ri < 2; ri++) {
        double fs = rates[ri];
        long N = (long)(fs * SECONDS);
        double **ref = bufs_new(c->nouts, N), **out = bufs_new(c->nouts, N);
        refsim_nl_info info;
        run_ref(c, fs, NULL, N, ref, &info);
        run_voice(v.cls, fs, NULL, N, out);
        char line[512];
        int len = snprintf(line, sizeof line, "%-13s %5.0f Hz: reference Newton %.2f it/sample "
                           "(max %d); relative RMS error:",
                           label, fs, (double)info.iters / N, info.maxit);
        for (int k = 0; k < c->nouts; k++) {
            double e = rel_rms_error(out[k], ref[k], N);
            len += snprintf(line + len, sizeof line - (size_t)len, " %s %.1f dB", c->outs[k].name,
                            tl_db(e));
            if (!(e < TOL_SOLVER)) {
                long at;
                double d = max_abs_diff(out[k], ref[k], N, &at);
                failed = 1;
                print_message("%s at %g Hz: output %s relative RMS error %.3g; largest "
                              "difference %.3g at n=%ld: voice %.17g, reference %.17g\n",
                              c->name, fs, c->outs[k].name, e, d, at, out[k][at], ref[k][at]);
            }
        }
        print_message("%s\n", line);
        if (info.unconverged) {
            failed = 1;
            print_message("%s: the reference did not converge at %ld samples\n", c->name,
                          info.unconverged);
        }
        tl_bufs_free(ref, c->nouts);
        tl_bufs_free(out, c->nouts);
    }
    tl_voice_free(&v);
    return failed ? -1 : 0;
}

static void test_hammer_ref(void **state) {
    (void)state;
    if (contact_vs_ref("netlists/hammer_bar.wdn", "hammer_bar") != 0)
        fail_msg("hammer_bar: the voice is off the converged reference");
}

static void test_mallet_ref(void **state) {
    (void)state;
    if (contact_vs_ref("netlists/mallet_plate.wdn", "mallet_plate") != 0)
        fail_msg("mallet_plate: the voice is off the converged reference");
}

static int has_nonlinear(const Circuit *c);

/* The other nonlinear examples (and test networks) that refsim simulates
 * (mutated reactances, say), with their own solvers, under 1 (V, N, ...)
 * white noise at 48 kHz for 0.5 s, with params at their defaults.  The
 * tolerance is TOL_SOLVER, or FLOOR_FACTOR times the run's floor: the
 * error of the reference itself with its state rounded to double after
 * every step, which a lightly damped nonlinear oscillator (a pitch that
 * depends on amplitude turns a rounding error into a growing phase error)
 * can raise above it. */
#define FLOOR_FACTOR 20.0
static void test_other_nonlinear(void **state) {
    (void)state;
    static const char *done[] = {"netlists/diode_clipper.wdn", "netlists/diode_single.wdn",
                                 "netlists/hammer_bar.wdn", "netlists/mallet_plate.wdn"};
    int n = 0, failed = 0;
    char **paths = tl_netlists(&n);
    for (int k = 0; k < n; k++) {
        int skip = 0;
        for (size_t j = 0; j < sizeof done / sizeof done[0]; j++)
            skip |= !strcmp(paths[k], done[j]);
        Circuit *c = wdc_load(paths[k]);
        assert_non_null(c);
        if (skip || !has_nonlinear(c))
            continue;
        if (!refsim_can_simulate(c)) {
            print_message("%-17s has elements the reference does not simulate: skipped\n",
                          c->name);
            continue;
        }
        tl_voice v;
        if (tl_voice_build_args(paths[k], 0, NULL, NULL, &v) != 0) {
            tl_voice_free(&v);
            tl_netlists_free(paths, n);
            fail_msg("%s: the voice could not be built", paths[k]);
        }
        tl_signal sig;
        tl_signal_init(&sig, TL_NOISE, 1.0, 0, 0xabcull + (uint64_t)k);
        tl_run_opts o = {0};
        o.fs = FS;
        o.nframes = (long)(0.5 * FS);
        o.signal = &sig;
        o.with_floor = 64;
        tl_run run;
        int rc = tl_run_side_by_side(c, v.cls, &o, &run);
        tl_voice_free(&v);
        if (rc != 0) {
            tl_netlists_free(paths, n);
            fail_msg("%s: the run failed", paths[k]);
        }
        int which = 0;
        double worst = tl_run_worst(&run, &which), fl = tl_run_floor(&run);
        double allowed = fmax(TOL_SOLVER, FLOOR_FACTOR * fl);
        print_message("%-17s worst relative RMS error %.3g (%.1f dB, output %s), floor %.3g\n",
                      c->name, worst, tl_db(worst), c->outs[which].name, fl);
        if (!(worst < allowed)) {
            failed = 1;
            print_message("  FAILED: above %.3g\n", allowed);
            for (int j = 0; j < run.nouts; j++)
                tl_run_report(&run, c, j, allowed);
        }
        tl_run_free(&run);
    }
    tl_netlists_free(paths, n);
    if (failed)
        fail_msg("a nonlinear voice is off the converged reference");
}

/* ---- 3. passivity ---- */

static int has_nonlinear(const Circuit *c) {
    for (int e = 0; e < c->nelems; e++)
        if (c->elems[e].kind == E_NL)
            return 1;
    return 0;
}

/* Result of one passivity run of a voice with one input. */
typedef struct pass_result {
    double e0;          /* initial energy */
    double peak;        /* largest energy */
    double margin;      /* smallest W + E0 - E, relative to the peak */
    long margin_at;
    long excess_at;     /* first sample with E > W + E0 + tolerance, or -1 */
    double rise;        /* largest rise while silent, relative to the peak */
    long rise_at;       /* first silent sample rising over the tolerance, or -1 */
    double e_at[3];     /* E, W, E0 at excess_at */
    double r_at[2];     /* energies before and at rise_at */
    double secs;
} pass_result;

/* nrand samples of the steps input (steps_next), then nsilent of silence,
 * one sample per process call; the tolerance of each check is PASS_TOL or
 * DECAY_TOL times the largest energy so far. */
static void passivity_run(const wdv_class *cls, long nrand, long nsilent, uint64_t seed,
                          pass_result *p) {
    memset(p, 0, sizeof *p);
    p->margin = INFINITY;
    p->excess_at = p->rise_at = p->margin_at = -1;
    void *st = tl_state_new(cls, FS);
    assert_non_null(st);
    steps g;
    steps_init(&g, seed);
    double x = 0.0, y[MAXOUT];
    double *op[MAXOUT];
    const double *ip[1] = {&x};
    for (int k = 0; k < MAXOUT; k++)
        op[k] = &y[k];
    double E0 = cls->energy(st), W0 = cls->work(st), Eprev = E0;
    double peak = fabs(E0), margin = INFINITY;
    clock_t t0 = clock();
    for (long n = 0; n < nrand + nsilent; n++) {
        x = n < nrand ? steps_next(&g) : 0.0;
        cls->process(st, ip, op, 1);
        double E = cls->energy(st), W = cls->work(st) - W0;
        if (!(E <= peak))
            peak = E;
        double m = W + E0 - E;
        if (!(m >= margin)) {
            margin = m;
            p->margin_at = n;
        }
        if (!(-m <= PASS_TOL * peak) && p->excess_at < 0) {
            p->excess_at = n;
            p->e_at[0] = E;
            p->e_at[1] = W;
            p->e_at[2] = E0;
        }
        /* silent: this sample and the one before (work is counted with
         * the average of the two) */
        if (n > nrand) {
            double rise = E - Eprev;
            if (rise > p->rise)
                p->rise = rise;
            if (!(rise <= DECAY_TOL * peak) && p->rise_at < 0) {
                p->rise_at = n;
                p->r_at[0] = Eprev;
                p->r_at[1] = E;
            }
        }
        Eprev = E;
    }
    p->secs = (double)(clock() - t0) / CLOCKS_PER_SEC;
    p->e0 = E0;
    p->peak = peak;
    p->margin = peak > 0.0 ? margin / peak : margin;
    p->rise = peak > 0.0 ? p->rise / peak : p->rise;
    tl_state_free(st);
}

static void test_passivity_inputs(void **state) {
    (void)state;
    int n = 0, tested = 0, failed = 0;
    char **paths = tl_netlists(&n);
    for (int k = 0; k < n; k++) {
        Circuit *c = wdc_load(paths[k]);
        assert_non_null(c);
        if (!has_nonlinear(c) || c->ninputs != 1 || c->nouts > MAXOUT)
            continue;
        tested++;
        char var[96];
        solver_free_variant(paths[k], var, sizeof var);
        /* the netlist as written (its own or the default solver), then
         * every solver on a copy without solver= keys */
        for (int s = -1; s < NSOLVERS; s++) {
            tl_voice v;
            int rc = s < 0 ? tl_voice_build_args(paths[k], 0, tl_energy, NULL, &v)
                           : tl_voice_build_args(var, 0, solvers[s].args, NULL, &v);
            if (rc != 0) {
                tl_voice_free(&v);
                tl_netlists_free(paths, n);
                fail_msg("%s: the voice could not be built", paths[k]);
            }
            long nrand = s < 0 ? PASS_SAMPLES : PASS_SAMPLES_OTHER;
            pass_result p, q;
            passivity_run(v.cls, nrand, (long)(0.1 * FS), 0xd10de + (uint64_t)k, &p);
            print_message("%-14s %-9s %8ld samples (%4.1f s): peak energy %.3g J; smallest "
                          "margin W + E0 - E %.3g of it (n=%ld); largest rise while silent "
                          "%.3g of it\n",
                          c->name, s < 0 ? "as given" : solvers[s].label, nrand, p.secs,
                          p.peak, p.margin, p.margin_at, p.rise);
            if (p.excess_at >= 0) {
                failed = 1;
                print_message("  FAILED: at n=%ld energy %.17g exceeds work %.17g + initial "
                              "energy %.17g\n",
                              p.excess_at, p.e_at[0], p.e_at[1], p.e_at[2]);
            }
            if (p.rise_at >= 0) {
                failed = 1;
                print_message("  FAILED: energy rises while silent at n=%ld: %.17g -> %.17g\n",
                              p.rise_at, p.r_at[0], p.r_at[1]);
            }
            /* silent from its initial state, the energy may not rise by
             * more than PASS_TOL of the peak of the run above (a network
             * at rest stays at rest) */
            passivity_run(v.cls, 0, (long)(0.1 * FS), 0, &q);
            if (q.peak > q.e0)
                print_message("%-14s %-9s silent from rest: the energy rises from %.3g J to "
                              "%.3g J with no work done\n",
                              c->name, s < 0 ? "as given" : solvers[s].label, q.e0, q.peak);
            if (!(q.peak <= q.e0 + PASS_TOL * p.peak)) {
                failed = 1;
                print_message("  FAILED: that is more than %.0e of the peak energy %.3g J\n",
                              PASS_TOL, p.peak);
            }
            tl_voice_free(&v);
        }
    }
    tl_netlists_free(paths, n);
    assert_true(tested >= 2);
    if (failed)
        fail_msg("a nonlinear voice is not passive");
}

/* Energy that the .ic values put into the reactances and contacts of c:
 * sum of C v^2 / 2, L i^2 / 2 and k C^(alpha+1) / (alpha+1). */
static double initial_energy(const Circuit *c) {
    double *p = circuit_defaults(c), E = 0.0;
    for (int e = 0; e < c->nelems; e++) {
        const Elem *el = &c->elems[e];
        if ((el->kind == E_C || el->kind == E_L) && el->ic) {
            double x = expr_eval(el->ic, p);
            E += 0.5 * elem_value(c, el, p) * x * x;
        }
        if (el->kind == E_NL && el->nl->kind == NL_CONTACT) {
            double X = -expr_eval(el->nl->gap, p);
            for (int j = 0; j < c->nics; j++)
                if (c->ics[j].fn == 'x')
                    X += (c->ics[j].node == el->n[0] ? 1 : c->ics[j].node == el->n[1] ? -1 : 0) *
                         expr_eval(c->ics[j].val, p);
            double a = expr_eval(el->nl->alpha, p);
            if (X > 0)
                E += expr_eval(el->nl->k, p) * pow(X, a + 1) / (a + 1);
        }
    }
    return E;
}

/* Renders a voice without inputs for nframes at fs, one sample per
 * process call, and with c != NULL refsim of c beside it.  Checks that
 * every output stays finite, that the energy starts at E0 (to 1e-12) and
 * never exceeds it (to 1e-12), and, if `monotone`, that it never rises
 * from one sample to the next (beyond DECAY_TOL of E0).  Returns 0 or -1
 * after reporting; *worst gets the largest rise relative to E0 (with the
 * reference's at the same sample in *ref_worst), *emax the largest
 * energy relative to E0. */
static int free_run(const wdv_class *cls, const Circuit *c, const char *what, double fs,
                    long nframes, double E0, int monotone, double *worst, double *ref_worst,
                    double *emax) {
    void *st = tl_state_new(cls, fs);
    assert_non_null(st);
    refsim *rs = c ? refsim_new(c, fs, NULL) : NULL;
    assert_true(!c || rs);
    double y[MAXOUT], o[MAXOUT];
    double *op[MAXOUT];
    for (int k = 0; k < MAXOUT; k++)
        op[k] = &y[k];
    int bad = 0, shown = 0;
    double E = cls->energy(st), Er = rs ? refsim_energy(rs) : 0.0;
    *worst = -INFINITY;
    *ref_worst = 0.0;
    *emax = E / E0;
    if (!(fabs(E - E0) <= 1e-12 * E0)) {
        print_message("%s at %g Hz: initial energy %.17g, expected m v^2 / 2 = %.17g\n", what,
                      fs, E, E0);
        bad = 1;
    }
    long nonfinite_at = -1, above_at = -1;
    for (long n = 0; n < nframes; n++) {
        cls->process(st, NULL, op, 1);
        if (rs)
            refsim_step(rs, NULL, o);
        for (int k = 0; k < cls->n_outputs; k++)
            if (!isfinite(y[k]) && nonfinite_at < 0)
                nonfinite_at = n;
        double En = cls->energy(st), Ern = rs ? refsim_energy(rs) : 0.0;
        if (!((En - E) / E0 <= *worst)) {
            *worst = (En - E) / E0;
            *ref_worst = (Ern - Er) / E0;
        }
        if (!(En / E0 <= *emax))
            *emax = En / E0;
        if (!(En <= E0 * (1.0 + 1e-12)) && above_at < 0) {
            above_at = n;
            print_message("%s at %g Hz: energy %.17g at n=%ld exceeds the initial %.17g\n",
                          what, fs, En, n, E0);
        }
        if (!(En - E <= DECAY_TOL * E0) && shown < 4) {
            shown++;
            if (monotone)
                bad = 1;
            print_message("%s at %g Hz: energy rises at n=%ld: %.17g -> %.17g (by %.3g of "
                          "the initial energy)",
                          what, fs, n, E, En, (En - E) / E0);
            if (rs)
                print_message("; the reference: %.17g -> %.17g (by %.3g)", Er, Ern,
                              (Ern - Er) / E0);
            print_message("\n");
        }
        E = En;
        Er = Ern;
    }
    if (nonfinite_at >= 0)
        print_message("%s at %g Hz: non-finite output at n=%ld\n", what, fs, nonfinite_at);
    tl_state_free(st);
    refsim_free(rs);
    return bad || above_at >= 0 || nonfinite_at >= 0 ? -1 : 0;
}

static void thrown(const char *path) {
    Circuit *c = wdc_load(path);
    assert_non_null(c);
    assert_int_equal(c->ninputs, 0);
    assert_true(c->nouts <= MAXOUT);
    double E0 = initial_energy(c);
    assert_true(E0 > 0.0);
    tl_voice v;
    if (tl_voice_build_args(path, 0, NULL, NULL, &v) != 0) {
        tl_voice_free(&v);
        fail_msg("%s: the voice could not be built", path);
    }
    int failed = 0;
    static const double rates[] = {48000.0, 8000.0};
    for (int ri = 0; ri < 2; ri++) {
        double worst, rworst, emax;
        /* The energy never exceeds what the throw put in and never rises
         * from one sample to the next: the contact gives back no more
         * than its felt stored, also as it lets go within a sample. */
        if (free_run(v.cls, c, c->name, rates[ri], (long)rates[ri], E0, 1, &worst, &rworst,
                     &emax) != 0)
            failed = 1;
        print_message("%-13s %5.0f Hz, 1 s: E0 = m v^2 / 2 = %.6g J; largest rise of the "
                      "energy in one sample %.3g of E0 (the reference %.3g), largest energy "
                      "%.15g of E0\n",
                      c->name, rates[ri], E0, worst, rworst, emax);
    }
    tl_voice_free(&v);
    if (failed)
        fail_msg("%s: the energy of the thrown mass is not passive", path);
}

static void test_passivity_hammer(void **state) {
    (void)state;
    thrown("netlists/hammer_bar.wdn");
}

static void test_passivity_mallet(void **state) {
    (void)state;
    thrown("netlists/mallet_plate.wdn");
}

/* ---- 4. stability where methods fail ---- */

/* The hammer-and-bar system: a hammer mass mh against a contact
 * k C^alpha (1 + lambda dC/dt), C = xh - xb - gap, on a bar mass mb held
 * by a spring kb and a damper cb to the frame. */
typedef struct hammer_sys {
    double mh, mb, kb, cb, k, alpha, lambda, gap;
    double vh0, xh0;
} hammer_sys;

static int elem_index(const Circuit *c, const char *name) {
    for (int e = 0; e < c->nelems; e++)
        if (!strcmp(c->elems[e].name, name))
            return e;
    return -1;
}

static hammer_sys hammer_from(const Circuit *c) {
    double *p = circuit_defaults(c);
    int mh = elem_index(c, "MH"), mb = elem_index(c, "MB"), kb = elem_index(c, "KB");
    int db = elem_index(c, "DB"), h1 = elem_index(c, "H1");
    assert_true(mh >= 0 && mb >= 0 && kb >= 0 && db >= 0 && h1 >= 0);
    hammer_sys h;
    h.mh = elem_value(c, &c->elems[mh], p);
    h.mb = elem_value(c, &c->elems[mb], p);
    h.kb = 1.0 / elem_value(c, &c->elems[kb], p);
    h.cb = 1.0 / elem_value(c, &c->elems[db], p);
    const NlSpec *nl = c->elems[h1].nl;
    h.k = expr_eval(nl->k, p);
    h.alpha = expr_eval(nl->alpha, p);
    h.lambda = expr_eval(nl->lambda, p);
    h.gap = expr_eval(nl->gap, p);
    h.vh0 = expr_eval(c->elems[mh].ic, p);
    h.xh0 = 0.0;
    for (int j = 0; j < c->nics; j++)
        if (c->ics[j].fn == 'x' && c->ics[j].node == c->elems[mh].n[0])
            h.xh0 = expr_eval(c->ics[j].val, p);
    return h;
}

static double hammer_force(const hammer_sys *h, double C, double vrel) {
    double d = 1.0 + h->lambda * vrel;
    return C > 0.0 && d > 0.0 ? h->k * pow(C, h->alpha) * d : 0.0;
}

static double hammer_energy(const hammer_sys *h, double xh, double vh, double xb, double vb) {
    double C = xh - xb - h->gap;
    double E = 0.5 * h->mh * vh * vh + 0.5 * h->mb * vb * vb + 0.5 * h->kb * xb * xb;
    if (C > 0.0)
        E += h->k * pow(C, h->alpha + 1.0) / (h->alpha + 1.0);
    return E;
}

/* Simulates the system for nframes at fs by forward Euler (method 0) or
 * by the trapezoidal rule with the contact force of the previous sample
 * (method 1).  Returns the largest energy over the run relative to the
 * initial one (INFINITY once anything is not finite); *after gets the
 * energy relative to the initial one when the contact first opens again. */
static double hammer_sim(const hammer_sys *h, int method, double fs, long nframes,
                         double *after) {
    double T = 1.0 / fs;
    double xh = h->xh0, vh = h->vh0, xb = 0.0, vb = 0.0;
    double E0 = hammer_energy(h, xh, vh, xb, vb), emax = 1.0;
    double up = 0.0; /* method 1: force of the previous sample */
    int closed = 0;
    *after = NAN;
    for (long n = 0; n < nframes; n++) {
        double C = xh - xb - h->gap;
        double F = hammer_force(h, C, vh - vb);
        if (method == 0) {
            double ah = -F / h->mh, ab = (F - h->kb * xb - h->cb * vb) / h->mb;
            xh += T * vh;
            xb += T * vb;
            vh += T * ah;
            vb += T * ab;
        } else {
            /* u[n] = F(state[n-1]): the force enters the step as a known
             * source, averaged with the previous sample's */
            double U = F + up;
            up = F;
            double vhn = vh - 0.5 * T * U / h->mh;
            double a = 0.25 * T * T * h->kb + 0.5 * T * h->cb;
            double vbn = (h->mb * vb + 0.5 * T * U - T * h->kb * xb - a * vb) / (h->mb + a);
            xh += 0.5 * T * (vh + vhn);
            xb += 0.5 * T * (vb + vbn);
            vh = vhn;
            vb = vbn;
        }
        double E = hammer_energy(h, xh, vh, xb, vb) / E0;
        if (!isfinite(E) || !isfinite(xh) || !isfinite(xb))
            return INFINITY;
        if (E > emax)
            emax = E;
        double Cn = xh - xb - h->gap;
        if (Cn > 0.0)
            closed = 1;
        else if (closed && isnan(*after))
            *after = E;
    }
    return emax;
}

static void test_stiff_contact(void **state) {
    (void)state;
    char var[96];
    assert_int_equal(write_variant("netlists/hammer_bar.wdn", "k=4.5e9", "k=4.5e11", var,
                                   sizeof var),
                     0);
    Circuit *c = wdc_load(var);
    assert_non_null(c);
    hammer_sys h = hammer_from(c);
    assert_true(h.k == 4.5e11);
    double E0 = initial_energy(c);
    assert_true(fabs(E0 - 0.5 * h.mh * h.vh0 * h.vh0) <= 1e-15 * E0);
    tl_voice v;
    if (tl_voice_build_args(var, 0, NULL, NULL, &v) != 0) {
        tl_voice_free(&v);
        fail_msg("the stiff hammer voice could not be built");
    }
    static const double rates[] = {8000.0, 48000.0};
    static const char *method[] = {"forward Euler", "unit delay in the loop"};
    int failed = 0;
    /* the stiff voice still solves its discrete equations */
    if (contact_vs_ref(var, "stiff hammer") != 0)
        failed = 1;
    long N = 0;
    for (int ri = 0; ri < 2; ri++) {
        double fs = rates[ri];
        N = (long)(0.2 * fs);
        for (int m = 0; m < 2; m++) {
            double after;
            double emax = hammer_sim(&h, m, fs, N, &after);
            print_message("stiff felt (k = %.3g, alpha = %g), %5.0f Hz, %-22s: largest energy "
                          "%.4g x E0, %.4g x E0 when the contact first opens\n",
                          h.k, h.alpha, fs, method[m], emax, after);
            if (!(emax > INSTABLE_GAIN)) {
                failed = 1;
                print_message("  expected %s to gain energy (above %.2f x E0) or blow up\n",
                              method[m], INSTABLE_GAIN);
            }
        }
        double worst, rworst, emax;
        int rc = free_run(v.cls, c, "stiff hammer voice", fs, N, E0, 0, &worst, &rworst, &emax);
        print_message("stiff felt (k = %.3g, alpha = %g), %5.0f Hz, %-22s: largest energy "
                      "%.15g x E0 (largest rise in one sample %.3g of E0, the reference's "
                      "%.3g)\n",
                      h.k, h.alpha, fs, "wave-digital voice", emax, worst, rworst);
        if (rc != 0)
            failed = 1;
    }
    tl_voice_free(&v);
    if (failed)
        fail_msg("stability comparison failed");
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_diode_clipper),
        cmocka_unit_test(test_diode_single),
        cmocka_unit_test(test_diode_reverse),
        cmocka_unit_test(test_fast_bound),
        cmocka_unit_test(test_fast_silence),
        cmocka_unit_test(test_fast_range),
        cmocka_unit_test(test_hammer_ref),
        cmocka_unit_test(test_mallet_ref),
        cmocka_unit_test(test_other_nonlinear),
        cmocka_unit_test(test_passivity_inputs),
        cmocka_unit_test(test_passivity_hammer),
        cmocka_unit_test(test_passivity_mallet),
        cmocka_unit_test(test_stiff_contact),
    };
    return cmocka_run_group_tests_name("nonlinear", tests, NULL, NULL);
}
