/* vsource.c: V NAME a b DRIVE [R=]: v(a) - v(b) = drive across its ideal
 * part, R in series; ideal without R or with R=0. */
#include "lower.h"

static const KindKey keys[] = {{"R", "ohm"}, {NULL, NULL}};

static Elem *lower(Lower *L, Line *l, const int *node) { return lower_source(L, l, E_V, node[0], node[1]); }

const Kind kind_vsource = {
    .desc = "voltage source",
    .letter = 'V',
    .nnodes = 2,
    .args = "d",
    .keys = keys,
    .ready = true,
    .law = "v(a) - v(b) = drive + R i",
    .lowers_to = "E_V (val NULL: ideal)",
    .lower = lower,
};
