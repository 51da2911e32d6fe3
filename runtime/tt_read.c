/*
 * tt_read.c - timbre trees: reading .tt text into trees of tt_node,
 * checking them, printing them back, and the files that hold them.
 *
 * Grammar (over the S-expressions of sexp.c; the forms of a file):
 *
 *   file     = ( tree | include | expr )*       at most one bare expr
 *   tree     = '(' 'tree' NAME [ '(' 'params' param* ')' ] expr ')'
 *   param    = '(' NAME DEFAULT [ MIN MAX ] ')'
 *   include  = '(' 'include' STRING ')'          more definitions
 *   expr     = NUMBER | NAME | '(' FUNCTION expr* ')' | special
 *   NAME     = a param of the tree, or t (seconds) or fs (Hz)
 *   special  = '(' 'osc' expr [ SHAPE ] ')'      SHAPE sine|saw|square|triangle
 *            | '(' 'sample' STRING [ expr ] ')'
 *            | '(' 'env' ( '(' T V ')' )+ ')'    numbers, times rising
 *            | '(' 'delay' expr expr [ MAX ] ')'
 *            | '(' 'rvector' expr N expr ')'
 *            | '(' 'voice' STRING ( '(' 'in' expr* ')' | '(' 'param' NAME expr ')' )* ')'
 *            | '(' 'importance' entry+ ')'
 *            | '(' 'inverse-importance' TIME [ '(' 'from' T0 ')' ] entry+ ')'
 *            | '(' 'use' NAME ( '(' PARAM expr ')' )* ')'
 *   entry    = '(' expr expr [ 'lock' ] ')'
 *
 * `use` expands a definition in place: its params become the expressions
 * given (or their defaults).  A name unknown to the file is looked up in
 * lib/NAME.tt next to the file.
 */
#include "tt.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>

const tt_opinfo tt_ops[TT_NOPS] = {
    [TT_NUM] = {"number", 0, 0, 0},
    [TT_PARAM] = {"param", 0, 0, 0},
    [TT_T] = {"t", 0, 0, 0},
    [TT_FS] = {"fs", 0, 0, 0},
    [TT_ADD] = {"+", 1, -1, 0},
    [TT_SUB] = {"-", 1, -1, 0},
    [TT_MUL] = {"*", 1, -1, 0},
    [TT_DIV] = {"/", 2, 2, 0},
    [TT_POW] = {"pow", 2, 2, 0},
    [TT_MIN] = {"min", 1, -1, 0},
    [TT_MAX] = {"max", 1, -1, 0},
    [TT_EXP] = {"exp", 1, 1, 0},
    [TT_LOG] = {"log", 1, 1, 0},
    [TT_SQRT] = {"sqrt", 1, 1, 0},
    [TT_ABS] = {"abs", 1, 1, 0},
    [TT_SIN] = {"sin", 1, 1, 0},
    [TT_COS] = {"cos", 1, 1, 0},
    [TT_FLOOR] = {"floor", 1, 1, 0},
    [TT_TANH] = {"tanh", 1, 1, 0},
    [TT_DAMP] = {"damp", 1, 1, 0},
    [TT_SINE] = {"sine", 1, 1, 0},
    [TT_SAW] = {"saw", 1, 1, 0},
    [TT_SQUARE] = {"square", 1, 1, 0},
    [TT_TRIANGLE] = {"triangle", 1, 1, 0},
    [TT_OSC] = {"osc", 1, 1, TT_F_STATE | TT_F_SPECIAL},
    [TT_NOISE] = {"noise", 0, 0, TT_F_STATE},
    [TT_PNOISE] = {"pnoise", 1, 2, 0},
    [TT_SAMPLE] = {"sample", 0, 1, TT_F_STATE | TT_F_SPECIAL},
    [TT_INTEGRAL] = {"integral", 1, 1, TT_F_STATE},
    [TT_ENV] = {"env", 0, 0, TT_F_STATE | TT_F_SPECIAL},
    [TT_DELAY] = {"delay", 2, 2, TT_F_STATE | TT_F_SPECIAL},
    [TT_LOWPASS] = {"lowpass", 2, 3, TT_F_STATE},
    [TT_HIGHPASS] = {"highpass", 2, 3, TT_F_STATE},
    [TT_BANDPASS] = {"bandpass", 2, 3, TT_F_STATE},
    [TT_RESON] = {"reson", 3, 3, TT_F_STATE},
    [TT_VECTOR] = {"vector", 1, -1, 0},
    [TT_RVECTOR] = {"rvector", 2, 2, TT_F_SPECIAL},
    [TT_COMBINE] = {"combine", 1, 1, 0},
    [TT_VOICE] = {"voice", 0, -1, TT_F_STATE | TT_F_SPECIAL},
    [TT_IMPORTANCE] = {"importance", 2, -1, TT_F_SPECIAL},
    [TT_INVIMPORTANCE] = {"inverse-importance", 4, -1, TT_F_STATE | TT_F_SPECIAL},
    [TT_ENERGETIC] = {"energetic", 2, 2, TT_F_STATE},
    [TT_SPUTTER] = {"sputter", 4, 4, TT_F_STATE},
};

static const char *const shapes[] = {"sine", "saw", "square", "triangle"};

/* ---- nodes ---- */

tt_node *tt_node_new(tt_op op, int n) {
    tt_node *x = calloc(1, sizeof *x);
    if (!x)
        return NULL;
    x->op = op;
    x->n = n;
    x->width = 1;
    if (n > 0 && !(x->a = calloc((size_t)n, sizeof *x->a))) {
        free(x);
        return NULL;
    }
    return x;
}

void tt_node_free(tt_node *x) {
    if (!x)
        return;
    for (int i = 0; i < x->n; i++)
        tt_node_free(x->a[i]);
    if (x->pn)
        for (int i = 0; i < x->n - x->nin; i++)
            free(x->pn[i]);
    free(x->pn);
    free(x->use);
    free(x->a);
    free(x->s);
    free(x->k);
    free(x);
}

static char *dupstr(const char *s) {
    if (!s)
        return NULL;
    char *d = malloc(strlen(s) + 1);
    if (d)
        strcpy(d, s);
    return d;
}

tt_node *tt_node_clone(const tt_node *x) {
    if (!x)
        return NULL;
    tt_node *y = tt_node_new(x->op, x->n);
    if (!y)
        return NULL;
    int ok = 1;
    y->v = x->v, y->nin = x->nin, y->doc = x->doc, y->line = x->line, y->col = x->col;
    y->width = x->width, y->rate = x->rate, y->nk = x->nk;
    if (x->s && !(y->s = dupstr(x->s)))
        ok = 0;
    if (x->use && !(y->use = dupstr(x->use)))
        ok = 0;
    if (x->nk && (y->k = malloc(sizeof(double) * (size_t)x->nk)))
        memcpy(y->k, x->k, sizeof(double) * (size_t)x->nk);
    else if (x->nk)
        ok = 0;
    if (x->pn) {
        int np = x->n - x->nin;
        if ((y->pn = calloc((size_t)(np > 0 ? np : 1), sizeof *y->pn)))
            for (int i = 0; i < np; i++)
                ok &= (y->pn[i] = dupstr(x->pn[i])) != NULL;
        else
            ok = 0;
    }
    for (int i = 0; i < x->n; i++)
        ok &= (y->a[i] = tt_node_clone(x->a[i])) != NULL;
    if (!ok) {
        tt_node_free(y);
        return NULL;
    }
    return y;
}

int tt_node_count(const tt_node *x) {
    int c = 1;
    for (int i = 0; i < x->n; i++)
        c += tt_node_count(x->a[i]);
    return c;
}

int tt_node_has(const tt_node *x, tt_op op) {
    if (x->op == op)
        return 1;
    for (int i = 0; i < x->n; i++)
        if (tt_node_has(x->a[i], op))
            return 1;
    return 0;
}

int tt_node_depth(const tt_node *x) {
    int d = 0;
    for (int i = 0; i < x->n; i++) {
        int e = tt_node_depth(x->a[i]);
        d = e > d ? e : d;
    }
    return d + 1;
}

/* ---- printing ---- */

static void print_num(FILE *f, double v) {
    char b[40];
    if (v == floor(v) && fabs(v) < 1e15) {
        fprintf(f, "%.0f", v == 0 ? 0.0 : v);
        return;
    }
    snprintf(b, sizeof b, "%.17g", v);
    /* the shortest text that reads back to the same double */
    for (int p = 1; p < 17; p++) {
        char c[40];
        snprintf(c, sizeof c, "%.*g", p, v);
        if (strtod(c, NULL) == v) {
            strcpy(b, c);
            break;
        }
    }
    fputs(b, f);
}

static void print_str(FILE *f, const char *s) {
    fputc('"', f);
    for (; *s; s++) {
        if (*s == '"' || *s == '\\')
            fputc('\\', f), fputc(*s, f);
        else if (*s == '\n')
            fputs("\\n", f);
        else if (*s == '\t')
            fputs("\\t", f);
        else
            fputc(*s, f);
    }
    fputc('"', f);
}

static void print_entries(FILE *f, const tt_node *x, int first) {
    for (int i = first, e = 0; i + 1 < x->n; i += 2, e++) {
        fputs(" (", f);
        tt_print(f, x->a[i]);
        fputc(' ', f);
        tt_print(f, x->a[i + 1]);
        if (e < x->nk && x->k[e] != 0)
            fputs(" lock", f);
        fputc(')', f);
    }
}

void tt_print(FILE *f, const tt_node *x) {
    switch (x->op) {
    case TT_NUM:
        print_num(f, x->v);
        return;
    case TT_PARAM:
        fputs(x->s ? x->s : "?", f);
        return;
    case TT_T:
        fputc('t', f);
        return;
    case TT_FS:
        fputs("fs", f);
        return;
    case TT_OSC:
        fputs("(osc ", f);
        tt_print(f, x->a[0]);
        if ((int)x->v != TT_SHAPE_SINE)
            fprintf(f, " %s", shapes[(int)x->v & 3]);
        fputc(')', f);
        return;
    case TT_SAMPLE:
        fputs("(sample ", f);
        print_str(f, x->s ? x->s : "");
        if (x->n) {
            fputc(' ', f);
            tt_print(f, x->a[0]);
        }
        fputc(')', f);
        return;
    case TT_ENV:
        fputs("(env", f);
        for (int i = 0; i + 1 < x->nk; i += 2) {
            fputs(" (", f);
            print_num(f, x->k[i]);
            fputc(' ', f);
            print_num(f, x->k[i + 1]);
            fputc(')', f);
        }
        fputc(')', f);
        return;
    case TT_DELAY:
        fputs("(delay ", f);
        tt_print(f, x->a[0]);
        fputc(' ', f);
        tt_print(f, x->a[1]);
        if (x->v > 0) {
            fputc(' ', f);
            print_num(f, x->v);
        }
        fputc(')', f);
        return;
    case TT_RVECTOR:
        fputs("(rvector ", f);
        tt_print(f, x->a[0]);
        fprintf(f, " %d ", (int)x->v);
        tt_print(f, x->a[1]);
        fputc(')', f);
        return;
    case TT_VOICE:
        fputs("(voice ", f);
        print_str(f, x->s ? x->s : "");
        if (x->nin) {
            fputs(" (in", f);
            for (int i = 0; i < x->nin; i++) {
                fputc(' ', f);
                tt_print(f, x->a[i]);
            }
            fputc(')', f);
        }
        for (int i = x->nin; i < x->n; i++) {
            fprintf(f, " (param %s ", x->pn[i - x->nin]);
            tt_print(f, x->a[i]);
            fputc(')', f);
        }
        fputc(')', f);
        return;
    case TT_IMPORTANCE:
        fputs("(importance", f);
        print_entries(f, x, 0);
        fputc(')', f);
        return;
    case TT_INVIMPORTANCE:
        fputs("(inverse-importance ", f);
        tt_print(f, x->a[0]);
        if (!(x->a[1]->op == TT_NUM && x->a[1]->v == 0)) {
            fputs(" (from ", f);
            tt_print(f, x->a[1]);
            fputc(')', f);
        }
        print_entries(f, x, 2);
        fputc(')', f);
        return;
    default:
        fprintf(f, "(%s", tt_ops[x->op].name);
        for (int i = 0; i < x->n; i++) {
            fputc(' ', f);
            tt_print(f, x->a[i]);
        }
        fputc(')', f);
        return;
    }
}

void tt_print_tree(FILE *f, const tt_tree *t) {
    fprintf(f, "(tree %s", t->name && t->name[0] ? t->name : "tree");
    if (t->nparams) {
        fputs(" (params", f);
        for (int i = 0; i < t->nparams; i++) {
            fprintf(f, " (%s ", t->pname[i]);
            print_num(f, t->pdef[i]);
            if (t->pmin[i] > -1e300 || t->pmax[i] < 1e300) {
                fputc(' ', f);
                print_num(f, t->pmin[i]);
                fputc(' ', f);
                print_num(f, t->pmax[i]);
            }
            fputc(')', f);
        }
        fputc(')', f);
    }
    fputs("\n  ", f);
    tt_print(f, t->root);
    fputs(")\n", f);
}

/* ---- schematics ---- */

static void dot_node(FILE *f, const tt_node *x, const char *prefix, int *id, char *name) {
    snprintf(name, 64, "%s%d", prefix, (*id)++);
    char kids[64];
    if (x->use && *id > 1) { /* a used tree: one box (wdrt dot of its file draws the inside) */
        fprintf(f, "  %s [shape=box3d style=filled fillcolor=\"#e6e6fa\" label=\"%s\"];\n", name, x->use);
        return;
    }
    switch (x->op) {
    case TT_NUM:
        fprintf(f, "  %s [shape=plaintext label=\"", name);
        print_num(f, x->v);
        fputs("\"];\n", f);
        return;
    case TT_PARAM:
        fprintf(f, "  %s [shape=invhouse style=filled fillcolor=\"#fff2cc\" label=\"%s\"];\n", name, x->s ? x->s : "?");
        return;
    case TT_T:
    case TT_FS:
        fprintf(f, "  %s [shape=plaintext label=\"%s\"];\n", name, x->op == TT_T ? "t" : "fs");
        return;
    default:
        break;
    }
    int mix = x->op >= TT_IMPORTANCE;
    const char *fill = mix ? "#d9ead3" : x->op == TT_VOICE ? "#cfe2f3" : (tt_ops[x->op].flags & TT_F_STATE) ? "#fce5cd" : "#ffffff";
    fprintf(f, "  %s [shape=%s style=filled fillcolor=\"%s\" label=\"%s", name, mix || x->op == TT_VOICE ? "box" : "ellipse", fill,
            tt_ops[x->op].name);
    if (x->op == TT_OSC && (int)x->v != TT_SHAPE_SINE)
        fprintf(f, " %s", shapes[(int)x->v & 3]);
    if (x->op == TT_RVECTOR)
        fprintf(f, " %d", (int)x->v);
    if ((x->op == TT_SAMPLE || x->op == TT_VOICE) && x->s) {
        const char *b = strrchr(x->s, '/');
        fputs("\\n", f);
        for (const char *c = b ? b + 1 : x->s; *c; c++)
            if (*c != '"' && *c != '\\')
                fputc(*c, f);
    }
    if (x->op == TT_ENV)
        fprintf(f, " (%d keys)", x->nk / 2);
    if (x->width > 1)
        fprintf(f, "\\n[%d]", x->width);
    fputs("\"];\n", f);
    int first = x->op == TT_INVIMPORTANCE ? 2 : 0;
    for (int i = 0; i < x->n; i++) {
        dot_node(f, x->a[i], prefix, id, kids);
        const char *lab = "";
        char b[80];
        if ((x->op == TT_IMPORTANCE || x->op == TT_INVIMPORTANCE) && i >= first) {
            int e = (i - first) / 2;
            snprintf(b, sizeof b, "%s%d%s", (i - first) % 2 ? "w" : "x", e + 1,
                     (i - first) % 2 && e < x->nk && x->k[e] != 0 ? " lock" : "");
            lab = b;
        } else if (x->op == TT_VOICE && i >= x->nin) {
            snprintf(b, sizeof b, "%s", x->pn[i - x->nin]);
            lab = b;
        }
        fprintf(f, "  %s -> %s [label=\"%s\"];\n", kids, name, lab);
    }
}

void tt_dot(FILE *f, const tt_node *x, const char *prefix, char *root) {
    int id = 0;
    dot_node(f, x, prefix, &id, root);
}

/* ---- trees ---- */

void tt_tree_free(tt_tree *t) {
    if (!t)
        return;
    for (int i = 0; i < t->nparams; i++)
        free(t->pname[i]);
    free(t->pname);
    free(t->pdef);
    free(t->pmin);
    free(t->pmax);
    free(t->name);
    tt_node_free(t->root);
    free(t);
}

/* A tree with room for np params, none named yet. */
static tt_tree *tree_new(const char *name, int np) {
    tt_tree *t = calloc(1, sizeof *t);
    if (!t)
        return NULL;
    size_t n = (size_t)(np > 0 ? np : 1);
    t->name = dupstr(name ? name : "");
    t->pname = calloc(n, sizeof *t->pname);
    t->pdef = calloc(n, sizeof *t->pdef);
    t->pmin = calloc(n, sizeof *t->pmin);
    t->pmax = calloc(n, sizeof *t->pmax);
    if (!t->name || !t->pname || !t->pdef || !t->pmin || !t->pmax) {
        tt_tree_free(t);
        return NULL;
    }
    return t;
}

tt_tree *tt_tree_clone(const tt_tree *t) {
    tt_tree *c = tree_new(t->name, t->nparams);
    if (!c)
        return NULL;
    for (int i = 0; i < t->nparams; i++) {
        if (!(c->pname[i] = dupstr(t->pname[i]))) {
            tt_tree_free(c);
            return NULL;
        }
        c->nparams = i + 1;
        c->pdef[i] = t->pdef[i], c->pmin[i] = t->pmin[i], c->pmax[i] = t->pmax[i];
    }
    if (!(c->root = tt_node_clone(t->root))) {
        tt_tree_free(c);
        return NULL;
    }
    return c;
}

/* ---- checking ---- */

typedef struct chk {
    const tt_tree *t;
    char *err;
    size_t errlen;
} chk;

static int cerr(chk *c, const tt_node *x, const char *fmt, ...) {
    char msg[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    if (x && x->doc)
        return sx_error_at(x->doc, x->line, x->col, c->err, c->errlen, "%s", msg);
    if (c->err && c->errlen)
        snprintf(c->err, c->errlen, "tree: error: %s\n", msg);
    return -1;
}

static const char *rate_name(int r) { return r == TT_CONST ? "a constant" : r == TT_CONTROL ? "a control value" : "audio"; }

/* The width elementwise arguments a[from..to) broadcast to. */
static int broadcast(chk *c, const tt_node *x, int from, int to, int *w) {
    *w = 1;
    for (int i = from; i < to; i++) {
        int wi = x->a[i]->width;
        if (wi == 1)
            continue;
        if (*w != 1 && wi != *w)
            return cerr(c, x->a[i], "a vector of %d where %s takes vectors of %d (or scalars)", wi,
                        tt_ops[x->op].name, *w);
        *w = wi;
    }
    return 0;
}

static int need_scalar(chk *c, const tt_node *x, const tt_node *arg, const char *what) {
    if (arg->width != 1)
        return cerr(c, arg, "%s of %s must be a scalar, found a vector of %d", what, tt_ops[x->op].name, arg->width);
    return 0;
}

static int need_rate(chk *c, const tt_node *x, const tt_node *arg, int most, const char *what) {
    if (arg->rate > most)
        return cerr(c, arg, "%s of %s must be %s, found %s", what, tt_ops[x->op].name,
                    most == TT_CONST ? "a constant" : "a constant or a control value (params)", rate_name(arg->rate));
    return 0;
}

static int check(chk *c, tt_node *x, int depth) {
    if (depth > TT_MAX_DEPTH)
        return cerr(c, x, "the tree nests deeper than %d", TT_MAX_DEPTH);
    if ((unsigned)x->op >= TT_NOPS)
        return cerr(c, x, "bad operation");
    const tt_opinfo *in = &tt_ops[x->op];
    if (x->op != TT_VOICE && x->op != TT_IMPORTANCE && x->op != TT_INVIMPORTANCE &&
        (x->n < in->min || (in->max >= 0 && x->n > in->max)))
        return cerr(c, x, "%s takes %d%s argument%s, found %d", in->name, in->min,
                    in->max < 0 ? " or more" : in->max > in->min ? " or more" : "", in->min == 1 && in->max == 1 ? "" : "s",
                    x->n);
    int rate = TT_CONST, w = 1;
    for (int i = 0; i < x->n; i++) {
        if (!x->a[i])
            return cerr(c, x, "missing argument");
        if (check(c, x->a[i], depth + 1))
            return -1;
        rate = x->a[i]->rate > rate ? x->a[i]->rate : rate;
    }
    switch (x->op) {
    case TT_NUM:
        if (!isfinite(x->v))
            return cerr(c, x, "a number must be finite");
        rate = TT_CONST;
        break;
    case TT_PARAM:
        if (x->v < 0 || x->v >= c->t->nparams || x->v != floor(x->v))
            return cerr(c, x, "unknown param");
        rate = TT_CONTROL;
        break;
    case TT_T:
        rate = TT_AUDIO;
        break;
    case TT_FS:
        rate = TT_CONTROL;
        break;
    case TT_OSC:
        if (!(x->v >= 0 && x->v <= 3 && x->v == floor(x->v)))
            return cerr(c, x, "unknown shape");
        w = x->a[0]->width;
        rate = TT_AUDIO;
        break;
    case TT_NOISE:
        rate = TT_AUDIO;
        break;
    case TT_SAMPLE:
        if (!x->s)
            return cerr(c, x, "sample needs a file");
        if (x->n && need_scalar(c, x, x->a[0], "the rate"))
            return -1;
        rate = TT_AUDIO;
        break;
    case TT_ENV:
        if (x->nk < 2 || x->nk % 2)
            return cerr(c, x, "env needs at least one (TIME VALUE) key");
        for (int i = 0; i < x->nk; i++)
            if (!isfinite(x->k[i]) || (i % 2 == 0 && (x->k[i] < 0 || (i >= 2 && x->k[i] < x->k[i - 2]))))
                return cerr(c, x, "env keys need times from 0, rising, and finite values");
        rate = TT_AUDIO;
        break;
    case TT_DELAY:
        if (broadcast(c, x, 0, 2, &w))
            return -1;
        if (x->v == 0) {
            if (need_rate(c, x, x->a[1], TT_CONST, "the time (without a MAX)"))
                return -1;
            if (x->a[1]->op == TT_NUM && !(x->a[1]->v >= 0 && x->a[1]->v <= TT_MAX_DELAY))
                return cerr(c, x->a[1], "a delay is 0 to %g s", TT_MAX_DELAY);
        } else if (!(x->v > 0 && x->v <= TT_MAX_DELAY)) {
            return cerr(c, x, "a delay holds at most %g s", TT_MAX_DELAY);
        }
        rate = TT_AUDIO;
        break;
    case TT_RVECTOR:
        if (!(x->v >= 1 && x->v <= TT_MAX_WIDTH && x->v == floor(x->v)))
            return cerr(c, x, "rvector makes 1 to %d values", TT_MAX_WIDTH);
        if (need_scalar(c, x, x->a[0], "the low end") || need_scalar(c, x, x->a[1], "the high end"))
            return -1;
        w = (int)x->v;
        break;
    case TT_VECTOR: {
        long sum = 0;
        for (int i = 0; i < x->n; i++)
            sum += x->a[i]->width;
        if (sum > TT_MAX_WIDTH)
            return cerr(c, x, "a vector holds at most %d values", TT_MAX_WIDTH);
        w = (int)sum;
        break;
    }
    case TT_COMBINE:
        w = 1;
        break;
    case TT_VOICE:
        if (!x->s || x->nin < 0 || x->nin > x->n)
            return cerr(c, x, "bad voice node");
        for (int i = 0; i < x->n; i++)
            if (need_scalar(c, x, x->a[i], i < x->nin ? "an input" : "a param"))
                return -1;
        rate = TT_AUDIO;
        break;
    case TT_IMPORTANCE:
    case TT_INVIMPORTANCE: {
        int first = x->op == TT_INVIMPORTANCE ? 2 : 0;
        if (x->n < first + 2 || (x->n - first) % 2 || x->nk != (x->n - first) / 2)
            return cerr(c, x, "%s needs entries (X W [lock])", in->name);
        if (first && (need_scalar(c, x, x->a[0], "the transition") || need_rate(c, x, x->a[0], TT_CONST, "the transition") ||
                      need_scalar(c, x, x->a[1], "the start") || need_rate(c, x, x->a[1], TT_CONST, "the start")))
            return -1;
        if (first && !(x->a[0]->op == TT_NUM && x->a[0]->v >= 0 && x->a[0]->v <= 86400 && x->a[1]->op == TT_NUM &&
                       x->a[1]->v >= 0 && x->a[1]->v <= 86400))
            return cerr(c, x->a[0], "the transition and its start are times from 0 to a day");
        for (int i = first; i < x->n; i += 2) {
            if (need_scalar(c, x, x->a[i + 1], "a weight") || need_rate(c, x, x->a[i + 1], TT_CONTROL, "a weight"))
                return -1;
            if (x->a[i]->width != 1) {
                if (w != 1 && x->a[i]->width != w)
                    return cerr(c, x->a[i], "a vector of %d where %s mixes vectors of %d (or scalars)", x->a[i]->width,
                                in->name, w);
                w = x->a[i]->width;
            }
        }
        if (first)
            rate = TT_AUDIO;
        break;
    }
    case TT_ENERGETIC:
        if (need_scalar(c, x, x->a[1], "the speed"))
            return -1;
        w = x->a[0]->width;
        rate = TT_AUDIO;
        break;
    case TT_SPUTTER:
        for (int i = 1; i < 4; i++)
            if (need_scalar(c, x, x->a[i], i == 3 ? "the duration" : "a rate") ||
                need_rate(c, x, x->a[i], TT_CONTROL, i == 3 ? "the duration" : "a rate"))
                return -1;
        w = x->a[0]->width;
        rate = TT_AUDIO;
        break;
    default:
        if (broadcast(c, x, 0, x->n, &w))
            return -1;
        if (in->flags & TT_F_STATE)
            rate = TT_AUDIO;
        break;
    }
    x->width = w;
    x->rate = rate;
    return 0;
}

int tt_check(tt_tree *t, char *err, size_t errlen) {
    chk c = {t, err, errlen};
    if (!t || !t->root)
        return cerr(&c, NULL, "an empty tree");
    if (t->nparams > TT_MAX_PARAMS)
        return cerr(&c, t->root, "a tree has at most %d params", TT_MAX_PARAMS);
    if (tt_node_count(t->root) > TT_MAX_NODES)
        return cerr(&c, t->root, "a tree has at most %d nodes", TT_MAX_NODES);
    if (check(&c, t->root, 0))
        return -1;
    if (t->root->width != 1)
        return cerr(&c, t->root, "a tree sounds one signal: combine its vector of %d (or pick one)", t->root->width);
    return 0;
}

/* ---- reading ---- */

typedef struct def {
    char *name;
    const sx_doc *doc;
    const sx *expr;
    char *dir;
    int np;
    char **pn;
    double *pd, *pmin, *pmax;
} def;

struct tt_file {
    char *path, *dir;
    sx_doc **docs;      /* owned, every file read */
    int ndocs;
    char **seen;        /* paths read (includes are read once) */
    int nseen;
    def *defs;
    int ndefs;
    tt_tree **trees;    /* in the order written */
    int ntrees;
};

/* A name in scope while an expression is read: a param, or (inside a
 * use) the expression it stands for. */
typedef struct binding {
    const char *name;
    int param;          /* >= 0: the tree's param */
    const tt_node *expr;/* or this expression */
} binding;

typedef struct rd {
    tt_file *F;
    const sx_doc *doc;
    const char *dir;
    binding *b;
    int nb;
    const def *stack[32]; /* uses being expanded */
    int nstack;
    long nodes;
    char *err;
    size_t errlen;
} rd;

#define RERR(R, x, ...) sx_error((R)->doc, (x), (R)->err, (R)->errlen, __VA_ARGS__)

static const char *kind_of(const sx *x) { return x ? sx_kind_name(x->kind) : "nothing"; }


/* The nearest of the names known here (functions, params, defs) to s. */
static const char *nearest(const rd *R, const char *s, int functions) {
    const char *best = NULL;
    int bd = 3;
#define TRY(name)                                                                                                      \
    do {                                                                                                               \
        int d_ = sx_edit_distance(s, (name));                                                                             \
        if (d_ < bd)                                                                                                   \
            bd = d_, best = (name);                                                                                    \
    } while (0)
    if (functions) {
        for (int i = TT_ADD; i < TT_NOPS; i++)
            TRY(tt_ops[i].name);
        TRY("use");
        for (int i = 0; i < R->F->ndefs; i++)
            TRY(R->F->defs[i].name);
    } else {
        for (int i = 0; i < R->nb; i++)
            TRY(R->b[i].name);
        TRY("t");
        TRY("fs");
    }
#undef TRY
    return best;
}

static tt_node *node(rd *R, tt_op op, int n, const sx *at) {
    if (++R->nodes > TT_MAX_NODES) {
        RERR(R, at, "the tree has more than %d nodes", TT_MAX_NODES);
        return NULL;
    }
    tt_node *x = tt_node_new(op, n);
    if (!x) {
        RERR(R, at, "out of memory");
        return NULL;
    }
    x->doc = R->doc;
    x->line = at ? at->line : 0;
    x->col = at ? at->col : 0;
    return x;
}

static tt_node *expr(rd *R, const sx *x, int depth);
static int load(tt_file *F, const char *path, const sx_doc *from, const sx *at, char *err, size_t errlen);

static int number(rd *R, const sx *x, double *v) {
    if (!x || x->kind != SX_NUM)
        return RERR(R, x, "expected a number, found a %s", kind_of(x));
    *v = x->num;
    return 0;
}

static char *join(const char *dir, const char *p) {
    if (p[0] == '/' || !dir || !dir[0])
        return dupstr(p);
    char *r = malloc(strlen(dir) + strlen(p) + 2);
    if (r)
        sprintf(r, "%s/%s", dir, p);
    return r;
}

static const def *find_def(const tt_file *F, const char *name) {
    for (int i = F->ndefs - 1; i >= 0; i--)
        if (!strcmp(F->defs[i].name, name))
            return &F->defs[i];
    return NULL;
}

/* The definition `use` names at n: of the file, its includes, or
 * lib/NAME.tt next to the file. */
static const def *lookup_def(rd *R, const sx *n) {
    const def *d = find_def(R->F, n->text);
    if (!d && strlen(n->text) < 200 && !strchr(n->text, '/')) {
        char rel[256];
        snprintf(rel, sizeof rel, "lib/%s.tt", n->text);
        char *p = join(R->dir, rel);
        if (p && !sx_file_ok(p)) {
            if (load(R->F, p, R->doc, n, R->err, R->errlen)) {
                free(p);
                return NULL;
            }
            d = find_def(R->F, n->text);
        }
        free(p);
    }
    if (!d) {
        const char *near = nearest(R, n->text, 1);
        if (near)
            RERR(R, n, "unknown tree '%s'; did you mean '%s'?", n->text, near);
        else
            RERR(R, n, "unknown tree '%s' (no definition in the file, its includes, or lib/%s.tt)", n->text, n->text);
        return NULL;
    }
    for (int i = 0; i < R->nstack; i++)
        if (R->stack[i] == d) {
            RERR(R, n, "tree '%s' uses itself", d->name);
            return NULL;
        }
    if (R->nstack == 32) {
        RERR(R, n, "uses nest deeper than 32");
        return NULL;
    }
    return d;
}

/* The (P EXPR) arguments of a use at n->next on, read in R's scope into
 * given[] (NULL where not given). */
static int use_args(rd *R, const def *d, const sx *n, tt_node **given, int depth) {
    for (const sx *p = n->next; p; p = p->next) {
        if (p->kind != SX_LIST || p->len != 2 || p->head->kind != SX_SYM)
            return RERR(R, p, "expected (PARAM EXPR)");
        int k = -1;
        for (int i = 0; i < d->np; i++)
            if (!strcmp(d->pn[i], p->head->text))
                k = i;
        if (k < 0) {
            const char *near = NULL;
            int bd = 3;
            for (int i = 0; i < d->np; i++) {
                int e = sx_edit_distance(p->head->text, d->pn[i]);
                if (e < bd)
                    bd = e, near = d->pn[i];
            }
            if (near)
                return RERR(R, p->head, "tree '%s' has no param '%s'; did you mean '%s'?", d->name, p->head->text,
                            near);
            return RERR(R, p->head, "tree '%s' has no param '%s'", d->name, p->head->text);
        }
        if (given[k])
            return RERR(R, p->head, "param '%s' given twice", p->head->text);
        if (!(given[k] = expr(R, p->head->next, depth + 1)))
            return -1;
    }
    return 0;
}

/* d's expression with its params bound: given[i], else param pidx[i] of
 * the tree being read (pidx NULL or pidx[i] < 0: the default). */
static tt_node *expand(rd *R, const def *d, tt_node **given, const int *pidx, const sx *at, int depth) {
    binding *b = calloc((size_t)(d->np > 0 ? d->np : 1), sizeof *b);
    tt_node **dflt = calloc((size_t)(d->np > 0 ? d->np : 1), sizeof *dflt);
    tt_node *out = NULL;
    if (!b || !dflt) {
        RERR(R, at, "out of memory");
        goto done;
    }
    for (int i = 0; i < d->np; i++) {
        b[i].name = d->pn[i], b[i].param = -1, b[i].expr = given[i];
        if (!given[i] && pidx && pidx[i] >= 0)
            b[i].param = pidx[i];
        else if (!given[i]) {
            if (!(dflt[i] = node(R, TT_NUM, 0, at)))
                goto done;
            dflt[i]->v = d->pd[i];
            b[i].expr = dflt[i];
        }
    }
    rd sub = *R;
    sub.doc = d->doc;
    sub.dir = d->dir;
    sub.b = b;
    sub.nb = d->np;
    sub.stack[sub.nstack++] = d;
    out = expr(&sub, d->expr, depth + 1);
    R->nodes = sub.nodes;
    if (out && !out->use && !(out->use = dupstr(d->name))) {
        RERR(R, at, "out of memory");
        tt_node_free(out);
        out = NULL;
    }
done:
    for (int i = 0; dflt && i < d->np; i++)
        tt_node_free(dflt[i]);
    free(dflt);
    free(b);
    return out;
}

/* (use NAME (P EXPR)...) */
static tt_node *use(rd *R, const sx *x, int depth) {
    const sx *n = x->head->next;
    if (!n || n->kind != SX_SYM) {
        RERR(R, n ? n : x, "expected the name of a tree to use, found a %s", kind_of(n));
        return NULL;
    }
    const def *d = lookup_def(R, n);
    if (!d)
        return NULL;
    tt_node **given = calloc((size_t)(d->np > 0 ? d->np : 1), sizeof *given);
    tt_node *out = NULL;
    if (!given)
        RERR(R, x, "out of memory");
    else if (use_args(R, d, n, given, depth) == 0)
        out = expand(R, d, given, NULL, n, depth);
    for (int i = 0; given && i < d->np; i++)
        tt_node_free(given[i]);
    free(given);
    return out;
}

/* entries (X W [lock]) from e on, into x->a[first..] and x->k */
static int entries(rd *R, tt_node *x, const sx *e, int first, int depth) {
    int i = first;
    for (; e; e = e->next, i += 2) {
        if (e->kind != SX_LIST || e->len < 2 || e->len > 3 || (e->len == 3 && !sx_is(sx_nth(e, 2), "lock")))
            return RERR(R, e, "expected an entry (X W) or (X W lock)");
        x->k[(i - first) / 2] = e->len == 3;
        if (!(x->a[i] = expr(R, e->head, depth + 1)) || !(x->a[i + 1] = expr(R, e->head->next, depth + 1)))
            return -1;
    }
    return 0;
}

static tt_node *special(rd *R, const sx *x, tt_op op, int depth) {
    const sx *a = x->head->next;
    int nargs = x->len - 1;
    tt_node *y = NULL;
    switch (op) {
    case TT_OSC: {
        if (nargs < 1 || nargs > 2) {
            RERR(R, x, "expected (osc FREQ [sine|saw|square|triangle])");
            return NULL;
        }
        int shape = TT_SHAPE_SINE;
        if (nargs == 2) {
            const sx *s = a->next;
            shape = -1;
            for (int i = 0; i < 4; i++)
                if (sx_is(s, shapes[i]))
                    shape = i;
            if (shape < 0) {
                const char *near = NULL;
                int bd = 3;
                for (int i = 0; s->kind == SX_SYM && i < 4; i++)
                    if (sx_edit_distance(s->text, shapes[i]) < bd)
                        bd = sx_edit_distance(s->text, shapes[i]), near = shapes[i];
                if (near)
                    RERR(R, s, "unknown shape '%s'; did you mean '%s'?", s->text, near);
                else
                    RERR(R, s, "expected a shape: sine, saw, square or triangle");
                return NULL;
            }
        }
        if (!(y = node(R, op, 1, x)))
            return NULL;
        y->v = shape;
        if (!(y->a[0] = expr(R, a, depth + 1)))
            goto fail;
        return y;
    }
    case TT_SAMPLE:
        if (nargs < 1 || nargs > 2) {
            RERR(R, x, "expected (sample \"file.wav\" [RATE])");
            return NULL;
        }
        if (a->kind != SX_STR) {
            RERR(R, a, "expected the sound file's name in double quotes, found a %s", kind_of(a));
            return NULL;
        }
        if (!(y = node(R, op, nargs - 1, x)))
            return NULL;
        if (!(y->s = join(R->dir, a->text)))
            goto fail;
        {
            int e = sx_file_ok(y->s);
            if (e) {
                RERR(R, a, "cannot read the sound file '%s': %s", y->s, sx_file_strerror(e));
                goto fail;
            }
        }
        if (nargs == 2 && !(y->a[0] = expr(R, a->next, depth + 1)))
            goto fail;
        return y;
    case TT_ENV: {
        if (nargs < 1) {
            RERR(R, x, "expected (env (TIME VALUE)...)");
            return NULL;
        }
        if (!(y = node(R, op, 0, x)))
            return NULL;
        if (!(y->k = malloc(sizeof(double) * 2 * (size_t)nargs)))
            goto oom;
        y->nk = 2 * nargs;
        int i = 0;
        for (const sx *k = a; k; k = k->next, i += 2) {
            if (k->kind != SX_LIST || k->len != 2) {
                RERR(R, k, "expected a key (TIME VALUE)");
                goto fail;
            }
            if (number(R, k->head, &y->k[i]) || number(R, k->head->next, &y->k[i + 1]))
                goto fail;
            if (y->k[i] < 0) {
                RERR(R, k->head, "a key's time must not be negative");
                goto fail;
            }
            if (i && y->k[i] < y->k[i - 2]) {
                RERR(R, k->head, "keys of an env must come in time order");
                goto fail;
            }
        }
        return y;
    }
    case TT_DELAY:
        if (nargs < 2 || nargs > 3) {
            RERR(R, x, "expected (delay X SECONDS [MAX])");
            return NULL;
        }
        if (!(y = node(R, op, 2, x)))
            return NULL;
        if (nargs == 3) {
            if (number(R, sx_nth(x, 3), &y->v))
                goto fail;
            if (!(y->v > 0 && y->v <= TT_MAX_DELAY)) {
                RERR(R, sx_nth(x, 3), "a delay holds more than 0 and at most %g s", TT_MAX_DELAY);
                goto fail;
            }
        }
        if (!(y->a[0] = expr(R, a, depth + 1)) || !(y->a[1] = expr(R, a->next, depth + 1)))
            goto fail;
        if (nargs == 2 && y->a[1]->op == TT_NUM && !(y->a[1]->v >= 0 && y->a[1]->v <= TT_MAX_DELAY)) {
            RERR(R, a->next, "a delay is 0 to %g s", TT_MAX_DELAY);
            goto fail;
        }
        return y;
    case TT_RVECTOR: {
        if (nargs != 3) {
            RERR(R, x, "expected (rvector LO N HI)");
            return NULL;
        }
        double n = 0;
        if (number(R, a->next, &n))
            return NULL;
        if (!(n >= 1 && n <= TT_MAX_WIDTH && n == floor(n))) {
            RERR(R, a->next, "rvector makes a whole number of values, 1 to %d", TT_MAX_WIDTH);
            return NULL;
        }
        if (!(y = node(R, op, 2, x)))
            return NULL;
        y->v = n;
        if (!(y->a[0] = expr(R, a, depth + 1)) || !(y->a[1] = expr(R, a->next->next, depth + 1)))
            goto fail;
        return y;
    }
    case TT_VOICE: {
        if (nargs < 1 || a->kind != SX_STR) {
            RERR(R, a ? a : x, "expected (voice \"file.wdn\" (in X...) (param P X)...)");
            return NULL;
        }
        int nin = 0, np = 0;
        for (const sx *p = a->next; p; p = p->next) {
            if (p->kind == SX_LIST && sx_is(p->head, "in"))
                nin += p->len - 1;
            else if (p->kind == SX_LIST && sx_is(p->head, "param") && p->len == 3 && p->head->next->kind == SX_SYM)
                np++;
            else {
                RERR(R, p, "expected (in X...) or (param NAME X)");
                return NULL;
            }
        }
        if (!(y = node(R, op, nin + np, x)))
            return NULL;
        y->nin = nin;
        if (!(y->s = join(R->dir, a->text)) || !(y->pn = calloc((size_t)(np ? np : 1), sizeof *y->pn)))
            goto oom;
        int ii = 0, pi = 0;
        for (const sx *p = a->next; p; p = p->next) {
            if (sx_is(p->head, "in")) {
                for (const sx *q = p->head->next; q; q = q->next)
                    if (!(y->a[ii++] = expr(R, q, depth + 1)))
                        goto fail;
            } else {
                if (!(y->pn[pi] = dupstr(p->head->next->text)))
                    goto oom;
                if (!(y->a[nin + pi++] = expr(R, p->head->next->next, depth + 1)))
                    goto fail;
            }
        }
        int e = sx_file_ok(y->s);
        if (e) {
            RERR(R, a, "cannot read the netlist '%s': %s", y->s, sx_file_strerror(e));
            goto fail;
        }
        return y;
    }
    case TT_IMPORTANCE:
    case TT_INVIMPORTANCE: {
        int first = op == TT_INVIMPORTANCE ? 2 : 0;
        const sx *e = a;
        double time = 0, from = 0;
        if (first) {
            if (number(R, a, &time))
                return NULL;
            if (!(time >= 0 && time <= 86400)) {
                RERR(R, a, "a transition is a time in seconds");
                return NULL;
            }
            e = a->next;
            if (e && e->kind == SX_LIST && sx_is(e->head, "from")) {
                if (e->len != 2 || number(R, e->head->next, &from))
                    return e->len != 2 ? (RERR(R, e, "expected (from TIME)"), NULL) : NULL;
                if (!(from >= 0 && from <= 86400)) {
                    RERR(R, e->head->next, "a start is a time in seconds");
                    return NULL;
                }
                e = e->next;
            }
        }
        int ne = 0;
        for (const sx *q = e; q; q = q->next)
            ne++;
        if (ne < 1) {
            RERR(R, x, "expected (%s%s (X W [lock])...)", tt_ops[op].name, first ? " TIME [(from T0)]" : "");
            return NULL;
        }
        if (!(y = node(R, op, first + 2 * ne, x)))
            return NULL;
        if (!(y->k = calloc((size_t)ne, sizeof(double))))
            goto oom;
        y->nk = ne;
        if (first) {
            if (!(y->a[0] = node(R, TT_NUM, 0, a)) || !(y->a[1] = node(R, TT_NUM, 0, a)))
                goto fail;
            y->a[0]->v = time, y->a[1]->v = from;
        }
        if (entries(R, y, e, first, depth))
            goto fail;
        return y;
    }
    default:
        break;
    }
    RERR(R, x, "internal: no reader for %s", tt_ops[op].name);
    return NULL;
oom:
    RERR(R, x, "out of memory");
fail:
    tt_node_free(y);
    return NULL;
}

static tt_node *expr(rd *R, const sx *x, int depth) {
    if (!x) {
        RERR(R, x, "expected an expression");
        return NULL;
    }
    if (depth > TT_MAX_DEPTH) {
        RERR(R, x, "the tree nests deeper than %d", TT_MAX_DEPTH);
        return NULL;
    }
    tt_node *y;
    switch (x->kind) {
    case SX_NUM:
        if (!(y = node(R, TT_NUM, 0, x)))
            return NULL;
        y->v = x->num;
        return y;
    case SX_STR:
        RERR(R, x, "expected an expression, found a string");
        return NULL;
    case SX_SYM:
        for (int i = R->nb - 1; i >= 0; i--)
            if (!strcmp(R->b[i].name, x->text)) {
                if (R->b[i].param < 0) {
                    if (!(y = tt_node_clone(R->b[i].expr)))
                        RERR(R, x, "out of memory");
                    else
                        R->nodes += tt_node_count(y);
                    return y;
                }
                if (!(y = node(R, TT_PARAM, 0, x)))
                    return NULL;
                y->v = R->b[i].param;
                if (!(y->s = dupstr(x->text))) {
                    tt_node_free(y);
                    RERR(R, x, "out of memory");
                    return NULL;
                }
                return y;
            }
        if (!strcmp(x->text, "t") || !strcmp(x->text, "fs"))
            return node(R, x->text[0] == 't' ? TT_T : TT_FS, 0, x);
        {
            const char *near = nearest(R, x->text, 0);
            for (int i = TT_ADD; i < TT_NOPS; i++)
                if (!strcmp(tt_ops[i].name, x->text)) {
                    RERR(R, x, "'%s' is a function: write (%s ...)", x->text, x->text);
                    return NULL;
                }
            if (near)
                RERR(R, x, "unknown name '%s'; did you mean '%s'?", x->text, near);
            else
                RERR(R, x, "unknown name '%s'", x->text);
        }
        return NULL;
    case SX_LIST:
        break;
    }
    if (!x->head) {
        RERR(R, x, "expected an expression, found ()");
        return NULL;
    }
    const sx *h = x->head;
    if (h->kind != SX_SYM) {
        RERR(R, h, "expected the name of a function, found a %s", kind_of(h));
        return NULL;
    }
    if (!strcmp(h->text, "use"))
        return use(R, x, depth);
    int op = -1;
    for (int i = TT_ADD; i < TT_NOPS; i++)
        if (!strcmp(tt_ops[i].name, h->text))
            op = i;
    if (op < 0) {
        if (find_def(R->F, h->text))
            RERR(R, h, "'%s' is a tree: write (use %s ...)", h->text, h->text);
        else {
            const char *near = nearest(R, h->text, 1);
            if (near)
                RERR(R, h, "unknown function '%s'; did you mean '%s'?", h->text, near);
            else
                RERR(R, h, "unknown function '%s'", h->text);
        }
        return NULL;
    }
    const tt_opinfo *in = &tt_ops[op];
    if (in->flags & TT_F_SPECIAL)
        return special(R, x, (tt_op)op, depth);
    int n = x->len - 1;
    if (n < in->min || (in->max >= 0 && n > in->max)) {
        if (in->min == in->max)
            RERR(R, x, "%s takes %d argument%s, found %d", in->name, in->min, in->min == 1 ? "" : "s", n);
        else if (in->max < 0)
            RERR(R, x, "%s takes at least %d argument%s, found %d", in->name, in->min, in->min == 1 ? "" : "s", n);
        else
            RERR(R, x, "%s takes %d to %d arguments, found %d", in->name, in->min, in->max, n);
        return NULL;
    }
    if (!(y = node(R, (tt_op)op, n, x)))
        return NULL;
    int i = 0;
    for (const sx *a = h->next; a; a = a->next, i++)
        if (!(y->a[i] = expr(R, a, depth + 1))) {
            tt_node_free(y);
            return NULL;
        }
    return y;
}

/* ---- files ---- */

static void def_free(def *d) {
    free(d->name);
    free(d->dir);
    for (int i = 0; i < d->np; i++)
        free(d->pn[i]);
    free(d->pn);
    free(d->pd);
    free(d->pmin);
    free(d->pmax);
}

void tt_file_free(tt_file *F) {
    if (!F)
        return;
    for (int i = 0; i < F->ntrees; i++)
        tt_tree_free(F->trees[i]);
    for (int i = 0; i < F->ndefs; i++)
        def_free(&F->defs[i]);
    for (int i = 0; i < F->ndocs; i++)
        sx_free(F->docs[i]);
    for (int i = 0; i < F->nseen; i++)
        free(F->seen[i]);
    free(F->seen);
    free(F->trees);
    free(F->defs);
    free(F->docs);
    free(F->path);
    free(F->dir);
    free(F);
}

static int push(void **arr, int n, size_t sz) {
    void *p = realloc(*arr, sz * (size_t)(n + 1));
    if (!p)
        return -1;
    *arr = p;
    return 0;
}

static char *dir_of(const char *path) {
    char *d = dupstr(path ? path : "");
    if (!d)
        return NULL;
    char *s = strrchr(d, '/');
    if (s)
        *s = 0;
    else
        d[0] = 0;
    return d;
}

/* Reads a params list into the def: (params (P D [MIN MAX])...). */
static int params(rd *R, const sx *p, def *d) {
    double **pmin = &d->pmin, **pmax = &d->pmax;
    int n = p->len - 1;
    if (n > TT_MAX_PARAMS)
        return RERR(R, p, "a tree has at most %d params", TT_MAX_PARAMS);
    d->pn = calloc((size_t)(n ? n : 1), sizeof *d->pn);
    d->pd = calloc((size_t)(n ? n : 1), sizeof *d->pd);
    *pmin = calloc((size_t)(n ? n : 1), sizeof **pmin);
    *pmax = calloc((size_t)(n ? n : 1), sizeof **pmax);
    if (!d->pn || !d->pd || !*pmin || !*pmax)
        return RERR(R, p, "out of memory");
    for (const sx *q = p->head->next; q; q = q->next) {
        if (q->kind != SX_LIST || (q->len != 2 && q->len != 4) || q->head->kind != SX_SYM)
            return RERR(R, q, "expected a param (NAME DEFAULT) or (NAME DEFAULT MIN MAX)");
        const char *nm = q->head->text;
        if (!strcmp(nm, "t") || !strcmp(nm, "fs"))
            return RERR(R, q->head, "'%s' is the tree's %s: pick another name", nm, nm[0] == 't' ? "time" : "rate");
        for (int i = TT_ADD; i < TT_NOPS; i++)
            if (!strcmp(nm, tt_ops[i].name))
                return RERR(R, q->head, "'%s' is a function: pick another name", nm);
        for (int i = 0; i < d->np; i++)
            if (!strcmp(d->pn[i], nm))
                return RERR(R, q->head, "param '%s' named twice", nm);
        double v = 0, lo = -1e300, hi = 1e300;
        if (number(R, q->head->next, &v) || (q->len == 4 && (number(R, sx_nth(q, 2), &lo) || number(R, sx_nth(q, 3), &hi))))
            return -1;
        if (!(lo <= hi) || v < lo || v > hi)
            return RERR(R, q, "a param's default lies within its range MIN..MAX");
        if (!(d->pn[d->np] = dupstr(nm)))
            return RERR(R, q, "out of memory");
        d->pd[d->np] = v, (*pmin)[d->np] = lo, (*pmax)[d->np] = hi;
        d->np++;
    }
    return 0;
}

/* A tree of def d, its params as params; checked. */
static tt_tree *elaborate(tt_file *F, const def *d, char *err, size_t errlen) {
    const double *pmin = d->pmin, *pmax = d->pmax;
    tt_tree *t = tree_new(d->name, d->np);
    binding *b = calloc((size_t)(d->np ? d->np : 1), sizeof *b);
    if (!t || !b) {
        free(b);
        tt_tree_free(t);
        sx_error(d->doc, d->expr, err, errlen, "out of memory");
        return NULL;
    }
    for (int i = 0; i < d->np; i++) {
        if (!(t->pname[i] = dupstr(d->pn[i])))
            break;
        t->nparams = i + 1;
        t->pdef[i] = d->pd[i];
        t->pmin[i] = pmin ? pmin[i] : -1e300;
        t->pmax[i] = pmax ? pmax[i] : 1e300;
        b[i].name = d->pn[i], b[i].param = i;
    }
    rd R = {F, d->doc, d->dir, b, d->np, {0}, 0, 0, err, errlen};
    R.stack[R.nstack++] = d;
    t->root = t->nparams == d->np ? expr(&R, d->expr, 0) : NULL;
    free(b);
    if (!t->root || tt_check(t, err, errlen)) {
        tt_tree_free(t);
        return NULL;
    }
    return t;
}

/* One form of a file: (tree ...), (include ...), or a bare expression
 * (bare: 1 to allow one). */
static int form(tt_file *F, const sx_doc *doc, const sx *f, const char *dir, int bare, char *err, size_t errlen) {
    rd R = {F, doc, dir, NULL, 0, {0}, 0, 0, err, errlen};
    if (f->kind == SX_LIST && sx_is(f->head, "include")) {
        if (f->len != 2 || f->head->next->kind != SX_STR)
            return RERR(&R, f, "expected (include \"file.tt\")");
        char *p = join(dir, f->head->next->text);
        if (!p)
            return RERR(&R, f, "out of memory");
        int r = load(F, p, doc, f->head->next, err, errlen);
        free(p);
        return r;
    }
    def d = {0};
    int r = -1;
    if (f->kind == SX_LIST && sx_is(f->head, "tree")) {
        const sx *n = f->head->next, *p = n ? n->next : NULL;
        if (!n || n->kind != SX_SYM)
            return RERR(&R, n ? n : f, "expected the tree's name, found a %s", kind_of(n));
        if (!p)
            return RERR(&R, f, "expected (tree NAME [(params (P DEFAULT)...)] EXPR)");
        if (!strcmp(n->text, "use") || !strcmp(n->text, "t") || !strcmp(n->text, "fs"))
            return RERR(&R, n, "'%s' cannot name a tree", n->text);
        for (int i = TT_ADD; i < TT_NOPS; i++)
            if (!strcmp(n->text, tt_ops[i].name))
                return RERR(&R, n, "'%s' is a function: pick another name", n->text);
        if (find_def(F, n->text))
            return RERR(&R, n, "a tree named '%s' is already defined", n->text);
        if (p->kind == SX_LIST && sx_is(p->head, "params")) {
            if (params(&R, p, &d))
                goto done;
            p = p->next;
        }
        if (!p || p->next) {
            RERR(&R, p ? p->next : f, "expected (tree NAME [(params (P DEFAULT)...)] EXPR): one expression");
            goto done;
        }
        d.name = dupstr(n->text);
        d.expr = p;
    } else {
        if (!bare) {
            RERR(&R, f, "a file holds at most one bare expression; name the others with (tree NAME ...)");
            goto done;
        }
        d.name = dupstr("");
        d.expr = f;
    }
    d.doc = doc;
    d.dir = dupstr(dir);
    if (!d.name || !d.dir) {
        RERR(&R, f, "out of memory");
        goto done;
    }
    tt_tree *t = elaborate(F, &d, err, errlen);
    if (!t)
        goto done;
    if (push((void **)&F->trees, F->ntrees, sizeof *F->trees) ||
        (d.name[0] && push((void **)&F->defs, F->ndefs, sizeof *F->defs))) {
        tt_tree_free(t);
        RERR(&R, f, "out of memory");
        goto done;
    }
    F->trees[F->ntrees++] = t;
    if (d.name[0]) {
        F->defs[F->ndefs++] = d;
        d = (def){0};
    }
    r = 0;
done:
    def_free(&d);
    return r;
}

static int read_doc(tt_file *F, sx_doc *doc, int top, char *err, size_t errlen) {
    char *dir = dir_of(doc->path);
    if (!dir)
        return -1;
    int bare = 0, r = 0;
    for (const sx *f = doc->forms; f && !r; f = f->next) {
        int is_bare = !(f->kind == SX_LIST && (sx_is(f->head, "tree") || sx_is(f->head, "include")));
        if (is_bare && !top) {
            r = sx_error(doc, f, err, errlen, "an included file holds definitions only: (tree NAME ...) or (include ...)");
            break;
        }
        r = form(F, doc, f, dir, is_bare && !bare, err, errlen);
        bare |= is_bare;
    }
    free(dir);
    return r;
}

/* Reads the file at path into F's definitions (once per path). */
static int load(tt_file *F, const char *path, const sx_doc *from, const sx *at, char *err, size_t errlen) {
    for (int i = 0; i < F->nseen; i++)
        if (!strcmp(F->seen[i], path))
            return 0;
    if (F->nseen >= 64)
        return sx_error(from, at, err, errlen, "more than 64 files included");
    if (push((void **)&F->seen, F->nseen, sizeof *F->seen) || !(F->seen[F->nseen] = dupstr(path)))
        return sx_error(from, at, err, errlen, "out of memory");
    F->nseen++;
    int e = sx_file_ok(path);
    if (e)
        return sx_error(from, at, err, errlen, "cannot read '%s': %s", path, sx_file_strerror(e));
    sx_doc *d = sx_read_file(path, err, errlen);
    if (!d)
        return -1;
    if (push((void **)&F->docs, F->ndocs, sizeof *F->docs)) {
        sx_free(d);
        return sx_error(from, at, err, errlen, "out of memory");
    }
    F->docs[F->ndocs++] = d;
    /* an included file's own trees are definitions, not renders */
    int before = F->ntrees;
    int r = read_doc(F, d, 0, err, errlen);
    for (int i = before; i < F->ntrees; i++)
        tt_tree_free(F->trees[i]);
    F->ntrees = before;
    return r;
}

static tt_file *file_new(const char *path) {
    tt_file *F = calloc(1, sizeof *F);
    if (!F)
        return NULL;
    F->path = dupstr(path ? path : "<string>");
    F->dir = dir_of(path);
    if (!F->path || !F->dir) {
        tt_file_free(F);
        return NULL;
    }
    return F;
}

tt_file *tt_file_read(const char *path, const char *text, size_t len, char *err, size_t errlen) {
    tt_file *F = file_new(path);
    if (!F) {
        if (err && errlen)
            snprintf(err, errlen, "%s: error: out of memory\n", path ? path : "tree");
        return NULL;
    }
    sx_doc *d = text ? sx_parse(path, text, len, err, errlen) : sx_read_file(path, err, errlen);
    if (!d || push((void **)&F->docs, F->ndocs, sizeof *F->docs)) {
        sx_free(d);
        tt_file_free(F);
        return NULL;
    }
    F->docs[F->ndocs++] = d;
    if (path && push((void **)&F->seen, F->nseen, sizeof *F->seen) == 0 && (F->seen[F->nseen] = dupstr(path)))
        F->nseen++;
    if (read_doc(F, d, 1, err, errlen)) {
        tt_file_free(F);
        return NULL;
    }
    if (F->ntrees == 0) {
        int line = 1;
        for (size_t i = 0; i < d->srclen; i++)
            line += d->src[i] == '\n';
        sx_error_at(d, line, 1, err, errlen, "no tree: write an expression or (tree NAME ...)");
        tt_file_free(F);
        return NULL;
    }
    return F;
}

tt_file *tt_file_from_string(const char *text, char *err, size_t errlen) {
    return tt_file_read("<expr>", text, strlen(text), err, errlen);
}

int tt_file_ntrees(const tt_file *F) { return F ? F->ntrees : 0; }

const tt_tree *tt_file_tree(const tt_file *F, int i) {
    if (!F || F->ntrees == 0)
        return NULL;
    if (i < 0)
        i = F->ntrees - 1;
    return i < F->ntrees ? F->trees[i] : NULL;
}

const tt_tree *tt_file_find(const tt_file *F, const char *name) {
    for (int i = 0; F && i < F->ntrees; i++)
        if (!strcmp(F->trees[i]->name, name))
            return F->trees[i];
    return NULL;
}

int tt_file_add_form(tt_file **defs, const sx_doc *d, const sx *f, const char *dir, char *err, size_t errlen) {
    if (!*defs && !(*defs = file_new(d->path)))
        return sx_error(d, f, err, errlen, "out of memory");
    return form(*defs, d, f, dir, 0, err, errlen);
}

/* (use NAME (P EXPR)...) as a whole tree: the params the use does not
 * give stay params (with their defaults and ranges), and the names in
 * pnames that are not the used tree's are params too, which the use's
 * expressions may read. */
static tt_tree *inline_use(tt_file *F, const sx_doc *doc, const sx *x, const char *dir, int np,
                           const char *const *pnames, const double *pdefs, char *err, size_t errlen) {
    rd R = {F, doc, dir, NULL, 0, {0}, 0, 0, err, errlen};
    const sx *n = x->head->next;
    if (!n || n->kind != SX_SYM) {
        RERR(&R, n ? n : x, "expected the name of a tree to use, found a %s", kind_of(n));
        return NULL;
    }
    const def *d = lookup_def(&R, n);
    if (!d)
        return NULL;
    tt_node **given = calloc((size_t)(d->np > 0 ? d->np : 1), sizeof *given);
    int *pidx = calloc((size_t)(d->np > 0 ? d->np : 1), sizeof *pidx);
    binding *b = calloc((size_t)(np > 0 ? np : 1), sizeof *b);
    tt_tree *t = tree_new(d->name, d->np + np);
    if (!given || !pidx || !t || !b) {
        RERR(&R, x, "out of memory");
        goto fail;
    }
    /* the used tree's params the use leaves, then the other names */
    for (int i = 0; i < d->np; i++) {
        int gv = 0;
        for (const sx *p = n->next; p; p = p->next)
            gv |= p->kind == SX_LIST && p->head && sx_is(p->head, d->pn[i]);
        pidx[i] = -1;
        if (gv)
            continue;
        int k = t->nparams;
        if (!(t->pname[k] = dupstr(d->pn[i]))) {
            RERR(&R, x, "out of memory");
            goto fail;
        }
        t->pdef[k] = d->pd[i];
        t->pmin[k] = d->pmin ? d->pmin[i] : -1e300, t->pmax[k] = d->pmax ? d->pmax[i] : 1e300;
        pidx[i] = k;
        t->nparams++;
    }
    int nb = 0;
    for (int j = 0; j < np; j++) {
        int own = 0;
        for (int i = 0; i < d->np; i++)
            own |= !strcmp(d->pn[i], pnames[j]);
        if (own)
            continue;
        int k = t->nparams;
        if (!(t->pname[k] = dupstr(pnames[j]))) {
            RERR(&R, x, "out of memory");
            goto fail;
        }
        t->pdef[k] = pdefs ? pdefs[j] : 0;
        t->pmin[k] = -1e300, t->pmax[k] = 1e300;
        t->nparams++;
        b[nb].name = pnames[j], b[nb].param = k, b[nb].expr = NULL;
        nb++;
    }
    R.b = b, R.nb = nb;
    if (use_args(&R, d, n, given, 0))
        goto fail;
    R.b = NULL, R.nb = 0;
    if (!(t->root = expand(&R, d, given, pidx, n, 0)) || tt_check(t, err, errlen))
        goto fail;
    for (int i = 0; i < d->np; i++)
        tt_node_free(given[i]);
    free(given);
    free(pidx);
    free(b);
    return t;
fail:
    for (int i = 0; given && i < d->np; i++)
        tt_node_free(given[i]);
    free(given);
    free(pidx);
    free(b);
    tt_tree_free(t);
    return NULL;
}

tt_tree *tt_tree_inline(tt_file *defs, const sx_doc *d, const sx *x, const char *dir, int np,
                        const char *const *pnames, const double *pdefs, char *err, size_t errlen) {
    tt_file *own = NULL;
    if (!defs && !(defs = own = file_new(d->path))) {
        sx_error(d, x, err, errlen, "out of memory");
        return NULL;
    }
    tt_tree *t = NULL;
    if (x->kind == SX_STR) { /* a .tt file: its last tree */
        char *p = join(dir, x->text);
        int e = p ? sx_file_ok(p) : ENOMEM;
        if (e)
            sx_error(d, x, err, errlen, "cannot read the tree file '%s': %s", p ? p : x->text, sx_file_strerror(e));
        else {
            tt_file *g = tt_file_read(p, NULL, 0, err, errlen);
            if (g)
                t = tt_tree_clone(tt_file_tree(g, -1));
            tt_file_free(g);
        }
        free(p);
    } else if (x->kind == SX_LIST && sx_is(x->head, "use")) {
        t = inline_use(defs, d, x, dir, np, pnames, pdefs, err, errlen);
    } else {
        t = tree_new("", np);
        binding *b = calloc((size_t)(np ? np : 1), sizeof *b);
        if (!t || !b) {
            sx_error(d, x, err, errlen, "out of memory");
            tt_tree_free(t);
            free(b);
            t = NULL;
        } else {
            int ok = 1;
            for (int i = 0; i < np && ok; i++) {
                ok = (t->pname[i] = dupstr(pnames[i])) != NULL;
                t->nparams = i + 1;
                t->pdef[i] = pdefs ? pdefs[i] : 0;
                t->pmin[i] = -1e300, t->pmax[i] = 1e300;
                b[i].name = pnames[i], b[i].param = i;
            }
            rd R = {defs, d, dir, b, np, {0}, 0, 0, err, errlen};
            t->root = ok ? expr(&R, x, 0) : NULL;
            free(b);
            if (!t->root || tt_check(t, err, errlen)) {
                tt_tree_free(t);
                t = NULL;
            }
        }
    }
    tt_file_free(own);
    return t;
}
