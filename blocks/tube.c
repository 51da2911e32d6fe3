/* tube.c: tube NAME a b L= r= [ends=open|closed[,open|closed]] [t60=
 * [t60hf=] [fhf=]] [c=] [rho=] [taps=NODE@FRACTION,...]: a cylindrical
 * bore carrying pressure and volume flow (.domain acoustic) from end a to
 * end b.  An end on node 0 is open (radiating, lengthened by 0.6133 r) or
 * closed; its port is rho c / (pi r^2); without t60= its wall losses are
 * alpha = 3e-5 sqrt(f) / r nepers a metre. */
#include <math.h>
#include <string.h>

#include "lower.h"

static const KindKey keys[] = {
    {"L", "m"}, {"r", "m"}, {"t60", "s"}, {"t60hf", "s"}, {"fhf", "Hz"}, {"ends", ""}, {"c", "m/s"},
    {"rho", "kg/m^3"}, {"taps", ""}, {NULL, NULL},
};

/* ends=open|closed[,open|closed]: the terminations of ends a and b. */
static void ends(Line *l, Waveguide *w) {
    KeyVal *ek = lower_key(l, "ends");
    if (!ek)
        return;
    int n = 0;
    const Token *t = ek->val.kind == VAL_LIST ? ek->val.toks : NULL;
    int nt = ek->val.kind == VAL_LIST ? ek->val.ntoks : 0;
    const char *one = ek->val.kind == VAL_NAME ? ek->val.name : NULL;
    for (int i = 0; one ? i < 1 : i < nt; i += 2) {
        const char *v = one ? one : t[i].kind == TK_IDENT ? arena_strndup(t[i].text, (size_t)t[i].len) : "";
        SrcPos vp = one ? ek->val.pos : t[i].pos;
        if (!one && i + 1 < nt && t[i + 1].kind != TK_COMMA)
            error_at(t[i + 1].pos, "ends= takes open or closed, or two of them separated by a comma");
        if (n >= 2 || (strcmp(v, "open") && strcmp(v, "closed")))
            error_at(vp, "ends= takes open or closed, or two of them separated by a comma");
        w->term[n++] = v[0];
    }
    if (n == 1)
        w->term[1] = w->term[0];
}

static void spec(Lower *L, Line *l, Waveguide *w, double len) {
    SrcPos pos = l->namepos;
    const int *node = w->end;
    Expr *r = lower_need(L, l, "r");
    double rd = expr_params(r) ? NAN : expr_eval(r, NULL), cs = 343.2, rho = 1.204;
    if (expr_params(r) || !(rd > 0) || !isfinite(rd))
        error_at(lower_key(l, "r")->val.pos, "r must be a positive number of metres");
    KeyVal *ck = lower_key(l, "c"), *rk = lower_key(l, "rho");
    if (ck)
        cs = lower_const(&ck->val, "c=");
    if (rk)
        rho = lower_const(&rk->val, "rho=");
    if (!(cs > 0) || !(rho > 0))
        error_at(ck && !(cs > 0) ? ck->val.pos : rk->val.pos, "c and rho must be positive");
    w->term[0] = w->term[1] = 'o';
    ends(l, w);
    /* end corrections of open ends (unflanged: 0.6133 r) */
    double Leff = len;
    for (int k = 0; k < 2; k++)
        if (!node[k] && w->term[k] == 'o') {
            Leff += 0.6133 * rd;
            w->rad = expr_num(rd / cs, pos);
        }
    bool closed = (!node[0] && w->term[0] == 'c'), open = (!node[0] && w->term[0] == 'o');
    closed |= !node[1] && w->term[1] == 'c';
    open |= !node[1] && w->term[1] == 'o';
    if (closed && open)
        w->nu1 = 0.5;
    w->f0 = expr_num(cs / (2 * Leff), pos);
    w->B = expr_num(0, pos);
    w->Rp = expr_num(rho * cs / (3.14159265358979323846 * rd * rd), pos);
    /* wall losses (boundary layers): alpha = 3e-5 sqrt(f) / r nepers a
     * metre, so t60 = 3 ln 10 / (alpha c) */
    if (!lower_key(l, "t60")) {
        double f1 = cs / (2 * Leff) * w->nu1, fh = 5000;
        w->t60 = expr_num(3 * log(10) / (3e-5 * sqrt(f1) / rd * cs), pos);
        w->t60hf = expr_num(3 * log(10) / (3e-5 * sqrt(fh) / rd * cs), pos);
        w->fhf = expr_num(fh, pos);
    }
}

static Elem *lower(Lower *L, Line *l, const int *node) {
    lower_waveguide(L, l, node, true, spec);
    return NULL;
}

const Kind kind_tube = {
    .desc = "tube",
    .keyword = "tube",
    .nnodes = 2,
    .args = "",
    .keys = keys,
    .ready = true,
    .law = "plane waves in a cylinder of radius r: a travelling wave's pressure is rho c / (pi r^2) times "
           "its volume flow; open ends radiate, closed ends reflect",
    .lowers_to = "a Waveguide, and an E_S to ground per side of each point joined to the network "
                 "(NAME.a, NAME.TAP.l, NAME.TAP.r, NAME.b)",
    .lower = lower,
};
