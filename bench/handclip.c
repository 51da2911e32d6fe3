/* handclip.c - a diode clipper written by hand (see peers.h). */
#include <math.h>

#include "peers.h"

#define MAXIT 50    /* Newton iterations per sample at most */
#define TOL 1e-9    /* V: the step that ends the iteration */

void handclip_init(handclip *d, double r, double c, double is, double nvt, int pair, double fs) {
    d->h = 1.0 / (2.0 * c * fs);
    d->g = 1.0 / r;
    d->is = is;
    d->nvt = nvt;
    d->pair = pair;
    d->v = 0.0;
    d->f1 = 0.0;
    d->maxed = 0;
}

/* The diode current at v, and its slope into *di. */
static double diode(const handclip *d, double v, double *di) {
    double e = exp(v / d->nvt);
    if (d->pair) {
        double r = 1.0 / e;
        *di = d->is * (e + r) / d->nvt;
        return d->is * (e - r);
    }
    *di = d->is * e / d->nvt;
    return d->is * (e - 1.0);
}

/* v - v[n-1] = h (f(v) + f[n-1]) with f(v) = (vin - v)/R - i(v). */
void handclip_process(handclip *d, const double *in, double *out, int n) {
    double v = d->v, f1 = d->f1;
    for (int k = 0; k < n; k++) {
        double rhs = v + d->h * (f1 + d->g * in[k]);
        double i = 0.0, di;
        int it;
        for (it = 0; it < MAXIT; it++) {
            i = diode(d, v, &di);
            double res = v + d->h * (d->g * v + i) - rhs;
            double step = res / (1.0 + d->h * (d->g + di));
            v -= step;
            if (fabs(step) < TOL)
                break;
        }
        if (it == MAXIT)
            d->maxed++;
        i = diode(d, v, &di);
        f1 = d->g * (in[k] - v) - i;
        out[k] = v;
    }
    d->v = v;
    d->f1 = f1;
}
