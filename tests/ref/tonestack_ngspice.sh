#!/bin/sh
# tonestack_ngspice.sh - the continuous-time reference for the tone stack.
#
# Writes tests/ref/tonestack_ac.csv: the AC response v(out)/v(in) of
# netlists/tonestack.wdn computed by ngspice, at three pot settings, for
# tests/test_spice.c.  Each row is
#
#     setting_index,treble,bass,mid,freq_hz,re,im
#
# with 17 significant digits.  The frequencies are ngspice's own grid
# (`ac dec 50 10 24k`: 170 points per setting), read back from its output,
# followed by four rows at exactly 1k, 5k, 10k and 15k Hz (one-point `ac lin`
# runs) where the test reports the frequency-warping error.
#
# The deck mirrors the netlist element for element.  A pot
# `pot P a w b R=Rt pos=p [taper=log]` is two resistors
#     R(a,w) = max(Rt*(1-t), Rt*1e-6)    R(w,b) = max(Rt*t, Rt*1e-6)
# with t = p (linear) or t = (10^(2p)-1)/99 (taper=log); a half whose two
# ends are the same node is left out.  The source is an ideal 1 V AC
# source.  Keep this in step with netlists/tonestack.wdn.
#
# To regenerate (from the repository root; installs ngspice with apt-get
# when it is missing):
#
#     sh tests/ref/tonestack_ngspice.sh
#
# Optional argument: the CSV path to write (default tests/ref/tonestack_ac.csv).

set -u

cd "$(dirname "$0")/../.." || exit 1
OUT=${1:-tests/ref/tonestack_ac.csv}

. tests/ref/ngspice_lib.sh
need_ngspice tonestack_ngspice

WORK=$(mktemp -d) || exit 1
trap 'rm -rf "$WORK"' EXIT INT TERM

# Pot settings: treble bass mid.
SETTINGS="0.5 0.5 0.5
0.1 0.9 0.3
1.0 0.0 1.0"

: >"$WORK/all.csv" || exit 1
idx=0
echo "$SETTINGS" | while read -r tr ba mi; do
    deck="$WORK/ts$idx.cir"
    data="$WORK/ts$idx.dat"
    awk -v tr="$tr" -v ba="$ba" -v mi="$mi" -v data="$data" '
    function half(x, rt) { return (x < 1e-6 ? rt * 1e-6 : rt * x) }
    BEGIN {
        tb = (10 ^ (2 * ba) - 1) / 99          # bass: log taper
        print "* tone stack, netlists/tonestack.wdn, treble=" tr " bass=" ba " mid=" mi
        print "V1 vin 0 dc 0 ac 1"
        print "C1 vin t 250p"
        printf "Rtreble_aw t out %.17g\n", half(1 - tr, 250e3)
        printf "Rtreble_wb out b %.17g\n", half(tr, 250e3)
        print "R4 vin c 56k"
        print "C2 c b 20n"
        print "C3 c m 20n"
        # pot Pbass m m b: the a-w half joins m to itself and is left out
        printf "Rbass_wb m b %.17g\n", half(tb, 1e6)
        # pot Pmid 0 0 m: the a-w half joins 0 to itself and is left out
        printf "Rmid_wb 0 m %.17g\n", half(mi, 25e3)
        print ".control"
        print "set numdgt=16"
        print "set wr_singlescale"
        print "ac dec 50 10 24k"
        print "wrdata " data " vr(out) vi(out)"
        print "set appendwrite"
        n = split("1k 5k 10k 15k", fx, " ")
        for (k = 1; k <= n; k++) {
            print "ac lin 1 " fx[k] " " fx[k]
            print "wrdata " data " vr(out) vi(out)"
        }
        print ".endc"
        print ".end"
    }' >"$deck" || exit 1
    # ngspice -b exits with 1 for a deck whose analyses live in .control
    # (it notes that no .print line ran one), so judge by its messages and
    # by the data it wrote.
    ngspice -b "$deck" >"$WORK/ts$idx.log" 2>&1
    if grep -qi 'error' "$WORK/ts$idx.log" || [ ! -s "$data" ]; then
        echo "tonestack_ngspice: error: ngspice failed on setting $idx:" >&2
        cat "$WORK/ts$idx.log" >&2
        exit 1
    fi
    awk -v i="$idx" -v tr="$tr" -v ba="$ba" -v mi="$mi" '
        NF == 3 && $1 + 0 > 0 {
            printf "%d,%s,%s,%s,%s,%s,%s\n", i, tr, ba, mi, $1, $2, $3
        }' "$data" >>"$WORK/all.csv" || exit 1
    idx=$((idx + 1))
done || exit 1

rows=$(wc -l <"$WORK/all.csv")
[ "$rows" -ge 450 ] || {
    echo "tonestack_ngspice: error: only $rows rows came out" >&2
    exit 1
}
{
    echo "setting_index,treble,bass,mid,freq_hz,re,im"
    cat "$WORK/all.csv"
} >"$OUT" || exit 1
echo "tonestack_ngspice: wrote $OUT ($rows rows, ngspice $(ngspice -v 2>/dev/null | sed -n 's/.*ngspice-\([0-9.]*\).*/\1/p' | head -1))"
