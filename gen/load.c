/* load.c: the front of the pipeline for programs that use the compiler as
 * a library (tests, benches): elaboration, then the waveguides' allpass
 * orders, netlist errors unwinding to here.  bin/wdc runs the same phases
 * one by one (main.c). */
#include "gen.h"

static Circuit *choose(Circuit *c) {
    if (!c)
        return NULL;
    jmp_buf jb, *saved = diag.jmp;
    diag.jmp = &jb;
    Circuit *r = NULL;
    if (!setjmp(jb)) {
        wg_choose(c);
        r = c;
    }
    diag.jmp = saved;
    return r;
}

Circuit *wdc_load(const char *path) { return choose(wdc_elaborate(path)); }

Circuit *wdc_load_string(const char *name, const char *text) { return choose(wdc_elaborate_string(name, text)); }
