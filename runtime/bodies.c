/*
 * bodies.c - bodies that sound when they touch, in an engine: the public
 * face (wdrt.h, "bodies") of the surfaces' world (surf.h).
 *
 * A wdrt_bodies holds a world and hands the engine one pool per
 * resonator: a "tap" voice that plays what the world made of its
 * resonator in the block (or, for a body that rings a compiled voice, that
 * voice with the world's force on its input).  The world runs in the
 * engine's excitations phase, before the voices: the physics thread's
 * events wait in a lock-free single-producer queue until the block that
 * holds their frame, and act at that frame; the taps of the resonators it
 * excited wake.  Nothing here allocates after wdrt_bodies_new.
 */
#include "wdrt.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "surf.h"

#define BLOCK 64 /* the engine's block at most: what a tap reads per block */

enum { BE_IMPACT, BE_CONTACT, BE_STOP, BE_ENABLE };

typedef struct bev {
    uint64_t frame;
    int kind, a, b, id;
    double d[4];
} bev;

typedef struct tapref {
    wdrt_bodies *h;
    int res;
} tapref;

struct wdrt_bodies {
    wdrt_bodies_config cfg;
    surf_world *w;
    int nbodies, nres;
    int *body_res;       /* per body: its resonator */
    int *res_body;       /* per resonator: the body that owns it */
    wdrt_body *body;     /* copies (modes point into the world's copy) */
    double *gain;        /* per resonator */
    wdv_class *vc;       /* per resonator: the tap of a voice body (process NULL: modal) */
    tapref *refs;        /* per resonator: what its tap is bound to */
    double *out;         /* [nres][BLOCK]: what each resonator made of the segment */
    int *cursor;         /* per resonator: frames its tap has read */
    int *active;         /* per resonator: the modes it was admitted with */
    unsigned char *clean;/* per resonator: its row of out is all zeros */
    int *act, nact;      /* the resonators that may sound: excited or awake */
    unsigned char *inact;
    int pool0;           /* the engine pool of resonator 0 */
    surf_contact *ids;   /* per contact id */
    bev *q;              /* the physics queue */
    uint32_t qmask, head, tail;
    uint64_t refused, lowered;
};

/* ---- the taps ---- */

typedef struct tap_state {
    wdrt_bodies *h;
    int res;
} tap_state;

static void tap_init(void *state, double fs) {
    (void)fs;
    memset(state, 0, sizeof(tap_state));
}
static void tap_reset(void *state) { (void)state; }
static int tap_set_param(void *state, int id, double v) {
    (void)state, (void)id, (void)v;
    return -1;
}
static double tap_get_param(const void *state, int id) {
    (void)state, (void)id;
    return 0;
}
static double tap_work(const void *state) {
    (void)state;
    return 0;
}
static int tap_set_ic(void *state, int n, const int *ids, const double *v) {
    (void)state, (void)n, (void)ids, (void)v;
    return -1;
}

static void tap_process(void *state, const double *const *in, double *const *out, int n) {
    (void)in;
    tap_state *t = state;
    if (!t->h) {
        memset(out[0], 0, sizeof(double) * (size_t)(n > 0 ? n : 0));
        return;
    }
    int c = t->h->cursor[t->res];
    const double *y = t->h->out + (size_t)t->res * BLOCK;
    for (int i = 0; i < n; i++)
        out[0][i] = c + i < BLOCK ? y[c + i] : 0;
    t->h->cursor[t->res] = c + n < BLOCK ? c + n : BLOCK; /* past the block: silence */
}

static double tap_energy(const void *state) {
    const tap_state *t = state;
    return t->h ? surf_resonator_energy(t->h->w, t->res) : 0;
}

/* A body's voice, rung through its force input: its state after a header,
 * then a block of zeros and a block per output it does not hear. */
typedef struct vtap_state {
    wdrt_bodies *h;
    int res, input, output;
    const wdv_class *cls;
    double fs;
} vtap_state;

static size_t up16(size_t n) { return (n + 15) & ~(size_t)15; }

static void vtap_init(void *state, double fs) {
    vtap_state *t = state;
    memset(t, 0, sizeof *t);
    t->fs = fs;
}

static void vtap_reset(void *state) {
    vtap_state *t = state;
    if (t->cls)
        t->cls->reset((char *)state + up16(sizeof *t));
}

static void vtap_process(void *state, const double *const *in, double *const *out, int n) {
    (void)in;
    vtap_state *t = state;
    if (!t->cls) {
        memset(out[0], 0, sizeof(double) * (size_t)(n > 0 ? n : 0));
        return;
    }
    const wdv_class *c = t->cls;
    char *inner = (char *)state + up16(sizeof *t);
    double *zero = (double *)(inner + up16(c->state_size));
    const double *ip[64];
    double *op[64];
    for (int k = 0; k < c->n_inputs && k < 64; k++)
        ip[k] = zero;
    if (t->h) {
        int cur = t->h->cursor[t->res];
        ip[t->input] = cur + n <= BLOCK ? t->h->out + (size_t)t->res * BLOCK + cur : zero;
        t->h->cursor[t->res] = cur + n < BLOCK ? cur + n : BLOCK;
    }
    for (int k = 0; k < c->n_outputs && k < 64; k++)
        op[k] = k == t->output ? out[0] : zero + BLOCK * (1 + (size_t)k);
    c->process(inner, ip, op, n);
}

static double vtap_energy(const void *state) {
    const vtap_state *t = state;
    return t->cls ? t->cls->energy((const char *)state + up16(sizeof *t)) : 0;
}

static double vtap_tuning(const void *state) {
    const vtap_state *t = state;
    return t->cls && t->cls->tuning ? t->cls->tuning((const char *)state + up16(sizeof *t)) : 0;
}

static void tap_bind(void *state, const void *data) {
    const tapref *r = data;
    const wdrt_body *b = &r->h->body[r->h->res_body[r->res]];
    if (b->voice) {
        vtap_state *v = state;
        v->h = r->h, v->res = r->res, v->cls = b->voice, v->input = b->input, v->output = b->output;
        v->cls->init((char *)state + up16(sizeof *v), v->fs);
        return;
    }
    tap_state *t = state;
    t->h = r->h;
    t->res = r->res;
}

static const wdv_port tap_out[1] = {{"out", ""}};
static const wdv_class tap_class = {"body",    WDV_ABI_VERSION, 64,           sizeof(tap_state), 0,
                                    1,         0,               0,            NULL,              tap_out,
                                    NULL,      NULL,            tap_init,     tap_reset,         tap_set_param,
                                    tap_get_param, tap_process, tap_energy,   tap_work,          tap_set_ic,
                                    0,         NULL,            NULL,         NULL,              NULL,
                                    NULL};

/* ---- set-up ---- */

wdrt_body wdrt_body_init(void) {
    wdrt_body b;
    memset(&b, 0, sizeof b);
    b.share = -1;
    b.mass = 0.1;
    b.hardness = 1e7;
    b.relief = WDRT_RELIEF_NOISE;
    b.relief_scale = 1e-4;
    b.relief_width = 5e-5;
    b.cutoff_roll = 200;
    b.cutoff_slip = 8000;
    b.gain = 1;
    b.quiet = 1e-5;
    b.contact_gains.master = b.impact_gains.master = 1;
    b.contact_gains.limit = b.impact_gains.limit = INFINITY;
    return b;
}

wdrt_bodies_config wdrt_bodies_config_init(double rate) {
    wdrt_bodies_config c;
    c.rate = rate;
    c.max_bodies = 64;
    c.max_modes = 64;
    c.contacts = 32;
    c.impacts = 64;
    c.queue = 4096;
    c.relief_frames = 0;
    c.active_modes = 0;
    return c;
}

void wdrt_bodies_free(wdrt_bodies *h) {
    if (!h)
        return;
    if (h->w)
        surf_uninit(h->w, NULL);
    free(h->body_res);
    free(h->res_body);
    free(h->body);
    free(h->gain);
    free(h->vc);
    free(h->refs);
    free(h->out);
    free(h->cursor);
    free(h->active);
    free(h->clean);
    free(h->act);
    free(h->inact);
    free(h->ids);
    free(h->q);
    free(h);
}

wdrt_result wdrt_bodies_new(const wdrt_bodies_config *c, wdrt_bodies **out) {
    if (!c || !out || !(c->rate >= 8000 && c->rate <= 768000) || c->max_bodies < 1 || c->max_bodies > 65536 ||
        c->max_modes < 0 || c->max_modes > 65536 || c->contacts < 1 || c->contacts > SURF_MAX_POOL ||
        c->impacts < 1 || c->impacts > SURF_MAX_POOL || c->queue < 1 || c->queue > (1 << 24) ||
        c->active_modes < 0 || c->relief_frames < 0)
        return WDRT_INVALID_ARGS;
    *out = NULL;
    wdrt_bodies *h = calloc(1, sizeof *h);
    if (!h)
        return WDRT_OUT_OF_MEMORY;
    h->cfg = *c;
    uint32_t qn = 1;
    while (qn < (uint32_t)c->queue)
        qn <<= 1;
    h->qmask = qn - 1;
    size_t nb = (size_t)c->max_bodies;
    h->body_res = calloc(nb, sizeof *h->body_res);
    h->res_body = calloc(nb, sizeof *h->res_body);
    h->body = calloc(nb, sizeof *h->body);
    h->gain = calloc(nb, sizeof *h->gain);
    h->vc = calloc(nb, sizeof *h->vc);
    h->refs = calloc(nb, sizeof *h->refs);
    h->out = calloc(nb * BLOCK, sizeof *h->out);
    h->cursor = calloc(nb, sizeof *h->cursor);
    h->active = calloc(nb, sizeof *h->active);
    h->act = calloc(nb, sizeof *h->act);
    h->inact = calloc(nb, 1);
    h->clean = malloc(nb);
    if (h->clean)
        memset(h->clean, 1, nb);
    h->ids = calloc((size_t)c->contacts, sizeof *h->ids);
    h->q = calloc(qn, sizeof *h->q);
    surf_config sc = surf_config_init(c->rate);
    sc.block = BLOCK;
    sc.max_bodies = c->max_bodies;
    sc.max_resonators = c->max_bodies;
    sc.max_surfaces = c->max_bodies;
    sc.max_modes = c->max_modes > 0 ? c->max_modes : 1;
    sc.max_pickups = 1;
    sc.max_contacts = c->contacts;
    sc.max_impacts = c->impacts;
    sc.relief_frames = c->relief_frames;
    if (!h->body_res || !h->res_body || !h->body || !h->gain || !h->vc || !h->refs || !h->out || !h->cursor || !h->active || !h->clean || !h->act || !h->inact ||
        !h->ids || !h->q || surf_init(&sc, NULL, &h->w) != WDRT_OK) {
        wdrt_bodies_free(h);
        return WDRT_OUT_OF_MEMORY;
    }
    *out = h;
    return WDRT_OK;
}

int wdrt_bodies_add(wdrt_bodies *h, const wdrt_body *b) {
    if (!h || !b || h->nbodies == h->cfg.max_bodies)
        return h && b ? WDRT_OUT_OF_MEMORY : WDRT_INVALID_ARGS;
    int own = (b->nmodes > 0) + (b->voice != NULL) + (b->share >= 0);
    if (own != 1 || (b->share >= h->nbodies) || b->nmodes > h->cfg.max_modes || (b->nmodes && !b->modes) ||
        (b->voice && (b->input < 0 || b->input >= b->voice->n_inputs || b->output < 0 ||
                      b->output >= b->voice->n_outputs || b->voice->n_inputs > 64 || b->voice->n_outputs > 64)) ||
        !isfinite(b->gain) || !(b->quiet >= 0))
        return WDRT_INVALID_ARGS;
    int r;
    if (b->share >= 0) {
        r = h->body_res[b->share];
    } else if (b->voice) {
        if ((r = surf_add_external(h->w)) < 0)
            return r;
        wdv_class *c = &h->vc[r];
        *c = tap_class;
        c->name = b->voice->name;
        c->state_size = up16(sizeof(vtap_state)) + up16(b->voice->state_size) +
                        sizeof(double) * BLOCK * (1 + (size_t)b->voice->n_outputs);
        c->init = vtap_init, c->reset = vtap_reset, c->process = vtap_process, c->energy = vtap_energy;
        c->tuning = b->voice->tuning ? vtap_tuning : NULL;
    } else {
        surf_mode *m = calloc((size_t)b->nmodes, sizeof *m);
        if (!m)
            return WDRT_OUT_OF_MEMORY;
        for (int k = 0; k < b->nmodes; k++)
            m[k].f = b->modes[k].f, m[k].t60 = b->modes[k].t60, m[k].gain[0] = b->modes[k].gain;
        surf_resonator_desc rd = surf_resonator_desc_init();
        rd.modes = m, rd.nmodes = b->nmodes, rd.npickups = 1, rd.quiet = b->quiet;
        r = surf_add_resonator(h->w, &rd);
        free(m);
        if (r < 0)
            return r;
    }
    if (b->share < 0) {
        h->res_body[r] = h->nbodies;
        h->gain[r] = b->voice ? 1 : b->gain;
        h->refs[r].h = h, h->refs[r].res = r;
        h->nres = r + 1;
    }
    surf_surface_desc sd = surf_surface_desc_init();
    sd.hardness = b->hardness;
    sd.damping = b->damping;
    sd.relief.kind = b->relief == WDRT_RELIEF_GRID      ? SURF_RELIEF_GRID
                     : b->relief == WDRT_RELIEF_NONE    ? SURF_RELIEF_NONE
                     : b->relief == WDRT_RELIEF_SEGMENT ? SURF_RELIEF_SEGMENT
                                                        : SURF_RELIEF_NOISE;
    sd.relief.scale = b->relief_scale;
    sd.relief.width = b->relief_width;
    sd.relief.samples = b->relief_samples;
    sd.relief.nsamples = b->relief_nsamples;
    sd.contact = (surf_gains){b->contact_gains.master, b->contact_gains.other, b->contact_gains.direct,
                              b->contact_gains.limit};
    sd.impact = (surf_gains){b->impact_gains.master, b->impact_gains.other, b->impact_gains.direct,
                             b->impact_gains.limit};
    sd.cutoff_roll = b->cutoff_roll;
    sd.cutoff_slip = b->cutoff_slip;
    int s = surf_add_surface(h->w, &sd);
    if (s < 0)
        return s;
    surf_body_desc bd = {r, s, b->mass};
    int i = surf_add_body(h->w, &bd);
    if (i < 0)
        return i;
    h->body_res[i] = r;
    h->body[i] = *b;
    h->body[i].modes = NULL; /* copied into the world */
    h->body[i].relief_samples = NULL;
    h->nbodies = i + 1;
    return i;
}

int wdrt_bodies_npools(const wdrt_bodies *h) { return h ? h->nres : 0; }

wdrt_result wdrt_bodies_pools(wdrt_bodies *h, wdrt_pool_config *pools, int first) {
    if (!h || (!pools && h->nres) || first < 0)
        return WDRT_INVALID_ARGS;
    h->pool0 = first;
    for (int r = 0; r < h->nres; r++) {
        const wdrt_body *b = &h->body[h->res_body[r]];
        wdrt_pool_config *p = &pools[first + r];
        *p = wdrt_pool_config_init(b->voice ? &h->vc[r] : &tap_class, 1);
        p->owned = 1;
        p->bind = tap_bind;
        p->data = &h->refs[r];
        p->quiet = b->quiet;
        p->gain = b->voice ? b->gain : 1;
        p->placed = b->placed;
        memcpy(p->pos, b->pos, sizeof b->pos);
        p->cost_ns = b->voice ? 0 : 1; /* a modal tap only copies: the world's cost is its own */
    }
    return WDRT_OK;
}

/* ---- the excitations phase ---- */

/* Admission under the mode limit: a resonator that is asleep when it is
 * excited gets the modes left (its loudest first); 0 if none are. */
static int admit(wdrt_bodies *h, int body) {
    int r = h->body_res[body];
    if (!h->cfg.active_modes || h->vc[r].process || surf_resonator_awake(h->w, r))
        return 1;
    int used = 0;
    for (int i = 0; i < h->nres; i++)
        if (i != r && !h->vc[i].process && surf_resonator_awake(h->w, i))
            used += h->active[i];
    int want = surf_resonator_modes(h->w, r), left = h->cfg.active_modes - used;
    int n = want < left ? want : left > 0 ? left : 0;
    surf_resonator_set_active_modes(h->w, r, n);
    h->active[r] = n;
    h->lowered += n < want;
    return n > 0;
}

/* Resonator r may sound from now on: the excitations phase visits it. */
static void visit(wdrt_bodies *h, int r) {
    if (h->inact[r])
        return;
    h->inact[r] = 1;
    h->act[h->nact++] = r;
}

static void apply(wdrt_bodies *h, const bev *x) {
    surf_world *w = h->w;
    if (x->kind != BE_STOP) {
        visit(h, h->body_res[x->a]);
        if (x->kind != BE_ENABLE)
            visit(h, h->body_res[x->b]);
    }
    if (x->kind == BE_IMPACT || (x->kind == BE_CONTACT && !h->ids[x->id])) {
        int ra = admit(h, x->a), rb = admit(h, x->b);
        h->refused += !ra && !rb; /* neither may ring: no room under the limit */
    }
    if (x->kind == BE_IMPACT) {
        surf_impact_data d = {x->d[0], x->d[1], x->d[2]};
        if (surf_impact(w, 0, x->a, x->b, &d) != WDRT_OK)
            h->refused++;
        return;
    }
    if (x->kind == BE_ENABLE) {
        surf_body_enable(w, x->a, x->id);
        return;
    }
    surf_contact *id = &h->ids[x->id];
    if (x->kind == BE_STOP) {
        if (*id)
            surf_contact_stop(w, *id);
        *id = 0;
        return;
    }
    surf_contact_data d = {x->d[0], x->d[1], x->d[2], x->d[3]};
    if (*id && surf_contact_update(w, *id, &d) == WDRT_OK)
        return;
    if (surf_contact_start(w, x->a, x->b, &d, id) != WDRT_OK) {
        *id = 0;
        h->refused++;
    }
}

static void excite(void *user, uint64_t t0, int nb, unsigned char *wake) {
    wdrt_bodies *h = user;
    uint32_t tail = __atomic_load_n(&h->tail, __ATOMIC_ACQUIRE);
    int done = 0;
    while (done < nb) {
        while (h->head != tail && h->q[h->head & h->qmask].frame <= t0 + (uint64_t)done) {
            apply(h, &h->q[h->head & h->qmask]);
            __atomic_store_n(&h->head, h->head + 1, __ATOMIC_RELEASE);
        }
        int upto = nb;
        if (h->head != tail && h->q[h->head & h->qmask].frame < t0 + (uint64_t)nb)
            upto = (int)(h->q[h->head & h->qmask].frame - t0);
        int m = surf_process(h->w, NULL, upto - done);
        for (int j = 0; j < h->nact; j++) { /* the others are asleep, their rows zero */
            int r = h->act[j];
            const double *y = surf_output(h->w, r, 0), *dy = h->vc[r].process ? NULL : surf_output(h->w, r, SURF_DIRECT);
            double *o = h->out + (size_t)r * BLOCK + done;
            if (!y && !dy) { /* silent: a row already zero stays so (most resonators sleep) */
                if (!h->clean[r] || done) {
                    memset(o, 0, sizeof(double) * (size_t)m);
                    h->clean[r] = done == 0 && m == BLOCK ? 1 : 0;
                }
                continue;
            }
            h->clean[r] = 0;
            for (int i = 0; i < m; i++)
                o[i] = y ? h->gain[r] * y[i] : 0;
            if (dy) /* Figure 4's direct path: the excitation heard unresonated */
                for (int i = 0; i < m; i++)
                    o[i] += h->gain[r] * dy[i];
            if ((y && h->vc[r].process) || dy) /* a voice the world excites, or a direct sound, wakes */
                wake[h->pool0 + r] = 1;
        }
        if (m <= 0)
            break;
        done += m;
    }
    for (int j = 0; j < h->nact; j++) {
        int r = h->act[j];
        h->cursor[r] = 0;
        if (surf_resonator_awake(h->w, r))
            wake[h->pool0 + r] = 1;
        else if (h->clean[r]) { /* asleep and silent: no longer visited until excited */
            h->inact[r] = 0;
            h->act[j--] = h->act[--h->nact];
        }
    }
}

void wdrt_bodies_attach(wdrt_bodies *h, wdrt_engine_config *c) {
    if (!h || !c)
        return;
    c->excite = excite;
    c->excite_user = h;
}

/* ---- the physics thread ---- */

static wdrt_result post(wdrt_bodies *h, const bev *x) {
    uint32_t head = __atomic_load_n(&h->head, __ATOMIC_ACQUIRE);
    if (h->tail - head > h->qmask)
        return WDRT_QUEUE_FULL;
    h->q[h->tail & h->qmask] = *x;
    __atomic_store_n(&h->tail, h->tail + 1, __ATOMIC_RELEASE);
    return WDRT_OK;
}

static int pair_ok(const wdrt_bodies *h, int a, int b) {
    return a >= 0 && b >= 0 && a < h->nbodies && b < h->nbodies && a != b;
}

wdrt_result wdrt_bodies_impact(wdrt_bodies *h, uint64_t frame, int a, int b, double J, double vn, double vt) {
    if (!h || !pair_ok(h, a, b) || !(J >= 0 && J < 1e9) || !isfinite(vn) || !isfinite(vt))
        return WDRT_INVALID_ARGS;
    bev x = {frame, BE_IMPACT, a, b, 0, {J, vn, vt, 0}};
    return post(h, &x);
}

wdrt_result wdrt_bodies_contact(wdrt_bodies *h, uint64_t frame, int id, int a, int b, double v_a, double v_b,
                                double slip, double force) {
    if (!h || !pair_ok(h, a, b) || id < 0 || id >= h->cfg.contacts || !isfinite(v_a) || !isfinite(v_b) ||
        !isfinite(slip) || !(force >= 0 && force < 1e12))
        return WDRT_INVALID_ARGS;
    bev x = {frame, BE_CONTACT, a, b, id, {fabs(v_a), fabs(v_b), fabs(slip), force}};
    return post(h, &x);
}

wdrt_result wdrt_bodies_contact_stop(wdrt_bodies *h, uint64_t frame, int id) {
    if (!h || id < 0 || id >= h->cfg.contacts)
        return WDRT_INVALID_ARGS;
    bev x = {frame, BE_STOP, 0, 0, id, {0, 0, 0, 0}};
    return post(h, &x);
}

wdrt_result wdrt_bodies_enable(wdrt_bodies *h, uint64_t frame, int body, int on) {
    if (!h || body < 0 || body >= h->nbodies)
        return WDRT_INVALID_ARGS;
    bev x = {frame, BE_ENABLE, body, 0, on != 0, {0, 0, 0, 0}};
    return post(h, &x);
}

void wdrt_bodies_get_stats(const wdrt_bodies *h, wdrt_bodies_stats *s) {
    surf_stats st;
    surf_get_stats(h->w, &st);
    s->contacts = st.contacts_in_use, s->contacts_hwm = st.contacts_hwm;
    s->impacts = st.impacts_in_use, s->impacts_hwm = st.impacts_hwm;
    s->refused = h->refused;
    s->lowered = h->lowered;
    s->awake = st.resonators_awake, s->modes = st.modes;
}
