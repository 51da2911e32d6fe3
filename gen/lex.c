/* lex.c: netlist text -> tokens.
 *
 * The netlist is line oriented: every logical line ends with TK_EOL.  A
 * line whose first non-blank character is '+' continues the previous one
 * (SPICE).  '#' and ';' start a comment anywhere; '*' at the start of a
 * line is a SPICE comment line.  A SPICE deck (SrcFile.spice) is read in
 * lower case after its title line, with '$' comments too and 'quoted'
 * expressions.  Words (names, nodes, numbers, directives) are runs
 * of letters, digits, '_' and '.'; whether a word is a number is decided by
 * the parser where it expects one, so SPICE node names such as `1` work. */
#include <ctype.h>
#include <errno.h>
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "gen.h"

typedef struct Lexer {
    SrcFile *file;
    const char *p;
    int line;
    const char *line_start;
    Token *toks;
    int ntok, cap;
} Lexer;

static SrcPos pos_of(Lexer *L, const char *p) {
    return (SrcPos){L->file, L->line, (int)(p - L->line_start) + 1};
}

static Token *push(Lexer *L, TokKind k, const char *start, int len) {
    if (L->ntok == L->cap) {
        L->cap = L->cap ? 2 * L->cap : 256;
        Token *t = arena_alloc(sizeof(Token) * (size_t)L->cap);
        if (L->ntok)
            memcpy(t, L->toks, sizeof(Token) * (size_t)L->ntok);
        L->toks = t;
    }
    Token *t = &L->toks[L->ntok++];
    *t = (Token){.kind = k, .pos = pos_of(L, start), .text = start, .len = len};
    return t;
}

static bool is_word(int c) { return isalnum(c) || c == '_' || c == '.'; }

bool tok_is(const Token *t, const char *s) {
    return (int)strlen(s) == t->len && !strncmp(t->text, s, (size_t)t->len);
}

/* Scale suffixes, case-insensitive, SPICE's: "meg" and "mil" (a
 * thousandth of an inch) before "m". */
static const struct { const char *s; double v; } suffixes[] = {
    {"meg", 1e6}, {"mil", 25.4e-6}, {"f", 1e-15}, {"p", 1e-12}, {"n", 1e-9},
    {"u", 1e-6},  {"m", 1e-3},      {"k", 1e3},   {"g", 1e9},   {"t", 1e12},
};

/* Unit words that may follow a number and its suffix (ignored), as
 * written; in a SPICE deck in any case (it is read folded: 10nF is 10nf). */
static const char *units[] = {"F", "H", "V", "A", "s", "Hz", "ohm", "Ohm", "N"};

bool lex_number(const char *s, int len, double *out, const char **why) { return lex_number_in(s, len, out, why, false); }

bool lex_number_in(const char *s, int len, double *out, const char **why, bool deck) {
    char buf[64];
    if (len <= 0 || len >= (int)sizeof buf) {
        *why = "number too long";
        return false;
    }
    memcpy(buf, s, (size_t)len);
    buf[len] = '\0';
    char *end;
    const char *q = buf;
    if (*q == '+' || *q == '-')
        q++;
    if (!isdigit((unsigned char)*q) && !(*q == '.' && isdigit((unsigned char)q[1]))) {
        *why = "not a number";
        return false;
    }
    /* strtod would accept hex and inf/nan; the checks above exclude them
     * except "0x", refused here. */
    if (q[0] == '0' && (q[1] == 'x' || q[1] == 'X')) {
        *why = "hexadecimal numbers are not accepted";
        return false;
    }
    errno = 0;
    double v = strtod(buf, &end);
    if (end == buf) {
        *why = "not a number";
        return false;
    }
    bool under = errno == ERANGE && fabs(v) < 1; /* 0 or subnormal from digits that were not 0 */
    const char *rest = end;
    double scale = 1;
    if (!strcmp(rest, "kg")) /* the SI unit of mass, not kilo-grams of anything */
        rest += 2;
    for (size_t i = 0; *rest && i < sizeof suffixes / sizeof suffixes[0]; i++) {
        size_t n = strlen(suffixes[i].s);
        if (!strncasecmp(rest, suffixes[i].s, n)) {
            scale = suffixes[i].v;
            rest += n;
            break;
        }
    }
    if (*rest) {
        bool ok = false;
        for (size_t i = 0; i < sizeof units / sizeof units[0]; i++)
            if (deck ? !strcasecmp(rest, units[i]) : !strcmp(rest, units[i]))
                ok = true;
        ok = ok || (deck && !strcmp(rest, "ohms"));
        if (!ok) {
            *why = format("unknown scale suffix or unit '%s'", rest);
            return false;
        }
    }
    v *= scale;
    if (!isfinite(v)) {
        *why = "number out of range";
        return false;
    }
    if (under || (v != 0 && fabs(v) < DBL_MIN)) {
        *why = "number out of range (its magnitude is below 2.2e-308)";
        return false;
    }
    *out = v;
    return true;
}

/* Skips a '+' continuation: returns true if the next line continues. */
static bool continues(const char *p) {
    while (*p == ' ' || *p == '\t')
        p++;
    return *p == '+';
}

static void newline(Lexer *L) {
    L->p++;
    L->line++;
    L->line_start = L->p;
}

static void lex_brace(Lexer *L) {
    const char *start = L->p;
    int depth = 0;
    for (const char *q = L->p; *q && *q != '\n'; q++) {
        if (*q == '{')
            depth++;
        else if (*q == '}' && --depth == 0) {
            Token *t = push(L, TK_LBRACE, start + 1, (int)(q - start - 1));
            t->pos = pos_of(L, start + 1);
            L->p = q + 1;
            return;
        }
    }
    error_at(pos_of(L, start), "unterminated '{': expected '}' on the same line");
}

static void lex_word(Lexer *L) {
    const char *s = L->p;
    const char *q = s;
    if (*q == '+' || *q == '-')
        q++;
    bool numeric = isdigit((unsigned char)*q) || (*q == '.' && isdigit((unsigned char)q[1]));
    while (*q) {
        if (is_word((unsigned char)*q))
            q++;
        else if ((*q == '+' || *q == '-') && numeric && (q[-1] == 'e' || q[-1] == 'E') &&
                 isdigit((unsigned char)q[1]))
            q++; /* exponent sign inside a number such as 1e-3 */
        else
            break;
    }
    Token *t = push(L, TK_IDENT, s, (int)(q - s));
    const char *why;
    double v;
    if (lex_number_in(s, (int)(q - s), &v, &why, L->file->spice)) {
        t->kind = TK_NUMBER;
        t->num = v;
    }
    L->p = q;
}

bool spice_always;

bool is_spice_path(const char *path) {
    static const char *const ext[] = {".cir", ".sp", ".spice", ".net"};
    const char *dot = strrchr(path, '.'), *slash = strrchr(path, '/');
    if (spice_always)
        return true;
    for (int i = 0; dot && (!slash || dot > slash) && i < (int)(sizeof ext / sizeof ext[0]); i++)
        if (!strcasecmp(dot, ext[i]))
            return true;
    return false;
}

/* A SPICE deck is read in lower case (quoted file names aside); tokens
 * point into that copy, which keeps every position of the original. */
static const char *folded(const char *text) {
    char *t = arena_strdup(text);
    bool quoted = false;
    for (char *q = t; *q; q++) {
        quoted = *q == '"' ? !quoted : *q == '\n' ? false : quoted;
        if (!quoted)
            *q = (char)tolower((unsigned char)*q);
    }
    return t;
}

/* 'expression' in a SPICE deck: the same as {expression}. */
static void lex_quote(Lexer *L) {
    const char *start = L->p, *q = start + 1;
    while (*q && *q != '\'' && *q != '\n')
        q++;
    if (*q != '\'')
        error_at(pos_of(L, start), "unterminated quote: expected ' on the same line");
    Token *t = push(L, TK_LBRACE, start + 1, (int)(q - start - 1));
    t->pos = pos_of(L, start + 1);
    L->p = q + 1;
}

Token *lex_file(SrcFile *f, int *ntok) {
    const char *text = f->spice ? folded(f->text) : f->text;
    Lexer L = {.file = f, .p = text, .line = 1, .line_start = text};
    bool at_line_start = true;
    if (f->spice && !f->includer) { /* the title line */
        while (*L.p && *L.p != '\n')
            L.p++;
        if (*L.p)
            newline(&L);
    }
    while (*L.p) {
        char c = *L.p;
        if (c == '\n') {
            if (continues(L.p + 1)) {
                newline(&L);
                while (*L.p == ' ' || *L.p == '\t')
                    L.p++;
                L.p++; /* the '+' */
                continue;
            }
            if (L.ntok && L.toks[L.ntok - 1].kind != TK_EOL)
                push(&L, TK_EOL, L.p, 0);
            newline(&L);
            at_line_start = true;
            continue;
        }
        if (c == ' ' || c == '\t' || c == '\r') {
            L.p++;
            continue;
        }
        if (c == '#' || c == ';' || (c == '*' && at_line_start) || (c == '$' && f->spice)) {
            while (*L.p && *L.p != '\n')
                L.p++;
            continue;
        }
        at_line_start = false;
        if (c == '{') {
            lex_brace(&L);
        } else if (c == '\'' && f->spice) {
            lex_quote(&L);
        } else if (c == '"') {
            const char *s = L.p + 1, *q = s;
            while (*q && *q != '"' && *q != '\n')
                q++;
            if (*q != '"')
                error_at(pos_of(&L, L.p), "unterminated string");
            Token *t = push(&L, TK_STRING, s, (int)(q - s));
            t->pos = pos_of(&L, L.p);
            L.p = q + 1;
        } else if (is_word((unsigned char)c) ||
                   ((c == '-' || c == '+') &&
                    (isdigit((unsigned char)L.p[1]) || L.p[1] == '.'))) {
            lex_word(&L);
        } else {
            TokKind k = c == '=' ? TK_EQ : c == '(' ? TK_LPAREN : c == ')' ? TK_RPAREN
                      : c == ',' ? TK_COMMA : TK_OTHER;
            if (k == TK_OTHER && !isprint((unsigned char)c))
                error_at(pos_of(&L, L.p), "stray byte 0x%02x in netlist", (unsigned char)c);
            push(&L, k, L.p, 1);
            L.p++;
        }
    }
    if (L.ntok && L.toks[L.ntok - 1].kind != TK_EOL)
        push(&L, TK_EOL, L.p, 0);
    push(&L, TK_EOF, L.p, 0);
    *ntok = L.ntok;
    return L.toks;
}
