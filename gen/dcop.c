/* dcop.c: a deck's DC operating point with its nonlinear elements and
 * controlled sources, found when the voice is compiled.
 *
 * Modified nodal analysis over the whole circuit: capacitors open,
 * inductors shorted, every source at its DC drive; a branch current
 * unknown for each voltage source, inductor, controlled voltage source,
 * op-amp and transformer winding.  An inductor's short keeps L_DC_R
 * ohms per henry, so that inductors in a loop (in parallel, or a
 * transformer's winding beside another's) share a DC current as they
 * would when it rose from rest, inversely to their inductance, instead of
 * leaving it undetermined.  Diodes (and pairs) follow their law with SPICE's GMIN
 * (1e-12 S) across them, curves their points (their end segments
 * extended), a transistor's controlled sources gain times their
 * junction's current.  Damped Newton: a junction asked to move far into
 * conduction moves by the log of it (SPICE's limiting), a step that does
 * not lower the residual is halved; the sources are raised from 0 to
 * their values in stages (source stepping) when the full values do not
 * converge from rest.  Bounded: at most DC_MAXN unknowns (a dense solve
 * each step) and DC_BUDGET Newton iterations in all. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "gen.h"

#define DC_GMIN 1e-12
#define DC_MAXIT 200     /* Newton iterations at one source scale */
#define DC_BUDGET 2000   /* and over all of them */
#define DC_MAXN 160      /* unknowns: a dense solve of more would be slow */
#define L_DC_R 1e-6      /* ohm per henry: 1 A through 10 mH drops 10 nV */

typedef struct Dc {
    const Circuit *c;
    const double *params, *drive;
    int nn, N;     /* node unknowns (ground excluded), all unknowns */
    int *br;       /* element -> its branch unknown, or -1 */
    double *A, *F, *x, *dx, *xt;
    double scale;  /* the sources' share, 0..1 */
    int iters;     /* Newton iterations so far */
} Dc;

/* Current from n0 to n1 of nonlinear element e at voltage v, its slope in *g. */
static double nl_current(const Dc *d, const Elem *e, double v, double *g) {
    const NlSpec *nl = e->nl;
    if (nl->kind == NL_CURVE) {
        int k = 0;
        while (k < nl->npts - 2 && v > nl->cv[k + 1])
            k++;
        *g = (nl->ci[k + 1] - nl->ci[k]) / (nl->cv[k + 1] - nl->cv[k]);
        return nl->ci[k] + *g * (v - nl->cv[k]);
    }
    double Is = expr_eval(nl->Is, d->params), nvt = expr_eval(nl->n, d->params) * expr_eval(nl->Vt, d->params);
    double u = fmin(v / nvt, 700);
    if (nl->pair) {
        *g = 2 * Is / nvt * cosh(u) + DC_GMIN;
        return 2 * Is * sinh(u) + DC_GMIN * v;
    }
    *g = Is / nvt * exp(u) + DC_GMIN;
    return Is * expm1(u) + DC_GMIN * v;
}

static double node_v(const double *x, int n) { return n ? x[n - 1] : 0; }

static void add(Dc *d, int r, int col, double v) {
    if (r >= 0 && col >= 0)
        d->A[r * d->N + col] += v;
}

/* F(x) and its Jacobian A. */
static void eval(Dc *d, const double *x) {
    const Circuit *c = d->c;
    int N = d->N;
    memset(d->A, 0, sizeof(double) * (size_t)(N * N));
    memset(d->F, 0, sizeof(double) * (size_t)N);
    for (int i = 0; i < c->nelems; i++) {
        const Elem *e = &c->elems[i];
        int a = e->n[0] - 1, b = e->n[1] - 1, k = d->br[i];
        double va = node_v(x, e->n[0]), vb = node_v(x, e->n[1]);
        double val = e->val ? expr_eval(e->val, d->params) : 0, s = d->scale * d->drive[i];
        switch (e->kind) {
        case E_R: {
            double g = 1 / val, i0 = g * (va - vb);
            if (a >= 0) d->F[a] += i0;
            if (b >= 0) d->F[b] -= i0;
            add(d, a, a, g), add(d, a, b, -g), add(d, b, a, -g), add(d, b, b, g);
            break;
        }
        case E_I: { /* drive from n0 through it to n1, R in parallel */
            double g = e->val ? 1 / val : 0, i0 = s + g * (va - vb);
            if (a >= 0) d->F[a] += i0;
            if (b >= 0) d->F[b] -= i0;
            add(d, a, a, g), add(d, a, b, -g), add(d, b, a, -g), add(d, b, b, g);
            break;
        }
        case E_V: case E_L: case E_CV: case E_OA: case E_XF: { /* branch current k from n0 through it to n1 */
            if (a >= 0) d->F[a] += x[k];
            if (b >= 0) d->F[b] -= x[k];
            add(d, a, k, 1), add(d, b, k, -1);
            if (e->kind == E_OA) { /* holds its probe at 0 */
                const Elem *p = &c->elems[e->peer];
                d->F[k] = node_v(x, p->n[0]) - node_v(x, p->n[1]);
                add(d, k, p->n[0] - 1, 1), add(d, k, p->n[1] - 1, -1);
                break;
            }
            d->F[k] = va - vb;
            add(d, k, a, 1), add(d, k, b, -1);
            if (e->kind == E_V) { /* v = drive + R i */
                d->F[k] -= s + (e->val ? val * x[k] : 0);
                add(d, k, k, e->val ? -val : 0);
            } else if (e->kind == E_L) { /* a short, but for L_DC_R L */
                d->F[k] -= L_DC_R * val * x[k];
                add(d, k, k, -L_DC_R * val);
            } else if (e->kind == E_CV || e->kind == E_XF) {
                const Elem *p = &c->elems[e->peer];
                int pa = p->n[0] - 1, pb = p->n[1] - 1;
                d->F[k] -= val * (node_v(x, p->n[0]) - node_v(x, p->n[1]));
                add(d, k, pa, -val), add(d, k, pb, val);
                if (e->kind == E_XF) { /* the reference winding draws -val x[k] */
                    if (pa >= 0) d->F[pa] -= val * x[k];
                    if (pb >= 0) d->F[pb] += val * x[k];
                    add(d, pa, k, -val), add(d, pb, k, val);
                }
            }
            break;
        }
        case E_CI: case E_CC: { /* gain times v(probe) or i(junction), n0 through it to n1 */
            const Elem *p = &c->elems[e->peer];
            double vp = node_v(x, p->n[0]) - node_v(x, p->n[1]), g = 1, i0 = vp;
            if (e->kind == E_CC)
                i0 = nl_current(d, p, vp, &g);
            i0 *= val, g *= val;
            if (a >= 0) d->F[a] += i0;
            if (b >= 0) d->F[b] -= i0;
            add(d, a, p->n[0] - 1, g), add(d, a, p->n[1] - 1, -g);
            add(d, b, p->n[0] - 1, -g), add(d, b, p->n[1] - 1, g);
            break;
        }
        case E_NL: {
            double g, i0 = nl_current(d, e, va - vb, &g);
            if (a >= 0) d->F[a] += i0;
            if (b >= 0) d->F[b] -= i0;
            add(d, a, a, g), add(d, a, b, -g), add(d, b, a, -g), add(d, b, b, g);
            break;
        }
        default: /* capacitors open; probes carry nothing */
            break;
        }
    }
}

static double norm2(const double *v, int n) {
    double s = 0;
    for (int i = 0; i < n; i++)
        s += v[i] * v[i];
    return isfinite(s) ? s : INFINITY;
}

/* The largest share of step dx that keeps every junction within SPICE's
 * limit: one asked to move far past its critical voltage moves by the log
 * of what it is asked. */
static double limit(const Dc *d) {
    const Circuit *c = d->c;
    double lim = 1;
    for (int i = 0; i < c->nelems; i++) {
        const Elem *e = &c->elems[i];
        if (e->kind != E_NL || e->nl->kind != NL_DIODE)
            continue;
        double v = node_v(d->x, e->n[0]) - node_v(d->x, e->n[1]);
        double dv = node_v(d->dx, e->n[0]) - node_v(d->dx, e->n[1]);
        if (e->nl->pair && v + dv < 0)
            v = -v, dv = -dv;
        double Is = expr_eval(e->nl->Is, d->params), nvt = expr_eval(e->nl->n, d->params) * expr_eval(e->nl->Vt, d->params);
        double vn = v + dv, vcrit = nvt * log(nvt / (sqrt(2) * Is));
        if (!(vn > vcrit && dv > 2 * nvt))
            continue;
        double to = v > 0 ? v + nvt * log1p(dv / nvt) : nvt * log(vn / nvt);
        lim = fmin(lim, (to - v) / dv);
    }
    return lim > 0 ? lim : 1;
}

/* Newton at the present source scale from d->x; true if it converged. */
static bool newton(Dc *d) {
    int N = d->N;
    eval(d, d->x);
    double f0 = norm2(d->F, N);
    for (int it = 0; it < DC_MAXIT && d->iters++ < DC_BUDGET; it++) {
        for (int i = 0; i < N; i++)
            d->dx[i] = -d->F[i];
        if (scatter_dense_solve(d->A, N, d->dx) < 0)
            return false;
        bool small = true;
        for (int i = 0; i < N; i++)
            small &= fabs(d->dx[i]) <= 1e-12 * fabs(d->x[i]) + (i < d->nn ? 1e-12 : 1e-15);
        if (small)
            return true;
        double lam = limit(d);
        for (int h = 0; h < 40; h++, lam *= 0.5) {
            for (int i = 0; i < N; i++)
                d->xt[i] = d->x[i] + lam * d->dx[i];
            eval(d, d->xt);
            if (norm2(d->F, N) <= f0 || h == 39)
                break;
        }
        memcpy(d->x, d->xt, sizeof(double) * (size_t)N);
        f0 = norm2(d->F, N);
        if (!isfinite(f0))
            return false;
    }
    return false;
}

bool dcop_solve(const Circuit *c, const double *params, const double *drive, double *nodev, double *cur) {
    Dc d = {.c = c, .params = params, .drive = drive, .nn = c->nnodes - 1};
    d.br = arena_alloc(sizeof(int) * (size_t)(c->nelems + 1));
    int N = d.nn;
    for (int i = 0; i < c->nelems; i++) {
        ElemKind k = c->elems[i].kind;
        if (k == E_W || k == E_S || (k == E_NL && (c->elems[i].nl->kind == NL_CONTACT || c->elems[i].nl->mutated)))
            return false; /* lines, waveguides and stored laws: not this solve's */
        d.br[i] = k == E_V || k == E_L || ELEM_VOUT(k) ? N++ : -1;
    }
    d.N = N;
    if (N > DC_MAXN)
        return false;
    d.A = arena_alloc(sizeof(double) * (size_t)(N * N + 1));
    d.F = arena_alloc(sizeof(double) * (size_t)(N + 1));
    d.x = arena_alloc(sizeof(double) * (size_t)(N + 1));
    d.dx = arena_alloc(sizeof(double) * (size_t)(N + 1));
    d.xt = arena_alloc(sizeof(double) * (size_t)(N + 1));
    d.scale = 1;
    bool ok = newton(&d);
    /* source stepping: from rest, the sources raised in stages, a stage
     * halved where Newton does not converge */
    double at = 0, step = 0.125;
    if (!ok)
        memset(d.x, 0, sizeof(double) * (size_t)N);
    double *good = arena_alloc(sizeof(double) * (size_t)(N + 1));
    while (!ok && step > 1e-4 && d.iters < DC_BUDGET) {
        memcpy(good, d.x, sizeof(double) * (size_t)N);
        d.scale = fmin(1, at + step);
        if (newton(&d)) {
            at = d.scale;
            ok = at >= 1;
            step *= 1.5;
        } else {
            memcpy(d.x, good, sizeof(double) * (size_t)N);
            step *= 0.25;
        }
    }
    if (!ok)
        return false;
    nodev[0] = 0;
    for (int n = 1; n < c->nnodes; n++)
        nodev[n] = d.x[n - 1];
    for (int i = 0; i < c->nelems; i++) {
        const Elem *e = &c->elems[i];
        double g, vp;
        cur[i] = 0;
        if (d.br[i] >= 0)
            cur[i] = d.x[d.br[i]];
        else if (e->kind == E_NL)
            cur[i] = nl_current(&d, e, nodev[e->n[0]] - nodev[e->n[1]], &g);
        else if (e->kind == E_CC) {
            const Elem *p = &c->elems[e->peer];
            vp = nodev[p->n[0]] - nodev[p->n[1]];
            cur[i] = expr_eval(e->val, params) * nl_current(&d, p, vp, &g);
        } else if (e->kind == E_P && c->elems[e->peer].kind == E_XF) /* what the reference winding draws */
            cur[i] = -expr_eval(c->elems[e->peer].val, params) * d.x[d.br[e->peer]];
    }
    return true;
}

double *dcop_drives(const Circuit *c, const double *params) {
    double *drive = arena_alloc(sizeof(double) * (size_t)(c->nelems + 1));
    for (int i = 0; i < c->nelems; i++) {
        const Elem *e = &c->elems[i];
        if (e->kind != E_V && e->kind != E_I)
            continue;
        if (e->input < 0)
            drive[i] = elem_drive(c, e, params);
        else if (c->input_fn[e->input])
            drive[i] = srcfn_at(c->input_fn[e->input], 0, 1 / c->rate);
    }
    return drive;
}
