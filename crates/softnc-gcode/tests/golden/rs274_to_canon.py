#!/usr/bin/env python3
"""Run LinuxCNC's stand-alone interpreter on a program and write its canonical motions
as softnc's canon JSON (the format of shared/gcode/*.canon.json and of
`softnc plan FILE --canon`): one object per motion,
  {"kind": "traverse"|"feed"|"arc", "end": [x, y, z] (mm), "feed_mm_min": F|null,
   and for arcs "plane": "xy"|"xz"|"yz", "center2": [the two in-plane centre
   coordinates in x,y / x,z / y,z order], "turns": rotation (G3 > 0)}.
Positions are rs274's printed values (4 decimals, program units) converted to mm.

Usage:
  rs274_to_canon.py PROGRAM.ngc [OUT.json] [-v VARFILE] [-t TOOLTABLE]
      runs `rs274 -g` in the program's folder; exit 1 (and the error on stderr)
      when rs274 rejects the program.
  rs274_to_canon.py --convert RS274_OUTPUT.txt   convert an existing rs274 output.
"""
import json, os, re, subprocess, sys

MM = 25.4
CALL = re.compile(r"^\s*\d+\s+N\S*\s+([A-Z_0-9]+)\((.*)\)\s*$")


def convert(text):
    inch = False
    plane = "xy"
    feed = 0.0
    out = []
    for line in text.splitlines():
        m = CALL.match(line)
        if not m:
            continue
        name, args = m.group(1), m.group(2)
        if name == "USE_LENGTH_UNITS":
            inch = "INCHES" in args
            continue
        if name == "SELECT_PLANE":
            plane = {"CANON_PLANE_XY": "xy", "CANON_PLANE_XZ": "xz", "CANON_PLANE_YZ": "yz"}.get(args.strip(), plane)
            continue
        if name not in ("SET_FEED_RATE", "STRAIGHT_TRAVERSE", "STRAIGHT_FEED", "ARC_FEED"):
            continue
        s = MM if inch else 1.0
        nums = [float(v) for v in re.split(r"[,\s]+", args.strip()) if v]
        if name == "SET_FEED_RATE":
            feed = nums[0] * s
        elif name == "STRAIGHT_TRAVERSE":
            out.append({"kind": "traverse", "end": [round(v * s, 6) for v in nums[:3]], "feed_mm_min": None})
        elif name == "STRAIGHT_FEED":
            out.append({"kind": "feed", "end": [round(v * s, 6) for v in nums[:3]], "feed_mm_min": round(feed, 6)})
        elif name == "ARC_FEED":
            e1, e2, c1, c2, rot, ax = nums[:6]
            if plane == "xy":
                end, center2 = [e1, e2, ax], [c1, c2]
            elif plane == "xz":      # first axis Z, second X, normal Y
                end, center2 = [e2, ax, e1], [c2, c1]
            else:                    # yz: first Y, second Z, normal X
                end, center2 = [ax, e1, e2], [c1, c2]
            out.append({"kind": "arc", "end": [round(v * s, 6) for v in end], "feed_mm_min": round(feed, 6),
                        "plane": plane, "center2": [round(v * s, 6) for v in center2], "turns": int(rot)})
    return out


def main(argv):
    if argv[:1] == ["--convert"]:
        json.dump(convert(open(argv[1]).read()), sys.stdout)
        print()
        return 0
    opts, rest, i = [], [], 0
    while i < len(argv):
        if argv[i] in ("-v", "-t"):
            opts += [argv[i], os.path.abspath(argv[i + 1])]
            i += 2
        else:
            rest.append(argv[i])
            i += 1
    prog = os.path.abspath(rest[0])
    r = subprocess.run(["rs274", *opts, "-g", prog, "/dev/stdout"], stdin=subprocess.DEVNULL,
                       capture_output=True, cwd=os.path.dirname(prog))
    if r.returncode != 0:
        sys.stderr.write(r.stderr.decode("utf-8", "replace"))
        return 1
    data = json.dumps(convert(r.stdout.decode("utf-8", "replace")))
    if len(rest) > 1:
        with open(rest[1], "w") as f:
            f.write(data + "\n")
    else:
        print(data)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
