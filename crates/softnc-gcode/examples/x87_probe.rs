//! Reads lines `x sin cos tan` (the last three in C's `%a`) on stdin and counts
//! where `softnc_gcode::x87`'s SIN, COS and TAN differ in any bit; used by
//! `tests/golden/x87_vs_glibc.sh`.

use std::io::BufRead;

fn main() {
    let (mut n, mut differ) = (0usize, [0usize; 3]);
    for line in std::io::stdin().lock().lines() {
        let line = line.expect("stdin");
        let f: Vec<&str> = line.split(' ').collect();
        let x: f64 = f[0].parse().expect("x");
        let ours = [
            softnc_gcode::x87::sin_deg(x),
            softnc_gcode::x87::cos_deg(x),
            softnc_gcode::x87::tan_deg(x),
        ];
        n += 1;
        for (k, name) in ["SIN", "COS", "TAN"].iter().enumerate() {
            let want = from_c_hex(f[k + 1]);
            if ours[k].to_bits() != want.to_bits() && !(ours[k].is_nan() && want.is_nan()) {
                differ[k] += 1;
                if differ[k] <= 3 {
                    eprintln!("{name}[{x:?}]: softnc {:?}, glibc {want:?}", ours[k]);
                }
            }
        }
    }
    println!(
        "{n} arguments; differ in some bit: SIN {}, COS {}, TAN {}",
        differ[0], differ[1], differ[2]
    );
}

/// C's `%a` (`-0x1.8p+1`, `0x0p+0`, `inf`, `nan`) as an `f64`.
fn from_c_hex(s: &str) -> f64 {
    let negative = s.starts_with('-');
    let s = s.trim_start_matches('-');
    let v = match s {
        "inf" => f64::INFINITY,
        "nan" | "-nan" => f64::NAN,
        _ => {
            let s = s.trim_start_matches("0x");
            let (mant, exp) = s.split_once('p').expect("p exponent");
            let (int, frac) = mant.split_once('.').unwrap_or((mant, ""));
            let bits = format!("{int}{frac}");
            let m = u64::from_str_radix(&bits, 16).expect("hex digits");
            let e: i32 = exp.parse().expect("exponent");
            // m × 16^-len(frac) × 2^e, exact (m has at most 53 significant bits)
            m as f64 * 2f64.powi(e - 4 * frac.len() as i32)
        }
    };
    if negative {
        -v
    } else {
        v
    }
}
