/* velocity.c: velocity NAME x y DRIVE: v(x) - v(y) = drive, in m/s; by
 * the mobility analogy an ideal voltage source. */
#include "lower.h"

static const KindKey keys[] = {{NULL, NULL}};

static Elem *lower(Lower *L, Line *l, const int *node) { return lower_source(L, l, E_V, node[0], node[1]); }

const Kind kind_velocity = {
    .desc = "velocity source",
    .keyword = "velocity",
    .nnodes = 2,
    .args = "d",
    .keys = keys,
    .ready = true,
    .law = "v(x) - v(y) = drive (an ideal voltage source)",
    .lowers_to = "E_V, ideal",
    .lower = lower,
};
