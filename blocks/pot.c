/* pot.c: pot NAME a w b R= pos= [taper=lin|log]: a potentiometer, two
 * resistors R(a, w) = R (1 - taper(pos)) and R(w, b) = R taper(pos), each
 * at least R 1e-6; pos=1 puts the wiper at a. */
#include <string.h>

#include "lower.h"

static const KindKey keys[] = {{"R", "ohm"}, {"pos", ""}, {"taper", ""}, {NULL, NULL}};

static Elem *lower(Lower *L, Line *l, const int *node) {
    Expr *R = lower_need(L, l, "R"), *pos = lower_need(L, l, "pos");
    KeyVal *tk = lower_key(l, "taper");
    FnKind taper = FN_POTLIN;
    if (tk) {
        const char *t = tk->val.kind == VAL_NAME ? tk->val.name : "";
        if (!strcmp(t, "log"))
            taper = FN_POTLOG;
        else if (strcmp(t, "lin"))
            error_at(tk->val.pos, "taper= takes lin or log");
    }
    Expr *t = expr_call(taper, pos, NULL);
    Expr *floor = expr_num(1e-6, l->pos);
    Expr *one = expr_num(1, l->pos);
    if (node[0] != node[1]) {
        Elem *e = lower_elem(L, l, E_R, ".aw", node[0], node[1]);
        e->val = expr_bin(EX_MUL, R, expr_call(FN_MAX, expr_bin(EX_SUB, one, t), floor));
    }
    if (node[1] != node[2]) {
        Elem *e = lower_elem(L, l, E_R, ".wb", node[1], node[2]);
        e->val = expr_bin(EX_MUL, R, expr_call(FN_MAX, t, floor));
    }
    return NULL;
}

const Kind kind_pot = {
    .desc = "potentiometer",
    .keyword = "pot",
    .nnodes = 3,
    .args = "",
    .keys = keys,
    .ready = true,
    .law = "R(a, w) = R max(1 - taper(pos), 1e-6), R(w, b) = R max(taper(pos), 1e-6)",
    .lowers_to = "two E_R, NAME.aw and NAME.wb (none where its nodes coincide)",
    .lower = lower,
};
