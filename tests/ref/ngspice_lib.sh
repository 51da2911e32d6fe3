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
