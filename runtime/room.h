/*
 * room.h - rooms of the spatial layer: early reflections by image sources
 * and late reverberation by a feedback delay network.  Internal to libwdrt:
 * not part of the public API.
 *
 * The model.  A room is an axis-aligned box whose six walls reflect alike.
 * Its reverberation time is given at two frequencies, T60 low (at and below
 * 500 Hz) and T60 high (at and above 4 kHz).  Eyring's formula ties T60 to
 * the walls: a sound that has travelled for t seconds has met, on average,
 * c t S / (4 V) walls (4V/S is the mean free path), so with a pressure
 * reflection coefficient beta per wall its energy falls as
 * beta^(2 c t S / (4V)), which is -60 dB at
 *
 *     T60 = 24 ln(10) V / (-c S ln(beta^2)),  i.e.
 *     beta = exp(-12 ln(10) V / (c S T60)).
 *
 * That is Eyring's law (absorption alpha = 1 - beta^2), chosen over
 * Sabine's because it is the decay the image sources themselves produce, so
 * early reflections and the tail agree, and because it gives a reflection
 * coefficient in (0, 1) for every T60, where Sabine's absorption exceeds 1
 * in dead rooms.
 *
 * Early reflections (Allen and Berkley, 1979).  The images of a source in
 * a box are its mirror images in the walls, the mirrors' mirror images,
 * and so on; each is heard as a tap on the source's propagation delay line
 * with its own delay (its distance / c), gain (its `gain` times the
 * distance gain), wall filter (below) and direction.  Up to order K there
 * are sum_{k=1..K} (4k^2 + 2) of them (6, 24, 62, 128, 230, 376).
 *
 * Late reverberation (Jot and Chaigne, 1991).  ROOM_FDN_N = 16 delay lines
 * of mutually prime lengths (distinct primes) spread geometrically over an
 * octave up from a base length: the travel time of one mean free path, so
 * that a pass through a line is about one reflection, but no less than
 * Jot's modal density asks (total length >= 0.15 T60), and 10 to 100 ms.
 * They are coupled by the orthogonal Hadamard matrix H16 / 4 (a
 * fast transform: 64 additions), and each ends in a first-order shelving
 * filter whose gains at 500 Hz and 4 kHz are exactly the decay its length
 * must have for T60 low and T60 high, so every mode near those
 * frequencies decays at the room's T60 there.  The shelf is fitted as
 * room_wall_filter_coefs is, with its crossover moved where needed to
 * keep the T60 at DC and at Nyquist within a factor 2 of the nearer band's
 * (8 in dead rooms whose lines lose many dB per pass); where one pole
 * cannot bend that far (the two bands' losses per pass some 18 dB apart)
 * it falls back to the bands' gains at DC and Nyquist.  Every gain is
 * below 1, so the network decays for any T60.  Fed mono through a
 * pre-delay; two orthogonal sets of output taps give two decorrelated
 * outputs (left, right).
 *
 * Levels.  Everything is in the convention of an inverse-distance law with
 * a reference distance of 1 m: the direct sound of a source r m away is its
 * signal times 1/r, an image's tap is gain/r_image.  In that convention the
 * image sources' energy arriving per sample at time t after emission is
 * 4 pi c / (V fs) 10^(-6 t / T60) on average (1/V images per m^3, each 1/r
 * loud), and the FDN is calibrated to continue it: fed the source's signal
 * as it leaves the source, each of its outputs starts room_mixing_time
 * later, at that level, and decays from there.  It has no tone correction
 * filter: a room's reverberation starts spectrally flat and decays faster
 * where it is absorbed more, and so does this one; its pre-delay instead
 * passes through a shelf that applies the decay of the pre-delay time.
 *
 * Units: positions and sizes in m, times in s, the speed of sound in m/s,
 * rates and frequencies in Hz, gains linear.  No global state.  Functions
 * say whether they may run on the audio thread.
 */
#ifndef WDRT_ROOM_H
#define WDRT_ROOM_H

#include <math.h>
#include <stddef.h>

#if defined(__GNUC__)
#define ROOM_HIDDEN __attribute__((visibility("hidden")))
#else
#define ROOM_HIDDEN
#endif

#define ROOM_MAX_ORDER 6    /* highest image-source order */
#define ROOM_FDN_N 16       /* delay lines of the FDN */
#define ROOM_T60_MIN 0.01   /* s: shortest T60 accepted (stable from here on) */
#define ROOM_T60_MAX 100.0  /* s: longest T60 accepted */
#define ROOM_FS_MIN 8000.0  /* Hz: lowest rate the FDN accepts */
#define ROOM_FS_MAX 768000.0

typedef struct room_config {
    double box[6];   /* x0 y0 z0 x1 y1 z1, m (x0 < x1 ...), finite */
    double t60_low;  /* s, reverberation time at and below 500 Hz */
    double t60_high; /* s, at and above 4 kHz; either may be the longer */
    int order;       /* image-source order, 0..ROOM_MAX_ORDER */
    double c;        /* speed of sound, m/s (> 0) */
    double fs;       /* Hz; used by the FDN only */
} room_config;

typedef struct room_image {
    double pos[3];   /* the image source's position, m */
    int reflections; /* how many walls it reflected from (its order) */
    double gain;     /* product of the walls' pressure reflection coefficients
                        at low frequency (no distance term) */
    double hf;       /* the same at high frequency (>= 4 kHz); a wall filter
                        between the two (room_wall_filter_coefs) */
} room_image;

/* ---- geometry ---- */

/* Whether the room contains point p (m), walls included; 0 for a point
 * with a NaN coordinate.  Real-time safe. */
ROOM_HIDDEN int room_contains(const room_config *cfg, const double p[3]);

/* The box's volume, m^3, and surface, m^2; 0 for a box whose corners are
 * not ordered (x0 < x1 ...) and finite.  Real-time safe. */
ROOM_HIDDEN double room_volume(const room_config *cfg);
ROOM_HIDDEN double room_surface(const room_config *cfg);

/* ---- early reflections ---- */

/* The number of images of order 1..order (the direct path excluded):
 * sum_{k=1..order} (4k^2 + 2); 0 for order <= 0, and the count for
 * ROOM_MAX_ORDER above it.  Real-time safe. */
ROOM_HIDDEN int room_max_images(int order);

/* Writes the images of a source at src (m, inside the room) up to
 * cfg->order into out, in order of increasing reflections, at most max of
 * them (when max is short, the lowest orders are kept).  Allen-Berkley:
 * along each axis of length L, with the source at u from the lower wall,
 * the image after j reflections on that axis lies at u + 2nL or 2nL - u
 * (j = 2|n| or |2n - 1|); an image's order is the sum over the three
 * axes.  Its gain is beta_low^order and hf beta_high^order (Eyring, above).
 * The order of the list does not depend on src: image i is the same wall
 * sequence in every call with the same cfg->order, so a moving source's
 * taps can be matched by index from block to block.
 * Returns the number written, or WDRT_INVALID_ARGS (negative) for a bad
 * cfg (box, order, T60s in [ROOM_T60_MIN, ROOM_T60_MAX], c), a src
 * outside the room or not finite, out NULL with max > 0, or max < 0.
 * fs is not used.  Real-time safe: no allocation, at most 376 images; call
 * it per block for moving sources. */
ROOM_HIDDEN int room_images(const room_config *cfg, const double src[3], room_image *out, int max);

/* The two frequencies the room's gains are specified at, Hz: 500 and
 * 4000, or at rates below 10 kHz 0.4 fs and an eighth of it.  Real-time
 * safe. */
static inline void room_bands(double fs, double *f_low, double *f_high) {
    *f_high = 0.4 * fs < 4000.0 ? 0.4 * fs : 4000.0;
    *f_low = *f_high / 8.0 < 500.0 ? *f_high / 8.0 : 500.0;
}

/* The wall filter of an image (or any gain given at the two bands): the
 * first-order shelf y[n] = b0 x[n] + b1 x[n-1] - a1 y[n-1] whose gain is
 * `gain` at 500 Hz and `hf` at 4 kHz (both >= 0), fitted exactly at those
 * two frequencies.  It is the bilinear transform of
 * H(s) = (G0 K + Gpi s) / (K + s), s in units of the warped frequency
 * tan(w/2), with its crossover K at the geometric mean of the two bands:
 * |H|^2 = (G0^2 K^2 + Gpi^2 W^2) / (K^2 + W^2) is linear in G0^2 and
 * Gpi^2, so the fit is a 2x2 linear solve.  Below 500 Hz the gain moves on
 * towards G0 (its DC gain), above 4 kHz towards Gpi (at Nyquist).  When the
 * fit would need a negative G0^2 or Gpi^2 (gains far apart, beyond what one
 * pole can bend), the shelf is `gain` at DC and `hf` at Nyquist instead.
 * Per image: room_wall_filter_coefs(im.gain, im.hf, fs, ...) once, when
 * the image appears (coefficients change only with the order).  Real-time
 * safe. */
static inline void room_wall_filter_coefs(double gain, double hf, double fs, double *b0, double *b1,
                                          double *a1) {
    const double pi = 3.14159265358979323846;
    double f1, f2;
    room_bands(fs, &f1, &f2);
    double w1 = tan(pi * f1 / fs), w2 = tan(pi * f2 / fs);
    double k = sqrt(w1 * w2), k2 = k * k;
    w1 *= w1;
    w2 *= w2;
    double p = gain * gain, q = hf * hf;
    double y = (q * (k2 + w2) - p * (k2 + w1)) / (w2 - w1);
    double x = (p * (k2 + w1) - y * w1) / k2;
    double g0 = x > 0 && y > 0 ? sqrt(x) : gain, gpi = x > 0 && y > 0 ? sqrt(y) : hf;
    *b0 = (g0 * k + gpi) / (k + 1);
    *b1 = (g0 * k - gpi) / (k + 1);
    *a1 = (k - 1) / (k + 1);
}

/* ---- late reverberation ---- */

typedef struct room_fdn room_fdn; /* opaque */

/* Bytes an FDN for cfg needs (its lines grow with the room and the T60s:
 * 16 lines of at most 0.2 s each, a pre-delay of at most 0.7 s), or 0 for
 * a bad cfg (as room_images, and fs in [ROOM_FS_MIN, ROOM_FS_MAX]).
 * Computes only: real-time safe. */
ROOM_HIDDEN size_t room_fdn_size(const room_config *cfg);

/* Makes an FDN for cfg in mem (room_fdn_size bytes, 16-byte aligned),
 * silent.  Returns it (at mem), or NULL for a bad cfg, a NULL or
 * misaligned mem.  No allocation, but it designs the filters and clears
 * every byte: not for the audio thread. */
ROOM_HIDDEN room_fdn *room_fdn_init(const room_config *cfg, void *mem);

/* Runs n samples (any n >= 0): reads in[0..n), adds the two outputs into
 * out_l and out_r.  in may not alias the outputs.  Real-time safe: no
 * allocation, locks or I/O; O(n ROOM_FDN_N).  Values that decay below
 * 1e-30 are flushed to zero, so a silent FDN never computes with
 * subnormal numbers. */
ROOM_HIDDEN void room_fdn_process(room_fdn *f, const double *in, double *out_l, double *out_r, int n);

/* Silences the FDN: it is then as room_fdn_init left it.  No allocation;
 * clears room_fdn_size bytes, so it costs a block's time in a large room:
 * real-time safe only where that fits the budget. */
ROOM_HIDDEN void room_fdn_clear(room_fdn *f);

/* The delay, s, from the FDN's input to its first output: the room's
 * mixing time, where its tail takes over from the image sources.  It is
 * (order + 1) mean free paths of travel (4V/S/c each; one at order 0),
 * when the average sound has met one more wall than the images model, and
 * at least the shortest line plus one sample.  0 for a bad cfg.  Computes
 * only: real-time safe. */
ROOM_HIDDEN double room_mixing_time(const room_config *cfg);

/* ---- for tests ---- */

/* The lengths of the FDN's lines, samples, into len[ROOM_FDN_N].
 * Real-time safe. */
ROOM_HIDDEN void room_fdn_lengths(const room_fdn *f, int len[ROOM_FDN_N]);
/* Test hook: makes every absorption filter and the pre-delay's shelf the
 * identity, leaving a lossless network (until the next room_fdn_init). */
ROOM_HIDDEN void room_fdn_bypass_filters(room_fdn *f);
/* The energy the FDN stores: the sum of squares of its lines, pre-delay
 * and filter states.  O(size): not for the audio thread. */
ROOM_HIDDEN double room_fdn_energy(const room_fdn *f);

#endif
