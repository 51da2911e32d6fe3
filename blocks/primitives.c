/*
 * primitives.c - the primitive elements every element kind lowers to, as
 * the wave-digital structure and the voice see them: each one's law, how
 * it is realised (its port resistance from its value, the wave it
 * reflects), what it stores, and how it enters the initial-condition
 * solve; its stamps are the C text the printer fills in for the wave it
 * reflects, what it stores, its energy and a strike (gen/gen.h, Prim).
 * The kinds of the netlist (the other files here) say which of these
 * they become.
 */
#include "gen.h"

const Prim prims[] = {
    [E_R] = {"resistor", "v = R i", WD_ADAPTED, 'v', 0, ROOT_NEVER, IC_RES, IC_RES, .reflect = "0"},
    /* trapezoidal: C = T / (2 R), so its energy C v^2 / 2 is v^2 / (4 fs R);
     * a mass's velocity is its voltage, set by v(node) */
    [E_C] = {"capacitor", "i = C dv/dt", WD_HOLD, 'C', 'C', ROOT_NEVER, IC_CAP, IC_CAP, .reflect = "$a",
             .stored = "0.5 * D($a + $b)", .energy = "double v = $x; E += 0.25 / (st->fs * D($R)) * v * v;",
             .strike = 'v', .struck = "$x"},
    /* L = R / (2 fs): its energy L i^2 / 2 is R i^2 / (4 fs); a spring's
     * force is its current and L i its stretch, set by x(node) */
    [E_L] = {"inductor", "v = L di/dt", WD_HOLD_NEG, 'L', 'L', ROOT_NEVER, IC_IND, IC_IND, .reflect = "-$a",
             .stored = "0.5 * D($a - $b) / D($R)", .energy = "double i = $x; E += 0.25 * D($R) / st->fs * i * i;",
             .strike = 'x', .struck = "$x / (0.5 * D($R) / st->fs)"},
    [E_V] = {"voltage source", "v = e + R i; ideal without R", WD_SOURCE, 'v', 0, ROOT_IDEAL, IC_V, IC_RV,
             .reflect = "$e"},
    [E_I] = {"current source", "i = j + v / R; ideal without R", WD_SOURCE, 'v', 0, ROOT_IDEAL, IC_I, IC_RI,
             .reflect = "-$R * $e"},
    /* a contact or a nonlinear inductor holds a force (IC_FORCE, see
     * prim_ic); a diode or curve at rest carries no current */
    [E_NL] = {"nonlinear one-port", "i = g(v), or the law of a stored coordinate (NlSpec)", WD_ROOT, 'v', 0,
              ROOT_ALWAYS, IC_OPEN, IC_OPEN},
    /* an empty line looks like its Z0 to the initial-condition solve; each
     * end keeps the waves that enter at it ($o: its buffer, $p: the other
     * end's, $k: the line, whose delay in samples is k_D$k, $m: the mask of
     * the positions).  The trapezoidal rule balances reactances against
     * the power of two-sample averages of v and i; in those terms a line
     * delays the averaged wave (a[m] + a[m-1]) / 2, each carrying
     * T a^2 / (4 Z0). */
    [E_W] = {"line end", "b(t) = a(t - TD) entered at the other end; port Z0", WD_DELAY, 'v', 0, ROOT_NEVER, IC_RES,
             IC_RES, .reflect = "s_dl[$p + ((t_pos - k_D$k) & $m)]", .absorb = "s_dl[$o + (t_pos & $m)] = flush($a);",
             .energy = "double s = 0;\n"
                       "        for (unsigned m = 1; m <= st->c_D[$k]; m++) {\n"
                       "            double a = D(st->s_dl[$o + ((st->s_pos - m) & $m)] + st->s_dl[$o + ((st->s_pos - m - 1) & $m)]);\n"
                       "            s += 0.25 * a * a;\n"
                       "        }\n"
                       "        E += s / (4 * st->fs * D($R));"},
    /* its last incoming wave behind its port resistance: read $d samples
     * back from the line that brings it ($o), what it takes in written at
     * $q into the other ($p); end b reads the loop filters' output instead */
    [E_S] = {"waveguide port", "b = the wave the string or tube brings; port its impedance", WD_WAVEGUIDE, 'v', 0,
             ROOT_NEVER, IC_WAVE, IC_WAVE, .reflect = "s_wv[$o + ((t_pos - $d) & $m)]",
             .absorb = "s_wv[$p + ($q & $m)] = $a;"},
    /* controlled sources stamp their root's nodal equations */
    [E_CV] = {"controlled voltage source", "v = gain v(probe)", WD_ROOT, 'v', 0, ROOT_ALWAYS, IC_CV, IC_CV},
    [E_CI] = {"controlled current source", "i = gain v(probe)", WD_ROOT, 'v', 0, ROOT_ALWAYS, IC_CI, IC_CI},
    [E_OA] = {"op-amp output", "any current that holds v(probe) = 0", WD_ROOT, 'v', 0, ROOT_ALWAYS, IC_OA, IC_OA},
    [E_P] = {"probe", "i = 0", WD_ROOT, 'v', 0, ROOT_ALWAYS, IC_PROBE, IC_PROBE},
    [E_CC] = {"controlled current source", "i = gain i(junction)", WD_ROOT, 'v', 0, ROOT_ALWAYS, IC_CC, IC_CC},
    [E_XF] = {"transformer winding", "v = n v(probe); the probe draws -n i", WD_ROOT, 'v', 0, ROOT_ALWAYS, IC_XF,
              IC_XF},
};

bool prim_at_root(const Elem *e) {
    const Prim *p = &prims[e->kind];
    return p->root == ROOT_ALWAYS || (p->root == ROOT_IDEAL && !e->val);
}

double prim_port(const Elem *e, double v, double fs) {
    switch (prims[e->kind].port) {
    case 'C': return 1 / (2 * fs * v);
    case 'L': return 2 * fs * v;
    default: return v;
    }
}

const char *prim_port_text(const Elem *e, const char *v) {
    switch (prims[e->kind].port) {
    case 'C': return format("T / (2 * %s)", v);
    case 'L': return format("2 * %s / T", v);
    default: return v;
    }
}

int prim_ic(const Elem *e) {
    if (e->kind == E_NL && (e->nl->kind == NL_CONTACT || e->nl->mutated == 'L'))
        return IC_FORCE;
    return e->val ? prims[e->kind].ic_resistive : prims[e->kind].ic;
}
