/*
 * refsim.h - a reference simulator for elaborated circuits.
 *
 * Simulates a Circuit (gen.h) by modified nodal analysis with
 * trapezoidal companion models, independently of the wave-digital
 * structure, so a voice can be checked against it sample for sample.
 * Linear networks take one solve per sample; networks with nonlinear
 * elements (E_NL) take a converged implicit step (see below).
 *
 * Conventions (the same as a voice's):
 *   - Every element's current i flows from its n[0] through it to n[1];
 *     its voltage is v(n[0]) - v(n[1]).
 *   - E_R: v = R i.  E_C: i[n] = (2C/T)(v[n] - v[n-1]) - i[n-1].
 *     E_L: v[n] = (2L/T)(i[n] - i[n-1]) - v[n-1].  Element values are those
 *     of the current sample (after any param change); across a change the Kirchhoff
 *     history v[n-1], i[n-1] is kept, except that a capacitor that grows
 *     keeps its charge (v[n-1] scales by C_old / C_new) and an inductor
 *     that grows its flux (i[n-1] scales by L_old / L_new): no change adds
 *     energy.
 *   - E_V: v = drive + R i (R = 0 without a value: ideal).
 *     E_I: i = drive + v/R (no v/R term without a value).
 *     drive is the source's input sample, or elem_drive() for sources that
 *     have no input.
 *   - Sample n = -1 is the initial state: capacitors hold their .ic
 *     voltage, inductors their .ic current (0 without one), and the rest
 *     is one resistive solve of the network with each capacitor replaced
 *     by a voltage source and each inductor by a current source of that
 *     value, input-driven sources at 0 and constant sources at their value.
 *     If that network is singular (a loop of capacitors and ideal voltage
 *     sources, or a cut of inductors and ideal current sources), the
 *     reactances keep their .ic values and everything else starts from
 *     node voltages of 0: no current through capacitors, no voltage across
 *     inductors, and source currents and voltages as those voltages give.
 *     refsim_start_at() replaces it with a given DC operating point (a
 *     SPICE deck's voice starts from one).
 *   - The first refsim_step() computes sample 0.
 *   - Probes (Circuit.outs): PR_V is v(n0) - v(n1); PR_I and PR_F the
 *     element's current (a source's whole current, parallel resistor
 *     included); PR_X the trapezoidal integral of v(n0) - v(n1), starting
 *     from the .ic x() values of its nodes.
 *   - E_NL (current i from n[0] through it to n[1], v = v(n0) - v(n1)):
 *     diode i = Is (exp(v/(n Vt)) - 1), a pair i = 2 Is sinh(v/(n Vt));
 *     curve: linear interpolation of its points, the end segments
 *     extended; contact: X[n] = X[n-1] + T/2 (v[n] + v[n-1]) from
 *     X[-1] = x_ic(n0) - x_ic(n1) (the .ic x() values, 0 if none),
 *     compression C = X - gap, elastic force F(C) = k C^alpha while
 *     C > 0, else 0, stored energy U(C) its integral.  Behind a mutator
 *     (NlSpec.mutated) the diode's or curve's law f makes a nonlinear
 *     inductor, F = f(X) with the flux X integrated as a contact's (R-L
 *     type), or a nonlinear capacitor, charge f(u) at the voltage u of
 *     its law, i[n] = (f(u[n]) - f(u[n-1])) 2/T - i[n-1] (R-C type).
 *     These three step passively: with R the resistance the rest of the
 *     step network presents to the element and M the mean of the elastic
 *     force over [C[n-1], C[n]] (U's difference over dC = C[n] - C[n-1]),
 *     the average (i[n] + i[n-1]) / 2 aims at (i[n-1] + F(C[n]) (1 +
 *     lambda v[n])) / 2 (the factor only for a contact while positive)
 *     and is held within [M, M + dC / (T R)] for dC > 0 and
 *     [M + dC / (T R), M] for dC < 0; a capacitor likewise holds the
 *     average voltage, aiming at (v[n-1] + u[n]) / 2, within the mean
 *     voltage over its charge and that plus dq R / T.  Each sample
 *     solves the whole
 *     nodal system with these laws by damped Newton from the last
 *     sample's solution: a step that raises the residual is halved (up to
 *     60 times), and the iteration ends when the full step is below 1e-13
 *     of the largest node voltage (node unknowns) or branch current
 *     (branch unknowns), at most 200 iterations (refsim_nl_stats counts
 *     the samples that did not converge).
 *     At sample -1 diodes, curves and nonlinear capacitors are open
 *     (they carry nothing at rest), a contact is a current source of its
 *     elastic force k C^alpha at its initial compression (0 if C <= 0),
 *     and a nonlinear inductor one of f(X) at its initial flux.
 *   - energy: sum of C v^2/2 + L i^2/2 at the last computed sample, plus
 *     k C^(alpha+1)/(alpha+1) for each contact with C > 0, F(X) for each
 *     nonlinear inductor and u f(u) - F(u) for each nonlinear capacitor,
 *     F being the integral of f from 0.
 *     work: sum over steps of -T * vbar * ibar over the sources, bars
 *     being averages of this and the previous sample, using the ideal part
 *     of a resistive source (its drive) for v (V) or i (I).
 */
#ifndef REFSIM_H
#define REFSIM_H

#include "gen.h"

typedef struct refsim refsim;

/* Whether an element kind is one of the linear ones refsim simulates
 * (E_R, E_C, E_L, E_V, E_I); whether refsim simulates every element of c
 * (those and E_NL; not lines, E_W); and whether every element of c is
 * linear. */
int refsim_linear_kind(int kind);
int refsim_can_simulate(const Circuit *c);
int refsim_is_linear(const Circuit *c);
/* A simulator of `c` at sample rate fs (Hz) with the given param values
 * (Circuit.nparams of them; NULL: the defaults), at sample -1.  The
 * Circuit must outlive it.  Returns NULL if out of memory, if c has an
 * element refsim does not simulate, or if the network cannot be simulated
 * (a loop of ideal voltage sources or a cut of ideal current sources;
 * contacts and curves count as open here, since they may carry nothing). */
refsim *refsim_new(const Circuit *c, double fs, const double *params);
/* Makes sample -1 the DC operating point given by node voltages
 * nodev[nnodes] (nodev[0], ground, is taken as 0) and element currents
 * cur[nelems] from n[0] to n[1], as dcop_solve (gen.h) returns them, in
 * place of the initial state above; call it before the first
 * refsim_step, with the params the point was found at.  Each element's
 * v is the difference of its nodes' voltages and its i is cur[e], except:
 * E_R: i = v / R; E_C: i = 0 (open at DC); E_L: v = 0 (shorted);
 * a constant E_I: i = its drive + v/R; E_CI: i = gain v(probe)
 * (dcop_solve leaves the current of E_I and E_CI at 0).  A
 * source's drive at sample -1 is its constant value, or for one an input
 * drives the drive that gives that v and i (E_V: v - R i; E_I: i - v/R).
 * A nonlinear capacitor's law starts at the voltage across it; contacts'
 * and nonlinear inductors' integrals and PR_X probes' integrals keep
 * their .ic values, a PR_X probe's last voltage is that of its nodes.
 * The work restarts from 0; refsim_init_singular then gives 0. */
void refsim_start_at(refsim *s, const double *nodev, const double *cur);
/* Changes param `id` (clamped to [min, max] as a voice does); it takes
 * effect from the next step on. */
void refsim_set_param(refsim *s, int id, double v);
double refsim_get_param(const refsim *s, int id);
/* Computes one sample: in[k] is input k (Circuit.ninputs, may be NULL
 * when there are none), out[k] probe k (Circuit.nouts). */
void refsim_step(refsim *s, const double *in, double *out);
/* Stored energy at the last computed sample (sample -1 before any step). */
double refsim_energy(const refsim *s);
/* Work done by the sources on the network since sample -1. */
double refsim_work(const refsim *s);
/* Samples computed so far. */
long refsim_time(const refsim *s);
/* Voltage and current of element e at the last computed sample. */
double refsim_elem_v(const refsim *s, int e);
double refsim_elem_i(const refsim *s, int e);
/* Voltage of graph node `node` (0: ground) at the last computed sample. */
double refsim_node_v(const refsim *s, int node);
/* Whether the initial network was singular (see above). */
int refsim_init_singular(const refsim *s);
/* With bits = 64 (32), the state (node voltages, element voltages and
 * currents, integrals, work) is rounded to double (float) after every
 * step and the factors of the step matrix when they are computed: the
 * error that merely storing the state and coefficients in that precision
 * causes, a floor for what a voice computing in it can reach.  0: off
 * (the default). */
void refsim_round_state(refsim *s, int bits);
/* How the Newton solves of a network with nonlinear elements went. */
typedef struct refsim_nl_info {
    long steps;       /* samples solved by Newton */
    long iters;       /* Newton iterations over them */
    int maxit;        /* most iterations one sample took */
    long unconverged; /* samples that reached the iteration cap */
    long forced;      /* iterations whose step raised the residual however
                         much it was halved, and was taken whole */
} refsim_nl_info;
void refsim_nl_stats(const refsim *s, refsim_nl_info *info);
void refsim_free(refsim *s);

#endif
