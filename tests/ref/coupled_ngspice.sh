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
need_ngspice coupled_ngspice
OUT=${1:-tests/ref/coupled_tran.csv}
WORK=$(mktemp -d) || exit 1
trap 'rm -rf "$WORK"' EXIT INT TERM
FS=48000
TSTEP=2.0833333333333333e-05

# deck NAME TSTOP "VECTORS" OPTIONS TMAX DATAFILE: the reference deck on
# stdout (the IC= of its elements left out)
deck() {
    awk '
        NR == 1 { print; next }
        tolower($1) ~ /^\.(tran|print|end)$/ { next }
        { for (k = 1; k <= NF; k++) if (toupper($k) !~ /^IC=/) printf "%s%s", (k > 1 ? " " : ""), $k; printf "\n" }' \
        "tests/nets/$1.cir"
    printf '.options %s\n.control\nset numdgt=16\n' "$4"
    printf 'tran %s %s 0 %s\nwrdata %s %s\n.endc\n.end\n' "$TSTEP" "$2" "$5" "$6" "$3"
}

: >"$WORK/all.csv" || exit 1
run() { # NAME TSTOP "VECTORS" "OPTIONS"
    nvec=$(echo "$3" | wc -w)
    nsamp=$(awk -v t="$2" -v fs="$FS" 'BEGIN { u = t; sub(/m$/, "", u); printf "%d", u * fs / 1000 + 0.5 }')
    for TMAX in 10n 5n; do
        deck "$1" "$2" "$3" "$4" "$TMAX" "$WORK/raw_$1_$TMAX.dat" >"$WORK/$1_$TMAX.cir"
        run_deck "$WORK/$1_$TMAX.cir" "$WORK/$1_$TMAX.log" "$WORK/raw_$1_$TMAX.dat"
        sample "$FS" "$nsamp" "$nvec" <"$WORK/raw_$1_$TMAX.dat" >"$WORK/s_$1_$TMAX.txt" || exit 1
    done
    paste -d ' ' "$WORK/s_$1_10n.txt" "$WORK/s_$1_5n.txt" | awk -v name="$1" -v nvec="$nvec" -v vecs="$3" '
        function abs(x) { return x < 0 ? -x : x }
        {
            for (k = 1; k <= nvec; k++) {
                c = $(2 * k); l = $(2 * k + 1); c5 = $(2 * nvec + 1 + 2 * k)
                if (abs(c - l) > dl[k]) dl[k] = abs(c - l)
                if (abs(c - c5) > ds[k]) ds[k] = abs(c - c5)
                if (abs(c) > pk[k]) pk[k] = abs(c)
            }
        }
        END {
            split(vecs, v, " ")
            for (k = 1; k <= nvec; k++)
                printf "coupled_ngspice: %s %s: peak %.6g; max |10 ns run - 5 ns run| %.3g; " \
                       "max |cubic - line| %.3g\n", name, v[k], pk[k], ds[k], dl[k]
        }'
    awk -v name="$1" -v nvec="$nvec" '{
        printf "%s,%s", name, $1
        for (k = 1; k <= nvec; k++) printf ",%s", $(2 * k)
        printf "\n"
    }' "$WORK/s_$1_10n.txt" >>"$WORK/all.csv" || exit 1
}

run xfmr_ct 5m "v(b) v(c) i(l1)" "RELTOL=1e-6 VNTOL=1e-9 ABSTOL=1e-15"
run xfmr_neg 5m "v(b) i(l2)" "RELTOL=1e-6 VNTOL=1e-9 ABSTOL=1e-15"
{
    echo "deck,t,v..."
    cat "$WORK/all.csv"
} >"$OUT" || exit 1
echo "coupled_ngspice: wrote $OUT ($(wc -l <"$WORK/all.csv") rows, ngspice $(ngspice -v 2>/dev/null | sed -n 's/.*ngspice-\([0-9.]*\).*/\1/p' | head -1))"
