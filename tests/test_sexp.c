/*
 * test_sexp.c - the S-expression reader of scenes and timbre trees
 * (runtime/sexp.c).
 *
 * Numbers with every scale suffix and unit, and, on random tokens, the
 * same values and the same complaints as the netlist's own reader
 * (gen/lex.c, lex_number); symbols, strings and escapes, comments; the
 * position of every node of a small scene; every error message verbatim
 * with its source line and caret; running out of memory at each
 * allocation in turn; and a seeded fuzzer that mutates realistic scenes
 * and trees (and tries random bytes): each text either parses, with every
 * node where the text has it and a re-serialisation that parses to the
 * same tree, or fails with "PATH:LINE:COL: error: " at a position inside
 * the text.
 *
 * The reader is compiled into this file (the #include of sexp.c below)
 * with allocators that count blocks and can fail on purpose.
 *
 * Environment: WDRT_FUZZ_ITERS (default 50000) and WDRT_FUZZ_SEED
 * (default 1); `make soak` runs many more iterations.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <sys/stat.h>
#include <errno.h>

#include "testlib.h"

/* ---- allocators that count and fail on demand ---- */

static long live_blocks; /* allocated, not yet freed */
static long alloc_calls; /* since the last t_fail_at */
static long fail_call = -1; /* the call that fails, or -1 */

static void t_fail_at(long n)
{
    alloc_calls = 0;
    fail_call = n;
}

static int t_should_fail(void) { return fail_call >= 0 && alloc_calls++ == fail_call; }

static void *t_malloc(size_t n)
{
    if (t_should_fail())
        return NULL;
    void *p = malloc(n);
    live_blocks += p != NULL;
    return p;
}

static void *t_realloc(void *p, size_t n)
{
    if (t_should_fail())
        return NULL;
    void *q = realloc(p, n);
    live_blocks += q && !p;
    return q;
}

static void t_free(void *p)
{
    live_blocks -= p != NULL;
    free(p);
}

#define SX_MALLOC t_malloc
#define SX_REALLOC t_realloc
#define SX_FREE t_free
#include "sexp.c"

#define PATH "t.wds"

/* gen/ frees its arena only at exit (its memory policy), so under
 * LeakSanitizer what the netlist's lex_number allocates is not a leak. */
#if defined(__SANITIZE_ADDRESS__)
#define UNDER_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define UNDER_ASAN 1
#endif
#endif
#ifdef UNDER_ASAN
#include <sanitizer/lsan_interface.h>
#define GEN_ALLOCS_BEGIN() __lsan_disable()
#define GEN_ALLOCS_END() __lsan_enable()
#else
#define GEN_ALLOCS_BEGIN() ((void)0)
#define GEN_ALLOCS_END() ((void)0)
#endif

/* ---- helpers ---- */

static sx_doc *parse_ok(const char *text)
{
    char err[1024];
    sx_doc *d = sx_parse(PATH, text, strlen(text), err, sizeof err);
    if (!d)
        fail_msg("'%s' did not parse: %s", text, err);
    return d;
}

/* The only form of text, which must be a number. */
static double number_of(const char *text)
{
    sx_doc *d = parse_ok(text);
    assert_int_equal(d->nforms, 1);
    assert_int_equal(d->forms->kind, SX_NUM);
    assert_string_equal(d->forms->text, text);
    double v = d->forms->num;
    sx_free(d);
    return v;
}

/* Parses len bytes of text, which must fail with exactly `want`. */
static void expect_error_n(const char *text, size_t len, const char *want)
{
    char err[4096];
    memset(err, 'x', sizeof err);
    sx_doc *d = sx_parse(PATH, text, len, err, sizeof err);
    if (d) {
        sx_free(d);
        fail_msg("'%s' parsed; expected %s", text, want);
    }
    assert_string_equal(err, want);
    assert_int_equal(live_blocks, 0);
}

static void expect_error(const char *text, const char *want)
{
    expect_error_n(text, strlen(text), want);
}

static void expect_node(const sx *x, sx_kind kind, int line, int col, const char *text)
{
    assert_non_null(x);
    assert_int_equal(x->kind, kind);
    assert_int_equal(x->line, line);
    assert_int_equal(x->col, col);
    if (text)
        assert_string_equal(x->text, text);
    else
        assert_null(x->text);
}

/* ---- numbers ---- */

static void numbers_with_every_suffix_and_unit(void **state)
{
    (void)state;
    static const struct {
        const char *tok;
        double v;
    } cases[] = {
        /* the value is the decimal's times the scale, as the netlist has it
           (4.7n is 4.7 * 1e-9, one ulp from the double nearest 4.7e-9) */
        {"0", 0},               {"440", 440},           {"48k", 48 * 1e3},
        {"48K", 48 * 1e3},      {"2.5meg", 2.5 * 1e6},  {"2.5MEG", 2.5 * 1e6},
        {"1Meg", 1e6},          {"10m", 10 * 1e-3},     {"1f", 1e-15},
        {"3p", 3 * 1e-12},      {"4.7n", 4.7 * 1e-9},   {"10u", 10 * 1e-6},
        {"2g", 2 * 1e9},        {"1t", 1e12},           {"1.5e3", 1.5e3},
        {"1E+3k", 1e3 * 1e3},   {"1e-3", 1e-3},         {".5", 0.5},
        {"-.5", -0.5},          {"+.5", 0.5},           {"1.", 1},
        {"1.e2", 100},          {"+7", 7},              {"-3dB", -3},
        {"2mil", 2 * 25.4e-6},  {"1MIL", 25.4e-6},      {"0e-400", 0},
        {"0.000", 0},
        {"6dB", 6},             {"-1kdB", -1e3},        {"440Hz", 440},
        {"1kHz", 1e3},          {"10ms", 10 * 1e-3},    {"2s", 2},
        {"1kg", 1},             {"5ohm", 5},            {"4.7kOhm", 4.7 * 1e3},
        {"1V", 1},              {"2A", 2},              {"3H", 3},
        {"2km", 2 * 1e3},       {"3mm", 3 * 1e-3},
        {"1e308", 1e308},
        /* SPICE's traps, kept as the netlist has them: F, N and M are scales */
        {"1F", 1e-15},          {"1N", 1e-9},           {"5MHz", 5 * 1e-3},
        {"10uF", 10 * 1e-6},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        double v = number_of(cases[i].tok);
        if (v != cases[i].v)
            fail_msg("%s: %.17g, expected %.17g", cases[i].tok, v, cases[i].v);
    }
    assert_true(fabs(number_of("10m") - 0.01) < 1e-17);
    double z = number_of("-0");
    assert_true(z == 0 && signbit(z));
}

/* Random number-like tokens: whatever the netlist accepts is accepted with
 * the same value; what it refuses is refused with the same reason, except
 * for the units only scenes have (dB, m). */
static void numbers_agree_with_the_netlist(void **state)
{
    (void)state;
    static const char alphabet[] = "0123456789..eeEE+-kKmMgGtTfFpPnNuUhHzZsSaAvVoOdDbBxXl";
    tl_rng r;
    tl_rng_seed(&r, 7);
    char tok[16], err[512], want[512];
    for (int it = 0; it < 20000; it++) {
        int n = 1 + (int)(tl_rng_next(&r) % 10);
        for (int k = 0; k < n; k++)
            tok[k] = alphabet[tl_rng_next(&r) % (sizeof alphabet - 1)];
        tok[n] = '\0';
        if (!looks_numeric(tok, (size_t)n))
            continue;
        double v1 = 0;
        const char *why = NULL;
        GEN_ALLOCS_BEGIN();
        bool ok1 = lex_number(tok, n, &v1, &why);
        GEN_ALLOCS_END();
        sx_doc *d = sx_parse(PATH, tok, (size_t)n, err, sizeof err);
        if (ok1 && (!d || memcmp(&d->forms->num, &v1, sizeof v1)))
            fail_msg("'%s': netlist %.17g, sexp %s", tok, v1, d ? "another value" : err);
        if (!ok1 && d && !(n > 2 && !strcmp(tok + n - 2, "dB")) && tok[n - 1] != 'm')
            fail_msg("'%s': the netlist refuses it (%s), sexp does not", tok, why);
        if (!ok1 && !d) {
            snprintf(want, sizeof want, PATH ":1:1: error: malformed number '%s': %s\n", tok,
                     why);
            assert_true(!strncmp(err, want, strlen(want)));
        }
        sx_free(d);
    }
}

static void numbers_ignore_the_locale(void **state)
{
    (void)state;
    static const char *const names[] = {"de_DE.UTF-8", "de_DE.utf8", "fr_FR.UTF-8",
                                        "fr_FR.utf8", "ru_RU.UTF-8"};
    const char *set = NULL;
    for (size_t i = 0; i < sizeof names / sizeof names[0] && !set; i++)
        set = setlocale(LC_NUMERIC, names[i]);
    if (!set)
        skip(); /* no locale with a decimal comma is installed */
    double v = number_of("0.5k");
    setlocale(LC_NUMERIC, "C");
    assert_true(v == 500);
}

/* ---- symbols, strings, comments ---- */

static void symbols(void **state)
{
    (void)state;
    static const char *const syms[] = {"+", "-", "...", "-x", "a.b", "set!", "<=", "f0",
                                       "C#4", "+-1", "-.x", ".", "e1", "k", "noise-hit",
                                       "a/b", "x:y", "%&^~$@?*=>_"};
    for (size_t i = 0; i < sizeof syms / sizeof syms[0]; i++) {
        sx_doc *d = parse_ok(syms[i]);
        expect_node(d->forms, SX_SYM, 1, 1, syms[i]);
        sx_free(d);
    }
}

static void strings_and_escapes(void **state)
{
    (void)state;
    sx_doc *d = parse_ok("\"\" \"a\\\"b\" \"back\\\\slash\" \"tab\\there\" \"nl\\nx\" "
                         "\"raw\ttab\" \"utf8 \xc3\xa9\" \"; no comment\" \"(no list)\"");
    static const char *const want[] = {"", "a\"b", "back\\slash", "tab\there", "nl\nx",
                                       "raw\ttab", "utf8 \xc3\xa9", "; no comment",
                                       "(no list)"};
    assert_int_equal(d->nforms, 9);
    const sx *x = d->forms;
    for (size_t i = 0; i < 9; i++, x = x->next) {
        assert_int_equal(x->kind, SX_STR);
        assert_string_equal(x->text, want[i]);
    }
    assert_null(x);
    sx_free(d);

    /* quotes are delimiters, like parentheses */
    d = parse_ok("(a\"b\"c)");
    assert_int_equal(d->forms->len, 3);
    expect_node(sx_nth(d->forms, 0), SX_SYM, 1, 2, "a");
    expect_node(sx_nth(d->forms, 1), SX_STR, 1, 3, "b");
    expect_node(sx_nth(d->forms, 2), SX_SYM, 1, 6, "c");
    sx_free(d);
}

static void comments_and_empty_texts(void **state)
{
    (void)state;
    static const char *const empty[] = {"", "   ", "; only a comment", "\n\n", "\t\r\n",
                                        ";\xc3\xa9 utf-8 in a comment\n; two\n"};
    for (size_t i = 0; i < sizeof empty / sizeof empty[0]; i++) {
        sx_doc *d = parse_ok(empty[i]);
        assert_int_equal(d->nforms, 0);
        assert_null(d->forms);
        sx_free(d);
    }
    sx_doc *d = parse_ok("a;b\n(c ; d)\n e) ; f");
    assert_int_equal(d->nforms, 2);
    expect_node(d->forms, SX_SYM, 1, 1, "a");
    const sx *l = d->forms->next;
    expect_node(l, SX_LIST, 2, 1, NULL);
    assert_int_equal(l->len, 2);
    expect_node(sx_nth(l, 1), SX_SYM, 3, 2, "e");
    sx_free(d);
    /* a UTF-8 byte-order mark at the start is skipped: columns count after it */
    d = parse_ok("\xef\xbb\xbf(a b)\r\n");
    assert_int_equal(d->nforms, 1);
    expect_node(d->forms, SX_LIST, 1, 1, NULL);
    expect_node(sx_nth(d->forms, 1), SX_SYM, 1, 4, "b");
    sx_free(d);
    expect_error("\xef\xbb\xbf(a\n", PATH ":1:3: error: expected ')' to close '(' at 1:1\n  (a\n    ^\n");
}

/* ---- structure and positions ---- */

static void nested_lists_and_positions(void **state)
{
    (void)state;
    sx_doc *d = parse_ok("; header\n"
                         "(rate 48k)\n"
                         "(voice piano \"piano.wdn\"\n"
                         "\t(pool 16))  ; sixteen\n"
                         "(at 0.5 (play piano (set f0 440)))");
    assert_int_equal(d->nforms, 3);
    const sx *f = d->forms;
    expect_node(f, SX_LIST, 2, 1, NULL);
    assert_int_equal(f->len, 2);
    expect_node(sx_nth(f, 0), SX_SYM, 2, 2, "rate");
    expect_node(sx_nth(f, 1), SX_NUM, 2, 7, "48k");
    assert_true(sx_nth(f, 1)->num == 48000);

    f = f->next;
    expect_node(f, SX_LIST, 3, 1, NULL);
    assert_int_equal(f->len, 4);
    expect_node(sx_nth(f, 0), SX_SYM, 3, 2, "voice");
    expect_node(sx_nth(f, 1), SX_SYM, 3, 8, "piano");
    expect_node(sx_nth(f, 2), SX_STR, 3, 14, "piano.wdn");
    const sx *pool = sx_nth(f, 3);
    expect_node(pool, SX_LIST, 4, 2, NULL);
    assert_int_equal(pool->len, 2);
    expect_node(sx_nth(pool, 0), SX_SYM, 4, 3, "pool");
    expect_node(sx_nth(pool, 1), SX_NUM, 4, 8, "16");

    f = f->next;
    expect_node(f, SX_LIST, 5, 1, NULL);
    assert_int_equal(f->len, 3);
    expect_node(sx_nth(f, 0), SX_SYM, 5, 2, "at");
    expect_node(sx_nth(f, 1), SX_NUM, 5, 5, "0.5");
    const sx *play = sx_nth(f, 2);
    expect_node(play, SX_LIST, 5, 9, NULL);
    assert_int_equal(play->len, 3);
    expect_node(sx_nth(play, 0), SX_SYM, 5, 10, "play");
    expect_node(sx_nth(play, 1), SX_SYM, 5, 15, "piano");
    const sx *set = sx_nth(play, 2);
    expect_node(set, SX_LIST, 5, 21, NULL);
    assert_int_equal(set->len, 3);
    expect_node(sx_nth(set, 0), SX_SYM, 5, 22, "set");
    expect_node(sx_nth(set, 1), SX_SYM, 5, 26, "f0");
    expect_node(sx_nth(set, 2), SX_NUM, 5, 29, "440");
    assert_null(f->next);
    sx_free(d);

    /* CR LF line ends; a string's escapes count as written */
    d = parse_ok("(a\r\n b)\r\n\"a\\\"b\" c");
    expect_node(sx_nth(d->forms, 1), SX_SYM, 2, 2, "b");
    expect_node(d->forms->next, SX_STR, 3, 1, "a\"b");
    expect_node(d->forms->next->next, SX_SYM, 3, 8, "c");
    sx_free(d);

    /* () and nesting to the limit */
    d = parse_ok("()");
    expect_node(d->forms, SX_LIST, 1, 1, NULL);
    assert_int_equal(d->forms->len, 0);
    assert_null(d->forms->head);
    sx_free(d);
    char deep[2 * SX_MAX_DEPTH + 1];
    memset(deep, '(', SX_MAX_DEPTH);
    memset(deep + SX_MAX_DEPTH, ')', SX_MAX_DEPTH);
    deep[2 * SX_MAX_DEPTH] = '\0';
    d = parse_ok(deep);
    const sx *x = d->forms;
    for (int i = 1; i < SX_MAX_DEPTH; i++)
        x = x->head;
    expect_node(x, SX_LIST, 1, SX_MAX_DEPTH, NULL);
    assert_null(x->head);
    sx_free(d);
}

static void helpers(void **state)
{
    (void)state;
    sx_doc *d = parse_ok("(voice 1 \"s\" ())");
    const sx *l = d->forms;
    assert_true(sx_is(sx_nth(l, 0), "voice"));
    assert_false(sx_is(sx_nth(l, 0), "voic"));
    assert_false(sx_is(sx_nth(l, 1), "1"));
    assert_false(sx_is(sx_nth(l, 2), "s"));
    assert_false(sx_is(NULL, "voice"));
    assert_null(sx_nth(l, 4));
    assert_null(sx_nth(l, -1));
    assert_null(sx_nth(sx_nth(l, 0), 0));
    assert_null(sx_nth(sx_nth(l, 3), 0));
    assert_null(sx_nth(NULL, 0));
    assert_string_equal(sx_kind_name(sx_nth(l, 0)->kind), "symbol");
    assert_string_equal(sx_kind_name(sx_nth(l, 1)->kind), "number");
    assert_string_equal(sx_kind_name(sx_nth(l, 2)->kind), "string");
    assert_string_equal(sx_kind_name(sx_nth(l, 3)->kind), "list");
    assert_string_equal(d->path, PATH);
    assert_int_equal(d->srclen, 16);
    assert_string_equal(d->src, "(voice 1 \"s\" ())");
    sx_free(d);
    sx_free(NULL);
}

/* ---- errors ---- */

static void error_parentheses(void **state)
{
    (void)state;
    expect_error("(a b))", PATH ":1:6: error: unexpected ')'\n  (a b))\n       ^\n");
    expect_error(")", PATH ":1:1: error: unexpected ')'\n  )\n  ^\n");
    expect_error("(voice piano\n  (pool 16)\n",
                 PATH ":2:12: error: expected ')' to close '(' at 1:1\n"
                      "    (pool 16)\n             ^\n");
    expect_error("(a (b ; comment\n\n", PATH ":1:6: error: expected ')' to close '(' at 1:4\n"
                                          "  (a (b ; comment\n       ^\n");
    expect_error("(", PATH ":1:2: error: expected ')' to close '(' at 1:1\n  (\n   ^\n");
    expect_error("\t(a\t))", PATH ":1:6: error: unexpected ')'\n  \t(a\t))\n  \t  \t ^\n");
    expect_error("(a)\r\n)", PATH ":2:1: error: unexpected ')'\n  )\n  ^\n");
}

static void error_nesting(void **state)
{
    (void)state;
    enum { N = 100000 }; /* deep enough to overflow a stack, were it not for the limit */
    static char text[N], err[2 * N];
    memset(text, '(', N);
    assert_null(sx_parse(PATH, text, N, err, sizeof err));
    char head[200];
    snprintf(head, sizeof head, PATH ":1:%d: error: lists nested more than %d deep\n  ",
             SX_MAX_DEPTH + 1, SX_MAX_DEPTH);
    assert_true(!strncmp(err, head, strlen(head)));
    /* of a long line, 100 bytes are shown, 60 of them before the column
     * ('(' 257), "..." where it is cut; the caret stands under the column */
    const char *src = err + strlen(head);
    assert_true(!strncmp(src, "...", 3));
    assert_int_equal(strspn(src + 3, "("), 100);
    assert_true(!strncmp(src + 103, "...\n", 4));
    const char *caret = src + 107;
    assert_int_equal(strspn(caret, " "), 2 + 3 + 60);
    assert_string_equal(caret + 2 + 3 + 60, "^\n");
    assert_int_equal(live_blocks, 0);
    /* a long line cut only after the column, and one short enough to show whole */
    char line[300];
    memset(line, 'a', sizeof line);
    memcpy(line, "(x \"", 4);
    line[sizeof line - 1] = '\n';
    assert_null(sx_parse(PATH, line, sizeof line, err, sizeof err));
    snprintf(head, sizeof head, PATH ":1:4: error: unterminated string\n  (x \"%.96s...\n     ^\n", line + 4);
    assert_string_equal(err, head);
}

static void error_strings(void **state)
{
    (void)state;
    expect_error("(voice \"piano.wdn)\n",
                 PATH ":1:8: error: unterminated string\n  (voice \"piano.wdn)\n         ^\n");
    expect_error("\"abc", PATH ":1:1: error: unterminated string\n  \"abc\n  ^\n");
    expect_error("x \"abc\\", PATH ":1:3: error: unterminated string\n  x \"abc\\\n    ^\n");
    expect_error("\"a\\\nb\"", PATH ":1:1: error: unterminated string\n  \"a\\\n  ^\n");
    expect_error("\"a\\qb\"", PATH ":1:3: error: unknown escape '\\q' in string (use \\\" "
                                "\\\\ \\n or \\t)\n  \"a\\qb\"\n    ^\n");
    expect_error("\"a\\\xc3\xa9\"",
                 PATH ":1:3: error: unknown escape: '\\' before byte 0xc3 in string (use "
                      "\\\" \\\\ \\n or \\t)\n  \"a\\\xc3\xa9\"\n    ^\n");
    expect_error("\"a\x03\"", PATH ":1:3: error: stray character 0x03\n  \"a\x03\"\n    ^\n");
}

static void error_numbers(void **state)
{
    (void)state;
    expect_error("(f 12abc3)", PATH ":1:4: error: malformed number '12abc3': unknown scale "
                               "suffix or unit 'abc3'\n  (f 12abc3)\n     ^\n");
    expect_error("1e", PATH ":1:1: error: malformed number '1e': unknown scale suffix or "
                       "unit 'e'\n  1e\n  ^\n");
    expect_error("0x10", PATH ":1:1: error: malformed number '0x10': hexadecimal numbers "
                         "are not accepted\n  0x10\n  ^\n");
    expect_error("-0X1", PATH ":1:1: error: malformed number '-0X1': hexadecimal numbers "
                         "are not accepted\n  -0X1\n  ^\n");
    expect_error("1e999", PATH ":1:1: error: malformed number '1e999': number out of "
                          "range\n  1e999\n  ^\n");
    expect_error("(x 1e303meg)", PATH ":1:4: error: malformed number '1e303meg': number out "
                                 "of range\n  (x 1e303meg)\n     ^\n");
    expect_error("1e-400", PATH ":1:1: error: malformed number '1e-400': number out of range (its "
                           "magnitude is below 2.2e-308)\n  1e-400\n  ^\n");
    expect_error("(x 1e-300f)", PATH ":1:4: error: malformed number '1e-300f': number out of range (its "
                                "magnitude is below 2.2e-308)\n  (x 1e-300f)\n     ^\n");
    expect_error("1.2.3", PATH ":1:1: error: malformed number '1.2.3': unknown scale suffix "
                          "or unit '.3'\n  1.2.3\n  ^\n");
    expect_error("440hz", PATH ":1:1: error: malformed number '440hz': unknown scale suffix "
                          "or unit 'hz'\n  440hz\n  ^\n");
    expect_error("1-2", PATH ":1:1: error: malformed number '1-2': unknown scale suffix or "
                        "unit '-2'\n  1-2\n  ^\n");
    char tok[65], want[300];
    memset(tok, '1', 64);
    tok[64] = '\0';
    snprintf(want, sizeof want,
             PATH ":1:1: error: malformed number '%s': number too long\n  %s\n  ^\n", tok,
             tok);
    expect_error(tok, want);
    tok[63] = '\0'; /* 63 digits are still a number */
    assert_true(number_of(tok) > 1e62);
}

static void error_bytes(void **state)
{
    (void)state;
    expect_error_n("(a\0)", 4, PATH ":1:3: error: stray character 0x00\n  (a\n    ^\n");
    expect_error("(a\x01" "b)", PATH ":1:3: error: stray character 0x01\n  (a\x01" "b)\n    ^\n");
    expect_error("a\x7f", PATH ":1:2: error: stray character 0x7f\n  a\x7f\n   ^\n");
    expect_error("a\vb", PATH ":1:2: error: stray character 0x0b\n  a\vb\n   ^\n");
    expect_error("x\n; a\x02\n", PATH ":2:4: error: stray character 0x02\n  ; a\x02\n     ^\n");
    expect_error("(caf\xc3\xa9)", PATH ":1:5: error: non-ASCII byte 0xc3 outside a string or "
                                  "comment\n  (caf\xc3\xa9)\n      ^\n");
    /* a byte-order mark is skipped at the start only */
    expect_error("(a)\xef\xbb\xbf", PATH ":1:4: error: non-ASCII byte 0xef outside a string "
                                    "or comment\n  (a)\xef\xbb\xbf\n     ^\n");
    expect_error("(a [b])", PATH ":1:4: error: unexpected character '['\n  (a [b])\n     ^\n");
    expect_error("'x", PATH ":1:1: error: unexpected character '''\n  'x\n  ^\n");
    expect_error("a,b", PATH ":1:2: error: unexpected character ','\n  a,b\n   ^\n");
    expect_error("1k|2", PATH ":1:3: error: unexpected character '|'\n  1k|2\n    ^\n");
    expect_error("{", PATH ":1:1: error: unexpected character '{'\n  {\n  ^\n");
    expect_error("\\n", PATH ":1:1: error: unexpected character '\\'\n  \\n\n  ^\n");
}

static void error_reporting_api(void **state)
{
    (void)state;
    char err[256];
    sx_doc *d = parse_ok("(voice piano \"p.wdn\")\n(at 1)");
    const sx *piano = sx_nth(d->forms, 1);
    assert_int_equal(sx_error(d, piano, err, sizeof err, "unknown voice '%s'", piano->text),
                     -1);
    assert_string_equal(err, PATH ":1:8: error: unknown voice 'piano'\n"
                             "  (voice piano \"p.wdn\")\n         ^\n");
    assert_int_equal(sx_error(d, NULL, err, sizeof err, "the scene has no (%s)", "rate"), -1);
    assert_string_equal(err, PATH ": error: the scene has no (rate)\n");
    assert_int_equal(sx_error_at(d, 2, 5, err, sizeof err, "expected %d", 2), -1);
    assert_string_equal(err, PATH ":2:5: error: expected 2\n  (at 1)\n      ^\n");
    sx_error_at(d, 2, 40, err, sizeof err, "past the end of the line");
    assert_string_equal(err, PATH ":2:40: error: past the end of the line\n  (at 1)\n"
                             "        ^\n");
    sx_error_at(d, 9, 3, err, sizeof err, "past the end of the text");
    assert_string_equal(err, PATH ":9:3: error: past the end of the text\n  \n  ^\n");
    sx_error_at(d, 0, 0, err, sizeof err, "nowhere");
    assert_string_equal(err, PATH ":0:0: error: nowhere\n  \n  ^\n");
    /* truncated to errlen, always terminated; err may be NULL */
    assert_int_equal(sx_error(d, piano, err, 10, "unknown voice"), -1);
    assert_string_equal(err, PATH ":1:8");
    assert_int_equal(sx_error(d, piano, NULL, 0, "unknown voice"), -1);
    err[0] = 'x';
    assert_int_equal(sx_error(d, NULL, err, 1, "x"), -1);
    assert_int_equal(err[0], '\0');
    sx_free(d);

    /* parse errors are truncated too; a NULL err is fine */
    assert_null(sx_parse(PATH, ")", 1, err, 12));
    assert_string_equal(err, PATH ":1:1: ");
    assert_null(sx_parse(PATH, ")", 1, NULL, 0));
    /* no path */
    assert_null(sx_parse(NULL, ")", 1, err, sizeof err));
    assert_string_equal(err, "<string>:1:1: error: unexpected ')'\n  )\n  ^\n");
    /* a length past what positions can hold, refused before the text is read */
    assert_null(sx_parse(PATH, "x", (size_t)INT_MAX, err, sizeof err));
    assert_string_equal(err, PATH ": error: text too large (2147483645 bytes at most)\n");
    assert_int_equal(live_blocks, 0);
}

/* ---- files ---- */

static void files(void **state)
{
    (void)state;
    char err[512];
    assert_null(sx_read_file("/nonexistent/x.wds", err, sizeof err));
    assert_string_equal(err,
                        "/nonexistent/x.wds: error: cannot read: No such file or directory\n");
    assert_null(sx_read_file("tests", err, sizeof err));
    assert_string_equal(err, "tests: error: cannot read: Is a directory\n");
    /* files that never end or block as they open are refused before it */
    assert_null(sx_read_file("/dev/zero", err, sizeof err));
    assert_string_equal(err, "/dev/zero: error: cannot read: not a regular file\n");
    char fifo[] = "/tmp/test_sexp_fifo_XXXXXX";
    int fdd = mkstemp(fifo);
    assert_true(fdd >= 0);
    close(fdd);
    unlink(fifo);
    assert_int_equal(mkfifo(fifo, 0600), 0);
    size_t flen;
    int fe = 0;
    assert_null(sx_slurp(fifo, &flen, &fe)); /* would block in fopen */
    assert_int_equal(fe, EINVAL);
    unlink(fifo);

    char path[] = "/tmp/test_sexp_XXXXXX";
    int fd = mkstemp(path);
    assert_true(fd >= 0);
    FILE *f = fdopen(fd, "w");
    assert_non_null(f);
    for (int i = 0; i < 2000; i++) /* bigger than the first read buffer */
        fprintf(f, "(at %d (strike piano (v h 3)))\n", i);
    fputs("(oops", f);
    fclose(f);
    assert_null(sx_read_file(path, err, sizeof err));
    char want[512];
    snprintf(want, sizeof want,
             "%s:2001:6: error: expected ')' to close '(' at 2001:1\n  (oops\n       ^\n",
             path);
    assert_string_equal(err, want);

    f = fopen(path, "a");
    assert_non_null(f);
    fputs(")", f);
    fclose(f);
    sx_doc *d = sx_read_file(path, err, sizeof err);
    assert_non_null(d);
    assert_int_equal(d->nforms, 2001);
    assert_string_equal(d->path, path);
    sx_free(d);

    /* out of memory while reading, at each allocation in turn */
    for (long k = 0;; k++) {
        t_fail_at(k);
        d = sx_read_file(path, err, sizeof err);
        t_fail_at(-1);
        if (d) {
            sx_free(d);
            assert_true(k > 3);
            break;
        }
        snprintf(want, sizeof want, "%s: error: out of memory\n", path);
        assert_string_equal(err, want);
        assert_int_equal(live_blocks, 0);
    }
    assert_int_equal(live_blocks, 0);
    unlink(path);
}

/* ---- out of memory ---- */

static const char scene_seed[] =
    "; a piano and a bell in a small room\n"
    "(rate 48k) (length 8) (output stereo)\n"
    "(c 343)                                   ; speed of sound, m/s\n"
    "(distance inverse (ref 1) (max 1000) (rolloff 1))\n"
    "(air on)\n"
    "(listener (pos 0 0 1.7) (facing 0 1 0))\n"
    "(room hall (box -5 -5 0 5 5 3) (t60 1.2 0.8) (reflections 2))\n"
    "(wall w1 (from -1 2) (to 1 2) (loss 6dB))\n"
    "(voice piano \"piano.wdn\" (pool 16) (pos 0 3 1) (gain -6dB) (param damp 0.2))\n"
    "(tree bell (mul (env (adsr 0.01 0.2 0.5 1)) (osc sine 440Hz))\n"
    "      (pos (path (0 -2 3 1) (8 2 3 1))))\n"
    "(body plate (modes (mode 220 1.5 0.3) (mode 548.2 0.9 0.2)) (pos 1 1 1))\n"
    "(at 0 (play piano (set f0 440) (strike (v h 3))))\n"
    "(at 0.5 (play piano (set f0 (curve (0 440) (1 880))) (strike (v h 3) (x h 1m))))\n"
    "(at 1.25 (impact plate piano (impulse 2.5m) (speed 1 0.2)))\n"
    "(at 2\t(set bell gain 0.5) (stop piano))\r\n"
    "(master (gain 0.8) (limit -1dB))\n";

static const char tree_seed[] =
    "; a bell: inharmonic partials under an envelope\n"
    "(tree bell (params (f 440) (decay 2.5))\n"
    "  (* (env (0 0) (0.01 1) (decay 0))\n"
    "     (combine (vector (sine (* f t)) (* 0.5 (sine (* 2.76 f t)))\n"
    "                      (* 0.25 (sine (* 5.4 f t)))))))\n"
    "(tree bell2 (f) (mul (env (adsr 0.01 0.2 0.5 1)) (osc sine f)))\n"
    "(tree hit (params (q 0.7)) (lowpass (* (noise) (damp (* 30 t))) 2k q))\n"
    "(tree sampled (params) (+ (sample \"hit.wav\" 48k) (delay (sample \"h\\\"i\\\\t\") 12.5ms)))\n"
    "(use bell (f 220) (decay 4))\n"
    "\"a string\\twith \\\"escapes\\\" and a \\n newline\"\n";

static const char short_seed[] =
    "(rate 48k) (voice piano \"piano.wdn\" (pool 16)) "
    "(at 0.5 (play piano (set f0 440) (strike (v h 3))))";

static void out_of_memory_at_every_allocation(void **state)
{
    (void)state;
    const char *texts[] = {scene_seed, tree_seed, short_seed, "", "x"};
    for (size_t i = 0; i < sizeof texts / sizeof texts[0]; i++) {
        char err[256];
        for (long k = 0;; k++) {
            t_fail_at(k);
            sx_doc *d = sx_parse(PATH, texts[i], strlen(texts[i]), err, sizeof err);
            t_fail_at(-1);
            if (d) {
                sx_free(d);
                break;
            }
            assert_string_equal(err, PATH ": error: out of memory\n");
            assert_int_equal(live_blocks, 0);
        }
    }
}

/* ---- fuzzing ---- */

typedef struct GrowBuf {
    char *p;
    size_t len, cap;
} GrowBuf;

static void buf_insert(GrowBuf *b, size_t at, const char *s, size_t n)
{
    if (b->len + n + 1 > b->cap) {
        while (b->len + n + 1 > b->cap)
            b->cap = b->cap ? 2 * b->cap : 1024;
        b->p = realloc(b->p, b->cap);
        assert_non_null(b->p);
    }
    memmove(b->p + at + n, b->p + at, b->len - at);
    memcpy(b->p + at, s, n);
    b->len += n;
    b->p[b->len] = '\0';
}

static void buf_delete(GrowBuf *b, size_t at, size_t n)
{
    if (at + n > b->len)
        n = b->len - at;
    memmove(b->p + at, b->p + at + n, b->len - at - n);
    b->len -= n;
    b->p[b->len] = '\0';
}

static void buf_puts(GrowBuf *b, const char *s) { buf_insert(b, b->len, s, strlen(s)); }

/* Writes the forms from x on, each list as "(a b c)", strings escaped. */
static void serialise(GrowBuf *b, const sx *x, const char *sep)
{
    for (; x; x = x->next) {
        if (x->kind == SX_LIST) {
            buf_puts(b, "(");
            serialise(b, x->head, " ");
            buf_puts(b, ")");
        } else if (x->kind == SX_STR) {
            buf_puts(b, "\"");
            for (const char *s = x->text; *s; s++)
                buf_puts(b, *s == '"'    ? "\\\""
                            : *s == '\\' ? "\\\\"
                            : *s == '\n' ? "\\n"
                                         : (char[2]){*s, 0});
            buf_puts(b, "\"");
        } else {
            buf_puts(b, x->text);
        }
        if (x->next)
            buf_puts(b, sep);
    }
}

static int same_tree(const sx *a, const sx *b)
{
    for (; a && b; a = a->next, b = b->next) {
        if (a->kind != b->kind || a->len != b->len)
            return 0;
        if (a->kind == SX_LIST ? !same_tree(a->head, b->head)
                               : strcmp(a->text, b->text) || memcmp(&a->num, &b->num, sizeof a->num))
            return 0;
    }
    return !a && !b;
}

/* The text being checked, with the start of each of its lines. */
typedef struct Text {
    const char *p;
    size_t len;
    size_t *line; /* line[i]: offset of line i+1 */
    int nlines;
} Text;

static void text_init(Text *t, const char *p, size_t len)
{
    t->p = p;
    t->len = len;
    t->nlines = 1;
    for (size_t i = 0; i < len; i++)
        t->nlines += p[i] == '\n';
    t->line = malloc(sizeof *t->line * (size_t)t->nlines);
    assert_non_null(t->line);
    int l = 0;
    t->line[l++] = 0;
    for (size_t i = 0; i < len; i++)
        if (p[i] == '\n')
            t->line[l++] = i + 1;
}

/* Bytes of line l (1-based) before its LF. */
static size_t line_len(const Text *t, int l)
{
    size_t s = t->line[l - 1], e = l < t->nlines ? t->line[l] - 1 : t->len;
    return e - s;
}

typedef struct Fuzz {
    long iter;
    const Text *t;
} Fuzz;

static void fuzz_fail(const Fuzz *z, const char *what, const char *detail)
{
    print_error("iteration %ld: %s\n%s\ninput (%zu bytes):\n", z->iter, what,
                detail ? detail : "", z->t->len);
    for (size_t i = 0; i < z->t->len && i < 4000; i++) {
        unsigned char c = (unsigned char)z->t->p[i];
        if (c == '\n' || (c >= ' ' && c < 0x7f))
            print_error("%c", c);
        else
            print_error("\\x%02x", c);
    }
    print_error("\n");
    fail();
}

/* Every node lies in the text, and the text has it there. */
static void check_positions(const Fuzz *z, const sx *x, int depth)
{
    const Text *t = z->t;
    for (; x; x = x->next) {
        if (depth > SX_MAX_DEPTH || x->line < 1 || x->line > t->nlines || x->col < 1 ||
            (size_t)x->col > line_len(t, x->line))
            fuzz_fail(z, "a node lies outside the text", x->text);
        const char *at = t->p + t->line[x->line - 1] + x->col - 1;
        size_t room = (size_t)(t->p + t->len - at);
        int ok = x->kind == SX_LIST ? *at == '(' && x->text == NULL
                 : x->kind == SX_STR ? *at == '"'
                                     : strlen(x->text) <= room && !strncmp(at, x->text, strlen(x->text));
        int n = 0;
        for (const sx *y = x->head; y; y = y->next)
            n++;
        if (!ok || n != x->len || (x->kind == SX_NUM && !isfinite(x->num)))
            fuzz_fail(z, "a node does not match the text at its position", x->text);
        if (x->kind == SX_LIST)
            check_positions(z, x->head, depth + 1);
    }
}

static void check_roundtrip(const Fuzz *z, const sx_doc *d)
{
    GrowBuf b = {0}, b2 = {0};
    buf_puts(&b, "");
    serialise(&b, d->forms, "\n");
    static char err[1 << 20];
    sx_doc *d2 = sx_parse("again", b.p, b.len, err, sizeof err);
    if (!d2)
        fuzz_fail(z, "its re-serialisation does not parse", err);
    if (d2->nforms != d->nforms || !same_tree(d->forms, d2->forms))
        fuzz_fail(z, "its re-serialisation parses to another tree", b.p);
    buf_puts(&b2, "");
    serialise(&b2, d2->forms, "\n");
    if (strcmp(b.p, b2.p))
        fuzz_fail(z, "serialising is not idempotent", b2.p);
    sx_free(d2);
    free(b.p);
    free(b2.p);
}

/* "PATH:LINE:COL: error: ..." with the position in the text (a column
 * up to just past the line's end), then the source line and the caret. */
static void check_error(const Fuzz *z, const char *err)
{
    const char *p = err + strlen(PATH);
    char *end;
    if (strncmp(err, PATH ":", strlen(PATH) + 1))
        fuzz_fail(z, "the error does not start with the path", err);
    long line = strtol(p + 1, &end, 10);
    long col = *end == ':' ? strtol(end + 1, &end, 10) : 0;
    if (strncmp(end, ": error: ", 9))
        fuzz_fail(z, "the error is not PATH:LINE:COL: error: ", err);
    if (line < 1 || line > z->t->nlines || col < 1 || (size_t)col > line_len(z->t, (int)line) + 1)
        fuzz_fail(z, "the error's position lies outside the text", err);
    int nl = 0;
    for (const char *q = err; *q; q++)
        nl += *q == '\n';
    size_t n = strlen(err);
    if (nl != 3 || n < 2 || strcmp(err + n - 2, "^\n"))
        fuzz_fail(z, "the error is not three lines ending in a caret", err);
}

/* Texts the fuzzer found readable, and texts it found wrong. */
static long n_parsed, n_refused;

static void check_text(long iter, const char *p, size_t len)
{
    static char err[1 << 20];
    Text t;
    text_init(&t, p, len);
    Fuzz z = {iter, &t};
    sx_doc *d = sx_parse(PATH, p, len, err, sizeof err);
    if (d) {
        check_positions(&z, d->forms, 1);
        check_roundtrip(&z, d);
        sx_free(d);
        n_parsed++;
    } else {
        check_error(&z, err);
        n_refused++;
    }
    if (live_blocks)
        fuzz_fail(&z, "memory was not freed", NULL);
    free(t.line);
}

static const char *const dict[] = {
    "(", ")", "()", "\"", "\\", ";", "\n", " ", "\t", "\r\n", "48k", "2.5meg", "10m", "-3dB",
    "1e", "1e999", "1e-999", "0x10", "12abc3", "1.2.3", ".5", "-.5", "-", "+", "...", "1kg",
    "\"a\\\"b\"", "\"\\q\"", "\"\\n\"", "\x01", "\x7f", "\xc3\xa9", "[", "'", "|", "{",
    "(at 1 (play p (strike (v h 3))))", "; comment\n", "(curve (0 1) (1 2))", "piano",
};

static size_t below(tl_rng *r, size_t n) { return n ? (size_t)(tl_rng_next(r) % n) : 0; }

static void mutate(GrowBuf *b, tl_rng *r)
{
    size_t at = below(r, b->len + 1);
    switch (below(r, 11)) {
    case 0: /* flip a bit */
        if (at < b->len)
            b->p[at] ^= (char)(1 << below(r, 8));
        break;
    case 1: /* replace a byte */
        if (at < b->len)
            b->p[at] = (char)below(r, 256);
        break;
    case 2: { /* insert a byte */
        char c = (char)below(r, 256);
        buf_insert(b, at, &c, 1);
        break;
    }
    case 3: /* delete a span */
        buf_delete(b, at, 1 + below(r, 24));
        break;
    case 4: { /* insert a token of the language or a bad one */
        const char *w = dict[below(r, sizeof dict / sizeof dict[0])];
        buf_insert(b, at, w, strlen(w));
        break;
    }
    case 5: /* random parentheses */
        for (size_t n = 1 + below(r, 8); n--;) {
            size_t to = below(r, b->len + 1); /* draws in a fixed order */
            buf_insert(b, to, below(r, 2) ? "(" : ")", 1);
        }
        break;
    case 6: /* delete the parenthesis nearest after at */
        while (at < b->len && b->p[at] != '(' && b->p[at] != ')')
            at++;
        buf_delete(b, at, 1);
        break;
    case 7: /* truncate */
        b->len = at;
        b->p[at] = '\0';
        break;
    case 8: { /* duplicate a span */
        size_t n = below(r, 64), s = below(r, b->len + 1);
        if (s + n > b->len)
            n = b->len - s;
        char *span = malloc(n + 1);
        assert_non_null(span);
        memcpy(span, b->p + s, n);
        buf_insert(b, at, span, n);
        free(span);
        break;
    }
    case 9: { /* a long run */
        static const char *const runs[] = {"(", ")", "((a)", "\"", "9", "a ", "\\", "; "};
        const char *w = runs[below(r, sizeof runs / sizeof runs[0])];
        for (size_t n = 200 + below(r, 2000); n--;)
            buf_insert(b, at, w, strlen(w));
        break;
    }
    case 10: /* a NUL byte */
        buf_insert(b, at, "", 1);
        break;
    }
}

/* Random bytes, mostly from the language's own characters. */
static void random_text(GrowBuf *b, tl_rng *r)
{
    static const char chars[] = "(((())))\"\\;\n \t.-+0123456789ekmMabc";
    b->len = 0;
    for (size_t n = below(r, 300); n--;) {
        char c = below(r, 4) ? chars[below(r, sizeof chars - 1)] : (char)below(r, 256);
        buf_insert(b, b->len, &c, 1);
    }
}

static long env_long(const char *name, long dflt)
{
    const char *s = getenv(name);
    return s && *s ? strtol(s, NULL, 10) : dflt;
}

static void fuzz(void **state)
{
    (void)state;
    const char *seeds[] = {scene_seed, tree_seed, short_seed};
    long iters = env_long("WDRT_FUZZ_ITERS", 50000);
    tl_rng r;
    tl_rng_seed(&r, (uint64_t)env_long("WDRT_FUZZ_SEED", 1));
    GrowBuf b = {0};
    for (size_t i = 0; i < 3; i++) /* the seeds themselves parse */
        sx_free(parse_ok(seeds[i]));
    for (long it = 0; it < iters; it++) {
        if (below(&r, 8) == 0) {
            random_text(&b, &r);
        } else {
            b.len = 0;
            const char *s = seeds[below(&r, 3)];
            buf_insert(&b, 0, s, strlen(s));
            for (size_t n = 1 + below(&r, 4); n--;)
                mutate(&b, &r);
        }
        buf_puts(&b, "");
        check_text(it, b.p, b.len);
    }
    free(b.p);
    print_message("%ld texts: %ld read, %ld refused\n", iters, n_parsed, n_refused);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(numbers_with_every_suffix_and_unit),
        cmocka_unit_test(numbers_agree_with_the_netlist),
        cmocka_unit_test(numbers_ignore_the_locale),
        cmocka_unit_test(symbols),
        cmocka_unit_test(strings_and_escapes),
        cmocka_unit_test(comments_and_empty_texts),
        cmocka_unit_test(nested_lists_and_positions),
        cmocka_unit_test(helpers),
        cmocka_unit_test(error_parentheses),
        cmocka_unit_test(error_nesting),
        cmocka_unit_test(error_strings),
        cmocka_unit_test(error_numbers),
        cmocka_unit_test(error_bytes),
        cmocka_unit_test(error_reporting_api),
        cmocka_unit_test(files),
        cmocka_unit_test(out_of_memory_at_every_allocation),
        cmocka_unit_test(fuzz),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
