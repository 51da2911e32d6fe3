/* coupled.c: coupled inductors.
 *
 *   K NAME L1 L2 k    inductors L1 and L2 share flux: their mutual
 *                     inductance is M = k sqrt(L1 L2), 0 < |k| <= 1, the
 *                     first node of each being its dotted end
 *   K NAME L1 L2 L3... k
 *                     every pair of them so (LTspice's form)
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
    int n = l->nargs - 1; /* the inductors; the coefficient comes last */
    if (n < 2)
        error_at(l->args[0].pos, "coupling '%s' needs the names of two inductors before its coefficient", l->name);
    const Value *kv = &l->args[n];
    double k = lower_const(kv, format("the coefficient of coupling '%s'", l->name));
    if (!(fabs(k) <= 1) || k == 0)
        error_at(kv->pos, "coupling '%s' has coefficient %g: it must lie in [-1, 1] and not be 0", l->name, k);
    for (int a = 0; a < n; a++)
        for (int b = a + 1; b < n; b++) {
            Coupling *c = arena_alloc(sizeof(Coupling));
            c->name = format("%s%s", lower_prefix(L), l->name);
            const Value *v[2] = {&l->args[a], &l->args[b]};
            for (int j = 0; j < 2; j++) {
                c->ind[j] = format("%s%s", lower_prefix(L), v[j]->name);
                c->indpos[j] = v[j]->pos;
            }
            c->k = k;
            c->kpos = kv->pos;
            c->line = l;
            lower_add_coupling(L, c);
        }
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
    .law = "M = k sqrt(Li Lj) between each pair of the inductors it names",
    .lowers_to = "per group of coupled windings: E_L leakages NAME, E_L L1.m, E_XF K.L2 with E_P K.L2.in",
    .lower = lower,
};
