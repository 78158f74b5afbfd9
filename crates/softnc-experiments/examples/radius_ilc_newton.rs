//! A diagnostic for paper 004's radius ILC, not a law: how far would a Newton step on
//! the per-degree radius error go in 5 iterations if the response of every degree to
//! every command were known? At each iteration the Jacobian J(i, j) = ∂e(i)/∂r(j),
//! |i − j| ≤ `--band`, is measured by one perturbation run per degree (`--perturb-um`
//! on r(j) alone; 360 runs an iteration, none counted as a learning iteration), and the
//! step is Levenberg–Marquardt's, (JᵀJ + λI) Δr = −Jᵀe (the plain Newton step, λ = 0,
//! diverges: eq 9's arc averaging makes J nearly singular for alternating patterns).
//! docs/reproduce-004.md, "Per-degree adaptive gains (beyond the paper)".
//!
//! ```text
//! cargo run --release -p softnc-experiments --example radius_ilc_newton -- \
//!     [--feed 1000|2000] [--perturb-um D] [--band B] [--lambda L] [--iterations N]
//! ```

use softnc_experiments::learning_runs::{find_circle, radius_stats, run_circle};
use softnc_learning::radius_ilc::{RadiusIlc, POINTS};
use softnc_machine::MachineProfile;
use softnc_sim::{simulated_engine, SimOptions};

/// Solve `m x = b` (n×n, row-major) by Gaussian elimination with partial pivoting.
fn solve(mut m: Vec<f64>, mut b: Vec<f64>) -> Option<Vec<f64>> {
    let n = b.len();
    for c in 0..n {
        let p = (c..n).max_by(|&x, &y| m[x * n + c].abs().total_cmp(&m[y * n + c].abs()))?;
        if m[p * n + c].abs() < f64::EPSILON {
            return None;
        }
        if p != c {
            for k in 0..n {
                m.swap(p * n + k, c * n + k);
            }
            b.swap(p, c);
        }
        for r in c + 1..n {
            let f = m[r * n + c] / m[c * n + c];
            for k in c..n {
                m[r * n + k] -= f * m[c * n + k];
            }
            b[r] -= f * b[c];
        }
    }
    let mut x = vec![0.0; n];
    for r in (0..n).rev() {
        let s: f64 = (r + 1..n).map(|k| m[r * n + k] * x[k]).sum();
        x[r] = (b[r] - s) / m[r * n + r];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

fn main() -> Result<(), String> {
    let (mut feed, mut perturb_um, mut band, mut lambda, mut iterations) =
        (1000u32, -5.0f64, 3usize, 0.01f64, 5usize);
    let mut it = std::env::args().skip(1);
    while let Some(k) = it.next() {
        let v = it.next().ok_or_else(|| format!("{k}: value missing"))?;
        let bad = || format!("{k}: bad value {v}");
        match k.as_str() {
            "--feed" => feed = v.parse().map_err(|_| bad())?,
            "--perturb-um" => perturb_um = v.parse().map_err(|_| bad())?,
            "--band" => band = v.parse().map_err(|_| bad())?,
            "--lambda" => lambda = v.parse().map_err(|_| bad())?,
            "--iterations" => iterations = v.parse().map_err(|_| bad())?,
            _ => return Err(format!("unknown option {k}")),
        }
    }
    if perturb_um == 0.0 || !perturb_um.is_finite() {
        return Err("--perturb-um: a non-zero number".into());
    }
    let root = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    let m = MachineProfile::load(&root.join("config/machines/tnv40-ilc.ron"))
        .map_err(|e| e.to_string())?;
    let file = format!("examples/learning/circle-r50-f{feed}.ngc");
    let text = std::fs::read_to_string(root.join(&file)).map_err(|e| format!("{file}: {e}"))?;
    let (circle, r_d) = find_circle(&text, &file, &m)?;
    let mut engine = simulated_engine(&m, m.servo.seed, SimOptions::default());
    let mut ilc = RadiusIlc::new(r_d, 1.0);
    let n = POINTS;
    let d_mm = perturb_um * 1e-3;
    println!("{file}: Levenberg–Marquardt with the measured Jacobian (band {band}, λ {lambda})");
    for k in 0..=iterations {
        let y = run_circle(&mut engine, &m, &circle, &ilc, "radius_ilc_newton")?;
        let e: Vec<f64> = y.iter().map(|v| v - r_d).collect();
        let st = radius_stats(k, &e);
        println!(
            "iteration {k}: RMS {:.3} µm, max |e| {:.2} µm ({} perturbation runs so far)",
            st.rms_um,
            st.max_abs_um,
            k * n
        );
        if k == iterations {
            break;
        }
        let mut jac = vec![0.0; n * n];
        for j in 0..n {
            let mut p = ilc.clone();
            p.radius_mm[j] += d_mm;
            let yp = run_circle(&mut engine, &m, &circle, &p, "radius_ilc_newton")?;
            for i in 0..n {
                if ((i + n - j) % n).min((j + n - i) % n) <= band {
                    jac[i * n + j] = (yp[i] - y[i]) / d_mm;
                }
            }
        }
        let mut jtj = vec![0.0; n * n];
        let mut rhs = vec![0.0; n];
        for a in 0..n {
            for b in 0..n {
                jtj[a * n + b] = (0..n).map(|r| jac[r * n + a] * jac[r * n + b]).sum();
            }
            jtj[a * n + a] += lambda;
            rhs[a] = -(0..n).map(|r| jac[r * n + a] * e[r]).sum::<f64>();
        }
        let step = solve(jtj, rhs).ok_or("singular normal equations")?;
        for (r, s) in ilc.radius_mm.iter_mut().zip(step) {
            *r += s;
        }
    }
    Ok(())
}
