//! Paper 002, Sec. 3: the zero-lag non-causal command filter in the position task.
//!
//! `examples/paper002/corner.ngc` (a 90° corner at 3 m/min with exact stop, then a
//! dwell) runs on `config/machines/mill-resonance.ron` — the default mill with a
//! lightly damped structural mode between motor and table on X and Y — twice, the
//! same seed: once with the profile's command filter removed, once with it (eq 1–3,
//! applied by the same position-task code the daemon runs, reading the window
//! [i−N, i+N] of the command ring).
//!
//! **Residual vibration** of an axis: the largest deflection of the structural mode,
//! |table − motor|, after the axis's move has ended and the filtered command has
//! come to rest too, i.e. from N cycles after the raw command's last change on that
//! axis (X: the corner; Y: the end of the second move) to the end of the dwell; the
//! same window of the job for both runs. Beside it, the largest |table − final
//! position| in that window: the vibration plus the servo's own settling.
//! **Zero lag**: the largest |filtered − raw| command on the samples whose whole
//! window lies at constant speed, beside the lag of the same coefficients applied
//! causally (N samples, v·N·T). **Cost**: the largest contour error with and without
//! the filter (the filter rounds the exact-stop corner).
//!
//! The paper gives no table for the filter; its claims are printed beside ours.

use crate::error::{failed, Context, ExperimentError, Result};
use crate::{workspace_file, Experiment, ExperimentId, Report, RunOptions};
use softnc_machine::MachineProfile;
use softnc_servo::CycleEngine;
use softnc_sim::{simulate_observed, CommandSample, SimOptions};

/// The machine of the experiment.
pub const MACHINE: &str = "config/machines/mill-resonance.ron";
/// The program of the experiment.
pub const PROGRAM: &str = "examples/paper002/corner.ngc";
/// The filter must cut the residual vibration by at least this factor (issue 5).
pub const ACCEPT_REDUCTION: f64 = 5.0;
/// Axes the experiment reports (X and Y).
const AXES: [usize; 2] = [0, 1];
/// A command counts as settled once it moves less than this per cycle (mm).
const SETTLED_STEP_MM: f64 = 1e-12;
/// Names of the reported axes.
const AXIS_NAMES: [&str; 2] = ["X", "Y"];

/// One run's figures.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Run {
    /// Peak residual vibration of X (after the corner) and Y (after the end): the
    /// structural mode's deflection |table − motor| (mm).
    pub residual_mm: [f64; 2],
    /// Peak |table − final position| in the same windows: vibration and the servo's
    /// own settling (mm).
    pub settle_mm: [f64; 2],
    /// Largest |contour error| over the feed moves (mm).
    pub max_contour_mm: f64,
    /// Largest |filtered − raw| command on constant-speed windows (mm).
    pub zero_lag_dev_mm: f64,
    /// Cycles run.
    pub cycles: u64,
}

/// The experiment's result.
#[derive(Debug, Clone, PartialEq)]
pub struct FilterResult {
    /// Filter frequency f (Hz) and order N of X.
    pub f_hz: f64,
    /// Order N.
    pub order: usize,
    /// Mode frequency (Hz) and damping ratio of X.
    pub mode_hz: f64,
    /// Damping ratio ζ.
    pub damping: f64,
    /// |H| of the filter at f and at the mode (eq 2, zero phase).
    pub gain_at_f: f64,
    /// |H(f_mode)|.
    pub gain_at_mode: f64,
    /// Feed of the program (mm/s) and the causal lag v·N·T (mm) it would have.
    pub causal_lag_mm: f64,
    /// Without and with the filter.
    pub unfiltered: Run,
    /// With the filter.
    pub filtered: Run,
}

impl FilterResult {
    /// Residual-vibration reduction per axis (unfiltered / filtered).
    pub fn reduction(&self) -> [f64; 2] {
        [0, 1].map(|a| self.unfiltered.residual_mm[a] / self.filtered.residual_mm[a])
    }
}

/// Run the experiment on `machine` (whose X and Y carry a filter and a mode).
#[allow(clippy::too_many_lines)]
pub fn experiment(machine: &MachineProfile) -> Result<FilterResult> {
    let servo_x = machine.axis_servo(0);
    let (Some(filter), Some(mode)) = (servo_x.command_filter, servo_x.resonance) else {
        return Err(ExperimentError::refused(
            "the machine needs a command filter and a structural mode on X",
        ));
    };
    let path = workspace_file(PROGRAM);
    let text = std::fs::read_to_string(&path)
        .with_context(|| format!("cannot read {}", path.display()))?;
    let program = softnc_gcode::read_program(&text, PROGRAM, machine).map_err(failed)?;
    let plan = softnc_planner::plan(&program, machine, &Default::default()).map_err(failed)?;
    let raw: Vec<CommandSample> = plan
        .interpolator()
        .map(|s| CommandSample {
            pos_mm: softnc_core::Axes::from_xyz(s.pos_mm.0, 0.0),
            motion: s.motion,
            feed_move: s.feed_move,
            outputs: Default::default(),
        })
        .collect();
    let n = filter.order;
    // the last cycle at which each axis's raw command still changes
    let last_change = AXES.map(|a| {
        raw.windows(2)
            .rposition(|w| (w[1].pos_mm[a] - w[0].pos_mm[a]).abs() > SETTLED_STEP_MM)
            .map_or(0, |k| k + 1)
    });
    let final_pos = AXES.map(|a| raw.last().map_or(0.0, |s| s.pos_mm[a]));
    // constant-speed samples: the whole window [k−N, k+N] moves by the same step
    let const_speed: Vec<bool> = (0..raw.len())
        .map(|k| {
            if k < n + 1 || k + n >= raw.len() {
                return false;
            }
            let step = |j: usize, a: usize| raw[j].pos_mm[a] - raw[j - 1].pos_mm[a];
            AXES.iter().all(|&a| {
                let s0 = step(k - n, a);
                (k - n + 1..=k + n).all(|j| (step(j, a) - s0).abs() < 1e-9)
            }) && AXES.iter().any(|&a| step(k, a).abs() > 0.0)
        })
        .collect();
    let speed_mm_s = raw
        .windows(2)
        .map(|w| {
            AXES.iter()
                .map(|&a| (w[1].pos_mm[a] - w[0].pos_mm[a]).powi(2))
                .sum::<f64>()
                .sqrt()
        })
        .fold(0.0, f64::max)
        / plan.cycle_s();

    let run = |profile: &MachineProfile| -> Result<Run> {
        let mut engine = CycleEngine::try_new(
            profile,
            softnc_sim::SimBackend::new(profile, profile.servo.seed, SimOptions::default()),
        )
        .map_err(failed)?;
        // the filter's lead-in cycles before the job's first sample
        let pad = engine.filter_window();
        let mut r = Run::default();
        let report = simulate_observed(
            &mut engine,
            plan.cycle_s(),
            raw.iter().copied(),
            |m| plan.motion_primitive(m as usize),
            |row, e| {
                // the job's sample under this cycle (the filter runs N lead-in cycles)
                let k = (row.cycle as usize).saturating_sub(pad).min(raw.len() - 1);
                let table = e.backend().table_pos_mm();
                let motor = e.backend().true_pos_mm();
                for (i, &a) in AXES.iter().enumerate() {
                    if k >= last_change[i] + n {
                        r.residual_mm[i] = r.residual_mm[i].max((table[a] - motor[a]).abs());
                        r.settle_mm[i] = r.settle_mm[i].max((table[a] - final_pos[i]).abs());
                    }
                }
                if const_speed[k] {
                    let dev = AXES
                        .iter()
                        .map(|&a| (row.record.cmd_mm[a] - raw[k].pos_mm[a]).abs())
                        .fold(0.0, f64::max);
                    r.zero_lag_dev_mm = r.zero_lag_dev_mm.max(dev);
                }
            },
        )
        .map_err(failed)?;
        r.max_contour_mm = report.contour.max_abs();
        r.cycles = report.cycles;
        Ok(r)
    };
    let mut without = machine.clone();
    for a in without.servo.axes.iter_mut() {
        a.command_filter = None;
    }
    let unfiltered = run(&without)?;
    let filtered = run(machine)?;
    let fir =
        softnc_control::ZeroLagFir::design(filter.frequency_hz, machine.interpolation_cycle_s, n)
            .map_err(failed)?;
    Ok(FilterResult {
        f_hz: filter.frequency_hz,
        order: n,
        mode_hz: mode.frequency_hz,
        damping: mode.damping_ratio,
        gain_at_f: fir.response(filter.frequency_hz, machine.interpolation_cycle_s),
        gain_at_mode: fir.response(mode.frequency_hz, machine.interpolation_cycle_s),
        causal_lag_mm: speed_mm_s * n as f64 * machine.interpolation_cycle_s,
        unfiltered,
        filtered,
    })
}

/// The JSON document.
pub fn to_json(r: &FilterResult) -> serde_json::Value {
    let um = 1000.0;
    let red = r.reduction();
    let rows: Vec<serde_json::Value> = (0..2)
        .map(|i| {
            serde_json::json!({
                "axis": AXIS_NAMES[i],
                "residual_um_unfiltered": r.unfiltered.residual_mm[i] * um,
                "residual_um_filtered": r.filtered.residual_mm[i] * um,
                "settle_um_unfiltered": r.unfiltered.settle_mm[i] * um,
                "settle_um_filtered": r.filtered.settle_mm[i] * um,
                "reduction": red[i],
            })
        })
        .collect();
    serde_json::json!({
        "experiment": "002-filter",
        "machine": MACHINE,
        "program": PROGRAM,
        "filter": {"f_hz": r.f_hz, "order": r.order,
                    "gain_at_f": r.gain_at_f, "gain_at_mode_db": 20.0 * r.gain_at_mode.abs().log10()},
        "mode": {"frequency_hz": r.mode_hz, "damping_ratio": r.damping},
        "rows": rows,
        "zero_lag_max_dev_um": r.filtered.zero_lag_dev_mm * um,
        "causal_lag_um": r.causal_lag_mm * um,
        "max_contour_um": {"unfiltered": r.unfiltered.max_contour_mm * um,
                           "filtered": r.filtered.max_contour_mm * um},
        "start_delay_s": r.order as f64 * 0.001,
        "paper": {"claims": ["zero phase: no lag on the command",
                             "unity DC gain (eq 3)",
                             "start delay of N cycles before motion, no effect on control"],
                  "table": null},
    })
}

/// The text table.
pub fn to_text(r: &FilterResult) -> String {
    let um = 1000.0;
    let red = r.reduction();
    let mut s = format!(
        "Paper 002 zero-lag filter on {MACHINE}, {PROGRAM}\n\
         filter f = {} Hz, N = {}: |H(f)| = {:.3}, |H({} Hz mode)| = {:.1} dB; mode ζ = {}\n\n\
         residual vibration after the move: peak |table − motor| (µm); beside it\n\
         the peak |table − end position| (vibration + servo settling, µm)\n\
         axis  unfiltered  filtered  reduction (issue: ≥ {ACCEPT_REDUCTION}×)   settle unfilt.  filtered\n",
        r.f_hz,
        r.order,
        r.gain_at_f,
        r.mode_hz,
        20.0 * r.gain_at_mode.abs().log10(),
        r.damping
    );
    for i in 0..2 {
        s += &format!(
            "{:<4}  {:>10.3}  {:>8.3}  {:>8.1}×                {:>8.1}  {:>8.1}\n",
            AXIS_NAMES[i],
            r.unfiltered.residual_mm[i] * um,
            r.filtered.residual_mm[i] * um,
            red[i],
            r.unfiltered.settle_mm[i] * um,
            r.filtered.settle_mm[i] * um,
        );
    }
    s += &format!(
        "\nzero lag: filtered − raw command on constant-speed windows ≤ {:.2e} µm \
         (the same taps applied causally lag N samples = {:.1} µm)\n\
         cost: max contour error {:.1} µm unfiltered, {:.1} µm filtered (corner rounded)\n\
         paper 002: zero phase, unity DC gain, start delay N·T = {} s; no figures printed\n",
        r.filtered.zero_lag_dev_mm * um,
        r.causal_lag_mm * um,
        r.unfiltered.max_contour_mm * um,
        r.filtered.max_contour_mm * um,
        r.order as f64 * 0.001,
    );
    s
}

/// The experiment `002-filter`.
pub struct ZeroLagFilter;

impl Report for FilterResult {
    fn to_json(&self) -> serde_json::Value {
        to_json(self)
    }
    fn to_text(&self) -> String {
        to_text(self)
    }
}

impl Experiment for ZeroLagFilter {
    fn id(&self) -> ExperimentId {
        ExperimentId::Filter002
    }
    fn default_machine(&self) -> &'static str {
        MACHINE
    }
    fn run(&self, options: &RunOptions) -> Result<Box<dyn Report>> {
        let machine = options.machine_profile(MACHINE)?;
        Ok(Box::new(experiment(&machine)?))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_filter_cuts_residual_vibration_at_least_fivefold_without_lag() {
        let machine = MachineProfile::load(&workspace_file(MACHINE)).unwrap();
        let r = experiment(&machine).unwrap();
        let red = r.reduction();
        for (i, red) in red.iter().enumerate() {
            assert!(
                *red >= ACCEPT_REDUCTION,
                "axis {i}: residual {} → {} mm, {red}×",
                r.unfiltered.residual_mm[i],
                r.filtered.residual_mm[i]
            );
        }
        // the unfiltered machine really rings (more than the encoder's resolution)
        assert!(r.unfiltered.residual_mm[0] > 10.0 * machine.axes[0].encoder_resolution_mm);
        // zero lag on the constant-speed part, where the causal filter lags v·N·T
        assert!(
            r.filtered.zero_lag_dev_mm < 1e-9,
            "{}",
            r.filtered.zero_lag_dev_mm
        );
        assert!(r.causal_lag_mm > 1.0);
        // the filtered run adds exactly N lead-in and N run-out cycles
        assert_eq!(r.filtered.cycles, r.unfiltered.cycles + 2 * r.order as u64);
    }
}
