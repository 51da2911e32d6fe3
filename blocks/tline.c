/* tline.c: T NAME a a' b b' Z0= TD=: a lossless transmission line; the
 * wave that enters one port leaves the other TD seconds later, each port
 * of resistance Z0.  Its delay, in whole samples, decouples what it joins. */
#include "lower.h"

static const KindKey keys[] = {{"Z0", "ohm"}, {"TD", "s"}, {NULL, NULL}};

static Elem *lower(Lower *L, Line *l, const int *node) {
    KeyVal *z = lower_key(l, "Z0"), *td = lower_key(l, "TD");
    if (!z || !td)
        error_at(l->namepos, "transmission line '%s' needs Z0= and TD=", l->name);
    double z0 = lower_const(&z->val, "Z0="), d = lower_const(&td->val, "TD=");
    if (!(z0 > 0))
        error_at(z->val.pos, "Z0 must be positive");
    if (!(d > 0) || d > 10)
        error_at(td->val.pos, "TD must lie between 0 and 10 s");
    double rate = lower_rate(L);
    if (!(d * rate >= 0.5))
        error_at(td->val.pos, "TD = %g s is shorter than half a sample at %g Hz: a line needs at least one "
                 "sample of delay", d, rate);
    int first = lower_nelems(L);
    Elem *e1 = lower_elem(L, l, E_W, ".1", node[0], node[1]);
    Elem *e2 = lower_elem(L, l, E_W, ".2", node[2], node[3]);
    e1->val = e2->val = expr_num(z0, z->val.pos);
    e1->td = e2->td = d;
    e1->peer = first + 1;
    e2->peer = first;
    if (node[0] == node[1] || node[2] == node[3])
        error_at(l->args[node[0] == node[1] ? 0 : 2].pos, "transmission line '%s' has both terminals of a "
                 "port on one node", l->name);
    return NULL;
}

const Kind kind_tline = {
    .desc = "transmission line",
    .letter = 'T',
    .nnodes = 4,
    .args = "",
    .keys = keys,
    .ready = true,
    .law = "a wave entering one port leaves the other TD later; each port v = Z0 i for its waves",
    .lowers_to = "two E_W, NAME.1 (a, a') and NAME.2 (b, b'), each the other's peer",
    .lower = lower,
};
