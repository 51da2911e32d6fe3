#!/bin/sh
# install-chart-deps.sh - installs what `make chart` needs beyond
# scripts/install-deps.sh: Faust (faust: the compiler and wdmodels.lib,
# which bench/faust/*.dsp import), gnuplot without X (gnuplot-nox: draws
# out/chart.png and out/chart.svg), the Synthesis ToolKit (libstk-dev:
# Stk.h, Plucked.h, -lstk) and a C++ compiler (g++) for bench/stkshim.cpp.
# Only the missing Debian packages are installed, with apt-get (after one
# `apt-get update`), through sudo when not root.  The tests need none of
# them.  Exit status: 0 when everything is present afterwards, 1 otherwise.
#
# Usage: sh scripts/install-chart-deps.sh      (make chart runs it)

set -u

say() { printf 'install-chart-deps: %s\n' "$*"; }
fail() { printf 'install-chart-deps: error: %s\n' "$*" >&2; exit 1; }

# pkg_installed PKG: dpkg knows PKG as installed.
pkg_installed() {
    dpkg-query -W -f='${Status}' "$1" 2>/dev/null | grep -q 'install ok installed'
}

have_faust() { command -v faust >/dev/null 2>&1 || pkg_installed faust; }
have_gnuplot() { command -v gnuplot >/dev/null 2>&1; }
have_stk() { pkg_installed libstk-dev; }
have_cxx() { command -v "${CXX:-g++}" >/dev/null 2>&1 || pkg_installed g++; }

command -v dpkg-query >/dev/null 2>&1 ||
    fail "dpkg-query is not available: install Faust (with wdmodels.lib), gnuplot, the STK headers and library (Stk.h, -lstk) and a C++ compiler with your system's package manager"

missing=""
if have_faust; then say "faust: found"
else say "faust: missing"; missing="$missing faust"; fi
if have_gnuplot; then say "gnuplot: found"
else say "gnuplot: missing"; missing="$missing gnuplot-nox"; fi
if have_stk; then say "libstk-dev: found"
else say "libstk-dev: missing"; missing="$missing libstk-dev"; fi
if have_cxx; then say "C++ compiler: found"
else say "C++ compiler: missing"; missing="$missing g++"; fi

if [ -z "$missing" ]; then
    say "everything needed is installed"
    exit 0
fi

# shellcheck disable=SC2086 # the package list is meant to split
sh "$(dirname "$0")/apt-install.sh" install-chart-deps $missing || exit 1

still=""
have_faust || still="$still faust"
have_gnuplot || still="$still gnuplot-nox"
have_stk || still="$still libstk-dev"
have_cxx || still="$still g++"
[ -z "$still" ] || fail "still missing after installing:$still"
say "done: installed$missing"
exit 0
