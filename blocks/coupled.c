/* coupled.c: coupled inductors.
 *
 *   K NAME L1 L2 k    inductors L1 and L2 share flux: their mutual
 *                     inductance is M = k sqrt(L1 L2), 0 < |k| <= 1, the
 *                     first node of each being its dotted end
 *
 * As in SPICE, a K line names the inductors, not nodes, and may come
 * before them.  Elaboration (elab.c, couple) takes each group of
 * inductors that K lines join as the windings of one core: a magnetising
 * inductance across the first winding, an ideal transformer (E_XF) from
 * it to each other winding, and each winding's leakage in series. */
#include <math.h>

#include "lower.h"

static Elem *lower(Lower *L, Line *l, const int *node) {
    (void)node;
    Coupling *k = arena_alloc(sizeof(Coupling));
    k->name = format("%s%s", lower_prefix(L), l->name);
    for (int j = 0; j < 2; j++) {
        const Value *v = &l->args[j];
        if (v->kind != VAL_NAME)
            error_at(v->pos, "coupling '%s' needs the names of two inductors before its coefficient", l->name);
        k->ind[j] = format("%s%s", lower_prefix(L), v->name);
        k->indpos[j] = v->pos;
    }
    k->k = lower_const(&l->args[2], format("the coefficient of coupling '%s'", l->name));
    k->kpos = l->args[2].pos;
    if (!(fabs(k->k) <= 1) || k->k == 0)
        error_at(k->kpos, "coupling '%s' has coefficient %g: it must lie in [-1, 1] and not be 0", l->name, k->k);
    k->line = l;
    lower_add_coupling(L, k);
    return NULL;
}

static const KindKey no_keys[] = {{NULL, NULL}};

const Kind kind_coupling = {
    .desc = "coupling",
    .letter = 'K',
    .nnodes = 0,
    .args = "mmv",
    .keys = no_keys,
    .ready = true,
    .law = "M = k sqrt(L1 L2) between inductors L1 and L2",
    .lowers_to = "per group of coupled windings: E_L leakages NAME, E_L L1.m, E_XF K.L2 with E_P K.L2.in",
    .lower = lower,
};
