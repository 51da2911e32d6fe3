/*
 * test_embed.c - examples/embed, the program that links a generated voice
 * in: it runs, and writes what the engine renders from the same score
 * with the same voice loaded at run time, sample for sample.
 */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "../examples/score.h"
#include "testlib.h"

static void test_embed(void **s) {
    (void)s;
    char dir[] = "/tmp/wdrt-embed.XXXXXX", cmd[256], wav[128];
    assert_non_null(mkdtemp(dir));
    snprintf(wav, sizeof wav, "%s/embed.wav", dir);
    snprintf(cmd, sizeof cmd, "build/examples/embed %s >/dev/null", wav);
    assert_int_equal(system(cmd), 0);
    int nch;
    double fs, *fr;
    long nf;
    assert_int_equal(wdrt_wav_read(wav, &nch, &fs, &fr, &nf), WDRT_OK);
    assert_int_equal(nch, 1);
    assert_true(fs == SCORE_RATE);
    assert_int_equal(nf, (long)(SCORE_SECONDS * SCORE_RATE));

    tl_voice v;
    assert_int_equal(tl_voice_build("scenes/piano_key.wdn", 0, &v), 0);
    wdrt_pool_config pool = wdrt_pool_config_init(v.cls, 8);
    wdrt_engine_config cfg = wdrt_engine_config_init(SCORE_RATE, 1, 1, &pool);
    wdrt_engine *e;
    assert_int_equal(wdrt_engine_init(&cfg, NULL, &e), WDRT_OK);
    assert_int_equal(post_score(e, v.cls), 0);
    double *y = malloc(sizeof(double) * (size_t)nf);
    wdrt_engine_process(e, y, (uint32_t)nf);
    long first = -1, differ = 0;
    for (long i = 0; i < nf; i++) {
        differ += (float)y[i] != (float)fr[i];
        if (first < 0 && fr[i] != 0)
            first = i;
    }
    /* the first note sounds from its frame on (its hammer is in flight
     * for a few samples before it touches the strings) */
    assert_true(first >= (long)(score_notes[0].t * SCORE_RATE + 0.5));
    assert_true(first < (long)(score_notes[0].t * SCORE_RATE + 0.5) + 480);
    assert_int_equal(differ, 0);
    wdrt_engine_uninit(e, NULL);
    tl_voice_free(&v);
    free(y);
    free(fr);
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    assert_int_equal(system(cmd), 0);
}

int main(void) {
    const struct CMUnitTest tests[] = {cmocka_unit_test(test_embed)};
    return cmocka_run_group_tests(tests, NULL, NULL);
}
