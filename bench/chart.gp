# chart.gp - draws speed against accuracy from the CSV build/bench/chart
# writes (see bench/chart.c for how each point is measured).
#
#     gnuplot -e "csv='out/chart.csv'; png='out/chart.png'; svg='out/chart.svg'" bench/chart.gp
#
# Three panels and the key: the circuits driven by a 1 V and by a 10 V
# sine (error in dB against the converged trapezoidal solve at 12.288 MHz),
# and the strings (worst tuning error of partials 1-4 in cents).  Speed is
# ns per sample on a log axis: better is down and to the left.  Colour is
# the model, the marker's shape who made it, a filled marker double
# precision and an open one float; each double point is labelled with
# its solver (our diode voices) or maker (peers) and its rate (its float
# twin has the same error and sits beside it).

if (!exists("csv")) csv = "out/chart.csv"
if (!exists("png")) png = "out/chart.png"
if (!exists("svg")) svg = "out/chart.svg"

set datafile separator comma
set datafile missing ""

# the CSV's columns
c_model = 3; c_solver = 4; c_rate = 5; c_prec = 6; c_ns = 7
c_db = 8; c_cents = 9; c_impl = 11; c_drive = 12

precs = "double float"

colour(m) = m eq "rc_lowpass" ? "#1f77b4" : m eq "diode_clipper" ? "#d62728" : \
            m eq "diode_single" ? "#2ca02c" : "#9467bd"
# filled markers for double, open ones for float
shape(i, p) = (i eq "wdc" ? 7 : i eq "faust" ? 9 : i eq "hand" ? 5 : 13) - (p eq "float" ? 1 : 0)
impl_title(i) = i eq "wdc" ? "wdc (ours)" : i eq "faust" ? "Faust wdmodels.lib" : \
                i eq "hand" ? "C by hand" : "STK Plucked"

is(m, i, p, d) = strcol(c_model) eq m && strcol(c_impl) eq i && strcol(c_prec) eq p && strcol(c_drive) eq d
# the label of the current row: solver (our diode voices) or maker, and rate
label(i, s) = (i eq "wdc" && s ne "linear" ? s : i) . sprintf(" %.0fk", column(c_rate) / 1000)

do for [t in "png svg"] {
    if (t eq "png") {
        set terminal pngcairo size 1800,1900 font "sans,11" noenhanced
        set output png
    } else {
        set terminal svg size 1800,1900 font "sans,11" dynamic noenhanced
        set output svg
    }
    set multiplot title "wdc: speed against accuracy, our voices beside their peers (one run, every point at 48, 96 and 192 kHz)"
    set logscale x
    set grid xtics ytics mxtics
    set offsets 0, 0, graph 0.08, graph 0.03
    set xlabel "ns per sample (log scale; left is faster)"
    unset key

    do for [d in "1 10"] {
        drive = "sine " . d . " V"
        set origin 0, (d eq "1" ? 0.64 : 0.31)
        set size 1, 0.33
        set title sprintf("Circuits, 440 Hz sine of %s V: error against the converged trapezoidal solve at 12.288 MHz", d)
        set ylabel "relative RMS error of v(out), dB (down is more accurate)"
        unset logscale y
        plot for [m in "rc_lowpass diode_clipper diode_single"] for [i in "wdc faust hand"] for [p in precs] \
                 csv using (is(m, i, p, drive) ? column(c_ns) : NaN):(column(c_db)) \
                 with points pt shape(i, p) ps 1.4 lc rgb colour(m), \
             for [m in "rc_lowpass diode_clipper diode_single"] for [i in "wdc faust hand"] \
                 csv using (is(m, i, "double", drive) ? column(c_ns) : NaN):(column(c_db)):(label(strcol(c_impl), strcol(c_solver))) \
                 with labels left rotate by 40 offset 0.6, 0.6 font ",8" tc rgb colour(m)
    }

    set origin 0, 0
    set size 0.55, 0.31
    set title "Strings, f0 = 110, 440 and 1760 Hz: worst tuning error of partials 1-4"
    set ylabel "worst |error| from n f0, cents (log scale; down is better tuned)"
    set logscale y
    plot for [i in "wdc stk"] for [p in precs] \
             csv using (is("pluck", i, p, "pluck") ? column(c_ns) : NaN):(column(c_cents)) \
             with points pt shape(i, p) ps 1.6 lc rgb colour("pluck"), \
         for [i in "wdc stk"] \
             csv using (is("pluck", i, "double", "pluck") ? column(c_ns) : NaN):(column(c_cents)):(label(strcol(c_impl), strcol(c_solver))) \
             with labels left rotate by 40 offset 0.6, 0.6 font ",9" tc rgb colour("pluck")

    # the key, beside the strings
    set origin 0.55, 0
    set size 0.45, 0.31
    unset title; unset xlabel; unset ylabel; unset logscale; unset grid
    unset border; unset tics
    set xrange [0:1]; set yrange [0:1]
    set key center center box spacing 1.4 font ",11"
    plot keyentry with points pt 7 ps 1.5 lc rgb "#1f77b4" title "RC lowpass (netlists/rc_lowpass.wdn)", \
         keyentry with points pt 7 ps 1.5 lc rgb "#d62728" title "diode clipper, antiparallel pair (diode_clipper.wdn)", \
         keyentry with points pt 7 ps 1.5 lc rgb "#2ca02c" title "diode clipper, one diode (diode_single.wdn)", \
         keyentry with points pt 7 ps 1.5 lc rgb "#9467bd" title "plucked string (pluck.wdn)", \
         keyentry with points pt 7 ps 1.5 lc rgb "black" title "wdc, ours (labels: solver and rate)", \
         keyentry with points pt 9 ps 1.5 lc rgb "black" title "Faust wdmodels.lib, faust -lang c", \
         keyentry with points pt 5 ps 1.5 lc rgb "black" title "C by hand (bilinear RC; trapezoidal rule + Newton)", \
         keyentry with points pt 13 ps 1.5 lc rgb "black" title "STK Plucked", \
         keyentry with points pt 7 ps 1.5 lc rgb "gray40" title "filled: double precision (labelled)", \
         keyentry with points pt 6 ps 1.5 lc rgb "gray40" title "open: float precision", \
         NaN notitle
    unset xrange; unset yrange; set border; set tics; unset key
    set autoscale

    unset multiplot
    set output
}
