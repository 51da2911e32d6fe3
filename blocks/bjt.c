/* bjt.c: Q NAME c b e MODEL [Is= BF= BR= NF= NR= Vt=]: a bipolar
 * transistor, Ebers-Moll (injection form), its keys from .model MODEL
 * NPN|PNP (...) where the line gives none.  For an NPN, with
 * aF = BF / (1 + BF) and aR = BR / (1 + BR):
 *
 *   iF = Is / aF (exp(vBE / (NF Vt)) - 1)    the base-emitter junction
 *   iR = Is / aR (exp(vBC / (NR Vt)) - 1)    the base-collector junction
 *   iC = aF iF - iR,  iE = iF - aR iR,  iB = iE - iC
 *
 * It lowers to the two junctions as diodes (NAME.be from b to e, NAME.bc
 * from b to c) and two current-controlled sources, aF iF from c to b
 * (NAME.f) and aR iR from e to b (NAME.r); a PNP has each turned round.
 * The junctions meet at the base with no delay between them, so they are
 * solved jointly at their root, whose equations the sources stamp. */
#include <string.h>
#include <strings.h>

#include "lower.h"

static const KindKey keys[] = {{"Is", "A"}, {"BF", ""}, {"BR", ""}, {"NF", ""}, {"NR", ""}, {"Vt", "V"},
                               {NULL, NULL}};

/* A gain BF or BR: a constant, positive. */
static double beta(Line *l, const char *k, double def) {
    KeyVal *kv = lower_key(l, k);
    if (!kv)
        return def;
    double b = lower_const(&kv->val, k);
    if (!(b > 0 && b < 1e9))
        error_at(kv->val.pos, "%s= of transistor '%s' must lie between 0 and 1e9", k, l->name);
    return b;
}

static Elem *junction(Lower *L, Line *l, Line *src, const char *suffix, int a, int k, Expr *Is, const char *nkey,
                      double alpha) {
    Elem *e = lower_elem(L, l, E_NL, suffix, a, k);
    NlSpec *nl = lower_nl(src, NL_DIODE);
    nl->Is = expr_bin(EX_DIV, Is, expr_num(alpha, l->pos));
    nl->n = lower_key_or(L, src, nkey, 1);
    nl->Vt = lower_key_or(L, src, "Vt", lower_vt(L, l));
    e->nl = nl;
    return e;
}

static Elem *lower(Lower *L, Line *l, const int *node) {
    const Value *mv = &l->args[3];
    Line *m = lower_model(L, mv);
    if (m->model_kind != BK_Q)
        error_at(mv->pos, "model '%s' is not a transistor model", mv->name);
    bool pnp = !strcasecmp(m->args[0].name, "pnp");
    Line *src = lower_model_keys(l, m);
    if (lower_key(src, "solver"))
        error_at(lower_key(src, "solver")->pos, "a transistor's junctions are solved jointly: solver= does not apply");
    double bf = beta(src, "BF", 100), br = beta(src, "BR", 1);
    double af = bf / (1 + bf), ar = br / (1 + br);
    Expr *Is = lower_key_or(L, src, "Is", 1e-16);
    int c = node[0], b = node[1], e = node[2];
    if (b == c || b == e || c == e)
        error_at(l->pos, "transistor '%s' has two terminals on one node", l->name);
    /* NPN: junctions from the base; PNP: into it */
    junction(L, l, src, ".be", pnp ? e : b, pnp ? b : e, Is, "NF", af);
    junction(L, l, src, ".bc", pnp ? c : b, pnp ? b : c, Is, "NR", ar);
    Elem *f = lower_elem(L, l, E_CC, ".f", pnp ? b : c, pnp ? c : b);
    Elem *r = lower_elem(L, l, E_CC, ".r", pnp ? b : e, pnp ? e : b);
    f->val = expr_num(af, l->pos);
    r->val = expr_num(ar, l->pos);
    return NULL;
}

const Kind kind_bjt = {
    .desc = "transistor",
    .letter = 'Q',
    .nnodes = 3,
    .args = "m",
    .keys = keys,
    .ready = true,
    .law = "Ebers-Moll: iC = aF iF - iR, iE = iF - aR iR, iF = Is/aF (exp(vBE/(NF Vt)) - 1), "
           "iR = Is/aR (exp(vBC/(NR Vt)) - 1), aF = BF/(1+BF), aR = BR/(1+BR); a PNP with signs turned",
    .lowers_to = "E_NL NAME.be and NAME.bc (NL_DIODE), E_CC NAME.f and NAME.r",
    .lower = lower,
};
