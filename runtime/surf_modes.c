/*
 * surf_modes.c - the reader of `.modes` files (one mode per line: F T60
 * GAIN...).  The format and the messages are in surf.h; errors are
 * formatted by sexp.c's sx_error_at, like every reader of the runtime.
 */
#include "surf.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sexp.h"

#define MAX_FIELDS (2 + SURF_MAX_PICKUPS)
#define MAX_TOKEN 63 /* characters of a number, at most */

typedef struct reader {
    sx_doc doc;        /* path and text, for sx_error_at */
    const char *text;
    size_t len, pos;   /* the text and the next byte */
    int line, col;     /* of text[pos], 1-based */
    char *err;
    size_t errlen;
} reader;

/* One number of a line, with its position. */
typedef struct field {
    double v;
    int col;
} field;

static int is_blank(int c) { return c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v'; }
static int ends_token(int c) { return is_blank(c) || c == '\n' || c == ';'; }

static void advance(reader *R) {
    if (R->text[R->pos++] == '\n')
        R->line++, R->col = 1;
    else
        R->col++;
}

/* Skips to the end of the line (past a comment), not past the newline. */
static void skip_rest(reader *R) {
    while (R->pos < R->len && R->text[R->pos] != '\n')
        advance(R);
}

/* The number token at R's position, into f; -1 after reporting one that
 * is not a finite number. */
static int number(reader *R, field *f) {
    size_t start = R->pos;
    f->col = R->col;
    while (R->pos < R->len && !ends_token((unsigned char)R->text[R->pos]))
        advance(R);
    size_t n = R->pos - start;
    char buf[MAX_TOKEN + 1], *end;
    if (n <= MAX_TOKEN) {
        memcpy(buf, R->text + start, n);
        buf[n] = 0;
        f->v = strtod(buf, &end);
        if (end == buf + n && memchr(buf, 0, n) == NULL && isfinite(f->v))
            return 0;
    }
    return sx_error_at(&R->doc, R->line, f->col, R->err, R->errlen, "expected a number, found '%.*s'",
                       n > 24 ? 24 : (int)n, R->text + start);
}

/* Reads the fields of one line (up to its newline, which is left);
 * returns how many, or -1 after an error. */
static int line_fields(reader *R, field *f) {
    int nf = 0;
    for (;;) {
        while (R->pos < R->len && is_blank((unsigned char)R->text[R->pos]))
            advance(R);
        if (R->pos == R->len || R->text[R->pos] == '\n')
            return nf;
        if (R->text[R->pos] == ';') {
            skip_rest(R);
            return nf;
        }
        if (nf == MAX_FIELDS)
            return sx_error_at(&R->doc, R->line, R->col, R->err, R->errlen,
                               "too many gains: at most %d pickups", SURF_MAX_PICKUPS);
        if (number(R, &f[nf++]))
            return -1;
    }
}

/* Checks one line's fields as a mode (the line is R->line); *np is the
 * gains per line so far (0 before the first mode) and `first` its line. */
static int check_mode(reader *R, const field *f, int nf, int *np, int first) {
    if (nf < 3)
        return sx_error_at(&R->doc, R->line, f[0].col, R->err, R->errlen,
                           "a mode needs a frequency, a T60 and at least one gain");
    if (!(f[0].v > 0))
        return sx_error_at(&R->doc, R->line, f[0].col, R->err, R->errlen, "the frequency must be positive (Hz)");
    if (!(f[1].v > 0))
        return sx_error_at(&R->doc, R->line, f[1].col, R->err, R->errlen, "the T60 must be positive (s)");
    if (*np && nf - 2 != *np)
        return sx_error_at(&R->doc, R->line, f[2].col, R->err, R->errlen,
                           "expected %d gain%s, as on line %d, found %d", *np, *np == 1 ? "" : "s", first,
                           nf - 2);
    *np = nf - 2;
    return 0;
}

int surf_modes_parse(const char *path, const char *text, size_t len, surf_mode *modes, int max,
                     int *npickups, char *err, size_t errlen) {
    reader R = {{0}, text, len, 0, 1, 1, err, errlen};
    R.doc.path = path ? path : "<string>";
    R.doc.src = text;
    R.doc.srclen = len;
    if (err && errlen)
        err[0] = 0;
    int count = 0, np = 0, first = 0;
    while (R.pos < R.len) {
        field f[MAX_FIELDS];
        int line = R.line, nf = line_fields(&R, f);
        if (nf < 0)
            return -1;
        if (nf > 0) {
            if (check_mode(&R, f, nf, &np, first))
                return -1;
            first = first ? first : line;
            if (modes && count == max)
                return sx_error_at(&R.doc, line, f[0].col, err, errlen, "more than %d modes", max);
            if (modes) {
                memset(&modes[count], 0, sizeof modes[count]);
                modes[count].f = f[0].v;
                modes[count].t60 = f[1].v;
                for (int p = 0; p < np; p++)
                    modes[count].gain[p] = f[2 + p].v;
            }
            count++;
        }
        if (R.pos < R.len)
            advance(&R); /* the newline */
    }
    if (npickups)
        *npickups = np;
    return count;
}

int surf_modes_read(const char *path, surf_mode *modes, int max, int *npickups, char *err, size_t errlen) {
    size_t n = 0;
    int e = 0;
    char *buf = sx_slurp(path, &n, &e);
    if (!buf) {
        if (e == ENOMEM)
            snprintf(err, errlen, "%s: error: out of memory\n", path);
        else
            snprintf(err, errlen, "%s: error: cannot read: %s\n", path, sx_file_strerror(e));
        return -1;
    }
    int r = surf_modes_parse(path, buf, n, modes, max, npickups, err, errlen);
    free(buf);
    return r;
}
