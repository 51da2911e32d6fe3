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
static bool at_root(const Elem *e) { return ((e->kind == E_V || e->kind == E_I) && !e->val) || e->kind == E_NL; }

static double leaf_R(const Circuit *c, const Elem *e, const double *p, double fs) {
    double v = elem_value(c, e, p);
    switch (e->kind) {
    case E_C: return 1 / (2 * fs * v);
    case E_L: return 2 * fs * v;
    default: return v;
    }
}

static WNode *new_node(WKind k, int u, int w) {
    WNode *n = arena_alloc(sizeof(WNode));
    n->kind = k;
    n->u = u;
    n->w = w;
    n->elem = -1;
    return n;
}

/* Adds child c with polarity pol to adaptor a, flattening a child of the
 * same kind into a. */
static void add_child(WNode *a, WNode *c, int pol, int *cap) {
    if (c->kind == a->kind) {
        for (int i = 0; i < c->nchild; i++)
            add_child(a, c->child[i], pol * c->pol[i], cap);
        return;
    }
    if (a->nchild == *cap) {
        *cap = *cap ? 2 * *cap : 4;
        WNode **ch = arena_alloc(sizeof(WNode *) * (size_t)*cap);
        int *po = arena_alloc(sizeof(int) * (size_t)*cap);
        if (a->nchild) {
            memcpy(ch, a->child, sizeof(WNode *) * (size_t)a->nchild);
            memcpy(po, a->pol, sizeof(int) * (size_t)a->nchild);
        }
        a->child = ch;
        a->pol = po;
    }
    a->child[a->nchild] = c;
    a->pol[a->nchild++] = pol;
    c->parent = a;
}

static WNode *combine(WKind k, Edge *e1, int p1, Edge *e2, int p2, int u, int w) {
    WNode *n = new_node(k, u, w);
    int cap = 0;
    add_child(n, e1->node, p1, &cap);
    add_child(n, e2->node, p2, &cap);
    double s = 0;
    for (int i = 0; i < n->nchild; i++) {
        s += k == W_SERIES ? n->child[i]->R : 1 / n->child[i]->R;
        n->pmask |= n->child[i]->pmask;
    }
    n->R = k == W_SERIES ? s : 1 / s;
    return n;
}

/* One parallel merge; returns true if it found one. */
static bool reduce_parallel(Edge *E, int ne) {
    for (int i = 0; i < ne; i++) {
        if (!E[i].alive || !E[i].node)
            continue;
        for (int j = i + 1; j < ne; j++) {
            if (!E[j].alive || !E[j].node)
                continue;
            bool same = E[i].u == E[j].u && E[i].w == E[j].w;
            bool rev = E[i].u == E[j].w && E[i].w == E[j].u;
            if (!same && !rev)
                continue;
            E[i].node = combine(W_PARALLEL, &E[i], 1, &E[j], same ? 1 : -1, E[i].u, E[i].w);
            E[j].alive = false;
            return true;
        }
    }
    return false;
}

/* One series merge at a node with exactly two edges. */
static bool reduce_series(Edge *E, int ne, int nnodes) {
    for (int n = 0; n < nnodes; n++) {
        int cnt = 0, at[3];
        for (int i = 0; i < ne && cnt < 3; i++)
            if (E[i].alive && (E[i].u == n || E[i].w == n))
                at[cnt++] = i;
        if (cnt != 2)
            continue;
        Edge *a = &E[at[0]], *b = &E[at[1]];
        if (!a->node || !b->node || a->u == a->w || b->u == b->w)
            continue;
        int x = a->u == n ? a->w : a->u;
        int y = b->u == n ? b->w : b->u;
        if (x == y)
            continue; /* a parallel pair: left to reduce_parallel */
        int pa = a->u == x ? 1 : -1; /* a runs x -> n */
        int pb = b->u == n ? 1 : -1; /* b runs n -> y */
        a->node = combine(W_SERIES, a, pa, b, pb, x, y);
        a->u = x;
        a->w = y;
        b->alive = false;
        return true;
    }
    return false;
}

static void number(Wdf *w, WNode *n, Vec *order) {
    for (int i = 0; i < n->nchild; i++)
        number(w, n->child[i], order);
    n->id = order->len;
    vec_push(order, n);
}

/* One nonlinear element per root: several need a delay between them. */
static void check_nonlinear(Wdf *wd, const Root *r) {
    if (r->nnl <= 1)
        return;
    const Elem *first = &wd->c->elems[r->edge[r->nport].elem];
    const Elem *second = &wd->c->elems[r->edge[r->nport + 1].elem];
    error_begin(second->pos, "'%s' and '%s' are coupled with no delay between them: each instantaneously "
                "coupled part may hold one nonlinear element; a delay element between them (a transmission "
                "line, string or tube) would decouple them", first->name, second->name);
    note_at(first->pos, "'%s' is here", first->name);
    for (int k = r->nport + 2; k < r->nport + r->nnl; k++)
        note_at(wd->c->elems[r->edge[k].elem].pos, "'%s', coupled to them too, is here",
                wd->c->elems[r->edge[k].elem].name);
    error_end();
}

/* Gives nonlinear edge k the resistance the rest of the core presents to
 * it, so that the wave the root sends it does not depend on its own. */
static void adapt_nonlinear(Wdf *wd, Root *r, int k) {
    const Elem *e = &wd->c->elems[r->edge[k].elem];
    r->R[k] = 1; /* unused by the solve, which leaves edge k out */
    double Rth;
    if (scatter_thevenin(r, r->R, k, &Rth) < 0 || !(Rth < 1e300))
        error_at(e->pos, "%s '%s' has no closed path through the rest of the network: no current can flow "
                 "through it", block_desc[e->user_kind].desc, e->name);
    if (!(Rth > 0))
        error_at(e->pos, "%s '%s' sits directly across an ideal source: nothing limits its current "
                 "(put a resistance in series)", block_desc[e->user_kind].desc, e->name);
    r->R[k] = Rth;
}

static void build_root(Wdf *wd, Root *r, Edge *E, int ne) {
    Circuit *c = wd->c;
    int *core = arena_alloc(sizeof(int) * (size_t)c->nnodes);
    for (int i = 0; i < c->nnodes; i++)
        core[i] = -2;
    r->ref_node = -1;
    for (int i = 0; i < ne; i++)
        if (E[i].alive) {
            core[E[i].u] = core[E[i].w] = -1;
            if (E[i].u == 0 || E[i].w == 0)
                r->ref_node = 0;
            if (r->ref_node < 0)
                r->ref_node = E[i].u;
        }
    r->core_node = arena_alloc(sizeof(int) * (size_t)c->nnodes);
    for (int n = 0; n < c->nnodes; n++)
        if (core[n] == -1 && n != r->ref_node) {
            core[n] = r->ncore;
            r->core_node[r->ncore++] = n;
        }
    core[r->ref_node] = -1;
    r->edge = arena_alloc(sizeof(RootEdge) * (size_t)ne);
    /* ports first, then nonlinear edges, V sources, I sources */
    static const int order[] = {0, 3, 1, 2};
    for (int pass = 0; pass < 4; pass++)
        for (int i = 0; i < ne; i++) {
            if (!E[i].alive)
                continue;
            ElemKind ek = E[i].node ? E_R : c->elems[E[i].src].kind;
            int kind = E[i].node ? 0 : ek == E_V ? 1 : ek == E_I ? 2 : 3;
            if (kind != order[pass])
                continue;
            RootEdge *re = &r->edge[r->nedge++];
            re->kind = kind;
            re->node = E[i].node;
            re->elem = E[i].src;
            re->p = core[E[i].u];
            re->q = core[E[i].w];
            if (kind == 0) {
                r->nport++;
                r->pmask |= E[i].node->pmask;
            }
            if (kind == 1)
                r->nv++;
            if (kind == 3)
                r->nnl++;
        }
    check_nonlinear(wd, r);
    r->M = arena_alloc(sizeof(double) * (size_t)(r->nedge * r->nedge));
    double *R = r->R = arena_alloc(sizeof(double) * (size_t)(r->nport + r->nnl + 1));
    for (int i = 0; i < r->nport; i++)
        R[i] = r->edge[i].node->R;
    for (int i = r->nport; i < r->nport + r->nnl; i++)
        adapt_nonlinear(wd, r, i);
    bool singular = scatter_root(r, R, r->M) < 0;
    if (singular && r->nedge == r->nport + r->nnl)
        error_at(c->elems[0].pos, "the network's equations are singular: its element values span too wide a "
                 "range to solve in double precision");
    if (singular) {
        Vec names = {0};
        for (int i = r->nport + r->nnl; i < r->nedge; i++)
            vec_push(&names, (void *)c->elems[r->edge[i].elem].name);
        const Elem *e0 = &c->elems[r->edge[r->nport + r->nnl].elem];
        char *list = "";
        for (int i = 0; i < names.len; i++)
            list = format("%s%s'%s'", list, i ? ", " : "", (char *)names.data[i]);
        error_at(e0->pos, "the ideal sources %s cannot all hold: voltage sources form a loop or "
                 "current sources a cut-set (give one a series or parallel resistance, R=)", list);
    }
}

/* Biconnected blocks of the element graph (alive edges): two edges share
 * a block if a simple cycle holds both.  Blocks that meet at one node
 * exchange no current, so each is solved on its own.  Depth-first search
 * with low points and a stack of edges; returns the number of blocks and
 * sets block[i] for every alive edge. */
typedef struct Dfs {
    Edge *E;
    int ne, nblocks, time;
    int *disc, *low, *stack, sp, *block;
} Dfs;

static void dfs(Dfs *d, int v, int via) {
    d->disc[v] = d->low[v] = ++d->time;
    for (int i = 0; i < d->ne; i++) {
        Edge *e = &d->E[i];
        if (!e->alive || i == via || (e->u != v && e->w != v))
            continue;
        int u = e->u == v ? e->w : e->u;
        if (!d->disc[u]) {
            d->stack[d->sp++] = i;
            dfs(d, u, i);
            if (d->low[u] < d->low[v])
                d->low[v] = d->low[u];
            if (d->low[u] >= d->disc[v]) { /* v separates: pop one block */
                int k;
                do {
                    k = d->stack[--d->sp];
                    d->block[k] = d->nblocks;
                } while (k != i);
                d->nblocks++;
            }
        } else if (d->disc[u] < d->disc[v]) {
            d->stack[d->sp++] = i;
            if (d->disc[u] < d->low[v])
                d->low[v] = d->disc[u];
        }
    }
}

static int blocks(Edge *E, int ne, int nnodes, int *block) {
    Dfs d = {.E = E, .ne = ne, .block = block};
    d.disc = arena_alloc(sizeof(int) * (size_t)nnodes);
    d.low = arena_alloc(sizeof(int) * (size_t)nnodes);
    d.stack = arena_alloc(sizeof(int) * (size_t)(ne + 1));
    for (int i = 0; i < ne; i++)
        block[i] = -1;
    for (int v = 0; v < nnodes; v++)
        if (!d.disc[v])
            dfs(&d, v, -1);
    return d.nblocks;
}

static void build_paths(Wdf *w) {
    Circuit *c = w->c;
    int nn = c->nnodes;
    int *pe = arena_alloc(sizeof(int) * (size_t)nn), *ps = arena_alloc(sizeof(int) * (size_t)nn);
    int *from = arena_alloc(sizeof(int) * (size_t)nn), *queue = arena_alloc(sizeof(int) * (size_t)nn);
    bool *seen = arena_alloc(sizeof(bool) * (size_t)nn);
    int head = 0, tail = 0;
    queue[tail++] = 0;
    seen[0] = true;
    while (head < tail) {
        int n = queue[head++];
        for (int i = 0; i < c->nelems; i++)
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
    w->path = arena_alloc(sizeof(int *) * (size_t)nn);
    w->pathlen = arena_alloc(sizeof(int) * (size_t)nn);
    for (int n = 1; n < nn; n++) {
        int len = 0;
        for (int m = n; m != 0; m = from[m])
            len++;
        w->path[n] = arena_alloc(sizeof(int) * (size_t)(2 * len));
        w->pathlen[n] = len;
        int k = len;
        for (int m = n; m != 0; m = from[m]) {
            k--;
            w->path[n][2 * k] = pe[m];
            w->path[n][2 * k + 1] = ps[m];
        }
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
    w->roots = arena_alloc(sizeof(Root) * (size_t)w->nroots);
    Edge *sub = arena_alloc(sizeof(Edge) * (size_t)c->nelems);
    for (int b = 0; b < w->nroots; b++) {
        for (int i = 0; i < c->nelems; i++) {
            sub[i] = E[i];
            sub[i].alive = block[i] == b;
        }
        while (reduce_parallel(sub, c->nelems) || reduce_series(sub, c->nelems, c->nnodes))
            ;
        build_root(w, &w->roots[b], sub, c->nelems);
    }
    Vec order = {0};
    for (int b = 0; b < w->nroots; b++)
        for (int i = 0; i < w->roots[b].nport; i++) {
            int first = order.len;
            number(w, w->roots[b].edge[i].node, &order);
            for (int k = first; k < order.len; k++)
                ((WNode *)order.data[k])->root = b;
        }
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
            if (e->kind == 0) {
                fprintf(out, "  root%d -> n%d;\n", b, e->node->id);
            } else {
                fprintf(out, "  s%d_%d [shape=circle,label=\"%s\\n%s\"];\n  root%d -> s%d_%d;\n", b, i,
                        c->elems[e->elem].name, e->kind == 1 ? "ideal V" : e->kind == 2 ? "ideal I" : "nonlinear",
                        b, b, i);
            }
        }
    fprintf(out, "}\n");
}

static void dump_node(const Wdf *w, const WNode *n, int depth, int pol, FILE *out) {
    fprintf(out, "%*s%c%s", 2 * depth, "", pol > 0 ? '+' : '-',
            n->kind == W_LEAF ? w->c->elems[n->elem].name : n->kind == W_SERIES ? "series" : "parallel");
    fprintf(out, " R=%.6g\n", n->R);
    for (int i = 0; i < n->nchild; i++)
        dump_node(w, n->child[i], depth + 1, n->pol[i], out);
}

void wdf_dump(const Wdf *w, FILE *out) {
    for (int b = 0; b < w->nroots; b++) {
        const Root *r = &w->roots[b];
        fprintf(out, "root %d: %d ports, %d nonlinear, %d ideal sources, %d core nodes\n", b, r->nport, r->nnl,
                r->nedge - r->nport - r->nnl, r->ncore);
        for (int i = 0; i < r->nedge; i++) {
            if (r->edge[i].kind == 0)
                dump_node(w, r->edge[i].node, 1, 1, out);
            else
                fprintf(out, "  %s %s\n", r->edge[i].kind == 3 ? "nonlinear" : "source",
                        w->c->elems[r->edge[i].elem].name);
        }
    }
}
