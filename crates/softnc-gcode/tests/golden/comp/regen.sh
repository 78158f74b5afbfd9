#!/usr/bin/env bash
# Regenerate the expected canonical calls of the cutter-compensation fixtures from
# LinuxCNC's stand-alone interpreter (`rs274`, Debian package linuxcnc-uspace 2.9, its
# built-in sample tool table: T1 3.175 mm, T2 1.5875 mm, T3 5.1054 mm in diameter):
# NAME.rs274 holds rs274's output for NAME.ngc with the sequence numbers left out;
# errors/NAME.err what rs274 says when it stops there (its message, then the text of
# the line it stopped at). CI does not need rs274: the expected files are committed.
set -euo pipefail
cd "$(dirname "$0")"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
: > "$tmp/empty.var"
for f in *.ngc errors/*.ngc; do
    cp "$f" "$tmp/x.ngc"
    (cd "$tmp" && rs274 -v empty.var -g x.ngc x.out < /dev/null > x.log 2>&1 || true)
    case "$f" in
        errors/*) grep -v '^executing$' "$tmp/x.log" > "${f%.ngc}.err" || true ;;
        *) sed -E 's/^ *[0-9]+ N\.+ //' "$tmp/x.out" > "${f%.ngc}.rs274" ;;
    esac
done
