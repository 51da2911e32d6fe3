/* testlib.c - helpers shared by the cmocka tests (see testlib.h). */
#include "testlib.h"

#include <cmocka.h>
#include <complex.h>
#include <dirent.h>
#include <sys/stat.h>
#include <errno.h>
#include <glob.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

/* ---- voices ---- */

int tl_voice_name(const char *dir, char *name, size_t cap) {
    DIR *d = opendir(dir);
    if (!d)
        return -1;
    int found = 0;
    struct dirent *de;
    while ((de = readdir(d)) != NULL) {
        size_t len = strlen(de->d_name);
        if (len > 2 && !strcmp(de->d_name + len - 2, ".c")) {
            found++;
            if (len - 2 < cap) {
                memcpy(name, de->d_name, len - 2);
                name[len - 2] = '\0';
            }
        }
    }
    closedir(d);
    return found == 1 ? 0 : -1;
}

void tl_remove_dir(const char *dir) {
    DIR *d = opendir(dir);
    if (!d)
        return;
    struct dirent *de;
    char path[512];
    while ((de = readdir(d)) != NULL) {
        if (!strcmp(de->d_name, ".") || !strcmp(de->d_name, ".."))
            continue;
        snprintf(path, sizeof path, "%s/%s", dir, de->d_name);
        struct stat st;
        if (lstat(path, &st) == 0 && S_ISDIR(st.st_mode))
            tl_remove_dir(path);
        else
            unlink(path);
    }
    closedir(d);
    rmdir(dir);
}

wdrt_scene *tl_scene_load(const char *dir, const char *name, const char *text) {
    const char *path = tl_write_file(dir, name, text);
    char err[4096] = "";
    wdrt_scene *s = NULL;
    if (wdrt_scene_load(path, &s, err, sizeof err) != WDRT_OK) {
        fprintf(stderr, "%s", err);
        return NULL;
    }
    return s;
}

void tl_scene_error(const char *dir, const char *name, const char *text, char *err, size_t len) {
    const char *path = tl_write_file(dir, name, text);
    wdrt_scene *s = NULL;
    err[0] = 0;
    if (wdrt_scene_load(path, &s, err, len) == WDRT_OK)
        wdrt_scene_free(s);
}

int tl_temp_dir(char dir[64], const char *stem) {
    snprintf(dir, 64, "/tmp/%.40s.XXXXXX", stem);
    return mkdtemp(dir) ? 0 : -1;
}

/* Build directories not yet removed, so that a test that fails between
 * tl_voice_build and tl_voice_free leaves nothing behind at exit. */
#define TL_MAX_DIRS 256
static char tl_dirs[TL_MAX_DIRS][64];

static int keep_dirs(void) {
    const char *keep = getenv("WDC_KEEP");
    return keep && *keep == '1';
}

static void remove_dirs_at_exit(void) {
    if (keep_dirs())
        return;
    for (int k = 0; k < TL_MAX_DIRS; k++)
        if (tl_dirs[k][0]) {
            tl_remove_dir(tl_dirs[k]);
            tl_dirs[k][0] = '\0';
        }
}

static void track_dir(const char *dir, int add) {
    static int registered;
    if (!registered) {
        atexit(remove_dirs_at_exit);
        registered = 1;
    }
    for (int k = 0; k < TL_MAX_DIRS; k++) {
        if (add && !tl_dirs[k][0]) {
            snprintf(tl_dirs[k], sizeof tl_dirs[k], "%s", dir);
            return;
        }
        if (!add && !strcmp(tl_dirs[k], dir)) {
            tl_dirs[k][0] = '\0';
            return;
        }
    }
}

/* Prints argv, space-separated, to stderr. */
static void print_argv(char *const argv[]) {
    for (int k = 0; argv[k]; k++)
        fprintf(stderr, "%s%s", k ? " " : "", argv[k]);
}

int tl_voice_make(const char *netlist, const char *dir, const char *const *extra,
                  const char *cflags) {
    const char *wdc = getenv("WDC");
    if (!wdc || !*wdc)
        wdc = "bin/wdc";
    char *argv[TL_MAX_WDC_ARGS + 5];
    int n = 0;
    argv[n++] = (char *)wdc;
    argv[n++] = (char *)netlist;
    argv[n++] = "-o";
    argv[n++] = (char *)dir;
    for (int k = 0; extra && extra[k]; k++) {
        if (k == TL_MAX_WDC_ARGS) {
            fprintf(stderr, "testlib: %s: more than %d arguments for wdc\n", netlist,
                    TL_MAX_WDC_ARGS);
            return -1;
        }
        argv[n++] = (char *)extra[k];
    }
    argv[n] = NULL;
    int st = -1;
    if (wdrt_spawn(argv, -1, &st) != WDRT_OK || st != 0) {
        fprintf(stderr, "testlib: ");
        print_argv(argv);
        fprintf(stderr, ": exit status %d\n", st);
        return -1;
    }
    char name[128];
    if (tl_voice_name(dir, name, sizeof name) != 0) {
        fprintf(stderr, "testlib: %s: expected one voice source in %s\n", netlist, dir);
        return -1;
    }
    char csrc[512], so[512];
    snprintf(csrc, sizeof csrc, "%s/%s.c", dir, name);
    snprintf(so, sizeof so, "%s/%s.so", dir, name);
    wdrt_result r = wdrt_voice_compile(csrc, so, NULL, cflags ? cflags : TL_VOICE_CFLAGS);
    if (r != WDRT_OK) {
        fprintf(stderr, "testlib: compiling %s: %s\n", csrc, wdrt_result_str(r));
        return -1;
    }
    return 0;
}

int tl_voice_load(tl_voice *v) {
    v->lib.handle = NULL;
    v->cls = NULL;
    if (tl_voice_name(v->dir, v->name, sizeof v->name) != 0) {
        fprintf(stderr, "testlib: expected one voice source in %s\n", v->dir);
        return -1;
    }
    char so[512];
    snprintf(so, sizeof so, "%s/%s.so", v->dir, v->name);
    wdrt_result r = wdrt_voice_open(so, v->name, &v->lib);
    if (r != WDRT_OK) {
        fprintf(stderr, "testlib: loading %s: %s\n", so, wdrt_result_str(r));
        return -1;
    }
    v->cls = v->lib.cls;
    return 0;
}

int tl_voice_build_args(const char *netlist, int single, const char *const *extra,
                        const char *cflags, tl_voice *v) {
    memset(v, 0, sizeof *v);
    snprintf(v->dir, sizeof v->dir, "/tmp/wdc-test-XXXXXX");
    if (!mkdtemp(v->dir)) {
        fprintf(stderr, "testlib: mkdtemp: %s\n", strerror(errno));
        v->dir[0] = '\0';
        return -1;
    }
    track_dir(v->dir, 1);
    /* --precision float first, then the caller's arguments */
    const char *args[TL_MAX_WDC_ARGS + 3];
    int n = 0;
    if (single) {
        args[n++] = "--precision";
        args[n++] = "float";
    }
    for (int k = 0; extra && extra[k] && n <= TL_MAX_WDC_ARGS; k++)
        args[n++] = extra[k];
    args[n] = NULL;
    if (tl_voice_make(netlist, v->dir, args, cflags) != 0 || tl_voice_load(v) != 0)
        return -1;
    if (v->cls->precision != (single ? 32 : 64)) {
        fprintf(stderr, "testlib: %s/%s.so: precision %d, expected %d\n", v->dir, v->name,
                v->cls->precision, single ? 32 : 64);
        return -1;
    }
    return 0;
}

const char *const tl_energy[] = {"--energy", NULL};

int tl_voice_build(const char *netlist, int single, tl_voice *v) {
    return tl_voice_build_args(netlist, single, NULL, NULL, v);
}

void tl_voice_free(tl_voice *v) {
    if (v->lib.handle)
        wdrt_voice_close(&v->lib);
    v->cls = NULL;
    if (v->dir[0]) {
        track_dir(v->dir, 0);
        if (!keep_dirs())
            tl_remove_dir(v->dir);
    }
    v->dir[0] = '\0';
}

void *tl_state_new(const wdv_class *cls, double fs) {
    size_t size = (cls->state_size + 63) / 64 * 64;
    void *p = NULL;
    if (posix_memalign(&p, 64, size ? size : 64) != 0)
        return NULL;
    memset(p, 0, size ? size : 64);
    cls->init(p, fs);
    return p;
}

void tl_state_free(void *state) { free(state); }

int tl_output_id(const wdv_class *cls, const char *name) {
    for (int k = 0; k < cls->n_outputs; k++)
        if (strcmp(cls->outputs[k].name, name) == 0)
            return k;
    return -1;
}

int tl_param_id(const wdv_class *cls, const char *name) {
    for (int k = 0; k < cls->n_params; k++)
        if (strcmp(cls->params[k].name, name) == 0)
            return k;
    return -1;
}

/* ---- fixtures ---- */

int tl_fixture_setup(void **state, const char *netlist, size_t data_size,
                     int (*load)(void *data), void (*release)(void *data)) {
    tl_fixture *fx = calloc(1, sizeof *fx);
    if (!fx)
        return -1;
    fx->data = calloc(1, data_size ? data_size : 1);
    if (!fx->data || load(fx->data) != 0) {
        free(fx->data);
        free(fx);
        return -1;
    }
    fx->release = release;
    if (tl_voice_build(netlist, 0, &fx->voice) != 0) {
        *state = fx;
        tl_fixture_teardown(state);
        *state = NULL;
        return -1;
    }
    *state = fx;
    return 0;
}

int tl_fixture_teardown(void **state) {
    tl_fixture *fx = *state;
    if (fx) {
        tl_voice_free(&fx->voice);
        if (fx->release)
            fx->release(fx->data);
        free(fx->data);
        free(fx);
    }
    return 0;
}

/* ---- random numbers ---- */

void tl_rng_seed(tl_rng *r, uint64_t seed) {
    /* splitmix64 of the seed, so nearby seeds give unrelated streams */
    uint64_t z = seed + 0x9E3779B97F4A7C15ull;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    z ^= z >> 31;
    r->s = z ? z : 0x2545F4914F6CDD1Dull;
}

uint64_t tl_rng_next(tl_rng *r) {
    uint64_t x = r->s;
    x ^= x >> 12;
    x ^= x << 25;
    x ^= x >> 27;
    r->s = x;
    return x * 0x2545F4914F6CDD1Dull;
}

double tl_rng_uniform(tl_rng *r) {
    return (double)(tl_rng_next(r) >> 11) * (1.0 / 9007199254740992.0);
}

double tl_rng_signed(tl_rng *r) { return 2.0 * tl_rng_uniform(r) - 1.0; }

uint64_t tl_hash_str(const char *s) {
    uint64_t h = 1469598103934665603ull;
    for (; *s; s++)
        h = (h ^ (unsigned char)*s) * 1099511628211ull;
    return h;
}

/* ---- measures ---- */

double rel_rms_error(const double *a, const double *b, long n) {
    double num = 0.0, den = 0.0;
    for (long k = 0; k < n; k++) {
        double d = a[k] - b[k];
        num += d * d;
        den += b[k] * b[k];
    }
    if (den == 0.0)
        return n > 0 ? sqrt(num / (double)n) : 0.0;
    return sqrt(num / den);
}

double tl_db(double x) { return x > 0.0 ? 20.0 * log10(x) : -400.0; }

long tl_first_divergence(const double *a, const double *b, long n, double tol) {
    double peak = 0.0;
    for (long k = 0; k < n; k++)
        if (fabs(b[k]) > peak)
            peak = fabs(b[k]);
    if (peak == 0.0)
        peak = 1.0;
    for (long k = 0; k < n; k++)
        if (!(fabs(a[k] - b[k]) <= tol * peak))
            return k;
    return -1;
}

void tl_assert_buf_near_(const double *a, const double *b, long n, double tol,
                         const char *file, int line) {
    for (long k = 0; k < n; k++)
        if (!(fabs(a[k] - b[k]) <= tol)) {
            print_error("sample %ld: %.17g vs %.17g (difference %.3g > %.3g)\n", k,
                        a[k], b[k], a[k] - b[k], tol);
            _fail(file, line);
        }
}

/* ---- input signals ---- */

void tl_signal_init(tl_signal *s, tl_sigkind kind, double amp, long at,
                    uint64_t seed) {
    memset(s, 0, sizeof *s);
    s->kind = kind;
    s->amp = amp;
    s->at = at;
    s->seed = seed;
    for (int k = 0; k < TL_MAX_INPUTS; k++)
        tl_rng_seed(&s->rng[k], seed * 1000003ull + (uint64_t)k);
}

double tl_signal_next(tl_signal *s, int input, long n) {
    tl_rng *r = &s->rng[input % TL_MAX_INPUTS];
    switch (s->kind) {
    case TL_SILENCE:
        return 0.0;
    case TL_NOISE:
        return s->amp * tl_rng_signed(r);
    case TL_STEP:
        return n >= s->at ? s->amp : 0.0;
    case TL_BURST:
        return n < s->at ? s->amp * tl_rng_signed(r) : 0.0;
    case TL_IMPULSE:
        return n == s->at ? s->amp : 0.0;
    }
    return 0.0;
}

/* ---- parameter changes ---- */

static double random_in_range(tl_rng *r, double lo, double hi) {
    if (lo > 0.0 && hi >= 10.0 * lo)
        return lo * pow(hi / lo, tl_rng_uniform(r));
    return lo + (hi - lo) * tl_rng_uniform(r);
}

int tl_random_changes(const Circuit *c, tl_rng *r, long nframes, int nchanges,
                      tl_change *out) {
    int n = 0;
    for (int j = 0; j < nchanges; j++) {
        /* moment j in the j-th of nchanges + 1 equal slices, not at 0 */
        double lo = (double)(j + 1) / (nchanges + 1) - 0.5 / (nchanges + 1);
        double f = lo + tl_rng_uniform(r) * (0.5 / (nchanges + 1));
        long at = (long)(f * (double)nframes) / 64 * 64;
        if (at <= 0)
            at = 64;
        for (int p = 0; p < c->nparams; p++) {
            out[n].at = at;
            out[n].param = p;
            out[n].value = random_in_range(r, c->params[p].min, c->params[p].max);
            n++;
        }
    }
    return n;
}

/* ---- buffers ---- */

double **tl_bufs_new(int n, long len) {
    double **b = calloc((size_t)n + 1, sizeof(double *));
    if (!b)
        return NULL;
    for (int k = 0; k < n; k++) {
        b[k] = calloc((size_t)len + 1, sizeof(double));
        if (!b[k]) {
            for (int j = 0; j < k; j++)
                free(b[j]);
            free(b);
            return NULL;
        }
    }
    return b;
}

void tl_bufs_free(double **b, int n) {
    if (!b)
        return;
    for (int k = 0; k < n; k++)
        free(b[k]);
    free(b);
}

/* ---- side by side ---- */

static int check_ports(const Circuit *c, const wdv_class *cls) {
    int ok = 1;
    if (cls->n_inputs != c->ninputs || cls->n_outputs != c->nouts ||
        cls->n_params != c->nparams) {
        print_error("voice %s has %d inputs, %d outputs, %d params; the netlist %d, "
                    "%d, %d\n",
                    cls->name, cls->n_inputs, cls->n_outputs, cls->n_params,
                    c->ninputs, c->nouts, c->nparams);
        return 0;
    }
    for (int k = 0; k < c->nouts; k++)
        if (strcmp(cls->outputs[k].name, c->outs[k].name)) {
            print_error("voice %s output %d is '%s', the netlist's '%s'\n", cls->name,
                        k, cls->outputs[k].name, c->outs[k].name);
            ok = 0;
        }
    for (int k = 0; k < c->ninputs; k++)
        if (strcmp(cls->inputs[k].name, c->inputs[k])) {
            print_error("voice %s input %d is '%s', the netlist's '%s'\n", cls->name, k,
                        cls->inputs[k].name, c->inputs[k]);
            ok = 0;
        }
    for (int k = 0; k < c->nparams; k++)
        if (strcmp(cls->params[k].name, c->params[k].name)) {
            print_error("voice %s param %d is '%s', the netlist's '%s'\n", cls->name, k,
                        cls->params[k].name, c->params[k].name);
            ok = 0;
        }
    return ok;
}

int tl_run_side_by_side(const Circuit *c, const wdv_class *cls,
                        const tl_run_opts *o, tl_run *r) {
    memset(r, 0, sizeof *r);
    if (!check_ports(c, cls))
        return -1;
    long N = o->nframes;
    int nin = c->ninputs, nout = c->nouts;
    int block = o->block > 0 ? o->block : 64;
    if (o->track_energy)
        block = 1;
    r->nframes = N;
    r->nouts = nout;
    r->ninputs = nin;
    r->voice = tl_bufs_new(nout, N);
    r->ref = tl_bufs_new(nout, N);
    if (o->with_floor)
        r->floor = tl_bufs_new(nout, N);
    r->in = tl_bufs_new(nin, N);
    void *st = tl_state_new(cls, o->fs);
    int linear = refsim_can_simulate(c);
    refsim *rs = linear ? refsim_new(c, o->fs, NULL) : NULL;
    refsim *rf = linear && o->with_floor ? refsim_new(c, o->fs, NULL) : NULL;
    r->have_ref = linear;
    if (rf)
        refsim_round_state(rf, o->with_floor);
    double *rin = calloc((size_t)nin + 1, sizeof(double));
    double *rout = calloc((size_t)nout + 1, sizeof(double));
    const double **ip = calloc((size_t)nin + 1, sizeof(double *));
    double **op = calloc((size_t)nout + 1, sizeof(double *));
    if (o->track_energy) {
        r->venergy = calloc((size_t)N + 1, sizeof(double));
        r->vwork = calloc((size_t)N + 1, sizeof(double));
        r->renergy = calloc((size_t)N + 1, sizeof(double));
        r->rwork = calloc((size_t)N + 1, sizeof(double));
    }
    int ok = r->voice && r->ref && r->in && st && (rs || !linear) && rin && rout &&
             ip && op && (!linear || !o->with_floor || (rf && r->floor)) &&
             (!o->track_energy || (r->venergy && r->vwork && r->renergy && r->rwork));
    if (!ok) {
        print_error("tl_run_side_by_side: %s\n",
                    !rs && st ? "refsim cannot simulate this network" : "out of memory");
        goto done;
    }
    for (int k = 0; k < nin; k++)
        for (long n = 0; n < N; n++)
            r->in[k][n] = o->input ? o->input[k][n] : o->signal ? tl_signal_next(o->signal, k, n) : 0.0;

    if (o->params0)
        for (int p = 0; p < c->nparams; p++) {
            cls->set_param(st, p, o->params0[p]);
            if (rs)
                refsim_set_param(rs, p, o->params0[p]);
            if (rf)
                refsim_set_param(rf, p, o->params0[p]);
        }
    r->venergy0 = cls->energy(st);
    r->vwork0 = cls->work ? cls->work(st) : NAN;
    r->renergy0 = rs ? refsim_energy(rs) : 0.0;
    r->rwork0 = rs ? refsim_work(rs) : 0.0;

    int ch = 0;
    for (long pos = 0; pos < N;) {
        while (ch < o->nchanges && o->changes[ch].at <= pos) {
            cls->set_param(st, o->changes[ch].param, o->changes[ch].value);
            if (rs)
                refsim_set_param(rs, o->changes[ch].param, o->changes[ch].value);
            if (rf)
                refsim_set_param(rf, o->changes[ch].param, o->changes[ch].value);
            ch++;
        }
        long end = (pos / block + 1) * block;
        if (end > N)
            end = N;
        if (ch < o->nchanges && o->changes[ch].at < end)
            end = o->changes[ch].at;
        int n = (int)(end - pos);
        for (int k = 0; k < nin; k++)
            ip[k] = r->in[k] + pos;
        for (int k = 0; k < nout; k++)
            op[k] = r->voice[k] + pos;
        cls->process(st, ip, op, n);
        for (long t = pos; rs && t < end; t++) {
            for (int k = 0; k < nin; k++)
                rin[k] = r->in[k][t];
            refsim_step(rs, rin, rout);
            for (int k = 0; k < nout; k++)
                r->ref[k][t] = rout[k];
            if (rf) {
                refsim_step(rf, rin, rout);
                for (int k = 0; k < nout; k++)
                    r->floor[k][t] = rout[k];
            }
        }
        if (o->track_energy) {
            r->venergy[end - 1] = cls->energy(st);
            r->vwork[end - 1] = cls->work ? cls->work(st) : NAN;
            r->renergy[end - 1] = rs ? refsim_energy(rs) : 0.0;
            r->rwork[end - 1] = rs ? refsim_work(rs) : 0.0;
        }
        pos = end;
    }
done:
    free(rin);
    free(rout);
    free(ip);
    free(op);
    refsim_free(rs);
    refsim_free(rf);
    tl_state_free(st);
    if (!ok) {
        tl_run_free(r);
        return -1;
    }
    return 0;
}

void tl_run_free(tl_run *r) {
    tl_bufs_free(r->voice, r->nouts);
    tl_bufs_free(r->ref, r->nouts);
    tl_bufs_free(r->floor, r->nouts);
    tl_bufs_free(r->in, r->ninputs);
    free(r->venergy);
    free(r->vwork);
    free(r->renergy);
    free(r->rwork);
    memset(r, 0, sizeof *r);
}

double tl_run_worst(const tl_run *r, int *which) {
    double worst = 0.0;
    int w = 0;
    for (int k = 0; k < r->nouts; k++) {
        double e = rel_rms_error(r->voice[k], r->ref[k], r->nframes);
        if (!(e <= worst)) {
            worst = e;
            w = k;
        }
    }
    if (which)
        *which = w;
    return worst;
}

double tl_run_floor(const tl_run *r) {
    double worst = 0.0;
    if (!r->floor)
        return 0.0;
    for (int k = 0; k < r->nouts; k++) {
        double e = rel_rms_error(r->floor[k], r->ref[k], r->nframes);
        if (!(e <= worst))
            worst = e;
    }
    return worst;
}

void tl_run_report(const tl_run *r, const Circuit *c, int k, double tol) {
    long n = tl_first_divergence(r->voice[k], r->ref[k], r->nframes, tol);
    if (n < 0) {
        print_message("  output %s: no sample differs by more than %.3g of the peak\n",
                      c->outs[k].name, tol);
        return;
    }
    print_message("  output %s: first sample off by more than %.3g of the peak: n=%ld, "
                  "voice %.17g, reference %.17g\n",
                  c->outs[k].name, tol, n, r->voice[k][n], r->ref[k][n]);
}

/* ---- netlists ---- */

char **tl_netlists(int *n) {
    glob_t g;
    *n = 0;
    /* the examples, and the test networks that exercise corner cases */
    if (glob("netlists/*.wdn", 0, NULL, &g) != 0)
        return NULL;
    glob("tests/nets/*.wdn", GLOB_APPEND, NULL, &g);
    char **v = calloc(g.gl_pathc + 1, sizeof(char *));
    if (!v) {
        globfree(&g);
        return NULL;
    }
    for (size_t k = 0; k < g.gl_pathc; k++)
        v[k] = strdup(g.gl_pathv[k]);
    *n = (int)g.gl_pathc;
    globfree(&g);
    return v;
}

void tl_netlists_free(char **v, int n) {
    if (!v)
        return;
    for (int k = 0; k < n; k++)
        free(v[k]);
    free(v);
}

static void test_netlists_present(void **state) {
    int n = *(int *)*state;
    assert_true(n > 0);
}

int tl_run_per_netlist(const char *group, void (*fn)(void **state),
                       const struct CMUnitTest *fixed, size_t nfixed) {
    int n = 0;
    char **paths = tl_netlists(&n);
    size_t first = 1 + nfixed;
    struct CMUnitTest *tests = calloc(first + (size_t)n, sizeof *tests);
    char **names = calloc((size_t)n + 1, sizeof *names);
    int rc = 1;
    if (!tests || !names)
        goto out;
    tests[0].name = "netlists_present";
    tests[0].test_func = test_netlists_present;
    tests[0].initial_state = &n;
    for (size_t k = 0; k < nfixed; k++)
        tests[1 + k] = fixed[k];
    for (int k = 0; k < n; k++) {
        names[k] = malloc(strlen(group) + strlen(paths[k]) + 2);
        if (!names[k])
            goto out;
        sprintf(names[k], "%s %s", group, paths[k]);
        tests[first + (size_t)k].name = names[k];
        tests[first + (size_t)k].test_func = fn;
        tests[first + (size_t)k].initial_state = paths[k];
    }
    rc = _cmocka_run_group_tests(group, tests, first + (size_t)n, NULL, NULL);
out:
    for (int k = 0; names && k < n; k++)
        free(names[k]);
    free(names);
    free(tests);
    tl_netlists_free(paths, n);
    return rc;
}

/* ---- frequency responses ---- */

double *tl_impulse_response(const wdv_class *cls, void *state, int oid, int block,
                            double decay_floor, long max_frames, long *n) {
    const long chunk = TL_IR_CHUNK;
    int nout = cls->n_outputs;
    long cap = 16 * chunk, len = 0;
    double *h = malloc((size_t)cap * sizeof *h);
    double *scratch = malloc((size_t)chunk * (size_t)nout * sizeof *scratch);
    double **out = malloc((size_t)nout * sizeof *out);
    double *imp = calloc((size_t)chunk, sizeof *imp);
    const double **in = calloc((size_t)(cls->n_inputs > 0 ? cls->n_inputs : 1), sizeof *in);
    if (!h || !scratch || !out || !imp || !in)
        goto fail;
    imp[0] = 1.0;
    for (;;) {
        if (len + chunk > cap) {
            cap *= 2;
            double *p = realloc(h, (size_t)cap * sizeof *h);
            if (!p)
                goto fail;
            h = p;
        }
        for (int k = 0; k < nout; k++)
            out[k] = (k == oid) ? h + len : scratch + (size_t)k * (size_t)chunk;
        for (int k = 0; k < cls->n_inputs; k++)
            in[k] = (len == 0) ? imp : NULL;
        wdrt_render(cls, state, in, out, chunk, block);
        double peak = 0;
        for (long i = len; i < len + chunk; i++) {
            if (!isfinite(h[i]))
                goto fail;
            if (fabs(h[i]) > peak)
                peak = fabs(h[i]);
        }
        len += chunk;
        if (len > chunk && peak < decay_floor)
            break;
        if (len >= max_frames)
            goto fail;
    }
    free(scratch);
    free(out);
    free(imp);
    free(in);
    *n = len;
    return h;
fail:
    free(h);
    free(scratch);
    free(out);
    free(imp);
    free(in);
    return NULL;
}

double complex tl_dtft(const double *h, long n, double w) {
    double complex acc = 0;
    const double complex step = cexp(-I * w);
    for (long k0 = 0; k0 < n; k0 += 256) {
        long k1 = k0 + 256 < n ? k0 + 256 : n;
        double complex z = cexp(-I * (w * (double)k0));
        double complex part = 0;
        for (long k = k0; k < k1; k++) {
            part += h[k] * z;
            z *= step;
        }
        acc += part;
    }
    return acc;
}

/* ---- reference data ---- */

int tl_read_csv(const char *path, const char *header, const char *regen,
                int (*row)(const char *line, const char *path, int lineno, void *ctx),
                void *ctx) {
    FILE *f = fopen(path, "r");
    if (!f) {
        fprintf(stderr, "testlib: cannot open %s (run from the repository root; "
                        "regenerate with %s)\n",
                path, regen);
        return -1;
    }
    int lineno = 0;
    char line[512];
    while (fgets(line, sizeof line, f)) {
        lineno++;
        if (lineno == 1 && header && strncmp(line, header, strlen(header)) == 0)
            continue;
        if (line[0] == '\n' || line[0] == '#')
            continue;
        if (row(line, path, lineno, ctx) != 0) {
            fclose(f);
            return -1;
        }
    }
    fclose(f);
    return 0;
}

void tl_drive(tl_drive_kind kind, double amp, int hold, double fs, long n, uint64_t seed, double *x) {
    tl_rng r;
    tl_rng_seed(&r, seed);
    double left = 0, v = 0;
    for (long k = 0; k < n; k++) {
        if (kind == TL_DRIVE_SINE)
            x[k] = amp * sin(2 * M_PI * 440.0 * (double)k / fs);
        else if (kind == TL_DRIVE_NOISE)
            x[k] = amp * tl_rng_signed(&r);
        else {
            if (left-- <= 0) {
                v = amp * tl_rng_signed(&r);
                left = (double)(tl_rng_next(&r) % (uint64_t)hold);
            }
            x[k] = v;
        }
    }
}

const char *const tl_exact_diodes[] = {"--tol", "1e-12", NULL};

Circuit *tl_load_both(const char *path, const char *name, tl_voice *vd, tl_voice *vf) {
    Circuit *c = wdc_load(path);
    if (!c)
        fail_msg("%s: %s does not load", name, path);
    if (!refsim_can_simulate(c))
        fail_msg("%s: refsim cannot simulate it", name);
    if (tl_voice_build_args(path, 0, tl_exact_diodes, NULL, vd) != 0 ||
        tl_voice_build_args(path, 1, tl_exact_diodes, NULL, vf) != 0)
        fail_msg("%s: the voice could not be built", name);
    return c;
}

/* ---- transients of SPICE decks against ngspice ---- */

typedef struct tran_ctx {
    tl_tran *decks;
    int ndecks;
    double fs;
} tran_ctx;

static int tran_row(const char *line, const char *path, int lineno, void *vctx) {
    tran_ctx *x = vctx;
    const char *comma = strchr(line, ',');
    tl_tran *d = NULL;
    for (int k = 0; k < x->ndecks && comma; k++)
        if ((size_t)(comma - line) == strlen(x->decks[k].name) && !strncmp(line, x->decks[k].name, (size_t)(comma - line)))
            d = &x->decks[k];
    if (!d) {
        fprintf(stderr, "%s:%d: unknown deck\n", path, lineno);
        return -1;
    }
    char *end;
    double t = strtod(comma + 1, &end);
    long m = lround(t * x->fs);
    if (fabs(t * x->fs - (double)m) > 1e-6 || m != d->n) {
        fprintf(stderr, "%s:%d: unexpected time\n", path, lineno);
        return -1;
    }
    if (d->n % 1024 == 0)
        for (int k = 0; k < d->nvec; k++) {
            double *v = realloc(d->v[k], sizeof(double) * (size_t)(d->n + 1024));
            if (!v) {
                fprintf(stderr, "%s:%d: out of memory\n", path, lineno);
                return -1;
            }
            d->v[k] = v;
        }
    for (int k = 0; k < d->nvec; k++) {
        if (*end != ',') {
            fprintf(stderr, "%s:%d: too few values\n", path, lineno);
            return -1;
        }
        d->v[k][m] = strtod(end + 1, &end);
    }
    d->n++;
    return 0;
}

int tl_tran_read(const char *path, const char *regen, double fs, tl_tran *decks, int ndecks) {
    for (int d = 0; d < ndecks; d++) {
        decks[d].n = 0;
        for (int k = 0; k < TL_TRAN_MAXVEC; k++)
            decks[d].v[k] = NULL;
        if (decks[d].nvec < 1 || decks[d].nvec > TL_TRAN_MAXVEC) {
            fprintf(stderr, "testlib: deck %s: %d vectors\n", decks[d].name, decks[d].nvec);
            return -1;
        }
    }
    tran_ctx x = {decks, ndecks, fs};
    if (tl_read_csv(path, "deck", regen, tran_row, &x) != 0) {
        tl_tran_free(decks, ndecks);
        return -1;
    }
    return 0;
}

void tl_tran_free(tl_tran *decks, int ndecks) {
    for (int d = 0; d < ndecks; d++)
        for (int k = 0; k < TL_TRAN_MAXVEC; k++) {
            free(decks[d].v[k]);
            decks[d].v[k] = NULL;
        }
}

int tl_render_deck(const char *path, const char *dir, double fs, int over, double seconds, int nvec, double **y,
                   long nref) {
    char cmd[1024], csv[256], line[1024];
    snprintf(cmd, sizeof cmd, "bin/wdc %s --render %s/o.wav --csv %s/o.csv --rate %.17g --seconds %.9g 2>/dev/null",
             path, dir, dir, fs * over, seconds + 1.5 / fs);
    if (tl_system(cmd) != 0) {
        fprintf(stderr, "testlib: %s failed\n", cmd);
        return -1;
    }
    snprintf(csv, sizeof csv, "%s/o.csv", dir);
    FILE *f = fopen(csv, "r");
    if (!f) {
        fprintf(stderr, "testlib: cannot read %s\n", csv);
        return -1;
    }
    long n = 0;
    while (fgets(line, sizeof line, f)) {
        if (n % over == 0 && n / over < nref) {
            char *p = line;
            for (int k = 0; k < nvec; k++) {
                y[k][n / over] = strtod(p, &p);
                p += *p == ',';
            }
        }
        n++;
    }
    fclose(f);
    if (n < (nref - 1) * over + 1) {
        fprintf(stderr, "testlib: %s rendered %ld samples, wanted %ld\n", path, n, (nref - 1) * over + 1);
        return -1;
    }
    return 0;
}

/* ---- diagnostics ---- */

/* Runs the phases on `text`; returns the first line of what they printed,
 * or "" if all succeeded. */
char *tl_first_report(const char *text, Solver solver) {
    char *buf = NULL;
    size_t len = 0;
    FILE *mem = open_memstream(&buf, &len);
    FILE *saved = diag.out;
    diag.out = mem;
    Circuit *c = wdc_load_string("t.wdn", text);
    static char dir[32];
    strcpy(dir, "/tmp/wdc-diag.XXXXXX");
    if (c && mkdtemp(dir)) {
        jmp_buf jb;
        diag.jmp = &jb;
        if (!setjmp(jb)) {
            Wdf *w = wdf_build(c, c->rate);
            EmitOpts eo = {.outdir = dir, .solver = solver, .table = 64, .tol = 1e-12, .maxit = 50};
            emit_voice(w, &eo);
        }
        diag.jmp = NULL;
        char cmd[64]; /* also after an error unwound the emitter */
        snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
        if (system(cmd) != 0)
            fprintf(mem, "cannot remove %s\n", dir);
    }
    fclose(mem);
    diag.out = saved;
    char *nl = strchr(buf, '\n');
    if (nl)
        *nl = 0;
    return buf;
}


const char *tl_write_file(const char *dir, const char *name, const char *text) {
    static char path[4096];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    FILE *f = fopen(path, "w");
    if (!f)
        fail_msg("cannot write %s", path);
    fputs(text, f);
    if (fclose(f) != 0)
        fail_msg("cannot write %s", path);
    return path;
}

int tl_system(const char *cmd) {
    int r = system(cmd);
    return WIFEXITED(r) ? WEXITSTATUS(r) : -1;
}

Circuit *tl_netlist_load(const char *text, const char **report) {
    char *buf = NULL;
    size_t len = 0;
    FILE *saved = diag.out;
    diag.out = open_memstream(&buf, &len);
    if (!diag.out) {
        diag.out = saved;
        *report = "";
        return NULL;
    }
    Circuit *c = wdc_load_string("t.wdn", text);
    fclose(diag.out);
    diag.out = saved;
    *report = arena_strndup(buf, strcspn(buf, "\n"));
    free(buf);
    return c;
}
