//! `softnc sim FILE --machine PROFILE`: planner → controller stacks → simulated machine,
//! in one process, as fast as the CPU allows; accuracy figures, trace and plot.

use crate::cmd_plan::{load_machine, read_file};
use anyhow::{Context, Result};
use plotters::prelude::*;
use softnc_core::{Primitive, Vec3};
use softnc_servo::TraceRow;
use softnc_sim::{simulate, simulated_engine, CommandSample, ErrorStats, SimOptions};
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
    cmd: [f64; 2],
    magnified: Option<[f64; 2]>,
    contour_um: Option<f64>,
    following_um: [f64; 2],
    normal: [f64; 2],
}

pub fn run(args: SimArgs) -> Result<ExitCode> {
    let machine = match load_machine(args.machine.as_ref()) {
        Ok(m) => m,
        Err(e) => {
            eprintln!("softnc: {e:#}");
            return Ok(ExitCode::from(crate::EXIT_REFUSED));
        }
    };
    let program = match read_file(&args.file, &machine)? {
        Ok(p) => p,
        Err(msg) => {
            eprintln!("{msg}");
            return Ok(ExitCode::from(crate::EXIT_REFUSED));
        }
    };
    for w in &program.warnings {
        eprintln!("warning: {w}");
    }
    let plan = match softnc_planner::plan(&program, &machine, &Default::default()) {
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
    let learned = if args.learned {
        match learned_correction(&args, &plan)? {
            Ok(c) => Some(c),
            Err(msg) => {
                eprintln!("softnc sim --learned: {msg}");
                return Ok(ExitCode::from(1));
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
    let (mut next_plot, mut next_progress) = (0u64, 0u64);
    let mut trace_err: Option<anyhow::Error> = None;

    let path_of = |m: u32| plan.motion_primitive(m as usize);
    let samples: Box<dyn Iterator<Item = CommandSample>> = match &learned {
        Some(c) => Box::new(c.corrected(command_samples(&plan))),
        None => Box::new(command_samples(&plan)),
    };
    let started = Instant::now();
    let report = simulate(&mut engine, cycle_s, samples, path_of, |row: &TraceRow| {
        if let Some(w) = trace.as_mut() {
            if trace_err.is_none() {
                if let Err(e) = w.row(row) {
                    trace_err = Some(anyhow::Error::from(e).context("writing the trace"));
                }
            }
        }
        if args.plot.is_some() && row.cycle >= next_plot {
            plot_points.push(plot_point(row, path_of(row.motion)));
            next_plot += stride;
        }
        if let Some(bar) = &progress {
            if row.cycle >= next_progress {
                next_progress += PROGRESS_CYCLES;
                bar.set_position(row.cycle);
            }
        }
    })
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
        draw_plot(path, &plot_points, &program.file)?;
    }

    let um = 1000.0;
    let axis =
        |s: &ErrorStats| serde_json::json!({"max_abs": s.max_abs() * um, "rms": s.rms() * um});
    let summary = serde_json::json!({
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
        for (name, s) in ["X", "Y", "Z"].iter().zip(&report.following) {
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

/// The stored Markov correction of the job for --learned, or why there is none.
fn learned_correction(
    args: &SimArgs,
    plan: &softnc_planner::Plan,
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
        || plan.interpolator().count(),
        plan.cycle_s(),
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

/// The plan's sample stream as the simulator takes it.
pub fn command_samples(plan: &softnc_planner::Plan) -> impl Iterator<Item = CommandSample> + '_ {
    plan.interpolator().map(|s| CommandSample {
        pos_mm: s.pos_mm.0,
        motion: s.motion,
        feed_move: s.feed_move,
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
        (Some(c), Some(p)) => (Some(c * 1000.0), normal_xy(&p, r.actual_mm)),
        _ => (None, [0.0, 0.0]),
    };
    PlotPoint {
        t_s: row.time_s,
        cmd: [r.cmd_mm[0], r.cmd_mm[1]],
        magnified: contour_um.map(|_| [r.actual_mm[0], r.actual_mm[1]]),
        contour_um,
        following_um: [r.following_mm[0] * 1000.0, r.following_mm[1] * 1000.0],
        normal,
    }
}

fn draw_plot(path: &Path, pts: &[PlotPoint], title: &str) -> Result<()> {
    let root = SVGBackend::new(path, (1400, 640)).into_drawing_area();
    root.fill(&WHITE)?;
    let (left, right) = root.split_horizontally(700);
    let plot_err = |e: &dyn std::fmt::Display| anyhow::anyhow!("plot {}: {e}", path.display());

    // left: the path, and the contour error magnified along the path's normal
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for p in pts {
        for k in 0..2 {
            lo[k] = lo[k].min(p.cmd[k]);
            hi[k] = hi[k].max(p.cmd[k]);
        }
    }
    if !lo[0].is_finite() {
        lo = [0.0; 2];
        hi = [1.0; 2];
    }
    let extent = (hi[0] - lo[0]).max(hi[1] - lo[1]).max(1e-3);
    let max_um = pts
        .iter()
        .filter_map(|p| p.contour_um)
        .fold(0.0f64, |m, c| m.max(c.abs()));
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
    let pad = 0.1 * extent;
    let cx = 0.5 * (lo[0] + hi[0]);
    let cy = 0.5 * (lo[1] + hi[1]);
    let half = 0.5 * extent + pad;
    let mut chart = ChartBuilder::on(&left)
        .caption(
            format!("{title}: contour error x{gain:.0} around the path (XY, mm)"),
            ("sans-serif", 16),
        )
        .margin(12)
        .x_label_area_size(30)
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

    // right: contour error (top) and following errors (bottom) over time
    let (top, bottom) = right.split_vertically(320);
    let t_max = pts.last().map(|p| p.t_s).unwrap_or(1.0).max(1e-3);
    let c_max = if max_um > 0.0 { max_um } else { 1.0 };
    let mut chart = ChartBuilder::on(&top)
        .caption("contour error (µm)", ("sans-serif", 16))
        .margin(12)
        .x_label_area_size(30)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..t_max, -1.05 * c_max..1.05 * c_max)
        .map_err(|e| plot_err(&e))?;
    chart.configure_mesh().draw().map_err(|e| plot_err(&e))?;
    chart
        .draw_series(
            pts.iter()
                .filter_map(|p| Some(Circle::new((p.t_s, p.contour_um?), 1, BLUE.filled()))),
        )
        .map_err(|e| plot_err(&e))?;
    let f_max = pts
        .iter()
        .flat_map(|p| [p.following_um[0].abs(), p.following_um[1].abs()])
        .fold(0.0, f64::max);
    let f_max = if f_max > 0.0 { f_max } else { 1.0 };
    let mut chart = ChartBuilder::on(&bottom)
        .caption("following error (µm)", ("sans-serif", 16))
        .margin(12)
        .x_label_area_size(30)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..t_max, -1.05 * f_max..1.05 * f_max)
        .map_err(|e| plot_err(&e))?;
    chart
        .configure_mesh()
        .x_desc("time (s)")
        .draw()
        .map_err(|e| plot_err(&e))?;
    for (k, (name, color)) in [("X", RED), ("Y", GREEN)].into_iter().enumerate() {
        chart
            .draw_series(LineSeries::new(
                pts.iter().map(|p| (p.t_s, p.following_um[k])),
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
        }
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
            let code = run(args(prog, mach, Some(out.clone()), seed)).unwrap();
            assert_eq!(format!("{code:?}"), format!("{:?}", ExitCode::SUCCESS));
            files.push(std::fs::read(&out).unwrap());
        }
        assert!(files[0] == files[1], "same seed, different trace");
        // the plot is drawn too
        let svg = dir.join("p.svg");
        let mut a = args(prog, mach, None, 3);
        a.plot = Some(svg.clone());
        run(a).unwrap();
        let svg = std::fs::read_to_string(&svg).unwrap();
        assert!(
            svg.starts_with("<svg") && svg.contains("contour error"),
            "plot"
        );
        assert!(files[0] != files[2], "different seeds, same trace");
        let text = String::from_utf8(files[0].clone()).unwrap();
        assert!(text.starts_with("time_s,cmd_x_mm,"), "{}", &text[..40]);
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn a_bad_program_is_refused_with_status_2() {
        let code = run(args(
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
