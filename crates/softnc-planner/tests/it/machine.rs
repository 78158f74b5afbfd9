//! The machine around the axes in the planner (issue 35): machine operations that
//! LinuxCNC's task waits for motion for stop the path exactly and wait there until
//! the machine sequencer releases them; synchronised outputs do not stop it and
//! switch at the first sample of the next move; a pause reports its own line.

use super::common;
use common::{limit_ratios, profile};
use softnc_core::machine_io::{MachineInputs, SpindleDir};
use softnc_core::MotionProfile;
use softnc_core::{FeedProfile, Vec3};
use softnc_gcode::Program;
use softnc_planner::machine_sequencer::{
    Action, Feedback, MachineSequencer, SequencerConfig, SequencerError, SequencerState, Waiting,
};
use softnc_planner::{plan, Plan, PlanOptions, Sample};

const BOTH: [FeedProfile; 2] = [FeedProfile::Trapezoidal, FeedProfile::SCurve];
const MAX_SAMPLES: usize = 1_000_000;

fn options() -> PlanOptions {
    PlanOptions {
        wait_at_machine_stops: true,
        wait_at_program_stops: true,
        ..Default::default()
    }
}

/// Read `text` whole (its motions kept) and plan it.
fn read_and_plan(
    text: &str,
    file: &str,
    p: &MotionProfile,
    options: &PlanOptions,
) -> Result<(Program, Plan), String> {
    let (program, _) = softnc_gcode::read_program_with(text, file, p, &options.read_options())
        .map_err(|e| e.to_string())?;
    let plan = plan(&program, p, options).map_err(|e| e.to_string())?;
    Ok((program, plan))
}

fn config(cycle_s: f64) -> SequencerConfig {
    SequencerConfig {
        cycle_s,
        spindle_at_speed_timeout_s: 2.0,
        user_m_timeout_s: 5.0,
    }
}

/// The line of a sample's motion.
fn line_of(program: &Program, s: &Sample) -> u32 {
    program.motions[s.motion as usize].line
}

/// Two collinear feeds with `between` on a line of its own between them.
fn collinear_with(between: &str) -> String {
    format!("G21 G90 G64\nG1 X10 F3000\n{between}\nG1 X20\nM2\n")
}

#[test]
fn a_spindle_or_coolant_change_stops_the_path_exactly_and_waits() {
    for fp in BOTH {
        let p = profile(fp);
        for between in [
            "M8",
            "S8000 M3",
            "M5",
            "M9",
            "T2 M6",
            "(MSG, hello)",
            "M64 P3",
        ] {
            let text = collinear_with(between);
            let (program, plan) = read_and_plan(&text, "t.ngc", &p, &options()).unwrap();
            let mut it = plan.interpolator();
            let mut samples: Vec<Sample> = Vec::new();
            let mut stood = 0;
            for _ in 0..MAX_SAMPLES {
                let Some(s) = it.next() else { break };
                if let Some(m) = it.machine_stop() {
                    // standing exactly at the end of the first move, carrying the
                    // operation's own motion (and so its line)
                    assert_eq!(s.pos_mm, Vec3::new(10.0, 0.0, 0.0), "{fp:?} {between}");
                    assert_eq!(s.motion, m, "{fp:?} {between}");
                    assert_eq!(line_of(&program, &s), 3, "{fp:?} {between}");
                    stood += 1;
                    if stood % 20 == 0 {
                        it.release_machine_stop();
                    }
                }
                samples.push(s);
            }
            assert!(it.is_finished(), "{fp:?} {between}");
            assert!(stood >= 20, "{fp:?} {between}: stood {stood} samples");
            assert_eq!(samples.last().unwrap().pos_mm, Vec3::new(20.0, 0.0, 0.0));
            let r = limit_ratios(&samples, &p);
            assert!(
                r[0] <= 1.0 + 1e-9 && r[1] <= 1.0 + 1e-9,
                "{fp:?} {between}: {r:?}"
            );
        }
    }
}

#[test]
fn without_the_wait_a_machine_stop_still_comes_to_rest_exactly_and_goes_on() {
    let p = profile(FeedProfile::Trapezoidal);
    let (_, plan) = read_and_plan(&collinear_with("M8"), "t.ngc", &p, &Default::default()).unwrap();
    let samples: Vec<Sample> = plan.interpolator().collect();
    // (the cycle it arrives in ends there: one sample stands exactly at the point)
    assert!(samples
        .iter()
        .any(|s| s.pos_mm == Vec3::new(10.0, 0.0, 0.0)));
    // the same program without the M8 runs through X10
    let (_, plan) = read_and_plan(&collinear_with(""), "t.ngc", &p, &Default::default()).unwrap();
    let through: Vec<Sample> = plan.interpolator().collect();
    assert!(!through
        .iter()
        .any(|s| s.pos_mm == Vec3::new(10.0, 0.0, 0.0)));
    assert!(through.len() < samples.len());
}

#[test]
fn a_synchronised_output_does_not_stop_and_switches_where_the_next_move_starts() {
    for fp in BOTH {
        let p = profile(fp);
        let text = collinear_with("M62 P1");
        let (program, plan) = read_and_plan(&text, "t.ngc", &p, &options()).unwrap();
        let mut seq = MachineSequencer::new(
            &program,
            config(p.interpolation_cycle_s),
            SequencerState::default(),
        );
        let mut it = plan.interpolator();
        let second_move = program.motions.iter().position(|m| m.line == 4).unwrap() as u32;
        let mut first_on = None;
        let mut speeds = Vec::new();
        let mut last: Option<Sample> = None;
        while let Some(s) = it.next() {
            assert_eq!(it.machine_stop(), None, "{fp:?}: M62 stopped the path");
            let fb = Feedback {
                applied_motion: Some(s.motion),
                ..Default::default()
            };
            let step = seq.step(s.motion, None, &fb);
            let on = step.state.outputs.digital & 2 != 0;
            if on && first_on.is_none() {
                first_on = Some(s);
            }
            assert_eq!(on, s.motion >= second_move, "{fp:?}: at {s:?}");
            if let Some(l) = last {
                speeds.push((s.pos_mm - l.pos_mm).norm());
            }
            last = Some(s);
        }
        let first_on = first_on.expect("the output never switched");
        assert_eq!(first_on.motion, second_move);
        // never at rest between the start and the end of the path
        let moving = &speeds[5..speeds.len() - 5];
        assert!(moving.iter().all(|&d| d > 0.0), "{fp:?}: the path stopped");
    }
}

/// The acceptance job's machine codes, through the sequencer with a scripted
/// machine: the spindle reaches its speed after a number of cycles, the operator
/// resumes the tool change and the M0, the M66 input is high.
#[test]
fn the_acceptance_job_runs_through_the_sequencer() {
    let text = "G21 G90 G64\n\
        S8000 M3\n\
        M8\n\
        G1 X10 F3000\n\
        T2 M6\n\
        (MSG, insert tool 2 and press resume)\n\
        M0\n\
        M62 P1\n\
        G1 X20\n\
        M66 P0 L3 Q2\n\
        G1 X30\n\
        M5 M9 M30\n";
    let p = profile(FeedProfile::Trapezoidal);
    let (program, plan) = read_and_plan(text, "t.ngc", &p, &options()).unwrap();
    let cycle_s = p.interpolation_cycle_s;
    let mut seq = MachineSequencer::new(&program, config(cycle_s), SequencerState::default());
    let mut it = plan.interpolator();
    let mut inputs = MachineInputs {
        spindle_at_speed: true,
        ..Default::default()
    };
    let (mut spin_up, mut prompts, mut paused_lines) = (0u32, Vec::new(), Vec::new());
    let mut feed_before_speed = false;
    let mut messages = Vec::new();
    let mut n = 0;
    while let Some(s) = it.next() {
        n += 1;
        assert!(n < MAX_SAMPLES);
        let mut fb = Feedback {
            inputs,
            applied_motion: Some(s.motion),
            ..Default::default()
        };
        if let Some(line) = it.paused_at_line() {
            paused_lines.push((line, line_of(&program, &s)));
            it.resume();
        }
        let stop = it.machine_stop();
        // the scripted machine: the spindle comes up 50 cycles after its command
        let step0 = seq.step(s.motion, stop, &fb);
        let out = step0.state.outputs;
        if out.spindle_dir == SpindleDir::Clockwise && spin_up < 50 {
            spin_up += 1;
            inputs.spindle_at_speed = false;
        } else {
            inputs.spindle_at_speed = true;
        }
        if s.feed_move && !inputs.spindle_at_speed && out.spindle_dir != SpindleDir::Stopped {
            feed_before_speed = true;
        }
        if let Some(m) = step0.state.message {
            if messages.last() != Some(&m) {
                messages.push(m);
            }
        }
        inputs.digital = 1; // M66 P0: high
        match step0.action {
            Action::Release => it.release_machine_stop(),
            Action::Wait(w @ Waiting::ToolChange { tool }) => {
                assert_eq!(tool, 2);
                prompts.push(w.to_string());
                fb.resume = true;
                if let Action::Release = seq.step(s.motion, stop, &fb).action {
                    it.release_machine_stop();
                }
            }
            Action::Wait(_) | Action::Run => {}
            Action::Fail(e) => panic!("{e}"),
        }
    }
    assert!(
        !feed_before_speed,
        "a feed move ran before the spindle was at speed"
    );
    assert_eq!(spin_up, 50);
    assert_eq!(
        prompts.first().map(String::as_str),
        Some("insert T2, then resume")
    );
    assert_eq!(paused_lines, vec![(7, 7)], "the M0 reports its own line");
    assert_eq!(messages.len(), 1);
    assert_eq!(
        seq.message_text(messages[0]),
        Some(" insert tool 2 and press resume")
    );
    assert_eq!(seq.input_result(), Some(1.0));
    let end = seq.state_at(program.motions.len() as u32);
    assert_eq!(end.outputs.spindle_dir, SpindleDir::Stopped);
    assert!(!end.outputs.coolant_flood);
    assert_eq!(end.tool_in_spindle, 2);
    assert_eq!(end.outputs.digital, 2);
}

/// Drive a lone `S… M3` stop with a scripted at-speed input: `Some(n)` at speed
/// after n applied cycles, `None` never.
fn spindle_wait(at_speed_after: Option<u32>) -> (u32, Action) {
    let text = "G21\nG1 X1 F600\nS8000 M3\nG1 X2\nM2\n";
    let p = profile(FeedProfile::Trapezoidal);
    let (program, _) = read_and_plan(text, "t.ngc", &p, &options()).unwrap();
    let mut seq = MachineSequencer::new(&program, config(0.001), SequencerState::default());
    let stop = program
        .motions
        .iter()
        .position(|m| matches!(m.kind, softnc_gcode::MotionKind::Machine(_)))
        .unwrap() as u32;
    let mut applied = 0;
    for cycle in 0..10_000u32 {
        // the machine gets the command three cycles after the interpolator
        let lagging = cycle < 3;
        let fb = Feedback {
            applied_motion: if lagging { Some(stop - 1) } else { Some(stop) },
            inputs: MachineInputs {
                // at speed from the old command until it arrives (a stopped spindle
                // commanded to stand is at speed)
                spindle_at_speed: lagging || at_speed_after.is_some_and(|n| applied >= n),
                ..Default::default()
            },
            ..Default::default()
        };
        if !lagging {
            applied += 1;
        }
        match seq.step(stop, Some(stop), &fb).action {
            Action::Wait(Waiting::Applied) => assert!(lagging),
            Action::Wait(Waiting::SpindleAtSpeed { .. }) => {}
            a => return (cycle, a),
        }
    }
    panic!("never decided");
}

#[test]
fn the_spindle_stop_releases_at_speed_and_fails_past_its_timeout() {
    // inputs read before the command reached the machine do not release it
    let (cycle, action) = spindle_wait(Some(40));
    assert_eq!(action, Action::Release);
    assert_eq!(cycle, 3 + 40);
    // never at speed: the profile's 2 s, then an error naming the line
    let (cycle, action) = spindle_wait(None);
    match action {
        Action::Fail(SequencerError::SpindleNotAtSpeed {
            line,
            rpm,
            waited_s,
        }) => {
            assert_eq!((line, rpm), (3, 8000.0));
            assert!((waited_s - 2.0).abs() < 1e-9, "{waited_s}");
            assert_eq!(cycle, 1999);
        }
        a => panic!("{a:?}"),
    }
}

#[test]
fn m66_times_out_with_minus_one() {
    let text = "G21\nM66 P3 L3 Q0.5\nG1 X1 F600\nM2\n";
    let p = profile(FeedProfile::Trapezoidal);
    let (program, _) = read_and_plan(text, "t.ngc", &p, &options()).unwrap();
    let mut seq = MachineSequencer::new(&program, config(0.001), SequencerState::default());
    let fb = Feedback {
        applied_motion: Some(0),
        ..Default::default()
    };
    let mut cycles = 0;
    loop {
        cycles += 1;
        match seq.step(0, Some(0), &fb).action {
            Action::Wait(Waiting::Input { .. }) => {}
            Action::Release => break,
            a => panic!("{a:?}"),
        }
    }
    assert_eq!(cycles, 500);
    assert_eq!(seq.input_result(), Some(-1.0));
}
