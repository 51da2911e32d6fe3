/* controlled.c: linear controlled sources and the ideal op-amp.
 *
 *   E NAME a b c d GAIN    v(a) - v(b) = GAIN (v(c) - v(d))
 *   G NAME a b c d GM      GM (v(c) - v(d)) flows a -> b through it
 *   opamp NAME out p n     v(p) = v(n), out driven against ground with
 *                          whatever current holds them equal
 *
 * Each lowers to its output (E_CV, E_CI, E_OA) and a probe (E_P) across
 * the controlling pair, which draws no current.  Both join one root
 * adaptor, whose nodal equations they stamp; the gain is a constant. */
#include "lower.h"

static Elem *controlled(Lower *L, Line *l, ElemKind k, int a, int b, int c, int d) {
    if (c == d)
        error_at(l->pos, "%s '%s' is controlled by the voltage between a node and itself", block_desc[l->kind].desc,
                 l->name);
    /* each is the other's peer, which elaboration sets by name once
     * the elements are final */
    Elem *e = lower_elem(L, l, k, "", a, b);
    lower_elem(L, l, E_P, ".in", c, d);
    return e;
}

static Elem *lower_gain(Lower *L, Line *l, const int *node, ElemKind k) {
    const Value *arg = lower_arg(l); /* the parser asks for it */
    Expr *g = lower_value(L, arg, "the gain");
    if (expr_params(g))
        error_at(arg->pos, "the gain of %s '%s' must be a constant, not a param", block_desc[l->kind].desc,
                 l->name);
    lower_magnitude(L, g, arg->pos, format("the gain of %s '%s'", block_desc[l->kind].desc, l->name),
                    k == E_CV ? "" : "S");
    Elem *e = controlled(L, l, k, node[0], node[1], node[2], node[3]);
    e->val = g;
    return e;
}

static Elem *lower_e(Lower *L, Line *l, const int *node) { return lower_gain(L, l, node, E_CV); }
static Elem *lower_g(Lower *L, Line *l, const int *node) { return lower_gain(L, l, node, E_CI); }

static Elem *lower_oa(Lower *L, Line *l, const int *node) {
    if (node[0] == 0)
        error_at(l->pos, "op-amp '%s' has its output at ground", l->name);
    return controlled(L, l, E_OA, node[0], 0, node[1], node[2]);
}

static const KindKey no_keys[] = {{NULL, NULL}};

const Kind kind_vcvs = {
    .desc = "controlled source",
    .letter = 'E',
    .nnodes = 4,
    .args = "v",
    .keys = no_keys,
    .ready = true,
    .law = "v(a) - v(b) = gain (v(c) - v(d))",
    .lowers_to = "E_CV from a to b and E_P NAME.in from c to d",
    .lower = lower_e,
};

const Kind kind_vccs = {
    .desc = "controlled source",
    .letter = 'G',
    .nnodes = 4,
    .args = "v",
    .keys = no_keys,
    .ready = true,
    .law = "gain (v(c) - v(d)) flows a -> b through it",
    .lowers_to = "E_CI from a to b and E_P NAME.in from c to d",
    .lower = lower_g,
};

const Kind kind_opamp = {
    .desc = "op-amp",
    .keyword = "opamp",
    .nnodes = 3,
    .args = "",
    .keys = no_keys,
    .ready = true,
    .law = "v(p) = v(n); out supplies any current",
    .lowers_to = "E_OA from out to ground and E_P NAME.in from p to n",
    .lower = lower_oa,
};
