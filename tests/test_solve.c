/*
 * test_solve.c - linear networks eliminated at compile time (gen/solve.c).
 *
 * The straight-line solve a voice prints for a root's matrix and for its
 * initial-condition state is run here as the printed code would run it
 * (sx_run) and compared with a dense solve of the same network's
 * modified nodal equations (partial pivoting, long double) over random
 * networks: conductances spread over six decades with a series emf each,
 * ideal voltage sources forming a random forest, current sources.  Node
 * potentials and every edge's current must agree to 1e-9 of the
 * network's scale (the largest potential; for currents, the largest
 * current or conductance times the potentials and emf it spans) (the elimination is backward stable for the positive
 * definite supernode matrix; 1e-9 leaves room for its condition number,
 * at most about 1e6 here).
 *
 * Networks the elimination must refuse are refused: a loop of voltage
 * sources, a node reached only through current sources, a supernode
 * floating on voltage sources.  Values that are numbers for any
 * conductance fold to numbers: a voltage source at a one-port root gives
 * a = 2 e - b, with no arithmetic printed.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gen.h"
#include "solve.h"

/* ---- a random network and the values of its names ---- */

#define MAXN 14
#define MAXE 48

typedef struct Net {
    int n, ne;
    char kind[MAXE];
    int p[MAXE], q[MAXE];
    double g[MAXE], val[MAXE];
} Net;

static uint64_t rng = 0x9e3779b97f4a7c15ull;

static double urand(void) {
    rng ^= rng << 13, rng ^= rng >> 7, rng ^= rng << 17;
    return (double)(rng >> 11) / 9007199254740992.0;
}

static int irand(int n) { return (int)(urand() * n); }

/* The value of a name the printed code reads: gK (conductance of edge K)
 * or eK (value of edge K). */
static double name_value(const char *text, void *ctx) {
    const Net *N = ctx;
    int k = atoi(text + 1);
    assert_true(k >= 0 && k < N->ne);
    return text[0] == 'g' ? N->g[k] : N->val[k];
}

static int find(int *uf, int a) {
    while (uf[a] != a)
        a = uf[a];
    return a;
}

/* n nodes (reference -1); a forest of voltage sources; conductances that
 * reach every node; a few current sources. */
static void random_net(Net *N) {
    N->n = 1 + irand(MAXN - 1);
    N->ne = 0;
    int uf[MAXN + 1];
    for (int i = 0; i <= N->n; i++)
        uf[i] = i;
    int nv = irand(N->n + 1);
    for (int t = 0; t < nv * 3 && nv > 0; t++) {
        int a = irand(N->n + 1), b = irand(N->n + 1);
        if (find(uf, a) == find(uf, b))
            continue;
        uf[find(uf, a)] = find(uf, b);
        N->kind[N->ne] = 'V', N->p[N->ne] = a == N->n ? -1 : a, N->q[N->ne] = b == N->n ? -1 : b;
        N->val[N->ne++] = 2 * urand() - 1;
        if (--nv == 0)
            break;
    }
    /* a conductance from each node to an earlier one or the reference,
     * then more at random */
    for (int i = 0; i < N->n; i++) {
        int j = irand(i + 1) - 1;
        N->kind[N->ne] = 'G', N->p[N->ne] = i, N->q[N->ne] = j;
        N->ne++;
    }
    int extra = irand(N->n + 2);
    for (int t = 0; t < extra && N->ne < MAXE - 4; t++) {
        int a = irand(N->n + 1) - 1, b = irand(N->n + 1) - 1;
        if (a == b)
            continue;
        N->kind[N->ne] = 'G', N->p[N->ne] = a, N->q[N->ne] = b;
        N->ne++;
    }
    int nj = irand(3);
    for (int t = 0; t < nj; t++) {
        int a = irand(N->n + 1) - 1, b = irand(N->n + 1) - 1;
        if (a == b)
            continue;
        N->kind[N->ne] = 'J', N->p[N->ne] = a, N->q[N->ne] = b;
        N->val[N->ne++] = 2 * urand() - 1;
    }
    for (int k = 0; k < N->ne; k++)
        if (N->kind[k] == 'G') {
            N->g[k] = pow(10, 6 * urand() - 3);
            N->val[k] = urand() < 0.5 ? 0 : 2 * urand() - 1; /* series emf */
        }
}

/* The modified nodal equations, solved densely: potentials v[n] and the
 * current of each edge from p to q.  Returns -1 if singular. */
static int dense_solve(const Net *N, double *v, double *cur) {
    int nv = 0, idx[MAXE];
    for (int k = 0; k < N->ne; k++)
        idx[k] = N->kind[k] == 'V' ? N->n + nv++ : -1;
    const int m = N->n + nv;
    long double A[MAXN + MAXE][MAXN + MAXE + 1];
    memset(A, 0, sizeof A);
    for (int k = 0; k < N->ne; k++) {
        int p = N->p[k], q = N->q[k];
        if (N->kind[k] == 'G') { /* g (vp - vq - emf) leaves p */
            long double g = N->g[k];
            if (p >= 0) A[p][p] += g, A[p][m] += g * N->val[k];
            if (q >= 0) A[q][q] += g, A[q][m] -= g * N->val[k];
            if (p >= 0 && q >= 0) A[p][q] -= g, A[q][p] -= g;
        } else if (N->kind[k] == 'J') {
            if (p >= 0) A[p][m] -= N->val[k];
            if (q >= 0) A[q][m] += N->val[k];
        } else {
            int r = idx[k];
            if (p >= 0) A[p][r] += 1, A[r][p] += 1;
            if (q >= 0) A[q][r] -= 1, A[r][q] -= 1;
            A[r][m] = N->val[k];
        }
    }
    for (int c = 0; c < m; c++) {
        int piv = c;
        for (int r = c + 1; r < m; r++)
            if (fabsl(A[r][c]) > fabsl(A[piv][c]))
                piv = r;
        if (fabsl(A[piv][c]) < 1e-30L)
            return -1;
        for (int j = 0; j <= m; j++) {
            long double t = A[c][j];
            A[c][j] = A[piv][j], A[piv][j] = t;
        }
        for (int r = 0; r < m; r++)
            if (r != c && A[r][c] != 0) {
                long double f = A[r][c] / A[c][c];
                for (int j = c; j <= m; j++)
                    A[r][j] -= f * A[c][j];
            }
    }
    long double x[MAXN + MAXE];
    for (int r = 0; r < m; r++)
        x[r] = A[r][m] / A[r][r];
    for (int i = 0; i < N->n; i++)
        v[i] = (double)x[i];
    for (int k = 0; k < N->ne; k++) {
        long double vp = N->p[k] >= 0 ? x[N->p[k]] : 0, vq = N->q[k] >= 0 ? x[N->q[k]] : 0;
        cur[k] = N->kind[k] == 'V' ? (double)x[idx[k]]
                 : N->kind[k] == 'J' ? N->val[k]
                                     : (double)(N->g[k] * (vp - vq - N->val[k]));
    }
    return 0;
}

/* The network as solve.c sees it: conductances and values by name. */
static Lin *lin_of(const Net *N, Sx *sx, Sym *val) {
    Lin *L = lin_new(sx, N->n);
    for (int k = 0; k < N->ne; k++) {
        int e = N->kind[k] == 'G' ? lin_g(L, N->p[k], N->q[k], sx_temp(sx, format("g%d", k)))
                : N->kind[k] == 'V' ? lin_v(L, N->p[k], N->q[k])
                                    : lin_j(L, N->p[k], N->q[k]);
        assert_int_equal(e, k);
        val[k] = sym_ext(format("e%d", k));
    }
    return L;
}

/* ---- the tests ---- */

static void test_random_networks(void **state) {
    (void)state;
    int solved = 0;
    double worst = 0;
    for (int trial = 0; trial < 3000; trial++) {
        Net N;
        random_net(&N);
        Sx *sx = sx_new("u");
        Sym val[MAXE], pot[MAXN], cur[MAXE];
        Lin *L = lin_of(&N, sx, val);
        double v[MAXN], c[MAXE];
        int dense = dense_solve(&N, v, c);
        assert_int_equal(dense, 0); /* every node reaches the reference through conductances */
        assert_true(lin_factor(L));
        lin_solve(L, val, pot, cur);
        double *run = sx_run(sx, name_value, &N);
        double scale = 1e-300;
        for (int i = 0; i < N.n; i++)
            scale = fmax(scale, fabs(v[i]));
        /* currents against what their terms are: g (|vp| + |vq| + |emf|) */
        double cscale = 1e-300;
        for (int k = 0; k < N.ne; k++) {
            cscale = fmax(cscale, fabs(c[k]));
            if (N.kind[k] == 'G')
                cscale = fmax(cscale, N.g[k] * ((N.p[k] >= 0 ? fabs(v[N.p[k]]) : 0) +
                                                (N.q[k] >= 0 ? fabs(v[N.q[k]]) : 0) + fabs(N.val[k])));
        }
        for (int i = 0; i < N.n; i++) {
            double got = sx_value(run, pot[i], name_value, &N), err = fabs(got - v[i]) / scale;
            worst = fmax(worst, err);
            if (!(err <= 1e-9))
                fail_msg("trial %d: v[%d] = %.17g, dense %.17g", trial, i, got, v[i]);
        }
        for (int k = 0; k < N.ne; k++) {
            double got = sx_value(run, cur[k], name_value, &N), err = fabs(got - c[k]) / cscale;
            worst = fmax(worst, err);
            if (!(err <= 1e-9))
                fail_msg("trial %d: current of edge %d (%c) = %.17g, dense %.17g", trial, k, N.kind[k], got, c[k]);
        }
        solved++;
    }
    printf("solve: %d random networks, worst error %.3g of their scale\n", solved, worst);
}

static void test_refused(void **state) {
    (void)state;
    Sx *sx = sx_new("u");
    /* a loop of voltage sources: two in parallel */
    Lin *L = lin_new(sx, 2);
    lin_v(L, 0, -1);
    lin_v(L, 0, -1);
    lin_g(L, 1, 0, sx_temp(sx, "g"));
    assert_false(lin_factor(L));
    /* a node reached through a current source only */
    L = lin_new(sx, 2);
    lin_g(L, 0, -1, sx_temp(sx, "g"));
    lin_j(L, 1, 0);
    assert_false(lin_factor(L));
    /* a supernode of two nodes held apart by a source, floating */
    L = lin_new(sx, 3);
    lin_g(L, 0, -1, sx_temp(sx, "g"));
    lin_v(L, 1, 2);
    lin_j(L, 1, -1);
    assert_false(lin_factor(L));
    /* the same tied down by one conductance is solved */
    L = lin_new(sx, 3);
    lin_g(L, 0, -1, sx_temp(sx, "g"));
    lin_v(L, 1, 2);
    lin_g(L, 2, 0, sx_temp(sx, "h"));
    assert_true(lin_factor(L));
}

/* A voltage source across a one-port root: the port's incident wave is
 * 2 e - b whatever its resistance, printed as no arithmetic at all; the
 * source's current is (e - b) / R, which is. */
static void test_numbers_fold(void **state) {
    (void)state;
    Sx *sx = sx_new("u");
    Lin *L = lin_new(sx, 1);
    lin_g(L, 0, -1, sx_temp(sx, "1.0 / st->c_R[0]"));
    lin_v(L, 0, -1);
    assert_true(lin_factor(L));
    for (int j = 0; j < 2; j++) {
        Sym val[2] = {sym_k(j == 0), sym_k(j == 1)}, pot[1], cur[2];
        lin_solve(L, val, pot, cur);
        Sym a = sx_sub(sx, sx_mul(sx, sym_k(2), pot[0]), sym_k(j == 0));
        assert_true(sym_is(a, j == 0 ? -1 : 2));
        assert_false(sym_is(cur[1], 0)); /* the current depends on R */
    }
    Buf o = {0};
    sx_code(sx, &o);
    assert_int_equal(o.len, 0); /* nothing used, nothing printed */
}

/* What the printer keeps: a statement's values and what they read, each
 * temporary once (the same text is the same value), in order. */
static void test_printing(void **state) {
    (void)state;
    Sx *sx = sx_new("u");
    Sym g = sx_temp(sx, "1.0 / st->c_R[3]"), h = sx_temp(sx, "1.0 / st->c_R[3]");
    Sym unused = sx_mul(sx, g, sym_ext("react[0]"));
    (void)unused;
    Sym s = sx_add(sx, g, sx_neg(sx, sx_neg(sx, h)));
    sx_stmt(sx, format("    st->c_M[0] = (real)%s;\n", sx_use(sx, s)));
    Buf o = {0};
    sx_code(sx, &o);
    assert_string_equal(o.s, "    const double u0 = 1.0 / st->c_R[3];\n"
                             "    const double u1 = u0 + u0;\n"
                             "    st->c_M[0] = (real)u1;\n");
}

/* With sx_once, a temporary read once is printed where it is read,
 * unless a statement between them writes what it reads (or may write
 * anything); a temporary read twice keeps its name. */
static void test_printing_once(void **state) {
    (void)state;
    Sx *sx = sx_new("u");
    sx_once(sx, true);
    Sym g = sx_temp(sx, "1.0 / st->c_R[0]");
    Sym d = sx_sub(sx, sym_ext("st->s_e[0]"), sym_ext("react[0]"));
    Sym u = sx_mul(sx, sym_ext("st->c_R[1]"), sx_mul(sx, g, d));
    Sym up = sx_add(sx, sym_ext("react[0]"), u), dn = sx_sub(sx, sym_ext("react[0]"), u);
    Sym reads_a = sx_add(sx, sym_ext("st->s_a[0]"), sym_k(1));
    sx_stmt(sx, format("    st->s_a[0] = (real)%s;\n", sx_use(sx, up)));
    sx_stmt(sx, format("    st->s_b[0] = (real)%s;\n", sx_use(sx, dn)));
    sx_stmt(sx, format("    st->s_c[0] = (real)%s;\n", sx_use(sx, reads_a)));
    Sym e = sx_mul(sx, sym_ext("st->c_R[2]"), sym_ext("react[1]"));
    sx_stmt(sx, "    {\n        anything();\n    }\n");
    sx_stmt(sx, format("    st->s_d[0] = (real)%s;\n", sx_use(sx, e)));
    Buf o = {0};
    sx_code(sx, &o);
    assert_string_equal(o.s, "    const double u0 = st->c_R[1] * ((1.0 / st->c_R[0]) * (st->s_e[0] - react[0]));\n"
                             "    const double u1 = st->s_a[0] + 1.0;\n"
                             "    st->s_a[0] = (real)(react[0] + u0);\n"
                             "    st->s_b[0] = (real)(react[0] - u0);\n"
                             "    st->s_c[0] = (real)u1;\n"
                             "    const double u2 = st->c_R[2] * react[1];\n"
                             "    {\n        anything();\n    }\n"
                             "    st->s_d[0] = (real)u2;\n");
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_random_networks),
        cmocka_unit_test(test_refused),
        cmocka_unit_test(test_numbers_fold),
        cmocka_unit_test(test_printing),
        cmocka_unit_test(test_printing_once),
    };
    return cmocka_run_group_tests_name("solve", tests, NULL, NULL);
}
