/*
 * lv2host.c - a small LV2 host for tests/test_lv2.c, on lilv.
 *
 *     lv2host BUNDLE URI OUT.wav [--rate HZ] [--frames N] [--blocks B,B,...]
 *             [--control SYMBOL=VALUE]... [--note FRAME:NOTE:VELOCITY]...
 *             [--off FRAME:NOTE]... [--cc FRAME:NUMBER:VALUE]... [--worker 1]
 *
 * Loads the bundle directory BUNDLE, instantiates plugin URI at HZ (default
 * 48000) with the urid:map feature, and runs it for N frames (default
 * 48000) in blocks whose lengths cycle through the --blocks list (default
 * 64; 0 is a run of no frames).  Audio inputs get silence; control inputs
 * their default or the --control value.  MIDI events (note on, note off,
 * control change, channel 1) go to the plugin's atom input at their frame,
 * in the block that holds it, in the order given.  Writes every audio
 * output as one channel of a 32-bit float WAV.  Exit status 0, or 1 after
 * printing what failed.
 *
 * --worker 1 offers the plugin a worker (work:schedule) that does the
 * work it schedules at once, on the thread that runs it, as a host does
 * when rendering offline; the answers go back to the plugin after the run
 * that scheduled them, in order, then end_run.
 */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <lilv/lilv.h>
#include <lv2/atom/atom.h>
#include <lv2/atom/util.h>
#include <lv2/midi/midi.h>
#include <lv2/urid/urid.h>
#include <lv2/worker/worker.h>
#include <sndfile.h>

#define MAX_EVENTS 256
#define MAX_BLOCKS 64
#define MAX_CONTROLS 32
#define ATOM_CAPACITY 65536

typedef struct Event {
    long frame;
    uint8_t msg[3];
} Event;

typedef struct Host {
    double rate;
    long frames;
    long blocks[MAX_BLOCKS];
    int nblocks;
    Event ev[MAX_EVENTS];
    int nev;
    const char *csym[MAX_CONTROLS];
    float cval[MAX_CONTROLS];
    int nctl;
    int worker;
} Host;

/* ---- urid:map: a table of the URIs seen, URID = index + 1 ---- */

static char *uris[256];
static int nuris;

static LV2_URID map_uri(LV2_URID_Map_Handle h, const char *uri) {
    (void)h;
    for (int i = 0; i < nuris; i++)
        if (!strcmp(uris[i], uri))
            return (LV2_URID)(i + 1);
    if (nuris == 256)
        return 0;
    uris[nuris] = malloc(strlen(uri) + 1);
    strcpy(uris[nuris], uri);
    return (LV2_URID)++nuris;
}

/* ---- the worker: work done at once, answers queued for after the run ---- */

#define WORK_QUEUE 262144

static const LV2_Worker_Interface *g_iface;
static LV2_Handle g_handle;
static unsigned char g_answers[WORK_QUEUE]; /* size (uint32_t), then the body, padded to 8 */
static size_t g_nanswers;

static LV2_Worker_Status respond(LV2_Worker_Respond_Handle h, uint32_t size, const void *data) {
    (void)h;
    size_t need = 8 + ((size + 7u) & ~7u);
    if (g_nanswers + need > WORK_QUEUE)
        return LV2_WORKER_ERR_NO_SPACE;
    memcpy(g_answers + g_nanswers, &size, sizeof size);
    memcpy(g_answers + g_nanswers + 8, data, size);
    g_nanswers += need;
    return LV2_WORKER_SUCCESS;
}

static LV2_Worker_Status schedule(LV2_Worker_Schedule_Handle h, uint32_t size, const void *data) {
    (void)h;
    return g_iface ? g_iface->work(g_handle, respond, NULL, size, data) : LV2_WORKER_ERR_UNKNOWN;
}

static void deliver(void) {
    for (size_t at = 0; at < g_nanswers;) {
        uint32_t size;
        memcpy(&size, g_answers + at, sizeof size);
        g_iface->work_response(g_handle, size, g_answers + at + 8);
        at += 8 + ((size + 7u) & ~7u);
    }
    g_nanswers = 0;
    if (g_iface->end_run)
        g_iface->end_run(g_handle);
}

/* ---- arguments ---- */

static void fail(const char *what, const char *arg) {
    fprintf(stderr, "lv2host: %s%s%s\n", what, arg ? ": " : "", arg ? arg : "");
    exit(1);
}

static void add_event(Host *h, long frame, int b0, int b1, int b2) {
    if (h->nev == MAX_EVENTS)
        fail("too many events", NULL);
    Event *e = &h->ev[h->nev++];
    e->frame = frame;
    e->msg[0] = (uint8_t)b0;
    e->msg[1] = (uint8_t)(b1 & 0x7F);
    e->msg[2] = (uint8_t)(b2 & 0x7F);
}

static void parse(Host *h, int argc, char **argv) {
    for (int i = 4; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        long f;
        int x, y;
        if (!v)
            fail("option needs a value", a);
        i++;
        if (!strcmp(a, "--rate"))
            h->rate = atof(v);
        else if (!strcmp(a, "--frames"))
            h->frames = atol(v);
        else if (!strcmp(a, "--blocks")) {
            h->nblocks = 0;
            for (const char *p = v; *p && h->nblocks < MAX_BLOCKS; p += strcspn(p, ","), p += *p == ',')
                h->blocks[h->nblocks++] = atol(p);
        } else if (!strcmp(a, "--control")) {
            const char *eq = strchr(v, '=');
            if (!eq || h->nctl == MAX_CONTROLS)
                fail("bad --control", v);
            char *sym = malloc((size_t)(eq - v) + 1);
            memcpy(sym, v, (size_t)(eq - v));
            sym[eq - v] = 0;
            h->csym[h->nctl] = sym;
            h->cval[h->nctl++] = (float)atof(eq + 1);
        } else if (!strcmp(a, "--note") && sscanf(v, "%ld:%d:%d", &f, &x, &y) == 3)
            add_event(h, f, LV2_MIDI_MSG_NOTE_ON, x, y);
        else if (!strcmp(a, "--off") && sscanf(v, "%ld:%d", &f, &x) == 2)
            add_event(h, f, LV2_MIDI_MSG_NOTE_OFF, x, 64);
        else if (!strcmp(a, "--cc") && sscanf(v, "%ld:%d:%d", &f, &x, &y) == 3)
            add_event(h, f, LV2_MIDI_MSG_CONTROLLER, x, y);
        else if (!strcmp(a, "--worker"))
            h->worker = atoi(v);
        else
            fail("bad option", a);
    }
}

/* ---- running ---- */

typedef struct Ports {
    uint32_t n;
    float **audio_out;     /* per port: buffer of every frame, or NULL */
    int *out_index;        /* output channel of each audio output port, or -1 */
    int nout;
    float *ctl;            /* value of each control port */
    float *silence;        /* audio inputs */
    LV2_Atom_Sequence *seq; /* the MIDI input, or NULL */
    uint32_t seq_port;
} Ports;

static const LilvPlugin *load(LilvWorld *w, const char *bundle, const char *uri) {
    char path[4096];
    snprintf(path, sizeof path, "%s%s", bundle, bundle[strlen(bundle) - 1] == '/' ? "" : "/");
    LilvNode *b = lilv_new_file_uri(w, NULL, path);
    lilv_world_load_bundle(w, b);
    lilv_node_free(b);
    LilvNode *u = lilv_new_uri(w, uri);
    const LilvPlugin *p = lilv_plugins_get_by_uri(lilv_world_get_all_plugins(w), u);
    lilv_node_free(u);
    return p;
}

/* Sorts the ports out and connects those that need no per-block pointer. */
static int setup_ports(LilvWorld *w, const LilvPlugin *p, LilvInstance *inst, const Host *h, Ports *ps) {
    LilvNode *audio = lilv_new_uri(w, LV2_CORE__AudioPort), *control = lilv_new_uri(w, LV2_CORE__ControlPort),
             *atom = lilv_new_uri(w, LV2_ATOM__AtomPort), *input = lilv_new_uri(w, LV2_CORE__InputPort);
    ps->n = lilv_plugin_get_num_ports(p);
    ps->out_index = calloc(ps->n, sizeof(int));
    ps->ctl = calloc(ps->n, sizeof(float));
    ps->silence = calloc((size_t)(h->frames + 1), sizeof(float));
    float *def = calloc(ps->n, sizeof(float));
    lilv_plugin_get_port_ranges_float(p, NULL, NULL, def);
    int ok = 1;
    for (uint32_t i = 0; i < ps->n; i++) {
        const LilvPort *port = lilv_plugin_get_port_by_index(p, i);
        int in = lilv_port_is_a(p, port, input);
        ps->out_index[i] = -1;
        if (lilv_port_is_a(p, port, audio) && !in) {
            ps->out_index[i] = ps->nout++;
        } else if (lilv_port_is_a(p, port, control) && in) {
            ps->ctl[i] = def[i];
            const char *sym = lilv_node_as_string(lilv_port_get_symbol(p, port));
            for (int k = 0; k < h->nctl; k++)
                if (!strcmp(sym, h->csym[k]))
                    ps->ctl[i] = h->cval[k];
            lilv_instance_connect_port(inst, i, &ps->ctl[i]);
        } else if (lilv_port_is_a(p, port, atom) && in) {
            ps->seq = calloc(1, sizeof(LV2_Atom_Sequence) + ATOM_CAPACITY);
            ps->seq_port = i;
            lilv_instance_connect_port(inst, i, ps->seq);
        } else if (lilv_port_is_a(p, port, audio) && in) {
            lilv_instance_connect_port(inst, i, ps->silence);
        } else {
            fprintf(stderr, "lv2host: port %u is of no kind this host knows\n", i);
            ok = 0;
        }
    }
    ps->audio_out = calloc((size_t)ps->nout + 1, sizeof(float *));
    for (int k = 0; k < ps->nout; k++)
        ps->audio_out[k] = calloc((size_t)(h->frames + 1), sizeof(float));
    free(def);
    lilv_node_free(audio);
    lilv_node_free(control);
    lilv_node_free(atom);
    lilv_node_free(input);
    return ok;
}

/* The MIDI events of frames [t, t + len), frames relative to t. */
static void fill_sequence(const Host *h, Ports *ps, long t, long len, LV2_URID seq_type, LV2_URID midi_type) {
    ps->seq->atom.type = seq_type;
    ps->seq->atom.size = sizeof(LV2_Atom_Sequence_Body);
    ps->seq->body.unit = 0;
    ps->seq->body.pad = 0;
    for (int k = 0; k < h->nev; k++) {
        if (h->ev[k].frame < t || h->ev[k].frame >= t + len)
            continue;
        struct {
            LV2_Atom_Event ev;
            uint8_t msg[3];
        } e;
        e.ev.time.frames = h->ev[k].frame - t;
        e.ev.body.type = midi_type;
        e.ev.body.size = 3;
        memcpy(e.msg, h->ev[k].msg, 3);
        if (!lv2_atom_sequence_append_event(ps->seq, ATOM_CAPACITY, &e.ev))
            fail("the atom sequence is full", NULL);
    }
}

static void run(LilvInstance *inst, const Host *h, Ports *ps, LV2_URID seq_type, LV2_URID midi_type) {
    long t = 0;
    for (int b = 0; t < h->frames; b = (b + 1) % h->nblocks) {
        long len = h->blocks[b] < h->frames - t ? h->blocks[b] : h->frames - t;
        for (uint32_t i = 0; i < ps->n; i++)
            if (ps->out_index[i] >= 0)
                lilv_instance_connect_port(inst, i, ps->audio_out[ps->out_index[i]] + t);
        if (ps->seq)
            fill_sequence(h, ps, t, len, seq_type, midi_type);
        lilv_instance_run(inst, (uint32_t)len);
        if (g_iface)
            deliver();
        t += len;
    }
}

static int write_wav(const char *path, const Host *h, const Ports *ps) {
    SF_INFO info = {.samplerate = (int)h->rate, .channels = ps->nout, .format = SF_FORMAT_WAV | SF_FORMAT_FLOAT};
    SNDFILE *f = sf_open(path, SFM_WRITE, &info);
    if (!f)
        return -1;
    float *frame = calloc((size_t)ps->nout, sizeof(float));
    int ok = 1;
    for (long i = 0; i < h->frames && ok; i++) {
        for (int k = 0; k < ps->nout; k++)
            frame[k] = ps->audio_out[k][i];
        ok = sf_writef_float(f, frame, 1) == 1;
    }
    free(frame);
    return sf_close(f) == 0 && ok ? 0 : -1;
}

int main(int argc, char **argv) {
    if (argc < 4)
        fail("usage: lv2host BUNDLE URI OUT.wav [options]", NULL);
    Host h = {.rate = 48000, .frames = 48000, .blocks = {64}, .nblocks = 1};
    parse(&h, argc, argv);
    int positive = 0;
    for (int b = 0; b < h.nblocks; b++)
        positive = positive || h.blocks[b] > 0;
    if (!positive || h.frames < 1 || h.rate < 1)
        fail("need frames, a rate and a block length above 0", NULL);
    LilvWorld *w = lilv_world_new();
    const LilvPlugin *p = load(w, argv[1], argv[2]);
    if (!p)
        fail("no such plugin in the bundle", argv[2]);
    LV2_URID_Map map = {NULL, map_uri};
    LV2_Feature map_feature = {LV2_URID__map, &map};
    LV2_Worker_Schedule sched = {NULL, schedule};
    LV2_Feature work_feature = {LV2_WORKER__schedule, &sched};
    const LV2_Feature *features[] = {&map_feature, h.worker ? &work_feature : NULL, NULL};
    LilvInstance *inst = lilv_plugin_instantiate(p, h.rate, features);
    if (!inst)
        fail("cannot instantiate", argv[2]);
    if (h.worker) {
        g_handle = lilv_instance_get_handle(inst);
        g_iface = lilv_instance_get_extension_data(inst, LV2_WORKER__interface);
        if (!g_iface)
            fail("the plugin has no worker interface", argv[2]);
    }
    Ports ps = {0};
    if (!setup_ports(w, p, inst, &h, &ps))
        return 1;
    lilv_instance_activate(inst);
    run(inst, &h, &ps, map_uri(NULL, LV2_ATOM__Sequence), map_uri(NULL, LV2_MIDI__MidiEvent));
    lilv_instance_deactivate(inst);
    lilv_instance_free(inst);
    lilv_world_free(w);
    if (write_wav(argv[3], &h, &ps) != 0)
        fail("cannot write", argv[3]);
    return 0;
}
