#!/bin/sh
# hammer_ode.sh - the continuous-time reference for the felt hammer.
#
# Writes tests/ref/hammer_ode.csv for tests/test_hammer.c: the felt force
# between the hammer and the sprung bar of netlists/hammer_bar.wdn, solved
# to near long-double precision by tests/ref/hammer_ode.c (RK4 with 1 ns
# steps and the contact's start and end located exactly; see that file for
# the equations and the file format): the peak force and its time, the
# contact start and end times, and the force at t = n/48000 s for 2 ms.
#
# The script also solves the problem with steps ten times longer (10 ns)
# and prints how far the two runs' figures differ: the size of the
# integration error left in the data.  Keep the constants in
# tests/ref/hammer_ode.c in step with netlists/hammer_bar.wdn.
#
# To regenerate (from the repository root; needs a C compiler, $CC or cc):
#
#     sh tests/ref/hammer_ode.sh
#
# Optional argument: the CSV path to write (default tests/ref/hammer_ode.csv).

set -u

cd "$(dirname "$0")/../.." || exit 1
OUT=${1:-tests/ref/hammer_ode.csv}
CC=${CC:-cc}

WORK=$(mktemp -d) || exit 1
trap 'rm -rf "$WORK"' EXIT INT TERM

$CC -O2 -std=c99 -Wall -Wextra -pedantic -o "$WORK/hammer_ode" \
    tests/ref/hammer_ode.c -lm || {
    echo "hammer_ode: error: cannot compile tests/ref/hammer_ode.c" >&2
    exit 1
}
"$WORK/hammer_ode" 20834 2e-3 >"$WORK/fine.csv" || {
    echo "hammer_ode: error: the solver failed" >&2
    exit 1
}
"$WORK/hammer_ode" 2083 2e-3 >"$WORK/coarse.csv" || {
    echo "hammer_ode: error: the solver failed (10 ns steps)" >&2
    exit 1
}

# The figures and the largest change of the sampled force between the runs.
awk -F, '
    function abs(x) { return x < 0 ? -x : x }
    FNR == 1 { file++ }
    /^#/ || /^t_s/ { next }
    $1 ~ /^[a-z]/ { val[file, $1] = $2; if (file == 1) keys[++nk] = $1; next }
    { f[file, FNR] = $2 + 0; if ($2 + 0 > pk) pk = $2 + 0; rows[FNR] = 1 }
    END {
        for (i = 1; i <= nk; i++)
            printf "hammer_ode: %-20s %.12g   (10 ns steps: %+.3g)\n", keys[i],
                   val[1, keys[i]], val[2, keys[i]] - val[1, keys[i]]
        for (r in rows) if (abs(f[1, r] - f[2, r]) > d) d = abs(f[1, r] - f[2, r])
        printf "hammer_ode: sampled force: largest change with 10 ns steps %.3g N " \
               "(peak %.6g N)\n", d, pk
        if (!(d < 1e-9 * pk)) {
            print "hammer_ode: error: the solution has not converged" > "/dev/stderr"
            exit 1
        }
    }' "$WORK/fine.csv" "$WORK/coarse.csv" || exit 1

cp "$WORK/fine.csv" "$OUT" || exit 1
rows=$(grep -c '^[0-9]' "$OUT")
echo "hammer_ode: wrote $OUT ($rows force samples)"
