/* refsim.c - trapezoidal-rule nodal simulation of a Circuit (see refsim.h). */
#include "refsim.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* The simulation runs in extended precision, so that its own rounding is
 * far below that of a double-precision voice it is compared with.
 * Building with -DREFSIM_REAL=double gives a plain double version. */
#ifndef REFSIM_REAL
#define REFSIM_REAL long double
#endif
typedef REFSIM_REAL real;

struct refsim {
    const Circuit *c;
    real fs, T;
    int nn;           /* node unknowns: graph nodes 1..nnodes-1 */
    int N;            /* unknowns of the step system */
    int *br;          /* element -> branch unknown of the step system, or -1 */
    double *params;
    int dirty;        /* params changed since the matrix was built */
    real *val;        /* element values in force (0: no value) */
    real *cdrv;       /* constant drive of each source without an input */
    real *A;          /* LU factors of the step matrix, N x N row-major */
    int *piv;
    real *rhs;        /* N */
    real *nodev;      /* node voltages, nnodes (0 for ground) */
    real *v, *i;      /* element voltage and current, last sample */
    real *d;          /* source drives, last sample */
    real *px;         /* PR_X integrals, per probe */
    real *pv;         /* PR_X: last v(n0) - v(n1), per probe */
    real work;
    long t;
    int singular0;    /* the network of sample -1 was singular */
    int round_state;  /* 0, or 64 / 32: state and factors rounded to
                         double / float (refsim_round_state) */
    /* nonlinear elements (E_NL) */
    int nnl;          /* how many */
    real *G;          /* the step matrix before factoring, N x N */
    real *J;          /* Newton: Jacobian and its factors, N x N */
    real *x, *dx, *xt, *r, *rt; /* Newton: iterate, step, trial, residuals */
    real *nlp;        /* 4 values per element: diode Is, n Vt, -, -;
                         contact k, alpha, lambda, gap */
    real *cx;         /* contact, nonlinear inductor: integral of its
                         voltage at the last sample (see has_flux);
                         nonlinear capacitor: the voltage of its law
                         that gives its charge */
    real gscale;      /* largest conductance in the step matrix */
    real ntol;        /* Newton's stop: NL_TOL, or coarser behind a gain */
    real *Rp;         /* contact, nonlinear inductor: the resistance the
                         rest of the step network presents to it */
    int nl_maxit;     /* most Newton iterations one step took */
    long nl_iters;    /* Newton iterations over all steps */
    long nl_unconverged; /* steps that hit the iteration cap */
    long nl_forced;   /* iterations whose step no halving made descend */
};

static real rd_(const refsim *s, real x) {
    return s->round_state == 32 ? (real)(float)x : (real)(double)x;
}
#define rd(x) rd_(s, (x))

/* ---- dense LU with partial pivoting ---- */

/* Factors the n x n row-major matrix in place; returns -1 if a pivot is
 * exactly zero. */
static int lu_factor(real *a, int *piv, int n) {
    for (int k = 0; k < n; k++) {
        int p = k;
        real best = fabsl(a[k * n + k]);
        for (int r = k + 1; r < n; r++)
            if (fabsl(a[r * n + k]) > best) {
                best = fabsl(a[r * n + k]);
                p = r;
            }
        piv[k] = p;
        if (best == 0.0)
            return -1;
        if (p != k)
            for (int j = 0; j < n; j++) {
                real tmp = a[k * n + j];
                a[k * n + j] = a[p * n + j];
                a[p * n + j] = tmp;
            }
        real inv = 1.0 / a[k * n + k];
        for (int r = k + 1; r < n; r++) {
            real f = a[r * n + k] * inv;
            a[r * n + k] = f;
            if (f != 0.0)
                for (int j = k + 1; j < n; j++)
                    a[r * n + j] -= f * a[k * n + j];
        }
    }
    return 0;
}

static void lu_solve(const real *a, const int *piv, int n, real *b) {
    for (int k = 0; k < n; k++) {
        int p = piv[k];
        if (p != k) {
            real tmp = b[k];
            b[k] = b[p];
            b[p] = tmp;
        }
    }
    for (int r = 1; r < n; r++) {
        real s = b[r];
        for (int j = 0; j < r; j++)
            s -= a[r * n + j] * b[j];
        b[r] = s;
    }
    for (int r = n - 1; r >= 0; r--) {
        real s = b[r];
        for (int j = r + 1; j < n; j++)
            s -= a[r * n + j] * b[j];
        b[r] = s / a[r * n + r];
    }
}

/* ---- structural solvability ---- */

static int uf_find(int *p, int x) {
    while (p[x] != x) {
        p[x] = p[p[x]];
        x = p[x];
    }
    return x;
}

/* Whether a resistive network is uniquely solvable: the voltage-defined
 * edges (is_vedge) form no loop, and every node that any element touches
 * reaches ground through edges that are not current-defined (is_iedge).
 * Nodes that no element touches are pinned to 0 by the caller. */
static int solvable(const Circuit *c, const int *is_vedge, const int *is_iedge) {
    int n = c->nnodes;
    int *p = malloc(sizeof(int) * (size_t)n);
    int *used = calloc((size_t)n, sizeof(int));
    if (!p || !used) {
        free(p);
        free(used);
        return 0;
    }
    int ok = 1;
    for (int k = 0; k < n; k++)
        p[k] = k;
    for (int e = 0; e < c->nelems && ok; e++) {
        if (!is_vedge[e])
            continue;
        int a = uf_find(p, c->elems[e].n[0]), b = uf_find(p, c->elems[e].n[1]);
        if (a == b)
            ok = 0;
        else
            p[a] = b;
    }
    for (int k = 0; k < n; k++)
        p[k] = k;
    for (int e = 0; e < c->nelems; e++) {
        const Elem *el = &c->elems[e];
        if (el->n[0] == el->n[1])
            continue;
        used[el->n[0]] = used[el->n[1]] = 1;
        if (is_iedge[e])
            continue;
        int a = uf_find(p, el->n[0]), b = uf_find(p, el->n[1]);
        if (a != b)
            p[a] = b;
    }
    for (int k = 1; k < n && ok; k++)
        if (used[k] && uf_find(p, k) != uf_find(p, 0))
            ok = 0;
    free(p);
    free(used);
    return ok;
}

static int has_value(const Elem *e) { return e->val != NULL; }

static int self_loop(const Elem *e) { return e->n[0] == e->n[1]; }

static int is_nl(const Elem *e) { return e->kind == E_NL && e->nl != NULL; }

static int is_contact(const Elem *e) { return is_nl(e) && e->nl->kind == NL_CONTACT; }

/* Elements whose state is the integral X of their voltage: contacts
 * (their compression plus gap) and nonlinear inductors (their flux). */
static int has_flux(const Elem *e) {
    return is_contact(e) || (is_nl(e) && e->nl->mutated == 'L');
}

static int is_nlcap(const Elem *e) { return is_nl(e) && e->nl->mutated == 'C'; }

/* Whether a resistive solve may rely on element e to carry current: a
 * nonlinear element is left out (as if open) when it may conduct nothing
 * (a contact that is open, a curve with a flat segment), a diode counts
 * since its slope never vanishes. */
static int nl_open_edge(const Elem *e) {
    return is_nl(e) && (e->nl->kind != NL_DIODE || e->nl->mutated);
}

/* Current at sample -1 of a nonlinear element (those that carry one at
 * rest act as current sources then): a contact's elastic force, a
 * nonlinear inductor's law at its initial flux. */
static real nl_rest_current(const refsim *s, int e);

/* ---- stamps ---- */

/* Adds g between the node unknowns of nodes a and b (0: ground). */
static void stamp_g(real *A, int N, int a, int b, real g) {
    if (a)
        A[(a - 1) * N + (a - 1)] += g;
    if (b)
        A[(b - 1) * N + (b - 1)] += g;
    if (a && b) {
        A[(a - 1) * N + (b - 1)] -= g;
        A[(b - 1) * N + (a - 1)] -= g;
    }
}

/* Adds a branch unknown k whose current flows from a to b, and the
 * v(a) - v(b) part of its own row. */
static void stamp_branch(real *A, int N, int a, int b, int k) {
    if (a) {
        A[(a - 1) * N + k] += 1.0;
        A[k * N + (a - 1)] += 1.0;
    }
    if (b) {
        A[(b - 1) * N + k] -= 1.0;
        A[k * N + (b - 1)] -= 1.0;
    }
}

/* A controlled source's output e (branch unknown k for a voltage output,
 * an op-amp or a transformer's winding) with gain g on the voltage across
 * its probe; a winding's probe draws -g times its current. */
static void stamp_ctl(const Circuit *c, real *A, int N, int e, int k, real g) {
    const Elem *el = &c->elems[e], *pr = &c->elems[el->peer];
    int a = el->n[0], b = el->n[1], cp = pr->n[0], cn = pr->n[1];
    if (el->kind == E_CI) { /* g v(probe) from a through it to b */
        if (a && cp) A[(a - 1) * N + cp - 1] += g;
        if (a && cn) A[(a - 1) * N + cn - 1] -= g;
        if (b && cp) A[(b - 1) * N + cp - 1] -= g;
        if (b && cn) A[(b - 1) * N + cn - 1] += g;
        return;
    }
    if (a) A[(a - 1) * N + k] += 1.0;
    if (b) A[(b - 1) * N + k] -= 1.0;
    if (el->kind == E_XF) {
        if (cp) A[(cp - 1) * N + k] -= g;
        if (cn) A[(cn - 1) * N + k] += g;
    }
    if (el->kind == E_CV || el->kind == E_XF) { /* v(a) - v(b) - g v(probe) = 0 */
        if (a) A[k * N + a - 1] += 1.0;
        if (b) A[k * N + b - 1] -= 1.0;
    } else { /* an op-amp: v(probe) = 0 */
        g = -1.0;
    }
    if (cp) A[k * N + cp - 1] -= g;
    if (cn) A[k * N + cn - 1] += g;
}

/* A current j flowing from a through an element to b, moved to the
 * right-hand side. */
static void stamp_j(real *rhs, int a, int b, real j) {
    if (a)
        rhs[a - 1] -= j;
    if (b)
        rhs[b - 1] += j;
}

/* Nodes no element touches get v = 0. */
static void pin_unused(const Circuit *c, real *A, int N) {
    for (int k = 1; k < c->nnodes; k++) {
        int used = 0;
        for (int e = 0; e < c->nelems && !used; e++)
            if (!self_loop(&c->elems[e]) &&
                (c->elems[e].n[0] == k || c->elems[e].n[1] == k))
                used = 1;
        if (!used)
            A[(k - 1) * N + (k - 1)] = 1.0;
    }
}

/* ---- the step system ---- */

static void update_values(refsim *s) {
    const Circuit *c = s->c;
    for (int e = 0; e < c->nelems; e++) {
        const Elem *el = &c->elems[e];
        if (is_nl(el)) {
            const NlSpec *nl = el->nl;
            real *q = s->nlp + 4 * e;
            s->val[e] = 0.0;
            if (nl->kind == NL_DIODE) {
                q[0] = expr_eval(nl->Is, s->params);
                q[1] = (real)expr_eval(nl->n, s->params) *
                       (real)expr_eval(nl->Vt, s->params);
            } else if (nl->kind == NL_CONTACT) {
                /* a compressed contact does not gain energy from a change:
                 * a stiffer felt is compressed less, a smaller gap keeps
                 * the compression (the voice's rule) */
                real k0 = q[0], g0 = q[3], X = s->cx ? s->cx[e] - g0 : 0;
                real kn = expr_eval(nl->k, s->params), gn = expr_eval(nl->gap, s->params);
                if (k0 > 0 && X > 0 && kn > k0)
                    s->cx[e] = g0 + X * powl(k0 / kn, 1 / (q[1] + 1)), X = s->cx[e] - g0;
                if (k0 > 0 && X > 0 && gn < g0)
                    s->cx[e] += gn - g0;
                q[0] = expr_eval(nl->k, s->params);
                q[1] = expr_eval(nl->alpha, s->params);
                q[2] = expr_eval(nl->lambda, s->params);
                q[3] = expr_eval(nl->gap, s->params);
            }
            continue;
        }
        int v = el->kind == E_R || el->kind == E_C || el->kind == E_L ||
                has_value(el);
        real old = s->val[e];
        s->val[e] = v ? elem_value(c, el, s->params) : 0.0;
        /* a reactance that grows keeps its charge or flux, one that shrinks
         * its voltage or current: a change never adds energy */
        if (old > 0 && s->val[e] > old && s->v && s->i) {
            if (el->kind == E_C)
                s->v[e] *= old / s->val[e];
            else if (el->kind == E_L)
                s->i[e] *= old / s->val[e];
        }
        if ((el->kind == E_V || el->kind == E_I) && el->input < 0)
            s->cdrv[e] = elem_drive(c, el, s->params);
    }
}

/* ---- nonlinear elements ---- */

/* Sum of the .ic x() values given for graph node `node`. */
static real ic_x(const refsim *s, int node) {
    real x = 0.0;
    if (node == 0)
        return 0.0;
    for (int j = 0; j < s->c->nics; j++)
        if (s->c->ics[j].fn == 'x' && s->c->ics[j].node == node)
            x += expr_eval(s->c->ics[j].val, s->params);
    return x;
}

/* Elastic force k C^alpha of contact e at compression C (0 if C <= 0). */
static real contact_elastic(const refsim *s, int e, real C) {
    const real *q = s->nlp + 4 * e;
    return C > 0.0 ? q[0] * powl(C, q[1]) : 0.0;
}

/* The law y = f(x) of a diode or curve (its i(v) as a resistor), and its
 * slope. */
static real law(const refsim *s, int e, real x, real *dy) {
    const NlSpec *nl = s->c->elems[e].nl;
    const real *q = s->nlp + 4 * e;
    *dy = 0.0;
    if (nl->kind == NL_DIODE) {
        real u = x / q[1];
        if (nl->pair) {
            *dy = 2.0 * q[0] * coshl(u) / q[1];
            return 2.0 * q[0] * sinhl(u);
        }
        *dy = q[0] * expl(u) / q[1];
        return q[0] * expm1l(u);
    }
    int n = nl->npts, k = 0;
    if (n < 2)
        return n == 1 ? (real)nl->ci[0] : 0.0;
    while (k + 2 < n && x >= (real)nl->cv[k + 1])
        k++;
    real x0 = nl->cv[k], x1 = nl->cv[k + 1];
    real y0 = nl->ci[k], y1 = nl->ci[k + 1];
    *dy = (y1 - y0) / (x1 - x0);
    /* from the nearer end: near a point of the curve (the origin, where
     * a network comes to rest) the value keeps its digits */
    return fabsl(x - x0) <= fabsl(x - x1) ? y0 + (x - x0) * *dy : y1 + (x - x1) * *dy;
}

/* The integral of the law from 0 to x. */
static real law_integral(const refsim *s, int e, real x) {
    const NlSpec *nl = s->c->elems[e].nl;
    const real *q = s->nlp + 4 * e;
    if (nl->kind == NL_DIODE) {
        real u = x / q[1];
        return nl->pair ? 2.0 * q[0] * q[1] * (coshl(u) - 1.0)
                        : q[0] * (q[1] * expm1l(u) - x);
    }
    /* trapezoids between 0, the points strictly between 0 and x, and x:
     * exact for a piecewise-linear law */
    real acc = 0.0, t = 0.0, d, yt = law(s, e, 0.0, &d);
    int n = nl->npts;
    for (int j = 0; j < n; j++) {
        int k = x > 0 ? j : n - 1 - j;
        real u = nl->cv[k];
        if (!(x > 0 ? u > 0.0 && u < x : u < 0.0 && u > x))
            continue;
        real yu = law(s, e, u, &d);
        acc += 0.5 * (u - t) * (yt + yu);
        t = u;
        yt = yu;
    }
    return acc + 0.5 * (x - t) * (yt + law(s, e, x, &d));
}

/* Elastic force (current) of contact or nonlinear inductor e at u, its
 * compression (contact) or flux, and its slope. */
static real elastic(const refsim *s, int e, real u, real *dF) {
    if (!is_contact(&s->c->elems[e]))
        return law(s, e, u, dF);
    const real *q = s->nlp + 4 * e;
    *dF = 0.0;
    if (!(u > 0.0))
        return 0.0;
    real p = q[0] * powl(u, q[1]);
    *dF = q[1] * p / u;
    return p;
}

/* Energy stored at u: the elastic force integrated from 0. */
static real stored(const refsim *s, int e, real u) {
    if (!is_contact(&s->c->elems[e]))
        return law_integral(s, e, u);
    const real *q = s->nlp + 4 * e;
    return u > 0.0 ? q[0] * powl(u, q[1] + 1.0) / (q[1] + 1.0) : 0.0;
}

/* Whether the elastic law has a corner strictly inside (u0, u1) or at
 * either end: the contact's 0, a curve's points. */
static int corner_between(const refsim *s, int e, real u0, real u1) {
    real lo = fminl(u0, u1), hi = fmaxl(u0, u1);
    const NlSpec *nl = s->c->elems[e].nl;
    if (nl->kind == NL_CONTACT)
        return lo <= 0.0 && hi >= 0.0;
    for (int j = 0; nl->kind == NL_CURVE && j < nl->npts; j++)
        if ((real)nl->cv[j] >= lo && (real)nl->cv[j] <= hi)
            return 1;
    return 0;
}

/* Mean of the elastic force over [u0, u1]: the stored energy's difference
 * over the distance or, where the ends lie within 1e-6 of their size
 * with no corner between, three-point Gauss-Legendre (exact to degree
 * five, so far below rounding there). */
static real elastic_mean(const refsim *s, int e, real u0, real u1) {
    real w = u1 - u0, d;
    if (w == 0.0)
        return elastic(s, e, u0, &d);
    if (fabsl(w) > 1e-6L * fmaxl(fabsl(u0), fabsl(u1)) || corner_between(s, e, u0, u1))
        return (stored(s, e, u1) - stored(s, e, u0)) / w;
    real m = 0.5L * (u0 + u1), r = 0.5L * w * sqrtl(0.6L);
    return (5.0L * elastic(s, e, m - r, &d) + 8.0L * elastic(s, e, m, &d) +
            5.0L * elastic(s, e, m + r, &d)) / 18.0L;
}

/* Current of a contact or nonlinear inductor e at voltage v, and its
 * slope.  Its coordinate u (compression or flux) moves by
 * du = T/2 (v + v[n-1]); over the step it gives the network the energy
 * du (i + i[n-1]) / 2 and stores stored(u1) - stored(u0) = du M.  The
 * average current aims at (i[n-1] + phi) / 2, phi the elastic law at u1
 * (a contact's times 1 + lambda v while that is positive), and is held
 * within [M, M + du / (T R)] for du > 0 and [M + du / (T R), M] for
 * du < 0, R = Rp[e]: passive, continuous and rising in v. */
static real flux_eval(const refsim *s, int e, real v, real *g) {
    const NlSpec *nl = s->c->elems[e].nl;
    const real *q = s->nlp + 4 * e;
    real h = 0.5 * s->T, ip = s->i[e], dF;
    real u0 = s->cx[e] - (nl->kind == NL_CONTACT ? q[3] : 0.0);
    real du = h * (v + s->v[e]), u1 = u0 + du;
    real F1 = elastic(s, e, u1, &dF), phi = F1, dphi = dF * h;
    if (nl->kind == NL_CONTACT) {
        real m = 1.0 + q[2] * v;
        phi = m > 0.0 ? F1 * m : 0.0;
        dphi = m > 0.0 ? dF * h * m + F1 * q[2] : 0.0;
    }
    real M = elastic_mean(s, e, u0, u1), dM = du != 0.0 ? (F1 - M) / du * h : 0.5 * dF * h;
    real kap = 1.0 / (s->T * s->Rp[e]);
    real lo = du < 0.0 ? M + kap * du : M, hi = du > 0.0 ? M + kap * du : M;
    real avg = 0.5 * (ip + phi), davg = 0.5 * dphi;
    if (avg < lo) {
        avg = lo;
        davg = dM + (du < 0.0 ? kap * h : 0.0);
    } else if (avg > hi) {
        avg = hi;
        davg = dM + (du > 0.0 ? kap * h : 0.0);
    }
    *g = 2.0 * davg;
    return 2.0 * avg - ip;
}

/* Nonlinear capacitor e (R-C mutator): its charge is law(u), u the
 * voltage of its law, which moves from u0 = cx[e] to u1 over the step.
 * It takes dq (v[n-1] + v) / 2 from the network, dq = law(u1) - law(u0),
 * and stores dq M, M the mean over the charge of the law's voltage; the
 * step's average voltage aims at (v[n-1] + u1) / 2 and is held within
 * [M, M + far] while u rises, [M + far, M] while it falls, far the
 * larger in size of dq R / T and (u1 - u0) / 2 (the dual of flux_eval;
 * M = u1 where the charge does not move).  Returns the voltage across
 * it, v = 2 vbar - v[n-1], and its slope in u1. */
static real cap_volt(const refsim *s, int e, real u1, real *dv) {
    real u0 = s->cx[e], d0, d1, q0 = law(s, e, u0, &d0), q1 = law(s, e, u1, &d1), dq = q1 - q0;
    real M = u1, dM = 0.5;
    if (dq != 0.0) {
        if (fabsl(u1 - u0) > 1e-6L * fmaxl(fabsl(u0), fabsl(u1)) || corner_between(s, e, u0, u1)) {
            /* E(q) = u law(u) - its integral */
            M = (u1 * q1 - law_integral(s, e, u1) - u0 * q0 + law_integral(s, e, u0)) / dq;
        } else { /* by parts, the law's mean by three-point Gauss-Legendre */
            real m = 0.5L * (u0 + u1), r = 0.5L * (u1 - u0) * sqrtl(0.6L), d;
            real mean = (5.0L * law(s, e, m - r, &d) + 8.0L * law(s, e, m, &d) + 5.0L * law(s, e, m + r, &d)) / 18.0L;
            M = u1 - (u1 - u0) * (mean - q0) / dq;
        }
        dM = (u1 - M) / dq * d1;
    }
    /* the far end of the hold: M + dq R / T or M + (u1 - u0) / 2,
     * whichever lies farther from M */
    real k = s->Rp[e] / s->T, vbar = 0.5 * (s->v[e] + u1), dvbar = 0.5, w = u1 - u0;
    real far = fabsl(k * dq) >= fabsl(0.5L * w) ? k * dq : 0.5L * w;
    real dfar = fabsl(k * dq) >= fabsl(0.5L * w) ? k * d1 : 0.5L;
    real lo = w < 0.0 ? M + far : M, hi = w > 0.0 ? M + far : M;
    if (vbar < lo) {
        vbar = lo;
        dvbar = dM + (w < 0.0 ? dfar : 0.0);
    } else if (vbar > hi) {
        vbar = hi;
        dvbar = dM + (w > 0.0 ? dfar : 0.0);
    }
    *dv = 2.0 * dvbar;
    return 2.0 * vbar - s->v[e];
}

/* The u1 whose cap_volt is v.  cap_volt rises with u1, and away from
 * its hold u1 = v gives v, so: a bracket doubled outward from v in steps
 * of the scale of v, u0 and v[n-1], then Newton kept inside it until a
 * step is below 4 ulps of u1 (or the bracket's ends meet). */
static real cap_law_voltage(const refsim *s, int e, real v) {
    real dv, u0 = s->cx[e], step = fabsl(v - u0) + fabsl(v - s->v[e]) + LDBL_EPSILON * fabsl(v) + 1e-300L;
    real lo = v, hi = v, f = cap_volt(s, e, v, &dv) - v;
    if (f == 0.0)
        return v;
    for (int k = 0; k < 300; k++, step *= 2.0L) {
        if (f > 0.0) {
            lo = hi - step;
            if (cap_volt(s, e, lo, &dv) - v <= 0.0)
                break;
            hi = lo;
        } else {
            hi = lo + step;
            if (cap_volt(s, e, hi, &dv) - v >= 0.0)
                break;
            lo = hi;
        }
    }
    real u = 0.5L * (lo + hi);
    for (int it = 0; it < 200; it++) {
        f = cap_volt(s, e, u, &dv) - v;
        if (f == 0.0)
            break;
        if (f > 0.0)
            hi = u;
        else
            lo = u;
        real un = u - f / dv;
        if (!(un > lo && un < hi))
            un = 0.5L * (lo + hi);
        if (fabsl(un - u) <= 4.0L * LDBL_EPSILON * fabsl(u) || !(lo < un && un < hi))
            return un; /* converged, or the bracket is down to adjacent numbers */
        u = un;
    }
    return u;
}

/* The current of nonlinear capacitor e at voltage v and its slope:
 * i = 2 dq / T - i[n-1] at the u1 that gives v. */
static real cap_eval(const refsim *s, int e, real v, real *g) {
    real dv, d0, d1, u = cap_law_voltage(s, e, v);
    real dq = law(s, e, u, &d1) - law(s, e, s->cx[e], &d0);
    cap_volt(s, e, u, &dv);
    *g = d1 / (0.5 * s->T) / dv;
    return dq / (0.5 * s->T) - s->i[e];
}

/* Current of nonlinear element e at voltage v in the sample being
 * solved, and its slope di/dv in *g.  A contact's compression and a
 * nonlinear inductor's flux (behind an R-L mutator) are their integrals
 * at the last sample advanced by the trapezoidal rule to v (flux_eval).
 * Behind an R-C mutator the law f of the diode or curve gives the charge
 * q = f(v), with i the trapezoidal derivative of q. */
static real nl_eval(const refsim *s, int e, real v, real *g) {
    const NlSpec *nl = s->c->elems[e].nl;
    *g = 0.0;
    if (has_flux(&s->c->elems[e]))
        return flux_eval(s, e, v, g);
    if (nl->mutated == 'C')
        return cap_eval(s, e, v, g);
    switch (nl->kind) {
    case NL_DIODE:
    case NL_CURVE:
        return law(s, e, v, g);
    case NL_CONTACT: /* has_flux */
        break;
    }
    return 0.0;
}

static real nl_rest_current(const refsim *s, int e) {
    const Elem *el = &s->c->elems[e];
    real d;
    if (is_contact(el))
        return contact_elastic(s, e, s->cx[e] - s->nlp[4 * e + 3]);
    if (el->nl->mutated == 'L')
        return law(s, e, s->cx[e], &d);
    return 0.0;
}

/* Newton's residual of the step system at x: r = G x - rhs plus the
 * currents of the nonlinear elements, and with J != NULL its Jacobian. */
static void nl_residual(refsim *s, const real *x, const real *rhs, real *r,
                        real *J) {
    const Circuit *c = s->c;
    int N = s->N;
    for (int k = 0; k < N; k++) {
        real acc = -rhs[k];
        const real *row = s->G + (size_t)k * (size_t)N;
        for (int j = 0; j < N; j++)
            acc += row[j] * x[j];
        r[k] = acc;
    }
    if (J)
        memcpy(J, s->G, sizeof(real) * (size_t)N * (size_t)N);
    for (int e = 0; e < c->nelems; e++) {
        const Elem *el = &c->elems[e];
        if (!is_nl(el) || self_loop(el))
            continue;
        int a = el->n[0], b = el->n[1];
        real v = (a ? x[a - 1] : 0.0) - (b ? x[b - 1] : 0.0), g;
        real i = nl_eval(s, e, v, &g);
        if (a)
            r[a - 1] += i;
        if (b)
            r[b - 1] -= i;
        if (J)
            stamp_g(J, N, a, b, g);
    }
    for (int e = 0; e < c->nelems; e++) { /* a transistor's sources: gain times a junction's current */
        const Elem *el = &c->elems[e], *d = el->kind == E_CC ? &c->elems[el->peer] : NULL;
        if (!d || self_loop(el))
            continue;
        int a = d->n[0], b = d->n[1], p = el->n[0], q = el->n[1];
        real v = (a ? x[a - 1] : 0.0) - (b ? x[b - 1] : 0.0), g;
        real i = s->val[e] * nl_eval(s, el->peer, v, &g);
        g *= s->val[e];
        if (p)
            r[p - 1] += i;
        if (q)
            r[q - 1] -= i;
        if (!J)
            continue;
        if (p && a) J[(p - 1) * N + a - 1] += g;
        if (p && b) J[(p - 1) * N + b - 1] -= g;
        if (q && a) J[(q - 1) * N + a - 1] -= g;
        if (q && b) J[(q - 1) * N + b - 1] += g;
    }
}

static real sumsq(const real *r, int n) {
    real f = 0.0;
    for (int k = 0; k < n; k++)
        f += r[k] * r[k];
    return isfinite(f) ? f : INFINITY;
}

#define NL_TOL 1e-13L    /* converged: every |dx| below this times its scale */
#define NL_MAXIT 200     /* Newton iterations per sample at most */
#define NL_HALVINGS 60   /* halvings of a step that raises the residual */

/* Solves the step system with its nonlinear elements by damped Newton,
 * starting from the last sample's solution; rhs (the step's right-hand
 * side) is replaced by the solution, as lu_solve does for linear ones.
 * A Newton step whose residual is larger than the present one is halved
 * until it is not; the iteration stops once the full step is below
 * NL_TOL relative to the largest node voltage (for node unknowns) or to
 * the larger of the largest branch current and the current the largest
 * conductance of the network drives at that voltage (branch unknowns:
 * a branch current that is the small difference of large ones is known
 * only to that).  Behind a controlled source of gain A, whose row
 * amplifies rounding A times, the bound is 64 A ulps where that is
 * coarser. */
static void nl_solve(refsim *s, real *rhs) {
    const Circuit *c = s->c;
    int N = s->N, nn = s->nn;
    real *x = s->x, *dx = s->dx, *xt = s->xt, *r = s->r, *rt = s->rt;
    for (int k = 1; k < c->nnodes; k++)
        x[k - 1] = s->nodev[k];
    for (int e = 0; e < c->nelems; e++)
        if (s->br[e] >= 0)
            x[s->br[e]] = s->i[e];
    nl_residual(s, x, rhs, r, s->J);
    real f0 = sumsq(r, N);
    int it, converged = 0;
    for (it = 0; it < NL_MAXIT && !converged; it++) {
        if (lu_factor(s->J, s->piv, N) != 0)
            die("refsim: singular Newton matrix at sample %ld", s->t);
        for (int k = 0; k < N; k++)
            dx[k] = -r[k];
        lu_solve(s->J, s->piv, N, dx);
        real sn = 0.0, sb = 0.0;
        for (int k = 0; k < N; k++) {
            real m = fmaxl(fabsl(x[k]), fabsl(x[k] + dx[k]));
            if (k < nn)
                sn = fmaxl(sn, m);
            else
                sb = fmaxl(sb, m);
        }
        converged = 1;
        for (int k = 0; k < N && converged; k++) {
            real sc = fmaxl(k < nn ? sn : fmaxl(sb, sn * s->gscale), 1e-300L);
            if (!(fabsl(dx[k]) <= s->ntol * sc))
                converged = 0;
        }
        real lam = 1.0;
        int ok = converged;
        for (int h = 0; h <= NL_HALVINGS && !ok; h++) {
            for (int k = 0; k < N; k++)
                xt[k] = x[k] + lam * dx[k];
            nl_residual(s, xt, rhs, rt, NULL);
            if (sumsq(rt, N) <= f0)
                ok = 1;
            else
                lam *= 0.5;
        }
        if (!ok) {
            lam = 1.0;
            s->nl_forced++;
        }
        for (int k = 0; k < N; k++)
            x[k] += lam * dx[k];
        nl_residual(s, x, rhs, r, s->J);
        f0 = sumsq(r, N);
    }
    s->nl_iters += it;
    if (it > s->nl_maxit)
        s->nl_maxit = it;
    if (!converged)
        s->nl_unconverged++;
    memcpy(rhs, x, sizeof(real) * (size_t)N);
}

/* The resistance between the nodes of each contact, nonlinear inductor
 * and nonlinear capacitor that the linear step network presents (the other nonlinear
 * elements open): the voltage a unit current into it makes.  Their
 * passive law (nl_eval) limits how fast the force may return to the
 * elastic law by it. */
static void port_resistances(refsim *s) {
    const Circuit *c = s->c;
    int N = s->N;
    for (int e = 0; e < c->nelems; e++) {
        const Elem *el = &c->elems[e];
        if (!(has_flux(el) || is_nlcap(el)) || self_loop(el))
            continue;
        memcpy(s->J, s->G, sizeof(real) * (size_t)N * (size_t)N);
        memset(s->dx, 0, sizeof(real) * (size_t)N);
        int a = el->n[0], b = el->n[1];
        if (a)
            s->dx[a - 1] = 1.0;
        if (b)
            s->dx[b - 1] = -1.0;
        if (lu_factor(s->J, s->piv, N) != 0)
            die("refsim: %s: no resistance at its port", el->name);
        lu_solve(s->J, s->piv, N, s->dx);
        s->Rp[e] = (a ? s->dx[a - 1] : 0.0) - (b ? s->dx[b - 1] : 0.0);
    }
}

static void build_step_matrix(refsim *s) {
    const Circuit *c = s->c;
    int N = s->N;
    real *A = s->A;
    memset(A, 0, sizeof(real) * (size_t)N * (size_t)N);
    for (int e = 0; e < c->nelems; e++) {
        const Elem *el = &c->elems[e];
        int a = el->n[0], b = el->n[1];
        real x = s->val[e];
        if (self_loop(el))
            continue;
        switch (el->kind) {
        case E_R:
            stamp_g(A, N, a, b, 1.0 / x);
            break;
        case E_C:
            stamp_g(A, N, a, b, 2.0 * x / s->T);
            break;
        case E_L: {
            int k = s->br[e];
            stamp_branch(A, N, a, b, k);
            A[k * N + k] -= 2.0 * x / s->T;
            break;
        }
        default: /* nonlinear elements enter through nl_residual */
            break;
        case E_V: {
            int k = s->br[e];
            stamp_branch(A, N, a, b, k);
            A[k * N + k] -= x;
            break;
        }
        case E_I:
            if (has_value(el))
                stamp_g(A, N, a, b, 1.0 / x);
            break;
        case E_CV: case E_CI: case E_OA: case E_XF:
            stamp_ctl(c, A, N, e, s->br[e], x);
            break;
        }
    }
    pin_unused(c, A, N);
    if (s->nnl) {
        /* Newton works on the unfactored matrix (nl_solve), which alone
         * may be singular (a node joined to the rest by diodes only). */
        memcpy(s->G, A, sizeof(real) * (size_t)N * (size_t)N);
        s->gscale = 0.0;
        for (int r = 0; r < s->nn; r++)
            for (int k = 0; k < s->nn; k++)
                s->gscale = fmaxl(s->gscale, fabsl(A[r * N + k]));
        /* a controlled source of gain A amplifies rounding A times: the
         * solution is resolved to about A ulps, no better */
        s->ntol = NL_TOL;
        for (int e = 0; e < c->nelems; e++)
            if (c->elems[e].kind == E_CV)
                s->ntol = fmaxl(s->ntol, 64 * LDBL_EPSILON * fabsl(s->val[e]));
        if (s->round_state)
            for (size_t k = 0; k < (size_t)N * (size_t)N; k++)
                s->G[k] = rd(s->G[k]);
        port_resistances(s);
        s->dirty = 0;
        return;
    }
    /* Solvability was checked structurally in refsim_new; a zero pivot
     * here can only come from values that cancel exactly. */
    if (lu_factor(A, s->piv, N) != 0)
        die("refsim: singular step matrix");
    if (s->round_state)
        for (size_t k = 0; k < (size_t)N * (size_t)N; k++)
            A[k] = rd(A[k]);
    s->dirty = 0;
}

static real drive_of(const refsim *s, int e, const double *in) {
    const Elem *el = &s->c->elems[e];
    real d = el->input >= 0 ? (in ? in[el->input] : 0.0) : s->cdrv[e];
    return s->round_state ? rd(d) : d;
}

/* ---- sample -1 ---- */

/* The resistive network of sample -1: capacitors as voltage sources
 * (branch unknowns br0[e]), inductors as current sources, sources at
 * their drive (0 when input-driven).  Fills the N x N matrix A and the
 * right-hand side x. */
static void build_init_system(const refsim *s, const int *br0, int N,
                              real *A, real *x) {
    const Circuit *c = s->c;
    memset(A, 0, sizeof(real) * (size_t)N * (size_t)N);
    memset(x, 0, sizeof(real) * (size_t)N);
    for (int e = 0; e < c->nelems; e++) {
        const Elem *el = &c->elems[e];
        int a = el->n[0], b = el->n[1];
        real val = s->val[e];
        real ic = el->ic ? expr_eval(el->ic, s->params) : 0.0;
        real d = el->input >= 0 ? 0.0 : s->cdrv[e];
        if (self_loop(el))
            continue;
        switch (el->kind) {
        case E_R:
            stamp_g(A, N, a, b, 1.0 / val);
            break;
        case E_C:
            stamp_branch(A, N, a, b, br0[e]);
            x[br0[e]] = ic;
            break;
        case E_L:
            stamp_j(x, a, b, ic);
            break;
        case E_V:
            stamp_branch(A, N, a, b, br0[e]);
            A[br0[e] * N + br0[e]] -= val;
            x[br0[e]] = d;
            break;
        case E_I:
            if (has_value(el))
                stamp_g(A, N, a, b, 1.0 / val);
            stamp_j(x, a, b, d);
            break;
        case E_NL:
            /* diodes and curves open; a contact pushes with its elastic
             * force at its initial compression */
            stamp_j(x, a, b, nl_rest_current(s, e));
            break;
        case E_CV: case E_CI: case E_OA: case E_XF:
            stamp_ctl(c, A, N, e, br0[e], val);
            break;
        default:
            break;
        }
    }
    pin_unused(c, A, N);
}

static void initial_state(refsim *s) {
    const Circuit *c = s->c;
    int ne = c->nelems;
    int *vedge = calloc((size_t)ne + 1, sizeof(int));
    int *iedge = calloc((size_t)ne + 1, sizeof(int));
    int *br0 = malloc(sizeof(int) * ((size_t)ne + 1));
    if (!vedge || !iedge || !br0)
        die("refsim: out of memory");
    int N = s->nn;
    for (int e = 0; e < ne; e++) {
        const Elem *el = &c->elems[e];
        br0[e] = -1;
        if ((el->kind == E_C || el->kind == E_V || ELEM_VOUT(el->kind)) && !self_loop(el))
            br0[e] = N++;
        vedge[e] = el->kind == E_C || (el->kind == E_V && !has_value(el)) || ELEM_VOUT(el->kind);
        iedge[e] = el->kind == E_L || (el->kind == E_I && !has_value(el)) ||
                   is_nl(el) || el->kind == E_CI || el->kind == E_P || el->kind == E_CC;
        if (has_flux(el))
            s->cx[e] = ic_x(s, el->n[0]) - ic_x(s, el->n[1]);
    }
    s->singular0 = !solvable(c, vedge, iedge);

    real *A = calloc((size_t)N * (size_t)N + 1, sizeof(real));
    real *x = calloc((size_t)N + 1, sizeof(real));
    int *piv = malloc(sizeof(int) * ((size_t)N + 1));
    if (!A || !x || !piv)
        die("refsim: out of memory");
    build_init_system(s, br0, N, A, x);
    if (!s->singular0 && lu_factor(A, piv, N) != 0)
        s->singular0 = 1;
    if (!s->singular0)
        lu_solve(A, piv, N, x);
    else
        memset(x, 0, sizeof(real) * (size_t)N);

    s->nodev[0] = 0.0;
    for (int k = 1; k < c->nnodes; k++)
        s->nodev[k] = x[k - 1];
    for (int e = 0; e < ne; e++) {
        const Elem *el = &c->elems[e];
        real ic = el->ic ? expr_eval(el->ic, s->params) : 0.0;
        real vv = self_loop(el) ? 0.0 : s->nodev[el->n[0]] - s->nodev[el->n[1]];
        s->d[e] = 0.0;
        switch (el->kind) {
        case E_R:
            s->v[e] = vv;
            s->i[e] = vv / s->val[e];
            break;
        case E_C:
            s->v[e] = ic;
            s->i[e] = s->singular0 || br0[e] < 0 ? 0.0 : x[br0[e]];
            break;
        case E_L:
            s->i[e] = ic;
            s->v[e] = s->singular0 ? 0.0 : vv;
            break;
        case E_V:
            s->d[e] = el->input >= 0 ? 0.0 : s->cdrv[e];
            s->v[e] = vv;
            if (s->singular0 && has_value(el))
                s->i[e] = (vv - s->d[e]) / s->val[e];
            else
                s->i[e] = br0[e] < 0 ? 0.0 : x[br0[e]];
            break;
        case E_I:
            s->d[e] = el->input >= 0 ? 0.0 : s->cdrv[e];
            s->v[e] = vv;
            s->i[e] = s->d[e] + (has_value(el) ? vv / s->val[e] : 0.0);
            break;
        case E_NL:
            s->v[e] = vv;
            s->i[e] = nl_rest_current(s, e);
            if (is_nlcap(el))
                s->cx[e] = vv; /* charged to the voltage across it */
            break;
        default:
            break;
        }
    }
    for (int k = 0; k < c->nouts; k++) {
        const Probe *p = &c->outs[k];
        s->px[k] = 0.0;
        s->pv[k] = 0.0;
        if (p->kind != PR_X)
            continue;
        s->pv[k] = s->nodev[p->n[0]] - s->nodev[p->n[1]];
        for (int j = 0; j < c->nics; j++) {
            const IcSpec *ic = &c->ics[j];
            if (ic->fn != 'x')
                continue;
            real xv = expr_eval(ic->val, s->params);
            if (ic->node == p->n[0] && ic->node != 0)
                s->px[k] += xv;
            if (ic->node == p->n[1] && ic->node != 0)
                s->px[k] -= xv;
        }
    }
    free(A);
    free(x);
    free(piv);
    free(vedge);
    free(iedge);
    free(br0);
}

/* ---- public ---- */

int refsim_linear_kind(int kind) {
    return kind == E_R || kind == E_C || kind == E_L || kind == E_V || kind == E_I || kind == E_CV || kind == E_CI ||
           kind == E_OA || kind == E_P || kind == E_CC || kind == E_XF;
}

int refsim_can_simulate(const Circuit *c) {
    for (int e = 0; e < c->nelems; e++)
        if (!refsim_linear_kind((int)c->elems[e].kind) && !is_nl(&c->elems[e]))
            return 0;
    return 1;
}

int refsim_is_linear(const Circuit *c) {
    for (int e = 0; e < c->nelems; e++)
        if (!refsim_linear_kind((int)c->elems[e].kind))
            return 0;
    return 1;
}

refsim *refsim_new(const Circuit *c, double fs, const double *params) {
    refsim *s = calloc(1, sizeof *s);
    if (!s)
        return NULL;
    int ne = c->nelems;
    size_t nes = (size_t)ne + 1, nos = (size_t)c->nouts + 1;
    s->c = c;
    s->fs = fs;
    s->T = 1.0L / fs;
    s->nn = c->nnodes - 1;
    s->br = malloc(sizeof(int) * nes);
    s->params = calloc((size_t)c->nparams + 1, sizeof(double));
    s->val = calloc(nes, sizeof(real));
    s->cdrv = calloc(nes, sizeof(real));
    s->v = calloc(nes, sizeof(real));
    s->i = calloc(nes, sizeof(real));
    s->d = calloc(nes, sizeof(real));
    s->nodev = calloc((size_t)c->nnodes + 1, sizeof(real));
    s->px = calloc(nos, sizeof(real));
    s->pv = calloc(nos, sizeof(real));
    s->nlp = calloc(4 * nes, sizeof(real));
    s->cx = calloc(nes, sizeof(real));
    s->Rp = calloc(nes, sizeof(real));
    if (!s->br || !s->params || !s->val || !s->cdrv || !s->v || !s->i ||
        !s->d || !s->nodev || !s->px || !s->pv || !s->nlp || !s->cx) {
        refsim_free(s);
        return NULL;
    }
    for (int k = 0; k < c->nparams; k++)
        s->params[k] = params ? params[k] : c->params[k].def;
    if (!refsim_can_simulate(c)) {
        refsim_free(s);
        return NULL;
    }

    int N = s->nn;
    int *vedge = calloc(nes, sizeof(int)), *iedge = calloc(nes, sizeof(int));
    if (!vedge || !iedge) {
        free(vedge);
        free(iedge);
        refsim_free(s);
        return NULL;
    }
    for (int e = 0; e < ne; e++) {
        const Elem *el = &c->elems[e];
        s->br[e] = -1;
        if ((el->kind == E_L || el->kind == E_V || ELEM_VOUT(el->kind)) && !self_loop(el))
            s->br[e] = N++;
        vedge[e] = (el->kind == E_V && !has_value(el)) || ELEM_VOUT(el->kind);
        iedge[e] = (el->kind == E_I && !has_value(el)) || nl_open_edge(el) || el->kind == E_CI || el->kind == E_P ||
                   el->kind == E_CC;
        if (is_nl(el))
            s->nnl++;
    }
    int ok = solvable(c, vedge, iedge);
    free(vedge);
    free(iedge);
    s->N = N;
    s->A = calloc((size_t)N * (size_t)N + 1, sizeof(real));
    s->piv = malloc(sizeof(int) * ((size_t)N + 1));
    s->rhs = calloc((size_t)N + 1, sizeof(real));
    if (s->nnl) {
        size_t nsq = (size_t)N * (size_t)N + 1, n1 = (size_t)N + 1;
        s->G = calloc(nsq, sizeof(real));
        s->J = calloc(nsq, sizeof(real));
        s->x = calloc(n1, sizeof(real));
        s->dx = calloc(n1, sizeof(real));
        s->xt = calloc(n1, sizeof(real));
        s->r = calloc(n1, sizeof(real));
        s->rt = calloc(n1, sizeof(real));
        if (!s->G || !s->J || !s->x || !s->dx || !s->xt || !s->r || !s->rt)
            ok = 0;
    }
    if (!ok || !s->A || !s->piv || !s->rhs) {
        refsim_free(s);
        return NULL;
    }
    update_values(s);
    initial_state(s);
    build_step_matrix(s);
    return s;
}

void refsim_start_at(refsim *s, const double *nodev, const double *cur) {
    const Circuit *c = s->c;
    if (s->dirty) { /* the values the operating point was found with */
        update_values(s);
        build_step_matrix(s);
    }
    s->nodev[0] = 0.0;
    for (int k = 1; k < c->nnodes; k++)
        s->nodev[k] = nodev[k];
    for (int e = 0; e < c->nelems; e++) {
        const Elem *el = &c->elems[e];
        real vv = self_loop(el) ? 0.0 : s->nodev[el->n[0]] - s->nodev[el->n[1]];
        real g = has_value(el) ? s->val[e] : 0.0;
        switch (el->kind) {
        case E_R:
            s->v[e] = vv;
            s->i[e] = vv / s->val[e];
            break;
        case E_C:
            s->v[e] = vv;
            s->i[e] = 0.0;
            break;
        case E_L:
            s->v[e] = 0.0;
            s->i[e] = cur[e];
            break;
        case E_V:
            s->v[e] = vv;
            s->i[e] = cur[e];
            s->d[e] = el->input >= 0 ? vv - g * s->i[e] : s->cdrv[e];
            break;
        case E_I:
            s->v[e] = vv;
            if (el->input >= 0) {
                s->i[e] = cur[e];
                s->d[e] = s->i[e] - (g != 0.0 ? vv / g : 0.0);
            } else {
                s->d[e] = s->cdrv[e];
                s->i[e] = s->d[e] + (g != 0.0 ? vv / g : 0.0);
            }
            break;
        case E_NL:
            s->v[e] = vv;
            s->i[e] = cur[e];
            if (is_nlcap(el))
                s->cx[e] = vv; /* charged to the voltage across it */
            break;
        case E_CI: {
            const Elem *pr = &c->elems[el->peer];
            s->v[e] = vv;
            s->i[e] = s->val[e] * (s->nodev[pr->n[0]] - s->nodev[pr->n[1]]);
            break;
        }
        case E_P: /* a transformer's reference winding draws current */
            s->v[e] = vv;
            s->i[e] = cur[e];
            break;
        case E_CV: case E_OA: case E_CC: case E_XF:
            s->v[e] = vv;
            s->i[e] = cur[e];
            break;
        default:
            break;
        }
    }
    for (int k = 0; k < c->nouts; k++)
        if (c->outs[k].kind == PR_X)
            s->pv[k] = s->nodev[c->outs[k].n[0]] - s->nodev[c->outs[k].n[1]];
    if (s->round_state) {
        for (int k = 1; k < c->nnodes; k++)
            s->nodev[k] = rd(s->nodev[k]);
        for (int e = 0; e < c->nelems; e++) {
            s->v[e] = rd(s->v[e]);
            s->i[e] = rd(s->i[e]);
            s->d[e] = rd(s->d[e]);
            s->cx[e] = rd(s->cx[e]);
        }
        for (int k = 0; k < c->nouts; k++)
            s->pv[k] = rd(s->pv[k]);
    }
    s->work = 0.0;
    s->singular0 = 0;
}

void refsim_set_param(refsim *s, int id, double v) {
    if (id < 0 || id >= s->c->nparams)
        return;
    const Param *p = &s->c->params[id];
    if (v < p->min)
        v = p->min;
    if (v > p->max)
        v = p->max;
    if (s->params[id] != v) {
        s->params[id] = v;
        s->dirty = 1;
    }
}

double refsim_get_param(const refsim *s, int id) {
    if (id < 0 || id >= s->c->nparams)
        return 0.0;
    return s->params[id];
}

void refsim_step(refsim *s, const double *in, double *out) {
    const Circuit *c = s->c;
    int N = s->N;
    real *rhs = s->rhs;
    if (s->dirty) {
        update_values(s);
        build_step_matrix(s);
    }
    memset(rhs, 0, sizeof(real) * (size_t)N);
    for (int e = 0; e < c->nelems; e++) {
        const Elem *el = &c->elems[e];
        int a = el->n[0], b = el->n[1];
        if (self_loop(el))
            continue;
        switch (el->kind) {
        case E_R:
            break;
        case E_C: {
            real g = 2.0 * s->val[e] / s->T;
            stamp_j(rhs, a, b, -(g * s->v[e] + s->i[e]));
            break;
        }
        default: /* a contact's history enters through nl_eval */
            break;
        case E_L: {
            real z = 2.0 * s->val[e] / s->T;
            rhs[s->br[e]] = -z * s->i[e] - s->v[e];
            break;
        }
        case E_V:
            rhs[s->br[e]] = drive_of(s, e, in);
            break;
        case E_I:
            stamp_j(rhs, a, b, drive_of(s, e, in));
            break;
        }
    }
    if (s->nnl)
        nl_solve(s, rhs);
    else
        lu_solve(s->A, s->piv, N, rhs);
    for (int k = 1; k < c->nnodes; k++)
        s->nodev[k] = rhs[k - 1];

    real pw = 0.0;
    for (int e = 0; e < c->nelems; e++) {
        const Elem *el = &c->elems[e];
        real vv = self_loop(el) ? 0.0 : s->nodev[el->n[0]] - s->nodev[el->n[1]];
        real pv = s->v[e], pi = s->i[e];
        switch (el->kind) {
        case E_R:
            s->v[e] = vv;
            s->i[e] = vv / s->val[e];
            break;
        case E_C: {
            real g = 2.0 * s->val[e] / s->T;
            s->v[e] = vv;
            s->i[e] = self_loop(el) ? 0.0 : g * (vv - pv) - pi;
            break;
        }
        case E_L:
            s->v[e] = vv;
            if (!self_loop(el))
                s->i[e] = rhs[s->br[e]];
            break;
        case E_V: {
            real dn = drive_of(s, e, in);
            s->v[e] = vv;
            s->i[e] = self_loop(el) ? 0.0 : rhs[s->br[e]];
            pw -= 0.25 * (dn + s->d[e]) * (s->i[e] + pi);
            s->d[e] = dn;
            break;
        }
        case E_I: {
            real dn = drive_of(s, e, in);
            s->v[e] = vv;
            s->i[e] = dn + (has_value(el) ? vv / s->val[e] : 0.0);
            pw -= 0.25 * (vv + pv) * (dn + s->d[e]);
            s->d[e] = dn;
            break;
        }
        case E_CV: case E_CI: case E_OA: case E_CC: { /* the work it does, as a source's */
            const Elem *pr = &c->elems[el->peer];
            real vp = s->nodev[pr->n[0]] - s->nodev[pr->n[1]], g;
            s->v[e] = vv;
            s->i[e] = el->kind == E_CI   ? s->val[e] * vp
                      : el->kind == E_CC ? s->val[e] * nl_eval(s, el->peer, vp, &g)
                      : self_loop(el)    ? 0.0
                                         : rhs[s->br[e]];
            pw -= 0.25 * (vv + pv) * (s->i[e] + pi);
            break;
        }
        case E_XF: /* what a winding supplies its reference winding absorbs */
            s->v[e] = vv;
            s->i[e] = self_loop(el) ? 0.0 : rhs[s->br[e]];
            break;
        case E_NL: {
            real g, ii = self_loop(el) ? 0.0 : nl_eval(s, e, vv, &g);
            if (has_flux(el))
                s->cx[e] += 0.5 * s->T * (vv + pv);
            if (is_nlcap(el) && !self_loop(el))
                s->cx[e] = cap_law_voltage(s, e, vv);
            s->v[e] = vv;
            s->i[e] = ii;
            break;
        }
        default:
            break;
        }
    }
    s->work += s->T * pw;
    if (s->round_state) {
        for (int k = 1; k < c->nnodes; k++)
            s->nodev[k] = rd(s->nodev[k]);
        for (int e = 0; e < c->nelems; e++) {
            s->v[e] = rd(s->v[e]);
            s->i[e] = rd(s->i[e]);
            s->cx[e] = rd(s->cx[e]);
        }
        s->work = rd(s->work);
    }

    for (int k = 0; k < c->nouts; k++) {
        const Probe *p = &c->outs[k];
        real o = 0.0;
        switch (p->kind) {
        case PR_V:
            o = s->nodev[p->n[0]] - s->nodev[p->n[1]];
            break;
        case PR_I:
        case PR_F:
            o = p->elem < 0 ? 0.0 : s->i[p->elem]; /* -1: a resistor that led nowhere */
            break;
        case PR_X: {
            real vv = s->nodev[p->n[0]] - s->nodev[p->n[1]];
            s->px[k] += 0.5 * s->T * (vv + s->pv[k]);
            if (s->round_state)
                s->px[k] = rd(s->px[k]);
            s->pv[k] = vv;
            o = s->px[k];
            break;
        }
        }
        if (out)
            out[k] = (double)o;
    }
    s->t++;
}

double refsim_energy(const refsim *s) {
    real E = 0.0;
    for (int e = 0; e < s->c->nelems; e++) {
        const Elem *el = &s->c->elems[e];
        if (el->kind == E_C)
            E += 0.5 * s->val[e] * s->v[e] * s->v[e];
        else if (el->kind == E_L)
            E += 0.5 * s->val[e] * s->i[e] * s->i[e];
        else if (is_contact(el)) {
            const real *q = s->nlp + 4 * e;
            real C = s->cx[e] - q[3];
            if (C > 0.0)
                E += q[0] * powl(C, q[1] + 1.0) / (q[1] + 1.0);
        } else if (is_nl(el) && el->nl->mutated == 'L') {
            E += law_integral(s, e, s->cx[e]);
        } else if (is_nlcap(el)) {
            real d, v = s->cx[e];
            E += v * law(s, e, v, &d) - law_integral(s, e, v);
        }
    }
    return (double)E;
}

void refsim_nl_stats(const refsim *s, refsim_nl_info *info) {
    info->steps = s->nnl ? s->t : 0;
    info->iters = s->nl_iters;
    info->maxit = s->nl_maxit;
    info->unconverged = s->nl_unconverged;
    info->forced = s->nl_forced;
}

double refsim_work(const refsim *s) { return (double)s->work; }

long refsim_time(const refsim *s) { return s->t; }

double refsim_elem_v(const refsim *s, int e) { return (double)s->v[e]; }

double refsim_elem_i(const refsim *s, int e) { return (double)s->i[e]; }

double refsim_node_v(const refsim *s, int node) { return (double)s->nodev[node]; }

int refsim_init_singular(const refsim *s) { return s->singular0; }

void refsim_round_state(refsim *s, int bits) {
    s->round_state = bits == 32 ? 32 : bits ? 64 : 0;
    s->dirty = 1;
}

void refsim_free(refsim *s) {
    if (!s)
        return;
    free(s->br);
    free(s->params);
    free(s->val);
    free(s->cdrv);
    free(s->A);
    free(s->piv);
    free(s->rhs);
    free(s->nodev);
    free(s->v);
    free(s->i);
    free(s->d);
    free(s->px);
    free(s->pv);
    free(s->nlp);
    free(s->cx);
    free(s->Rp);
    free(s->G);
    free(s->J);
    free(s->x);
    free(s->dx);
    free(s->xt);
    free(s->r);
    free(s->rt);
    free(s);
}
