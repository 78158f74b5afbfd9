#!/bin/sh
# Regenerate the golden canonical files from LinuxCNC's rs274 (needs `rs274`, from the
# Debian package linuxcnc-uspace): every NAME.ngc here → NAME.canon.json.
# The work offsets come from golden.var (values in inches: rs274's stand-alone canon
# reads parameters in inches); tests/golden.rs gives the profile the same offsets in mm.
set -e
cd "$(dirname "$0")"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
for f in *.ngc; do
    cp golden.var "$tmp/golden.var"       # rs274 writes its parameters back at exit
    python3 rs274_to_canon.py "$f" "${f%.ngc}.canon.json" -v "$tmp/golden.var"
    echo "$f: $(python3 -c "import json,sys; print(len(json.load(open(sys.argv[1]))))" "${f%.ngc}.canon.json") motions"
done
