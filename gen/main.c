/* main.c: the wdc command line.  The pipeline runs straight through:
 * load (parse + elaborate) -> structure -> check -> emit -> [render]. */
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "gen.h"
#include "wdrt.h"

enum { EXIT_NETLIST = 1, EXIT_USAGE = 2, EXIT_TOOL = 3 };

typedef struct Opts {
    const char *file, *outdir, *render, *csv, *dot, *events, *lv2;
    const char *inputs[16];
    int ninputs;
    double seconds, rate;
    bool check, single, dump_elab, dump_wdf, tableau, has_outdir;
    Solver solver;
    int table, maxit;
    double tol;
} Opts;

static void usage(FILE *f) {
    fprintf(f,
        "usage: wdc FILE.wdn [-o DIR] [--precision double|float]\n"
        "       wdc FILE.wdn --check\n"
        "       wdc FILE.wdn --render OUT.wav [--input SPEC]... [--seconds S] [--rate HZ]\n"
        "                    [--csv OUT.csv] [--events FILE]\n"
        "       wdc FILE.wdn --lv2 DIR [--precision double|float]  an LV2 plugin bundle of the voice\n"
        "       wdc FILE.wdn --dot OUT.dot\n"
        "       wdc FILE.wdn --tableau            each root adaptor's tableau and solved matrix\n"
        "nonlinear elements: [--solver newton|omega|pwl] [--table N] [--tol T] [--maxit N]\n"
        "SPEC: impulse[:A] | step[:A] | sine:FREQ[:A] | noise[:A] | FILE.wav (one per .input, in order)\n"
        "-delab, -dwdf print the elaborated circuit or the adaptor tree.\n"
        "exit status: 0 ok, 1 netlist error, 2 usage error, 3 toolchain or internal error\n");
}

static void usage_error(const char *fmt, const char *arg) {
    fprintf(stderr, "wdc: ");
    fprintf(stderr, fmt, arg);
    fprintf(stderr, "\n");
    usage(stderr);
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
        else if (!strcmp(a, "--render")) o.render = TAKE();
        else if (!strcmp(a, "--csv")) o.csv = TAKE();
        else if (!strcmp(a, "--dot")) o.dot = TAKE();
        else if (!strcmp(a, "--events")) o.events = TAKE();
        else if (!strcmp(a, "--seconds")) o.seconds = number_arg(a, TAKE());
        else if (!strcmp(a, "--rate")) o.rate = number_arg(a, TAKE());
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
                     : !strcmp(v, "pwl") ? SOLVER_PWL : SOLVER_DEFAULT;
            if (o.solver == SOLVER_DEFAULT)
                usage_error("--solver takes newton, omega or pwl, not '%s'", v);
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
            o.tol = number_arg(a, TAKE());
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
    return o;
}

/* ---- input signals ---- */

typedef struct Signal {
    double *data;
    long n;
} Signal;

static Signal make_signal(const char *spec, double fs, long n, int ninputs_expected) {
    (void)ninputs_expected;
    Signal s = {calloc((size_t)n + 1, sizeof(double)), n};
    char kind[32] = {0};
    double a = 1, f = 0;
    const char *colon = strchr(spec, ':');
    size_t klen = colon ? (size_t)(colon - spec) : strlen(spec);
    if (klen >= sizeof kind)
        klen = sizeof kind - 1;
    memcpy(kind, spec, klen);
    const char *rest = colon ? colon + 1 : NULL;
    if (!strcmp(kind, "sine")) {
        if (!rest)
            usage_error("sine input needs a frequency: sine:FREQ[:A], got '%s'", spec);
        char *end;
        f = strtod(rest, &end);
        if (end == rest || !(f >= 0) || (*end && *end != ':'))
            usage_error("bad sine frequency in '%s'", spec);
        rest = *end == ':' ? end + 1 : NULL;
    }
    if (rest) {
        char *end;
        a = strtod(rest, &end);
        if (end == rest || *end || !isfinite(a))
            usage_error("bad amplitude in input spec '%s'", spec);
    }
    uint32_t seed = 0x9e3779b9u;
    for (long i = 0; i < n; i++) {
        if (!strcmp(kind, "impulse"))
            s.data[i] = i == 0 ? a : 0;
        else if (!strcmp(kind, "step"))
            s.data[i] = a;
        else if (!strcmp(kind, "sine"))
            s.data[i] = a * sin(2 * M_PI * f * (double)i / fs);
        else if (!strcmp(kind, "noise")) {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            s.data[i] = a * (2.0 * seed / 4294967295.0 - 1);
        } else
            usage_error("unknown input spec '%s' (impulse, step, sine:FREQ, noise or a .wav file)", spec);
    }
    return s;
}

static bool is_wav(const char *spec) {
    size_t n = strlen(spec);
    return n > 4 && !strcasecmp(spec + n - 4, ".wav");
}

/* ---- events ---- */

typedef struct Event {
    long frame;
    int order; /* line order, which keeps events at one time in sequence */
    int kind; /* 0 set param, 1 ic */
    int param;
    double value;
    int nic;
    int ids[8];
    double vals[8];
} Event;

static int cmp_event(const void *a, const void *b) {
    const Event *x = a, *y = b;
    return x->frame < y->frame ? -1 : x->frame > y->frame ? 1 : x->order - y->order;
}

static void event_error(const char *path, int line, int col, const char *msg) {
    fprintf(stderr, "%s:%d:%d: error: %s\n", path, line, col, msg);
    exit(EXIT_NETLIST);
}

static Event *read_events(const char *path, const wdv_class *cls, double fs, int *nev) {
    char *text = read_file(path, NULL);
    if (!text) {
        fprintf(stderr, "wdc: error: cannot read events file '%s'\n", path);
        exit(EXIT_USAGE);
    }
    Event *ev = arena_alloc(sizeof(Event) * 1);
    int n = 0, cap = 1, line = 0;
    for (char *l = text; l && *l; ) {
        char *nl = strchr(l, '\n');
        if (nl)
            *nl = 0;
        line++;
        char *hash = strchr(l, '#');
        if (hash)
            *hash = 0;
        char *tok[20];
        int nt = 0;
        for (char *t = strtok(l, " \t\r"); t && nt < 20; t = strtok(NULL, " \t\r"))
            tok[nt++] = t;
        if (nt) {
            if (n == cap) {
                Event *e2 = arena_alloc(sizeof(Event) * (size_t)cap * 2);
                memcpy(e2, ev, sizeof(Event) * (size_t)n);
                ev = e2;
                cap *= 2;
            }
            Event *e = &ev[n];
            double t;
            const char *why;
            int col = (int)(tok[0] - l) + 1;
            if (!lex_number(tok[0], (int)strlen(tok[0]), &t, &why) || t < 0)
                event_error(path, line, col, "expected a time in seconds");
            e->frame = lround(t * fs);
            e->order = n;
            if (nt >= 2 && !strcmp(tok[1], "set")) {
                if (nt != 4)
                    event_error(path, line, (int)(tok[1] - l) + 1, "expected: TIME set PARAM VALUE");
                e->kind = 0;
                e->param = -1;
                for (int i = 0; i < cls->n_params; i++)
                    if (!strcmp(cls->params[i].name, tok[2]))
                        e->param = i;
                if (e->param < 0)
                    event_error(path, line, (int)(tok[2] - l) + 1, format("unknown param '%s'", tok[2]));
                if (!lex_number(tok[3], (int)strlen(tok[3]), &e->value, &why))
                    event_error(path, line, (int)(tok[3] - l) + 1, "expected a number");
            } else if (nt >= 3 && !strcmp(tok[1], "ic")) {
                e->kind = 1;
                for (int k = 2; k < nt; k++) {
                    char *eq = strchr(tok[k], '=');
                    int col2 = (int)(tok[k] - l) + 1;
                    if (!eq || e->nic == 8)
                        event_error(path, line, col2, "expected v(node)=VALUE or x(node)=VALUE");
                    *eq = 0;
                    int id = -1;
                    for (int i = 0; i < cls->n_ic_targets; i++)
                        if (!strcmp(cls->ic_targets[i].name, tok[k]))
                            id = i;
                    if (id < 0)
                        event_error(path, line, col2, format("unknown initial-condition target '%s'", tok[k]));
                    if (!lex_number(eq + 1, (int)strlen(eq + 1), &e->vals[e->nic], &why))
                        event_error(path, line, (int)(eq + 1 - l) + 1, "expected a number");
                    e->ids[e->nic++] = id;
                }
            } else {
                event_error(path, line, nt >= 2 ? (int)(tok[1] - l) + 1 : col, "expected 'set' or 'ic' after the time");
            }
            n++;
        }
        l = nl ? nl + 1 : NULL;
    }
    qsort(ev, (size_t)n, sizeof(Event), cmp_event);
    *nev = n;
    return ev;
}

/* ---- render ---- */

static int render(const Opts *o, const Circuit *c, const char *cfile, double fs) {
    char tmpl[] = "/tmp/wdc.XXXXXX";
    if (!mkdtemp(tmpl)) {
        fprintf(stderr, "wdc: error: cannot make a temporary directory: %s\n", strerror(errno));
        return EXIT_TOOL;
    }
    const char *so = format("%s/%s.so", tmpl, c->name);
    wdrt_voice_lib lib;
    wdrt_result r = wdrt_voice_compile(cfile, so, NULL, "-O2");
    if (r == WDRT_OK)
        r = wdrt_voice_open(so, c->name, &lib);
    unlink(so);
    rmdir(tmpl);
    if (r != WDRT_OK) {
        fprintf(stderr, "wdc: error: %s: %s\n", cfile, wdrt_result_str(r));
        return EXIT_TOOL;
    }
    const wdv_class *cls = lib.cls;
    if (c->nouts == 0) {
        fprintf(stderr, "%s: error: nothing to render: the netlist has no .output\n", c->path);
        return EXIT_NETLIST;
    }
    if (o->ninputs > c->ninputs)
        usage_error("more --input options than the netlist's %s", format("%d inputs", c->ninputs));
    long n = o->seconds > 0 ? lround(o->seconds * fs) : -1;
    Signal in[16] = {{0}};
    for (int k = 0; k < o->ninputs; k++)
        if (is_wav(o->inputs[k])) {
            int nch;
            double wfs;
            double *frames;
            long nf;
            if (wdrt_wav_read(o->inputs[k], &nch, &wfs, &frames, &nf) != WDRT_OK) {
                fprintf(stderr, "wdc: error: cannot read input '%s'\n", o->inputs[k]);
                return EXIT_USAGE;
            }
            if (fabs(wfs - fs) > 0.5)
                usage_error("input file rate differs from the render rate (%s)", format("%g Hz vs %g Hz", wfs, fs));
            in[k].data = malloc(sizeof(double) * (size_t)(nf + 1));
            for (long i = 0; i < nf; i++)
                in[k].data[i] = frames[i * nch];
            in[k].n = nf;
            free(frames);
            if (n < 0)
                n = nf;
        }
    int nev = 0;
    Event *ev = o->events ? read_events(o->events, cls, fs, &nev) : NULL;
    if (n < 0 && nev) /* the last event and three seconds of what follows */
        n = ev[nev - 1].frame + lround(3 * fs);
    if (n < 0)
        n = lround(fs);
    for (int k = 0; k < o->ninputs; k++) {
        if (!is_wav(o->inputs[k])) {
            in[k] = make_signal(o->inputs[k], fs, n, c->ninputs);
        } else if (in[k].n < n) { /* pad a short file with silence */
            double *d = calloc((size_t)n + 1, sizeof(double));
            memcpy(d, in[k].data, sizeof(double) * (size_t)in[k].n);
            free(in[k].data);
            in[k].data = d;
            in[k].n = n;
        }
    }
    double *outbuf = calloc((size_t)n * (size_t)c->nouts + 1, sizeof(double));
    double *ptr_o[64];
    const double *ptr_i[64];
    void *st = NULL;
    if (posix_memalign(&st, 64, (cls->state_size + 63) / 64 * 64) != 0)
        st = NULL;
    if (!outbuf || !st || c->nouts > 64 || c->ninputs > 64) {
        fprintf(stderr, "wdc: error: out of memory or too many channels\n");
        return EXIT_TOOL;
    }
    double *chan = calloc((size_t)n * (size_t)c->nouts + 1, sizeof(double));
    cls->init(st, fs);
    long pos = 0;
    int ei = 0;
    while (pos < n) {
        while (ei < nev && ev[ei].frame <= pos) {
            if (ev[ei].kind == 0)
                cls->set_param(st, ev[ei].param, ev[ei].value);
            else if (cls->set_ic(st, ev[ei].nic, ev[ei].ids, ev[ei].vals) != 0)
                fprintf(stderr, "%s: warning: initial conditions at %.6g s cannot all hold\n", o->events,
                        (double)pos / fs);
            ei++;
        }
        long end = ei < nev && ev[ei].frame < n ? ev[ei].frame : n;
        if (end - pos > 64)
            end = pos + 64;
        for (int k = 0; k < c->ninputs; k++)
            ptr_i[k] = k < o->ninputs ? in[k].data + pos : NULL;
        for (int k = 0; k < c->nouts; k++)
            ptr_o[k] = chan + (size_t)k * (size_t)n + (size_t)pos;
        wdrt_render(cls, st, ptr_i, ptr_o, end - pos, 64);
        pos = end;
    }
    for (long i = 0; i < n; i++)
        for (int k = 0; k < c->nouts; k++)
            outbuf[i * c->nouts + k] = chan[(size_t)k * (size_t)n + (size_t)i];
    int status = 0;
    if (wdrt_wav_write(o->render, c->nouts, fs, outbuf, n) != WDRT_OK) {
        fprintf(stderr, "wdc: error: cannot write '%s'\n", o->render);
        status = EXIT_USAGE;
    }
    if (o->csv) {
        FILE *f = fopen(o->csv, "w");
        if (!f) {
            fprintf(stderr, "wdc: error: cannot write '%s'\n", o->csv);
            status = EXIT_USAGE;
        } else {
            for (long i = 0; i < n; i++)
                for (int k = 0; k < c->nouts; k++)
                    fprintf(f, "%.17g%c", outbuf[i * c->nouts + k], k + 1 < c->nouts ? ',' : '\n');
            if (fclose(f) != 0)
                status = EXIT_USAGE;
        }
    }
    free(st);
    free(chan);
    free(outbuf);
    for (int k = 0; k < o->ninputs; k++)
        free(in[k].data);
    wdrt_voice_close(&lib);
    return status;
}

int main(int argc, char **argv) {
    Opts o = parse_args(argc, argv);
    Circuit *c = wdc_load(o.file);
    if (!c)
        return EXIT_NETLIST;
    if (o.dump_elab)
        circuit_dump(c, stdout);
    double fs = o.rate > 0 ? o.rate : c->rate;
    jmp_buf jb;
    diag.jmp = &jb;
    if (setjmp(jb))
        return EXIT_NETLIST;
    Wdf *w = wdf_build(c, fs);
    scatter_check(w, 1e-9);
    diag.jmp = NULL;
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
    if (o.check || ((o.dot || o.tableau) && !o.render))
        return 0;
    EmitOpts eo = {.single = o.single, .outdir = o.outdir, .solver = o.solver, .table = o.table, .tol = o.tol,
                   .maxit = o.maxit};
    if (o.lv2) {
        diag.jmp = &jb;
        int r = lv2_bundle(w, &eo, o.lv2);
        diag.jmp = NULL;
        return r == 0 ? 0 : r == LV2_ENETLIST ? EXIT_NETLIST : r == LV2_EIO ? EXIT_USAGE : EXIT_TOOL;
    }
    diag.jmp = &jb;
    int emitted = mkdir_p(o.outdir) == 0 ? emit_voice(w, &eo) : -1;
    diag.jmp = NULL;
    if (emitted != 0) {
        fprintf(stderr, "wdc: error: cannot write the voice to '%s': %s\n", o.outdir, strerror(errno));
        return EXIT_USAGE;
    }
    if (o.render)
        return render(&o, c, format("%s/%s.c", o.outdir, c->name), fs);
    return 0;
}
