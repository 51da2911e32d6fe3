/* mutator.c: mutator NAME a b c d type=RC|RL: the diode or nonlinear
 * resistor across (c, d), alone there, appears at (a, b) as a nonlinear
 * capacitor (RC: q = g(v)) or inductor (RL: i = g(flux)).  Elaboration
 * applies it once every element is lowered. */
#include <string.h>

#include "lower.h"

static const KindKey keys[] = {{"type", ""}, {NULL, NULL}};

static Elem *lower(Lower *L, Line *l, const int *node) {
    Mutator *m = arena_alloc(sizeof(Mutator));
    KeyVal *t = lower_key(l, "type");
    const char *ty = t && t->val.kind == VAL_NAME ? t->val.name : "";
    if (!t || (strcmp(ty, "RC") && strcmp(ty, "RL")))
        error_at(t ? t->val.pos : l->namepos, "mutator '%s' needs type=RC or type=RL", l->name);
    m->name = format("%s%s", lower_prefix(L), l->name);
    for (int i = 0; i < 4; i++)
        m->n[i] = node[i];
    m->type = ty[1];
    m->pos = l->namepos;
    m->line = l;
    if (node[0] == node[1] || node[2] == node[3])
        error_at(l->args[node[0] == node[1] ? 0 : 2].pos, "mutator '%s' has both terminals of a port on one "
                 "node", l->name);
    lower_add_mutator(L, m);
    return NULL;
}

const Kind kind_mutator = {
    .desc = "mutator",
    .keyword = "mutator",
    .nnodes = 4,
    .args = "",
    .keys = keys,
    .ready = true,
    .law = "RC: q(a, b) = g(v(a, b)); RL: i(a, b) = g(flux(a, b)), g the law across (c, d)",
    .lowers_to = "the E_NL across (c, d), moved to (a, b) and named NAME",
    .lower = lower,
};
