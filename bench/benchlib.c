/* benchlib.c - helpers shared by the benchmarks (see benchlib.h). */
#include "benchlib.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

const double bench_rates[BENCH_NRATES] = {48000.0, 96000.0, 192000.0};
const double bench_amps[BENCH_NAMPS] = {1.0, 10.0};

double bench_now(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

double bench_measure(void (*render)(void *ctx, long nblocks), void *ctx, int block, int runs,
                     double warmup, double seconds) {
    long done = 0;
    double t0 = bench_now(), t;
    do {
        render(ctx, 16);
        done += 16;
        t = bench_now();
    } while (t - t0 < warmup);
    /* about 5 ms of work between clock reads */
    long batch = (long)((double)done / (t - t0) * 0.005);
    if (batch < 1)
        batch = 1;
    double best = INFINITY;
    for (int run = 0; run < runs; run++) {
        long blocks = 0;
        double start = bench_now(), el;
        do {
            render(ctx, batch);
            blocks += batch;
            el = bench_now() - start;
        } while (el < seconds);
        double ns = el * 1e9 / ((double)blocks * block);
        if (ns < best)
            best = ns;
    }
    return best;
}

int bench_args(int argc, char **argv, double *seconds, int *width, const char *usage) {
    int first = 1;
    if (argc > 2 && !strcmp(argv[1], "-t")) {
        *seconds = atof(argv[2]);
        first = 3;
    }
    if (first >= argc || !(*seconds > 0)) {
        fprintf(stderr, "usage: %s\n", usage);
        exit(2);
    }
    for (int i = first; i < argc && width; i++) {
        char label[64];
        bench_label(argv[i], label, sizeof label);
        if ((int)strlen(label) > *width)
            *width = (int)strlen(label);
    }
    return first;
}

int bench_each(int argc, char **argv, int first, double seconds, int (*one)(const char *path, double seconds)) {
    fflush(stdout);
    int failed = 0;
    for (int i = first; i < argc; i++)
        failed |= one(argv[i], seconds);
    bench_print_notes();
    return failed;
}

void bench_first_line(const char *cmd, char *buf, size_t cap) {
    snprintf(buf, cap, "?");
    FILE *p = popen(cmd, "r");
    if (!p)
        return;
    if (fgets(buf, (int)cap, p))
        buf[strcspn(buf, "\n")] = '\0';
    else
        snprintf(buf, cap, "?");
    pclose(p);
}

void bench_cpu_model(char *buf, size_t cap) {
    snprintf(buf, cap, "?");
    FILE *f = fopen("/proc/cpuinfo", "r");
    if (!f)
        return;
    char line[512];
    while (fgets(line, sizeof line, f)) {
        if (!strncmp(line, "model name", 10)) {
            char *c = strchr(line, ':');
            if (c) {
                c++;
                while (*c == ' ' || *c == '\t')
                    c++;
                c[strcspn(c, "\n")] = '\0';
                snprintf(buf, cap, "%s", c);
            }
            break;
        }
    }
    fclose(f);
}

void bench_print_setup(const char *cflags) {
    const char *cc = getenv("CC");
    if (!cc || !*cc)
        cc = "cc";
    char version[256], cpu[256], cmd[512];
    snprintf(cmd, sizeof cmd, "%s --version 2>/dev/null", cc);
    bench_first_line(cmd, version, sizeof version);
    bench_cpu_model(cpu, sizeof cpu);
    printf("compiler: %s (%s)\n", cc, version);
    printf("flags:    -std=c99 -shared -fPIC %s ... -lm\n", cflags);
    printf("cpu:      %s\n\n", cpu);
}

void bench_label(const char *path, char *label, size_t cap) {
    const char *s = strrchr(path, '/');
    snprintf(label, cap, "%s", s ? s + 1 : path);
    char *dot = strrchr(label, '.');
    if (dot && !strcmp(dot, ".wdn"))
        *dot = '\0';
}

void bench_dashes(char *buf, size_t cap, int n) {
    if (cap == 0)
        return;
    size_t nd = n < 0 ? 0 : (size_t)n < cap - 1 ? (size_t)n : cap - 1;
    memset(buf, '-', nd);
    buf[nd] = '\0';
}

#define MAXNOTES 64
static char notes[MAXNOTES][256];
static int nnotes;

void bench_note(const char *fmt, ...) {
    if (nnotes >= MAXNOTES)
        return;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(notes[nnotes++], sizeof notes[0], fmt, ap);
    va_end(ap);
}

void bench_print_notes(void) {
    if (!nnotes)
        return;
    printf("\n");
    for (int k = 0; k < nnotes; k++)
        printf("note: %s\n", notes[k]);
}

double bench_rel_rms(const double *a, const double *b, long n) {
    long double num = 0, den = 0;
    for (long k = 0; k < n; k++) {
        long double d = (long double)a[k] - b[k];
        num += d * d;
        den += (long double)b[k] * b[k];
    }
    if (den == 0)
        return n > 0 ? (double)sqrtl(num / n) : 0.0;
    return (double)sqrtl(num / den);
}

double bench_worst_error(double *const *y, double *const *r, int nouts, long n, int *which) {
    double w = -1;
    *which = 0;
    for (int k = 0; k < nouts; k++) {
        double e = bench_rel_rms(y[k], r[k], n);
        if (!(e <= w)) {
            w = e;
            *which = k;
        }
    }
    return w;
}

void bench_fmt_db(char *buf, size_t cap, double e, const char *out) {
    if (!(e >= 0))
        snprintf(buf, cap, "nan");
    else if (e == 0)
        snprintf(buf, cap, "-inf %s", out);
    else
        snprintf(buf, cap, "%.1f %s", 20.0 * log10(e), out);
}

static int is_word_char(char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' ||
           c == '.' || c == ':';
}

/* Copies the code of one line (len bytes at p, up to its comment) to f
 * without its solver= keys; returns how many it dropped. */
static int drop_keys(FILE *f, const char *p, size_t code) {
    int dropped = 0;
    size_t k = 0;
    while (k < code) {
        if (!strncmp(p + k, "solver", 6) && (k == 0 || !is_word_char(p[k - 1]))) {
            size_t j = k + 6;
            while (j < code && (p[j] == ' ' || p[j] == '\t'))
                j++;
            if (j < code && p[j] == '=') {
                j++;
                while (j < code && (p[j] == ' ' || p[j] == '\t'))
                    j++;
                while (j < code && is_word_char(p[j]))
                    j++;
                k = j;
                dropped++;
                continue;
            }
        }
        fputc(p[k], f);
        k++;
    }
    return dropped;
}

int bench_drop_solver_keys(const char *text, const char *path) {
    FILE *f = fopen(path, "w");
    if (!f)
        return -1;
    int dropped = 0;
    const char *p = text;
    while (*p) {
        const char *eol = strchr(p, '\n');
        size_t len = eol ? (size_t)(eol - p) + 1 : strlen(p);
        /* the code of the line ends at its comment; a line starting with
         * '*' is all comment */
        size_t code = 0;
        const char *q = p;
        while (q < p + len && (*q == ' ' || *q == '\t'))
            q++;
        if (!(q < p + len && *q == '*'))
            while (code < len && p[code] != '#' && p[code] != ';' && p[code] != '\n')
                code++;
        dropped += drop_keys(f, p, code);
        fwrite(p + code, 1, len - code, f);
        p += len;
    }
    return fclose(f) == 0 ? dropped : -1;
}

char *bench_read_netlist(const char *prog, const char *path, const char *label) {
    char *text = read_file(path, NULL);
    if (!text) {
        fprintf(stderr, "%s: cannot read %s\n", prog, path);
        return NULL;
    }
    if (strstr(text, ".include"))
        bench_note("%s: includes other files, which the copy without solver= keys may not find", label);
    return text;
}

int bench_voice_dir(const char *prog, const char *text, char *dir, size_t cap) {
    snprintf(dir, cap, "/tmp/wdc-%s-XXXXXX", prog);
    if (!mkdtemp(dir)) {
        fprintf(stderr, "%s: mkdtemp: %s\n", prog, strerror(errno));
        dir[0] = '\0';
        return -1;
    }
    if (!text)
        return 0;
    char src[128];
    snprintf(src, sizeof src, "%s/netlist.wdn", dir);
    if (bench_drop_solver_keys(text, src) < 0) {
        fprintf(stderr, "%s: cannot write %s\n", prog, src);
        return -1;
    }
    return 0;
}

int bench_voice_make(const char *prog, const char *netlist, const char *src, const char *dir, const bench_solver *sc,
                     double fs, const char *cflags) {
    char rate[32];
    snprintf(rate, sizeof rate, "%.0f", fs);
    const char *args[8];
    int n = 0;
    args[n++] = "--rate";
    args[n++] = rate;
    for (int k = 0; sc->args[k] && n < 7; k++)
        args[n++] = sc->args[k];
    args[n] = NULL;
    if (tl_voice_make(src, dir, args, cflags) != 0) {
        fprintf(stderr, "%s: %s --rate %s, solver %s: the voice could not be built\n", prog, netlist, rate,
                sc->label);
        return -1;
    }
    return 0;
}

/* One instance timed by bench_time_voice. */
typedef struct Timed {
    const wdv_class *cls;
    void *st;
    double *const *drive; /* per input, len frames, cycled; NULL: reset every len frames */
    long len, pos;
    int block;
    const double *in[BENCH_MAXIO];
    double *out[BENCH_MAXIO];
} Timed;

static void render_blocks(void *ctx, long nblocks) {
    Timed *v = ctx;
    const wdv_class *cls = v->cls;
    for (long b = 0; b < nblocks; b++) {
        if (v->drive) {
            for (int k = 0; k < cls->n_inputs; k++)
                v->in[k] = v->drive[k] + v->pos;
        } else if (v->pos == 0) {
            cls->reset(v->st);
        }
        cls->process(v->st, v->in, v->out, v->block);
        v->pos += v->block;
        if (v->pos + v->block > v->len)
            v->pos = 0;
    }
}

double bench_time_voice(const wdv_class *cls, double fs, double *const *drive, long len, double **out, int block,
                        int runs, double warmup, double seconds, int *finite) {
    if (cls->n_inputs > BENCH_MAXIO || cls->n_outputs > BENCH_MAXIO)
        return -1;
    Timed tv = {0};
    tv.cls = cls;
    tv.st = tl_state_new(cls, fs);
    tv.drive = drive;
    tv.len = len;
    tv.block = block;
    for (int k = 0; k < cls->n_outputs; k++)
        tv.out[k] = out[k];
    if (!tv.st)
        return -1;
    double ns = bench_measure(render_blocks, &tv, block, runs, warmup, seconds);
    for (int k = 0; k < cls->n_outputs; k++)
        for (int n = 0; n < block; n++)
            if (!isfinite(out[k][n]))
                *finite = 0;
    tl_state_free(tv.st);
    return ns;
}

int bench_render_voice(const wdv_class *cls, double fs, double *const *in, long nframes, int block, double **out,
                       unsigned long *stats) {
    for (int k = 0; stats && k < WDV_SOLVE_N; k++)
        stats[k] = 0;
    if (cls->n_inputs > BENCH_MAXIO || cls->n_outputs > BENCH_MAXIO)
        return -1;
    void *st = tl_state_new(cls, fs);
    if (!st)
        return -1;
    const double *ip[BENCH_MAXIO];
    double *op[BENCH_MAXIO];
    for (long pos = 0; pos < nframes; pos += block) {
        int n = nframes - pos < block ? (int)(nframes - pos) : block;
        for (int k = 0; k < cls->n_inputs; k++)
            ip[k] = in[k] + pos;
        for (int k = 0; k < cls->n_outputs; k++)
            op[k] = out[k] + pos;
        cls->process(st, ip, op, n);
    }
    if (stats && cls->solve_stats)
        cls->solve_stats(st, stats);
    tl_state_free(st);
    for (int k = 0; k < cls->n_outputs; k++)
        for (long n = 0; n < nframes; n++)
            if (!isfinite(out[k][n]))
                return -1;
    return 0;
}

void bench_run_jobs(int njobs, int (*job)(void *ctx, int k), void *ctx, int *status) {
    long ncpu = sysconf(_SC_NPROCESSORS_ONLN);
    int slots = ncpu < 1 ? 1 : ncpu > 16 ? 16 : (int)ncpu;
    pid_t pid[16];
    int which[16], running = 0, next = 0;
    for (int k = 0; k < njobs; k++)
        status[k] = 1;
    while (next < njobs || running > 0) {
        while (next < njobs && running < slots) {
            fflush(NULL);
            pid_t c = fork();
            if (c < 0) { /* no more processes: do it here */
                status[next] = job(ctx, next);
                next++;
                continue;
            }
            if (c == 0)
                _exit(job(ctx, next));
            pid[running] = c;
            which[running] = next++;
            running++;
        }
        if (running == 0)
            continue;
        int st = 0;
        pid_t done = wait(&st);
        if (done < 0) {
            if (errno == EINTR)
                continue;
            return; /* the jobs still counted as running keep status 1 */
        }
        for (int k = 0; k < running; k++)
            if (pid[k] == done) {
                status[which[k]] = WIFEXITED(st) ? WEXITSTATUS(st) : 1;
                pid[k] = pid[running - 1];
                which[k] = which[running - 1];
                running--;
                break;
            }
    }
}

int bench_refs_new(bench_refs *refs, int nruns, int nouts, const long *frames) {
    memset(refs, 0, sizeof *refs);
    size_t doubles = 0, nbufs = (size_t)nruns * (size_t)nouts;
    for (int k = 0; k < nruns; k++)
        doubles += (size_t)nouts * (size_t)frames[k];
    /* the outputs' pointers, their samples, unconverged, ok */
    size_t size = nbufs * sizeof(double *) + doubles * sizeof(double) + (size_t)nruns * (sizeof(long) + sizeof(int));
    void *mem = mmap(NULL, size, PROT_READ | PROT_WRITE, MAP_SHARED | MAP_ANONYMOUS, -1, 0);
    if (mem == MAP_FAILED)
        return -1;
    refs->nruns = nruns;
    refs->nouts = nouts;
    refs->size = size;
    refs->out = mem;
    double *at = (double *)(void *)(refs->out + nbufs);
    for (int k = 0; k < nruns; k++)
        for (int j = 0; j < nouts; j++) {
            refs->out[(size_t)k * (size_t)nouts + (size_t)j] = at;
            at += frames[k];
        }
    refs->unconverged = (long *)(void *)at;
    refs->ok = (int *)(void *)(refs->unconverged + nruns);
    return 0;
}

double **bench_refs_out(const bench_refs *refs, int run) { return refs->out + (size_t)run * (size_t)refs->nouts; }

void bench_refs_free(bench_refs *refs) {
    if (refs->out)
        munmap(refs->out, refs->size);
    memset(refs, 0, sizeof *refs);
}

/* The jobs of bench_prepare: the reference runs, then the builds. */
typedef struct Prepared {
    const int *runs; /* [k]: the run of job k < nruns */
    int nruns;
    const int *builds; /* [k - nruns]: the voice of job k >= nruns */
    int (*build)(void *ctx, int i);
    int (*ref)(void *ctx, int run);
    void *ctx;
} Prepared;

static int prepared_job(void *ctx, int k) {
    Prepared *p = ctx;
    if (k < p->nruns)
        return p->ref(p->ctx, p->runs[k]);
    return p->build(p->ctx, p->builds[k - p->nruns]);
}

int bench_prepare(const char *prog, const char *text, bench_built *built, int nbuilt, int (*build)(void *ctx, int i),
                  bench_refs *refs, const int *runs, int nruns, int (*ref)(void *ctx, int run), void *ctx) {
    int *builds = malloc(sizeof(int) * ((size_t)nbuilt + 1));
    int *status = malloc(sizeof(int) * ((size_t)nruns + (size_t)nbuilt + 1));
    if (!builds || !status) {
        free(builds);
        free(status);
        return -1;
    }
    int nbuilds = 0;
    for (int i = 0; i < nbuilt; i++) {
        memset(&built[i], 0, sizeof built[i]);
        if (bench_voice_dir(prog, text, built[i].v.dir, sizeof built[i].v.dir) == 0)
            builds[nbuilds++] = i;
    }
    Prepared p = {runs, nruns, builds, build, ref, ctx};
    bench_run_jobs(nruns + nbuilds, prepared_job, &p, status);
    for (int k = 0; k < nruns; k++)
        refs->ok[runs[k]] = status[k] == 0;
    for (int k = 0; k < nbuilds; k++)
        built[builds[k]].ok = status[nruns + k] == 0;
    free(builds);
    free(status);
    return 0;
}
