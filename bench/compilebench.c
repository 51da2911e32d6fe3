/*
 * compilebench.c - how compile time grows with the netlist.
 *
 *     build/bench/compilebench [MAX]
 *
 * Three series-parallel networks, each of 10^3, 10^4 and 10^5 elements
 * (sizes up to MAX, default 100000), driven by a resistive source: a
 * chain of series R, L and C, a ladder (series R, shunt C) and a
 * balanced tree of nested series and parallel connections.  Each netlist
 * is written into a temporary folder and compiled through the library as
 * bin/wdc compiles it, every stage timed: wdc_load (lexing, parsing,
 * elaboration), wdf_build (the adaptor forest), scatter_check (the
 * checks) and emit_voice (the C text, written into the folder).  Each
 * size runs in a child process of its own, since the compiler frees
 * nothing before it exits; its peak resident memory is printed too.  The
 * last column is the total's growth over the previous size: 10 where
 * the time is linear in the size.
 *
 * A benchmark, not a test: the exit status is non-zero only if a netlist
 * fails to compile.
 */
#include <setjmp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include "benchlib.h"
#include "../tests/testlib.h"

#define FS 48000.0
#define NSTAGE 4

static const char *const stage_name[NSTAGE] = {"load", "build", "check", "emit"};

/* ---- netlists ---- */

static void head(FILE *f, const char *voice) {
    fprintf(f, ".voice %s\n.input in\nV1 in 0 in R=50\n", voice);
}

/* One element of kind R, L or C (by k) between a and b. */
static void element(FILE *f, int k, const char *a, const char *b) {
    static const char *const val[3] = {"100", "1m", "1u"};
    fprintf(f, "%c%d %s %s %s\n", "RLC"[k % 3], k, a, b, val[k % 3]);
}

static void chain(FILE *f, int n) {
    head(f, "chain");
    char a[32] = "in", b[32];
    for (int k = 1; k <= n; k++) {
        snprintf(b, sizeof b, k == n ? "0" : "n%d", k);
        element(f, k, a, b);
        memcpy(a, b, sizeof a);
    }
    fprintf(f, ".output out v(n1)\n");
}

static void ladder(FILE *f, int n) {
    head(f, "ladder");
    for (int k = 1; k <= n / 2; k++) {
        if (k == 1)
            fprintf(f, "R1 in n1 100\n");
        else
            fprintf(f, "R%d n%d n%d 100\n", k, k - 1, k);
        fprintf(f, "C%d n%d 0 1u\n", k, k);
    }
    fprintf(f, ".output out v(n%d)\n", n / 2);
}

/* size elements between a and b: halves in series or in parallel, the two
 * alternating by level. */
static void tree_part(FILE *f, const char *a, const char *b, int size, int series, int *k, int *m) {
    if (size == 1) {
        element(f, ++*k, a, b);
        return;
    }
    int h = size / 2;
    if (!series) {
        tree_part(f, a, b, h, 1, k, m);
        tree_part(f, a, b, size - h, 1, k, m);
        return;
    }
    char mid[32];
    snprintf(mid, sizeof mid, "m%d", ++*m);
    tree_part(f, a, mid, h, 0, k, m);
    tree_part(f, mid, b, size - h, 0, k, m);
}

static void tree(FILE *f, int n) {
    head(f, "sptree");
    int k = 0, m = 0;
    tree_part(f, "in", "0", n, 1, &k, &m);
    fprintf(f, ".output out v(in)\n");
}

/* ---- timing ---- */

/* Compiles the netlist at path into dir, each stage's seconds into t;
 * returns 0, or -1 if a stage refuses it. */
static int compile(const char *path, const char *dir, double *t) {
    double t0 = bench_now();
    Circuit *c = wdc_load(path);
    t[0] = bench_now() - t0;
    if (!c)
        return -1;
    jmp_buf jb;
    diag.jmp = &jb;
    if (setjmp(jb))
        return -1;
    t0 = bench_now();
    Wdf *w = wdf_build(c, c->rate);
    t[1] = bench_now() - t0;
    t0 = bench_now();
    scatter_check(w, 1e-9);
    t[2] = bench_now() - t0;
    EmitOpts eo = {.outdir = dir, .table = 256, .tol = 1e-9, .maxit = 50};
    t0 = bench_now();
    int r = emit_voice(w, &eo);
    t[3] = bench_now() - t0;
    return r;
}

/* Writes the netlist of `n` elements by gen, compiles it in a child
 * process and fills t (seconds per stage) and *kb (peak memory); returns
 * 0, or -1 after printing what failed. */
static int measure(void (*gen)(FILE *, int), int n, double *t, long *kb) {
    char dir[64];
    if (tl_temp_dir(dir, "wdc-compilebench") != 0) {
        perror("compilebench: temporary folder");
        return -1;
    }
    char *text = NULL;
    size_t len = 0;
    FILE *f = open_memstream(&text, &len);
    if (!f)
        return -1;
    gen(f, n);
    fclose(f);
    char path[128];
    snprintf(path, sizeof path, "%s/net.wdn", dir);
    f = fopen(path, "w");
    int ok = f && fwrite(text, 1, len, f) == len;
    ok = f && fclose(f) == 0 && ok;
    free(text);
    int fd[2];
    if (!ok || pipe(fd) != 0) {
        tl_remove_dir(dir);
        return -1;
    }
    fflush(NULL);
    pid_t pid = fork();
    if (pid == 0) {
        close(fd[0]);
        double tt[NSTAGE] = {0};
        int r = compile(path, dir, tt);
        ssize_t w = write(fd[1], tt, sizeof tt);
        _exit(r == 0 && w == (ssize_t)sizeof tt ? 0 : 1);
    }
    close(fd[1]);
    int st = 1;
    struct rusage ru;
    ssize_t got = pid > 0 ? read(fd[0], t, sizeof(double) * NSTAGE) : -1;
    close(fd[0]);
    if (pid < 0 || wait4(pid, &st, 0, &ru) != pid || !WIFEXITED(st) || WEXITSTATUS(st) != 0 ||
        got != (ssize_t)(sizeof(double) * NSTAGE)) {
        fprintf(stderr, "compilebench: %d elements: the netlist did not compile (%s)\n", n, path);
        return -1;
    }
    *kb = ru.ru_maxrss;
    tl_remove_dir(dir);
    return 0;
}

int main(int argc, char **argv) {
    int max = argc > 1 ? atoi(argv[1]) : 100000;
    static const struct {
        const char *name;
        void (*gen)(FILE *, int);
    } nets[] = {{"chain", chain}, {"ladder", ladder}, {"sp tree", tree}};
    char cpu[128];
    bench_cpu_model(cpu, sizeof cpu);
    printf("compile time by netlist size (seconds), %s\n\n", cpu);
    printf("%-8s %8s", "netlist", "elements");
    for (int s = 0; s < NSTAGE; s++)
        printf(" %8s", stage_name[s]);
    printf(" %8s %9s %7s\n", "total", "peak MB", "growth");
    int status = 0;
    for (size_t i = 0; i < sizeof nets / sizeof nets[0]; i++) {
        double prev = 0;
        for (int n = 1000; n <= max; n *= 10) {
            double t[NSTAGE], total = 0;
            long kb = 0;
            if (measure(nets[i].gen, n, t, &kb) != 0) {
                status = 1;
                break;
            }
            printf("%-8s %8d", nets[i].name, n);
            for (int s = 0; s < NSTAGE; s++) {
                printf(" %8.3f", t[s]);
                total += t[s];
            }
            printf(" %8.3f %9.1f", total, kb / 1024.0);
            if (prev > 0)
                printf(" %6.1fx", total / prev);
            printf("\n");
            fflush(stdout);
            prev = total;
        }
    }
    return status;
}
