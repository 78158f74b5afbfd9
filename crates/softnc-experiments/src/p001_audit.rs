//! Paper 001, Table 5: audit of the plant readings and of the FLC's working range
//! (`softnc reproduce 001-table5 --audit`).
//!
//! The paper leaves three things open that decide how hard the plant is to control:
//! the unit of the open-loop gain K (Table 2 prints 28.35 and 28.96 without one), how
//! the DAC's counts relate to the amplifier's volts, and how the reference was
//! generated (no acceleration limit is given). Every reading that the text allows is
//! run here through the same six cases, and each is judged by what the paper does fix:
//! the feeds must be reachable through the 8-bit DAC, and Table 4's PID must be a
//! working controller on it. The second part measures the FLC's gains where it
//! actually operates, against the sector-bound "equivalent" gains of eq 13.

use crate::error::{ExperimentError, Result};
use crate::p001_cases::{machine_for, prepare, run, table, Row, Stack, CASES};
use nalgebra::{Matrix2, Vector2};
use softnc_control::discrete_tf::{is_schur_stable, poly_add, poly_mul};
use softnc_control::fuzzy::{EquivalentGains, FuzzyController, SectorGrid};
use softnc_machine::fuzzy::FuzzyConfig;
use softnc_machine::servo::PlantModel;
use softnc_machine::MachineProfile;

/// Seconds per minute: the profile stores K in (mm/min) per DAC count.
const S_PER_MIN: f64 = 60.0;
/// Counts on each side of zero of a signed 8-bit DAC (paper 001: "8-bit output").
const DAC_HALF_COUNTS: f64 = 128.0;
/// Full-scale voltages of an 8-bit DAC that the (mm/s)/V reading has to assume
/// (the paper does not give one): the two common ranges ±10 V and ±5 V.
const DAC_FULL_SCALE_V: [f64; 2] = [10.0, 5.0];
/// "Constant feed" reference: acceleration and jerk so large that every feed is
/// reached within a microsecond, i.e. the reference velocity steps as in an
/// interpolator without acceleration control (mm/s², mm/s³) …
const CONST_FEED_ACC_MM_PER_S2: f64 = 1.0e6;
const CONST_FEED_JERK_MM_PER_S3: f64 = 1.0e9;
/// … and a corner-blending tolerance so small that the corner is sharp (mm).
const CONST_FEED_TOLERANCE_MM: f64 = 1.0e-5;

/// One reading of the paper's unstated units and reference.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reading {
    /// Short name.
    pub name: &'static str,
    /// What K means in this reading.
    pub k_unit: &'static str,
    /// Factor from the profile's K ((mm/min) per count) to this reading's K.
    pub gain_scale: f64,
    /// Reference without acceleration limits (velocity steps, sharp corner).
    pub const_feed: bool,
}

/// The readings, the project's own (the main table) first.
pub fn readings(machine: &MachineProfile) -> Vec<Reading> {
    // K·K_e as one loop gain in BLU/s per count: K · BLU mm/s instead of K/60 mm/s.
    let blu_mm = machine.axes[0].encoder_resolution_mm;
    let blu = S_PER_MIN * blu_mm;
    // K in (mm/s)/V and (mm/min)/V behind an 8-bit DAC of ±U volts: U/128 V per count.
    let [v10, v5] = DAC_FULL_SCALE_V.map(|u| u / DAC_HALF_COUNTS);
    let mut v = Vec::new();
    for const_feed in [false, true] {
        v.push(Reading {
            name: "mm/min per count",
            k_unit: "(mm/min)/count",
            gain_scale: 1.0,
            const_feed,
        });
        v.push(Reading {
            name: "BLU/s per count",
            k_unit: "(BLU/s)/count",
            gain_scale: blu,
            const_feed,
        });
    }
    v.push(Reading {
        name: "mm/s per V, ±5 V",
        k_unit: "(mm/s)/V, DAC ±5 V",
        gain_scale: S_PER_MIN * v5,
        const_feed: false,
    });
    v.push(Reading {
        name: "mm/s per V, ±10 V",
        k_unit: "(mm/s)/V, DAC ±10 V",
        gain_scale: S_PER_MIN * v10,
        const_feed: false,
    });
    v.push(Reading {
        name: "mm/min per V, ±10 V",
        k_unit: "(mm/min)/V, DAC ±10 V",
        gain_scale: v10,
        const_feed: false,
    });
    v
}

/// `base` as `reading` reads the paper: K scaled on every DC-motor axis, and for a
/// constant-feed reference the planner's limits lifted.
pub fn machine_for_reading(base: &MachineProfile, reading: &Reading) -> MachineProfile {
    let mut m = base.clone();
    for axis in m.servo.axes.iter_mut() {
        if let PlantModel::DcMotor {
            gain_mm_per_min_per_dac,
            ..
        } = &mut axis.plant
        {
            *gain_mm_per_min_per_dac *= reading.gain_scale;
        }
    }
    if reading.const_feed {
        for a in m.axes.iter_mut() {
            a.max_acc_mm_per_s2 = CONST_FEED_ACC_MM_PER_S2;
            a.max_jerk_mm_per_s3 = CONST_FEED_JERK_MM_PER_S3;
        }
        m.planner.tolerance_mm = CONST_FEED_TOLERANCE_MM;
    }
    m
}

/// Figures of one reading.
#[derive(Debug, Clone, PartialEq)]
pub struct ReadingResult {
    /// The reading.
    pub reading: Reading,
    /// K of X in mm/s per DAC count.
    pub k_x_mm_s_per_count: f64,
    /// Fastest X speed the DAC can drive against Coulomb friction, K·(limit − F_d(V≥12)).
    pub v_max_mm_s: f64,
    /// Fastest programmed feed of Table 5 (mm/s).
    pub v_needed_mm_s: f64,
    /// Radial error a type-2 loop leaves on the fast circle, a/K_a with a = V²/r and
    /// K_a = K·K_i/T (10 µm): Table 4's PID cannot do worse than this in steady state.
    pub circle_high_radial_10um: f64,
    /// Largest closed-loop pole radius of Table 4's PID on this reading's linear plant
    /// (no friction, no DAC): above 1 the PID loop is unstable.
    pub pid_pole_radius: f64,
    /// The six rows, when the feeds are reachable.
    pub rows: Option<Vec<Row>>,
}

impl ReadingResult {
    /// Cells (of 12) where the FLC is not worse than the PID.
    pub fn flc_not_worse(&self) -> Option<usize> {
        self.rows.as_ref().map(|rows| {
            rows.iter()
                .map(|r| (r.flc.max <= r.pid.max) as usize + (r.flc.rms <= r.pid.rms) as usize)
                .sum()
        })
    }
    /// Largest FLC/PID ratio over the 12 cells.
    pub fn worst_flc_over_pid(&self) -> Option<f64> {
        self.rows.as_ref().map(|rows| {
            rows.iter()
                .flat_map(|r| [r.flc.max / r.pid.max, r.flc.rms / r.pid.rms])
                .fold(0.0, f64::max)
        })
    }
    /// (min, max) of ours/paper over the PID cells, then over the FLC cells.
    pub fn paper_ratio_ranges(&self) -> Option<[(f64, f64); 2]> {
        self.rows.as_ref().map(|rows| {
            let range = |it: &mut dyn Iterator<Item = f64>| {
                it.fold((f64::INFINITY, 0.0f64), |(lo, hi), x| {
                    (lo.min(x), hi.max(x))
                })
            };
            let pid = range(
                &mut rows
                    .iter()
                    .flat_map(|r| [r.pid.max / r.case.paper[0], r.pid.rms / r.case.paper[2]]),
            );
            let flc = range(
                &mut rows
                    .iter()
                    .flat_map(|r| [r.flc.max / r.case.paper[1], r.flc.rms / r.case.paper[3]]),
            );
            [pid, flc]
        })
    }
}

/// Where the FLC actually worked in one case (both axes, all seeds).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VisitedRange {
    /// Case index into [`CASES`].
    pub case: usize,
    /// Share of cycles with |e| and |Δe| inside the innermost sets' centres (the rule
    /// cell ZR/PS × ZR/PS and its mirror images).
    pub inner_share: f64,
    /// Least-squares fit F(e, Δe) ≈ P·e + D·Δe over the visited cycles.
    pub p: f64,
    /// See `p`.
    pub d: f64,
}

/// The whole audit.
#[derive(Debug, Clone, PartialEq)]
pub struct Audit {
    /// One result per reading.
    pub readings: Vec<ReadingResult>,
    /// Eq 13's sector bounds and equivalent gains of the FLC (at the centres).
    pub equivalent: EquivalentGains,
    /// Table 4's PID gains (P, D) per BLU, from the profile.
    pub pid: (f64, f64),
    /// Per case, under the project's reading.
    pub visited: Vec<VisitedRange>,
}

/// Run every reading and the visited-range analysis.
pub fn audit(machine: &MachineProfile, flc: &FuzzyConfig, seeds: &[u64]) -> Result<Audit> {
    let v_needed = CASES
        .iter()
        .map(|c| c.feed_mm_min / S_PER_MIN)
        .fold(0.0, f64::max);
    let circle_high = CASES
        .iter()
        .find(|c| c.contour == "circle" && c.feed == "high")
        .expect("Table 5 has the fast circle");
    let servo = machine.axis_servo(0);
    let cycle_s = machine.interpolation_cycle_s;
    let mut results = Vec::new();
    for reading in readings(machine) {
        let m = machine_for_reading(machine, &reading);
        let PlantModel::DcMotor {
            gain_mm_per_min_per_dac,
            dac_limit,
            friction,
            ..
        } = m.axis_servo(0).plant
        else {
            return Err(ExperimentError::refused(
                "001 audit: axis X of the profile is not paper 001's DC motor",
            ));
        };
        let k = gain_mm_per_min_per_dac / S_PER_MIN;
        let PlantModel::DcMotor { tau_s, .. } = m.axis_servo(0).plant else {
            unreachable!("matched above")
        };
        let c = &servo.controller;
        let pid_pole_radius = pid_pole_radius(k, tau_s, cycle_s, [c.kp, c.ki, c.kd]);
        let v_max = k * (dac_limit - friction.pos_sat);
        let v = circle_high.feed_mm_min / S_PER_MIN;
        let acc = v * v / CIRCLE_RADIUS_MM;
        let k_a = k * servo.controller.ki / cycle_s;
        let rows = if v_max >= v_needed {
            Some(table(&m, flc, seeds)?)
        } else {
            None
        };
        results.push(ReadingResult {
            reading,
            k_x_mm_s_per_count: k,
            v_max_mm_s: v_max,
            v_needed_mm_s: v_needed,
            circle_high_radial_10um: acc / k_a * MM_TO_10UM,
            pid_pole_radius,
            rows,
        });
    }
    let ctl = FuzzyController::new(flc);
    let eq = ctl.equivalent_gains(SectorGrid::Centres);
    let unit = flc.input_unit_mm;
    let c_e = smallest_positive(&flc.e.centres);
    let c_de = smallest_positive(&flc.de.centres);
    let flc_machine = machine_for(machine, Stack::Flc, flc);
    let mut visited = Vec::new();
    for (ci, case) in CASES.iter().enumerate() {
        let prepared = prepare(case, machine)?;
        // normal equations (Σ x xᵀ) [P, D]ᵀ = Σ x F of F ≈ P e + D Δe, x = [e, Δe]ᵀ
        let mut normal = Matrix2::<f64>::zeros();
        let mut rhs = Vector2::<f64>::zeros();
        let (mut n, mut inner) = (0usize, 0usize);
        for &seed in seeds {
            let mut prev = [0.0f64; 2];
            run(&prepared, &flc_machine, seed, |t| {
                for (axis, p) in prev.iter_mut().enumerate() {
                    let e = t.following_mm[axis] / unit;
                    let de = e - *p;
                    *p = e;
                    let f = ctl.surface(e, de);
                    let x = Vector2::new(e, de);
                    normal += x * x.transpose();
                    rhs += x * f;
                    n += 1;
                    if e.abs() <= c_e && de.abs() <= c_de {
                        inner += 1;
                    }
                }
            })?;
        }
        // Σ x xᵀ is symmetric positive definite unless e and Δe never varied
        // independently; then the fit is undefined (NaN), as the printed table says
        let fit = normal
            .cholesky()
            .map_or(Vector2::repeat(f64::NAN), |c| c.solve(&rhs));
        visited.push(VisitedRange {
            case: ci,
            inner_share: inner as f64 / n.max(1) as f64,
            p: fit[0],
            d: fit[1],
        });
    }
    // the profile's PID gains are per mm; the paper's per BLU
    let per_blu = machine.axes[0].encoder_resolution_mm;
    Ok(Audit {
        readings: results,
        equivalent: eq,
        pid: (servo.controller.kp * per_blu, servo.controller.kd * per_blu),
        visited,
    })
}

/// Radius of Table 5's circle (mm), as in `examples/paper001/circle_*.ngc`.
const CIRCLE_RADIUS_MM: f64 = 20.0;
/// mm → the paper's unit, 10 µm.
const MM_TO_10UM: f64 = 100.0;

/// Largest closed-loop pole radius of the incremental PID (eq 14, gains per mm and
/// cycle) on the plant K/(s(τs + 1)) (K in mm/s per count) held by a zero-order hold
/// over `cycle_s`. Characteristic polynomial in z⁻¹:
/// (1 − z⁻¹)²(1 − a z⁻¹) + (b₁z⁻¹ + b₂z⁻²)(k_p + k_i + k_d − (k_p + 2k_d)z⁻¹ + k_d z⁻²),
/// a = e^{−T/τ}, b₁ = K(T − τ(1 − a)), b₂ = K(τ(1 − a) − aT). The radius is found by
/// bisection on ρ with the Schur–Cohn test of the polynomial scaled to z → ρz.
pub fn pid_pole_radius(
    k_mm_s_per_count: f64,
    tau_s: f64,
    cycle_s: f64,
    gains_per_mm: [f64; 3],
) -> f64 {
    let [kp, ki, kd] = gains_per_mm;
    let (k, t) = (k_mm_s_per_count, cycle_s);
    let a = (-t / tau_s).exp();
    let b1 = k * (t - tau_s * (1.0 - a));
    let b2 = k * (tau_s * (1.0 - a) - a * t);
    let open = poly_mul(&poly_mul(&[1.0, -1.0], &[1.0, -1.0]), &[1.0, -a]);
    let closed = poly_mul(&[0.0, b1, b2], &[kp + ki + kd, -(kp + 2.0 * kd), kd]);
    let c = poly_add(&open, &closed);
    let inside = |rho: f64| {
        let scaled: Vec<f64> = c
            .iter()
            .enumerate()
            .map(|(i, ci)| ci / rho.powi(i as i32))
            .collect();
        is_schur_stable(&scaled)
    };
    let (mut lo, mut hi) = (0.0, 1.0);
    while !inside(hi) {
        lo = hi;
        hi *= 2.0;
    }
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if inside(mid) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    hi
}

fn smallest_positive(centres: &[f64]) -> f64 {
    centres
        .iter()
        .copied()
        .filter(|c| *c > 0.0)
        .fold(f64::INFINITY, f64::min)
}

/// The audit as text.
pub fn to_text(a: &Audit) -> String {
    let mut s = String::from(
        "plant-reading audit (same seeds, same six cases; ref = reference: planner = profile's \
         acceleration limits, const = constant feed without acc/dec)\n",
    );
    s += "K reading               ref     K_x mm/s/cnt  v_max mm/s  PID |z|max  circle-high a/K_a | FLC<=PID  worst FLC/PID | PID/paper     FLC/paper\n";
    for r in &a.readings {
        let head = format!(
            "{:<23} {:<7} {:>12.4}  {:>10.1}  {:>10.3}  {:>17.2} |",
            r.reading.k_unit,
            if r.reading.const_feed {
                "const"
            } else {
                "planner"
            },
            r.k_x_mm_s_per_count,
            r.v_max_mm_s,
            r.pid_pole_radius,
            r.circle_high_radial_10um,
        );
        match (
            r.flc_not_worse(),
            r.worst_flc_over_pid(),
            r.paper_ratio_ranges(),
        ) {
            (Some(n), Some(w), Some([p, f])) => {
                s += &format!(
                    "{head} {n:>5}/12  {w:>13.2} | {:.2} .. {:.2}  {:.2} .. {:.2}\n",
                    p.0, p.1, f.0, f.1
                )
            }
            _ => {
                s += &format!(
                    "{head} not run: the DAC cannot drive the paper's {:.1} mm/s\n",
                    r.v_needed_mm_s
                )
            }
        }
    }
    s += "\nper reading, PID max/rms and FLC max/rms per row (10 µm):\n";
    for r in &a.readings {
        let Some(rows) = &r.rows else { continue };
        s += &format!(
            "{:<23} {:<7}",
            r.reading.k_unit,
            if r.reading.const_feed {
                "const"
            } else {
                "planner"
            }
        );
        for row in rows {
            s += &format!(
                " | {:.1}/{:.2} {:.1}/{:.2}",
                row.pid.max, row.pid.rms, row.flc.max, row.flc.rms
            );
        }
        s += "\n";
    }
    s += &format!(
        "\nFLC gains where it works (project's reading, FLC runs, X and Y, every cycle of the feed moves):\n\
         eq 13 sector bounds K1 {:.3} .. {:.3}, K2 {:.3} .. {:.3}: equivalent P {:.3}, D {:.3}; \
         Table 4 PID P {:.3}, D {:.3}\n",
        a.equivalent.k1_min,
        a.equivalent.k1_max,
        a.equivalent.k2_min,
        a.equivalent.k2_max,
        a.equivalent.p,
        a.equivalent.d,
        a.pid.0,
        a.pid.1
    );
    s += "contour feed  | inner cell share | fitted P  fitted D\n";
    for v in &a.visited {
        let c = &CASES[v.case];
        s += &format!(
            "{:<7} {:<4}  | {:>15.0}% | {:>8.3}  {:>8.3}\n",
            c.contour,
            c.feed,
            100.0 * v.inner_share,
            v.p,
            v.d
        );
    }
    s
}

/// The audit as JSON (the `audit` member of the 001 document).
pub fn to_json(a: &Audit) -> serde_json::Value {
    let r2 = |x: f64| (x * 100.0).round() / 100.0;
    serde_json::json!({
        "readings": a.readings.iter().map(|r| serde_json::json!({
            "k_unit": r.reading.k_unit,
            "reference": if r.reading.const_feed { "constant feed" } else { "planner" },
            "k_x_mm_s_per_count": (r.k_x_mm_s_per_count * 1e4).round() / 1e4,
            "v_max_mm_s": r2(r.v_max_mm_s),
            "circle_high_radial_10um": r2(r.circle_high_radial_10um),
            "pid_pole_radius": (r.pid_pole_radius * 1000.0).round() / 1000.0,
            "flc_not_worse_cells": r.flc_not_worse(),
            "worst_flc_over_pid": r.worst_flc_over_pid().map(r2),
            "rows": r.rows.as_ref().map(|rows| rows.iter().map(|row| serde_json::json!({
                "contour": row.case.contour,
                "feed": row.case.feed,
                "pid": {"max": r2(row.pid.max), "rms": r2(row.pid.rms)},
                "flc": {"max": r2(row.flc.max), "rms": r2(row.flc.rms)},
            })).collect::<Vec<_>>()),
        })).collect::<Vec<_>>(),
        "equivalent_gains": {
            "k1_min": a.equivalent.k1_min, "k1_max": a.equivalent.k1_max,
            "k2_min": a.equivalent.k2_min, "k2_max": a.equivalent.k2_max,
            "p": a.equivalent.p, "d": a.equivalent.d,
        },
        "pid_gains": {"p": a.pid.0, "d": a.pid.1},
        "visited": a.visited.iter().map(|v| serde_json::json!({
            "contour": CASES[v.case].contour,
            "feed": CASES[v.case].feed,
            "inner_share": r2(v.inner_share),
            "p": (v.p * 1000.0).round() / 1000.0,
            "d": (v.d * 1000.0).round() / 1000.0,
        })).collect::<Vec<_>>(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::workspace_file;

    #[test]
    fn readings_scale_k_and_lift_the_limits() {
        let m = MachineProfile::load(&workspace_file("config/machines/mill-friction.ron")).unwrap();
        let rs = readings(&m);
        assert_eq!(rs[0].gain_scale, 1.0);
        assert!(!rs[0].const_feed);
        let blu = rs.iter().find(|r| r.k_unit.starts_with("(BLU/s)")).unwrap();
        assert!((blu.gain_scale - 0.6).abs() < 1e-12);
        let mm = machine_for_reading(&m, blu);
        let PlantModel::DcMotor {
            gain_mm_per_min_per_dac,
            ..
        } = mm.axis_servo(1).plant
        else {
            panic!()
        };
        assert!((gain_mm_per_min_per_dac - 28.96 * 0.6).abs() < 1e-9);
        let c = rs.iter().find(|r| r.const_feed).unwrap();
        let mc = machine_for_reading(&m, c);
        assert_eq!(mc.axes[1].max_acc_mm_per_s2, CONST_FEED_ACC_MM_PER_S2);
    }

    /// The audit's finding on the FLC, which explains the negative result: where it
    /// works (mostly the innermost rule cell) its proportional gain is the PID's but
    /// its derivative gain is well below Table 4's 6.7. One seed keeps it fast.
    #[test]
    fn flc_works_with_the_pid_p_but_less_d() {
        let m = MachineProfile::load(&workspace_file("config/machines/mill-friction.ron")).unwrap();
        let f = FuzzyConfig::load(&workspace_file("config/fuzzy/paper001.ron")).unwrap();
        let a = audit(&m, &f, &[1]).unwrap();
        assert_eq!(a.readings.len(), readings(&m).len());
        assert!((a.equivalent.p - 2.381).abs() < 1e-3 && (a.equivalent.d - 6.667).abs() < 1e-3);
        assert_eq!(a.visited.len(), CASES.len());
        for v in &a.visited {
            let c = &CASES[v.case];
            assert!(v.inner_share > 0.75, "{} {}: {v:?}", c.contour, c.feed);
            assert!(v.p > 2.0 && v.p < 3.0, "{} {}: {v:?}", c.contour, c.feed);
            assert!(v.d < 0.75 * a.pid.1, "{} {}: {v:?}", c.contour, c.feed);
        }
        // Table 4's PID is stable on the project's reading, unstable with K in (mm/s)/V
        // behind a ±10 V DAC
        assert!(a.readings[0].pid_pole_radius < 1.0);
        let v10 = a
            .readings
            .iter()
            .find(|r| r.reading.k_unit == "(mm/s)/V, DAC ±10 V");
        assert!(v10.unwrap().pid_pole_radius > 1.0);
        // the (mm/min)/V reading cannot reach the paper's feeds and is not simulated
        let slow = a.readings.last().unwrap();
        assert!(slow.v_max_mm_s < slow.v_needed_mm_s && slow.rows.is_none());
    }

    #[test]
    fn pid_pole_radius_matches_an_independent_root_finder() {
        // Table 4 per mm (×100 BLU/mm) on K = 28.35 (mm/min)/count and on the ±10 V
        // reading; reference radii from a Durand–Kerner root finder on the same polynomial
        let g = [240.0, 10.0, 670.0];
        let r = pid_pole_radius(28.35 / 60.0, 0.055, 0.01, g);
        assert!((r - 0.95214).abs() < 2e-4, "{r}");
        let r = pid_pole_radius(28.35 * 10.0 / 128.0, 0.055, 0.01, g);
        assert!((r - 1.28678).abs() < 2e-4, "{r}");
    }
}
