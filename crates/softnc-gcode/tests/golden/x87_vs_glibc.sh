#!/usr/bin/env bash
# Compares softnc's SIN, COS and TAN (crate::x87) bit for bit with glibc's sinl,
# cosl and tanl of (x * M_PIl) / 180.0 stored in a double, as LinuxCNC computes
# them, over whole, half and 1-4-decimal degrees and random reals (seeded).
# Needs gcc and python3 on x86-64. Run from the repository root.
set -euo pipefail
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
cat > "$tmp/ref.c" <<'C'
#define _GNU_SOURCE
#include <math.h>
#include <stdio.h>
int main(void) {
    double x;
    while (scanf("%lf", &x) == 1) {
        long double a = (x * M_PIl) / 180.0;
        double s = sinl(a), c = cosl(a), t = tanl(a);
        printf("%.17g %a %a %a\n", x, s, c, t);
    }
    return 0;
}
C
gcc -O0 "$tmp/ref.c" -o "$tmp/ref" -lm
python3 - > "$tmp/args.txt" <<'PY'
import random
random.seed(1)
xs = [i for i in range(-720, 721)] + [i / 2 for i in range(-720, 721)]
xs += [round(random.uniform(-360, 360), random.choice([1, 2, 3, 4])) for _ in range(20000)]
xs += [random.uniform(-1000, 1000) for _ in range(5000)]
print("\n".join(repr(float(x)) for x in xs))
PY
"$tmp/ref" < "$tmp/args.txt" > "$tmp/ref.txt"
cargo run -q --release -p softnc-gcode --example x87_probe < "$tmp/ref.txt"
