#!/bin/sh
# diode_clipper_ngspice.sh - the continuous-time reference for the clipper.
#
# Writes tests/ref/diode_clipper_tran.csv: the transient response v(out) of
# netlists/diode_clipper.wdn computed by ngspice, for tests/test_diode_spice.c.
# The input is an ideal sine source of 440 Hz starting at phase 0,
#
#     v(in) = A sin(2 pi 440 t),   A = 1 V and A = 10 V,
#
# over 10 ms from rest, and v(out) is sampled at exactly t = m/48000 s,
# m = 0..480.  Each row is
#
#     amplitude,t,v_out
#
# with 17 significant digits.
#
# The deck mirrors the netlist element for element: V1 ideal, R1 2.2k,
# C1 10n, and the antiparallel pair (pair=1) as two SPICE diodes of the
# model IS=2.52n N=1.752, one each way.
#
# Thermal voltage.  SPICE's diode computes its own Vt = kT/q from the
# circuit temperature TEMP; the netlist fixes Vt = 25.85 mV.  At
# TEMP = TNOM = 27 C ngspice uses Vt = 25.864917 mV (this script measures
# it and prints it: k = 1.38064852e-23 J/K, q = 1.6021766208e-19 C,
# T = 300.15 K), 0.058 % more than the netlist's.  So the deck runs at
#
#     TEMP = TNOM = 26.826895261366076 C  (T = 299.976895 K),
#
# where kT/q = 25.85 mV with ngspice's constants.  TNOM is set equal to
# TEMP so that ngspice does not rescale IS with temperature; the script
# checks that Vt comes out as 25.85 mV to 1e-9 relative before it runs
# the transient.
#
# What remains different from the netlist's diode i = Is (e^(v/nVt) -
# e^(-v/nVt)):
#   - SPICE's reverse branch: below -3 nVt a SPICE diode's current is
#     -Is (1 + (3 nVt / (e v))^3) instead of Is (e^(v/nVt) - 1).  Both tend
#     to -Is; they differ by under 0.05 Is = 0.13 nA, i.e. below 0.3 uV
#     across R1.
#   - GMIN: ngspice puts GMIN across every junction; it is set to 1e-15 S
#     (2e-15 S for the pair, against 1/R1 = 4.5e-4 S).
#
# Accuracy.  Transient with RELTOL=1e-6, VNTOL=1e-9, ABSTOL=1e-15 and a
# maximum step of 10 ns (the trapezoidal rule, ngspice's default); the
# steps ngspice takes are not on the 48 kHz grid, so v(out) at t = m/48000
# is interpolated from its four nearest time points by a cubic
# (Lagrange) through them.  The script runs each amplitude a second time
# with a 5 ns maximum step and prints the largest difference between the
# two sampled outputs, and the largest difference between the cubic and a
# straight-line interpolation (about the error of the coarser of the two,
# so a bound on the cubic's).  With ngspice 39 they are 2.7e-10 V and
# 3.6e-10 V at 1 V, 1.4e-8 V and 2.9e-8 V at 10 V: far below the errors
# the test measures (1e-5 V and up).
#
# To regenerate (from the repository root; installs ngspice with apt-get
# when it is missing):
#
#     sh tests/ref/diode_clipper_ngspice.sh
#
# Optional argument: the CSV path to write (default
# tests/ref/diode_clipper_tran.csv).  Takes about half a minute.

set -u

cd "$(dirname "$0")/../.." || exit 1
OUT=${1:-tests/ref/diode_clipper_tran.csv}

. tests/ref/ngspice_lib.sh
need_ngspice diode_clipper_ngspice

WORK=$(mktemp -d) || exit 1
trap 'rm -rf "$WORK"' EXIT INT TERM

TEMP_C=26.826895261366076
VT_WANT=0.02585
IS=2.52n
N=1.752
FS=48000
NSAMP=480          # 10 ms at 48 kHz
TSTEP=2.0833333333333333e-05

# ---- the thermal voltage ngspice uses ----
# A diode of N=1 carrying I = IS (e^10 - 1) has v = 10 Vt exactly.
vt_at() {
    iv=$(awk 'BEGIN { printf "%.17g", 2.52e-9 * (exp(10) - 1) }')
    cat >"$WORK/vt.cir" <<EOF
* thermal voltage of the ngspice diode at TEMP = TNOM = $1 C
.options TEMP=$1 TNOM=$1 GMIN=1e-20 RELTOL=1e-12 VNTOL=1e-15 ABSTOL=1e-20
I1 0 a $iv
D1 a 0 dvt
.model dvt D(IS=2.52n N=1)
.control
op
wrdata $WORK/vt.dat v(a)
.endc
.end
EOF
    rm -f "$WORK/vt.dat"
    run_deck "$WORK/vt.cir" "$WORK/vt.log" "$WORK/vt.dat"
    awk 'NF >= 2 { printf "%.12g\n", $2 / 10 }' "$WORK/vt.dat" | tail -1
}
VT27=$(vt_at 27) || exit 1
VT=$(vt_at "$TEMP_C") || exit 1
echo "diode_clipper_ngspice: ngspice Vt = kT/q = $VT27 V at 27 C; $VT V at $TEMP_C C"
awk -v vt="$VT" -v want="$VT_WANT" 'BEGIN {
    d = (vt - want) / want; if (d < 0) d = -d
    if (d > 1e-9) {
        printf "diode_clipper_ngspice: error: Vt = %s, not %s\n", vt, want > "/dev/stderr"
        exit 1
    }
}' || exit 1

# ---- the transient runs ----
# deck AMPLITUDE TMAX DATAFILE
deck() {
    cat <<EOF
* diode clipper, netlists/diode_clipper.wdn, sine 440 Hz at $1 V
.options TEMP=$TEMP_C TNOM=$TEMP_C RELTOL=1e-6 VNTOL=1e-9 ABSTOL=1e-15 GMIN=1e-15
V1 in1 0 SIN(0 $1 440)
R1 in1 out 2.2k
C1 out 0 10n
D1 out 0 d1n4148
D2 0 out d1n4148
.model d1n4148 D(IS=$IS N=$N)
.control
set numdgt=16
tran $TSTEP 10m 0 $2
wrdata $3 v(out)
.endc
.end
EOF
}

: >"$WORK/all.csv" || exit 1
for A in 1 10; do
    for TMAX in 10n 5n; do
        deck "$A" "$TMAX" "$WORK/raw_${A}_$TMAX.dat" >"$WORK/dc_${A}_$TMAX.cir"
        run_deck "$WORK/dc_${A}_$TMAX.cir" "$WORK/dc_${A}_$TMAX.log" "$WORK/raw_${A}_$TMAX.dat"
        sample "$FS" "$NSAMP" 1 <"$WORK/raw_${A}_$TMAX.dat" >"$WORK/s_${A}_$TMAX.txt" || exit 1
    done
    npts=$(wc -l <"$WORK/raw_${A}_10n.dat")
    paste -d ' ' "$WORK/s_${A}_10n.txt" "$WORK/s_${A}_5n.txt" | awk -v A="$A" -v np="$npts" '
        function abs(x) { return x < 0 ? -x : x }
        {
            if (abs($2 - $3) > dl) dl = abs($2 - $3)
            if (abs($2 - $5) > ds) ds = abs($2 - $5)
            if (abs($2) > pk) pk = abs($2)
        }
        END {
            printf "diode_clipper_ngspice: A=%s V: %d time points, peak |v(out)| %.6f V; " \
                   "max |10 ns run - 5 ns run| %.3g V; max |cubic - linear interpolation| %.3g V\n",
                   A, np, pk, ds, dl
        }'
    awk -v A="$A" '{ printf "%s,%s,%s\n", A, $1, $2 }' "$WORK/s_${A}_10n.txt" >>"$WORK/all.csv" || exit 1
done

rows=$(wc -l <"$WORK/all.csv")
[ "$rows" -eq $((2 * (NSAMP + 1))) ] || {
    echo "diode_clipper_ngspice: error: $rows rows came out" >&2
    exit 1
}
{
    echo "amplitude,t,v_out"
    cat "$WORK/all.csv"
} >"$OUT" || exit 1
echo "diode_clipper_ngspice: wrote $OUT ($rows rows, ngspice $(ngspice -v 2>/dev/null | sed -n 's/.*ngspice-\([0-9.]*\).*/\1/p' | head -1))"
