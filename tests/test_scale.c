/*
 * test_scale.c - large netlists compile, and compile right (issue 14,
 * item 5).
 *
 * Three series-parallel networks of 10^4 elements are written into a
 * temporary folder and compiled through the library as bin/wdc does
 * (wdc_load, wdf_build, scatter_check, emit_voice): a chain of resistors,
 * a ladder (series R, shunt C) and a balanced tree of nested series and
 * parallel connections of R, C and L.  Each hangs from an ideal current
 * source, which the reduction never merges, so the rest reduces to one
 * adaptor tree between the source's nodes whose port resistance is the
 * network's resistance there (C as 1/(2 fs C), L as 2 fs L), computed
 * here independently: the sum of the chain, a continued fraction for the
 * ladder, the tree's own recursion.  The counts of adaptors and their
 * children, the chain's element order and polarities, and the emitted
 * voice are checked too.
 *
 * The losslessness check must still fail on an adaptor that is wrong
 * (a port resistance or a polarity altered): a child process runs it on
 * a damaged tree and must end with the internal-error status 3.
 *
 * Netlists whose blocks would expand past the limits (10^6 elements in
 * all, instances 64 deep) are refused at the `use` line that crosses
 * them, with the position; blocks that use themselves, directly or not,
 * are refused.  Diagnostics are compared verbatim, first line only, as
 * in test_parse.c.  No timings are asserted (bench/compilebench.c
 * measures them).
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
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "testlib.h"

#define N 10000    /* elements of each network, the source aside */
#define FS 48000.0 /* the netlists' rate */

static char tmpdir[64];

static int make_tmpdir(void **state) {
    (void)state;
    return tl_temp_dir(tmpdir, "wdc-scale");
}

static int remove_tmpdir(void **state) {
    (void)state;
    tl_remove_dir(tmpdir);
    return 0;
}

/* ---- netlists ---- */

typedef struct Text {
    char *buf;
    size_t len;
    FILE *f;
} Text;

static void text_begin(Text *t, const char *voice) {
    t->buf = NULL;
    t->len = 0;
    t->f = open_memstream(&t->buf, &t->len);
    assert_non_null(t->f);
    fprintf(t->f, ".voice %s\n.rate %g\n.input in\nI1 0 in in\n", voice, FS);
}

/* Ends the text with a probe and writes it to the temporary folder:
 * returns its path (arena). */
static const char *text_end(Text *t, const char *file) {
    fprintf(t->f, ".output vin v(in)\n");
    assert_int_equal(fclose(t->f), 0);
    const char *path = arena_strdup(tl_write_file(tmpdir, file, t->buf));
    free(t->buf);
    return path;
}

/* R1 in n1 1, R2 n1 n2 2, ... RN n(N-1) 0 N: N(N+1)/2 ohms, exactly. */
static const char *chain_netlist(void) {
    Text t;
    text_begin(&t, "chain");
    for (int k = 1; k <= N; k++)
        fprintf(t.f, "R%d %s%.0d %s%.0d %d\n", k, k == 1 ? "in" : "n", k == 1 ? 0 : k - 1, k == N ? "0" : "n",
                k == N ? 0 : k, k);
    return text_end(&t, "chain.wdn");
}

static double ladder_R(int k) { return 100 + k % 7; }
static double ladder_C(int k) { return (1 + k % 5) * 1e-6; }

/* Rk n(k-1) nk, Ck nk 0, k = 1 .. N/2 (n0 = in). */
static const char *ladder_netlist(double *want) {
    Text t;
    text_begin(&t, "ladder");
    int m = N / 2;
    for (int k = 1; k <= m; k++) {
        if (k == 1)
            fprintf(t.f, "R1 in n1 %.17g\n", ladder_R(k));
        else
            fprintf(t.f, "R%d n%d n%d %.17g\n", k, k - 1, k, ladder_R(k));
        fprintf(t.f, "C%d n%d 0 %.17g\n", k, k, ladder_C(k));
    }
    /* from the far end: Z = R_m + Rc_m, then Z = R_k + (Rc_k || Z) */
    double z = ladder_R(m) + 1 / (2 * FS * ladder_C(m));
    for (int k = m - 1; k >= 1; k--) {
        double rc = 1 / (2 * FS * ladder_C(k));
        z = ladder_R(k) + rc * z / (rc + z);
    }
    *want = z;
    return text_end(&t, "ladder.wdn");
}

typedef struct Tree {
    FILE *f;
    int nelem, nnode, nadapt;
} Tree;

/* size elements between nodes a and b: halves in series (through a new
 * node) or in parallel, the two alternating by level, so no adaptor
 * flattens into its parent; returns their resistance. */
static double tree(Tree *t, const char *a, const char *b, int size, int series) {
    if (size == 1) {
        int k = ++t->nelem;
        double v[3] = {10 + k % 90, (1 + k % 3) * 1e-6, (1 + k % 4) * 1e-3};
        fprintf(t->f, "%c%d %s %s %.17g\n", "RCL"[k % 3], k, a, b, v[k % 3]);
        return k % 3 == 0 ? v[0] : k % 3 == 1 ? 1 / (2 * FS * v[1]) : 2 * FS * v[2];
    }
    t->nadapt++;
    int h = size / 2;
    if (!series)
        return 1 / (1 / tree(t, a, b, h, 1) + 1 / tree(t, a, b, size - h, 1));
    char m[32];
    snprintf(m, sizeof m, "m%d", ++t->nnode);
    double ra = tree(t, a, m, h, 0);
    return ra + tree(t, m, b, size - h, 0);
}

static const char *tree_netlist(double *want, int *nadapt) {
    Text t;
    text_begin(&t, "sptree");
    Tree tr = {.f = t.f};
    *want = tree(&tr, "in", "0", N, 1);
    *nadapt = tr.nadapt;
    return text_end(&t, "tree.wdn");
}

/* ---- compiling ---- */

/* Loads, builds and checks the netlist at path, as bin/wdc does; fails
 * the test with the diagnostics if any stage refuses it. */
static Wdf *compile(const char *path) {
    Circuit *c = wdc_load(path);
    if (!c)
        fail_msg("%s: not loaded", path);
    jmp_buf jb;
    jmp_buf *saved = diag.jmp;
    Wdf *volatile w = NULL;
    diag.jmp = &jb;
    if (!setjmp(jb)) {
        w = wdf_build(c, FS);
        double err = scatter_check(w, 1e-9);
        assert_true(err <= 1e-9);
    }
    diag.jmp = saved;
    if (!w)
        fail_msg("%s: no adaptor tree", path);
    return w;
}

/* One root: a port holding every element but the current source I1 (the
 * first element), and that source. */
static const WNode *single_port(const Wdf *w) {
    assert_int_equal(w->nroots, 1);
    const Root *r = &w->roots[0];
    assert_int_equal(r->nport, 1);
    assert_int_equal(r->nedge, 2);
    assert_int_equal(r->edge[1].kind, 2);
    assert_int_equal(r->edge[1].elem, 0);
    for (int i = 1; i < w->c->nelems; i++)
        assert_non_null(w->leaf_of[i]);
    /* post-order: children numbered before their parents */
    for (int i = 0; i < w->nnodes; i++)
        for (int k = 0; k < w->nodes[i]->nchild; k++)
            assert_true(w->nodes[i]->child[k]->id < i);
    return r->edge[0].node;
}

static void assert_rel_near(double got, double want, double tol) {
    if (!(fabs(got - want) <= tol * fabs(want)))
        fail_msg("%.17g, expected %.17g (relative error %.3g)", got, want, fabs(got - want) / fabs(want));
}

/* Emits the voice into a folder of its own; its C file must be there. */
static void emit_into(const Wdf *w, const char *sub) {
    const char *dir = format("%s/%s", tmpdir, sub);
    assert_int_equal(mkdir(dir, 0777), 0);
    EmitOpts eo = {.outdir = dir, .table = 256, .tol = 1e-9, .maxit = 50};
    assert_int_equal(emit_voice(w, &eo), 0);
    struct stat st;
    assert_int_equal(stat(format("%s/%s.c", dir, w->c->name), &st), 0);
    assert_true(st.st_size > 1000L * N / 10);
}

/* ---- the tests ---- */

static void test_chain(void **state) {
    (void)state;
    const Wdf *w = compile(chain_netlist());
    assert_int_equal(w->c->nelems, N + 1);
    const WNode *top = single_port(w);
    /* one series adaptor of all N resistors, in order, all one way */
    assert_int_equal(w->nnodes, N + 1);
    assert_int_equal(top->kind, W_SERIES);
    assert_int_equal(top->nchild, N);
    for (int k = 0; k < N; k++) {
        assert_int_equal(top->child[k]->kind, W_LEAF);
        assert_int_equal(top->child[k]->elem, k + 1);
        assert_int_equal(top->pol[k], top->pol[0]);
        assert_ptr_equal(top->child[k]->parent, top);
    }
    assert_true(top->R == (double)N * (N + 1) / 2);
}

static void test_ladder(void **state) {
    (void)state;
    double want;
    const Wdf *w = compile(ladder_netlist(&want));
    assert_int_equal(w->c->nelems, N + 1);
    const WNode *top = single_port(w);
    /* alternating series (R, rest) and parallel (C, rest): N - 1 two-ports */
    assert_int_equal(w->nnodes, N + N - 1);
    for (int i = 0; i < w->nnodes; i++)
        assert_true(w->nodes[i]->kind == W_LEAF || w->nodes[i]->nchild == 2);
    assert_rel_near(top->R, want, 1e-12);
    emit_into(w, "ladder");
}

static void test_tree(void **state) {
    (void)state;
    double want;
    int nadapt;
    const Wdf *w = compile(tree_netlist(&want, &nadapt));
    assert_int_equal(w->c->nelems, N + 1);
    const WNode *top = single_port(w);
    assert_int_equal(nadapt, N - 1);
    assert_int_equal(w->nnodes, N + nadapt);
    assert_rel_near(top->R, want, 1e-12);
    emit_into(w, "tree");
}

/* Runs scatter_check on w in a child process after damage(w): its exit
 * status (3 for the internal error that a wrong adaptor is). */
static int check_damaged(Wdf *w, void (*damage)(Wdf *w)) {
    fflush(NULL);
    pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        if (!freopen("/dev/null", "w", stderr))
            _exit(4);
        damage(w);
        scatter_check(w, 1e-9);
        _exit(0);
    }
    int st;
    assert_int_equal(waitpid(pid, &st, 0), pid);
    return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

static WNode *top_of(Wdf *w) { return w->roots[0].edge[0].node; }
static void nothing(Wdf *w) { (void)w; }
static void up_port_off(Wdf *w) { top_of(w)->R *= 1 + 1e-6; }
static void child_off(Wdf *w) { top_of(w)->child[N / 2]->R *= 1.5; }
static void pol_two(Wdf *w) { top_of(w)->pol[N / 3] = 2; }
static void pol_zero(Wdf *w) { top_of(w)->pol[N / 2 + 1] = 0; }
static void nan_child(Wdf *w) { top_of(w)->child[3]->R = NAN; }

static void test_check_catches_wrong_adaptors(void **state) {
    (void)state;
    Wdf *w = compile(chain_netlist());
    assert_int_equal(check_damaged(w, nothing), 0);
    assert_int_equal(check_damaged(w, up_port_off), 3);
    assert_int_equal(check_damaged(w, child_off), 3);
    assert_int_equal(check_damaged(w, pol_two), 3);
    assert_int_equal(check_damaged(w, pol_zero), 3);
    assert_int_equal(check_damaged(w, nan_child), 3);
}

/* ---- expansion limits ---- */

/* The first line printed loading text as "t.wdn", which must fail, is
 * exactly want. */
static void expect_error(const char *text, const char *want) {
    const char *got;
    if (tl_netlist_load(text, &got))
        fail_msg("netlist accepted, expected: %s", want);
    if (strcmp(got, want))
        fail_msg("expected: %s\n     got: %s", want, got);
}

/* Blocks b0 .. b<levels-1>: b0 holds ten resistors, each b<k> ten
 * instances of b<k-1> (10^(k+1) elements). */
static void tens(FILE *f, int levels) {
    fprintf(f, ".block b0 x y\n");
    for (int i = 0; i < 10; i++)
        fprintf(f, "R%d x y 1k\n", i);
    fprintf(f, ".endblock\n");
    for (int k = 1; k < levels; k++) {
        fprintf(f, ".block b%d x y\n", k);
        for (int i = 0; i < 10; i++)
            fprintf(f, "use b%d u%d x y\n", k - 1, i);
        fprintf(f, ".endblock\n");
    }
}

static void test_expansion_limit(void **state) {
    (void)state;
    char *text;
    size_t len;
    /* one instance past the limit alone: line 87 is the use */
    FILE *f = open_memstream(&text, &len);
    tens(f, 7);
    fprintf(f, ".input in\nV1 a 0 in R=50\nuse b6 big a 0\n");
    fclose(f);
    expect_error(text, "t.wdn:87:5: error: instance 'big' of block 'b6' expands to more than 1000000 elements, "
                       "the most a netlist may hold");
    free(text);
    /* instances within the limit, until one crosses it with what came before */
    f = open_memstream(&text, &len);
    tens(f, 6);
    fprintf(f, ".input in\nV1 a 0 in R=50\nuse b2 small a 0\nuse b5 big a 0\n");
    fclose(f);
    expect_error(text, "t.wdn:76:5: error: instance 'big' of block 'b5' adds 1000000 elements to the 1001 before "
                       "it: more than the 1000000 a netlist may hold");
    free(text);
    /* 2^40 elements from 40 blocks: refused before any is made */
    f = open_memstream(&text, &len);
    fprintf(f, ".block d0 x y\nR1 x y 1k\nR2 x y 2k\n.endblock\n");
    for (int k = 1; k < 40; k++)
        fprintf(f, ".block d%d x y\nuse d%d p x y\nuse d%d q x y\n.endblock\n", k, k - 1, k - 1);
    fprintf(f, ".input in\nV1 a 0 in R=50\nuse d39 all a 0\n");
    fclose(f);
    expect_error(text, "t.wdn:163:5: error: instance 'all' of block 'd39' expands to more than 1000000 elements, "
                       "the most a netlist may hold");
    free(text);
}

static void test_nesting_limit(void **state) {
    (void)state;
    char *text;
    size_t len;
    /* c0 uses c1 ... uses c69: the instance of c64 inside c63 is the 65th level */
    FILE *f = open_memstream(&text, &len);
    for (int k = 0; k < 70; k++) {
        if (k < 69)
            fprintf(f, ".block c%d x y\nuse c%d i%d x y\n.endblock\n", k, k + 1, k + 1);
        else
            fprintf(f, ".block c%d x y\nR1 x y 1k\n.endblock\n", k);
    }
    fprintf(f, ".input in\nV1 a 0 in R=50\nuse c0 top a 0\n");
    fclose(f);
    expect_error(text, "t.wdn:191:5: error: instance 'i64' of block 'c64' nests instances more than 64 deep");
    free(text);
    /* 64 levels are fine */
    f = open_memstream(&text, &len);
    for (int k = 0; k < 64; k++) {
        if (k < 63)
            fprintf(f, ".block c%d x y\nuse c%d i%d x y\n.endblock\n", k, k + 1, k + 1);
        else
            fprintf(f, ".block c%d x y\nR1 x y 1k\n.endblock\n", k);
    }
    fprintf(f, ".input in\nV1 a 0 in R=50\nuse c0 top a 0\n.output o v(a)\n");
    fclose(f);
    Circuit *c = wdc_load_string("t.wdn", text);
    assert_non_null(c);
    assert_int_equal(c->nelems, 2);
    free(text);
}

static void test_recursive_blocks(void **state) {
    (void)state;
    expect_error(".block a x y\nuse a self x y\n.endblock\n.input in\nV1 n 0 in R=50\nuse a top n 0\n",
                 "t.wdn:2:5: error: block 'a' uses itself");
    expect_error(".block a x y\nR1 x y 1k\nuse b one x y\n.endblock\n.block b x y\nuse a two x y\n.endblock\n"
                 ".input in\nV1 n 0 in R=50\nuse a top n 0\n",
                 "t.wdn:6:5: error: block 'a' uses itself");
    /* a cycle that the netlist never instantiates is no error */
    Circuit *c = wdc_load_string("t.wdn", ".block a x y\nuse b one x y\n.endblock\n.block b x y\nuse a two x y\n"
                                          ".endblock\n.input in\nV1 n 0 in R=50\nR1 n 0 1k\n.output o v(n)\n");
    assert_non_null(c);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_chain),
        cmocka_unit_test(test_ladder),
        cmocka_unit_test(test_tree),
        cmocka_unit_test(test_check_catches_wrong_adaptors),
        cmocka_unit_test(test_expansion_limit),
        cmocka_unit_test(test_nesting_limit),
        cmocka_unit_test(test_recursive_blocks),
    };
    return cmocka_run_group_tests(tests, make_tmpdir, remove_tmpdir);
}
