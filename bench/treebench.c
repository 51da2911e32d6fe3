/*
 * treebench.c - what a timbre tree (runtime/tt.h) costs per sample, three
 * ways: the compiled program, the per-sample post-order walk of the tree
 * that Hahn et al.'s system evaluated, and the same sound written by hand
 * in C.
 *
 *     build/bench/treebench
 *
 * Run from the repository root (as `make bench` does).  The trees: two
 * of the demos' (scenes/lib/), the rest read from TREES below:
 *   drum20       scenes/lib/drum.tt, Hahn et al.'s drum: the sum of 20
 *                damped sines, frequencies from rvector 200..10000 Hz;
 *   drum64       the same with 64 modes (and the same defaults);
 *   fm_siren     an FM siren: a 600 Hz sine, its phase swung by a 0.7 Hz
 *                sine of depth 3 cycles;
 *   siren        scenes/lib/siren.tt: a band-limited square swept
 *                exponentially between two pitches, through a highpass
 *                and a lowpass;
 *   noise_lp     white noise through a biquad lowpass;
 *   osc_lp       a band-limited saw oscillator with vibrato, through a
 *                lowpass;
 *   importance4  four sines mixed by importance (Tong and Wong), one of
 *                them locked;
 *   energetic17  a sine replayed at speed 1.7 (Tong and Wong);
 *   sputter12    a saw sputtering from 12 Hz down to 1 Hz over 2 s.
 *
 * The evaluators, at 48 kHz:
 *   compiled  tt_compile, then a state of its tt_class (tl_state_new,
 *             tt_class_bind) run by the class's process in blocks of
 *             TT_BLOCK frames;
 *   walk      the evaluator of the paper: at every sample t = n/fs and
 *             the params are bound, and the tree of tt_node is traversed
 *             in post-order (the arguments, then the node), each node's
 *             value a small array of its width.  What a node keeps from
 *             sample to sample (a filter's or an oscillator's state, the
 *             replay's ring) lives in a side table, one slot per node in
 *             the order the walk visits them, and so do rvector's values,
 *             drawn once (tt_rvector_u) as the paper's system drew its
 *             random vectors once;
 *   hand      the drums and the sirens as a C programmer would write
 *             them: one loop over samples (and modes) calling sin, exp
 *             and pow, the modes' frequencies from tt_rvector_u, the
 *             siren's filters designed once, its params' defaults read
 *             from the tree.
 * The walk and the hand C are built with the runtime's flags (the
 * Makefile's CFLAGS).  Every evaluator restarts its tree every PERIOD
 * frames (the compiled one by its class's reset), a strike every 2 s: time
 * stays small, and a drum's modes never decay into subnormal numbers.
 *
 * First each evaluator renders two periods; the first is compared with
 * tt_render of the tree (the largest difference relative to tt_render's
 * peak; the walk computes sines and exponentials of time directly where
 * the program runs recurrences, so they agree to rounding, not bit for
 * bit), and the compiled class's second with its first (its reset
 * restarts the tree).  The walk's noise cannot be the program's (its seed
 * is private): only its RMS is compared.  Then ns per sample: RUNS rounds
 * in which the evaluators of the tree take turns, each run a
 * bench_measure of at least SPAN s after WARM s untimed; the best run of
 * each evaluator counts.
 *
 * A benchmark, not a test: nothing is asserted about times.  The exit
 * status is non-zero if a tree could not be read or compiled, a render
 * was not finite, or an evaluator disagreed with tt_render by more than
 * TOL relative to its peak (a noise's RMS by more than 5 %).
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "benchlib.h"
#include "tt.h"
#include "../tests/testlib.h"

#define FS 48000.0
#define BLOCK TT_BLOCK
#define PERIOD 96000L /* frames between restarts (2 s); a multiple of BLOCK */
#define RUNS 7     /* rounds, the evaluators of a tree taking turns */
#define WARM 0.03  /* s untimed before each run */
#define SPAN 0.15  /* s of wall time, at least, per run */
#define TOL 1e-9 /* largest relative difference from tt_render that passes */
#define TWO_PI 6.283185307179586476925286766559

static const char TREES[] =
    "(tree drum64 (params (loudness 0.05) (damping 0.0005))\n"
    "  (* loudness (combine (* (sine (* (rvector 200 64 10000) t))\n"
    "                          (damp (* (rvector 200 64 10000) (* damping t)))))))\n"
    "(tree fm_siren (params (depth 3))\n"
    "  (* 0.5 (sine (+ (* 600 t) (* depth (sine (* 0.7 t)))))))\n"
    "(tree noise_lp (params (cutoff 800))\n"
    "  (* 0.5 (lowpass (noise) cutoff 2)))\n"
    "(tree osc_lp (params (cutoff 1500))\n"
    "  (* 0.3 (lowpass (osc (+ 220 (* 30 (sine (* 5 t)))) saw) cutoff 0.9)))\n"
    "(tree importance4 (params (w0 4))\n"
    "  (importance ((sine (* 220 t)) w0) ((sine (* 277 t)) 2 lock)\n"
    "              ((sine (* 330 t)) 1) ((sine (* 440 t)) 1)))\n"
    "(tree energetic17 (params (speed 1.7))\n"
    "  (energetic (* 0.5 (sine (* 440 t))) speed))\n"
    "(tree sputter12 (params (f0 12))\n"
    "  (sputter (* 0.5 (saw (* 110 t))) f0 1 2))\n";

enum { H_NONE, H_DRUM, H_FMSIREN, H_SIREN }; /* hand-written C */

/* The trees in the order of the table: from TREES (file NULL) or from a
 * file of the demos, and their hand C. */
static const struct {
    const char *label, *file, *name;
    int hand;  /* H_* */
    int modes; /* H_DRUM */
} g_trees[] = {
    {"drum20", "scenes/lib/drum.tt", "drum", H_DRUM, 20},
    {"drum64", NULL, "drum64", H_DRUM, 64},
    {"fm_siren", NULL, "fm_siren", H_FMSIREN, 0},
    {"siren", "scenes/lib/siren.tt", "siren", H_SIREN, 0},
    {"noise_lp", NULL, "noise_lp", H_NONE, 0},
    {"osc_lp", NULL, "osc_lp", H_NONE, 0},
    {"importance4", NULL, "importance4", H_NONE, 0},
    {"energetic17", NULL, "energetic17", H_NONE, 0},
    {"sputter12", NULL, "sputter12", H_NONE, 0},
};
#define NTREES ((int)(sizeof g_trees / sizeof g_trees[0]))

static void *xcalloc(size_t n, size_t size) {
    void *p = calloc(n ? n : 1, size);
    if (!p) {
        fprintf(stderr, "treebench: out of memory\n");
        exit(1);
    }
    return p;
}

/* ---- the walk: Hahn et al.'s per-sample post-order evaluator ---- */

/* A node's place in the side table. */
typedef struct wslot {
    double *v;          /* [width]: the node's value at this sample */
    const double **arg; /* [n]: its arguments' values */
    double *s;          /* [ns]: what a stateful node remembers */
    int ns;
    double *u;          /* rvector: tt_rvector_u(N, i) */
    uint64_t rng;       /* noise: xorshift state */
    int size;           /* energetic: the nodes of its argument X */
} wslot;

typedef struct walk {
    const tt_tree *tree;
    double fs, t;
    double par[TT_MAX_PARAMS];
    long n;      /* the next sample */
    int nslot;   /* nodes */
    int next;    /* slot of the next node the walk visits */
    wslot *slot; /* [nslot] */
    float *sinc; /* energetic: the windowed sinc, or NULL */
    const char *unsupported; /* the name of an op the walk does not know, or NULL */
} walk;

/* The energetic replay: a Kaiser-windowed sinc (beta 9) of SINC_H zero
 * crossings each side, tabulated in float at SINC_RES points per unit and
 * read linearly, and a ring of RING frames of the argument per element,
 * as tt_run.c replays (the walk must do the same work to make the same
 * sound: X may keep state, so it cannot simply be evaluated at 1.7 t). */
#define SINC_H 16
#define SINC_RES 512
#define RING 1024

static double bessel_i0(double x) {
    double s = 1, term = 1;
    for (int k = 1; k < 60 && term >= 1e-17 * s; k++) {
        term *= (x / (2 * k)) * (x / (2 * k));
        s += term;
    }
    return s;
}

static float *sinc_table(void) {
    int n = SINC_H * SINC_RES + 2;
    float *tab = xcalloc((size_t)n, sizeof(float));
    double i0b = bessel_i0(9.0);
    for (int i = 0; i < n; i++) {
        double u = (double)i / SINC_RES, r = u / SINC_H;
        double win = r < 1 ? bessel_i0(9.0 * sqrt(1 - r * r)) / i0b : 0;
        tab[i] = (float)(i == 0 ? 1 : sin(M_PI * u) / (M_PI * u) * win);
    }
    return tab;
}

static double sinc_at(const float *tab, double u) {
    u = fabs(u) * SINC_RES;
    if (u >= SINC_H * SINC_RES)
        return 0;
    int j = (int)u;
    double f = u - j;
    return tab[j] + f * (tab[j + 1] - tab[j]);
}

/* Doubles of state a node keeps. */
static int wk_nstate(const tt_node *x) {
    switch (x->op) {
    case TT_OSC: return x->width;              /* phase */
    case TT_LOWPASS:                           /* x1 x2 y1 y2 */
    case TT_HIGHPASS:
    case TT_BANDPASS: return 4 * x->width;
    case TT_SPUTTER: return 1;                 /* phase */
    case TT_ENERGETIC: return 2 + RING * x->width; /* tau, frames made, the rings */
    default: return 0;
    }
}

/* Gives x and its subtree their slots, in the order wk_eval visits them. */
static void wk_setup(walk *w, const tt_node *x) {
    wslot *sl = &w->slot[w->next++];
    sl->v = xcalloc((size_t)x->width, sizeof(double));
    sl->arg = xcalloc((size_t)x->n, sizeof(double *));
    sl->ns = wk_nstate(x);
    if (sl->ns)
        sl->s = xcalloc((size_t)sl->ns, sizeof(double));
    if (x->op == TT_RVECTOR) {
        sl->u = xcalloc((size_t)x->width, sizeof(double));
        for (int i = 0; i < x->width; i++)
            sl->u[i] = tt_rvector_u(x->width, i);
    }
    if (x->op == TT_ENERGETIC) {
        sl->size = tt_node_count(x->a[0]);
        if (!w->sinc)
            w->sinc = sinc_table();
    }
    for (int i = 0; i < x->n; i++)
        wk_setup(w, x->a[i]);
}

static void wk_restart(walk *w) {
    w->n = 0;
    for (int k = 0; k < w->nslot; k++) {
        if (w->slot[k].ns)
            memset(w->slot[k].s, 0, sizeof(double) * (size_t)w->slot[k].ns);
        w->slot[k].rng = 0x9E3779B97F4A7C15ull * (uint64_t)(k + 1) | 1;
    }
}

static void wk_init(walk *w, const tt_tree *t, double fs) {
    memset(w, 0, sizeof *w);
    w->tree = t;
    w->fs = fs;
    for (int i = 0; i < t->nparams; i++)
        w->par[i] = t->pdef[i];
    w->nslot = tt_node_count(t->root);
    w->slot = xcalloc((size_t)w->nslot, sizeof(wslot));
    wk_setup(w, t->root);
    wk_restart(w);
}

static void wk_free(walk *w) {
    for (int k = 0; k < w->nslot; k++) {
        free(w->slot[k].v);
        free(w->slot[k].arg);
        free(w->slot[k].s);
        free(w->slot[k].u);
    }
    free(w->slot);
    free(w->sinc);
}

/* Argument j of x at element i, a scalar broadcast. */
#define ARG(j, i) (x->a[j]->width == 1 ? sl->arg[j][0] : sl->arg[j][i])

static double frac(double x) { return x - floor(x); }

/* Uniform in [-1, 1): the generator of tt_run.c (xorshift64, then a
 * multiply), seeded per node. */
static double wk_noise(wslot *sl) {
    uint64_t x = sl->rng;
    x ^= x >> 12;
    x ^= x << 25;
    x ^= x >> 27;
    sl->rng = x;
    return (double)((x * 2685821657736338717ull) >> 11) * 0x1.0p-53 * 2 - 1;
}

/* A pure function of one number. */
static double wk_math1(tt_op op, double a) {
    switch (op) {
    case TT_EXP: return exp(a);
    case TT_LOG: return log(a);
    case TT_SQRT: return sqrt(a);
    case TT_ABS: return fabs(a);
    case TT_SIN: return sin(a);
    case TT_COS: return cos(a);
    case TT_FLOOR: return floor(a);
    case TT_TANH: return tanh(a);
    case TT_DAMP: return exp(-a);
    case TT_SINE: return sin(TWO_PI * a);
    case TT_SAW: return 2 * frac(a + 0.5) - 1;
    case TT_SQUARE: return frac(a) < 0.5 ? 1 : -1;
    case TT_TRIANGLE: return 1 - 4 * fabs(frac(a + 0.25) - 0.5);
    default: return NAN;
    }
}

/* An arithmetic node over its arguments, element by element. */
static void wk_arith(const tt_node *x, wslot *sl) {
    for (int i = 0; i < x->width; i++) {
        double r = ARG(0, i);
        switch (x->op) {
        case TT_ADD:
            for (int j = 1; j < x->n; j++)
                r += ARG(j, i);
            break;
        case TT_SUB:
            if (x->n == 1)
                r = -r;
            for (int j = 1; j < x->n; j++)
                r -= ARG(j, i);
            break;
        case TT_MUL:
            for (int j = 1; j < x->n; j++)
                r *= ARG(j, i);
            break;
        case TT_DIV: r /= ARG(1, i); break;
        case TT_POW: r = pow(r, ARG(1, i)); break;
        case TT_MIN:
            for (int j = 1; j < x->n; j++)
                r = fmin(r, ARG(j, i));
            break;
        case TT_MAX:
            for (int j = 1; j < x->n; j++)
                r = fmax(r, ARG(j, i));
            break;
        default: r = wk_math1(x->op, r); break;
        }
        sl->v[i] = r;
    }
}

/* A biquad (the Audio EQ Cookbook's lowpass, highpass and bandpass of
 * constant peak gain, F clamped to (0, fs/2) and Q to [1e-3, 1e3] as
 * tt_run.c clamps them), its coefficients made at every sample, direct
 * form I; state x1 x2 y1 y2 per element. */
static void wk_biquad(walk *w, const tt_node *x, wslot *sl) {
    for (int i = 0; i < x->width; i++) {
        double in = ARG(0, i), f = ARG(1, i) / w->fs, q = x->n > 2 ? ARG(2, i) : M_SQRT1_2;
        f = !(f > 1e-6) ? 1e-6 : f > 0.4999 ? 0.4999 : f;
        q = !(q > 1e-3) ? 1e-3 : q > 1e3 ? 1e3 : q;
        double w0 = TWO_PI * f, c = cos(w0), al = sin(w0) / (2 * q);
        double b0, b1, b2;
        if (x->op == TT_LOWPASS)
            b0 = (1 - c) / 2, b1 = 1 - c, b2 = b0;
        else if (x->op == TT_HIGHPASS)
            b0 = (1 + c) / 2, b1 = -(1 + c), b2 = b0;
        else
            b0 = al, b1 = 0, b2 = -al;
        double a0 = 1 + al, a1 = -2 * c, a2 = 1 - al;
        double *s = sl->s + 4 * i;
        double y = (b0 * in + b1 * s[0] + b2 * s[1] - a1 * s[2] - a2 * s[3]) / a0;
        s[1] = s[0], s[0] = in, s[3] = s[2], s[2] = y;
        sl->v[i] = y;
    }
}

/* PolyBLEP: the correction of a unit step at phase 0 of a phase t that
 * advances dt per sample. */
static double blep(double t, double dt) {
    if (t < dt) {
        t /= dt;
        return 2 * t - t * t - 1;
    }
    if (t > 1 - dt) {
        t = (t - 1) / dt;
        return t * t + 2 * t + 1;
    }
    return 0;
}

/* (osc F SHAPE): phase p_0 = 0, p_{n+1} = frac(p_n + F_n / fs); saw and
 * square band-limited by polyBLEP. */
static void wk_osc(walk *w, const tt_node *x, wslot *sl) {
    for (int i = 0; i < x->width; i++) {
        double p = sl->s[i], dt = ARG(0, i) / w->fs, adt = fabs(dt), y;
        if (!isfinite(dt))
            dt = adt = 0;
        adt = adt > 0.5 ? 0.5 : adt;
        switch ((int)x->v) {
        case TT_SHAPE_SINE: y = sin(TWO_PI * p); break;
        case TT_SHAPE_SAW: {
            double q = frac(p + 0.5);
            y = 2 * q - 1 - (adt > 0 ? blep(q, adt) : 0);
            break;
        }
        case TT_SHAPE_SQUARE:
            y = (p < 0.5 ? 1 : -1) + (adt > 0 ? blep(p, adt) - blep(frac(p + 0.5), adt) : 0);
            break;
        default: y = 1 - 4 * fabs(frac(p + 0.25) - 0.5); break;
        }
        sl->v[i] = y;
        sl->s[i] = frac(p + dt);
    }
}

#define MAX_ENTRIES 256 /* of an importance node the walk takes */

/* (importance (X W [lock])...): the weights of this sample (tt_importance,
 * locks in x->k), then the weighted sum.  (The program ramps a change of
 * weights over a block; the walk steps at the sample.) */
static void wk_importance(const tt_node *x, wslot *sl) {
    int ne = x->n / 2;
    double wt[MAX_ENTRIES], wv[MAX_ENTRIES];
    for (int j = 0; j < ne; j++)
        wt[j] = sl->arg[2 * j + 1][0];
    tt_importance(ne, wt, x->k, wv);
    for (int i = 0; i < x->width; i++) {
        double y = 0;
        for (int j = 0; j < ne; j++)
            y += wv[j] * ARG(2 * j, i);
        sl->v[i] = y;
    }
}

/* (sputter X F0 F1 DUR): X times falling ramps whose rate glides
 * exponentially from F0 to F1 over DUR s, rising over min(0.5, 0.002 f)
 * of each cycle. */
static void wk_sputter(walk *w, const tt_node *x, wslot *sl) {
    double F0 = sl->arg[1][0], F1 = sl->arg[2][0], D = sl->arg[3][0], fmax = 0.25 * w->fs;
    F0 = !(F0 > 1e-3) ? 1e-3 : F0 > fmax ? fmax : F0;
    F1 = !(F1 > 1e-3) ? 1e-3 : F1 > fmax ? fmax : F1;
    double f = D > 0 && w->t < D ? F0 * pow(F1 / F0, w->t / D) : F1;
    double fr = frac(sl->s[0]), a = 0.002 * f;
    a = a > 0.5 ? 0.5 : a;
    double env = fr < a ? fr / a : (1 - fr) / (1 - a);
    sl->s[0] = frac(sl->s[0] + f / w->fs);
    for (int i = 0; i < x->width; i++)
        sl->v[i] = ARG(0, i) * env;
}

/* The node x, its arguments' values in sl->arg, into sl->v. */
static void wk_node(walk *w, const tt_node *x, wslot *sl) {
    switch (x->op) {
    case TT_NUM: sl->v[0] = x->v; break;
    case TT_PARAM: sl->v[0] = w->par[(int)x->v]; break;
    case TT_T: sl->v[0] = w->t; break;
    case TT_FS: sl->v[0] = w->fs; break;
    case TT_ADD: case TT_SUB: case TT_MUL: case TT_DIV: case TT_POW: case TT_MIN: case TT_MAX:
    case TT_EXP: case TT_LOG: case TT_SQRT: case TT_ABS: case TT_SIN: case TT_COS: case TT_FLOOR:
    case TT_TANH: case TT_DAMP: case TT_SINE: case TT_SAW: case TT_SQUARE: case TT_TRIANGLE:
        wk_arith(x, sl);
        break;
    case TT_NOISE: sl->v[0] = wk_noise(sl); break;
    case TT_OSC: wk_osc(w, x, sl); break;
    case TT_LOWPASS: case TT_HIGHPASS: case TT_BANDPASS: wk_biquad(w, x, sl); break;
    case TT_VECTOR: {
        int k = 0;
        for (int j = 0; j < x->n; j++)
            for (int i = 0; i < x->a[j]->width; i++)
                sl->v[k++] = sl->arg[j][i];
        break;
    }
    case TT_RVECTOR: {
        double lo = sl->arg[0][0], hi = sl->arg[1][0];
        for (int i = 0; i < x->width; i++)
            sl->v[i] = lo + (hi - lo) * sl->u[i];
        break;
    }
    case TT_COMBINE: {
        double s = 0;
        for (int i = 0; i < x->a[0]->width; i++)
            s += sl->arg[0][i];
        sl->v[0] = s;
        break;
    }
    case TT_SPUTTER: wk_sputter(w, x, sl); break;
    case TT_IMPORTANCE:
        if (x->n / 2 <= MAX_ENTRIES) {
            wk_importance(x, sl);
            break;
        }
        /* fall through */
    default:
        if (!w->unsupported)
            w->unsupported = tt_ops[x->op].name;
        for (int i = 0; i < x->width; i++)
            sl->v[i] = 0;
        break;
    }
}

static const double *wk_eval(walk *w, const tt_node *x);

/* (energetic X SPEED): X runs on its own clock, one frame at a time as
 * far as the window needs, into a ring; the output is the windowed sinc
 * at X's time tau (advancing SPEED frames per sample), its cutoff falling
 * as 1/SPEED above 1.  X's slots are visited once per frame of X. */
static void wk_energetic(walk *w, const tt_node *x, wslot *sl) {
    int base = w->next, W = x->width;
    w->next = base + sl->size;
    double speed = wk_eval(w, x->a[1])[0];
    int end = w->next;
    double *tau = &sl->s[0], *made = &sl->s[1], *ring = sl->s + 2, t = w->t;
    speed = !(speed > 0) ? 0 : speed > TT_MAX_SPEED ? TT_MAX_SPEED : speed;
    double c = speed > 1 ? 1 / speed : 1, half = SINC_H / c;
    long hi = (long)floor(*tau + half), lo = (long)ceil(*tau - half);
    while ((long)*made <= hi) {
        long m = (long)*made;
        w->next = base;
        w->t = (double)m / w->fs;
        const double *y = wk_eval(w, x->a[0]);
        for (int k = 0; k < W; k++)
            ring[k * RING + (m & (RING - 1))] = y[x->a[0]->width == 1 ? 0 : k];
        *made += 1;
    }
    w->t = t;
    w->next = end;
    lo = lo < 0 ? 0 : lo;
    lo = lo < (long)*made - RING ? (long)*made - RING : lo;
    for (int k = 0; k < W; k++) {
        double acc = 0;
        for (long j = lo; j <= hi; j++)
            acc += ring[k * RING + (j & (RING - 1))] * sinc_at(w->sinc, c * (*tau - (double)j));
        sl->v[k] = c * acc;
    }
    *tau += speed;
}

/* Post-order: the arguments, then the node. */
static const double *wk_eval(walk *w, const tt_node *x) {
    wslot *sl = &w->slot[w->next++];
    if (x->op == TT_ENERGETIC) {
        wk_energetic(w, x, sl);
        return sl->v;
    }
    for (int i = 0; i < x->n; i++)
        sl->arg[i] = wk_eval(w, x->a[i]);
    wk_node(w, x, sl);
    return sl->v;
}

static void wk_run(walk *w, double *out, int nframes) {
    for (int k = 0; k < nframes; k++) {
        w->t = (double)w->n / w->fs;
        w->next = 0;
        out[k] = wk_eval(w, w->tree->root)[0];
        w->n++;
    }
}

/* ---- hand-written C ---- */

/* An RBJ biquad, transposed direct form II, coefficients over a0. */
typedef struct biquad {
    double b0, b1, b2, a1, a2, z1, z2;
} biquad;

static void biquad_design(biquad *q, int highpass, double f, double q_) {
    double w0 = TWO_PI * f / FS, c = cos(w0), al = sin(w0) / (2 * q_), a0 = 1 + al;
    q->b0 = (highpass ? 1 + c : 1 - c) / 2 / a0;
    q->b1 = (highpass ? -(1 + c) : 1 - c) / a0;
    q->b2 = q->b0;
    q->a1 = -2 * c / a0;
    q->a2 = (1 - al) / a0;
    q->z1 = q->z2 = 0;
}

static double biquad_run(biquad *q, double x) {
    double y = q->b0 * x + q->z1;
    q->z1 = q->b1 * x - q->a1 * y + q->z2;
    q->z2 = q->b2 * x - q->a2 * y;
    return y;
}

typedef struct hand {
    int kind; /* H_* */
    int nm;   /* a drum's modes */
    double w[TT_MAX_WIDTH], d[TT_MAX_WIDTH]; /* rad/s, 1/s */
    double gain, depth;                      /* a drum's loudness; fm_siren's depth */
    double low, high, rate, phase;           /* siren: Hz, Hz, Hz, cycles */
    biquad hp, lp;
    long n;
} hand;

/* The default of param `name` of t. */
static double pdef(const tt_tree *t, const char *name) {
    for (int i = 0; i < t->nparams; i++)
        if (!strcmp(t->pname[i], name))
            return t->pdef[i];
    fprintf(stderr, "treebench: tree %s has no param %s\n", t->name, name);
    exit(1);
}

static void hand_init(hand *h, int kind, int modes, const tt_tree *t) {
    memset(h, 0, sizeof *h);
    h->kind = kind;
    if (kind == H_DRUM) {
        h->nm = modes;
        h->gain = pdef(t, "loudness");
        for (int i = 0; i < modes; i++) {
            double f = 200 + (10000 - 200) * tt_rvector_u(modes, i);
            h->w[i] = TWO_PI * f;
            h->d[i] = f * pdef(t, "damping");
        }
    } else if (kind == H_FMSIREN)
        h->depth = pdef(t, "depth");
    else if (kind == H_SIREN) {
        h->low = pdef(t, "low"), h->high = pdef(t, "high"), h->rate = pdef(t, "rate");
        h->gain = pdef(t, "level");
        biquad_design(&h->hp, 1, 450, M_SQRT1_2);
        biquad_design(&h->lp, 0, 3500, M_SQRT1_2);
    }
}

static void hand_restart(hand *h) {
    h->n = 0;
    h->phase = 0;
    h->hp.z1 = h->hp.z2 = h->lp.z1 = h->lp.z2 = 0;
}

/* (* loudness (combine (* (sine (* F t)) (damp (* F (* damping t)))))) */
static void hand_drum(hand *h, double *out, int nframes) {
    for (int k = 0; k < nframes; k++, h->n++) {
        double t = (double)h->n / FS, s = 0;
        for (int i = 0; i < h->nm; i++)
            s += sin(h->w[i] * t) * exp(-h->d[i] * t);
        out[k] = h->gain * s;
    }
}

static void hand_fm_siren(hand *h, double *out, int nframes) {
    for (int k = 0; k < nframes; k++, h->n++) {
        double t = (double)h->n / FS;
        out[k] = 0.5 * sin(TWO_PI * (600 * t + h->depth * sin(TWO_PI * 0.7 * t)));
    }
}

/* scenes/lib/siren.tt: a polyBLEP square swept exponentially between low
 * and high, through a 450 Hz highpass and a 3500 Hz lowpass. */
static void hand_siren(hand *h, double *out, int nframes) {
    for (int k = 0; k < nframes; k++, h->n++) {
        double t = (double)h->n / FS;
        double f = h->low * pow(h->high / h->low, 0.5 + 0.5 * sin(TWO_PI * (h->rate * t - 0.25)));
        double p = h->phase, dt = f / FS;
        double y = (p < 0.5 ? 1 : -1) + blep(p, dt) - blep(frac(p + 0.5), dt);
        h->phase = frac(p + dt);
        out[k] = h->gain * biquad_run(&h->lp, biquad_run(&h->hp, y));
    }
}

static void hand_run(hand *h, double *out, int nframes) {
    if (h->kind == H_DRUM)
        hand_drum(h, out, nframes);
    else if (h->kind == H_FMSIREN)
        hand_fm_siren(h, out, nframes);
    else
        hand_siren(h, out, nframes);
}

/* ---- the compiled program ---- */

typedef struct compiled {
    tt_class c;
    void *state;
} compiled;

static void comp_run(compiled *p, double *out, int nframes) {
    double *outs[1] = {out};
    p->c.cls.process(p->state, NULL, outs, nframes);
}

/* ---- measuring ---- */

enum { E_COMP, E_WALK, E_HAND, NEVAL };

/* One evaluator of one tree, as bench_measure drives it. */
typedef struct runner {
    int kind;   /* E_* */
    compiled *comp;
    walk *walk;
    hand *hand;
    long pos;   /* frames since the last restart */
    double sink;
} runner;

static void restart(runner *r) {
    if (r->kind == E_COMP)
        r->comp->c.cls.reset(r->comp->state);
    else if (r->kind == E_WALK)
        wk_restart(r->walk);
    else
        hand_restart(r->hand);
    r->pos = 0;
}

/* nframes (at most BLOCK) of r; restarts it every PERIOD frames. */
static void run(runner *r, double *out, int nframes) {
    if (r->pos >= PERIOD)
        restart(r);
    if (r->kind == E_COMP)
        comp_run(r->comp, out, nframes);
    else if (r->kind == E_WALK)
        wk_run(r->walk, out, nframes);
    else
        hand_run(r->hand, out, nframes);
    r->pos += nframes;
}

static void render_blocks(void *ctx, long nblocks) {
    runner *r = ctx;
    double out[BLOCK];
    for (long b = 0; b < nblocks; b++) {
        run(r, out, BLOCK);
        r->sink += out[BLOCK - 1];
    }
}

/* Renders n frames of r from where it stands into out. */
static void render(runner *r, double *out, long n) {
    for (long pos = 0; pos < n; pos += BLOCK)
        run(r, out + pos, (int)(n - pos < BLOCK ? n - pos : BLOCK));
}

/* The largest |a - b| relative to the peak of ref; -1 if a is not finite. */
static double rel_diff(const double *a, const double *ref, long n) {
    double d = 0, pk = 0;
    for (long i = 0; i < n; i++) {
        if (!isfinite(a[i]))
            return -1;
        d = fmax(d, fabs(a[i] - ref[i]));
        pk = fmax(pk, fabs(ref[i]));
    }
    return pk > 0 ? d / pk : d;
}

static double rms(const double *x, long n) {
    double s = 0;
    for (long i = 0; i < n; i++)
        s += x[i] * x[i];
    return sqrt(s / (double)n);
}


typedef struct result {
    int ninstr, nodes;
    double ns[NEVAL];   /* NAN: not measured */
    double diff[NEVAL]; /* relative to tt_render; -1: not finite; NAN: not compared */
    double restart;     /* the compiled class's second period against its first */
    double rms;         /* a tree with noise: RMS of the walk / of tt_render */
    const char *why;    /* why the walk was not measured */
} result;

static void cell(char *buf, size_t cap, const char *fmt, double v) {
    if (isnan(v))
        snprintf(buf, cap, "-");
    else
        snprintf(buf, cap, fmt, v);
}

/* Compares and times the evaluators of tree t, with hand C of kind
 * hand (H_*) and modes; 0, or -1 if it failed. */
static int bench_tree(const tt_tree *t, int hand_kind, int modes, result *res) {
    char err[1024];
    for (int e = 0; e < NEVAL; e++)
        res->ns[e] = res->diff[e] = NAN;
    res->restart = res->rms = NAN;
    res->why = NULL;
    res->ninstr = -1;
    res->nodes = tt_node_count(t->root);
    tt_prog *p = tt_compile(t, err, sizeof err);
    if (!p) {
        fprintf(stderr, "treebench: %s: %s\n", t->name, err);
        return -1;
    }
    res->ninstr = tt_prog_ninstr(p);
    compiled comp;
    if (tt_class_init(&comp.c, p, FS, err, sizeof err) != 0) {
        fprintf(stderr, "treebench: %s: %s\n", t->name, err);
        tt_prog_free(p);
        return -1;
    }
    comp.state = tl_state_new(&comp.c.cls, FS);
    if (!comp.state) {
        fprintf(stderr, "treebench: out of memory\n");
        exit(1);
    }
    tt_class_bind(comp.state, &comp.c);

    double *ref = xcalloc(PERIOD, sizeof(double)), *out = xcalloc(2 * PERIOD, sizeof(double));
    int failed = tt_render(p, FS, NULL, ref, PERIOD, err, sizeof err) != 0;
    if (failed)
        fprintf(stderr, "treebench: %s: tt_render: %s\n", t->name, err);

    walk w;
    wk_init(&w, t, FS);
    hand h;
    hand_init(&h, hand_kind, modes, t);
    runner rs[NEVAL] = {{E_COMP, &comp, NULL, NULL, 0, 0}, {E_WALK, NULL, &w, NULL, 0, 0},
                        {E_HAND, NULL, NULL, &h, 0, 0}};
    int use[NEVAL] = {1, 1, hand_kind != H_NONE}, noisy = tt_node_has(t->root, TT_NOISE);
    for (int e = 0; e < NEVAL && !failed; e++) {
        if (!use[e])
            continue;
        runner *r = &rs[e];
        render(r, out, 2 * PERIOD); /* two periods: the second after a restart */
        restart(r);
        if (e == E_WALK && w.unsupported) {
            res->why = w.unsupported;
            use[e] = 0;
            continue;
        }
        if (e == E_WALK && noisy) { /* another seed: compare the level */
            res->rms = rms(out, PERIOD) / rms(ref, PERIOD);
            failed |= !(fabs(res->rms - 1) < 0.05);
            continue;
        }
        res->diff[e] = rel_diff(out, ref, PERIOD);
        if (e == E_COMP)
            res->restart = rel_diff(out + PERIOD, out, PERIOD);
        failed |= !(res->diff[e] >= 0 && res->diff[e] <= TOL);
    }
    /* rounds, the evaluators taking turns; the best run of each counts */
    for (int round = 0; round < RUNS && !failed; round++)
        for (int e = 0; e < NEVAL; e++)
            if (use[e]) {
                double ns = bench_measure(render_blocks, &rs[e], BLOCK, 1, WARM, SPAN);
                res->ns[e] = round == 0 || ns < res->ns[e] ? ns : res->ns[e];
            }
    for (int e = 0; e < NEVAL; e++)
        failed |= !isfinite(rs[e].sink);
    wk_free(&w);
    free(ref);
    free(out);
    tl_state_free(comp.state);
    tt_class_uninit(&comp.c);
    tt_prog_free(p);
    return failed ? -1 : 0;
}

static void print_row(const char *label, const result *r) {
    char c[8][32];
    cell(c[0], 32, "%.1f", r->ns[E_COMP]);
    cell(c[1], 32, "%.1f", r->ns[E_WALK]);
    cell(c[2], 32, "%.1f", r->ns[E_HAND]);
    cell(c[3], 32, "%.1fx", r->ns[E_WALK] / r->ns[E_COMP]);
    cell(c[4], 32, "%.2fx", r->ns[E_COMP] / r->ns[E_HAND]);
    cell(c[5], 32, "%.1e", r->diff[E_WALK]);
    if (!isnan(r->rms))
        snprintf(c[5], 32, "rms%.3f", r->rms);
    cell(c[6], 32, "%.1e", r->diff[E_HAND]);
    cell(c[7], 32, "%.1e", r->restart);
    printf("%-11s %5d %5d %9s %9s %9s %9s %9s %9s %9s %9s", label, r->nodes, r->ninstr, c[0], c[1], c[2], c[3],
           c[4], c[5], c[6], c[7]);
    if (r->why)
        printf("  (walk: no %s)", r->why);
    printf("\n");
    fflush(stdout);
}

int main(int argc, char **argv) {
    (void)argv;
    if (argc > 1) {
        fprintf(stderr, "usage: treebench\n");
        return 2;
    }
    double t_start = bench_now();
    char err[1024], cpu[256];
    tt_file *f = tt_file_read("scenes/treebench.tt", TREES, sizeof TREES - 1, err, sizeof err);
    if (!f) {
        fprintf(stderr, "treebench: %s\n", err);
        return 1;
    }
    bench_cpu_model(cpu, sizeof cpu);
    printf("timbre tree benchmark: %.0f Hz, one tree at a time restarted every %.0f s; the compiled program\n"
           "(a tt_class state, process in blocks of %d), Hahn et al.'s per-sample post-order walk of the\n"
           "tree, and hand-written C (sin, exp, pow in one loop over samples and modes); best of %d runs of\n"
           ">= %.2g s, each after %.2g s untimed, the evaluators of a tree taking turns; walk and hand C\n"
           "built like the runtime (the Makefile's CFLAGS)\n"
           "cpu: %s\n\n",
           FS, PERIOD / FS, BLOCK, RUNS, SPAN, WARM, cpu);
    printf("%-11s %5s %5s %9s %9s %9s %9s %9s %9s %9s %9s\n", "", "", "", "compiled", "walk", "hand C",
           "walk/", "compiled/", "walk", "hand C", "restart");
    printf("%-11s %5s %5s %9s %9s %9s %9s %9s %9s %9s %9s\n", "tree", "nodes", "instr", "ns/sample",
           "ns/sample", "ns/sample", "compiled", "hand C", "diff", "diff", "diff");
    printf("%-11s %5s %5s %9s %9s %9s %9s %9s %9s %9s %9s\n", "-----------", "-----", "-----", "---------",
           "---------", "---------", "---------", "---------", "---------", "---------", "---------");
    fflush(stdout);
    int failed = 0;
    double worst_hand = 0, least_walk = INFINITY;
    const char *worst_hand_tree = "-", *least_walk_tree = "-";
    for (int i = 0; i < NTREES; i++) {
        tt_file *lib = NULL;
        if (g_trees[i].file && !(lib = tt_file_read(g_trees[i].file, NULL, 0, err, sizeof err))) {
            fprintf(stderr, "treebench: %s\n", err);
            failed = 1;
            continue;
        }
        const tt_tree *t = tt_file_find(lib ? lib : f, g_trees[i].name);
        result r;
        if (!t)
            fprintf(stderr, "treebench: no tree %s\n", g_trees[i].name);
        if (!t || bench_tree(t, g_trees[i].hand, g_trees[i].modes, &r) != 0)
            failed = 1;
        tt_file_free(lib);
        if (!t)
            continue;
        print_row(g_trees[i].label, &r);
        if (r.ns[E_COMP] / r.ns[E_HAND] > worst_hand)
            worst_hand = r.ns[E_COMP] / r.ns[E_HAND], worst_hand_tree = g_trees[i].label;
        if (r.ns[E_WALK] / r.ns[E_COMP] < least_walk)
            least_walk = r.ns[E_WALK] / r.ns[E_COMP], least_walk_tree = g_trees[i].label;
    }
    printf("\ndiff: the largest difference from tt_render over the first %.0f s, relative to its peak (restart:\n"
           "the compiled class's second period, after its reset, against its first); rmsX: the walk's noise\n"
           "has tt_run.c's generator with another seed (the program's seed is private): RMS walk / tt_render\n",
           PERIOD / FS);
    printf("compiled / hand C, the worst: %.2fx (%s; aim <= 1.5x); walk / compiled, the least: %.1fx (%s;\n"
           "aim >= 10x)\n",
           worst_hand, worst_hand_tree, least_walk, least_walk_tree);
    tt_file_free(f);
    printf("(%.0f s)\n", bench_now() - t_start);
    return failed;
}
