/* scatter.c: scattering matrices of the adaptors, solved with LAPACKE, and
 * their losslessness.  This is the only file that includes lapacke.h. */
#include <lapacke.h>
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "gen.h"

/* The core's nodal matrix, plus a row and column per controlled voltage
 * output and per ideal V source: ports and nonlinear edges stamp their
 * conductance 1/R, edge `skip` is left out; controlled sources stamp
 * their gains. */
static double *core_matrix(const Root *r, const double *R, int skip, int *dim) {
    int nc = r->ncore, D = nc + r->nx + r->nv;
    double *A = arena_alloc(sizeof(double) * (size_t)(D * D));
    int m = 0;
    for (int k = 0, x = nc; k < r->nctl; k++) {
        const struct RootCtl *c = &r->ctl[k];
        int p = c->p, q = c->q, cp = c->cp, cn = c->cn;
        if (c->kind == E_CI || c->kind == E_CC) { /* g v(probe) leaves p, enters q */
            /* a junction's current is (v - b) / R at its edge: gain / R on
             * its voltage here, its wave b in the inputs (scatter_root);
             * none when the edge is the one left out */
            double g = c->kind == E_CI ? c->gain : c->ce == skip ? 0 : c->gain / R[c->ce];
            if (p >= 0 && cp >= 0) A[p * D + cp] += g;
            if (p >= 0 && cn >= 0) A[p * D + cn] -= g;
            if (q >= 0 && cp >= 0) A[q * D + cp] -= g;
            if (q >= 0 && cn >= 0) A[q * D + cn] += g;
            continue;
        }
        /* its current x leaves p, enters q; its row: v(p) - v(q) - gain
         * v(probe) = 0, or an op-amp's v(probe) = 0 */
        if (p >= 0) A[p * D + x] += 1;
        if (q >= 0) A[q * D + x] -= 1;
        double g = c->kind == E_OA ? -1 : c->gain;
        if (c->kind != E_OA && p >= 0) A[x * D + p] += 1;
        if (c->kind != E_OA && q >= 0) A[x * D + q] -= 1;
        if (cp >= 0) A[x * D + cp] -= g;
        if (cn >= 0) A[x * D + cn] += g;
        /* a transformer's reference winding draws -gain times its current */
        if (c->kind == E_XF && cp >= 0) A[cp * D + x] -= g;
        if (c->kind == E_XF && cn >= 0) A[cn * D + x] += g;
        x++;
    }
    for (int k = 0; k < r->nedge; k++) {
        const RootEdge *e = &r->edge[k];
        int p = e->p, q = e->q;
        if (e->kind == EDGE_V) {
            int row = nc + r->nx + m++;
            if (p >= 0) { A[p * D + row] += 1; A[row * D + p] += 1; }
            if (q >= 0) { A[q * D + row] -= 1; A[row * D + q] -= 1; }
        } else if ((e->kind == EDGE_PORT || e->kind == EDGE_NL) && k != skip) {
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

int scatter_dense_solve(double *A, int n, double *b) { return solve(A, n, b, 1); }

int scatter_thevenin(const Root *r, const double *R, int k, double *Rth) {
    int D;
    double *A = core_matrix(r, R, k, &D);
    double *B = arena_alloc(sizeof(double) * (size_t)D);
    const RootEdge *e = &r->edge[k];
    if (e->p >= 0) B[e->p] = 1;
    if (e->q >= 0) B[e->q] = -1;
    /* the unit current flows through edge k from q to p: a source that
     * takes gain times its current sends -gain from its p to its q */
    for (int j = 0; j < r->nctl; j++)
        if (r->ctl[j].kind == E_CC && r->ctl[j].ce == k) {
            if (r->ctl[j].p >= 0) B[r->ctl[j].p] += r->ctl[j].gain;
            if (r->ctl[j].q >= 0) B[r->ctl[j].q] -= r->ctl[j].gain;
        }
    if (solve(A, D, B, 1) < 0)
        return -1;
    *Rth = (e->p >= 0 ? B[e->p] : 0) - (e->q >= 0 ? B[e->q] : 0);
    return 0;
}

int scatter_root(const Root *r, const double *R, double *M) {
    int nc = r->ncore, ne = r->nedge, D;
    if (nc + r->nx + r->nv == 0)
        die("root without core nodes");
    double *A = core_matrix(r, R, -1, &D);
    double *B = arena_alloc(sizeof(double) * (size_t)(D * ne));
#define BT(i, j) B[(i) * ne + (j)]
    int m = 0;
    for (int k = 0; k < ne; k++) {
        const RootEdge *e = &r->edge[k];
        int p = e->p, q = e->q;
        if (e->kind == EDGE_PORT || e->kind == EDGE_NL) {
            double G = 1 / R[k];
            if (p >= 0) BT(p, k) += G;
            if (q >= 0) BT(q, k) -= G;
        } else if (e->kind == EDGE_V) {
            BT(nc + r->nx + m++, k) = 1;
        } else {
            if (p >= 0) BT(p, k) -= 1;
            if (q >= 0) BT(q, k) += 1;
        }
    }
    for (int j = 0; j < r->nctl; j++) { /* a junction's wave in the current its source takes */
        const struct RootCtl *c = &r->ctl[j];
        if (c->kind != E_CC)
            continue;
        if (c->p >= 0) BT(c->p, c->ce) += c->gain / R[c->ce];
        if (c->q >= 0) BT(c->q, c->ce) -= c->gain / R[c->ce];
    }
    if (solve(A, D, B, ne) < 0)
        return -1;
    m = 0;
    for (int k = 0; k < ne; k++) {
        const RootEdge *e = &r->edge[k];
        for (int j = 0; j < ne; j++) {
            double vp = e->p >= 0 ? BT(e->p, j) : 0, vq = e->q >= 0 ? BT(e->q, j) : 0;
            double out;
            if (e->kind == EDGE_PORT || e->kind == EDGE_NL)
                out = 2 * (vp - vq) - (j == k);
            else if (e->kind == EDGE_V)
                out = BT(nc + r->nx + m, j);
            else
                out = vp - vq;
            M[k * ne + j] = out;
        }
        if (e->kind == EDGE_V)
            m++;
    }
#undef BT
    return 0;
}

/* A series or parallel adaptor's scattering matrix is a rank-one change
 * of a reflection, S = sigma I + u v^T (ports: up port first, then the
 * children; s_k their polarities, s_0 = 1):
 *   series:   S_kj = d_kj - 2 s_k s_j R_k / sum R:  sigma = 1,  u_k = -2 s_k R_k / sum R,  v_j = s_j
 *   parallel: S_kj = 2 s_k s_j G_j / sum G - d_kj:  sigma = -1, u_k = 2 s_k / sum G,  v_j = s_j G_j
 * with G = 1/R.  Sets u, v and R (n->nchild + 1 each) and returns sigma. */
static double node_factors(const WNode *n, double *u, double *v, double *R) {
    int np = n->nchild + 1;
    bool series = n->kind == W_SERIES;
    R[0] = n->R;
    for (int i = 0; i < n->nchild; i++)
        R[i + 1] = n->child[i]->R;
    double tot = 0;
    for (int i = 0; i < np; i++)
        tot += series ? R[i] : 1 / R[i];
    for (int k = 0; k < np; k++) {
        double s = k ? n->pol[k - 1] : 1;
        u[k] = series ? -2 * s * R[k] / tot : 2 * s / tot;
        v[k] = series ? s : s / R[k];
    }
    return series ? 1 : -1;
}

void scatter_node(const WNode *n, double *S) {
    int np = n->nchild + 1;
    double *u = arena_alloc(sizeof(double) * 3 * (size_t)np), *v = u + np, *R = v + np;
    double sigma = node_factors(n, u, v, R);
    for (int k = 0; k < np; k++)
        for (int j = 0; j < np; j++)
            S[k * np + j] = (k == j ? sigma : 0) + u[k] * v[j];
}

/* max |S^T G S - G|_ij / sqrt(G_i G_j) for an n-port with port
 * resistances R: unchanged by scaling all resistances, and an error at a
 * small conductance is not hidden by a large one.  S^T G S is symmetric:
 * its upper triangle is summed row of S by row of S, so that every pass
 * reads memory in order. */
static double lossless_err(const double *S, const double *R, int n) {
    double *A = arena_alloc(sizeof(double) * (size_t)n * (size_t)n); /* S^T G S */
    for (int k = 0; k < n; k++) {
        const double *restrict row = S + (size_t)k * (size_t)n;
        for (int i = 0; i < n; i++) {
            double x = row[i] / R[k];
            double *restrict a = A + (size_t)i * (size_t)n;
            for (int j = i; j < n; j++)
                a[j] += x * row[j];
        }
    }
    double err = 0;
    for (int i = 0; i < n; i++)
        for (int j = i; j < n; j++)
            err = fmax(err, fabs(A[(size_t)i * (size_t)n + j] - (i == j) / R[i]) * sqrt(R[i] * R[j]));
    return err;
}

/* The same measure for S = sigma I + u v^T in O(n).  With G = diag(1/R),
 * w = G u and kappa = u^T G u,
 *   S^T G S - G = (sigma^2 - 1) G + sigma (v w^T + w v^T) + kappa v v^T;
 * scaled entry by entry (x~_i = x_i sqrt(R_i)) and with w~ = lambda v~ + r
 * (r orthogonal to v~), its entries are at most
 *   |sigma^2 - 1| + |2 sigma lambda + kappa| max v~_i^2 + 2 |sigma| max |v~_i| max |r_i|,
 * the bound returned: the error itself when r = 0, as for a true series
 * or parallel adaptor, and never less than it. */
static double lossless_err_rank1(double sigma, const double *u, const double *v, const double *R, int n) {
    double vw = 0, vv = 0, kappa = 0, vmax = 0;
    for (int i = 0; i < n; i++) {
        double vt = v[i] * sqrt(R[i]), wt = u[i] / sqrt(R[i]);
        vw += vt * wt;
        vv += vt * vt;
        kappa += u[i] * u[i] / R[i];
        vmax = fmax(vmax, fabs(vt));
    }
    double lambda = vv > 0 ? vw / vv : 0, rmax = 0;
    for (int i = 0; i < n; i++)
        rmax = fmax(rmax, fabs(u[i] / sqrt(R[i]) - lambda * v[i] * sqrt(R[i])));
    return fabs(sigma * sigma - 1) + fabs(2 * sigma * lambda + kappa) * vmax * vmax + 2 * fabs(sigma) * vmax * rmax;
}

static double root_check(const Root *r, double tol);

double scatter_check(const Wdf *w, double tol) {
    double worst = 0;
    int cap = 0;
    double *u = NULL;
    for (int i = 0; i < w->nnodes; i++) {
        const WNode *n = w->nodes[i];
        if (n->kind == W_LEAF)
            continue;
        int np = n->nchild + 1;
        if (np > cap) {
            cap = 2 * np;
            u = arena_alloc(sizeof(double) * 3 * (size_t)cap);
        }
        double *v = u + np, *R = v + np;
        double sigma = node_factors(n, u, v, R);
        double err = lossless_err_rank1(sigma, u, v, R, np), s00 = sigma + u[0] * v[0];
        if (!(err <= tol))
            die("%s adaptor %d is not lossless (error %g)", n->kind == W_SERIES ? "series" : "parallel",
                n->id, err);
        if (!(fabs(s00) <= tol))
            die("%s adaptor %d is not adapted at its up port (S00 = %g)",
                n->kind == W_SERIES ? "series" : "parallel", n->id, s00);
        worst = fmax(worst, err);
    }
    for (int b = 0; b < w->nroots; b++)
        worst = fmax(worst, root_check(&w->roots[b], tol));
    return worst;
}

static double tableau_residual(const Root *r, const double *M);

static double root_check(const Root *r, double tol) {
    int np = r->nport + r->nnl, ne = r->nedge;
    double scale = 0;
    for (int i = 0; i < ne * ne; i++)
        scale = fmax(scale, fabs(r->M[i]));
    double *S = arena_alloc(sizeof(double) * (size_t)(np * np + 1));
    for (int k = 0; k < np; k++)
        for (int j = 0; j < np; j++)
            S[k * np + j] = r->M[k * ne + j];
    double err = lossless_err(S, r->R, np), lo = INFINITY, hi = 0;
    for (int k = 0; k < np; k++)
        lo = fmin(lo, r->R[k]), hi = fmax(hi, r->R[k]);
    /* the nodal solve loses digits with the spread of port resistances */
    double bound = fmax(tol, 64 * DBL_EPSILON * hi / lo);
    bool active = false; /* transformers neither store nor supply power */
    for (int j = 0; j < r->nctl; j++)
        active |= r->ctl[j].kind != E_XF;
    if (active) { /* neither lossless nor a tableau over its edges alone */
        for (int i = 0; i < ne * ne; i++)
            if (!isfinite(r->M[i]))
                die("the root's matrix is not finite");
        err = 0;
    } else if (!(err <= bound))
        die("root adaptor is not lossless (error %g)", err);
    double res = r->nctl ? 0 : tableau_residual(r, r->M);
    if (!(res <= bound * fmax(scale, 1) * 1e3))
        die("the root's matrix does not satisfy its tableau of Kirchhoff's laws (residual %g)", res);
    for (int k = r->nport; k < np && !r->joint; k++) /* a joint root's are not */
        if (fabs(S[k * np + k]) > tol)
            die("nonlinear edge %d of the root is not adapted (S = %g)", k, S[k * np + k]);
    return err;
}

/* ---- the tableau ----
 *
 * The same root written as Kirchhoff's laws over its edges: one KCL row
 * per core node (the reference left out) and one KVL row per fundamental
 * loop of a spanning tree.  A port or nonlinear edge k enters through its
 * waves, v = (a + b) / 2 and i = (a - b) / (2 R); an ideal V source through
 * its current (v = e known), an ideal I source through its voltage
 * (i = j known).  Unknowns: a of each port, i of each V, v of each I;
 * knowns: b of each port, the drives.  T * unknowns = U * knowns. */

typedef struct Tableau {
    int n;          /* rows = unknowns = edges */
    double *T, *U;  /* n x n each, row-major */
    int nkcl;       /* KCL rows first, then KVL rows */
} Tableau;

/* Fundamental loops: BFS tree over the core's nodes (reference = -1 is
 * node index ncore); loop of each non-tree edge with signs along it. */
static void loops(const Root *r, int *tree_edge, double *loopm, int *nloops) {
    int nn = r->ncore + 1, ne = r->nedge;
    int *parent = arena_alloc(sizeof(int) * (size_t)nn), *pedge = arena_alloc(sizeof(int) * (size_t)nn);
    int *queue = arena_alloc(sizeof(int) * (size_t)nn), *depth = arena_alloc(sizeof(int) * (size_t)nn);
    bool *seen = arena_alloc(sizeof(bool) * (size_t)nn);
#define NODE(x) ((x) < 0 ? r->ncore : (x))
    int head = 0, tail = 0;
    queue[tail++] = r->ncore;
    seen[r->ncore] = true;
    parent[r->ncore] = -1;
    while (head < tail) {
        int v = queue[head++];
        for (int k = 0; k < ne; k++) {
            int p = NODE(r->edge[k].p), q = NODE(r->edge[k].q);
            if (p != v && q != v)
                continue;
            int u = p == v ? q : p;
            if (seen[u])
                continue;
            seen[u] = true;
            parent[u] = v;
            pedge[u] = k;
            depth[u] = depth[v] + 1;
            tree_edge[k] = 1;
            queue[tail++] = u;
        }
    }
    *nloops = 0;
    for (int k = 0; k < ne; k++) {
        if (tree_edge[k])
            continue;
        double *row = loopm + (size_t)(*nloops)++ * (size_t)ne;
        row[k] = 1; /* around the loop in the edge's direction: p -> q, then back q -> p in the tree */
        int a = NODE(r->edge[k].q), b = NODE(r->edge[k].p);
        while (a != b) { /* walk both ends up to their common ancestor */
            if (depth[a] >= depth[b]) {
                int e = pedge[a];
                row[e] += NODE(r->edge[e].p) == a ? 1 : -1; /* traversed a -> parent */
                a = parent[a];
            } else {
                int e = pedge[b];
                row[e] += NODE(r->edge[e].p) == b ? -1 : 1; /* traversed parent -> b */
                b = parent[b];
            }
        }
    }
#undef NODE
}

static Tableau tableau(const Root *r, const double *R) {
    int ne = r->nedge, nl;
    Tableau t = {.n = ne};
    t.T = arena_alloc(sizeof(double) * (size_t)(ne * ne));
    t.U = arena_alloc(sizeof(double) * (size_t)(ne * ne));
    int *tree = arena_alloc(sizeof(int) * (size_t)ne);
    double *L = arena_alloc(sizeof(double) * (size_t)(ne * ne));
    loops(r, tree, L, &nl);
    /* edge k's current and voltage as (coefficient on unknown k, on known k) */
    for (int k = 0; k < ne; k++) {
        const RootEdge *e = &r->edge[k];
        bool port = e->kind == EDGE_PORT || e->kind == EDGE_NL;
        double iu = port ? 1 / (2 * R[k]) : e->kind == EDGE_V ? 1 : 0;  /* i = iu*x_k + ik*known_k */
        double ik = port ? -1 / (2 * R[k]) : e->kind == EDGE_I ? 1 : 0;
        double vu = port ? 0.5 : e->kind == EDGE_I ? 1 : 0;
        double vk = port ? 0.5 : e->kind == EDGE_V ? 1 : 0;
        for (int n = 0; n < r->ncore; n++) { /* KCL: current leaving node n */
            double s = (e->p == n) - (e->q == n);
            t.T[n * ne + k] += s * iu;
            t.U[n * ne + k] -= s * ik;
        }
        for (int l = 0; l < nl; l++) { /* KVL */
            double s = L[l * ne + k];
            t.T[(r->ncore + l) * ne + k] += s * vu;
            t.U[(r->ncore + l) * ne + k] -= s * vk;
        }
    }
    t.nkcl = r->ncore;
    if (r->ncore + nl != ne)
        die("tableau has %d rows for %d edges", r->ncore + nl, ne);
    return t;
}

int scatter_tableau(const Root *r, const double *R, double *M) {
    Tableau t = tableau(r, R);
    int ne = t.n;
    double *A = arena_alloc(sizeof(double) * (size_t)(ne * ne));
    /* rows mix conductances and plain 1/2s: scale each to its largest
     * entry so the singularity test compares like with like */
    for (int i = 0; i < ne; i++) {
        double m = 0;
        for (int k = 0; k < ne; k++)
            m = fmax(m, fabs(t.T[i * ne + k]));
        m = m > 0 ? m : 1;
        for (int k = 0; k < ne; k++) {
            A[i * ne + k] = t.T[i * ne + k] / m;
            M[i * ne + k] = t.U[i * ne + k] / m;
        }
    }
    return solve(A, ne, M, ne);
}

/* The subtree under top as an expression, "(R1 + -(C1 | R2))": written
 * into one stream without recursion (trees are as deep as ladders long). */
/* How far M is from solving the root's tableau, T M = U: the largest
 * |(T M - U)_ij| over the sum of |T_ik| along row i, which bounds the
 * error of M's entries that the residual shows.  Each row costs its
 * nonzeros (a KCL row: the edges at a node; a KVL row: a loop) times the
 * edges, where solving the tableau again would cost the edges cubed. */
static double tableau_residual(const Root *r, const double *M) {
    Tableau t = tableau(r, r->R);
    int ne = t.n;
    int *nz = arena_alloc(sizeof(int) * (size_t)(ne + 1));
    double *acc = arena_alloc(sizeof(double) * (size_t)(ne + 1)), worst = 0;
    for (int i = 0; i < ne; i++) {
        const double *T = t.T + (size_t)i * (size_t)ne, *U = t.U + (size_t)i * (size_t)ne;
        double norm = 0;
        int n = 0;
        for (int k = 0; k < ne; k++)
            if (T[k] != 0) {
                nz[n++] = k;
                norm += fabs(T[k]);
            }
        for (int j = 0; j < ne; j++)
            acc[j] = -U[j];
        for (int m = 0; m < n; m++) {
            const double x = T[nz[m]], *row = M + (size_t)nz[m] * (size_t)ne;
            for (int j = 0; j < ne; j++)
                acc[j] += x * row[j];
        }
        for (int j = 0; j < ne; j++)
            worst = fmax(worst, fabs(acc[j]) / (norm > 0 ? norm : 1));
    }
    return worst;
}

static const char *edge_label(const Circuit *c, const WNode *top) {
    typedef struct { const WNode *n; int next; } Frame; /* next: child to write, -1 before '(' */
    char *buf = NULL;
    size_t len = 0;
    FILE *f = open_memstream(&buf, &len);
    if (!f)
        die("out of memory");
    int cap = 16, sp = 0;
    Frame *st = arena_alloc(sizeof(Frame) * (size_t)cap);
    st[sp++] = (Frame){top, -1};
    while (sp) {
        Frame *t = &st[sp - 1];
        const WNode *n = t->n;
        if (n->kind == W_LEAF) {
            fputs(c->elems[n->elem].name, f);
            sp--;
            continue;
        }
        if (t->next < 0) {
            fputc('(', f);
            t->next = 0;
        }
        if (t->next == n->nchild) {
            fputc(')', f);
            sp--;
            continue;
        }
        int i = t->next++;
        fprintf(f, "%s%s", i ? (n->kind == W_SERIES ? " + " : " | ") : "", n->pol[i] < 0 ? "-" : "");
        if (sp == cap) {
            Frame *g = arena_alloc(sizeof(Frame) * (size_t)(2 * cap));
            memcpy(g, st, sizeof(Frame) * (size_t)cap);
            st = g;
            cap *= 2;
        }
        st[sp++] = (Frame){n->child[i], -1};
    }
    if (fclose(f) != 0 || !buf)
        die("out of memory");
    const char *s = arena_strndup(buf, len);
    free(buf);
    return s;
}

void scatter_print_tableau(const Wdf *w, FILE *out) {
    const Circuit *c = w->c;
    for (int b = 0; b < w->nroots; b++) {
        const Root *r = &w->roots[b];
        int ne = r->nedge;
        const char **name = arena_alloc(sizeof(char *) * (size_t)ne);
        const char **unk = arena_alloc(sizeof(char *) * (size_t)ne);
        const char **kn = arena_alloc(sizeof(char *) * (size_t)ne);
        fprintf(out, "root %d: %d edges, %d core nodes besides the reference '%s'\n", b, ne, r->ncore,
                c->nodes[r->ref_node]);
        for (int k = 0; k < ne; k++) {
            const RootEdge *e = &r->edge[k];
            name[k] = e->kind == EDGE_PORT ? edge_label(c, e->node) : c->elems[e->elem].name;
            const char *pn = e->p >= 0 ? c->nodes[r->core_node[e->p]] : c->nodes[r->ref_node];
            const char *qn = e->q >= 0 ? c->nodes[r->core_node[e->q]] : c->nodes[r->ref_node];
            bool port = e->kind == EDGE_PORT || e->kind == EDGE_NL;
            unk[k] = format(port ? "a%d" : e->kind == EDGE_V ? "i%d" : "v%d", k);
            kn[k] = format(port ? "b%d" : e->kind == EDGE_V ? "e%d" : "j%d", k);
            fprintf(out, "  edge %d: %s, %s -> %s, %s%s\n", k, name[k], pn, qn,
                    e->kind == EDGE_PORT ? "port" : e->kind == EDGE_V ? "ideal V" : e->kind == EDGE_I ? "ideal I" : "nonlinear, port",
                    port ? format(" R = %.6g", r->R[k]) : "");
        }
        for (int k = 0; k < r->nctl; k++) {
            const struct RootCtl *x = &r->ctl[k];
#define NAME(n) c->nodes[(n) >= 0 ? r->core_node[n] : r->ref_node]
            fprintf(out, "  %s: %s, %s -> %s, %s%s\n", c->elems[x->elem].name,
                    x->kind == E_OA ? "op-amp output" : x->kind == E_CV ? "controlled V" : x->kind == E_XF ? "transformer winding" : "controlled I",
                    NAME(x->p), NAME(x->q), x->kind == E_OA ? "holding 0 =" : format("gain %.6g times", x->gain),
                    x->kind == E_CC ? format(" i(%s)", c->elems[r->edge[x->ce].elem].name)
                                    : format(" v(%s, %s)", NAME(x->cp), NAME(x->cn)));
#undef NAME
        }
        if (r->nctl) /* its KCL would hold the outputs' currents, which are not edges */
            fprintf(out, "  its controlled sources are solved in its nodal equations, not a tableau over its edges\n");
        Tableau t = r->nctl ? (Tableau){0} : tableau(r, r->R);
        fprintf(out, "  tableau T x = U k, x = [");
        for (int k = 0; k < ne; k++)
            fprintf(out, "%s%s", k ? " " : "", unk[k]);
        fprintf(out, "], k = [");
        for (int k = 0; k < ne; k++)
            fprintf(out, "%s%s", k ? " " : "", kn[k]);
        fprintf(out, "]\n");
        for (int i = 0; i < t.n; i++) {
            fprintf(out, "  %-4s", i < t.nkcl ? "KCL" : "KVL");
            for (int k = 0; k < ne; k++)
                fprintf(out, " %11.4g", t.T[i * ne + k]);
            fprintf(out, "  |");
            for (int k = 0; k < ne; k++)
                fprintf(out, " %11.4g", t.U[i * ne + k]);
            fprintf(out, "\n");
        }
        fprintf(out, "  solved: x = M k\n");
        for (int i = 0; i < ne; i++) {
            fprintf(out, "  %-4s =", unk[i]);
            for (int k = 0; k < ne; k++)
                fprintf(out, " %+11.4g %s", r->M[i * ne + k], kn[k]);
            fprintf(out, "\n");
        }
    }
}
