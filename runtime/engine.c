/*
 * engine.c - the voice host: pools of voice instances, sample-accurate
 * events through a lock-free queue, sleep and wake, and a cost budget.
 *
 * Implements the engine part of runtime/wdrt.h.  Time is cut on a fixed
 * grid of `block` frames counted from frame 0, whatever lengths the host
 * asks for, so a render does not depend on how it was cut into process
 * calls; a process call that ends inside a grid block renders part of it.
 * Within a grid block each voice renders in segments between the frames at
 * which its events (and param-ramp steps) act.
 *
 * Phases of a (sub-)block: take events from the queue into a heap ordered
 * by (frame, post order); resolve those due in this block, in order,
 * onto per-voice and per-pool chains (plays take instances here);
 * render each awake voice along its chains and mix it; at the end of a
 * grid block, put quiet voices to sleep and keep the cost within budget.
 */
#include "wdrt.h"

#include <assert.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "hrtf.h"
#include "room.h"
#include "space.h"

#define MAX_BLOCK 4096
#define RAMP_STEPS 16  /* a param ramp sets the voice this many times at most */
#define GRACE_BLOCKS 4 /* a new note sounds this many blocks before it can be stolen */
#define SEQ_BITS 22
#define SEQ_MASK ((1u << SEQ_BITS) - 1)
#define MAX_POOLS 1000
#define LANES 8        /* instances of one pool rendered by one process_batch call at most */

enum { EV_STRIKE, EV_SET, EV_GAIN, EV_PLAY, EV_STOP, EV_MOVE, EV_LISTEN, EV_DESIGN };
#define AIR_TABLE 256 /* distances the air filter is tabulated at */
#define LISTEN_MAX 16 /* listener moves one block takes in order */
#define IMAGE_ORDER 3 /* the highest image order the engine renders */
#define MAX_IMAGES 62 /* images up to IMAGE_ORDER */
enum { M_FREE, M_AWAKE, M_ASLEEP, M_VIRTUAL };
enum { A_NONE, A_SLEEP, A_FREE, A_VIRTUAL, A_RESET };

typedef struct ev {
    uint64_t frame;  /* absolute frame it acts at */
    uint64_t seq;    /* post order */
    int type;        /* EV_* */
    int n;           /* EV_STRIKE: pairs; EV_SET: param; EV_PLAY: priority; EV_DESIGN: slot */
    int pool;        /* EV_PLAY */
    int off;         /* offset in the block being rendered */
    int next;        /* next event of the same chain, or -1 */
    wdrt_voice v;    /* target (EV_PLAY: the new note) */
    double value;    /* EV_SET, EV_GAIN: the value; EV_PLAY: gain */
    int ids[WDRT_STRIKE_MAX];
    double vals[WDRT_STRIKE_MAX];
} ev;

/* A linear ramp: v moves by step for `left` more frames, ending at `to`. */
typedef struct ramp {
    double v, to, step;
    int left;
    int hold; /* frames it stays at v before it moves */
} ramp;

/* A param on its way to `to`: set at frames next, next + every, ... */
typedef struct pramp {
    double from, to;
    int done, steps, every;
    uint64_t next;
} pramp;

typedef struct inst {
    unsigned char *st; /* the voice's state */
    pramp *pr;         /* one per param */
    const double **in; /* bound inputs, per input (standing voices) */
    int pool;
    int mode;          /* M_* */
    int spare;         /* carries fade-outs of stolen notes only */
    int after;         /* A_*: what the end of a fade-out does */
    int act;           /* index in the active list, or -1 */
    int start;         /* offset in this block it renders from */
    uint64_t born;     /* the frame its note was played at */
    int chain, tail;   /* its events in this block */
    int age;           /* grid blocks since it started sounding */
    int priority;
    int nramps;        /* params ramping */
    int hasin;         /* some input is bound */
    wdrt_voice note;   /* the handle it answers to; 0 when free */
    double note_gain;  /* play gain, times which the pool's gain applies */
    ramp gain, fade;
    double peak;       /* largest |output| heard in this grid block */
    double level;      /* audibility: peaks held with a 50 ms release */
    double last;       /* level one grid block ago */
    double eref;       /* energy after its last strike (or init) */
    double equiet;     /* energy when its output fell quiet */
    int quiet;         /* grid blocks its output has been quiet */
    double vest, vdec; /* virtual: estimated level and its decay per block */
    double pos[3];     /* placed: where it is, m */
    ramp path[3];      /* placed: its motion toward the last move */
    int slot;          /* placed: its delay line, or -1 */
    double sgain;      /* placed: the gain of its way to the listener */
} inst;

/* A delay line of the spatial layer: what a placed voice sounded, and
 * where it was at each grid block, read by the listener at the retarded
 * time.  It outlives its voice until the last sound fed has arrived. */
typedef struct slot {
    int inst;             /* the voice feeding it, or -1 while it drains */
    int owner;            /* the voice that fed it last */
    int busy;
    uint64_t moved;       /* the last block its position changed in */
    double *buf;          /* samples, at buf[frame & mask] */
    double (*hist)[3];    /* position at each grid block start, at hist[block & hmask] */
    uint64_t start;       /* the first frame fed (earlier: silence) */
    uint64_t fed;         /* frames before this are in buf */
    uint64_t hlast;       /* the last block whose position is recorded */
    double tau;           /* s: the retarded delay last heard at */
    double gain;          /* distance gain last heard with */
    double occ, occ_to;   /* occlusion: how much of the muffled path is heard */
    double occ_gain;      /* and its loss */
    double lp;            /* state of the muffling low-pass */
    double air[SPACE_AIR_POLES];
    hrtf_src *ear;        /* binaural: its filters and history */
    struct tap *taps;     /* its image sources (MAX_IMAGES) */
    int ntaps;            /* in use in the last block */
    double tail;          /* s: the longest of their delays */
    int room;             /* the room it was in, or -1 */
} slot;

/* One image source of a slot: a tap read at its own delay, through its
 * walls' filter, with its distance gain and direction. */
typedef struct tap {
    double delay, gain, gl, gr; /* s, and gains, at the last block's end */
    double b0, b1, a1, x1, y1;  /* the wall filter and its state */
    double wg, whf;             /* the reflection it was made for */
} tap;

/* A room of the scene: its geometry and its reverb. */
typedef struct room {
    room_config cfg;
    room_fdn *fdn;
    double *in;           /* what the sources in it sounded this block */
    double heard, heard_to; /* its reverb's gain at the listener */
    int fed;              /* some source fed it this block */
    int asleep;           /* unfed and rung down: not computed */
} room;

typedef struct pool {
    wdrt_pool_config cfg;
    int first, nspare;     /* voices at [first, first + cfg.voices), then spares */
    unsigned char *tmpl;   /* a state as init left it */
    double *param;         /* values notes start from */
    double gain;           /* the pool's gain, ramped into every voice */
    double cl, cr;         /* its constant-power pan: left and right gains */
    double cost;           /* ns per sample of one voice */
    uint32_t next_seq;     /* producer: the next note's sequence number */
    double *pparam;        /* producer: the pool's params as posted */
    unsigned char *design; /* the design of its latest prepared params (design_size bytes) */
    int has_design;
    int chain, tail;       /* pool-wide events in this block */
} pool;

struct wdrt_engine {
    double fs;
    int nch, B, npools, ninst;
    pool *pools;
    inst *inst;
    /* the queue: the producer writes head, the consumer tail */
    ev *q;
    uint32_t qmask, qhead, qtail;
    uint64_t seq;          /* producer: post order */
    /* designs prepared by wdrt_engine_set_prepared: WDRT_DESIGN_SLOTS of
     * dsize bytes, each held (dbusy, atomic) from its post by the
     * producer to the end of the block that applies it */
    unsigned char *dslot;
    size_t dsize;
    unsigned char dbusy[WDRT_DESIGN_SLOTS];
    int dnext;             /* producer: the slot to try first */
    ev *heap;
    int nheap, cap;
    ev *blk;               /* this block's events, chained */
    int nblk;
    int *active, nactive;
    int *virt, nvirt;
    int *inputs, ninputs;  /* standing voices with bound inputs */
    int *touched, ntouched; /* pools with events chained in this block */
    unsigned char *pwake;   /* pools the excitations phase woke this block */
    void (*excite)(void *user, uint64_t frame, int nframes, unsigned char *wake);
    void *excite_user;
    /* space */
    wdrt_space_config sp;
    slot *slots;
    int nslots;
    uint64_t dmask;        /* delay line length - 1 */
    uint64_t hmask;        /* position history length - 1 */
    double lis[3], face[3];
    ramp lpath[3];
    ev lmoves[LISTEN_MAX];
    int nlmoves;
    double *lpos;          /* the listener's position at each frame of the block */
    double *sig;           /* a slot's arriving signal in the block */
    const hrtf *ears;      /* binaural output, or NULL */
    room *rooms;
    int nrooms;
    double *rout;          /* a room's reverb in the block, left then right */
    double *earbuf;        /* left and right ear of the block */
    double air_p[AIR_TABLE];
    int air_n[AIR_TABLE];
    double *mix;           /* B * nch */
    double *obuf, *zero;   /* lanes of maxout * B outputs (LANES when a pool has process_batch, else one); B zeros */
    double **optr;         /* lanes of maxout + 1 */
    const double **iptr;   /* lanes of maxin + 1 */
    int maxout, maxin;
    uint64_t time;         /* frames rendered (atomic) */
    double budget, rel;
    int sleep;
    int from_alloc;
    void *base;            /* what init's allocation returned */
    wdrt_engine_stats s;
};

/* ---- memory layout ---- */

typedef struct layout {
    size_t slots, dbufs, hists, walls, lpos, sig, ears, earbuf, hsize, taps, rooms, fdns, rin, rout;
    size_t fdnsize[64];
    int ntaps;             /* images per slot: 0 when no room reflects */
    uint64_t dlen, hlen;
    size_t dsize;          /* bytes of a design slot */
    size_t designs, pdesigns, pparams;
    size_t engine, pools, inst, params, pramps, inptrs, states, q, heap, blk, active, virt, inputs, touched, pwake, mix,
        obuf, zero, optr, iptr, total;
    int ninst, nparams, nin, maxout, maxin, qcap;
    int lanes;             /* LANES if a pool's class has process_batch, else 1 */
} layout;

static size_t up(size_t x, size_t a) { return (x + a - 1) / a * a; }

static uint32_t pow2(int n) {
    uint32_t p = 1;
    while ((int)p < n)
        p <<= 1;
    return p;
}

static int pool_spares(const wdrt_pool_config *p) { return p->owned ? 0 : p->spares; }

static room_config room_cfg(const wdrt_room *r, const wdrt_engine_config *c) {
    room_config rc;
    memcpy(rc.box, r->box, sizeof rc.box);
    rc.t60_low = r->t60_low;
    rc.t60_high = r->t60_high;
    rc.order = r->order;
    rc.c = c->space.c;
    rc.fs = c->rate;
    return rc;
}

/* One place computes where everything lives, for get_size and init. */
static void get_layout(const wdrt_engine_config *c, layout *L) {
    memset(L, 0, sizeof *L);
    size_t states = 0;
    for (int i = 0; i < c->npools; i++) {
        const wdrt_pool_config *p = &c->pools[i];
        int n = p->voices + pool_spares(p);
        L->ninst += n;
        states += up(p->cls->state_size, 64) * (size_t)(n + 1); /* its instances and its template */
        L->nparams += n * p->cls->n_params + p->cls->n_params;
        if (p->owned)
            L->nin += n * p->cls->n_inputs;
        if (p->cls->prepare && up(p->cls->design_size, 64) > L->dsize)
            L->dsize = up(p->cls->design_size, 64);
        if (p->cls->n_outputs > L->maxout)
            L->maxout = p->cls->n_outputs;
        if (p->cls->n_inputs > L->maxin)
            L->maxin = p->cls->n_inputs;
        if (p->cls->process_batch)
            L->lanes = LANES;
    }
    if (!L->lanes)
        L->lanes = 1;
    L->qcap = (int)pow2(c->queue);
    size_t o = 0;
#define PLACE(field, bytes, align) (o = up(o, align), L->field = o, o += (bytes))
    PLACE(engine, sizeof(wdrt_engine), 64);
    PLACE(pools, sizeof(pool) * (size_t)c->npools, 16);
    PLACE(inst, sizeof(inst) * (size_t)L->ninst, 16);
    PLACE(params, sizeof(double) * (size_t)L->nparams, 16);
    PLACE(pramps, sizeof(pramp) * (size_t)L->nparams, 16);
    size_t pd = 0, pp = 0;
    for (int i = 0; i < c->npools; i++) {
        pd += c->pools[i].cls->prepare ? up(c->pools[i].cls->design_size, 64) : 0;
        pp += (size_t)c->pools[i].cls->n_params;
    }
    PLACE(designs, L->dsize * WDRT_DESIGN_SLOTS, 64);
    PLACE(pdesigns, pd, 64);
    PLACE(pparams, sizeof(double) * pp, 16);
    PLACE(inptrs, sizeof(double *) * (size_t)L->nin, 16);
    PLACE(states, states, 64);
    PLACE(q, sizeof(ev) * (size_t)L->qcap, 16);
    PLACE(heap, sizeof(ev) * (size_t)c->pending, 16);
    PLACE(blk, sizeof(ev) * (size_t)c->pending, 16);
    PLACE(active, sizeof(int) * (size_t)L->ninst, 16);
    PLACE(virt, sizeof(int) * (size_t)L->ninst, 16);
    PLACE(inputs, sizeof(int) * (size_t)L->ninst, 16);
    PLACE(touched, sizeof(int) * (size_t)(c->npools + 1), 16);
    PLACE(pwake, (size_t)(c->npools + 1), 16);
    PLACE(mix, sizeof(double) * (size_t)c->block * (size_t)c->channels, 64);
    PLACE(obuf, sizeof(double) * (size_t)L->lanes * (size_t)c->block * (size_t)(L->maxout ? L->maxout : 1), 64);
    PLACE(zero, sizeof(double) * (size_t)c->block, 64);
    PLACE(optr, sizeof(double *) * (size_t)L->lanes * (size_t)(L->maxout + 1), 16);
    PLACE(iptr, sizeof(double *) * (size_t)L->lanes * (size_t)(L->maxin + 1), 16);
    int ns = c->space.sources;
    if (ns > 0) {
        double md = c->space.max_delay > 0 ? c->space.max_delay : fmin(c->space.max / c->space.c, 3.0);
        L->dlen = pow2((int)(md * c->rate) + 2 * c->block + 8);
        L->hlen = pow2((int)(L->dlen / (uint64_t)c->block) + 4);
    }
    PLACE(slots, sizeof(slot) * (size_t)ns, 16);
    PLACE(dbufs, sizeof(double) * (size_t)L->dlen * (size_t)ns, 64);
    PLACE(hists, sizeof(double) * 3 * (size_t)L->hlen * (size_t)ns, 16);
    PLACE(walls, sizeof(wdrt_wall) * (size_t)c->space.nwalls, 16);
    PLACE(lpos, sizeof(double) * 3 * (size_t)c->block, 16);
    PLACE(sig, sizeof(double) * (size_t)c->block, 16);
    const hrtf *h = (const hrtf *)c->space.hrtf;
    L->hsize = h && ns > 0 ? up(hrtf_src_size(h), 64) : 0;
    PLACE(ears, L->hsize * (size_t)ns, 64);
    PLACE(earbuf, sizeof(double) * 2 * (size_t)c->block, 16);
    int nr = c->space.nrooms, order = 0;
    for (int i = 0; i < nr; i++)
        order = c->space.rooms[i].order > order ? c->space.rooms[i].order : order;
    L->ntaps = order > 0 ? MAX_IMAGES : 0;
    PLACE(taps, sizeof(tap) * (size_t)L->ntaps * (size_t)ns, 16);
    PLACE(rooms, sizeof(room) * (size_t)nr, 16);
    size_t fdns = 0;
    for (int i = 0; i < nr; i++) {
        room_config rc = room_cfg(&c->space.rooms[i], c);
        L->fdnsize[i] = up(room_fdn_size(&rc), 64);
        fdns += L->fdnsize[i];
    }
    PLACE(fdns, fdns, 64);
    PLACE(rin, sizeof(double) * (size_t)c->block * (size_t)nr, 16);
    PLACE(rout, sizeof(double) * 2 * (size_t)c->block, 16);
#undef PLACE
    L->total = o;
}

/* ---- configs ---- */

wdrt_pool_config wdrt_pool_config_init(const wdv_class *cls, int voices) {
    wdrt_pool_config p;
    memset(&p, 0, sizeof p);
    p.cls = cls;
    p.voices = voices;
    p.gain = 1;
    p.quiet = 1e-5;
    p.floor_db = -60;
    p.hold = 0.1;
    p.spares = 2;
    return p;
}

wdrt_engine_config wdrt_engine_config_init(double rate, int channels, int npools, const wdrt_pool_config *pools) {
    wdrt_engine_config c;
    memset(&c, 0, sizeof c);
    c.rate = rate;
    c.channels = channels;
    c.block = 64;
    c.queue = 4096;
    c.pending = 4096;
    c.sleep = 1;
    c.npools = npools;
    c.pools = pools;
    c.space.c = 343;
    c.space.distance = WDRT_DISTANCE_INVERSE;
    c.space.ref = 1;
    c.space.max = 1000;
    c.space.rolloff = 1;
    c.space.air = 1;
    c.space.facing[1] = 1;
    return c;
}

static wdrt_result check_config(const wdrt_engine_config *c) {
    if (!c || !(c->rate >= 1 && c->rate <= 1e7) || (c->channels != 1 && c->channels != 2) || c->block < 1 ||
        c->block > MAX_BLOCK || c->queue < 1 || c->queue > (1 << 24) || c->pending < 1 || c->pending > (1 << 24) ||
        !(c->budget_ns >= 0) || c->npools < 0 || c->npools > MAX_POOLS || (c->npools && !c->pools))
        return WDRT_INVALID_ARGS;
    const wdrt_space_config *sp = &c->space;
    if (sp->sources < 0 || sp->sources > 4096 ||
        (sp->sources > 0 &&
         (!(sp->c >= 1 && sp->c <= 1e5) || !(sp->ref > 0) || !(sp->max > sp->ref && sp->max <= 1e6) ||
          !(sp->rolloff >= 0 && sp->rolloff <= 100) || !(sp->max_delay >= 0 && sp->max_delay <= 30) ||
          sp->distance < WDRT_DISTANCE_NONE || sp->distance > WDRT_DISTANCE_EXPONENT || sp->nwalls < 0 ||
          sp->nwalls > 4096 || (sp->nwalls && !sp->walls) ||
          !isfinite(sp->listener[0] + sp->listener[1] + sp->listener[2]) ||
          !(fabs(sp->facing[0]) + fabs(sp->facing[1]) > 0) || (sp->hrtf && c->channels != 2) || sp->nrooms < 0 ||
          sp->nrooms > 64 || (sp->nrooms && !sp->rooms))))
        return WDRT_INVALID_ARGS;
    for (int i = 0; sp->sources > 0 && i < sp->nrooms; i++) {
        const wdrt_room *r = &sp->rooms[i];
        room_config rc = room_cfg(r, c);
        if (r->order < 0 || r->order > IMAGE_ORDER || room_fdn_size(&rc) == 0)
            return WDRT_INVALID_ARGS;
    }
    for (int i = 0; i < c->npools; i++) {
        const wdrt_pool_config *p = &c->pools[i];
        if (p->placed && (sp->sources <= 0 || !isfinite(p->pos[0] + p->pos[1] + p->pos[2])))
            return WDRT_INVALID_ARGS;
        if (p->ambient && (p->placed || sp->sources <= 0 || p->ambient < 0 || p->ambient > sp->nrooms))
            return WDRT_INVALID_ARGS;
        if (!p->cls || p->cls->abi_version != WDV_ABI_VERSION || p->voices < 1 || p->voices > (int)(SEQ_MASK / 2) ||
            p->spares < 0 || p->spares > 64 || p->output < 0 || p->output >= p->cls->n_outputs ||
            !isfinite(p->gain) || !(p->pan >= -1 && p->pan <= 1) || !(p->cost_ns >= 0) || !(p->quiet >= 0) ||
            !isfinite(p->floor_db) || !(p->hold >= 0 && p->hold <= 3600) || p->cls->n_params > 64 || p->cls->n_inputs > 64 || p->cls->n_outputs > 64)
            return WDRT_INVALID_ARGS;
    }
    return WDRT_OK;
}

wdrt_result wdrt_engine_get_size(const wdrt_engine_config *cfg, size_t *size) {
    if (!size || check_config(cfg) != WDRT_OK)
        return WDRT_INVALID_ARGS;
    layout L;
    get_layout(cfg, &L);
    *size = L.total + 64;
    return WDRT_OK;
}

/* ---- set-up ---- */

static double now_ns(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec * 1e9 + ts.tv_nsec;
}

/* ns per sample of one voice of cls: the best of three runs of 4096
 * frames from the state init leaves, in the engine's block length. */
/* Points the scratch ports at silence in and the block buffers out, for a
 * voice of cls run outside the mix (cost measurement, settling). */
static void scratch_ports(wdrt_engine *e, const wdv_class *cls) {
    for (int k = 0; k < cls->n_outputs; k++)
        e->optr[k] = e->obuf + (size_t)k * (size_t)e->B;
    for (int k = 0; k < cls->n_inputs; k++)
        e->iptr[k] = e->zero;
}

static double measure_cost(wdrt_engine *e, const wdrt_pool_config *pc, void *st) {
    const wdv_class *cls = pc->cls;
    double best = 1e300;
    for (int rep = 0; rep < 3; rep++) {
        cls->init(st, e->fs);
        if (pc->bind)
            pc->bind(st, pc->data);
        scratch_ports(e, cls);
        int frames = 0;
        double t0 = now_ns();
        for (; frames < 4096; frames += e->B)
            cls->process(st, e->iptr, e->optr, e->B);
        double dt = (now_ns() - t0) / frames;
        if (dt < best)
            best = dt;
    }
    return best > 0.01 ? best : 0.01;
}

/* Brings a state's coefficients up to its params now (a process call of
 * no frames), so that instances copied from it do not each redesign on
 * the audio thread. */
static void settle(wdrt_engine *e, const wdv_class *cls, void *st) {
    scratch_ports(e, cls);
    cls->process(st, e->iptr, e->optr, 0);
}

static void init_pools(wdrt_engine *e, const wdrt_engine_config *c, unsigned char *m, const layout *L) {
    double *par = (double *)(m + L->params);
    pramp *pr = (pramp *)(m + L->pramps);
    const double **ip = (const double **)(m + L->inptrs);
    int k = 0;
    unsigned char *sm = m + L->states; /* each pool's template, then its instances */
    unsigned char *dm = m + L->pdesigns;
    double *pp = (double *)(m + L->pparams);
    e->dslot = m + L->designs;
    e->dsize = L->dsize;
    for (int i = 0; i < c->npools; i++) {
        pool *p = &e->pools[i];
        const wdv_class *cls = c->pools[i].cls;
        size_t stride = up(cls->state_size, 64);
        p->cfg = c->pools[i];
        p->first = k;
        p->nspare = pool_spares(&p->cfg);
        p->tmpl = sm;
        sm += stride;
        p->param = par;
        par += cls->n_params;
        p->gain = p->cfg.gain;
        p->cl = c->channels == 2 ? cos((p->cfg.pan + 1) * 0.7853981633974483) : 1;
        p->cr = c->channels == 2 ? sin((p->cfg.pan + 1) * 0.7853981633974483) : 0;
        p->next_seq = (uint32_t)p->cfg.voices + 1;
        p->chain = p->tail = -1;
        cls->init(p->tmpl, e->fs);
        if (p->cfg.bind)
            p->cfg.bind(p->tmpl, p->cfg.data);
        for (int j = 0; p->cfg.params && j < cls->n_params; j++)
            cls->set_param(p->tmpl, j, p->cfg.params[j]);
        p->cfg.params = NULL;
        settle(e, cls, p->tmpl);
        for (int j = 0; j < cls->n_params; j++)
            p->param[j] = cls->get_param(p->tmpl, j);
        p->pparam = pp;
        pp += cls->n_params;
        memcpy(p->pparam, p->param, sizeof(double) * (size_t)cls->n_params);
        if (cls->prepare) {
            p->design = dm;
            dm += up(cls->design_size, 64);
        }
        p->cost = p->cfg.cost_ns;
        for (int j = 0; j < i && p->cost <= 0; j++) /* a class is measured once */
            if (e->pools[j].cfg.cls == cls && e->pools[j].cfg.cost_ns <= 0)
                p->cost = e->pools[j].cost;
        if (p->cost <= 0)
            p->cost = measure_cost(e, &p->cfg, sm); /* its own first instance, set below */
        for (int j = 0; j < p->cfg.voices + p->nspare; j++, k++) {
            inst *v = &e->inst[k];
            memset(v, 0, sizeof *v);
            v->st = sm;
            sm += stride;
            memcpy(v->st, p->tmpl, cls->state_size);
            v->pr = pr;
            pr += cls->n_params;
            if (p->cfg.owned) {
                v->in = ip;
                ip += cls->n_inputs;
            }
            v->pool = i;
            v->spare = j >= p->cfg.voices;
            v->act = -1;
            v->chain = v->tail = -1;
            v->mode = M_FREE;
            v->fade.v = 1;
            v->gain.v = p->gain;
            v->note_gain = 1;
        }
    }
}

static void activate(wdrt_engine *e, int k) {
    inst *v = &e->inst[k];
    if (v->act < 0) {
        v->act = e->nactive;
        e->active[e->nactive++] = k;
    }
}

/* Standing voices start awake, from the state init left them in. */
static void start_owned(wdrt_engine *e) {
    for (int i = 0; i < e->npools; i++) {
        pool *p = &e->pools[i];
        if (!p->cfg.owned)
            continue;
        for (int j = 0; j < p->cfg.voices; j++) {
            inst *v = &e->inst[p->first + j];
            v->mode = M_AWAKE;
            v->note = ((uint32_t)(i + 1) << SEQ_BITS) | (uint32_t)(j + 1);
            v->priority = p->cfg.priority;
            v->eref = p->cfg.cls->energy(v->st);
            activate(e, p->first + j);
        }
    }
}

static void init_space(wdrt_engine *e, const wdrt_engine_config *c, unsigned char *m, const layout *L) {
    e->sp = c->space;
    e->nslots = c->space.sources;
    e->slots = (slot *)(m + L->slots);
    e->dmask = L->dlen ? L->dlen - 1 : 0;
    e->hmask = L->hlen ? L->hlen - 1 : 0;
    for (int i = 0; i < e->nslots; i++) {
        slot *q = &e->slots[i];
        q->buf = (double *)(m + L->dbufs) + (size_t)L->dlen * (size_t)i;
        q->hist = (double(*)[3])(m + L->hists) + (size_t)L->hlen * (size_t)i;
        q->inst = q->owner = -1;
    }
    wdrt_wall *w = (wdrt_wall *)(m + L->walls);
    if (c->space.nwalls)
        memcpy(w, c->space.walls, sizeof *w * (size_t)c->space.nwalls);
    e->sp.walls = w;
    e->lpos = (double *)(m + L->lpos);
    e->sig = (double *)(m + L->sig);
    e->ears = (const hrtf *)c->space.hrtf;
    e->earbuf = (double *)(m + L->earbuf);
    for (int i = 0; e->ears && i < e->nslots; i++)
        e->slots[i].ear = hrtf_src_init(e->ears, m + L->ears + L->hsize * (size_t)i);
    for (int i = 0; i < e->nslots; i++) {
        e->slots[i].taps = L->ntaps ? (tap *)(m + L->taps) + MAX_IMAGES * (size_t)i : NULL;
        e->slots[i].room = -1;
    }
    e->nrooms = c->space.sources > 0 ? c->space.nrooms : 0;
    e->rooms = (room *)(m + L->rooms);
    e->rout = (double *)(m + L->rout);
    unsigned char *fm = m + L->fdns;
    for (int i = 0; i < e->nrooms; i++) {
        room *r = &e->rooms[i];
        r->cfg = room_cfg(&c->space.rooms[i], c);
        r->fdn = room_fdn_init(&r->cfg, fm);
        fm += L->fdnsize[i];
        r->in = (double *)(m + L->rin) + (size_t)c->block * (size_t)i;
        r->heard = r->heard_to = room_contains(&r->cfg, c->space.listener) ? 1 : 0;
    }
    double f = hypot(c->space.facing[0], c->space.facing[1]);
    for (int k = 0; k < 3; k++) {
        e->lis[k] = e->lpath[k].v = e->lpath[k].to = c->space.listener[k];
        e->face[k] = k < 2 && f > 0 ? c->space.facing[k] / f : 0;
    }
    if (e->nslots > 0) /* air filters tabulated over the square root of distance */
        for (int j = 0; j < AIR_TABLE; j++) {
            double r = (double)j / (AIR_TABLE - 1);
            space_air_fit(c->space.max * r * r, c->rate, &e->air_n[j], &e->air_p[j]);
        }
    for (int i = 0; i < e->ninst; i++) {
        inst *v = &e->inst[i];
        const double *p0 = e->pools[v->pool].cfg.pos;
        v->slot = -1;
        v->sgain = 1;
        for (int k = 0; k < 3; k++)
            v->pos[k] = v->path[k].v = v->path[k].to = p0[k];
    }
}

wdrt_result wdrt_engine_init_prealloc(const wdrt_engine_config *cfg, void *mem, wdrt_engine **engine) {
    if (!mem || !engine || check_config(cfg) != WDRT_OK)
        return WDRT_INVALID_ARGS;
    layout L;
    get_layout(cfg, &L);
    unsigned char *m = (unsigned char *)up((size_t)mem, 64);
    memset(m, 0, L.total);
    wdrt_engine *e = (wdrt_engine *)(m + L.engine);
    e->fs = cfg->rate;
    e->nch = cfg->channels;
    e->B = cfg->block;
    e->npools = cfg->npools;
    e->ninst = L.ninst;
    e->pools = (pool *)(m + L.pools);
    e->inst = (inst *)(m + L.inst);
    e->q = (ev *)(m + L.q);
    e->qmask = (uint32_t)L.qcap - 1;
    e->heap = (ev *)(m + L.heap);
    e->cap = cfg->pending;
    e->blk = (ev *)(m + L.blk);
    e->active = (int *)(m + L.active);
    e->virt = (int *)(m + L.virt);
    e->inputs = (int *)(m + L.inputs);
    e->touched = (int *)(m + L.touched);
    e->pwake = (unsigned char *)(m + L.pwake);
    e->excite = cfg->excite;
    e->excite_user = cfg->excite_user;
    e->mix = (double *)(m + L.mix);
    e->obuf = (double *)(m + L.obuf);
    e->zero = (double *)(m + L.zero);
    e->optr = (double **)(m + L.optr);
    e->iptr = (const double **)(m + L.iptr);
    e->maxout = L.maxout;
    e->maxin = L.maxin;
    e->budget = cfg->budget_ns;
    e->sleep = cfg->sleep;
    e->rel = exp(-cfg->block / (0.05 * cfg->rate));
    e->base = mem;
    init_pools(e, cfg, m, &L);
    /* a voice that cannot be tuned at this rate would play out of tune */
    for (int i = 0; i < e->npools; i++)
        if (e->pools[i].cfg.cls->tuning && !(e->pools[i].cfg.cls->tuning(e->pools[i].tmpl) < INFINITY))
            return WDRT_OUT_OF_TUNE;
    init_space(e, cfg, m, &L);
    start_owned(e);
    e->s.budget_ns = e->budget;
    *engine = e;
    return WDRT_OK;
}

static void *def_alloc(size_t n, void *user) {
    (void)user;
    return malloc(n);
}

static void def_free(void *p, void *user) {
    (void)user;
    free(p);
}

wdrt_result wdrt_engine_init(const wdrt_engine_config *cfg, const wdrt_alloc_callbacks *alloc, wdrt_engine **engine) {
    size_t n;
    wdrt_result r = wdrt_engine_get_size(cfg, &n);
    if (r != WDRT_OK || !engine)
        return WDRT_INVALID_ARGS;
    void *mem = alloc && alloc->alloc ? alloc->alloc(n, alloc->user) : def_alloc(n, NULL);
    if (!mem)
        return WDRT_OUT_OF_MEMORY;
    r = wdrt_engine_init_prealloc(cfg, mem, engine);
    if (r != WDRT_OK) {
        if (alloc && alloc->free)
            alloc->free(mem, alloc->user);
        else
            def_free(mem, NULL);
        return r;
    }
    (*engine)->from_alloc = 1;
    return WDRT_OK;
}

void wdrt_engine_uninit(wdrt_engine *e, const wdrt_alloc_callbacks *alloc) {
    if (!e || !e->from_alloc)
        return;
    void *mem = e->base;
    if (alloc && alloc->free)
        alloc->free(mem, alloc->user);
    else
        def_free(mem, NULL);
}

/* ---- the producer's side ---- */

wdrt_hrtf *wdrt_hrtf_open(const char *sofa, double fs, char *err, size_t errlen) {
    return (wdrt_hrtf *)hrtf_open(sofa, fs, err, errlen);
}

void wdrt_hrtf_close(wdrt_hrtf *h) { hrtf_close((hrtf *)h); }

uint64_t wdrt_engine_time(const wdrt_engine *e) { return e ? __atomic_load_n(&e->time, __ATOMIC_ACQUIRE) : 0; }

wdrt_voice wdrt_engine_voice(const wdrt_engine *e, int pool, int index) {
    if (!e || pool < 0 || pool >= e->npools || !e->pools[pool].cfg.owned || index < 0 ||
        index >= e->pools[pool].cfg.voices)
        return 0;
    return ((uint32_t)(pool + 1) << SEQ_BITS) | (uint32_t)(index + 1);
}

wdrt_voice wdrt_engine_pool(const wdrt_engine *e, int pool) {
    if (!e || pool < 0 || pool >= e->npools)
        return 0;
    return (uint32_t)(pool + 1) << SEQ_BITS;
}

static int voice_pool(const wdrt_engine *e, wdrt_voice v) {
    int p = (int)(v >> SEQ_BITS) - 1;
    return v && p >= 0 && p < e->npools ? p : -1;
}

/* Copies ev into the queue (lock-free, one producer and one consumer). */
static wdrt_result post(wdrt_engine *e, ev *x) {
    uint32_t h = __atomic_load_n(&e->qhead, __ATOMIC_RELAXED);
    uint32_t t = __atomic_load_n(&e->qtail, __ATOMIC_ACQUIRE);
    if (h - t > e->qmask)
        return WDRT_QUEUE_FULL;
    x->seq = e->seq++;
    e->q[h & e->qmask] = *x;
    __atomic_store_n(&e->qhead, h + 1, __ATOMIC_RELEASE);
    return WDRT_OK;
}

static void ev_init(ev *x, int type, uint64_t frame, wdrt_voice v) {
    x->type = type;
    x->frame = frame;
    x->v = v;
    x->n = 0;
    x->pool = -1;
    x->value = 0;
}

wdrt_result wdrt_engine_strike(wdrt_engine *e, uint64_t frame, wdrt_voice v, int n, const int *ids,
                               const double *values) {
    if (!e || voice_pool(e, v) < 0 || n < 0 || n > WDRT_STRIKE_MAX || (n && (!ids || !values)))
        return WDRT_INVALID_ARGS;
    const wdv_class *cls = e->pools[voice_pool(e, v)].cfg.cls;
    ev x;
    ev_init(&x, EV_STRIKE, frame, v);
    for (int k = 0; k < n; k++) {
        if (ids[k] < 0 || ids[k] >= cls->n_ic_targets || !isfinite(values[k]))
            return WDRT_INVALID_ARGS;
        x.ids[k] = ids[k];
        x.vals[k] = values[k];
    }
    x.n = n;
    return post(e, &x);
}

wdrt_result wdrt_engine_set(wdrt_engine *e, uint64_t frame, wdrt_voice v, int param, double value) {
    if (!e || voice_pool(e, v) < 0 || param < 0 || param >= e->pools[voice_pool(e, v)].cfg.cls->n_params ||
        !isfinite(value))
        return WDRT_INVALID_ARGS;
    ev x;
    ev_init(&x, EV_SET, frame, v);
    x.n = param;
    x.value = value;
    wdrt_result r = post(e, &x);
    if (r == WDRT_OK && !(v & SEQ_MASK))
        e->pools[voice_pool(e, v)].pparam[param] = value;
    return r;
}

wdrt_result wdrt_engine_set_prepared(wdrt_engine *e, uint64_t frame, wdrt_voice v, int n, const int *params,
                                     const double *values) {
    int pi = e ? voice_pool(e, v) : -1;
    if (pi < 0 || n < 0 || n > WDRT_STRIKE_MAX || (n && (!params || !values)))
        return WDRT_INVALID_ARGS;
    pool *p = &e->pools[pi];
    const wdv_class *cls = p->cfg.cls;
    for (int k = 0; k < n; k++)
        if (params[k] < 0 || params[k] >= cls->n_params || !isfinite(values[k]))
            return WDRT_INVALID_ARGS;
    uint32_t h = __atomic_load_n(&e->qhead, __ATOMIC_RELAXED);
    uint32_t t = __atomic_load_n(&e->qtail, __ATOMIC_ACQUIRE);
    if (h - t + (uint32_t)n + 1 > e->qmask + 1)
        return WDRT_QUEUE_FULL;
    int slot = -1;
    for (int k = 0; k < WDRT_DESIGN_SLOTS && cls->prepare && slot < 0; k++) {
        int c = (e->dnext + k) % WDRT_DESIGN_SLOTS;
        if (!__atomic_load_n(&e->dbusy[c], __ATOMIC_ACQUIRE))
            slot = c;
    }
    if (cls->prepare && slot < 0)
        return WDRT_QUEUE_FULL;
    for (int k = 0; k < n; k++) /* every event fits: none fails */
        wdrt_engine_set(e, frame, v, params[k], values[k]);
    if (!cls->prepare)
        return WDRT_OK;
    /* the pool's params as posted, with these values */
    double par[64]; /* a class has at most 64 params (check_config) */
    memcpy(par, p->pparam, sizeof(double) * (size_t)cls->n_params);
    for (int k = 0; k < n; k++)
        par[params[k]] = values[k];
    cls->prepare(e->fs, par, e->dslot + (size_t)slot * e->dsize);
    e->dnext = (slot + 1) % WDRT_DESIGN_SLOTS;
    __atomic_store_n(&e->dbusy[slot], 1, __ATOMIC_RELAXED);
    ev x;
    ev_init(&x, EV_DESIGN, frame, v);
    x.n = slot;
    return post(e, &x); /* release: the design and its slot's flag before the event */
}

wdrt_result wdrt_engine_gain(wdrt_engine *e, uint64_t frame, wdrt_voice v, double gain) {
    if (!e || voice_pool(e, v) < 0 || !isfinite(gain))
        return WDRT_INVALID_ARGS;
    ev x;
    ev_init(&x, EV_GAIN, frame, v);
    x.value = gain;
    return post(e, &x);
}

wdrt_result wdrt_engine_play(wdrt_engine *e, uint64_t frame, int pool, double gain, int priority, wdrt_voice *note) {
    if (!e || pool < 0 || pool >= e->npools || e->pools[pool].cfg.owned || !isfinite(gain))
        return WDRT_INVALID_ARGS;
    struct pool *p = &e->pools[pool];
    uint32_t seq = p->next_seq;
    ev x;
    ev_init(&x, EV_PLAY, frame, ((uint32_t)(pool + 1) << SEQ_BITS) | seq);
    x.pool = pool;
    x.value = gain;
    x.n = priority;
    wdrt_result r = post(e, &x);
    if (r != WDRT_OK)
        return r;
    /* sequence numbers above the standing ones, wrapping */
    p->next_seq = seq + 1 > SEQ_MASK ? (uint32_t)p->cfg.voices + 1 : seq + 1;
    if (note)
        *note = x.v;
    return WDRT_OK;
}

wdrt_result wdrt_engine_stop(wdrt_engine *e, uint64_t frame, wdrt_voice v) {
    if (!e || voice_pool(e, v) < 0)
        return WDRT_INVALID_ARGS;
    ev x;
    ev_init(&x, EV_STOP, frame, v);
    return post(e, &x);
}

wdrt_result wdrt_engine_move(wdrt_engine *e, uint64_t frame, wdrt_voice v, const double pos[3]) {
    if (!e || voice_pool(e, v) < 0 || !pos || !isfinite(pos[0] + pos[1] + pos[2]) ||
        !e->pools[voice_pool(e, v)].cfg.placed)
        return WDRT_INVALID_ARGS;
    ev x;
    ev_init(&x, EV_MOVE, frame, v);
    memcpy(x.vals, pos, 3 * sizeof(double));
    return post(e, &x);
}

wdrt_result wdrt_engine_listen(wdrt_engine *e, uint64_t frame, const double pos[3], const double facing[3]) {
    if (!e || e->nslots <= 0 || !pos || !isfinite(pos[0] + pos[1] + pos[2]) ||
        (facing && !(isfinite(facing[0] + facing[1]) && fabs(facing[0]) + fabs(facing[1]) > 0)))
        return WDRT_INVALID_ARGS;
    ev x;
    ev_init(&x, EV_LISTEN, frame, 0);
    memcpy(x.vals, pos, 3 * sizeof(double));
    x.n = facing != NULL;
    if (facing)
        memcpy(x.vals + 3, facing, 3 * sizeof(double));
    return post(e, &x);
}

wdrt_result wdrt_engine_bind_input(wdrt_engine *e, wdrt_voice v, int k, const double *samples) {
    int p = e ? voice_pool(e, v) : -1;
    if (p < 0 || !e->pools[p].cfg.owned || (v & SEQ_MASK) == 0 || k < 0 || k >= e->pools[p].cfg.cls->n_inputs)
        return WDRT_INVALID_ARGS;
    int i = e->pools[p].first + (int)(v & SEQ_MASK) - 1;
    inst *x = &e->inst[i];
    x->in[k] = samples;
    if (samples && !x->hasin) {
        x->hasin = 1;
        e->inputs[e->ninputs++] = i;
    }
    return WDRT_OK;
}

/* ---- the heap of pending events, ordered by (frame, seq) ---- */

static int ev_before(const ev *a, const ev *b) { return a->frame < b->frame || (a->frame == b->frame && a->seq < b->seq); }

static void heap_push(wdrt_engine *e, const ev *x) {
    int i = e->nheap++;
    while (i > 0) {
        int p = (i - 1) / 2;
        if (!ev_before(x, &e->heap[p]))
            break;
        e->heap[i] = e->heap[p];
        i = p;
    }
    e->heap[i] = *x;
}

static void heap_pop(wdrt_engine *e, ev *out) {
    *out = e->heap[0];
    ev last = e->heap[--e->nheap];
    int i = 0, n = e->nheap;
    for (;;) {
        int c = 2 * i + 1;
        if (c >= n)
            break;
        if (c + 1 < n && ev_before(&e->heap[c + 1], &e->heap[c]))
            c++;
        if (!ev_before(&e->heap[c], &last))
            break;
        e->heap[i] = e->heap[c];
        i = c;
    }
    if (n > 0)
        e->heap[i] = last;
}

/* Moves what the producer posted into the heap, while it has room. */
static void drain(wdrt_engine *e) {
    uint32_t t = __atomic_load_n(&e->qtail, __ATOMIC_RELAXED);
    uint32_t h = __atomic_load_n(&e->qhead, __ATOMIC_ACQUIRE);
    while (t != h && e->nheap < e->cap) {
        heap_push(e, &e->q[t & e->qmask]);
        t++;
    }
    __atomic_store_n(&e->qtail, t, __ATOMIC_RELEASE);
}

/* ---- the audio thread: events ---- */

static void chain_push(ev *blk, int *head, int *tail, int i) {
    blk[i].next = -1;
    if (*tail >= 0)
        blk[*tail].next = i;
    else
        *head = i;
    *tail = i;
}

/* The instance a handle names: its index, -2 for a whole pool, -1 when
 * the note has ended. */
static int find_inst(const wdrt_engine *e, wdrt_voice v) {
    const pool *p = &e->pools[voice_pool(e, v)];
    uint32_t seq = v & SEQ_MASK;
    if (seq == 0)
        return -2;
    if (p->cfg.owned)
        return seq <= (uint32_t)p->cfg.voices ? p->first + (int)seq - 1 : -1;
    for (int i = p->first; i < p->first + p->cfg.voices + p->nspare; i++)
        if (e->inst[i].note == v && e->inst[i].mode != M_FREE)
            return i;
    return -1;
}

static const wdv_class *cls_of(const wdrt_engine *e, const inst *v) { return e->pools[v->pool].cfg.cls; }

static void ramp_to(ramp *r, double to, int frames) {
    r->to = to;
    r->step = (to - r->v) / frames;
    r->left = frames;
    r->hold = 0;
}

static double ramp_next(ramp *r) {
    double v = r->v;
    if (r->hold > 0)
        r->hold--;
    else if (r->left > 0)
        r->v = --r->left == 0 ? r->to : r->v + r->step;
    return v;
}

/* Puts a state back as init left it, with the pool's current params. */
static void restore(wdrt_engine *e, inst *v) {
    const pool *p = &e->pools[v->pool];
    const wdv_class *cls = p->cfg.cls;
    memcpy(v->st, p->tmpl, cls->state_size);
    for (int j = 0; j < cls->n_params; j++)
        if (p->param[j] != cls->get_param(p->tmpl, j))
            cls->set_param(v->st, j, p->param[j]);
    if (p->has_design)
        cls->install(v->st, p->design);
    for (int j = 0; j < cls->n_params; j++)
        v->pr[j].steps = v->pr[j].done = 0;
    v->nramps = 0;
}

/* A voice that stops feeding its delay line lets it drain: what it fed
 * still travels to the listener. */
static void detach(wdrt_engine *e, inst *v) {
    if (v->slot >= 0 && e->slots[v->slot].inst == (int)(v - e->inst))
        e->slots[v->slot].inst = -1;
}

static void rest(wdrt_engine *e, inst *v) {
    v->mode = M_FREE;
    v->note = 0;
    v->after = A_NONE;
    detach(e, v);
}

/* The least important of a pool's voices that may be taken for a new
 * note: a virtual one first, then by priority and level; notes too young
 * to have a level only when every voice is young, the oldest first. */
static int victim(const wdrt_engine *e, const pool *p) {
    int best = -1;
    for (int i = p->first; i < p->first + p->cfg.voices; i++) {
        const inst *v = &e->inst[i], *b = best >= 0 ? &e->inst[best] : NULL;
        if (v->mode == M_VIRTUAL)
            return i;
        int young = v->age < GRACE_BLOCKS, byoung = b && b->age < GRACE_BLOCKS;
        if (!b || (byoung && !young) ||
            (young == byoung && (v->priority < b->priority ||
                                 (v->priority == b->priority &&
                                  (young ? v->age > b->age : v->level < b->level)))))
            best = i;
    }
    return best;
}

static void unvirt(wdrt_engine *e, int k) {
    for (int i = 0; i < e->nvirt; i++)
        if (e->virt[i] == k) {
            e->virt[i] = e->virt[--e->nvirt];
            return;
        }
}

/* Moves the sound of instance k onto a free spare of its pool, which fades
 * it out over one block from offset `off` of the span being rendered (the
 * frame of the note that takes k, whatever the host's calls); k is then
 * free to play. */
static void steal(wdrt_engine *e, int k, int off) {
    inst *v = &e->inst[k];
    const pool *p = &e->pools[v->pool];
    e->s.steals++;
    if (v->mode == M_VIRTUAL) {
        unvirt(e, k);
        return;
    }
    int s = -1;
    for (int i = p->first + p->cfg.voices; i < p->first + p->cfg.voices + p->nspare; i++)
        if (e->inst[i].mode == M_FREE)
            s = i;
    if (s < 0) {
        e->s.cuts++;
        v->chain = v->tail = -1;
        return;
    }
    inst *w = &e->inst[s];
    const wdv_class *cls = p->cfg.cls;
    memcpy(w->st, v->st, cls->state_size);
    memcpy(w->pr, v->pr, sizeof(pramp) * (size_t)cls->n_params);
    inst keep = *w;
    *w = *v;
    w->st = keep.st, w->pr = keep.pr, w->in = keep.in, w->spare = 1, w->act = keep.act;
    w->after = A_FREE;
    ramp_to(&w->fade, 0, e->B);
    w->fade.hold = off > w->start ? off - w->start : 0;
    activate(e, s);
    if (v->slot >= 0 && e->slots[v->slot].inst == k) /* the old sound goes on from the same place */
        e->slots[v->slot].inst = e->slots[v->slot].owner = s;
    v->slot = -1;
    v->chain = v->tail = -1;
}

static void play(wdrt_engine *e, const ev *x) {
    pool *p = &e->pools[x->pool];
    int k = -1;
    for (int i = p->first; i < p->first + p->cfg.voices && k < 0; i++)
        if (e->inst[i].mode == M_FREE)
            k = i;
    if (k < 0) {
        k = victim(e, p);
        steal(e, k, x->off);
    }
    inst *v = &e->inst[k];
    restore(e, v);
    v->mode = M_AWAKE;
    v->note = x->v;
    v->note_gain = x->value;
    v->priority = p->cfg.priority + x->n;
    v->after = A_NONE;
    v->start = x->off;
    v->born = x->frame;
    v->age = 0;
    v->level = v->last = v->peak = 0;
    v->quiet = 0;
    v->fade.v = 1, v->fade.left = 0;
    v->gain.v = x->value * p->gain, v->gain.left = 0;
    v->eref = p->cfg.cls->energy(v->st);
    for (int j = 0; j < 3; j++)
        v->pos[j] = v->path[j].v = v->path[j].to = p->cfg.pos[j], v->path[j].left = 0;
    activate(e, k);
}

/* A strike, set, gain or stop for an instance that is not awake.  A
 * strike wakes it; the event joins its chain when `own` (else the pool's
 * chain carries it). */
static void apply_idle(wdrt_engine *e, int k, const ev *x, int own) {
    inst *v = &e->inst[k];
    const wdv_class *cls = cls_of(e, v);
    switch (x->type) {
    case EV_STRIKE:
        if (v->mode == M_VIRTUAL) {
            unvirt(e, k);
            e->s.revived++;
        } else {
            e->s.wakes++;
        }
        v->mode = M_AWAKE;
        v->after = A_NONE;
        v->fade.v = 1, v->fade.left = 0;
        v->start = x->off;
        v->age = GRACE_BLOCKS;
        v->quiet = 0;
        activate(e, k);
        if (own)
            chain_push(e->blk, &v->chain, &v->tail, (int)(x - e->blk));
        break;
    case EV_SET:
        cls->set_param(v->st, x->n, x->value);
        v->pr[x->n].steps = v->pr[x->n].done = 0;
        break;
    case EV_DESIGN:
        cls->install(v->st, e->dslot + (size_t)x->n * e->dsize);
        break;
    case EV_GAIN:
        if (x->v & SEQ_MASK)
            v->note_gain = x->value;
        v->gain.v = v->note_gain * e->pools[v->pool].gain, v->gain.left = 0;
        break;
    case EV_MOVE:
        for (int j = 0; j < 3; j++)
            v->pos[j] = v->path[j].v = v->path[j].to = x->vals[j], v->path[j].left = 0;
        break;
    case EV_STOP:
        if (v->mode == M_VIRTUAL)
            unvirt(e, k);
        if (e->pools[v->pool].cfg.owned) {
            restore(e, v);
            v->mode = M_ASLEEP;
        } else {
            rest(e, v);
        }
        break;
    }
}

static void dispatch(wdrt_engine *e, ev *x) {
    if (x->type == EV_PLAY) {
        play(e, x);
        return;
    }
    if (x->type == EV_LISTEN) {
        if (e->nlmoves < LISTEN_MAX)
            e->lmoves[e->nlmoves++] = *x;
        else /* more than a block can take in order: the latest wins at once */
            e->lmoves[LISTEN_MAX - 1] = *x, e->lmoves[LISTEN_MAX - 1].off = 0;
        return;
    }
    int k = find_inst(e, x->v);
    if (k == -1) {
        e->s.dropped++;
        return;
    }
    if (k >= 0) {
        inst *v = &e->inst[k];
        if (v->mode == M_AWAKE)
            chain_push(e->blk, &v->chain, &v->tail, (int)(x - e->blk));
        else
            apply_idle(e, k, x, 1);
        return;
    }
    pool *p = &e->pools[voice_pool(e, x->v)];
    if (x->type == EV_SET)
        p->param[x->n] = x->value;
    if (x->type == EV_DESIGN) { /* notes played later start from it */
        memcpy(p->design, e->dslot + (size_t)x->n * e->dsize, p->cfg.cls->design_size);
        p->has_design = 1;
    }
    if (x->type == EV_GAIN)
        p->gain = x->value;
    if (x->type == EV_MOVE)
        memcpy(p->cfg.pos, x->vals, 3 * sizeof(double));
    int chained = 0;
    for (int i = p->first; i < p->first + p->cfg.voices + p->nspare; i++) {
        inst *v = &e->inst[i];
        if (v->mode == M_FREE || (v->spare && x->type != EV_GAIN))
            continue;
        if (v->mode != M_AWAKE)
            apply_idle(e, i, x, 0);
        chained |= v->mode == M_AWAKE;
    }
    if (chained) {
        if (p->chain < 0)
            e->touched[e->ntouched++] = (int)(p - e->pools);
        chain_push(e->blk, &p->chain, &p->tail, (int)(x - e->blk));
    }
}

/* Takes the events due before frame t0 + nb off the heap and resolves
 * them in order. */
static void resolve(wdrt_engine *e, uint64_t t0, int nb) {
    e->nblk = 0;
    while (e->nheap > 0 && e->heap[0].frame < t0 + (uint64_t)nb && e->nblk < e->cap) {
        ev *x = &e->blk[e->nblk++];
        heap_pop(e, x);
        if (x->frame < t0) {
            e->s.late++;
            x->off = 0;
        } else {
            x->off = (int)(x->frame - t0);
        }
        e->s.events++;
        e->s.designs += x->type == EV_DESIGN;
        dispatch(e, x);
    }
}

/* ---- the audio thread: rendering ---- */

static void place(wdrt_engine *e, int k, uint64_t t0);

static void ramps_next(inst *v, int np) {
    v->nramps = 0;
    for (int j = 0; j < np; j++)
        v->nramps += v->pr[j].done < v->pr[j].steps;
}

/* Sets every ramping param whose next step is due at frame `now`. */
static void apply_ramps(wdrt_engine *e, inst *v, uint64_t now) {
    const wdv_class *cls = cls_of(e, v);
    for (int j = 0; j < cls->n_params; j++) {
        pramp *r = &v->pr[j];
        while (r->done < r->steps && r->next <= now) {
            r->done++;
            double x = r->done == r->steps ? r->to : r->from + (r->to - r->from) * r->done / r->steps;
            cls->set_param(v->st, j, x);
            r->next += (uint64_t)r->every;
        }
    }
    ramps_next(v, cls->n_params);
}

/* The first frame after `now` at which a ramp steps, or UINT64_MAX. */
static uint64_t ramp_due(const wdrt_engine *e, const inst *v) {
    uint64_t t = UINT64_MAX;
    for (int j = 0; j < cls_of(e, v)->n_params; j++)
        if (v->pr[j].done < v->pr[j].steps && v->pr[j].next < t)
            t = v->pr[j].next;
    return t;
}

static void fade_out(wdrt_engine *e, inst *v, int after) {
    v->after = after;
    ramp_to(&v->fade, 0, e->B);
}

static void apply_event(wdrt_engine *e, int k, const ev *x, uint64_t now) {
    inst *v = &e->inst[k];
    const wdv_class *cls = cls_of(e, v);
    switch (x->type) {
    case EV_STRIKE:
        cls->set_ic(v->st, x->n, x->ids, x->vals);
        v->eref = cls->energy(v->st);
        v->quiet = 0;
        if (v->after != A_NONE && !v->spare) { /* struck while fading out: back up */
            v->after = A_NONE;
            ramp_to(&v->fade, 1, e->B);
        }
        break;
    case EV_SET: {
        pramp *r = &v->pr[x->n];
        /* a step, not a ramp: for a voice that asks for it, and for a note
         * set at the frame it is played (its first sample has the value) */
        if ((cls->params[x->n].flags & WDV_PARAM_STEP) ||
            (!e->pools[v->pool].cfg.owned && x->frame == v->born && v->age == 0)) {
            cls->set_param(v->st, x->n, x->value);
            r->steps = r->done = 0;
            ramps_next(v, cls->n_params);
            break;
        }
        r->from = cls->get_param(v->st, x->n);
        r->to = x->value;
        r->steps = e->B < RAMP_STEPS ? e->B : RAMP_STEPS;
        r->every = e->B / r->steps;
        r->done = 0;
        r->next = now;
        apply_ramps(e, v, now);
        break;
    }
    case EV_DESIGN:
        cls->install(v->st, e->dslot + (size_t)x->n * e->dsize);
        break;
    case EV_GAIN:
        if (x->v & SEQ_MASK)
            v->note_gain = x->value;
        ramp_to(&v->gain, v->note_gain * e->pools[v->pool].gain, e->B);
        break;
    case EV_STOP:
        fade_out(e, v, e->pools[v->pool].cfg.owned ? A_RESET : A_FREE);
        break;
    case EV_MOVE:
        for (int j = 0; j < 3; j++)
            ramp_to(&v->path[j], x->vals[j], e->B);
        break;
    }
}

/* Mixes frames [a, b) of the heard output into the mix, with the gain and
 * fade envelopes, and keeps the peak. */
/* Feeds frames [a, b) of a placed voice's heard output, with its gain
 * and fade, into its delay line (none: it is not heard), and moves it
 * along its path. */
/* The gain of the next frame: the voice's gain times its fade, each
 * moving along its ramp. */
static double envelope(inst *v) {
    if (v->gain.left | v->fade.left)
        return ramp_next(&v->gain) * ramp_next(&v->fade);
    return v->gain.v * v->fade.v;
}

static void feed_segment(wdrt_engine *e, inst *v, const double *y, int a, int b, uint64_t t0) {
    int k = (int)(v - e->inst);
    slot *q = v->slot >= 0 && e->slots[v->slot].inst == k ? &e->slots[v->slot] : NULL;
    int moving = v->path[0].left | v->path[1].left | v->path[2].left;
    double pk = v->peak;
    for (int n = a; n < b; n++) {
        double x = envelope(v) * y[n];
        pk = fabs(x) > pk ? fabs(x) : pk;
        if (q)
            q->buf[(t0 + (uint64_t)n) & e->dmask] = x;
        if (moving)
            for (int j = 0; j < 3; j++)
                v->pos[j] = ramp_next(&v->path[j]);
    }
    v->peak = pk;
    if (q)
        q->fed = t0 + (uint64_t)b;
}

static double room_heard(const wdrt_engine *e, const room *r);

/* Mixes [a, b) of the instance's outputs, which start at obuf (the
 * outputs one after another, B frames apart). */
static void mix_segment(wdrt_engine *e, inst *v, const double *obuf, int a, int b, uint64_t t0) {
    const pool *p = &e->pools[v->pool];
    const double *y = obuf + (size_t)p->cfg.output * (size_t)e->B;
    if (p->cfg.placed) {
        feed_segment(e, v, y, a, b, t0);
        return;
    }
    double *m = e->mix, pk = v->peak, h = 1, dh = 0;
    if (p->cfg.ambient) { /* heard as its room's reverb is, along the same ramp */
        const room *r = &e->rooms[p->cfg.ambient - 1];
        double h1 = room_heard(e, r);
        dh = (h1 - r->heard) / e->B;
        h = r->heard + dh * (a + 1);
    }
    for (int n = a; n < b; n++, h += dh) {
        double x = h * envelope(v) * y[n];
        pk = fabs(x) > pk ? fabs(x) : pk;
        if (e->nch == 1)
            m[n] += x;
        else
            m[2 * n] += p->cl * x, m[2 * n + 1] += p->cr * x;
    }
    v->peak = pk;
}

static void process_segment(wdrt_engine *e, inst *v, int a, int b, int callpos, uint64_t t0) {
    const wdv_class *cls = cls_of(e, v);
    for (int j = 0; j < cls->n_outputs; j++)
        e->optr[j] = e->obuf + (size_t)j * (size_t)e->B + a;
    for (int j = 0; j < cls->n_inputs; j++)
        e->iptr[j] = v->in && v->in[j] ? v->in[j] + callpos + a : e->zero;
    cls->process(v->st, e->iptr, e->optr, b - a);
    mix_segment(e, v, e->obuf, a, b, t0);
}

/* The next event of the instance's chain or its pool's (pool events from
 * before the instance started this block were applied already). */
static const ev *next_event(const wdrt_engine *e, const inst *v, int *ci, int *pi) {
    while (*pi >= 0 && e->blk[*pi].off < v->start)
        *pi = e->blk[*pi].next;
    if (*ci < 0 && *pi < 0)
        return NULL;
    if (*pi < 0 || (*ci >= 0 && (e->blk[*ci].off < e->blk[*pi].off ||
                                 (e->blk[*ci].off == e->blk[*pi].off && e->blk[*ci].seq < e->blk[*pi].seq)))) {
        const ev *x = &e->blk[*ci];
        *ci = x->next;
        return x;
    }
    const ev *x = &e->blk[*pi];
    *pi = x->next;
    return x;
}

static const ev *peek_event(const wdrt_engine *e, const inst *v, int ci, int pi) {
    return next_event(e, v, &ci, &pi);
}

/* Renders instance k over [start, nb) of the block at frame t0, segment by
 * segment between the frames its events and ramp steps act at. */
static void render_inst(wdrt_engine *e, int k, uint64_t t0, int nb, int callpos) {
    inst *v = &e->inst[k];
    if (e->pools[v->pool].cfg.placed)
        place(e, k, t0);
    int ci = v->chain, pi = v->spare ? -1 : e->pools[v->pool].chain;
    int pos = v->start;
    while (pos < nb) {
        const ev *x;
        while ((x = peek_event(e, v, ci, pi)) && x->off <= pos) {
            next_event(e, v, &ci, &pi);
            apply_event(e, k, x, t0 + (uint64_t)pos);
        }
        if (v->nramps)
            apply_ramps(e, v, t0 + (uint64_t)pos);
        int end = nb;
        if (x && x->off < end)
            end = x->off;
        if (v->nramps) {
            uint64_t r = ramp_due(e, v);
            if (r < t0 + (uint64_t)end)
                end = (int)(r - t0);
        }
        process_segment(e, v, pos, end, callpos, t0);
        pos = end;
    }
    v->start = 0;
    v->chain = v->tail = -1;
}

/* Instance k renders the whole span [0, nb) in one process call: nothing
 * acts on it inside the span (no event of its own or of its pool, no
 * ramp), its class has process_batch, and it is not placed in space (a
 * placed voice takes its slot as it renders). */
static int whole_span(const wdrt_engine *e, int k) {
    const inst *v = &e->inst[k];
    const pool *p = &e->pools[v->pool];
    return p->cfg.cls->process_batch && !p->cfg.placed && v->start == 0 && v->chain < 0 &&
           (v->spare || p->chain < 0) && !v->nramps;
}

/* Renders the n instances ks (of one pool, each whole_span) by one
 * process_batch call, each into its lane of obuf, then mixes them in
 * order: what render_inst would give, bit for bit, since a voice's lanes
 * compute what its process does. */
static void render_lanes(wdrt_engine *e, const int *ks, int n, uint64_t t0, int nb, int callpos) {
    const wdv_class *cls = cls_of(e, &e->inst[ks[0]]);
    void *st[LANES];
    const double *const *in[LANES];
    double *const *out[LANES];
    for (int l = 0; l < n; l++) {
        inst *v = &e->inst[ks[l]];
        double **o = e->optr + (size_t)l * (size_t)(e->maxout + 1);
        const double **i = e->iptr + (size_t)l * (size_t)(e->maxin + 1);
        for (int j = 0; j < cls->n_outputs; j++)
            o[j] = e->obuf + ((size_t)l * (size_t)e->maxout + (size_t)j) * (size_t)e->B;
        for (int j = 0; j < cls->n_inputs; j++)
            i[j] = v->in && v->in[j] ? v->in[j] + callpos : e->zero;
        st[l] = v->st;
        in[l] = i;
        out[l] = o;
    }
    cls->process_batch(st, n, in, out, nb);
    for (int l = 0; l < n; l++) {
        inst *v = &e->inst[ks[l]];
        mix_segment(e, v, e->obuf + (size_t)l * (size_t)e->maxout * (size_t)e->B, 0, nb, t0);
        v->chain = v->tail = -1;
    }
}

/* Renders the active instances in order; runs of up to LANES of one pool
 * that render their whole span go through process_batch together. */
static void render_active(wdrt_engine *e, uint64_t t0, int nb, int callpos) {
    for (int i = 0; i < e->nactive;) {
        int k = e->active[i], n = 1;
        if (whole_span(e, k))
            while (n < LANES && i + n < e->nactive && e->inst[e->active[i + n]].pool == e->inst[k].pool &&
                   whole_span(e, e->active[i + n]))
                n++;
        if (n > 1)
            render_lanes(e, e->active + i, n, t0, nb, callpos);
        else
            render_inst(e, k, t0, nb, callpos);
        i += n;
    }
}

/* Ends a fade-out that has run its course. */
static void finish(wdrt_engine *e, int k) {
    inst *v = &e->inst[k];
    detach(e, v);
    switch (v->after) {
    case A_SLEEP:
        v->mode = M_ASLEEP;
        break;
    case A_FREE:
        rest(e, v);
        break;
    case A_VIRTUAL:
        v->mode = M_VIRTUAL;
        e->virt[e->nvirt++] = k;
        break;
    case A_RESET:
        restore(e, v);
        v->mode = M_ASLEEP;
        break;
    }
    v->after = A_NONE;
    v->fade.v = 1, v->fade.left = 0;
}

/* Drops from the active list what no longer renders. */
static void compact(wdrt_engine *e) {
    int n = 0;
    for (int i = 0; i < e->nactive; i++) {
        int k = e->active[i];
        inst *v = &e->inst[k];
        if (v->after != A_NONE && v->fade.left == 0)
            finish(e, k);
        if (v->mode == M_AWAKE) {
            v->act = n;
            e->active[n++] = k;
        } else {
            v->act = -1;
        }
    }
    e->nactive = n;
}

/* Wakes standing voices whose bound input is not silent in [0, nb). */
/* Wakes instance k (a sleeper starts at frame `start` of the block), or
 * turns back its fade into sleep. */
static void wake(wdrt_engine *e, int k, int start) {
    inst *v = &e->inst[k];
    if (v->mode == M_ASLEEP) {
        e->s.wakes++;
        v->mode = M_AWAKE;
        v->start = start;
        v->age = GRACE_BLOCKS;
        v->fade.v = 1, v->fade.left = 0;
        activate(e, k);
    } else if (v->mode == M_AWAKE && v->after == A_SLEEP) {
        v->after = A_NONE;
        ramp_to(&v->fade, 1, e->B);
    }
}

static void wake_inputs(wdrt_engine *e, int callpos, int nb) {
    for (int i = 0; i < e->ninputs; i++) {
        int k = e->inputs[i];
        inst *v = &e->inst[k];
        const wdv_class *cls = cls_of(e, v);
        int first = nb;
        for (int j = 0; j < cls->n_inputs; j++)
            if (v->in[j])
                for (int n = 0; n < first; n++)
                    if (v->in[j][callpos + n] != 0) {
                        first = n;
                        break;
                    }
        if (first == nb) {
            continue;
        }
        v->peak = v->peak > e->pools[v->pool].cfg.quiet ? v->peak : e->pools[v->pool].cfg.quiet;
        if (v->mode == M_VIRTUAL) { /* still fed: it stays as audible as it was, and the budget decides */
            v->vdec = 1;
            continue;
        }
        wake(e, k, first);
    }
}

/* ---- the audio thread: space ---- */

static double dist3(const double *a, const double *b) {
    return sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
}

/* Gives placed voice k a delay line from `now` on: its own if it is still
 * draining (the silence since it stopped is written), else a free one. */
static void slot_attach(wdrt_engine *e, int k, uint64_t now) {
    inst *v = &e->inst[k];
    slot *q = v->slot >= 0 && e->slots[v->slot].owner == k && e->slots[v->slot].busy ? &e->slots[v->slot] : NULL;
    if (q) {
        uint64_t gap = now > q->fed ? now - q->fed : 0;
        for (uint64_t f = 0; f < gap && f <= e->dmask; f++)
            q->buf[(q->fed + f) & e->dmask] = 0;
        q->fed = now > q->fed ? now : q->fed;
        q->inst = k;
        return;
    }
    int i = 0;
    while (i < e->nslots && e->slots[i].busy)
        i++;
    if (i == e->nslots) {
        e->s.unplaced++;
        v->slot = -1;
        return;
    }
    q = &e->slots[i];
    memset(q->buf, 0, sizeof(double) * (size_t)(e->dmask + 1));
    for (uint64_t h = 0; h <= e->hmask; h++)
        memcpy(q->hist[h], v->pos, sizeof v->pos);
    q->busy = 1;
    q->inst = q->owner = k;
    q->start = q->fed = now;
    q->hlast = now / (uint64_t)e->B;
    q->moved = 0;
    q->tau = dist3(v->pos, e->lis) / e->sp.c;
    q->gain = 0;
    q->occ = q->occ_to = 0;
    q->occ_gain = 1;
    q->lp = 0;
    memset(q->air, 0, sizeof q->air);
    if (q->ear)
        hrtf_src_clear(q->ear);
    q->ntaps = -1;
    q->tail = 0;
    q->room = -1;
    v->slot = i;
}

/* Before a placed voice renders: a delay line, and its position at the
 * start of each grid block. */
static void place(wdrt_engine *e, int k, uint64_t t0) {
    inst *v = &e->inst[k];
    if (v->slot < 0 || e->slots[v->slot].inst != k)
        slot_attach(e, k, t0 + (uint64_t)v->start);
    if (v->slot < 0 || t0 % (uint64_t)e->B)
        return;
    slot *q = &e->slots[v->slot];
    uint64_t b = t0 / (uint64_t)e->B;
    double *h = q->hist[b & e->hmask], *hp = q->hist[(b - 1) & e->hmask];
    memcpy(h, v->pos, sizeof v->pos);
    if (h[0] != hp[0] || h[1] != hp[1] || h[2] != hp[2])
        q->moved = b;
    q->hlast = b;
}

/* Where the source of q was at fractional frame te, and how fast it was
 * moving (m/s): linear between the positions of grid block starts. */
static void slot_pos(const wdrt_engine *e, const slot *q, double te, double p[3], double vel[3]) {
    double b = te > 0 ? te / e->B : 0;
    uint64_t k = (uint64_t)b;
    if (k + e->hmask < q->hlast)
        k = q->hlast - e->hmask, b = (double)k;
    if (k >= q->hlast) {
        memcpy(p, q->hist[q->hlast & e->hmask], 3 * sizeof(double));
        vel[0] = vel[1] = vel[2] = 0;
        return;
    }
    const double *h0 = q->hist[k & e->hmask], *h1 = q->hist[(k + 1) & e->hmask];
    double f = b - (double)k;
    for (int j = 0; j < 3; j++) {
        p[j] = h0[j] + (h1[j] - h0[j]) * f;
        vel[j] = (h1[j] - h0[j]) * e->fs / e->B;
    }
}

/* The retarded delay tau (s) at frame t for a listener at L: what is heard
 * now left the source where it was tau ago, c tau = |p(t - tau) - L|.
 * Newton's method from the last tau, which is close: at most three steps.
 * f(tau) = c tau - |p(t - tau) - L| is -|p(t) - L| <= 0 at 0 and grows
 * without bound, so a root lies between the last tau where f < 0 and the
 * first where f > 0; a step that leaves that bracket, or a slope that is
 * not positive (the source comes at the listener as fast as sound or
 * faster, which a jump of its position between blocks also gives), is
 * replaced by doubling tau until f > 0, then by halving the bracket: the
 * solve stays finite and bounded for any path. */
static double retarded(const wdrt_engine *e, const slot *q, double t, const double *L, double tau, double p[3]) {
    double vel[3], lo = 0, hi = HUGE_VAL;
    for (int it = 0, newton = 0; it < 64; it++) {
        slot_pos(e, q, t - tau * e->fs, p, vel);
        double dx[3] = {p[0] - L[0], p[1] - L[1], p[2] - L[2]};
        double d = sqrt(dx[0] * dx[0] + dx[1] * dx[1] + dx[2] * dx[2]);
        double f = e->sp.c * tau - d;
        double fp = e->sp.c + (d > 0 ? (dx[0] * vel[0] + dx[1] * vel[1] + dx[2] * vel[2]) / d : 0);
        if (f == 0)
            break;
        if (f < 0)
            lo = tau;
        else
            hi = tau;
        double step = f / fp, next = tau - step;
        if (fp > 0 && next >= lo && next <= hi) {
            tau = next;
            if (fabs(step) * e->fs < 1e-9 || ++newton == 3)
                break;
        } else {
            tau = hi == HUGE_VAL ? 2 * tau + 1 / e->fs : 0.5 * (lo + hi);
            if (hi - lo < 1e-9 / e->fs)
                break;
        }
    }
    return tau > 2 / e->fs ? tau : 2 / e->fs;
}

/* The listener's position at each frame of the block, its moves taken at
 * their frames. */
static void listener_path(wdrt_engine *e, int nb) {
    int m = 0;
    for (int n = 0; n < nb; n++) {
        while (m < e->nlmoves && e->lmoves[m].off <= n) {
            const ev *x = &e->lmoves[m++];
            for (int j = 0; j < 3; j++)
                ramp_to(&e->lpath[j], x->vals[j], e->B);
            double f = hypot(x->vals[3], x->vals[4]);
            if (x->n && f > 0)
                e->face[0] = x->vals[3] / f, e->face[1] = x->vals[4] / f;
        }
        for (int j = 0; j < 3; j++)
            e->lpos[3 * n + j] = ramp_next(&e->lpath[j]);
    }
    e->nlmoves = 0;
    memcpy(e->lis, e->lpos + 3 * (nb - 1), sizeof e->lis);
}

/* Walls crossed by the straight path from L to p: their loss in dB. */
static double wall_loss(const wdrt_engine *e, const double *L, const double *p) {
    double db = 0;
    for (int i = 0; i < e->sp.nwalls; i++)
        if (space_segments_cross(L, p, e->sp.walls[i].from, e->sp.walls[i].to))
            db += e->sp.walls[i].loss_db;
    return db;
}

/* Stereo gains for a sound arriving from p at a listener at L. */
static void pan_gains(const wdrt_engine *e, const double *L, const double *p, double *gl, double *gr) {
    double dx = p[0] - L[0], dy = p[1] - L[1], d = hypot(dx, dy);
    /* right = facing x up */
    double x = d > 0 ? (dx * e->face[1] - dy * e->face[0]) / d : 0;
    double th = (x + 1) * 0.7853981633974483;
    *gl = cos(th), *gr = sin(th);
}

/* The air filter for distance d: poles interpolated in the table. */
static void air_poles(const wdrt_engine *e, double d, double *p) {
    double r = sqrt(d / e->sp.max);
    r = r < 0 ? 0 : r > 1 ? 1 : r;
    double x = r * (AIR_TABLE - 1);
    int j = (int)x < AIR_TABLE - 1 ? (int)x : AIR_TABLE - 2;
    double f = x - j;
    for (int k = 0; k < SPACE_AIR_POLES; k++) {
        double a = k < e->air_n[j] ? e->air_p[j] : 0, b = k < e->air_n[j + 1] ? e->air_p[j + 1] : 0;
        p[k] = a + (b - a) * f;
    }
}

/* Binaural: the block's arriving signal in e->sig through the HRTF for
 * its direction in the listener's frame (x right, y ahead, z up). */
static void hear(wdrt_engine *e, slot *q, const double *L, const double *p, int nb) {
    double u[3] = {p[0] - L[0], p[1] - L[1], p[2] - L[2]};
    double dir[3] = {u[0] * e->face[1] - u[1] * e->face[0], u[0] * e->face[0] + u[1] * e->face[1], u[2]};
    double *l = e->earbuf, *r = e->earbuf + e->B;
    memset(e->earbuf, 0, sizeof(double) * 2 * (size_t)e->B);
    hrtf_src_process(e->ears, q->ear, dir, e->sig, l, r, nb);
    for (int n = 0; n < nb; n++)
        e->mix[2 * n] += l[n], e->mix[2 * n + 1] += r[n];
}

/* The room a point is in, or -1. */
static int room_of(const wdrt_engine *e, const double *p) {
    for (int i = 0; i < e->nrooms; i++)
        if (room_contains(&e->rooms[i].cfg, p))
            return i;
    return -1;
}

/* The images of q's source in its room, heard by a listener in the same
 * room: each a tap on the delay line at its own delay (from where the
 * source is now; the retarded time of the direct path is not solved for
 * them), through its walls' filter, with its distance gain and panned by
 * its direction (binaural output too). */
static void images(wdrt_engine *e, slot *q, const room *r, uint64_t t0, int nb, const double *L, const double *p) {
    room_image img[MAX_IMAGES];
    if (!q->taps || r->cfg.order == 0) {
        q->ntaps = 0;
        return;
    }
    int n = room_images(&r->cfg, p, img, MAX_IMAGES);
    if (n < 0)
        n = 0;
    if (n != q->ntaps)
        memset(q->taps, 0, sizeof(tap) * MAX_IMAGES);
    q->tail = 0;
    for (int i = 0; i < n; i++) {
        tap *k = &q->taps[i];
        double d = dist3(img[i].pos, L);
        double delay = d / e->sp.c, gain = space_distance_gain(e->sp.distance, d, e->sp.ref, e->sp.max, e->sp.rolloff);
        double gl = 1, gr = 0;
        if (e->nch == 2)
            pan_gains(e, L, img[i].pos, &gl, &gr);
        if (i >= q->ntaps || k->delay == 0) /* a new tap starts where it is */
            k->delay = delay, k->gain = gain, k->gl = gl, k->gr = gr;
        if (img[i].gain != k->wg || img[i].hf != k->whf) { /* the same walls: the same filter */
            room_wall_filter_coefs(img[i].gain, img[i].hf, e->fs, &k->b0, &k->b1, &k->a1);
            k->wg = img[i].gain, k->whf = img[i].hf;
        }
        double dd = (delay - k->delay) / nb, dg = (gain - k->gain) / nb, dl = (gl - k->gl) / nb,
               dr = (gr - k->gr) / nb;
        for (int j = 0; j < nb; j++) {
            double te = (double)(t0 + (uint64_t)j) - (k->delay + dd * j) * e->fs;
            double x = te < (double)q->start - 2 ? 0 : space_read(q->buf, e->dmask, te);
            double y = k->b0 * x + k->b1 * k->x1 - k->a1 * k->y1;
            k->x1 = x, k->y1 = y;
            y *= k->gain + dg * j;
            if (e->nch == 1)
                e->mix[j] += y;
            else
                e->mix[2 * j] += (k->gl + dl * j) * y, e->mix[2 * j + 1] += (k->gr + dr * j) * y;
        }
        k->delay = delay, k->gain = gain, k->gl = gl, k->gr = gr;
        q->tail = delay > q->tail ? delay : q->tail;
    }
    q->ntaps = n;
}

/* How a room's reverb is heard from outside it: as from its nearest
 * point (the scene's distance model at that distance), and through the
 * walls between the listener and the room's centre. */
static double outside(const wdrt_engine *e, const room *r, const double *c) {
    const double *b = r->cfg.box;
    double d2 = 0;
    for (int j = 0; j < 3; j++) {
        double x = e->lis[j] < b[j] ? b[j] - e->lis[j] : e->lis[j] > b[j + 3] ? e->lis[j] - b[j + 3] : 0;
        d2 += x * x;
    }
    return space_distance_gain(e->sp.distance, sqrt(d2), e->sp.ref, e->sp.max, e->sp.rolloff) *
           pow(10, -wall_loss(e, e->lis, c) / 20);
}

/* How much of a room's reverb (and ambience) the listener hears now. */
static double room_heard(const wdrt_engine *e, const room *r) {
    const double *b = r->cfg.box;
    double c[3] = {(b[0] + b[3]) / 2, (b[1] + b[4]) / 2, (b[2] + b[5]) / 2};
    return room_contains(&r->cfg, e->lis) ? 1 : outside(e, r, c);
}

/* The reverb of every room, fed by the sources in it this block and heard
 * fully inside it, and from outside as outside() says. */
static void reverb(wdrt_engine *e, int nb) {
    e->s.rooms = 0;
    for (int i = 0; i < e->nrooms; i++) {
        room *r = &e->rooms[i];
        r->heard_to = room_heard(e, r);
        if (!r->fed && r->asleep) {
            r->heard = r->heard_to;
            continue;
        }
        if (!r->fed)
            memset(r->in, 0, sizeof(double) * (size_t)nb);
        double *l = e->rout, *rr = e->rout + e->B;
        memset(e->rout, 0, sizeof(double) * 2 * (size_t)e->B);
        room_fdn_process(r->fdn, r->in, l, rr, nb);
        double h = r->heard, dh = (r->heard_to - r->heard) / nb;
        for (int n = 0; n < nb; n++, h += dh) {
            if (e->nch == 1)
                e->mix[n] += h * l[n];
            else
                e->mix[2 * n] += h * l[n], e->mix[2 * n + 1] += h * rr[n];
        }
        r->heard = r->heard_to;
        /* unfed, it sleeps once what it holds has died away (its lines are
         * summed only once its output is quiet) */
        r->asleep = 0;
        if (!r->fed) {
            double pk = 0;
            for (int n = 0; n < nb; n++)
                pk = fmax(pk, fabs(l[n]) + fabs(rr[n]));
            r->asleep = pk < 1e-12 && room_fdn_energy(r->fdn) < 1e-24;
        }
        e->s.rooms += !r->asleep;
        r->fed = 0;
    }
}

/* What reaches the listener from slot q in this block, mixed in. */
static void slot_render(wdrt_engine *e, slot *q, uint64_t t0, int nb) {
    double p0[3], p1[3];
    /* nothing is written past what was fed: what an interpolator reads
     * there (a sleeping voice's line draining, the last frames of a
     * source at the listener) is silence, not the line's older laps */
    for (uint64_t f = q->fed > t0 ? q->fed : t0; f < t0 + (uint64_t)nb + 4; f++)
        q->buf[f & e->dmask] = 0;
    double tau0 = retarded(e, q, (double)t0, e->lpos, q->tau, p0);
    double tau = tau0;
    /* the source at rest since before what is heard, and the listener
     * still: the delay is the same for the whole block */
    int still = (double)q->moved * e->B + e->B < (double)t0 - tau0 * e->fs - 4 && e->lpath[0].left == 0 &&
                e->lpath[1].left == 0 && e->lpath[2].left == 0 && e->nlmoves == 0;
    /* otherwise tau is solved at the block's first, middle and last frames
     * and follows the parabola through them: over 64 frames its error is
     * of the order of the third derivative of tau times h^3, far below a
     * thousandth of a sample for any source slower than sound */
    double qa = 0, qb = 0;
    int m = (nb - 1) / 2, last = nb - 1;
    if (!still && last > 0) {
        double pm[3];
        double tm = retarded(e, q, (double)(t0 + (uint64_t)m), e->lpos + 3 * m, tau0, pm);
        tau = retarded(e, q, (double)(t0 + (uint64_t)last), e->lpos + 3 * last, tm, p1);
        /* tau(n) = tau0 + qa n + qb n^2 through (m, tm) and (last, tau) */
        if (m > 0) {
            double d1 = (tm - tau0) / m, d2 = (tau - tau0) / last;
            qb = (d2 - d1) / (last - m);
            qa = d1 - qb * m;
        } else {
            qa = (tau - tau0) / last;
        }
    } else {
        memcpy(p1, p0, sizeof p1);
    }
    for (int n = 0; n < nb; n++) {
        double te = (double)(t0 + (uint64_t)n) - (tau0 + (qa + qb * n) * n) * e->fs;
        e->sig[n] = te < (double)q->start - 2 ? 0 : space_read(q->buf, e->dmask, te);
    }
    /* the room the source is in hears it as the listener does, before the
     * way's losses: its reverb starts after the direct sound */
    int ri = e->nrooms ? room_of(e, p1) : -1;
    if (ri != q->room)
        q->ntaps = -1; /* into another room: its images start anew */
    q->room = ri;
    if (ri >= 0) {
        room *r = &e->rooms[ri];
        if (!r->fed)
            memset(r->in, 0, sizeof(double) * (size_t)nb);
        for (int n = 0; n < nb; n++)
            r->in[n] += e->sig[n];
        r->fed = 1;
        r->asleep = 0;
    }
    q->tau = tau;
    const double *L0 = e->lpos, *L1 = e->lpos + 3 * (nb - 1);
    double d0 = e->sp.c * tau0, d1 = e->sp.c * tau;
    double g0 = q->gain, g1 = space_distance_gain(e->sp.distance, d1, e->sp.ref, e->sp.max, e->sp.rolloff);
    if (q->gain == 0 && q->fed <= q->start + (uint64_t)nb)
        g0 = space_distance_gain(e->sp.distance, d0, e->sp.ref, e->sp.max, e->sp.rolloff);
    q->gain = g1;
    /* occlusion, faded in or out over the block */
    double loss = wall_loss(e, L1, p1);
    q->occ_to = loss > 0 ? 1 : 0;
    if (loss > 0)
        q->occ_gain = pow(10, -loss / 20);
    double occ_step = (q->occ_to - q->occ) / nb, lpa = exp(-2 * M_PI * 1000 / e->fs);
    double air[SPACE_AIR_POLES];
    int nair = 0;
    if (e->sp.air) {
        air_poles(e, d1, air);
        while (nair < SPACE_AIR_POLES && air[nair] > 0)
            nair++;
    }
    double gl0 = 1, gr0 = 0, gl1 = 1, gr1 = 0;
    if (e->ears) { /* the HRTF makes the direction: the gains stay whole */
        gl0 = gl1 = 1;
    } else if (e->nch == 2) {
        pan_gains(e, L0, p0, &gl0, &gr0);
        pan_gains(e, L1, p1, &gl1, &gr1);
    }
    for (int n = 0; n < nb; n++) {
        double w = (double)n / nb, x = e->sig[n];
        for (int k = 0; k < nair; k++)
            x = q->air[k] += (1 - air[k]) * (x - q->air[k]);
        q->lp += (1 - lpa) * (x - q->lp);
        q->occ += occ_step;
        x = (1 - q->occ) * x + q->occ * q->occ_gain * q->lp;
        x *= g0 + (g1 - g0) * w;
        if (e->ears)
            e->sig[n] = x;
        else if (e->nch == 1)
            e->mix[n] += x;
        else
            e->mix[2 * n] += (gl0 + (gl1 - gl0) * w) * x, e->mix[2 * n + 1] += (gr0 + (gr1 - gr0) * w) * x;
    }
    if (e->ears)
        hear(e, q, L1, p1, nb);
    if (ri >= 0) {
        room *r = &e->rooms[ri];
        if (room_contains(&r->cfg, L1))
            images(e, q, r, t0, nb, L1, p1);
        else
            q->ntaps = 0;
    }
    q->occ = q->occ_to;
    for (int k = nair; k < SPACE_AIR_POLES; k++)
        q->air[k] = q->air[nair ? nair - 1 : 0];
    /* a voice's audibility for the budget is what arrives */
    if (q->inst >= 0)
        e->inst[q->inst].sgain = g1 * (1 - q->occ_to + q->occ_to * q->occ_gain);
    /* drained: everything fed has arrived */
    if (q->inst < 0 && (double)q->fed + 4 < (double)(t0 + (uint64_t)nb) - (tau > q->tail ? tau : q->tail) * e->fs)
        q->busy = 0;
}

static void space_mix(wdrt_engine *e, uint64_t t0, int nb) {
    if (e->nslots <= 0)
        return;
    listener_path(e, nb);
    int n = 0;
    for (int i = 0; i < e->nslots; i++)
        if (e->slots[i].busy) {
            slot_render(e, &e->slots[i], t0, nb);
            n++;
        }
    e->s.sources = n;
    reverb(e, nb);
}

/* ---- the audio thread: the end of a grid block ---- */

static int more_important(const inst *a, double la, const inst *b, double lb) {
    return a->priority > b->priority || (a->priority == b->priority && la > lb);
}

/* Voices quiet for their hold whose energy has run down, or stays put,
 * fade out and sleep. */
static void sleep_quiet(wdrt_engine *e) {
    for (int i = 0; i < e->nactive; i++) {
        inst *v = &e->inst[e->active[i]];
        const pool *p = &e->pools[v->pool];
        if (v->after != A_NONE || v->fade.left || v->spare || v->peak >= p->cfg.quiet) {
            v->quiet = 0;
            continue;
        }
        if (v->quiet++ == 0)
            v->equiet = p->cfg.cls->energy(v->st);
        if (v->quiet * (double)e->B < p->cfg.hold * e->fs)
            continue;
        double en = p->cfg.cls->energy(v->st);
        v->quiet = 0;
        double floor = v->eref * pow(10, p->cfg.floor_db / 10);
        if (en > floor && fabs(en - v->equiet) > floor)
            continue;
        fade_out(e, v, p->cfg.owned ? A_SLEEP : A_FREE);
        e->s.sleeps++;
    }
}

static double running_cost(const wdrt_engine *e) {
    double c = 0;
    for (int i = 0; i < e->nactive; i++) {
        const inst *v = &e->inst[e->active[i]];
        if (v->after == A_NONE)
            c += e->pools[v->pool].cost;
    }
    return c;
}

/* Past the budget, the least important voices fade out to be stolen or
 * made virtual. */
static void enforce_budget(wdrt_engine *e) {
    double c = running_cost(e);
    while (c > e->budget) {
        int w = -1;
        for (int i = 0; i < e->nactive; i++) {
            const inst *v = &e->inst[e->active[i]];
            if (v->after != A_NONE || v->age < GRACE_BLOCKS)
                continue;
            if (w < 0 || more_important(&e->inst[w], e->inst[w].level, v, v->level))
                w = e->active[i];
        }
        if (w < 0)
            return;
        inst *v = &e->inst[w];
        const pool *p = &e->pools[v->pool];
        if (p->cfg.virtualize || p->cfg.owned) {
            v->vest = v->level;
            v->vdec = v->last > 0 && v->level < v->last ? v->level / v->last : 1;
            fade_out(e, v, A_VIRTUAL);
            e->s.virtualized++;
        } else {
            fade_out(e, v, A_FREE);
            e->s.steals++;
        }
        c -= p->cost;
    }
}

/* Virtual voices: their level is followed as it was falling; those that
 * fall silent end, and the most important come back while the budget has
 * room. */
static void revive(wdrt_engine *e) {
    for (int i = 0; i < e->nvirt;) {
        int k = e->virt[i];
        inst *v = &e->inst[k];
        const pool *p = &e->pools[v->pool];
        v->vest *= v->vdec;
        if (v->vest < p->cfg.quiet) {
            e->virt[i] = e->virt[--e->nvirt];
            if (p->cfg.owned)
                v->mode = M_ASLEEP;
            else
                rest(e, v);
            continue;
        }
        i++;
    }
    double c = running_cost(e);
    for (;;) {
        int w = -1, wi = -1;
        for (int i = 0; i < e->nvirt; i++) {
            const inst *v = &e->inst[e->virt[i]];
            if (c + e->pools[v->pool].cost > e->budget && e->budget > 0)
                continue;
            if (w < 0 || more_important(v, v->vest, &e->inst[w], e->inst[w].vest))
                w = e->virt[i], wi = i;
        }
        if (w < 0)
            return;
        inst *v = &e->inst[w];
        e->virt[wi] = e->virt[--e->nvirt];
        v->mode = M_AWAKE;
        v->fade.v = 0;
        ramp_to(&v->fade, 1, e->B);
        v->level = v->vest;
        v->age = GRACE_BLOCKS;
        activate(e, w);
        e->s.revived++;
        c += e->pools[v->pool].cost;
    }
}

static void end_block(wdrt_engine *e) {
    for (int i = 0; i < e->nactive; i++) {
        inst *v = &e->inst[e->active[i]];
        if (e->excite && e->pwake[v->pool]) { /* excited: its floor is what it holds, as after a strike */
            double E = cls_of(e, v)->energy(v->st);
            v->eref = E > v->eref ? E : v->eref;
        }
        v->last = v->level;
        double pk = e->pools[v->pool].cfg.placed ? v->peak * v->sgain : v->peak; /* what arrives */
        v->level = pk > v->level * e->rel ? pk : v->level * e->rel;
        v->age++;
    }
    if (e->sleep)
        sleep_quiet(e);
    if (e->budget > 0) {
        enforce_budget(e);
        revive(e);
    }
    for (int i = 0; i < e->nactive; i++)
        e->inst[e->active[i]].peak = 0;
    e->s.cost_ns = running_cost(e);
}

/* The excitations phase: the hook computes what excites the sources this
 * block (bodies touching, struck); the voices of the pools it names wake
 * from sleep at the block's start. */
static void excite(wdrt_engine *e, uint64_t t0, int nb) {
    memset(e->pwake, 0, (size_t)e->npools);
    e->excite(e->excite_user, t0, nb, e->pwake);
    for (int p = 0; p < e->npools; p++) {
        if (!e->pwake[p])
            continue;
        for (int k = e->pools[p].first; k < e->pools[p].first + e->pools[p].cfg.voices; k++) {
            wake(e, k, 0);
            e->inst[k].quiet = 0;
        }
    }
}

void wdrt_engine_process(wdrt_engine *e, double *out, uint32_t nframes) {
    if (!e || (!out && nframes))
        return;
    uint32_t done = 0;
    while (done < nframes) {
        uint64_t t0 = e->time;
        uint64_t grid = (t0 / (uint64_t)e->B + 1) * (uint64_t)e->B;
        int nb = (int)(grid - t0 < nframes - done ? grid - t0 : nframes - done);
        drain(e);
        resolve(e, t0, nb);
        wake_inputs(e, (int)done, nb);
        if (e->excite)
            excite(e, t0, nb);
        memset(e->mix, 0, sizeof(double) * (size_t)nb * (size_t)e->nch);
        render_active(e, t0, nb, (int)done);
        space_mix(e, t0, nb);
        for (int i = 0; i < e->nblk; i++) /* the designs this span applied go back to the producer */
            if (e->blk[i].type == EV_DESIGN)
                __atomic_store_n(&e->dbusy[e->blk[i].n], 0, __ATOMIC_RELEASE);
        for (int i = 0; i < e->ntouched; i++)
            e->pools[e->touched[i]].chain = e->pools[e->touched[i]].tail = -1;
        e->ntouched = 0;
        if (t0 + (uint64_t)nb == grid)
            end_block(e);
        compact(e);
        memcpy(out + (size_t)done * (size_t)e->nch, e->mix, sizeof(double) * (size_t)nb * (size_t)e->nch);
        __atomic_store_n(&e->time, t0 + (uint64_t)nb, __ATOMIC_RELEASE);
        done += (uint32_t)nb;
    }
    for (int i = 0; i < e->ninputs; i++) { /* bound for one call */
        inst *v = &e->inst[e->inputs[i]];
        for (int j = 0; j < cls_of(e, v)->n_inputs; j++)
            v->in[j] = NULL;
        v->hasin = 0;
    }
    e->ninputs = 0;
}

void wdrt_engine_get_stats(const wdrt_engine *e, wdrt_engine_stats *s) {
    if (!e || !s)
        return;
    *s = e->s;
    s->frames = e->time;
    s->awake = e->nactive;
    s->fading = s->asleep = s->free = 0;
    for (int i = 0; i < e->nactive; i++) {
        const inst *v = &e->inst[e->active[i]];
        s->fading += v->after != A_NONE || v->fade.left > 0;
    }
    for (int i = 0; i < e->ninst; i++) {
        s->asleep += e->inst[i].mode == M_ASLEEP;
        s->free += e->inst[i].mode == M_FREE && !e->inst[i].spare;
    }
    s->virtual_ = e->nvirt;
}

double wdrt_engine_pool_cost(const wdrt_engine *e, int pool) {
    return e && pool >= 0 && pool < e->npools ? e->pools[pool].cost : 0;
}
