/* benchlib.c - helpers shared by the benchmarks (see benchlib.h). */
#include "benchlib.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

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
