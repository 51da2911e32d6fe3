/*
 * host.c - compiling, loading and rendering emitted voices.
 *
 * Implements runtime/wdrt.h except the WAV functions (sndio.c).
 * None of this is real-time safe: it forks programs (the C compiler among
 * them), opens shared objects and allocates.
 */
#include "wdrt.h"

#include <dlfcn.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

const char *wdrt_result_str(wdrt_result r)
{
    switch (r) {
    case WDRT_OK: return "ok";
    case WDRT_ERROR: return "error";
    case WDRT_INVALID_ARGS: return "invalid arguments";
    case WDRT_OUT_OF_MEMORY: return "out of memory";
    case WDRT_TOOLCHAIN: return "the C compiler failed";
    case WDRT_LOAD: return "could not load the voice (dlopen/dlsym)";
    case WDRT_IO: return "file could not be read or written";
    case WDRT_FORMAT: return "file is not in a readable format";
    case WDRT_QUEUE_FULL: return "the event queue is full";
    case WDRT_SYNTAX: return "syntax error";
    case WDRT_OUT_OF_TUNE: return "a voice's string, tube or delay line cannot be tuned at this rate";
    }
    return "unknown result";
}

wdrt_result wdrt_spawn(char *const argv[], int out_fd, int *status)
{
    if (!argv || !argv[0] || !*argv[0])
        return WDRT_INVALID_ARGS;
    fflush(NULL);
    pid_t pid = fork();
    if (pid < 0)
        return WDRT_ERROR;
    if (pid == 0) {
        if (out_fd >= 0) {
            dup2(out_fd, STDOUT_FILENO);
            dup2(out_fd, STDERR_FILENO);
            if (out_fd > STDERR_FILENO)
                close(out_fd);
        }
        execvp(argv[0], argv);
        fprintf(stderr, "wdrt: cannot run %s: %s\n", argv[0],
                strerror(errno));
        _exit(127);
    }
    int st = 0;
    while (waitpid(pid, &st, 0) < 0)
        if (errno != EINTR)
            return WDRT_ERROR;
    if (status)
        *status = WIFSIGNALED(st) ? 128 + WTERMSIG(st)
                  : WIFEXITED(st) ? WEXITSTATUS(st)
                                  : -1;
    return WDRT_OK;
}

/* Appends the space-separated words of `s` (a writable copy) to argv. */
static int split_words(char *s, char **argv, int at, int max)
{
    char *p = s;
    while (*p) {
        while (*p == ' ' || *p == '\t' || *p == '\n')
            *p++ = '\0';
        if (!*p)
            break;
        if (at >= max)
            return -1;
        argv[at++] = p;
        while (*p && *p != ' ' && *p != '\t' && *p != '\n')
            p++;
    }
    return at;
}

static int count_words(const char *s)
{
    int n = 0, in = 0;
    for (; *s; s++) {
        int sp = (*s == ' ' || *s == '\t' || *s == '\n');
        if (!sp && !in)
            n++;
        in = !sp;
    }
    return n;
}

wdrt_result wdrt_voice_compile(const char *csrc, const char *so,
                               const char *cc, const char *cflags)
{
    if (!csrc || !so || !*csrc || !*so)
        return WDRT_INVALID_ARGS;
    if (!cc || !*cc) {
        cc = getenv("CC");
        if (!cc || !*cc)
            cc = "cc";
    }
    if (!cflags)
        cflags = "-O2";

    /* The compiler may itself be a command with words ("ccache gcc"). */
    char *ccbuf = malloc(strlen(cc) + 1);
    char *flbuf = malloc(strlen(cflags) + 1);
    int max = count_words(cc) + count_words(cflags) + 16;
    char **argv = malloc((size_t)max * sizeof *argv);
    wdrt_result res = WDRT_OK;
    if (!ccbuf || !flbuf || !argv) {
        res = WDRT_OUT_OF_MEMORY;
        goto done;
    }
    strcpy(ccbuf, cc);
    strcpy(flbuf, cflags);

    int n = split_words(ccbuf, argv, 0, max);
    if (n <= 0) {
        res = WDRT_INVALID_ARGS;
        goto done;
    }
    static char a_std[] = "-std=c99", a_shared[] = "-shared",
                a_fpic[] = "-fPIC", a_o[] = "-o", a_lm[] = "-lm";
    argv[n++] = a_std;
    argv[n++] = a_shared;
    argv[n++] = a_fpic;
    n = split_words(flbuf, argv, n, max - 6);
    if (n < 0) {
        res = WDRT_INVALID_ARGS;
        goto done;
    }
    argv[n++] = (char *)csrc;
    argv[n++] = a_o;
    argv[n++] = (char *)so;
    argv[n++] = a_lm;
    argv[n] = NULL;

    /* The compiler's messages go to our stderr; keep stdout clean for
     * callers that write data there. */
    int status = 0;
    if (wdrt_spawn(argv, STDERR_FILENO, &status) != WDRT_OK || status != 0)
        res = WDRT_TOOLCHAIN;

done:
    free(argv);
    free(flbuf);
    free(ccbuf);
    return res;
}

wdrt_result wdrt_voice_open(const char *so, const char *name,
                            wdrt_voice_lib *lib)
{
    if (!so || !name || !lib)
        return WDRT_INVALID_ARGS;
    lib->handle = NULL;
    lib->cls = NULL;

    /* dlopen searches the library path for a bare name; a path with a
     * slash is taken as is, so make a relative file name explicit. */
    const char *path = so;
    char *buf = NULL;
    if (!strchr(so, '/')) {
        buf = malloc(strlen(so) + 3);
        if (!buf)
            return WDRT_OUT_OF_MEMORY;
        strcpy(buf, "./");
        strcat(buf, so);
        path = buf;
    }
    void *h = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    free(buf);
    if (!h) {
        fprintf(stderr, "wdrt: %s\n", dlerror());
        return WDRT_LOAD;
    }

    size_t len = strlen(name);
    char *sym = malloc(len + sizeof "_class");
    if (!sym) {
        dlclose(h);
        return WDRT_OUT_OF_MEMORY;
    }
    memcpy(sym, name, len);
    memcpy(sym + len, "_class", sizeof "_class");
    dlerror();
    void *p = dlsym(h, sym);
    const char *err = dlerror();
    if (err || !p) {
        fprintf(stderr, "wdrt: %s: no symbol %s%s%s\n", so, sym,
                err ? ": " : "", err ? err : "");
        free(sym);
        dlclose(h);
        return WDRT_LOAD;
    }
    free(sym);

    const wdv_class *cls = (const wdv_class *)p;
    if (cls->abi_version != WDV_ABI_VERSION) {
        fprintf(stderr, "wdrt: %s: voice ABI version %d, host expects %d\n",
                so, cls->abi_version, WDV_ABI_VERSION);
        dlclose(h);
        return WDRT_LOAD;
    }
    lib->handle = h;
    lib->cls = cls;
    return WDRT_OK;
}

void wdrt_voice_close(wdrt_voice_lib *lib)
{
    if (!lib)
        return;
    if (lib->handle)
        dlclose(lib->handle);
    lib->handle = NULL;
    lib->cls = NULL;
}

/* Largest block wdrt_render hands to a voice; also the length of the
 * silent buffer that stands in for NULL inputs. */
#define WDRT_MAX_BLOCK 4096
#define WDRT_MAX_CH 64

static const double wdrt_zero[WDRT_MAX_BLOCK];

void wdrt_render(const wdv_class *cls, void *state, const double *const *in,
                 double *const *out, long nframes, int block)
{
    if (!cls || !state || nframes <= 0)
        return;
    if (block <= 0 || block > WDRT_MAX_BLOCK)
        block = WDRT_MAX_BLOCK;

    const double *ip[WDRT_MAX_CH];
    double *op[WDRT_MAX_CH];
    const double *const *inv = ip;
    double *const *outv = op;
    int nin = cls->n_inputs, nout = cls->n_outputs;

    /* Beyond the fixed channel arrays, fall back to the heap once. */
    const double **ipa = NULL;
    double **opa = NULL;
    const double **ipw = ip;
    double **opw = op;
    if (nin > WDRT_MAX_CH) {
        ipa = malloc((size_t)nin * sizeof *ipa);
        if (!ipa)
            return;
        ipw = ipa;
        inv = ipa;
    }
    if (nout > WDRT_MAX_CH) {
        opa = malloc((size_t)nout * sizeof *opa);
        if (!opa) {
            free(ipa);
            return;
        }
        opw = opa;
        outv = opa;
    }

    for (long pos = 0; pos < nframes; pos += block) {
        int n = (nframes - pos < block) ? (int)(nframes - pos) : block;
        for (int k = 0; k < nin; k++)
            ipw[k] = (in && in[k]) ? in[k] + pos : wdrt_zero;
        for (int k = 0; k < nout; k++)
            opw[k] = out[k] + pos;
        cls->process(state, inv, outv, n);
    }
    free(ipa);
    free(opa);
}
