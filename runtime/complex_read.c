/*
 * complex_read.c - reading a simplicial complex from a file.
 *
 * Two formats, told apart by the first token:
 *
 *   Frank Lutz's lists, several to a file:
 *     file    = { list [ coords ] }
 *     list    = NAME '=' '[' facet { ',' facet } ']'
 *     facet   = '[' VERTEX { ',' VERTEX } ']'
 *   A name `manifold_D_N_...` promises dimension D and vertices 1..N: every
 *   facet has D + 1 vertices and every vertex 1..N lies in one.  Newlines
 *   may fall anywhere inside a list.
 *
 *   One facet per line:
 *     file    = { facet NEWLINE } [ coords ]
 *     facet   = VERTEX { VERTEX }
 *
 *   Either may give the vertices coordinates, after the list (or the
 *   facets) they belong to:
 *     coords  = 'coordinates' NEWLINE { VERTEX NUMBER { NUMBER } NEWLINE }
 *   every vertex once, each row as long as the first (at most
 *   CX_MAX_COORDS numbers).  They make the waves' turns geometric
 *   (cx.h, cx_turns).
 *
 * VERTEX is a whole number from 0 to 999999999; `#` starts a comment
 * that runs to the end of its line.  The complex is the closure of its
 * facets, so every face of a facet is in it by construction; what can be
 * wrong is checked here with its position: a vertex out of range or
 * repeated in a facet, a facet of the wrong size, listed twice, or too
 * large, a promised vertex in no facet, coordinates for a vertex the
 * complex lacks, twice, missing or of the wrong count.  Errors read like
 * the scene reader's (sexp.h): FILE:LINE:COL: error: message, the line
 * and a caret.
 */
#include "cx.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>

#include "sexp.h"

#define MAX_LABEL 999999999L

/* complex.c: the closure, reporting a facet listed twice by index. */
CX_HIDDEN cx_complex *cx_build_(int nf, const int *fo, const long *lab, int *dup, int *first);

enum { T_EOF, T_NL, T_NUM, T_NAME, T_LB, T_RB, T_COMMA, T_EQ, T_BAD };

typedef struct tok {
    int kind;
    int line, col;
    const char *s; /* its text in the source */
    int n;
} tok;

typedef struct pos {
    int line, col;
} pos;

/* Growing arrays of what the chosen list holds. */
typedef struct facets {
    int *fo;       /* facet f: labels lab[fo[f] .. fo[f+1]) */
    long *lab;
    pos *at;       /* each facet's '[' (or first vertex) */
    int nf, nl, capf, capa, capl;
    long *rlab;    /* coordinate rows: label, position, values */
    pos *rat;
    double *rval;
    int nrow, caprl, capra, caprv, ncoord;
    pos coords;    /* the word 'coordinates', or line 0 */
} facets;

typedef struct reader {
    const char *path, *src;
    size_t len, p;
    int line, col;
    tok t;         /* the token at hand */
    sx_doc doc;    /* for sx_error_at: path and text only */
    char *err;
    size_t errlen;
    const char *want; /* the list asked for, or NULL: the first */
    int keep;      /* this list is the one read into F */
    int found;
    int lutz;
    char names[256]; /* the lists seen, for a message */
    int dim, nmax; /* a manifold_D_N name's promise, or -1 */
    char *name;    /* the list at hand */
    char *kname;   /* the list kept, its position and promise */
    pos name_at;
    int knmax;
    facets F;
} reader;

static int error_at(reader *R, int line, int col, const char *fmt, ...) SX_PRINTF(4, 5);
static int error_at(reader *R, int line, int col, const char *fmt, ...) {
    char msg[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    return sx_error_at(&R->doc, line, col, R->err, R->errlen, "%s", msg);
}

#define ERR_AT(tk, ...) error_at(R, (tk).line, (tk).col, __VA_ARGS__)

/* ---- tokens ---- */

static int name_char(int c, int first) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_' ||
           (!first && ((c >= '0' && c <= '9') || c == '.' || c == '+' || c == '-'));
}

static int num_char(int c) { return (c >= '0' && c <= '9') || c == '.' || c == 'e' || c == 'E' || c == '+' || c == '-'; }

static void advance(reader *R) {
    const char *s = R->src;
    while (R->p < R->len && (s[R->p] == ' ' || s[R->p] == '\t' || s[R->p] == '\r' || s[R->p] == '#')) {
        if (s[R->p] == '#')
            while (R->p < R->len && s[R->p] != '\n')
                R->p++, R->col++;
        else
            R->p++, R->col++;
    }
    tok *t = &R->t;
    t->line = R->line, t->col = R->col, t->s = s + R->p, t->n = 1;
    if (R->p >= R->len) {
        t->kind = T_EOF, t->n = 0;
        return;
    }
    int c = (unsigned char)s[R->p];
    const char *one = strchr("\n[],=", c);
    if (c && one) {
        static const int kinds[] = {T_NL, T_LB, T_RB, T_COMMA, T_EQ};
        t->kind = kinds[one - "\n[],="];
    } else if (name_char(c, 1) || num_char(c)) {
        int nm = name_char(c, 1);
        t->kind = nm ? T_NAME : T_NUM;
        while (R->p + (size_t)t->n < R->len && (nm ? name_char(s[R->p + (size_t)t->n], 0) : num_char(s[R->p + (size_t)t->n])))
            t->n++;
    } else {
        t->kind = T_BAD;
    }
    R->p += (size_t)t->n, R->col += t->n;
    if (t->kind == T_NL)
        R->line++, R->col = 1;
}

static int is_word(const tok *t, const char *w) { return t->kind == T_NAME && (size_t)t->n == strlen(w) && !strncmp(t->s, w, (size_t)t->n); }

static int bad_token(reader *R, const char *what) {
    const tok *t = &R->t;
    if (t->kind == T_EOF)
        return ERR_AT(*t, "expected %s, found the end of the file", what);
    if (t->kind == T_NL)
        return ERR_AT(*t, "expected %s, found the end of the line", what);
    if (t->kind == T_BAD) {
        unsigned char c = (unsigned char)t->s[0];
        if (c >= 32 && c < 127)
            return ERR_AT(*t, "expected %s, found '%c'", what, c);
        return ERR_AT(*t, "expected %s, found the byte 0x%02x", what, c);
    }
    return ERR_AT(*t, "expected %s, found '%.*s'", what, t->n > 40 ? 40 : t->n, t->s);
}

/* VERTEX: a whole number, 0 .. MAX_LABEL. */
static int vertex(reader *R, long *v) {
    const tok *t = &R->t;
    if (t->kind != T_NUM)
        return bad_token(R, "a vertex number");
    long x = 0;
    for (int i = 0; i < t->n; i++) {
        if (t->s[i] < '0' || t->s[i] > '9')
            return ERR_AT(*t, "a vertex is a whole number from 0, not '%.*s'", t->n > 40 ? 40 : t->n, t->s);
        x = x * 10 + (t->s[i] - '0');
        if (x > MAX_LABEL)
            return ERR_AT(*t, "vertex number too large (at most %ld)", MAX_LABEL);
    }
    if (R->nmax >= 0 && (x < 1 || x > R->nmax))
        return ERR_AT(*t, "vertex %ld is out of range: %s has vertices 1 to %d", x, R->name, R->nmax);
    *v = x;
    advance(R);
    return 0;
}

/* ---- what the chosen list holds ---- */

static int grow_to(void **p, int *cap, int need, size_t sz) {
    if (need <= *cap)
        return 0;
    int c = *cap ? *cap : 256;
    while (c < need)
        c *= 2;
    void *q = realloc(*p, sz * (size_t)c);
    if (!q)
        return -1;
    *p = q, *cap = c;
    return 0;
}

static int oom(reader *R) { return error_at(R, R->t.line, R->t.col, "out of memory"); }

static int begin_facet(reader *R, pos at) {
    facets *F = &R->F;
    if (!R->keep)
        return 0;
    if (grow_to((void **)&F->fo, &F->capf, F->nf + 2, sizeof *F->fo) ||
        grow_to((void **)&F->at, &F->capa, F->nf + 2, sizeof *F->at))
        return oom(R);
    F->at[F->nf] = at;
    F->fo[F->nf] = F->nl;
    return 0;
}

/* Adds vertex v at t to the facet begun last: not twice, at most
 * CX_MAX_VERTS. */
static int add_vertex(reader *R, long v, tok t) {
    facets *F = &R->F;
    if (!R->keep)
        return 0;
    int n = F->nl - F->fo[F->nf];
    for (int i = F->fo[F->nf]; i < F->nl; i++)
        if (F->lab[i] == v)
            return ERR_AT(t, "vertex %ld is already in this facet", v);
    if (n == CX_MAX_VERTS)
        return ERR_AT(t, "a facet has at most %d vertices (dimension %d)", CX_MAX_VERTS, CX_MAX_VERTS - 1);
    if (grow_to((void **)&F->lab, &F->capl, F->nl + 1, sizeof *F->lab))
        return oom(R);
    F->lab[F->nl++] = v;
    return 0;
}

static int end_facet(reader *R) {
    facets *F = &R->F;
    if (!R->keep)
        return 0;
    int n = F->nl - F->fo[F->nf];
    if (R->dim >= 0 && n != R->dim + 1)
        return error_at(R, F->at[F->nf].line, F->at[F->nf].col, "a facet of %s has %d vertices, not %d", R->name, n,
                        R->dim + 1);
    F->fo[++F->nf] = F->nl;
    return 0;
}

/* ---- Lutz's lists ---- */

static void skip_newlines(reader *R) {
    while (R->t.kind == T_NL)
        advance(R);
}

/* facet = '[' VERTEX { ',' VERTEX } ']' */
static int lutz_facet(reader *R) {
    skip_newlines(R);
    if (R->t.kind != T_LB)
        return bad_token(R, "'[' to start a facet");
    pos at = {R->t.line, R->t.col};
    advance(R);
    if (begin_facet(R, at))
        return -1;
    for (;;) {
        skip_newlines(R);
        tok vt = R->t;
        long v = 0;
        if (vertex(R, &v) || add_vertex(R, v, vt))
            return -1;
        skip_newlines(R);
        if (R->t.kind == T_RB)
            break;
        if (R->t.kind != T_COMMA)
            return bad_token(R, "',' or ']' after a vertex");
        advance(R);
    }
    advance(R);
    return end_facet(R);
}

/* What a name `manifold_D_N...` promises. */
static void promise(reader *R) {
    int d, n, used = 0;
    R->dim = R->nmax = -1;
    if (sscanf(R->name, "manifold_%d_%d%n", &d, &n, &used) == 2 && used > 0 && d >= 0 && n >= 1 &&
        (R->name[used] == 0 || R->name[used] == '_'))
        R->dim = d, R->nmax = n;
}

static void note_name(reader *R, const char *name) {
    size_t n = strlen(R->names);
    if (n + strlen(name) + 8 < sizeof R->names)
        snprintf(R->names + n, sizeof R->names - n, "%s%s", n ? ", " : "", name);
    else if (n + 5 < sizeof R->names && !strstr(R->names, "..."))
        strcat(R->names, ", ...");
}

/* list = NAME '=' '[' facet { ',' facet } ']' */
static int lutz_list(reader *R) {
    tok nt = R->t;
    free(R->name);
    R->name = malloc((size_t)nt.n + 1);
    if (!R->name)
        return oom(R);
    memcpy(R->name, nt.s, (size_t)nt.n);
    R->name[nt.n] = 0;
    note_name(R, R->name);
    R->keep = !R->found && (!R->want || !strcmp(R->want, R->name));
    promise(R);
    if (R->keep) {
        R->found = 1, R->name_at = (pos){nt.line, nt.col};
        R->knmax = R->nmax;
        if (!(R->kname = malloc(strlen(R->name) + 1)))
            return oom(R);
        strcpy(R->kname, R->name);
    }
    advance(R);
    skip_newlines(R);
    if (R->t.kind != T_EQ)
        return bad_token(R, "'=' after the list's name");
    advance(R);
    skip_newlines(R);
    if (R->t.kind != T_LB)
        return bad_token(R, "'[' to start the list of facets");
    advance(R);
    for (;;) {
        if (lutz_facet(R))
            return -1;
        skip_newlines(R);
        if (R->t.kind == T_RB)
            break;
        if (R->t.kind != T_COMMA)
            return bad_token(R, "',' or ']' after a facet");
        advance(R);
    }
    advance(R);
    return 0;
}

/* ---- coordinates ---- */

static int number(reader *R, double *x) {
    const tok *t = &R->t;
    char buf[64];
    if (t->kind != T_NUM)
        return bad_token(R, "a coordinate");
    if (t->n >= (int)sizeof buf)
        return ERR_AT(*t, "'%.40s...' is not a number", t->s);
    memcpy(buf, t->s, (size_t)t->n);
    buf[t->n] = 0;
    char *end;
    errno = 0;
    *x = strtod(buf, &end);
    if (*end || !isfinite(*x) || errno == ERANGE)
        return ERR_AT(*t, "'%s' is not a finite number", buf);
    advance(R);
    return 0;
}

/* One row: VERTEX NUMBER { NUMBER } NEWLINE */
static int coord_row(reader *R) {
    facets *F = &R->F;
    tok lt = R->t;
    long v = 0;
    if (vertex(R, &v))
        return -1;
    int n = 0;
    if (R->keep && (grow_to((void **)&F->rlab, &F->caprl, F->nrow + 1, sizeof *F->rlab) ||
                    grow_to((void **)&F->rat, &F->capra, F->nrow + 1, sizeof *F->rat)))
        return oom(R);
    while (R->t.kind != T_NL && R->t.kind != T_EOF) {
        double x = 0;
        tok xt = R->t;
        if (number(R, &x))
            return -1;
        if (n == CX_MAX_COORDS)
            return ERR_AT(xt, "a vertex has at most %d coordinates", CX_MAX_COORDS);
        if (F->nrow > 0 && n == F->ncoord && R->keep)
            return ERR_AT(xt, "expected %d coordinate%s, as on the first row", F->ncoord, F->ncoord > 1 ? "s" : "");
        if (R->keep && grow_to((void **)&F->rval, &F->caprv, F->nrow * CX_MAX_COORDS + n + 1, sizeof *F->rval))
            return oom(R);
        if (R->keep)
            F->rval[F->nrow * CX_MAX_COORDS + n] = x;
        n++;
    }
    if (n == 0)
        return bad_token(R, "coordinates after the vertex");
    if (R->keep && F->nrow > 0 && n != F->ncoord)
        return ERR_AT(lt, "expected %d coordinate%s, as on the first row, found %d", F->ncoord, F->ncoord > 1 ? "s" : "",
                      n);
    if (R->keep) {
        F->ncoord = n;
        F->rlab[F->nrow] = v;
        F->rat[F->nrow++] = (pos){lt.line, lt.col};
    }
    return 0;
}

/* coords = 'coordinates' NEWLINE { row } : rows up to the end of the
 * file, or (in a Lutz file) up to the next list. */
static int coords(reader *R) {
    if (R->keep && R->F.coords.line)
        return ERR_AT(R->t, "this complex has coordinates already (from %d:%d)", R->F.coords.line, R->F.coords.col);
    if (R->keep)
        R->F.coords = (pos){R->t.line, R->t.col};
    advance(R);
    if (R->t.kind != T_NL && R->t.kind != T_EOF)
        return bad_token(R, "the end of the line after 'coordinates'");
    for (skip_newlines(R); R->t.kind == T_NUM; skip_newlines(R))
        if (coord_row(R))
            return -1;
    return 0;
}

/* ---- the file ---- */

static int lutz_file(reader *R) {
    while (R->t.kind != T_EOF) {
        if (is_word(&R->t, "coordinates")) {
            if (!R->name)
                return ERR_AT(R->t, "coordinates come after the list they belong to");
            if (coords(R))
                return -1;
        } else if (R->t.kind == T_NAME) {
            if (lutz_list(R))
                return -1;
        } else {
            return bad_token(R, "a list NAME=[[...],...]");
        }
        skip_newlines(R);
    }
    return 0;
}

/* file = { facet NEWLINE } [ coords ] */
static int plain_file(reader *R) {
    R->keep = R->found = 1;
    R->dim = R->nmax = -1;
    while (R->t.kind != T_EOF) {
        if (is_word(&R->t, "coordinates")) {
            if (coords(R))
                return -1;
            if (R->t.kind != T_EOF)
                return bad_token(R, "a row of coordinates (VERTEX X Y ...)");
            break;
        }
        pos at = {R->t.line, R->t.col};
        if (begin_facet(R, at))
            return -1;
        while (R->t.kind != T_NL && R->t.kind != T_EOF) {
            tok vt = R->t;
            long v = 0;
            if (vertex(R, &v) || add_vertex(R, v, vt))
                return -1;
        }
        if (end_facet(R))
            return -1;
        skip_newlines(R);
    }
    return 0;
}

/* Every vertex a manifold_D_N name promises lies in a facet. */
static int check_promise(reader *R, const cx_complex *K) {
    if (!R->lutz || R->knmax < 0 || K->nv == R->knmax)
        return 0;
    for (long v = 1; v <= R->knmax; v++)
        if (cx_vertex(K, v) < 0)
            return error_at(R, R->name_at.line, R->name_at.col, "vertex %ld of %s lies in no facet", v, R->kname);
    return 0;
}

/* Coordinates for every vertex, once each. */
static int attach_coords(reader *R, cx_complex *K) {
    facets *F = &R->F;
    if (!F->coords.line)
        return 0;
    int *row = malloc(sizeof *row * ((size_t)K->nv + 1));
    K->coord = malloc(sizeof *K->coord * ((size_t)K->nv * (size_t)F->ncoord + 1));
    if (!row || !K->coord) {
        free(row);
        return error_at(R, F->coords.line, F->coords.col, "out of memory");
    }
    K->ncoord = F->ncoord;
    for (int v = 0; v < K->nv; v++)
        row[v] = -1;
    int r = 0;
    for (int i = 0; i < F->nrow && !r; i++) {
        int v = cx_vertex(K, F->rlab[i]);
        if (v < 0)
            r = error_at(R, F->rat[i].line, F->rat[i].col, "vertex %ld lies in no facet", F->rlab[i]);
        else if (row[v] >= 0)
            r = error_at(R, F->rat[i].line, F->rat[i].col, "vertex %ld has coordinates already (at %d:%d)",
                         F->rlab[i], F->rat[row[v]].line, F->rat[row[v]].col);
        else
            row[v] = i, memcpy(K->coord + (size_t)v * (size_t)K->ncoord, F->rval + (size_t)i * CX_MAX_COORDS,
                               sizeof *K->coord * (size_t)K->ncoord);
    }
    for (int v = 0; v < K->nv && !r; v++)
        if (row[v] < 0)
            r = error_at(R, F->coords.line, F->coords.col, "vertex %ld has no coordinates", K->label[v]);
    free(row);
    return r;
}

static cx_complex *make(reader *R) {
    facets *F = &R->F;
    if (!R->found) {
        if (R->want)
            sx_error(&R->doc, NULL, R->err, R->errlen, "no complex named '%s' in this file (it holds %s)", R->want,
                     R->names[0] ? R->names : "none");
        else
            sx_error(&R->doc, NULL, R->err, R->errlen, "the file holds no complex");
        return NULL;
    }
    if (F->nf == 0) {
        error_at(R, R->lutz ? R->name_at.line : R->t.line, R->lutz ? R->name_at.col : R->t.col,
                 "%s holds no facets", R->lutz ? R->kname : "the file");
        return NULL;
    }
    int dup, first;
    cx_complex *K = cx_build_(F->nf, F->fo, F->lab, &dup, &first);
    if (!K && dup >= 0)
        error_at(R, F->at[dup].line, F->at[dup].col, "this facet is listed twice (first at %d:%d)", F->at[first].line,
                 F->at[first].col);
    else if (!K)
        error_at(R, 1, 1, "out of memory");
    if (K && (check_promise(R, K) || attach_coords(R, K))) {
        cx_free(K);
        return NULL;
    }
    return K;
}

static void reader_free(reader *R) {
    facets *F = &R->F;
    free(F->fo), free(F->lab), free(F->at), free(F->rlab), free(F->rat), free(F->rval);
}

cx_complex *cx_parse(const char *path, const char *text, size_t len, const char *name, char *err, size_t errlen) {
    reader R;
    memset(&R, 0, sizeof R);
    R.path = path ? path : "<string>";
    size_t bom = sx_bom(text, len);
    text += bom, len -= bom;
    R.src = text, R.len = len, R.line = R.col = 1;
    R.doc.path = R.path, R.doc.src = text, R.doc.srclen = len;
    R.err = err, R.errlen = errlen, R.want = name;
    R.dim = R.nmax = -1;
    if (err && errlen)
        err[0] = 0;
    advance(&R);
    skip_newlines(&R);
    R.lutz = R.t.kind == T_NAME && !is_word(&R.t, "coordinates");
    cx_complex *K = NULL;
    if (name && !R.lutz) { /* a name picks one of a Lutz file's lists; this file holds one complex */
        if (err && errlen)
            snprintf(err, errlen, "%s: error: no complex named '%s': the file holds one complex, of facets a line, "
                     "and names only a Lutz file's lists\n", R.path, name);
        free(R.name);
        free(R.kname);
        return NULL;
    }
    if (R.lutz ? !lutz_file(&R) : !plain_file(&R))
        K = make(&R);
    if (K && (!(K->path = malloc(strlen(R.path) + 1)) || (R.lutz && !(K->name = malloc(strlen(R.kname) + 1))))) {
        cx_free(K);
        K = NULL;
        sx_error(&R.doc, NULL, err, errlen, "out of memory");
    }
    if (K) {
        strcpy(K->path, R.path);
        if (R.lutz)
            strcpy(K->name, R.kname);
    }
    free(R.name);
    free(R.kname);
    reader_free(&R);
    return K;
}

cx_complex *cx_read_file(const char *path, const char *name, char *err, size_t errlen) {
    size_t n = 0;
    int e = 0;
    char *buf = sx_slurp(path, &n, &e);
    if (!buf) {
        if (e == ENOMEM)
            snprintf(err, errlen, "%s: error: out of memory\n", path);
        else
            snprintf(err, errlen, "%s: error: cannot read: %s\n", path, sx_file_strerror(e));
        return NULL;
    }
    cx_complex *K = cx_parse(path, buf, n, name, err, errlen);
    free(buf);
    return K;
}
