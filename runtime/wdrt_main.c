/*
 * wdrt_main.c - the command line of the runtime, bin/wdrt.
 *
 *     wdrt render SCENE.wds [-o OUT.wav] [--seconds S] [--rate HZ]
 *                 [--budget NS] [--nosleep] [--quiet]
 *     wdrt complex FILE [--name LIST] [--start V] [--waves] [--tempo X]
 *                  [--granular[=X]] [-o OUT.wav] [--rate HZ] [--quiet]
 *
 * Each netlist a scene names is turned into a voice by running wdc and
 * the C compiler once; the shared object is kept under the cache folder
 * (out/cache, or $WDRT_CACHE) by a hash of the netlist, the files it
 * includes, the compiler wdc and the C flags, so later renders load it at
 * once.  A voice is built in a folder of its own and renamed into place,
 * so renders running at the same time never see half a voice.
 *
 * Exit status: 0 ok, 1 input error, 2 usage error, 3 toolchain or
 * internal error.
 */
#include "wdrt.h"

#include "sexp.h"

#include "cx.h"
#include "tt.h"
#include "tt_evolve.h"

#include <dirent.h>
#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

enum { EXIT_INPUT = 1, EXIT_USAGE = 2, EXIT_TOOL = 3 };

#define VOICE_CFLAGS "-O3"

static const char usage_text[] =
    "usage: wdrt render SCENE.wds [-o OUT.wav] [--seconds S] [--rate HZ]\n"
    "                             [--budget NS] [--nosleep] [--quiet]\n"
    "       wdrt complex FILE [--name LIST] [--start V] [--waves] [--tempo X]\n"
    "                     [--granular[=X]] [-o OUT.wav] [--rate HZ] [--quiet]\n"
    "       wdrt tree FILE.tt|'(EXPR)' [-o OUT.wav] [--seconds S] [--rate HZ]\n"
    "                     [--param NAME=VALUE]... [--print] [--quiet]\n"
    "       wdrt evolve SEED.tt [--target T.wav] [--population N] [--generations G]\n"
    "                     [--seed K] [-o DIR] ...   (wdrt evolve --help)\n"
    "       wdrt dot SCENE.wds|FILE.tt [-o OUT.dot]\n"
    "       wdrt --help\n"
    "\n"
    "render   renders a scene (.wds) to a 32-bit float WAV (default: out/SCENE.wav);\n"
    "         netlists it names are compiled with wdc and cached under out/cache\n"
    "         (or $WDRT_CACHE); $WDC names the compiler (default: wdc beside wdrt)\n"
    "  -o OUT.wav      where to write\n"
    "  --seconds S     length (default: the scene's, or until its last event has rung down)\n"
    "  --rate HZ       sample rate (default: the scene's, or 48 kHz)\n"
    "  --budget NS     ns per sample the voices may cost (default: the scene's budget)\n"
    "  --nosleep       never put quiet voices to sleep\n"
    "  --quiet         no progress and no summary\n"
    "\n"
    "complex  reads a simplicial complex (Lutz's NAME=[[1,2,3],...] lists, or one facet per\n"
    "         line) and hears it: its tree of waves as additive synthesis, written to a WAV\n"
    "         (default: out/FILE.wav, unless --waves alone is asked for)\n"
    "  --name LIST     the list of a Lutz file to read (default: the first)\n"
    "  --start V       the vertex the traversal starts at (default: the lowest-numbered)\n"
    "  --waves         print the tree of waves, one line per wave component:\n"
    "                  dim=D wave=I component=C vertices=V simplices=S parent=P\n"
    "  --tempo X       play X times as fast (default 1: a 1-wave lasts 0.24 s)\n"
    "  --granular[=X]  cut the sound into grains, sparser and shorter as the explosion\n"
    "                  factor X (0..1, default 0.5) grows\n"
    "  -o OUT.wav      where to write\n"
    "  --rate HZ       sample rate (default 48 kHz)\n"
    "  --quiet         no summary\n"
    "\n"
    "tree     renders a timbre tree: the last tree of a .tt file, or an expression given\n"
    "         in parentheses (default: out/NAME.wav, out/tree.wav for an expression)\n"
    "  --seconds S     length (default: until the tree has ended and rung down, at most\n"
    "                  60 s; 4 s for a tree that never ends)\n"
    "  --rate HZ       sample rate (default 48 kHz)\n"
    "  --param P=V     sets a param of the tree (repeatable)\n"
    "  --print         print the tree as read (uses expanded), and its program's size\n"
    "  -o OUT.wav      where to write\n"
    "  --quiet         no summary\n"
    "\n"
    "dot      writes the sound network of a scene, or a tree's expression, for Graphviz\n"
    "         (default: to stdout): sources, trees, mix nodes, rooms and the listener\n"
    "\n"
    "exit status: 0 ok, 1 input error, 2 usage error, 3 toolchain or internal error\n";

static void usage_error(const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    fprintf(stderr, "wdrt: error: ");
    vfprintf(stderr, fmt, ap);
    /* the synopsis (the text up to its first blank line), not the whole help */
    fprintf(stderr, "\n%.*s", (int)(strstr(usage_text, "\n\n") + 1 - usage_text), usage_text);
    fprintf(stderr, "(wdrt --help says more)\n");
    va_end(ap);
    exit(EXIT_USAGE);
}

/* "peak -6.0 dBFS", or "silent" */
static const char *peak_text(double pk, char *buf, size_t n) {
    if (pk > 0)
        snprintf(buf, n, "peak %.1f dBFS", 20 * log10(pk));
    else
        snprintf(buf, n, "silent");
    return buf;
}

/* ---- the voice cache ---- */

typedef struct hash {
    uint64_t h;
} hash;

static void hash_bytes(hash *h, const void *p, size_t n) {
    const unsigned char *b = p;
    for (size_t i = 0; i < n; i++)
        h->h = (h->h ^ b[i]) * 0x100000001b3ull;
}

static char *read_all(const char *path, size_t *len) {
    size_t n;
    int e;
    char *text = sx_slurp(path, len ? len : &n, &e);
    if (!text)
        errno = e;
    return text;
}

/* Hashes a netlist and, depth first, the files its .include lines name. */
static int hash_netlist(hash *h, const char *path, int depth) {
    size_t n;
    char *text = read_all(path, &n);
    if (!text)
        return -1;
    hash_bytes(h, path, strlen(path));
    hash_bytes(h, text, n);
    for (char *l = text; depth < 16 && l && *l;) {
        char *nl = strchr(l, '\n');
        while (*l == ' ' || *l == '\t')
            l++;
        if (!strncmp(l, ".include", 8)) {
            char *q = strchr(l, '"'), *q2 = q ? strchr(q + 1, '"') : NULL;
            if (q && q2 && (!nl || q2 < nl)) {
                char inc[PATH_MAX];
                const char *slash = strrchr(path, '/');
                int dl = slash && q[1] != '/' ? (int)(slash - path + 1) : 0;
                snprintf(inc, sizeof inc, "%.*s%.*s", dl, path, (int)(q2 - q - 1), q + 1);
                hash_netlist(h, inc, depth + 1); /* wdc reports a missing file */
            }
        }
        l = nl ? nl + 1 : NULL;
    }
    free(text);
    return 0;
}

static int mkdir_p(const char *dir) {
    char buf[PATH_MAX];
    snprintf(buf, sizeof buf, "%s", dir);
    for (char *p = buf + 1; *p; p++)
        if (*p == '/') {
            *p = 0;
            if (mkdir(buf, 0777) != 0 && errno != EEXIST)
                return -1;
            *p = '/';
        }
    return mkdir(buf, 0777) != 0 && errno != EEXIST ? -1 : 0;
}

static void remove_dir(const char *dir) {
    DIR *d = opendir(dir);
    if (d) {
        struct dirent *de;
        while ((de = readdir(d)))
            if (strcmp(de->d_name, ".") && strcmp(de->d_name, "..")) {
                char p[PATH_MAX];
                snprintf(p, sizeof p, "%s/%s", dir, de->d_name);
                unlink(p);
            }
        closedir(d);
    }
    rmdir(dir);
}

/* The NAME of the one NAME.ext in dir, into name. */
static int find_ext(const char *dir, const char *ext, char *name, size_t cap) {
    DIR *d = opendir(dir);
    int found = 0;
    if (!d)
        return -1;
    struct dirent *de;
    size_t el = strlen(ext);
    while ((de = readdir(d))) {
        size_t n = strlen(de->d_name);
        if (n > el && !strcmp(de->d_name + n - el, ext) && n - el < cap) {
            memcpy(name, de->d_name, n - el);
            name[n - el] = 0;
            found++;
        }
    }
    closedir(d);
    return found == 1 ? 0 : -1;
}

static const char *wdc_path(const char *argv0) {
    static char buf[PATH_MAX];
    const char *env = getenv("WDC");
    if (env && *env)
        return env;
    ssize_t n = readlink("/proc/self/exe", buf, sizeof buf - 8);
    if (n <= 0) {
        const char *slash = strrchr(argv0, '/');
        if (!slash)
            return "wdc";
        n = snprintf(buf, sizeof buf - 8, "%s", argv0);
    }
    buf[n] = 0;
    char *slash = strrchr(buf, '/');
    strcpy(slash ? slash + 1 : buf, "wdc");
    return access(buf, X_OK) == 0 ? buf : "wdc";
}

/* A voice runs at any rate, but a string's or tube's loop needs a rate
 * high enough for its pitch: `wdc --check --rate` says so at the string,
 * once for each rate a cached voice is used at (a file in its folder
 * remembers it).  0, or the exit status, said. */
static int check_rate(const char *dir, const char *netlist, const char *wdc, double rate) {
    char mark[PATH_MAX + 128], r[64];
    snprintf(r, sizeof r, "%.17g", rate);
    snprintf(mark, sizeof mark, "%s/rate-%s.ok", dir, r);
    if (access(mark, F_OK) == 0)
        return 0;
    char *argv[] = {(char *)wdc, (char *)netlist, "--check", "--rate", r, NULL};
    int status = 0;
    if (wdrt_spawn(argv, STDERR_FILENO, &status) != WDRT_OK || status != 0) {
        if (status == 1)
            return EXIT_INPUT; /* wdc said which loop is too short, and where */
        fprintf(stderr, "wdrt: error: %s failed on '%s' (status %d)\n", wdc, netlist, status);
        return EXIT_TOOL;
    }
    FILE *f = fopen(mark, "w"); /* a cache that cannot remember checks again next time */
    if (f)
        fclose(f);
    return 0;
}

/* Builds (or finds in the cache) the voice of `netlist`, checked at
 * `rate`.  Returns 0, or the exit status after printing why. */
static int cached_voice(const char *netlist, const char *wdc, double rate, wdrt_voice_lib *lib) {
    const char *root = getenv("WDRT_CACHE");
    if (!root || !*root)
        root = "out/cache";
    hash h = {0xcbf29ce484222325ull};
    hash_bytes(&h, "wdrt-voice-3", 12); /* the version of how a voice is built here */
    if (hash_netlist(&h, netlist, 0) != 0) {
        fprintf(stderr, "wdrt: error: cannot read netlist '%s': %s\n", netlist, sx_file_strerror(errno));
        return EXIT_INPUT;
    }
    size_t n;
    char *bin = read_all(wdc, &n);
    if (bin) {
        hash_bytes(&h, bin, n);
        free(bin);
    }
    const char *cc = getenv("CC");
    hash_bytes(&h, cc ? cc : "cc", strlen(cc ? cc : "cc"));
    hash_bytes(&h, VOICE_CFLAGS, strlen(VOICE_CFLAGS));
    /* a voice holds its delays up to four times its netlist's rate and
     * 192 kHz at least; above that it is built for the rate it runs at */
    char rarg[64] = "";
    if (rate > 192000) {
        snprintf(rarg, sizeof rarg, "%.17g", rate);
        hash_bytes(&h, rarg, strlen(rarg));
    }
    char dir[PATH_MAX], name[256], so[PATH_MAX + 300];
    snprintf(dir, sizeof dir, "%s/%016llx", root, (unsigned long long)h.h);
    if (find_ext(dir, ".so", name, sizeof name) != 0) {
        char tmp[PATH_MAX];
        snprintf(tmp, sizeof tmp, "%s/tmp.XXXXXX", root);
        if (mkdir_p(root) != 0 || !mkdtemp(tmp)) {
            fprintf(stderr, "wdrt: error: cannot make the cache folder '%s': %s\n", root, strerror(errno));
            return EXIT_TOOL;
        }
        /* --batch: the engine renders a pool's voices side by side */
        char *argv[] = {(char *)wdc, (char *)netlist, "-o", tmp, "--batch", rarg[0] ? "--rate" : NULL, rarg, NULL};
        int status = 0;
        if (wdrt_spawn(argv, STDERR_FILENO, &status) != WDRT_OK || status != 0) {
            remove_dir(tmp);
            if (status == 1)
                return EXIT_INPUT; /* wdc said what is wrong with the netlist */
            fprintf(stderr, "wdrt: error: %s failed on '%s' (status %d)\n", wdc, netlist, status);
            return EXIT_TOOL;
        }
        char csrc[PATH_MAX + 300];
        if (find_ext(tmp, ".c", name, sizeof name) != 0) {
            remove_dir(tmp);
            fprintf(stderr, "wdrt: error: %s wrote no voice for '%s'\n", wdc, netlist);
            return EXIT_TOOL;
        }
        snprintf(csrc, sizeof csrc, "%s/%s.c", tmp, name);
        snprintf(so, sizeof so, "%s/%s.so", tmp, name);
        if (wdrt_voice_compile(csrc, so, NULL, VOICE_CFLAGS) != WDRT_OK) {
            remove_dir(tmp);
            fprintf(stderr, "wdrt: error: the C compiler failed on the voice of '%s'\n", netlist);
            return EXIT_TOOL;
        }
        if (rename(tmp, dir) != 0) /* another render made it first: use theirs */
            remove_dir(tmp);
    }
    int st = check_rate(dir, netlist, wdc, rate);
    if (st)
        return st;
    snprintf(so, sizeof so, "%s/%s.so", dir, name);
    if (wdrt_voice_open(so, name, lib) != WDRT_OK) {
        fprintf(stderr, "wdrt: error: cannot load the voice of '%s' from %s\n", netlist, so);
        return EXIT_TOOL;
    }
    return 0;
}

/* ---- render ---- */

typedef struct progress {
    const char *name;
    int tty;
    double last;
} progress;

static void show_progress(double done, void *user) {
    progress *p = user;
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    double now = ts.tv_sec + ts.tv_nsec * 1e-9;
    if (!p->tty || now - p->last < 0.1)
        return;
    p->last = now;
    if (done >= 0)
        fprintf(stderr, "\rwdrt: %s: %3.0f%%", p->name, done * 100);
    else
        fprintf(stderr, "\rwdrt: %s: %.1f s", p->name, -done);
    fflush(stderr);
}

typedef struct opts {
    const char *scene, *out;
    wdrt_render_opts ro;
    int quiet;
} opts;

static double take_number(int argc, char **argv, int *i) {
    if (*i + 1 >= argc)
        usage_error("%s needs a value", argv[*i]);
    char *end;
    double x = strtod(argv[++*i], &end);
    if (*end || !(x > 0) || !isfinite(x))
        usage_error("%s takes a positive number, not '%s'", argv[*i - 1], argv[*i]);
    return x;
}

static opts parse_render(int argc, char **argv) {
    opts o;
    memset(&o, 0, sizeof o);
    for (int i = 2; i < argc; i++) {
        const char *a = argv[i];
        if (!strcmp(a, "-o")) {
            if (i + 1 >= argc)
                usage_error("-o needs a file name");
            o.out = argv[++i];
        } else if (!strcmp(a, "--seconds")) {
            o.ro.seconds = take_number(argc, argv, &i);
            if (o.ro.seconds > 86400)
                usage_error("--seconds: at most a day");
        } else if (!strcmp(a, "--rate")) {
            o.ro.rate = take_number(argc, argv, &i);
            if (o.ro.rate < 1000 || o.ro.rate > 768000)
                usage_error("--rate lies between 1000 and 768000 Hz");
        } else if (!strcmp(a, "--budget")) {
            o.ro.budget_ns = take_number(argc, argv, &i);
        } else if (!strcmp(a, "--nosleep")) {
            o.ro.nosleep = 1;
        } else if (!strcmp(a, "--quiet")) {
            o.quiet = 1;
        } else if (a[0] == '-' && a[1]) {
            usage_error("unknown option '%s'", a);
        } else if (o.scene) {
            usage_error("one scene at a time ('%s' and '%s')", o.scene, a);
        } else {
            o.scene = a;
        }
    }
    if (!o.scene)
        usage_error("render needs a scene file");
    return o;
}

static char *default_out(const char *scene) {
    const char *base = strrchr(scene, '/');
    base = base ? base + 1 : scene;
    size_t n = strlen(base);
    if (n > 4 && !strcmp(base + n - 4, ".wds"))
        n -= 4;
    char *p = malloc(n + 16);
    if (p)
        sprintf(p, "out/%.*s.wav", (int)n, base);
    return p;
}

/* Where a render's frames go: the file, and their peak for the summary. */
typedef struct sink {
    wdrt_wav_out *w;
    double peak, rate;
    int failed;
    long frames;     /* written so far */
    long bad;        /* the first frame that is not finite, or -1 */
    int badch;       /* its channel */
} sink;

/* Writes a run of frames; a sample that is not finite stops the render. */
static int to_file(const double *frames, long n, int nch, void *user) {
    sink *k = user;
    for (long i = 0; i < n * nch; i++) {
        if (!isfinite(frames[i])) {
            k->bad = k->frames + i / nch;
            k->badch = (int)(i % nch);
            return 1;
        }
        k->peak = fabs(frames[i]) > k->peak ? fabs(frames[i]) : k->peak;
    }
    if (wdrt_wav_append(k->w, frames, n) != WDRT_OK)
        k->failed = 1;
    k->frames += n;
    return k->failed;
}

/* Opens k's file for secs of nch channels at rate, if a WAV file holds
 * them (`what` set the length); 0, or the exit status, said. */
static int sink_open(sink *k, const char *path, double secs, int nch, double rate, const char *what) {
    if (!wdrt_wav_fits(secs * rate, nch)) {
        fprintf(stderr, "wdrt: error: %s: %g s is too long for a WAV file, which holds at most 4 GiB: %.0f s of %d "
                        "channel%s at %g Hz\n", what, secs, wdrt_wav_max_seconds(nch, rate), nch, nch > 1 ? "s" : "",
                rate);
        return EXIT_USAGE;
    }
    if (wdrt_wav_open(path, nch, rate, &k->w) != WDRT_OK) {
        fprintf(stderr, "wdrt: error: cannot write '%s'\n", path);
        return EXIT_USAGE;
    }
    k->rate = rate;
    k->bad = -1;
    return 0;
}

/* Closes k's file, which then takes path's place.  If the render failed
 * (`why` says how, unless writing failed first or a sample was not
 * finite) or the writing did, nothing is written: a file at path is left
 * as it was.  0, or the exit status. */
static int sink_close(sink *k, const char *path, int rendered, const char *why) {
    if (rendered && !k->failed && k->bad < 0) {
        if (wdrt_wav_close(k->w) != WDRT_OK)
            k->failed = 1;
    } else if (k->w) {
        wdrt_wav_abort(k->w);
    }
    k->w = NULL;
    if (rendered && !k->failed && k->bad < 0)
        return 0;
    if (k->failed)
        fprintf(stderr, "wdrt: error: cannot write '%s'\n", path);
    else if (k->bad >= 0)
        fprintf(stderr, "wdrt: error: the output went non-finite at %.6g s (frame %ld, channel %d): nothing written\n",
                (double)k->bad / k->rate, k->bad, k->badch + 1);
    else
        fputs(why, stderr);
    return k->failed ? EXIT_USAGE : EXIT_TOOL;
}

static int to_file_mono(const double *frames, long n, void *user) { return to_file(frames, n, 1, user); }

static int cmd_render(int argc, char **argv) {
    opts o = parse_render(argc, argv);
    char err[4096];
    wdrt_scene *s;
    wdrt_result r = wdrt_scene_load(o.scene, &s, err, sizeof err);
    if (r != WDRT_OK) {
        fputs(err, stderr);
        return EXIT_INPUT;
    }
    const char *wdc = wdc_path(argv[0]);
    int nv = wdrt_scene_nvoices(s), status = 0;
    wdrt_voice_lib *libs = calloc((size_t)nv + 1, sizeof *libs);
    for (int i = 0; i < nv && !status; i++) {
        if (!(status = cached_voice(wdrt_scene_voice_netlist(s, i), wdc, wdrt_scene_rate(s, &o.ro), &libs[i]))) {
            if (wdrt_scene_bind(s, i, libs[i].cls, err, sizeof err) != WDRT_OK)
                status = EXIT_INPUT;
            fputs(err, stderr); /* the error, or the warnings */
        }
    }
    double *frames = NULL, rate = 0;
    long n = 0;
    int nch = 0;
    wdrt_engine_stats st;
    progress pr = {o.scene, isatty(STDERR_FILENO) && !o.quiet, 0};
    o.ro.progress = show_progress;
    o.ro.user = &pr;
    /* the frames go to the file as they are rendered: a long scene takes
     * no more memory than a short one */
    char *out = o.out ? NULL : default_out(o.scene);
    const char *path = o.out ? o.out : out;
    if (!status && !o.out)
        mkdir_p("out");
    sink snk = {0};
    double secs = o.ro.seconds > 0 ? o.ro.seconds : wdrt_scene_length(s);
    if (!status)
        status = sink_open(&snk, path, secs, wdrt_scene_channels(s), wdrt_scene_rate(s, &o.ro),
                           o.ro.seconds > 0 ? "--seconds" : o.scene);
    o.ro.sink = to_file;
    o.ro.sink_user = &snk;
    struct timespec t0, t1;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    wdrt_result rr = status ? WDRT_OK : wdrt_scene_render(s, &o.ro, &frames, &n, &nch, &rate, &st);
    clock_gettime(CLOCK_MONOTONIC, &t1);
    if (pr.tty)
        fprintf(stderr, "\r\033[K");
    if (!status) {
        char why[1024];
        snprintf(why, sizeof why, "wdrt: error: %s: the scene could not be rendered (%s)\n", o.scene,
                 wdrt_result_str(rr));
        if (rr == WDRT_OUT_OF_TUNE) /* said at the scene's line: an error in the scene at this rate */
            why[0] = '\0';
        status = sink_close(&snk, path, rr == WDRT_OK, why);
        if (rr == WDRT_OUT_OF_TUNE)
            status = EXIT_INPUT;
    }
    if (!status && !o.quiet) {
        double pk = snk.peak, wall = (t1.tv_sec - t0.tv_sec) + (t1.tv_nsec - t0.tv_nsec) * 1e-9;
        char pb[40];
        fprintf(stderr,
                "wdrt: wrote %s: %.2f s, %d channel%s at %.0f Hz, %s; %llu events (%llu late), "
                "%llu sleeps, %llu steals, %llu virtual; %.1fx real time\n",
                path, n / rate, nch, nch > 1 ? "s" : "", rate, peak_text(pk, pb, sizeof pb),
                (unsigned long long)st.events, (unsigned long long)st.late, (unsigned long long)st.sleeps,
                (unsigned long long)st.steals, (unsigned long long)st.virtualized, wall > 0 ? n / rate / wall : 0);
    }
    free(out);
    free(frames);
    wdrt_scene_free(s);
    for (int i = 0; i < nv; i++)
        wdrt_voice_close(&libs[i]);
    free(libs);
    return status;
}

/* ---- complex ---- */

typedef struct cxopts {
    const char *file, *name, *out, *start;
    int waves, quiet;
    double rate;
    cx_sound_opts snd;
} cxopts;

static cxopts parse_complex(int argc, char **argv) {
    cxopts o;
    memset(&o, 0, sizeof o);
    o.snd = cx_sound_opts_init();
    o.rate = 48000;
    for (int i = 2; i < argc; i++) {
        const char *a = argv[i];
        if (!strcmp(a, "-o") || !strcmp(a, "--name") || !strcmp(a, "--start")) {
            if (i + 1 >= argc)
                usage_error("%s needs a value", a);
            *(a[1] == 'o' ? &o.out : a[2] == 'n' ? &o.name : &o.start) = argv[++i];
        } else if (!strcmp(a, "--waves")) {
            o.waves = 1;
        } else if (!strcmp(a, "--quiet")) {
            o.quiet = 1;
        } else if (!strcmp(a, "--tempo")) {
            o.snd.tempo = take_number(argc, argv, &i);
            if (o.snd.tempo > 100) /* a 1-wave of 2.4 ms, as a scene's (tempo X) allows; faster ones vanish */
                usage_error("--tempo is a speed factor above 0 and at most 100");
        } else if (!strcmp(a, "--rate")) {
            o.rate = take_number(argc, argv, &i);
            if (o.rate < 1000 || o.rate > 768000)
                usage_error("--rate lies between 1000 and 768000 Hz");
        } else if (!strcmp(a, "--granular") || !strncmp(a, "--granular=", 11)) {
            char *end = NULL;
            o.snd.granular = a[10] ? strtod(a + 11, &end) : 0.5;
            if ((end && *end) || !(o.snd.granular >= 0 && o.snd.granular <= 1))
                usage_error("--granular takes an explosion factor from 0 to 1, not '%s'", a + 11);
        } else if (a[0] == '-' && a[1]) {
            usage_error("unknown option '%s'", a);
        } else if (o.file) {
            usage_error("one complex at a time ('%s' and '%s')", o.file, a);
        } else {
            o.file = a;
        }
    }
    if (!o.file)
        usage_error("complex needs a file");
    return o;
}

/* The vertex labelled `text` in K, or -1 after saying why. */
static int start_vertex(const cx_complex *K, const char *file, const char *text) {
    char *end;
    long v = strtol(text, &end, 10);
    if (*end || end == text)
        usage_error("--start takes a vertex number, not '%s'", text);
    int id = cx_vertex(K, v);
    if (id < 0)
        fprintf(stderr, "wdrt: error: %s: the complex has no vertex %ld\n", file, v);
    return id;
}

/* Renders the score through an engine, as a scene would host it, into
 * the sink in runs of 4096 frames; *n frames in all.  0, or -1 (out of
 * memory, or the sink refused a run). */
static int render_score(const cx_score *sc, double fs, long *n, sink *k) {
    cx_source src;
    cx_source_init(&src, sc, 0);
    wdrt_pool_config pc = wdrt_pool_config_init(&src.cls, 1);
    pc.owned = 1, pc.bind = cx_source_bind, pc.data = &src, pc.cost_ns = 1;
    wdrt_engine_config ec = wdrt_engine_config_init(fs, 1, 1, &pc);
    wdrt_engine *e;
    *n = (long)llround(sc->length * fs) + 1;
    double *y = malloc(sizeof *y * 4096);
    if (!y || wdrt_engine_init(&ec, NULL, &e) != WDRT_OK) {
        free(y);
        return -1;
    }
    int r = 0;
    for (long t = 0; t < *n && !r; t += 4096) {
        long m = *n - t < 4096 ? *n - t : 4096;
        wdrt_engine_process(e, y, (uint32_t)m);
        r = to_file_mono(y, m, k);
    }
    wdrt_engine_uninit(e, NULL);
    free(y);
    return r ? -1 : 0;
}

/* out/NAME.wav for FILE = .../NAME.EXT */
static char *complex_out(const char *file) {
    const char *base = strrchr(file, '/'), *dot;
    base = base ? base + 1 : file;
    dot = strrchr(base, '.');
    int n = dot && dot > base ? (int)(dot - base) : (int)strlen(base);
    char *p = malloc((size_t)n + 16);
    if (p)
        sprintf(p, "out/%.*s.wav", n, base);
    return p;
}

/* The score written as it is rendered: however slow the tempo, no more
 * memory than a second of it. */
static int write_complex(const cxopts *o, const cx_score *sc) {
    char *def = o->out ? NULL : complex_out(o->file);
    const char *path = o->out ? o->out : def;
    long n = 0;
    int status = 0;
    sink snk = {0};
    if (sc->length > 86400) {
        fprintf(stderr, "wdrt: error: %s: the score lasts %.6g s, more than a day (raise --tempo)\n", o->file,
                sc->length);
        status = EXIT_USAGE;
    } else {
        if (!o->out)
            mkdir_p("out");
        if (!(status = sink_open(&snk, path, sc->length, 1, o->rate, o->file)))
            status = sink_close(&snk, path, !render_score(sc, o->rate, &n, &snk), "wdrt: error: out of memory\n");
    }
    if (!status && !o->quiet) {
        char pb[40];
        fprintf(stderr, "wdrt: wrote %s: %.2f s, %d notes (at most %d at once), %s\n", path, n / o->rate,
                sc->nnotes, sc->maxactive, peak_text(snk.peak, pb, sizeof pb));
    }
    free(def);
    return status;
}

static int cmd_complex(int argc, char **argv) {
    cxopts o = parse_complex(argc, argv);
    char err[4096];
    cx_complex *K = cx_read_file(o.file, o.name, err, sizeof err);
    if (!K) {
        fputs(err, stderr);
        return EXIT_INPUT;
    }
    int start = o.start ? start_vertex(K, o.file, o.start) : 0, status = start < 0 ? EXIT_INPUT : 0;
    cx_tree *T = status ? NULL : cx_waves(K, start);
    cx_score *sc = NULL;
    if (!status && T) {
        cx_turns(K, T);
        sc = cx_score_new(T, &o.snd);
    }
    if (!status && !sc) {
        fprintf(stderr, "wdrt: error: out of memory\n");
        status = EXIT_TOOL;
    }
    if (!status && o.waves)
        cx_tree_print(stdout, T);
    if (!status && (o.out || !o.waves))
        status = write_complex(&o, sc);
    cx_score_free(sc);
    cx_tree_free(T);
    cx_free(K);
    return status;
}

/* ---- tree ---- */

/* out/NAME.wav for FILE = .../NAME.EXT, out/tree.wav for an expression */
static char *tree_out(const char *file, int expr) {
    return expr ? strcpy(malloc(16), "out/tree.wav") : complex_out(file);
}

/* Builds (through the cache) the voices the tree's voice nodes name. */
static int tree_voices(tt_prog *P, const char *argv0, double rate, wdrt_voice_lib **libs) {
    int nv = tt_prog_nvoices(P), status = 0;
    *libs = calloc((size_t)nv + 1, sizeof **libs);
    char err[4096];
    for (int k = 0; k < nv && !status; k++)
        if (!(status = cached_voice(tt_prog_voice_path(P, k), wdc_path(argv0), rate, &(*libs)[k])) &&
            tt_prog_bind_voice(P, k, (*libs)[k].cls, err, sizeof err)) {
            fputs(err, stderr);
            status = EXIT_INPUT;
        }
    return status;
}

static int cmd_tree(int argc, char **argv) {
    const char *file = NULL, *out = NULL;
    double seconds = 0, rate = 48000;
    int quiet = 0, print = 0, np = 0;
    char *pn[TT_MAX_PARAMS];
    double pv[TT_MAX_PARAMS];
    for (int i = 2; i < argc; i++) {
        const char *a = argv[i];
        if (!strcmp(a, "-o")) {
            if (i + 1 >= argc)
                usage_error("-o needs a file name");
            out = argv[++i];
        } else if (!strcmp(a, "--seconds")) {
            seconds = take_number(argc, argv, &i);
            if (seconds > 86400)
                usage_error("--seconds: at most a day");
        } else if (!strcmp(a, "--rate")) {
            rate = take_number(argc, argv, &i);
            if (rate < 1000 || rate > 768000)
                usage_error("--rate lies between 1000 and 768000 Hz");
        } else if (!strcmp(a, "--param")) {
            if (i + 1 >= argc)
                usage_error("--param needs NAME=VALUE");
            char *eq = strchr(argv[++i], '='), *end;
            if (!eq || eq == argv[i])
                usage_error("--param takes NAME=VALUE, not '%s'", argv[i]);
            if (np == TT_MAX_PARAMS)
                usage_error("too many --param");
            pv[np] = strtod(eq + 1, &end);
            if (*end || end == eq + 1 || !isfinite(pv[np]))
                usage_error("--param %s: '%s' is not a number", argv[i], eq + 1);
            *eq = 0;
            pn[np++] = argv[i];
        } else if (!strcmp(a, "--quiet")) {
            quiet = 1;
        } else if (!strcmp(a, "--print")) {
            print = 1;
        } else if (a[0] == '-' && a[1] && a[1] != '(' ) {
            usage_error("unknown option '%s'", a);
        } else if (file) {
            usage_error("one tree at a time ('%s' and '%s')", file, a);
        } else {
            file = a;
        }
    }
    if (!file)
        usage_error("tree needs a .tt file or an expression in parentheses");
    char err[4096];
    int expr = file[strspn(file, " \t\n")] == '(';
    tt_file *F = expr ? tt_file_from_string(file, err, sizeof err) : tt_file_read(file, NULL, 0, err, sizeof err);
    if (!F) {
        fputs(err, stderr);
        return EXIT_INPUT;
    }
    const tt_tree *t = tt_file_tree(F, -1);
    double *params = calloc((size_t)t->nparams + 1, sizeof *params);
    for (int k = 0; k < t->nparams; k++)
        params[k] = t->pdef[k];
    int status = 0;
    for (int j = 0; j < np && !status; j++) {
        int k = -1;
        for (int q = 0; q < t->nparams; q++)
            if (!strcmp(t->pname[q], pn[j]))
                k = q;
        if (k < 0) {
            fprintf(stderr, "wdrt: error: the tree has no param '%s'\n", pn[j]);
            status = EXIT_USAGE;
        } else {
            params[k] = pv[j] < t->pmin[k] ? t->pmin[k] : pv[j] > t->pmax[k] ? t->pmax[k] : pv[j];
        }
    }
    tt_prog *P = status ? NULL : tt_compile(t, err, sizeof err);
    if (!status && !P) {
        fputs(err, stderr);
        status = EXIT_INPUT;
    }
    wdrt_voice_lib *libs = NULL;
    if (!status)
        status = tree_voices(P, argv[0], rate, &libs);
    if (!status && print) {
        tt_print_tree(stdout, t);
        printf("; %d nodes, depth %d, %d instructions\n", tt_node_count(t->root), tt_node_depth(t->root),
               tt_prog_ninstr(P));
    }
    double end = P ? tt_prog_end(P) : HUGE_VAL;
    int trim = seconds <= 0 && isfinite(end); /* rendered to 60 s, cut once rung down */
    if (seconds <= 0)
        seconds = isfinite(end) ? 60 : 4;
    long n = (long)llround(seconds * rate);
    char *def = out ? NULL : tree_out(file, expr);
    const char *path = out ? out : def;
    if (!status && !out)
        mkdir_p("out");
    double *y = NULL;
    sink snk = {0};
    if (!status && !trim) { /* a length given: written as it is rendered, in no more memory for an hour */
        if (!(status = sink_open(&snk, path, seconds, 1, rate, "--seconds")))
            status = sink_close(&snk, path, !tt_render_to(P, rate, params, n, to_file_mono, &snk, err, sizeof err),
                                err);
    } else if (!status) { /* to 60 s at most, then cut */
        y = malloc(sizeof *y * (size_t)(n > 0 ? n : 1));
        if (!y || tt_render(P, rate, params, y, n, err, sizeof err)) {
            fputs(y ? err : "wdrt: error: out of memory\n", stderr);
            status = EXIT_TOOL;
        }
    }
    if (!status && trim) { /* after its end, until 100 dB below its peak, and 0.1 s more */
        double pk = 0;
        long last = 0, from = (long)llround(end * rate);
        for (long i = 0; i < n; i++)
            pk = fmax(pk, fabs(y[i]));
        for (long i = 0; i < n; i++)
            if (fabs(y[i]) > 1e-5 * pk)
                last = i;
        last = (last > from ? last : from) + (long)llround(0.1 * rate);
        n = last < n ? last : n;
    }
    if (!status && trim && wdrt_wav_write(path, 1, rate, y, n) != WDRT_OK) {
        fprintf(stderr, "wdrt: error: cannot write '%s'\n", path);
        status = EXIT_USAGE;
    }
    if (!status && !quiet) {
        double pk = snk.peak;
        for (long i = 0; trim && i < n; i++)
            pk = fmax(pk, fabs(y[i]));
        char pb[40];
        fprintf(stderr, "wdrt: wrote %s: %.2f s at %.0f Hz, %s\n", path, n / rate, rate,
                peak_text(pk, pb, sizeof pb));
    }
    free(def);
    free(y);
    free(params);
    for (int k = 0; libs && P && k < tt_prog_nvoices(P); k++) /* before P, which counts them, is freed */
        wdrt_voice_close(&libs[k]);
    tt_prog_free(P);
    free(libs);
    tt_file_free(F);
    return status;
}

/* ---- dot ---- */

static int cmd_dot(int argc, char **argv) {
    const char *file = NULL, *out = NULL;
    for (int i = 2; i < argc; i++) {
        if (!strcmp(argv[i], "-o")) {
            if (i + 1 >= argc)
                usage_error("-o needs a file name");
            out = argv[++i];
        } else if (argv[i][0] == '-' && argv[i][1]) {
            usage_error("unknown option '%s'", argv[i]);
        } else if (file) {
            usage_error("one file at a time ('%s' and '%s')", file, argv[i]);
        } else {
            file = argv[i];
        }
    }
    if (!file)
        usage_error("dot needs a scene (.wds) or a tree (.tt, or an expression in parentheses)");
    char err[4096];
    size_t n = strlen(file);
    int tree = file[0] == '(' || (n > 3 && !strcmp(file + n - 3, ".tt"));
    FILE *f = out ? fopen(out, "w") : stdout;
    if (!f) {
        fprintf(stderr, "wdrt: error: cannot write '%s': %s\n", out, strerror(errno));
        return EXIT_USAGE;
    }
    int status = 0;
    if (tree) {
        tt_file *F = file[0] == '(' ? tt_file_from_string(file, err, sizeof err) : tt_file_read(file, NULL, 0, err, sizeof err);
        if (!F) {
            fputs(err, stderr);
            status = EXIT_INPUT;
        } else {
            char root[64];
            fputs("digraph tree {\n  rankdir=LR;\n  node [fontname=\"Helvetica\" fontsize=11];\n"
                  "  edge [fontname=\"Helvetica\" fontsize=9];\n",
                  f);
            tt_dot(f, tt_file_tree(F, -1)->root, "n", root);
            fprintf(f, "  out [shape=doublecircle label=\"out\"];\n  %s -> out;\n}\n", root);
            tt_file_free(F);
        }
    } else {
        wdrt_scene *s;
        if (wdrt_scene_load(file, &s, err, sizeof err) != WDRT_OK) {
            fputs(err, stderr);
            status = EXIT_INPUT;
        } else {
            wdrt_scene_dot(s, f);
            wdrt_scene_free(s);
        }
    }
    if (out && fclose(f) != 0 && !status) {
        fprintf(stderr, "wdrt: error: cannot write '%s'\n", out);
        status = EXIT_USAGE;
    }
    return status;
}

int main(int argc, char **argv) {
    if (argc < 2)
        usage_error("no command");
    if (!strcmp(argv[1], "--help") || !strcmp(argv[1], "-h") || !strcmp(argv[1], "help")) {
        fputs(usage_text, stdout);
        return 0;
    }
    if (!strcmp(argv[1], "render"))
        return cmd_render(argc, argv);
    if (!strcmp(argv[1], "complex"))
        return cmd_complex(argc, argv);
    if (!strcmp(argv[1], "tree"))
        return cmd_tree(argc, argv);
    if (!strcmp(argv[1], "dot"))
        return cmd_dot(argc, argv);
    if (!strcmp(argv[1], "evolve"))
        return tt_evolve_main(argc - 1, argv + 1);
    usage_error("unknown command '%s'", argv[1]);
    return EXIT_USAGE;
}
