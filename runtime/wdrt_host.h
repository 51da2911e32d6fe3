/*
 * wdrt_host.h - loading emitted voices and moving audio in and out of files.
 *
 * Nothing here is real-time safe: these functions compile, load, allocate
 * and do file I/O.  They serve the command line, the tests and the bench.
 */
#ifndef WDRT_HOST_H
#define WDRT_HOST_H

#include <stddef.h>

#include "wdvoice.h"

typedef enum wdrt_result {
    WDRT_OK = 0,
    WDRT_ERROR = -1,         /* generic failure */
    WDRT_INVALID_ARGS = -2,
    WDRT_OUT_OF_MEMORY = -3,
    WDRT_TOOLCHAIN = -4,     /* the C compiler failed */
    WDRT_LOAD = -5,          /* dlopen/dlsym failed */
    WDRT_IO = -6,            /* file could not be read or written */
    WDRT_FORMAT = -7,        /* file is not in a readable format */
} wdrt_result;

const char *wdrt_result_str(wdrt_result r);

/* A voice class loaded from a shared object. */
typedef struct wdrt_voice_lib {
    void *handle;            /* dlopen handle */
    const wdv_class *cls;    /* NAME_class in the object */
} wdrt_voice_lib;

/* Runs the program argv[0] (looked up in PATH unless the name has a
 * slash) with the NULL-terminated argument list argv, and waits for it to
 * end.  With out_fd < 0 the program writes to our stdout and stderr;
 * otherwise both its stdout and its stderr go to the file descriptor
 * out_fd (STDERR_FILENO: everything to our stderr).  *status (if not NULL)
 * gets its exit status, 128 + N if signal N ended it, or 127 if it could
 * not be started (with a message on its stderr).  Returns WDRT_OK once the
 * program has been waited for, whatever its status; WDRT_INVALID_ARGS, or
 * WDRT_ERROR if fork or waitpid failed.  Flushes all stdio streams first.
 * Forks and blocks until the program ends: not real-time safe. */
wdrt_result wdrt_spawn(char *const argv[], int out_fd, int *status);

/* Compiles the C file `csrc` into the shared object `so` with the compiler
 * `cc` (NULL: $CC, or "cc") and extra flags `cflags` (NULL: "-O2").  The
 * compiler's messages go to stderr.  Allocates; not real-time safe. */
wdrt_result wdrt_voice_compile(const char *csrc, const char *so,
                               const char *cc, const char *cflags);

/* Loads `so` and finds the class `NAME_class`. */
wdrt_result wdrt_voice_open(const char *so, const char *name,
                            wdrt_voice_lib *lib);
void wdrt_voice_close(wdrt_voice_lib *lib);

/* Writes nframes of nch interleaved channels as 32-bit float WAV at rate
 * fs (Hz). */
wdrt_result wdrt_wav_write(const char *path, int nch, double fs,
                           const double *frames, long nframes);

/* Reads a WAV (any libsndfile format) as interleaved doubles; *frames is
 * malloc'ed and freed by the caller. */
wdrt_result wdrt_wav_read(const char *path, int *nch, double *fs,
                          double **frames, long *nframes);

/* Renders nframes of a voice instance into out[k] (one buffer per output)
 * from in[k] (one per input; NULL entries read silence), in blocks of at
 * most `block` frames. */
void wdrt_render(const wdv_class *cls, void *state, const double *const *in,
                 double *const *out, long nframes, int block);

#endif
