//! Program flow: M0/M1 as canonical pauses (LinuxCNC's `convert_stop`), the
//! block-delete switch (`read_text`), run from line (LinuxCNC task's run-from-line,
//! with a safe approach), and parameters in and out (the persistent parameters).

use softnc_core::{MotionProfile, Vec3};
use softnc_gcode::{GcodeError, MotionKind, Params, PathMode, Program, ReadOptions};
use std::path::PathBuf;

fn profile() -> MotionProfile {
    MotionProfile::load(
        &PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../config/machines/default.ron"),
    )
    .unwrap()
}

fn read(text: &str, options: &ReadOptions) -> Result<(Program, Params), GcodeError> {
    softnc_gcode::read_program_with(text, "t.ngc", &profile(), options)
}

/// Kind names of the motions, with their lines.
fn kinds(p: &Program) -> Vec<(u32, &'static str)> {
    p.motions
        .iter()
        .map(|m| {
            let k = match m.kind {
                MotionKind::Traverse { .. } => "traverse",
                MotionKind::Feed { .. } => "feed",
                MotionKind::Arc { .. } => "arc",
                MotionKind::Dwell { .. } => "dwell",
                MotionKind::Pause { optional: false } => "M0",
                MotionKind::Pause { optional: true } => "M1",
                MotionKind::Sync => "sync",
                MotionKind::Probe { .. } => "probe",
                MotionKind::Machine(_) => "machine",
            };
            (m.line, k)
        })
        .collect()
}

/// Machine position of every move's end (mm).
fn machine_ends(p: &Program) -> Vec<Vec3> {
    p.motions
        .iter()
        .filter_map(|m| m.kind.end().map(|e| e + m.offset_mm))
        .collect()
}

fn close(a: Vec3, b: Vec3) -> bool {
    (a - b).norm() < 1e-9
}

#[test]
fn m0_pauses_after_its_line_and_m1_only_with_the_switch() {
    let text = "G0 X1\nG1 X2 F100 M0\nM1\nG0 X3\nM2\n";
    let (p, _) = read(text, &ReadOptions::default()).unwrap();
    assert_eq!(
        kinds(&p),
        vec![(1, "traverse"), (2, "feed"), (2, "M0"), (4, "traverse")]
    );
    // the pause stands where the line's motion ended, and prints nothing as a move
    let pause = &p.motions[2];
    assert!(close(pause.start, Vec3::new(2.0, 0.0, 0.0)));
    assert_eq!(pause.canon_view(), (None, None));
    assert_eq!(pause.kind.end(), None);
    let on = ReadOptions {
        optional_stop: true,
        ..Default::default()
    };
    let (p, _) = read(text, &on).unwrap();
    assert_eq!(
        kinds(&p),
        vec![
            (1, "traverse"),
            (2, "feed"),
            (2, "M0"),
            (3, "M1"),
            (4, "traverse")
        ]
    );
}

#[test]
fn block_delete_skips_slash_lines_only_when_on() {
    // the assignment, the move and the bad line on `/` lines; a `/` after blanks
    let text = "#1=1\n/#1=5\nG0 X#1\n  /G0 X7\n/G0 X1 X2\nG0 X2\nM2\n";
    let off = read(text, &ReadOptions::default()).unwrap_err();
    assert_eq!(off.line, 5, "{off}");
    let on = ReadOptions {
        block_delete: true,
        ..Default::default()
    };
    let (p, _) = read(text, &on).unwrap();
    let xs: Vec<f64> = machine_ends(&p).iter().map(|e| e.0[0]).collect();
    assert_eq!(xs, vec![1.0, 2.0]);
    // off, a `/` line runs (rs274's default, the corpus' reading)
    let (p, _) = read("/G0 X4\nM2\n", &ReadOptions::default()).unwrap();
    assert_eq!(machine_ends(&p), vec![Vec3::new(4.0, 0.0, 0.0)]);
    // a deleted M2 does not end the program
    let (p, _) = read("G0 X1\n/M2\nG0 X3\nM2\n", &on).unwrap();
    assert_eq!(machine_ends(&p).len(), 2);
}

const PART: &str = "G21 G90\n\
G10 L2 P1 X100\n\
G0 Z5\n\
G0 X10 Y10\n\
G1 Z-1 F300\n\
G1 X20\n\
G1 Y20\n\
M2\n";

#[test]
fn run_from_line_recovers_the_state_and_approaches_z_first() {
    // the machine stands at (3, 4, 20): Z is already above the start point
    let options = ReadOptions {
        from_line: Some(6),
        start_mm: Some(Vec3::new(3.0, 4.0, 20.0)),
        ..Default::default()
    };
    let (p, _) = read(PART, &options).unwrap();
    assert_eq!(
        kinds(&p),
        vec![
            (6, "traverse"),
            (6, "traverse"),
            (6, "sync"),
            (6, "feed"),
            (7, "feed")
        ]
    );
    // G54 X100 from line 2 is in force: the start point is machine (110, 10, -1)
    assert_eq!(
        machine_ends(&p),
        vec![
            Vec3::new(110.0, 10.0, 20.0),
            Vec3::new(110.0, 10.0, -1.0),
            Vec3::new(120.0, 10.0, -1.0),
            Vec3::new(120.0, 20.0, -1.0),
        ]
    );
    let first = &p.motions[0];
    assert!(close(
        first.start + first.offset_mm,
        Vec3::new(3.0, 4.0, 20.0)
    ));
    assert!(p.motions[..2]
        .iter()
        .all(|m| m.path_mode == PathMode::ExactStop));
    // the modal feed of line 5 is recovered
    assert!(
        matches!(p.motions[3].kind, MotionKind::Feed { feed_mm_per_min, .. } if feed_mm_per_min == 300.0)
    );
    // each motion starts where the one before ended
    for w in p.motions.windows(2) {
        let end = w[0].kind.end().unwrap_or(w[0].start) + w[0].offset_mm;
        assert!(close(end, w[1].start + w[1].offset_mm), "{w:?}");
    }

    // the machine below the start point: Z up to the start's Z first, no Z down
    let low = ReadOptions {
        start_mm: Some(Vec3::new(0.0, 0.0, -30.0)),
        ..options.clone()
    };
    let (p, _) = read(PART, &low).unwrap();
    assert_eq!(
        machine_ends(&p)[..2],
        [Vec3::new(0.0, 0.0, -1.0), Vec3::new(110.0, 10.0, -1.0)]
    );
    // already there: no approach move, only the sync
    let there = ReadOptions {
        start_mm: Some(Vec3::new(110.0, 10.0, -1.0)),
        ..options
    };
    let (p, _) = read(PART, &there).unwrap();
    assert_eq!(kinds(&p)[..2], [(6, "sync"), (6, "feed")]);
}

#[test]
fn run_from_line_after_a_loop_and_on_a_blank_line() {
    let text = "#1=0\n\
o1 while [#1 LT 3]\n\
G0 X#1\n\
#1=[#1+1]\n\
o1 endwhile\n\
\n\
G0 X10\n\
M2\n";
    let options = |n| ReadOptions {
        from_line: Some(n),
        ..Default::default()
    };
    // from line 6 (blank): the loop ran, the point is X2
    let (p, _) = read(text, &options(6)).unwrap();
    assert_eq!(
        machine_ends(&p),
        vec![Vec3::new(2.0, 0.0, 0.0), Vec3::new(10.0, 0.0, 0.0)]
    );
    // from line 3, inside the loop's body: from its first pass on
    let (p, _) = read(text, &options(3)).unwrap();
    let xs: Vec<f64> = machine_ends(&p).iter().map(|e| e.0[0]).collect();
    assert_eq!(xs, vec![0.0, 1.0, 2.0, 10.0]);
}

#[test]
fn run_from_line_refusals_name_the_line() {
    let options = |n| ReadOptions {
        from_line: Some(n),
        ..Default::default()
    };
    let sub = "o<s> sub\nG0 X1\no<s> endsub\nG0 Y1\no<s> call\nM2\n";
    let e = read(sub, &options(2)).unwrap_err();
    assert!(
        e.to_string().starts_with(
            "t.ngc:2:1: cannot run from line 2: it lies in the definition of subroutine"
        ),
        "{e}"
    );
    // after the definition it runs
    assert!(read(sub, &options(4)).is_ok());
    let e = read("G0 X1\nM2\n", &options(9)).unwrap_err();
    assert_eq!(
        e.to_string(),
        "t.ngc:9:1: cannot run from line 9: no block at or after line 9 runs"
    );
    let e = read("G0 X1\nM2\n", &options(2)).unwrap_err();
    assert_eq!(
        e.to_string(),
        "t.ngc:2:1: cannot run from line 2: no motion follows it"
    );
    // an error before line N is still the program's error
    let e = read("G0 X1 X2\nG0 X3\nM2\n", &options(2)).unwrap_err();
    assert_eq!(e.line, 1);
    // inside a compensated stretch (or before its exit move) the moves held for
    // the corner before the start were never cut: refused; after it, it runs
    let comp = "G21 F300\nG0 X-10 Y-10\nG41 D1\nG1 X0 Y0\nG1 X20\nG1 Y20\nG40 G1 X30\nG1 Y30\nM2\n";
    for n in [5, 6, 7] {
        let e = read(comp, &options(n)).unwrap_err();
        assert!(
            e.to_string().starts_with(&format!(
                "t.ngc:{n}:1: cannot run from line {n}: cutter radius compensation is on"
            )),
            "{e}"
        );
    }
    let (p, _) = read(comp, &options(8)).unwrap();
    assert_eq!(p.motions.last().unwrap().canon_end.0[..2], [30.0, 30.0]);
}

#[test]
fn parameter_5220_selects_the_coordinate_system_at_start() {
    let mut params = Params::default();
    params.set(5220, 2.0); // G55
    params.set(5241, 12.5); // G55 X
    let options = ReadOptions {
        params: Some(params),
        ..Default::default()
    };
    let (p, end) = read("G0 X0\nM2\n", &options).unwrap();
    assert_eq!(machine_ends(&p), vec![Vec3::new(12.5, 0.0, 0.0)]);
    // M2 selects G54 again (convert_stop)
    assert_eq!(end.get(5220), 1.0);
}

#[test]
fn touch_off_persists_through_the_end_parameters() {
    // the machine at X 12.5; G10 L20 P2 X0 makes that G55's X0
    let first = ReadOptions {
        start_mm: Some(Vec3::new(12.5, 0.0, 0.0)),
        ..Default::default()
    };
    let (_, end) = read("G10 L20 P2 X0\nM2\n", &first).unwrap();
    assert_eq!(end.get(5241), 12.5);
    let second = ReadOptions {
        params: Some(end),
        ..Default::default()
    };
    let (p, _) = read("G55 G0 X0\nM2\n", &second).unwrap();
    assert_eq!(machine_ends(&p), vec![Vec3::new(12.5, 0.0, 0.0)]);
}

#[test]
fn the_modal_state_a_program_leaves_is_where_the_next_one_starts() {
    // MDI "G91 G1 F300" then "X2": incremental, at F300, in the machine's state
    let (first, _) = read(
        "%\nG20\nG91 G1 F300 S1200 M3\nM8\n%\n",
        &ReadOptions::default(),
    )
    .unwrap();
    let modal = first.end_modal.clone();
    for want in ["G20", "G91", "F300", "S1200", "M3", "G1", "M8"] {
        assert!(modal.contains(want), "{want} not in {modal:?}");
    }
    let options = ReadOptions {
        preamble: Some(modal),
        start_mm: Some(Vec3([10.0, 0.0, 0.0])),
        ..Default::default()
    };
    let (second, _) = read("%\nX2\n%\n", &options).unwrap();
    assert_eq!(second.motions.len(), 1, "{:?}", second.motions);
    let m = &second.motions[0];
    match m.kind {
        MotionKind::Feed {
            end,
            feed_mm_per_min,
        } => {
            // 2 inches on from X10 mm, at 300 in/min
            assert!((end.0[0] - (10.0 + 2.0 * 25.4)).abs() < 1e-9, "{end:?}");
            assert!((feed_mm_per_min - 300.0 * 25.4).abs() < 1e-9);
        }
        k => panic!("a feed move, not {k:?}"),
    }
    assert_eq!(m.line, 2, "the preamble takes no line of the program");
    assert!(m.spindle_rpm > 0.0, "the spindle still turns");
    // the tool in the spindle and its length offset stay (tool 1 of the profile)
    let (tooled, _) = read("%\nT1 M6\nG43\n%\n", &ReadOptions::default()).unwrap();
    assert!(tooled.end_modal.contains("T1 M6"), "{}", tooled.end_modal);
    let len = profile().tool_length_mm(1).unwrap();
    let options = ReadOptions {
        preamble: Some(tooled.end_modal.clone()),
        ..Default::default()
    };
    let (next, params) = read("%\nG0 Z0\n%\n", &options).unwrap();
    let m = &next.motions[0];
    // machine Z = the canonical end + the offset in force (the tool length)
    let z = m.kind.end().unwrap().0[2] + m.offset_mm.0[2];
    assert!((z - len).abs() < 1e-9, "Z0 with tool 1's length {len}: {z}");
    let _ = params;
    // a program that ends with M2 leaves LinuxCNC's reset state
    let (ended, _) = read("G91 G55 M8\nM2\n", &ReadOptions::default()).unwrap();
    assert!(
        ended.end_modal.contains("G90")
            && ended.end_modal.contains("G54")
            && !ended.end_modal.contains("M8"),
        "{}",
        ended.end_modal
    );
    // a program that never set a feed rate leaves G1 at F0, one in inverse time
    // G93 without an F: the next program still starts in that mode, not refused
    for first in ["G0 X5 Y5\nM2\n", "%\nG93 G1 X1 F2\n%\n"] {
        let (p, _) = read(first, &ReadOptions::default()).unwrap();
        let options = ReadOptions {
            preamble: Some(p.end_modal.clone()),
            ..Default::default()
        };
        let (next, _) = read("G0 X1\nG94 G1 X2 F100\nX3\nM2\n", &options)
            .unwrap_or_else(|e| panic!("after {first:?} ({}): {e}", p.end_modal));
        // (three moves; no spindle stop at M2: the spindle never turned)
        assert_eq!(next.motions.len(), 3, "after {first:?}");
    }
    // a bad preamble is an error that names it
    let bad = ReadOptions {
        preamble: Some("G1 G0\n".into()),
        ..Default::default()
    };
    let e = read("G0 X1\nM2\n", &bad).unwrap_err();
    assert!(e.to_string().contains("modal state"), "{e}");
}

/// A job after one that left a tool length offset in force (the modal state says
/// `G43.1 Z…` or `T1 M6 G43`) starts where the machine stands: its first move
/// starts at the machine position, not one offset away (found from the web panel:
/// a second job after `examples/demo.ngc` jumped Z by the tool's length and
/// tripped the following-error limit).
#[test]
fn a_job_after_a_tool_length_offset_starts_where_the_machine_stands() {
    let at = Vec3([3.0, 4.0, 50.0]);
    let (first, _) = read("%\nT1 M6\nG43 H1\nG0 Z60\n%\n", &ReadOptions::default()).unwrap();
    for preamble in [first.end_modal.clone(), "G43.1 Z12.9794\n".to_string()] {
        let options = ReadOptions {
            preamble: Some(preamble.clone()),
            start_mm: Some(at),
            ..Default::default()
        };
        let (next, _) = read("G1 X10 F600\nM2\n", &options).unwrap();
        let m = &next.motions[0];
        let start = m.start + m.offset_mm;
        assert!(close(start, at), "after {preamble:?}: starts at {start:?}");
        // and it moves X only
        let end = m.kind.end().unwrap() + m.offset_mm;
        assert!(
            close(end, Vec3([10.0, 4.0, 50.0])),
            "after {preamble:?}: ends at {end:?}"
        );
        // the same with the demo's own tool change and offset again first
        let (next, _) = read("T1 M6\nG43 H1\nG0 X10\nM2\n", &options).unwrap();
        let m = next
            .motions
            .iter()
            .find(|m| matches!(m.kind, MotionKind::Traverse { .. }))
            .unwrap();
        let start = m.start + m.offset_mm;
        assert!(
            close(start, at),
            "after {preamble:?}, T1 M6 G43 H1: starts at {start:?}"
        );
    }
}
