//! Manual motion: the per-axis mover (limits on the samples, exact landing, bounded
//! time, stop distance), jog targets, the homing sequence against simulated axes,
//! and that stepping allocates nothing.

use proptest::prelude::*;
use softnc_core::{AxisConfig, AxisHoming, MotionProfile};
use softnc_planner::manual::{
    jog_target, simulated_switch_active, AxisMover, HomingError, HomingEvent, HomingPhase,
    HomingSequence, JogDirection, ManualError,
};

use softnc_test_support::{allocations as allocs, Counting};

#[global_allocator]
static GLOBAL: Counting = Counting;

/// The interpolation cycle of every profile here (s).
const DT_S: f64 = 0.001;
/// Relative slack of the limit checks (the brief's 1 + 1e-9).
const REL: f64 = 1e-9;

const DEFAULT: &str = include_str!("../../../config/machines/default.ron");
const INCREMENTAL: &str = include_str!("../../../config/machines/default-incremental.ron");

fn incremental() -> MotionProfile {
    MotionProfile::from_ron_str(INCREMENTAL, "default-incremental.ron").unwrap()
}

/// Velocity and acceleration of the samples `p` (p[0] = p[1] = the start at rest)
/// within the limits: |Δp|/T ≤ v_max(1+1e-9), |Δ²p|/T² ≤ a_max(1+1e-9).
fn check_limits(p: &[f64], vmax: f64, amax: f64) -> Result<(), String> {
    for k in 1..p.len() {
        let v = (p[k] - p[k - 1]) / DT_S;
        if v.abs() > vmax * (1.0 + REL) {
            return Err(format!("sample {k}: |v| {v} > {vmax}"));
        }
        if k >= 2 {
            // differences of neighbours first: exact (Sterbenz), so the check adds
            // no rounding of its own
            let a = ((p[k] - p[k - 1]) - (p[k - 1] - p[k - 2])) / (DT_S * DT_S);
            if a.abs() > amax * (1.0 + REL) {
                return Err(format!("sample {k}: |a| {a} > {amax}"));
            }
        }
    }
    Ok(())
}

/// Continuous trapezoid time of a rest-to-rest move of `d` at `v`, `a`.
fn trapezoid_s(d: f64, v: f64, a: f64) -> f64 {
    let d = d.abs();
    if d >= v * v / a {
        d / v + v / a
    } else {
        2.0 * (d / a).sqrt()
    }
}

/// Step `m` until at rest (at most `max` steps), appending the samples.
fn run(m: &mut AxisMover, samples: &mut Vec<f64>, max: usize) -> usize {
    let mut n = 0;
    while !m.at_rest() && n < max {
        samples.push(m.step());
        n += 1;
    }
    n
}

fn start(m: &AxisMover) -> Vec<f64> {
    vec![m.pos_mm(), m.pos_mm()]
}

#[test]
fn moves_land_exactly_within_the_trapezoid_time() {
    // (start, target, speed, vmax, amax): cruise, triangle, tiny, negative, clamped speed
    let cases = [
        (0.0, 100.0, 200.0, 400.0, 3000.0),
        (10.0, 12.5, 400.0, 400.0, 3000.0),
        (-3.0, -3.0 + 1e-7, 50.0, 400.0, 3000.0),
        (250.0, -249.9, 300.0, 300.0, 2500.0),
        (0.0, 7.3, 1e6, 20.0, 100.0),
        (1.0, 1.0 + 0.0031, 10.0, 400.0, 3000.0),
    ];
    for (p0, target, speed, vmax, amax) in cases {
        let mut m = AxisMover::new(p0, vmax, amax, DT_S).unwrap();
        m.move_to(target, speed).unwrap();
        let mut s = start(&m);
        let n = run(&mut m, &mut s, 1_000_000);
        check_limits(&s, vmax, amax).unwrap();
        assert_eq!(m.pos_mm(), target, "{p0} → {target}");
        assert!(m.at_rest() && m.vel_mm_per_s() == 0.0);
        let dir = (target - p0).signum();
        assert!(s.iter().all(|&x| dir * (x - target) <= 1e-9), "overshoot");
        let ideal = (trapezoid_s(target - p0, speed.min(vmax), amax) / DT_S).ceil() as usize;
        assert!(n <= ideal + 3, "{p0} → {target}: {n} cycles, ideal {ideal}");
    }
}

#[test]
fn speed_is_clamped_and_cruise_reaches_it() {
    let mut m = AxisMover::new(0.0, 50.0, 1000.0, DT_S).unwrap();
    m.move_to(100.0, 1e9).unwrap();
    let mut s = start(&m);
    run(&mut m, &mut s, 100_000);
    let peak = s
        .windows(2)
        .map(|w| (w[1] - w[0]) / DT_S)
        .fold(0.0, f64::max);
    assert!((peak - 50.0).abs() < 1e-9, "peak {peak}");
}

#[test]
fn bad_arguments_are_refused() {
    assert!(matches!(
        AxisMover::new(0.0, 0.0, 1.0, DT_S),
        Err(ManualError::NotPositive {
            what: "max_vel_mm_per_s",
            ..
        })
    ));
    assert!(AxisMover::new(f64::NAN, 1.0, 1.0, DT_S).is_err());
    assert!(AxisMover::new(0.0, 1.0, 1.0, -1.0).is_err());
    let mut m = AxisMover::new(0.0, 1.0, 1.0, DT_S).unwrap();
    assert!(m.move_to(1.0, 0.0).is_err());
    assert!(m.move_to(f64::INFINITY, 1.0).is_err());
    assert!(m.at_rest(), "a refused move leaves the mover as it was");
    m.move_to(0.0, 1.0).unwrap();
    assert!(m.at_rest(), "a move to where it stands is done");
}

#[test]
fn stop_comes_to_rest_within_the_braking_distance() {
    let (vmax, amax) = (400.0, 3000.0);
    for cruise_cycles in [1usize, 5, 60, 400] {
        let mut m = AxisMover::new(0.0, vmax, amax, DT_S).unwrap();
        m.move_to(1000.0, vmax).unwrap();
        let mut s = start(&m);
        for _ in 0..cruise_cycles {
            s.push(m.step());
        }
        let (p, v) = (m.pos_mm(), m.vel_mm_per_s());
        m.stop();
        run(&mut m, &mut s, 100_000);
        check_limits(&s, vmax, amax).unwrap();
        assert!(m.at_rest() && m.vel_mm_per_s() == 0.0);
        let travel = m.pos_mm() - p;
        let bound = v * v / (2.0 * amax) + v * DT_S;
        assert!((0.0..=bound).contains(&travel), "{travel} vs {bound}");
    }
}

#[test]
fn retarget_behind_the_moving_axis_brakes_reverses_and_lands() {
    let (vmax, amax) = (400.0, 3000.0);
    let mut m = AxisMover::new(0.0, vmax, amax, DT_S).unwrap();
    m.move_to(300.0, vmax).unwrap();
    let mut s = start(&m);
    for _ in 0..150 {
        s.push(m.step());
    }
    let here = m.pos_mm();
    m.move_to(here - 5.0, 100.0).unwrap();
    run(&mut m, &mut s, 100_000);
    check_limits(&s, vmax, amax).unwrap();
    assert_eq!(m.pos_mm(), here - 5.0);
    // it went on past `here` while braking, then came back
    assert!(s.iter().cloned().fold(f64::MIN, f64::max) > here);
}

#[test]
fn jog_targets_follow_linuxcnc() {
    let p = MotionProfile::from_ron_str(DEFAULT, "default.ron").unwrap();
    let x = &p.axes[0];
    use JogDirection::*;
    assert_eq!(jog_target(x, 12.0, Positive, true), x.max_mm);
    assert_eq!(jog_target(x, 12.0, Negative, true), x.min_mm);
    // beyond a soft limit: no motion further out, back in allowed
    assert_eq!(
        jog_target(x, x.max_mm + 3.0, Positive, true),
        x.max_mm + 3.0
    );
    assert_eq!(jog_target(x, x.max_mm + 3.0, Negative, true), x.min_mm);
    // unhomed: a travel span either way
    let span = x.max_mm - x.min_mm;
    assert_eq!(jog_target(x, 12.0, Positive, false), 12.0 + span);
    assert_eq!(jog_target(x, 12.0, Negative, false), 12.0 - span);
}

#[test]
fn a_continuous_jog_stops_at_the_soft_limit_without_overshoot() {
    let p = MotionProfile::from_ron_str(DEFAULT, "default.ron").unwrap();
    let z = &p.axes[2];
    let mut m = AxisMover::for_axis(z, 0.0, DT_S).unwrap();
    m.move_to(
        jog_target(z, 0.0, JogDirection::Positive, true),
        z.max_vel_mm_per_s,
    )
    .unwrap();
    let mut s = start(&m);
    run(&mut m, &mut s, 100_000);
    check_limits(&s, z.max_vel_mm_per_s, z.max_acc_mm_per_s2).unwrap();
    assert!(s.iter().all(|&x| x <= z.max_mm));
    assert_eq!(m.pos_mm(), z.max_mm);
}

/// An upper bound on the cycles to target from state (p, v): brake to rest at the
/// acceleration limit on the sample grid (|v| − a·T, |v| − 2a·T, … , 0), then a
/// rest-to-rest trapezoid from there, plus the 3 slack cycles.
fn bound_cycles(p: f64, v: f64, target: f64, speed: f64, amax: f64) -> usize {
    let h = amax * DT_S;
    let (mut w, mut stop_at, mut n) = (v.abs(), p, 0usize);
    while w > 0.0 {
        w = (w - h).max(0.0);
        stop_at += v.signum() * w * DT_S;
        n += 1;
    }
    n + (trapezoid_s(target - stop_at, speed, amax) / DT_S).ceil() as usize + 3
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 1000, ..ProptestConfig::default() })]

    /// From rest: limits on every sample, no overshoot, exact landing, ≤ ideal + 3 cycles.
    #[test]
    fn prop_move_from_rest(
        p0 in -400.0f64..400.0, d in -800.0f64..800.0, speed in 0.5f64..600.0,
        vmax in 1.0f64..500.0, amax in 50.0f64..20000.0,
    ) {
        let target = p0 + d;
        let mut m = AxisMover::new(p0, vmax, amax, DT_S).unwrap();
        m.move_to(target, speed).unwrap();
        let mut s = start(&m);
        let n = run(&mut m, &mut s, 10_000_000);
        check_limits(&s, vmax, amax).map_err(TestCaseError::fail)?;
        prop_assert_eq!(m.pos_mm(), target);
        prop_assert!(m.at_rest());
        let dir = d.signum();
        prop_assert!(s.iter().all(|&x| dir * (x - target) <= 1e-9));
        let ideal = (trapezoid_s(d, speed.min(vmax), amax) / DT_S).ceil() as usize;
        prop_assert!(n <= ideal + 3, "{} cycles, ideal {}", n, ideal);
    }

    /// Retargets (ahead, behind, new speeds) and stops at random cycles mid-move:
    /// limits on every sample, and the last move lands exactly within the bound.
    #[test]
    fn prop_retargets_and_stops(
        p0 in -400.0f64..400.0,
        vmax in 1.0f64..500.0, amax in 50.0f64..20000.0,
        moves in prop::collection::vec(
            (-400.0f64..400.0, 0.5f64..600.0, 0usize..400, prop::bool::weighted(0.2)), 1..6),
    ) {
        let mut m = AxisMover::new(p0, vmax, amax, DT_S).unwrap();
        let mut s = start(&m);
        for &(target, speed, cycles, stop) in &moves {
            if stop { m.stop() } else { m.move_to(target, speed).unwrap() }
            for _ in 0..cycles {
                s.push(m.step());
            }
        }
        let &(target, speed, _, _) = moves.last().unwrap();
        m.move_to(target, speed).unwrap();
        let bound = bound_cycles(m.pos_mm(), m.vel_mm_per_s(), target, speed.min(vmax), amax);
        let n = run(&mut m, &mut s, 10_000_000);
        check_limits(&s, vmax, amax).map_err(TestCaseError::fail)?;
        prop_assert_eq!(m.pos_mm(), target);
        prop_assert!(m.at_rest());
        prop_assert!(n <= bound, "{} cycles, bound {}", n, bound);
    }

    /// A stop at any point of any move: rest within v²/2a + one cycle's travel.
    #[test]
    fn prop_stop_distance(
        d in -800.0f64..800.0, speed in 0.5f64..600.0, amax in 50.0f64..20000.0,
        cycles in 1usize..2000,
    ) {
        let mut m = AxisMover::new(0.0, 500.0, amax, DT_S).unwrap();
        m.move_to(d, speed).unwrap();
        let mut s = start(&m);
        for _ in 0..cycles {
            s.push(m.step());
        }
        let (p, v) = (m.pos_mm(), m.vel_mm_per_s());
        m.stop();
        run(&mut m, &mut s, 10_000_000);
        check_limits(&s, 500.0, amax).map_err(TestCaseError::fail)?;
        prop_assert!(m.at_rest());
        let travel = (m.pos_mm() - p) * v.signum();
        prop_assert!(travel >= 0.0 && travel <= v * v / (2.0 * amax) + v.abs() * DT_S + 1e-12);
    }
}

// ---- homing ----

/// A simulated axis: its encoder reads `true_mm − offset_mm` (the machine does
/// not know `offset_mm` before homing), the switch trips at `switch_true_mm`, and
/// the axis follows the command exactly (`tau_s` = 0) or through a first-order lag.
struct SimAxis {
    true_mm: f64,
    offset_mm: f64,
    switch_true_mm: f64,
    tau_s: f64,
    /// The correction the controller applied (its coordinates = encoder + this).
    correction_mm: f64,
}

impl SimAxis {
    /// The actual position in the controller's current coordinates.
    fn actual_mm(&self) -> f64 {
        self.true_mm - self.offset_mm + self.correction_mm
    }
    /// Follow a command given in the controller's coordinates for one cycle.
    fn follow(&mut self, command_mm: f64) {
        let target_true = command_mm - self.correction_mm + self.offset_mm;
        if self.tau_s == 0.0 {
            self.true_mm = target_true;
        } else {
            let k = 1.0 - (-DT_S / self.tau_s).exp();
            self.true_mm += k * (target_true - self.true_mm);
        }
    }
}

struct HomingRun {
    /// Command samples in one frame (the correction taken out after re-referencing).
    commands_raw: Vec<f64>,
    phases: Vec<HomingPhase>,
    events: Vec<HomingEvent>,
    seq: HomingSequence,
}

fn home(axis: &AxisConfig, h: &AxisHoming, margin: f64, sim: &mut SimAxis) -> HomingRun {
    let start_mm = sim.actual_mm();
    let mut seq = HomingSequence::new(axis, h, margin, DT_S, start_mm).unwrap();
    let mut out = HomingRun {
        commands_raw: vec![start_mm, start_mm],
        phases: vec![],
        events: vec![],
        seq: seq.clone(),
    };
    for _ in 0..2_000_000 {
        let actual = sim.actual_mm();
        let sw = simulated_switch_active(h.search_vel_mm_per_s, sim.switch_true_mm, sim.true_mm);
        let st = seq.step(actual, sw);
        if let Some(HomingEvent::Rereferenced { correction_mm }) = st.event {
            sim.correction_mm += correction_mm;
        }
        out.commands_raw.push(st.command_mm - sim.correction_mm);
        if out.phases.last() != Some(&st.phase) {
            out.phases.push(st.phase);
        }
        sim.follow(st.command_mm);
        if let Some(e) = st.event {
            out.events.push(e);
            if matches!(e, HomingEvent::Done | HomingEvent::Failed(_)) {
                break;
            }
        }
    }
    out.seq = seq;
    out
}

/// Home every axis of the incremental profile on exact and lagging axes, from
/// several unknown encoder offsets and starts, either side of the switch.
#[test]
fn homing_finds_the_switch_latches_and_ends_at_home() {
    let p = incremental();
    let hc = p.homing.clone().unwrap();
    for (i, (axis, h)) in p.axes.iter().zip(&hc.axes).enumerate() {
        // true position of the switch's trip point in machine coordinates = switch_mm
        for (tau_s, offset_mm, start_true) in [
            (0.0, 0.0, 0.0),
            (0.0, 123.456, axis.min_mm + 1.0),
            (0.02, -77.7, 0.5 * (axis.min_mm + axis.max_mm)),
            (0.005, 3.21, h.switch_mm + 2.0), // starts on the switch: backs off first
        ] {
            let mut sim = SimAxis {
                true_mm: start_true,
                offset_mm,
                switch_true_mm: h.switch_mm,
                tau_s,
                correction_mm: 0.0,
            };
            let r = home(axis, h, hc.switch_margin_mm, &mut sim);
            let what = format!("axis {i} tau {tau_s} offset {offset_mm} start {start_true}");
            assert_eq!(
                r.events.last(),
                Some(&HomingEvent::Done),
                "{what}: {:?}",
                r.events
            );
            let want_phases: &[HomingPhase] = if start_true > h.switch_mm {
                &[HomingPhase::BackOff, HomingPhase::Search]
            } else {
                &[HomingPhase::Search]
            };
            assert_eq!(&r.phases[..want_phases.len()], want_phases, "{what}");
            assert_eq!(
                &r.phases[want_phases.len()..],
                &[
                    HomingPhase::SearchStop,
                    HomingPhase::Latch,
                    HomingPhase::LatchStop,
                    HomingPhase::Final,
                    HomingPhase::Done
                ],
                "{what}"
            );
            // the latch (midpoint of the two cycles straddling the edge) is within half a
            // cycle's latch travel of the true switch (encoder frame)
            let latch_err = r.seq.latched_mm() - (h.switch_mm - offset_mm);
            assert!(
                latch_err.abs() <= 0.5 * h.latch_vel_mm_per_s.abs() * DT_S + 1e-9,
                "{what}: latch error {latch_err}"
            );
            // corrected coordinates = machine coordinates (to the latch error)
            assert!((r.seq.correction_mm() - offset_mm).abs() <= h.latch_vel_mm_per_s.abs() * DT_S);
            assert_eq!(sim.correction_mm, r.seq.correction_mm());
            // at home, at rest
            assert_eq!(r.seq.command_mm(), h.home_mm, "{what}");
            check_limits(
                &r.commands_raw,
                axis.max_vel_mm_per_s,
                axis.max_acc_mm_per_s2,
            )
            .unwrap_or_else(|e| panic!("{what}: {e}"));
            let n = r.commands_raw.len();
            assert_eq!(
                r.commands_raw[n - 1],
                r.commands_raw[n - 2],
                "{what}: not at rest"
            );
            if tau_s == 0.0 {
                assert_eq!(sim.actual_mm(), h.home_mm, "{what}");
            }
            // the machine position of the actual axis = its true position (± latch error)
            assert!((sim.actual_mm() - sim.true_mm).abs() <= h.latch_vel_mm_per_s.abs() * DT_S);
        }
    }
}

#[test]
fn homing_without_a_switch_fails_at_rest() {
    let p = incremental();
    let hc = p.homing.clone().unwrap();
    let (axis, h) = (&p.axes[0], &hc.axes[0]);
    let mut sim = SimAxis {
        true_mm: 0.0,
        offset_mm: 0.0,
        switch_true_mm: f64::INFINITY, // never trips
        tau_s: 0.0,
        correction_mm: 0.0,
    };
    let r = home(axis, h, hc.switch_margin_mm, &mut sim);
    let travel_mm = axis.max_mm - axis.min_mm + 2.0 * hc.switch_margin_mm;
    let e = HomingError::SwitchNotFound { travel_mm };
    assert_eq!(r.events, vec![HomingEvent::Failed(e)]);
    assert_eq!(r.seq.phase(), HomingPhase::Failed(e));
    check_limits(
        &r.commands_raw,
        axis.max_vel_mm_per_s,
        axis.max_acc_mm_per_s2,
    )
    .unwrap();
    let n = r.commands_raw.len();
    assert_eq!(r.commands_raw[n - 1], r.commands_raw[n - 2], "not at rest");
    assert_eq!(r.seq.command_mm(), travel_mm, "searched the whole travel");
    assert!(e.to_string().contains("not found"));
}

#[test]
fn homing_with_a_stuck_switch_fails_at_rest() {
    let p = incremental();
    let hc = p.homing.clone().unwrap();
    let (axis, h) = (&p.axes[1], &hc.axes[1]);
    let mut sim = SimAxis {
        true_mm: 0.0,
        offset_mm: 0.0,
        switch_true_mm: f64::NEG_INFINITY, // always active
        tau_s: 0.0,
        correction_mm: 0.0,
    };
    let r = home(axis, h, hc.switch_margin_mm, &mut sim);
    assert!(matches!(
        r.events.as_slice(),
        [HomingEvent::Failed(HomingError::SwitchNotReleased { .. })]
    ));
    let n = r.commands_raw.len();
    assert_eq!(r.commands_raw[n - 1], r.commands_raw[n - 2], "not at rest");
}

#[test]
fn homing_from_a_profile_without_homing_is_refused() {
    let p = MotionProfile::from_ron_str(DEFAULT, "default.ron").unwrap();
    assert_eq!(
        HomingSequence::from_profile(&p, 0, 0.0).unwrap_err(),
        ManualError::NoHoming { axis: 0 }
    );
    assert!(HomingSequence::from_profile(&incremental(), 2, 0.0).is_ok());
    assert!(HomingSequence::from_profile(&incremental(), 3, 0.0).is_err());
}

#[test]
fn stepping_allocates_nothing() {
    let p = incremental();
    let hc = p.homing.clone().unwrap();
    let (axis, h) = (&p.axes[2], &hc.axes[2]);
    let mut seq = HomingSequence::from_profile(&p, 2, 0.0).unwrap();
    let mut m = AxisMover::for_axis(axis, 0.0, DT_S).unwrap();
    let mut actual = 0.0;
    let mut correction = 0.0;
    let before = allocs();
    m.move_to(50.0, 100.0).unwrap();
    for k in 0..200_000 {
        if k == 100 {
            m.move_to(-20.0, 300.0).unwrap();
        }
        if k == 150 {
            m.stop();
        }
        m.step();
        let sw = simulated_switch_active(
            h.search_vel_mm_per_s,
            h.switch_mm - 5.0,
            actual - correction,
        );
        let st = seq.step(actual, sw);
        if let Some(HomingEvent::Rereferenced { correction_mm }) = st.event {
            correction += correction_mm;
        }
        actual = st.command_mm;
        if seq.is_done() {
            break;
        }
    }
    assert_eq!(allocs(), before, "manual motion allocated");
    assert!(seq.is_done());
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    /// Any axis of the incremental profile, any unknown encoder offset, any start
    /// within the travel (either side of the switch), exact or lagging axis: homed,
    /// latched within one cycle's latch travel, at rest at home, limits on every sample.
    #[test]
    fn prop_homing(
        i in 0usize..3, offset_mm in -500.0f64..500.0, start_frac in 0.0f64..1.0,
        tau_s in prop_oneof![Just(0.0), 0.001f64..0.05],
    ) {
        let p = incremental();
        let hc = p.homing.clone().unwrap();
        let (axis, h) = (&p.axes[i], &hc.axes[i]);
        let lo = axis.min_mm - hc.switch_margin_mm;
        let hi = axis.max_mm + hc.switch_margin_mm;
        let mut sim = SimAxis {
            true_mm: lo + start_frac * (hi - lo),
            offset_mm,
            switch_true_mm: h.switch_mm,
            tau_s,
            correction_mm: 0.0,
        };
        let r = home(axis, h, hc.switch_margin_mm, &mut sim);
        prop_assert_eq!(r.events.last(), Some(&HomingEvent::Done), "{:?}", r.events);
        let latch_travel_mm = h.latch_vel_mm_per_s.abs() * DT_S;
        // the midpoint of the two cycles straddling the edge: within half a cycle's travel
        let latch_err = r.seq.latched_mm() - (h.switch_mm - offset_mm);
        prop_assert!(latch_err.abs() <= 0.5 * latch_travel_mm + 1e-9, "latch error {}", latch_err);
        prop_assert_eq!(r.seq.command_mm(), h.home_mm);
        check_limits(&r.commands_raw, axis.max_vel_mm_per_s, axis.max_acc_mm_per_s2)
            .map_err(TestCaseError::fail)?;
        prop_assert!((sim.actual_mm() - sim.true_mm).abs() <= latch_travel_mm);
    }
}

/// A homing aborted mid-search (a limit switch, LinuxCNC's HOME_ABORT) brakes
/// within the axis's limits and reports its error once, at rest; a later abort
/// changes nothing.
#[test]
fn an_aborted_homing_brakes_to_rest_and_fails_with_its_error() {
    let p = incremental();
    let hc = p.homing.clone().unwrap();
    let (axis, h) = (&p.axes[0], &hc.axes[0]);
    let mut seq = HomingSequence::new(axis, h, hc.switch_margin_mm, DT_S, 0.0).unwrap();
    let mut cmds = vec![0.0, 0.0];
    // search for 0.5 s (at full search speed by then), then abort
    for _ in 0..500 {
        let c = seq.step(*cmds.last().unwrap(), false).command_mm;
        cmds.push(c);
    }
    assert_eq!(seq.phase(), HomingPhase::Search);
    let e = HomingError::LimitSwitch { max: true };
    seq.abort(e);
    let mut events = vec![];
    for _ in 0..10_000 {
        let st = seq.step(*cmds.last().unwrap(), false);
        cmds.push(st.command_mm);
        events.extend(st.event);
        if matches!(st.phase, HomingPhase::Failed(_)) {
            break;
        }
    }
    assert_eq!(events, vec![HomingEvent::Failed(e)]);
    seq.abort(HomingError::LimitSwitch { max: false });
    assert_eq!(seq.phase(), HomingPhase::Failed(e));
    check_limits(&cmds, axis.max_vel_mm_per_s, axis.max_acc_mm_per_s2).unwrap();
    let n = cmds.len();
    assert_eq!(cmds[n - 1], cmds[n - 2], "not at rest");
    // braked from the search speed: v²/2a past where the abort came (± a cycle)
    let v = h.search_vel_mm_per_s;
    let braking_mm = v * v / (2.0 * axis.max_acc_mm_per_s2);
    let braked_mm = cmds[n - 1] - cmds[501];
    assert!(
        (braked_mm - braking_mm).abs() <= v * DT_S + 1e-9,
        "braked {braked_mm} mm, v²/2a = {braking_mm} mm"
    );
    assert!(e.to_string().contains("maximum limit switch"), "{e}");
}
