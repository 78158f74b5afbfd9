//! The RS274/NGC language around the words: parameters, expressions, O-words, as
//! LinuxCNC 2.9 runs them (the expected values are what LinuxCNC's semantics give,
//! worked out by hand from `interp_o_word.cc` / `interp_read.cc`).

use softnc_core::MotionProfile;
use softnc_gcode::{ErrorKind, MotionKind, PathMode, ReadOptions};
use std::path::PathBuf;

fn profile() -> MotionProfile {
    MotionProfile::load(
        &PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../config/machines/default.ron"),
    )
    .unwrap()
}

/// X of every motion end (mm).
fn xs(text: &str) -> Vec<f64> {
    let p = softnc_gcode::read_program(text, "t.ngc", &profile()).unwrap();
    p.motions
        .iter()
        .filter_map(|m| m.kind.end().map(|e| e.0[0]))
        .collect()
}

fn error(text: &str) -> softnc_gcode::GcodeError {
    softnc_gcode::read_program(text, "t.ngc", &profile()).unwrap_err()
}

#[test]
fn parameters_take_effect_after_the_line() {
    assert_eq!(xs("#1=5 G0 X#1\nG0 X#1\nM2\n"), vec![0.0, 5.0]);
    assert_eq!(xs("#1=2 #2=3\nG0 X[#1*#2+1]\nM2\n"), vec![7.0]);
    assert_eq!(xs("#<a>=4\n#<_bb>=[#<a>+1]\nG0 X#<_bb>\nM2\n"), vec![5.0]);
    assert_eq!(xs("#3=7 #7=9\nG0 X##3\nM2\n"), vec![9.0]);
    assert_eq!(xs("G21 G0 X[2**3] Y0\nG0 X#<_x>\nM2\n"), vec![8.0, 8.0]);
}

#[test]
fn parameter_errors_as_linuxcnc() {
    let e = error("G0 X#<nope>\nM2\n");
    assert_eq!(e.kind.to_string(), "Named parameter #<nope> not defined");
    assert_eq!((e.line, e.column), (1, 5));
    assert_eq!(
        error("#5420=1\nM2\n").kind.to_string(),
        "Parameter is readonly"
    );
    assert_eq!(
        error("#6000=1\nM2\n").kind.to_string(),
        "Parameter number out of range"
    );
    assert_eq!(
        error("#1 5\nM2\n").kind.to_string(),
        "Equal sign missing in parameter setting"
    );
    assert_eq!(
        error("G0 X[1/0]\nM2\n").kind.to_string(),
        "Attempt to divide by zero"
    );
    assert_eq!(
        error("#<_x>=1\nM2\n").kind.to_string(),
        "Cannot assign to read-only parameter #<_x>"
    );
}

#[test]
fn subroutines_with_arguments_and_return_values() {
    let text = "o<sq> sub\n#<r>=[#1*#1]\no<sq> return [#<r>]\no<sq> endsub\n\
                o<sq> call [3]\nG0 X#<_value>\n#1=2\no100 call [#1+2] [5]\nG0 X#1\nM2\n\
                o100 sub\nG0 X[#1*10+#2]\no100 endsub\n";
    // o100 is defined after the main program: LinuxCNC skips forward to it
    assert_eq!(xs(text), vec![9.0, 45.0, 2.0]);
}

#[test]
fn recursion_and_the_call_depth_limit() {
    let fact = "o<f> sub\no1 if [#1 le 1]\no<f> return [1]\no1 endif\n\
                o<f> call [#1-1]\no<f> return [#<_value>*#1]\no<f> endsub\n\
                o<f> call [5]\nG0 X#<_value>\nM2\n";
    assert_eq!(xs(fact), vec![120.0]);
    let deep = "o<d> sub\no<d> call [#1+1]\no<d> endsub\no<d> call [0]\nM2\n";
    let e = error(deep);
    assert_eq!(e.kind.to_string(), "Too many subroutine levels");
    // rs274 runs nine nested levels (its DEBUG prints 1 … 9) and stops at the
    // tenth call
    let count = "#<_n>=0\no<r> sub\n#<_n>=[#<_n>+1]\n(DEBUG,#<_n>)\no<r> call\n\
                 o<r> endsub\no<r> call\nM2\n";
    let e = error(count);
    assert_eq!(
        (e.line, e.kind.to_string().as_str()),
        (5, "Too many subroutine levels")
    );
    let (p, _) = softnc_gcode::read_program_with(
        "#<_n>=0\no<r> sub\n#<_n>=[#<_n>+1]\n(DEBUG,#<_n>)\no1 if [#<_n> LT 9]\n\
         o<r> call\no1 endif\no<r> endsub\no<r> call\nM2\n",
        "t.ngc",
        &profile(),
        &ReadOptions::default(),
    )
    .unwrap();
    assert_eq!(p.warnings.last().unwrap(), "t.ngc:4: debug: 9.000000");
}

/// A kept O-line compiled whole is read and run at once (`Interp::run_kept_o`):
/// loops, calls and returns through kept lines go where the text says, and an
/// error of its control flow has the line and column of the line read once.
#[test]
fn kept_o_lines_read_and_run_at_once() {
    // the call line is kept from the second call on; the tenth call fails there
    let e = error("o<r> sub\n  o<r> call [#1+1]\no<r> endsub\no<r> call [0]\nM2\n");
    assert_eq!(
        (e.line, e.column, e.kind.to_string().as_str()),
        (2, 3, "Too many subroutine levels")
    );
    let text = "o<s> sub\nG0 X[#1*10+#2]\no<s> endsub\n#1=0\no1 do\n#1=[#1+1]\n#2=0\n\
                o2 while [#2 lt 3]\n#2=[#2+1]\no3 if [#2 eq 2]\no2 continue\no3 endif\n\
                o<s> call [#1] [#2]\no2 endwhile\no4 repeat [2]\no1 while [#1 lt 3]\n\
                o4 endrepeat\nM2\n";
    assert_eq!(xs(text), vec![11.0, 13.0, 21.0, 23.0, 31.0, 33.0]);
}

/// A kept O-line remembers its label and keyword only where the label is fixed
/// text: a label read from an expression is evaluated again on every pass. Here
/// the loop calls o11, o12, then o13 (as `rs274` does); lines are kept from the
/// second pass on, so the third is the first that could reuse a kept label.
#[test]
fn an_o_label_from_an_expression_is_read_on_every_pass() {
    let text = "o11 sub\nG0 X11\no11 endsub\no12 sub\nG0 X12\no12 endsub\n\
                o13 sub\nG0 X13\no13 endsub\n#1=0\no1 while [#1 lt 3]\n#1=[#1+1]\n\
                o[10+#1] call\no1 endwhile\nM2\n";
    assert_eq!(xs(text), vec![11.0, 12.0, 13.0]);
}

#[test]
fn loops_and_conditionals() {
    let w = "#1=0\no1 while [#1 lt 3]\nG0 X#1\n#1=[#1+1]\no1 endwhile\nM2\n";
    assert_eq!(xs(w), vec![0.0, 1.0, 2.0]);
    let d = "#1=5\no2 do\nG0 X#1\n#1=[#1+1]\no2 while [#1 lt 3]\nM2\n";
    assert_eq!(xs(d), vec![5.0]);
    let r = "o3 repeat [3]\nG91 G0 X1\no3 endrepeat\nM2\n";
    assert_eq!(xs(r), vec![1.0, 2.0, 3.0]);
    let i =
        "#1=2\no4 if [#1 eq 1]\nG0 X1\no4 elseif [#1 eq 2]\nG0 X2\no4 else\nG0 X3\no4 endif\nM2\n";
    assert_eq!(xs(i), vec![2.0]);
    let e = "o4 if [0]\nG0 X1\nG81 Q##\no4 else\nG0 X3\no4 endif\nM2\n";
    // the skipped branch is not read at all (LinuxCNC reads only O-lines there)
    assert_eq!(xs(e), vec![3.0]);
    let bc = "#1=0\no5 while [#1 lt 6]\n#1=[#1+1]\no6 if [#1 eq 2]\no5 continue\no6 endif\n\
              o7 if [#1 eq 4]\no5 break\no7 endif\nG0 X#1\no5 endwhile\nM2\n";
    assert_eq!(xs(bc), vec![1.0, 3.0]);
}

#[test]
fn endless_loops_end_at_the_block_limit() {
    let text = "o1 while [1]\nG0 X1\no1 endwhile\nM2\n";
    let options = ReadOptions {
        block_limit: Some(10_000),
        ..Default::default()
    };
    let e = softnc_gcode::read_program_with(text, "t.ngc", &profile(), &options).unwrap_err();
    assert!(
        matches!(e.kind, ErrorKind::BlockLimit { limit: 10_000 }),
        "{e}"
    );
    // the default limit also ends it
    assert!(matches!(error(text).kind, ErrorKind::BlockLimit { .. }));
}

#[test]
fn o_word_errors_as_linuxcnc() {
    assert_eq!(
        error("o1 if 1\nM2\n").kind.to_string(),
        "Left bracket missing after 'if'"
    );
    assert_eq!(
        error("o1 foo\nM2\n").kind.to_string(),
        "Unknown control command in o word"
    );
    assert_eq!(
        error("o1 if [1] G0 X1\no1 endif\nM2\n").kind.to_string(),
        "Unexpected character after O-word"
    );
    let e = error("o1 if [0]\nG0 X1\nM2\n");
    assert!(
        e.kind.to_string().contains("looking for O-word label"),
        "{e}"
    );
    let e = error("M98 P100\nM2\n");
    assert!(
        e.kind
            .to_string()
            .contains("looking for O-word label '100'"),
        "{e}"
    );
}

#[test]
fn subroutine_files_on_the_search_path() {
    let dir = std::env::temp_dir().join(format!("softnc-subs-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(
        dir.join("twice.ngc"),
        "o<twice> sub\nG0 X[#1*2]\no<twice> endsub\n",
    )
    .unwrap();
    let options = ReadOptions {
        subroutine_path: vec![dir.clone()],
        ..Default::default()
    };
    let (p, _) = softnc_gcode::read_program_with(
        "o<twice> call [4]\no<twice> call [5]\nG0 X1\nM2\n",
        "t.ngc",
        &profile(),
        &options,
    )
    .unwrap();
    let ends: Vec<f64> = p
        .motions
        .iter()
        .filter_map(|m| match m.kind {
            MotionKind::Traverse { end } => Some(end.0[0]),
            _ => None,
        })
        .collect();
    assert_eq!(ends, vec![8.0, 10.0, 1.0]);
    assert_eq!(p.motions[2].line, 3);
    let e = softnc_gcode::read_program_with("o<none> call\nM2\n", "t.ngc", &profile(), &options)
        .unwrap_err();
    assert!(
        e.kind
            .to_string()
            .contains("looking for O-word label 'none'"),
        "{e}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

fn read(text: &str) -> softnc_gcode::Program {
    softnc_gcode::read_program(text, "t.ngc", &profile()).unwrap()
}

/// The program with its machine operations left out (the program end's spindle
/// stop among them: `machine_ops.rs` checks those): its moves, dwells and stops.
fn moves(text: &str) -> softnc_gcode::Program {
    let mut p = read(text);
    p.motions
        .retain(|m| !matches!(m.kind, MotionKind::Machine(_)));
    p
}

#[test]
fn g92_g52_and_their_parameters() {
    // G92 X1 at X3: the point is now X1, the offset 2 (5211), restored by G92.3
    let p = read(
        "G0 X3\nG92 X1\nG0 X2\n(PRINT,#5210 #5211 %d#5211)\nG92.2\nG0 X2\nG92.3\nG0 X0\nG92.1\nG0 X0\nM2\n",
    );
    let ends: Vec<(f64, f64)> = p
        .motions
        .iter()
        .filter(|m| !matches!(m.kind, MotionKind::Machine(_)))
        .map(|m| (m.kind.end().unwrap().0[0], m.offset_mm.0[0]))
        .collect();
    assert_eq!(
        ends,
        vec![(3.0, 0.0), (2.0, 2.0), (2.0, 0.0), (0.0, 2.0), (0.0, 0.0)]
    );
    assert!(p
        .warnings
        .iter()
        .any(|w| w == "t.ngc:4: print: 1.000000 2.000000 2"));
    // G52 sets the offset itself
    let p = read("G0 X3\nG52 X1\nG0 X0\nM2\n");
    assert_eq!(p.motions[1].offset_mm.0[0], 1.0);
    assert_eq!(p.motions[1].start.0[0], 2.0);
    assert_eq!(
        error("G92\nM2\n").kind.to_string(),
        "All axes missing with g52 or g92"
    );
    assert_eq!(
        error("G92 G1 X1\nM2\n").kind.to_string(),
        "Cannot use two g codes that both use axis values"
    );
}

#[test]
fn g10_l2_l20_set_work_offsets() {
    // G10 L2 P1 sets G54 (active): the same program point moves with it
    let p = moves("G10 L2 P1 X5\nG0 X1\nG10 L2 P2 Y7\nG55 G0 X1\n#1=#5242\nG0 X#1\nM2\n");
    let offs: Vec<[f64; 3]> = p.motions.iter().map(|m| m.offset_mm.0).collect();
    assert_eq!(
        offs,
        vec![[5.0, 0.0, 0.0], [0.0, 7.0, 0.0], [0.0, 7.0, 0.0]]
    );
    assert_eq!(p.motions[2].kind.end().unwrap().0[0], 7.0);
    // L20: the current point becomes the value given
    let p = moves("G0 X4\nG10 L20 P0 X1\nG0 Y0\nM2\n");
    assert_eq!(p.motions[1].start.0[0], 1.0);
    assert_eq!(p.motions[1].offset_mm.0[0], 3.0);
    assert!(matches!(
        error("G10 L1 P1 Y1\nM2\n").kind,
        ErrorKind::Unsupported { .. }
    ));
    assert_eq!(
        error("G10 L2 P10 X1\nM2\n").kind.to_string(),
        "P value out of range (0-9) with G10 L2"
    );
}

#[test]
fn g28_g30_go_through_the_waypoint_to_the_stored_position() {
    let p = moves("G0 X5 Y5 Z5\nG28.1\nG0 X0 Y0 Z0\nG28 Z1\nG30\nM2\n");
    let ends: Vec<[f64; 3]> = p.motions.iter().map(|m| m.kind.end().unwrap().0).collect();
    assert_eq!(
        ends,
        vec![
            [5.0, 5.0, 5.0],
            [0.0, 0.0, 0.0],
            [0.0, 0.0, 1.0], // the waypoint
            [0.0, 0.0, 5.0], // only Z goes home
            [0.0, 0.0, 5.0], // G30: no axis words, through the current point
            [0.0, 0.0, 0.0], // to #5181-5183 (0)
        ]
    );
}

#[test]
fn print_formats_as_linuxcnc() {
    let p = read("#1=1.5 #<v>=-2\n(PRINT,a=#1 b=#<v> %f#1 %.2f#<v> c=#<nope> #x 100%)\nM2\n");
    assert_eq!(
        p.warnings,
        vec!["t.ngc:2: print: a=1.500000 b=-2.000000 1.5000 -2.00 c=###### #x 100%"]
    );
    let p = read("#5599=0\n(DEBUG,hidden)\n#5599=1\n(debug, shown #5599)\nM2\n");
    assert_eq!(p.warnings, vec!["t.ngc:4: debug:  shown 1.000000"]);
}

#[test]
fn fanuc_m98_m99_subprograms() {
    // M98 P1 L3 runs O1 three times; #1 is passed on as it is (no arguments)
    let text = "#1=1\nG91\nM98 P1 L3\nG90 G0 X#1\nM30\nO1\nG0 X1\n#1=[#1+1]\nM99\n";
    assert_eq!(xs(text), vec![1.0, 2.0, 3.0, 4.0]);
    let bare = "O100 (main program)\nG0 X1\nM2\n";
    assert_eq!(xs(bare), vec![1.0]);
    assert_eq!(
        error("M98 L2\nM2\n").kind.to_string(),
        "Found 'm98' code with no P-word"
    );
    assert_eq!(
        error("o1 call\nM2\nO1\nG0 X1\nM99\n").kind.to_string(),
        "Fanuc 'O....' subroutine must be called with 'M98'"
    );
    assert_eq!(
        error("M98 P1\nM2\nO1\nG0 X1\no1 endsub\n").kind.to_string(),
        "Fanuc 'O....' subroutine definition must end with 'M99'"
    );
    assert_eq!(
        error("o1 call\nM2\no1 sub\nG0 X1\nM99\n").kind.to_string(),
        "'O.... endsub' or 'O.... return' must follow 'O.... sub' subroutine definition"
    );
    // M99 in the main program loops it forever in LinuxCNC: refused
    assert!(matches!(
        error("G0 X1\nM99\n").kind,
        ErrorKind::Unsupported { .. }
    ));
}

mod fuzz {
    use super::*;
    use proptest::prelude::*;

    /// Lines made of the language's pieces in random order: O-words, parameters,
    /// expressions, words, comments, broken fragments.
    fn piece() -> impl Strategy<Value = String> {
        prop::sample::select(vec![
            "o1 ",
            "o<a> ",
            "sub",
            "endsub",
            "call",
            "[1]",
            "[#1]",
            "return",
            "if",
            "elseif",
            "else",
            "endif",
            "while",
            "endwhile",
            "do",
            "repeat",
            "endrepeat",
            "break",
            "continue",
            "#1",
            "#<a>",
            "#<_b>",
            "=",
            "[",
            "]",
            "+",
            "-",
            "*",
            "/",
            "**",
            " mod ",
            " eq ",
            " lt ",
            " and ",
            "sin",
            "atan",
            "exists",
            "2",
            "0.5",
            "-1",
            "G0",
            "G1",
            "G92",
            "G10 L2 P1",
            "G28",
            "X",
            "Y",
            "Z",
            "F100",
            "M98 P1",
            "M99",
            "O1",
            "M2",
            "(print,#1)",
            "(",
            ")",
            ";",
            "%",
            "\n",
            "\n",
            "\n",
            "\n",
        ])
        .prop_map(str::to_string)
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(3000))]
        /// Never a panic, never a hang: every program reads or fails with file:line.
        #[test]
        fn random_language_programs_never_panic_or_hang(
            pieces in prop::collection::vec(piece(), 1..80)
        ) {
            let text: String = pieces.concat();
            let options = ReadOptions { block_limit: Some(20_000), ..Default::default() };
            match softnc_gcode::read_program_with(&text, "f.ngc", &profile(), &options) {
                Ok(_) => {}
                Err(e) => prop_assert!(e.line >= 1 && e.to_string().starts_with("f.ngc:"), "{e}"),
            }
        }
    }
}

#[test]
fn m70_m73_save_and_restore_the_modal_state() {
    // M70 saves G21 G90 F100 at X0; G20 G91 F5 change it (F before G20 on a line:
    // 5 mm/min, as LinuxCNC); M72 brings them back
    let p = moves("G21 G90 F100\nM70\nG20 G91 F5\nG1 X1\nM72\nG1 X2\nM2\n");
    let m: Vec<(f64, f64, bool)> = p
        .motions
        .iter()
        .map(|m| match m.kind {
            MotionKind::Feed {
                end,
                feed_mm_per_min,
            } => (end.0[0], feed_mm_per_min, m.inch),
            _ => panic!(),
        })
        .collect();
    assert_eq!(m, vec![(25.4, 5.0, true), (2.0, 100.0, false)]);
    // M73 in a subroutine restores on return
    let p = moves("G90 F100\no1 sub\nM73\nG91 F7\nG1 X1\no1 endsub\no1 call\nG1 X5\nM2\n");
    let ends: Vec<f64> = p
        .motions
        .iter()
        .map(|m| m.kind.end().unwrap().0[0])
        .collect();
    assert_eq!(ends, vec![1.0, 5.0]);
    assert_eq!(
        error("M72\nM2\n").kind.to_string(),
        "Cannot restore context from invalid stack frame - missing M70/M73?"
    );
    assert!(error("M70\nM71\nM72\nM2\n")
        .kind
        .to_string()
        .contains("missing M70/M73"));
}

#[test]
fn m70_m72_restore_g64_p_and_q() {
    // rs274 (2.9.0~pre1) prints, for the feeds of this program, the modes
    // SET_MOTION_CONTROL_MODE(CANON_CONTINUOUS, P) + SET_NAIVECAM_TOLERANCE(Q):
    // X1 (0.5, 0.3); after M72 X2 (0.02, 0.01); X3 after G61 and M72 (0.04, 0.04:
    // LinuxCNC takes P for a missing Q, softnc merges only with a Q); X4 after
    // G64 P1 and M72 (0, 0.07)
    let p = moves(
        "G21 F100\nG64 P0.02 Q0.01\nM70\nG64 P0.5 Q0.3\nG1 X1\nM72\nG1 X2\n\
         G64 P0.04\nM70\nG61\nM72\nG1 X3\nG64 Q0.07\nM70\nG64 P1\nM72\nG1 X4\nM2\n",
    );
    let modes: Vec<PathMode> = p.motions.iter().map(|m| m.path_mode).collect();
    let blend = |p: Option<f64>, q: Option<f64>| PathMode::Blend {
        tolerance_mm: p,
        naive_cam_mm: q,
    };
    assert_eq!(
        modes,
        vec![
            blend(Some(0.5), Some(0.3)),
            blend(Some(0.02), Some(0.01)),
            blend(Some(0.04), None),
            blend(None, Some(0.07)),
        ]
    );
    // in inches, P and Q come back in the program's unit
    let p = moves("G20\nF1\nG64 P0.001 Q0.002\nM70\nG64 P0.5\nG21\nM72\nG1 X1\nM2\n");
    match p.motions[0].path_mode {
        PathMode::Blend {
            tolerance_mm: Some(t),
            naive_cam_mm: Some(q),
        } => {
            assert!(
                (t - 0.0254).abs() < 1e-12 && (q - 0.0508).abs() < 1e-12,
                "{t} {q}"
            );
        }
        m => panic!("{m:?}"),
    }
}

#[test]
fn program_end_selects_g54_again() {
    // rs274 -v FILE writes 5220 = 1 after M2 (convert_stop), 2 after a program
    // that ends with its closing %
    let end = |text: &str| {
        let (_, params) =
            softnc_gcode::read_program_with(text, "t.ngc", &profile(), &ReadOptions::default())
                .unwrap();
        params.get(5220)
    };
    assert_eq!(end("G55\nG0 X1\nM2\n"), 1.0);
    assert_eq!(end("G55\nG0 X1\nM30\n"), 1.0);
    assert_eq!(end("%\nG55\nG0 X1\n%\n"), 2.0);
}

#[test]
fn skipped_lines_are_still_lines() {
    // read_text checks comments on every line, also in a branch not taken
    assert_eq!(
        error("o1 if [0]\nG0 X1 (open\no1 endif\nM2\n")
            .kind
            .to_string(),
        "Unclosed comment found"
    );
    // a lone % is the end of the file, also while skipping: an error there
    assert_eq!(
        error("%\nG0 X1\no1 call\n%\no1 sub\no1 endsub\n")
            .kind
            .to_string(),
        "Failed to find sub 'O1' before EOF"
    );
}

#[test]
fn g43_1_sets_and_g43_2_adds_a_tool_length() {
    let p = moves("G0 Z10\nG43.1 Z5\nG0 Z0\nG43.2 Z1\nG0 Z0\nG49\nG0 Z0\nM2\n");
    let z: Vec<(f64, f64)> = p
        .motions
        .iter()
        .map(|m| (m.start.0[2], m.offset_mm.0[2]))
        .collect();
    // G43.1 takes the Z word (no motion on its line); G43.2 leaves it to the motion
    // mode in force too (LinuxCNC's enhance_block), so its line also moves to Z1
    assert_eq!(
        z,
        vec![(0.0, 0.0), (5.0, 5.0), (-1.0, 6.0), (1.0, 6.0), (6.0, 0.0)]
    );
    assert_eq!(
        error("G43.2\nM2\n").kind.to_string(),
        "G43.2: No axes specified and H word missing"
    );
    assert!(matches!(
        error("G43.1 X1\nM2\n").kind,
        ErrorKind::Unsupported { .. }
    ));
}

#[test]
fn g10_l1_l10_l11_set_tool_lengths() {
    // L1: tool 2 is 7 mm long now; G43 H2 uses it
    let p = read("G10 L1 P2 Z7\nG43 H2\nG0 X0\nM2\n");
    assert_eq!(p.motions[0].offset_mm.0[2], 7.0);
    // L10: with tool 1 loaded and G43, the current Z becomes Z3 in the active system
    let p = read("T1 M6\nG43\nG0 Z10\nG10 L10 P1 Z3\nG43\nG0 X0\nM2\n");
    let last = p.motions.last().unwrap();
    assert!((last.start.0[2] - 3.0).abs() < 1e-9, "{:?}", last.start);
    // L11 measures in G59.3 (here all offsets 0: the same as L10)
    let p = read("T1 M6\nG43\nG0 Z10\nG10 L11 P1 Z3\nG43\nG0 X0\nM2\n");
    assert!((p.motions.last().unwrap().start.0[2] - 3.0).abs() < 1e-9);
    assert_eq!(
        error("G10 L1 P2\nM2\n").kind.to_string(),
        "G10 L1 without offsets has no effect"
    );
    assert_eq!(
        error("G10 L1 P7 Z1\nM2\n").kind.to_string(),
        "Requested tool 7 not found in the tool table"
    );
    assert!(matches!(
        error("G10 L1 P1 X1\nM2\n").kind,
        ErrorKind::Unsupported { .. }
    ));
}

#[test]
fn state_parameters_follow_the_machine_state() {
    let p = read(
        "T1 M6\nG10 L2 P1 X10\nG0 X1 Y2\nG92 X0\nM3 M8\n\
         (PRINT,#5400 #5420 %.1f#<_abs_x> #<_x> #<_current_tool> #<_spindle_cw> #<_flood> #<_mist>)\nM2\n",
    );
    assert_eq!(
        p.warnings,
        vec!["t.ngc:6: print: 1.000000 0.000000 11.0 0.0 1.0 1.0 1.0 0.0"]
    );
}

/// Lines of loops and subroutines are compiled once and evaluated on each pass
/// (`softnc_gcode::compiled`): values change from pass to pass, and an error on a
/// later pass is the one the line's text gives, at its column.
#[test]
fn compiled_loop_lines_read_as_their_text() {
    let loop_text = "#<i> = 3\n\
        o1 while [#<i> GT -1]\n\
        G1 X[12 / #<i>] Y#<i> F100\n\
        #<i> = [#<i> - 1]\n\
        o1 endwhile\n\
        M2\n";
    let e = error(loop_text);
    // the fourth pass divides by zero: as the same line read once
    let once = error("#<i> = 0\n#<j> = 0\nG1 X[12 / #<i>] Y#<i> F100\nM2\n");
    assert_eq!((e.line, e.column), (3, once.column));
    assert_eq!(e.kind.to_string(), once.kind.to_string());
    assert!(e.kind.to_string().contains("divide by zero"), "{e}");
    // three passes before it, each with its own values
    let ok = loop_text.replace("GT -1", "GT 0");
    assert_eq!(xs(&ok), vec![4.0, 6.0, 12.0]);
    // a subroutine called with changing arguments, numbered parameters and labels
    let sub = "o<f> sub\n\
        G1 X[#1 * 2 + #2] F100\n\
        o<f> endsub\n\
        #1 = 7\n\
        o2 repeat [3]\n\
        o<f> call [#1] [ABS[#1 - 10]]\n\
        #1 = [#1 + 1]\n\
        o2 endrepeat\n\
        M2\n";
    assert_eq!(xs(sub), vec![17.0, 18.0, 19.0]);
}

/// A kept line (read again by a loop or a call) is found by its start and its end
/// remembered: line numbers, lines ended by CRLF or by the end of the text, and a
/// line sharing a loop's text read as when it was read once.
#[test]
fn kept_lines_read_again_as_read_once() {
    // the loop body's lines end in CRLF; the program's last line has no newline
    let text =
        "#1=0\r\no1 while [#1 LT 3]\r\nG0 X[#1*2]\r\n#1=[#1+1]\r\no1 endwhile\r\nG0 X9\r\nM2";
    assert_eq!(xs(text), vec![0.0, 2.0, 4.0, 9.0]);
    // a subroutine called from its own last line's neighbour, the last line of the
    // text (no newline) read on every pass
    let text = "o<s> sub\nG0 X#1\no<s> endsub\n#2=0\no2 while [#2 LT 2]\no<s> call [#2+5]\n#2=[#2+1]\no2 endwhile\nM2";
    assert_eq!(xs(text), vec![5.0, 6.0]);
    // an error on a later pass (the third: 10/0) names the line and column it has
    // when read once
    let e = error("#1=0\no1 while [#1 LT 5]\n#1=[#1+1]\nG0 X[10/[3-#1]]\no1 endwhile\nM2\n");
    let once = error("#1=3\nG0 X[10/[3-#1]]\nM2\n");
    assert_eq!((e.line, e.column, e.kind), (4, once.column, once.kind));
}

/// A kept line is compiled whole once read (its words, settings and comments; an
/// O-line's condition or arguments): later passes evaluate only its values, with
/// the same values, side effects and errors as its text gives.
#[test]
fn lines_compiled_whole_read_as_their_text() {
    // words, a named and a numbered setting, a comment expanded on every pass
    let text = "#<k>=3\no1 while [#<k> GT 0]\nG0 X[#<k>*2] Y#2 (PRINT,k=%d#<k>)\n\
                #<k>=[#<k>-1] #2=[#2+1]\no1 endwhile\nM2\n";
    assert_eq!(xs(text), vec![6.0, 4.0, 2.0]);
    let p = read(text);
    assert_eq!(
        p.warnings,
        vec![
            "t.ngc:3: print: k=3",
            "t.ngc:3: print: k=2",
            "t.ngc:3: print: k=1"
        ]
    );
    // a numbered setting whose index leaves the range on the third pass
    let e = error("#<k>=2\no1 while [#<k> GT -5]\n#<k>=[#<k>-1] #[#<k>]=1\no1 endwhile\nM2\n");
    let once = error("#<k>=0\n#<k>=[#<k>-1] #[#<k>]=1\nM2\n");
    assert_eq!((e.line, e.column), (3, once.column));
    assert_eq!(e.kind.to_string(), "Parameter number out of range");
    // a condition and a call argument dividing by zero on a later pass
    let e = error("#<k>=2\no1 while [10/#<k> GT -100]\n#<k>=[#<k>-1]\no1 endwhile\nM2\n");
    let once = error("#<k>=0\no1 while [10/#<k> GT -100]\no1 endwhile\nM2\n");
    assert_eq!((e.line, e.column, e.kind), (2, once.column, once.kind));
    let e = error(
        "o<s> sub\no<s> endsub\n#<k>=2\no1 while [#<k> GT -1]\no<s> call [1] [10/#<k>]\n\
         #<k>=[#<k>-1]\no1 endwhile\nM2\n",
    );
    let once = error("o<s> sub\no<s> endsub\n#<k>=0\no<s> call [1] [10/#<k>]\nM2\n");
    assert_eq!((e.line, e.column, e.kind), (5, once.column, once.kind));
    // a return value and a local label read in the subroutine that runs them
    let text = "o<s> sub\no1 if [#1 GT 1]\no<s> return [#1*10]\no1 endif\no<s> endsub [#1]\n\
                #<k>=0\no2 while [#<k> LT 4]\no<s> call [#<k>]\nG0 X#<_value>\n#<k>=[#<k>+1]\n\
                o2 endwhile\nM2\n";
    assert_eq!(xs(text), vec![0.0, 1.0, 20.0, 30.0]);
}

/// Call arguments beyond the first few, up to LinuxCNC's 30, reach `#1`…`#30` (the
/// missing ones 0, the caller's restored on return); a 31st is refused.
#[test]
fn call_arguments_up_to_thirty() {
    let args: String = (1..=30).map(|k| format!(" [{k}]")).collect();
    let text = format!(
        "o<s> sub\nG0 X#5 Y#30\nG0 X#6 Y#7\no<s> endsub\n#5=9\no<s> call [1] [2] [3] [4] [5] [6]\no<s> call{args}\nG0 X#5 Y0\nM2\n"
    );
    assert_eq!(xs(&text), vec![5.0, 6.0, 5.0, 6.0, 9.0]);
    let p = softnc_gcode::read_program(&text, "t.ngc", &profile()).unwrap();
    let ys: Vec<f64> = p
        .motions
        .iter()
        .filter_map(|m| m.kind.end().map(|e| e.0[1]))
        .collect();
    assert_eq!(ys, vec![0.0, 0.0, 30.0, 7.0, 0.0]);
    let e = error(&format!(
        "o<s> sub\no<s> endsub\no<s> call{args} [31]\nM2\n"
    ));
    assert_eq!(e.kind.to_string(), "Too many subroutine parameters");
    assert_eq!(e.line, 3);
}

/// XY of every motion end (mm).
fn xys(text: &str) -> Vec<(f64, f64)> {
    read(text)
        .motions
        .iter()
        .filter_map(|m| m.kind.end().map(|e| (e.0[0], e.0[1])))
        .collect()
}

#[test]
fn polar_coordinates_as_linuxcnc() {
    // LinuxCNC 2.9 `rs274 -g` on each program: the same points to its 4 decimals
    let near = |got: Vec<(f64, f64)>, want: &[(f64, f64)]| {
        assert_eq!(got.len(), want.len(), "{got:?}");
        for (g, w) in got.iter().zip(want) {
            assert!(
                (g.0 - w.0).abs() < 5e-5 && (g.1 - w.1).abs() < 5e-5,
                "{got:?} vs {want:?}"
            );
        }
    };
    // G90: @ from the origin, ^ in degrees from +X; the last of two @ counts
    near(xys("G0 X10\n@5 ^90\nM2\n"), &[(10.0, 0.0), (0.0, 5.0)]);
    near(xys("G0 X1\n@5 @6\nM2\n"), &[(1.0, 0.0), (6.0, 0.0)]);
    near(xys("G0 X1\n^5 ^6\nM2\n"), &[(1.0, 0.0), (0.9945, 0.1045)]);
    // one of the two: the other from the current point
    near(
        xys("G0 X10\nG1 @[2*3] ^-90 F100\n@-5\nM2\n"),
        &[(10.0, 0.0), (0.0, -6.0), (0.0, 5.0)],
    );
    // G91: the distance added, then the angle turned, each from the point before
    near(xys("G0 X1\nG91 @2 ^90\nM2\n"), &[(1.0, 0.0), (0.0, 3.0)]);
    near(
        xys("G0 X1 Y1\nG91 @1\nG91 ^45\nG90 ^0\nM2\n"),
        &[(1.0, 1.0), (1.7071, 1.7071), (0.0, 2.4142), (2.4142, 0.0)],
    );
    // arcs end there too (R and IJK); LinuxCNC 2.9 takes them in any plane
    near(
        xys("G0 X10\nG2 ^90 R10 F100\nM2\n"),
        &[(10.0, 0.0), (0.0, 10.0)],
    );
    near(
        xys("G0 X10 Y0\nG3 ^90 I-10 F100\nM2\n"),
        &[(10.0, 0.0), (0.0, 10.0)],
    );
    near(xys("G18 G0 @5 ^1\nM2\n"), &[(4.9992, 0.0873)]);
    for (text, msg) in [
        (
            "G0 X1\n@5 Y1\nM2\n",
            "Cannot specify both polar coordinate and Y word",
        ),
        (
            "G0 @5 X1\nM2\n",
            "Cannot specify both polar coordinate and X word",
        ),
        (
            "G0 @5\nM2\n",
            "Must specify angle in polar coordinate if at the origin",
        ),
        (
            "G91 G0 ^5\nM2\n",
            "G91 motion with polar coordinates is indeterminate when at the origin",
        ),
        (
            "G91 G0 @5\nM2\n",
            "Incremental motion with polar coordinates is indeterminate when at the origin",
        ),
        (
            "G53 G0 @5 ^0\nM2\n",
            "Cannot use polar coordinates with G53",
        ),
        (
            "G0 X3\nG28 @5\nM2\n",
            "Polar coordinates can only be used for motion",
        ),
        (
            "G92 @5\nM2\n",
            "Polar coordinates can only be used for motion",
        ),
        (
            "@5 ^3\nM2\n",
            "Cannot use axis values without a g code that uses them",
        ),
        ("G80 @1\nM2\n", "Cannot use axis values with g80"),
        (
            "G0 X10\nG18 G2 ^90 R10 F100\nM2\n",
            "X and z words missing for arc in xz plane",
        ),
    ] {
        assert_eq!(error(text).kind.to_string(), msg, "{text}");
    }
}

/// The differences a differential test against `rs274` found, each with its
/// minimal program; the expected values are what `rs274` printed.
#[test]
fn differences_once_found_against_rs274() {
    let debug = |text: &str| read(text).warnings;
    // #<_coord_system> of G59.1 is 591 (G59.2, G59.3: 592, 593)
    assert_eq!(
        debug("G59.1\n(DEBUG, #<_coord_system>)\nG59.3\n(DEBUG, #<_coord_system>)\nM2\n"),
        vec!["t.ngc:2: debug:  591.000000", "t.ngc:4: debug:  593.000000"]
    );
    // SIN in long double: SIN[30] is 0.5 exactly, so FIX[SIN[30] * 2] is 1
    assert_eq!(xs("#1 = FIX[SIN[30] * 2]\nG0 X#1\nM2\n"), vec![1.0]);
    // ROUND out of int's range: x86's integer indefinite, INT_MIN
    assert_eq!(
        debug("#1 = ROUND[3000000000]\n(DEBUG, #1)\n#2 = ROUND[-0.2]\n(DEBUG, #2)\nM2\n"),
        vec![
            "t.ngc:2: debug:  -2147483648.000000",
            "t.ngc:4: debug:  0.000000"
        ]
    );
    // a subroutine defined twice
    assert_eq!(
        error("o<s> sub\no<s> endsub\no<s> sub\no<s> endsub\nM2\n")
            .kind
            .to_string(),
        "redefining sub: o<s> already defined in line 1"
    );
    // a definition after a forward call to it, or inside a loop
    let e = error("o<s> call\no<s> sub\no<s> endsub\nM2\n");
    assert_eq!(
        (e.line, e.kind.to_string().as_str()),
        (2, "sub: o<s> found in illegal location")
    );
    let e =
        error("#1=0\no<l> while [#1 LT 2]\no<s> sub\no<s> endsub\n#1=[#1+1]\no<l> endwhile\nM2\n");
    assert_eq!(
        (e.line, e.kind.to_string().as_str()),
        (3, "sub: o<s> found in illegal location")
    );
    // #<_value> is set by every endsub/return read (also in a definition being
    // skipped) and not cleared by a call
    assert_eq!(
        debug("o<s> sub\n(DEBUG, v=#<_value> r=#<_value_returned>)\no<s> endsub [7]\no<s> call\no<s> call\nM2\n"),
        vec![
            "t.ngc:2: debug:  v=7.000000 r=1.000000",
            "t.ngc:2: debug:  v=7.000000 r=1.000000"
        ]
    );
    assert_eq!(
        debug("o<s> sub\no<s> endsub [5]\no<s> call\no<t> sub\no<t> return [2]\no<t> endsub\n(DEBUG, v=#<_value> r=#<_value_returned>)\nM2\n"),
        vec!["t.ngc:7: debug:  v=0.000000 r=0.000000"]
    );
    // a label being skipped to another leaves them alone
    assert_eq!(
        debug("o<s> sub\no<s> endsub [5]\no<i> if [0]\no<s> endsub [9]\no<i> endif\n(DEBUG, v=#<_value>)\nM2\n"),
        vec!["t.ngc:6: debug:  v=5.000000"]
    );
    // the N word and M98 are read on a line being skipped too
    let e = error("o<i> if [0]\nM98\no<i> endif\nM2\n");
    assert_eq!(
        (e.line, e.kind.to_string().as_str()),
        (2, "Found 'm98' code with no P-word")
    );
    let e = error("o<i> if [0]\nNX G0 X1\no<i> endif\nM2\n");
    assert_eq!(
        (e.line, e.kind.to_string().as_str()),
        (2, "Bad format unsigned integer")
    );
    // what LinuxCNC accepts there stays accepted
    assert_eq!(
        xs("o<i> if [0]\nN1.5 G0 X1\nG0 X[1/0]\n#1=[1/0]\no<i> endif\nG0 X2\nM2\n"),
        vec![2.0]
    );
}

#[test]
fn log_files_are_collected_with_a_log_folder_and_refused_without() {
    let with_logs = |text: &str| {
        let options = ReadOptions {
            log_files: true,
            ..Default::default()
        };
        softnc_gcode::read_program_with(text, "t.ngc", &profile(), &options).map(|(p, _)| p)
    };
    let p = with_logs(
        "#1=2.5\n(LOGAPPEND,a.txt)\n(LOG,x=#1)\n(logopen, b.txt )\n(log,in b)\n(LOGCLOSE)\n(LOG,nowhere)\nM2\n",
    )
    .unwrap();
    let files: Vec<(&str, bool, &str)> = p
        .log_files
        .iter()
        .map(|f| (f.name.as_str(), f.truncate, f.text.as_str()))
        .collect();
    assert_eq!(
        files,
        vec![("a.txt", false, "x=2.500000\n"), ("b.txt", true, "in b\n")]
    );
    for name in ["../up.txt", "/tmp/abs.txt", "sub/dir.txt", ".."] {
        let e = with_logs(&format!("G21\n(LOGOPEN,{name})\nM2\n")).unwrap_err();
        assert_eq!(e.line, 2, "{e}");
        assert!(e.kind.to_string().contains("plain file name"), "{e}");
    }
    // without a log folder: refused as unsupported, where it is
    let e = error("G21\n(LOGOPEN,a.txt)\nM2\n");
    assert!(
        matches!(e.kind, ErrorKind::Unsupported { .. }) && e.line == 2,
        "{e}"
    );
    // the reading writes nothing itself
    assert!(!std::path::Path::new("a.txt").exists());
}
