/*
 * test_lv2.c - LV2 bundles (wdc --lv2) checked with real LV2 tools.
 *
 * The bundles of the tone stack (an effect), piano_mid and the test key
 * tests/lv2host/key.wdn (instruments; the key has a pitch and a damper
 * param) compile warning-free under gcc and clang and pass lv2_validate.
 * lv2apply runs the tone stack on noise, and must give what
 * `wdc --render` gives for the same input, with the default controls and
 * with changed ones.  tests/lv2host (lilv) plays the key with MIDI in
 * blocks of odd lengths (0 and many chunks long included): a note must be
 * the voice struck directly through the ABI (state after init, the note's
 * pitch, the .ic scaled by velocity), starting at its frame; two notes
 * must sum; a note-off must damp (and wait for the sustain pedal); a
 * seventeenth note must steal the oldest, which fades out.  At 1 kHz,
 * too low a rate for its string, the key is refused at instantiation with
 * a message.  Offered a
 * worker, the key plays notes from the designs it made, and they must be
 * the same, bit for bit, as the notes it designs as they start.
 *
 * Tolerances: the plugin and the references compute the same double
 * samples (the same voice code; only where its process calls split
 * differs, which moves nothing above 1e-30); what differs is the rounding
 * to float32 of what the plugin outputs (and, for wdc --render, of what it
 * writes too): at most 2^-24 of a sample's magnitude per rounding.  So a
 * plugin sample may differ from a double reference by 2^-24 |y| and from a
 * float one by 2^-23 |y|; the tests allow 2^-23 of the signal's peak.
 */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "testlib.h"

#define KEY "tests/lv2host/key.wdn"
#define HOST "build/tests/lv2host"
#define TOL 0x1p-23 /* of the peak: float32 rounding, see above */

static char dir[64];     /* bundles in dir/lv2, everything else in dir */
static tl_voice key;     /* the key's voice, loaded in this process */
static Circuit *key_c;   /* and its netlist, for its .ic */

/* Runs a shell command; returns its exit status. */
static int run(const char *fmt, ...) {
    char cmd[4096];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(cmd, sizeof cmd, fmt, ap);
    va_end(ap);
    int st = system(cmd);
    return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

static int bundle(const char *cc, const char *netlist, const char *outdir, const char *name) {
    return run("CC='%s -Wall -Wextra -pedantic -Werror' bin/wdc %s --lv2 %s/%s.lv2", cc, netlist, outdir, name);
}

static int setup(void **s) {
    (void)s;
    strcpy(dir, "/tmp/wdc-lv2.XXXXXX");
    if (!mkdtemp(dir) || run("mkdir -p %s/lv2 %s/clang", dir, dir) != 0)
        return -1;
    if (bundle("gcc", "netlists/tonestack.wdn", format("%s/lv2", dir), "tonestack") != 0 ||
        bundle("gcc", "netlists/piano_mid.wdn", format("%s/lv2", dir), "piano_mid") != 0 ||
        bundle("gcc", KEY, format("%s/lv2", dir), "key") != 0)
        return -1;
    key_c = wdc_load(KEY);
    return key_c && tl_voice_build(KEY, 0, &key) == 0 ? 0 : -1;
}

static int teardown(void **s) {
    (void)s;
    tl_voice_free(&key);
    return run("rm -rf %s", dir) == 0 ? 0 : -1;
}

/* ---- files ---- */

/* Channel ch of a WAV file (malloc'd), its length in *n. */
static double *wav_channel(const char *path, int ch, long *n) {
    int nch;
    double fs, *frames;
    if (wdrt_wav_read(path, &nch, &fs, &frames, n) != WDRT_OK || ch >= nch) {
        print_error("cannot read channel %d of %s\n", ch, path);
        return NULL;
    }
    double *d = malloc(sizeof(double) * (size_t)(*n + 1));
    for (long i = 0; i < *n; i++)
        d[i] = frames[i * nch + ch];
    free(frames);
    return d;
}

static double peak(const double *x, long n) {
    double m = 0;
    for (long i = 0; i < n; i++)
        m = fabs(x[i]) > m ? fabs(x[i]) : m;
    return m;
}

static double rms(const double *x, long n) {
    double s = 0;
    for (long i = 0; i < n; i++)
        s += x[i] * x[i];
    return n ? sqrt(s / n) : 0;
}

/* Largest |a - b| relative to the peak of b. */
static double max_err(const double *a, const double *b, long n) {
    double e = 0, p = peak(b, n);
    for (long i = 0; i < n; i++)
        e = fabs(a[i] - b[i]) > e ? fabs(a[i] - b[i]) : e;
    return p > 0 ? e / p : e;
}

static long first_nonzero(const double *x, long n) {
    for (long i = 0; i < n; i++)
        if (x[i] != 0)
            return i;
    return -1;
}

/* ---- bundles ---- */

/* The bundles' C compiles warning-free with clang too (gcc made them in
 * setup, also with -Werror), and holds the three files of a bundle. */
static void test_bundles(void **s) {
    (void)s;
    const char *names[] = {"tonestack", "piano_mid", "key"};
    const char *nets[] = {"netlists/tonestack.wdn", "netlists/piano_mid.wdn", KEY};
    for (int k = 0; k < 3; k++) {
        assert_int_equal(bundle("clang", nets[k], format("%s/clang", dir), names[k]), 0);
        const char *files[] = {"manifest.ttl", format("%s.ttl", names[k]), format("%s.so", names[k])};
        for (int f = 0; f < 3; f++)
            assert_int_equal(access(format("%s/lv2/%s.lv2/%s", dir, names[k], files[f]), R_OK), 0);
    }
    /* an unbounded param cannot be a control port: a netlist error */
    FILE *f = fopen(format("%s/free.wdn", dir), "w");
    assert_non_null(f);
    fprintf(f, ".voice free\n.input in\n.param r 1k min=1\nV1 a 0 in\nR1 a out {r}\nC1 out 0 1u\n"
               ".output out v(out)\n.end\n");
    fclose(f);
    assert_int_equal(run("bin/wdc %s/free.wdn --lv2 %s/free.lv2 2>%s/free.err", dir, dir, dir), 1);
    char *err = read_file(format("%s/free.err", dir), NULL);
    assert_non_null(strstr(err, "free.wdn:3:8: error: param 'r' needs min= and max="));
    assert_int_equal(run("bin/wdc %s --lv2 %s/x.lv2 -o %s 2>/dev/null", KEY, dir, dir), 2);
}

/* lv2_validate exits 0 and reports nothing about the bundle's files: its
 * only message on stderr may be sord_validate skipping a file of the
 * installed LV2 specification. */
static void test_validate(void **s) {
    (void)s;
    const char *names[] = {"tonestack", "piano_mid", "key"};
    for (int k = 0; k < 3; k++) {
        const char *b = format("%s/lv2/%s.lv2", dir, names[k]);
        assert_int_equal(run("lv2_validate %s/manifest.ttl %s/%s.ttl >%s/val.out 2>%s/val.err", b, b, names[k],
                             dir, dir), 0);
        char *out = read_file(format("%s/val.out", dir), NULL), *err = read_file(format("%s/val.err", dir), NULL);
        assert_non_null(out);
        assert_non_null(err);
        if (!strstr(out, "Found 0 errors"))
            fail_msg("lv2_validate on %s: %s", b, out);
        for (char *l = strtok(err, "\n"); l; l = strtok(NULL, "\n"))
            if (strncmp(l, "Skipping file ", 14) || strstr(l, dir))
                fail_msg("lv2_validate on %s says: %s", b, l);
    }
}

/* ---- the tone stack through lv2apply ---- */

/* lv2apply on noise against wdc --render of the same WAV, with the
 * default controls and with treble and bass moved (events that set the
 * params at frame 0, to the float values the control ports hold). */
static void test_lv2apply(void **s) {
    (void)s;
    enum { N = 24000 };
    static double in[N];
    tl_rng r;
    tl_rng_seed(&r, tl_hash_str("lv2apply"));
    for (long i = 0; i < N; i++)
        in[i] = 0.5 * tl_rng_signed(&r);
    assert_int_equal(wdrt_wav_write(format("%s/in.wav", dir), 1, 48000, in, N), WDRT_OK);
    FILE *f = fopen(format("%s/set.events", dir), "w");
    assert_non_null(f);
    fprintf(f, "0 set treble %.17g\n0 set bass %.17g\n", (double)0.2f, (double)0.9f);
    fclose(f);
    const char *apply = format("LV2_PATH=%s/lv2 lv2apply -i %s/in.wav", dir, dir);
    const char *render = format("bin/wdc netlists/tonestack.wdn -o %s/src --render", dir);
    assert_int_equal(run("%s -o %s/lv.wav urn:wdc:voice:tonestack", apply, dir), 0);
    assert_int_equal(run("%s -o %s/lvc.wav -c treble 0.2 -c bass 0.9 urn:wdc:voice:tonestack", apply, dir), 0);
    assert_int_equal(run("%s %s/ref.wav --input %s/in.wav", render, dir, dir), 0);
    assert_int_equal(run("%s %s/refc.wav --input %s/in.wav --events %s/set.events --seconds 0.5", render, dir, dir,
                         dir), 0);
    long n[4];
    double *lv = wav_channel(format("%s/lv.wav", dir), 0, &n[0]), *lvc = wav_channel(format("%s/lvc.wav", dir), 0, &n[1]);
    double *ref = wav_channel(format("%s/ref.wav", dir), 0, &n[2]), *refc = wav_channel(format("%s/refc.wav", dir), 0, &n[3]);
    assert_true(lv && lvc && ref && refc);
    for (int k = 0; k < 4; k++)
        assert_int_equal(n[k], N);
    double e = max_err(lv, ref, N), ec = max_err(lvc, refc, N), moved = rel_rms_error(lvc, lv, N);
    print_message("tone stack: lv2apply vs wdc --render %.3g, with controls %.3g (of the peak; allowed %.3g); "
                  "the controls move the output by %.3g (relative RMS)\n", e, ec, TOL, moved);
    assert_true(peak(ref, N) > 1e-3);
    assert_true(e <= TOL);
    assert_true(ec <= TOL);
    assert_true(moved > 0.05);
    free(lv);
    free(lvc);
    free(ref);
    free(refc);
}

/* ---- the key through lv2host ---- */

/* The key struck directly through the ABI: a state right after init, the
 * pitch of `note`, the netlist's .ic with velocities scaled by vel/100;
 * nframes of output `out` at fs. */
static double *strike(double fs, int note, int vel, int out, long nframes) {
    const wdv_class *cls = key.cls;
    void *st = tl_state_new(cls, fs);
    double *o = calloc((size_t)nframes + 64, sizeof(double)), *ob[2];
    double *scratch = calloc(64, sizeof(double));
    int ids[8];
    double vals[8];
    assert_true(st && o && key_c->nics <= 8);
    cls->set_param(st, tl_param_id(cls, "f0"), 440 * pow(2, (note - 69) / 12.0));
    const double *def = circuit_defaults(key_c);
    for (int k = 0; k < key_c->nics; k++) {
        const IcSpec *ic = &key_c->ics[k];
        const char *name = format("%c(%s)", ic->fn, key_c->nodes[ic->node]);
        ids[k] = -1;
        for (int t = 0; t < cls->n_ic_targets; t++)
            if (!strcmp(cls->ic_targets[t].name, name))
                ids[k] = t;
        vals[k] = expr_eval(ic->val, def) * (ic->fn == 'v' ? vel / 100.0 : 1);
    }
    assert_int_equal(cls->set_ic(st, key_c->nics, ids, vals), 0);
    for (long i = 0; i < nframes; i += 64) {
        ob[0] = out == 0 ? o + i : scratch;
        ob[1] = out == 1 ? o + i : scratch;
        cls->process(st, NULL, ob, (int)(nframes - i < 64 ? nframes - i : 64));
    }
    free(scratch);
    tl_state_free(st);
    return o;
}

/* Runs lv2host on the key; returns output channel `ch` (nframes long). */
static double *play(double fs, long nframes, const char *events, int ch) {
    const char *wav = format("%s/play.wav", dir);
    int st = run("%s %s/lv2/key.lv2 urn:wdc:voice:key %s --rate %g --frames %ld --blocks 0,1,7,64,100,1000,4096,33 %s",
                 HOST, dir, wav, fs, nframes, events);
    assert_int_equal(st, 0);
    long n;
    double *y = wav_channel(wav, ch, &n);
    assert_non_null(y);
    assert_int_equal(n, nframes);
    return y;
}

/* The first note is the voice struck through the ABI, from its frame on,
 * on both outputs, at 44.1 kHz; nothing before it. */
static void test_first_note(void **s) {
    (void)s;
    const double fs = 44100;
    const long N = 20000, at = 1237;
    for (int ch = 0; ch < 2; ch++) {
        double *y = play(fs, N, "--note 1237:69:80", ch);
        double *ref = strike(fs, 69, 80, ch, N - at), *other = strike(fs, 69, 100, ch, N - at);
        assert_int_equal(first_nonzero(y, N), at + first_nonzero(ref, N - at));
        double e = max_err(y + at, ref, N - at), eo = max_err(y + at, other, N - at);
        print_message("key, output %d: plugin vs ABI %.3g of the peak (allowed %.3g); against velocity 100 "
                      "instead of 80: %.3g; first sound at frame %ld\n", ch, e, TOL, eo, first_nonzero(y, N));
        assert_true(peak(ref, N - at) > 0);
        assert_true(e <= TOL);
        assert_true(eo > 100 * TOL); /* the comparison tells velocities apart */
        free(y);
        free(ref);
        free(other);
    }
}

/* At a rate too low for the key's string at its default pitch, the
 * plugin refuses to be instantiated and says why, instead of playing out
 * of tune; at 2 kHz it plays.  So does a transmission line's plugin at a
 * rate where its delay cannot be held; at 44.1 kHz it plays. */
static void test_rate_too_low(void **s) {
    (void)s;
    const char *wav = format("%s/low.wav", dir), *err = format("%s/low.err", dir);
    assert_int_equal(run("%s %s/lv2/key.lv2 urn:wdc:voice:key %s --rate 1000 --frames 100 2>%s", HOST, dir, wav, err),
                     1);
    char *msg = read_file(err, NULL);
    assert_non_null(msg);
    print_message("%s", msg);
    assert_non_null(strstr(msg, "key: a string, tube or delay line cannot be tuned at 1000 Hz (a loop too short "
                                "for its filters there, a delay shorter than half a sample, or longer than its "
                                "lines hold)"));
    assert_int_equal(run("%s %s/lv2/key.lv2 urn:wdc:voice:key %s --rate 2000 --frames 100 2>%s", HOST, dir, wav, err),
                     0);
    /* a transmission line of 1 ms: shorter than half a sample at 400 Hz,
     * longer than its lines hold (made for 192 kHz) at 384 kHz */
    assert_int_equal(bundle("gcc", "tests/nets/tline.wdn", format("%s/lv2", dir), "tline"), 0);
    for (int k = 0; k < 3; k++) {
        const double fs = k == 0 ? 400 : k == 1 ? 384000 : 44100;
        assert_int_equal(run("%s %s/lv2/tline.lv2 urn:wdc:voice:tline %s --rate %g --frames 100 2>%s", HOST, dir, wav,
                             fs, err),
                         k == 2 ? 0 : 1);
        msg = read_file(err, NULL);
        assert_non_null(msg);
        print_message("tline at %g Hz: %s", fs, *msg ? msg : "plays\n");
        if (k < 2)
            assert_non_null(strstr(msg, format("tline: a string, tube or delay line cannot be tuned at %g Hz", fs)));
    }
}

/* Two overlapping notes of different pitch and velocity sum. */
static void test_two_notes(void **s) {
    (void)s;
    const double fs = 48000;
    const long N = 24000, a = 500, b = 3001;
    double *y = play(fs, N, "--note 500:60:100 --note 3001:67:64", 0);
    double *ra = strike(fs, 60, 100, 0, N - a), *rb = strike(fs, 67, 64, 0, N - b);
    double *sum = calloc((size_t)N, sizeof(double));
    for (long i = a; i < N; i++)
        sum[i] = ra[i - a] + (i >= b ? rb[i - b] : 0);
    double e = max_err(y, sum, N), ea = rel_rms_error(y + b, ra + (b - a), N - b);
    print_message("two notes: plugin vs the sum of both struck through the ABI %.3g of the peak (allowed %.3g); "
                  "the second note is %.3g of the first alone (relative RMS)\n", e, TOL, ea);
    assert_true(e <= TOL);
    assert_true(ea > 0.1);
    free(y);
    free(ra);
    free(rb);
    free(sum);
}

/* A note-off lowers the damper (dmp to its max): the tail falls far below
 * the undamped note's.  With the sustain pedal down the note-off waits,
 * and the damper falls when the pedal comes up. */
static void test_damper(void **s) {
    (void)s;
    const double fs = 48000;
    const long N = 48000, off = 12000, up = 24000, tail = 36000;
    double *ring = play(fs, N, "--note 0:60:100", 0);
    double *damped = play(fs, N, "--note 0:60:100 --off 12000:60", 0);
    double *pedal = play(fs, N, "--note 0:60:100 --cc 6000:64:127 --off 12000:60 --cc 24000:64:0", 0);
    double r = rms(ring + tail, N - tail), rd = rms(damped + tail, N - tail), rp = rms(pedal + tail, N - tail);
    print_message("damper: tail RMS after note-off %.3g dB of the undamped note's, after the pedal's release "
                  "%.3g dB\n", tl_db(rd / r), tl_db(rp / r));
    assert_true(r > 0);
    assert_memory_equal(damped, ring, sizeof(double) * (size_t)off); /* nothing moves before the note-off */
    assert_memory_equal(pedal, ring, sizeof(double) * (size_t)up);   /* nor before the pedal comes up */
    assert_true(rd < 0.1 * r);
    assert_true(rp < 0.1 * r);
    free(ring);
    free(damped);
    free(pedal);
}

/* Notes far apart in pitch with the host's worker, which designs the
 * loops of each note off the run (middle C first, four notes a run): the
 * same render as without one, bit for bit, and the first note is the
 * voice struck through the ABI. */
static void test_worker(void **s) {
    (void)s;
    const double fs = 48000;
    const long N = 24000;
    const char *notes = "--note 500:60:100 --note 3001:67:64 --note 9000:40:90 --note 15000:96:110";
    for (int ch = 0; ch < 2; ch++) {
        double *y = play(fs, N, notes, ch);
        double *yw = play(fs, N, format("%s --worker 1", notes), ch);
        assert_memory_equal(y, yw, sizeof(double) * (size_t)N);
        double *ref = strike(fs, 60, 100, ch, 2501);
        double e = max_err(yw + 500, ref, 2501);
        print_message("worker, output %d: the same render as without one; first note vs ABI %.3g of the peak\n", ch,
                      e);
        assert_true(e <= TOL);
        free(y);
        free(yw);
        free(ref);
    }
}

/* Seventeen notes, none released: the pool holds sixteen, so the last
 * steals the first, which fades out linearly over 5 ms (240 frames at
 * 48 kHz) while the others ring on: the output is the sum of the notes
 * struck through the ABI, the first one faded. */
static void test_steal(void **s) {
    (void)s;
    const double fs = 48000;
    const long N = 17 * 480 + 4800, fade = 240;
    char events[2048] = "";
    for (int k = 0; k < 17; k++)
        snprintf(events + strlen(events), sizeof events - strlen(events), "--note %d:%d:100 ", k * 480, 48 + k);
    double *y = play(fs, N, events, 0);
    double *sum = calloc((size_t)N, sizeof(double)), *plain = calloc((size_t)N, sizeof(double));
    for (int k = 0; k < 17; k++) {
        long at = k * 480;
        double *r = strike(fs, 48 + k, 100, 0, N - at);
        for (long i = at; i < N; i++) {
            long since = i - 16 * 480; /* frames since the steal */
            double g = k > 0 || since < 0 ? 1 : since < fade ? 1 - (double)since / fade : 0;
            sum[i] += g * r[i - at];
            plain[i] += r[i - at];
        }
        free(r);
    }
    double e = max_err(y, sum, N), ep = max_err(y, plain, N);
    print_message("steal: plugin vs the notes through the ABI with the first faded %.3g of the peak (allowed %.3g); "
                  "vs all seventeen sounding %.3g\n", e, TOL, ep);
    assert_true(e <= TOL);
    assert_true(ep > 100 * TOL);
    free(y);
    free(sum);
    free(plain);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_bundles),   cmocka_unit_test(test_validate), cmocka_unit_test(test_lv2apply),
        cmocka_unit_test(test_first_note), cmocka_unit_test(test_two_notes), cmocka_unit_test(test_damper),
        cmocka_unit_test(test_steal),      cmocka_unit_test(test_worker), cmocka_unit_test(test_rate_too_low),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
