/* force.c: force NAME x y DRIVE: pushes x forward and y back with the
 * drive, in N; by the mobility analogy a current source. */
#include "lower.h"

static const KindKey keys[] = {{NULL, NULL}};

/* a force on x from y injects current into x: it flows y -> x */
static Elem *lower(Lower *L, Line *l, const int *node) { return lower_source(L, l, E_I, node[1], node[0]); }

const Kind kind_force = {
    .desc = "force source",
    .keyword = "force",
    .nnodes = 2,
    .args = "d",
    .keys = keys,
    .ready = true,
    .law = "F = drive on x, -drive on y (a current source from y to x)",
    .lowers_to = "E_I from y to x",
    .lower = lower,
};
