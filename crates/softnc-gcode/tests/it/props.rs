//! Robustness: random bytes never panic; random valid programs (G0/G1/G2/G3 with sane
//! values in all planes, units and distance modes) never panic and yield motions whose
//! starts follow on from the previous ends.

use proptest::prelude::*;
use softnc_core::MotionProfile;
use softnc_gcode::lexer::{lex_line, Line};
use softnc_gcode::{read_program, MotionKind};
use std::path::PathBuf;
use std::sync::OnceLock;

fn profile() -> &'static MotionProfile {
    static P: OnceLock<MotionProfile> = OnceLock::new();
    P.get_or_init(|| {
        MotionProfile::load(
            &PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../config/machines/default.ron"),
        )
        .unwrap()
    })
}

/// One move of a valid program, written so that it is valid whatever the current
/// point: arcs use incremental coordinates (G91) with the end on the circle.
fn a_move() -> impl Strategy<Value = String> {
    let coord = -50.0f64..50.0;
    prop_oneof![
        (coord.clone(), coord.clone(), coord.clone())
            .prop_map(|(x, y, z)| format!("G90 G0 X{x:.4} Y{y:.4} Z{z:.4}")),
        (coord.clone(), coord.clone(), 1.0f64..5000.0)
            .prop_map(|(x, y, f)| format!("G91 G1 X{x:.3} Y{y:.3} F{f:.1}")),
        (
            0usize..3,
            any::<bool>(),
            0.5f64..30.0,
            0.0f64..std::f64::consts::TAU,
            0.0f64..std::f64::consts::TAU,
            -5.0f64..5.0,
            1u32..4
        )
            .prop_map(|(plane, cw, r, a0, a1, h, p)| {
                // centre offset from the start, end on the same circle (exact enough
                // at 6 decimals), helix along the normal
                let (i, j) = (-r * a0.cos(), -r * a0.sin());
                let (e1, e2) = (i + r * a1.cos(), j + r * a1.sin());
                let (g, l1, l2, n, o1, o2) = match plane {
                    0 => ("G17", 'X', 'Y', 'Z', 'I', 'J'),
                    1 => ("G18", 'Z', 'X', 'Y', 'K', 'I'),
                    _ => ("G19", 'Y', 'Z', 'X', 'J', 'K'),
                };
                format!(
                    "{g} G91 {} {l1}{e1:.6} {l2}{e2:.6} {n}{h:.3} {o1}{i:.6} {o2}{j:.6} P{p} F500",
                    if cw { "G2" } else { "G3" }
                )
            }),
        (
            0usize..3,
            any::<bool>(),
            1.0f64..20.0,
            -20.0f64..20.0,
            -20.0f64..20.0
        )
            .prop_map(|(plane, cw, k, e1, e2)| {
                let half = e1.hypot(e2) / 2.0;
                let r = (half * k).max(half + 0.01);
                let (g, l1, l2) = match plane {
                    0 => ("G17", 'X', 'Y'),
                    1 => ("G18", 'Z', 'X'),
                    _ => ("G19", 'Y', 'Z'),
                };
                format!(
                    "{g} G91 {} {l1}{e1:.4} {l2}{e2:.4} R{r:.4} F300",
                    if cw { "G2" } else { "G3" }
                )
            }),
        Just("G20".to_string()),
        Just("G21".to_string()),
        Just("G4 P0.1".to_string()),
        Just("G55".to_string()),
        Just("G54".to_string()),
        Just("T1 M6 G43".to_string()),
        Just("G49".to_string()),
        Just("G64 P0.01".to_string()),
        Just("G61".to_string()),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn random_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..400)) {
        let text = String::from_utf8_lossy(&bytes);
        let _ = read_program(&text, "random.ngc", profile());
    }

    #[test]
    fn random_gcode_like_text_never_panics(
        words in proptest::collection::vec(
            "[GMXYZIJKRPQFSTHN%/();#\\[\\]. +\\-0-9\n]{1,12}", 0..60)
    ) {
        let text = words.concat();
        let _ = read_program(&text, "random.ngc", profile());
    }

    #[test]
    fn numbers_read_as_the_standard_library_reads_them(
        sign in "[-+]?",
        int in "[0-9]{0,12}",
        frac in proptest::option::of("[0-9]{0,12}"),
        space in "[ ]{0,2}",
    ) {
        let digits = match &frac {
            Some(f) => format!("{int}.{f}"),
            None => int.clone(),
        };
        prop_assume!(digits.bytes().any(|c| c.is_ascii_digit()));
        let mut line = Line::default();
        lex_line(&format!("X{sign}{digits}{space}Y1"), &mut line).unwrap();
        let want = digits.parse::<f64>().unwrap();
        let want = if sign == "-" { -want } else { want };
        prop_assert_eq!(line.words[0].value.to_bits(), want.to_bits(), "{}", digits);
    }

    #[test]
    fn random_valid_programs_yield_motions(moves in proptest::collection::vec(a_move(), 1..40)) {
        let mut text = String::from("G21 G90 G94 F1000\n");
        for m in &moves {
            text.push_str(m);
            text.push('\n');
        }
        text.push_str("M2\n");
        let program = read_program(&text, "valid.ngc", profile())
            .map_err(|e| TestCaseError::fail(format!("{e}\n{text}")))?;
        let moving = moves.iter().filter(|m| m.contains(" X") || m.contains(" Y") || m.contains(" Z")).count();
        let got = program.motions.iter().filter(|m| !matches!(m.kind, MotionKind::Dwell { .. } | MotionKind::Machine(_))).count();
        prop_assert_eq!(got, moving);
        for w in program.motions.windows(2) {
            if let Some(prev) = w[0].kind.end() {
                let gap = (w[1].start + w[1].offset_mm - prev - w[0].offset_mm).norm();
                // tool changes re-read the position as rs274 does (see docs/gcode.md)
                if !text.contains("M6") {
                    prop_assert!(gap < 1e-6, "gap {} at line {}", gap, w[1].line);
                }
            }
            for v in w[1].start.0 {
                prop_assert!(v.is_finite());
            }
        }
    }
}
