//! Iterative learning of the command radius of a circle (paper 004, eq 8–9).
//!
//! The circle is cut into one-degree arc commands. After each run the radius actually
//! made is measured per degree, y^k(i), and the command radius corrected:
//!
//!   r^{k+1}(i) = r^k(i) + α (r^d − y^k(i))                                (004 eq 8)
//!
//! and the arc from point i−1 to point i is commanded with the mean of its two end
//! radii, ½ (r^{k+1}(i) + r^{k+1}(i−1))                                    (004 eq 9).

/// Per-degree command radii of one circle.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RadiusIlc {
    /// Desired radius r^d (mm).
    pub desired_mm: f64,
    /// Learning rate α.
    pub alpha: f64,
    /// Command radius at each degree point, r^k(i), i = 0..360 (mm).
    pub radius_mm: Vec<f64>,
}

/// Points (degrees) a circle is cut into.
pub const POINTS: usize = 360;

impl RadiusIlc {
    /// Start with the desired radius everywhere.
    pub fn new(desired_mm: f64, alpha: f64) -> Self {
        RadiusIlc {
            desired_mm,
            alpha,
            radius_mm: vec![desired_mm; POINTS],
        }
    }

    /// Eq 8 with the measured radius per degree.
    pub fn update(&mut self, measured_mm: &[f64]) {
        for (r, y) in self.radius_mm.iter_mut().zip(measured_mm) {
            *r += self.alpha * (self.desired_mm - y);
        }
    }

    /// Eq 9: the radius to command for the arc ending at degree point `i`.
    pub fn arc_radius_mm(&self, i: usize) -> f64 {
        let prev = (i + POINTS - 1) % POINTS;
        0.5 * (self.radius_mm[i % POINTS] + self.radius_mm[prev])
    }
}

/// Where a learnt circle lies: centre, start angle, direction, feed.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Circle {
    /// Centre X, Y (mm).
    pub center_mm: [f64; 2],
    /// Height of the circle's plane (mm).
    pub z_mm: f64,
    /// Angle of the start point about the centre (rad).
    pub start_rad: f64,
    /// Counter-clockwise (G3) or clockwise (G2).
    pub ccw: bool,
    /// Feed (mm/min).
    pub feed_mm_per_min: f64,
}

impl Circle {
    /// Angle of degree point `i` (rad).
    pub fn point_angle_rad(&self, i: usize) -> f64 {
        let dir = if self.ccw { 1.0 } else { -1.0 };
        self.start_rad + dir * (i as f64).to_radians()
    }

    /// Degrees travelled from the start to the direction of `xy` from the centre,
    /// in [0, 360).
    pub fn degrees_from_start(&self, xy: [f64; 2]) -> f64 {
        let a = (xy[1] - self.center_mm[1]).atan2(xy[0] - self.center_mm[0]);
        let d = if self.ccw {
            a - self.start_rad
        } else {
            self.start_rad - a
        };
        d.to_degrees().rem_euclid(360.0)
    }

    /// Radius of `xy` about the centre (mm).
    pub fn radius_of(&self, xy: [f64; 2]) -> f64 {
        (xy[0] - self.center_mm[0]).hypot(xy[1] - self.center_mm[1])
    }

    /// The measured radius per degree point y(i), i = 0..360: the mean radius of the
    /// samples within ±½° of point i; points no sample reached are interpolated from
    /// their nearest measured neighbours (around the circle).
    pub fn radius_per_degree(&self, xy_mm: &[[f64; 2]]) -> Vec<f64> {
        let mut sum = vec![0.0; POINTS];
        let mut n = vec![0usize; POINTS];
        for &p in xy_mm {
            let i = self.degrees_from_start(p).round() as usize % POINTS;
            sum[i] += self.radius_of(p);
            n[i] += 1;
        }
        let measured: Vec<usize> = (0..POINTS).filter(|&i| n[i] > 0).collect();
        let mut out: Vec<f64> = (0..POINTS)
            .map(|i| {
                if n[i] > 0 {
                    sum[i] / n[i] as f64
                } else {
                    f64::NAN
                }
            })
            .collect();
        if measured.is_empty() {
            return out;
        }
        for i in 0..POINTS {
            if n[i] > 0 {
                continue;
            }
            // nearest measured point before and after i, around the circle
            let before = (1..POINTS)
                .map(|d| (i + POINTS - d) % POINTS)
                .find(|&j| n[j] > 0);
            let after = (1..POINTS).map(|d| (i + d) % POINTS).find(|&j| n[j] > 0);
            if let (Some(b), Some(a)) = (before, after) {
                let db = ((i + POINTS - b) % POINTS) as f64;
                let da = ((a + POINTS - i) % POINTS) as f64;
                let (yb, ya) = (sum[b] / n[b] as f64, sum[a] / n[a] as f64);
                out[i] = yb + (ya - yb) * db / (db + da);
            }
        }
        out
    }
}

impl RadiusIlc {
    /// The circle as 360 one-degree arc commands (G-code): the arc to degree point i
    /// ends at radius r(i) and is commanded with eq 9's radius ½ (r(i) + r(i−1)).
    /// The machine dwells `dwell_s` at the start point first, so the circle starts at
    /// rest there.
    pub fn program(&self, circle: &Circle, title: &str, dwell_s: f64) -> String {
        use std::fmt::Write;
        let point = |i: usize| {
            let a = circle.point_angle_rad(i);
            let r = self.radius_mm[i % POINTS];
            [
                circle.center_mm[0] + r * a.cos(),
                circle.center_mm[1] + r * a.sin(),
            ]
        };
        let g = if circle.ccw { "G3" } else { "G2" };
        let mut s = String::new();
        let p0 = point(0);
        let _ = writeln!(s, "({title})");
        let _ = writeln!(s, "G21 G90 G17 G94");
        let _ = writeln!(s, "G0 X{:.6} Y{:.6} Z{:.6}", p0[0], p0[1], circle.z_mm);
        if dwell_s > 0.0 {
            let _ = writeln!(s, "G4 P{dwell_s}");
        }
        for i in 1..=POINTS {
            let p = point(i);
            let _ = write!(
                s,
                "{g} X{:.6} Y{:.6} R{:.6}",
                p[0],
                p[1],
                self.arc_radius_mm(i)
            );
            if i == 1 {
                let _ = write!(s, " F{}", circle.feed_mm_per_min);
            }
            s.push('\n');
        }
        s.push_str("M2\n");
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constant_shrink_is_learnt_away_in_one_step_with_alpha_one() {
        let mut ilc = RadiusIlc::new(50.0, 1.0);
        // a servo that makes every radius 31 µm too small
        let measured: Vec<f64> = ilc.radius_mm.iter().map(|r| r - 0.031).collect();
        ilc.update(&measured);
        let next: Vec<f64> = ilc.radius_mm.iter().map(|r| r - 0.031).collect();
        assert!(next.iter().all(|y| (y - 50.0).abs() < 1e-12));
        assert!((ilc.arc_radius_mm(0) - 50.031).abs() < 1e-12);
    }

    fn circle(ccw: bool) -> Circle {
        Circle {
            center_mm: [1.0, 2.0],
            z_mm: 0.0,
            start_rad: 0.3,
            ccw,
            feed_mm_per_min: 1000.0,
        }
    }

    #[test]
    fn radius_per_degree_bins_and_fills_gaps() {
        for ccw in [true, false] {
            let c = circle(ccw);
            // samples only at even degrees, radius 50 + i/1000 at degree i
            let pts: Vec<[f64; 2]> = (0..POINTS)
                .step_by(2)
                .map(|i| {
                    let a = c.point_angle_rad(i);
                    let r = 50.0 + i as f64 / 1000.0;
                    [1.0 + r * a.cos(), 2.0 + r * a.sin()]
                })
                .collect();
            let y = c.radius_per_degree(&pts);
            assert!((y[10] - 50.010).abs() < 1e-9, "{}", y[10]);
            assert!((y[11] - 50.011).abs() < 1e-9, "interpolated {}", y[11]);
            // 359 lies between 358 and 0 (around the circle)
            assert!((y[359] - 0.5 * (50.358 + 50.0)).abs() < 1e-9, "{}", y[359]);
        }
    }

    #[test]
    fn program_has_360_one_degree_arcs_with_eq9_radii() {
        let mut ilc = RadiusIlc::new(50.0, 1.0);
        ilc.radius_mm[5] = 50.01;
        let text = ilc.program(&circle(true), "t", 0.5);
        assert!(text.contains("\nG4 P0.5\n"));
        let arcs: Vec<&str> = text.lines().filter(|l| l.starts_with("G3")).collect();
        assert_eq!(arcs.len(), POINTS);
        assert!(arcs[4].ends_with("R50.005000"), "{}", arcs[4]); // arc to point 5
        assert!(arcs[5].ends_with("R50.005000"), "{}", arcs[5]); // arc to point 6
        assert!(arcs[6].ends_with("R50.000000"), "{}", arcs[6]);
    }
}
