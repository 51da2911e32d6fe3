#!/bin/sh
# coupled_ngspice.sh - the continuous-time references of the decks with
# coupled inductors (K).
#
# Writes tests/ref/coupled_tran.csv for tests/test_coupled.c: ngspice's
# transient of each deck below, sampled at exactly t = m/48000 s from
# t = 0 to TSTOP.  Each row is
#
#     deck,t,v1[,v2...]
#
# with 17 significant digits, the vectors being those listed with the
# deck.
#
#     tests/nets/xfmr_ct.cir   5 ms  v(b) v(c) i(l1)   (three windings)
#     tests/nets/xfmr_neg.cir  5 ms  v(b) i(l2)        (k < 0)
#
# Each deck is run as written, its .tran and .print lines replaced by a
# .control block (the rate and length above), from its DC operating point.
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
#     sh tests/ref/coupled_ngspice.sh [OUT.csv]
#
# Takes about a minute.

set -u

cd "$(dirname "$0")/../.." || exit 1
. tests/ref/ngspice_lib.sh
OUT=${1:-tests/ref/coupled_tran.csv}
tran_begin coupled_ngspice
run() { tran_ref "tests/nets/$1.cir" "$@"; }

run xfmr_ct 5m "v(b) v(c) i(l1)" "RELTOL=1e-6 VNTOL=1e-9 ABSTOL=1e-15"
run xfmr_neg 5m "v(b) i(l2)" "RELTOL=1e-6 VNTOL=1e-9 ABSTOL=1e-15"
tran_end "$OUT"
