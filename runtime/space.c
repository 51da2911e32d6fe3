/*
 * space.c - distance gains, air absorption and wall tests of the spatial
 * layer (see space.h).
 */
#include "space.h"

#include <math.h>

double space_distance_gain(int model, double d, double ref, double max, double rolloff) {
    if (model == SPACE_NONE)
        return 1;
    d = d < ref ? ref : d > max ? max : d;
    switch (model) {
    case SPACE_INVERSE:
        return ref / (ref + rolloff * (d - ref));
    case SPACE_LINEAR: {
        double g = max > ref ? 1 - rolloff * (d - ref) / (max - ref) : 1;
        return g > 0 ? g : 0;
    }
    case SPACE_EXPONENT:
        return pow(d / ref, -rolloff);
    }
    return 1;
}

/* ISO 9613-1:1993, equations (3) to (5), at T = 293.15 K, 50 % RH. */
double space_air_alpha(double f) {
    const double T = 293.15, T0 = 293.15, T01 = 273.16, hr = 50, pa = 1; /* pa in units of the reference */
    double csat = -6.8346 * pow(T01 / T, 1.261) + 4.6151;
    double h = hr * pow(10, csat) / pa;
    double frO = pa * (24 + 4.04e4 * h * (0.02 + h) / (0.391 + h));
    double frN = pa * pow(T / T0, -0.5) * (9 + 280 * h * exp(-4.170 * (pow(T / T0, -1.0 / 3) - 1)));
    double f2 = f * f;
    return 8.686 * f2 *
           (1.84e-11 / pa * sqrt(T / T0) +
            pow(T / T0, -2.5) * (0.01275 * exp(-2239.1 / T) / (frO + f2 / frO) +
                                 0.1068 * exp(-3352.0 / T) / (frN + f2 / frN)));
}

static double one_pole_db(double p, double w) {
    /* |(1 - p) / (1 - p e^{-jw})|^2 */
    double m2 = (1 - p) * (1 - p) / (1 - 2 * p * cos(w) + p * p);
    return -10 * log10(m2);
}


/* The pole in [0, 1) whose attenuation at w is `db` (>= 0), by bisection. */
static double pole_for(double db, double w) {
    double lo = 0, hi = 1;
    if (db <= 0)
        return 0;
    for (int i = 0; i < 60; i++) {
        double mid = (lo + hi) / 2;
        if (one_pole_db(mid, w) < db)
            lo = mid;
        else
            hi = mid;
    }
    return (lo + hi) / 2;
}

/* Below its corner a one-pole's attenuation in dB grows as f^2, as the
 * absorption of air does; past it, only as fast as 20 dB a decade.  So the
 * 8 kHz target is shared among as many equal poles as keep each of them
 * below 2 dB there (at most SPACE_AIR_POLES), which holds the f^2 shape. */
void space_air_fit(double d, double fs, int *n, double *p) {
    double f8 = fs / 2 * 0.9 < 8000 ? fs / 2 * 0.9 : 8000;
    double t8 = space_air_alpha(f8) * d;
    int k = (int)ceil(t8 / 2);
    k = k < 1 ? 1 : k > SPACE_AIR_POLES ? SPACE_AIR_POLES : k;
    *n = k;
    *p = pole_for(t8 / k, 2 * M_PI * f8 / fs);
}

static double cross(const double o[2], const double a[2], const double b[2]) {
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]);
}

int space_segments_cross(const double a[2], const double b[2], const double c[2], const double d[2]) {
    double d1 = cross(c, d, a), d2 = cross(c, d, b), d3 = cross(a, b, c), d4 = cross(a, b, d);
    return ((d1 > 0 && d2 < 0) || (d1 < 0 && d2 > 0)) && ((d3 > 0 && d4 < 0) || (d3 < 0 && d4 > 0));
}
