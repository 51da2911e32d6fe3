/*
 * tt.h - timbre trees: parameterised sounds as functional expressions,
 * after Hahn et al.'s timbre trees, with the aesthetic mix nodes of Tong
 * and Wong.  Internal to libwdrt: not part of the public API.
 *
 * Three stages, none of them on the audio path:
 *
 *   1. Reading (tt_read.c): S-expressions (sexp.h) become trees of
 *      tt_node.  Names are resolved (params, functions, `use` of named
 *      trees, `t`, `fs`), arities and literal kinds checked, every error
 *      at FILE:LINE:COL with the nearest known name.
 *   2. Checking (tt_check, tt_read.c): every node gets its width (1: a
 *      scalar, N: a vector of N; arithmetic broadcasts a scalar over a
 *      vector, vectors of different widths do not mix) and its rate
 *      (a constant, a control value that changes only when params do, or
 *      audio that changes every sample).  Trees built by programs (the
 *      genetic explorer) are checked the same way.
 *   3. Compiling (tt_comp.c): a checked tree becomes a flat program of
 *      block instructions over registers: constants folded, control
 *      values computed once per block, audio computed a block at a time,
 *      sines and exponentials of time turned into recurrences.  A class
 *      (tt_class) wraps a program as a voice class (wdvoice.h) at one
 *      sample rate, so an engine hosts trees like compiled voices; its
 *      process (tt_run.c) never allocates.
 *
 * Memory: trees (tt_node) are malloc'ed node by node, freed by
 * tt_node_free; files, programs and classes by their free functions.
 * Nothing is global.
 */
#ifndef WDRT_TT_H
#define WDRT_TT_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "sexp.h"
#include "wdvoice.h"

#if defined(__GNUC__)
#define TT_HIDDEN __attribute__((visibility("hidden")))
#else
#define TT_HIDDEN
#endif

#define TT_BLOCK 64         /* frames an instruction runs at once */
#define TT_MAX_WIDTH 4096   /* elements of a vector */
#define TT_MAX_DEPTH 200    /* nesting of a tree (after `use` is expanded) */
#define TT_MAX_NODES 100000 /* nodes of a tree (after `use` is expanded) */
#define TT_MAX_PARAMS 64
#define TT_MAX_DELAY 60.0   /* s a delay may hold */
#define TT_MAX_SPEED 8.0    /* energetic replays at most this fast */

/* ---- operations ---- */

typedef enum tt_op {
    /* atoms */
    TT_NUM,     /* v: the value */
    TT_PARAM,   /* v: the param's index, s: its name */
    TT_T,       /* seconds since the tree started */
    TT_FS,      /* the sample rate */
    /* arithmetic: broadcast over vectors */
    TT_ADD,     /* (+ A B ...) */
    TT_SUB,     /* (- A) negates; (- A B ...) subtracts the rest from A */
    TT_MUL,     /* (* A B ...) */
    TT_DIV,     /* (/ A B) */
    TT_POW,     /* (pow A B) */
    TT_MIN,     /* (min A B ...) */
    TT_MAX,     /* (max A B ...) */
    TT_EXP, TT_LOG, TT_SQRT, TT_ABS, TT_SIN, TT_COS, TT_FLOOR, TT_TANH,
    TT_DAMP,    /* exp(-X) */
    /* waveforms of a phase in cycles */
    TT_SINE,    /* sin(2 pi X) */
    TT_SAW,     /* 2 frac(X + 1/2) - 1: 0 at X = 0, rising */
    TT_SQUARE,  /* 1 for frac(X) < 1/2, else -1 */
    TT_TRIANGLE,/* 1 - 4 |frac(X + 1/4) - 1/2|: 0 at X = 0, rising */
    /* generators and state */
    TT_OSC,     /* (osc F [SHAPE]): v = shape (TT_SHAPE_*), band-limited */
    TT_NOISE,   /* (noise): white, uniform in [-1, 1] */
    TT_PNOISE,  /* (pnoise X [Y]): Perlin gradient noise, 1-D or 2-D */
    TT_SAMPLE,  /* (sample "f.wav" [RATE]): s = the file (resolved) */
    TT_INTEGRAL,/* (integral X): the running integral of X, in X times seconds */
    TT_ENV,     /* (env (T V) ...): k = T0 V0 T1 V1 ..., nk = 2 x keys */
    TT_DELAY,   /* (delay X SECONDS [MAX]): v = MAX s (0: SECONDS is a constant) */
    TT_LOWPASS, TT_HIGHPASS, TT_BANDPASS, /* (F X FREQ [Q]), biquads */
    TT_RESON,   /* (reson X F T60): a two-pole resonator, unit sine response */
    /* vectors */
    TT_VECTOR,  /* (vector A B ...): widths add up */
    TT_RVECTOR, /* (rvector LO N HI): v = N, args LO and HI */
    TT_COMBINE, /* (combine V): the sum of V's elements */
    /* a compiled netlist */
    TT_VOICE,   /* (voice "f.wdn" (in X...) (param P X)...): s = the netlist,
                   nin inputs first, then params named pn[] */
    /* mix nodes (Tong and Wong) */
    TT_IMPORTANCE,     /* (importance (X W [lock])...): args X0 W0 X1 W1 ...,
                          k[i] = 1 if entry i is locked, nk = entries */
    TT_INVIMPORTANCE,  /* (inverse-importance TIME [(from T0)] (X W [lock])...):
                          args TIME T0 X0 W0 ...; k as for importance */
    TT_ENERGETIC,      /* (energetic X SPEED) */
    TT_SPUTTER,        /* (sputter X F0 F1 DUR) */
    TT_NOPS
} tt_op;

enum { TT_SHAPE_SINE, TT_SHAPE_SAW, TT_SHAPE_SQUARE, TT_SHAPE_TRIANGLE };

/* Rates, ordered: a node is at least as fast as its fastest argument. */
enum { TT_CONST, TT_CONTROL, TT_AUDIO };

/* What each operation is: its name as written, the arguments it takes
 * (max -1: any number), and flags. */
enum {
    TT_F_STATE = 1,  /* keeps state from sample to sample: audio rate */
    TT_F_SPECIAL = 2,/* written in a form of its own (not (NAME ARG...)) */
};
typedef struct tt_opinfo {
    const char *name;
    int min, max;
    unsigned flags;
} tt_opinfo;
TT_HIDDEN extern const tt_opinfo tt_ops[TT_NOPS];

/* ---- trees ---- */

typedef struct tt_node {
    tt_op op;
    int n;                 /* arguments */
    struct tt_node **a;    /* [n] */
    double v;              /* see the ops */
    char *s;               /* see the ops */
    double *k;             /* see the ops */
    int nk;
    char **pn;             /* TT_VOICE: [n - nin] param names */
    char *use;             /* the tree a (use NAME ...) expanded here, or NULL:
                              schematics draw it as one box */
    int nin;               /* TT_VOICE: inputs */
    /* where it was written: doc NULL for nodes a program made */
    const sx_doc *doc;
    int line, col;
    /* set by tt_check */
    int width;             /* 1, or the vector's length */
    int rate;              /* TT_CONST, TT_CONTROL or TT_AUDIO */
} tt_node;

/* A named tree: its params with defaults, and its expression. */
typedef struct tt_tree {
    char *name;            /* "" for a bare expression */
    int nparams;
    char **pname;          /* [nparams] */
    double *pdef;          /* [nparams] defaults */
    double *pmin, *pmax;   /* [nparams] ranges (default -1e300 .. 1e300) */
    tt_node *root;
} tt_tree;

TT_HIDDEN tt_node *tt_node_new(tt_op op, int n);          /* args zeroed; NULL: out of memory */
TT_HIDDEN tt_node *tt_node_clone(const tt_node *x);       /* deep; NULL: out of memory */
TT_HIDDEN void tt_node_free(tt_node *x);
TT_HIDDEN int tt_node_count(const tt_node *x);
TT_HIDDEN int tt_node_depth(const tt_node *x);
TT_HIDDEN int tt_node_has(const tt_node *x, tt_op op); /* x or a node under it is op */
/* Writes the tree as an expression that reads back to the same tree
 * (numbers in the shortest text that reads back to the same double). */
TT_HIDDEN void tt_print(FILE *f, const tt_node *x);
/* A whole definition: (tree NAME (params (P DEFAULT)...) EXPR). */
TT_HIDDEN void tt_print_tree(FILE *f, const tt_tree *t);

/* Writes the tree's nodes and edges as Graphviz statements (no graph
 * header): node names start with `prefix`; returns the root's name in
 * root (at least 64 bytes). */
TT_HIDDEN void tt_dot(FILE *f, const tt_node *x, const char *prefix, char *root);

TT_HIDDEN tt_tree *tt_tree_clone(const tt_tree *t);
TT_HIDDEN void tt_tree_free(tt_tree *t);

/* Sets width and rate of every node of t->root and checks kinds (widths
 * that do not broadcast, a vector where a scalar is needed, an audio
 * value where a constant is needed, params out of range).  Returns 0, or
 * -1 with "FILE:LINE:COL: error: MESSAGE" (or "tree: error: MESSAGE" for
 * nodes made by programs) in err. */
TT_HIDDEN int tt_check(tt_tree *t, char *err, size_t errlen);

/* ---- files ---- */

/* The trees of a .tt file (or a scene's inline text): definitions
 * `(tree NAME (params (P DEFAULT [MIN MAX])...) EXPR)`, `(include
 * "f.tt")` of more definitions, and at most one bare expression.  `(use
 * NAME (P EXPR)...)` expands a definition of the file, of a file it
 * includes, or of `lib/NAME.tt` next to it. */
typedef struct tt_file tt_file;

/* Reads and checks every tree of the file `path` (text NULL: read from
 * disk).  NULL with the error in err. */
TT_HIDDEN tt_file *tt_file_read(const char *path, const char *text, size_t len, char *err, size_t errlen);
TT_HIDDEN void tt_file_free(tt_file *f);
TT_HIDDEN int tt_file_ntrees(const tt_file *f);
/* Tree i, in the order written; -1: the last (what `wdrt tree` renders). */
TT_HIDDEN const tt_tree *tt_file_tree(const tt_file *f, int i);
TT_HIDDEN const tt_tree *tt_file_find(const tt_file *f, const char *name);

/* A tree written inline in a scene: EXPR, or (use NAME (P EXPR)...), or
 * a string naming a .tt file (its last tree).  `params` lists the names a
 * scene may set (the params of a used tree come with it; the names of
 * `(param P V)` properties of an inline expression are its params).
 * Definitions and includes come from `defs` (may be NULL); relative
 * paths from `dir`.  Its docs must outlive the tree. */
TT_HIDDEN tt_tree *tt_tree_inline(tt_file *defs, const sx_doc *d, const sx *expr, const char *dir,
                                  int nparams, const char *const *pnames, const double *pdefs,
                                  char *err, size_t errlen);
/* Reads definitions (tree and include forms) found in a scene doc into
 * defs (made if *defs is NULL).  Returns 0 or -1 with err. */
TT_HIDDEN int tt_file_add_form(tt_file **defs, const sx_doc *d, const sx *form, const char *dir,
                               char *err, size_t errlen);

/* Parses one expression from text (for `wdrt tree '(EXPR)'` and tests):
 * a tree with no params except those named in `(param ...)`-free form:
 * unknown names are errors.  The doc stays with the file. */
TT_HIDDEN tt_file *tt_file_from_string(const char *text, char *err, size_t errlen);

/* ---- programs and classes ---- */

typedef struct tt_prog tt_prog;

/* Compiles a checked tree (a copy is kept).  NULL with err on failure (a
 * sample file that cannot be read, out of memory). */
TT_HIDDEN tt_prog *tt_compile(const tt_tree *t, char *err, size_t errlen);
TT_HIDDEN void tt_prog_free(tt_prog *p);
/* Netlists its voice nodes name; each must be given its class before a
 * class of the program is made. */
TT_HIDDEN int tt_prog_nvoices(const tt_prog *p);
TT_HIDDEN const char *tt_prog_voice_path(const tt_prog *p, int k);
TT_HIDDEN int tt_prog_bind_voice(tt_prog *p, int k, const wdv_class *cls, char *err, size_t errlen);
/* Instructions (after folding) and registers, for benches and tests. */
TT_HIDDEN int tt_prog_ninstr(const tt_prog *p);
/* The tree's time beyond which it is silent for good (an env that ends at
 * 0, a sample that ends), or HUGE_VAL. */
TT_HIDDEN double tt_prog_end(const tt_prog *p);

/* A program as a voice class at one sample rate: no inputs, one output
 * ("out"), the tree's params.  Its states must be bound (tt_class_bind)
 * after init: an engine does so through wdrt_pool_config.bind with data =
 * the tt_class. */
typedef struct tt_class {
    wdv_class cls;
    const tt_prog *prog;
    double fs;
    wdv_param *params;
    size_t layout[4];      /* private: offsets of the state's parts */
    size_t *stoff;         /* private: offsets of the instructions' states */
} tt_class;

TT_HIDDEN int tt_class_init(tt_class *c, const tt_prog *p, double fs, char *err, size_t errlen);
TT_HIDDEN void tt_class_uninit(tt_class *c);
TT_HIDDEN void tt_class_bind(void *state, const void *tt_class_ptr);

/* Renders n frames of the tree from its start into out at fs, with
 * params (NULL: defaults).  Allocates a state; returns 0 or -1 with err. */
TT_HIDDEN int tt_render(const tt_prog *p, double fs, const double *params, double *out, long n, char *err,
                        size_t errlen);
/* The same handed to sink in runs of at most 4096 frames as they are
 * rendered, none kept; a non-zero return from sink stops it (-1). */
TT_HIDDEN int tt_render_to(const tt_prog *p, double fs, const double *params, long n,
                           int (*sink)(const double *y, long n, void *user), void *user, char *err, size_t errlen);

/* The i-th of rvector's n values spread over [0, 1): stratified (one in
 * each of n equal cells), pseudo-random within its cell, the same for the
 * same n.  (rvector LO N HI) is LO + (HI - LO) * tt_rvector_u(N, i). */
TT_HIDDEN double tt_rvector_u(int n, int i);
/* Perlin gradient noise at x (1-D) and at (x, y); 0 at integers. */
TT_HIDDEN double tt_pnoise1(double x);
TT_HIDDEN double tt_pnoise2(double x, double y);
/* The weights of an importance node: w[n] in, locked[n] flags; out[n]
 * sums to one (see tt_run.c). */
TT_HIDDEN void tt_importance(int n, const double *w, const double *locked, double *out);

#endif
