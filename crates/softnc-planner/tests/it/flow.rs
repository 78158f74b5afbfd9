//! Program flow in the planner: M0/M1 pauses (an exact stop where the path waits for
//! `resume`), single block (from the start and switched on mid-stream), run from
//! line (a safe approach, then the uninterrupted plan's samples), and parameters in
//! and out (issue 19's program flow, issue 16's persistent parameters).

use super::common;
use common::{limit_ratios, profile};
use softnc_core::{FeedProfile, MotionProfile, Vec3};
use softnc_planner::{
    check_and_stream, check_program, PlanOptions, Sample, StopKind, StreamInterpolator,
};

const BOTH: [FeedProfile; 2] = [FeedProfile::Trapezoidal, FeedProfile::SCurve];

/// Samples pulled at most before a test gives up (a path that never ends).
const MAX_SAMPLES: usize = 2_000_000;

/// Check and stream `text`, handing the interpolator to `f`.
fn stream<R>(
    text: &str,
    p: &MotionProfile,
    options: &PlanOptions,
    f: impl FnOnce(&mut StreamInterpolator) -> R,
) -> R {
    check_and_stream(text, "t.ngc", p, options, f)
        .unwrap_or_else(|e| panic!("{e}"))
        .1
}

/// Pull samples until the path pauses or ends: the samples, and the pause's line.
fn until_pause(it: &mut StreamInterpolator, out: &mut Vec<Sample>) -> Option<u32> {
    for _ in 0..MAX_SAMPLES {
        match it.next() {
            Some(s) => out.push(s),
            None => return None,
        }
        if let Some(line) = it.paused_at_line() {
            return Some(line);
        }
    }
    panic!("neither paused nor ended");
}

fn assert_within_limits(samples: &[Sample], p: &MotionProfile, what: &str) {
    let r = limit_ratios(samples, p);
    let jerk_checked = p.planner.feed_profile == FeedProfile::SCurve;
    assert!(
        r[0] <= 1.0 + 1e-9 && r[1] <= 1.0 + 1e-9 && (!jerk_checked || r[2] <= 1.0 + 1e-9),
        "{what}: limit ratios v, a, j = {r:?}"
    );
}

const SQUARE_M0: &str = "G21 G90 G64\n\
G1 X20 Y0 F3000\n\
G1 X20 Y20\n\
M0\n\
G1 X0 Y20\n\
M2\n";

#[test]
fn m0_comes_to_rest_exactly_there_and_waits_for_resume() {
    for fp in BOTH {
        let p = profile(fp);
        let options = PlanOptions {
            wait_at_program_stops: true,
            ..Default::default()
        };
        let corner = Vec3::new(20.0, 20.0, 0.0);
        stream(SQUARE_M0, &p, &options, |it| {
            let mut samples = Vec::new();
            assert_eq!(until_pause(it, &mut samples), Some(4), "{fp:?}");
            assert_eq!(it.pause_kind(), Some(StopKind::Program));
            let at = samples.last().unwrap().pos_mm;
            assert!((at - corner).norm() < 1e-9, "{fp:?}: paused at {at:?}");
            // it waits: standing samples, for as long as nobody resumes
            for _ in 0..500 {
                let s = it.next().unwrap();
                assert_eq!(s.pos_mm, at);
                samples.push(s);
            }
            assert_eq!(it.paused_at_line(), Some(4));
            assert!(!it.is_finished());
            it.resume();
            assert_eq!(it.paused_at_line(), None);
            assert_eq!(until_pause(it, &mut samples), None);
            let end = samples.last().unwrap().pos_mm;
            assert_eq!(end, Vec3::new(0.0, 20.0, 0.0));
            assert_within_limits(&samples, &p, "M0");
        });
    }
}

#[test]
fn m0_without_waiting_rests_and_goes_on() {
    let p = profile(FeedProfile::Trapezoidal);
    let samples: Vec<Sample> = stream(SQUARE_M0, &p, &PlanOptions::default(), |it| {
        it.take(MAX_SAMPLES).collect()
    });
    assert_eq!(samples.last().unwrap().pos_mm, Vec3::new(0.0, 20.0, 0.0));
    // the corner is not blended: the path passes exactly through it
    assert!(samples
        .iter()
        .any(|s| s.pos_mm == Vec3::new(20.0, 20.0, 0.0)));
    assert_within_limits(&samples, &p, "M0 not waiting");
}

#[test]
fn m1_pauses_only_with_the_optional_stop_switch() {
    let text = "G21\nG1 X20 F3000\nM1\nG1 Y20\nM2\n";
    let p = profile(FeedProfile::Trapezoidal);
    for (switch, want) in [(false, None), (true, Some(3))] {
        let options = PlanOptions {
            wait_at_program_stops: true,
            optional_stop: switch,
            ..Default::default()
        };
        let line = stream(text, &p, &options, |it| until_pause(it, &mut Vec::new()));
        assert_eq!(line, want, "switch {switch}");
    }
}

#[test]
fn a_feed_hold_and_a_pause_do_not_interfere() {
    let p = profile(FeedProfile::Trapezoidal);
    let options = PlanOptions {
        wait_at_program_stops: true,
        ..Default::default()
    };
    stream(SQUARE_M0, &p, &options, |it| {
        let mut samples = Vec::new();
        // a hold on the way: the path stands, and that is not a pause
        samples.extend(it.by_ref().take(100));
        it.set_feed_override(0.0);
        for _ in 0..2000 {
            samples.push(it.next().unwrap());
        }
        let held = samples.last().unwrap().pos_mm;
        assert_eq!(it.path_speed_mm_per_s(), 0.0);
        assert_eq!(it.paused_at_line(), None);
        it.resume(); // not paused: nothing
        assert_eq!(it.next().unwrap().pos_mm, held);
        it.set_feed_override(1.0);
        assert_eq!(until_pause(it, &mut samples), Some(4));
        let at = samples.last().unwrap().pos_mm;
        // held while paused, then resumed: it stays at rest until the hold ends
        it.set_feed_override(0.0);
        it.resume();
        for _ in 0..200 {
            let s = it.next().unwrap();
            assert_eq!(s.pos_mm, at);
            samples.push(s);
        }
        assert_eq!(it.paused_at_line(), None);
        it.set_feed_override(1.0);
        assert_eq!(until_pause(it, &mut samples), None);
        assert_eq!(samples.last().unwrap().pos_mm, Vec3::new(0.0, 20.0, 0.0));
        assert_within_limits(&samples, &p, "hold and pause");
    });
}

const BLOCKS: &str = "G21 G90 G64\n\
G1 X10 F3000\n\
G1 X10 Y10\n\
G0 X0 Y10 Z5\n\
G1 Z0\n\
M2\n";

#[test]
fn single_block_from_the_start_stops_at_every_programmed_block_end() {
    for fp in BOTH {
        let p = profile(fp);
        let options = PlanOptions {
            single_block: true,
            ..Default::default()
        };
        let stops = stream(BLOCKS, &p, &options, |it| {
            assert!(it.single_block());
            let mut samples = Vec::new();
            let mut stops = Vec::new();
            while let Some(line) = until_pause(it, &mut samples) {
                assert_eq!(it.pause_kind(), Some(StopKind::Block));
                stops.push((line, samples.last().unwrap().pos_mm));
                it.resume();
            }
            assert_within_limits(&samples, &p, "single block");
            assert_eq!(samples.last().unwrap().pos_mm, Vec3::new(0.0, 10.0, 0.0));
            stops
        });
        let want = [
            (2, Vec3::new(10.0, 0.0, 0.0)),
            (3, Vec3::new(10.0, 10.0, 0.0)),
            (4, Vec3::new(0.0, 10.0, 5.0)),
        ];
        assert_eq!(stops.len(), want.len(), "{fp:?}: {stops:?}");
        for ((line, at), (wl, wat)) in stops.iter().zip(want) {
            assert_eq!(*line, wl, "{fp:?}");
            assert!((*at - wat).norm() < 1e-9, "{fp:?}: line {line} at {at:?}");
        }
    }
}

/// A zig-zag of blended lines `amp_mm` high, one per block: corner k is the end of
/// line k + 3.
fn zigzag(n: usize, amp_mm: f64) -> (String, Vec<Vec3>) {
    let mut text = String::from("G21 G90 G64\nG0 X0 Y0\n");
    let mut corners = Vec::new();
    for k in 0..n {
        let c = Vec3::new(
            4.0 * (k + 1) as f64,
            if k % 2 == 0 { amp_mm } else { 0.0 },
            0.0,
        );
        text.push_str(&format!("G1 X{} Y{} F6000\n", c.0[0], c.0[1]));
        corners.push(c);
    }
    text.push_str("M2\n");
    (text, corners)
}

#[test]
fn single_block_switched_on_mid_stream_stops_at_a_reachable_block_end() {
    // the S-curve stops at corners it cannot take at a tenth of the speed around
    // them: a flatter zig-zag, so that its corners are blended too
    for (fp, amp_mm) in [(FeedProfile::Trapezoidal, 0.5), (FeedProfile::SCurve, 0.05)] {
        let (text, corners) = zigzag(60, amp_mm);
        let p = profile(fp);
        stream(&text, &p, &PlanOptions::default(), |it| {
            let mut samples: Vec<Sample> = it.by_ref().take(300).collect();
            assert!(!samples.last().unwrap().pos_mm.0[0].is_nan());
            it.set_single_block(true);
            let line = until_pause(it, &mut samples).expect("single block stops");
            let at = samples.last().unwrap().pos_mm;
            let k = line as usize - 3;
            let (from, corner) = (corners[k - 1], corners[k]);
            // at the end of its block: on the block's own programmed line, where
            // the blend into the next block begins (at most half the line before
            // its end; exactly there where the corner is a stop)
            let u = (corner - from) * (1.0 / (corner - from).norm());
            let along = (at - from).dot(u);
            let off_line = (at - from - u * along).norm();
            let before_end = (corner - from).norm() - along;
            assert!(
                off_line < 1e-9
                    && before_end >= -1e-9
                    && before_end <= 0.5 * (corner - from).norm(),
                "{fp:?}: paused at {at:?} for line {line}, corner {corner:?}"
            );
            // the corners are blended: a stop the plan did not have
            assert!(before_end > 1e-6, "{fp:?}: {before_end}");
            for _ in 0..100 {
                assert_eq!(it.next().unwrap().pos_mm, at);
            }
            // the next block end, then off: on to the end
            it.resume();
            let next = until_pause(it, &mut samples).expect("the next block end");
            assert_eq!(next, line + 1, "{fp:?}");
            it.set_single_block(false);
            it.resume();
            assert_eq!(until_pause(it, &mut samples), None);
            assert_eq!(samples.last().unwrap().pos_mm, *corners.last().unwrap());
            assert_within_limits(&samples, &p, "single block mid-stream");
        });
    }
}

/// Line 5 starts after an exact stop (the M0 of line 4).
const RESTART: &str = "G21 G90 G64\n\
G0 X10 Y5 Z2\n\
G1 X30 F2400\n\
M0\n\
G1 X40 Y20\n\
G1 X60 Y10\n\
G2 X70 Y0 R10\n\
G0 Z10\n\
M2\n";

/// Samples from the first move of program line `first_motion` on (standing
/// samples at its start left out).
fn from_motion(samples: &[Sample], first_motion: u32, start: Vec3) -> Vec<Vec3> {
    samples
        .iter()
        .filter(|s| s.motion >= first_motion)
        .map(|s| s.pos_mm)
        .skip_while(|&p| p == start)
        .collect()
}

#[test]
fn run_from_line_gives_the_uninterrupted_samples_after_its_approach() {
    let p = profile(FeedProfile::Trapezoidal);
    let start = Vec3::new(30.0, 5.0, 2.0);
    let whole = PlanOptions {
        wait_at_program_stops: true,
        ..Default::default()
    };
    let uninterrupted = stream(RESTART, &p, &whole, |it| {
        let mut samples = Vec::new();
        assert_eq!(until_pause(it, &mut samples), Some(4));
        it.resume();
        assert_eq!(until_pause(it, &mut samples), None);
        samples
    });
    let restart = PlanOptions {
        from_line: Some(5),
        start_mm: Some([0.0, 0.0, 0.0]),
        ..Default::default()
    };
    let (_, checked) = check_program(RESTART, "t.ngc", &p, &restart).unwrap();
    // the approach (Z up, X and Y; no Z down), the sync, then lines 5 to 8
    assert_eq!(checked.motions(), 2 + 1 + 4);
    let resumed: Vec<Sample> = stream(RESTART, &p, &restart, |it| it.take(MAX_SAMPLES).collect());
    // the approach: Z first, then X and Y at the start's Z
    let approach: Vec<Vec3> = resumed
        .iter()
        .filter(|s| s.motion < 2)
        .map(|s| s.pos_mm)
        .collect();
    let top = approach.iter().position(|q| q.0[2] == 2.0).unwrap();
    assert!(approach[..top]
        .iter()
        .all(|q| q.0[0] == 0.0 && q.0[1] == 0.0));
    assert!(approach[top..].iter().all(|q| q.0[2] == 2.0));
    assert_within_limits(&resumed, &p, "run from line");
    // motion 3 is line 5 in both: (G0, G1, M0 | Z up, XY, sync), then G1 X40
    let want = from_motion(&uninterrupted, 3, start);
    let got = from_motion(&resumed, 3, start);
    assert!(want.len() > 100);
    assert_eq!(got.len(), want.len());
    for (k, (g, w)) in got.iter().zip(&want).enumerate() {
        assert!(
            g.0.iter().zip(w.0).all(|(a, b)| a.to_bits() == b.to_bits()),
            "sample {k} after the start: {g:?} vs {w:?}"
        );
    }
}

#[test]
fn run_from_line_stays_within_limits_and_ends_as_the_program() {
    // from line 6, after a blended corner: the approach, then the rest, both profiles
    for fp in BOTH {
        let p = profile(fp);
        let restart = PlanOptions {
            from_line: Some(6),
            start_mm: Some([5.0, -5.0, 8.0]),
            ..Default::default()
        };
        let samples: Vec<Sample> =
            stream(RESTART, &p, &restart, |it| it.take(MAX_SAMPLES).collect());
        assert_eq!(samples[0].pos_mm, Vec3::new(5.0, -5.0, 8.0), "{fp:?}");
        assert_eq!(
            samples.last().unwrap().pos_mm,
            Vec3::new(70.0, 0.0, 10.0),
            "{fp:?}"
        );
        // the approach ends exactly at line 6's start (40, 20, 2), from Z 8 down
        assert!(
            samples
                .iter()
                .any(|s| (s.pos_mm - Vec3::new(40.0, 20.0, 2.0)).norm() < 1e-9),
            "{fp:?}"
        );
        assert_within_limits(&samples, &p, "run from line 6");
    }
}

#[test]
fn end_parameters_carry_a_touch_off_to_the_next_program() {
    let p = profile(FeedProfile::Trapezoidal);
    let first = PlanOptions {
        start_mm: Some([12.5, 0.0, 0.0]),
        ..Default::default()
    };
    let (_, checked) = check_program("G10 L20 P2 X0\nG0 Y1\nM2\n", "a.ngc", &p, &first).unwrap();
    assert_eq!(checked.end_params().get(5241), 12.5);
    let second = PlanOptions {
        params: Some(checked.end_params().clone()),
        ..Default::default()
    };
    let last = stream("G55 G0 X0\nM2\n", &p, &second, |it| it.last().unwrap());
    assert_eq!(last.pos_mm.0[0], 12.5);
    // 5220 at the start selects the system, as LinuxCNC at start-up
    let mut params = checked.end_params().clone();
    params.set(5220, 2.0);
    let third = PlanOptions {
        params: Some(params),
        start_mm: Some([0.0, 0.0, 0.0]),
        ..Default::default()
    };
    let last = stream("G0 X0\nM2\n", &p, &third, |it| it.last().unwrap());
    assert_eq!(last.pos_mm.0[0], 12.5);
}
