/*
 * score.h - the short score examples/embed.c plays: a phrase on a piano
 * key pool (scenes/piano_key.wdn), with the dampers lifted for the last
 * chord, and the function that posts it into an engine.  Shared with
 * tests/test_embed.c, which renders it again through a voice loaded at
 * run time and expects the same samples.
 */
#ifndef WDC_EXAMPLE_SCORE_H
#define WDC_EXAMPLE_SCORE_H

#include <string.h>

#include "wdrt.h"

typedef struct score_note {
    double t;     /* s */
    double f0;    /* Hz */
    double speed; /* hammer speed, m/s */
} score_note;

#define SCORE_RATE 48000.0
#define SCORE_SECONDS 6.0
#define SCORE_DAMPER_DOWN 50.0 /* N s/m: a key's damper on its strings */

static const score_note score_notes[] = {
    {0.10, 261.63, 2.0}, {0.40, 293.66, 1.6}, {0.70, 329.63, 1.8}, {1.00, 349.23, 1.4},
    {1.30, 392.00, 2.4}, {1.90, 329.63, 1.2}, {2.20, 261.63, 1.0}, {3.00, 130.81, 2.2},
    {3.00, 196.00, 1.8}, {3.00, 261.63, 1.8}, {3.00, 329.63, 2.0},
};
#define SCORE_NOTES ((int)(sizeof score_notes / sizeof *score_notes))

/* Each key of the phrase is let go (its damper comes down) this long
 * after it was struck; the final chord rings. */
#define SCORE_HOLD 0.28

/* The index of a param or strike target of the class, by name. */
static int param_id(const wdv_class *c, const char *name) {
    for (int i = 0; i < c->n_params; i++)
        if (!strcmp(c->params[i].name, name))
            return i;
    return -1;
}

static int ic_id(const wdv_class *c, const char *name) {
    for (int i = 0; i < c->n_ic_targets; i++)
        if (!strcmp(c->ic_targets[i].name, name))
            return i;
    return -1;
}

/* Posts the score: for each note a play from pool 0, its pitch, its
 * strike, and its damper coming down when the key is let go.  The pitch
 * is set with wdrt_engine_set_prepared: the design of the strings' loops
 * for it is made here, on the control side, so the audio side only takes
 * it (the score holds fewer notes than the engine has design slots). */
static int post_score(wdrt_engine *e, const wdv_class *c) {
    const int f0 = param_id(c, "f0"), dmp = param_id(c, "dmp");
    const int ids[4] = {ic_id(c, "v(h1)"), ic_id(c, "x(h1)"), ic_id(c, "v(h2)"), ic_id(c, "x(h2)")};
    for (int i = 0; i < SCORE_NOTES; i++) {
        const score_note *n = &score_notes[i];
        uint64_t at = (uint64_t)(n->t * SCORE_RATE + 0.5);
        double vals[4] = {n->speed, -1e-3, n->speed, -1e-3};
        wdrt_voice note;
        if (wdrt_engine_play(e, at, 0, 1.0, 0, &note) != WDRT_OK ||
            wdrt_engine_set_prepared(e, at, note, 1, &f0, &n->f0) != WDRT_OK ||
            wdrt_engine_strike(e, at, note, 4, ids, vals) != WDRT_OK)
            return -1;
        if (n->t < 3.0 && wdrt_engine_set(e, at + (uint64_t)(SCORE_HOLD * SCORE_RATE), note, dmp,
                                          SCORE_DAMPER_DOWN) != WDRT_OK)
            return -1;
    }
    return 0;
}

#endif
