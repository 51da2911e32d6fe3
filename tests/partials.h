/*
 * partials.h - tuning and decay of the partials of a rendered sound.
 *
 * pt_peak_freq finds the frequency of one partial far below the bin
 * spacing of a spectrum, pt_t60 the time it takes to decay by 60 dB, and
 * pt_cents compares frequencies in cents.  The tests of strings and tubes
 * measure their renders with these; tests/test_partials.c checks them on
 * synthetic signals whose answers are known.  Both measures look at the
 * signal from sample 0 on (a note starting at 0, as a render does) and
 * take O(n log n) time.  No global state: safe to call from threads.
 */
#ifndef PARTIALS_H
#define PARTIALS_H

#include <stddef.h>

/* Frequency (Hz) of the strongest spectral peak of x[0..n) (sampled at fs)
 * between f_lo and f_hi, refined far below the bin spacing.
 *
 * The analysis window (Kaiser, beta PT_BETA, over x[0..L)) is chosen among
 * L = n, n/2, n/4, ...: the longest whose peak in the band, against the
 * white noise the window lets through, is within 3 dB of the best one's,
 * so that a partial that dies out early in a long signal is not drowned
 * in what follows, while one that lasts gets the whole signal.  L does not
 * go below 8 periods of the band's centre nor below PT_LOBE / (2 hw)
 * seconds (hw the band's half-width; shorter windows would spread
 * components outside the band well into it), and windows where the peak
 * does not stand 6 dB above both ends of the band (a neighbour leaking
 * in) are passed over while another will do.  The strongest local maximum
 * of the spectrum (zero-padded to a power of two) in the band is then
 * refined by Newton's method on |DTFT|^2 of the windowed signal at
 * continuous frequency.  For one decaying complex exponential the maximum
 * is exactly at its frequency (window times decay is a real weight); what
 * is left is leakage from the other components, kept tiny by the window's
 * sidelobes (-122 dB).
 *
 * Accurate to better than 0.05 cent for a decaying sinusoid (t60 down to
 * ~0.3 s) of at least ~40 periods that lies among other partials at least
 * ~3 % away in frequency and up to 40 dB stronger, with white noise 80 dB
 * below it, provided the neighbours can be told apart at all: they lie
 * outside the band, at least ~12 / t60 Hz away (t60 the shorter of theirs
 * and the partial's; the half-power width of a partial is 2.2 / t60 Hz),
 * and the band is about centred on the partial with a half-width of at
 * least ~3 / t60 Hz.  Closer neighbours 40 dB stronger can pull it by
 * ~0.003 / t60 Hz (10 / t60 Hz away) to ~0.03 / t60 Hz (6 / t60 Hz
 * away).  With noise only 40 dB below the partial, expect errors of a few
 * hundredths of a cent, up to ~0.1, for t60 = 0.3 s.
 *
 * Local maxima more than PT_FLOOR_DB below the strongest bin of the whole
 * spectrum are not peaks (sidelobes, rounding).  Returns NAN if there is no
 * peak in the band, or if the arguments make no band (f_lo >= f_hi, the
 * band outside [0, fs/2], fewer than 16 samples). */
double pt_peak_freq(const double *x, size_t n, double fs, double f_lo, double f_hi);

/* Decay time (s) to fall 60 dB of the partial near f (Hz) in x[0..n):
 * the band around f (half-width bw Hz, which isolates the partial from its
 * neighbours) is tracked over time and a straight line is fitted to its
 * level in dB between the moments it is `skip_db` and `skip_db + span_db`
 * below its peak (e.g. 3 and 30 dB).
 *
 * The band is x demodulated by exp(-j 2 pi f t) and low-passed by a Kaiser
 * kernel (beta PT_BETA, sum 1) whose first spectral null is at bw:
 * components bw or more away from f are rejected by its sidelobes (-122
 * dB).  Levels are taken only where the kernel lies wholly inside the
 * signal, and as the kernel is symmetric an exponential decay keeps its
 * exact rate through it, whatever f's error.  The kernel lasts
 * PT_LOBE / bw seconds and the decay during its first half is not seen:
 * bw must be wide enough that the partial is still well above the noise
 * by then (a partial with t60 = 0.05 s needs bw of ~100 Hz or more).
 *
 * Accurate to 2 % for exponentially decaying partials with t60 from 0.05 s
 * to 30 s given at least a few hundred periods of signal (if the signal is
 * shorter than span_db of decay, fit what there is as long as it covers at
 * least 10 dB; otherwise return NAN).  A level that stops at a noise floor
 * before span_db is not recognised: the fit then takes in the floor.  Also
 * NAN for arguments that make no band (f or bw not positive, span_db not
 * positive, a kernel longer than the signal) and for a level that never
 * falls skip_db. */
double pt_t60(const double *x, size_t n, double fs, double f, double bw, double skip_db,
              double span_db);

/* Cents between f and ref: 1200 log2(f / ref). */
double pt_cents(double f, double ref);

/* Shape of the Kaiser windows and kernels above. */
#define PT_BETA 16.0
/* The first null of the spectrum of a Kaiser window of PT_BETA lasting T
 * seconds lies PT_LOBE / T Hz from its centre: sqrt(1 + (PT_BETA/pi)^2). */
#define PT_LOBE 5.1902
/* pt_peak_freq ignores local maxima this far below the strongest bin. */
#define PT_FLOOR_DB 100.0

#endif
