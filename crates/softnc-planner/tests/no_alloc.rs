//! Pulling samples allocates nothing (a counting global allocator proves it).

mod common;
use common::*;
use softnc_core::{FeedProfile, Plane, Vec3};

use softnc_test_support::{allocations as allocs, Counting};

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn sample_generation_allocates_nothing() {
    for fp in [FeedProfile::Trapezoidal, FeedProfile::SCurve] {
        let p = profile(fp);
        let mut b = Builder::new(Vec3::ZERO);
        b.rapid(10.0, 10.0, -2.0)
            .line(40.0, 10.0, -2.0, 2400.0)
            .line(40.0, 30.0, -3.0, 2400.0);
        b.arc(
            Vec3::new(40.0, 30.0, -3.0),
            Vec3::new(30.0, 30.0, -3.0),
            Plane::XY,
            1,
            1800.0,
        )
        .dwell(0.1);
        b.line(0.0, 0.0, 0.0, 3000.0);
        let plan = plan_of(&b, &p);
        let mut it = plan.interpolator();
        let before = allocs();
        let mut n = 0u64;
        let mut last = Vec3::ZERO;
        while let Some(s) = it.next() {
            n += 1;
            last = s.pos_mm;
            if n == 500 {
                it.set_feed_override(1.7);
            }
            if n == 50 {
                it.set_rapid_override(0.6);
            }
        }
        let after = allocs();
        assert!(n > 1000);
        assert_eq!(last, b.pos);
        assert_eq!(
            after - before,
            0,
            "{fp:?}: {} allocations while pulling {n} samples",
            after - before
        );
    }
}

/// Pauses, resume and single block switched live allocate nothing either.
#[test]
fn pauses_and_single_block_allocate_nothing() {
    let text = "G21 G64\nG1 X20 F3000\nG1 X20 Y20\nM0\nG1 X0 Y20\nG1 X0 Y0\nG1 X10 Y5\nM2\n";
    for fp in [FeedProfile::Trapezoidal, FeedProfile::SCurve] {
        let p = profile(fp);
        let options = softnc_planner::PlanOptions {
            wait_at_program_stops: true,
            ..Default::default()
        };
        let (_, plan) = softnc_planner::read_and_plan(text, "t.ngc", &p, &options).unwrap();
        let mut it = plan.interpolator();
        let before = allocs();
        let (mut n, mut pauses) = (0u64, 0u32);
        let mut last = Vec3::ZERO;
        while let Some(s) = it.next() {
            n += 1;
            last = s.pos_mm;
            if it.paused_at_line().is_some() {
                pauses += 1;
                it.resume();
            }
            if n == 200 {
                it.set_single_block(true);
            }
        }
        let after = allocs();
        assert!(pauses >= 2, "{fp:?}: {pauses} pauses");
        assert_eq!(last, Vec3::new(10.0, 5.0, 0.0));
        assert_eq!(
            after - before,
            0,
            "{fp:?}: allocations while pulling {n} samples"
        );
    }
}

/// Machine stops and the machine sequencer (outputs per sample, releases from the
/// inputs, the tool change's resume) allocate nothing once built.
#[test]
fn machine_stops_and_the_sequencer_allocate_nothing() {
    use softnc_planner::machine_sequencer::{
        Action, Feedback, MachineSequencer, SequencerConfig, SequencerState,
    };
    let text = "G21 G64\nS8000 M3\nM8\nG1 X20 F3000\nT2 M6\n(MSG, hello)\nM62 P1\n\
                G1 X20 Y20\nM66 P0 L3 Q1\nM67 E1 Q2.5\nG1 X0 Y20\nM5 M9\nM2\n";
    for fp in [FeedProfile::Trapezoidal, FeedProfile::SCurve] {
        let p = profile(fp);
        let options = softnc_planner::PlanOptions {
            wait_at_machine_stops: true,
            ..Default::default()
        };
        let (program, _) =
            softnc_gcode::read_program_with(text, "t.ngc", &p, &options.read_options()).unwrap();
        let plan = softnc_planner::plan(&program, &p, &options).unwrap();
        let cfg = SequencerConfig {
            cycle_s: p.interpolation_cycle_s,
            spindle_at_speed_timeout_s: 5.0,
            user_m_timeout_s: 5.0,
        };
        let mut seq = MachineSequencer::new(&program, cfg, SequencerState::default());
        let mut it = plan.interpolator();
        let mut fb = Feedback::default();
        let before = allocs();
        let (mut n, mut releases, mut digital) = (0u64, 0u32, 0u64);
        let mut last = Vec3::ZERO;
        while let Some(s) = it.next() {
            n += 1;
            last = s.pos_mm;
            fb.applied_motion = Some(s.motion);
            fb.inputs.spindle_at_speed = n % 7 == 0;
            fb.inputs.digital = 1;
            fb.resume = n % 11 == 0;
            let step = seq.step(s.motion, it.machine_stop(), &fb);
            digital |= step.state.outputs.digital;
            match step.action {
                Action::Release => {
                    releases += 1;
                    it.release_machine_stop();
                }
                Action::Fail(e) => panic!("{e}"),
                _ => {}
            }
        }
        let after = allocs();
        assert!(releases >= 6, "{fp:?}: {releases} releases");
        assert_eq!(digital, 2);
        assert_eq!(last, Vec3::new(0.0, 20.0, 0.0));
        assert_eq!(
            after - before,
            0,
            "{fp:?}: allocations while pulling {n} samples"
        );
    }
}
