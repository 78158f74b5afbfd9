//! `softnc sim FILE --machine PROFILE`: planner → controller stacks → simulated machine,
//! in one process, as fast as the CPU allows; accuracy figures, trace and plot.

use crate::cmd_plan::{load_machine, read_file};
use anyhow::{Context, Result};
use plotters::prelude::*;
use softnc_core::{Primitive, Vec3};
use softnc_daemon::plan_samples::PlanSamples;
use softnc_servo::TraceRow;
use softnc_sim::{
    simulate_adaptive, simulate_sequenced, simulated_engine, CommandSample, ErrorStats,
    OverridableSamples, SimOptions,
};
use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

/// Arguments of `softnc sim`.
#[derive(clap::Args)]
pub struct SimArgs {
    /// The G-code program.
    file: PathBuf,
    /// Machine profile (RON) with its `servo` section; default `config/machines/default.ron`.
    #[arg(long)]
    machine: Option<PathBuf>,
    /// Print the figures as one JSON object.
    #[arg(long)]
    json: bool,
    /// Write the per-cycle trace (CSV): time, command, actual, following and contour error.
    #[arg(long, value_name = "OUT.csv")]
    trace: Option<PathBuf>,
    /// Draw contour error around the path (magnified) and errors over time (SVG).
    #[arg(long, value_name = "OUT.svg")]
    plot: Option<PathBuf>,
    /// Random seed of the simulated machine (default: the profile's `servo.seed`).
    #[arg(long)]
    seed: Option<u64>,
    /// Spindle override in percent, in force from the start (as the daemon's
    /// `softnc spindle-override` before a job): every S word's PDC is designed for
    /// the overridden speed. Within the profile's `spindle` range.
    #[arg(long, value_name = "PCT", default_value_t = 100.0)]
    spindle_override: f64,
    /// Add the correction `softnc learn` stored for this job on this profile (paper
    /// 002 eq 5), exactly as the daemon applies it to an un-retimed job.
    #[arg(long)]
    learned: bool,
    /// Learning store folder --learned reads (default: as `softnc learn`).
    #[arg(long)]
    store: Option<PathBuf>,
    /// Feed override in percent in force from the start (as the daemon's `softnc
    /// feed-override` before a job); with --adaptive-force the ceiling of the force
    /// loop's override.
    #[arg(long, value_name = "PCT", default_value_t = 100.0)]
    feed_override: f64,
    /// Rapid override in percent (0..=100) in force from the start (as the
    /// daemon's `softnc rapid-override` before a job): traverses run at it.
    #[arg(long, value_name = "PCT", default_value_t = 100.0)]
    rapid_override: f64,
    /// Close paper 003's force loop on the job (the profile's `force.adaptive_feed`,
    /// the simulated stock of `force.sim_workpiece`), exactly as the daemon closes it
    /// for `softnc job submit --adaptive-force`.
    #[arg(long)]
    adaptive_force: bool,
    /// With --adaptive-force: samples between the cycle an override is computed at
    /// and the sample it acts on (default: the daemon configuration's
    /// `lookahead_samples`, as the daemon applies it).
    #[arg(long, value_name = "SAMPLES")]
    lookahead: Option<u64>,
    /// Block delete: lines starting with `/` are skipped. On by default, as the
    /// daemon (and LinuxCNC's controller) starts.
    #[arg(long, value_name = "on|off", default_value = "on")]
    block_delete: crate::cmd_operator::OnOff,
    /// Optional stop: M1 brings the path to rest. On by default, as the daemon (and
    /// LinuxCNC's controller) starts.
    #[arg(long, value_name = "on|off", default_value = "on")]
    optional_stop: crate::cmd_operator::OnOff,
    /// The user M codes' folder (the daemon's `user_m_path`): a program's M100–M199
    /// must have their executable there, as in the daemon's check. The simulator
    /// does not run them: each is taken as done at once (and said so).
    #[arg(long, value_name = "DIR")]
    user_m_codes: Option<PathBuf>,
}

/// Cycles between progress-bar updates.
const PROGRESS_CYCLES: u64 = 4096;
/// Most points a plot keeps per series; longer runs are decimated evenly.
const PLOT_POINTS: u64 = 20_000;
/// The magnified contour error's typical excursion (4 × its RMS), as a fraction of the
/// path's extent; start-up transients beyond it run off further.
const PLOT_MAGNIFIED_FRACTION: f64 = 0.04;
/// The typical excursion in RMS units.
const PLOT_RMS_SPAN: f64 = 4.0;

/// One decimated cycle for the plot.
#[derive(Clone, Copy)]
struct PlotPoint {
    t_s: f64,
    cmd: [f64; 3],
    magnified: Option<[f64; 2]>,
    contour_um: Option<f64>,
    following_um: [f64; 3],
    normal: [f64; 2],
    /// The blending tolerance in force (µm); `None` at an exact stop.
    tolerance_um: Option<f64>,
}

/// Where the contour error was worst, for the plot's labels.
#[derive(Clone, Copy, Debug, PartialEq)]
struct WorstSpot {
    t_s: f64,
    contour_um: f64,
    line: u32,
}

/// Spots labelled on the plot: the worst of different program lines.
const WORST_SPOTS: usize = 3;
/// The error charts' scale: this quantile of |error| (a start-up transient beyond it
/// runs off the chart, clipped at its edge, and is said so).
const PLOT_SCALE_QUANTILE: f64 = 0.995;

/// Keep the [`WORST_SPOTS`] worst |contour error|s, one per program line.
fn note_worst(worst: &mut Vec<WorstSpot>, spot: WorstSpot) {
    if let Some(w) = worst.iter_mut().find(|w| w.line == spot.line) {
        if spot.contour_um.abs() > w.contour_um.abs() {
            *w = spot;
        }
    } else if worst.len() < WORST_SPOTS {
        worst.push(spot);
    } else if let Some(w) = worst
        .iter_mut()
        .min_by(|a, b| a.contour_um.abs().total_cmp(&b.contour_um.abs()))
    {
        if spot.contour_um.abs() > w.contour_um.abs() {
            *w = spot;
        }
    }
}

/// The [`PLOT_SCALE_QUANTILE`] of |v| over `values` (1 when there are none).
fn robust_scale(values: impl Iterator<Item = f64>) -> f64 {
    let mut v: Vec<f64> = values.map(f64::abs).filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return 1.0;
    }
    v.sort_by(f64::total_cmp);
    let k = ((v.len() - 1) as f64 * PLOT_SCALE_QUANTILE).round() as usize;
    let q = v[k.min(v.len() - 1)];
    if q > 0.0 {
        1.1 * q
    } else {
        1.0
    }
}

#[allow(clippy::too_many_lines)]
pub fn run(args: SimArgs, config: &Path) -> Result<ExitCode> {
    let machine = match load_machine(args.machine.as_ref()) {
        Ok(m) => m,
        Err(e) => {
            eprintln!("softnc: {e:#}");
            return Ok(ExitCode::from(crate::EXIT_REFUSED));
        }
    };
    let options = softnc_planner::PlanOptions {
        block_delete: args.block_delete.on(),
        optional_stop: args.optional_stop.on(),
        // the machine stops wait for the simulated machine, as in the daemon
        wait_at_machine_stops: true,
        user_m_codes: args.user_m_codes.clone(),
        ..Default::default()
    };
    let program = match read_file(&args.file, &machine, &options.read_options())? {
        Ok(p) => p,
        Err(msg) => {
            eprintln!("{msg}");
            return Ok(ExitCode::from(crate::EXIT_REFUSED));
        }
    };
    for m in &program.motions {
        if let softnc_gcode::MotionKind::Machine(softnc_gcode::MachineOp::UserM { code, p, q }) =
            m.kind
        {
            eprintln!(
                "note: line {}: M{code} {p:.6} {q:.6} is not run by the simulator: taken as done at once",
                m.line
            );
        }
    }
    for w in &program.warnings {
        eprintln!("warning: {w}");
    }
    let plan = match softnc_planner::plan(&program, &machine, &options) {
        Ok(p) => p,
        Err(e) => {
            eprintln!("{e}");
            return Ok(ExitCode::from(crate::EXIT_REFUSED));
        }
    };
    let seed = args.seed.unwrap_or(machine.servo.seed);
    let spindle_override = args.spindle_override / 100.0;
    let range = machine.spindle;
    if !(range.min_override..=range.max_override).contains(&spindle_override) {
        eprintln!(
            "softnc: --spindle-override {} %: must be {:.0}..={:.0} % (the profile's spindle section)",
            args.spindle_override,
            range.min_override * 100.0,
            range.max_override * 100.0
        );
        return Ok(ExitCode::from(crate::EXIT_REFUSED));
    }
    let cycle_s = plan.cycle_s();
    let total = plan.stats().samples;
    if args.adaptive_force && args.learned {
        eprintln!("softnc: --adaptive-force re-times the job: not with --learned");
        return Ok(ExitCode::from(crate::EXIT_REFUSED));
    }
    let learned = if args.learned {
        // the samples counted as the daemon counts them (and `softnc learn` plans
        // them): the machine stops not waited at
        let count = || {
            let options = softnc_planner::PlanOptions {
                wait_at_machine_stops: false,
                ..options.clone()
            };
            softnc_planner::plan(&program, &machine, &options)
                .map_or(0, |p| p.interpolator().count())
        };
        match learned_correction(&args, count, cycle_s)? {
            Ok(c) => Some(c),
            Err(msg) => {
                eprintln!("softnc sim --learned: {msg}");
                return Ok(ExitCode::from(1));
            }
        }
    } else {
        None
    };
    let rapid_override = args.rapid_override / 100.0;
    if !(0.0..=1.0).contains(&rapid_override)
        || (rapid_override != 1.0 && (args.learned || args.adaptive_force))
    {
        eprintln!(
            "softnc: --rapid-override {} %: must be 0..=100 %, and 100 % with --learned or --adaptive-force",
            args.rapid_override
        );
        return Ok(ExitCode::from(crate::EXIT_REFUSED));
    }
    let feed_override = args.feed_override / 100.0;
    let max_override = machine.planner.max_feed_override;
    if !(0.0..=max_override).contains(&feed_override) || (learned.is_some() && feed_override != 1.0)
    {
        eprintln!(
            "softnc: --feed-override {} %: must be 0..={:.0} % (the planner's max_feed_override), and 100 % with --learned",
            args.feed_override,
            max_override * 100.0
        );
        return Ok(ExitCode::from(crate::EXIT_REFUSED));
    }
    // the daemon's lookahead: the interpolation process hears the machine that many
    // samples late (machine stops), and adaptive feed's overrides act that late
    let daemon_lookahead = match args.lookahead {
        Some(n) => Ok(n),
        None => softnc_daemon::config::DaemonConfig::load(config)
            .map(|l| l.config.lookahead_samples as u64)
            .map_err(|e| e.to_string()),
    };
    let mut adaptive = if args.adaptive_force {
        let latency = match args.lookahead {
            Some(n) => n,
            None => match softnc_daemon::config::DaemonConfig::load(config) {
                Ok(l) => l.config.lookahead_samples as u64,
                Err(e) => {
                    eprintln!("softnc: --adaptive-force needs the daemon's lookahead (--lookahead N, or its configuration): {e}");
                    return Ok(ExitCode::from(crate::EXIT_REFUSED));
                }
            },
        };
        match softnc_servo::adaptive_feed::AdaptiveFeed::from_profile(&machine, feed_override) {
            Ok(a) => Some((a, latency, ForceLog::default())),
            Err(e) => {
                eprintln!("softnc: --adaptive-force: {e}");
                return Ok(ExitCode::from(crate::EXIT_REFUSED));
            }
        }
    } else {
        None
    };
    let mut engine = simulated_engine(&machine, seed, SimOptions::default());
    // the job's S words: PDC designs per spindle speed, as the position process makes them
    if let Err(e) = engine.set_spindle_schedule(&machine, plan.spindle_changes(), spindle_override)
    {
        eprintln!(
            "softnc: {}: a spindle speed of the job: {e}",
            args.file.display()
        );
        return Ok(ExitCode::from(crate::EXIT_REFUSED));
    }

    let progress = if std::io::stderr().is_terminal() && !args.json {
        let bar = indicatif::ProgressBar::new(total);
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "simulating {bar:40} {percent:>3}% {pos}/{len} cycles, {eta} left",
            )
            .expect("static template"),
        );
        Some(bar)
    } else {
        None
    };
    let mut trace = match &args.trace {
        // the daemon's trace writer: `softnc sim` and a lockstep daemon run write
        // byte-identical files for the same job
        Some(path) => Some(
            softnc_daemon::trace::TraceFile::create(path)
                .with_context(|| format!("cannot create {}", path.display()))?,
        ),
        None => None,
    };
    let stride = total.div_ceil(PLOT_POINTS).max(1);
    let mut plot_points: Vec<PlotPoint> = Vec::new();
    let mut worst: Vec<WorstSpot> = Vec::new();
    let line_of = |m: u32| program.motions.get(m as usize).map_or(0, |m| m.line);
    let tolerance_um = |m: u32| match program.motions.get(m as usize).map(|m| m.path_mode) {
        Some(softnc_gcode::PathMode::Blend { tolerance_mm, .. }) => Some(
            1000.0
                * tolerance_mm
                    .filter(|&t| t > 0.0)
                    .unwrap_or(machine.planner.tolerance_mm),
        ),
        _ => None,
    };
    let (mut next_plot, mut next_progress) = (0u64, 0u64);
    let mut trace_err: Option<anyhow::Error> = None;

    let lag = match daemon_lookahead {
        Ok(n) => n,
        // without the daemon's configuration: the least lookahead whose filter
        // window is the engine's
        Err(_) => softnc_core::ring::lookahead_for_window(engine.filter_window()) as u64,
    };
    let machine_samples = || {
        let (seq, heard) =
            softnc_daemon::plan_samples::sim_machine(&program, &machine, &options, lag);
        (
            PlanSamples::with_machine(plan.interpolator(), seq, heard.clone())
                .without_tool_changer(!softnc_daemon::plan_samples::has_tool_changer(&machine)),
            heard,
        )
    };
    let path_of = |m: u32| plan.motion_primitive(m as usize);
    let started = Instant::now();
    let mut on_row = |row: &TraceRow| {
        if let Some(w) = trace.as_mut() {
            if trace_err.is_none() {
                if let Err(e) = w.row(row) {
                    trace_err = Some(anyhow::Error::from(e).context("writing the trace"));
                }
            }
        }
        if args.plot.is_some() {
            // every cycle for the worst spots, a decimated few for the curves
            if let Some(c) = row.contour_mm {
                note_worst(
                    &mut worst,
                    WorstSpot {
                        t_s: row.time_s,
                        contour_um: c * 1000.0,
                        line: line_of(row.motion),
                    },
                );
            }
            if row.cycle >= next_plot {
                let mut p = plot_point(row, path_of(row.motion));
                p.tolerance_um = tolerance_um(row.motion);
                plot_points.push(p);
                next_plot += stride;
            }
        }
        if let Some(bar) = &progress {
            if row.cycle >= next_progress {
                next_progress += PROGRESS_CYCLES;
                bar.set_position(row.cycle);
            }
        }
    };
    let (mut samples, heard) = machine_samples();
    let report = match adaptive.as_mut() {
        None => {
            let samples: Box<dyn Iterator<Item = CommandSample>> = match &learned {
                Some(c) => Box::new(c.corrected(samples)),
                None => {
                    if feed_override != 1.0 {
                        // from rest: the first sample already runs at it (as the daemon)
                        samples.set_feed_override(feed_override);
                    }
                    if rapid_override != 1.0 {
                        samples.interpolator().set_rapid_override(rapid_override);
                    }
                    Box::new(samples)
                }
            };
            simulate_sequenced(
                &mut engine,
                cycle_s,
                samples,
                path_of,
                |row, engine, seq| {
                    softnc_daemon::plan_samples::hear(&heard, seq, row, engine);
                    on_row(row);
                },
            )
        }
        Some((feed, latency, log)) => simulate_adaptive(
            &mut engine,
            cycle_s,
            samples,
            feed,
            *latency,
            feed_override,
            path_of,
            |row, engine, seq, rev| {
                softnc_daemon::plan_samples::hear(&heard, seq, row, engine);
                on_row(row);
                log.cycle(engine.backend(), rev);
            },
        ),
    }
    .map_err(|e| anyhow::anyhow!("servo backend: {e}"))?;
    if let Some(e) = trace_err {
        return Err(e);
    }
    if let Some(w) = trace {
        w.finish()?;
    }
    let wall_time_s = started.elapsed().as_secs_f64();
    if let Some(bar) = progress {
        bar.finish_and_clear();
    }
    if let Some(path) = &args.plot {
        draw_plot(path, &plot_points, &worst, &program.file)?;
    }

    let um = 1000.0;
    let axis =
        |s: &ErrorStats| serde_json::json!({"max_abs": s.max_abs() * um, "rms": s.rms() * um});
    let adaptive_summary = adaptive
        .as_ref()
        .map(|(_, latency, log)| log.summary(&machine, *latency));
    let summary = serde_json::json!({
        "adaptive_force": adaptive_summary,
        "learned": learned.as_ref().map(|c| serde_json::json!({
            "entry": c.entry, "repetitions": c.repetitions, "max_abs_correction_um": c.max_abs_mm() * um,
        })),
        "cycles": report.cycles,
        "sim_time_s": report.sim_time_s,
        "wall_time_s": wall_time_s,
        "contour_error_um": {
            "max_abs": report.contour.max_abs() * um,
            "rms": report.contour.rms() * um,
            "mean": report.contour.mean() * um,
        },
        "following_error_um": {
            "x": axis(&report.following[0]),
            "y": axis(&report.following[1]),
            "z": axis(&report.following[2]),
        },
    });
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    if args.json {
        writeln!(out, "{summary}")?;
    } else {
        let c = &report.contour;
        writeln!(
            out,
            "{}: {} cycles, {:.3} s simulated in {:.3} s ({:.0}x real time), seed {seed}",
            program.file,
            report.cycles,
            report.sim_time_s,
            wall_time_s,
            report.sim_time_s / wall_time_s.max(1e-12)
        )?;
        if let Some(a) = &adaptive_summary {
            writeln!(
                out,
                "adaptive force: {} revolutions, override {:.0}..{:.0} %, reference {:.0} N (override acts {} samples after its revolution)",
                a["revolutions"],
                a["override_range"][0].as_f64().unwrap_or(0.0) * 100.0,
                a["override_range"][1].as_f64().unwrap_or(0.0) * 100.0,
                a["force_ref_n"].as_f64().unwrap_or(0.0),
                a["latency_samples"],
            )?;
            writeln!(out, "  segment  depth mm  force N  error %  est. N  feed mm/min  (settled: the segment's last revolutions)")?;
            for g in a["segments"].as_array().into_iter().flatten() {
                let f = |k: &str| g[k].as_f64().unwrap_or(f64::NAN);
                writeln!(
                    out,
                    "  {:>7}  {:>8.1}  {:>7.1}  {:>7.2}  {:>6.1}  {:>11.1}",
                    g["segment"],
                    f("depth_mm"),
                    f("force_n"),
                    f("error_pct"),
                    f("est_force_n"),
                    f("feed_mm_per_min")
                )?;
            }
        }
        if let Some(c) = &learned {
            writeln!(
                out,
                "learned correction: entry {} ({} repetitions, max |correction| {:.3} µm)",
                c.entry,
                c.repetitions,
                c.max_abs_mm() * um
            )?;
        }
        writeln!(
            out,
            "contour error: max |e| {:.3} µm, rms {:.3} µm, mean {:.3} µm",
            c.max_abs() * um,
            c.rms() * um,
            c.mean() * um
        )?;
        for (name, s) in softnc_core::Axis::carried()
            .map(softnc_core::Axis::name)
            .zip(&report.following)
        {
            writeln!(
                out,
                "following error {name}: max |e| {:.3} µm, rms {:.3} µm",
                s.max_abs() * um,
                s.rms() * um
            )?;
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// One revolution of adaptive feed, as the simulated stock saw it.
struct RevRecord {
    /// The stock's segment the whole revolution was cut in (`None`: out of the
    /// stock, or across a change).
    segment: Option<usize>,
    /// True peak cutting force of the revolution (N).
    force_n: f64,
    /// The loop's estimate (N).
    est_force_n: f64,
    /// The override it gave (fraction).
    override_frac: f64,
}

/// The revolutions of an adaptive-feed run.
#[derive(Default)]
struct ForceLog {
    peak_n: f64,
    segment: Option<usize>,
    straddled: bool,
    started: bool,
    revs: Vec<RevRecord>,
}

impl ForceLog {
    /// After a cycle: the stock's force, and the revolution the loop closed.
    fn cycle(
        &mut self,
        b: &softnc_sim::SimBackend,
        rev: Option<softnc_servo::adaptive_feed::Revolution>,
    ) {
        let Some(stock) = b.stock() else { return };
        let seg = stock.segment_at(b.true_pos_mm()[stock.feed_axis()]);
        if !self.started {
            self.segment = seg;
            self.started = true;
        }
        self.straddled |= seg != self.segment;
        self.peak_n = self.peak_n.max(stock.force_n());
        if let Some(r) = rev {
            self.revs.push(RevRecord {
                segment: if self.straddled { None } else { seg },
                force_n: self.peak_n,
                est_force_n: r.est_force_n,
                override_frac: r.override_frac,
            });
            self.peak_n = 0.0;
            self.segment = seg;
            self.straddled = false;
        }
    }

    /// Per segment of the stock, the means over its last `settled_revolutions`
    /// whole revolutions (as `softnc reproduce 003-force` reports its cases).
    fn summary(&self, machine: &softnc_machine::MachineProfile, latency: u64) -> serde_json::Value {
        let Some((_, case)) = machine.force.as_ref().and_then(|f| f.adaptive_case()) else {
            return serde_json::Value::Null;
        };
        let f_ref = case.force_ref_n;
        let mean = |v: &[&RevRecord], f: fn(&RevRecord) -> f64| {
            v.iter().map(|r| f(r)).sum::<f64>() / v.len().max(1) as f64
        };
        let segments: Vec<_> = case
            .segments
            .iter()
            .enumerate()
            .map(|(i, seg)| {
                let revs: Vec<&RevRecord> =
                    self.revs.iter().filter(|r| r.segment == Some(i)).collect();
                let n = case.settled_revolutions as usize;
                let last = &revs[revs.len().saturating_sub(n)..];
                let force = mean(last, |r| r.force_n);
                serde_json::json!({
                    "segment": i,
                    "depth_mm": seg.depth_mm,
                    "material": seg.material,
                    "revolutions": revs.len(),
                    "force_n": force,
                    "error_pct": (force - f_ref) / f_ref * 100.0,
                    "est_force_n": mean(last, |r| r.est_force_n),
                    "feed_mm_per_min": mean(last, |r| r.override_frac) * case.programmed_feed_mm_per_min,
                })
            })
            .collect();
        let (lo, hi) = self
            .revs
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), r| {
                (l.min(r.override_frac), h.max(r.override_frac))
            });
        serde_json::json!({
            "case": case.name,
            "force_ref_n": f_ref,
            "latency_samples": latency,
            "revolutions": self.revs.len(),
            "override_range": [lo, hi],
            "segments": segments,
        })
    }
}

/// The stored Markov correction of the job for --learned, or why there is none.
fn learned_correction(
    args: &SimArgs,
    planned_samples: impl FnOnce() -> usize,
    cycle_s: f64,
) -> Result<Result<softnc_learning::JobCorrection, String>> {
    let mpath = args
        .machine
        .clone()
        .unwrap_or_else(crate::default_machine_path);
    let read = |p: &Path| std::fs::read(p).with_context(|| format!("cannot read {}", p.display()));
    let store =
        softnc_learning::LearningStore::new(softnc_learning::store_dir(args.store.as_deref()));
    let found = softnc_learning::entry::lookup(
        &store,
        &read(&args.file)?,
        &read(&mpath)?,
        softnc_learning::entry::OVERRIDE_PCT,
        planned_samples,
        cycle_s,
    )?;
    Ok(match found {
        softnc_learning::Lookup::Markov(c) => Ok(c),
        softnc_learning::Lookup::NotApplied(why) => Err(why),
        softnc_learning::Lookup::None => Err(format!(
            "no learning entry for {} on {} in {} (run `softnc learn` first)",
            args.file.display(),
            mpath.display(),
            store.dir().display()
        )),
    })
}

/// Outward unit normal of the contour-error field at `p` (its gradient), in XY.
fn normal_xy(prim: &Primitive, p: [f64; 3]) -> [f64; 2] {
    let d = 1e-6;
    let e = |dx: f64, dy: f64| prim.contour_error(Vec3::new(p[0] + dx, p[1] + dy, p[2]));
    let g = [
        (e(d, 0.0) - e(-d, 0.0)) / (2.0 * d),
        (e(0.0, d) - e(0.0, -d)) / (2.0 * d),
    ];
    let n = g[0].hypot(g[1]);
    if n > 0.0 {
        [g[0] / n, g[1] / n]
    } else {
        [0.0, 0.0]
    }
}

fn plot_point(row: &TraceRow, prim: Option<Primitive>) -> PlotPoint {
    let r = &row.record;
    let (contour_um, normal) = match (row.contour_mm, prim) {
        (Some(c), Some(p)) => (Some(c * 1000.0), normal_xy(&p, r.actual_mm.xyz())),
        _ => (None, [0.0, 0.0]),
    };
    PlotPoint {
        t_s: row.time_s,
        cmd: [r.cmd_mm[0], r.cmd_mm[1], r.cmd_mm[2]],
        magnified: contour_um.map(|_| [r.actual_mm[0], r.actual_mm[1]]),
        contour_um,
        following_um: r.following_mm.xyz().map(|f| f * 1000.0),
        normal,
        tolerance_um: None,
    }
}

/// The job's plot (SVG): left, the XY path with the contour error magnified along its
/// normal (with its µm scale) above the XZ and YZ paths; right, the contour error over
/// time with the blending tolerance in force and the worst spots' program lines, and
/// the three axes' following errors. Error scales come from the 99.5 % quantile: a
/// start-up transient does not set them (it is clipped, and said so).
#[allow(clippy::too_many_lines)]
fn draw_plot(path: &Path, pts: &[PlotPoint], worst: &[WorstSpot], title: &str) -> Result<()> {
    let root = SVGBackend::new(path, (1400, 900)).into_drawing_area();
    root.fill(&WHITE)?;
    let plot_err = |e: &dyn std::fmt::Display| anyhow::anyhow!("plot {}: {e}", path.display());
    let name = Path::new(title)
        .file_name()
        .map_or(title.to_string(), |n| n.to_string_lossy().into_owned());
    let root = root
        .titled(&name, ("sans-serif", 20))
        .map_err(|e| plot_err(&e))?;
    let (left, right) = root.split_horizontally(700);
    let (xy_area, projections) = left.split_vertically(520);
    let (xz_area, yz_area) = projections.split_horizontally(350);

    // the XY path, and the contour error magnified along the path's normal
    let (lo, hi) = bounds(pts.iter().map(|p| p.cmd));
    let extent = (hi[0] - lo[0]).max(hi[1] - lo[1]).max(1e-3);
    let (n, sq) = pts
        .iter()
        .filter_map(|p| p.contour_um)
        .fold((0usize, 0.0f64), |(n, s), c| (n + 1, s + c * c));
    let rms_um = if n > 0 { (sq / n as f64).sqrt() } else { 0.0 };
    let gain = if rms_um > 0.0 {
        (PLOT_MAGNIFIED_FRACTION * extent / (PLOT_RMS_SPAN * rms_um / 1000.0)).max(1.0)
    } else {
        1.0
    };
    let half = 0.5 * extent + 0.1 * extent;
    let (cx, cy) = (0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]));
    let mut chart = ChartBuilder::on(&xy_area)
        .caption(
            format!(
                "XY (mm); error ×{gain:.0}: 1 mm here = {:.1} µm",
                1000.0 / gain
            ),
            ("sans-serif", 15),
        )
        .margin(10)
        .x_label_area_size(28)
        .y_label_area_size(50)
        .build_cartesian_2d(cx - half..cx + half, cy - half..cy + half)
        .map_err(|e| plot_err(&e))?;
    chart.configure_mesh().draw().map_err(|e| plot_err(&e))?;
    chart
        .draw_series(LineSeries::new(
            pts.iter().map(|p| (p.cmd[0], p.cmd[1])),
            RGBColor(170, 170, 170),
        ))
        .map_err(|e| plot_err(&e))?;
    chart
        .draw_series(pts.iter().filter_map(|p| {
            let c = p.contour_um? / 1000.0;
            let a = p.magnified?;
            // the foot on the path plus the error times the gain, along the normal
            let foot = [a[0] - c * p.normal[0], a[1] - c * p.normal[1]];
            let m = [
                foot[0] + gain * c * p.normal[0],
                foot[1] + gain * c * p.normal[1],
            ];
            Some(Circle::new((m[0], m[1]), 1, BLUE.filled()))
        }))
        .map_err(|e| plot_err(&e))?;

    // the XZ and YZ paths (the command)
    for (area, (a, label)) in [(&xz_area, (0, "XZ (mm)")), (&yz_area, (1, "YZ (mm)"))] {
        let (lo, hi) = bounds(pts.iter().map(|p| [p.cmd[a], p.cmd[2], 0.0]));
        let pad = |l: f64, h: f64| {
            let d = (h - l).max(1e-3);
            (l - 0.05 * d, h + 0.05 * d)
        };
        let (x0, x1) = pad(lo[0], hi[0]);
        let (z0, z1) = pad(lo[1], hi[1]);
        let mut chart = ChartBuilder::on(area)
            .caption(label, ("sans-serif", 15))
            .margin(10)
            .x_label_area_size(28)
            .y_label_area_size(45)
            .build_cartesian_2d(x0..x1, z0..z1)
            .map_err(|e| plot_err(&e))?;
        chart
            .configure_mesh()
            .x_labels(5)
            .y_labels(5)
            .draw()
            .map_err(|e| plot_err(&e))?;
        chart
            .draw_series(LineSeries::new(
                pts.iter().map(|p| (p.cmd[a], p.cmd[2])),
                RGBColor(90, 90, 90),
            ))
            .map_err(|e| plot_err(&e))?;
    }

    // the contour error over time, the tolerance in force, the worst spots
    let (top, bottom) = right.split_vertically(440);
    let t_max = pts.last().map(|p| p.t_s).unwrap_or(1.0).max(1e-3);
    let c_scale = robust_scale(pts.iter().filter_map(|p| p.contour_um));
    let tol_max = pts
        .iter()
        .filter_map(|p| p.tolerance_um)
        .fold(0.0f64, f64::max);
    let c_max = c_scale.max(1.1 * tol_max.min(10.0 * c_scale));
    let clipped = pts
        .iter()
        .filter_map(|p| p.contour_um)
        .filter(|c| c.abs() > c_max)
        .count();
    // the worst spots are numbered on the plot and listed in the caption, so that
    // their labels never cover each other or the data
    let mut worst = worst.to_vec();
    worst.sort_by(|a, b| b.contour_um.abs().total_cmp(&a.contour_um.abs()));
    let mut caption = "contour error (µm)".to_string();
    if !worst.is_empty() {
        let list: Vec<String> = worst
            .iter()
            .enumerate()
            .map(|(i, w)| format!("{} line {} {:.1}", i + 1, w.line, w.contour_um))
            .collect();
        caption.push_str(&format!("; worst: {}", list.join(", ")));
    }
    if clipped > 0 {
        caption.push_str(&format!("; {clipped} beyond ±{c_max:.1} clipped"));
    }
    let mut chart = ChartBuilder::on(&top)
        .caption(caption, ("sans-serif", 15))
        .margin(10)
        .x_label_area_size(28)
        .y_label_area_size(55)
        .build_cartesian_2d(0.0..t_max, -c_max..c_max)
        .map_err(|e| plot_err(&e))?;
    chart.configure_mesh().draw().map_err(|e| plot_err(&e))?;
    for sign in [1.0, -1.0] {
        let series = chart
            .draw_series(LineSeries::new(
                pts.iter()
                    .filter_map(|p| Some((p.t_s, sign * p.tolerance_um?.min(c_max)))),
                RED.mix(0.6),
            ))
            .map_err(|e| plot_err(&e))?;
        if sign > 0.0 {
            series
                .label("G64 tolerance in force")
                .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], RED));
        }
    }
    chart
        .draw_series(pts.iter().filter_map(|p| {
            let c = p.contour_um?.clamp(-c_max, c_max);
            Some(Circle::new((p.t_s, c), 1, BLUE.filled()))
        }))
        .map_err(|e| plot_err(&e))?;
    chart
        .draw_series(worst.iter().enumerate().map(|(i, w)| {
            let y = w.contour_um.clamp(-c_max, c_max);
            EmptyElement::at((w.t_s, y))
                + Circle::new((0, 0), 4, BLACK)
                + Text::new(
                    format!("{}", i + 1),
                    (6, if y >= 0.0 { -14 } else { 4 }),
                    ("sans-serif", 13),
                )
        }))
        .map_err(|e| plot_err(&e))?;
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::LowerRight)
        .background_style(WHITE.mix(0.6))
        .border_style(BLACK)
        .draw()
        .map_err(|e| plot_err(&e))?;

    // the following errors of the three axes
    let f_max = robust_scale(pts.iter().flat_map(|p| p.following_um));
    let mut chart = ChartBuilder::on(&bottom)
        .caption("following error (µm)", ("sans-serif", 15))
        .margin(10)
        .x_label_area_size(28)
        .y_label_area_size(55)
        .build_cartesian_2d(0.0..t_max, -f_max..f_max)
        .map_err(|e| plot_err(&e))?;
    chart
        .configure_mesh()
        .x_desc("time (s)")
        .draw()
        .map_err(|e| plot_err(&e))?;
    for (k, (name, color)) in [("X", RED), ("Y", GREEN), ("Z", BLUE)]
        .into_iter()
        .enumerate()
    {
        chart
            .draw_series(LineSeries::new(
                pts.iter()
                    .map(|p| (p.t_s, p.following_um[k].clamp(-f_max, f_max))),
                color,
            ))
            .map_err(|e| plot_err(&e))?
            .label(name)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], color));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(|e| plot_err(&e))?;
    root.present().map_err(|e| plot_err(&e))?;
    Ok(())
}

/// Smallest and largest of each coordinate (X and Y of `[x, y, _]`); the unit square
/// when there are no points.
fn bounds(points: impl Iterator<Item = [f64; 3]>) -> ([f64; 2], [f64; 2]) {
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for p in points {
        for k in 0..2 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    if lo[0].is_finite() && lo[1].is_finite() {
        (lo, hi)
    } else {
        ([0.0; 2], [1.0; 2])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ws(rel: &str) -> PathBuf {
        PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("../..")
            .join(rel)
    }

    fn args(file: &str, machine: &str, trace: Option<PathBuf>, seed: u64) -> SimArgs {
        SimArgs {
            file: ws(file),
            machine: Some(ws(machine)),
            json: true,
            trace,
            plot: None,
            seed: Some(seed),
            spindle_override: 100.0,
            learned: false,
            store: None,
            feed_override: 100.0,
            rapid_override: 100.0,
            adaptive_force: false,
            lookahead: None,
            block_delete: crate::cmd_operator::OnOff::On,
            optional_stop: crate::cmd_operator::OnOff::On,
            user_m_codes: None,
        }
    }

    /// The daemon configuration (`--adaptive-force` reads its lookahead).
    fn config() -> PathBuf {
        ws("config/default.ron")
    }

    fn run_args(a: SimArgs) -> Result<ExitCode> {
        run(a, &config())
    }

    #[test]
    fn adaptive_force_needs_a_force_model_and_no_learned_correction() {
        let prog = "crates/softnc-sim/tests/data/circle-r20-f400.ngc";
        let mut a = args(prog, "config/machines/mill-friction.ron", None, 1);
        a.adaptive_force = true;
        let code = run_args(a).unwrap();
        assert_eq!(
            format!("{code:?}"),
            format!("{:?}", ExitCode::from(crate::EXIT_REFUSED))
        );
        let mut a = args(prog, "config/machines/mch10-force.ron", None, 1);
        a.adaptive_force = true;
        a.learned = true;
        let code = run_args(a).unwrap();
        assert_eq!(
            format!("{code:?}"),
            format!("{:?}", ExitCode::from(crate::EXIT_REFUSED))
        );
    }

    #[cfg(unix)]
    #[test]
    fn user_m_codes_need_their_folder_and_are_taken_as_done_at_once() {
        use std::os::unix::fs::PermissionsExt;
        let dir = std::env::temp_dir().join(format!("softnc-sim-userm-{}", std::process::id()));
        let mcodes = dir.join("mcodes");
        std::fs::create_dir_all(&mcodes).unwrap();
        // (an executable that would never end: the simulator does not run it)
        let m = mcodes.join("M101");
        std::fs::write(&m, "#!/bin/sh\nsleep 1000\n").unwrap();
        std::fs::set_permissions(&m, std::fs::Permissions::from_mode(0o755)).unwrap();
        let prog = dir.join("userm.ngc");
        std::fs::write(&prog, "G21 G90\nG1 X5 F1200\nM101 P1 Q2\nG1 X10\nM2\n").unwrap();
        let p = prog.to_str().unwrap();
        let refused = run_args(args(p, "config/machines/default.ron", None, 1)).unwrap();
        assert_eq!(
            format!("{refused:?}"),
            format!("{:?}", ExitCode::from(crate::EXIT_REFUSED))
        );
        let mut a = args(p, "config/machines/default.ron", None, 1);
        a.user_m_codes = Some(mcodes);
        let t = std::time::Instant::now();
        let code = run_args(a).unwrap();
        assert_eq!(format!("{code:?}"), format!("{:?}", ExitCode::SUCCESS));
        assert!(t.elapsed().as_secs() < 100, "{:?}", t.elapsed());
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn one_seed_gives_a_byte_identical_trace_file() {
        let dir = std::env::temp_dir().join(format!("softnc-sim-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let prog = "crates/softnc-sim/tests/data/circle-r20-f400.ngc";
        let mach = "config/machines/mill-friction.ron";
        let mut files = Vec::new();
        for (i, seed) in [3, 3, 4].into_iter().enumerate() {
            let out = dir.join(format!("t{i}.csv"));
            let code = run_args(args(prog, mach, Some(out.clone()), seed)).unwrap();
            assert_eq!(format!("{code:?}"), format!("{:?}", ExitCode::SUCCESS));
            files.push(std::fs::read(&out).unwrap());
        }
        assert!(files[0] == files[1], "same seed, different trace");
        // the plot is drawn too
        let svg = dir.join("p.svg");
        let mut a = args(prog, mach, None, 3);
        a.plot = Some(svg.clone());
        run(a, &config()).unwrap();
        let svg = std::fs::read_to_string(&svg).unwrap();
        assert!(
            svg.starts_with("<svg") && svg.contains("contour error"),
            "plot"
        );
        // every axis, the µm scale of the magnified path, the tolerance, the worst
        // spots' program lines
        for want in [
            "XZ (mm)",
            "YZ (mm)",
            "µm",
            "G64 tolerance in force",
            "line ",
        ] {
            assert!(svg.contains(want), "the plot has no {want:?}");
        }
        assert!(files[0] != files[2], "different seeds, same trace");
        let text = String::from_utf8(files[0].clone()).unwrap();
        assert!(text.starts_with("time_s,cmd_x_mm,"), "{}", &text[..40]);
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn the_worst_spots_are_of_different_lines_and_a_transient_does_not_set_the_scale() {
        let mut worst = Vec::new();
        for (k, (c, line)) in [(1.0, 5), (-9.0, 5), (3.0, 6), (2.0, 7), (4.0, 8), (0.5, 9)]
            .into_iter()
            .enumerate()
        {
            note_worst(
                &mut worst,
                WorstSpot {
                    t_s: k as f64,
                    contour_um: c,
                    line,
                },
            );
        }
        let mut lines: Vec<u32> = worst.iter().map(|w| w.line).collect();
        lines.sort();
        assert_eq!(lines, [5, 6, 8], "{worst:?}");
        assert_eq!(worst.iter().find(|w| w.line == 5).unwrap().contour_um, -9.0);
        // 1000 points within ±2 µm and a start transient of 500 µm
        let values = (0..1000)
            .map(|k| 2.0 * (k as f64 * 0.1).sin())
            .chain([500.0, -480.0]);
        let scale = robust_scale(values);
        assert!(scale > 1.9 && scale < 3.0, "{scale}");
    }

    #[test]
    fn a_bad_program_is_refused_with_status_2() {
        let code = run_args(args(
            "crates/softnc-sim/tests/data/bad.ngc",
            "config/machines/mill-friction.ron",
            None,
            1,
        ))
        .unwrap();
        assert_eq!(
            format!("{code:?}"),
            format!("{:?}", ExitCode::from(crate::EXIT_REFUSED))
        );
    }
}
