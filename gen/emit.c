/* emit.c: Wdf -> C text of a voice, through the templates in templates/.
 *
 * Code is generated into memory: each template hole ({{name}}) is filled
 * from a table of strings built here, and the files are written only once
 * all of it succeeded.  The sample loop is straight-line code: a forward
 * pass computing the waves each subtree reflects towards the root, the
 * root's matrix, and a backward pass sending waves down to the leaves. */
#include <math.h>
#include <string.h>

#include "gen.h"

extern const char tmpl_voice_c[], tmpl_voice_h[], tmpl_wdvoice_h[], tmpl_nl_diode_i[], tmpl_nl_wright[], tmpl_nl_diode[], tmpl_nl_omega[],
    tmpl_nl_pwl[], tmpl_nl_law[], tmpl_nl_passive[], tmpl_nl_memory[], tmpl_nl_memcap[], tmpl_waveguide[], tmpl_waveguide_state[];

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

typedef struct Buf {
    char *s;
    size_t len, cap;
} Buf;

static void emit(Buf *b, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void emit(Buf *b, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(NULL, 0, fmt, ap);
    va_end(ap);
    if (b->len + (size_t)n + 1 > b->cap) {
        size_t cap = (b->cap + (size_t)n + 1) * 2;
        char *s = arena_alloc(cap);
        if (b->len)
            memcpy(s, b->s, b->len);
        b->s = s;
        b->cap = cap;
    }
    va_start(ap, fmt);
    vsnprintf(b->s + b->len, (size_t)n + 1, fmt, ap);
    va_end(ap);
    b->len += (size_t)n;
}

static const char *str(Buf *b) { return b->s ? b->s : ""; }

/* ---- emission context ---- */

typedef struct Ctx {
    const Wdf *w;
    const Circuit *c;
    bool single;
    int *react;      /* tree node -> reactance index or -1 */
    int *koff;       /* tree node -> first coefficient in c_k */
    int nk, nreact;
    int *src;        /* element -> source index or -1 */
    int nsrc;
    int *nl_root;    /* nonlinear index -> its root */
    int *nl_edge;    /* nonlinear index -> its edge in that root */
    int *nl_first;   /* root -> nonlinear index of its first nonlinear edge */
    int *moff;       /* root -> offset of its matrix in c_M */
    int nM;          /* entries of all root matrices */
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
} Ctx;

static const char *lit(Ctx *x, double v) {
    char *s = format("%.17g", v);
    if (!strpbrk(s, ".eni"))
        s = format("%s.0", s);
    if (x->single)
        s = format("%sf", s);
    return v < 0 ? format("(%s)", s) : s;
}

static const Elem *nl_elem(Ctx *x, int k) {
    return &x->c->elems[x->w->roots[x->nl_root[k]].edge[x->nl_edge[k]].elem];
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

static void emit_update(Ctx *x, Buf *o) {
    const Circuit *c = x->c;
    for (int i = 0; i < x->w->nnodes; i++) {
        const WNode *n = x->w->nodes[i];
        if (n->kind == W_LEAF) {
            const Elem *e = &c->elems[n->elem];
            const char *v = format("pos(%s)", cexpr(x, e->val));
            emit(o, "    %s /* %s (%s:%d:%d) */\n", guard(n->pmask), e->name, e->pos.file->path,
                 e->pos.line, e->pos.col);
            if (e->kind == E_C)
                emit(o, "        retune(st, %d, %d, T / (2 * %s), 1);\n", n->id, x->react[n->id], v);
            else if (e->kind == E_L)
                emit(o, "        retune(st, %d, %d, 2 * %s / T, 0);\n", n->id, x->react[n->id], v);
            else
                emit(o, "        st->c_R[%d] = (real)%s;\n", n->id, v);
            continue;
        }
        emit(o, "    %s { /* %s adaptor */\n        double t = 0;\n", guard(n->pmask),
             n->kind == W_SERIES ? "series" : "parallel");
        for (int k = 0; k < n->nchild; k++)
            emit(o, n->kind == W_SERIES ? "        t += st->c_R[%d];\n" : "        t += 1.0 / st->c_R[%d];\n",
                 n->child[k]->id);
        emit(o, "        st->c_R[%d] = (real)(%s);\n", n->id, n->kind == W_SERIES ? "t" : "1.0 / t");
        for (int k = 0; k < n->nchild; k++)
            emit(o, n->kind == W_SERIES ? "        st->c_k[%d] = (real)(st->c_R[%d] / t);\n"
                                        : "        st->c_k[%d] = (real)(1.0 / st->c_R[%d] / t);\n",
                 x->koff[n->id] + k, n->child[k]->id);
        emit(o, "    }\n");
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
            emit(o, "    %s { /* %s */\n        const double t_new = %s;\n", guard(expr_params(v[j])), e->name,
                 cexpr(x, v[j]));
            /* a contact held compressed keeps its energy from rising: a
             * stiffer felt is compressed less, a smaller gap keeps the
             * compression */
            if (nl->kind == NL_CONTACT && !nl->mutated && (j == 0 || j == 3))
                emit(o, "        const double t_X = st->s_nX[%d] - st->c_nl[%d], t_old = st->c_nl[%d];\n"
                        "        if (!full && t_X > 0 && t_old > 0 && t_new %s t_old)\n"
                        "            st->s_nX[%d] = (real)(%s);\n", k, 4 * k + 3, 4 * k + j, j == 0 ? ">" : "<", k,
                     j == 0 ? format("st->c_nl[%d] + t_X * pow(t_old / t_new, 1 / (st->c_nl[%d] + 1))", 4 * k + 3, 4 * k + 1)
                            : format("st->s_nX[%d] + t_new - t_old", k));
            emit(o, "        st->c_nl[%d] = (real)t_new;\n    }\n", 4 * k + j);
        }
    }
    for (int b = 0; b < x->w->nroots; b++)
        emit(o, "    %s\n        root_solve(st, %d);\n", guard(x->w->roots[b].pmask), b);
    for (int i = 0; i < c->nelems; i++) {
        const Elem *e = &c->elems[i];
        if (e->kind == E_W && e->peer > i) /* one delay per line */
            emit(o, "    if (full) { /* %s: delay in whole samples */\n"
                    "        double t_d = floor(%.17g * st->fs + 0.5);\n"
                    "        st->c_D[%d] = (unsigned)(t_d < 1 ? 1 : t_d > %d ? %d : t_d);\n    }\n",
                 e->name, e->td, x->line_of[i], x->dl_size[x->line_of[i]] - 1, x->dl_size[x->line_of[i]] - 1);
    }
    for (int w = 0; w < c->nwgs; w++) {
        const Waveguide *g = &c->wgs[w];
        uint64_t mask = expr_params(g->f0) | expr_params(g->Rp) | expr_params(g->B) | expr_params(g->fhf) |
                        (g->t60 ? expr_params(g->t60) : 0) | (g->t60hf ? expr_params(g->t60hf) : 0);
        Buf xs = {0};
        for (int j = 0; j < g->ntaps; j++) {
            mask |= expr_params(g->tap_pos[j]);
            emit(&xs, "%s%s", j ? ", " : "", cexpr(x, g->tap_pos[j]));
        }
        emit(o, "    %s { /* %s (%s:%d:%d) */\n", guard(mask), g->name, g->pos.file->path, g->pos.line, g->pos.col);
        emit(o, "        const wg_spec sp = {st->fs, fmax(%s, %.17g), %s, %s, %s, %s, %.17g, %.17g, %d, %d, %d};\n",
             cexpr(x, g->f0), g->f0_min, cexpr(x, g->B), g->t60 ? cexpr(x, g->t60) : "0.0",
             g->t60hf ? cexpr(x, g->t60hf) : "0.0", cexpr(x, g->fhf), g->nu1,
             g->rad ? expr_eval(g->rad, NULL) : 0.0, g->nrad, g->M, g->nmin);
        emit(o, "        const double x[] = {%s};\n        wg_retune(st, %d, &sp, pos(%s), x);\n    }\n",
             g->ntaps ? str(&xs) : "0.0", w, cexpr(x, g->Rp));
    }
    for (int i = 0; i < c->nelems; i++) {
        const Elem *e = &c->elems[i];
        if (x->src[i] >= 0 && e->input < 0)
            emit(o, "    %s /* %s */\n        st->c_e[%d] = (real)(%s);\n", guard(expr_params(e->drive)),
                 e->name, x->src[i], cexpr(x, e->drive));
    }
}

/* ---- the sample loop ---- */

/* A waveguide port at a tap that a param moves: it may be off its string. */
static bool roams(const Ctx *x, const Elem *e) {
    const Waveguide *g = &x->c->wgs[e->wg];
    return e->pt > 0 && e->pt <= g->ntaps && expr_params(g->tap_pos[e->pt - 1]);
}

/* Each waveguide's right-going wave meets end b through the loop filters;
 * terminated ends reflect. */
static void emit_waveguides(Ctx *x, Buf *o) {
    for (int w = 0; w < x->c->nwgs; w++) {
        const Waveguide *g = &x->c->wgs[w];
        int m = x->wv_size[w] - 1, R = x->wv_off[w], L = R + x->wv_size[w], f = x->wf_off[w];
        emit(o, "        /* %s: the right-going wave meets end b through the loop filters */\n", g->name);
        emit(o, "        real t_wb%d;\n        {\n", w);
        emit(o, "            real t_x = s_wv[%d + ((t_pos - k_wNR%d) & %du)], t_y;\n", R, w, m);
        emit(o, "            t_y = k_wlb%d * t_x - k_wla%d * s_wf%d;\n            s_wq%d = s_wf%d;\n            s_wf%d = t_y;\n"
                "            t_x = t_y;\n", w, w, f, f, f, f);
        int j = f + 1;
        for (int k = 0; k < g->nrad; k++, j++)
            emit(o, "            t_y = (1 + k_wra%d) * t_x - k_wra%d * s_wf%d;\n            s_wq%d = s_wf%d;\n"
                    "            s_wf%d = t_y;\n            t_x = t_y;\n", w, w, j, j, j, j);
        /* the allpass lattice: its top stage in use gives the output, then
         * each stage m down to 1 passes on its rotation; the state of stage
         * m holds the output of stage m - 1 a sample earlier */
        emit(o, "            {\n                real *const t_s = st->s_wf + %d, *const t_q = st->s_wfp + %d;\n"
                "                const real *const t_c = st->c_wf + %d;\n"
                "                const unsigned t_J = %s;\n"
                "                const real t_k = t_c[2 * t_J - 2], t_cc = t_c[2 * t_J - 1], t_sm = t_s[t_J - 1];\n"
                "                t_y = t_k * t_x + t_cc * t_sm;\n"
                "                t_x = t_cc * t_x - t_k * t_sm;\n",
             j, j, x->wc_off[w] + 3, g->M == 1 ? "1u" : format("k_wJ%d", w));
        if (g->M > 1) /* one stage is the fine tuning alone */
            emit(o, "                for (unsigned m = t_J - 1; m >= 1; m--) {\n"
                    "                    const real t_km = t_c[2 * m - 2], t_cm = t_c[2 * m - 1], t_s1 = t_s[m - 1];\n"
                    "                    t_q[m] = t_s[m];\n"
                    "                    t_s[m] = t_km * t_x + t_cm * t_s1;\n"
                    "                    t_x = t_cm * t_x - t_km * t_s1;\n                }\n");
        emit(o, "                t_q[0] = t_s[0];\n                t_s[0] = t_x;\n            }\n"
                "            t_wb%d = t_y;\n        }\n", w);
        for (int e = 0; e < 2; e++) {
            if (g->end[e])
                continue;
            const char *sg = g->term[e] == 'c' ? "" : "-";
            if (e == 0)
                emit(o, "        s_wv[%d + (t_pos & %du)] = flush(%ss_wv[%d + ((t_pos - k_wNL%d) & %du)]); /* end a */\n",
                     R, m, sg, L, w, m);
            else
                emit(o, "        s_wv[%d + (t_pos & %du)] = flush(%st_wb%d); /* end b */\n", L, m, sg, w);
        }
    }
}

static void emit_forward(Ctx *x, Buf *o) {
    const Circuit *c = x->c;
    emit_waveguides(x, o);
    emit(o, "        /* forward: waves reflected towards the root */\n");
    for (int i = 0; i < x->w->nnodes; i++) {
        const WNode *n = x->w->nodes[i];
        if (n->kind == W_LEAF) {
            const Elem *e = &c->elems[n->elem];
            switch (e->kind) {
            case E_R: x->b[i] = "0"; break;
            case E_C: x->b[i] = format("s_a%d", x->react[i]); break;
            case E_L:
                emit(o, "        const real t_b%d = -s_a%d; /* %s */\n", i, x->react[i], e->name);
                x->b[i] = format("t_b%d", i);
                break;
            case E_V: x->b[i] = drive_of(x, e); break;
            case E_I:
                emit(o, "        const real t_b%d = -k_R%d * %s; /* %s */\n", i, i, drive_of(x, e), e->name);
                x->b[i] = format("t_b%d", i);
                break;
            case E_W: {
                int k = x->line_of[n->elem];
                emit(o, "        const real t_b%d = s_dl[%d + ((t_pos - k_D%d) & %du)]; /* %s */\n", i,
                     x->dl_off[e->peer], k, x->dl_size[k] - 1, e->name);
                x->b[i] = format("t_b%d", i);
                break;
            }
            case E_S: {
                int w = e->wg, m = x->wv_size[w] - 1;
                const Waveguide *g = &x->c->wgs[w];
                if (e->side == 0)
                    emit(o, "        const real t_b%d = %s; /* %s */\n", i, e->pt == g->ntaps + 1 ? format("t_wb%d", w)
                         : format("s_wv[%d + ((t_pos - k_wk%d) & %du)]", x->wv_off[w], x->wt_off[w] + e->pt - 1, m), e->name);
                else
                    emit(o, "        const real t_b%d = s_wv[%d + ((t_pos - %s) & %du)]; /* %s */\n", i,
                         x->wv_off[w] + x->wv_size[w], e->pt == 0 ? format("k_wNL%d", w)
                         : format("(k_wNL%d - k_wk%d)", w, x->wt_off[w] + e->pt - 1), m, e->name);
                emit(o, "        s_wpre%d = t_b%d;\n", x->sp_of[n->elem], i);
                x->b[i] = format("t_b%d", i);
                if (roams(x, e)) {
                    /* a tap off its string sends nothing into its junction */
                    emit(o, "        const real t_bo%d = k_won%d ? t_b%d : %s;\n", i, x->wt_off[w] + e->pt - 1, i, lit(x, 0));
                    x->b[i] = format("t_bo%d", i);
                }
                break;
            }
            case E_NL: unreachable();
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
        emit(o, "        const real t_b%d = %s;\n", i, str(&t));
        x->b[i] = format("t_b%d", i);
    }
}

/* input j of the root: b of a port or the drive of a source */
static const char *root_in(Ctx *x, int b, int j) {
    const RootEdge *e = &x->w->roots[b].edge[j];
    if (e->kind == 3)
        return format("t_bn%d", x->nl_first[b] + j - x->w->roots[b].nport);
    return e->kind == 0 ? x->b[e->node->id] : drive_of(x, &x->c->elems[e->elem]);
}

static Solver solver_of(Ctx *x, const NlSpec *nl) {
    return nl->solver != SOLVER_DEFAULT ? nl->solver : x->opt->solver != SOLVER_DEFAULT ? x->opt->solver
                                                                                      : SOLVER_NEWTON;
}

/* The wave a nonlinear edge reflects, from the wave the root sends it. */
static void emit_nl_solve(Ctx *x, Buf *o, int k) {
    const Elem *e = nl_elem(x, k);
    const NlSpec *nl = e->nl;
    const char *tol = format("%.17g", x->opt->tol);
    int it = x->opt->maxit;
    emit(o, "        real t_bn%d; /* %s (%s:%d:%d) */\n", k, e->name, e->pos.file->path, e->pos.line, e->pos.col);
    if (nl->kind == NL_CONTACT && !nl->mutated)
        emit(o, "        int t_open%d;\n", k);
    emit(o, "        {\n");
    if (nl->mutated == 'C') { /* passive stepping of a stored charge: cap_solve */
        emit(o, "            const el_law t_L = %s;\n            double t_v;\n", el_law_init(k, nl, true));
        emit(o, "            s_nf%d = (real)cap_solve(&t_L, t_an%d, k_Rn%d, s_nf%d, s_nv%d, s_nX%d, 0.5 * k_T, %s, %d, &t_v);\n",
             k, k, k, k, k, k, tol, it);
        emit(o, "            s_nX%d = (real)((t_an%d - t_v) / k_Rn%d);\n", k, k, k);
        emit(o, "            s_nv%d = (real)t_v;\n            t_bn%d = (real)(2 * t_v - t_an%d);\n        }\n", k, k, k);
        return;
    }
    if (nl->mutated == 'L' || nl->kind == NL_CONTACT) { /* passive stepping of a stored energy: el_solve */
        const char *solve = format("el_solve(&t_L, t_an%d, k_Rn%d, t_X, s_nv%d, s_nf%d, 0.5 * k_T, %s, %d)", k, k, k,
                                   k, tol, it);
        emit(o, "            const el_law t_L = %s;\n", el_law_init(k, nl, true));
        if (nl->kind == NL_CONTACT) /* open with no force left, and staying open at v = a: a passes */
            emit(o, "            const double t_X = s_nX%d - c_nl%d_3;\n"
                    "            const double t_v = s_nf%d == 0 && !(t_X > 0) && !(t_X + 0.5 * k_T * (t_an%d + s_nv%d) > 0)\n"
                    "                                   ? (double)t_an%d : %s;\n", k, k, k, k, k, k, solve);
        else
            emit(o, "            const double t_X = s_nX%d;\n            const double t_v = %s;\n", k, solve);
        emit(o, "            s_nX%d += k_hT * (real)(t_v + s_nv%d);\n", k, k);
        if (nl->kind == NL_CONTACT)
            emit(o, "            t_open%d = t_v == (double)t_an%d; /* no force: the contact is open */\n"
                    "            (void)t_open%d;\n", k, k, k);
        emit(o, "            s_nf%d = (real)((t_an%d - t_v) / k_Rn%d);\n", k, k, k);
        emit(o, "            s_nv%d = (real)t_v;\n            t_bn%d = (real)(2 * t_v - t_an%d);\n        }\n", k, k, k);
        return;
    }
    switch (solver_of(x, nl)) {
    case SOLVER_PWL:
        emit(o, "            t_bn%d = pwl_map(t_an%d, c_pa%d, c_pb%d, c_ps%d, %d);\n", k, k, k, k, k, x->pwl_n[k]);
        emit(o, "            (void)s_nv%d;\n", k);
        break;
    case SOLVER_OMEGA:
        emit(o, "            const double t_v = diode_omega(t_an%d, k_Rn%d, c_nl%d_0, c_nl%d_1, %d, %s, %d);\n", k, k, k, k,
             nl->pair, tol, it);
        emit(o, "            s_nv%d = (real)t_v;\n            t_bn%d = (real)(2 * t_v - t_an%d);\n", k, k, k);
        break;
    default:
        emit(o, "            const double t_v = diode_newton(t_an%d, k_Rn%d, c_nl%d_0, c_nl%d_1, %d, s_nv%d, %s, %d);\n",
             k, k, k, k, nl->pair, k, tol, it);
        emit(o, "            s_nv%d = (real)t_v;\n            t_bn%d = (real)(2 * t_v - t_an%d);\n", k, k, k);
        break;
    }
    emit(o, "        }\n");
}

static void emit_root(Ctx *x, Buf *o, int b) {
    const Root *r = &x->w->roots[b];
    emit(o, "        /* root %d */\n", b);
    for (int k = r->nport; k < r->nport + r->nnl; k++) {
        Buf t = {0};
        for (int j = 0; j < r->nedge; j++) {
            const char *in = root_in(x, b, j);
            if (j != k && !is_zero(in))
                emit(&t, "%sm%d_%d_%d * %s", t.len ? " + " : "", b, k, j, in);
        }
        int g = x->nl_first[b] + k - r->nport;
        emit(o, "        const real t_an%d = %s;\n", g, t.len ? str(&t) : lit(x, 0));
        emit_nl_solve(x, o, g);
    }
    for (int k = 0; k < r->nedge; k++) {
        if (r->edge[k].kind == 3)
            continue;
        Buf t = {0};
        for (int j = 0; j < r->nedge; j++) {
            const char *in = root_in(x, b, j);
            if (!is_zero(in))
                emit(&t, "%sm%d_%d_%d * %s", t.len ? " + " : "", b, k, j, in);
        }
        const char *v = t.len ? str(&t) : lit(x, 0);
        if (r->edge[k].kind == 0) {
            emit(o, "        const real t_a%d = %s;\n", r->edge[k].node->id, v);
            x->a[r->edge[k].node->id] = format("t_a%d", r->edge[k].node->id);
        } else {
            emit(o, "        const real t_r%d_%d = %s; /* %s of %s */\n", b, k, v,
                 r->edge[k].kind == 1 ? "current" : "voltage", x->c->elems[r->edge[k].elem].name);
        }
    }
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

static void emit_backward(Ctx *x, Buf *o) {
    emit(o, "        /* backward: waves sent to the leaves */\n");
    for (int i = x->w->nnodes - 1; i >= 0; i--) {
        const WNode *n = x->w->nodes[i];
        const char *a = x->a[i], *b = x->b[i];
        if (n->kind == W_LEAF) {
            const Elem *e = &x->c->elems[n->elem];
            x->bpost[i] = b;
            if (e->kind == E_C || e->kind == E_L) {
                int r = x->react[i];
                emit(o, "        s_b%d = %s;\n        s_a%d = %s;\n", r, b, r, a);
                x->bpost[i] = format("s_b%d", r);
            } else if (e->kind == E_W) {
                emit(o, "        s_dl[%d + (t_pos & %du)] = flush(%s); /* %s */\n", x->dl_off[n->elem],
                     x->dl_size[x->line_of[n->elem]] - 1, a, e->name);
            } else if (e->kind == E_S) {
                int open[64], nopen, tk = tap_kind(x, n->elem, open, &nopen);
                if (tk == 1) {
                    /* nothing else meets here: the wave passes untouched */
                    int pe = partner_port(x, n->elem);
                    emit(o, "        (void)t_a%d; /* %s: transparent */\n", i, e->name);
                    x->a[i] = x->b[x->w->leaf_of[pe]->id];
                    x->bpost[i] = b;
                    continue;
                }
                int w = e->wg, m = x->wv_size[w] - 1, tap = x->wt_off[w] + e->pt - 1;
                const Waveguide *g = &x->c->wgs[w];
                const char *d;
                if (e->side == 0) /* writes the left-going line */
                    d = e->pt == g->ntaps + 1 ? "t_pos" : format("(t_pos - (k_wNL%d - k_wk%d))", w, tap);
                else
                    d = e->pt == 0 ? "t_pos" : format("(t_pos - k_wk%d)", tap);
                /* untouched while its contacts are open or it is off its string */
                Buf cond = {0};
                if (roams(x, e))
                    emit(&cond, "k_won%d", tap);
                for (int j = 0; j < nopen; j++)
                    emit(&cond, "%s%st_open%d%s", j ? " && " : cond.len ? " && !(" : "!(", "", open[j],
                         j == nopen - 1 ? ")" : "");
                if (cond.len)
                    emit(o, "        if (%s)\n    ", str(&cond));
                emit(o, "        s_wv[%d + (%s & %du)] = flush(%s); /* %s */\n",
                     x->wv_off[w] + (e->side == 0 ? x->wv_size[w] : 0), d, m, a, e->name);
            } else {
                emit(o, "        (void)%s; /* %s */\n", a, e->name);
            }
            continue;
        }
        if (n->kind == W_SERIES) {
            emit(o, "        const real t_d%d = %s%s%s;\n", i, a, is_zero(b) ? "" : " - ", is_zero(b) ? "" : b);
            for (int k = 0; k < n->nchild; k++) {
                int cid = n->child[k]->id;
                const char *bc = x->b[cid];
                emit(o, "        const real t_a%d = %s%s%sc_k%d * t_d%d;\n", cid, is_zero(bc) ? "" : bc,
                     n->pol[k] > 0 ? (is_zero(bc) ? "" : " + ") : (is_zero(bc) ? "-" : " - "), "",
                     x->koff[i] + k, i);
                x->a[cid] = format("t_a%d", cid);
            }
        } else {
            emit(o, "        const real t_s%d = %s%s%s;\n", i, a, is_zero(b) ? "" : " + ", is_zero(b) ? "" : b);
            for (int k = 0; k < n->nchild; k++) {
                int cid = n->child[k]->id;
                const char *bc = x->b[cid];
                emit(o, "        const real t_a%d = %st_s%d%s%s;\n", cid, n->pol[k] > 0 ? "" : "-", i,
                     is_zero(bc) ? "" : " - ", is_zero(bc) ? "" : bc);
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

static void emit_outputs(Ctx *x, Buf *o) {
    const Circuit *c = x->c;
    int xp = 0;
    emit(o, "        /* outputs */\n");
    for (int k = 0; k < c->nouts; k++) {
        const Probe *p = &c->outs[k];
        switch (p->kind) {
        case PR_V: emit(o, "        out[%d][n] = (double)(%s);\n", k, pair_v(x, p->n)); break;
        case PR_I: case PR_F: emit(o, "        out[%d][n] = (double)(%s);\n", k, elem_i(x, p->elem)); break;
        case PR_X:
            emit(o, "        {\n            const real t_v = %s;\n", pair_v(x, p->n));
            emit(o, "            s_x%d += 0.5 * k_T * ((double)t_v + (double)s_xv%d);\n            s_xv%d = t_v;\n", xp, xp, xp);
            emit(o, "            out[%d][n] = (double)s_x%d;\n        }\n", k, xp);
            xp++;
            break;
        }
    }
}

/* work done by the sources, trapezoidal averages: W += -T (e+e')(i+i')/4 */
static void emit_work(Ctx *x, Buf *o) {
    const Circuit *c = x->c;
    if (!x->nsrc)
        return;
    emit(o, "        /* work of the sources */\n");
    for (int i = 0; i < c->nelems; i++) {
        int s = x->src[i];
        if (s < 0)
            continue;
        const Elem *e = &c->elems[i];
        const char *dr = drive_of(x, e), *other = e->kind == E_V ? elem_i(x, i) : elem_v(x, i);
        emit(o, "        {\n            const real t_o = %s;\n", other);
        emit(o, "            s_work += k_qT * (double)(%s + s_we%d) * (double)(t_o + s_wi%d);\n", dr, s, s);
        emit(o, "            s_we%d = %s;\n            s_wi%d = t_o;\n        }\n", s, dr, s);
    }
}

/* ---- hoisting and write-back ---- */

static void emit_hoist(Ctx *x, Buf *o, Buf *wb, Buf *fl) {
    const Circuit *c = x->c;
    emit(o, "    const real k_hT = (real)(0.5 / st->fs);\n    const double k_qT = -0.25 / st->fs;\n");
    emit(o, "    double s_work = st->s_work;\n    (void)k_hT;\n    (void)k_qT;\n");
    emit(wb, "    st->s_work = s_work;\n");
    if (x->nline || c->nwgs) {
        emit(o, "    unsigned t_pos = st->s_pos;\n    real *const s_dl = st->s_dl;\n    real *const s_wv = st->s_wv;\n");
        emit(o, "    (void)s_dl;\n    (void)s_wv;\n");
        for (int k = 0; k < x->nline; k++)
            emit(o, "    const unsigned k_D%d = st->c_D[%d];\n", k, k);
        emit(wb, "    st->s_pos = t_pos;\n");
    }
    for (int w = 0; w < c->nwgs; w++) {
        emit(o, "    const unsigned k_wNR%d = st->c_wN[%d], k_wNL%d = st->c_wN[%d];\n    (void)k_wNL%d;\n", w, 2 * w, w,
             2 * w + 1, w);
        static const char *cf[] = {"lb", "la", "ra"};
        for (int j = 0; j < 3; j++)
            emit(o, "    const real k_w%s%d = st->c_wf[%d];\n    (void)k_w%s%d;\n", cf[j], w, x->wc_off[w] + j, cf[j], w);

        for (int j = 0; j < c->wgs[w].ntaps; j++) {
            int t = x->wt_off[w] + j;
            emit(o, "    const unsigned k_wk%d = st->c_wk[%d];\n    const int k_won%d = st->c_won[%d];\n    (void)k_won%d;\n",
                 t, t, t, t, t);
        }
    }
    for (int w = 0; w < c->nwgs; w++) {
        int f0 = x->wf_off[w], nl = 1 + c->wgs[w].nrad;
        for (int f = f0; f < f0 + nl; f++) { /* one-poles: locals */
            emit(o, "    real s_wf%d = st->s_wf[%d], s_wq%d = st->s_wfp[%d];\n", f, f, f, f);
            emit(wb, "    st->s_wf[%d] = s_wf%d;\n    st->s_wfp[%d] = s_wq%d;\n", f, f, f, f);
            emit(fl, "        s_wf%d = flush(s_wf%d);\n        s_wq%d = flush(s_wq%d);\n", f, f, f, f);
        }
        emit(o, "    const unsigned k_wJ%d = st->c_wJ[%d];\n    (void)k_wJ%d;\n", w, w, w);
        emit(fl, "        for (int m = %d; m < %d; m++) {\n            st->s_wf[m] = flush(st->s_wf[m]);\n"
                 "            st->s_wfp[m] = flush(st->s_wfp[m]);\n        }\n", f0 + nl, f0 + nl + c->wgs[w].M);
    }
    for (int k = 0; k < x->nsp; k++) {
        emit(o, "    real s_wpre%d = st->s_wpre[%d];\n", k, k);
        emit(wb, "    st->s_wpre[%d] = s_wpre%d;\n", k, k);
    }
    emit(o, "    const double k_T = 1.0 / st->fs;\n    (void)k_T;\n");
    for (int k = 0; k < x->nnl; k++) {
        emit(o, "    const real k_Rn%d = st->c_Rn[%d], k_gn%d = (real)(0.5 / st->c_Rn[%d]);\n", k, k, k, k);
        emit(o, "    (void)k_Rn%d;\n    (void)k_gn%d;\n", k, k);
        for (int j = 0; j < 4; j++)
            emit(o, "    const double c_nl%d_%d = st->c_nl[%d];\n    (void)c_nl%d_%d;\n", k, j, 4 * k + j, k, j);
        emit(o, "    real s_nX%d = st->s_nX[%d], s_nv%d = st->s_nv[%d], s_nf%d = st->s_nf[%d];\n    (void)s_nf%d;\n", k,
             k, k, k, k, k, k);
        emit(wb, "    st->s_nX[%d] = s_nX%d;\n    st->s_nv[%d] = s_nv%d;\n    st->s_nf[%d] = s_nf%d;\n", k, k, k, k, k, k);
        emit(fl, "        s_nX%d = flush(s_nX%d);\n        s_nv%d = flush(s_nv%d);\n        s_nf%d = flush(s_nf%d);\n", k,
             k, k, k, k, k);
        if (x->pwl_n[k])
            emit(o, "    const real *const c_pa%d = st->c_pa + %d, *const c_pb%d = st->c_pb + %d, "
                    "*const c_ps%d = st->c_ps + %d;\n", k, x->pwl_off[k], k, x->pwl_off[k], k, x->pwl_off[k]);
    }
    for (int i = 0; i < c->ninputs; i++)
        emit(o, "    const double *const in%d = in[%d];\n", i, i);
    for (int i = 0; i < x->nk; i++)
        emit(o, "    const real c_k%d = st->c_k[%d];\n    (void)c_k%d;\n", i, i, i);
    for (int b = 0; b < x->w->nroots; b++) {
        const Root *r = &x->w->roots[b];
        for (int k = 0; k < r->nedge; k++)
            for (int j = 0; j < r->nedge; j++)
                emit(o, "    const real m%d_%d_%d = st->c_M[%d];\n    (void)m%d_%d_%d;\n", b, k, j,
                     x->moff[b] + k * r->nedge + j, b, k, j);
    }
    for (int i = 0; i < x->w->nnodes; i++) {
        emit(o, "    const real k_R%d = st->c_R[%d], k_g%d = (real)(0.5 / st->c_R[%d]);\n", i, i, i, i);
        emit(o, "    (void)k_R%d;\n    (void)k_g%d;\n", i, i);
    }
    for (int i = 0; i < c->nelems; i++)
        if (x->src[i] >= 0 && c->elems[i].input < 0)
            emit(o, "    const real c_e%d = st->c_e[%d];\n    (void)c_e%d;\n", x->src[i], x->src[i], x->src[i]);
    for (int r2 = 0; r2 < x->nreact; r2++) {
        emit(o, "    real s_a%d = st->s_a[%d], s_b%d = st->s_b[%d];\n", r2, r2, r2, r2);
        emit(wb, "    st->s_a[%d] = s_a%d;\n    st->s_b[%d] = s_b%d;\n", r2, r2, r2, r2);
        emit(fl, "        s_a%d = flush(s_a%d);\n        s_b%d = flush(s_b%d);\n", r2, r2, r2, r2);
    }
    int xp = 0;
    for (int k = 0; k < c->nouts; k++)
        if (c->outs[k].kind == PR_X) {
            emit(o, "    double s_x%d = st->s_x[%d];\n    real s_xv%d = st->s_xv[%d];\n", xp, xp, xp, xp);
            emit(wb, "    st->s_x[%d] = s_x%d;\n    st->s_xv[%d] = s_xv%d;\n", xp, xp, xp, xp);
            emit(fl, "        s_xv%d = flush(s_xv%d);\n", xp, xp);
            xp++;
        }
    for (int s = 0; s < x->nsrc; s++) {
        emit(o, "    real s_we%d = st->s_we[%d], s_wi%d = st->s_wi[%d];\n", s, s, s, s);
        emit(wb, "    st->s_we[%d] = s_we%d;\n    st->s_wi[%d] = s_wi%d;\n", s, s, s, s);
    }
}

/* ---- reset, initial conditions, energy ---- */

static int x_probes(const Circuit *c) {
    int n = 0;
    for (int k = 0; k < c->nouts; k++)
        n += c->outs[k].kind == PR_X;
    return n;
}

static const char *ic_node_value(Ctx *x, char fn, int node) {
    if (node == 0)
        return "0";
    for (int i = 0; i < x->c->nics; i++)
        if (x->c->ics[i].fn == fn && x->c->ics[i].node == node)
            return format("(%s)", cexpr(x, x->c->ics[i].val));
    return "0";
}

static void emit_reset(Ctx *x, Buf *o, Buf *probes) {
    const Circuit *c = x->c;
    for (int i = 0; i < c->nelems; i++) {
        const Elem *e = &c->elems[i];
        WNode *n = x->w->leaf_of[i];
        if (e->ic && n)
            emit(o, "    react[%d] = %s; /* %s */\n", x->react[n->id], cexpr(x, e->ic), e->name);
        if (x->src[i] >= 0 && e->input < 0)
            emit(o, "    st->s_we[%d] = st->c_e[%d];\n", x->src[i], x->src[i]);
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
        emit(probes, e->nl->mutated == 'C' ? "        st->s_nf[%d] = st->s_nv[%d];\n"
                                           : "        st->s_nf[%d] = (real)nl_force(st, %d);\n", k, k);
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
    emit(o, "    settle(st, react);\n");
}

static void emit_energy(Ctx *x, Buf *o, Buf *kirch) {
    for (int w = 0; w < x->c->nwgs; w++)
        emit(o, "    E += wg_energy(st, %d); /* %s */\n", w, x->c->wgs[w].name);
    for (int i = 0; i < x->c->nelems; i++) {
        const Elem *e = &x->c->elems[i];
        if (e->kind != E_W)
            continue;
        int k = x->line_of[i];
        /* The trapezoidal rule balances reactances against the power of
         * two-sample averages of v and i; in those terms a line delays the
         * averaged wave (a[m] + a[m-1]) / 2, each carrying T a^2 / (4 Z0). */
        emit(o, "    { /* %s: the waves in flight */\n"
                "        double s = 0;\n"
                "        for (unsigned m = 1; m <= st->c_D[%d]; m++) {\n"
                "            double a = st->s_dl[%d + ((st->s_pos - m) & %du)] + st->s_dl[%d + ((st->s_pos - m - 1) & %du)];\n"
                "            s += 0.25 * a * a;\n"
                "        }\n"
                "        E += s / (4 * st->fs * st->c_R[%d]);\n    }\n",
             e->name, k, x->dl_off[i], x->dl_size[k] - 1, x->dl_off[i], x->dl_size[k] - 1, x->w->leaf_of[i]->id);
    }
    for (int k = 0; k < x->nnl; k++) {
        const Elem *e = nl_elem(x, k);
        if (e->nl->mutated == 'L')
            emit(o, "    { const double c_nl%d_0 = st->c_nl[%d], c_nl%d_1 = st->c_nl[%d]; (void)c_nl%d_0; (void)c_nl%d_1; "
                    "E += mem_G(st->s_nX[%d], %s); }\n", k, 4 * k, k, 4 * k + 1, k, k, k, mem_args(k, e->nl));
        if (e->nl->mutated == 'C')
            emit(o, "    { const double c_nl%d_0 = st->c_nl[%d], c_nl%d_1 = st->c_nl[%d], v = st->s_nf[%d]; double d; "
                    "(void)c_nl%d_0; (void)c_nl%d_1; E += v * mem_g(v, %s, &d) - mem_G(v, %s); }\n",
                 k, 4 * k, k, 4 * k + 1, k, k, k, mem_args(k, e->nl), mem_args(k, e->nl));
        if (e->nl->kind == NL_CONTACT)
            emit(o, "    { double X = st->s_nX[%d] - st->c_nl[%d], al = st->c_nl[%d]; "
                    "if (X > 0) E += st->c_nl[%d] * pow(X, al + 1) / (al + 1); } /* %s */\n",
                 k, 4 * k + 3, 4 * k + 1, 4 * k, e->name);
    }
    for (int i = 0; i < x->w->nnodes; i++) {
        int r = x->react[i];
        if (r < 0)
            continue;
        bool cap = x->c->elems[x->w->nodes[i]->elem].kind == E_C;
        emit(kirch, "    react[%d] = %s;\n", r,
             cap ? format("0.5 * (st->s_a[%d] + st->s_b[%d])", r, r)
                 : format("0.5 * (st->s_a[%d] - st->s_b[%d]) / st->c_R[%d]", r, r, i));
        if (cap)
            emit(o, "    { double v = 0.5 * (st->s_a[%d] + st->s_b[%d]); E += 0.25 / (st->fs * st->c_R[%d]) * v * v; }\n",
                 r, r, i);
        else
            emit(o, "    { double i = 0.5 * (st->s_a[%d] - st->s_b[%d]) / st->c_R[%d]; E += 0.25 * st->c_R[%d] / st->fs * i * i; }\n",
                 r, r, i, i);
    }
}

/* strike targets: v(node) sets capacitors from node to ground, x(node)
 * sets inductors from node to ground and the node's displacement probes */
static void emit_ic_cases(Ctx *x, Buf *targets, Buf *cases) {
    const Circuit *c = x->c;
    int id = 0;
    for (int nd = 1; nd < c->nnodes; nd++)
        for (int f = 0; f < 2; f++, id++) {
            char fn = f ? 'x' : 'v';
            emit(targets, "%s{\"%c(%s)\", \"%s\"}", id ? ", " : "", fn, c->nodes[nd], domain_unit(c->domain, fn));
            emit(cases, "        case %d: /* %c(%s) */\n", id, fn, c->nodes[nd]);
            for (int i = 0; i < x->w->nnodes; i++) {
                const WNode *n = x->w->nodes[i];
                if (x->react[i] < 0)
                    continue;
                const Elem *e = &c->elems[n->elem];
                int sg = e->n[0] == nd && e->n[1] == 0 ? 1 : e->n[1] == nd && e->n[0] == 0 ? -1 : 0;
                if (!sg || (e->kind == E_C) != (fn == 'v'))
                    continue;
                if (e->kind == E_C)
                    emit(cases, "            react[%d] = %s values[k];\n", x->react[i], sg > 0 ? "" : "-");
                else
                    emit(cases, "            react[%d] = %s values[k] / (0.5 * st->c_R[%d] / st->fs);\n",
                         x->react[i], sg > 0 ? "" : "-", i);
            }
            /* a contact's compression is set from either of its nodes: its
             * distance from what it strikes, negative while apart */
            for (int k = 0; k < x->nnl && fn == 'x'; k++) {
                const Elem *e = nl_elem(x, k);
                int sg = e->n[0] == nd ? 1 : e->n[1] == nd ? -1 : 0;
                if (sg && e->nl->kind == NL_CONTACT)
                    emit(cases, "            st->s_nX[%d] = (real)(%svalues[k]);\n", k, sg > 0 ? "" : "-");
            }
            int xp = 0;
            for (int k = 0; k < c->nouts; k++)
                if (c->outs[k].kind == PR_X) {
                    if (fn == 'x' && c->outs[k].n[0] == nd && c->outs[k].n[1] == 0)
                        emit(cases, "            st->s_x[%d] = values[k];\n", xp);
                    xp++;
                }
            emit(cases, "            break;\n");
        }
}

/* ---- nonlinear elements: kernels, tables, hooks ---- */

static void emit_nonlinear(Ctx *x, Buf *kernels, Buf *tables, Buf *retune, Buf *force) {
    bool diode = false, omega = false, pwl = false, contact = false, memory = false, inductor = false,
         capacitor = false;
    for (int k = 0; k < x->nnl; k++) {
        const Elem *e = nl_elem(x, k);
        if (e->nl->mutated) {
            memory = true;
            inductor |= e->nl->mutated == 'L';
            capacitor |= e->nl->mutated == 'C';
            if (e->nl->kind == NL_CURVE) {
                Buf v = {0}, i = {0};
                for (int j = 0; j < e->nl->npts; j++) {
                    emit(&v, "%s%.17g", j ? ", " : "", e->nl->cv[j]);
                    emit(&i, "%s%.17g", j ? ", " : "", e->nl->ci[j]);
                }
                emit(tables, "/* %s: its inner resistor's curve (V, A) */\n", e->name);
                emit(tables, "static const double mem_v%d[] = {%s};\nstatic const double mem_i%d[] = {%s};\n", k,
                     str(&v), k, str(&i));
            }
            if (e->nl->mutated == 'L')
                emit(force, "    if (k == %d) { const double c_nl%d_0 = st->c_nl[%d], c_nl%d_1 = st->c_nl[%d]; double d; "
                            "(void)c_nl%d_0; (void)c_nl%d_1; return mem_g(st->s_nX[%d], %s, &d); }\n",
                     k, k, 4 * k, k, 4 * k + 1, k, k, k, mem_args(k, e->nl));
        } else if (e->nl->kind == NL_CONTACT) {
            contact = true;
            emit(force, "    if (k == %d) { const el_law L = %s; double d; return el_F(&L, st->s_nX[%d] - st->c_nl[%d], &d); }\n",
                 k, el_law_init(k, e->nl, false), k, 4 * k + 3);
        } else if (x->pwl_n[k]) {
            pwl = true;
            Buf v = {0}, i = {0};
            for (int j = 0; j < x->pwl_n[k]; j++) {
                emit(&v, "%s%.17g", j ? ", " : "", x->pwl_v[k][j]);
                emit(&i, "%s%.17g", j ? ", " : "", x->pwl_i[k][j]);
            }
            emit(tables, "/* %s: Kirchhoff points of its piecewise-linear map (V, A) */\n", e->name);
            emit(tables, "static const double nl_v%d[] = {%s};\nstatic const double nl_i%d[] = {%s};\n", k, str(&v),
                 k, str(&i));
            emit(retune, "    pwl_table(nl_v%d, nl_i%d, %d, st->c_Rn[%d], st->c_pa + %d, st->c_pb + %d, st->c_ps + %d);\n",
                 k, k, x->pwl_n[k], k, x->pwl_off[k], x->pwl_off[k], x->pwl_off[k]);
        } else {
            diode = true;
            omega |= solver_of(x, e->nl) == SOLVER_OMEGA;
        }
    }
    if (diode || memory)
        emit(kernels, "%s", tmpl_nl_diode_i);
    if (diode)
        emit(kernels, "%s%s", tmpl_nl_wright, tmpl_nl_diode);
    if (omega)
        emit(kernels, "%s", tmpl_nl_omega);
    if (pwl)
        emit(kernels, "%s", tmpl_nl_pwl);
    if (memory)
        emit(kernels, "%s", tmpl_nl_memory);
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
/* The params a waveguide's loop design depends on: the voice redesigns the
 * loop when one moves, so a host steps them rather than ramping them
 * (WDV_PARAM_STEP). */
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
                 (step_params(c) >> i) & 1 ? "WDV_PARAM_STEP" : "0");
        }
    }
    if (n == 0)
        emit(&b, which == 'p' ? "{\"\", \"\", 0, 0, 0, 0}" : "{\"\", \"\"}");
    emit(&b, "}");
    return str(&b);
}

/* The edges of every root, one after the other, and per root: first
 * edge, edge count, nodal unknowns, ideal V sources, matrix offset. */
static const char *root_table(Ctx *x, Buf *desc) {
    Buf b = {0};
    emit(&b, "{");
    emit(desc, "{");
    int first = 0;
    for (int rb = 0; rb < x->w->nroots; rb++) {
        const Root *r = &x->w->roots[rb];
        for (int k = 0; k < r->nedge; k++) {
            const RootEdge *e = &r->edge[k];
            emit(&b, "%s{%d, %d, %d, %d}", first + k ? ", " : "", e->kind, e->p, e->q,
                 e->kind == 0 ? e->node->id : e->kind == 3 ? x->nl_first[rb] + k - r->nport : -1);
        }
        emit(desc, "%s{%d, %d, %d, %d, %d}", rb ? ", " : "", first, r->nedge, r->ncore + r->nv, r->nv, x->moff[rb]);
        first += r->nedge;
    }
    emit(&b, "}");
    emit(desc, "}");
    return str(&b);
}

static const char *ic_table(Ctx *x, int *nv) {
    const Circuit *c = x->c;
    Buf b = {0};
    emit(&b, "{");
    *nv = 0;
    for (int i = 0; i < c->nelems; i++) {
        const Elem *e = &c->elems[i];
        WNode *n = x->w->leaf_of[i];
        int kind;
        switch (e->kind) {
        case E_R: kind = 0; break;
        case E_C: kind = 1; break;
        case E_L: kind = 2; break;
        case E_V: kind = e->val ? 5 : 3; break;
        case E_I: kind = e->val ? 6 : 4; break;
        case E_NL: kind = e->nl->kind == NL_CONTACT || e->nl->mutated == 'L' ? 8 : 7; break;
        case E_W: kind = 0; break; /* an empty line looks like its Z0 */
        case E_S: kind = 9; break; /* its last incoming wave behind its port resistance */
        default: unreachable();
        }
        *nv += kind == 1 || kind == 3;
        int nli = -1;
        for (int k = 0; k < x->nnl; k++)
            if (nl_elem(x, k) == e)
                nli = k;
        emit(&b, "%s{%d, %d, %d, %d, %d, %d}", i ? ", " : "", kind, e->n[0], e->n[1], n ? n->id : -1,
             e->kind == E_S ? x->sp_of[i] : n ? x->react[n->id] : nli, x->src[i]);
    }
    emit(&b, "}");
    return str(&b);
}

static const char *state_fields(Ctx *x, int nd) {
    const Circuit *c = x->c;
    const char *r = format("%s_real", c->name);
    int nx = x_probes(c);
#define M1(n) ((n) > 0 ? (n) : 1)
    return format(
        "    double p[%d];          /* param values */\n"
        "    unsigned long long dirty; /* params changed since the last coefficient update */\n"
        "    double fs;             /* sample rate, Hz */\n"
        "    %s c_R[%d];     /* port resistance of each tree node */\n"
        "    %s c_k[%d];     /* adaptor coefficients */\n"
        "    %s c_M[%d];     /* root adaptor matrix */\n"
        "    %s c_e[%d];     /* control-rate source drives */\n"
        "    %s s_a[%d];     /* reactances: last incident wave */\n"
        "    %s s_b[%d];     /* reactances: last reflected wave */\n"
        "    double s_x[%d];        /* displacement probes (double: an integral gathers rounding) */\n"
        "    %s s_xv[%d];    /* displacement probes: last velocity */\n"
        "    %s s_we[%d];    /* sources: last drive */\n"
        "    %s s_wi[%d];    /* sources: last current (V) or voltage (I) */\n"
        "    double s_work;         /* work done by the sources since reset */\n"
        "    %s c_Rn[%d];    /* nonlinear edges: adapted port resistance */\n"
        "    %s c_nl[%d];    /* nonlinear edges: Is, n Vt (diode) or k, alpha, lambda, gap (contact) */\n"
        "    %s s_nX[%d];    /* contacts: x(n0) - x(n1), m */\n"
        "    %s s_nv[%d];    /* nonlinear edges: last voltage (velocity) across */\n"
        "    %s s_nf[%d];    /* contacts, nonlinear inductors: last current (force); capacitors: voltage of the charge */\n"
        "    %s c_pa[%d];    /* piecewise-linear wave maps: a at the breakpoints */\n"
        "    %s c_pb[%d];    /* b at the breakpoints */\n"
        "    %s c_ps[%d];    /* slope db/da of each segment */\n"
        "    %s s_dl[%d];    /* transmission lines: the waves that entered each end */\n"
        "    unsigned s_pos;        /* transmission lines: next write position */\n"
        "    unsigned c_D[%d];      /* transmission lines: delay in samples */\n"
        "    %s s_wv[%d];    /* waveguides: right- and left-going lines */\n"
        "    unsigned c_wN[%d];     /* waveguides: whole samples of each line */\n"
        "    unsigned c_wJ[%d];     /* waveguides: stages of the allpass lattice in use */\n"
        "    unsigned c_wk[%d];     /* waveguide taps: samples from end a */\n"
        "    int c_won[%d];         /* waveguide taps: on their string (a moving tap may leave it) */\n"
        "    double c_wR[%d];       /* waveguides: port resistance */\n"
        "    %s c_wf[%d];    /* waveguides: loss b and a, radiation a, allpass lattice k and c */\n"
        "    double c_ww[%d];       /* waveguides: storage weights of their filters */\n"
        "    %s s_wf[%d];    /* waveguide filters: states */\n"
        "    %s s_wfp[%d];   /* waveguide filters: states a sample earlier */\n"
        "    %s s_wpre[%d];  /* waveguide ports: the wave that last arrived */\n"
        "    double w_A[%d];        /* solve workspace (control rate only) */\n"
        "    double w_x[%d];\n"
        "    int w_piv[%d];",
        M1(c->nparams), r, M1(x->w->nnodes), r, M1(x->nk), r, x->nM, r, M1(x->nsrc), r, M1(x->nreact), r,
        M1(x->nreact), M1(nx), r, M1(nx), r, M1(x->nsrc), r, M1(x->nsrc), r, M1(x->nnl), r, M1(4 * x->nnl),
        r, M1(x->nnl), r, M1(x->nnl), r, M1(x->nnl), r, M1(x->npwl), r, M1(x->npwl), r, M1(x->npwl), r, M1(x->ndl), M1(x->nline),
        r, M1(x->nwv), M1(2 * c->nwgs), M1(c->nwgs), M1(x->nwt), M1(x->nwt), M1(c->nwgs), r, M1(x->nwc), M1(2 * c->nwgs), r, M1(x->nwf),
        r, M1(x->nwf), r, M1(x->nsp), nd * nd, nd, nd);
#undef M1
}

/* ---- templates ---- */

const char *fill(const char *tmpl, const Hole *holes, int n) {
    Buf b = {0};
    for (const char *p = tmpl; *p;) {
        const char *h = strstr(p, "{{");
        if (!h) {
            emit(&b, "%s", p);
            break;
        }
        emit(&b, "%.*s", (int)(h - p), p);
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
        emit(&b, "%s", text);
        p = e + 2;
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
                 "not depend on params (use solver=newton or omega)", e->name);
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
        if (n->kind == W_LEAF && (c->elems[n->elem].kind == E_C || c->elems[n->elem].kind == E_L))
            x->react[i] = x->nreact++;
        x->koff[i] = x->nk;
        if (n->kind != W_LEAF)
            x->nk += n->nchild;
    }
    x->nl_first = arena_alloc(sizeof(int) * (size_t)(w->nroots + 1));
    x->moff = arena_alloc(sizeof(int) * (size_t)(w->nroots + 1));
    for (int b = 0; b < w->nroots; b++) {
        x->nl_first[b] = x->nnl;
        x->nnl += w->roots[b].nnl;
        x->moff[b] = x->nM;
        x->nM += w->roots[b].nedge * w->roots[b].nedge;
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
        if (e->nl->kind == NL_CONTACT || solver_of(x, e->nl) != SOLVER_PWL)
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
            double fmax = c->rate * 4 > 192000 ? c->rate * 4 : 192000;
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
        double fmax = c->rate * 4 > 192000 ? c->rate * 4 : 192000;
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
    for (int i = 0; i < c->nelems; i++)
        x->src[i] = c->elems[i].kind == E_V || c->elems[i].kind == E_I ? x->nsrc++ : -1;
}

int emit_voice(const Wdf *w, const EmitOpts *opt) {
    Ctx x = {.w = w, .c = w->c, .single = opt->single, .opt = opt};
    const Circuit *c = w->c;
    index_tree(&x);
    Buf update = {0}, sample = {0}, hoist = {0}, wb = {0}, flushes = {0}, reset = {0}, probes = {0}, energy = {0},
        kirch = {0}, targets = {0}, cases = {0};
    emit_update(&x, &update);
    for (int i = 0; i < c->ninputs; i++)
        emit(&sample, "        const real t_in%d = (real)in%d[n];\n", i, i);
    emit_forward(&x, &sample);
    for (int b = 0; b < w->nroots; b++)
        emit_root(&x, &sample, b);
    emit_backward(&x, &sample);
    emit_outputs(&x, &sample);
    emit_work(&x, &sample);
    if (x.nline || c->nwgs)
        emit(&sample, "        t_pos++;\n");
    emit_hoist(&x, &hoist, &wb, &flushes);
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
        emit(&wgk, "};\n%s", tmpl_waveguide_state);
    }
    int nicv;
    const char *ictab = ic_table(&x, &nicv);
    int ncore = 0, nicn = c->nnodes - 1 + nicv, nports = 0, nsrcs = 0;
    for (int b = 0; b < w->nroots; b++) {
        const Root *r = &w->roots[b];
        ncore = r->ncore + r->nv > ncore ? r->ncore + r->nv : ncore;
        nports += r->nport;
        nsrcs += r->nedge - r->nport - r->nnl;
    }
    Buf rdesc = {0};
    const char *rtab = root_table(&x, &rdesc);
    int nd = ncore > nicn ? ncore : nicn;
    const char *real = opt->single ? "float" : "double";
    const char *options = format("precision %s, rate %g Hz by default", real, c->rate);
    const char *summary = format("%d elements, %d nodes; %d adaptors and leaves under %d root adaptors with %d "
                                 "ports, %d nonlinear elements and %d ideal sources in all.", c->nelems, c->nnodes,
                                 w->nnodes, w->nroots, nports, x.nnl, nsrcs);
    char *guard = format("WDV_%s_H", c->name);
    for (char *g = guard; *g; g++)
        *g = (char)(*g >= 'a' && *g <= 'z' ? *g - 32 : *g);
    Hole holes[] = {
        {"name", c->name}, {"version", WDC_VERSION}, {"source", c->path}, {"hash", format("%08x", c->hash)},
        {"options", options}, {"summary", summary}, {"guard", guard}, {"real", real},
        {"state_fields", state_fields(&x, nd)}, {"n_params", format("%d", c->nparams)},
        {"n_roots", format("%d", w->nroots)}, {"n_work", format("%d", nd)}, {"root_desc", str(&rdesc)},
        {"n_icn", format("%d", nicn)}, {"n_icv", format("%d", nicv)},
        {"inputs", descriptors(&x, 'i')}, {"outputs", descriptors(&x, 'o')}, {"params", descriptors(&x, 'p')},
        {"ic_targets", format("{%s}", str(&targets))}, {"n_ic_targets", format("%d", 2 * (c->nnodes - 1))},
        {"root_edges", rtab}, {"ic_elems", ictab}, {"update", str(&update)},
        {"settle_probes", str(&probes)}, {"n_react_arr", format("%d", x.nreact > 0 ? x.nreact : 1)},
        {"reset", str(&reset)}, {"energy", str(&energy)}, {"kirchhoff", str(&kirch)},
        {"ic_cases", str(&cases)}, {"hoist", str(&hoist)}, {"sample", str(&sample)},
        {"writeback", str(&wb)}, {"precision", opt->single ? "32" : "64"},
        {"n_inputs", format("%d", c->ninputs)}, {"n_outputs", format("%d", c->nouts)},
        {"nl_kernels", str(&kernels)}, {"nl_tables", str(&tables)}, {"nl_retune", str(&retune)},
        {"nl_force", str(&force)}, {"flush", str(&flushes)}, {"wg_kernels", str(&wgk)},
        {"flush_below", opt->single ? "1e-18f" : "1e-30"},
    };
    int nh = (int)(sizeof holes / sizeof holes[0]);
    const char *ctext = fill(tmpl_voice_c, holes, nh);
    const char *htext = fill(tmpl_voice_h, holes, nh);
    if (write_text(format("%s/%s.c", opt->outdir, c->name), ctext) ||
        write_text(format("%s/%s.h", opt->outdir, c->name), htext) ||
        write_text(format("%s/wdvoice.h", opt->outdir), tmpl_wdvoice_h))
        return -1;
    return 0;
}
