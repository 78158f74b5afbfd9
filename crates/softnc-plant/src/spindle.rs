//! A spindle: a rotor of inertia J, its drive's speed loop with a torque limit, a
//! viscous loss, and its own encoder with one index pulse per revolution.
//!
//! J·dω/dt = τ_drive − b·ω, with τ_drive = clamp(J·(ω_cmd − ω)/T_s + b·ω, ±τ_max):
//! the drive feeds the loss forward and closes a proportional speed loop of time
//! constant T_s, so the spindle accelerates at (τ_max − b·ω)/J until it is near its
//! command, then settles on it. Disabled, the drive brakes it to rest the same way
//! (a VFD's stop ramp). One step per interpolation cycle (explicit Euler; the
//! profile's check keeps T_s ≥ two cycles).
//!
//! M19 ([`Spindle::step_orient`]): a position loop around that speed loop turns
//! the spindle to an angle measured by its encoder from the index (as LinuxCNC's
//! `orient` component does on `spindle.N.revs` after the index), the way M19 P
//! asks (0 the shorter way, 1 clockwise, 2 counter-clockwise: the sense of the
//! first move, fixed once the spindle is down to `orient_rpm`; from there the loop
//! holds the target), at most `orient_rpm`, with
//! a gain of 1/(4·T_s) (well damped around the speed loop's lag). It reports
//! itself oriented (`spindle.N.is-oriented`) while the encoder's angle is within
//! `orient_band_deg` of the target.

use crate::config::SpindleModel;
use std::f64::consts::TAU;

/// rad/s per rpm.
const RAD_S_PER_RPM: f64 = TAU / 60.0;

/// What the spindle's encoder reports.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SpindleReading {
    /// Speed from the counts of the last step (rpm, signed: + clockwise).
    pub rpm: f64,
    /// Position (revolutions since the model started, quantised to counts).
    pub revs: f64,
    /// Index pulses seen since the model started (one per revolution, either way).
    pub index_count: u64,
    /// M19: the encoder's angle is within the band of the orient target.
    pub oriented: bool,
}

/// The simulated spindle.
#[derive(Debug, Clone, PartialEq)]
pub struct Spindle {
    cfg: SpindleModel,
    /// Speed (rad/s).
    omega_rad_s: f64,
    /// Angle (revolutions, continuous).
    revs: f64,
    counts: i64,
    reading: SpindleReading,
    /// M19 in progress: (angle asked (deg), direction, target (revolutions of the
    /// encoder)).
    orient: Option<(f64, u8, f64)>,
}

impl Spindle {
    /// A spindle at rest at angle 0.
    pub fn new(cfg: &SpindleModel) -> Self {
        Spindle {
            cfg: *cfg,
            omega_rad_s: 0.0,
            revs: 0.0,
            counts: 0,
            reading: SpindleReading::default(),
            orient: None,
        }
    }

    /// One step of `dt_s` with the drive enabled at signed speed command `rpm`
    /// (+ clockwise; clipped to the drive's max speed), or disabled (braked to
    /// rest).
    pub fn step(&mut self, enabled: bool, rpm: f64, dt_s: f64) {
        self.orient = None;
        self.advance(enabled, rpm, dt_s);
    }

    /// One step of `dt_s` orienting the spindle (M19) to `angle_deg` from the
    /// index, turning the way `direction` says (M19 P: 0 the shorter way, 1
    /// clockwise, 2 counter-clockwise).
    pub fn step_orient(&mut self, angle_deg: f64, direction: u8, dt_s: f64) {
        let cpr = f64::from(self.cfg.encoder_counts_per_rev);
        let measured = self.counts as f64 / cpr;
        let max_rps = self.cfg.orient_rpm / 60.0;
        let target = match self.orient {
            Some((a, d, t)) if a == angle_deg && d == direction => t,
            _ if self.reading.rpm.abs() > self.cfg.orient_rpm => {
                // turning faster than the orient speed: slowed to it first
                let rpm = self
                    .reading
                    .rpm
                    .clamp(-self.cfg.orient_rpm, self.cfg.orient_rpm);
                self.advance(true, rpm, dt_s);
                return;
            }
            _ => {
                // the first move's sense, from the encoder's angle since the index
                let from_index = self
                    .counts
                    .rem_euclid(i64::from(self.cfg.encoder_counts_per_rev));
                let at_deg = from_index as f64 / cpr * 360.0;
                let ahead = (angle_deg - at_deg).rem_euclid(360.0);
                let move_deg = match direction {
                    1 => ahead,
                    2 if ahead > 0.0 => ahead - 360.0,
                    2 => 0.0,
                    _ if ahead > 180.0 => ahead - 360.0,
                    _ => ahead,
                };
                let t = measured + move_deg / 360.0;
                self.orient = Some((angle_deg, direction, t));
                t
            }
        };
        let gain_per_s = 1.0 / (4.0 * self.cfg.speed_loop_s);
        let rps = ((target - measured) * gain_per_s).clamp(-max_rps, max_rps);
        self.advance(true, rps * 60.0, dt_s);
        let err_deg = (target - self.counts as f64 / cpr) * 360.0;
        self.reading.oriented = err_deg.abs() <= self.cfg.orient_band_deg;
    }

    /// The model's step under a speed command.
    fn advance(&mut self, enabled: bool, rpm: f64, dt_s: f64) {
        let c = &self.cfg;
        let cmd_rpm = if enabled && rpm.is_finite() {
            rpm.clamp(-c.max_rpm, c.max_rpm)
        } else {
            0.0
        };
        let w_cmd = cmd_rpm * RAD_S_PER_RPM;
        let w = self.omega_rad_s;
        let loss = c.viscous_nm_per_rad_s * w;
        let drive = (c.inertia_kg_m2 * (w_cmd - w) / c.speed_loop_s + loss)
            .clamp(-c.max_torque_nm, c.max_torque_nm);
        self.omega_rad_s = w + dt_s * (drive - loss) / c.inertia_kg_m2;
        let before = self.revs;
        self.revs += self.omega_rad_s * dt_s / TAU;
        let cpr = f64::from(c.encoder_counts_per_rev);
        let counts = (self.revs * cpr).floor() as i64;
        let index = (self.revs.floor() - before.floor()).abs() as u64;
        self.reading = SpindleReading {
            rpm: (counts - self.counts) as f64 / cpr / dt_s * 60.0,
            revs: counts as f64 / cpr,
            index_count: self.reading.index_count + index,
            oriented: false,
        };
        self.counts = counts;
    }

    /// The encoder's report after the last step.
    pub fn reading(&self) -> SpindleReading {
        self.reading
    }

    /// The true speed (rpm, signed).
    pub fn true_rpm(&self) -> f64 {
        self.omega_rad_s / RAD_S_PER_RPM
    }

    /// The true angle (revolutions since the start).
    pub fn true_revs(&self) -> f64 {
        self.revs
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shipped profiles' 12,000 rpm spindle (config/machines/default.ron).
    fn model() -> SpindleModel {
        SpindleModel {
            inertia_kg_m2: 0.01,
            max_torque_nm: 15.0,
            viscous_nm_per_rad_s: 0.0004,
            speed_loop_s: 0.05,
            max_rpm: 12000.0,
            encoder_counts_per_rev: 4096,
            orient_rpm: 60.0,
            orient_band_deg: 0.5,
        }
    }

    const DT: f64 = 0.001;

    /// Steps until the true speed is within `frac` of `rpm` (s).
    fn time_to(s: &mut Spindle, rpm: f64, frac: f64) -> f64 {
        for k in 1..100_000 {
            s.step(true, rpm, DT);
            if (s.true_rpm() - rpm).abs() <= frac * rpm.abs() {
                return k as f64 * DT;
            }
        }
        panic!("never reached {rpm} rpm");
    }

    #[test]
    fn reaches_full_speed_in_about_a_second_as_the_torque_limit_says() {
        let c = model();
        let mut s = Spindle::new(&c);
        let t = time_to(&mut s, 12000.0, 0.01);
        // torque-limited: ∫ J dω / (τ_max − bω) from 0 to 0.99·ω_max, then the loop
        let w = 0.99 * 12000.0 * RAD_S_PER_RPM;
        let b = c.viscous_nm_per_rad_s;
        let expected = -c.inertia_kg_m2 / b * ((c.max_torque_nm - b * w) / c.max_torque_nm).ln();
        assert!((0.8..1.2).contains(&t), "{t} s to 12,000 rpm");
        assert!(
            (t - expected).abs() < 0.1,
            "{t} s, the torque limit alone gives {expected} s"
        );
        // then it holds the speed, and the encoder reads it to a count per cycle
        for _ in 0..2000 {
            s.step(true, 12000.0, DT);
        }
        assert!((s.true_rpm() - 12000.0).abs() < 1e-6, "{}", s.true_rpm());
        let count_rpm = 60.0 / 4096.0 / DT;
        assert!((s.reading().rpm - 12000.0).abs() <= count_rpm + 1e-9);
        // disabled, the drive brakes it to rest as fast
        let t_stop = (1..100_000)
            .find(|_| {
                s.step(false, 12000.0, DT);
                s.true_rpm().abs() < 1.0
            })
            .unwrap() as f64
            * DT;
        assert!((0.6..1.2).contains(&t_stop), "{t_stop} s to stop");
        assert_eq!(s.reading().rpm, 0.0);
    }

    #[test]
    fn counter_clockwise_is_negative_and_clipped_at_max() {
        let mut s = Spindle::new(&model());
        time_to(&mut s, -12000.0, 0.001);
        for _ in 0..2000 {
            s.step(true, -20000.0, DT);
        }
        assert!((s.true_rpm() + 12000.0).abs() < 1e-6, "{}", s.true_rpm());
        assert!(s.reading().revs < 0.0);
    }

    #[test]
    fn one_index_pulse_per_revolution_either_way() {
        let mut s = Spindle::new(&model());
        // 600 rpm: 10 rev/s
        for _ in 0..5000 {
            s.step(true, 600.0, DT);
        }
        let r = s.reading();
        assert_eq!(r.index_count, s.true_revs().floor() as u64);
        assert!((r.revs - s.true_revs()).abs() <= 1.0 / 4096.0);
        assert!(r.index_count >= 45, "{}", r.index_count);
        // back the other way through zero: every revolution passed counts again
        let forward = r.index_count;
        let at = s.true_revs();
        while s.true_revs() > -2.5 {
            s.step(true, -600.0, DT);
        }
        let passed = (at.floor() - s.true_revs().floor()) as u64;
        assert_eq!(s.reading().index_count, forward + passed);
    }

    /// The encoder's angle from the index (degrees, 0..360).
    fn angle_deg(s: &Spindle) -> f64 {
        (s.reading().revs.rem_euclid(1.0)) * 360.0
    }

    /// Orient until oriented (s), then hold it a second; the angle error there (deg).
    fn orient(s: &mut Spindle, angle: f64, dir: u8) -> (f64, f64) {
        let t = (1..20_000)
            .find(|_| {
                s.step_orient(angle, dir, DT);
                s.reading().oriented
            })
            .expect("never oriented") as f64
            * DT;
        for _ in 0..1000 {
            s.step_orient(angle, dir, DT);
            assert!(s.reading().oriented);
        }
        let err = (angle_deg(s) - angle + 180.0).rem_euclid(360.0) - 180.0;
        (t, err)
    }

    #[test]
    fn m19_orients_to_the_angle_from_the_index_the_way_asked() {
        let c = model();
        let count_deg = 360.0 / 4096.0;
        // from a spindle turning at 3000 rpm, then from rest, each way
        let mut s = Spindle::new(&c);
        for _ in 0..2000 {
            s.step(true, 3000.0, DT);
        }
        let (t, err) = orient(&mut s, 90.0, 0);
        println!("from 3000 rpm to 90 deg: {t:.3} s, angle error {err:.4} deg");
        assert!(err.abs() <= count_deg, "{err} deg");
        assert!(s.true_rpm().abs() < 0.5, "{} rpm", s.true_rpm());
        assert!(t < 2.0, "{t} s");
        for (angle, dir) in [(270.0, 1u8), (10.0, 2), (300.0, 0), (0.0, 0)] {
            let before = s.true_revs();
            let at = angle_deg(&s);
            let (t, err) = orient(&mut s, angle, dir);
            let moved = s.true_revs() - before;
            println!("{at:.1} -> {angle} deg (P{dir}): {t:.3} s, moved {:.1} deg, angle error {err:.4} deg", moved * 360.0);
            assert!(err.abs() <= count_deg, "{angle} P{dir}: {err} deg");
            match dir {
                1 => assert!(moved > 0.0, "P1 turns clockwise: {moved}"),
                2 => assert!(moved < 0.0, "P2 turns counter-clockwise: {moved}"),
                _ => assert!(moved.abs() <= 0.5 + 1e-3, "P0 the shorter way: {moved}"),
            }
        }
        // a speed command ends the orientation
        s.step(true, 600.0, DT);
        assert!(!s.reading().oriented);
    }
}
