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
                    if line_of(&program, &s) == 5 {
                        // M2's spindle stop (after S8000 M3) or coolant off (after
                        // M8), at the path's end
                        assert_eq!(s.pos_mm, Vec3::new(20.0, 0.0, 0.0), "{fp:?} {between}");
                        it.release_machine_stop();
                        samples.push(s);
                        continue;
                    }
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
            // (nor does M2: the spindle never turned, the coolant is off)
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

/// The sequencer of `text` and the motion index of its `n`-th machine operation.
fn sequencer_and_stop(text: &str, n: usize) -> (Program, MachineSequencer, u32) {
    let p = profile(FeedProfile::Trapezoidal);
    let (program, _) = read_and_plan(text, "t.ngc", &p, &options()).unwrap();
    let seq = MachineSequencer::new(&program, config(0.001), SequencerState::default());
    let stop = program
        .motions
        .iter()
        .enumerate()
        .filter(|(_, m)| matches!(m.kind, softnc_gcode::MotionKind::Machine(_)))
        .nth(n)
        .unwrap()
        .0 as u32;
    (program, seq, stop)
}

#[test]
fn an_m66_result_is_reported_once_and_fills_the_debug_text_reached_after_it() {
    let text =
        "G21\nM66 P3 L3 Q0.5\n(DEBUG, in=%d#5399)\nG1 X1 F600\nM66 E1\n(PRINT, e=%.1f#5399)\nM2\n";
    let (_, mut seq, m66) = sequencer_and_stop(text, 0);
    let (_, _, debug) = sequencer_and_stop(text, 1);
    let mut inputs = MachineInputs::default();
    let fb = |inputs: MachineInputs, m: u32| Feedback {
        applied_motion: Some(m),
        inputs,
        ..Default::default()
    };
    // P3 low: waits; high: released with 1, reported on that step only
    assert!(matches!(
        seq.step(m66, Some(m66), &fb(inputs, m66)).action,
        Action::Wait(Waiting::Input { .. })
    ));
    inputs.digital = 1 << 3;
    let step = seq.step(m66, Some(m66), &fb(inputs, m66));
    assert_eq!(step.action, Action::Release);
    let r = step.input_result.expect("the M66's result");
    assert_eq!((r.line, r.value, r.timed_out), (2, 1.0, false));
    assert_eq!(r.to_string(), "M66 P3 (line 2): 1 (#5399)");
    assert_eq!(seq.input_result(), Some(1.0));
    // the (DEBUG,…) reached after it shows the machine's value
    let step = seq.step(debug, Some(debug), &fb(inputs, debug));
    assert_eq!(step.input_result, None);
    let i = step.state.message.unwrap();
    let mut shown = String::new();
    seq.write_message(i, &mut shown).unwrap();
    assert_eq!(shown, "in=1");
    // an analog M66 (immediate): its value, then the (PRINT,…) after it
    let (_, _, m66e) = sequencer_and_stop(text, 2);
    let (_, _, print) = sequencer_and_stop(text, 3);
    inputs.analog[1] = 2.25;
    let step = seq.step(m66e, Some(m66e), &fb(inputs, m66e));
    assert_eq!(step.input_result.map(|r| r.value), Some(2.25));
    let step = seq.step(print, None, &fb(inputs, print));
    let mut shown = String::new();
    seq.write_message(step.state.printed.unwrap(), &mut shown)
        .unwrap();
    assert_eq!(shown, "e=2.2");
}

#[test]
fn an_m66_timeout_is_reported_as_minus_one() {
    let (_, mut seq, m66) = sequencer_and_stop("G21\nM66 P0 L4 Q0.01\nM66 P0 L1 Q0.01\nM2\n", 1);
    let fb = Feedback {
        applied_motion: Some(m66),
        inputs: MachineInputs::default(),
        ..Default::default()
    };
    let r = (0..100)
        .find_map(|_| seq.step(m66, Some(m66), &fb).input_result)
        .unwrap();
    assert_eq!((r.value, r.timed_out), (-1.0, true));
    assert_eq!(r.to_string(), "M66 P0 (line 3): timed out: -1 (#5399)");
}

#[test]
fn a_user_m_code_releases_when_done_and_fails_on_its_exit_status_or_timeout() {
    let dir = std::env::temp_dir().join(format!("softnc-seq-m-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let exe = dir.join("M101");
    std::fs::write(&exe, "#!/bin/sh\nexit 0\n").unwrap();
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&exe, std::fs::Permissions::from_mode(0o755)).unwrap();
    }
    let p = profile(FeedProfile::Trapezoidal);
    let opts = PlanOptions {
        user_m_codes: Some(dir.clone()),
        ..options()
    };
    let (program, _) = read_and_plan("G21\nM101 P1 Q2.5\nM2\n", "t.ngc", &p, &opts).unwrap();
    let new = || MachineSequencer::new(&program, config(0.001), SequencerState::default());
    let running = Feedback {
        applied_motion: Some(0),
        ..Default::default()
    };
    let mut seq = new();
    match seq.step(0, Some(0), &running).action {
        Action::Wait(w @ Waiting::UserCommand { code: 101, .. }) => {
            assert_eq!(w.to_string(), "running M101 1.000000 2.500000");
        }
        a => panic!("{a:?}"),
    }
    let done = Feedback {
        user_command_done: true,
        ..running
    };
    assert_eq!(seq.step(0, Some(0), &done).action, Action::Release);
    let failed = Feedback {
        user_command_failed: Some(3),
        ..running
    };
    let mut seq = new();
    assert_eq!(
        seq.step(0, Some(0), &failed).action,
        Action::Fail(SequencerError::UserCommandFailed {
            line: 2,
            code: 101,
            status: 3
        })
    );
    // never done: the configured 5 s
    let mut seq = new();
    let end = (1..10_000)
        .find_map(|k| match seq.step(0, Some(0), &running).action {
            Action::Fail(e) => Some((k, e)),
            _ => None,
        })
        .unwrap();
    assert!(
        matches!(
            end,
            (5000, SequencerError::UserCommandTimeout { code: 101, .. })
        ),
        "{end:?}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn m19_with_q_waits_for_the_spindle_oriented_and_fails_past_q() {
    let text = "G21\nM19 R90 Q0.2 P1\nM19 R45\nM2\n";
    let (program, mut seq, orient) = sequencer_and_stop(text, 0);
    let fb = |oriented: bool| Feedback {
        applied_motion: Some(orient),
        inputs: MachineInputs {
            spindle_oriented: oriented,
            ..Default::default()
        },
        ..Default::default()
    };
    let step = seq.step(orient, Some(orient), &fb(false));
    assert_eq!(step.state.outputs.spindle_orient_deg, Some(90.0));
    assert_eq!(step.state.outputs.spindle_orient_dir, 1);
    assert_eq!(step.state.outputs.spindle_dir, SpindleDir::Stopped);
    assert_eq!(
        step.action,
        Action::Wait(Waiting::SpindleOriented { angle_deg: 90.0 })
    );
    assert_eq!(
        seq.step(orient, Some(orient), &fb(true)).action,
        Action::Release
    );
    // never oriented: LinuxCNC's "wait for orient complete: TIMED OUT" after Q
    let mut seq = MachineSequencer::new(&program, config(0.001), SequencerState::default());
    let end = (1..10_000)
        .find_map(
            |k| match seq.step(orient, Some(orient), &fb(false)).action {
                Action::Fail(e) => Some((k, e)),
                _ => None,
            },
        )
        .unwrap();
    assert!(
        matches!(
            end,
            (200, SequencerError::SpindleNotOriented { line: 2, .. })
        ),
        "{end:?}"
    );
    // without Q LinuxCNC does not wait for it: released once the machine has it
    let (_, _, no_q) = sequencer_and_stop(text, 1);
    let applied = Feedback {
        applied_motion: Some(no_q),
        ..Default::default()
    };
    assert_eq!(seq.step(no_q, Some(no_q), &applied).action, Action::Release);
}

/// A job after `S5000 M3 M8` in an earlier MDI command: its sequencer starts from
/// the outputs the machine holds and the modal state (preamble) says M3 S5000. Its
/// feed moves run at once with the spindle turning (no wait: the spindle is not
/// started again), its own S word while the spindle turns is a speed change that
/// waits for the spindle at speed, and its M2 stops the spindle and the coolant.
#[test]
fn a_job_starts_from_the_held_outputs_and_its_program_end_stops_them() {
    let p = profile(FeedProfile::Trapezoidal);
    let held = softnc_core::MachineOutputs {
        spindle_dir: SpindleDir::Clockwise,
        spindle_rpm: 5000.0,
        coolant_flood: true,
        digital: 0b100,
        ..Default::default()
    };
    let start = SequencerState {
        outputs: held.held_for_next_job(),
        ..SequencerState::default()
    };
    let opts = PlanOptions {
        preamble: Some("G21\nF0 S5000\nG1\nM3\nM8\n".into()),
        ..options()
    };
    let run = |text: &str| {
        let (program, plan) = read_and_plan(text, "t.ngc", &p, &opts).unwrap();
        let mut seq = MachineSequencer::new(&program, config(p.interpolation_cycle_s), start);
        let mut it = plan.interpolator();
        // (motion, line, outputs, a machine stop) of every sample
        let mut rows = Vec::new();
        while let Some(s) = it.next() {
            assert!(rows.len() < MAX_SAMPLES);
            let stop = it.machine_stop();
            let fb = Feedback {
                applied_motion: Some(s.motion),
                inputs: MachineInputs {
                    spindle_at_speed: true,
                    ..Default::default()
                },
                ..Default::default()
            };
            let step = seq.step(s.motion, stop, &fb);
            if step.action == Action::Release {
                it.release_machine_stop();
            }
            rows.push((
                line_of(&program, &s),
                step.state.outputs,
                stop.is_some(),
                s.feed_move,
            ));
        }
        rows
    };
    // a feed alone: the spindle and the coolant on from its first sample, no stop
    // before the feed; M2's stop last, the spindle and the coolant off there, the
    // digital output as it was
    let rows = run("G1 X10 F3000\nM2\n");
    let first = rows[0].1;
    assert_eq!(first.spindle_signed_rpm(), 5000.0);
    assert!(first.coolant_flood && first.digital == 0b100);
    let feed_rows: Vec<_> = rows.iter().filter(|r| r.0 == 1).collect();
    assert!(
        feed_rows.iter().all(|r| !r.2 && r.1 == first),
        "no stop, nothing switched"
    );
    let last = rows.last().unwrap().1;
    assert_eq!(last.spindle_signed_rpm(), 0.0);
    assert!(!last.coolant_flood && last.digital == 0b100);
    assert!(rows.iter().any(|r| r.0 == 2 && r.2), "M2 stands");
    // an S while it turns: a speed change, waited for before the feed
    let rows = run("S6000\nG1 X10 F3000\nM2\n");
    assert_eq!(rows[0].1.spindle_rpm, 6000.0);
    let stood = rows
        .iter()
        .rposition(|r| r.0 == 1 && r.2)
        .expect("S6000 stands");
    assert!(rows[..=stood].iter().all(|r| !r.3), "no feed before it");
}
