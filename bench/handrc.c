/* handrc.c - an RC lowpass written by hand (see peers.h). */
#include "peers.h"

void handrc_init(handrc *f, double r, double c, double fs) {
    double k = 2.0 * r * c * fs; /* s = k (1 - z^-1) / (1 + z^-1) over 1/RC */
    f->b0 = 1.0 / (1.0 + k);
    f->a1 = (1.0 - k) / (1.0 + k);
    f->x1 = 0.0;
    f->y1 = 0.0;
}

void handrc_process(handrc *f, const double *in, double *out, int n) {
    double x1 = f->x1, y1 = f->y1;
    for (int i = 0; i < n; i++) {
        double y = f->b0 * (in[i] + x1) - f->a1 * y1;
        x1 = in[i];
        y1 = y;
        out[i] = y;
    }
    f->x1 = x1;
    f->y1 = y1;
}
