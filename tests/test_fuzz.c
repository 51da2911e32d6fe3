/*
 * test_fuzz.c - a seeded mutation fuzzer over the netlist front end.
 *
 * Seeds are every netlists/ *.wdn and blocks/ *.wdn plus hand-written
 * netlists that use every directive and element kind.  Each iteration
 * copies a seed and applies one to four random mutations (bit flips,
 * random bytes, deletions, insertions of punctuation, digits and scale
 * letters, insertions of keywords, token duplication, line splicing,
 * joining, deletion and duplication, truncation, very long runs), then
 * loads the text with wdc_load_string (as a SPICE deck, fuzz.cir, one
 * time in three) and, when that succeeds, builds the
 * adaptor tree and checks it (wdf_build, scatter_check), as bin/wdc does.
 * About one iteration in forty writes the text to a file with NUL bytes
 * in it and goes through wdc_load instead.
 *
 * An iteration fails the test if the compiler crashes, exits (an internal
 * error), runs longer than ITER_SECONDS, or rejects the netlist without
 * printing an "error:" line of the form FILE:LINE:COL: error: ... whose
 * position lies inside the text.  Iterations run in batches in child
 * processes, so that the compiler's arena (freed only at exit) stays small
 * and a crash names the input that caused it; the child prints the input
 * and writes it to /tmp/wdc_fuzz_fail_PID.wdn.
 *
 * Environment: WDC_FUZZ_SEED (default 1), WDC_FUZZ_ITERS (default
 * 60000), WDC_FUZZ_SEEDS (a glob pattern of more seed files),
 * WDC_FUZZ_ONLY=N replays iteration N alone in this process and prints its
 * input, WDC_FUZZ_VERBOSE=1 prints every input, WDC_FUZZ_SHOW_NONFINITE=1
 * prints the accepted inputs whose adaptor tree holds a port resistance or
 * root matrix entry that is not finite (counted, not a failure).  Tests run from
 * the repository root.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>
#include <errno.h>
#include <fcntl.h>
#include <glob.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "gen.h"

#define DEFAULT_ITERS 60000
#define BATCH 500         /* iterations per child process */
#define ITER_SECONDS 5    /* one iteration longer than this is a hang */
#define MAX_FAILS 8       /* failing batches reported before giving up */
#define NAME "netlists/fuzz.wdn" /* includes resolve against netlists/ */
#define DECK "netlists/fuzz.cir" /* the same read as a SPICE deck, one iteration in three */

/* ---- random numbers (splitmix64) ---- */

typedef struct Rng {
    uint64_t s;
} Rng;

static uint64_t rng_next(Rng *r) {
    uint64_t z = (r->s += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
}

/* Uniform in [0, n); n > 0. */
static size_t rng_below(Rng *r, size_t n) { return (size_t)(rng_next(r) % n); }

/* ---- seeds ---- */

static const char *hand_seeds[] = {
    /* SPICE decks (read as such in the iterations named fuzz.cir) */
    "Vox-style tone stack, a title that reads like a source\n"
    ".param rt=220k 'cb'=22n\nV1 IN 0 DC 0 AC 1 SIN(0 1 1k 0 0 90) $ the drive\nVCC vcc 0 9\n"
    "R1 in a {rt}\nC1 a OUT 'cb*2'\nR2 out 0 1meg ; load\nRb vcc out 1meg\nRx out dangling 10k\n"
    ".model D1N914 D(IS=2.52n, N=1.752 RS=.568 CJO=4p)\nD1 out 0 d1n914\n"
    ".tran 10u 20m uic\n.ac dec 10 10 100k\n.control\nrun\n.endc\n.print tran v(OUT) v(in,out) i(r1)\n.END\n",
    "pulse and pwl\nV2 a 0 PULSE(0 5 1m 1u 1u 2m 4m)\nI1 0 b PWL(0 0 1m 1m 2m 0)\nR1 a b 1k\nC1 b 0 1u\n"
    "V3 c 0 EXP(0 1 0 1m 2m 1m)\nL1 c b 10m\n.options reltol=1e-4\n.save v(b) all\n.end\n",
    /* every directive */
    ".voice all_dirs\n.domain electrical\n.rate 44.1k\n.input in in2\n"
    ".param g 0.5 min=0 max=1 unit=V/V\n.param Rb=10k min=1k max=100k\n"
    ".model big R R=1meg\n.model DM diode Is=1e-12 n=1.8 Vt=25.85m\n"
    ".block div top mid R=1k\nR1 top mid {R}\nR2 mid 0 {R}\n.endblock\n"
    ".block pair a b\nuse div D a b R=2k\nC1 a b 1n\n.ends\n"
    ".include \"../blocks/sprung_mass.wdn\"\n"
    "V1 in 0 in R=50\nI1 0 x in2 R=1k\nuse pair P in x\nR3 x 0 {Rb*g+1}\n"
    "R4 in x model=big\nC2 x 0 10u IC=1\nL1 x 0 1m ic=0\n"
    ".output vx v(x)\n.output vd v(in,x)\n.output ir i(R3)\n.output fl x(x)\n"
    ".ic v(x)=1m x(in)=0\n.end\n",
    /* SPICE flavour: comments, continuations, suffixes */
    "* a SPICE-style deck\n.input in\nV1 1 0 in ; drive\nR1 1 2\n+ 4.7k\nC1 2 0 10uF # cap\n"
    "L1 2 3 2.2mH\nR2 3 gnd 1MEG\nR3 3 GND 1e-3\n.output out v(2)\n.end\n",
    /* every mechanical kind */
    ".voice mech\n.domain mechanical\n.input f v0\n.param k 20k min=1k max=1meg\n"
    ".model heavy mass m=40m\nforce F1 a 0 f\nvelocity U1 b 0 v0\nmass M1 a m=10m\n"
    "mass M2 c model=heavy\nspring K1 a 0 k={k}\nspring K2 a c k=5k\ndamper B1 a c c=0.2\n"
    "damper B2 b c c=1\n.output v v(a)\n.output x x(c)\n.output fk f(K1)\n.ic v(a)=1 x(c)=1m\n",
    /* elements later work implements */
    ".input in\n.model DM diode Is=1e-12 n=1.5 pair=1\nV1 a 0 in\nR1 a b 1k\nD1 b 0 DM\n"
    "T1 b 0 c 0 Z0=600 TD=1m\nnlres N1 c 0 curve=(0:0 1:1m 2:4m)\n"
    "mutator X1 c 0 d 0 type=RC\njunction J1 series a b c\n"
    "contact H1 d 0 k=4e9 alpha=2.5 lambda=0.1 gap=1m\n"
    "string S1 d 0 L=0.62 f0=261.6 t60=3 B=1e-4 taps=h@0.12,p@0.5\ntube W1 d 0 L=0.6 r=7.5m\n",
    /* pots and expressions */
    ".input in\n.param treble 0.5 min=0 max=1\n.param bass 0.5 min=0 max=1\nV1 vin 0 in\n"
    "pot P1 vin w 0 R=250k pos=treble taper=log\npot P2 w m 0 R=1meg pos={1-bass} taper=lin\n"
    "R1 m 0 {sqrt(4)*pow(10,3)*max(bass,0.1)+exp(0)-log(1)+abs(-1)+min(1,2)**2+2^3}\n"
    "C1 w 0 {1n*(1+sin(0)+cos(0)+tan(0)+log10(10)+potlin(bass)+potlog(treble))}\n"
    ".output o v(w)\n.output i i(P1.aw)\n",
    /* a bridge (rigid root) and a loop of ideal sources */
    ".input in\nV1 a 0 in\nR1 a b 1k\nR2 a c 2k\nR3 b c 3k\nR4 b 0 4k\nR5 c 0 5k\n.output o v(b,c)\n",
    ".input in in2\nV1 a 0 in\nV2 a 0 in2\nR1 a 0 1k\nI1 b 0 in\nI2 b 0 in2\n",
};

typedef struct Seeds {
    char **text;
    int n, cap;
} Seeds;

static void seeds_add(Seeds *s, char *text) {
    if (s->n == s->cap) {
        s->cap = s->cap ? 2 * s->cap : 16;
        s->text = realloc(s->text, sizeof(char *) * (size_t)s->cap);
        assert_non_null(s->text);
    }
    s->text[s->n++] = text;
}

static void seeds_glob(Seeds *s, const char *pattern) {
    glob_t g;
    if (glob(pattern, 0, NULL, &g) != 0)
        return;
    for (size_t i = 0; i < g.gl_pathc; i++) {
        FILE *f = fopen(g.gl_pathv[i], "rb");
        assert_non_null(f);
        char *buf = NULL;
        size_t len = 0;
        FILE *m = open_memstream(&buf, &len);
        int ch;
        while ((ch = fgetc(f)) != EOF)
            fputc(ch, m);
        fclose(m);
        fclose(f);
        seeds_add(s, buf);
    }
    globfree(&g);
}

static Seeds seeds_load(void) {
    Seeds s = {0};
    seeds_glob(&s, "netlists/*.wdn");
    seeds_glob(&s, "netlists/*.cir");
    seeds_glob(&s, "blocks/*.wdn");
    const char *extra = getenv("WDC_FUZZ_SEEDS");
    if (extra && *extra)
        seeds_glob(&s, extra);
    assert_true(s.n > 0); /* run from the repository root */
    for (size_t i = 0; i < sizeof hand_seeds / sizeof hand_seeds[0]; i++)
        seeds_add(&s, strdup(hand_seeds[i]));
    return s;
}

/* ---- the text being mutated ---- */

typedef struct Text {
    char *p;
    size_t len, cap;
} Text;

static void text_reserve(Text *b, size_t n) {
    if (b->len + n + 1 <= b->cap)
        return;
    while (b->len + n + 1 > b->cap)
        b->cap = b->cap ? 2 * b->cap : 1024;
    b->p = realloc(b->p, b->cap);
    assert_non_null(b->p);
}

static void buf_insert(Text *b, size_t at, const char *s, size_t n) {
    text_reserve(b, n);
    memmove(b->p + at + n, b->p + at, b->len - at);
    memcpy(b->p + at, s, n);
    b->len += n;
    b->p[b->len] = '\0';
}

static void buf_delete(Text *b, size_t at, size_t n) {
    if (at + n > b->len)
        n = b->len - at;
    memmove(b->p + at, b->p + at + n, b->len - at - n);
    b->len -= n;
    b->p[b->len] = '\0';
}

static const char charset[] = "{}()=:,.@+-*/#\"\\\n 0123456789eEkKmMuUpPn";

static const char *dict[] = {
    ".voice", ".domain", ".rate", ".input", ".param", ".model", ".include", ".block",
    ".endblock", ".ends", ".output", ".ic", ".end", "use", "pot", "mass", "spring",
    "damper", "force", "velocity", "contact", "nlres", "mutator", "junction", "string",
    "tube", "R", "C", "L", "V", "I", "D", "T", "v(", "i(", "x(", "f(", "gnd", "0", "R=",
    "C=", "L=", "m=", "k=", "c=", "pos=", "model=", "min=", "max=", "unit=", "IC=", "taper=log",
    "curve=(", "taps=", "{", "}", "(", ")", "1meg", "1e308", "1e-308", "-1", "-0", "nan", "inf",
    "0x1", "1e999", "sqrt(", "pow(", "potlog(", "min(", "**", "^", "\"", "\n+", "\n", "\n*",
    "#", ";", "=", "electrical", "mechanical", "acoustic", "diode", "series", "parallel",
    "\"../blocks/sprung_mass.wdn\"", "\"fuzz.wdn\"", "sprung_mass", "in", "a", "b", "x", "\t",
    "\r", "1k", "4.7k", "10uF", "2.2n", "1e-3", "\xc3\xa9", "\x7f",
};

static const char *lines_of(const Seeds *s, Rng *r, size_t *n) {
    const char *t = s->text[rng_below(r, (size_t)s->n)];
    size_t len = strlen(t);
    if (!len) {
        *n = 0;
        return t;
    }
    size_t at = rng_below(r, len);
    while (at > 0 && t[at - 1] != '\n')
        at--;
    size_t e = at;
    while (t[e] && t[e] != '\n')
        e++;
    *n = e - at + (t[e] == '\n');
    return t + at;
}

/* Start of the line holding position at, and the start of the next. */
static size_t line_start(const Text *b, size_t at) {
    while (at > 0 && b->p[at - 1] != '\n')
        at--;
    return at;
}

static size_t line_next(const Text *b, size_t at) {
    while (at < b->len && b->p[at] != '\n')
        at++;
    return at < b->len ? at + 1 : at;
}

static bool word_char(char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
           c == '_' || c == '.';
}

static void mutate(Text *b, const Seeds *s, Rng *r, bool allow_nul) {
    size_t at = b->len ? rng_below(r, b->len + 1) : 0;
    switch (rng_below(r, 16)) {
    case 0: /* flip one bit */
        if (at < b->len) {
            b->p[at] ^= (char)(1 << rng_below(r, 8));
            if (!b->p[at] && !allow_nul)
                b->p[at] = '\x80';
        }
        break;
    case 1: { /* a random byte */
        char c = (char)(rng_below(r, allow_nul ? 256 : 255) + !allow_nul);
        if (at < b->len)
            b->p[at] = c;
        else
            buf_insert(b, at, &c, 1);
        break;
    }
    case 2: /* delete a span */
        buf_delete(b, at, 1 + rng_below(r, 16));
        break;
    case 3: { /* insert characters of the netlist syntax */
        size_t n = 1 + rng_below(r, 8);
        for (size_t i = 0; i < n; i++)
            buf_insert(b, at, &charset[rng_below(r, sizeof charset - 1)], 1);
        break;
    }
    case 4: { /* insert a keyword or an interesting value */
        const char *w = dict[rng_below(r, sizeof dict / sizeof dict[0])];
        if (rng_below(r, 2))
            buf_insert(b, at, " ", 1);
        buf_insert(b, at, w, strlen(w));
        break;
    }
    case 5: { /* duplicate a token, next to itself or elsewhere */
        if (!b->len)
            break;
        size_t s0 = at < b->len ? at : b->len - 1, e0 = s0;
        while (s0 > 0 && word_char(b->p[s0 - 1]))
            s0--;
        while (e0 < b->len && word_char(b->p[e0]))
            e0++;
        if (e0 == s0)
            e0 = s0 + 1;
        size_t n = e0 - s0;
        char *tok = malloc(n + 1);
        assert_non_null(tok);
        memcpy(tok, b->p + s0, n);
        size_t to = rng_below(r, 2) ? e0 : rng_below(r, b->len + 1);
        buf_insert(b, to, tok, n);
        if (rng_below(r, 2))
            buf_insert(b, to, " ", 1);
        free(tok);
        break;
    }
    case 6: { /* splice in a line of some seed */
        size_t n;
        const char *l = lines_of(s, r, &n);
        size_t to = line_start(b, at);
        buf_insert(b, to, l, n);
        if (n && l[n - 1] != '\n')
            buf_insert(b, to + n, "\n", 1);
        break;
    }
    case 7: { /* splice a line's tail onto another line */
        size_t n;
        const char *l = lines_of(s, r, &n);
        size_t cut = n ? rng_below(r, n) : 0;
        buf_insert(b, at, l + cut, n - cut);
        break;
    }
    case 8: { /* join a line with the next */
        size_t e = line_next(b, at);
        if (e > 0 && b->p[e - 1] == '\n')
            buf_delete(b, e - 1, 1);
        break;
    }
    case 9: { /* delete or duplicate a whole line */
        size_t s0 = line_start(b, at), e = line_next(b, at);
        if (rng_below(r, 2)) {
            buf_delete(b, s0, e - s0);
        } else {
            char *l = malloc(e - s0 + 1);
            assert_non_null(l);
            memcpy(l, b->p + s0, e - s0);
            buf_insert(b, e, l, e - s0);
            free(l);
        }
        break;
    }
    case 10: /* truncate */
        b->len = at;
        b->p[b->len] = '\0';
        break;
    case 11: { /* a very long run of one character or one word */
        static const char *runs[] = {"9", "a", " ", "{", "(", ")", "-", "+", "\n", "\n+",
                                     "1+", "x ", "R=1 ", "(1", "a@", "\"", "k", ".", "#"};
        const char *w = runs[rng_below(r, sizeof runs / sizeof runs[0])];
        size_t n = 256 + rng_below(r, 8000), wl = strlen(w);
        char *run = malloc(n * wl);
        assert_non_null(run);
        for (size_t i = 0; i < n; i++)
            memcpy(run + i * wl, w, wl);
        buf_insert(b, at, run, n * wl);
        free(run);
        break;
    }
    case 12: /* a NUL byte (file loads only) */
        if (allow_nul)
            buf_insert(b, at, "", 1);
        break;
    case 13: { /* replace a number-like token with an extreme value */
        static const char *vals[] = {"0", "-1", "1e308", "1e-308", "1e-320", "4.9e-324",
                                     "-0", "1e300", "1t", "1f", "{0/0}", "{1/0}", "{-1/0}"};
        size_t s0 = at, e0 = at;
        while (s0 > 0 && word_char(b->p[s0 - 1]))
            s0--;
        while (e0 < b->len && word_char(b->p[e0]))
            e0++;
        buf_delete(b, s0, e0 - s0);
        const char *v = vals[rng_below(r, sizeof vals / sizeof vals[0])];
        buf_insert(b, s0, v, strlen(v));
        break;
    }
    case 14: { /* replace a word with a keyword or an interesting value */
        size_t s0 = at, e0 = at;
        while (s0 > 0 && word_char(b->p[s0 - 1]))
            s0--;
        while (e0 < b->len && word_char(b->p[e0]))
            e0++;
        buf_delete(b, s0, e0 - s0);
        const char *w = dict[rng_below(r, sizeof dict / sizeof dict[0])];
        buf_insert(b, s0, w, strlen(w));
        break;
    }
    case 15: { /* replace a word with an expression over words of the text */
        size_t s0 = at, e0 = at;
        while (s0 > 0 && word_char(b->p[s0 - 1]))
            s0--;
        while (e0 < b->len && word_char(b->p[e0]))
            e0++;
        char expr[160];
        size_t n = 0;
        expr[n++] = '{';
        int terms = 1 + (int)rng_below(r, 3);
        for (int k = 0; k < terms && n < 120; k++) {
            if (k)
                expr[n++] = "+-*/^"[rng_below(r, 5)];
            if (rng_below(r, 4) == 0)
                expr[n++] = '-';
            size_t p = b->len ? rng_below(r, b->len) : 0;
            while (p > 0 && word_char(b->p[p - 1]))
                p--;
            size_t q = p;
            while (q < b->len && word_char(b->p[q]) && q - p < 32)
                q++;
            if (q == p) {
                expr[n++] = '1';
            } else {
                memcpy(expr + n, b->p + p, q - p);
                n += q - p;
            }
        }
        expr[n++] = '}';
        buf_delete(b, s0, e0 - s0);
        buf_insert(b, s0, expr, n);
        break;
    }
    }
}

/* ---- checking one input ---- */

/* The state a crash handler reports. */
static const char *cur_text;
static size_t cur_len;
static long cur_iter = -1;
static char fail_path[64];

static void write_all(int fd, const char *s, size_t n) {
    while (n > 0) {
        ssize_t k = write(fd, s, n);
        if (k <= 0)
            return;
        s += k;
        n -= (size_t)k;
    }
}

static void write_str(int fd, const char *s) { write_all(fd, s, strlen(s)); }

static int open_fail_file(void) { return open(fail_path, O_WRONLY | O_CREAT | O_TRUNC, 0644); }

/* Async-signal-safe: prints the iteration and its input, saves the input. */
static void report_current(const char *what) {
    char num[32];
    int k = sizeof num;
    long v = cur_iter < 0 ? 0 : cur_iter;
    num[--k] = '\0';
    do
        num[--k] = (char)('0' + v % 10);
    while ((v /= 10) > 0 && k > 0);
    write_str(2, "\nfuzz: ");
    write_str(2, what);
    write_str(2, " at iteration ");
    write_str(2, num + k);
    write_str(2, "; input saved in ");
    write_str(2, fail_path);
    write_str(2, ":\n-----\n");
    if (cur_text)
        write_all(2, cur_text, cur_len > 4000 ? 4000 : cur_len);
    write_str(2, cur_len > 4000 ? "\n[... truncated]\n-----\n" : "\n-----\n");
    int fd = open_fail_file();
    if (fd >= 0 && cur_text) {
        write_all(fd, cur_text, cur_len);
        close(fd);
    }
}

static void on_signal(int sig) {
    report_current(sig == SIGALRM ? "hang (iteration ran too long)"
                   : sig == SIGSEGV ? "crash (SIGSEGV)"
                   : sig == SIGBUS ? "crash (SIGBUS)"
                   : sig == SIGFPE ? "crash (SIGFPE)"
                   : sig == SIGILL ? "crash (SIGILL)" : "crash (SIGABRT)");
    if (sig == SIGALRM)
        _exit(124);
    signal(sig, SIG_DFL);
    raise(sig);
}

static void on_exit_inside(void) {
    if (cur_iter >= 0)
        report_current("exit() from inside the compiler (an internal error)");
}

/* With -fsanitize, the sanitizer's report is followed by this. */
extern void __sanitizer_set_death_callback(void (*cb)(void)) __attribute__((weak));

static void on_sanitizer_death(void) { report_current("sanitizer error"); }

typedef struct Stats {
    long iters, accepted, rejected_load, rejected_build, nul_files;
    long bad;       /* rejected without a well-formed error line */
    long nonfinite; /* accepted with a port resistance or root matrix entry
                       that is not finite (counted, not a failure) */
} Stats;

/* True if every port resistance is positive and finite and the root
 * matrix is finite. */
static bool wdf_finite(const Wdf *w) {
    for (int i = 0; i < w->nnodes; i++)
        if (!(w->nodes[i]->R > 0) || !isfinite(w->nodes[i]->R))
            return false;
    for (int b = 0; b < w->nroots; b++)
        for (int i = 0; i < w->roots[b].nedge * w->roots[b].nedge; i++)
            if (!isfinite(w->roots[b].M[i]))
                return false;
    return true;
}

/* Checks that out holds an error line with a position inside text (when
 * the error is in the file `name` itself); returns a complaint or NULL. */
static const char *check_error_text(const char *out, const char *name, const char *text,
                                    size_t len) {
    const char *e = strstr(out, ": error: ");
    if (!e)
        return "rejected without an error: line";
    const char *ls = e;
    while (ls > out && ls[-1] != '\n')
        ls--;
    if (!strncmp(ls, "wdc: error: ", 12))
        return NULL;
    size_t nl = strlen(name);
    if (strncmp(ls, name, nl) || ls[nl] != ':')
        return NULL; /* in an included file */
    long line, col;
    char colon;
    if (sscanf(ls + nl, ":%ld:%ld%c", &line, &col, &colon) != 3 || colon != ':')
        return "error line without FILE:LINE:COL";
    /* find the line in the text */
    long l = 1;
    size_t p = 0;
    while (l < line && p < len) {
        if (text[p] == '\n')
            l++;
        p++;
    }
    if (line < 1 || l != line)
        return "error line number outside the file";
    size_t q = p;
    while (q < len && text[q] != '\n')
        q++;
    if (col < 1 || (size_t)col > q - p + 1)
        return "error column outside its line";
    return NULL;
}

/* Runs one input; returns a complaint or NULL. */
static const char *run_one(const char *text, size_t len, bool as_file, bool deck, Stats *st, char **out) {
    static char path[64];
    const char *name = deck ? DECK : NAME;
    if (as_file) {
        snprintf(path, sizeof path, "/tmp/wdc_fuzz_%ld.wdn", (long)getpid());
        FILE *f = fopen(path, "wb");
        if (!f || fwrite(text, 1, len, f) != len || fclose(f))
            fail_msg("cannot write %s", path);
        st->nul_files++;
    }
    size_t outlen;
    FILE *saved = diag.out;
    diag.out = open_memstream(out, &outlen);
    Circuit *c = as_file ? wdc_load(path) : wdc_load_string(name, text);
    const char *bad = NULL;
    if (!c) {
        st->rejected_load++;
        fflush(diag.out);
        bad = check_error_text(*out, as_file ? path : name, text, len);
    } else {
        jmp_buf jb;
        jmp_buf *prev = diag.jmp;
        diag.jmp = &jb;
        if (!setjmp(jb)) {
            Wdf *w = wdf_build(c, c->rate);
            scatter_check(w, 1e-9);
            st->accepted++;
            if (!wdf_finite(w)) {
                st->nonfinite++;
                if (getenv("WDC_FUZZ_SHOW_NONFINITE"))
                    report_current("accepted with a non-finite port resistance or root matrix");
            }
        } else {
            st->rejected_build++;
            fflush(diag.out);
            bad = check_error_text(*out, as_file ? path : name, text, len);
        }
        diag.jmp = prev;
    }
    fclose(diag.out);
    diag.out = saved;
    if (bad)
        st->bad++;
    return bad;
}

/* Builds the input of iteration i (reproducible from seed and i alone). */
static void make_input(const Seeds *s, uint64_t seed, long i, Text *b, bool *as_file) {
    Rng r = {seed * 0x2545f4914f6cdd1dull ^ (uint64_t)i * 0x9e3779b97f4a7c15ull};
    rng_next(&r);
    *as_file = rng_below(&r, 40) == 0;
    const char *t = s->text[rng_below(&r, (size_t)s->n)];
    b->len = 0;
    buf_insert(b, 0, t, strlen(t));
    int n = 1 + (int)rng_below(&r, 4);
    for (int k = 0; k < n; k++)
        mutate(b, s, &r, *as_file);
    if (*as_file && !memchr(b->p, '\0', b->len))
        buf_insert(b, rng_below(&r, b->len + 1), "", 1);
}

/* Under a sanitizer, whose reports may end the process without running
 * any handler of ours, every input is saved before it runs. */
static bool save_each;

static void run_range(const Seeds *s, uint64_t seed, long from, long to, Stats *st, bool verbose) {
    Text b = {0};
    for (long i = from; i < to; i++) {
        bool as_file;
        cur_iter = i;
        cur_text = NULL;
        make_input(s, seed, i, &b, &as_file);
        cur_text = b.p;
        cur_len = b.len;
        if (save_each) {
            int fd = open_fail_file();
            if (fd >= 0) {
                write_all(fd, b.p, b.len);
                close(fd);
            }
        }
        if (verbose) {
            fprintf(stderr, "== iteration %ld%s\n", i, as_file ? " (file with NUL)" : "");
            fwrite(b.p, 1, b.len, stderr);
            fputc('\n', stderr);
        }
        char *out = NULL;
        alarm(ITER_SECONDS);
        const char *bad = run_one(b.p, b.len, as_file, i % 3 == 1, st, &out);
        alarm(0);
        if (verbose)
            fputs(out, stderr);
        if (bad) {
            report_current(bad);
            fprintf(stderr, "printed:\n%s-----\n", out);
        }
        free(out);
        st->iters++;
        cur_iter = -1;
    }
    free(b.p);
}

static void install_handlers(void) {
    int sigs[] = {SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT, SIGALRM};
    bool sanitized = __sanitizer_set_death_callback != NULL;
    if (sanitized)
        __sanitizer_set_death_callback(on_sanitizer_death);
    save_each = sanitized;
    for (size_t k = 0; k < sizeof sigs / sizeof sigs[0]; k++)
        if (!sanitized || sigs[k] == SIGALRM)
            signal(sigs[k], on_signal);
    atexit(on_exit_inside);
}

static long env_long(const char *name, long def) {
    const char *v = getenv(name);
    return v && *v ? strtol(v, NULL, 0) : def;
}

static void test_fuzz_parser(void **state) {
    (void)state;
    Seeds s = seeds_load();
    uint64_t seed = (uint64_t)env_long("WDC_FUZZ_SEED", 1);
    long iters = env_long("WDC_FUZZ_ITERS", DEFAULT_ITERS);
    long only = env_long("WDC_FUZZ_ONLY", -1);
    bool verbose = env_long("WDC_FUZZ_VERBOSE", 0) != 0;
    snprintf(fail_path, sizeof fail_path, "/tmp/wdc_fuzz_fail_%ld.wdn", (long)getpid());
    if (only >= 0) { /* replay one iteration here */
        Stats st = {0};
        install_handlers();
        run_range(&s, seed, only, only + 1, &st, true);
        char tmp[64];
        snprintf(tmp, sizeof tmp, "/tmp/wdc_fuzz_%ld.wdn", (long)getpid());
        unlink(tmp);
        assert_int_equal(st.bad, 0);
        return;
    }
    struct timespec t0, t1;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    Stats total = {0};
    int nfail = 0;
    char fails[MAX_FAILS][160];
    for (long from = 0; from < iters && nfail < MAX_FAILS; from += BATCH) {
        long to = from + BATCH < iters ? from + BATCH : iters;
        int pfd[2];
        assert_int_equal(pipe(pfd), 0);
        fflush(NULL);
        pid_t pid = fork();
        assert_true(pid >= 0);
        if (pid == 0) {
            close(pfd[0]);
            snprintf(fail_path, sizeof fail_path, "/tmp/wdc_fuzz_fail_%ld.wdn", (long)getpid());
            install_handlers();
            Stats st = {0};
            run_range(&s, seed, from, to, &st, verbose);
            write_all(pfd[1], (const char *)&st, sizeof st);
            if (!st.bad)
                unlink(fail_path);
            char tmp[64];
            snprintf(tmp, sizeof tmp, "/tmp/wdc_fuzz_%ld.wdn", (long)getpid());
            unlink(tmp);
            _exit(st.bad ? 1 : 0);
        }
        close(pfd[1]);
        Stats st = {0};
        ssize_t got = read(pfd[0], &st, sizeof st);
        close(pfd[0]);
        int status;
        while (waitpid(pid, &status, 0) < 0 && errno == EINTR)
            ;
        if (got == (ssize_t)sizeof st) {
            total.iters += st.iters;
            total.accepted += st.accepted;
            total.rejected_load += st.rejected_load;
            total.rejected_build += st.rejected_build;
            total.nul_files += st.nul_files;
            total.bad += st.bad;
            total.nonfinite += st.nonfinite;
        }
        if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
            snprintf(fails[nfail++], sizeof fails[0],
                     "iterations %ld..%ld: %s %d, input in /tmp/wdc_fuzz_fail_%ld.wdn", from, to - 1,
                     WIFSIGNALED(status) ? "killed by signal" : "exit status",
                     WIFSIGNALED(status) ? WTERMSIG(status) : WEXITSTATUS(status), (long)pid);
        }
    }
    clock_gettime(CLOCK_MONOTONIC, &t1);
    double secs = (double)(t1.tv_sec - t0.tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0.tv_nsec);
    print_message("fuzz: seed %llu, %ld iterations in %.1f s from %d seeds: %ld accepted and "
                  "built, %ld rejected by wdc_load, %ld by wdf_build, %ld files with NUL bytes\n",
                  (unsigned long long)seed, total.iters, secs, s.n, total.accepted,
                  total.rejected_load, total.rejected_build, total.nul_files);
    if (total.nonfinite)
        print_message("fuzz: %ld accepted netlists have a port resistance or root matrix entry "
                      "that is not finite (WDC_FUZZ_SHOW_NONFINITE=1 prints them)\n",
                      total.nonfinite);
    for (int i = 0; i < nfail; i++)
        print_error("fuzz: %s (replay one with WDC_FUZZ_SEED=%llu WDC_FUZZ_ONLY=N)\n", fails[i],
                    (unsigned long long)seed);
    for (int i = 0; i < s.n; i++)
        free(s.text[i]);
    free(s.text);
    assert_int_equal(nfail, 0);
    assert_true(total.iters >= iters);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_fuzz_parser),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
