/*
 * test_complex.c - simplicial complexes heard through their waves
 * (runtime/cx.h): waves against the paper's definition (Figure 5,
 * links of closed stars, computed naively) and against graph distance;
 * the splits that tell a torus from a sphere and a hollow thickened torus
 * from a solid one (Figure 4); components of a disjoint union; the
 * partials of a render against the frequency formula and the durations
 * against the bottom-up rule; linear time; a scene with a complex; the
 * reader's errors with their positions, and the reader fuzzed.
 *
 * The complexes are generated here: grids on a torus and a Klein bottle,
 * an octahedral sphere, Kuhn-triangulated 3-dimensional grids (a
 * 3-torus, thickened tori hollow and solid), the boundary of the
 * 4-dimensional cross-polytope (a 3-sphere), random complexes.
 */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>

#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>
#ifdef __GLIBC__
#include <malloc.h>
#endif

#include "cx.h"
#include "partials.h"
#include "testlib.h"

static char g_dir[64];

static int setup(void **s) {
    (void)s;
    return tl_temp_dir(g_dir, "wdrt-complex");
}

static int teardown(void **s) {
    (void)s;
    tl_remove_dir(g_dir);
    return 0;
}

static const char *write_file(const char *name, const char *text) { return tl_write_file(g_dir, name, text); }

/* ---- facet lists ---- */

typedef struct flist {
    int nf, nl;
    int *fo;
    long *lab;
    int ncoord;
    double *xyz; /* coordinates by label (labels 0..maxlab), or NULL */
    long maxlab;
} flist;

static void fl_init(flist *F) {
    memset(F, 0, sizeof *F);
    F->fo = malloc(sizeof *F->fo);
    F->fo[0] = 0;
}

static void fl_add(flist *F, int n, const long *v) {
    F->fo = realloc(F->fo, sizeof *F->fo * (size_t)(F->nf + 2));
    F->lab = realloc(F->lab, sizeof *F->lab * (size_t)(F->nl + n));
    for (int i = 0; i < n; i++)
        F->lab[F->nl++] = v[i], F->maxlab = v[i] > F->maxlab ? v[i] : F->maxlab;
    F->fo[++F->nf] = F->nl;
}

static void fl_free(flist *F) {
    free(F->fo), free(F->lab), free(F->xyz);
}

static cx_complex *fl_complex(const flist *F) {
    char err[256];
    cx_complex *K = cx_from_facets(F->nf, F->fo, F->lab, err, sizeof err);
    if (!K)
        fail_msg("cx_from_facets: %s", err);
    return K;
}

/* A disjoint copy of G's facets, labels shifted by `shift`. */
static void fl_union(flist *F, const flist *G, long shift) {
    for (int f = 0; f < G->nf; f++) {
        long v[CX_MAX_VERTS];
        int n = G->fo[f + 1] - G->fo[f];
        for (int i = 0; i < n; i++)
            v[i] = G->lab[G->fo[f] + i] + shift;
        fl_add(F, n, v);
    }
}

/* ---- generators ---- */

static long wrap(long i, long n) { return ((i % n) + n) % n; }

/* An a x b grid on the torus (a, b >= 3), two triangles a square;
 * vertex (i, j) is label 1 + i b + j, at the point of a torus of radii
 * 2 and 0.8 when coords. */
static void torus(flist *F, int a, int b, int coords) {
    fl_init(F);
    for (long i = 0; i < a; i++)
        for (long j = 0; j < b; j++) {
            long p = 1 + i * b + j, q = 1 + wrap(i + 1, a) * b + j, r = 1 + wrap(i + 1, a) * b + wrap(j + 1, b),
                 s = 1 + i * b + wrap(j + 1, b);
            long t1[3] = {p, q, r}, t2[3] = {p, s, r};
            fl_add(F, 3, t1), fl_add(F, 3, t2);
        }
    if (!coords)
        return;
    F->ncoord = 3;
    F->xyz = calloc((size_t)(F->maxlab + 1) * 3, sizeof(double));
    for (long i = 0; i < a; i++)
        for (long j = 0; j < b; j++) {
            double u = 2 * M_PI * i / a, v = 2 * M_PI * j / b, *x = F->xyz + (1 + i * b + j) * 3;
            x[0] = (2 + 0.8 * cos(v)) * cos(u), x[1] = (2 + 0.8 * cos(v)) * sin(u), x[2] = 0.8 * sin(v);
        }
}

/* An a x b grid on the Klein bottle: across j's seam, i is mirrored. */
static long klein_v(long i, long j, int a, int b) {
    if (j >= b)
        i = a - 1 - i, j -= b;
    return 1 + wrap(i, a) * b + j;
}

static void klein(flist *F, int a, int b) {
    fl_init(F);
    for (long i = 0; i < a; i++)
        for (long j = 0; j < b; j++) {
            long p = klein_v(i, j, a, b), q = klein_v(i + 1, j, a, b), r = klein_v(i + 1, j + 1, a, b),
                 s = klein_v(i, j + 1, a, b);
            long t1[3] = {p, q, r}, t2[3] = {p, s, r};
            fl_add(F, 3, t1), fl_add(F, 3, t2);
        }
}

/* The octahedral sphere |x| + |y| + |z| = m, each face of the octahedron
 * cut into m^2 triangles; label 1 + index of (x, y, z) in a cube. */
static long oct_v(int x, int y, int z, int m) { return 1 + ((long)(x + m) * (2 * m + 1) + (y + m)) * (2 * m + 1) + (z + m); }

static void sphere(flist *F, int m) {
    fl_init(F);
    for (int oct = 0; oct < 8; oct++) {
        int sx = oct & 1 ? -1 : 1, sy = oct & 2 ? -1 : 1, sz = oct & 4 ? -1 : 1;
        for (int i = 0; i < m; i++)
            for (int j = 0; i + j < m; j++) {
                int k = m - i - j; /* (i, j, k) barycentric, up-triangle then down */
                long t[3] = {oct_v(sx * i, sy * j, sz * k, m), oct_v(sx * (i + 1), sy * j, sz * (k - 1), m),
                             oct_v(sx * i, sy * (j + 1), sz * (k - 1), m)};
                fl_add(F, 3, t);
                if (i + j + 1 < m) {
                    long u[3] = {oct_v(sx * (i + 1), sy * j, sz * (k - 1), m),
                                 oct_v(sx * i, sy * (j + 1), sz * (k - 1), m),
                                 oct_v(sx * (i + 1), sy * (j + 1), sz * (k - 2), m)};
                    fl_add(F, 3, u);
                }
            }
    }
}

/* A grid of n[0] x n[1] x n[2] cubes, each cut into six tetrahedra along
 * its main diagonal (Kuhn); an axis with per[a] wraps around (n >= 3),
 * one without has n + 1 layers of points. */
static long grid_v(const int *p, const int *n, const int *per) {
    long id = 0;
    for (int a = 0; a < 3; a++) {
        int m = per[a] ? n[a] : n[a] + 1;
        id = id * m + (per[a] ? wrap(p[a], m) : p[a]);
    }
    return 1 + id;
}

static void grid3(flist *F, const int *n, const int *per) {
    static const int perm[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
    fl_init(F);
    for (int i = 0; i < n[0]; i++)
        for (int j = 0; j < n[1]; j++)
            for (int k = 0; k < n[2]; k++)
                for (int q = 0; q < 6; q++) {
                    int p[3] = {i, j, k};
                    long t[4];
                    t[0] = grid_v(p, n, per);
                    for (int s = 0; s < 3; s++)
                        p[perm[q][s]]++, t[s + 1] = grid_v(p, n, per);
                    fl_add(F, 4, t);
                }
}

/* The boundary of the cross-polytope in 4 dimensions: a 3-sphere of 8
 * vertices (+e_i is 2i + 1, -e_i is 2i + 2) and 16 tetrahedra. */
static void sphere3(flist *F) {
    fl_init(F);
    for (int signs = 0; signs < 16; signs++) {
        long t[4];
        for (int i = 0; i < 4; i++)
            t[i] = 2 * i + 1 + ((signs >> i) & 1);
        fl_add(F, 4, t);
    }
}

/* A random complex: nf facets of 2 to dmax + 1 vertices among n. */
static void random_complex(flist *F, tl_rng *r, int n, int nf, int dmax) {
    fl_init(F);
    for (int f = 0; f < nf; f++) {
        int k = 2 + (int)(tl_rng_next(r) % (uint64_t)dmax);
        long v[CX_MAX_VERTS];
        for (int i = 0; i < k; i++) {
            int again;
            do {
                v[i] = 1 + (long)(tl_rng_next(r) % (uint64_t)n);
                again = 0;
                for (int j = 0; j < i; j++)
                    again |= v[j] == v[i];
            } while (again);
        }
        /* skip a facet listed already (the same set in any order) */
        int dup = 0;
        for (int g = 0; g < F->nf && !dup; g++) {
            int m = F->fo[g + 1] - F->fo[g], same = m == k;
            for (int i = 0; i < k && same; i++) {
                int in = 0;
                for (int j = 0; j < m; j++)
                    in |= F->lab[F->fo[g] + j] == v[i];
                same = in;
            }
            dup = same;
        }
        if (!dup)
            fl_add(F, k, v);
    }
}

/* ---- waves by the definition ---- */

static int lev(const cx_tree *T, int level, const cx_complex *K, int s) {
    return T->nodeof[(size_t)(level - T->leaf) * (size_t)K->nv + (size_t)K->vert[K->off[s]]];
}

/* The closure of the simplices marked in x (faces marked too). */
static void closure(const cx_complex *K, char *x) {
    for (int d = K->dim; d >= 1; d--)
        for (int s = K->nv; s < K->ns; s++)
            if (x[s] && cx_dim(K, s) == d)
                for (int j = K->off[s]; j < K->off[s + 1]; j++)
                    x[K->face[j]] = 1;
}

/* The waves of the complex inW from u by the paper's Figure 5: L' the
 * star of what is reached, L'' its closure, the wave L'' - L'.  wave[s]
 * gets each simplex's wave (-1: none); returns the number of waves. */
static int naive_waves(const cx_complex *K, const char *inW, int u, int *wave) {
    char *star = calloc((size_t)K->ns, 1), *cl = calloc((size_t)K->ns, 1);
    for (int s = 0; s < K->ns; s++)
        wave[s] = -1;
    wave[u] = 0;
    cl[u] = 1; /* wave 0, the start, is what is reached first */
    int i = 0;
    for (;;) {
        int any = 0;
        for (int s = 0; s < K->ns; s++) { /* L' = star(L'') */
            star[s] = 0;
            for (int j = K->off[s]; inW[s] && j < K->off[s + 1] && !star[s]; j++)
                star[s] = cl[K->vert[j]];
        }
        memcpy(cl, star, (size_t)K->ns);
        closure(K, cl);
        i++;
        for (int s = 0; s < K->ns; s++)
            if (cl[s] && !star[s])
                wave[s] = i, any = 1;
        if (!any)
            break;
    }
    free(star), free(cl);
    return i;
}

/* Components of wave i's 1-skeleton by a plain search: comp[v] gets
 * the lowest vertex of v's component. */
static void naive_components(const cx_complex *K, const int *wave, int i, int *comp) {
    for (int v = 0; v < K->nv; v++)
        comp[v] = wave[v] == i ? v : -1;
    for (int changed = 1; changed;) {
        changed = 0;
        for (int s = K->nv; s < K->ns; s++)
            if (wave[s] == i && cx_dim(K, s) == 1) {
                int a = K->vert[K->off[s]], b = K->vert[K->off[s] + 1], m = comp[a] < comp[b] ? comp[a] : comp[b];
                changed |= comp[a] != m || comp[b] != m;
                comp[a] = comp[b] = m;
            }
    }
}

/* Node W against the definition, and its children recursively. */
static void check_node(const cx_complex *K, const cx_tree *T, int W) {
    const cx_node *n = &T->node[W];
    char *inW = calloc((size_t)K->ns, 1);
    int nv = 0, ns = 0;
    for (int s = 0; s < K->ns; s++)
        if (T->lowest[s] <= n->level && lev(T, n->level, K, s) == W)
            inW[s] = 1, ns++, nv += cx_dim(K, s) == 0;
    assert_int_equal(nv, n->nverts);
    assert_int_equal(ns, n->nsimp);
    if (n->level == T->leaf) {
        free(inW);
        return;
    }
    int *wave = malloc(sizeof *wave * (size_t)K->ns), *comp = malloc(sizeof *comp * (size_t)K->nv);
    int nw = naive_waves(K, inW, n->start, wave);
    assert_int_equal(nw, n->nwaves);
    for (int s = 0; s < K->ns; s++) {
        int tw = inW[s] && T->lowest[s] <= n->level - 1 ? T->node[lev(T, n->level - 1, K, s)].wave : -1;
        if (tw != (inW[s] ? wave[s] : -1))
            fail_msg("level %d node %d: simplex %d in wave %d by the tree, %d by the definition", n->level, W, s, tw,
                     wave[s]);
    }
    for (int c = 0; c < n->nchild; c++) {
        const cx_node *k = &T->node[n->first + c];
        assert_int_equal(k->parent, W);
        naive_components(K, wave, k->wave, comp);
        assert_int_equal(comp[k->start], k->start); /* starts at its lowest vertex */
        int ncomp = 0;
        for (int v = 0; v < K->nv; v++) {
            ncomp += comp[v] == v;
            if (comp[v] >= 0 && (comp[v] == k->start) != (lev(T, n->level - 1, K, v) == n->first + c))
                fail_msg("vertex %d: its component and its node disagree", v);
        }
        assert_int_equal(ncomp, k->ncomp);
        if (c > 0 && k->wave == k[-1].wave)
            assert_true(k->start > k[-1].start && k->comp == k[-1].comp + 1);
        check_node(K, T, n->first + c);
    }
    free(wave), free(comp), free(inW);
}

static void check_tree(const cx_complex *K, const cx_tree *T) {
    for (int i = 0; i < T->nnodes && T->node[i].parent < 0; i++)
        check_node(K, T, i);
}

/* The closure: every face of every facet is a simplex, found by its
 * vertices, and nothing else is. */
static void check_closure(const flist *F, const cx_complex *K) {
    int count = 0;
    char *seen = calloc((size_t)K->ns, 1);
    for (int f = 0; f < F->nf; f++) {
        int n = F->fo[f + 1] - F->fo[f];
        for (int mask = 1; mask < 1 << n; mask++) {
            int v[CX_MAX_VERTS], m = 0;
            for (int i = 0; i < n; i++)
                if (mask >> i & 1)
                    v[m++] = cx_vertex(K, F->lab[F->fo[f] + i]);
            int s = cx_find(K, v, m);
            assert_true(s >= 0);
            count += !seen[s];
            seen[s] = 1;
        }
    }
    assert_int_equal(count, K->ns);
    free(seen);
}

/* Random complexes of dimension 1 to 4 and every start vertex of some:
 * the whole tree against the definition. */
static void test_waves_definition(void **s) {
    (void)s;
    tl_rng r;
    tl_rng_seed(&r, 0xc0ffee);
    int trees = 0;
    for (int it = 0; it < 60; it++) {
        flist F;
        int n = 6 + (int)(tl_rng_next(&r) % 30), dmax = 1 + it % 4;
        random_complex(&F, &r, n, n + (int)(tl_rng_next(&r) % (uint64_t)(3 * n)), dmax);
        cx_complex *K = fl_complex(&F);
        check_closure(&F, K);
        for (int u = 0; u < K->nv; u += 1 + it % 3) {
            cx_tree *T = cx_waves(K, u);
            assert_non_null(T);
            check_tree(K, T);
            cx_tree_free(T);
            trees++;
        }
        cx_free(K);
        fl_free(&F);
    }
    print_message("definition: %d trees of random complexes agree\n", trees);
}

/* Graph distance by a plain breadth-first search over all edges. */
static void distances(const cx_complex *K, int u, int *dist) {
    for (int v = 0; v < K->nv; v++)
        dist[v] = -1;
    dist[u] = 0;
    for (int changed = 1; changed;) {
        changed = 0;
        for (int s = K->nv; s < K->ns; s++)
            if (cx_dim(K, s) == 1) {
                int a = K->vert[K->off[s]], b = K->vert[K->off[s] + 1];
                if (dist[a] >= 0 && (dist[b] < 0 || dist[b] > dist[a] + 1))
                    dist[b] = dist[a] + 1, changed = 1;
                if (dist[b] >= 0 && (dist[a] < 0 || dist[a] > dist[b] + 1))
                    dist[a] = dist[b] + 1, changed = 1;
            }
    }
}

static void check_distances(const cx_complex *K, int u) {
    cx_tree *T = cx_waves(K, u);
    int *dist = malloc(sizeof *dist * (size_t)K->nv);
    distances(K, u, dist);
    for (int v = 0; v < K->nv; v++)
        if (dist[v] >= 0 && T->leaf < T->d)
            assert_int_equal(T->node[T->nodeof[(size_t)(T->d - 1 - T->leaf) * (size_t)K->nv + (size_t)v]].wave,
                             dist[v]);
    free(dist);
    cx_tree_free(T);
}

/* The waves are the classes of graph distance from the start. */
static void test_waves_distance(void **s) {
    (void)s;
    flist F[5];
    int n3[3] = {4, 5, 3}, p3[3] = {1, 1, 0};
    torus(&F[0], 7, 11, 0), sphere(&F[1], 5), klein(&F[2], 6, 8), grid3(&F[3], n3, p3), sphere3(&F[4]);
    for (int i = 0; i < 5; i++) {
        cx_complex *K = fl_complex(&F[i]);
        check_closure(&F[i], K);
        for (int u = 0; u < K->nv; u += 1 + K->nv / 9)
            check_distances(K, u);
        cx_tree *T = cx_waves(K, 0);
        check_tree(K, T);
        cx_tree_free(T);
        cx_free(K);
        fl_free(&F[i]);
    }
}

/* ---- splits ---- */

/* The component counts of node W's waves, as a string ("11222221"). */
static void splits(const cx_tree *T, int W, char *buf, size_t cap) {
    const cx_node *n = &T->node[W];
    size_t k = 0;
    for (int c = 0; c < n->nchild && k + 2 < cap; c++) {
        const cx_node *ch = &T->node[n->first + c];
        if (ch->comp == ch->ncomp)
            buf[k++] = (char)('0' + (ch->ncomp < 9 ? ch->ncomp : 9));
    }
    buf[k] = 0;
}

/* On a long torus the 1-waves split into two components, which circle
 * the hole and join again; on a sphere, from any start, they never split
 * (the paper, section 3). */
static void test_torus_sphere(void **s) {
    (void)s;
    flist F;
    char buf[256];
    torus(&F, 5, 20, 0);
    cx_complex *K = fl_complex(&F);
    for (int u = 0; u < K->nv; u += 13) {
        cx_tree *T = cx_waves(K, u);
        splits(T, 0, buf, sizeof buf);
        size_t a = strspn(buf, "1"), b = a + strspn(buf + a, "2");
        if (!(a >= 1 && b > a + 2 && buf[b] == '1' && strspn(buf + b, "1") == strlen(buf + b)))
            fail_msg("torus from %d: components %s, not 1..2..1", u, buf);
        if (u == 0)
            print_message("torus 5x20: components of the 1-waves %s\n", buf);
        cx_tree_free(T);
    }
    cx_free(K), fl_free(&F);
    sphere(&F, 6);
    K = fl_complex(&F);
    for (int u = 0; u < K->nv; u++) {
        cx_tree *T = cx_waves(K, u);
        splits(T, 0, buf, sizeof buf);
        if (strspn(buf, "1") != strlen(buf))
            fail_msg("sphere from %d: components %s", u, buf);
        cx_tree_free(T);
    }
    print_message("sphere (%d vertices): no split from any of its vertices\n", K->nv);
    cx_free(K), fl_free(&F);
}

/* The travelling fronts (2-wave components of a 2-wave that has split
 * in two) whose own 1-waves split, over all fronts. */
static void fronts(const int *n, const int *per, int *split, int *all) {
    flist F;
    char buf[256];
    grid3(&F, n, per);
    cx_complex *K = fl_complex(&F);
    cx_tree *T = cx_waves(K, 0);
    *split = *all = 0;
    for (int c = 0; c < T->node[0].nchild; c++) {
        int W = T->node[0].first + c;
        if (T->node[W].ncomp < 2)
            continue;
        splits(T, W, buf, sizeof buf);
        (*all)++;
        *split += strchr(buf, '2') != NULL;
    }
    cx_tree_free(T), cx_free(K), fl_free(&F);
}

/* The paper's Figure 4: once a 2-wave has crossed the tube, on a hollow
 * thickened torus (torus x interval) it is an annulus, whose 1-waves
 * split; on a solid torus (disk x circle) it is a disk, whose 1-waves do
 * not. */
static void test_thickened(void **s) {
    (void)s;
    int hollow[3] = {6, 24, 1}, hper[3] = {1, 1, 0}, solid[3] = {3, 24, 3}, sper[3] = {0, 1, 0}, hs, ha, ss, sa;
    fronts(hollow, hper, &hs, &ha);
    fronts(solid, sper, &ss, &sa);
    print_message("fronts whose 1-waves split: hollow %d of %d, solid %d of %d\n", hs, ha, ss, sa);
    assert_true(ha >= 8 && sa >= 8);
    assert_int_equal(hs, ha);
    assert_int_equal(ss, 0);
}

/* A disjoint union is traversed component by component: the start's
 * first, then by lowest vertex; each as it is alone. */
static void test_union(void **s) {
    (void)s;
    flist F, G[3];
    torus(&G[0], 5, 7, 0), sphere(&G[1], 3), sphere3(&G[2]);
    fl_init(&F);
    long shift = 0, shifts[3];
    int nv[5];
    for (int i = 0; i < 3; i++) {
        fl_union(&F, &G[i], shifts[i] = shift);
        cx_complex *K = fl_complex(&G[i]);
        nv[i] = K->nv;
        cx_free(K);
        shift += G[i].maxlab + 10;
    }
    long edge[2] = {shift, shift + 1}, point[1] = {shift + 5};
    fl_add(&F, 2, edge), fl_add(&F, 1, point);
    nv[3] = 2, nv[4] = 1;
    cx_complex *K = fl_complex(&F);
    assert_int_equal(K->dim, 3);
    int start = cx_vertex(K, G[1].lab[0] + shifts[1]); /* a vertex of the sphere */
    assert_true(start >= 0);
    cx_tree *T = cx_waves(K, start);
    int order[5] = {1, 0, 2, 3, 4}, ntops = 0;
    for (int i = 0; i < T->nnodes && T->node[i].parent < 0; i++, ntops++) {
        assert_int_equal(T->node[i].comp, i + 1);
        assert_int_equal(T->node[i].ncomp, 5);
        assert_int_equal(T->node[i].nverts, nv[order[i]]);
    }
    assert_int_equal(ntops, 5);
    assert_int_equal(T->node[0].start, start);
    check_tree(K, T);
    cx_turns(K, T);
    cx_score *sc = cx_score_new(T, NULL);
    double end = 0; /* the tops follow one another */
    for (int i = 0; i < sc->nnotes; i++)
        if (sc->note[i].kind == CX_TOP) {
            assert_true(fabs(sc->note[i].on - end) < 1e-9);
            end = sc->note[i].on + sc->note[i].dur;
        }
    assert_true(fabs(end - sc->length) < 1e-9);
    cx_score_free(sc), cx_tree_free(T), cx_free(K), fl_free(&F);
    for (int i = 0; i < 3; i++)
        fl_free(&G[i]);
}

/* A flat patch of the triangular lattice: on it the combinatorial turn
 * is the geometric one (a hexagonal wave turns pi/3 at its corners, 0 at
 * the vertices between). */
static long hex_v(int q, int r, int R) { return 1 + (long)(q + R) * (2 * R + 1) + (r + R); }

static int hex_in(int q, int r, int R) { return abs(q) <= R && abs(r) <= R && abs(q + r) <= R; }

static void hex_patch(flist *F, int R) {
    fl_init(F);
    for (int q = -R; q <= R; q++)
        for (int r = -R; r <= R; r++) {
            if (hex_in(q, r, R) && hex_in(q + 1, r, R) && hex_in(q, r + 1, R)) {
                long t[3] = {hex_v(q, r, R), hex_v(q + 1, r, R), hex_v(q, r + 1, R)};
                fl_add(F, 3, t);
            }
            if (hex_in(q, r, R) && hex_in(q + 1, r - 1, R) && hex_in(q + 1, r, R)) {
                long t[3] = {hex_v(q, r, R), hex_v(q + 1, r - 1, R), hex_v(q + 1, r, R)};
                fl_add(F, 3, t);
            }
        }
    F->ncoord = 2;
    F->xyz = calloc((size_t)(F->maxlab + 1) * 2, sizeof(double));
    for (int q = -R; q <= R; q++)
        for (int r = -R; r <= R; r++)
            if (hex_in(q, r, R))
                F->xyz[hex_v(q, r, R) * 2] = q + r / 2.0, F->xyz[hex_v(q, r, R) * 2 + 1] = r * sqrt(3) / 2;
}

static void give_coords(cx_complex *K, const flist *F) {
    K->ncoord = F->ncoord;
    K->coord = malloc(sizeof(double) * (size_t)K->nv * (size_t)F->ncoord);
    for (int v = 0; v < K->nv; v++)
        memcpy(K->coord + (size_t)v * (size_t)F->ncoord, F->xyz + K->label[v] * F->ncoord,
               sizeof(double) * (size_t)F->ncoord);
}

static void test_turns(void **s) {
    (void)s;
    flist F;
    hex_patch(&F, 4);
    for (int geo = 0; geo < 2; geo++) {
        cx_complex *K = fl_complex(&F);
        if (geo)
            give_coords(K, &F);
        cx_tree *T = cx_waves(K, cx_vertex(K, hex_v(0, 0, 4)));
        cx_turns(K, T);
        const cx_node *w = &T->node[T->node[0].first];
        assert_int_equal(T->node[0].nchild, 5);
        assert_true(fabs(w[1].turn - M_PI / 3) < 1e-9); /* 6 corners */
        assert_true(fabs(w[2].turn - M_PI / 6) < 1e-9); /* 6 corners, 6 straight */
        assert_true(fabs(w[3].turn - M_PI / 9) < 1e-9); /* 6 corners, 12 straight */
        assert_true(w[0].npairs == 0 && w[0].turn == 0);
        cx_tree_free(T), cx_free(K);
    }
    fl_free(&F);
}

/* ---- sound ---- */

/* The score rendered through an engine, the source starting after `at`
 * seconds: n frames, or the score's end (and a little) when n is 0. */
static double *render(const cx_score *sc, double fs, double at, long *n) {
    cx_source src;
    cx_source_init(&src, sc, at);
    wdrt_pool_config pc = wdrt_pool_config_init(&src.cls, 1);
    pc.owned = 1, pc.bind = cx_source_bind, pc.data = &src, pc.cost_ns = 1;
    wdrt_engine_config ec = wdrt_engine_config_init(fs, 1, 1, &pc);
    wdrt_engine *e;
    assert_int_equal(wdrt_engine_init(&ec, NULL, &e), WDRT_OK);
    if (*n == 0)
        *n = (long)((at + sc->length + 0.3) * fs);
    double *y = malloc(sizeof *y * (size_t)*n);
    for (long t = 0; t < *n; t += 1000)
        wdrt_engine_process(e, y + t, (uint32_t)(*n - t < 1000 ? *n - t : 1000));
    wdrt_engine_uninit(e, NULL);
    return y;
}

static cx_score *score_of(const flist *F, double tempo, cx_complex **Kp, cx_tree **Tp) {
    cx_complex *K = fl_complex(F);
    if (F->xyz)
        give_coords(K, F);
    cx_tree *T = cx_waves(K, 0);
    cx_turns(K, T);
    cx_sound_opts o = cx_sound_opts_init();
    o.tempo = tempo;
    cx_score *sc = cx_score_new(T, &o);
    *Kp = K, *Tp = T;
    return sc;
}

/* The paper's formula, written out again. */
static double formula(int v, int n) {
    if (v == n)
        return 100;
    return 100 + 1500 * (pow(2, 4 * (1 - log(v) / log(n))) - 1) / 15;
}

/* Every partial of a render where its wave sounds alone: the group's
 * fundamental and harmonics at the formula's frequency and its
 * multiples, the whole complex at 100 Hz. */
static void test_frequencies(void **s) {
    (void)s;
    const double fs = 48000;
    flist F;
    cx_complex *K;
    cx_tree *T;
    torus(&F, 5, 20, 1);
    cx_score *sc = score_of(&F, 0.5, &K, &T);
    long n = 0;
    double *y = render(sc, fs, 0, &n), worst = 0;
    int checked = 0, harmonics = 0;
    for (int i = 0; i < sc->nnotes; i++) {
        const cx_note *nt = &sc->note[i];
        const cx_node *nd = &T->node[nt->node];
        double want = nt->kind == CX_TOP ? 100 : formula(nd->nverts, T->node[0].nverts);
        assert_true(fabs(nt->freq - want) <= 1e-9 * want);
        if (nt->kind != CX_GROUP || nd->ncomp != 1)
            continue;
        long a = (long)((nt->on + 0.05) * fs), b = (long)((nt->on + nt->dur - 0.05) * fs);
        for (int k = 1; k <= CX_HARMONICS && (k == 1 || nt->rough > 0.2); k++) {
            double f = pt_peak_freq(y + a, (size_t)(b - a), fs, 0.97 * k * want, 1.03 * k * want);
            worst = fmax(worst, fabs(f / (k * want) - 1));
            checked++, harmonics += k > 1;
        }
    }
    double f = pt_peak_freq(y, (size_t)n, fs, 90, 110);
    print_message("frequencies: %d partials (%d harmonics) within %.2g of the formula; the complex %.4f Hz\n", checked,
                  harmonics, worst, f);
    assert_true(checked >= 10 && harmonics >= 5);
    assert_true(worst < 2e-5);
    assert_true(fabs(f - 100) < 0.01);
    free(y), cx_score_free(sc), cx_tree_free(T), cx_free(K), fl_free(&F);
}

/* The bottom-up rule, written out again: a lowest node lasts a step; a
 * wave lasts until its last component ends, component c starting (c-1)
 * offsets late; a node lasts the sum of its waves. */
static double rule(const cx_tree *T, int i, double step, double off, double on, double *ons, double *durs) {
    const cx_node *n = &T->node[i];
    ons[i] = on;
    if (n->nchild == 0)
        return durs[i] = step;
    double t = 0;
    for (int c = 0; c < n->nchild;) {
        double wave = 0;
        int w = T->node[n->first + c].wave;
        for (; c < n->nchild && T->node[n->first + c].wave == w; c++) {
            const cx_node *k = &T->node[n->first + c];
            wave = fmax(wave, (k->comp - 1) * off + rule(T, n->first + c, step, off, on + t + (k->comp - 1) * off, ons, durs));
        }
        t += wave;
    }
    return durs[i] = t;
}

/* Sums of the amplitudes of each level's notes sounding at each onset
 * stay within the level's share; the render never exceeds 0.9. */
static void check_levels(const cx_score *sc, const cx_tree *T, const double *y, long n) {
    for (int i = 0; i < sc->nnotes; i++) {
        double sum[CX_MAX_VERTS + 1] = {0}, t = sc->note[i].on + 1e-6;
        for (int j = 0; j < sc->nnotes; j++)
            if (sc->note[j].on <= t && t < sc->note[j].on + sc->note[j].dur)
                sum[T->node[sc->note[j].node].level] += sc->note[j].amp;
        for (int l = T->leaf; l < T->d; l++)
            assert_true(sum[l] <= 0.7 / (T->d - T->leaf) + 1e-12);
        assert_true(sum[T->d] <= 0.2 + 1e-12);
    }
    double pk = 0;
    for (long i = 0; i < n; i++)
        pk = fmax(pk, fabs(y[i]));
    assert_true(pk <= 0.9);
}

static void check_durations(const flist *F, double tempo) {
    const double fs = 48000, at = 0.25;
    cx_complex *K;
    cx_tree *T;
    cx_score *sc = score_of(F, tempo, &K, &T);
    double *ons = malloc(sizeof(double) * (size_t)T->nnodes), *durs = malloc(sizeof(double) * (size_t)T->nnodes);
    double on = 0, step = 0.24 / tempo, off = 0.04 / tempo;
    for (int i = 0; i < T->nnodes && T->node[i].parent < 0; i++)
        on += rule(T, i, step, off, on, ons, durs);
    for (int i = 0; i < sc->nnotes; i++) {
        const cx_note *nt = &sc->note[i];
        assert_true(fabs(nt->on - ons[nt->node]) < 1e-9 && fabs(nt->dur - durs[nt->node]) < 1e-9);
    }
    assert_true(fabs(sc->length - on) < 1e-9);
    long n = 0;
    double *y = render(sc, fs, at, &n);
    long first = -1, last = -1;
    for (long i = 0; i < n; i++)
        if (y[i] != 0)
            last = i, first = first < 0 ? i : first;
    /* silent until its time; sound until the end of the last note */
    assert_true(first == (long)llround(at * fs) + 1 || first == (long)llround(at * fs));
    assert_true(last < (long)llround((at + sc->length) * fs) && last > (long)llround((at + sc->length - 0.03) * fs));
    check_levels(sc, T, y, n);
    print_message("durations: %d notes, %.3f s at tempo %g\n", sc->nnotes, sc->length, tempo);
    free(y), free(ons), free(durs), cx_score_free(sc), cx_tree_free(T), cx_free(K);
}

static void test_durations(void **s) {
    (void)s;
    flist F;
    int n[3] = {6, 12, 1}, per[3] = {1, 1, 0};
    grid3(&F, n, per); /* a 3-complex whose waves split at both levels */
    check_durations(&F, 4);
    fl_free(&F);
    torus(&F, 5, 12, 1);
    check_durations(&F, 1);
    fl_free(&F);
    klein(&F, 5, 9);
    check_durations(&F, 2);
    fl_free(&F);
}

/* The source sleeps in an engine once it has played, and a strike with
 * no targets plays it again. */
static void test_source(void **s) {
    (void)s;
    flist F;
    cx_complex *K;
    cx_tree *T;
    torus(&F, 4, 5, 0);
    cx_score *sc = score_of(&F, 4, &K, &T);
    cx_source src;
    cx_source_init(&src, sc, 0.1);
    wdrt_pool_config pc = wdrt_pool_config_init(&src.cls, 1);
    pc.owned = 1, pc.bind = cx_source_bind, pc.data = &src;
    wdrt_engine_config ec = wdrt_engine_config_init(48000, 1, 1, &pc);
    wdrt_engine *e;
    assert_int_equal(wdrt_engine_init(&ec, NULL, &e), WDRT_OK);
    long n = 48000 * 2, k = 48000 + 17;
    assert_int_equal(wdrt_engine_strike(e, (uint64_t)k, wdrt_engine_voice(e, 0, 0), 0, NULL, NULL), WDRT_OK);
    double *y = malloc(sizeof *y * (size_t)n);
    wdrt_engine_process(e, y, (uint32_t)n);
    wdrt_engine_stats st;
    wdrt_engine_get_stats(e, &st);
    long m = (long)llround(sc->length * 48000);
    for (long i = 0; i < m; i++) /* the strike's traversal is the first again */
        assert_true(fabs(y[k + i] - y[4800 + i]) < 1e-12);
    assert_true(st.sleeps == 2 && st.wakes == 1);
    assert_true(y[n - 1] == 0);
    free(y);
    wdrt_engine_uninit(e, NULL);
    cx_score_free(sc), cx_tree_free(T), cx_free(K), fl_free(&F);
}

/* Granular rendering: grains of the same sound, never louder. */
static void test_granular(void **s) {
    (void)s;
    flist F;
    cx_complex *K;
    cx_tree *T;
    torus(&F, 5, 7, 0);
    cx_score *sc = score_of(&F, 1, &K, &T);
    long n = 0, m = 0;
    double *y = render(sc, 48000, 0, &n);
    sc->granular = 1; /* sparse grains: 20 ms in every 100 */
    double *g = render(sc, 48000, 0, &m);
    long on = 0, sounding = 0;
    for (long i = 0; i < n; i++) {
        double t = fmod(i / 48000.0, 0.1);
        assert_true(fabs(g[i]) <= fabs(y[i]));
        assert_true(t < 0.0201 || fabs(g[i]) < 1e-9);
        on += fabs(g[i]) >= 1e-9, sounding += y[i] != 0;
    }
    print_message("granular: %.3f of the sound in grains\n", (double)on / sounding);
    assert_true(on > sounding * 0.17 && on < sounding * 0.205);
    free(y), free(g), cx_score_free(sc), cx_tree_free(T), cx_free(K), fl_free(&F);
}

/* ---- linear time ---- */

static double now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + ts.tv_nsec * 1e-9;
}

/* ns per simplex to build the complex from its facets and to walk its
 * whole tree of waves: the best of a few runs of at least 0.1 s, and the
 * first run alone (*cold: both together), which also pays for the first
 * touch of every page it writes. */
static void timing(const flist *F, int *ns, double *build, double *walk, double *cold, double *bsteps,
                   double *wsteps) {
    *build = *walk = *cold = 1e300;
    for (int rep = 0; rep < 3; rep++) {
        int runs = 0;
        double t0 = now(), t1, tw = 0;
        do {
            double ta = now();
            cx_complex *K = fl_complex(F);
            t1 = now();
            cx_tree *T = cx_waves(K, 0);
            tw += now() - t1;
            assert_non_null(T);
            if (rep == 0 && runs == 0)
                *cold = (now() - ta) / K->ns * 1e9;
            *bsteps = (double)K->steps / K->ns, *wsteps = (double)T->steps / K->ns;
            cx_tree_free(T);
            *ns = K->ns;
            cx_free(K);
            runs++;
        } while (now() - t0 < 0.1);
        *build = fmin(*build, ((now() - t0) - tw) / runs / *ns * 1e9);
        *walk = fmin(*walk, tw / runs / *ns * 1e9);
    }
}

/* Work per simplex stays flat from a thousand simplices to a million:
 * tori (2-complexes) and 3-tori (3-complexes, their 2-waves walked
 * again).  The work is counted (cx_complex.steps, cx_tree.steps), so the
 * test holds on a busy machine; the times are printed beside it.  From
 * ten thousand simplices to a million, the walk's steps per simplex may
 * grow by 10 % (what is not linear would grow a hundredfold), the
 * build's by 40 %: its binary searches of the labels take log2 of the
 * vertices, 11 to 17 halvings here. */
static void test_linear(void **s) {
    (void)s;
    static const int tor[4] = {13, 41, 129, 408}, cube[4] = {4, 7, 15, 33};
    int sizes = getenv("WDRT_COMPLEX_QUICK") ? 2 : 4; /* under sanitizers: the figures only */
#ifdef __GLIBC__
    /* Freed memory stays in the heap: above glibc's mmap threshold every
     * run would map fresh pages and fault on each (costly in a VM), below
     * it never -- timing the kernel, not the walk. */
    mallopt(M_MMAP_MAX, 0);
    mallopt(M_TRIM_THRESHOLD, INT_MAX);
#endif
    for (int kind = 0; kind < 2; kind++) {
        double walk[4], build[4], cold, bsteps[4], wsteps[4];
        for (int i = 0; i < sizes; i++) {
            flist F;
            int n[3] = {cube[i], cube[i], cube[i]}, per[3] = {1, 1, 1}, ns;
            if (kind == 0)
                torus(&F, tor[i], tor[i], 0);
            else
                grid3(&F, n, per);
            timing(&F, &ns, &build[i], &walk[i], &cold, &bsteps[i], &wsteps[i]);
            print_message("linear: %s of %7d simplices: build %6.1f ns, waves %5.1f ns per simplex (first run %6.1f); "
                          "steps per simplex: build %.3f, waves %.3f\n",
                          kind ? "3-torus" : "torus  ", ns, build[i], walk[i], cold, bsteps[i], wsteps[i]);
            fl_free(&F);
        }
        if (sizes == 4) {
            assert_true(wsteps[3] <= 1.1 * wsteps[1]);
            assert_true(bsteps[3] <= 1.4 * bsteps[1]);
        }
    }
#ifdef __GLIBC__
    mallopt(M_MMAP_MAX, 65536);
#endif
}

/* ---- scenes and the command line ---- */

static const char g_lutz[] = "# two of Lutz's surfaces\n"
                             "manifold_2_4_1=[[1,2,3],[1,2,4],[1,3,4],[2,3,4]]\n"
                             "coordinates\n1 1 1 1\n2 1 -1 -1\n3 -1 1 -1\n4 -1 -1 1\n\n"
                             "manifold_2_7_1=[[1,2,3],[1,2,4],[1,3,5],[1,4,6],[1,5,7],[1,6,7],[2,3,6],[2,4,7],\n"
                             "  [2,5,6],[2,5,7],[3,4,5],[3,4,7],[3,6,7],[4,5,6]]\n";

/* A complex in a scene sounds as the source alone, from its time, with
 * its gain; and sleeps once played, which ends a scene without length. */
static void test_scene(void **s) {
    (void)s;
    write_file("t.txt", g_lutz);
    const char *path = write_file("c.wds", "; a torus heard\n"
                                           "(complex a \"t.txt\" (name \"manifold_2_7_1\") (start 3) (at 0.5)\n"
                                           "         (gain 0.5) (tempo 2))\n");
    char err[4096] = "", *p = strdup(path);
    wdrt_scene *sc;
    assert_int_equal(wdrt_scene_load(p, &sc, err, sizeof err), WDRT_OK);
    assert_int_equal(wdrt_scene_nvoices(sc), 0);
    double *y, rate;
    long n;
    int nch;
    wdrt_engine_stats st;
    assert_int_equal(wdrt_scene_render(sc, NULL, &y, &n, &nch, &rate, &st), WDRT_OK);
    snprintf(err, sizeof err, "%s/t.txt", g_dir);
    cx_complex *K = cx_read_file(err, "manifold_2_7_1", err, sizeof err);
    assert_non_null(K);
    cx_tree *T = cx_waves(K, cx_vertex(K, 3));
    cx_turns(K, T);
    cx_sound_opts o = cx_sound_opts_init();
    o.tempo = 2;
    cx_score *score = cx_score_new(T, &o);
    long m = 0;
    double *ref = render(score, 48000, 0, &m);
    for (long i = 0; i < n; i++)
        assert_true(fabs(y[i] - (i < 24000 ? 0 : i - 24000 < m ? 0.5 * ref[i - 24000] : 0)) < 1e-15);
    print_message("scene: %.3f s for a traversal of %.3f s from 0.5 s; %d sleeps\n", n / rate, score->length,
                  (int)st.sleeps);
    assert_true(n / rate > 0.5 + score->length && n / rate < 0.5 + score->length + 0.3);
    assert_int_equal((int)st.sleeps, 1);
    free(y), free(ref), free(p), cx_score_free(score), cx_tree_free(T), cx_free(K);
    wdrt_scene_free(sc);
}


/* wdrt complex: the tree printed as DESIGN 6.7 says, a WAV written, and
 * the exit statuses. */
static void test_cli(void **s) {
    (void)s;
    const char *t = write_file("t.txt", g_lutz);
    char cmd[PATH_MAX * 3], out[PATH_MAX];
    snprintf(out, sizeof out, "%s/w.txt", g_dir);
    snprintf(cmd, sizeof cmd, "bin/wdrt complex %s --name manifold_2_7_1 --start 4 --waves > %s", t, out);
    assert_int_equal(tl_system(cmd), 0);
    FILE *f = fopen(out, "r");
    char text[1024] = "";
    assert_true(fread(text, 1, sizeof text - 1, f) > 0);
    fclose(f);
    assert_string_equal(text, "dim=2 wave=0 component=1 vertices=7 simplices=42 parent=0\n"
                              "dim=1 wave=0 component=1 vertices=1 simplices=1 parent=1\n"
                              "dim=1 wave=1 component=1 vertices=6 simplices=12 parent=1\n");
    snprintf(cmd, sizeof cmd, "bin/wdrt complex %s --tempo 4 --granular=0.2 -o %s/c.wav --quiet", t, g_dir);
    assert_int_equal(tl_system(cmd), 0);
    snprintf(out, sizeof out, "%s/c.wav", g_dir);
    int nch;
    double fs, *fr;
    long nf;
    assert_int_equal(wdrt_wav_read(out, &nch, &fs, &fr, &nf), WDRT_OK);
    assert_true(nch == 1 && fs == 48000 && nf == 2 * 2880 + 1); /* two 1-waves of 0.06 s */
    free(fr);
    snprintf(cmd, sizeof cmd, "bin/wdrt complex %s --start 9 2>/dev/null", t);
    assert_int_equal(tl_system(cmd), 1);
    snprintf(cmd, sizeof cmd, "bin/wdrt complex %s --tempo -1 2>/dev/null", t);
    assert_int_equal(tl_system(cmd), 2);
    /* so fast its notes vanish (a score of 0 s, silent, at 1e9) */
    snprintf(cmd, sizeof cmd, "bin/wdrt complex %s --tempo 101 2>&1 | grep -q 'at most 100'", t);
    assert_int_equal(tl_system(cmd), 0);
    /* a tempo so slow the score passes a day, or what a WAV file holds, is
     * refused before anything is rendered (0.48 s of two 1-waves at tempo 1) */
    snprintf(cmd, sizeof cmd, "bin/wdrt complex %s --tempo 1e-6 -o %s/slow.wav 2>&1 | grep -q 'more than a day'", t,
             g_dir);
    assert_int_equal(tl_system(cmd), 0);
    snprintf(cmd, sizeof cmd, "bin/wdrt complex %s --tempo 1e-5 -o %s/slow.wav 2>&1 | grep -q 'too long for a WAV file'",
             t, g_dir);
    assert_int_equal(tl_system(cmd), 0);
    snprintf(cmd, sizeof cmd, "test ! -e %s/slow.wav", g_dir);
    assert_int_equal(tl_system(cmd), 0);
    assert_int_equal(tl_system("bin/wdrt complex /nonexistent.txt 2>/dev/null"), 1);
    /* --name picks a list of a Lutz file: of a file of one complex it is an error, not ignored */
    const char *plain = write_file("plain.txt", "\xef\xbb\xbf" "1 2 3\r\n2 3 4\r\n"); /* a byte-order mark and CRLF, read */
    snprintf(cmd, sizeof cmd, "bin/wdrt complex %s --name nope 2>&1 | grep -q \"no complex named 'nope': the file "
             "holds one complex\"", plain);
    assert_int_equal(tl_system(cmd), 0);
    snprintf(cmd, sizeof cmd, "bin/wdrt complex %s -o %s/plain.wav --quiet", plain, g_dir);
    assert_int_equal(tl_system(cmd), 0);
}

/* ---- errors ---- */

typedef struct bad {
    const char *text;
    const char *name; /* the list asked for */
    const char *msg;  /* after "PATH:" */
} bad;

static const bad g_errors[] = {
    {"manifold_2_4_1=[[1,2,3],[1,2,4],[1,3,4],[2,3,5]]", NULL,
     "1:46: error: vertex 5 is out of range: manifold_2_4_1 has vertices 1 to 4"},
    {"manifold_2_4_1=[[1,2,3],[1,2,4],[1,3,4],[2,3]]", NULL, "1:41: error: a facet of manifold_2_4_1 has 2 vertices, not 3"},
    {"manifold_2_4_1=[[1,2,3],[1,2,4],[1,3,3],[2,3,4]]", NULL, "1:38: error: vertex 3 is already in this facet"},
    {"manifold_2_4_1=[[1,2,3],[1,2,4],\n  [1,3,4],[2,1,4],[2,3,4]]", NULL,
     "2:11: error: this facet is listed twice (first at 1:25)"},
    {"# five promised\nmanifold_2_5_1=[[1,2,3],[1,2,4],[1,3,4],[2,3,4]]", NULL,
     "2:1: error: vertex 5 of manifold_2_5_1 lies in no facet"},
    {"manifold_2_4_1=[[1,2,3],[1,2,4] [1,3,4]]", NULL, "1:33: error: expected ',' or ']' after a facet, found '['"},
    {"manifold_2_4_1 [[1,2,3]]", NULL, "1:16: error: expected '=' after the list's name, found '['"},
    {"manifold_2_4_1=[[1,2,x]]", NULL, "1:22: error: expected a vertex number, found 'x'"},
    {"manifold_2_4_1=[[1,2,3.5]]", NULL, "1:22: error: a vertex is a whole number from 0, not '3.5'"},
    {"manifold_2_4_1=[[1,2,3],\n", NULL, "2:1: error: expected '[' to start a facet, found the end of the file"},
    {"manifold_2_4_1=[[1;2,3]]", NULL, "1:19: error: expected ',' or ']' after a vertex, found ';'"},
    {"manifold_2_4_1=[[1,2,3]]", "manifold_2_7_1",
     "error: no complex named 'manifold_2_7_1' in this file (it holds manifold_2_4_1)"},
    {"a=[[1,2,3]]\ncoordinates\n1 0\n2 1\n3 0 1\n", NULL, "5:5: error: expected 1 coordinate, as on the first row"},
    {"1 2 3\n1 2 4\n1 2 3\n", NULL, "3:1: error: this facet is listed twice (first at 1:1)"},
    {"1 2 3\n4 -5 6\n", NULL, "2:3: error: a vertex is a whole number from 0, not '-5'"},
    {"# nothing\n", NULL, "2:1: error: the file holds no facets"},
    {"1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17\n", NULL, "1:40: error: a facet has at most 16 vertices (dimension 15)"},
    {"1 2 10000000000\n", NULL, "1:5: error: vertex number too large (at most 999999999)"},
    {"1 2 3\ncoordinates\n1 0 0\n2 1 0\n", NULL, "2:1: error: vertex 3 has no coordinates"},
    {"1 2 3\ncoordinates\n1 0 0\n2 1 0 0\n3 0 1\n", NULL, "4:7: error: expected 2 coordinates, as on the first row"},
    {"1 2 3\ncoordinates\n1 0 0\n2 1 0\n3 0 1\n4 1 1\n", NULL, "6:1: error: vertex 4 lies in no facet"},
    {"1 2 3\ncoordinates\n1 0 0\n1 1 0\n", NULL, "4:1: error: vertex 1 has coordinates already (at 3:1)"},
    {"1 2 3\ncoordinates\n1 0 1e999\n", NULL, "3:5: error: '1e999' is not a finite number"},
    {"1 2 3\ncoordinates\n1 0 nan\n", NULL, "3:5: error: expected a coordinate, found 'nan'"},
    {"1 2 3\ncoordinates please\n", NULL, "2:13: error: expected the end of the line after 'coordinates', found 'please'"},
    {"1 2 3\n2 3 \x01\n", NULL, "2:5: error: expected a vertex number, found the byte 0x01"},
    {"coordinates\n1 0\n", NULL, "3:1: error: the file holds no facets"},
};

static int valid_error(const char *path, const char *err) {
    size_t n = strlen(path);
    if (strncmp(err, path, n) != 0 || err[n] != ':')
        return 0;
    int line, col;
    char word[16];
    if (!strncmp(err + n, ": error: ", 9))
        return 1;
    return sscanf(err + n + 1, "%d:%d: %15s", &line, &col, word) == 3 && line >= 1 && col >= 1 &&
           !strcmp(word, "error:") && strchr(err, '^');
}

static void test_errors(void **s) {
    (void)s;
    for (size_t i = 0; i < sizeof g_errors / sizeof *g_errors; i++) {
        char *path = strdup(write_file("e.txt", g_errors[i].text)), err[2048] = "", want[4096];
        cx_complex *K = cx_read_file(path, g_errors[i].name, err, sizeof err);
        assert_null(K);
        snprintf(want, sizeof want, "%s:%s", path, g_errors[i].msg);
        if (g_errors[i].msg[0] == 'e')
            snprintf(want, sizeof want, "%s: %s", path, g_errors[i].msg);
        if (strncmp(err, want, strlen(want)) != 0)
            fail_msg("expected \"%s\", got \"%s\"", want, err);
        assert_true(valid_error(path, err));
        free(path);
    }
}

static const bad g_scene_errors[] = {
    {"(complex c \"t.txt\" (start 99))", NULL, "1:27: error: complex c has no vertex 99"},
    {"(complex c \"t.txt\" (start 1.5))", NULL, "1:27: error: a vertex is a whole number from 0"},
    {"(complex c \"t.txt\" (tempo 0))", NULL, "1:27: error: a tempo is a speed factor from 0.01 to 100"},
    {"(complex c \"t.txt\" (granular 2))", NULL, "1:30: error: an explosion factor lies between 0 and 1"},
    {"(complex c \"t.txt\" (pan -3))", NULL, "1:25: error: pan lies between -1 (left) and 1 (right)"},
    {"(complex c t.txt)", NULL, "1:12: error: expected the complex's file name in double quotes, found a symbol"},
    {"(complex \"t.txt\")", NULL, "1:1: error: expected (complex NAME \"file\" ...)"},
    {"(voice c \"x.wdn\")\n(complex c \"t.txt\")", NULL, "2:10: error: 'c' is already in the scene"},
    {"(complex c \"t.txt\")\n(voice c \"x.wdn\")", NULL, "2:8: error: 'c' is already in the scene"},
    {"(complex c \"t.txt\" (strat 1))", NULL, "1:21: error: unknown property 'strat'; did you mean 'start'?"},
    {"(complex c \"t.txt\" (name foo))", NULL, "1:26: error: expected the list's name in double quotes, found a symbol"},
    {"(complex c \"t.txt\")\n(at 1 (stop c))", NULL, "2:13: error: unknown voice 'c'"},
    {"(complex c \"nowhere.txt\")", NULL, "1:12: error: cannot read the complex '"},
};

static void test_scene_errors(void **s) {
    (void)s;
    write_file("t.txt", g_lutz);
    for (size_t i = 0; i < sizeof g_scene_errors / sizeof *g_scene_errors; i++) {
        char *path = strdup(write_file("e.wds", g_scene_errors[i].text)), err[2048] = "", want[4096];
        wdrt_scene *sc = NULL;
        assert_int_equal(wdrt_scene_load(path, &sc, err, sizeof err), WDRT_SYNTAX);
        snprintf(want, sizeof want, "%s:%s", path, g_scene_errors[i].msg);
        if (strncmp(err, want, strlen(want)) != 0)
            fail_msg("expected \"%s\", got \"%s\"", want, err);
        free(path);
    }
    /* errors in the complex's file are the file's own */
    write_file("bad.txt", "1 2 3\n1 2 x\n");
    const char *path = write_file("e.wds", "(complex c \"bad.txt\")");
    char err[2048], want[PATH_MAX + 64];
    wdrt_scene *sc = NULL;
    assert_int_equal(wdrt_scene_load(path, &sc, err, sizeof err), WDRT_SYNTAX);
    snprintf(want, sizeof want, "%s/bad.txt:2:5: error: expected a vertex number, found 'x'", g_dir);
    assert_true(strncmp(err, want, strlen(want)) == 0);
}

/* ---- the reader fuzzed ---- */

static const char *const g_seeds[] = {
    g_lutz,
    "# a plain file\n1 2 3\n1 2 4\n1 3 4\n2 3 4 5\n7\n\ncoordinates\n1 0 0\n2 1 0\n3 0 1\n4 1 1\n5 2 2\n7 -1 0.5e1\n",
    "manifold_3_5_1=[[1,2,3,4],[1,2,3,5],[1,2,4,5],[1,3,4,5],[2,3,4,5]]\nx_1=[[10,20],[20,30]]\n",
};

/* Mutated files: each reads and is traversed and scored, or gives a
 * positioned error; nothing crashes or hangs. */
static void fuzz(long iters, uint64_t seed) {
    tl_rng r;
    tl_rng_seed(&r, seed);
    const char *alphabet = "[],=\n #0123456789.-e_mx coordinates manifold_2_";
    char path[PATH_MAX];
    snprintf(path, sizeof path, "%s/f.txt", g_dir);
    long ok = 0, errs = 0;
    for (long it = 0; it < iters; it++) {
        const char *text = g_seeds[tl_rng_next(&r) % 3];
        char buf[4096], err[4096] = "";
        size_t n = strlen(text);
        memcpy(buf, text, n);
        for (int m = 0, muts = 1 + (int)(tl_rng_next(&r) % 6); m < muts; m++) {
            size_t at = n ? tl_rng_next(&r) % n : 0;
            int op = (int)(tl_rng_next(&r) % 4);
            char c = tl_rng_next(&r) % 8 == 0 ? (char)(tl_rng_next(&r) % 256)
                                              : alphabet[tl_rng_next(&r) % strlen(alphabet)];
            if (op == 0 && n + 1 < sizeof buf)
                memmove(buf + at + 1, buf + at, n - at), buf[at] = c, n++;
            else if (op == 1 && n > 0)
                memmove(buf + at, buf + at + 1, n - at - 1), n--;
            else if (op == 2 && n > 0)
                buf[at] = c;
            else
                n = at;
        }
        cx_complex *K = cx_parse(path, buf, n, tl_rng_next(&r) % 4 ? NULL : "x_1", err, sizeof err);
        if (!K) {
            if (!valid_error(path, err))
                fail_msg("iteration %ld: bad message \"%s\"", it, err);
            errs++;
            continue;
        }
        cx_tree *T = cx_waves(K, (int)(tl_rng_next(&r) % (uint64_t)K->nv));
        assert_non_null(T);
        cx_turns(K, T);
        cx_score *sc = cx_score_new(T, NULL);
        assert_true(sc && isfinite(sc->length) && sc->length > 0);
        for (int i = 0; i < sc->nnotes; i++)
            assert_true(isfinite(sc->note[i].rough) && sc->note[i].freq >= 100 && sc->note[i].freq <= 1600);
        cx_score_free(sc), cx_tree_free(T), cx_free(K);
        ok++;
    }
    print_message("fuzz: %ld complexes read, %ld errors reported\n", ok, errs);
}

/* Mutated scenes with complexes: each loads and renders a little, or
 * gives a positioned error (of the scene, or of the complex's file). */
static void fuzz_scenes(long iters, uint64_t seed) {
    static const char text[] = "(output stereo) (length 0.05)\n"
                               "(complex c \"t.txt\" (name \"manifold_2_7_1\") (start 3) (tempo 20) (gain 0.5)\n"
                               "         (pan 0.2) (at 0.01) (granular 0.3))\n"
                               "(complex d \"t.txt\" (tempo 9))\n";
    tl_rng r;
    tl_rng_seed(&r, seed);
    const char *alphabet = "()\" \n0123456789.-complexstartnamegranular";
    char path[PATH_MAX];
    write_file("t.txt", g_lutz);
    snprintf(path, sizeof path, "%s/f.wds", g_dir);
    long ok = 0;
    for (long it = 0; it < iters; it++) {
        char buf[1024], err[4096] = "";
        size_t n = strlen(text);
        memcpy(buf, text, n);
        for (int m = 0, muts = 1 + (int)(tl_rng_next(&r) % 3 == 0); m < muts; m++) {
            size_t at = tl_rng_next(&r) % n;
            char c = alphabet[tl_rng_next(&r) % strlen(alphabet)];
            if (tl_rng_next(&r) % 2 && n + 1 < sizeof buf)
                memmove(buf + at + 1, buf + at, n - at), buf[at] = c, n++;
            else
                buf[at] = c;
        }
        FILE *f = fopen(path, "wb");
        fwrite(buf, 1, n, f);
        fclose(f);
        wdrt_scene *sc = NULL;
        if (wdrt_scene_load(path, &sc, err, sizeof err) != WDRT_OK) {
            const char *colon = strchr(err + strlen(g_dir), ':'); /* the scene's or a complex's file */
            char file[PATH_MAX];
            snprintf(file, sizeof file, "%.*s", colon ? (int)(colon - err) : 0, err);
            if (strncmp(err, g_dir, strlen(g_dir)) || !valid_error(file, err))
                fail_msg("iteration %ld: bad message \"%s\"", it, err);
            continue;
        }
        wdrt_render_opts o = {0};
        o.seconds = 0.05;
        double *y, rate;
        long nf;
        int nch;
        assert_int_equal(wdrt_scene_render(sc, &o, &y, &nf, &nch, &rate, NULL), WDRT_OK);
        for (long i = 0; i < nf * nch; i++)
            assert_true(isfinite(y[i])); /* levels are absolute: a mutated gain may pass 1 */
        free(y);
        wdrt_scene_free(sc);
        ok++;
    }
    print_message("fuzz: %ld of %ld scenes with complexes rendered\n", ok, iters);
}

/* WDRT_FUZZ_SEED, mixed into the fuzzers' own seeds (0 without it). */
static uint64_t fuzz_seed(void) {
    const char *e = getenv("WDRT_FUZZ_SEED");
    return e ? strtoull(e, NULL, 0) : 0;
}

static void test_fuzz(void **s) {
    (void)s;
    const char *e = getenv("WDRT_FUZZ_ITERS");
    fuzz(e ? atol(e) : 20000, 0xc0311e ^ fuzz_seed());
    fuzz_scenes(e ? atol(e) / 10 : 1000, 0x5ce4e ^ fuzz_seed());
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_waves_definition), cmocka_unit_test(test_waves_distance),
        cmocka_unit_test(test_torus_sphere),     cmocka_unit_test(test_thickened),
        cmocka_unit_test(test_union),            cmocka_unit_test(test_turns),
        cmocka_unit_test(test_frequencies),      cmocka_unit_test(test_durations),
        cmocka_unit_test(test_source),           cmocka_unit_test(test_granular),
        cmocka_unit_test(test_linear),           cmocka_unit_test(test_scene),
        cmocka_unit_test(test_cli),              cmocka_unit_test(test_errors),
        cmocka_unit_test(test_scene_errors),     cmocka_unit_test(test_fuzz),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
