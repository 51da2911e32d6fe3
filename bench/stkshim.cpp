// stkshim.cpp - a C interface to STK's Plucked (libstk-dev) for
// bench/stkbench.c, the only C++ in the benches.  Nothing here throws
// into C: a failed construction returns NULL.
#include <cstdlib>
#include <new>

#include <stk/Plucked.h>
#include <stk/Stk.h>

extern "C" {

struct stkp {
    stk::Plucked p;
    explicit stkp(double lowest) : p(lowest) {}
};

// The sample rate of every Plucked made afterwards (STK keeps it globally).
void stkp_set_rate(double fs) { stk::Stk::setSampleRate(fs); }

// A Plucked for frequencies down to `lowest` Hz, its noise seeded with
// `seed` (STK's Noise draws from rand()), or NULL.
struct stkp *stkp_new(double lowest, unsigned seed) {
    try {
        stkp *s = new stkp(lowest);
        std::srand(seed);
        return s;
    } catch (...) {
        return NULL;
    }
}

void stkp_note_on(struct stkp *s, double freq, double amp) { s->p.noteOn(freq, amp); }

void stkp_tick(struct stkp *s, double *buf, int n) {
    for (int i = 0; i < n; i++)
        buf[i] = s->p.tick();
}

void stkp_free(struct stkp *s) { delete s; }

} // extern "C"
