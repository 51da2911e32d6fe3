/*
 * hrtf.h - the binaural renderer of the spatial layer (DESIGN §6.5): a
 * mono source heard from a direction, through the head-related impulse
 * responses (HRIRs) of a SOFA file.  Internal to libwdrt: not part of the
 * public API.
 *
 * Loading.  libmysofa reads the file (a SimpleFreeFieldHRIR set),
 * resamples it to the engine's rate and normalises its loudness, as its
 * mysofa_open does.  Every measured HRIR (one per measurement and ear) is
 * then split into a delay and an onset-aligned filter:
 *   - its onset is the first sample that reaches a tenth (-20 dB) of its
 *     peak; the filter keeps it from 0.2 ms before the onset (the rise
 *     and the resampler's pre-ringing) for 5.33 ms (256 taps at 48 kHz,
 *     512 at 96 kHz), the last 1 ms faded out.  The MIT KEMAR responses
 *     run on past that at about -26 dB of their energy (median), mostly
 *     the measurement loudspeaker ringing below 200 Hz; cutting them moves
 *     third-octave levels by 0.8 dB (median);
 *   - its delay is the onset plus the file's own Data.Delay (AES69 gives
 *     it in samples at the file's rate: it is converted), less the delay
 *     common to every response (the loudspeaker's distance: the engine's
 *     propagation delay line stands for distance).  The two ears' delays
 *     differ by the interaural time difference (ITD).
 *
 * Directions.  A grid every 2.5 degrees of azimuth and elevation holds
 * for each of its points the three nearest measurements (among those at
 * the file's largest distance) and modified Shepard weights (Franke and
 * Nielson), which are 1 on a measurement and fall to 0 where a fourth
 * measurement becomes as near, so the blend is continuous across the
 * grid.  A direction takes its nearest grid point: the filter is the
 * weighted sum of the three aligned filters (aligned, they add without
 * the comb filtering that blending delayed responses gives), and each
 * ear's delay the weighted sum of theirs, rounded to a whole sample
 * (20.8 us at 48 kHz, about the smallest ITD change a listener hears).
 * The delays are applied at run time as offsets into the source's
 * history, which costs nothing.
 *
 * Per source: the history of its samples and two filter slots.  When the
 * direction moves to another grid point between blocks, the new filter is
 * built in the other slot (6 * hrtf_length multiply-adds) and the block's
 * output fades linearly from the old filter's output to the new one's:
 * a source that moves every block never clicks.
 *
 * Coordinates: directions are in the listener's frame, x right, y ahead,
 * z up; SOFA's is x ahead, y left, z up, converted here.  Distance is not
 * rendered (the engine's spatial layer applies it).
 *
 * Cost: direct-form FIR, 2 * hrtf_length multiply-adds per sample, twice
 * that in a block where the direction changed.  No global state: an hrtf
 * is read-only once open and is shared by any number of sources on any
 * thread.
 */
#ifndef WDRT_HRTF_H
#define WDRT_HRTF_H

#include <stddef.h>

#if defined(__GNUC__)
#define HRTF_HIDDEN __attribute__((visibility("hidden")))
#else
#define HRTF_HIDDEN
#endif

/* The SOFA file a scene that names none is heard through (Debian's
 * libmysofa-data: the MIT KEMAR dummy head, normal pinna). */
#define HRTF_DEFAULT_SOFA "/usr/share/libmysofa/MIT_KEMAR_normal_pinna.sofa"

/* A loaded HRTF set, shared by all sources; opaque. */
typedef struct hrtf hrtf;

/* Loads the SOFA file `sofa` (NULL: HRTF_DEFAULT_SOFA) for rendering at
 * fs (Hz, 8000 to 768000) and precomputes the filters, delays and
 * direction grid described above.  Returns the set, or NULL with
 * "PATH: error: WHY\n" in err (truncated to errlen; err may be NULL):
 * "cannot read: <strerror>", "not a SOFA file", "sample rate ... out of
 * range", "out of memory", ...  Allocates (a few MB) and reads the file:
 * not real-time safe. */
HRTF_HIDDEN hrtf *hrtf_open(const char *sofa, double fs, char *err, size_t errlen);

/* Frees the set.  NULL is ignored.  No source may use it afterwards.
 * Not real-time safe. */
HRTF_HIDDEN void hrtf_close(hrtf *h);

/* Taps of its filters (256 at 48 kHz).  Real-time safe. */
HRTF_HIDDEN int hrtf_length(const hrtf *h);

/* Per-source state: the source's recent samples and its current filters.
 * Memory is the caller's; the state holds no pointers, so it may be
 * copied. */
typedef struct hrtf_src hrtf_src;

/* Bytes a source of h needs (about 12 KB at 48 kHz).  Real-time safe. */
HRTF_HIDDEN size_t hrtf_src_size(const hrtf *h);

/* Makes a silent source of h in mem (hrtf_src_size(h) bytes, 16-byte
 * aligned).  Returns it (at mem), or NULL if h or mem is NULL.  Does not
 * allocate; real-time safe. */
HRTF_HIDDEN hrtf_src *hrtf_src_init(const hrtf *h, void *mem);

/* Renders n frames of the source's mono signal `in` heard from direction
 * dir (listener frame, x right, y ahead, z up; any length, normalised
 * here; zero or not finite: ahead), ADDING them into out_l and out_r.
 * The direction holds for the whole block; if it falls on another grid
 * point than the previous block's, the output crossfades linearly from
 * the previous filter to the new one over this block (the first block
 * after init or clear starts on the new one).  n may be anything from 0
 * up (the engine's blocks are at most 4096); `in` may be out_l or out_r.
 * h must be the set the source was made for.  Real-time safe: no
 * allocation, locks or I/O; time linear in n. */
HRTF_HIDDEN void hrtf_src_process(const hrtf *h, hrtf_src *s, const double dir[3], const double *in,
                                  double *out_l, double *out_r, int n);

/* Forgets the source's history and direction: silent, as after init.
 * Real-time safe. */
HRTF_HIDDEN void hrtf_src_clear(hrtf_src *s);

#endif
