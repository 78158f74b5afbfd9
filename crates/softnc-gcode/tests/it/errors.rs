//! Every error kind: the message, its line and its column (1-based character of the
//! offending word), and for refused constructs the word "unsupported" and the word.

use softnc_core::MotionProfile;
use softnc_gcode::{read_program, ErrorKind, GcodeError};
use std::path::PathBuf;

fn profile() -> MotionProfile {
    MotionProfile::load(
        &PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../config/machines/default.ron"),
    )
    .unwrap()
}

fn err(text: &str) -> GcodeError {
    match read_program(text, "t.ngc", &profile()) {
        Ok(p) => panic!("accepted: {text:?} → {:?}", p.motions),
        Err(e) => e,
    }
}

/// (program, line, column, text the message contains)
const INVALID: &[(&str, u32, u32, &str)] = &[
    // a user M code without its executable (NCE_UNKNOWN_M_CODE_USED)
    ("M100\nM2\n", 1, 1, "Unknown M code used: M100"),
    // modal groups and repeated words
    (
        "G0 G1 X1\nM2\n",
        1,
        4,
        "Two g codes used from same modal group",
    ),
    (
        "G17 G18\nM2\n",
        1,
        5,
        "Two g codes used from same modal group",
    ),
    (
        "G20 G21\nM2\n",
        1,
        5,
        "Two g codes used from same modal group",
    ),
    (
        "M3 M4\nM2\n",
        1,
        4,
        "Two m codes used from same modal group",
    ),
    (
        "M7 M8\nM2\n",
        1,
        4,
        "Two m codes used from same modal group",
    ),
    ("G0 X1 X2\nM2\n", 1, 7, "Multiple x words on one line"),
    ("G4 P1 P2\nM2\n", 1, 7, "Multiple p words on one line"),
    (
        "M0 M3 M7 M5\nM2\n",
        1,
        10,
        "Two m codes used from same modal group",
    ),
    (
        "G21\nM3 M7 M0 M48 M6\nM2\n",
        2,
        14,
        "Too many m codes on line",
    ),
    // codes
    ("G12 X1\nM2\n", 1, 1, "Unknown g code used"),
    ("G9 G1 X1 F10\nM2\n", 1, 1, "Unknown g code used"),
    ("G1.001 X1\nM2\n", 1, 1, "G-code out of range"),
    ("G1000\nM2\n", 1, 1, "G-code out of range"),
    ("G-1\nM2\n", 1, 1, "Negative g code used"),
    ("M45\nM2\n", 1, 1, "Unknown m code used: M45"),
    ("M200\nM2\n", 1, 1, "M-code greater than 199: M200"),
    ("M-1\nM2\n", 1, 1, "Negative m code used"),
    ("M3.5\nM2\n", 1, 1, "Non integer value for integer"),
    // numbers and characters
    (
        "G0 X\nM2\n",
        1,
        4,
        "No characters found in reading real value",
    ),
    ("G0 X.\nM2\n", 1, 5, "Bad number format (conversion failed)"),
    (
        "G0 X1.2.3\nM2\n",
        1,
        5,
        "Bad number format (trailing characters)",
    ),
    ("G0 X-\nM2\n", 1, 5, "Bad number format (conversion failed)"),
    ("G0 X1 &\nM2\n", 1, 7, "Bad character '&' used"),
    ("G0 X1 N10\nM2\n", 1, 7, "Bad character 'n' used"),
    ("G0 X1\n%\nM2\n", 2, 1, "Bad character '%' used"),
    ("(é) G0 X1 é\nM2\n", 1, 11, "Bad character '\\303' used"),
    ("G0 X1 (open\nM2\n", 1, 7, "Unclosed comment found"),
    ("G0 X1 (a (b) c)\nM2\n", 1, 10, "Nested comment found"),
    (
        "G0 XY1\nM2\n",
        1,
        5,
        "Unknown word where unary operation could be",
    ),
    (
        "G0 X1 E2\nM2\n",
        1,
        7,
        "E word with no G70, G76, M66, M67 or M68 to use it",
    ),
    // words nothing uses
    (
        "X1\nM2\n",
        1,
        1,
        "Cannot use axis values without a g code that uses them",
    ),
    (
        "G0 X1\nG80\nX2\nM2\n",
        3,
        1,
        "Cannot use axis values without a g code that uses them",
    ),
    ("G80 X1\nM2\n", 1, 5, "Cannot use axis values with g80"),
    ("G0 X1 P2\nM2\n", 1, 7, "P word with no G2 G3 G4"),
    ("G0 X1 Q2\nM2\n", 1, 7, "Q word with no G5, G10, G64"),
    ("G0 X1 R2\nM2\n", 1, 7, "R word with no g code that uses it"),
    ("G0 X1 I2\nM2\n", 1, 7, "I word with no G2, G3"),
    ("G0 X1 K2\nM2\n", 1, 7, "K word with no G2, G3"),
    (
        "G0 X1 H1\nM2\n",
        1,
        7,
        "H word with no G43 or G76 to use it",
    ),
    ("G0 X1 L1\nM2\n", 1, 7, "L word with no G10"),
    ("G0 X1 D1\nM2\n", 1, 7, "D word with no G41"),
    // feeds
    ("G1 X1\nM2\n", 1, 1, "Cannot do g1 with zero feed rate"),
    ("G1 X1 F0\nM2\n", 1, 1, "Cannot do g1 with zero feed rate"),
    (
        "G1 X1 F100\nG94\nG1 X2\nM2\n",
        3,
        1,
        "Cannot do g1 with zero feed rate",
    ),
    (
        "G2 X1 Y1 I1\nM2\n",
        1,
        1,
        "Cannot make arc with zero feed rate",
    ),
    (
        "G93 G1 X1\nM2\n",
        1,
        5,
        "F word missing with inverse time g1 move",
    ),
    (
        "G93 G2 X2 I1 F1\nG2 X0 I-1\nM2\n",
        2,
        1,
        "F word missing with inverse time arc move",
    ),
    ("G1 X1 F-5\nM2\n", 1, 7, "Negative f word used"),
    ("M3 S-1\nM2\n", 1, 4, "Negative spindle speed used"),
    // arcs
    (
        "F100\nG2 X10 Y0 I4 J0\nM2\n",
        2,
        1,
        "Radius to end of arc differs from radius to start",
    ),
    (
        "F100\nG2 X10 Y0 R4\nM2\n",
        2,
        11,
        "Arc radius too small to reach end point",
    ),
    (
        "F100\nG2 X0 Y0 R4\nM2\n",
        2,
        10,
        "Current point same as end point of arc",
    ),
    (
        "F100\nG2 X10 Y0 R5 I5\nM2\n",
        2,
        11,
        "Mixed radius ijk format for arc",
    ),
    (
        "F100\nG2 X10 Y0\nM2\n",
        2,
        1,
        "R i j k words all missing for arc",
    ),
    (
        "F100\nG2 Z1 R5\nM2\n",
        2,
        1,
        "X and y words missing for arc in xy plane",
    ),
    (
        "F100\nG18 G2 Y1 R5\nM2\n",
        2,
        5,
        "X and z words missing for arc in xz plane",
    ),
    (
        "F100\nG19 G2 X1 R5\nM2\n",
        2,
        5,
        "Y and z words missing for arc in yz plane",
    ),
    (
        "F100\nG2 X10 I5 K1\nM2\n",
        2,
        11,
        "K word given for arc in xy plane",
    ),
    (
        "F100\nG18 G2 X10 I5 J1\nM2\n",
        2,
        15,
        "J word given for arc in xz plane",
    ),
    (
        "F100\nG19 G2 Y10 J5 I1\nM2\n",
        2,
        15,
        "I word given for arc in yz plane",
    ),
    (
        "F100 G90.1\nG2 X10 J0\nM2\n",
        2,
        1,
        "I word missing in absolute center arc",
    ),
    ("F100\nG2 X10 Y0 I0 J0\nM2\n", 2, 1, "Zero-radius arc"),
    (
        "F100\nG2 X10 I5 P0\nM2\n",
        2,
        11,
        "P value should be 1 or greater with G2 or G3",
    ),
    (
        "F100\nG2 X10 I5 P1.5\nM2\n",
        2,
        11,
        "P value not an integer with M19 G2 or G3",
    ),
    (
        "F100\nG4 G2 X10 I5 P1\nM2\n",
        2,
        1,
        "G4 not allowed with G2 or G3 because they both use P",
    ),
    // G4, G53, tools
    ("G4\nM2\n", 1, 1, "Dwell time missing with g4"),
    (
        "G53 X1\nM2\n",
        1,
        5,
        "Cannot use axis values without a g code that uses them",
    ),
    ("G91\nG53 G0 X1\nM2\n", 2, 1, "Cannot use g53 incremental"),
    (
        "F100\nG53 G2 X1 I1\nM2\n",
        2,
        1,
        "Must use g0 or g1 with g53",
    ),
    (
        "T4\nM2\n",
        1,
        1,
        "Requested tool 4 not found in the tool table",
    ),
    (
        "G43 H4\nM2\n",
        1,
        5,
        "Requested tool 4 not found in the tool table",
    ),
    ("G43 H1.5\nM2\n", 1, 5, "Non integer value for integer"),
    ("T-1\nM2\n", 1, 1, "Negative tool id"),
    (
        "M61\nM2\n",
        1,
        1,
        "Need non-negative Q-word to specify tool number with M61",
    ),
    (
        "G0 X1 (abort, operator stop)\nM2\n",
        1,
        7,
        "Program aborted:  operator stop",
    ),
    // program structure
    (
        "G0 X1\n",
        1,
        1,
        "File ended with no percent sign or program end",
    ),
    ("%\nG0 X1\n", 2, 1, "File ended with no percent sign"),
    ("%\nG0 X1\nM2\n%\n", 0, 0, "accepted: M2 ends the program"),
    ("\n  \n", 2, 1, "File ended with no percent sign"),
];

#[test]
fn invalid_programs_are_rejected_where_linuxcnc_rejects_them() {
    for &(text, line, column, msg) in INVALID {
        if line == 0 {
            assert!(read_program(text, "t.ngc", &profile()).is_ok(), "{msg}");
            continue;
        }
        let e = err(text);
        let shown = e.to_string();
        assert!(shown.contains(msg), "{text:?}: {shown}");
        assert_eq!((e.line, e.column), (line, column), "{text:?}: {shown}");
        assert!(
            shown.starts_with(&format!("t.ngc:{line}:{column}: ")),
            "{shown}"
        );
    }
}

#[test]
fn long_lines_are_too_long_as_in_linuxcnc() {
    let ok = format!("G0 X1 ({})\nM2\n", "a".repeat(244)); // 252 bytes and a newline
    assert!(read_program(&ok, "t.ngc", &profile()).is_ok());
    let long = format!("G0 X1 ({})\nM2\n", "a".repeat(245));
    let e = err(&long);
    assert_eq!(e.kind, ErrorKind::Invalid("Command too long".into()));
}

/// (program, line, column, the word named)
const UNSUPPORTED: &[(&str, u32, u32, &str)] = &[
    ("G0 X1\nG88 X1 Y1 Z-1 R1 P1\nM2\n", 2, 1, "G88"),
    ("G0 X1\nG76 P1 Z-5 I-0.1 J0.1 K0.5\nM2\n", 2, 1, "G76"),
    ("G0 X1\nM99\n", 2, 1, "M99"),
    ("#1=2\nG0 X#1 A#1\nM2\n", 2, 8, "A"),
    ("G0 X#<_feed_override>\nM2\n", 1, 5, "#<_feed_override>"),
    ("G0 A10\nM2\n", 1, 4, "A"),
    ("G0 X1 W2\nM2\n", 1, 7, "W"),
    ("G10 L1 P1 X0\nM2\n", 1, 1, "G10 L1"),
    ("G10 L2 P1 R45\nF9\nG19 G2 Y2 Z0 J1 K0\nM2\n", 3, 5, "G2"),
    ("G33 X1 K1\nM2\n", 1, 1, "G33"),
    ("G38.2 Z-1 F10\nM2\n", 1, 1, "G38.2"),
    ("G5.2 X1\nM2\n", 1, 1, "G5.2"),
    ("G7\nM2\n", 1, 1, "G7"),
    ("G95\nM2\n", 1, 1, "G95"),
    ("G43.1 X1\nM2\n", 1, 1, "G43.1"),
    ("M3 $1\nM2\n", 1, 4, "$1"),
    ("(py, x = 1)\nM2\n", 1, 1, "(py,"),
    (";py,x = 1\nM2\n", 1, 1, ";py,"),
];

#[test]
fn unsupported_constructs_are_refused_naming_the_word() {
    for &(text, line, column, word) in UNSUPPORTED {
        let e = err(text);
        let shown = e.to_string();
        match &e.kind {
            ErrorKind::Unsupported { word: w, .. } => assert_eq!(w, word, "{text:?}: {shown}"),
            k => panic!("{text:?}: not refused as unsupported: {k:?}"),
        }
        assert!(shown.contains("unsupported"), "{shown}");
        assert_eq!((e.line, e.column), (line, column), "{text:?}: {shown}");
    }
}
