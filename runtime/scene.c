/*
 * scene.c - scenes (.wds): reading, checking against the voices' classes,
 * and rendering through an engine.
 *
 * Implements the scene part of runtime/wdrt.h.  The grammar of the forms
 * this file knows is in the comments above their readers; every form is
 * one entry of the table `forms`, so the forms of trees, surfaces, spatial
 * layers and complexes join it without touching the others.  Nothing here
 * is real-time safe: it reads files and allocates; the audio runs in the
 * engine.
 */
#include "wdrt.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cx.h"
#include "sexp.h"
#include "surf.h"
#include "tt.h"

#define MAX_PLAY_SETS 32
#define SURF_MAX_MODES_FILE 1024 /* modes of one body */
#define LAST_RING_S 120.0 /* a scene without length ends at the latest this long after its last event */

enum { SE_STRIKE, SE_SET, SE_GAIN, SE_PLAY, SE_STOP, SE_IMPACT, SE_HIT, SE_CONTACT };

/* A number, or a curve over scene time: (curve (T V) (T V) ...). */
typedef struct scnum {
    double v;
    const sx *curve;  /* the (curve ...) list, or NULL */
    const sx *motion; /* a motion binding such as (speed OBJ), or NULL */
} scnum;

typedef struct scparam {
    const char *name;
    const sx *at;
    scnum val;
    int id; /* set at bind */
} scparam;

typedef struct scvoice {
    const char *name;
    const sx *at;
    char *netlist;
    int pool;         /* (pool N): N instances to play from; 0: one standing voice */
    double gain, pan, cost, quiet, hold;
    const sx *gain_curve;
    int priority, virtualize;
    int placed;       /* (pos ...) given */
    double pos[3];
    const sx *path;   /* (pos (path ...)), or NULL */
    const char *out_name;
    const sx *out_at;
    int output;
    scparam *params;
    int nparams;
    const wdv_class *cls;
    /* a timbre tree (section "trees"): its tree, program and the names of
     * its params until a class is made at the render's rate */
    tt_tree *tree;
    tt_prog *prog;
    wdv_class stub;
    wdv_param *stub_params;
    int ambient;       /* 0, or 1 + the room it is the ambience of */
    char *ownname;     /* a name made here (an ambience's), freed with the scene */
} scvoice;

typedef struct scpair {
    char name[128]; /* v(NODE) or x(NODE) */
    const sx *at;
    double value;
    int id;
} scpair;

typedef struct scevent {
    double time;
    int order;
    int kind; /* SE_* */
    int voice;
    const sx *at;
    scparam set;         /* SE_SET; SE_GAIN's value */
    scparam *sets;       /* SE_PLAY */
    int nsets;
    double gain;         /* SE_PLAY */
    int priority;        /* SE_PLAY */
    scpair *pairs;       /* SE_STRIKE, SE_PLAY */
    int npairs;
    const sx *hitter;    /* SE_IMPACT: the object that strikes */
    double impulse;      /* SE_IMPACT: N s, or < 0: from the mass and the path */
    double mass;         /* SE_IMPACT: kg */
    int ba, bb;          /* SE_HIT, SE_CONTACT: the bodies */
    double vn, vt;       /* SE_HIT: normal and tangential speeds, m/s */
    scnum force, slip, roll; /* SE_CONTACT: N, m/s, m/s (curves from the event's time) */
    double until;        /* SE_CONTACT: s, when it parts */
} scevent;

struct wdrt_scene {
    sx_doc *doc;
    char *dir;           /* the scene's folder, for relative paths */
    double rate, length, budget_cpu;
    int channels, sleep;
    scvoice *voices;
    int nvoices;
    scevent *ev;
    int nev;
    struct sccomplex *cx; /* complexes (section "complexes"): pools after the voices */
    int ncx;
    struct scbody *bodies; /* bodies (section "bodies"): taps after the complexes */
    int nbodies;
    int active_modes;      /* (active-modes N): modes the bodies may ring at once; 0: any */
    /* space (section "space") */
    wdrt_space_config sp;
    double lis[3];
    const sx *lis_path;  /* the listener's (path ...), or NULL */
    wdrt_wall *walls;
    int nwalls, sources;
    wdrt_room *rooms;
    int nrooms;
    int binaural;        /* (output binaural) */
    const sx *binaural_at; /* its mode, or its file: where an HRTF that cannot be used is reported */
    wdrt_hrtf *ears;     /* its HRTF, read at ears_fs (the scene's rate) */
    double ears_fs;
    char *sofa;          /* its HRTF file, or NULL: the default */
    char *err;           /* where readers write their error */
    size_t errlen;
    tt_file *tdefs;      /* tree definitions: (include ...) and lib/ */
    struct scnl { int vi, k; } *nl; /* what needs a netlist's class: a voice (k < 0)
                            or voice node k of the program of tree vi */
    int nnl;
};

/* ---- small helpers ---- */

static void *xcalloc(size_t n, size_t sz) {
    void *p = calloc(n ? n : 1, sz);
    if (!p) {
        fprintf(stderr, "wdrt: out of memory\n");
        abort();
    }
    return p;
}

static void *grow(void *p, int n, size_t sz) {
    /* arrays grow to powers of two: room for element n */
    if (n & (n - 1) || n == 0) {
        if (n)
            return p;
        return xcalloc(1, sz);
    }
    void *q = realloc(p, sz * (size_t)n * 2);
    if (!q) {
        fprintf(stderr, "wdrt: out of memory\n");
        abort();
    }
    return q;
}

static char *xstrdup(const char *s) {
    char *d = xcalloc(strlen(s) + 1, 1);
    strcpy(d, s);
    return d;
}

#define ERR(x, ...) sx_error(S->doc, (x), S->err, S->errlen, __VA_ARGS__)

static const char *kind_of(const sx *x) { return x ? sx_kind_name(x->kind) : "nothing"; }

/* The closest of `names` to s (edit distance at most 2), or NULL. */
static const char *nearest(const char *s, const char *const *names, int n) {
    const char *best = NULL;
    int bd = 3;
    for (int i = 0; i < n; i++) {
        const char *t = names[i];
        int d = sx_edit_distance(s, t);
        if (d < bd)
            bd = d, best = t;
    }
    return best;
}

static int unknown(wdrt_scene *S, const sx *at, const char *what, const char *name, const char *const *names, int n) {
    const char *near = nearest(name, names, n);
    if (near)
        return ERR(at, "unknown %s '%s'; did you mean '%s'?", what, name, near);
    return ERR(at, "unknown %s '%s'", what, name);
}

/* number = NUM */
static int number(wdrt_scene *S, const sx *x, double *v) {
    *v = 0;
    if (!x || x->kind != SX_NUM)
        return ERR(x, "expected a number, found a %s", kind_of(x));
    *v = x->num;
    return 0;
}

/* curve = '(' 'curve' ( '(' T V ')' )+ ')'   times rising, in seconds */
static int curve(wdrt_scene *S, const sx *c) {
    if (c->len < 2)
        return ERR(c, "a curve needs at least one (TIME VALUE) key");
    double last = -1;
    for (const sx *k = c->head->next; k; k = k->next) {
        double t, v;
        if (k->kind != SX_LIST || k->len != 2)
            return ERR(k, "expected a key (TIME VALUE)");
        if (number(S, k->head, &t) || number(S, k->head->next, &v))
            return -1;
        if (t < 0)
            return ERR(k->head, "a key's time must not be negative");
        if (t < last)
            return ERR(k->head, "keys of a curve must come in time order");
        last = t;
    }
    return 0;
}

/* The value of a curve at time t: linear between keys, held outside. */
static double curve_at(const sx *c, double t) {
    const sx *k = c->head->next;
    double t0 = k->head->num, v0 = k->head->next->num;
    if (t <= t0)
        return v0;
    for (k = k->next; k; k = k->next) {
        double t1 = k->head->num, v1 = k->head->next->num;
        if (t < t1)
            return t1 > t0 ? v0 + (v1 - v0) * (t - t0) / (t1 - t0) : v1;
        t0 = t1, v0 = v1;
    }
    return v0;
}

static const char *const motions[] = {"speed", "distance", "travel", "impulse", "x", "y", "z"};
#define NMOTIONS 7

/* motion = '(' ( 'speed' | 'travel' | 'x' | 'y' | 'z' ) OBJ ')' | '(' 'distance' OBJ OBJ ')'
 *        | '(' 'impulse' ')'     OBJ: an object with a position, or listener */
static int motion(wdrt_scene *S, const sx *x) {
    int k = -1;
    for (int i = 0; i < NMOTIONS; i++)
        if (sx_is(x->head, motions[i]))
            k = i;
    int want = k == 1 ? 3 : k == 3 ? 1 : 2;
    if (x->len != want)
        return ERR(x, "expected %s", k == 1 ? "(distance A B)" : k == 3 ? "(impulse)" : "(MOTION OBJECT)");
    for (const sx *o = x->head->next; o; o = o->next)
        if (o->kind != SX_SYM)
            return ERR(o, "expected the name of an object, found a %s", kind_of(o));
    return 0;
}

/* value = number | curve | motion */
static int value(wdrt_scene *S, const sx *x, scnum *v, int curves) {
    v->curve = NULL;
    v->motion = NULL;
    if (x && x->kind == SX_LIST && x->head && x->head->kind == SX_SYM && !sx_is(x->head, "curve")) {
        for (int i = 0; i < NMOTIONS; i++)
            if (sx_is(x->head, motions[i])) {
                if (motion(S, x))
                    return -1;
                v->motion = x;
                v->v = 0;
                return 0;
            }
    }
    if (x && x->kind == SX_LIST && sx_is(x->head, "curve")) {
        if (!curves)
            return ERR(x, "a curve is not allowed here");
        if (curve(S, x))
            return -1;
        v->curve = x;
        v->v = curve_at(x, 0);
        return 0;
    }
    return number(S, x, &v->v);
}

/* Gains are factors of at most GAIN_MAX in size (+120 dB): past that a
 * sound is surely a typo, and would overflow what a WAV file holds. */
#define GAIN_MAX 1e6
#define GAIN_WHY "a gain is a factor of at most 10^6 (+120 dB) in size"

/* A gain read by value(): a number, or each point of a curve, in range. */
static int gain_value(wdrt_scene *S, const sx *x, scnum *g) {
    if (value(S, x, g, 1))
        return -1;
    if (g->curve) {
        for (const sx *k = g->curve->head->next; k; k = k->next)
            if (!(fabs(k->head->next->num) <= GAIN_MAX))
                return ERR(k->head->next, GAIN_WHY);
    } else if (!g->motion && !(fabs(g->v) <= GAIN_MAX)) {
        return ERR(x, GAIN_WHY);
    }
    return 0;
}

static double curve_end(const sx *c) {
    const sx *k = c->head->next;
    while (k->next)
        k = k->next;
    return k->head->num;
}

static double curve_start(const sx *c) { return c->head->next->head->num; }

static int arity(wdrt_scene *S, const sx *f, int lo, int hi, const char *usage) {
    if (f->len < lo || (hi >= 0 && f->len > hi))
        return ERR(f, "expected %s", usage);
    return 0;
}

static int voice_index(const wdrt_scene *S, const char *name) {
    for (int i = 0; i < S->nvoices; i++)
        if (!strcmp(S->voices[i].name, name))
            return i;
    return -1;
}

/* complexes' names share the voices' (section "complexes") */
static int complex_index(const wdrt_scene *S, const char *name);

static int voice_ref(wdrt_scene *S, const sx *x, int *vi) {
    if (!x || x->kind != SX_SYM)
        return ERR(x, "expected the name of a voice, found a %s", kind_of(x));
    *vi = voice_index(S, x->text);
    if (*vi >= 0)
        return 0;
    const char **names = xcalloc((size_t)S->nvoices + 1, sizeof *names);
    for (int i = 0; i < S->nvoices; i++)
        names[i] = S->voices[i].name;
    int r = unknown(S, x, "voice", x->text, names, S->nvoices);
    free(names);
    return r;
}

/* ---- settings ---- */

/* rate = '(' 'rate' HZ ')' */
static int f_rate(wdrt_scene *S, const sx *f) {
    if (arity(S, f, 2, 2, "(rate HZ)") || number(S, f->head->next, &S->rate))
        return -1;
    if (!(S->rate >= 1000 && S->rate <= 768000))
        return ERR(f->head->next, "a rate must lie between 1 kHz and 768 kHz");
    return 0;
}

/* length = '(' 'length' SECONDS ')' */
static int f_length(wdrt_scene *S, const sx *f) {
    if (arity(S, f, 2, 2, "(length SECONDS)") || number(S, f->head->next, &S->length))
        return -1;
    if (!(S->length > 0 && S->length <= 86400))
        return ERR(f->head->next, "a length must be positive and at most a day");
    return 0;
}

static char *resolve_path(const wdrt_scene *S, const char *p) {
    if (p[0] == '/' || !S->dir[0])
        return xstrdup(p);
    char *r = xcalloc(strlen(S->dir) + strlen(p) + 2, 1);
    sprintf(r, "%s/%s", S->dir, p);
    return r;
}

/* output = '(' 'output' ( 'mono' | 'stereo' | 'binaural' [ STRING ] ) ')'
 *   binaural: through the HRTF of the SOFA file (default Debian's KEMAR) */
static int f_output(wdrt_scene *S, const sx *f) {
    if (arity(S, f, 2, 3, "(output mono|stereo|binaural [\"file.sofa\"])"))
        return -1;
    const sx *m = f->head->next;
    if (sx_is(m, "mono"))
        S->channels = 1;
    else if (sx_is(m, "stereo"))
        S->channels = 2;
    else if (sx_is(m, "binaural"))
        S->channels = 2, S->binaural = 1;
    else
        return ERR(m, "expected mono, stereo or binaural");
    if (f->len > 2 && !S->binaural)
        return ERR(m->next, "only binaural output takes a file");
    if (f->len > 2) {
        const sx *file = m->next;
        if (file->kind != SX_STR)
            return ERR(file, "expected the SOFA file's name in double quotes, found a %s", kind_of(file));
        free(S->sofa);
        S->sofa = resolve_path(S, file->text);
        int e = sx_file_ok(S->sofa);
        if (e)
            return ERR(file, "cannot read the HRTF file '%s': %s", S->sofa, sx_file_strerror(e));
    }
    S->binaural_at = S->binaural ? (f->len > 2 ? m->next : m) : NULL;
    return 0;
}

/* Binaural output: the HRTF, read once the scene's rate is known, so that
 * a file that is not one is an error at its place and not when the scene
 * renders (which takes it, at that rate). */
static int load_ears(wdrt_scene *S) {
    char err[512] = "";
    wdrt_hrtf_close(S->ears);
    if ((S->ears = wdrt_hrtf_open(S->sofa, S->rate, err, sizeof err))) {
        S->ears_fs = S->rate;
        return 0;
    }
    const char *cut = strstr(err, ": error: "), *why = cut ? cut + 9 : err; /* "PATH: error: why" */
    int np = cut ? (int)(cut - err) : 0, n = (int)strcspn(why, "\n");
    return S->sofa ? ERR(S->binaural_at, "cannot use the HRTF file '%s': %.*s", S->sofa, n, why)
                   : ERR(S->binaural_at, "binaural output needs an HRTF, and the default one, '%.*s', cannot be "
                                         "used: %.*s", np, err, n, why);
}

/* budget = '(' 'budget' CPU ')'   the share of one core voices may use */
static int f_budget(wdrt_scene *S, const sx *f) {
    if (arity(S, f, 2, 2, "(budget CPU)") || number(S, f->head->next, &S->budget_cpu))
        return -1;
    if (!(S->budget_cpu > 0 && S->budget_cpu <= 64))
        return ERR(f->head->next, "a budget is a share of one core (0.5 = half), above 0 and at most 64");
    return 0;
}

/* A form of a switch: (NAME on|off). */
static int on_off(wdrt_scene *S, const sx *f, const char *usage, int *on) {
    if (arity(S, f, 2, 2, usage))
        return -1;
    if (!sx_is(f->head->next, "on") && !sx_is(f->head->next, "off"))
        return ERR(f->head->next, "expected on or off");
    *on = sx_is(f->head->next, "on");
    return 0;
}

/* sleep = '(' 'sleep' ( 'on' | 'off' ) ')' */
static int f_sleep(wdrt_scene *S, const sx *f) { return on_off(S, f, "(sleep on|off)", &S->sleep); }

/* ---- space ---- */

/* path = '(' 'path' ( '(' T X Y Z ')' )+ ')'   times rising, s and m */
static int path(wdrt_scene *S, const sx *f) {
    if (f->len < 2)
        return ERR(f, "a path needs at least one (TIME X Y Z) key");
    double last = -1;
    for (const sx *k = f->head->next; k; k = k->next) {
        double v[4];
        if (k->kind != SX_LIST || k->len != 4)
            return ERR(k, "expected a key (TIME X Y Z)");
        int i = 0;
        for (const sx *x = k->head; x; x = x->next)
            if (number(S, x, &v[i++]))
                return -1;
        if (v[0] < 0)
            return ERR(k->head, "a key's time must not be negative");
        if (v[0] < last)
            return ERR(k->head, "keys of a path must come in time order");
        if (fabs(v[1]) > 1e6 || fabs(v[2]) > 1e6 || fabs(v[3]) > 1e6)
            return ERR(k, "positions lie within 1000 km");
        last = v[0];
    }
    return 0;
}

/* Where a path is at time t: linear between keys, held outside. */
static void path_at(const sx *f, double t, double p[3]) {
    const sx *k = f->head->next, *prev = NULL;
    while (k && k->head->num <= t)
        prev = k, k = k->next;
    const sx *a = prev ? prev : k, *b = k ? k : prev;
    double ta = a->head->num, tb = b->head->num, w = tb > ta ? (t - ta) / (tb - ta) : 0;
    const sx *xa = a->head->next, *xb = b->head->next;
    for (int j = 0; j < 3; j++, xa = xa->next, xb = xb->next)
        p[j] = xa->num + (xb->num - xa->num) * (w < 0 ? 0 : w > 1 ? 1 : w);
}

static double path_end(const sx *f) {
    const sx *k = f->head->next;
    while (k->next)
        k = k->next;
    return k->head->num;
}

/* position = '(' 'pos' ( X Y Z | path ) ')' */
static int position(wdrt_scene *S, const sx *f, double p[3], const sx **pth) {
    const sx *a = f->head->next;
    *pth = NULL;
    if (a && a->kind == SX_LIST && sx_is(a->head, "path")) {
        if (arity(S, f, 2, 2, "(pos (path (TIME X Y Z)...))") || path(S, a))
            return -1;
        *pth = a;
        path_at(a, 0, p);
        return 0;
    }
    if (arity(S, f, 4, 4, "(pos X Y Z) or (pos (path (TIME X Y Z)...))"))
        return -1;
    for (int j = 0; j < 3; j++, a = a->next)
        if (number(S, a, &p[j]))
            return -1;
    if (fabs(p[0]) > 1e6 || fabs(p[1]) > 1e6 || fabs(p[2]) > 1e6)
        return ERR(f, "positions lie within 1000 km");
    return 0;
}

/* c = '(' 'c' M/S ')' */
static int f_c(wdrt_scene *S, const sx *f) {
    if (arity(S, f, 2, 2, "(c M/S)") || number(S, f->head->next, &S->sp.c))
        return -1;
    if (!(S->sp.c >= 1 && S->sp.c <= 1e5))
        return ERR(f->head->next, "the speed of sound lies between 1 and 100000 m/s");
    return 0;
}

/* distance = '(' 'distance' MODEL ( '(' ( 'ref' | 'max' | 'rolloff' ) NUMBER ')' )* ')' */
static int f_distance(wdrt_scene *S, const sx *f) {
    static const char *const models[] = {"none", "inverse", "linear", "exponent"};
    if (arity(S, f, 2, 5, "(distance inverse|linear|exponent|none (ref M) (max M) (rolloff R))"))
        return -1;
    const sx *m = f->head->next;
    int k = -1;
    for (int i = 0; i < 4; i++)
        if (sx_is(m, models[i]))
            k = i;
    if (k < 0)
        return m->kind == SX_SYM ? unknown(S, m, "distance model", m->text, models, 4)
                                 : ERR(m, "expected inverse, linear, exponent or none");
    S->sp.distance = (wdrt_distance)k;
    for (const sx *p = m->next; p; p = p->next) {
        double x;
        if (p->kind != SX_LIST || p->len != 2 ||
            !(sx_is(p->head, "ref") || sx_is(p->head, "max") || sx_is(p->head, "rolloff")))
            return ERR(p, "expected (ref M), (max M) or (rolloff R)");
        if (number(S, p->head->next, &x))
            return -1;
        if (sx_is(p->head, "rolloff") ? !(x >= 0 && x <= 100) : !(x > 0 && x <= 1e6))
            return ERR(p->head->next, sx_is(p->head, "rolloff") ? "a rolloff lies between 0 and 100"
                                                                   : "a distance is in m, above 0 and at most 10^6");
        *(sx_is(p->head, "ref") ? &S->sp.ref : sx_is(p->head, "max") ? &S->sp.max : &S->sp.rolloff) = x;
    }
    if (!(S->sp.max > S->sp.ref))
        return ERR(f, "the maximum distance must be beyond the reference distance");
    return 0;
}

/* air = '(' 'air' ( 'on' | 'off' ) ')' */
static int f_air(wdrt_scene *S, const sx *f) { return on_off(S, f, "(air on|off)", &S->sp.air); }

/* listener = '(' 'listener' [ position ] [ '(' 'facing' X Y Z ')' ] ')' */
static int f_listener(wdrt_scene *S, const sx *f) {
    for (const sx *p = f->head->next; p; p = p->next) {
        if (p->kind == SX_LIST && sx_is(p->head, "pos")) {
            if (position(S, p, S->lis, &S->lis_path))
                return -1;
        } else if (p->kind == SX_LIST && sx_is(p->head, "facing")) {
            if (arity(S, p, 4, 4, "(facing X Y Z)"))
                return -1;
            const sx *a = p->head->next;
            for (int j = 0; j < 3; j++, a = a->next)
                if (number(S, a, &S->sp.facing[j]))
                    return -1;
            if (!(fabs(S->sp.facing[0]) + fabs(S->sp.facing[1]) > 0))
                return ERR(p, "a listener faces some way across the ground (x or y not 0)");
        } else {
            return ERR(p, "expected (pos ...) or (facing X Y Z)");
        }
    }
    return 0;
}

/* wall = '(' 'wall' NAME '(' 'from' X Y ')' '(' 'to' X Y ')' '(' 'loss' DB ')' ')' */
static int f_wall(wdrt_scene *S, const sx *f) {
    if (arity(S, f, 5, 5, "(wall NAME (from X Y) (to X Y) (loss DB))"))
        return -1;
    if (f->head->next->kind != SX_SYM)
        return ERR(f->head->next, "expected the name of the wall, found a %s", kind_of(f->head->next));
    S->walls = grow(S->walls, S->nwalls, sizeof *S->walls);
    wdrt_wall *w = &S->walls[S->nwalls++];
    const char *keys[] = {"from", "to", "loss"};
    const sx *p = f->head->next->next;
    for (int i = 0; i < 3; i++, p = p->next) {
        int n = i < 2 ? 3 : 2;
        if (p->kind != SX_LIST || !sx_is(p->head, keys[i]) || p->len != n)
            return ERR(p, "expected (%s %s)", keys[i], i < 2 ? "X Y" : "DB");
        double *dst = i == 0 ? w->from : i == 1 ? w->to : &w->loss_db;
        if (number(S, p->head->next, &dst[0]) || (n == 3 && number(S, p->head->next->next, &dst[1])))
            return -1;
    }
    if (!(w->loss_db >= 0 && w->loss_db <= 200))
        return ERR(f, "a wall's loss is 0 to 200 dB");
    return 0;
}

static int make_tree(wdrt_scene *S, const sx *n, const char *name, const sx *x);

/* room = '(' 'room' NAME '(' 'box' X0 Y0 Z0 X1 Y1 Z1 ')' '(' 't60' LOW HIGH ')'
 *        [ '(' 'reflections' ORDER ')' ] ')'
 *   LOW: T60 in s at and below 500 Hz, HIGH: at and above 4 kHz */
static int f_room(wdrt_scene *S, const sx *f) {
    if (arity(S, f, 4, 7, "(room NAME (box X0 Y0 Z0 X1 Y1 Z1) (t60 LOW HIGH) [(reflections ORDER)] [(ambient TREE)])"))
        return -1;
    if (f->head->next->kind != SX_SYM)
        return ERR(f->head->next, "expected the name of the room, found a %s", kind_of(f->head->next));
    S->rooms = grow(S->rooms, S->nrooms, sizeof *S->rooms);
    wdrt_room *r = &S->rooms[S->nrooms++];
    memset(r, 0, sizeof *r);
    r->order = 1;
    int have = 0;
    for (const sx *p = f->head->next->next; p; p = p->next) {
        if (p->kind == SX_LIST && sx_is(p->head, "ambient")) {
            /* (ambient EXPR property...): a standing tree heard as the room's reverb is */
            if (p->len < 2)
                return ERR(p, "expected (ambient TREE ...)");
            char *name = xcalloc(strlen(f->head->next->text) + 16, 1);
            sprintf(name, "%s.ambient", f->head->next->text);
            int ri = S->nrooms;
            if (make_tree(S, p, name, p->head->next)) {
                if (S->nvoices && !S->voices[S->nvoices - 1].ownname && S->voices[S->nvoices - 1].name == name)
                    S->voices[S->nvoices - 1].ownname = name;
                else
                    free(name);
                return -1;
            }
            scvoice *v = &S->voices[S->nvoices - 1];
            v->ownname = name;
            v->ambient = ri;
            if (v->placed || v->pool)
                return ERR(p, "an ambience is heard throughout its room: no (pos ...) or (pool N)");
            r = &S->rooms[S->nrooms - 1];
            continue;
        }
        int k = sx_is(p->head, "box") ? 0 : sx_is(p->head, "t60") ? 1 : sx_is(p->head, "reflections") ? 2 : -1;
        int len = k == 0 ? 7 : k == 1 ? 3 : 2;
        if (p->kind != SX_LIST || k < 0 || p->len != len)
            return ERR(p, "expected (box X0 Y0 Z0 X1 Y1 Z1), (t60 LOW HIGH) or (reflections ORDER)");
        double v[6];
        const sx *a = p->head->next;
        for (int i = 0; i < len - 1; i++, a = a->next)
            if (number(S, a, &v[i]))
                return -1;
        have |= 1 << k;
        if (k == 0) {
            memcpy(r->box, v, sizeof r->box);
            if (!(v[0] < v[3] && v[1] < v[4] && v[2] < v[5]) || fabs(v[0]) + fabs(v[3]) > 1e4 ||
                fabs(v[1]) + fabs(v[4]) > 1e4 || fabs(v[2]) + fabs(v[5]) > 1e4)
                return ERR(p, "a box runs from its lower corner to its upper one, within 10 km");
        } else if (k == 1) {
            r->t60_low = v[0], r->t60_high = v[1];
            if (!(v[0] >= 0.05 && v[0] <= 60 && v[1] >= 0.05 && v[1] <= 60))
                return ERR(p, "reverberation times lie between 0.05 and 60 s");
        } else {
            if (v[0] != floor(v[0]) || v[0] < 0 || v[0] > 3)
                return ERR(p->head->next, "reflections of order 0 to 3");
            r->order = (int)v[0];
        }
    }
    if ((have & 3) != 3)
        return ERR(f, "a room needs its (box ...) and its (t60 LOW HIGH)");
    return 0;
}

/* A form of one whole number in [lo, hi]: (NAME N). */
static int whole_form(wdrt_scene *S, const sx *f, const char *usage, double lo, double hi, const char *range, int *n) {
    double x;
    if (arity(S, f, 2, 2, usage) || number(S, f->head->next, &x))
        return -1;
    if (x != floor(x) || x < lo || x > hi)
        return ERR(f->head->next, "%s", range);
    *n = (int)x;
    return 0;
}

/* sources = '(' 'sources' N ')'   delay lines: placed voices heard at once */
static int f_sources(wdrt_scene *S, const sx *f) {
    return whole_form(S, f, "(sources N)", 1, 4096, "1 to 4096 sources", &S->sources);
}

/* ---- voices ---- */


/* param = '(' 'param' NAME value ')' */
static int param(wdrt_scene *S, const sx *f, scparam *p) {
    if (arity(S, f, 3, 3, "(param NAME VALUE)"))
        return -1;
    const sx *n = f->head->next;
    if (n->kind != SX_SYM)
        return ERR(n, "expected the name of a param, found a %s", kind_of(n));
    p->name = n->text;
    p->at = n;
    p->id = -1;
    return value(S, n->next, &p->val, 1);
}

/* A property of a voice: (pool N) (param P V) (gain G) (pan X)
 * (priority P) (output NAME) (cost NS) (quiet DB) (hold S) (virtual) */
static int voice_prop(wdrt_scene *S, scvoice *v, const sx *p) {
    static const char *const props[] = {"pool", "param", "gain", "pan", "priority", "output",
                                        "cost", "quiet", "hold", "virtual", "pos"};
    if (p->kind != SX_LIST || !p->head || p->head->kind != SX_SYM)
        return ERR(p, "expected a property such as (pool N) or (param NAME VALUE)");
    const char *k = p->head->text;
    const sx *a = p->head->next;
    double x;
    if (!strcmp(k, "param")) {
        v->params = grow(v->params, v->nparams, sizeof *v->params);
        return param(S, p, &v->params[v->nparams++]);
    }
    if (!strcmp(k, "virtual"))
        return arity(S, p, 1, 1, "(virtual)") ? -1 : (v->virtualize = 1, 0);
    if (!strcmp(k, "output")) {
        if (arity(S, p, 2, 2, "(output NAME)"))
            return -1;
        if (a->kind != SX_SYM)
            return ERR(a, "expected the name of an output, found a %s", kind_of(a));
        v->out_name = a->text, v->out_at = a;
        return 0;
    }
    if (!strcmp(k, "gain")) {
        scnum g;
        if (arity(S, p, 2, 2, "(gain G)") || gain_value(S, a, &g))
            return -1;
        v->gain = g.v, v->gain_curve = g.curve;
        return 0;
    }
    if (!strcmp(k, "pos")) {
        v->placed = 1;
        return position(S, p, v->pos, &v->path);
    }
    int known = 0;
    for (int i = 0; i < (int)(sizeof props / sizeof *props); i++)
        known |= !strcmp(k, props[i]);
    if (!known)
        return unknown(S, p->head, "property", k, props, (int)(sizeof props / sizeof *props));
    if (arity(S, p, 2, 2, "one number") || number(S, a, &x))
        return -1;
    if (!strcmp(k, "pool")) {
        if (x != floor(x) || x < 1 || x > 100000)
            return ERR(a, "a pool holds 1 to 100000 voices");
        v->pool = (int)x;
    } else if (!strcmp(k, "pan")) {
        if (!(x >= -1 && x <= 1))
            return ERR(a, "pan lies between -1 (left) and 1 (right)");
        v->pan = x;
    } else if (!strcmp(k, "priority")) {
        if (x != floor(x) || fabs(x) > 1e6)
            return ERR(a, "a priority is a whole number");
        v->priority = (int)x;
    } else if (!strcmp(k, "cost")) {
        if (!(x > 0 && x < 1e9))
            return ERR(a, "a cost is a number of ns per sample, above 0 and below 10^9");
        v->cost = x;
    } else if (!strcmp(k, "quiet")) {
        if (!(x <= 0 && x >= -300))
            return ERR(a, "a quiet level is in dB, between -300 and 0");
        v->quiet = pow(10, x / 20);
    } else if (!strcmp(k, "hold")) {
        if (!(x >= 0 && x <= 3600))
            return ERR(a, "a hold is a time in seconds, from 0 to 3600");
        v->hold = x;
    }
    return 0;
}

/* voice = '(' 'voice' NAME STRING property* ')' */
static int f_voice(wdrt_scene *S, const sx *f) {
    if (arity(S, f, 3, -1, "(voice NAME \"file.wdn\" ...)"))
        return -1;
    const sx *n = f->head->next, *file = n->next;
    if (n->kind != SX_SYM)
        return ERR(n, "expected the name of the voice, found a %s", kind_of(n));
    if (voice_index(S, n->text) >= 0)
        return ERR(n, "a voice named '%s' is already in the scene", n->text);
    if (complex_index(S, n->text) >= 0)
        return ERR(n, "'%s' is already in the scene", n->text);
    if (file->kind != SX_STR)
        return ERR(file, "expected the netlist's file name in double quotes, found a %s", kind_of(file));
    S->voices = grow(S->voices, S->nvoices, sizeof *S->voices);
    scvoice *v = &S->voices[S->nvoices++];
    memset(v, 0, sizeof *v);
    v->name = n->text;
    v->at = n;
    v->netlist = resolve_path(S, file->text);
    v->gain = 1;
    v->quiet = 1e-5;
    v->hold = 0.1;
    for (const sx *p = file->next; p; p = p->next)
        if (voice_prop(S, v, p))
            return -1;
    return 0;
}

/* ---- trees ----
 *
 * A tree is heard like a voice (it is one of S->voices, with no netlist):
 * its expression is read and compiled when the scene loads, and made a
 * class at the render's rate.  Inline expressions name their params with
 * (param P V); a (use NAME ...) or a "file.tt" brings its own.  Voice nodes
 * of a tree need classes the host builds: they are entries of S->nl. */

/* include = '(' 'include' STRING ')'   tree definitions */
static int f_include(wdrt_scene *S, const sx *f) {
    return tt_file_add_form(&S->tdefs, S->doc, f, S->dir, S->err, S->errlen);
}

static int add_nl(wdrt_scene *S, int vi, int k) {
    S->nl = grow(S->nl, S->nnl, sizeof *S->nl);
    S->nl[S->nnl].vi = vi, S->nl[S->nnl].k = k;
    S->nnl++;
    return 0;
}

/* A tree named `name` (written at n) of expression x with the
 * properties after it. */
static int make_tree(wdrt_scene *S, const sx *n, const char *name, const sx *x) {
    S->voices = grow(S->voices, S->nvoices, sizeof *S->voices);
    int vi = S->nvoices;
    scvoice *v = &S->voices[S->nvoices++];
    memset(v, 0, sizeof *v);
    v->name = name;
    v->at = n;
    v->gain = 1;
    v->quiet = 1e-5;
    v->hold = 0.1;
    for (const sx *p = x->next; p; p = p->next)
        if (voice_prop(S, v, p))
            return -1;
    int inl = x->kind != SX_STR; /* an expression, or a use whose arguments may read the names */
    const char *names[TT_MAX_PARAMS];
    double defs[TT_MAX_PARAMS];
    int np = 0;
    if (inl)
        for (int k = 0; k < v->nparams; k++) {
            for (int j = 0; j < np; j++)
                if (!strcmp(names[j], v->params[k].name))
                    return ERR(v->params[k].at, "param '%s' given twice", names[j]);
            if (np == TT_MAX_PARAMS)
                return ERR(v->params[k].at, "a tree has at most %d params", TT_MAX_PARAMS);
            names[np] = v->params[k].name;
            defs[np++] = v->params[k].val.curve ? curve_at(v->params[k].val.curve, 0) : v->params[k].val.v;
        }
    if (!(v->tree = tt_tree_inline(S->tdefs, S->doc, x, S->dir, inl ? np : 0, names, defs, S->err, S->errlen)))
        return -1;
    char err[1024];
    if (!(v->prog = tt_compile(v->tree, err, sizeof err))) {
        snprintf(S->err, S->errlen, "%s", err);
        return -1;
    }
    const tt_tree *t = v->tree;
    v->stub_params = xcalloc((size_t)t->nparams + 1, sizeof *v->stub_params);
    for (int k = 0; k < t->nparams; k++)
        v->stub_params[k] = (wdv_param){t->pname[k], "", t->pdef[k], t->pmin[k], t->pmax[k], 0};
    v->stub.name = v->name;
    v->stub.n_params = t->nparams;
    v->stub.params = v->stub_params;
    v->stub.n_outputs = 1;
    static const wdv_port out[1] = {{"out", ""}};
    v->stub.outputs = out;
    v->cls = &v->stub;
    for (int k = 0; k < tt_prog_nvoices(v->prog); k++)
        add_nl(S, vi, k);
    return 0;
}

/* tree = '(' 'tree' NAME ( expr | '(' 'use' ... ')' | STRING ) property* ')' */
static int f_tree(wdrt_scene *S, const sx *f) {
    if (arity(S, f, 3, -1, "(tree NAME EXPR ...)"))
        return -1;
    const sx *n = f->head->next;
    if (n->kind != SX_SYM)
        return ERR(n, "expected the name of the tree, found a %s", kind_of(n));
    if (voice_index(S, n->text) >= 0 || complex_index(S, n->text) >= 0 || !strcmp(n->text, "listener"))
        return ERR(n, "'%s' is already in the scene", n->text);
    return make_tree(S, n, n->text, n->next);
}

/* ---- complexes ----
 *
 * A complex (cx.h) is heard as a source of its own: its file is read
 * and its tree of waves and score made when the scene loads; at render
 * it is one more owned pool after the voices, its class built around its
 * score and reached through the pool's bind hook.  It stands awake from
 * the start and plays silence until its (at T), then the traversal;
 * once played it sleeps (its energy is the time it has left).  Events do
 * not address complexes. */

typedef struct sccomplex {
    const char *name;
    const sx *at;
    double gain, pan, time;
    cx_complex *K;
    cx_tree *T;
    cx_score *score;
    int placed;        /* (pos ...) given */
    double pos[3];
    const sx *path;    /* (pos (path ...)), or NULL */
} sccomplex;

static int complex_index(const wdrt_scene *S, const char *name) {
    for (int i = 0; i < S->ncx; i++)
        if (!strcmp(S->cx[i].name, name))
            return i;
    return -1;
}

/* One number in [lo, hi] from (KEY X). */
static int cx_number(wdrt_scene *S, const sx *p, const char *usage, double lo, double hi, const char *range,
                     double *x) {
    if (arity(S, p, 2, 2, usage) || number(S, p->head->next, x))
        return -1;
    if (!(*x >= lo && *x <= hi))
        return ERR(p->head->next, "%s", range);
    return 0;
}

/* A property of a complex: (name "LIST") (start V) (tempo X) (gain G)
 * (pan X) (at T) (granular X) */
static int complex_prop(wdrt_scene *S, sccomplex *c, const sx *p, cx_sound_opts *o, const sx **list,
                        const sx **start) {
    static const char *const props[] = {"name", "start", "tempo", "gain", "pan", "at", "granular", "pos"};
    if (p->kind != SX_LIST || !p->head || p->head->kind != SX_SYM)
        return ERR(p, "expected a property such as (start V) or (tempo X)");
    const char *k = p->head->text;
    if (!strcmp(k, "name")) {
        if (arity(S, p, 2, 2, "(name \"LIST\")"))
            return -1;
        if (p->head->next->kind != SX_STR)
            return ERR(p->head->next, "expected the list's name in double quotes, found a %s", kind_of(p->head->next));
        *list = p->head->next;
        return 0;
    }
    if (!strcmp(k, "start")) {
        double v;
        if (cx_number(S, p, "(start VERTEX)", 0, 999999999, "a vertex is a whole number from 0", &v))
            return -1;
        if (v != floor(v))
            return ERR(p->head->next, "a vertex is a whole number from 0");
        *start = p->head->next;
        return 0;
    }
    if (!strcmp(k, "tempo"))
        return cx_number(S, p, "(tempo X)", 0.01, 100, "a tempo is a speed factor from 0.01 to 100", &o->tempo);
    if (!strcmp(k, "gain"))
        return cx_number(S, p, "(gain G)", -GAIN_MAX, GAIN_MAX, GAIN_WHY, &c->gain);
    if (!strcmp(k, "pan"))
        return cx_number(S, p, "(pan X)", -1, 1, "pan lies between -1 (left) and 1 (right)", &c->pan);
    if (!strcmp(k, "at"))
        return cx_number(S, p, "(at TIME)", 0, 86400, "a start time is in seconds, at most a day", &c->time);
    if (!strcmp(k, "pos")) {
        c->placed = 1;
        return position(S, p, c->pos, &c->path);
    }
    if (!strcmp(k, "granular"))
        return cx_number(S, p, "(granular X)", 0, 1, "an explosion factor lies between 0 and 1", &o->granular);
    return unknown(S, p->head, "property", k, props, (int)(sizeof props / sizeof *props));
}

/* The complex's file read, its start found, its tree and score made. */
static int complex_load(wdrt_scene *S, sccomplex *c, const sx *file, const sx *list, const sx *start,
                        const cx_sound_opts *o) {
    char *path = resolve_path(S, file->text);
    int e = sx_file_ok(path);
    if (e) { /* said here, at the name; errors inside the file are the file's */
        ERR(file, "cannot read the complex '%s': %s", path, sx_file_strerror(e));
        free(path);
        return -1;
    }
    c->K = cx_read_file(path, list ? list->text : NULL, S->err, S->errlen);
    free(path);
    if (!c->K)
        return -1;
    int v = start ? cx_vertex(c->K, (long)start->num) : 0;
    if (v < 0)
        return ERR(start, "complex %s has no vertex %ld", c->name, (long)start->num);
    if (!(c->T = cx_waves(c->K, v)))
        return ERR(file, "out of memory");
    cx_turns(c->K, c->T);
    if (!(c->score = cx_score_new(c->T, o)))
        return ERR(file, "out of memory");
    return 0;
}

/* complex = '(' 'complex' NAME STRING property* ')' */
static int f_complex(wdrt_scene *S, const sx *f) {
    if (arity(S, f, 3, -1, "(complex NAME \"file\" ...)"))
        return -1;
    const sx *n = f->head->next, *file = n->next, *list = NULL, *start = NULL;
    if (n->kind != SX_SYM)
        return ERR(n, "expected the name of the complex, found a %s", kind_of(n));
    if (voice_index(S, n->text) >= 0 || complex_index(S, n->text) >= 0)
        return ERR(n, "'%s' is already in the scene", n->text);
    if (file->kind != SX_STR)
        return ERR(file, "expected the complex's file name in double quotes, found a %s", kind_of(file));
    S->cx = grow(S->cx, S->ncx, sizeof *S->cx);
    sccomplex *c = &S->cx[S->ncx++];
    memset(c, 0, sizeof *c);
    c->name = n->text, c->at = n, c->gain = 1;
    cx_sound_opts o = cx_sound_opts_init();
    for (const sx *p = file->next; p; p = p->next)
        if (complex_prop(S, c, p, &o, &list, &start))
            return -1;
    return complex_load(S, c, file, list, start, &o);
}

static void complex_free(sccomplex *c) {
    cx_score_free(c->score);
    cx_tree_free(c->T);
    cx_free(c->K);
}

/* The complexes' pools, after the voices' in pc; their classes live in
 * src (S->ncx of them), which must outlive the engine. */
static void complex_pools(const wdrt_scene *S, wdrt_pool_config *pc, cx_source *src) {
    for (int i = 0; i < S->ncx; i++) {
        const sccomplex *c = &S->cx[i];
        cx_source_init(&src[i], c->score, c->time);
        pc[i] = wdrt_pool_config_init(&src[i].cls, 1);
        pc[i].owned = 1;
        pc[i].gain = c->gain;
        pc[i].pan = c->pan;
        pc[i].placed = c->placed;
        memcpy(pc[i].pos, c->pos, sizeof c->pos);
        pc[i].bind = cx_source_bind;
        pc[i].data = &src[i];
        /* measured at init, a complex that starts later would cost its
         * silence: about 23 ns a sample per note sounding, at most maxactive */
        pc[i].cost_ns = CX_NOTE_NS * (c->score->maxactive > 0 ? c->score->maxactive : 1);
    }
}

static uint64_t frame_of(double t, double fs) { return (uint64_t)llround(t * fs); }

/* ---- bodies ----
 *
 * Bodies that sound when they touch (surf.h).  Each body with modes of
 * its own is a resonator heard as a source (a pool of one "tap" voice
 * after the complexes, placed where the body is); a body that shares
 * another's resonator rings it.  The world runs in the engine's
 * excitations phase, before the voices: impacts and contacts of the
 * timeline act at their frames, and each tap hears its resonator. */

typedef struct scbody {
    const char *name;
    const sx *at;
    char *netlist;      /* a compiled voice as its resonator, or NULL */
    const sx *in_name, *out_name; /* (input NAME) (output NAME) of that voice */
    const wdv_class *cls;
    int input, output;
    surf_mode *modes;
    int nmodes;
    int share;          /* the body whose resonator it rings, or -1 */
    double mass, gain, quiet;
    surf_surface_desc surf;
    int placed;
    double pos[3];
    const sx *path;
    double *segment;    /* (relief "f.wav" SCALE): its samples, mono */
    long nsegment;
} scbody;

static int body_index(const wdrt_scene *S, const char *name) {
    for (int i = 0; i < S->nbodies; i++)
        if (!strcmp(S->bodies[i].name, name))
            return i;
    return -1;
}

static int body_ref(wdrt_scene *S, const sx *x, int *bi) {
    if (!x || x->kind != SX_SYM)
        return ERR(x, "expected the name of a body, found a %s", kind_of(x));
    if ((*bi = body_index(S, x->text)) >= 0)
        return 0;
    const char **names = xcalloc((size_t)S->nbodies + 1, sizeof *names);
    for (int i = 0; i < S->nbodies; i++)
        names[i] = S->bodies[i].name;
    int r = unknown(S, x, "body", x->text, names, S->nbodies);
    free(names);
    return r;
}

/* (modes (F T60 GAIN)...) or (modes "file.modes") */
static int body_modes(wdrt_scene *S, scbody *b, const sx *p) {
    if (p->len == 2 && p->head->next->kind == SX_STR) {
        char *path = resolve_path(S, p->head->next->text);
        int e = sx_file_ok(path);
        if (e) {
            ERR(p->head->next, "cannot read the modes '%s': %s", path, sx_file_strerror(e));
            free(path);
            return -1;
        }
        b->modes = xcalloc(SURF_MAX_MODES_FILE, sizeof *b->modes);
        int np = 0;
        b->nmodes = surf_modes_read(path, b->modes, SURF_MAX_MODES_FILE, &np, S->err, S->errlen);
        free(path);
        return b->nmodes < 0 ? -1 : 0;
    }
    if (p->len < 2)
        return ERR(p, "expected (modes (F T60 GAIN)...) or (modes \"file.modes\")");
    b->modes = xcalloc((size_t)p->len, sizeof *b->modes);
    for (const sx *m = p->head->next; m; m = m->next) {
        double v[3];
        if (m->kind != SX_LIST || m->len != 3)
            return ERR(m, "expected a mode (F T60 GAIN): Hz, s, and its gain");
        int i = 0;
        for (const sx *x = m->head; x; x = x->next)
            if (number(S, x, &v[i++]))
                return -1;
        if (!(v[0] > 0 && v[0] < 1e6 && v[1] > 0 && v[1] <= 1000 && fabs(v[2]) < 1e9))
            return ERR(m, "a mode has a frequency in Hz (above 0, below 10^6), a T60 in s (above 0, at most 1000) "
                          "and a gain (below 10^9 in size)");
        surf_mode *md = &b->modes[b->nmodes++];
        md->f = v[0], md->t60 = v[1], md->gain[0] = v[2];
    }
    return 0;
}

/* A property of a body */
static int body_prop(wdrt_scene *S, scbody *b, const sx *p) {
    static const char *const props[] = {"modes", "share", "mass", "hardness", "damping", "relief", "roll",
                                        "slip", "gain", "quiet", "pos", "skid", "voice", "input", "output", "gains"};
    if (p->kind != SX_LIST || !p->head || p->head->kind != SX_SYM)
        return ERR(p, "expected a property such as (modes ...) or (mass M)");
    const char *k = p->head->text;
    const sx *a = p->head->next;
    double x;
    if (!strcmp(k, "modes"))
        return body_modes(S, b, p);
    if (!strcmp(k, "voice")) { /* (voice "file.wdn"): rings a compiled voice through its force input */
        if (arity(S, p, 2, 2, "(voice \"file.wdn\")"))
            return -1;
        if (a->kind != SX_STR)
            return ERR(a, "expected the netlist's file name in double quotes, found a %s", kind_of(a));
        free(b->netlist);
        b->netlist = resolve_path(S, a->text);
        return 0;
    }
    if (!strcmp(k, "input") || !strcmp(k, "output")) {
        if (arity(S, p, 2, 2, k[0] == 'i' ? "(input NAME)" : "(output NAME)"))
            return -1;
        if (a->kind != SX_SYM)
            return ERR(a, "expected the name of a voice's %s, found a %s", k, kind_of(a));
        *(k[0] == 'i' ? &b->in_name : &b->out_name) = a;
        return 0;
    }
    if (!strcmp(k, "share")) {
        if (arity(S, p, 2, 2, "(share BODY)") || body_ref(S, a, &b->share))
            return -1;
        if (S->bodies[b->share].share >= 0)
            b->share = S->bodies[b->share].share;
        return 0;
    }
    if (!strcmp(k, "pos")) {
        b->placed = 1;
        return position(S, p, b->pos, &b->path);
    }
    if (!strcmp(k, "relief")) {
        /* (relief noise|grid|none SCALE [WIDTH]) or (relief "f.wav" SCALE) */
        static const char *const kinds[] = {"none", "noise", "grid"};
        if (arity(S, p, 2, 4, "(relief noise|grid|none [SCALE] [WIDTH]) or (relief \"file.wav\" SCALE)"))
            return -1;
        if (a->kind == SX_STR) { /* an audio segment, one sample every SCALE m */
            if (p->len != 3 || number(S, a->next, &b->surf.relief.scale) || !(b->surf.relief.scale > 0 && b->surf.relief.scale < 1))
                return p->len != 3 || a->next->kind == SX_NUM ? ERR(p, "expected (relief \"file.wav\" SCALE), SCALE in m per sample") : -1;
            char *path = resolve_path(S, a->text);
            int nch;
            double fs, *fr;
            long nf;
            wdrt_result r = wdrt_wav_read(path, &nch, &fs, &fr, &nf);
            free(path);
            if (r != WDRT_OK || nf < 2)
                return ERR(a, "cannot read the sound file '%s' as a relief (two samples at least)", a->text);
            free(b->segment);
            b->segment = xcalloc((size_t)nf, sizeof *b->segment);
            for (long i = 0; i < nf; i++) {
                for (int c = 0; c < nch; c++)
                    b->segment[i] += fr[i * nch + c];
                b->segment[i] /= nch;
            }
            free(fr);
            b->nsegment = nf;
            b->surf.relief.kind = SURF_RELIEF_SEGMENT;
            return 0;
        }
        int kind = -1;
        for (int i = 0; i < 3; i++)
            if (sx_is(a, kinds[i]))
                kind = i;
        if (kind < 0)
            return a->kind == SX_SYM ? unknown(S, a, "relief", a->text, kinds, 3)
                                     : ERR(a, "expected noise, grid or none");
        b->surf.relief.kind = (surf_relief_kind)kind;
        if (a->next && (number(S, a->next, &b->surf.relief.scale) || !(b->surf.relief.scale > 0 && b->surf.relief.scale < 1e3)))
            return a->next->kind == SX_NUM ? ERR(a->next, "a relief's scale is a length in m, above 0 and below 1000") : -1;
        b->surf.relief.width = b->surf.relief.scale / 2;
        if (a->next && a->next->next &&
            (number(S, a->next->next, &b->surf.relief.width) ||
             !(b->surf.relief.width > 0 && b->surf.relief.width <= b->surf.relief.scale)))
            return a->next->next->kind == SX_NUM ? ERR(a->next->next, "a grid's bumps are 0 to SCALE wide") : -1;
        return 0;
    }
    if (!strcmp(k, "gains")) { /* (gains contact|impact MASTER OTHER DIRECT LIMIT) */
        if (arity(S, p, 6, 6, "(gains contact|impact MASTER OTHER DIRECT LIMIT)"))
            return -1;
        if (!sx_is(a, "contact") && !sx_is(a, "impact"))
            return ERR(a, "expected contact or impact");
        double v[4];
        int i = 0;
        for (const sx *x = a->next; x; x = x->next)
            if (number(S, x, &v[i++]))
                return -1;
        if (!(isfinite(v[0]) && isfinite(v[1]) && isfinite(v[2]) && v[3] > 0))
            return ERR(p, "gains are numbers and a limit (N) above 0");
        surf_gains *g = sx_is(a, "contact") ? &b->surf.contact : &b->surf.impact;
        g->master = v[0], g->other = v[1], g->direct = v[2], g->limit = v[3];
        return 0;
    }
    if (!strcmp(k, "skid")) { /* (skid DECEL THICKNESS) */
        if (arity(S, p, 3, 3, "(skid DECEL THICKNESS)") || number(S, a, &b->surf.skid_decel) ||
            number(S, a->next, &b->surf.skid_thickness))
            return -1;
        if (!(b->surf.skid_decel >= 0 && b->surf.skid_thickness >= 0))
            return ERR(p, "a skid's deceleration (m/s^2) and thickness (m) are 0 or more");
        return 0;
    }
    int known = 0;
    for (int i = 0; i < (int)(sizeof props / sizeof *props); i++)
        known |= !strcmp(k, props[i]);
    if (!known)
        return unknown(S, p->head, "property", k, props, (int)(sizeof props / sizeof *props));
    if (arity(S, p, 2, 2, "one number") || number(S, a, &x))
        return -1;
    if (!strcmp(k, "mass")) {
        if (!(x > 0))
            return ERR(a, "a mass is in kg, above 0");
        b->mass = x;
    } else if (!strcmp(k, "hardness")) {
        if (!(x > 0))
            return ERR(a, "a hardness is a stiffness in N/m, above 0");
        b->surf.hardness = x;
    } else if (!strcmp(k, "damping")) {
        if (!(x >= 0 && x < 1e6))
            return ERR(a, "a contact damping is a rate in 1/s, 0 or more and below 10^6");
        b->surf.damping = x;
    } else if (!strcmp(k, "roll") || !strcmp(k, "slip")) {
        if (!(x > 0 && x < 1e6))
            return ERR(a, "a cutoff is a frequency in Hz, above 0 and below 10^6");
        *(k[0] == 'r' ? &b->surf.cutoff_roll : &b->surf.cutoff_slip) = x;
    } else if (!strcmp(k, "gain")) {
        if (!(fabs(x) <= GAIN_MAX))
            return ERR(a, GAIN_WHY);
        b->gain = x;
    } else if (!strcmp(k, "quiet")) {
        if (!(x <= 0 && x >= -300))
            return ERR(a, "a quiet level is in dB, between -300 and 0");
        b->quiet = pow(10, x / 20);
    }
    return 0;
}

/* active-modes = '(' 'active-modes' N ')' */
static int f_active_modes(wdrt_scene *S, const sx *f) {
    return whole_form(S, f, "(active-modes N)", 1, 1e6, "a whole number of modes, at least 1", &S->active_modes);
}

/* body = '(' 'body' NAME property* ')' */
static int f_body(wdrt_scene *S, const sx *f) {
    if (arity(S, f, 2, -1, "(body NAME (modes ...) ...)"))
        return -1;
    const sx *n = f->head->next;
    if (n->kind != SX_SYM)
        return ERR(n, "expected the name of the body, found a %s", kind_of(n));
    if (voice_index(S, n->text) >= 0 || complex_index(S, n->text) >= 0 || body_index(S, n->text) >= 0 ||
        !strcmp(n->text, "listener"))
        return ERR(n, "'%s' is already in the scene", n->text);
    if (S->nbodies == 256)
        return ERR(n, "a scene holds at most 256 bodies");
    S->bodies = grow(S->bodies, S->nbodies, sizeof *S->bodies);
    scbody *b = &S->bodies[S->nbodies++];
    memset(b, 0, sizeof *b);
    b->name = n->text;
    b->at = n;
    b->share = -1;
    b->mass = 0.1;
    b->gain = 1;
    b->quiet = 1e-5;
    b->surf = surf_surface_desc_init();
    b->surf.relief.kind = SURF_RELIEF_NOISE;
    b->surf.relief.scale = 1e-4;
    for (const sx *p = n->next; p; p = p->next)
        if (body_prop(S, b, p))
            return -1;
    if (b->share < 0 && b->nmodes == 0 && !b->netlist)
        return ERR(n, "body %s needs its (modes ...), a (voice \"file.wdn\") or (share BODY)", b->name);
    if ((b->share >= 0) + (b->nmodes > 0) + (b->netlist != NULL) > 1)
        return ERR(n, "body %s rings one resonator: its modes, a voice, or another's", b->name);
    if (b->netlist)
        add_nl(S, -1 - (S->nbodies - 1), -1);
    if (b->nmodes > SURF_MAX_MODES_FILE)
        return ERR(n, "a body has at most %d modes", SURF_MAX_MODES_FILE);
    return 0;
}

/* (impact A B (impulse J) [(speed VN VT)]) between bodies */
static int body_hit(wdrt_scene *S, const sx *f, scevent *e) {
    const sx *a = f->head->next, *b = a->next;
    e->kind = SE_HIT;
    e->voice = -1;
    if (body_ref(S, a, &e->ba) || body_ref(S, b, &e->bb))
        return -1;
    if (e->ba == e->bb)
        return ERR(b, "a body does not strike itself");
    e->impulse = -1;
    for (const sx *p = b->next; p; p = p->next) {
        if (p->kind == SX_LIST && sx_is(p->head, "impulse") && p->len == 2) {
            if (number(S, p->head->next, &e->impulse))
                return -1;
            if (!(e->impulse >= 0 && e->impulse < 1e6))
                return ERR(p->head->next, "an impulse is in N s, 0 or more and below 10^6");
        } else if (p->kind == SX_LIST && sx_is(p->head, "speed") && p->len == 3) {
            if (number(S, p->head->next, &e->vn) || number(S, p->head->next->next, &e->vt))
                return -1;
            if (!(fabs(e->vn) < 1e4 && fabs(e->vt) < 1e4))
                return ERR(p, "speeds are in m/s, below 10^4 in size");
        } else {
            return ERR(p, "expected (impulse J) or (speed VN VT)");
        }
    }
    if (e->impulse < 0)
        return ERR(f, "an impact between bodies needs its (impulse J)");
    return 0;
}

/* (contact A B (force F) (slip V) [(roll V)] (until T)) */
static int body_contact(wdrt_scene *S, const sx *f, scevent *e) {
    if (f->len < 3)
        return ERR(f, "expected (contact A B (force F) (slip V) [(roll V)] (until T))");
    const sx *a = f->head->next, *b = a->next;
    e->voice = -1;
    if (body_ref(S, a, &e->ba) || body_ref(S, b, &e->bb))
        return -1;
    if (e->ba == e->bb)
        return ERR(b, "a body does not touch itself");
    int have = 0;
    for (const sx *p = b->next; p; p = p->next) {
        int k = p->kind == SX_LIST && p->len == 2 ? (sx_is(p->head, "force") ? 0 : sx_is(p->head, "slip") ? 1
                                                     : sx_is(p->head, "roll")  ? 2
                                                     : sx_is(p->head, "until") ? 3
                                                                               : -1)
                                                  : -1;
        if (k < 0)
            return ERR(p, "expected (force F), (slip V), (roll V) or (until T)");
        if (k == 3) {
            if (number(S, p->head->next, &e->until))
                return -1;
            if (!(e->until > e->time && e->until <= 86400))
                return ERR(p->head->next, "a contact lasts until a time after it starts, at most a day");
        } else if (value(S, p->head->next, k == 0 ? &e->force : k == 1 ? &e->slip : &e->roll, 1)) {
            return -1;
        } else if ((k == 0 ? &e->force : k == 1 ? &e->slip : &e->roll)->motion) {
            return ERR(p->head->next, "a contact's force and speeds are numbers or curves");
        }
        have |= 1 << k;
    }
    if ((have & 9) != 9)
        return ERR(f, "a contact needs its (force F) and (until T)");
    return 0;
}

/* A render's bodies (wdrt_bodies, bodies.c) and their timeline: the
 * impacts, and the contacts started, updated every block from their
 * curves and stopped, in the order of their frames. */
typedef struct swent {
    uint64_t frame;
    int kind;           /* 0 impact, 1 contact data, 2 stop */
    int a, b, id;
    double d[4];        /* impact: J vn vt; contact: v_a v_b slip force */
} swent;

typedef struct swtl {
    swent *ev;
    int nev, next, cap;
} swtl;

static void sw_push(swtl *T, swent e) {
    if (T->nev == T->cap) {
        T->cap = T->cap ? 2 * T->cap : 64;
        T->ev = realloc(T->ev, sizeof *T->ev * (size_t)T->cap);
        if (!T->ev) {
            fprintf(stderr, "wdrt: out of memory\n");
            abort();
        }
    }
    T->ev[T->nev++] = e;
}

static int cmp_swent(const void *a, const void *b) {
    const swent *x = a, *y = b;
    return x->frame < y->frame ? -1 : x->frame > y->frame ? 1 : x->kind - y->kind;
}

static double scnum_at(const scnum *v, double t) { return v->curve ? curve_at(v->curve, t) : v->v; }

/* The scene's bodies into *out (NULL when it has none) and its timeline
 * into T. */
static int sw_build(const wdrt_scene *S, double fs, wdrt_bodies **out, swtl *T) {
    *out = NULL;
    memset(T, 0, sizeof *T);
    if (S->nbodies == 0)
        return 0;
    int maxm = 1, ncont = 0;
    for (int i = 0; i < S->nbodies; i++)
        maxm = S->bodies[i].nmodes > maxm ? S->bodies[i].nmodes : maxm;
    for (int i = 0; i < S->nev; i++)
        ncont += S->ev[i].kind == SE_CONTACT;
    wdrt_bodies_config c = wdrt_bodies_config_init(fs);
    c.max_bodies = S->nbodies;
    c.max_modes = maxm;
    c.contacts = ncont ? ncont : 1;
    c.queue = 1 << 16;
    c.active_modes = S->active_modes;
    for (int i = 0; i < S->nbodies; i++)
        c.relief_frames += S->bodies[i].nsegment;
    wdrt_bodies *h;
    if (wdrt_bodies_new(&c, &h) != WDRT_OK)
        return -1;
    *out = h;
    for (int i = 0; i < S->nbodies; i++) {
        const scbody *sb = &S->bodies[i];
        wdrt_body b = wdrt_body_init();
        wdrt_mode *m = xcalloc((size_t)sb->nmodes + 1, sizeof *m);
        for (int k = 0; k < sb->nmodes; k++)
            m[k].f = sb->modes[k].f, m[k].t60 = sb->modes[k].t60, m[k].gain = sb->modes[k].gain[0];
        b.modes = m, b.nmodes = sb->nmodes;
        b.voice = sb->netlist ? sb->cls : NULL;
        b.input = sb->input, b.output = sb->output;
        b.share = sb->share;
        b.mass = sb->mass;
        b.hardness = sb->surf.hardness, b.damping = sb->surf.damping;
        b.relief = sb->surf.relief.kind == SURF_RELIEF_GRID   ? WDRT_RELIEF_GRID
                   : sb->surf.relief.kind == SURF_RELIEF_NONE ? WDRT_RELIEF_NONE
                                                              : WDRT_RELIEF_NOISE;
        b.relief = sb->segment ? WDRT_RELIEF_SEGMENT : b.relief;
        b.relief_scale = sb->surf.relief.scale, b.relief_width = sb->surf.relief.width;
        b.relief_samples = sb->segment, b.relief_nsamples = sb->nsegment;
        b.contact_gains = (wdrt_gains){sb->surf.contact.master, sb->surf.contact.other, sb->surf.contact.direct,
                                       sb->surf.contact.limit};
        b.impact_gains = (wdrt_gains){sb->surf.impact.master, sb->surf.impact.other, sb->surf.impact.direct,
                                      sb->surf.impact.limit};
        b.cutoff_roll = sb->surf.cutoff_roll, b.cutoff_slip = sb->surf.cutoff_slip;
        b.gain = sb->gain, b.quiet = sb->quiet;
        b.placed = sb->placed;
        memcpy(b.pos, sb->pos, sizeof b.pos);
        int r = (sb->netlist && !sb->cls) ? -1 : wdrt_bodies_add(h, &b);
        free(m);
        if (r != i)
            return -1;
    }
    int id = 0;
    const uint64_t B = 64;
    for (int i = 0; i < S->nev; i++) {
        const scevent *x = &S->ev[i];
        swent e;
        memset(&e, 0, sizeof e);
        e.a = x->ba, e.b = x->bb;
        e.frame = frame_of(x->time, fs);
        if (x->kind == SE_HIT) {
            e.kind = 0;
            e.d[0] = x->impulse, e.d[1] = x->vn, e.d[2] = x->vt;
            sw_push(T, e);
        } else if (x->kind == SE_CONTACT) {
            e.id = id++;
            uint64_t end = frame_of(x->until, fs);
            for (uint64_t f = e.frame; f < end; f = (f / B + 1) * B) {
                double t = (double)f / fs - x->time;
                double roll = fabs(scnum_at(&x->roll, t)), slip = fabs(scnum_at(&x->slip, t));
                double force = scnum_at(&x->force, t);
                e.kind = 1;
                e.frame = f;
                e.d[0] = roll, e.d[1] = roll + slip, e.d[2] = slip, e.d[3] = force < 0 ? 0 : force;
                sw_push(T, e);
            }
            e.kind = 2;
            e.frame = end;
            sw_push(T, e);
        }
    }
    if (T->nev > 1)
        qsort(T->ev, (size_t)T->nev, sizeof *T->ev, cmp_swent);
    return 0;
}

/* Posts the bodies' events before frame `until`; returns the frame the
 * render may go to. */
static uint64_t sw_post(wdrt_bodies *h, swtl *T, uint64_t now, uint64_t until) {
    while (h && T->next < T->nev && T->ev[T->next].frame < until) {
        const swent *x = &T->ev[T->next];
        wdrt_result r = x->kind == 0   ? wdrt_bodies_impact(h, x->frame, x->a, x->b, x->d[0], x->d[1], x->d[2])
                        : x->kind == 1 ? wdrt_bodies_contact(h, x->frame, x->id, x->a, x->b, x->d[0], x->d[1],
                                                             x->d[2], x->d[3])
                                       : wdrt_bodies_contact_stop(h, x->frame, x->id);
        if (r == WDRT_QUEUE_FULL)
            return x->frame > now ? x->frame : now + 1;
        T->next++;
    }
    return until;
}

/* ---- the timeline ---- */

/* pair = '(' ( 'v' | 'x' ) NODE NUMBER ')' */
static int pair(wdrt_scene *S, const sx *p, scpair *q) {
    if (p->kind != SX_LIST || p->len != 3 || !(sx_is(p->head, "v") || sx_is(p->head, "x")))
        return ERR(p, "expected (v NODE VALUE) or (x NODE VALUE)");
    const sx *node = p->head->next;
    if (node->kind != SX_SYM && node->kind != SX_NUM)
        return ERR(node, "expected a node name, found a %s", kind_of(node));
    if (strlen(node->text) > 100)
        return ERR(node, "node name too long");
    snprintf(q->name, sizeof q->name, "%s(%s)", p->head->text, node->text);
    q->at = p;
    q->id = -1;
    return number(S, node->next, &q->value);
}

static int pairs(wdrt_scene *S, const sx *form, const sx *first, scevent *e) {
    for (const sx *p = first; p; p = p->next) {
        if (e->npairs == WDRT_STRIKE_MAX)
            return ERR(p, "a strike sets at most %d targets", WDRT_STRIKE_MAX);
        e->pairs = grow(e->pairs, e->npairs, sizeof *e->pairs);
        if (pair(S, p, &e->pairs[e->npairs++]))
            return -1;
    }
    if (e->npairs == 0)
        return ERR(form, "a strike needs at least one (v NODE VALUE) or (x NODE VALUE)");
    return 0;
}

/* play = '(' 'play' POOL ( '(' 'gain' G ')' | '(' 'priority' P ')' |
 *        '(' 'set' PARAM VALUE ')' | '(' 'strike' pair+ ')' )* ')' */
static int play(wdrt_scene *S, const sx *f, scevent *e) {
    for (const sx *p = f->head->next->next; p; p = p->next) {
        if (p->kind != SX_LIST || !p->head)
            return ERR(p, "expected (set PARAM VALUE), (strike ...), (gain G) or (priority P)");
        if (sx_is(p->head, "set")) {
            if (arity(S, p, 3, 3, "(set PARAM VALUE)"))
                return -1;
            if (e->nsets == MAX_PLAY_SETS)
                return ERR(p, "a play sets at most %d params", MAX_PLAY_SETS);
            e->sets = grow(e->sets, e->nsets, sizeof *e->sets);
            scparam *q = &e->sets[e->nsets++];
            if (p->head->next->kind != SX_SYM)
                return ERR(p->head->next, "expected the name of a param, found a %s", kind_of(p->head->next));
            q->name = p->head->next->text, q->at = p->head->next, q->id = -1;
            if (value(S, p->head->next->next, &q->val, 0))
                return -1;
        } else if (sx_is(p->head, "strike")) {
            if (e->npairs)
                return ERR(p, "a play strikes once");
            if (pairs(S, p, p->head->next, e))
                return -1;
        } else if (sx_is(p->head, "gain")) {
            if (arity(S, p, 2, 2, "(gain G)") || number(S, p->head->next, &e->gain))
                return -1;
            if (!(fabs(e->gain) <= GAIN_MAX))
                return ERR(p->head->next, GAIN_WHY);
        } else if (sx_is(p->head, "priority")) {
            double x;
            if (arity(S, p, 2, 2, "(priority P)") || number(S, p->head->next, &x))
                return -1;
            if (x != floor(x) || fabs(x) > 1e6)
                return ERR(p->head->next, "a priority is a whole number");
            e->priority = (int)x;
        } else {
            return ERR(p, "expected (set PARAM VALUE), (strike ...), (gain G) or (priority P)");
        }
    }
    return 0;
}

/* impact = '(' 'impact' A B ( '(' 'impulse' J ')' | '(' 'mass' M ')' ) ')'
 *   B: a tree with a pool, played with its (impulse)-bound params at J; with
 *   a mass, J = M |v+ - v-| from A's path around the time */
static int impact(wdrt_scene *S, const sx *f, scevent *e) {
    const sx *a = f->head->next, *b = a ? a->next : NULL;
    if (!a || !b || a->kind != SX_SYM)
        return ERR(a ? a : f, "expected (impact A B (impulse J)) or (impact A B (mass M))");
    e->hitter = a;
    if (voice_ref(S, b, &e->voice))
        return -1;
    if (!S->voices[e->voice].tree || !S->voices[e->voice].pool)
        return ERR(b, "'%s' is not a tree with a (pool N): an impact plays a note of one", b->text);
    e->impulse = -1;
    for (const sx *p = b->next; p; p = p->next) {
        if (p->kind != SX_LIST || p->len != 2 || !(sx_is(p->head, "impulse") || sx_is(p->head, "mass")))
            return ERR(p, "expected (impulse J) or (mass M)");
        double x;
        if (number(S, p->head->next, &x))
            return -1;
        if (!(x >= 0 && x < 1e9))
            return ERR(p->head->next, "expected a number, 0 or more and below 10^9");
        if (sx_is(p->head, "impulse"))
            e->impulse = x;
        else
            e->mass = x;
    }
    if (e->impulse < 0 && !(e->mass > 0))
        return ERR(f, "an impact needs its (impulse J) or the (mass M) of what strikes");
    return 0;
}

/* event = '(' 'strike' VOICE pair+ ')' | '(' 'set' NAME PARAM value ')'
 *       | '(' 'gain' NAME value ')' | play | '(' 'stop' NAME ')' | impact */
static int event(wdrt_scene *S, const sx *f, double t, scevent *e) {
    static const char *const kinds[] = {"strike", "set", "gain", "play", "stop", "impact", "", "contact"};
    memset(e, 0, sizeof *e);
    e->time = t;
    e->at = f;
    e->gain = 1;
    if (f->kind != SX_LIST || !f->head || f->head->kind != SX_SYM)
        return ERR(f, "expected an event: (strike ...), (set ...), (gain ...), (play ...) or (stop ...)");
    e->kind = -1;
    for (int i = 0; i < 8; i++)
        if (kinds[i][0] && sx_is(f->head, kinds[i]))
            e->kind = i;
    if (e->kind < 0)
        return unknown(S, f->head, "event", f->head->text, kinds, 8);
    if (e->kind == SE_CONTACT)
        return body_contact(S, f, e);
    if (e->kind == SE_IMPACT && f->len >= 3 && f->head->next->kind == SX_SYM &&
        body_index(S, f->head->next->text) >= 0)
        return body_hit(S, f, e);
    if (e->kind == SE_IMPACT)
        return impact(S, f, e);
    if (f->len < 2)
        return ERR(f, "expected the voice the event is for");
    if (voice_ref(S, f->head->next, &e->voice))
        return -1;
    const scvoice *v = &S->voices[e->voice];
    const sx *a = f->head->next->next;
    switch (e->kind) {
    case SE_STRIKE:
        return pairs(S, f, a, e);
    case SE_SET:
        if (arity(S, f, 4, 4, "(set NAME PARAM VALUE)"))
            return -1;
        if (a->kind != SX_SYM)
            return ERR(a, "expected the name of a param, found a %s", kind_of(a));
        e->set.name = a->text, e->set.at = a, e->set.id = -1;
        return value(S, a->next, &e->set.val, 1);
    case SE_GAIN:
        if (arity(S, f, 3, 3, "(gain NAME G)"))
            return -1;
        return gain_value(S, a, &e->set.val);
    case SE_PLAY:
        if (!v->pool)
            return ERR(f->head->next, "'%s' is a single voice: play takes a voice with (pool N)", v->name);
        return play(S, f, e);
    case SE_STOP:
        return arity(S, f, 2, 2, "(stop NAME)");
    }
    return 0;
}

/* at = '(' 'at' TIME event+ ')' */
static int f_at(wdrt_scene *S, const sx *f) {
    double t;
    if (arity(S, f, 3, -1, "(at TIME EVENT...)") || number(S, f->head->next, &t))
        return -1;
    if (!(t >= 0 && t <= 86400))
        return ERR(f->head->next, "an event's time is in seconds from the start, at most a day");
    for (const sx *x = f->head->next->next; x; x = x->next) {
        S->ev = grow(S->ev, S->nev, sizeof *S->ev);
        scevent *e = &S->ev[S->nev]; /* counted at once: a failed one is freed with the scene */
        e->order = S->nev++;
        if (event(S, x, t, e))
            return -1;
        e->order = S->nev - 1;
    }
    return 0;
}

/* ---- the scene ---- */

typedef struct form {
    const char *name;
    int (*read)(wdrt_scene *S, const sx *f);
} form;

static const form forms[] = {
    {"rate", f_rate},   {"length", f_length}, {"output", f_output}, {"budget", f_budget},
    {"sleep", f_sleep}, {"voice", f_voice},   {"at", f_at},       {"c", f_c},
    {"distance", f_distance}, {"air", f_air}, {"listener", f_listener}, {"wall", f_wall}, {"sources", f_sources},
    {"room", f_room},     {"complex", f_complex}, {"tree", f_tree}, {"include", f_include},
    {"body", f_body}, {"active-modes", f_active_modes},
};
#define NFORMS ((int)(sizeof forms / sizeof *forms))

static int read_form(wdrt_scene *S, const sx *f) {
    if (f->kind != SX_LIST || !f->head || f->head->kind != SX_SYM)
        return ERR(f, "expected a form such as (voice ...) or (at ...)");
    for (int i = 0; i < NFORMS; i++)
        if (sx_is(f->head, forms[i].name))
            return forms[i].read(S, f);
    const char *names[NFORMS];
    for (int i = 0; i < NFORMS; i++)
        names[i] = forms[i].name;
    return unknown(S, f->head, "form", f->head->text, names, NFORMS);
}

static int bind_voice(wdrt_scene *S, int i, const wdv_class *cls);
static int bind_body(wdrt_scene *S, scbody *b, const wdv_class *cls);
static int check_motions(wdrt_scene *S);

static int cmp_event(const void *a, const void *b) {
    const scevent *x = a, *y = b;
    return x->time < y->time ? -1 : x->time > y->time ? 1 : x->order - y->order;
}

wdrt_result wdrt_scene_load(const char *path, wdrt_scene **scene, char *err, size_t errlen) {
    if (!path || !scene)
        return WDRT_INVALID_ARGS;
    *scene = NULL;
    sx_doc *d = sx_read_file(path, err, errlen);
    if (!d)
        return WDRT_SYNTAX;
    wdrt_scene *S = xcalloc(1, sizeof *S);
    S->doc = d;
    S->err = err;
    S->errlen = errlen;
    S->rate = 48000;
    S->channels = 1;
    S->sleep = 1;
    S->sp = wdrt_engine_config_init(48000, 1, 0, NULL).space;
    S->dir = xstrdup(path);
    char *slash = strrchr(S->dir, '/');
    if (slash)
        *slash = 0;
    else
        S->dir[0] = 0;
    for (const sx *f = d->forms; f; f = f->next)
        if (read_form(S, f)) {
            wdrt_scene_free(S);
            return WDRT_SYNTAX;
        }
    for (int i = 0; i < S->nvoices; i++) /* the array has moved as it grew: point at the stubs again */
        if (S->voices[i].tree && bind_voice(S, i, S->voices[i].cls = &S->voices[i].stub)) {
            wdrt_scene_free(S);
            return WDRT_SYNTAX;
        }
    for (int i = 0; i < S->nvoices; i++)
        if (!S->voices[i].tree)
            add_nl(S, i, -1);
    if (check_motions(S) || (S->binaural && load_ears(S))) {
        wdrt_scene_free(S);
        return WDRT_SYNTAX;
    }
    if (S->nev > 1)
        qsort(S->ev, (size_t)S->nev, sizeof *S->ev, cmp_event);
    *scene = S;
    return WDRT_OK;
}

void wdrt_scene_free(wdrt_scene *S) {
    if (!S)
        return;
    wdrt_hrtf_close(S->ears);
    for (int i = 0; i < S->nvoices; i++) {
        free(S->voices[i].netlist);
        free(S->voices[i].params);
        tt_prog_free(S->voices[i].prog);
        free(S->voices[i].ownname);
        tt_tree_free(S->voices[i].tree);
        free(S->voices[i].stub_params);
    }
    tt_file_free(S->tdefs);
    free(S->nl);
    for (int i = 0; i < S->nev; i++) {
        free(S->ev[i].sets);
        free(S->ev[i].pairs);
    }
    for (int i = 0; i < S->ncx; i++)
        complex_free(&S->cx[i]);
    for (int i = 0; i < S->nbodies; i++)
        free(S->bodies[i].modes), free(S->bodies[i].netlist), free(S->bodies[i].segment);
    free(S->bodies);
    free(S->cx);
    free(S->voices);
    free(S->walls);
    free(S->rooms);
    free(S->sofa);
    free(S->ev);
    free(S->dir);
    sx_free(S->doc);
    free(S);
}

/* The host sees the netlists the scene needs: its voices' and those of
 * voice nodes of its trees (S->nl). */
int wdrt_scene_nvoices(const wdrt_scene *s) { return s ? s->nnl : 0; }
int wdrt_scene_channels(const wdrt_scene *s) { return s ? s->channels : 0; }
double wdrt_scene_length(const wdrt_scene *s) { return s ? s->length : 0; }
double wdrt_scene_rate(const wdrt_scene *s, const wdrt_render_opts *o) {
    return o && o->rate > 0 ? o->rate : s ? s->rate : 0;
}
const char *wdrt_scene_voice_name(const wdrt_scene *s, int i) {
    if (!s || i < 0 || i >= s->nnl)
        return NULL;
    if (s->nl[i].vi < 0) /* a body's voice */
        return s->bodies[-1 - s->nl[i].vi].name;
    return s->voices[s->nl[i].vi].name;
}
const char *wdrt_scene_voice_netlist(const wdrt_scene *s, int i) {
    if (!s || i < 0 || i >= s->nnl)
        return NULL;
    if (s->nl[i].vi < 0)
        return s->bodies[-1 - s->nl[i].vi].netlist;
    const scvoice *v = &s->voices[s->nl[i].vi];
    return s->nl[i].k < 0 ? v->netlist : tt_prog_voice_path(v->prog, s->nl[i].k);
}

/* ---- binding classes ---- */

static int bind_param(wdrt_scene *S, const wdv_class *cls, scparam *p) {
    const char *names[64];
    for (int i = 0; i < cls->n_params; i++) {
        names[i] = cls->params[i].name;
        if (!strcmp(cls->params[i].name, p->name))
            p->id = i;
    }
    if (p->id >= 0) {
        const wdv_param *d = &cls->params[p->id];
        if (!p->val.curve && !p->val.motion && (p->val.v < d->min || p->val.v > d->max)) /* the voice clamps it */
            sx_warning(S->doc, p->at, S->err, S->errlen, "%s = %g lies outside its range [%g, %g]: the voice holds it at %g",
                       p->name, p->val.v, d->min, d->max, p->val.v < d->min ? d->min : d->max);
        return 0;
    }
    if (cls->n_params == 0)
        return ERR(p->at, "unknown param '%s': voice %s has no params", p->name, cls->name);
    return unknown(S, p->at, "param", p->name, names, cls->n_params > 64 ? 64 : cls->n_params);
}

static int bind_pairs(wdrt_scene *S, const wdv_class *cls, scevent *e) {
    for (int k = 0; k < e->npairs; k++) {
        scpair *q = &e->pairs[k];
        const char *names[256];
        int n = cls->n_ic_targets < 256 ? cls->n_ic_targets : 256;
        for (int i = 0; i < cls->n_ic_targets; i++) {
            if (i < 256)
                names[i] = cls->ic_targets[i].name;
            if (!strcmp(cls->ic_targets[i].name, q->name))
                q->id = i;
        }
        if (q->id < 0) {
            if (n == 0)
                return ERR(q->at, "voice %s has nothing to strike", cls->name);
            return unknown(S, q->at, "strike target", q->name, names, n);
        }
    }
    return 0;
}

wdrt_result wdrt_scene_bind(wdrt_scene *S, int i, const wdv_class *cls, char *err, size_t errlen) {
    if (!S || i < 0 || i >= S->nnl || !cls)
        return WDRT_INVALID_ARGS;
    S->err = err, S->errlen = errlen;
    if (err && errlen)
        err[0] = '\0'; /* on success, the warnings */
    if (S->nl[i].vi < 0)
        return bind_body(S, &S->bodies[-1 - S->nl[i].vi], cls) ? WDRT_SYNTAX : WDRT_OK;
    if (S->nl[i].k >= 0) {
        scvoice *v = &S->voices[S->nl[i].vi];
        return tt_prog_bind_voice(v->prog, S->nl[i].k, cls, err, errlen) ? WDRT_SYNTAX : WDRT_OK;
    }
    return bind_voice(S, S->nl[i].vi, cls) ? WDRT_SYNTAX : WDRT_OK;
}

/* A body's voice: its force input and the output heard. */
static int port_of(wdrt_scene *S, const wdv_port *ports, int n, const sx *name, const char *what, int *k) {
    *k = 0;
    if (!name)
        return n > 0 ? 0 : -1;
    const char *names[64];
    for (int j = 0; j < n; j++) {
        if (j < 64)
            names[j] = ports[j].name;
        if (!strcmp(ports[j].name, name->text)) {
            *k = j;
            return 0;
        }
    }
    return unknown(S, name, what, name->text, names, n < 64 ? n : 64);
}

static int bind_body(wdrt_scene *S, scbody *b, const wdv_class *cls) {
    if (cls->n_inputs < 1)
        return ERR(b->at, "voice %s has no input for the force that rings it", cls->name);
    if (cls->n_outputs < 1)
        return ERR(b->at, "voice %s has no output to hear", cls->name);
    if (port_of(S, cls->inputs, cls->n_inputs, b->in_name, "input", &b->input) ||
        port_of(S, cls->outputs, cls->n_outputs, b->out_name, "output", &b->output))
        return -1;
    b->cls = cls;
    return 0;
}

static int bind_voice(wdrt_scene *S, int i, const wdv_class *cls) {
    scvoice *v = &S->voices[i];
    v->cls = cls;
    if (cls->n_outputs == 0)
        return ERR(v->at, "voice %s has no output to hear", cls->name) ? WDRT_SYNTAX : WDRT_SYNTAX;
    if (cls->n_inputs > 0) /* a scene drives no voice's inputs; a body drives its voice's force input */
        sx_warning(S->doc, v->at, S->err, S->errlen, "nothing in a scene drives the input%s '%s'%s of voice %s%s",
                   cls->n_inputs > 1 ? "s" : "", cls->inputs[0].name, cls->n_inputs > 1 ? ", ..." : "", cls->name,
                   cls->n_ic_targets ? ": it sounds only when struck"
                                     : ", and it has nothing to strike: it stays silent");
    v->output = 0;
    if (v->out_name) {
        const char *names[64];
        v->output = -1;
        for (int k = 0; k < cls->n_outputs; k++) {
            if (k < 64)
                names[k] = cls->outputs[k].name;
            if (!strcmp(cls->outputs[k].name, v->out_name))
                v->output = k;
        }
        if (v->output < 0) {
            unknown(S, v->out_at, "output", v->out_name, names, cls->n_outputs < 64 ? cls->n_outputs : 64);
            return WDRT_SYNTAX;
        }
    }
    for (int k = 0; k < v->nparams; k++)
        if (bind_param(S, cls, &v->params[k]))
            return WDRT_SYNTAX;
    for (int k = 0; k < S->nev; k++) {
        scevent *e = &S->ev[k];
        if (e->voice != i)
            continue;
        if (e->kind == SE_SET && bind_param(S, cls, &e->set))
            return WDRT_SYNTAX;
        for (int j = 0; j < e->nsets; j++)
            if (bind_param(S, cls, &e->sets[j]))
                return WDRT_SYNTAX;
        if (bind_pairs(S, cls, e))
            return WDRT_SYNTAX;
    }
    return WDRT_OK;
}

/* ---- motion ---- */

typedef struct objref {
    double p[3];
    const sx *path; /* or NULL: at p */
} objref;

/* Where the object `name` is: 0, or 1 if it has no position, -1 if there
 * is no such object. */
static int find_obj(const wdrt_scene *S, const char *name, objref *o) {
    if (!strcmp(name, "listener")) {
        memcpy(o->p, S->lis, sizeof o->p);
        o->path = S->lis_path;
        return 0;
    }
    int i = voice_index(S, name);
    if (i >= 0) {
        memcpy(o->p, S->voices[i].pos, sizeof o->p);
        o->path = S->voices[i].path;
        return S->voices[i].placed ? 0 : 1;
    }
    if ((i = complex_index(S, name)) >= 0) {
        memcpy(o->p, S->cx[i].pos, sizeof o->p);
        o->path = S->cx[i].path;
        return S->cx[i].placed ? 0 : 1;
    }
    return -1;
}

static void obj_at(const objref *o, double t, double p[3]) {
    if (o->path)
        path_at(o->path, t, p);
    else
        memcpy(p, o->p, sizeof o->p);
}

/* Metres along a path from its start to time t. */
static double travel(const objref *o, double t) {
    if (!o->path)
        return 0;
    double d = 0, a[3], b[3];
    const sx *k = o->path->head->next;
    path_at(o->path, k->head->num, a);
    for (k = k->next; k; k = k->next) {
        double tk = k->head->num;
        path_at(o->path, tk < t ? tk : t, b);
        d += sqrt((b[0] - a[0]) * (b[0] - a[0]) + (b[1] - a[1]) * (b[1] - a[1]) + (b[2] - a[2]) * (b[2] - a[2]));
        memcpy(a, b, sizeof a);
        if (tk >= t)
            break;
    }
    return d;
}

static double dist3(const double a[3], const double b[3]) {
    return sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
}

/* Velocity of o just before (dir -1) or after (dir 1) time t, m/s. */
static void velocity(const objref *o, double t, int dir, double v[3]) {
    const double h = 1e-4;
    double a[3], b[3], t0 = dir < 0 ? t - h : t, t1 = dir < 0 ? t : t + h;
    if (t0 < 0)
        t0 = 0, t1 = h;
    obj_at(o, t0, a);
    obj_at(o, t1, b);
    for (int j = 0; j < 3; j++)
        v[j] = (b[j] - a[j]) / (t1 - t0);
}

/* The value of a motion binding at scene time t; J: the impulse of the
 * impact that plays the note (0 otherwise). */
/* A motion binding with its objects found: what a drive evaluates every
 * block without looking names up again. */
enum { MO_SPEED, MO_DISTANCE, MO_TRAVEL, MO_IMPULSE, MO_X, MO_Y, MO_Z };
typedef struct motion_ref {
    int kind; /* MO_*, in the order of motions[] */
    objref A, B;
} motion_ref;

static motion_ref motion_resolve(const wdrt_scene *S, const sx *m) {
    motion_ref r;
    memset(&r, 0, sizeof r);
    for (int i = 0; i < NMOTIONS; i++)
        if (sx_is(m->head, motions[i]))
            r.kind = i;
    const sx *a = m->head->next;
    if (a)
        find_obj(S, a->text, &r.A);
    if (a && a->next)
        find_obj(S, a->next->text, &r.B);
    return r;
}

static double motion_eval(const motion_ref *r, double t, double J) {
    double p[3], q[3], v0[3], v1[3], z[3] = {0, 0, 0};
    switch (r->kind) {
    case MO_IMPULSE:
        return J;
    case MO_DISTANCE:
        obj_at(&r->A, t, p);
        obj_at(&r->B, t, q);
        return dist3(p, q);
    case MO_SPEED:
        velocity(&r->A, t, 1, v1);
        velocity(&r->A, t, -1, v0);
        return 0.5 * (dist3(v0, z) + dist3(v1, z));
    case MO_TRAVEL:
        return travel(&r->A, t);
    default:
        obj_at(&r->A, t, p);
        return p[r->kind - MO_X];
    }
}

static double motion_at(const wdrt_scene *S, const sx *m, double t, double J) {
    motion_ref r = motion_resolve(S, m);
    return motion_eval(&r, t, J);
}

/* The impulse of an impact: given, or the mass times the jump in the
 * hitter's velocity at the time. */
static double impact_impulse(const wdrt_scene *S, const scevent *x) {
    if (x->impulse >= 0)
        return x->impulse;
    objref A;
    double v0[3], v1[3];
    find_obj(S, x->hitter->text, &A);
    velocity(&A, x->time, -1, v0);
    velocity(&A, x->time, 1, v1);
    return x->mass * dist3(v0, v1);
}

static int check_motion(wdrt_scene *S, const scnum *v) {
    if (!v->motion)
        return 0;
    for (const sx *o = v->motion->head->next; o; o = o->next) {
        objref r;
        int k = find_obj(S, o->text, &r);
        if (k > 0)
            return ERR(o, "'%s' has no position: give it (pos ...)", o->text);
        if (k < 0) {
            const char **names = xcalloc((size_t)(S->nvoices + S->ncx) + 1, sizeof *names);
            int n = 0;
            names[n++] = "listener";
            for (int i = 0; i < S->nvoices; i++)
                names[n++] = S->voices[i].name;
            for (int i = 0; i < S->ncx; i++)
                names[n++] = S->cx[i].name;
            int r2 = unknown(S, o, "object", o->text, names, n);
            free(names);
            return r2;
        }
    }
    return 0;
}

static int check_motions(wdrt_scene *S) {
    for (int i = 0; i < S->nvoices; i++)
        for (int k = 0; k < S->voices[i].nparams; k++)
            if (check_motion(S, &S->voices[i].params[k].val))
                return -1;
    for (int i = 0; i < S->nev; i++) {
        scevent *e = &S->ev[i];
        if (check_motion(S, &e->set.val))
            return -1;
        for (int j = 0; j < e->nsets; j++)
            if (check_motion(S, &e->sets[j].val))
                return -1;
        if (e->kind == SE_IMPACT) {
            objref r;
            int k = find_obj(S, e->hitter->text, &r);
            if (k < 0)
                return ERR(e->hitter, "unknown object '%s'", e->hitter->text);
            if (k != 0 && e->impulse < 0)
                return ERR(e->hitter, "'%s' is not an object with a position: its impulse cannot come from its path",
                           e->hitter->text);
        }
    }
    return 0;
}

/* ---- schematic ---- */

static void dot_label(FILE *f, const char *s) {
    for (; *s; s++)
        if (*s == '"' || *s == '\\')
            fputc('\\', f), fputc(*s, f);
        else
            fputc(*s, f);
}

/* The node an object is drawn as (trees: their root). */
static void obj_node(const wdrt_scene *S, const char *name, char *out, size_t n) {
    int i = voice_index(S, name);
    if (!strcmp(name, "listener"))
        snprintf(out, n, "listener");
    else if (i >= 0 && S->voices[i].tree)
        snprintf(out, n, "t%d_0", i);
    else if (i >= 0)
        snprintf(out, n, "v%d", i);
    else
        snprintf(out, n, "c%d", complex_index(S, name));
}

void wdrt_scene_dot(const wdrt_scene *S, FILE *f) {
    fputs("digraph scene {\n  rankdir=LR;\n  compound=true;\n  node [fontname=\"Helvetica\" fontsize=11];\n"
          "  edge [fontname=\"Helvetica\" fontsize=9];\n",
          f);
    fprintf(f, "  listener [shape=doublecircle style=filled fillcolor=\"#f4cccc\" label=\"listener\\n%s\"];\n",
            S->channels == 1 ? "mono" : S->binaural ? "binaural" : "stereo");
    int placed = 0, direct = 0;
    for (int i = 0; i < S->nvoices; i++)
        placed |= S->voices[i].placed, direct |= !S->voices[i].placed;
    for (int i = 0; i < S->ncx; i++)
        placed |= S->cx[i].placed, direct |= !S->cx[i].placed;
    if (placed) {
        fprintf(f, "  space [shape=box style=\"rounded,filled\" fillcolor=\"#ead1dc\" label=\"propagation\\n"
                   "delay (Doppler), distance%s%s\"];\n",
                S->sp.air ? ", air" : "", S->nwalls ? ", walls" : "");
        fputs("  space -> listener;\n", f);
    }
    if (direct) {
        fputs("  mix [shape=circle label=\"+\"];\n  mix -> listener;\n", f);
    }
    for (int r = 0; r < S->nrooms; r++) {
        fprintf(f, "  room%d [shape=box3d style=filled fillcolor=\"#d0e0e3\" label=\"room %d\\nT60 %.2g / %.2g s\\n"
                   "%d reflections\"];\n  space -> room%d;\n  room%d -> listener;\n",
                r, r + 1, S->rooms[r].t60_low, S->rooms[r].t60_high, S->rooms[r].order, r, r);
    }
    for (int w = 0; w < S->nwalls; w++)
        fprintf(f, "  wall%d [shape=note label=\"wall\\n%.3g dB\"];\n  wall%d -> space [style=dotted arrowhead=tee];\n",
                w, S->walls[w].loss_db, w);
    for (int i = 0; i < S->nvoices; i++) {
        const scvoice *v = &S->voices[i];
        char root[64];
        if (v->tree) {
            char prefix[32];
            snprintf(prefix, sizeof prefix, "t%d_", i);
            fprintf(f, "  subgraph cluster_t%d {\n  label=\"", i);
            dot_label(f, v->name);
            if (v->pool)
                fprintf(f, " (tree, %d notes)", v->pool);
            else
                fputs(" (tree)", f);
            fputs("\";\n  style=rounded;\n", f);
            tt_dot(f, v->tree->root, prefix, root);
            fputs("  }\n", f);
        } else {
            snprintf(root, sizeof root, "v%d", i);
            const char *b = strrchr(v->netlist, '/');
            fprintf(f, "  %s [shape=box style=filled fillcolor=\"#cfe2f3\" label=\"", root);
            dot_label(f, v->name);
            fputs("\\n", f);
            dot_label(f, b ? b + 1 : v->netlist);
            if (v->pool)
                fprintf(f, "\\n%d notes", v->pool);
            fputs("\"];\n", f);
        }
        fprintf(f, "  %s -> %s [label=\"gain %.3g\"];\n", root, v->placed ? "space" : "mix", v->gain);
        for (int k = 0; k < v->nparams; k++) {
            const sx *m = v->params[k].val.motion;
            if (!m)
                continue;
            for (const sx *o = m->head->next; o; o = o->next) {
                char from[64];
                obj_node(S, o->text, from, sizeof from);
                if (!strcmp(from, root))
                    continue;
                fprintf(f, "  %s -> %s [style=dashed color=\"#999999\" label=\"%s: %s\"];\n", from, root,
                        v->params[k].name, m->head->text);
            }
        }
    }
    for (int i = 0; i < S->ncx; i++) {
        fprintf(f, "  c%d [shape=component style=filled fillcolor=\"#fff2cc\" label=\"", i);
        dot_label(f, S->cx[i].name);
        fprintf(f, "\\ncomplex\"];\n  c%d -> %s;\n", i, S->cx[i].placed ? "space" : "mix");
    }
    /* what the timeline does to each object */
    for (int i = 0; i < S->nvoices; i++) {
        int n[6] = {0};
        for (int k = 0; k < S->nev; k++)
            if (S->ev[k].voice == i)
                n[S->ev[k].kind]++;
        if (!(n[SE_PLAY] + n[SE_IMPACT] + n[SE_STRIKE] + n[SE_SET]))
            continue;
        char root[64];
        obj_node(S, S->voices[i].name, root, sizeof root);
        fprintf(f, "  ev%d [shape=cds style=filled fillcolor=\"#eeeeee\" label=\"", i);
        const char *sep = "";
        static const char *const what[] = {"strikes", "sets", "gains", "plays", "stops", "impacts"};
        for (int k = 0; k < 6; k++)
            if (n[k]) {
                fprintf(f, "%s%d %s", sep, n[k], what[k]);
                sep = "\\n";
            }
        fprintf(f, "\"];\n  ev%d -> %s [style=dashed];\n", i, root);
    }
    /* who strikes whom */
    for (int k = 0; k < S->nev; k++) {
        const scevent *x = &S->ev[k];
        if (x->kind != SE_IMPACT)
            continue;
        int dup = 0;
        for (int j = 0; j < k; j++)
            dup |= S->ev[j].kind == SE_IMPACT && S->ev[j].voice == x->voice && !strcmp(S->ev[j].hitter->text, x->hitter->text);
        if (dup)
            continue;
        char a[64], b[64];
        obj_node(S, x->hitter->text, a, sizeof a);
        obj_node(S, S->voices[x->voice].name, b, sizeof b);
        fprintf(f, "  %s -> %s [style=bold color=\"#cc0000\" label=\"impacts\"];\n", a, b);
    }
    fputs("}\n", f);
}

/* ---- rendering ---- */

/* A curve that drives a param or a gain during the render. */
enum { DRIVE_GAIN = -1, DRIVE_MOVE = -2, DRIVE_LISTEN = -3 };

typedef struct drive {
    const sx *curve;
    double offset;  /* s added to the curve's times */
    wdrt_voice v;
    int param;      /* DRIVE_GAIN, DRIVE_MOVE, DRIVE_LISTEN, or the param */
    uint64_t next;  /* the next grid frame it posts at */
    uint64_t end;   /* the frame after which it has posted its last value */
    int motion;     /* curve is a motion binding, its objects in mo */
    motion_ref mo;
} drive;

typedef struct render {
    const wdrt_scene *S;
    wdrt_engine *e;
    double fs;
    int B;
    drive *dr;
    int ndr;
    int ei;          /* next scene event to post */
    int si;          /* a play posted in parts: 0, or 1 + the sets posted */
    wdrt_voice note; /* the note that play made */
    tt_class *tc;    /* the trees' classes, at the render's rate */
} render;


static wdrt_voice handle(const render *R, int vi) {
    return R->S->voices[vi].pool ? wdrt_engine_pool(R->e, vi) : wdrt_engine_voice(R->e, vi, 0);
}

static void add_drive(render *R, const sx *c, double offset, wdrt_voice v, int param) {
    R->dr = grow(R->dr, R->ndr, sizeof *R->dr);
    drive *d = &R->dr[R->ndr++];
    memset(d, 0, sizeof *d);
    d->curve = c;
    d->offset = offset;
    d->v = v;
    d->param = param;
    int moves = param == DRIVE_MOVE || param == DRIVE_LISTEN; /* a path: its keys are (T X Y Z) */
    uint64_t f0 = frame_of(offset + (moves ? c->head->next->head->num : curve_start(c)), R->fs);
    d->next = f0 / (uint64_t)R->B * (uint64_t)R->B;
    d->end = frame_of(offset + (moves ? path_end(c) : curve_end(c)), R->fs) + (uint64_t)R->B;
}

/* A param that follows a motion: posted every block while anything it
 * reads moves. */
static void add_motion_drive(render *R, const sx *m, wdrt_voice v, int param) {
    R->dr = grow(R->dr, R->ndr, sizeof *R->dr);
    drive *d = &R->dr[R->ndr++];
    memset(d, 0, sizeof *d);
    d->curve = m, d->v = v, d->param = param, d->motion = 1;
    d->mo = motion_resolve(R->S, m);
    double end = 0;
    for (const sx *o = m->head->next; o; o = o->next) {
        objref r;
        if (find_obj(R->S, o->text, &r) == 0 && r.path)
            end = fmax(end, path_end(r.path));
    }
    d->next = 0;
    d->end = frame_of(end, R->fs) + (uint64_t)R->B;
}

/* The motion-bound params of voice vi, set on a note played at t. */
static int motion_sets(const wdrt_scene *S, int vi) {
    int n = 0;
    for (int k = 0; k < S->voices[vi].nparams; k++)
        n += S->voices[vi].params[k].val.motion != NULL;
    return n;
}

static const scparam *motion_set(const wdrt_scene *S, int vi, int j) {
    for (int k = 0; k < S->voices[vi].nparams; k++)
        if (S->voices[vi].params[k].val.motion && j-- == 0)
            return &S->voices[vi].params[k];
    return NULL;
}

/* Posts one scene event; a play goes in parts (the play, its sets, its
 * strike), all at its frame. */
/* A param whose change redesigns part of voice vi's class (a string's
 * loop): posted with its design made here, on the thread that posts, so
 * the block that plays it does not make it (and the engine's budget does
 * not count it). */
static int designs(const render *R, int vi, int id) {
    const wdv_class *c = R->S->voices[vi].cls;
    return c && c->prepare && id >= 0 && id < c->n_params && (c->params[id].flags & WDV_PARAM_DESIGN);
}

/* Set s (from 1) of a play: its own sets, then its voice's params bound
 * to motion; 0 for a bound one the play sets itself. */
static int play_set(const render *R, const scevent *x, int s, double J, int *id, double *val) {
    const scparam *q = s <= x->nsets ? &x->sets[s - 1] : motion_set(R->S, x->voice, s - 1 - x->nsets);
    for (int j = 0; s > x->nsets && j < x->nsets; j++)
        if (x->sets[j].id == q->id)
            return 0; /* a play's own set wins over the param's binding */
    *id = q->id;
    *val = q->val.motion ? motion_at(R->S, q->val.motion, x->time, J) : q->val.v;
    return 1;
}

static wdrt_result post_event(render *R, const scevent *x, uint64_t f) {
    wdrt_engine *e = R->e;
    if (x->kind == SE_HIT || x->kind == SE_CONTACT)
        return WDRT_OK;
    wdrt_voice v = handle(R, x->voice);
    int ids[WDRT_STRIKE_MAX];
    double vals[WDRT_STRIKE_MAX];
    for (int k = 0; k < x->npairs; k++)
        ids[k] = x->pairs[k].id, vals[k] = x->pairs[k].value;
    switch (x->kind) {
    case SE_STRIKE:
        return wdrt_engine_strike(e, f, v, x->npairs, ids, vals);
    case SE_SET:
        if (x->set.val.curve) {
            add_drive(R, x->set.val.curve, x->time, v, x->set.id);
            return WDRT_OK;
        }
        if (x->set.val.motion)
            return wdrt_engine_set(e, f, v, x->set.id, motion_at(R->S, x->set.val.motion, x->time, 0));
        if (designs(R, x->voice, x->set.id))
            return wdrt_engine_set_prepared(e, f, v, 1, &x->set.id, &x->set.val.v);
        return wdrt_engine_set(e, f, v, x->set.id, x->set.val.v);
    case SE_GAIN:
        if (x->set.val.curve) {
            add_drive(R, x->set.val.curve, x->time, v, DRIVE_GAIN);
            return WDRT_OK;
        }
        return wdrt_engine_gain(e, f, v, x->set.val.v);
    case SE_STOP:
        return wdrt_engine_stop(e, f, v);
    case SE_HIT:
    case SE_CONTACT: /* the world's timeline (section "bodies") */
        return WDRT_OK;
    case SE_IMPACT:
    case SE_PLAY: {
        wdrt_result r;
        if (R->si == 0) {
            if ((r = wdrt_engine_play(e, f, x->voice, x->gain, x->priority, &R->note)) != WDRT_OK)
                return r;
            R->si = 1;
        }
        /* the play's own sets, then the params bound to motion, at the
         * time; those that redesign the voice together, with their design */
        double J = x->kind == SE_IMPACT ? impact_impulse(R->S, x) : 0;
        int total = x->nsets + motion_sets(R->S, x->voice), id;
        double val;
        for (; R->si <= total; R->si++)
            if (play_set(R, x, R->si, J, &id, &val) && !designs(R, x->voice, id) &&
                (r = wdrt_engine_set(e, f, R->note, id, val)) != WDRT_OK)
                return r;
        if (R->si == total + 1) {
            int n = 0;
            for (int s = 1; s <= total && n < WDRT_STRIKE_MAX; s++)
                if (play_set(R, x, s, J, &ids[n], &vals[n]) && designs(R, x->voice, ids[n]))
                    n++;
            if (n && (r = wdrt_engine_set_prepared(e, f, R->note, n, ids, vals)) != WDRT_OK)
                return r;
            R->si++;
        }
        for (int k = 0; k < x->npairs; k++)
            ids[k] = x->pairs[k].id, vals[k] = x->pairs[k].value;
        if (x->npairs && (r = wdrt_engine_strike(e, f, R->note, x->npairs, ids, vals)) != WDRT_OK)
            return r;
        R->si = 0;
        return WDRT_OK;
    }
    }
    return WDRT_OK;
}

/* Posts what acts before frame `until`; returns the frame the render may
 * go to (less than until when the queue filled up). */
static uint64_t post_due(render *R, uint64_t now, uint64_t until) {
    const wdrt_scene *S = R->S;
    while (R->ei < S->nev) {
        const scevent *x = &S->ev[R->ei];
        uint64_t f = frame_of(x->time, R->fs);
        if (f >= until)
            break;
        if (post_event(R, x, f) == WDRT_QUEUE_FULL)
            return f > now ? f : now + 1;
        R->ei++;
    }
    for (int i = 0; i < R->ndr; i++) {
        drive *d = &R->dr[i];
        while (d->next < until && d->next <= d->end) {
            /* the value the ramp from this frame reaches a block later */
            double t = (double)(d->next + (uint64_t)R->B) / R->fs - d->offset, p[3];
            wdrt_result r;
            if (d->param == DRIVE_MOVE || d->param == DRIVE_LISTEN) {
                path_at(d->curve, t, p);
                r = d->param == DRIVE_MOVE ? wdrt_engine_move(R->e, d->next, d->v, p)
                                           : wdrt_engine_listen(R->e, d->next, p, NULL);
            } else {
                double x = d->motion ? motion_eval(&d->mo, t, 0) : curve_at(d->curve, t);
                r = d->param == DRIVE_GAIN ? wdrt_engine_gain(R->e, d->next, d->v, x)
                                           : wdrt_engine_set(R->e, d->next, d->v, d->param, x);
            }
            if (r == WDRT_QUEUE_FULL)
                return d->next > now ? d->next : now + 1;
            d->next += (uint64_t)R->B;
        }
    }
    return until;
}

/* Whether p is a param the class knows, set to a number (not a curve or
 * a motion). */
static int constant(const scparam *p) { return p->id >= 0 && !p->val.curve && !p->val.motion; }

/* Sets on st the constant params of ps. */
static void set_consts(const wdv_class *c, void *st, const scparam *ps, int n) {
    for (int k = 0; k < n; k++)
        if (constant(&ps[k]))
            c->set_param(st, ps[k].id, ps[k].val.v);
}

/* The first of ps that moves a string's or tube's loop, or NULL; the
 * values of those (by param, NAN where not set) go to key. */
static const scparam *design_param(const wdv_class *c, const scparam *ps, int n, double *key) {
    const scparam *d = NULL;
    for (int i = 0; i < c->n_params; i++)
        key[i] = NAN;
    for (int k = 0; k < n; k++)
        if (constant(&ps[k]) && (c->params[ps[k].id].flags & WDV_PARAM_DESIGN)) {
            key[ps[k].id] = ps[k].val.v;
            d = d ? d : &ps[k];
        }
    return d;
}

/* Whether key (n values, NAN alike) is among the nk keys seen. */
static int key_seen(const double *keys, int nk, const double *key, int n) {
    for (int j = 0; j < nk; j++) {
        int same = 1;
        for (int i = 0; i < n && same; i++)
            same = keys[j * n + i] == key[i] || (isnan(keys[j * n + i]) && isnan(key[i]));
        if (same)
            return 1;
    }
    return 0;
}

/* A voice whose string or tube cannot be tuned at rate fs
 * (wdv_class.tuning), at its params or with the loop params an event
 * sets on top of them, would play out of tune: an error at the param (or
 * the voice).  wdrt builds a voice for a rate its lines would not hold,
 * so what cannot be tuned here is a loop too short for its filters.  0,
 * or -1 after printing it. */
static int check_tuning(const wdrt_scene *S, double fs) {
    double dummy[1] = {0};
    const double *in[64];
    double *out[64];
    for (int k = 0; k < 64; k++)
        in[k] = dummy, out[k] = dummy;
    for (int i = 0; i < S->nvoices; i++) {
        const scvoice *v = &S->voices[i];
        const wdv_class *c = v->cls;
        if (v->tree || !c || !c->tuning || c->n_inputs > 64 || c->n_outputs > 64)
            continue;
        void *st = xcalloc(1, c->state_size);
        /* the loop params' values checked so far: each set once */
        const int np = c->n_params > 0 ? c->n_params : 1, cap = 1024;
        double *keys = xcalloc((size_t)cap * (size_t)np, sizeof(double)), *key = xcalloc((size_t)np, sizeof(double));
        int nk = 0, bad = 0;
        for (int e = -1; e < S->nev && !bad; e++) {
            const scparam *ps = v->params, *d = NULL;
            int n = v->nparams;
            if (e >= 0) {
                const scevent *ev = &S->ev[e];
                if (ev->voice != i || (ev->kind != SE_SET && ev->kind != SE_PLAY))
                    continue;
                ps = ev->kind == SE_SET ? &ev->set : ev->sets, n = ev->kind == SE_SET ? 1 : ev->nsets;
                if (!(d = design_param(c, ps, n, key)) || key_seen(keys, nk, key, np))
                    continue;
                if (nk < cap)
                    memcpy(keys + (size_t)nk++ * (size_t)np, key, sizeof(double) * (size_t)np);
            }
            c->init(st, fs);
            set_consts(c, st, v->params, v->nparams);
            if (e >= 0)
                set_consts(c, st, ps, n);
            c->process(st, in, out, 0);
            if (!(c->tuning(st) < INFINITY)) {
                char err[1024];
                if (d)
                    sx_error(S->doc, d->at, err, sizeof err,
                             "with %s = %g, a string or tube of voice %s cannot be tuned at %g Hz: its loop is too "
                             "short for its filters there, and would play out of tune (lower it, or raise the rate)",
                             d->name, d->val.v, v->name, fs);
                else
                    sx_error(S->doc, v->at, err, sizeof err,
                             "a string or tube of voice %s cannot be tuned at %g Hz: its loop is too short for its "
                             "filters there, and would play out of tune (raise the rate)", v->name, fs);
                fputs(err, stderr);
                bad = 1;
            }
        }
        free(st);
        free(keys);
        free(key);
        if (bad)
            return -1;
    }
    return 0;
}

static int render_init(render *R, const wdrt_scene *S, const wdrt_render_opts *o, wdrt_pool_config *pc,
                       double **pv) {
    memset(R, 0, sizeof *R);
    R->S = S;
    R->fs = wdrt_scene_rate(S, o);
    R->tc = xcalloc((size_t)S->nvoices + 1, sizeof *R->tc);
    for (int i = 0; i < S->nvoices; i++) {
        const scvoice *v = &S->voices[i];
        if (!v->cls)
            return -1;
        if (v->tree) {
            char err[1024];
            if (tt_class_init(&R->tc[i], v->prog, R->fs, err, sizeof err)) {
                fputs(err, stderr);
                return -1;
            }
        }
        pc[i] = wdrt_pool_config_init(v->tree ? &R->tc[i].cls : v->cls, v->pool ? v->pool : 1);
        if (v->tree) {
            pc[i].bind = tt_class_bind;
            pc[i].data = &R->tc[i];
        }
        pc[i].owned = !v->pool;
        pc[i].output = v->output;
        pc[i].gain = v->gain_curve ? curve_at(v->gain_curve, 0) : v->gain;
        pc[i].pan = v->pan;
        pc[i].priority = v->priority;
        pc[i].cost_ns = v->cost;
        pc[i].quiet = v->quiet;
        pc[i].hold = v->hold;
        pc[i].virtualize = v->virtualize;
        pc[i].placed = v->placed;
        pc[i].ambient = v->ambient;
        memcpy(pc[i].pos, v->pos, sizeof v->pos);
        pv[i] = xcalloc((size_t)v->cls->n_params + 1, sizeof(double));
        for (int k = 0; k < v->cls->n_params; k++)
            pv[i][k] = v->cls->params[k].def;
        for (int k = 0; k < v->nparams; k++)
            pv[i][v->params[k].id] = v->params[k].val.curve    ? curve_at(v->params[k].val.curve, 0)
                                     : v->params[k].val.motion ? motion_at(S, v->params[k].val.motion, 0, 0)
                                                               : v->params[k].val.v;
        pc[i].params = pv[i];
    }
    return 0;
}

static void add_voice_drives(render *R) {
    const wdrt_scene *S = R->S;
    for (int i = 0; i < S->nvoices; i++) {
        const scvoice *v = &S->voices[i];
        for (int k = 0; k < v->nparams; k++)
            if (v->params[k].val.curve)
                add_drive(R, v->params[k].val.curve, 0, handle(R, i), v->params[k].id);
            else if (v->params[k].val.motion && !v->pool)
                add_motion_drive(R, v->params[k].val.motion, handle(R, i), v->params[k].id);
        if (v->gain_curve)
            add_drive(R, v->gain_curve, 0, handle(R, i), DRIVE_GAIN);
        if (v->path)
            add_drive(R, v->path, 0, handle(R, i), DRIVE_MOVE);
    }
}

/* The frame after the scene's last event or curve key. */
static uint64_t last_frame(const render *R) {
    const wdrt_scene *S = R->S;
    double t = 0;
    for (int i = 0; i < S->nev; i++) {
        double te = S->ev[i].kind == SE_CONTACT ? S->ev[i].until : S->ev[i].time;
        if (S->ev[i].set.val.curve)
            te += curve_end(S->ev[i].set.val.curve);
        t = te > t ? te : t;
    }
    for (int i = 0; i < S->nvoices; i++) {
        for (int k = 0; k < S->voices[i].nparams; k++)
            if (S->voices[i].params[k].val.curve)
                t = fmax(t, curve_end(S->voices[i].params[k].val.curve));
        if (S->voices[i].gain_curve)
            t = fmax(t, curve_end(S->voices[i].gain_curve));
        if (S->voices[i].path)
            t = fmax(t, path_end(S->voices[i].path));
    }
    if (S->lis_path)
        t = fmax(t, path_end(S->lis_path));
    for (int i = 0; i < S->ncx; i++)
        if (S->cx[i].path)
            t = fmax(t, path_end(S->cx[i].path));
    return frame_of(t, R->fs) + 1;
}

/* The engine's spatial layer: on when a voice is placed, with a delay line
 * for each placed voice (at most 64 unless the scene says) and a few for
 * sound still in flight. */
static void space_config(const wdrt_scene *S, wdrt_space_config *sp) {
    int n = 0;
    for (int i = 0; i < S->nvoices; i++)
        if (S->voices[i].placed)
            n += S->voices[i].pool ? S->voices[i].pool : 1;
    for (int i = 0; i < S->ncx; i++)
        n += S->cx[i].placed;
    for (int i = 0; i < S->nbodies; i++)
        n += S->bodies[i].placed && S->bodies[i].share < 0;
    int amb = 0;
    for (int i = 0; i < S->nvoices; i++)
        amb |= S->voices[i].ambient > 0;
    *sp = S->sp;
    if (n == 0 && amb)
        n = 1; /* rooms live in the spatial layer */
    sp->sources = n == 0 ? 0 : S->sources ? S->sources : n + 4 < 64 ? n + 4 : 64;
    memcpy(sp->listener, S->lis, sizeof S->lis);
    sp->walls = S->walls;
    sp->nwalls = S->nwalls;
    sp->rooms = S->rooms;
    sp->nrooms = S->nrooms;
}

/* The sink wdrt_scene_render keeps the frames with when the caller gives
 * none: an array that grows by doubling, up to the render's length. */
typedef struct kept {
    double *y;
    uint64_t n, alloc, cap; /* frames kept, room, the render's length */
} kept;

static int keep_frames(const double *frames, long n, int nch, void *user) {
    kept *k = user;
    if (k->n + (uint64_t)n > k->alloc) {
        uint64_t a = 2 * (k->n + (uint64_t)n);
        a = a < k->cap ? a : k->cap;
        double *p = realloc(k->y, sizeof(double) * (size_t)a * (size_t)nch);
        if (!p)
            return 1;
        k->y = p, k->alloc = a;
    }
    memcpy(k->y + k->n * (uint64_t)nch, frames, sizeof(double) * (size_t)n * (size_t)nch);
    k->n += (uint64_t)n;
    return 0;
}

wdrt_result wdrt_scene_render(const wdrt_scene *S, const wdrt_render_opts *o, double **frames, long *nframes,
                              int *nch, double *rate, wdrt_engine_stats *stats) {
    if (!S || !frames || !nframes || !nch)
        return WDRT_INVALID_ARGS;
    render R;
    wdrt_pool_config *pc = xcalloc((size_t)S->nvoices + (size_t)S->ncx + 1, sizeof *pc);
    wdrt_bodies *bodies = NULL;
    swtl tl;
    memset(&tl, 0, sizeof tl);
    cx_source *srcs = xcalloc((size_t)S->ncx + 1, sizeof *srcs);
    double **pv = xcalloc((size_t)S->nvoices + 1, sizeof *pv);
    wdrt_result res = WDRT_INVALID_ARGS;
    double *out = NULL;
    wdrt_hrtf *ears = NULL;
    kept keep = {NULL, 0, 0, 0}; /* the frames, kept when the caller gives no sink; freed at done */
    if (render_init(&R, S, o, pc, pv) != 0)
        goto done;
    if (check_tuning(S, R.fs) != 0) {
        res = WDRT_OUT_OF_TUNE;
        goto done;
    }
    complex_pools(S, pc + S->nvoices, srcs);
    if (sw_build(S, R.fs, &bodies, &tl) != 0) {
        fprintf(stderr, "wdrt: error: the scene's bodies could not be built\n");
        goto done;
    }
    int nres = wdrt_bodies_npools(bodies);
    if (nres) {
        pc = realloc(pc, sizeof *pc * ((size_t)S->nvoices + (size_t)S->ncx + (size_t)nres + 1));
        if (!pc) {
            res = WDRT_OUT_OF_MEMORY;
            goto done;
        }
        wdrt_bodies_pools(bodies, pc, S->nvoices + S->ncx);
    }
    wdrt_engine_config ec = wdrt_engine_config_init(R.fs, S->channels, S->nvoices + S->ncx + nres, pc);
    if (nres)
        wdrt_bodies_attach(bodies, &ec);
    ec.queue = 1 << 16;
    ec.pending = 1 << 16;
    ec.sleep = S->sleep && !(o && o->nosleep);
    ec.budget_ns = o && o->budget_ns > 0 ? o->budget_ns : S->budget_cpu * 1e9 / R.fs;
    space_config(S, &ec.space);
    if (S->binaural && ec.space.sources > 0) { /* the scene's HRTF, or at another rate its own */
        char err[512];
        if (R.fs != S->ears_fs && !(ears = wdrt_hrtf_open(S->sofa, R.fs, err, sizeof err))) {
            fputs(err, stderr);
            res = WDRT_FORMAT;
            goto done;
        }
        ec.space.hrtf = ears ? ears : S->ears;
    }
    if ((res = wdrt_engine_init(&ec, NULL, &R.e)) != WDRT_OK)
        goto done;
    R.B = ec.block;
    add_voice_drives(&R);
    if (S->lis_path)
        add_drive(&R, S->lis_path, 0, 0, DRIVE_LISTEN);
    for (int i = 0; i < S->ncx; i++)
        if (S->cx[i].path)
            add_drive(&R, S->cx[i].path, 0, wdrt_engine_voice(R.e, S->nvoices + i, 0), DRIVE_MOVE);
    double secs = o && o->seconds > 0 ? o->seconds : S->length;
    for (int i = 0; secs <= 0 && i < S->nvoices; i++)
        if (S->voices[i].tree && !S->voices[i].pool && !isfinite(tt_prog_end(S->voices[i].prog))) {
            fprintf(stderr,
                    "%s: note: tree '%s' never ends and the scene has no (length): it is rendered until %g s "
                    "after the last event\n",
                    S->doc->path, S->voices[i].name, LAST_RING_S);
            break;
        }
    uint64_t n = secs > 0 ? frame_of(secs, R.fs) : 0, last = last_frame(&R);
    uint64_t cap = secs > 0 ? n : last + frame_of(LAST_RING_S, R.fs), t = 0;
    const uint64_t chunk = 4096;
    /* every run goes to a sink: the caller's, or one that keeps the frames */
    keep.cap = cap;
    int (*sink)(const double *, long, int, void *) = o && o->sink ? o->sink : keep_frames;
    void *user = o && o->sink ? o->sink_user : &keep;
    if (!(out = malloc(sizeof(double) * (size_t)chunk * (size_t)S->channels))) {
        res = WDRT_OUT_OF_MEMORY;
        goto done;
    }
    wdrt_engine_stats st;
    while (t < cap) {
        uint64_t want = t + chunk < cap ? t + chunk : cap;
        uint64_t end = post_due(&R, t, sw_post(bodies, &tl, t, want)); /* a run is at most a chunk */
        wdrt_engine_process(R.e, out, (uint32_t)(end - t));
        if (sink(out, (long)(end - t), S->channels, user)) {
            res = sink == keep_frames ? WDRT_OUT_OF_MEMORY : WDRT_IO;
            goto done;
        }
        t = end;
        wdrt_engine_get_stats(R.e, &st);
        if (o && o->progress)
            o->progress(secs > 0 ? (double)t / (double)cap : -(double)t / R.fs, o->user);
        if (secs <= 0 && t >= last && R.ei == S->nev && st.awake == 0 && st.virtual_ == 0 && st.sources == 0 &&
            st.rooms == 0) /* rung down: nothing sounds, nothing in flight, no reverb left */
            break;
    }
    wdrt_engine_get_stats(R.e, &st);
    if (stats)
        *stats = st;
    *frames = keep.y; /* NULL through the caller's sink */
    keep.y = NULL;
    *nframes = (long)t;
    *nch = S->channels;
    if (rate)
        *rate = R.fs;
    res = WDRT_OK;
done:
    free(keep.y);
    free(out);
    if (R.e)
        wdrt_engine_uninit(R.e, NULL);
    wdrt_hrtf_close(ears);
    for (int i = 0; i < S->nvoices; i++)
        free(pv[i]);
    free(pv);
    free(pc);
    free(srcs);
    free(R.dr);
    for (int i = 0; R.tc && i < S->nvoices; i++)
        tt_class_uninit(&R.tc[i]);
    free(R.tc);
    wdrt_bodies_free(bodies);
    free(tl.ev);
    return res;
}
