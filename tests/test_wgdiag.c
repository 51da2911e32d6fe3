/*
 * test_wgdiag.c - diagnostics of strings and tubes, each with its line and
 * column: missing and contradictory keys, taps off the string, on ground,
 * twice or malformed, loops too short for their filters at the rate,
 * pitches that move without bounds, bad ends, a string that joins nothing.
 * Each netlist goes through the phases the command line runs (load,
 * structure, emit) until one reports.
 */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gen.h"
#include "testlib.h"

static void expect(const char *text, const char *want) {
    char *got = tl_first_report(text, SOLVER_DEFAULT);
    if (strcmp(got, want))
        fail_msg("netlist:\n%s\nexpected: %s\n     got: %s", text, want, got);
    free(got);
}

static void test_missing_f0(void **state) {
    (void)state;
    expect(".domain mechanical\nstring S1 0 0 L=0.6 taps=p@0.5\nR1 p 0 1k\n.end\n", "t.wdn:2:8: error: string 'S1' needs f0=");
}

static void test_missing_L(void **state) {
    (void)state;
    expect(".domain mechanical\nstring S1 0 0 f0=200 taps=p@0.5\nR1 p 0 1k\n.end\n", "t.wdn:2:8: error: string 'S1' needs L=");
}

static void test_mu_and_T(void **state) {
    (void)state;
    expect(".domain mechanical\nstring S1 0 0 L=0.6 f0=200 mu=1m T=50 taps=p@0.5\nR1 p 0 1k\n.end\n", "t.wdn:2:34: error: string 'S1': give mu= or T=, not both (f0 and L fix the other)");
}

static void test_tap_outside(void **state) {
    (void)state;
    expect(".domain mechanical\nstring S1 0 0 L=0.6 f0=200 taps=p@1.5\nR1 p 0 1k\n.end\n", "t.wdn:2:35: error: tap 'p' of string 'S1' is at 1.5 of its length; it must lie between 0 and 1");
}

static void test_tap_twice(void **state) {
    (void)state;
    expect(".domain mechanical\nstring S1 0 0 L=0.6 f0=200 taps=p@0.5,p@0.3\nR1 p 0 1k\n.end\n", "t.wdn:2:39: error: tap 'p' is given twice");
}

static void test_tap_malformed(void **state) {
    (void)state;
    expect(".domain mechanical\nstring S1 0 0 L=0.6 f0=200 taps=p0.5\nR1 p 0 1k\n.end\n", "t.wdn:2:33: error: taps= takes a list NODE@FRACTION,NODE@FRACTION,...");
}

static void test_tap_on_end(void **state) {
    (void)state;
    expect(".domain mechanical\nstring S1 0 p L=0.6 f0=200 taps=p@0.5\nR1 p 0 1k\n.end\n", "t.wdn:2:33: error: tap 'p' is also an end of string 'S1'");
}

static void test_tap_ground(void **state) {
    (void)state;
    expect(".domain mechanical\nstring S1 0 0 L=0.6 f0=200 taps=gnd@0.5\nR1 p 0 1k\nR2 p 0 1k\n.end\n", "t.wdn:2:33: error: a tap cannot be on ground (node 0)");
}

static void test_joins_nothing(void **state) {
    (void)state;
    expect(".domain mechanical\nstring S1 0 0 L=0.6 f0=200\n.end\n", "t.wdn:2:8: error: string 'S1' joins nothing: put an end on a node or give it taps=");
}

static void test_too_short(void **state) {
    (void)state;
    expect(".domain mechanical\nstring S1 0 0 L=0.6 f0=20k taps=p@0.5\nR1 p 0 1k\n.end\n", "t.wdn:2:8: error: string 'S1' is too short for its filters at 48000 Hz: its loop holds 2.40 samples and needs at least 5 (lower f0, or raise .rate)");
}

static void test_unbounded_f0(void **state) {
    (void)state;
    expect(".domain mechanical\n.param f 100\nstring S1 0 0 L=0.6 f0={f} taps=p@0.5\nR1 p 0 1k\n.end\n", "t.wdn:3:8: error: f0 depends on param 'f', which needs min= and max= (they size the delay lines)");
}

static void test_negative_B(void **state) {
    (void)state;
    expect(".domain mechanical\nstring S1 0 0 L=0.6 f0=200 B=-1 taps=p@0.5\nR1 p 0 1k\n.end\n", "t.wdn:2:30: error: string 'S1' has B = -1; the stiffness must be at least 0");
}

static void test_t60hf_alone(void **state) {
    (void)state;
    expect(".domain mechanical\nstring S1 0 0 L=0.6 f0=200 t60hf=1 taps=p@0.5\nR1 p 0 1k\n.end\n", "t.wdn:2:28: error: t60hf= needs t60= too");
}

static void test_both_ends_one_node(void **state) {
    (void)state;
    expect(".domain mechanical\nstring S1 a a L=0.6 f0=200\nR1 a 0 1k\n.end\n", "t.wdn:2:13: error: string 'S1' has both ends on one node");
}

static void test_L_param(void **state) {
    (void)state;
    expect(".domain mechanical\n.param x 1 min=0.5 max=2\nstring S1 0 a L={x} f0=200\nR1 a 0 1k\n.end\n", "t.wdn:3:18: error: L must be a positive number of metres");
}

static void test_tube_ends(void **state) {
    (void)state;
    expect(".domain mechanical\ntube W1 0 0 L=0.6 r=7m ends=open,shut taps=p@0.5\nR1 p 0 1k\n.end\n", "t.wdn:2:34: error: ends= takes open or closed, or two of them separated by a comma");
}

static void test_tube_radius(void **state) {
    (void)state;
    expect(".domain mechanical\ntube W1 0 0 L=0.6 taps=p@0.5\nR1 p 0 1k\n.end\n", "t.wdn:2:6: error: tube 'W1' needs r=");
}

static void test_tube_unknown_key(void **state) {
    (void)state;
    expect(".domain mechanical\ntube W1 0 0 L=0.6 r=7m f0=100 taps=p@0.5\nR1 p 0 1k\n.end\n", "t.wdn:2:24: error: unknown key 'f0' for tube 'W1'");
}

static void test_two_hammers_one_tap(void **state) {
    (void)state;
    expect(".domain mechanical\nstring S1 0 0 L=0.6 f0=200 taps=h@0.3\nmass M1 a m=5m\ncontact H1 a h k=1e9 alpha=2.5\n"
           "mass M2 b m=5m\ncontact H2 b h k=1e9 alpha=2.5\n.end\n",
           "t.wdn:4:9: error: contact 'H1' is coupled to 'H2' with no delay between them: a contact stores energy "
           "and is solved alone, so a delay element (a transmission line, string or tube) must part it from other "
           "nonlinear elements");
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_missing_f0),
        cmocka_unit_test(test_missing_L),
        cmocka_unit_test(test_mu_and_T),
        cmocka_unit_test(test_tap_outside),
        cmocka_unit_test(test_tap_twice),
        cmocka_unit_test(test_tap_malformed),
        cmocka_unit_test(test_tap_on_end),
        cmocka_unit_test(test_tap_ground),
        cmocka_unit_test(test_joins_nothing),
        cmocka_unit_test(test_too_short),
        cmocka_unit_test(test_unbounded_f0),
        cmocka_unit_test(test_negative_B),
        cmocka_unit_test(test_t60hf_alone),
        cmocka_unit_test(test_both_ends_one_node),
        cmocka_unit_test(test_L_param),
        cmocka_unit_test(test_tube_ends),
        cmocka_unit_test(test_tube_radius),
        cmocka_unit_test(test_tube_unknown_key),
        cmocka_unit_test(test_two_hammers_one_tap),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
