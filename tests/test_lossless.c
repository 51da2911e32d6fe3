/*
 * test_lossless.c - every adaptor the compiler builds is lossless.
 *
 * An n-port with port resistances R_k (conductances G_k = 1/R_k) and
 * scattering matrix S (reflected waves b = S a, a_k = v_k + R_k i_k,
 * b_k = v_k - R_k i_k) is lossless when the power it absorbs,
 * sum G_k (a_k^2 - b_k^2) / 4, is zero for every a, that is when
 * S^T G S = G with G = diag(G_k).
 *
 * The error measure is relative entry by entry:
 *
 *     max_ij |(S^T G S - G)_ij| / sqrt(G_i G_j),
 *
 * which is the distance from orthogonality of G^1/2 S G^-1/2.  It does not
 * change when all resistances are scaled, and unlike a division by max G
 * it does not let the large conductances hide an error in the small ones.
 *
 * For every netlists/ *.wdn (loaded and structured at 48 kHz):
 *  - each series and parallel adaptor (scatter_node; ports: up port first,
 *    then children, resistances from the WNodes) is lossless to 1e-12 and
 *    adapted at its up port: |S[0][0]| <= 1e-12;
 *  - the rigid root's matrix M (scatter_root) agrees with the one
 *    wdf_build stored, and its port-to-port block is lossless to 1e-10 for
 *    the default port resistances and for 20 random sets, each resistance
 *    the default times a log-uniform factor in [1e-3, 1e3].  (With the
 *    ideal sources' drives zero, the ports see a connection network only,
 *    so that block alone must be lossless.)
 *  - at every corner of the params' ranges (all 2^n combinations of min
 *    and max, up to 8 params), with every port resistance of the tree
 *    recomputed from the elements as the voice does, the adaptors and the
 *    root again pass the same checks.
 * The worst errors of each netlist are printed: adaptors, the root at the
 * defaults, over the random sets, over the param corners.
 *
 * The root is solved from its nodal equations, whose conditioning grows
 * with the square of the spread of port conductances: spreads far beyond
 * what the params and sample rates reach (1e12 and more) lose digits, so the
 * random sets stay within a factor 1e3 of the defaults, the corners cover
 * the params' real extremes, and the root's tolerance is 1e-10 or
 * 64 eps times the spread of its port resistances, whichever is larger.
 *
 * Separately, scatter_node is compared on hand-made 3-ports against the
 * textbook closed forms and against a direct solve of the Kirchhoff
 * equations of the junction, and the checker is shown to reject matrices
 * that are not lossless.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>
#include <lapacke.h>
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testlib.h"

#define TOL_NODE 1e-12
#define TOL_ROOT 1e-10
#define NRANDOM 20
#define FS 48000.0

/* max_ij |(S^T G S - G)_ij| / sqrt(G_i G_j) for an n x n row-major S and
 * port resistances R. */
static double lossless_error(const double *S, const double *R, int n) {
    double err = 0;
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++) {
            long double acc = 0;
            for (int k = 0; k < n; k++)
                acc += (long double)S[k * n + i] * S[k * n + j] / R[k];
            double d = (double)(acc - (i == j ? 1.0L / R[i] : 0.0L));
            double e = fabs(d) * sqrt(R[i] * R[j]);
            if (!(e <= err)) /* NaN counts as worst */
                err = isnan(e) ? INFINITY : e;
        }
    return err;
}

/* The same residual divided by max G only, as scatter_check measures it;
 * printed next to failures for comparison. */
static double maxg_error(const double *S, const double *R, int n) {
    double err = 0, gmax = 0;
    for (int i = 0; i < n; i++)
        gmax = fmax(gmax, 1 / R[i]);
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++) {
            long double acc = 0;
            for (int k = 0; k < n; k++)
                acc += (long double)S[k * n + i] * S[k * n + j] / R[k];
            err = fmax(err, fabs((double)(acc - (i == j ? 1.0L / R[i] : 0.0L))));
        }
    return err / gmax;
}

/* Port resistances of an adaptor: up port first, then the children. */
static void node_ports(const WNode *n, double *R) {
    R[0] = n->R;
    for (int k = 0; k < n->nchild; k++)
        R[k + 1] = n->child[k]->R;
}

static Wdf *build(const char *path) {
    Circuit *c = wdc_load(path);
    if (!c)
        return NULL;
    jmp_buf jb;
    jmp_buf *saved = diag.jmp;
    Wdf *volatile w = NULL;
    diag.jmp = &jb;
    if (!setjmp(jb))
        w = wdf_build(c, FS);
    diag.jmp = saved;
    return w;
}

/* ---- the netlists ---- */

/* Worst errors over the checks of one netlist. */
typedef struct Worst {
    double node, s00, root_default, root_random, root_corner;
    int nadapt, failed;
} Worst;

/* Checks every series/parallel adaptor with the port resistances the
 * WNodes hold now; `label` names the param set in messages. */
static void check_adaptors(const char *path, const Wdf *w, const char *label, Worst *x) {
    x->nadapt = 0;
    for (int i = 0; i < w->nnodes; i++) {
        const WNode *n = w->nodes[i];
        if (n->kind == W_LEAF)
            continue;
        x->nadapt++;
        int np = n->nchild + 1;
        double *S = calloc((size_t)(np * np), sizeof *S), *R = calloc((size_t)np, sizeof *R);
        assert_non_null(S);
        assert_non_null(R);
        node_ports(n, R);
        scatter_node(n, S);
        double err = lossless_error(S, R, np);
        const char *kind = n->kind == W_SERIES ? "series" : "parallel";
        if (!(err <= TOL_NODE)) {
            print_error("%s (%s): %s adaptor %d (%d ports) not lossless: error %.3g > %.0e\n", path, label, kind,
                        n->id, np, err, TOL_NODE);
            x->failed = 1;
        }
        if (!(fabs(S[0]) <= TOL_NODE)) {
            print_error("%s (%s): %s adaptor %d not adapted at its up port: S[0][0] = %.3g\n", path, label, kind,
                        n->id, S[0]);
            x->failed = 1;
        }
        x->node = fmax(x->node, err);
        x->s00 = fmax(x->s00, fabs(S[0]));
        free(S);
        free(R);
    }
}

/* Losslessness of the root's port block for port resistances R; returns
 * the error, or INFINITY if scatter_root refuses them. */
static double root_error(const char *path, const Root *r, double *R, const char *label, double *M,
                         double *S, Worst *x) {
    int np = r->nport + r->nnl, ne = r->nedge;
    /* a nonlinear edge is adapted to what the rest of the core presents */
    for (int k = r->nport; k < np; k++)
        if (scatter_thevenin(r, R, k, &R[k]) != 0) {
            print_error("%s: no Thevenin resistance for nonlinear edge %d at %s port resistances\n", path, k, label);
            x->failed = 1;
            return INFINITY;
        }
    if (scatter_root(r, R, M) != 0) {
        print_error("%s: scatter_root calls the root singular for %s port resistances (all positive)\n", path,
                    label);
        x->failed = 1;
        return INFINITY;
    }
    for (int k = 0; k < np; k++)
        for (int j = 0; j < np; j++)
            S[k * np + j] = M[k * ne + j];
    double err = lossless_error(S, R, np);
    double lo = INFINITY, hi = 0;
    for (int k = 0; k < np; k++)
        lo = fmin(lo, R[k]), hi = fmax(hi, R[k]);
    /* The root comes from an LU solve of the nodal matrix Q G Q^T, whose
     * condition number grows with the spread hi/lo of the port
     * resistances: the error bound is a small multiple of eps times it. */
    double tol = fmax(TOL_ROOT, 64 * DBL_EPSILON * hi / lo);
    if (!(err <= tol)) {
        print_error("%s: root port block not lossless for %s port resistances (%.3g .. %.3g ohm): "
                    "error %.3g > %.3g (divided by max G instead: %.3g)\n",
                    path, label, lo, hi, err, tol, maxg_error(S, R, np));
        x->failed = 1;
    }
    return err;
}

/* Sets the port resistance of every tree node for the param values p, as
 * the voice computes them (bilinear reactances at FS, series sums,
 * parallel conductance sums; values clamped like the voice's pos()). */
static void retune_tree(Wdf *w, const double *p) {
    for (int i = 0; i < w->nnodes; i++) { /* post-order: children first */
        WNode *n = w->nodes[i];
        if (n->kind == W_LEAF) {
            const Elem *e = &w->c->elems[n->elem];
            double v = elem_value(w->c, e, p);
            v = v > 1e-18 && v < 1e300 ? v : v >= 1e300 ? 1e300 : 1e-18;
            n->R = e->kind == E_C ? 1 / (2 * w->fs * v) : e->kind == E_L ? 2 * w->fs * v : v;
            continue;
        }
        double t = 0;
        for (int k = 0; k < n->nchild; k++)
            t += n->kind == W_SERIES ? n->child[k]->R : 1 / n->child[k]->R;
        n->R = n->kind == W_SERIES ? t : 1 / t;
    }
}

static void test_netlist(void **state) {
    const char *path = *state;
    Wdf *w = build(path);
    if (!w)
        fail_msg("%s: does not load or structure", path);
    Worst x = {0};

    /* series and parallel adaptors at the default params */
    check_adaptors(path, w, "defaults", &x);

    /* the roots */
    int npmax = 0, nemax = 0, np = 0, ne = 0;
    for (int rb = 0; rb < w->nroots; rb++) {
    const Root *r = &w->roots[rb];
    np = r->nport + r->nnl, ne = r->nedge;
    npmax = np > npmax ? np : npmax;
    nemax = ne > nemax ? ne : nemax;
    double root_stored = 0;
    if (np > 0) {
        double *M = calloc((size_t)(ne * ne), sizeof *M);
        double *S = calloc((size_t)(np * np), sizeof *S);
        double *R0 = calloc((size_t)np, sizeof *R0), *R = calloc((size_t)np, sizeof *R);
        assert_non_null(M);
        assert_non_null(S);
        assert_non_null(R0);
        assert_non_null(R);
        for (int k = 0; k < np; k++)
            R0[k] = k < r->nport ? r->edge[k].node->R : r->R[k];
        x.root_default = fmax(x.root_default, root_error(path, r, R0, "the default", M, S, &x));
        for (int k = 0; k < ne * ne; k++)
            root_stored = fmax(root_stored, fabs(M[k] - r->M[k]));
        if (!(root_stored <= 1e-12)) {
            print_error("%s: scatter_root at the default resistances differs from the stored root matrix "
                        "by %.3g\n", path, root_stored);
            x.failed = 1;
        }
        tl_rng rng;
        tl_rng_seed(&rng, 0x1055ull);
        for (int set = 1; set <= NRANDOM; set++) {
            for (int k = 0; k < r->nport; k++)
                R[k] = R0[k] * pow(10.0, -3.0 + 6.0 * tl_rng_uniform(&rng));
            char label[32];
            snprintf(label, sizeof label, "random set %d of", set);
            x.root_random = fmax(x.root_random, root_error(path, r, R, label, M, S, &x));
        }
        free(M);
        free(S);
        free(R0);
        free(R);
    }
    }

    /* every corner of the params' ranges, the whole tree retuned */
    const Circuit *c = w->c;
    int ncorner = c->nparams <= 8 ? 1 << c->nparams : 256;
    if (c->nparams > 0) {
        double *saved = calloc((size_t)w->nnodes, sizeof *saved), *p = calloc((size_t)c->nparams, sizeof *p);
        double *M = calloc((size_t)(nemax * nemax) + 1, sizeof *M), *S = calloc((size_t)(npmax * npmax) + 1, sizeof *S);
        double *R = calloc((size_t)npmax + 1, sizeof *R);
        assert_non_null(saved);
        assert_non_null(p);
        assert_non_null(M);
        assert_non_null(S);
        assert_non_null(R);
        for (int i = 0; i < w->nnodes; i++)
            saved[i] = w->nodes[i]->R;
        /* the recomputation agrees with wdf_build at the defaults */
        for (int k = 0; k < c->nparams; k++)
            p[k] = c->params[k].def;
        retune_tree(w, p);
        for (int i = 0; i < w->nnodes; i++)
            if (!(fabs(w->nodes[i]->R - saved[i]) <= 1e-12 * saved[i])) {
                print_error("%s: tree node %d has R = %.17g, but its elements give %.17g at the defaults\n", path,
                            i, saved[i], w->nodes[i]->R);
                x.failed = 1;
            }
        for (int corner = 0; corner < ncorner; corner++) {
            char label[256] = "";
            size_t len = 0;
            for (int k = 0; k < c->nparams; k++) {
                int hi = k < 8 ? (corner >> k) & 1 : 0;
                p[k] = hi ? c->params[k].max : c->params[k].min;
                if (len < sizeof label)
                    len += (size_t)snprintf(label + len, sizeof label - len, "%s%s=%g", k ? " " : "",
                                            c->params[k].name, p[k]);
            }
            retune_tree(w, p);
            check_adaptors(path, w, label, &x);
            for (int rb = 0; rb < w->nroots; rb++) {
                const Root *r = &w->roots[rb];
                if (r->nport + r->nnl == 0)
                    continue;
                for (int k = 0; k < r->nport; k++)
                    R[k] = r->edge[k].node->R;
                char what[300];
                snprintf(what, sizeof what, "the param corner (%s)", label);
                x.root_corner = fmax(x.root_corner, root_error(path, r, R, what, M, S, &x));
            }
        }
        for (int i = 0; i < w->nnodes; i++)
            w->nodes[i]->R = saved[i];
        free(saved);
        free(p);
        free(M);
        free(S);
        free(R);
    }

    print_message("%-26s %2d adaptors: worst %.2e (|S00| %.1e); %d roots: default %.2e, "
                  "%d random sets %.2e",
                  path, x.nadapt, x.node, x.s00, w->nroots, x.root_default, NRANDOM, x.root_random);
    if (c->nparams > 0)
        print_message(", %d param corners %.2e", ncorner, x.root_corner);
    print_message("\n");
    if (x.failed)
        fail_msg("%s: an adaptor is not lossless", path);
}

/* ---- hand-made junctions ---- */

/* Kirchhoff solve of an n-port series (all port currents equal up to
 * polarity, polarised voltages summing to zero) or parallel junction
 * (all port voltages equal up to polarity, polarised currents summing to
 * zero): column j of S is b for a = e_j. */
static void kirchhoff_S(int series, const double *R, const int *s, int n, double *S) {
    int N = 2 * n; /* unknowns: v_0..v_n-1, i_0..i_n-1 (into the junction) */
    for (int j = 0; j < n; j++) {
        double A[64] = {0}, b[8] = {0};
        int piv[8];
        int row = 0;
        for (int k = 0; k < n; k++, row++) { /* v_k + R_k i_k = a_k */
            A[row * N + k] = 1;
            A[row * N + n + k] = R[k];
            b[row] = k == j;
        }
        int off = series ? n : 0;  /* the quantity shared by all ports */
        int sum = series ? 0 : n;  /* the one whose signed sum is zero */
        for (int k = 1; k < n; k++, row++) { /* s_k x_k = s_0 x_0 */
            A[row * N + off + k] = s[k];
            A[row * N + off] = -s[0];
        }
        for (int k = 0; k < n; k++) /* sum s_k y_k = 0 */
            A[row * N + sum + k] = s[k];
        assert_int_equal(LAPACKE_dgesv(LAPACK_ROW_MAJOR, N, 1, A, N, piv, b, 1), 0);
        for (int k = 0; k < n; k++)
            S[k * n + j] = b[k] - R[k] * b[n + k];
    }
}

/* Textbook closed forms, with polarities s (s_0 = +1 for the up port):
 * series   S = I - 2 (s.R) s^T / sum R,
 * parallel S = 2 s (s.G)^T / sum G - I. */
static void closed_form_S(int series, const double *R, const int *s, int n, double *S) {
    double sum = 0;
    for (int k = 0; k < n; k++)
        sum += series ? R[k] : 1 / R[k];
    for (int k = 0; k < n; k++)
        for (int j = 0; j < n; j++) {
            double d = k == j;
            S[k * n + j] = series ? d - 2 * (s[k] * R[k]) * s[j] / sum : 2 * s[k] * (s[j] / R[j]) / sum - d;
        }
}

static double max_diff(const double *a, const double *b, int n) {
    double m = 0;
    for (int k = 0; k < n; k++)
        m = fmax(m, fabs(a[k] - b[k]));
    return m;
}

/* A 3-port adaptor of `kind` with children of resistances R1, R2 and
 * polarities p1, p2; the up port gets R0 (adapted: <= 0). */
static void hand_case(WKind kind, double R1, double R2, int p1, int p2, double R0) {
    WNode leaf[2], node;
    memset(leaf, 0, sizeof leaf);
    memset(&node, 0, sizeof node);
    WNode *child[2] = {&leaf[0], &leaf[1]};
    int pol[2] = {p1, p2};
    leaf[0].kind = leaf[1].kind = W_LEAF;
    leaf[0].R = R1;
    leaf[1].R = R2;
    node.kind = kind;
    node.nchild = 2;
    node.child = child;
    node.pol = pol;
    int series = kind == W_SERIES;
    int adapted = !(R0 > 0);
    node.R = adapted ? (series ? R1 + R2 : 1 / (1 / R1 + 1 / R2)) : R0;
    leaf[0].parent = leaf[1].parent = &node;

    double S[9], C[9], K[9], R[3] = {node.R, R1, R2};
    int s[3] = {1, p1, p2};
    scatter_node(&node, S);
    closed_form_S(series, R, s, 3, C);
    kirchhoff_S(series, R, s, 3, K);
    double dc = max_diff(S, C, 9), dk = max_diff(S, K, 9), loss = lossless_error(S, R, 3);
    print_message("%-8s R=(%g, %g, %g) pol=(+,%c,%c): |S-closed| %.1e, |S-Kirchhoff| %.1e, lossless %.1e, "
                  "S00 %.2g\n",
                  series ? "series" : "parallel", R[0], R1, R2, p1 > 0 ? '+' : '-', p2 > 0 ? '+' : '-', dc, dk,
                  loss, S[0]);
    assert_true(dc <= 1e-14);
    assert_true(dk <= 1e-12);
    assert_true(loss <= TOL_NODE);
    if (adapted)
        assert_true(fabs(S[0]) <= 1e-15);
}

static void test_hand_made(void **state) {
    (void)state;
    hand_case(W_SERIES, 100.0, 470.0, 1, 1, 0);
    hand_case(W_SERIES, 2.2e3, 1e-3, 1, -1, 0);
    hand_case(W_SERIES, 3.0, 5.0, -1, -1, 11.0);
    hand_case(W_PARALLEL, 100.0, 470.0, 1, 1, 0);
    hand_case(W_PARALLEL, 2.2e3, 1e-3, -1, 1, 0);
    hand_case(W_PARALLEL, 3.0, 5.0, -1, -1, 11.0);

    /* the closed forms by hand for one case: series, R = (3, 1, 2),
     * pol (+, +, -): S_kj = d_kj - s_k s_j R_k / 3 */
    double S[9], R[3] = {3, 1, 2};
    int s[3] = {1, 1, -1};
    const double want[9] = {0, -1, 1, -1.0 / 3, 2.0 / 3, 1.0 / 3, 2.0 / 3, 2.0 / 3, 1.0 / 3};
    closed_form_S(1, R, s, 3, S);
    assert_true(max_diff(S, want, 9) <= 1e-15);
    /* parallel, G = (3, 1, 2), pol (+, -, +): S_kj = s_k s_j G_j / 3 - d_kj */
    double Rp[3] = {1.0 / 3, 1, 0.5};
    int sp[3] = {1, -1, 1};
    const double wantp[9] = {0, -1.0 / 3, 2.0 / 3, -1, -2.0 / 3, -2.0 / 3, 1, -1.0 / 3, -1.0 / 3};
    closed_form_S(0, Rp, sp, 3, S);
    assert_true(max_diff(S, wantp, 9) <= 1e-15);
}

/* The checker rejects what is not lossless. */
static void test_checker_can_fail(void **state) {
    (void)state;
    double R[3] = {570.0, 100.0, 470.0}, S[9];
    int s[3] = {1, 1, 1};
    closed_form_S(1, R, s, 3, S);
    assert_true(lossless_error(S, R, 3) <= TOL_NODE);

    double L[9];
    for (int k = 0; k < 9; k++) /* a lossy adaptor: every wave attenuated */
        L[k] = 0.999 * S[k];
    assert_true(lossless_error(L, R, 3) > 1e-4);

    memcpy(L, S, sizeof L); /* one coefficient off by 1e-9 */
    L[5] += 1e-9;
    assert_true(lossless_error(L, R, 3) > TOL_NODE);

    /* lossless, but for other port resistances */
    double R2[3] = {570.0, 470.0, 100.0};
    assert_true(lossless_error(S, R2, 3) > 1e-2);

    /* an error in the smallest conductance is seen even next to huge ones */
    double Rw[3] = {1e6 + 1e-6, 1e6, 1e-6};
    closed_form_S(1, Rw, s, 3, S);
    assert_true(lossless_error(S, Rw, 3) <= TOL_NODE);
    S[0] += 1e-9; /* reflection at the 1e-6 S up port */
    assert_true(lossless_error(S, Rw, 3) > TOL_NODE);

    /* NaN is never lossless */
    S[0] = NAN;
    assert_true(lossless_error(S, Rw, 3) > TOL_NODE);
}

int main(void) {
    const struct CMUnitTest fixed[] = {
        {.name = "hand_made_3_ports", .test_func = test_hand_made},
        {.name = "checker_can_fail", .test_func = test_checker_can_fail},
    };
    return tl_run_per_netlist("lossless", test_netlist, fixed, sizeof fixed / sizeof fixed[0]);
}
