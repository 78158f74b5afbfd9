#!/usr/bin/env python3
"""Planned run time of every tier A/B program of ../shared/gcode that LinuxCNC
accepts, on a machine profile: the table in docs/planner.md.

Usage: tools/planner-table.py [path/to/softnc] [--machine PROFILE]
Prints a Markdown table (program, lines, moves, path length, planned time, max feed)."""
import json, os, subprocess, sys

here = os.path.dirname(os.path.abspath(__file__))
shared = os.path.join(here, "..", "..", "shared", "gcode")
args = [a for a in sys.argv[1:] if not a.startswith("--")]
binp = os.path.abspath(args[0] if args else os.path.join(here, "..", "target", "release", "softnc"))
machine = []
if "--machine" in sys.argv:
    machine = ["--machine", os.path.abspath(sys.argv[sys.argv.index("--machine") + 1])]
man = json.load(open(os.path.join(shared, "manifest.json")))
rows = []
for e in man:
    if e.get("tier") not in ("A", "B") or e.get("rs274_accepts") is not True or e.get("rs274_options"):
        continue
    f = os.path.join(shared, e["file"])
    r = subprocess.run([binp, "plan", f, "--json", "--ignore-soft-limits"] + machine,
                       capture_output=True, text=True, cwd=os.path.dirname(f))
    if r.returncode != 0:
        rows.append((e["file"], e["lines"], "-", "-", "refused: " + r.stderr.strip()[:60], "-"))
        continue
    j = json.loads(r.stdout)
    rows.append((e["file"], e["lines"], j["moves"], f'{j["path_length_mm"]:.1f}', f'{j["duration_s"]:.2f}', f'{j["max_feed_mm_min"]:.0f}'))
print("| program | lines | moves | path mm | planned s | max feed mm/min |")
print("|---|---:|---:|---:|---:|---:|")
for r in rows:
    print("| " + " | ".join(str(x) for x in r) + " |")
