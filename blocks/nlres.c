/* nlres.c: nlres NAME a b curve=(v0:i0 v1:i1 ...) [solver=pwl]: a
 * nonlinear resistor, i = curve(v), linear between its points (passive,
 * non-decreasing, through the origin); its piecewise-linear wave map
 * solves it exactly. */
#include "lower.h"

static const KindKey keys[] = {{"curve", "V:A"}, {"solver", ""}, {NULL, NULL}};

static Elem *lower(Lower *L, Line *l, const int *node) {
    Elem *e = lower_elem(L, l, E_NL, "", node[0], node[1]);
    NlSpec *nl = lower_nl(l, NL_CURVE);
    lower_curve(l, nl);
    lower_only_solver(nl, SOLVER_PWL, "a curve given by points is solved exactly by its piecewise-linear wave "
                                      "map: use solver=pwl");
    e->nl = nl;
    return e;
}

const Kind kind_nlres = {
    .desc = "nonlinear resistor",
    .keyword = "nlres",
    .nnodes = 2,
    .args = "",
    .keys = keys,
    .ready = true,
    .law = "i = curve(v)",
    .lowers_to = "E_NL (NL_CURVE)",
    .lower = lower,
};
