/*
 * complex.c - simplicial complexes: the closure of a list of facets, the
 * tree of waves (Axen and Choi, sections 4 and 5), how far each wave
 * turns, and the tree printed.  See cx.h for the model; the reader
 * is complex_read.c, the score complex_score.c.
 */
#include "cx.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

/* ---- growing arrays ---- */

typedef struct ibuf {
    int *p;
    size_t n, cap;
} ibuf;

static int ib_push(ibuf *b, int x) {
    if (b->n == b->cap) {
        size_t cap = b->cap ? b->cap * 2 : 1024;
        int *p = realloc(b->p, cap * sizeof *p);
        if (!p)
            return -1;
        b->p = p, b->cap = cap;
    }
    b->p[b->n++] = x;
    return 0;
}

/* ---- the closure of the facets ----
 *
 * Each simplex is stored once and found by a hash of its vertex tuple,
 * in the region of the table that belongs to its lowest vertex.  A
 * region is sized from the facets: half as much again as the subsets of
 * facets that start at its vertex, which bound the simplices that do, so
 * probing in it stays short whatever the degrees; and facets read in
 * order touch neighbouring regions, so the table's traffic stays in cache
 * (a hash over the whole table made a million simplices cost four times
 * as much each as ten thousand).  A new simplex looks up (or makes) its
 * boundary faces, and only the faces it made are visited in turn, so
 * every simplex is made once and looks up its k + 1 faces once: linear
 * in the number of simplices. */

typedef struct hslot {
    int id;     /* simplex + 1; 0: empty (a zeroed table is empty) */
    uint32_t h; /* its hash: most mismatches are seen without its vertices */
} hslot;

typedef struct builder {
    ibuf off, vert, face;
    hslot *slot;
    size_t *base; /* vertex v's region: slots [base[v], base[v + 1]) */
    int ns;
    int err;      /* out of memory */
    unsigned long long steps; /* the work done (cx_complex.steps) */
} builder;

static uint32_t hash_verts(const int *v, int n) {
    uint64_t h = 0x9e3779b97f4a7c15ull * (uint64_t)(n + 1);
    for (int i = 0; i < n; i++) {
        h ^= (uint32_t)v[i];
        h *= 0xff51afd7ed558ccdull;
        h ^= h >> 29;
    }
    return (uint32_t)(h ^ (h >> 32));
}

static int same_verts(const builder *b, int s, const int *v, int n) {
    int o = b->off.p[s];
    if (b->off.p[s + 1] - o != n)
        return 0;
    return memcmp(b->vert.p + o, v, sizeof *v * (size_t)n) == 0;
}

/* The regions: facet f (ids ascending) has 2^(n-1-i) subsets whose
 * lowest vertex is its i-th. */
static int make_regions(builder *b, int nv, int nf, const int *fo, const int *fv) {
    b->base = calloc((size_t)nv + 1, sizeof *b->base);
    if (!b->base)
        return -1;
    for (int f = 0; f < nf; f++)
        for (int i = fo[f], n = fo[f + 1] - fo[f]; i < fo[f + 1]; i++)
            b->base[fv[i] + 1] += (size_t)1 << (n - 1 - (i - fo[f]));
    for (int v = 0; v < nv; v++)
        b->base[v + 1] = b->base[v] + b->base[v + 1] + b->base[v + 1] / 2 + 1;
    b->steps += (unsigned long long)fo[nf] + (unsigned long long)nv;
    b->slot = calloc(b->base[nv] + 1, sizeof *b->slot);
    return b->slot ? 0 : -1;
}

/* Room for every simplex the facets can have, reserved at once: the
 * arrays never move, and pages never written are never touched. */
static int reserve(builder *b, int nv, int nf, const int *fo) {
    size_t ns = (size_t)nv + 1, nvert = (size_t)nv;
    for (int f = 0; f < nf; f++) {
        int n = fo[f + 1] - fo[f];
        ns += ((size_t)1 << n) - 1, nvert += (size_t)n << (n - 1);
    }
    if (ns > INT32_MAX / 2 || nvert > INT32_MAX / 2)
        return -1;
    b->off.p = malloc(sizeof(int) * (ns + 1)), b->off.cap = ns + 1;
    b->vert.p = malloc(sizeof(int) * nvert), b->vert.cap = nvert;
    b->face.p = malloc(sizeof(int) * nvert), b->face.cap = nvert;
    return b->off.p && b->vert.p && b->face.p ? 0 : -1;
}

/* The id of the simplex v[0..n) (ascending), made if new (*made = 1). */
static int lookup(builder *b, const int *v, int n, int *made) {
    uint32_t h = hash_verts(v, n);
    size_t lo = b->base[v[0]], size = b->base[v[0] + 1] - lo, i = (size_t)(((uint64_t)h * size) >> 32);
    hslot *q;
    *made = 0;
    b->steps += (unsigned long long)n;
    for (; (q = &b->slot[lo + i])->id > 0; i = i + 1 == size ? 0 : i + 1, b->steps++)
        if (q->h == h && same_verts(b, q->id - 1, v, n))
            return q->id - 1;
    int s = b->ns++;
    q->id = s + 1, q->h = h;
    for (int j = 0; j < n; j++)
        if (ib_push(&b->vert, v[j]) || ib_push(&b->face, -1))
            b->err = 1;
    if (ib_push(&b->off, (int)b->vert.n))
        b->err = 1;
    *made = 1;
    return s;
}

/* Makes the faces of simplex s and, depth first, theirs. */
static void close_down(builder *b, int s, ibuf *stack) {
    if (ib_push(stack, s))
        b->err = 1;
    while (stack->n && !b->err) {
        int t = stack->p[--stack->n], o = b->off.p[t], n = b->off.p[t + 1] - o;
        int v[CX_MAX_VERTS];
        if (n < 2)
            continue;
        memcpy(v, b->vert.p + o, sizeof *v * (size_t)n);
        for (int j = 0; j < n && !b->err; j++) {
            int w[CX_MAX_VERTS], m = 0, made;
            b->steps += (unsigned long long)n;
            for (int i = 0; i < n; i++)
                if (i != j)
                    w[m++] = v[i];
            int f = lookup(b, w, m, &made);
            b->face.p[o + j] = f;
            if (made && ib_push(stack, f))
                b->err = 1;
        }
    }
}

/* Cofaces: the faces inverted, as one array with offsets. */
static int make_cofaces(cx_complex *K) {
    K->cooff = calloc((size_t)K->ns + 1, sizeof *K->cooff);
    K->cof = malloc(sizeof *K->cof * ((size_t)K->off[K->ns] + 1));
    if (!K->cooff || !K->cof)
        return -1;
    for (int s = K->nv; s < K->ns; s++)
        for (int j = K->off[s]; j < K->off[s + 1]; j++)
            K->cooff[K->face[j] + 1]++;
    for (int s = 0; s < K->ns; s++)
        K->cooff[s + 1] += K->cooff[s];
    int *fill = malloc(sizeof *fill * ((size_t)K->ns + 1));
    if (!fill)
        return -1;
    memcpy(fill, K->cooff, sizeof *fill * (size_t)K->ns);
    for (int s = K->nv; s < K->ns; s++)
        for (int j = K->off[s]; j < K->off[s + 1]; j++)
            K->cof[fill[K->face[j]]++] = s;
    free(fill);
    K->steps += 2 * (unsigned long long)K->off[K->ns] + (unsigned long long)K->ns;
    return 0;
}

static void builder_free(builder *b) {
    free(b->off.p), free(b->vert.p), free(b->face.p), free(b->slot), free(b->base);
}

/* Moves what the builder made into K. */
static int finish(cx_complex *K, builder *b) {
    K->ns = b->ns;
    K->off = b->off.p, K->vert = b->vert.p, K->face = b->face.p;
    b->off.p = b->vert.p = b->face.p = NULL;
    K->dim = 0;
    for (int s = K->nv; s < K->ns; s++)
        K->dim = cx_dim(K, s) > K->dim ? cx_dim(K, s) : K->dim;
    K->steps += (unsigned long long)K->ns;
    return make_cofaces(K);
}

static int cmp_long(const void *a, const void *b) {
    long x = *(const long *)a, y = *(const long *)b;
    return x < y ? -1 : x > y;
}

/* The vertices: the distinct labels, ascending. */
static int make_vertices(cx_complex *K, int nl, const long *lab) {
    K->label = malloc(sizeof *K->label * ((size_t)nl + 1));
    if (!K->label)
        return -1;
    memcpy(K->label, lab, sizeof *lab * (size_t)nl);
    qsort(K->label, (size_t)nl, sizeof *K->label, cmp_long);
    int n = 0;
    for (int i = 0; i < nl; i++)
        if (n == 0 || K->label[n - 1] != K->label[i])
            K->label[n++] = K->label[i];
    K->nv = n;
    K->steps += (unsigned long long)nl; /* and the library's sort */
    return 0;
}

/* The vertex of label (binary search), -1 if none; *steps counts its halvings. */
static int vertex_of(const cx_complex *K, long label, unsigned long long *steps) {
    int lo = 0, hi = K->nv - 1;
    while (lo <= hi) {
        ++*steps;
        int mid = lo + (hi - lo) / 2;
        if (K->label[mid] == label)
            return mid;
        if (K->label[mid] < label)
            lo = mid + 1;
        else
            hi = mid - 1;
    }
    return -1;
}

int cx_vertex(const cx_complex *K, long label) {
    unsigned long long steps = 0;
    return vertex_of(K, label, &steps);
}

static void sort_ints(int *v, int n, unsigned long long *steps) {
    for (int i = 1; i < n; i++)
        for (int j = i; j > 0 && v[j - 1] > v[j]; j--, ++*steps) {
            int t = v[j];
            v[j] = v[j - 1], v[j - 1] = t;
        }
}

/* The facets as vertex ids, each ascending. */
static int *facet_ids(cx_complex *K, int nf, const int *fo, const long *lab) {
    int *fv = malloc(sizeof *fv * ((size_t)fo[nf] + 1));
    if (!fv)
        return NULL;
    for (int f = 0; f < nf; f++) {
        for (int i = fo[f]; i < fo[f + 1]; i++)
            fv[i] = vertex_of(K, lab[i], &K->steps);
        sort_ints(fv + fo[f], fo[f + 1] - fo[f], &K->steps);
    }
    return fv;
}

/* The facets in: *dup gets the facet listed twice (and *first the facet
 * listed before it), else -1.  listed[s]: the facet that named simplex
 * s, grown with the simplices. */
static int add_facets(builder *b, int nf, const int *fo, const int *fv, int *dup, int *first) {
    ibuf listed = {0}, stack = {0};
    for (int f = 0; f < nf && !b->err && *dup < 0; f++) {
        int made, s = lookup(b, fv + fo[f], fo[f + 1] - fo[f], &made);
        b->steps++;
        while (listed.n <= (size_t)s && !b->err)
            b->err = ib_push(&listed, -1) != 0;
        if (b->err)
            break;
        if (listed.p[s] >= 0)
            *dup = f, *first = listed.p[s];
        listed.p[s] = f;
        if (made)
            close_down(b, s, &stack);
    }
    free(listed.p);
    free(stack.p);
    return b->err ? -1 : 0;
}

static cx_complex *build(int nf, const int *fo, const long *lab, int *dup, int *first) {
    cx_complex *K = calloc(1, sizeof *K);
    int *fv = NULL;
    builder b;
    memset(&b, 0, sizeof b);
    *dup = *first = -1;
    if (!K || make_vertices(K, fo[nf], lab) || !(fv = facet_ids(K, nf, fo, lab)) || reserve(&b, K->nv, nf, fo) ||
        ib_push(&b.off, 0) || make_regions(&b, K->nv, nf, fo, fv))
        goto fail;
    for (int v = 0; v < K->nv; v++) { /* the vertex simplices take ids 0..nv-1 */
        int made;
        lookup(&b, &v, 1, &made);
    }
    if (b.err || add_facets(&b, nf, fo, fv, dup, first) || *dup >= 0 || finish(K, &b))
        goto fail;
    K->steps += b.steps;
    free(fv);
    builder_free(&b);
    return K;
fail:
    free(fv);
    builder_free(&b);
    cx_free(K);
    return NULL;
}

/* Used by the reader, which reports errors with positions. */
CX_HIDDEN cx_complex *cx_build_(int nf, const int *fo, const long *lab, int *dup, int *first);
cx_complex *cx_build_(int nf, const int *fo, const long *lab, int *dup, int *first) {
    return build(nf, fo, lab, dup, first);
}

cx_complex *cx_from_facets(int nf, const int *fo, const long *lab, char *err, size_t errlen) {
    if (err && errlen)
        err[0] = 0;
    for (int f = 0; f < nf; f++) {
        int n = fo[f + 1] - fo[f];
        if (n < 1 || n > CX_MAX_VERTS) {
            snprintf(err, errlen, "facet %d has %d vertices (1 to %d)", f, n, CX_MAX_VERTS);
            return NULL;
        }
        for (int i = fo[f]; i < fo[f + 1]; i++)
            for (int j = fo[f]; j < i; j++)
                if (lab[i] == lab[j]) {
                    snprintf(err, errlen, "facet %d holds vertex %ld twice", f, lab[i]);
                    return NULL;
                }
    }
    int dup, first;
    cx_complex *K = build(nf, fo, lab, &dup, &first);
    if (!K && dup >= 0)
        snprintf(err, errlen, "facet %d is facet %d again", dup, first);
    else if (!K)
        snprintf(err, errlen, "out of memory");
    return K;
}

void cx_free(cx_complex *K) {
    if (!K)
        return;
    free(K->path), free(K->name), free(K->label), free(K->off), free(K->vert), free(K->face);
    free(K->cooff), free(K->cof), free(K->coord);
    free(K);
}

int cx_find(const cx_complex *K, const int *v, int n) {
    int w[CX_MAX_VERTS];
    if (n < 1 || n > CX_MAX_VERTS)
        return -1;
    memcpy(w, v, sizeof *w * (size_t)n);
    unsigned long long steps = 0;
    sort_ints(w, n, &steps);
    int s = w[0];
    if (s < 0 || s >= K->nv)
        return -1;
    for (int k = 1; k < n; k++) { /* climb the cofaces one vertex at a time */
        int next = -1;
        for (int c = K->cooff[s]; c < K->cooff[s + 1] && next < 0; c++) {
            int t = K->cof[c], o = K->off[t], i = 0;
            while (i < k + 1 && K->vert[o + i] == w[i])
                i++;
            next = i == k + 1 ? t : -1;
        }
        if ((s = next) < 0)
            return -1;
    }
    return s;
}

/* ---- the tree of waves ---- */

typedef struct walker {
    const cx_complex *K;
    cx_tree *T;
    int cap;          /* nodes allocated */
    int *rng;         /* per node: where its simplices start in cur */
    int *cur, *nxt;   /* the simplices of this level's nodes, node by node */
    int *dist, *queue, *uf, *usz, *compof, *compv;
    int *slotbase, *count, *cbase, *ccount;
    unsigned long long steps; /* the work done (cx_tree.steps) */
} walker;

static int *nodeof(const walker *w, int level) { return w->T->nodeof + (size_t)(level - w->T->leaf) * (size_t)w->K->nv; }

static int find(walker *w, int x) {
    int *uf = w->uf;
    for (; uf[x] != x; w->steps++)
        x = uf[x] = uf[uf[x]];
    return x;
}

static void unite(walker *w, int a, int b) {
    a = find(w, a), b = find(w, b);
    if (a == b)
        return;
    if (w->usz[a] < w->usz[b]) {
        int t = a;
        a = b, b = t;
    }
    w->uf[b] = a;
    w->usz[a] += w->usz[b];
}

static void uf_reset(walker *w) {
    for (int v = 0; v < w->K->nv; v++)
        w->uf[v] = v, w->usz[v] = 1, w->compof[v] = 0;
    w->steps += (unsigned long long)w->K->nv;
}

static int grow_nodes(walker *w, int n) {
    if (w->T->nnodes + n <= w->cap)
        return 0;
    int cap = (w->T->nnodes + n) * 2;
    cx_node *p = realloc(w->T->node, sizeof *p * (size_t)cap);
    int *r = p ? realloc(w->rng, sizeof *r * (size_t)cap) : NULL;
    if (p)
        w->T->node = p;
    if (!r)
        return -1;
    w->rng = r, w->cap = cap;
    return 0;
}

static cx_node *new_node(walker *w, int level, int parent) {
    cx_node *n = &w->T->node[w->T->nnodes++];
    memset(n, 0, sizeof *n);
    n->level = level;
    n->parent = parent;
    n->start = -1;
    return n;
}

/* Groups the simplices of the given nodes' parents (those in cur whose
 * lowest level is at most `level`) by their node at `level`, into nxt:
 * a counting sort on the node of each simplex's first vertex. */
static void distribute(walker *w, int level, int nb, int ne, const int *from, int nfrom) {
    const cx_complex *K = w->K;
    cx_tree *T = w->T;
    const int *no = nodeof(w, level);
    for (int i = nb; i < ne; i++)
        T->node[i].nsimp = T->node[i].maxdim = 0;
    for (int i = 0; i < nfrom; i++) {
        int s = from[i];
        if (T->lowest[s] <= level)
            T->node[no[K->vert[K->off[s]]]].nsimp++;
    }
    int at = 0;
    for (int i = nb; i < ne; i++)
        w->rng[i] = at, at += T->node[i].nsimp, T->node[i].nsimp = 0;
    for (int i = 0; i < nfrom; i++) {
        int s = from[i];
        if (T->lowest[s] > level)
            continue;
        cx_node *n = &T->node[no[K->vert[K->off[s]]]];
        w->nxt[w->rng[n - T->node] + n->nsimp++] = s;
        n->maxdim = cx_dim(K, s) > n->maxdim ? cx_dim(K, s) : n->maxdim;
    }
    int *t = w->cur;
    w->cur = w->nxt, w->nxt = t;
    w->steps += 2 * (unsigned long long)nfrom + 2 * (unsigned long long)(ne - nb);
}

/* The tops: the complex's components, the start's first, then by their
 * lowest vertex. */
static int tops(walker *w, int start) {
    const cx_complex *K = w->K;
    cx_tree *T = w->T;
    int d = T->d, nc = 0, *no = nodeof(w, d);
    uf_reset(w);
    for (int s = K->nv; s < K->ns; s++)
        if (cx_dim(K, s) == 1)
            unite(w, K->vert[K->off[s]], K->vert[K->off[s] + 1]);
    if (K->nv)
        w->compof[find(w, start)] = ++nc;
    for (int v = 0; v < K->nv; v++)
        if (!w->compof[find(w, v)])
            w->compof[find(w, v)] = ++nc;
    if (grow_nodes(w, nc))
        return -1;
    for (int c = 0; c < nc; c++) {
        cx_node *n = new_node(w, d, -1);
        n->comp = c + 1, n->ncomp = nc;
    }
    for (int v = 0; v < K->nv; v++) {
        cx_node *n = &T->node[no[v] = w->compof[find(w, v)] - 1];
        n->nverts++;
        if (n->start < 0)
            n->start = n->comp == 1 ? start : v;
    }
    for (int s = 0; s < K->ns; s++)
        w->cur[s] = s, T->lowest[s] = (signed char)d;
    w->steps += 2 * (unsigned long long)K->ns + 2 * (unsigned long long)K->nv + (unsigned long long)nc;
    distribute(w, d, 0, nc, w->cur, K->ns);
    return 0;
}

/* Breadth first from the node's start over its edges: the distances of
 * its vertices, which are their waves.  Returns the number of waves. */
static int bfs(walker *w, int W, int level) {
    const cx_complex *K = w->K;
    const signed char *low = w->T->lowest;
    int head = 0, tail = 0, u = w->T->node[W].start;
    w->dist[u] = 0;
    w->queue[tail++] = u;
    while (head < tail) {
        int x = w->queue[head++];
        for (int c = K->cooff[x]; c < K->cooff[x + 1]; c++, w->steps++) {
            int e = K->cof[c], o = K->off[e];
            if (low[e] > level || cx_dim(K, e) != 1)
                continue;
            int y = K->vert[o] == x ? K->vert[o + 1] : K->vert[o];
            if (w->dist[y] < 0)
                w->dist[y] = w->dist[x] + 1, w->queue[tail++] = y;
        }
    }
    return w->dist[w->queue[tail - 1]] + 1;
}

/* Node W's waves, one level down: its vertices, and every face of one
 * of its simplices opposite that simplex's only vertex at the lowest
 * distance (the link of the contracted ball); then the waves' edges
 * join their components. */
static void mark_waves(walker *w, int W, int level) {
    const cx_complex *K = w->K;
    signed char *low = w->T->lowest;
    const int *sl = w->cur + w->rng[W];
    int n = w->T->node[W].nsimp;
    for (int i = 0; i < n; i++) {
        int s = sl[i], o = K->off[s], k = K->off[s + 1] - o;
        if (k == 1) {
            low[s] = (signed char)(level - 1);
            continue;
        }
        int m = w->dist[K->vert[o]], at = 0, cnt = 0;
        w->steps += (unsigned long long)k;
        for (int j = 0; j < k; j++) {
            int dj = w->dist[K->vert[o + j]];
            if (dj < m)
                m = dj, at = j, cnt = 1;
            else if (dj == m)
                cnt++, at = cnt == 1 ? j : at;
        }
        if (k >= 3 && cnt == 1)
            low[K->face[o + at]] = (signed char)(level - 1);
    }
    w->steps += 2 * (unsigned long long)n;
    for (int i = 0; i < n; i++) {
        int s = sl[i], o = K->off[s];
        if (K->off[s + 1] - o == 2 && low[s] == level - 1)
            unite(w, K->vert[o], K->vert[o + 1]);
    }
}

/* Numbers the components of every wave of this level by their lowest
 * vertex, in one pass over the vertices in order, and makes their
 * nodes; returns the number of new nodes, or -1. */
static int make_children(walker *w, int pb, int pe, int level) {
    const cx_complex *K = w->K;
    cx_tree *T = w->T;
    int *up = nodeof(w, level + 1), *no = nodeof(w, level), nslots = 0;
    for (int W = pb; W < pe; W++)
        w->slotbase[W - pb] = nslots, nslots += T->node[W].nwaves;
    memset(w->count, 0, sizeof *w->count * (size_t)(nslots + 1));
    for (int v = 0; v < K->nv; v++) {
        int slot = w->slotbase[up[v] - pb] + w->dist[v], r = find(w, v);
        if (!w->compof[r])
            w->compof[r] = ++w->count[slot];
        w->compv[v] = w->compof[r];
    }
    int total = 0;
    for (int sl = 0; sl < nslots; sl++)
        w->cbase[sl] = T->nnodes + total, total += w->count[sl];
    if (grow_nodes(w, total))
        return -1;
    for (int W = pb; W < pe; W++) {
        cx_node *p = &T->node[W];
        int b = w->slotbase[W - pb];
        p->first = w->cbase[b];
        for (int wv = 0; wv < p->nwaves; wv++)
            for (int c = 1; c <= w->count[b + wv]; c++) {
                cx_node *n = new_node(w, level, W);
                n->wave = wv, n->comp = c, n->ncomp = w->count[b + wv];
            }
        p->nchild = T->nnodes - p->first;
    }
    w->steps += 2 * (unsigned long long)K->nv + (unsigned long long)nslots + (unsigned long long)total +
                (unsigned long long)(pe - pb);
    for (int v = 0; v < K->nv; v++) {
        cx_node *n = &T->node[no[v] = w->cbase[w->slotbase[up[v] - pb] + w->dist[v]] + w->compv[v] - 1];
        n->nverts++;
        if (n->start < 0)
            n->start = v;
    }
    return total;
}

/* One level: the waves of every node of the level above. */
static int level_down(walker *w, int level) {
    cx_tree *T = w->T;
    int pb = 0, pe = T->nnodes;
    while (pb < pe && T->node[pb].level != level + 1)
        pb++;
    for (int v = 0; v < w->K->nv; v++)
        w->dist[v] = -1;
    w->steps += (unsigned long long)w->K->nv;
    uf_reset(w);
    int nfrom = 0;
    for (int W = pb; W < pe; W++) {
        T->node[W].nwaves = bfs(w, W, level + 1);
        mark_waves(w, W, level + 1);
        nfrom += T->node[W].nsimp;
    }
    int first = T->nnodes;
    if (make_children(w, pb, pe, level) < 0)
        return -1;
    distribute(w, level, first, T->nnodes, w->cur, nfrom);
    return 0;
}

static int walker_init(walker *w, const cx_complex *K, cx_tree *T) {
    size_t nv = (size_t)K->nv + 1, ns = (size_t)K->ns + 1;
    int levels = T->d - T->leaf + 1;
    memset(w, 0, sizeof *w);
    w->K = K, w->T = T;
    T->nodeof = malloc(sizeof *T->nodeof * nv * (size_t)levels);
    T->lowest = malloc(ns);
    w->cur = malloc(sizeof *w->cur * ns), w->nxt = malloc(sizeof *w->nxt * ns);
    int **v[] = {&w->dist, &w->queue, &w->uf, &w->usz, &w->compof, &w->compv, &w->slotbase, &w->count, &w->cbase};
    int bad = !T->nodeof || !T->lowest || !w->cur || !w->nxt;
    for (size_t i = 0; i < sizeof v / sizeof *v; i++)
        bad |= !(*v[i] = malloc(sizeof(int) * nv));
    return bad ? -1 : 0;
}

static void walker_free(walker *w) {
    free(w->rng), free(w->cur), free(w->nxt), free(w->dist), free(w->queue), free(w->uf), free(w->usz);
    free(w->compof), free(w->compv), free(w->slotbase), free(w->count), free(w->cbase);
}

cx_tree *cx_waves(const cx_complex *K, int start) {
    cx_tree *T = calloc(1, sizeof *T);
    walker w;
    if (!T)
        return NULL;
    T->d = K->dim;
    T->leaf = K->dim >= 2 ? 1 : 0;
    int bad = walker_init(&w, K, T) || K->nv == 0 || tops(&w, start >= 0 && start < K->nv ? start : 0);
    for (int level = T->d - 1; level >= T->leaf && !bad; level--)
        bad = level_down(&w, level);
    T->steps = w.steps;
    walker_free(&w);
    if (bad) {
        cx_tree_free(T);
        return NULL;
    }
    return T;
}

void cx_tree_free(cx_tree *T) {
    if (!T)
        return;
    free(T->node), free(T->nodeof), free(T->lowest);
    free(T);
}

/* ---- how far the waves turn ---- */

typedef struct turner {
    const cx_complex *K;
    const cx_tree *T;
    int *mark, stamp; /* link vertices of the face at hand carry the stamp */
    int *via;         /* a link vertex's coface of the face */
    int *dist, *queue;
} turner;

/* s lies in node W of the given level. */
static int in_node(const turner *t, int s, int W, int level) {
    const cx_tree *T = t->T;
    return T->lowest[s] <= level &&
           T->nodeof[(size_t)(level - T->leaf) * (size_t)t->K->nv + (size_t)t->K->vert[t->K->off[s]]] == W;
}

/* The vertex of c that s (a face of c) lacks. */
static int extra(const cx_complex *K, int c, int s) {
    int oc = K->off[c], os = K->off[s], n = K->off[s + 1] - os;
    for (int i = 0; i < n; i++)
        if (K->vert[oc + i] != K->vert[os + i])
            return K->vert[oc + i];
    return K->vert[oc + n];
}

/* The turn from F + a to F + b read from the link of F in node P: the
 * graph distance g of a and b on it, L its vertices: pi (1 - 2g/L). */
static double turn_link(turner *t, int F, int ca, int cb, int P, int level) {
    const cx_complex *K = t->K;
    int L = 0, a = extra(K, ca, F), b = extra(K, cb, F), head = 0, tail = 0;
    t->stamp++;
    for (int c = K->cooff[F]; c < K->cooff[F + 1]; c++)
        if (in_node(t, K->cof[c], P, level)) {
            int x = extra(K, K->cof[c], F);
            t->mark[x] = t->stamp, t->via[x] = K->cof[c], t->dist[x] = -1, L++;
        }
    t->dist[a] = 0;
    t->queue[tail++] = a;
    while (head < tail && t->dist[b] < 0) {
        int x = t->queue[head++], c1 = t->via[x];
        for (int c = K->cooff[c1]; c < K->cooff[c1 + 1]; c++) {
            int y = extra(K, K->cof[c], c1);
            if (in_node(t, K->cof[c], P, level) && t->mark[y] == t->stamp && t->dist[y] < 0)
                t->dist[y] = t->dist[x] + 1, t->queue[tail++] = y;
        }
    }
    if (t->dist[b] < 0 || L == 0)
        return M_PI;
    double r = 1 - 2.0 * t->dist[b] / L;
    return r > 0 ? M_PI * r : 0;
}

static const double *pos(const cx_complex *K, int v) { return K->coord + (size_t)v * (size_t)K->ncoord; }

/* y less its projection on the orthonormal vectors b[0..nb). */
static void project_out(double *y, double (*b)[CX_MAX_COORDS], int nb, int m) {
    for (int j = 0; j < nb; j++) {
        double dp = 0;
        for (int r = 0; r < m; r++)
            dp += y[r] * b[j][r];
        for (int r = 0; r < m; r++)
            y[r] -= dp * b[j][r];
    }
}

static double norm2(const double *y, int m) {
    double s = 0;
    for (int r = 0; r < m; r++)
        s += y[r] * y[r];
    return s;
}

/* The turn from F + a to F + b in space: pi minus the angle between a
 * and b, each taken perpendicular to F (Gram-Schmidt on F's edges). */
static double turn_space(const cx_complex *K, int F, int ca, int cb) {
    double b[CX_MAX_VERTS][CX_MAX_COORDS], u[2][CX_MAX_COORDS];
    int m = K->ncoord, o = K->off[F], n = K->off[F + 1] - o, nb = 0;
    const double *p0 = pos(K, K->vert[o]);
    for (int i = 1; i < n; i++) {
        const double *p = pos(K, K->vert[o + i]);
        for (int r = 0; r < m; r++)
            b[nb][r] = p[r] - p0[r];
        project_out(b[nb], b, nb, m);
        double nn = sqrt(norm2(b[nb], m));
        if (nn > 1e-12) {
            for (int r = 0; r < m; r++)
                b[nb][r] /= nn;
            nb++;
        }
    }
    const int ends[2] = {extra(K, ca, F), extra(K, cb, F)};
    for (int e = 0; e < 2; e++) {
        const double *q = pos(K, ends[e]);
        for (int r = 0; r < m; r++)
            u[e][r] = q[r] - p0[r];
        project_out(u[e], b, nb, m);
    }
    double na = norm2(u[0], m), nb2 = norm2(u[1], m), dp = 0;
    if (na <= 1e-24 || nb2 <= 1e-24)
        return 0; /* an end lies on the face's span: no direction to turn from */
    for (int r = 0; r < m; r++)
        dp += u[0][r] * u[1][r];
    double c = dp / sqrt(na * nb2);
    return M_PI - acos(c > 1 ? 1 : c < -1 ? -1 : c);
}

/* The faces one dimension below a node's top simplices, each with the
 * node's simplices on it: two make a pair, more a branch. */
static void turns_at(turner *t, cx_tree *T, int level, double *sum) {
    const cx_complex *K = t->K;
    for (int F = 0; F < K->ns; F++) {
        if (T->lowest[F] > level)
            continue;
        int W = T->nodeof[(size_t)(level - T->leaf) * (size_t)K->nv + (size_t)K->vert[K->off[F]]];
        cx_node *n = &T->node[W];
        if (n->maxdim == 0 || cx_dim(K, F) != n->maxdim - 1)
            continue;
        int c2[2], nc = 0;
        for (int c = K->cooff[F]; c < K->cooff[F + 1]; c++)
            if (in_node(t, K->cof[c], W, level)) {
                if (nc < 2)
                    c2[nc] = K->cof[c];
                nc++;
            }
        if (nc == 2)
            sum[W] += K->ncoord ? turn_space(K, F, c2[0], c2[1]) : turn_link(t, F, c2[0], c2[1], n->parent, level + 1);
        else if (nc > 2)
            sum[W] += M_PI * (nc - 1);
        n->npairs += nc >= 2 ? nc - 1 : 0;
    }
}

void cx_turns(const cx_complex *K, cx_tree *T) {
    turner t = {K, T, NULL, 0, NULL, NULL, NULL};
    size_t nv = (size_t)K->nv + 1;
    double *sum = calloc((size_t)T->nnodes + 1, sizeof *sum);
    t.mark = calloc(nv, sizeof(int)), t.via = malloc(nv * sizeof(int));
    t.dist = malloc(nv * sizeof(int)), t.queue = malloc(nv * sizeof(int));
    if (sum && t.mark && t.via && t.dist && t.queue) {
        for (int i = 0; i < T->nnodes; i++)
            T->node[i].npairs = 0;
        for (int level = T->d - 1; level >= T->leaf; level--)
            turns_at(&t, T, level, sum);
        for (int i = 0; i < T->nnodes; i++)
            T->node[i].turn = T->node[i].npairs ? sum[i] / T->node[i].npairs : 0;
    }
    free(sum), free(t.mark), free(t.via), free(t.dist), free(t.queue);
}

/* ---- printing ---- */

static void print_node(FILE *f, const cx_tree *T, int i, int parent_line, int *line) {
    const cx_node *n = &T->node[i];
    int me = ++*line;
    fprintf(f, "dim=%d wave=%d component=%d vertices=%d simplices=%d parent=%d\n", n->level, n->wave, n->comp,
            n->nverts, n->nsimp, parent_line);
    for (int c = 0; c < n->nchild; c++)
        print_node(f, T, n->first + c, me, line);
}

void cx_tree_print(FILE *f, const cx_tree *T) {
    int line = 0;
    for (int i = 0; i < T->nnodes && T->node[i].parent < 0; i++)
        print_node(f, T, i, 0, &line);
}
