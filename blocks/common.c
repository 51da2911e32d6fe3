/* common.c: lowerings that several element kinds share. */
#include <math.h>
#include <string.h>

#include "lower.h"

/* ---- linear elements and sources ---- */

Elem *lower_linear(Lower *L, Line *l, const int *node, ElemKind k, const char *vkey) {
    Elem *e = lower_elem(L, l, k, "", node[0], node[1]);
    const Value *arg = lower_arg(l);
    if (arg && lower_key(l, vkey))
        error_at(lower_key(l, vkey)->pos, "value of '%s' given twice", l->name);
    e->val = arg ? lower_value(L, arg, "the value") : lower_need(L, l, vkey);
    KeyVal *ic = lower_key(l, "IC") ? lower_key(l, "IC") : lower_key(l, "ic");
    if (ic) {
        e->ic = lower_value(L, &ic->val, "IC");
        lower_magnitude(L, e->ic, ic->val.pos, format("the initial %s of %s '%s'", k == E_C ? "voltage" : "current",
                                                      block_desc[l->kind].desc, e->name), k == E_C ? "V" : "A");
    }
    return e;
}

Elem *lower_source(Lower *L, Line *l, ElemKind k, int from, int to) {
    Elem *e = lower_elem(L, l, k, "", from, to);
    lower_drive(L, e, lower_arg(l));
    if (lower_key(l, "R"))
        e->val = lower_value(L, &lower_key(l, "R")->val, "R");
    /* a voltage source with no resistance in series is the ideal one,
     * as if R= were not given (a value that params move stays a
     * resistance, checked positive) */
    if (k == E_V && e->val && expr_is_const(e->val) && expr_eval(e->val, NULL) == 0)
        e->val = NULL;
    return e;
}

Expr *lower_recip(Expr *x) { return expr_bin(EX_DIV, expr_num(1, x->pos), x); }

/* ---- nonlinear laws ---- */

static Solver solver_of(Line *l, NlSpec *nl) {
    KeyVal *k = lower_key(l, "solver");
    if (!k)
        return SOLVER_DEFAULT;
    const char *v = k->val.kind == VAL_NAME ? k->val.name : "";
    nl->solver_pos = k->val.pos;
    if (!strcmp(v, "pwl"))
        return SOLVER_PWL;
    if (!strcmp(v, "newton"))
        return SOLVER_NEWTON;
    if (!strcmp(v, "omega"))
        return SOLVER_OMEGA;
    if (!strcmp(v, "fast"))
        return SOLVER_FAST;
    error_at(k->val.pos, "solver= takes fast, newton, omega or pwl");
}

NlSpec *lower_nl(Line *l, NlKind k) {
    NlSpec *nl = arena_alloc(sizeof(NlSpec));
    nl->solver = solver_of(l, nl);
    nl->kind = k;
    return nl;
}

void lower_only_solver(NlSpec *nl, Solver s, const char *why) {
    if (nl->solver != SOLVER_DEFAULT && nl->solver != s)
        error_at(nl->solver_pos, "%s", why);
    nl->solver = s;
}

/* curve=(v0:i0 v1:i1 ...): points of a monotone, passive v-i curve */
void lower_curve(Line *l, NlSpec *nl) {
    KeyVal *k = lower_key(l, "curve");
    if (!k)
        error_at(l->namepos, "nonlinear resistor '%s' needs curve=(v0:i0 v1:i1 ...)", l->name);
    if (k->val.kind != VAL_LIST)
        error_at(k->val.pos, "curve= takes a list of points in parentheses, (v0:i0 v1:i1 ...)");
    int n = k->val.ntoks;
    const Token *t = k->val.toks;
    nl->cv = arena_alloc(sizeof(double) * (size_t)(n / 3 + 2));
    nl->ci = arena_alloc(sizeof(double) * (size_t)(n / 3 + 2));
    for (int i = 0; i < n; i += 3) {
        if (i + 2 >= n || t[i + 1].len != 1 || t[i + 1].text[0] != ':')
            error_at(t[i].pos, "expected a point v:i in the curve");
        for (int j = 0; j < 3; j += 2)
            if (t[i + j].kind != TK_NUMBER)
                error_at(t[i + j].pos, "malformed number '%.*s' in the curve", t[i + j].len, t[i + j].text);
        int m = nl->npts++;
        nl->cv[m] = t[i].num;
        nl->ci[m] = t[i + 2].num;
        if (m > 0 && !(nl->cv[m] > nl->cv[m - 1]))
            error_at(t[i].pos, "curve voltages must increase from point to point");
        if (m > 0 && nl->ci[m] < nl->ci[m - 1])
            error_at(t[i + 2].pos, "curve currents must not decrease (a falling curve has no unique wave map)");
        if (nl->cv[m] * nl->ci[m] < 0)
            error_at(t[i].pos, "point %g:%g delivers power: a passive curve has v*i >= 0", nl->cv[m], nl->ci[m]);
    }
    if (nl->npts < 2)
        error_at(k->val.pos, "a curve needs at least two points");
    /* the current at v = 0, on the curve or its extension, must be 0 */
    int a = 0;
    while (a + 2 < nl->npts && nl->cv[a + 1] < 0)
        a++;
    double v0 = nl->cv[a], v1 = nl->cv[a + 1];
    double i0 = nl->ci[a] + (0 - v0) * (nl->ci[a + 1] - nl->ci[a]) / (v1 - v0);
    if (fabs(i0) > 1e-12 * (fabs(nl->ci[0]) + fabs(nl->ci[nl->npts - 1])))
        error_at(k->val.pos, "the curve passes v = 0 at i = %g: a passive curve goes through the origin", i0);
}

/* The mutator the compiler puts in takes the curve to its root, where
 * Newton solves it. */
bool lower_curve_reactance(Lower *L, Line *l, const int *node, const char *vkey, char type) {
    KeyVal *cv = lower_key(l, "curve");
    if (!cv)
        return false;
    if (lower_key(l, vkey) || lower_arg(l))
        error_at(cv->pos, "%s '%s' takes a value or curve=, not both", block_desc[l->kind].desc, l->name);
    if (lower_key(l, "IC") || lower_key(l, "ic"))
        error_at((lower_key(l, "IC") ? lower_key(l, "IC") : lower_key(l, "ic"))->pos, "a nonlinear %s takes no "
                 "IC= (a spring's stretch comes from .ic x(node); a capacitor starts at rest)",
                 block_desc[l->kind].desc);
    Elem *e = lower_elem(L, l, E_NL, "", node[0], node[1]);
    NlSpec *nl = arena_alloc(sizeof(NlSpec));
    nl->kind = NL_CURVE;
    lower_curve(l, nl);
    nl->solver = SOLVER_NEWTON;
    nl->mutated = type;
    e->nl = nl;
    return true;
}

/* ---- waveguides ---- */

/* One value of a token list (taps=h@0.12,p@{pos}). */
static Value token_value(const Token *t) {
    Value v = {.pos = t->pos};
    if (t->kind == TK_NUMBER) {
        v.kind = VAL_EXPR;
        v.expr = expr_num(t->num, t->pos);
    } else if (t->kind == TK_LBRACE) {
        v.kind = VAL_EXPR;
        v.expr = parse_expr_text(t);
    } else if (t->kind == TK_IDENT) {
        v.kind = VAL_NAME;
        v.name = arena_strndup(t->text, (size_t)t->len);
    } else {
        error_at(t->pos, "expected a number, a param or {expression}, found '%.*s'", t->len, t->text);
    }
    return v;
}

static bool is_tok(const Token *t, char c) { return t->len == 1 && t->text[0] == c && t->kind != TK_IDENT; }

/* taps=NODE@FRACTION,...: each tap's node, position, where its position
 * is written and its node's name, into w. */
static void taps(Lower *L, Line *l, const int *node, Waveguide *w) {
    Vec tn = {0}, tp = {0}, tsrc = {0}, tnames = {0};
    KeyVal *tk = lower_key(l, "taps");
    if (tk) {
        const Token *t = tk->val.kind == VAL_LIST ? tk->val.toks : NULL;
        int nt = t ? tk->val.ntoks : 0;
        if (!t)
            error_at(tk->val.pos, "taps= takes a list NODE@FRACTION,NODE@FRACTION,...");
        for (int i = 0; i < nt; i += 4) {
            if (t[i].kind != TK_IDENT || i + 2 >= nt || !is_tok(&t[i + 1], '@'))
                error_at(t[i].pos, "expected NODE@FRACTION in taps=");
            if (i + 3 < nt && t[i + 3].kind != TK_COMMA)
                error_at(t[i + 3].pos, "expected ',' between taps");
            const char *nm = arena_strndup(t[i].text, (size_t)t[i].len);
            int nd = lower_node(L, nm, t[i].pos);
            if (nd == 0)
                error_at(t[i].pos, "a tap cannot be on ground (node 0)");
            if (nd == node[0] || nd == node[1])
                error_at(t[i].pos, "tap '%s' is also an end of %s '%s'", nm, w->tube ? "tube" : "string", l->name);
            for (int j = 0; j < tn.len; j++)
                if (*(int *)tn.data[j] == nd)
                    error_at(t[i].pos, "tap '%s' is given twice", nm);
            Value v = token_value(&t[i + 2]);
            Expr *x = lower_value(L, &v, "a tap position");
            int *pn = arena_alloc(sizeof(int));
            *pn = nd;
            vec_push(&tn, pn);
            vec_push(&tp, x);
            SrcPos *ps = arena_alloc(sizeof(SrcPos));
            *ps = t[i + 2].pos;
            vec_push(&tsrc, ps);
            vec_push(&tnames, (void *)nm);
        }
    }
    w->ntaps = tn.len;
    w->tap_node = arena_alloc(sizeof(int) * (size_t)(tn.len + 1));
    w->tap_pos = arena_alloc(sizeof(Expr *) * (size_t)(tn.len + 1));
    w->tap_src = arena_alloc(sizeof(SrcPos) * (size_t)(tn.len + 1));
    w->tap_name = arena_alloc(sizeof(char *) * (size_t)(tn.len + 1));
    for (int j = 0; j < tn.len; j++) {
        w->tap_node[j] = *(int *)tn.data[j];
        w->tap_pos[j] = tp.data[j];
        w->tap_src[j] = *(SrcPos *)tsrc.data[j];
        w->tap_name[j] = tnames.data[j];
    }
}

/* The ports of waveguide wi: end a (faces b), taps (both sides), end b
 * (faces a), each joined point's a port to ground. */
static void ports(Lower *L, Line *l, const int *node, const Waveguide *w, int wi) {
    for (int pt = 0; pt <= w->ntaps + 1; pt++) {
        int nd = pt == 0 ? node[0] : pt == w->ntaps + 1 ? node[1] : w->tap_node[pt - 1];
        if (!nd)
            continue;
        for (int side = 0; side < 2; side++) {
            if ((pt == 0 && side == 0) || (pt == w->ntaps + 1 && side == 1))
                continue;
            const char *suffix = pt == 0 ? ".a" : pt == w->ntaps + 1 ? ".b"
                                 : format(".%s.%c", w->tap_name[pt - 1], side ? 'r' : 'l');
            Elem *e = lower_elem(L, l, E_S, suffix, nd, 0);
            e->val = w->Rp;
            /* a tap that a param moves may leave its string: its ports
             * then drop out of their junction */
            if (pt > 0 && pt <= w->ntaps && expr_params(w->tap_pos[pt - 1]))
                e->val = expr_bin(EX_DIV, w->Rp, expr_call(FN_TAPON, w->tap_pos[pt - 1], NULL));
            e->wg = wi;
            e->pt = pt;
            e->side = side;
        }
    }
}

void lower_waveguide(Lower *L, Line *l, const int *node, bool tube, GuideSpec *spec) {
    Waveguide *w = arena_alloc(sizeof(Waveguide));
    w->name = format("%s%s", lower_prefix(L), l->name);
    w->tube = tube;
    w->pos = l->namepos;
    w->end[0] = node[0];
    w->end[1] = node[1];
    w->nu1 = 1;
    SrcPos pos = l->namepos;
    Expr *len = lower_need(L, l, "L");
    double Ld = expr_params(len) ? NAN : expr_eval(len, NULL);
    if (expr_params(len) || !(Ld > 0) || !isfinite(Ld))
        error_at(lower_key(l, "L")->val.pos, "L must be a positive number of metres");
    spec(L, l, w, Ld);
    if (lower_key(l, "t60")) {
        w->t60 = lower_need(L, l, "t60");
        w->t60hf = lower_key(l, "t60hf") ? lower_need(L, l, "t60hf") : NULL;
        w->fhf = lower_key_or(L, l, "fhf", 5000);
    } else if (lower_key(l, "t60hf")) {
        error_at(lower_key(l, "t60hf")->pos, "t60hf= needs t60= too");
    }
    if (!w->fhf)
        w->fhf = expr_num(5000, pos);
    w->f0_min = lower_expr_min(L, w->f0, pos, "f0");
    if (!(w->f0_min >= 1) || !isfinite(w->f0_min))
        error_at(tube ? pos : lower_key(l, "f0")->val.pos, "%s '%s' has a first resonance of %g Hz; it must be at "
                 "least 1 Hz", tube ? "tube" : "string", l->name, w->f0_min * w->nu1);
    taps(L, l, node, w);
    w->nmin = w->ntaps ? 4 : 2;
    for (int k = 0; k < 2; k++)
        w->nrad += tube && !node[k] && w->term[k] == 'o';
    if (node[0] && node[0] == node[1])
        error_at(l->args[1].pos, "%s '%s' has both ends on one node", tube ? "tube" : "string", l->name);
    if (!node[0] && !node[1] && !w->ntaps)
        error_at(l->namepos, "%s '%s' joins nothing: put an end on a node or give it taps=", tube ? "tube" : "string",
                 l->name);
    ports(L, l, node, w, lower_add_waveguide(L, w));
}
