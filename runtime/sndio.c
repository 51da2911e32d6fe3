/*
 * sndio.c - WAV input and output through libsndfile.
 *
 * Implements the WAV functions of runtime/wdrt.h; the only file that
 * sees sndfile.h.
 */
#include "wdrt.h"
#include "sexp.h"

#include <errno.h>
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include <sndfile.h>

/* Frames per libsndfile call when writing. */
#define WDRT_IO_CHUNK 65536

struct wdrt_wav_out {
    SNDFILE *f;
    char *path;
    char *tmp; /* the file written, beside path, or NULL: path itself */
    int nch;
    unsigned long long bytes; /* of samples written */
};

char *wdrt_temp_beside(const char *path)
{
    struct stat sb;
    int exists = lstat(path, &sb) == 0;
    if (exists && (!S_ISREG(sb.st_mode) || access(path, W_OK) != 0))
        return NULL; /* a device, a FIFO, a link, or a file we may not write, is written (or refused) as it is */
    size_t n = strlen(path) + 40;
    char *t = malloc(n);
    if (!t)
        return NULL;
    /* made as path itself would be (0666 less the umask, which only the
     * kernel applies without a race), under a name no other writer has */
    int fd = -1;
    for (unsigned long k = 0; k < 64 && fd < 0; k++) { /* another name where one is taken */
        unsigned long x = (unsigned long)getpid() * 2654435761ul ^ (unsigned long)time(NULL) ^
                          (unsigned long)(uintptr_t)&fd ^ k * 40503ul;
        snprintf(t, n, "%s.%06lx", path, x & 0xfffffful);
        fd = open(t, O_WRONLY | O_CREAT | O_EXCL, 0666);
        if (fd < 0 && errno != EEXIST)
            break;
    }
    if (fd < 0) {
        free(t);
        return NULL;
    }
    if (exists) /* the mode of the file it replaces */
        (void)fchmod(fd, sb.st_mode & 07777);
    close(fd);
    return t;
}

int wdrt_temp_settle(char *tmp, const char *path, int keep)
{
    int r = 0;
    struct stat sb;
    if (!tmp) { /* written in place: a half-written regular file goes */
        if (!keep && lstat(path, &sb) == 0 && S_ISREG(sb.st_mode))
            remove(path);
        return keep ? 0 : -1;
    }
    if (!keep || rename(tmp, path) != 0) {
        int e = errno;
        remove(tmp);
        errno = e;
        r = -1;
    }
    free(tmp);
    return keep ? r : -1;
}

int wdrt_wav_fits(double nframes, int nch)
{
    return nframes * nch * 4.0 <= (double)WDRT_WAV_MAX_BYTES;
}

double wdrt_wav_max_seconds(int nch, double fs)
{
    return floor((double)WDRT_WAV_MAX_BYTES / (4.0 * nch * fs));
}

wdrt_result wdrt_wav_open(const char *path, int nch, double fs, wdrt_wav_out **out)
{
    if (!path || !out || nch <= 0 || !(fs >= 1.0) || fs > 2147483647.0)
        return WDRT_INVALID_ARGS;
    *out = NULL;
    SF_INFO info = {0};
    info.samplerate = (int)lround(fs);
    info.channels = nch;
    info.format = SF_FORMAT_WAV | SF_FORMAT_FLOAT;
    if (!sf_format_check(&info))
        return WDRT_INVALID_ARGS;
    wdrt_wav_out *w = calloc(1, sizeof *w);
    size_t n = strlen(path) + 1;
    if (!w || !(w->path = malloc(n))) {
        free(w);
        return WDRT_OUT_OF_MEMORY;
    }
    memcpy(w->path, path, n);
    w->nch = nch;
    w->tmp = wdrt_temp_beside(path);
    errno = 0;
    if (!(w->f = sf_open(w->tmp ? w->tmp : path, SFM_WRITE, &info))) {
        /* the system's reason where there is one ("Is a directory"), else libsndfile's */
        fprintf(stderr, "%s: cannot write: %s\n", path, errno ? strerror(errno) : sf_strerror(NULL));
        if (w->tmp) /* in place, nothing was written: a file at path stays */
            wdrt_temp_settle(w->tmp, path, 0);
        free(w->path);
        free(w);
        return WDRT_IO;
    }
    /* Samples are written as they are: no clipping or normalisation. */
    sf_command(w->f, SFC_SET_CLIPPING, NULL, SF_FALSE);
    sf_command(w->f, SFC_SET_NORM_DOUBLE, NULL, SF_FALSE);
    /* No PEAK chunk: it carries the time of writing, and the same render
     * should give the same file, byte for byte. */
    sf_command(w->f, SFC_SET_ADD_PEAK_CHUNK, NULL, SF_FALSE);
    *out = w;
    return WDRT_OK;
}

wdrt_result wdrt_wav_append(wdrt_wav_out *w, const double *frames, long nframes)
{
    if (!w || nframes < 0 || (nframes > 0 && !frames))
        return WDRT_INVALID_ARGS;
    unsigned long long more = (unsigned long long)nframes * (unsigned long long)w->nch * 4;
    if (w->bytes + more > WDRT_WAV_MAX_BYTES) { /* past it, the header's sizes would wrap */
        fprintf(stderr, "wdrt: %s: a WAV file holds at most 4 GiB of samples\n", w->path);
        return WDRT_IO;
    }
    /* a 32-bit float holds magnitudes up to FLT_MAX: past it a finite
     * sample would be written as infinite */
    for (size_t i = 0; i < (size_t)nframes * (size_t)w->nch; i++)
        if (isfinite(frames[i]) && fabs(frames[i]) > FLT_MAX) {
            fprintf(stderr, "wdrt: %s: a sample is %g, which a 32-bit float WAV file cannot hold (at most %g)\n",
                    w->path, frames[i], (double)FLT_MAX);
            return WDRT_IO;
        }
    w->bytes += more;
    for (long done = 0; done < nframes;) {
        long n = nframes - done < WDRT_IO_CHUNK ? nframes - done : WDRT_IO_CHUNK;
        if (sf_writef_double(w->f, frames + (size_t)done * (size_t)w->nch, n) != n) {
            fprintf(stderr, "wdrt: %s: %s\n", w->path, sf_strerror(w->f));
            return WDRT_IO;
        }
        done += n;
    }
    return WDRT_OK;
}

/* Closes w's file and puts it in place (keep), or removes it. */
static wdrt_result wav_end(wdrt_wav_out *w, int keep)
{
    if (!w)
        return WDRT_INVALID_ARGS;
    wdrt_result res = WDRT_OK;
    if (sf_close(w->f) != 0) {
        fprintf(stderr, "wdrt: %s: %s\n", w->path, sf_strerror(NULL));
        res = WDRT_IO;
        keep = 0;
    }
    if (wdrt_temp_settle(w->tmp, w->path, keep) != 0 && keep) {
        fprintf(stderr, "wdrt: %s: %s\n", w->path, strerror(errno));
        res = WDRT_IO;
    }
    free(w->path);
    free(w);
    return res;
}

wdrt_result wdrt_wav_close(wdrt_wav_out *w) { return wav_end(w, 1); }

wdrt_result wdrt_wav_abort(wdrt_wav_out *w) { return w ? (wav_end(w, 0), WDRT_OK) : WDRT_INVALID_ARGS; }

wdrt_result wdrt_wav_write(const char *path, int nch, double fs,
                           const double *frames, long nframes)
{
    if (nframes < 0 || (nframes > 0 && !frames))
        return WDRT_INVALID_ARGS;
    wdrt_wav_out *w;
    wdrt_result res = wdrt_wav_open(path, nch, fs, &w);
    if (res != WDRT_OK)
        return res;
    res = wdrt_wav_append(w, frames, nframes);
    wdrt_result c = wdrt_wav_close(w);
    return res != WDRT_OK ? res : c;
}

wdrt_result wdrt_wav_read(const char *path, int *nch, double *fs,
                          double **frames, long *nframes)
{
    if (!path || !nch || !fs || !frames || !nframes)
        return WDRT_INVALID_ARGS;
    *frames = NULL;
    *nframes = 0;
    *nch = 0;
    *fs = 0;

    int e = sx_file_ok(path); /* a device or a FIFO would never end, or block */
    if (e) {
        fprintf(stderr, "%s: %s\n", path, sx_file_strerror(e));
        return WDRT_IO;
    }

    SF_INFO info = {0};
    SNDFILE *f = sf_open(path, SFM_READ, &info);
    if (!f) {
        fprintf(stderr, "wdrt: %s: %s\n", path, sf_strerror(NULL));
        return WDRT_FORMAT;
    }
    if (info.channels <= 0 || info.frames < 0) {
        sf_close(f);
        fprintf(stderr, "wdrt: %s: holds no channel\n", path);
        return WDRT_FORMAT;
    }
    /* Integer formats read as [-1, 1); float files keep their values. */
    sf_command(f, SFC_SET_NORM_DOUBLE, NULL, SF_TRUE);

    size_t total = (size_t)info.frames * (size_t)info.channels;
    double *buf = malloc(total > 0 ? total * sizeof *buf : sizeof *buf);
    if (!buf) {
        sf_close(f);
        return WDRT_OUT_OF_MEMORY;
    }
    sf_count_t got = 0;
    while (got < info.frames) {
        sf_count_t r = sf_readf_double(f, buf + (size_t)got * info.channels,
                                       info.frames - got);
        if (r <= 0)
            break;
        got += r;
    }
    sf_close(f);
    if (got < info.frames) {
        free(buf);
        fprintf(stderr, "wdrt: %s: file ends early\n", path);
        return WDRT_IO;
    }
    /* a float file can hold NaN or infinities, which no sound made of it survives */
    for (size_t i = 0; i < total; i++)
        if (!isfinite(buf[i])) {
            fprintf(stderr, "wdrt: %s: the sample at frame %zu, channel %zu, is %s\n", path,
                    i / (size_t)info.channels, i % (size_t)info.channels + 1,
                    isnan(buf[i]) ? "not a number" : "infinite");
            free(buf);
            return WDRT_FORMAT;
        }
    *frames = buf;
    *nframes = (long)got;
    *nch = info.channels;
    *fs = (double)info.samplerate;
    return WDRT_OK;
}
