//! Reader throughput: a generated 200,000-line program of G1/G2/G3 moves (short lines
//! and small arcs in both formats, as CAM output looks), read into canonical motions;
//! and the language: `nested_while.ngc` (loops, expressions, subroutine calls); and
//! one expression of its loop body read from its text against its compiled form
//! (`softnc_gcode::compiled`, what lines of loops and subroutines use).
//!
//! `SOFTNC_WRITE_BIG=1 cargo bench -p softnc-gcode --bench parse` also writes the
//! program to `$TMPDIR/softnc-gcode-big.ngc`, to time LinuxCNC on the same file:
//! `time rs274 -g $TMPDIR/softnc-gcode-big.ngc /dev/null < /dev/null`.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use softnc_core::MotionProfile;
use std::fmt::Write;

/// `lines` lines of G1/G2/G3 (with a few G0 retracts), mm, ending in M2.
fn big_program(lines: usize) -> String {
    let mut s = String::with_capacity(lines * 32);
    s.push_str("G21 G90 G17 G94 G64 P0.01\nG0 X0 Y0 Z1\nG1 Z-1 F1200\n");
    let (mut x, mut y) = (0.0f64, 0.0f64);
    let mut i = 3;
    while i < lines - 1 {
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
        i += 1;
        if x > 300.0 && i + 3 < lines - 1 {
            x = 0.0;
            writeln!(s, "G0 Z1\nG0 X0 Y{y:.4}\nG1 Z-1").unwrap();
            i += 3;
        }
    }
    s.push_str("M2\n");
    s
}

fn benches(c: &mut Criterion) {
    let profile = MotionProfile::load(
        concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../config/machines/default.ron"
        )
        .as_ref(),
    )
    .expect("default profile");
    let text = big_program(200_000);
    let n_lines = text.lines().count() as u64;
    if std::env::var_os("SOFTNC_WRITE_BIG").is_some() {
        let path = std::env::temp_dir().join("softnc-gcode-big.ngc");
        std::fs::write(&path, &text).unwrap();
        eprintln!("wrote {} ({n_lines} lines)", path.display());
    }
    let program = softnc_gcode::read_program(&text, "big.ngc", &profile).expect("valid");
    assert!(program.motions.len() as u64 > n_lines - 10);
    let mut g = c.benchmark_group("gcode");
    g.throughput(Throughput::Elements(n_lines));
    g.sample_size(20);
    g.bench_function("read_200k_lines", |b| {
        b.iter(|| softnc_gcode::read_program(&text, "big.ngc", &profile).unwrap())
    });
    g.finish();
    // the language: nested while loops, expressions, a subroutine call per
    // iteration (benches/nested_while.ngc, 161,621 executed blocks)
    let nested = include_str!("nested_while.ngc");
    let program = softnc_gcode::read_program(nested, "nested_while.ngc", &profile).expect("valid");
    let mut g = c.benchmark_group("gcode");
    g.throughput(Throughput::Elements(program.blocks as u64));
    g.sample_size(20);
    g.bench_function("read_nested_while", |b| {
        b.iter(|| softnc_gcode::read_program(nested, "nested_while.ngc", &profile).unwrap())
    });
    g.finish();
}

/// Parameters for the expression benchmark.
struct Vars(Vec<f64>);

impl softnc_gcode::expr::Env for Vars {
    fn numbered(&self, index: usize) -> f64 {
        self.0[index]
    }
    fn named(&self, _: &str) -> Result<Option<f64>, softnc_gcode::ErrorKind> {
        Ok(None)
    }
}

fn expressions(c: &mut Criterion) {
    use softnc_gcode::compiled::{compile, eval, Kind};
    let mut norm = softnc_gcode::norm::Norm::default();
    norm.build(b"[#1 * 0.5 + SIN[#2 * 3.6] * 2]");
    let mut vars = vec![0.0; softnc_gcode::params::NUM_PARAMS];
    vars[1] = 17.0;
    vars[2] = 42.0;
    let env = Vars(vars);
    let code = compile(&norm.b, 0, Kind::Real).expect("compiles");
    let mut g = c.benchmark_group("expr");
    g.bench_function("read_from_text", |b| {
        b.iter(|| {
            softnc_gcode::expr::Reader::new(std::hint::black_box(&norm.b), 0, &env)
                .real_value()
                .unwrap()
        })
    });
    g.bench_function("compiled_eval", |b| {
        b.iter(|| eval(std::hint::black_box(&code), &env).unwrap())
    });
    g.finish();
}

criterion_group!(parse, benches, expressions);
criterion_main!(parse);
