/* string.c: string NAME a b L= f0= [mu=|T=] [B=] [t60= [t60hf=] [fhf=]]
 * [taps=NODE@FRACTION,...]: a stiff string from end a to end b (an end on
 * node 0 is fixed rigidly), velocity and force by the mobility analogy.
 * Partial n sits at n f0 sqrt((1 + B n^2) / (1 + B)); its port is
 * 1 / sqrt(T mu). */
#include <math.h>

#include "lower.h"

static const KindKey keys[] = {
    {"L", "m"}, {"f0", "Hz"}, {"mu", "kg/m"}, {"T", "N"}, {"t60", "s"}, {"t60hf", "s"}, {"fhf", "Hz"},
    {"B", ""}, {"taps", ""}, {NULL, NULL},
};

static void spec(Lower *L, Line *l, Waveguide *w, double len) {
    SrcPos pos = l->namepos;
    w->term[0] = w->term[1] = 'r';
    w->f0 = lower_need(L, l, "f0");
    w->B = lower_key_or(L, l, "B", 0);
    double Bmin = lower_expr_min(L, w->B, lower_key(l, "B") ? lower_key(l, "B")->val.pos : pos, "B");
    if (!(Bmin >= 0) || !isfinite(Bmin))
        error_at(lower_key(l, "B")->val.pos, "string '%s' has B = %g; the stiffness must be at least 0", l->name, Bmin);
    KeyVal *mu = lower_key(l, "mu"), *T = lower_key(l, "T");
    if (mu && T)
        error_at(T->pos, "string '%s': give mu= or T=, not both (f0 and L fix the other)", l->name);
    /* c = 2 L f0 / sqrt(1 + B); Z = mu c or T / c; the port is 1 / Z */
    Expr *cw = expr_bin(EX_DIV, expr_bin(EX_MUL, expr_num(2 * len, pos), w->f0),
                        expr_call(FN_SQRT, expr_bin(EX_ADD, expr_num(1, pos), w->B), NULL));
    Expr *Z = T ? expr_bin(EX_DIV, lower_value(L, &T->val, "T"), cw)
                : expr_bin(EX_MUL, mu ? lower_value(L, &mu->val, "mu") : expr_num(1e-3, pos), cw);
    w->Rp = expr_bin(EX_DIV, expr_num(1, pos), Z);
}

static Elem *lower(Lower *L, Line *l, const int *node) {
    lower_waveguide(L, l, node, false, spec);
    return NULL;
}

const Kind kind_string = {
    .desc = "string",
    .keyword = "string",
    .nnodes = 2,
    .args = "",
    .keys = keys,
    .ready = true,
    .law = "mu d2y/dt2 = T d2y/dx2 with stiffness B (partial n at n f0 sqrt((1 + B n^2) / (1 + B))); "
           "a travelling wave's force is sqrt(T mu) times its velocity",
    .lowers_to = "a Waveguide, and an E_S to ground per side of each point joined to the network "
                 "(NAME.a, NAME.TAP.l, NAME.TAP.r, NAME.b)",
    .lower = lower,
};
