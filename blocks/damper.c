/* damper.c: damper NAME x y c=N*s/m: by the mobility analogy a resistor,
 * R = 1/c. */
#include "lower.h"

static const KindKey keys[] = {{"c", "N*s/m"}, {NULL, NULL}};

static Elem *lower(Lower *L, Line *l, const int *node) {
    Elem *e = lower_elem(L, l, E_R, "", node[0], node[1]);
    e->val = lower_recip(lower_need(L, l, "c"));
    return e;
}

const Kind kind_damper = {
    .desc = "damper",
    .keyword = "damper",
    .nnodes = 2,
    .args = "",
    .keys = keys,
    .ready = true,
    .law = "F = c v (a resistor, R = 1/c)",
    .lowers_to = "E_R",
    .lower = lower,
};
