/*
 * test_passive.c - the kernels that step contacts, nonlinear inductors and
 * nonlinear capacitors (templates/nl_law.c.tmpl, nl_passive.c.tmpl,
 * nl_memcap.c.tmpl), the voice's own code, on states drawn at random.
 *
 *   - el_mean, the mean of the elastic law over an interval, against
 *     composite Gauss-Legendre quadrature in long double (exact to
 *     rounding on each piece where the law is smooth): within 1e-12 of
 *     the larger of the mean and the law's size on the interval, for
 *     intervals from 1e-12 to 10 of their ends' size, across a contact's
 *     0 and a curve's points;
 *   - el_force and cap_h, the port laws, at 4000 states each with 200
 *     velocities (voltages) around the state: passive, the energy the
 *     network takes back over the step, dX (f + fp) / 2, never exceeds
 *     what the element stored, U(X1) - U(X0), beyond rounding (1e-12 of
 *     the energies involved); rising in v (never falling by more than
 *     1e-12 of the force's size); continuous (between velocities 1e-9
 *     apart the force moves by no more than the slope bound, 1/R plus
 *     the law's slope, times the step, and 1e-12 of its size);
 *   - where the trapezoidal target is passive and inside the clamp the
 *     force is the elastic law at the new state, exactly as computed;
 *   - el_solve and cap_solve meet their port law: |v + R f(v) - a| below
 *     1e-9 of |a| + R |f| for random waves (for cap_solve, plus what
 *     rounding its unknown to double makes of it through the slope of the
 *     port law), and the first returns a itself when the contact stays
 *     open with no force.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testlib.h"

#include "../templates/nl_diode_i.c.tmpl"
#include "../templates/nl_g.c.tmpl"
#include "../templates/nl_memory.c.tmpl"
#include "../templates/nl_law.c.tmpl"
#include "../templates/nl_passive.c.tmpl"
#include "../templates/nl_memcap.c.tmpl"

static const double curve_v[] = {-3, -1, 0, 0.5, 1, 3};
static const double curve_i[] = {-2e-3, -1e-3, 0, 0.2e-3, 1e-3, 1.3e-3};

/* The laws tried: a felt, a felt with damping, a diode, a pair, a curve. */
static el_law make_law(int kind) {
    el_law L = {0, 0, 1, 0, 0, 1, 0, 0, NULL, NULL};
    switch (kind) {
    case 0: L.contact = 1, L.k = 4.5e9, L.alpha = 2.5; break;
    case 1: L.contact = 1, L.k = 1e8, L.alpha = 3.0, L.lambda = 0.3; break;
    case 2: L.Is = 2.52e-9, L.nVt = 1.752 * 0.02585; break;
    case 3: L.Is = 1e-12, L.nVt = 0.02585, L.pair = 1; break;
    default: L.n = 6, L.cv = curve_v, L.ci = curve_i; break;
    }
    return L;
}
#define NKINDS 5

/* A typical size of the law's coordinate: felt compressions of some
 * tenths of a mm, diode voltages of some tenths of a volt. */
static double scale_of(int kind) { return kind < 2 ? 3e-4 : kind < 4 ? 0.4 : 1.5; }

/* The elastic law in long double, for the references. */
static long double law_ld(const el_law *L, long double x) {
    if (L->contact)
        return x > 0 ? (long double)L->k * powl(x, L->alpha) : 0.0L;
    if (L->n == 0) {
        long double u = x / L->nVt;
        return L->pair ? 2.0L * L->Is * sinhl(u) : L->Is * expm1l(u);
    }
    int k = 0;
    while (k + 2 < L->n && x >= L->cv[k + 1])
        k++;
    long double s = ((long double)L->ci[k + 1] - L->ci[k]) / ((long double)L->cv[k + 1] - L->cv[k]);
    return L->ci[k] + (x - L->cv[k]) * s;
}

/* Gauss-Legendre, 5 points, composite over n pieces of [a, b], each piece
 * cut further at the law's corners. */
static long double gl_piece(const el_law *L, long double a, long double b) {
    static const long double x[5] = {0.0L, 0.538469310105683091036314420700208805L,
                                     -0.538469310105683091036314420700208805L,
                                     0.906179845938663992797626878299392965L,
                                     -0.906179845938663992797626878299392965L};
    static const long double w[5] = {0.568888888888888888888888888888888889L,
                                     0.478628670499366468041291514835638192L,
                                     0.478628670499366468041291514835638192L,
                                     0.236926885056189087514264040719917363L,
                                     0.236926885056189087514264040719917363L};
    long double m = 0.5L * (a + b), h = 0.5L * (b - a), s = 0;
    for (int k = 0; k < 5; k++)
        s += w[k] * law_ld(L, m + h * x[k]);
    return s * h;
}

static long double mean_ref(const el_law *L, double a, double b) {
    long double lo = fminl(a, b), hi = fmaxl(a, b), cuts[16];
    int nc = 0;
    cuts[nc++] = lo;
    if (L->contact && lo < 0 && hi > 0)
        cuts[nc++] = 0;
    for (int j = 0; !L->contact && j < L->n; j++)
        if (L->cv[j] > lo && L->cv[j] < hi)
            cuts[nc++] = L->cv[j];
    cuts[nc++] = hi;
    long double s = 0;
    for (int j = 0; j + 1 < nc; j++)
        for (int p = 0; p < 512; p++) {
            long double x0 = cuts[j] + (cuts[j + 1] - cuts[j]) * p / 512.0L;
            long double x1 = cuts[j] + (cuts[j + 1] - cuts[j]) * (p + 1) / 512.0L;
            s += gl_piece(L, x0, x1);
        }
    return s / (hi - lo);
}

/* Stored energy in long double, for the passivity checks: the integral
 * of the law from 0, in closed form (a curve: trapezoids between its
 * points, exact for it). */
static long double energy_ld(const el_law *L, double X) {
    if (L->contact)
        return X > 0 ? (long double)L->k * powl(X, L->alpha + 1) / (L->alpha + 1) : 0.0L;
    if (L->n == 0) {
        long double V = L->nVt, u = X / V;
        return L->pair ? 2.0L * L->Is * V * (coshl(u) - 1.0L) : L->Is * (V * expm1l(u) - X);
    }
    long double s = 0, t = 0;
    for (int j = 0; j <= L->n; j++) {
        int k = X > 0 ? j : L->n - 1 - j;
        long double u = j < L->n ? (long double)L->cv[k] : (long double)X;
        if (j < L->n && !(X > 0 ? u > 0 && u < X : u < 0 && u > X))
            continue;
        s += 0.5L * (u - t) * (law_ld(L, t) + law_ld(L, u));
        t = u;
    }
    return s;
}

static void test_mean(void **state) {
    (void)state;
    tl_rng rng;
    tl_rng_seed(&rng, 11);
    double worst = 0;
    for (int kind = 0; kind < NKINDS; kind++) {
        el_law L = make_law(kind);
        for (int t = 0; t < 3000; t++) {
            double sc = scale_of(kind);
            double a = sc * (2 * tl_rng_uniform(&rng) - 0.5);
            double w = fabs(a) * pow(10, -12 + 13 * tl_rng_uniform(&rng)) + 1e-300;
            double b = tl_rng_uniform(&rng) < 0.5 ? a + w : a - w;
            double da, db, m = el_mean(&L, a, b, el_F(&L, a, &da), el_F(&L, b, &db));
            long double r = mean_ref(&L, a, b);
            double d, size = fmax(fabs(el_F(&L, a, &d)), fabs(el_F(&L, b, &d)));
            double err = fabs((double)(m - r)) / fmax(size, 1e-300);
            if (size > 0 && err > worst)
                worst = err;
            if (!(err <= 1e-12 || size == 0))
                fail_msg("law %d: mean over [%.17g, %.17g] is %.17g, quadrature %.17Lg", kind, a, b, m, r);
        }
    }
    print_message("el_mean: largest error %.3g of the law's size over the interval\n", worst);
}

/* The trapezoidal target of el_force at v, recomputed here. */
static double target(const el_law *L, double v, double X0, double vp, double fp, double h2) {
    double d, F1 = el_F(L, X0 + h2 * (v + vp), &d);
    if (L->contact && L->lambda != 0)
        F1 = 1 + L->lambda * v > 0 ? F1 * (1 + L->lambda * v) : 0;
    return 0.5 * (fp + F1);
}

static void test_force(void **state) {
    (void)state;
    tl_rng rng;
    tl_rng_seed(&rng, 12);
    const double h2 = 0.5 / 48000;
    long clamped = 0, followed = 0;
    double worst = 0;
    for (int kind = 0; kind < NKINDS; kind++) {
        el_law L = make_law(kind);
        double sc = scale_of(kind);
        for (int t = 0; t < 4000; t++) {
            double X0 = sc * (2 * tl_rng_uniform(&rng) - 0.5);
            double vs = sc / h2 * 0.05; /* velocities that move X by some % of its size a sample */
            double vp = vs * (2 * tl_rng_uniform(&rng) - 1);
            double d, F0 = el_F(&L, X0, &d);
            /* the last force: the elastic law, or off it (a residual) */
            double fp = tl_rng_uniform(&rng) < 0.5 ? F0 : F0 + (fabs(F0) + 1e-3) * (2 * tl_rng_uniform(&rng) - 1);
            double R = vs / (fabs(F0) + 1e-3) * pow(10, -2 + 3 * tl_rng_uniform(&rng));
            double fprev = -INFINITY, vprev = 0;
            for (int j = 0; j < 200; j++) {
                double v = vs * (-2 + 4 * j / 199.0), df;
                double f = el_force(&L, v, X0, F0, vp, fp, h2, R, &df);
                double X1 = X0 + h2 * (v + vp);
                long double give = -(long double)(X1 - X0) * 0.5L * ((long double)f + fp);
                long double held = energy_ld(&L, X0) - energy_ld(&L, X1);
                long double scale = fabsl(energy_ld(&L, X0)) + fabsl(energy_ld(&L, X1)) +
                                    fabsl((long double)(X1 - X0) * 0.5L * (fabs(f) + fabs(fp))) + 1e-300L;
                double over = (double)((give - held) / scale);
                if (over > worst)
                    worst = over;
                if (!(over <= 1e-12))
                    fail_msg("law %d: X0 %.17g vp %.17g fp %.17g R %.17g v %.17g: gives back %.17Lg, held %.17Lg",
                             kind, X0, vp, fp, R, v, give, held);
                double size = fabs(f) + fabs(fp) + fabs(F0);
                if (!(f >= fprev - 1e-12 * size))
                    fail_msg("law %d: the force falls from %.17g to %.17g between v = %.17g and %.17g", kind, fprev,
                             f, vprev, v);
                double g = 0.5 * (f + fp), tg = target(&L, v, X0, vp, fp, h2);
                if (g == tg)
                    followed++;
                else
                    clamped++;
                /* continuity: a step of 1e-9 vs moves f by at most the
                 * slope bound times it */
                double dv = 1e-9 * vs, df2;
                double f2 = el_force(&L, v + dv, X0, F0, vp, fp, h2, R, &df2);
                double F2, d2;
                F2 = el_F(&L, X0 + h2 * (v + dv + vp), &d2);
                double bound = (1 / R + 2 * fmax(fmax(df, df2), d2 * h2 * (1 + fabs(L.lambda * v)) + fabs(F2 * L.lambda))) * dv;
                if (!(fabs(f2 - f) <= 2 * bound + 1e-12 * size))
                    fail_msg("law %d: the force jumps from %.17g to %.17g between v = %.17g and %.17g", kind, f, f2, v,
                             v + dv);
                fprev = f;
                vprev = v;
            }
        }
    }
    print_message("el_force: %ld points on the trapezoidal target, %ld clamped; largest energy returned beyond "
                  "what was held %.3g of the energies\n", followed, clamped, worst);
    assert_true(followed > 0 && clamped > 0);
}

static void test_capacitor(void **state) {
    (void)state;
    tl_rng rng;
    tl_rng_seed(&rng, 13);
    const double h2 = 0.5 / 48000;
    double worst = 0;
    for (int kind = 2; kind < NKINDS; kind++) {
        el_law L = make_law(kind);
        double sc = scale_of(kind);
        for (int t = 0; t < 4000; t++) {
            double u0 = sc * (2 * tl_rng_uniform(&rng) - 0.5), d;
            double vp = u0 + sc * 0.2 * (2 * tl_rng_uniform(&rng) - 1);
            double ip = 1e-3 * (2 * tl_rng_uniform(&rng) - 1);
            double R = pow(10, 1 + 3 * tl_rng_uniform(&rng));
            double vprev = -INFINITY;
            for (int j = 0; j < 200; j++) {
                double u1 = u0 + sc * (-1 + 2 * j / 199.0), v, dh;
                cap_h(&L, u1, 0, R, u0, el_F(&L, u0, &d), vp, ip, h2, &v, &dh);
                long double dq = (long double)el_F(&L, u1, &d) - el_F(&L, u0, &d);
                /* E(q) = u g(u) - G(u) */
                long double E0 = u0 * (long double)el_F(&L, u0, &d) - energy_ld(&L, u0);
                long double E1 = u1 * (long double)el_F(&L, u1, &d) - energy_ld(&L, u1);
                long double give = -dq * 0.5L * ((long double)v + vp), held = E0 - E1;
                long double scale = fabsl(E0) + fabsl(E1) + fabsl(dq * 0.5L * (fabs(v) + fabs(vp))) + 1e-300L;
                double over = (double)((give - held) / scale);
                if (over > worst)
                    worst = over;
                if (!(over <= 1e-12))
                    fail_msg("law %d: u0 %.17g vp %.17g ip %.17g R %.17g u1 %.17g: gives back %.17Lg, held %.17Lg",
                             kind, u0, vp, ip, R, u1, give, held);
                if (!(v >= vprev - 1e-12 * (fabs(v) + fabs(vp))))
                    fail_msg("law %d: the voltage falls from %.17g to %.17g as u1 rises to %.17g", kind, vprev, v, u1);
                vprev = v;
            }
            /* the solver meets the port law */
            double a = 4 * sc * (2 * tl_rng_uniform(&rng) - 1), v, dh;
            double u = cap_solve(&L, a, R, u0, vp, ip, h2, 1e-12, 50, &v);
            double h = cap_h(&L, u, a, R, u0, el_F(&L, u0, &d), vp, ip, h2, &v, &dh);
            double i = (el_F(&L, u, &d) - el_F(&L, u0, &d)) / h2 - ip;
            /* u is known to its last digits only, which the slope of h
             * (large where the charge grows steeply) magnifies */
            if (!(fabs(h) <= 1e-9 * (fabs(a) + R * fabs(i) + fabs(v)) + 8 * DBL_EPSILON * fabs(u) * dh))
                fail_msg("law %d: cap_solve leaves a residual %.17g", kind, h);
        }
    }
    print_message("cap_h: largest energy returned beyond what was held %.3g of the energies\n", worst);
}

static void test_solve(void **state) {
    (void)state;
    tl_rng rng;
    tl_rng_seed(&rng, 14);
    const double h2 = 0.5 / 48000;
    for (int kind = 0; kind < NKINDS; kind++) {
        el_law L = make_law(kind);
        double sc = scale_of(kind);
        for (int t = 0; t < 4000; t++) {
            double X0 = sc * (2 * tl_rng_uniform(&rng) - 0.5), d;
            double vs = sc / h2 * 0.05, vp = vs * (2 * tl_rng_uniform(&rng) - 1);
            double F0 = el_F(&L, X0, &d), fp = F0 * (1 + 0.1 * (2 * tl_rng_uniform(&rng) - 1));
            double R = vs / (fabs(F0) + 1e-3) * pow(10, -2 + 3 * tl_rng_uniform(&rng));
            double a = 3 * vs * (2 * tl_rng_uniform(&rng) - 1), df;
            double v = el_solve(&L, a, R, X0, vp, fp, h2, 1e-12, 50);
            double f = el_force(&L, v, X0, F0, vp, fp, h2, R, &df);
            if (!(fabs(v + R * f - a) <= 1e-9 * (fabs(a) + R * fabs(f))))
                fail_msg("law %d: el_solve leaves a residual %.17g", kind, v + R * f - a);
        }
    }
    /* a contact that stays open with no force returns the wave as it came */
    el_law L = make_law(0);
    assert_true(el_solve(&L, 0.7, 1e-3, -1e-3, 2.0, 0, h2, 1e-12, 50) == 0.7);
}

int main(void) {
    (void)mem_G; /* the voices' energy, not stepped here */
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_mean),
        cmocka_unit_test(test_force),
        cmocka_unit_test(test_capacitor),
        cmocka_unit_test(test_solve),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
