/* scatter.c: scattering matrices of the adaptors, solved with LAPACKE, and
 * their losslessness.  This is the only file that includes lapacke.h. */
#include <lapacke.h>
#include <float.h>
#include <math.h>
#include <string.h>

#include "gen.h"

/* The core's nodal matrix (plus one row and column per ideal V source):
 * ports and nonlinear edges stamp their conductance 1/R, edge `skip` is
 * left out. */
static double *core_matrix(const Root *r, const double *R, int skip, int *dim) {
    int nc = r->ncore, D = nc + r->nv;
    double *A = arena_alloc(sizeof(double) * (size_t)(D * D));
    int m = 0;
    for (int k = 0; k < r->nedge; k++) {
        const RootEdge *e = &r->edge[k];
        int p = e->p, q = e->q;
        if (e->kind == 1) {
            int row = nc + m++;
            if (p >= 0) { A[p * D + row] += 1; A[row * D + p] += 1; }
            if (q >= 0) { A[q * D + row] -= 1; A[row * D + q] -= 1; }
        } else if ((e->kind == 0 || e->kind == 3) && k != skip) {
            double G = 1 / R[k];
            if (p >= 0) A[p * D + p] += G;
            if (q >= 0) A[q * D + q] += G;
            if (p >= 0 && q >= 0) { A[p * D + q] -= G; A[q * D + p] -= G; }
        }
    }
    *dim = D;
    return A;
}

/* LU solve with a singularity test relative to the largest entry. */
static int solve(double *A, int D, double *B, int nrhs) {
    double amax = 0;
    for (int i = 0; i < D * D; i++)
        amax = fmax(amax, fabs(A[i]));
    int *piv = arena_alloc(sizeof(int) * (size_t)D);
    if (LAPACKE_dgesv(LAPACK_ROW_MAJOR, D, nrhs, A, D, piv, B, nrhs) != 0)
        return -1;
    for (int i = 0; i < D; i++)
        if (fabs(A[i * D + i]) < 1e-13 * fmax(amax, 1))
            return -1;
    return 0;
}

int scatter_thevenin(const Root *r, const double *R, int k, double *Rth) {
    int D;
    double *A = core_matrix(r, R, k, &D);
    double *B = arena_alloc(sizeof(double) * (size_t)D);
    const RootEdge *e = &r->edge[k];
    if (e->p >= 0) B[e->p] = 1;
    if (e->q >= 0) B[e->q] = -1;
    if (solve(A, D, B, 1) < 0)
        return -1;
    *Rth = (e->p >= 0 ? B[e->p] : 0) - (e->q >= 0 ? B[e->q] : 0);
    return 0;
}

int scatter_root(const Root *r, const double *R, double *M) {
    int nc = r->ncore, ne = r->nedge, D;
    if (nc + r->nv == 0)
        die("root without core nodes");
    double *A = core_matrix(r, R, -1, &D);
    double *B = arena_alloc(sizeof(double) * (size_t)(D * ne));
#define BT(i, j) B[(i) * ne + (j)]
    int m = 0;
    for (int k = 0; k < ne; k++) {
        const RootEdge *e = &r->edge[k];
        int p = e->p, q = e->q;
        if (e->kind == 0 || e->kind == 3) {
            double G = 1 / R[k];
            if (p >= 0) BT(p, k) += G;
            if (q >= 0) BT(q, k) -= G;
        } else if (e->kind == 1) {
            BT(nc + m++, k) = 1;
        } else {
            if (p >= 0) BT(p, k) -= 1;
            if (q >= 0) BT(q, k) += 1;
        }
    }
    if (solve(A, D, B, ne) < 0)
        return -1;
    m = 0;
    for (int k = 0; k < ne; k++) {
        const RootEdge *e = &r->edge[k];
        for (int j = 0; j < ne; j++) {
            double vp = e->p >= 0 ? BT(e->p, j) : 0, vq = e->q >= 0 ? BT(e->q, j) : 0;
            double out;
            if (e->kind == 0 || e->kind == 3)
                out = 2 * (vp - vq) - (j == k);
            else if (e->kind == 1)
                out = BT(nc + m, j);
            else
                out = vp - vq;
            M[k * ne + j] = out;
        }
        if (e->kind == 1)
            m++;
    }
#undef BT
    return 0;
}

void scatter_node(const WNode *n, double *S) {
    int np = n->nchild + 1;
    double R[np];
    int s[np];
    R[0] = n->R;
    s[0] = 1;
    for (int i = 0; i < n->nchild; i++) {
        R[i + 1] = n->child[i]->R;
        s[i + 1] = n->pol[i];
    }
    double tot = 0;
    for (int i = 0; i < np; i++)
        tot += n->kind == W_SERIES ? R[i] : 1 / R[i];
    for (int k = 0; k < np; k++)
        for (int j = 0; j < np; j++) {
            double d = k == j;
            S[k * np + j] = n->kind == W_SERIES ? d - 2 * s[k] * s[j] * R[k] / tot
                                                : 2 * s[k] * s[j] / R[j] / tot - d;
        }
}

/* max |S^T G S - G|_ij / sqrt(G_i G_j) for an n-port with port
 * resistances R: unchanged by scaling all resistances, and an error at a
 * small conductance is not hidden by a large one. */
static double lossless_err(const double *S, const double *R, int n) {
    double err = 0;
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++) {
            double acc = 0;
            for (int k = 0; k < n; k++)
                acc += S[k * n + i] * S[k * n + j] / R[k];
            err = fmax(err, fabs(acc - (i == j) / R[i]) * sqrt(R[i] * R[j]));
        }
    return err;
}

static double root_check(const Root *r, double tol);

double scatter_check(const Wdf *w, double tol) {
    double worst = 0;
    for (int i = 0; i < w->nnodes; i++) {
        const WNode *n = w->nodes[i];
        if (n->kind == W_LEAF)
            continue;
        int np = n->nchild + 1;
        double *S = arena_alloc(sizeof(double) * (size_t)(np * np));
        double *R = arena_alloc(sizeof(double) * (size_t)np);
        scatter_node(n, S);
        R[0] = n->R;
        for (int k = 0; k < n->nchild; k++)
            R[k + 1] = n->child[k]->R;
        double err = lossless_err(S, R, np);
        if (err > tol)
            die("%s adaptor %d is not lossless (error %g)", n->kind == W_SERIES ? "series" : "parallel",
                n->id, err);
        if (fabs(S[0]) > tol)
            die("%s adaptor %d is not adapted at its up port (S00 = %g)",
                n->kind == W_SERIES ? "series" : "parallel", n->id, S[0]);
        worst = fmax(worst, err);
    }
    for (int b = 0; b < w->nroots; b++)
        worst = fmax(worst, root_check(&w->roots[b], tol));
    return worst;
}

static double root_check(const Root *r, double tol) {
    int np = r->nport + r->nnl, ne = r->nedge;
    double *S = arena_alloc(sizeof(double) * (size_t)(np * np + 1));
    for (int k = 0; k < np; k++)
        for (int j = 0; j < np; j++)
            S[k * np + j] = r->M[k * ne + j];
    double err = lossless_err(S, r->R, np), lo = INFINITY, hi = 0;
    for (int k = 0; k < np; k++)
        lo = fmin(lo, r->R[k]), hi = fmax(hi, r->R[k]);
    /* the nodal solve loses digits with the spread of port resistances */
    if (err > fmax(tol, 64 * DBL_EPSILON * hi / lo))
        die("root adaptor is not lossless (error %g)", err);
    for (int k = r->nport; k < np; k++)
        if (fabs(S[k * np + k]) > tol)
            die("nonlinear edge %d of the root is not adapted (S = %g)", k, S[k * np + k]);
    return err;
}
