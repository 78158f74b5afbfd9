//! Sensorless force measurement from the feed motor's phase currents (003 eq 25–32).

/// I_q from phase currents i_u, i_v (i_w = −i_u − i_v) and the electrical rotor angle
/// θ_e = n_p·θ (rad): Clarke (α, β) then Park rotation (003 eq 25–27).
pub fn park_iq(i_u: f64, i_v: f64, theta_e: f64) -> f64 {
    let alpha = i_u;
    let beta = (i_u + 2.0 * i_v) / 3f64.sqrt();
    -alpha * theta_e.sin() + beta * theta_e.cos()
}

/// Linear calibration I_q = a·F + b (003 eq 31–32), fitted by least squares.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ForceCalibration {
    /// Slope a (A/N).
    pub a_per_n: f64,
    /// Offset b (A): friction and no-load current.
    pub b_a: f64,
}

impl ForceCalibration {
    /// Fit from pairs (known force N, measured I_q A). `None` with fewer than two
    /// distinct forces.
    pub fn fit(pairs: &[(f64, f64)]) -> Option<Self> {
        let n = pairs.len() as f64;
        if pairs.len() < 2 {
            return None;
        }
        let (sf, si) = pairs
            .iter()
            .fold((0.0, 0.0), |(a, b), (f, i)| (a + f, b + i));
        let (mf, mi) = (sf / n, si / n);
        let sff: f64 = pairs.iter().map(|(f, _)| (f - mf) * (f - mf)).sum();
        if sff <= 0.0 {
            return None;
        }
        let sfi: f64 = pairs.iter().map(|(f, i)| (f - mf) * (i - mi)).sum();
        let a = sfi / sff;
        Some(ForceCalibration {
            a_per_n: a,
            b_a: mi - a * mf,
        })
    }

    /// Force (N) from I_q (A).
    pub fn force_n(&self, iq_a: f64) -> f64 {
        (iq_a - self.b_a) / self.a_per_n
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn balanced_currents_give_their_q_amplitude() {
        let amp = 3.0;
        for k in 0..50 {
            let th = k as f64 * 0.37;
            // currents of a pure q-axis current of `amp` at angle th
            let iu = -amp * th.sin();
            let iv = -amp * (th - 2.0 * std::f64::consts::PI / 3.0).sin();
            assert!((park_iq(iu, iv, th) - amp).abs() < 1e-12);
        }
    }

    #[test]
    fn calibration_recovers_the_papers_line() {
        let pairs: Vec<(f64, f64)> = (0..10)
            .map(|k| (k as f64 * 100.0, 0.00362 * k as f64 * 100.0 + 4.127))
            .collect();
        let c = ForceCalibration::fit(&pairs).unwrap();
        assert!((c.a_per_n - 0.00362).abs() < 1e-12 && (c.b_a - 4.127).abs() < 1e-9);
        assert!((c.force_n(0.00362 * 450.0 + 4.127) - 450.0).abs() < 1e-6);
    }
}
