#!/bin/sh
# install-deps.sh - installs what building wdc needs, and nothing else.
#
# Checks for a C compiler and for the headers and libraries of libsndfile,
# LAPACKE, cmocka and libmysofa (the binaural renderer's SOFA reader; the
# libmysofa1 it pulls in ships the MIT KEMAR set, HRTF_DEFAULT_SOFA), for
# clang (the tests compile voices with it), and for what the LV2 tests
# use: the LV2 headers and lv2_validate (lv2-dev), lilv (liblilv-dev),
# lv2apply (lilv-utils) and sord_validate (sordi, which lv2_validate
# runs); installs only the missing Debian packages with
# apt-get (after one `apt-get update`), through sudo when not root.
# Exit status: 0 when everything is present afterwards, 1 otherwise.
#
# Usage: sh scripts/install-deps.sh      (or: make deps)

set -u

say() { printf 'install-deps: %s\n' "$*"; }
fail() { printf 'install-deps: error: %s\n' "$*" >&2; exit 1; }

CC_CMD=${CC:-cc}
TMPDIR_DEPS=$(mktemp -d 2>/dev/null || echo "/tmp/wdc-deps.$$")
mkdir -p "$TMPDIR_DEPS" || fail "cannot create a temporary directory"
trap 'rm -rf "$TMPDIR_DEPS"' EXIT INT TERM

have_cc() {
    command -v "$CC_CMD" >/dev/null 2>&1 || return 1
    printf 'int main(void) { return 0; }\n' >"$TMPDIR_DEPS/cc.c"
    "$CC_CMD" "$TMPDIR_DEPS/cc.c" -o "$TMPDIR_DEPS/cc.out" >/dev/null 2>&1
}

# have_lib HEADER LIB: the header compiles and the library links.  Without
# a compiler, looks for the header in the usual include directories.
have_lib() {
    if have_cc; then
        printf '#include <%s>\nint main(void) { return 0; }\n' "$1" \
            >"$TMPDIR_DEPS/t.c"
        "$CC_CMD" "$TMPDIR_DEPS/t.c" -o "$TMPDIR_DEPS/t.out" "-l$2" \
            >/dev/null 2>&1
        return $?
    fi
    for d in /usr/include /usr/local/include /usr/include/*-linux-gnu; do
        [ -f "$d/$1" ] && return 0
    done
    return 1
}

# cmocka.h needs the standard headers it uses included first.
have_cmocka() {
    if have_cc; then
        printf '%s\n' '#include <stdarg.h>' '#include <stddef.h>' \
            '#include <stdint.h>' '#include <setjmp.h>' \
            '#include <cmocka.h>' 'int main(void) { return 0; }' \
            >"$TMPDIR_DEPS/c.c"
        "$CC_CMD" "$TMPDIR_DEPS/c.c" -o "$TMPDIR_DEPS/c.out" -lcmocka \
            >/dev/null 2>&1
        return $?
    fi
    have_lib cmocka.h cmocka
}

missing=""
if have_cc; then
    say "C compiler: $CC_CMD works"
else
    say "C compiler: $CC_CMD missing or not working"
    missing="$missing build-essential"
fi
if have_lib sndfile.h sndfile; then say "libsndfile: found"
else say "libsndfile: missing"; missing="$missing libsndfile1-dev"; fi
if have_lib lapacke.h lapacke; then say "LAPACKE: found"
else say "LAPACKE: missing"; missing="$missing liblapacke-dev"; fi
if have_cmocka; then say "cmocka: found"
else say "cmocka: missing"; missing="$missing libcmocka-dev"; fi
if have_lib mysofa.h mysofa; then say "libmysofa: found"
else say "libmysofa: missing"; missing="$missing libmysofa-dev"; fi
# the tests compile every emitted voice with clang as well as gcc
if command -v clang >/dev/null 2>&1; then say "clang: found"
else say "clang: missing"; missing="$missing clang"; fi

# the LV2 tests: lilv's headers live in their own directory
have_lilv() {
    have_cc || { [ -f /usr/include/lilv-0/lilv/lilv.h ]; return $?; }
    printf '#include <lilv/lilv.h>\nint main(void) { lilv_world_free(lilv_world_new()); return 0; }\n' \
        >"$TMPDIR_DEPS/l.c"
    # shellcheck disable=SC2046 # pkg-config's flags are meant to split
    "$CC_CMD" "$TMPDIR_DEPS/l.c" -o "$TMPDIR_DEPS/l.out" \
        $(pkg-config --cflags --libs lilv-0 2>/dev/null || echo -I/usr/include/lilv-0 -llilv-0) \
        >/dev/null 2>&1
}
have_lv2() { have_lib lv2/core/lv2.h c && command -v lv2_validate >/dev/null 2>&1; }
if have_lv2; then say "LV2 headers and lv2_validate: found"
else say "LV2 headers and lv2_validate: missing"; missing="$missing lv2-dev"; fi
if have_lilv; then say "lilv: found"
else say "lilv: missing"; missing="$missing liblilv-dev"; fi
if command -v lv2apply >/dev/null 2>&1; then say "lv2apply: found"
else say "lv2apply: missing"; missing="$missing lilv-utils"; fi
if command -v sord_validate >/dev/null 2>&1; then say "sord_validate: found"
else say "sord_validate: missing"; missing="$missing sordi"; fi

if [ -z "$missing" ]; then
    say "everything needed is installed"
    exit 0
fi

# shellcheck disable=SC2086 # the package list is meant to split
sh "$(dirname "$0")/apt-install.sh" install-deps $missing || exit 1

# Check again: a package may be installed yet not give what is needed.
still=""
have_cc || still="$still compiler($CC_CMD)"
have_lib sndfile.h sndfile || still="$still sndfile.h/-lsndfile"
have_lib lapacke.h lapacke || still="$still lapacke.h/-llapacke"
have_cmocka || still="$still cmocka.h/-lcmocka"
have_lib mysofa.h mysofa || still="$still mysofa.h/-lmysofa"
command -v clang >/dev/null 2>&1 || still="$still clang"
have_lv2 || still="$still lv2/core/lv2.h/lv2_validate"
have_lilv || still="$still lilv/lilv.h/-llilv-0"
command -v lv2apply >/dev/null 2>&1 || still="$still lv2apply"
command -v sord_validate >/dev/null 2>&1 || still="$still sord_validate"
[ -z "$still" ] || fail "still missing after installing:$still"
say "done: installed$missing"
exit 0
