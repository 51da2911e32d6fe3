/*
 * hammer_ode.c - a high-accuracy solution of the felt hammer thrown at the
 * sprung bar of netlists/hammer_bar.wdn, the continuous-time reference of
 * tests/test_hammer.c.  tests/ref/hammer_ode.sh compiles and runs it.
 *
 * The system (SI units, x positive in the direction of the throw):
 *
 *     hammer  mh xh'' = -F                    mh = 8.7 g
 *     bar     mb xb'' =  F - K xb - c xb'     mb = 30 g, K = 106.6 kN/m,
 *                                             c = 0.5 N s/m
 *     felt    F = max(0, k C^alpha (1 + lambda C'))  for C = xh - xb > 0,
 *             F = 0 otherwise                 k = 4.5e9, alpha = 2.5,
 *                                             lambda = 0.1 s/m
 *
 * from xh = -1 mm, xh' = 2 m/s, xb = xb' = 0 at t = 0.
 *
 * Method: until the hammer touches the bar nothing moves but the hammer,
 * so the touch is exact: t = 1 mm / (2 m/s) = 0.5 ms.  From there on, the
 * classical fourth-order Runge-Kutta method in long double with a fixed
 * step: each 1/48000 s sample interval is cut into M equal steps
 * (M = 20834 by default: h = 1.00 ns).  The force switches on and off
 * where C crosses zero, where it is not smooth; a step across a crossing
 * is replaced by a step that ends exactly on it (found by bisection on the
 * length of that step, to 1e-20 s) followed by the rest, so every step
 * integrates a smooth right-hand side.  The force's maximum is found from
 * a parabola through the largest value on the step grid and its two
 * neighbours.
 *
 * Usage: hammer_ode [M] [T_END]
 *   M      steps per sample interval (default 20834)
 *   T_END  seconds of force samples written (default 2e-3)
 * Writes to stdout:
 *
 *     # comment lines
 *     peak_force_N,VALUE
 *     peak_time_s,VALUE
 *     contact_start_s,VALUE
 *     contact_end_s,VALUE
 *     contact_duration_s,VALUE
 *     t_s,force_N
 *     t,F          one row per t = n/48000 s, n = 0 .. T_END*48000
 *
 * with 17 significant digits.  Integration goes on past T_END until the
 * first contact has ended; a second contact inside the written span is
 * reported on stderr (and makes the exit status 1).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#define FS 48000.0L

static const long double MH = 8.7e-3L, MB = 30e-3L, KB = 106.6e3L,
                         CB = 0.5L, KF = 4.5e9L, ALPHA = 2.5L,
                         LAMBDA = 0.1L;

typedef struct st {
    long double xh, vh, xb, vb;
} st;

static long double felt(const st *s)
{
    long double c = s->xh - s->xb;
    if (c <= 0)
        return 0;
    long double f = KF * powl(c, ALPHA) * (1 + LAMBDA * (s->vh - s->vb));
    return f > 0 ? f : 0;
}

static st deriv(const st *s)
{
    long double f = felt(s);
    st d;
    d.xh = s->vh;
    d.vh = -f / MH;
    d.xb = s->vb;
    d.vb = (f - KB * s->xb - CB * s->vb) / MB;
    return d;
}

static st axpy(const st *s, long double a, const st *d)
{
    st r = {s->xh + a * d->xh, s->vh + a * d->vh, s->xb + a * d->xb,
            s->vb + a * d->vb};
    return r;
}

static st rk4(const st *s, long double h)
{
    st k1 = deriv(s);
    st y = axpy(s, h / 2, &k1);
    st k2 = deriv(&y);
    y = axpy(s, h / 2, &k2);
    st k3 = deriv(&y);
    y = axpy(s, h, &k3);
    st k4 = deriv(&y);
    st r;
    r.xh = s->xh + h / 6 * (k1.xh + 2 * k2.xh + 2 * k3.xh + k4.xh);
    r.vh = s->vh + h / 6 * (k1.vh + 2 * k2.vh + 2 * k3.vh + k4.vh);
    r.xb = s->xb + h / 6 * (k1.xb + 2 * k2.xb + 2 * k3.xb + k4.xb);
    r.vb = s->vb + h / 6 * (k1.vb + 2 * k2.vb + 2 * k3.vb + k4.vb);
    return r;
}

static int in_contact(const st *s) { return s->xh - s->xb > 0; }

/* Event log. */
static long double t_start[16], t_end[16];
static int nstart, nend;

/* Peak tracking on the step grid: the last three (t, F). */
static long double pk_f = -1, pk_t, pk_prev_f, pk_next_f, pk_h;
static int pk_need_next;
static long double last_f;

static void observe(long double t, long double f)
{
    if (pk_need_next) {
        pk_next_f = f;
        pk_h = t - pk_t;
        pk_need_next = 0;
    }
    if (f > pk_f) {
        pk_f = f;
        pk_t = t;
        pk_prev_f = last_f;
        pk_need_next = 1;
    }
    last_f = f;
}

/* Advances s from t by h, splitting the step where C crosses zero. */
static void step(st *s, long double *t, long double h)
{
    st n = rk4(s, h);
    int was = in_contact(s), now = in_contact(&n);
    /* a step that starts exactly on a crossing has nothing to locate */
    if (was == now || s->xh - s->xb == 0) {
        *s = n;
        *t += h;
        observe(*t, felt(s));
        return;
    }
    /* the crossing lies in (0, h]: bisect the length of the first part */
    long double lo = 0, hi = h;
    for (int it = 0; it < 200 && hi - lo > 1e-20L; it++) {
        long double mid = (lo + hi) / 2;
        st m = rk4(s, mid);
        if (in_contact(&m) == was)
            lo = mid;
        else
            hi = mid;
    }
    /* land on the crossing from the side the step started on, then go on */
    st a = rk4(s, lo);
    long double tc = *t + lo;
    if (was) {
        if (nend < 16)
            t_end[nend++] = tc;
    } else {
        if (nstart < 16)
            t_start[nstart++] = tc;
    }
    /* from the crossing on, the rest of the step lies on the other side */
    st b = rk4(&a, h - lo);
    *s = b;
    *t += h;
    observe(*t, felt(s));
}

int main(int argc, char **argv)
{
    long m = argc > 1 ? atol(argv[1]) : 20834;
    double tspan = argc > 2 ? atof(argv[2]) : 2e-3;
    if (m < 1 || !(tspan > 0)) {
        fprintf(stderr, "usage: hammer_ode [M] [T_END]\n");
        return 2;
    }
    long nsamp = lround(tspan * (double)FS);
    long double *fs = malloc((size_t)(nsamp + 1) * sizeof *fs);
    if (!fs)
        return 2;
    /* Free flight, solved exactly: the bar rests at its equilibrium and
     * the hammer closes the 1 mm gap at 2 m/s, touching at t = 0.5 ms. */
    const long double xh0 = -1e-3L, vh0 = 2.0L;
    long double tc = -xh0 / vh0;
    t_start[nstart++] = tc;
    long n0 = (long)ceill(tc * FS - 1e-6L);
    for (long k = 0; k < n0 && k <= nsamp; k++)
        fs[k] = 0;
    st s = {0, vh0, 0, 0};
    long double t = tc;
    /* from the touch to the first sample time on or after it */
    long double h0 = ((long double)n0 / FS - tc) / (long double)m;
    if (h0 * (long double)m < 1e-15L)
        h0 = 0; /* the touch falls on a sample time, up to rounding */
    for (long k = 0; h0 > 0 && k < m; k++) {
        t = tc + (long double)k * h0;
        step(&s, &t, h0);
    }
    long double h = 1 / FS / (long double)m;
    long n = n0;
    if (n <= nsamp)
        fs[n] = felt(&s);
    /* the samples, then on until the first contact has ended */
    while (n < nsamp || nend == 0) {
        long double t0 = (long double)n / FS;
        for (long k = 0; k < m; k++) {
            t = t0 + (long double)k * h;
            step(&s, &t, h);
        }
        n++;
        t = (long double)n / FS;
        if (n <= nsamp)
            fs[n] = felt(&s);
        if (n > (long)(0.1L * FS)) {
            fprintf(stderr, "hammer_ode: no end of contact within 0.1 s\n");
            return 1;
        }
    }
    if (nstart < 1 || nend < 1) {
        fprintf(stderr, "hammer_ode: no contact found\n");
        return 1;
    }
    /* the vertex of the parabola through the peak and its neighbours */
    long double d = pk_prev_f - 2 * pk_f + pk_next_f;
    long double off = d < 0 ? pk_h * (pk_prev_f - pk_next_f) / (2 * d) : 0;
    long double peak = pk_f - (pk_prev_f - pk_next_f) * (pk_prev_f - pk_next_f) /
                                  (8 * (d < 0 ? d : -1));
    if (!(d < 0))
        peak = pk_f;
    long double tpk = pk_t + off;

    int bad = 0;
    for (int k = 1; k < nstart; k++)
        if (t_start[k] <= (long double)nsamp / FS) {
            fprintf(stderr, "hammer_ode: a second contact starts at %.12Lg s\n",
                    t_start[k]);
            bad = 1;
        }

    printf("# felt hammer thrown at the sprung bar of netlists/hammer_bar.wdn\n");
    printf("# RK4 in long double, %ld steps per 1/48000 s (h = %.6Lg s), "
           "contact crossings located to 1e-20 s\n", m, h);
    printf("peak_force_N,%.17Lg\n", peak);
    printf("peak_time_s,%.17Lg\n", tpk);
    printf("contact_start_s,%.17Lg\n", t_start[0]);
    printf("contact_end_s,%.17Lg\n", t_end[0]);
    printf("contact_duration_s,%.17Lg\n", t_end[0] - t_start[0]);
    printf("t_s,force_N\n");
    for (long k = 0; k <= nsamp; k++)
        printf("%.17Lg,%.17Lg\n", (long double)k / FS, fs[k]);
    free(fs);
    return bad;
}
