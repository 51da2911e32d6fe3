/* parse.c: tokens -> syntax lines, and braced expressions -> Expr.
 *
 * The grammar, one production per function below:
 *
 *   netlist   = line* EOF
 *   line      = EOL | directive EOL | element EOL
 *   element   = NAME node{n} arg* keyval*       (kind from NAME's letter)
 *             | KEYWORD NAME node{n} arg* keyval*
 *   keyval    = WORD '=' value
 *   value     = NUMBER | '{' expr '}' | WORD | STRING | '(' token* ')'
 *               (a value followed by '@', ',' or ':' runs on as a list)
 *   directive = '.voice' NAME | '.domain' WORD | '.rate' value
 *             | '.input' NAME+ | '.param' NAME ['='] value keyval*
 *             | '.model' NAME KIND keyval* | '.include' (STRING | WORD)
 *             | '.block' NAME node* keyval* | '.endblock'
 *             | '.output' NAME ref | '.ic' (ref '=' value)+ | '.end'
 *   ref       = WORD '(' WORD [',' WORD] ')'
 *
 *   expr      = term (('+' | '-') term)*
 *   term      = unary (('*' | '/') unary)*
 *   unary     = ('-' | '+') unary | power
 *   power     = primary [('^' | '**') unary]
 *   primary   = NUMBER | NAME | NAME '(' expr [',' expr] ')' | '(' expr ')'
 */
#include <ctype.h>
#include <math.h>
#include <string.h>

#include "gen.h"

typedef struct Parser {
    Token *tok;   /* current token */
    SrcFile *file;
} Parser;

static char *tok_str(const Token *t) { return arena_strndup(t->text, (size_t)t->len); }

static bool at_eol(Parser *P) { return P->tok->kind == TK_EOL || P->tok->kind == TK_EOF; }

static bool is_punct(const Token *t, char c) {
    return t->len == 1 && t->text[0] == c && t->kind != TK_STRING && t->kind != TK_LBRACE;
}

/* ---- expressions ---- */

typedef struct ELex {
    const char *p, *start;
    SrcPos base; /* position of the first character inside the braces */
    char kind;   /* 'n' number, 'w' word, 'e' end, or the punctuation char */
    int depth;   /* nesting of the production being parsed */
    int nodes;   /* nodes built so far */
    const char *text;
    int len;
    double num;
    SrcPos pos;
} ELex;

static void enext(ELex *E) {
    while (*E->p == ' ' || *E->p == '\t')
        E->p++;
    E->text = E->p;
    E->pos = E->base;
    E->pos.col += (int)(E->p - E->start);
    if (!*E->p) {
        E->kind = 'e';
        E->len = 0;
        return;
    }
    if (isalnum((unsigned char)*E->p) || *E->p == '_' || *E->p == '.') {
        const char *q = E->p;
        bool numeric = isdigit((unsigned char)*q) || *q == '.';
        while (isalnum((unsigned char)*q) || *q == '_' || *q == '.' ||
               (numeric && (*q == '+' || *q == '-') && (q[-1] == 'e' || q[-1] == 'E') &&
                isdigit((unsigned char)q[1])))
            q++;
        E->len = (int)(q - E->p);
        E->p = q;
        if (numeric) {
            const char *why;
            if (!lex_number_in(E->text, E->len, &E->num, &why, E->base.file && E->base.file->spice))
                error_at(E->pos, "malformed number '%.*s': %s", E->len, E->text, why);
            E->kind = 'n';
        } else {
            E->kind = 'w';
        }
        return;
    }
    if (E->p[0] == '*' && E->p[1] == '*') {
        E->kind = '^';
        E->len = 2;
        E->p += 2;
        return;
    }
    if (strchr("+-*/^(),", *E->p)) {
        E->kind = *E->p;
        E->len = 1;
        E->p++;
        return;
    }
    error_at(E->pos, "unexpected character '%c' in expression", *E->p);
}

static Expr *new_expr(ExprKind k, SrcPos pos) {
    Expr *e = arena_alloc(sizeof(Expr));
    e->kind = k;
    e->pos = pos;
    return e;
}

Expr *expr_num(double v, SrcPos pos) {
    Expr *e = new_expr(EX_NUM, pos);
    e->num = v;
    return e;
}

Expr *expr_bin(ExprKind k, Expr *a, Expr *b) {
    Expr *e = new_expr(k, a->pos);
    e->a = a;
    e->b = b;
    return e;
}

Expr *expr_call(FnKind fn, Expr *a, Expr *b) {
    Expr *e = new_expr(EX_CALL, a->pos);
    e->fn = fn;
    e->a = a;
    e->b = b;
    return e;
}

static const struct { const char *name; int nargs; } fns[FN_COUNT] = {
    [FN_SQRT] = {"sqrt", 1}, [FN_EXP] = {"exp", 1},   [FN_LOG] = {"log", 1},
    [FN_LOG10] = {"log10", 1}, [FN_SIN] = {"sin", 1}, [FN_COS] = {"cos", 1},
    [FN_TAN] = {"tan", 1},   [FN_ABS] = {"abs", 1},   [FN_POW] = {"pow", 2},
    [FN_MIN] = {"min", 2},   [FN_MAX] = {"max", 2},   [FN_POTLIN] = {"potlin", 1},
    [FN_POTLOG] = {"potlog", 1}, [FN_TAPON] = {"tapon", 1},
};

const char *fn_name(FnKind fn) { return fns[fn].name; }

static Expr *expr(ELex *E);
static Expr *unary(ELex *E);
static Expr *unary_(ELex *E);

static void expect(ELex *E, char k, const char *what) {
    if (E->kind != k)
        error_at(E->pos, "expected %s in expression", what);
    enext(E);
}

/* Expressions are small; these limits keep the recursive passes over
 * them (here and in later phases) well inside the stack. */
enum { EXPR_MAX_DEPTH = 200, EXPR_MAX_NODES = 4000 };

static void enter(ELex *E) {
    if (++E->depth > EXPR_MAX_DEPTH)
        error_at(E->pos, "expression nested too deeply");
    if (++E->nodes > EXPR_MAX_NODES)
        error_at(E->pos, "expression too long");
}

/* primary = NUMBER | NAME | NAME '(' expr [',' expr] ')' | '(' expr ')' */
static Expr *primary(ELex *E) {
    SrcPos pos = E->pos;
    if (E->kind == 'n') {
        Expr *e = expr_num(E->num, pos);
        enext(E);
        return e;
    }
    if (E->kind == '(') {
        enext(E);
        Expr *e = expr(E);
        expect(E, ')', "')'");
        return e;
    }
    if (E->kind != 'w')
        error_at(pos, E->kind == 'e' ? "expression ends too early" : "expected a number, a name or '('");
    char *name = arena_strndup(E->text, (size_t)E->len);
    enext(E);
    if (E->kind != '(') {
        Expr *e = new_expr(EX_NAME, pos);
        e->name = name;
        return e;
    }
    int fn = -1;
    for (int i = 0; i < FN_COUNT; i++)
        if (!strcmp(fns[i].name, name))
            fn = i;
    if (fn < 0)
        error_at(pos, "unknown function '%s'", name);
    enext(E);
    Expr *a = expr(E), *b = NULL;
    if (fns[fn].nargs == 2) {
        expect(E, ',', "',' (the function takes two arguments)");
        b = expr(E);
    }
    expect(E, ')', "')'");
    Expr *e = expr_call((FnKind)fn, a, b);
    e->pos = pos;
    return e;
}

/* power = primary [('^' | '**') unary] */
static Expr *power(ELex *E) {
    Expr *e = primary(E);
    if (E->kind == '^') {
        enext(E);
        e = expr_bin(EX_POW, e, unary(E));
    }
    return e;
}

/* unary = ('-' | '+') unary | power */
static Expr *unary(ELex *E) {
    enter(E);
    Expr *e = unary_(E);
    E->depth--;
    return e;
}

static Expr *unary_(ELex *E) {
    if (E->kind == '-' || E->kind == '+') {
        SrcPos pos = E->pos;
        bool neg = E->kind == '-';
        enext(E);
        Expr *a = unary(E);
        if (!neg)
            return a;
        Expr *e = new_expr(EX_NEG, pos);
        e->a = a;
        return e;
    }
    return power(E);
}

/* term = unary (('*' | '/') unary)* */
static Expr *term(ELex *E) {
    Expr *e = unary(E);
    while (E->kind == '*' || E->kind == '/') {
        ExprKind k = E->kind == '*' ? EX_MUL : EX_DIV;
        enext(E);
        e = expr_bin(k, e, unary(E));
    }
    return e;
}

/* expr = term (('+' | '-') term)* */
static Expr *expr(ELex *E) {
    Expr *e = term(E);
    while (E->kind == '+' || E->kind == '-') {
        ExprKind k = E->kind == '+' ? EX_ADD : EX_SUB;
        enext(E);
        e = expr_bin(k, e, term(E));
    }
    return e;
}

Expr *parse_expr_text(const Token *brace) {
    char *text = tok_str(brace);
    ELex E = {.p = text, .start = text, .base = brace->pos};
    enext(&E);
    if (E.kind == 'e')
        error_at(brace->pos, "empty expression");
    Expr *e = expr(&E);
    if (E.kind != 'e')
        error_at(E.pos, "unexpected '%.*s' after expression", E.len, E.text);
    return e;
}

/* ---- lines ---- */

static bool starts_numeric(const Token *t) {
    const char *s = t->text;
    if (*s == '+' || *s == '-')
        s++;
    return isdigit((unsigned char)*s) || (*s == '.' && t->len > 1);
}

static Value number_value(const Token *t) {
    if (t->kind != TK_NUMBER) {
        const char *why = "not a number";
        double v;
        lex_number_in(t->text, t->len, &v, &why, t->pos.file && t->pos.file->spice);
        error_at(t->pos, "malformed number '%.*s': %s", t->len, t->text, why);
    }
    return (Value){.kind = VAL_EXPR, .pos = t->pos, .expr = expr_num(t->num, t->pos)};
}

/* value = NUMBER | '{' expr '}' | WORD | STRING | '(' token* ')' */
static Value value(Parser *P) {
    Token *t = P->tok;
    Value v = {.pos = t->pos};
    if (t->kind == TK_NUMBER || (t->kind == TK_IDENT && starts_numeric(t))) {
        v = number_value(t);
    } else if (t->kind == TK_LBRACE) {
        v.kind = VAL_EXPR;
        v.expr = parse_expr_text(t);
    } else if (t->kind == TK_IDENT) {
        v.kind = VAL_NAME;
        v.name = tok_str(t);
    } else if (t->kind == TK_STRING) {
        v.kind = VAL_STRING;
        v.name = tok_str(t);
    } else if (t->kind == TK_LPAREN) {
        Token *s = ++P->tok;
        while (P->tok->kind != TK_RPAREN) {
            if (at_eol(P))
                error_at(t->pos, "unterminated '(': expected ')' before the end of the line");
            P->tok++;
        }
        v.kind = VAL_LIST;
        v.toks = s;
        v.ntoks = (int)(P->tok - s);
    } else {
        error_at(t->pos, at_eol(P) ? "expected a value at the end of the line"
                                   : "expected a value, found '%.*s'", t->len, t->text);
    }
    P->tok++;
    /* taps=h@0.12,p@0.5 and similar run on as a list of tokens */
    if (is_punct(P->tok, '@') || is_punct(P->tok, ':') || is_punct(P->tok, '/') ||
        (P->tok->kind == TK_COMMA && !P->file->spice)) { /* a deck's commas part keys: D(IS=1n, N=2) */
        v.kind = VAL_LIST;
        v.toks = t;
        while (!at_eol(P) && !(P->tok->kind == TK_IDENT && P->tok[1].kind == TK_EQ))
            P->tok++;
        v.ntoks = (int)(P->tok - t);
    }
    return v;
}

static bool at_keyval(Parser *P) { return P->tok->kind == TK_IDENT && P->tok[1].kind == TK_EQ; }

/* keyval = WORD '=' value, at a keyval. */
static KeyVal *keyval(Parser *P) {
    KeyVal *k = arena_alloc(sizeof(KeyVal));
    k->key = tok_str(P->tok);
    k->pos = P->tok->pos;
    P->tok += 2;
    if (at_eol(P))
        error_at(P->tok[-1].pos, "expected a value after '='");
    k->val = value(P);
    return k;
}

/* Collects keyvals to the end of the line. */
static void keyvals(Parser *P, Line *l) {
    Vec kv = {0};
    while (!at_eol(P)) {
        if (P->tok->kind == TK_COMMA && P->file->spice) { /* SPICE: D(IS=1n, N=2) */
            P->tok++;
            continue;
        }
        if (!at_keyval(P)) {
            Token *t = P->tok;
            error_at(t->pos, "unexpected '%.*s': expected key=value", t->len, t->text);
        }
        KeyVal *k = keyval(P);
        for (int i = 0; i < kv.len; i++)
            if (!strcmp(((KeyVal *)kv.data[i])->key, k->key))
                error_at(k->pos, "key '%s' given twice", k->key);
        vec_push(&kv, k);
    }
    l->nkv = kv.len;
    l->kv = arena_alloc(sizeof(KeyVal) * (size_t)(kv.len + 1));
    for (int i = 0; i < kv.len; i++)
        l->kv[i] = *(KeyVal *)kv.data[i];
}

static const char *word(Parser *P, const char *what) {
    Token *t = P->tok;
    if (t->kind != TK_IDENT && t->kind != TK_NUMBER)
        error_at(t->pos, at_eol(P) ? "missing %s at the end of the line" : "expected %s", what);
    P->tok++;
    return tok_str(t);
}

/* A deck's 'params:' before the keys of a .subckt or an X line. */
static bool at_params(Parser *P) { return tok_is(P->tok, "params") && is_punct(P->tok + 1, ':'); }

static void add_arg(Vec *args, Value v) {
    Value *p = arena_alloc(sizeof(Value));
    *p = v;
    vec_push(args, p);
}

static void set_args(Line *l, Vec *args) {
    l->nargs = args->len;
    l->args = arena_alloc(sizeof(Value) * (size_t)(args->len + 1));
    for (int i = 0; i < args->len; i++)
        l->args[i] = *(Value *)args->data[i];
}

static Value node_value(Parser *P) {
    Token *t = P->tok;
    if (t->kind != TK_IDENT && t->kind != TK_NUMBER)
        error_at(t->pos, "expected a node name, found '%.*s'", t->len, t->text);
    P->tok++;
    return (Value){.kind = VAL_NAME, .pos = t->pos, .name = tok_str(t)};
}

/* A deck's element whose SPICE letter names a device the compiler does
 * not model: said as SPICE names it, with the letters a deck may use. */
static void spice_unsupported(const Token *h) {
    static const char *const what[26] = {
        ['A' - 'A'] = "an XSPICE code model", ['B' - 'A'] = "a behavioural source",
        ['F' - 'A'] = "a current-controlled current source", ['H' - 'A'] = "a current-controlled voltage source",
        ['J' - 'A'] = "a JFET", ['M' - 'A'] = "a MOSFET", ['N' - 'A'] = "a numerical device",
        ['O' - 'A'] = "a lossy transmission line", ['P' - 'A'] = "a coupled multiconductor line",
        ['S' - 'A'] = "a voltage-controlled switch", ['U' - 'A'] = "a uniform RC line",
        ['W' - 'A'] = "a current-controlled switch", ['Y' - 'A'] = "a transmission line (Y)",
        ['Z' - 'A'] = "a MESFET",
    };
    int c = toupper((unsigned char)h->text[0]);
    if (c >= 'A' && c <= 'Z' && what[c - 'A'])
        error_at(h->pos, "'%c%.*s' is %s, which decks here do not take (they take R, C, L, V, I, D, Q, E, G, "
                         "K, T and X)", c, h->len - 1, h->text + 1, what[c - 'A']);
}

/* element = NAME node{n} arg* keyval* | KEYWORD NAME node{n} arg* keyval* */
static void element(Parser *P, Line *l) {
    Token *h = P->tok;
    int kind = block_by_keyword(h->text, h->len);
    if (kind >= 0) {
        P->tok++;
        if (at_eol(P))
            error_at(P->tok->pos, kind == BK_USE ? "missing block name after 'use'" : "missing %s name after '%s'",
                     block_desc[kind].desc, l->head);
        l->namepos = P->tok->pos;
        l->name = word(P, "a name");
    } else if (P->file->spice && h->kind == TK_IDENT && h->text[0] == 'x') {
        /* a deck's X1 n1 n2 SUBCKT [params:] k=v: use SUBCKT X1 n1 n2 k=v */
        l->name = l->head;
        l->namepos = h->pos;
        l->kind = BK_USE;
        P->tok++;
        Vec args = {0};
        while (!at_eol(P) && !at_keyval(P) && !at_params(P))
            add_arg(&args, node_value(P));
        if (args.len < 1)
            error_at(P->tok->pos, "instance '%s' needs its nodes and the name of its .subckt", l->name);
        Value sub = *(Value *)args.data[args.len - 1];
        Vec use = {0};
        add_arg(&use, sub);
        for (int i = 0; i < args.len - 1; i++)
            add_arg(&use, *(Value *)args.data[i]);
        if (at_params(P))
            P->tok += 2;
        set_args(l, &use);
        keyvals(P, l);
        return;
    } else {
        kind = h->kind == TK_IDENT ? block_by_letter(h->text[0]) : -1;
        if (kind < 0 && P->file->spice && h->kind == TK_IDENT)
            spice_unsupported(h);
        if (kind < 0)
            error_at(h->pos, "unknown element kind '%.*s'", h->len, h->text);
        l->name = l->head;
        l->namepos = h->pos;
        P->tok++;
    }
    l->kind = kind;
    const Kind *d = block_desc[kind].kind;
    Vec args = {0};
    if (kind == BK_USE) { /* use BLOCK INST node...: what was read as the name is the block */
        add_arg(&args, (Value){.kind = VAL_NAME, .pos = l->namepos, .name = l->name});
        l->namepos = P->tok->pos;
        l->name = word(P, "an instance name");
    }
    for (const char *a = d->args; *a == 't'; a++)
        add_arg(&args, node_value(P));
    if (d->nnodes < 0) {
        while (!at_eol(P) && !at_keyval(P))
            add_arg(&args, node_value(P));
    } else {
        for (int i = 0; i < d->nnodes; i++) {
            if (at_eol(P) || at_keyval(P))
                error_at(P->tok->pos, "%s '%s' needs %d node%s, found %d", d->desc, l->name,
                         d->nnodes, d->nnodes > 1 ? "s" : "", i);
            add_arg(&args, node_value(P));
        }
    }
    if (kind == BK_K) { /* K NAME L1 L2 [L3...] k: the inductors' names, then the coefficient */
        while (P->tok->kind == TK_IDENT && !at_keyval(P))
            add_arg(&args, node_value(P));
        if (at_eol(P) || at_keyval(P))
            error_at(P->tok->pos, "coupling '%s' needs a coefficient after its inductors' names", l->name);
        Token *kt = P->tok;
        add_arg(&args, value(P));
        set_args(l, &args);
        if (!at_eol(P) && !at_keyval(P))
            error_at(kt->pos, "coupling '%s' takes inductors' names, then one coefficient: '%.*s' is not an "
                     "inductor's name", l->name, kt->len, kt->text);
        keyvals(P, l);
        return;
    }
    if (P->file->spice && (kind == BK_V || kind == BK_I)) { /* DC 1 AC 1 SIN(...): elab reads them */
        while (!at_eol(P) && !at_keyval(P))
            add_arg(&args, value(P));
        set_args(l, &args);
        keyvals(P, l);
        return;
    }
    for (const char *a = d->args; *a; a++) {
        if (*a == 't')
            continue;
        if (at_eol(P) || at_keyval(P)) {
            if (*a == 'v' && at_keyval(P))
                break; /* value may come as a key, e.g. R1 a b R=1k */
            error_at(P->tok->pos, "%s '%s' needs %s after its nodes", d->desc, l->name,
                     *a == 'm' ? "a model name" : *a == 'd' ? "a drive (input, param or value)" : "a value");
        }
        /* a model's name may start with a digit (1N4148) */
        add_arg(&args, *a == 'm' && P->tok->kind == TK_IDENT ? node_value(P) : value(P));
    }
    set_args(l, &args);
    if (!at_eol(P) && !at_keyval(P)) {
        Token *t = P->tok;
        if (d->nnodes >= 0)
            error_at(t->pos, "too many nodes or values for %s '%s': unexpected '%.*s'", d->desc,
                     l->name, t->len, t->text);
    }
    keyvals(P, l);
}

/* SPICE's measures of the AC analysis, vdb(out) and such, which name a
 * signal v() or i(). */
static bool ac_measure(const Token *t) {
    static const char *const ac[] = {"vdb", "vm", "vp", "vr", "vi", "idb", "im", "ip", "ir", "ii"};
    for (int i = 0; i < (int)(sizeof ac / sizeof ac[0]); i++)
        if (tok_is(t, ac[i]))
            return true;
    return false;
}

/* ref = WORD '(' WORD [',' WORD] ')' */
static Ref ref(Parser *P) {
    Token *t = P->tok;
    Ref r = {.pos = t->pos};
    if (P->file->spice && t->kind == TK_IDENT && t[1].kind == TK_LPAREN && ac_measure(t)) {
        /* .print ac vdb(out): the signal is v(out) */
        note_at(t->pos, "'%.*s(...)' measures the AC analysis; the voice outputs the signal, %c(...)", t->len, t->text,
                t->text[0]);
        t->len = 1;
    }
    if (t->kind != TK_IDENT || t->len != 1 || !strchr("vixfVIXF", t->text[0]) ||
        t[1].kind != TK_LPAREN)
        error_at(t->pos, "expected a probe v(node), v(a,b), i(elem), x(node) or f(elem)");
    r.fn = (char)tolower((unsigned char)t->text[0]);
    P->tok += 2;
    for (int i = 0; i < 2; i++) {
        Token *a = P->tok;
        if (a->kind != TK_IDENT && a->kind != TK_NUMBER)
            error_at(a->pos, "expected a %s name in the probe", r.fn == 'i' || r.fn == 'f' ? "element" : "node");
        r.arg[i] = tok_str(a);
        r.argpos[i] = a->pos;
        P->tok++;
        if (P->tok->kind == TK_RPAREN)
            break;
        if (P->tok->kind != TK_COMMA || i == 1)
            error_at(P->tok->pos, "expected ')' to close the probe");
        P->tok++;
    }
    P->tok++;
    return r;
}

static void push_ref(Vec *refs, Vec *vals, Ref r, Value *v) {
    Ref *rp = arena_alloc(sizeof(Ref));
    *rp = r;
    vec_push(refs, rp);
    if (vals)
        vec_push(vals, v);
}

static void set_refs(Line *l, Vec *refs, Vec *vals) {
    l->nrefs = refs->len;
    l->refs = arena_alloc(sizeof(Ref) * (size_t)(refs->len + 1));
    l->refvals = arena_alloc(sizeof(Value) * (size_t)(refs->len + 1));
    for (int i = 0; i < refs->len; i++) {
        l->refs[i] = *(Ref *)refs->data[i];
        if (vals)
            l->refvals[i] = *(Value *)vals->data[i];
    }
}

/* directive = '.voice' NAME | ... (see the grammar at the top) */
static bool directive(Parser *P, Line *l) {
    const char *d = l->head;
    Vec args = {0};
    P->tok++;
    if (!strcmp(d, ".voice") || !strcmp(d, ".domain") || !strcmp(d, ".endblock") ||
        !strcmp(d, ".ends") || !strcmp(d, ".end")) {
        if (strcmp(d, ".endblock") && strcmp(d, ".ends") && strcmp(d, ".end")) {
            if (at_eol(P))
                error_at(P->tok->pos, "missing %s after %s", d[1] == 'v' ? "voice name" : "domain", d);
            add_arg(&args, node_value(P));
        } else if (!strcmp(d, ".ends") && P->file->spice && P->tok->kind == TK_IDENT && P->tok[1].kind != TK_EQ) {
            P->tok++; /* .ends NAME */
        }
    } else if (!strcmp(d, ".rate")) {
        if (at_eol(P))
            error_at(P->tok->pos, "missing sample rate after .rate");
        add_arg(&args, value(P));
    } else if (!strcmp(d, ".input")) {
        if (at_eol(P))
            error_at(P->tok->pos, "missing input name after .input");
        while (!at_eol(P))
            add_arg(&args, node_value(P));
    } else if (!strcmp(d, ".param")) {
        l->namepos = P->tok->pos;
        l->name = word(P, "a param name");
        if (P->tok->kind == TK_EQ)
            P->tok++;
        if (at_eol(P))
            error_at(P->tok->pos, "missing default value of param '%s'", l->name);
        add_arg(&args, value(P));
        /* a deck's .param a=1 b=2: each key another param (elab) */
    } else if (!strcmp(d, ".model")) {
        l->namepos = P->tok->pos;
        l->name = word(P, "a model name");
        if (at_eol(P))
            error_at(P->tok->pos, "missing the kind of model '%s' (such as D)", l->name);
        add_arg(&args, node_value(P));
        if (P->tok->kind == TK_LPAREN) { /* SPICE's KIND(key=value ...) */
            Token *open = P->tok++;
            Token *close = P->tok;
            while (close->kind != TK_RPAREN && close->kind != TK_EOL && close->kind != TK_EOF)
                close++;
            if (close->kind != TK_RPAREN)
                error_at(open->pos, "unclosed '(' in .model");
            if (close[1].kind != TK_EOL && close[1].kind != TK_EOF)
                error_at(close[1].pos, "unexpected '%.*s' after the model's ')'", close[1].len, close[1].text);
            close->kind = TK_EOL;
            set_args(l, &args);
            keyvals(P, l);
            if (P->tok == close)
                P->tok++;
            return false;
        }
    } else if (!strcmp(d, ".include")) {
        if (P->tok->kind != TK_STRING && P->tok->kind != TK_IDENT)
            error_at(P->tok->pos, "expected a file name after .include");
        add_arg(&args, value(P));
    } else if (!strcmp(d, ".block") || (P->file->spice && !strcmp(d, ".subckt"))) {
        l->head = ".block"; /* a deck's .subckt NAME n1 n2 [params:] k=v is a block */
        l->namepos = P->tok->pos;
        l->name = word(P, "a block name");
        while (!at_eol(P) && !at_keyval(P) && !at_params(P))
            add_arg(&args, node_value(P));
        if (at_params(P))
            P->tok += 2;
    } else if (!strcmp(d, ".output")) {
        l->namepos = P->tok->pos;
        l->name = word(P, "an output name");
        Vec refs = {0};
        push_ref(&refs, NULL, ref(P), NULL);
        set_refs(l, &refs, NULL);
    } else if (P->file->spice && (!strcmp(d, ".print") || !strcmp(d, ".plot") || !strcmp(d, ".probe") ||
                                  !strcmp(d, ".save"))) {
        /* the vectors a deck prints are its outputs: v(n), v(a,b), i(V1) */
        Vec refs = {0};
        if (P->tok->kind == TK_IDENT && P->tok[1].kind != TK_LPAREN) /* tran, ac, all... */
            P->tok++;
        while (!at_eol(P)) {
            if (P->tok->kind == TK_IDENT && P->tok[1].kind != TK_LPAREN) { /* 'all' and such */
                P->tok++;
                continue;
            }
            push_ref(&refs, NULL, ref(P), NULL);
        }
        set_refs(l, &refs, NULL);
    } else if (P->file->spice && !strcmp(d, ".tran")) {
        while (!at_eol(P) && P->tok->kind != TK_IDENT)
            add_arg(&args, value(P));
        if (args.len < 2)
            error_at(P->tok->pos, ".tran needs a step and a stop time");
        if (P->tok->kind == TK_IDENT && tok_is(P->tok, "uic"))
            add_arg(&args, node_value(P));
    } else if (P->file->spice && (!strcmp(d, ".options") || !strcmp(d, ".option"))) {
        /* key=value settings and bare flags; elab takes temp= */
        Vec kv = {0};
        while (!at_eol(P)) {
            if (!at_keyval(P)) {
                P->tok++;
                continue;
            }
            vec_push(&kv, keyval(P));
        }
        l->head = ".options";
        l->nkv = kv.len;
        l->kv = arena_alloc(sizeof(KeyVal) * (size_t)(kv.len + 1));
        for (int i = 0; i < kv.len; i++)
            l->kv[i] = *(KeyVal *)kv.data[i];
        set_args(l, &args);
        return false;
    } else if (P->file->spice && !strcmp(d, ".temp")) {
        if (at_eol(P))
            error_at(P->tok->pos, "missing the temperature (degrees C) after .temp");
        add_arg(&args, value(P));
    } else if (P->file->spice && (!strcmp(d, ".ac") || !strcmp(d, ".dc") || !strcmp(d, ".op") ||
                                  !strcmp(d, ".noise") || !strcmp(d, ".meas") || !strcmp(d, ".measure") ||
                                  !strcmp(d, ".four") || !strcmp(d, ".width") || !strcmp(d, ".nodeset") ||
                                  !strcmp(d, ".global") || !strcmp(d, ".title") || !strcmp(d, ".disto") ||
                                  !strcmp(d, ".sens") || !strcmp(d, ".tf") || !strcmp(d, ".pz"))) {
        note_at(l->headpos, "'%s' is an analysis or control line; the voice has no use for it and skips it", d);
        while (!at_eol(P))
            P->tok++;
        l->head = ".skip";
        return false;
    } else if (!strcmp(d, ".ic")) {
        Vec refs = {0}, vals = {0};
        if (at_eol(P))
            error_at(P->tok->pos, "expected v(node)=value or x(node)=value after .ic");
        while (!at_eol(P)) {
            Ref r = ref(P);
            if (P->tok->kind != TK_EQ)
                error_at(P->tok->pos, "expected '=' after %c(%s)", r.fn, r.arg[0]);
            P->tok++;
            Value *v = arena_alloc(sizeof(Value));
            *v = value(P);
            push_ref(&refs, &vals, r, v);
        }
        set_refs(l, &refs, &vals);
    } else {
        error_at(l->headpos, "unknown directive '%s'", d);
    }
    set_args(l, &args);
    keyvals(P, l);
    return !strcmp(d, ".end");
}

SrcFile *srcfile_new(const char *path, const char *text) {
    SrcFile *f = arena_alloc(sizeof(SrcFile));
    f->path = arena_strdup(path);
    f->text = strncmp(text, "\xef\xbb\xbf", 3) ? text : text + 3; /* a UTF-8 byte-order mark, as editors on Windows write */
    return f;
}

/* A deck's .control ... .endc: ngspice's commands.  Of them the voice
 * takes `tran STEP STOP` (as .tran) and the vectors that `print`, `plot`,
 * `wrdata FILE` and `write FILE` name (as .print); the rest is skipped. */
static void control(Parser *P, Vec *lines, SrcPos pos) {
    Token *start = P->tok;
    Token *t = P->tok;
    while (t->kind != TK_EOF && !(tok_is(t, ".endc") && t[-1].kind == TK_EOL)) /* a line of its own */
        t++;
    if (t->kind == TK_EOF)
        error_at(pos, "'.control' without '.endc'");
    note_at(start->pos, "'.control' starts ngspice's commands: of them the voice takes tran and the vectors "
                        "print, plot, wrdata and write name, and skips the rest");
    while (!at_eol(P))
        P->tok++;
    while (P->tok != t) { /* the lines up to that '.endc' */
        if (P->tok->kind == TK_EOL) {
            P->tok++;
            continue;
        }
        Token *cmd = P->tok;
        bool print = tok_is(cmd, "print") || tok_is(cmd, "plot"), file = tok_is(cmd, "wrdata") || tok_is(cmd, "write");
        Line *l = arena_alloc(sizeof(Line));
        l->pos = l->headpos = cmd->pos;
        l->kind = -1;
        P->tok++;
        if (tok_is(cmd, "tran")) {
            Vec args = {0};
            while (!at_eol(P) && (P->tok->kind == TK_NUMBER || starts_numeric(P->tok)) && args.len < 2)
                add_arg(&args, value(P));
            if (args.len == 2) {
                l->head = ".tran";
                set_args(l, &args);
                vec_push(lines, l);
            }
        } else if (print || file) {
            Vec refs = {0};
            if (file && !at_eol(P)) /* the file's name */
                P->tok++;
            while (!at_eol(P) && P->tok != t) {
                Token *w = P->tok;
                if (w->kind == TK_IDENT && w[1].kind == TK_LPAREN &&
                    (w->len == 1 ? strchr("vi", w->text[0]) != NULL : ac_measure(w)))
                    push_ref(&refs, NULL, ref(P), NULL);
                else
                    P->tok++;
            }
            if (refs.len) {
                l->head = ".print";
                set_refs(l, &refs, NULL);
                vec_push(lines, l);
            }
        }
        while (!at_eol(P) && P->tok != t)
            P->tok++;
    }
    while (!at_eol(P))
        P->tok++;
}

/* netlist = line* EOF */
Program *parse_file(SrcFile *f) {
    int ntok;
    Token *toks = lex_file(f, &ntok);
    Parser P = {.tok = toks, .file = f};
    Vec lines = {0};
    while (P.tok->kind != TK_EOF) {
        if (P.tok->kind == TK_EOL) {
            P.tok++;
            continue;
        }
        Line *l = arena_alloc(sizeof(Line));
        l->pos = l->headpos = P.tok->pos;
        l->head = tok_str(P.tok);
        l->kind = -1;
        bool end = false;
        if (f->spice && tok_is(P.tok, ".control")) { /* ngspice's commands, to .endc */
            control(&P, &lines, l->pos);
            continue;
        }
        if (P.tok->kind == TK_IDENT && P.tok->text[0] == '.')
            end = directive(&P, l);
        else if (P.tok->kind == TK_IDENT || P.tok->kind == TK_NUMBER)
            element(&P, l);
        else
            error_at(P.tok->pos, "expected an element or a directive, found '%.*s'", P.tok->len,
                     P.tok->text);
        if (!at_eol(&P))
            error_at(P.tok->pos, "unexpected '%.*s' at the end of the line", P.tok->len, P.tok->text);
        vec_push(&lines, l);
        if (end)
            break;
    }
    Program *prog = arena_alloc(sizeof(Program));
    prog->file = f;
    prog->nlines = lines.len;
    prog->lines = arena_alloc(sizeof(Line) * (size_t)(lines.len + 1));
    for (int i = 0; i < lines.len; i++)
        prog->lines[i] = *(Line *)lines.data[i];
    return prog;
}
