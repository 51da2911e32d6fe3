/* lv2.c: an LV2 plugin bundle of a voice (wdc FILE --lv2 DIR).
 *
 * The bundle holds manifest.ttl, NAME.ttl and NAME.so: the voice's C from
 * emit.c and a wrapper (templates/lv2.c.tmpl) compiled as one translation
 * unit in a temporary directory, so the plugin needs only libc and libm.
 * What only the netlist knows is decided here and written into the
 * wrapper as constants: whether the voice is an instrument (it has .ic
 * values, which a MIDI note strikes), the strike itself, and which params
 * a note sets (the pitch) and a note-off raises (the damper). */
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "gen.h"
#include "wdrt.h"

extern const char tmpl_lv2_c[], tmpl_lv2_manifest[], tmpl_lv2_plugin[];

enum { POOL = 16, SPARES = 4 };

/* ---- text ---- */

static int write_text(const char *path, const char *text) {
    FILE *f = fopen(path, "w");
    if (!f)
        return -1;
    size_t n = strlen(text);
    int ok = fwrite(text, 1, n, f) == n;
    return fclose(f) == 0 && ok ? 0 : -1;
}

/* A string literal, for Turtle or C (the same escapes serve both). */
static const char *quoted(const char *s) {
    const char *out = "\"";
    for (; *s; s++)
        out = *s == '"' || *s == '\\' ? format("%s\\%c", out, *s)
            : *s == '\n'              ? format("%s\\n", out)
                                      : format("%s%c", out, *s);
    return format("%s\"", out);
}

/* A Turtle number that reads back as the same double, in the fewest
 * digits that do (a decimal point or an exponent makes it a decimal or a
 * double, not an integer). */
static const char *ttl_number(double v) {
    const char *s = format("%.15g", v);
    for (int digits = 16; strtod(s, NULL) != v && digits <= 17; digits++)
        s = format("%.*g", digits, v);
    return strpbrk(s, ".e") ? s : format("%s.0", s);
}

/* ---- ports ---- */

/* A unit of the LV2 units extension for a param's unit=, or a units:Unit
 * of its own that shows the unit as written; NULL for no unit. */
static const char *ttl_unit(const char *unit) {
    static const char *const known[][2] = {
        {"Hz", "hz"}, {"kHz", "khz"}, {"MHz", "mhz"}, {"s", "s"}, {"ms", "ms"}, {"min", "min"},
        {"dB", "db"}, {"cent", "cent"}, {"cents", "cent"}, {"semitone", "semitone12TET"},
        {"oct", "oct"}, {"m", "m"}, {"cm", "cm"}, {"mm", "mm"}, {"km", "km"}, {"%", "pc"},
        {"deg", "degree"}, {"bpm", "bpm"},
    };
    if (!*unit)
        return NULL;
    for (size_t i = 0; i < sizeof known / sizeof known[0]; i++)
        if (!strcmp(unit, known[i][0]))
            return format("units:%s", known[i][1]);
    const char *render = "%f ";
    for (const char *p = unit; *p; p++) /* units:render is a printf format */
        render = format("%s%s", render, *p == '%' ? "%%" : format("%c", *p));
    return format("[\n            a units:Unit ;\n            rdfs:label %s ;\n            units:symbol %s ;\n"
                  "            units:render %s\n        ]", quoted(unit), quoted(unit), quoted(render));
}

/* An LV2 symbol for `name` (a C identifier) that no earlier port has. */
static const char *port_symbol(const char *name, const char **taken, int ntaken) {
    char *s = arena_strdup(*name ? name : "port");
    for (char *p = s; *p; p++)
        if (!(*p == '_' || (*p >= 'a' && *p <= 'z') || (*p >= 'A' && *p <= 'Z') || (*p >= '0' && *p <= '9')))
            *p = '_';
    const char *base = *s >= '0' && *s <= '9' ? format("_%s", s) : s, *sym = base;
    for (int k = 2, i = 0; i < ntaken; i++)
        if (!strcmp(taken[i], sym)) {
            sym = format("%s_%d", base, k++);
            i = -1;
        }
    return sym;
}

/* The param a MIDI note sets: the first whose unit is Hz and whose name is
 * f0, f, freq, frequency or pitch; -1 if there is none. */
static int pitch_param(const Circuit *c) {
    static const char *const names[] = {"f0", "f", "freq", "frequency", "pitch"};
    for (int i = 0; i < c->nparams; i++)
        for (size_t k = 0; k < sizeof names / sizeof names[0]; k++)
            if (!strcmp(c->params[i].unit, "Hz") && !strcmp(c->params[i].name, names[k]))
                return i;
    return -1;
}

/* The param a note-off raises to its max: the first named damp or damper,
 * or whose name starts with dmp; -1 if there is none. */
static int damper_param(const Circuit *c) {
    for (int i = 0; i < c->nparams; i++) {
        const char *n = c->params[i].name;
        if (!strcmp(n, "damp") || !strcmp(n, "damper") || !strncmp(n, "dmp", 3))
            return i;
    }
    return -1;
}

typedef struct Plan {
    const Circuit *c;
    bool instrument;  /* it has .ic values: notes from a pool, a MIDI input */
    int pitch, damper; /* params notes set, or -1 (always -1 in an effect) */
} Plan;

/* The ports written so far: their Turtle and their symbols. */
typedef struct Ports {
    const char *ttl;
    const char **sym;
    int n;
} Ports;

/* Appends a port of the given classes and further properties (each
 * starting " ;\n"); its symbol comes from `name`. */
static void add_port(Ports *ps, const char *name, const char *classes, const char *props) {
    const char *sym = port_symbol(name, ps->sym, ps->n);
    ps->ttl = format("%s%s[\n        a %s ;\n        lv2:index %d ;\n        lv2:symbol \"%s\" ;\n        lv2:name %s%s\n    ]",
                     ps->ttl, ps->n ? " , " : "", classes, ps->n, sym, quoted(name), props);
    ps->sym[ps->n++] = sym;
}

static void control_port(Ports *ps, const Plan *pl, int i) {
    const Param *p = &pl->c->params[i];
    const char *unit = ttl_unit(p->unit);
    const char *props = format(" ;\n        lv2:default %s ;\n        lv2:minimum %s ;\n        lv2:maximum %s",
                               ttl_number(p->def), ttl_number(p->min), ttl_number(p->max));
    if (unit)
        props = format("%s ;\n        units:unit %s", props, unit);
    if (i == pl->pitch || i == pl->damper)
        props = format("%s ;\n        lv2:portProperty pprops:notOnGUI ;\n        rdfs:comment %s", props,
                       quoted(i == pl->pitch ? "set by each MIDI note; the port is not read"
                                             : "raised to its maximum by note-offs; the port is not read"));
    add_port(ps, p->name, "lv2:InputPort , lv2:ControlPort", props);
}

/* Every port in index order: inputs, outputs, params, MIDI. */
static const char *ports_ttl(const Plan *pl) {
    const Circuit *c = pl->c;
    Ports ps = {.ttl = "", .sym = arena_alloc(sizeof(char *) * (size_t)(c->ninputs + c->nouts + c->nparams + 1))};
    for (int i = 0; i < c->ninputs; i++)
        add_port(&ps, c->inputs[i], "lv2:InputPort , lv2:AudioPort", "");
    for (int i = 0; i < c->nouts; i++)
        add_port(&ps, c->outs[i].name, "lv2:OutputPort , lv2:AudioPort", "");
    for (int i = 0; i < c->nparams; i++)
        control_port(&ps, pl, i);
    if (pl->instrument)
        add_port(&ps, "midi", "lv2:InputPort , atom:AtomPort",
                 " ;\n        atom:bufferType atom:Sequence ;\n        atom:supports midi:MidiEvent ;\n"
                 "        lv2:designation lv2:control");
    return ps.ttl;
}

/* ---- the wrapper ---- */

/* The .ic strike: target names, values at the params' defaults, and which
 * are velocities (scaled by a note's velocity / 100). */
static void strike(const Circuit *c, const char **names, const char **values, const char **vel) {
    const double *p = circuit_defaults(c);
    *names = *values = *vel = "";
    for (int i = 0; i < c->nics; i++) {
        const IcSpec *ic = &c->ics[i];
        double v = expr_eval(ic->val, p);
        if (!isfinite(v))
            error_at(ic->pos, "initial condition %c(%s) is %g at the params' defaults", ic->fn,
                     c->nodes[ic->node], v);
        if (expr_params(ic->val))
            warn_at(ic->pos, "the LV2 plugin strikes with %c(%s) = %g, its value at the params' defaults", ic->fn,
                    c->nodes[ic->node], v);
        const char *sep = i ? ", " : "";
        *names = format("%s%s%s", *names, sep, quoted(format("%c(%s)", ic->fn, c->nodes[ic->node])));
        *values = format("%s%s%.17g", *values, sep, v);
        *vel = format("%s%s%d", *vel, sep, ic->fn == 'v');
    }
}

static const char *wrapper_c(const Plan *pl, const char *uri) {
    const Circuit *c = pl->c;
    const char *names, *values, *vel;
    strike(c, &names, &values, &vel);
    Hole holes[] = {
        {"name", c->name}, {"version", WDC_VERSION}, {"source", c->path}, {"uri", uri},
        {"n_inputs", format("%d", c->ninputs)}, {"n_outputs", format("%d", c->nouts)},
        {"n_params", format("%d", c->nparams)}, {"instrument", pl->instrument ? "1" : "0"},
        {"pool", format("%d", pl->instrument ? POOL : 1)}, {"spares", format("%d", pl->instrument ? SPARES : 0)},
        {"pitch", format("%d", pl->pitch)}, {"damper", format("%d", pl->damper)},
        {"n_ic", format("%d", c->nics)}, {"ic_names", format("{%s}", c->nics ? names : "\"\"")},
        {"ic_values", format("{%s}", c->nics ? values : "0")}, {"ic_velocity", format("{%s}", c->nics ? vel : "0")},
    };
    return fill(tmpl_lv2_c, holes, (int)(sizeof holes / sizeof holes[0]));
}

/* ---- the bundle ---- */

/* A control port needs a range: a host draws it and clamps to it. */
static void check_ranges(const Circuit *c) {
    for (int i = 0; i < c->nparams; i++)
        if (!isfinite(c->params[i].min) || !isfinite(c->params[i].max))
            error_at(c->params[i].pos, "param '%s' needs min= and max= to become an LV2 control port",
                     c->params[i].name);
}

static void remove_sources(const char *tmp, const char *name) {
    unlink(format("%s/%s.c", tmp, name));
    unlink(format("%s/%s.h", tmp, name));
    unlink(format("%s/%s_lv2.c", tmp, name));
    unlink(format("%s/wdvoice.h", tmp));
    rmdir(tmp);
}

/* Emits the voice and the wrapper into tmp and compiles them into so. */
static int build(const Wdf *w, const EmitOpts *eo, const Plan *pl, const char *uri, const char *tmp,
                 const char *so) {
    EmitOpts o = *eo;
    o.outdir = tmp;
    const char *src = format("%s/%s_lv2.c", tmp, pl->c->name);
    if (emit_voice(w, &o) != 0 || write_text(src, wrapper_c(pl, uri)) != 0) {
        fprintf(stderr, "wdc: error: cannot write the plugin's C to '%s': %s\n", tmp, strerror(errno));
        return LV2_EIO;
    }
    wdrt_result r = wdrt_voice_compile(src, so, NULL, "-O2 -fvisibility=hidden");
    if (r != WDRT_OK) {
        fprintf(stderr, "wdc: error: cannot build '%s': %s\n", so, wdrt_result_str(r));
        return LV2_ETOOL;
    }
    return 0;
}

/* build() in a temporary directory that is removed afterwards, also when
 * a netlist error unwinds through here. */
static int build_in_tmp(const Wdf *w, const EmitOpts *eo, const Plan *pl, const char *uri, const char *so) {
    char tmp[] = "/tmp/wdc-lv2.XXXXXX";
    if (!mkdtemp(tmp)) {
        fprintf(stderr, "wdc: error: cannot make a temporary directory: %s\n", strerror(errno));
        return LV2_EIO;
    }
    jmp_buf jb, *outer = diag.jmp;
    diag.jmp = &jb;
    if (setjmp(jb)) {
        remove_sources(tmp, pl->c->name);
        diag.jmp = outer;
        if (outer)
            longjmp(*outer, 1);
        exit(1);
    }
    int r = build(w, eo, pl, uri, tmp, so);
    diag.jmp = outer;
    remove_sources(tmp, pl->c->name);
    return r;
}

int lv2_bundle(const Wdf *w, const EmitOpts *eo, const char *dir) {
    const Circuit *c = w->c;
    Plan pl = {.c = c, .instrument = c->nics > 0, .pitch = -1, .damper = -1};
    if (pl.instrument) {
        pl.pitch = pitch_param(c);
        pl.damper = damper_param(c);
    }
    if (c->nouts == 0) {
        fprintf(stderr, "%s: error: nothing to export: the netlist has no .output\n", c->path);
        return LV2_ENETLIST;
    }
    check_ranges(c);
    if (!c->ninputs && !pl.instrument)
        fprintf(stderr, "%s: warning: no .input and no .ic: the plugin only outputs silence\n", c->path);
    const char *uri = format("urn:wdc:voice:%s", c->name);
    const char *classes = pl.instrument ? "lv2:Plugin , lv2:InstrumentPlugin" : "lv2:Plugin";
    Hole holes[] = {
        {"name", c->name}, {"version", WDC_VERSION}, {"uri", uri}, {"classes", classes},
        {"comment", format("A wave-digital model compiled by wdc %s from %s.", WDC_VERSION, c->path)},
        {"features", pl.instrument ? "    lv2:requiredFeature urid:map ;\n"
                                      "    lv2:optionalFeature <http://lv2plug.in/ns/ext/worker#schedule> ;\n"
                                      "    lv2:extensionData <http://lv2plug.in/ns/ext/worker#interface> ;\n"
                                    : ""}, {"ports", ports_ttl(&pl)},
    };
    int nh = (int)(sizeof holes / sizeof holes[0]);
    if (mkdir_p(dir) != 0) {
        fprintf(stderr, "wdc: error: cannot make the bundle '%s': %s\n", dir, strerror(errno));
        return LV2_EIO;
    }
    /* the binary first: a bundle whose compilation failed has no .ttl that
     * would announce a plugin */
    int r = build_in_tmp(w, eo, &pl, uri, format("%s/%s.so", dir, c->name));
    if (r == 0 && (write_text(format("%s/manifest.ttl", dir), fill(tmpl_lv2_manifest, holes, nh)) != 0 ||
                   write_text(format("%s/%s.ttl", dir, c->name), fill(tmpl_lv2_plugin, holes, nh)) != 0)) {
        fprintf(stderr, "wdc: error: cannot write the bundle '%s': %s\n", dir, strerror(errno));
        return LV2_EIO;
    }
    return r;
}
