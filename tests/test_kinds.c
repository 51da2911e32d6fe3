/*
 * test_kinds.c - the element kinds' descriptors (blocks/).
 *
 * Every descriptor says what it is, how a line of its kind is written
 * (keyword or SPICE letter, nodes, positional arguments, keys with their
 * units), its law and what it lowers to, and an implemented kind has a
 * lowering; the registry finds each kind by its keyword or letter.  Each
 * kind's lowering is checked on a small netlist: the primitive elements
 * it adds, their nodes and values at the default params.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>
#include <math.h>
#include <string.h>

#include "testlib.h"

/* ---- descriptors ---- */

static void test_descriptors(void **state) {
    (void)state;
    for (int k = 0; k < BK_COUNT; k++) {
        const Kind *d = block_desc[k].kind;
        assert_non_null(d);
        assert_ptr_equal(block_desc[k].desc, d->desc);
        assert_true(d->desc[0]);
        assert_true((d->keyword != NULL) != (d->letter != 0));
        assert_true(d->nnodes >= -1 && d->nnodes <= 4);
        assert_non_null(d->args);
        assert_int_equal(strspn(d->args, "vdmt"), strlen(d->args));
        assert_non_null(d->law);
        assert_true(d->law[0]);
        assert_non_null(d->lowers_to);
        assert_true(d->lowers_to[0]);
        /* `use` is instantiated, not lowered; a kind not implemented has no lowering */
        assert_true(d->lower ? d->ready && k != BK_USE : !d->ready || k == BK_USE);
        for (const KindKey *key = d->keys; key->name; key++) {
            assert_non_null(key->unit);
            assert_true(block_has_key(k, key->name));
        }
        assert_false(block_has_key(k, "model"));
    }
}

/* The stamps of a primitive name only what the printer gives ($a $b $e
 * $R $x; a line end's $o $p $k $m; a waveguide port's $a $o $p $m $d $q)
 * and close every parenthesis; what stores between samples has all its
 * stamps, what keeps a buffer reflects from it (and a line end counts its
 * energy), and only what joins a root adaptor reflects nothing of its
 * own.  line: 1 a line end, 2 a waveguide port, else 0. */
static void stamp_ok(const char *t, int line) {
    if (!t)
        return;
    int depth = 0;
    for (const char *p = t; *p; p++) {
        depth += *p == '(' ? 1 : *p == ')' ? -1 : 0;
        assert_true(depth >= 0);
        if (*p == '$') {
            assert_non_null(strchr(line == 2 ? "aopmdq" : line ? "abeRxopkm" : "abeRx", p[1]));
            assert_true(p[1] != 0);
        }
    }
    assert_int_equal(depth, 0);
}

static void test_primitives(void **state) {
    (void)state;
    for (int k = E_R; k <= E_XF; k++) {
        const Prim *p = &prims[k];
        assert_non_null(p->name);
        assert_non_null(p->law);
        int line = p->wd == WD_DELAY ? 1 : p->wd == WD_WAVEGUIDE ? 2 : 0;
        const char *st[] = {p->reflect, p->absorb, p->stored, p->energy, p->struck};
        for (int j = 0; j < 5; j++)
            stamp_ok(st[j], line);
        if (p->state)
            assert_true(p->reflect && p->stored && p->energy && p->struck && (p->strike == 'v' || p->strike == 'x'));
        if (p->absorb) /* a waveguide's energy is its lines', not its ports' */
            assert_true(p->reflect && (p->energy || line == 2) && strstr(p->absorb, "$a"));
        assert_true((p->reflect == NULL) == (p->wd == WD_ROOT));
        assert_true((p->absorb != NULL) == (line > 0));
    }
}

static void test_registry(void **state) {
    (void)state;
    for (int k = 0; k < BK_COUNT; k++) {
        const Kind *d = block_desc[k].kind;
        if (d->keyword)
            assert_int_equal(block_by_keyword(d->keyword, (int)strlen(d->keyword)), k);
        else
            assert_int_equal(block_by_letter((char)(d->letter - 'A' + 'a')), k);
    }
    assert_int_equal(block_by_keyword("massx", 4), BK_MASS);
    assert_int_equal(block_by_keyword("mas", 3), -1);
    assert_int_equal(block_by_letter('X'), -1);
}

/* ---- lowerings ---- */

/* The circuit of a netlist that must load. */
static Circuit *load(const char *text) {
    const char *report;
    Circuit *c = tl_netlist_load(text, &report);
    if (!c)
        fail_msg("%s\n%s", text, report);
    return c;
}

/* The element named name, which c must hold. */
static const Elem *elem(const Circuit *c, const char *name) {
    for (int i = 0; i < c->nelems; i++)
        if (!strcmp(c->elems[i].name, name))
            return &c->elems[i];
    fail_msg("no element '%s'", name);
    return NULL;
}

/* e is of kind k from node a to node b, of value val (when val is not NAN). */
static void check(const Circuit *c, const Elem *e, ElemKind k, const char *a, const char *b, double val) {
    assert_int_equal(e->kind, k);
    assert_string_equal(c->nodes[e->n[0]], a);
    assert_string_equal(c->nodes[e->n[1]], b);
    if (!isnan(val))
        assert_float_equal(elem_value(c, e, circuit_defaults(c)), val, 1e-12 * fabs(val));
}

static void test_electrical(void **state) {
    (void)state;
    Circuit *c = load(".input in\nV1 a 0 in R=50\nR1 a b 1k\nC1 b 0 C=1u IC=0.5\nL1 b d 2m\nR2 d 0 10\n"
                      "I1 d 0 in\nV2 e 0 1 R=0\nR3 e 0 1\n");
    check(c, elem(c, "V1"), E_V, "a", "0", 50);
    check(c, elem(c, "R1"), E_R, "a", "b", 1e3);
    const Elem *c1 = elem(c, "C1");
    check(c, c1, E_C, "b", "0", 1e-6);
    assert_float_equal(expr_eval(c1->ic, NULL), 0.5, 0);
    check(c, elem(c, "L1"), E_L, "b", "d", 2e-3);
    check(c, elem(c, "I1"), E_I, "d", "0", NAN);
    assert_null(elem(c, "V2")->val); /* R=0: the ideal source */
}

static void test_mechanical(void **state) {
    (void)state;
    Circuit *c = load(".domain mechanical\n.input f\nforce F1 a b f\nmass M1 a m=2\nspring K1 a b k=400\n"
                      "damper B1 b 0 c=0.5\nmass M2 b m=1\nvelocity U1 d 0 0.1\ndamper B2 d 0 c=1\n");
    check(c, elem(c, "F1"), E_I, "b", "a", NAN); /* pushes a: current from b into a */
    check(c, elem(c, "M1"), E_C, "a", "0", 2);
    check(c, elem(c, "K1"), E_L, "a", "b", 1.0 / 400);
    check(c, elem(c, "B1"), E_R, "b", "0", 2);
    check(c, elem(c, "U1"), E_V, "d", "0", NAN);
}

static void test_pot_and_line(void **state) {
    (void)state;
    Circuit *c = load(".input in\nV1 a 0 in R=1k\npot P1 a w 0 R=10k pos=0.25\nT1 w 0 c 0 Z0=600 TD=1m\n"
                      "R2 c 0 600\n");
    check(c, elem(c, "P1.aw"), E_R, "a", "w", 7.5e3);
    check(c, elem(c, "P1.wb"), E_R, "w", "0", 2.5e3);
    const Elem *t1 = elem(c, "T1.1"), *t2 = elem(c, "T1.2");
    check(c, t1, E_W, "w", "0", 600);
    check(c, t2, E_W, "c", "0", 600);
    assert_ptr_equal(&c->elems[t1->peer], t2);
    assert_ptr_equal(&c->elems[t2->peer], t1);
    assert_float_equal(t1->td, 1e-3, 0);
}

/* E, G and opamp: an output and a probe each, peers of each other even
 * when elements before them leave (a facing diode taken into a pair). */
static void test_controlled(void **state) {
    (void)state;
    Circuit *c = load(".input in\n.model DM D Is=2e-12\nV1 a 0 in R=1k\nD1 a 0 DM\nD2 0 a DM\nE1 b 0 a 0 2.5\n"
                      "R2 b n 1k\nG1 n 0 b 0 1m\nopamp U1 o a n\nR3 o n 10k\n");
    const Elem *e1 = elem(c, "E1"), *g1 = elem(c, "G1"), *u1 = elem(c, "U1");
    check(c, e1, E_CV, "b", "0", NAN);
    check(c, g1, E_CI, "n", "0", NAN);
    check(c, u1, E_OA, "o", "0", NAN);
    assert_float_equal(expr_eval(e1->val, NULL), 2.5, 0);
    assert_float_equal(expr_eval(g1->val, NULL), 1e-3, 0);
    assert_null(u1->val);
    check(c, elem(c, "E1.in"), E_P, "a", "0", NAN);
    check(c, elem(c, "G1.in"), E_P, "b", "0", NAN);
    check(c, elem(c, "U1.in"), E_P, "a", "n", NAN);
    for (const char *const *nm = (const char *const[]){"E1", "G1", "U1", NULL}; *nm; nm++) {
        const Elem *o = elem(c, *nm), *p = &c->elems[o->peer];
        assert_int_equal(p->kind, E_P);
        assert_ptr_equal(&c->elems[p->peer], o);
    }
}

static void test_nonlinear(void **state) {
    (void)state;
    Circuit *c = load(".input in\n.model DM D Is=2e-12 n=1.5\nV1 a 0 in R=1k\nD1 a b DM pair=1\nR2 b 0 1k\n"
                      "T1 b 0 c 0 Z0=600 TD=1m\nnlres N1 c 0 curve=(-1:-1m 0:0 1:1m)\n"
                      "T2 c 0 d 0 Z0=600 TD=1m\nC1 d 0 curve=(-1:-1u 0:0 1:1u)\n");
    const Elem *d1 = elem(c, "D1"), *n1 = elem(c, "N1"), *c1 = elem(c, "C1");
    check(c, d1, E_NL, "a", "b", NAN);
    assert_int_equal(d1->nl->kind, NL_DIODE);
    assert_true(d1->nl->pair);
    assert_float_equal(expr_eval(d1->nl->Is, NULL), 2e-12, 0);
    assert_int_equal(n1->nl->kind, NL_CURVE);
    assert_int_equal(n1->nl->solver, SOLVER_PWL);
    assert_int_equal(n1->nl->npts, 3);
    assert_int_equal(c1->nl->kind, NL_CURVE);
    assert_int_equal(c1->nl->mutated, 'C');
}

static void test_contact_and_mutator(void **state) {
    (void)state;
    Circuit *c = load(".domain mechanical\n.input f\nforce F1 a 0 f\nmass M1 a m=1\n"
                      "contact H1 a b k=4e9 alpha=2.5\nmass M2 b m=1\n");
    const Elem *h1 = elem(c, "H1");
    check(c, h1, E_NL, "a", "b", NAN);
    assert_int_equal(h1->nl->kind, NL_CONTACT);
    assert_int_equal(h1->nl->solver, SOLVER_NEWTON);
    c = load(".input in\n.model DM D\nV1 a 0 in R=1k\nmutator X1 a 0 c d type=RL\nD1 c d DM\n");
    const Elem *x1 = elem(c, "X1");
    check(c, x1, E_NL, "a", "0", NAN);
    assert_int_equal(x1->nl->mutated, 'L');
    assert_int_equal(c->nelems, 2); /* the diode moved to the mutator's first port */
}

static void test_waveguides(void **state) {
    (void)state;
    Circuit *c = load(".domain mechanical\n.input f\nforce F1 h 0 f\n"
                      "string S1 0 b L=0.5 f0=200 T=100 taps=h@0.25\nmass M1 b m=1\n");
    assert_int_equal(c->nwgs, 1);
    assert_int_equal(c->wgs[0].ntaps, 1);
    /* c = 2 L f0 = 200 m/s; the port is 1 / Z = c / T */
    check(c, elem(c, "S1.h.l"), E_S, "h", "0", 2.0);
    check(c, elem(c, "S1.h.r"), E_S, "h", "0", 2.0);
    check(c, elem(c, "S1.b"), E_S, "b", "0", 2.0);
    c = load(".domain acoustic\n.input f\nI1 a 0 f R=1k\ntube W1 a 0 L=0.6 r=10m ends=closed\n");
    assert_true(c->wgs[0].tube);
    assert_int_equal(c->wgs[0].term[1], 'c');
    check(c, elem(c, "W1.a"), E_S, "a", "0", 1.204 * 343.2 / (M_PI * 1e-4));
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_descriptors),
        cmocka_unit_test(test_primitives),
        cmocka_unit_test(test_registry),
        cmocka_unit_test(test_electrical),
        cmocka_unit_test(test_mechanical),
        cmocka_unit_test(test_pot_and_line),
        cmocka_unit_test(test_controlled),
        cmocka_unit_test(test_nonlinear),
        cmocka_unit_test(test_contact_and_mutator),
        cmocka_unit_test(test_waveguides),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
