/* util.c: arena, strings, files and diagnostics. */
#include <errno.h>
#include <math.h>
#include <sys/stat.h>
#include <stdlib.h>
#include <string.h>

#include "gen.h"

Diag diag;

static void *zeroed(size_t n) {
    void *p = calloc(1, n ? n : 1);
    if (!p)
        die("out of memory (%zu bytes)", n);
    return p;
}

/* Small allocations are carved from chunks (zeroed once, by calloc, in
 * fresh pages), which saves calloc's work and header on each of the
 * millions of short strings a large network prints; a sanitizer build
 * keeps one allocation each, for its bounds. */
#if defined(__SANITIZE_ADDRESS__)
#define ARENA_CHUNKS 0
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define ARENA_CHUNKS 0
#endif
#endif
#ifndef ARENA_CHUNKS
#define ARENA_CHUNKS 1
#endif
enum { CHUNK = 1 << 20, SMALL = 1 << 10 };

void *arena_alloc(size_t n) {
    static char *next, *end;
    if (!ARENA_CHUNKS || n > SMALL)
        return zeroed(n);
    n = n ? (n + 15) & ~(size_t)15 : 16;
    if ((size_t)(end - next) < n) {
        next = zeroed(CHUNK);
        end = next + CHUNK;
    }
    void *p = next;
    next += n;
    return p;
}

char *arena_strndup(const char *s, size_t n) {
    char *p = arena_alloc(n + 1);
    memcpy(p, s, n);
    return p;
}

char *arena_strdup(const char *s) { return arena_strndup(s, strlen(s)); }

char *format(const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(NULL, 0, fmt, ap);
    va_end(ap);
    char *p = arena_alloc((size_t)n + 1);
    va_start(ap, fmt);
    vsnprintf(p, (size_t)n + 1, fmt, ap);
    va_end(ap);
    return p;
}

/* The largest file the compiler reads.  Netlists are hand-written text:
 * the largest in the repository is a few kilobytes, and a bound keeps a
 * mistaken argument (a device, a log, a sound file) from eating memory. */
#define MAX_FILE_BYTES (16u << 20)

const char *read_file_refused(int err) {
    if (err == EINVAL)
        return "is not a regular file";
    if (err == EFBIG)
        return "is larger than 16 MiB";
    return NULL;
}

bool text_nul(const char *text, size_t len, int *line, int *col) {
    if (strlen(text) == len)
        return false;
    *line = 1, *col = 1;
    for (const char *q = text; *q; q++, ++*col)
        if (*q == '\n')
            ++*line, *col = 0;
    return true;
}

/* Reads a whole regular file of at most MAX_FILE_BYTES into the arena,
 * NUL-terminated.  Returns NULL with errno set if it cannot: EINVAL for
 * anything but a regular file (a device such as /dev/zero, a FIFO, a
 * directory: none has an end worth waiting for), EFBIG for a larger file,
 * or the error of stat, fopen or fread. */
char *read_file(const char *path, size_t *len) {
    struct stat st;
    if (stat(path, &st) != 0)
        return NULL;
    if (!S_ISREG(st.st_mode)) { /* checked before fopen, which blocks on a FIFO */
        errno = EINVAL;
        return NULL;
    }
    if (st.st_size > (off_t)MAX_FILE_BYTES) {
        errno = EFBIG;
        return NULL;
    }
    FILE *f = fopen(path, "rb");
    if (!f)
        return NULL;
    /* st_size is a hint (files under /proc report 0): read to the end,
     * one byte past the limit at most, so a file that grew shows */
    size_t cap = (size_t)st.st_size + 2, n = 0;
    char *buf = malloc(cap);
    while (buf && n <= MAX_FILE_BYTES) {
        if (n + 1 >= cap) {
            cap = 2 * cap < MAX_FILE_BYTES + 2 ? 2 * cap : MAX_FILE_BYTES + 2;
            char *b = realloc(buf, cap);
            if (!b)
                die("out of memory reading %s", path);
            buf = b;
        }
        size_t k = fread(buf + n, 1, cap - n - 1, f);
        if (k == 0)
            break;
        n += k;
    }
    if (!buf)
        die("out of memory reading %s", path);
    bool bad = ferror(f);
    fclose(f);
    if (bad || n > MAX_FILE_BYTES) {
        free(buf);
        errno = bad ? EIO : EFBIG;
        return NULL;
    }
    char *p = arena_strndup(buf, n);
    free(buf);
    if (len)
        *len = n;
    return p;
}

void vec_push(Vec *v, void *p) {
    if (v->len == v->cap) {
        int cap = v->cap ? 2 * v->cap : 8;
        void **d = arena_alloc(sizeof(void *) * (size_t)cap);
        if (v->len)
            memcpy(d, v->data, sizeof(void *) * (size_t)v->len);
        v->data = d;
        v->cap = cap;
    }
    v->data[v->len++] = p;
}

static uint32_t str_hash(const char *s) {
    uint32_t h = 2166136261u; /* FNV-1a */
    for (; *s; s++)
        h = (h ^ (unsigned char)*s) * 16777619u;
    return h;
}

/* The slot that holds key, or the empty slot where it would go. */
static int map_slot(const Map *m, const char *key) {
    unsigned mask = (unsigned)m->cap - 1, i = str_hash(key) & mask;
    while (m->keys[i] && strcmp(m->keys[i], key))
        i = (i + 1) & mask;
    return (int)i;
}

int map_get(const Map *m, const char *key) {
    if (!m->cap)
        return -1;
    int i = map_slot(m, key);
    return m->keys[i] ? m->vals[i] : -1;
}

void map_put(Map *m, const char *key, int val) {
    if (2 * (m->len + 1) > m->cap) { /* at most half full */
        Map g = {.cap = m->cap ? 2 * m->cap : 16};
        g.keys = arena_alloc(sizeof(char *) * (size_t)g.cap);
        g.vals = arena_alloc(sizeof(int) * (size_t)g.cap);
        for (int i = 0; i < m->cap; i++)
            if (m->keys[i]) {
                int j = map_slot(&g, m->keys[i]);
                g.keys[j] = m->keys[i];
                g.vals[j] = m->vals[i];
            }
        g.len = m->len;
        *m = g;
    }
    int i = map_slot(m, key);
    if (!m->keys[i]) {
        m->keys[i] = key;
        m->len++;
    }
    m->vals[i] = val;
}

/* Prints "path:line:col: KIND: message", the source line and a caret. */
static void vreport(SrcPos pos, const char *kind, const char *fmt, va_list ap) {
    FILE *out = diag.out ? diag.out : stderr;
    if (!pos.file) {
        fprintf(out, "wdc: %s: ", kind);
        vfprintf(out, fmt, ap);
        fputc('\n', out);
        return;
    }
    fprintf(out, "%s:%d:%d: %s: ", pos.file->path, pos.line, pos.col, kind);
    vfprintf(out, fmt, ap);
    fputc('\n', out);
    const char *p = pos.file->text;
    for (int l = 1; l < pos.line && *p; p++)
        if (*p == '\n')
            l++;
    const char *e = p;
    while (*e && *e != '\n' && *e != '\r')
        e++;
    /* a long line is shown SHOW_LINE bytes about the column, "..." where cut */
    enum { SHOW_LINE = 100, SHOW_BEFORE = 60 };
    const char *c = p + pos.col - 1 < e ? p + pos.col - 1 : e;
    const char *a = e - p > SHOW_LINE && c - p > SHOW_BEFORE ? c - SHOW_BEFORE : p;
    const char *b = e - a > SHOW_LINE ? a + SHOW_LINE : e;
    fprintf(out, "  %s%.*s%s\n  %s", a > p ? "..." : "", (int)(b - a), a, b < e ? "..." : "", a > p ? "   " : "");
    for (const char *q = a; q < c; q++)
        fputc(*q == '\t' ? '\t' : ' ', out);
    fputs("^\n", out);
    for (SrcFile *f = pos.file; f->includer; f = f->includer)
        fprintf(out, "%s:%d:%d: note: included from here\n", f->includer->path,
                f->inc_line, f->inc_col);
}

void error_at(SrcPos pos, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    vreport(pos, "error", fmt, ap);
    va_end(ap);
    diag.errors++;
    if (diag.jmp)
        longjmp(*diag.jmp, 1);
    exit(1);
}

void error_begin(SrcPos pos, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    vreport(pos, "error", fmt, ap);
    va_end(ap);
    diag.errors++;
}

void error_end(void) {
    if (diag.jmp)
        longjmp(*diag.jmp, 1);
    exit(1);
}

void warn_at(SrcPos pos, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    vreport(pos, "warning", fmt, ap);
    va_end(ap);
    diag.warnings++;
}

void note_at(SrcPos pos, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    vreport(pos, "note", fmt, ap);
    va_end(ap);
}

void die_(const char *file, int line, const char *fmt, ...) {
    va_list ap;
    fprintf(stderr, "wdc: internal error at %s:%d: ", file, line);
    va_start(ap, fmt);
    vfprintf(stderr, fmt, ap);
    va_end(ap);
    fputc('\n', stderr);
    exit(3);
}

/* Creates a directory and its parents, like mkdir -p. */
int mkdir_p(const char *path) {
    char *p = arena_strdup(path);
    for (char *s = p + 1; *s; s++)
        if (*s == '/') {
            *s = 0;
            if (mkdir(p, 0777) != 0 && errno != EEXIST)
                return -1;
            *s = '/';
        }
    if (mkdir(p, 0777) != 0 && errno != EEXIST)
        return -1;
    return 0;
}

/* Room for n more bytes and the terminator: exactly that (a reserve),
 * or twice what is needed (growth while appending). */
static void room(Buf *b, size_t n, size_t factor) {
    if (b->len + n + 1 > b->cap) {
        size_t cap = (b->len + n + 1) * factor;
        char *s = arena_alloc(cap);
        if (b->len)
            memcpy(s, b->s, b->len);
        b->s = s;
        b->cap = cap;
    }
}

void buf_reserve(Buf *b, size_t n) { room(b, n, 1); }

void buf_put(Buf *b, const char *s, size_t n) {
    room(b, n, 2);
    memcpy(b->s + b->len, s, n);
    b->len += n;
    b->s[b->len] = 0;
}

void buf_vadd(Buf *b, const char *fmt, va_list ap) {
    /* the two formats that only copy text, copied at once: most of a
     * large voice's text passes through them */
    if (fmt[0] == '%' && fmt[1] == 's' && !fmt[2]) {
        const char *s = va_arg(ap, const char *);
        buf_put(b, s, strlen(s));
        return;
    }
    if (!strcmp(fmt, "%.*s")) {
        int n = va_arg(ap, int);
        const char *s = va_arg(ap, const char *);
        buf_put(b, s, n >= 0 ? strnlen(s, (size_t)n) : strlen(s)); /* negative: no precision */
        return;
    }
    va_list aq;
    va_copy(aq, ap);
    int n = vsnprintf(NULL, 0, fmt, aq);
    va_end(aq);
    room(b, (size_t)n, 2);
    vsnprintf(b->s + b->len, (size_t)n + 1, fmt, ap);
    b->len += (size_t)n;
}

void buf_add(Buf *b, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    buf_vadd(b, fmt, ap);
    va_end(ap);
}

/* The value of a deck source's time function at t (s), as SPICE's
 * transient reads it; step: the default rise and fall (1/rate). */
double srcfn_at(const SrcFn *f, double t, double step) {
    const double *v = f->v;
    int n = f->nv;
#define ARG(i, def) (n > (i) ? v[i] : (def))
    switch (f->kind) {
    case 's': {
        double td = ARG(3, 0), th = ARG(4, 0), ph = ARG(5, 0) * 3.14159265358979323846 / 180;
        if (t < td)
            return v[0] + v[1] * sin(ph);
        return v[0] + v[1] * exp(-(t - td) * th) * sin(2 * 3.14159265358979323846 * v[2] * (t - td) + ph);
    }
    case 'p': {
        double td = ARG(2, 0), tr = ARG(3, 0) > 0 ? v[3] : step, tf = ARG(4, 0) > 0 ? v[4] : step;
        double pw = ARG(5, INFINITY), per = ARG(6, 0) > 0 ? v[6] : INFINITY;
        if (t < td)
            return v[0];
        double u = isfinite(per) ? fmod(t - td, per) : t - td;
        if (u < tr)
            return v[0] + (v[1] - v[0]) * u / tr;
        if (u < tr + pw)
            return v[1];
        if (u < tr + pw + tf)
            return v[1] + (v[0] - v[1]) * (u - tr - pw) / tf;
        return v[0];
    }
    case 'w':
        if (t <= v[0])
            return v[1];
        for (int k = 2; k < n; k += 2)
            if (t < v[k])
                return v[k - 1] + (v[k + 1] - v[k - 1]) * (t - v[k - 2]) / (v[k] - v[k - 2]);
        return v[n - 1];
    case 'e': {
        double td1 = ARG(2, 0), tau1 = ARG(3, 0) > 0 ? v[3] : step, td2 = ARG(4, td1 + step),
               tau2 = ARG(5, 0) > 0 ? v[5] : step, y = v[0];
        if (t > td1)
            y += (v[1] - v[0]) * (1 - exp(-(t - td1) / tau1));
        if (t > td2)
            y += (v[0] - v[1]) * (1 - exp(-(t - td2) / tau2));
        return y;
    }
    default:
        return f->dc;
    }
#undef ARG
}
