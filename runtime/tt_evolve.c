/*
 * tt_evolve.c - genetic exploration of timbre trees: `wdrt evolve`
 * (DESIGN §6.3; the model is described in tt_evolve.h).
 *
 * A generation is a population of trees, each rendered once when it is
 * made: a mutant whose render fails (non-finite samples, silence where
 * the seed sounds, a tree that does not compile) is made again.  Target
 * mode scores each render by its spectral distance to the target and
 * draws parents by tournaments of three; rating mode writes every render
 * (and its tree) to DIR/gen-NNN/ and draws parents in proportion to the
 * ratings it reads.  Both keep the best unchanged (elitism), so the best
 * of the last generation is the best of the run.
 *
 * The random numbers are drawn in a fixed order (never two draws in the
 * arguments of one call, whose order C leaves open), so a seed repeats a
 * run bit for bit wherever the C library's libm gives the same results.
 */
#include "tt_evolve.h"

#include "wdrt.h"

#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

enum { EXIT_INPUT = 1, EXIT_USAGE = 2, EXIT_TOOL = 3 };

#define PI 3.14159265358979323846
#define MUT_TRIES 100  /* mutants tt_evo_mutate makes before it gives up */
#define CHILD_TRIES 40 /* mutants rendered before a parent is copied instead */
#define TOURNAMENT 3   /* target mode: parents are the best of this many drawn */
#define SILENT 1e-9    /* a render whose peak stays below this is silent */

/* ---- random numbers: xoshiro256**, seeded by splitmix64 ---- */

static uint64_t splitmix64(uint64_t *x) {
    uint64_t z = (*x += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
}

void tt_evo_rng_seed(tt_evo_rng *r, uint64_t seed) {
    for (int i = 0; i < 4; i++)
        r->s[i] = splitmix64(&seed);
}

static uint64_t rotl(uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }

uint64_t tt_evo_rng_next(tt_evo_rng *r) {
    uint64_t *s = r->s, out = rotl(s[1] * 5, 7) * 9, t = s[1] << 17;
    s[2] ^= s[0];
    s[3] ^= s[1];
    s[1] ^= s[2];
    s[0] ^= s[3];
    s[2] ^= t;
    s[3] = rotl(s[3], 45);
    return out;
}

double tt_evo_rng_uniform(tt_evo_rng *r) { return (double)(tt_evo_rng_next(r) >> 11) * 0x1.0p-53; }

/* Box-Muller, one of the pair (no state beyond the generator's). */
double tt_evo_rng_normal(tt_evo_rng *r) {
    double u = 1 - tt_evo_rng_uniform(r);
    double v = tt_evo_rng_uniform(r);
    return sqrt(-2 * log(u)) * cos(2 * PI * v);
}

static int below(tt_evo_rng *r, int n) { return (int)(tt_evo_rng_uniform(r) * n); }

static double log_uniform(tt_evo_rng *r, double lo, double hi) {
    return lo * exp(tt_evo_rng_uniform(r) * log(hi / lo));
}

#define NELEM(a) ((int)(sizeof(a) / sizeof((a)[0])))
#define PICK(r, tab) ((tab)[below((r), NELEM(tab))])

/* ---- building nodes (made by a program: doc NULL) ---- */

/* A node over args (taken); NULL if an arg is NULL or memory runs out,
 * the args freed. */
static tt_node *node(tt_op op, int n, tt_node **args) {
    int ok = 1;
    for (int i = 0; i < n; i++)
        ok &= args[i] != NULL;
    tt_node *x = ok ? tt_node_new(op, n) : NULL;
    for (int i = 0; i < n; i++)
        if (x)
            x->a[i] = args[i];
        else
            tt_node_free(args[i]);
    return x;
}

static tt_node *op0(tt_op op) { return tt_node_new(op, 0); }

static tt_node *op1(tt_op op, tt_node *a) { return node(op, 1, &a); }

static tt_node *op2(tt_op op, tt_node *a, tt_node *b) {
    tt_node *v[2] = {a, b};
    return node(op, 2, v);
}

static tt_node *op3(tt_op op, tt_node *a, tt_node *b, tt_node *c) {
    tt_node *v[3] = {a, b, c};
    return node(op, 3, v);
}

static tt_node *num(double v) {
    tt_node *x = tt_node_new(TT_NUM, 0);
    if (x)
        x->v = v;
    return x;
}

static tt_node *param(const tt_tree *t, int i) {
    tt_node *x = tt_node_new(TT_PARAM, 0);
    if (x && !(x->s = malloc(strlen(t->pname[i]) + 1))) {
        tt_node_free(x);
        return NULL;
    }
    if (x) {
        strcpy(x->s, t->pname[i]);
        x->v = i;
    }
    return x;
}

static tt_node *osc(tt_node *f, int shape) {
    tt_node *x = op1(TT_OSC, f);
    if (x)
        x->v = shape;
    return x;
}

/* (env (0 0) (A 1) (E 0)): an attack and a linear fall. */
static tt_node *env_ad(double attack, double end) {
    tt_node *x = tt_node_new(TT_ENV, 0);
    if (x && !(x->k = malloc(6 * sizeof *x->k))) {
        tt_node_free(x);
        return NULL;
    }
    if (x) {
        double k[6] = {0, 0, attack, 1, end, 0};
        memcpy(x->k, k, sizeof k);
        x->nk = 6;
    }
    return x;
}

/* (* X (damp (* R t))): X dying away at R nepers a second. */
static tt_node *decay(tt_node *x, double rate) { return op2(TT_MUL, x, op1(TT_DAMP, op2(TT_MUL, num(rate), op0(TT_T)))); }

/* (WAVE (* F t)) */
static tt_node *tone(tt_op wave, double f) { return op1(wave, op2(TT_MUL, num(f), op0(TT_T))); }

/* ---- where nodes are ---- */

/* The slots (the pointers that hold them) of every node, in preorder. */
typedef struct slots {
    tt_node ***v;
    int n;
} slots;

static void collect(tt_node **s, slots *out) {
    out->v[out->n++] = s;
    for (int i = 0; i < (*s)->n; i++)
        collect(&(*s)->a[i], out);
}

static int slots_of(tt_node **root, slots *out) {
    out->n = 0;
    if (!(out->v = malloc(sizeof *out->v * (size_t)tt_node_count(*root))))
        return -1;
    collect(root, out);
    return 0;
}

/* A slot drawn evenly among those whose node passes ok (NULL: all). */
static tt_node **pick(const slots *s, int (*ok)(const tt_node *), tt_evo_rng *r) {
    int m = 0;
    for (int i = 0; i < s->n; i++)
        m += !ok || ok(*s->v[i]);
    if (!m)
        return NULL;
    int k = below(r, m);
    for (int i = 0; i < s->n; i++)
        if ((!ok || ok(*s->v[i])) && k-- == 0)
            return s->v[i];
    return NULL;
}

static tt_node **find_slot(tt_node **s, const tt_node *x) {
    if (*s == x)
        return s;
    for (int i = 0; i < (*s)->n; i++) {
        tt_node **f = find_slot(&(*s)->a[i], x);
        if (f)
            return f;
    }
    return NULL;
}

/* Node k (preorder) of x; *k counts down. */
static const tt_node *nth_node(const tt_node *x, int *k) {
    if ((*k)-- == 0)
        return x;
    for (int i = 0; i < x->n; i++) {
        const tt_node *y = nth_node(x->a[i], k);
        if (y)
            return y;
    }
    return NULL;
}


static int has_args(const tt_node *x) { return x->n > 0; }

/* ---- random subtrees ---- */

/* Functions of a kind: a change swaps one for another of its kind. */
static const tt_op k_arith[] = {TT_ADD, TT_SUB, TT_MUL, TT_DIV, TT_POW, TT_MIN, TT_MAX};
static const tt_op k_math[] = {TT_EXP, TT_LOG, TT_SQRT, TT_ABS, TT_SIN, TT_COS, TT_FLOOR, TT_TANH, TT_DAMP};
static const tt_op k_wave[] = {TT_SINE, TT_SAW, TT_SQUARE, TT_TRIANGLE};
static const tt_op k_filter[] = {TT_LOWPASS, TT_HIGHPASS, TT_BANDPASS};
/* binary functions new subtrees use (pow of a signal is mostly NaN) */
static const tt_op k_binary[] = {TT_ADD, TT_ADD, TT_SUB, TT_MUL, TT_MUL, TT_DIV, TT_MIN, TT_MAX};

static double rand_freq(tt_evo_rng *r) { return log_uniform(r, 30, 3000); }

static double rand_const(tt_evo_rng *r) {
    double u = tt_evo_rng_uniform(r);
    if (u < 0.4)
        return log_uniform(r, 0.1, 10);
    if (u < 0.7)
        return rand_freq(r);
    return 2 * tt_evo_rng_uniform(r) - 1;
}

/* A number, t, a param of t, or noise. */
static tt_node *rand_leaf(const tt_tree *t, tt_evo_rng *r) {
    double u = tt_evo_rng_uniform(r);
    if (u < 0.7 && u >= 0.5 && t->nparams)
        return param(t, below(r, t->nparams));
    if (u < 0.7)
        return num(rand_const(r));
    if (u < 0.92)
        return op0(TT_T);
    return op0(TT_NOISE);
}

/* A random expression at most d deep, mostly of things that sound:
 * waves of time, oscillators, filters, resonators, decays, envelopes. */
static tt_node *rand_tree(const tt_tree *t, tt_evo_rng *r, int d) {
    if (d <= 1 || tt_evo_rng_uniform(r) < 0.2)
        return rand_leaf(t, r);
    tt_node *a, *b;
    tt_op op;
    double f, q;
    switch (below(r, 9)) {
    case 0:
        op = PICK(r, k_wave);
        return tone(op, rand_freq(r));
    case 1:
        q = below(r, 4);
        a = below(r, 2) ? num(rand_freq(r)) : rand_tree(t, r, d - 1);
        return osc(a, (int)q);
    case 2:
        op = PICK(r, k_binary);
        a = rand_tree(t, r, d - 1);
        b = rand_tree(t, r, d - 1);
        return op2(op, a, b);
    case 3:
        op = PICK(r, k_math);
        return op1(op, rand_tree(t, r, d - 1));
    case 4:
        op = PICK(r, k_filter);
        f = log_uniform(r, 50, 8000);
        q = log_uniform(r, 0.5, 8);
        return op3(op, rand_tree(t, r, d - 1), num(f), num(q));
    case 5:
        f = rand_freq(r);
        q = log_uniform(r, 0.05, 2);
        return op3(TT_RESON, rand_tree(t, r, d - 1), num(f), num(q));
    case 6:
        f = log_uniform(r, 0.5, 20);
        return decay(rand_tree(t, r, d - 1), f);
    case 7:
        op = PICK(r, k_wave);
        return op1(op, rand_tree(t, r, d - 1));
    default:
        f = log_uniform(r, 0.001, 0.05);
        q = log_uniform(r, 0.05, 2);
        return env_ad(f, f + q);
    }
}

/* A function around `hole` (x's stand-in; x itself is only copied, by
 * the echo): three times in ten a gain, which retunes what a param or a
 * product sets; else one of nine others. */
static tt_node *wrapper(const tt_tree *t, tt_evo_rng *r, tt_node *hole, const tt_node *x) {
    tt_op op;
    double f, q;
    tt_node *y;
    int k = tt_evo_rng_uniform(r) < 0.3 ? 0 : 1 + below(r, 9);
    switch (k) {
    case 0: /* a gain: a small step (a param retuned), or a large one */
        f = tt_evo_rng_uniform(r) < 0.5 ? exp(0.2 * tt_evo_rng_normal(r)) : log_uniform(r, 0.25, 4);
        return op2(TT_MUL, num(f), hole);
    case 1:
        y = rand_tree(t, r, 2);
        return op2(TT_ADD, hole, y);
    case 2:
        op = PICK(r, k_wave);
        return op1(op, hole);
    case 3:
        f = log_uniform(r, 0.5, 8);
        return op1(TT_TANH, op2(TT_MUL, num(f), hole));
    case 4:
        op = PICK(r, k_filter);
        f = log_uniform(r, 50, 8000);
        q = log_uniform(r, 0.5, 8);
        return op3(op, hole, num(f), num(q));
    case 5:
        f = rand_freq(r);
        q = log_uniform(r, 0.05, 2);
        return op3(TT_RESON, hole, num(f), num(q));
    case 6:
        return decay(hole, log_uniform(r, 0.5, 20));
    case 7: /* ring modulation */
        op = PICK(r, k_wave);
        f = log_uniform(r, 0.5, 1000);
        return op2(TT_MUL, hole, tone(op, f));
    case 8: /* an echo */
        f = log_uniform(r, 0.001, 0.2);
        q = 0.2 + 0.6 * tt_evo_rng_uniform(r);
        return op2(TT_ADD, hole, op2(TT_MUL, num(q), op2(TT_DELAY, tt_node_clone(x), num(f))));
    default:
        op = PICK(r, k_binary);
        y = rand_leaf(t, r);
        return below(r, 2) ? op2(op, hole, y) : op2(op, y, hole);
    }
}

/* ---- mutations ---- */

static double perturb(tt_evo_rng *r, double v) {
    static const double sigma[] = {0.003, 0.02, 0.1, 0.4};
    if (fabs(v) < 1e-3)
        return v + 0.05 * tt_evo_rng_normal(r);
    double s = PICK(r, sigma);
    return v * exp(s * tt_evo_rng_normal(r));
}

/* A number, or an env value (never a time: times must keep rising). */
static int mut_perturb(tt_evo_rng *r, const slots *s) {
    int m = 0;
    for (int i = 0; i < s->n; i++) {
        const tt_node *x = *s->v[i];
        m += x->op == TT_NUM ? 1 : x->op == TT_ENV ? x->nk / 2 : 0;
    }
    if (!m)
        return 0;
    int k = below(r, m);
    for (int i = 0; i < s->n; i++) {
        tt_node *x = *s->v[i];
        if (x->op == TT_NUM && k-- == 0) {
            x->v = perturb(r, x->v);
            return 1;
        }
        if (x->op == TT_ENV && k < x->nk / 2) {
            x->k[2 * k + 1] = perturb(r, x->k[2 * k + 1]);
            return 1;
        }
        if (x->op == TT_ENV)
            k -= x->nk / 2;
    }
    return 0;
}

static int mut_replace(const tt_tree *t, tt_evo_rng *r, const slots *s) {
    tt_node **at = pick(s, NULL, r);
    int d = 1 + below(r, 3);
    tt_node *y = rand_tree(t, r, d);
    if (!y)
        return 0;
    tt_node_free(*at);
    *at = y;
    return 1;
}

static int mut_wrap(const tt_tree *t, tt_evo_rng *r, const slots *s) {
    tt_node **at = pick(s, NULL, r), *hole = op0(TT_T);
    tt_node *w = hole ? wrapper(t, r, hole, *at) : NULL; /* frees hole if it fails */
    if (!w)
        return 0;
    tt_node **h = find_slot(&w, hole);
    tt_node_free(hole);
    *h = *at;
    *at = w;
    return 1;
}

static const tt_op *kind_of(tt_op op, int *n) {
    static const struct {
        const tt_op *ops;
        int n;
    } kinds[] = {{k_arith, NELEM(k_arith)}, {k_math, NELEM(k_math)}, {k_wave, NELEM(k_wave)},
                 {k_filter, NELEM(k_filter)}};
    for (int k = 0; k < NELEM(kinds); k++)
        for (int i = 0; i < kinds[k].n; i++)
            if (kinds[k].ops[i] == op) {
                *n = kinds[k].n;
                return kinds[k].ops;
            }
    *n = 0;
    return NULL;
}

static int takes(tt_op op, int n) { return n >= tt_ops[op].min && (tt_ops[op].max < 0 || n <= tt_ops[op].max); }

/* The functions x may become: its kind's, other than its own, taking
 * its number of arguments.  Returns how many (into alt). */
static int alternatives(const tt_node *x, tt_op *alt) {
    int nk, m = 0;
    const tt_op *k = kind_of(x->op, &nk);
    for (int i = 0; i < nk; i++)
        if (k[i] != x->op && takes(k[i], x->n))
            alt[m++] = k[i];
    return m;
}

static int changeable(const tt_node *x) {
    tt_op alt[16];
    return x->op == TT_OSC || alternatives(x, alt) > 0;
}

static int mut_change(tt_evo_rng *r, const slots *s) {
    tt_node **at = pick(s, changeable, r);
    if (!at)
        return 0;
    tt_node *x = *at;
    if (x->op == TT_OSC) {
        x->v = ((int)x->v + 1 + below(r, 3)) % 4;
        return 1;
    }
    tt_op alt[16];
    int m = alternatives(x, alt);
    x->op = alt[below(r, m)];
    return 1;
}

static int mut_hoist(tt_evo_rng *r, const slots *s) {
    tt_node **at = pick(s, has_args, r);
    if (!at)
        return 0;
    tt_node *y = tt_node_clone((*at)->a[below(r, (*at)->n)]);
    if (!y)
        return 0;
    tt_node_free(*at);
    *at = y;
    return 1;
}

/* A subtree of b (an inner node seven times in ten, if b has one) in
 * place of a node of the mutant. */
static int mut_cross(tt_evo_rng *r, const slots *s, const tt_tree *b) {
    tt_node **at = pick(s, NULL, r);
    int nb = tt_node_count(b->root), inner = has_args(b->root) && tt_evo_rng_uniform(r) < 0.7;
    const tt_node *y = NULL;
    while (!y || (inner && !y->n)) {
        int k = below(r, nb);
        y = nth_node(b->root, &k);
    }
    tt_node *c = tt_node_clone(y);
    if (!c)
        return 0;
    tt_node_free(*at);
    *at = c;
    return 1;
}

/* Relative weights of the mutations, in tt_mutation order. */
static const int k_weights[TT_NMUT] = {35, 12, 13, 12, 10, 18};

static tt_mutation draw_kind(tt_evo_rng *r) {
    int sum = 0;
    for (int i = 0; i < TT_NMUT; i++)
        sum += k_weights[i];
    int u = below(r, sum);
    for (int i = 0; i < TT_NMUT; i++)
        if ((u -= k_weights[i]) < 0)
            return (tt_mutation)i;
    return TT_MUT_PERTURB;
}

static int apply(tt_tree *t, const tt_tree *b, tt_mutation kind, tt_evo_rng *r, const slots *s) {
    switch (kind) {
    case TT_MUT_PERTURB:
        return mut_perturb(r, s);
    case TT_MUT_REPLACE:
        return mut_replace(t, r, s);
    case TT_MUT_WRAP:
        return mut_wrap(t, r, s);
    case TT_MUT_CHANGE:
        return mut_change(r, s);
    case TT_MUT_HOIST:
        return mut_hoist(r, s);
    default:
        return mut_cross(r, s, b);
    }
}

static int fits(tt_tree *t, const tt_evo_limits *lim) {
    char err[512];
    return tt_node_depth(t->root) <= lim->max_depth && tt_node_count(t->root) <= lim->max_nodes &&
           !tt_node_has(t->root, TT_VOICE) && tt_check(t, err, sizeof err) == 0;
}

tt_evo_limits tt_evo_default_limits(const tt_tree *seed) {
    tt_evo_limits l;
    l.max_depth = tt_node_depth(seed->root) + 4;
    l.max_nodes = 2 * tt_node_count(seed->root) + 40;
    l.max_depth = l.max_depth < TT_MAX_DEPTH ? l.max_depth : TT_MAX_DEPTH;
    l.max_nodes = l.max_nodes < TT_MAX_NODES ? l.max_nodes : TT_MAX_NODES;
    return l;
}

tt_tree *tt_evo_mutate(const tt_tree *a, const tt_tree *b, tt_mutation kind, const tt_evo_limits *lim,
                       tt_evo_rng *r) {
    for (int tries = 0; tries < MUT_TRIES; tries++) {
        tt_tree *t = tt_tree_clone(a);
        slots s;
        if (!t || slots_of(&t->root, &s)) {
            tt_tree_free(t);
            return NULL;
        }
        tt_mutation k = kind == TT_MUT_ANY ? draw_kind(r) : kind;
        int ok = apply(t, b ? b : a, k, r, &s);
        free(s.v);
        if (ok && fits(t, lim))
            return t;
        tt_tree_free(t);
    }
    return NULL;
}

/* ---- the FFT ---- */

/* Radix-2, in place, decimation in time; c[k], s[k] = cos, sin of
 * 2 pi k / n for k < n / 2. */
static void fft(double *re, double *im, int n, const double *c, const double *s) {
    for (int i = 1, j = 0; i < n; i++) {
        int bit = n >> 1;
        for (; j & bit; bit >>= 1)
            j ^= bit;
        j ^= bit;
        if (i < j) {
            double tr = re[i], ti = im[i];
            re[i] = re[j], im[i] = im[j], re[j] = tr, im[j] = ti;
        }
    }
    for (int len = 2; len <= n; len <<= 1) {
        int half = len / 2, step = n / len;
        for (int i = 0; i < n; i += len)
            for (int k = 0; k < half; k++) {
                double wr = c[k * step], wi = -s[k * step];
                int p = i + k, q = p + half;
                double xr = re[q] * wr - im[q] * wi, xi = re[q] * wi + im[q] * wr;
                re[q] = re[p] - xr, im[q] = im[p] - xi;
                re[p] += xr, im[p] += xi;
            }
    }
}

static int twiddles(int n, double **c, double **s) {
    *c = malloc(sizeof **c * (size_t)(n / 2 + 1));
    *s = malloc(sizeof **s * (size_t)(n / 2 + 1));
    if (!*c || !*s)
        return -1;
    for (int k = 0; k < n / 2; k++)
        (*c)[k] = cos(2 * PI * k / n), (*s)[k] = sin(2 * PI * k / n);
    return 0;
}

int tt_evo_fft(double *re, double *im, int n) {
    if (n < 1 || (n & (n - 1)))
        return -1;
    double *c, *s;
    int st = twiddles(n, &c, &s);
    if (!st)
        fft(re, im, n, c, s);
    free(c);
    free(s);
    return st;
}

/* ---- the spectral distance ---- */

#define SP_NSCALE 4
#define SP_PER_OCTAVE 24   /* bands an octave */
#define SP_FLOOR 1e-6      /* the floor, 60 dB under the target's loudest band */
static const double k_scales[SP_NSCALE] = {0, 1.0 / 12, 1.0 / 3, 1}; /* octaves */

struct tt_evo_spectra {
    double fs;
    long n;                   /* the target's frames */
    int nfft, hop, nframes, nbands;
    int *blo, *bhi;           /* [nbands] the band's bins [blo, bhi), or none */
    double *bc;               /* [nbands] its centre, in bins (for bands with no bin) */
    double *win, *cs, *sn;    /* [nfft] window; [nfft / 2] twiddles */
    double *kern[SP_NSCALE];  /* [2 khalf + 1] Gaussian over bands, sum 1 */
    int khalf[SP_NSCALE];
    double eps;               /* the floor, in power */
    double *target, *work;    /* [SP_NSCALE][nframes][nbands] dB */
    double *re, *im, *band;   /* scratch [nfft], [nfft], [nbands] */
};

void tt_evo_spectra_free(tt_evo_spectra *s) {
    if (!s)
        return;
    free(s->blo), free(s->bhi), free(s->bc), free(s->win), free(s->cs), free(s->sn);
    for (int i = 0; i < SP_NSCALE; i++)
        free(s->kern[i]);
    free(s->target), free(s->work), free(s->re), free(s->im), free(s->band);
    free(s);
}

static void sp_bands(tt_evo_spectra *s) {
    double df = s->fs / s->nfft, flo = 20;
    for (int k = 0; k < s->nbands; k++) {
        double fc = flo * pow(2, (double)k / SP_PER_OCTAVE), w = pow(2, 0.5 / SP_PER_OCTAVE);
        int lo = (int)ceil(fc / w / df), hi = (int)ceil(fc * w / df);
        s->blo[k] = lo < s->nfft / 2 ? lo : s->nfft / 2;
        s->bhi[k] = hi < s->nfft / 2 + 1 ? hi : s->nfft / 2 + 1;
        s->bc[k] = fc / df;
    }
}

static void sp_kernels(tt_evo_spectra *s) {
    for (int i = 0; i < SP_NSCALE; i++) {
        double sigma = k_scales[i] * SP_PER_OCTAVE, sum = 0;
        int h = s->khalf[i];
        for (int j = -h; j <= h; j++)
            sum += s->kern[i][j + h] = sigma > 0 ? exp(-0.5 * j * j / (sigma * sigma)) : 1;
        for (int j = 0; j <= 2 * h; j++)
            s->kern[i][j] /= sum;
    }
}

static tt_evo_spectra *sp_alloc(long n, double fs) {
    tt_evo_spectra *s = calloc(1, sizeof *s);
    if (!s)
        return NULL;
    s->fs = fs;
    s->n = n > 0 ? n : 1;
    s->nfft = 64;
    while (s->nfft < 0.05 * fs)
        s->nfft *= 2;
    while (s->nfft > 64 && s->nfft > s->n)
        s->nfft /= 2;
    s->hop = s->nfft / 2;
    s->nframes = s->n > s->nfft ? (int)(1 + (s->n - s->nfft) / s->hop) : 1;
    double fhi = fmin(0.475 * fs, 20000);
    s->nbands = fhi > 20 ? (int)floor(SP_PER_OCTAVE * log2(fhi / 20)) + 1 : 1;
    size_t nb = (size_t)s->nbands, all = (size_t)SP_NSCALE * (size_t)s->nframes * nb;
    s->blo = malloc(sizeof *s->blo * nb), s->bhi = malloc(sizeof *s->bhi * nb), s->bc = malloc(sizeof *s->bc * nb);
    s->win = malloc(sizeof *s->win * (size_t)s->nfft), s->band = malloc(sizeof *s->band * nb);
    s->re = malloc(sizeof *s->re * (size_t)s->nfft), s->im = malloc(sizeof *s->im * (size_t)s->nfft);
    s->target = malloc(sizeof *s->target * all), s->work = malloc(sizeof *s->work * all);
    int ok = s->blo && s->bhi && s->bc && s->win && s->band && s->re && s->im && s->target && s->work &&
             !twiddles(s->nfft, &s->cs, &s->sn);
    for (int i = 0; i < SP_NSCALE; i++) {
        s->khalf[i] = (int)ceil(4 * k_scales[i] * SP_PER_OCTAVE);
        ok = ok && (s->kern[i] = malloc(sizeof *s->kern[i] * (size_t)(2 * s->khalf[i] + 1)));
    }
    if (!ok) {
        tt_evo_spectra_free(s);
        return NULL;
    }
    for (int i = 0; i < s->nfft; i++) { /* Blackman-Harris: side lobes 92 dB down, under the floor */
        double w = 2 * PI * i / s->nfft;
        s->win[i] = 0.35875 - 0.48829 * cos(w) + 0.14128 * cos(2 * w) - 0.01168 * cos(3 * w);
    }
    sp_bands(s);
    sp_kernels(s);
    return s;
}

/* The band powers of frame f of y[n] into s->band; returns the largest. */
static double sp_frame(tt_evo_spectra *s, const double *y, long n, int f) {
    long at = (long)f * s->hop;
    for (int i = 0; i < s->nfft; i++) {
        s->re[i] = at + i < n ? y[at + i] * s->win[i] : 0;
        s->im[i] = 0;
    }
    fft(s->re, s->im, s->nfft, s->cs, s->sn);
    for (int i = 0; i <= s->nfft / 2; i++)
        s->re[i] = s->re[i] * s->re[i] + s->im[i] * s->im[i];
    double top = 0;
    for (int k = 0; k < s->nbands; k++) {
        double p = 0;
        if (s->bhi[k] > s->blo[k]) {
            for (int i = s->blo[k]; i < s->bhi[k]; i++)
                p += s->re[i];
            p /= s->bhi[k] - s->blo[k];
        } else { /* narrower than a bin: the power between the two nearest */
            int i = (int)s->bc[k];
            double u = s->bc[k] - i;
            p = i < s->nfft / 2 ? (1 - u) * s->re[i] + u * s->re[i + 1] : s->re[s->nfft / 2];
        }
        s->band[k] = p;
        top = fmax(top, p);
    }
    return top;
}

/* The smoothed band powers of every frame and scale of y[n] into out;
 * returns the largest band power seen (before smoothing). */
static double sp_analyse(tt_evo_spectra *s, const double *y, long n, double *out) {
    double top = 0;
    for (int f = 0; f < s->nframes; f++) {
        top = fmax(top, sp_frame(s, y, n, f));
        for (int sc = 0; sc < SP_NSCALE; sc++) {
            double *o = out + ((size_t)sc * s->nframes + f) * s->nbands;
            int h = s->khalf[sc];
            for (int k = 0; k < s->nbands; k++) {
                double p = 0;
                for (int j = -h; j <= h; j++)
                    if (k + j >= 0 && k + j < s->nbands)
                        p += s->kern[sc][j + h] * s->band[k + j];
                o[k] = p;
            }
        }
    }
    return top;
}

static void sp_db(const tt_evo_spectra *s, double *x) {
    size_t all = (size_t)SP_NSCALE * (size_t)s->nframes * (size_t)s->nbands;
    for (size_t i = 0; i < all; i++)
        x[i] = 10 * log10(x[i] + s->eps);
}

tt_evo_spectra *tt_evo_spectra_new(const double *x, long n, double fs) {
    tt_evo_spectra *s = sp_alloc(n, fs);
    if (!s)
        return NULL;
    double top = sp_analyse(s, x, n, s->target);
    s->eps = top > 0 ? top * SP_FLOOR : 1e-30;
    sp_db(s, s->target);
    return s;
}

double tt_evo_distance(tt_evo_spectra *s, const double *y, long n) {
    sp_analyse(s, y, n < s->n ? n : s->n, s->work);
    sp_db(s, s->work);
    size_t all = (size_t)SP_NSCALE * (size_t)s->nframes * (size_t)s->nbands;
    double d = 0;
    for (size_t i = 0; i < all; i++)
        d += fabs(s->work[i] - s->target[i]);
    return d / (double)all;
}

/* ---- the run ---- */

typedef struct evo_opts {
    const char *seed_path, *target, *dir, *ratings;
    int population, generations, depth, max_nodes, quiet, have_seed;
    uint64_t seed;
    double rate, seconds;
} evo_opts;

typedef struct indiv {
    tt_tree *t;
    double score; /* target: the distance (lower is better); else the rating (higher is better) */
} indiv;

typedef struct evo {
    const evo_opts *o;
    tt_tree *seed;       /* the file's last tree, its samples' paths made absolute */
    tt_evo_limits lim;
    tt_evo_rng rng;
    double fs;
    long n;              /* frames a render has */
    double *buf, *wav;   /* [n] a render; what is written of it */
    tt_evo_spectra *sp;  /* target mode; NULL: ratings */
    double seed_score;   /* the seed's distance */
    int allow_silent;    /* the seed itself is silent */
    indiv *pop, *next;   /* [npop] */
    int npop;
    FILE *rf;            /* the ratings: the file, or stdin */
    const char *rname;
    int rline;
    int tty;
    char path[PATH_MAX];
    char err[4096];
} evo;

static int better(const evo *e, double a, double b) { return e->sp ? a < b : a > b; }

/* Renders t into e->buf: 0, or -1 with why in e->err. */
static int render(evo *e, const tt_tree *t) {
    tt_prog *p = tt_compile(t, e->err, sizeof e->err);
    if (!p)
        return -1;
    int st = tt_render(p, e->fs, NULL, e->buf, e->n, e->err, sizeof e->err);
    tt_prog_free(p);
    if (st)
        return -1;
    double pk = 0;
    for (long i = 0; i < e->n; i++) {
        if (!isfinite(e->buf[i])) {
            snprintf(e->err, sizeof e->err, "wdrt evolve: error: the tree renders to non-finite samples\n");
            return -1;
        }
        pk = fmax(pk, fabs(e->buf[i]));
    }
    if (pk < SILENT && !e->allow_silent) {
        snprintf(e->err, sizeof e->err, "wdrt evolve: error: the tree is silent\n");
        return -1;
    }
    return 0;
}

/* A child of a and b, rendered into e->buf: a mutant, or after
 * CHILD_TRIES mutants that would not render, a copy of a. */
static tt_tree *make_child(evo *e, const tt_tree *a, const tt_tree *b) {
    for (int tries = 0; tries < CHILD_TRIES; tries++) {
        tt_tree *t = tt_evo_mutate(a, b, TT_MUT_ANY, &e->lim, &e->rng);
        if (t && !render(e, t))
            return t;
        tt_tree_free(t);
    }
    tt_tree *t = tt_tree_clone(a);
    if (t && render(e, t)) {
        tt_tree_free(t);
        return NULL;
    }
    return t;
}

static int mkdir_p(const char *dir) {
    char buf[PATH_MAX];
    if (snprintf(buf, sizeof buf, "%s", dir) >= (int)sizeof buf)
        return -1;
    for (char *p = buf + 1; *p; p++)
        if (*p == '/') {
            *p = 0;
            if (mkdir(buf, 0777) != 0 && errno != EEXIST)
                return -1;
            *p = '/';
        }
    return mkdir(buf, 0777) != 0 && errno != EEXIST ? -1 : 0;
}

/* e->path = DIR/NAME (printf); 0, or -1 if it does not fit. */
static int path_of(evo *e, const char *fmt, ...) {
    int m = snprintf(e->path, sizeof e->path, "%s/", e->o->dir);
    if (m >= (int)sizeof e->path) {
        errno = ENAMETOOLONG;
        return -1;
    }
    va_list ap;
    va_start(ap, fmt);
    int k = vsnprintf(e->path + m, sizeof e->path - (size_t)m, fmt, ap);
    va_end(ap);
    if (m + k >= (int)sizeof e->path) {
        errno = ENAMETOOLONG;
        return -1;
    }
    return 0;
}

static int cannot_write(const evo *e) {
    fprintf(stderr, "wdrt evolve: error: cannot write '%s': %s\n", e->path, strerror(errno));
    return EXIT_USAGE;
}

/* A tree as a file `wdrt tree` reads: a definition, or a bare expression
 * if it has neither name nor params. */
static int write_tree(evo *e, const tt_tree *t) {
    FILE *f = fopen(e->path, "w");
    if (!f)
        return cannot_write(e);
    if (t->nparams || t->name[0]) {
        tt_print_tree(f, t);
    } else {
        tt_print(f, t->root);
        fputc('\n', f);
    }
    if (ferror(f) | fclose(f))
        return cannot_write(e);
    return 0;
}

/* e->buf as a WAV, scaled down to a peak of 1 if it goes beyond. */
static int write_wav(evo *e) {
    double pk = 0;
    for (long i = 0; i < e->n; i++)
        pk = fmax(pk, fabs(e->buf[i]));
    for (long i = 0; i < e->n; i++)
        e->wav[i] = pk > 1 ? e->buf[i] / pk : e->buf[i];
    if (wdrt_wav_write(e->path, 1, e->fs, e->wav, e->n) != WDRT_OK)
        return cannot_write(e);
    return 0;
}

/* Individual x (number i of generation g), just rendered into e->buf:
 * scored (target) or written with its tree (ratings). */
static int settle(evo *e, int g, int i, indiv *x) {
    if (e->sp) {
        x->score = tt_evo_distance(e->sp, e->buf, e->n);
        return 0;
    }
    int st;
    if (path_of(e, "gen-%03d", g) || mkdir_p(e->path))
        return cannot_write(e);
    if (path_of(e, "gen-%03d/ind-%02d.tt", g, i))
        return cannot_write(e);
    if ((st = write_tree(e, x->t)))
        return st;
    if (path_of(e, "gen-%03d/ind-%02d.wav", g, i))
        return cannot_write(e);
    return write_wav(e);
}

/* Indices of e->pop from best to worst (ties: the earlier first). */
static void ranking(const evo *e, int *order) {
    for (int i = 0; i < e->npop; i++) {
        int j = i;
        for (; j > 0 && better(e, e->pop[i].score, e->pop[order[j - 1]].score); j--)
            order[j] = order[j - 1];
        order[j] = i;
    }
}

static int best_of(const evo *e) {
    int b = 0;
    for (int i = 1; i < e->npop; i++)
        b = better(e, e->pop[i].score, e->pop[b].score) ? i : b;
    return b;
}

/* Target: the best of TOURNAMENT drawn; ratings: drawn in proportion to
 * the ratings (evenly if all are 0). */
static int select_parent(evo *e) {
    if (e->sp) {
        int best = below(&e->rng, e->npop);
        for (int k = 1; k < TOURNAMENT; k++) {
            int c = below(&e->rng, e->npop);
            best = e->pop[c].score < e->pop[best].score ? c : best;
        }
        return best;
    }
    /* ratings over the largest, so that their sum stays finite (1e308s) */
    double top = 0, sum = 0;
    for (int i = 0; i < e->npop; i++)
        top = fmax(top, e->pop[i].score);
    if (!(top > 0))
        return below(&e->rng, e->npop);
    for (int i = 0; i < e->npop; i++)
        sum += e->pop[i].score / top;
    double u = tt_evo_rng_uniform(&e->rng) * sum;
    for (int i = 0; i < e->npop; i++)
        if ((u -= e->pop[i].score / top) < 0)
            return i;
    return e->npop - 1;
}

static int out_of_memory(void) {
    fprintf(stderr, "wdrt evolve: error: out of memory\n");
    return EXIT_TOOL;
}

/* Generation 0: the seed and its mutants. */
static int first_generation(evo *e) {
    for (int i = 0; i < e->npop; i++) {
        indiv *x = &e->pop[i];
        if (!(x->t = i ? make_child(e, e->seed, e->seed) : tt_tree_clone(e->seed)))
            return out_of_memory();
        if (!i && render(e, x->t)) {
            fputs(e->err, stderr);
            return EXIT_INPUT;
        }
        int st = settle(e, 0, i, x);
        if (st)
            return st;
    }
    e->seed_score = e->pop[0].score;
    return 0;
}

/* Generation g from the last: its elites as they are (written again
 * when rating), then children of parents drawn by their scores. */
static int next_generation(evo *e, int g) {
    int *order = malloc(sizeof *order * (size_t)e->npop), st = 0;
    if (!order)
        return out_of_memory();
    ranking(e, order);
    int nelite = e->sp ? (e->npop + 9) / 10 : 1;
    for (int i = 0; i < e->npop && !st; i++) {
        indiv *x = &e->next[i];
        if (i < nelite) {
            x->t = tt_tree_clone(e->pop[order[i]].t);
            x->score = e->pop[order[i]].score;
        } else {
            int a = select_parent(e), b = select_parent(e);
            x->t = make_child(e, e->pop[a].t, e->pop[b].t);
        }
        if (!x->t)
            st = out_of_memory();
        else if (i < nelite && !e->sp && render(e, x->t))
            st = (fputs(e->err, stderr), EXIT_TOOL); /* it rendered before */
        else if (i >= nelite || !e->sp)
            st = settle(e, g, i, x);
    }
    free(order);
    for (int i = 0; i < e->npop; i++) {
        tt_tree_free(e->pop[i].t);
        e->pop[i].t = NULL;
    }
    indiv *p = e->pop;
    e->pop = e->next, e->next = p;
    return st;
}

/* One line of ratings: 0, -1 if it holds none (blank, a # comment), or
 * EXIT_INPUT after saying what is wrong. */
static int parse_ratings(evo *e, const char *line) {
    if (e->rline == 1)
        line += sx_bom(line, strlen(line));
    const char *sep = " \t\r\n,", *p = line + strspn(line, sep);
    if (!*p || *p == '#')
        return -1;
    int k = 0;
    for (; *p && *p != '#'; p += strspn(p, sep)) {
        char *end;
        double v = strtod(p, &end);
        int col = (int)(p - line) + 1;
        if (end == p || !isfinite(v) || v < 0 || (*end && !strchr(sep, *end) && *end != '#')) {
            fprintf(stderr, "%s:%d:%d: error: a rating is a number >= 0\n", e->rname, e->rline, col);
            return EXIT_INPUT;
        }
        if (k == e->npop) {
            fprintf(stderr, "%s:%d:%d: error: more than %d ratings (one for each individual)\n", e->rname,
                    e->rline, col, e->npop);
            return EXIT_INPUT;
        }
        e->pop[k++].score = v;
        p = end;
    }
    if (k < e->npop) {
        fprintf(stderr, "%s:%d:1: error: %d rating%s where the generation has %d individuals\n", e->rname, e->rline,
                k, k == 1 ? "" : "s", e->npop);
        return EXIT_INPUT;
    }
    return 0;
}

/* The ratings of generation g into e->pop[].score: the next line of
 * numbers.  At a terminal, they are asked for, and asked again if the
 * line is wrong. */
static int read_ratings(evo *e, int g) {
    char *line = NULL;
    size_t cap = 0;
    int st = -1, tty = e->rf == stdin && isatty(STDIN_FILENO);
    while (st < 0) {
        if (tty)
            fprintf(stderr, "generation %d: rate the %d sounds of %s/gen-%03d (%d numbers, higher is better): ", g,
                    e->npop, e->o->dir, g, e->npop);
        ssize_t n = getline(&line, &cap, e->rf);
        if (n < 0) {
            fprintf(stderr, "%s: error: no ratings for generation %d (a line of %d numbers a generation)\n", e->rname,
                    g, e->npop);
            st = EXIT_INPUT;
            break;
        }
        e->rline++;
        if (strlen(line) != (size_t)n) { /* what follows the NUL would be lost without a word */
            fprintf(stderr, "%s:%d:%d: error: the line contains a NUL byte\n", e->rname, e->rline,
                    (int)strlen(line) + 1);
            st = EXIT_INPUT;
            break;
        }
        st = parse_ratings(e, line);
        if (st > 0 && tty)
            st = -1;
    }
    free(line);
    return st;
}

static void progress(const evo *e, int g, int b) {
    if (!e->tty || !e->sp)
        return;
    fprintf(stderr, "\rwdrt evolve: generation %d of %d, best distance %.4g dB ", g + 1, e->o->generations,
            e->pop[b].score);
    fflush(stderr);
}

static int generation(evo *e, int g) {
    int st = g ? next_generation(e, g) : first_generation(e);
    if (!st && !e->sp)
        st = read_ratings(e, g);
    if (st)
        return st;
    int b = best_of(e);
    progress(e, g, b);
    if (path_of(e, "gen-%03d-best.tt", g))
        return cannot_write(e);
    return write_tree(e, e->pop[b].t);
}

static void params_to_numbers(tt_node *x, const tt_tree *t) {
    if (x->op == TT_PARAM) {
        x->op = TT_NUM;
        x->v = t->pdef[(int)x->v];
        free(x->s);
        x->s = NULL;
    }
    for (int i = 0; i < x->n; i++)
        params_to_numbers(x->a[i], t);
}

/* DIR/best.tt, DIR/best.wav, and the best as an expression on stdout. */
static int finish(evo *e) {
    const tt_tree *t = e->pop[best_of(e)].t;
    int st;
    if (path_of(e, "best.tt"))
        return cannot_write(e);
    if ((st = write_tree(e, t)))
        return st;
    if (render(e, t)) {
        fputs(e->err, stderr);
        return EXIT_TOOL;
    }
    if (path_of(e, "best.wav"))
        return cannot_write(e);
    if ((st = write_wav(e)))
        return st;
    tt_node *x = tt_node_clone(t->root);
    if (!x)
        return out_of_memory();
    params_to_numbers(x, t);
    tt_print(stdout, x);
    fputc('\n', stdout);
    fflush(stdout);
    tt_node_free(x);
    return 0;
}

/* ---- setting up ---- */

static const tt_node *find_op(const tt_node *x, tt_op op) {
    if (x->op == op)
        return x;
    for (int i = 0; i < x->n; i++) {
        const tt_node *y = find_op(x->a[i], op);
        if (y)
            return y;
    }
    return NULL;
}

/* Sample files named from the written trees' folder: as absolute paths. */
static void absolute_samples(tt_node *x) {
    if (x->op == TT_SAMPLE && x->s && x->s[0] != '/') {
        char *p = realpath(x->s, NULL);
        if (p) {
            free(x->s);
            x->s = p;
        }
    }
    for (int i = 0; i < x->n; i++)
        absolute_samples(x->a[i]);
}

/* The seed: the file's last tree, without voices; the limits. */
static int take_seed(evo *e, const tt_file *f) {
    const evo_opts *o = e->o;
    const tt_tree *t = tt_file_tree(f, -1);
    if (!t) {
        fprintf(stderr, "%s: error: the file holds no tree\n", o->seed_path);
        return EXIT_INPUT;
    }
    if (!(e->seed = tt_tree_clone(t)))
        return out_of_memory();
    absolute_samples(e->seed->root);
    const tt_node *v = find_op(e->seed->root, TT_VOICE);
    if (v) {
        if (v->doc)
            sx_error_at(v->doc, v->line, v->col, e->err, sizeof e->err, "evolve does not take voice nodes");
        else
            snprintf(e->err, sizeof e->err, "%s: error: evolve does not take voice nodes\n", o->seed_path);
        fputs(e->err, stderr);
        return EXIT_INPUT;
    }
    e->lim = tt_evo_default_limits(e->seed);
    int depth = tt_node_depth(e->seed->root), count = tt_node_count(e->seed->root);
    if (o->depth && o->depth < depth) {
        fprintf(stderr, "wdrt evolve: error: --depth %d is less than the seed's depth, %d\n", o->depth, depth);
        return EXIT_USAGE;
    }
    if (o->max_nodes && o->max_nodes < count) {
        fprintf(stderr, "wdrt evolve: error: --max-nodes %d is less than the seed's %d nodes\n", o->max_nodes, count);
        return EXIT_USAGE;
    }
    e->lim.max_depth = o->depth ? o->depth : e->lim.max_depth;
    e->lim.max_nodes = o->max_nodes ? o->max_nodes : e->lim.max_nodes;
    return 0;
}

/* The target, mixed to mono: its analysis, rate and length. */
static int take_target(evo *e) {
    const evo_opts *o = e->o;
    int nch;
    double *frames = NULL;
    long n;
    wdrt_result r = wdrt_wav_read(o->target, &nch, &e->fs, &frames, &n);
    if (r != WDRT_OK) {
        /* the reader has said why, but for memory */
        fprintf(stderr, "wdrt evolve: error: cannot read the target '%s'%s\n", o->target,
                r == WDRT_OUT_OF_MEMORY ? ": out of memory" : "");
        return EXIT_INPUT;
    }
    if (n < 1 || nch < 1) {
        free(frames);
        fprintf(stderr, "wdrt evolve: error: '%s' holds no sound\n", o->target);
        return EXIT_INPUT;
    }
    if (!(e->fs >= 1000 && e->fs <= 768000)) {
        free(frames);
        fprintf(stderr, "wdrt evolve: error: '%s' is at %g Hz; a target's rate lies between 1000 and 768000 Hz\n",
                o->target, e->fs);
        return EXIT_INPUT;
    }
    if (o->rate && o->rate != e->fs) {
        free(frames);
        fprintf(stderr, "wdrt evolve: error: --rate %g: with a target, the rate is the target's (%g Hz)\n", o->rate,
                e->fs);
        return EXIT_USAGE;
    }
    for (long i = 0; i < n; i++) {
        double s = 0;
        for (int c = 0; c < nch; c++)
            s += frames[i * nch + c];
        frames[i] = s / nch;
    }
    e->n = o->seconds && o->seconds * e->fs < n ? (long)fmax(1, floor(o->seconds * e->fs)) : n;
    long loud = 0;
    while (loud < e->n && frames[loud] == 0)
        loud++;
    if (loud == e->n) {
        free(frames);
        fprintf(stderr, "wdrt evolve: error: '%s' is silent%s: there is nothing to evolve towards\n", o->target,
                e->n < n ? " over the --seconds asked" : "");
        return EXIT_INPUT;
    }
    e->sp = tt_evo_spectra_new(frames, e->n, e->fs);
    free(frames);
    return e->sp ? 0 : out_of_memory();
}

static int take_buffers(evo *e) {
    e->npop = e->o->population;
    e->buf = malloc(sizeof *e->buf * (size_t)e->n);
    e->wav = malloc(sizeof *e->wav * (size_t)e->n);
    e->pop = calloc((size_t)e->npop, sizeof *e->pop);
    e->next = calloc((size_t)e->npop, sizeof *e->next);
    return e->buf && e->wav && e->pop && e->next ? 0 : out_of_memory();
}

static void evo_free(evo *e) {
    for (int i = 0; e->pop && i < e->npop; i++)
        tt_tree_free(e->pop[i].t);
    for (int i = 0; e->next && i < e->npop; i++)
        tt_tree_free(e->next[i].t);
    free(e->pop), free(e->next), free(e->buf), free(e->wav);
    tt_evo_spectra_free(e->sp);
    tt_tree_free(e->seed);
    if (e->rf && e->rf != stdin)
        fclose(e->rf);
}

static int run(evo *e, const tt_file *f) {
    const evo_opts *o = e->o;
    int st = take_seed(e, f);
    if (!st && o->target) {
        st = take_target(e);
    } else if (!st) {
        e->fs = o->rate ? o->rate : 48000;
        e->n = (long)fmax(1, floor((o->seconds ? o->seconds : 2) * e->fs));
    }
    if (!st)
        st = take_buffers(e);
    if (!st && !o->target && o->ratings && !(e->rf = fopen(o->ratings, "r"))) {
        fprintf(stderr, "wdrt evolve: error: cannot read '%s': %s\n", o->ratings, strerror(errno));
        st = EXIT_INPUT;
    }
    if (!st && !o->target && !o->ratings)
        e->rf = stdin;
    e->rname = o->ratings ? o->ratings : "<stdin>";
    if (!st && mkdir_p(o->dir)) {
        fprintf(stderr, "wdrt evolve: error: cannot make '%s': %s\n", o->dir, strerror(errno));
        st = EXIT_USAGE;
    }
    if (st)
        return st;
    /* the seed's own render decides whether silence is allowed */
    e->allow_silent = 1;
    if (render(e, e->seed)) {
        fputs(e->err, stderr);
        return EXIT_INPUT;
    }
    double pk = 0;
    for (long i = 0; i < e->n; i++)
        pk = fmax(pk, fabs(e->buf[i]));
    e->allow_silent = pk < SILENT;
    tt_evo_rng_seed(&e->rng, o->seed);
    e->tty = isatty(STDERR_FILENO) && !o->quiet;
    for (int g = 0; g < o->generations && !st; g++)
        st = generation(e, g);
    if (e->tty && e->sp)
        fputs("\r\033[K", stderr);
    return st ? st : finish(e);
}

/* ---- the command line ---- */

static const char synopsis[] =
    "usage: wdrt evolve SEED.tt [--target T.wav] [--population N] [--generations G] [--seed K]\n"
    "                   [-o DIR] [--rate HZ] [--seconds S] [--ratings FILE] [--depth D]\n"
    "                   [--max-nodes M] [--quiet]\n";

static const char help_text[] =
    "\n"
    "Breeds the last tree of SEED.tt.  Every generation is a population of its mutants (a\n"
    "constant perturbed, a subtree replaced by a random one or wrapped in a function, a\n"
    "function changed for another of its kind, a node hoisted into one of its arguments, a\n"
    "subtree crossed in from another parent), each with the seed's params, checked, within\n"
    "the limits and rendered (mutants that render to non-finite samples, or to silence\n"
    "where the seed sounds, are made again).  The best of a generation is kept as it is;\n"
    "the parents of the others are drawn by their scores.  Voice nodes are not taken.\n"
    "\n"
    "With --target, the score is a spectral distance to T.wav, rendered at its rate and\n"
    "length: the mean difference in dB between short-time spectra (Blackman-Harris windows\n"
    "of about 50 ms or more, half overlapping) in 1/24-octave bands from 20 Hz, each\n"
    "smoothed over 0, 1/12, 1/3 and 1 octave (the smoothed ones keep a slope towards a\n"
    "pitch that is still far off), with a floor 60 dB under the target's loudest band.\n"
    "Lower is better; parents are the best of 3 drawn; the best tenth is kept.\n"
    "\n"
    "Without a target, you rate: generation NNN is written to DIR/gen-NNN/ind-MM.wav\n"
    "(32-bit float, scaled to a peak of 1 where it is louder) with its tree in ind-MM.tt,\n"
    "and its ratings are read as one line of N numbers >= 0, higher is better (spaces or\n"
    "commas between them): the next line of the --ratings file (one line a generation,\n"
    "blank lines and lines starting with # skipped), or of standard input.  Parents are\n"
    "drawn in proportion to their ratings (evenly if all are 0); the best is kept.\n"
    "\n"
    "Every generation's best tree is written to DIR/gen-NNN-best.tt, the last generation's\n"
    "to DIR/best.tt and its sound to DIR/best.wav; the last line on standard output is the\n"
    "best tree as an expression for `wdrt tree '(EXPR)'` (params at their defaults).\n"
    "\n"
    "  --target T.wav     evolve towards this sound\n"
    "  --population N     individuals a generation (default 8 when rating, 24 with a target)\n"
    "  --generations G    generations (default 5 when rating, 40 with a target)\n"
    "  --seed K           the random seed, 0 to 2^64-1 (default: from the clock, printed);\n"
    "                     the same seed and options give the same run\n"
    "  -o DIR             where to write (default: out/evolve-NAME for NAME.tt)\n"
    "  --rate HZ          sample rate when rating (default 48 kHz; a target has its own)\n"
    "  --seconds S        length rendered (default 2 when rating; with a target, its\n"
    "                     length, or its first S seconds)\n"
    "  --ratings FILE     read the ratings from FILE, not from standard input\n"
    "  --depth D          mutants nest at most D deep (default: the seed's depth + 4)\n"
    "  --max-nodes M      mutants have at most M nodes (default: twice the seed's + 40)\n"
    "  --quiet            no progress, seed or summary on standard error\n"
    "\n"
    "exit status: 0 ok, 1 input error, 2 usage error, 3 internal error\n";

static int usage(const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    fputs("wdrt evolve: error: ", stderr);
    vfprintf(stderr, fmt, ap);
    va_end(ap);
    fprintf(stderr, "\n%s(wdrt evolve --help says more)\n", synopsis);
    return EXIT_USAGE;
}

/* The value of option argv[*i]: the next argument, or NULL. */
static const char *value(int argc, char **argv, int *i) { return *i + 1 < argc ? argv[++*i] : NULL; }

static int int_opt(const char *name, const char *v, long lo, long hi, int *out) {
    char *end;
    errno = 0;
    long x = v ? strtol(v, &end, 10) : 0;
    if (!v || !*v || *end || errno || x < lo || x > hi)
        return usage("%s takes a whole number from %ld to %ld, not '%s'", name, lo, hi, v ? v : "nothing");
    *out = (int)x;
    return -1;
}

static int num_opt(const char *name, const char *v, double lo, double hi, double *out) {
    char *end;
    double x = v ? strtod(v, &end) : 0;
    if (!v || !*v || *end || !(x >= lo && x <= hi))
        return usage("%s takes a number from %g to %g, not '%s'", name, lo, hi, v ? v : "nothing");
    *out = x;
    return -1;
}

static int seed_opt(const char *v, uint64_t *out) {
    char *end;
    errno = 0;
    unsigned long long x = v && *v != '-' ? strtoull(v, &end, 10) : 0;
    if (!v || !*v || *v == '-' || *end || errno)
        return usage("--seed takes a whole number from 0 to 18446744073709551615, not '%s'", v ? v : "nothing");
    *out = (uint64_t)x;
    return -1;
}

/* out/evolve-NAME for .../NAME.tt */
static void default_dir(evo_opts *o, char *buf, size_t cap) {
    const char *base = strrchr(o->seed_path, '/'), *dot;
    base = base ? base + 1 : o->seed_path;
    dot = strrchr(base, '.');
    int n = dot && dot > base ? (int)(dot - base) : (int)strlen(base);
    snprintf(buf, cap, "out/evolve-%.*s", n, base);
    o->dir = buf;
}

/* One option at argv[*i]; -1 to go on, else the exit status. */
static int option(evo_opts *o, int argc, char **argv, int *i) {
    const char *a = argv[*i];
    if (!strcmp(a, "--target"))
        return (o->target = value(argc, argv, i)) ? -1 : usage("--target needs a WAV file");
    if (!strcmp(a, "--ratings"))
        return (o->ratings = value(argc, argv, i)) ? -1 : usage("--ratings needs a file");
    if (!strcmp(a, "-o"))
        return (o->dir = value(argc, argv, i)) && *o->dir ? -1 : usage("-o needs a folder");
    if (!strcmp(a, "--population"))
        return int_opt(a, value(argc, argv, i), 2, 10000, &o->population);
    if (!strcmp(a, "--generations"))
        return int_opt(a, value(argc, argv, i), 1, 1000000, &o->generations);
    if (!strcmp(a, "--depth"))
        return int_opt(a, value(argc, argv, i), 1, TT_MAX_DEPTH, &o->depth);
    if (!strcmp(a, "--max-nodes"))
        return int_opt(a, value(argc, argv, i), 1, TT_MAX_NODES, &o->max_nodes);
    if (!strcmp(a, "--rate"))
        return num_opt(a, value(argc, argv, i), 1000, 768000, &o->rate);
    if (!strcmp(a, "--seconds")) {
        int st = num_opt(a, value(argc, argv, i), 0, 3600, &o->seconds);
        return st >= 0 || o->seconds > 0 ? st : usage("--seconds takes a length above 0 s");
    }
    if (!strcmp(a, "--seed")) {
        o->have_seed = 1;
        return seed_opt(value(argc, argv, i), &o->seed);
    }
    if (!strcmp(a, "--quiet")) {
        o->quiet = 1;
        return -1;
    }
    if (a[0] == '-' && a[1])
        return usage("unknown option '%s'", a);
    if (o->seed_path)
        return usage("one seed at a time ('%s' and '%s')", o->seed_path, a);
    o->seed_path = a;
    return -1;
}

/* Returns -1 to go on, else the exit status (0 after --help). */
static int parse_opts(int argc, char **argv, evo_opts *o, char *dirbuf, size_t cap) {
    memset(o, 0, sizeof *o);
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--help") || !strcmp(argv[i], "-h")) {
            fputs(synopsis, stdout);
            fputs(help_text, stdout);
            return 0;
        }
    }
    for (int i = 1; i < argc; i++) {
        int st = option(o, argc, argv, &i);
        if (st >= 0)
            return st;
    }
    if (!o->seed_path)
        return usage("evolve needs a seed tree (a .tt file)");
    if (o->target && o->ratings)
        return usage("--ratings or --target, not both");
    if (!o->population)
        o->population = o->target ? 24 : 8;
    if (!o->generations)
        o->generations = o->target ? 40 : 5;
    if (!o->dir)
        default_dir(o, dirbuf, cap);
    if (!o->have_seed) {
        o->seed = (uint64_t)time(NULL) ^ ((uint64_t)getpid() << 32);
        if (!o->quiet)
            fprintf(stderr, "wdrt evolve: --seed %llu\n", (unsigned long long)o->seed);
    }
    return -1;
}

int tt_evolve_main(int argc, char **argv) {
    evo_opts o;
    char dirbuf[PATH_MAX];
    int st = parse_opts(argc, argv, &o, dirbuf, sizeof dirbuf);
    if (st >= 0)
        return st;
    char err[4096];
    tt_file *f = tt_file_read(o.seed_path, NULL, 0, err, sizeof err);
    if (!f) {
        fputs(err, stderr);
        return EXIT_INPUT;
    }
    evo *e = calloc(1, sizeof *e);
    if (!e) {
        tt_file_free(f);
        return out_of_memory();
    }
    e->o = &o;
    struct timespec t0, t1;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    st = run(e, f);
    clock_gettime(CLOCK_MONOTONIC, &t1);
    if (!st && !o.quiet) {
        double wall = (double)(t1.tv_sec - t0.tv_sec) + (t1.tv_nsec - t0.tv_nsec) * 1e-9;
        fprintf(stderr, "wdrt evolve: %d generation%s of %d in %.1f s", o.generations, o.generations == 1 ? "" : "s",
                o.population, wall);
        if (e->sp)
            fprintf(stderr, ", distance %.4g dB (the seed's %.4g dB)", e->pop[best_of(e)].score, e->seed_score);
        fprintf(stderr, "; wrote %s/best.tt\n", o.dir);
    }
    evo_free(e);
    free(e);
    tt_file_free(f);
    return st;
}
