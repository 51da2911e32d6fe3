/*
 * test_cli.c - the wdc command line: rendering to WAV and CSV, input specs
 * and files, rate override, events, Graphviz output and exit statuses.
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

static char dir[64];

static int setup(void **s) {
    (void)s;
    return tl_temp_dir(dir, "wdc-cli");
}

static int teardown(void **s) {
    (void)s;
    tl_remove_dir(dir);
    return 0;
}

/* Runs a shell command; returns its exit status. */
static int run(const char *fmt, ...) {
    char cmd[2048];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(cmd, sizeof cmd, fmt, ap);
    va_end(ap);
    int st = system(cmd);
    return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

static double *read_csv(const char *path, int ncol, long *n) {
    FILE *f = fopen(path, "r");
    assert_non_null(f);
    long cap = 1024, k = 0;
    double *d = malloc(sizeof(double) * (size_t)cap);
    while (1) {
        double v;
        int c = fscanf(f, "%lf", &v);
        if (c != 1)
            break;
        if (k == cap) {
            cap *= 2;
            d = realloc(d, sizeof(double) * (size_t)cap);
        }
        d[k++] = v;
        int ch = fgetc(f);
        (void)ch;
    }
    fclose(f);
    *n = k / ncol;
    return d;
}

/* --render with --csv: the WAV (float) and the CSV (17 digits) hold the
 * same frames, one channel per .output, and the step response is the one
 * the trapezoidal rule gives for the RC lowpass. */
static void test_render_csv_wav(void **s) {
    (void)s;
    assert_int_equal(run("bin/wdc netlists/rlc_series.wdn -o %s --render %s/r.wav --input step --seconds 0.01 "
                         "--csv %s/r.csv", dir, dir, dir), 0);
    int nch;
    double fs, *wav;
    long nf, ncsv;
    assert_int_equal(wdrt_wav_read(format("%s/r.wav", dir), &nch, &fs, &wav, &nf), WDRT_OK);
    assert_int_equal(nch, 3);
    assert_true(fs == 48000);
    assert_int_equal(nf, 480);
    double *csv = read_csv(format("%s/r.csv", dir), 3, &ncsv);
    assert_int_equal(ncsv, 480);
    for (long i = 0; i < 3 * nf; i++)
        assert_true(fabs(wav[i] - csv[i]) <= 1e-7 * fabs(csv[i]) + 1e-30);
    free(wav);
    free(csv);

    assert_int_equal(run("bin/wdc netlists/rc_lowpass.wdn -o %s --render %s/a.wav --input step:2 --seconds 0.001 "
                         "--csv %s/a.csv", dir, dir, dir), 0);
    csv = read_csv(format("%s/a.csv", dir), 1, &ncsv);
    assert_int_equal(ncsv, 48);
    double T = 1 / 48000.0, a = T / (2 * 1e3 * 100e-9), p = (1 - a) / (1 + a), y = 0, up = 0;
    for (long i = 0; i < ncsv; i++) {
        y = p * y + a / (1 + a) * (2 + up);
        up = 2;
        assert_true(fabs(csv[i] - y) < 1e-13);
    }
    free(csv);
}

/* A WAV input sets the length; --rate renders at another rate. */
static void test_wav_input_and_rate(void **s) {
    (void)s;
    double sig[1000];
    for (int i = 0; i < 1000; i++)
        sig[i] = sin(0.01 * i);
    assert_int_equal(wdrt_wav_write(format("%s/in.wav", dir), 1, 48000, sig, 1000), WDRT_OK);
    assert_int_equal(run("bin/wdc netlists/rc_lowpass.wdn -o %s --render %s/b.wav --input %s/in.wav", dir, dir, dir), 0);
    int nch;
    double fs, *wav;
    long nf;
    assert_int_equal(wdrt_wav_read(format("%s/b.wav", dir), &nch, &fs, &wav, &nf), WDRT_OK);
    assert_int_equal(nf, 1000);
    free(wav);
    assert_int_equal(run("bin/wdc netlists/msd.wdn -o %s --render %s/c.wav --input impulse --rate 96000 --seconds 0.5",
                         dir, dir), 0);
    assert_int_equal(wdrt_wav_read(format("%s/c.wav", dir), &nch, &fs, &wav, &nf), WDRT_OK);
    assert_true(fs == 96000);
    assert_int_equal(nf, 48000);
    assert_int_equal(nch, 3);
    free(wav);
    /* a file at another rate than the render is a usage error that names
     * the rate to render at */
    assert_int_equal(run("bin/wdc netlists/rc_lowpass.wdn -o %s --render %s/b.wav --input %s/in.wav --rate 44100 "
                         "2>&1 | grep -q -- '(48000 Hz vs 44100 Hz; --rate 48000 renders at the file.s)'",
                         dir, dir, dir), 0);
    /* a file of two channels gives their mean, and says so */
    double st[2000];
    for (int i = 0; i < 1000; i++)
        st[2 * i] = 2 * sig[i], st[2 * i + 1] = 0;
    assert_int_equal(wdrt_wav_write(format("%s/st.wav", dir), 2, 48000, st, 1000), WDRT_OK);
    assert_int_equal(run("bin/wdc netlists/rc_lowpass.wdn -o %s --render %s/d.wav --input %s/st.wav 2>%s/st.err",
                         dir, dir, dir, dir), 0);
    assert_int_equal(run("grep -q \"note: input '%s/st.wav' has 2 channels; the voice's input takes their mean\" "
                         "%s/st.err", dir, dir), 0);
    assert_int_equal(run("cmp -s %s/b.wav %s/d.wav", dir, dir), 0);
    /* an empty file that would set the length is an error, not an empty render */
    assert_int_equal(wdrt_wav_write(format("%s/empty.wav", dir), 1, 48000, sig, 0), WDRT_OK);
    assert_int_equal(run("bin/wdc netlists/rc_lowpass.wdn -o %s --render %s/e.wav --input %s/empty.wav 2>&1 | "
                         "grep -q \"holds no frames, and sets the render's length: give --seconds\"", dir, dir, dir), 0);
    assert_int_equal(run("bin/wdc netlists/rc_lowpass.wdn -o %s --render %s/e.wav --input %s/empty.wav 2>/dev/null",
                         dir, dir, dir), 2);
}

/* The WAV writer writes beside its file and puts it in place on close:
 * until then, and after an abort, a file of that name is as it was, and
 * no temporary is left; a device is written as it is. */
static void test_wav_replaced_whole(void **s) {
    (void)s;
    double a[100], b[200];
    for (int i = 0; i < 200; i++)
        b[i] = i < 100 ? (a[i] = 0.25 * sin(0.1 * i)) : 0.5;
    const char *path = format("%s/whole.wav", dir);
    assert_int_equal(wdrt_wav_write(path, 1, 8000, a, 100), WDRT_OK);
    size_t n0;
    char *before = read_file(path, &n0);
    wdrt_wav_out *w;
    assert_int_equal(wdrt_wav_open(path, 2, 8000, &w), WDRT_OK);
    assert_int_equal(wdrt_wav_append(w, b, 100), WDRT_OK);
    size_t n1;
    assert_memory_equal(read_file(path, &n1), before, n0); /* still the old one while written */
    assert_int_equal(n1, n0);
    assert_int_equal(wdrt_wav_abort(w), WDRT_OK);
    assert_memory_equal(read_file(path, &n1), before, n0);
    assert_int_equal(n1, n0);
    assert_int_equal(run("ls %s | grep -q 'whole\\.wav\\.'", dir), 1);
    assert_int_equal(wdrt_wav_open(path, 2, 8000, &w), WDRT_OK);
    assert_int_equal(wdrt_wav_append(w, b, 100), WDRT_OK);
    assert_int_equal(wdrt_wav_close(w), WDRT_OK);
    int nch;
    double fs, *y;
    long nf;
    assert_int_equal(wdrt_wav_read(path, &nch, &fs, &y, &nf), WDRT_OK);
    assert_int_equal(nch, 2);
    assert_int_equal(nf, 100);
    for (int i = 0; i < 200; i++)
        assert_true(y[i] == (double)(float)b[i]);
    free(y);
    assert_int_equal(run("ls %s | grep -q 'whole\\.wav\\.'", dir), 1);
    assert_int_equal(wdrt_wav_write("/dev/null", 1, 8000, a, 100), WDRT_OK);
    /* a sample past what a 32-bit float holds is refused, not written as infinite */
    double big[2] = {0.5, 1e39};
    assert_int_equal(wdrt_wav_open(path, 1, 8000, &w), WDRT_OK);
    assert_int_equal(wdrt_wav_append(w, big, 2), WDRT_IO);
    assert_int_equal(wdrt_wav_abort(w), WDRT_OK);
    assert_int_equal(wdrt_wav_read(path, &nch, &fs, &y, &nf), WDRT_OK); /* the last whole file */
    assert_int_equal(nch, 2);
    free(y);
}

/* Events: a param set mid-render takes effect at its frame, as it does
 * when the host sets it on the voice directly. */
static void test_events(void **s) {
    (void)s;
    FILE *f = fopen(format("%s/ev.txt", dir), "w");
    fprintf(f, "# time event\n0.005 set R 10k\n0.0025 set R 330\n");
    fclose(f);
    assert_int_equal(run("bin/wdc netlists/rc_lowpass.wdn -o %s --render %s/e.wav --input noise --seconds 0.01 "
                         "--csv %s/e.csv --events %s/ev.txt", dir, dir, dir, dir), 0);
    long n;
    double *csv = read_csv(format("%s/e.csv", dir), 1, &n);
    assert_int_equal(n, 480);
    tl_voice v;
    assert_int_equal(tl_voice_build("netlists/rc_lowpass.wdn", 0, &v), 0);
    void *st = tl_state_new(v.cls, 48000);
    /* the same noise as wdc's noise spec: xorshift32 from 0x9e3779b9 */
    double in[480], out[480];
    uint32_t seed = 0x9e3779b9u;
    for (int i = 0; i < 480; i++) {
        seed ^= seed << 13;
        seed ^= seed >> 17;
        seed ^= seed << 5;
        in[i] = 2.0 * seed / 4294967295.0 - 1;
    }
    const double *ip[1];
    double *op[1];
    long cut[] = {0, 120, 240, 480};
    double val[] = {0, 330, 10e3};
    for (int k = 0; k < 3; k++) {
        if (k)
            v.cls->set_param(st, 0, val[k]);
        ip[0] = in + cut[k];
        op[0] = out + cut[k];
        v.cls->process(st, ip, op, (int)(cut[k + 1] - cut[k]));
    }
    assert_buf_near(csv, out, 480, 1e-15);
    tl_state_free(st);
    tl_voice_free(&v);
    free(csv);
    /* a bad event names its line and column */
    f = fopen(format("%s/bad.txt", dir), "w");
    fprintf(f, "0.1 set R 1k\n0.2 set Q 3\n");
    fclose(f);
    assert_int_equal(run("bin/wdc netlists/rc_lowpass.wdn -o %s --render %s/e.wav --events %s/bad.txt 2>%s/err.txt",
                         dir, dir, dir, dir), 1);
    f = fopen(format("%s/err.txt", dir), "r");
    char line[256] = {0};
    assert_non_null(fgets(line, sizeof line, f));
    fclose(f);
    assert_string_equal(line, format("%s/bad.txt:2:9: error: unknown param 'Q'\n", dir));
    /* a NUL byte is an error at its place: the lines after it were lost */
    f = fopen(format("%s/nul.txt", dir), "w");
    fwrite("0.1 set R 1k\n0.2\0 set Q 3\n", 1, 27, f);
    fclose(f);
    assert_int_equal(run("bin/wdc netlists/rc_lowpass.wdn -o %s --render %s/e.wav --events %s/nul.txt 2>%s/err.txt",
                         dir, dir, dir, dir), 1);
    f = fopen(format("%s/err.txt", dir), "r");
    assert_non_null(fgets(line, sizeof line, f));
    fclose(f);
    assert_string_equal(line, format("%s/nul.txt:2:4: error: the file contains a NUL byte\n", dir));
}

/* A strike event sets a mass's velocity on top of the running state. */
static void test_strike_event(void **s) {
    (void)s;
    FILE *f = fopen(format("%s/strike.txt", dir), "w");
    fprintf(f, "0.01 ic v(x)=0.5\n");
    fclose(f);
    assert_int_equal(run("bin/wdc netlists/msd.wdn -o %s --render %s/s.wav --seconds 0.02 --csv %s/s.csv "
                         "--events %s/strike.txt", dir, dir, dir, dir), 0);
    long n;
    double *csv = read_csv(format("%s/s.csv", dir), 3, &n);
    assert_int_equal(n, 960);
    for (long i = 0; i < 480; i++)
        assert_true(csv[3 * i] == 0);
    /* the first sample after the strike moves from v = 0.5 by one
     * trapezoidal step of the spring-mass-damper */
    assert_true(fabs(csv[3 * 480] - 0.5) < 0.01);
    free(csv);
}

static void test_dot(void **s) {
    (void)s;
    assert_int_equal(run("bin/wdc netlists/tonestack.wdn --dot %s/t.dot", dir), 0);
    char *text = read_file(format("%s/t.dot", dir), NULL);
    assert_non_null(text);
    assert_non_null(strstr(text, "digraph tonestack"));
    assert_non_null(strstr(text, "root"));
    const char *names[] = {"C1", "Ptreble.aw", "Ptreble.wb", "R4", "C2", "C3", "Pbass.wb", "Pmid.wb", "V1"};
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++)
        assert_non_null(strstr(text, names[i]));
}

static void test_exit_status(void **s) {
    (void)s;
    assert_int_equal(run("bin/wdc 2>/dev/null"), 2);
    assert_int_equal(run("bin/wdc netlists/rc_lowpass.wdn --frobnicate 2>/dev/null"), 2);
    assert_int_equal(run("bin/wdc netlists/rc_lowpass.wdn -o %s --render %s/x.wav --input saw 2>/dev/null", dir, dir), 2);
    assert_int_equal(run("bin/wdc netlists/rc_lowpass.wdn --seconds 0 2>/dev/null"), 2);
    assert_int_equal(run("bin/wdc %s/missing.wdn 2>/dev/null", dir), 1);
    FILE *f = fopen(format("%s/bad.wdn", dir), "w");
    fprintf(f, "R1 a 0 1k\nC1 a 0 1u\n.output v v(a)\n");
    fclose(f);
    assert_int_equal(run("bin/wdc %s/bad.wdn -o %s --render %s/x.wav --seconds 0.01", dir, dir, dir), 0);
    f = fopen(format("%s/noout.wdn", dir), "w");
    fprintf(f, "R1 a 0 1k\nC1 a 0 1u\n");
    fclose(f);
    assert_int_equal(run("bin/wdc %s/noout.wdn -o %s --render %s/x.wav 2>/dev/null", dir, dir, dir), 1);
    assert_int_equal(run("CC=false bin/wdc netlists/rc_lowpass.wdn -o %s --render %s/x.wav 2>/dev/null", dir, dir), 3);
    assert_int_equal(run("bin/wdc netlists/tonestack.wdn --check"), 0);
    /* a tolerance so loose a Newton solve would stop where it starts */
    assert_int_equal(run("bin/wdc netlists/diode_clipper.wdn --tol 1 --check 2>/dev/null"), 2);
    assert_int_equal(run("bin/wdc netlists/diode_clipper.wdn --tol 1e-3 --check"), 0);
}

/* A deck written for ngspice with a fine .tran step renders at the rate
 * --rate gives (without it, the step is an error that says so), and its
 * line's delay is checked against that rate and held at it (the line was
 * sized for 192 kHz and cut 30 samples to 3); the render matches one of
 * the same deck whose step gives that rate, to the bit. */
static void test_deck_rate_given(void **s) {
    (void)s;
    FILE *f = fopen(format("%s/fine.cir", dir), "w");
    fprintf(f, "fine step\nV1 in 0 PULSE(0 1 0 1n 1n 20u 40u)\nR1 in a 50\nT1 a 0 b 0 Z0=50 TD=3u\nR2 b 0 50\n"
               ".tran 10n 100u\n.print tran v(b)\n.end\n");
    fclose(f);
    f = fopen(format("%s/coarse.cir", dir), "w");
    fprintf(f, "coarse step\nV1 in 0 PULSE(0 1 0 1n 1n 20u 40u)\nR1 in a 50\nT1 a 0 b 0 Z0=50 TD=3u\nR2 b 0 50\n"
               ".tran 0.1u 100u\n.print tran v(b)\n.end\n");
    fclose(f);
    assert_int_equal(run("bin/wdc %s/fine.cir --check 2>%s/fine.err", dir, dir), 1);
    size_t n;
    char *err = read_file(format("%s/fine.err", dir), &n); /* the compiler's arena: not freed */
    assert_non_null(strstr(err, "fine.cir:6:7: error: .tran's step gives a rate of 1e+08 Hz; it must be from 1 Hz to "
                                "10 MHz (or give the voice's rate with --rate)"));
    assert_int_equal(run("bin/wdc %s/fine.cir --check --rate 1e7", dir), 0);
    assert_int_equal(run("bin/wdc %s/fine.cir --check --rate 1e5 2>%s/fine.err", dir, dir), 1);
    err = read_file(format("%s/fine.err", dir), &n);
    assert_non_null(strstr(err, "fine.cir:4:21: error: TD = 3e-06 s is shorter than half a sample at 100000 Hz"));
    assert_int_equal(run("bin/wdc %s/fine.cir -o %s --render %s/fine.csv --rate 1e7", dir, dir, dir), 0);
    assert_int_equal(run("bin/wdc %s/coarse.cir -o %s --render %s/coarse.csv", dir, dir, dir), 0);
    size_t na, nb;
    char *a = read_file(format("%s/fine.csv", dir), &na), *b = read_file(format("%s/coarse.csv", dir), &nb);
    assert_true(a && b && na > 1000);
    assert_int_equal(na, nb);
    assert_memory_equal(a, b, na);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_deck_rate_given),
        cmocka_unit_test(test_render_csv_wav), cmocka_unit_test(test_wav_input_and_rate),
        cmocka_unit_test(test_wav_replaced_whole),
        cmocka_unit_test(test_events),         cmocka_unit_test(test_strike_event),
        cmocka_unit_test(test_dot),            cmocka_unit_test(test_exit_status),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
