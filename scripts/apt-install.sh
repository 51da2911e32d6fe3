#!/bin/sh
# apt-install.sh - installs Debian packages for the scripts that need them.
#
#     sh scripts/apt-install.sh WHO PACKAGE...
#
# Runs `apt-get update` once, then `apt-get install -y PACKAGE...`
# non-interactively, through sudo when not root.  WHO prefixes the
# messages.  Exit status: 0 when apt-get succeeded, 1 otherwise.

set -u

who=$1
shift
fail() { printf '%s: error: %s\n' "$who" "$*" >&2; exit 1; }

command -v apt-get >/dev/null 2>&1 ||
    fail "missing: $*; apt-get is not available, install the equivalent packages with your system's package manager"

if [ "$(id -u)" -eq 0 ]; then
    SUDO=""
elif command -v sudo >/dev/null 2>&1; then
    SUDO="sudo"
else
    fail "missing: $*; not root and sudo is not available: run as root: apt-get install $*"
fi

printf '%s: running: %sapt-get update\n' "$who" "${SUDO:+$SUDO }"
$SUDO apt-get update || fail "apt-get update failed"
printf '%s: installing: %s\n' "$who" "$*"
$SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y "$@" || fail "apt-get install $* failed"
exit 0
