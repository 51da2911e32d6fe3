#!/bin/sh
# joint_ngspice.sh - the continuous-time references of the decks whose
# nonlinear elements are solved jointly.
#
# Writes tests/ref/joint_tran.csv for tests/test_joint_spice.c: ngspice's
# transient of each deck below, sampled at exactly t = m/48000 s from
# t = 0 to TSTOP.  Each row is
#
#     deck,t,v1[,v2...]
#
# with 17 significant digits, the vectors being those listed with the
# deck (the first is the one its .print names).
#
#     netlists/clipper_asym.cir  20 ms  v(out) v(mid)
#     netlists/tubescreamer.cir  20 ms  v(out) v(n)
#     netlists/fuzzface.cir      20 ms  v(out) v(c2)
#     netlists/bigmuff.cir       20 ms  v(out) v(c)
#     netlists/bridge.cir        20 ms  v(o) v(p)
#     netlists/clipper_sym.cir   20 ms  v(out)
#
# (clipper_sym's 1N4148 model gives RS, CJO, M, TT, BV and IBV, which the
# voice notes and ignores; ngspice runs it with IS and N only, the diode
# the voice has.)
#
# Each deck is run as written, its .tran and .print lines replaced by a
# .control block (the rate and length above), from its DC operating point
# (the IC= of its elements left out), as the voice starts.  At ngspice's default
# temperature of 27 C, which is also where wdc reads a deck's diodes
# (kT/q with SPICE's constants); their models give IS and N only, as the
# voice has them.  What differs from the voice's diode
# i = Is (e^(v/nVt) - 1):
#   - SPICE's reverse branch: below -3 nVt a SPICE diode's current is
#     -Is (1 + (3 nVt / (e v))^3) instead; both tend to -Is and differ by
#     under 0.05 Is (0.13 nA for the 1N4148, 0.35 nA for the 1N4007);
#   - GMIN: ngspice puts GMIN across every junction; it is set to 1e-15 S.
#
# Accuracy.  RELTOL=1e-6, VNTOL=1e-9, ABSTOL=1e-15 and a maximum step of
# 10 ns (the trapezoidal rule); the cubic through the four nearest time
# points gives the value at each sample.  Each deck runs a second time with
# a 5 ns maximum step, and the script prints, per vector, the largest
# difference between the two runs and between the cubic and the straight
# line: bounds on the reference's own error, to set against the errors
# the test measures.
#
# To regenerate (from the repository root; installs ngspice with apt-get
# when it is missing):
#
#     sh tests/ref/joint_ngspice.sh [OUT.csv]
#
# Takes about four minutes.

set -u

cd "$(dirname "$0")/../.." || exit 1
. tests/ref/ngspice_lib.sh
OUT=${1:-tests/ref/joint_tran.csv}
tran_begin joint_ngspice
run() { tran_ref "netlists/$1.cir" "$@"; }

run clipper_asym 20m "v(out) v(mid)" "RELTOL=1e-6 VNTOL=1e-9 ABSTOL=1e-15 GMIN=1e-15"
run tubescreamer 20m "v(out) v(n)" "RELTOL=1e-6 VNTOL=1e-9 ABSTOL=1e-15 GMIN=1e-15"
run fuzzface 20m "v(out) v(c2)" "RELTOL=1e-6 VNTOL=1e-9 ABSTOL=1e-15 GMIN=1e-15"
run bigmuff 20m "v(out) v(c)" "RELTOL=1e-6 VNTOL=1e-9 ABSTOL=1e-15 GMIN=1e-15"
run bridge 20m "v(o) v(p)" "RELTOL=1e-6 VNTOL=1e-9 ABSTOL=1e-15 GMIN=1e-15"
sed 's/^\(\.model 1N4148 D(IS=2.52n N=1.752\).*/\1)/' netlists/clipper_sym.cir >"$WORK/clipper_sym.cir" || exit 1
grep -q '^\.model 1N4148 D(IS=2.52n N=1.752)$' "$WORK/clipper_sym.cir" || { echo "joint_ngspice: clipper_sym's model?" >&2; exit 1; }
tran_ref "$WORK/clipper_sym.cir" clipper_sym 20m "v(out)" "RELTOL=1e-6 VNTOL=1e-9 ABSTOL=1e-15 GMIN=1e-15"
tran_end "$OUT"
