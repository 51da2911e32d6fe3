/* elab.c: syntax lines -> Circuit.
 *
 * Includes are expanded and blocks instantiated; every element line is
 * lowered by its kind's descriptor (blocks/, through lower.h) to primitive
 * elements in SI units.  This file keeps what every kind shares: names,
 * nodes and scopes, values and their checks, models, and the checks of
 * the whole circuit. */
#include <ctype.h>
#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "lower.h"

typedef struct BlockDef {
    const char *name;
    Line *head;   /* the .block line */
    Vec lines;    /* Line* of its body */
    Map formals;  /* formal node name -> its index in head->args */
    long size;    /* elements an instance adds, nested blocks expanded */
    int sized;    /* size: 0 not yet, 1 being counted, 2 known */
} BlockDef;

/* One level of block instantiation. */
typedef struct Scope {
    const char *prefix;   /* "" at top level, "inst." inside */
    BlockDef *def;
    int *formal_node;     /* actual node of each formal node */
    Expr **bparam;        /* actual value of each block param (kv of head) */
    struct Scope *parent;
    SrcPos usepos;        /* the instance name on its `use` line */
} Scope;

/* The kinds of names, each checked for names that differ only in case. */
enum { NS_NODE, NS_ELEM, NS_PARAM, NS_INPUT, NS_MODEL, NS_BLOCK, NS_OUT, NS_N };

typedef struct Elab {
    Circuit *c;
    Vec nodes;     /* const char* */
    Vec elems;     /* Elem* */
    Vec params;    /* Param* */
    Vec inputs;    /* const char* */
    Vec input_fn;  /* SrcFn*, parallel to inputs (NULL: none) */
    Vec input_pos; /* SrcPos* of each .input name, parallel to inputs (NULL: a deck's own) */
    Vec outs;      /* Probe* */
    Vec ics;       /* IcSpec* */
    Vec models;    /* Line* */
    Vec blocks;    /* BlockDef* */
    Vec top;       /* Line* of the top level, includes expanded */
    Vec names;     /* Elem names' first positions, parallel to elems */
    Vec incstack;  /* const char* resolved paths being included */
    Vec mutators;  /* Mutator* */
    Vec couplings; /* Coupling* */
    Vec wgs;       /* Waveguide* */
    /* names -> indices into the vectors above */
    Map node_ix, param_ix, input_ix, model_ix, block_ix, out_ix;
    Map elem_ix;   /* element name -> index of the first element of that name */
    bool elem_ix_stale; /* while mutators take elements out: search elems */
    Map dropped_ix; /* resistors to nodes nothing else meets, taken out -> 1 */
    Vec dropped;    /* Dropped*: those resistors, for check_graph's messages */
    Map paired_ix;  /* a diode merged into the one it faces -> index of that one's name in paired */
    Map perfect_ix; /* a perfectly coupled winding, taken out -> 1 */
    Vec paired;     /* const char*: the diodes that took in their facing twins */
    Map fold_ix[NS_N]; /* each namespace's names in lower case -> index in fold_name */
    Vec fold_name[NS_N]; /* the first spelling of each */
    long nelements; /* element lines elaborated, blocks expanded */
    IcSpec **ic_at[2]; /* node -> its .ic v(node) [0] or x(node) [1], or NULL */
    bool have_voice, have_domain, have_rate;
    double rate_given; /* the voice's rate if the caller gives it (> 0): a .tran step too fine is no
                          error, and lowering checks against it */
    double temp;    /* a deck's temperature (C): .temp, .options temp= */
    SrcPos endpos;  /* the last line of the main file, for whole-netlist errors */
} Elab;

/* What a kind's lowering works on: the elaboration, and the scope of the
 * line it lowers. */
struct Lower {
    Elab *E;
    Scope *S;
};

/* ---- names ---- */

/* Two names of one kind that differ only in case are one name mistyped
 * (SPICE reads them as one): an error at the second. */
static void case_check(Elab *E, int ns, const char *name, SrcPos pos) {
    static const char *const what[NS_N] = {"node", "element", "param", "input", "model", "block", "output"};
    char *low = arena_strdup(name);
    for (char *q = low; *q; q++)
        *q = (char)tolower((unsigned char)*q);
    int i = map_get(&E->fold_ix[ns], low);
    if (i < 0) {
        vec_push(&E->fold_name[ns], (void *)name);
        map_put(&E->fold_ix[ns], low, E->fold_name[ns].len - 1);
    } else if (strcmp(E->fold_name[ns].data[i], name))
        error_at(pos, "%s '%s' differs from %s '%s' only in case", what[ns], name, what[ns],
                 (const char *)E->fold_name[ns].data[i]);
}

static bool is_ground(const char *s) { return !strcmp(s, "0") || !strcasecmp(s, "gnd"); }

static int find_str(Vec *v, const char *s) {
    for (int i = 0; i < v->len; i++)
        if (!strcmp(v->data[i], s))
            return i;
    return -1;
}

static int find_param(Elab *E, const char *s) { return map_get(&E->param_ix, s); }

static int find_input(Elab *E, const char *s) { return map_get(&E->input_ix, s); }

/* Index of the first element named s, or -1. */
static int elem_index(Elab *E, const char *s) {
    if (!E->elem_ix_stale)
        return map_get(&E->elem_ix, s);
    for (int i = 0; i < E->elems.len; i++)
        if (!strcmp(((Elem *)E->elems.data[i])->name, s))
            return i;
    return -1;
}

static Elem *find_elem(Elab *E, const char *s) {
    int i = elem_index(E, s);
    return i < 0 ? NULL : E->elems.data[i];
}

/* elem_ix again from elems, the first of each name winning. */
static void index_elems(Elab *E) {
    E->elem_ix = (Map){0};
    for (int i = 0; i < E->elems.len; i++) {
        const char *name = ((Elem *)E->elems.data[i])->name;
        if (map_get(&E->elem_ix, name) < 0)
            map_put(&E->elem_ix, name, i);
    }
    E->elem_ix_stale = false;
}

static bool is_c_ident(const char *s) {
    if (!isalpha((unsigned char)*s) && *s != '_')
        return false;
    for (; *s; s++)
        if (!isalnum((unsigned char)*s) && *s != '_')
            return false;
    return true;
}

/* C's keywords (C99 and C11), which no generated symbol may be named. */
static const char *const c_keywords[] = {
    "auto", "break", "case", "char", "const", "continue", "default", "do", "double", "else", "enum",
    "extern", "float", "for", "goto", "if", "inline", "int", "long", "register", "restrict", "return",
    "short", "signed", "sizeof", "static", "struct", "switch", "typedef", "union", "unsigned", "void",
    "volatile", "while", "_Alignas", "_Alignof", "_Atomic", "_Bool", "_Complex", "_Generic",
    "_Imaginary", "_Noreturn", "_Static_assert", "_Thread_local",
};

/* Why a voice name cannot be used, or NULL if it can.  The voice's name
 * names its files (NAME.c, NAME.h, beside wdvoice.h) and prefixes its C
 * symbols (NAME_real, NAME_state, NAME_class), which share a translation
 * unit with the voice ABI (wdvoice.h: wdv_*, WDV_*) and, in a host, the
 * runtime (wdrt_*); an LV2 bundle also holds NAME.ttl. */
static const char *voice_name_clash(const char *s) {
    if (!is_c_ident(s))
        return "is not a C identifier";
    for (size_t i = 0; i < sizeof c_keywords / sizeof c_keywords[0]; i++)
        if (!strcmp(s, c_keywords[i]))
            return "is a C keyword";
    if (s[0] == '_')
        return "starts with '_' (such C names are reserved)";
    if (!strcasecmp(s, "wdvoice"))
        return "would write its header over the voice ABI's, wdvoice.h";
    if (!strcmp(s, "manifest"))
        return "would write its LV2 description over the bundle's manifest.ttl";
    if (!strcmp(s, "wdv"))
        return "would define wdv_class, the voice ABI's own type";
    if (!strncasecmp(s, "wdv_", 4))
        return "takes the voice ABI's prefix wdv_";
    if (!strcmp(s, "wdrt") || !strncmp(s, "wdrt_", 5))
        return "takes the runtime's prefix wdrt_";
    return NULL;
}

/* Node index of a name in a scope, creating it if `create`. */
static int node_of(Elab *E, Scope *S, const char *name, SrcPos pos, bool create) {
    if (is_ground(name))
        return 0;
    if (S->def) {
        int i = map_get(&S->def->formals, name);
        if (i >= 0)
            return S->formal_node[i];
    }
    const char *full = S->prefix[0] ? format("%s%s", S->prefix, name) : name;
    int i = map_get(&E->node_ix, full);
    if (i >= 0)
        return i;
    if (!create)
        error_at(pos, "unknown node '%s'", full);
    full = arena_strdup(full);
    case_check(E, NS_NODE, full, pos);
    vec_push(&E->nodes, (void *)full);
    map_put(&E->node_ix, full, E->nodes.len - 1);
    return E->nodes.len - 1;
}

int lower_node(Lower *L, const char *name, SrcPos pos) { return node_of(L->E, L->S, name, pos, true); }

/* ---- expressions ---- */

static Expr *resolve(Elab *E, Scope *S, Expr *e);

static Expr *lookup_name(Elab *E, Scope *S, const char *name, SrcPos pos) {
    if (S && S->def) { /* a param of the block being instantiated */
        Line *h = S->def->head;
        for (int i = 0; i < h->nkv; i++)
            if (!strcmp(h->kv[i].key, name))
                return S->bparam[i];
    }
    int p = find_param(E, name);
    if (p < 0) {
        if (find_input(E, name) >= 0)
            error_at(pos, "'%s' is an audio input; only params may appear in values", name);
        error_at(pos, "unknown param '%s'", name);
    }
    Expr *e = arena_alloc(sizeof(Expr));
    e->kind = EX_PARAM;
    e->param = p;
    e->pos = pos;
    e->name = name;
    return e;
}

static Expr *resolve(Elab *E, Scope *S, Expr *e) {
    if (!e)
        return NULL;
    if (e->kind == EX_NAME)
        return lookup_name(E, S, e->name, e->pos);
    if (e->kind == EX_NUM || e->kind == EX_PARAM)
        return e;
    Expr *r = arena_alloc(sizeof(Expr));
    *r = *e;
    r->a = resolve(E, S, e->a);
    r->b = resolve(E, S, e->b);
    return r;
}

Expr *lower_value(Lower *L, const Value *v, const char *what) {
    if (v->kind == VAL_EXPR)
        return resolve(L->E, L->S, v->expr);
    if (v->kind == VAL_NAME)
        return lookup_name(L->E, L->S, v->name, v->pos);
    error_at(v->pos, "expected a number, {expression} or param name for %s", what);
}

static double fn_eval(FnKind fn, double a, double b) {
    switch (fn) {
    case FN_SQRT: return sqrt(a);
    case FN_EXP: return exp(a);
    case FN_LOG: return log(a);
    case FN_LOG10: return log10(a);
    case FN_SIN: return sin(a);
    case FN_COS: return cos(a);
    case FN_TAN: return tan(a);
    case FN_ABS: return fabs(a);
    case FN_POW: return pow(a, b);
    case FN_MIN: return a < b ? a : b;
    case FN_MAX: return a > b ? a : b;
    case FN_POTLIN: return a < 0 ? 0 : a > 1 ? 1 : a;
    case FN_POTLOG: a = a < 0 ? 0 : a > 1 ? 1 : a; return (pow(10, 2 * a) - 1) / 99;
    case FN_TAPON: return a > 0 && a < 1 ? 1 : 1e-9;
    case FN_COUNT: break;
    }
    unreachable();
}

double expr_eval(const Expr *e, const double *p) {
    switch (e->kind) {
    case EX_NUM: return e->num;
    case EX_PARAM: return p[e->param];
    case EX_NAME: die("unresolved name '%s'", e->name);
    case EX_NEG: return -expr_eval(e->a, p);
    case EX_ADD: return expr_eval(e->a, p) + expr_eval(e->b, p);
    case EX_SUB: return expr_eval(e->a, p) - expr_eval(e->b, p);
    case EX_MUL: return expr_eval(e->a, p) * expr_eval(e->b, p);
    case EX_DIV: return expr_eval(e->a, p) / expr_eval(e->b, p);
    case EX_POW: return pow(expr_eval(e->a, p), expr_eval(e->b, p));
    case EX_CALL: return fn_eval(e->fn, expr_eval(e->a, p), e->b ? expr_eval(e->b, p) : 0);
    }
    unreachable();
}

uint64_t expr_params(const Expr *e) {
    if (!e)
        return 0;
    if (e->kind == EX_PARAM)
        return e->param < 64 ? (uint64_t)1 << e->param : ~(uint64_t)0;
    return expr_params(e->a) | expr_params(e->b);
}

bool expr_is_const(const Expr *e) { return expr_params(e) == 0; }

double *circuit_defaults(const Circuit *c) {
    double *p = arena_alloc(sizeof(double) * (size_t)(c->nparams + 1));
    for (int i = 0; i < c->nparams; i++)
        p[i] = c->params[i].def;
    return p;
}

double elem_value(const Circuit *c, const Elem *e, const double *params) {
    (void)c;
    return e->val ? expr_eval(e->val, params) : 0;
}

double elem_drive(const Circuit *c, const Elem *e, const double *params) {
    (void)c;
    return e->drive ? expr_eval(e->drive, params) : 0;
}

/* ---- includes and blocks ---- */

static void collect(Elab *E, Program *prog, BlockDef *into);

static const char *resolve_path(SrcFile *from, const char *name) {
    if (name[0] == '/')
        return name;
    const char *slash = strrchr(from->path, '/');
    if (slash) {
        const char *p = format("%.*s/%s", (int)(slash - from->path), from->path, name);
        struct stat st; /* not fopen: opening a FIFO would wait for a writer */
        if (stat(p, &st) == 0)
            return p;
    }
    return name;
}

static void include(Elab *E, Line *l, BlockDef *into) {
    if (l->nargs != 1 || (l->args[0].kind != VAL_STRING && l->args[0].kind != VAL_NAME))
        error_at(l->pos, "expected a file name after .include");
    const char *path = resolve_path(l->pos.file, l->args[0].name);
    char real[PATH_MAX];
    const char *key = realpath(path, real) ? arena_strdup(real) : path;
    if (find_str(&E->incstack, key) >= 0)
        error_at(l->args[0].pos, "include cycle: '%s' is already being read", l->args[0].name);
    if (E->incstack.len > 32)
        error_at(l->args[0].pos, "includes nested too deeply");
    size_t len;
    char *text = read_file(path, &len);
    if (!text) {
        const char *why = read_file_refused(errno);
        if (why)
            error_at(l->args[0].pos, "included file '%s' %s", l->args[0].name, why);
        error_at(l->args[0].pos, "cannot read included file '%s'", l->args[0].name);
    }
    if (strlen(text) != len)
        error_at(l->args[0].pos, "included file '%s' contains a NUL byte", l->args[0].name);
    SrcFile *f = srcfile_new(path, text);
    f->spice = l->pos.file->spice;
    f->includer = l->pos.file;
    f->inc_line = l->pos.line;
    f->inc_col = l->pos.col;
    vec_push(&E->incstack, (void *)key);
    E->c->hash = (E->c->hash ^ (uint32_t)len) * 16777619u;
    for (const char *p = text; *p; p++)
        E->c->hash = (E->c->hash ^ (unsigned char)*p) * 16777619u;
    collect(E, parse_file(f), into);
    E->incstack.len--;
}

/* Sorts lines into the top level or the block being defined. */
static void collect(Elab *E, Program *prog, BlockDef *into) {
    BlockDef *cur = into;
    for (int i = 0; i < prog->nlines; i++) {
        Line *l = &prog->lines[i];
        if (!strcmp(l->head, ".include")) {
            include(E, l, cur);
        } else if (!strcmp(l->head, ".block")) {
            if (cur)
                error_at(l->pos, "'.block' inside the definition of block '%s' (blocks do not nest)",
                         cur->name);
            if (map_get(&E->block_ix, l->name) >= 0)
                error_at(l->namepos, "duplicate block name '%s'", l->name);
            case_check(E, NS_BLOCK, l->name, l->namepos);
            cur = arena_alloc(sizeof(BlockDef));
            cur->name = l->name;
            cur->head = l;
            for (int j = 0; j < l->nargs; j++) /* the first of a repeated name counts */
                if (map_get(&cur->formals, l->args[j].name) < 0)
                    map_put(&cur->formals, l->args[j].name, j);
            vec_push(&E->blocks, cur);
            map_put(&E->block_ix, l->name, E->blocks.len - 1);
        } else if (!strcmp(l->head, ".endblock") || !strcmp(l->head, ".ends")) {
            if (!cur || cur == into)
                error_at(l->pos, "'%s' without a matching '.block'", l->head);
            cur = into;
        } else if (cur) {
            if (l->head[0] == '.' && strcmp(l->head, ".end"))
                error_at(l->pos, "directive '%s' is not allowed inside a block", l->head);
            vec_push(&cur->lines, l);
        } else {
            vec_push(&E->top, l);
        }
    }
    if (cur != into)
        error_at(cur->head->pos, "block '%s' has no '.endblock'", cur->name);
}

/* ---- directives ---- */

static bool has_names(const Expr *e) {
    return e && (e->kind == EX_NAME || e->kind == EX_PARAM || has_names(e->a) || has_names(e->b));
}

/* A value that must be known at compile time: a number or a braced
 * expression of numbers, never of params. */
double lower_const(const Value *v, const char *what) {
    if (v->kind != VAL_EXPR || has_names(v->expr))
        error_at(v->pos, "%s must be a number (params are not known at compile time)", what);
    double x = expr_eval(v->expr, NULL);
    if (!isfinite(x))
        error_at(v->pos, "%s is not a finite number", what);
    return x;
}

/* The largest magnitude of a source's drive or of an initial condition,
 * in SI units (V, A, m/s, N, m, Pa, ...).  No physical voice comes near it
 * (a petavolt), and it keeps the voice's arithmetic finite: waves are sums
 * of a few such values, and energies their squares over port resistances,
 * which in single precision must stay below FLT_MAX (3.4e38); 1e308 in
 * double overflows at the first sum. */
#define MAX_MAGNITUDE 1e15

/* Refuses x at pos unless |x| <= MAX_MAGNITUDE at the default params and
 * with each param it reads alone at either finite bound. */
void lower_magnitude(Lower *L, const Expr *x, SrcPos pos, const char *what, const char *unit) {
    Elab *E = L->E;
    double *p = arena_alloc(sizeof(double) * (size_t)(E->params.len + 1));
    for (int j = 0; j < E->params.len; j++)
        p[j] = ((Param *)E->params.data[j])->def;
    double v = expr_eval(x, p);
    if (!(fabs(v) <= MAX_MAGNITUDE))
        error_at(pos, "%s is %s; its magnitude must not exceed %g %s", what,
                 isnan(v) ? "not a number" : format("%g %s", v, unit), MAX_MAGNITUDE, unit);
    for (int j = 0; j < E->params.len && j < 64; j++) {
        if (!(expr_params(x) >> j & 1))
            continue;
        const Param *pr = E->params.data[j];
        for (int s = 0; s < 2; s++) {
            double save = p[j];
            p[j] = s ? pr->max : pr->min;
            v = isfinite(p[j]) ? expr_eval(x, p) : 0;
            if (!(fabs(v) <= MAX_MAGNITUDE))
                error_at(pos, "%s %s when param '%s' = %g; its magnitude must not exceed %g %s "
                         "(narrow the param's range)", what,
                         isnan(v) ? "is not a number" : format("reaches %g %s", v, unit), pr->name, p[j],
                         MAX_MAGNITUDE, unit);
            p[j] = save;
        }
    }
}

static void dir_param(Elab *E, Line *l) {
    if (!is_c_ident(l->name))
        error_at(l->namepos, "param name '%s' is not an identifier", l->name);
    if (find_param(E, l->name) >= 0)
        error_at(l->namepos, "duplicate param '%s'", l->name);
    if (find_input(E, l->name) >= 0)
        error_at(l->namepos, "'%s' is already an input", l->name);
    Param *p = arena_alloc(sizeof(Param));
    p->name = l->name;
    p->pos = l->namepos;
    p->unit = "";
    p->min = -INFINITY;
    p->max = INFINITY;
    const Value *v = &l->args[0];
    p->def = lower_const(v, format("the default of param '%s'", l->name));
    SrcPos minpos = l->pos;
    for (int i = 0; i < l->nkv; i++) {
        KeyVal *k = &l->kv[i];
        if (!strcmp(k->key, "unit")) {
            if (k->val.kind == VAL_LIST) {
                const Token *a = &k->val.toks[0], *b = &k->val.toks[k->val.ntoks - 1];
                p->unit = arena_strndup(a->text, (size_t)(b->text + b->len - a->text));
            } else if (k->val.kind == VAL_NAME || k->val.kind == VAL_STRING) {
                p->unit = k->val.name;
            } else {
                error_at(k->val.pos, "unit= takes a word, such as unit=Hz");
            }
            for (const char *q = p->unit; *q; q++)
                if (*q == '"' || *q == '\\' || *q == ' ')
                    error_at(k->val.pos, "unit= may not contain quotes, spaces or backslashes");
            continue;
        }
        if (strcmp(k->key, "min") && strcmp(k->key, "max"))
            error_at(k->pos, "unknown key '%s' for .param (expected min=, max= or unit=)", k->key);
        double x = lower_const(&k->val, format("%s= of param '%s'", k->key, l->name));
        if (!strcmp(k->key, "min")) {
            p->min = x;
            minpos = k->pos;
        } else {
            p->max = x;
        }
    }
    if (!(p->min <= p->max))
        error_at(minpos, "param '%s' has min greater than max", l->name);
    if (p->def < p->min || p->def > p->max)
        error_at(v->pos, "default %g of param '%s' lies outside [%g, %g]", p->def, l->name, p->min,
                 p->max);
    case_check(E, NS_PARAM, p->name, l->namepos);
    vec_push(&E->params, p);
    map_put(&E->param_ix, p->name, E->params.len - 1);
}

/* A SPICE deck's keys are its kind's keys in any case.  A model's keys
 * that the kind does not model (a diode's RS, CJO, TT, BV...) are noted
 * and left out, so a vendor's model pastes in. */
static void spice_keys(Line *l, int kind, bool model) {
    int n = 0;
    for (int i = 0; i < l->nkv; i++) {
        KeyVal *k = &l->kv[i];
        const KindKey *kk = block_desc[kind].kind->keys;
        while (kk->name && strcasecmp(kk->name, k->key))
            kk++;
        if (kk->name)
            k->key = kk->name;
        else if (model && !(kind == BK_D && !strcmp(k->key, "level"))) {
            note_at(k->pos, "%s model '%s': %s= is not modelled and is ignored", block_desc[kind].desc, l->name,
                    k->key);
            continue;
        }
        l->kv[n++] = *k;
    }
    l->nkv = n;
}

/* SPICE's diode model kind is D; its keys go as spice_keys says. */
static void spice_model(Line *l) {
    const char *k = l->args[0].name;
    int kind = block_by_keyword(k, (int)strlen(k));
    if (kind < 0 && strlen(k) == 1)
        kind = block_by_letter((char)toupper((unsigned char)k[0]));
    if (kind < 0 && (!strcasecmp(k, "npn") || !strcasecmp(k, "pnp")))
        kind = BK_Q;
    if (kind >= 0 && kind != BK_USE)
        spice_keys(l, kind, true);
}

static void dir_simple(Elab *E, Line *l) {
    Circuit *c = E->c;
    const char *d = l->head;
    if (!strcmp(d, ".temp") || !strcmp(d, ".options")) { /* a deck's temperature sets its diodes' kT/q */
        const Value *t = NULL;
        for (int i = 0; i < l->nkv; i++)
            if (!strcmp(l->kv[i].key, "temp"))
                t = &l->kv[i].val;
        if (!strcmp(d, ".temp"))
            t = &l->args[0];
        if (t) {
            E->temp = lower_const(t, "the temperature");
            if (!(E->temp > -273.15 && E->temp < 1000))
                error_at(t->pos, "the temperature must be above -273.15 C and below 1000 C");
        }
        if (l->nkv > (t && strcmp(d, ".temp") ? 1 : 0) || (!t && !strcmp(d, ".options")))
            note_at(l->headpos, "of '%s', the voice takes only the temperature (temp=); the rest is skipped", d);
    } else if (!strcmp(d, ".tran")) { /* a deck's step and length: the render's rate and length */
        double step = lower_const(&l->args[0], "the step of .tran"), stop = lower_const(&l->args[1], "the stop time of .tran");
        if (!(step > 0))
            error_at(l->args[0].pos, ".tran's step must be above 0");
        if (!(1 / step <= 1e7) && !(E->rate_given > 0))
            error_at(l->args[0].pos, ".tran's step gives a rate of %g Hz; it must be from 1 Hz to 10 MHz (or give the "
                     "voice's rate with --rate)", 1 / step);
        if (!(stop > 0) || !(stop <= 86400))
            error_at(l->args[1].pos, ".tran's stop time must be above 0 and at most a day");
        c->uic = l->nargs > 2 && l->args[2].kind == VAL_NAME && !strcmp(l->args[2].name, "uic");
        if (!E->have_rate && 1 / step <= 1e7) /* 10u is 100 kHz, not 99999.99999999999 */
            c->rate = fabs(1 / step - round(1 / step)) <= 1e-9 / step ? round(1 / step) : 1 / step;
        c->tstop = stop;
    } else if (!strcmp(d, ".voice")) {
        if (E->have_voice)
            error_at(l->pos, "second .voice line");
        const char *why = voice_name_clash(l->args[0].name);
        if (why)
            error_at(l->args[0].pos, "voice name '%s' %s", l->args[0].name, why);
        c->name = l->args[0].name;
        E->have_voice = true;
    } else if (!strcmp(d, ".domain")) {
        const char *s = l->args[0].name;
        if (!strcmp(s, "electrical"))
            c->domain = DOM_ELECTRICAL;
        else if (!strcmp(s, "mechanical"))
            c->domain = DOM_MECHANICAL;
        else if (!strcmp(s, "acoustic"))
            c->domain = DOM_ACOUSTIC;
        else
            error_at(l->args[0].pos, "unknown domain '%s' (expected electrical, mechanical or acoustic)", s);
        if (E->have_domain)
            error_at(l->pos, "second .domain line");
        E->have_domain = true;
    } else if (!strcmp(d, ".rate")) {
        const Value *v = &l->args[0];
        c->rate = lower_const(v, "the sample rate");
        if (!(c->rate >= 1 && c->rate <= 1e7))
            error_at(v->pos, "sample rate %g Hz is out of range (1 Hz to 10 MHz)", c->rate);
        if (E->have_rate)
            error_at(l->pos, "second .rate line");
        E->have_rate = true;
    } else if (!strcmp(d, ".input")) {
        for (int i = 0; i < l->nargs; i++) {
            const char *s = l->args[i].name;
            if (!is_c_ident(s))
                error_at(l->args[i].pos, "input name '%s' is not an identifier", s);
            if (find_input(E, s) >= 0)
                error_at(l->args[i].pos, "duplicate input '%s'", s);
            case_check(E, NS_INPUT, s, l->args[i].pos);
            vec_push(&E->inputs, (void *)s);
            vec_push(&E->input_fn, NULL);
            vec_push(&E->input_pos, &l->args[i].pos);
            map_put(&E->input_ix, s, E->inputs.len - 1);
        }
    } else if (!strcmp(d, ".model")) {
        if (l->pos.file->spice)
            spice_model(l);
        if (map_get(&E->model_ix, l->name) >= 0)
            error_at(l->namepos, "duplicate model '%s'", l->name);
        case_check(E, NS_MODEL, l->name, l->namepos);
        const char *k = l->args[0].name;
        int kind = block_by_keyword(k, (int)strlen(k));
        if (kind < 0 && strlen(k) == 1)
            kind = block_by_letter(k[0]);
        if (kind < 0 && !strcasecmp(k, "diode"))
            kind = BK_D;
        if (kind < 0 && (!strcasecmp(k, "npn") || !strcasecmp(k, "pnp")))
            kind = BK_Q;
        if (kind < 0 || kind == BK_USE)
            error_at(l->args[0].pos, "unknown model kind '%s'", k);
        for (int i = 0; i < l->nkv; i++)
            if (!block_has_key(kind, l->kv[i].key))
                error_at(l->kv[i].pos, "unknown key '%s' for a %s model", l->kv[i].key,
                         block_desc[kind].desc);
        l->model_kind = kind;
        vec_push(&E->models, l);
        map_put(&E->model_ix, l->name, E->models.len - 1);
    }
}

/* ---- elements: what a kind's lowering uses (lower.h), and element lines ---- */

KeyVal *lower_key(Line *l, const char *k) {
    for (int i = 0; i < l->nkv; i++)
        if (!strcmp(l->kv[i].key, k))
            return &l->kv[i];
    return NULL;
}

const Value *lower_arg(const Line *l) {
    int nn = block_desc[l->kind].kind->nnodes;
    return nn < l->nargs ? &l->args[nn] : NULL;
}

/* Adds element `name` (whole, prefix and all) of kind k from n0 to n1 for
 * line l, in scope S (NULL: elaboration adds it itself). */
static Elem *add_elem(Elab *E, Scope *S, Line *l, ElemKind k, const char *name, int n0, int n1) {
    Elem *prev = find_elem(E, name);
    if (prev) {
        if (S && S->def)
            error_at(S->usepos, "duplicate element name '%s' (in this instance of block '%s')", name,
                     S->def->name);
        SrcPos p = l->namepos;
        error_at(p, "duplicate element name '%s'", name);
    }
    case_check(E, NS_ELEM, name, l->namepos);
    Elem *e = arena_alloc(sizeof(Elem));
    e->kind = k;
    e->name = name;
    e->n[0] = n0;
    e->n[1] = n1;
    e->input = -1;
    e->pos = l->namepos;
    e->user_kind = l->kind;
    vec_push(&E->elems, e);
    if (!E->elem_ix_stale)
        map_put(&E->elem_ix, name, E->elems.len - 1);
    return e;
}

Elem *lower_elem(Lower *L, Line *l, ElemKind k, const char *suffix, int n0, int n1) {
    return add_elem(L->E, L->S, l, k, format("%s%s%s", L->S->prefix, l->name, suffix), n0, n1);
}

int lower_nelems(Lower *L) { return L->E->elems.len; }

const char *lower_prefix(Lower *L) { return L->S->prefix; }

double lower_rate(Lower *L) { return L->E->rate_given > 0 ? L->E->rate_given : L->E->c->rate; }

void lower_add_mutator(Lower *L, Mutator *m) { vec_push(&L->E->mutators, m); }
void lower_add_coupling(Lower *L, Coupling *k) { vec_push(&L->E->couplings, k); }

int lower_add_waveguide(Lower *L, Waveguide *w) {
    vec_push(&L->E->wgs, w);
    return L->E->wgs.len - 1;
}

Expr *lower_need(Lower *L, Line *l, const char *k) {
    KeyVal *kv = lower_key(l, k);
    if (!kv)
        error_at(l->namepos, "%s '%s' needs %s=", block_desc[l->kind].desc, l->name, k);
    return lower_value(L, &kv->val, k);
}

/* The thermal voltage kT/q a diode takes when its model gives no Vt: at
 * a deck's temperature (27 C unless .temp or .options temp= says), with
 * SPICE's constants, or 25.852 mV in a .wdn. */
double lower_vt(Lower *L, const Line *l) {
    if (!l->pos.file->spice)
        return 25.852e-3;
    return 1.38064852e-23 * (L->E->temp + 273.15) / 1.6021766208e-19;
}

Expr *lower_key_or(Lower *L, Line *l, const char *k, double def) {
    KeyVal *kv = lower_key(l, k);
    return kv ? lower_value(L, &kv->val, k) : expr_num(def, l->pos);
}

void lower_drive(Lower *L, Elem *e, const Value *v) {
    Elab *E = L->E;
    Scope *S = L->S;
    if (v->kind == VAL_NAME) {
        int in = find_input(E, v->name);
        if (in >= 0) {
            e->input = in;
            return;
        }
        if (find_param(E, v->name) < 0 && !(S->def && lower_key(S->def->head, v->name)))
            error_at(v->pos, "unknown input or param '%s' (declare inputs with .input)", v->name);
    }
    e->drive = lower_value(L, v, "the drive");
    lower_magnitude(L, e->drive, v->pos, format("the drive of %s '%s'", block_desc[e->user_kind].desc, e->name),
                    domain_unit(E->c->domain, e->kind == E_V ? 'v' : 'i'));
}

double lower_expr_min(Lower *L, Expr *e, SrcPos pos, const char *what) {
    Elab *E = L->E;
    double *p = arena_alloc(sizeof(double) * (size_t)(E->params.len + 1));
    for (int j = 0; j < E->params.len; j++)
        p[j] = ((Param *)E->params.data[j])->def;
    double m = expr_eval(e, p);
    for (int j = 0; j < E->params.len && j < 64; j++) {
        if (!(expr_params(e) >> j & 1))
            continue;
        Param *pr = E->params.data[j];
        if (!isfinite(pr->min) || !isfinite(pr->max))
            error_at(pos, "%s depends on param '%s', which needs min= and max= (they size the delay lines)", what,
                     pr->name);
        for (int s = 0; s < 2; s++) {
            double save = p[j];
            p[j] = s ? pr->max : pr->min;
            double v = expr_eval(e, p);
            m = v < m || v != v ? v : m;
            p[j] = save;
        }
    }
    return m;
}

static void check_keys(Line *l) {
    if (l->pos.file->spice)
        spice_keys(l, l->kind, false);
    for (int i = 0; i < l->nkv; i++)
        if (!block_has_key(l->kind, l->kv[i].key) && strcmp(l->kv[i].key, "model"))
            error_at(l->kv[i].pos, "unknown key '%s' for %s '%s'", l->kv[i].key,
                     block_desc[l->kind].desc, l->name);
}

Line *lower_model(Lower *L, const Value *v) {
    if (v->kind != VAL_NAME)
        error_at(v->pos, "expected a model name");
    int i = map_get(&L->E->model_ix, v->name);
    if (i >= 0)
        return L->E->models.data[i];
    error_at(v->pos, "unknown model '%s'", v->name);
}

Line *lower_model_keys(Line *l, const Line *m) {
    Line *r = arena_alloc(sizeof(Line));
    *r = *l;
    r->kv = arena_alloc(sizeof(KeyVal) * (size_t)(l->nkv + m->nkv + 1));
    r->nkv = 0;
    for (int i = 0; i < l->nkv; i++)
        if (strcmp(l->kv[i].key, "model"))
            r->kv[r->nkv++] = l->kv[i];
    for (int i = 0; i < m->nkv; i++)
        if (!lower_key(l, m->kv[i].key))
            r->kv[r->nkv++] = m->kv[i];
    return r;
}

/* model=NAME: the model's keys become defaults of the element's. */
static Line *with_model(Lower *L, Line *l) {
    KeyVal *mk = lower_key(l, "model");
    if (!mk)
        return l;
    Line *m = lower_model(L, &mk->val);
    if (m->model_kind != l->kind)
        error_at(mk->val.pos, "model '%s' is a %s model, not a %s model", m->name,
                 block_desc[m->model_kind].desc, block_desc[l->kind].desc);
    return lower_model_keys(l, m);
}

/* The most elements a netlist may hold once its blocks are expanded, and
 * the deepest instances may nest.  Past either, the `use` line that would
 * cross it is refused: a few lines can otherwise ask for more than any
 * machine holds (a block used twice in each of 40 nested blocks is 2^40
 * elements). */
#define MAX_ELEMENTS 1000000
#define MAX_BLOCK_DEPTH 64

static void instantiate(Elab *E, Scope *S, Line *l);

/* An element line: counted, its keys checked, a model's keys lent, its
 * nodes numbered, then lowered by its kind. */
/* A SPICE deck's independent source, V1 a b [[DC] v] [AC mag [phase]]
 * [SIN(...) | PULSE(...) | PWL(...) | EXP(...)]: with AC or a time
 * function it is driven by an input named after it (v1; x1_v1 in an
 * instance), which a render without --input drives with that function
 * or its DC value; with a DC value alone it is that constant. */
static Line *spice_source(Elab *E, Scope *S, Line *l) {
    if (l->nargs == 3 && l->args[2].kind == VAL_NAME &&
        (find_input(E, l->args[2].name) >= 0 || find_param(E, l->args[2].name) >= 0))
        return l; /* driven by an input or param, as in a .wdn */
    SrcFn *f = arena_alloc(sizeof(SrcFn));
    bool ac = false, have_dc = false;
    f->kind = 'd';
    f->pos = l->namepos;
    for (int i = 2; i < l->nargs; i++) {
        const Value *v = &l->args[i];
        const char *w = v->kind == VAL_NAME ? v->name : "";
        if (v->kind == VAL_EXPR && !have_dc) {
            f->dc = lower_const(v, "a source's DC value"), have_dc = true;
        } else if (!strcmp(w, "dc") && i + 1 < l->nargs && l->args[i + 1].kind == VAL_EXPR) {
            f->dc = lower_const(&l->args[++i], "a source's DC value"), have_dc = true;
        } else if (!strcmp(w, "ac")) {
            ac = true;
            for (int k = 0; k < 2 && i + 1 < l->nargs && l->args[i + 1].kind == VAL_EXPR; k++)
                lower_const(&l->args[++i], "a source's AC magnitude or phase");
        } else if ((!strcmp(w, "sin") || !strcmp(w, "pulse") || !strcmp(w, "pwl") || !strcmp(w, "exp")) &&
                   i + 1 < l->nargs && l->args[i + 1].kind == VAL_LIST && f->kind == 'd') {
            const Value *list = &l->args[++i];
            f->kind = w[1] == 'i' ? 's' : w[1] == 'u' ? 'p' : w[1] == 'w' ? 'w' : 'e';
            f->v = arena_alloc(sizeof(double) * (size_t)(list->ntoks + 1));
            for (int k = 0; k < list->ntoks; k++) {
                const Token *t = &list->toks[k];
                if (t->kind == TK_COMMA)
                    continue;
                if (t->kind != TK_NUMBER)
                    error_at(t->pos, "expected a number in %s(...), found '%.*s'", w, t->len, t->text);
                if (!isfinite(t->num))
                    error_at(t->pos, "%s(...) takes finite numbers", w);
                f->v[f->nv++] = t->num;
            }
            static const int need[] = {['s'] = 3, ['p'] = 2, ['w'] = 2, ['e'] = 2};
            if (f->nv < need[(int)f->kind] || (f->kind == 'w' && f->nv % 2))
                error_at(list->pos, f->kind == 'w' ? "pwl(...) takes time, value pairs"
                                                   : "%s(...) needs at least %d values", w, need[(int)f->kind]);
            for (int k = 2; f->kind == 'w' && k < f->nv; k += 2)
                if (!(f->v[k] >= f->v[k - 2]))
                    error_at(list->pos, "pwl(...) times must not go back");
        } else {
            error_at(v->pos, "expected DC, AC, SIN(...), PULSE(...), PWL(...) or EXP(...) in source '%s'", l->name);
        }
    }
    if (!isfinite(f->dc))
        error_at(l->namepos, "source '%s' has a DC value that is not finite", l->name);
    Line *n = arena_alloc(sizeof(Line));
    *n = *l;
    n->nargs = 3;
    n->args = arena_alloc(sizeof(Value) * 4);
    n->args[0] = l->args[0], n->args[1] = l->args[1];
    Value *drive = &n->args[2];
    drive->pos = l->namepos;
    if (!ac && f->kind == 'd') {
        drive->kind = VAL_EXPR;
        drive->expr = expr_num(f->dc, l->namepos);
        return n;
    }
    char *in = format("%s%s", S->prefix, l->name);
    for (char *q = in; *q; q++)
        if (!isalnum((unsigned char)*q))
            *q = '_';
    if (find_input(E, in) >= 0 || find_param(E, in) >= 0)
        error_at(l->namepos, "source '%s' would be driven by input '%s', but that name is taken", l->name, in);
    vec_push(&E->inputs, in);
    vec_push(&E->input_fn, f);
    vec_push(&E->input_pos, NULL);
    map_put(&E->input_ix, in, E->inputs.len - 1);
    drive->kind = VAL_NAME;
    drive->name = in;
    return n;
}

static void element(Elab *E, Scope *S, Line *l) {
    const Kind *d = block_desc[l->kind].kind;
    if (l->kind == BK_USE) {
        instantiate(E, S, l);
        return;
    }
    if (l->pos.file->spice && (l->kind == BK_V || l->kind == BK_I) && l->nargs >= 2)
        l = spice_source(E, S, l);
    if (E->nelements >= MAX_ELEMENTS)
        error_at(l->namepos, "the netlist holds more than %d elements", MAX_ELEMENTS);
    E->nelements++;
    check_keys(l);
    Lower L = {E, S};
    l = with_model(&L, l);
    int node[4] = {0};
    for (int i = 0; i < d->nnodes && i < 4; i++)
        node[i] = node_of(E, S, l->args[i].name, l->args[i].pos, true);
    if (!d->ready)
        error_at(l->headpos, "%s '%s' is not supported yet", d->desc, l->name);
    Elem *e = d->lower(&L, l, node);
    if (e && e->n[0] == e->n[1])
        error_at(l->args[0].pos, "%s '%s' has both terminals on node '%s'", d->desc, l->name,
                 l->args[0].name);
}

/* The block a `use` line names, or NULL. */
static BlockDef *used_block(Elab *E, const Line *l) {
    int i = map_get(&E->block_ix, l->args[0].name);
    return i < 0 ? NULL : E->blocks.data[i];
}

static long add_sat(long a, long b) { return a + b > MAX_ELEMENTS ? MAX_ELEMENTS + 1 : a + b; }

/* Elements an instance of def adds, nested instances expanded (past
 * MAX_ELEMENTS: MAX_ELEMENTS + 1).  Depth-first with a stack of its own,
 * since blocks may nest as deeply as a file is long; an unknown block or
 * one that uses itself counts nothing here (instantiating reports it). */
static long block_size(Elab *E, BlockDef *def) {
    typedef struct { BlockDef *def; int line; } Frame;
    if (def->sized == 2)
        return def->size;
    int cap = 16, sp = 0;
    Frame *st = arena_alloc(sizeof(Frame) * (size_t)cap);
    st[sp++] = (Frame){def, 0};
    def->sized = 1;
    while (sp) {
        Frame *f = &st[sp - 1];
        if (f->line == f->def->lines.len) {
            f->def->sized = 2;
            if (--sp)
                st[sp - 1].def->size = add_sat(st[sp - 1].def->size, f->def->size);
            continue;
        }
        Line *l = f->def->lines.data[f->line++];
        BlockDef *d = l->kind == BK_USE ? used_block(E, l) : NULL;
        if (l->kind < 0 || (l->kind == BK_USE && (!d || d->sized == 1)))
            continue;
        if (l->kind != BK_USE || d->sized == 2) {
            f->def->size = add_sat(f->def->size, d ? d->size : 1);
            continue;
        }
        if (sp == cap) {
            Frame *g = arena_alloc(sizeof(Frame) * (size_t)(2 * cap));
            memcpy(g, st, sizeof(Frame) * (size_t)cap);
            st = g;
            cap *= 2;
        }
        d->sized = 1;
        st[sp++] = (Frame){d, 0};
    }
    return def->size;
}

/* Refuses an instance that would nest too deeply or hold too much. */
static void check_expansion(Elab *E, Scope *S, Line *l, BlockDef *def) {
    int depth = 0;
    for (Scope *s = S; s; s = s->parent)
        depth += s->def != NULL;
    if (depth >= MAX_BLOCK_DEPTH)
        error_at(l->args[0].pos, "instance '%s' of block '%s' nests instances more than %d deep", l->name,
                 def->name, MAX_BLOCK_DEPTH);
    long n = block_size(E, def);
    if (n > MAX_ELEMENTS)
        error_at(l->args[0].pos, "instance '%s' of block '%s' expands to more than %d elements, the most a "
                 "netlist may hold", l->name, def->name, MAX_ELEMENTS);
    if (E->nelements + n > MAX_ELEMENTS)
        error_at(l->args[0].pos, "instance '%s' of block '%s' adds %ld elements to the %ld before it: more "
                 "than the %d a netlist may hold", l->name, def->name, n, E->nelements, MAX_ELEMENTS);
}

static void instantiate(Elab *E, Scope *S, Line *l) {
    const char *bname = l->args[0].name;
    BlockDef *def = used_block(E, l);
    if (!def)
        error_at(l->args[0].pos, "unknown block '%s'", bname);
    for (Scope *s = S; s; s = s->parent)
        if (s->def == def)
            error_at(l->args[0].pos, "block '%s' uses itself", bname);
    Line *h = def->head;
    if (l->nargs - 1 != h->nargs)
        error_at(l->namepos, "block '%s' has %d node%s, instance '%s' gives %d", bname, h->nargs,
                 h->nargs == 1 ? "" : "s", l->name, l->nargs - 1);
    check_expansion(E, S, l, def);
    Scope *in = arena_alloc(sizeof(Scope));
    in->prefix = format("%s%s.", S->prefix, l->name);
    in->def = def;
    in->parent = S;
    in->usepos = l->namepos;
    in->formal_node = arena_alloc(sizeof(int) * (size_t)(h->nargs + 1));
    for (int i = 0; i < h->nargs; i++)
        in->formal_node[i] = node_of(E, S, l->args[i + 1].name, l->args[i + 1].pos, true);
    in->bparam = arena_alloc(sizeof(Expr *) * (size_t)(h->nkv + 1));
    for (int i = 0; i < l->nkv; i++)
        if (!lower_key(h, l->kv[i].key))
            error_at(l->kv[i].pos, "block '%s' has no param '%s'", bname, l->kv[i].key);
    for (int i = 0; i < h->nkv; i++) {
        KeyVal *given = lower_key(l, h->kv[i].key);
        in->bparam[i] = given ? lower_value(&(Lower){E, S}, &given->val, h->kv[i].key)
                              : lower_value(&(Lower){E, S->def ? S : &(Scope){.prefix = ""}}, &h->kv[i].val,
                                            h->kv[i].key);
    }
    for (int i = 0; i < def->lines.len; i++) {
        Line *bl = def->lines.data[i];
        if (bl->kind >= 0)
            element(E, in, bl);
    }
}

/* use BLOCK INST nodes... key=value...: an instance of a block, which
 * instantiate expands rather than a lowering. */
static const KindKey use_keys[] = {{NULL, NULL}};

const Kind kind_use = {
    .desc = "block instance",
    .keyword = "use",
    .nnodes = -1,
    .args = "",
    .keys = use_keys,
    .ready = true,
    .law = "those of the block's elements",
    .lowers_to = "the block's elements, named INST.NAME",
};

/* Each mutator takes the nonlinear resistor across its second port, which
 * must be alone there, and becomes a nonlinear reactance at its first. */
static void mutate(Elab *E) {
    E->elem_ix_stale = E->mutators.len > 0; /* elements move and change names below */
    for (int k = 0; k < E->mutators.len; k++) {
        Mutator *m = E->mutators.data[k];
        int found = -1, others = 0;
        for (int i = 0; i < E->elems.len; i++) {
            Elem *e = E->elems.data[i];
            bool across = (e->n[0] == m->n[2] && e->n[1] == m->n[3]) || (e->n[0] == m->n[3] && e->n[1] == m->n[2]);
            bool touches = e->n[0] == m->n[2] || e->n[0] == m->n[3] || e->n[1] == m->n[2] || e->n[1] == m->n[3];
            if (across && e->kind == E_NL && e->nl->kind != NL_CONTACT && !e->nl->mutated && found < 0)
                found = i;
            else if (touches)
                others++;
        }
        if (found < 0)
            error_at(m->pos, "mutator '%s' needs a diode or nonlinear resistor across its second port", m->name);
        if (others || m->n[2] == 0 || m->n[3] == 0)
            error_at(m->pos, "mutator '%s': its second port must hold only the nonlinear resistor, on nodes of "
                     "its own (not ground)", m->name);
        Elem *in = E->elems.data[found];
        NlSpec *nl = arena_alloc(sizeof(NlSpec));
        *nl = *in->nl;
        if (in->n[0] != m->n[2]) { /* the resistor runs d -> c: its curve turns over */
            if (nl->kind == NL_DIODE && !nl->pair)
                error_at(in->pos, "the diode '%s' on mutator '%s' must have its anode on the mutator's third node",
                         in->name, m->name);
            if (nl->kind == NL_CURVE) {
                double *v = arena_alloc(sizeof(double) * (size_t)nl->npts), *c = arena_alloc(sizeof(double) * (size_t)nl->npts);
                for (int j = 0; j < nl->npts; j++) {
                    v[j] = -nl->cv[nl->npts - 1 - j];
                    c[j] = -nl->ci[nl->npts - 1 - j];
                }
                nl->cv = v;
                nl->ci = c;
            }
        }
        if (nl->solver_pos.file && nl->solver != SOLVER_NEWTON)
            error_at(nl->solver_pos, "through a mutator the element has memory: only solver=newton applies");
        nl->solver = SOLVER_NEWTON;
        nl->mutated = m->type;
        /* the resistor leaves the network; the reactance takes the mutator's name */
        E->elems.data[found] = E->elems.data[--E->elems.len];
        Elem *e = add_elem(E, NULL, m->line, E_NL, m->name, m->n[0], m->n[1]);
        e->nl = nl;
        e->user_kind = BK_MUTATOR;
    }
    if (!E->mutators.len)
        return;
    /* the nodes of the mutators' second ports are left with no element */
    int *map = arena_alloc(sizeof(int) * (size_t)E->nodes.len);
    bool *used = arena_alloc(sizeof(bool) * (size_t)E->nodes.len);
    used[0] = true;
    for (int i = 0; i < E->elems.len; i++)
        for (int k = 0; k < 2; k++)
            used[((Elem *)E->elems.data[i])->n[k]] = true;
    Vec nodes = {0};
    E->node_ix = (Map){0};
    for (int n = 0; n < E->nodes.len; n++)
        if (used[n]) {
            map[n] = nodes.len;
            vec_push(&nodes, E->nodes.data[n]);
            map_put(&E->node_ix, E->nodes.data[n], nodes.len - 1);
        }
    for (int i = 0; i < E->elems.len; i++)
        for (int k = 0; k < 2; k++)
            ((Elem *)E->elems.data[i])->n[k] = map[((Elem *)E->elems.data[i])->n[k]];
    E->nodes = nodes;
    index_elems(E);
}

/* A node of its own for what elaboration adds, named after `base`. */
static int fresh_node(Elab *E, const char *base) {
    const char *name = format("%s.x", base);
    while (map_get(&E->node_ix, name) >= 0)
        name = format("%s.x", name);
    vec_push(&E->nodes, (void *)name);
    map_put(&E->node_ix, name, E->nodes.len - 1);
    return E->nodes.len - 1;
}

#define MAX_WINDINGS 16

/* Coupled inductors (K lines).  The inductors that couplings join form a
 * group, the windings of one core; their inductance matrix must be
 * D + s s^T with D diagonal and not negative: k_ij = sigma_i sigma_j c_i
 * c_j for the pair i, j, with 0 < c_i <= 1 and signs sigma_i (sigma of
 * the first winding +1), which any two windings satisfy (c = sqrt|k|)
 * and more windings satisfy when each pair's coupling is the product of
 * its windings' (every pair needs its K line).  Then s_i = sigma_i c_i
 * sqrt(L_i), D_i = (1 - c_i^2) L_i, and the group is realised as:
 *   - the magnetising inductance s_1^2 = c_1^2 L_1 across the first
 *     winding behind its leakage (named after it, L1.m);
 *   - winding i's leakage D_i in series from its first node (taking the
 *     inductor's name), none when D_i is 0 (|k| = 1): then no element
 *     carries the winding's current alone, and i() of it is refused;
 *   - an ideal transformer (E_XF NAME.Li, its probe NAME.Li.in across the
 *     magnetising inductance) of ratio s_i / s_1 behind it.
 * The inductances are constants (the transformer's ratio is). */
static void couple(Elab *E) {
    int nk = E->couplings.len;
    if (!nk)
        return;
    int ne = E->elems.len;
    int *at = arena_alloc(sizeof(int) * (size_t)(2 * nk)); /* each end's element */
    int *grp = arena_alloc(sizeof(int) * (size_t)(ne + 1)); /* union-find over elements */
    for (int i = 0; i < ne; i++)
        grp[i] = i;
    for (int j = 0; j < nk; j++) {
        Coupling *k = E->couplings.data[j];
        for (int s = 0; s < 2; s++) {
            int i = elem_index(E, k->ind[s]);
            Elem *e = i < 0 ? NULL : E->elems.data[i];
            if (!e)
                error_at(k->indpos[s], "coupling '%s' names '%s', which is not an element of the netlist", k->name,
                         k->ind[s]);
            if (e->kind != E_L || e->user_kind != BK_L)
                error_at(k->indpos[s], "coupling '%s' names '%s', which is a %s, not an inductor", k->name,
                         k->ind[s], block_desc[e->user_kind].desc);
            if (expr_params(e->val))
                error_at(k->indpos[s], "coupled inductor '%s' must have a constant inductance, not one that "
                         "depends on a param", k->ind[s]);
            at[2 * j + s] = i;
        }
        if (at[2 * j] == at[2 * j + 1])
            error_at(k->indpos[1], "coupling '%s' couples '%s' with itself", k->name, k->ind[0]);
        int a = at[2 * j], b = at[2 * j + 1];
        while (grp[a] != a)
            a = grp[a];
        while (grp[b] != b)
            b = grp[b];
        grp[a > b ? a : b] = a < b ? a : b;
    }
    bool *gone = arena_alloc(sizeof(bool) * (size_t)(ne + 1));
    bool *done = arena_alloc(sizeof(bool) * (size_t)(ne + 1));
    for (int j0 = 0; j0 < nk; j0++) {
        int root = at[2 * j0];
        while (grp[root] != root)
            root = grp[root];
        if (done[root])
            continue;
        done[root] = true;
        Coupling *first = E->couplings.data[j0];
        /* the group's windings, in the order the couplings name them */
        int w[MAX_WINDINGS], n = 0;
        double kk[MAX_WINDINGS][MAX_WINDINGS] = {{0}};
        Coupling *by[MAX_WINDINGS][MAX_WINDINGS] = {{0}};
        for (int j = j0; j < nk; j++) {
            int r = at[2 * j];
            while (grp[r] != r)
                r = grp[r];
            if (r != root)
                continue;
            Coupling *k = E->couplings.data[j];
            int ix[2];
            for (int s = 0; s < 2; s++) {
                ix[s] = -1;
                for (int m = 0; m < n; m++)
                    if (w[m] == at[2 * j + s])
                        ix[s] = m;
                if (ix[s] < 0) {
                    if (n == MAX_WINDINGS)
                        error_at(k->indpos[s], "more than %d inductors are coupled together", MAX_WINDINGS);
                    ix[s] = n;
                    w[n++] = at[2 * j + s];
                }
            }
            if (by[ix[0]][ix[1]])
                error_at(k->line->namepos, "coupling '%s' couples '%s' and '%s' again (after '%s')", k->name,
                         k->ind[0], k->ind[1], by[ix[0]][ix[1]]->name);
            kk[ix[0]][ix[1]] = kk[ix[1]][ix[0]] = k->k;
            by[ix[0]][ix[1]] = by[ix[1]][ix[0]] = k;
        }
        for (int a = 0; a < n; a++)
            for (int b = a + 1; b < n; b++)
                if (!by[a][b])
                    error_at(first->line->namepos, "'%s' and '%s' are coupled through others but no K line couples "
                             "them: the windings of one core need a coupling for each pair",
                             ((Elem *)E->elems.data[w[a]])->name, ((Elem *)E->elems.data[w[b]])->name);
        /* c_i from any two others: k_ij k_il / k_jl = c_i^2 */
        double cc[MAX_WINDINGS], sg[MAX_WINDINGS];
        for (int i = 0; i < n; i++) {
            int j = i == 0 ? 1 : 0, l = i == 2 ? 1 : 2; /* two others */
            cc[i] = n == 2 ? sqrt(fabs(kk[0][1])) : sqrt(fabs(kk[i][j] * kk[i][l] / kk[j][l]));
            sg[i] = i == 0 ? 1 : (kk[0][i] < 0 ? -1 : 1);
            if (!(cc[i] <= 1 + 1e-12))
                error_at(first->line->namepos, "the couplings of '%s' with the other windings would need it "
                         "coupled more than perfectly (%g): they are not those of one core",
                         ((Elem *)E->elems.data[w[i]])->name, cc[i]);
            cc[i] = fmin(cc[i], 1);
        }
        for (int a = 0; a < n; a++)
            for (int b = a + 1; b < n; b++)
                if (fabs(kk[a][b] - sg[a] * sg[b] * cc[a] * cc[b]) > 1e-9)
                    error_at(by[a][b]->kpos, "coupling '%s' gives %g where the group's other couplings give %g: "
                             "the couplings are not those of windings on one core (k_ij = c_i c_j)",
                             by[a][b]->name, kk[a][b], sg[a] * sg[b] * cc[a] * cc[b]);
        /* realise */
        double L[MAX_WINDINGS];
        for (int i = 0; i < n; i++)
            L[i] = expr_eval(((Elem *)E->elems.data[w[i]])->val, NULL);
        int x1 = 0, b1 = ((Elem *)E->elems.data[w[0]])->n[1];
        for (int i = 0; i < n; i++) {
            Elem *e = E->elems.data[w[i]];
            double D = (1 - cc[i] * cc[i]) * L[i];
            bool leak = D > 1e-12 * L[i];
            if (!leak && e->ic)
                error_at(e->pos, "'%s' is coupled perfectly (|k| = 1): no element carries its current alone, "
                         "so it cannot take an initial current", e->name);
            int x = leak ? fresh_node(E, e->name) : e->n[0], b = e->n[1];
            if (i == 0)
                x1 = x;
            if (leak) { /* the inductor becomes its leakage, up to x */
                e->n[1] = x;
                e->val = expr_num(D, e->pos);
            } else { /* no element carries its current alone: it goes */
                gone[w[i]] = true;
                map_put(&E->perfect_ix, e->name, 1);
            }
            if (i == 0) { /* the magnetising inductance, x to b1 */
                Elem *m = add_elem(E, NULL, first->line, E_L, format("%s.m", e->name), x, b1);
                m->user_kind = BK_L;
                m->pos = e->pos;
                m->ic = leak ? e->ic : NULL;
                /* its current: the first winding's and what the others
                 * draw through their transformers */
                for (int j = 1; j < n; j++) {
                    Elem *f = E->elems.data[w[j]];
                    Expr *g = expr_num(sg[j] * cc[j] * sqrt(L[j]) / (cc[0] * sqrt(L[0])), f->pos);
                    if (f->ic)
                        m->ic = m->ic ? expr_bin(EX_ADD, m->ic, expr_bin(EX_MUL, g, f->ic)) : expr_bin(EX_MUL, g, f->ic);
                }
                m->val = expr_num(cc[0] * cc[0] * L[0], e->pos);
                continue;
            }
            Coupling *k = by[0][i];
            Elem *t = add_elem(E, NULL, k->line, E_XF, format("%s.%s", k->name, e->name), x, b);
            t->val = expr_num(sg[i] * cc[i] * sqrt(L[i]) / (cc[0] * sqrt(L[0])), k->kpos);
            add_elem(E, NULL, k->line, E_P, format("%s.in", t->name), x1, b1);
        }
    }
    Vec elems = {0};
    for (int i = 0; i < E->elems.len; i++)
        if (i >= ne || !gone[i])
            vec_push(&elems, E->elems.data[i]);
    E->elems = elems;
    index_elems(E);
}

/* The value of a diode's key when it holds no param, else NaN. */
static double fixed(const Expr *e) { return e && !has_names(e) ? expr_eval(e, NULL) : NAN; }

/* Two diodes facing each other across one pair of nodes with the same
 * law (the usual symmetric clipper) are one antiparallel pair, whose
 * closed form (pair=1) gives the same answer as solving the two: the
 * first takes the second in.  Diodes that differ, or carry params, stay
 * two, which the root solves jointly. */
static void pair_diodes(Elab *E) {
    int ne = E->elems.len, n = 0;
    bool *gone = arena_alloc(sizeof(bool) * (size_t)(ne + 1));
    for (int i = 0; i < ne; i++) {
        Elem *a = E->elems.data[i];
        if (gone[i] || a->kind != E_NL || a->nl->kind != NL_DIODE || a->nl->pair || a->nl->mutated ||
            a->user_kind == BK_Q)
            continue;
        for (int j = i + 1; j < ne; j++) {
            Elem *b = E->elems.data[j];
            if (gone[j] || b->kind != E_NL || b->nl->kind != NL_DIODE || b->nl->pair || b->nl->mutated ||
                b->user_kind == BK_Q ||
                b->n[0] != a->n[1] || b->n[1] != a->n[0] || b->nl->solver != a->nl->solver)
                continue;
            double ka[3] = {fixed(a->nl->Is), fixed(a->nl->n), fixed(a->nl->Vt)};
            double kb[3] = {fixed(b->nl->Is), fixed(b->nl->n), fixed(b->nl->Vt)};
            if (!(ka[0] == kb[0] && ka[1] == kb[1] && ka[2] == kb[2]))
                continue;
            a->nl->pair = true;
            gone[j] = true;
            vec_push(&E->paired, (void *)a->name);
            map_put(&E->paired_ix, b->name, E->paired.len - 1);
            break;
        }
    }
    Vec elems = {0};
    for (int i = 0; i < ne; i++)
        if (!gone[i])
            vec_push(&elems, E->elems.data[i]), n++;
    if (n == ne)
        return;
    E->elems = elems;
    index_elems(E);
}

typedef struct Dropped {
    const char *name, *far; /* the resistor, and the node nothing else met */
    int near;               /* the node it hung from, numbered as after the drop */
} Dropped;

/* A resistor to a node that nothing else meets carries no current, and
 * that node has the potential of the resistor's other end (SPICE allows
 * it: an output read through a resistor that leads nowhere).  Each such
 * resistor leaves the network, repeatedly (a chain of them goes), and
 * its far node becomes another name of its near one; a probe of the
 * resistor's current reads 0. */
static void drop_dangling(Elab *E) {
    int nn = E->nodes.len, ne = E->elems.len;
    int *deg = arena_alloc(sizeof(int) * (size_t)nn), *alias = arena_alloc(sizeof(int) * (size_t)nn);
    bool *gone = arena_alloc(sizeof(bool) * (size_t)(ne + 1));
    int *ends = arena_alloc(sizeof(int) * (size_t)(ne + 1)); /* a dropped one's far node */
    for (int i = 0; i < ne; i++)
        for (int k = 0; k < 2; k++)
            deg[((Elem *)E->elems.data[i])->n[k]]++;
    for (int n = 0; n < nn; n++)
        alias[n] = n;
    int dropped = 0;
    for (bool more = true; more;) {
        more = false;
        for (int i = 0; i < ne; i++) {
            Elem *e = E->elems.data[i];
            if (gone[i] || e->kind != E_R || e->n[0] == e->n[1])
                continue;
            for (int k = 0; k < 2; k++) {
                int far = e->n[k], near = e->n[!k];
                if (far == 0 || deg[far] != 1)
                    continue;
                gone[i] = more = true;
                ends[i] = far;
                dropped++;
                deg[far]--, deg[near]--;
                alias[far] = near;
                map_put(&E->dropped_ix, e->name, 1);
                break;
            }
        }
    }
    if (!dropped)
        return;
    int *map = arena_alloc(sizeof(int) * (size_t)nn);
    Vec nodes = {0}, elems = {0};
    for (int n = 0; n < nn; n++)
        if (alias[n] == n) {
            map[n] = nodes.len;
            vec_push(&nodes, E->nodes.data[n]);
        }
    E->node_ix = (Map){0};
    for (int n = 0; n < nn; n++) {
        int to = n;
        while (alias[to] != to)
            to = alias[to];
        map_put(&E->node_ix, E->nodes.data[n], map[to]);
    }
    for (int i = 0; i < ne; i++) {
        Elem *e = E->elems.data[i];
        if (!gone[i]) {
            for (int k = 0; k < 2; k++)
                e->n[k] = map[e->n[k]];
            vec_push(&elems, e);
            continue;
        }
        Dropped *d = arena_alloc(sizeof *d);
        int far = ends[i], near = alias[far];
        while (alias[near] != near)
            near = alias[near];
        *d = (Dropped){e->name, E->nodes.data[far], map[near]};
        vec_push(&E->dropped, d);
    }
    E->nodes = nodes;
    E->elems = elems;
    index_elems(E);
}

/* ---- probes and initial conditions ---- */

/* Index of the element a probe names. */
static int probe_elem(Elab *E, const Ref *r) {
    int i = elem_index(E, r->arg[0]);
    if (i >= 0)
        return i;
    if (find_elem(E, format("%s.aw", r->arg[0])) || find_elem(E, format("%s.wb", r->arg[0])))
        error_at(r->argpos[0], "'%s' is a pot: probe one half, %s.aw or %s.wb", r->arg[0],
                 r->arg[0], r->arg[0]);
    error_at(r->argpos[0], "unknown element '%s'", r->arg[0]);
}

static void dir_output(Elab *E, Line *l);

/* The vectors a deck's .print (.plot, .probe, .save) names, each an
 * output named after it (v(out): v_out; v(a,b): v_a_b; i(v1): i_v1); a
 * vector printed twice is one output. */
static void deck_outputs(Elab *E, Line *l) {
    for (int i = 0; i < l->nrefs; i++) {
        const Ref *r = &l->refs[i];
        char *name = format("%c_%s%s%s", r->fn, r->arg[0], r->arg[1] ? "_" : "", r->arg[1] ? r->arg[1] : "");
        for (char *q = name; *q; q++)
            if (!isalnum((unsigned char)*q))
                *q = '_';
        if (map_get(&E->out_ix, name) >= 0)
            continue;
        Line *o = arena_alloc(sizeof(Line));
        *o = *l;
        o->head = ".output";
        o->name = name;
        o->namepos = r->pos;
        o->nrefs = 1;
        o->refs = (Ref *)r;
        dir_output(E, o);
    }
}

static void dir_output(Elab *E, Line *l) {
    if (map_get(&E->out_ix, l->name) >= 0)
        error_at(l->namepos, "duplicate output '%s'", l->name);
    const Ref *r = &l->refs[0];
    Probe *p = arena_alloc(sizeof(Probe));
    p->name = l->name;
    p->pos = r->pos;
    Scope top = {.prefix = ""};
    if (r->fn == 'v' || r->fn == 'x') {
        p->kind = r->fn == 'v' ? PR_V : PR_X;
        for (int i = 0; i < 2; i++)
            p->n[i] = r->arg[i] ? node_of(E, &top, r->arg[i], r->argpos[i], false) : 0;
    } else {
        if (r->arg[1])
            error_at(r->argpos[1], "%c() takes one element name", r->fn);
        if (r->fn == 'f' && E->c->domain == DOM_ELECTRICAL)
            error_at(r->pos, "f() reads a force; this netlist is electrical (use i())");
        p->kind = r->fn == 'i' ? PR_I : PR_F;
        int twin = map_get(&E->paired_ix, r->arg[0]);
        if (twin >= 0)
            error_at(r->argpos[0], "diode '%s' faces '%s' and the two are solved as one antiparallel pair: probe "
                     "%c(%s), the pair's current", r->arg[0], (const char *)E->paired.data[twin], r->fn,
                     (const char *)E->paired.data[twin]);
        if (map_get(&E->perfect_ix, r->arg[0]) >= 0)
            error_at(r->argpos[0], "'%s' is coupled perfectly (|k| = 1): no element carries its current alone, "
                     "so %c(%s) cannot be read", r->arg[0], r->fn, r->arg[0]);
        p->elem = map_get(&E->dropped_ix, r->arg[0]) >= 0 ? -1 : probe_elem(E, r);
    }
    case_check(E, NS_OUT, p->name, l->namepos);
    vec_push(&E->outs, p);
    map_put(&E->out_ix, p->name, E->outs.len - 1);
}

/* The .ic conditions of kind fn ('v' or 'x') by node. */
static IcSpec **ic_table(Elab *E, char fn) {
    IcSpec ***t = &E->ic_at[fn == 'x'];
    if (!*t)
        *t = arena_alloc(sizeof(IcSpec *) * (size_t)E->nodes.len);
    return *t;
}

static void dir_ic(Elab *E, Line *l) {
    Scope top = {.prefix = ""};
    Lower at_top = {E, &top};
    for (int i = 0; i < l->nrefs; i++) {
        const Ref *r = &l->refs[i];
        if (r->fn != 'v' && r->fn != 'x')
            error_at(r->pos, ".ic sets v(node) or x(node), not %c()", r->fn);
        if (r->arg[1])
            error_at(r->argpos[1], ".ic takes one node per condition");
        IcSpec *ic = arena_alloc(sizeof(IcSpec));
        ic->fn = r->fn;
        ic->node = node_of(E, &top, r->arg[0], r->argpos[0], false);
        if (ic->node == 0)
            error_at(r->argpos[0], "ground has no initial condition");
        ic->val = lower_value(&at_top, &l->refvals[i], "the initial condition");
        lower_magnitude(&at_top, ic->val, l->refvals[i].pos, format("the initial condition %c(%s)", r->fn, r->arg[0]),
                        domain_unit(E->c->domain, r->fn));
        ic->pos = r->pos;
        IcSpec **at = ic_table(E, ic->fn);
        if (at[ic->node])
            error_at(r->pos, "second initial condition for %c(%s)", r->fn, r->arg[0]);
        at[ic->node] = ic;
        vec_push(&E->ics, ic);
    }
}

/* The .ic node values become element values: a capacitor gets
 * v(n0) - v(n1), an inductor (x - x) / L, since x is its flux. */
static void apply_ics(Elab *E) {
    for (int i = 0; i < E->elems.len; i++) {
        Elem *e = E->elems.data[i];
        if ((e->kind != E_C && e->kind != E_L) || e->ic)
            continue;
        IcSpec **at = E->ics.len ? ic_table(E, e->kind == E_C ? 'v' : 'x') : NULL;
        Expr *side[2] = {NULL, NULL};
        for (int k = 0; k < 2 && at; k++)
            side[k] = at[e->n[k]] ? at[e->n[k]]->val : NULL;
        if (!side[0] && !side[1])
            continue;
        SrcPos pos = e->pos;
        Expr *d = expr_bin(EX_SUB, side[0] ? side[0] : expr_num(0, pos),
                           side[1] ? side[1] : expr_num(0, pos));
        e->ic = e->kind == E_C ? d : expr_bin(EX_DIV, d, e->val);
    }
}

/* ---- checks ---- */

static void check_nl(const Circuit *c, const Elem *e, const double *p) {
    (void)c;
    const NlSpec *nl = e->nl;
    typedef struct { Expr *x; const char *name; double lo; bool strict; double hi; } Bound;
    Bound k[4];
    int n = 0;
    /* a diode's n Vt sets the scale of its solvers' errors: past 1000 x 1 V
     * (n of a thousand diodes in series, Vt of 11600 K) a voltage of one
     * is lost in them */
    if (nl->kind == NL_DIODE) {
        k[n++] = (Bound){nl->Is, "Is", 0, true, INFINITY};
        k[n++] = (Bound){nl->n, "n", 0, true, 1000};
        k[n++] = (Bound){nl->Vt, "Vt", 0, true, 1};
    } else if (nl->kind == NL_CONTACT) {
        k[n++] = (Bound){nl->k, "k", 0, true, INFINITY};
        k[n++] = (Bound){nl->alpha, "alpha", 1, false, INFINITY};
        k[n++] = (Bound){nl->lambda, "lambda", 0, false, INFINITY};
    }
    for (int i = 0; i < n; i++) {
        double v = expr_eval(k[i].x, p);
        if (!isfinite(v) || (k[i].strict ? !(v > k[i].lo) : !(v >= k[i].lo)) || v > k[i].hi)
            error_at(e->pos, "%s '%s' has %s = %g; it must be %s %g%s", block_desc[e->user_kind].desc, e->name,
                     k[i].name, v, k[i].strict ? "greater than" : "at least", k[i].lo,
                     isfinite(k[i].hi) ? format(" and at most %g", k[i].hi) : "");
    }
}

static void check_values(Elab *E) {
    Circuit *c = E->c;
    double *p = circuit_defaults(c);
    for (int i = 0; i < c->nelems; i++) {
        Elem *e = &c->elems[i];
        if (e->kind == E_V && !e->val)
            continue;
        if ((e->kind == E_I && !e->val) || ELEM_CONTROLLED(e->kind)) /* gains: checked as lowered */
            continue;
        if (e->kind == E_NL) {
            check_nl(c, e, p);
            continue;
        }
        double v = elem_value(c, e, p);
        if (!(v > 0) || !isfinite(v))
            error_at(e->pos, "%s '%s' has %s %g at the default params; it must be positive and finite",
                     block_desc[e->user_kind].desc, e->name,
                     e->kind == E_C ? "capacitance" : e->kind == E_L ? "inductance" : "resistance", v);
        /* each param alone at its bounds */
        for (int j = 0; j < c->nparams; j++) {
            if (!(expr_params(e->val) >> j & 1) || j >= 64)
                continue;
            for (int s = 0; s < 2; s++) {
                double save = p[j];
                p[j] = s ? c->params[j].max : c->params[j].min;
                if (isfinite(p[j])) {
                    double w = elem_value(c, e, p);
                    if (!(w > 0) || !isfinite(w))
                        error_at(e->pos, "%s '%s' reaches %g when param '%s' = %g; it must stay positive "
                                 "(narrow the param's range)", block_desc[e->user_kind].desc, e->name, w,
                                 c->params[j].name, p[j]);
                }
                p[j] = save;
            }
        }
    }
}

/* An input that no source reads is most likely a slip (a source's drive
 * given as a number, or the name spelt otherwise): the voice would
 * ignore what is fed to it. */
static void check_inputs(Elab *E) {
    const Circuit *c = E->c;
    bool *read = arena_alloc(sizeof(bool) * (size_t)(E->inputs.len + 1));
    for (int k = 0; k < c->nelems; k++)
        if (c->elems[k].input >= 0)
            read[c->elems[k].input] = true;
    for (int i = 0; i < E->inputs.len; i++) {
        const SrcPos *pos = E->input_pos.data[i];
        if (pos && !read[i])
            warn_at(*pos, "input '%s' drives nothing: no source reads it", (const char *)E->inputs.data[i]);
    }
}

/* Every node needs two connections and a path to ground. */
static void check_graph(Elab *E) {
    Circuit *c = E->c;
    if (c->nelems == 0)
        error_at(E->endpos, "the netlist has no elements");
    int *deg = arena_alloc(sizeof(int) * (size_t)c->nnodes);
    int *first = arena_alloc(sizeof(int) * (size_t)c->nnodes);
    for (int i = c->nelems - 1; i >= 0; i--)
        for (int k = 0; k < 2; k++) {
            deg[c->elems[i].n[k]]++;
            first[c->elems[i].n[k]] = i;
        }
    for (int n = 1; n < c->nnodes; n++) {
        if (deg[n] >= 2)
            continue;
        /* a resistor that led from it to a node nothing else meets has
         * left the network: say so, or the message names the wrong place */
        const char *why = "";
        for (int k = 0; k < E->dropped.len; k++) {
            const Dropped *d = E->dropped.data[k];
            if (d->near == n)
                why = format("; %s went on to '%s', which nothing else meets, and was taken out", d->name, d->far);
        }
        error_at(c->elems[first[n]].pos, "node '%s' has only one connection (%s)%s", c->nodes[n],
                 c->elems[first[n]].name, why);
    }
    if (deg[0] == 0)
        error_at(c->elems[0].pos, "nothing connects to ground (node 0)");
    /* the elements at each node (CSR), then a search from ground */
    int *start = arena_alloc(sizeof(int) * (size_t)(c->nnodes + 1));
    int *at = arena_alloc(sizeof(int) * (size_t)(2 * c->nelems + 1));
    for (int n = 0; n < c->nnodes; n++)
        start[n + 1] = start[n] + deg[n];
    int *fill = arena_alloc(sizeof(int) * (size_t)c->nnodes);
    for (int i = 0; i < c->nelems; i++)
        for (int k = 0; k < 2; k++) {
            int n = c->elems[i].n[k];
            at[start[n] + fill[n]++] = c->elems[i].n[!k];
        }
    int *seen = arena_alloc(sizeof(int) * (size_t)c->nnodes);
    int *stack = arena_alloc(sizeof(int) * (size_t)c->nnodes);
    int sp = 0;
    seen[0] = 1;
    stack[sp++] = 0;
    while (sp) {
        int n = stack[--sp];
        for (int j = start[n]; j < start[n + 1]; j++)
            if (!seen[at[j]]) {
                seen[at[j]] = 1;
                stack[sp++] = at[j];
            }
    }
    for (int n = 1; n < c->nnodes; n++)
        if (!seen[n])
            error_at(c->elems[first[n]].pos, "node '%s' has no path to ground (node 0)", c->nodes[n]);
}

static const char *base_name(const char *path) {
    const char *s = strrchr(path, '/');
    s = s ? s + 1 : path;
    const char *dot = strrchr(s, '.');
    char *n = arena_strndup(s, dot ? (size_t)(dot - s) : strlen(s));
    for (char *p = n; *p; p++)
        if (!isalnum((unsigned char)*p))
            *p = '_';
    if (!isalpha((unsigned char)n[0]) || voice_name_clash(n))
        n = format("v_%s", n); /* the file's name is not the user's choice of a C name */
    return n;
}

static void finish(Elab *E) {
    Circuit *c = E->c;
#define COPY(vec, field, count, T)                                          \
    c->count = E->vec.len;                                                   \
    c->field = arena_alloc(sizeof(T) * (size_t)(E->vec.len + 1));            \
    for (int i = 0; i < E->vec.len; i++)                                     \
        c->field[i] = *(T *)E->vec.data[i];
    COPY(elems, elems, nelems, Elem)
    COPY(params, params, nparams, Param)
    COPY(outs, outs, nouts, Probe)
    COPY(ics, ics, nics, IcSpec)
    COPY(wgs, wgs, nwgs, Waveguide)
#undef COPY
    /* peers by name: passes before this one drop elements */
    for (int i = 0; i < c->nelems; i++) {
        Elem *e = &c->elems[i];
        size_t n = strlen(e->name);
        if (e->kind == E_W)
            e->peer = elem_index(E, format("%.*s%c", (int)n - 1, e->name, e->name[n - 1] == '1' ? '2' : '1'));
        else if (e->kind == E_CV || e->kind == E_CI || e->kind == E_OA || e->kind == E_XF)
            e->peer = elem_index(E, format("%s.in", e->name));
        else if (e->kind == E_P)
            e->peer = elem_index(E, format("%.*s", (int)n - 3, e->name));
        else if (e->kind == E_CC) /* a transistor's NAME.f takes NAME.be's current, NAME.r NAME.bc's */
            e->peer = elem_index(E, format("%.*s.b%c", (int)n - 2, e->name, e->name[n - 1] == 'f' ? 'e' : 'c'));
        if ((e->kind == E_W || ELEM_CONTROLLED(e->kind)) && e->peer < 0)
            die("element '%s' lost its peer", e->name);
    }
    c->nnodes = E->nodes.len;
    c->nodes = (const char **)E->nodes.data;
    c->ninputs = E->inputs.len;
    c->inputs = (const char **)E->inputs.data;
    c->input_fn = arena_alloc(sizeof(SrcFn *) * (size_t)(E->inputs.len + 1));
    for (int i = 0; i < E->inputs.len; i++)
        c->input_fn[i] = i < E->input_fn.len ? E->input_fn.data[i] : NULL;
}

static Circuit *elaborate(SrcFile *f, double rate) {
    Elab E = {.temp = 27, .rate_given = rate};
    int lines = 1;
    for (const char *q = f->text; *q; q++)
        lines += *q == '\n' && q[1];
    E.endpos = (SrcPos){f, lines, 1};
    Circuit *c = E.c = arena_alloc(sizeof(Circuit));
    c->path = f->path;
    c->deck = f->spice;
    c->rate = 48000;
    c->hash = 2166136261u;
    for (const char *p = f->text; *p; p++)
        c->hash = (c->hash ^ (unsigned char)*p) * 16777619u;
    vec_push(&E.nodes, "0");
    map_put(&E.node_ix, "0", 0);
    char real[PATH_MAX];
    vec_push(&E.incstack, realpath(f->path, real) ? arena_strdup(real) : (char *)f->path);
    collect(&E, parse_file(f), NULL);
    for (int i = 0; i < E.top.len; i++) {
        Line *l = E.top.data[i];
        if (!strcmp(l->head, ".param") && l->pos.file->spice) {
            /* .param a=1 b=2: every key another param */
            Line one = *l;
            one.nkv = 0;
            dir_param(&E, &one);
            for (int k = 0; k < l->nkv; k++) {
                Line *p = arena_alloc(sizeof(Line));
                *p = one;
                p->name = l->kv[k].key;
                p->namepos = l->kv[k].pos;
                p->args = &l->kv[k].val;
                p->nargs = 1;
                dir_param(&E, p);
            }
        } else if (!strcmp(l->head, ".param"))
            dir_param(&E, l);
        else if (!strcmp(l->head, ".skip"))
            continue;
        else if (l->kind < 0)
            dir_simple(&E, l);
    }
    if (E.params.len > 64)
        error_at(((Param *)E.params.data[64])->pos, "more than 64 params");
    Scope top = {.prefix = ""};
    for (int i = 0; i < E.top.len; i++) {
        Line *l = E.top.data[i];
        if (l->kind >= 0)
            element(&E, &top, l);
    }
    mutate(&E);
    couple(&E);
    pair_diodes(&E);
    drop_dangling(&E);
    for (int i = 0; i < E.top.len; i++) {
        Line *l = E.top.data[i];
        if (l->pos.file->spice && (!strcmp(l->head, ".print") || !strcmp(l->head, ".plot") ||
                                   !strcmp(l->head, ".probe") || !strcmp(l->head, ".save")))
            deck_outputs(&E, l);
        else if (!strcmp(l->head, ".output"))
            dir_output(&E, l);
        else if (!strcmp(l->head, ".ic"))
            dir_ic(&E, l);
    }
    if (!c->name)
        c->name = base_name(f->path);
    apply_ics(&E);
    finish(&E);
    check_graph(&E);
    check_inputs(&E);
    check_values(&E);
    return c;
}

static Circuit *load(SrcFile *f, double rate) {
    jmp_buf jb;
    jmp_buf *saved = diag.jmp;
    diag.jmp = &jb;
    Circuit *c = NULL;
    if (!setjmp(jb))
        c = elaborate(f, rate);
    diag.jmp = saved;
    return c;
}

Circuit *wdc_elaborate_string(const char *name, const char *text) {
    SrcFile *f = srcfile_new(name, arena_strdup(text));
    f->spice = is_spice_path(name);
    return load(f, 0);
}

Circuit *wdc_elaborate(const char *path) { return wdc_elaborate_at(path, 0); }

Circuit *wdc_elaborate_at(const char *path, double rate) {
    size_t len;
    char *text = read_file(path, &len);
    if (!text) {
        const char *why = read_file_refused(errno);
        FILE *out = diag.out ? diag.out : stderr;
        if (why)
            fprintf(out, "%s: error: the netlist %s\n", path, why);
        else
            fprintf(out, "%s: error: cannot read the netlist: %s\n", path, strerror(errno));
        diag.errors++;
        return NULL;
    }
    int line, col;
    if (text_nul(text, len, &line, &col)) {
        fprintf(diag.out ? diag.out : stderr, "%s:%d:%d: error: the file contains a NUL byte\n", path, line, col);
        diag.errors++;
        return NULL;
    }
    SrcFile *f = srcfile_new(path, text);
    f->spice = is_spice_path(path);
    return load(f, rate);
}

const char *domain_unit(Domain d, char fn) {
    bool mech = d == DOM_MECHANICAL;
    bool ac = d == DOM_ACOUSTIC;
    switch (fn) {
    case 'v': return mech ? "m/s" : ac ? "Pa" : "V";
    case 'i': case 'f': return mech ? "N" : ac ? "m^3/s" : "A";
    case 'x': return mech ? "m" : ac ? "Pa*s" : "V*s";
    }
    return "";
}

void circuit_dump(const Circuit *c, FILE *out) {
    static const char *const kn[] = {[E_R] = "R", [E_C] = "C",   [E_L] = "L", [E_V] = "V",
                                     [E_I] = "I", [E_NL] = "NL", [E_W] = "W", [E_S] = "S",
                                     [E_CV] = "E", [E_CI] = "G", [E_OA] = "OA", [E_P] = "P",
                                     [E_CC] = "F", [E_XF] = "XF"};
    double *p = circuit_defaults(c);
    fprintf(out, "voice %s, %d nodes, %d elements, rate %g\n", c->name, c->nnodes, c->nelems, c->rate);
    for (int i = 0; i < c->nelems; i++) {
        const Elem *e = &c->elems[i];
        if ((unsigned)e->kind >= sizeof kn / sizeof kn[0] || !kn[e->kind])
            die("element '%s' of unknown kind %d", e->name, (int)e->kind);
        fprintf(out, "  %s %s %s %s", kn[e->kind], e->name, c->nodes[e->n[0]], c->nodes[e->n[1]]);
        if (e->val)
            fprintf(out, " %.6g", elem_value(c, e, p));
        if (e->input >= 0)
            fprintf(out, " <- %s", c->inputs[e->input]);
        else if (e->drive)
            fprintf(out, " = %.6g", elem_drive(c, e, p));
        if (e->ic)
            fprintf(out, " ic=%.6g", expr_eval(e->ic, p));
        fputc('\n', out);
    }
}
