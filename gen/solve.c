/*
 * solve.c - linear networks solved in straight-line code.
 *
 * A voice solves small linear networks at control rate: a root adaptor's
 * matrix, the resistance a root presents to its nonlinear edge, the
 * Kirchhoff state reset and set_ic start from.  Their structure is known
 * when the voice is compiled and only their values change, so the
 * compiler does the elimination here and prints what is left: a few
 * lines of arithmetic in place of a dense LU with pivoting.
 *
 * The method.  Ideal voltage sources (and capacitors held at a voltage)
 * form a forest over the nodes; each tree is a supernode whose nodes
 * differ from its root by known voltages, and a tree that holds the
 * reference node is known outright.  What remains is nodal analysis of
 * the free supernodes: a weighted Laplacian, symmetric positive definite
 * when each free supernode reaches the reference through conductances.
 * It is eliminated without pivoting (stable for such a matrix) in a
 * minimum-degree order, over its structure: entries that are zero, one or
 * known numbers fold away as it is printed.  The currents of the sources
 * follow from Kirchhoff's current law, subtree by subtree of the forest.
 * A loop of voltage sources, a floating supernode, or an elimination too
 * large to print are refused (lin_factor returns false) and the voice
 * keeps its general solver.
 *
 * Printing.  A Sx collects the values (named temporaries, in order of
 * making) and statements; sx_code prints the statements and the
 * temporaries they need, and nothing else.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "gen.h"
#include "solve.h"

/* ---- values and their printing ---- */

typedef struct Item {
    const char *text; /* a temporary: its expression; a statement: its line */
    int dep[2];       /* temporaries it reads (-1: none) */
    int negof;        /* a negation: 1 + the temporary it negates; else 0 */
    char op;          /* + - * / n (negation) x (C text), for sx_eval */
    Sym a, b;         /* operands */
    bool stmt, live;
} Item;

struct Sx {
    const char *prefix; /* of the temporaries' names */
    Item *it;
    int n, cap;
    int next; /* number of the next temporary */
    int *num; /* item -> its temporary's number */
    int *hash; /* open addressing over the temporaries' texts, 1 + item (0: empty) */
    int nhash;
    int fence; /* items before it were made before the last statement */
    bool once;  /* a temporary read once is printed where it is read */
    int *once_in; /* sx_code: temporary -> 1 + the item it is printed in, else 0 */
};

static unsigned text_hash(const char *s) {
    unsigned h = 2166136261u;
    for (; *s; s++)
        h = (h ^ (unsigned char)*s) * 16777619u;
    return h;
}

Sx *sx_new(const char *prefix) {
    Sx *s = arena_alloc(sizeof *s);
    s->prefix = prefix;
    return s;
}

static int sx_push(Sx *s, Item it) {
    if (s->n == s->cap) {
        int cap = s->cap ? 2 * s->cap : 64;
        Item *n = arena_alloc(sizeof(Item) * (size_t)cap);
        int *num = arena_alloc(sizeof(int) * (size_t)cap);
        if (s->n) {
            memcpy(n, s->it, sizeof(Item) * (size_t)s->n);
            memcpy(num, s->num, sizeof(int) * (size_t)s->n);
        }
        s->it = n, s->num = num, s->cap = cap;
    }
    s->it[s->n] = it;
    s->num[s->n] = -1;
    return s->n++;
}

Sym sym_k(double c) { return (Sym){.t = -1, .c = c}; }

Sym sym_ext(const char *text) { return (Sym){.t = -1, .ext = text}; }

bool sym_number(Sym a) { return a.t < 0 && !a.ext; }

bool sym_is(Sym a, double c) { return sym_number(a) && a.c == c; }

/* The operand text of a: a number, an external's text, or a temporary's
 * name (a marker the printer resolves: "\001N\002", N its item). */
static const char *operand(Sym a) {
    if (a.ext)
        return strchr(a.ext, ' ') || a.ext[0] == '-' ? format("(%s)", a.ext) : a.ext;
    if (a.t >= 0)
        return format("\001%d\002", a.t);
    const char *s = format("%.17g", a.c);
    if (!strpbrk(s, ".eni"))
        s = format("%s.0", s);
    return a.c < 0 ? format("(%s)", s) : s;
}

/* The temporary holding text: the one made before with the same text
 * (the same value), or a new one. */
static Sym temp(Sx *s, char op, const char *text, Sym a, Sym b) {
    if (2 * (s->n + 1) > s->nhash) {
        int nh = s->nhash ? 2 * s->nhash : 256;
        int *h = arena_alloc(sizeof(int) * (size_t)nh);
        for (int i = 0; i < s->nhash; i++)
            if (s->hash[i]) {
                unsigned j = text_hash(s->it[s->hash[i] - 1].text) & (unsigned)(nh - 1);
                while (h[j])
                    j = (j + 1) & (unsigned)(nh - 1);
                h[j] = s->hash[i];
            }
        s->hash = h, s->nhash = nh;
    }
    unsigned j = text_hash(text) & (unsigned)(s->nhash - 1);
    for (; s->hash[j]; j = (j + 1) & (unsigned)(s->nhash - 1))
        if (!strcmp(s->it[s->hash[j] - 1].text, text)) {
            if (s->hash[j] - 1 >= s->fence)
                return (Sym){.t = s->hash[j] - 1};
            break; /* made before a statement: a new one takes its slot */
        }
    int t = sx_push(s, (Item){.text = text, .dep = {a.t, b.t}, .op = op, .a = a, .b = b});
    s->hash[j] = t + 1;
    return (Sym){.t = t};
}

Sym sx_temp(Sx *s, const char *text) { return temp(s, 'x', text, sym_k(0), sym_k(0)); }

Sym sx_neg(Sx *s, Sym a) {
    if (sym_number(a))
        return sym_k(-a.c);
    if (a.t >= 0 && s->it[a.t].negof)
        return (Sym){.t = s->it[a.t].negof - 1};
    Sym n = temp(s, 'n', format("-%s", operand(a)), a, sym_k(0));
    s->it[n.t].negof = a.t >= 0 ? a.t + 1 : 0;
    return n;
}

Sym sx_add(Sx *s, Sym a, Sym b) {
    if (sym_number(a) && sym_number(b))
        return sym_k(a.c + b.c);
    if (sym_is(a, 0))
        return b;
    if (sym_is(b, 0))
        return a;
    return temp(s, '+', format("%s + %s", operand(a), operand(b)), a, b);
}

Sym sx_sub(Sx *s, Sym a, Sym b) {
    if (sym_number(a) && sym_number(b))
        return sym_k(a.c - b.c);
    if (sym_is(b, 0))
        return a;
    if (sym_is(a, 0))
        return sx_neg(s, b);
    return temp(s, '-', format("%s - %s", operand(a), operand(b)), a, b);
}

Sym sx_mul(Sx *s, Sym a, Sym b) {
    if (sym_number(a) && sym_number(b))
        return sym_k(a.c * b.c);
    if (sym_is(a, 0) || sym_is(b, 0))
        return sym_k(0);
    if (sym_is(a, 1))
        return b;
    if (sym_is(b, 1))
        return a;
    if (sym_is(a, -1))
        return sx_neg(s, b);
    if (sym_is(b, -1))
        return sx_neg(s, a);
    return temp(s, '*', format("%s * %s", operand(a), operand(b)), a, b);
}

Sym sx_div(Sx *s, Sym a, Sym b) {
    if (sym_number(a) && sym_number(b))
        return sym_k(a.c / b.c);
    if (sym_is(a, 0))
        return sym_k(0);
    if (sym_is(b, 1))
        return a;
    if (sym_is(b, -1))
        return sx_neg(s, a);
    return temp(s, '/', format("%s / %s", operand(a), operand(b)), a, b);
}

const char *sx_use(Sx *s, Sym a) {
    if (a.t >= 0)
        s->it[a.t].live = true;
    return operand(a);
}

/* A statement may write what a temporary reads: none made before it is
 * reused after it (the fence, rather than clearing the table, which made
 * a statement per element quadratic). */
void sx_stmt(Sx *s, const char *line) {
    s->fence = sx_push(s, (Item){.text = line, .dep = {-1, -1}, .stmt = true}) + 1;
}

/* An operand's value once every temporary before it has one. */
static double value(const double *v, Sym a, double (*ext)(const char *, void *), void *ctx) {
    return a.ext ? ext(a.ext, ctx) : a.t < 0 ? a.c : v[a.t];
}

double *sx_run(Sx *s, double (*ext)(const char *text, void *ctx), void *ctx) {
    double *v = arena_alloc(sizeof(double) * (size_t)(s->n + 1));
    for (int i = 0; i < s->n; i++) {
        const Item *it = &s->it[i];
        double a = it->stmt ? 0 : value(v, it->a, ext, ctx), b = it->stmt ? 0 : value(v, it->b, ext, ctx);
        switch (it->stmt ? 0 : it->op) {
        case 0: break;
        case 'x': v[i] = ext(it->text, ctx); break;
        case 'n': v[i] = -a; break;
        case '+': v[i] = a + b; break;
        case '-': v[i] = a - b; break;
        case '*': v[i] = a * b; break;
        case '/': v[i] = a / b; break;
        default: unreachable();
        }
    }
    return v;
}

double sx_value(const double *v, Sym a, double (*ext)(const char *text, void *ctx), void *ctx) {
    return value(v, a, ext, ctx);
}

void sx_once(Sx *s, bool on) { s->once = on; }

/* text with each temporary's marker replaced by its name, or by its own
 * text in parentheses where it is printed in place */
static void put(Sx *s, Buf *o, const char *text) {
    for (const char *p = text; *p;) {
        const char *m = strchr(p, '\001');
        if (!m) {
            buf_add(o, "%s", p);
            break;
        }
        buf_add(o, "%.*s", (int)(m - p), p);
        int k = atoi(m + 1);
        if (s->once_in && s->once_in[k]) {
            buf_add(o, "(");
            put(s, o, s->it[k].text);
            buf_add(o, ")");
        } else
            buf_add(o, "%s%d", s->prefix, s->num[k]);
        p = strchr(m, '\002') + 1;
    }
}

/* The length of text as put prints it. */
static int put_len(Sx *s, const char *text) {
    int n = 0;
    for (const char *p = text; *p;) {
        const char *m = strchr(p, '\001');
        if (!m)
            return n + (int)strlen(p);
        n += (int)(m - p);
        int k = atoi(m + 1);
        n += s->once_in[k] ? 2 + put_len(s, s->it[k].text) : (int)strlen(s->prefix) + 4;
        p = strchr(m, '\002') + 1;
    }
    return n;
}

/* What statement text assigns, if it is one assignment "    LHS = ...;",
 * else NULL (it may write anything). */
static const char *assigns(const char *text) {
    const char *eq = strstr(text, " = "), *nl = strchr(text, '\n');
    if (strncmp(text, "    ", 4) || !eq || !nl || nl[1] || eq > nl || memchr(text + 4, ' ', (size_t)(eq - text - 4)))
        return NULL;
    return format("%.*s", (int)(eq - text - 4), text + 4);
}

/* The text of temporary k as put prints it. */
static const char *put_text(Sx *s, int k) {
    Buf b = {0};
    put(s, &b, s->it[k].text);
    return b.s ? b.s : "";
}

/* True if no statement between items k and u writes what temporary k
 * reads: a few assignments, none of whose targets its text names.
 * stmts[i] counts the statements among items 0..i-1, and sidx lists
 * them. */
static bool stays(Sx *s, int k, int u, const int *stmts, const int *sidx) {
    if (stmts[u] - stmts[k + 1] > 8)
        return false;
    const char *text = NULL;
    for (int j = stmts[k + 1]; j < stmts[u]; j++) {
        const char *w = assigns(s->it[sidx[j]].text);
        if (!w)
            return false;
        if (!text)
            text = put_text(s, k);
        if (strstr(text, w))
            return false;
    }
    return true;
}

/* With sx_once: each live temporary that one item reads, and once, is
 * printed inside that item, if no statement between them writes what it
 * reads and the text stays short. */
static void plan_once(Sx *s) {
    int *uses = arena_alloc(sizeof(int) * (size_t)(s->n + 1)), *user = arena_alloc(sizeof(int) * (size_t)(s->n + 1));
    int *stmts = arena_alloc(sizeof(int) * (size_t)(s->n + 1)), *sidx = arena_alloc(sizeof(int) * (size_t)(s->n + 1));
    s->once_in = arena_alloc(sizeof(int) * (size_t)(s->n + 1));
    for (int i = 0; i < s->n; i++) {
        stmts[i + 1] = stmts[i];
        if (s->it[i].stmt)
            sidx[stmts[i + 1]++] = i;
        if (!s->it[i].stmt && !s->it[i].live)
            continue;
        for (const char *m = strchr(s->it[i].text, '\001'); m; m = strchr(m + 1, '\001')) {
            int k = atoi(m + 1);
            uses[k]++, user[k] = i;
        }
    }
    for (int k = 0; k < s->n; k++)
        if (!s->it[k].stmt && s->it[k].live && uses[k] == 1 && put_len(s, s->it[k].text) <= 48 &&
            stays(s, k, user[k], stmts, sidx))
            s->once_in[k] = 1 + user[k];
}

void sx_code(Sx *s, Buf *o) {
    for (int i = s->n - 1; i >= 0; i--)
        if (s->it[i].live)
            for (int j = 0; j < 2; j++)
                if (s->it[i].dep[j] >= 0)
                    s->it[s->it[i].dep[j]].live = true;
    if (s->once)
        plan_once(s);
    for (int i = 0; i < s->n; i++) {
        const Item *it = &s->it[i];
        if (it->stmt) {
            put(s, o, it->text);
            continue;
        }
        if (!it->live || (s->once_in && s->once_in[i]))
            continue;
        s->num[i] = s->next++;
        buf_add(o, "    const double %s%d = ", s->prefix, s->num[i]);
        put(s, o, it->text);
        buf_add(o, ";\n");
    }
}

/* ---- networks ---- */

typedef struct LEdge {
    char kind; /* 'G' conductance (with a series emf), 'V' ideal voltage, 'J' current */
    int p, q;  /* nodes, n: the reference */
    Sym g;     /* G: its conductance */
} LEdge;

struct Lin {
    Sx *sx;
    int n, ne, cap;
    LEdge *e;
    /* lin_factor's results */
    int *comp;   /* node -> free supernode, -1 for the reference's tree */
    int *up;     /* node -> the edge to its parent in the forest, -1 at a root */
    int *order;  /* nodes (the reference included), parents before children */
    int m;       /* free supernodes */
    int *perm;   /* elimination order of the supernodes */
    Sym *A;      /* m x m: the factors, L below the diagonal (unit), U on and above */
};

Lin *lin_new(Sx *sx, int n) {
    Lin *L = arena_alloc(sizeof *L);
    L->sx = sx;
    L->n = n;
    return L;
}

static int lin_edge(Lin *L, char kind, int p, int q, Sym g) {
    if (L->ne == L->cap) {
        int cap = L->cap ? 2 * L->cap : 16;
        LEdge *e = arena_alloc(sizeof(LEdge) * (size_t)cap);
        if (L->ne)
            memcpy(e, L->e, sizeof(LEdge) * (size_t)L->ne);
        L->e = e, L->cap = cap;
    }
    L->e[L->ne] = (LEdge){kind, p < 0 ? L->n : p, q < 0 ? L->n : q, g};
    return L->ne++;
}

int lin_g(Lin *L, int p, int q, Sym g) { return lin_edge(L, 'G', p, q, g); }
int lin_v(Lin *L, int p, int q) { return lin_edge(L, 'V', p, q, sym_k(0)); }
int lin_j(Lin *L, int p, int q) { return lin_edge(L, 'J', p, q, sym_k(0)); }

static int find(int *uf, int a) {
    while (uf[a] != a)
        a = uf[a] = uf[uf[a]];
    return a;
}

/* The most arithmetic an elimination may print before the voice keeps
 * its general solver instead. */
#define MAX_OPS 20000

bool lin_factor(Lin *L) {
    const int n = L->n, N = n + 1;
    int *uf = arena_alloc(sizeof(int) * (size_t)N);
    for (int i = 0; i < N; i++)
        uf[i] = i;
    /* the forest of voltage sources; a loop of them is refused */
    int *deg = arena_alloc(sizeof(int) * (size_t)(N + 1));
    for (int k = 0; k < L->ne; k++) {
        const LEdge *e = &L->e[k];
        if (e->kind != 'V')
            continue;
        int a = find(uf, e->p), b = find(uf, e->q);
        if (a == b)
            return false;
        uf[a] = b;
        deg[e->p]++, deg[e->q]++;
    }
    /* adjacency of the forest, then each tree from its root: the
     * reference, or its lowest node */
    int *first = arena_alloc(sizeof(int) * (size_t)(N + 1)), *adj = arena_alloc(sizeof(int) * (size_t)(2 * L->ne + 1));
    for (int i = 0; i < N; i++)
        first[i + 1] = first[i] + deg[i];
    int *fill = arena_alloc(sizeof(int) * (size_t)N);
    for (int k = 0; k < L->ne; k++)
        if (L->e[k].kind == 'V') {
            adj[first[L->e[k].p] + fill[L->e[k].p]++] = k;
            adj[first[L->e[k].q] + fill[L->e[k].q]++] = k;
        }
    L->comp = arena_alloc(sizeof(int) * (size_t)N);
    L->up = arena_alloc(sizeof(int) * (size_t)N);
    L->order = arena_alloc(sizeof(int) * (size_t)N);
    bool *seen = arena_alloc(sizeof(bool) * (size_t)N);
    int no = 0;
    L->m = 0;
    for (int r0 = 0; r0 < N; r0++) {
        int r = r0 == 0 ? n : r0 - 1; /* the reference's tree first */
        if (seen[r])
            continue;
        int c = r == n ? -1 : L->m++;
        int head = no;
        seen[r] = true;
        L->up[r] = -1;
        L->order[no++] = r;
        for (; head < no; head++) {
            int u = L->order[head];
            L->comp[u] = c;
            for (int j = first[u]; j < first[u + 1]; j++) {
                const LEdge *e = &L->e[adj[j]];
                int v = e->p == u ? e->q : e->p;
                if (!seen[v]) {
                    seen[v] = true;
                    L->up[v] = adj[j];
                    L->order[no++] = v;
                }
            }
        }
    }
    const int m = L->m;
    if ((double)m * m * m / 3 > 4.0 * MAX_OPS * MAX_OPS)
        return false;
    /* every free supernode must reach the reference through conductances */
    int *cu = arena_alloc(sizeof(int) * (size_t)(m + 1));
    for (int i = 0; i <= m; i++)
        cu[i] = i;
    for (int k = 0; k < L->ne; k++) {
        const LEdge *e = &L->e[k];
        int a = L->comp[e->p], b = L->comp[e->q];
        if (e->kind == 'G' && a != b)
            cu[find(cu, a < 0 ? m : a)] = find(cu, b < 0 ? m : b);
    }
    for (int i = 0; i < m; i++)
        if (find(cu, i) != find(cu, m))
            return false;
    /* the structure of the supernodes' matrix, and a minimum-degree order
     * of elimination; too much fill and the general solver stays */
    bool *P = arena_alloc(sizeof(bool) * (size_t)m * (size_t)m);
    for (int k = 0; k < L->ne; k++) {
        const LEdge *e = &L->e[k];
        int a = L->comp[e->p], b = L->comp[e->q];
        if (e->kind == 'G' && a != b && a >= 0 && b >= 0)
            P[(size_t)a * m + b] = P[(size_t)b * m + a] = true;
    }
    L->perm = arena_alloc(sizeof(int) * (size_t)(m + 1));
    bool *done = arena_alloc(sizeof(bool) * (size_t)(m + 1));
    long ops = 0;
    for (int s = 0; s < m; s++) {
        int best = -1, bd = 0;
        for (int i = 0; i < m; i++) {
            if (done[i])
                continue;
            int d = 0;
            for (int j = 0; j < m; j++)
                d += !done[j] && j != i && P[(size_t)i * m + j];
            if (best < 0 || d < bd)
                best = i, bd = d;
        }
        L->perm[s] = best;
        done[best] = true;
        ops += (long)bd * (bd + 1);
        if (ops > MAX_OPS)
            return false;
        for (int i = 0; i < m; i++)
            for (int j = 0; j < m && !done[i] && P[(size_t)best * m + i]; j++)
                if (!done[j] && P[(size_t)best * m + j])
                    P[(size_t)i * m + j] = true;
    }
    /* the matrix in elimination order, then its factors */
    int *pos = arena_alloc(sizeof(int) * (size_t)(m + 1));
    for (int s = 0; s < m; s++)
        pos[L->perm[s]] = s;
    Sx *sx = L->sx;
    Sym *A = L->A = arena_alloc(sizeof(Sym) * (size_t)m * (size_t)m + 1);
    for (size_t i = 0; i < (size_t)m * m; i++)
        A[i] = sym_k(0);
    for (int k = 0; k < L->ne; k++) {
        const LEdge *e = &L->e[k];
        int a = L->comp[e->p], b = L->comp[e->q];
        if (e->kind != 'G' || a == b)
            continue;
        a = a < 0 ? -1 : pos[a], b = b < 0 ? -1 : pos[b];
        if (a >= 0)
            A[(size_t)a * m + a] = sx_add(sx, A[(size_t)a * m + a], e->g);
        if (b >= 0)
            A[(size_t)b * m + b] = sx_add(sx, A[(size_t)b * m + b], e->g);
        if (a >= 0 && b >= 0) {
            A[(size_t)a * m + b] = sx_sub(sx, A[(size_t)a * m + b], e->g);
            A[(size_t)b * m + a] = sx_sub(sx, A[(size_t)b * m + a], e->g);
        }
    }
    for (int k = 0; k < m; k++)
        for (int i = k + 1; i < m; i++) {
            Sym *lik = &A[(size_t)i * m + k];
            if (sym_is(*lik, 0))
                continue;
            *lik = sx_div(sx, *lik, A[(size_t)k * m + k]);
            for (int j = k + 1; j < m; j++)
                if (!sym_is(A[(size_t)k * m + j], 0))
                    A[(size_t)i * m + j] = sx_sub(sx, A[(size_t)i * m + j], sx_mul(sx, *lik, A[(size_t)k * m + j]));
        }
    return true;
}

void lin_solve(Lin *L, const Sym *val, Sym *pot, Sym *cur) {
    Sx *sx = L->sx;
    const int n = L->n, N = n + 1, m = L->m;
    /* each node against its tree's root, then the right-hand side of
     * each free supernode's current law */
    Sym *off = arena_alloc(sizeof(Sym) * (size_t)N);
    for (int k = 0; k < N; k++) {
        int u = L->order[k], e = L->up[u];
        if (e < 0) {
            off[u] = sym_k(0);
            continue;
        }
        const LEdge *d = &L->e[e];
        off[u] = d->p == u ? sx_add(sx, off[d->q], val[e]) : sx_sub(sx, off[d->p], val[e]);
    }
    int *pos = arena_alloc(sizeof(int) * (size_t)(m + 1));
    for (int s = 0; s < m; s++)
        pos[L->perm[s]] = s;
    Sym *x = arena_alloc(sizeof(Sym) * (size_t)(m + 1));
    for (int s = 0; s < m; s++)
        x[s] = sym_k(0);
    for (int k = 0; k < L->ne; k++) {
        const LEdge *e = &L->e[k];
        int a = L->comp[e->p], b = L->comp[e->q];
        if (e->kind == 'V' || a == b)
            continue;
        /* the current it carries from p to q, but for the supernodes'
         * unknowns: outflow of a, inflow of b */
        Sym i = e->kind == 'J' ? val[k] : sx_mul(sx, e->g, sx_sub(sx, sx_sub(sx, off[e->p], off[e->q]), val[k]));
        if (a >= 0)
            x[pos[a]] = sx_sub(sx, x[pos[a]], i);
        if (b >= 0)
            x[pos[b]] = sx_add(sx, x[pos[b]], i);
    }
    const Sym *A = L->A;
    for (int k = 0; k < m; k++)
        for (int i = k + 1; i < m; i++)
            if (!sym_is(A[(size_t)i * m + k], 0))
                x[i] = sx_sub(sx, x[i], sx_mul(sx, A[(size_t)i * m + k], x[k]));
    for (int k = m - 1; k >= 0; k--) {
        for (int j = k + 1; j < m; j++)
            if (!sym_is(A[(size_t)k * m + j], 0))
                x[k] = sx_sub(sx, x[k], sx_mul(sx, A[(size_t)k * m + j], x[j]));
        x[k] = sx_div(sx, x[k], A[(size_t)k * m + k]);
    }
    Sym *v = arena_alloc(sizeof(Sym) * (size_t)N);
    for (int u = 0; u < N; u++)
        v[u] = L->comp[u] < 0 ? off[u] : sx_add(sx, x[pos[L->comp[u]]], off[u]);
    if (pot)
        for (int u = 0; u < n; u++)
            pot[u] = v[u];
    if (!cur)
        return;
    /* currents: a conductance's and a source's from their values; a
     * voltage source's from the current law of the subtree it holds */
    Sym *out = arena_alloc(sizeof(Sym) * (size_t)N);
    for (int u = 0; u < N; u++)
        out[u] = sym_k(0);
    for (int k = 0; k < L->ne; k++) {
        const LEdge *e = &L->e[k];
        if (e->kind == 'V')
            continue;
        cur[k] = e->kind == 'J' ? val[k] : sx_mul(sx, e->g, sx_sub(sx, sx_sub(sx, v[e->p], v[e->q]), val[k]));
        out[e->p] = sx_add(sx, out[e->p], cur[k]);
        out[e->q] = sx_sub(sx, out[e->q], cur[k]);
    }
    for (int k = N - 1; k >= 0; k--) {
        int u = L->order[k], e = L->up[u];
        if (e < 0)
            continue;
        const LEdge *d = &L->e[e];
        int parent = d->p == u ? d->q : d->p;
        cur[e] = d->p == u ? sx_neg(sx, out[u]) : out[u];
        out[parent] = sx_add(sx, out[parent], out[u]);
    }
}
