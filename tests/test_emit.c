/*
 * test_emit.c - every example netlist emits a voice that is standalone,
 * portable C.
 *
 * For each netlists/ *.wdn, in double and in float precision (both with
 * --batch, so that process_batch is checked too) and in double with
 * --energy, bin/wdc writes NAME.c / NAME.h into a temporary
 * directory, and NAME.c must compile with gcc and with clang (clang is
 * skipped with a notice only if it is not installed) under -std=c99 -Wall
 * -Wextra -pedantic -Werror -O2 with exit status 0 and no compiler output
 * at all.  A voice carries only what it uses: -Wall's unused-function and
 * unused-variable checks see all of it, since its code casts nothing to
 * (void) to quiet them.  A float voice computes its samples in float:
 * gcc's -Wdouble-promotion finds no float widened unseen anywhere in it,
 * and clang's (which also sees a float passed to a double parameter) none
 * in process, process_batch or the kernels they call per sample.
 *
 * The emitted text is then read:
 *  - the code (comments and string literals removed) names no allocator,
 *    no stdio, no threads or locks and no LAPACK/BLAS symbol;
 *  - NAME.c includes only <math.h>, <string.h> and the voice's own
 *    headers ("NAME.h", "wdvoice.h"); NAME.h only "wdvoice.h";
 *  - NAME.h declares `extern const wdv_class NAME_class` and NAME.c
 *    defines it;
 *  - the state keeps no slot the code never names: each coefficient
 *    array (c_*) that the code indexes by constants only has every slot
 *    named.
 *
 * A voice must never allocate, lock or do I/O (wdvoice.h).  Rather than
 * hooking malloc while process runs, the test reads the symbol table of
 * each compiled object: `nm -u` may list only the C99 <math.h> functions
 * (any precision), memset, memcpy and memmove, plus the stack-protector
 * pair __stack_chk_fail / __stack_chk_guard that hardened compilers insert
 * on their own.  That covers process and every other entry point at once.
 * The object must also export exactly one global symbol, NAME_class, so
 * many voices can be linked into one program.
 *
 * A last test feeds the text and symbol checkers known-bad input, so they
 * are shown able to fail.
 *
 * $WDC overrides the compiler path (default bin/wdc); $WDC_KEEP=1 keeps
 * the temporary directories.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>
#include <ctype.h>
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "testlib.h"

#define STD_FLAGS "-std=c99", "-Wall", "-Wextra", "-pedantic", "-Werror", "-O2", "-c"

/* ---- processes and files ---- */

/* Runs argv (looked up in PATH) with stdout and stderr both going to the
 * file `log`; returns the exit status, 127 if it could not be started,
 * 126 if the log cannot be written, or -1. */
static int run_logged(char *const argv[], const char *log) {
    int fd = open(log, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fd < 0)
        return 126;
    int status = -1;
    wdrt_result r = wdrt_spawn(argv, fd, &status);
    close(fd);
    return r == WDRT_OK ? status : -1;
}

/* Whole contents of a file (malloc'ed, NUL-terminated), or NULL. */
static char *slurp(const char *path) {
    FILE *f = fopen(path, "rb");
    if (!f)
        return NULL;
    size_t cap = 4096, len = 0;
    char *s = malloc(cap);
    while (s) {
        size_t got = fread(s + len, 1, cap - len - 1, f);
        len += got;
        if (got == 0)
            break;
        if (len + 1 == cap) {
            char *t = realloc(s, cap * 2);
            if (!t) {
                free(s);
                s = NULL;
                break;
            }
            s = t;
            cap *= 2;
        }
    }
    fclose(f);
    if (s)
        s[len] = '\0';
    return s;
}

/* True if an executable named `prog` is on PATH. */
static int on_path(const char *prog) {
    const char *path = getenv("PATH");
    if (!path)
        return 0;
    char buf[1024];
    while (*path) {
        const char *colon = strchr(path, ':');
        size_t n = colon ? (size_t)(colon - path) : strlen(path);
        snprintf(buf, sizeof buf, "%.*s/%s", (int)n, n ? path : ".", prog);
        if (access(buf, X_OK) == 0)
            return 1;
        path += n + (colon != NULL);
    }
    return 0;
}

/* ---- text checks ---- */

/* Set while the checkers are fed known-bad input on purpose. */
static int quiet;

#define report(...) \
    do { \
        if (!quiet) \
            print_error(__VA_ARGS__); \
    } while (0)

/* A copy of C text with comments and string/char literals blanked out
 * (newlines kept, so line numbers still match). */
static char *code_only(const char *s) {
    size_t n = strlen(s);
    char *o = malloc(n + 1);
    if (!o)
        return NULL;
    size_t i = 0;
    while (i < n) {
        if (s[i] == '/' && s[i + 1] == '*') {
            o[i] = o[i + 1] = ' ';
            i += 2;
            while (i < n && !(s[i] == '*' && s[i + 1] == '/')) {
                o[i] = s[i] == '\n' ? '\n' : ' ';
                i++;
            }
            for (int k = 0; k < 2 && i < n; k++)
                o[i++] = ' ';
        } else if (s[i] == '/' && s[i + 1] == '/') {
            while (i < n && s[i] != '\n')
                o[i++] = ' ';
        } else if (s[i] == '"' || s[i] == '\'') {
            char q = s[i];
            o[i++] = q;
            while (i < n && s[i] != q && s[i] != '\n') {
                if (s[i] == '\\' && i + 1 < n) {
                    o[i++] = ' ';
                }
                o[i++] = ' ';
            }
            if (i < n)
                o[i] = s[i], i++;
        } else {
            o[i] = s[i];
            i++;
        }
    }
    o[n] = '\0';
    return o;
}

static int ci_contains(const char *s, const char *sub) {
    size_t m = strlen(sub);
    for (; *s; s++) {
        size_t k = 0;
        while (k < m && s[k] && tolower((unsigned char)s[k]) == tolower((unsigned char)sub[k]))
            k++;
        if (k == m)
            return 1;
    }
    return 0;
}

/* Why an identifier may not appear in a voice, or NULL if it may. */
static const char *forbidden_ident(const char *id) {
    static const char *const exact[] = {
        /* allocation */
        "malloc", "calloc", "realloc", "free", "aligned_alloc", "posix_memalign",
        "alloca", "valloc", "memalign", "strdup", "strndup",
        /* stdio and other I/O */
        "printf", "fprintf", "sprintf", "snprintf", "vprintf", "vfprintf",
        "vsprintf", "vsnprintf", "puts", "fputs", "putchar", "fputc", "putc",
        "fopen", "freopen", "fdopen", "fclose", "fread", "fwrite", "fflush",
        "perror", "open", "read", "write", "stdout", "stderr", "FILE",
        /* processes, dynamic loading, time */
        "exit", "abort", "system", "dlopen", "sleep", "usleep", "nanosleep",
        "clock_gettime", "time",
    };
    for (size_t k = 0; k < sizeof exact / sizeof exact[0]; k++)
        if (!strcmp(id, exact[k]))
            return exact[k];
    if (!strncmp(id, "pthread", 7))
        return "pthread";
    if (!strncmp(id, "mtx_", 4) || !strncmp(id, "cnd_", 4) || !strncmp(id, "thrd_", 5) ||
        !strncmp(id, "sem_", 4) || !strncmp(id, "atomic_", 7))
        return "threads/locks";
    if (ci_contains(id, "lapack") || ci_contains(id, "cblas") || !strncmp(id, "dgesv", 5) ||
        !strncmp(id, "dgetr", 5))
        return "LAPACK/BLAS";
    return NULL;
}

/* Checks the code of one emitted file: forbidden identifiers and
 * #include lines outside `allowed` (NULL-terminated, each written with
 * its <> or "").  Returns the number of problems, each printed with
 * `file` and its line. */
static int check_text(const char *file, const char *text, const char *const *allowed) {
    char *code = code_only(text);
    if (!code) {
        report("%s: out of memory\n", file);
        return 1;
    }
    int bad = 0, line = 1;
    const char *p = code;
    int at_line_start = 1;
    while (*p) {
        if (*p == '\n') {
            line++;
            at_line_start = 1;
            p++;
            continue;
        }
        if (at_line_start && (*p == ' ' || *p == '\t')) {
            p++;
            continue;
        }
        if (at_line_start && *p == '#') {
            const char *q = p + 1;
            while (*q == ' ' || *q == '\t')
                q++;
            if (!strncmp(q, "include", 7)) {
                /* the include's target is a literal: read it from text */
                const char *t = text + (q + 7 - code);
                while (*t == ' ' || *t == '\t')
                    t++;
                const char *e = t;
                while (*e && *e != '\n' && *e != ' ' && *e != '\t')
                    e++;
                int ok = 0;
                for (int k = 0; allowed[k]; k++)
                    if ((size_t)(e - t) == strlen(allowed[k]) && !strncmp(t, allowed[k], (size_t)(e - t)))
                        ok = 1;
                if (!ok) {
                    report("%s:%d: #include %.*s is not allowed in a voice\n", file, line,
                                (int)(e - t), t);
                    bad++;
                }
                while (*p && *p != '\n')
                    p++;
                continue;
            }
        }
        at_line_start = 0;
        if (isalpha((unsigned char)*p) || *p == '_') {
            const char *s = p;
            while (isalnum((unsigned char)*p) || *p == '_')
                p++;
            char id[128];
            size_t len = (size_t)(p - s) < sizeof id - 1 ? (size_t)(p - s) : sizeof id - 1;
            memcpy(id, s, len);
            id[len] = '\0';
            const char *why = forbidden_ident(id);
            if (why) {
                report("%s:%d: '%s' (%s) has no place in a voice\n", file, line, id, why);
                bad++;
            }
            continue;
        }
        if (isdigit((unsigned char)*p)) { /* skip numbers such as 1e-30f */
            while (isalnum((unsigned char)*p) || *p == '.' || *p == '_')
                p++;
            continue;
        }
        p++;
    }
    free(code);
    return bad;
}

/* ---- symbol checks ---- */

static int allowed_undefined(const char *sym) {
    static const char *const math[] = {
        "acos", "asin", "atan", "atan2", "cos", "sin", "tan", "acosh", "asinh", "atanh",
        "cosh", "sinh", "tanh", "exp", "exp2", "expm1", "frexp", "ldexp", "ilogb",
        "log", "log10", "log1p", "log2", "logb", "modf", "scalbn", "scalbln", "cbrt",
        "fabs", "hypot", "pow", "sqrt", "erf", "erfc", "lgamma", "tgamma", "ceil",
        "floor", "nearbyint", "rint", "lrint", "llrint", "round", "lround", "llround",
        "trunc", "fmod", "remainder", "remquo", "copysign", "nan", "nextafter",
        "nexttoward", "fdim", "fmax", "fmin", "fma",
        "sincos", /* libm's sin and cos at once: compilers merge the two calls into it */
    };
    static const char *const other[] = {
        "memset", "memcpy", "memmove", "__stack_chk_fail", "__stack_chk_guard",
    };
    for (size_t k = 0; k < sizeof other / sizeof other[0]; k++)
        if (!strcmp(sym, other[k]))
            return 1;
    for (size_t k = 0; k < sizeof math / sizeof math[0]; k++) {
        size_t m = strlen(math[k]);
        if (strncmp(sym, math[k], m))
            continue;
        /* double, float and long double variants */
        if (!sym[m] || ((sym[m] == 'f' || sym[m] == 'l') && !sym[m + 1]))
            return 1;
    }
    return 0;
}

/* Checks `nm -u` / `nm -g --defined-only` listings of one object (the
 * text nm printed).  Returns the number of problems, printed. */
static int check_symbols(const char *obj, const char *undef, const char *defs, const char *name) {
    int bad = 0;
    char line[512];
    for (const char *p = undef; *p;) {
        const char *e = strchr(p, '\n');
        size_t n = e ? (size_t)(e - p) : strlen(p);
        snprintf(line, sizeof line, "%.*s", (int)n, p);
        p += n + (e != NULL);
        /* the last word is the symbol; strip a symbol version (@GLIBC_x) */
        char *sym = strrchr(line, ' ');
        sym = sym ? sym + 1 : line;
        char *at = strchr(sym, '@');
        if (at)
            *at = '\0';
        if (!*sym)
            continue;
        if (!allowed_undefined(sym)) {
            report("%s: calls '%s', which a voice may not (only libm, memset, memcpy, memmove)\n",
                        obj, sym);
            bad++;
        }
    }
    char want[256];
    snprintf(want, sizeof want, "%s_class", name);
    int nglobal = 0, has_class = 0;
    for (const char *p = defs; *p;) {
        const char *e = strchr(p, '\n');
        size_t n = e ? (size_t)(e - p) : strlen(p);
        snprintf(line, sizeof line, "%.*s", (int)n, p);
        p += n + (e != NULL);
        char *sym = strrchr(line, ' ');
        sym = sym ? sym + 1 : line;
        if (!*sym)
            continue;
        nglobal++;
        if (!strcmp(sym, want))
            has_class = 1;
        else {
            report("%s: exports '%s'; a voice exports only %s\n", obj, sym, want);
            bad++;
        }
    }
    if (!has_class) {
        report("%s: does not define %s\n", obj, want);
        bad++;
    }
    (void)nglobal;
    return bad;
}

/* ---- one netlist ---- */

typedef struct Ctx {
    char dir[64];
    char name[128];
    char path[1024];
    int problems;
} Ctx;

static void file_in(const Ctx *x, char *buf, size_t cap, const char *suffix) {
    snprintf(buf, cap, "%s/%s%s", x->dir, x->name, suffix);
}

/* Prints a log file's contents (if any) through print_error. */
static void show_log(const char *what, const char *log) {
    char *t = slurp(log);
    if (t && *t)
        print_error("---- %s ----\n%s", what, t);
    free(t);
}

/* Compiles NAME.c with cc into NAME.<cc>.o and checks the output and the
 * object's symbols. */
static void compile_and_check(Ctx *x, const char *cc, const char *prec) {
    char csrc[1024], obj[1024], log[1024];
    file_in(x, csrc, sizeof csrc, ".c");
    snprintf(obj, sizeof obj, "%s/%s.%s.%s.o", x->dir, x->name, prec, cc);
    snprintf(log, sizeof log, "%s/%s.%s.%s.log", x->dir, x->name, prec, cc);
    char *argv[] = {(char *)cc, STD_FLAGS, csrc, "-o", obj, NULL};
    int st = run_logged(argv, log);
    char *out = slurp(log);
    int silent = out && !*out;
    if (st != 0 || !silent) {
        print_error("%s (%s): %s -std=c99 -Wall -Wextra -pedantic -Werror -O2 -c: exit status %d%s\n",
                    x->path, prec, cc, st, silent ? "" : ", with output:");
        if (out && *out)
            print_error("%s", out);
        x->problems++;
    }
    free(out);
    if (st != 0)
        return;

    char ulog[1100], dlog[1100];
    snprintf(ulog, sizeof ulog, "%s.undef", obj);
    snprintf(dlog, sizeof dlog, "%s.defs", obj);
    char *nm_u[] = {"nm", "-u", obj, NULL};
    char *nm_d[] = {"nm", "-g", "--defined-only", obj, NULL};
    int s1 = run_logged(nm_u, ulog), s2 = run_logged(nm_d, dlog);
    if (s1 != 0 || s2 != 0) {
        print_error("%s: nm failed (exit status %d, %d)\n", obj, s1, s2);
        show_log("nm -u", ulog);
        x->problems++;
        return;
    }
    char *undef = slurp(ulog), *defs = slurp(dlog);
    if (!undef || !defs) {
        print_error("%s: cannot read the nm listings\n", obj);
        x->problems++;
    } else {
        x->problems += check_symbols(obj, undef, defs, x->name);
    }
    free(undef);
    free(defs);
}

static int ident(char ch) { return isalnum((unsigned char)ch) || ch == '_'; }

/* The state holds no slot its code never names: every array of
 * coefficients (c_*) in the header that the code names only as
 * NAME[digits] has each of its slots named.  Returns the problems. */
static int check_slots(const char *file, const char *h, const char *c) {
    int problems = 0;
    for (const char *p = h; (p = strstr(p, " c_")) != NULL; p++) {
        char name[64];
        int n, len;
        if (sscanf(p + 1, "%63[A-Za-z0-9_][%d];%n", name, &n, &len) != 2 || n <= 0 || n > 100000)
            continue;
        size_t nl = strlen(name);
        char *named = calloc((size_t)n, 1);
        int plain = 1;
        for (const char *q = c; plain && (q = strstr(q, name)) != NULL; q += nl) {
            if ((q > c && ident(q[-1])) || ident(q[nl]))
                continue;
            char *end;
            long i = q[nl] == '[' && isdigit((unsigned char)q[nl + 1]) ? strtol(q + nl + 1, &end, 10) : -1;
            if (i < 0 || i >= n || *end != ']')
                plain = 0; /* named another way: a computed index, a pointer */
            else
                named[i] = 1;
        }
        for (int i = 0; plain && i < n; i++)
            if (!named[i]) {
                print_error("%s: slot %d of %s[%d] is never named: the state keeps room nothing uses\n", file, i,
                            name, n);
                problems++;
                break;
            }
        free(named);
    }
    return problems;
}

static void check_emitted_text(Ctx *x) {
    char csrc[1024], hdr[1024], wdv[1024];
    file_in(x, csrc, sizeof csrc, ".c");
    file_in(x, hdr, sizeof hdr, ".h");
    snprintf(wdv, sizeof wdv, "%s/wdvoice.h", x->dir);
    char *c = slurp(csrc), *h = slurp(hdr), *v = slurp(wdv);
    if (!c || !h || !v) {
        print_error("%s: emitted %s.c, %s.h and wdvoice.h are not all readable in %s\n", x->path,
                    x->name, x->name, x->dir);
        x->problems++;
        free(c), free(h), free(v);
        return;
    }
    char own[256];
    snprintf(own, sizeof own, "\"%s.h\"", x->name);
    const char *const c_allowed[] = {"<math.h>", "<string.h>", own, "\"wdvoice.h\"", NULL};
    const char *const h_allowed[] = {"\"wdvoice.h\"", NULL};
    const char *const v_allowed[] = {"<stddef.h>", NULL};
    x->problems += check_text(csrc, c, c_allowed);
    x->problems += check_text(hdr, h, h_allowed);
    x->problems += check_text(wdv, v, v_allowed);
    x->problems += check_slots(hdr, h, c);
    char *code = code_only(c);
    if (code && strstr(code, "(void)")) {
        print_error("%s: casts to (void): a voice carries only what it uses\n", csrc);
        x->problems++;
    }
    free(code);

    /* NAME.h declares the class, NAME.c defines it */
    char decl[256], def[256];
    snprintf(decl, sizeof decl, "extern const wdv_class %s_class;", x->name);
    snprintf(def, sizeof def, "const wdv_class %s_class =", x->name);
    char *hc = code_only(h), *cc = code_only(c);
    if (!hc || !strstr(hc, decl)) {
        print_error("%s: does not declare `%s`\n", hdr, decl);
        x->problems++;
    }
    if (!cc || !strstr(cc, def)) {
        print_error("%s: does not define `%s ...`\n", csrc, def);
        x->problems++;
    }
    free(hc);
    free(cc);
    free(c);
    free(h);
    free(v);
}

/* The functions a float voice runs every sample: process and the
 * kernels it calls. */
static const char *const per_sample[] = {
    "voice_process", "flush", "pwl_map", "diode_fast", "fast_poly", "fast_halley", "diode_newton", "diode_omega", "diode_estimate", "wright_omega",
    "diode_i", "el_solve", "el_force", "el_F", "el_mean", "cap_solve", "cap_h", "mem_g", "voice_process_batch",
    "fast_lane", "flush_lane", NULL,
};

/* The function of the voice's source whose text holds line `ln`
 * (1-based): the name before the first '(' of the nearest line above it
 * that starts in column 0 with a letter, "" if none. */
static const char *function_at(const char *src, int ln, char *name, size_t size) {
    const char *at = NULL;
    int n = 1;
    for (const char *p = src; *p && n <= ln; n++) {
        if (((*p >= 'a' && *p <= 'z') || (*p >= 'A' && *p <= 'Z') || *p == '_') && strchr(p, '('))
            at = p;
        const char *e = strchr(p, '\n');
        if (!e)
            break;
        p = e + 1;
    }
    name[0] = '\0';
    if (!at)
        return name;
    const char *paren = strchr(at, '('), *b = paren;
    while (b > at && (b[-1] == '_' || (b[-1] >= 'a' && b[-1] <= 'z') || (b[-1] >= 'A' && b[-1] <= 'Z') ||
                      (b[-1] >= '0' && b[-1] <= '9')))
        b--;
    snprintf(name, size, "%.*s", (int)(paren - b), b);
    return name;
}

/* -Wdouble-promotion on a float voice: no warning under gcc, and none
 * under clang (if on the path; it also sees a float passed to a double
 * parameter, or a float constant put in a double) in a function that runs
 * per sample. */
static void check_float_promotion(Ctx *x, const char *cc) {
    char csrc[1024], log[1024];
    file_in(x, csrc, sizeof csrc, ".c");
    snprintf(log, sizeof log, "%s/%s.promotion.%s.log", x->dir, x->name, cc);
    char *argv[] = {(char *)cc, "-std=c99", "-O2", "-Wdouble-promotion", "-c", csrc, "-o", "/dev/null", NULL};
    if (run_logged(argv, log) != 0) {
        print_error("%s: %s -Wdouble-promotion failed\n", csrc, cc);
        x->problems++;
        return;
    }
    char *out = slurp(log), *src = slurp(csrc);
    for (char *line = out && src ? strtok(out, "\n") : NULL; line; line = strtok(NULL, "\n")) {
        const char *at = strstr(line, csrc);
        int ln = 0;
        if (!strstr(line, "Wdouble-promotion") || !at || sscanf(at + strlen(csrc), ":%d:", &ln) != 1)
            continue;
        char fn[128];
        function_at(src, ln, fn, sizeof fn);
        bool each = false;
        for (int k = 0; per_sample[k]; k++)
            each = each || !strcmp(fn, per_sample[k]);
        if (each || !strcmp(cc, "gcc")) {
            print_error("%s: a float widened%s (%s, %s): %s\n", csrc, each ? " per sample" : "", fn, cc, line);
            x->problems++;
        }
    }
    free(out);
    free(src);
}

static int have_clang = -1;

/* The compiler under test: $WDC, else bin/wdc. */
static const char *wdc_path(void) {
    const char *wdc = getenv("WDC");
    return wdc && *wdc ? wdc : "bin/wdc";
}

static void test_netlist(void **state) {
    const char *netlist = *state;
    const char *wdc = wdc_path();
    static const char *const precs[] = {"double", "float", "double"};
    int problems = 0;
    quiet = 0;
    for (int pi = 0; pi < 3; pi++) {
        Ctx x = {0};
        snprintf(x.path, sizeof x.path, "%s", netlist);
        snprintf(x.dir, sizeof x.dir, "/tmp/wdc-emit-XXXXXX");
        if (!mkdtemp(x.dir))
            fail_msg("mkdtemp: %s", strerror(errno));
        char log[256];
        snprintf(log, sizeof log, "%s/wdc.log", x.dir);
        char *argv[] = {(char *)wdc, (char *)netlist, "-o", x.dir, "--precision", (char *)precs[pi],
                        pi == 2 ? "--energy" : "--batch", NULL};
        int st = run_logged(argv, log);
        if (st != 0) {
            print_error("%s %s -o %s --precision %s%s: exit status %d\n", wdc, netlist, x.dir, precs[pi],
                        pi == 2 ? " --energy" : " --batch", st);
            show_log("wdc", log);
            x.problems++;
        } else {
            unlink(log);
            if (tl_voice_name(x.dir, x.name, sizeof x.name) != 0) {
                print_error("%s: expected exactly one NAME.c in %s\n", netlist, x.dir);
                x.problems++;
            } else {
                const char *what = pi == 2 ? "energy" : precs[pi];
                check_emitted_text(&x);
                compile_and_check(&x, "gcc", what);
                if (have_clang)
                    compile_and_check(&x, "clang", what);
                if (pi == 1)
                    check_float_promotion(&x, "gcc");
                if (pi == 1 && have_clang)
                    check_float_promotion(&x, "clang");
            }
        }
        if (!x.problems)
            print_message("%-26s %-6s gcc%s: clean\n", netlist, pi == 2 ? "energy" : precs[pi],
                          have_clang ? " and clang" : "");
        problems += x.problems;
        const char *keep = getenv("WDC_KEEP");
        if (keep && *keep == '1')
            print_message("kept %s\n", x.dir);
        else
            tl_remove_dir(x.dir);
    }
    if (problems)
        fail_msg("%s: %d problem(s) in the emitted voice", netlist, problems);
}

/* The checkers themselves reject what they are meant to reject. */
static void test_checkers_can_fail(void **state) {
    (void)state;
    const char *const allowed[] = {"<math.h>", "<string.h>", "\"v.h\"", NULL};
    /* accepted: forbidden words only in comments and strings, allowed
     * includes, identifiers that merely contain a forbidden word */
    const char *good = "#include <math.h>\n#include \"v.h\"\n/* malloc free printf */\n"
                       "static const char *s = \"fopen pthread\"; // lapack\n"
                       "static double freq_free_1(double x) { return sqrt(x) * 1e-30; }\n";
    assert_int_equal(check_text("good.c", good, allowed), 0);
    static const char *const bad[] = {
        "#include <stdio.h>\n",
        "#  include <stdlib.h>\n",
        "void f(void) { void *p = malloc(4); (void)p; }\n",
        "void f(void *p) { free(p); }\n",
        "void f(void) { printf(\"x\"); }\n",
        "void f(void) { fopen(\"x\", \"r\"); }\n",
        "void f(void) { pthread_mutex_lock(0); }\n",
        "void f(void) { LAPACKE_dgesv(0); }\n",
        "void f(void) { dgesv_(0); }\n",
    };
    quiet = 1;
    for (size_t k = 0; k < sizeof bad / sizeof bad[0]; k++)
        assert_true(check_text("bad.c", bad[k], allowed) > 0);

    assert_true(allowed_undefined("sin") && allowed_undefined("sinf") && allowed_undefined("powl"));
    assert_true(allowed_undefined("memset") && allowed_undefined("fmax"));
    assert_false(allowed_undefined("malloc"));
    assert_false(allowed_undefined("sinh_") || allowed_undefined("single"));
    assert_int_equal(check_symbols("ok.o", "                 U memset\n                 U pow\n",
                                   "0000000000000000 R v_class\n", "v"),
                     0);
    assert_true(check_symbols("bad.o", "                 U malloc\n", "0000 R v_class\n", "v") > 0);
    assert_true(check_symbols("bad.o", "                 U printf@GLIBC_2.2.5\n", "0000 R v_class\n", "v") > 0);
    assert_true(check_symbols("bad.o", "", "0000 T helper\n0000 R v_class\n", "v") > 0);
    assert_true(check_symbols("bad.o", "", "0000 R w_class\n", "v") > 0);
    /* a slot nothing names is found; an array indexed by computation is left alone */
    const char *hdr = "    real c_k[3];    /* adaptor coefficients */\n    real c_M[2];\n";
    assert_int_equal(check_slots("ok.h", hdr, "x = st->c_k[0] + st->c_k[1] + st->c_k[2]; y = st->c_M[i];"), 0);
    assert_true(check_slots("bad.h", hdr, "x = st->c_k[0] + st->c_k[2]; y = st->c_M[i];") > 0);
    quiet = 0;
}

/* Lean voices: the RC lowpass's source stays under 150 lines, and work
 * accounting is in the voice only with --energy. */
static void test_lean_rc(void **state) {
    (void)state;
    const char *wdc = wdc_path();
    for (int energy = 0; energy < 2; energy++) {
        char dir[] = "/tmp/wdc-lean-XXXXXX", log[64], src[96];
        if (!mkdtemp(dir))
            fail_msg("mkdtemp: %s", strerror(errno));
        snprintf(log, sizeof log, "%s/wdc.log", dir);
        snprintf(src, sizeof src, "%s/rc_lowpass.c", dir);
        char *argv[] = {(char *)wdc, "netlists/rc_lowpass.wdn", "-o", dir, energy ? "--energy" : NULL, NULL};
        assert_int_equal(run_logged(argv, log), 0);
        char *c = slurp(src);
        assert_non_null(c);
        int lines = 0;
        for (const char *p = c; *p; p++)
            lines += *p == '\n';
        if (!energy && lines >= 150)
            fail_msg("%s: %d lines (a lean RC lowpass is under 150)", src, lines);
        assert_int_equal(strstr(c, "s_work") != NULL, energy);
        free(c);
        tl_remove_dir(dir);
    }
}

/* Wrap-free segments: in process, every line position that the loops
 * read or write is a segment's pointer (wrapfree), none is masked at each
 * frame (the flushes after a run may mask): a string with its taps, the
 * idle hammers' loop and a transmission line.  With hammers that skip,
 * the segments hold the positions the skipping loop reads and writes;
 * the full loop masks the others, the idle hammers' ports (at taps, k_wk),
 * that the skipping loop does not read. */
static void test_segments(void **state) {
    (void)state;
    static const char *const nets[][2] = {{"netlists/pluck.wdn", "pluck"},
                                          {"tests/nets/hammers_eight.wdn", "hammers_eight"},
                                          {"netlists/clipper_line.wdn", "clipper_line"}};
    for (size_t i = 0; i < sizeof nets / sizeof nets[0]; i++) {
        char dir[] = "/tmp/wdc-seg-XXXXXX", log[64], src[96];
        if (!mkdtemp(dir))
            fail_msg("mkdtemp: %s", strerror(errno));
        snprintf(log, sizeof log, "%s/wdc.log", dir);
        snprintf(src, sizeof src, "%s/%s.c", dir, nets[i][1]);
        char *argv[] = {(char *)wdc_path(), (char *)nets[i][0], "-o", dir, NULL};
        assert_int_equal(run_logged(argv, log), 0);
        char *c = slurp(src);
        assert_non_null(c);
        const char *p = strstr(c, "static void voice_process(");
        assert_non_null(p);
        const char *end = strstr(p, "\n}\n"), *fl = strstr(p, "if (t_run == FLUSH_RUN)");
        assert_non_null(end);
        if (fl && fl < end) /* the flushes after a run may mask */
            end = fl;
        /* the skipping loop, if any, and the full loop after it */
        const char *idle = strstr(p, "the contacts are open"), *full = strstr(p, "        for (; n < t_end; n++) {");
        assert_non_null(full);
        int segs = 0, masked = 0, ports = 0;
        for (const char *q = p; q < end; q++) {
            segs += !strncmp(q, "wrapfree(", 9);
            if (strncmp(q, "s_wv[", 5) && strncmp(q, "s_dl[", 5))
                continue;
            char at[128] = "";
            const char *e = strchr(q, ']');
            if (e && e - q < (long)sizeof at)
                memcpy(at, q, (size_t)(e - q)), at[e - q] = '\0';
            bool tap = strstr(at, "k_wk") != NULL;
            if (idle && idle < q && q > full && tap)
                ports++;
            else
                masked++, print_error("%s: %.60s\n", nets[i][0], q);
        }
        printf("%-30s %d positions in segments, %d masked in the loops, %d idle hammers' ports masked in the full loop\n",
               nets[i][0], segs, masked, ports);
        assert_true(segs > 0);
        assert_int_equal(masked, 0);
        assert_true(!idle == !ports); /* the ports the skipping loop does not read */
        free(c);
        tl_remove_dir(dir);
    }
}

int main(void) {
    have_clang = on_path("clang");
    if (!have_clang)
        printf("test_emit: clang is not installed; compiling with gcc only\n");
    const struct CMUnitTest fixed[] = {
        {.name = "checkers_can_fail", .test_func = test_checkers_can_fail},
        {.name = "lean_rc", .test_func = test_lean_rc},
        {.name = "segments", .test_func = test_segments},
    };
    return tl_run_per_netlist("emit", test_netlist, fixed, 3);
}
