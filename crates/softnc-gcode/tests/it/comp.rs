//! Cutter radius compensation (G40, G41, G42, G41.1, G42.1) against LinuxCNC's
//! own: each program of `tests/golden/comp/*.ngc` with the canonical calls `rs274`
//! (LinuxCNC 2.9, its sample tool table) printed for it (`*.rs274`, made by
//! `regen.sh` there; CI needs no `rs274`). softnc's reading must make the same
//! sequence of motions — straight ends, and arcs with their ends, centres and turns
//! in the plane's order, to `rs274`'s four decimals — with what LinuxCNC holds back
//! behind the held moves (dwells, spindle, coolant) and what it hands on at once
//! (tool selection and change, messages) in the same places. Each program of
//! `tests/golden/comp/errors/` stops with `rs274`'s message (`*.err`: the message,
//! then the text of the line it stopped at) at that line.

use softnc_core::MotionProfile;
use softnc_gcode::{MachineOp, MotionKind, Program, ReadOptions};
use std::path::{Path, PathBuf};

fn dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/golden/comp")
}

/// The checkout's default profile with rs274's tool table to the bit: its sample
/// `tool.tbl` holds inches, which rs274 turns into mm by dividing by its
/// `GET_EXTERNAL_LENGTH_UNITS()` of 0.03937007874016 (a radius of T2 is then a
/// hair under 0.79375 mm, which decides how a point half way between two printed
/// decimals prints).
fn profile() -> MotionProfile {
    let mut p = MotionProfile::load(
        &PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../config/machines/default.ron"),
    )
    .unwrap();
    const PER_MM: f64 = 0.03937007874016;
    for (number, diameter_in, length_in) in [
        (1, 0.125, 0.511),
        (2, 0.0625, 0.1),
        (3, 0.201, 1.273),
        (99999, 0.0, 0.1),
    ] {
        let t = p.tools.iter_mut().find(|t| t.number == number).unwrap();
        t.diameter_mm = diameter_in / PER_MM;
        t.length_mm = length_in / PER_MM;
    }
    p
}

/// The numbers between the parentheses of a canonical call.
fn args(line: &str) -> Vec<&str> {
    let inner = &line[line.find('(').unwrap() + 1..line.rfind(')').unwrap()];
    inner.split(',').map(str::trim).collect()
}

/// `rs274`'s output as the events compared: motions (an arc with its first and
/// second end, centre, turns and the normal axis' end), dwells, the spindle on
/// (started, or its speed changed while it turns) and off, coolant, tool selection
/// and change, messages, program stops.
pub fn expected(rs274: &str) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    let lines: Vec<&str> = rs274.lines().collect();
    let mut spindle_on = false;
    for (k, line) in lines.iter().enumerate() {
        if crate::rs274_calls::is_implicit_stop_softnc_leaves_out(&lines, k, spindle_on) {
            continue;
        }
        let name = &line[..line.find('(').unwrap_or(line.len())];
        let ev = match name {
            "STRAIGHT_TRAVERSE" | "STRAIGHT_FEED" => {
                let a = args(line);
                format!("{name}({}, {}, {})", a[0], a[1], a[2])
            }
            "ARC_FEED" => {
                let a = args(line);
                format!("ARC_FEED({})", a[..6].join(", "))
            }
            "DWELL" => line.to_string(),
            "START_SPINDLE_CLOCKWISE" | "START_SPINDLE_COUNTERCLOCKWISE" => {
                spindle_on = true;
                "SPINDLE_ON".into()
            }
            "SET_SPINDLE_SPEED" => {
                let next = lines.get(k + 1).copied().unwrap_or("");
                if !spindle_on || next.starts_with("START_SPINDLE") {
                    continue;
                }
                "SPINDLE_ON".into()
            }
            "STOP_SPINDLE_TURNING" => {
                spindle_on = false;
                "SPINDLE_OFF".into()
            }
            "MIST_ON" | "MIST_OFF" | "FLOOD_ON" | "FLOOD_OFF" => {
                if out.last().map(String::as_str) == Some("COOLANT") {
                    continue;
                }
                "COOLANT".into()
            }
            "SELECT_TOOL" => line.to_string(),
            "CHANGE_TOOL" => line.to_string(),
            "MESSAGE" => "MESSAGE".into(),
            "PROGRAM_STOP" => name.to_string(),
            _ => continue,
        };
        out.push(ev);
    }
    out.into_iter()
        .map(|l| l.replace("-0.0000", "0.0000"))
        .collect()
}

/// softnc's reading as the same events.
pub fn ours(p: &Program) -> Vec<String> {
    let mut out = Vec::new();
    for m in &p.motions {
        let e = m.canon_end;
        let ev = match m.kind {
            MotionKind::Traverse { .. } => {
                format!("STRAIGHT_TRAVERSE({:.4}, {:.4}, {:.4})", e[0], e[1], e[2])
            }
            MotionKind::Feed { .. } => {
                format!("STRAIGHT_FEED({:.4}, {:.4}, {:.4})", e[0], e[1], e[2])
            }
            MotionKind::Arc { plane, turns, .. } => {
                let c = m.canon_center;
                let (a, b, n) = plane.axes();
                format!(
                    "ARC_FEED({:.4}, {:.4}, {:.4}, {:.4}, {turns}, {:.4})",
                    e[a], e[b], c[a], c[b], e[n]
                )
            }
            MotionKind::Dwell { seconds } => format!("DWELL({seconds:.4})"),
            MotionKind::Pause { optional: false } => "PROGRAM_STOP".into(),
            MotionKind::Pause { optional: true } => "OPTIONAL_PROGRAM_STOP".into(),
            MotionKind::Sync => "SYNC".into(),
            MotionKind::Probe { .. } => "STRAIGHT_PROBE".into(),
            MotionKind::Machine(op) => match op {
                MachineOp::SpindleOn { .. } => "SPINDLE_ON".into(),
                MachineOp::SpindleOff => "SPINDLE_OFF".into(),
                // (M9's two calls as one, as `expected` takes them)
                MachineOp::Coolant { .. } if out.last().map(String::as_str) == Some("COOLANT") => {
                    continue
                }
                MachineOp::Coolant { .. } => "COOLANT".into(),
                MachineOp::ToolPrepare { tool } => format!("SELECT_TOOL({tool})"),
                MachineOp::ToolChange { tool } => format!("CHANGE_TOOL({tool})"),
                MachineOp::Message { .. } => "MESSAGE".into(),
                _ => continue,
            },
        };
        out.push(ev.replace("-0.0000", "0.0000"));
    }
    out
}

fn read(text: &str) -> Result<Program, softnc_gcode::GcodeError> {
    softnc_gcode::read_program_with(text, "t.ngc", &profile(), &ReadOptions::default())
        .map(|(p, _)| p)
}

/// The files of `dir` ending in `.ngc`, sorted.
fn programs(dir: &Path) -> Vec<PathBuf> {
    let mut names: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .filter_map(|e| {
            let p = e.unwrap().path();
            (p.extension()? == "ngc").then_some(p)
        })
        .collect();
    names.sort();
    names
}

#[test]
fn compensated_programs_read_as_rs274_reads_them() {
    let names = programs(&dir());
    assert!(names.len() >= 7, "{names:?}");
    let (mut events, mut arcs) = (0, 0);
    for path in names {
        let text = std::fs::read_to_string(&path).unwrap();
        let want = expected(&std::fs::read_to_string(path.with_extension("rs274")).unwrap());
        let program = read(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let got = ours(&program);
        for (k, (g, w)) in got.iter().zip(&want).enumerate() {
            assert_eq!(g, w, "{}: event {k}", path.display());
        }
        assert_eq!(got.len(), want.len(), "{}: {got:#?}", path.display());
        events += got.len();
        arcs += got.iter().filter(|e| e.starts_with("ARC")).count();
        // the motions join: each starts where the one before ended
        let mut at: Option<softnc_core::Vec3> = None;
        for m in &program.motions {
            if let Some(end) = m.kind.end() {
                if let Some(a) = at {
                    let gap = (m.start + m.offset_mm - a).norm();
                    assert!(gap < 1e-9, "{}: line {}: gap {gap}", path.display(), m.line);
                }
                at = Some(end + m.offset_mm);
            }
        }
    }
    assert!(events > 150 && arcs > 40, "{events} events, {arcs} arcs");
}

#[test]
fn compensation_errors_are_rs274s_at_its_line() {
    let names = programs(&dir().join("errors"));
    assert!(names.len() >= 30, "{names:?}");
    for path in names {
        let text = std::fs::read_to_string(&path).unwrap();
        let err_text = std::fs::read_to_string(path.with_extension("err")).unwrap();
        let mut err_lines = err_text.lines();
        let (msg, at) = (err_lines.next().unwrap(), err_lines.next().unwrap());
        let line = text.lines().position(|l| l == at).unwrap() as u32 + 1;
        let err = match read(&text) {
            Ok(_) => panic!("{}: read, rs274 says {msg:?}", path.display()),
            Err(e) => e,
        };
        assert!(
            err.to_string().contains(msg),
            "{}: {err} (rs274: {msg:?})",
            path.display()
        );
        assert_eq!(err.line, line, "{}: {err}", path.display());
    }
}

/// A program ending with `%` while moves are held: rs274 never hands them on,
/// and neither does softnc, which warns.
#[test]
fn moves_held_at_a_percent_end_are_dropped_with_a_warning() {
    let text = "%\nG21 F300\nG0 X-10 Y-10\nG41 D1\nG1 X0 Y0\nG1 X20\nG1 Y20\n%\n";
    let p = read(text).unwrap();
    let ends: Vec<[f64; 3]> = p
        .motions
        .iter()
        .filter_map(|m| m.kind.end().map(|_| m.canon_end.0))
        .collect();
    // the traverse, the entry, the corner arc, the line to X20 (Y20 held)
    assert_eq!(ends.len(), 4, "{ends:?}");
    assert!((ends[3][0] - 18.4125).abs() < 1e-4, "{ends:?}");
    assert!(
        p.warnings
            .iter()
            .any(|w| w.contains("cutter radius compensation on") && w.contains("left out")),
        "{:?}",
        p.warnings
    );
}

/// The modal state: `#<_ccomp>` reads the side, M70/M72 restore it, and the
/// state handed to the next job never carries compensation.
#[test]
fn compensation_state_as_linuxcnc_reports_it() {
    let p = read(
        "G21 F300\nG0 X-10 Y-10\nG42 D1\n#1 = #<_ccomp>\nG1 X0 Y0\nG1 X20\n\
         G40 G1 X30\n#2 = #<_ccomp>\nG0 X#1 Y#2\nM2\n",
    )
    .unwrap();
    assert_eq!(p.motions.last().unwrap().canon_end.0[..2], [420.0, 400.0]);
    let p = read("%\nG21 F300\nG0 X-10 Y-10\nG41 D1\nG1 X0 Y0\nG1 X20\n%\n").unwrap();
    assert!(p.end_modal.contains("G40"), "{}", p.end_modal);
    assert!(!p.end_modal.contains("G41"), "{}", p.end_modal);
}

/// Read in chunks (as the daemon streams a job), a compensated program hands on the
/// same motions as read whole: the held moves go out when their corner is known,
/// whatever the chunk boundaries.
#[test]
fn compensated_programs_read_in_chunks_as_whole() {
    let profile = profile();
    for path in programs(&dir()) {
        let text = std::fs::read_to_string(&path).unwrap();
        let whole = read(&text).unwrap();
        for chunk in [1, 2, 3, 7] {
            let mut got = Vec::new();
            softnc_gcode::read_program_chunked(&text, "t.ngc", &profile, chunk, &mut |c| {
                got.append(c)
            })
            .unwrap();
            assert_eq!(
                got,
                whole.motions,
                "{} in chunks of {chunk}",
                path.display()
            );
        }
    }
}
