//! End-to-end tests of the runtime: softncd and its three processes driven through the
//! operator client, on the simulated machine. Each test runs its own controller
//! instance (service names, data directory), so tests can run side by side.

mod support;
use support::*;

#[test]
fn lockstep_job_through_three_processes_equals_the_simulator_bit_for_bit() {
    lockstep_equals_simulator("run", "default.ron");
}

#[test]
fn lockstep_with_the_zero_lag_filter_equals_the_simulator_bit_for_bit() {
    // paper 002's filter (N = 75) and a structural mode: the position process reads the
    // window [i−N, i+N] of its ring exactly as the simulator does
    lockstep_equals_simulator("fir", "mill-resonance.ron");
}

#[test]
fn lockstep_with_s_words_and_the_pdc_equals_the_simulator_bit_for_bit() {
    // paper 000's TNV-40 with its PDC, a job changing the spindle speed twice: the
    // preparation thread designs the tables the simulator designs, swapped at the same
    // cycles
    lockstep_equals_simulator_on("pdc", "tnv40-dob-pdc.ron", |dir| {
        let p = dir.join("s-words.ngc");
        std::fs::write(
            &p,
            "G21 G90 G17 G94\nG0 X0 Y0\nS1500 M3\nG1 X2 Y1 F600\nS1800\nG1 X4 Y0\nS1200\nG1 X2 Y-1\nM5\nM2\n",
        )
        .unwrap();
        p
    });
}

#[test]
fn lockstep_with_machine_waits_equals_the_simulator_bit_for_bit() {
    // issue 35's acceptance job without its M0 (the simulator has no operator to
    // resume it): the spindle's run-up on its model gates the feed, the tool change
    // waits for the simulated changer's tool-changed (2 s), M66 for its input until
    // its 2 s timeout, each stop released at the same sample (the machine heard
    // `lookahead` samples late in both)
    lockstep_equals_simulator_on("machinewait", "default.ron", |dir| {
        let text = std::fs::read_to_string(repo().join("examples/machine/acceptance.ngc"))
            .unwrap()
            .replace("M0\n", "");
        assert!(!text.contains("M0\n"));
        let p = dir.join("machine-waits.ngc");
        std::fs::write(&p, text).unwrap();
        p
    });
}

fn lockstep_equals_simulator(tag: &str, machine: &str) {
    lockstep_equals_simulator_on(tag, machine, short_job)
}

fn lockstep_equals_simulator_on(tag: &str, machine: &str, job: impl Fn(&Path) -> PathBuf) {
    let d = Daemon::start_on(tag, "Lockstep", true, machine);
    let op = d.operator();
    let job = job(&d.dir);
    let r = op.request(&submit(&abs(&job))).unwrap();
    assert!(r.is_accepted(), "{}", r.message());
    let s = d.wait_job(&op, r.job_id().unwrap(), Duration::from_secs(120));
    assert_eq!(job_of(&s).outcome, Outcome::Completed, "{s}");
    assert!(s.alarms.is_empty(), "{s}");
    let sim_trace = d.dir.join("sim.csv");
    simulator_trace(&job, &d.dir.join("machines/default.ron"), &sim_trace);
    let want = std::fs::read(&sim_trace).unwrap();
    let got = d.trace_of(r.job_id().unwrap(), want.len());
    assert_same_trace(&got, &want);
}

/// The two traces are byte-identical (else: where they first differ).
fn assert_same_trace(got: &[u8], want: &[u8]) {
    assert!(want.len() > 10_000, "simulator trace too short");
    if got != want {
        let (g, w) = (String::from_utf8_lossy(got), String::from_utf8_lossy(want));
        let first = g.lines().zip(w.lines()).position(|(a, b)| a != b);
        panic!(
            "daemon trace ({} lines) differs from the simulator's ({} lines) first at line {first:?}:\n{:?}\n{:?}",
            g.lines().count(),
            w.lines().count(),
            first.and_then(|i| g.lines().nth(i)),
            first.and_then(|i| w.lines().nth(i))
        );
    }
}

#[test]
#[allow(clippy::too_many_lines)]
fn adaptive_force_in_the_daemon_holds_the_force_where_the_depth_changes_bit_for_bit_as_the_simulator(
) {
    // paper 003's case I on its machine: a cut through 2, 3.5 and 5 mm of duralumin
    // with the force loop closed in the position process and its override applied by
    // the interpolator; the operator's override (255 %) is its ceiling
    let d = Daemon::start_on("adaptive", "Lockstep", true, "mch10-force.ron");
    let op = d.operator();
    let job = d.dir.join("cut.ngc");
    std::fs::write(&job, "G21 G90 G17 G94\nS600 M3\nG1 X90 F200\nM5\nM2\n").unwrap();
    let r = op
        .request(&Request::FeedOverride { fraction: 2.55 })
        .unwrap();
    assert!(r.is_accepted(), "{}", r.message());
    let r = op
        .request(&Request::SubmitJob {
            path: abs(&job),
            from_line: None,
            adaptive_force: true,
        })
        .unwrap();
    assert!(r.is_accepted(), "{}", r.message());
    let s = d.wait_job(&op, r.job_id().unwrap(), Duration::from_secs(120));
    assert_eq!(job_of(&s).outcome, Outcome::Completed, "{s}");
    assert!(s.alarms.is_empty(), "{s}");
    let jobs = op.jobs().unwrap();
    let rec = jobs
        .iter()
        .find(|j| j.job_id == r.job_id().unwrap())
        .unwrap();
    assert!(rec.adaptive_force, "{rec}");

    // the simulator, the same job: the same samples, overrides and machine
    let profile =
        softnc_machine::MachineProfile::load(&d.dir.join("machines/default.ron")).unwrap();
    let latency = softnc_daemon::config::DaemonConfig::load(&d.config)
        .unwrap()
        .config
        .lookahead_samples as u64;
    let text = std::fs::read_to_string(&job).unwrap();
    let program = softnc_gcode::read_program(&text, &job.display().to_string(), &profile).unwrap();
    let options = softnc_planner::PlanOptions {
        wait_at_machine_stops: true,
        ..Default::default()
    };
    let plan = softnc_planner::plan(&program, &profile, &options).unwrap();
    let (seq, heard) =
        softnc_daemon::plan_samples::sim_machine(&program, &profile, &options, latency);
    let mut engine = softnc_sim::simulated_engine(
        &profile,
        profile.servo.seed,
        softnc_sim::SimOptions::default(),
    );
    engine
        .set_spindle_schedule(&profile, plan.spindle_changes(), 1.0)
        .unwrap();
    let mut feed = softnc_servo::adaptive_feed::AdaptiveFeed::from_profile(&profile, 2.55).unwrap();
    let sim_trace = d.dir.join("sim.csv");
    let mut file = softnc_daemon::trace::TraceFile::create(&sim_trace).unwrap();
    // per revolution: the stock's segment (None across a change) and its true peak force
    let mut revs: Vec<(Option<usize>, f64)> = Vec::new();
    let (mut peak, mut seg0, mut across) = (0.0f64, None, false);
    softnc_sim::simulate_adaptive(
        &mut engine,
        plan.cycle_s(),
        softnc_daemon::plan_samples::PlanSamples::with_machine(
            plan.interpolator(),
            seq,
            heard.clone(),
        ),
        &mut feed,
        latency,
        2.55,
        |m| plan.motion_primitive(m as usize),
        |row, engine, seq, rev| {
            softnc_daemon::plan_samples::hear(&heard, seq, row, engine);
            file.row(row).unwrap();
            let b = engine.backend();
            let stock = b.stock().unwrap();
            let seg = stock.segment_at(b.true_pos_mm()[0]);
            across |= seg != seg0;
            peak = peak.max(stock.force_n());
            if rev.is_some() {
                revs.push((if across { None } else { seg }, peak));
                (peak, seg0, across) = (0.0, seg, false);
            }
        },
    )
    .unwrap();
    file.finish().unwrap();
    let want = std::fs::read(&sim_trace).unwrap();
    let got = d.trace_of(r.job_id().unwrap(), want.len());
    assert_same_trace(&got, &want);

    // the force: at the reference within 5 % once settled in every depth
    let (_, case) = profile.force.as_ref().unwrap().adaptive_case().unwrap();
    let f_ref = case.force_ref_n;
    let mut settled_feed_mm_per_s = Vec::new();
    for (i, seg) in case.segments.iter().enumerate() {
        let forces: Vec<f64> = revs
            .iter()
            .filter(|r| r.0 == Some(i))
            .map(|r| r.1)
            .collect();
        let n = case.settled_revolutions as usize;
        assert!(
            forces.len() > n,
            "segment {i}: {} revolutions",
            forces.len()
        );
        let last = &forces[forces.len() - n..];
        let mean = last.iter().sum::<f64>() / n as f64;
        assert!(
            (mean - f_ref).abs() <= 0.05 * f_ref,
            "segment {i} ({} mm deep): {mean:.1} N against {f_ref} N",
            seg.depth_mm
        );
        // the daemon's trace: the feed it ran at in the segment's settled stretch
        // (X command advance per cycle, its last second before the segment ends)
        let end_mm: f64 = case.segments[..=i].iter().map(|s| s.length_mm).sum();
        let xs: Vec<f64> = String::from_utf8_lossy(&got)
            .lines()
            .skip(1)
            .map(|l| l.split(',').nth(1).unwrap().parse::<f64>().unwrap())
            .filter(|x| *x < end_mm - 1.0 && *x > end_mm - 6.0)
            .collect();
        let v = (xs.last().unwrap() - xs[0]) / ((xs.len() - 1) as f64 * plan.cycle_s());
        settled_feed_mm_per_s.push(v);
    }
    // slower in deeper cuts, faster than programmed in the shallow one (the loop
    // raised the override above 100 %, within the operator's 255 %)
    let f = &settled_feed_mm_per_s;
    assert!(
        f[0] > 200.0 / 60.0 && f[0] > f[1] && f[1] > f[2],
        "{f:?} mm/s"
    );
}

/// Contour-error RMS (µm) of a trace (its `contour_um` column, feed moves only).
fn trace_contour_rms_um(trace: &[u8]) -> f64 {
    let (mut n, mut sq) = (0usize, 0.0f64);
    for line in String::from_utf8_lossy(trace).lines().skip(1) {
        let c = line.rsplit(',').next().unwrap();
        if !c.is_empty() {
            let v: f64 = c.parse().unwrap();
            n += 1;
            sq += v * v;
        }
    }
    assert!(n > 1000, "{n} feed-move rows");
    (sq / n as f64).sqrt()
}

#[test]
fn a_learned_job_runs_with_its_correction_bit_for_bit_as_the_simulator_and_far_more_accurately() {
    // paper 002's learning on default.ron (Coulomb friction, stick–slip): the job of
    // `softnc reproduce 002-learning` (3.2 s of lines and arcs at 3 m/min)
    let d = Daemon::start_on("learned", "Lockstep", true, "default.ron");
    let op = d.operator();
    let job = d.dir.join("lines-arcs.ngc");
    std::fs::copy(repo().join("examples/learning/lines-arcs.ngc"), &job).unwrap();
    let machine = d.dir.join("machines/default.ron");
    let store = d.dir.join("learning"); // the config's learning_dir
    let run = |what: &str| {
        let r = op.request(&submit(&abs(&job))).unwrap();
        assert!(r.is_accepted(), "{}", r.message());
        let s = d.wait_job(&op, r.job_id().unwrap(), Duration::from_secs(120));
        assert_eq!(job_of(&s).outcome, Outcome::Completed, "{what}: {s}");
        assert!(s.alarms.is_empty(), "{what}: {s}");
        d.wait_status(&op, Duration::from_secs(10), "idle", |s| {
            s.state == MachineState::Idle
        });
        (r.job_id().unwrap(), s)
    };
    // before learning: no entry, no note, the unlearned trace
    let (before_id, s) = run("unlearned");
    assert!(job_of(&s).notes.is_empty(), "{s}");
    let sim = d.dir.join("sim.csv");
    simulator_trace(&job, &machine, &sim);
    let want = std::fs::read(&sim).unwrap();
    let before = d.trace_of(before_id, want.len());
    assert_same_trace(&before, &want);
    let rms_before = trace_contour_rms_um(&before);

    let learning = learn_job(&store, &job, &machine, 4);
    let (after_id, s) = run("learned");
    let notes = job_of(&s).notes.join("\n");
    assert!(notes.contains("learned correction applied"), "{s}");
    simulator_trace_learned(&job, &machine, &sim, Some(&store));
    let want = std::fs::read(&sim).unwrap();
    let after = d.trace_of(after_id, want.len());
    assert_same_trace(&after, &want);
    // with the learnt hold tail the correction runs out to zero: the learned job ends
    // on its programmed end point (not off it by the correction of its last planned
    // sample, which leads the decelerating axes)
    let rows = |t: &[u8]| String::from_utf8_lossy(t).lines().count();
    let tail = (softnc_learning::entry::HOLD_S / 1e-3).round() as usize;
    assert_eq!(
        rows(&after),
        rows(&before) + tail,
        "the learned run's hold tail"
    );
    let last_cmd = |t: &[u8]| -> Vec<f64> {
        let text = String::from_utf8_lossy(t).into_owned();
        let line = text.lines().last().unwrap().to_string();
        line.split(',')
            .skip(1)
            .take(3)
            .map(|v| v.parse().unwrap())
            .collect()
    };
    assert_eq!(
        last_cmd(&after),
        last_cmd(&before),
        "the learned job's end point"
    );
    let rms_after = trace_contour_rms_um(&after);
    eprintln!(
        "daemon contour-error RMS: {rms_before:.3} µm unlearned, {rms_after:.3} µm learned \
         (learning runs on the simulator: {learning:.3?} µm); status accuracy {:?}",
        job_of(&s).accuracy
    );
    assert!(
        rms_after < 0.1 * rms_before,
        "learned {rms_after:.3} µm vs unlearned {rms_before:.3} µm"
    );
}

#[test]
fn a_feed_override_fades_the_learned_correction_out_and_notes_it() {
    let d = Daemon::start_on("fade", "Realtime", false, "default.ron");
    let op = d.operator();
    let job = d.dir.join("lines-arcs.ngc");
    std::fs::copy(repo().join("examples/learning/lines-arcs.ngc"), &job).unwrap();
    let machine = d.dir.join("machines/default.ron");
    learn_job(&d.dir.join("learning"), &job, &machine, 2);
    let r = op.request(&submit(&abs(&job))).unwrap();
    assert!(r.is_accepted(), "{}", r.message());
    d.wait_status(&op, Duration::from_secs(20), "motion", |s| {
        s.job.as_ref().map_or(0, |j| j.record.cycles) > 1000
    });
    let o = op
        .request(&Request::FeedOverride { fraction: 0.5 })
        .unwrap();
    assert!(o.is_accepted(), "{}", o.message());
    let s = d.wait_job(&op, r.job_id().unwrap(), Duration::from_secs(60));
    assert_eq!(job_of(&s).outcome, Outcome::Completed, "{s}");
    assert!(s.alarms.is_empty(), "{s}");
    let notes = job_of(&s).notes.join("\n");
    assert!(notes.contains("learned correction applied"), "{notes}");
    assert!(
        notes.contains("faded out from sample") && notes.contains("feed override changed"),
        "{notes}"
    );
    // faded to nothing: the job ends on its programmed end point, not off it by the
    // last learned correction
    let end = d.wait_status(&op, Duration::from_secs(10), "idle", |s| {
        s.state == MachineState::Idle
    });
    let profile = softnc_machine::MachineProfile::load(&machine).unwrap();
    let text = std::fs::read_to_string(&job).unwrap();
    let (_, plan) =
        softnc_planner::read_and_plan(&text, "job.ngc", &profile, &Default::default()).unwrap();
    let last = plan.interpolator().last().unwrap().pos_mm.0;
    let cmd: Vec<f64> = end.axes.as_ref().unwrap().cmd_mm.clone();
    for a in 0..3 {
        assert!(
            (cmd[a] - last[a]).abs() < 1e-9,
            "axis {a}: command {} mm at the end, planned {} mm",
            cmd[a],
            last[a]
        );
    }
}

#[test]
fn jobs_run_one_after_another() {
    let d = Daemon::start("seq", "Lockstep", false);
    let op = d.operator();
    let job = short_job(&d.dir);
    for _ in 0..3 {
        let r = op.request(&submit(&abs(&job))).unwrap();
        assert!(r.is_accepted(), "{}", r.message());
        let s = d.wait_job(&op, r.job_id().unwrap(), Duration::from_secs(60));
        assert_eq!(job_of(&s).outcome, Outcome::Completed, "{s}");
        let s = d.wait_status(&op, Duration::from_secs(10), "idle", |s| {
            s.state == MachineState::Idle
        });
        // a job ends with the axes in position (the profile's 10 µm band), and the
        // servo goes on holding them there (it was frozen, 126 µm off, before)
        let band_um = 10.0;
        let mut s = s;
        for _ in 0..3 {
            let fe: Vec<f64> = s.axes.as_ref().unwrap().following_err_um.clone();
            assert!(fe.iter().all(|e| e.abs() <= band_um), "in position: {s}");
            std::thread::sleep(Duration::from_millis(100));
            s = op.status().unwrap();
        }
    }
    // the feed override is the machine's: set between jobs, the next job runs at it
    let o = op
        .request(&Request::FeedOverride { fraction: 0.5 })
        .unwrap();
    assert!(o.is_accepted(), "{}", o.message());
    let r = op.request(&submit(&abs(&job))).unwrap();
    let s = d.wait_job(&op, r.job_id().unwrap(), Duration::from_secs(60));
    assert_eq!(job_of(&s).outcome, Outcome::Completed, "{s}");
    assert_eq!(s.feed_override, 0.5);
    let (cycles, planned) = (job_of(&s).cycles, job_of(&s).planned_samples);
    assert!(
        cycles as f64 > 1.6 * planned as f64,
        "at 50 % the job takes about twice its planned {planned} cycles, not {cycles}"
    );
    // the rapid override (issue 35): a rapid-only job at 50 % takes about twice as
    // long as at 100 % (the feed override leaves traverses alone)
    let rapids = d.dir.join("rapids.ngc");
    std::fs::write(
        &rapids,
        "G21 G90 G61\nG0 X0 Y0 Z0\nG0 X350 Y200\nG0 X-350 Y-200 Z-250\nG0 X300 Y0 Z50\nG0 X0 Y0 Z0\nM2\n",
    )
    .unwrap();
    let run = |op: &softnc_client::Operator| {
        let r = op.request(&submit(&abs(&rapids))).unwrap();
        assert!(r.is_accepted(), "{}", r.message());
        let s = d.wait_job(op, r.job_id().unwrap(), Duration::from_secs(60));
        assert_eq!(job_of(&s).outcome, Outcome::Completed, "{s}");
        (job_of(&s).cycles, s.rapid_override)
    };
    // (the first run starts where the last job left the machine: the second
    // starts at the origin, as the third)
    run(&op);
    let (full, at) = run(&op);
    assert_eq!(at, 1.0);
    let o = op
        .request(&Request::RapidOverride { fraction: 0.5 })
        .unwrap();
    assert!(o.is_accepted(), "{}", o.message());
    let (half, at) = run(&op);
    assert_eq!(at, 0.5);
    let ratio = half as f64 / full as f64;
    eprintln!("rapids: {full} cycles at 100 %, {half} at 50 % ({ratio:.3})");
    assert!(
        (1.8..=2.05).contains(&ratio),
        "rapids at 50 %: {half} cycles against {full} at 100 %"
    );
    let o = op
        .request(&Request::RapidOverride { fraction: 1.5 })
        .unwrap();
    assert!(!o.is_accepted(), "150 % accepted: {}", o.message());
}

#[test]
fn a_bad_job_is_refused_with_its_position_and_nothing_moves() {
    let d = Daemon::start("bad", "Lockstep", false);
    let op = d.operator();
    let bad = d.dir.join("bad.ngc");
    std::fs::write(&bad, "G21 G90\nG1 X10 Y10 F600\nG2 X20 Y0 R1\nM2\n").unwrap();
    let far = d.dir.join("far.ngc");
    std::fs::write(&far, "G21 G90\nG0 X900\nM2\n").unwrap();
    for (file, want) in [(&bad, "bad.ngc:3:"), (&far, "far.ngc:2:")] {
        let r = op.request(&submit(&abs(file))).unwrap();
        assert!(!r.is_accepted());
        assert!(r.message().contains(want), "{}", r.message());
    }
    // adaptive feed on a machine without a force model: refused by name
    let good = d.dir.join("good.ngc");
    std::fs::write(&good, "G21 G90\nG1 X10 F600\nM2\n").unwrap();
    let r = op
        .request(&Request::SubmitJob {
            path: abs(&good),
            from_line: None,
            adaptive_force: true,
        })
        .unwrap();
    assert!(!r.is_accepted());
    assert!(
        r.message().contains("force.adaptive_feed"),
        "{}",
        r.message()
    );
    let s = op.status().unwrap();
    assert_eq!(s.state, MachineState::Idle);
    assert!(s.job.is_none(), "no job was started: {s}");
}

#[test]
fn killing_the_interpolator_stops_along_the_path_and_a_reset_recovers() {
    let mut d = Daemon::start("kill", "Realtime", true);
    let op = d.operator();
    let job = short_job(&d.dir);
    let r = op.request(&submit(&abs(&job))).unwrap();
    assert!(r.is_accepted());
    // a second client cannot start another job while this one runs
    let op2 = d.operator();
    let busy = op2.request(&submit(&abs(&job))).unwrap();
    assert!(!busy.is_accepted(), "{}", busy.message());
    d.wait_status(&op, Duration::from_secs(20), "motion", |s| {
        s.job.as_ref().map_or(0, |j| j.record.cycles) > 800
    });
    d.kill9("softnc-interp");
    let s = d.wait_status(&op, Duration::from_secs(10), "fault", |s| {
        s.state == MachineState::Faulted
    });
    let alarms = alarm_text(&s);
    assert!(
        alarms.contains("RingDry") || alarms.contains("ran dry"),
        "{alarms}"
    );
    // the axes stopped along the path: no jump anywhere, also not where the ring
    // ran dry
    assert_stops_along_the_path(
        &d.dir
            .join(format!("data/trace-job{}.csv", r.job_id().unwrap())),
    );
    // a second client cannot start a job on a faulted machine
    let again = op.request(&submit(&abs(&job))).unwrap();
    assert!(!again.is_accepted(), "{}", again.message());
    // the operator sees the interpolator's death and its restart (a job started
    // before the death is told is lost with the dead process: see
    // `a_job_sent_to_a_dead_interpolator_is_aborted_when_its_death_is_told`)
    d.wait_status(&op, Duration::from_secs(10), "interp restarted", |s| {
        alarm_text(s).contains("softnc-interp started again")
    });
    // reset (the drives stay off), on; the supervisor has restarted the
    // interpolator: a new job runs
    op.request(&Request::Reset).unwrap();
    d.wait_status(&op, Duration::from_secs(10), "off + interp alive", |s| {
        s.state == MachineState::Off && s.processes.interp == ProcessHealth::Alive
    });
    op.machine_on(Duration::from_secs(10)).unwrap();
    let r2 = op.request(&submit(&abs(&job))).unwrap();
    assert!(r2.is_accepted(), "{}", r2.message());
    let s = d.wait_job(&op, r2.job_id().unwrap(), Duration::from_secs(60));
    assert_eq!(job_of(&s).outcome, Outcome::Completed, "{s}");
    drop(op);
    drop(op2);
    d.shutdown_leaving_nothing("kill");
}

#[test]
fn killing_the_mmi_leaves_motion_running_and_the_client_reconnects() {
    let mut d = Daemon::start("mmi", "Realtime", false);
    let op = d.operator();
    let job = short_job(&d.dir);
    let r = op.request(&submit(&abs(&job))).unwrap();
    assert!(r.is_accepted());
    d.wait_status(&op, Duration::from_secs(20), "motion", |s| {
        s.job.as_ref().map_or(0, |j| j.record.cycles) > 300
    });
    d.kill9("softnc-mmi");
    std::thread::sleep(Duration::from_millis(300));
    let op2 = d.operator();
    let s = d.wait_job(&op2, r.job_id().unwrap(), Duration::from_secs(60));
    assert_eq!(
        job_of(&s).outcome,
        Outcome::Completed,
        "motion continued without the MMI: {s}"
    );
    drop(op);
    drop(op2);
    d.shutdown_leaving_nothing("mmi");
}

#[test]
fn a_job_sent_to_a_dead_interpolator_is_aborted_when_its_death_is_told() {
    // the race a loaded machine opens: the interpolator dies, and a job is
    // submitted before the supervisor has told anyone (here: the supervisor is
    // stopped until the job is in); the job must not wait for ever for samples
    // no one will send
    let d = Daemon::start("deadinterp", "Realtime", false);
    let op = d.operator();
    let softncd = d.child.id();
    signal(softncd, "-STOP");
    d.kill9("softnc-interp");
    let job = short_job(&d.dir);
    let r = op.request(&submit(&abs(&job))).unwrap();
    signal(softncd, "-CONT");
    if r.is_accepted() {
        let s = d.wait_job(&op, id(&r), Duration::from_secs(10));
        let record = &s.job(id(&r)).unwrap().record;
        assert_eq!(record.outcome, Outcome::Aborted, "{s}");
        assert!(
            record
                .alarms
                .iter()
                .any(|a| a.contains("softnc-interp exited")),
            "{s}"
        );
    }
    // the restarted interpolator runs the next job
    d.wait_status(&op, Duration::from_secs(10), "interp restarted", |s| {
        alarm_text(s).contains("softnc-interp started again")
            && s.processes.interp == ProcessHealth::Alive
            && s.state == MachineState::Idle
    });
    let r = op.request(&submit(&abs(&job))).unwrap();
    assert!(r.is_accepted(), "{}", r.message());
    let s = d.wait_job(&op, id(&r), Duration::from_secs(60));
    assert_eq!(job_of(&s).outcome, Outcome::Completed, "{s}");
    drop(op);
}

#[test]
fn killing_the_position_process_faults_and_reset_restarts_it() {
    let mut d = Daemon::start("pos", "Realtime", false);
    let op = d.operator();
    // mid-job: the servo loop (the simulated drives) dies under a moving job
    let killed_job = start_moving(&d, &op);
    d.kill9("softnc-position");
    let s = d.wait_status(&op, Duration::from_secs(10), "fault", |s| {
        s.processes.position == ProcessHealth::Lost
    });
    let _ = s;
    let s = d.wait_status(&op, Duration::from_secs(10), "alarm", |s| {
        alarm_text(s).contains("ProcessLost")
    });
    assert!(alarm_text(&s).contains("softnc-position"), "{s}");
    assert_eq!(s.state, MachineState::Faulted, "{s}");
    assert_eq!(
        d.job_record(killed_job).map(|j| j.outcome),
        Some(Outcome::Aborted)
    );
    op.request(&Request::Reset).unwrap();
    d.wait_status(&op, Duration::from_secs(15), "position back, off", |s| {
        s.processes.position == ProcessHealth::Alive && s.state == MachineState::Off
    });
    op.machine_on(Duration::from_secs(10)).unwrap();
    let job = short_job(&d.dir);
    let r = op.request(&submit(&abs(&job))).unwrap();
    assert!(r.is_accepted(), "{}", r.message());
    let s = d.wait_job(&op, r.job_id().unwrap(), Duration::from_secs(60));
    assert_eq!(job_of(&s).outcome, Outcome::Completed, "{s}");
    drop(op);
    d.shutdown_leaving_nothing("pos");
}

#[test]
fn feed_hold_stops_motion_within_the_ring_depth_and_resume_finishes_the_job() {
    let d = Daemon::start("hold", "Realtime", false);
    let op = d.operator();
    let job = short_job(&d.dir);
    let r = op.request(&submit(&abs(&job))).unwrap();
    assert!(r.is_accepted());
    d.wait_status(&op, Duration::from_secs(20), "motion", |s| {
        s.job.as_ref().map_or(0, |j| j.record.cycles) > 900
    });
    op.request(&Request::Hold).unwrap();
    // the ring holds `lookahead_samples` of samples (1 ms each) already sent; the
    // deceleration follows them
    let lookahead_ms = softnc_daemon::config::DaemonConfig::load(&d.config)
        .unwrap()
        .config
        .lookahead_samples as u64;
    std::thread::sleep(Duration::from_millis(lookahead_ms + 300));
    let a = op.status().unwrap();
    std::thread::sleep(Duration::from_millis(300));
    let b = op.status().unwrap();
    assert_eq!(cmd_mm(&a), cmd_mm(&b), "standing still in feed hold");
    assert_eq!(job_of(&b).outcome, Outcome::Running);
    // progress is the position along the path: it stands still in the hold
    // while the cycles go on
    let progress = |s: &Status| s.job.as_ref().unwrap().progress;
    assert!(Some(job_of(&b).cycles) > Some(job_of(&a).cycles), "{b}");
    assert_eq!(progress(&a), progress(&b), "{a}\n{b}");
    assert!(progress(&b) > 0.05 && progress(&b) < 0.95, "{b}");
    // the line of the sample the position loop stands on: a move of the program
    // (lines 3-10), the same while held
    let line = b.program_line.unwrap_or(0);
    assert!((3..=10).contains(&line), "{b}");
    assert_eq!(a.program_line, b.program_line);
    // the distance to go: the work position and it add up to the end of that
    // line's motion (a fresh machine: no offsets), held as running
    let ends = [
        [0.0, 0.0, -1.0],
        [20.0, 0.0, -1.0],
        [30.0, 10.0, -1.0],
        [30.0, 30.0, -1.0],
        [20.0, 40.0, -1.0],
        [0.0, 40.0, -1.0],
        [0.0, 0.0, -1.0],
        [0.0, 0.0, 5.0],
    ];
    let w = b.work_mm.unwrap();
    let to_go = b.distance_to_go_mm;
    let end = ends[line as usize - 3];
    assert!(
        (0..3).all(|i| (w[i] + to_go[i] - end[i]).abs() < 1e-9),
        "held on line {line} at {w:?} with {to_go:?} to go: not its end {end:?}"
    );
    assert_eq!(a.distance_to_go_mm, to_go, "{a}\n{b}");
    // at a quarter of the feed the job runs past its planned cycles while its
    // progress stays under 100 %
    op.request(&Request::FeedOverride { fraction: 0.25 })
        .unwrap();
    op.request(&Request::Resume).unwrap();
    let planned = job_of(&b).planned_samples;
    let s = d.wait_status(
        &op,
        Duration::from_secs(30),
        "past the planned cycles",
        |s| job_of(s).cycles > planned + 200,
    );
    assert_eq!(job_of(&s).outcome, Outcome::Running, "{s}");
    assert!(progress(&s) > progress(&b) && progress(&s) < 1.0, "{s}");
    op.request(&Request::FeedOverride { fraction: 1.0 })
        .unwrap();
    let s = d.wait_job(&op, r.job_id().unwrap(), Duration::from_secs(60));
    assert_eq!(job_of(&s).outcome, Outcome::Completed, "{s}");
    assert_eq!(progress(&s), 1.0, "{s}");
    assert!(s.program_line.is_none(), "no line outside a job: {s}");
    assert_eq!(machine_mm(&s).to_vec(), cmd_mm(&s), "{s}");
    let s = d.wait_status(&op, Duration::from_secs(10), "idle", |s| {
        s.state == softnc_api::MachineState::Idle
    });
    assert_eq!(s.distance_to_go_mm, [0.0; 3], "nothing to go at rest: {s}");
}

#[test]
fn a_spindle_override_redesigns_the_pdc_in_a_running_job_and_stays_for_the_next() {
    let d = Daemon::start_on("spindle", "Realtime", false, "tnv40-dob-pdc.ron");
    let op = d.operator();
    // outside the profile's 50..=120 %: refused, nothing sent
    let r = op
        .request(&Request::SpindleOverride { fraction: 1.5 })
        .unwrap();
    assert!(!r.is_accepted(), "{}", r.message());
    assert!(r.message().contains("50..=120 %"), "{}", r.message());
    // a 2 s cut at 1500 rpm (f_d = 50 Hz with the profile's two flutes)
    let job = d.dir.join("cut.ngc");
    std::fs::write(
        &job,
        "G21 G90 G17 G94\nG0 X0 Y0\nS1500 M3\nG1 X4 F120\nM5\nM2\n",
    )
    .unwrap();
    let r = op.request(&submit(&abs(&job))).unwrap();
    assert!(r.is_accepted(), "{}", r.message());
    let first = r.job_id().unwrap();
    let s = d.wait_status(&op, Duration::from_secs(20), "cutting at 1500 rpm", |s| {
        s.job.as_ref().map_or(0, |j| j.record.cycles) > 300 && s.spindle_rpm == Some(1500.0)
    });
    assert_eq!(s.spindle_override, Some(1.0));
    let r = op
        .request(&Request::SpindleOverride { fraction: 1.2 })
        .unwrap();
    assert!(r.is_accepted(), "{}", r.message());
    // designed off the cycle, swapped in with the new speed while the job runs
    let s = d.wait_status(&op, Duration::from_secs(5), "1800 rpm", |s| {
        s.spindle_rpm == Some(1800.0)
    });
    assert_eq!(job_of(&s).outcome, Outcome::Running, "{s}");
    let s = d.wait_job(&op, first, Duration::from_secs(30));
    assert_eq!(job_of(&s).outcome, Outcome::Completed, "{s}");
    assert!(s.alarms.is_empty(), "no alarm: {}", alarm_text(&s));
    // the override is the machine's, not the job's: the next job starts at 1800 rpm
    let r = op.request(&submit(&abs(&job))).unwrap();
    assert!(r.is_accepted(), "{}", r.message());
    let s = d.wait_status(&op, Duration::from_secs(20), "second job cutting", |s| {
        s.job(r.job_id().unwrap()).is_some() && s.job.as_ref().map_or(0, |j| j.record.cycles) > 100
    });
    assert_eq!(s.spindle_rpm, Some(1800.0), "{s}");
    let s = d.wait_job(&op, r.job_id().unwrap(), Duration::from_secs(30));
    assert_eq!(job_of(&s).outcome, Outcome::Completed, "{s}");
}

/// A stop by signal: the job stops along its path and is recorded as aborted,
/// softncd exits 0, no process and no iceoryx2 service of the instance is left.
fn signal_stops_in_order(tag: &str, signal: &str, to_group: bool) {
    let mut d = Daemon::start(tag, "Realtime", true);
    let instance = format!("e2e{tag}{}", std::process::id());
    let op = d.operator();
    let job_id = start_moving(&d, &op);
    drop(op);
    let kids = d.children();
    assert_eq!(kids.len(), 3, "three processes: {kids:?}");
    let pid = d.child.id() as i32;
    let target = if to_group { -pid } else { pid };
    let ok = Command::new("kill")
        .args([&format!("-{signal}"), "--", &target.to_string()])
        .status()
        .unwrap()
        .success();
    assert!(ok, "kill -{signal} {target}");
    let status = d.wait_exit(&format!("SIG{signal}"));
    assert_eq!(status.code(), Some(0), "softncd exits 0 on SIG{signal}");
    Daemon::wait_gone(&kids, Duration::from_secs(5));
    assert_stops_along_the_path(&d.dir.join(format!("data/trace-job{job_id}.csv")));
    let rec = d.job_record(job_id).expect("the job's record");
    assert_eq!(rec.outcome, Outcome::Aborted, "the job's record: {rec}");
    assert_eq!(
        services_of(&instance),
        Vec::<String>::new(),
        "iceoryx2 services left"
    );
}

#[test]
fn sigterm_stops_the_job_along_its_path_and_softncd_exits_0_leaving_nothing() {
    signal_stops_in_order("term", "TERM", false);
}

#[test]
fn sigint_to_the_process_group_stops_the_job_along_its_path_and_everything_exits() {
    signal_stops_in_order("int", "INT", true);
}

#[test]
fn killing_softncd_stops_its_children_along_the_path_and_a_new_softncd_runs_the_next_job() {
    let mut d = Daemon::start("orphan", "Realtime", true);
    let op = d.operator();
    let job_id = start_moving(&d, &op);
    drop(op);
    let kids = d.children();
    assert_eq!(kids.len(), 3, "three processes: {kids:?}");
    d.child.kill().unwrap();
    let _ = d.child.wait();
    // the children notice their parent is gone and stop in order by themselves
    Daemon::wait_gone(&kids, Duration::from_secs(10));
    assert_stops_along_the_path(&d.dir.join(format!("data/trace-job{job_id}.csv")));
    // a new softncd on the same instance starts cleanly and runs a job
    d.child = Command::new(env!("CARGO_BIN_EXE_softncd"))
        .arg("--config")
        .arg(&d.config)
        .env("SOFTNC_RUN_DIR", &d.dir)
        .env("RUST_LOG", "warn")
        .process_group(0)
        .spawn()
        .unwrap();
    let op = d.operator();
    d.wait_status(&op, Duration::from_secs(10), "processes up", |s| {
        s.processes.interp == ProcessHealth::Alive && s.processes.position == ProcessHealth::Alive
    });
    let s = d.runs_the_short_job(&op);
    assert!(
        !alarm_text(&s).contains("SequenceError"),
        "no second set of processes: {s}"
    );
    drop(op);
    d.shutdown_leaving_nothing("orphan");
}

#[test]
fn a_second_softncd_on_the_same_instance_is_refused_and_the_first_runs_on() {
    let d = Daemon::start("second", "Lockstep", false);
    let op = d.operator();
    let out = Command::new(env!("CARGO_BIN_EXE_softncd"))
        .arg("--config")
        .arg(&d.config)
        .env("SOFTNC_RUN_DIR", &d.dir)
        .env("RUST_LOG", "warn")
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1), "second softncd: {out:?}");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("already controlled by softncd pid")
            && err.contains(&d.child.id().to_string()),
        "{err}"
    );
    // the first one's processes are untouched and run a job
    d.runs_the_short_job(&op);
}

#[test]
fn commands_say_what_the_machine_does_in_every_state() {
    let d = Daemon::start("states", "Realtime", false);
    let op = d.operator();
    let req = |k: Request| op.request(&k).unwrap();
    // idle: nothing to hold or resume; an abort stops only the spindle and the
    // coolant (LinuxCNC's); a reset only clears alarms
    for k in [Request::Hold, Request::Resume] {
        let r = req(k.clone());
        assert!(!r.is_accepted(), "{k:?} when idle: {}", r.message());
    }
    let r = req(Request::Abort);
    assert!(
        r.is_accepted() && r.message().contains("spindle stopped, coolant off"),
        "{}",
        r.message()
    );
    assert_eq!(op.status().unwrap().state, MachineState::Idle);
    assert!(req(Request::Reset).is_accepted());
    let job_id = start_moving(&d, &op);
    // running: resume refused, reset refused (the job moves), hold shows held
    let r = req(Request::Resume);
    assert!(!r.is_accepted(), "{}", r.message());
    let r = req(Request::Reset);
    assert!(!r.is_accepted(), "{}", r.message());
    assert!(r.message().contains("abort"), "{}", r.message());
    let s = op.status().unwrap();
    assert_eq!(s.state, MachineState::Running, "{s}");
    assert_eq!(
        job_of(&s).outcome,
        Outcome::Running,
        "a refused reset changed nothing: {s}"
    );
    assert!(req(Request::Hold).is_accepted());
    let s = op.status().unwrap();
    assert_eq!(s.state, MachineState::Held, "{s}");
    assert!(!req(Request::Hold).is_accepted(), "already held");
    // held: abort stops the job along its path; it ends aborted, the machine idle
    let r = req(Request::Abort);
    assert!(r.is_accepted(), "{}", r.message());
    assert_eq!(op.status().unwrap().state, MachineState::Stopping);
    let s = d.wait_job(&op, job_id, Duration::from_secs(20));
    assert_eq!(job_of(&s).outcome, Outcome::Aborted, "{s}");
    let s = d.wait_status(&op, Duration::from_secs(5), "idle", |s| {
        s.state == MachineState::Idle
    });
    assert!(s.alarms.is_empty(), "an abort is no alarm: {s}");
    // the machine runs the next job; an E-stop faults it, the alarm shows until a
    // reset clears it (kept in the job's record)
    let job2 = start_moving(&d, &op);
    assert!(req(Request::EStop).is_accepted());
    let s = d.wait_job(&op, job2, Duration::from_secs(10));
    assert_eq!(job_of(&s).outcome, Outcome::Aborted, "{s}");
    let s = d.wait_status(&op, Duration::from_secs(5), "E-stop alarm", |s| {
        alarm_text(s).contains("EStop")
    });
    assert_eq!(s.state, MachineState::EStopped);
    for k in [Request::Hold, Request::Resume, Request::Abort] {
        assert!(!req(k.clone()).is_accepted(), "{k:?} when E-stopped");
    }
    let r = op.request(&submit(&abs(&short_job(&d.dir)))).unwrap();
    assert!(!r.is_accepted(), "{}", r.message());
    assert!(req(Request::Reset).is_accepted());
    // the latch cleared, the drives off: `on` switches them on
    let s = d.wait_status(&op, Duration::from_secs(5), "off", |s| {
        s.state == MachineState::Off
    });
    assert!(s.alarms.is_empty(), "cleared: {s}");
    let rec = d.job_record(job2).expect("the job's record");
    assert!(
        rec.alarms.iter().any(|a| a.contains("EStop")),
        "kept in the record: {rec}"
    );
}

#[test]
fn odd_job_files_are_refused_and_nothing_moves_and_a_rewritten_file_does_not_run() {
    let d = Daemon::start("files", "Lockstep", false);
    let op = d.operator();
    // a FIFO (reading it would block the MMI for ever), a device (endless), a
    // directory: refused at once, the MMI answers on
    let fifo = d.dir.join("fifo.ngc");
    assert!(Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap()
        .success());
    for (file, want) in [
        (abs(&fifo), "not a regular file (a FIFO)"),
        (
            "/dev/zero".to_string(),
            "not a regular file (a character device)",
        ),
        (abs(&d.dir), "not a regular file (a directory)"),
    ] {
        let r = op.request(&submit(&file)).unwrap();
        assert!(!r.is_accepted(), "{file}");
        assert!(r.message().contains(want), "{}", r.message());
    }
    // a path longer than the wire holds is refused by the client, not cut (a cut
    // path could name another file)
    let long = format!("{}/{}.ngc", d.dir.display(), "x".repeat(5000));
    let e = op.request(&submit(&long)).unwrap_err();
    let capacity = softnc_ipc::OperatorRequest::MESSAGE_CAPACITY;
    assert!(
        e.to_string().contains(&format!(
            "over the {capacity} bytes a request holds: nothing sent"
        )),
        "{e}"
    );
    let s = op.status().unwrap();
    assert_eq!(s.state, MachineState::Idle);
    assert!(s.job.is_none(), "no job was started: {s}");
    // a file rewritten after the check: the job runs what was checked
    let job = short_job(&d.dir);
    let r = op.request(&submit(&abs(&job))).unwrap();
    assert!(r.is_accepted(), "{}", r.message());
    std::fs::write(&job, "G21 G90\nG0 X900\nM2\n").unwrap();
    let s = d.wait_job(&op, r.job_id().unwrap(), Duration::from_secs(60));
    assert_eq!(job_of(&s).outcome, Outcome::Completed, "{s}");
    let about_it = s
        .alarms
        .iter()
        .filter(|a| a.job_id == r.job_id().unwrap())
        .count();
    assert_eq!(about_it, 0, "{s}");
}

#[test]
fn a_long_job_history_is_listed_whole_page_by_page() {
    // 200 records with 300-character paths: about 100 kB of JSON, twelve times what
    // one reply holds
    let d = Daemon::start_with_history("history", 200, 300);
    let op = d.operator();
    let jobs = op.jobs().unwrap();
    assert_eq!(jobs.len(), 200);
    let ids: Vec<u64> = jobs.iter().map(|j| j.job_id).collect();
    assert_eq!(
        ids,
        (1..=200).rev().collect::<Vec<_>>(),
        "newest first, none twice"
    );
    assert!(jobs.iter().all(|j| j.path.len() == 300));
}

#[test]
fn the_next_job_starts_where_the_machine_is_without_a_step() {
    let d = Daemon::start("cont", "Lockstep", true);
    let op = d.operator();
    let a = d.dir.join("a.ngc");
    std::fs::write(&a, "G21 G90 G17\nG1 X50 Y50 F3000\nM2\n").unwrap();
    // names X only: Y stays where the machine is (50), not where the program began
    let b = d.dir.join("b.ngc");
    std::fs::write(&b, "G21 G90 G17\nG1 X70 F600\nM2\n").unwrap();
    let mut ids = Vec::new();
    for f in [&a, &b] {
        let r = op.request(&submit(&abs(f))).unwrap();
        assert!(r.is_accepted(), "{}", r.message());
        let s = d.wait_job(&op, r.job_id().unwrap(), Duration::from_secs(60));
        assert_eq!(job_of(&s).outcome, Outcome::Completed, "{s}");
        d.wait_status(&op, Duration::from_secs(10), "idle", |s| {
            s.state == MachineState::Idle
        });
        ids.push(r.job_id().unwrap());
    }
    let s = op.status().unwrap();
    let cmd: Vec<f64> = s.axes.as_ref().unwrap().cmd_mm.clone();
    assert!(
        (cmd[0] - 70.0).abs() < 1e-6 && (cmd[1] - 50.0).abs() < 1e-6 && cmd[2].abs() < 1e-6,
        "job B ends at X70 Y50 Z0: {cmd:?}"
    );
    // B's following error stays in the normal band of a 10 mm/s move (it was the
    // 50 mm back to the program's origin)
    let fe = format!("{:?}", job_of(&s).accuracy.following_max_abs_um);
    let fe: Vec<f64> = serde_json::from_str(&fe).unwrap();
    assert!(
        fe.iter().all(|e| *e < 100.0),
        "job B's following error: {fe:?} µm"
    );
    // B's samples start at (50, 50, 0) and never step
    let trace = d.dir.join(format!("data/trace-job{}.csv", ids[1]));
    let text = d.trace_of(ids[1], 1000);
    let first: Vec<f64> = String::from_utf8_lossy(&text)
        .lines()
        .nth(1)
        .unwrap()
        .split(',')
        .skip(1)
        .take(3)
        .map(|v| v.parse().unwrap())
        .collect();
    assert!(
        (first[0] - 50.0).abs() < 1e-6 && (first[1] - 50.0).abs() < 1e-6,
        "job B's first command: {first:?}"
    );
    assert_stops_along_the_path(&trace);
}

#[test]
fn a_stopped_interpolator_is_noticed_killed_and_restarted_and_reset_recovers() {
    let d = Daemon::start_edited(
        "sigstop",
        "Realtime",
        &[("watchdog_s: 10.0", "watchdog_s: 1.5")],
    );
    let op = d.operator();
    let _job = start_moving(&d, &op);
    let pid = d.pid_of("softnc-interp").unwrap();
    // SIGSTOP: alive to the kernel, silent to everyone
    assert!(Command::new("kill")
        .args(["-STOP", &pid.to_string()])
        .status()
        .unwrap()
        .success());
    let s = d.wait_status(&op, Duration::from_secs(10), "fault", |s| {
        s.state == MachineState::Faulted
    });
    assert!(alarm_text(&s).contains("RingDry"), "{s}");
    // the watchdog kills it and softncd starts a new one
    let s = d.wait_status(&op, Duration::from_secs(10), "watchdog", |s| {
        alarm_text(s).contains("watchdog")
    });
    assert!(alarm_text(&s).contains("softnc-interp"), "{s}");
    assert!(
        std::fs::read_to_string(format!("/proc/{pid}/stat")).map_or(true, |st| st.contains(") Z ")),
        "the stopped interpolator was killed"
    );
    op.request(&Request::Reset).unwrap();
    d.wait_status(&op, Duration::from_secs(10), "off + a new interp", |s| {
        s.state == MachineState::Off && s.processes.interp == ProcessHealth::Alive
    });
    op.machine_on(Duration::from_secs(10)).unwrap();
    d.runs_the_short_job(&op);
}

#[test]
fn a_stopped_position_process_is_noticed_killed_and_restarted_and_reset_recovers() {
    let mut d = Daemon::start_edited(
        "sigstoppos",
        "Realtime",
        &[("watchdog_s: 10.0", "watchdog_s: 1.5")],
    );
    let op = d.operator();
    let job = start_moving(&d, &op);
    sigstop_until_the_watchdog_acts(&d, &op, "softnc-position");
    let s = d.wait_status(&op, Duration::from_secs(10), "watchdog alarm", |s| {
        alarm_text(s).contains("watchdog")
    });
    assert!(alarm_text(&s).contains("softnc-position"), "{s}");
    assert_eq!(s.state, MachineState::Faulted, "{s}");
    assert_eq!(d.job_record(job).map(|j| j.outcome), Some(Outcome::Aborted));
    op.request(&Request::Reset).unwrap();
    d.wait_status(
        &op,
        Duration::from_secs(15),
        "off + a new position process",
        |s| s.state == MachineState::Off && s.processes.position == ProcessHealth::Alive,
    );
    op.machine_on(Duration::from_secs(10)).unwrap();
    d.runs_the_short_job(&op);
    drop(op);
    d.shutdown_leaving_nothing("sigstoppos");
}

#[test]
fn a_stopped_mmi_stops_the_job_along_its_path_and_is_killed_and_restarted() {
    let mut d = Daemon::start_edited(
        "sigstopmmi",
        "Realtime",
        &[("watchdog_s: 10.0", "watchdog_s: 1.5")],
    );
    let op = d.operator();
    let job = start_moving(&d, &op);
    sigstop_until_the_watchdog_acts(&d, &op, "softnc-mmi");
    drop(op);
    // silent past `mmi_silence_stop_s` (1 s) before the watchdog (1.5 s): the
    // position process stopped the job along its path; the new MMI serves
    let op = d.operator_off();
    let s = d.wait_job(&op, job, Duration::from_secs(60));
    assert_ne!(
        job_of(&s).outcome,
        Outcome::Completed,
        "motion stopped without the MMI: {s}"
    );
    assert_eq!(s.state, MachineState::Faulted, "{s}");
    drop(op);
    d.shutdown_leaving_nothing("sigstopmmi");
}

/// A program whose check takes seconds: a few MB of comments (they raise the
/// executed-block limit) and a loop of millions of blocks, then one move.
fn slow_to_check_job(dir: &Path) -> PathBuf {
    let p = dir.join("slow-check.ngc");
    let mut text = String::from("G21 G90\n");
    for _ in 0..100_000 {
        text.push_str("(a long comment line that only makes the file bigger ....)\n");
    }
    text.push_str("#1=0\no100 while [#1 LT 1900000]\n#1=[#1+1]\no100 endwhile\nG1 X10 F600\nM2\n");
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn a_job_is_checked_off_the_loop_status_and_estop_answer_meanwhile() {
    let d = Daemon::start("check", "Realtime", false);
    let op = d.operator();
    let job = slow_to_check_job(&d.dir);
    let config = d.config.clone();
    let path = abs(&job);
    let submitted = std::thread::spawn(move || {
        let op = Operator::connect(&config).unwrap();
        op.request(&submit(&path)).unwrap()
    });
    // while it is checked the MMI answers at once and says so
    let s = d.wait_status(&op, Duration::from_secs(10), "checking", |s| {
        s.checking.is_some()
    });
    assert_eq!(s.state, MachineState::Idle, "{s}");
    // one job at a time: a second one is refused while the first is checked
    let second = op.request(&submit(&abs(&short_job(&d.dir)))).unwrap();
    assert!(!second.is_accepted(), "{}", second.message());
    assert!(
        second.message().contains("being checked"),
        "{}",
        second.message()
    );
    let t0 = Instant::now();
    let e = op.request(&Request::EStop).unwrap();
    assert!(e.is_accepted(), "{}", e.message());
    assert!(
        t0.elapsed() < Duration::from_secs(1),
        "E-stop answered in {:?} while a job was checked",
        t0.elapsed()
    );
    // the job checked under an E-stop is not started: nothing moves
    let r = submitted.join().unwrap();
    assert!(!r.is_accepted(), "{}", r.message());
    assert!(r.message().contains("emergency stop"), "{}", r.message());
    let s = op.status().unwrap();
    assert!(s.checking.is_none(), "{s}");
    assert_eq!(cmd_mm(&s), [0.0, 0.0, 0.0], "{s}");
    assert!(op.jobs().unwrap().is_empty(), "no job record");
    // reset (the drives stay off), on; the same program checked again runs
    op.request(&Request::Reset).unwrap();
    d.wait_status(&op, Duration::from_secs(10), "off", |s| {
        s.state == MachineState::Off
    });
    op.machine_on(Duration::from_secs(10)).unwrap();
    let r = op.request(&submit(&abs(&job))).unwrap();
    assert!(r.is_accepted(), "{}", r.message());
    let s = d.wait_job(&op, r.job_id().unwrap(), Duration::from_secs(60));
    assert_eq!(job_of(&s).outcome, Outcome::Completed, "{s}");
    assert_eq!(cmd_mm(&s)[0], 10.0, "{s}");
}

#[test]
fn a_loopback_daemon_runs_a_job_whose_axes_follow_the_command_exactly() {
    let d = Daemon::start_in(
        fresh_dir("loopback"),
        "loopback",
        "Lockstep",
        true,
        "default.ron",
        &[("backend: Simulated", "backend: Loopback")],
    );
    let op = d.operator();
    let s = d.runs_the_short_job(&op);
    // each cycle measures where the previous one commanded, to a nanometre
    let trace = std::fs::read_to_string(
        d.dir
            .join(format!("data/trace-job{}.csv", job_of(&s).job_id)),
    )
    .unwrap();
    let rows: Vec<Vec<f64>> = trace
        .lines()
        .skip(1)
        .map(|l| l.split(',').take(7).map(|v| v.parse().unwrap()).collect())
        .collect();
    assert!(rows.len() > 1000, "{} rows", rows.len());
    for w in rows.windows(2) {
        for axis in 0..3 {
            let (cmd_before, act_now) = (w[0][1 + axis], w[1][4 + axis]);
            assert!(
                (act_now - cmd_before).abs() <= 1e-9,
                "t {}: axis {axis} at {act_now}, commanded {cmd_before}",
                w[1][0]
            );
        }
    }
    // far below the simulated machine's (tens of µm) on the same job
    let rms = job_of(&s).accuracy.contour_rms_um;
    assert!(rms < 1.0, "contour rms {rms} µm");
    // every commanded sample is within the program's G64 P0.01 of its path, and
    // the axes, a cycle behind, are on the path commanded: the contour error (the
    // actual position's distance to the programmed path near it) is within it too
    let contour_max_um = trace
        .lines()
        .skip(1)
        .filter_map(|l| l.split(',').nth(10)?.parse::<f64>().ok())
        .fold(0.0f64, |m, e| m.max(e.abs()));
    eprintln!("loopback: contour error max |e| {contour_max_um} µm, rms {rms} µm");
    assert!(
        contour_max_um <= 10.0,
        "contour error {contour_max_um} µm beyond the program's G64 P0.01"
    );
    // the next job takes the drive over where the first left it (not homed again)
    let end1 = machine_mm(&op.status().unwrap());
    let r2 = op.request(&submit(&abs(&short_job(&d.dir)))).unwrap();
    assert!(r2.is_accepted(), "{}", r2.message());
    let s = d.wait_job(&op, r2.job_id().unwrap(), Duration::from_secs(60));
    assert_eq!(job_of(&s).outcome, Outcome::Completed, "{s}");
    let trace2 = std::fs::read_to_string(
        d.dir
            .join(format!("data/trace-job{}.csv", r2.job_id().unwrap())),
    )
    .unwrap();
    let first: Vec<f64> = trace2
        .lines()
        .nth(1)
        .unwrap()
        .split(',')
        .take(7)
        .map(|v| v.parse().unwrap())
        .collect();
    for axis in 0..3 {
        assert!(
            (first[4 + axis] - end1[axis]).abs() <= 1e-9,
            "job 2 starts at {first:?}, job 1 ended at {end1:?}"
        );
    }
}

#[test]
fn a_long_program_is_streamed_not_held_whole_in_the_interpolator() {
    let d = Daemon::start("stream", "Realtime", false);
    let op = d.operator();
    // 400,000 short moves (8.5 MB): its whole plan would take some 200 MB
    let job = d.dir.join("long.ngc");
    let mut text = String::from("G21 G90 G64 P0.01\nG0 X0 Y0 Z0\nF3000\n");
    for k in 0..400_000u32 {
        let x = f64::from(k % 1000) * 0.05;
        let y = f64::from(k / 1000) * 0.05;
        text.push_str(&format!("G1 X{x:.3} Y{y:.3}\n"));
    }
    text.push_str("M2\n");
    std::fs::write(&job, &text).unwrap();
    let interp = d.pid_of("softnc-interp").unwrap();
    let position = d.pid_of("softnc-position").unwrap();
    let before_kb = peak_rss_kb(interp);
    let position_before_kb = peak_rss_kb(position);
    let r = op.request(&submit(&abs(&job))).unwrap();
    assert!(r.is_accepted(), "{}", r.message());
    d.wait_status(&op, Duration::from_secs(60), "motion", |s| {
        s.job.as_ref().map_or(0, |j| j.record.cycles) > 500
    });
    let grew_kb = peak_rss_kb(interp) - before_kb;
    let position_grew_kb = peak_rss_kb(position) - position_before_kb;
    assert!(
        grew_kb < 64 * 1024,
        "the interpolation process grew by {grew_kb} kB for an {} kB program",
        text.len() / 1024
    );
    // the position process keeps each motion's programmed primitive (for the
    // contour error), not the plan: 51 MB here, 112 MB with the whole plan
    assert!(
        position_grew_kb < 80 * 1024,
        "the position process grew by {position_grew_kb} kB"
    );
    let a = op.request(&Request::Abort).unwrap();
    assert!(a.is_accepted(), "{}", a.message());
    let s = d.wait_job(&op, r.job_id().unwrap(), Duration::from_secs(30));
    assert_eq!(job_of(&s).outcome, Outcome::Aborted, "{s}");
}

#[allow(clippy::too_many_lines)]
#[test]
fn a_shop_day_home_jog_touch_off_mdi_and_restart_keeps_offsets_and_tools() {
    let tag = "shopday";
    let profile_dir =
        std::env::temp_dir().join(format!("softnc-e2e-profile-{}", std::process::id()));
    let profile = quick_homing_profile(&profile_dir);
    let dir = fresh_dir(tag);
    // a subroutine on the configured search path, for an MDI call
    std::fs::create_dir_all(dir.join("subs")).unwrap();
    std::fs::write(
        dir.join("subs/nudge.ngc"),
        "o<nudge> sub\nG91 G0 X#1\nG90\no<nudge> endsub\nM2\n",
    )
    .unwrap();
    let subs = [(
        "subroutine_path: [\"../subroutines\"]",
        "subroutine_path: [\"subs\"]",
    )];
    // traced: homing and jogs go to data/trace-manual-<pid>.csv
    let mut d = Daemon::start_in(
        dir.clone(),
        tag,
        "Lockstep",
        true,
        profile.to_str().unwrap(),
        &subs,
    );
    let op = d.operator_off();
    let job = short_job(&d.dir);
    // the daemon starts off: nothing runs
    let s = d.wait_status(&op, Duration::from_secs(10), "off", |s| {
        s.machine_mm.is_some()
    });
    assert_eq!(s.state, MachineState::Off, "{s}");
    let (ok, msg) = ask(&op, &submit(&abs(&job)));
    assert!(!ok && msg.contains("off"), "{msg}");
    let (ok, msg) = ask(&op, &jog_step(0, 10.0));
    assert!(!ok && msg.contains("off"), "{msg}");
    op.machine_on(Duration::from_secs(10)).unwrap();
    // no limit switch tripped: nothing to override (LinuxCNC's override limits)
    let (ok, msg) = ask(&op, &Request::OverrideLimits);
    assert!(!ok && msg.contains("no limit switch is tripped"), "{msg}");
    // not homed: jobs and MDI refused, state unchanged
    let s = op.status().unwrap();
    assert!(s.limits_tripped.is_empty() && !s.limits_overridden, "{s}");
    assert_eq!(s.homed, [false, false, false], "{s}");
    for request in [submit(&abs(&job)), mdi_request("G0 X1")] {
        let (ok, msg) = ask(&op, &request);
        assert!(!ok && msg.contains("not homed"), "{request:?}: {msg}");
    }
    assert_eq!(op.status().unwrap().state, MachineState::Idle);

    // home all: Z, X, Y in the profile's order, each at its home position
    let (ok, msg) = ask(&op, &Request::Home { axis: None });
    assert!(ok, "{msg}");
    // the state the command asked for, from the reply on (not the one before it)
    assert_eq!(op.status().unwrap().state, MachineState::Homing);
    let s = d.wait_status(&op, Duration::from_secs(60), "homed", |s| {
        s.state == MachineState::Idle && s.homed == [true, true, true]
    });
    let home = machine_mm(&s);
    for (got, want) in home.iter().zip([0.0, 0.0, 90.0]) {
        assert!((got - want).abs() < 1e-9, "home position {home:?}");
    }

    // jog X+ 10 mm incremental: lands exactly there
    let (ok, msg) = ask(&op, &jog_step(0, 10.0));
    assert!(ok, "{msg}");
    let s = d.wait_status(&op, Duration::from_secs(10), "jog step", |s| {
        s.state == MachineState::Idle && (machine_mm(s)[0] - 10.0).abs() < 1e-9
    });
    assert_eq!(machine_mm(&s)[1], 0.0);
    // a step beyond the soft limit is refused and nothing moves
    let (ok, msg) = ask(&op, &jog_step(0, 500.0));
    assert!(!ok && msg.contains("soft limit"), "{msg}");
    std::thread::sleep(Duration::from_millis(200));
    let s = op.status().unwrap();
    assert_eq!((s.state, machine_mm(&s)[0]), (MachineState::Idle, 10.0));

    // continuous jog X+ at 12 m/min (clamped to the profile's jog limit), renewed
    // by its client: stops at the soft limit, never beyond
    let (ok, msg) = ask(&op, &jog(0, 12000.0));
    assert!(ok, "{msg}");
    let t0 = Instant::now();
    let mut max_x: f64 = 0.0;
    loop {
        let s = op.status().unwrap();
        max_x = max_x.max(machine_mm(&s)[0]);
        if s.state == MachineState::Idle {
            break;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(20),
            "jog never ended: {s}"
        );
        let (ok, _) = ask(&op, &jog(0, 12000.0));
        assert!(ok || op.status().unwrap().state == MachineState::Idle);
        // renewed as a client must, within the profile's dead-man
        std::thread::sleep(softnc_api::JOG_RENEW_PERIOD);
    }
    let s = op.status().unwrap();
    assert_eq!(machine_mm(&s)[0], 400.0, "stopped on the soft limit: {s}");
    assert!(max_x <= 400.0, "beyond the soft limit: {max_x}");
    // at the limit, further out is refused
    let (ok, msg) = ask(&op, &jog(0, 600.0));
    assert!(!ok && msg.contains("soft limit"), "{msg}");
    // a continuous jog whose client goes away stops by itself (the dead-man)
    let (ok, msg) = ask(&op, &jog(0, -6000.0));
    assert!(ok, "{msg}");
    assert_eq!(op.status().unwrap().state, MachineState::Jogging);
    let s = d.wait_status(&op, Duration::from_secs(5), "dead-man stop", |s| {
        s.state == MachineState::Idle
    });
    let x = machine_mm(&s)[0];
    assert!(
        x < 400.0 && x > 300.0,
        "the dead-man stopped the jog at {x}"
    );
    assert!(
        alarm_text(&s).contains("did not renew"),
        "the stop is reported: {s}"
    );
    let (ok, _) = ask(&op, &Request::Reset);
    assert!(ok);

    // touch off X0 Y0 Z0 in G55 where the machine stands; G54 stays active
    let p = machine_mm(&op.status().unwrap());
    for i in 0..3 {
        let (ok, msg) = ask(
            &op,
            &Request::TouchOff {
                axis: axis(i),
                value_mm: 0.0,
                coords: Some("G55".to_string()),
            },
        );
        assert!(ok, "{msg}");
    }
    let offsets = op.offsets().unwrap();
    let g55 = &offsets.systems[1];
    assert_eq!(g55.coords, "G55");
    for (got, want) in g55.origin_mm.iter().zip(p) {
        assert!((got - want).abs() < 1e-6, "{offsets:?}");
    }
    // move away, then MDI `G55 G0 X0 Y0` lands on the touch-off point in X and Y
    let (ok, msg) = ask(&op, &jog_step(1, -15.0));
    assert!(ok, "{msg}");
    d.wait_status(&op, Duration::from_secs(10), "jog Y", |s| {
        s.state == MachineState::Idle && (machine_mm(s)[1] - (p[1] - 15.0)).abs() < 1e-9
    });
    let r = op.request(&mdi_request("G55 G0 X0 Y0")).unwrap();
    assert!(r.is_accepted(), "{}", r.message());
    let s = d.wait_job(&op, r.job_id().unwrap(), Duration::from_secs(20));
    assert_eq!(job_of(&s).outcome, Outcome::Completed, "{s}");
    let s = d.wait_status(&op, Duration::from_secs(5), "at rest", |s| {
        s.state == MachineState::Idle
    });
    let at = machine_mm(&s);
    for i in 0..3 {
        assert!(
            (at[i] - p[i]).abs() < 1e-6,
            "MDI landed at {at:?}, touch-off point {p:?}"
        );
    }
    // the MDI's G55 stays active: work coordinates read 0 there
    assert_eq!(s.coords, "G55", "{s}");
    for w in s.work_mm.unwrap() {
        assert!(w.abs() < 1e-6, "{s}");
    }
    // the modal state stays from one MDI command to the next (G91 here)
    let r = op.request(&mdi_request("G91")).unwrap();
    assert!(r.is_accepted(), "{}", r.message());
    let r = op.request(&mdi_request("G0 Y-1")).unwrap();
    assert!(r.is_accepted(), "{}", r.message());
    d.wait_job(&op, r.job_id().unwrap(), Duration::from_secs(20));
    let s = d.wait_status(&op, Duration::from_secs(5), "at rest", |s| {
        s.state == MachineState::Idle
    });
    assert!(
        (machine_mm(&s)[1] - (p[1] - 1.0)).abs() < 1e-6,
        "incremental: {s}"
    );
    assert!(
        s.modal
            .clone()
            .unwrap_or_default()
            .join(" ")
            .contains("G91"),
        "{s}"
    );
    let r = op.request(&mdi_request("G90 G0 Y0")).unwrap();
    assert!(r.is_accepted(), "{}", r.message());
    d.wait_job(&op, r.job_id().unwrap(), Duration::from_secs(20));
    // MDI calls a subroutine found on the search path
    let r = op.request(&mdi_request("o<nudge> call [2.5]")).unwrap();
    assert!(r.is_accepted(), "{}", r.message());
    d.wait_job(&op, r.job_id().unwrap(), Duration::from_secs(20));
    let s = d.wait_status(&op, Duration::from_secs(5), "at rest", |s| {
        s.state == MachineState::Idle
    });
    assert!((machine_mm(&s)[0] - (p[0] + 2.5)).abs() < 1e-6, "{s}");
    // touch-off and MDI are refused while a job moves (a slow one, in G55; between
    // percent signs: no M2, which would make G54 active again, as in LinuxCNC)
    let slow = d.dir.join("slow.ngc");
    std::fs::write(&slow, "%\nG21 G90\nG1 X-20 F300\nG1 X0\n%\n").unwrap();
    let r = op.request(&submit(&abs(&slow))).unwrap();
    assert!(r.is_accepted(), "{}", r.message());
    d.wait_status(&op, Duration::from_secs(10), "moving", |s| {
        s.state == MachineState::Running
    });
    let (ok, msg) = ask(&op, &mdi_request("G0 X1"));
    assert!(!ok && msg.contains("busy"), "{msg}");
    let (ok, msg) = ask(
        &op,
        &Request::TouchOff {
            axis: axis(0),
            value_mm: 0.0,
            coords: None,
        },
    );
    assert!(!ok && msg.contains("moving"), "{msg}");
    d.wait_job(&op, r.job_id().unwrap(), Duration::from_secs(60));
    // a tool table edit; the tool loaded with its length offset stays for the next
    // program
    let (ok, msg) = ask(
        &op,
        &Request::ToolSet {
            tool: 5,
            length_mm: 42.5,
            diameter_mm: "6".parse().ok(),
        },
    );
    assert!(ok, "{msg}");
    let r = op.request(&mdi_request("T5 M6 G43")).unwrap();
    assert!(r.is_accepted(), "{}", r.message());
    d.wait_job(&op, r.job_id().unwrap(), Duration::from_secs(20));
    let s = op.status().unwrap();
    assert_eq!(s.tool, 5, "{s}");
    assert_eq!(s.offsets.tool_offset_mm[2], 42.5, "{s}");

    // a restart keeps the offsets, the active system and the tools (not the homing)
    d.keep_dir = true;
    drop(op);
    d.shutdown_leaving_nothing(tag);
    drop(d);
    // every sample of the homing and the jogs within each axis's limits
    let machine = softnc_machine::MachineProfile::load(&profile).unwrap();
    let mut rows = 0;
    // the furthest each axis was commanded in its search direction (+ here)
    let mut top_mm = [f64::NEG_INFINITY; 3];
    for e in std::fs::read_dir(dir.join("data")).unwrap() {
        let path = e.unwrap().path();
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        if !name.starts_with("trace-manual-") {
            continue;
        }
        let text = std::fs::read_to_string(&path).unwrap();
        let pts: Vec<(f64, [f64; 3])> = text
            .lines()
            .skip(1)
            .map(|l| {
                let f: Vec<f64> = l.split(',').take(4).map(|c| c.parse().unwrap()).collect();
                (f[0], [f[1], f[2], f[3]])
            })
            .collect();
        rows += pts.len();
        for (_, p) in &pts {
            for (top, x) in top_mm.iter_mut().zip(p) {
                *top = top.max(*x);
            }
        }
        let t = machine.interpolation_cycle_s;
        for w in pts.windows(3) {
            // consecutive cycles only (manual motions are traced apart, and a
            // re-referencing leaves a gap: the coordinates step there)
            if (w[1].0 - w[0].0 - t).abs() > 1e-9 || (w[2].0 - w[1].0 - t).abs() > 1e-9 {
                continue;
            }
            for (i, a) in machine.axes.iter().enumerate() {
                let v = (w[2].1[i] - w[1].1[i]) / t;
                let acc = ((w[2].1[i] - w[1].1[i]) - (w[1].1[i] - w[0].1[i])) / (t * t);
                assert!(
                    v.abs() <= a.max_vel_mm_per_s * (1.0 + 1e-9),
                    "{name}: {} at {} s: {v} mm/s",
                    a.name,
                    w[2].0
                );
                assert!(
                    acc.abs() <= a.max_acc_mm_per_s2 * (1.0 + 1e-6),
                    "{name}: {} at {} s: {acc} mm/s²",
                    a.name,
                    w[2].0
                );
            }
        }
    }
    assert!(rows > 10_000, "homing and jogs traced: {rows} rows");
    // each axis's search went to its home switch (the simulated machine's input,
    // beyond the soft limit: no jog goes there) and stopped on it, within the
    // braking from the search speed (the homed position is asserted above)
    let homing = machine.homing.as_ref().unwrap();
    for ((top, h), a) in top_mm.iter().zip(&homing.axes).zip(&machine.axes) {
        let v = h.search_vel_mm_per_s;
        let braking_mm = v * v / (2.0 * a.max_acc_mm_per_s2);
        assert!(
            *top >= h.switch_mm && *top <= h.switch_mm + braking_mm + v * 0.005,
            "{}: searched to {top} mm, switch at {} mm",
            a.name,
            h.switch_mm
        );
    }
    let d = Daemon::start_in(
        dir,
        tag,
        "Lockstep",
        false,
        profile.to_str().unwrap(),
        &subs,
    );
    let op = d.operator();
    let offsets = op.offsets().unwrap();
    assert_eq!(offsets.active, "G55", "{offsets:?}");
    for (got, want) in offsets.systems[1].origin_mm.iter().zip(p) {
        assert!((got - want).abs() < 1e-6, "{offsets:?}");
    }
    let tools = op.tools().unwrap();
    let t5 = tools
        .iter()
        .find(|t| t.number == 5)
        .unwrap_or_else(|| panic!("tool 5 kept: {tools:?}"));
    assert_eq!((t5.length_mm, t5.diameter_mm), (42.5, 6.0));
    assert_eq!(op.status().unwrap().homed, [false, false, false]);
    let _ = std::fs::remove_dir_all(&profile_dir);
}

#[allow(clippy::too_many_lines)]
#[test]
fn m0_pauses_single_block_steps_abort_stops_and_run_from_line_continues_as_the_whole_job() {
    let d = Daemon::start("flow", "Lockstep", true);
    let op = d.operator();
    // the switches start as LinuxCNC's controller starts them
    assert_eq!(
        op.status().unwrap().switches,
        softnc_api::Switches {
            single_block: false,
            optional_stop: true,
            block_delete: true
        }
    );
    // M0 pauses where it is: the axes at rest there, for as long as it takes
    let m0 = d.dir.join("m0.ngc");
    std::fs::write(&m0, "G21 G90 G64 P0.01\nG1 X10 F1200\nM0\nG1 X20 Y5\nM2\n").unwrap();
    let r = op.request(&submit(&abs(&m0))).unwrap();
    assert!(r.is_accepted(), "{}", r.message());
    let s = wait_paused(&d, &op);
    // the line of the M0 itself (issue 35: it was the line of the motion before)
    assert_eq!(s.program_line, Some(3), "paused at the M0 of line 3: {s}");
    std::thread::sleep(Duration::from_millis(500));
    let s = op.status().unwrap();
    assert_eq!(s.state, MachineState::Paused, "{s}");
    assert!((machine_mm(&s)[0] - 10.0).abs() < 1e-9, "{s}");
    let (ok, msg) = ask(&op, &Request::Resume);
    assert!(ok, "{msg}");
    let s = d.wait_job(&op, r.job_id().unwrap(), Duration::from_secs(30));
    assert_eq!(job_of(&s).outcome, Outcome::Completed, "{s}");
    let at = machine_mm(&op.status().unwrap());
    assert!(
        (at[0] - 20.0).abs() < 1e-9 && (at[1] - 5.0).abs() < 1e-9,
        "{at:?}"
    );

    // block delete (on): the line starting with `/` is not run
    let deleted = d.dir.join("deleted.ngc");
    std::fs::write(
        &deleted,
        "G21 G90 G64 P0.01\n/G1 Y50 F3000\nG1 X22 F3000\nG1 X20\nM2\n",
    )
    .unwrap();
    let r = op.request(&submit(&abs(&deleted))).unwrap();
    assert!(r.is_accepted(), "{}", r.message());
    let s = d.wait_job(&op, r.job_id().unwrap(), Duration::from_secs(30));
    assert_eq!(job_of(&s).outcome, Outcome::Completed, "{s}");
    let at = machine_mm(&op.status().unwrap());
    assert!(
        (at[0] - 20.0).abs() < 1e-9 && (at[1] - 5.0).abs() < 1e-9,
        "the deleted move ran: {at:?}"
    );

    // single block: one block per step (from where the last job left the machine,
    // X20 Y5)
    let blocks = d.dir.join("blocks.ngc");
    std::fs::write(
        &blocks,
        "G21 G90 G64 P0.01\nG1 X30 F3000\nG1 Y15\nG1 X40\nM2\n",
    )
    .unwrap();
    let (ok, msg) = ask(&op, &Request::SingleBlock { on: 1.0 != 0.0 });
    assert!(ok, "{msg}");
    let r = op.request(&submit(&abs(&blocks))).unwrap();
    assert!(r.is_accepted(), "{}", r.message());
    // paused at the end of each block, standing there until stepped; the last
    // block runs to the program's end
    let mut stops = Vec::new();
    loop {
        let s = d.wait_status(&op, Duration::from_secs(30), "a pause or the end", |s| {
            s.state == MachineState::Paused
                || s.job.as_ref().is_some_and(|j| j.record.outcome.ended())
        });
        if job_of(&s).outcome != Outcome::Running {
            assert_eq!(job_of(&s).outcome, Outcome::Completed, "{s}");
            break;
        }
        let line = s.program_line.unwrap();
        let at = machine_mm(&s);
        std::thread::sleep(Duration::from_millis(200));
        let s = op.status().unwrap();
        assert_eq!((s.state, machine_mm(&s)), (MachineState::Paused, at));
        stops.push((line, at));
        let (ok, msg) = ask(&op, &Request::Step);
        assert!(ok, "{msg}");
        d.wait_status(&op, Duration::from_secs(10), "stepped", |s| {
            s.program_line != Some(line) || s.job.as_ref().is_some_and(|j| j.record.outcome.ended())
        });
        assert!(stops.len() < 5, "{stops:?}");
    }
    assert_eq!(
        stops,
        [(2, [30.0, 5.0, 0.0]), (3, [30.0, 15.0, 0.0])],
        "one block per step, each stopped exactly at its end"
    );
    let (ok, msg) = ask(&op, &Request::SingleBlock { on: 0.0 != 0.0 });
    assert!(ok, "{msg}");

    // abort while paused: stops, the job ends aborted
    let r = op.request(&submit(&abs(&m0))).unwrap();
    assert!(r.is_accepted(), "{}", r.message());
    wait_paused(&d, &op);
    let (ok, msg) = ask(&op, &Request::Abort);
    assert!(ok, "{msg}");
    let s = d.wait_job(&op, r.job_id().unwrap(), Duration::from_secs(30));
    assert_eq!(job_of(&s).outcome, Outcome::Aborted, "{s}");

    // run from line: the remaining samples after the safe approach are the whole
    // job's from that line (an M0 before it: the whole job is at rest there too, on
    // a cycle boundary)
    let whole = d.dir.join("whole.ngc");
    std::fs::write(
        &whole,
        "G21 G90 G64 P0.01\nG0 X0 Y0 Z5\nG1 Z-1 F600\nG1 X20 F2400\nG2 X30 Y10 R10\nM0\nG1 Y30\nG3 X20 Y40 I-10 J0\nG1 X0\nG0 Z5\nM2\n",
    )
    .unwrap();
    let r = op.request(&submit(&abs(&whole))).unwrap();
    assert!(r.is_accepted(), "{}", r.message());
    let whole_id = r.job_id().unwrap();
    wait_paused(&d, &op);
    let (ok, msg) = ask(&op, &Request::Resume);
    assert!(ok, "{msg}");
    d.wait_job(&op, whole_id, Duration::from_secs(60));
    // from elsewhere: the approach has something to do
    let (ok, msg) = ask(&op, &jog_step(0, -25.0));
    assert!(ok, "{msg}");
    d.wait_status(&op, Duration::from_secs(10), "jogged", |s| {
        s.state == MachineState::Idle
    });
    let r = op.request(&submit_from(&abs(&whole), 7)).unwrap();
    assert!(r.is_accepted(), "{}", r.message());
    let from_id = r.job_id().unwrap();
    let s = d.wait_job(&op, from_id, Duration::from_secs(60));
    assert_eq!(job_of(&s).outcome, Outcome::Completed, "{s}");
    let cmds = |job: u64| -> Vec<String> {
        // the trace is written out by its own thread: read it once it stops growing
        let mut text = Vec::new();
        for _ in 0..100 {
            let now = d.trace_of(job, 1);
            if !now.is_empty() && now.len() == text.len() {
                break;
            }
            text = now;
            std::thread::sleep(Duration::from_millis(200));
        }
        String::from_utf8(text)
            .unwrap()
            .lines()
            .skip(1)
            .map(|l| l.split(',').skip(1).take(3).collect::<Vec<_>>().join(","))
            .collect()
    };
    let (a, b) = (cmds(whole_id), cmds(from_id));
    // the start of line 7 (X30 Y10 Z-1): from the last sample there in each
    let tail = |v: &[String]| -> Vec<String> {
        let i = v
            .iter()
            .rposition(|p| {
                let x: Vec<f64> = p.split(',').map(|c| c.parse().unwrap()).collect();
                (x[0] - 30.0).abs() < 1e-9
                    && (x[1] - 10.0).abs() < 1e-9
                    && (x[2] + 1.0).abs() < 1e-9
            })
            .expect("at the start of line 7");
        // up to the job's last command (the axes settle after it for as long as
        // they take)
        let last = v.last().unwrap();
        let end = v.iter().position(|p| p == last).unwrap();
        v[i..=end.max(i)].to_vec()
    };
    let (ta, tb) = (tail(&a), tail(&b));
    assert!(ta.len() > 100, "{}", ta.len());
    assert_eq!(ta.len(), tb.len(), "same remaining samples");
    assert!(
        ta == tb,
        "run from line 7 differs from the whole job after the approach"
    );
    // the approach raised Z first: no sample below Z5 away from X30 Y10 before it
    let approach_end = b
        .iter()
        .rposition(|p| *p == tb[0])
        .expect("the approach ends at the start of line 7");
    let approach = &b[..approach_end];
    assert!(!approach.is_empty(), "an approach was made");
    for p in approach {
        let x: Vec<f64> = p.split(',').map(|c| c.parse().unwrap()).collect();
        let at_xy = (x[0] - 30.0).abs() < 1e-6 && (x[1] - 10.0).abs() < 1e-6;
        assert!(at_xy || x[2] >= 5.0 - 1e-9, "the approach crossed low: {p}");
    }
    // refused inside a subroutine, as LinuxCNC refuses
    let sub = d.dir.join("sub.ngc");
    std::fs::write(
        &sub,
        "G21 G90\no100 sub\nG1 X5 F600\no100 endsub\no100 call\nM2\n",
    )
    .unwrap();
    let r = op.request(&submit_from(&abs(&sub), 3)).unwrap();
    assert!(!r.is_accepted(), "{}", r.message());
    assert!(r.message().contains("sub"), "{}", r.message());
    assert_eq!(op.status().unwrap().state, MachineState::Idle);
}

/// Issue 35: the death of a process and its restart are alarms the operator sees —
/// in `status` (what the TUI lists) and in the record of the job that ran — even
/// the MMI's own: the restarted MMI learns of its predecessor's death.
#[test]
fn process_deaths_and_restarts_are_alarms_the_restarted_mmi_shows_and_the_job_keeps() {
    let d = Daemon::start("deaths", "Realtime", false);
    let op = d.operator();
    // about 16 s: four laps of a 40 mm square at 2400 mm/min
    let job = d.dir.join("laps.ngc");
    let mut text = String::from("G21 G90 G17 G64 P0.01\nG0 X0 Y0 Z5\nG1 Z-1 F600\n");
    for _ in 0..4 {
        text.push_str("G1 X40 F2400\nG1 Y40\nG1 X0\nG1 Y0\n");
    }
    text.push_str("G0 Z5\nM2\n");
    std::fs::write(&job, text).unwrap();
    let r = op.request(&submit(&abs(&job))).unwrap();
    assert!(r.is_accepted(), "{}", r.message());
    let job = id(&r);
    d.wait_status(&op, Duration::from_secs(20), "motion", |s| {
        s.job.as_ref().map_or(0, |j| j.record.cycles) > 500
    });
    let has = |s: &Status, kind: AlarmKind, text: &str| {
        s.alarms
            .iter()
            .any(|a| a.code == kind && a.message.contains(text))
    };
    let in_record = |s: &Status, text: &str| {
        s.job.as_ref().is_some_and(|j| {
            j.record.job_id == job && j.record.alarms.iter().any(|a| a.contains(text))
        })
    };
    // the MMI, killed mid-job: its successor shows the death and the restart
    let mmi = d.pid_of("softnc-mmi").unwrap();
    d.kill9("softnc-mmi");
    drop(op);
    std::thread::sleep(Duration::from_millis(300));
    let op = d.operator();
    let s = d.wait_status(
        &op,
        Duration::from_secs(10),
        "the MMI's death and restart",
        |s| {
            has(s, AlarmKind::ProcessLost, "softnc-mmi exited")
                && has(s, AlarmKind::ProcessRestarted, "softnc-mmi started again")
        },
    );
    assert_ne!(d.pid_of("softnc-mmi"), Some(mmi));
    assert_eq!(s.state, MachineState::Running, "motion went on: {s}");
    assert!(in_record(&s, "softnc-mmi exited"), "{s}");
    assert!(in_record(&s, "softnc-mmi started again"), "{s}");
    // the interpolator, killed mid-job: the job stops along its path; its death
    // and its restart are alarms, its death in the record of the job it stopped
    d.kill9("softnc-interp");
    let s = d.wait_status(
        &op,
        Duration::from_secs(10),
        "the interpolator's death and restart",
        |s| {
            has(s, AlarmKind::ProcessLost, "softnc-interp exited")
                && has(
                    s,
                    AlarmKind::ProcessRestarted,
                    "softnc-interp started again",
                )
                && s.job.as_ref().is_some_and(|j| j.record.outcome.ended())
        },
    );
    assert!(in_record(&s, "softnc-interp exited"), "{s}");
    // the kinds as `status --json` prints them
    let json = serde_json::to_string(&s).unwrap();
    assert!(json.contains("\"ProcessRestarted\""), "{json}");
    // the job's record in the history keeps them too
    let t0 = Instant::now();
    let record = loop {
        match d.job_record(job) {
            Some(r) if r.alarms.iter().any(|a| a.contains("softnc-interp exited")) => break r,
            _ if t0.elapsed() > Duration::from_secs(5) => {
                panic!("the history's record of job {job}: {:?}", d.job_record(job))
            }
            _ => std::thread::sleep(Duration::from_millis(100)),
        }
    };
    assert!(
        record
            .alarms
            .iter()
            .any(|a| a.contains("softnc-mmi exited")),
        "{record:?}"
    );
}
