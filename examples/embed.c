/*
 * embed.c - a program that embeds a compiled voice the way an application
 * does: the voice's C (made by `bin/wdc scenes/piano_key.wdn`) is compiled
 * into the program and linked with libwdrt; nothing is compiled or loaded
 * at run time.  It makes an engine with a pool of eight piano keys, plays
 * the phrase of score.h into it from the "control" side, renders it the
 * way an audio callback would (512 frames at a time) and writes a WAV.
 *
 *     build/examples/embed [OUT.wav]        (default out/embed.wav)
 */
#include <stdio.h>
#include <stdlib.h>

#include "piano_key.h" /* the generated voice: piano_key_class */
#include "score.h"
#include "wdrt.h"

int main(int argc, char **argv) {
    const char *path = argc > 1 ? argv[1] : "out/embed.wav";
    const wdv_class *c = &piano_key_class;
    wdrt_pool_config pool = wdrt_pool_config_init(c, 8);
    wdrt_engine_config cfg = wdrt_engine_config_init(SCORE_RATE, 1, 1, &pool);
    wdrt_engine *e;
    wdrt_result r = wdrt_engine_init(&cfg, NULL, &e);
    if (r != WDRT_OK) {
        fprintf(stderr, "embed: error: %s\n", wdrt_result_str(r));
        return 1;
    }
    if (post_score(e, c) != 0) {
        fprintf(stderr, "embed: error: the score did not fit the event queue\n");
        return 1;
    }
    long n = (long)(SCORE_SECONDS * SCORE_RATE);
    double *out = malloc(sizeof(double) * (size_t)n);
    if (!out)
        return 1;
    for (long pos = 0; pos < n; pos += 512) /* as an audio callback would */
        wdrt_engine_process(e, out + pos, (uint32_t)(n - pos < 512 ? n - pos : 512));
    wdrt_engine_stats st;
    wdrt_engine_get_stats(e, &st);
    wdrt_engine_uninit(e, NULL);
    r = wdrt_wav_write(path, 1, SCORE_RATE, out, n);
    free(out);
    if (r != WDRT_OK) {
        fprintf(stderr, "embed: error: cannot write %s: %s\n", path, wdrt_result_str(r));
        return 1;
    }
    printf("embed: wrote %s: %d notes, %llu events, %llu voices slept\n", path, SCORE_NOTES,
           (unsigned long long)st.events, (unsigned long long)st.sleeps);
    return 0;
}
