#!/bin/sh
# demo.sh - compiles every example netlist and renders it to out/.
#
# For each netlists/*.wdn (and each SPICE deck, netlists/*.cir, driven by
# its own sources): `bin/wdc FILE -o out` emits out/NAME.c and
# out/NAME.h, then `bin/wdc FILE --render out/NAME.wav --seconds 2` renders
# two seconds, driven by an input that suits the netlist: a tap (an
# impulse) for a mechanical system, white noise for a circuit (its
# filtering is what one hears), and no input at all for a netlist without
# `.input`.  A netlist whose own strike (.ic) is too hard for full scale is
# struck more gently at time 0 (out/events/NAME.strike.events), and one
# with timed events, netlists/NAME.WHAT.events (strikes and param changes:
# a chord and a scale on the piano, a phrase on the dulcimer), plays its
# first in out/NAME.wav; each events file is also rendered to
# out/NAME.WHAT.wav, until three seconds after its last event.  Every
# render should peak between -40 and 0 dBFS over its outputs: a warning
# line says when one does not.  Prints one line per render; stops with
# non-zero status at the first failure.
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

# wdc has no gain option, so each render is made playable, peaking between
# -40 and 0 dBFS over all its outputs, by what drives it: the input's
# amplitude, a gentler strike at time 0 than the netlist's .ic (hammer and
# mallet forces are written in newtons), or, for the netlists whose sound
# is their events (piano, dulcimer), their first events file.

# The input SPEC for one netlist (empty: the netlist has no input).
input_for() {
    grep -q '^[[:space:]]*\.input[[:space:]]' "$1" || return 0
    case "$(basename "$1" .wdn)" in
    tonestack) echo "sine:220:0.5" ;;   # a tone shows the EQ's colouring
    bore) echo "noise:1e-7" ;;          # a breath of 0.1 ml/s: about 1 Pa in the bore
    chain2) echo "impulse:50" ;;        # light masses on stiff springs: a hard tap
    chain3 | msd) echo "impulse:10" ;;
    guitar) echo "impulse:0.1" ;;       # a pluck, not a blow
    pluck) echo "impulse:0.2" ;;
    stiffening_spring) echo "impulse:0.05" ;;
    *)
        if grep -q '^[[:space:]]*\.domain[[:space:]][[:space:]]*mechanical' "$1"
        then echo "impulse"
        else echo "noise:0.5"
        fi ;;
    esac
}

# A strike at time 0 that replaces the netlist's .ic, for those whose own
# drives the contact force past full scale (empty: keep the .ic).
strike_for() {
    case "$(basename "$1" .wdn)" in
    hammer_bar) echo "0 ic v(h)=0.08 x(h)=-1m" ;;
    mallet_plate) echo "0 ic v(m)=0.01 x(m)=-0.5m" ;;
    piano_bass) echo "0 ic v(h1)=0.15 x(h1)=-1m v(h2)=0.15 x(h2)=-1m" ;;
    piano_mid) echo "0 ic v(h1)=0.25 x(h1)=-1m v(h2)=0.25 x(h2)=-1m v(h3)=0.25 x(h3)=-1m" ;;
    piano_treble) echo "0 ic v(h1)=0.25 x(h1)=-0.5m v(h2)=0.25 x(h2)=-0.5m v(h3)=0.25 x(h3)=-0.5m" ;;
    stiffening_spring) echo "0 ic v(m)=0.1" ;;
    esac
}

# The factor the strike speeds of a netlist's events files are scaled by
# (their hammers' forces, in newtons, are outputs too).
strike_scale() {
    case "$(basename "$1" .wdn)" in
    dulcimer) echo 0.1 ;;
    *) echo 1 ;;
    esac
}

# events_for NETLIST EVENTS: EVENTS with its strike speeds scaled for the
# demo, as a file under $OUT/events/ (EVENTS itself when unscaled).
events_for() {
    k=$(strike_scale "$1")
    [ "$k" = 1 ] && { echo "$2"; return; }
    mkdir -p "$OUT/events" || exit 1
    e="$OUT/events/$(basename "$2")"
    awk -v k="$k" '$2 == "ic" { for (i = 3; i <= NF; i++) if ($i ~ /^v\(.*\)=/) {
            split($i, kv, "="); $i = kv[1] "=" kv[2] * k } } { print }' "$2" >"$e" || exit 1
    echo "$e"
}

# render NETLIST SPEC ARGS...: bin/wdc NETLIST --render ARGS, driven by
# SPEC when there is one; stops the demo if it fails, and warns when the
# render's peak (over all its outputs) is not between -40 and 0 dBFS.
render() {
    f=$1 spec=$2
    shift 2
    csv="$OUT/.demo-peak.$$.csv"
    "$WDC" "$f" --render "$@" ${spec:+--input "$spec"} --csv "$csv" || {
        rm -f "$csv"
        echo "demo: FAILED: $WDC $f --render $*${spec:+ --input $spec}" >&2
        exit 1
    }
    peak=$(awk -F, '{ for (i = 1; i <= NF; i++) { v = $i < 0 ? -$i : $i; if (v > m) m = v } }
        END { if (m > 0) printf "%.1f", 20 * log(m) / log(10); else print "-inf" }' "$csv")
    rm -f "$csv"
    case "$peak" in
    -inf) warn=1 ;;
    *) warn=$(awk -v p="$peak" 'BEGIN { print (p < -40 || p > 0) ? 1 : 0 }') ;;
    esac
    [ "$warn" = 1 ] && echo "demo: warning: $f --render $1 peaks at $peak dBFS, outside -40..0 dBFS" >&2
    return 0
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
    first=""
    for ev in netlists/"$name".*.events; do
        [ -e "$ev" ] && { first=$(events_for "$f" "$ev"); break; }
    done
    strike=$(strike_for "$f")
    if [ -n "$first" ]; then # as long as its events last
        render "$f" "$spec" "$wav" --events "$first"
        echo "demo: $f -> $OUT/ (C) and $wav (input: ${spec:-none}, events: $first)"
    elif [ -n "$strike" ]; then
        mkdir -p "$OUT/events" || exit 1
        first="$OUT/events/$name.strike.events"
        echo "$strike" >"$first" || exit 1
        render "$f" "$spec" "$wav" --seconds "$SECONDS_" --events "$first"
        echo "demo: $f -> $OUT/ (C) and $wav (${SECONDS_} s, input: ${spec:-none}, strike: $strike)"
    else
        render "$f" "$spec" "$wav" --seconds "$SECONDS_"
        echo "demo: $f -> $OUT/ (C) and $wav (${SECONDS_} s, input: ${spec:-none})"
    fi
    n=$((n + 1))
    for ev in netlists/"$name".*.events; do
        [ -e "$ev" ] || continue
        ewav="$OUT/$(basename "$ev" .events).wav"
        render "$f" "$spec" "$ewav" --events "$(events_for "$f" "$ev")"
        echo "demo: $f with $ev -> $ewav"
    done
done
echo "demo: $n netlists compiled and rendered"

# SPICE decks: netlists/*.cir, driven by the time functions of their own
# sources, two seconds each.
nd=0
for f in netlists/*.cir; do
    [ -e "$f" ] || continue
    name=$(basename "$f" .cir)
    "$WDC" "$f" -o "$OUT" 2>/dev/null || { echo "demo: FAILED: $WDC $f -o $OUT" >&2; exit 1; }
    render "$f" "" "$OUT/$name.wav" --seconds "$SECONDS_" 2>/dev/null
    echo "demo: $f -> $OUT/ (C) and $OUT/$name.wav (${SECONDS_} s, driven by its sources)"
    nd=$((nd + 1))
done
echo "demo: $nd SPICE decks compiled and rendered"

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
