/*
 * space.h - the physics of the spatial layer, shared by the engine and
 * its tests.  Internal to libwdrt.
 *
 * Sound leaves a source, travels at c and arrives late, quieter and
 * duller.  Here: the distance gains OpenAL defines (clamped at the
 * reference and maximum distances), air absorption after ISO 9613-1
 * (20 °C, 50 % relative humidity, one atmosphere) and a pair of one-pole
 * low-passes fitted to it per distance, the retarded time a listener hears
 * a moving source at, a four-point Lagrange reader for delay lines read at
 * moving fractional delays, and segment tests for walls.  Units: metres,
 * seconds, Hz, m/s.  Everything here is real-time safe unless it says
 * otherwise.
 */
#ifndef WDRT_SPACE_H
#define WDRT_SPACE_H

#include <stddef.h>

#if defined(__GNUC__)
#define SPACE_HIDDEN __attribute__((visibility("hidden")))
#else
#define SPACE_HIDDEN
#endif

enum { SPACE_NONE, SPACE_INVERSE, SPACE_LINEAR, SPACE_EXPONENT };

/* Gain at distance d (m) by model SPACE_*: OpenAL's clamped forms, with d
 * clamped to [ref, max] first:
 *   inverse   ref / (ref + rolloff (d - ref))
 *   linear    1 - rolloff (d - ref) / (max - ref)      (not below 0)
 *   exponent  (d / ref)^-rolloff
 * SPACE_NONE gives 1. */
SPACE_HIDDEN double space_distance_gain(int model, double d, double ref, double max, double rolloff);

/* ISO 9613-1 attenuation coefficient of air for a pure tone of f Hz at
 * 20 °C, 50 % relative humidity and 101.325 kPa, in dB per metre. */
SPACE_HIDDEN double space_air_alpha(double f);

/* Air absorption over d metres as *n equal one-pole low-passes
 * y += (1 - p)(x - y) in series (at most SPACE_AIR_POLES): their
 * attenuation matches ISO 9613-1 at 8 kHz (or 0.45 fs, if lower) and,
 * quadratic in f below their corners as the absorption is, follows it
 * below (within 1 dB at 1, 4 and 8 kHz up to about 200 m; beyond, the
 * high frequencies are more than 30 dB down and the fit is looser).  A
 * search: the engine tabulates it at init. */
#define SPACE_AIR_POLES 8
SPACE_HIDDEN void space_air_fit(double d, double fs, int *n, double *p);


/* A four-point Lagrange read of the delay line buf (mask + 1 samples, a
 * power of two) at fractional frame `at` (sample i at buf[i & mask]). */
static inline double space_read(const double *buf, unsigned long long mask, double at) {
    long long i = (long long)at - (at < 0);
    double x = at - (double)i;
    double xm1 = x - 1, xm2 = x - 2, xp1 = x + 1;
    double hm1 = -x * xm1 * xm2 / 6, h0 = xp1 * xm1 * xm2 / 2, h1 = -xp1 * x * xm2 / 2, h2 = xp1 * x * xm1 / 6;
    unsigned long long u = (unsigned long long)i;
    return hm1 * buf[(u - 1) & mask] + h0 * buf[u & mask] + h1 * buf[(u + 1) & mask] + h2 * buf[(u + 2) & mask];
}

/* Whether segments (a, b) and (c, d) of the plane cross. */
SPACE_HIDDEN int space_segments_cross(const double a[2], const double b[2], const double c[2], const double d[2]);

#endif
