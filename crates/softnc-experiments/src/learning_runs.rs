//! Learning runs on the simulated machine (`softnc-learning`'s laws, `softnc-sim`'s
//! machine): the Markov-parameter identification run,
//! repetitions of a job under paper 002's eq 5, and repetitions of a circle under paper
//! 004's radius ILC (eq 8–9). Used by `softnc learn` and `softnc reproduce 002-learning
//! / 004-ilc` and the daemon's end-to-end tests; the laws are [`softnc_learning::markov`] and
//! [`softnc_learning::radius_ilc`].

use softnc_core::Axes;
use softnc_core::Primitive;
use softnc_learning::markov::{identify_markov, settled_terms, Improvement, MarkovJob, AXES};
use softnc_learning::radius_ilc::{Circle, RadiusIlc, POINTS};
use softnc_machine::MachineProfile;
use softnc_servo::{CycleEngine, ServoBackend};
use softnc_sim::{simulate, CommandSample, ErrorStats, SimBackend};

pub use softnc_learning::entry::{IterationStats, HOLD_S};

/// Height of the identification pulse (mm): large against encoder resolution and
/// noise (1e-4 of it at 0.1 µm) and against Coulomb friction, small against travel.
pub const PULSE_MM: f64 = 1.0;

/// Cycles at rest before the identification pulse.
pub const PULSE_AT: usize = 10;

/// A planned job: its command samples (with the hold tail) and programmed paths.
#[derive(Debug, Clone)]
pub struct PreparedJob {
    /// Planned command samples, the hold tail included.
    pub samples: Vec<CommandSample>,
    /// Programmed path of each motion.
    pub prims: Vec<Option<Primitive>>,
    /// Interpolation cycle (s).
    pub cycle_s: f64,
}

impl PreparedJob {
    /// Read and plan `text` for `machine`; a refusal comes back as its message.
    pub fn new(text: &str, name: &str, machine: &MachineProfile) -> Result<Self, String> {
        let program = softnc_gcode::read_program(text, name, machine).map_err(|e| e.to_string())?;
        let plan = softnc_planner::plan(&program, machine, &Default::default())
            .map_err(|e| e.to_string())?;
        let mut samples: Vec<CommandSample> = plan
            .interpolator()
            .map(|s| CommandSample {
                pos_mm: Axes::from_xyz(s.pos_mm.0, 0.0),
                motion: s.motion,
                feed_move: s.feed_move,
                outputs: Default::default(),
            })
            .collect();
        let cycle_s = plan.cycle_s();
        if let Some(last) = samples.last().copied() {
            let hold = (HOLD_S / cycle_s).round() as usize;
            let tail = CommandSample {
                pos_mm: last.pos_mm,
                motion: last.motion,
                feed_move: false,
                outputs: Default::default(),
            };
            samples.extend(std::iter::repeat_n(tail, hold));
        }
        let prims = (0..plan.motions())
            .map(|m| plan.motion_primitive(m))
            .collect();
        Ok(PreparedJob {
            samples,
            prims,
            cycle_s,
        })
    }

    /// Planned positions per sample.
    pub fn planned_mm(&self) -> Vec<[f64; AXES]> {
        self.samples.iter().map(|s| s.pos_mm.0).collect()
    }
}

/// What one repetition did.
#[derive(Debug, Clone)]
pub struct Run {
    /// Measured position at each sample (mm): `actual_mm` of the cycle that commanded
    /// sample k, i.e. the response to the commands before it. With a command filter
    /// of order N that is cycle N + k: the N cycles of lead-in (and of run-out) are
    /// not job samples.
    pub measured_mm: Vec<[f64; AXES]>,
    /// Contour error over the feed moves (mm).
    pub contour: ErrorStats,
}

/// Run `job` once on `engine` with `command(k, planned)` as the command of sample k.
pub fn run_job(
    engine: &mut CycleEngine<SimBackend>,
    job: &PreparedJob,
    command: impl Fn(usize, [f64; AXES]) -> [f64; AXES],
) -> Result<Run, String> {
    let mut measured_mm = Vec::with_capacity(job.samples.len());
    let lead_in = engine.filter_window() as u64;
    let samples = job.samples.iter().enumerate().map(|(k, s)| CommandSample {
        pos_mm: Axes(command(k, s.pos_mm.0)),
        motion: s.motion,
        feed_move: s.feed_move,
        outputs: Default::default(),
    });
    let report = simulate(
        engine,
        job.cycle_s,
        samples,
        |m| job.prims.get(m as usize).copied().flatten(),
        |row| {
            if row.cycle >= lead_in && measured_mm.len() < job.samples.len() {
                measured_mm.push(row.record.actual_mm.0);
            }
        },
    )
    .map_err(|e| format!("servo backend: {e}"))?;
    Ok(Run {
        measured_mm,
        contour: report.contour,
    })
}

/// The Markov parameters h(1..) of each axis's closed loop, measured on `engine`: at
/// rest at `at_mm`, a one-sample pulse of [`PULSE_MM`] on that axis alone, and its
/// measured response for `n` cycles (the simulator's encoders: quantised and noisy
/// as configured). Terms after the response has settled to its rest value within
/// the measurement floor (two encoder counts plus four noise σ, see
/// [`settled_terms`]) are dropped: they are floor and friction, not response.
pub fn identify(
    engine: &mut CycleEngine<SimBackend>,
    machine: &MachineProfile,
    at_mm: [f64; AXES],
    n: usize,
) -> Result<[Vec<f64>; AXES], String> {
    let mut out: [Vec<f64>; AXES] = Default::default();
    for (axis, h) in out.iter_mut().enumerate() {
        engine.reset(at_mm);
        let mut y = Vec::with_capacity(PULSE_AT + n + 1);
        for k in 0..=PULSE_AT + n {
            let mut cmd = at_mm;
            if k == PULSE_AT {
                cmd[axis] += PULSE_MM;
            }
            let r = engine
                .step(cmd, false)
                .map_err(|e| format!("servo backend: {e}"))?;
            y.push(r.actual_mm[axis] - at_mm[axis]);
        }
        let all = identify_markov(&y, PULSE_AT, PULSE_MM, n);
        let floor_mm =
            2.0 * engine.backend().mm_per_count(axis) + 4.0 * machine.axis_servo(axis).noise_mm;
        let keep = settled_terms(&all, floor_mm / PULSE_MM);
        *h = all[..keep].to_vec();
    }
    Ok(out)
}

const UM: f64 = 1000.0;

/// Failed learning steps in a row that end a Markov learning run. A step fails when
/// the run it commands has a larger ‖e‖₂ than the best run so far (the anchor): the
/// correction goes back to the anchor's and the gain is halved (for the rest of the
/// run). For an LTI loop eq 5 is a gradient step on ‖e‖₂ and a small enough gain
/// always reduces it ([`softnc_learning::markov::MarkovLearner::default_gain`]); five halvings
/// in a row (s/32) that still do not mean the error left is friction and noise the
/// identified loop does not describe, and the run stops. On the short program of
/// `tests/never_worse.rs` mill-friction.ron needed four (s = 0.5 gave ‖e‖₂ × 5.8) (issue 15: with a fixed gain the error fed itself,
/// 93 → 53 → 274 → … → 31,382 µm on tnv40-ilc.ron).
pub const FAILED_STEPS_TO_STOP: usize = 5;

/// The default bound of the correction per axis (mm) when the profile's
/// `learning.max_correction_mm` is absent: the following error of the identified
/// loop `h` (Markov parameters, one per interpolation cycle) at the axis's top speed,
/// `max_vel_mm_per_s` × its mean delay Σ i·|h(i)| / Σ |h(i)| cycles — the lead a
/// correction needs to track the fastest programmable motion. With the field, that
/// value on every axis.
pub fn correction_bound_mm(machine: &MachineProfile, h: &[Vec<f64>; AXES]) -> [f64; AXES] {
    if let Some(m) = machine.learning.max_correction_mm {
        return [m; AXES];
    }
    std::array::from_fn(|a| {
        let (mut w, mut s) = (0.0, 0.0);
        for (i, v) in h[a].iter().enumerate() {
            w += (i + 1) as f64 * v.abs();
            s += v.abs();
        }
        let delay_s = if s > 0.0 { w / s } else { 1.0 } * machine.interpolation_cycle_s;
        machine.axes[a].max_vel_mm_per_s * delay_s
    })
}

/// Repetitions of `job` learning with `mj`: run, learn, run, … up to `iterations`
/// times; `after(stats, mj)` sees every run (the first before any learning) with the
/// state it left, `mj.improvement` set when that run's correction is the best so far
/// and did better (contour-error RMS) than the unlearned run.
///
/// Learning never makes it worse. Each step learns from the anchor, the run with the
/// smallest ‖e‖₂ so far: a step whose run has a larger ‖e‖₂ is undone and the gain
/// halved for the steps after it; after [`FAILED_STEPS_TO_STOP`] such steps in a row the run stops (fewer
/// stats returned). The correction is clamped to `mj.max_correction_mm`. At the end
/// `mj` holds the correction of the best run (contour-error RMS) that improved on the
/// unlearned one, `improvement` recording by how much; when none did, the correction
/// it came in with and `improvement` `None`. The unlearned run is the first one, or
/// with a resumed `mj` that already records an improvement, that record's.
pub fn learn_markov(
    engine: &mut CycleEngine<SimBackend>,
    job: &PreparedJob,
    mj: &mut MarkovJob,
    iterations: usize,
    mut after: impl FnMut(&IterationStats, &MarkovJob) -> Result<(), String>,
) -> Result<Vec<IterationStats>, String> {
    let planned = job.planned_mm();
    let mut out: Vec<IterationStats> = Vec::with_capacity(iterations + 1);
    let mut unlearned_rms_um = mj.improvement.map(|i| i.unlearned_rms_um);
    let start = mj.clone();
    let base_gain = mj.gain;
    let mut best: Option<MarkovJob> = None;
    // the run with the smallest ‖e‖₂: its state, what it measured, its ‖e‖₂
    let mut anchor: Option<(MarkovJob, Vec<[f64; AXES]>, f64)> = None;
    let mut failed = 0;
    let mut scale = 1.0;
    for it in 0..=iterations {
        if let Some((state, measured, _)) = &anchor {
            *mj = state.clone();
            mj.gain = base_gain.map(|g| g * scale);
            mj.learn(&planned, measured);
        }
        let run = run_job(engine, job, |k, p| mj.command(k, p))?;
        let norm_mm = planned
            .iter()
            .zip(&run.measured_mm)
            .map(|(p, y)| (0..AXES).map(|a| (p[a] - y[a]).powi(2)).sum::<f64>())
            .sum::<f64>()
            .sqrt();
        let stats = IterationStats {
            iteration: it,
            rms_um: run.contour.rms() * UM,
            max_abs_um: run.contour.max_abs() * UM,
            norm_um: norm_mm * UM,
            max_um: run.contour.max_abs() * UM,
            min_um: -run.contour.max_abs() * UM,
        };
        let unlearned = *unlearned_rms_um.get_or_insert(stats.rms_um);
        let candidate = Improvement {
            iteration: it,
            unlearned_rms_um: unlearned,
            rms_um: stats.rms_um,
        };
        let best_rms = best
            .as_ref()
            .and_then(|b| b.improvement)
            .map_or(f64::INFINITY, |i| i.rms_um);
        mj.improvement = (candidate.improved() && stats.rms_um < best_rms).then_some(candidate);
        if mj.improvement.is_some() {
            best = Some(mj.clone());
        }
        after(&stats, mj)?;
        out.push(stats);
        match &anchor {
            Some((_, _, anchor_norm)) if norm_mm >= *anchor_norm || norm_mm.is_nan() => {
                failed += 1;
                scale *= 0.5;
                if failed >= FAILED_STEPS_TO_STOP {
                    break;
                }
            }
            _ => {
                failed = 0;
                anchor = Some((mj.clone(), run.measured_mm, norm_mm));
            }
        }
    }
    *mj = match best {
        Some(b) => b,
        None => MarkovJob {
            improvement: None,
            ..start
        },
    };
    Ok(out)
}

/// The one full circle of a program (its single feed move, a whole-turn arc in the XY
/// plane) and its radius (mm).
pub fn find_circle(
    text: &str,
    name: &str,
    machine: &MachineProfile,
) -> Result<(Circle, f64), String> {
    use softnc_gcode::canon::MotionKind;
    let program = softnc_gcode::read_program(text, name, machine).map_err(|e| e.to_string())?;
    let mut found = None;
    for m in &program.motions {
        match m.kind {
            MotionKind::Traverse { .. } | MotionKind::Dwell { .. } => {}
            // a zero-length feed move (`G1 F1800` setting the feed on its own line,
            // as LinuxCNC also emits) moves nothing: not a motion of the circle
            MotionKind::Feed { end, .. } if (end - m.start).norm() < 1e-9 => {}
            MotionKind::Arc {
                end,
                center,
                turns,
                feed_mm_per_min,
                plane,
            } if plane == softnc_core::Plane::XY
                && turns.abs() == 1
                && (end - m.start).norm() < 1e-9
                && found.is_none() =>
            {
                let s = m.start + m.offset_mm;
                let c = center + m.offset_mm;
                let circle = Circle {
                    center_mm: [c[0], c[1]],
                    z_mm: s[2],
                    start_rad: (s[1] - c[1]).atan2(s[0] - c[0]),
                    ccw: turns > 0,
                    feed_mm_per_min,
                };
                found = Some((circle, (s[0] - c[0]).hypot(s[1] - c[1])));
            }
            _ => {
                return Err(format!(
                    "{name}:{}: the radius law learns one full circle (G2/G3 back to its start in G17); this motion is not it",
                    m.line
                ))
            }
        }
    }
    found.ok_or_else(|| format!("{name}: no full circle (G2/G3 back to its start) to learn"))
}

/// One radius-ILC run: the per-degree program of `ilc` on `engine`; the measured
/// radius per degree from the feed-move samples and the hold tail.
pub fn run_circle(
    engine: &mut CycleEngine<SimBackend>,
    machine: &MachineProfile,
    circle: &Circle,
    ilc: &RadiusIlc,
    title: &str,
) -> Result<Vec<f64>, String> {
    let text = ilc.program(circle, title, HOLD_S);
    let job = PreparedJob::new(&text, "radius-ilc.ngc", machine)?;
    let first_feed = job
        .samples
        .iter()
        .position(|s| s.feed_move)
        .ok_or("the circle program has no feed move")?;
    let run = run_job(engine, &job, |_, p| p)?;
    let xy: Vec<[f64; 2]> = run.measured_mm[first_feed..]
        .iter()
        .map(|p| [p[0], p[1]])
        .collect();
    Ok(circle.radius_per_degree(&xy))
}

/// Figures of a radius error per degree (mm → µm).
pub fn radius_stats(iteration: usize, err_mm: &[f64]) -> IterationStats {
    let mut st = ErrorStats::default();
    let (mut max, mut min) = (f64::NEG_INFINITY, f64::INFINITY);
    for &e in err_mm {
        st.add(e);
        max = max.max(e);
        min = min.min(e);
    }
    IterationStats {
        iteration,
        rms_um: st.rms() * UM,
        max_abs_um: st.max_abs() * UM,
        norm_um: err_mm.iter().map(|e| e * e).sum::<f64>().sqrt() * UM,
        max_um: max * UM,
        min_um: min * UM,
    }
}

/// Repetitions of a circle under the radius ILC: run, measure per degree, eq 8, …
/// `after(stats, ilc, err)` sees every run (the first before any learning) with the
/// state it left and the radius error per degree (mm). The run stops early (fewer
/// stats returned) after a run whose radius-error RMS is above the first run's.
pub fn learn_radius(
    engine: &mut CycleEngine<SimBackend>,
    machine: &MachineProfile,
    circle: &Circle,
    ilc: &mut RadiusIlc,
    iterations: usize,
    mut after: impl FnMut(&IterationStats, &RadiusIlc, &[f64]) -> Result<(), String>,
) -> Result<Vec<IterationStats>, String> {
    let mut out = Vec::with_capacity(iterations + 1);
    let mut measured: Vec<f64> = Vec::new();
    for it in 0..=iterations {
        if it > 0 {
            ilc.update(&measured);
        }
        measured = run_circle(
            engine,
            machine,
            circle,
            ilc,
            &format!("softnc learn: radius ILC of paper 004, iteration {it}"),
        )?;
        let err: Vec<f64> = measured.iter().map(|y| y - ilc.desired_mm).collect();
        let stats = radius_stats(it, &err);
        after(&stats, ilc, &err)?;
        // learning made the circle worse than not learning at all: eq 8 is
        // diverging (α too large for this loop), stop
        let worse = out
            .first()
            .is_some_and(|f: &IterationStats| stats.rms_um > f.rms_um || stats.rms_um.is_nan());
        out.push(stats);
        if worse {
            break;
        }
    }
    debug_assert_eq!(measured.len(), POINTS);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn workspace_file(rel: &str) -> std::path::PathBuf {
        std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("../..")
            .join(rel)
    }
    use softnc_machine::servo::CommandFilterConfig;
    use softnc_sim::{simulated_engine, SimOptions};

    /// With a command filter on, the measured positions stay one per job sample and
    /// aligned with them: on a constant-velocity line the zero-lag filter leaves the
    /// command unchanged, so mid-line the run measures what it measures unfiltered.
    #[test]
    fn measured_samples_stay_aligned_with_a_command_filter() {
        let plain = MachineProfile::load(&workspace_file("config/machines/default.ron")).unwrap();
        let mut filtered = plain.clone();
        for a in &mut filtered.servo.axes {
            a.command_filter = Some(CommandFilterConfig {
                frequency_hz: 15.0,
                order: 40,
            });
        }
        let text = "G21 G90 G94\nG0 X0 Y0 Z0\nG1 X60 F3000\nM2\n";
        let run = |m: &MachineProfile| {
            let job = PreparedJob::new(text, "line.ngc", m).unwrap();
            let opts = SimOptions {
                noise: false,
                variation: false,
                ..SimOptions::default()
            };
            let mut engine = simulated_engine(m, 1, opts);
            assert_eq!(
                engine.filter_window(),
                if std::ptr::eq(m, &plain) { 0 } else { 40 }
            );
            let r = run_job(&mut engine, &job, |_, p| p).unwrap();
            assert_eq!(r.measured_mm.len(), job.samples.len());
            r.measured_mm
        };
        let (a, b) = (run(&plain), run(&filtered));
        let mid = a.len() / 2;
        // 40 samples at 50 mm/s would be 2 mm apart
        assert!(
            (a[mid][0] - b[mid][0]).abs() < 0.01,
            "{} vs {}",
            a[mid][0],
            b[mid][0]
        );
    }
}
