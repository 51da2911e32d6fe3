/*
 * faustpeer.c - one class Faust generated (faust -lang c) behind the
 * faust_peer interface of peers.h.  Compiled once per class with
 *
 *     -DFAUST_C='"PATH/NAME.c"' -DFAUST_CLASS=NAME
 *
 * (the file made with `faust -lang c -cn NAME`), it defines
 * `const faust_peer faust_NAME`.  Samples cross as double (FAUSTFLOAT),
 * whatever precision the class computes in, as they do for our voices.
 * A class keeps its state in its struct, so where it computes in double
 * its output buffer may alias that state and the compiler reloads the
 * state every sample: the -double RC costs about twice what it does with
 * float samples (and the float one twice as much with float samples).
 */
#define FAUSTFLOAT double
#include <faust/gui/CInterface.h>

#include FAUST_C

#include "peers.h"

#define CAT_(a, b) a##b
#define CAT(a, b) CAT_(a, b)
#define STR_(a) #a
#define STR(a) STR_(a)
#define FN(verb) CAT(verb, FAUST_CLASS)

static void *peer_new(void) { return FN(new)(); }
static void peer_init(void *dsp, int fs) { FN(init)(dsp, fs); }
static void peer_compute(void *dsp, int n, double **in, double **out) { FN(compute)(dsp, n, in, out); }
static void peer_delete(void *dsp) { FN(delete)(dsp); }

const faust_peer CAT(faust_, FAUST_CLASS) = {STR(FAUST_CLASS), peer_new, peer_init, peer_compute,
                                             peer_delete};
