/* wdf.c: Circuit -> adaptor forest.
 *
 * Every adaptable element (R, C, L, resistive sources, a line's end) is a
 * leaf whose port resistance makes it reflection-free or gives it a
 * one-sample memory (bilinear transform: C -> T/(2C), L -> 2L/T).  The
 * element graph splits into biconnected blocks: blocks that share one
 * node, or meet only through a line's delay, exchange no instantaneous
 * current, and each gets a root of its own.  Inside a block,
 * series-parallel reduction builds adapted series and parallel adaptors
 * bottom-up: two edges between the same nodes merge in parallel, a node
 * with exactly two edges merges them in series; chains of the same kind
 * flatten into one n-port adaptor.  Ideal sources and the nonlinear element
 * cannot be adapted and are never merged.  What cannot be reduced further
 * (bridges, non-series-parallel frames, ideal sources, the nonlinearity)
 * is the block's core: one rigid root adaptor whose matrix is solved from
 * the core's nodal equations (scatter.c). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "gen.h"

typedef struct Edge {
    int u, w;     /* oriented u -> w */
    WNode *node;  /* subtree, or NULL for an ideal source */
    int src;      /* element index of an ideal source, else -1 */
    bool alive;
} Edge;

/* Ideal sources and nonlinear elements cannot be adapted: they go to the
 * root. */
static bool at_root(const Elem *e) { return prim_at_root(e); }

static int cmp_int(const void *a, const void *b) {
    int x = *(const int *)a, y = *(const int *)b;
    return (x > y) - (x < y);
}

static double leaf_R(const Circuit *c, const Elem *e, const double *p, double fs) {
    return prim_port(e, elem_value(c, e, p), fs);
}

static WNode *new_node(WKind k, int u, int w) {
    WNode *n = arena_alloc(sizeof(WNode));
    n->kind = k;
    n->u = u;
    n->w = w;
    n->elem = -1;
    return n;
}

/* An adaptor joining two edges' subtrees with polarities p1, p2, as the
 * reduction finds it: just those two children.  A child of its own kind
 * is flattened into it, and its port resistance set, once the block is
 * reduced (finish_tree): flattening at every merge would copy a chain's
 * children at each step. */
static WNode *combine(WKind k, Edge *e1, int p1, Edge *e2, int p2, int u, int w) {
    WNode *n = new_node(k, u, w);
    n->nchild = 2;
    n->child = arena_alloc(sizeof(WNode *) * 2);
    n->pol = arena_alloc(sizeof(int) * 2);
    n->child[0] = e1->node;
    n->pol[0] = p1;
    n->child[1] = e2->node;
    n->pol[1] = p2;
    return n;
}

/* A growable stack of subtrees with polarities. */
typedef struct Item {
    WNode *n;
    int pol;
} Item;

typedef struct Items {
    Item *v;
    int len, cap;
} Items;

static void items_push(Items *s, WNode *n, int pol) {
    if (s->len == s->cap) {
        s->cap = s->cap ? 2 * s->cap : 16;
        Item *v = arena_alloc(sizeof(Item) * (size_t)s->cap);
        if (s->len)
            memcpy(v, s->v, sizeof(Item) * (size_t)s->len);
        s->v = v;
    }
    s->v[s->len++] = (Item){n, pol};
}

/* Gives adaptor n its final children: each child of n's kind is replaced
 * by its own children, in order, their polarities times its own, so a
 * chain of series (or parallel) connections is one n-port adaptor. */
static void flatten(WNode *n, Items *stack, Items *out) {
    stack->len = out->len = 0;
    for (int i = n->nchild - 1; i >= 0; i--)
        items_push(stack, n->child[i], n->pol[i]);
    while (stack->len) {
        Item it = stack->v[--stack->len];
        if (it.n->kind != n->kind) {
            items_push(out, it.n, it.pol);
            continue;
        }
        for (int i = it.n->nchild - 1; i >= 0; i--)
            items_push(stack, it.n->child[i], it.pol * it.n->pol[i]);
    }
    n->nchild = out->len;
    n->child = arena_alloc(sizeof(WNode *) * (size_t)out->len);
    n->pol = arena_alloc(sizeof(int) * (size_t)out->len);
    for (int i = 0; i < out->len; i++) {
        n->child[i] = out->v[i].n;
        n->pol[i] = out->v[i].pol;
        out->v[i].n->parent = n;
    }
}

/* Flattens the adaptors of the subtree under top (made by combine), then
 * sets their port resistances, children before parents: a series
 * adaptor's is the sum of its children's, a parallel adaptor's the
 * inverse of the sum of their conductances.  No recursion: a ladder's
 * tree is as deep as the ladder is long. */
static void finish_tree(WNode *top) {
    Items todo = {0}, stack = {0}, out = {0}, order = {0};
    items_push(&todo, top, 1);
    while (todo.len) {
        WNode *n = todo.v[--todo.len].n;
        if (n->kind == W_LEAF)
            continue;
        items_push(&order, n, 1);
        flatten(n, &stack, &out);
        for (int i = n->nchild - 1; i >= 0; i--)
            items_push(&todo, n->child[i], 1);
    }
    for (int k = order.len - 1; k >= 0; k--) {
        WNode *n = order.v[k].n;
        double s = 0;
        for (int i = 0; i < n->nchild; i++) {
            s += n->kind == W_SERIES ? n->child[i]->R : 1 / n->child[i]->R;
            n->pmask |= n->child[i]->pmask;
        }
        n->R = n->kind == W_SERIES ? s : 1 / s;
    }
}

/* ---- series-parallel reduction of one block ----
 *
 * The rule: merge the first parallel pair (edges i < j between the same
 * two nodes, both adaptable; lowest i, then lowest j) while there is one,
 * else the two edges at the lowest node that has exactly two, both
 * adaptable (the lower-numbered edge keeps the merge); repeat until
 * neither applies.  The order decides each adaptor's children and their
 * order, so it is kept exactly, without rescanning the block for each
 * merge: after the first round of parallel merges every pair of nodes is
 * joined by at most one adaptable edge, a new pair can only form where a
 * series merge has just put its edge, and a node only becomes a series
 * candidate when a parallel merge lowers its degree to two.  Edges by
 * their two nodes sit in a hash table, candidate nodes in a heap. */

typedef struct Reduce {
    Edge *E;           /* the block's edges, in element order */
    int ne;
    const int *loc;    /* graph node -> local node of the block */
    int nl;            /* local nodes, numbered in graph order */
    int *deg;          /* local node -> alive edges at it */
    int **adj;         /* local node -> edges that reach or reached it */
    int *nadj, *cadj;
    uint64_t *key;     /* hash table: node pair -> its adaptable edge */
    int *val;          /* -1: none */
    unsigned mask;
    int *heap;         /* local nodes that may have two edges */
    int nheap;
} Reduce;

static void adj_push(Reduce *R, int v, int e) {
    if (R->nadj[v] == R->cadj[v]) {
        int cap = R->cadj[v] ? 2 * R->cadj[v] : 4;
        int *a = arena_alloc(sizeof(int) * (size_t)cap);
        if (R->nadj[v])
            memcpy(a, R->adj[v], sizeof(int) * (size_t)R->nadj[v]);
        R->adj[v] = a;
        R->cadj[v] = cap;
    }
    R->adj[v][R->nadj[v]++] = e;
}

/* The slot of the table for the pair of graph nodes a, b. */
static int *pair_slot(Reduce *R, int a, int b) {
    uint64_t k = ((uint64_t)(a < b ? a : b) << 32 | (uint32_t)(a < b ? b : a)) + 1; /* never 0 */
    unsigned i = (unsigned)((k * 0x9E3779B97F4A7C15u) >> 32) & R->mask;
    while (R->key[i] && R->key[i] != k)
        i = (i + 1) & R->mask;
    if (!R->key[i]) {
        R->key[i] = k;
        R->val[i] = -1;
    }
    return &R->val[i];
}

static void heap_push(Reduce *R, int v) {
    int i = R->nheap++;
    for (; i > 0 && R->heap[(i - 1) / 2] > v; i = (i - 1) / 2)
        R->heap[i] = R->heap[(i - 1) / 2];
    R->heap[i] = v;
}

static int heap_pop(Reduce *R) {
    int top = R->heap[0], v = R->heap[--R->nheap], i = 0;
    for (;;) {
        int c = 2 * i + 1;
        if (c >= R->nheap)
            break;
        if (c + 1 < R->nheap && R->heap[c + 1] < R->heap[c])
            c++;
        if (R->heap[c] >= v)
            break;
        R->heap[i] = R->heap[c];
        i = c;
    }
    if (R->nheap)
        R->heap[i] = v;
    return top;
}

static void drop_edge(Reduce *R, int j) {
    Edge *e = &R->E[j];
    e->alive = false;
    R->deg[R->loc[e->u]]--;
    if (e->w != e->u)
        R->deg[R->loc[e->w]]--;
}

/* Edge j joins edge i < j in parallel; i keeps the adaptor. */
static void merge_parallel(Reduce *R, int i, int j) {
    Edge *E = R->E;
    bool same = E[i].u == E[j].u && E[i].w == E[j].w;
    E[i].node = combine(W_PARALLEL, &E[i], 1, &E[j], same ? 1 : -1, E[i].u, E[i].w);
    drop_edge(R, j);
}

/* The two alive edges at local node v (whose degree is 2), lower first;
 * stale entries of its list go. */
static void two_edges(Reduce *R, int v, int g, int *a, int *b) {
    int n = 0;
    for (int k = 0; k < R->nadj[v]; k++) {
        int e = R->adj[v][k];
        const Edge *x = &R->E[e];
        if (!x->alive || (x->u != g && x->w != g) || (n > 0 && R->adj[v][0] == e) ||
            (n > 1 && R->adj[v][1] == e))
            continue;
        R->adj[v][n++] = e;
    }
    R->nadj[v] = n;
    if (n != 2)
        die("node %d has %d edges where its degree is 2", g, n);
    *a = R->adj[v][0] < R->adj[v][1] ? R->adj[v][0] : R->adj[v][1];
    *b = R->adj[v][0] < R->adj[v][1] ? R->adj[v][1] : R->adj[v][0];
}

/* One series merge at local node v if it has exactly two edges, both
 * adaptable, to two different nodes; then the parallel merge it may
 * allow. */
static void merge_series(Reduce *R, int v, int g) {
    Edge *E = R->E;
    int ia, ib;
    two_edges(R, v, g, &ia, &ib);
    Edge *a = &E[ia], *b = &E[ib];
    if (!a->node || !b->node || a->u == a->w || b->u == b->w)
        return;
    int x = a->u == g ? a->w : a->u;
    int y = b->u == g ? b->w : b->u;
    if (x == y)
        return; /* a parallel pair: merged already */
    int pa = a->u == x ? 1 : -1; /* a runs x -> g */
    int pb = b->u == g ? 1 : -1; /* b runs g -> y */
    a->node = combine(W_SERIES, a, pa, b, pb, x, y);
    *pair_slot(R, x, g) = -1;
    *pair_slot(R, g, y) = -1;
    a->u = x;
    a->w = y;
    b->alive = false;
    R->deg[v] = 0;
    adj_push(R, R->loc[y], ia);
    int *p = pair_slot(R, x, y);
    if (*p >= 0) {
        int i = *p < ia ? *p : ia, j = *p < ia ? ia : *p;
        merge_parallel(R, i, j);
        *p = i;
    } else {
        *p = ia;
    }
    if (R->deg[R->loc[x]] == 2)
        heap_push(R, R->loc[x]);
    if (R->deg[R->loc[y]] == 2)
        heap_push(R, R->loc[y]);
}

/* Reduces the block's edges E (alive, in element order) whose nodes are
 * the graph nodes gl[0..nl) in increasing order (loc the inverse). */
static void reduce(Edge *E, int ne, const int *gl, int nl, const int *loc) {
    Reduce R = {.E = E, .ne = ne, .loc = loc, .nl = nl};
    R.deg = arena_alloc(sizeof(int) * (size_t)(nl + 1));
    R.adj = arena_alloc(sizeof(int *) * (size_t)(nl + 1));
    R.nadj = arena_alloc(sizeof(int) * (size_t)(nl + 1));
    R.cadj = arena_alloc(sizeof(int) * (size_t)(nl + 1));
    unsigned cap = 16;
    while (cap < 4u * (unsigned)ne + 4)
        cap *= 2;
    R.mask = cap - 1;
    R.key = arena_alloc(sizeof(uint64_t) * cap);
    R.val = arena_alloc(sizeof(int) * cap);
    R.heap = arena_alloc(sizeof(int) * (size_t)(nl + 2 * ne + 1));
    for (int i = 0; i < ne; i++) {
        R.deg[loc[E[i].u]]++;
        adj_push(&R, loc[E[i].u], i);
        if (E[i].w != E[i].u) {
            R.deg[loc[E[i].w]]++;
            adj_push(&R, loc[E[i].w], i);
        }
    }
    for (int i = 0; i < ne; i++) { /* the first round of parallel merges */
        if (!E[i].node)
            continue;
        int *p = pair_slot(&R, E[i].u, E[i].w);
        if (*p < 0)
            *p = i;
        else
            merge_parallel(&R, *p, i);
    }
    for (int v = 0; v < nl; v++)
        if (R.deg[v] == 2)
            heap_push(&R, v);
    while (R.nheap) {
        int v = heap_pop(&R);
        if (R.deg[v] == 2)
            merge_series(&R, v, gl[v]);
    }
}

/* Nonlinear elements solved jointly at one root: memoryless laws (diodes,
 * pairs, curves), at most WD_JOINT_MAX of them.  Contacts and the laws
 * behind a mutator store energy and step passively, each alone: a delay
 * must part them from any other. */
static bool joins(const Elem *e) { return (e->nl->kind == NL_DIODE || e->nl->kind == NL_CURVE) && !e->nl->mutated; }

static void check_nonlinear(Wdf *wd, Root *r) {
    if (r->nnl <= 1)
        return;
    int bad = -1;
    for (int k = r->nport; k < r->nport + r->nnl && bad < 0; k++)
        if (!joins(&wd->c->elems[r->edge[k].elem]))
            bad = k;
    if (bad < 0 && r->nnl <= WD_JOINT_MAX) {
        r->joint = true;
        return;
    }
    /* refused at the element that cannot join, else at the first past the limit */
    int at = bad >= 0 ? bad : r->nport + WD_JOINT_MAX, other = at == r->nport ? r->nport + 1 : r->nport;
    const Elem *first = &wd->c->elems[r->edge[other].elem];
    const Elem *second = &wd->c->elems[r->edge[at].elem];
    if (r->nnl > WD_JOINT_MAX)
        error_begin(second->pos, "'%s' makes %d nonlinear elements coupled with no delay between them: at most %d "
                    "are solved jointly; a delay element (a transmission line, string or tube) would part them",
                    second->name, r->nnl, WD_JOINT_MAX);
    else
        error_begin(second->pos, "%s '%s' is coupled to '%s' with no delay between them: a %s stores energy and "
                    "is solved alone, so a delay element (a transmission line, string or tube) must part it from "
                    "other nonlinear elements", block_desc[second->user_kind].desc, second->name, first->name,
                    second->nl->kind == NL_CONTACT ? "contact" : "nonlinear reactance");
    note_at(first->pos, "'%s' is here", first->name);
    error_end();
}

/* Gives nonlinear edge k the resistance the rest of the core presents to
 * it, so that the wave the root sends it does not depend on its own.  At a
 * joint root the others count at their present resistances. */
static void adapt_nonlinear(Wdf *wd, Root *r, int k) {
    const Elem *e = &wd->c->elems[r->edge[k].elem];
    double Rth;
    int ok = scatter_thevenin(r, r->R, k, &Rth);
    /* an active joint root may present no positive resistance to an
     * edge: it keeps the one it has, which only conditions the solve */
    if (r->joint && r->nctl && !(ok == 0 && Rth > 0 && Rth < 1e300))
        return;
    if (ok < 0 || !(Rth < 1e300))
        error_at(e->pos, "%s '%s' has no closed path through the rest of the network: no current can flow "
                 "through it", block_desc[e->user_kind].desc, e->name);
    if (!(Rth > 0))
        error_at(e->pos, "%s '%s' sits directly across an ideal source: nothing limits its current "
                 "(put a resistance in series)", block_desc[e->user_kind].desc, e->name);
    r->R[k] = Rth;
}

/* The port resistances of a root's nonlinear edges.  One edge is adapted
 * (its resistance follows the ports').  At a joint root they are fixed
 * here: each starts at the ports' geometric mean and is adapted to the
 * rest, the others included, in three sweeps; the joint solve's answer does
 * not depend on them, only its conditioning. */
static void adapt_root(Wdf *wd, Root *r) {
    int k0 = r->nport, k1 = r->nport + r->nnl;
    if (!r->joint) {
        for (int k = k0; k < k1; k++)
            adapt_nonlinear(wd, r, k);
        return;
    }
    double lg = 0;
    for (int i = 0; i < r->nport; i++)
        lg += log(r->R[i]);
    double R0 = r->nport ? exp(lg / r->nport) : 1;
    for (int k = k0; k < k1; k++)
        r->R[k] = R0;
    for (int sweep = 0; sweep < 3; sweep++)
        for (int k = k0; k < k1; k++)
            adapt_nonlinear(wd, r, k);
    /* in an active root a junction's current, (a - b) / 2R, also drives
     * the sources that take it, gain / R times: a resistance far below
     * the network's leaves that current a few digits, so none is below a
     * hundredth of the ports' mean (the Fuzz Face's input junction would
     * otherwise sit at 0.03 Ohm at 192 kHz, behind its coupling capacitor) */
    for (int k = k0; k < k1 && r->nctl; k++)
        r->R[k] = fmax(r->R[k], 1e-2 * R0);
}

static void build_root(Wdf *wd, Root *r, Edge *E, int ne, const int *gl, int nl, const int *loc) {
    Circuit *c = wd->c;
    int *core = arena_alloc(sizeof(int) * (size_t)(nl + 1)); /* local node -> core index */
    for (int i = 0; i < nl; i++)
        core[i] = -2;
    r->ref_node = -1;
    for (int i = 0; i < ne; i++)
        if (E[i].alive) {
            core[loc[E[i].u]] = core[loc[E[i].w]] = -1;
            if (E[i].u == 0 || E[i].w == 0)
                r->ref_node = 0;
            if (r->ref_node < 0)
                r->ref_node = E[i].u;
        }
    r->core_node = arena_alloc(sizeof(int) * (size_t)(nl + 1));
    for (int v = 0; v < nl; v++)
        if (core[v] == -1 && gl[v] != r->ref_node) {
            core[v] = r->ncore;
            r->core_node[r->ncore++] = gl[v];
        }
    if (r->ref_node >= 0)
        core[loc[r->ref_node]] = -1;
    int nalive = 0;
    for (int i = 0; i < ne; i++)
        nalive += E[i].alive;
    r->edge = arena_alloc(sizeof(RootEdge) * (size_t)(nalive + 1));
    /* ports first, then nonlinear edges, V sources, I sources */
    static const int order[] = {EDGE_PORT, EDGE_NL, EDGE_V, EDGE_I};
    for (int pass = 0; pass < 4; pass++)
        for (int i = 0; i < ne; i++) {
            if (!E[i].alive)
                continue;
            ElemKind ek = E[i].node ? E_R : c->elems[E[i].src].kind;
            if (ELEM_CONTROLLED(ek))
                continue;
            int kind = E[i].node ? EDGE_PORT : ek == E_V ? EDGE_V : ek == E_I ? EDGE_I : EDGE_NL;
            if (kind != order[pass])
                continue;
            RootEdge *re = &r->edge[r->nedge++];
            re->kind = kind;
            re->node = E[i].node;
            re->elem = E[i].src;
            re->p = core[loc[E[i].u]];
            re->q = core[loc[E[i].w]];
            if (kind == EDGE_PORT) {
                r->nport++;
                r->pmask |= E[i].node->pmask;
            }
            if (kind == EDGE_V)
                r->nv++;
            if (kind == EDGE_NL)
                r->nnl++;
        }
    r->ctl = arena_alloc(sizeof(*r->ctl) * (size_t)(nalive + 1));
    for (int i = 0; i < ne; i++) {
        if (!E[i].alive || E[i].node || !ELEM_CONTROLLED(c->elems[E[i].src].kind) || c->elems[E[i].src].kind == E_P)
            continue;
        const Elem *e = &c->elems[E[i].src], *pr = &c->elems[e->peer];
        struct RootCtl *x = &r->ctl[r->nctl++];
        x->elem = E[i].src;
        x->kind = e->kind;
        x->p = core[loc[E[i].u]];
        x->q = core[loc[E[i].w]];
        x->cp = core[loc[pr->n[0]]];
        x->cn = core[loc[pr->n[1]]];
        x->ce = -1;
        for (int k = 0; k < r->nedge && e->kind == E_CC; k++)
            if (r->edge[k].kind == EDGE_NL && r->edge[k].elem == e->peer)
                x->ce = k;
        if (e->kind == E_CC && x->ce < 0)
            die("'%s' is not at the root of its junction", e->name);
        x->gain = e->val ? expr_eval(e->val, NULL) : 0;
        r->nx += ELEM_VOUT(e->kind);
    }
    check_nonlinear(wd, r);
    r->M = arena_alloc(sizeof(double) * (size_t)(r->nedge * r->nedge));
    double *R = r->R = arena_alloc(sizeof(double) * (size_t)(r->nport + r->nnl + 1));
    for (int i = 0; i < r->nport; i++)
        R[i] = r->edge[i].node->R;
    adapt_root(wd, r);
    bool singular = scatter_root(r, R, r->M) < 0;
    if (singular && r->nedge == r->nport + r->nnl)
        error_at(c->elems[0].pos, "the network's equations are singular: its element values span too wide a "
                 "range to solve in double precision");
    if (singular) {
        int first = r->nport + r->nnl;
        const Elem *e0 = &c->elems[r->edge[first].elem];
        size_t len = 1;
        for (int i = first; i < r->nedge; i++)
            len += strlen(c->elems[r->edge[i].elem].name) + 4;
        char *list = arena_alloc(len), *p = list;
        for (int i = first; i < r->nedge; i++)
            p += sprintf(p, "%s'%s'", i > first ? ", " : "", c->elems[r->edge[i].elem].name);
        error_at(e0->pos, "the ideal sources %s cannot all hold: voltage sources form a loop or "
                 "current sources a cut-set (give one a series or parallel resistance, R=)", list);
    }
}

/* The edges at each graph node, in edge order (an edge from a node to
 * itself once): CSR arrays start[nnodes + 1], at[]. */
static int *incidence(const Edge *E, int ne, int nnodes, int **start_out) {
    int *start = arena_alloc(sizeof(int) * (size_t)(nnodes + 1));
    int *fill = arena_alloc(sizeof(int) * (size_t)(nnodes + 1));
    for (int i = 0; i < ne; i++) {
        start[E[i].u + 1]++;
        if (E[i].w != E[i].u)
            start[E[i].w + 1]++;
    }
    for (int v = 0; v < nnodes; v++)
        start[v + 1] += start[v];
    int *at = arena_alloc(sizeof(int) * (size_t)(start[nnodes] + 1));
    for (int i = 0; i < ne; i++) {
        at[start[E[i].u] + fill[E[i].u]++] = i;
        if (E[i].w != E[i].u)
            at[start[E[i].w] + fill[E[i].w]++] = i;
    }
    *start_out = start;
    return at;
}

/* Biconnected blocks of the element graph (alive edges): two edges share
 * a block if a simple cycle holds both.  Blocks that meet at one node
 * exchange no current, so each is solved on its own.  Depth-first search
 * with low points and a stack of edges (Hopcroft and Tarjan), its own
 * stack of frames in place of recursion; returns the number of blocks and
 * sets block[i] for every alive edge (an edge from a node to itself is in
 * none: -1). */
typedef struct Frame {
    int v, via, next; /* node, edge it was reached by, next of its edges to try */
} Frame;

static int blocks(Edge *E, int ne, int nnodes, int *block) {
    int *start, *at = incidence(E, ne, nnodes, &start);
    int *disc = arena_alloc(sizeof(int) * (size_t)(nnodes + 1));
    int *low = arena_alloc(sizeof(int) * (size_t)(nnodes + 1));
    int *stack = arena_alloc(sizeof(int) * (size_t)(ne + 1));
    Frame *fr = arena_alloc(sizeof(Frame) * (size_t)(nnodes + 1));
    int sp = 0, nf = 0, time = 0, nblocks = 0;
    for (int i = 0; i < ne; i++)
        block[i] = -1;
    for (int root = 0; root < nnodes; root++) {
        if (disc[root])
            continue;
        disc[root] = low[root] = ++time;
        fr[nf++] = (Frame){root, -1, start[root]};
        while (nf) {
            Frame *f = &fr[nf - 1];
            int v = f->v;
            if (f->next < start[v + 1]) {
                int i = at[f->next++];
                Edge *e = &E[i];
                if (!e->alive || i == f->via)
                    continue;
                int u = e->u == v ? e->w : e->u;
                if (!disc[u]) {
                    stack[sp++] = i;
                    disc[u] = low[u] = ++time;
                    fr[nf++] = (Frame){u, i, start[u]};
                } else if (disc[u] < disc[v]) {
                    stack[sp++] = i;
                    if (disc[u] < low[v])
                        low[v] = disc[u];
                }
                continue;
            }
            int via = f->via;
            if (--nf == 0)
                break;
            int p = fr[nf - 1].v; /* back in the parent: v done */
            if (low[v] < low[p])
                low[p] = low[v];
            if (low[v] >= disc[p]) { /* p separates: pop one block */
                int k;
                do {
                    k = stack[--sp];
                    block[k] = nblocks;
                } while (k != via);
                nblocks++;
            }
        }
    }
    return nblocks;
}

/* A controlled source's output and its probe stamp one root's nodal
 * equations: their blocks become one (the root's core then holds parts
 * that meet only through the control). */
static void merge_controlled(const Circuit *c, int *block, int *nblocks) {
    int nb = *nblocks;
    int *uf = arena_alloc(sizeof(int) * (size_t)(nb + 1)), *id = arena_alloc(sizeof(int) * (size_t)(nb + 1));
    for (int b = 0; b < nb; b++)
        uf[b] = b, id[b] = -1;
    bool any = false;
    for (int i = 0; i < c->nelems; i++) {
        const Elem *e = &c->elems[i];
        if (e->kind != E_P && e->kind != E_CC) /* a probe, or a transistor's source: with its junction */
            continue;
        int a = block[i], b = block[e->peer];
        if (a < 0 || b < 0)
            error_at(e->pos, "%s '%s' joins a node to itself", block_desc[e->user_kind].desc, e->name);
        while (uf[a] != a)
            a = uf[a];
        while (uf[b] != b)
            b = uf[b];
        if (a != b)
            uf[a > b ? a : b] = a < b ? a : b, any = true;
    }
    if (!any)
        return;
    int n = 0;
    for (int b = 0; b < nb; b++) {
        int r = b;
        while (uf[r] != r)
            r = uf[r];
        if (id[r] < 0)
            id[r] = n++;
        id[b] = id[r];
    }
    for (int i = 0; i < c->nelems; i++)
        if (block[i] >= 0)
            block[i] = id[block[i]];
    *nblocks = n;
}

/* The path from ground to each graph node along a breadth-first tree of
 * the element graph: element indices with sign, so v(node) = sum sign *
 * v(elem).  A node's path is its parent's and one step more, so a node
 * shares its storage with the child whose subtree is deepest: a chain of
 * n nodes holds n steps in all, not n^2 / 2. */
static void build_paths(Wdf *w) {
    Circuit *c = w->c;
    int nn = c->nnodes;
    Edge *E = arena_alloc(sizeof(Edge) * (size_t)(c->nelems + 1));
    for (int i = 0; i < c->nelems; i++)
        E[i] = (Edge){c->elems[i].n[0], c->elems[i].n[1], NULL, -1, true};
    int *start, *at = incidence(E, c->nelems, nn, &start);
    int *pe = arena_alloc(sizeof(int) * (size_t)nn), *ps = arena_alloc(sizeof(int) * (size_t)nn);
    int *from = arena_alloc(sizeof(int) * (size_t)nn), *queue = arena_alloc(sizeof(int) * (size_t)nn);
    bool *seen = arena_alloc(sizeof(bool) * (size_t)nn);
    int head = 0, tail = 0;
    queue[tail++] = 0;
    seen[0] = true;
    while (head < tail) {
        int n = queue[head++];
        for (int j = start[n]; j < start[n + 1]; j++) {
            int i = at[j];
            if (ELEM_CONTROLLED(c->elems[i].kind)) /* no voltage of their own to read */
                continue;
            for (int k = 0; k < 2; k++) {
                int m = c->elems[i].n[!k];
                if (c->elems[i].n[k] != n || seen[m])
                    continue;
                seen[m] = true;
                pe[m] = i;
                ps[m] = k == 1 ? 1 : -1; /* reached n0 from n1: v(n0) = v(n1) + v */
                from[m] = n;
                queue[tail++] = m;
            }
        }
    }
    for (int n = 1; n < nn; n++) /* reached only through controlled sources */
        if (!seen[n])
            for (int i = 0; i < c->nelems; i++)
                if (c->elems[i].n[0] == n || c->elems[i].n[1] == n)
                    error_at(c->elems[i].pos, "node '%s' meets only controlled sources and op-amps: give it a "
                             "path to ground through other elements", c->nodes[n]);
    /* height of each node's subtree; each node's deepest child (the first
     * of equals) continues its storage */
    int *height = arena_alloc(sizeof(int) * (size_t)nn), *heir = arena_alloc(sizeof(int) * (size_t)nn);
    for (int n = 0; n < nn; n++)
        heir[n] = -1;
    for (int t = tail - 1; t > 0; t--) {
        int m = queue[t], p = from[m];
        if (heir[p] < 0 || height[m] + 1 > height[p])
            height[p] = height[m] + 1, heir[p] = m;
    }
    w->path = arena_alloc(sizeof(int *) * (size_t)nn);
    w->pathlen = arena_alloc(sizeof(int) * (size_t)nn);
    for (int t = 1; t < tail; t++) {
        int m = queue[t], p = from[m], len = w->pathlen[p] + 1;
        if (p != 0 && heir[p] == m) {
            w->path[m] = w->path[p];
        } else {
            w->path[m] = arena_alloc(sizeof(int) * (size_t)(2 * (len + height[m])));
            if (p != 0)
                memcpy(w->path[m], w->path[p], sizeof(int) * (size_t)(2 * (len - 1)));
        }
        w->pathlen[m] = len;
        w->path[m][2 * (len - 1)] = pe[m];
        w->path[m][2 * (len - 1) + 1] = ps[m];
    }
}

/* Post-order numbering of a subtree (children before parents). */
static void number(WNode *top, int root, Vec *order) {
    Items st = {0};
    items_push(&st, top, 0); /* pol: the next child to visit */
    while (st.len) {
        Item *it = &st.v[st.len - 1];
        if (it->pol < it->n->nchild) {
            WNode *ch = it->n->child[it->pol++];
            items_push(&st, ch, 0);
            continue;
        }
        it->n->id = order->len;
        it->n->root = root;
        vec_push(order, it->n);
        st.len--;
    }
}

Wdf *wdf_build(Circuit *c, double fs) {
    Wdf *w = arena_alloc(sizeof(Wdf));
    w->c = c;
    w->fs = fs;
    double *p = circuit_defaults(c);
    Edge *E = arena_alloc(sizeof(Edge) * (size_t)c->nelems);
    w->leaf_of = arena_alloc(sizeof(WNode *) * (size_t)c->nelems);
    for (int i = 0; i < c->nelems; i++) {
        const Elem *e = &c->elems[i];
        E[i] = (Edge){e->n[0], e->n[1], NULL, -1, true};
        if (at_root(e)) {
            E[i].src = i;
            continue;
        }
        WNode *n = new_node(W_LEAF, e->n[0], e->n[1]);
        n->elem = i;
        n->R = leaf_R(c, e, p, fs);
        if (!(n->R > 1e-150 && n->R < 1e150))
            error_at(e->pos, "%s '%s' has port resistance %g at %g Hz, out of the range a voice can compute "
                     "with (1e-150 to 1e150)", block_desc[e->user_kind].desc, e->name, n->R, fs);
        n->pmask = expr_params(e->val);
        E[i].node = w->leaf_of[i] = n;
    }
    /* blocks first: reduction inside each never merges across a node that
     * joins independent parts */
    int *block = arena_alloc(sizeof(int) * (size_t)c->nelems);
    w->nroots = blocks(E, c->nelems, c->nnodes, block);
    merge_controlled(c, block, &w->nroots);
    w->roots = arena_alloc(sizeof(Root) * (size_t)w->nroots);
    /* each block's edges in element order, and its nodes in graph order */
    int *bstart = arena_alloc(sizeof(int) * (size_t)(w->nroots + 1));
    int *bedge = arena_alloc(sizeof(int) * (size_t)(c->nelems + 1));
    for (int i = 0; i < c->nelems; i++)
        if (block[i] >= 0)
            bstart[block[i] + 1]++;
    for (int b = 0; b < w->nroots; b++)
        bstart[b + 1] += bstart[b];
    int *fill = arena_alloc(sizeof(int) * (size_t)(w->nroots + 1));
    for (int i = 0; i < c->nelems; i++)
        if (block[i] >= 0)
            bedge[bstart[block[i]] + fill[block[i]]++] = i;
    int *loc = arena_alloc(sizeof(int) * (size_t)c->nnodes);
    int *gl = arena_alloc(sizeof(int) * (size_t)(2 * c->nelems + 1));
    Edge *sub = arena_alloc(sizeof(Edge) * (size_t)(c->nelems + 1));
    for (int n = 0; n < c->nnodes; n++)
        loc[n] = -1;
    for (int b = 0; b < w->nroots; b++) {
        int ne = bstart[b + 1] - bstart[b], nl = 0;
        for (int k = 0; k < ne; k++) {
            sub[k] = E[bedge[bstart[b] + k]];
            for (int s = 0; s < 2; s++) {
                int n = s ? sub[k].w : sub[k].u;
                if (loc[n] < 0) {
                    loc[n] = 0;
                    gl[nl++] = n;
                }
            }
        }
        qsort(gl, (size_t)nl, sizeof(int), cmp_int);
        for (int v = 0; v < nl; v++)
            loc[gl[v]] = v;
        reduce(sub, ne, gl, nl, loc);
        for (int k = 0; k < ne; k++)
            if (sub[k].alive && sub[k].node)
                finish_tree(sub[k].node);
        build_root(w, &w->roots[b], sub, ne, gl, nl, loc);
        for (int v = 0; v < nl; v++)
            loc[gl[v]] = -1;
    }
    Vec order = {0};
    for (int b = 0; b < w->nroots; b++)
        for (int i = 0; i < w->roots[b].nport; i++)
            number(w->roots[b].edge[i].node, b, &order);
    w->nodes = (WNode **)order.data;
    w->nnodes = order.len;
    build_paths(w);
    return w;
}

static const char *node_label(const Wdf *w, const WNode *n) {
    const Circuit *c = w->c;
    if (n->kind == W_LEAF)
        return format("%s\\nR=%.4g", c->elems[n->elem].name, n->R);
    return format("%s\\nR=%.4g", n->kind == W_SERIES ? "series" : "parallel", n->R);
}

void wdf_dot(const Wdf *w, FILE *out) {
    const Circuit *c = w->c;
    fprintf(out, "digraph %s {\n  node [fontname=\"Helvetica\"];\n", c->name);
    for (int b = 0; b < w->nroots; b++)
        fprintf(out, "  root%d [shape=doubleoctagon,label=\"root %d (%s, %d ports)\"];\n", b, b,
                w->roots[b].nedge > 1 ? "rigid" : "open end", w->roots[b].nport);
    for (int i = 0; i < w->nnodes; i++) {
        const WNode *n = w->nodes[i];
        fprintf(out, "  n%d [shape=%s,label=\"%s\"];\n", n->id, n->kind == W_LEAF ? "box" : "ellipse",
                node_label(w, n));
        for (int k = 0; k < n->nchild; k++)
            fprintf(out, "  n%d -> n%d [label=\"%s\"];\n", n->id, n->child[k]->id,
                    n->pol[k] > 0 ? "+" : "-");
    }
    for (int b = 0; b < w->nroots; b++)
        for (int i = 0; i < w->roots[b].nedge; i++) {
            const RootEdge *e = &w->roots[b].edge[i];
            if (e->kind == EDGE_PORT) {
                fprintf(out, "  root%d -> n%d;\n", b, e->node->id);
            } else {
                fprintf(out, "  s%d_%d [shape=circle,label=\"%s\\n%s\"];\n  root%d -> s%d_%d;\n", b, i,
                        c->elems[e->elem].name, e->kind == EDGE_V ? "ideal V" : e->kind == EDGE_I ? "ideal I" : "nonlinear",
                        b, b, i);
            }
        }
    fprintf(out, "}\n");
}

/* The subtree under top, one line per node, children indented. */
static void dump_node(const Wdf *w, WNode *top, FILE *out) {
    Items st = {0};
    items_push(&st, top, 1); /* pol: the node's polarity times its depth */
    while (st.len) {
        Item it = st.v[--st.len];
        const WNode *n = it.n;
        int depth = abs(it.pol);
        fprintf(out, "%*s%c%s", 2 * depth, "", it.pol > 0 ? '+' : '-',
                n->kind == W_LEAF ? w->c->elems[n->elem].name : n->kind == W_SERIES ? "series" : "parallel");
        fprintf(out, " R=%.6g\n", n->R);
        for (int i = n->nchild - 1; i >= 0; i--)
            items_push(&st, n->child[i], n->pol[i] * (depth + 1));
    }
}

void wdf_dump(const Wdf *w, FILE *out) {
    for (int b = 0; b < w->nroots; b++) {
        const Root *r = &w->roots[b];
        fprintf(out, "root %d: %d ports, %d nonlinear%s, %d ideal sources, %d core nodes\n", b, r->nport, r->nnl,
                r->joint ? " (solved jointly)" : "", r->nedge - r->nport - r->nnl, r->ncore);
        for (int i = 0; i < r->nedge; i++) {
            if (r->edge[i].kind == EDGE_PORT)
                dump_node(w, r->edge[i].node, out);
            else
                fprintf(out, "  %s %s\n", r->edge[i].kind == EDGE_NL ? "nonlinear" : "source",
                        w->c->elems[r->edge[i].elem].name);
        }
        for (int i = 0; i < r->nctl; i++)
            fprintf(out, "  %s %s\n", r->ctl[i].kind == E_OA ? "op-amp" : r->ctl[i].kind == E_XF ? "transformer" : "controlled",
                    w->c->elems[r->ctl[i].elem].name);
    }
}
