/*
 * solve.h - linear networks solved in straight-line code (solve.c).
 */
#ifndef WDC_SOLVE_H
#define WDC_SOLVE_H

#include "gen.h"

/* A value of the printed code: a number (t < 0, ext NULL), an external
 * expression (ext), or a temporary (t: its item in a Sx). */
typedef struct Sym {
    int t;
    double c;
    const char *ext;
} Sym;

typedef struct Sx Sx;

/* Printed values and statements; temporaries are named prefix0, prefix1... */
Sx *sx_new(const char *prefix);
Sym sym_k(double c);
Sym sym_ext(const char *text);
bool sym_number(Sym a);       /* a is a number (its value in c) */
bool sym_is(Sym a, double c); /* a is the number c */
Sym sx_temp(Sx *s, const char *text); /* a temporary holding C text */
Sym sx_neg(Sx *s, Sym a);
Sym sx_add(Sx *s, Sym a, Sym b);
Sym sx_sub(Sx *s, Sym a, Sym b);
Sym sx_mul(Sx *s, Sym a, Sym b);
Sym sx_div(Sx *s, Sym a, Sym b);
/* The operand text of a in statements, marking it needed. */
const char *sx_use(Sx *s, Sym a);
/* A statement, printed in order among the temporaries (its text may name
 * values through sx_use). */
void sx_stmt(Sx *s, const char *line);
/* The values of every temporary, computed here as the printed code would
 * (for tests): ext gives the value of an external's or a C-text
 * temporary's text.  sx_value reads one value of a run. */
double *sx_run(Sx *s, double (*ext)(const char *text, void *ctx), void *ctx);
double sx_value(const double *v, Sym a, double (*ext)(const char *text, void *ctx), void *ctx);
/* Prints the statements and the temporaries they need, in order. */
void sx_code(Sx *s, Buf *o);
/* Whether sx_code prints a temporary read once where it is read (exact
 * where every value is a double, as in a double voice). */
void sx_once(Sx *s, bool on);

/* A linear network of n nodes (-1: the reference): conductances with a
 * series emf (current g (v_p - v_q - emf) from p to q), ideal voltage
 * sources (v_p - v_q = value) and current sources (value from p to q).
 * Each returns the edge's index. */
typedef struct Lin Lin;
Lin *lin_new(Sx *sx, int n);
int lin_g(Lin *L, int p, int q, Sym g);
int lin_v(Lin *L, int p, int q);
int lin_j(Lin *L, int p, int q);
/* Eliminates the network's conductances: false if it is singular for its
 * structure (a loop of voltage sources, nodes that reach the reference
 * only through current sources) or too large to print. */
bool lin_factor(Lin *L);
/* The node potentials (pot[n], or NULL) and the current of each edge from
 * p to q (cur[ne], or NULL) for the edges' values val[] (emf, voltage or
 * current; conductances' emf 0 if none). */
void lin_solve(Lin *L, const Sym *val, Sym *pot, Sym *cur);

#endif
