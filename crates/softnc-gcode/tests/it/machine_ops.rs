//! Machine operations (issue 35): spindle, coolant, tools, messages, I/O, M66,
//! M19, user M codes and override switches as canonical items in program order,
//! checked against LinuxCNC's own canonical output (the interpreter tests'
//! `expected` files of `../shared/gcode`) and its errors.

use softnc_core::MotionProfile;
use softnc_gcode::CoolantLine;
use softnc_gcode::{
    read_program_with, ErrorKind, M66Results, MachineOp, MessageKind, MotionKind, Program,
    ReadOptions, SpindleTurn, WaitMode,
};
use std::path::PathBuf;

fn profile() -> MotionProfile {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../config/machines/default.ron");
    MotionProfile::load(&p).unwrap()
}

fn read_opts(text: &str, options: &ReadOptions) -> Result<Program, softnc_gcode::GcodeError> {
    read_program_with(text, "t.ngc", &profile(), options).map(|(p, _)| p)
}

fn read(text: &str) -> Program {
    read_opts(text, &ReadOptions::default()).unwrap_or_else(|e| panic!("{e}"))
}

/// (line, operation) of every machine operation.
fn ops(p: &Program) -> Vec<(u32, MachineOp)> {
    p.motions
        .iter()
        .filter_map(|m| match m.kind {
            MotionKind::Machine(op) => Some((m.line, op)),
            _ => None,
        })
        .collect()
}

fn cw(rpm: f64) -> MachineOp {
    MachineOp::SpindleOn {
        dir: SpindleTurn::Clockwise,
        rpm,
    }
}

fn mist(on: bool) -> MachineOp {
    MachineOp::Coolant {
        which: CoolantLine::Mist,
        on,
    }
}

fn flood(on: bool) -> MachineOp {
    MachineOp::Coolant {
        which: CoolantLine::Flood,
        on,
    }
}

fn dout(line: u8, on: bool, synchronised: bool) -> MachineOp {
    MachineOp::DigitalOut {
        line,
        on,
        synchronised,
    }
}

fn aout(line: u8, value: f64, synchronised: bool) -> MachineOp {
    MachineOp::AnalogOut {
        line,
        value,
        synchronised,
    }
}

#[test]
fn the_acceptance_job_reads_in_program_order() {
    let p = read(
        "G21 G90\nS8000 M3\nM8\nG1 X10 F600\nT2 M6\n(MSG, insert tool 2)\nM0\nM62 P1\n\
         G1 X20\nM66 P0 L3 Q2\nS9000 M3\nM64 P5\nM65 P5\nM67 E1 Q2.5\nM68 E2 Q-1\nM5 M9 M30\n",
    );
    let wait = MachineOp::WaitInput {
        input: softnc_gcode::WaitInput::Digital(0),
        mode: WaitMode::High,
        timeout_s: 2.0,
    };
    let msg = MachineOp::Message {
        index: 0,
        kind: MessageKind::Msg,
    };
    assert_eq!(
        ops(&p),
        vec![
            (2, cw(8000.0)),
            (3, flood(true)),
            (5, MachineOp::ToolPrepare { tool: 2 }),
            // LinuxCNC stops the spindle for the change
            (5, MachineOp::SpindleOff),
            (5, MachineOp::ToolChange { tool: 2 }),
            (6, msg),
            (8, dout(1, true, true)),
            (10, wait),
            (11, cw(9000.0)),
            (12, dout(5, true, false)),
            (13, dout(5, false, false)),
            (14, aout(1, 2.5, true)),
            (15, aout(2, -1.0, false)),
            (16, MachineOp::SpindleOff),
            // M9: mist off, then flood off
            (16, mist(false)),
            (16, flood(false)),
            // M30: no second spindle stop (M5 stopped it), coolant already off
        ]
    );
    assert_eq!(p.messages, vec![" insert tool 2".to_string()]);
    // stopping ones as LinuxCNC's task waits for motion; M62, M67, T go with it
    let stops: Vec<bool> = ops(&p).iter().map(|(_, o)| o.stops_motion()).collect();
    assert_eq!(
        stops,
        vec![
            true, true, false, true, true, true, false, true, true, true, true, false, true, true,
            true, true
        ]
    );
    // the M0 is where it was: on its own line
    assert!(p
        .motions
        .iter()
        .any(|m| m.line == 7 && matches!(m.kind, MotionKind::Pause { optional: false })));
}

#[test]
fn debug_and_print_substitute_parameters_and_m19_and_switches_read() {
    let p = read(
        "#<v> = 1.123456789\n(DEBUG, v = %f#<v>)\n(PRINT, p = %d#<v>)\n(LOG, not shown)\n\
         M19 R45 Q2 P1\nM48\nM50 P0\nM53\nM2\n",
    );
    assert_eq!(p.messages, vec![" v = 1.1235", " p = 1"]);
    let kinds: Vec<&str> = ops(&p).iter().map(|(_, o)| o.canon_name()).collect();
    assert_eq!(
        kinds,
        vec![
            "MESSAGE",
            "PRINT",
            "ORIENT_SPINDLE",
            "ENABLE_FEED_OVERRIDE",
            "DISABLE_FEED_OVERRIDE",
            "ENABLE_FEED_HOLD"
        ]
    );
    assert_eq!(
        ops(&p)[2].1,
        MachineOp::SpindleOrient {
            angle_deg: 45.0,
            direction: 1,
            timeout_s: 2.0
        }
    );
    // (DEBUG,) is silent while #5599 is 0, as LinuxCNC's
    let p = read("#5599 = 0\n(DEBUG, hidden)\nM2\n");
    assert!(p.messages.is_empty() && ops(&p).is_empty());
    // the program end stops a spindle that turns, and only then
    let p = read("S1000 M3\nG0 X1\nM2\n");
    assert_eq!(ops(&p), vec![(1, cw(1000.0)), (3, MachineOp::SpindleOff)]);
    let p = read("S1000 M3\nM5\nT1 M6\nM2\n");
    assert_eq!(
        ops(&p),
        vec![
            (1, cw(1000.0)),
            (2, MachineOp::SpindleOff),
            (3, MachineOp::ToolPrepare { tool: 1 }),
            (3, MachineOp::ToolChange { tool: 1 })
        ]
    );
}

#[test]
fn io_codes_are_checked_as_linuxcnc_checks_them() {
    for (text, col, want) in [
        ("M62\nM2\n", 1, "No valid P word with M62"),
        (
            "M66 P1 E1\nM2\n",
            1,
            "Invalid to select both a digital and an analog input with M66",
        ),
        (
            "M66 P1 L3\nM2\n",
            1,
            "Zero timeout with wait type != immediate return",
        ),
        (
            "M66 E1 L1 Q2\nM2\n",
            1,
            "Can't select analog input with wait type != immediate return",
        ),
        (
            "M66\nM2\n",
            1,
            "Need to have either a valid P or a valid E word with M66",
        ),
        ("M67 Q2\nM2\n", 1, "Invalid analog index with M67"),
        ("M19 P3\nM2\n", 5, "P value must be 0,1,or 2 with M19"),
        (
            "M19 R400\nM2\n",
            5,
            "R value must be within 0..360 with M19",
        ),
        ("G1 X1 F1 L2\nM2\n", 10, "L word with no G10"),
    ] {
        let e = read_opts(text, &ReadOptions::default()).unwrap_err();
        assert_eq!((e.line, e.column), (1, col), "{text:?}: {e}");
        assert!(e.to_string().contains(want), "{text:?}: {e}");
    }
}

#[test]
fn m66_results_are_refused_where_read_unless_the_stand_in_is_asked_for() {
    let text = "#5399 = 1\nM66 P0 L0\no1 if [#5399 LT 0]\nG0 X1\no1 endif\nM2\n";
    let e = read_opts(text, &ReadOptions::default()).unwrap_err();
    assert_eq!(e.line, 3, "{e}");
    assert!(
        matches!(&e.kind, ErrorKind::Unsupported { word, .. } if word == "#5399"),
        "{e}"
    );
    // rs274's stand-in: a digital input reads as (#5399 != 0)
    let stand_in = ReadOptions {
        m66_results: M66Results::StandIn,
        ..Default::default()
    };
    let (p, params) = read_program_with(text, "t.ngc", &profile(), &stand_in).unwrap();
    assert_eq!(params.get(5399), 1.0);
    assert!(p.motions.iter().all(|m| m.kind.end().is_none()));
    // a program that does not read it runs
    assert!(read_opts("M66 P0 L3 Q1\nG0 X1\nM2\n", &ReadOptions::default()).is_ok());
}

#[test]
fn m66_results_in_debug_and_print_are_filled_in_at_the_machine() {
    let text =
        "#5399 = 7\n(DEBUG, before %d#5399)\nM66 P0 L3 Q2\n(DEBUG, got #5399 then %.2f#5399)\n\
                (PRINT, p=%d#5399)\n(MSG, #5399 is not read in a message)\nG0 X1\nM2\n";
    let p = read(text);
    let shown = |i: usize, v: Option<f64>| {
        let mut s = String::new();
        softnc_gcode::write_message(&mut s, &p.messages[i], v).unwrap();
        s
    };
    // before the M66: the value at read time
    assert_eq!(shown(0, Some(1.0)), " before 7");
    assert!(!softnc_gcode::message_shows_m66_result(&p.messages[0]));
    // after it: the machine's value, with the comment's format, when reached
    assert!(softnc_gcode::message_shows_m66_result(&p.messages[1]));
    assert_eq!(shown(1, Some(1.0)), " got 1.000000 then 1.00");
    assert_eq!(shown(1, Some(-1.0)), " got -1.000000 then -1.00");
    assert_eq!(shown(1, None), " got #5399 then #5399");
    assert_eq!(shown(2, Some(0.0)), " p=0");
    // (MSG,…) is shown as written (LinuxCNC's convert_comment: MESSAGE, no
    // parameters), so it reads nothing
    assert_eq!(shown(3, Some(1.0)), " #5399 is not read in a message");
    // the check's output says the value comes from the machine
    assert!(
        p.warnings
            .iter()
            .any(|w| w.ends_with("debug:  got #5399 then #5399")),
        "{:?}",
        p.warnings
    );
}

#[test]
fn m66_results_deciding_motion_are_refused_at_the_5399_that_reads_them() {
    for (text, line, col) in [
        ("M66 P0 L3 Q2\nG0 X[#5399 + 1]\nM2\n", 2, 6),
        (
            "M66 P0 L3 Q2\no1 if [#5399 LT 0]\nG0 X1\no1 endif\nM2\n",
            2,
            8,
        ),
        ("M66 E0\n#1 = # 5399\nM2\n", 2, 6),
        (
            "M66 P0 L3 Q2\no2 while [#5399 EQ 0]\nM66 P0 L3 Q2\no2 endwhile\nM2\n",
            2,
            11,
        ),
    ] {
        let e = read_opts(text, &ReadOptions::default()).unwrap_err();
        assert_eq!((e.line, e.column), (line, col), "{text:?}: {e}");
        assert!(
            e.to_string().contains("the result of the M66 on line 1")
                && e.to_string().contains("(DEBUG,…)"),
            "{e}"
        );
    }
}

#[cfg(unix)]
#[test]
fn user_m_codes_run_from_their_folder_and_refuse_missing_ones_before_motion() {
    use std::os::unix::fs::PermissionsExt;
    let dir = std::env::temp_dir().join(format!("softnc-user-m-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let exe = dir.join("M101");
    std::fs::write(&exe, "#!/bin/sh\nexit 0\n").unwrap();
    std::fs::set_permissions(&exe, std::fs::Permissions::from_mode(0o755)).unwrap();
    let plain = dir.join("M102");
    std::fs::write(&plain, "not executable\n").unwrap();
    std::fs::set_permissions(&plain, std::fs::Permissions::from_mode(0o644)).unwrap();
    let options = ReadOptions {
        user_m_codes: Some(dir.clone()),
        ..Default::default()
    };
    let p = read_opts("G0 X1\nM101 P2 Q3\nM101\nM2\n", &options).unwrap();
    assert_eq!(
        ops(&p),
        vec![
            (
                2,
                MachineOp::UserM {
                    code: 101,
                    p: 2.0,
                    q: 3.0
                }
            ),
            (
                3,
                MachineOp::UserM {
                    code: 101,
                    p: -1.0,
                    q: -1.0
                }
            )
        ]
    );
    for (text, line, col) in [
        ("G0 X1\nM102\nM2\n", 2, 1),
        ("G0 X1\nG0 X2\nS1 M103\nM2\n", 3, 4),
    ] {
        let e = read_opts(text, &options).unwrap_err();
        assert_eq!(
            (e.file.as_str(), e.line, e.column),
            ("t.ngc", line, col),
            "{e}"
        );
        // LinuxCNC's NCE_UNKNOWN_M_CODE_USED, with why
        assert!(e.to_string().contains("Unknown M code used: M10"), "{e}");
        assert!(
            e.to_string().contains("is not an executable file")
                || e.to_string().contains("cannot be read"),
            "{e}"
        );
    }
    // without a folder every user M code is refused
    assert!(read_opts("M101\nM2\n", &ReadOptions::default()).is_err());
    std::fs::remove_dir_all(&dir).unwrap();
}

fn corpus() -> Option<PathBuf> {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/gcode");
    p.join("manifest.json").exists().then_some(p)
}

/// The canonical calls LinuxCNC's `expected` output shows for the operations
/// softnc emits one for as LinuxCNC does (spindle starts and stops — M5, before a
/// tool change, at the program end —, coolant on and off — M7, M8, M9, at the
/// program end —, messages, tool select and change, I/O), in order. The
/// implicit `STOP_SPINDLE_TURNING` of a spindle that does not turn (LinuxCNC's
/// before every `CHANGE_TOOL` and at every program end, `SET_SPINDLE_MODE` and
/// `PROGRAM_END` after it) is left out: softnc emits none
/// (`crate::rs274_calls`); an explicit M5's stays.
fn expected_calls(text: &str) -> Vec<String> {
    let calls: Vec<String> = text
        .lines()
        .filter_map(|l| l.split_once("N..... ").map(|(_, c)| c.trim().to_string()))
        .collect();
    let all: Vec<&str> = calls.iter().map(String::as_str).collect();
    let mut turning = false;
    let mut kept = Vec::new();
    for (i, c) in calls.iter().enumerate() {
        let was_turning = turning;
        turning = crate::rs274_calls::turning_after(c, turning);
        if !NAMES.iter().any(|n| c.starts_with(n))
            || crate::rs274_calls::is_implicit_stop_softnc_leaves_out(&all, i, was_turning)
        {
            continue;
        }
        kept.push(match c.split_once('(') {
            Some(("MESSAGE", _)) | Some(("SELECT_TOOL", _)) => c.clone(),
            Some((name, _)) => name.to_string(),
            None => c.clone(),
        });
    }
    kept
}

/// The calls [`expected_calls`] compares.
const NAMES: [&str; 16] = [
    "START_SPINDLE_CLOCKWISE(",
    "START_SPINDLE_COUNTERCLOCKWISE(",
    "STOP_SPINDLE_TURNING(",
    "MIST_ON(",
    "MIST_OFF(",
    "FLOOD_ON(",
    "FLOOD_OFF(",
    "MESSAGE(",
    "SELECT_TOOL(",
    "CHANGE_TOOL(",
    "SET_MOTION_OUTPUT_BIT(",
    "CLEAR_MOTION_OUTPUT_BIT(",
    "SET_AUX_OUTPUT_BIT(",
    "CLEAR_AUX_OUTPUT_BIT(",
    "SET_MOTION_OUTPUT_VALUE(",
    "SET_AUX_OUTPUT_VALUE(",
];

/// Ours, printed the same way.
fn our_calls(p: &Program) -> Vec<String> {
    ops(p)
        .iter()
        .filter_map(|(_, op)| match *op {
            MachineOp::Message {
                index,
                kind: MessageKind::Msg | MessageKind::Debug,
            } => Some(format!("MESSAGE(\"{}\")", p.messages[index as usize])),
            MachineOp::ToolPrepare { tool } => Some(format!("SELECT_TOOL({tool})")),
            MachineOp::SpindleOn { .. }
            | MachineOp::SpindleOff
            | MachineOp::Coolant { .. }
            | MachineOp::ToolChange { .. }
            | MachineOp::DigitalOut { .. }
            | MachineOp::AnalogOut { .. } => Some(op.canon_name().to_string()),
            _ => None,
        })
        .collect()
}

/// Every interpreter test LinuxCNC accepts and softnc reads (without options
/// softnc has no flag for) makes the same spindle, coolant, message, tool and I/O
/// calls in the same order as LinuxCNC's `expected` output, the program end's
/// included.
#[test]
fn machine_calls_are_linuxcncs_in_its_interpreter_tests() {
    let Some(root) = corpus() else {
        eprintln!("SKIPPED: ../shared/gcode is not beside the repository");
        return;
    };
    let manifest: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(root.join("manifest.json")).unwrap())
            .unwrap();
    let (mut compared, mut calls) = (0, 0);
    for e in manifest.as_array().unwrap() {
        let file = e["file"].as_str().unwrap();
        if !file.starts_with("linuxcnc-interp-tests/")
            || e["rs274_accepts"] != serde_json::Value::Bool(true)
            || e.get("rs274_options").is_some()
        {
            continue;
        }
        let path = root.join(file);
        let dir = path.parent().unwrap();
        let Ok(expected) = std::fs::read_to_string(dir.join("expected")) else {
            continue;
        };
        let ngcs = std::fs::read_dir(dir)
            .unwrap()
            .filter(|f| {
                f.as_ref()
                    .is_ok_and(|f| f.path().extension().is_some_and(|x| x == "ngc"))
            })
            .count();
        if ngcs != 1 {
            continue;
        }
        let text = String::from_utf8_lossy(&std::fs::read(&path).unwrap()).into_owned();
        let options = ReadOptions {
            m66_results: M66Results::StandIn,
            subroutine_path: vec![dir.to_path_buf()],
            ..Default::default()
        };
        let Ok((p, _)) = read_program_with(&text, file, &profile(), &options) else {
            continue;
        };
        let want = expected_calls(&expected);
        // (LinuxCNC's `test.sh` prints through `awk '{$1=""; print}'`, which
        // joins the words of a line with one space)
        let ours: Vec<String> = our_calls(&p)
            .iter()
            .map(|c| c.split_whitespace().collect::<Vec<_>>().join(" "))
            .collect();
        let want: Vec<String> = want
            .iter()
            .map(|c| c.split_whitespace().collect::<Vec<_>>().join(" "))
            .collect();
        assert_eq!(ours, want, "{file}");
        compared += 1;
        calls += want.len();
    }
    // (29 programs, 116 calls when this was written)
    assert!(
        compared >= 29 && calls >= 116,
        "{compared} programs, {calls} calls"
    );
    eprintln!("{compared} programs, {calls} machine calls as LinuxCNC's");
}

/// Run from line: the operations before the start block are left out with its
/// motions, and the spindle and coolant the modal state has there are switched on
/// during the approach, before its last traverse.
#[test]
fn run_from_line_switches_the_spindle_and_coolant_on_before_the_last_approach() {
    let text = "G21\nS5000 M4\nM8\nG1 X10 F600\nG1 X20\nG1 X30\nM2\n";
    let options = ReadOptions {
        from_line: Some(5),
        ..Default::default()
    };
    let p = read_opts(text, &options).unwrap();
    let kinds: Vec<String> = p
        .motions
        .iter()
        .map(|m| match m.kind {
            MotionKind::Machine(op) => op.canon_name().to_string(),
            MotionKind::Traverse { .. } => "traverse".into(),
            MotionKind::Feed { .. } => "feed".into(),
            MotionKind::Sync => "sync".into(),
            _ => "other".into(),
        })
        .collect();
    assert_eq!(
        kinds,
        vec![
            "START_SPINDLE_COUNTERCLOCKWISE",
            "FLOOD_ON",
            "traverse",
            "sync",
            "feed",
            "feed",
            // M2
            "STOP_SPINDLE_TURNING",
            "FLOOD_OFF"
        ]
    );
    assert_eq!(
        ops(&p)[0].1,
        MachineOp::SpindleOn {
            dir: SpindleTurn::CounterClockwise,
            rpm: 5000.0
        }
    );
}
