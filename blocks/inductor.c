/* inductor.c: L NAME a b VALUE [IC=A], in H; v = L di/dt. */
#include "lower.h"

static const KindKey keys[] = {{"L", "H"}, {"IC", "A"}, {"ic", "A"}, {NULL, NULL}};

static Elem *lower(Lower *L, Line *l, const int *node) { return lower_linear(L, l, node, E_L, "L"); }

const Kind kind_inductor = {
    .desc = "inductor",
    .letter = 'L',
    .nnodes = 2,
    .args = "v",
    .keys = keys,
    .ready = true,
    .law = "v = L di/dt",
    .lowers_to = "E_L",
    .lower = lower,
};
