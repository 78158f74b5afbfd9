//! Davison's robust servo controller in discrete time (003 eq 13–22) with the gains
//! chosen so that the four closed-loop poles sit exactly where asked.
//!
//! Plant (eq 10, observable form): x(t+1) = Φx + Γv, f = C_m x, with
//! Φ = [[0, −φ₂], [1, −φ₁]], Γ = [θ₂, θ₁]ᵀ, C_m = [0, 1].
//! Servo compensator (eq 14): η(t+1) = η(t) + T_s·(f(t) − f*(t)).
//! Stabilising compensator (eq 16): ε(t+1) = r₀ε(t) + r₁f(t) + r₂η(t).
//! Feedback (eq 17): v(t) = kη(t) + r₃f(t) + r₄ε(t).
//!
//! **Pole placement.** The loop is the plant B/A (A = z² + φ₁z + φ₂, B = θ₁z + θ₂)
//! under the dynamic output feedback v/f = P(z)/((z − 1)(z − r₀)) with
//! P(z) = T_s(k(z − r₀) + r₄r₂) + (z − 1)(r₃(z − r₀) + r₄r₁) = p₂z² + p₁z + p₀, so the
//! closed-loop characteristic polynomial is A(z)(z − 1)(z − r₀) − B(z)P(z). Matching
//! it to the desired D(z) = Π(z − zᵢ) gives four equations *linear* in (r₀, p₂, p₁, p₀)
//! — solvable exactly whenever A(z)(z − 1) and B(z) have no common root, i.e. the
//! plant is controllable and no transmission zero sits at z = 1 (the paper's
//! conditions 2 and 4). The six gains follow with the compensator's free scale fixed
//! by r₄ = 1 and r₁ = 0: r₃ = p₂, k = (p₁ + r₃(r₀ + 1))/T_s, r₂ = (p₀ − r₃r₀)/T_s + k·r₀.
//! (The paper uses Fahmy–O'Reilly eigenstructure assignment; any exact placement is
//! acceptable, and this one needs a 4×4 linear solve per control sample: an LU
//! decomposition with partial pivoting of nalgebra's fixed-size [`Matrix4`], which
//! allocates nothing.)

use crate::zoh::Arma2;
use nalgebra::{Matrix4, Vector4};

/// A pivot smaller than this times the largest entry of the placement matrix makes it
/// singular: A(z)(z − 1) and B(z) (nearly) share a root.
const SINGULAR_PIVOT_RATIO: f64 = 1e-12;

/// The six gains K = [k, r₀, r₁, r₂, r₃, r₄] (eq 22).
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct ServoGains {
    /// k.
    pub k: f64,
    /// r₀.
    pub r0: f64,
    /// r₁.
    pub r1: f64,
    /// r₂.
    pub r2: f64,
    /// r₃.
    pub r3: f64,
    /// r₄.
    pub r4: f64,
}

/// Why the poles cannot be placed.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum PlacementError {
    /// A(z)(z − 1) and B(z) share a root: uncontrollable, or a zero at z = 1.
    #[error(
        "the model is not controllable with an integrator (common root of A(z)(z-1) and B(z))"
    )]
    Uncontrollable,
    /// A requested pole lies outside the unit circle.
    #[error("requested pole {0} is not inside the unit circle")]
    UnstablePole(f64),
}

/// Gains placing the closed-loop poles at `poles` for `model` at sample time `t_s`.
pub fn place_poles(model: &Arma2, poles: [f64; 4], t_s: f64) -> Result<ServoGains, PlacementError> {
    if let Some(&p) = poles.iter().find(|p| p.abs() >= 1.0 || !p.is_finite()) {
        return Err(PlacementError::UnstablePole(p));
    }
    // D(z) = z⁴ + d3 z³ + d2 z² + d1 z + d0
    let [_, d3, d2, d1, d0] = poly_from_roots(poles);
    let (phi1, phi2, th1, th2) = (model.phi1, model.phi2, model.theta1, model.theta2);
    // Q(z) = A(z)(z − 1) = z³ + q2 z² + q1 z + q0
    let (q2, q1, q0) = (phi1 - 1.0, phi2 - phi1, -phi2);
    // A(z)(z − 1)(z − r₀) − B(z)P(z) = D(z), coefficient by coefficient, in (r₀, p₂, p₁, p₀)
    #[rustfmt::skip]
    let m = Matrix4::new(
        -1.0, -th1,  0.0,  0.0,
        -q2,  -th2, -th1,  0.0,
        -q1,   0.0, -th2, -th1,
        -q0,   0.0,  0.0, -th2,
    );
    let rhs = Vector4::new(d3 - q2, d2 - q1, d1 - q0, d0);
    let scale = m.amax().max(f64::MIN_POSITIVE);
    let lu = m.lu();
    if lu
        .u()
        .diagonal()
        .iter()
        .any(|p| p.abs() < SINGULAR_PIVOT_RATIO * scale)
    {
        return Err(PlacementError::Uncontrollable);
    }
    let x = lu.solve(&rhs).ok_or(PlacementError::Uncontrollable)?;
    let (r0, p2, p1, p0) = (x[0], x[1], x[2], x[3]);
    let (r1, r4) = (0.0, 1.0);
    let r3 = p2;
    let k = (p1 + r3 * (r0 + 1.0)) / t_s;
    let r2 = (p0 - r3 * r0) / t_s + k * r0;
    Ok(ServoGains {
        k,
        r0,
        r1,
        r2,
        r3,
        r4,
    })
}

/// The closed-loop matrix Φ̄(K) of eq 20 for state [x₁, x₂, η, ε].
pub fn closed_loop_matrix(model: &Arma2, g: &ServoGains, t_s: f64) -> Matrix4<f64> {
    // Φ = [[0, −φ₂], [1, −φ₁]], Γ = [θ₂, θ₁]ᵀ, C_m = [0, 1]
    let (gamma1, gamma2) = (model.theta2, model.theta1);
    #[rustfmt::skip]
    let a = Matrix4::new(
        0.0, -model.phi2 + gamma1 * g.r3, gamma1 * g.k, gamma1 * g.r4,
        1.0, -model.phi1 + gamma2 * g.r3, gamma2 * g.k, gamma2 * g.r4,
        0.0, t_s,                         1.0,          0.0,
        0.0, g.r1,                        g.r2,         g.r0,
    );
    a
}

/// Characteristic polynomial det(zI − A) of a 4×4 matrix, highest power first
/// (Faddeev–LeVerrier): checks that placed poles are the closed loop's eigenvalues.
pub fn characteristic_polynomial(a: &Matrix4<f64>) -> [f64; 5] {
    let mut c = [1.0, 0.0, 0.0, 0.0, 0.0];
    let mut m = Matrix4::zeros();
    for k in 1..=4 {
        // M_k = A M_{k−1} + c_{k−1} I,  c_k = −tr(A M_k)/k
        let mk = a * m + Matrix4::from_diagonal_element(c[k - 1]);
        c[k] = -(a * mk).trace() / k as f64;
        m = mk;
    }
    c
}

/// Π(z − pᵢ), highest power first.
pub fn poly_from_roots(poles: [f64; 4]) -> [f64; 5] {
    let mut d = [1.0, 0.0, 0.0, 0.0, 0.0];
    for p in poles {
        let mut nd = [0.0; 5];
        for i in 0..5 {
            nd[i] += d[i];
            if i + 1 < 5 {
                nd[i + 1] -= p * d[i];
            }
        }
        d = nd;
    }
    d
}

/// The robust servo's state and one step per control sample.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RobustServo {
    /// Servo compensator state η.
    pub eta: f64,
    /// Stabilising compensator state ε.
    pub eps: f64,
}

impl RobustServo {
    /// Control v(t) from the measured f(t) and the reference f*(t); advances η and ε
    /// (eq 14–17).
    pub fn step(&mut self, g: &ServoGains, f: f64, f_ref: f64, t_s: f64) -> f64 {
        let v = g.k * self.eta + g.r3 * f + g.r4 * self.eps;
        let eps_next = g.r0 * self.eps + g.r1 * f + g.r2 * self.eta;
        self.eta += t_s * (f - f_ref);
        self.eps = eps_next;
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::zoh::zoh_second_order;

    #[test]
    fn placed_poles_are_the_closed_loop_eigenvalues() {
        let t_s = 0.1;
        for (gain, ts, tc) in [(2.0, 0.05, 0.3), (0.8, 0.12, 0.05), (5.0, 0.07, 0.07)] {
            let m = zoh_second_order(gain, ts, tc, t_s);
            for poles in [[0.4, 0.45, 0.65, 0.7], [0.3, 0.35, 0.7, 0.75]] {
                let g = place_poles(&m, poles, t_s).unwrap();
                let a = closed_loop_matrix(&m, &g, t_s);
                let cp = characteristic_polynomial(&a);
                for p in poles {
                    let v = cp.iter().fold(0.0, |acc, c| acc * p + c);
                    // |det(pI − Φ̄)| / scale: each requested pole is an eigenvalue
                    assert!(v.abs() < 1e-9, "pole {p}: charpoly {v}");
                }
                let want = poly_from_roots(poles);
                for (x, y) in cp.iter().zip(want) {
                    assert!((x - y).abs() < 1e-6, "{cp:?} vs {want:?}");
                }
            }
        }
    }

    #[test]
    fn closed_loop_tracks_a_constant_reference_without_error() {
        let t_s = 0.1;
        let m = zoh_second_order(3.0, 0.05, 0.25, t_s);
        let g = place_poles(&m, [0.4, 0.45, 0.65, 0.7], t_s).unwrap();
        let mut servo = RobustServo::default();
        let (mut y1, mut y2, mut u1, mut u2) = (0.0, 0.0, 0.0, 0.0);
        let f_ref = 450.0;
        let mut y = 0.0;
        for _ in 0..200 {
            y = -m.phi1 * y1 - m.phi2 * y2 + m.theta1 * u1 + m.theta2 * u2;
            let u = servo.step(&g, y, f_ref, t_s);
            (y2, y1, u2, u1) = (y1, y, u1, u);
        }
        assert!((y - f_ref).abs() < 1e-6, "settled at {y}");
    }

    #[test]
    fn refuses_unstable_poles_and_uncontrollable_models() {
        let m = zoh_second_order(3.0, 0.05, 0.25, 0.1);
        assert!(matches!(
            place_poles(&m, [0.4, 1.2, 0.5, 0.5], 0.1),
            Err(PlacementError::UnstablePole(_))
        ));
        let dead = Arma2 {
            phi1: -0.5,
            phi2: 0.0,
            theta1: 0.0,
            theta2: 0.0,
        };
        assert_eq!(
            place_poles(&dead, [0.4, 0.45, 0.65, 0.7], 0.1),
            Err(PlacementError::Uncontrollable)
        );
    }
}
