/*
 * test_render_defects.c - `wdc --render` against inputs that used to crash
 * it or pass silently (issue 14, item 6): lengths past a day, allocations
 * that fail, event times past the render, non-finite or absurd input
 * amplitudes and strikes, events-file diagnostics with the line and a
 * caret, events checked before the C compiler runs, and renders running
 * at once in one folder.
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
#include <sys/stat.h>
#include <unistd.h>

#include "testlib.h"

static char dir[64];
static char root[1024]; /* the repository root, where the tests run */

static int setup(void **s) {
    (void)s;
    if (!getcwd(root, sizeof root))
        return -1;
    return tl_temp_dir(dir, "wdc-rdef");
}

static int teardown(void **s) {
    (void)s;
    tl_remove_dir(dir);
    return 0;
}

/* Runs bin/wdc with args, stderr to DIR/err.txt; returns its exit status. */
static int wdc(const char *args) {
    return tl_system(format("bin/wdc %s 2>%s/err.txt", args, dir));
}

/* What the last wdc() printed on stderr (arena: valid to the end). */
static const char *err_text(void) {
    char *t = read_file(format("%s/err.txt", dir), NULL);
    assert_non_null(t);
    return t;
}

static void assert_err_has(const char *needle) {
    const char *t = err_text();
    if (!strstr(t, needle))
        fail_msg("stderr lacks \"%s\":\n%s", needle, t);
}

/* Lengths past a day are usage errors that name --seconds (1e13 s used
 * to crash on an unchecked calloc, 1e308 s rendered one second). */
static void test_seconds_limit(void **s) {
    (void)s;
    const char *out = format("%s/x.wav", dir);
    assert_int_equal(wdc(format("netlists/msd.wdn --render %s --seconds 1e13 --input impulse", out)), 2);
    assert_err_has("--seconds");
    assert_int_equal(wdc(format("netlists/msd.wdn --render %s --seconds 1e308 --input impulse", out)), 2);
    assert_err_has("--seconds");
    assert_int_equal(wdc(format("netlists/msd.wdn --render %s --seconds 86401 --input impulse", out)), 2);
    assert_err_has("--seconds");
}

/* A render streams: 20000 s of three outputs at 1 kHz (what held them
 * whole took 1.1 GB) renders under a 1 GB address-space limit, each block
 * made and written as it goes.  A day at 48 kHz does not fit in a WAV
 * file (4 GiB): refused before anything is rendered. */
static void test_allocation_failure(void **s) {
    (void)s;
    int st = tl_system(format("ulimit -v 1000000; bin/wdc netlists/msd.wdn --render %s/x.wav --seconds 20000 "
                              "--rate 1000 --input impulse 2>%s/err.txt", dir, dir));
    assert_int_equal(st, 0);
    struct stat sb; /* 3 channels of 32-bit float and a header */
    assert_int_equal(stat(format("%s/x.wav", dir), &sb), 0);
    assert_true(sb.st_size > 20000L * 1000 * 3 * 4 && sb.st_size < 20000L * 1000 * 3 * 4 + 256);
    remove(format("%s/x.wav", dir));
    st = tl_system(format("bin/wdc netlists/msd.wdn --render %s/x.wav --seconds 86400 --input impulse 2>%s/err.txt",
                          dir, dir));
    assert_int_equal(st, 2);
    assert_err_has("86400 s of 3 outputs at 48000 Hz is too long for a WAV file, which holds at most 4 GiB (7456 s)");
}

/* A string too short for its filters at the rate a render asks for is
 * an error at the string, as at the netlist's own rate (at 2 kHz the
 * treble strings of a piano, 2093 Hz, rendered detuned without a word). */
static void test_rate_too_low_for_strings(void **s) {
    (void)s;
    assert_int_equal(wdc(format("netlists/piano_treble.wdn --render %s/x.wav --seconds 0.01 --rate 2000", dir)), 1);
    assert_err_has("piano.wdn:7:9: error: string 'U1.S' is too short for its filters at 2000 Hz: its loop holds "
                   "0.96 samples and needs at least 5 (lower f0, or raise the rate)");
    assert_int_equal(wdc(format("netlists/piano_treble.wdn --render %s/x.wav --seconds 0.01 --rate 44100", dir)), 0);
}

/* A render that fails leaves a file of its name as it was (it writes
 * beside it and renames once whole): the WAV and CSV a good render wrote
 * survive one that overflows, and no temporary is left. */
static void test_failed_render_keeps_files(void **s) {
    (void)s;
    assert_int_equal(wdc(format("netlists/rlc_series.wdn --render %s/keep.wav --csv %s/keep.csv --seconds 0.01", dir,
                                dir)), 0);
    size_t n1;
    char *wav = read_file(format("%s/keep.wav", dir), &n1), *csv = read_file(format("%s/keep.csv", dir), NULL);
    assert_non_null(wav);
    assert_non_null(csv);
    double sig[480];
    for (int i = 0; i < 480; i++)
        sig[i] = i & 1 ? -3e38 : 3e38;
    assert_int_equal(wdrt_wav_write(format("%s/huge2.wav", dir), 1, 48000, sig, 480), WDRT_OK);
    assert_int_equal(wdc(format("netlists/rlc_series.wdn --precision float --render %s/keep.wav --csv %s/keep.csv "
                                "--input %s/huge2.wav", dir, dir, dir)), 3);
    assert_err_has("nothing written");
    assert_string_equal(read_file(format("%s/keep.csv", dir), NULL), csv);
    size_t n2;
    char *wav2 = read_file(format("%s/keep.wav", dir), &n2);
    assert_non_null(wav2);
    assert_int_equal(n2, n1);
    assert_memory_equal(wav2, wav, n1);
    assert_int_equal(tl_system(format("ls %s | grep -q 'keep\\.\\(wav\\|csv\\)\\.'", dir)), 1);
}

/* Event times past the render, or past a day without --seconds, are
 * errors at their line and column. */
static void test_event_times(void **s) {
    (void)s;
    const char *ev = tl_write_file(dir, "late.events", "0.01 set R 1k\n1e15 set R 2k\n");
    assert_int_equal(wdc(format("netlists/rc_lowpass.wdn --render %s/x.wav --events %s", dir, ev)), 1);
    assert_err_has(format("%s:2:1: error:", ev));
    ev = tl_write_file(dir, "past.events", "0.5 set R 1k\n");
    assert_int_equal(wdc(format("netlists/rc_lowpass.wdn --render %s/x.wav --seconds 0.1 --events %s", dir, ev)), 1);
    assert_err_has(format("%s:1:1: error:", ev));
    ev = tl_write_file(dir, "inf.events", "\n  1e999 set R 1k\n");
    assert_int_equal(wdc(format("netlists/rc_lowpass.wdn --render %s/x.wav --events %s", dir, ev)), 1);
    assert_err_has(format("%s:2:3: error:", ev));
    /* the last moment of the render is still in it */
    ev = tl_write_file(dir, "end.events", "0.1 set R 1k\n");
    assert_int_equal(wdc(format("netlists/rc_lowpass.wdn --render %s/x.wav --seconds 0.1 --events %s", dir, ev)), 0);
    /* a value past a param's range is held at the bound by the voice: a warning says so */
    ev = tl_write_file(dir, "range.events", "0.01 set R 1e9\n");
    assert_int_equal(wdc(format("netlists/rc_lowpass.wdn --render %s/x.wav --seconds 0.1 --events %s", dir, ev)), 0);
    assert_err_has(format("%s:1:12: warning: R = 1e+09 lies outside its range [100, 100000]: the voice holds it "
                          "at 100000", ev));
    /* an events file that is a device is refused, and says why */
    assert_int_equal(wdc(format("netlists/rc_lowpass.wdn --render %s/x.wav --events /dev/zero", dir)), 2);
    assert_err_has("cannot read events file '/dev/zero': it is not a regular file");
}

/* Non-finite or absurd input specs are usage errors. */
static void test_input_specs(void **s) {
    (void)s;
    const char *specs[] = {"sine:inf", "sine:nan", "sine:1e308", "impulse:1e308", "step:inf", "noise:-1e300",
                           "sine:440:1e308", "impulse:nan"};
    for (size_t k = 0; k < sizeof specs / sizeof specs[0]; k++) {
        assert_int_equal(wdc(format("netlists/rc_lowpass.wdn --render %s/x.wav --seconds 0.01 --input %s", dir,
                                    specs[k])), 2);
        assert_err_has(specs[k]);
    }
    assert_int_equal(wdc(format("netlists/rc_lowpass.wdn --render %s/x.wav --seconds 0.01 --input sine:440:0.5", dir)),
                     0);
}

/* A strike or a set of an absurd or non-finite value is an error at its
 * column. */
static void test_event_values(void **s) {
    (void)s;
    const char *ev = tl_write_file(dir, "big.events", "0.01 ic v(x)=1e308\n");
    assert_int_equal(wdc(format("netlists/msd.wdn --render %s/x.wav --seconds 0.1 --events %s", dir, ev)), 1);
    assert_err_has(format("%s:1:14: error:", ev));
    ev = tl_write_file(dir, "bigset.events", "0.01 set R 1e999\n");
    assert_int_equal(wdc(format("netlists/rc_lowpass.wdn --render %s/x.wav --seconds 0.1 --events %s", dir, ev)), 1);
    assert_err_has(format("%s:1:12: error:", ev));
}

/* Output that goes non-finite is reported, with status 3: a float voice
 * fed a WAV at the top of float's range overflows. */
static void test_nonfinite_output(void **s) {
    (void)s;
    double sig[480];
    for (int i = 0; i < 480; i++)
        sig[i] = i & 1 ? -3e38 : 3e38;
    assert_int_equal(wdrt_wav_write(format("%s/huge.wav", dir), 1, 48000, sig, 480), WDRT_OK);
    assert_int_equal(wdc(format("netlists/rlc_series.wdn --precision float --render %s/x.wav --input %s/huge.wav",
                                dir, dir)), 3);
    assert_err_has("non-finite");
}

/* Events-file errors print the line and a caret; nine targets on a line
 * are refused for being more than eight. */
static void test_event_diagnostics(void **s) {
    (void)s;
    const char *ev = tl_write_file(dir, "bad.events", "0.1 set R 1k\n0.2 set Q 3\n");
    assert_int_equal(wdc(format("netlists/rc_lowpass.wdn --render %s/x.wav --events %s", dir, ev)), 1);
    assert_string_equal(err_text(), format("%s:2:9: error: unknown param 'Q'\n  0.2 set Q 3\n          ^\n", ev));
    ev = tl_write_file(dir, "nine.events",
                       "0 ic v(x)=0 v(x)=0 v(x)=0 v(x)=0 v(x)=0 v(x)=0 v(x)=0 v(x)=0 v(x)=1\n");
    assert_int_equal(wdc(format("netlists/msd.wdn --render %s/x.wav --events %s", dir, ev)), 1);
    const char *t = err_text();
    assert_non_null(strstr(t, format("%s:1:62: error: ", ev)));
    assert_non_null(strstr(t, "at most 8"));
    assert_non_null(strstr(t, "\n  0 ic v(x)=0"));
    /* a byte-order mark and CRLF, as editors on Windows write, are read; columns count after the mark */
    ev = tl_write_file(dir, "bom.events", "\xef\xbb\xbf" "0.1 set R 1k\r\n0.2 set Q 3\r\n");
    assert_int_equal(wdc(format("netlists/rc_lowpass.wdn --render %s/x.wav --events %s", dir, ev)), 1);
    assert_err_has(format("%s:2:9: error: unknown param 'Q'", ev));
    /* eight are fine */
    ev = tl_write_file(dir, "eight.events", "0 ic v(x)=0 v(x)=0 v(x)=0 v(x)=0 v(x)=0 v(x)=0 v(x)=0 v(x)=1\n");
    assert_int_equal(wdc(format("netlists/msd.wdn --render %s/x.wav --seconds 0.01 --events %s", dir, ev)), 0);
}

/* A strike target, or a netlist's .ic, that sets nothing is an error at
 * its place, with what it would need, before the C compiler runs; the
 * voice lists only the targets it can set. */
static void test_targets_that_set_nothing(void **s) {
    (void)s;
    const char *ev = tl_write_file(dir, "nothing.events", "0.1 ic v(out)=0.5\n0.2 ic  v(out)=1 x(out)=1\n");
    assert_int_equal(tl_system(format("CC=false bin/wdc netlists/rc_lowpass.wdn --render %s/x.wav --events %s "
                                      "2>%s/err.txt", dir, ev, dir)), 1);
    assert_string_equal(err_text(), format("%s:2:18: error: strike target x(out) sets nothing: no inductor (spring) "
                                           "joins 'out' to ground, and no contact or displacement probe is at it\n"
                                           "  0.2 ic  v(out)=1 x(out)=1\n                   ^\n", ev));
    ev = tl_write_file(dir, "source.events", "0.1 ic v(in)=1\n");
    assert_int_equal(wdc(format("netlists/rc_lowpass.wdn --render %s/x.wav --events %s", dir, ev)), 1);
    assert_err_has(format("%s:1:8: error: strike target v(in) sets nothing: no capacitor (mass) joins 'in' to ground",
                          ev));
    /* what sets something renders */
    ev = tl_write_file(dir, "good.events", "0.01 ic v(out)=0.5\n");
    assert_int_equal(wdc(format("netlists/rc_lowpass.wdn --render %s/x.wav --seconds 0.02 --events %s", dir, ev)), 0);
    const char *net = tl_write_file(dir, "icsrc.wdn", ".voice icsrc\n.input u\nV1 a 0 u\nR1 a b 1k\nC1 b 0 1u\n"
                                                      ".ic v(b)=1 v(a)=1\n.output y v(b)\n.end\n");
    assert_int_equal(wdc(format("%s --check", net)), 1);
    assert_err_has(format("%s:6:12: error: initial condition v(a) sets nothing: no capacitor (mass) joins 'a' to "
                          "ground", net));
    /* the voice's targets: v(out) alone */
    tl_voice v;
    assert_int_equal(tl_voice_build("netlists/rc_lowpass.wdn", 0, &v), 0);
    assert_int_equal(v.cls->n_ic_targets, 1);
    assert_string_equal(v.cls->ic_targets[0].name, "v(out)");
    void *st = tl_state_new(v.cls, 48000);
    int ids[2] = {0, 1};
    double vals[2] = {0.25, 1};
    assert_int_equal(v.cls->set_ic(st, 2, ids, vals), -1); /* one id past the list: nothing taken */
    double e0 = v.cls->energy(st);
    assert_true(e0 == 0);
    assert_int_equal(v.cls->set_ic(st, 1, ids, vals), 0);
    assert_true(v.cls->energy(st) > 0);
    tl_state_free(st);
    tl_voice_free(&v);
}

/* A bad events file fails before the C compiler runs: with CC=false the
 * status is the events file's 1, not the toolchain's 3. */
static void test_events_fail_fast(void **s) {
    (void)s;
    const char *ev = tl_write_file(dir, "ff.events", "0.1 set Q 3\n");
    assert_int_equal(tl_system(format("CC=false bin/wdc netlists/rc_lowpass.wdn --render %s/x.wav --events %s "
                                      "2>%s/err.txt", dir, ev, dir)), 1);
    assert_err_has("unknown param 'Q'");
}

/* Eight renders of one netlist at once in one folder all succeed, leave
 * nothing in that folder but their WAVs, and clean up under $TMPDIR. */
static void test_concurrent_renders(void **s) {
    (void)s;
    const char *work = format("%s/conc", dir), *tmp = format("%s/tmp", dir);
    assert_int_equal(tl_system(format("mkdir -p %s %s", work, tmp)), 0);
    assert_int_equal(tl_system(format("cd %s && for i in 1 2 3 4 5 6 7 8; do "
                                      "(TMPDIR=%s %s/bin/wdc %s/netlists/piano.wdn --render r$i.wav --seconds 0.05 "
                                      "2>err$i.txt; echo $? >st$i) & done; wait",
                                      work, tmp, root, root)), 0);
    for (int i = 1; i <= 8; i++) {
        char *st = read_file(format("%s/st%d", work, i), NULL);
        assert_non_null(st);
        if (strcmp(st, "0\n"))
            fail_msg("render %d: status %s%s", i, st, read_file(format("%s/err%d.txt", work, i), NULL));
        int nch;
        double fs, *wav;
        long nf;
        assert_int_equal(wdrt_wav_read(format("%s/r%d.wav", work, i), &nch, &fs, &wav, &nf), WDRT_OK);
        assert_int_equal(nf, 2400);
        free(wav);
    }
    /* no ./out rewritten behind the user's back, no temporaries left */
    assert_int_equal(access(format("%s/out", work), F_OK), -1);
    assert_int_equal(tl_system(format("test -z \"$(ls -A %s)\"", tmp)), 0);
}

/* With -o, --render still leaves the voice's C in DIR, written whole. */
static void test_render_keeps_outdir(void **s) {
    (void)s;
    assert_int_equal(wdc(format("netlists/rc_lowpass.wdn -o %s/src --render %s/x.wav --seconds 0.01 --input step",
                                dir, dir)), 0);
    assert_int_equal(access(format("%s/src/rc_lowpass.c", dir), R_OK), 0);
    assert_int_equal(access(format("%s/src/rc_lowpass.h", dir), R_OK), 0);
    assert_int_equal(access(format("%s/src/wdvoice.h", dir), R_OK), 0);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_seconds_limit),      cmocka_unit_test(test_allocation_failure),
        cmocka_unit_test(test_failed_render_keeps_files), cmocka_unit_test(test_rate_too_low_for_strings),
        cmocka_unit_test(test_event_times),        cmocka_unit_test(test_input_specs),
        cmocka_unit_test(test_event_values),       cmocka_unit_test(test_nonfinite_output),
        cmocka_unit_test(test_event_diagnostics),  cmocka_unit_test(test_events_fail_fast), cmocka_unit_test(test_targets_that_set_nothing),
        cmocka_unit_test(test_concurrent_renders), cmocka_unit_test(test_render_keeps_outdir),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
