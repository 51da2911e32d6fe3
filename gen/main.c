/* main.c: the wdc command line.  The pipeline runs straight through:
 * load (parse + elaborate) -> structure -> check -> emit -> [render]. */
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "gen.h"
#include "wdrt.h"

enum { EXIT_NETLIST = 1, EXIT_USAGE = 2, EXIT_TOOL = 3 };

/* The longest render, s: a day.  Past it a length is surely a typo, and
 * its buffers would not fit in memory anyway. */
#define MAX_SECONDS 86400.0
/* The highest --rate, Hz. */
#define MAX_RATE 1e7
/* The largest input amplitude or strike value accepted, in the netlist's
 * units: beyond it a voice's arithmetic overflows before it is heard. */
#define MAX_LEVEL 1e6


typedef struct Opts {
    const char *file, *outdir, *render, *csv, *dot, *events, *lv2;
    const char *inputs[16];
    int ninputs;
    double seconds, rate;
    bool check, single, energy, no_skip, batch, dump_elab, dump_wdf, tableau, has_outdir;
    Solver solver;
    int table, maxit;
    double tol, fast_tol; /* fast_tol: 0 unless --tol was given */
} Opts;

static const char synopsis[] =
    "usage: wdc FILE.wdn [-o DIR] [--precision double|float] [--energy] [--no-skip] [--batch]\n"
    "       wdc FILE.wdn --check\n"
    "       wdc FILE.wdn --render OUT.wav [--input SPEC]... [--seconds S] [--rate HZ]\n"
    "                    [--csv OUT.csv] [--events FILE]\n"
    "       wdc FILE.wdn --lv2 DIR [--precision double|float]  an LV2 plugin bundle of the voice\n"
    "       wdc FILE.wdn --dot OUT.dot\n"
    "       wdc FILE.wdn --tableau            each root adaptor's tableau and solved matrix\n";

static void usage(FILE *f) {
    fprintf(f, "%s", synopsis);
    fprintf(f,
        "nonlinear elements: [--solver fast|newton|omega|pwl] [--table N] [--tol T] [--maxit N]\n"
        "--tol T: a Newton solve's relative tolerance (default 1e-12, at most 1e-3); the fast solver's error is\n"
        "          below 5e-8 (|v| + nVt) by its table, and only a T below that adds Halley steps\n"
        "SPEC: impulse[:A] | step[:A] | sine:FREQ[:A] | noise[:A] | FILE.wav (one per .input, in order)\n"
        "--energy: the voice counts the work its sources do, sample by sample (its work()); without\n"
        "          it process does no such accounting and work() returns NaN (energy() is always there)\n"
        "--no-skip: process computes every part every sample; by default it skips a hammer (a mass\n"
        "          behind a contact on a string) while the contact stays open, with the same output\n"
        "--batch: the voice's process_batch renders many instances at once, in lanes, each as\n"
        "          process would (without it the class has none, and a host calls process for each)\n"
        "--spice: read FILE as a SPICE deck (as a file ending .cir, .sp, .spice or .net is read)\n"
        "-delab, -dwdf print the elaborated circuit or the adaptor tree.\n"
        "exit status: 0 ok, 1 netlist error, 2 usage error, 3 toolchain or internal error\n");
}

/* The error and the synopsis, not the whole help. */
static void usage_error(const char *fmt, const char *arg) {
    fprintf(stderr, "wdc: error: ");
    fprintf(stderr, fmt, arg);
    fprintf(stderr, "\n%s(wdc --help says more)\n", synopsis);
    exit(EXIT_USAGE);
}

static double number_arg(const char *opt, const char *s) {
    double v;
    const char *why;
    if (!s || !lex_number(s, (int)strlen(s), &v, &why) || !(v > 0))
        usage_error(format("%s needs a positive number, got '%%s'", opt), s ? s : "");
    return v;
}

static Opts parse_args(int argc, char **argv) {
    Opts o = {.outdir = "out", .table = 256, .tol = 1e-12, .maxit = 50};
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        const char *next = i + 1 < argc ? argv[i + 1] : NULL;
#define TAKE() (next ? (i++, next) : (usage_error("%s needs an argument", a), ""))
        if (!strcmp(a, "-h") || !strcmp(a, "--help")) {
            usage(stdout);
            exit(0);
        } else if (!strcmp(a, "--version")) {
            printf("wdc %s\n", WDC_VERSION);
            exit(0);
        } else if (!strcmp(a, "-o")) {
            o.outdir = TAKE();
            o.has_outdir = true;
        } else if (!strcmp(a, "--lv2")) o.lv2 = TAKE();
        else if (!strcmp(a, "--check")) o.check = true;
        else if (!strcmp(a, "--energy")) o.energy = true;
        else if (!strcmp(a, "--no-skip")) o.no_skip = true;
        else if (!strcmp(a, "--batch")) o.batch = true;
        else if (!strcmp(a, "--spice")) spice_always = true;
        else if (!strcmp(a, "--render")) o.render = TAKE();
        else if (!strcmp(a, "--csv")) o.csv = TAKE();
        else if (!strcmp(a, "--dot")) o.dot = TAKE();
        else if (!strcmp(a, "--events")) o.events = TAKE();
        else if (!strcmp(a, "--seconds")) {
            o.seconds = number_arg(a, TAKE());
            if (o.seconds > MAX_SECONDS)
                usage_error("--seconds takes at most 86400 (a day), not '%s'", argv[i]);
        } else if (!strcmp(a, "--rate")) {
            o.rate = number_arg(a, TAKE());
            if (o.rate > MAX_RATE)
                usage_error("--rate takes at most 10 MHz (1e7), not '%s'", argv[i]);
        }
        else if (!strcmp(a, "-delab")) o.dump_elab = true;
        else if (!strcmp(a, "-dwdf")) o.dump_wdf = true;
        else if (!strcmp(a, "--tableau")) o.tableau = true;
        else if (!strcmp(a, "--input")) {
            if (o.ninputs == 16)
                usage_error("too many --input options (%s)", "16 at most");
            o.inputs[o.ninputs++] = TAKE();
        } else if (!strcmp(a, "--solver")) {
            const char *v = TAKE();
            o.solver = !strcmp(v, "newton") ? SOLVER_NEWTON : !strcmp(v, "omega") ? SOLVER_OMEGA
                     : !strcmp(v, "pwl") ? SOLVER_PWL : !strcmp(v, "fast") ? SOLVER_FAST : SOLVER_DEFAULT;
            if (o.solver == SOLVER_DEFAULT)
                usage_error("--solver takes fast, newton, omega or pwl, not '%s'", v);
        } else if (!strcmp(a, "--table")) {
            double v = number_arg(a, TAKE());
            if (v < 2 || v > 1e6 || v != (int)v)
                usage_error("--table takes a whole number of points from 2 to 1000000, not '%s'", argv[i]);
            o.table = (int)v;
        } else if (!strcmp(a, "--maxit")) {
            double v = number_arg(a, TAKE());
            if (v > 1000 || v != (int)v)
                usage_error("--maxit takes a whole number from 1 to 1000, not '%s'", argv[i]);
            o.maxit = (int)v;
        } else if (!strcmp(a, "--tol")) {
            o.tol = o.fast_tol = number_arg(a, TAKE());
            if (o.tol > 1e-3) /* past it a Newton solve stops where it starts */
                usage_error("--tol takes a relative tolerance above 0 and at most 1e-3, not %s", argv[i]);
        } else if (!strcmp(a, "--precision")) {
            const char *p = TAKE();
            if (strcmp(p, "float") && strcmp(p, "double"))
                usage_error("--precision takes double or float, not '%s'", p);
            o.single = !strcmp(p, "float");
        } else if (a[0] == '-' && a[1]) {
            usage_error("unknown option '%s'", a);
        } else if (o.file) {
            usage_error("more than one netlist given ('%s')", a);
        } else {
            o.file = a;
        }
#undef TAKE
    }
    if (!o.file)
        usage_error("%s", "no netlist given");
    if ((o.csv || o.events || o.ninputs || o.seconds > 0) && !o.render)
        usage_error("%s", "--csv, --events, --input and --seconds need --render");
    if (o.lv2 && (o.render || o.has_outdir))
        usage_error("%s", "--lv2 writes only the bundle: it does not combine with -o or --render");
    if (o.check && (o.render || o.lv2 || o.has_outdir))
        usage_error("%s", "--check writes nothing: it does not combine with -o, --render or --lv2");
    return o;
}

static bool sane_level(double v) { return isfinite(v) && fabs(v) <= MAX_LEVEL; }

/* calloc that reports failure as wdc's toolchain/internal status. */
static void *checked_calloc(size_t n, size_t size, const char *what) {
    void *p = calloc(n, size);
    if (!p) {
        fprintf(stderr, "wdc: error: out of memory for %s (%zu bytes)\n", what, n * size);
        exit(EXIT_TOOL);
    }
    return p;
}

/* ---- input signals ---- */

/* An input, made block by block as the render reaches it: a WAV file's
 * first channel (then silence), a deck source's time function, or a
 * spec's impulse, step, sine or noise. */
typedef struct Signal {
    char kind;         /* 'w' a file, 'f' a time function, 'i' 's' 'n' 'r': impulse, step, sine, noise; 0 none */
    double *data;      /* 'w': the file's n samples */
    long n;
    const SrcFn *fn;   /* 'f' */
    double a, f;       /* amplitude; a sine's frequency */
    uint32_t seed;     /* 'r': the noise's state, which runs on from block to block */
} Signal;

/* Parses SPEC's kind, frequency (sine) and amplitude; a usage error for
 * anything non-finite, absurd, or (frequency) past Nyquist. */
static void parse_spec(const char *spec, double fs, char kind[32], double *f, double *a) {
    const char *colon = strchr(spec, ':');
    size_t klen = colon ? (size_t)(colon - spec) : strlen(spec);
    memcpy(kind, spec, klen < 31 ? klen : 31);
    kind[klen < 31 ? klen : 31] = 0;
    const char *rest = colon ? colon + 1 : NULL;
    *a = 1;
    *f = 0;
    if (strcmp(kind, "impulse") && strcmp(kind, "step") && strcmp(kind, "sine") && strcmp(kind, "noise"))
        usage_error("unknown input spec '%s' (impulse, step, sine:FREQ, noise or a .wav file)", spec);
    if (!strcmp(kind, "sine")) {
        if (!rest)
            usage_error("sine input needs a frequency: sine:FREQ[:A], got '%s'", spec);
        char *end;
        *f = strtod(rest, &end);
        if (end == rest || (*end && *end != ':'))
            usage_error("bad sine frequency in '%s'", spec);
        if (!(*f >= 0 && *f <= fs / 2))
            usage_error("%s", format("the sine frequency in '%s' must be from 0 Hz to half the rate (%g Hz)", spec,
                                     fs / 2));
        rest = *end == ':' ? end + 1 : NULL;
    }
    if (rest) {
        char *end;
        *a = strtod(rest, &end);
        if (end == rest || *end)
            usage_error("bad amplitude in input spec '%s'", spec);
        if (!sane_level(*a))
            usage_error("%s", format("the amplitude in input spec '%s' must be finite and at most %g in size", spec,
                                     MAX_LEVEL));
    }
}

static Signal make_signal(const char *spec, double fs) {
    char kind[32];
    Signal s = {0};
    parse_spec(spec, fs, kind, &s.f, &s.a);
    s.kind = !strcmp(kind, "impulse") ? 'i' : !strcmp(kind, "step") ? 's' : !strcmp(kind, "sine") ? 'n' : 'r';
    s.seed = 0x9e3779b9u;
    return s;
}

/* Frames pos .. pos + m - 1 of s into out (blocks asked in order). */
static void signal_fill(Signal *s, long pos, long m, double fs, double *out) {
    for (long j = 0; j < m; j++) {
        long i = pos + j;
        switch (s->kind) {
        case 'w': out[j] = i < s->n ? s->data[i] : 0; break;
        case 'f': out[j] = srcfn_at(s->fn, (double)i / fs, 1 / fs); break;
        case 'i': out[j] = i == 0 ? s->a : 0; break;
        case 's': out[j] = s->a; break;
        case 'n': out[j] = s->a * sin(2 * M_PI * s->f * (double)i / fs); break;
        default:
            s->seed ^= s->seed << 13;
            s->seed ^= s->seed >> 17;
            s->seed ^= s->seed << 5;
            out[j] = s->a * (2.0 * s->seed / 4294967295.0 - 1);
        }
    }
}

static bool is_wav(const char *spec) {
    size_t n = strlen(spec);
    return n > 4 && !strcasecmp(spec + n - 4, ".wav");
}

/* A WAV input, its channels averaged as the runtime's sound files are (a
 * note says so), which must be at the render's rate and hold only finite
 * samples. */
static Signal read_wav_input(const char *path, double fs) {
    int nch;
    double wfs, *frames;
    long nf;
    if (wdrt_wav_read(path, &nch, &wfs, &frames, &nf) != WDRT_OK) {
        fprintf(stderr, "wdc: error: cannot read input '%s'\n", path);
        exit(EXIT_USAGE);
    }
    if (fabs(wfs - fs) > 0.5)
        usage_error("input file rate differs from the render rate (%s)",
                    format("%g Hz vs %g Hz; --rate %g renders at the file's", wfs, fs, wfs));
    if (nch > 1)
        fprintf(stderr, "wdc: note: input '%s' has %d channels; the voice's input takes their mean\n", path, nch);
    Signal s = {.kind = 'w', .data = checked_calloc((size_t)nf + 1, sizeof(double), format("input '%s'", path)), .n = nf};
    for (long i = 0; i < nf; i++) {
        double m = 0;
        for (int k = 0; k < nch; k++)
            m += frames[i * nch + k];
        s.data[i] = m / nch;
        if (!isfinite(s.data[i]))
            usage_error("%s", format("input '%s' holds a non-finite sample at frame %ld", path, i));
    }
    free(frames);
    return s;
}

/* ---- events ---- */

typedef struct Event {
    long frame;
    int order; /* line order, which keeps events at one time in sequence */
    int kind; /* 0 set param, 1 ic */
    int param;
    double value;
    int nic;
    int ids[8]; /* as find_ic_target gives them, then the voice's (settable_ids) */
    double vals[8];
    SrcPos at[8]; /* each target's place in the events file */
} Event;

/* What a line of an events file is read against: the circuit and the
 * render's rate and length (tmax, s; `why` says where that limit comes
 * from). */
typedef struct EventCtx {
    SrcFile *file;
    const Circuit *c;
    double fs, tmax;
    const char *why;
} EventCtx;

static int cmp_event(const void *a, const void *b) {
    const Event *x = a, *y = b;
    return x->frame < y->frame ? -1 : x->frame > y->frame ? 1 : x->order - y->order;
}

static SrcPos ev_pos(const EventCtx *x, int line, int col) { return (SrcPos){x->file, line, col}; }

/* The index of param NAME, or -1. */
static int find_param(const Circuit *c, const char *name) {
    for (int i = 0; i < c->nparams; i++)
        if (!strcmp(c->params[i].name, name))
            return i;
    return -1;
}

/* The id of strike target "v(NODE)" or "x(NODE)" in the voice's
 * ic_targets (emit.c: node by node from 1, v then x), or -1. */
static int find_ic_target(const Circuit *c, const char *name) {
    size_t len = strlen(name);
    if (len < 4 || (name[0] != 'v' && name[0] != 'x') || name[1] != '(' || name[len - 1] != ')')
        return -1;
    for (int nd = 1; nd < c->nnodes; nd++)
        if (strlen(c->nodes[nd]) == len - 3 && !strncmp(c->nodes[nd], name + 2, len - 3))
            return 2 * (nd - 1) + (name[0] == 'x');
    return -1;
}

static double ev_number(const EventCtx *x, int line, int col, const char *s) {
    double v;
    const char *why;
    if (!lex_number(s, (int)strlen(s), &v, &why))
        error_at(ev_pos(x, line, col), "expected a number, got '%s'", s);
    if (!isfinite(v))
        error_at(ev_pos(x, line, col), "'%s' is not a finite number", s);
    return v;
}

/* TIME set PARAM VALUE */
static void ev_set(const EventCtx *x, int line, char **tok, const int *col, int nt, Event *e) {
    if (nt != 4)
        error_at(ev_pos(x, line, col[1]), "expected: TIME set PARAM VALUE");
    e->kind = 0;
    e->param = find_param(x->c, tok[2]);
    if (e->param < 0)
        error_at(ev_pos(x, line, col[2]), "unknown param '%s'", tok[2]);
    e->value = ev_number(x, line, col[3], tok[3]);
    const Param *pr = &x->c->params[e->param];
    if (e->value < pr->min || e->value > pr->max) /* the voice clamps it: say so */
        warn_at(ev_pos(x, line, col[3]), "%s = %g lies outside its range [%g, %g]: the voice holds it at %g", pr->name,
                e->value, pr->min, pr->max, e->value < pr->min ? pr->min : pr->max);
}

/* TIME ic TARGET=VALUE ...  (at most 8 targets) */
static void ev_ic(const EventCtx *x, int line, char **tok, const int *col, int nt, Event *e) {
    e->kind = 1;
    for (int k = 2; k < nt; k++) {
        if (e->nic == 8)
            error_at(ev_pos(x, line, col[k]), "at most 8 initial conditions on one line: this is the 9th");
        char *eq = strchr(tok[k], '=');
        if (!eq)
            error_at(ev_pos(x, line, col[k]), "expected v(node)=VALUE or x(node)=VALUE");
        *eq = 0;
        int id = find_ic_target(x->c, tok[k]);
        if (id < 0)
            error_at(ev_pos(x, line, col[k]), "unknown initial-condition target '%s'", tok[k]);
        int vcol = col[k] + (int)(eq + 1 - tok[k]);
        double v = ev_number(x, line, vcol, eq + 1);
        if (!sane_level(v))
            error_at(ev_pos(x, line, vcol), "a strike value must be at most %g in size, not '%s'", MAX_LEVEL, eq + 1);
        e->ids[e->nic] = id;
        e->at[e->nic] = ev_pos(x, line, col[k]);
        e->vals[e->nic++] = v;
    }
}

/* One line, comments already cut; returns false for a blank line. */
static bool ev_line(const EventCtx *x, int line, char *text, Event *e) {
    char *tok[20];
    int col[20], nt = 0;
    for (char *t = strtok(text, " \t\r"); t && nt < 20; t = strtok(NULL, " \t\r")) {
        col[nt] = (int)(t - text) + 1;
        tok[nt++] = t;
    }
    if (!nt)
        return false;
    double t;
    const char *why;
    if (!lex_number(tok[0], (int)strlen(tok[0]), &t, &why) || t < 0)
        error_at(ev_pos(x, line, col[0]), "expected a time in seconds");
    if (!(t <= x->tmax))
        error_at(ev_pos(x, line, col[0]), "an event at %s s is past %s (%g s)", tok[0], x->why, x->tmax);
    e->frame = lround(t * x->fs);
    if (nt >= 2 && !strcmp(tok[1], "set"))
        ev_set(x, line, tok, col, nt, e);
    else if (nt >= 3 && !strcmp(tok[1], "ic"))
        ev_ic(x, line, tok, col, nt, e);
    else
        error_at(ev_pos(x, line, nt >= 2 ? col[1] : col[0]), "expected 'set' or 'ic' after the time");
    return true;
}

/* Reads and checks an events file against the circuit, before the voice
 * is compiled; errors print FILE:LINE:COL, the line and a caret, and exit 1.
 * Returns the events sorted by frame (arena). */
static Event *read_events(const char *path, EventCtx *x, int *nev) {
    size_t len;
    int nline, ncol;
    char *text = read_file(path, &len);
    if (!text) {
        int e = errno;
        const char *why = read_file_refused(e);
        fprintf(stderr, "wdc: error: cannot read events file '%s': %s%s\n", path, why ? "it " : "",
                why ? why : strerror(e));
        exit(EXIT_USAGE);
    }
    if (text_nul(text, len, &nline, &ncol)) { /* what follows would be lost without a word */
        fprintf(stderr, "%s:%d:%d: error: the file contains a NUL byte\n", path, nline, ncol);
        exit(EXIT_NETLIST);
    }
    x->file = srcfile_new(path, text);
    Event *ev = arena_alloc(sizeof(Event));
    int n = 0, cap = 1, line = 0;
    for (const char *l = x->file->text; *l; line++) { /* the text after a byte-order mark, as srcfile_new keeps it */
        const char *nl = strchr(l, '\n');
        size_t len = nl ? (size_t)(nl - l) : strlen(l);
        char *copy = arena_strndup(l, len), *hash = strchr(copy, '#');
        if (hash)
            *hash = 0;
        if (n == cap) {
            Event *e2 = arena_alloc(sizeof(Event) * (size_t)cap * 2);
            memcpy(e2, ev, sizeof(Event) * (size_t)n);
            ev = e2;
            cap *= 2;
        }
        memset(&ev[n], 0, sizeof(Event));
        ev[n].order = n;
        if (ev_line(x, line + 1, copy, &ev[n]))
            n++;
        l = nl ? nl + 1 : l + len;
    }
    qsort(ev, (size_t)n, sizeof(Event), cmp_event);
    *nev = n;
    return ev;
}

/* ---- render ---- */

/* Everything a render needs that the user gave, checked and allocated
 * before the voice is compiled. */
typedef struct Render {
    long n;           /* frames */
    Signal in[64];
    Event *ev;
    int nev;
} Render;

static void render_prepare(const Opts *o, const Circuit *c, double fs, Render *rd) {
    if (c->nouts == 0) {
        fprintf(stderr, "%s: error: nothing to render: the netlist has no .output\n", c->path);
        exit(EXIT_NETLIST);
    }
    if (o->ninputs > c->ninputs)
        usage_error("more --input options than the netlist's %s", format("%d inputs", c->ninputs));
    if (c->nouts > 64 || c->ninputs > 64) {
        fprintf(stderr, "wdc: error: too many channels to render (64 at most)\n");
        exit(EXIT_TOOL);
    }
    /* --seconds, or a deck's .tran stop time */
    double secs = o->seconds > 0 ? o->seconds : c->tstop;
    long n = secs > 0 ? lround(secs * fs) : -1;
    double tmax = secs > 0 ? secs : MAX_SECONDS;
    const char *why = o->seconds > 0 ? "the end of the render" : secs > 0 ? "the end of the render (.tran)"
                                                                           : "a day, the longest render";
    for (int k = 0; k < o->ninputs; k++)
        if (is_wav(o->inputs[k])) {
            rd->in[k] = read_wav_input(o->inputs[k], fs);
            if (n < 0) {
                n = rd->in[k].n;
                tmax = (double)n / fs;
                why = format("the end of the render, which '%s' sets", o->inputs[k]);
                if (n == 0)
                    usage_error("input '%s' holds no frames, and sets the render's length: give --seconds",
                                o->inputs[k]);
            }
        }
    if (o->events) {
        EventCtx x = {NULL, c, fs, tmax, why};
        rd->ev = read_events(o->events, &x, &rd->nev);
    }
    if (n < 0 && rd->nev) /* the last event and three seconds of what follows */
        n = rd->ev[rd->nev - 1].frame + lround(3 * fs);
    if (n < 0)
        n = lround(fs);
    if (!wdrt_wav_fits((double)n, c->nouts)) { /* a WAV's sizes are 32-bit */
        fprintf(stderr, "wdc: error: %.6g s of %d output%s at %g Hz is too long for a WAV file, which holds at most "
                        "4 GiB (%.0f s)\n", n / fs, c->nouts, c->nouts > 1 ? "s" : "", fs,
                wdrt_wav_max_seconds(c->nouts, fs));
        exit(EXIT_USAGE);
    }
    /* a deck's sources that no --input drives: their time functions */
    for (int k = o->ninputs; k < c->ninputs; k++)
        if (c->input_fn[k])
            rd->in[k] = (Signal){.kind = 'f', .fn = c->input_fn[k]};
    for (int k = 0; k < o->ninputs; k++)
        if (!is_wav(o->inputs[k]))
            rd->in[k] = make_signal(o->inputs[k], fs);
    rd->n = n;
}

/* The temporary folder a voice is emitted and compiled in, removed at
 * exit: each run has its own, so renders at once never share a file. */
static char *build_dir;
static const char *build_name;

static void remove_build_dir(void) {
    if (!build_dir)
        return;
    const char *files[] = {"%s/%s.c", "%s/%s.h", "%s/%s.so"};
    for (int k = 0; k < 3; k++)
        unlink(format(files[k], build_dir, build_name));
    unlink(format("%s/wdvoice.h", build_dir));
    rmdir(build_dir);
    build_dir = NULL;
}

static int make_build_dir(const char *name) {
    const char *tmp = getenv("TMPDIR");
    char *d = format("%s/wdc.XXXXXX", tmp && *tmp ? tmp : "/tmp");
    if (!mkdtemp(d)) {
        fprintf(stderr, "wdc: error: cannot make a temporary folder '%s': %s\n", d, strerror(errno));
        return -1;
    }
    build_dir = d;
    build_name = name;
    atexit(remove_build_dir);
    return 0;
}

/* Copies FILE of the build folder into DIR through a temporary there and
 * a rename, so a reader of DIR sees the old file or the new one whole. */
static int install(const char *dir, const char *file) {
    FILE *in = fopen(format("%s/%s", build_dir, file), "rb");
    char *tmp = format("%s/.%s.XXXXXX", dir, file);
    int fd = in ? mkstemp(tmp) : -1;
    if (fd < 0) {
        if (in)
            fclose(in);
        return -1;
    }
    FILE *f = fdopen(fd, "w");
    bool ok = f && fchmod(fd, 0644) == 0;
    char buf[65536];
    for (size_t n; ok && (n = fread(buf, 1, sizeof buf, in)) > 0;) /* a voice of any size, a chunk at a time */
        ok = fwrite(buf, 1, n, f) == n;
    ok = ok && !ferror(in);
    fclose(in);
    ok = (f ? fclose(f) == 0 : (close(fd), false)) && ok;
    if (!ok || rename(tmp, format("%s/%s", dir, file)) != 0) {
        unlink(tmp);
        return -1;
    }
    return 0;
}

static int install_voice(const char *dir, const char *name) {
    if (mkdir_p(dir) != 0 || install(dir, format("%s.c", name)) || install(dir, format("%s.h", name)) ||
        install(dir, "wdvoice.h")) {
        fprintf(stderr, "wdc: error: cannot write the voice to '%s': %s\n", dir, strerror(errno));
        return EXIT_USAGE;
    }
    return 0;
}

/* Index of the first non-finite sample of n, or -1. */
static long first_nonfinite(const double *x, long n) {
    for (long i = 0; i < n; i++)
        if (!isfinite(x[i]))
            return i;
    return -1;
}

/* Where a render's samples go as they are made: the WAV file and the CSV
 * file, if asked, each written beside its place and put there once whole;
 * if the render fails, files of their names are left as they were. */
typedef struct Sink {
    const char *wav, *csv;
    char *csv_tmp; /* the CSV written beside it (the WAV writer keeps its own), or NULL: in place */
    wdrt_wav_out *w;
    FILE *f;
    bool failed; /* a write failed */
    double peak;
    bool tty, line; /* progress is shown; a progress line is open */
    double last;    /* when it was last shown */
} Sink;

/* Ends an open progress line, before a message. */
static void end_line(Sink *k) {
    if (k->line)
        fputc('\n', stderr);
    k->line = false;
}

static int sink_open(const Opts *o, const Circuit *c, double fs, Sink *k) {
    *k = (Sink){o->render, o->csv, .tty = isatty(STDERR_FILENO)};
    if (wdrt_wav_open(k->wav, c->nouts, fs, &k->w) != WDRT_OK) {
        fprintf(stderr, "wdc: error: cannot write '%s'\n", k->wav);
        return EXIT_USAGE;
    }
    if (k->csv && (k->csv_tmp = wdrt_temp_beside(k->csv), !(k->f = fopen(k->csv_tmp ? k->csv_tmp : k->csv, "w")))) {
        fprintf(stderr, "wdc: error: cannot write '%s'\n", k->csv);
        if (k->csv_tmp) /* in place, nothing was written: a file at its name stays */
            wdrt_temp_settle(k->csv_tmp, k->csv, 0);
        wdrt_wav_abort(k->w);
        return EXIT_USAGE;
    }
    return 0;
}

/* m interleaved frames of nch channels to the files. */
static void sink_put(Sink *k, const double *frames, long m, int nch) {
    for (long i = 0; i < m * nch; i++)
        k->peak = fmax(k->peak, fabs(frames[i]));
    const char *bad = NULL;
    if (wdrt_wav_append(k->w, frames, m) != WDRT_OK)
        bad = k->wav;
    for (long i = 0; k->f && !bad && i < m; i++)
        for (int c = 0; c < nch; c++)
            if (fprintf(k->f, "%.17g%c", frames[i * nch + c], c + 1 < nch ? ',' : '\n') < 0)
                bad = k->csv;
    if (bad && !k->failed) {
        end_line(k);
        fprintf(stderr, "wdc: error: cannot write '%s'\n", bad);
    }
    k->failed |= bad != NULL;
}

/* Closes the files and puts them in place; status is the render's: on
 * failure (or a write that failed) what was written goes, and files of
 * their names are left as they were.  Returns the exit status. */
static int sink_close(Sink *k, int status) {
    end_line(k);
    if (k->f && fclose(k->f) != 0 && !k->failed) {
        fprintf(stderr, "wdc: error: cannot write '%s'\n", k->csv);
        k->failed = true;
    }
    if (status == 0 && k->failed)
        status = EXIT_USAGE;
    if (status != 0)
        wdrt_wav_abort(k->w);
    else if (wdrt_wav_close(k->w) != WDRT_OK) {
        fprintf(stderr, "wdc: error: cannot write '%s'\n", k->wav);
        status = EXIT_USAGE;
    }
    if (k->csv && wdrt_temp_settle(k->csv_tmp, k->csv, status == 0) != 0 && status == 0) {
        fprintf(stderr, "wdc: error: cannot write '%s': %s\n", k->csv, strerror(errno));
        status = EXIT_USAGE;
    }
    return status;
}

/* "wdc: rendering NAME: 42%" on a terminal, at most ten times a second. */
static void show_progress(Sink *k, const char *name, long pos, long n) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    double now = (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
    if (!k->tty || now - k->last < 0.1)
        return;
    k->last = now;
    k->line = true;
    fprintf(stderr, "\r\033[Kwdc: rendering %s: %3.0f%%", name, 100.0 * (double)pos / (double)n);
    fflush(stderr);
}

/* Runs the voice over the render's frames, events applied at their frame,
 * each block's inputs made and its outputs written as it goes; returns
 * 0, or EXIT_TOOL once an output goes non-finite. */
static int render_run(const Opts *o, const Circuit *c, const wdv_class *cls, void *st, double fs, Render *rd,
                      Sink *sk) {
    enum { BLOCK = 64 };
    double *ptr_o[64], inb[64][BLOCK], outb[64][BLOCK], frames[64 * BLOCK];
    const double *ptr_i[64];
    long n = rd->n, pos = 0;
    int ei = 0;
    cls->init(st, fs);
    for (int k = 0; k < c->ninputs; k++)
        ptr_i[k] = rd->in[k].kind ? inb[k] : NULL;
    for (int k = 0; k < c->nouts; k++)
        ptr_o[k] = outb[k];
    while (pos < n) {
        for (; ei < rd->nev && rd->ev[ei].frame <= pos; ei++) {
            const Event *e = &rd->ev[ei];
            if (e->kind == 0)
                cls->set_param(st, e->param, e->value);
            else if (cls->set_ic(st, e->nic, e->ids, e->vals) != 0) {
                end_line(sk);
                fprintf(stderr, "%s: warning: initial conditions at %.6g s cannot all hold\n", o->events,
                        (double)pos / fs);
            }
        }
        long end = ei < rd->nev && rd->ev[ei].frame < n ? rd->ev[ei].frame : n;
        if (end - pos > BLOCK)
            end = pos + BLOCK;
        long m = end - pos;
        for (int k = 0; k < c->ninputs; k++)
            if (rd->in[k].kind)
                signal_fill(&rd->in[k], pos, m, fs, inb[k]);
        wdrt_render(cls, st, ptr_i, ptr_o, m, BLOCK);
        for (int k = 0; k < c->nouts; k++) {
            long i = first_nonfinite(ptr_o[k], m);
            if (i >= 0) {
                end_line(sk);
                fprintf(stderr, "wdc: error: output '%s' went non-finite at %.6g s (frame %ld): the voice "
                        "overflowed; nothing written\n", c->outs[k].name, (double)(pos + i) / fs, pos + i);
                return EXIT_TOOL;
            }
        }
        for (long i = 0; i < m; i++)
            for (int k = 0; k < c->nouts; k++)
                frames[i * c->nouts + k] = outb[k][i];
        sink_put(sk, frames, m, c->nouts);
        if (sk->failed)
            return EXIT_USAGE;
        pos = end;
        show_progress(sk, c->name, pos, n);
    }
    if (sk->tty) {
        fprintf(stderr, "\r\033[Kwdc: rendered %s to %s: %.6g s, %d channel%s at %g Hz, %s\n", c->name, sk->wav,
                (double)n / fs, c->nouts, c->nouts > 1 ? "s" : "", fs,
                sk->peak > 0 ? format("peak %.3g", sk->peak) : "silent");
        sk->line = false;
    }
    unsigned long js[WDV_SOLVE_N] = {0};
    if (cls->solve_stats)
        cls->solve_stats(st, js);
    if (js[WDV_SOLVE_CAPPED])
        fprintf(stderr, "wdc: warning: %lu of %lu joint solves of the nonlinear elements stopped at the cap of %d "
                "iterations before they converged (raise --maxit)\n", js[WDV_SOLVE_CAPPED], js[WDV_SOLVE_SOLVES],
                o->maxit);
    return 0;
}

/* Compiles the voice emitted in the build folder, loads it and renders. */
static int render(const Opts *o, const Circuit *c, double fs, Render *rd) {
    const char *cfile = format("%s/%s.c", build_dir, c->name), *so = format("%s/%s.so", build_dir, c->name);
    wdrt_voice_lib lib;
    if (isatty(STDERR_FILENO)) {
        fprintf(stderr, "wdc: compiling %s", c->name);
        fflush(stderr);
    }
    wdrt_result r = wdrt_voice_compile(cfile, so, NULL, "-O2");
    if (isatty(STDERR_FILENO))
        fputs("\r\033[K", stderr);
    if (r == WDRT_OK)
        r = wdrt_voice_open(so, c->name, &lib);
    if (r != WDRT_OK) {
        fprintf(stderr, "wdc: error: %s: %s\n", cfile, wdrt_result_str(r));
        return EXIT_TOOL;
    }
    const wdv_class *cls = lib.cls;
    if (cls->n_params != c->nparams || cls->n_ic_targets > 2 * (c->nnodes - 1) || cls->n_outputs != c->nouts)
        die("the compiled voice does not match its circuit");
    void *st = NULL;
    if (posix_memalign(&st, 64, (cls->state_size + 63) / 64 * 64) != 0) {
        fprintf(stderr, "wdc: error: out of memory for the voice's state (%zu bytes)\n", cls->state_size);
        wdrt_voice_close(&lib);
        return EXIT_TOOL;
    }
    Sink sk;
    int status = sink_open(o, c, fs, &sk);
    if (status == 0)
        status = sink_close(&sk, render_run(o, c, cls, st, fs, rd, &sk));
    free(st);
    wdrt_voice_close(&lib);
    return status;
}

/* What a strike target that sets nothing would need, for its message. */
static const char *ic_needs(char fn, const char *node) {
    return fn == 'v' ? format("no capacitor (mass) joins '%s' to ground", node)
                     : format("no inductor (spring) joins '%s' to ground, and no contact or displacement probe is at it",
                              node);
}

/* The netlist's .ic targets and the events' strikes against the targets
 * the voice can set (wdf_ic_settable): one that sets nothing is an error
 * at its place; the events' ids become the voice's (ic_targets lists only
 * the targets that set something). */
static bool settable_ids(const Wdf *w, Render *rd) {
    const Circuit *c = w->c;
    int n = 2 * (c->nnodes - 1);
    bool *set = arena_alloc(sizeof(bool) * (size_t)(n + 1));
    int *id = arena_alloc(sizeof(int) * (size_t)(n + 1));
    wdf_ic_settable(w, set);
    for (int k = 0, m = 0; k < n; k++)
        id[k] = set[k] ? m++ : -1;
    jmp_buf jb;
    diag.jmp = &jb;
    if (setjmp(jb)) {
        diag.jmp = NULL;
        return false;
    }
    for (int k = 0; k < c->nics; k++) {
        const IcSpec *ic = &c->ics[k];
        if (ic->node > 0 && !set[2 * (ic->node - 1) + (ic->fn == 'x')])
            error_at(ic->pos, "initial condition %c(%s) sets nothing: %s", ic->fn, c->nodes[ic->node],
                     ic_needs(ic->fn, c->nodes[ic->node]));
    }
    for (int e = 0; rd && e < rd->nev; e++)
        for (int k = 0; k < rd->ev[e].nic; k++) {
            int full = rd->ev[e].ids[k], nd = full / 2 + 1;
            char fn = full % 2 ? 'x' : 'v';
            if (id[full] < 0)
                error_at(rd->ev[e].at[k], "strike target %c(%s) sets nothing: %s", fn, c->nodes[nd],
                         ic_needs(fn, c->nodes[nd]));
            rd->ev[e].ids[k] = id[full];
        }
    diag.jmp = NULL;
    return true;
}

/* wdf_build and scatter_check, netlist errors unwinding to here: NULL. */
static Wdf *structure(Circuit *c, double fs) {
    jmp_buf jb;
    diag.jmp = &jb;
    if (setjmp(jb)) {
        diag.jmp = NULL;
        return NULL;
    }
    Wdf *w = wdf_build(c, fs);
    scatter_check(w, 1e-9);
    diag.jmp = NULL;
    return w;
}

/* The voice as C in eo->outdir, or (lv2) an LV2 bundle in lv2; returns
 * the exit status. */
static int emit(Wdf *w, const EmitOpts *eo, const char *lv2) {
    jmp_buf jb;
    diag.jmp = &jb;
    if (setjmp(jb)) {
        diag.jmp = NULL;
        return EXIT_NETLIST;
    }
    int r = lv2 ? lv2_bundle(w, eo, lv2) : emit_voice(w, eo);
    diag.jmp = NULL;
    if (lv2)
        return r == 0 ? 0 : r == LV2_ENETLIST ? EXIT_NETLIST : r == LV2_EIO ? EXIT_USAGE : EXIT_TOOL;
    if (r != 0)
        fprintf(stderr, "wdc: error: cannot write the voice to '%s': %s\n", eo->outdir, strerror(errno));
    return r == 0 ? 0 : EXIT_TOOL;
}

/* wg_choose, and the loops at the rate fs --rate asks for (0: none; a
 * host such as wdrt checks a voice at its rate with --check --rate),
 * netlist errors unwinding to here: false. */
static bool choose_orders(Circuit *c, double fs) {
    jmp_buf jb;
    diag.jmp = &jb;
    if (setjmp(jb)) {
        diag.jmp = NULL;
        return false;
    }
    wg_choose(c);
    if (fs > 0 && fs != c->rate)
        wg_check_rate(c, fs);
    diag.jmp = NULL;
    return true;
}

int main(int argc, char **argv) {
    Opts o = parse_args(argc, argv);
    Circuit *c = wdc_elaborate_at(o.file, o.rate);
    if (!c || !choose_orders(c, o.rate))
        return EXIT_NETLIST;
    if (o.dump_elab)
        circuit_dump(c, stdout);
    double fs = o.rate > 0 ? o.rate : c->rate;
    Render rd = {0};
    if (o.render) /* what the user gave is checked before any compiling */
        render_prepare(&o, c, fs, &rd);
    Wdf *w = structure(c, fs);
    if (!w || !settable_ids(w, o.render ? &rd : NULL))
        return EXIT_NETLIST;
    if (o.dump_wdf)
        wdf_dump(w, stdout);
    if (o.tableau)
        scatter_print_tableau(w, stdout);
    if (o.dot) {
        FILE *f = fopen(o.dot, "w");
        if (!f) {
            fprintf(stderr, "wdc: error: cannot write '%s'\n", o.dot);
            return EXIT_USAGE;
        }
        wdf_dot(w, f);
        fclose(f);
    }
    if (o.check || ((o.dot || o.tableau) && !o.render && !o.has_outdir)) /* -o DIR: the voice as well */
        return 0;
    EmitOpts eo = {.single = o.single, .energy = o.energy, .no_skip = o.no_skip, .batch = o.batch, .outdir = o.outdir, .solver = o.solver,
                   .table = o.table, .tol = o.tol, .fast_tol = o.fast_tol, .maxit = o.maxit};
    if (o.lv2)
        return emit(w, &eo, o.lv2);
    /* the voice is emitted in a folder of this run's own; -o DIR (or no
     * --render) then gets each file renamed into place */
    if (make_build_dir(c->name) != 0)
        return EXIT_TOOL;
    eo.outdir = build_dir;
    int status = emit(w, &eo, NULL);
    if (status == 0 && (!o.render || o.has_outdir))
        status = install_voice(o.outdir, c->name);
    if (status == 0 && o.render)
        status = render(&o, c, fs, &rd);
    return status;
}
