/* waveguide.c: compile-time design of waveguide loops.
 *
 * The design code is the voice's own (templates/waveguide.c.tmpl), so
 * what the compiler checks is what the voice computes when a param moves.
 * Here it chooses the order of each loop's allpass and checks that each
 * loop is long enough for its filters at the netlist's rate. */
#include <math.h>
#include <string.h>

#include "gen.h"

#include "../templates/waveguide.c.tmpl"

const int wg_nspec = WG_NSPEC, wg_nrec = WG_NREC;

static double eval_or(const Expr *e, const double *p, double def) { return e ? expr_eval(e, p) : def; }

/* The design input of w at params p and rate fs. */
static wg_spec spec_of(const Waveguide *w, const double *p, double fs) {
    return (wg_spec){.fs = fs, .f0 = expr_eval(w->f0, p), .B = expr_eval(w->B, p), .t60 = eval_or(w->t60, p, 0),
                     .t60hf = eval_or(w->t60hf, p, 0), .fhf = expr_eval(w->fhf, p), .nu1 = w->nu1,
                     .rad = eval_or(w->rad, p, 0), .nrad = w->nrad, .K = w->M, .nmin = w->nmin};
}

/* A loop too short for its filters at s->fs (set by `rate`): an error. */
static void too_short(const Waveguide *w, const wg_spec *s, const char *rate) {
    error_at(w->pos, "%s '%s' is too short for its filters at %g Hz: its loop holds %.2f samples and needs at "
             "least %d (lower f0, or raise %s)", w->tube ? "tube" : "string", w->name, s->fs, wg_target(s, s->nu1),
             s->nmin + 1, rate);
}

void wg_check_rate(const Circuit *c, double fs) {
    double *p = circuit_defaults(c);
    for (int i = 0; i < c->nwgs; i++) {
        wg_loop l = {0};
        wg_spec s = spec_of(&c->wgs[i], p, fs);
        if (wg_design(&s, &l) < 0)
            too_short(&c->wgs[i], &s, "the rate");
    }
}

/* The lowest allpass order that brings partials 1..12 within half a
 * cent at the default params, at the netlist's rate and at 44.1 and
 * 96 kHz (or the best order up to 32; a voice at another rate may use a
 * lower order), and errors for loops too short for their filters. */
void wg_choose(Circuit *c) {
    double *p = circuit_defaults(c);
    for (int i = 0; i < c->nwgs; i++) {
        Waveguide *w = &c->wgs[i];
        wg_loop l = {0};
        w->M = 1;
        wg_spec s = spec_of(w, p, c->rate);
        if (!(s.B >= 0) || !isfinite(s.B))
            error_at(w->pos, "string '%s' has B = %g; it must be at least 0", w->name, s.B);
        if (!(s.t60 >= 0) || !(s.t60hf >= 0) || !(s.fhf > 0))
            error_at(w->pos, "%s '%s': t60, t60hf and fhf must be positive", w->tube ? "tube" : "string", w->name);
        if (wg_design(&s, &l) < 0)
            too_short(w, &s, ".rate");
        /* the order must serve the usual rates too: a voice runs at the
         * host's rate, and uses a lower order where that suffices */
        if (!(s.B > 0))
            continue; /* one stage tunes a string without stiffness */
        /* the error of each order at each rate, designed once; an order K
         * serves a rate with the orders the voice tries (wg_design) */
        static const int Ks[] = {2, 3, 4, 6, 8, 12, 16, 24, 32};
        static const double rates[] = {0, 44100, 96000};
        double err[3][WG_KMAX + 1];
        for (int r = 0; r < 3; r++)
            for (int j = 0; j <= WG_KMAX; j++)
                err[r][j] = -1;
        double best = 1e300;
        int bestK = 1;
        for (int k = 0; k < (int)(sizeof Ks / sizeof Ks[0]) && best > 0.5; k++) {
            double worst = 0;
            int K = Ks[k];
            for (int r = 0; r < 3 && worst < best; r++) {
                double e = 1e300;
                for (int J = K; J >= 1; J = wg_next_order(J, K)) {
                    if (err[r][J] < 0) {
                        wg_spec sr = s;
                        sr.fs = r ? rates[r] : c->rate;
                        wg_loss(&sr, &l);
                        wg_radiation(&sr, &l);
                        err[r][J] = wg_design_order(&sr, J, sr.nmin, &l) < 0 ? 1e300 : wg_score(&l);
                    }
                    e = fmin(e, err[r][J]);
                }
                worst = fmax(worst, e);
            }
            if (worst < best - 0.01)
                best = worst, bestK = K;
        }
        w->M = bestK;
    }
    for (int i = 0; i < c->nwgs; i++) {
        Waveguide *w = &c->wgs[i];
        for (int j = 0; j < w->ntaps; j++) {
            double x = expr_eval(w->tap_pos[j], p);
            if (!(x > 0 && x < 1) && (!expr_params(w->tap_pos[j]) || !isfinite(x)))
                error_at(w->tap_src[j], "tap '%s' of %s '%s' is at %g of its length; it must lie between 0 and 1",
                         c->nodes[w->tap_node[j]], w->tube ? "tube" : "string", w->name, x);
        }
    }
}
