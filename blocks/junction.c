/* junction.c: junction NAME series|parallel nodes...: an explicit series
 * or parallel junction.  Parsed and refused as not supported yet. */
#include "lower.h"

static const KindKey keys[] = {{NULL, NULL}};

const Kind kind_junction = {
    .desc = "explicit junction",
    .keyword = "junction",
    .nnodes = -1,
    .args = "t",
    .keys = keys,
    .ready = false,
    .law = "Kirchhoff's laws of a series or a parallel connection",
    .lowers_to = "nothing yet",
};
