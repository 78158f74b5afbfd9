//! Paper 001, Table 5's cases and runs: the six contour/feed cases, the controller
//! stacks (PID, FLC), each case planned and run on the simulated machine, the table's
//! rows, their JSON and text, and the circle plot — what the experiment
//! ([`crate::p001`]) and its audit ([`crate::p001_audit`]) both run.

use crate::error::{failed, Context, Result};
use crate::plot::{write_svg, Panel, Series};
use crate::workspace_file;
use plotters::style::colors::{BLUE, RED};
use softnc_machine::fuzzy::FuzzyConfig;
use softnc_machine::MachineProfile;
use softnc_sim::{simulated_engine, SimOptions};
use std::path::Path;

/// Time the command is held at the end point after the program ends (s), so the final
/// settling is part of the error.
pub const HOLD_S: f64 = 0.5;

/// One of the paper's cases with its printed figures (10 µm).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Case {
    /// "line", "circle" or "corner".
    pub contour: &'static str,
    /// "low" or "high".
    pub feed: &'static str,
    /// Programmed feed (mm/min), as in the G-code file.
    pub feed_mm_min: f64,
    /// Paper's PID max, FLC max, PID RMS, FLC RMS.
    pub paper: [f64; 4],
}

/// Table 5 of paper 001.
pub const CASES: [Case; 6] = [
    Case {
        contour: "line",
        feed: "low",
        feed_mm_min: 400.0,
        paper: [9.3, 6.6, 1.8, 1.6],
    },
    Case {
        contour: "line",
        feed: "high",
        feed_mm_min: 900.0,
        paper: [9.4, 8.3, 1.9, 1.6],
    },
    Case {
        contour: "circle",
        feed: "low",
        feed_mm_min: 400.0,
        paper: [11.9, 10.0, 4.2, 2.7],
    },
    Case {
        contour: "circle",
        feed: "high",
        feed_mm_min: 1300.0,
        paper: [39.9, 25.7, 27.7, 11.7],
    },
    Case {
        contour: "corner",
        feed: "low",
        feed_mm_min: 300.0,
        paper: [25.2, 17.4, 5.0, 3.2],
    },
    Case {
        contour: "corner",
        feed: "high",
        feed_mm_min: 600.0,
        paper: [46.0, 40.2, 7.8, 5.3],
    },
];

impl Case {
    /// The G-code file of this case, relative to the workspace.
    pub fn file(&self) -> String {
        format!("examples/paper001/{}_{}.ngc", self.contour, self.feed)
    }
}

/// Which controller stack runs the X and Y axes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stack {
    /// Incremental PID of eq 14 with Table 4's gains (the profile's controller).
    Pid,
    /// Paper 001's FLC (eq 2–8, Table 3, reconstructed Table 1, K_I of Table 4).
    Flc,
    /// The best stack we have for this machine: see [`best_stack`].
    Best,
}

/// Max and RMS contour error (10 µm).
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct Stats {
    /// Largest |ε|.
    pub max: f64,
    /// RMS of ε.
    pub rms: f64,
}

/// One row: our figures (mean over seeds) and the paper's.
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    /// The case.
    pub case: Case,
    /// PID, FLC, best: mean over seeds.
    pub pid: Stats,
    /// See `pid`.
    pub flc: Stats,
    /// See `pid`.
    pub best: Stats,
    /// Per seed: (PID, FLC, best).
    pub per_seed: Vec<(u64, Stats, Stats, Stats)>,
}

/// One sample of a run, for plots.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TracePoint {
    /// Command position X, Y (mm).
    pub cmd_mm: [f64; 2],
    /// Signed contour error (mm).
    pub contour_mm: f64,
    /// Position error command − measured of X and Y that the controllers acted on (mm).
    pub following_mm: [f64; 2],
}

/// The velocity and acceleration feedforward that invert the nominal drive of axis
/// `axis`, u = (V + τ dV/dt)/K in DAC counts: (vff per mm/s, aff per mm/s²).
pub fn drive_feedforward(machine: &MachineProfile, axis: usize) -> (f64, f64) {
    match machine.axis_servo(axis).plant {
        softnc_machine::servo::PlantModel::DcMotor {
            gain_mm_per_min_per_dac,
            tau_s,
            ..
        } => {
            let k = gain_mm_per_min_per_dac / 60.0; // mm/s per DAC count
            (1.0 / k, tau_s / k)
        }
        _ => (0.0, 0.0),
    }
}

/// The best stack this project has for the machine: PID (eq 14, Table 4) plus velocity
/// and acceleration feedforward inverting the nominal K, τ of Table 2. (FLC with the
/// same feedforward was measured too and is worse in RMS on five of the six rows;
/// see `docs/reproduce-001.md`.)
pub fn best_stack() -> (Stack, &'static str) {
    (
        Stack::Pid,
        "PID + velocity/acceleration feedforward (1/K, tau/K of Table 2)",
    )
}

/// `base` with the controller of X and Y set to `stack`.
pub fn machine_for(base: &MachineProfile, stack: Stack, flc: &FuzzyConfig) -> MachineProfile {
    let mut m = base.clone();
    for i in 0..m.servo.axes.len().min(2) {
        let (vff, aff) = drive_feedforward(base, i);
        let c = &mut m.servo.axes[i].controller;
        match stack {
            Stack::Pid => c.fuzzy = None,
            Stack::Flc => c.fuzzy = Some(flc.clone()),
            Stack::Best => {
                c.fuzzy = match best_stack().0 {
                    Stack::Flc => Some(flc.clone()),
                    _ => None,
                };
                c.vff = vff;
                c.aff = aff;
            }
        }
    }
    m
}

/// A planned case, ready to run many times.
pub struct PreparedCase {
    plan: softnc_planner::Plan,
}

/// Read and plan the G-code of `case` for `machine`.
pub fn prepare(case: &Case, machine: &MachineProfile) -> Result<PreparedCase> {
    let path = workspace_file(case.file());
    let text = std::fs::read_to_string(&path)
        .with_context(|| format!("cannot read {}", path.display()))?;
    let program = softnc_gcode::read_program(&text, &case.file(), machine).map_err(failed)?;
    let plan = softnc_planner::plan(&program, machine, &softnc_planner::PlanOptions::default())
        .map_err(failed)?;
    Ok(PreparedCase { plan })
}

/// Run one planned case on `machine` with `seed`; `observe` sees every measured sample.
pub fn run(
    prepared: &PreparedCase,
    machine: &MachineProfile,
    seed: u64,
    mut observe: impl FnMut(TracePoint),
) -> Result<Stats> {
    let plan = &prepared.plan;
    let cycle_s = plan.cycle_s();
    let mut engine = simulated_engine(machine, seed, SimOptions::default());
    let samples: Vec<softnc_planner::Sample> = plan.interpolator().collect();
    let first = samples.first().context("empty plan")?;
    engine.reset(first.pos_mm.0);
    let last_feed = samples
        .iter()
        .rev()
        .find(|s| s.feed_move)
        .context("no feed move")?;
    let hold = (HOLD_S / cycle_s).round() as usize;
    let tail = std::iter::repeat_n(*last_feed, hold);
    let (mut n, mut sum_sq, mut max) = (0usize, 0.0f64, 0.0f64);
    for s in samples.iter().copied().chain(tail) {
        let rec = engine.step(s.pos_mm.0, s.feed_move).map_err(failed)?;
        if !s.feed_move {
            continue;
        }
        let Some(prim) = plan.motion_primitive(s.motion as usize) else {
            continue;
        };
        let p = engine.backend().true_pos_mm();
        let e = prim.contour_error(softnc_core::Vec3(p.xyz()));
        observe(TracePoint {
            cmd_mm: [s.pos_mm.0[0], s.pos_mm.0[1]],
            contour_mm: e,
            following_mm: [rec.following_mm[0], rec.following_mm[1]],
        });
        n += 1;
        sum_sq += e * e;
        max = max.max(e.abs());
    }
    let to_10um = 100.0;
    Ok(Stats {
        max: max * to_10um,
        rms: (sum_sq / n.max(1) as f64).sqrt() * to_10um,
    })
}

/// All six rows over `seeds`.
pub fn table(machine: &MachineProfile, flc: &FuzzyConfig, seeds: &[u64]) -> Result<Vec<Row>> {
    let machines = [Stack::Pid, Stack::Flc, Stack::Best].map(|s| machine_for(machine, s, flc));
    let mut rows = Vec::new();
    for case in CASES {
        let prepared = prepare(&case, machine)?;
        let mut per_seed = Vec::new();
        for &seed in seeds {
            let [p, f, b] = [0, 1, 2].map(|k| run(&prepared, &machines[k], seed, |_| {}));
            per_seed.push((seed, p?, f?, b?));
        }
        let mean = |pick: fn(&(u64, Stats, Stats, Stats)) -> Stats| {
            let n = per_seed.len().max(1) as f64;
            Stats {
                max: per_seed.iter().map(|r| pick(r).max).sum::<f64>() / n,
                rms: per_seed.iter().map(|r| pick(r).rms).sum::<f64>() / n,
            }
        };
        rows.push(Row {
            case,
            pid: mean(|r| r.1),
            flc: mean(|r| r.2),
            best: mean(|r| r.3),
            per_seed,
        });
    }
    Ok(rows)
}

/// The JSON document of the issue: `{"rows":[{contour, feed, pid, flc, best, paper}]}`.
pub fn to_json(rows: &[Row]) -> serde_json::Value {
    let r1 = |x: f64| (x * 100.0).round() / 100.0;
    let st = |s: &Stats| serde_json::json!({"max": r1(s.max), "rms": r1(s.rms)});
    serde_json::json!({
        "rows": rows.iter().map(|r| serde_json::json!({
            "contour": r.case.contour,
            "feed": r.case.feed,
            "pid": st(&r.pid),
            "flc": st(&r.flc),
            "best": st(&r.best),
            "paper": {
                "pid_max": r.case.paper[0],
                "flc_max": r.case.paper[1],
                "pid_rms": r.case.paper[2],
                "flc_rms": r.case.paper[3],
            },
        })).collect::<Vec<_>>()
    })
}

/// The table as text, ours beside the paper's.
pub fn to_text(rows: &[Row], seeds: &[u64]) -> String {
    let mut s = format!(
        "paper 001 Table 5 on mill-friction.ron: contour error in 10 µm, mean over seeds {seeds:?}\n\
         best = {}\n\n",
        best_stack().1
    );
    s += "contour feed  mm/min | PID max  FLC max  PID rms  FLC rms | paper: PID max  FLC max  PID rms  FLC rms | best max  best rms\n";
    for r in rows {
        s += &format!(
            "{:<7} {:<4} {:>6} | {:>7.2}  {:>7.2}  {:>7.2}  {:>7.2} |        {:>7.1}  {:>7.1}  {:>7.1}  {:>7.1} | {:>8.2}  {:>8.2}\n",
            r.case.contour,
            r.case.feed,
            r.case.feed_mm_min,
            r.pid.max,
            r.flc.max,
            r.pid.rms,
            r.flc.rms,
            r.case.paper[0],
            r.case.paper[1],
            r.case.paper[2],
            r.case.paper[3],
            r.best.max,
            r.best.rms
        );
    }
    s += "\nours / paper (factor-2 band: 0.50 .. 2.00)\n";
    s += "contour feed  | PID max  FLC max  PID rms  FLC rms\n";
    for r in rows {
        let q = |ours: f64, k: usize| ours / r.case.paper[k];
        s += &format!(
            "{:<7} {:<4}  | {:>7.2}  {:>7.2}  {:>7.2}  {:>7.2}\n",
            r.case.contour,
            r.case.feed,
            q(r.pid.max, 0),
            q(r.flc.max, 1),
            q(r.pid.rms, 2),
            q(r.flc.rms, 3)
        );
    }
    s
}

/// Contour error around the circle (angle from the start point, degrees) for PID and
/// FLC, seed `seed`, as an SVG file.
pub fn plot_circle(
    case: &Case,
    machine: &MachineProfile,
    flc: &FuzzyConfig,
    seed: u64,
    out: &Path,
) -> Result<()> {
    let prepared = prepare(case, machine)?;
    let mut series = Vec::new();
    for (stack, name, colour) in [(Stack::Pid, "PID", RED), (Stack::Flc, "FLC", BLUE)] {
        let m = machine_for(machine, stack, flc);
        let mut pts = Vec::new();
        run(&prepared, &m, seed, |t| {
            // centre (0, 20), start at the origin, counter-clockwise
            let ang = t.cmd_mm[0].atan2(20.0 - t.cmd_mm[1]).to_degrees();
            let ang = if ang < 0.0 { ang + 360.0 } else { ang };
            pts.push((ang, t.contour_mm * 100.0));
        })?;
        // the hold samples and the closing point sit at 360°; keep the path order
        if let Some(k) = pts.iter().position(|p| p.0 > 300.0) {
            for p in pts[k..].iter_mut() {
                if p.0 < 60.0 {
                    p.0 += 360.0;
                }
            }
        }
        series.push(Series::new(name, pts, colour));
    }
    let (lo, hi) = series
        .iter()
        .flat_map(|s| s.points.iter().map(|p| p.1))
        .fold((0.0f64, 0.0f64), |(lo, hi), v| (lo.min(v), hi.max(v)));
    let pad = 0.05 * (hi - lo).max(1.0);
    let panel = Panel {
        x_labels: Some(9),
        ..Panel::new(
            format!(
                "paper 001 circle r = 20 mm, {} m/min, seed {seed}: contour error (10 µm)",
                case.feed_mm_min / 1000.0
            ),
            420,
            0.0..362.0,
            (lo - pad)..(hi + pad),
        )
        .axes("angle from the start point (deg)", "contour error (10 µm)")
        .lines(series)
    };
    write_svg(out, 900, &[panel])
}
