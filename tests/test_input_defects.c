/*
 * test_input_defects.c - inputs the front end once mishandled (issue 14,
 * item 6): the -delab dump of waveguides, files that are not netlists
 * (devices, FIFOs, huge files), voice names that collide with the ABI or
 * C, a voltage source with R=0, and drives and initial conditions too
 * large for the voice's arithmetic.
 *
 * Diagnostics are compared verbatim, first line only, as in test_parse.c.
 * Commands run bin/wdc ($WDC overrides the path) under a time limit and a
 * memory limit, so a regression fails instead of hanging or exhausting
 * the machine.  Tests run from the repository root.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "testlib.h"

static char tmpdir[64];

static int make_tmpdir(void **state) {
    (void)state;
    return tl_temp_dir(tmpdir, "wdc-indef");
}

static int remove_tmpdir(void **state) {
    (void)state;
    tl_remove_dir(tmpdir);
    return 0;
}

static const char *wdc_path(void) {
    const char *w = getenv("WDC");
    return w && *w ? w : "bin/wdc";
}

/* Runs bin/wdc with args (shell words) for at most 20 s and 2 GB of
 * address space; *out gets stdout and stderr (free it).  Returns the exit
 * status, 124 on the time limit, or -1 if a signal ended it. */
static int run_wdc(const char *args, char **out) {
    const char *cmd = format("ulimit -v 2000000; timeout 20 %s %s 2>&1", wdc_path(), args);
    FILE *p = popen(cmd, "r");
    assert_non_null(p);
    size_t cap = 4096, n = 0, k;
    char *buf = malloc(cap);
    assert_non_null(buf);
    while ((k = fread(buf + n, 1, cap - n - 1, p)) > 0) {
        n += k;
        if (n + 1 == cap) {
            buf = realloc(buf, cap *= 2);
            assert_non_null(buf);
        }
    }
    buf[n] = '\0';
    int st = pclose(p);
    *out = buf;
    return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

/* First line of s, in the arena. */
static const char *first_line(const char *s) { return arena_strndup(s, strcspn(s, "\n")); }

/* Loads text as "t.wdn"; returns the circuit (NULL on an error) and in
 * *report the first line printed. */
static Circuit *load(const char *text, const char **report) { return tl_netlist_load(text, report); }

/* text must be refused, its first line of diagnostics exactly want. */
static void expect_error(const char *text, const char *want) {
    const char *got;
    if (load(text, &got))
        fail_msg("netlist accepted, expected an error:\n%s", text);
    if (strcmp(got, want))
        fail_msg("netlist:\n%s\nexpected: %s\n     got: %s", text, want, got);
}

static Circuit *expect_ok(const char *text) {
    const char *got;
    Circuit *c = load(text, &got);
    if (!c || got[0])
        fail_msg("netlist:\n%s\nrefused: %s", text, got);
    return c;
}

static const char *write_tmp(const char *name, const char *text) {
    return arena_strdup(tl_write_file(tmpdir, name, text));
}

/* ---- 1. the -delab dump names every element's kind ---- */

#define STRING_NET                                                                                           \
    ".voice s\n.domain mechanical\n.input f\n"                                                             \
    "string S1 0 0 L=0.6 f0=220 t60=2 taps=p@0.1,o@0.3\n"                                                 \
    "force F1 p 0 f\n.output vel v(o)\n"

static void test_dump_waveguide(void **state) {
    (void)state;
    Circuit *c = expect_ok(STRING_NET);
    char *buf = NULL;
    size_t len = 0;
    FILE *f = open_memstream(&buf, &len);
    assert_non_null(f);
    circuit_dump(c, f);
    fclose(f);
    /* a header line, then one line per element, each with its kind */
    int lines = 0;
    for (const char *q = buf; *q; q++)
        lines += *q == '\n';
    assert_int_equal(lines, c->nelems + 1);
    assert_null(strstr(buf, "(null)"));
    const char *want[] = {"  S S1.p.l p 0 ", "  S S1.p.r p 0 ", "  S S1.o.l o 0 ", "  S S1.o.r o 0 ",
                          "  I F1 0 p <- f\n"};
    for (size_t i = 0; i < sizeof want / sizeof want[0]; i++)
        if (!strstr(buf, want[i]))
            fail_msg("no line '%s' in the dump:\n%s", want[i], buf);
    free(buf);

    /* the same through the command line, a tube too */
    char *out;
    assert_int_equal(run_wdc("netlists/bore.wdn -delab --check", &out), 0);
    assert_null(strstr(out, "(null)"));
    assert_non_null(strstr(out, "\n  S "));
    free(out);

    /* controlled sources and their probes, a transistor's sources, a
     * transformer's winding */
    static const struct {
        const char *args, *want[2];
    } decks[] = {
        {"netlists/tubescreamer.cir -delab --check", {"\n  E e1 out 0 1e+06\n", "\n  P e1.in in n\n"}},
        {"netlists/fuzzface.cir -delab --check", {"\n  F q1.f c1 b1 0.997506\n", "\n  NL q1.be b1 0\n"}},
        {"tests/nets/xfmr_neg.cir -delab --check", {"\n  XF k1.l1 l1.x 0 -2\n", "\n  L l2.m l2.x 0 0.00225\n"}},
    };
    for (size_t d = 0; d < sizeof decks / sizeof decks[0]; d++) {
        assert_int_equal(run_wdc(decks[d].args, &out), 0);
        for (int k = 0; k < 2; k++)
            if (!strstr(out, decks[d].want[k]))
                fail_msg("%s: no line '%s' in the dump:\n%s", decks[d].args, decks[d].want[k], out);
        free(out);
    }
}

/* ---- 2. files that are not netlists ---- */

static void test_special_files(void **state) {
    (void)state;
    char *out;
    /* a device without end: refused at once, not read until memory runs out */
    assert_int_equal(run_wdc("/dev/zero --check", &out), 1);
    assert_string_equal(first_line(out), "/dev/zero: error: the netlist is not a regular file");
    free(out);

    /* a FIFO: refused without waiting for a writer */
    const char *fifo = format("%s/fifo.wdn", tmpdir);
    assert_int_equal(mkfifo(fifo, 0600), 0);
    assert_int_equal(run_wdc(format("'%s' --check", fifo), &out), 1);
    assert_string_equal(first_line(out), format("%s: error: the netlist is not a regular file", fifo));
    free(out);

    /* a directory */
    assert_int_equal(run_wdc(format("'%s' --check", tmpdir), &out), 1);
    assert_string_equal(first_line(out), format("%s: error: the netlist is not a regular file", tmpdir));
    free(out);

    /* a regular file over the limit (sparse: no disk is used) */
    const char *big = format("%s/big.wdn", tmpdir);
    assert_int_equal(truncate(write_tmp("big.wdn", ""), (16 << 20) + 1), 0);
    assert_int_equal(run_wdc(format("'%s' --check", big), &out), 1);
    assert_string_equal(first_line(out), format("%s: error: the netlist is larger than 16 MiB", big));
    free(out);

    /* a missing file names itself too */
    assert_int_equal(run_wdc(format("'%s/none.wdn' --check", tmpdir), &out), 1);
    assert_string_equal(first_line(out),
                        format("%s/none.wdn: error: cannot read the netlist: No such file or directory", tmpdir));
    free(out);

    /* at an .include: the error is at the file name's position */
    const char *inc = write_tmp("inc.wdn", ".input in\nV1 a 0 in\nR1 a 0 1k\n.include \"/dev/zero\"\n");
    assert_int_equal(run_wdc(format("'%s' --check", inc), &out), 1);
    assert_string_equal(first_line(out),
                        format("%s:4:10: error: included file '/dev/zero' is not a regular file", inc));
    free(out);
    inc = write_tmp("incbig.wdn", ".input in\nV1 a 0 in\nR1 a 0 1k\n.include \"big.wdn\"\n");
    assert_int_equal(run_wdc(format("'%s' --check", inc), &out), 1);
    assert_string_equal(first_line(out), format("%s:4:10: error: included file 'big.wdn' is larger than 16 MiB", inc));
    free(out);
}

/* ---- 3. voice names ---- */

#define BODY ".input in\nV1 a 0 in\nR1 a b 1k\nC1 b 0 1u\n.output o v(b)\n"

static void test_voice_names(void **state) {
    (void)state;
    static const struct { const char *name, *why; } bad[] = {
        {"wdvoice", "would write its header over the voice ABI's, wdvoice.h"},
        {"wdv", "would define wdv_class, the voice ABI's own type"},
        {"wdv_x", "takes the voice ABI's prefix wdv_"},
        {"WDV_x", "takes the voice ABI's prefix wdv_"},
        {"wdrt_osc", "takes the runtime's prefix wdrt_"},
        {"int", "is a C keyword"},
        {"static", "is a C keyword"},
        {"double", "is a C keyword"},
        {"_Bool", "is a C keyword"},
        {"_x", "starts with '_' (such C names are reserved)"},
        {"manifest", "would write its LV2 description over the bundle's manifest.ttl"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++)
        expect_error(format(".voice %s\n" BODY, bad[i].name),
                     format("t.wdn:1:8: error: voice name '%s' %s", bad[i].name, bad[i].why));
    expect_ok(".voice wdvoice2\n" BODY);
    expect_ok(".voice integer\n" BODY);

    /* a name taken from the file is not the user's choice: made safe */
    char *out;
    const char *net = write_tmp("int.wdn", BODY);
    const char *dir = format("%s/int.out", tmpdir);
    assert_int_equal(run_wdc(format("'%s' -o '%s'", net, dir), &out), 0);
    free(out);
    struct stat st;
    assert_int_equal(stat(format("%s/v_int.c", dir), &st), 0);
    assert_int_equal(tl_system(format("cc -std=c99 -Wall -Wextra -Werror -pedantic -c '%s/v_int.c' -o '%s/v_int.o'",
                                      dir, dir)), 0);
    net = write_tmp("wdvoice.wdn", BODY);
    dir = format("%s/wdvoice.out", tmpdir);
    assert_int_equal(run_wdc(format("'%s' -o '%s'", net, dir), &out), 0);
    free(out);
    assert_int_equal(tl_system(format("cc -std=c99 -Wall -Wextra -Werror -pedantic -c '%s/v_wdvoice.c' -o "
                                      "'%s/v.o'", dir, dir)), 0);
}

/* ---- 4. V with R=0 is the ideal source ---- */

#define RC(vline)                                                                                             \
    ".voice rc\n.input in\n" vline "\nR1 in out 1k\nC1 out 0 100n\n.output out v(out)\n.output i i(V1)\n"

static void test_vsource_r0(void **state) {
    (void)state;
    Circuit *c = expect_ok(RC("V1 in 0 in R=0"));
    assert_int_equal(c->elems[0].kind, E_V);
    assert_null(c->elems[0].val); /* ideal, as without R= */
    expect_ok(RC("V1 in 0 in R={1-1}"));
    /* a source with a resistance stays one */
    c = expect_ok(RC("V1 in 0 in R=1"));
    assert_non_null(c->elems[0].val);
    /* a current source's parallel R=0 is a short: still refused */
    expect_error(".input in\nI1 0 a in R=0\nR1 a 0 1k\nC1 a 0 1u\n",
                 "t.wdn:2:1: error: current source 'I1' has resistance 0 at the default params; it must be "
                 "positive and finite");

    /* both forms compile, and render the same, sample for sample */
    const char *nets[2] = {write_tmp("ideal.wdn", RC("V1 in 0 in")), NULL};
    nets[1] = write_tmp("r0.wdn", RC("V1 in 0 in R=0"));
    enum { N = 2000 };
    double *y[2][2];
    for (int k = 0; k < 2; k++) {
        tl_voice v;
        assert_int_equal(tl_voice_build(nets[k], 0, &v), 0);
        void *st = tl_state_new(v.cls, 48000);
        double *in = calloc(N, sizeof(double));
        y[k][0] = calloc(N, sizeof(double));
        y[k][1] = calloc(N, sizeof(double));
        for (int n = 0; n < N; n++)
            in[n] = n < 100 ? 1 : sin(0.01 * n);
        const double *ins[1] = {in};
        double *outs[2] = {y[k][0], y[k][1]};
        v.cls->process(st, ins, outs, N);
        free(in);
        tl_state_free(st);
        tl_voice_free(&v);
    }
    for (int o = 0; o < 2; o++) {
        assert_buf_near(y[1][o], y[0][o], N, 0);
        free(y[0][o]);
        free(y[1][o]);
    }
}

/* ---- 5. drives and initial conditions within the voice's range ---- */

static void test_magnitudes(void **state) {
    (void)state;
    expect_error(".input in\nV1 a 0 in\nR1 a b 1k\nC1 b 0 100n IC=1e308\n",
                 "t.wdn:4:16: error: the initial voltage of capacitor 'C1' is 1e+308 V; its magnitude must not "
                 "exceed 1e+15 V");
    expect_error(".input in\nV1 a 0 in\nR1 a b 1k\nL1 b 0 1m IC=-2e15\n",
                 "t.wdn:4:14: error: the initial current of inductor 'L1' is -2e+15 A; its magnitude must not "
                 "exceed 1e+15 A");
    expect_error(".input in\nV1 a 0 in\nR1 a b 1k\nC1 b 0 1u\n.ic v(b)=1e308\n",
                 "t.wdn:5:10: error: the initial condition v(b) is 1e+308 V; its magnitude must not exceed 1e+15 V");
    expect_error(".domain mechanical\nmass M1 m m=1\nspring K1 m 0 k=1k\n.ic x(m)={1e300*1e300}\n",
                 "t.wdn:4:11: error: the initial condition x(m) is inf m; its magnitude must not exceed 1e+15 m");
    expect_error("V1 a 0 1e308\nR1 a b 1k\nC1 b 0 1u\n",
                 "t.wdn:1:8: error: the drive of voltage source 'V1' is 1e+308 V; its magnitude must not exceed "
                 "1e+15 V");
    expect_error(".domain mechanical\n.param F 1 min=0 max=1e20\nforce F1 m 0 {F}\nmass M1 m m=1\n"
                 "damper B1 m 0 c=1\n",
                 "t.wdn:3:15: error: the drive of force source 'F1' reaches 1e+20 N when param 'F' = 1e+20; its "
                 "magnitude must not exceed 1e+15 N (narrow the param's range)");
    expect_error(".param v 0 min=-1 max=1\nV1 a 0 {sqrt(v)}\nR1 a 0 1k\n",
                 "t.wdn:2:9: error: the drive of voltage source 'V1' is not a number when param 'v' = -1; its "
                 "magnitude must not exceed 1e+15 V (narrow the param's range)");

    /* at the limit, in single precision, the voice stays finite */
    const char *net = write_tmp("big_ic.wdn", ".input in\nV1 a 0 in\nR1 a b 1k\nC1 b 0 100n IC=1e15\n"
                                              "L1 b c 1m IC=1e15\nR2 c 0 1\n.output o v(b)\n.output i i(L1)\n");
    tl_voice v;
    assert_int_equal(tl_voice_build(net, 1, &v), 0);
    void *st = tl_state_new(v.cls, 48000);
    enum { N = 4800 };
    double *in = calloc(N, sizeof(double)), *o0 = calloc(N, sizeof(double)), *o1 = calloc(N, sizeof(double));
    const double *ins[1] = {in};
    double *outs[2] = {o0, o1};
    v.cls->process(st, ins, outs, N);
    for (int n = 0; n < N; n++)
        if (!isfinite(o0[n]) || !isfinite(o1[n]))
            fail_msg("sample %d is not finite: %g %g", n, o0[n], o1[n]);
    assert_true(fabs(o0[0]) > 1e12);
    free(in);
    free(o0);
    free(o1);
    tl_state_free(st);
    tl_voice_free(&v);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_dump_waveguide), cmocka_unit_test(test_special_files),
        cmocka_unit_test(test_voice_names),    cmocka_unit_test(test_vsource_r0),
        cmocka_unit_test(test_magnitudes),
    };
    return cmocka_run_group_tests(tests, make_tmpdir, remove_tmpdir);
}
