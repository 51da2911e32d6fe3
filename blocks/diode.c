/* diode.c: D NAME a k MODEL [Is= n= Vt= pair=1 solver=]: a Shockley
 * diode, its keys from .model MODEL D ... where the line gives none;
 * i = Is (exp(v / (n Vt)) - 1), or 2 Is sinh(v / (n Vt)) for an
 * antiparallel pair. */
#include "lower.h"

static const KindKey keys[] = {{"Is", "A"}, {"n", ""}, {"Vt", "V"}, {"pair", ""}, {"solver", ""}, {NULL, NULL}};

static Elem *lower(Lower *L, Line *l, const int *node) {
    const Value *mv = &l->args[2];
    Line *m = lower_model(L, mv);
    if (m->model_kind != BK_D)
        error_at(mv->pos, "model '%s' is not a diode model", mv->name);
    Elem *e = lower_elem(L, l, E_NL, "", node[0], node[1]);
    Line *src = lower_model_keys(l, m);
    NlSpec *nl = lower_nl(src, NL_DIODE);
    nl->Is = lower_key_or(L, src, "Is", 1e-14);
    nl->n = lower_key_or(L, src, "n", 1);
    nl->Vt = lower_key_or(L, src, "Vt", lower_vt(L, l));
    KeyVal *pk = lower_key(src, "pair");
    if (pk) {
        double pv = lower_const(&pk->val, "pair=");
        if (pv != 0 && pv != 1)
            error_at(pk->val.pos, "pair= takes 0 or 1");
        nl->pair = pv == 1;
    }
    e->nl = nl;
    return e;
}

const Kind kind_diode = {
    .desc = "diode",
    .letter = 'D',
    .nnodes = 2,
    .args = "m",
    .keys = keys,
    .ready = true,
    .law = "i = Is (exp(v / (n Vt)) - 1); a pair: i = 2 Is sinh(v / (n Vt))",
    .lowers_to = "E_NL (NL_DIODE)",
    .lower = lower,
};
