//! Shared by the planner's benchmark and examples: the throughput workload and the
//! machine profile they plan for.
#![allow(dead_code)] // each user takes what it needs

use softnc_core::MotionProfile;
use std::fmt::Write;

/// `config/machines/default.ron`.
pub fn default_profile() -> MotionProfile {
    MotionProfile::load(
        concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../config/machines/default.ron"
        )
        .as_ref(),
    )
    .expect("config/machines/default.ron loads")
}

/// A program of `lines` G1/G2/G3 moves: a zig-zag of short lines with arcs in both
/// formats (I/J and R), as CAM output looks.
pub fn big_program(lines: usize) -> String {
    let mut s = String::with_capacity(lines * 32);
    s.push_str("G21 G90 G17 G94 G64 P0.01\nG0 X0 Y0 Z1\nG1 Z-1 F1200\n");
    let mut y = 0.0f64;
    let mut x = 0.0f64;
    let mut i = 0usize;
    while i < lines {
        match i % 4 {
            0 | 2 => {
                x += 0.8;
                y += if i % 8 < 4 { 0.05 } else { -0.05 };
                writeln!(s, "G1 X{x:.4} Y{y:.4}").unwrap();
            }
            1 => {
                writeln!(s, "G2 X{:.4} Y{y:.4} I0.25 J0", x + 0.5).unwrap();
                x += 0.5;
            }
            _ => {
                writeln!(s, "G3 X{:.4} Y{y:.4} R0.25", x + 0.5).unwrap();
                x += 0.5;
            }
        }
        if x > 300.0 {
            x = 0.0;
            writeln!(s, "G0 Z1\nG0 X0 Y{y:.4}\nG1 Z-1").unwrap();
            i += 3;
        }
        i += 1;
    }
    s.push_str("M2\n");
    s
}
