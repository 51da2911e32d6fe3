/* refsim.c - trapezoidal-rule nodal simulation of a Circuit (see refsim.h). */
#include "refsim.h"

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
        int v = el->kind == E_R || el->kind == E_C || el->kind == E_L ||
                has_value(el);
        s->val[e] = v ? elem_value(c, el, s->params) : 0.0;
        if ((el->kind == E_V || el->kind == E_I) && el->input < 0)
            s->cdrv[e] = elem_drive(c, el, s->params);
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
        default: /* not linear: refused by refsim_new */
            break;
        }
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
        }
    }
    pin_unused(c, A, N);
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
        default: /* not linear: refused by refsim_new */
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
        if ((el->kind == E_C || el->kind == E_V) && !self_loop(el))
            br0[e] = N++;
        vedge[e] = el->kind == E_C || (el->kind == E_V && !has_value(el));
        iedge[e] = el->kind == E_L || (el->kind == E_I && !has_value(el));
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
        default: /* not linear: refused by refsim_new */
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
    return kind == E_R || kind == E_C || kind == E_L || kind == E_V || kind == E_I;
}

int refsim_can_simulate(const Circuit *c) {
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
    if (!s->br || !s->params || !s->val || !s->cdrv || !s->v || !s->i ||
        !s->d || !s->nodev || !s->px || !s->pv) {
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
        if ((el->kind == E_L || el->kind == E_V) && !self_loop(el))
            s->br[e] = N++;
        vedge[e] = el->kind == E_V && !has_value(el);
        iedge[e] = el->kind == E_I && !has_value(el);
    }
    int ok = solvable(c, vedge, iedge);
    free(vedge);
    free(iedge);
    s->N = N;
    s->A = calloc((size_t)N * (size_t)N + 1, sizeof(real));
    s->piv = malloc(sizeof(int) * ((size_t)N + 1));
    s->rhs = calloc((size_t)N + 1, sizeof(real));
    if (!ok || !s->A || !s->piv || !s->rhs) {
        refsim_free(s);
        return NULL;
    }
    update_values(s);
    initial_state(s);
    build_step_matrix(s);
    return s;
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
        default: /* not linear: refused by refsim_new */
            break;
        }
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
        default: /* not linear: refused by refsim_new */
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
        }
    }
    s->work += s->T * pw;
    if (s->round_state) {
        for (int k = 1; k < c->nnodes; k++)
            s->nodev[k] = rd(s->nodev[k]);
        for (int e = 0; e < c->nelems; e++) {
            s->v[e] = rd(s->v[e]);
            s->i[e] = rd(s->i[e]);
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
            o = s->i[p->elem];
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
    }
    return (double)E;
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
    free(s);
}
