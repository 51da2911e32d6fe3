# ngspice_lib.sh - what the reference scripts share (sourced, not run).
#
# need_ngspice NAME   installs ngspice with apt-get when it is missing
# run_deck DECK LOG DATA
#                     runs DECK in ngspice's batch mode, its log in LOG;
#                     fails unless the data file DATA came out (ngspice -b
#                     exits with 1 for a deck whose analyses live in
#                     .control, so it is judged by its messages and data)
# sample FS NSAMP NVEC
#                     samples ngspice's wrdata output on stdin (NVEC
#                     vectors: time and value columns for each) at
#                     t = m/FS, m = 0..NSAMP, by the cubic through the four
#                     nearest time points (Lagrange); prints per sample
#                     "t c_1 l_1 ... c_NVEC l_NVEC", c the cubic and l the
#                     straight line between the two nearest points (their
#                     difference is about the coarser one's error, so a
#                     bound on the cubic's)
# tran_begin PROG  sets up the transient references of script PROG: ngspice
#                     installed if missing, WORK (removed at exit), FS
#                     (48 kHz), TSTEP (1/FS) and an empty $WORK/all.csv
# tran_end OUT     writes the header and the rows tran_ref gathered to OUT
# tran_ref DECK NAME TSTOP "VECTORS" "OPTIONS"
#                     runs the deck file DECK as written but for its IC=
#                     values and its .tran, .print and .end lines, from its
#                     DC operating point, with .options OPTIONS and a
#                     .control block: the transient to TSTOP (e.g. 20m) with
#                     a maximum step of 10 ns, then again with 5 ns;
#                     appends to $WORK/all.csv a row "NAME,t,v1,..." per
#                     sample at t = m/$FS (the cubic of the 10 ns run, 17
#                     digits) and prints, per vector, the largest
#                     difference between the runs and between the cubic and
#                     the straight line (bounds on the reference's own
#                     error), after tran_begin.

need_ngspice() {
    command -v ngspice >/dev/null 2>&1 && return 0
    echo "$1: ngspice not found; installing it with apt-get"
    SUDO=""
    [ "$(id -u)" -eq 0 ] || SUDO=sudo
    { $SUDO apt-get update && $SUDO apt-get install -y ngspice; } || {
        echo "$1: error: could not install ngspice" >&2
        exit 1
    }
}

run_deck() {
    ngspice -b "$1" >"$2" 2>&1
    if grep -qi 'error' "$2" || [ ! -s "$3" ]; then
        echo "ngspice failed on $1:" >&2
        cat "$2" >&2
        exit 1
    fi
}

sample() {
    awk -v fs="$1" -v nsamp="$2" -v nvec="$3" '
    NF >= 2 * nvec { n++; t[n] = $1 + 0; for (k = 1; k <= nvec; k++) v[k, n] = $(2 * k) + 0 }
    END {
        if (n < 4) { print "too few points" > "/dev/stderr"; exit 1 }
        i = 1
        for (m = 0; m <= nsamp; m++) {
            tt = m / fs
            while (i < n - 1 && t[i + 1] <= tt) i++
            if (tt < t[1] || tt > t[n] * (1 + 1e-12)) {
                printf "sample %d (t=%.17g) outside the run\n", m, tt > "/dev/stderr"
                exit 1
            }
            j0 = i - 1; if (j0 < 1) j0 = 1; if (j0 > n - 3) j0 = n - 3
            printf "%.17g", tt
            for (k = 1; k <= nvec; k++) {
                c = 0
                for (a = j0; a < j0 + 4; a++) {
                    w = 1
                    for (b = j0; b < j0 + 4; b++)
                        if (b != a) w *= (tt - t[b]) / (t[a] - t[b])
                    c += w * v[k, a]
                }
                l = v[k, i] + (v[k, i + 1] - v[k, i]) * (tt - t[i]) / (t[i + 1] - t[i])
                printf " %.17g %.17g", c, l
            }
            printf "\n"
        }
    }'
}

tran_ref() {
    nvec=$(echo "$4" | wc -w)
    nsamp=$(awk -v t="$3" -v fs="$FS" 'BEGIN { u = t; sub(/m$/, "", u); printf "%d", u * fs / 1000 + 0.5 }')
    for TMAX in 10n 5n; do
        {
            awk '
                NR == 1 { print; next }
                tolower($1) ~ /^\.(tran|print|end)$/ { next }
                { for (k = 1; k <= NF; k++) if (toupper($k) !~ /^IC=/) printf "%s%s", (k > 1 ? " " : ""), $k; printf "\n" }' "$1"
            printf '.options %s\n.control\nset numdgt=16\n' "$5"
            printf 'tran %s %s 0 %s\nwrdata %s %s\n.endc\n.end\n' "$TSTEP" "$3" "$TMAX" "$WORK/raw_$2_$TMAX.dat" "$4"
        } >"$WORK/$2_$TMAX.cir"
        run_deck "$WORK/$2_$TMAX.cir" "$WORK/$2_$TMAX.log" "$WORK/raw_$2_$TMAX.dat"
        sample "$FS" "$nsamp" "$nvec" <"$WORK/raw_$2_$TMAX.dat" >"$WORK/s_$2_$TMAX.txt" || exit 1
    done
    paste -d ' ' "$WORK/s_$2_10n.txt" "$WORK/s_$2_5n.txt" | awk -v name="$2" -v nvec="$nvec" -v vecs="$4" -v prog="$PROG" '
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
                printf "%s: %s %s: peak %.6g; max |10 ns run - 5 ns run| %.3g; " \
                       "max |cubic - line| %.3g\n", prog, name, v[k], pk[k], ds[k], dl[k]
        }'
    awk -v name="$2" -v nvec="$nvec" '{
        printf "%s,%s", name, $1
        for (k = 1; k <= nvec; k++) printf ",%s", $(2 * k)
        printf "\n"
    }' "$WORK/s_$2_10n.txt" >>"$WORK/all.csv" || exit 1
}

tran_begin() {
    PROG=$1
    need_ngspice "$PROG"
    WORK=$(mktemp -d) || exit 1
    trap 'rm -rf "$WORK"' EXIT INT TERM
    FS=48000
    TSTEP=2.0833333333333333e-05
    : >"$WORK/all.csv" || exit 1
}

tran_end() {
    {
        echo "deck,t,v..."
        cat "$WORK/all.csv"
    } >"$1" || exit 1
    echo "$PROG: wrote $1 ($(wc -l <"$WORK/all.csv") rows, ngspice $(ngspice -v 2>/dev/null | sed -n 's/.*ngspice-\([0-9.]*\).*/\1/p' | head -1))"
}
