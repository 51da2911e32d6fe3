#!/bin/sh
# install-bench-deps.sh - installs what the comparison benches need beyond
# scripts/install-deps.sh: for bench/stkbench.c (with bench/stkshim.cpp) the
# Synthesis ToolKit (libstk-dev: Stk.h, Plucked.h, -lstk) and a C++
# compiler (g++); for bench/spacebench.c OpenAL Soft (libopenal-dev:
# AL/al.h, AL/alext.h, -lopenal; it brings libopenal-data, the HRTF data).
# Only the missing Debian packages are installed, with
# apt-get (after one `apt-get update`), through sudo when not root.
# Exit status: 0 when everything is present afterwards, 1 otherwise.
#
# Usage: sh scripts/install-bench-deps.sh      (make bench runs it)

set -u

say() { printf 'install-bench-deps: %s\n' "$*"; }
fail() { printf 'install-bench-deps: error: %s\n' "$*" >&2; exit 1; }

# pkg_installed PKG: dpkg knows PKG as installed.
pkg_installed() {
    dpkg-query -W -f='${Status}' "$1" 2>/dev/null | grep -q 'install ok installed'
}

have_stk() { pkg_installed libstk-dev; }
have_cxx() { command -v "${CXX:-g++}" >/dev/null 2>&1 || pkg_installed g++; }
have_openal() { pkg_installed libopenal-dev; }

command -v dpkg-query >/dev/null 2>&1 ||
    fail "dpkg-query is not available: install the STK headers and library (Stk.h, -lstk), OpenAL Soft's (AL/al.h, -lopenal) and a C++ compiler with your system's package manager"

missing=""
if have_stk; then say "libstk-dev: found"
else say "libstk-dev: missing"; missing="$missing libstk-dev"; fi
if have_cxx; then say "C++ compiler: found"
else say "C++ compiler: missing"; missing="$missing g++"; fi
if have_openal; then say "libopenal-dev: found"
else say "libopenal-dev: missing"; missing="$missing libopenal-dev"; fi

if [ -z "$missing" ]; then
    say "everything needed is installed"
    exit 0
fi

# shellcheck disable=SC2086 # the package list is meant to split
sh "$(dirname "$0")/apt-install.sh" install-bench-deps $missing || exit 1

still=""
have_stk || still="$still libstk-dev"
have_cxx || still="$still g++"
have_openal || still="$still libopenal-dev"
[ -z "$still" ] || fail "still missing after installing:$still"
say "done: installed$missing"
exit 0
