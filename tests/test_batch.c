/*
 * test_batch.c - process_batch (wdc --batch) against process: the lanes of
 * a batch are the instances they stand for, bit for bit.
 *
 * For every example netlist (netlists/ *.wdn, tl_run_per_netlist) and the
 * test networks with idle hammers and the diode decks (one with its pair,
 * two whose diodes are solved jointly), in double and in float: LANES
 * instances (not a multiple of the voice's lanes of 8, so that the last
 * group is partly filled) each get their own param values, drawn in their
 * ranges, their own strikes (set_ic with random targets and values; a
 * strike that cannot hold is refused alike on both sides) and their own
 * input (white noise of their own seed and amplitude).  One set of
 * instances runs by process, one call per instance and block; a copy runs
 * by one process_batch call per block, on the same blocks of 1 to 127
 * frames; between blocks some instances take new param values or strikes,
 * the same on both sides.  Every output sample must be finite and
 * identical (compared as bits: the lanes compute what process computes, in
 * the same order), and so must every instance's energy() at the end (and
 * work(), for
 * voices built with --energy).  A batch of one instance and a batch of
 * none are run too.  The voices whose diodes diode_fast solves run again
 * driven past its tables (inputs up to 3 kV) and built with --tol 1e-12,
 * where fast_lane leaves lanes to diode_fast.  Lanes that start at
 * different points of their runs of FLUSH_RUN samples decay in silence
 * after a burst of noise: each is flushed at its own frames, as process
 * flushes it.  Strings and a transmission line run over several turns of
 * their buffers, which process steps through in wrap-free segments.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "testlib.h"

#define LANES 11
#define FRAMES 6000
#define MAXIO 16

typedef struct side {
    void *st[LANES];
    double *out[LANES][MAXIO];
} side;

static void side_new(side *s, const wdv_class *cls, double fs, int frames) {
    for (int l = 0; l < LANES; l++) {
        s->st[l] = tl_state_new(cls, fs);
        assert_non_null(s->st[l]);
        for (int k = 0; k < cls->n_outputs; k++) {
            s->out[l][k] = calloc((size_t)frames, sizeof(double));
            assert_non_null(s->out[l][k]);
        }
    }
}

static void side_free(side *s, const wdv_class *cls) {
    for (int l = 0; l < LANES; l++) {
        tl_state_free(s->st[l]);
        for (int k = 0; k < cls->n_outputs; k++)
            free(s->out[l][k]);
    }
}

/* The same random param value or strike for lane l on both sides. */
static void change(const wdv_class *cls, side *a, side *b, int l, tl_rng *r) {
    if (cls->n_params && tl_rng_uniform(r) < 0.5) {
        int id = (int)(tl_rng_next(r) % (uint64_t)cls->n_params);
        const wdv_param *p = &cls->params[id];
        double v = p->min + (p->max - p->min) * tl_rng_uniform(r);
        assert_int_equal(cls->set_param(a->st[l], id, v), 0);
        assert_int_equal(cls->set_param(b->st[l], id, v), 0);
    } else if (cls->n_ic_targets) {
        int ids[2];
        double vals[2];
        int n = 1 + (int)(tl_rng_next(r) % 2);
        for (int k = 0; k < n; k++) {
            ids[k] = (int)(tl_rng_next(r) % (uint64_t)cls->n_ic_targets);
            /* velocities and voltages near 1, displacements near 1 mm */
            vals[k] = tl_rng_signed(r) * (cls->ic_targets[ids[k]].name[0] == 'x' ? 1e-3 : 1.0);
        }
        int ra = cls->set_ic(a->st[l], n, ids, vals), rb = cls->set_ic(b->st[l], n, ids, vals);
        assert_int_equal(ra, rb);
    }
}

/* Frames pos to pos + nf: side a's instances by a process call each, side
 * b's by one process_batch call; in[l] are lane l's inputs. */
static void block(const wdv_class *cls, side *a, side *b, double *in[][MAXIO], int pos, int nf) {
    const double *ip[LANES][MAXIO], *const *ipl[LANES];
    double *op[LANES][MAXIO], *const *opl[LANES];
    void *bst[LANES];
    for (int l = 0; l < LANES; l++) {
        for (int k = 0; k < cls->n_inputs; k++)
            ip[l][k] = in[l][k] + pos;
        for (int k = 0; k < cls->n_outputs; k++)
            op[l][k] = a->out[l][k] + pos;
        cls->process(a->st[l], ip[l], op[l], nf);
        for (int k = 0; k < cls->n_outputs; k++)
            op[l][k] = b->out[l][k] + pos;
        ipl[l] = ip[l];
        opl[l] = op[l];
        bst[l] = b->st[l];
    }
    cls->process_batch(bst, LANES, ipl, opl, nf);
}

/* The voice of `path` built with `args` (which hold --batch), its lanes
 * against process calls; the inputs' amplitudes are drawn from 0.1 to 2.1,
 * or log-uniformly from 0.01 to amax if amax is positive. */
static void lanes_run(const char *path, int single, const char *const *args, double amax, int frames) {
    tl_voice v;
    int energy = 0;
    for (int i = 0; args[i]; i++)
        energy |= !strcmp(args[i], "--energy");
    if (tl_voice_build_args(path, single, args, NULL, &v) != 0)
        fail_msg("%s: the voice could not be built", path);
    const wdv_class *cls = v.cls;
    assert_non_null(cls->process_batch);
    assert_true(cls->n_inputs <= MAXIO && cls->n_outputs <= MAXIO);
    double fs = 48000;
    side a, b;
    side_new(&a, cls, fs, frames);
    side_new(&b, cls, fs, frames);
    tl_rng r;
    tl_rng_seed(&r, tl_hash_str(path) ^ (uint64_t)single);
    for (int l = 0; l < LANES; l++)
        for (int k = 0; k < 3; k++)
            change(cls, &a, &b, l, &r);
    /* each lane's inputs: noise of its own amplitude */
    double *in[LANES][MAXIO];
    for (int l = 0; l < LANES; l++)
        for (int k = 0; k < cls->n_inputs; k++) {
            in[l][k] = malloc(sizeof(double) * (size_t)frames);
            assert_non_null(in[l][k]);
            double amp = amax > 0 ? 0.01 * exp(log(amax / 0.01) * tl_rng_uniform(&r)) : 0.1 + 2 * tl_rng_uniform(&r);
            for (int n = 0; n < frames; n++)
                in[l][k][n] = amp * tl_rng_signed(&r);
        }
    for (int pos = 0; pos < frames;) {
        int nf = 1 + (int)(tl_rng_next(&r) % 127);
        if (nf > frames - pos)
            nf = frames - pos;
        block(cls, &a, &b, in, pos, nf);
        pos += nf;
        for (int l = 0; l < LANES; l++)
            if (tl_rng_uniform(&r) < 0.05)
                change(cls, &a, &b, l, &r);
    }
    long diff = 0, first = -1, bad = 0;
    int fl = -1, fk = -1;
    for (int l = 0; l < LANES; l++)
        for (int k = 0; k < cls->n_outputs; k++)
            for (int n = 0; n < frames; n++) {
                if (memcmp(&a.out[l][k][n], &b.out[l][k][n], sizeof(double))) {
                    if (first < 0)
                        first = n, fl = l, fk = k;
                    diff++;
                }
                bad += !isfinite(a.out[l][k][n]); /* alike on both sides is no excuse */
            }
    int ediff = 0;
    for (int l = 0; l < LANES; l++) {
        double ea = cls->energy(a.st[l]), eb = cls->energy(b.st[l]);
        double wa = energy ? cls->work(a.st[l]) : 0, wb = energy ? cls->work(b.st[l]) : 0;
        ediff += memcmp(&ea, &eb, sizeof ea) != 0;
        ediff += energy && memcmp(&wa, &wb, sizeof wa) != 0;
    }
    /* a batch of one instance, and of none, over the first 16 frames again */
    const double *ip[MAXIO], *const *ipl[1] = {ip};
    double *op[MAXIO], *const *opl[1] = {op};
    for (int k = 0; k < cls->n_inputs; k++)
        ip[k] = in[0][k];
    for (int k = 0; k < cls->n_outputs; k++)
        op[k] = b.out[0][k];
    cls->process_batch(b.st, 1, ipl, opl, 16);
    cls->process_batch(b.st, 0, ipl, opl, 16);
    /* three instances that share their output buffers: the last one's
     * samples are what is left, as after three process calls in order */
    enum { NS = 3, NSF = 64 };
    double shared[2][MAXIO][NSF];
    const double *sip[NS][MAXIO], *const *sipl[NS];
    double *sop[2][MAXIO], *const *sopl[NS];
    for (int l = 0; l < NS; l++) {
        for (int k = 0; k < cls->n_inputs; k++)
            sip[l][k] = in[l][k];
        sipl[l] = sip[l];
    }
    for (int k = 0; k < cls->n_outputs; k++)
        sop[0][k] = shared[0][k], sop[1][k] = shared[1][k];
    for (int l = 0; l < NS; l++) {
        cls->process(a.st[l], sip[l], sop[0], NSF);
        sopl[l] = sop[1];
    }
    cls->process_batch(b.st, NS, sipl, sopl, NSF);
    for (int k = 0; k < cls->n_outputs; k++)
        diff += memcmp(shared[0][k], shared[1][k], sizeof shared[0][k]) != 0;
    char opts[64] = "";
    for (int i = 0; args[i]; i++)
        if (strcmp(args[i], "--batch") && strlen(opts) + strlen(args[i]) + 2 < sizeof opts)
            strcat(strcat(opts, " "), args[i]);
    printf("%-34s %-6s%s%s %d lanes, %d frames: %ld output samples and %d energies%s differ from process\n", path,
           single ? "float" : "double", opts, amax > 0 ? " (loud)" : "", LANES, frames, diff, ediff,
           energy ? " and works" : "");
    if (diff)
        print_error("first at lane %d, output %d, frame %ld: process %.17g, batch %.17g\n", fl, fk, first,
                    a.out[fl][fk][first], b.out[fl][fk][first]);
    for (int l = 0; l < LANES; l++)
        for (int k = 0; k < cls->n_inputs; k++)
            free(in[l][k]);
    side_free(&a, cls);
    side_free(&b, cls);
    tl_voice_free(&v);
    if (bad)
        print_error("%s: %ld output samples are not finite\n", path, bad);
    assert_int_equal(diff, 0);
    assert_int_equal(ediff, 0);
    assert_int_equal(bad, 0);
}

static void lanes_same(const char *path, int single, int energy) {
    static const char *const batch[] = {"--batch", NULL}, *const counted[] = {"--batch", "--energy", NULL};
    lanes_run(path, single, energy ? counted : batch, 0, FRAMES);
}

static void test_netlist(void **state) {
    const char *path = *state;
    lanes_same(path, 0, 0);
    lanes_same(path, 1, 0);
}

/* Without --batch a class has no process_batch. */
static void test_opt_in(void **state) {
    (void)state;
    tl_voice v;
    assert_int_equal(tl_voice_build("netlists/rc_lowpass.wdn", 0, &v), 0);
    assert_null(v.cls->process_batch);
    tl_voice_free(&v);
}

static void test_hammers(void **state) {
    (void)state;
    static const char *const nets[] = {"tests/nets/hammers_eight.wdn", "tests/nets/idle_with.wdn",
                                       "netlists/clipper_sym.cir", "netlists/clipper_asym.cir",
                                       "netlists/bridge.cir"};
    for (int k = 0; k < 5; k++) {
        lanes_same(nets[k], 0, 0);
        lanes_same(nets[k], 1, 0);
    }
}

/* Voices that count their sources' work (--energy): work() too. */
static void test_energy(void **state) {
    (void)state;
    static const char *const nets[] = {"netlists/diode_clipper.wdn", "netlists/rlc_series.wdn",
                                       "netlists/mallet_plate.wdn"};
    for (int k = 0; k < 3; k++)
        lanes_same(nets[k], 0, 1);
}

/* Diodes that diode_fast solves, driven past its tables (inputs up to 3
 * kV) and solved to a tighter tol than the tables': the lanes that
 * fast_lane leaves to diode_fast get its answers, bit for bit. */
static void test_fast_lanes(void **state) {
    (void)state;
    static const char *const nets[] = {"netlists/diode_clipper.wdn", "netlists/diode_single.wdn",
                                       "netlists/clipper_asym.cir", "netlists/tubescreamer.cir"};
    static const char *const batch[] = {"--batch", NULL}, *const tight[] = {"--batch", "--tol", "1e-12", NULL};
    for (int k = 0; k < 4; k++)
        for (int single = 0; single < 2; single++) {
            lanes_run(nets[k], single, batch, 3000, FRAMES);
            lanes_run(nets[k], single, tight, 30, FRAMES);
        }
}

/* Strings and a transmission line over several turns of their buffers:
 * process steps through segments in which no line position wraps (8192
 * positions a line in the pluck, 512 in hammers_eight, 128 in
 * clipper_line), its samples against the lanes', which mask every
 * position. */
static void test_wraps(void **state) {
    (void)state;
    static const char *const nets[] = {"netlists/pluck.wdn", "tests/nets/hammers_eight.wdn",
                                       "netlists/clipper_line.wdn"};
    static const char *const batch[] = {"--batch", NULL};
    for (int k = 0; k < 3; k++)
        lanes_run(nets[k], k == 2, batch, 0, 3 * 8192 + 517);
}

/* Lanes at different points of their runs of FLUSH_RUN (8) samples,
 * decaying in silence after a burst of noise: each lane's states are
 * flushed at its own frames, as process flushes them, and the flushes
 * happen (once below FLUSH_BELOW, 1e-30 in double and 1e-18 in float, an
 * output is 0 within a run or two, where the first output is a
 * capacitor's voltage, the mean of its two waves: `cap`). */
static void lanes_decay(const char *path, int single, int cap) {
    static const char *const batch[] = {"--batch", NULL};
    tl_voice v;
    if (tl_voice_build_args(path, single, batch, NULL, &v) != 0)
        fail_msg("%s: the voice could not be built", path);
    const wdv_class *cls = v.cls;
    assert_true(cls->n_inputs <= MAXIO && cls->n_outputs <= MAXIO);
    side a, b;
    side_new(&a, cls, 48000, FRAMES);
    side_new(&b, cls, 48000, FRAMES);
    tl_rng r;
    tl_rng_seed(&r, tl_hash_str(path) ^ 77u ^ (uint64_t)single);
    double *in[MAXIO];
    for (int k = 0; k < cls->n_inputs; k++) {
        in[k] = calloc(FRAMES, sizeof(double));
        assert_non_null(in[k]);
        for (int n = 0; n < 300; n++)
            in[k][n] = tl_rng_signed(&r);
    }
    double *lin[LANES][MAXIO]; /* every lane's inputs are the same */
    const double *ip[MAXIO];
    double *op[MAXIO];
    /* lane l starts l frames into its runs: l frames of silence first, by process on both sides */
    for (int l = 0; l < LANES; l++) {
        for (int k = 0; k < cls->n_inputs; k++)
            lin[l][k] = in[k], ip[k] = in[k] + FRAMES - LANES;
        for (int k = 0; k < cls->n_outputs; k++)
            op[k] = a.out[l][k];
        cls->process(a.st[l], ip, op, l);
        cls->process(b.st[l], ip, op, l);
    }
    for (int pos = 0; pos < FRAMES;) {
        int nf = 1 + (int)(tl_rng_next(&r) % 127);
        if (nf > FRAMES - pos)
            nf = FRAMES - pos;
        block(cls, &a, &b, lin, pos, nf);
        pos += nf;
    }
    const double below = single ? 1e-18 : 1e-30;
    long diff = 0, tiny = 0, worst = 0;
    for (int l = 0; l < LANES; l++)
        for (int k = 0; k < cls->n_outputs; k++) {
            long t = 0;
            for (int n = 0; n < FRAMES; n++) {
                diff += memcmp(&a.out[l][k][n], &b.out[l][k][n], sizeof(double)) != 0;
                t += k == 0 && a.out[l][k][n] != 0 && fabs(a.out[l][k][n]) < below;
            }
            tiny += t;
            worst = t > worst ? t : worst;
        }
    printf("%-34s %-6s %d lanes decaying, %d frames: %ld output samples differ from process; "
           "%ld samples of output 0 below %g and not 0 (at most %ld in one lane)\n",
           path, single ? "float" : "double", LANES, FRAMES, diff, tiny, below, worst);
    for (int k = 0; k < cls->n_inputs; k++)
        free(in[k]);
    side_free(&a, cls);
    side_free(&b, cls);
    tl_voice_free(&v);
    assert_int_equal(diff, 0);
    if (cap)
        assert_true(worst <= 2 * 8);
}

static void test_decay(void **state) {
    (void)state;
    static const char *const nets[] = {"netlists/rc_lowpass.wdn", "netlists/rlc_series.wdn",
                                       "netlists/diode_clipper.wdn", "netlists/clipper_asym.cir"};
    static const int cap[] = {1, 0, 1, 1};
    for (int k = 0; k < 4; k++) {
        lanes_decay(nets[k], 0, cap[k]);
        lanes_decay(nets[k], 1, cap[k]);
    }
}

int main(void) {
    const struct CMUnitTest fixed[] = {cmocka_unit_test(test_hammers), cmocka_unit_test(test_opt_in),
                                       cmocka_unit_test(test_energy), cmocka_unit_test(test_fast_lanes),
                                       cmocka_unit_test(test_decay), cmocka_unit_test(test_wraps)};
    return tl_run_per_netlist("batch", test_netlist, fixed, 6);
}
