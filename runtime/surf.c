/*
 * surf.c - the world of bodies, surfaces and modal resonators: set-up,
 * the pools of contacts and impacts, their generators, and the block
 * process.  The model, units and real-time rules are in surf.h.
 */
#include "surf.h"

#include <assert.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#define PI 3.14159265358979323846
#define LN1000 6.90775527898213705205 /* a T60's decay, in nepers */
#define SQRT2 1.41421356237309504880
#define FLUSH 1e-30                   /* states below this become 0 */
#define CUTOFF_MIN 1.0                /* Hz */
#define CUTOFF_MAX 0.45               /* of fs */
#define MAX_COUNT 65535               /* bodies, resonators, surfaces, modes */
#define MAX_RELIEF (1L << 30)         /* segment samples in a world */
#define NOISE_SPAN ((int64_t)1 << 40) /* noise reliefs repeat after this many grains */
#define MAX_STEP 1e6                  /* points a needle may pass in one sample */

/* A generator: the needle on one surface's relief and its low-pass (a
 * trapezoidal state-variable filter, Simper's form). */
typedef struct gen {
    int64_t idx;      /* the relief point the needle has passed */
    double frac;      /* [0, 1): how far on towards the next */
    int64_t cached;   /* noise: the point v0 is for (v1: the next) */
    double v0, v1;
    double s1, s2;    /* filter states */
    double fc;        /* cutoff the coefficients are for (0: none yet) */
    double a1, a2, a3;/* filter coefficients */
    double f;         /* contacts: force at the end of the last block, N */
} gen;

typedef struct contact {
    int used;
    int stopping;            /* stopped: fades out in the next block */
    uint16_t serial;         /* the id's generation */
    int body[2];             /* a, b */
    surf_contact_data d;     /* speeds as magnitudes */
    gen g[2];                /* a's surface's generator, b's */
} contact;

typedef struct skid {
    double f0;  /* N: force at its start (skid_gain skid_ratio J) */
    double len; /* samples: T fs (0: none) */
    double v;   /* m/s: slip at its start, |vt| */
} skid;

typedef struct impact {
    int used;
    int body[2];
    int64_t start; /* frame of the pulse's first sample */
    double T;      /* pulse length, samples (0: one sample) */
    double J;      /* N s */
    int64_t end;   /* samples after start when pulse and skids are over */
    skid sk[2];
    gen g[2];
} impact;

typedef struct resonator {
    int nmodes, nactive, npick;
    double quiet, max_damp;
    double damp;      /* D applied now, 1/s */
    double damp_next; /* accumulated for the coming block */
    int awake, fading;
    int external;     /* rings outside the world: its output is its input force */
    long fpos;        /* samples of the fade done */
    int has_input;    /* in[] holds this block's input */
    int live;         /* the pickups hold this block's output */
    int direct_live;  /* the direct channel holds this block's sound */
    double *sig, *cw, *sw;  /* per mode: s_k (1/s), cos w_k, sin w_k */
    double *cr, *ci;        /* c_k */
    double *yr, *yi;        /* y_k */
    double *wk;             /* sum_p g_kp^2 */
    double *g;              /* g[k * max_pickups + p] */
    double *in;             /* [block] force, N (then impulse, N s) */
    double *out;            /* [(max_pickups + 1) * block]: pickups, then direct */
} resonator;

typedef struct surface {
    surf_surface_desc d; /* d.relief.samples points into the world */
    uint64_t seed;       /* of its noise and start points */
} surface;

typedef struct body {
    int res, surf;
    double mass;
    int enabled;
} body;

struct surf_world {
    surf_config cfg;
    double inv_fs;
    int64_t now;       /* frame of the next block's first sample */
    int nres, nsurf, nbody;
    resonator *res;
    surface *surf;
    body *body;
    contact *con;
    int *con_free, ncon_free, con_hwm;
    impact *imp;
    int *imp_free, nimp_free, imp_hwm;
    double *relief;    /* segment samples */
    long relief_used;
    double *e, *r, *p, *f; /* [block] scratch: excitation, skid, pulse, force */
    int last_gens, last_awake, last_modes;
};

/* ---- layout ---- */

typedef struct layout {
    size_t res, surf, body, con, con_free, imp, imp_free;
    size_t modes, gains, in, out, relief, scratch, size;
} layout;

static size_t align16(size_t n) { return (n + 15) & ~(size_t)15; }

static int count_ok(int n, int max) { return n >= 0 && n <= max; }

static int config_ok(const surf_config *c) {
    return c && c->fs >= SURF_FS_MIN && c->fs <= SURF_FS_MAX && c->block >= 1 && c->block <= SURF_MAX_BLOCK &&
           count_ok(c->max_bodies, MAX_COUNT) && count_ok(c->max_resonators, MAX_COUNT) &&
           count_ok(c->max_surfaces, MAX_COUNT) && count_ok(c->max_modes, MAX_COUNT) && c->max_pickups >= 1 &&
           c->max_pickups <= SURF_MAX_PICKUPS && count_ok(c->max_contacts, SURF_MAX_POOL) &&
           count_ok(c->max_impacts, SURF_MAX_POOL) && c->relief_frames >= 0 && c->relief_frames <= MAX_RELIEF &&
           isfinite(c->quiet_force) && c->quiet_force >= 0 && isfinite(c->quiet_speed) && c->quiet_speed >= 0;
}

/* Where each array of a world goes (get_size and init share it).  Sizes
 * are summed in double first, so an overflow is seen. */
static wdrt_result get_layout(const surf_config *c, layout *L) {
    if (!config_ok(c))
        return WDRT_INVALID_ARGS;
    double nr = c->max_resonators, nm = c->max_modes, blk = c->block;
    double per_res = sizeof(resonator) + nm * 8 * 8 + nm * c->max_pickups * 8 + blk * 8 * (c->max_pickups + 2);
    double total = sizeof(struct surf_world) + nr * per_res + c->max_surfaces * (double)sizeof(surface) +
                   c->max_bodies * (double)sizeof(body) + c->max_contacts * (double)(sizeof(contact) + 4) +
                   c->max_impacts * (double)(sizeof(impact) + 4) + c->relief_frames * 8.0 + 4 * blk * 8 + 16 * 16;
    if (total > (double)SIZE_MAX / 2)
        return WDRT_OUT_OF_MEMORY;
    size_t off = align16(sizeof(struct surf_world)), R = (size_t)c->max_resonators, M = (size_t)c->max_modes;
#define TAKE(field, bytes) (L->field = off, off = align16(off + (bytes)))
    TAKE(res, R * sizeof(resonator));
    TAKE(surf, (size_t)c->max_surfaces * sizeof(surface));
    TAKE(body, (size_t)c->max_bodies * sizeof(body));
    TAKE(con, (size_t)c->max_contacts * sizeof(contact));
    TAKE(con_free, (size_t)c->max_contacts * sizeof(int));
    TAKE(imp, (size_t)c->max_impacts * sizeof(impact));
    TAKE(imp_free, (size_t)c->max_impacts * sizeof(int));
    TAKE(modes, R * M * 8 * sizeof(double));
    TAKE(gains, R * M * (size_t)c->max_pickups * sizeof(double));
    TAKE(in, R * (size_t)c->block * sizeof(double));
    TAKE(out, R * (size_t)c->block * (size_t)(c->max_pickups + 1) * sizeof(double));
    TAKE(relief, (size_t)c->relief_frames * sizeof(double));
    TAKE(scratch, 4 * (size_t)c->block * sizeof(double));
#undef TAKE
    L->size = off;
    return WDRT_OK;
}

surf_config surf_config_init(double fs) {
    surf_config c;
    memset(&c, 0, sizeof c);
    c.fs = fs;
    c.block = 256;
    c.max_bodies = 64;
    c.max_resonators = 64;
    c.max_surfaces = 16;
    c.max_modes = 32;
    c.max_pickups = 2;
    c.max_contacts = 32;
    c.max_impacts = 64;
    c.quiet_force = 1e-6;
    c.quiet_speed = 1e-5;
    c.seed = 1;
    return c;
}

wdrt_result surf_get_size(const surf_config *cfg, size_t *size) {
    layout L;
    if (!size)
        return WDRT_INVALID_ARGS;
    wdrt_result r = get_layout(cfg, &L);
    if (r == WDRT_OK)
        *size = L.size;
    return r;
}

/* Points each resonator at its arrays. */
static void carve_resonators(surf_world *w, char *base, const layout *L) {
    const surf_config *c = &w->cfg;
    size_t M = (size_t)c->max_modes, B = (size_t)c->block;
    double *modes = (double *)(base + L->modes), *gains = (double *)(base + L->gains);
    double *in = (double *)(base + L->in), *out = (double *)(base + L->out);
    for (int i = 0; i < c->max_resonators; i++) {
        resonator *r = &w->res[i];
        double *m = modes + (size_t)i * M * 8;
        r->sig = m, r->cw = m + M, r->sw = m + 2 * M, r->cr = m + 3 * M, r->ci = m + 4 * M;
        r->yr = m + 5 * M, r->yi = m + 6 * M, r->wk = m + 7 * M;
        r->g = gains + (size_t)i * M * (size_t)c->max_pickups;
        r->in = in + (size_t)i * B;
        r->out = out + (size_t)i * B * (size_t)(c->max_pickups + 1);
    }
}

wdrt_result surf_init_prealloc(const surf_config *cfg, void *mem, surf_world **wp) {
    layout L;
    if (!mem || ((uintptr_t)mem & 15) || !wp || get_layout(cfg, &L) != WDRT_OK)
        return WDRT_INVALID_ARGS;
    memset(mem, 0, L.size);
    char *base = mem;
    surf_world *w = mem;
    w->cfg = *cfg;
    w->inv_fs = 1 / cfg->fs;
    w->res = (resonator *)(base + L.res);
    w->surf = (surface *)(base + L.surf);
    w->body = (body *)(base + L.body);
    w->con = (contact *)(base + L.con);
    w->con_free = (int *)(base + L.con_free);
    w->imp = (impact *)(base + L.imp);
    w->imp_free = (int *)(base + L.imp_free);
    w->relief = (double *)(base + L.relief);
    w->e = (double *)(base + L.scratch);
    w->r = w->e + cfg->block;
    w->p = w->r + cfg->block;
    w->f = w->p + cfg->block;
    carve_resonators(w, base, &L);
    surf_reset(w);
    *wp = w;
    return WDRT_OK;
}

wdrt_result surf_init(const surf_config *cfg, const wdrt_alloc_callbacks *alloc, surf_world **wp) {
    size_t size;
    wdrt_result r = surf_get_size(cfg, &size);
    if (r != WDRT_OK || !wp)
        return r != WDRT_OK ? r : WDRT_INVALID_ARGS;
    void *mem = alloc && alloc->alloc ? alloc->alloc(size, alloc->user) : malloc(size);
    if (!mem)
        return WDRT_OUT_OF_MEMORY;
    r = surf_init_prealloc(cfg, mem, wp);
    if (r != WDRT_OK) {
        if (alloc && alloc->free)
            alloc->free(mem, alloc->user);
        else
            free(mem);
    }
    return r;
}

void surf_uninit(surf_world *w, const wdrt_alloc_callbacks *alloc) {
    if (!w)
        return;
    if (alloc && alloc->free)
        alloc->free(w, alloc->user);
    else
        free(w);
}

/* ---- resonators ---- */

/* c_k from s_k and the damping D: r = exp(-(s_k + D) / fs). */
static void set_coefs(const surf_world *w, resonator *r) {
    for (int k = 0; k < r->nmodes; k++) {
        double rad = exp(-(r->sig[k] + r->damp) * w->inv_fs);
        r->cr[k] = rad * r->cw[k];
        r->ci[k] = rad * r->sw[k];
    }
}

static void silence_resonator(const surf_world *w, resonator *r) {
    memset(r->yr, 0, (size_t)w->cfg.max_modes * sizeof(double));
    memset(r->yi, 0, (size_t)w->cfg.max_modes * sizeof(double));
    r->awake = r->fading = 0;
    r->fpos = 0;
    r->has_input = r->live = r->direct_live = 0;
}

void surf_reset(surf_world *w) {
    const surf_config *c = &w->cfg;
    for (int i = 0; i < w->nres; i++) {
        silence_resonator(w, &w->res[i]);
        w->res[i].damp = w->res[i].damp_next = 0;
        set_coefs(w, &w->res[i]);
    }
    memset(w->con, 0, (size_t)c->max_contacts * sizeof(contact));
    memset(w->imp, 0, (size_t)c->max_impacts * sizeof(impact));
    /* free stacks: slot 0 is taken first */
    for (int i = 0; i < c->max_contacts; i++)
        w->con_free[i] = c->max_contacts - 1 - i;
    for (int i = 0; i < c->max_impacts; i++)
        w->imp_free[i] = c->max_impacts - 1 - i;
    w->ncon_free = c->max_contacts;
    w->nimp_free = c->max_impacts;
    w->con_hwm = w->imp_hwm = 0;
    w->now = 0;
    w->last_gens = w->last_awake = w->last_modes = 0;
}

surf_resonator_desc surf_resonator_desc_init(void) {
    surf_resonator_desc d;
    memset(&d, 0, sizeof d);
    d.npickups = 1;
    d.quiet = 1e-6;
    d.max_damping = 100;
    return d;
}

static int mode_ok(const surf_mode *m, int np) {
    if (!(isfinite(m->f) && m->f > 0 && isfinite(m->t60) && m->t60 > 0))
        return 0;
    for (int p = 0; p < np; p++)
        if (!isfinite(m->gain[p]))
            return 0;
    return 1;
}

static double loudness(const surf_mode *m, int np) {
    double g2 = 0;
    for (int p = 0; p < np; p++)
        g2 += m->gain[p] * m->gain[p];
    return g2 * m->t60;
}

/* Copies mode slot j to slot j + 1 (all arrays but the state). */
static void move_mode(resonator *r, size_t np, int j) {
    r->cr[j + 1] = r->cr[j];
    r->sig[j + 1] = r->sig[j];
    r->cw[j + 1] = r->cw[j];
    r->sw[j + 1] = r->sw[j];
    r->wk[j + 1] = r->wk[j];
    memcpy(r->g + (size_t)(j + 1) * np, r->g + (size_t)j * np, np * sizeof *r->g);
}

/* Puts mode m in slot j of r. */
static void put_mode(const surf_world *w, resonator *r, int j, const surf_mode *m, int npick) {
    size_t np = (size_t)w->cfg.max_pickups;
    r->sig[j] = LN1000 / m->t60;
    r->cw[j] = cos(2 * PI * m->f * w->inv_fs);
    r->sw[j] = sin(2 * PI * m->f * w->inv_fs);
    r->wk[j] = 0;
    memset(r->g + (size_t)j * np, 0, np * sizeof *r->g);
    for (int p = 0; p < npick; p++) {
        r->g[(size_t)j * np + (size_t)p] = m->gain[p];
        r->wk[j] += m->gain[p] * m->gain[p];
    }
}

/* Loads the modes below fs/2 into r, loudest first (a stable insertion
 * sort; cr holds the loudness until set_coefs). */
static void load_modes(const surf_world *w, resonator *r, const surf_resonator_desc *d) {
    int n = 0;
    for (int k = 0; k < d->nmodes; k++) {
        const surf_mode *m = &d->modes[k];
        if (m->f >= 0.5 * w->cfg.fs)
            continue;
        double l = loudness(m, d->npickups);
        int j = n++;
        for (; j > 0 && r->cr[j - 1] < l; j--)
            move_mode(r, (size_t)w->cfg.max_pickups, j - 1);
        put_mode(w, r, j, m, d->npickups);
        r->cr[j] = l;
    }
    r->nmodes = r->nactive = n;
}

int surf_add_resonator(surf_world *w, const surf_resonator_desc *d) {
    const surf_config *c = &w->cfg;
    if (!d || d->nmodes < 0 || d->nmodes > c->max_modes || (d->nmodes && !d->modes) || d->npickups < 1 ||
        d->npickups > c->max_pickups || !(d->quiet >= 0 && isfinite(d->quiet)) ||
        !(d->max_damping >= 0 && isfinite(d->max_damping)))
        return WDRT_INVALID_ARGS;
    for (int k = 0; k < d->nmodes; k++)
        if (!mode_ok(&d->modes[k], d->npickups))
            return WDRT_INVALID_ARGS;
    if (w->nres == c->max_resonators)
        return SURF_POOL_FULL;
    resonator *r = &w->res[w->nres];
    load_modes(w, r, d);
    r->npick = d->npickups;
    r->quiet = d->quiet;
    r->max_damp = d->max_damping;
    silence_resonator(w, r);
    r->damp = r->damp_next = 0;
    set_coefs(w, r);
    return w->nres++;
}

static resonator *get_res(const surf_world *w, int i) { return w && i >= 0 && i < w->nres ? &w->res[i] : NULL; }

int surf_add_external(surf_world *w) {
    surf_resonator_desc d = surf_resonator_desc_init();
    d.quiet = 0;
    int i = surf_add_resonator(w, &d);
    if (i >= 0)
        w->res[i].external = 1;
    return i;
}

wdrt_result surf_resonator_set_active_modes(surf_world *w, int res, int n) {
    resonator *r = get_res(w, res);
    if (!r)
        return WDRT_INVALID_ARGS;
    n = n < 0 ? 0 : n > r->nmodes ? r->nmodes : n;
    for (int k = n; k < r->nactive; k++)
        r->yr[k] = r->yi[k] = 0;
    r->nactive = n;
    return WDRT_OK;
}

wdrt_result surf_resonator_set_quiet(surf_world *w, int res, double quiet) {
    resonator *r = get_res(w, res);
    if (!r || !(quiet >= 0 && isfinite(quiet)))
        return WDRT_INVALID_ARGS;
    r->quiet = quiet;
    return WDRT_OK;
}

wdrt_result surf_resonator_set_max_damping(surf_world *w, int res, double d) {
    resonator *r = get_res(w, res);
    if (!r || !(d >= 0 && isfinite(d)))
        return WDRT_INVALID_ARGS;
    r->max_damp = d;
    return WDRT_OK;
}

wdrt_result surf_resonator_make_quiet(surf_world *w, int res) {
    resonator *r = get_res(w, res);
    if (!r)
        return WDRT_INVALID_ARGS;
    if (r->awake && !r->fading)
        r->fading = 1, r->fpos = 0;
    return WDRT_OK;
}

static double mode_energy(const resonator *r) {
    double e = 0;
    for (int k = 0; k < r->nactive; k++)
        e += r->wk[k] * (r->yr[k] * r->yr[k] + r->yi[k] * r->yi[k]);
    return sqrt(e);
}

int surf_resonator_awake(const surf_world *w, int res) {
    const resonator *r = get_res(w, res);
    return r ? r->awake : WDRT_INVALID_ARGS;
}

double surf_resonator_energy(const surf_world *w, int res) {
    const resonator *r = get_res(w, res);
    return r ? mode_energy(r) : NAN;
}

double surf_resonator_damping(const surf_world *w, int res) {
    const resonator *r = get_res(w, res);
    return r ? r->damp : NAN;
}

int surf_resonator_modes(const surf_world *w, int res) {
    const resonator *r = get_res(w, res);
    return r ? r->nmodes : WDRT_INVALID_ARGS;
}

/* ---- surfaces and bodies ---- */

surf_surface_desc surf_surface_desc_init(void) {
    surf_surface_desc d;
    memset(&d, 0, sizeof d);
    d.hardness = 1e7;
    surf_gains g = {1, 0, 0, INFINITY};
    d.contact = d.impact = g;
    d.relief.kind = SURF_RELIEF_NOISE;
    d.relief.scale = 1e-4;
    d.relief.width = 1e-4;
    d.relief.amp = 1;
    d.cutoff_roll = 200;
    d.cutoff_slip = 4000;
    d.slip_ref = 1;
    d.skid_gain = 1;
    d.skid_ratio = 100;
    d.skid_decel = 20;
    d.skid_thickness = 1e-3;
    d.skid_max = 0.2;
    return d;
}

static int fin(double x) { return isfinite(x); }
static int nonneg(double x) { return isfinite(x) && x >= 0; }
static int pos(double x) { return isfinite(x) && x > 0; }

static int gains_ok(const surf_gains *g) {
    return fin(g->master) && fin(g->other) && fin(g->direct) && g->limit > 0; /* limit may be INFINITY */
}

static int relief_ok(const surf_relief *r) {
    switch (r->kind) {
    case SURF_RELIEF_NONE:
        return 1;
    case SURF_RELIEF_NOISE:
        return pos(r->scale) && fin(r->amp);
    case SURF_RELIEF_GRID:
        return pos(r->scale) && fin(r->amp) && pos(r->width) && r->width <= r->scale;
    case SURF_RELIEF_SEGMENT:
        return pos(r->scale) && fin(r->amp) && r->samples && r->nsamples >= 2;
    }
    return 0;
}

static int surface_ok(const surf_surface_desc *d) {
    return d && d->hardness > 0 && !isnan(d->hardness) && nonneg(d->damping) && gains_ok(&d->contact) &&
           gains_ok(&d->impact) && relief_ok(&d->relief) && pos(d->cutoff_roll) && pos(d->cutoff_slip) &&
           pos(d->slip_ref) && fin(d->skid_gain) && nonneg(d->skid_ratio) && nonneg(d->skid_decel) &&
           nonneg(d->skid_thickness) && nonneg(d->skid_min) && fin(d->skid_max) && d->skid_max >= d->skid_min;
}

/* splitmix64's finaliser: a well-mixed 64-bit hash. */
static uint64_t mix64(uint64_t x) {
    x += 0x9e3779b97f4a7c15ull;
    x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
    x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
    return x ^ (x >> 31);
}

/* Copies a segment into the world's relief memory, its mean removed. */
static int copy_segment(surf_world *w, surf_relief *r) {
    if (r->nsamples > w->cfg.relief_frames - w->relief_used)
        return SURF_POOL_FULL;
    double *dst = w->relief + w->relief_used, mean = 0;
    for (long i = 0; i < r->nsamples; i++) {
        if (!isfinite(r->samples[i]))
            return WDRT_INVALID_ARGS;
        mean += r->samples[i];
    }
    mean /= (double)r->nsamples;
    for (long i = 0; i < r->nsamples; i++)
        dst[i] = r->samples[i] - mean;
    w->relief_used += r->nsamples;
    r->samples = dst;
    return WDRT_OK;
}

int surf_add_surface(surf_world *w, const surf_surface_desc *d) {
    if (!w || !surface_ok(d))
        return WDRT_INVALID_ARGS;
    if (w->nsurf == w->cfg.max_surfaces)
        return SURF_POOL_FULL;
    surface *s = &w->surf[w->nsurf];
    s->d = *d;
    if (d->relief.kind == SURF_RELIEF_SEGMENT) {
        int r = copy_segment(w, &s->d.relief);
        if (r != WDRT_OK)
            return r;
    }
    s->seed = mix64(w->cfg.seed ^ mix64((uint64_t)w->nsurf + 0x51ull));
    return w->nsurf++;
}

int surf_add_body(surf_world *w, const surf_body_desc *d) {
    if (!w || !d || d->resonator < 0 || d->resonator >= w->nres || d->surface < 0 || d->surface >= w->nsurf ||
        !(d->mass > 0))
        return WDRT_INVALID_ARGS;
    if (w->nbody == w->cfg.max_bodies)
        return SURF_POOL_FULL;
    body *b = &w->body[w->nbody];
    b->res = d->resonator;
    b->surf = d->surface;
    b->mass = d->mass;
    b->enabled = 1;
    return w->nbody++;
}

static int body_ok(const surf_world *w, int b) { return w && b >= 0 && b < w->nbody; }

wdrt_result surf_body_enable(surf_world *w, int b, int on) {
    if (!body_ok(w, b))
        return WDRT_INVALID_ARGS;
    w->body[b].enabled = on != 0;
    return WDRT_OK;
}

/* ---- the laws ---- */

double surf_pulse_width(const surf_world *w, int a, int b) {
    if (!body_ok(w, a) || !body_ok(w, b))
        return NAN;
    const body *A = &w->body[a], *B = &w->body[b];
    double k = 1 / (1 / w->surf[A->surf].d.hardness + 1 / w->surf[B->surf].d.hardness);
    double m = 1 / (1 / A->mass + 1 / B->mass);
    if (isinf(m))
        return NAN; /* two immovable bodies cannot collide */
    return isinf(k) ? 0 : PI * sqrt(m / k);
}

static double skid_time(const surf_surface_desc *s, const surf_impact_data *d) {
    double vt = fabs(d->vt), vn = fabs(d->vn), t = INFINITY;
    if (vt == 0)
        return 0;
    if (s->skid_decel > 0)
        t = vt / s->skid_decel;
    if (s->skid_thickness > 0 && vn > 0)
        t = fmin(t, 2 * s->skid_thickness / vn);
    return fmin(fmax(t, s->skid_min), s->skid_max);
}

double surf_skid_time(const surf_world *w, int s, const surf_impact_data *d) {
    if (!w || s < 0 || s >= w->nsurf || !d)
        return NAN;
    return skid_time(&w->surf[s].d, d);
}

static double cutoff(const surf_world *w, const surf_surface_desc *s, double slip) {
    double fc = s->cutoff_roll + (s->cutoff_slip - s->cutoff_roll) * fabs(slip) / s->slip_ref;
    return fmin(fmax(fc, CUTOFF_MIN), CUTOFF_MAX * w->cfg.fs);
}

double surf_contact_cutoff(const surf_world *w, int s, double slip) {
    if (!w || s < 0 || s >= w->nsurf || !isfinite(slip))
        return NAN;
    return cutoff(w, &w->surf[s].d, slip);
}

/* ---- generators ---- */

/* A generator on surface s, started for a contact or impact with body
 * `other` at frame `frame`: its needle at a hashed point of the relief. */
static void gen_start(const surf_world *w, gen *g, int s, int other, int64_t frame) {
    const surf_relief *r = &w->surf[s].d.relief;
    uint64_t h = mix64(w->surf[s].seed ^ mix64((uint64_t)frame ^ ((uint64_t)other << 48)));
    memset(g, 0, sizeof *g);
    g->cached = INT64_MIN;
    if (r->kind == SURF_RELIEF_NOISE)
        g->idx = (int64_t)(h % (uint64_t)NOISE_SPAN);
    else if (r->kind == SURF_RELIEF_SEGMENT)
        g->idx = (int64_t)(h % (uint64_t)r->nsamples);
}

/* The noise relief's value at point i (periodic in NOISE_SPAN), uniform
 * in [-1, 1). */
static double noise_at(uint64_t seed, int64_t i) {
    return (double)(mix64(seed ^ (uint64_t)(i & (NOISE_SPAN - 1))) >> 11) * (2.0 / 9007199254740992.0) - 1;
}

/* Moves the needle on by `step` points (at most MAX_STEP: absurd speeds
 * cannot overflow the index). */
static void needle_advance(gen *g, double step) {
    g->frac += fmin(step, MAX_STEP);
    if (g->frac >= 1) {
        double whole = floor(g->frac);
        g->idx += (int64_t)whole;
        g->frac -= whole;
    }
}

/* The relief under the needle for m samples, the needle moving at
 * v0 + dv j m/s (clipped at 0) in sample j: Menzies' gramophone needle. */
static void relief_read(const surf_world *w, gen *g, const surface *s, double v0, double dv, double *out, int m) {
    const surf_relief *r = &s->d.relief;
    double k = w->inv_fs / r->scale; /* points per sample per m/s */
    switch (r->kind) {
    case SURF_RELIEF_NONE:
        memset(out, 0, (size_t)m * sizeof *out);
        return;
    case SURF_RELIEF_NOISE:
        for (int j = 0; j < m; j++) {
            if (g->idx != g->cached) {
                g->v0 = g->idx == g->cached + 1 ? g->v1 : noise_at(s->seed, g->idx);
                g->v1 = noise_at(s->seed, g->idx + 1);
                g->cached = g->idx;
            }
            out[j] = r->amp * (g->v0 + (g->v1 - g->v0) * g->frac);
            needle_advance(g, fmax(v0 + dv * j, 0) * k);
            g->idx &= NOISE_SPAN - 1;
        }
        return;
    case SURF_RELIEF_GRID: {
        double wfrac = r->width / r->scale, mean = 0.5 * wfrac;
        for (int j = 0; j < m; j++) {
            double bump = g->frac < wfrac ? 0.5 - 0.5 * cos(2 * PI * g->frac / wfrac) : 0;
            out[j] = r->amp * (bump - mean);
            needle_advance(g, fmax(v0 + dv * j, 0) * k);
            g->idx = 0; /* only the phase within a cell matters */
        }
        return;
    }
    case SURF_RELIEF_SEGMENT: {
        const double *x = r->samples;
        long n = r->nsamples;
        for (int j = 0; j < m; j++) {
            long i = (long)g->idx, i1 = i + 1 == n ? 0 : i + 1;
            out[j] = r->amp * (x[i] + (x[i1] - x[i]) * g->frac);
            needle_advance(g, fmax(v0 + dv * j, 0) * k);
            if (g->idx >= n)
                g->idx %= n;
        }
        return;
    }
    }
}

/* The two-pole Butterworth low-pass at fc, in place over x[0..m):
 * Simper's trapezoidal SVF, k = sqrt 2 (Q = 1/sqrt 2), g prewarped. */
static void lowpass(const surf_world *w, gen *g, double fc, double *x, int m) {
    if (fc != g->fc) {
        double t = tan(PI * fc * w->inv_fs);
        g->a1 = 1 / (1 + t * (t + SQRT2));
        g->a2 = t * g->a1;
        g->a3 = t * g->a2;
        g->fc = fc;
    }
    double s1 = g->s1, s2 = g->s2, a1 = g->a1, a2 = g->a2, a3 = g->a3;
    for (int j = 0; j < m; j++) {
        double v3 = x[j] - s2, v1 = a1 * s1 + a2 * v3, v2 = s2 + a2 * s1 + a3 * v3;
        s1 = 2 * v1 - s1;
        s2 = 2 * v2 - s2;
        x[j] = v2;
    }
    g->s1 = fabs(s1) < FLUSH ? 0 : s1;
    g->s2 = fabs(s2) < FLUSH ? 0 : s2;
}

/* One generator over out[0..m): the relief read at v0 + dv j, low-passed
 * at fc, times force[j] (N). */
static void gen_run(const surf_world *w, gen *g, const surface *s, double fc, double v0, double dv,
                    const double *force, double *out, int m) {
    relief_read(w, g, s, v0, dv, out, m);
    lowpass(w, g, fc, out, m);
    for (int j = 0; j < m; j++)
        out[j] *= force[j];
}

/* ---- routing (Menzies' Figure 4) ---- */

static void add_into(double *dst, int *live, const double *e, double gain, int j0, int n) {
    if (!*live) {
        memset(dst, 0, (size_t)n * sizeof *dst);
        *live = 1;
    }
    for (int j = j0; j < n; j++)
        dst[j] += gain * e[j];
}

/* Sends surface excitation e[j0..n) of body bi (touching bj) on: master,
 * limit, then its own resonator, the other's, and the direct channel. */
static void route(surf_world *w, int bi, int bj, const surf_gains *gn, double *e, int j0, int n) {
    resonator *own = &w->res[w->body[bi].res];
    double lim = gn->limit;
    for (int j = j0; j < n; j++) {
        double v = gn->master * e[j];
        e[j] = v > lim ? lim : v < -lim ? -lim : v;
    }
    add_into(own->in, &own->has_input, e, 1, j0, n);
    if (gn->other != 0 && w->body[bj].enabled) {
        resonator *o = &w->res[w->body[bj].res];
        add_into(o->in, &o->has_input, e, gn->other, j0, n);
    }
    if (gn->direct != 0)
        add_into(own->out + (size_t)w->cfg.max_pickups * w->cfg.block, &own->direct_live, e, gn->direct, j0, n);
}

/* ---- contacts ---- */

static int data_ok(const surf_contact_data *d) {
    return d && fin(d->v_a) && fin(d->v_b) && fin(d->slip) && nonneg(d->force);
}

static contact *find_contact(surf_world *w, surf_contact id) {
    long s = (long)(id & 0xffff) - 1;
    if (!w || s < 0 || s >= w->cfg.max_contacts)
        return NULL;
    contact *c = &w->con[s];
    return c->used && !c->stopping && c->serial == (uint16_t)(id >> 16) ? c : NULL;
}

static void set_data(contact *c, const surf_contact_data *d) {
    c->d.v_a = fabs(d->v_a);
    c->d.v_b = fabs(d->v_b);
    c->d.slip = fabs(d->slip);
    c->d.force = d->force;
}

static void free_contact(surf_world *w, contact *c) {
    c->used = 0;
    w->con_free[w->ncon_free++] = (int)(c - w->con);
}

wdrt_result surf_contact_start(surf_world *w, int a, int b, const surf_contact_data *d, surf_contact *id) {
    if (!body_ok(w, a) || !body_ok(w, b) || a == b || !data_ok(d) || !id)
        return WDRT_INVALID_ARGS;
    if (w->ncon_free == 0)
        return SURF_POOL_FULL;
    int s = w->con_free[--w->ncon_free];
    contact *c = &w->con[s];
    uint16_t serial = (uint16_t)(c->serial + 1);
    memset(c, 0, sizeof *c);
    c->used = 1;
    c->serial = serial;
    c->body[0] = a;
    c->body[1] = b;
    set_data(c, d);
    gen_start(w, &c->g[0], w->body[a].surf, b, w->now);
    gen_start(w, &c->g[1], w->body[b].surf, a, w->now);
    int in_use = w->cfg.max_contacts - w->ncon_free;
    w->con_hwm = in_use > w->con_hwm ? in_use : w->con_hwm;
    *id = (uint32_t)serial << 16 | (uint32_t)(s + 1);
    return WDRT_OK;
}

wdrt_result surf_contact_update(surf_world *w, surf_contact id, const surf_contact_data *d) {
    contact *c = find_contact(w, id);
    if (!c || !data_ok(d))
        return WDRT_INVALID_ARGS;
    set_data(c, d);
    return WDRT_OK;
}

wdrt_result surf_contact_stop(surf_world *w, surf_contact id) {
    contact *c = find_contact(w, id);
    if (!c)
        return WDRT_INVALID_ARGS;
    if (c->g[0].f == 0 && c->g[1].f == 0)
        free_contact(w, c); /* silent: nothing to fade */
    else
        c->stopping = 1;
    return WDRT_OK;
}

/* The force side i of contact c aims at in this block: 0 when stopping,
 * disabled or quiet. */
static double contact_target(const surf_world *w, const contact *c, int i) {
    double v = i ? c->d.v_b : c->d.v_a;
    if (c->stopping || !w->body[c->body[i]].enabled || c->d.force < w->cfg.quiet_force || c->d.force == 0 ||
        v < w->cfg.quiet_speed)
        return 0;
    return c->d.force;
}

static int run_contact(surf_world *w, contact *c, int n) {
    int gens = 0;
    for (int i = 0; i < 2; i++) {
        gen *g = &c->g[i];
        double target = contact_target(w, c, i);
        if (g->f == 0 && target == 0) {
            g->s1 = g->s2 = 0; /* quiet: costs nothing, restarts clean */
            continue;
        }
        const surface *s = &w->surf[w->body[c->body[i]].surf];
        double v = i ? c->d.v_b : c->d.v_a, f = g->f, step = target - f;
        for (int j = 0; j < n; j++)
            w->f[j] = f + step * (j + 1) / n; /* exactly the target at the end */
        gen_run(w, g, s, cutoff(w, &s->d, c->d.slip), v, 0, w->f, w->e, n);
        g->f = target;
        route(w, c->body[i], c->body[1 - i], &s->d.contact, w->e, 0, n);
        gens++;
    }
    if (c->stopping)
        free_contact(w, c);
    return gens;
}

/* ---- impacts ---- */

static int impact_data_ok(const surf_impact_data *d) {
    return d && nonneg(d->impulse) && fin(d->vn) && fin(d->vt);
}

wdrt_result surf_impact(surf_world *w, long offset, int a, int b, const surf_impact_data *d) {
    if (!body_ok(w, a) || !body_ok(w, b) || a == b || !impact_data_ok(d) || offset < 0)
        return WDRT_INVALID_ARGS;
    double tau = surf_pulse_width(w, a, b);
    if (isnan(tau))
        return WDRT_INVALID_ARGS;
    if (d->impulse == 0)
        return WDRT_OK;
    if (w->nimp_free == 0)
        return SURF_POOL_FULL;
    impact *m = &w->imp[w->imp_free[--w->nimp_free]];
    memset(m, 0, sizeof *m);
    m->used = 1;
    m->body[0] = a;
    m->body[1] = b;
    m->start = w->now + offset;
    m->T = tau * w->cfg.fs;
    m->J = d->impulse;
    m->end = m->T > 0 ? (int64_t)ceil(m->T) : 1;
    for (int i = 0; i < 2; i++) {
        int s = w->body[m->body[i]].surf;
        const surf_surface_desc *sd = &w->surf[s].d;
        m->sk[i].len = skid_time(sd, d) * w->cfg.fs;
        m->sk[i].f0 = sd->skid_gain * sd->skid_ratio * d->impulse;
        m->sk[i].v = fabs(d->vt);
        gen_start(w, &m->g[i], s, m->body[1 - i], m->start);
        int64_t e = (int64_t)ceil(m->sk[i].len);
        m->end = e > m->end ? e : m->end;
    }
    int in_use = w->cfg.max_impacts - w->nimp_free;
    w->imp_hwm = in_use > w->imp_hwm ? in_use : w->imp_hwm;
    return WDRT_OK;
}

/* The half-sine pulse's samples p0 .. p0+m-1 into out: each the mean force
 * over its sample, J fs/2 (cos(pi p/T) - cos(pi (p+1)/T)), which sum to
 * exactly J fs. */
static void pulse_fill(const surf_world *w, const impact *im, int64_t p0, double *out, int m) {
    double c = 0.5 * im->J * w->cfg.fs;
    for (int j = 0; j < m; j++) {
        int64_t p = p0 + j;
        if (im->T <= 0) {
            out[j] = p == 0 ? im->J * w->cfg.fs : 0;
            continue;
        }
        double a = fmin((double)p / im->T, 1), b = fmin((double)(p + 1) / im->T, 1);
        out[j] = a >= 1 ? 0 : c * (cos(PI * a) - cos(PI * b));
    }
}

/* Side i's skid over samples p0 .. p0+m-1 of the impact, added to e: force
 * and slip fall linearly from f0 and v to 0 over len samples (the force
 * f0 (len - p) / len, zero from p = len on exactly). */
static void skid_add(surf_world *w, impact *im, int i, int64_t p0, double *e, int m) {
    const skid *k = &im->sk[i];
    const surface *s = &w->surf[w->body[im->body[i]].surf];
    double left = 1 - (double)p0 / k->len, mid = 1 - (p0 + 0.5 * m) / k->len;
    double fc = cutoff(w, &s->d, k->v * fmax(mid, 0));
    for (int j = 0; j < m; j++)
        w->f[j] = k->f0 * fmax(k->len - (double)(p0 + j), 0) / k->len;
    gen_run(w, &im->g[i], s, fc, k->v * left, -k->v / k->len, w->f, w->r, m);
    for (int j = 0; j < m; j++)
        e[j] += w->r[j];
}

static int run_impact(surf_world *w, impact *im, int n) {
    int64_t rel = im->start - w->now;
    if (rel >= n)
        return 0; /* not yet */
    int j0 = rel > 0 ? (int)rel : 0, m = n - j0, gens = 0;
    int64_t p0 = w->now + j0 - im->start;
    int pulse = p0 < (im->T > 0 ? (int64_t)ceil(im->T) : 1);
    if (pulse)
        pulse_fill(w, im, p0, w->p + j0, m);
    for (int i = 0; i < 2; i++) {
        int sliding = p0 < ceil(im->sk[i].len);
        if (!w->body[im->body[i]].enabled || !(pulse || sliding))
            continue;
        double *e = w->e;
        if (pulse)
            memcpy(e + j0, w->p + j0, (size_t)m * sizeof *e);
        else
            memset(e + j0, 0, (size_t)m * sizeof *e);
        if (sliding)
            skid_add(w, im, i, p0, e + j0, m);
        route(w, im->body[i], im->body[1 - i], &w->surf[w->body[im->body[i]].surf].d.impact, e, j0, n);
        gens++;
    }
    if (p0 + m >= im->end) {
        im->used = 0;
        w->imp_free[w->nimp_free++] = (int)(im - w->imp);
    }
    return gens;
}

/* ---- the block ---- */

/* Each resonator's damping for the coming block: the damping of every
 * surface touching one of its bodies in a live contact, up to its cap. */
static void apply_damping(surf_world *w) {
    for (int i = 0; i < w->nres; i++)
        w->res[i].damp_next = 0;
    for (int s = 0; s < w->cfg.max_contacts; s++) {
        const contact *c = &w->con[s];
        if (!c->used || c->stopping)
            continue;
        const body *A = &w->body[c->body[0]], *B = &w->body[c->body[1]];
        if (!A->enabled || !B->enabled)
            continue;
        w->res[A->res].damp_next += w->surf[B->surf].d.damping;
        w->res[B->res].damp_next += w->surf[A->surf].d.damping;
    }
    for (int i = 0; i < w->nres; i++) {
        resonator *r = &w->res[i];
        double d = r->damp_next < r->max_damp ? r->damp_next : r->max_damp; /* no call: every resonator, every block */
        if (d != r->damp) {
            r->damp = d;
            set_coefs(w, r);
        }
    }
}

/* Runs the active modes over n samples into the pickups. */
static void modes_run(const surf_world *w, resonator *r, int n) {
    size_t np = (size_t)w->cfg.max_pickups;
    double *in = r->in, *tmp = w->e;
    if (r->has_input)
        for (int j = 0; j < n; j++)
            in[j] *= w->inv_fs; /* force (N) to impulse per sample (N s) */
    for (int p = 0; p < r->npick; p++)
        memset(r->out + (size_t)p * w->cfg.block, 0, (size_t)n * sizeof(double));
    int k = 0;
    /* four modes abreast: their chains overlap in the processor; each
     * pickup still sums the modes in order, so the result is the same to
     * the bit as one mode at a time */
    for (; k + 4 <= r->nactive; k += 4) {
        double cr[4], ci[4], yr[4], yi[4], t4[4][64];
        for (int q = 0; q < 4; q++)
            cr[q] = r->cr[k + q], ci[q] = r->ci[k + q], yr[q] = r->yr[k + q], yi[q] = r->yi[k + q];
        for (int j0 = 0; j0 < n; j0 += 64) {
            int m = n - j0 < 64 ? n - j0 : 64;
            for (int j = 0; j < m; j++) {
                double x = r->has_input ? in[j0 + j] : 0;
                for (int q = 0; q < 4; q++) {
                    double t = cr[q] * yr[q] - ci[q] * yi[q] + x;
                    yi[q] = cr[q] * yi[q] + ci[q] * yr[q];
                    yr[q] = t;
                    t4[q][j] = yi[q];
                }
            }
            for (int p = 0; p < r->npick; p++) {
                double *out = r->out + (size_t)p * w->cfg.block + j0;
                const double *g = &r->g[(size_t)k * np + (size_t)p];
                for (int j = 0; j < m; j++) {
                    out[j] += g[0] * t4[0][j];
                    out[j] += g[np] * t4[1][j];
                    out[j] += g[2 * np] * t4[2][j];
                    out[j] += g[3 * np] * t4[3][j];
                }
            }
        }
        for (int q = 0; q < 4; q++) {
            if (yr[q] * yr[q] + yi[q] * yi[q] < FLUSH * FLUSH)
                yr[q] = yi[q] = 0;
            r->yr[k + q] = yr[q];
            r->yi[k + q] = yi[q];
        }
    }
    for (; k < r->nactive; k++) {
        double cr = r->cr[k], ci = r->ci[k], yr = r->yr[k], yi = r->yi[k];
        if (r->has_input)
            for (int j = 0; j < n; j++) {
                double t = cr * yr - ci * yi + in[j];
                yi = cr * yi + ci * yr;
                yr = t;
                tmp[j] = yi;
            }
        else
            for (int j = 0; j < n; j++) {
                double t = cr * yr - ci * yi;
                yi = cr * yi + ci * yr;
                yr = t;
                tmp[j] = yi;
            }
        for (int p = 0; p < r->npick; p++) {
            double g = r->g[k * np + (size_t)p], *out = r->out + (size_t)p * w->cfg.block;
            for (int j = 0; j < n; j++)
                out[j] += g * tmp[j];
        }
        if (yr * yr + yi * yi < FLUSH * FLUSH)
            yr = yi = 0;
        r->yr[k] = yr;
        r->yi[k] = yi;
    }
}

/* The fade before sleep: gain 1 - (fpos + 1) / block, sample by sample,
 * across calls; at its end the resonator sleeps. */
static void fade(const surf_world *w, resonator *r, int n) {
    double B = w->cfg.block;
    for (int j = 0; j < n; j++, r->fpos++) {
        double g = fmax(1 - (r->fpos + 1) / B, 0);
        for (int p = 0; p < r->npick; p++)
            r->out[(size_t)p * w->cfg.block + (size_t)j] *= g;
    }
    if (r->fpos >= w->cfg.block) {
        int live = r->live, direct = r->direct_live;
        silence_resonator(w, r);
        r->live = live, r->direct_live = direct;
    }
}

/* One resonator's block: wake on input, ring, then the sleep logic. */
static void run_resonator(surf_world *w, resonator *r, int n) {
    r->live = 0;
    if (r->external) { /* the force, for a resonator outside the world to ring with */
        if (r->has_input)
            memcpy(r->out, r->in, (size_t)n * sizeof *r->out);
        r->live = r->has_input;
        r->awake = 0;
        return;
    }
    if (r->has_input)
        r->awake = 1;
    if (!r->awake)
        return;
    modes_run(w, r, n);
    r->live = 1;
    w->last_awake++;
    w->last_modes += r->nactive;
    if (r->has_input)
        r->fading = 0;
    else if (r->fading)
        fade(w, r, n);
    else if (mode_energy(r) < r->quiet)
        r->fading = 1, r->fpos = 0;
}

static void mix_out(const surf_world *w, double *mix, int n) {
    memset(mix, 0, (size_t)n * sizeof *mix);
    for (int i = 0; i < w->nres; i++) {
        const resonator *r = &w->res[i];
        for (int ch = 0; ch <= w->cfg.max_pickups; ch++) {
            int direct = ch == w->cfg.max_pickups;
            if (direct ? !r->direct_live : !(r->live && ch < r->npick))
                continue;
            const double *x = r->out + (size_t)ch * w->cfg.block;
            for (int j = 0; j < n; j++)
                mix[j] += x[j];
        }
    }
}

int surf_process(surf_world *w, double *mix, int nframes) {
    int n = nframes < w->cfg.block ? nframes : w->cfg.block;
    if (n <= 0)
        return 0;
    for (int i = 0; i < w->nres; i++)
        w->res[i].has_input = w->res[i].direct_live = 0;
    apply_damping(w);
    int gens = 0;
    for (int s = 0; s < w->cfg.max_contacts; s++)
        if (w->con[s].used)
            gens += run_contact(w, &w->con[s], n);
    for (int s = 0; s < w->cfg.max_impacts; s++)
        if (w->imp[s].used)
            gens += run_impact(w, &w->imp[s], n);
    w->last_gens = gens;
    w->last_awake = w->last_modes = 0;
    for (int i = 0; i < w->nres; i++)
        run_resonator(w, &w->res[i], n);
    if (mix)
        mix_out(w, mix, n);
    w->now += n;
    return n;
}

const double *surf_output(const surf_world *w, int res, int ch) {
    const resonator *r = get_res(w, res);
    if (!r)
        return NULL;
    if (ch == SURF_DIRECT)
        return r->direct_live ? r->out + (size_t)w->cfg.max_pickups * w->cfg.block : NULL;
    return ch >= 0 && ch < r->npick && r->live ? r->out + (size_t)ch * w->cfg.block : NULL;
}

void surf_get_stats(const surf_world *w, surf_stats *s) {
    s->contacts_in_use = w->cfg.max_contacts - w->ncon_free;
    s->contacts_hwm = w->con_hwm;
    s->impacts_in_use = w->cfg.max_impacts - w->nimp_free;
    s->impacts_hwm = w->imp_hwm;
    s->generators = w->last_gens;
    s->resonators_awake = w->last_awake;
    s->modes = w->last_modes;
    s->cost = w->last_modes + SURF_GEN_COST * w->last_gens;
}

int64_t surf_frame(const surf_world *w) { return w->now; }
