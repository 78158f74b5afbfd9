//! Paper 003, Sec. 3: adaptive robust cutting-force control on the simulated MCH-10
//! (`config/machines/mch10-force.ron`), cases I, II (two pole sets) and III.
//!
//! The loop, offline, one interpolation cycle at a time: the planner's interpolator
//! (a straight cut along the feed axis at the programmed feed, with the live feed
//! override) → the axis servo (the profile's first-order lag, eq 1) → the milling
//! process at the tool's position in the cut's depth/material profile (eq 2–4) → the
//! PMSM's phase currents for the force plus friction and inertia (eq 24–30) → the
//! force estimate (Park transform and calibration, eq 25–32), its peak per spindle
//! revolution → once per revolution the adaptive robust controller (RLS, pole
//! placement, Davison servo, clamp and rate limit) → the interpolator's live feed
//! override, the same call an operator's override makes.
//!
//! Before the cases, the calibration routine cuts the profile's calibration slot at
//! a fixed feed and several depths and fits I_q = a·F + b (eq 31–32) to the peak I_q
//! and the true peak force of each settled revolution.
//!
//! **Figures per segment** (revolutions wholly inside the segment): settled values
//! are means over its last `settled_revolutions`; the force is the simulation's true
//! peak force per revolution; the feed is the axis's actual mean speed over the
//! revolution. Overshoot: after the force first crosses the reference within the
//! segment, the largest excursion beyond it on the other side (% of the reference);
//! the jump when a deeper or harder stretch begins is the process's, not the
//! controller's, and is reported apart as the segment's highest peak.

use crate::error::{failed, Context, ExperimentError, Result};
use crate::plot::{self, write_svg, Panel, Series};
use crate::{Experiment, ExperimentId, RunOptions};
use plotters::style::colors::{BLACK, BLUE, CYAN, GREEN, MAGENTA, RED};
use softnc_adaptive::{
    Arma2, ForceCalibration, ForceEstimator, ForceLoop, RevolutionPeak, ServoGains,
};
use softnc_machine::force::{ForceCase, ForceEvent, ForceProfile};
use softnc_machine::MachineProfile;
use softnc_sim::milling::{CutProfile, MillingProcess};
use softnc_sim::pmsm::PmsmFeedMotor;
use softnc_sim::{simulated_engine, Rng, SimOptions};
use std::path::{Path, PathBuf};

/// Random stream of the current sensors' noise: the simulated stock's.
use softnc_sim::workpiece::STREAM_CURRENT_NOISE;
/// Seconds per minute.
const SECONDS_PER_MINUTE: f64 = 60.0;

/// The profile's force section, or an error naming the file.
pub fn force_section<'a>(machine: &'a MachineProfile, file: &str) -> Result<&'a ForceProfile> {
    machine.force.as_ref().ok_or_else(|| {
        ExperimentError::refused(format!(
            "{file}: the profile has no `force` section (paper 003)"
        ))
    })
}

/// One spindle revolution of a run.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct RevRow {
    /// Time at the end of the revolution (s).
    pub t_s: f64,
    /// Segment the whole revolution was in (`None`: straddles a boundary or air).
    pub segment: Option<usize>,
    /// True peak feed force of the revolution (N).
    pub force_n: f64,
    /// Estimated peak force (N) (peak I_q through the calibration).
    pub est_force_n: f64,
    /// Peak I_q of the revolution (A).
    pub peak_iq_a: f64,
    /// Actual mean feed over the revolution (mm/min).
    pub feed_mm_min: f64,
    /// Feed command applied at the end of the revolution (mm/min).
    pub feed_cmd_mm_min: f64,
    /// Override applied (fraction).
    pub override_frac: f64,
    /// Θ = [−φ₁, −φ₂, θ₁, θ₂] in use.
    pub theta: [f64; 4],
    /// Gains in use.
    pub gains: [f64; 6],
    /// True while the planner was still moving at the end of the revolution.
    pub moving: bool,
}

/// The whole run.
#[derive(Debug, Clone, PartialEq)]
pub struct Run {
    /// Revolutions.
    pub rows: Vec<RevRow>,
    /// Control sample = revolution period (s).
    pub t_rev_s: f64,
    /// Covariance resets of the estimator.
    pub covariance_resets: u64,
    /// Estimates refused (last good gains kept).
    pub rejected: u64,
    /// Largest change of override between consecutive control samples.
    pub max_override_step: f64,
    /// Lowest and highest override commanded.
    pub override_range: (f64, f64),
    /// Largest change of the interpolator's path speed between cycles (mm/s).
    pub max_speed_step_mm_s: f64,
    /// Largest distance of a command sample from the programmed line (mm).
    pub max_path_deviation_mm: f64,
}

/// What a cut is made with.
pub struct CutSpec<'a> {
    /// Tool name.
    pub tool: &'a str,
    /// Spindle (rpm).
    pub spindle_rpm: f64,
    /// Depth/material along the cut.
    pub cut: CutProfile,
    /// Programmed feed (mm/min).
    pub programmed_feed_mm_per_min: f64,
    /// Process disturbances.
    pub events: &'a [ForceEvent],
}

/// The controller of a case (None: fixed 100 % override, e.g. calibration).
pub struct ControlSpec {
    /// Calibration of the force estimate.
    pub calibration: ForceCalibration,
    /// Reference peak force (N).
    pub force_ref_n: f64,
    /// Closed-loop poles.
    pub poles: [f64; 4],
}

/// Run one straight cut along the feed axis through the whole loop.
#[allow(clippy::too_many_lines)]
pub fn run_cut(
    machine: &MachineProfile,
    force: &ForceProfile,
    spec: &CutSpec,
    control: Option<&ControlSpec>,
    noise: bool,
) -> Result<Run> {
    let axis = force.feed_axis;
    let tool = force
        .tool(spec.tool)
        .with_context(|| format!("no tool `{}`", spec.tool))?;
    let length = spec.cut.length_mm();
    let letter = softnc_core::Axis::name_of(axis);
    let text = format!(
        "G90 G21 G17 G94\nG1 {letter}{length:.4} F{:.4}\nM2\n",
        spec.programmed_feed_mm_per_min
    );
    let program = softnc_gcode::read_program(&text, "paper003-cut.ngc", machine).map_err(failed)?;
    let plan = softnc_planner::plan(&program, machine, &softnc_planner::PlanOptions::default())
        .map_err(failed)?;
    let h = plan.cycle_s();
    let options = SimOptions {
        quantisation: true,
        noise,
        cutting: false,
        variation: false,
    };
    let mut engine = simulated_engine(machine, machine.servo.seed, options);
    engine.reset([0.0; 3]);
    let mut milling = MillingProcess::new(tool, spec.spindle_rpm);
    let mut motor = PmsmFeedMotor::new(
        &force.motor,
        Rng::stream(machine.servo.seed, STREAM_CURRENT_NOISE),
        noise,
    );
    let t_rev = milling.revolution_s();
    let cycles_per_rev = ForceLoop::cycles_per_revolution(t_rev, h);
    let f_prog = spec.programmed_feed_mm_per_min;
    let loop_cfg = softnc_servo::adaptive_feed::loop_config(
        h,
        &force.controller,
        spec.spindle_rpm,
        f_prog,
        control.map(|c| (c.poles, c.force_ref_n, c.calibration)),
    );
    debug_assert_eq!(loop_cfg.cycles_per_revolution, cycles_per_rev);
    let mut force_loop = ForceLoop::new(loop_cfg).context("prior model")?;
    let mut true_peak = RevolutionPeak::default();
    let mut interp = plan.interpolator();
    let mut rows = Vec::new();
    let mut cycle: u64 = 0;
    let mut x_prev = 0.0;
    let mut x_rev_start = 0.0;
    let mut seg_rev_start = spec.cut.index_at(0.0);
    let mut straddled = false;
    let mut last_cmd = [0.0; 3];
    let mut last_speed = 0.0;
    let mut max_speed_step: f64 = 0.0;
    let mut max_dev: f64 = 0.0;
    let mut override_frac = 1.0;
    let mut max_override_step: f64 = 0.0;
    let mut override_lo = f64::INFINITY;
    let mut override_hi = f64::NEG_INFINITY;
    let mut theta = [0.0; 4];
    let mut gains = [0.0; 6];
    while let Some(s) = interp.next() {
        let cmd = s.pos_mm.0;
        // the path stays the programmed line whatever the override does
        let dev = (0..3)
            .filter(|&i| i != axis)
            .map(|i| cmd[i].abs())
            .fold(0.0, f64::max);
        max_dev = max_dev.max(dev);
        if cycle > 0 {
            let speed = (cmd[axis] - last_cmd[axis]) / h;
            max_speed_step = max_speed_step.max((speed - last_speed).abs());
            last_speed = speed;
        }
        last_cmd = cmd;
        engine.step(cmd, s.feed_move).map_err(failed)?;
        let x = engine.backend().true_pos_mm()[axis];
        let v = (x - x_prev) / h;
        x_prev = x;
        let t = (cycle + 1) as f64 * h;
        let seg = spec.cut.index_at(x);
        match spec.cut.at(x) {
            Some((k_c, d)) => milling.set_cut(k_c, d),
            None => milling.set_cut(0.0, 0.0),
        }
        if seg != seg_rev_start {
            straddled = true;
        }
        let scale = spec
            .events
            .iter()
            .filter(|e| t >= e.at_s && t < e.at_s + e.duration_s)
            .fold(1.0, |a, e| a * e.force_scale);
        let f_true = milling.step(v, h) * scale;
        let currents = motor.step(f_true, x, h);
        let measured_x = engine.measured_mm()[axis];
        true_peak.push(f_true);
        cycle += 1;
        if let Some(rev) = force_loop.cycle(
            currents.meas_u,
            currents.meas_v,
            motor.electrical_rad(measured_x),
        ) {
            let f_peak = true_peak.take().unwrap_or(0.0);
            let feed = (x - x_rev_start) / t_rev * SECONDS_PER_MINUTE;
            if let Some(st) = rev.control {
                max_override_step =
                    max_override_step.max((rev.override_frac - override_frac).abs());
                override_frac = rev.override_frac;
                override_lo = override_lo.min(override_frac);
                override_hi = override_hi.max(override_frac);
                interp.set_feed_override(override_frac);
                theta = st.theta.into();
                let g: ServoGains = st.gains;
                gains = [g.k, g.r0, g.r1, g.r2, g.r3, g.r4];
            }
            rows.push(RevRow {
                t_s: t,
                segment: if straddled { None } else { seg },
                force_n: f_peak,
                est_force_n: rev.est_force_n,
                peak_iq_a: rev.peak_iq_a,
                feed_mm_min: feed,
                feed_cmd_mm_min: rev.feed_cmd,
                override_frac,
                theta,
                gains,
                moving: !interp.is_finished(),
            });
            x_rev_start = x;
            seg_rev_start = seg;
            straddled = false;
        }
    }
    let (covariance_resets, rejected) = (force_loop.covariance_resets(), force_loop.rejected());
    Ok(Run {
        rows,
        t_rev_s: t_rev,
        covariance_resets,
        rejected,
        max_override_step,
        override_range: (override_lo, override_hi),
        max_speed_step_mm_s: max_speed_step,
        max_path_deviation_mm: max_dev,
    })
}

/// The calibration fit and its data.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Calibration {
    /// Fitted slope a (A/N).
    pub a_per_n: f64,
    /// Fitted offset b (A).
    pub b_a: f64,
    /// (true peak force N, peak I_q A) per settled revolution.
    pub pairs: Vec<(f64, f64)>,
    /// Largest |estimate − true| / true over the calibration pairs.
    pub max_rel_error: f64,
}

impl Calibration {
    /// As the estimator's calibration.
    pub fn line(&self) -> ForceCalibration {
        ForceCalibration {
            a_per_n: self.a_per_n,
            b_a: self.b_a,
        }
    }
}

/// The calibration routine (eq 31–32): cut the calibration slot at a fixed feed over
/// the profile's depths, fit peak I_q against true peak force.
pub fn calibrate(
    machine: &MachineProfile,
    force: &ForceProfile,
    noise: bool,
) -> Result<Calibration> {
    let c = &force.calibration;
    let k_c = force
        .material(&c.material)
        .with_context(|| format!("no material `{}`", c.material))?
        .k_c_n_per_mm2;
    let t_rev = SECONDS_PER_MINUTE / c.spindle_rpm;
    let len = c.feed_mm_per_min / SECONDS_PER_MINUTE * t_rev * c.revolutions_per_depth as f64;
    let mut end = 0.0;
    let stretches = c
        .depths_mm
        .iter()
        .map(|&d| {
            end += len;
            (end, k_c, d)
        })
        .collect();
    let spec = CutSpec {
        tool: &c.tool,
        spindle_rpm: c.spindle_rpm,
        cut: CutProfile::new(stretches),
        programmed_feed_mm_per_min: c.feed_mm_per_min,
        events: &[],
    };
    let run = run_cut(machine, force, &spec, None, noise)?;
    let mut pairs = Vec::new();
    for seg in 0..c.depths_mm.len() {
        let in_seg: Vec<&RevRow> = run
            .rows
            .iter()
            .filter(|r| r.segment == Some(seg) && r.moving)
            .collect();
        pairs.extend(
            in_seg
                .iter()
                .skip(c.skip_revolutions as usize)
                .map(|r| (r.force_n, r.peak_iq_a)),
        );
    }
    let line =
        ForceCalibration::fit(&pairs).context("calibration: fewer than two distinct forces")?;
    let max_rel_error = pairs
        .iter()
        .map(|(f, iq)| ((line.force_n(*iq) - f) / f).abs())
        .fold(0.0, f64::max);
    Ok(Calibration {
        a_per_n: line.a_per_n,
        b_a: line.b_a,
        pairs,
        max_rel_error,
    })
}

/// Figures of one segment.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct SegmentResult {
    /// Axial depth (mm).
    pub depth_mm: f64,
    /// Material.
    pub material: String,
    /// Settled true peak force (N).
    pub force_n: f64,
    /// Reference (N).
    pub force_ref_n: f64,
    /// (force − reference)/reference (%).
    pub error_pct: f64,
    /// Settled estimated peak force (N).
    pub est_force_n: f64,
    /// Mean |estimate − true|/true over the settled revolutions (%).
    pub est_error_pct: f64,
    /// Settled actual feed (mm/min).
    pub feed_mm_min: f64,
    /// The paper's feed (mm/min), when printed.
    pub paper_feed_mm_min: Option<f64>,
    /// Settled feed vs the paper's (%).
    pub feed_vs_paper_pct: Option<f64>,
    /// Overshoot after the first crossing of the reference (% of the reference).
    pub overshoot_pct: f64,
    /// Highest peak force in the segment (N).
    pub max_force_n: f64,
    /// Largest |force − reference| over the settled revolutions (N).
    pub settled_max_abs_error_n: f64,
    /// Transmission zero −b₂/b₁ of the true sampled plant (eq 5–7) on this segment.
    pub plant_zero: f64,
}

/// Figures of one case.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct CaseResult {
    /// Case name.
    pub case: String,
    /// Closed-loop poles.
    pub poles: [f64; 4],
    /// Reference (N).
    pub force_ref_n: f64,
    /// Programmed feed (mm/min).
    pub programmed_feed_mm_min: f64,
    /// Per segment.
    pub segments: Vec<SegmentResult>,
    /// Covariance resets of the estimator.
    pub covariance_resets: u64,
    /// Estimates refused.
    pub rejected_estimates: u64,
    /// Largest override step between control samples (fraction).
    pub max_override_step: f64,
    /// Lowest / highest override commanded.
    pub override_min: f64,
    /// Highest override commanded.
    pub override_max: f64,
}

/// Overshoot beyond `r` after the first crossing, as a fraction of `r`.
pub fn overshoot(forces: &[f64], r: f64) -> f64 {
    let Some(&first) = forces.first() else {
        return 0.0;
    };
    let above = first > r;
    let Some(k) = forces.iter().position(|&f| (f > r) != above) else {
        return 0.0;
    };
    forces[k..]
        .iter()
        .map(|&f| if above { r - f } else { f - r })
        .fold(0.0, f64::max)
        / r
}

/// Run a case and reduce it to its figures.
pub fn run_case(
    machine: &MachineProfile,
    force: &ForceProfile,
    case: &ForceCase,
    cal: ForceCalibration,
    noise: bool,
) -> Result<(CaseResult, Run)> {
    let poles = case.poles.unwrap_or(force.controller.poles);
    let spec = CutSpec {
        tool: &case.tool,
        spindle_rpm: case.spindle_rpm,
        cut: CutProfile::from_case(force, case),
        programmed_feed_mm_per_min: case.programmed_feed_mm_per_min,
        events: &case.events,
    };
    let control = ControlSpec {
        calibration: cal,
        force_ref_n: case.force_ref_n,
        poles,
    };
    let run = run_cut(machine, force, &spec, Some(&control), noise)?;
    let tool = force.tool(&case.tool).context("no tool")?;
    let r = case.force_ref_n;
    let mut segments = Vec::new();
    for (j, s) in case.segments.iter().enumerate() {
        let rows: Vec<&RevRow> = run
            .rows
            .iter()
            .filter(|row| row.segment == Some(j) && row.moving)
            .collect();
        let n = case.settled_revolutions as usize;
        if rows.len() < n + 2 {
            return Err(ExperimentError::refused(format!(
                "case {} segment {j}: only {} whole revolutions; make it longer",
                case.name,
                rows.len()
            )));
        }
        let settled = &rows[rows.len() - n..];
        let mean =
            |f: &dyn Fn(&RevRow) -> f64| settled.iter().map(|r| f(r)).sum::<f64>() / n as f64;
        let force_n = mean(&|r| r.force_n);
        let est_force_n = mean(&|r| r.est_force_n);
        let est_err = mean(&|r| ((r.est_force_n - r.force_n) / r.force_n).abs());
        let feed = mean(&|r| r.feed_mm_min);
        let forces: Vec<f64> = rows.iter().map(|r| r.force_n).collect();
        let k_c = force
            .material(&s.material)
            .context("no material")?
            .k_c_n_per_mm2;
        let mut m = MillingProcess::new(tool, case.spindle_rpm);
        m.set_cut(k_c, s.depth_mm);
        let tau_s = match machine.axis_servo(force.feed_axis).plant {
            softnc_machine::servo::PlantModel::FirstOrderLag { tau_s, .. } => tau_s,
            _ => f64::NAN,
        };
        let z: Arma2 = softnc_adaptive::zoh_second_order(1.0, tau_s, m.tau_c_s(), run.t_rev_s);
        segments.push(SegmentResult {
            depth_mm: s.depth_mm,
            material: s.material.clone(),
            force_n,
            force_ref_n: r,
            error_pct: 100.0 * (force_n - r) / r,
            est_force_n,
            est_error_pct: 100.0 * est_err,
            feed_mm_min: feed,
            paper_feed_mm_min: s.paper_feed_mm_per_min,
            feed_vs_paper_pct: s.paper_feed_mm_per_min.map(|p| 100.0 * (feed - p) / p),
            overshoot_pct: 100.0 * overshoot(&forces, r),
            max_force_n: forces.iter().copied().fold(0.0, f64::max),
            settled_max_abs_error_n: settled
                .iter()
                .map(|row| (row.force_n - r).abs())
                .fold(0.0, f64::max),
            plant_zero: -z.theta2 / z.theta1,
        });
    }
    Ok((
        CaseResult {
            case: case.name.clone(),
            poles,
            force_ref_n: r,
            programmed_feed_mm_min: case.programmed_feed_mm_per_min,
            segments,
            covariance_resets: run.covariance_resets,
            rejected_estimates: run.rejected,
            max_override_step: run.max_override_step,
            override_min: run.override_range.0,
            override_max: run.override_range.1,
        },
        run,
    ))
}

/// Frequency response of the force estimate (instantaneous, before the peak): a
/// sinusoidal force of `freq_hz` on top of a steady one at a constant feed, no sensor
/// noise; returns |estimate amplitude| / |true amplitude| at steady state.
pub fn estimate_gain(
    force: &ForceProfile,
    cal: ForceCalibration,
    amp_n: f64,
    freq_hz: f64,
    h: f64,
) -> f64 {
    let mut motor = PmsmFeedMotor::new(&force.motor, Rng::new(0), false);
    let mut est = ForceEstimator::new(cal);
    let feed_mm_s = force.calibration.feed_mm_per_min / SECONDS_PER_MINUTE;
    let mean_n = amp_n;
    // settle for 20 periods of the motor's lag and of the signal, measure 10 periods
    let settle_s = 20.0 / force.motor.torque_bandwidth_hz + 20.0 / freq_hz;
    let measure_s = 10.0 / freq_hz;
    let n_settle = (settle_s / h).ceil() as u64;
    let n_meas = (measure_s / h).ceil() as u64;
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for k in 0..n_settle + n_meas {
        let t = k as f64 * h;
        let f = mean_n + amp_n * (std::f64::consts::TAU * freq_hz * t).sin();
        let x = feed_mm_s * t;
        let c = motor.step(f, x, h);
        let e = est.push(c.meas_u, c.meas_v, motor.electrical_rad(x));
        if k >= n_settle {
            lo = lo.min(e);
            hi = hi.max(e);
        }
    }
    (hi - lo) / (2.0 * amp_n)
}

/// Everything the command prints.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Report {
    /// The calibration.
    pub calibration: CalibrationSummary,
    /// Indirect measurement figures.
    pub estimator: EstimatorSummary,
    /// The cases.
    pub cases: Vec<CaseResult>,
}

/// Calibration summary (no pairs).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct CalibrationSummary {
    /// Fitted a (A/N).
    pub a_per_n: f64,
    /// Fitted b (A).
    pub b_a: f64,
    /// The paper's eq 32 a.
    pub paper_a_per_n: f64,
    /// The paper's eq 32 b.
    pub paper_b_a: f64,
    /// Revolutions fitted.
    pub revolutions: usize,
    /// Largest relative error of the fit over its revolutions (%).
    pub max_error_pct: f64,
}

/// The indirect measurement's figures.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct EstimatorSummary {
    /// (frequency Hz, gain) of the instantaneous estimate.
    pub response: Vec<(f64, f64)>,
    /// −3 dB frequency (Hz), interpolated.
    pub bandwidth_hz: f64,
    /// Tooth frequency of case I (Hz).
    pub tooth_hz: f64,
}

/// The paper's calibration line (eq 32), for the record beside ours.
pub const PAPER_EQ32: (f64, f64) = (0.00362, 4.127);

/// Frequencies of the estimate's frequency response (Hz).
const RESPONSE_HZ: [f64; 9] = [5.0, 10.0, 20.0, 30.0, 40.0, 60.0, 80.0, 120.0, 200.0];

/// Calibrate, measure the estimator, run every case.
pub fn report(machine: &MachineProfile, file: &str) -> Result<(Report, Vec<Run>)> {
    let force = force_section(machine, file)?;
    let cal = calibrate(machine, force, true)?;
    let h = machine.interpolation_cycle_s;
    let response: Vec<(f64, f64)> = RESPONSE_HZ
        .iter()
        .map(|&f| {
            let amp = force.cases[0].force_ref_n;
            (f, estimate_gain(force, cal.line(), amp, f, h.min(1e-4)))
        })
        .collect();
    let half_power = std::f64::consts::FRAC_1_SQRT_2;
    let bandwidth_hz = response
        .windows(2)
        .find(|w| w[0].1 >= half_power && w[1].1 < half_power)
        .map(|w| w[0].0 + (w[0].1 - half_power) / (w[0].1 - w[1].1) * (w[1].0 - w[0].0))
        .unwrap_or(f64::NAN);
    let first = &force.cases[0];
    let tool = force.tool(&first.tool).context("no tool")?;
    let tooth_hz = MillingProcess::new(tool, first.spindle_rpm).tooth_hz();
    let mut cases = Vec::new();
    let mut runs = Vec::new();
    for case in &force.cases {
        let (res, run) = run_case(machine, force, case, cal.line(), true)
            .with_context(|| format!("case {}", case.name))?;
        cases.push(res);
        runs.push(run);
    }
    Ok((
        Report {
            calibration: CalibrationSummary {
                a_per_n: cal.a_per_n,
                b_a: cal.b_a,
                paper_a_per_n: PAPER_EQ32.0,
                paper_b_a: PAPER_EQ32.1,
                revolutions: cal.pairs.len(),
                max_error_pct: 100.0 * cal.max_rel_error,
            },
            estimator: EstimatorSummary {
                response,
                bandwidth_hz,
                tooth_hz,
            },
            cases,
        },
        runs,
    ))
}

/// The text table.
pub fn to_text(r: &Report) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let c = &r.calibration;
    let _ = writeln!(
        s,
        "calibration (eq 31-32): I_q = {:.5} F + {:.3}  (paper: {} F + {}), {} revolutions, max fit error {:.1} %",
        c.a_per_n, c.b_a, c.paper_a_per_n, c.paper_b_a, c.revolutions, c.max_error_pct
    );
    let e = &r.estimator;
    let _ = writeln!(
        s,
        "force estimate from currents: -3 dB at {:.1} Hz (paper: about 60 Hz); gain at the {:.0} Hz tooth frequency {:.3}",
        e.bandwidth_hz,
        e.tooth_hz,
        e.response
            .iter()
            .find(|p| (p.0 - e.tooth_hz).abs() < 1e-9)
            .map(|p| p.1)
            .unwrap_or(f64::NAN)
    );
    for case in &r.cases {
        let _ = writeln!(
            s,
            "\ncase {}: reference {} N, programmed feed {} mm/min, poles {:?}; covariance resets {}, estimates refused {}, override {:.0}..{:.0} %, largest step {:.0} %/rev",
            case.case,
            case.force_ref_n,
            case.programmed_feed_mm_min,
            case.poles,
            case.covariance_resets,
            case.rejected_estimates,
            100.0 * case.override_min,
            100.0 * case.override_max,
            100.0 * case.max_override_step
        );
        let _ = writeln!(
            s,
            "  depth  material     force N  error %  est. N  est.err %  feed mm/min  paper  vs paper %  overshoot %  max N  settled |e| N  zero"
        );
        for g in &case.segments {
            let _ = writeln!(
                s,
                "  {:>5.1}  {:<11} {:>8.1}  {:>7.2}  {:>6.1}  {:>9.2}  {:>11.1}  {:>5}  {:>10}  {:>11.1}  {:>5.0}  {:>13.1}  {:>5.2}",
                g.depth_mm,
                g.material,
                g.force_n,
                g.error_pct,
                g.est_force_n,
                g.est_error_pct,
                g.feed_mm_min,
                g.paper_feed_mm_min
                    .map(|p| format!("{p:.0}"))
                    .unwrap_or_else(|| "-".into()),
                g.feed_vs_paper_pct
                    .map(|p| format!("{p:+.1}"))
                    .unwrap_or_else(|| "-".into()),
                g.overshoot_pct,
                g.max_force_n,
                g.settled_max_abs_error_n,
                g.plant_zero
            );
        }
    }
    s
}

/// The JSON document: `{"cases":[{"case":"I","segments":[{…}]}], …}`.
pub fn to_json(r: &Report) -> serde_json::Value {
    serde_json::to_value(r).unwrap_or(serde_json::Value::Null)
}

/// Plots of one case: force, feed, estimated parameters, gains over time (SVG).
pub fn plot_case(case: &CaseResult, run: &Run, out: &Path) -> Result<()> {
    let t_max = run.rows.last().map(|r| r.t_s).unwrap_or(1.0);
    let over_time = |f: &dyn Fn(&RevRow) -> f64| -> Vec<(f64, f64)> {
        run.rows.iter().map(|r| (r.t_s, f(r))).collect()
    };
    let panel = |title: String, ylab: &str, series: Vec<Series>| {
        let y = plot::y_range(&series, 0.05, 1e-6, 0.0..1.0);
        Panel {
            title_px: 16,
            ..Panel::new(title, 250, 0.0..t_max, y)
                .axes("time (s)", ylab)
                .lines(series)
        }
    };
    let panels = [
        panel(
            format!(
                "case {}: peak feed force per revolution (reference {} N)",
                case.case, case.force_ref_n
            ),
            "N",
            vec![
                Series::new("true", over_time(&|r| r.force_n), RED),
                Series::new(
                    "estimated from currents",
                    over_time(&|r| r.est_force_n),
                    BLUE,
                ),
                Series::new(
                    "reference",
                    vec![(0.0, case.force_ref_n), (t_max, case.force_ref_n)],
                    BLACK,
                ),
            ],
        ),
        panel(
            "feed (mm/min)".into(),
            "mm/min",
            vec![
                Series::new("actual", over_time(&|r| r.feed_mm_min), RED),
                Series::new(
                    "commanded (override x programmed)",
                    over_time(&|r| r.feed_cmd_mm_min),
                    BLUE,
                ),
            ],
        ),
        panel(
            "estimated parameters Θ = [−φ1, −φ2, θ1, θ2]".into(),
            "",
            (0..4)
                .map(|i| {
                    Series::new(
                        ["-phi1", "-phi2", "theta1", "theta2"][i],
                        over_time(&|r| r.theta[i]),
                        [RED, BLUE, GREEN, MAGENTA][i],
                    )
                })
                .collect(),
        ),
        panel(
            "gains K = [k, r0, r1, r2, r3, r4] (r1 = 0, r4 = 1 fixed; k and r2 scaled by 0.1)"
                .into(),
            "",
            (0..6)
                .filter(|&i| i != 2 && i != 5)
                .map(|i| {
                    let scale = if i == 0 || i == 3 { 0.1 } else { 1.0 };
                    Series::new(
                        ["k/10", "r0", "r1", "r2/10", "r3", "r4"][i],
                        over_time(&|r| scale * r.gains[i]),
                        [RED, BLUE, CYAN, GREEN, MAGENTA, BLACK][i],
                    )
                })
                .collect(),
        ),
    ];
    write_svg(out, 900, &panels)
}

/// One case's figures on one seed (robustness summary).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct SeedCase {
    /// Seed of the simulated machine (sensor noise, encoder).
    pub seed: u64,
    /// Case name.
    pub case: String,
    /// Largest |settled force error| over the segments (%).
    pub max_abs_error_pct: f64,
    /// Largest estimate error over the segments (%).
    pub max_est_error_pct: f64,
    /// Settled feeds per segment (mm/min).
    pub feeds_mm_min: Vec<f64>,
    /// Largest overshoot over the segments (%).
    pub worst_overshoot_pct: f64,
    /// Sum of the segments' overshoots (%).
    pub total_overshoot_pct: f64,
}

/// Every case on seeds 1..=n (calibrated anew on each seed).
pub fn seed_summaries(machine: &MachineProfile, file: &str, n: u64) -> Result<Vec<SeedCase>> {
    let mut out = Vec::new();
    for seed in 1..=n {
        let mut m = machine.clone();
        m.servo.seed = seed;
        let force = force_section(&m, file)?;
        let cal = calibrate(&m, force, true)?;
        for case in &force.cases {
            let (r, _) = run_case(&m, force, case, cal.line(), true)?;
            let fold =
                |f: &dyn Fn(&SegmentResult) -> f64| r.segments.iter().map(f).fold(0.0, f64::max);
            out.push(SeedCase {
                seed,
                case: r.case.clone(),
                max_abs_error_pct: fold(&|s| s.error_pct.abs()),
                max_est_error_pct: fold(&|s| s.est_error_pct),
                feeds_mm_min: r.segments.iter().map(|s| s.feed_mm_min).collect(),
                worst_overshoot_pct: fold(&|s| s.overshoot_pct),
                total_overshoot_pct: r.segments.iter().map(|s| s.overshoot_pct).sum(),
            });
        }
    }
    Ok(out)
}

/// The robustness summary as text.
pub fn seeds_text(rows: &[SeedCase]) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    if rows.is_empty() {
        return s;
    }
    let _ = writeln!(
        s,
        "
every case on seeds 1..={} (sensor noise and encoder; calibrated per seed):",
        rows.iter().map(|r| r.seed).max().unwrap_or(0)
    );
    let _ = writeln!(
        s,
        "  seed  case     max |error| %  max est.err %  worst overshoot %  sum overshoot %  feeds mm/min"
    );
    for r in rows {
        let feeds: Vec<String> = r.feeds_mm_min.iter().map(|f| format!("{f:.1}")).collect();
        let _ = writeln!(
            s,
            "  {:>4}  {:<7}  {:>13.2}  {:>13.2}  {:>17.1}  {:>15.1}  {}",
            r.seed,
            r.case,
            r.max_abs_error_pct,
            r.max_est_error_pct,
            r.worst_overshoot_pct,
            r.total_overshoot_pct,
            feeds.join(" / ")
        );
    }
    s
}

/// The machine of the experiment.
pub const MACHINE: &str = "config/machines/mch10-force.ron";

/// The experiment `003-force`.
pub struct AdaptiveForce;

/// What the experiment found, and what its plots need.
pub struct ForceReport {
    /// Calibration, estimator and the cases.
    pub report: Report,
    /// Each case's run, in the order of `report.cases`.
    pub runs: Vec<Run>,
    /// The robustness summary over seeds.
    pub seeds: Vec<SeedCase>,
}

impl crate::Report for ForceReport {
    fn to_json(&self) -> serde_json::Value {
        let mut v = to_json(&self.report);
        v["seeds"] = serde_json::to_value(&self.seeds).unwrap_or(serde_json::Value::Null);
        v
    }
    fn to_text(&self) -> String {
        to_text(&self.report) + &seeds_text(&self.seeds)
    }
    fn write_plots(&self, dir: &Path) -> Result<Vec<PathBuf>> {
        let mut written = Vec::new();
        for (case, run) in self.report.cases.iter().zip(&self.runs) {
            let out = dir.join(format!("reproduce-003-case-{}.svg", case.case));
            plot_case(case, run, &out)?;
            written.push(out);
        }
        Ok(written)
    }
}

impl Experiment for AdaptiveForce {
    fn id(&self) -> ExperimentId {
        ExperimentId::Force003
    }
    fn default_machine(&self) -> &'static str {
        MACHINE
    }
    fn run(&self, options: &RunOptions) -> Result<Box<dyn crate::Report>> {
        let machine = options.machine_profile(MACHINE)?;
        let file = options.machine_path(MACHINE).display().to_string();
        let (report, runs) = report(&machine, &file)?;
        let seeds = seed_summaries(&machine, &file, options.seeds)?;
        Ok(Box::new(ForceReport {
            report,
            runs,
            seeds,
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::workspace_file;

    fn machine() -> MachineProfile {
        MachineProfile::load(&workspace_file(MACHINE)).unwrap()
    }

    fn case(m: &MachineProfile, name: &str) -> (CaseResult, Run) {
        let force = m.force.as_ref().unwrap();
        let cal = calibrate(m, force, true).unwrap();
        run_case(m, force, force.case(name).unwrap(), cal.line(), true).unwrap()
    }

    /// Case I: settled peak force within ±5 % of 450 N at each depth; feeds ordered
    /// and within ±20 % of the paper's 280 / 150 / 100 mm/min.
    #[test]
    fn case_i_holds_the_reference_and_the_feeds_fall_with_depth() {
        let m = machine();
        let (r, run) = case(&m, "I");
        assert_eq!(r.segments.len(), 3);
        for s in &r.segments {
            assert!(s.error_pct.abs() <= 5.0, "{s:?}");
            let paper = s.paper_feed_mm_min.unwrap();
            assert!(((s.feed_mm_min - paper) / paper).abs() <= 0.2, "{s:?}");
        }
        assert!(r
            .segments
            .windows(2)
            .all(|w| w[0].feed_mm_min > w[1].feed_mm_min));
        // the path stays the programmed line while the speed changes
        assert!(run.max_path_deviation_mm < 1e-9);
        let again = case(&m, "I").0;
        assert_eq!(r, again, "same seed, same figures");
    }

    /// Case II: the feed rises across steel → duralumin by the paper's factor
    /// (220/90) within ±25 %; the faster poles overshoot more than the slower ones.
    #[test]
    fn case_ii_adapts_to_the_material_and_faster_poles_overshoot_more() {
        let m = machine();
        let (slow, _) = case(&m, "II");
        let factor = |r: &CaseResult| {
            let steel = r
                .segments
                .iter()
                .find(|s| s.material == "SM45C" && s.paper_feed_mm_min.is_some())
                .unwrap();
            let dural = r
                .segments
                .iter()
                .find(|s| s.material == "duralumin" && s.paper_feed_mm_min.is_some())
                .unwrap();
            assert_eq!(steel.depth_mm, dural.depth_mm);
            (
                dural.feed_mm_min / steel.feed_mm_min,
                dural.paper_feed_mm_min.unwrap() / steel.paper_feed_mm_min.unwrap(),
            )
        };
        let (ours, paper) = factor(&slow);
        assert!((ours / paper - 1.0).abs() <= 0.25, "{ours} vs {paper}");
        for s in &slow.segments {
            assert!(s.error_pct.abs() <= 5.0, "{s:?}");
        }
        let (fast, _) = case(&m, "II-fast");
        let worst = |r: &CaseResult| {
            r.segments
                .iter()
                .map(|s| s.overshoot_pct)
                .fold(0.0, f64::max)
        };
        let total = |r: &CaseResult| r.segments.iter().map(|s| s.overshoot_pct).sum::<f64>();
        assert!(
            worst(&fast) > worst(&slow),
            "{} vs {}",
            worst(&fast),
            worst(&slow)
        );
        assert!(
            total(&fast) > total(&slow),
            "{} vs {}",
            total(&fast),
            total(&slow)
        );
    }

    /// The force estimate from the currents is within 15 % of the true peak at steady
    /// state, and its bandwidth is above the tooth frequency.
    #[test]
    fn force_estimate_is_accurate_and_fast_enough() {
        let m = machine();
        let force = m.force.as_ref().unwrap();
        let cal = calibrate(&m, force, true).unwrap();
        assert!(cal.max_rel_error < 0.05, "{}", cal.max_rel_error);
        for name in ["I", "II", "III"] {
            let (r, _) = run_case(&m, force, force.case(name).unwrap(), cal.line(), true).unwrap();
            for s in &r.segments {
                assert!(s.est_error_pct < 15.0, "{name}: {s:?}");
            }
        }
        let case = &force.cases[0];
        let tooth =
            MillingProcess::new(force.tool(&case.tool).unwrap(), case.spindle_rpm).tooth_hz();
        let g = estimate_gain(force, cal.line(), case.force_ref_n, tooth, 1e-4);
        assert!(
            g > std::f64::consts::FRAC_1_SQRT_2,
            "gain {g} at the tooth frequency"
        );
    }

    /// Tool breakage (force lost) and a force spike never drive the override out of
    /// its range nor change it faster than the configured rate limit.
    #[test]
    fn breakage_and_spike_keep_the_override_in_range_and_rate_limited() {
        let m = machine();
        let force = m.force.as_ref().unwrap();
        let cal = calibrate(&m, force, true).unwrap();
        let mut c = force.case("I").unwrap().clone();
        c.events = vec![
            ForceEvent {
                at_s: 5.0,
                duration_s: 2.0,
                force_scale: 0.0,
            },
            ForceEvent {
                at_s: 15.0,
                duration_s: 0.3,
                force_scale: 3.0,
            },
            ForceEvent {
                at_s: 25.0,
                duration_s: 0.05,
                force_scale: 10.0,
            },
        ];
        let (r, run) = run_case(&m, force, &c, cal.line(), true).unwrap();
        let k = &force.controller;
        assert!(run.override_range.0 >= k.override_min && run.override_range.1 <= k.override_max);
        assert!(run.max_override_step <= k.override_step_max + 1e-12);
        // the breakage raised the feed to the top, the spike cut it
        assert!(run
            .rows
            .iter()
            .any(|row| (row.override_frac - k.override_max).abs() < 1e-12));
        for w in run.rows.windows(2) {
            let step = (w[1].feed_cmd_mm_min - w[0].feed_cmd_mm_min).abs();
            assert!(step <= k.override_step_max * c.programmed_feed_mm_per_min + 1e-9);
        }
        // the interpolator's own speed changes stay within the axis acceleration
        let a = m.axes[force.feed_axis].max_acc_mm_per_s2;
        assert!(run.max_speed_step_mm_s <= a * m.interpolation_cycle_s * (1.0 + 1e-6));
        assert!(r.segments.iter().all(|s| s.force_n.is_finite()));
    }

    /// The gains in force at every revolution of cases I and II, with the estimated
    /// model they were computed from, give the closed-loop matrix of eq 20 the
    /// requested poles (characteristic polynomial to 1e-6).
    #[test]
    fn gains_from_estimated_models_place_the_poles() {
        use softnc_adaptive::robust_servo::{
            characteristic_polynomial, closed_loop_matrix, poly_from_roots,
        };
        let m = machine();
        let mut checked = 0;
        for name in ["I", "II"] {
            let (r, run) = case(&m, name);
            let want = poly_from_roots(r.poles);
            let mut models = std::collections::BTreeSet::new();
            for row in &run.rows {
                let model = Arma2::from_theta(&row.theta.into());
                let g = ServoGains {
                    k: row.gains[0],
                    r0: row.gains[1],
                    r1: row.gains[2],
                    r2: row.gains[3],
                    r3: row.gains[4],
                    r4: row.gains[5],
                };
                let cp = characteristic_polynomial(&closed_loop_matrix(&model, &g, run.t_rev_s));
                for (a, b) in cp.iter().zip(want) {
                    assert!(
                        (a - b).abs() < 1e-6,
                        "{name} t {}: {cp:?} vs {want:?}",
                        row.t_s
                    );
                }
                models.insert(row.theta.map(f64::to_bits));
                checked += 1;
            }
            assert!(models.len() >= 3, "{name}: the estimate must have moved");
        }
        assert!(checked > 500);
    }

    /// The pole-speed observation is not one seed's luck: on seeds 1–3 the faster
    /// poles overshoot more (largest and summed), and every case holds ±5 %.
    #[test]
    fn faster_poles_overshoot_more_on_every_seed() {
        let m = machine();
        let rows = seed_summaries(&m, "mch10-force.ron", 3).unwrap();
        for seed in 1..=3 {
            let get = |c: &str| rows.iter().find(|r| r.seed == seed && r.case == c).unwrap();
            let (slow, fast) = (get("II"), get("II-fast"));
            assert!(
                fast.worst_overshoot_pct > slow.worst_overshoot_pct,
                "{seed}"
            );
            assert!(
                fast.total_overshoot_pct > slow.total_overshoot_pct,
                "{seed}"
            );
        }
        assert!(rows
            .iter()
            .all(|r| r.max_abs_error_pct <= 5.0 && r.max_est_error_pct < 15.0));
    }

    #[test]
    fn overshoot_counts_only_beyond_the_first_crossing() {
        assert_eq!(
            overshoot(&[600.0, 500.0, 440.0, 455.0], 450.0),
            10.0 / 450.0
        );
        assert_eq!(overshoot(&[300.0, 400.0, 449.0], 450.0), 0.0);
        assert_eq!(overshoot(&[300.0, 500.0, 460.0], 450.0), 50.0 / 450.0);
    }

    /// The JSON has the issue's shape: cases[].case, cases[].segments[] with depth,
    /// material, force, reference, feed and the paper's feed (null when unprinted).
    #[test]
    fn json_has_the_issues_shape() {
        let m = machine();
        let (r, _) = report(&m, "mch10-force.ron").unwrap();
        let v = to_json(&r);
        let cases = v["cases"].as_array().unwrap();
        assert_eq!(cases[0]["case"], "I");
        for c in cases {
            for s in c["segments"].as_array().unwrap() {
                for key in ["depth_mm", "force_n", "force_ref_n", "feed_mm_min"] {
                    assert!(s[key].as_f64().unwrap().is_finite(), "{key}");
                }
                assert!(s["material"].is_string());
                assert!(s["paper_feed_mm_min"].is_f64() || s["paper_feed_mm_min"].is_null());
            }
        }
        assert_eq!(cases[0]["segments"][0]["paper_feed_mm_min"], 280.0);
    }

    #[test]
    fn a_profile_without_force_section_is_refused() {
        let m = MachineProfile::load(&workspace_file("config/machines/tnv40-ilc.ron")).unwrap();
        let e = report(&m, "tnv40-ilc.ron").unwrap_err().to_string();
        assert!(e.contains("no `force` section"), "{e}");
    }
}
