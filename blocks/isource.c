/* isource.c: I NAME a b DRIVE [R=]: the drive flows from a through the
 * source to b, R in parallel. */
#include "lower.h"

static const KindKey keys[] = {{"R", "ohm"}, {NULL, NULL}};

static Elem *lower(Lower *L, Line *l, const int *node) { return lower_source(L, l, E_I, node[0], node[1]); }

const Kind kind_isource = {
    .desc = "current source",
    .letter = 'I',
    .nnodes = 2,
    .args = "d",
    .keys = keys,
    .ready = true,
    .law = "i = drive from a through the source to b, R in parallel",
    .lowers_to = "E_I",
    .lower = lower,
};
