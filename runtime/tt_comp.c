/*
 * tt_comp.c - timbre trees compiled into flat block programs
 * (tt_prog.h), and programs made into voice classes.
 *
 * Compiling walks the checked tree once, post-order, and emits an
 * instruction per node at the node's rate:
 *   - constants fold: an instruction whose arguments are all constant
 *     runs once, here, and becomes a constant register;
 *   - control values (params and what depends on them only) run once per
 *     block;
 *   - audio runs a block of frames at a time.
 * Sines and exponentials of an argument that is affine in time (s t + o
 * with s and o control values, as in the modes of a struck body) become
 * recurrences: a rotation or a multiplication per sample, re-anchored
 * exactly at the start of every block.  Registers of audio temporaries
 * are reused once read.
 *
 * The liveness of a tree (how long it may still sound: an env that ends
 * at zero, a sample that ends, a decaying exponential of time) is worked
 * out here too; the class reports it as the tree's energy, so an engine
 * lets a finished tree sleep and never a tree that is only pausing.
 */
#include "tt_prog.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "wdrt.h"

typedef struct cc {
    tt_prog *P;
    int seg;
    int *freelist;  /* audio registers free for reuse */
    int nfree;
    char *err;
    size_t errlen;
    int oom;
} cc;

static void *grow(void *p, size_t n, size_t sz, int *oom) {
    void *q = realloc(p, sz * (n + 1));
    if (!q)
        *oom = 1;
    return q ? q : p;
}

static int new_reg(cc *c, int w, int rate) {
    tt_prog *P = c->P;
    if (rate == TT_AUDIO)
        for (int i = 0; i < c->nfree; i++)
            if (P->regs[c->freelist[i]].w == w) {
                int r = c->freelist[i];
                c->freelist[i] = c->freelist[--c->nfree];
                return r;
            }
    tt_reg *nr = grow(P->regs, (size_t)P->nregs, sizeof *P->regs, &c->oom);
    P->regs = nr;
    if (c->oom)
        return 0;
    tt_reg *r = &P->regs[P->nregs];
    r->w = w;
    r->rate = rate;
    if (rate == TT_CONST) {
        double *cd = realloc(P->cdata, sizeof(double) * (P->ncdata + (size_t)w));
        if (!cd) {
            c->oom = 1;
            return 0;
        }
        P->cdata = cd;
        r->off = P->ncdata;
        memset(cd + P->ncdata, 0, sizeof(double) * (size_t)w);
        P->ncdata += (size_t)w;
    } else {
        r->off = P->nrdata;
        P->nrdata += (size_t)w * (rate == TT_AUDIO ? TT_BLOCK : 1);
    }
    return P->nregs++;
}

/* Gives back a temporary the instruction just read. */
static void release(cc *c, int r) {
    tt_prog *P = c->P;
    if (P->regs[r].rate != TT_AUDIO)
        return;
    for (int i = 0; i < c->nfree; i++)
        if (c->freelist[i] == r)
            return;
    int *f = grow(c->freelist, (size_t)c->nfree, sizeof *f, &c->oom);
    c->freelist = f;
    if (!c->oom)
        c->freelist[c->nfree++] = r;
}

/* Emits kernel k over args; returns its register. */
static int emit(cc *c, int k, int rate, int w, const int *args, int na, const tt_node *x, double v) {
    tt_prog *P = c->P;
    if (c->oom)
        return 0;
    int dst = new_reg(c, w, rate);
    tt_ins *ni = grow(P->ins, (size_t)P->nins, sizeof *P->ins, &c->oom);
    P->ins = ni;
    if (c->oom)
        return 0;
    tt_ins *I = &P->ins[P->nins];
    memset(I, 0, sizeof *I);
    I->k = k, I->rate = rate, I->seg = c->seg, I->dst = dst, I->na = na, I->x = x, I->v = v;
    I->data = -1, I->child = -1;
    if (na > 8) {
        int *xa = realloc(P->xargs, sizeof(int) * ((size_t)P->nxargs + (size_t)na + 1));
        if (!xa) {
            c->oom = 1;
            return 0;
        }
        P->xargs = xa;
        if (P->nxargs == 0)
            P->nxargs = 1; /* ax 0 means "in a[]" */
        I->ax = P->nxargs;
        memcpy(P->xargs + P->nxargs, args, sizeof(int) * (size_t)na);
        P->nxargs += na;
    } else if (na > 0) {
        memcpy(I->a, args, sizeof(int) * (size_t)na);
    }
    P->nins++;
    if (rate == TT_CONST) {
        tt_run_const(P, I);
        P->nins--; /* folded: only its register stays */
    }
    for (int i = 0; i < na; i++)
        if (args[i] != dst)
            release(c, args[i]);
    return dst;
}

static int rate_of(const cc *c, int r) { return c->P->regs[r].rate; }

static int const_reg(cc *c, double v) {
    int r = new_reg(c, 1, TT_CONST);
    if (!c->oom)
        c->P->cdata[c->P->regs[r].off] = v;
    return r;
}

static int comp(cc *c, const tt_node *x);

/* ---- affine arguments: s t + o with s and o control values ---- */

static int affine(const tt_node *x) {
    if (x->rate <= TT_CONTROL || x->op == TT_T)
        return 1;
    int audio = 0;
    switch (x->op) {
    case TT_ADD:
    case TT_SUB:
        for (int i = 0; i < x->n; i++)
            if (!affine(x->a[i]))
                return 0;
        return 1;
    case TT_MUL:
        for (int i = 0; i < x->n; i++)
            if (x->a[i]->rate == TT_AUDIO) {
                if (audio++ || !affine(x->a[i]))
                    return 0;
            }
        return 1;
    case TT_DIV:
        return x->a[1]->rate <= TT_CONTROL && affine(x->a[0]);
    default:
        return 0;
    }
}

static int rate2(cc *c, int a, int b) {
    int ra = rate_of(c, a), rb = rate_of(c, b);
    return ra > rb ? ra : rb;
}

static int wid2(cc *c, int a, int b) {
    int wa = c->P->regs[a].w, wb = c->P->regs[b].w;
    return wa > wb ? wa : wb;
}

static int bin(cc *c, int op, int a, int b) {
    int args[2] = {a, b};
    return emit(c, op, rate2(c, a, b), wid2(c, a, b), args, 2, NULL, 0);
}

/* The slope s and offset o of affine x (registers). */
static void affine_parts(cc *c, const tt_node *x, int *s, int *o) {
    if (x->op == TT_T) {
        *s = const_reg(c, 1), *o = const_reg(c, 0);
        return;
    }
    if (x->rate <= TT_CONTROL) {
        *s = const_reg(c, 0), *o = comp(c, x);
        return;
    }
    int s0, o0;
    switch (x->op) {
    case TT_ADD:
    case TT_SUB:
        affine_parts(c, x->a[0], s, o);
        if (x->op == TT_SUB && x->n == 1) {
            int z = const_reg(c, 0);
            *s = bin(c, TT_SUB, z, *s);
            *o = bin(c, TT_SUB, const_reg(c, 0), *o);
            return;
        }
        for (int i = 1; i < x->n; i++) {
            affine_parts(c, x->a[i], &s0, &o0);
            *s = bin(c, x->op, *s, s0);
            *o = bin(c, x->op, *o, o0);
        }
        return;
    case TT_MUL: {
        int k = -1, f = -1;
        for (int i = 0; i < x->n; i++) {
            if (x->a[i]->rate == TT_AUDIO) {
                k = i;
                continue;
            }
            int r = comp(c, x->a[i]);
            f = f < 0 ? r : bin(c, TT_MUL, f, r);
        }
        affine_parts(c, x->a[k], s, o);
        if (f >= 0) {
            /* f is read twice: keep it from the free list until both are made */
            *s = bin(c, TT_MUL, *s, f);
            *o = bin(c, TT_MUL, *o, f);
        }
        return;
    }
    case TT_DIV: {
        int d = comp(c, x->a[1]);
        affine_parts(c, x->a[0], s, o);
        *s = bin(c, TT_DIV, *s, d);
        *o = bin(c, TT_DIV, *o, d);
        return;
    }
    default:
        *s = const_reg(c, 0), *o = comp(c, x);
        return;
    }
}

/* ---- the tree ---- */

static int new_seg(cc *c) {
    tt_prog *P = c->P;
    int *so = grow(P->segout, (size_t)P->nseg, sizeof *so, &c->oom);
    P->segout = so;
    if (c->oom)
        return 0;
    P->segout[P->nseg] = -1;
    return P->nseg++;
}

static int add_sample(cc *c, const tt_node *x) {
    tt_prog *P = c->P;
    for (int i = 0; i < P->nsamples; i++)
        if (!strcmp(P->samples[i].path, x->s))
            return i;
    tt_sample *ns = grow(P->samples, (size_t)P->nsamples, sizeof *ns, &c->oom);
    P->samples = ns;
    if (c->oom)
        return -1;
    tt_sample *s = &P->samples[P->nsamples];
    memset(s, 0, sizeof *s);
    int nch;
    double *fr;
    long n;
    if (wdrt_wav_read(x->s, &nch, &s->fs, &fr, &n) != WDRT_OK) {
        if (x->doc)
            sx_error_at(x->doc, x->line, x->col, c->err, c->errlen, "cannot read the sound file '%s'", x->s);
        else
            snprintf(c->err, c->errlen, "%s: error: cannot read the sound file\n", x->s);
        return -2;
    }
    s->x = malloc(sizeof(double) * (size_t)(n > 0 ? n : 1));
    s->path = malloc(strlen(x->s) + 1);
    if (!s->x || !s->path) {
        free(s->x), free(s->path), free(fr);
        c->oom = 1;
        return -1;
    }
    strcpy(s->path, x->s);
    for (long i = 0; i < n; i++) {
        double m = 0;
        for (int ch = 0; ch < nch; ch++)
            m += fr[i * nch + ch];
        s->x[i] = m / nch;
    }
    free(fr);
    s->n = n;
    return P->nsamples++;
}

static int add_voice(cc *c, const tt_node *x) {
    tt_prog *P = c->P;
    tt_vslot *nv = grow(P->voices, (size_t)P->nvoices, sizeof *nv, &c->oom);
    P->voices = nv;
    if (c->oom)
        return -1;
    tt_vslot *v = &P->voices[P->nvoices];
    v->cls = NULL;
    if (!(v->path = malloc(strlen(x->s) + 1))) {
        c->oom = 1;
        return -1;
    }
    strcpy(v->path, x->s);
    return P->nvoices++;
}

static int comp(cc *c, const tt_node *x) {
    tt_prog *P = c->P;
    if (c->oom)
        return 0;
    switch (x->op) {
    case TT_NUM:
        return const_reg(c, x->v);
    case TT_PARAM:
        return P->param_reg[(int)x->v];
    case TT_FS:
        if (P->fs_reg < 0)
            P->fs_reg = new_reg(c, 1, TT_CONTROL);
        return P->fs_reg;
    case TT_T:
        return emit(c, TT_T, TT_AUDIO, 1, NULL, 0, x, 0);
    case TT_COMBINE:
    case TT_MUL: {
        /* a mode: a sine of time times a decay of time, one decaying
         * rotation; and the sum of such modes without storing each */
        const tt_node *m = x->op == TT_COMBINE ? x->a[0] : x;
        if (m->op == TT_MUL && m->n == 2) {
            const tt_node *sn = m->a[0], *dm = m->a[1];
            if (sn->op == TT_DAMP || sn->op == TT_EXP)
                sn = x->a[1], dm = x->a[0];
            if ((sn->op == TT_SINE || sn->op == TT_SIN) && (dm->op == TT_DAMP || dm->op == TT_EXP) &&
                sn->a[0]->rate == TT_AUDIO && affine(sn->a[0]) && dm->a[0]->rate == TT_AUDIO && affine(dm->a[0])) {
                int so[4];
                affine_parts(c, sn->a[0], &so[0], &so[1]);
                affine_parts(c, dm->a[0], &so[2], &so[3]);
                int r = emit(c, x->op == TT_COMBINE ? K_MODESUM : K_DSINREC, TT_AUDIO, x->width, so, 4, x,
                             sn->op == TT_SINE ? 1 : 1 / (2 * M_PI));
                if (!c->oom)
                    P->ins[P->nins - 1].v2 = dm->op == TT_DAMP ? -1 : 1;
                return r;
            }
        }
        break;
    }
    case TT_SINE:
    case TT_SIN:
    case TT_COS:
    case TT_DAMP:
    case TT_EXP:
        if (x->a[0]->rate == TT_AUDIO && affine(x->a[0])) {
            int so[2];
            affine_parts(c, x->a[0], &so[0], &so[1]);
            int k = x->op == TT_COS ? K_COSREC : x->op == TT_DAMP || x->op == TT_EXP ? K_EXPREC : K_SINREC;
            double v = x->op == TT_SINE ? 1 : x->op == TT_DAMP ? -1 : x->op == TT_EXP ? 1 : 1 / (2 * M_PI);
            return emit(c, k, TT_AUDIO, x->width, so, 2, x, v);
        }
        break;
    case TT_ENERGETIC: {
        /* the child runs in the middle of the parent's instruction: its
         * registers are its own (a free list of its own, dropped after),
         * and the speed is made before it */
        int sp = comp(c, x->a[1]);
        int parent = c->seg, child = new_seg(c), *pfree = c->freelist, pnfree = c->nfree;
        c->freelist = NULL, c->nfree = 0;
        c->seg = child;
        int out = comp(c, x->a[0]);
        if (!c->oom && rate_of(c, out) != TT_AUDIO) { /* a segment's output is audio */
            int a1[1] = {out};
            out = emit(c, K_COPY, TT_AUDIO, x->a[0]->width, a1, 1, x, 0);
        }
        free(c->freelist);
        c->freelist = pfree, c->nfree = pnfree;
        c->seg = parent;
        if (c->oom)
            return 0;
        P->segout[child] = out;
        int r = emit(c, TT_ENERGETIC, TT_AUDIO, x->width, &sp, 1, x, 0);
        if (!c->oom)
            P->ins[P->nins - 1].child = child;
        return r;
    }
    default:
        break;
    }
    int stack[16], *args = x->n <= 16 ? stack : malloc(sizeof(int) * (size_t)x->n);
    if (!args) {
        c->oom = 1;
        return 0;
    }
    int rate = TT_CONST;
    for (int i = 0; i < x->n; i++) {
        args[i] = comp(c, x->a[i]);
        if (c->oom)
            break;
        rate = rate_of(c, args[i]) > rate ? rate_of(c, args[i]) : rate;
    }
    int r = 0;
    if (c->oom)
        goto out;
    if (tt_ops[x->op].flags & TT_F_STATE || x->op == TT_INVIMPORTANCE)
        rate = TT_AUDIO;
    switch (x->op) {
    case TT_ADD:
    case TT_MUL:
    case TT_MIN:
    case TT_MAX:
    case TT_SUB:
        if (x->n == 1) {
            if (x->op != TT_SUB) {
                r = args[0];
                goto out;
            }
            int z = const_reg(c, 0);
            r = bin(c, TT_SUB, z, args[0]);
            goto out;
        }
        r = args[0];
        for (int i = 1; i < x->n; i++)
            r = bin(c, x->op, r, args[i]);
        goto out;
    default:
        break;
    }
    int data = -1;
    if (x->op == TT_SAMPLE && (data = add_sample(c, x)) < 0) {
        if (data == -2) {
            c->oom = 2;
        }
        goto out;
    }
    if (x->op == TT_VOICE && (data = add_voice(c, x)) < 0)
        goto out;
    r = emit(c, x->op, rate, x->width, args, x->n, x, x->v);
    if (!c->oom && data >= 0)
        P->ins[P->nins - 1].data = data;
out:
    if (args != stack)
        free(args);
    return r;
}

/* ---- liveness ---- */

enum { LV_DEAD, LV_DECAY, LV_LIVE };
typedef struct lv {
    int k;
    double t; /* LV_DEAD: silent after t; LV_DECAY: only decaying after t */
} lv;

static lv live(const tt_prog *P, const tt_node *x) {
    lv r = {LV_LIVE, HUGE_VAL}, a;
    switch (x->op) {
    case TT_NUM:
        return x->v == 0 ? (lv){LV_DEAD, 0} : r;
    case TT_ENV:
        return x->k[x->nk - 1] == 0 ? (lv){LV_DEAD, x->k[x->nk - 2]} : r;
    case TT_SAMPLE: /* silent once its position has passed the file's end (and
                     * the interpolator's reach, one frame) at a constant rate */
        for (int i = 0; i < P->nsamples; i++)
            if (!strcmp(P->samples[i].path, x->s)) {
                double rate = x->n == 0 ? 1 : x->a[0]->op == TT_NUM ? x->a[0]->v : -1;
                if (rate > 0)
                    return (lv){LV_DEAD, ((double)P->samples[i].n + 1) / (P->samples[i].fs * rate)};
            }
        return r;
    case TT_DAMP:
    case TT_EXP:
        /* exp(-(s t + o)) with s a positive constant decays */
        if (affine(x->a[0]) && x->a[0]->rate == TT_AUDIO) {
            const tt_node *y = x->a[0];
            int neg = x->op == TT_EXP;
            /* the sign of the slope, when the tree says it plainly */
            if (y->op == TT_T)
                return neg ? r : (lv){LV_DECAY, 0};
            if (y->op == TT_MUL || y->op == TT_DIV) {
                double k = 1;
                int known = 1;
                for (int i = 0; i < y->n; i++)
                    if (y->a[i]->rate == TT_CONST && y->a[i]->op == TT_NUM)
                        k *= (y->op == TT_DIV && i == 1) ? 1 / y->a[i]->v : y->a[i]->v;
                    else if (y->a[i]->rate != TT_AUDIO)
                        known = 0; /* a param: taken as a positive rate (a damping) */
                if (!known || (neg ? k < 0 : k > 0))
                    return (lv){LV_DECAY, 0};
            }
        }
        return r;
    case TT_MUL:
    case TT_DIV: {
        lv best = {LV_LIVE, HUGE_VAL};
        int n = x->op == TT_DIV ? 1 : x->n;
        for (int i = 0; i < n; i++) {
            a = live(P, x->a[i]);
            if (a.k == LV_DEAD && (best.k != LV_DEAD || a.t < best.t))
                best = a;
            else if (a.k == LV_DECAY && best.k == LV_LIVE)
                best = a;
            else if (a.k == LV_DECAY && best.k == LV_DECAY && a.t > best.t)
                best.t = a.t;
        }
        return best;
    }
    case TT_ADD:
    case TT_SUB:
    case TT_VECTOR:
    case TT_COMBINE:
    case TT_IMPORTANCE:
    case TT_INVIMPORTANCE:
    case TT_SPUTTER:
    case TT_LOWPASS:
    case TT_HIGHPASS:
    case TT_BANDPASS:
    case TT_RESON:
    case TT_DELAY: {
        int first = x->op == TT_INVIMPORTANCE ? 2 : 0, step = x->op == TT_IMPORTANCE || x->op == TT_INVIMPORTANCE ? 2 : 1;
        int n = x->op == TT_SPUTTER || x->op == TT_DELAY || x->op == TT_LOWPASS || x->op == TT_HIGHPASS ||
                        x->op == TT_BANDPASS || x->op == TT_RESON
                    ? 1
                    : x->n;
        lv acc = {LV_DEAD, 0};
        for (int i = first; i < n; i += step) {
            a = live(P, x->a[i]);
            if (a.k > acc.k)
                acc.k = a.k;
            if (a.t > acc.t)
                acc.t = a.t;
        }
        if (acc.k == LV_LIVE)
            return r;
        if (x->op == TT_DELAY) {
            double d = x->v > 0 ? x->v : x->a[1]->op == TT_NUM ? x->a[1]->v : TT_MAX_DELAY;
            acc.t += d;
        }
        if (x->op == TT_LOWPASS || x->op == TT_HIGHPASS || x->op == TT_BANDPASS || x->op == TT_RESON ||
            x->op == TT_DELAY)
            acc.k = LV_DECAY; /* rings down after its input ends */
        return acc;
    }
    case TT_ENERGETIC:
        a = live(P, x->a[0]);
        if (a.k != LV_LIVE && x->a[1]->op == TT_NUM && x->a[1]->v > 0) {
            a.t = a.t / x->a[1]->v + (double)SINC_H / 1000.0;
            return a;
        }
        return r;
    default:
        return r;
    }
}

/* ---- programs ---- */

void tt_prog_free(tt_prog *P) {
    if (!P)
        return;
    for (int i = 0; i < P->nsamples; i++)
        free(P->samples[i].x), free(P->samples[i].path);
    for (int i = 0; i < P->nvoices; i++)
        free(P->voices[i].path);
    free(P->samples);
    free(P->voices);
    free(P->ins);
    free(P->xargs);
    free(P->regs);
    free(P->cdata);
    free(P->segout);
    free(P->param_reg);
    free(P->sinc);
    tt_tree_free(P->tree);
    free(P);
}

/* The windowed sinc of the energetic replay: Kaiser, beta 9. */
static double bessel_i0(double x) {
    double s = 1, term = 1;
    for (int k = 1; k < 60; k++) {
        term *= (x / (2 * k)) * (x / (2 * k));
        s += term;
        if (term < 1e-17 * s)
            break;
    }
    return s;
}

static float *sinc_table(void) {
    int n = SINC_H * SINC_RES + 2;
    float *t = malloc(sizeof(float) * (size_t)n);
    if (!t)
        return NULL;
    const double beta = 9.0, i0b = bessel_i0(beta);
    for (int i = 0; i < n; i++) {
        double u = (double)i / SINC_RES, r = u / SINC_H;
        double w = r < 1 ? bessel_i0(beta * sqrt(1 - r * r)) / i0b : 0;
        t[i] = (float)(i == 0 ? 1 : sin(M_PI * u) / (M_PI * u) * w);
    }
    return t;
}

tt_prog *tt_compile(const tt_tree *t, char *err, size_t errlen) {
    tt_prog *P = calloc(1, sizeof *P);
    cc c = {P, 0, NULL, 0, err, errlen, 0};
    if (!P)
        goto oom;
    P->fs_reg = -1;
    if (!(P->tree = tt_tree_clone(t)) || tt_check(P->tree, err, errlen)) {
        if (!P->tree)
            goto oom;
        tt_prog_free(P);
        return NULL;
    }
    if (!(P->param_reg = calloc((size_t)(t->nparams + 1), sizeof *P->param_reg)))
        goto oom;
    for (int i = 0; i < t->nparams; i++)
        P->param_reg[i] = new_reg(&c, 1, TT_CONTROL);
    new_seg(&c);
    int out = comp(&c, P->tree->root);
    if (c.oom == 2) { /* err says why */
        free(c.freelist);
        tt_prog_free(P);
        return NULL;
    }
    if (!c.oom && rate_of(&c, out) != TT_AUDIO) {
        int a1[1] = {out};
        out = emit(&c, K_COPY, TT_AUDIO, 1, a1, 1, P->tree->root, 0);
    }
    if (c.oom)
        goto oom;
    P->segout[0] = out;
    free(c.freelist);
    for (int i = 0; i < P->nins; i++)
        if (P->ins[i].k == TT_ENERGETIC && !P->sinc && !(P->sinc = sinc_table()))
            goto oom;
    lv l = live(P, P->tree->root);
    P->live_until = l.k == LV_LIVE ? HUGE_VAL : l.t;
    return P;
oom:
    free(c.freelist);
    if (err && errlen)
        snprintf(err, errlen, "tree: error: out of memory\n");
    tt_prog_free(P);
    return NULL;
}

int tt_prog_nvoices(const tt_prog *P) { return P ? P->nvoices : 0; }
const char *tt_prog_voice_path(const tt_prog *P, int k) {
    return P && k >= 0 && k < P->nvoices ? P->voices[k].path : NULL;
}
int tt_prog_ninstr(const tt_prog *P) { return P ? P->nins : 0; }
double tt_prog_end(const tt_prog *P) { return P ? P->live_until : HUGE_VAL; }

int tt_prog_bind_voice(tt_prog *P, int k, const wdv_class *cls, char *err, size_t errlen) {
    if (!P || k < 0 || k >= P->nvoices || !cls)
        return -1;
    /* the node's inputs and params must be the voice's */
    for (int i = 0; i < P->nins; i++) {
        const tt_ins *I = &P->ins[i];
        if (I->k != TT_VOICE || I->data != k)
            continue;
        const tt_node *x = I->x;
        if (cls->n_outputs < 1 || x->nin > cls->n_inputs) {
            if (x->doc)
                return sx_error_at(x->doc, x->line, x->col, err, errlen,
                                   "voice %s has %d input%s and %d output%s; the node feeds %d", cls->name,
                                   cls->n_inputs, cls->n_inputs == 1 ? "" : "s", cls->n_outputs,
                                   cls->n_outputs == 1 ? "" : "s", x->nin);
            snprintf(err, errlen, "tree: error: voice %s does not take %d inputs\n", cls->name, x->nin);
            return -1;
        }
        for (int j = 0; j < x->n - x->nin; j++) {
            int found = 0;
            for (int q = 0; q < cls->n_params; q++)
                found |= !strcmp(cls->params[q].name, x->pn[j]);
            if (!found) {
                if (x->doc)
                    return sx_error_at(x->doc, x->line, x->col, err, errlen, "voice %s has no param '%s'",
                                       cls->name, x->pn[j]);
                snprintf(err, errlen, "tree: error: voice %s has no param '%s'\n", cls->name, x->pn[j]);
                return -1;
            }
        }
    }
    P->voices[k].cls = cls;
    return 0;
}

/* ---- classes ---- */

static const wdv_port out_port[1] = {{"out", ""}};

static void c_init(void *state, double fs) {
    tt_state *st = state;
    st->C = NULL;
    st->fs = fs;
}

static void c_reset(void *state) {
    tt_state *st = state;
    if (st->C)
        tt_run_reset(st);
}

static double *param_slot(tt_state *st, int id) {
    const tt_prog *P = st->C->prog;
    return (double *)((char *)st + st->C->layout[L_REGS]) + P->regs[P->param_reg[id]].off;
}

static int c_set_param(void *state, int id, double v) {
    tt_state *st = state;
    if (!st->C || id < 0 || id >= st->C->cls.n_params)
        return -1;
    if (v != v)
        return 0;
    const wdv_param *p = &st->C->params[id];
    *param_slot(st, id) = v < p->min ? p->min : v > p->max ? p->max : v;
    return 0;
}

static double c_get_param(const void *state, int id) {
    tt_state *st = (tt_state *)state;
    if (!st->C || id < 0 || id >= st->C->cls.n_params)
        return 0;
    return *param_slot(st, id);
}

static void c_process(void *state, const double *const *in, double *const *out, int n) {
    (void)in;
    tt_state *st = state;
    if (!st->C) {
        memset(out[0], 0, sizeof(double) * (size_t)(n > 0 ? n : 0));
        return;
    }
    for (int i = 0; i < n; i += TT_BLOCK)
        tt_run_block(st, out[0] + i, n - i < TT_BLOCK ? n - i : TT_BLOCK);
}

static double c_energy(const void *state) { return tt_run_energy(state); }
static double c_work(const void *state) {
    (void)state;
    return 0;
}
static int c_set_ic(void *state, int n, const int *ids, const double *v) {
    (void)state, (void)n, (void)ids, (void)v;
    return -1;
}

void tt_class_bind(void *state, const void *data) {
    tt_state *st = state;
    st->C = data;
    tt_run_init_state(st);
}

static size_t align16(size_t n) { return (n + 15) & ~(size_t)15; }

int tt_class_init(tt_class *c, const tt_prog *P, double fs, char *err, size_t errlen) {
    memset(c, 0, sizeof *c);
    if (!P || !(fs >= 1 && fs <= 1e7)) {
        snprintf(err, errlen, "tree: error: bad rate\n");
        return -1;
    }
    for (int k = 0; k < P->nvoices; k++)
        if (!P->voices[k].cls) {
            snprintf(err, errlen, "%s: error: the voice has no class\n", P->voices[k].path);
            return -1;
        }
    const tt_tree *t = P->tree;
    c->prog = P;
    c->fs = fs;
    c->params = calloc((size_t)(t->nparams + 1), sizeof *c->params);
    c->stoff = calloc((size_t)(P->nins + 1), sizeof *c->stoff);
    if (!c->params || !c->stoff) {
        tt_class_uninit(c);
        snprintf(err, errlen, "tree: error: out of memory\n");
        return -1;
    }
    for (int i = 0; i < t->nparams; i++)
        c->params[i] = (wdv_param){t->pname[i], "", t->pdef[i], t->pmin[i], t->pmax[i], 0};
    size_t off = align16(sizeof(tt_state));
    c->layout[L_REGS] = off;
    off = align16(off + sizeof(double) * P->nrdata);
    c->layout[L_SEGF] = off;
    off = align16(off + sizeof(int64_t) * (size_t)P->nseg);
    for (int i = 0; i < P->nins; i++) {
        size_t n = tt_run_state_size(P, &P->ins[i], fs);
        c->stoff[i] = off;
        off = align16(off + n);
    }
    c->layout[L_SIZE] = off;
    wdv_class *k = &c->cls;
    k->name = t->name && t->name[0] ? t->name : "tree";
    k->abi_version = WDV_ABI_VERSION;
    k->precision = 64;
    k->state_size = off;
    k->n_inputs = 0;
    k->n_outputs = 1;
    k->n_params = t->nparams;
    k->outputs = out_port;
    k->params = c->params;
    k->init = c_init;
    k->reset = c_reset;
    k->set_param = c_set_param;
    k->get_param = c_get_param;
    k->process = c_process;
    k->energy = c_energy;
    k->work = c_work;
    k->set_ic = c_set_ic;
    return 0;
}

void tt_class_uninit(tt_class *c) {
    if (!c)
        return;
    free(c->params);
    free(c->stoff);
    c->params = NULL;
    c->stoff = NULL;
}

int tt_render_to(const tt_prog *P, double fs, const double *params, long n,
                 int (*sink)(const double *y, long n, void *user), void *user, char *err, size_t errlen) {
    tt_class c;
    if (tt_class_init(&c, P, fs, err, errlen))
        return -1;
    void *st = NULL;
    double *buf = malloc(sizeof *buf * 4096);
    if (!buf || posix_memalign(&st, 16, align16(c.cls.state_size))) {
        free(buf);
        tt_class_uninit(&c);
        snprintf(err, errlen, "tree: error: out of memory\n");
        return -1;
    }
    c.cls.init(st, fs);
    tt_class_bind(st, &c);
    for (int i = 0; params && i < c.cls.n_params; i++)
        c.cls.set_param(st, i, params[i]);
    int r = 0;
    for (long i = 0; i < n && !r; i += 4096) {
        long k = n - i < 4096 ? n - i : 4096;
        double *o[1] = {buf};
        c.cls.process(st, NULL, o, (int)k);
        if ((r = sink(buf, k, user)))
            snprintf(err, errlen, "tree: error: the rendered frames could not be kept\n");
    }
    free(buf);
    free(st);
    tt_class_uninit(&c);
    return r ? -1 : 0;
}

/* tt_render's sink: the frames into the caller's array, in order. */
static int into_array(const double *y, long n, void *user) {
    double **at = user;
    memcpy(*at, y, sizeof *y * (size_t)n);
    *at += n;
    return 0;
}

int tt_render(const tt_prog *P, double fs, const double *params, double *out, long n, char *err, size_t errlen) {
    double *at = out;
    return tt_render_to(P, fs, params, n, into_array, &at, err, errlen);
}
