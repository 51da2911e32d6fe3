/*
 * bench.c - speed of the emitted voices.
 *
 *     build/bench/bench [-t SECONDS] NETLIST.wdn...
 *
 * For each netlist, in double and in float precision: bin/wdc ($WDC
 * overrides the path) emits the voice into a temporary directory, $CC
 * (default cc) compiles it into a shared object with -O2 -march=native,
 * and the runtime loads it (wdrt_voice_open).  One instance at 48 kHz
 * then renders white noise on every input in blocks of 64 frames: a
 * warm-up of 0.2 s, then 5 timed runs of at least SECONDS (default 0.5)
 * of wall time each.  The best run gives ns per sample and the number of
 * such voices one core renders in real time at 48 kHz.
 *
 * A benchmark, not a test: the exit status is non-zero only if a voice
 * could not be built or loaded, or produced a non-finite sample.
 */
#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <dirent.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "wdrt_host.h"
#include "wdvoice.h"

#define FS 48000.0
#define BLOCK 64
#define NOISE_LEN 8192 /* frames of noise per input, cycled */
#define RUNS 5
#define WARMUP_S 0.2
#define CFLAGS "-O2 -march=native"

static double now(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/* ---- set-up helpers (not timed) ---- */

static int run_command(char *const argv[]) {
    fflush(NULL);
    pid_t pid = fork();
    if (pid < 0)
        return -1;
    if (pid == 0) {
        execvp(argv[0], argv);
        fprintf(stderr, "bench: cannot run %s: %s\n", argv[0], strerror(errno));
        _exit(127);
    }
    int status = 0;
    while (waitpid(pid, &status, 0) < 0)
        if (errno != EINTR)
            return -1;
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

static int find_voice(const char *dir, char *name, size_t cap) {
    DIR *d = opendir(dir);
    if (!d)
        return -1;
    int found = 0;
    struct dirent *de;
    while ((de = readdir(d)) != NULL) {
        size_t len = strlen(de->d_name);
        if (len > 2 && !strcmp(de->d_name + len - 2, ".c") && len - 2 < cap) {
            memcpy(name, de->d_name, len - 2);
            name[len - 2] = '\0';
            found++;
        }
    }
    closedir(d);
    return found == 1 ? 0 : -1;
}

static void remove_dir(const char *dir) {
    DIR *d = opendir(dir);
    if (!d)
        return;
    struct dirent *de;
    char path[1024];
    while ((de = readdir(d)) != NULL) {
        if (!strcmp(de->d_name, ".") || !strcmp(de->d_name, ".."))
            continue;
        snprintf(path, sizeof path, "%s/%s", dir, de->d_name);
        unlink(path);
    }
    closedir(d);
    rmdir(dir);
}

/* First line of `cmd`'s output, or "?" */
static void first_line(const char *cmd, char *buf, size_t cap) {
    snprintf(buf, cap, "?");
    FILE *p = popen(cmd, "r");
    if (!p)
        return;
    if (fgets(buf, (int)cap, p)) {
        buf[strcspn(buf, "\n")] = '\0';
    } else {
        snprintf(buf, cap, "?");
    }
    pclose(p);
}

static void cpu_model(char *buf, size_t cap) {
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

static const char *basename_of(const char *path) {
    const char *s = strrchr(path, '/');
    return s ? s + 1 : path;
}

/* ---- the measurement ---- */

typedef struct Voice {
    const wdv_class *cls;
    void *st;
    double *noise[16];
    double *outbuf[16];
    const double *in[16];
    double *out[16];
    long pos; /* frame offset into the noise */
} Voice;

static void render_blocks(Voice *v, long nblocks) {
    const wdv_class *cls = v->cls;
    for (long b = 0; b < nblocks; b++) {
        for (int k = 0; k < cls->n_inputs; k++)
            v->in[k] = v->noise[k] + v->pos;
        cls->process(v->st, v->in, v->out, BLOCK);
        v->pos += BLOCK;
        if (v->pos + BLOCK > NOISE_LEN)
            v->pos = 0;
    }
}

/* Best ns per sample over RUNS runs of at least `seconds` each. */
static double measure(Voice *v, double seconds) {
    /* warm-up, and the batch size: about 5 ms of work between clock reads */
    long done = 0;
    double t0 = now(), t;
    do {
        render_blocks(v, 16);
        done += 16;
        t = now();
    } while (t - t0 < WARMUP_S);
    long batch = (long)((double)done / (t - t0) * 0.005);
    if (batch < 1)
        batch = 1;
    double best = INFINITY;
    for (int run = 0; run < RUNS; run++) {
        long blocks = 0;
        double start = now(), el;
        do {
            render_blocks(v, batch);
            blocks += batch;
            el = now() - start;
        } while (el < seconds);
        double ns = el * 1e9 / ((double)blocks * BLOCK);
        if (ns < best)
            best = ns;
    }
    return best;
}

/* uniform white noise in [-1, 1) (xorshift64*) */
static double noise_sample(uint64_t *s) {
    uint64_t x = *s;
    x ^= x >> 12;
    x ^= x << 25;
    x ^= x >> 27;
    *s = x;
    return (double)((x * 0x2545F4914F6CDD1Dull) >> 11) * (2.0 / 9007199254740992.0) - 1.0;
}

typedef struct Result {
    double ns;
    size_t state_size;
    int ok, finite;
} Result;

static Result bench_one(const char *wdc, const char *netlist, int single, double seconds) {
    Result res = {0};
    char dir[] = "/tmp/wdc-bench-XXXXXX";
    if (!mkdtemp(dir)) {
        fprintf(stderr, "bench: mkdtemp: %s\n", strerror(errno));
        return res;
    }
    char *argv[] = {(char *)wdc, (char *)netlist, "-o", dir, "--precision", single ? "float" : "double", NULL};
    char name[256], csrc[1024], so[1024];
    wdrt_voice_lib lib = {0};
    Voice v = {0};
    int st = run_command(argv);
    if (st != 0) {
        fprintf(stderr, "bench: %s %s -o %s --precision %s: exit status %d\n", wdc, netlist, dir,
                single ? "float" : "double", st);
        goto out;
    }
    if (find_voice(dir, name, sizeof name) != 0) {
        fprintf(stderr, "bench: %s: expected one voice source in %s\n", netlist, dir);
        goto out;
    }
    snprintf(csrc, sizeof csrc, "%s/%s.c", dir, name);
    snprintf(so, sizeof so, "%s/%s.so", dir, name);
    wdrt_result r = wdrt_voice_compile(csrc, so, NULL, CFLAGS);
    if (r != WDRT_OK) {
        fprintf(stderr, "bench: compiling %s: %s\n", csrc, wdrt_result_str(r));
        goto out;
    }
    r = wdrt_voice_open(so, name, &lib);
    if (r != WDRT_OK) {
        fprintf(stderr, "bench: loading %s: %s\n", so, wdrt_result_str(r));
        goto out;
    }
    v.cls = lib.cls;
    if (v.cls->n_inputs > 16 || v.cls->n_outputs > 16) {
        fprintf(stderr, "bench: %s: more than 16 inputs or outputs\n", netlist);
        goto out;
    }
    size_t size = (v.cls->state_size + 63) / 64 * 64;
    if (posix_memalign(&v.st, 64, size ? size : 64) != 0) {
        v.st = NULL;
        goto out;
    }
    memset(v.st, 0, size ? size : 64);
    uint64_t seed = 0x9E3779B97F4A7C15ull;
    for (int k = 0; k < v.cls->n_inputs; k++) {
        v.noise[k] = malloc(sizeof(double) * NOISE_LEN);
        if (!v.noise[k])
            goto out;
        for (long n = 0; n < NOISE_LEN; n++)
            v.noise[k][n] = noise_sample(&seed);
    }
    for (int k = 0; k < v.cls->n_outputs; k++) {
        v.outbuf[k] = calloc(BLOCK, sizeof(double));
        if (!v.outbuf[k])
            goto out;
        v.out[k] = v.outbuf[k];
    }
    v.cls->init(v.st, FS);
    res.ns = measure(&v, seconds);
    res.state_size = v.cls->state_size;
    res.finite = 1;
    for (int k = 0; k < v.cls->n_outputs; k++)
        for (int n = 0; n < BLOCK; n++)
            if (!isfinite(v.outbuf[k][n]))
                res.finite = 0;
    res.ok = 1;
out:
    for (int k = 0; k < 16; k++) {
        free(v.noise[k]);
        free(v.outbuf[k]);
    }
    free(v.st);
    if (lib.handle)
        wdrt_voice_close(&lib);
    const char *keep = getenv("WDC_KEEP");
    if (!(keep && *keep == '1'))
        remove_dir(dir);
    return res;
}

int main(int argc, char **argv) {
    double seconds = 0.5;
    int first = 1;
    if (argc > 2 && !strcmp(argv[1], "-t")) {
        seconds = atof(argv[2]);
        first = 3;
    }
    if (first >= argc || !(seconds > 0)) {
        fprintf(stderr, "usage: bench [-t SECONDS] NETLIST.wdn...\n");
        return 2;
    }
    const char *wdc = getenv("WDC");
    if (!wdc || !*wdc)
        wdc = "bin/wdc";
    const char *cc = getenv("CC");
    if (!cc || !*cc)
        cc = "cc";
    char version[256], cpu[256], cmd[512];
    snprintf(cmd, sizeof cmd, "%s --version 2>/dev/null", cc);
    first_line(cmd, version, sizeof version);
    cpu_model(cpu, sizeof cpu);

    printf("wdc voice benchmark: one voice at %.0f Hz, white noise on every input, blocks of %d frames,\n"
           "best of %d runs of >= %.2g s after a %.2g s warm-up\n",
           FS, BLOCK, RUNS, seconds, WARMUP_S);
    printf("compiler: %s (%s)\n", cc, version);
    printf("flags:    -std=c99 -shared -fPIC %s ... -lm\n", CFLAGS);
    printf("cpu:      %s\n\n", cpu);
    printf("%-16s %-9s %10s %10s %18s\n", "netlist", "precision", "state B", "ns/sample", "voices/core@48k");
    printf("%-16s %-9s %10s %10s %18s\n", "----------------", "---------", "----------", "----------",
           "------------------");
    fflush(stdout);

    int failed = 0;
    for (int i = first; i < argc; i++) {
        for (int single = 0; single < 2; single++) {
            char label[64];
            snprintf(label, sizeof label, "%s", basename_of(argv[i]));
            char *dot = strrchr(label, '.');
            if (dot && !strcmp(dot, ".wdn"))
                *dot = '\0';
            Result r = bench_one(wdc, argv[i], single, seconds);
            if (!r.ok) {
                printf("%-16s %-9s %10s %10s %18s\n", label, single ? "float" : "double", "-", "failed", "-");
                failed = 1;
            } else {
                printf("%-16s %-9s %10zu %10.2f %18.0f%s\n", label, single ? "float" : "double", r.state_size,
                       r.ns, 1e9 / (r.ns * FS), r.finite ? "" : "  (non-finite output!)");
                if (!r.finite)
                    failed = 1;
            }
            fflush(stdout);
        }
    }
    return failed;
}
