//! Paper 000, Sec. IV: the five compensation configurations — (a) none, (b) DOB,
//! (c) MBDA, (d) DOB + PDC, (e) MBDA + PDC — on the line and circle cuts of
//! `examples/paper000/`, on the TNV-40 velocity loops of
//! `config/machines/tnv40-pdc.ron` with Coulomb friction and the periodic cutting
//! disturbance, at the paper's 1500 rpm and at 1200 and 1800 rpm.
//!
//! **Error measured.** The error caused by the disturbances: each run's error minus
//! the error of a reference run of the same plan on the ideal machine (no friction,
//! no cutting disturbance, no quantisation, no compensation). That removes the
//! P position loop's own tracking lag (v/K_pp, a feed-forward matter), leaving
//! what the compensators act on. Line: the following error of X and Y (pooled);
//! circle: the contour (radial) error, paper 001 eq 10. Positions are the true
//! table positions (the loop itself sees the quantised encoder).
//!
//! **Constant-speed part** (the paper: "the constant-speed part, where the periodic
//! disturbance matters more than friction"): cycles of feed moves where the command
//! speed is within [`CONST_SPEED_TOL`] of its maximum, except the [`SPIKE_WINDOW_S`]
//! after an axis starts or reverses. **Spikes**: the largest error inside those
//! windows (start-up stiction on the line, quadrant crossings on the circle).
//!
//! **Spindle speeds.** At 1500 rpm the controllers are designed from the profile.
//! At 1200 and 1800 rpm the controllers are still designed for the profile's
//! 1500 rpm; the new spindle speed arrives as at a job's S word: the PDC is
//! redesigned off the cycle and swapped in at the first cycle boundary.

use crate::error::{failed, Context, ExperimentError, Result};
use crate::pdc_profile::{load_pdc_profile, pdc_profile_path, PdcProfile};
use crate::plot::{write_svg, Panel, Series};
use crate::{workspace_file, ExperimentId, Report, RunOptions};
use plotters::style::colors::{BLACK, BLUE, GREEN, MAGENTA, RED};
use softnc_machine::compensation::{Compensation, OuterCompensator};
use softnc_machine::servo::PlantModel;
use softnc_machine::MachineProfile;
use softnc_servo::CycleEngine;
use softnc_sim::{simulated_engine, SimBackend, SimOptions};
use std::path::{Path, PathBuf};

/// The machine of the experiment.
pub const MACHINE: &str = "config/machines/tnv40-pdc.ron";
/// 1 pulse = 1/2.4 µm (paper 000 Sec. IV).
pub const UM_PER_PULSE: f64 = 1.0 / 2.4;
/// The RMS errors the paper prints for the line cut (pulse), in print order; its
/// labels (a)…(f) are garbled (six values for five configurations).
pub const PAPER_RMS_PULSE: [f64; 6] = [0.1271, 0.9406, 1.5144, 0.8987, 0.2616, 0.1802];
/// The experiment's settings (`examples/paper000/experiment.ron`).
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Experiment {
    /// Axial depth of cut (mm).
    pub depth_mm: f64,
    /// Periodic disturbance amplitude per mm of depth on X and Y (rad/s per mm).
    pub amplitude_rad_s_per_mm: f64,
    /// Spindle speeds (rpm); the first is the paper's.
    pub spindle_rpm: Vec<f64>,
}

impl Experiment {
    /// Load the experiment file.
    pub fn load(path: &std::path::Path) -> Result<Self> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read {}", path.display()))?;
        softnc_core::config::parse_ron(&text, &path.display().to_string())
            .map_err(|e| ExperimentError::Config(e.to_string()))
    }

    /// A_per on X and Y (rad/s).
    pub fn amplitude_rad_s(&self) -> f64 {
        self.depth_mm * self.amplitude_rad_s_per_mm
    }
}
/// Command speed within this fraction of its maximum counts as constant speed.
pub const CONST_SPEED_TOL: f64 = 0.01;
/// Window after an axis starts or reverses in which a spike is looked for (s).
pub const SPIKE_WINDOW_S: f64 = 0.3;
/// Fraction of the RMS error left by DOB or MBDA alone that the PDC must remove.
pub const ACCEPT_PDC_REMOVAL: f64 = 0.8;
/// Seed of the simulated machine.
pub const SEED: u64 = 1;

/// The five configurations of the paper.
pub const CONFIGS: [&str; 5] = ["none", "dob", "mbda", "dob+pdc", "mbda+pdc"];
/// The two contours.
pub const CONTOURS: [&str; 2] = ["line", "circle"];

/// The compensation of configuration `name` from the design file.
pub fn compensation(name: &str, design: &PdcProfile) -> Result<Compensation> {
    let dob = OuterCompensator::Dob(design.dob);
    let mbda = OuterCompensator::Mbda(design.mbda);
    let pdc = Some(design.pdc.clone());
    Ok(match name {
        "none" => Compensation::default(),
        "dob" => Compensation {
            outer: dob,
            pdc: None,
        },
        "mbda" => Compensation {
            outer: mbda,
            pdc: None,
        },
        "dob+pdc" => Compensation { outer: dob, pdc },
        "mbda+pdc" => Compensation { outer: mbda, pdc },
        other => {
            return Err(ExperimentError::refused(format!(
                "unknown configuration {other}"
            )))
        }
    })
}

/// `base` with compensation `comp` on X and Y, the spindle at `rpm` and the
/// periodic disturbance amplitude `amplitude` on X and Y (`None`: the profile's).
pub fn machine_for(
    base: &MachineProfile,
    comp: &Compensation,
    rpm: f64,
    amplitude: Option<f64>,
) -> MachineProfile {
    let mut m = base.clone();
    m.servo.axes = (0..3).map(|i| m.axis_servo(i)).collect();
    for a in m.servo.axes.iter_mut().take(2) {
        a.compensation = comp.clone();
    }
    if let Some(c) = m.servo.cutting.as_mut() {
        c.spindle_rpm = rpm;
        if let Some(a) = amplitude {
            c.amplitude[0] = a;
            c.amplitude[1] = a;
        }
    }
    m
}

/// The ideal machine: no friction, no compensation (the reference run).
fn ideal(base: &MachineProfile) -> MachineProfile {
    let mut m = machine_for(base, &Compensation::default(), 0.0, None);
    for a in &mut m.servo.axes {
        if let PlantModel::VelocityLoop { coulomb_rad_s, .. } = &mut a.plant {
            *coulomb_rad_s = 0.0;
        }
    }
    m
}

/// A contour planned once.
pub struct Prepared {
    /// "line" or "circle".
    pub contour: &'static str,
    plan: softnc_planner::Plan,
    samples: Vec<softnc_planner::Sample>,
    const_speed: Vec<bool>,
    spike_window: Vec<bool>,
}

/// Read and plan `examples/paper000/<contour>.ngc`.
pub fn prepare(contour: &'static str, machine: &MachineProfile) -> Result<Prepared> {
    let rel = format!("examples/paper000/{contour}.ngc");
    let path = workspace_file(&rel);
    let text = std::fs::read_to_string(&path)
        .with_context(|| format!("cannot read {}", path.display()))?;
    let program = softnc_gcode::read_program(&text, &rel, machine).map_err(failed)?;
    let plan = softnc_planner::plan(&program, machine, &softnc_planner::PlanOptions::default())
        .map_err(failed)?;
    let samples: Vec<softnc_planner::Sample> = plan.interpolator().collect();
    if samples.is_empty() {
        return Err(ExperimentError::refused(format!("{rel}: empty plan")));
    }
    let t = plan.cycle_s();
    let vel = |k: usize, ax: usize| -> f64 {
        if k == 0 {
            return 0.0;
        }
        (samples[k].pos_mm.0[ax] - samples[k - 1].pos_mm.0[ax]) / t
    };
    let speed: Vec<f64> = (0..samples.len())
        .map(|k| vel(k, 0).hypot(vel(k, 1)))
        .collect();
    let vmax = speed
        .iter()
        .zip(&samples)
        .filter(|(_, s)| s.feed_move)
        .map(|(v, _)| *v)
        .fold(0.0, f64::max);
    let mut const_speed: Vec<bool> = speed
        .iter()
        .zip(&samples)
        .map(|(v, s)| s.feed_move && *v >= (1.0 - CONST_SPEED_TOL) * vmax)
        .collect();
    // starts and reversals of X or Y: the command velocity leaves zero or changes sign
    let window = (SPIKE_WINDOW_S / t).round() as usize;
    let mut spike_window = vec![false; samples.len()];
    let eps = 1e-9;
    for ax in 0..2 {
        let mut last_sign = 0.0;
        for k in 1..samples.len() {
            let v = vel(k, ax);
            if v.abs() < eps {
                continue;
            }
            if v.signum() != last_sign {
                for w in spike_window.iter_mut().skip(k).take(window) {
                    *w = true;
                }
            }
            last_sign = v.signum();
        }
    }
    for (c, w) in const_speed.iter_mut().zip(&spike_window) {
        *c = *c && !*w;
    }
    Ok(Prepared {
        contour,
        plan,
        samples,
        const_speed,
        spike_window,
    })
}

/// The error of every cycle of one run (mm): line [e_x, e_y], circle [ε, 0].
fn errors(p: &Prepared, engine: &mut CycleEngine<SimBackend>) -> Result<Vec<[f64; 2]>> {
    engine.reset(p.samples[0].pos_mm.0);
    let mut out = Vec::with_capacity(p.samples.len());
    for s in &p.samples {
        engine.step(s.pos_mm.0, s.feed_move).map_err(failed)?;
        let pos = engine.backend().true_pos_mm();
        let e = match p.contour {
            "line" => [s.pos_mm.0[0] - pos[0], s.pos_mm.0[1] - pos[1]],
            _ => {
                let c = p
                    .plan
                    .motion_primitive(s.motion as usize)
                    .filter(|_| s.feed_move)
                    .map(|prim| prim.contour_error(softnc_core::Vec3(pos.xyz())))
                    .unwrap_or(0.0);
                [c, 0.0]
            }
        };
        out.push(e);
    }
    Ok(out)
}

/// Figures of one run (µm) and its disturbance error trace.
#[derive(Debug, Clone, PartialEq)]
pub struct RunResult {
    /// RMS in the constant-speed part (µm).
    pub rms_um: f64,
    /// Largest |error| in the constant-speed part (µm).
    pub max_abs_um: f64,
    /// Largest |error| after starts and reversals (µm).
    pub spike_um: f64,
    /// Disturbance error per cycle (µm): line X and Y, circle ε and 0.
    pub trace_um: Vec<[f64; 2]>,
}

/// The reference (ideal machine) errors of a contour.
pub fn reference(p: &Prepared, base: &MachineProfile) -> Result<Vec<[f64; 2]>> {
    let m = ideal(base);
    let opts = SimOptions {
        quantisation: false,
        noise: false,
        cutting: false,
        variation: false,
    };
    errors(p, &mut simulated_engine(&m, SEED, opts))
}

/// Run configuration `comp` at `rpm` (see the module docs for off-design speeds).
pub fn run(
    p: &Prepared,
    base: &MachineProfile,
    comp: &Compensation,
    rpm: f64,
    amplitude: Option<f64>,
    reference: &[[f64; 2]],
) -> Result<RunResult> {
    let design_rpm = base
        .servo
        .cutting
        .as_ref()
        .context("the machine profile has no servo.cutting section")?
        .spindle_rpm;
    let actual = machine_for(base, comp, rpm, amplitude);
    let designed = machine_for(base, comp, design_rpm, amplitude);
    let backend = SimBackend::new(&actual, SEED, SimOptions::default());
    let mut engine = CycleEngine::try_new(&designed, backend).map_err(failed)?;
    if rpm != design_rpm {
        let fd_hz = actual.servo.cutting.as_ref().map(|c| c.frequency_hz());
        engine.redesign_pdc(fd_hz.unwrap_or(0.0)).map_err(failed)?;
    }
    let errs = errors(p, &mut engine)?;
    let trace_um: Vec<[f64; 2]> = errs
        .iter()
        .zip(reference)
        .map(|(e, r)| [(e[0] - r[0]) * 1e3, (e[1] - r[1]) * 1e3])
        .collect();
    let axes = if p.contour == "line" { 2 } else { 1 };
    let (mut n, mut sum_sq, mut max_abs, mut spike) = (0usize, 0.0, 0.0f64, 0.0f64);
    for (k, e) in trace_um.iter().enumerate() {
        for v in &e[..axes] {
            if p.const_speed[k] {
                n += 1;
                sum_sq += v * v;
                max_abs = max_abs.max(v.abs());
            }
            if p.spike_window[k] {
                spike = spike.max(v.abs());
            }
        }
    }
    Ok(RunResult {
        rms_um: (sum_sq / n.max(1) as f64).sqrt(),
        max_abs_um: max_abs,
        spike_um: spike,
        trace_um,
    })
}

/// A named disturbance-error trace (µm per cycle) of one run.
pub type Trace = (String, Vec<[f64; 2]>);

/// One row of the table.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Row {
    /// "line" or "circle".
    pub contour: &'static str,
    /// "none", "dob", "mbda", "dob+pdc", "mbda+pdc".
    pub config: &'static str,
    /// Spindle speed (rpm).
    pub spindle_rpm: f64,
    /// Tooth frequency (Hz).
    pub fd_hz: f64,
    /// RMS in the constant-speed part (pulse).
    pub rms_pulse: f64,
    /// RMS in the constant-speed part (µm).
    pub rms_um: f64,
    /// Largest |error| in the constant-speed part (µm).
    pub max_abs_um: f64,
    /// Largest |error| after starts and reversals (µm).
    pub spike_um: f64,
}

/// Every contour × configuration × spindle speed.
pub fn table(
    base: &MachineProfile,
    design: &PdcProfile,
    exp: &Experiment,
) -> Result<(Vec<Row>, Vec<Trace>)> {
    let flutes = base.servo.cutting.as_ref().map(|c| c.flutes).unwrap_or(0) as f64;
    let mut rows = Vec::new();
    let mut traces = Vec::new();
    for contour in CONTOURS {
        let p = prepare(contour, base)?;
        let r = reference(&p, base)?;
        for &rpm in &exp.spindle_rpm {
            for config in CONFIGS {
                let comp = compensation(config, design)?;
                let res = run(&p, base, &comp, rpm, Some(exp.amplitude_rad_s()), &r)?;
                rows.push(Row {
                    contour,
                    config,
                    spindle_rpm: rpm,
                    fd_hz: rpm * flutes / 60.0,
                    rms_pulse: res.rms_um / UM_PER_PULSE,
                    rms_um: res.rms_um,
                    max_abs_um: res.max_abs_um,
                    spike_um: res.spike_um,
                });
                if rpm == exp.spindle_rpm[0] {
                    traces.push((format!("{contour} {config}"), res.trace_um));
                }
            }
        }
    }
    Ok((rows, traces))
}

fn find<'a>(rows: &'a [Row], contour: &str, config: &str, rpm: f64) -> Option<&'a Row> {
    rows.iter()
        .find(|r| r.contour == contour && r.config == config && r.spindle_rpm == rpm)
}

/// The acceptance checks of issue 7, each with its figures.
pub fn acceptance(rows: &[Row], spindle_rpm: &[f64]) -> Vec<(String, bool)> {
    let mut out = Vec::new();
    for contour in CONTOURS {
        for &rpm in spindle_rpm {
            for outer in ["dob", "mbda"] {
                let (Some(a), Some(b)) = (
                    find(rows, contour, outer, rpm),
                    find(rows, contour, &format!("{outer}+pdc"), rpm),
                ) else {
                    continue;
                };
                let removed = 1.0 - b.rms_um / a.rms_um;
                out.push((
                    format!(
                        "{contour} {rpm} rpm: PDC removes {:.1} % of the RMS left by {outer} ({:.3} -> {:.3} µm)",
                        100.0 * removed,
                        a.rms_um,
                        b.rms_um
                    ),
                    removed >= ACCEPT_PDC_REMOVAL,
                ));
            }
        }
        let rpm = spindle_rpm[0];
        if let Some(none) = find(rows, contour, "none", rpm) {
            for outer in ["dob", "mbda"] {
                if let Some(o) = find(rows, contour, outer, rpm) {
                    out.push((
                        format!(
                            "{contour} {rpm} rpm: {outer} spike {:.3} µm vs none {:.3} µm",
                            o.spike_um, none.spike_um
                        ),
                        o.spike_um < none.spike_um,
                    ));
                }
            }
        }
    }
    out
}

/// The JSON document: `{"rows":[…], "paper":{…}, "acceptance":[…]}`.
pub fn to_json(rows: &[Row], checks: &[(String, bool)], exp: &Experiment) -> serde_json::Value {
    let r4 = |x: f64| (x * 1e4).round() / 1e4;
    serde_json::json!({
        "rows": rows.iter().map(|r| serde_json::json!({
            "contour": r.contour,
            "config": r.config,
            "spindle_rpm": r.spindle_rpm,
            "fd_hz": r.fd_hz,
            "rms_pulse": r4(r.rms_pulse),
            "rms_um": r4(r.rms_um),
            "max_abs_um": r4(r.max_abs_um),
            "spike_um": r4(r.spike_um),
        })).collect::<Vec<_>>(),
        "paper": {
            "unit": "pulse (1 pulse = 1/2.4 um)",
            "line_rms_pulse_as_printed": PAPER_RMS_PULSE,
            "note": "labels (a)-(f) garbled in the paper; claim: PDC removes about 80 % of the periodic error",
        },
        "experiment": {
            "depth_mm": exp.depth_mm,
            "amplitude_rad_s": exp.amplitude_rad_s(),
            "spindle_rpm": exp.spindle_rpm,
        },
        "acceptance": checks.iter().map(|(what, ok)| serde_json::json!({"check": what, "pass": ok})).collect::<Vec<_>>(),
    })
}

/// The table as text.
pub fn to_text(rows: &[Row], checks: &[(String, bool)], exp: &Experiment) -> String {
    let mut s = format!(
        "paper 000 on tnv40-pdc.ron, depth {} mm, A_per = {:.3} rad/s on X and Y:\n\
         disturbance error in the constant-speed part (1 pulse = 1/2.4 µm);\n\
         spike = largest error after starts/reversals\n\n\
         contour rpm   f_d | config    | rms pulse  rms µm  max µm  spike µm\n",
        exp.depth_mm,
        exp.amplitude_rad_s()
    );
    for r in rows {
        s += &format!(
            "{:<7} {:>4} {:>4} | {:<9} | {:>9.4} {:>7.4} {:>7.4} {:>9.4}\n",
            r.contour,
            r.spindle_rpm,
            r.fd_hz,
            r.config,
            r.rms_pulse,
            r.rms_um,
            r.max_abs_um,
            r.spike_um
        );
    }
    s += &format!(
        "\npaper, line, RMS as printed (pulse; labels garbled): {:?}\n\nacceptance:\n",
        PAPER_RMS_PULSE
    );
    for (what, ok) in checks {
        s += &format!("  [{}] {what}\n", if *ok { "pass" } else { "FAIL" });
    }
    s
}

/// Error vs time of every configuration on `contour` at 1500 rpm (SVG).
pub fn plot_traces(contour: &str, traces: &[Trace], cycle_s: f64, out: &Path) -> Result<()> {
    let series: Vec<Series> = traces
        .iter()
        .filter(|(name, _)| name.starts_with(contour))
        .zip([BLACK, RED, BLUE, MAGENTA, GREEN])
        .map(|((name, tr), colour)| {
            Series::new(
                name.split(' ').nth(1).unwrap_or(""),
                tr.iter()
                    .enumerate()
                    .map(|(k, e)| (k as f64 * cycle_s, e[0] / UM_PER_PULSE))
                    .collect(),
                colour,
            )
        })
        .collect();
    let t_end = series.iter().map(|s| s.points.len()).max().unwrap_or(1) as f64 * cycle_s;
    let lim = series
        .iter()
        .flat_map(|s| s.points.iter().map(|p| p.1.abs()))
        .fold(0.1f64, f64::max)
        * 1.05;
    let what = if contour == "line" {
        "X following"
    } else {
        "contour"
    };
    let panel = Panel::new(
        format!(
            "paper 000 {contour}, 1500 rpm (f_d = 50 Hz): {what} error caused by the disturbances"
        ),
        480,
        0.0..t_end,
        -lim..lim,
    )
    .axes("time (s)", "error (pulse, 1/2.4 µm)")
    .lines(series);
    write_svg(out, 1000, &[panel])
}

/// |L|, |W|, |H·P_n| (dB) and ∠H·P_n (deg) of the X-axis design at `fd` (SVG).
pub fn plot_responses(design: &PdcProfile, machine: &str, fd: f64, out: &Path) -> Result<()> {
    use softnc_control::discrete_tf::DiscreteTf;
    let (model, t, _) = crate::pdc_profile::nominal_plant(machine, design, "x")?;
    let d = softnc_control::pdc::design(&design.pdc, &model, t, fd).map_err(failed)?;
    let fir = |taps: &[f64]| DiscreteTf::fir(taps.to_vec()).map_err(failed);
    let (l, w, h) = (fir(&d.l_taps)?, fir(&d.w_taps)?, fir(&d.h_taps)?);
    let nyq = 0.5 / t;
    let freqs: Vec<f64> = (1..=500).map(|i| nyq * i as f64 / 500.0).collect();
    let (db_lo, db_hi) = (-60.0, 40.0);
    let db = |x: f64| (20.0 * x.log10()).clamp(db_lo, db_hi);
    let curve = |g: &dyn Fn(f64) -> f64| freqs.iter().map(|&f| (f, g(f))).collect();
    let magnitude = Panel {
        marks: vec![(fd, GREEN)],
        ..Panel::new(
            format!("PDC design, X axis (P_nx, eq 35), f_d = {fd} Hz: magnitude"),
            420,
            0.0..nyq,
            db_lo..db_hi,
        )
        .axes("frequency (Hz)", "dB")
        .lines(vec![
            Series::new("|L| dB", curve(&|f| db(l.response(f, t).norm())), BLUE),
            Series::new("|W| dB", curve(&|f| db(w.response(f, t).norm())), RED),
            Series::new(
                "|H·P_n| dB",
                curve(&|f| db((h.response(f, t) * model.response(f, t)).norm())),
                BLACK,
            ),
        ])
    };
    let phase = Panel {
        title_px: 16,
        marks: vec![(fd, GREEN)],
        ..Panel::new(
            "phase of H·P_n (deg); 0 at f_d",
            280,
            0.0..nyq,
            -180.0..180.0,
        )
        .axes("frequency (Hz)", "deg")
        .lines(vec![Series::new(
            "",
            curve(&|f| (h.response(f, t) * model.response(f, t)).arg().to_degrees()),
            BLACK,
        )])
    };
    write_svg(out, 1000, &[magnitude, phase])
}

/// The experiment `000-pdc`.
pub struct Pdc;

/// What the experiment found, and what its plots need.
pub struct PdcReport {
    /// The table rows.
    pub rows: Vec<Row>,
    /// The acceptance checks.
    pub checks: Vec<(String, bool)>,
    /// The experiment's settings.
    pub experiment: Experiment,
    /// Error traces at 1500 rpm per contour and configuration.
    pub traces: Vec<Trace>,
    /// The machine's interpolation cycle (s).
    pub cycle_s: f64,
    /// The compensator design file.
    pub design: PdcProfile,
    /// The machine profile's path.
    pub machine_path: PathBuf,
    /// The cutting disturbance's frequency (Hz), when the profile has one.
    pub fd_hz: Option<f64>,
}

impl Report for PdcReport {
    fn to_json(&self) -> serde_json::Value {
        to_json(&self.rows, &self.checks, &self.experiment)
    }
    fn to_text(&self) -> String {
        to_text(&self.rows, &self.checks, &self.experiment)
    }
    fn write_plots(&self, dir: &Path) -> Result<Vec<PathBuf>> {
        let mut written = Vec::new();
        for contour in CONTOURS {
            let out = dir.join(format!("reproduce-000-{contour}.svg"));
            plot_traces(contour, &self.traces, self.cycle_s, &out)?;
            written.push(out);
        }
        let out = dir.join("reproduce-000-pdc-response.svg");
        let fd = self.fd_hz.context("no servo.cutting")?;
        plot_responses(
            &self.design,
            &self.machine_path.display().to_string(),
            fd,
            &out,
        )?;
        written.push(out);
        Ok(written)
    }
}

impl crate::Experiment for Pdc {
    fn id(&self) -> ExperimentId {
        ExperimentId::Pdc000
    }
    fn default_machine(&self) -> &'static str {
        MACHINE
    }
    fn run(&self, options: &RunOptions) -> Result<Box<dyn Report>> {
        let machine_path = options.machine_path(MACHINE);
        let base = options.machine_profile(MACHINE)?;
        let design = load_pdc_profile(&pdc_profile_path("tnv40-pdc", None))?;
        let experiment = Experiment::load(&workspace_file("examples/paper000/experiment.ron"))?;
        let (rows, traces) = table(&base, &design, &experiment)?;
        let checks = acceptance(&rows, &experiment.spindle_rpm);
        Ok(Box::new(PdcReport {
            rows,
            checks,
            experiment,
            traces,
            cycle_s: base.interpolation_cycle_s,
            design,
            machine_path,
            fd_hz: base.servo.cutting.as_ref().map(|c| c.frequency_hz()),
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pdc_removes_most_of_the_periodic_error_on_the_line() {
        let base = MachineProfile::load(&workspace_file(MACHINE)).unwrap();
        let design = load_pdc_profile(&pdc_profile_path("tnv40-pdc", None)).unwrap();
        let exp = Experiment::load(&workspace_file("examples/paper000/experiment.ron")).unwrap();
        let p = prepare("line", &base).unwrap();
        let r = reference(&p, &base).unwrap();
        let a = Some(exp.amplitude_rad_s());
        let rpm = exp.spindle_rpm[0];
        let run_cfg =
            |c: &str| run(&p, &base, &compensation(c, &design).unwrap(), rpm, a, &r).unwrap();
        let (dob, dob_pdc) = (run_cfg("dob"), run_cfg("dob+pdc"));
        assert!(
            dob_pdc.rms_um < (1.0 - ACCEPT_PDC_REMOVAL) * dob.rms_um,
            "{dob_pdc:?} vs {dob:?}"
        );
    }
}
