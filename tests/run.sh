#!/bin/sh
# run.sh TEST...: runs each cmocka test binary from the repository root and
# reports which failed.  Exit status is non-zero if any failed.
failed=""
for t in "$@"; do
    echo "== $t"
    if ! "$t"; then
        failed="$failed $t"
    fi
done
if [ -n "$failed" ]; then
    echo "FAILED:$failed"
    exit 1
fi
echo "all test programs passed"
