/*
 * complex_score.c - the additive score of a tree of waves (Axen and
 * Choi, section 7): one note per node of the tree, its pitch from the
 * node's size, its timbre from how far it turns, its time from the
 * traversal built bottom up, its level from a share of full scale fixed
 * per dimension.  See cx.h (cx_score_new) for the rules.
 */
#include "cx.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define TOP_SHARE 0.2   /* of full scale: the 100 Hz partial of the whole complex */
#define WAVE_SHARE 0.7  /* shared equally by the levels below the top */
#define END_SLACK 1e-3  /* s: notes that meet are counted as overlapping when sizing the voice */

cx_sound_opts cx_sound_opts_init(void) {
    cx_sound_opts o;
    o.tempo = 1;
    o.step = 0.24;
    o.offset = 0.04;
    o.granular = -1;
    return o;
}

double cx_freq(int v, int n) {
    if (v >= n || n <= 1)
        return 100;
    double r = (pow(2, 4 * (1 - log((double)v) / log((double)n))) - 1) / 15;
    return 100 + 1500 * r;
}

/* Durations, bottom up: children have higher indices than their parent,
 * so one backward pass sees every child before its parent. */
static void durations(const cx_tree *T, double step, double offset, double *dur) {
    for (int i = T->nnodes - 1; i >= 0; i--) {
        const cx_node *n = &T->node[i];
        double total = 0, wave = 0;
        for (int c = 0; c < n->nchild; c++) {
            const cx_node *k = &T->node[n->first + c];
            double end = (k->comp - 1) * offset + dur[n->first + c];
            wave = end > wave ? end : wave;
            if (k->comp == k->ncomp)
                total += wave, wave = 0;
        }
        dur[i] = n->nchild ? total : step;
    }
}

/* Onsets, top down: the tops one after another; a node's waves one
 * after another from its onset, a wave's components offset by turns. */
static void onsets(const cx_tree *T, double offset, const double *dur, double *on) {
    double t = 0;
    for (int i = 0; i < T->nnodes && T->node[i].parent < 0; i++)
        on[i] = t, t += dur[i];
    for (int i = 0; i < T->nnodes; i++) {
        const cx_node *n = &T->node[i];
        double wave = on[i], len = 0;
        for (int c = 0; c < n->nchild; c++) {
            const cx_node *k = &T->node[n->first + c];
            on[n->first + c] = wave + (k->comp - 1) * offset;
            double end = (k->comp - 1) * offset + dur[n->first + c];
            len = end > len ? end : len;
            if (k->comp == k->ncomp)
                wave += len, len = 0;
        }
    }
}

/* A node's share of its level's amplitude: its parent's, divided among
 * the components of its wave, which sound together. */
static void shares(const cx_tree *T, double *share) {
    for (int i = 0; i < T->nnodes; i++) {
        const cx_node *n = &T->node[i];
        share[i] = n->parent < 0 ? 1 : share[n->parent] / n->ncomp;
    }
}

static int top_of(const cx_tree *T, int i) {
    while (T->node[i].parent >= 0)
        i = T->node[i].parent;
    return i;
}

static int cmp_note(const void *a, const void *b) {
    const cx_note *x = a, *y = b;
    if (x->on != y->on)
        return x->on < y->on ? -1 : 1;
    return x->node - y->node;
}

typedef struct edge {
    double t;
    int d; /* +1 a note starts, -1 one ends */
} edge;

static int cmp_edge(const void *a, const void *b) {
    const edge *x = a, *y = b;
    if (x->t != y->t)
        return x->t < y->t ? -1 : 1;
    return y->d - x->d; /* at one time, starts first: the count errs high */
}

/* Most notes sounding at once: a sweep over onsets and (slightly late)
 * ends. */
static int max_active(const cx_score *s) {
    edge *e = malloc(sizeof *e * ((size_t)s->nnotes * 2 + 1));
    int best = 0, now = 0;
    if (!e)
        return s->nnotes;
    for (int i = 0; i < s->nnotes; i++) {
        e[2 * i] = (edge){s->note[i].on, 1};
        e[2 * i + 1] = (edge){s->note[i].on + s->note[i].dur + END_SLACK, -1};
    }
    qsort(e, (size_t)s->nnotes * 2, sizeof *e, cmp_edge);
    for (int i = 0; i < s->nnotes * 2; i++)
        best = (now += e[i].d) > best ? now : best;
    free(e);
    return best;
}

static void make_note(const cx_tree *T, int i, const double *on, const double *dur, const double *share,
                      double level_amp, cx_note *nt) {
    const cx_node *n = &T->node[i];
    nt->on = on[i], nt->dur = dur[i], nt->node = i;
    nt->kind = n->level == T->d ? CX_TOP : n->level == T->d - 1 ? CX_GROUP : CX_PARTIAL;
    nt->freq = cx_freq(n->nverts, T->node[top_of(T, i)].nverts);
    nt->amp = (nt->kind == CX_TOP ? TOP_SHARE : level_amp) * share[i];
    double r = n->turn / (M_PI / 2);
    nt->rough = nt->kind == CX_GROUP ? (r < 1 ? r : 1) : 0;
}

cx_score *cx_score_new(const cx_tree *T, const cx_sound_opts *o) {
    cx_sound_opts def = cx_sound_opts_init();
    if (!o)
        o = &def;
    cx_score *s = calloc(1, sizeof *s);
    size_t n = (size_t)T->nnodes + 1;
    double *dur = malloc(sizeof *dur * n), *on = malloc(sizeof *on * n), *share = malloc(sizeof *share * n);
    if (s)
        s->note = malloc(sizeof *s->note * n);
    if (!s || !s->note || !dur || !on || !share) {
        free(dur), free(on), free(share), cx_score_free(s);
        return NULL;
    }
    double tempo = o->tempo > 0 ? o->tempo : 1;
    s->step = o->step / tempo, s->offset = o->offset / tempo, s->granular = o->granular;
    durations(T, s->step, s->offset, dur);
    onsets(T, s->offset, dur, on);
    shares(T, share);
    int levels = T->d - T->leaf; /* the levels below the top */
    double level_amp = levels > 0 ? WAVE_SHARE / levels : 0;
    s->nnotes = T->nnodes;
    for (int i = 0; i < T->nnodes; i++) {
        make_note(T, i, on, dur, share, level_amp, &s->note[i]);
        s->length = fmax(s->length, on[i] + dur[i]);
    }
    qsort(s->note, (size_t)s->nnotes, sizeof *s->note, cmp_note);
    s->maxactive = max_active(s);
    free(dur), free(on), free(share);
    return s;
}

void cx_score_free(cx_score *s) {
    if (!s)
        return;
    free(s->note);
    free(s);
}
