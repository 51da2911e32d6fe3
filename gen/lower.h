/*
 * lower.h - what the descriptor of an element kind, in blocks/, uses to
 * lower a netlist line to the compiler's primitive elements (E_R ... E_S).
 *
 * A kind's `lower` is called by elaboration (elab.c) once the line's keys
 * are checked against the kind's, a model= has lent it its keys and its
 * nodes are numbered; it adds elements with lower_elem and reads the
 * line's values with the helpers below, which resolve names in the scope
 * of the block instance the line sits in.  Errors unwind through diag.
 */
#ifndef WDC_LOWER_H
#define WDC_LOWER_H

#include "gen.h"

/* The descriptors (blocks/blocks.def). */
#define BLOCK(id, kind) extern const Kind kind;
#include "../blocks/blocks.def"
#undef BLOCK

/* elab.c: the elaboration a lowering adds to */

/* A mutator X a b c d type=RC|RL: once every element is lowered, the
 * nonlinear resistor across (c, d) appears at (a, b) as a nonlinear
 * capacitor (RC: q = g(v)) or inductor (RL: i = g(flux)). */
typedef struct Mutator {
    const char *name;
    int n[4];
    char type;     /* 'C' or 'L' */
    SrcPos pos;
    Line *line;
} Mutator;

/* A coupling K NAME L1 L2 k: once every element is lowered, elaboration
 * realises each group of inductors that couplings join (elab.c, couple). */
typedef struct Coupling {
    const char *name;   /* prefix + the line's name */
    const char *ind[2]; /* the inductors' names, prefixed */
    SrcPos indpos[2];
    double k;
    SrcPos kpos;
    Line *line;
} Coupling;

/* Adds a primitive element named prefix + l->name + suffix from n0 to n1;
 * an element of that name already there is an error. */
Elem *lower_elem(Lower *L, Line *l, ElemKind k, const char *suffix, int n0, int n1);
/* Elements added so far: the next one added gets this index. */
int lower_nelems(Lower *L);
/* The prefix of names in this scope: "" at top level, "INST." in an instance. */
const char *lower_prefix(Lower *L);
/* The sample rate, Hz: the one the command line gives, else the
 * netlist's (.rate, a deck's .tran, or 48 kHz). */
double lower_rate(Lower *L);
/* Node index of a name in this scope, made if new. */
int lower_node(Lower *L, const char *name, SrcPos pos);
/* Hands a mutator to elaboration, which applies it after the last element. */
void lower_add_mutator(Lower *L, Mutator *m);
/* Hands a coupling to elaboration, which applies it after the last element. */
void lower_add_coupling(Lower *L, Coupling *k);
/* Adds a waveguide; returns its index (Elem.wg of its ports). */
int lower_add_waveguide(Lower *L, Waveguide *w);

/* The key=value k on line l, or NULL. */
KeyVal *lower_key(Line *l, const char *k);
/* The first positional argument after l's nodes, or NULL. */
const Value *lower_arg(const Line *l);
/* A value as an expression in this scope (params resolved); `what`
 * names it where it is neither a number, an expression nor a param. */
Expr *lower_value(Lower *L, const Value *v, const char *what);
/* The value of key k, which l must give ("KIND 'NAME' needs k="). */
Expr *lower_need(Lower *L, Line *l, const char *k);
/* The value of key k, or def where l does not give it. */
Expr *lower_key_or(Lower *L, Line *l, const char *k, double def);
double lower_vt(Lower *L, const Line *l);
/* A value known at compile time: a number or an expression of numbers. */
double lower_const(const Value *v, const char *what);
/* Refuses x at pos unless its magnitude stays within what a voice can
 * hold, at the default params and with each param at its bounds. */
void lower_magnitude(Lower *L, const Expr *x, SrcPos pos, const char *what, const char *unit);
/* The lowest value of e over the params' ranges (each param alone at its
 * bounds, and the defaults); each param it reads needs finite bounds. */
double lower_expr_min(Lower *L, Expr *e, SrcPos pos, const char *what);
/* Sets a source's drive: an input, or a value checked in magnitude. */
void lower_drive(Lower *L, Elem *e, const Value *v);
/* The .model line a model name names. */
Line *lower_model(Lower *L, const Value *v);
/* l with the keys of model m it does not give itself (and without model=). */
Line *lower_model_keys(Line *l, const Line *m);

/* blocks/common.c: lowerings that several kinds share */

/* A two-terminal R, C or L of kind k valued by its positional argument or
 * by key vkey, with an initial voltage or current from IC= (or ic=). */
Elem *lower_linear(Lower *L, Line *l, const int *node, ElemKind k, const char *vkey);
/* An independent source (E_V or E_I) from node `from` to node `to`, driven
 * by its positional argument; R= is its series (V) or parallel (I)
 * resistance, and a voltage source with R=0 is the ideal one. */
Elem *lower_source(Lower *L, Line *l, ElemKind k, int from, int to);
/* 1/x: the mobility analogy's L = 1/k and R = 1/c. */
Expr *lower_recip(Expr *x);
/* A nonlinearity of kind k, its solver= read from line l. */
NlSpec *lower_nl(Line *l, NlKind k);
/* A nonlinearity that only solver s solves: any other solver= is refused
 * with `why`, and s becomes its solver. */
void lower_only_solver(NlSpec *nl, Solver s, const char *why);
/* Reads curve=(v0:i0 v1:i1 ...) into nl: a monotone, passive curve. */
void lower_curve(Line *l, NlSpec *nl);
/* A capacitor or spring given by curve= instead of its value (key vkey):
 * a nonlinear reactance behind a mutator of type 'C' (charge =
 * curve(voltage)) or 'L' (force = curve(stretch)); false if l has no
 * curve=. */
bool lower_curve_reactance(Lower *L, Line *l, const int *node, const char *vkey, char type);
/* What a string or a tube sets of its waveguide w (its ends' nodes in
 * w->end), given its length len (m): f0, B, its port resistance Rp, the
 * terminations of its ends, and the losses it has where t60= is not
 * given. */
typedef void GuideSpec(Lower *L, Line *l, Waveguide *w, double len);
/* A string (tube false) or tube from node[0] to node[1] with its taps: a
 * Waveguide (spec sets what its kind decides), and a port to ground
 * (E_S) for each side of each point that joins the network. */
void lower_waveguide(Lower *L, Line *l, const int *node, bool tube, GuideSpec *spec);

#endif
