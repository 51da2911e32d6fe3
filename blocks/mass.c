/* mass.c: mass NAME x m=KG: by the mobility analogy a capacitor from x
 * to ground, C = m. */
#include "lower.h"

static const KindKey keys[] = {{"m", "kg"}, {NULL, NULL}};

static Elem *lower(Lower *L, Line *l, const int *node) {
    Elem *e = lower_elem(L, l, E_C, "", node[0], 0);
    e->val = lower_need(L, l, "m");
    return e;
}

const Kind kind_mass = {
    .desc = "mass",
    .keyword = "mass",
    .nnodes = 1,
    .args = "",
    .keys = keys,
    .ready = true,
    .law = "F = m dv/dt (a capacitor to ground, C = m)",
    .lowers_to = "E_C to ground",
    .lower = lower,
};
