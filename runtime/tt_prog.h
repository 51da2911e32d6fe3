/*
 * tt_prog.h - the inside of a compiled timbre tree, shared by the
 * compiler (tt_comp.c) and the kernels that run it (tt_run.c).  Private
 * to those two files.
 *
 * A program is a list of instructions in segments.  Segment 0 is the
 * tree; every energetic node runs its argument as a segment of its own,
 * with its own clock, pulled as far as the replay needs.  An instruction
 * writes one register from registers before it: a constant register
 * (filled at compile time, in the program), a control register (one
 * value per element, computed once per block) or an audio register (a
 * block of TT_BLOCK frames per element, laid out element after element).
 * Registers and the state of stateful instructions live in each
 * instance's state at offsets the program and its class fix, so a state
 * may be copied with memcpy.
 */
#ifndef WDRT_TT_PROG_H
#define WDRT_TT_PROG_H

#include "tt.h"

/* kernels beyond the tree's ops */
enum {
    K_SINREC = TT_NOPS, /* sin(2 pi (s t + o)) by rotation: args s, o; v: cycles per unit (1 or 1/2pi) */
    K_COSREC,           /* cos(...) likewise */
    K_EXPREC,           /* exp(g (s t + o)) by multiplication: args s, o; v: g (-1 damp, 1 exp) */
    K_DSINREC,          /* exp(g (s2 t + o2)) sin(2 pi v (s1 t + o1)): a decaying rotation;
                           args s1, o1, s2, o2; v: cycles per unit, v2: g */
    K_MODESUM,          /* the sum over elements of K_DSINREC: (combine (* (sine ..) (damp ..))) */
    K_COPY,             /* a register copied (a segment's output) */
    K_NKERNELS
};

typedef struct tt_reg {
    int w;          /* elements */
    int rate;       /* TT_CONST: in the program's constants; else in the state */
    size_t off;     /* doubles from the start of the constants or of the state's registers */
} tt_reg;

typedef struct tt_ins {
    int k;          /* TT_* op or K_* kernel */
    int rate;       /* TT_CONTROL: runs once per block; TT_AUDIO: a block of frames */
    int seg;        /* the segment it belongs to */
    int dst;        /* register */
    int na;
    int a[8];       /* argument registers (more in args: see ax) */
    int ax;         /* > 0: the arguments are prog->xargs[ax .. ax + na) */
    const tt_node *x;/* the node (its constants, names, keys); in the program's tree */
    double v, v2;   /* kernel constants */
    int child;      /* TT_ENERGETIC: the segment it replays */
    int data;       /* TT_SAMPLE: the sample; TT_VOICE: the voice */
} tt_ins;

typedef struct tt_sample {
    char *path;
    double *x;      /* mono, n frames */
    long n;
    double fs;
} tt_sample;

typedef struct tt_vslot {
    char *path;
    const wdv_class *cls;
} tt_vslot;

struct tt_prog {
    tt_tree *tree;          /* the tree compiled (a copy) */
    tt_ins *ins;
    int nins;
    int *xargs;
    int nxargs;
    tt_reg *regs;
    int nregs;
    double *cdata;          /* constant registers */
    size_t ncdata;
    size_t nrdata;          /* doubles of state registers */
    int nseg;
    int *segout;            /* [nseg] each segment's output register */
    int *param_reg;         /* [nparams] the control register of each param */
    int fs_reg;             /* the control register of fs, -1: none */
    tt_sample *samples;
    int nsamples;
    tt_vslot *voices;
    int nvoices;
    int nstate;             /* stateful instructions */
    double live_until;      /* t after which only ringing state can sound; HUGE_VAL: always */
    float *sinc;            /* the energetic replay's windowed-sinc table */
};

/* The sinc table: SINC_H zero crossings each side, SINC_RES points per unit. */
#define SINC_H 16
#define SINC_RES 512

/* Layout of an instance's state (offsets in the class's layout[]). */
enum { L_REGS, L_SEGF, L_SIZE };

typedef struct tt_state {
    const tt_class *C;      /* bound class, NULL: silence */
    double fs;
    /* then: registers (doubles), segment frame counters (int64), op states */
} tt_state;

/* tt_run.c */
TT_HIDDEN void tt_run_init_state(tt_state *st);   /* after bind: constants of state, reset */
TT_HIDDEN void tt_run_reset(tt_state *st);
TT_HIDDEN void tt_run_block(tt_state *st, double *out, int n);
TT_HIDDEN double tt_run_energy(const tt_state *st);
/* bytes of op state instruction I needs at fs */
TT_HIDDEN size_t tt_run_state_size(const tt_prog *p, const tt_ins *I, double fs);
/* runs one constant instruction at compile time into p->cdata */
TT_HIDDEN void tt_run_const(const tt_prog *p, const tt_ins *I);

#endif
