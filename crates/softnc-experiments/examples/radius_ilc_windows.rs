//! Paper 004's radius ILC (eq 8–9, `softnc learn --law radius`) with other readings of
//! "y^k(i), the measured radius at angle i" and with a lead in the update, to see what
//! the stick spike after each axis reversal does under each (docs/reproduce-004.md,
//! "Why 90 % is not reached within 5 iterations").
//!
//! ```text
//! cargo run --release -p softnc-experiments --example radius_ilc_windows -- \
//!     [--feed 1000|2000] [--iterations N] [--window centred|after|before|point|command] \
//!     [--lead DEG] [--alpha A] [--trace DEG] [--machine PROFILE]
//! ```
//!
//! Windows (per degree point i, measured encoder positions from the first feed sample
//! to the end of the hold): `centred` the law's own (mean radius at output angles
//! within ±½° of i, [`Circle::radius_per_degree`]); `after` output angles in [i, i+1);
//! `before` in (i−1, i] (the arc eq 9 commands with r(i)); `point` the radius where the
//! output angle first crosses i (linear between samples); `command` the mean measured
//! radius while the *command* is within ±½° of i (time-aligned). `--lead d` corrects
//! r(i−d) with the error measured at i. Every row gives the RMS and max |e| of the
//! per-degree error in the `centred` window (the figures of `softnc reproduce 004-ilc`)
//! and in the window learnt from, and the largest |radius error| of any single sample.

use softnc_experiments::learning_runs::{find_circle, PreparedJob, HOLD_S};
use softnc_learning::radius_ilc::{Circle, RadiusIlc, POINTS};
use softnc_machine::MachineProfile;
use softnc_servo::SimulatedMachine;
use softnc_sim::{simulate_observed, simulated_engine, SimOptions};

#[derive(Debug, Clone, Copy, PartialEq)]
enum Window {
    Centred,
    After,
    Before,
    Point,
    Command,
}

struct Args {
    feed: u32,
    iterations: usize,
    window: Window,
    lead: usize,
    alpha: f64,
    trace: Option<usize>,
    machine: String,
}

fn parse() -> Result<Args, String> {
    let mut a = Args {
        feed: 1000,
        iterations: 5,
        window: Window::Centred,
        lead: 0,
        alpha: 1.0,
        trace: None,
        machine: "config/machines/tnv40-ilc.ron".into(),
    };
    let mut it = std::env::args().skip(1);
    while let Some(k) = it.next() {
        let v = it.next().ok_or_else(|| format!("{k}: value missing"))?;
        let bad = || format!("{k}: bad value {v}");
        match k.as_str() {
            "--feed" => a.feed = v.parse().map_err(|_| bad())?,
            "--iterations" => a.iterations = v.parse().map_err(|_| bad())?,
            "--lead" => a.lead = v.parse().map_err(|_| bad())?,
            "--alpha" => a.alpha = v.parse().map_err(|_| bad())?,
            "--trace" => a.trace = Some(v.parse().map_err(|_| bad())?),
            "--machine" => a.machine = v,
            "--window" => {
                a.window = match v.as_str() {
                    "centred" => Window::Centred,
                    "after" => Window::After,
                    "before" => Window::Before,
                    "point" => Window::Point,
                    "command" => Window::Command,
                    _ => return Err(format!("--window: unknown {v}")),
                }
            }
            _ => return Err(format!("unknown option {k}")),
        }
    }
    if a.feed != 1000 && a.feed != 2000 {
        return Err("--feed: 1000 or 2000 (examples/learning/circle-r50-f*.ngc)".into());
    }
    if a.lead >= POINTS || a.trace.is_some_and(|t| t >= POINTS) {
        return Err("--lead and --trace are degrees below 360".into());
    }
    Ok(a)
}

/// Mean radius per degree of the samples whose degree (from `deg`) rounds to i.
fn binned(c: &Circle, xy: &[[f64; 2]], deg: impl Fn(usize) -> f64) -> Vec<f64> {
    let mut sum = vec![0.0; POINTS];
    let mut n = vec![0usize; POINTS];
    for (k, p) in xy.iter().enumerate() {
        let i = deg(k).round().rem_euclid(POINTS as f64) as usize % POINTS;
        sum[i] += c.radius_of(*p);
        n[i] += 1;
    }
    (0..POINTS)
        .map(|i| {
            if n[i] > 0 {
                sum[i] / n[i] as f64
            } else {
                f64::NAN
            }
        })
        .collect()
}

/// Radius where the output angle (unwrapped from the start) first crosses each point.
fn crossings(c: &Circle, xy: &[[f64; 2]]) -> Vec<f64> {
    let mut out = vec![f64::NAN; POINTS];
    let (mut turns, mut last) = (0.0, 0.0);
    let mut prev: Option<(f64, f64)> = None;
    for p in xy {
        let mut a = c.degrees_from_start(*p) + turns;
        if a < last - 180.0 {
            turns += 360.0;
            a += 360.0;
        }
        last = a;
        let r = c.radius_of(*p);
        if let Some((pa, pr)) = prev {
            if a > pa {
                let mut i = pa.ceil();
                while i <= a {
                    let k = (i as usize) % POINTS;
                    if out[k].is_nan() {
                        out[k] = pr + (r - pr) * (i - pa) / (a - pa);
                    }
                    i += 1.0;
                }
            }
        }
        prev = Some((a, r));
    }
    out
}

fn rms_max_um(y: &[f64], r_d: f64) -> (f64, f64) {
    let e: Vec<f64> = y
        .iter()
        .filter(|v| v.is_finite())
        .map(|v| (v - r_d) * 1e3)
        .collect();
    let rms = (e.iter().map(|v| v * v).sum::<f64>() / e.len().max(1) as f64).sqrt();
    (rms, e.iter().fold(0.0f64, |m, v| m.max(v.abs())))
}

fn main() -> Result<(), String> {
    let a = parse()?;
    let root = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    let machine = MachineProfile::load(&root.join(&a.machine)).map_err(|e| e.to_string())?;
    let file = format!("examples/learning/circle-r50-f{}.ngc", a.feed);
    let text = std::fs::read_to_string(root.join(&file)).map_err(|e| format!("{file}: {e}"))?;
    let (circle, r_d) = find_circle(&text, &file, &machine)?;
    let mut engine = simulated_engine(&machine, machine.servo.seed, SimOptions::default());
    let mut ilc = RadiusIlc::new(r_d, a.alpha);
    println!(
        "{file}, window {:?}, lead {}°, α = {} (µm; centred = the figures of softnc reproduce 004-ilc)",
        a.window, a.lead, a.alpha
    );
    println!("iteration  rms(centred) max|e|(centred)  rms(window) max|e|(window)  sample peak");
    let mut learnt: Option<Vec<f64>> = None;
    for it in 0..=a.iterations {
        if let Some(y) = &learnt {
            // r(i − lead) += α (r_d − y(i)); a point the window missed learns nothing
            let shifted: Vec<f64> = (0..POINTS)
                .map(|j| y[(j + a.lead) % POINTS])
                .map(|v| if v.is_finite() { v } else { r_d })
                .collect();
            ilc.update(&shifted);
        }
        let prog = ilc.program(&circle, "radius_ilc_windows", HOLD_S);
        let job = PreparedJob::new(&prog, "radius-ilc.ngc", &machine)?;
        let first = job
            .samples
            .iter()
            .position(|s| s.feed_move)
            .ok_or("no feed move")?;
        // measured positions (one per sample: this profile has no command filter) and
        // whether X or Y was held by static friction in that cycle
        let mut measured: Vec<[f64; 2]> = Vec::with_capacity(job.samples.len());
        let mut held: Vec<bool> = Vec::with_capacity(job.samples.len());
        simulate_observed(
            &mut engine,
            job.cycle_s,
            job.samples.iter().copied(),
            |m| job.prims.get(m as usize).copied().flatten(),
            |row, e| {
                measured.push([row.record.actual_mm[0], row.record.actual_mm[1]]);
                let b = e.backend();
                held.push(b.stuck(0) || b.stuck(1));
            },
        )
        .map_err(|e| format!("servo backend: {e}"))?;
        measured.truncate(job.samples.len());
        let xy: Vec<[f64; 2]> = measured[first..].to_vec();
        let held = &held[first..];
        let cmd: Vec<[f64; 2]> = job.samples[first..]
            .iter()
            .map(|s| [s.pos_mm[0], s.pos_mm[1]])
            .collect();
        let centred = circle.radius_per_degree(&xy);
        let y = match a.window {
            Window::Centred => centred.clone(),
            Window::After => binned(&circle, &xy, |k| circle.degrees_from_start(xy[k]) - 0.5),
            Window::Before => binned(&circle, &xy, |k| circle.degrees_from_start(xy[k]) + 0.5),
            Window::Point => crossings(&circle, &xy),
            Window::Command => binned(&circle, &xy, |k| circle.degrees_from_start(cmd[k])),
        };
        let (rc, mc) = rms_max_um(&centred, r_d);
        let (rw, mw) = rms_max_um(&y, r_d);
        let peak = xy
            .iter()
            .map(|p| (circle.radius_of(*p) - r_d).abs() * 1e3)
            .fold(0.0, f64::max);
        println!("{it:>9} {rc:>13.2} {mc:>16.2} {rw:>12.2} {mw:>14.2} {peak:>12.2}");
        if let Some(t) = a.trace {
            let pts = (t..t + 4).map(|i| i % POINTS);
            let r: Vec<String> = pts
                .clone()
                .map(|i| format!("{:.1}", (ilc.radius_mm[i] - r_d) * 1e3))
                .collect();
            let e: Vec<String> = pts.map(|i| format!("{:.2}", (y[i] - r_d) * 1e3)).collect();
            // the hold after the reversal at t: first and last held cycle with the
            // command within (t − 1, t + 5)° of the start
            let near = |k: usize| {
                let d = circle.degrees_from_start(cmd[k]);
                d > t as f64 - 1.0 && d < t as f64 + 5.0
            };
            let ks: Vec<usize> = (0..held.len()).filter(|&k| held[k] && near(k)).collect();
            let hold = match (ks.first(), ks.last()) {
                (Some(&k0), Some(&k1)) => format!(
                    "held {:.0} ms, output at {:.2}..{:.2}°, command at {:.2}..{:.2}°",
                    (k1 + 1 - k0) as f64 * job.cycle_s * 1e3,
                    circle.degrees_from_start(xy[k0]),
                    circle.degrees_from_start(xy[k1]),
                    circle.degrees_from_start(cmd[k0]),
                    circle.degrees_from_start(cmd[k1])
                ),
                _ => "not held".into(),
            };
            println!(
                "          degrees {t}..{}: r − r_d [{}], error [{}]; {hold}",
                t + 3,
                r.join(", "),
                e.join(", ")
            );
        }
        learnt = Some(y);
    }
    Ok(())
}
