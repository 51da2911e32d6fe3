/* contact.c: contact NAME x y k= [alpha= lambda= gap= solver=newton]: a
 * one-sided power-law felt (Hunt-Crossley); while the compression
 * X = x(x) - x(y) - gap is positive it pushes y forward and x back with
 * F = k X^alpha (1 + lambda dX/dt).  Its compression is state, so Newton
 * solves it. */
#include "lower.h"

static const KindKey keys[] = {
    {"k", "N/m^alpha"}, {"alpha", ""}, {"lambda", "s/m"}, {"gap", "m"}, {"solver", ""}, {NULL, NULL},
};

static Elem *lower(Lower *L, Line *l, const int *node) {
    Elem *e = lower_elem(L, l, E_NL, "", node[0], node[1]);
    NlSpec *nl = lower_nl(l, NL_CONTACT);
    nl->k = lower_need(L, l, "k");
    nl->alpha = lower_key_or(L, l, "alpha", 1);
    nl->lambda = lower_key_or(L, l, "lambda", 0);
    nl->gap = lower_key_or(L, l, "gap", 0);
    lower_only_solver(nl, SOLVER_NEWTON, "a contact has memory (its compression): only solver=newton applies");
    e->nl = nl;
    return e;
}

const Kind kind_contact = {
    .desc = "contact",
    .keyword = "contact",
    .nnodes = 2,
    .args = "",
    .keys = keys,
    .ready = true,
    .law = "F = k X^alpha (1 + lambda dX/dt) for X = x(x) - x(y) - gap > 0, else 0",
    .lowers_to = "E_NL (NL_CONTACT)",
    .lower = lower,
};
