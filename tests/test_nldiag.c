/*
 * test_nldiag.c - diagnostics of nonlinear elements and transmission
 * lines, each with its line and column: coupled nonlinearities, a diode
 * across an ideal source, a diode with no closed path, bad curves, solver
 * choices, lines shorter than a sample.  Each netlist goes through the
 * phases the command line runs (load, structure, emit) until one reports.
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

#define MODEL ".model dd D Is=2.52n n=1.752\n"

static void test_coupled_nonlinearities(void **s) {
    (void)s;
    /* two diodes with no delay between them: solved jointly */
    expect(".input in\n" MODEL "V1 a 0 in R=1k\nD1 a 0 dd\nR2 a b 1k\nD2 b 0 dd\n", "");
    /* a contact stores energy: it is solved alone, so a diode or curve
     * coupled to it is refused at the contact, naming the other */
    expect(".domain mechanical\n.input f\nforce F1 a 0 f\nmass M1 a m=10m\ncontact K1 a b k=1e6 alpha=1.5\n"
           "mass M2 b m=20m\nspring S2 b 0 k=1k\nnlres N1 a b curve=(-1:-1 1:1)\n",
           "t.wdn:5:9: error: contact 'K1' is coupled to 'N1' with no delay between them: a contact stores "
           "energy and is solved alone, so a delay element (a transmission line, string or tube) must part it "
           "from other nonlinear elements");
    /* more than WD_JOINT_MAX at one root: refused at the first past it */
    expect(".input in\n" MODEL "V1 a 0 in R=1k\nD1 a 0 dd\nD2 a 0 dd\nD3 a 0 dd\nD4 a 0 dd\nD5 a 0 dd\n"
           "D6 a 0 dd\nD7 a 0 dd\nD8 a 0 dd\nD9 a 0 dd\n",
           "t.wdn:12:1: error: 'D9' makes 9 nonlinear elements coupled with no delay between them: at most 8 are "
           "solved jointly; a delay element (a transmission line, string or tube) would part them");
    /* a line between them decouples: accepted */
    expect(".input in\n" MODEL "V1 a 0 in R=1k\nD1 a 0 dd\nT1 a 0 b 0 Z0=100 TD=1m\nR2 b 0 1k\nD2 b 0 dd\n", "");
    /* sharing only ground is no coupling either */
    expect(".input in\n" MODEL "V1 a 0 in R=1k\nD1 a 0 dd\nI2 0 b in R=1k\nD2 b 0 dd\n", "");
}

static void test_unadaptable(void **s) {
    (void)s;
    expect(".input in\n" MODEL "V1 a 0 in\nD1 a 0 dd\nR1 a 0 1k\n",
           "t.wdn:4:1: error: diode 'D1' sits directly across an ideal source: nothing limits its current "
           "(put a resistance in series)");
    expect(".input in\n" MODEL "V1 a 0 in R=1k\nR1 a b 1k\nD1 b c dd\nR2 c 0 1k\nC1 b c 1u\nR3 a c 1k\n", "");
}

static void test_curves(void **s) {
    (void)s;
    expect(".input in\nV1 a 0 in R=1k\nnlres N1 a 0 curve=(-1:-1 0:0 1:0.5 2:0.2)\n",
           "t.wdn:3:39: error: curve currents must not decrease (a falling curve has no unique wave map)");
    expect(".input in\nV1 a 0 in R=1k\nnlres N1 a 0 curve=(-1:1 0:0 1:1)\n",
           "t.wdn:3:21: error: point -1:1 delivers power: a passive curve has v*i >= 0");
    expect(".input in\nV1 a 0 in R=1k\nnlres N1 a 0 curve=(-1:-1 1:3)\n",
           "t.wdn:3:20: error: the curve passes v = 0 at i = 1: a passive curve goes through the origin");
    expect(".input in\nV1 a 0 in R=1k\nnlres N1 a 0 curve=(0:0 0:1)\n",
           "t.wdn:3:25: error: curve voltages must increase from point to point");
    expect(".input in\nV1 a 0 in R=1k\nnlres N1 a 0 curve=(0:0)\n", "t.wdn:3:20: error: a curve needs at least two points");
    expect(".input in\nV1 a 0 in R=1k\nnlres N1 a 0 curve=(-1:-2 0:0 1:1) solver=newton\n",
           "t.wdn:3:43: error: a curve given by points is solved exactly by its piecewise-linear wave map: use "
           "solver=pwl");
}

static void test_solvers(void **s) {
    (void)s;
    expect(".ic v(h)=1\nmass M h m=10m\ncontact H1 h 0 k=1e9 alpha=2.5 solver=pwl\n",
           "t.wdn:3:39: error: a contact has memory (its compression): only solver=newton applies");
    expect(".input in\nV1 a 0 in R=1k\nnlres N1 a 0 curve=(-1:-1 1:1) solver=secant\n",
           "t.wdn:3:39: error: solver= takes fast, newton, omega or pwl");
    expect(".input in\n.param is 1n min=1p max=1u\nV1 a 0 in R=1k\nD1 a 0 dd solver=pwl\n.model dd D Is={is}\n",
           "t.wdn:4:1: error: diode 'D1': a piecewise-linear table is made at compile time, so Is, n and Vt must "
           "not depend on params (use solver=fast, newton or omega)");
    expect(".input in\nV1 a 0 in R=1k\nD1 a 0 dd\n.model dd D Is=0\n",
           "t.wdn:3:1: error: diode 'D1' has Is = 0; it must be greater than 0");
    /* n Vt past 1000 V would lose a volt in the solvers' error (n = 1e32 rendered silence) */
    expect(".input in\nV1 a 0 in R=1k\nD1 a 0 dd\n.model dd D n=1e32\n",
           "t.wdn:3:1: error: diode 'D1' has n = 1e+32; it must be greater than 0 and at most 1000");
    expect(".input in\nV1 a 0 in R=1k\nD1 a 0 dd\n.model dd D Vt=2\n",
           "t.wdn:3:1: error: diode 'D1' has Vt = 2; it must be greater than 0 and at most 1");
    expect(".ic v(h)=1\nmass M h m=10m\ncontact H1 h 0 k=1e9 alpha=0.5\n",
           "t.wdn:3:9: error: contact 'H1' has alpha = 0.5; it must be at least 1");
    expect(".input in\nV1 a 0 in R=1k\nD1 a 0 dd\n.model dd D pair=2\n", "t.wdn:4:18: error: pair= takes 0 or 1");
}

static void test_lines(void **s) {
    (void)s;
    expect(".input in\nV1 a 0 in R=1k\nT1 a 0 b 0 Z0=50 TD=1u\nR2 b 0 50\n",
           "t.wdn:3:21: error: TD = 1e-06 s is shorter than half a sample at 48000 Hz: a line needs at least one "
           "sample of delay");
    expect(".input in\nV1 a 0 in R=1k\nT1 a 0 b 0 Z0=50\nR2 b 0 50\n",
           "t.wdn:3:1: error: transmission line 'T1' needs Z0= and TD=");
    expect(".input in\nV1 a 0 in R=1k\nT1 a 0 b 0 Z0=-50 TD=1m\nR2 b 0 50\n", "t.wdn:3:15: error: Z0 must be positive");
    expect(".input in\n.param z 50\nV1 a 0 in R=1k\nT1 a 0 b 0 Z0={z} TD=1m\nR2 b 0 50\n",
           "t.wdn:4:16: error: Z0= must be a number (params are not known at compile time)");
}

/* springs and capacitors with a curve (the compiler's mutators) */
static void test_nonlinear_reactances(void **s) {
    (void)s;
    expect(".ic v(m)=1\nmass M m m=1m\nspring K m 0 k=1k curve=(-1m:-1 0:0 1m:1)\n",
           "t.wdn:3:19: error: spring 'K' takes a value or curve=, not both");
    expect(".ic v(m)=1\nmass M m m=1m\nspring K m 0 curve=(-1m:1 0:0 1m:1)\n",
           "t.wdn:3:21: error: point -0.001:1 delivers power: a passive curve has v*i >= 0");
    expect(".input in\nV1 a 0 in R=1k\nCX a 0 curve=(-1:-1u 0:0 1:1u) IC=1\n",
           "t.wdn:3:32: error: a nonlinear capacitor takes no IC= (a spring's stretch comes from .ic x(node); a "
           "capacitor starts at rest)");
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_nonlinear_reactances),
        cmocka_unit_test(test_coupled_nonlinearities), cmocka_unit_test(test_unadaptable),
        cmocka_unit_test(test_curves), cmocka_unit_test(test_solvers), cmocka_unit_test(test_lines),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
