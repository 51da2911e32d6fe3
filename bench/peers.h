/*
 * peers.h - the peers bench/chart.c measures beside our voices: circuits
 * written by hand in C (handrc.c, handclip.c), Faust's wdmodels.lib
 * models compiled to C (faustpeer.c over faust -lang c), and STK's
 * Plucked (stkshim.cpp).  Every one runs one instance per object, at a
 * sample rate given to its init, one block of samples at a time, on
 * doubles; none allocates or locks in its process.
 */
#ifndef PEERS_H
#define PEERS_H

/* ---- handrc.c ---- */

/* An RC lowpass (a series R into a grounded C, the output the voltage
 * across C) as the bilinear transform of 1 / (1 + s R C): the
 * trapezoidal rule, one first-order section. */
typedef struct handrc {
    double b0, a1; /* y[n] = b0 (x[n] + x[n-1]) - a1 y[n-1] */
    double x1, y1; /* last input and output, V */
} handrc;

/* r in ohm, c in F, fs in Hz; starts at rest. */
void handrc_init(handrc *f, double r, double c, double fs);
/* n frames of input voltage (V) into the voltage across C (V). */
void handrc_process(handrc *f, const double *in, double *out, int n);

/* ---- handclip.c ---- */

/* A diode clipper: a source drives a series R into a grounded C with a
 * diode (or an antiparallel pair) across it.  The node's equation
 * C dv/dt = (vin - v)/R - i(v), i(v) = Is (exp(v/nVt) - 1) (one diode)
 * or 2 Is sinh(v/nVt) (a pair), stepped by the trapezoidal rule and
 * solved each sample by Newton's method from the last sample's voltage. */
typedef struct handclip {
    double h;      /* T / (2 C), V/A */
    double g;      /* 1 / R, S */
    double is;     /* saturation current, A */
    double nvt;    /* n Vt, V */
    int pair;      /* antiparallel pair */
    double v;      /* voltage across C at the last sample, V */
    double f1;     /* C dv/dt at the last sample, A */
    long maxed;    /* samples whose Newton iteration hit the cap */
} handclip;

/* r in ohm, c in F, is in A, nvt (the ideality n times Vt) in V, fs in
 * Hz; starts at rest. */
void handclip_init(handclip *d, double r, double c, double is, double nvt, int pair, double fs);
/* n frames of input voltage (V) into the voltage across C (V). */
void handclip_process(handclip *d, const double *in, double *out, int n);

/* ---- faustpeer.c: one per Faust class ---- */

/* A class Faust generated from bench/faust/NAME.dsp (one input, one
 * output), with samples crossing as double.  new allocates (not
 * real-time safe); init sets the rate and clears the state. */
typedef struct faust_peer {
    const char *name; /* the class, NAME_d (faust -double) or NAME_f */
    void *(*new_dsp)(void);
    void (*init)(void *dsp, int fs);
    void (*compute)(void *dsp, int n, double **in, double **out);
    void (*delete_dsp)(void *dsp);
} faust_peer;

extern const faust_peer faust_rc_lowpass_d, faust_rc_lowpass_f;
extern const faust_peer faust_diode_clipper_d, faust_diode_clipper_f;

/* ---- stkshim.cpp ---- */

struct stkp;
/* The sample rate of every Plucked made afterwards (STK keeps it globally). */
void stkp_set_rate(double fs);
/* A Plucked for frequencies down to `lowest` Hz, its noise seeded with
 * `seed`, or NULL.  Allocates. */
struct stkp *stkp_new(double lowest, unsigned seed);
void stkp_note_on(struct stkp *s, double freq, double amp);
void stkp_tick(struct stkp *s, double *buf, int n);
void stkp_free(struct stkp *s);

#endif
