/*
 * complex_source.c - a score of a complex (complex_score.c) as a voice
 * class an engine hosts like any compiled voice.
 *
 * The class is built at run time (cx_source_init): its state holds the
 * score's address, the sample rate, the frame of the traversal and one
 * slot per note that may sound at once (the score's maxactive), so
 * process never allocates.  A note's partials are sines whose phases
 * accumulate per sample; a group's six harmonics come from the sine and
 * cosine of its phase by the Chebyshev recurrence.  Every note has a
 * short raised-sine attack and release inside its duration, so a note
 * ends exactly at its end and none overlaps the next of its level.
 */
#include "cx.h"

#include <math.h>
#include <stddef.h>
#include <string.h>

#define ATTACK_S 0.008  /* a note's rise */
#define RELEASE_S 0.03  /* and fall, each at most a quarter of the note */
#define SOFTEN_TO 0.25  /* the top partial falls to this part of its level */
#define SOFTEN_S 0.3    /* with this time constant, after its onset */
#define NYQUIST_USE 0.45 /* harmonics above this fraction of the rate are left out */

typedef struct slot {
    int note;
    double phase; /* cycles, 0..1 */
} slot;

typedef struct cxs_state {
    const cx_score *sc; /* NULL until bound: silence */
    double fs;
    double at;          /* s of silence before the traversal */
    long long frame;    /* of the traversal: negative before it starts */
    int next;           /* the next note to start */
    int nact, cap;
    slot act[];         /* cap slots: the notes sounding */
} cxs_state;

static long long frames(double s, double fs) { return llround(s * fs); }

static void cxs_reset(void *state) {
    cxs_state *st = state;
    st->frame = -frames(st->at, st->fs);
    st->next = st->nact = 0;
}

static void cxs_init(void *state, double fs) {
    cxs_state *st = state;
    memset(st, 0, sizeof *st);
    st->fs = fs;
}

void cx_source_bind(void *state, const void *data) {
    cxs_state *st = state;
    const cx_source *src = data;
    st->sc = src->score;
    st->at = src->at;
    st->cap = src->score->maxactive;
    cxs_reset(st);
}

static int cxs_set_param(void *state, int id, double value) {
    (void)state, (void)id, (void)value;
    return -1;
}

static double cxs_get_param(const void *state, int id) {
    (void)state, (void)id;
    return 0;
}

/* The note's envelope t seconds after its onset. */
static double envelope(const cx_note *n, double t) {
    double a = fmin(ATTACK_S, n->dur / 4), r = fmin(RELEASE_S, n->dur / 4), e = 1;
    if (t < a) {
        double s = sin(M_PI / 2 * t / a);
        e = s * s;
    }
    if (n->dur - t < r) {
        double s = sin(M_PI / 2 * fmax(n->dur - t, 0) / r);
        e *= s * s;
    }
    if (n->kind == CX_TOP) /* the drone of the whole complex steps back once heard */
        e *= SOFTEN_TO + (1 - SOFTEN_TO) * exp(-t / fmin(SOFTEN_S, n->dur / 4));
    return e;
}

/* A group's harmonic weights: from a sine (rough 0) to the six-partial
 * sawtooth 1/k (rough 1), over their sum, so the group never exceeds its
 * amplitude; harmonics past NYQUIST_USE are dropped. */
static void weights(const cx_note *n, double fs, double *w) {
    double sum = 0;
    for (int k = 1; k <= CX_HARMONICS; k++) {
        w[k - 1] = (k == 1 ? 1 - n->rough : 0) + n->rough / k;
        sum += w[k - 1];
    }
    for (int k = 1; k <= CX_HARMONICS; k++)
        w[k - 1] = k * n->freq < NYQUIST_USE * fs ? w[k - 1] / sum : 0;
}

/* Adds note n's frames [a, b) of the traversal into out (whose frame 0
 * is f0). */
static void render_note(const cxs_state *st, slot *s, long long a, long long b, long long f0, double *out) {
    const cx_note *n = &st->sc->note[s->note];
    long long on = frames(n->on, st->fs);
    double inc = n->freq / st->fs, w[CX_HARMONICS], ph = s->phase;
    int group = n->kind == CX_GROUP;
    if (group)
        weights(n, st->fs, w);
    for (long long t = a; t < b; t++) {
        double s1 = sin(2 * M_PI * ph), y = s1;
        if (group) {
            double c2 = 2 * cos(2 * M_PI * ph), sk = s1, sk1 = 0;
            y = w[0] * s1;
            for (int k = 1; k < CX_HARMONICS; k++) {
                double next = c2 * sk - sk1;
                sk1 = sk, sk = next;
                y += w[k] * sk;
            }
        }
        out[t - f0] += n->amp * envelope(n, (double)(t - on) / st->fs) * y;
        ph += inc;
        ph -= ph >= 1 ? 1 : 0;
    }
    s->phase = ph;
}

/* The granular rendering (the paper's section 7.5): the sound is cut
 * into Hann-windowed grains; a larger explosion factor x spaces their
 * onsets further (20 to 100 ms) and shortens them (from the whole space
 * to a fifth of it).  Grains never overlap, so the gate stays within 1. */
static double grain(double x, double t) {
    double space = 0.02 + 0.08 * x, len = space * (1 - 0.8 * x), u = fmod(t, space);
    if (u >= len)
        return 0;
    double s = sin(M_PI * u / len);
    return s * s;
}

/* Starts the notes that begin before frame f1. */
static void admit(cxs_state *st, long long f1) {
    const cx_score *sc = st->sc;
    while (st->next < sc->nnotes && frames(sc->note[st->next].on, st->fs) < f1) {
        if (st->nact < st->cap)
            st->act[st->nact++] = (slot){st->next, 0};
        st->next++;
    }
}

static void cxs_process(void *state, const double *const *in, double *const *out, int nframes) {
    cxs_state *st = state;
    (void)in;
    memset(out[0], 0, sizeof(double) * (size_t)nframes);
    if (!st->sc)
        return;
    long long f0 = st->frame, f1 = f0 + nframes;
    admit(st, f1);
    for (int i = 0; i < st->nact;) {
        const cx_note *n = &st->sc->note[st->act[i].note];
        long long a = frames(n->on, st->fs), b = frames(n->on + n->dur, st->fs);
        render_note(st, &st->act[i], a > f0 ? a : f0, b < f1 ? b : f1, f0, out[0]);
        if (b <= f1)
            st->act[i] = st->act[--st->nact]; /* done: its slot is free */
        else
            i++;
    }
    if (st->sc->granular >= 0)
        for (long long t = f0 > 0 ? f0 : 0; t < f1; t++)
            out[0][t - f0] *= grain(fmin(st->sc->granular, 1), (double)t / st->fs);
    st->frame = f1;
}

/* The sound left, in seconds: it reaches 0 when the traversal ends, and
 * falls all along before that, so an engine never puts the source to
 * sleep while it has something to play. */
static double cxs_energy(const void *state) {
    const cxs_state *st = state;
    if (!st->sc)
        return 0;
    long long left = frames(st->sc->length, st->fs) - st->frame;
    return left > 0 ? (double)left / st->fs : 0;
}

static double cxs_work(const void *state) {
    (void)state;
    return 0;
}

/* A strike with no targets plays the traversal again from now. */
static int cxs_set_ic(void *state, int n, const int *ids, const double *values) {
    cxs_state *st = state;
    (void)ids, (void)values;
    if (n != 0)
        return -1;
    st->frame = 0;
    st->next = st->nact = 0;
    return 0;
}

void cx_source_init(cx_source *src, const cx_score *score, double at) {
    memset(src, 0, sizeof *src);
    src->score = score;
    src->at = at > 0 ? at : 0;
    src->out.name = "out";
    src->out.unit = "";
    wdv_class *c = &src->cls;
    c->name = "complex";
    c->abi_version = WDV_ABI_VERSION;
    c->precision = 64;
    c->state_size = offsetof(cxs_state, act) + sizeof(slot) * (size_t)(score->maxactive > 0 ? score->maxactive : 1);
    c->n_outputs = 1;
    c->outputs = &src->out;
    c->init = cxs_init;
    c->reset = cxs_reset;
    c->set_param = cxs_set_param;
    c->get_param = cxs_get_param;
    c->process = cxs_process;
    c->energy = cxs_energy;
    c->work = cxs_work;
    c->set_ic = cxs_set_ic;
}
