/*
 * sexp.h - the S-expression reader that scenes (.wds) and timbre trees
 * (.tt) share.  Internal to libwdrt: not part of the public API.
 *
 * A document is a sequence of forms.  A form is a list `( ... )` or an
 * atom: a number (with the netlist's SI scale suffixes and unit words,
 * `48k`, `2.5meg`, `10ms`, `-3dB`), a symbol (`voice`, `+`, `f0`) or a
 * string in double quotes (`"piano.wdn"`, escapes \" \\ \n \t, on one
 * line).  `;` starts a comment that runs to the end of the line.  The
 * exact grammar is the comment at the top of sexp.c.
 *
 * Every node carries the position of its first character, so the readers
 * built on this one report their own errors with sx_error in the style of
 * the netlist compiler:
 *
 *     scene.wds:3:14: error: unknown voice 'piano'
 *       (at 0.5 (play piano (set f0 440)))
 *                     ^
 *
 * Memory: a document owns everything reachable from it (nodes, texts, a
 * copy of the source) in one arena, freed at once by sx_free.  Nothing is
 * global; documents are independent.  Parsing allocates and is not
 * real-time safe.
 */
#ifndef WDRT_SEXP_H
#define WDRT_SEXP_H

#include <stddef.h>

#if defined(__GNUC__)
#define SX_PRINTF(f, a) __attribute__((format(printf, f, a)))
#define SX_HIDDEN __attribute__((visibility("hidden")))
#else
#define SX_PRINTF(f, a)
#define SX_HIDDEN
#endif

/* Lists may nest this deep; deeper is an error, so hostile input cannot
 * overflow the reader's stack (nor the stacks of recursive readers of the
 * tree). */
#define SX_MAX_DEPTH 256

typedef enum sx_kind {
    SX_LIST, /* ( ... ) */
    SX_SYM,  /* a name */
    SX_NUM,  /* a number */
    SX_STR,  /* "a string" */
} sx_kind;

typedef struct sx {
    sx_kind kind;
    int line, col;    /* 1-based position of its first character ('(' for a list) */
    double num;       /* SX_NUM: the value, SI suffix applied */
    const char *text; /* SX_SYM: the name; SX_STR: the contents, escapes resolved;
                         SX_NUM: the token as written; SX_LIST: NULL */
    struct sx *head;  /* SX_LIST: first element, or NULL for () */
    struct sx *next;  /* next element of the enclosing list (or next top-level form) */
    int len;          /* SX_LIST: number of elements; 0 for atoms */
} sx;

typedef struct sx_doc {
    const char *path; /* as given (a copy); "<string>" if NULL was given */
    const char *src;  /* the whole text, NUL-terminated copy owned by the doc */
    size_t srclen;
    sx *forms;        /* the top-level forms, chained by next */
    int nforms;
    /* private fields after this line (arena) */
    struct sx_chunk *_chunks; /* the arena's chunks, newest first */
} sx_doc;

/* Parses text (len bytes, need not be NUL-terminated; it may hold NUL
 * bytes, which are errors).  Returns the doc, or NULL with
 * "PATH:LINE:COL: error: MESSAGE\n  <source line>\n  <caret line>\n" in err
 * (truncated to errlen; err may be NULL).  Running out of memory gives
 * "PATH: error: out of memory\n".  Allocates; not real-time safe. */
SX_HIDDEN sx_doc *sx_parse(const char *path, const char *text, size_t len, char *err,
                           size_t errlen);

/* Reads the file and parses it; a file that cannot be read gives
 * "PATH: error: cannot read: <sx_file_strerror>\n".  Allocates; not real-time safe. */
SX_HIDDEN sx_doc *sx_read_file(const char *path, char *err, size_t errlen);

/* The largest file the runtime reads as text: scenes, trees and modes
 * are hand-written, a complex's facet list may run to tens of megabytes,
 * and a bound keeps a mistaken argument from eating memory. */
#define SX_MAX_FILE ((size_t)256 << 20)

/* The whole file as a malloc'ed, NUL-terminated buffer of *len bytes
 * (free it with free()); NULL with *err = an errno value (ENOMEM when
 * memory ran out, EFBIG past SX_MAX_FILE, or sx_file_ok's) if it cannot
 * be read.  Allocates; not real-time safe. */
SX_HIDDEN char *sx_slurp(const char *path, size_t *len, int *err);

/* 0 if path names a regular file this process may read, else an errno
 * value: EISDIR for a directory, EINVAL for any other file that is not
 * regular (a device such as /dev/zero, a FIFO: none has an end worth
 * waiting for, and opening a FIFO blocks), or stat's or access's error.
 * Checked before anything opens the file. */
SX_HIDDEN int sx_file_ok(const char *path);

/* The text of such an errno value: strerror's, but for EINVAL ("not a
 * regular file") and EFBIG (the bound). */
SX_HIDDEN const char *sx_file_strerror(int e);

/* The length of a UTF-8 byte-order mark (as editors on Windows write) at
 * the start of text (len bytes): 3, or 0 where there is none.  The
 * readers skip it, and count columns after it. */
SX_HIDDEN size_t sx_bom(const char *text, size_t len);

/* Frees the doc and every node and text of it.  NULL is ignored. */
SX_HIDDEN void sx_free(sx_doc *d);

/* Formats an error at node `at` of doc d the same way into err (the
 * source line and a caret under at's column), or, if at is NULL, an error
 * about the whole file: "PATH: error: MESSAGE\n".  Returns -1 so callers
 * can `return sx_error(...)`.  Does not allocate. */
SX_HIDDEN int sx_error(const sx_doc *d, const sx *at, char *err, size_t errlen,
                       const char *fmt, ...) SX_PRINTF(5, 6);
/* A warning at node `at` in the same form ("PATH:LINE:COL: warning:
 * MESSAGE", the line and a caret), added after what err holds. */
SX_HIDDEN void sx_warning(const sx_doc *d, const sx *at, char *err, size_t errlen,
                          const char *fmt, ...) SX_PRINTF(5, 6);
/* The same at a line and column (1-based; out-of-range positions are
 * printed as given, with an empty source line past the end). */
SX_HIDDEN int sx_error_at(const sx_doc *d, int line, int col, char *err, size_t errlen,
                          const char *fmt, ...) SX_PRINTF(6, 7);

/* The edit distance (insertions, deletions, substitutions) between a and
 * b, for "did you mean" suggestions; 99 for names over 60 bytes.  Does not
 * allocate. */
SX_HIDDEN int sx_edit_distance(const char *a, const char *b);

/* x is the symbol sym (false for NULL x). */
SX_HIDDEN int sx_is(const sx *x, const char *sym);
/* The i-th element (from 0) of a list; NULL past the end, for i < 0, or
 * if list is NULL or not a list. */
SX_HIDDEN const sx *sx_nth(const sx *list, int i);
/* "list", "symbol", "number", "string": for messages such as
 * "expected a number, found a string". */
SX_HIDDEN const char *sx_kind_name(sx_kind k);

#endif
