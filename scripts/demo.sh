#!/bin/sh
# demo.sh - compiles every example netlist and renders it to out/.
#
# For each netlists/*.wdn: `bin/wdc FILE -o out` emits out/NAME.c and
# out/NAME.h, then `bin/wdc FILE --render out/NAME.wav --seconds 2` renders
# two seconds, driven by an input that suits the netlist: an impulse for a
# mechanical system (a tap), white noise for a circuit (its filtering is
# what one hears), and no input at all for a netlist without `.input`.
# A netlist may come with timed events, netlists/NAME.WHAT.events (strikes
# and param changes: a scale on the piano, a phrase on the dulcimer); each
# is rendered to out/NAME.WHAT.wav, until three seconds after its last
# event.  Prints one line per render; stops with non-zero status at the
# first failure.
#
# Then renders every scene, scenes/*.wds, with bin/wdrt (among them the
# timbre-tree demos: drum, siren, scrape, engine, mix), renders three
# seconds of each tree of the library the scenes use, scenes/lib/*.tt, to
# out/lib/NAME.wav, draws the schematics of two scenes (out/drum.svg,
# out/mix.svg), and writes LV2 bundles of the tone stack and a piano note
# to out/lv2/.
#
# Usage: sh scripts/demo.sh     (or: make demo, which builds bin/wdc first)

set -u

cd "$(dirname "$0")/.." || exit 1

WDC=bin/wdc
OUT=out
SECONDS_=2

[ -x "$WDC" ] || { echo "demo: $WDC is not built (run make)" >&2; exit 1; }
mkdir -p "$OUT" || exit 1

# The input SPEC for one netlist (empty: the netlist has no input).
input_for() {
    grep -q '^[[:space:]]*\.input[[:space:]]' "$1" || return 0
    case "$(basename "$1" .wdn)" in
    tonestack) echo "sine:220:0.5" ;; # a tone shows the EQ's colouring
    bore) echo "noise:1e-7" ;;          # a breath of 0.1 ml/s: about 1 Pa in the bore
    *)
        if grep -q '^[[:space:]]*\.domain[[:space:]][[:space:]]*mechanical' "$1"
        then echo "impulse"
        else echo "noise:0.5"
        fi ;;
    esac
}

# render NETLIST SPEC ARGS...: bin/wdc NETLIST --render ARGS, driven by
# SPEC when there is one; stops the demo if it fails.
render() {
    f=$1 spec=$2
    shift 2
    "$WDC" "$f" --render "$@" ${spec:+--input "$spec"} || {
        echo "demo: FAILED: $WDC $f --render $*${spec:+ --input $spec}" >&2
        exit 1
    }
}

n=0
for f in netlists/*.wdn; do
    [ -e "$f" ] || { echo "demo: no netlists in netlists/" >&2; exit 1; }
    name=$(basename "$f" .wdn)
    wav="$OUT/$name.wav"
    spec=$(input_for "$f")

    if ! "$WDC" "$f" -o "$OUT"; then
        echo "demo: FAILED: $WDC $f -o $OUT" >&2
        exit 1
    fi
    render "$f" "$spec" "$wav" --seconds "$SECONDS_"
    echo "demo: $f -> $OUT/ (C) and $wav (${SECONDS_} s, input: ${spec:-none})"
    n=$((n + 1))
    for ev in netlists/"$name".*.events; do
        [ -e "$ev" ] || continue
        ewav="$OUT/$(basename "$ev" .events).wav"
        render "$f" "$spec" "$ewav" --events "$ev"
        echo "demo: $f with $ev -> $ewav"
    done
done
echo "demo: $n netlists compiled and rendered"

# Scenes: bin/wdrt renders each scenes/*.wds to out/NAME.wav, compiling the
# netlists it names once (cached under out/cache).
WDRT=bin/wdrt
[ -x "$WDRT" ] || { echo "demo: $WDRT is not built (run make)" >&2; exit 1; }
ns=0
for s in scenes/*.wds; do
    [ -e "$s" ] || continue
    swav="$OUT/$(basename "$s" .wds).wav"
    "$WDRT" render "$s" -o "$swav" || { echo "demo: FAILED: $WDRT render $s" >&2; exit 1; }
    ns=$((ns + 1))
done
echo "demo: $ns scenes rendered"

# The tree library: bin/wdrt tree renders the last tree of each
# scenes/lib/*.tt to out/lib/NAME.wav, with params that show it off where
# its defaults are quiet.
params_for() {
    case "$(basename "$1" .tt)" in
    crowd) echo "--param applause=0.6" ;; # the defaults are a hall's murmur
    esac
}
mkdir -p "$OUT/lib" || exit 1
nt=0
for t in scenes/lib/*.tt; do
    [ -e "$t" ] || continue
    twav="$OUT/lib/$(basename "$t" .tt).wav"
    # shellcheck disable=SC2046 # the params are words
    "$WDRT" tree "$t" -o "$twav" --seconds 3 $(params_for "$t") ||
        { echo "demo: FAILED: $WDRT tree $t $(params_for "$t")" >&2; exit 1; }
    nt=$((nt + 1))
done
echo "demo: $nt trees of scenes/lib rendered to $OUT/lib/"

# Schematics: the sound networks of two scenes drawn by Graphviz
# (installed here when missing: it only draws pictures).
command -v dot >/dev/null 2>&1 || sh scripts/apt-install.sh demo graphviz ||
    echo "demo: no Graphviz: the schematics stay as .dot files" >&2
for s in drum mix; do
    "$WDRT" dot "scenes/$s.wds" -o "$OUT/$s.dot" || { echo "demo: FAILED: $WDRT dot scenes/$s.wds" >&2; exit 1; }
    if command -v dot >/dev/null 2>&1; then
        dot -Tsvg "$OUT/$s.dot" -o "$OUT/$s.svg" || { echo "demo: FAILED: dot -Tsvg $OUT/$s.dot" >&2; exit 1; }
        echo "demo: $OUT/$s.svg, the schematic of scenes/$s.wds"
    fi
done

# Plugins: an effect and an instrument as LV2 bundles, for any LV2 host
# (LV2_PATH=$PWD/out/lv2).
for f in netlists/tonestack.wdn netlists/piano_mid.wdn; do
    b="$OUT/lv2/$(basename "$f" .wdn).lv2"
    "$WDC" "$f" --lv2 "$b" || { echo "demo: FAILED: $WDC $f --lv2 $b" >&2; exit 1; }
    echo "demo: $f -> $b"
done
