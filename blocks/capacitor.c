/* capacitor.c: C NAME a b VALUE [IC=V], in F; i = C dv/dt.  Given as
 * C NAME a b curve=(v0:q0 v1:q1 ...) it is nonlinear: q = curve(v). */
#include "lower.h"

static const KindKey keys[] = {{"C", "F"}, {"IC", "V"}, {"ic", "V"}, {"curve", "V:C"}, {NULL, NULL}};

static Elem *lower(Lower *L, Line *l, const int *node) {
    if (lower_curve_reactance(L, l, node, "C", 'C'))
        return NULL;
    return lower_linear(L, l, node, E_C, "C");
}

const Kind kind_capacitor = {
    .desc = "capacitor",
    .letter = 'C',
    .nnodes = 2,
    .args = "v",
    .keys = keys,
    .ready = true,
    .law = "i = C dv/dt; with curve=, q = curve(v)",
    .lowers_to = "E_C; with curve=, E_NL (NL_CURVE) behind an R-C mutator",
    .lower = lower,
};
