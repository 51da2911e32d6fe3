/*
 * sexp.c - the S-expression reader of scenes (.wds) and timbre trees (.tt).
 *
 * Grammar, over bytes ([x] is optional, x* repeats, x+ repeats at least
 * once); it is the language reference for both kinds of file:
 *
 *   doc      = blanks (datum blanks)* EOF
 *   datum    = list | string | atom
 *   list     = '(' blanks (datum blanks)* ')'   nested at most SX_MAX_DEPTH deep
 *   string   = '"' (strchar | escape)* '"'      on one line: \n makes a newline
 *   strchar  = any byte but '"' '\' CR LF and control bytes; TAB is allowed,
 *              bytes >= 0x80 are kept as they are (UTF-8 goes in raw)
 *   escape   = '\"' | '\\' | '\n' | '\t'
 *   atom     = symchar+                         ends at a delim or EOF
 *   symchar  = letter | digit | one of ! # $ % & * + - . / : < = > ? @ ^ _ ~
 *   delim    = ' ' | TAB | CR | LF | '(' | ')' | '"' | ';'
 *   blanks   = (' ' | TAB | CR | LF | comment)*
 *   comment  = ';' (any byte but LF and control bytes)*
 *
 * An atom that starts with a digit, or with '.' then a digit, or with '+'
 * or '-' then either of those, is a number, and must be all of
 *
 *   number   = [+-] mantissa [exponent] ([scale] [unit] | "kg")
 *   mantissa = digit+ ['.' digit*] | '.' digit+
 *   exponent = ('e' | 'E') [+-] digit+
 *   scale    = meg | f | p | n | u | m | k | g | t   in any case, "meg" tried
 *              first: "M" is milli as in SPICE (5MHz is 5 mHz)
 *   unit     = F | H | V | A | s | Hz | ohm | Ohm | N | dB | m   as written
 *
 * in fewer than 64 bytes.  That is gen/lex.c's lex_number (the netlist's
 * numbers, with its error messages) plus the units dB and m that scenes
 * need.  Units are ignored (-3dB is -3, 2km is 2000); "kg" right after the
 * digits is the unit of mass, not a scale.  The value is the decimal's
 * double times the scale's, as in the netlist, and must be finite (an
 * underflow to 0 is accepted, as there).  Every other atom is a symbol.
 *
 * Other bytes are errors: control bytes but TAB CR LF anywhere, even in
 * comments ("stray character"), bytes >= 0x80 outside strings and
 * comments, and the printable characters kept for later syntax:
 * ' ` , [ ] { } \ |.  A '(' left open is reported just past the last
 * token of the text ("expected ')' to close '(' at L:C").  Lines are
 * counted at LF; columns count bytes from 1 (a TAB is one).
 */
#include "sexp.h"

#include <assert.h>
#include <errno.h>
#include <float.h>
#include <limits.h>
#include <locale.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* A test builds this file with allocators that fail on purpose. */
#ifndef SX_MALLOC
#define SX_MALLOC malloc
#define SX_REALLOC realloc
#define SX_FREE free
#endif

/* ---- arena ------------------------------------------------------------ */

typedef union sx_align {
    long double ld;
    long long ll;
    void *p;
} sx_align;

struct sx_chunk {
    struct sx_chunk *next; /* older chunk */
    size_t used, cap;      /* bytes of data */
    sx_align data[];       /* aligned for any node or text */
};

#define CHUNK_MIN 4096
#define CHUNK_MAX ((size_t)1 << 20) /* growth stops doubling here */

/* A new chunk of twice the last one's size (up to CHUNK_MAX), or n bytes
 * if n is more: few chunks for big texts, little waste for small ones. */
static struct sx_chunk *chunk_new(sx_doc *d, size_t n)
{
    size_t cap = d->_chunks ? 2 * d->_chunks->cap : CHUNK_MIN;
    if (cap > CHUNK_MAX)
        cap = CHUNK_MAX;
    if (cap < n)
        cap = n;
    if (cap > SIZE_MAX - sizeof(struct sx_chunk))
        return NULL;
    struct sx_chunk *c = SX_MALLOC(sizeof *c + cap);
    if (!c)
        return NULL;
    c->used = 0;
    c->cap = cap;
    c->next = d->_chunks;
    d->_chunks = c;
    return c;
}

static void *doc_alloc(sx_doc *d, size_t n)
{
    const size_t a = sizeof(sx_align);
    if (n > SIZE_MAX - a)
        return NULL;
    n = (n + a - 1) / a * a;
    struct sx_chunk *c = d->_chunks;
    if (!c || c->cap - c->used < n)
        c = chunk_new(d, n);
    if (!c)
        return NULL;
    void *p = (char *)c->data + c->used;
    c->used += n;
    return p;
}

static char *doc_strndup(sx_doc *d, const char *s, size_t n)
{
    char *p = doc_alloc(d, n + 1);
    if (p) {
        memcpy(p, s, n);
        p[n] = '\0';
    }
    return p;
}

void sx_free(sx_doc *d)
{
    if (!d)
        return;
    for (struct sx_chunk *c = d->_chunks, *next; c; c = next) {
        next = c->next;
        SX_FREE(c);
    }
    SX_FREE(d);
}

/* ---- diagnostics ------------------------------------------------------ */

/* A bounded writer into the caller's err buffer: what does not fit is cut. */
typedef struct Out {
    char *p;
    size_t cap, len;
} Out;

static void out_vf(Out *o, const char *fmt, va_list ap)
{
    size_t room = o->len < o->cap ? o->cap - o->len : 0;
    int n = vsnprintf(room ? o->p + o->len : NULL, room, fmt, ap);
    if (n > 0)
        o->len += (size_t)n;
}

static void out_f(Out *o, const char *fmt, ...) SX_PRINTF(2, 3);
static void out_f(Out *o, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    out_vf(o, fmt, ap);
    va_end(ap);
}

/* "PATH: error: MESSAGE\n", for what has no position. */
static void vfile_error(const char *path, char *err, size_t errlen, const char *fmt,
                        va_list ap)
{
    if (!err || !errlen)
        return;
    Out o = {err, errlen, 0};
    err[0] = '\0';
    out_f(&o, "%s: error: ", path);
    out_vf(&o, fmt, ap);
    out_f(&o, "\n");
}

static void file_error(const char *path, char *err, size_t errlen, const char *fmt, ...)
    SX_PRINTF(4, 5);
static void file_error(const char *path, char *err, size_t errlen, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vfile_error(path, err, errlen, fmt, ap);
    va_end(ap);
}

/* The bytes [*s, *e) of line `line` of d's text; empty past the end.  A
 * line ends at LF, CR or a NUL byte, as gen/util.c's reports end it. */
static void line_bounds(const sx_doc *d, int line, const char **s, const char **e)
{
    const char *p = d->src, *end = d->src + d->srclen;
    for (int l = 1; l < line && p < end; p++)
        if (*p == '\n')
            l++;
    if (line < 1)
        p = end;
    const char *q = p;
    while (q < end && *q != '\n' && *q != '\r' && *q != '\0')
        q++;
    *s = p;
    *e = q;
}

/* The netlist compiler's format (gen/util.c, vreport): the message, the
 * source line indented by two, and a caret under the column; the caret
 * line copies the source's tabs so the caret lines up in a terminal. */
static void vreport(const sx_doc *d, int line, int col, char *err, size_t errlen,
                    const char *kind, const char *fmt, va_list ap)
{
    if (!err || !errlen)
        return;
    /* an error replaces what err held; a warning is added to it */
    size_t at = strcmp(kind, "error") ? strnlen(err, errlen - 1) : 0;
    Out o = {err, errlen, at};
    err[at] = '\0';
    out_f(&o, "%s:%d:%d: %s: ", d->path, line, col, kind);
    out_vf(&o, fmt, ap);
    const char *s, *e;
    line_bounds(d, line, &s, &e);
    /* a long line is shown SHOW_LINE bytes about the column, "..." where cut */
    enum { SHOW_LINE = 100, SHOW_BEFORE = 60 };
    const char *c = col >= 1 && col - 1 < e - s ? s + col - 1 : e;
    const char *a = e - s > SHOW_LINE && c - s > SHOW_BEFORE ? c - SHOW_BEFORE : s;
    const char *b = e - a > SHOW_LINE ? a + SHOW_LINE : e;
    out_f(&o, "\n  %s%.*s%s\n  %s", a > s ? "..." : "", (int)(b - a), a, b < e ? "..." : "", a > s ? "   " : "");
    for (const char *q = a; q < c; q++)
        out_f(&o, "%c", *q == '\t' ? '\t' : ' ');
    out_f(&o, "^\n");
}

int sx_error_at(const sx_doc *d, int line, int col, char *err, size_t errlen,
                const char *fmt, ...)
{
    assert(d);
    va_list ap;
    va_start(ap, fmt);
    vreport(d, line, col, err, errlen, "error", fmt, ap);
    va_end(ap);
    return -1;
}

int sx_error(const sx_doc *d, const sx *at, char *err, size_t errlen, const char *fmt,
             ...)
{
    assert(d);
    va_list ap;
    va_start(ap, fmt);
    if (at)
        vreport(d, at->line, at->col, err, errlen, "error", fmt, ap);
    else
        vfile_error(d->path, err, errlen, fmt, ap);
    va_end(ap);
    return -1;
}

void sx_warning(const sx_doc *d, const sx *at, char *err, size_t errlen, const char *fmt, ...)
{
    assert(d && at);
    va_list ap;
    va_start(ap, fmt);
    vreport(d, at->line, at->col, err, errlen, "warning", fmt, ap);
    va_end(ap);
}

/* ---- characters -------------------------------------------------------- */

/* Our own ASCII tests: <ctype.h> follows the host's locale. */
static int is_digit(int c) { return c >= '0' && c <= '9'; }
static int is_alpha(int c) { return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z'); }
static int lower(int c) { return c >= 'A' && c <= 'Z' ? c - 'A' + 'a' : c; }

static int is_symchar(int c)
{
    return is_alpha(c) || is_digit(c) || (c && strchr("!#$%&*+-./:<=>?@^_~", c));
}

static int is_delim(int c)
{
    return c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '(' || c == ')' ||
           c == '"' || c == ';';
}

/* Control bytes that may not appear anywhere (TAB, CR and LF may). */
static int is_stray(int c)
{
    return (c < 0x20 && c != '\t' && c != '\r' && c != '\n') || c == 0x7f;
}

/* ---- numbers ----------------------------------------------------------- */

/* The netlist's rule for a word that is a number (gen/lex.c, lex_word). */
static int looks_numeric(const char *s, size_t n)
{
    size_t i = n && (s[0] == '+' || s[0] == '-');
    return i < n && (is_digit(s[i]) || (s[i] == '.' && i + 1 < n && is_digit(s[i + 1])));
}

/* Length of the prefix [+-] mantissa [exponent] of s (NUL-terminated):
 * exactly what strtod reads of a decimal number. */
static size_t decimal_len(const char *s)
{
    size_t i = s[0] == '+' || s[0] == '-';
    while (is_digit(s[i]))
        i++;
    if (s[i] == '.')
        for (i++; is_digit(s[i]);)
            i++;
    if (s[i] == 'e' || s[i] == 'E') {
        size_t j = i + 1 + (s[i + 1] == '+' || s[i + 1] == '-');
        if (is_digit(s[j]))
            for (i = j; is_digit(s[i]);)
                i++;
    }
    return i;
}

/* strtod of the n-byte decimal s, which reads '.' as the radix whatever
 * locale the host has set (a host that calls setlocale(LC_ALL, "") in a
 * locale with a decimal comma would otherwise read 0.5 as 0). */
static double decimal_value(const char *s, size_t n)
{
    const char *radix = localeconv()->decimal_point;
    size_t rl = radix && *radix && strlen(radix) <= 8 ? strlen(radix) : 0;
    char buf[64 + 8];
    size_t k = 0;
    for (size_t i = 0; i < n; i++) {
        if (s[i] == '.' && rl) {
            memcpy(buf + k, radix, rl);
            k += rl;
        } else {
            buf[k++] = s[i];
        }
    }
    buf[k] = '\0';
    char *end;
    double v = strtod(buf, &end);
    assert(*end == '\0');
    return v;
}

/* Scale suffixes, case-insensitive; "meg" and "mil" before "m"
 * (gen/lex.c's table). */
static const struct {
    const char *s;
    double v;
} scales[] = {
    {"meg", 1e6}, {"mil", 25.4e-6}, {"f", 1e-15}, {"p", 1e-12}, {"n", 1e-9},
    {"u", 1e-6},  {"m", 1e-3},      {"k", 1e3},   {"g", 1e9},   {"t", 1e12},
};

/* Unit words that may end a number (ignored): gen/lex.c's, then the
 * decibel and the metre, which scenes use. */
static const char *const units[] = {"F", "H",   "V",   "A",  "s", "Hz",
                                    "ohm", "Ohm", "N", "dB", "m"};

/* Skips a scale suffix at the start of *rest, returning its factor. */
static double scale_of(const char **rest)
{
    for (size_t i = 0; **rest && i < sizeof scales / sizeof scales[0]; i++) {
        size_t n = strlen(scales[i].s), k = 0;
        while (k < n && lower((*rest)[k]) == scales[i].s[k])
            k++;
        if (k == n) {
            *rest += n;
            return scales[i].v;
        }
    }
    return 1;
}

static int is_unit(const char *s)
{
    for (size_t i = 0; i < sizeof units / sizeof units[0]; i++)
        if (!strcmp(s, units[i]))
            return 1;
    return 0;
}

/* Reads the number token s (n bytes, looks_numeric) into *out.  Returns 0,
 * or -1 with the reason in why (gen/lex.c's wording). */
static int read_number(const char *s, size_t n, double *out, char *why, size_t whylen)
{
    char buf[64];
    if (n >= sizeof buf) {
        snprintf(why, whylen, "number too long");
        return -1;
    }
    memcpy(buf, s, n);
    buf[n] = '\0';
    const char *q = buf + (buf[0] == '+' || buf[0] == '-');
    if (q[0] == '0' && (q[1] == 'x' || q[1] == 'X')) {
        snprintf(why, whylen, "hexadecimal numbers are not accepted");
        return -1;
    }
    size_t m = decimal_len(buf);
    errno = 0;
    double v = decimal_value(buf, m);
    int under = errno == ERANGE && fabs(v) < 1; /* 0 or subnormal from digits that were not 0 (gen/lex.c's test) */
    const char *rest = buf + m;
    if (!strcmp(rest, "kg")) /* the unit of mass, not kilo-grams */
        rest += 2;
    v *= scale_of(&rest);
    if (*rest && !is_unit(rest)) {
        snprintf(why, whylen, "unknown scale suffix or unit '%s'", rest);
        return -1;
    }
    if (!isfinite(v)) {
        snprintf(why, whylen, "number out of range");
        return -1;
    }
    if (under || (v != 0 && fabs(v) < DBL_MIN)) {
        snprintf(why, whylen, "number out of range (its magnitude is below 2.2e-308)");
        return -1;
    }
    *out = v;
    return 0;
}

/* ---- lexer ------------------------------------------------------------- */

typedef enum tok_kind { T_EOF, T_LPAREN, T_RPAREN, T_STRING, T_ATOM } tok_kind;

typedef struct Parser {
    sx_doc *doc;
    const char *p, *end;    /* next byte, end of the text */
    const char *line_start; /* first byte of p's line */
    int line;               /* p's line */
    int depth;              /* lists open */
    char *err;
    size_t errlen;
    tok_kind tk;            /* the current token */
    const char *ts, *te;    /* its bytes */
    int tline, tcol;        /* its position */
    int last_line, last_col; /* just past the last token before EOF */
} Parser;

static int col_of(const Parser *P, const char *q) { return (int)(q - P->line_start) + 1; }

static int syntax_error(Parser *P, int line, int col, const char *fmt, ...)
    SX_PRINTF(4, 5);
static int syntax_error(Parser *P, int line, int col, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vreport(P->doc, line, col, P->err, P->errlen, "error", fmt, ap);
    va_end(ap);
    return -1;
}

static int out_of_memory(Parser *P)
{
    file_error(P->doc->path, P->err, P->errlen, "out of memory");
    return -1;
}

/* A byte no token may hold, at q on the current line. */
static int bad_byte(Parser *P, const char *q)
{
    int c = (unsigned char)*q, col = col_of(P, q);
    if (is_stray(c))
        return syntax_error(P, P->line, col, "stray character 0x%02x", c);
    if (c >= 0x80)
        return syntax_error(P, P->line, col,
                            "non-ASCII byte 0x%02x outside a string or comment", c);
    return syntax_error(P, P->line, col, "unexpected character '%c'", c);
}

/* blanks = (' ' | TAB | CR | LF | comment)* */
static int blanks(Parser *P)
{
    while (P->p < P->end) {
        char c = *P->p;
        if (c == '\n') {
            P->line++;
            P->line_start = ++P->p;
        } else if (c == ' ' || c == '\t' || c == '\r') {
            P->p++;
        } else if (c == ';') {
            /* comment = ';' (any byte but LF and control bytes)* */
            for (; P->p < P->end && *P->p != '\n'; P->p++)
                if (is_stray((unsigned char)*P->p))
                    return bad_byte(P, P->p);
        } else {
            break;
        }
    }
    return 0;
}

/* An escape \c with c not one of " \ n t, at q (the backslash). */
static int bad_escape(Parser *P, const char *q)
{
    int c = (unsigned char)q[1], col = col_of(P, q);
    if (is_stray(c))
        return bad_byte(P, q + 1);
    if (c > ' ' && c < 0x7f)
        return syntax_error(P, P->line, col,
                            "unknown escape '\\%c' in string (use \\\" \\\\ \\n or \\t)", c);
    return syntax_error(P, P->line, col,
                        "unknown escape: '\\' before byte 0x%02x in string "
                        "(use \\\" \\\\ \\n or \\t)",
                        c);
}

/* string = '"' (strchar | escape)* '"', on one line.  Only checks it;
 * string() decodes it. */
static int lex_string(Parser *P)
{
    const char *q = P->p + 1;
    for (;;) {
        if (q == P->end || *q == '\n' || *q == '\r')
            return syntax_error(P, P->tline, P->tcol, "unterminated string");
        if (*q == '"')
            break;
        if (*q == '\\') {
            if (q + 1 == P->end || q[1] == '\n' || q[1] == '\r')
                return syntax_error(P, P->tline, P->tcol, "unterminated string");
            if (q[1] != '"' && q[1] != '\\' && q[1] != 'n' && q[1] != 't')
                return bad_escape(P, q);
            q += 2;
            continue;
        }
        if (is_stray((unsigned char)*q))
            return bad_byte(P, q);
        q++;
    }
    P->p = q + 1;
    P->tk = T_STRING;
    return 0;
}

/* atom = symchar+, ending at a delimiter or EOF. */
static int lex_atom(Parser *P)
{
    while (P->p < P->end && is_symchar((unsigned char)*P->p))
        P->p++;
    if (P->p < P->end && !is_delim((unsigned char)*P->p))
        return bad_byte(P, P->p);
    P->tk = T_ATOM;
    return 0;
}

/* Reads the next token into P->tk, ts, te, tline, tcol. */
static int lex(Parser *P)
{
    if (blanks(P))
        return -1;
    P->ts = P->p;
    P->tline = P->line;
    P->tcol = col_of(P, P->p);
    if (P->p == P->end) {
        P->tk = T_EOF;
        P->te = P->p;
        return 0;
    }
    int c = (unsigned char)*P->p;
    if (c == '(' || c == ')') {
        P->tk = c == '(' ? T_LPAREN : T_RPAREN;
        P->p++;
    } else if (c == '"') {
        if (lex_string(P))
            return -1;
    } else if (is_symchar(c)) {
        if (lex_atom(P))
            return -1;
    } else {
        return bad_byte(P, P->p);
    }
    P->te = P->p;
    P->last_line = P->tline;
    P->last_col = P->tcol + (int)(P->te - P->ts);
    return 0;
}

/* ---- parser ------------------------------------------------------------ */

/* A node of kind k at the current token. */
static sx *node(Parser *P, sx_kind k)
{
    sx *x = doc_alloc(P->doc, sizeof *x);
    if (!x) {
        out_of_memory(P);
        return NULL;
    }
    *x = (sx){.kind = k, .line = P->tline, .col = P->tcol};
    return x;
}

/* The contents of the current string token, escapes resolved. */
static char *string_text(Parser *P)
{
    const char *s = P->ts + 1, *e = P->te - 1;
    char *t = doc_alloc(P->doc, (size_t)(e - s) + 1), *w = t;
    if (!t)
        return NULL;
    while (s < e) {
        char c = *s++;
        if (c == '\\') {
            c = *s++;
            c = c == 'n' ? '\n' : c == 't' ? '\t' : c;
        }
        *w++ = c;
    }
    *w = '\0';
    return t;
}

/* string: see lex_string. */
static sx *string(Parser *P)
{
    sx *x = node(P, SX_STR);
    if (!x)
        return NULL;
    x->text = string_text(P);
    if (!x->text) {
        out_of_memory(P);
        return NULL;
    }
    return lex(P) ? NULL : x;
}

/* atom = number | symbol: a number if it starts like one (looks_numeric). */
static sx *atom(Parser *P)
{
    size_t n = (size_t)(P->te - P->ts);
    int num = looks_numeric(P->ts, n);
    double v = 0;
    char why[128];
    if (num && read_number(P->ts, n, &v, why, sizeof why)) {
        syntax_error(P, P->tline, P->tcol, "malformed number '%.*s': %s", (int)n, P->ts, why);
        return NULL;
    }
    sx *x = node(P, num ? SX_NUM : SX_SYM);
    if (!x)
        return NULL;
    x->num = v;
    x->text = doc_strndup(P->doc, P->ts, n);
    if (!x->text) {
        out_of_memory(P);
        return NULL;
    }
    return lex(P) ? NULL : x;
}

static sx *datum(Parser *P);

/* list = '(' blanks (datum blanks)* ')', at most SX_MAX_DEPTH deep */
static sx *list(Parser *P)
{
    int line = P->tline, col = P->tcol;
    if (++P->depth > SX_MAX_DEPTH) {
        syntax_error(P, line, col, "lists nested more than %d deep", SX_MAX_DEPTH);
        return NULL;
    }
    sx *x = node(P, SX_LIST);
    if (!x || lex(P))
        return NULL;
    for (sx **tail = &x->head; P->tk != T_RPAREN; x->len++) {
        if (P->tk == T_EOF) {
            syntax_error(P, P->last_line, P->last_col,
                         "expected ')' to close '(' at %d:%d", line, col);
            return NULL;
        }
        sx *y = datum(P);
        if (!y)
            return NULL;
        *tail = y;
        tail = &y->next;
    }
    P->depth--;
    return lex(P) ? NULL : x;
}

/* datum = list | string | atom */
static sx *datum(Parser *P)
{
    switch (P->tk) {
    case T_LPAREN: return list(P);
    case T_STRING: return string(P);
    case T_ATOM: return atom(P);
    case T_RPAREN: syntax_error(P, P->tline, P->tcol, "unexpected ')'"); return NULL;
    case T_EOF: break;
    }
    assert(!"datum at EOF");
    return NULL;
}

/* doc = blanks (datum blanks)* EOF */
static int document(Parser *P)
{
    if (lex(P))
        return -1;
    for (sx **tail = &P->doc->forms; P->tk != T_EOF; P->doc->nforms++) {
        sx *x = datum(P);
        if (!x)
            return -1;
        *tail = x;
        tail = &x->next;
    }
    return 0;
}

/* ---- documents --------------------------------------------------------- */

size_t sx_bom(const char *text, size_t len)
{
    return len >= 3 && !memcmp(text, "\xef\xbb\xbf", 3) ? 3 : 0;
}

/* An empty doc holding copies of path and text (after a byte-order mark), or NULL. */
static sx_doc *doc_new(const char *path, const char *text, size_t len)
{
    size_t bom = sx_bom(text, len);
    text += bom, len -= bom;
    sx_doc *d = SX_MALLOC(sizeof *d);
    if (!d)
        return NULL;
    *d = (sx_doc){0};
    char *src = doc_alloc(d, len + 1);
    d->path = doc_strndup(d, path, strlen(path));
    if (!src || !d->path) {
        sx_free(d);
        return NULL;
    }
    if (len)
        memcpy(src, text, len);
    src[len] = '\0';
    d->src = src;
    d->srclen = len;
    return d;
}

sx_doc *sx_parse(const char *path, const char *text, size_t len, char *err, size_t errlen)
{
    assert(text || !len);
    if (err && errlen)
        err[0] = '\0';
    if (!path)
        path = "<string>";
    /* Positions are ints: keep every column and line count in range. */
    if (len > (size_t)INT_MAX - 2) {
        file_error(path, err, errlen, "text too large (%d bytes at most)", INT_MAX - 2);
        return NULL;
    }
    sx_doc *d = doc_new(path, text, len);
    if (!d) {
        file_error(path, err, errlen, "out of memory");
        return NULL;
    }
    Parser P = {.doc = d, .p = d->src, .end = d->src + d->srclen, .line_start = d->src,
                .line = 1, .err = err, .errlen = errlen, .last_line = 1, .last_col = 1};
    if (document(&P)) {
        sx_free(d);
        return NULL;
    }
    return d;
}

int sx_file_ok(const char *path)
{
    struct stat st;
    if (stat(path, &st) != 0)
        return errno ? errno : ENOENT;
    if (S_ISDIR(st.st_mode))
        return EISDIR;
    if (!S_ISREG(st.st_mode))
        return EINVAL;
    if (access(path, R_OK) != 0)
        return errno ? errno : EACCES;
    return 0;
}

const char *sx_file_strerror(int e)
{
    if (e == EINVAL)
        return "not a regular file";
    if (e == EFBIG)
        return "larger than 256 MiB";
    return strerror(e);
}

char *sx_slurp(const char *path, size_t *len, int *e)
{
    if ((*e = sx_file_ok(path)))
        return NULL;
    FILE *f = fopen(path, "rb");
    if (!f) {
        *e = errno ? errno : EIO;
        return NULL;
    }
    size_t cap = 0, n = 0;
    char *buf = NULL;
    for (;;) {
        if (n + 1 >= cap) { /* room for the bytes and a NUL after them */
            if (cap >= SX_MAX_FILE + 2) { /* a byte past the bound was read */
                *e = EFBIG;
                break;
            }
            size_t c = cap ? 2 * cap : 4096;
            c = c < SX_MAX_FILE + 2 ? c : SX_MAX_FILE + 2;
            char *b = SX_REALLOC(buf, c);
            if (!b) {
                *e = ENOMEM;
                break;
            }
            buf = b;
            cap = c;
        }
        size_t k = fread(buf + n, 1, cap - n - 1, f);
        n += k;
        if (k == 0) {
            *e = ferror(f) ? (errno ? errno : EIO) : 0;
            break;
        }
    }
    fclose(f);
    if (*e) {
        SX_FREE(buf);
        return NULL;
    }
    buf[n] = '\0';
    *len = n;
    return buf;
}

sx_doc *sx_read_file(const char *path, char *err, size_t errlen)
{
    assert(path);
    size_t len = 0;
    int e = 0;
    errno = 0;
    char *text = sx_slurp(path, &len, &e);
    if (!text) {
        if (e == ENOMEM)
            file_error(path, err, errlen, "out of memory");
        else
            file_error(path, err, errlen, "cannot read: %s", sx_file_strerror(e));
        return NULL;
    }
    sx_doc *d = sx_parse(path, text, len, err, errlen);
    SX_FREE(text);
    return d;
}

/* ---- helpers ----------------------------------------------------------- */

int sx_is(const sx *x, const char *sym)
{
    return x && x->kind == SX_SYM && !strcmp(x->text, sym);
}

const sx *sx_nth(const sx *list, int i)
{
    if (!list || list->kind != SX_LIST || i < 0)
        return NULL;
    const sx *x = list->head;
    while (x && i--)
        x = x->next;
    return x;
}

const char *sx_kind_name(sx_kind k)
{
    switch (k) {
    case SX_LIST: return "list";
    case SX_SYM: return "symbol";
    case SX_NUM: return "number";
    case SX_STR: return "string";
    }
    return "?";
}

int sx_edit_distance(const char *s, const char *t) {
    int ls = (int)strlen(s), lt = (int)strlen(t);
    if (ls > 60 || lt > 60)
        return 99;
    int d[61][61];
    for (int a = 0; a <= ls; a++)
        d[a][0] = a;
    for (int b = 0; b <= lt; b++)
        d[0][b] = b;
    for (int a = 1; a <= ls; a++)
        for (int b = 1; b <= lt; b++) {
            int c = d[a - 1][b - 1] + (s[a - 1] != t[b - 1]);
            c = d[a - 1][b] + 1 < c ? d[a - 1][b] + 1 : c;
            d[a][b] = d[a][b - 1] + 1 < c ? d[a][b - 1] + 1 : c;
        }
    return d[ls][lt];
}
