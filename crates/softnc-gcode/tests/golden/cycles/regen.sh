#!/usr/bin/env bash
# Regenerate the expected canonical calls of the canned-cycle fixtures from LinuxCNC's
# stand-alone interpreter (`rs274`, Debian package linuxcnc-uspace 2.9): NAME.rs274
# holds rs274's output for NAME.ngc with the sequence numbers left out. CI does not
# need rs274: the expected files are committed.
set -euo pipefail
cd "$(dirname "$0")"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
: > "$tmp/empty.var"
for f in *.ngc; do
    cp "$f" "$tmp/"
    (cd "$tmp" && rs274 -v empty.var -g "$f" "$f.out" < /dev/null > /dev/null 2>&1 || true)
    sed -E 's/^ *[0-9]+ N\.+ //' "$tmp/$f.out" > "${f%.ngc}.rs274"
done
