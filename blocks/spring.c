/* spring.c: spring NAME x y k=N/m: by the mobility analogy an inductor,
 * L = 1/k.  Given as spring NAME x y curve=(x0:f0 x1:f1 ...) it is
 * nonlinear: force = curve(stretch). */
#include "lower.h"

static const KindKey keys[] = {{"k", "N/m"}, {"curve", "m:N"}, {NULL, NULL}};

static Elem *lower(Lower *L, Line *l, const int *node) {
    if (lower_curve_reactance(L, l, node, "k", 'L'))
        return NULL;
    Elem *e = lower_elem(L, l, E_L, "", node[0], node[1]);
    e->val = lower_recip(lower_need(L, l, "k"));
    return e;
}

const Kind kind_spring = {
    .desc = "spring",
    .keyword = "spring",
    .nnodes = 2,
    .args = "",
    .keys = keys,
    .ready = true,
    .law = "dF/dt = k v (an inductor, L = 1/k); with curve=, F = curve(x)",
    .lowers_to = "E_L; with curve=, E_NL (NL_CURVE) behind an R-L mutator",
    .lower = lower,
};
