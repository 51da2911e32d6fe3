/* resistor.c: R NAME a b VALUE (or R=VALUE), in ohm; v(a) - v(b) = R i. */
#include "lower.h"

static const KindKey keys[] = {{"R", "ohm"}, {NULL, NULL}};

static Elem *lower(Lower *L, Line *l, const int *node) { return lower_linear(L, l, node, E_R, "R"); }

const Kind kind_resistor = {
    .desc = "resistor",
    .letter = 'R',
    .nnodes = 2,
    .args = "v",
    .keys = keys,
    .ready = true,
    .law = "v = R i",
    .lowers_to = "E_R",
    .lower = lower,
};
