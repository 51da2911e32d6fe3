/* emit.c: Wdf -> C text of a voice, through the templates in templates/.
 *
 * Code is generated into memory: each template hole ({{name}}) is filled
 * from a table of strings built here, and the files are written only once
 * all of it succeeded.  The sample loop is straight-line code: a forward
 * pass computing the waves each subtree reflects towards the root, the
 * root's matrix, and a backward pass sending waves down to the leaves. */
#include <ctype.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "gen.h"
#include "solve.h"

extern const char tmpl_voice_c[], tmpl_voice_h[], tmpl_wdvoice_h[], tmpl_nl_diode_i[], tmpl_nl_wright[], tmpl_nl_diode[], tmpl_nl_omega[], tmpl_nl_fast[], tmpl_nl_fast_lane[],
    tmpl_nl_pwl[], tmpl_nl_law[], tmpl_nl_passive[], tmpl_nl_memory[], tmpl_nl_g[], tmpl_nl_joint[], tmpl_nl_memcap[], tmpl_waveguide[], tmpl_waveguide_state[],
    tmpl_lu[], tmpl_retune[], tmpl_root[], tmpl_nl_adapt[], tmpl_settle[], tmpl_params[], tmpl_ctl_stamp[];

/* Arguments that name a mutated element's inner law for the mem_ kernels. */
static const char *mem_args(int k, const NlSpec *nl) {
    if (nl->kind == NL_DIODE)
        return format("c_nl%d_0, c_nl%d_1, %d, NULL, NULL, 0", k, k, nl->pair);
    return format("0, 1, 0, mem_v%d, mem_i%d, %d", k, k, nl->npts);
}

/* Coefficient j of nonlinear element k: the sample loop's local, or the
 * state's field. */
static const char *nl_coef(int k, int j, bool local) {
    return local ? format("c_nl%d_%d", k, j) : format("st->c_nl[%d]", 4 * k + j);
}

/* Initialiser of the el_law of nonlinear element k: a contact, or the
 * diode or curve behind a mutator. */
static const char *el_law_init(int k, const NlSpec *nl, bool local) {
    if (nl->kind == NL_CONTACT)
        return format("{1, %s, %s, %s, 0, 1, 0, 0, NULL, NULL}", nl_coef(k, 0, local), nl_coef(k, 1, local),
                      nl_coef(k, 2, local));
    if (nl->kind == NL_DIODE)
        return format("{0, 0, 1, 0, %s, %s, %d, 0, NULL, NULL}", nl_coef(k, 0, local), nl_coef(k, 1, local),
                      nl->pair);
    return format("{0, 0, 1, 0, 0, 1, 0, %d, mem_v%d, mem_i%d}", nl->npts, k, k);
}

#define emit buf_add

static const char *str(Buf *b) { return b->s ? b->s : ""; }

/* ---- names: what the printed text uses ----
 *
 * The printer keeps a statement, a local or a helper only when some kept
 * text names it.  A Names is a set of the identifiers of C text (those in
 * comments and string literals left out). */

typedef struct Names {
    const char **key; /* open addressing, NULL: empty; not terminated: */
    size_t *len;      /* each key's length (keys point into the text named) */
    size_t cap, n;
} Names;

static uint32_t name_hash(const char *s, size_t len) {
    uint32_t h = 2166136261u;
    for (size_t i = 0; i < len; i++)
        h = (h ^ (unsigned char)s[i]) * 16777619u;
    return h;
}

static bool names_find(const Names *t, const char *s, size_t len, size_t *slot) {
    if (!t->cap)
        return false;
    size_t i = name_hash(s, len) & (t->cap - 1);
    for (; t->key[i]; i = (i + 1) & (t->cap - 1))
        if (t->len[i] == len && !memcmp(t->key[i], s, len))
            break;
    *slot = i;
    return t->key[i] != NULL;
}

/* Adds the name s[0..len), which must stay as it is while t is used. */
static void names_put(Names *t, const char *s, size_t len) {
    size_t i;
    if (2 * (t->n + 1) > t->cap) {
        size_t cap = t->cap ? 2 * t->cap : 64;
        Names u = {arena_alloc(sizeof(char *) * cap), arena_alloc(sizeof(size_t) * cap), cap, 0};
        for (size_t k = 0; k < t->cap; k++)
            if (t->key[k]) {
                names_find(&u, t->key[k], t->len[k], &i);
                u.key[i] = t->key[k], u.len[i] = t->len[k];
                u.n++;
            }
        *t = u;
    }
    if (!names_find(t, s, len, &i)) {
        t->key[i] = s, t->len[i] = len;
        t->n++;
    }
}

static bool names_has_n(const Names *t, const char *name, size_t len) {
    size_t i;
    return names_find(t, name, len, &i);
}

static bool names_has(const Names *t, const char *name) { return names_has_n(t, name, strlen(name)); }

static bool ident_char(char ch) {
    return (ch >= 'a' && ch <= 'z') || (ch >= 'A' && ch <= 'Z') || (ch >= '0' && ch <= '9') || ch == '_';
}

/* The end of the comment that starts at s ("/" "*"): just past its close,
 * or the end of the text.  By hand, as strstr need not stop at the first
 * match without first measuring the whole text. */
static const char *comment_end(const char *s) {
    for (s += 2; *s && !(s[0] == '*' && s[1] == '/'); s++)
        ;
    return *s ? s + 2 : s;
}

/* The next identifier of C text from *s (numbers, comments and literals
 * skipped): its start, its length in *len, and *s just past it; NULL at
 * the end of the text. */
static const char *next_ident(const char **sp, size_t *len) {
    const char *s = *sp;
    while (*s) {
        if (s[0] == '/' && s[1] == '*') {
            s = comment_end(s);
        } else if (*s == '"' || *s == '\'') {
            char q = *s++;
            while (*s && *s != q)
                s += s[0] == '\\' && s[1] ? 2 : 1;
            s += *s != 0;
        } else if (ident_char(*s)) {
            const char *b = s;
            while (ident_char(*s))
                s++;
            if (!(*b >= '0' && *b <= '9')) {
                *sp = s, *len = (size_t)(s - b);
                return b;
            }
        } else {
            s++;
        }
    }
    *sp = s;
    return NULL;
}

/* Adds every identifier of C text. */
static void names_scan(Names *t, const char *s) {
    size_t len;
    for (const char *b; (b = next_ident(&s, &len));)
        names_put(t, b, len);
}

/* Adds the identifiers of C text that `want` holds: a small set, where a
 * large text's every name would make a large one. */
static void names_scan_in(Names *t, const char *s, const Names *want) {
    size_t len;
    for (const char *b; (b = next_ident(&s, &len));)
        if (names_has_n(want, b, len))
            names_put(t, b, len);
}

/* True if C text names `name`: a scan that stops at the first use. */
static bool uses(const char *text, const char *name) {
    size_t n = strlen(name), len;
    for (const char *b; (b = next_ident(&text, &len));)
        if (len == n && !memcmp(b, name, n))
            return true;
    return false;
}

/* True if text calls a function other than flush_lane and fabs (which
 * a loop over the lanes vectorises). */
static bool calls_out(const char *text) {
    size_t len;
    for (const char *b; (b = next_ident(&text, &len));)
        if (*text == '(' && !(len == 10 && !memcmp(b, "flush_lane", 10)) && !(len == 4 && !memcmp(b, "fabs", 4)) &&
            !(len == 5 && !memcmp(b, "fabsf", 5)))
            return true;
    return false;
}

/* True if any of the n texts names `name`. */
static bool uses_any(const char *const *texts, int n, const char *name) {
    for (int i = 0; i < n; i++)
        if (uses(texts[i], name))
            return true;
    return false;
}

/* ---- emission context ---- */

/* One statement of the sample loop: `def` names the temporary it defines,
 * kept only if a later kept statement names it; a statement without one
 * stores a state or an output and always stays. */
typedef struct Stmt {
    const char *def, *text;
    int own;    /* the root whose tree it computes, -1: none */
    char phase; /* 'f' forward, 'a' a nonlinear edge's incident wave, 'r' root, 'b' backward,
                   'p' the wave that last arrived at a waveguide port, 0 other */
} Stmt;

/* A local of process, loaded before the sample loop: `name` (NULL: always
 * there), its declaration, and for a state the lines that store it back
 * after the loop and flush it between runs. */
typedef struct Local {
    const char *name, *decl, *wb, *fl;
} Local;

/* A statement of update(), the control-rate code, in order: its lines
 * (a guard included), the coefficient slot it stores ("c_k[3]", NULL for
 * none) and the adaptor it belongs to (-1: none).  A coefficient nothing
 * reads is not computed, and an adaptor left storing nothing goes whole
 * (prune_update). */
typedef struct Upd {
    const char *text, *store;
    int block;
} Upd;

typedef struct Ctx {
    const Wdf *w;
    const Circuit *c;
    bool single;
    bool energy;     /* work accounting in process */
    bool settle;     /* reset and set_ic solve for a consistent Kirchhoff state */
    bool ic_direct;  /* strike target k sets react[k] and nothing else */
    bool flushes;    /* process flushes tiny states, every FLUSH_RUN samples counted across calls */
    Stmt *stmt;      /* the sample loop, in order */
    int nstmt, capstmt;
    Upd *upd;        /* update(), in order */
    int nupd, capupd;
    Local *loc;      /* the locals of process, in order */
    int nloc, caploc;
    int *react;      /* tree node -> reactance index or -1 */
    int *koff;       /* tree node -> first coefficient in c_k */
    int nk, nreact;
    int *src;        /* element -> source index or -1 */
    int nsrc;
    int nctl;        /* controlled sources and op-amps (their outputs) */
    int ncc;         /* transistors' current-controlled sources */
    double *nlop;    /* a deck's operating point with nonlinear elements or
                        controlled sources (dcop_nonlinear): each element's
                        current there, or NULL */
    int *nl_root;    /* nonlinear index -> its root */
    int *nl_edge;    /* nonlinear index -> its edge in that root */
    int *nl_first;   /* root -> nonlinear index of its first nonlinear edge */
    int *moff;       /* root -> offset of its matrix in c_M */
    bool **mzero;    /* root -> its matrix's entries that vanish for any port resistances */
    const char **rfn; /* root -> its straight-line solve (solve.c), "" if its matrix is all numbers, NULL: root_solve */
    bool **mnum;     /* root -> its matrix's entries that are numbers, for any port resistances */
    double **mval;   /* those numbers */
    Sym **msym;      /* root -> its matrix's entries as values of its straight-line solve */
    Sx **rsx;        /* root -> the values of its straight-line solve */
    int nM;          /* entries of all root matrices */
    int *jq_off;     /* root -> its nonlinear edges' matrix in c_jQ (float voices, joint roots solved in straight
                        lines), or -1 */
    int njq;
    int nline;       /* transmission lines */
    int *line_of;    /* element -> its line, or -1 */
    int *dl_off;     /* element (a line's end) -> its buffer in s_dl */
    int *dl_size;    /* line -> buffer length (a power of two) */
    int ndl;         /* entries of all delay buffers */
    const char **b;  /* tree node -> C expression of its reflected wave */
    const char **bpost; /* the same after the backward pass */
    const char **a;  /* tree node -> C expression of its incident wave */
    const EmitOpts *opt;
    int nnl;         /* nonlinear root edges */
    int npwl;        /* points in all piecewise-linear tables */
    int *pwl_off;    /* nonlinear index -> first point of its table */
    int *pwl_n;      /* nonlinear index -> points in its table, 0: none */
    double **pwl_v, **pwl_i; /* Kirchhoff points of each table */
    /* waveguides */
    int *wv_off;     /* waveguide -> offset of its right-going line in s_wv (the left one follows) */
    int *wv_size;    /* waveguide -> length of each line (a power of two) */
    int nwv;         /* entries of s_wv */
    int *wf_off;     /* waveguide -> its first filter state */
    int nwf;
    int *wc_off;     /* waveguide -> its first coefficient in c_wf */
    int nwc;
    int *wt_off;     /* waveguide -> its first tap in c_wk */
    int nwt;
    int *sp_of;      /* element (E_S) -> its index in s_wpre, or -1 */
    int nsp;
    int *wtap_port;  /* tap -> ports facing a and b (2 each) */
    /* idle roots: a contact, and behind it masses and string taps that
     * the open contact leaves untouched; process skips them while every
     * such contact stays open */
    bool *idle;      /* root -> idle root */
    int nidle;
    bool skip;       /* process has the loop that skips them (not --no-skip, --energy) */
    /* an idle root's contact travels in chunks while every such contact
     * is open (chunk_texts): nonlinear index -> the plan that starts one,
     * its end, and its cut at the frame t_q */
    const char **ck_plan, **ck_end, **ck_cut;
    /* strings whose taps never scatter while the idle contacts are open
     * and that an idle contact reads: their lines keep running sums
     * (s_wP, and of sizes s_wA), so a chunk's sums take four reads */
    bool *wg_sum;
    bool anysum;
    int nic;         /* strike targets that set something (ic_targets) */
    int own;         /* the root the statements being put compute, -1: none */
    char phase;      /* their phase (Stmt.phase) */
    const char *dcop; /* a deck's DC operating point (dcop_static), or NULL */
} Ctx;

/* Room for one more in an arena array of n items of `size` bytes whose
 * capacity is *cap: the array, moved to a larger one when full. */
static void *grow(void *a, int n, int *cap, size_t size) {
    if (n < *cap)
        return a;
    *cap = *cap ? 2 * *cap : 64;
    void *b = arena_alloc(size * (size_t)*cap);
    if (n)
        memcpy(b, a, size * (size_t)n);
    return b;
}

/* The text fmt makes of ap (arena). */
static const char *vtext(const char *fmt, va_list ap) {
    Buf b = {0};
    buf_vadd(&b, fmt, ap);
    return str(&b);
}

/* A statement of the sample loop defining `def` (NULL: a store). */
static void put(Ctx *x, const char *def, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
static void put(Ctx *x, const char *def, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    const char *text = vtext(fmt, ap);
    va_end(ap);
    x->stmt = grow(x->stmt, x->nstmt, &x->capstmt, sizeof(Stmt));
    x->stmt[x->nstmt++] = (Stmt){def, text, x->own, x->phase};
}

/* A statement of update() storing `store` (NULL: none) in adaptor block
 * `block` (-1: none). */
static void upd(Ctx *x, int block, const char *store, const char *fmt, ...) __attribute__((format(printf, 4, 5)));
static void upd(Ctx *x, int block, const char *store, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    const char *text = vtext(fmt, ap);
    va_end(ap);
    x->upd = grow(x->upd, x->nupd, &x->capupd, sizeof(Upd));
    x->upd[x->nupd++] = (Upd){text, store, block};
}

/* A local of process named `name` (NULL: always there), its declaration,
 * write-back and flush (each NULL: none). */
static void local(Ctx *x, const char *name, const char *decl, const char *wb, const char *fl) {
    x->loc = grow(x->loc, x->nloc, &x->caploc, sizeof(Local));
    x->loc[x->nloc++] = (Local){name, decl ? decl : "", wb ? wb : "", fl ? fl : ""};
}

static const char *lit(Ctx *x, double v) {
    char *s = format("%.17g", v);
    if (!strpbrk(s, ".eni"))
        s = format("%s.0", s);
    if (x->single)
        s = format("%sf", s);
    return v < 0 ? format("(%s)", s) : s;
}

/* s in double: a float voice's value cast where the arithmetic is double
 * on purpose (coefficients, a Newton solve's answer), so that no float
 * is widened unseen. */
static const char *dbl(Ctx *x, const char *s) { return x->single ? format("(double)%s", s) : s; }

/* The texts a primitive's stamp (blocks/primitives.c) is filled with:
 * $a, $b, $e, $R and $x; a line end's and a waveguide port's $o, $p,
 * $k, $m, $d and $q (line_args). */
typedef struct StampArgs {
    const char *a, *b, *e, *R, *x;
    const char *o, *p, *k, *m; /* a line end's: its buffer's offset, the other end's, the line, the mask */
    const char *d, *q;         /* a waveguide port's: how far back it reads, where it writes */
} StampArgs;

/* Fills *s up to an unmatched ')' or its end into o; D(...) becomes its
 * contents in double (dbl; parenthesised if they hold a space, as a
 * stamp's operators do). */
static const char *stamp_fill(Ctx *x, const char *s, const StampArgs *g, Buf *o) {
    while (*s && *s != ')') {
        if (*s == '$') {
            const char *v = s[1] == 'a' ? g->a : s[1] == 'b' ? g->b : s[1] == 'e' ? g->e : s[1] == 'R' ? g->R
                          : s[1] == 'x' ? g->x : s[1] == 'o' ? g->o : s[1] == 'p' ? g->p : s[1] == 'k' ? g->k
                          : s[1] == 'm' ? g->m : s[1] == 'd' ? g->d : s[1] == 'q' ? g->q : NULL;
            if (!v)
                die("a stamp names $%c, which its printer does not give", s[1]);
            emit(o, "%s", v);
            s += 2;
        } else if (s[0] == 'D' && s[1] == '(') {
            Buf in = {0};
            s = stamp_fill(x, s + 2, g, &in);
            if (*s++ != ')')
                die("a stamp's D( is not closed");
            const char *t = str(&in);
            emit(o, "%s", dbl(x, strchr(t, ' ') ? format("(%s)", t) : t));
        } else if (*s == '(') {
            emit(o, "(");
            s = stamp_fill(x, s + 1, g, o);
            if (*s)
                emit(o, "%c", *s++);
        } else
            emit(o, "%c", *s++);
    }
    return s;
}

/* A line end's arguments to its stamps (element i): where the waves
 * that enter at it are kept, where the other end's are, its line's delay
 * and the mask of the buffers' positions.  A waveguide port's: the line
 * it reads ($o) and how many samples back ($d), the line it writes ($p)
 * and at which position ($q), and the mask; g as it is for anything
 * else. */
static StampArgs line_args(Ctx *x, int i, StampArgs g) {
    const Elem *e = &x->c->elems[i];
    if (prims[e->kind].wd == WD_WAVEGUIDE) {
        int w = e->wg, tap = x->wt_off[w] + e->pt - 1, R = x->wv_off[w], L = R + x->wv_size[w];
        const Waveguide *wg = &x->c->wgs[w];
        g.m = format("%du", x->wv_size[w] - 1);
        if (e->side == 0) { /* reads the right-going line, writes the left-going one */
            bool end = e->pt == wg->ntaps + 1; /* end b: its wave is the loop filters' output, no read */
            g.o = format("%d", R), g.p = format("%d", L), g.d = end ? NULL : format("k_wk%d", tap);
            g.q = end ? "t_pos" : format("(t_pos - (k_wNL%d - k_wk%d))", w, tap);
        } else {
            g.o = format("%d", L), g.p = format("%d", R);
            g.d = e->pt == 0 ? format("k_wNL%d", w) : format("(k_wNL%d - k_wk%d)", w, tap);
            g.q = e->pt == 0 ? "t_pos" : format("(t_pos - k_wk%d)", tap);
        }
        return g;
    }
    if (prims[e->kind].wd != WD_DELAY)
        return g;
    int k = x->line_of[i];
    g.o = format("%d", x->dl_off[i]), g.p = format("%d", x->dl_off[e->peer]);
    g.k = format("%d", k), g.m = format("%du", x->dl_size[k] - 1);
    return g;
}

/* A primitive's stamp as C text. */
static const char *stamp(Ctx *x, const char *s, StampArgs g) {
    Buf o = {0};
    if (*stamp_fill(x, s, &g, &o))
        die("a stamp has an unmatched ')'");
    return str(&o);
}

/* Whether text is a name or a number, which a statement need not hold. */
static bool plain(const char *t) {
    return *t && !t[strspn(t, "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_.")];
}

static const Elem *nl_elem(Ctx *x, int k) {
    return &x->c->elems[x->w->roots[x->nl_root[k]].edge[x->nl_edge[k]].elem];
}

/* The solver of nonlinear edge k: a joint root's own, else the element's
 * choice, the command line's, or the default. */
static Solver solver_of(Ctx *x, int k) {
    const NlSpec *nl = nl_elem(x, k)->nl;
    if (x->w->roots[x->nl_root[k]].joint)
        return SOLVER_JOINT;
    return nl->solver != SOLVER_DEFAULT ? nl->solver : x->opt->solver != SOLVER_DEFAULT ? x->opt->solver
                                                                                      : SOLVER_FAST;
}

/* Nonlinear edge k is a diode (or pair) that diode_fast solves. */
static bool fast_diode(Ctx *x, int k) {
    const NlSpec *nl = nl_elem(x, k)->nl;
    return nl->kind == NL_DIODE && !nl->mutated && solver_of(x, k) == SOLVER_FAST;
}

static bool any_fast(Ctx *x) {
    for (int k = 0; k < x->nnl; k++)
        if (fast_diode(x, k))
            return true;
    return false;
}

/* Nonlinear edge k is a diode (or pair) solved alone by a kernel that
 * returns its voltage t_vK: the root's sums take 2 t_vK - t_anK for its
 * wave t_bnK, with the t_anK term first, so that they wait for the solve
 * at one last term. */
static bool returns_v(Ctx *x, int k) {
    const NlSpec *nl = nl_elem(x, k)->nl;
    Solver s = solver_of(x, k);
    return nl->kind == NL_DIODE && !nl->mutated && s != SOLVER_PWL && s != SOLVER_JOINT;
}

/* The fixed port resistance of nonlinear edge k of joint root rb, as the
 * voice stores it. */
static double joint_R(Ctx *x, int rb, int k) {
    double R = x->w->roots[rb].R[k];
    return x->single ? (double)(float)R : R;
}

static bool any_joint(Ctx *x) {
    for (int b = 0; b < x->w->nroots; b++)
        if (x->w->roots[b].joint)
            return true;
    return false;
}

/* C text of an elaborated expression over p[]. */
static const char *cexpr(Ctx *x, const Expr *e) {
    static const char *ops = "+-*/";
    switch (e->kind) {
    case EX_NUM: { /* always a double constant: 1/2 must not be integer division */
        const char *s = format("%.17g", e->num);
        return strpbrk(s, ".eni") ? s : format("%s.0", s);
    }
    case EX_PARAM: return format("p[%d]", e->param);
    case EX_NEG: return format("(-%s)", cexpr(x, e->a));
    case EX_ADD: case EX_SUB: case EX_MUL: case EX_DIV:
        return format("(%s %c %s)", cexpr(x, e->a), ops[e->kind - EX_ADD], cexpr(x, e->b));
    case EX_POW: return format("pow(%s, %s)", cexpr(x, e->a), cexpr(x, e->b));
    case EX_CALL: {
        const char *f = fn_name(e->fn);
        if (e->fn == FN_ABS) f = "fabs";
        if (e->fn == FN_MIN) f = "fmin";
        if (e->fn == FN_MAX) f = "fmax";
        if (e->b)
            return format("%s(%s, %s)", f, cexpr(x, e->a), cexpr(x, e->b));
        return format("%s(%s)", f, cexpr(x, e->a));
    }
    case EX_NAME: break;
    }
    unreachable();
}

static bool is_zero(const char *s) { return !strcmp(s, "0"); }

/* drive of a source element as a per-sample expression */
static const char *drive_of(Ctx *x, const Elem *e) {
    if (e->input >= 0)
        return format("t_in%d", e->input);
    return format("c_e%d", x->src[e - x->c->elems]);
}

/* ---- update: coefficients at control rate ---- */

static const char *guard(uint64_t mask) {
    if (!mask)
        return "if (full)";
    return format("if (full || (d & 0x%llxULL))", (unsigned long long)mask);
}

/* Params a waveguide's loop design depends on (not its taps or port
 * resistance, which move without a new design). */
static uint64_t wg_design_params(const Waveguide *g) {
    return expr_params(g->f0) | expr_params(g->B) | expr_params(g->fhf) | (g->t60 ? expr_params(g->t60) : 0) |
           (g->t60hf ? expr_params(g->t60hf) : 0);
}

/* Params some waveguide's loop design depends on. */
static uint64_t wg_params(const Circuit *c) {
    uint64_t m = 0;
    for (int w = 0; w < c->nwgs; w++)
        m |= wg_design_params(&c->wgs[w]);
    return m;
}

/* wg_spec_at: the spec of each waveguide's loop at rate fs (and params p
 * when a design depends on them), for update and prepare alike. */
static void emit_wg_specs(Ctx *x, Buf *o) {
    const Circuit *c = x->c;
    emit(o, "/* The spec of waveguide w's loop at rate fs%s. */\n", wg_params(c) ? " for params p" : "");
    emit(o, "static void wg_spec_at(double fs, %sint w, wg_spec *sp) {\n    switch (w) {\n",
         wg_params(c) ? "const double *p, " : "");
    for (int w = 0; w < c->nwgs; w++) {
        const Waveguide *g = &c->wgs[w];
        emit(o, "    case %d: { /* %s */\n", w, g->name);
        emit(o, "        const wg_spec s = {fs, fmax(%s, %.17g), %s, %s, %s, %s, %.17g, %.17g, %d, %d, %d};\n",
             cexpr(x, g->f0), g->f0_min, cexpr(x, g->B), g->t60 ? cexpr(x, g->t60) : "0.0",
             g->t60hf ? cexpr(x, g->t60hf) : "0.0", cexpr(x, g->fhf), g->nu1,
             g->rad ? expr_eval(g->rad, NULL) : 0.0, g->nrad, g->M, g->nmin);
        emit(o, "        *sp = s;\n        break;\n    }\n");
    }
    emit(o, "    }\n}\n");
}

/* An element's value as update passes it on, kept within (1e-18, 1e300)
 * by pos(): a number or a param whose range lies within needs no pos(). */
static const char *pos_value(Ctx *x, const Expr *e) {
    const Param *p = e->kind == EX_PARAM ? &x->c->params[e->param] : NULL;
    if ((e->kind == EX_NUM && e->num > 1e-18 && e->num < 1e300) || (p && p->min > 1e-18 && p->max < 1e300))
        return cexpr(x, e);
    return format("pos(%s)", cexpr(x, e));
}

static void emit_update(Ctx *x) {
    int nb = 0;
    const Circuit *c = x->c;
    for (int i = 0; i < x->w->nnodes; i++) {
        const WNode *n = x->w->nodes[i];
        if (n->kind == W_LEAF) {
            const Elem *e = &c->elems[n->elem];
            const char *v = pos_value(x, e->val);
            upd(x, -1, NULL, "    %s /* %s (%s:%d:%d) */\n", guard(n->pmask), e->name, e->pos.file->path, e->pos.line,
                e->pos.col);
            /* a reactance a param moves is retuned; one that none moves
             * is set once, in init, from a cleared state */
            const Prim *pr = &prims[e->kind];
            if (pr->state && n->pmask)
                upd(x, -1, NULL, "        retune(st, %d, %d, %s, %d);\n", n->id, x->react[n->id], prim_port_text(e, v),
                    pr->state == 'C');
            else if (pr->state)
                upd(x, -1, NULL, "        st->c_R[%d] = (real)(%s);\n", n->id, prim_port_text(e, v));
            else
                upd(x, -1, NULL, "        st->c_R[%d] = (real)%s;\n", n->id, prim_port_text(e, v));
            continue;
        }
        const int blk = nb++;
        upd(x, blk, NULL, "    %s { /* %s adaptor */\n", guard(n->pmask), n->kind == W_SERIES ? "series" : "parallel");
        /* the sum of resistances (conductances) in child order: one
         * expression for a few, else a running sum */
        Buf sum = {0};
        for (int k = 0; k < n->nchild; k++)
            emit(&sum,
                 n->kind == W_SERIES ? (n->nchild <= 4 ? "%s%s" : "        t += %s%s;\n")
                                     : (n->nchild <= 4 ? "%s1.0 / %s" : "        t += 1.0 / %s%s;\n"),
                 n->nchild <= 4 && k ? " + " : "", dbl(x, format("st->c_R[%d]", n->child[k]->id)));
        upd(x, blk, NULL, n->nchild <= 4 ? "        const double t = %s;\n" : "        double t = 0;\n%s", str(&sum));
        upd(x, blk, format("c_R[%d]", n->id), "        st->c_R[%d] = (real)(%s);\n", n->id,
            n->kind == W_SERIES ? "t" : "1.0 / t");
        for (int k = 0; k < n->nchild; k++)
            upd(x, blk, format("c_k[%d]", x->koff[n->id] + k),
                n->kind == W_SERIES ? "        st->c_k[%d] = (real)(%s / t);\n"
                                    : "        st->c_k[%d] = (real)(1.0 / %s / t);\n",
                x->koff[n->id] + k, dbl(x, format("st->c_R[%d]", n->child[k]->id)));
        upd(x, blk, NULL, "    }\n");
    }
    for (int k = 0; k < x->nnl; k++) {
        const Elem *e = nl_elem(x, k);
        const NlSpec *nl = e->nl;
        Expr *v[4] = {NULL, NULL, NULL, NULL};
        if (nl->kind == NL_DIODE) {
            v[0] = nl->Is;
            v[1] = expr_bin(EX_MUL, nl->n, nl->Vt);
        } else if (nl->kind == NL_CONTACT) {
            v[0] = nl->k, v[1] = nl->alpha, v[2] = nl->lambda, v[3] = nl->gap;
        }
        for (int j = 0; j < 4; j++) {
            if (!v[j])
                continue;
            upd(x, -1, NULL, "    %s { /* %s */\n        const double t_new = %s;\n", guard(expr_params(v[j])), e->name,
                cexpr(x, v[j]));
            /* a contact held compressed keeps its energy from rising: a
             * stiffer felt is compressed less, a smaller gap keeps the
             * compression */
            if (nl->kind == NL_CONTACT && !nl->mutated && (j == 0 || j == 3))
                upd(x, -1, NULL,
                    "        const double t_X = st->s_nX[%d] - st->c_nl[%d], t_old = st->c_nl[%d];\n"
                    "        if (!full && t_X > 0 && t_old > 0 && t_new %s t_old)\n"
                    "            st->s_nX[%d] = (real)(%s);\n",
                    k, 4 * k + 3, 4 * k + j, j == 0 ? ">" : "<", k,
                    j == 0 ? format("%s + t_X * pow(t_old / t_new, 1 / (st->c_nl[%d] + 1))",
                                    dbl(x, format("st->c_nl[%d]", 4 * k + 3)), 4 * k + 1)
                           : format("%s + t_new - t_old", dbl(x, format("st->s_nX[%d]", k))));
            upd(x, -1, NULL, "        st->c_nl[%d] = (real)t_new;\n    }\n", 4 * k + j);
        }
    }
    for (int b = 0; b < x->w->nroots; b++) /* fixed: their laws are solved jointly */
        for (int k = 0; k < x->w->roots[b].nnl && x->w->roots[b].joint; k++)
            upd(x, -1, NULL, "    st->c_Rn[%d] = %s;\n", x->nl_first[b] + k,
                lit(x, joint_R(x, b, x->w->roots[b].nport + k)));
    for (int b = 0; b < x->w->nroots; b++) {
        if (!x->rfn[b])
            upd(x, -1, NULL, "    %s\n        root_solve(st, %d);\n", guard(x->w->roots[b].pmask), b);
        else if (*x->rfn[b])
            upd(x, -1, NULL, "    %s\n        root%d_solve(st);\n", guard(x->w->roots[b].pmask), b);
    }
    for (int k = 0; k < x->nnl; k++) /* diode_fast's constants, from the adapted port and the law */
        if (fast_diode(x, k))
            upd(x, -1, NULL, "    fast_setup(st->c_fk + %d, %s, %s, %s, %d, fast_om);\n", 6 * k,
                dbl(x, format("st->c_Rn[%d]", k)), dbl(x, format("st->c_nl[%d]", 4 * k)),
                dbl(x, format("st->c_nl[%d]", 4 * k + 1)), nl_elem(x, k)->nl->pair);
    for (int i = 0; i < c->nelems; i++) {
        const Elem *e = &c->elems[i];
        if (e->kind == E_W && e->peer > i) /* one delay per line */
            upd(x, -1, NULL,
                "    if (full) { /* %s: delay in whole samples */\n"
                "        double t_d = floor(%.17g * st->fs + 0.5);\n"
                "        st->c_D[%d] = (unsigned)(t_d < 1 ? 1 : t_d > %d ? %d : t_d);\n    }\n",
                e->name, e->td, x->line_of[i], x->dl_size[x->line_of[i]] - 1, x->dl_size[x->line_of[i]] - 1);
    }
    for (int w = 0; w < c->nwgs; w++) {
        const Waveguide *g = &c->wgs[w];
        uint64_t mask = wg_design_params(g) | expr_params(g->Rp);
        Buf xs = {0};
        for (int j = 0; j < g->ntaps; j++) {
            mask |= expr_params(g->tap_pos[j]);
            emit(&xs, "%s%s", j ? ", " : "", cexpr(x, g->tap_pos[j]));
        }
        upd(x, -1, NULL, "    %s { /* %s (%s:%d:%d) */\n", guard(mask), g->name, g->pos.file->path, g->pos.line,
            g->pos.col);
        upd(x, -1, NULL, "        wg_spec sp;\n        wg_spec_at(st->fs, %s%d, &sp);\n", wg_params(c) ? "p, " : "", w);
        upd(x, -1, NULL, "        const double x[] = {%s};\n        wg_retune(st, %d, &sp, pos(%s), x);\n    }\n",
            g->ntaps ? str(&xs) : "0.0", w, cexpr(x, g->Rp));
    }
    for (int i = 0; i < c->nelems; i++) {
        const Elem *e = &c->elems[i];
        if (x->src[i] >= 0 && e->input < 0)
            upd(x, -1, NULL, "    %s /* %s */\n        st->c_e[%d] = (real)(%s);\n", guard(expr_params(e->drive)),
                e->name, x->src[i], cexpr(x, e->drive));
    }
}

/* ---- the sample loop ---- */

/* Outputs that are displacement probes. */
static int x_probes(const Circuit *c) {
    int n = 0;
    for (int k = 0; k < c->nouts; k++)
        n += c->outs[k].kind == PR_X;
    return n;
}


/* A waveguide port at a tap that a param moves: it may be off its string. */
static bool roams(const Ctx *x, const Elem *e) {
    const Waveguide *g = &x->c->wgs[e->wg];
    return e->pt > 0 && e->pt <= g->ntaps && expr_params(g->tap_pos[e->pt - 1]);
}

/* Each waveguide's right-going wave meets end b through the loop filters;
 * terminated ends reflect. */
static void emit_waveguides(Ctx *x) {
    for (int w = 0; w < x->c->nwgs; w++) {
        const Waveguide *g = &x->c->wgs[w];
        int m = x->wv_size[w] - 1, R = x->wv_off[w], L = R + x->wv_size[w], f = x->wf_off[w];
        Buf o = {0};
        emit(&o, "        /* %s: the right-going wave meets end b through the loop filters */\n", g->name);
        emit(&o, "        real t_wb%d;\n        {\n", w);
        emit(&o, "            real t_x = s_wv[%d + ((t_pos - k_wNR%d) & %du)], t_y;\n", R, w, m);
        emit(&o, "            t_y = k_wlb%d * t_x - k_wla%d * s_wf%d;\n            s_wq%d = s_wf%d;\n            s_wf%d = t_y;\n"
                 "            t_x = t_y;\n", w, w, f, f, f, f);
        int j = f + 1;
        for (int k = 0; k < g->nrad; k++, j++)
            emit(&o, "            t_y = (1 + k_wra%d) * t_x - k_wra%d * s_wf%d;\n            s_wq%d = s_wf%d;\n"
                     "            s_wf%d = t_y;\n            t_x = t_y;\n", w, w, j, j, j, j);
        /* the allpass lattice: its top stage in use gives the output, then
         * each stage m down to 1 passes on its rotation; the state of stage
         * m holds the output of stage m - 1 a sample earlier.  A lattice of
         * one stage (the fine tuning alone) keeps its state in locals. */
        if (g->M == 1) {
            emit(&o, "            t_y = k_wak%d * t_x + k_wac%d * s_wf%d;\n            t_x = k_wac%d * t_x - k_wak%d * s_wf%d;\n"
                     "            s_wq%d = s_wf%d;\n            s_wf%d = t_x;\n            t_wb%d = t_y;\n        }\n",
                 w, w, j, w, w, j, j, j, j, w);
            put(x, NULL, "%s", str(&o));
            goto ends;
        }
        emit(&o, "            {\n                real *const t_s = st->s_wf + %d, *const t_q = st->s_wfp + %d;\n"
                 "                const real *const t_c = st->c_wf + %d;\n"
                 "                const unsigned t_J = %s;\n"
                 "                const real t_k = t_c[2 * t_J - 2], t_cc = t_c[2 * t_J - 1], t_sm = t_s[t_J - 1];\n"
                 "                t_y = t_k * t_x + t_cc * t_sm;\n"
                 "                t_x = t_cc * t_x - t_k * t_sm;\n",
             j, j, x->wc_off[w] + 3, g->M == 1 ? "1u" : format("k_wJ%d", w));
        if (g->M > 1) /* one stage is the fine tuning alone */
            emit(&o, "                for (unsigned m = t_J - 1; m >= 1; m--) {\n"
                     "                    const real t_km = t_c[2 * m - 2], t_cm = t_c[2 * m - 1], t_s1 = t_s[m - 1];\n"
                     "                    t_q[m] = t_s[m];\n"
                     "                    t_s[m] = t_km * t_x + t_cm * t_s1;\n"
                     "                    t_x = t_cm * t_x - t_km * t_s1;\n                }\n");
        emit(&o, "                t_q[0] = t_s[0];\n                t_s[0] = t_x;\n            }\n"
                 "            t_wb%d = t_y;\n        }\n", w);
        put(x, NULL, "%s", str(&o));
    ends:
        for (int e = 0; e < 2; e++) {
            if (g->end[e])
                continue;
            const char *sg = g->term[e] == 'c' ? "" : "-";
            /* one flush in the loop: at end b, through which every wave
             * passes once a round trip (after the run, emit_hoist), or at
             * end a where end b is joined */
            if (e == 0) {
                const char *wave = format("%ss_wv[%d + ((t_pos - k_wNL%d) & %du)]", sg, L, w, m);
                put(x, NULL, "        s_wv[%d + (t_pos & %du)] = %s; /* end a */\n", R, m,
                    g->end[1] ? format("flush(%s)", wave) : wave);
            } else
                put(x, NULL, "        s_wv[%d + (t_pos & %du)] = %st_wb%d; /* end b */\n", L, m, sg, w);
        }
    }
}

static void emit_forward(Ctx *x) {
    const Circuit *c = x->c;
    x->own = -1, x->phase = 0;
    emit_waveguides(x);
    put(x, NULL, "        /* forward: waves reflected towards the root */\n");
    for (int i = 0; i < x->w->nnodes; i++) {
        const WNode *n = x->w->nodes[i];
        x->own = n->root, x->phase = 'f';
        const char *tb = format("t_b%d", i);
        if (n->kind == W_LEAF) {
            const Elem *e = &c->elems[n->elem];
            const Prim *pr = &prims[e->kind];
            /* its descriptor's stamp: a name as it is, else a statement; at
             * end b, the wave the loop filters pass on */
            bool wg = pr->wd == WD_WAVEGUIDE;
            if (!pr->reflect) /* a leaf that reflects nothing of its own: none is left to the printer */
                unreachable();
            const char *b =
                wg && e->side == 0 && e->pt == c->wgs[e->wg].ntaps + 1
                    ? format("t_wb%d", e->wg)
                    : stamp(x, pr->reflect,
                            line_args(x, n->elem,
                                      (StampArgs){.a = x->react[i] >= 0 ? format("s_a%d", x->react[i]) : NULL,
                                                  .e = pr->wd == WD_SOURCE ? drive_of(x, e) : NULL,
                                                  .R = format("k_R%d", i)}));
            x->b[i] = b;
            if (!plain(b) || wg) {
                put(x, tb, "        const real t_b%d = %s; /* %s */\n", i, b, e->name);
                x->b[i] = tb;
            }
            if (wg) {
                char ph = x->phase;
                x->phase = 'p'; /* the idle loop keeps it too: a strike's settle reads it */
                put(x, NULL, "        s_wpre%d = t_b%d;\n", x->sp_of[n->elem], i);
                x->phase = ph;
                if (roams(x, e)) {
                    /* a tap off its string sends nothing into its junction */
                    put(x, format("t_bo%d", i), "        const real t_bo%d = k_won%d ? t_b%d : %s;\n", i,
                        x->wt_off[e->wg] + e->pt - 1, i, lit(x, 0));
                    x->b[i] = format("t_bo%d", i);
                }
            }
            continue;
        }
        Buf t = {0};
        for (int k = 0; k < n->nchild; k++) {
            const char *bc = x->b[n->child[k]->id];
            if (is_zero(bc))
                continue;
            const char *sg = n->pol[k] > 0 ? (t.len ? " + " : "") : (t.len ? " - " : "-");
            if (n->kind == W_SERIES)
                emit(&t, "%s%s", sg, bc);
            else
                emit(&t, "%sc_k%d * %s", sg, x->koff[i] + k, bc);
        }
        if (!t.len) {
            x->b[i] = "0";
            continue;
        }
        put(x, tb, "        const real t_b%d = %s;\n", i, str(&t));
        x->b[i] = tb;
    }
    x->own = -1, x->phase = 0;
}

/* input j of the root: b of a port or the drive of a source */
static const char *root_in(Ctx *x, int b, int j) {
    const RootEdge *e = &x->w->roots[b].edge[j];
    if (e->kind == EDGE_NL)
        return format("t_bn%d", x->nl_first[b] + j - x->w->roots[b].nport);
    return e->kind == EDGE_PORT ? x->b[e->node->id] : drive_of(x, &x->c->elems[e->elem]);
}


/* The element at the other side of a waveguide port's point. */
static int partner_port(Ctx *x, int ei) {
    const Elem *e = &x->c->elems[ei];
    for (int i = 0; i < x->c->nelems; i++) {
        const Elem *f = &x->c->elems[i];
        if (f->kind == E_S && f->wg == e->wg && f->pt == e->pt && f->side != e->side)
            return i;
    }
    return -1;
}

/* A waveguide tap is transparent when nothing but its two ports meets
 * there (1), or nothing else but contacts and other strings' taps (2:
 * transparent while the contacts are open, listed in open[]); else 0. */
static int tap_kind(Ctx *x, int ei, int *open, int *nopen) {
    const Elem *e = &x->c->elems[ei];
    const Waveguide *g = &x->c->wgs[e->wg];
    *nopen = 0;
    if (e->pt == 0 || e->pt == g->ntaps + 1)
        return 0;
    int nd = e->n[0], ports = 0, other = 0;
    for (int i = 0; i < x->c->nelems; i++) {
        const Elem *f = &x->c->elems[i];
        if (f->n[0] != nd && f->n[1] != nd)
            continue;
        if (f->kind == E_S && f->pt > 0 && f->pt <= x->c->wgs[f->wg].ntaps) {
            ports++;
            other |= f->wg != e->wg || f->pt != e->pt;
            continue;
        }
        int k = -1;
        for (int j = 0; j < x->nnl && f->kind == E_NL && f->nl->kind == NL_CONTACT && !f->nl->mutated; j++)
            if (nl_elem(x, j) == f)
                k = j;
        if (k < 0) { /* something else meets here: never transparent */
            *nopen = 0;
            return 0;
        }
        open[(*nopen)++] = k;
    }
    /* taps of several strings meet only through contacts: while those are
     * open, each string passes on its own */
    return *nopen ? 2 : ports == 2 && !other ? 1 : 0;
}

/* True if some tap's wave waits on contact k being open. */
static bool contact_gates(Ctx *x, int k) {
    int open[64], nopen;
    for (int i = 0; i < x->w->nnodes; i++) {
        const WNode *n = x->w->nodes[i];
        if (n->kind != W_LEAF || x->c->elems[n->elem].kind != E_S || tap_kind(x, n->elem, open, &nopen) != 2)
            continue;
        for (int j = 0; j < nopen; j++)
            if (open[j] == k)
                return true;
    }
    return false;
}

/* Idle roots: a root of one port and one contact whose tree holds only
 * string taps that the open contact leaves untouched and masses.  While
 * the contact is open and carries no force, the masses keep their
 * velocities and the taps pass their waves on: process then follows the
 * contact's travel alone and skips the rest of the tree. */
static void find_idle(Ctx *x) {
    const Wdf *w = x->w;
    x->idle = arena_alloc(sizeof(bool) * (size_t)(w->nroots + 1));
    for (int b = 0; b < w->nroots; b++) {
        const Root *r = &w->roots[b];
        int k = x->nl_first[b];
        if (r->nedge != 2 || r->nport != 1 || r->nnl != 1)
            continue;
        const Elem *ce = nl_elem(x, k);
        if (ce->nl->kind != NL_CONTACT || ce->nl->mutated || !contact_gates(x, k))
            continue;
        bool ok = true;
        for (int i = 0; i < w->nnodes && ok; i++) {
            const WNode *n = w->nodes[i];
            if (n->root != b || n->kind != W_LEAF)
                continue;
            const Elem *e = &x->c->elems[n->elem];
            int open[64], nopen = 0;
            if (e->kind == E_C)
                continue;
            ok = e->kind == E_S && tap_kind(x, n->elem, open, &nopen) > 0;
            for (int j = 0; j < nopen && ok; j++)
                ok = open[j] == k;
        }
        x->idle[b] = ok;
        x->nidle += ok;
    }
    x->skip = x->nidle && !x->energy && !x->opt->no_skip;
}

/* True if nonlinear edge k is the contact of an idle root. */
static bool idle_contact(const Ctx *x, int k) {
    for (int b = 0; b < x->w->nroots; b++)
        if (x->idle[b] && x->nl_first[b] == k)
            return true;
    return false;
}

/* The wave a nonlinear edge reflects, from the wave the root sends it. */
static void emit_nl_solve(Ctx *x, int k) {
    const Elem *e = nl_elem(x, k);
    const NlSpec *nl = e->nl;
    const char *tol = format("%.17g", x->opt->tol);
    const char *an = dbl(x, format("t_an%d", k));
    int it = x->opt->maxit;
    bool gates = nl->kind == NL_CONTACT && !nl->mutated && contact_gates(x, k);
    Buf o = {0};
    emit(&o, "        %s%d; /* %s (%s:%d:%d) */\n", returns_v(x, k) ? "double t_v" : "real t_bn", k, e->name,
         e->pos.file->path, e->pos.line, e->pos.col);
    if (gates)
        emit(&o, "        int t_open%d;\n", k);
    emit(&o, "        {\n");
    if (nl->mutated == 'C') { /* passive stepping of a stored charge: cap_solve */
        emit(&o, "            const el_law t_L = %s;\n            double t_v;\n", el_law_init(k, nl, true));
        emit(&o, "            s_nf%d = (real)cap_solve(&t_L, %s, %s, %s, %s, %s, 0.5 * k_T, %s, %d, &t_v);\n", k, an,
             dbl(x, format("k_Rn%d", k)), dbl(x, format("s_nf%d", k)), dbl(x, format("s_nv%d", k)),
             dbl(x, format("s_nX%d", k)), tol, it);
        emit(&o, "            s_nX%d = (real)((%s - t_v) / %s);\n", k, an, dbl(x, format("k_Rn%d", k)));
        emit(&o, "            s_nv%d = (real)t_v;\n            t_bn%d = (real)(2 * t_v - %s);\n        }\n", k, k, an);
        put(x, NULL, "%s", str(&o));
        return;
    }
    if (nl->mutated == 'L' || nl->kind == NL_CONTACT) { /* passive stepping of a stored energy: el_solve */
        const char *solve = format("el_solve(&t_L, %s, %s, t_X, %s, %s, 0.5 * k_T, %s, %d)", an,
                                   dbl(x, format("k_Rn%d", k)), dbl(x, format("s_nv%d", k)),
                                   dbl(x, format("s_nf%d", k)), tol, it);
        emit(&o, "            const el_law t_L = %s;\n", el_law_init(k, nl, true));
        /* an idle contact in a chunk is open, its travel the chunk's */
        bool ck = idle_contact(x, k);
        const char *inck = ck ? format("s_ck%d > 0 || ", k) : "", *step = ck ? format("if (s_ck%d == 0)\n    ", k) : "";
        if (nl->kind == NL_CONTACT) /* open with no force left, and staying open at v = a: a passes */
            emit(&o, "            const double t_X = %s - c_nl%d_3;\n"
                     "            const double t_v = %s%ss_nf%d == 0 && !(t_X > 0) && !(t_X + 0.5 * k_T * %s > 0)%s\n"
                     "                                   ? (double)t_an%d : %s;\n", dbl(x, format("s_nX%d", k)), k,
                 inck, ck ? "(" : "", k, dbl(x, format("(t_an%d + s_nv%d)", k, k)), ck ? ")" : "", k, solve);
        else
            emit(&o, "            const double t_X = %s;\n            const double t_v = %s;\n", dbl(x, format("s_nX%d", k)),
                 solve);
        emit(&o, "            %ss_nX%d += k_hT * (real)(t_v + %s);\n", step, k, dbl(x, format("s_nv%d", k)));
        if (gates)
            emit(&o, "            t_open%d = t_v == (double)t_an%d; /* no force: the contact is open */\n", k, k);
        emit(&o, "            s_nf%d = (real)((%s - t_v) / %s);\n", k, an, dbl(x, format("k_Rn%d", k)));
        emit(&o, "            %ss_nv%d = (real)t_v;\n            t_bn%d = (real)(2 * t_v - %s);\n        }\n", step, k, k, an);
        put(x, NULL, "%s", str(&o));
        return;
    }
    switch (solver_of(x, k)) {
    case SOLVER_PWL:
        emit(&o, "            t_bn%d = pwl_map(t_an%d, c_pa%d, c_pb%d, c_ps%d, %d);\n", k, k, k, k, k, x->pwl_n[k]);
        break;
    case SOLVER_FAST:
        emit(&o, "            t_v%d = diode_fast(%s, %d, ", k, an, nl->pair);
        for (int j = 0; j < 6; j++)
            emit(&o, "%s, ", dbl(x, format("c_fk%d_%d", k, j)));
        emit(&o, "fast_om, %s, %d);\n", x->opt->fast_tol > 0 ? format("%.17g", x->opt->fast_tol) : "FAST_BOUND", it);
        break;
    case SOLVER_OMEGA:
        emit(&o, "            t_v%d = diode_omega(%s, %s, %s, %s, %d, %s, %d);\n", k, an, dbl(x, format("k_Rn%d", k)),
             dbl(x, format("c_nl%d_0", k)), dbl(x, format("c_nl%d_1", k)), nl->pair, tol, it);
        break;
    default:
        emit(&o, "            t_v%d = diode_newton(%s, %s, %s, %s, %d, %s, %s, %d);\n", k, an,
             dbl(x, format("k_Rn%d", k)), dbl(x, format("c_nl%d_0", k)), dbl(x, format("c_nl%d_1", k)), nl->pair,
             dbl(x, format("s_nv%d", k)), tol, it);
        break;
    }
    if (returns_v(x, k))
        emit(&o, "            s_nv%d = (real)t_v%d;\n", k, k);
    emit(&o, "        }\n");
    put(x, NULL, "%s", str(&o));
    if (returns_v(x, k))
        put(x, format("t_bn%d", k), "        const real t_bn%d = (real)(2 * t_v%d - %s);\n", k, k, an);
}

/* Entries of root r's matrix that vanish for any port resistances (an
 * adapted port reflects nothing, say): zero at the defaults, and again
 * with every port's resistance moved and the nonlinear edges adapted
 * anew.  The sample loop leaves their products out. */
static bool *root_zeros(const Root *r) {
    int ne = r->nedge, np = r->nport + r->nnl;
    bool *z = arena_alloc(sizeof(bool) * (size_t)(ne * ne));
    double *R = arena_alloc(sizeof(double) * (size_t)(np + 1)), *M = arena_alloc(sizeof(double) * (size_t)(ne * ne));
    for (int i = 0; i < ne * ne; i++)
        z[i] = r->M[i] == 0;
    for (int trial = 0; trial < 2; trial++) {
        for (int k = 0; k < r->nport; k++)
            R[k] = r->R[k] * (trial ? 0.61 : 1.37) * (1 + 0.173 * k);
        for (int k = r->nport; k < np; k++)
            if (r->joint || scatter_thevenin(r, R, k, &R[k]) != 0)
                R[k] = r->R[k];
        bool ok = scatter_root(r, R, M) == 0;
        for (int k = 0; k < ne; k++) {
            double big = 0;
            for (int j = 0; j < ne; j++)
                big = fmax(big, fabs(M[k * ne + j]));
            for (int j = 0; j < ne; j++)
                z[k * ne + j] = z[k * ne + j] && ok && fabs(M[k * ne + j]) <= 1e-12 * big;
        }
    }
    return z;
}

/* Root rb's matrix in straight-line code (solve.c), as a function
 * rootN_solve into x->rfn[rb], with the entries that are numbers for any
 * port resistances in x->mnum and x->mval; x->rfn[rb] stays NULL if the
 * root keeps the general solve (root_solve), "" if no entry needs code. */
static void root_static(Ctx *x, int rb) {
    const Root *r = &x->w->roots[rb];
    const int ne = r->nedge;
    if (r->nctl) /* controlled sources: the general solve */
        return;
    Sx *sx = sx_new("u");
    sx_once(sx, !x->opt->single);
    Sym *g = arena_alloc(sizeof(Sym) * (size_t)(ne + 1)), *val = arena_alloc(sizeof(Sym) * (size_t)(ne + 1));
    Sym *pot = arena_alloc(sizeof(Sym) * (size_t)(r->ncore + 1)), *cur = arena_alloc(sizeof(Sym) * (size_t)(ne + 2));
    for (int k = 0; k < ne; k++)
        if (r->edge[k].kind == EDGE_PORT)
            g[k] = sx_temp(sx, format("1.0 / %s", dbl(x, format("st->c_R[%d]", r->edge[k].node->id))));
#define POT(p) ((p) >= 0 ? pot[p] : sym_k(0))
    /* a joint root's nonlinear edges keep the resistances wdf.c gave them */
    for (int k = r->nport; k < r->nport + r->nnl && r->joint; k++)
        g[k] = sym_k(1 / joint_R(x, rb, k));
    /* else each nonlinear edge is adapted first: the resistance the rest
     * of the core presents to it, with its sources at rest */
    for (int k = r->nport; k < r->nport + r->nnl && !r->joint; k++) {
        Lin *L = lin_new(sx, r->ncore);
        for (int j = 0; j < ne; j++) {
            const RootEdge *e = &r->edge[j];
            if (j != k && (e->kind == EDGE_PORT || e->kind == EDGE_NL))
                lin_g(L, e->p, e->q, g[j]);
            else if (e->kind == EDGE_V)
                lin_v(L, e->p, e->q);
            else
                lin_j(L, e->p, e->q); /* the unit current in edge k; sources open */
        }
        if (!lin_factor(L))
            return;
        for (int j = 0; j < ne; j++)
            val[j] = sym_k(j == k ? -1 : 0);
        lin_solve(L, val, pot, NULL);
        Sym R = sx_sub(sx, POT(r->edge[k].p), POT(r->edge[k].q));
        if (sym_number(R))
            return; /* held by ideal sources: the general solve keeps what it had */
        int nl = x->nl_first[rb] + k - r->nport;
        const char *v = sx_use(sx, R);
        sx_stmt(sx, format("    if (%s > 0 && %s < 1e300) /* the nonlinear edge adapted */\n        st->c_Rn[%d] = (real)%s;\n",
                           v, v, nl, v));
        g[k] = sx_temp(sx, format("1.0 / %s", dbl(x, format("st->c_Rn[%d]", nl))));
    }
    Lin *L = lin_new(sx, r->ncore);
    for (int j = 0; j < ne; j++) {
        const RootEdge *e = &r->edge[j];
        if (e->kind == EDGE_PORT || e->kind == EDGE_NL)
            lin_g(L, e->p, e->q, g[j]);
        else if (e->kind == EDGE_V)
            lin_v(L, e->p, e->q);
        else
            lin_j(L, e->p, e->q);
    }
    if (!lin_factor(L))
        return;
    bool *num = arena_alloc(sizeof(bool) * (size_t)(ne * ne));
    double *mv = arena_alloc(sizeof(double) * (size_t)(ne * ne));
    Sym *ms = arena_alloc(sizeof(Sym) * (size_t)(ne * ne));
    for (int j = 0; j < ne; j++) {
        for (int k = 0; k < ne; k++)
            val[k] = sym_k(k == j);
        lin_solve(L, val, pot, cur);
        for (int k = 0; k < ne; k++) {
            const RootEdge *e = &r->edge[k];
            Sym v = sx_sub(sx, POT(e->p), POT(e->q));
            Sym out = e->kind == EDGE_V ? cur[k] : e->kind == EDGE_I ? v : sx_sub(sx, sx_mul(sx, sym_k(2), v), sym_k(j == k));
            num[k * ne + j] = sym_number(out);
            mv[k * ne + j] = out.c;
            ms[k * ne + j] = out;
        }
    }
#undef POT
    x->mnum[rb] = num;
    x->mval[rb] = mv;
    x->msym[rb] = ms;
    x->rsx[rb] = sx;
    for (int i = 0; i < ne * ne; i++)
        x->mzero[rb][i] = num[i] && mv[i] == 0;
    x->rfn[rb] = "";
}

/* The function of each root solved in straight-line code: the entries of
 * its matrix process names (`live`) that are not numbers, stored; none if
 * there are none and no nonlinear edge to adapt. */
static void root_fns(Ctx *x, const Names *live) {
    for (int rb = 0; rb < x->w->nroots; rb++) {
        const Root *r = &x->w->roots[rb];
        const int ne = r->nedge;
        if (!x->rfn[rb])
            continue;
        Sx *sx = x->rsx[rb];
        bool code = r->nnl > 0;
        for (int i = 0; i < ne * ne; i++)
            if (!x->mnum[rb][i] && names_has(live, format("m%d_%d_%d", rb, i / ne, i % ne))) {
                sx_stmt(sx, format("    st->c_M[%d] = (real)%s;\n", x->moff[rb] + i, sx_use(sx, x->msym[rb][i])));
                code = true;
            }
        /* a float voice's joint solve takes the root's rows of its
         * nonlinear edges in double: rounded, they would lose the exact
         * null space of diodes in series and leak current into the node
         * between them, whose voltage only tiny currents decide */
        for (int k = 0; k < r->nnl && x->jq_off[rb] >= 0; k++)
            for (int j = 0; j < ne; j++) {
                int i = (r->nport + k) * ne + j;
                if (!x->mnum[rb][i])
                    sx_stmt(sx, format("    st->c_jQ[%d] = %s;\n", x->jq_off[rb] + k * ne + j,
                                       sx_use(sx, x->msym[rb][i])));
            }
        if (!code)
            continue;
        Buf o = {0};
        emit(&o, "/* Root %d's matrix for the present port resistances: the entries of\n"
                 " * root_edge's order that process uses and that are not numbers. */\n"
                 "static void root%d_solve(state *st) {\n", rb, rb);
        sx_code(sx, &o);
        emit(&o, "%s}\n", r->nnl ? "{{nl_retune}}" : "");
        x->rfn[rb] = str(&o);
    }
}

/* The term of M[k][j] of root b times `in` in a sum t: an entry that is
 * a number for any port resistances is written as one. */
static void mterm(Ctx *x, Buf *t, int b, int k, int j, const char *in) {
    const int ne = x->w->roots[b].nedge;
    const char *plus = t->len ? " + " : "";
    if (!plain(in))
        in = format("(%s)", in);
    if (!x->mnum[b] || !x->mnum[b][k * ne + j])
        emit(t, "%sm%d_%d_%d * %s", plus, b, k, j, in);
    else if (x->mval[b][k * ne + j] == 1)
        emit(t, "%s%s", plus, in);
    else if (x->mval[b][k * ne + j] == -1)
        emit(t, "%s%s", t->len ? " - " : "-", in);
    else
        emit(t, "%s%s * %s", plus, lit(x, x->mval[b][k * ne + j]), in);
}

/* For M[k][j] t_bnG, G a nonlinear edge that returns_v: the term
 * -M t_anG (`late` false) or the term 2 M t_vG (`late`) of a sum t. */
static void vterm(Ctx *x, Buf *t, int b, int k, int j, int g, bool late) {
    const int ne = x->w->roots[b].nedge;
    const char *tv = x->single ? format("(real)t_v%d", g) : format("t_v%d", g);
    if (x->mnum[b] && x->mnum[b][k * ne + j]) {
        double m = x->mval[b][k * ne + j] * (late ? 2 : -1);
        const char *in = late ? tv : format("t_an%d", g);
        if (m == 1 || m == -1)
            emit(t, "%s%s", m < 0 ? (t->len ? " - " : "-") : t->len ? " + " : "", in);
        else
            emit(t, "%s%s * %s", t->len ? " + " : "", lit(x, m), in);
    } else if (late)
        emit(t, "%s2 * m%d_%d_%d * %s", t->len ? " + " : "", b, k, j, tv);
    else
        emit(t, "%sm%d_%d_%d * t_an%d", t->len ? " - " : "-", b, k, j, g);
}

/* Entry M[k][j] of root b as C text: a number, or its local. */
static const char *mcoef(Ctx *x, int b, int k, int j) {
    const int ne = x->w->roots[b].nedge;
    if (x->mzero[b][k * ne + j])
        return "0";
    if (!x->mnum[b] || !x->mnum[b][k * ne + j])
        return format("m%d_%d_%d", b, k, j);
    return format("%.17g", x->mval[b][k * ne + j]);
}

/* Entry M[k][j] of root b (k a nonlinear edge) as the double a float
 * voice's joint solve reads from c_jQ, or NULL where the voice takes M
 * itself (a double voice, or a number). */
static const char *jrow(Ctx *x, int b, int k, int j) {
    const Root *r = &x->w->roots[b];
    if (x->jq_off[b] < 0 || (x->mnum[b] && x->mnum[b][k * r->nedge + j]))
        return NULL;
    return format("st->c_jQ[%d]", x->jq_off[b] + (k - r->nport) * r->nedge + j);
}

/* Union-find over a root's core nodes: the root of a's set. */
static int uf_find(int *up, int a) {
    while (up[a] != a)
        a = up[a] = up[up[a]];
    return a;
}

/* joint_solve's list of the floating groups of joint root b: the groups
 * of core nodes that only nonlinear edges tie to the rest of the root
 * (the reference's group excluded), each as its count of edges, then each
 * edge with its side (see joint_float), and a 0 at the end; "" if none. */
static const char *joint_groups(Ctx *x, int b) {
    const Root *r = &x->w->roots[b];
    int nc = r->ncore, *up = arena_alloc(sizeof(int) * (size_t)(nc + 1));
    for (int v = 0; v <= nc; v++)
        up[v] = v; /* nc: the reference */
    for (int j = 0; j < r->nedge; j++) {
        const RootEdge *e = &r->edge[j];
        if (e->kind == EDGE_NL)
            continue;
        int p = uf_find(up, e->p >= 0 ? e->p : nc), q = uf_find(up, e->q >= 0 ? e->q : nc);
        if (p != q)
            up[p < q ? p : q] = p < q ? q : p; /* the reference stays its set's root */
    }
    /* a controlled source ties what it drives and what it reads (an
     * output's current is no leakage either): no group through one floats */
    for (int j = 0; j < 2 * r->nctl; j++) {
        const struct RootCtl *c = &r->ctl[j / 2];
        int a = j % 2 ? c->cp : c->p, z = j % 2 ? c->cn : c->q;
        int p = uf_find(up, a >= 0 ? a : nc), q = uf_find(up, z >= 0 ? z : nc);
        if (p != q)
            up[p < q ? p : q] = p < q ? q : p;
    }
    Buf o = {0};
    for (int grp = 0; grp < nc; grp++) {
        if (uf_find(up, grp) != grp)
            continue;
        Buf t = {0};
        int n = 0;
        for (int k = 0; k < r->nnl; k++) {
            const RootEdge *e = &r->edge[r->nport + k];
            bool in_p = e->p >= 0 && uf_find(up, e->p) == grp, in_q = e->q >= 0 && uf_find(up, e->q) == grp;
            if (in_p != in_q)
                emit(&t, ", %d, %d", k, in_p ? 1 : -1);
            n += in_p != in_q;
        }
        if (n)
            emit(&o, "%d%s, ", n, str(&t));
    }
    return o.len ? format("%s0", str(&o)) : "";
}

/* The nonlinear edges of joint root b, solved together (joint_solve):
 * what the root's other inputs send them, the root's matrix among them,
 * their resistances and laws, from the last sample's voltages. */
static void emit_joint(Ctx *x, int b) {
    const Root *r = &x->w->roots[b];
    const int m = r->nnl, g0 = x->nl_first[b];
    Buf c = {0}, q = {0}, R = {0}, L = {0}, v = {0}, out = {0};
    for (int k = 0; k < m; k++) {
        const int ek = r->nport + k, g = g0 + k;
        const Elem *e = nl_elem(x, g);
        Buf t = {0};
        for (int j = 0; j < r->nedge; j++) {
            const char *in = root_in(x, b, j);
            if (r->edge[j].kind == EDGE_NL || is_zero(in) || x->mzero[b][ek * r->nedge + j])
                continue;
            if (jrow(x, b, ek, j))
                emit(&t, "%s%s * %s", t.len ? " + " : "", jrow(x, b, ek, j), dbl(x, in));
            else
                mterm(x, &t, b, ek, j, in);
        }
        const char *sep = k ? ", " : "";
        emit(&c, "%s%s", sep, t.len ? dbl(x, format("(%s)", str(&t))) : "0");
        for (int j = r->nport; j < r->nport + m; j++) {
            const char *qk = jrow(x, b, ek, j);
            emit(&q, "%s%s", k || j > r->nport ? ", " : "", qk ? qk : dbl(x, mcoef(x, b, ek, j)));
        }
        emit(&R, "%s%s", sep, dbl(x, format("k_Rn%d", g)));
        if (e->nl->kind == NL_DIODE)
            emit(&L, "%s{c_nl%d_0, c_nl%d_1, %d, 0, NULL, NULL}", sep, g, g, e->nl->pair);
        else
            emit(&L, "%s{0, 1, 0, %d, nl_v%d, nl_i%d}", sep, e->nl->npts, g, g);
        emit(&v, "%s%s", sep, dbl(x, format("s_nv%d", g)));
        emit(&out, "            s_nv%d = (real)t_jv%d[%d];\n", g, b, k);
    }
    Buf o = {0};
    emit(&o, "        double t_jv%d[] = {%s}, t_ji%d[%d]; /* solved jointly:", b, str(&v), b, m);
    for (int k = 0; k < m; k++) {
        const Elem *e = nl_elem(x, g0 + k);
        emit(&o, " %s (%s:%d:%d)%s", e->name, e->pos.file->path, e->pos.line, e->pos.col, k + 1 < m ? "," : "");
    }
    emit(&o, " */\n        {\n");
    emit(&o, "            const double t_c[] = {%s};\n            const double t_Q[] = {%s};\n", str(&c), str(&q));
    emit(&o, "            const double t_R[] = {%s};\n            const jlaw t_L[] = {%s};\n", str(&R), str(&L));
    const char *grp = joint_groups(x, b);
    if (*grp)
        emit(&o, "            static const signed char t_g[] = {%s}; /* floating groups */\n", grp);
    emit(&o, "            const int t_n = joint_solve(%d, t_Q, t_R, t_c, t_L, %s, t_jv%d, t_ji%d, %.17g, %d);\n"
             "            st->s_js[0]++;\n"
             "            st->s_js[1] += (unsigned long)(t_n < 0 ? %d : t_n);\n"
             "            st->s_js[2] += t_n < 0; /* not converged within the cap */\n",
         m, *grp ? "t_g" : "NULL", b, b, x->opt->tol, x->opt->maxit, x->opt->maxit);
    emit(&o, "%s        }\n", str(&out));
    put(x, NULL, "%s", str(&o));
    /* the waves of each edge: b to the root, a for probes */
    for (int k = 0; k < m; k++) {
        const int g = g0 + k;
        const char *R = dbl(x, format("k_Rn%d", g));
        put(x, format("t_bn%d", g), "        const real t_bn%d = (real)(t_jv%d[%d] - %s * t_ji%d[%d]);\n", g, b, k,
            R, b, k);
        put(x, format("t_an%d", g), "        const real t_an%d = (real)(t_jv%d[%d] + %s * t_ji%d[%d]);\n", g, b, k,
            R, b, k);
    }
}

static void emit_root(Ctx *x, int b) {
    const Root *r = &x->w->roots[b];
    x->own = b, x->phase = 'r';
    if (x->w->nroots > 1) /* one root sits between forward and backward, unnamed */
        put(x, NULL, "        /* root %d */\n", b);
    if (r->joint)
        emit_joint(x, b);
    for (int k = r->nport; k < r->nport + r->nnl && !r->joint; k++) {
        Buf t = {0};
        for (int j = 0; j < r->nedge; j++) {
            const char *in = root_in(x, b, j);
            if (j != k && !is_zero(in) && !x->mzero[b][k * r->nedge + j])
                mterm(x, &t, b, k, j, in);
        }
        int g = x->nl_first[b] + k - r->nport;
        x->phase = 'a';
        put(x, format("t_an%d", g), "        const real t_an%d = %s;\n", g, t.len ? str(&t) : lit(x, 0));
        x->phase = 'r';
        emit_nl_solve(x, g);
    }
    for (int k = 0; k < r->nedge; k++) {
        if (r->edge[k].kind == EDGE_NL)
            continue;
        /* the nonlinear edges' waves last: the sum waits for their solve
         * only at its last terms */
        Buf t = {0};
        for (int nl = 0; nl < 3; nl++)
            for (int j = 0; j < r->nedge; j++) {
                const char *in = root_in(x, b, j);
                if ((r->edge[j].kind == EDGE_NL) != (nl > 0) || is_zero(in) || x->mzero[b][k * r->nedge + j])
                    continue;
                int g = r->edge[j].kind == EDGE_NL ? x->nl_first[b] + j - r->nport : -1;
                if (g >= 0 && returns_v(x, g))
                    vterm(x, &t, b, k, j, g, nl == 2);
                else if (nl < 2)
                    mterm(x, &t, b, k, j, in);
            }
        const char *v = t.len ? str(&t) : lit(x, 0);
        if (x->idle[b]) /* the open contact: the port sees an open end */
            v = format("t_open%d ? %s : %s", x->nl_first[b], root_in(x, b, k), v);
        if (r->edge[k].kind == EDGE_PORT) {
            int id = r->edge[k].node->id;
            put(x, format("t_a%d", id), "        const real t_a%d = %s;\n", id, v);
            x->a[id] = format("t_a%d", id);
        } else {
            put(x, format("t_r%d_%d", b, k), "        const real t_r%d_%d = %s; /* %s of %s */\n", b, k, v,
                r->edge[k].kind == EDGE_V ? "current" : "voltage", x->c->elems[r->edge[k].elem].name);
        }
    }
    x->own = -1, x->phase = 0;
}

static void emit_backward(Ctx *x) {
    put(x, NULL, "        /* backward: waves sent to the leaves */\n");
    for (int i = x->w->nnodes - 1; i >= 0; i--) {
        const WNode *n = x->w->nodes[i];
        const char *a = x->a[i], *b = x->b[i];
        x->own = n->root, x->phase = 'b';
        if (n->kind == W_LEAF) {
            const Elem *e = &x->c->elems[n->elem];
            x->bpost[i] = b;
            if (prims[e->kind].state) {
                int r = x->react[i];
                put(x, NULL, "        s_b%d = %s;\n        s_a%d = %s;\n", r, b, r, a);
                x->bpost[i] = format("s_b%d", r);
            } else if (prims[e->kind].wd != WD_WAVEGUIDE) {
                if (prims[e->kind].absorb)
                    put(x, NULL, "        %s /* %s */\n",
                        stamp(x, prims[e->kind].absorb, line_args(x, n->elem, (StampArgs){.a = a})), e->name);
            } else {
                int open[64], nopen, tk = tap_kind(x, n->elem, open, &nopen);
                if (tk == 1) {
                    /* nothing else meets here: the wave passes untouched */
                    int pe = partner_port(x, n->elem);
                    x->a[i] = x->b[x->w->leaf_of[pe]->id];
                    x->bpost[i] = b;
                    continue;
                }
                int w = e->wg, tap = x->wt_off[w] + e->pt - 1;
                const Waveguide *g = &x->c->wgs[w];
                /* untouched while its contacts are open or it is off its string */
                Buf cond = {0}, o = {0};
                if (roams(x, e))
                    emit(&cond, "k_won%d", tap);
                for (int j = 0; j < nopen; j++)
                    emit(&cond, "%s%st_open%d%s", j ? " && " : cond.len ? " && !(" : "!(", "", open[j],
                         j == nopen - 1 ? ")" : "");
                if (cond.len)
                    emit(&o, "        if (%s)\n    ", str(&cond));
                /* what a tap writes reaches an end within a pass of the line,
                 * where it is flushed: tiny waves do not circulate */
                bool end = e->pt == 0 || e->pt == g->ntaps + 1;
                emit(&o, "        %s /* %s */\n",
                     stamp(x, prims[e->kind].absorb, line_args(x, n->elem, (StampArgs){.a = end ? format("flush(%s)", a) : a})),
                     e->name);
                put(x, NULL, "%s", str(&o));
            }
            continue;
        }
        if (n->kind == W_SERIES) {
            put(x, format("t_d%d", i), "        const real t_d%d = %s%s%s;\n", i, a, is_zero(b) ? "" : " - ",
                is_zero(b) ? "" : b);
            for (int k = 0; k < n->nchild; k++) {
                int cid = n->child[k]->id;
                const char *bc = x->b[cid];
                put(x, format("t_a%d", cid), "        const real t_a%d = %s%s%sc_k%d * t_d%d;\n", cid,
                    is_zero(bc) ? "" : bc, n->pol[k] > 0 ? (is_zero(bc) ? "" : " + ") : (is_zero(bc) ? "-" : " - "), "",
                    x->koff[i] + k, i);
                x->a[cid] = format("t_a%d", cid);
            }
        } else {
            put(x, format("t_s%d", i), "        const real t_s%d = %s%s%s;\n", i, a, is_zero(b) ? "" : " + ",
                is_zero(b) ? "" : b);
            for (int k = 0; k < n->nchild; k++) {
                int cid = n->child[k]->id;
                const char *bc = x->b[cid];
                put(x, format("t_a%d", cid), "        const real t_a%d = %st_s%d%s%s;\n", cid, n->pol[k] > 0 ? "" : "-",
                    i, is_zero(bc) ? "" : " - ", is_zero(bc) ? "" : bc);
                x->a[cid] = format("t_a%d", cid);
            }
        }
    }
}

/* The root edge that holds element ei (an ideal source or the nonlinear
 * element): its root and index. */
static void root_edge_of(Ctx *x, int ei, int *rb, int *k) {
    for (*rb = 0; *rb < x->w->nroots; ++*rb)
        for (*k = 0; *k < x->w->roots[*rb].nedge; ++*k)
            if (x->w->roots[*rb].edge[*k].elem == ei)
                return;
    unreachable();
}

/* voltage (n0 - n1) and current (n0 -> n1) of an element after the pass:
 * from its waves, or for a root's source the drive and the root's output */
static const char *elem_vi(Ctx *x, int ei, bool want_v) {
    const Elem *e = &x->c->elems[ei];
    WNode *n = x->w->leaf_of[ei];
    const char *sum = want_v ? "+" : "-";
    if (n) {
        const char *b = x->bpost[n->id];
        const char *scale = want_v ? lit(x, 0.5) : format("k_g%d", n->id);
        return is_zero(b) ? format("%s * t_a%d", scale, n->id)
                          : format("%s * (t_a%d %s %s)", scale, n->id, sum, b);
    }
    int rb, k;
    root_edge_of(x, ei, &rb, &k);
    if (e->kind == E_NL) {
        int g = x->nl_first[rb] + k - x->w->roots[rb].nport;
        return format("%s * (t_an%d %s t_bn%d)", want_v ? lit(x, 0.5) : format("k_gn%d", g), g, sum, g);
    }
    /* a V source's voltage and an I source's current are their drives */
    if ((e->kind == E_V) == want_v)
        return drive_of(x, e);
    return format("t_r%d_%d", rb, k);
}

static const char *elem_v(Ctx *x, int ei) { return elem_vi(x, ei, true); }
static const char *elem_i(Ctx *x, int ei) { return elem_vi(x, ei, false); }

static const char *node_v(Ctx *x, int node) {
    if (node == 0)
        return NULL;
    Buf t = {0};
    for (int k = 0; k < x->w->pathlen[node]; k++) {
        int ei = x->w->path[node][2 * k], sg = x->w->path[node][2 * k + 1];
        emit(&t, "%s(%s)", sg > 0 ? (k ? " + " : "") : (k ? " - " : "-"), elem_v(x, ei));
    }
    return str(&t);
}

static const char *pair_v(Ctx *x, const int *n) {
    const char *a = node_v(x, n[0]), *b = node_v(x, n[1]);
    if (!a && !b)
        return lit(x, 0);
    if (!b)
        return a;
    if (!a)
        return format("-(%s)", b);
    return format("(%s) - (%s)", a, b);
}

static void emit_outputs(Ctx *x) {
    const Circuit *c = x->c;
    int xp = 0;
    put(x, NULL, "        /* outputs */\n");
    for (int k = 0; k < c->nouts; k++) {
        const Probe *p = &c->outs[k];
        switch (p->kind) {
        case PR_V: put(x, NULL, "        out[%d][n] = (double)(%s);\n", k, pair_v(x, p->n)); break;
        case PR_I: case PR_F: /* a resistor that led nowhere carries nothing */
            put(x, NULL, "        out[%d][n] = %s;\n", k, p->elem < 0 ? "0.0" : format("(double)(%s)", elem_i(x, p->elem)));
            break;
        case PR_X:
            put(x, NULL, "        {\n            const real t_v = %s;\n"
                         "            s_x%d += 0.5 * k_T * ((double)t_v + (double)s_xv%d);\n            s_xv%d = t_v;\n"
                         "            out[%d][n] = (double)s_x%d;\n        }\n", pair_v(x, p->n), xp, xp, xp, k, xp);
            xp++;
            break;
        }
    }
}

/* work done by the sources, trapezoidal averages: W += -T (e+e')(i+i')/4 */
static void emit_work(Ctx *x) {
    const Circuit *c = x->c;
    if (!x->energy || !x->nsrc)
        return;
    put(x, NULL, "        /* work of the sources */\n");
    for (int i = 0; i < c->nelems; i++) {
        int s = x->src[i];
        if (s < 0)
            continue;
        const Elem *e = &c->elems[i];
        const char *dr = drive_of(x, e), *other = e->kind == E_V ? elem_i(x, i) : elem_v(x, i);
        put(x, NULL, "        {\n            const real t_o = %s;\n"
                     "            s_work += k_qT * (double)(%s + s_e%d) * (double)(t_o + s_wi%d);\n"
                     "            s_e%d = %s;\n            s_wi%d = t_o;\n        }\n", other, dr, s, s, s, dr, s);
    }
}

/* The sample loop's statements that an output or a state needs: from the
 * last back, a definition stays if a statement kept after it names it.
 * Returns which stay; *live then holds every name they use. */
static bool *live_keep(const Stmt *l, int n, Names *live) {
    bool *keep = arena_alloc(sizeof(bool) * (size_t)(n + 1));
    for (int i = n - 1; i >= 0; i--) {
        if (l[i].def && !names_has(live, l[i].def))
            continue;
        keep[i] = true;
        names_scan(live, l[i].text);
    }
    return keep;
}

/* The text of the statements live_keep keeps. */
static const char *live_text(const Stmt *l, int n, Names *live) {
    bool *keep = live_keep(l, n, live);
    Buf b = {0};
    size_t need = 0;
    for (int i = 0; i < n; i++)
        need += keep[i] ? strlen(l[i].text) : 0;
    buf_reserve(&b, need); /* allocated once */
    for (int i = 0; i < n; i++)
        if (keep[i])
            buf_put(&b, l[i].text, strlen(l[i].text));
    return str(&b);
}

static const char *sample_text(Ctx *x, Names *live) { return live_text(x->stmt, x->nstmt, live); }

/* text with every occurrence of `from` replaced by `to`. */
static const char *replace_all(const char *text, const char *from, const char *to) {
    Buf b = {0};
    size_t n = strlen(from);
    for (const char *p; (p = strstr(text, from));) {
        emit(&b, "%.*s%s", (int)(p - text), text, to);
        text = p + n;
    }
    emit(&b, "%s", text);
    return str(&b);
}

/* Each line of text `levels` levels (four spaces each) deeper. */
static const char *deeper(const char *text, int levels) {
    Buf b = {0};
    for (const char *p = text; *p;) {
        const char *e = strchr(p, '\n');
        size_t n = e ? (size_t)(e - p) + 1 : strlen(p);
        emit(&b, "%*s%.*s", 4 * levels, "", (int)n, p);
        p += n;
    }
    return str(&b);
}

/* ---- an open contact's travel in chunks ----
 *
 * While every idle root's contact is open, each such contact's travel
 * (its compression X and the velocity v across it) is advanced a chunk
 * of frames at a time, in process and in the skipping loop alike: its
 * incident wave is linear in the waves its string ports read (weights
 * alpha) and its masses' held waves (kappa, their sum), so the
 * trapezoidal sum over a chunk needs only the sum of the waves each port
 * reads in it.  A chunk starts (plan) only where those waves are all
 * known: written already, and no tap that scatters (a damper, a contact
 * that is not idle) lies between them and the port; the plan bounds the
 * travel through the chunk by the sizes of those waves and starts it
 * only if the contact stays open throughout.  A contact that meets ends
 * every chunk (cut) where it meets; params and strikes end them first.
 * Skipping or not, every voice computes the same chunks: their samples
 * are the same to the bit. */

/* A string port that an idle contact's incident wave reads. */
typedef struct CkPort {
    int elem;           /* its E_S element */
    const char *alpha;  /* its weight in the incident wave (double) */
} CkPort;

/* The weight of tree node i's reflected wave in its root's tree: the
 * product of the adaptor coefficients from it to the root port. */
static const char *path_weight(Ctx *x, const WNode *n) {
    Buf b = {0};
    int sign = 1;
    for (; n->parent; n = n->parent) {
        const WNode *p = n->parent;
        int k = 0;
        while (p->child[k] != n)
            k++;
        sign *= p->pol[k] > 0 ? 1 : -1;
        if (p->kind != W_SERIES)
            emit(&b, " * (double)c_k%d", x->koff[p->id] + k);
    }
    return format("%s1.0%s", sign < 0 ? "-" : "", str(&b));
}

/* True if tap t (global index) of string w may scatter while every idle
 * root's contact is open: something other than idle contacts meets there. */
static bool tap_writes(Ctx *x, int w, int t) {
    for (int i = 0; i < x->c->nelems; i++) {
        const Elem *e = &x->c->elems[i];
        if (e->kind != E_S || e->wg != w || e->pt != t - x->wt_off[w] + 1)
            continue;
        int open[64], nopen, kind = tap_kind(x, i, open, &nopen);
        if (kind == 1)
            return false;
        if (kind == 0)
            return true;
        for (int j = 0; j < nopen; j++) {
            int r = -1;
            for (int b = 0; b < x->w->nroots; b++)
                if (x->nl_first[b] == open[j] && x->w->roots[b].nnl == 1)
                    r = b;
            if (r < 0 || !x->idle[r])
                return true;
        }
        return false;
    }
    return false;
}

/* The frames from now on whose waves port e (a string's port at a tap)
 * knows: it lowers t_w to them. */
static const char *port_reach(Ctx *x, const Elem *e) {
    const Waveguide *g = &x->c->wgs[e->wg];
    int w = e->wg, T = x->wt_off[w] + e->pt - 1;
    Buf b = {0}, ext = {0};
    if (e->side == 0) { /* the right-going line, from end a */
        Buf wr = {0};
        for (int j = 0; j < g->ntaps; j++) {
            int J = x->wt_off[w] + j;
            if (!tap_writes(x, w, J))
                continue;
            emit(&wr, "                if (k_wk%d < k_wk%d) {\n                    if (k_wk%d - k_wk%d < t_u)\n"
                      "                        t_u = k_wk%d - k_wk%d;\n                    t_lo = 1;\n"
                      "                } else if (k_wk%d == k_wk%d)\n                    t_u = 0;\n",
                 J, T, T, J, T, J, J, T);
            emit(&ext, "                    if (k_wk%d < t_x)\n                        t_x = k_wk%d;\n", J, J);
        }
        emit(&b, "                unsigned t_u = k_wk%d;\n%s%s", T, wr.len ? "                int t_lo = 0;\n" : "", str(&wr));
        if (!g->end[0]) /* end a reflects what the left-going line brings it */
            emit(&b, "                if (%st_u > 0) {\n                    unsigned t_x = k_wNL%d;\n%s"
                     "                    t_u += t_x;\n                }\n", wr.len ? "!t_lo && " : "", w, str(&ext));
    } else { /* the left-going line, from end b */
        emit(&b, "                unsigned t_u = k_wNL%d - k_wk%d;\n", w, T);
        for (int j = 0; j < g->ntaps; j++) {
            int J = x->wt_off[w] + j;
            if (!tap_writes(x, w, J))
                continue;
            emit(&b, "                if (k_wk%d > k_wk%d) {\n                    if (k_wk%d - k_wk%d < t_u)\n"
                     "                        t_u = k_wk%d - k_wk%d;\n                } else if (k_wk%d == k_wk%d)\n"
                     "                    t_u = 0;\n", J, T, J, T, J, T, J, T);
        }
    }
    emit(&b, "                if (t_u < t_w)\n                    t_w = t_u;\n");
    return str(&b);
}

/* The arguments, after the lines, of port_window, port_wave and port_sum
 * for port e: the mask, its delay, the other line's delay to end a and
 * end a's reflection (none from end b, whose waves pass the filters). */
static const char *port_geom(Ctx *x, const Elem *e) {
    const Waveguide *g = &x->c->wgs[e->wg];
    int w = e->wg, T = x->wt_off[w] + e->pt - 1, m = x->wv_size[w] - 1;
    if (e->side == 0)
        return format("%du, k_wk%d, k_wNL%d, %s", m, T, w, g->end[0] ? "0.0" : g->term[0] == 'c' ? "1.0" : "-1.0");
    return format("%du, k_wNL%d - k_wk%d, 0u, 0.0", m, w, T);
}

/* port_window's and port_wave's arguments for port e before the frame:
 * its line, the other line, port_geom. */
static const char *port_args(Ctx *x, const Elem *e) {
    int R = x->wv_off[e->wg], L = R + x->wv_size[e->wg], own = e->side ? L : R;
    return format("s_wv + %d, s_wv + %d, %s", own, L, port_geom(x, e));
}

/* port_sum's: the running sums of the waves and sizes of its line and the
 * other's, port_geom. */
static const char *port_sargs(Ctx *x, const Elem *e) {
    int R = x->wv_off[e->wg], L = R + x->wv_size[e->wg], own = e->side ? L : R;
    return format("s_wP + %d, s_wA + %d, s_wP + %d, s_wA + %d, %s", own, own, L, L, port_geom(x, e));
}

/* Marks the strings whose lines keep running sums (wg_sum). */
static void find_sums(Ctx *x) {
    x->wg_sum = arena_alloc(sizeof(bool) * (size_t)(x->c->nwgs + 1));
    for (int i = 0; i < x->w->nnodes; i++) {
        const WNode *n = x->w->nodes[i];
        if (n->kind != W_LEAF || !x->idle[n->root] || x->c->elems[n->elem].kind != E_S)
            continue;
        int w = x->c->elems[n->elem].wg;
        bool clean = true;
        for (int j = 0; j < x->c->wgs[w].ntaps && clean; j++)
            clean = !tap_writes(x, w, x->wt_off[w] + j);
        x->wg_sum[w] = clean;
        x->anysum |= clean;
    }
}

static void chunk_texts(Ctx *x) {
    find_sums(x);
    int nnl = x->nnl > 0 ? x->nnl : 1;
    x->ck_plan = arena_alloc(sizeof(char *) * (size_t)nnl);
    x->ck_end = arena_alloc(sizeof(char *) * (size_t)nnl);
    x->ck_cut = arena_alloc(sizeof(char *) * (size_t)nnl);
    for (int b = 0; b < x->w->nroots; b++) {
        if (!x->idle[b])
            continue;
        int k = x->nl_first[b];
        const Elem *ce = nl_elem(x, k);
        /* the incident wave: M[1][0] times the tree's reflected wave */
        Buf mt = {0};
        mterm(x, &mt, b, 1, 0, "1");
        const char *mc = x->mzero[b][1 * x->w->roots[b].nedge + 0] ? "0.0" : format("(double)(%s)", str(&mt));
        CkPort *port = arena_alloc(sizeof(CkPort) * (size_t)(x->w->nnodes + 1));
        int np = 0;
        Buf kap = {0};
        for (int i = 0; i < x->w->nnodes; i++) {
            const WNode *n = x->w->nodes[i];
            if (n->root != b || n->kind != W_LEAF)
                continue;
            const Elem *e = &x->c->elems[n->elem];
            const char *wt = format("%s * %s", mc, path_weight(x, n));
            if (e->kind == E_S) {
                if (roams(x, e))
                    wt = format("(k_won%d ? %s : 0.0)", x->wt_off[e->wg] + e->pt - 1, wt);
                port[np++] = (CkPort){n->elem, wt};
            } else if (x->react[i] >= 0) {
                const char *bm = stamp(x, prims[e->kind].reflect,
                                       line_args(x, n->elem, (StampArgs){.a = format("s_a%d", x->react[i]),
                                                                          .R = format("k_R%d", i)}));
                emit(&kap, " + %s * (double)(%s)", wt, bm);
            }
        }
        Buf w8 = {0}, pre = {0};
        emit(&pre, "                const double t_ka = 0.0%s;\n", str(&kap));
        for (int q = 0; q < np; q++)
            emit(&pre, "                const double t_al%d = %s;\n", q, port[q].alpha);
        /* plan: the frames ahead the contact is known to stay open */
        Buf p = {0};
        emit(&p, "            if (s_ck%d == 0) { /* %s (%s:%d:%d): how long its travel stays open */\n"
                 "                unsigned t_w = 1u << 20;\n",
             k, ce->name, ce->pos.file->path, ce->pos.line, ce->pos.col);
        for (int q = 0; q < np; q++) {
            const Elem *e = &x->c->elems[port[q].elem];
            const char *reach = port_reach(x, e);
            if (roams(x, e))
                emit(&p, "                if (k_won%d) {\n%s                }\n", x->wt_off[e->wg] + e->pt - 1,
                     deeper(reach, 1));
            else
                emit(&p, "                {\n%s                }\n", deeper(reach, 1));
        }
        /* ending with a run of FLUSH_RUN frames: the skipping loop's batches are whole runs */
        emit(&p, "                if (((t_pos + t_w) & ~(FLUSH_RUN - 1u)) - t_pos - 1u < t_w)\n"
                 "                    t_w = ((t_pos + t_w) & ~(FLUSH_RUN - 1u)) - t_pos;\n");
        emit(&p, "%s", str(&pre));
        emit(&p, "                const double t_X = %s - c_nl%d_3, t_nv = %s;\n", dbl(x, format("s_nX%d", k)), k,
             dbl(x, format("s_nv%d", k)));
        emit(&p, "                double t_S = t_ka * t_w, t_A = fabs(t_ka) * t_w, t_E = t_ka, t_m;\n"
                 "                if (t_w > 0) {\n");
        for (int q = 0; q < np; q++) {
            const Elem *e = &x->c->elems[port[q].elem];
            const char *a = port_args(x, e);
            if (x->wg_sum[e->wg])
                emit(&p, "                    if (t_al%d != 0) {\n"
                         "                        t_S += t_al%d * port_sum(%s, t_pos, t_pos - 1u, t_w, &t_m);\n"
                         "                        t_A += fabs(t_al%d) * t_m;\n"
                         "                        t_E += t_al%d * port_wave(%s, t_pos + t_w - 1u, t_pos - 1u);\n"
                         "                    }\n", q, q, port_sargs(x, e), q, q, a);
            else
                emit(&p, "                    if (t_al%d != 0) {\n"
                         "                        t_S += t_al%d * port_window(%s, t_pos, t_pos - 1u, t_w, &t_m);\n"
                         "                        t_A += fabs(t_al%d) * t_m;\n"
                         "                        t_E += t_al%d * port_wave(%s, t_pos + t_w - 1u, t_pos - 1u);\n"
                         "                    }\n", q, q, a, q, q, a);
            emit(&w8, "                        t_a1 += t_al%d * port_wave(%s, t_pos, t_pos - 1u);\n", q, a);
        }
        emit(&p, "                    /* the travel through the chunk is at most T/2 (|v| + 2 sum |a|) */\n"
                 "                    const double t_B = 0.5 * k_T * (fabs(t_nv) + 2 * t_A);\n"
                 "                    if (!(t_X + t_B <= -1e-10 * (fabs(t_X) + t_B))) {\n"
                 "                        /* not through all of it: through the next frame? */\n"
                 "                        double t_a1 = t_ka;\n%s"
                 "                        const double t_X1 = t_X + 0.5 * k_T * (t_nv + t_a1);\n"
                 "                        t_w = t_X1 <= -1e-10 * (fabs(t_X) + 0.5 * k_T * (fabs(t_nv) + fabs(t_a1))) ? 1u : 0u;\n"
                 "                        t_S = t_E = t_a1;\n"
                 "                    }\n"
                 "                    s_ck%d = (int)t_w;\n"
                 "                    s_ce%d = t_pos + t_w, s_cS%d = t_S, s_cE%d = t_E;\n"
                 "                }\n            }\n",
             str(&w8), k, k, k, k);
        x->ck_plan[k] = str(&p);
        x->ck_end[k] = format("s_nX%d = flush((real)(%s + 0.5 * k_T * (%s + 2 * s_cS%d - s_cE%d)));\n"
                              "s_nv%d = flush((real)s_cE%d);\n",
                              k, dbl(x, format("s_nX%d", k)), dbl(x, format("s_nv%d", k)), k, k, k, k);
        /* cut: the chunk's sum less that of the frames from t_q on */
        Buf c = {0};
        emit(&c, "            if (s_ck%d > 0) { /* %s: its travel up to t_q */\n%s"
                 "                const unsigned t_r = s_ce%d - t_q;\n"
                 "                double t_R = t_ka * t_r, t_E = t_ka, t_m;\n",
             k, ce->name, str(&pre), k);
        for (int q = 0; q < np; q++) {
            const Elem *e = &x->c->elems[port[q].elem];
            const char *a = port_args(x, e);
            emit(&c, "                if (t_al%d != 0) {\n"
                     "                    if (t_r > 0)\n"
                     "                        t_R += t_al%d * %s;\n"
                     "                    t_E += t_al%d * port_wave(%s, t_q - 1u, t_q - 1u);\n"
                     "                }\n", q, q,
                 x->wg_sum[e->wg] ? format("port_sum(%s, t_q, t_q - 1u, t_r, &t_m)", port_sargs(x, e))
                                  : format("port_window(%s, t_q, t_q - 1u, t_r, &t_m)", a), q, a);
        }
        emit(&c, "                s_nX%d = (real)(%s + 0.5 * k_T * (%s + 2 * (s_cS%d - t_R) - t_E));\n"
                 "                s_nv%d = (real)t_E;\n                s_ck%d = 0;\n            }\n",
             k, dbl(x, format("s_nX%d", k)), dbl(x, format("s_nv%d", k)), k, k, k);
        x->ck_cut[k] = str(&c);
    }
}

/* The texts t[k] of the idle contacts k, one after another. */
static const char *idle_each(Ctx *x, const char **t) {
    Buf b = {0};
    for (int r = 0; r < x->w->nroots; r++)
        if (x->idle[r])
            emit(&b, "%s", t[x->nl_first[r]]);
    return str(&b);
}

/* fmt (naming a contact's index once) for each idle contact, joined by sep. */
static const char *idle_join(Ctx *x, const char *fmt, const char *sep) {
    Buf b = {0};
    for (int r = 0; r < x->w->nroots; r++)
        if (x->idle[r])
            emit(&b, "%s%s", b.len ? sep : "", format(fmt, x->nl_first[r]));
    return str(&b);
}

/* The plans of the idle contacts not in a chunk, in process's text. */
static const char *chunk_plans(Ctx *x) {
    Buf b = {0};
    if (x->anysum) { /* the running sums, anew after a contact touched a string, and every 2^22 frames
                      * (a sum of sizes that grew without end would lose the small ones) */
        /* where a contact plans: the same frames skipping or not */
        emit(&b, "            if ((%s) && (!s_wPv || t_pos - s_wPt > 1u << 22)) {\n                s_wPt = t_pos;\n",
             idle_join(x, "s_ck%d == 0", " || "));
        for (int w = 0; w < x->c->nwgs; w++)
            if (x->wg_sum[w])
                for (int d = 0; d < 2; d++) {
                    int off = x->wv_off[w] + d * x->wv_size[w];
                    emit(&b, "                ring_sums(s_wv + %d, s_wP + %d, s_wA + %d, %du, t_pos, &s_wPr%d, &s_wAr%d);\n",
                         off, off, off, x->wv_size[w] - 1, 2 * w + d, 2 * w + d);
                }
        emit(&b, "                s_wPv = 1;\n            }\n");
    }
    return format("%s%s", str(&b), idle_each(x, x->ck_plan));
}

/* The cuts of every idle contact's chunk at frame t_q. */
static const char *chunk_cuts(Ctx *x) {
    return format("%s%s", x->anysum ? "            s_wPv = 0; /* a contact touches a string: its sums are made anew */\n" : "",
                  idle_each(x, x->ck_cut));
}

/* "s_nf0 == 0 && ...": every idle contact open (carried no force). */
static const char *all_open(Ctx *x) { return idle_join(x, "s_nf%d == 0", " && "); }

/* The sample loop while the contacts of idle roots stay open: their
 * trees' forward waves and their contacts' incident waves first; then the
 * test that leaves this sample to the full loop if a contact would not
 * stay open; then the contacts' travel; then the rest of the loop without
 * the idle trees' stores (their masses hold, their taps pass untouched).
 * Returns the text; *live gains the names it uses. */
static const char *idle_text(Ctx *x, Names *live) {
    Stmt *l = arena_alloc(sizeof(Stmt) * (size_t)(x->nstmt + 4 * x->nidle + 1));
    int n = 0;
    /* an output may read a contact's incident wave: the trees' forward
     * waves, computed only if one does */
    for (int i = 0; i < x->nstmt; i++) {
        const Stmt *s = &x->stmt[i];
        if (s->own >= 0 && x->idle[s->own] && s->def && (s->phase == 'f' || s->phase == 'a'))
            l[n++] = *s;
    }
    Buf wpre = {0}, stop = {0}, ends = {0};
    for (int b = 0; b < x->w->nroots; b++) {
        if (!x->idle[b])
            continue;
        int k = x->nl_first[b];
        l[n++] = (Stmt){format("t_bn%d", k), format("        const real t_bn%d = (real)(2 * %s - %s);\n", k,
                                                   dbl(x, format("t_an%d", k)), dbl(x, format("t_an%d", k))), -1, 0};
        l[n++] = (Stmt){format("t_open%d", k), format("        const int t_open%d = 1;\n", k), -1, 0};
        emit(&stop, "%s                    if (s_ck%d < t_left)\n                        t_left = s_ck%d;\n",
             stop.len ? "" : "                    t_left = 1 << 30;\n", k, k);
        emit(&ends, "s_ck%d -= t_done;\nif (s_ck%d == 0) {\n%s}\n", k, k, deeper(x->ck_end[k], 1));
    }
    for (int i = 0; i < x->nstmt; i++) {
        const Stmt *s = &x->stmt[i];
        if (s->phase != 'k' && !(s->own >= 0 && x->idle[s->own] && (!s->def || s->phase == 'f' || s->phase == 'a')))
            l[n++] = *s;
    }
    /* leaving: the waves that last arrived at the trees' string ports */
    for (int i = 0; i < x->w->nnodes; i++) {
        const WNode *nd = x->w->nodes[i];
        const Elem *e = &x->c->elems[nd->elem];
        if (nd->kind == W_LEAF && x->idle[nd->root] && e->kind == E_S && x->sp_of[nd->elem] >= 0)
            emit(&wpre, "                s_wpre%d = (real)port_wave(%s, t_pos - 1u, t_pos - 1u);\n", x->sp_of[nd->elem],
                 port_args(x, e));
    }
    Names lv = {0};
    const char *body = deeper(live_text(l, n, &lv), 2);
    /* entering: each mass's last incident wave is its held one, as after
     * a sample of the full loop with the contact open */
    Buf hold = {0};
    for (int i = 0; i < x->w->nnodes; i++) {
        const WNode *nd = x->w->nodes[i];
        if (nd->kind == W_LEAF && x->idle[nd->root] && x->react[i] >= 0)
            emit(&hold, "            s_b%d = %s;\n", x->react[i],
                 stamp(x, prims[x->c->elems[nd->elem].kind].reflect, (StampArgs){.a = format("s_a%d", x->react[i])}));
    }
    /* t_left: frames before the first chunk ends; t_done: frames since
     * the chunks' counts (s_ck) were brought up to date; t_wait: the last
     * frame was this loop's (the ports' last waves are still in the lines) */
    const char *text = format("        if (t_left > 0 || (%s)) {\n"
                              "            /* the contacts are open: the parts behind them wait,\n"
                              "             * and their travel goes by chunks */\n"
                              "            while (n < t_end) {\n"
                              "                if (t_left == 0) {\n%s"
                              "                    if (t_done > 0) { /* the chunks that ended */\n%s"
                              "                        t_done = 0;\n                    }\n%s"
                              "                    if (%s)\n"
                              "                        break; /* a contact's travel is not known: the full loop steps it */\n%s"
                              "                }\n"
                              "                const int t_stop = t_end - n < t_left ? t_end : n + t_left;\n"
                              "                t_left -= t_stop - n, t_done += t_stop - n;\n"
                              "                for (; n < t_stop; n++) {\n%s                }\n"
                              "                t_wait = 1;\n"
                              "            }\n"
                              "            if (n < t_end || n == nframes) { /* leaving for the full loop or the host */\n"
                              "                if (t_done > 0) {\n%s                    t_done = 0;\n                }\n"
                              "                if (t_wait) {\n%s                }\n"
                              "            }\n"
                              "        }\n",
                              all_open(x), deeper(str(&hold), 2), deeper(str(&ends), 6), deeper(chunk_plans(x), 2),
                              idle_join(x, "s_ck%d == 0", " || "), str(&stop), body, deeper(str(&ends), 5), deeper(str(&wpre), 1));
    names_scan(live, text);
    return text;
}

/* ---- hoisting and write-back ---- */

/* The locals of process (block-rate values, and states held in registers
 * through the loop), each with its write-back and flush. */
static void emit_hoist(Ctx *x) {
    const Circuit *c = x->c;
    local(x, "k_hT", "    const real k_hT = (real)(0.5 / st->fs);\n", NULL, NULL);
    local(x, "k_qT", "    const double k_qT = -0.25 / st->fs;\n", NULL, NULL);
    local(x, "s_work", "    double s_work = st->s_work;\n", "    st->s_work = s_work;\n", NULL);
    if (x->nline || c->nwgs)
        local(x, "t_pos", "    unsigned t_pos = st->s_pos;\n", "    st->s_pos = t_pos;\n", NULL);
    local(x, "s_dl", "    real *const s_dl = st->s_dl;\n", NULL, NULL);
    local(x, "s_wv", "    real *const s_wv = st->s_wv;\n", NULL, NULL);
    for (int k = 0; k < x->nline; k++)
        local(x, format("k_D%d", k), format("    const unsigned k_D%d = st->c_D[%d];\n", k, k), NULL, NULL);
    for (int w = 0; w < c->nwgs; w++) {
        local(x, format("k_wNR%d", w), format("    const unsigned k_wNR%d = st->c_wN[%d];\n", w, 2 * w), NULL, NULL);
        local(x, format("k_wNL%d", w), format("    const unsigned k_wNL%d = st->c_wN[%d];\n", w, 2 * w + 1), NULL,
              NULL);
        static const char *cf[] = {"lb", "la", "ra"};
        for (int j = 0; j < 3; j++)
            local(x, format("k_w%s%d", cf[j], w),
                  format("    const real k_w%s%d = st->c_wf[%d];\n", cf[j], w, x->wc_off[w] + j), NULL, NULL);
        for (int j = 0; j < c->wgs[w].ntaps; j++) {
            int t = x->wt_off[w] + j;
            local(x, format("k_wk%d", t), format("    const unsigned k_wk%d = st->c_wk[%d];\n", t, t), NULL, NULL);
            local(x, format("k_won%d", t), format("    const int k_won%d = st->c_won[%d];\n", t, t), NULL, NULL);
        }
    }
    for (int w = 0; w < c->nwgs; w++) {
        int f0 = x->wf_off[w], nl = 1 + c->wgs[w].nrad;
        /* the waves end b wrote in the run: flushed one by one once the
         * loop filter's state is (a wave below FLUSH_BELOW comes only from
         * a quiet loop, and that state follows the loop's level) */
        int L = x->wv_off[w] + x->wv_size[w], m = x->wv_size[w] - 1;
        const char *quiet = c->wgs[w].end[1] ? ""
                            : format("        if (s_wf%d == 0) /* a quiet loop: the waves end b wrote in the run */\n"
                                     "            for (unsigned j = 1; j <= FLUSH_RUN; j++)\n"
                                     "                s_wv[%d + ((t_pos - j) & %du)] = flush(s_wv[%d + ((t_pos - j) & %du)]);\n",
                                     f0, L, m, L, m);
        for (int f = f0; f < f0 + nl; f++) { /* one-poles: locals */
            local(x, format("s_wf%d", f), format("    real s_wf%d = st->s_wf[%d];\n", f, f),
                  format("    st->s_wf[%d] = s_wf%d;\n", f, f),
                  format("        s_wf%d = flush(s_wf%d);\n%s", f, f, f == f0 ? quiet : ""));
            local(x, format("s_wq%d", f), format("    real s_wq%d = st->s_wfp[%d];\n", f, f),
                  format("    st->s_wfp[%d] = s_wq%d;\n", f, f), format("        s_wq%d = flush(s_wq%d);\n", f, f));
        }
        local(x, format("k_wJ%d", w), format("    const unsigned k_wJ%d = st->c_wJ[%d];\n", w, w), NULL, NULL);
        if (c->wgs[w].M == 1) { /* the one stage's state and rotation: locals */
            int f = f0 + nl;
            local(x, format("k_wak%d", w), format("    const real k_wak%d = st->c_wf[%d];\n", w, x->wc_off[w] + 3),
                  NULL, NULL);
            local(x, format("k_wac%d", w), format("    const real k_wac%d = st->c_wf[%d];\n", w, x->wc_off[w] + 4),
                  NULL, NULL);
            local(x, format("s_wf%d", f), format("    real s_wf%d = st->s_wf[%d];\n", f, f),
                  format("    st->s_wf[%d] = s_wf%d;\n", f, f), format("        s_wf%d = flush(s_wf%d);\n", f, f));
            local(x, format("s_wq%d", f), format("    real s_wq%d = st->s_wfp[%d];\n", f, f),
                  format("    st->s_wfp[%d] = s_wq%d;\n", f, f), format("        s_wq%d = flush(s_wq%d);\n", f, f));
            continue;
        }
        local(x, NULL, NULL, NULL,
              format("        for (int m = %d; m < %d; m++) {\n            st->s_wf[m] = flush(st->s_wf[m]);\n"
                     "            st->s_wfp[m] = flush(st->s_wfp[m]);\n        }\n", f0 + nl, f0 + nl + c->wgs[w].M));
    }
    if (x->anysum) {
        local(x, "s_wP", "    double *const s_wP = st->s_wP;\n", NULL, NULL);
        local(x, "s_wA", "    double *const s_wA = st->s_wA;\n", NULL, NULL);
        local(x, "s_wPv", "    int s_wPv = st->s_wPv;\n", "    st->s_wPv = s_wPv;\n", NULL);
        local(x, "s_wPt", "    unsigned s_wPt = st->s_wPt;\n", "    st->s_wPt = s_wPt;\n", NULL);
        for (int w = 0; w < c->nwgs; w++)
            for (int d = 0; x->wg_sum[w] && d < 2; d++) {
                int j = 2 * w + d;
                local(x, format("s_wPr%d", j), format("    double s_wPr%d = st->s_wPr[%d];\n", j, j),
                      format("    st->s_wPr[%d] = s_wPr%d;\n", j, j), NULL);
                local(x, format("s_wAr%d", j), format("    double s_wAr%d = st->s_wAr[%d];\n", j, j),
                      format("    st->s_wAr[%d] = s_wAr%d;\n", j, j), NULL);
            }
    }
    for (int k = 0; k < x->nsp; k++)
        local(x, format("s_wpre%d", k), format("    real s_wpre%d = st->s_wpre[%d];\n", k, k),
              format("    st->s_wpre[%d] = s_wpre%d;\n", k, k), NULL);
    local(x, "k_T", "    const double k_T = 1.0 / st->fs;\n", NULL, NULL);
    for (int k = 0; k < x->nnl; k++) {
        local(x, format("k_Rn%d", k), format("    const real k_Rn%d = st->c_Rn[%d];\n", k, k), NULL, NULL);
        local(x, format("k_gn%d", k), format("    const real k_gn%d = %s / st->c_Rn[%d];\n", k, lit(x, 0.5), k), NULL,
              NULL);
        for (int j = 0; j < 6; j++)
            local(x, format("c_fk%d_%d", k, j), format("    const double c_fk%d_%d = st->c_fk[%d];\n", k, j, 6 * k + j),
                  NULL, NULL);
        for (int j = 0; j < 4; j++)
            local(x, format("c_nl%d_%d", k, j),
                  format("    const double c_nl%d_%d = %s;\n", k, j, dbl(x, format("st->c_nl[%d]", 4 * k + j))), NULL,
                  NULL);
        static const char *sn[] = {"X", "v", "f"};
        for (int j = 0; j < 3; j++)
            local(x, format("s_n%s%d", sn[j], k), format("    real s_n%s%d = st->s_n%s[%d];\n", sn[j], k, sn[j], k),
                  format("    st->s_n%s[%d] = s_n%s%d;\n", sn[j], k, sn[j], k),
                  format("        s_n%s%d = flush(s_n%s%d);\n", sn[j], k, sn[j], k));
        if (idle_contact(x, k)) { /* its chunk */
            static const char *cn[] = {"k", "e", "S", "E"}, *ct[] = {"int", "unsigned", "double", "double"};
            for (int j = 0; j < 4; j++)
                local(x, format("s_c%s%d", cn[j], k), format("    %s s_c%s%d = st->s_c%s[%d];\n", ct[j], cn[j], k, cn[j], k),
                      format("    st->s_c%s[%d] = s_c%s%d;\n", cn[j], k, cn[j], k), NULL);
        }
        if (x->pwl_n[k]) {
            static const char *pn[] = {"a", "b", "s"};
            for (int j = 0; j < 3; j++)
                local(x, format("c_p%s%d", pn[j], k),
                      format("    const real *const c_p%s%d = st->c_p%s + %d;\n", pn[j], k, pn[j], x->pwl_off[k]),
                      NULL, NULL);
        }
    }
    for (int i = 0; i < c->ninputs; i++)
        local(x, format("in%d", i), format("    const double *const in%d = in[%d];\n", i, i), NULL, NULL);
    for (int i = 0; i < x->nk; i++)
        local(x, format("c_k%d", i), format("    const real c_k%d = st->c_k[%d];\n", i, i), NULL, NULL);
    for (int b = 0; b < x->w->nroots; b++) {
        const Root *r = &x->w->roots[b];
        for (int k = 0; k < r->nedge; k++)
            for (int j = 0; j < r->nedge; j++)
                local(x, format("m%d_%d_%d", b, k, j),
                      x->mnum[b] && x->mnum[b][k * r->nedge + j]
                          ? format("    const real m%d_%d_%d = %s;\n", b, k, j, lit(x, x->mval[b][k * r->nedge + j]))
                          : format("    const real m%d_%d_%d = st->c_M[%d];\n", b, k, j, x->moff[b] + k * r->nedge + j),
                      NULL, NULL);
    }
    for (int i = 0; i < x->w->nnodes; i++) {
        local(x, format("k_R%d", i), format("    const real k_R%d = st->c_R[%d];\n", i, i), NULL, NULL);
        local(x, format("k_g%d", i), format("    const real k_g%d = %s / st->c_R[%d];\n", i, lit(x, 0.5), i), NULL,
              NULL);
    }
    for (int i = 0; i < c->nelems; i++)
        if (x->src[i] >= 0 && c->elems[i].input < 0)
            local(x, format("c_e%d", x->src[i]), format("    const real c_e%d = st->c_e[%d];\n", x->src[i], x->src[i]),
                  NULL, NULL);
    for (int r = 0; r < x->nreact; r++) {
        local(x, format("s_a%d", r), format("    real s_a%d = st->s_a[%d];\n", r, r),
              format("    st->s_a[%d] = s_a%d;\n", r, r), format("        s_a%d = flush(s_a%d);\n", r, r));
        local(x, format("s_b%d", r), format("    real s_b%d = st->s_b[%d];\n", r, r),
              format("    st->s_b[%d] = s_b%d;\n", r, r), format("        s_b%d = flush(s_b%d);\n", r, r));
    }
    for (int k = 0; k < x_probes(c); k++) {
        local(x, format("s_x%d", k), format("    double s_x%d = st->s_x[%d];\n", k, k),
              format("    st->s_x[%d] = s_x%d;\n", k, k), NULL);
        local(x, format("s_xv%d", k), format("    real s_xv%d = st->s_xv[%d];\n", k, k),
              format("    st->s_xv[%d] = s_xv%d;\n", k, k), format("        s_xv%d = flush(s_xv%d);\n", k, k));
    }
    for (int s = 0; s < x->nsrc; s++) {
        local(x, format("s_e%d", s), format("    real s_e%d = st->s_e[%d];\n", s, s),
              format("    st->s_e[%d] = s_e%d;\n", s, s), NULL);
        local(x, format("s_wi%d", s), format("    real s_wi%d = st->s_wi[%d];\n", s, s),
              format("    st->s_wi[%d] = s_wi%d;\n", s, s), NULL);
    }
    /* without the accounting, the drive of the last sample is kept for
     * settle once a block */
    if (x->nsrc && x->settle && !x->energy) {
        Buf wb = {0};
        for (int i = 0; i < c->nelems; i++) {
            const Elem *e = &c->elems[i];
            if (x->src[i] >= 0)
                emit(&wb, "        st->s_e[%d] = %s;\n", x->src[i],
                     e->input >= 0 ? format("(real)in[%d][nframes - 1]", e->input) : format("st->c_e[%d]", x->src[i]));
        }
        /* one statement needs no braces */
        bool one = strchr(str(&wb), '\n') == str(&wb) + wb.len - 1;
        local(x, NULL, NULL,
              one ? format("    if (nframes > 0)\n%s", str(&wb)) : format("    if (nframes > 0) {\n%s    }\n", str(&wb)),
              NULL);
    }
}

/* The locals that kept text names (and those their declarations name),
 * in order: declarations, write-backs, flushes. */
/* The locals process keeps: those the text in *live names, and those
 * their own declarations name; *live takes in their names. */
static bool *kept_locals(Ctx *x, Names *live) {
    bool *keep = arena_alloc(sizeof(bool) * (size_t)(x->nloc + 1));
    for (int i = x->nloc - 1; i >= 0; i--) {
        const Local *l = &x->loc[i];
        if (l->name && !names_has(live, l->name))
            continue;
        keep[i] = true;
        names_scan(live, l->decl);
    }
    return keep;
}

/* True if local `name` is a state of an idle root's tree or contact: it
 * holds while the skipping loop runs (a chunk's end flushes the travel). */
static bool idle_state(const Ctx *x, const char *name) {
    if (!name || !x->nidle)
        return false;
    int k, r;
    char c;
    if (sscanf(name, "s_n%c%d", &c, &k) == 2 && (c == 'X' || c == 'v' || c == 'f'))
        return idle_contact(x, k);
    if (sscanf(name, "s_%c%d", &c, &r) == 2 && (c == 'a' || c == 'b'))
        for (int i = 0; i < x->w->nnodes; i++)
            if (x->react[i] == r)
                return x->w->nodes[i]->kind == W_LEAF && x->idle[x->w->nodes[i]->root];
    return false;
}

/* The kept locals' declarations, write-backs and flushes (those of idle
 * states in *fli, if given). */
static void print_locals_split(Ctx *x, Names *live, Buf *decl, Buf *wb, Buf *fl, Buf *fli) {
    bool *keep = kept_locals(x, live);
    for (int i = 0; i < x->nloc; i++)
        if (keep[i]) {
            emit(decl, "%s", x->loc[i].decl);
            emit(wb, "%s", x->loc[i].wb);
            emit(fli && idle_state(x, x->loc[i].name) ? fli : fl, "%s", x->loc[i].fl);
        }
}

static void print_locals(Ctx *x, Names *live, Buf *decl, Buf *wb, Buf *fl) {
    print_locals_split(x, live, decl, wb, fl, NULL);
}

/* voice_cut, which param changes (update) and strikes (set_ic) call
 * before they change the state: every idle contact's chunk ends before
 * the next frame; "" for a voice without idle contacts. */
static const char *chunk_fn(Ctx *x) {
    if (!x->nidle)
        return "";
    Buf cuts = {0};
    for (const char *p = chunk_cuts(x); *p;) { /* a level less deep */
        const char *e = strchr(p, '\n');
        size_t n = e ? (size_t)(e - p) + 1 : strlen(p);
        size_t lead = n > 4 && !strncmp(p, "    ", 4) ? 4 : 0;
        emit(&cuts, "%.*s", (int)(n - lead), p + lead);
        p += n;
    }
    const char *body = format("    const unsigned t_q = t_pos;\n%s", str(&cuts));
    Names live = {0};
    names_scan(&live, body);
    bool *keep = kept_locals(x, &live);
    Buf decl = {0}, wb = {0};
    for (int i = 0; i < x->nloc; i++)
        if (keep[i] && x->loc[i].name) {
            emit(&decl, "%s", x->loc[i].decl);
            emit(&wb, "%s", x->loc[i].wb);
        }
    return format("/* Ends the chunk of every idle contact's travel before the next frame:\n"
                  " * a param change or a strike changes what it summed. */\n"
                  "static void voice_cut(state *st) {\n%s%s%s}\n\n", str(&decl), body, str(&wb));
}

/* ---- reset, initial conditions, energy ---- */

static const char *ic_node_value(Ctx *x, char fn, int node) {
    if (node == 0)
        return "0";
    for (int i = 0; i < x->c->nics; i++)
        if (x->c->ics[i].fn == fn && x->c->ics[i].node == node)
            return format("(%s)", cexpr(x, x->c->ics[i].val));
    return "0";
}

/* The force (current) nonlinear edge k holds at rest: a contact's or a
 * nonlinear inductor's elastic one; diodes and curves carry none. */
static bool nl_has_force(Ctx *x, int k) {
    const NlSpec *nl = nl_elem(x, k)->nl;
    return nl->mutated == 'L' || (nl->kind == NL_CONTACT && !nl->mutated);
}

/* The state a voice keeps of its sources' drives: the last one, for
 * settle and the work. */
static bool keeps_drive(Ctx *x) { return x->nsrc && (x->settle || x->energy); }

/* True if the cleared state is the one settle would find at reset: no
 * initial condition, constant drive, nonlinear edge or waveguide gives
 * any Kirchhoff quantity a value, so all of them are 0. */
static bool rests_at_zero(Ctx *x) {
    const Circuit *c = x->c;
    if (c->nics || x->nnl || c->nwgs)
        return false;
    for (int i = 0; i < c->nelems; i++)
        if (c->elems[i].ic || (x->src[i] >= 0 && c->elems[i].input < 0 && keeps_drive(x)))
            return false;
    return true;
}

/* What reset sets after clearing the states (initial conditions, then
 * the Kirchhoff state from settle), and in *probes what settle then sets
 * of nonlinear edges and displacement probes from the node values x[]. */
static void emit_reset(Ctx *x, Buf *o, Buf *probes) {
    const Circuit *c = x->c;
    for (int i = 0; i < c->nelems; i++) {
        const Elem *e = &c->elems[i];
        if (x->src[i] >= 0 && e->input < 0 && keeps_drive(x))
            emit(o, "    st->s_e[%d] = st->c_e[%d];\n", x->src[i], x->src[i]);
        /* a deck's source driven by its input starts at its time function's
         * first value, which a render without --input plays from there */
        if (x->src[i] >= 0 && e->input >= 0 && keeps_drive(x) && x->dcop && c->input_fn[e->input] &&
            srcfn_at(c->input_fn[e->input], 0, 1 / c->rate) != 0)
            emit(o, "    st->s_e[%d] = %s;\n", x->src[i], lit(x, srcfn_at(c->input_fn[e->input], 0, 1 / c->rate)));
    }
    if (x->dcop)
        emit(o, "    dcop(st, react);\n");
    for (int i = 0; i < c->nelems; i++) {
        const Elem *e = &c->elems[i];
        WNode *n = x->w->leaf_of[i];
        if (e->ic && n && x->settle)
            emit(o, "    react[%d] = %s; /* %s */\n", x->react[n->id], cexpr(x, e->ic), e->name);
    }
    for (int k = 0; k < x->nnl; k++) {
        const Elem *e = nl_elem(x, k);
        if (e->nl->kind == NL_CONTACT || e->nl->mutated == 'L')
            emit(o, "    st->s_nX[%d] = (real)(%s - %s);\n", k, ic_node_value(x, 'x', e->n[0]),
                 ic_node_value(x, 'x', e->n[1]));
        emit(probes, "        st->s_nv[%d] = (real)((%s) - (%s));\n", k,
             e->n[0] ? format("x[%d]", e->n[0] - 1) : "0", e->n[1] ? format("x[%d]", e->n[1] - 1) : "0");
        /* the last force of a contact or inductor; a capacitor holds the
         * charge of the voltage across it */
        if (e->nl->mutated == 'C')
            emit(probes, "        st->s_nf[%d] = st->s_nv[%d];\n", k, k);
        else
            emit(probes, nl_has_force(x, k) ? "        st->s_nf[%d] = (real)nl_force(st, %d);\n"
                                            : "        st->s_nf[%d] = 0;\n", k, k);
    }
    int xp = 0;
    for (int k = 0; k < c->nouts; k++) {
        const Probe *p = &c->outs[k];
        if (p->kind != PR_X)
            continue;
        emit(o, "    st->s_x[%d] = (double)(%s - %s);\n", xp, ic_node_value(x, 'x', p->n[0]),
             ic_node_value(x, 'x', p->n[1]));
        emit(probes, "        st->s_xv[%d] = (real)((%s) - (%s));\n", xp,
             p->n[0] ? format("x[%d]", p->n[0] - 1) : "0", p->n[1] ? format("x[%d]", p->n[1] - 1) : "0");
        xp++;
    }
    if (c->nwgs)
        emit(o, "    memset(st->s_wv, 0, sizeof st->s_wv);\n    memset(st->s_wf, 0, sizeof st->s_wf);\n"
                "    memset(st->s_wfp, 0, sizeof st->s_wfp);\n    memset(st->s_wpre, 0, sizeof st->s_wpre);\n");
    if (x->settle && (!rests_at_zero(x) || x->dcop))
        emit(o, "    settle(st, %s);\n", x->nreact ? "react" : "NULL");
}

/* Locals c_nlK_0 and c_nlK_1 (Is, n Vt) that mem_args names for the
 * diode law behind mutator k. */
static const char *mem_locals(int k, const NlSpec *nl) {
    if (nl->kind != NL_DIODE)
        return "";
    return format("const double c_nl%d_0 = st->c_nl[%d], c_nl%d_1 = st->c_nl[%d]; ", k, 4 * k, k, 4 * k + 1);
}

/* Stored energy (into o) and, into kirch, the reactances' Kirchhoff
 * values (v of C, i of L) read back from their waves. */
static void emit_energy(Ctx *x, Buf *o, Buf *kirch) {
    for (int w = 0; w < x->c->nwgs; w++)
        emit(o, "    E += wg_energy(st, %d); /* %s */\n", w, x->c->wgs[w].name);
    for (int i = 0; i < x->c->nelems; i++) { /* the waves a line end keeps */
        const Elem *e = &x->c->elems[i];
        if (prims[e->kind].absorb && prims[e->kind].energy)
            emit(o, "    { /* %s: the waves in flight */\n        %s\n    }\n", e->name,
                 stamp(x, prims[e->kind].energy, line_args(x, i, (StampArgs){.R = format("st->c_R[%d]", x->w->leaf_of[i]->id)})));
    }
    for (int k = 0; k < x->nnl; k++) {
        const Elem *e = nl_elem(x, k);
        if (e->nl->mutated == 'L')
            emit(o, "    { %sE += mem_G(st->s_nX[%d], %s); }\n", mem_locals(k, e->nl), k, mem_args(k, e->nl));
        if (e->nl->mutated == 'C')
            emit(o, "    { %sconst double v = st->s_nf[%d]; double d; E += v * mem_g(v, %s, &d) - mem_G(v, %s); }\n",
                 mem_locals(k, e->nl), k, mem_args(k, e->nl), mem_args(k, e->nl));
        if (e->nl->kind == NL_CONTACT)
            emit(o, "    { double X = st->s_nX[%d] - st->c_nl[%d], al = st->c_nl[%d]; "
                    "if (X > 0) E += %s * pow(X, al + 1) / (al + 1); } /* %s */\n",
                 k, 4 * k + 3, 4 * k + 1, dbl(x, format("st->c_nl[%d]", 4 * k)), e->name);
    }
    for (int i = 0; i < x->w->nnodes; i++) {
        int r = x->react[i];
        if (r < 0)
            continue;
        const Prim *pr = &prims[x->c->elems[x->w->nodes[i]->elem].kind];
        StampArgs g = {.a = format("st->s_a[%d]", r), .b = format("st->s_b[%d]", r), .R = format("st->c_R[%d]", i)};
        g.x = stamp(x, pr->stored, g);
        emit(kirch, "    react[%d] = %s;\n", r, g.x);
        emit(o, "    { %s }\n", stamp(x, pr->energy, g));
    }
}

/* Which strike targets set something, in ic_targets' order (node by node
 * from 1, v then x): v(node) a capacitor (mass) from node to ground;
 * x(node) an inductor (spring) from node to ground, a contact at node, or
 * a displacement probe of node.  set[] takes 2 (nnodes - 1) entries.
 * emit_ic_cases writes a case for just these. */
void wdf_ic_settable(const Wdf *w, bool *set) {
    const Circuit *c = w->c;
    for (int id = 0; id < 2 * (c->nnodes - 1); id++)
        set[id] = false;
    for (int i = 0; i < w->nnodes; i++) {
        const WNode *n = w->nodes[i];
        if (n->kind != W_LEAF || !prims[c->elems[n->elem].kind].state)
            continue;
        const Elem *e = &c->elems[n->elem];
        int nd = e->n[1] == 0 ? e->n[0] : e->n[0] == 0 ? e->n[1] : 0;
        if (nd)
            set[2 * (nd - 1) + (prims[e->kind].strike == 'x')] = true;
    }
    for (int b = 0; b < w->nroots; b++)
        for (int j = 0; j < w->roots[b].nnl; j++) {
            const Elem *e = &c->elems[w->roots[b].edge[w->roots[b].nport + j].elem];
            for (int t = 0; t < 2 && e->nl->kind == NL_CONTACT; t++)
                if (e->n[t])
                    set[2 * (e->n[t] - 1) + 1] = true;
        }
    for (int k = 0; k < c->nouts; k++)
        if (c->outs[k].kind == PR_X && c->outs[k].n[0] && c->outs[k].n[1] == 0)
            set[2 * (c->outs[k].n[0] - 1) + 1] = true;
}

/* strike targets: v(node) sets capacitors from node to ground, x(node)
 * sets inductors from node to ground and the node's displacement probes;
 * a target that sets nothing has no case (wdf_ic_settable) */
static void emit_ic_cases(Ctx *x, Buf *targets, Buf *cases) {
    const Circuit *c = x->c;
    int id = 0, full = 0;
    bool direct = true; /* every case sets react[id] to its value */
    bool *set = arena_alloc(sizeof(bool) * (size_t)(2 * c->nnodes + 1));
    wdf_ic_settable(x->w, set);
    /* the reactances from each node to ground, in tree order */
    int *first = arena_alloc(sizeof(int) * (size_t)(c->nnodes + 1));
    int *next = arena_alloc(sizeof(int) * (size_t)(x->w->nnodes + 1));
    for (int nd = 0; nd < c->nnodes; nd++)
        first[nd] = -1;
    for (int i = x->w->nnodes - 1; i >= 0; i--) {
        if (x->react[i] < 0)
            continue;
        const Elem *e = &c->elems[x->w->nodes[i]->elem];
        int nd = e->n[1] == 0 ? e->n[0] : e->n[0] == 0 ? e->n[1] : 0;
        if (nd) {
            next[i] = first[nd];
            first[nd] = i;
        }
    }
    for (int nd = 1; nd < c->nnodes; nd++)
        for (int f = 0; f < 2; f++, full++) {
            char fn = f ? 'x' : 'v';
            Buf t = {0};
            for (int i = first[nd]; i >= 0; i = next[i]) {
                const WNode *n = x->w->nodes[i];
                const Elem *e = &c->elems[n->elem];
                int sg = e->n[0] == nd && e->n[1] == 0 ? 1 : e->n[1] == nd && e->n[0] == 0 ? -1 : 0;
                /* the target its descriptor names: v(node) a charge, x(node) a flux */
                if (!sg || prims[e->kind].strike != fn)
                    continue;
                emit(&t, "            react[%d] = %s;\n", x->react[i],
                     stamp(x, prims[e->kind].struck,
                           (StampArgs){.x = sg > 0 ? "values[k]" : "-values[k]", .R = format("st->c_R[%d]", i)}));
            }
            /* a contact's compression is set from either of its nodes: its
             * distance from what it strikes, negative while apart */
            for (int k = 0; k < x->nnl && fn == 'x'; k++) {
                const Elem *e = nl_elem(x, k);
                int sg = e->n[0] == nd ? 1 : e->n[1] == nd ? -1 : 0;
                if (sg && e->nl->kind == NL_CONTACT)
                    emit(&t, "            st->s_nX[%d] = (real)(%svalues[k]);\n", k, sg > 0 ? "" : "-");
            }
            int xp = 0;
            for (int k = 0; k < c->nouts; k++)
                if (c->outs[k].kind == PR_X) {
                    if (fn == 'x' && c->outs[k].n[0] == nd && c->outs[k].n[1] == 0)
                        emit(&t, "            st->s_x[%d] = values[k];\n", xp);
                    xp++;
                }
            if ((t.len > 0) != set[full])
                die("strike target %c(%s): its cases and wdf_ic_settable disagree", fn, c->nodes[nd]);
            if (!t.len)
                continue;
            emit(targets, "%s{\"%c(%s)\", \"%s\"}", id ? ", " : "", fn, c->nodes[nd], domain_unit(c->domain, fn));
            emit(cases, "        case %d: /* %c(%s) */\n%s            break;\n", id, fn, c->nodes[nd], str(&t));
            direct = direct && !strcmp(str(&t), format("            react[%d] = values[k];\n", id));
            id++;
        }
    x->nic = id;
    x->ic_direct = direct;
}

/* ---- nonlinear elements: kernels, tables, hooks ---- */

/* The table PREFIX_vK[], PREFIX_iK[] of n points (V, A), under a comment
 * saying what it is. */
static void points_table(Buf *tables, const char *what, const char *prefix, int k, const double *v, const double *i,
                         int n) {
    Buf tv = {0}, ti = {0};
    for (int j = 0; j < n; j++) {
        emit(&tv, "%s%.17g", j ? ", " : "", v[j]);
        emit(&ti, "%s%.17g", j ? ", " : "", i[j]);
    }
    emit(tables, "/* %s (V, A) */\nstatic const double %s_v%d[] = {%s};\nstatic const double %s_i%d[] = {%s};\n", what,
         prefix, k, str(&tv), prefix, k, str(&ti));
}

static void emit_nonlinear(Ctx *x, Buf *kernels, Buf *tables, Buf *retune, Buf *force) {
    bool newton = false, fast = false, omega = false, pwl = false, contact = false, memory = false, inductor = false,
         capacitor = false, joint = false;
    for (int k = 0; k < x->nnl; k++) {
        const Elem *e = nl_elem(x, k);
        if (solver_of(x, k) == SOLVER_JOINT) {
            joint = true;
            if (e->nl->kind == NL_CURVE)
                points_table(tables, format("%s: its curve", e->name), "nl", k, e->nl->cv, e->nl->ci, e->nl->npts);
        } else if (e->nl->mutated) {
            memory = true;
            inductor |= e->nl->mutated == 'L';
            capacitor |= e->nl->mutated == 'C';
            if (e->nl->kind == NL_CURVE)
                points_table(tables, format("%s: its inner resistor's curve", e->name), "mem", k, e->nl->cv,
                             e->nl->ci, e->nl->npts);
            if (e->nl->mutated == 'L')
                emit(force, "    if (k == %d) { %sdouble d; return mem_g(st->s_nX[%d], %s, &d); }\n", k,
                     mem_locals(k, e->nl), k, mem_args(k, e->nl));
        } else if (e->nl->kind == NL_CONTACT) {
            contact = true;
            emit(force, "    if (k == %d) { const el_law L = %s; double d; return el_F(&L, st->s_nX[%d] - st->c_nl[%d], &d); }\n",
                 k, el_law_init(k, e->nl, false), k, 4 * k + 3);
        } else if (x->pwl_n[k]) {
            pwl = true;
            points_table(tables, format("%s: Kirchhoff points of its piecewise-linear map", e->name), "nl", k,
                         x->pwl_v[k], x->pwl_i[k], x->pwl_n[k]);
            emit(retune, "    pwl_table(nl_v%d, nl_i%d, %d, st->c_Rn[%d], st->c_pa + %d, st->c_pb + %d, st->c_ps + %d);\n",
                 k, k, x->pwl_n[k], k, x->pwl_off[k], x->pwl_off[k], x->pwl_off[k]);
        } else {
            Solver s = solver_of(x, k);
            omega |= s == SOLVER_OMEGA;
            fast |= s == SOLVER_FAST;
            newton |= s == SOLVER_NEWTON || s == SOLVER_OMEGA; /* omega finishes a pair by Newton */
        }
    }
    if (newton || memory || joint)
        emit(kernels, "%s", tmpl_nl_diode_i);
    if (newton)
        emit(kernels, "%s", tmpl_nl_wright);
    if (newton)
        emit(kernels, "%s", tmpl_nl_diode);
    if (omega)
        emit(kernels, "%s", tmpl_nl_omega);
    if (fast) {
        int n;
        const double *om = fast_tables(&n);
        emit(kernels, "%s", tmpl_nl_fast);
        emit(tables, "/* diode_fast's tables (templates/nl_fast_table.c.tmpl): a cubic in t per line */\n"
                     "static const double fast_om[OM_SIZE] = {\n");
        for (int i = 0; i < n; i++)
            emit(tables, "%s%a%s", i % 4 ? " " : "    ", om[i], i + 1 < n ? (i % 4 == 3 ? ",\n" : ",") : "\n};\n");
    }
    if (pwl)
        emit(kernels, "%s", tmpl_nl_pwl);
    if (memory || joint)
        emit(kernels, "%s", tmpl_nl_g);
    if (memory)
        emit(kernels, "%s", tmpl_nl_memory);
    if (joint)
        emit(kernels, "%s", tmpl_nl_joint);
    if (contact || memory)
        emit(kernels, "%s", tmpl_nl_law);
    if (contact || inductor)
        emit(kernels, "%s", tmpl_nl_passive);
    if (capacitor)
        emit(kernels, "%s", tmpl_nl_memcap);
}

/* ---- tables and descriptors ---- */

static const char *c_string(const char *s) {
    Buf b = {0};
    emit(&b, "\"");
    for (; *s; s++)
        emit(&b, *s == '"' || *s == '\\' ? "\\%c" : "%c", *s);
    emit(&b, "\"");
    return str(&b);
}
/* The params a waveguide's loop design or tap positions depend on: a
 * host steps them rather than ramping them (WDV_PARAM_STEP), and those
 * of the design (wg_params) ask for a new one (WDV_PARAM_DESIGN). */
static uint64_t step_params(const Circuit *c) {
    uint64_t mask = 0;
    for (int w = 0; w < c->nwgs; w++) {
        const Waveguide *g = &c->wgs[w];
        mask |= expr_params(g->f0) | expr_params(g->Rp) | expr_params(g->B) | expr_params(g->fhf) |
                (g->t60 ? expr_params(g->t60) : 0) | (g->t60hf ? expr_params(g->t60hf) : 0);
        for (int j = 0; j < g->ntaps; j++)
            mask |= expr_params(g->tap_pos[j]);
    }
    return mask;
}


static const char *descriptors(Ctx *x, char which) {
    const Circuit *c = x->c;
    Buf b = {0};
    emit(&b, "{");
    int n = which == 'i' ? c->ninputs : which == 'o' ? c->nouts : c->nparams;
    for (int i = 0; i < n; i++) {
        if (which == 'i') {
            const Elem *drv = NULL;
            for (int k = 0; k < c->nelems; k++)
                if (c->elems[k].input == i)
                    drv = &c->elems[k];
            char fn = drv && drv->kind == E_I ? 'i' : 'v';
            emit(&b, "%s{%s, \"%s\"}", i ? ", " : "", c_string(c->inputs[i]), domain_unit(c->domain, fn));
        } else if (which == 'o') {
            const Probe *p = &c->outs[i];
            char fn = p->kind == PR_V ? 'v' : p->kind == PR_X ? 'x' : 'i';
            emit(&b, "%s{%s, \"%s\"}", i ? ", " : "", c_string(p->name), domain_unit(c->domain, fn));
        } else {
            const Param *p = &c->params[i];
            emit(&b, "%s{%s, %s, %.17g, %s, %s, %s}", i ? ", " : "", c_string(p->name), c_string(p->unit), p->def,
                 isfinite(p->min) ? format("%.17g", p->min) : "-1e308",
                 isfinite(p->max) ? format("%.17g", p->max) : "1e308",
                 (wg_params(c) >> i) & 1 ? "WDV_PARAM_STEP | WDV_PARAM_DESIGN"
                 : (step_params(c) >> i) & 1 ? "WDV_PARAM_STEP" : "0");
        }
    }
    emit(&b, "}");
    return str(&b);
}

/* The edges of every root, one after the other, and per root: first
 * edge, edge count, nodal unknowns, ideal V sources, matrix offset. */
/* The codes of the voice's tables (templates/codes.def). */
static const struct Code {
    const char *name, *what;
    int value;
} all_codes[] = {
#define CODE(name, value, what) {#name, what, value},
#include "../templates/codes.def"
#undef CODE
};
#define NCODES ((int)(sizeof all_codes / sizeof all_codes[0]))

/* The name of code `value` of a group (its prefix: "EDGE_", "IC_"...). */
static const char *code_name(const char *group, int value) {
    for (int i = 0; i < NCODES; i++)
        if (!strncmp(all_codes[i].name, group, strlen(group)) && all_codes[i].value == value)
            return all_codes[i].name;
    unreachable();
}

static const char *edge_code(int kind) { return code_name("EDGE_", kind); }
static const char *ic_code(int kind) { return code_name("IC_", kind); }

static const char *root_table(Ctx *x, Buf *desc) {
    Buf b = {0};
    emit(&b, "{");
    emit(desc, "{");
    int first = 0;
    for (int rb = 0; rb < x->w->nroots; rb++) {
        const Root *r = &x->w->roots[rb];
        for (int k = 0; k < r->nedge; k++) {
            const RootEdge *e = &r->edge[k];
            emit(&b, "%s{%s, %d, %d, %d}", first + k ? ", " : "", edge_code(e->kind), e->p, e->q,
                 e->kind == EDGE_PORT ? e->node->id : e->kind == EDGE_NL ? x->nl_first[rb] + k - r->nport : -1);
        }
        emit(desc, "%s{%d, %d, %d, %d, %d}", rb ? ", " : "", first, r->nedge, r->ncore + r->nx + r->nv, r->nv,
             x->moff[rb]);
        first += r->nedge;
    }
    emit(&b, "}");
    emit(desc, "}");
    return str(&b);
}


/* The nonlinear index of element e, or -1. */
static int nl_index(Ctx *x, const Elem *e) {
    for (int k = 0; k < x->nnl; k++)
        if (nl_elem(x, k) == e)
            return k;
    return -1;
}

/* settle in straight-line code (solve.c): the network of ic_table solved
 * as the compiler eliminated it, or NULL if it needs the general solve.
 * `force`: whether nl_force exists; `probes`: what settle sets from the
 * node values x[]. */
/* Element i of the Kirchhoff solves (settle, dcop) when it is a resistor
 * or a source: its edge in L, its value into *v (a resistor's emf, a
 * source's last drive); -2 for the reactances and the rest, which each
 * solve stamps its own way. */
static int stamp_source(Ctx *x, Sx *sx, Lin *L, int i, Sym *val, Sym *v) {
    const Elem *e = &x->c->elems[i];
    const WNode *n = x->w->leaf_of[i];
    int kind = prim_ic(e), p = e->n[0] - 1, q = e->n[1] - 1, k;
    Sym drive = keeps_drive(x) && x->src[i] >= 0 ? sym_ext(dbl(x, format("st->s_e[%d]", x->src[i]))) : sym_k(0);
    Sym g = n ? sx_temp(sx, format("1.0 / %s", dbl(x, format("st->c_R[%d]", n->id)))) : sym_k(0);
    *v = sym_k(0);
    switch (kind) {
    case IC_RES: return n ? lin_g(L, p, q, g) : -1;
    case IC_V: *v = drive; return lin_v(L, p, q);
    case IC_I: *v = drive; return lin_j(L, p, q);
    case IC_RV: *v = drive; return lin_g(L, p, q, g);
    case IC_RI:
        k = lin_g(L, p, q, g);
        val[k] = sym_k(0);
        *v = drive;
        return lin_j(L, p, q);
    case IC_WAVE: /* a waveguide's port: its resistance and the wave that last arrived */
        *v = sym_ext(dbl(x, format("st->s_wpre[%d]", x->sp_of[i])));
        return lin_g(L, p, q, g);
    default: return -2;
    }
}

static const char *settle_static(Ctx *x, bool force, const char *probes) {
    const Circuit *c = x->c;
    if (x->nctl || x->nlop) /* the straight-line solve takes conductances and sources only */
        return NULL;
    Sx *sx = sx_new("u");
    sx_once(sx, !x->opt->single);
    Lin *L = lin_new(sx, c->nnodes - 1);
    int *ea = arena_alloc(sizeof(int) * (size_t)c->nelems);
    Sym *val = arena_alloc(sizeof(Sym) * (size_t)(2 * c->nelems + 1));
    /* capacitors across one pair of nodes hold one voltage: the first
     * stands for them all (lead, sign sg against it), and their current
     * parts as their capacitances, as their conductances 1/R (gsum) */
    int *lead = arena_alloc(sizeof(int) * (size_t)c->nelems), *sg = arena_alloc(sizeof(int) * (size_t)c->nelems);
    Sym *gsum = arena_alloc(sizeof(Sym) * (size_t)c->nelems);
    bool *shared = arena_alloc(sizeof(bool) * (size_t)c->nelems);
    /* the first capacitor across each pair of nodes, found through a
     * table keyed by the pair (open addressing), in time linear in the
     * count */
    size_t cap = 16;
    while (cap < 2 * (size_t)c->nelems)
        cap *= 2;
    int *first = arena_alloc(sizeof(int) * cap);
    for (size_t h = 0; h < cap; h++)
        first[h] = -1;
    for (int i = 0; i < c->nelems; i++) {
        const Elem *e = &c->elems[i];
        lead[i] = -1, sg[i] = 1;
        if (prim_ic(e) != IC_CAP)
            continue;
        size_t lo = (size_t)(e->n[0] < e->n[1] ? e->n[0] : e->n[1]), hi = (size_t)(e->n[0] < e->n[1] ? e->n[1] : e->n[0]);
        size_t h = (lo * 2654435761u ^ hi * 40503u) & (cap - 1);
        for (; first[h] >= 0; h = (h + 1) & (cap - 1)) {
            const Elem *f = &c->elems[first[h]];
            if ((f->n[0] == e->n[0] && f->n[1] == e->n[1]) || (f->n[0] == e->n[1] && f->n[1] == e->n[0]))
                break;
        }
        if (first[h] >= 0)
            lead[i] = first[h], sg[i] = c->elems[first[h]].n[0] == e->n[0] ? 1 : -1;
        else
            first[h] = lead[i] = i;
    }
    for (int i = 0; i < c->nelems; i++)
        if (lead[i] >= 0 && lead[i] != i) {
            int l = lead[i];
            Sym gi = sx_temp(sx, format("1.0 / %s", dbl(x, format("st->c_R[%d]", x->w->leaf_of[i]->id))));
            if (!shared[l])
                gsum[l] = sx_temp(sx, format("1.0 / %s", dbl(x, format("st->c_R[%d]", x->w->leaf_of[l]->id))));
            shared[l] = true;
            gsum[l] = sx_add(sx, gsum[l], gi);
        }
    for (int i = 0; i < c->nelems; i++) {
        const Elem *e = &c->elems[i];
        const WNode *n = x->w->leaf_of[i];
        int kind = prim_ic(e), p = e->n[0] - 1, q = e->n[1] - 1, k = -1;
        if (kind == IC_CAP && lead[i] != i) {
            ea[i] = -1;
            continue;
        }
        Sym v;
        k = stamp_source(x, sx, L, i, val, &v);
        if (kind == IC_CAP)
            k = lin_v(L, p, q), v = sym_ext(format("react[%d]", x->react[n->id]));
        else if (kind == IC_IND)
            k = lin_j(L, p, q), v = sym_ext(format("react[%d]", x->react[n->id]));
        else if (kind == IC_FORCE)
            k = lin_j(L, p, q), v = force ? sx_temp(sx, format("nl_force(st, %d)", nl_index(x, e))) : sym_k(0);
        ea[i] = k;
        if (k >= 0)
            val[k] = v;
    }
    if (!lin_factor(L))
        return NULL;
    Sym *pot = arena_alloc(sizeof(Sym) * (size_t)c->nnodes), *cur = arena_alloc(sizeof(Sym) * (size_t)(2 * c->nelems + 1));
    lin_solve(L, val, pot, cur);
    bool work = x->energy && x->nsrc;
    /* the values first, then what settle stores of them */
    const char **lhs = arena_alloc(sizeof(char *) * (size_t)(3 * c->nelems + 1));
    Sym *rhs = arena_alloc(sizeof(Sym) * (size_t)(3 * c->nelems + 1));
    int nout = 0;
    for (int i = 0; i < c->nelems; i++) {
        const Elem *e = &c->elems[i];
        const WNode *n = x->w->leaf_of[i];
        int kind = prim_ic(e), p = e->n[0] - 1, q = e->n[1] - 1;
        Sym v = sx_sub(sx, p >= 0 ? pot[p] : sym_k(0), q >= 0 ? pot[q] : sym_k(0));
        if (kind == IC_CAP || kind == IC_IND) {
            int r = x->react[n->id], l = kind == IC_CAP ? lead[i] : i;
            Sym Ri = shared[l] ? sx_div(sx, cur[ea[l]], gsum[l])
                                  : sx_mul(sx, sym_ext(dbl(x, format("st->c_R[%d]", n->id))), cur[ea[i]]);
            if (kind == IC_CAP)
                v = val[ea[l]];
            if (sg[i] < 0)
                v = sx_neg(sx, v), Ri = sx_neg(sx, Ri);
            lhs[nout] = format("st->s_a[%d]", r), rhs[nout++] = sx_add(sx, v, Ri);
            lhs[nout] = format("st->s_b[%d]", r), rhs[nout++] = sx_sub(sx, v, Ri);
        }
        if (work && x->src[i] >= 0)
            lhs[nout] = format("st->s_wi[%d]", x->src[i]), rhs[nout++] = kind == IC_V || kind == IC_RV ? cur[ea[i]] : v;
    }
    for (int k = 0; k < nout; k++)
        sx_stmt(sx, format("    %s = (real)%s;\n", lhs[k], sx_use(sx, rhs[k])));
    if (*probes) {
        Buf xs = {0};
        for (int k = 0; k + 1 < c->nnodes; k++)
            emit(&xs, "%s%s", k ? ", " : "", sx_use(sx, pot[k]));
        sx_stmt(sx, c->nnodes > 1 ? format("    {\n        const double x[] = {%s};\n%s    }\n", str(&xs), probes)
                                  : format("    {\n%s    }\n", probes));
    }
    Buf o = {0};
    sx_code(sx, &o);
    const char *body = str(&o);
    return format("/* The last sample's waves from a consistent Kirchhoff state: the network as eliminated, with\n"
                  " * the given reactances (v of a capacitor, i of an inductor) and the sources' last drives. */\n"
                  "static int settle(state *st, const double *react%s) {\n%s    return 0;\n}\n",
                  uses(body, "react") ? "" : " UNUSED", body);
}

/* A SPICE deck starts from its DC operating point, as SPICE's transient
 * does: capacitors open, inductors shorted, sources at their drives (an
 * input's at 0), and, where a node is held only by capacitors or current
 * sources, SPICE's GMIN (1e-12 S) from every node to ground.  Sets x->dcop
 * to dcop(), which writes each reactance's value (a capacitor's voltage,
 * an inductor's current) for settle; false where it does not apply: not a
 * deck, .tran ... UIC, nonlinear elements, lines or waveguides (whose
 * operating point this linear solve cannot give), or a network singular
 * even with GMIN. */
static bool dcop_try(Ctx *x, bool gmin) {
    const Circuit *c = x->c;
    if (!c->deck || c->uic || !x->settle || !x->nreact || x->nnl || c->nwgs || x->nline || x->nctl)
        return false;
    Sx *sx = sx_new("u");
    sx_once(sx, !x->opt->single);
    Lin *L = lin_new(sx, c->nnodes - 1);
    int *ea = arena_alloc(sizeof(int) * (size_t)c->nelems);
    Sym *val = arena_alloc(sizeof(Sym) * (size_t)(2 * c->nelems + c->nnodes + 1));
    for (int i = 0; i < c->nelems; i++) {
        const Elem *e = &c->elems[i];
        int kind = prim_ic(e), p = e->n[0] - 1, q = e->n[1] - 1, k;
        Sym v;
        k = stamp_source(x, sx, L, i, val, &v);
        if (kind == IC_CAP)
            k = -1; /* open */
        else if (kind == IC_IND)
            k = lin_v(L, p, q), v = sym_k(0); /* shorted */
        else if (k == -2 || kind == IC_WAVE)
            return false;
        ea[i] = k;
        if (k >= 0)
            val[k] = v;
    }
    for (int nd = 0; gmin && nd + 1 < c->nnodes; nd++)
        val[lin_g(L, nd, -1, sym_k(1e-12))] = sym_k(0);
    if (!lin_factor(L))
        return false;
    Sym *pot = arena_alloc(sizeof(Sym) * (size_t)c->nnodes), *cur = arena_alloc(sizeof(Sym) * (size_t)(2 * c->nelems + c->nnodes + 1));
    lin_solve(L, val, pot, cur);
    for (int i = 0; i < c->nelems; i++) {
        const Elem *e = &c->elems[i];
        const WNode *n = x->w->leaf_of[i];
        int kind = prim_ic(e), p = e->n[0] - 1, q = e->n[1] - 1;
        if (kind == IC_CAP)
            sx_stmt(sx, format("    react[%d] = %s;\n", x->react[n->id],
                               sx_use(sx, sx_sub(sx, p >= 0 ? pot[p] : sym_k(0), q >= 0 ? pot[q] : sym_k(0)))));
        else if (kind == IC_IND)
            sx_stmt(sx, format("    react[%d] = %s;\n", x->react[n->id], sx_use(sx, cur[ea[i]])));
    }
    Buf o = {0};
    sx_code(sx, &o);
    x->dcop = format("/* The deck's DC operating point, as SPICE's transient starts from it:\n"
                     " * capacitors open, inductors shorted, the sources at their drives (an\n"
                     " * input's at 0)%s; each reactance's value into react for settle. */\n"
                     "static void dcop(const state *st, double *react) {\n%s}\n",
                     gmin ? ", GMIN 1e-12 S from every node to ground" : "", str(&o));
    return true;
}

/* A deck with nonlinear elements or controlled sources starts from its
 * DC operating point too, found here (dcop.c) at the default params:
 * dcop() writes each reactance's value there, and settle takes each
 * diode, curve and transistor source as a source of its current there
 * (x->nlop), so that the capacitors start with no current through them. */
static const char *dcop_nonlinear(Ctx *x) {
    const Circuit *c = x->c;
    if (!c->deck || c->uic || !x->settle || !x->nreact || !(x->nnl || x->nctl || x->ncc) || c->nwgs || x->nline)
        return NULL;
    double *p = circuit_defaults(c), *drive = dcop_drives(c, p);
    double *nodev = arena_alloc(sizeof(double) * (size_t)(c->nnodes + 1));
    double *cur = arena_alloc(sizeof(double) * (size_t)(c->nelems + 1));
    if (!dcop_solve(c, p, drive, nodev, cur)) {
        note_at(c->elems[0].pos, "the deck's DC operating point was not found: its voice starts from rest");
        return NULL;
    }
    bool rest = true; /* where the operating point is rest, the voice starts there anyway */
    for (int n = 0; n < c->nnodes; n++)
        rest &= nodev[n] == 0;
    for (int i = 0; i < c->nelems; i++)
        rest &= cur[i] == 0;
    if (rest)
        return NULL;
    Buf b = {0};
    for (int i = 0; i < c->nelems; i++) {
        const Elem *e = &c->elems[i];
        const WNode *n = x->w->leaf_of[i];
        if (n && prim_ic(e) == IC_CAP)
            emit(&b, "    react[%d] = %s; /* %s */\n", x->react[n->id], lit(x, nodev[e->n[0]] - nodev[e->n[1]]), e->name);
        else if (n && prim_ic(e) == IC_IND)
            emit(&b, "    react[%d] = %s; /* %s */\n", x->react[n->id], lit(x, cur[i]), e->name);
    }
    x->nlop = cur;
    return format("/* The deck's DC operating point, as SPICE's transient starts from it:\n"
                  " * capacitors open, inductors shorted, the sources at their drives (an\n"
                  " * input's at its first value), the nonlinear elements and controlled\n"
                  " * sources solved with them when the voice was compiled (at the\n"
                  " * default params); each reactance's value into react for settle. */\n"
                  "static void dcop(const state *st UNUSED, double *react) {\n%s}\n", str(&b));
}

static const char *dcop_static(Ctx *x) {
    return dcop_try(x, false) || dcop_try(x, true) ? x->dcop : dcop_nonlinear(x);
}

/* settle's case of diodes, curves and transistors' sources: open at rest,
 * or at a deck's operating point the current they carry there. */
static const char *ic_open(Ctx *x) {
    if (!x->nlop)
        return "        case IC_OPEN: break; /* a diode or curve at rest carries no current */\n";
    Buf b = {0};
    for (int i = 0; i < x->c->nelems; i++)
        emit(&b, "%s%s", i ? ", " : "", lit(x, x->nlop[i]));
    return format("        case IC_OPEN: case IC_CC: { /* the current it carries at the operating point */\n"
                  "            static const double op[] = {%s};\n"
                  "            if (p >= 0) x[p] -= op[k];\n"
                  "            if (q >= 0) x[q] += op[k];\n"
                  "            break;\n"
                  "        }\n", str(&b));
}

static const char *ic_table(Ctx *x, int *nv) {
    const Circuit *c = x->c;
    Buf b = {0};
    emit(&b, "{");
    *nv = 0;
    int nctl = 0;
    for (int i = 0; i < c->nelems; i++) {
        const Elem *e = &c->elems[i];
        WNode *n = x->w->leaf_of[i];
        int kind = prim_ic(e), nli = nl_index(x, e);
        *nv += kind == IC_CAP || kind == IC_V || kind == IC_CV || kind == IC_OA || kind == IC_XF;
        if (ELEM_CONTROLLED(e->kind)) /* an output: its row of ic_ctl */
            nli = e->kind == E_P || e->kind == E_CC ? -1 : nctl++;
        emit(&b, "%s{%s, %d, %d, %d, %d, %d}", i ? ", " : "", ic_code(kind), e->n[0], e->n[1], n ? n->id : -1,
             e->kind == E_S ? x->sp_of[i] : n ? x->react[n->id] : nli, x->src[i]);
    }
    emit(&b, "}");
    return str(&b);
}

/* The fields of the state that keep each waveguide's loop design: the
 * spec of the design in effect, and one prepare made, handed over by
 * install (WG_NSPEC and WG_NREC doubles each, see waveguide_state.c.tmpl). */
static const char *wg_fields(const Circuit *c) {
    if (!c->nwgs)
        return "";
    const char *f = format("    double c_wsp[%d];      /* waveguides: the spec of each loop's design */\n", wg_nspec * c->nwgs);
    if (wg_params(c))
        f = format("%s    double c_wmade[%d];    /* waveguides: designs prepare made, handed over by install */\n", f,
                   wg_nrec * c->nwgs);
    return f;
}

/* The class's design_size, prepare and install: a voice whose loop
 * designs depend on params has them. */
static const char *design_entries(const Circuit *c) {
    if (!wg_params(c))
        return "0, NULL, NULL";
    return "sizeof(double) * WG_NREC * N_WG, voice_prepare, voice_install";
}

/* One field of the state, if it has entries: C has no empty arrays, and a
 * voice keeps nothing it does not use. */
static void field(Buf *b, const char *type, const char *name, int n, const char *what) {
    if (n > 0)
        emit(b, "%s    %-26s /* %s */", b->len ? "\n" : "", format("%s %s[%d];", type, name, n), what);
}

/* A scalar field of the state, if the voice keeps it. */
static void scalar(Buf *b, bool keep, const char *decl, const char *what) {
    if (keep)
        emit(b, "%s    %-26s /* %s */", b->len ? "\n" : "", decl, what);
}

/* The fields of the state.  A waveguide's are there whenever it is, even
 * with no taps: the waveguide kernels name them all.  nd: rows of the
 * solve workspace, 0 for none in the state. */
static const char *state_fields(Ctx *x, int nd) {
    const Circuit *c = x->c;
    const char *r = format("%s_real", c->name);
    int nx = x_probes(c), nw = c->nwgs, nctl = 0;
    bool work = x->energy && x->nsrc;
    for (int i = 0; i < c->nelems; i++)
        nctl += x->src[i] >= 0 && c->elems[i].input < 0;
#define W1(n) (nw ? ((n) > 0 ? (n) : 1) : 0)
    Buf b = {0};
    field(&b, "double", "p", c->nparams, "param values");
    scalar(&b, c->nparams, "unsigned long long dirty;", "params changed since the last coefficient update");
    scalar(&b, true, "double fs;", "sample rate, Hz");
    field(&b, r, "c_R", x->w->nnodes, "port resistance of each tree node");
    field(&b, r, "c_k", x->nk, "adaptor coefficients");
    field(&b, r, "c_M", x->nM, "root adaptor matrix");
    field(&b, "double", "c_jQ", x->njq, "joint roots: the rows of their nonlinear edges, in double");
    field(&b, r, "c_e", nctl ? x->nsrc : 0, "control-rate source drives");
    field(&b, r, "s_a", x->nreact, "reactances: last incident wave");
    field(&b, r, "s_b", x->nreact, "reactances: last reflected wave");
    field(&b, "double", "s_x", nx, "displacement probes (double: an integral gathers rounding)");
    field(&b, r, "s_xv", nx, "displacement probes: last velocity");
    field(&b, r, "s_e", keeps_drive(x) ? x->nsrc : 0, "sources: the drive of the last sample");
    field(&b, r, "s_wi", work ? x->nsrc : 0, "sources: last current (V) or voltage (I)");
    scalar(&b, work, "double s_work;", "work done by the sources since reset");
    field(&b, r, "c_Rn", x->nnl, "nonlinear edges: adapted port resistance");
    field(&b, "double", "c_fk", any_fast(x) ? 6 * x->nnl : 0, "diode_fast: each diode's constants (fast_setup)");
    field(&b, r, "c_nl", 4 * x->nnl,
          "nonlinear edges: Is, n Vt (diode) or k, alpha, lambda, gap (contact)");
    field(&b, r, "s_nX", x->nnl, "contacts: x(n0) - x(n1), m");
    field(&b, r, "s_nv", x->nnl, "nonlinear edges: last voltage (velocity) across");
    field(&b, r, "s_nf", x->nnl,
          "contacts, nonlinear inductors: last current (force); capacitors: voltage of the charge");
    field(&b, "double", "s_wP", x->anysum ? x->nwv : 0, "strings idle contacts read: running sums of each line");
    field(&b, "double", "s_wA", x->anysum ? x->nwv : 0, "the same of the waves' sizes");
    field(&b, "double", "s_wPr", x->anysum ? 2 * nw : 0, "the running sums at the last position written");
    field(&b, "double", "s_wAr", x->anysum ? 2 * nw : 0, "the same of the sizes");
    scalar(&b, x->anysum, "int s_wPv;", "the running sums hold (no contact touched a string since they were made)");
    scalar(&b, x->anysum, "unsigned s_wPt;", "the line position where they were made");
    field(&b, "int", "s_ck", x->nidle ? x->nnl : 0, "idle contacts: frames left in the chunk of their travel");
    field(&b, "unsigned", "s_ce", x->nidle ? x->nnl : 0, "idle contacts: the line position the chunk ends before");
    field(&b, "double", "s_cS", x->nidle ? x->nnl : 0, "idle contacts: the sum of the incident wave over the chunk");
    field(&b, "double", "s_cE", x->nidle ? x->nnl : 0, "idle contacts: the incident wave at its last frame");
    field(&b, r, "c_pa", x->npwl, "piecewise-linear wave maps: a at the breakpoints");
    field(&b, r, "c_pb", x->npwl, "b at the breakpoints");
    field(&b, r, "c_ps", x->npwl, "slope db/da of each segment");
    field(&b, r, "s_dl", x->ndl, "transmission lines: the waves that entered each end");
    scalar(&b, x->nline || nw, "unsigned s_pos;", "delays: next write position");
    scalar(&b, x->flushes, "unsigned s_run;", "samples since the states were last flushed");
    field(&b, "unsigned long", "s_js", any_joint(x) ? 3 : 0, "joint solves, their Newton steps, those capped");
    field(&b, "unsigned", "c_D", x->nline, "transmission lines: delay in samples");
    field(&b, r, "s_wv", W1(x->nwv), "waveguides: right- and left-going lines");
    field(&b, "unsigned", "c_wN", W1(2 * nw), "waveguides: whole samples of each line");
    field(&b, "unsigned", "c_wJ", W1(nw), "waveguides: stages of the allpass lattice in use");
    field(&b, "unsigned", "c_wk", W1(x->nwt), "waveguide taps: samples from end a");
    field(&b, "int", "c_won", W1(x->nwt), "waveguide taps: on their string (a moving tap may leave it)");
    field(&b, "double", "c_wR", W1(nw), "waveguides: port resistance");
    field(&b, r, "c_wf", W1(x->nwc), "waveguides: loss b and a, radiation a, allpass lattice k and c");
    field(&b, "double", "c_ww", W1(2 * nw), "waveguides: storage weights of their filters");
    field(&b, "double", "c_werr", W1(nw), "waveguides: largest tuning error of each loop's design, cents");
    field(&b, r, "s_wf", W1(x->nwf), "waveguide filters: states");
    field(&b, r, "s_wfp", W1(x->nwf), "waveguide filters: states a sample earlier");
    field(&b, r, "s_wpre", W1(x->nsp), "waveguide ports: the wave that last arrived");
    field(&b, "double", "w_A", nd * nd, "solve workspace (control rate only)");
    field(&b, "double", "w_x", nd, "solve workspace: right-hand side");
    field(&b, "int", "w_piv", nd, "solve workspace: pivots");
#undef W1
    return str(&b);
}

/* ---- templates ---- */

/* The text of the hole that starts at h ("{{"), and its end in *end. */
static const char *hole_text(const char *h, const Hole *holes, int n, const char **end) {
    const char *e = strstr(h, "}}");
    if (!e)
        die("unterminated hole in template");
    int len = (int)(e - h - 2);
    const char *text = NULL;
    for (int i = 0; i < n; i++)
        if ((int)strlen(holes[i].name) == len && !strncmp(holes[i].name, h + 2, (size_t)len))
            text = holes[i].text;
    if (!text)
        die("template hole '%.*s' has no value", len, h + 2);
    *end = e + 2;
    return text;
}

/* Measured first and then written, so that a voice's whole text is
 * allocated once. */
const char *fill(const char *tmpl, const Hole *holes, int n) {
    Buf b = {0};
    for (int pass = 0; pass < 2; pass++) {
        size_t need = 0;
        for (const char *p = tmpl; *p;) {
            const char *h = strstr(p, "{{"), *e;
            size_t k = h ? (size_t)(h - p) : strlen(p);
            if (pass)
                buf_put(&b, p, k);
            need += k;
            if (!h)
                break;
            const char *text = hole_text(h, holes, n, &e);
            if (pass)
                buf_put(&b, text, strlen(text));
            need += strlen(text);
            p = e;
        }
        if (!pass)
            buf_reserve(&b, need);
    }
    return str(&b);
}

static int write_text(const char *path, const char *text) {
    FILE *f = fopen(path, "w");
    if (!f)
        return -1;
    size_t n = strlen(text);
    bool ok = fwrite(text, 1, n, f) == n;
    ok = (fclose(f) == 0) && ok;
    return ok ? 0 : -1;
}

/* Kirchhoff points of a piecewise-linear table: a curve's own, or a
 * diode's sampled evenly in v over +-nVt ln(1 + 1 A / Is), the voltage at
 * which it carries 1 A. */
static void pwl_points(Ctx *x, const Elem *e, int k) {
    const NlSpec *nl = e->nl;
    if (nl->kind == NL_CURVE) {
        x->pwl_n[k] = nl->npts;
        x->pwl_v[k] = nl->cv;
        x->pwl_i[k] = nl->ci;
        return;
    }
    if (expr_params(nl->Is) || expr_params(nl->n) || expr_params(nl->Vt))
        error_at(e->pos, "diode '%s': a piecewise-linear table is made at compile time, so Is, n and Vt must "
                 "not depend on params (use solver=fast, newton or omega)", e->name);
    double Is = expr_eval(nl->Is, NULL), nVt = expr_eval(nl->n, NULL) * expr_eval(nl->Vt, NULL);
    int n = x->opt->table;
    double vmax = nVt * log(1 + 1 / Is);
    x->pwl_n[k] = n;
    x->pwl_v[k] = arena_alloc(sizeof(double) * (size_t)n);
    x->pwl_i[k] = arena_alloc(sizeof(double) * (size_t)n);
    for (int j = 0; j < n; j++) {
        double v = -vmax + 2 * vmax * j / (n - 1);
        x->pwl_v[k][j] = v;
        x->pwl_i[k][j] = nl->pair ? 2 * Is * sinh(v / nVt) : Is * expm1(v / nVt);
    }
}

/* The highest rate a voice's delay lines and waveguides hold their
 * delays at: four times the netlist's rate or the rate it is compiled
 * for (--rate), and at least 192 kHz; a host running it faster gets
 * delays cut to what the lines hold, and tuning says so (INFINITY). */
static double line_rate(Ctx *x) {
    double top = x->c->rate > x->w->fs ? x->c->rate : x->w->fs;
    return 4 * top > 192000 ? 4 * top : 192000;
}

static void index_tree(Ctx *x) {
    const Wdf *w = x->w;
    const Circuit *c = x->c;
    x->react = arena_alloc(sizeof(int) * (size_t)(w->nnodes + 1));
    x->koff = arena_alloc(sizeof(int) * (size_t)(w->nnodes + 1));
    x->b = arena_alloc(sizeof(char *) * (size_t)(w->nnodes + 1));
    x->bpost = arena_alloc(sizeof(char *) * (size_t)(w->nnodes + 1));
    x->a = arena_alloc(sizeof(char *) * (size_t)(w->nnodes + 1));
    for (int i = 0; i < w->nnodes; i++) {
        const WNode *n = w->nodes[i];
        x->react[i] = -1;
        if (n->kind == W_LEAF && prims[c->elems[n->elem].kind].state)
            x->react[i] = x->nreact++;
        x->koff[i] = x->nk;
        if (n->kind != W_LEAF)
            x->nk += n->nchild;
    }
    x->nl_first = arena_alloc(sizeof(int) * (size_t)(w->nroots + 1));
    x->moff = arena_alloc(sizeof(int) * (size_t)(w->nroots + 1));
    x->mzero = arena_alloc(sizeof(bool *) * (size_t)(w->nroots + 1));
    for (int b = 0; b < w->nroots; b++) {
        x->nl_first[b] = x->nnl;
        x->nnl += w->roots[b].nnl;
        x->moff[b] = x->nM;
        x->nM += w->roots[b].nedge * w->roots[b].nedge;
    }
    x->rfn = arena_alloc(sizeof(char *) * (size_t)(w->nroots + 1));
    x->mnum = arena_alloc(sizeof(bool *) * (size_t)(w->nroots + 1));
    x->mval = arena_alloc(sizeof(double *) * (size_t)(w->nroots + 1));
    x->msym = arena_alloc(sizeof(Sym *) * (size_t)(w->nroots + 1));
    x->rsx = arena_alloc(sizeof(Sx *) * (size_t)(w->nroots + 1));
    for (int b = 0; b < w->nroots; b++) {
        /* the entries that vanish: exactly from the straight-line solve,
         * else as the root's matrix shows them at perturbed resistances */
        x->mzero[b] = arena_alloc(sizeof(bool) * (size_t)(w->roots[b].nedge * w->roots[b].nedge + 1));
        root_static(x, b);
        if (!x->rfn[b])
            x->mzero[b] = root_zeros(&w->roots[b]);
    }
    x->jq_off = arena_alloc(sizeof(int) * (size_t)(w->nroots + 1));
    for (int b = 0; b < w->nroots; b++) {
        x->jq_off[b] = -1;
        if (x->single && w->roots[b].joint) {
            x->jq_off[b] = x->njq;
            x->njq += w->roots[b].nnl * w->roots[b].nedge;
        }
    }
    x->nl_root = arena_alloc(sizeof(int) * (size_t)(x->nnl + 1));
    x->nl_edge = arena_alloc(sizeof(int) * (size_t)(x->nnl + 1));
    for (int b = 0; b < w->nroots; b++)
        for (int k = 0; k < w->roots[b].nnl; k++) {
            x->nl_root[x->nl_first[b] + k] = b;
            x->nl_edge[x->nl_first[b] + k] = w->roots[b].nport + k;
        }
    x->pwl_off = arena_alloc(sizeof(int) * (size_t)(x->nnl + 1));
    x->pwl_n = arena_alloc(sizeof(int) * (size_t)(x->nnl + 1));
    x->pwl_v = arena_alloc(sizeof(double *) * (size_t)(x->nnl + 1));
    x->pwl_i = arena_alloc(sizeof(double *) * (size_t)(x->nnl + 1));
    for (int k = 0; k < x->nnl; k++) {
        const Elem *e = nl_elem(x, k);
        if (e->nl->kind == NL_CONTACT || solver_of(x, k) != SOLVER_PWL)
            continue;
        pwl_points(x, e, k);
        x->pwl_off[k] = x->npwl;
        x->npwl += x->pwl_n[k];
    }
    /* delay lines: one buffer per end, holding the waves that entered it,
     * long enough for the delay at 192 kHz or four times the netlist's rate */
    x->line_of = arena_alloc(sizeof(int) * (size_t)c->nelems);
    x->dl_off = arena_alloc(sizeof(int) * (size_t)c->nelems);
    x->dl_size = arena_alloc(sizeof(int) * (size_t)(c->nelems + 1));
    for (int i = 0; i < c->nelems; i++) {
        const Elem *e = &c->elems[i];
        x->line_of[i] = -1;
        if (e->kind != E_W)
            continue;
        if (e->peer < i) {
            x->line_of[i] = x->line_of[e->peer];
        } else {
            double fmax = line_rate(x);
            int need = (int)ceil(e->td * fmax) + 2, size = 1;
            while (size < need)
                size *= 2;
            x->line_of[i] = x->nline;
            x->dl_size[x->nline++] = size;
        }
        x->dl_off[i] = x->ndl;
        x->ndl += x->dl_size[x->line_of[i]];
    }
    /* waveguides: two lines each, long enough for the lowest f0 at 192 kHz
     * or four times the netlist's rate */
    int nw = c->nwgs;
    x->wv_off = arena_alloc(sizeof(int) * (size_t)(nw + 1));
    x->wv_size = arena_alloc(sizeof(int) * (size_t)(nw + 1));
    x->wf_off = arena_alloc(sizeof(int) * (size_t)(nw + 1));
    x->wt_off = arena_alloc(sizeof(int) * (size_t)(nw + 1));
    x->wc_off = arena_alloc(sizeof(int) * (size_t)(nw + 1));
    for (int w = 0; w < nw; w++) {
        const Waveguide *g = &c->wgs[w];
        double fmax = line_rate(x);
        int need = (int)ceil(fmax / g->f0_min / 2) + 4, size = 4;
        while (size < need)
            size *= 2;
        x->wv_off[w] = x->nwv;
        x->wv_size[w] = size;
        x->nwv += 2 * size;
        x->wf_off[w] = x->nwf;
        x->nwf += 1 + g->nrad + g->M;
        x->wc_off[w] = x->nwc;
        x->nwc += 3 + 2 * g->M;
        x->wt_off[w] = x->nwt;
        x->nwt += g->ntaps;
    }
    x->sp_of = arena_alloc(sizeof(int) * (size_t)(c->nelems + 1));
    x->wtap_port = arena_alloc(sizeof(int) * (size_t)(2 * x->nwt + 2));
    for (int i = 0; i < c->nelems; i++) {
        const Elem *e = &c->elems[i];
        x->sp_of[i] = -1;
        if (e->kind != E_S)
            continue;
        x->sp_of[i] = x->nsp++;
        if (e->pt > 0 && e->pt <= c->wgs[e->wg].ntaps)
            x->wtap_port[2 * (x->wt_off[e->wg] + e->pt - 1) + e->side] = x->sp_of[i];
    }
    x->src = arena_alloc(sizeof(int) * (size_t)c->nelems);
    for (int i = 0; i < c->nelems; i++) {
        ElemKind k = c->elems[i].kind;
        x->nctl += k == E_CV || k == E_CI || k == E_OA || k == E_XF;
        x->ncc += k == E_CC;
    }
    for (int i = 0; i < c->nelems; i++)
        x->src[i] = c->elems[i].kind == E_V || c->elems[i].kind == E_I ? x->nsrc++ : -1;
}

/* ---- the voice's functions ---- */

/* Helpers a voice's code may call, each after those it calls: a voice
 * carries those its text names. */
static const struct {
    const char *name, *text;
} helper_tab[] = {
    {"UNUSED", "/* Marks a parameter the ABI passes that this voice has no use for. */\n"
               "#if defined(__GNUC__)\n#define UNUSED __attribute__((unused))\n#else\n#define UNUSED\n#endif\n"},
    {"clampd", "static double clampd(double x, double lo, double hi) { return x < lo ? lo : x > hi ? hi : x; }\n"},
    {"pos", "static double pos(double x) { return x > 1e-18 && x < 1e300 ? x : x >= 1e300 ? 1e300 : 1e-18; }\n"},
    {"potlin", "static double potlin(double x) { return clampd(x, 0, 1); }\n"},
    {"potlog", "static double potlog(double x) { return (pow(10, 2 * clampd(x, 0, 1)) - 1) / 99; }\n"},
    {"tapon", "/* 1 for a tap position on its string, else a conductance scale that takes\n"
              " * its ports out of their junction */\n"
              "static double tapon(double x) { return x > 0 && x < 1 ? 1 : 1e-9; }\n"},
    {"flush", "static real flush(real x) { return x > -FLUSH_BELOW && x < FLUSH_BELOW ? (real)0 : x; }\n"},
    {"flush_lane", "/* flush(x) in a lane whose run ends here (t is FLUSH_BELOW), x in the others\n"
                   " * (t is 0): one test without branches in every lane and every frame, so\n"
                   " * that the loop over the lanes is vectorised whole */\n"
                   "static real flush_lane(real t, real x) { return fabs(x) < t ? (real)0 : x; }\n"},
    {"port_window",
     "/* The waves a string's port reads at frames p to p + w - 1 (at positions\n"
     " * d behind the frame's): their sum, and the sum of their sizes in *mag.\n"
     " * A position past `last` is not written yet: the end its line starts\n"
     " * from will write there sg times the wave the other line brings it (od\n"
     " * behind).  Summed in four lanes, always in the same order. */\n"
     "static inline double port_window(const real *line, const real *other, unsigned m, unsigned d, unsigned od, double sg,\n"
     "                          unsigned p, unsigned last, unsigned w, double *mag) {\n"
     "    const unsigned q = p - d;\n"
     "    unsigned known = (int)(last - q) < 0 ? 0u : last - q + 1u;\n"
     "    if (known > w)\n        known = w;\n"
     "    double s = 0, a = 0;\n"
     "    for (int part = 0; part < 2; part++) {\n"
     "        const real *src = part ? other : line;\n"
     "        const double g = part ? sg : 1.0;\n"
     "        unsigned i = part ? q + known - od : q, n = part ? w - known : known;\n"
     "        while (n > 0) {\n"
     "            const unsigned at = i & m, k = n < m + 1u - at ? n : m + 1u - at;\n"
     "            const real *v = src + at, *const e = v + k;\n"
     "            double s0 = 0, s1 = 0, s2 = 0, s3 = 0, a0 = 0, a1 = 0, a2 = 0, a3 = 0;\n"
     "            for (; e - v >= 4; v += 4) {\n"
     "                const double v0 = (double)v[0], v1 = (double)v[1], v2 = (double)v[2], v3 = (double)v[3];\n"
     "                s0 += v0, s1 += v1, s2 += v2, s3 += v3;\n"
     "                a0 += fabs(v0), a1 += fabs(v1), a2 += fabs(v2), a3 += fabs(v3);\n"
     "            }\n"
     "            for (; v < e; v++)\n"
     "                s0 += (double)*v, a0 += fabs((double)*v);\n"
     "            s += g * ((s0 + s1) + (s2 + s3));\n"
     "            a += (a0 + a1) + (a2 + a3);\n"
     "            i += k, n -= k;\n"
     "        }\n"
     "    }\n"
     "    *mag = a;\n"
     "    return s;\n"
     "}\n"},
    {"port_sum", "/* port_window's sums from a line's running sums of waves P and of sizes A\n"
                 " * (and the other line's, PL and AL): eight reads. */\n"
                 "static inline double port_sum(const double *P, const double *A, const double *PL, const double *AL, unsigned m,\n"
                 "                              unsigned d, unsigned od, double sg, unsigned p, unsigned last, unsigned w,\n"
                 "                              double *mag) {\n"
                 "    const unsigned q = (p - d - 1u) & m, e = (p - d + w - 1u) & m;\n"
                 "    if ((int)(last - (p - d + w - 1u)) >= 0) {\n"
                 "        *mag = A[e] - A[q];\n        return P[e] - P[q];\n    }\n"
                 "    /* the last position written, and the other line's positions that end reflects */\n"
                 "    const unsigned f = ((int)(last - (p - d)) >= 0 ? last : p - d - 1u) & m, g = (f - od) & m, h = (e - od) & m;\n"
                 "    *mag = A[f] - A[q] + (AL[h] - AL[g]);\n"
                 "    return P[f] - P[q] + sg * (PL[h] - PL[g]);\n"
                 "}\n"},
    {"ring_sums", "/* The running sums of a line's waves and of their sizes, made anew from\n"
                  " * its oldest position (pos) to its newest; *p and *a the last. */\n"
                  "static void ring_sums(const real *line, double *P, double *A, unsigned m, unsigned pos, double *p, double *a) {\n"
                  "    double s = 0, z = 0;\n"
                  "    for (unsigned i = 0; i <= m; i++) {\n"
                  "        const double v = (double)line[(pos + i) & m];\n"
                  "        s += v, z += fabs(v);\n"
                  "        P[(pos + i) & m] = s, A[(pos + i) & m] = z;\n"
                  "    }\n"
                  "    *p = s, *a = z;\n"
                  "}\n"},
    {"port_wave", "/* The wave a string's port reads at frame t (port_window's terms). */\n"
                  "static inline double port_wave(const real *line, const real *other, unsigned m, unsigned d, unsigned od,\n"
                  "                               double sg, unsigned t, unsigned last) {\n"
                  "    const unsigned q = t - d;\n"
                  "    return (int)(last - q) >= 0 ? (double)line[q & m] : sg * (double)other[(q - od) & m];\n"
                  "}\n"},
    {"wrapfree", "/* line + q, for a loop that reads or writes position q of a line of `size`\n"
                 " * from frame n on; *se becomes the frame before which it stays on the line */\n"
                 "static real *wrapfree(real *line, unsigned q, unsigned size, int n, int *se) {\n"
                 "    if ((unsigned)(*se - n) > size - q)\n        *se = n + (int)(size - q);\n    return line + q;\n}\n"},
    {"line_err", "/* e, or if larger the error in cents of a delay of t samples held as d\n"
                 " * (update's, rounded to whole samples from 1 to cap); INFINITY where it\n"
                 " * cannot be held: shorter than half a sample, or longer than its line */\n"
                 "static double line_err(double e, double t, unsigned d, unsigned cap) {\n"
                 "    const double c = t < 0.5 || t >= cap + 0.5 ? (double)INFINITY : 1200 * fabs(log2(d / t));\n"
                 "    return c > e ? c : e;\n}\n"},
    {"lu_factor", tmpl_lu},
    {"retune", tmpl_retune},
    {"ctl_stamp", tmpl_ctl_stamp},
};

/* True for a helper that is one static function on one line. */
static bool one_line(const char *t) {
    return t && !strncmp(t, "static ", 7) && strchr(t, '\n') == t + strlen(t) - 1;
}

/* The helpers that `text` (the voice without them) and `wg` (the
 * waveguide kernels) name, in order.  clampd is named by the waveguides'
 * prepare, which a voice has only with params, and then set_param names
 * it too. */
static const char *helpers(const char *text, const char *wg, bool single) {
    int n = (int)(sizeof helper_tab / sizeof helper_tab[0]);
    bool keep[sizeof helper_tab / sizeof helper_tab[0]] = {0};
    Names used = {0}, wgn = {0}, all = {0};
    for (int k = 0; k < n; k++)
        names_put(&all, helper_tab[k].name, strlen(helper_tab[k].name));
    names_scan_in(&used, text, &all);
    names_scan_in(&wgn, wg, &all);
    for (int k = n - 1; k >= 0; k--) {
        const char *h = helper_tab[k].name;
        keep[k] = names_has(&used, h) || (strcmp(h, "clampd") && names_has(&wgn, h));
        if (keep[k])
            names_scan_in(&used, helper_tab[k].text, &all);
    }
    Buf b = {0};
    const char *last = NULL; /* one-line definitions go together, others apart */
    for (int k = 0; k < n; k++)
        if (keep[k]) {
            const char *t = helper_tab[k].text;
            emit(&b, "%s%s", b.len && !(one_line(last) && one_line(t)) ? "\n" : "",
                 single && !strcmp(helper_tab[k].name, "flush_lane") ? replace_all(helper_tab[k].text, "fabs(", "fabsf(")
                                                                     : helper_tab[k].text);
            last = t;
        }
    return str(&b);
}

/* The statements of the sample loop, in order. */
static void emit_sample(Ctx *x) {
    x->own = -1, x->phase = 0;
    if (x->nidle) { /* chunks start only where every idle contact is open */
        chunk_texts(x);
        x->phase = 'k';
        if (x->skip)
            put(x, NULL, "        t_full = 1, t_left = 0, t_wait = 0;\n");
        put(x, NULL, "        if (%s) { /* the idle contacts are open */\n%s        }\n", all_open(x), chunk_plans(x));
        x->phase = 0;
    }
    for (int i = 0; i < x->c->ninputs; i++)
        put(x, format("t_in%d", i), "        const real t_in%d = (real)in%d[n];\n", i, i);
    emit_forward(x);
    for (int b = 0; b < x->w->nroots; b++)
        emit_root(x, b);
    if (x->nidle) {
        x->own = -1, x->phase = 'k';
        put(x, NULL, "        if (!(%s)) { /* a contact meets: every chunk ends with this frame */\n"
                     "            const unsigned t_q = t_pos + 1u;\n%s        }\n", idle_join(x, "t_open%d", " && "),
            chunk_cuts(x));
    }
    emit_backward(x);
    x->own = -1, x->phase = 0;
    emit_outputs(x);
    emit_work(x);
    for (int w = 0; x->anysum && w < x->c->nwgs; w++)
        for (int d = 0; x->wg_sum[w] && d < 2; d++) {
            int off = x->wv_off[w] + d * x->wv_size[w], m = x->wv_size[w] - 1;
            put(x, NULL, "        { /* %s: the running sums of its %s line */\n"
                         "            const double t_w = (double)s_wv[%d + (t_pos & %du)];\n"
                         "            s_wPr%d += t_w, s_wAr%d += fabs(t_w);\n"
                         "            s_wP[%d + (t_pos & %du)] = s_wPr%d, s_wA[%d + (t_pos & %du)] = s_wAr%d;\n"
                         "        }\n", x->c->wgs[w].name, d ? "left-going" : "right-going", off, m,
                2 * w + d, 2 * w + d, off, m, 2 * w + d, off, m, 2 * w + d);
        }
    if (x->nline || x->c->nwgs)
        put(x, NULL, "        t_pos++;\n");
    x->phase = 'k';
    for (int b = 0; b < x->w->nroots; b++)
        if (x->idle[b]) {
            int k = x->nl_first[b];
            put(x, NULL, "        if (s_ck%d > 0 && --s_ck%d == 0) {\n%s        }\n", k, k, deeper(x->ck_end[k], 3));
        }
    x->phase = 0;
}

/* A parameter list with the parameters that none of the texts `parts`
 * names marked UNUSED: each of `names` is the name of the declaration in
 * `decls` at the same place. */
static const char *params_of(const char *const *parts, int nparts, int n, const char *const *decls,
                             const char *const *names) {
    Buf b = {0};
    for (int k = 0; k < n; k++)
        emit(&b, "%s%s%s", k ? ", " : "", decls[k], uses_any(parts, nparts, names[k]) ? "" : " UNUSED");
    return str(&b);
}

/* A function body, with `local` (the state behind the void pointer)
 * first if the rest names `st`. */
static const char *with_st(const char *local, const char *body) {
    return uses(body, "st") ? format("%s%s", local, body) : body;
}

/* What settle stores from its solve: the waves of each reactance and,
 * with the accounting, the current or voltage of each source; then
 * nonlinear edges and probes from the node values (`probes`). */
static const char *settle_store(Ctx *x, int nicv, const char *probes) {
    Buf b = {0};
    bool work = x->energy && x->nsrc;
    if (x->nreact || work) {
        emit(&b, "    m = N_ICN - %d;\n"
                 "    for (int k = 0; k < ne; k++) {\n"
                 "        const short *e = ic_elem[k];\n"
                 "        int p = e[1] - 1, q = e[2] - 1;\n"
                 "        double v = ok ? (p >= 0 ? x[p] : 0) - (q >= 0 ? x[q] : 0) : 0, i = 0;\n"
                 "        double R = e[3] >= 0 ? st->c_R[e[3]] : 0;\n"
                 "        if (e[0] == IC_CAP || e[0] == IC_V%s)\n"
                 "            i = ok ? x[m++] : 0;\n"
                 "        switch (e[0]) {\n"
                 "        case IC_CAP: v = react[e[4]]; break;\n"
                 "        case IC_IND: i = react[e[4]]; break;\n", nicv, x->nctl ? " || e[0] == IC_CV || e[0] == IC_OA || e[0] == IC_XF" : "");
        if (work)
            emit(&b, "        case IC_V: st->s_wi[e[5]] = (real)i; break;\n"
                     "        case IC_RV: st->s_wi[e[5]] = (real)((v - (double)st->s_e[e[5]]) / R); break;\n"
                     "        case IC_I: case IC_RI: st->s_wi[e[5]] = (real)v; break;\n");
        emit(&b, "        }\n");
        if (x->nreact)
            emit(&b, "        if (e[0] == IC_CAP || e[0] == IC_IND) {\n"
                     "            st->s_a[e[4]] = (real)(v + R * i);\n"
                     "            st->s_b[e[4]] = (real)(v - R * i);\n"
                     "        }\n");
        emit(&b, "    }\n");
    }
    if (*probes)
        emit(&b, "    if (ok) {\n%s    }\n", probes);
    return str(&b);
}

/* The clearing of every signal state reset starts from. */
static const char *clears(Ctx *x) {
    Buf b = {0};
    const char *arr[] = {x->nreact ? "s_a" : NULL, x->nreact ? "s_b" : NULL, x_probes(x->c) ? "s_x" : NULL,
                         x_probes(x->c) ? "s_xv" : NULL, keeps_drive(x) ? "s_e" : NULL,
                         x->energy && x->nsrc ? "s_wi" : NULL, x->ndl ? "s_dl" : NULL};
    for (int k = 0; k < (int)(sizeof arr / sizeof arr[0]); k++)
        if (arr[k])
            emit(&b, "    memset(st->%s, 0, sizeof st->%s);\n", arr[k], arr[k]);
    if (x->nidle)
        emit(&b, "    memset(st->s_ck, 0, sizeof st->s_ck);\n");
    if (x->anysum)
        emit(&b, "    st->s_wPv = 0;\n");
    if (x->nline || x->c->nwgs)
        emit(&b, "    st->s_pos = 0;\n");
    if (x->flushes)
        emit(&b, "    st->s_run = 0;\n");
    if (any_joint(x))
        emit(&b, "    memset(st->s_js, 0, sizeof st->s_js);\n");
    if (x->energy && x->nsrc)
        emit(&b, "    st->s_work = 0;\n");
    return str(&b);
}

/* The holes of a voice's templates, filled one part after another. */
typedef struct Holes {
    Hole h[96];
    int n;
} Holes;

static void set(Holes *t, const char *name, const char *text) {
    if (t->n == (int)(sizeof t->h / sizeof t->h[0]))
        die("too many template holes");
    t->h[t->n++] = (Hole){name, text};
}

static const char *fill_with(const char *tmpl, const Holes *t) { return fill(tmpl, t->h, t->n); }

/* update: its parameters (the params changed `d`, `full`, as its guards
 * name them), its locals, the call in init and the call when params
 * changed (returned: nothing without params). */
static const char *update_holes(Ctx *x, Holes *t, const char *body) {
    const Circuit *c = x->c;
    bool ud = uses(body, "d"), uf = uses(body, "full");
    Buf head = {0};
    if (uses(body, "p"))
        emit(&head, "    const double *p = st->p;\n");
    if (uses(body, "T"))
        emit(&head, "    const double T = 1.0 / st->fs;\n");
    if (c->nparams) /* the params changed since the last call, taken */
        emit(&head, "%s    st->dirty = 0;\n", ud ? "    const unsigned long long d = st->dirty;\n" : "");
    set(t, "update_args", format("state *st%s", uf ? ", int full" : ""));
    set(t, "update", format("%s%s%s", x->nidle ? "    voice_cut(st);\n" : "", str(&head), body));
    set(t, "init", format("%s    update(st%s);\n",
                          c->nparams ? "    for (int i = 0; i < N_PARAMS; i++)\n        st->p[i] = param_desc[i].def;\n"
                                     : "",
                          uf ? ", 1" : ""));
    set(t, "param_fns", c->nparams ? tmpl_params
                                   : "/* The voice has no params: every id is unknown. */\n"
                                     "static int voice_set_param(void *vst UNUSED, int id UNUSED, double value UNUSED) { return -1; }\n\n"
                                     "static double voice_get_param(const void *vst UNUSED, int id UNUSED) { return 0; }\n");
    if (!c->nparams)
        return "";
    return format("    if (st->dirty)\n        update(st%s);\n", uf ? ", 0" : "");
}

/* True if text indexes `name` (c_R or c_k) other than by a number, as the
 * general root solve's tables do. */
static bool indexed(const char *text, const char *name) {
    size_t len = strlen(name);
    for (const char *q = text; *q; q++) /* by hand: one pass, as strstr from each match need not be */
        if (*q == *name && !strncmp(q, name, len) && q[len] == '[' && !(q[len + 1] >= '0' && q[len + 1] <= '9'))
            return true;
    return false;
}

/* update()'s text: its statements in order, those gone (if any) left out. */
static const char *upd_text(const Ctx *x, const bool *gone) {
    Buf b = {0};
    size_t need = 0;
    for (int i = 0; i < x->nupd; i++)
        need += !gone || !gone[i] ? strlen(x->upd[i].text) : 0;
    buf_reserve(&b, need); /* allocated once */
    for (int i = 0; i < x->nupd; i++)
        if (!gone || !gone[i])
            buf_put(&b, x->upd[i].text, strlen(x->upd[i].text));
    return str(&b);
}

/* The slots of c_R (as -1 - i) and c_k (as i) that C text names by
 * number, in order, into *out (arena); their count. */
static int slot_refs(const char *text, int **out) {
    int n = 0, cap = 0, *v = NULL;
    for (const char *q = text; *q; q++) {
        if (q[0] != 'c' || q[1] != '_' || (q > text && ident_char(q[-1])) || (q[2] != 'R' && q[2] != 'k') ||
            q[3] != '[' || !(q[4] >= '0' && q[4] <= '9'))
            continue;
        int i = 0;
        const char *d = q + 4;
        while (*d >= '0' && *d <= '9' && i < 100000000)
            i = 10 * i + (*d++ - '0');
        if (*d != ']')
            continue;
        v = grow(v, n, &cap, sizeof(int));
        v[n++] = q[2] == 'R' ? -1 - i : i;
    }
    *out = v;
    return n;
}

/* Marks in gone[] the statements of update() that compute what nothing
 * reads: a coefficient that neither `rest` (the voice without update's
 * body) nor a kept statement of update reads, to a fixed point, and then
 * every adaptor left storing nothing.  Coefficients that some code reads
 * by computed index (the general root solve's tables) all stay.  Each
 * slot's readers are counted once, and a statement is looked at again
 * only when a slot it stores loses a reader, so the work is linear in
 * the text. */
static void prune_update(const Ctx *x, const char *rest, bool *gone) {
    bool keepR = indexed(rest, "c_R"), keepK = indexed(rest, "c_k");
    const Upd *u = x->upd;
    int n = x->nupd, nb = 0, nR = x->w->nnodes, nK = x->nk;
    int *cnt = (int *)arena_alloc(sizeof(int) * (size_t)(nR + nK + 1)) + nR; /* c_R[i] at cnt[-1 - i], c_k[i] at cnt[i] */
    int *by = (int *)arena_alloc(sizeof(int) * (size_t)(nR + nK + 1)) + nR; /* the statement that stores a slot, or -1 */
    int **refs = arena_alloc(sizeof(int *) * (size_t)(n + 1)), *nref = arena_alloc(sizeof(int) * (size_t)(n + 1));
    int *slot = arena_alloc(sizeof(int) * (size_t)(n + 1)), *work = NULL, cap = 0;
    for (int i = -nR; i < nK; i++)
        by[i] = -1;
    int *r, nr = slot_refs(rest, &r);
    for (int k = 0; k < nr; k++)
        if (r[k] >= -nR && r[k] < nK)
            cnt[r[k]]++;
    int top = 0;
    for (int i = 0; i < n; i++) {
        nref[i] = slot_refs(u[i].text, &refs[i]);
        for (int k = 0; k < nref[i]; k++)
            if (refs[i][k] >= -nR && refs[i][k] < nK)
                cnt[refs[i][k]]++;
        int j = -1 - nR;
        if (u[i].store && sscanf(u[i].store + 4, "%d", &j) == 1)
            j = u[i].store[2] == 'R' ? -1 - j : j;
        slot[i] = j >= -nR && j < nK && !(j < 0 ? keepR : keepK) ? j : -1 - nR;
        if (slot[i] >= -nR) {
            by[slot[i]] = i;
            work = grow(work, top, &cap, sizeof(int));
            work[top++] = i;
        }
    }
    while (top > 0) {
        int i = work[--top], own = 0;
        if (gone[i])
            continue;
        for (int k = 0; k < nref[i]; k++)
            own += refs[i][k] == slot[i];
        if (cnt[slot[i]] > own) /* read by the rest or by another kept statement */
            continue;
        gone[i] = true;
        for (int k = 0; k < nref[i]; k++) {
            int j = refs[i][k];
            if (j < -nR || j >= nK)
                continue;
            cnt[j]--;
            if (by[j] >= 0 && by[j] != i && !gone[by[j]]) {
                work = grow(work, top, &cap, sizeof(int));
                work[top++] = by[j];
            }
        }
    }
    for (int i = 0; i < n; i++)
        nb = u[i].block >= nb ? u[i].block + 1 : nb;
    bool *stores = arena_alloc(sizeof(bool) * (size_t)(nb + 1));
    for (int i = 0; i < n; i++) /* an adaptor that stores nothing now goes whole */
        if (u[i].block >= 0 && u[i].store && !gone[i])
            stores[u[i].block] = true;
    for (int i = 0; i < n; i++)
        gone[i] |= u[i].block >= 0 && !stores[u[i].block];
}

/* One identifier token of C text at s (s not inside another): its end. */
static const char *ident_end(const char *s) {
    while (ident_char(*s))
        s++;
    return s;
}

/* Renumbers the slots of a coefficient array NAME[N] that C text names
 * only as NAME[digits]: map[i] is slot i's new index, or -1 if unused.
 * Hoisted copies named NAME<digits> follow the same map. */
static const char *renumber(const char *text, const char *name, const int *map, int n, bool rename) {
    Buf b = {0};
    size_t nl = strlen(name);
    buf_reserve(&b, strlen(text)); /* smaller numbers: the text does not grow */
    const char *kept = text; /* text from here to s is copied as it is */
    for (const char *s = text; *s;) {
        if (!ident_char(*s)) {
            s++;
            continue;
        }
        const char *e = ident_end(s);
        if ((size_t)(e - s) >= nl && !strncmp(s, name, nl)) {
            const char *d = s + nl;
            int i = 0;
            bool digits = d < e;
            for (const char *q = d; q < e; q++)
                digits &= *q >= '0' && *q <= '9';
            if (d == e && *e == '[') { /* NAME[i] */
                i = atoi(e + 1);
                const char *r = e + 1;
                while (*r >= '0' && *r <= '9')
                    r++;
                buf_put(&b, kept, (size_t)(s - kept));
                emit(&b, "%s[%d", name, i < n && map[i] >= 0 ? map[i] : i);
                s = kept = r;
                continue;
            }
            if (rename && digits && (i = atoi(d)) < n && map[i] >= 0) { /* NAME<i>: a hoisted copy */
                buf_put(&b, kept, (size_t)(s - kept));
                emit(&b, "%s%d", name, map[i]);
                s = kept = e;
                continue;
            }
        }
        s = e;
    }
    buf_put(&b, kept, strlen(kept));
    return str(&b);
}

/* Coefficient arrays (c_*) that the voice names only by constant index
 * keep just the slots it names, renumbered in order: pruning leaves holes
 * (a coefficient nothing reads, a root matrix folded into constants) that
 * would otherwise take room in every instance.  *text and *fields (lines
 * of state_fields) are rewritten together; an array named any other way
 * (by a computed index, a pointer, sizeof) is left whole. */
static void dense_slots(const char **text, const char **fields) {
    Buf out = {0};
    for (const char *q = *fields; *q;) {
        const char *e = strchr(q, '\n');
        size_t len = e ? (size_t)(e - q) + 1 : strlen(q);
        const char *l = format("%.*s", (int)len, q);
        q += len;
        char type[128], name[64];
        int n = 0;
        const char *what = strstr(l, "/* ");
        if (sscanf(l, " %127s %63[A-Za-z0-9_][%d];", type, name, &n) != 3 || strncmp(name, "c_", 2) || !what ||
            n <= 0) {
            emit(&out, "%s", l);
            continue;
        }
        bool *used = arena_alloc(sizeof(bool) * (size_t)n), plain = true, hoisted = true;
        size_t nl = strlen(name);
        Names copies = {0}, copying = {0}; /* hoisted copies, and those that copy their own slot */
        for (const char *s = *text; *s && plain;) {
            if (!ident_char(*s) || (s > *text && ident_char(s[-1]))) {
                s++;
                continue;
            }
            const char *t = ident_end(s);
            if ((size_t)(t - s) == nl && !strncmp(s, name, nl)) {
                char *r = NULL;
                long i = *t == '[' && t[1] >= '0' && t[1] <= '9' ? strtol(t + 1, &r, 10) : -1;
                plain = i >= 0 && i < n && *r == ']';
                if (plain)
                    used[i] = true;
            } else if ((size_t)(t - s) > nl && !strncmp(s, name, nl) && s[nl] >= '0' && s[nl] <= '9') {
                /* a hoisted copy (NAME<i> = st->NAME[i], or a lane's NAME<i>[l]) */
                size_t len = (size_t)(t - s);
                names_put(&copies, s, len);
                const char *v = !strncmp(t, " = st->", 7) ? t + 7 : !strncmp(t, "[l] = st->", 10) ? t + 10 : NULL;
                if (v && !strncmp(v, name, nl) && v[nl] == '[' && !strncmp(v + nl + 1, s + nl, len - nl) &&
                    v[nl + 1 + len - nl] == ']')
                    names_put(&copying, s, len);
            }
            s = t;
        }
        for (size_t k = 0; k < copies.cap; k++) /* a copy keeps its slot's number only if that is what it copies */
            hoisted &= !copies.key[k] || names_has_n(&copying, copies.key[k], copies.len[k]);
        int *map = arena_alloc(sizeof(int) * (size_t)n), m = 0;
        for (int i = 0; i < n; i++)
            map[i] = used[i] ? m++ : -1;
        if (!plain || m == n || m == 0) {
            emit(&out, "%s", l);
            continue;
        }
        *text = renumber(*text, name, map, n, hoisted);
        emit(&out, "    %-26s %s", format("%s %s[%d];", type, name, m), what);
    }
    *fields = str(&out);
}

/* The state's fields (lines of state_fields) that the voice's text names:
 * a field nothing reads or writes (a root matrix folded into constants,
 * say) takes no room. */
static const char *used_fields(const char *fields, const char *text) {
    Buf b = {0};
    Names want = {0}, named = {0};
    Vec lines = {0}, names = {0}; /* each field line and its name (NULL: none) */
    for (const char *q = fields; *q;) {
        const char *e = strchr(q, '\n');
        size_t len = e ? (size_t)(e - q) + 1 : strlen(q);
        const char *l = format("%.*s", (int)len, q), *name = NULL;
        q += len;
        for (const char *r = l; *r && *r != '/'; r++) /* the identifier before '[' or ';' */
            if (ident_char(*r) && (r == l || !ident_char(r[-1]))) {
                const char *t = r;
                while (ident_char(*t))
                    t++;
                if (*t == '[' || *t == ';')
                    name = format("%.*s", (int)(t - r), r);
            }
        vec_push(&lines, (void *)l);
        vec_push(&names, (void *)name);
        if (name)
            names_put(&want, name, strlen(name));
    }
    names_scan_in(&named, text, &want);
    for (int i = 0; i < lines.len; i++)
        if (!names.data[i] || names_has(&named, names.data[i]))
            emit(&b, "%s", (const char *)lines.data[i]);
    return str(&b);
}

/* ---- lanes: process for many instances at once ---- */

/* Every identifier of C text that `lane` holds becomes t_ln.NAME[l], lane
 * l's copy; members (after -> or .), comments and literals are left
 * alone. */
static const char *in_lanes(const char *s, const Names *lane) {
    Buf b = {0};
    while (*s) {
        if (s[0] == '/' && s[1] == '*') {
            const char *e = comment_end(s);
            emit(&b, "%.*s", (int)(e - s), s);
            s = e;
        } else if (*s == '"' || *s == '\'') {
            const char *p = s;
            char q = *p++;
            while (*p && *p != q)
                p += p[0] == '\\' && p[1] ? 2 : 1;
            p += *p != 0;
            emit(&b, "%.*s", (int)(p - s), s);
            s = p;
        } else if (ident_char(*s) && !(*s >= '0' && *s <= '9')) {
            const char *p = s;
            while (ident_char(*p))
                p++;
            const char *q = b.len ? str(&b) + b.len : NULL; /* what precedes it */
            bool member = q && ((q[-1] == '.') || (b.len >= 2 && q[-2] == '-' && q[-1] == '>'));
            size_t slot;
            bool hit = !member && names_find(lane, s, (size_t)(p - s), &slot);
            emit(&b, hit ? "t_ln.%.*s[l]" : "%.*s", (int)(p - s), s);
            s = p;
        } else if (*s >= '0' && *s <= '9') { /* a number, with its suffixes and exponent */
            const char *p = s;
            while (ident_char(*p) || *p == '.' || ((*p == '+' || *p == '-') && (p[-1] == 'e' || p[-1] == 'E')))
                p++;
            emit(&b, "%.*s", (int)(p - s), s);
            s = p;
        } else
            emit(&b, "%c", *s++);
    }
    return str(&b);
}

/* A local's declaration `TYPE NAME = VALUE;` split into the type of its
 * lanes' copies (its top-level const dropped: they are filled after they
 * are declared) and its value; false for any other form. */
static bool split_decl(const char *decl, const char *name, const char **type, const char **value) {
    const char *p = decl;
    while (*p == ' ')
        p++;
    const char *eq = strstr(p, " = "), *end = strrchr(p, ';');
    size_t nl = strlen(name);
    if (!eq || !end || end < eq || strcmp(end, ";\n") || (size_t)(eq - p) <= nl ||
        strncmp(eq - nl, name, nl) || ident_char(eq[-(long)nl - 1]) || strchr(eq + 3, ';') != end)
        return false;
    char *t = format("%.*s", (int)(eq - nl - p), p);
    size_t n = strlen(t);
    while (n && t[n - 1] == ' ')
        t[--n] = 0;
    if (n > 6 && !strcmp(t + n - 6, "*const"))
        t[n - 5] = 0; /* "T *const" -> "T *" */
    else if (!strchr(t, '*') && !strncmp(t, "const ", 6))
        t += 6;
    *type = t;
    *value = format("%.*s", (int)(end - eq - 3), eq + 3);
    return true;
}

/* A line of the sample loop's top level (eight spaces in) that declares:
 * `[const ]TYPE NAME = VALUE;` or `TYPE NAME;` (a comment may follow),
 * TYPE one of real, double, int and unsigned.  Returns 1 with *type,
 * *name and *rest (what follows NAME) set; 2 for a declaration of
 * another form (arrays, several names); 0 for a line that declares
 * nothing. */
static int top_decl(const char *line, const char **type, const char **name, const char **rest) {
    static const char *const types[] = {"real", "double", "int", "unsigned"};
    if (strncmp(line, "        ", 8) || line[8] == ' ')
        return 0;
    const char *p = line + 8;
    if (!strncmp(p, "const ", 6))
        p += 6;
    for (int i = 0; i < 4; i++) {
        size_t n = strlen(types[i]);
        if (strncmp(p, types[i], n) || p[n] != ' ')
            continue;
        const char *q = p + n + 1, *e = q;
        while (ident_char(*e))
            e++;
        if (e == q || (*q >= '0' && *q <= '9') || (strncmp(e, " = ", 3) && *e != ';'))
            return 2;
        *type = types[i];
        *name = format("%.*s", (int)(e - q), q);
        *rest = e;
        return 1;
    }
    return 0;
}

/* The arguments of the call to `fn` on the line of text that holds it,
 * split at their commas, into args (at most max); their count, or -1. */
static int call_args(const char *text, const char *fn, const char **args, int max) {
    const char *p = strstr(text, fn);
    if (!p)
        return -1;
    p += strlen(fn);
    int n = 0, depth = 0;
    const char *a = p;
    for (; *p && *p != '\n'; p++) {
        if (*p == '(')
            depth++;
        else if ((*p == ',' && depth == 0) || (*p == ')' && depth-- == 0)) {
            if (n == max)
                return -1;
            while (*a == ' ')
                a++;
            args[n++] = format("%.*s", (int)(p - a), a);
            a = p + 1;
            if (*p == ')')
                return n;
        }
    }
    return -1;
}

/* One lane member of process_batch's t_ln: a local, an input sample, a
 * temporary that one loop over the lanes leaves to a later one, an output
 * sample, an output's buffer or a solve's flag. */
typedef struct LaneVar {
    const char *type, *name;
    bool loaded; /* filled from the state before the samples (lanes past nl copy the last instance's) */
    bool out;    /* an output's pointer */
} LaneVar;

/* process_batch: n instances of the voice in lanes of WDV_LANES.  Each
 * of the voice's locals becomes an array of one copy per lane (t_ln,
 * a structure of arrays), loaded from each instance's state.  Per frame,
 * the lanes' inputs are gathered; the sample loop's statements run as
 * loops over the lanes, one after the other, with plain arithmetic on
 * arrays that a compiler vectorises; the outputs are scattered; the
 * lanes whose run of FLUSH_RUN samples ends there are flushed.  A diode
 * that diode_fast solves ends one such loop: fast_lane answers every
 * lane from the tables, and the lanes that need more (past the tables,
 * a tighter tol) are answered again by diode_fast before the next loop.
 * Temporaries that a later loop uses become lane arrays too.  Each lane
 * does process's arithmetic in process's order, so the lanes' outputs
 * are bit for bit n process calls'.  A hammer's idle loop is left out
 * (its skip is exact).  A voice with delay lines or strings, or whose
 * locals or temporaries do not all take the plain forms, is batched by
 * calling process for each instance: its lines are a working set of
 * their own. */
static const char *batch_text(Ctx *x, const char *dirty) {
    /* gcc (8 and later) unrolls a short loop over the lanes completely,
     * and then vectorises the frame's flush_lane selects lane by lane or
     * not at all: kept a loop, it is vectorised whole.  clang, too, unrolls
     * it and then leaves it mostly scalar; kept a loop, it vectorises it
     * once told that no lane touches another's (each iteration reads and
     * writes element l of the lane arrays only) and once the inputs are
     * read in it rather than in a loop of their own, as gcc prefers */
    static const char *const lane_loop =
        "#if defined(__GNUC__) && !defined(__clang__) && __GNUC__ >= 8\n"
        "#define LANE_LOOP _Pragma(\"GCC unroll 1\")\n%s"
        "#else\n#define LANE_LOOP\n#endif\n\n";
    /* clang's, left out for a loop that calls a solver, which clang cannot
     * vectorise (and would say so) */
    static const char *const lane_clang =
        "#elif defined(__clang__)\n"
        "#define LANE_LOOP _Pragma(\"clang loop unroll(disable) vectorize(assume_safety)\")\n";
    static const char *const head =
        "/* process_batch's lanes: the instances whose samples are computed side by side */\n"
        "#define WDV_LANES 8\n\n"
        "/* Renders nframes for n instances at once (see wdvoice.h): states[l],\n"
        " * in[l][k][i] and out[l][k][i] are instance l's. */\n"
        "static void voice_process_batch(void *const *states, int n, const double *const *const *ins%s,\n"
        "                                double *const *const *outs%s, int nframes) {\n";
    const char *fallback =
        format("%s    for (int l = 0; l < n; l++)\n        voice_process(states[l], ins[l], outs[l], nframes);\n}\n",
               format(head, "", ""));
    if (x->nloc == 0 || x->nline || x->c->nwgs)
        return fallback;
    Names live = {0};
    bool *skeep = live_keep(x->stmt, x->nstmt, &live);
    bool *keep = kept_locals(x, &live);
    Names lane = {0};
    size_t nlines = 0; /* at most a lane member per line of the statements, and two per diode */
    for (int i = 0; i < x->nstmt; i++)
        for (const char *q = x->stmt[i].text; *q; q++)
            nlines += *q == '\n';
    LaneVar *var = arena_alloc(sizeof(LaneVar) * ((size_t)x->nloc + 2 * nlines + 2 * (size_t)x->c->nouts + 8));
    int nvar = 0;
    Buf fix = {0}, load = {0}, wb = {0}, fl = {0};
    for (int i = 0; i < x->nloc; i++) {
        const Local *l = &x->loc[i];
        const char *type, *value;
        if (!keep[i])
            continue;
        if (!*l->decl) { /* nothing loaded: a store at the end only */
            emit(&wb, "%s", l->wb);
            emit(&fl, "%s", l->fl);
            continue;
        }
        if (!l->name || !split_decl(l->decl, l->name, &type, &value))
            return fallback;
        Names used = {0};
        names_scan(&used, value);
        bool fixed = true; /* a number, the same in every lane (cast to real, perhaps) */
        for (size_t k = 0; k < used.cap; k++)
            fixed = fixed && (!used.key[k] || (used.len[k] == 4 && !memcmp(used.key[k], "real", 4)));
        if (fixed) {
            emit(&fix, "        const %s %s = %s;\n", type, l->name, value);
            continue;
        }
        names_put(&lane, l->name, strlen(l->name));
        var[nvar++] = (LaneVar){type, l->name, true, false};
        emit(&load, "%s = %s;\n", l->name, value);
        emit(&wb, "%s", l->wb);
        emit(&fl, "%s", l->fl);
    }
    /* the statements, cut into loops over the lanes at each diode that
     * diode_fast solves; the inputs gathered, the outputs scattered */
    int cap = x->nstmt + 1, nseg = 1;
    Buf *seg = arena_alloc(sizeof(Buf) * (size_t)cap), *fixup = arena_alloc(sizeof(Buf) * (size_t)cap);
    Buf gather = {0}, scatter = {0}, anys = {0};
    for (int i = 0; i < x->nstmt; i++) {
        if (!skeep[i])
            continue;
        const Stmt *s = &x->stmt[i];
        const char *t = s->text;
        int k;
        if (s->def && sscanf(s->def, "t_in%d", &k) == 1 && !strcmp(t, format("        const real t_in%d = (real)in%d[n];\n", k, k))) {
            names_put(&lane, s->def, strlen(s->def));
            var[nvar++] = (LaneVar){"real", s->def, false, false};
            emit(&gather, "%s = (real)in%d[n];\n", s->def, k);
            continue;
        }
        const char *call = strstr(t, " = diode_fast(");
        if (call) {
            const char *a[12];
            const char *line = call;
            while (line > t && line[-1] != '\n')
                line--;
            if (sscanf(line, " t_v%d = diode_fast(", &k) != 1 || call_args(line, "diode_fast(", a, 12) != 11 ||
                strncmp(t, format("        double t_v%d;", k), strlen(format("        double t_v%d;", k))))
                return fallback;
            const char *v = format("t_v%d", k), *slow = format("t_slow%d", k);
            names_put(&lane, v, strlen(v));
            names_put(&lane, slow, strlen(slow));
            var[nvar++] = (LaneVar){"double", v, false, false};
            var[nvar++] = (LaneVar){"int", slow, false, false};
            const char *comment = strstr(t, "/*"), *eol = strchr(t, '\n');
            if (comment && comment < eol)
                emit(&seg[nseg - 1], "        %.*s\n", (int)(eol - comment), comment);
            emit(&seg[nseg - 1], "        %s = fast_lane(%s, %s, %s, %s, %s, %s, %s, %s, %s, &%s);\n        t_any%d |= %s;\n", v,
                 a[0], a[1], a[2], a[3], a[4], a[5], a[6], a[8], a[9], slow, k, slow);
            emit(&anys, "            int t_any%d = 0;\n", k);
            const char *le = strchr(call, '\n') + 1, *close = strstr(le, "\n        }\n");
            emit(&fixup[nseg - 1], "        if (t_any%d) { /* lanes past the tables, or a tighter tol */\n"
                                   "            LANE_CALLS();\n"
                                   "            for (int l = 0; l < nl; l++)\n                if (%s)\n        %.*s"
                                   "        }\n",
                 k, slow, (int)(le - line), line);
            nseg++;
            if (close && close + 1 > le)
                emit(&seg[nseg - 1], "        {\n%.*s        }\n", (int)(close + 1 - le), le);
            continue;
        }
        for (int o = 0; o < x->c->nouts; o++)
            t = replace_all(t, format("out[%d][n] = ", o), format("t_y%d = ", o));
        emit(&seg[nseg - 1], "%s", t);
    }
    for (int o = 0; o < x->c->nouts; o++) {
        const char *y = format("t_y%d", o), *p = format("t_o%d", o);
        names_put(&lane, y, strlen(y));
        names_put(&lane, p, strlen(p));
        var[nvar++] = (LaneVar){"double", y, false, false};
        var[nvar++] = (LaneVar){"double *", p, false, true};
        emit(&load, "%s = out[%d];\n", p, o);
        emit(&scatter, "%s[n] = %s;\n", p, y);
    }
    /* temporaries that a later loop (or a diode's second answer) names */
    for (int s = 0; s < nseg; s++) {
        Names later = {0};
        for (int r = 0; r < nseg; r++) {
            if (r != s)
                names_scan(&later, str(&seg[r]));
            names_scan(&later, str(&fixup[r]));
        }
        Buf b = {0};
        for (const char *p = str(&seg[s]); *p;) {
            const char *e = strchr(p, '\n');
            size_t n = e ? (size_t)(e - p) + 1 : strlen(p);
            const char *line = format("%.*s", (int)n, p), *type, *name, *rest;
            p += n;
            int d = top_decl(line, &type, &name, &rest);
            if (d == 2) {
                Names in = {0};
                names_scan(&in, line);
                for (size_t j = 0; j < in.cap; j++)
                    if (in.key[j] && names_has_n(&later, in.key[j], in.len[j]) && !names_has_n(&lane, in.key[j], in.len[j]))
                        return fallback;
            }
            if (d != 1 || !names_has(&later, name)) {
                emit(&b, "%s", line);
                continue;
            }
            names_put(&lane, name, strlen(name));
            var[nvar++] = (LaneVar){type, name, false, false};
            if (rest[0] == ';') { /* the declaration alone: its comment stays */
                const char *c = strstr(rest, "/*");
                if (c)
                    emit(&b, "        %s", c);
            } else
                emit(&b, "        %s%s", name, rest);
        }
        seg[s] = b;
    }
    /* a loop that names the state (a joint solve's counts) runs over the
     * instances only; the others run over every lane, the lanes past nl
     * repeating lane 0's work (never stored), so that their count is a
     * constant */
    bool wide = true;
    for (int s = 0; s < nseg; s++)
        wide = wide && !uses(str(&seg[s]), "st") && !uses(str(&fixup[s]), "st");
    const char *lanes = wide ? "WDV_LANES" : "nl";
    /* Where every loop over the lanes is a loop over all of them (no lane
     * is left to a solver's own steps), the states of every lane go
     * through flush_lane at the end of each frame's loop, with the
     * threshold of the frame's row (FLUSH_BELOW in the lanes whose run
     * ends there, 0 in the others): a select on values the loop has just
     * computed, which the compiler vectorises with the rest, where a
     * separate test would leave the states in memory behind masked
     * stores.  Otherwise (the states are in memory anyway) a loop over
     * the instances flushes those whose run ends. */
    bool flushes = fl.len > 0, each = !anys.len && wide;
    /* The lanes past nl copy the last instance (nl - 1).  Where every
     * lane runs every statement, a single output is then stored from every
     * lane, each copy storing its instance's own value again after it, by
     * a loop of constant count that compilers make a scatter or straight
     * stores (RC lowpass 0.87 -> 0.71 ns per voice-sample, tone stack
     * 1.68 -> 1.27, under gcc here); several outputs' stores stay a loop
     * over the instances, which measured faster for three under gcc than
     * any of the constant forms, scattered or not. */
    bool wide_out = each && x->c->nouts == 1;
    for (int i = 0; i < nvar && wide_out; i++)
        var[i].loaded = var[i].loaded || var[i].out;
    if (flushes && each) {
        if (nseg != 1 || fixup[0].len)
            die("batch: a voice flushed in every lane has one loop over the lanes");
        emit(&seg[0], "%s", replace_all(str(&fl), "flush(", "flush_lane(t_f[l], "));
    }
    Buf body = {0};
    /* the lanes past nl read the input of the lane they copy; under clang, in the loop over
     * the lanes (LANE_LOOP) */
    const char *gtext = deeper(in_lanes(str(&gather), &lane), 4);
    bool vec = each && seg[0].len && !calls_out(str(&seg[0])), gin = gather.len && vec;
    if (gather.len)
        emit(&body, "%s            for (int l = 0; l < %s; l++) {\n%s            }\n%s", gin ? "#if !defined(__clang__)\n" : "",
             lanes, gtext, gin ? "#endif\n" : "");
    emit(&body, "%s", str(&anys));
    if (flushes && each)
        emit(&body, "            const real *const t_f = t_fl[n %% FLUSH_RUN];\n");
    for (int s = 0; s < nseg; s++) {
        if (seg[s].len) {
            const char *text = in_lanes(str(&seg[s]), &lane);
            emit(&body, "%s            for (int l = 0; l < %s; l++) {\n%s%s%s            }\n", each ? "            LANE_LOOP\n" : "",
                 lanes, uses(text, "st") ? "                state *const st = vsts[l];\n" : "",
                 gin ? format("#if defined(__clang__)\n%s#endif\n", gtext) : "", deeper(text, 2));
        }
        emit(&body, "%s", deeper(in_lanes(str(&fixup[s]), &lane), 1));
    }
    if (scatter.len)
        emit(&body, "            for (int l = 0; l < %s; l++) {\n%s            }\n", wide_out ? "WDV_LANES" : "nl",
             deeper(in_lanes(str(&scatter), &lane), 4));
    if (flushes && !each) {
        emit(&body, "            const unsigned t_m = t_fm[n %% FLUSH_RUN]; /* the lanes whose run ends here */\n"
                    "            if (t_m)\n                for (int l = 0; l < nl; l++)\n"
                    "                    if (t_m >> l & 1) {\n%s                    }\n",
             deeper(in_lanes(str(&fl), &lane), 4));
        if (wide) /* the lanes past nl take the last instance's flushed states: its copies, out of the subnormals */
            emit(&body, "            if (t_m >> (nl - 1) & 1u)\n                for (int l = nl; l < WDV_LANES; l++) {\n%s                }\n",
                 deeper(replace_all(replace_all(in_lanes(str(&fl), &lane), "flush(", ""), "[l]);", "[nl - 1];"), 3));
    }
    if (uses(str(&body), "in") || uses(str(&body), "out"))
        return fallback;
    if (flushes)
        emit(&wb, "    st->s_run = (st->s_run + (unsigned)nframes) %% FLUSH_RUN;\n");
    const char *ltext = format("%s%s%s", deeper(dirty, 2), deeper(in_lanes(str(&load), &lane), 3),
                               !flushes ? ""
                               : each   ? "            t_fl[FLUSH_RUN - 1 - st->s_run % FLUSH_RUN][l] = FLUSH_BELOW;\n"
                                        : "            t_fm[FLUSH_RUN - 1 - st->s_run % FLUSH_RUN] |= 1u << l;\n");
    const char *wtext = deeper(in_lanes(str(&wb), &lane), 2);
    /* a lane's view of its own instance, named as process names it */
    static const char *const view[3] = {"state *const st = vsts[l];", "const double *const *const in = inl[l];",
                                        "double *const *const out = outl[l];"};
    static const char *const vname[3] = {"st", "in", "out"};
    bool uin = uses(ltext, "in") || uses(wtext, "in"), uout = uses(ltext, "out") || uses(wtext, "out");
    Buf b = {0};
    emit(&b, "%s%s%s    for (int l0 = 0; l0 < n; l0 += WDV_LANES) {\n", anys.len ? format("%s\n", tmpl_nl_fast_lane) : "",
         each ? format(lane_loop, vec ? lane_clang : "") : "", format(head, uin ? "" : " UNUSED", uout ? "" : " UNUSED"));
    emit(&b, "        const int nl = n - l0 < WDV_LANES ? n - l0 : WDV_LANES;\n"
             "        void *const *const vsts = states + l0;\n%s%s%s",
         uin ? "        const double *const *const *const inl = ins + l0;\n" : "",
         uout ? "        double *const *const *const outl = outs + l0;\n" : "", str(&fix));
    emit(&b, "        struct {\n");
    for (int i = 0; i < nvar; i++)
        emit(&b, "            %s%s%s[WDV_LANES];\n", var[i].type, var[i].type[strlen(var[i].type) - 1] == '*' ? "" : " ",
             var[i].name);
    emit(&b, "        } t_ln;\n");
    if (flushes && each)
        emit(&b, "        /* per frame mod FLUSH_RUN, each lane's flush threshold: FLUSH_BELOW where its run ends */\n"
                 "        real t_fl[FLUSH_RUN][WDV_LANES] = {{0}};\n");
    else if (flushes)
        emit(&b, "        unsigned t_fm[FLUSH_RUN] = {0}; /* per frame mod FLUSH_RUN, the lanes whose run ends there */\n");
    const char *parts[2] = {ltext, wtext};
    for (int k = 0; k < 2; k++) {
        emit(&b, k ? "        for (int l = 0; l < nl; l++) {\n" : "        for (int l = 0; l < nl; l++) {\n");
        for (int j = 0; j < 3; j++)
            if (uses(parts[k], vname[j]))
                emit(&b, "            %s\n", view[j]);
        emit(&b, "%s        }\n", parts[k]);
        if (k == 0 && wide) {
            emit(&b, "        for (int l = nl; l < WDV_LANES; l++) { /* lanes past nl: copies of lane nl - 1%s */\n",
                 wide_out ? "" : ", not stored");
            for (int i = 0; i < nvar; i++)
                if (var[i].loaded)
                    emit(&b, "            t_ln.%s[l] = t_ln.%s[nl - 1];\n", var[i].name, var[i].name);
            /* flushed with the lane they copy, they stay its copies (and out of the subnormals) */
            if (flushes && each)
                emit(&b, "            for (int m = 0; m < FLUSH_RUN; m++)\n                t_fl[m][l] = t_fl[m][nl - 1];\n");

            emit(&b, "        }\n");
        }
        if (k == 0)
            emit(&b, "        for (int n = 0; n < nframes; n++) {\n%s        }\n", str(&body));
    }
    emit(&b, "    }\n}\n");
    return str(&b);
}

/* process: the statements and locals its outputs and states need, and
 * its parameters (UNUSED where a voice has no inputs, say). */
/* The count of samples since the last flush: loaded, stored, and the
 * flush done when a run is complete. */
static void decl_run(Buf *decl, Buf *wb, Buf *fl) {
    emit(decl, "    unsigned t_run = st->s_run;\n");
    emit(wb, "    st->s_run = t_run;\n");
    const char *body = str(fl);
    Buf b = {0};
    emit(&b, "        if (t_run == FLUSH_RUN) {\n            t_run = 0;\n");
    emit(&b, "%s", deeper(body, 1));
    emit(&b, "        }\n");
    *fl = b;
}

/* tuning (wdv_class.tuning) for a voice with strings or tubes (their loops'
 * design errors) or delay lines (each one's delay held in whole samples,
 * as update holds it: line_err), the largest; "" for one without. */
static const char *tuning_text(Ctx *x) {
    const Circuit *c = x->c;
    if (!c->nwgs && !x->nline)
        return "";
    Buf b = {0};
    emit(&b, "static double voice_tuning(const void *vst) {\n    const state *st = vst;\n    double e = 0;\n");
    if (c->nwgs)
        emit(&b, "    for (int w = 0; w < N_WG; w++)\n"
                 "        e = st->c_werr[w] > e ? st->c_werr[w] : e;\n"
                 "    if (!(e < WG_UNTUNABLE))\n        return (double)INFINITY;\n");
    for (int i = 0; i < c->nelems; i++) {
        const Elem *e = &c->elems[i];
        if (e->kind == E_W && e->peer > i) { /* named as its line: NAME.1 */
            const char *dot = strrchr(e->name, '.');
            emit(&b, "    e = line_err(e, %.17g * st->fs, st->c_D[%d], %d); /* %.*s */\n", e->td, x->line_of[i],
                 x->dl_size[x->line_of[i]] - 1, dot ? (int)(dot - e->name) : (int)strlen(e->name), e->name);
        }
    }
    emit(&b, "    return e;\n}\n\n");
    return str(&b);
}

/* ---- wrap-free segments ----
 *
 * A line's positions are masked into its buffer at every read and write.
 * process instead steps through segments of frames in which no position
 * that the loops read or write wraps: at a segment's first frame each
 * position becomes a pointer (t_lK, from wrapfree), and frame n reads
 * t_lK[n - t_s0].  The arithmetic is the same; the masks go. */

typedef struct {
    const char *text; /* the access as printed: s_wv[OFF + ((t_pos - D) & M)] */
    const char *at;   /* its position, (t_pos - D) & M */
    const char *arr;  /* s_wv or s_dl */
    const char *line; /* its region: s_wv + OFF */
    unsigned size;    /* M + 1 */
} LinePos;

/* True if the n characters at d make a delay that stays put through a
 * call of process: names k_*, numbers, parentheses, + and -. */
static bool steady_delay(const char *d, size_t n) {
    for (size_t i = 0; i < n;) {
        if (isalpha((unsigned char)d[i]) || d[i] == '_') {
            if (strncmp(d + i, "k_", 2))
                return false;
            while (i < n && (isalnum((unsigned char)d[i]) || d[i] == '_'))
                i++;
        } else if (isdigit((unsigned char)d[i]) || strchr(" ()+-", d[i]))
            i++;
        else
            return false;
    }
    return n > 0;
}

/* The length of the line access at p (s_wv[OFF + (t_pos & M)] or
 * s_wv[OFF + ((t_pos - D) & M)], or s_dl's) with *lp filled in; 0 if p
 * starts none. */
static size_t line_access(const char *p, LinePos *lp) {
    const char *q = p;
    if (strncmp(q, "s_wv[", 5) && strncmp(q, "s_dl[", 5))
        return 0;
    q += 5;
    const char *off = q;
    while (isdigit((unsigned char)*q))
        q++;
    if (q == off || strncmp(q, " + (", 4))
        return 0;
    size_t noff = (size_t)(q - off);
    q += 4;
    const char *at = q, *d = NULL;
    size_t nd = 0;
    if (!strncmp(q, "t_pos & ", 8))
        q += 8;
    else if (!strncmp(q, "(t_pos - ", 9)) {
        d = q += 9;
        for (int depth = 0; *q && !(*q == ')' && depth == 0); q++)
            depth += *q == '(' ? 1 : *q == ')' ? -1 : 0;
        nd = (size_t)(q - d);
        if (*q != ')' || strncmp(q, ") & ", 4) || !steady_delay(d, nd))
            return 0;
        q += 4;
    } else
        return 0;
    const char *m = q;
    unsigned long mask = strtoul(m, (char **)&q, 10);
    if (q == m || strncmp(q, "u)]", 3) || mask == 0 || mask >= 1ul << 30 || (mask & (mask + 1)))
        return 0;
    size_t nat = (size_t)(q + 1 - at);
    q += 3;
    const char *arr = format("%.4s", p);
    *lp = (LinePos){format("%.*s", (int)(q - p), p), format("%.*s", (int)nat, at), arr,
                    noff == 1 && *off == '0' ? arr : format("%s + %.*s", arr, (int)noff, off), (unsigned)mask + 1};
    return (size_t)(q - p);
}

/* texts[0..n) with each line access turned into its segment pointer's;
 * *open gets the statements that start a segment, *decl the pointers'
 * declarations.  False (texts untouched) if they have none. */
static bool segment_lines(const char **texts, int n, int nadd, Buf *open, Buf *decl) {
    LinePos *pos = NULL;
    int npos = 0, cap = 0, nslot = 0, *slot = NULL; /* slot: open addressing over pos by text */
    for (int t = 0; t < n; t++) {
        Buf b = {0};
        for (const char *p = texts[t]; *p;) {
            const char *s = strstr(p, "s_");
            if (!s) {
                buf_put(&b, p, strlen(p));
                break;
            }
            buf_put(&b, p, (size_t)(s - p));
            LinePos lp;
            size_t len = line_access(s, &lp);
            if (!len) {
                buf_put(&b, s, 2);
                p = s + 2;
                continue;
            }
            if (t >= nadd) { /* a text that only takes the positions the first ones hold */
                int k = -1;
                if (nslot) {
                    unsigned h = name_hash(lp.text, strlen(lp.text)) & (unsigned)(nslot - 1);
                    while (slot[h] >= 0 && strcmp(pos[slot[h]].text, lp.text))
                        h = (h + 1) & (unsigned)(nslot - 1);
                    k = slot[h];
                }
                if (k >= 0)
                    emit(&b, "t_l%d[n - t_s0]", k);
                else
                    buf_put(&b, s, len);
                p = s + len;
                continue;
            }
            if (2 * (npos + 1) > nslot) { /* grow the table, rehash */
                nslot = nslot ? 2 * nslot : 64;
                slot = arena_alloc(sizeof(int) * (size_t)nslot);
                for (int k = 0; k < nslot; k++)
                    slot[k] = -1;
                for (int k = 0; k < npos; k++) {
                    unsigned h = name_hash(pos[k].text, strlen(pos[k].text)) & (unsigned)(nslot - 1);
                    while (slot[h] >= 0)
                        h = (h + 1) & (unsigned)(nslot - 1);
                    slot[h] = k;
                }
            }
            unsigned h = name_hash(lp.text, strlen(lp.text)) & (unsigned)(nslot - 1);
            while (slot[h] >= 0 && strcmp(pos[slot[h]].text, lp.text))
                h = (h + 1) & (unsigned)(nslot - 1);
            if (slot[h] < 0) {
                pos = grow(pos, npos, &cap, sizeof *pos);
                pos[npos] = lp;
                slot[h] = npos++;
            }
            emit(&b, "t_l%d[n - t_s0]", slot[h]);
            p = s + len;
        }
        texts[t] = str(&b);
    }
    if (!npos)
        return false;
    emit(decl, "    int t_s0 = 0, t_se = 0; /* the segment: its first frame and the frame past it */\n    real ");
    emit(open, "        if (n == t_se) { /* a segment in which no line position wraps */\n"
               "            t_s0 = n, t_se = nframes;\n");
    for (int k = 0; k < npos; k++) {
        emit(decl, "%s*t_l%d = %s", k ? ", " : "", k, pos[k].arr);
        emit(open, "            t_l%d = wrapfree(%s, %s, %uu, n, &t_se);\n", k, pos[k].line, pos[k].at, pos[k].size);
    }
    emit(decl, ";\n");
    emit(open, "        }\n");
    return true;
}

static void process_holes(Ctx *x, Holes *t, const char *dirty) {
    Names live = {0};
    const char *sample = sample_text(x, &live);
    const char *idle = x->skip ? idle_text(x, &live) : "";
    Buf decl = {0}, wb = {0}, fl = {0}, open = {0}, seg = {0};
    /* with hammers that skip, the segments hold the positions the
     * skipping loop reads and writes (the full loop masks the others: the
     * idle contacts' ports), so that positions it does not read do not
     * cut its runs short */
    const char *loops[] = {idle, sample};
    bool segs = segment_lines(loops, 2, x->skip ? 1 : 2, &open, &seg);
    idle = loops[0], sample = loops[1];
    Buf fli = {0};
    print_locals_split(x, &live, &decl, &wb, &fl, x->skip ? &fli : NULL);
    if (x->skip) { /* a run the skipping loop took whole leaves the idle states as they were: flushed */
        emit(&decl, "    int t_full = 1; /* the full loop ran since the last flush */\n"
                    "    int t_left = 0, t_done = 0, t_wait = 0; /* the skipping loop's: see idle_text */\n");
        emit(&fl, "        if (t_full) {\n%s        }\n        t_full = 0;\n", deeper(str(&fli), 1));
    }
    emit(&decl, "%s", str(&seg));
    /* runs of FLUSH_RUN samples are counted across calls (s_run), so the
     * states are flushed at the same samples however a host splits its
     * calls */
    x->flushes = fl.len > 0;
    if (x->flushes) {
        decl_run(&decl, &wb, &fl);
    }
    const char *head = format("%s%s", dirty, str(&decl));
    const char *parts[] = {head, idle, sample, str(&fl), str(&wb), str(&open)}; /* what process holds */
    if (uses_any(parts, 6, "st"))
        parts[0] = head = format("    state *st = vst;\n%s", head);
    static const char *const decls[] = {"void *vst", "const double *const *in", "double *const *out"};
    static const char *const names[] = {"vst", "in", "out"};
    set(t, "process_args", format("%s, int nframes", params_of(parts, 6, 3, decls, names)));
    set(t, "hoist", head);
    set(t, "sample", sample);
    set(t, "idle", idle);
    set(t, "flush", str(&fl));
    const char *last = segs ? "t_se" : "nframes";
    set(t, "segment", str(&open));
    set(t, "run_end", x->flushes ? format("%s - n > (int)(FLUSH_RUN - t_run) ? n + (int)(FLUSH_RUN - t_run) : %s", last, last)
                                 : format("%s - n > FLUSH_RUN ? n + FLUSH_RUN : %s", last, last));
    set(t, "run_count", x->flushes ? "        t_run += (unsigned)(t_end - n);\n" : "");
    set(t, "writeback", str(&wb));
    set(t, "batch", x->opt->batch ? batch_text(x, dirty) : "");
    set(t, "chunks", chunk_fn(x));
    set(t, "batch_entry", x->opt->batch ? "voice_process_batch" : "NULL");
    set(t, "solve_stats", any_joint(x) ? "static void voice_solve_stats(const void *vst, unsigned long stats[WDV_SOLVE_N]) {\n"
                                         "    for (int k = 0; k < WDV_SOLVE_N; k++)\n"
                                         "        stats[k] = ((const state *)vst)->s_js[k];\n}\n\n" : "");
    set(t, "solve_stats_entry", any_joint(x) ? "voice_solve_stats" : "NULL");
    set(t, "tuning", tuning_text(x));
    set(t, "tuning_entry", x->c->nwgs || x->nline ? "voice_tuning" : "NULL");
}

/* reset and set_ic: what they set before settle (`rest`: initial values;
 * `kirch`: reactances read back; `cases`: each target's), and settle. */
static void reset_holes(Ctx *x, Holes *t, const char *dirty, const char *rest, const char *kirch, const char *cases) {
    const char *react = x->settle && x->nreact ? format("    double react[%d] = {0};\n", x->nreact) : "";
    const char *st = "    state *st = vst;\n";
    /* reset brings the coefficients up to date only if it reads them: a
     * cleared state is the same under any, and process updates first */
    bool reads = uses(rest, "settle") || uses(rest, "dcop") || strstr(rest, "st->c_");
    const char *reset = with_st(st, format("%s%s%s%s%s", uses(rest, "p") ? "    const double *p = st->p;\n" : "",
                                           uses(rest, "react") ? react : "", reads ? dirty : "", clears(x), rest));
    set(t, "reset_args", uses(reset, "vst") ? "void *vst" : "void *vst UNUSED");
    set(t, "reset", reset);
    const char *sw = *cases ? format("    for (int k = 0; k < n; k++) {\n        switch (ids[k]) {\n%s        }\n    }\n", cases) : "";
    if (*cases && x->ic_direct)
        sw = "    for (int k = 0; k < n; k++)\n        react[ids[k]] = values[k];\n";
    const char *res = x->settle ? format("settle(st, %s) == 0 ? 0 : -1", x->nreact ? "react" : "NULL") : "0";
    const char *head = format("%s%s%s%s", react, x->nidle ? "    voice_cut(st);\n" : "", dirty, kirch);
    const char *parts[] = {head, sw, res};
    bool used = uses_any(parts, 3, "st");
    set(t, "set_ic_args", format("void *vst%s, int n, const int *ids%s, const double *values%s", used ? "" : " UNUSED",
                                 x->nic ? "" : " UNUSED", x->nic ? "" : " UNUSED"));
    set(t, "set_ic", used ? format("%s%s", st, head) : head);
    set(t, "ic_check", x->nic ? format("    for (int k = 0; k < n; k++)\n"
                                       "        if (ids[k] < 0 || ids[k] >= %d || values[k] != values[k])\n"
                                       "            return -1;\n", x->nic)
                              : "    if (n > 0) /* nothing to strike */\n        return -1;\n");
    set(t, "ic_cases", sw);
    set(t, "ic_result", res);
}

/* energy, from the state, and work: the sum process keeps with --energy. */
static void measure_holes(Ctx *x, Holes *t, const char *energy) {
    set(t, "energy_args", *energy ? "const void *vst" : "const void *vst UNUSED");
    set(t, "energy", *energy ? format("    const state *st = vst;\n    double E = 0;\n%s    return E;\n", energy)
                             : "    return 0;\n");
    set(t, "work", x->energy && x->nsrc ? "static double voice_work(const void *vst) { return ((const state *)vst)->s_work; }\n\n"
                   : x->energy          ? "/* The voice has no sources: nothing does work on it. */\n"
                                          "static double voice_work(const void *vst UNUSED) { return 0; }\n\n"
                                        : ""); /* counted with --energy only; the class's work is NULL */
    set(t, "work_entry", x->energy ? "voice_work" : "NULL");
}

/* settle's cases for controlled sources and op-amps: each output's row
 * of ic_ctl holds its probe's nodes and its gain; a voltage output's
 * current is an unknown, as an ideal V source's is. */
static const char *ic_ctl(Ctx *x) {
    if (!x->nctl)
        return "";
    const Circuit *c = x->c;
    Buf b = {0};
    emit(&b, "        case IC_CV: case IC_CI: case IC_OA: case IC_XF: {\n"
             "            static const double ic_ctl[][3] = {");
    for (int i = 0, k = 0; i < c->nelems; i++) {
        const Elem *e = &c->elems[i];
        if (!ELEM_CONTROLLED(e->kind) || e->kind == E_P || e->kind == E_CC)
            continue;
        const Elem *pr = &c->elems[e->peer];
        emit(&b, "%s{%d, %d, %s}", k++ ? ", " : "", pr->n[0], pr->n[1], lit(x, e->val ? expr_eval(e->val, NULL) : 0));
    }
    emit(&b, "}; /* probe's nodes, gain */\n"
             "            const double *t = ic_ctl[e[4]];\n"
             "            ctl_stamp(A, N_ICN, e[0], p, q, (int)t[0] - 1, (int)t[1] - 1, m, t[2]);\n"
             "            if (e[0] != IC_CI)\n"
             "                x[m++] = 0;\n"
             "            break;\n"
             "        }\n"
             "        case IC_PROBE: break; /* no current */\n");
    return str(&b);
}

/* What root_solve stores of a joint root's nonlinear rows in c_jQ, in
 * double, for a float voice's joint solve. */
static const char *jq_store(Ctx *x) {
    Buf b = {0};
    bool any = false;
    for (int rb = 0; rb < x->w->nroots; rb++) {
        any |= x->jq_off[rb] >= 0 && !x->rfn[rb];
        emit(&b, "%s{%d, %d}", rb ? ", " : "", x->rfn[rb] ? -1 : x->jq_off[rb], x->w->roots[rb].nport);
    }
    if (!any)
        return "";
    return format("            if (e[0] == EDGE_NL) { /* its row in double too: offset, ports */\n"
                  "                static const short jq[][2] = {%s};\n"
                  "                if (jq[rb][0] >= 0)\n"
                  "                    st->c_jQ[jq[rb][0] + (k - jq[rb][1]) * ne + j] = out;\n"
                  "            }\n", str(&b));
}

/* The controlled sources of the roots, for core_matrix. */
static const char *root_ctl_table(Ctx *x) {
    if (!x->nctl && !x->ncc)
        return "";
    Buf b = {0};
    emit(&b, "/* Controlled sources and op-amps in the roots: root, kind, output's\n"
             " * core unknowns p q, probe's cp cn (-1: reference), the unknown of its\n"
             " * current (voltage outputs), gain. */\n"
             "static const double root_ctl[][8] = {");
    int k = 0;
    for (int rb = 0; rb < x->w->nroots; rb++) {
        const Root *r = &x->w->roots[rb];
        for (int j = 0, u = r->ncore; j < r->nctl; j++) {
            const struct RootCtl *c = &r->ctl[j];
            bool cur = c->kind == E_CI || c->kind == E_CC;
            /* a transistor's source: gain / R on its junction's voltage */
            double g = c->kind == E_CC ? c->gain / r->R[c->ce] : c->gain;
            emit(&b, "%s{%d, %s, %d, %d, %d, %d, %d, %s}", k++ ? ", " : "", rb,
                 c->kind == E_CV ? "IC_CV" : c->kind == E_XF ? "IC_XF" : cur ? "IC_CI" : "IC_OA", c->p, c->q, c->cp, c->cn,
                 cur ? -1 : u,
                 lit(x, g));
            u += !cur;
        }
    }
    emit(&b, "};\n\n");
    if (!x->ncc)
        return str(&b);
    /* and -gain / R on its junction's wave, an input of the root */
    emit(&b, "/* Transistors' sources in the roots: root, the junction edge whose\n"
             " * current each takes, the source's core unknowns p q, gain over the\n"
             " * junction's resistance. */\n"
             "static const double root_cc[][5] = {");
    k = 0;
    for (int rb = 0; rb < x->w->nroots; rb++) {
        const Root *r = &x->w->roots[rb];
        for (int j = 0; j < r->nctl; j++) {
            const struct RootCtl *c = &r->ctl[j];
            if (c->kind == E_CC)
                emit(&b, "%s{%d, %d, %d, %d, %s}", k++ ? ", " : "", rb, c->ce, c->p, c->q,
                     lit(x, c->gain / r->R[c->ce]));
        }
    }
    emit(&b, "};\n\n");
    return str(&b);
}

/* The holes of root.c.tmpl and settle.c.tmpl, and the elastic forces
 * (`force`: one line per element that has one) settle asks for. */
static void solve_holes(Ctx *x, Holes *t, const char *force, const char *retune, const char *probes, int nicv) {
    set(t, "nl_force", *force ? format("\n/* Elastic force of nonlinear edge k at its present state (contacts,\n"
                                       " * nonlinear inductors). */\nstatic double nl_force(const state *st, int k) {\n"
                                       "%s    return 0;\n}\n", force)
                              : "");
    set(t, "nl_retune", retune);
    set(t, "edge_R", x->nnl ? "e[0] == EDGE_PORT ? st->c_R[e[3]] : st->c_Rn[e[3]]" : "st->c_R[e[3]]");
    set(t, "nl_adapt", x->nnl ? tmpl_nl_adapt : "");
    set(t, "nl_adapt_call", x->nnl ? "    nl_adapt(st, rb, A, x, piv);\n" : "");
    set(t, "ic_ctl", ic_ctl(x));
    set(t, "ic_open", ic_open(x));
    set(t, "jq_store", jq_store(x));
    set(t, "root_ctl_table", root_ctl_table(x));
    set(t, "ctl_column", x->ncc ? "        for (size_t c = 0; c < sizeof root_cc / sizeof root_cc[0]; c++)\n"
                                  "            if ((int)root_cc[c][0] == rb && (int)root_cc[c][1] == j) {\n"
                                  "                int p = (int)root_cc[c][2], q = (int)root_cc[c][3];\n"
                                  "                if (p >= 0) x[p] += root_cc[c][4];\n"
                                  "                if (q >= 0) x[q] -= root_cc[c][4];\n"
                                  "            }\n"
                                : "");
    set(t, "root_ctl_stamp", x->nctl || x->ncc ? "    for (size_t c = 0; c < sizeof root_ctl / sizeof root_ctl[0]; c++)\n"
                                       "        if ((int)root_ctl[c][0] == rb)\n"
                                       "            ctl_stamp(A, n, (int)root_ctl[c][1], (int)root_ctl[c][2], (int)root_ctl[c][3],\n"
                                       "                      (int)root_ctl[c][4], (int)root_ctl[c][5], (int)root_ctl[c][6], root_ctl[c][7]);\n"
                                     : "");
    set(t, "ic_drive", keeps_drive(x) ? "e[5] >= 0 ? st->s_e[e[5]] : 0" : "0");
    set(t, "ic_current", *force ? "e[0] == IC_IND ? react[e[4]] : e[0] == IC_FORCE ? nl_force(st, e[4]) : drive"
                                : "e[0] == IC_IND ? react[e[4]] : drive");
    set(t, "ic_wave", x->c->nwgs ? "        case IC_WAVE: /* a waveguide's port: the wave that last arrived behind its resistance */\n"
                                   "            stamp(A, N_ICN, p, q, g);\n"
                                   "            if (p >= 0) x[p] += g * (double)st->s_wpre[e[4]];\n"
                                   "            if (q >= 0) x[q] -= g * (double)st->s_wpre[e[4]];\n"
                                   "            break;\n"
                                 : "");
    set(t, "ic_store", settle_store(x, nicv, probes));
}

/* The descriptor arrays a voice has (C has no empty ones) and the class's
 * pointers to them, NULL where there are none. */
static void emit_descriptors(Ctx *x, const char *targets, Buf *decl, Buf *ptrs) {
    const Circuit *c = x->c;
    static const char *const type[] = {"wdv_port", "wdv_port", "wdv_param", "wdv_ic_target"};
    static const char *const name[] = {"in_desc", "out_desc", "param_desc", "ic_desc"};
    int n[] = {c->ninputs, c->nouts, c->nparams, x->nic};
    const char *init[] = {descriptors(x, 'i'), descriptors(x, 'o'), descriptors(x, 'p'), format("{%s}", targets)};
    for (int k = 0; k < 4; k++) {
        if (n[k])
            emit(decl, "static const %s %s[] = %s;\n", type[k], name[k], init[k]);
        emit(ptrs, "%s%s", k ? ", " : "", n[k] ? name[k] : "NULL");
    }
}

/* The codes of templates/codes.def that the voice's text (and its
 * waveguide kernels, wg) names, as the enum the compiler has them in:
 * each group (EDGE_, IC_, WGT_) whole, if the text names one of it. */
static const char *codes(const char *text, const char *wg) {
    static const char *const groups[] = {"EDGE_", "IC_", "WGT_"};
    static const char *const about[] = {"what an edge of a root adaptor is (root_edge[][0])",
                                        "how an element enters the initial-condition solve (ic_elem[][0])",
                                        "the columns of a waveguide's row of wg_tab"};
    Buf b = {0};
    Names names = {0}, all = {0};
    for (int i = 0; i < NCODES; i++)
        names_put(&all, all_codes[i].name, strlen(all_codes[i].name));
    names_scan_in(&names, text, &all);
    names_scan_in(&names, wg, &all);
    for (int g = 0; g < 3; g++) {
        size_t len = strlen(groups[g]);
        bool used = false;
        for (int i = 0; i < NCODES; i++)
            used |= !strncmp(all_codes[i].name, groups[g], len) && names_has(&names, all_codes[i].name);
        if (!used)
            continue;
        emit(&b, "/* %s */\nenum {\n", about[g]);
        for (int i = 0; i < NCODES; i++)
            if (!strncmp(all_codes[i].name, groups[g], len))
                emit(&b, "    %s = %d, /* %s */\n", all_codes[i].name, all_codes[i].value, all_codes[i].what);
        emit(&b, "};\n");
    }
    return str(&b);
}

/* text with each run of blank lines (holes left empty) made one. */
static const char *one_blank(const char *text) {
    char *s = arena_strdup(text), *o = s;
    for (const char *p = text; *p; p++)
        if (!(*p == '\n' && o - s >= 2 && o[-1] == '\n' && o[-2] == '\n'))
            *o++ = *p;
    *o = 0;
    return s;
}

int emit_voice(const Wdf *w, const EmitOpts *opt) {
    Ctx x = {.w = w, .c = w->c, .single = opt->single, .energy = opt->energy, .opt = opt};
    const Circuit *c = w->c;
    index_tree(&x);
    find_idle(&x);
    x.settle = x.nreact || x.nnl || x_probes(c) || (x.energy && x.nsrc);
    x.dcop = dcop_static(&x);
    Buf reset = {0}, probes = {0}, energy = {0}, kirch = {0}, targets = {0}, cases = {0};
    emit_sample(&x);
    emit_hoist(&x);
    {
        /* what process names decides what the roots' solves store */
        Names live = {0};
        Buf d = {0}, wb = {0}, fl = {0};
        sample_text(&x, &live);
        if (x.skip)
            idle_text(&x, &live);
        print_locals(&x, &live, &d, &wb, &fl);
        root_fns(&x, &live);
    }
    emit_update(&x);
    emit_reset(&x, &reset, &probes);
    emit_energy(&x, &energy, &kirch);
    emit_ic_cases(&x, &targets, &cases);
    Buf kernels = {0}, tables = {0}, retune = {0}, force = {0}, wgk = {0};
    emit_nonlinear(&x, &kernels, &tables, &retune, &force);
    if (c->nwgs) {
        emit(&wgk, "%s\nstatic const int wg_tab[][8] = {", tmpl_waveguide);
        for (int w = 0; w < c->nwgs; w++)
            emit(&wgk, "%s{%d, %d, %d, %d, %d, %d, %d, %d}", w ? ", " : "", x.wv_off[w], x.wv_off[w] + x.wv_size[w],
                 x.wv_size[w] - 1, x.wf_off[w], c->wgs[w].nrad, c->wgs[w].M, x.wt_off[w], c->wgs[w].ntaps);
        emit(&wgk, "};\nstatic const int wg_tap[][2] = {");
        for (int t = 0; t < x.nwt; t++)
            emit(&wgk, "%s{%d, %d}", t ? ", " : "", x.wtap_port[2 * t], x.wtap_port[2 * t + 1]);
        emit(&wgk, "%s};\nstatic const int wg_coef[] = {", x.nwt ? "" : "{-1, -1}");
        for (int w = 0; w < c->nwgs; w++)
            emit(&wgk, "%s%d", w ? ", " : "", x.wc_off[w]);
        emit(&wgk, "};\n#define N_WG %d\n#define WG_PREPARED %d\n", c->nwgs, wg_params(c) != 0);
        emit_wg_specs(&x, &wgk);
        emit(&wgk, "%s", tmpl_waveguide_state);
    }
    int nicv;
    const char *ictab = ic_table(&x, &nicv);
    int ncore = 0, nicn = c->nnodes - 1 + nicv, nports = 0, nsrcs = 0;
    for (int b = 0; b < w->nroots; b++) {
        const Root *r = &w->roots[b];
        if (!x.rfn[b]) /* a root with the general solve */
            ncore = r->ncore + r->nx + r->nv > ncore ? r->ncore + r->nx + r->nv : ncore;
        nports += r->nport;
        nsrcs += r->nedge - r->nport - r->nnl;
    }
    Buf rdesc = {0};
    const char *rtab = root_table(&x, &rdesc);
    /* the solve workspace: the general root_solve's and settle's, if any */
    const char *fast = x.settle ? settle_static(&x, force.len > 0, str(&probes)) : NULL;
    int nd = x.settle && !fast && nicn > ncore ? nicn : ncore;
    const char *real = opt->single ? "float" : "double";
    const char *options = format("precision %s%s, rate %g Hz by default", real, x.energy ? ", energy" : "", c->rate);
    const char *summary = format("%d elements, %d nodes; %d adaptors and leaves under %d root adaptors with %d "
                                 "ports, %d nonlinear elements and %d ideal sources in all.", c->nelems, c->nnodes,
                                 w->nnodes, w->nroots, nports, x.nnl, nsrcs);
    char *guard = format("WDV_%s_H", c->name);
    for (char *g = guard; *g; g++)
        *g = (char)(*g >= 'a' && *g <= 'z' ? *g - 32 : *g);
    Buf dtext = {0}, dptrs = {0};
    emit_descriptors(&x, str(&targets), &dtext, &dptrs);
    Holes t = {0};
    bool *gone = arena_alloc(sizeof(bool) * (size_t)(x.nupd + 1));
    const char *ubody = upd_text(&x, NULL), *bare;
    /* twice if update computes what nothing reads: the second time
     * without it (prune_update, reading the voice the first made) */
    for (int pass = 0;; pass++) {
        t.n = 0;
        const char *dirty = update_holes(&x, &t, ubody);
        process_holes(&x, &t, dirty);
        reset_holes(&x, &t, dirty, str(&reset), str(&kirch), str(&cases));
        measure_holes(&x, &t, str(&energy));
        solve_holes(&x, &t, str(&force), str(&retune), str(&probes), nicv);
        const Hole fixed[] = {
            {"name", c->name}, {"version", WDC_VERSION}, {"source", c->path}, {"hash", format("%08x", c->hash)},
            {"options", options}, {"summary", summary}, {"guard", guard}, {"real", real},
            {"precision", opt->single ? "32" : "64"}, {"state_fields", state_fields(&x, nd)},
            {"n_params", format("%d", c->nparams)}, {"n_inputs", format("%d", c->ninputs)},
            {"n_outputs", format("%d", c->nouts)}, {"n_ic_targets", format("%d", x.nic)},
            {"descriptors", str(&dtext)}, {"descriptor_ptrs", str(&dptrs)}, {"root_edges", rtab},
            {"root_desc", str(&rdesc)}, {"ic_elems", ictab}, {"n_icn", format("%d", nicn)}, {"n_icv", format("%d", nicv)},
            {"nl_kernels", str(&kernels)}, {"nl_tables", str(&tables)}, {"wg_fields", wg_fields(c)},
            {"design", design_entries(c)}, {"flush_below", opt->single ? "1e-18f" : "1e-30"},
        };
        for (int i = 0; i < (int)(sizeof fixed / sizeof fixed[0]); i++)
            set(&t, fixed[i].name, fixed[i].text);
        Buf solve = {0};
        bool general = false;
        for (int b = 0; b < w->nroots; b++) {
            general |= !x.rfn[b];
            if (x.rfn[b] && *x.rfn[b])
                emit(&solve, "\n%s", fill_with(x.rfn[b], &t));
        }
        set(&t, "solve", format("%s%s", general ? fill_with(tmpl_root, &t) : "", str(&solve)));
        set(&t, "settle", format("%s%s", x.dcop ? x.dcop : "", fast ? fast : x.settle ? fill_with(tmpl_settle, &t) : ""));
        /* the helpers the rest of the voice names */
        set(&t, "wg_kernels", "");
        set(&t, "helpers", "");
        set(&t, "codes", "");
        bare = fill_with(tmpl_voice_c, &t);
        const char *at = pass ? NULL : strstr(bare, ubody), *pruned = ubody;
        if (at) {
            prune_update(&x, format("%.*s%s%s", (int)(at - bare), bare, at + strlen(ubody), str(&wgk)), gone);
            pruned = upd_text(&x, gone);
        }
        if (!strcmp(pruned, ubody))
            break;
        ubody = pruned;
    }
    t.n -= 3;
    set(&t, "wg_kernels", str(&wgk));
    set(&t, "helpers", helpers(bare, str(&wgk), opt->single));
    set(&t, "codes", codes(bare, str(&wgk)));
    const char *ctext = one_blank(fill_with(tmpl_voice_c, &t));
    const char *fields = used_fields(state_fields(&x, nd), ctext);
    dense_slots(&ctext, &fields);
    set(&t, "state_fields", fields);
    const char *htext = one_blank(fill_with(tmpl_voice_h, &t));
    if (write_text(format("%s/%s.c", opt->outdir, c->name), ctext) ||
        write_text(format("%s/%s.h", opt->outdir, c->name), htext) ||
        write_text(format("%s/wdvoice.h", opt->outdir), tmpl_wdvoice_h))
        return -1;
    return 0;
}
