/*
 * tt_run.c - the kernels of compiled timbre trees (tt_prog.h): each runs
 * one instruction over a block, for every element of its vector.  Real-
 * time safe: no allocation, no locks, no I/O, bounded time (a block of an
 * energetic replay runs its argument for at most TT_MAX_SPEED blocks and
 * a window more).
 *
 * The definitions of the functions (DESIGN §6.3 and §6.6) as computed
 * here:
 *   t            n / fs, n counted from the tree's start (per segment)
 *   sine X       sin(2 pi X); saw, square, triangle of a phase in cycles
 *   osc F SHAPE  phase p_0 = 0, p_{n+1} = p_n + F_n / fs; saw and square
 *                band-limited by polyBLEP
 *   integral X   trapezoid rule from 0
 *   env          linear between keys, held outside them
 *   delay X S    y_n = x_{n - S fs}: 4-point Catmull-Rom between samples
 *   lowpass ...  RBJ biquads (bilinear, prewarped at F), Q 1/sqrt 2
 *   reson X F T  w_n = r e^{i th} w_{n-1} + x_n, y_n = Im(e^{i th} w_n), th = 2 pi F / fs,
 *                r = 10^(-3 / (T fs)): an impulse rings as r^n sin(th (n+1))
 *   sample       the file's channels averaged; Catmull-Rom at a position
 *                advancing RATE fs_file / fs per sample
 *   importance   weights that sum to one (tt_importance), ramped over a
 *                block when they change
 *   energetic    the argument replayed at its own time tau (tau_0 = 0,
 *                advancing SPEED / fs), by a Kaiser-windowed sinc whose
 *                cutoff falls as 1/SPEED above 1
 *   sputter      an envelope of falling ramps whose rate glides
 *                exponentially from F0 to F1 over DUR, rising over
 *                min(0.5, 0.002 f) of each cycle so that it never jumps
 */
#include "tt_prog.h"

#include <math.h>
#include <string.h>

#define TB TT_BLOCK
#define RING 1024 /* energetic: frames of its argument kept */

typedef struct ex {
    tt_state *st;
    const tt_class *C;
    const tt_prog *P;
    double *regs;
    const double *cdata;
    double fs;
} ex;

static double *reg(const ex *e, int r) {
    const tt_reg *g = &e->P->regs[r];
    return g->rate == TT_CONST ? (double *)e->cdata + g->off : e->regs + g->off;
}

/* element and frame strides of register r read by an instruction */
static void strides(const ex *e, int r, int *es, int *fs) {
    const tt_reg *g = &e->P->regs[r];
    *fs = g->rate == TT_AUDIO;
    *es = g->w == 1 ? 0 : g->rate == TT_AUDIO ? TB : 1;
}

static int64_t *segf(const ex *e) { return (int64_t *)((char *)e->st + e->C->layout[L_SEGF]); }
static void *opst(const ex *e, int i) { return (char *)e->st + e->C->stoff[i]; }
static const int *args_of(const tt_prog *P, const tt_ins *I) { return I->ax ? P->xargs + I->ax : I->a; }

/* ---- helpers shared with the compiler and tests ---- */

static uint64_t mix64(uint64_t z) {
    z += 0x9e3779b97f4a7c15ull;
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
}

static double u01(uint64_t h) { return (double)(h >> 11) * 0x1.0p-53; }

double tt_rvector_u(int n, int i) {
    if (n < 1)
        return 0;
    return (i + u01(mix64(((uint64_t)(uint32_t)n << 32) ^ (uint32_t)i ^ 0x5eed0000000000ull))) / n;
}

static double grad1(int64_t i) { return u01(mix64((uint64_t)i)) * 2 - 1; }

static double fade(double f) { return f * f * f * (f * (f * 6 - 15) + 10); }

double tt_pnoise1(double x) {
    if (!isfinite(x) || fabs(x) > 1e15)
        return 0;
    double x0 = floor(x), f = x - x0;
    int64_t i = (int64_t)x0;
    double g0 = grad1(i) * f, g1 = grad1(i + 1) * (f - 1);
    return 2 * (g0 + fade(f) * (g1 - g0));
}

static double grad2(int64_t i, int64_t j, double x, double y) {
    uint64_t h = mix64((uint64_t)i * 0x9e3779b97f4a7c15ull ^ mix64((uint64_t)j));
    double a = u01(h) * 2 * M_PI;
    return cos(a) * x + sin(a) * y;
}

double tt_pnoise2(double x, double y) {
    if (!isfinite(x) || !isfinite(y) || fabs(x) > 1e15 || fabs(y) > 1e15)
        return 0;
    double x0 = floor(x), y0 = floor(y), fx = x - x0, fy = y - y0;
    int64_t i = (int64_t)x0, j = (int64_t)y0;
    double n00 = grad2(i, j, fx, fy), n10 = grad2(i + 1, j, fx - 1, fy);
    double n01 = grad2(i, j + 1, fx, fy - 1), n11 = grad2(i + 1, j + 1, fx - 1, fy - 1);
    double u = fade(fx), v = fade(fy);
    double a = n00 + u * (n10 - n00), b = n01 + u * (n11 - n01);
    return 1.4142135623730951 * (a + v * (b - a));
}

void tt_importance(int n, const double *w, const double *locked, double *out) {
    double rem = 1, F = 0;
    int nfree = 0;
    for (int j = 0; j < n; j++) {
        double wj = w[j] > 0 ? w[j] : 0;
        if (locked && locked[j] != 0) {
            out[j] = wj < rem ? wj : rem;
            rem -= out[j];
        } else {
            F += wj;
            nfree++;
        }
    }
    if (rem < 0)
        rem = 0;
    for (int j = 0; j < n; j++)
        if (!(locked && locked[j] != 0)) {
            double wj = w[j] > 0 ? w[j] : 0;
            out[j] = F > 0 ? rem * wj / F : rem / nfree;
        }
    if (nfree == 0 && n > 0)
        out[n - 1] += rem;
}

static double frac(double x) { return x - floor(x); }

/* sin(2 pi x) without a call: x folded to a quarter period, then the
 * Taylor series of sin to u^21 (its remainder below 2e-18 there), so
 * the result is within a few ulps of sin(2 pi frac(x)); branch-free, so
 * loops over a block vectorize. */
static inline double sin2pi(double x) {
    double r = x - floor(x + 0.5);         /* [-1/2, 1/2) */
    double a = fabs(r);
    double f = a > 0.25 ? 0.5 - a : a;     /* sin(2 pi a) = sin(2 pi (1/2 - a)) */
    double u = 6.283185307179586 * f, u2 = u * u;
    double p = 1.9572941063391261e-20;     /* 1/21! */
    p = p * u2 - 8.2206352466243297e-18;   /* -1/19! */
    p = p * u2 + 2.8114572543455206e-15;   /* 1/17! */
    p = p * u2 - 7.6471637318198164e-13;   /* -1/15! */
    p = p * u2 + 1.6059043836821613e-10;   /* 1/13! */
    p = p * u2 - 2.5052108385441720e-08;   /* -1/11! */
    p = p * u2 + 2.7557319223985893e-06;   /* 1/9! */
    p = p * u2 - 1.9841269841269841e-04;   /* -1/7! */
    p = p * u2 + 8.3333333333333333e-03;   /* 1/5! */
    p = p * u2 - 1.6666666666666667e-01;   /* -1/3! */
    p = u + u * u2 * p;
    return r < 0 ? -p : p;
}

/* exp(x) without a call where the result is a normal double: x = n ln 2
 * + f with |f| <= ln2/2 (ln 2 in two parts, Cody and Waite), e^f by its
 * Taylor series to f^13 (remainder below 5e-18), 2^n by the exponent's
 * bits; elsewhere (and for NaN) the library's. */
static inline double fexp(double x) {
    if (!(x > -708 && x < 709))
        return exp(x);
    double n = floor(x * 1.4426950408889634 + 0.5);
    double f = (x - n * 0.693145751953125) - n * 1.4286068203094173e-06;
    double p = 1.6059043836821613e-10;     /* 1/13! */
    p = p * f + 2.0876756987868099e-09;    /* 1/12! */
    p = p * f + 2.5052108385441720e-08;
    p = p * f + 2.7557319223985893e-07;
    p = p * f + 2.7557319223985888e-06;
    p = p * f + 2.4801587301587302e-05;
    p = p * f + 1.9841269841269841e-04;
    p = p * f + 1.3888888888888889e-03;
    p = p * f + 8.3333333333333333e-03;
    p = p * f + 4.1666666666666667e-02;
    p = p * f + 1.6666666666666667e-01;
    p = p * f + 0.5;
    p = p * f + 1;
    p = p * f + 1;
    union {
        double d;
        uint64_t u;
    } b;
    b.u = (uint64_t)((int64_t)n + 1023) << 52;
    return p * b.d;
}

static double wave(int op, double x) {
    switch (op) {
    case TT_SINE:
        return sin2pi(x);
    case TT_SAW:
        return 2 * frac(x + 0.5) - 1;
    case TT_SQUARE:
        return frac(x) < 0.5 ? 1 : -1;
    default:
        return 1 - 4 * fabs(frac(x + 0.25) - 0.5);
    }
}

static double math1(int op, double x) {
    switch (op) {
    case TT_EXP:
        return fexp(x);
    case TT_LOG:
        return log(x);
    case TT_SQRT:
        return sqrt(x);
    case TT_ABS:
        return fabs(x);
    case TT_SIN:
        return sin(x);
    case TT_COS:
        return cos(x);
    case TT_FLOOR:
        return floor(x);
    case TT_TANH:
        return tanh(x);
    case TT_DAMP:
        return fexp(-x);
    case TT_SUB:
        return -x;
    case TT_PNOISE:
        return tt_pnoise1(x);
    default:
        return wave(op, x);
    }
}

static double math2(int op, double x, double y) {
    switch (op) {
    case TT_ADD:
        return x + y;
    case TT_SUB:
        return x - y;
    case TT_MUL:
        return x * y;
    case TT_DIV:
        return x / y;
    case TT_POW:
        return pow(x, y);
    case TT_MIN:
        return x < y ? x : y;
    case TT_MAX:
        return x > y ? x : y;
    default:
        return tt_pnoise2(x, y);
    }
}

/* Values that are not finite would poison every block after them (a
 * filter's state, a sum): they become 0 where a tree computes them. */
static double fin(double x) { return isfinite(x) ? x : 0; }

/* ---- elementwise ---- */

static void k_math(const ex *e, const tt_ins *I, int n) {
    const int *A = args_of(e->P, I);
    int W = e->P->regs[I->dst].w;
    double *d = reg(e, I->dst);
    int des = I->rate == TT_AUDIO ? TB : 1;
    int aes, afs;
    const double *a = reg(e, A[0]);
    strides(e, A[0], &aes, &afs);
    if (I->na == 1) {
        for (int k = 0; k < W; k++) {
            double *dk = d + k * des;
            const double *ak = a + k * aes;
            if (afs && I->k == TT_SINE)
                for (int i = 0; i < n; i++)
                    dk[i] = sin2pi(ak[i]);
            else if (afs)
                for (int i = 0; i < n; i++)
                    dk[i] = fin(math1(I->k, ak[i]));
            else {
                double y = fin(math1(I->k, ak[0]));
                for (int i = 0; i < n; i++)
                    dk[i] = y;
            }
        }
        return;
    }
    int bes, bfs;
    const double *b = reg(e, A[1]);
    strides(e, A[1], &bes, &bfs);
    for (int k = 0; k < W; k++) {
        double *dk = d + k * des;
        const double *ak = a + k * aes, *bk = b + k * bes;
        switch (I->k) { /* the common ones without a call per sample */
        case TT_ADD:
            if (afs && bfs)
                for (int i = 0; i < n; i++)
                    dk[i] = ak[i] + bk[i];
            else if (afs)
                for (int i = 0; i < n; i++)
                    dk[i] = ak[i] + bk[0];
            else if (bfs)
                for (int i = 0; i < n; i++)
                    dk[i] = ak[0] + bk[i];
            else
                for (int i = 0; i < n; i++)
                    dk[i] = ak[0] + bk[0];
            continue;
        case TT_MUL:
            if (afs && bfs)
                for (int i = 0; i < n; i++)
                    dk[i] = ak[i] * bk[i];
            else if (afs)
                for (int i = 0; i < n; i++)
                    dk[i] = ak[i] * bk[0];
            else if (bfs)
                for (int i = 0; i < n; i++)
                    dk[i] = ak[0] * bk[i];
            else
                for (int i = 0; i < n; i++)
                    dk[i] = ak[0] * bk[0];
            continue;
        case TT_POW:
            if (!afs && bfs && ak[0] > 0 && isfinite(ak[0])) { /* a^b(t) = e^(b ln a), ln a once */
                double la = log(ak[0]);
                for (int i = 0; i < n; i++)
                    dk[i] = fin(fexp(bk[i] * la));
                continue;
            }
            /* fall through */
        default:
            for (int i = 0; i < n; i++)
                dk[i] = fin(math2(I->k, ak[i * afs], bk[i * bfs]));
        }
    }
}

/* sin/cos(2 pi v (s t + o)), exp(v (s t + o)) and their products by
 * recurrences anchored exactly at the block's first frame: a rotation
 * (or a multiplication, or a decaying rotation) per sample.  Four
 * elements advance side by side, so their chains overlap in the
 * processor instead of waiting on each other. */
#define RG 4

static void k_rec(const ex *e, const tt_ins *I, int64_t f0, int n) {
    int W = e->P->regs[I->dst].w, kind = I->k;
    double *d = reg(e, I->dst), t0 = (double)f0 / e->fs;
    const int *A = args_of(e->P, I);
    int es[4], fs_[4];
    const double *x[4] = {NULL, NULL, NULL, NULL};
    for (int j = 0; j < I->na; j++) {
        x[j] = reg(e, A[j]);
        strides(e, A[j], &es[j], &fs_[j]);
    }
    for (int k0 = 0; k0 < W; k0 += RG) {
        int m = W - k0 < RG ? W - k0 : RG;
        double zr[RG], zi[RG], rr[RG], ri[RG];
        for (int g = 0; g < RG; g++) {
            int k = k0 + (g < m ? g : 0);
            double s = x[0][k * es[0]], o = x[1][k * es[1]];
            if (kind == K_EXPREC) {
                double y = exp(I->v * (s * t0 + o)), r = exp(I->v * s / e->fs);
                zr[g] = y, zi[g] = 0, rr[g] = r, ri[g] = 0;
            } else {
                double c0 = frac(I->v * (s * t0 + o)), dc = frac(I->v * s / e->fs);
                zr[g] = cos(2 * M_PI * c0), zi[g] = sin(2 * M_PI * c0);
                rr[g] = cos(2 * M_PI * dc), ri[g] = sin(2 * M_PI * dc);
                if (kind == K_DSINREC) {
                    double s2 = x[2][k * es[2]], o2 = x[3][k * es[3]];
                    double a = exp(I->v2 * (s2 * t0 + o2)), q = exp(I->v2 * s2 / e->fs);
                    zr[g] *= a, zi[g] *= a, rr[g] *= q, ri[g] *= q;
                }
            }
            if (!(isfinite(zr[g]) && isfinite(zi[g]) && isfinite(rr[g]) && isfinite(ri[g])))
                zr[g] = zi[g] = rr[g] = ri[g] = 0;
        }
        double *dk[RG];
        for (int g = 0; g < RG; g++)
            dk[g] = d + (size_t)(k0 + (g < m ? g : 0)) * TB;
        if (kind == K_EXPREC) {
            for (int i = 0; i < n; i++)
                for (int g = 0; g < RG; g++) {
                    dk[g][i] = zr[g];
                    zr[g] *= rr[g];
                }
        } else {
            int re = kind == K_COSREC;
            for (int i = 0; i < n; i++)
                for (int g = 0; g < RG; g++) {
                    dk[g][i] = re ? zr[g] : zi[g];
                    double nr = zr[g] * rr[g] - zi[g] * ri[g];
                    zi[g] = zr[g] * ri[g] + zi[g] * rr[g];
                    zr[g] = nr;
                }
        }
    }
}

/* The sum of decaying rotations (K_MODESUM), eight modes side by side:
 * the modes of a struck body without a register per mode. */
#define MG 8

static void k_modesum(const ex *e, const tt_ins *I, int64_t f0, int n) {
    const int *A = args_of(e->P, I);
    int W = 1, es[4], fs_[4];
    const double *x[4];
    for (int j = 0; j < 4; j++) {
        x[j] = reg(e, A[j]);
        strides(e, A[j], &es[j], &fs_[j]);
        W = e->P->regs[A[j]].w > W ? e->P->regs[A[j]].w : W;
    }
    double *d = reg(e, I->dst), t0 = (double)f0 / e->fs;
    for (int i = 0; i < n; i++)
        d[i] = 0;
    for (int k0 = 0; k0 < W; k0 += MG) {
        double zr[MG], zi[MG], rr[MG], ri[MG];
        for (int g = 0; g < MG; g++) {
            zr[g] = zi[g] = rr[g] = ri[g] = 0;
            int k = k0 + g;
            if (k >= W)
                continue;
            double s = x[0][k * es[0]], o = x[1][k * es[1]], s2 = x[2][k * es[2]], o2 = x[3][k * es[3]];
            double c0 = frac(I->v * (s * t0 + o)), dc = frac(I->v * s / e->fs);
            double a = exp(I->v2 * (s2 * t0 + o2)), q = exp(I->v2 * s2 / e->fs);
            zr[g] = a * cos(2 * M_PI * c0), zi[g] = a * sin(2 * M_PI * c0);
            rr[g] = q * cos(2 * M_PI * dc), ri[g] = q * sin(2 * M_PI * dc);
            if (!(isfinite(zr[g]) && isfinite(zi[g]) && isfinite(rr[g]) && isfinite(ri[g])))
                zr[g] = zi[g] = rr[g] = ri[g] = 0;
        }
        for (int i = 0; i < n; i++) {
            double acc = 0;
            for (int g = 0; g < MG; g++) {
                acc += zi[g];
                double nr = zr[g] * rr[g] - zi[g] * ri[g];
                zi[g] = zr[g] * ri[g] + zi[g] * rr[g];
                zr[g] = nr;
            }
            d[i] += acc;
        }
    }
}

/* a register copied into the destination's shape (broadcast) */
static void k_copy(const ex *e, const tt_ins *I, int n) {
    int W = e->P->regs[I->dst].w, es, fs;
    double *d = reg(e, I->dst);
    const double *a = reg(e, I->a[0]);
    strides(e, I->a[0], &es, &fs);
    int des = I->rate == TT_AUDIO ? TB : 1;
    for (int k = 0; k < W; k++)
        for (int i = 0; i < n; i++)
            d[k * des + i] = a[k * es + i * fs];
}

/* ---- vectors ---- */

static void k_vector(const ex *e, const tt_ins *I, int n) {
    const int *A = args_of(e->P, I);
    double *d = reg(e, I->dst);
    int des = I->rate == TT_AUDIO ? TB : 1, at = 0;
    for (int j = 0; j < I->na; j++) {
        int w = e->P->regs[A[j]].w, es, fs;
        const double *a = reg(e, A[j]);
        strides(e, A[j], &es, &fs);
        for (int k = 0; k < w; k++, at++)
            for (int i = 0; i < n; i++)
                d[at * des + i] = a[k * es + i * fs];
    }
}

static void k_rvector(const ex *e, const tt_ins *I, int n) {
    int W = e->P->regs[I->dst].w, les, lfs, hes, hfs;
    double *d = reg(e, I->dst);
    const double *lo = reg(e, I->a[0]), *hi = reg(e, I->a[1]);
    strides(e, I->a[0], &les, &lfs);
    strides(e, I->a[1], &hes, &hfs);
    int des = I->rate == TT_AUDIO ? TB : 1;
    for (int k = 0; k < W; k++) {
        double u = tt_rvector_u(W, k);
        for (int i = 0; i < n; i++)
            d[k * des + i] = lo[i * lfs] + (hi[i * hfs] - lo[i * lfs]) * u;
    }
}

static void k_combine(const ex *e, const tt_ins *I, int n) {
    int w = e->P->regs[I->a[0]].w, es, fs;
    double *d = reg(e, I->dst);
    const double *a = reg(e, I->a[0]);
    strides(e, I->a[0], &es, &fs);
    if (!fs) {
        double s = 0;
        for (int k = 0; k < w; k++)
            s += a[k * es];
        for (int i = 0; i < n; i++)
            d[i] = s;
        return;
    }
    memcpy(d, a, sizeof(double) * (size_t)n);
    for (int k = 1; k < w; k++) {
        const double *ak = a + k * TB;
        for (int i = 0; i < n; i++)
            d[i] += ak[i];
    }
}

/* ---- generators ---- */

static double blep(double t, double dt) {
    if (t < dt) {
        t /= dt;
        return t + t - t * t - 1;
    }
    if (t > 1 - dt) {
        t = (t - 1) / dt;
        return t * t + t + t + 1;
    }
    return 0;
}

/* the residual of a band-limited corner whose slope changes by 2 per
 * sample, t cycles after it (2-point polyBLAMP: the integral of blep) */
static double blamp(double t, double dt) {
    if (t < dt) {
        t = t / dt - 1;
        return -t * t * t / 3;
    }
    if (t > 1 - dt) {
        t = (t - 1) / dt + 1;
        return t * t * t / 3;
    }
    return 0;
}

static void k_osc(const ex *e, const tt_ins *I, void *S, int n) {
    int W = e->P->regs[I->dst].w, es, fs, shape = (int)I->v;
    double *d = reg(e, I->dst), *ph = S;
    const double *F = reg(e, I->a[0]);
    strides(e, I->a[0], &es, &fs);
    for (int k = 0; k < W; k++) {
        double p = ph[k];
        for (int i = 0; i < n; i++) {
            double dt = F[k * es + i * fs] / e->fs, adt = fabs(dt), y;
            if (!isfinite(dt))
                dt = adt = 0;
            if (adt > 0.5)
                adt = 0.5;
            switch (shape) {
            case TT_SHAPE_SINE:
                y = sin(2 * M_PI * p);
                break;
            case TT_SHAPE_SAW: {
                double q = frac(p + 0.5);
                y = 2 * q - 1 - (adt > 0 ? blep(q, adt) : 0);
                break;
            }
            case TT_SHAPE_SQUARE:
                y = (p < 0.5 ? 1 : -1) + (adt > 0 ? blep(p, adt) - blep(frac(p + 0.5), adt) : 0);
                break;
            default: /* corners at 1/4 (slope -8 per cycle) and 3/4 (+8) */
                y = 1 - 4 * fabs(frac(p + 0.25) - 0.5);
                if (adt > 0)
                    y += 4 * adt * (blamp(frac(p + 0.25), adt) - blamp(frac(p + 0.75), adt)); /* half the slope change (blamp: a step of 2) */
                break;
            }
            d[k * TB + i] = y;
            p = frac(p + dt);
        }
        ph[k] = p;
    }
}

static void k_noise(const ex *e, const tt_ins *I, void *S, int n) {
    uint64_t *s = S;
    double *d = reg(e, I->dst);
    for (int i = 0; i < n; i++) {
        uint64_t x = *s;
        x ^= x >> 12;
        x ^= x << 25;
        x ^= x >> 27;
        *s = x;
        d[i] = u01(x * 2685821657736338717ull) * 2 - 1;
    }
}

static double catmull(double p0, double p1, double p2, double p3, double f) {
    /* between p1 (f = 0) and p2 (f = 1) */
    return p1 + 0.5 * f * (p2 - p0 + f * (2 * p0 - 5 * p1 + 4 * p2 - p3 + f * (3 * (p1 - p2) + p3 - p0)));
}

static void k_sample(const ex *e, const tt_ins *I, void *S, int n) {
    const tt_sample *sm = &e->P->samples[I->data];
    double *pos = S, *d = reg(e, I->dst), base = sm->fs / e->fs;
    int es = 0, fs = 0;
    const double *R = NULL;
    if (I->na) {
        R = reg(e, I->a[0]);
        strides(e, I->a[0], &es, &fs);
    }
    for (int i = 0; i < n; i++) {
        double p = *pos, y = 0;
        if (p > -2 && p < (double)sm->n + 1) {
            long j = (long)floor(p);
            double f = p - (double)j, q[4];
            for (int m = 0; m < 4; m++) {
                long jj = j - 1 + m;
                q[m] = jj >= 0 && jj < sm->n ? sm->x[jj] : 0;
            }
            y = catmull(q[0], q[1], q[2], q[3], f);
        }
        d[i] = y;
        double r = R ? R[i * fs] : 1;
        if (isfinite(r))
            *pos = p + r * base;
    }
}

typedef struct integ {
    double y, x;
} integ;

static void k_integral(const ex *e, const tt_ins *I, void *S, int n, int64_t f0) {
    int W = e->P->regs[I->dst].w, es, fs;
    integ *s = S;
    double *d = reg(e, I->dst), h = 0.5 / e->fs;
    const double *a = reg(e, I->a[0]);
    strides(e, I->a[0], &es, &fs);
    for (int k = 0; k < W; k++) {
        double y = s[k].y, xp = s[k].x;
        for (int i = 0; i < n; i++) {
            double x = a[k * es + i * fs];
            if (f0 + i > 0)
                y += h * (xp + x);
            xp = x;
            d[k * TB + i] = y = fin(y);
        }
        s[k].y = y, s[k].x = xp;
    }
}

static void k_env(const ex *e, const tt_ins *I, void *S, int n, int64_t f0) {
    int *at = S;
    const double *K = I->x->k;
    int nk = I->x->nk / 2;
    double *d = reg(e, I->dst);
    for (int i = 0; i < n; i++) {
        double t = (double)(f0 + i) / e->fs;
        while (*at < nk && K[2 * *at] <= t)
            ++*at;
        double y;
        if (*at == 0)
            y = K[1];
        else if (*at == nk)
            y = K[2 * nk - 1];
        else {
            double ta = K[2 * (*at - 1)], va = K[2 * (*at - 1) + 1], tb = K[2 * *at], vb = K[2 * *at + 1];
            y = tb > ta ? va + (vb - va) * (t - ta) / (tb - ta) : vb;
        }
        d[i] = y;
    }
}

/* ---- delays and filters ---- */

typedef struct dly {
    int64_t w;   /* frames written */
    int64_t mask;
    double maxd; /* frames */
} dly;

static void k_delay(const ex *e, const tt_ins *I, void *S, int n) {
    int W = e->P->regs[I->dst].w, xes, xfs, ses, sfs;
    dly *s = S;
    double *buf = (double *)(s + 1), *d = reg(e, I->dst);
    const double *x = reg(e, I->a[0]), *D = reg(e, I->a[1]);
    strides(e, I->a[0], &xes, &xfs);
    strides(e, I->a[1], &ses, &sfs);
    int64_t M = s->mask + 1;
    for (int k = 0; k < W; k++) {
        double *b = buf + (size_t)k * (size_t)M;
        for (int i = 0; i < n; i++) {
            int64_t w = s->w + i;
            b[w & s->mask] = x[k * xes + i * xfs];
            double dd = D[k * ses + i * sfs] * e->fs;
            dd = !(dd > 0) ? 0 : dd > s->maxd ? s->maxd : dd;
            int64_t m = (int64_t)dd;
            double f = dd - (double)m, y;
#define AT(j) ((w - (j)) >= 0 ? b[(w - (j)) & s->mask] : 0.0)
            if (m == 0)
                y = AT(0) + f * (AT(1) - AT(0));
            else
                y = catmull(AT(m - 1), AT(m), AT(m + 1), AT(m + 2), f);
#undef AT
            d[k * TB + i] = y;
        }
    }
    s->w += n;
}


static void coefs(int op, double F, double Q, double fs, double c[5]) {
    double f = F / fs;
    f = !(f > 1e-6) ? 1e-6 : f > 0.4999 ? 0.4999 : f;
    Q = !(Q > 1e-3) ? 1e-3 : Q > 1e3 ? 1e3 : Q;
    double w0 = 2 * M_PI * f, cw = cos(w0), sw = sin(w0), al = sw / (2 * Q), a0 = 1 + al;
    double b0, b1, b2;
    if (op == TT_LOWPASS)
        b0 = (1 - cw) / 2, b1 = 1 - cw, b2 = b0;
    else if (op == TT_HIGHPASS)
        b0 = (1 + cw) / 2, b1 = -(1 + cw), b2 = b0;
    else
        b0 = al, b1 = 0, b2 = -al;
    c[0] = b0 / a0, c[1] = b1 / a0, c[2] = b2 / a0, c[3] = -2 * cw / a0, c[4] = (1 - al) / a0;
}

/* A filter's state, and the coefficients of the last block's params: a
 * block whose params have not moved reuses them (no cos, sin or pow). */
typedef struct bq {
    double z1, z2;
    double p1, p2;  /* the params the coefficients are for */
    double c[5];
    int ok;         /* c holds them */
} bq;

static const double *block_coefs(bq *s, int op, double F, double Q, double fs) {
    if (!s->ok || F != s->p1 || Q != s->p2) {
        coefs(op, F, Q, fs, s->c);
        s->p1 = F, s->p2 = Q, s->ok = 1;
    }
    return s->c;
}

static void k_biquad(const ex *e, const tt_ins *I, void *S, int n) {
    int W = e->P->regs[I->dst].w, xes, xfs, fes, ffs, qes = 0, qfs = 0;
    bq *s = S;
    double *d = reg(e, I->dst), q0 = M_SQRT1_2;
    const double *x = reg(e, I->a[0]), *F = reg(e, I->a[1]), *Q = &q0;
    strides(e, I->a[0], &xes, &xfs);
    strides(e, I->a[1], &fes, &ffs);
    if (I->na > 2) {
        Q = reg(e, I->a[2]);
        strides(e, I->a[2], &qes, &qfs);
    }
    for (int k = 0; k < W; k++) {
        double z1 = s[k].z1, z2 = s[k].z2;
        const double *xk = x + k * xes;
        double *dk = d + k * TB;
        if (!ffs && !qfs) { /* coefficients that hold for the block: kept in registers */
            const double *c = block_coefs(&s[k], I->k, F[k * fes], Q[k * qes], e->fs);
            double b0 = c[0], b1 = c[1], b2 = c[2], a1 = c[3], a2 = c[4];
            for (int i = 0; i < n; i++) {
                double xi = xk[i * xfs], y = b0 * xi + z1;
                z1 = b1 * xi - a1 * y + z2;
                z2 = b2 * xi - a2 * y;
                dk[i] = y;
            }
        } else { /* a moving frequency or Q: coefficients every sample */
            double c[5];
            for (int i = 0; i < n; i++) {
                coefs(I->k, F[k * fes + i * ffs], Q[k * qes + i * qfs], e->fs, c);
                double xi = xk[i * xfs], y = c[0] * xi + z1;
                z1 = c[1] * xi - c[3] * y + z2;
                z2 = c[2] * xi - c[4] * y;
                dk[i] = y;
            }
        }
        if (!isfinite(z1) || !isfinite(z2))
            z1 = z2 = 0;
        s[k].z1 = z1, s[k].z2 = z2;
    }
}

/* A complex one-pole: w_n = r e^{i theta} w_{n-1} + x_n, y_n = Im(e^{i theta} w_n),
 * whose impulse rings as r^n sin(theta (n + 1)); its pole's modulus is r
 * whatever theta does, so a frequency moving every sample cannot make it
 * grow (a direct-form two-pole can). */
static void k_reson(const ex *e, const tt_ins *I, void *S, int n) {
    int W = e->P->regs[I->dst].w, xes, xfs, fes, ffs, tes, tfs;
    bq *s = S; /* z1, z2: the real and imaginary parts of w */
    double *d = reg(e, I->dst);
    const double *x = reg(e, I->a[0]), *F = reg(e, I->a[1]), *T = reg(e, I->a[2]);
    strides(e, I->a[0], &xes, &xfs);
    strides(e, I->a[1], &fes, &ffs);
    strides(e, I->a[2], &tes, &tfs);
    for (int k = 0; k < W; k++) {
        double wr = s[k].z1, wi = s[k].z2, c = 0, sn = 0, r = 0;
        for (int i = 0; i < n; i++) {
            double Fi = F[k * fes + i * ffs], T60 = T[k * tes + i * tfs];
            if (!s[k].ok || Fi != s[k].p1 || T60 != s[k].p2) { /* the pole, when its params move */
                double w = 2 * M_PI * Fi / e->fs;
                s[k].c[0] = T60 > 0 && isfinite(T60) ? pow(10, -3 / (T60 * e->fs)) : 0;
                if (!isfinite(w))
                    w = 0;
                s[k].c[1] = cos(w), s[k].c[2] = sin(w);
                s[k].p1 = Fi, s[k].p2 = T60, s[k].ok = 1;
            }
            if (i == 0 || ffs || tfs)
                r = s[k].c[0], c = s[k].c[1], sn = s[k].c[2];
            double xi = x[k * xes + i * xfs];
            double nr = r * (c * wr - sn * wi) + xi;
            wi = r * (sn * wr + c * wi);
            wr = nr;
            d[k * TB + i] = sn * wr + c * wi;
        }
        if (!isfinite(wr) || !isfinite(wi))
            wr = wi = 0;
        s[k].z1 = wr, s[k].z2 = wi;
    }
}

/* ---- a compiled netlist ---- */

typedef struct vst {
    int pid[TT_MAX_PARAMS];
    double last[TT_MAX_PARAMS];
    double zero[TB], junk[TB];
    double inb[8][TB];
    /* then the voice's state, 16-byte aligned */
} vst;

static size_t vst_head(void) { return (sizeof(vst) + 15) & ~(size_t)15; }

static void k_voice(const ex *e, const tt_ins *I, void *S, int n) {
    const wdv_class *cls = e->P->voices[I->data].cls;
    vst *v = S;
    void *vs = (char *)S + vst_head();
    const int *A = args_of(e->P, I);
    const tt_node *x = I->x;
    for (int j = 0; j < x->n - x->nin; j++) {
        double p = reg(e, A[x->nin + j])[0];
        if (p != v->last[j] && v->pid[j] >= 0) {
            cls->set_param(vs, v->pid[j], p);
            v->last[j] = p;
        }
    }
    const double *in[64];
    double *out[64];
    for (int k = 0; k < cls->n_inputs && k < 64; k++) {
        in[k] = v->zero;
        if (k < x->nin) {
            const tt_reg *g = &e->P->regs[A[k]];
            if (g->rate == TT_AUDIO)
                in[k] = reg(e, A[k]);
            else if (k < 8) {
                double c = reg(e, A[k])[0];
                for (int i = 0; i < n; i++)
                    v->inb[k][i] = c;
                in[k] = v->inb[k];
            }
        }
    }
    for (int k = 0; k < cls->n_outputs && k < 64; k++)
        out[k] = k == 0 ? reg(e, I->dst) : v->junk;
    cls->process(vs, in, out, n);
}

/* ---- mix nodes ---- */

typedef struct imp {
    int have;
    double w[]; /* the weights the last block ended at */
} imp;

static void k_importance(const ex *e, const tt_ins *I, void *S, int n, int64_t f0) {
    const int *A = args_of(e->P, I);
    int W = e->P->regs[I->dst].w, first = I->k == TT_INVIMPORTANCE ? 2 : 0, ne = (I->na - first) / 2;
    imp *s = S;
    double *wv = s->w + ne, *wt = s->w + 2 * ne, *d = reg(e, I->dst);
    for (int j = 0; j < ne; j++)
        wt[j] = reg(e, A[first + 2 * j + 1])[0];
    tt_importance(ne, wt, I->x->k, wv);
    int des = I->rate == TT_AUDIO ? TB : 1;
    double T = first ? reg(e, A[0])[0] : 0, T0 = first ? reg(e, A[1])[0] : 0;
    for (int k = 0; k < W; k++)
        for (int i = 0; i < n; i++)
            d[k * des + i] = 0;
    for (int i = 0; i < n; i++) {
        double m = 0;
        if (first) {
            double t = (double)(f0 + i) / e->fs, u = T > 0 ? (t - T0) / T : t >= T0;
            u = u < 0 ? 0 : u > 1 ? 1 : u;
            m = 0.5 - 0.5 * cos(M_PI * u);
        }
        double r = s->have && n > 1 ? (double)(i + 1) / n : 1;
        for (int j = 0; j < ne; j++) {
            double wj = first ? (1 - m) * wv[j] + m * wv[ne - 1 - j] : wv[j];
            if (s->have && !first)
                wj = s->w[j] + (wj - s->w[j]) * r;
            int es, fs;
            const double *x = reg(e, A[first + 2 * j]);
            strides(e, A[first + 2 * j], &es, &fs);
            for (int k = 0; k < W; k++)
                d[k * des + i] += wj * x[k * es + i * fs];
        }
    }
    for (int j = 0; j < ne; j++)
        s->w[j] = wv[j];
    s->have = 1;
}

typedef struct spt {
    double phase;
} spt;

static void k_sputter(const ex *e, const tt_ins *I, void *S, int n, int64_t f0) {
    int W = e->P->regs[I->dst].w, es, fs;
    spt *s = S;
    double *d = reg(e, I->dst);
    const double *x = reg(e, I->a[0]);
    strides(e, I->a[0], &es, &fs);
    double F0 = reg(e, I->a[1])[0], F1 = reg(e, I->a[2])[0], D = reg(e, I->a[3])[0];
    F0 = !(F0 > 1e-3) ? 1e-3 : F0 > 0.25 * e->fs ? 0.25 * e->fs : F0;
    F1 = !(F1 > 1e-3) ? 1e-3 : F1 > 0.25 * e->fs ? 0.25 * e->fs : F1;
    double t0 = (double)f0 / e->fs;
    double f = D > 0 && t0 < D ? F0 * pow(F1 / F0, t0 / D) : F1;
    double q = D > 0 ? pow(F1 / F0, 1 / (D * e->fs)) : 1;
    double env[TB];
    for (int i = 0; i < n; i++) {
        double fr = frac(s->phase), a = 0.002 * f;
        a = a > 0.5 ? 0.5 : a;
        env[i] = fr < a ? fr / a : (1 - fr) / (1 - a);
        s->phase = frac(s->phase + f / e->fs);
        if (D > 0 && (double)(f0 + i + 1) / e->fs < D)
            f *= q;
        else
            f = F1;
    }
    for (int k = 0; k < W; k++)
        for (int i = 0; i < n; i++)
            d[k * TB + i] = x[k * es + i * fs] * env[i];
}

/* ---- energetic replay ---- */

typedef struct eng {
    double tau;      /* frames of the argument's time */
    int64_t made;    /* frames of the argument rendered */
    double ring[];   /* [W][RING] */
} eng;

static void run_seg(const ex *e, int seg, int n);

static double sinc_at(const float *tab, double u) {
    u = fabs(u) * SINC_RES;
    if (u >= SINC_H * SINC_RES)
        return 0;
    int j = (int)u;
    double f = u - j;
    return tab[j] + f * (tab[j + 1] - tab[j]);
}

static void k_energetic(const ex *e, const tt_ins *I, void *S, int n) {
    int W = e->P->regs[I->dst].w, es, fs;
    eng *s = S;
    double *d = reg(e, I->dst);
    const double *sp = reg(e, I->a[0]);
    strides(e, I->a[0], &es, &fs);
    int out = e->P->segout[I->child];
    const float *tab = e->P->sinc;
    for (int i = 0; i < n; i++) {
        double speed = sp[i * fs];
        speed = !(speed > 0) ? 0 : speed > TT_MAX_SPEED ? TT_MAX_SPEED : speed;
        double c = speed > 1 ? 1 / speed : 1, half = SINC_H / c, ctr = s->tau;
        int64_t hi = (int64_t)floor(ctr + half), lo = (int64_t)ceil(ctr - half);
        while (s->made <= hi) { /* the argument's next block */
            run_seg(e, I->child, TB);
            const double *src = reg(e, out);
            for (int k = 0; k < W; k++)
                for (int j = 0; j < TB; j++)
                    s->ring[(size_t)k * RING + (size_t)((s->made + j) & (RING - 1))] =
                        src[(e->P->regs[out].w == 1 ? 0 : k * TB) + j];
            s->made += TB;
        }
        if (lo < 0)
            lo = 0;
        if (lo < s->made - RING)
            lo = s->made - RING;
        for (int k = 0; k < W; k++) {
            const double *r = s->ring + (size_t)k * RING;
            double acc = 0;
            for (int64_t j = lo; j <= hi; j++)
                acc += r[j & (RING - 1)] * sinc_at(tab, c * (ctr - (double)j));
            d[k * TB + i] = c * acc;
        }
        s->tau += speed;
    }
}

/* ---- running ---- */

static void exec(const ex *e, int idx, int n, int64_t f0) {
    const tt_ins *I = &e->P->ins[idx];
    void *S = opst(e, idx);
    if (I->rate != TT_AUDIO)
        n = 1;
    switch (I->k) {
    case TT_T: {
        double *d = reg(e, I->dst);
        for (int i = 0; i < n; i++)
            d[i] = (double)(f0 + i) / e->fs;
        return;
    }
    case K_SINREC:
    case K_COSREC:
    case K_EXPREC:
    case K_DSINREC:
        k_rec(e, I, f0, n);
        return;
    case K_MODESUM:
        k_modesum(e, I, f0, n);
        return;
    case K_COPY:
        k_copy(e, I, n);
        return;
    case TT_VECTOR:
        k_vector(e, I, n);
        return;
    case TT_RVECTOR:
        k_rvector(e, I, n);
        return;
    case TT_COMBINE:
        k_combine(e, I, n);
        return;
    case TT_OSC:
        k_osc(e, I, S, n);
        return;
    case TT_NOISE:
        k_noise(e, I, S, n);
        return;
    case TT_SAMPLE:
        k_sample(e, I, S, n);
        return;
    case TT_INTEGRAL:
        k_integral(e, I, S, n, f0);
        return;
    case TT_ENV:
        k_env(e, I, S, n, f0);
        return;
    case TT_DELAY:
        k_delay(e, I, S, n);
        return;
    case TT_LOWPASS:
    case TT_HIGHPASS:
    case TT_BANDPASS:
        k_biquad(e, I, S, n);
        return;
    case TT_RESON:
        k_reson(e, I, S, n);
        return;
    case TT_VOICE:
        k_voice(e, I, S, n);
        return;
    case TT_IMPORTANCE:
    case TT_INVIMPORTANCE:
        k_importance(e, I, S, n, f0);
        return;
    case TT_SPUTTER:
        k_sputter(e, I, S, n, f0);
        return;
    case TT_ENERGETIC:
        k_energetic(e, I, S, n);
        return;
    default:
        k_math(e, I, n);
        return;
    }
}

static void run_seg(const ex *e, int seg, int n) {
    int64_t *F = segf(e);
    int64_t f0 = F[seg];
    for (int i = 0; i < e->P->nins; i++)
        if (e->P->ins[i].seg == seg)
            exec(e, i, n, f0);
    F[seg] = f0 + n;
}

static ex mkex(tt_state *st) {
    ex e;
    e.st = st;
    e.C = st->C;
    e.P = st->C->prog;
    e.regs = (double *)((char *)st + st->C->layout[L_REGS]);
    e.cdata = e.P->cdata;
    e.fs = st->fs;
    return e;
}

void tt_run_block(tt_state *st, double *out, int n) {
    ex e = mkex(st);
    run_seg(&e, 0, n);
    const double *y = reg(&e, e.P->segout[0]);
    for (int i = 0; i < n; i++)
        out[i] = y[i];
}

double tt_run_energy(const tt_state *st) {
    if (!st->C)
        return 0;
    ex e = mkex((tt_state *)st);
    double t = (double)segf(&e)[0] / e.fs;
    if (t < e.P->live_until)
        return 1 + t; /* may still sound: never still, never below its start */
    double E = 0;
    for (int i = 0; i < e.P->nins; i++)
        if (e.P->ins[i].k == TT_VOICE) {
            const wdv_class *cls = e.P->voices[e.P->ins[i].data].cls;
            E += cls->energy((char *)opst(&e, i) + vst_head());
        }
    return E;
}

/* ---- state ---- */

static int64_t delay_frames(const tt_prog *P, const tt_ins *I, double fs) {
    double m = I->x->v;
    if (m <= 0) {
        const tt_reg *g = &P->regs[I->a[1]];
        m = 0;
        for (int k = 0; g->rate == TT_CONST && k < g->w; k++)
            m = P->cdata[g->off + (size_t)k] > m ? P->cdata[g->off + (size_t)k] : m;
    }
    if (!(m <= TT_MAX_DELAY))
        m = TT_MAX_DELAY;
    return (int64_t)ceil(m * fs);
}

size_t tt_run_state_size(const tt_prog *P, const tt_ins *I, double fs) {
    int W = P->regs[I->dst].w;
    switch (I->k) {
    case TT_OSC:
        return sizeof(double) * (size_t)W;
    case TT_NOISE:
        return sizeof(uint64_t);
    case TT_SAMPLE:
        return sizeof(double);
    case TT_INTEGRAL:
        return sizeof(integ) * (size_t)W;
    case TT_ENV:
        return sizeof(int);
    case TT_DELAY: {
        int64_t need = delay_frames(P, I, fs) + 8, M = 1;
        while (M < need)
            M <<= 1;
        return sizeof(dly) + sizeof(double) * (size_t)M * (size_t)W;
    }
    case TT_LOWPASS:
    case TT_HIGHPASS:
    case TT_BANDPASS:
    case TT_RESON:
        return sizeof(bq) * (size_t)W;
    case TT_VOICE:
        return vst_head() + (P->voices[I->data].cls ? P->voices[I->data].cls->state_size : 0);
    case TT_IMPORTANCE:
    case TT_INVIMPORTANCE:
        return sizeof(imp) + sizeof(double) * 3 * (size_t)I->x->nk;
    case TT_SPUTTER:
        return sizeof(spt);
    case TT_ENERGETIC:
        return sizeof(eng) + sizeof(double) * RING * (size_t)W;
    default:
        return 0;
    }
}

void tt_run_reset(tt_state *st) {
    ex e = mkex(st);
    const tt_prog *P = e.P;
    memset(segf(&e), 0, sizeof(int64_t) * (size_t)P->nseg);
    for (int i = 0; i < P->nins; i++) {
        const tt_ins *I = &P->ins[i];
        size_t sz = tt_run_state_size(P, I, e.fs);
        void *S = opst(&e, i);
        if (I->k == TT_VOICE) {
            const wdv_class *cls = P->voices[I->data].cls;
            vst *v = S;
            for (int j = 0; j < TT_MAX_PARAMS; j++)
                v->last[j] = NAN;
            cls->reset((char *)S + vst_head());
            continue;
        }
        if (sz)
            memset(S, 0, sz);
        if (I->k == TT_NOISE)
            *(uint64_t *)S = mix64(0x7ee5eedull + (uint64_t)i) | 1;
        if (I->k == TT_DELAY) {
            dly *s = S;
            int64_t need = delay_frames(P, I, e.fs) + 8, M = 1;
            while (M < need)
                M <<= 1;
            s->mask = M - 1;
            s->maxd = (double)delay_frames(P, I, e.fs);
        }
    }
}

void tt_run_init_state(tt_state *st) {
    if (!st->C)
        return;
    ex e = mkex(st);
    const tt_prog *P = e.P;
    memset((char *)st + sizeof(tt_state), 0, st->C->layout[L_SIZE] - sizeof(tt_state));
    for (int i = 0; i < P->tree->nparams; i++)
        e.regs[P->regs[P->param_reg[i]].off] = P->tree->pdef[i];
    if (P->fs_reg >= 0)
        e.regs[P->regs[P->fs_reg].off] = e.fs;
    for (int i = 0; i < P->nins; i++) {
        const tt_ins *I = &P->ins[i];
        if (I->k != TT_VOICE)
            continue;
        const wdv_class *cls = P->voices[I->data].cls;
        vst *v = opst(&e, i);
        cls->init((char *)v + vst_head(), e.fs);
        const tt_node *x = I->x;
        for (int j = 0; j < x->n - x->nin && j < TT_MAX_PARAMS; j++) {
            v->pid[j] = -1;
            for (int q = 0; q < cls->n_params; q++)
                if (!strcmp(cls->params[q].name, x->pn[j]))
                    v->pid[j] = q;
        }
    }
    tt_run_reset(st);
}

void tt_run_const(const tt_prog *P, const tt_ins *I) {
    tt_state st0;
    tt_class C0;
    memset(&st0, 0, sizeof st0);
    memset(&C0, 0, sizeof C0);
    size_t zero = 0;
    C0.prog = P;
    C0.stoff = &zero;
    st0.C = &C0;
    st0.fs = 48000; /* constants do not depend on it */
    ex e = {&st0, &C0, P, NULL, P->cdata, 48000};
    /* only stateless kernels are constant */
    tt_ins J = *I;
    J.rate = TT_CONTROL;
    switch (J.k) {
    case TT_VECTOR:
        k_vector(&e, &J, 1);
        break;
    case TT_RVECTOR:
        k_rvector(&e, &J, 1);
        break;
    case TT_COMBINE:
        k_combine(&e, &J, 1);
        break;
    case K_COPY:
        k_copy(&e, &J, 1);
        break;
    case TT_IMPORTANCE: {
        /* the weights of constant entries: a state on the stack */
        double buf[1 + 3 * 64];
        if (I->x->nk <= 64) {
            memset(buf, 0, sizeof buf);
            k_importance(&e, &J, buf, 1, 0);
        }
        break;
    }
    default:
        k_math(&e, &J, 1);
        break;
    }
}
