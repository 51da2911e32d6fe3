/*
 * gen.h - the internal header of the wdc compiler.
 *
 * The pipeline, one phase per file:
 *
 *   lex.c    netlist text -> tokens (with source positions)
 *   parse.c  tokens -> syntax lines (one Line per netlist line)
 *   elab.c   lines -> Circuit: one flat graph of primitive elements in SI
 *            units (mechanical elements mapped by the mobility analogy),
 *            params, inputs, probes, initial conditions; each line is
 *            lowered by its kind's descriptor in blocks/ (lower.h)
 *   waveguide.c  the order of each waveguide's allpass (wg_choose)
 *   wdf.c    Circuit -> Wdf: an adaptor forest, one root per biconnected
 *            block (series/parallel adaptors found by series-parallel
 *            reduction; the irreducible rest, ideal sources and the
 *            block's nonlinear element gathered into a rigid root)
 *   scatter.c  scattering matrices (LAPACKE) and the losslessness check
 *   emit.c   Wdf -> C text of the voice, through templates/
 *   lv2.c    Wdf -> an LV2 plugin bundle of the voice
 *
 * Memory policy: everything the compiler allocates comes from an arena
 * (zeroed: small pieces carved from chunks, large ones calloc'd) and is
 * released only when the process exits.  Errors in the
 * user's netlist go through error_at(), which prints
 * FILE:LINE:COL: error: MESSAGE, the source line and a caret, and then
 * unwinds to the caller of the phase (see Diag).  Internal failures go
 * through die(), which names the C file and line and exits with status 3.
 */
#ifndef WDC_GEN_H
#define WDC_GEN_H

#include <setjmp.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>

#define WDC_VERSION "0.1.0"

/* util.c */

typedef struct SrcFile SrcFile;
struct SrcFile {
    const char *path;   /* as given or resolved for .include */
    const char *text;   /* whole contents, NUL-terminated */
    SrcFile *includer;  /* file that included this one, or NULL */
    int inc_line;       /* position of the .include line in includer */
    int inc_col;
    bool spice;         /* a SPICE deck (DESIGN 3.1): case folded, '$' comments,
                           'quoted' expressions; the main deck's first line is its title */
};

/* Read every netlist as a SPICE deck (wdc --spice); otherwise a file
 * ending .cir, .sp, .spice or .net is one. */
extern bool spice_always;
bool is_spice_path(const char *path);

typedef struct SrcPos {
    SrcFile *file;
    int line; /* 1-based */
    int col;  /* 1-based, in bytes */
} SrcPos;

/* Where diagnostics go.  A phase entry point sets `jmp` with setjmp; an
 * error longjmps there after printing. */
typedef struct Diag {
    FILE *out;       /* stderr unless a test captures it */
    int errors;
    int warnings;
    jmp_buf *jmp;    /* unwind target for error_at, or NULL to exit(1) */
} Diag;

extern Diag diag;

void *arena_alloc(size_t n);
char *arena_strdup(const char *s);
char *arena_strndup(const char *s, size_t n);
char *format(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
/* Text that grows (in the arena): buf_add appends printf-style. */
typedef struct Buf {
    char *s;
    size_t len, cap;
} Buf;
void buf_add(Buf *b, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
void buf_vadd(Buf *b, const char *fmt, va_list ap);
void buf_put(Buf *b, const char *s, size_t n); /* n bytes of s, as they are */
void buf_reserve(Buf *b, size_t n);             /* room for n more bytes */
/* The whole of a regular file of at most 16 MiB, NUL-terminated, in the
 * arena (*len its length); NULL with errno set otherwise (EINVAL: not a
 * regular file, EFBIG: too large). */
char *read_file(const char *path, size_t *len);
/* Why read_file refused a file it could open, from its errno ("is not a
 * regular file", "is larger than 16 MiB"), or NULL for an error of the
 * system (no such file, no permission). */
const char *read_file_refused(int err);
/* If text (len bytes) holds a NUL byte: true, with its line and column. */
bool text_nul(const char *text, size_t len, int *line, int *col);

void error_at(SrcPos pos, const char *fmt, ...)
    __attribute__((format(printf, 2, 3), noreturn));
/* An error followed by notes: error_begin prints it, the notes follow,
 * error_end unwinds as error_at does. */
void error_begin(SrcPos pos, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
void error_end(void) __attribute__((noreturn));
void warn_at(SrcPos pos, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));
void note_at(SrcPos pos, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));
void die_(const char *file, int line, const char *fmt, ...)
    __attribute__((format(printf, 3, 4), noreturn));
#define die(...) die_(__FILE__, __LINE__, __VA_ARGS__)
#define unreachable() die("unreachable")

/* Growable array of pointers, arena-backed. */
typedef struct Vec {
    void **data;
    int len;
    int cap;
} Vec;
void vec_push(Vec *v, void *p);
int mkdir_p(const char *path);

/* A hash map from strings to non-negative ints, arena-backed (open
 * addressing).  Keys are not copied: each must outlive the map.  A zeroed
 * Map is empty. */
typedef struct Map {
    const char **keys;
    int *vals;
    int cap; /* slots: 0 or a power of two */
    int len; /* keys held */
} Map;
/* The value of key, or -1 if it has none. */
int map_get(const Map *m, const char *key);
/* Sets key's value (val >= 0), replacing any it had. */
void map_put(Map *m, const char *key, int val);

/* lex.c */

typedef enum {
    TK_IDENT,  /* names, keywords, node names: [A-Za-z_0-9.:]-words */
    TK_NUMBER, /* 4.7k, 1e-3, 10uF */
    TK_STRING, /* "path" */
    TK_LBRACE, /* the text of a braced expression is lexed on demand */
    TK_EQ,
    TK_LPAREN,
    TK_RPAREN,
    TK_COMMA,
    TK_OTHER,  /* any other punctuation: one char */
    TK_EOL,
    TK_EOF,
} TokKind;

typedef struct Token {
    TokKind kind;
    SrcPos pos;
    const char *text; /* the token's characters (for braces: the inside) */
    int len;
    double num;       /* TK_NUMBER: the value in SI units */
} Token;

/* Tokenises a whole file; errors (bad numbers, unterminated strings or
 * braces) are reported at their position. */
Token *lex_file(SrcFile *f, int *ntok);
/* Parses a SPICE number with scale suffix; returns false if malformed and
 * sets *why. */
bool lex_number(const char *s, int len, double *out, const char **why);
/* The same in a SPICE deck (deck): its units in any case. */
bool lex_number_in(const char *s, int len, double *out, const char **why, bool deck);
bool tok_is(const Token *t, const char *s);

/* parse.c: expressions */

typedef enum {
    EX_NUM,   /* num */
    EX_PARAM, /* param (index into Circuit.params) */
    EX_NAME,  /* unresolved name (before elaboration) */
    EX_NEG,
    EX_ADD,
    EX_SUB,
    EX_MUL,
    EX_DIV,
    EX_POW,
    EX_CALL,  /* fn(a[, b]) */
} ExprKind;

typedef enum {
    FN_SQRT, FN_EXP, FN_LOG, FN_LOG10, FN_SIN, FN_COS, FN_TAN, FN_ABS,
    FN_POW, FN_MIN, FN_MAX, FN_POTLIN, FN_POTLOG, FN_TAPON, FN_COUNT
} FnKind;

typedef struct Expr Expr;
struct Expr {
    ExprKind kind;
    SrcPos pos;
    double num;
    int param;
    const char *name;
    FnKind fn;
    Expr *a, *b;
};

Expr *expr_num(double v, SrcPos pos);
Expr *expr_bin(ExprKind k, Expr *a, Expr *b);
Expr *expr_call(FnKind fn, Expr *a, Expr *b);
/* Value of an elaborated expression for the given param values. */
double expr_eval(const Expr *e, const double *params);
/* Bitmask of params an expression reads (params 0..63). */
uint64_t expr_params(const Expr *e);
bool expr_is_const(const Expr *e);
const char *fn_name(FnKind fn);

/* parse.c: lines */

typedef enum {
    VAL_EXPR,   /* number or {expression} */
    VAL_NAME,   /* bare word */
    VAL_STRING, /* "text" */
    VAL_LIST,   /* ( ... ): raw tokens, for curve= */
} ValKind;

typedef struct Value {
    ValKind kind;
    SrcPos pos;
    Expr *expr;       /* VAL_EXPR */
    const char *name; /* VAL_NAME, VAL_STRING */
    Token *toks;      /* VAL_LIST and taps lists */
    int ntoks;
} Value;

typedef struct KeyVal {
    const char *key;
    SrcPos pos;
    Value val;
} KeyVal;

/* A probe or initial-condition reference: v(a), v(a,b), i(R1), x(n), f(K1). */
typedef struct Ref {
    char fn;             /* 'v', 'i', 'x' or 'f' */
    SrcPos pos;
    const char *arg[2];  /* node or element names; arg[1] may be NULL */
    SrcPos argpos[2];
} Ref;

typedef struct Line {
    SrcPos pos;
    const char *head;    /* directive (".param") or element name / keyword */
    SrcPos headpos;
    int kind;            /* element kind (BK_*) or -1 for directives */
    int model_kind;      /* .model lines: the kind of element they serve */
    const char *name;    /* element instance name */
    SrcPos namepos;
    Value *args;         /* positional arguments after the name */
    int nargs;
    KeyVal *kv;
    int nkv;
    Ref *refs;           /* .output probe / .ic references */
    Value *refvals;      /* .ic values, parallel to refs */
    int nrefs;
} Line;

typedef struct Program {
    SrcFile *file;
    Line *lines;
    int nlines;
} Program;

/* Parses one file (not its includes: elaboration follows them).  Errors
 * unwind through diag. */
Program *parse_file(SrcFile *f);
Expr *parse_expr_text(const Token *brace);
SrcFile *srcfile_new(const char *path, const char *text);

/* blocks.c: the element library.  Each kind of element a netlist line
 * can hold has one descriptor, defined with its lowering in blocks/
 * (blocks/resistor.c, ...); blocks/blocks.def lists them, in the order of
 * the BK_* enum. */

#define BLOCK(id, kind) id,
typedef enum {
#include "../blocks/blocks.def"
    BK_COUNT
} BlockKind;
#undef BLOCK

typedef struct Lower Lower; /* elaboration as a kind's lowering sees it (lower.h) */
struct Elem;

/* A key an element kind accepts. */
typedef struct KindKey {
    const char *name; /* as written (keys are case-sensitive) */
    const char *unit; /* SI unit of its value; "" for a plain number or a word */
} KindKey;

typedef struct Kind {
    char desc[24];        /* what it is, for messages ("resistor"); an array,
                             so that block_desc can point at it statically */
    const char *keyword;  /* e.g. "mass"; NULL for SPICE-letter-only kinds */
    char letter;          /* SPICE first letter, or 0 */
    int nnodes;           /* -1: variadic */
    const char *args;     /* positional arguments: after the nodes v value,
                             d drive (input, param or value), m model name;
                             before them t junction type */
    const KindKey *keys;  /* accepted keys, ending with {NULL} */
    bool ready;           /* implemented by the current compiler */
    const char *law;      /* its law, in the netlist's units */
    const char *lowers_to; /* the primitive elements (E_*) it becomes */
    /* Adds the kind's primitive elements for line l (keys checked, model
     * keys merged, its nodes at node[]).  Returns the element whose two
     * terminals must differ, or NULL if the kind checked its own. */
    struct Elem *(*lower)(Lower *L, Line *l, const int *node);
} Kind;

/* The registry: each kind's descriptor, and its noun for messages. */
typedef struct BlockDesc {
    const char *desc; /* kind->desc */
    const Kind *kind;
} BlockDesc;

extern const BlockDesc block_desc[BK_COUNT];
int block_by_keyword(const char *s, int len);
int block_by_letter(char c);
bool block_has_key(int kind, const char *key);

/* elab.c: the circuit */

typedef enum { DOM_ELECTRICAL, DOM_MECHANICAL, DOM_ACOUSTIC } Domain;

typedef enum {
    E_R, /* resistor: val = resistance (ohm) */
    E_C, /* capacitor: val = capacitance (F) */
    E_L, /* inductor: val = inductance (H) */
    E_V, /* voltage source: v(n0)-v(n1) = drive + val*i; val NULL: ideal */
    E_I, /* current source: drive flows n0 -> n1 through it; val: parallel R */
    E_NL, /* nonlinear one-port (diode, curve, contact): see NlSpec */
    E_W,  /* one end of a lossless line: val = Z0; reflects the wave that
             entered the other end `peer` td seconds earlier */
    E_S,  /* one side of a point of a waveguide (string, tube) from node n0
             to ground: val = its port resistance; see Waveguide */
    E_CV, /* controlled voltage source: v(n0)-v(n1) = val * the voltage
             across its probe `peer` */
    E_CI, /* controlled current source: val * the voltage across its probe
             `peer` flows n0 -> n1 through it */
    E_OA, /* ideal op-amp's output, n0 to n1 (ground): any current that
             holds the voltage across its probe `peer` at 0 */
    E_P,  /* the probe of a controlled source or op-amp: no current; its
             voltage v(n0)-v(n1) is the control */
    E_CC, /* current-controlled current source: val * the current of
             nonlinear element `peer` (a transistor's junction) flows n0 -> n1
             through it */
    E_XF, /* a winding of an ideal transformer: v(n0)-v(n1) = val * the
             voltage across its probe `peer` (the reference winding), which
             draws -val times its current, so that the two together neither
             store nor supply power (coupled inductors, K) */
} ElemKind;

/* Whether e is a controlled source's output or probe (they join a root
 * together and stamp its nodal equations, not its scattering edges). */
#define ELEM_CONTROLLED(k) ((k) == E_CV || (k) == E_CI || (k) == E_OA || (k) == E_P || (k) == E_CC || (k) == E_XF)
/* Whether e is an output that holds a voltage, whose current is an
 * unknown of the equations it stamps. */
#define ELEM_VOUT(k) ((k) == E_CV || (k) == E_OA || (k) == E_XF)

typedef enum {
    NL_DIODE,   /* i = Is (exp(v/(n Vt)) - 1), or 2 Is sinh(v/(n Vt)) for a pair */
    NL_CURVE,   /* i = f(v), piecewise linear through given points */
    NL_CONTACT, /* i = k X^alpha (1 + lambda dX/dt) for X > 0, X = x(n0) - x(n1) - gap */
} NlKind;

typedef enum {
    SOLVER_DEFAULT, /* the command line's choice */
    SOLVER_PWL,     /* piecewise-linear wave map, explicit */
    SOLVER_NEWTON,  /* damped, bracketed Newton with a hard iteration cap */
    SOLVER_OMEGA,   /* Wright omega closed form (diodes) */
    SOLVER_FAST,    /* tabulated omega predictor, Halley steps on the exact law (diodes' default) */
    SOLVER_JOINT,   /* several at one root: damped Newton on their joint equations (not a choice) */
} Solver;

/* A nonlinear element.  Its current flows from n0 to n1 through it. */
typedef struct NlSpec {
    NlKind kind;
    Expr *Is, *n, *Vt;   /* diode: saturation current (A), ideality, thermal voltage (V) */
    bool pair;           /* diode: antiparallel pair */
    double *cv, *ci;     /* curve: points (V, A), v strictly increasing */
    int npts;
    Expr *k, *alpha, *lambda, *gap; /* contact: N/m^alpha, exponent, s/m, m */
    Solver solver;
    SrcPos solver_pos;
    char mutated;        /* through a mutator: 'C' for q = g(v) (R-C type),
                            'L' for i = g(flux) (R-L type), 0 for i = g(v) */
} NlSpec;

typedef struct Elem {
    ElemKind kind;
    const char *name;  /* unique; pots give "P1.aw" and "P1.wb" */
    int n[2];          /* node indices; 0 is ground */
    Expr *val;         /* see ElemKind */
    int input;         /* sources: index of the driving input, or -1 */
    Expr *drive;       /* sources without input: control-rate value */
    Expr *ic;          /* C: initial voltage, L: initial current, or NULL */
    NlSpec *nl;        /* E_NL: the nonlinearity */
    int peer;          /* E_W: element of the line's other end */
    double td;         /* E_W: delay of the line, s */
    int wg, pt, side;  /* E_S: waveguide, its point (0: end a, 1..ntaps:
                          taps, ntaps+1: end b), side (0 faces end a, 1 b) */
    SrcPos pos;
    int user_kind;     /* BlockKind it came from */
} Elem;

/* A waveguide: a string (velocity and force, mobility analogy) or a
 * tube (pressure and volume flow) from end a to end b, with taps between.
 * It is two delay lines, one per direction, with the loop's loss,
 * dispersion and fine-tuning filters lumped where the right-going wave
 * meets end b.  Points joined to the network are ports to ground (E_S
 * elements); a terminated end reflects. */
typedef struct Waveguide {
    const char *name;
    bool tube;
    int end[2];          /* nodes of ends a and b; 0: terminated */
    char term[2];        /* terminated ends: 'r' rigid (string), 'o' open
                            (tube, radiating), 'c' closed (tube) */
    Expr *f0;            /* string: first partial with rigid ends, Hz;
                            tube: c / (2 L_eff), L_eff with end corrections */
    Expr *Rp;            /* port resistance: 1/sqrt(T mu) (string), rho c / (pi r^2) (tube) */
    Expr *B, *fhf;
    Expr *t60, *t60hf;   /* NULL: lossless; t60hf NULL: = t60 */
    Expr *rad;           /* tube: radiation radius r / c * fs scale (s), else NULL */
    double nu1;          /* first resonance in units of f0: 1, or 0.5 for a closed-open tube */
    int ntaps;
    int *tap_node;
    Expr **tap_pos;      /* fraction of the length from end a */
    SrcPos *tap_src;     /* where each tap is written */
    const char **tap_name; /* each tap's node as written */
    double f0_min;       /* lowest f0 over the params' ranges: sizes the lines */
    int M;               /* order of the loop's allpass (chosen at compile time) */
    int nrad;            /* open tube ends: radiation filters */
    int nmin;            /* fewest whole samples its loop may hold (4 with taps) */
    SrcPos pos;
} Waveguide;

typedef struct Param {
    const char *name;
    const char *unit;
    double def, min, max;
    SrcPos pos;
} Param;

typedef enum { PR_V, PR_I, PR_X, PR_F } ProbeKind;

typedef struct Probe {
    const char *name; /* output name */
    ProbeKind kind;
    int n[2];         /* PR_V / PR_X: nodes (n[1] = 0 for ground) */
    int elem;         /* PR_I / PR_F: element index; -1: a resistor to a node nothing else meets (0) */
    SrcPos pos;
} Probe;

typedef struct IcSpec {
    char fn;     /* 'v' or 'x' */
    int node;
    Expr *val;
    SrcPos pos;
} IcSpec;

/* The time function of a SPICE deck's independent source (SIN, PULSE,
 * PWL, EXP, or its DC value alone), which drives the source's input in a
 * render without --input.  v: the function's values as the deck gives
 * them (PWL: time, value pairs). */
typedef struct SrcFn {
    char kind; /* 'd' DC, 's' SIN, 'p' PULSE, 'w' PWL, 'e' EXP */
    double dc;
    double *v;
    int nv;
    SrcPos pos;
} SrcFn;

double srcfn_at(const SrcFn *f, double t, double step);

typedef struct Circuit {
    const char *name;     /* voice name */
    const char *path;     /* main netlist file */
    Domain domain;
    double rate;          /* default sample rate, Hz */
    double tstop;         /* a deck's .tran stop time: a render's length (s), 0: none */
    bool deck;            /* read as a SPICE deck: starts from its DC operating point */
    bool uic;             /* the deck's .tran says UIC: it starts from rest and its .ic */
    int nnodes;           /* node 0 is ground */
    const char **nodes;
    Elem *elems;
    int nelems;
    Param *params;
    int nparams;
    const char **inputs;
    const SrcFn **input_fn; /* per input: a deck source's time function, NULL: none */
    int ninputs;
    Probe *outs;
    int nouts;
    IcSpec *ics;
    int nics;
    Waveguide *wgs;
    int nwgs;
    uint32_t hash;        /* FNV-1a of the netlist text, includes appended */
} Circuit;

/* Parses and elaborates a netlist file (the phases before any structure:
 * wg_choose, then wdf_build, come after).  Returns NULL after printing a
 * diagnostic if the netlist has an error. */
Circuit *wdc_elaborate(const char *path);
/* The same with the voice's rate given (> 0, as `--rate` gives it): a
 * deck's .tran step too fine for a voice's rate is then no error, and
 * sets no rate. */
Circuit *wdc_elaborate_at(const char *path, double rate);
/* Same, from text in memory (name is used in diagnostics). */
Circuit *wdc_elaborate_string(const char *name, const char *text);
/* wdc_elaborate and wg_choose: a circuit ready for wdf_build, for
 * programs that use the compiler as a library (load.c). */
Circuit *wdc_load(const char *path);
Circuit *wdc_load_string(const char *name, const char *text);
/* Element values for the given params (not clamped: the voice clamps to
 * positive values at run time, the compiler checks defaults); also used by
 * tests as the reference for a network's values. */
double elem_value(const Circuit *c, const Elem *e, const double *params);
double elem_drive(const Circuit *c, const Elem *e, const double *params);
/* Param defaults in one array (arena). */
double *circuit_defaults(const Circuit *c);
const char *domain_unit(Domain d, char fn);
void circuit_dump(const Circuit *c, FILE *out);

/* waveguide.c */

/* Chooses the order of each waveguide's allpass; errors for loops too
 * short for their filters and taps outside their waveguide (unwinding
 * through diag). */
void wg_choose(Circuit *c);
/* An error if a waveguide's loop, at the default params, is too short for
 * its filters at rate fs (a render's --rate). */
void wg_check_rate(const Circuit *c, double fs);
/* Doubles a voice's state keeps per waveguide: the spec of the design in
 * effect, and a design prepare made with its spec. */
extern const int wg_nspec, wg_nrec;

/* wdf.c: the adaptor tree */

typedef enum {
    W_LEAF,     /* one adaptable element */
    W_SERIES,   /* series adaptor; its up port is adapted */
    W_PARALLEL, /* parallel adaptor; its up port is adapted */
} WKind;

typedef struct WNode WNode;
struct WNode {
    WKind kind;
    int id;           /* index in Wdf.nodes (post-order) */
    int elem;         /* W_LEAF: element index */
    int u, w;         /* graph nodes of the port, oriented u -> w */
    int nchild;
    WNode **child;
    int *pol;         /* +1/-1: child's orientation against this port */
    WNode *parent;
    int root;         /* index of the root whose tree holds it */
    double R;         /* port resistance at the default params and rate */
    uint64_t pmask;   /* params its port resistance depends on */
};

/* The codes of a voice's tables, shared with the voice (emit.c prints
 * the same enum into it): kinds of root edges (EDGE_*), of elements in
 * the initial-condition solve (IC_*), columns of a waveguide's row
 * (WGT_*). */
#define CODE(name, value, what) name = value,
enum {
#include "../templates/codes.def"
};

/* blocks/primitives.c: what each primitive element is to the structure
 * and the voice.  Realisations: */
typedef enum {
    WD_ADAPTED,   /* an adapted one-port that reflects nothing (a resistor) */
    WD_HOLD,      /* reflects the wave it last took in (a capacitor, trapezoidal) */
    WD_HOLD_NEG,  /* reflects that wave's negative (an inductor) */
    WD_SOURCE,    /* a resistive source: reflects its drive (V) or -R times it (I) */
    WD_ROOT,      /* joins its block's root adaptor: a nonlinear one-port */
    WD_DELAY,     /* reflects what entered the other end of its line TD earlier */
    WD_WAVEGUIDE, /* reflects what its string or tube brings to its point */
} WdReal;

enum { ROOT_NEVER, ROOT_IDEAL, ROOT_ALWAYS };

/* Its stamps are C text the printer (emit.c) fills in: $a is the wave it
 * took in last (incident), $b the wave it reflected, $e its drive, $R its
 * port resistance, $x a value the stamp says; a line end's also name its
 * buffer's offset in s_dl ($o), the other end's ($p), its line ($k, whose
 * delay is k_D$k in the sample loop and st->c_D[$k] elsewhere) and the
 * mask of the buffers' positions ($m); D(...) is computed in double in a
 * float voice.  A stamp a primitive does not have is NULL. */
typedef struct Prim {
    const char *name;
    const char *law;   /* in its value: R, C, L, e and R, j and R, Z0 */
    WdReal wd;
    char port;         /* its port resistance from its value v: 'v' v, 'C' 1/(2 fs v), 'L' 2 fs v */
    char state;        /* what it stores between samples: 'C' a charge (its voltage), 'L' a flux (its current), 0 nothing */
    int root;          /* ROOT_*: when it joins the root adaptor (ROOT_IDEAL: without a resistance) */
    int ic, ic_resistive; /* how it enters the initial-condition solve (IC_*), ideal and with a resistance */
    const char *reflect;  /* the wave it reflects ($a: its held wave); NULL only for what joins a root */
    const char *absorb;   /* a statement keeping the wave it takes in ($a) in a buffer of its own, or NULL */
    const char *stored;   /* what it stores (its voltage, its current), from its waves $a and $b */
    const char *energy;   /* statements adding its stored energy to E, $x being what it stores */
    char strike;          /* the strike target that sets what it stores, between its node and ground: 'v' or 'x' */
    const char *struck;   /* what it stores, from that target's value $x */
} Prim;

extern const Prim prims[]; /* by ElemKind */

/* Whether e cannot be adapted and joins its block's root adaptor. */
bool prim_at_root(const Elem *e);
/* e's port resistance for value v at rate fs. */
double prim_port(const Elem *e, double v, double fs);
/* The same as C text of the value's text v (T: the sample period). */
const char *prim_port_text(const Elem *e, const char *v);
/* How e enters the initial-condition solve (IC_*). */
int prim_ic(const Elem *e);
#undef CODE

/* One edge of the root adaptor: a subtree's port or an ideal source. */
typedef struct RootEdge {
    int kind;   /* EDGE_PORT: port of subtree `node`, EDGE_V: ideal V
                   source, EDGE_I: ideal I, EDGE_NL: nonlinear element
                   (its port adapted to the core) */
    WNode *node;
    int elem;   /* sources: element index */
    int p, q;   /* core node indices (-1: the reference node) */
} RootEdge;

/* Nonlinear elements one root solves jointly, at most (JOINT_MAX of
 * templates/nl_joint.c.tmpl). */
#define WD_JOINT_MAX 8

typedef struct Root {
    int ncore;         /* core nodes, the reference excluded */
    int *core_node;    /* graph node of each core index */
    int ref_node;      /* graph node used as reference */
    RootEdge *edge;
    int nedge;
    int nport;         /* ports first in edge[], then nonlinear edges, then sources */
    int nnl;           /* nonlinear edges */
    bool joint;        /* nnl > 1: solved jointly, their resistances fixed */
    int nv;            /* ideal voltage sources among the edges */
    double *R;         /* port resistance of each port and nonlinear edge */
    /* M (nedge x nedge, row-major): outputs [a of each port and
     * nonlinear edge; i of each V source, v of each I source] from inputs
     * [b of each port and nonlinear edge; drive of each source], at the
     * default params and rate. */
    double *M;
    uint64_t pmask;    /* params M depends on */
    /* Controlled sources and op-amps held in the core: each output
     * (E_CV, E_CI, E_OA, E_CC, E_XF) with its probe's core nodes; a
     * voltage output adds an unknown (its current) after the nodes and
     * before the ideal V sources' currents.  Active (but for E_XF), so
     * the root is not checked lossless. */
    struct RootCtl {
        int elem;      /* the output element */
        int kind;      /* E_CV, E_CI, E_OA, E_CC or E_XF */
        int p, q;      /* output's core nodes */
        int cp, cn;    /* probe's core nodes (E_CC: its nonlinear edge's) */
        int ce;        /* E_CC: the nonlinear edge whose current it takes */
        double gain;
    } *ctl;
    int nctl;
    int nx;            /* unknowns the outputs add: E_CV, E_OA and E_XF */
} Root;

typedef struct Wdf {
    Circuit *c;
    double fs;
    WNode **nodes;     /* post-order: children before parents, root by root */
    int nnodes;
    Root *roots;       /* one per block of the core: parts that share at most
                          one node, or meet only through a delay, are
                          independent */
    int nroots;
    WNode **leaf_of;   /* element index -> its leaf, NULL for root sources */
    /* Path from ground to each graph node: element indices with sign,
     * so v(node) = sum sign * v(elem).  Paths share storage (a node's
     * path runs on into a child's): read pathlen[n] pairs, no more. */
    int **path;
    int *pathlen;
} Wdf;

Wdf *wdf_build(Circuit *c, double fs);
void wdf_dot(const Wdf *w, FILE *out);
void wdf_dump(const Wdf *w, FILE *out);

/* scatter.c */

/* Solves A x = b (n x n, row-major; both overwritten, x into b): 0, or -1
 * if A is singular. */
int scatter_dense_solve(double *A, int n, double *b);

/* dcop.c: the DC operating point of a circuit with nonlinear elements
 * and controlled sources (capacitors open, inductors shorted, element i's
 * source at drive[i]): node voltages (nodev[nnodes], ground 0) and each
 * element's current from n0 to n1 (cur[nelems]: sources, inductors,
 * nonlinear elements, controlled sources); false if it is not found
 * within its bounds (160 unknowns, 2000 Newton iterations) or the circuit
 * has lines, waveguides or stored laws. */
bool dcop_solve(const Circuit *c, const double *params, const double *drive, double *nodev, double *cur);
/* The drives of the operating point, drive[nelems] (in the arena): each
 * source's constant value at the params, or its input's time function's
 * first value (0 for an input without one); 0 for other elements. */
double *dcop_drives(const Circuit *c, const double *params);

/* Solves the root adaptor's matrix M for port resistances R (one per port
 * edge) and returns 0, or -1 if the core is singular. */
int scatter_root(const Root *r, const double *R, double *M);
/* Resistance the core presents to edge k (ideal V sources shorted, ideal I
 * sources open, other ports and nonlinear edges at R): the port
 * resistance that adapts a nonlinear edge.  Returns 0, or -1 if the edge
 * has no closed path through the rest of the core (infinite resistance). */
int scatter_thevenin(const Root *r, const double *R, int k, double *Rth);
/* Scattering matrix of an adaptor (ports: up port first, then children),
 * n x n row-major; for the root, the port-to-port block. */
void scatter_node(const WNode *n, double *S);
/* The root's matrix again, from its tableau of Kirchhoff's laws over its
 * edges (KCL per core node, KVL per fundamental loop) rather than from
 * its nodal equations; returns 0 or -1 if singular. */
int scatter_tableau(const Root *r, const double *R, double *M);
/* Prints every root's edges, tableau and solved matrix, with names. */
void scatter_print_tableau(const Wdf *w, FILE *out);
/* Largest losslessness error over every adaptor (|S^T G S - G| per port
 * pair over sqrt(G_i G_j); for a series or parallel adaptor a bound on it
 * from its closed form, in time linear in its ports); internal error if
 * one exceeds tol or an adaptor is not adapted at its up port, or if a
 * root's matrix does not satisfy its tableau of Kirchhoff's laws. */
double scatter_check(const Wdf *w, double tol);

/* emit.c */

/* A template hole and the text that fills it. */
typedef struct Hole {
    const char *name, *text;
} Hole;

/* tmpl with every {{name}} replaced by its hole's text (arena); a hole
 * without a value is an internal error. */
const char *fill(const char *tmpl, const Hole *holes, int n);

typedef struct EmitOpts {
    bool single;        /* float precision */
    bool energy;        /* work accounting in process (--energy); else work() is NAN */
    bool no_skip;       /* process computes idle contacts' parts every sample (--no-skip) */
    bool batch;         /* the class's process_batch renders instances in lanes (--batch) */
    Solver solver;      /* for nonlinear elements that name none */
    int table;          /* points of a diode's piecewise-linear table */
    double tol;         /* Newton: relative step tolerance */
    double fast_tol;    /* solver fast: the same, 0 for its table's bound (no Halley steps) */
    int maxit;          /* Newton: iteration cap */
    const char *outdir;
    const char *tmpldir; /* templates/ */
} EmitOpts;

/* Writes outdir/NAME.c and outdir/NAME.h; returns 0 or -1 (I/O error). */
int emit_voice(const Wdf *w, const EmitOpts *o);
/* Which strike targets set something, by the id v(node) and x(node) take
 * node by node from 1 (2 (node - 1) and one more): set[] takes 2 (nnodes -
 * 1) entries.  A voice's ic_targets lists these, in this order. */
void wdf_ic_settable(const Wdf *w, bool *set);

/* fasttab.c: the fast diode solver's tables (templates/nl_fast.c.tmpl),
 * their *n doubles. */
const double *fast_tables(int *n);

/* lv2.c */

enum { LV2_ENETLIST = -1, LV2_EIO = -2, LV2_ETOOL = -3 };

/* Writes an LV2 bundle of the voice into dir (made if missing):
 * manifest.ttl, NAME.ttl and NAME.so, the voice (emitted with o, into a
 * temporary directory) and templates/lv2.c.tmpl compiled together with
 * $CC (default cc).  The plugin's URI is urn:wdc:voice:NAME.  Returns 0,
 * or after printing why: LV2_ENETLIST (nothing to export), LV2_EIO (a
 * file cannot be written), LV2_ETOOL (the C compiler failed).  Errors at
 * a netlist position (a param without a range) unwind through diag. */
int lv2_bundle(const Wdf *w, const EmitOpts *o, const char *dir);

#endif
