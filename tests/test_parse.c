/*
 * test_parse.c - diagnostics of the netlist front end (lexer, parser and
 * elaboration), and the netlists it must accept.
 *
 * Every user error is one small netlist given to wdc_load_string (or to
 * wdc_load, for includes) with the diagnostics captured in memory; the
 * load must fail and the first line printed must be exactly
 * "t.wdn:LINE:COL: error: MESSAGE", the position pointing at the token
 * at fault.  Errors found after elaboration (ideal sources in a loop) and
 * the exit status of bin/wdc are checked by running bin/wdc ($WDC
 * overrides the path) on temporary files.  Tests run from the repository
 * root.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>
#include <glob.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "gen.h"

/* ---- helpers ---- */

typedef struct Capture {
    char *buf;
    size_t len;
    FILE *saved;
} Capture;

static void capture_begin(Capture *c) {
    c->buf = NULL;
    c->len = 0;
    c->saved = diag.out;
    diag.out = open_memstream(&c->buf, &c->len);
    assert_non_null(diag.out);
}

/* Restores diag.out; returns the captured text (free it). */
static char *capture_end(Capture *c) {
    fclose(diag.out);
    diag.out = c->saved;
    return c->buf;
}

/* First line of s, as a new string. */
static char *first_line(const char *s) {
    size_t n = strcspn(s, "\n");
    char *r = malloc(n + 1);
    assert_non_null(r);
    memcpy(r, s, n);
    r[n] = '\0';
    return r;
}

/* Loads text as "t.wdn", which must fail; returns everything printed. */
static char *load_fails(const char *text) {
    Capture cap;
    capture_begin(&cap);
    Circuit *c = wdc_load_string("t.wdn", text);
    char *out = capture_end(&cap);
    if (c)
        fail_msg("netlist accepted, expected an error:\n%s", text);
    return out;
}

/* The first line printed for text must be exactly `want`. */
static void expect_error(const char *text, const char *want) {
    char *out = load_fails(text);
    char *got = first_line(out);
    if (strcmp(got, want))
        fail_msg("netlist:\n%s\nexpected: %s\n     got: %s", text, want, got);
    free(got);
    free(out);
}

/* Loads text as "t.wdn", which must succeed silently. */
static Circuit *load_ok(const char *name, const char *text) {
    Capture cap;
    capture_begin(&cap);
    Circuit *c = wdc_load_string(name, text);
    char *out = capture_end(&cap);
    if (!c || out[0])
        fail_msg("netlist rejected or warned:\n%s\n--- printed:\n%s", text, out);
    free(out);
    return c;
}

static const Elem *elem_named(const Circuit *c, const char *name) {
    for (int i = 0; i < c->nelems; i++)
        if (!strcmp(c->elems[i].name, name))
            return &c->elems[i];
    fail_msg("no element '%s'", name);
    return NULL;
}

/* Value of element `name` at the default params, checked against want
 * to a relative 1e-12. */
static void check_value(const Circuit *c, const char *name, double want) {
    double got = elem_value(c, elem_named(c, name), circuit_defaults(c));
    if (!(fabs(got - want) <= 1e-12 * fabs(want)))
        fail_msg("%s = %.17g, expected %.17g", name, got, want);
}

static int node_named(const Circuit *c, const char *name) {
    for (int i = 0; i < c->nnodes; i++)
        if (!strcmp(c->nodes[i], name))
            return i;
    fail_msg("no node '%s'", name);
    return -1;
}

static char tmpdir[64];

static int make_tmpdir(void **state) {
    (void)state;
    strcpy(tmpdir, "/tmp/wdc_parse.XXXXXX");
    return mkdtemp(tmpdir) ? 0 : -1;
}

static int remove_tmpdir(void **state) {
    (void)state;
    char cmd[128];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmpdir);
    return system(cmd) == 0 ? 0 : -1;
}

/* Writes text to tmpdir/name; returns the path (static buffer). */
static const char *write_tmp(const char *name, const char *text) {
    static char path[256];
    snprintf(path, sizeof path, "%s/%s", tmpdir, name);
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs(text, f);
    assert_int_equal(fclose(f), 0);
    return path;
}

static const char *wdc_path(void) {
    const char *p = getenv("WDC");
    return p && *p ? p : "bin/wdc";
}

/* Runs bin/wdc with args (a shell fragment); returns its exit status and
 * puts what it printed on stderr and stdout into *out (free it). */
static int run_wdc(const char *args, char **out) {
    char cmd[1024];
    snprintf(cmd, sizeof cmd, "%s %s 2>&1", wdc_path(), args);
    FILE *p = popen(cmd, "r");
    assert_non_null(p);
    size_t cap = 4096, n = 0;
    char *buf = malloc(cap);
    assert_non_null(buf);
    size_t k;
    while ((k = fread(buf + n, 1, cap - n - 1, p)) > 0) {
        n += k;
        if (n + 1 == cap) {
            cap *= 2;
            buf = realloc(buf, cap);
            assert_non_null(buf);
        }
    }
    buf[n] = '\0';
    int st = pclose(p);
    *out = buf;
    assert_true(WIFEXITED(st));
    return WEXITSTATUS(st);
}

#define SRC "V1 a 0 in\n" /* an ideal source driving node a */

/* ---- lexical errors ---- */

static void test_unknown_kind(void **state) {
    (void)state;
    expect_error(".input in\n" SRC "Y1 a b 1k\n",
                 "t.wdn:3:1: error: unknown element kind 'Y1'");
    expect_error(".input in\n" SRC "  frob F1 a 0\n",
                 "t.wdn:3:3: error: unknown element kind 'frob'");
    expect_error(".input in\n" SRC "R1 a 0 1k\n+ C2 a 0 1u\n",
                 "t.wdn:4:3: error: too many nodes or values for resistor 'R1': unexpected 'C2'");
    expect_error("+ R1 a 0 1k\n",
                 "t.wdn:1:1: error: expected an element or a directive, found '+'");
}

static void test_unknown_directive(void **state) {
    (void)state;
    expect_error(".input in\n.foo bar\n" SRC, "t.wdn:2:1: error: unknown directive '.foo'");
    expect_error(".subckt x a b\n", "t.wdn:1:1: error: unknown directive '.subckt'");
}

static void test_malformed_numbers(void **state) {
    (void)state;
    expect_error(".input in\n" SRC "R1 a 0 4.7q\n",
                 "t.wdn:3:8: error: malformed number '4.7q': unknown scale suffix or unit 'q'");
    expect_error(".input in\n" SRC "R1 a 0 1e\n",
                 "t.wdn:3:8: error: malformed number '1e': unknown scale suffix or unit 'e'");
    expect_error(".input in\n" SRC "R1 a 0 {10x}\n",
                 "t.wdn:3:9: error: malformed number '10x': unknown scale suffix or unit 'x'");
    expect_error(".input in\n" SRC "R1 a 0 {2*1e}\n",
                 "t.wdn:3:11: error: malformed number '1e': unknown scale suffix or unit 'e'");
    expect_error(".input in\n" SRC "R1 a 0 R=3kk\n",
                 "t.wdn:3:10: error: malformed number '3kk': unknown scale suffix or unit 'k'");
    expect_error(".input in\n" SRC "R1 a 0 0x10\n",
                 "t.wdn:3:8: error: malformed number '0x10': hexadecimal numbers are not accepted");
    expect_error(".input in\n" SRC "R1 a 0 1e999\n",
                 "t.wdn:3:8: error: malformed number '1e999': number out of range");
    expect_error(".input in\n" SRC "R1 a 0 1e-400\n",
                 "t.wdn:3:8: error: malformed number '1e-400': number out of range (its magnitude is below 2.2e-308)");
    expect_error(".input in\n" SRC "R1 a 0 1e-300f\n",
                 "t.wdn:3:8: error: malformed number '1e-300f': number out of range (its magnitude is below 2.2e-308)");
    expect_error(".param x 1.2.3\n",
                 "t.wdn:1:10: error: malformed number '1.2.3': unknown scale suffix or unit '.3'");
    expect_error(".rate 48q\n",
                 "t.wdn:1:7: error: malformed number '48q': unknown scale suffix or unit 'q'");
    expect_error(".input in\n" SRC "R1 a 0 1k\nC1 a 0 1u\n.ic v(a)=2z\n",
                 "t.wdn:5:10: error: malformed number '2z': unknown scale suffix or unit 'z'");
}

static void test_bad_expressions(void **state) {
    (void)state;
    expect_error(".input in\n" SRC "R1 a 0 {}\n", "t.wdn:3:9: error: empty expression");
    expect_error(".input in\n" SRC "R1 a 0 {1+}\n", "t.wdn:3:11: error: expression ends too early");
    expect_error(".input in\n" SRC "R1 a 0 {foo(1)}\n", "t.wdn:3:9: error: unknown function 'foo'");
    expect_error(".input in\n" SRC "R1 a 0 {pow(1)}\n",
                 "t.wdn:3:14: error: expected ',' (the function takes two arguments) in expression");
    expect_error(".input in\n" SRC "R1 a 0 {1 2}\n", "t.wdn:3:11: error: unexpected '2' after expression");
    expect_error(".input in\n" SRC "R1 a 0 {1 $ 2}\n",
                 "t.wdn:3:11: error: unexpected character '$' in expression");
    expect_error(".input in\n" SRC "R1 a 0 {(1+2}\n", "t.wdn:3:13: error: expected ')' in expression");
}

/* ---- structure of element lines ---- */

static void test_node_counts(void **state) {
    (void)state;
    expect_error(".input in\n" SRC "R1 a\n", "t.wdn:3:5: error: resistor 'R1' needs 2 nodes, found 1");
    expect_error("R1\n", "t.wdn:1:3: error: resistor 'R1' needs 2 nodes, found 0");
    expect_error(".input in\n" SRC "R1 a R=1k\n",
                 "t.wdn:3:6: error: resistor 'R1' needs 2 nodes, found 1");
    expect_error(".input in\n" SRC "pot P1 a b R=1k pos=0.5\n",
                 "t.wdn:3:12: error: potentiometer 'P1' needs 3 nodes, found 2");
    expect_error(".input in\n" SRC "R1 a 0 b 1k\n",
                 "t.wdn:3:10: error: too many nodes or values for resistor 'R1': unexpected '1k'");
    expect_error(".input in\n" SRC "R1 a 0 1k 2k\n",
                 "t.wdn:3:11: error: too many nodes or values for resistor 'R1': unexpected '2k'");
    expect_error(".domain mechanical\n.input f\nforce F1 a 0 f\nmass M1 a b m=1\n",
                 "t.wdn:4:11: error: too many nodes or values for mass 'M1': unexpected 'b'");
    expect_error(".input in\n" SRC "R1 a a 1k\n",
                 "t.wdn:3:4: error: resistor 'R1' has both terminals on node 'a'");
}

static void test_unknown_keys(void **state) {
    (void)state;
    expect_error(".input in\n" SRC "R1 a 0 1k foo=2\n",
                 "t.wdn:3:11: error: unknown key 'foo' for resistor 'R1'");
    expect_error(".input in\n" SRC "R1 a 0 1k taper=log\n",
                 "t.wdn:3:11: error: unknown key 'taper' for resistor 'R1'");
    expect_error(".param x 1 foo=2\n",
                 "t.wdn:1:12: error: unknown key 'foo' for .param (expected min=, max= or unit=)");
    expect_error(".model M diode Is=1e-12 foo=1\n",
                 "t.wdn:1:25: error: unknown key 'foo' for a diode model");
    expect_error(".block B x\nR1 x 0 1k\n.endblock\n.input in\n" SRC "use B X1 a zz=1\n",
                 "t.wdn:6:12: error: block 'B' has no param 'zz'");
    expect_error(".input in\n" SRC "R1 a 0 1k R=1k\n",
                 "t.wdn:3:11: error: value of 'R1' given twice");
    expect_error(".input in\n" SRC "R1 a 0 R=1k R=2k\n", "t.wdn:3:13: error: key 'R' given twice");
    expect_error(".input in\n" SRC "pot P1 a w 0 R=1k pos=0.5 taper=cubic\nR1 w 0 1k\n",
                 "t.wdn:3:33: error: taper= takes lin or log");
}

static void test_duplicates(void **state) {
    (void)state;
    expect_error(".input in\n" SRC "R1 a 0 1k\nR1 a 0 2k\n",
                 "t.wdn:4:1: error: duplicate element name 'R1'");
    expect_error(".input in\n" SRC "pot P1 a w 0 R=1k pos=0.5\npot P1 a w 0 R=1k pos=0.5\n",
                 "t.wdn:4:5: error: duplicate element name 'P1.aw'");
    expect_error(".param x 1\n.param x 2\n", "t.wdn:2:8: error: duplicate param 'x'");
    expect_error(".input in\n.input out in\n", "t.wdn:2:12: error: duplicate input 'in'");
    expect_error(".input in\n.param in 1\n", "t.wdn:2:8: error: 'in' is already an input");
    expect_error(".input in\n" SRC "R1 a 0 1k\n.output o v(a)\n.output o i(R1)\n",
                 "t.wdn:5:9: error: duplicate output 'o'");
    expect_error(".model M diode Is=1e-12\n.model M diode Is=2e-12\n",
                 "t.wdn:2:8: error: duplicate model 'M'");
    expect_error(".block B x\nR1 x 0 1k\n.endblock\n.block B x\nR2 x 0 1k\n.endblock\n",
                 "t.wdn:4:8: error: duplicate block name 'B'");
    expect_error(".voice a\n.voice b\n", "t.wdn:2:1: error: second .voice line");
    expect_error(".input in\n" SRC "C1 a 0 1u\nR1 a 0 1k\n.ic v(a)=1 v(a)=2\n",
                 "t.wdn:5:12: error: second initial condition for v(a)");
    /* two instances of one name: reported at the second instance's name */
    char *out = load_fails(".block rc in out\nR1 in out 1k\n.endblock\n.input in\n" SRC
                           "use rc X a b\nuse rc X b 0\n");
    assert_non_null(strstr(out, "t.wdn:7:8: error: duplicate element name 'X.R1' (in this instance of block 'rc')"));
    free(out);
}

/* Names of one kind that differ only in case: the second is an error
 * that names the first, never a second node, param or element. */
static void test_case(void **state) {
    (void)state;
    expect_error(".input in\n" SRC "R1 a out 1k\nR2 OUT 0 1k\n",
                 "t.wdn:4:4: error: node 'OUT' differs from node 'out' only in case");
    expect_error(".input in\n" SRC "R1 a 0 1k\nr1 a 0 2k\n",
                 "t.wdn:4:1: error: element 'r1' differs from element 'R1' only in case");
    expect_error(".param gain 1\n.param Gain 2\n", "t.wdn:2:8: error: param 'Gain' differs from param 'gain' only in case");
    expect_error(".input in In\n", "t.wdn:1:11: error: input 'In' differs from input 'in' only in case");
    expect_error(".model M diode Is=1e-12\n.model m diode Is=2e-12\n",
                 "t.wdn:2:8: error: model 'm' differs from model 'M' only in case");
    expect_error(".block rc x\nR1 x 0 1k\n.endblock\n.block RC x\nR2 x 0 1k\n.endblock\n",
                 "t.wdn:4:8: error: block 'RC' differs from block 'rc' only in case");
    expect_error(".input in\n" SRC "R1 a 0 1k\n.output o v(a)\n.output O i(R1)\n",
                 "t.wdn:5:9: error: output 'O' differs from output 'o' only in case");
    /* ground is 0, gnd or GND; one spelling of a node throughout is fine */
    Circuit *c = load_ok("t.wdn", ".input in\n" SRC "R1 a Out 1k\nC1 Out GND 1u\n.output y v(Out)\n");
    assert_int_equal(c->nnodes, 3);
}

/* ---- names that are not defined ---- */

static void test_undefined_params(void **state) {
    (void)state;
    expect_error(".input in\n" SRC "R1 a 0 {y*2}\n", "t.wdn:3:9: error: unknown param 'y'");
    expect_error(".input in\n.param y 1\n" SRC "R1 a 0 {2k*y + 1k*zz}\n",
                 "t.wdn:4:19: error: unknown param 'zz'");
    expect_error(".input in\n" SRC "R1 a 0 R={in}\n",
                 "t.wdn:3:11: error: 'in' is an audio input; only params may appear in values");
    expect_error(".input in\n" SRC "R1 a 0 bass\n", "t.wdn:3:8: error: unknown param 'bass'");
    expect_error("V1 a 0 nosuch\nR1 a 0 1k\n",
                 "t.wdn:1:8: error: unknown input or param 'nosuch' (declare inputs with .input)");
    expect_error(".block B x\nR1 x 0 {zz}\n.endblock\n.input in\n" SRC "use B X a\n",
                 "t.wdn:2:9: error: unknown param 'zz'");
    expect_error(".input in\n" SRC "R1 a 0 1k\nC1 a 0 1u\n.ic v(a)={q}\n",
                 "t.wdn:5:11: error: unknown param 'q'");
}

static void test_undefined_models(void **state) {
    (void)state;
    expect_error(".input in\n" SRC "R1 a b 1k\nD1 b 0 MM\n", "t.wdn:4:8: error: unknown model 'MM'");
    expect_error(".domain mechanical\n.model heavy mass m=40m\n.input f\nforce F1 a 0 f\n"
                 "mass M1 a model=light\nspring K1 a 0 k=1k\n",
                 "t.wdn:5:17: error: unknown model 'light'");
    expect_error(".domain mechanical\n.model heavy mass m=40m\n.input f\nforce F1 a 0 f\n"
                 "spring K1 a 0 k=1k model=heavy\n",
                 "t.wdn:5:26: error: model 'heavy' is a mass model, not a spring model");
    expect_error(".model M widget Is=1\n", "t.wdn:1:10: error: unknown model kind 'widget'");
}

static void test_undefined_blocks(void **state) {
    (void)state;
    expect_error(".input in\n" SRC "use nosuch X1 a 0\n", "t.wdn:3:5: error: unknown block 'nosuch'");
    expect_error(".block B x y\nR1 x y 1k\n.endblock\n.input in\n" SRC "use B X1 a\n",
                 "t.wdn:6:7: error: block 'B' has 2 nodes, instance 'X1' gives 1");
    expect_error(".block rc a b\nuse rc Y a b\n.endblock\n.input in\n" SRC "use rc X a 0\n",
                 "t.wdn:2:5: error: block 'rc' uses itself");
    expect_error(".block B x\n.block C y\n.endblock\n",
                 "t.wdn:2:1: error: '.block' inside the definition of block 'B' (blocks do not nest)");
    expect_error(".endblock\n", "t.wdn:1:1: error: '.endblock' without a matching '.block'");
    expect_error(".block B x\nR1 x 0 1k\n", "t.wdn:1:1: error: block 'B' has no '.endblock'");
    expect_error(".block B x\n.param p 1\n.endblock\n",
                 "t.wdn:2:1: error: directive '.param' is not allowed inside a block");
}

static void test_probes(void **state) {
    (void)state;
    expect_error(".input in\n" SRC "R1 a 0 1k\n.output o v(zz)\n", "t.wdn:4:13: error: unknown node 'zz'");
    expect_error(".input in\n" SRC "R1 a 0 1k\n.output o v(a,q)\n", "t.wdn:4:15: error: unknown node 'q'");
    expect_error(".input in\n" SRC "R1 a 0 1k\n.output o i(R9)\n",
                 "t.wdn:4:13: error: unknown element 'R9'");
    expect_error(".input in\n" SRC "pot P1 a w 0 R=1k pos=0.5\nR1 w 0 1k\n.output o i(P1)\n",
                 "t.wdn:5:13: error: 'P1' is a pot: probe one half, P1.aw or P1.wb");
    expect_error(".input in\n" SRC "R1 a 0 1k\n.output o f(R1)\n",
                 "t.wdn:4:11: error: f() reads a force; this netlist is electrical (use i())");
    expect_error(".input in\n" SRC "R1 a 0 1k\n.output o q(a)\n",
                 "t.wdn:4:11: error: expected a probe v(node), v(a,b), i(elem), x(node) or f(elem)");
    expect_error(".input in\n" SRC "R1 a 0 1k\n.output o v(a\n",
                 "t.wdn:4:14: error: expected ')' to close the probe");
    expect_error(".input in\n" SRC "R1 a 0 1k\n.output o v(a,0,b)\n",
                 "t.wdn:4:16: error: expected ')' to close the probe");
    expect_error(".input in\n" SRC "R1 a 0 1k\nC1 a 0 1u\n.ic v(zz)=1\n",
                 "t.wdn:5:7: error: unknown node 'zz'");
    expect_error(".input in\n" SRC "R1 a 0 1k\nC1 a 0 1u\n.ic v(a)=1 x(q)=0\n",
                 "t.wdn:5:14: error: unknown node 'q'");
    expect_error(".input in\n" SRC "R1 a 0 1k\n.ic i(R1)=1\n",
                 "t.wdn:4:5: error: .ic sets v(node) or x(node), not i()");
    expect_error(".input in\n" SRC "C1 a 0 1u\nR1 a 0 1k\n.ic v(0)=1\n",
                 "t.wdn:5:7: error: ground has no initial condition");
    expect_error(".input in\n" SRC "C1 a 0 1u\nR1 a 0 1k\n.ic v(a) 1\n",
                 "t.wdn:5:10: error: expected '=' after v(a)");
}

/* ---- unterminated and missing things ---- */

static void test_unterminated(void **state) {
    (void)state;
    expect_error(".input in\n" SRC "R1 a 0 {1k*2\n",
                 "t.wdn:3:8: error: unterminated '{': expected '}' on the same line");
    expect_error(".input in\n" SRC "R1 a 0 {1k*{2}\nC1 a 0 1u\n",
                 "t.wdn:3:8: error: unterminated '{': expected '}' on the same line");
    expect_error(".include \"foo.wdn\n", "t.wdn:1:10: error: unterminated string");
    expect_error(".param u 1 unit=\"Hz\n", "t.wdn:1:17: error: unterminated string");
    expect_error(".input in\n" SRC "nlres N1 a 0 curve=(0:0 1:1\n",
                 "t.wdn:3:20: error: unterminated '(': expected ')' before the end of the line");
}

static void test_missing_values(void **state) {
    (void)state;
    expect_error(".input in\n" SRC "R1 a 0\n", "t.wdn:3:7: error: resistor 'R1' needs a value after its nodes");
    expect_error(".input in\n" SRC "R1 a 0 R=\n", "t.wdn:3:9: error: expected a value after '='");
    expect_error(".param x\n", "t.wdn:1:9: error: missing default value of param 'x'");
    expect_error(".param x=\n", "t.wdn:1:10: error: missing default value of param 'x'");
    expect_error(".rate\n", "t.wdn:1:6: error: missing sample rate after .rate");
    expect_error(".input\n", "t.wdn:1:7: error: missing input name after .input");
    expect_error(".input in\n" SRC "R1 a 0 1k\nC1 a 0 1u\n.ic v(a)=\n",
                 "t.wdn:5:10: error: expected a value at the end of the line");
    expect_error(".input in\n" SRC "R1 a 0 1k\nC1 a 0 1u\n.ic\n",
                 "t.wdn:5:4: error: expected v(node)=value or x(node)=value after .ic");
    expect_error(".domain mechanical\n.input f\nforce F1 a 0 f\nmass M1 a\n",
                 "t.wdn:4:6: error: mass 'M1' needs m=");
    expect_error(".input in\n" SRC "pot P1 a w 0 R=1k\nR1 w 0 1k\n",
                 "t.wdn:3:5: error: potentiometer 'P1' needs pos=");
    expect_error(".input in\nV1 a 0\n",
                 "t.wdn:2:7: error: voltage source 'V1' needs a drive (input, param or value) after its nodes");
    expect_error(".input in\n" SRC "R1 a b 1k\nD1 b 0\n",
                 "t.wdn:4:7: error: diode 'D1' needs a model name after its nodes");
    expect_error("mass\n", "t.wdn:1:5: error: missing mass name after 'mass'");
    expect_error(".input in\n" SRC "R1 a 0 1k\n.output o\n",
                 "t.wdn:4:10: error: expected a probe v(node), v(a,b), i(elem), x(node) or f(elem)");
    expect_error(".include\n", "t.wdn:1:9: error: expected a file name after .include");
    expect_error(".input in\n" SRC "R1 a 0 \"1k\"\n",
                 "t.wdn:3:8: error: expected a number, {expression} or param name for the value");
}

/* ---- values ---- */

static void test_values(void **state) {
    (void)state;
    expect_error(".param x 1\n.input in\n" SRC "R1 a b {x-1}\nR2 b 0 1k\n",
                 "t.wdn:4:1: error: resistor 'R1' has resistance 0 at the default params; "
                 "it must be positive and finite");
    expect_error(".input in\n" SRC "C1 a 0 -1u\nR1 a 0 1k\n",
                 "t.wdn:3:1: error: capacitor 'C1' has capacitance -1e-06 at the default params; "
                 "it must be positive and finite");
    expect_error(".input in\n" SRC "R1 a 0 {1/0}\n",
                 "t.wdn:3:1: error: resistor 'R1' has resistance inf at the default params; "
                 "it must be positive and finite");
    expect_error(".param x 1 min=0 max=2\n.input in\n" SRC "R1 a 0 {x}\n",
                 "t.wdn:4:1: error: resistor 'R1' reaches 0 when param 'x' = 0; "
                 "it must stay positive (narrow the param's range)");
    expect_error(".param x 5 min=0 max=1\n", "t.wdn:1:10: error: default 5 of param 'x' lies outside [0, 1]");
    expect_error(".param y 1\n.param x {-y}\n",
                 "t.wdn:2:11: error: the default of param 'x' must be a number (params are not known at compile time)");
    expect_error(".param y 1\n.rate {y*48k}\n",
                 "t.wdn:2:8: error: the sample rate must be a number (params are not known at compile time)");
    expect_error(".param x 1 min=2 max=1\n", "t.wdn:1:12: error: param 'x' has min greater than max");
    expect_error(".param 1x 2\n", "t.wdn:1:8: error: param name '1x' is not an identifier");
    expect_error(".param x y\n", "t.wdn:1:10: error: the default of param 'x' must be a number (params are not known at compile time)");
    expect_error(".voice 1abc\n", "t.wdn:1:8: error: voice name '1abc' is not a C identifier");
    expect_error(".input 1x\n", "t.wdn:1:8: error: input name '1x' is not an identifier");
    expect_error(".domain foo\n",
                 "t.wdn:1:9: error: unknown domain 'foo' (expected electrical, mechanical or acoustic)");
    expect_error(".rate 0\n", "t.wdn:1:7: error: sample rate 0 Hz is out of range (1 Hz to 10 MHz)");
}

/* ---- kinds later work implements ---- */

static void test_not_supported_yet(void **state) {
    (void)state;
    /* each kind is checked while blocks.def marks it not ready */
    static const struct {
        int kind;
        const char *text, *want;
    } cases[] = {
        {BK_D, ".model DM diode Is=1e-12 n=1.5\n.input in\n" SRC "R1 a b 1k\nD1 b 0 DM\n",
         "t.wdn:5:1: error: diode 'D1' is not supported yet"},
        {BK_T, ".input in\n" SRC "R1 a b 1k\nT1 b 0 c 0 Z0=600 TD=1m\nR2 c 0 1k\n",
         "t.wdn:4:1: error: transmission line 'T1' is not supported yet"},
        {BK_CONTACT, ".domain mechanical\n.input f\nforce F1 a 0 f\nmass M1 a m=1\n"
                     "  contact H1 a b k=4e9 alpha=2.5\nmass M2 b m=1\n",
         "t.wdn:5:3: error: contact 'H1' is not supported yet"},
        {BK_NLRES, ".input in\n" SRC "R1 a b 1k\nnlres N1 b 0 curve=(0:0 1:1e-3)\n",
         "t.wdn:4:1: error: nonlinear resistor 'N1' is not supported yet"},
        {BK_MUTATOR, ".input in\n" SRC "R1 a b 1k\nmutator X1 b 0 c 0 type=RC\nC1 c 0 1u\n",
         "t.wdn:4:1: error: mutator 'X1' is not supported yet"},
        {BK_STRING, ".domain mechanical\n.input f\nforce F1 a 0 f\n"
                    "string S1 a 0 L=0.62 f0=261.6 taps=h@0.12,p@0.5\n",
         "t.wdn:4:1: error: string 'S1' is not supported yet"},
        {BK_TUBE, ".domain acoustic\n.input f\nI1 a 0 f\ntube W1 a 0 L=0.6 r=7.5m\n",
         "t.wdn:4:1: error: tube 'W1' is not supported yet"},
        {BK_JUNCTION, ".input in\n" SRC "R1 a b 1k\njunction J1 series a b 0\n",
         "t.wdn:4:1: error: explicit junction 'J1' is not supported yet"},
    };
    int checked = 0;
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        if (block_desc[cases[i].kind].kind->ready)
            continue;
        expect_error(cases[i].text, cases[i].want);
        checked++;
    }
    if (checked < (int)(sizeof cases / sizeof cases[0]))
        print_message("%d of %d later element kinds are implemented now; their cases were skipped\n",
                      (int)(sizeof cases / sizeof cases[0]) - checked,
                      (int)(sizeof cases / sizeof cases[0]));
}

/* ---- graph ---- */

static void test_graph(void **state) {
    (void)state;
    expect_error(".input in\n" SRC "C1 a b 1u\n", "t.wdn:3:1: error: node 'b' has only one connection (C1)");
    expect_error(".input in\nV1 a 0 in\n", "t.wdn:2:1: error: node 'a' has only one connection (V1)");
    /* a resistor to a node nothing else meets carries no current: it goes,
     * and leaves the source alone at a */
    expect_error(".input in\n" SRC "R1 a b 1k\n", "t.wdn:2:1: error: node 'a' has only one connection (V1); R1 went "
                                               "on to 'b', which nothing else meets, and was taken out");
    expect_error(".input in\n" SRC "R1 a 0 1k\nR2 b c 1k\nC2 b c 1u\n",
                 "t.wdn:4:1: error: node 'b' has no path to ground (node 0)");
    expect_error(".input in\nV1 a b in\nR1 a b 1k\n",
                 "t.wdn:2:1: error: nothing connects to ground (node 0)");
}

/* An input no source reads loads, with a warning at its name. */
static void test_unread_input(void **state) {
    (void)state;
    Capture cap;
    capture_begin(&cap);
    Circuit *c = wdc_load_string("t.wdn", ".input in\n.input x\n" SRC "R1 a 0 1k\n.output o v(a)\n");
    char *out = capture_end(&cap);
    assert_non_null(c);
    char *got = first_line(out);
    assert_string_equal(got, "t.wdn:2:8: warning: input 'x' drives nothing: no source reads it");
    free(got);
    free(out);
}

/* An output read through resistors that lead nowhere, as SPICE allows:
 * they carry no current, so their far nodes are their near node under
 * other names and a probe of their current reads 0. */
static void test_dangling_resistors(void **state) {
    (void)state;
    Circuit *c = load_ok("t.wdn", ".input in\n" SRC "R1 a b 1k\nC1 b 0 1u\nR2 b m 10k\nR3 m out 10k\n"
                                  ".output o v(out)\n.output mid v(m, 0)\n.output b v(b)\n.output i i(R3)\n"
                                  ".output j i(R1)\n");
    assert_int_equal(c->nelems, 3);
    assert_int_equal(c->nnodes, 3);
    int b = c->outs[2].n[0];
    assert_string_equal(c->nodes[b], "b");
    assert_int_equal(c->outs[0].n[0], b);
    assert_int_equal(c->outs[1].n[0], b);
    assert_int_equal(c->outs[3].elem, -1);
    assert_string_equal(c->elems[c->outs[4].elem].name, "R1");
    /* a damper to a point nothing else holds: no force either */
    c = load_ok("t.wdn", ".domain mechanical\n.input f\nforce F1 m 0 f\nmass M1 m m=1\ndamper D1 m free c=2\n"
                         ".output v v(free)\n");
    assert_int_equal(c->nelems, 2);
    expect_error(".input in\n" SRC "R1 a b 1k\nC1 b 0 1u\nR2 b out 1k\n.output o i(R9)\n",
                 "t.wdn:6:13: error: unknown element 'R9'");
}

/* Two diodes facing each other with one law are the antiparallel pair
 * (pair=1): the symmetric clipper compiles, in a deck or a .wdn.  Two
 * that differ stay two, and the refusal says why. */
static void test_facing_diodes(void **state) {
    (void)state;
    Circuit *c = load_ok("t.wdn", ".input in\n" SRC ".model dm diode Is=2.52n n=1.752\nR1 a b 2.2k\nC1 b 0 10n\n"
                                  "D1 b 0 dm\nD2 0 b dm\n.output o v(b)\n");
    assert_int_equal(c->nelems, 4);
    const Elem *d = elem_named(c, "D1");
    assert_true(d->nl->pair);
    assert_true(expr_eval(d->nl->Is, NULL) == 2.52e-9);
    expect_error(".input in\n" SRC ".model dm diode Is=2.52n\nR1 a b 1k\nD1 b 0 dm\nD2 0 b dm\n.output o i(D2)\n",
                 "t.wdn:7:13: error: diode 'D2' faces 'D1' and the two are solved as one antiparallel pair: probe i(D1), "
                 "the pair's current");
}

/* Renders deck `text` (written as `name`) with bin/wdc and reads the
 * first row of its CSV into v[0..n). */
static void render_first_row(const char *name, const char *text, double *v, int n) {
    const char *p = write_tmp(name, text);
    char args[1024], path[300], *out;
    snprintf(path, sizeof path, "%s.csv", p);
    snprintf(args, sizeof args, "'%s' --render '%s.wav' --csv '%s'", p, p, path);
    assert_int_equal(run_wdc(args, &out), 0);
    free(out);
    FILE *f = fopen(path, "r");
    assert_non_null(f);
    char line[512];
    assert_non_null(fgets(line, sizeof line, f));
    fclose(f);
    char *c = line;
    for (int k = 0; k < n; k++) {
        v[k] = strtod(c, &c);
        if (*c == ',')
            c++;
    }
}

/* A deck starts from its DC operating point, as SPICE's transient does:
 * a biased divider with a coupling capacitor and an inductor to ground
 * renders its operating point from the first sample on (no thump); with
 * .tran ... UIC it starts from rest instead. */
static void test_cli_deck_op(void **state) {
    (void)state;
    const char *deck = "Biased divider with a coupling cap\nVCC vcc 0 9\nR1 vcc b 100k\nR2 b 0 10k\nC1 b out 1u\n"
                       "R3 out 0 100k\nL1 vcc c 10m\nR4 c 0 1k\n.tran 20.8333333333u 0.05%s\n"
                       ".print tran v(b) v(out) i(l1)\n.end\n";
    for (int uic = 0; uic < 2; uic++) {
        char text[1024];
        snprintf(text, sizeof text, deck, uic ? " uic" : "");
        double v[3];
        render_first_row("bias.cir", text, v, 3);
        printf("%s: first sample v(b) %.17g V, v(out) %.3g V, i(L1) %.17g A\n", uic ? "uic" : "operating point", v[0],
               v[1], v[2]);
        if (uic) {
            assert_true(fabs(v[0] - 9.0 / 11) > 0.01);
        } else {
            assert_true(fabs(v[0] - 9.0 / 11) < 1e-14);
            assert_true(fabs(v[1]) < 1e-15);
            assert_true(fabs(v[2] - 9e-3) < 1e-16);
        }
    }
    /* a source with AC is the voice's input; its DC value is where the
     * operating point and the render's drive start */
    double v[2];
    render_first_row("bin.cir", "Biased input\nV1 in 0 DC 5 AC 1\nR1 in b 10k\nC1 b 0 1u\nR2 b 0 10k\n"
                                ".tran 20.8333333333u 0.01\n.print tran v(b) v(in)\n.end\n", v, 2);
    assert_true(v[0] == 2.5 && v[1] == 5);
}

/* --spice reads any file as a deck, and a deck's .include is read as a
 * deck too (no title line of its own, case folded). */
static void test_cli_spice_flag(void **state) {
    (void)state;
    write_tmp("parts.inc", "* parts\nR2 OUT 0 10K\n.MODEL DX D(IS=1N)\n");
    const char *p = write_tmp("deck.txt", "A deck named .txt\n.include parts.inc\nV1 IN 0 DC 1\nR1 in out 10k\n"
                                          "C1 out 0 1u\n.print tran v(out)\n.end\n");
    char args[1024], *out;
    snprintf(args, sizeof args, "'%s' --check", p);
    assert_int_equal(run_wdc(args, &out), 1); /* read as a .wdn: the title is a line */
    free(out);
    snprintf(args, sizeof args, "'%s' --spice -delab", p);
    assert_int_equal(run_wdc(args, &out), 0);
    assert_non_null(strstr(out, "R r2 out 0 10000"));
    assert_non_null(strstr(out, "R r1 in out 10000"));
    free(out);
}

/* An asymmetric clipper: the facing diodes' laws differ, so the two stay
 * two, solved jointly at their root; -dwdf shows both at it. */
static void test_cli_facing_diodes(void **state) {
    (void)state;
    const char *p = write_tmp("asym.wdn", ".input in\nV1 a 0 in\n.model dm diode Is=2.52n\n.model dn diode Is=1n\n"
                                          "R1 a b 1k\nD1 b 0 dm\nD2 0 b dn\n.output o v(b)\n");
    char args[512], *out;
    snprintf(args, sizeof args, "'%s' --check", p);
    assert_int_equal(run_wdc(args, &out), 0);
    free(out);
    snprintf(args, sizeof args, "'%s' -dwdf", p);
    assert_int_equal(run_wdc(args, &out), 0);
    assert_non_null(strstr(out, "2 nonlinear (solved jointly)"));
    free(out);
}

/* ---- SPICE decks ---- */

/* Loads text as the deck "t.cir": the circuit (NULL on an error) and
 * everything printed into *out (to free). */
static Circuit *deck(const char *text, char **out) {
    Capture cap;
    capture_begin(&cap);
    Circuit *c = wdc_load_string("t.cir", text);
    *out = capture_end(&cap);
    return c;
}

static void expect_deck_error(const char *text, const char *want) {
    char *out;
    assert_null(deck(text, &out));
    char *got = first_line(out);
    if (strcmp(got, want))
        fail_msg("deck:\n%s\nexpected: %s\n     got: %s", text, want, got);
    free(got);
    free(out);
}

static int input_named(const Circuit *c, const char *name) {
    for (int i = 0; i < c->ninputs; i++)
        if (!strcmp(c->inputs[i], name))
            return i;
    return -1;
}

/* A deck as ngspice reads it: its first line is the title (even one that
 * reads like a source), names and keywords in any case are one, '$' and
 * ';' start comments, .param lists and 'quoted' expressions, a diode
 * model in parentheses with SPICE's keys (those we do not model noted),
 * .tran for the rate and length, .print's vectors as outputs, analysis
 * and control lines noted and skipped. */
static void test_deck(void **state) {
    (void)state;
    char *out;
    Circuit *c = deck("Vox AC30 top boost (a title, not a source)\n"
                      "* a comment line\n"
                      ".PARAM rval=2.2K cval='10n*2' $ two params\n"
                      "V1 IN 0 DC 0 AC 1 SIN(0 1 1k)\n"
                      "VCC Vcc 0 9 ; a rail\n"
                      "R1 in OUT {rval}\nC1 Out 0 'cval'\nRb vcc out 1MEG\n"
                      ".MODEL 1N914 D(IS=2.52n, N=1.752 RS=.568)\nD1 out 0 1n914\n"
                      ".tran 10u 50m\n.ac dec 10 10 100k\n.control\nrun\n.endc\n"
                      ".print TRAN V(out) v(in,out) I(r1)\n.END\n",
                      &out);
    if (!c)
        fail_msg("deck rejected:\n%s", out);
    assert_int_equal(c->nnodes, 4); /* 0, in, out, vcc */
    assert_int_equal(c->nelems, 6);
    assert_true(c->rate == 1e5);
    assert_true(c->tstop == 0.05);
    assert_int_equal(c->nouts, 3);
    assert_string_equal(c->outs[0].name, "v_out");
    assert_string_equal(c->outs[1].name, "v_in_out");
    assert_string_equal(c->outs[2].name, "i_r1");
    assert_int_equal(c->nparams, 2);
    assert_true(fabs(c->params[1].def - 2e-8) < 1e-22);
    /* V1 has AC and SIN: an input of its own; VCC is a constant 9 V */
    int v1 = input_named(c, "v1");
    assert_true(v1 >= 0);
    assert_int_equal(c->ninputs, 1);
    assert_non_null(c->input_fn[v1]);
    assert_int_equal(c->input_fn[v1]->kind, 's');
    assert_true(strstr(out, "t.cir:9:34: note: diode model '1n914': rs= is not modelled and is ignored") != NULL);
    assert_true(strstr(out, "t.cir:12:1: note: '.ac' is an analysis or control line") != NULL);
    assert_true(strstr(out, "t.cir:13:1: note: '.control' starts ngspice's commands") != NULL);
    free(out);
    /* ngspice's own commands: tran, and the vectors plot and wrdata name */
    c = deck("* all in .control\nV1 in 0 SIN(0 1 1k)\nR1 in out 1k\nC1 out 0 100n\n.control\nset numdgt=16\n"
             "tran 10u 5m\nplot v(out) v(in) vs time\nwrdata /tmp/x.dat v(out) i(v1)\nrun\n.endc\n.end\n", &out);
    if (!c)
        fail_msg("deck rejected:\n%s", out);
    assert_true(c->rate == 1e5 && c->tstop == 5e-3);
    assert_int_equal(c->nouts, 3);
    assert_string_equal(c->outs[2].name, "i_v1");
    assert_null(strstr(out, "error"));
    free(out);
    /* .subckt with params, X instances in any case */
    c = deck("Two RC sections\n.subckt rcsec IN OUT params: r=1k c=100n\nR1 in out {r}\nC1 out 0 {c}\n"
             ".ends rcsec\nV1 a 0 DC 0 AC 1\nX1 a b RCSEC\nX2 b c rcsec params: r=2k\n.print tran v(c)\n.end\n",
             &out);
    if (!c)
        fail_msg("deck rejected:\n%s", out);
    free(out);
    assert_int_equal(c->nelems, 5);
    assert_string_equal(c->elems[3].name, "x2.r1");
    assert_true(c->elems[3].val && expr_eval(c->elems[3].val, NULL) == 2000);
    /* units after the scale in any case (10nF, 12.88mH); an AC measure's
     * signal as the output */
    c = deck("* LC section\nVS 1 0 AC 1\nRS 1 2 50\nL1 2 3 12.88MH\nC1 3 0 10nF\nRL 3 0 50ohms\n"
             ".print ac vdb(3)\n.end\n", &out);
    if (!c)
        fail_msg("deck rejected:\n%s", out);
    assert_non_null(strstr(out, "t.cir:7:11: note: 'vdb(...)' measures the AC analysis; the voice outputs the signal, v(...)"));
    free(out);
    assert_true(fabs(expr_eval(elem_named(c, "l1")->val, NULL) - 12.88e-3) < 1e-15);
    assert_true(fabs(expr_eval(elem_named(c, "c1")->val, NULL) - 10e-9) < 1e-20);
    assert_string_equal(c->outs[0].name, "v_3");
    /* a .wdn keeps its case, takes no title and has no '$' comments */
    expect_error("V1 a 0 in $ drive\n", "t.wdn:1:11: error: too many nodes or values for voltage source 'V1': unexpected '$'");
    /* errors in a deck at their place */
    expect_deck_error("title\nV1 a 0 FOO 1\nR1 a 0 1k\n.end\n",
                      "t.cir:2:8: error: expected DC, AC, SIN(...), PULSE(...), PWL(...) or EXP(...) in source 'v1'");
    expect_deck_error("title\nV1 a 0 PWL(0 0 1m)\nR1 a 0 1k\n.end\n", "t.cir:2:11: error: pwl(...) takes time, value pairs");
    expect_deck_error("title\nV1 a 0 SIN(0 1)\nR1 a 0 1k\n.end\n", "t.cir:2:11: error: sin(...) needs at least 3 values");
    expect_deck_error("title\nR1 a 0 'rv\n.end\n", "t.cir:2:8: error: unterminated quote: expected ' on the same line");
    expect_deck_error("title\nV1 a 0 1\nR1 a 0 1k\n.tran 0 1\n.end\n", "t.cir:4:7: error: .tran's step must be above 0");
    expect_deck_error("title\nV1 a 0 1\nR1 a 0 1k\n.tran 10n 1u\n.end\n",
                      "t.cir:4:7: error: .tran's step gives a rate of 1e+08 Hz; it must be from 1 Hz to 10 MHz (or give "
                      "the voice's rate with --rate)");
    expect_deck_error("title\n.control\nrun\n", "t.cir:2:1: error: '.control' without '.endc'");
    /* an '.endc' inside a line does not end it (the reader ran past the end of the deck: the fuzzer's find) */
    expect_deck_error("title\nV1 in 0 1\nR1 in out 1k\nC1 out 0 1u\n.control\nrun\n}1-4*.endc\n.print tran v(out)\n",
                      "t.cir:5:1: error: '.control' without '.endc'");
    expect_deck_error("title\n.control\nprint v(a) .endc\n", "t.cir:2:1: error: '.control' without '.endc'");
    /* a SPICE device the compiler does not model is named as SPICE names it */
    expect_deck_error("title\nV1 a 0 1\nR1 a b 1k\nM1 b a 0 0 nmos\n.end\n",
                      "t.cir:4:1: error: 'M1' is a MOSFET, which decks here do not take (they take R, C, L, V, I, D, "
                      "Q, E, G, K, T and X)");
    expect_deck_error("title\n.model d1 d(is=1n n=2\n", "t.cir:2:12: error: unclosed '(' in .model");
    assert_true(is_spice_path("a/b.CIR") && is_spice_path("x.sp") && is_spice_path("x.spice") &&
                is_spice_path("x.net") && !is_spice_path("x.wdn") && !is_spice_path("net.d/x"));
}

/* The time functions of a deck's sources as SPICE's transient reads them. */
static void test_deck_sources(void **state) {
    (void)state;
    double sv[] = {0.5, 2, 1000, 1e-3, 0, 90}, pv[] = {0, 5, 1e-3, 1e-4, 2e-4, 1e-3, 4e-3},
           wv[] = {0, 0, 1e-3, 1, 2e-3, 0}, ev[] = {0, 1, 0, 1e-3, 5e-3, 2e-3};
    SrcFn s = {'s', 0, sv, 6, {0}}, p = {'p', 0, pv, 7, {0}}, w = {'w', 0, wv, 6, {0}}, e = {'e', 0, ev, 6, {0}};
    double T = 1e-5;
    assert_true(fabs(srcfn_at(&s, 0.5e-3, T) - 2.5) < 1e-12); /* before the delay: VO + VA sin(phase) */
    assert_true(fabs(srcfn_at(&s, 1.25e-3, T) - (0.5 + 2 * cos(M_PI / 2))) < 1e-12);
    assert_true(fabs(srcfn_at(&s, 1.125e-3, T) - (0.5 + 2 * cos(M_PI / 4))) < 1e-12);
    assert_true(srcfn_at(&p, 0.9e-3, T) == 0);
    assert_true(fabs(srcfn_at(&p, 1.05e-3, T) - 2.5) < 1e-12); /* half way up */
    assert_true(srcfn_at(&p, 1.5e-3, T) == 5);
    assert_true(fabs(srcfn_at(&p, 2.2e-3, T) - 2.5) < 1e-12); /* half way down */
    assert_true(srcfn_at(&p, 3e-3, T) == 0);
    assert_true(srcfn_at(&p, 5.5e-3, T) == 5); /* the next period */
    assert_true(fabs(srcfn_at(&w, 0.5e-3, T) - 0.5) < 1e-12);
    assert_true(fabs(srcfn_at(&w, 1.5e-3, T) - 0.5) < 1e-12);
    assert_true(srcfn_at(&w, 5e-3, T) == 0);
    assert_true(fabs(srcfn_at(&e, 1e-3, T) - (1 - exp(-1))) < 1e-12);
    assert_true(fabs(srcfn_at(&e, 7e-3, T) - ((1 - exp(-7)) - (1 - exp(-1)))) < 1e-12);
    SrcFn d = {'d', 9, NULL, 0, {0}};
    assert_true(srcfn_at(&d, 1, T) == 9);
}

/* ---- includes ---- */

static void expect_file_error(const char *path, const char *want_suffix, int included) {
    Capture cap;
    capture_begin(&cap);
    Circuit *c = wdc_load(path);
    char *out = capture_end(&cap);
    assert_null(c);
    char *got = first_line(out);
    char want[512];
    snprintf(want, sizeof want, "%s%s", path, want_suffix);
    if (strcmp(got, want))
        fail_msg("expected: %s\n     got: %s", want, got);
    if (included)
        assert_non_null(strstr(out, "note: included from here"));
    free(got);
    free(out);
}

static void test_include_cycles(void **state) {
    (void)state;
    const char *self = write_tmp("self.wdn", ".input in\n" SRC "R1 a 0 1k\n.include \"self.wdn\"\n");
    char p[256];
    snprintf(p, sizeof p, "%s", self);
    /* the main file is among those being read: its own line 4 closes the cycle */
    expect_file_error(p, ":4:10: error: include cycle: 'self.wdn' is already being read", 0);

    /* a.wdn -> b.wdn -> a.wdn: b's line closes it */
    write_tmp("b.wdn", "* the second half of a cycle\n.include \"a.wdn\"\n");
    const char *a = write_tmp("a.wdn", ".input in\n.include \"b.wdn\"\n" SRC "R1 a 0 1k\n");
    snprintf(p, sizeof p, "%s", a);
    Capture cap;
    capture_begin(&cap);
    assert_null(wdc_load(p));
    char *out = capture_end(&cap);
    char *line = first_line(out);
    size_t dl = strlen(tmpdir);
    if (strncmp(line, tmpdir, dl) || strcmp(line + dl, "/b.wdn:2:10: error: include cycle: 'a.wdn' is already being read"))
        fail_msg("unexpected report of an include cycle: %s", line);
    free(line);
    free(out);

    const char *m = write_tmp("m.wdn", ".input in\n" SRC "R1 a 0 1k\n.include \"nosuch.wdn\"\n");
    snprintf(p, sizeof p, "%s", m);
    capture_begin(&cap);
    assert_null(wdc_load(p));
    out = capture_end(&cap);
    line = first_line(out);
    char want[512];
    snprintf(want, sizeof want, "%s:4:10: error: cannot read included file 'nosuch.wdn'", p);
    assert_string_equal(line, want);
    free(line);
    free(out);

    /* an error inside an included file names that file and the include */
    write_tmp("bad.wdn", "R1 x 0 4.7q\n");
    const char *ib = write_tmp("ib.wdn", ".include \"bad.wdn\"\n");
    snprintf(p, sizeof p, "%s", ib);
    capture_begin(&cap);
    assert_null(wdc_load(p));
    out = capture_end(&cap);
    snprintf(want, sizeof want,
             "%s/bad.wdn:1:8: error: malformed number '4.7q': unknown scale suffix or unit 'q'\n"
             "  R1 x 0 4.7q\n"
             "         ^\n"
             "%s:1:1: note: included from here\n", tmpdir, p);
    assert_string_equal(out, want);
    free(out);
}

/* A UTF-8 byte-order mark at the start of a netlist (as editors on
 * Windows write) is skipped, and CRLF line ends read as LF; columns
 * count after the mark. */
static void test_byte_order_mark(void **state) {
    (void)state;
    Circuit *c = load_ok("t.wdn", "\xef\xbb\xbf.voice bom\r\n.input in\r\n" SRC "R1 a b 1k\r\nC1 b 0 1u\r\n"
                                  ".output y v(b)\r\n");
    assert_string_equal(c->name, "bom");
    expect_error("\xef\xbb\xbf.voyce bom\n", "t.wdn:1:1: error: unknown directive '.voyce'");
}

/* A long line is shown 100 bytes about the column, "..." where it is cut,
 * with the caret under the column. */
static void test_long_line(void **state) {
    (void)state;
    char text[400];
    int n = snprintf(text, sizeof text, ".input in\n" SRC "R1 a 0 {");
    for (int i = 0; i < 40; i++)
        n += snprintf(text + n, sizeof text - (size_t)n, "1 + ");
    snprintf(text + n, sizeof text - (size_t)n, "q + 2 + 3 + 4 + 5 + 6 + 7 + 8 + 9 + 10 + 11 + 12 + 13 + 14 + 15}\n");
    char *out = load_fails(text);
    char want[512];
    snprintf(want, sizeof want,
             "t.wdn:3:169: error: unknown param 'q'\n"
             "  ...%.60sq + 2 + 3 + 4 + 5 + 6 + 7 + 8 + 9 + 10 +...\n"
             "  %*s^\n", "1 + 1 + 1 + 1 + 1 + 1 + 1 + 1 + 1 + 1 + 1 + 1 + 1 + 1 + 1 + ", 63, "");
    assert_string_equal(out, want);
    free(out);
}

/* ---- good inputs ---- */

static void test_spice_numbers(void **state) {
    (void)state;
    Circuit *c = load_ok("t.wdn", ".input in\n" SRC
                                  "R1 a b 4.7k\nR2 b 0 1meg\nC1 a 0 10uF\nL1 b 0 2.2n\n"
                                  "R3 a 0 1e-3\nR4 a 0 4.7kOhm\nR5 a 0 1MEG\nC2 a 0 1.5pF\n"
                                  "L2 a 0 10mH\nR6 a 0 .5\nR7 a 0 2.5e+3\nC3 a 0 3f\nR8 a 0 1G\n"
                                  "R9 a 0 R={2*(1k+500)}\nR10 a 0 1T\nR11 a 0 1000mil\n");
    check_value(c, "R1", 4700);
    check_value(c, "R2", 1e6);
    check_value(c, "C1", 1e-5);
    check_value(c, "L1", 2.2e-9);
    check_value(c, "R3", 1e-3);
    check_value(c, "R4", 4700);
    check_value(c, "R5", 1e6);
    check_value(c, "C2", 1.5e-12);
    check_value(c, "L2", 1e-2);
    check_value(c, "R6", 0.5);
    check_value(c, "R7", 2500);
    check_value(c, "C3", 3e-15);
    check_value(c, "R8", 1e9);
    check_value(c, "R9", 3000);
    check_value(c, "R10", 1e12);
    check_value(c, "R11", 1000 * 25.4e-6); /* SPICE's mil, a thousandth of an inch */
}

static void test_comments_and_continuations(void **state) {
    (void)state;
    Circuit *c = load_ok("t.wdn", "* a SPICE comment line\n"
                                  "   * also one, indented\n"
                                  ".input in # the drive\n"
                                  "\n"
                                  "V1 a 0 in ; another comment\n"
                                  "R1 a\n"
                                  "+ b\n"
                                  "  + 2.2k\n"
                                  "C1 b gnd 1u # gnd is ground\n"
                                  "C2 b GND 1u\n"
                                  ".output o v(b,gnd)\n"
                                  ".end\n"
                                  "this line is after .end and is ignored\n");
    assert_int_equal(c->nelems, 4);
    check_value(c, "R1", 2200);
    assert_int_equal(elem_named(c, "C1")->n[1], 0);
    assert_int_equal(elem_named(c, "C2")->n[1], 0);
    assert_int_equal(elem_named(c, "R1")->n[1], node_named(c, "b"));
    assert_int_equal(c->nouts, 1);
    assert_int_equal(c->outs[0].n[1], 0);
}

static void test_params(void **state) {
    (void)state;
    Circuit *c = load_ok("t.wdn", ".param x=2k\n.param g = 0.5 min=0.1 max=1 unit=V/V\n"
                                  ".input in\n" SRC "R1 a b {x}\nR2 b 0 R={x*g+1k}\n");
    assert_int_equal(c->nparams, 2);
    assert_string_equal(c->params[0].name, "x");
    assert_true(c->params[0].def == 2000);
    assert_string_equal(c->params[1].unit, "V/V");
    assert_true(c->params[1].min == 0.1 && c->params[1].max == 1);
    check_value(c, "R1", 2000);
    check_value(c, "R2", 2000);
}

static void test_blocks(void **state) {
    (void)state;
    Circuit *c = load_ok("t.wdn", ".block rc in out R=1k C=1u\n"
                                  "R1 in out {R}\n"
                                  "C1 out 0 {C}\n"
                                  ".endblock\n"
                                  ".block two in out R=2k\n"
                                  "use rc A in mid R={R}\n"
                                  "use rc B mid out C=2u\n"
                                  ".endblock\n"
                                  ".param rr 3k min=1 max=10k\n"
                                  ".input in\n" SRC
                                  "use two T1 a b R={rr}\n"
                                  "R9 b 0 1k\n"
                                  ".output o v(b)\n"
                                  ".output i i(T1.B.R1)\n");
    check_value(c, "T1.A.R1", 3000);
    check_value(c, "T1.A.C1", 1e-6);
    check_value(c, "T1.B.R1", 1000);
    check_value(c, "T1.B.C1", 2e-6);
    assert_int_equal(elem_named(c, "T1.A.R1")->n[0], node_named(c, "a"));
    assert_int_equal(elem_named(c, "T1.A.R1")->n[1], node_named(c, "T1.mid"));
    assert_int_equal(elem_named(c, "T1.B.C1")->n[0], node_named(c, "b"));
    assert_int_equal(c->nouts, 2);
    assert_int_equal(c->outs[1].elem, (int)(elem_named(c, "T1.B.R1") - c->elems));
}

static void test_models(void **state) {
    (void)state;
    Circuit *c = load_ok("t.wdn", ".domain mechanical\n"
                                  ".model heavy mass m=40m\n"
                                  ".model stiff spring k=20k\n"
                                  ".input f\n"
                                  "force F1 a 0 f\n"
                                  "mass M1 a model=heavy\n"
                                  "mass M2 b model=heavy m=10m\n"
                                  "spring K1 a 0 model=stiff\n"
                                  "spring K2 a b model=stiff\n");
    check_value(c, "M1", 40e-3);
    check_value(c, "M2", 10e-3);
    check_value(c, "K1", 1 / 20e3);
}

static void test_include_block_file(void **state) {
    (void)state;
    write_tmp("lib.wdn", "# a library of blocks\n"
                         ".block divider top mid R=1k\n"
                         "R1 top mid {R}\n"
                         "R2 mid 0 {R}\n"
                         ".endblock\n");
    const char *top = write_tmp("top.wdn", ".include \"lib.wdn\"\n"
                                           ".input in\n" SRC
                                           "use divider D1 a m R=10k\n"
                                           "C1 m 0 1u\n"
                                           ".output o v(m)\n");
    Capture cap;
    capture_begin(&cap);
    Circuit *c = wdc_load(top);
    char *out = capture_end(&cap);
    if (!c || out[0])
        fail_msg("%s", out);
    free(out);
    check_value(c, "D1.R1", 1e4);
    check_value(c, "D1.R2", 1e4);
    /* the example netlist that includes ../blocks/sprung_mass.wdn */
    capture_begin(&cap);
    c = wdc_load("netlists/chain3.wdn");
    out = capture_end(&cap);
    if (!c || out[0])
        fail_msg("%s", out);
    free(out);
    elem_named(c, "S2.K");
}

/* ---- bin/wdc ---- */

static void test_cli_voltage_loop(void **state) {
    (void)state;
    const char *p = write_tmp("vloop.wdn", ".input in\n.input in2\nV1 a 0 in\nV2 a 0 in2\nR1 a 0 1k\n");
    char path[256], args[512], want[1024];
    snprintf(path, sizeof path, "%s", p);
    snprintf(args, sizeof args, "'%s' --check", path);
    char *out;
    assert_int_equal(run_wdc(args, &out), 1);
    char *line = first_line(out);
    snprintf(want, sizeof want,
             "%s:3:1: error: the ideal sources 'V1', 'V2' cannot all hold: voltage sources form a "
             "loop or current sources a cut-set (give one a series or parallel resistance, R=)", path);
    assert_string_equal(line, want);
    free(line);
    free(out);
}

static void test_cli_exit_status(void **state) {
    (void)state;
    char *out;
    assert_int_equal(run_wdc("", &out), 2);
    assert_non_null(strstr(out, "no netlist given"));
    free(out);
    assert_int_equal(run_wdc("netlists/rc_lowpass.wdn --frobnicate", &out), 2);
    assert_non_null(strstr(out, "wdc: error: unknown option '--frobnicate'\nusage: wdc FILE.wdn"));
    assert_null(strstr(out, "exit status:")); /* the synopsis, not the whole help */
    free(out);
    assert_int_equal(run_wdc("--check", &out), 2);
    free(out);
    /* --check writes nothing: a render or a folder asked with it is refused, not dropped */
    assert_int_equal(run_wdc("netlists/rc_lowpass.wdn --check --render /tmp/never.wav", &out), 2);
    assert_non_null(strstr(out, "--check writes nothing"));
    free(out);
    /* --dot alone writes no voice; with -o DIR, the voice as well */
    char dargs[512], dpath[512];
    snprintf(dargs, sizeof dargs, "netlists/rc_lowpass.wdn --dot %s/rc.dot -o %s/dotvoice", tmpdir, tmpdir);
    assert_int_equal(run_wdc(dargs, &out), 0);
    free(out);
    snprintf(dpath, sizeof dpath, "%s/dotvoice/rc_lowpass.c", tmpdir);
    assert_int_equal(access(dpath, R_OK), 0);
    assert_int_equal(run_wdc("netlists/rc_lowpass.wdn netlists/msd.wdn --check", &out), 2);
    free(out);
    const char *bad = write_tmp("bad_cli.wdn", "R1 a 0 4.7q\n");
    char args[512];
    snprintf(args, sizeof args, "'%s' --check", bad);
    assert_int_equal(run_wdc(args, &out), 1);
    free(out);

    glob_t g;
    assert_int_equal(glob("netlists/*.wdn", 0, NULL, &g), 0);
    assert_true(g.gl_pathc > 0);
    for (size_t i = 0; i < g.gl_pathc; i++) {
        snprintf(args, sizeof args, "'%s' --check", g.gl_pathv[i]);
        int st = run_wdc(args, &out);
        if (st != 0 || out[0])
            fail_msg("wdc %s: status %d\n%s", args, st, out);
        free(out);
    }
    globfree(&g);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_unknown_kind),
        cmocka_unit_test(test_unknown_directive),
        cmocka_unit_test(test_malformed_numbers),
        cmocka_unit_test(test_bad_expressions),
        cmocka_unit_test(test_node_counts),
        cmocka_unit_test(test_unknown_keys),
        cmocka_unit_test(test_duplicates),
        cmocka_unit_test(test_case),
        cmocka_unit_test(test_undefined_params),
        cmocka_unit_test(test_undefined_models),
        cmocka_unit_test(test_undefined_blocks),
        cmocka_unit_test(test_probes),
        cmocka_unit_test(test_unterminated),
        cmocka_unit_test(test_missing_values),
        cmocka_unit_test(test_values),
        cmocka_unit_test(test_not_supported_yet),
        cmocka_unit_test(test_graph),
        cmocka_unit_test(test_dangling_resistors),
        cmocka_unit_test(test_unread_input),
        cmocka_unit_test(test_facing_diodes),
        cmocka_unit_test(test_deck),
        cmocka_unit_test(test_deck_sources),
        cmocka_unit_test(test_include_cycles),
        cmocka_unit_test(test_spice_numbers), cmocka_unit_test(test_long_line), cmocka_unit_test(test_byte_order_mark),
        cmocka_unit_test(test_comments_and_continuations),
        cmocka_unit_test(test_params),
        cmocka_unit_test(test_blocks),
        cmocka_unit_test(test_models),
        cmocka_unit_test(test_include_block_file),
        cmocka_unit_test(test_cli_voltage_loop),
        cmocka_unit_test(test_cli_facing_diodes),
        cmocka_unit_test(test_cli_deck_op),
        cmocka_unit_test(test_cli_spice_flag),
        cmocka_unit_test(test_cli_exit_status),
    };
    return cmocka_run_group_tests(tests, make_tmpdir, remove_tmpdir);
}
