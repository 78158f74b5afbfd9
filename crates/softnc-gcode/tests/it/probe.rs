//! Probe moves (G38.2–G38.5): read with rs274's stand-in results
//! (`ProbeResults::StandIn`) as its stand-alone interpreter reads them, refused
//! for the machine (`ProbeResults::Refuse`, the default). The expected values are
//! what `rs274 -g` printed for the same programs (LinuxCNC 2.9).

use softnc_core::MotionProfile;
use softnc_gcode::{ErrorKind, MotionKind, ProbeKind, ProbeResults, ReadOptions};
use std::path::PathBuf;

fn profile() -> MotionProfile {
    MotionProfile::load(
        &PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../config/machines/default.ron"),
    )
    .unwrap()
}

fn read_as(
    text: &str,
    probes: ProbeResults,
) -> Result<softnc_gcode::Program, softnc_gcode::GcodeError> {
    let options = ReadOptions {
        probe_results: probes,
        ..Default::default()
    };
    softnc_gcode::read_program_with(text, "t.ngc", &profile(), &options).map(|(p, _)| p)
}

/// The (DEBUG,…) texts of a program read with stand-in results.
fn debug(text: &str) -> Vec<String> {
    read_as(text, ProbeResults::StandIn).unwrap().warnings
}

#[test]
fn a_probe_move_reads_as_rs274_reads_it() {
    let p = read_as(
        "G21 G90 F100\nG0 X1 Y2 Z3\nG38.2 Z-10\n(DEBUG, #5061 #5062 #5063 #5070 #5064)\n\
         G91 G1 X1\nG90 G0 Z5\nG38.3 X5 Y5 Z0\n(DEBUG, #5061 #5062 #5063)\nG91 G1 Y1\nG90\n\
         G38.4 X0\nG38.5 X0\nG91 G0 Z1\nM2\n",
        ProbeResults::StandIn,
    )
    .unwrap();
    let probes: Vec<_> = p
        .motions
        .iter()
        .filter_map(|m| match m.kind {
            MotionKind::Probe {
                feed_mm_per_min,
                probe,
                ..
            } => Some((
                m.line,
                m.canon_view().0.unwrap().0,
                feed_mm_per_min,
                probe.name(),
            )),
            _ => None,
        })
        .collect();
    // rs274: STRAIGHT_PROBE(1, 2, -10), (5, 5, 0), (0, 5.8838, 0.1937) twice
    assert_eq!(
        probes,
        vec![
            (3, [1.0, 2.0, -10.0], 100.0, "G38.2"),
            (7, [5.0, 5.0, 0.0], 100.0, "G38.3"),
            (11, [0.0, 5.8838, 0.1937], 100.0, "G38.4"),
            (12, [0.0, 5.8838, 0.1937], 100.0, "G38.5"),
        ]
    );
    assert_eq!(
        p.warnings,
        vec![
            "t.ngc:4: debug:  1.000000 2.000000 -10.000000 0.000000 0.000000",
            "t.ngc:8: debug:  5.000000 5.000000 0.000000",
        ]
    );
    // rs274: the point after a probe is its end backed off 0.254 mm toward the
    // start: STRAIGHT_FEED(2, 2, -9.746), (4.8838, 5.8838, 0.1937), and the
    // traverse after the G38.4/G38.5 pair X 0.2540
    let ends: Vec<[f64; 3]> = p
        .motions
        .iter()
        .filter(|m| {
            matches!(
                m.kind,
                MotionKind::Feed { .. } | MotionKind::Traverse { .. }
            )
        })
        .map(|m| m.canon_view().0.unwrap().0)
        .collect();
    assert_eq!(
        ends,
        vec![
            [1.0, 2.0, 3.0],
            [2.0, 2.0, -9.746],
            [2.0, 2.0, 5.0],
            [4.8838, 5.8838, 0.1937],
            [0.254, 5.8838, 1.1937],
        ]
    );
}

#[test]
fn in_inches_the_back_off_is_a_hundredth_of_an_inch() {
    // rs274: STRAIGHT_TRAVERSE(0, 0, -0.2900) after G38.2 Z-0.5 and G91 G0 Z0.2;
    // after G10 L2 P1 X1 Y1 Z1 the probe of X2 reads 2 -1 -1.29
    let p = read_as(
        "G20 G90 F4\nG0 Z0.1\nG38.2 Z-0.5\nG91 G0 Z0.2\nG90\nG54 G10 L2 P1 X1 Y1 Z1\n\
         G38.2 X2\n(DEBUG, #5061 #5062 #5063)\nG91 G1 X1\nM2\n",
        ProbeResults::StandIn,
    )
    .unwrap();
    let ends: Vec<[f64; 3]> = p
        .motions
        .iter()
        .filter(|m| m.kind.end().is_some())
        .map(|m| {
            m.canon_view()
                .0
                .unwrap()
                .0
                .map(|x| (x / 25.4 * 1e4).round() / 1e4)
        })
        .collect();
    assert_eq!(
        ends,
        vec![
            [0.0, 0.0, 0.1],
            [0.0, 0.0, -0.5],
            [0.0, 0.0, -0.29],
            [2.0, -1.0, -1.29],
            [2.99, -1.0, -1.29],
        ]
    );
    assert_eq!(
        p.warnings,
        vec!["t.ngc:8: debug:  2.000000 -1.000000 -1.290000"]
    );
    assert!(p.motions.iter().any(|m| matches!(
        m.kind,
        MotionKind::Probe {
            probe: ProbeKind {
                toward_contact: true,
                fails_without_trip: true
            },
            ..
        }
    )));
}

#[test]
fn probe_errors_as_rs274() {
    let err = |text: &str| {
        let e = read_as(text, ProbeResults::StandIn).unwrap_err();
        (e.line, e.kind.to_string())
    };
    assert_eq!(
        err("G21 F100\nG38.2 X0\nM2\n"),
        (2, "Start point too close to probe point".into())
    );
    assert_eq!(
        err("G21 F100\nG38.4 X0\nM2\n"),
        (2, "Start point too close to probe point".into())
    );
    assert_eq!(
        err("G21\nG38.2 X5\nM2\n"),
        (2, "Cannot probe with zero feed rate".into())
    );
    assert_eq!(
        err("G21 F100 T1 M6\nG41 D1 G1 X5 Y5\nG38.2 X10\nM2\n"),
        (3, "Cannot probe with cutter radius comp on".into())
    );
    assert_eq!(
        err("G21 F100\nG38.2\nM2\n"),
        (2, "All axes missing with motion code".into())
    );
    // G38.3 and G38.5 may start at their end (rs274: STRAIGHT_PROBE(0, 0, 0))
    assert!(read_as("G21 F100\nG38.3 X0\nG38.5 X0\nM2\n", ProbeResults::StandIn).is_ok());
    // the mode is modal: a bare X probes again
    let p = read_as("G21 F100\nG38.3 X5\nX7\nM2\n", ProbeResults::StandIn).unwrap();
    let probes = p
        .motions
        .iter()
        .filter(|m| matches!(m.kind, MotionKind::Probe { .. }))
        .count();
    assert_eq!(probes, 2);
    assert_eq!(
        debug("G21 F100\nG38.3 X5\n(DEBUG, #5070)\nM2\n"),
        vec!["t.ngc:3: debug:  0.000000"]
    );
}

#[test]
fn jobs_refuse_a_probe_move_at_its_word() {
    let e = read_as(
        "G21 F100\nG0 X1\nG1 X2 G38.2 Z-5\nM2\n",
        ProbeResults::Refuse,
    )
    .unwrap_err();
    assert_eq!((e.line, e.column), (3, 7));
    let ErrorKind::Unsupported { word, why } = &e.kind else {
        panic!("{e}");
    };
    assert_eq!(word, "G38.2");
    assert!(why.contains("not run by the machine yet"), "{why}");
    // the default
    let e =
        softnc_gcode::read_program("G21 F100\nG38.3 Z-5\nM2\n", "t.ngc", &profile()).unwrap_err();
    assert!(matches!(e.kind, ErrorKind::Unsupported { .. }), "{e}");
}

/// A program that probes twice, in a work offset, then moves by what it probed.
const TWO_PROBES: &str = "G21 G90 F100\nG10 L2 P1 Z-100\nG54\nG0 X10 Y10 Z10\n\
     G38.2 Z-20\n(DEBUG, #5063 #5070)\nG91 G0 Z2\nG90 G38.3 Z-30\nG0 Z[#5063 + 5]\nM2\n";

fn known(results: &[softnc_gcode::ProbeResult]) -> softnc_gcode::Program {
    read_as(TWO_PROBES, ProbeResults::Known(results.to_vec())).unwrap()
}

fn at(x: f64, y: f64, z: f64) -> softnc_core::Vec3 {
    softnc_core::Vec3([x, y, z])
}

/// (line, kind, start, end) of each motion that moves (program frame, mm).
fn moves(p: &softnc_gcode::Program) -> Vec<(u32, &'static str, [f64; 3], [f64; 3])> {
    p.motions
        .iter()
        .filter_map(|m| {
            let kind = match m.kind {
                MotionKind::Traverse { .. } => "traverse",
                MotionKind::Probe { .. } => "probe",
                MotionKind::Feed { .. } => "feed",
                _ => return None,
            };
            let r = |v: [f64; 3]| v.map(|x| (x * 1e9).round() / 1e9);
            Some((m.line, kind, r(m.start.0), r(m.kind.end()?.0)))
        })
        .collect()
}

#[test]
fn with_the_machines_results_the_reading_goes_on_from_each_probe() {
    // none run yet: the reading ends after the first probe move
    let p = known(&[]);
    assert_eq!(p.awaits_probe, Some(5));
    assert_eq!(
        moves(&p),
        vec![
            (4, "traverse", [0.0, 0.0, 100.0], [10.0, 10.0, 10.0]),
            (5, "probe", [10.0, 10.0, 10.0], [10.0, 10.0, -20.0]),
        ]
    );
    // the first ran: it tripped at machine Z −105.5, the machine stopped at
    // −105.7 (G54 Z −100): the program goes on from Z −5.7 with #5063 −5.5
    let first = softnc_gcode::ProbeResult {
        tripped: true,
        probed_mm: at(10.0, 10.0, -105.5),
        stopped_mm: at(10.0, 10.0, -105.7),
    };
    let p = known(&[first]);
    assert_eq!(p.awaits_probe, Some(8));
    assert_eq!(
        moves(&p),
        vec![
            (7, "traverse", [10.0, 10.0, -5.7], [10.0, 10.0, -3.7]),
            (8, "probe", [10.0, 10.0, -3.7], [10.0, 10.0, -30.0]),
        ]
    );
    assert_eq!(p.warnings, vec!["t.ngc:6: debug:  -5.500000 1.000000"]);
    // the second (G38.3) ended at its end without a trip: no error, #5063 is
    // where it stopped, and the program runs to its end
    let second = softnc_gcode::ProbeResult {
        tripped: false,
        probed_mm: at(10.0, 10.0, -130.0),
        stopped_mm: at(10.0, 10.0, -130.0),
    };
    let p = known(&[first, second]);
    assert_eq!(p.awaits_probe, None);
    assert_eq!(
        moves(&p),
        vec![(9, "traverse", [10.0, 10.0, -30.0], [10.0, 10.0, -25.0])]
    );
    // a G38.2 that did not trip refuses the program at its line
    let missed = softnc_gcode::ProbeResult {
        tripped: false,
        ..first
    };
    let e = read_as(TWO_PROBES, ProbeResults::Known(vec![missed])).unwrap_err();
    assert_eq!(
        (e.line, e.kind.to_string()),
        (5, "G38.2: probe move finished without tripping".into())
    );
}

#[test]
fn probes_in_a_loop_are_counted_as_they_run() {
    // three probes from one line: each result is the next pass's
    let text = "G21 G90 F100\n#1=0\no1 while [#1 LT 3]\nG0 X[#1*10] Z5\nG38.2 Z-10\n\
                (DEBUG, #1 #5063)\n#1=[#1+1]\no1 endwhile\nM2\n";
    let r = |x: f64, z: f64| softnc_gcode::ProbeResult {
        tripped: true,
        probed_mm: at(x, 0.0, z),
        stopped_mm: at(x, 0.0, z),
    };
    let read = |k: usize| {
        let ran: Vec<_> = [r(0.0, -1.0), r(10.0, -2.0), r(20.0, -3.0)][..k].to_vec();
        read_as(text, ProbeResults::Known(ran)).unwrap()
    };
    let p = read(2);
    assert_eq!(p.awaits_probe, Some(5));
    assert_eq!(
        moves(&p),
        vec![
            (4, "traverse", [10.0, 0.0, -2.0], [20.0, 0.0, 5.0]),
            (5, "probe", [20.0, 0.0, 5.0], [20.0, 0.0, -10.0]),
        ]
    );
    let p = read(3);
    assert_eq!(p.awaits_probe, None);
    assert!(moves(&p).is_empty());
    assert_eq!(
        p.warnings,
        vec![
            "t.ngc:6: debug:  0.000000 -1.000000",
            "t.ngc:6: debug:  1.000000 -2.000000",
            "t.ngc:6: debug:  2.000000 -3.000000",
        ]
    );
}
