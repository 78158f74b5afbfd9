//! S words in a running job (paper 000 Sec. III): the tooth frequency follows the
//! spindle, f_d = rpm · flutes / 60 (eq 2), and every axis's PDC must be redesigned for
//! it. The designs for every spindle speed of a job are made when the job starts —
//! before motion, off the cycle path — and each is swapped in at the cycle where its
//! speed takes effect; the taps it replaces go back to the pool, so a speed that comes
//! again costs nothing and the cycle allocates nothing.

use crate::backend::MAX_AXES;

/// Taps of H = L·W for one tooth frequency (Hz), while not running.
pub type Taps = Option<(Vec<f64>, f64)>;

/// The spindle speeds of a job and their PDC designs.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SpindleSchedule {
    /// Index into `speeds_rpm` per program motion; `None` while the spindle is stopped
    /// (the running design stays).
    pub(crate) speed_of_motion: Vec<Option<usize>>,
    /// Distinct spindle speeds (rpm); entry 0 is the one designed at start.
    pub(crate) speeds_rpm: Vec<f64>,
    /// Their tooth frequencies f_d = rpm · flutes / 60 (Hz, eq 2).
    pub(crate) fd_hz: Vec<f64>,
    /// Designed taps per speed and axis, while not running.
    pub(crate) taps: Vec<[Taps; MAX_AXES]>,
    /// The speed whose design runs.
    pub(crate) active: usize,
    /// The speed whose taps the last swap retired (to go back to `taps`).
    pub(crate) retiring: Option<usize>,
}

impl SpindleSchedule {
    /// Speeds of `rpm_of_motion` (0 = stopped), with `start_rpm` running now, on a
    /// tool of `flutes` flutes.
    pub fn new(start_rpm: f64, flutes: f64, rpm_of_motion: &[f64]) -> Self {
        let mut speeds_rpm = vec![start_rpm];
        let speed_of_motion = rpm_of_motion
            .iter()
            .map(|&rpm| {
                if rpm <= 0.0 {
                    return None;
                }
                Some(match speeds_rpm.iter().position(|&s| s == rpm) {
                    Some(i) => i,
                    None => {
                        speeds_rpm.push(rpm);
                        speeds_rpm.len() - 1
                    }
                })
            })
            .collect();
        let taps = speeds_rpm.iter().map(|_| [None, None, None]).collect();
        let fd_hz = speeds_rpm.iter().map(|rpm| rpm * flutes / 60.0).collect();
        SpindleSchedule {
            speed_of_motion,
            speeds_rpm,
            fd_hz,
            taps,
            active: 0,
            retiring: None,
        }
    }

    /// The distinct speeds (rpm), the one running at start first.
    pub fn speeds_rpm(&self) -> &[f64] {
        &self.speeds_rpm
    }

    /// The speed whose design runs now (rpm).
    pub fn active_rpm(&self) -> f64 {
        self.speeds_rpm[self.active]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distinct_speeds_in_order_of_first_use() {
        let s = SpindleSchedule::new(1500.0, 2.0, &[0.0, 1200.0, 1200.0, 1500.0, 1800.0, 0.0]);
        assert_eq!(s.speeds_rpm(), &[1500.0, 1200.0, 1800.0]);
        assert_eq!(s.fd_hz, vec![50.0, 40.0, 60.0]);
        assert_eq!(
            s.speed_of_motion,
            vec![None, Some(1), Some(1), Some(0), Some(2), None]
        );
        assert_eq!(s.active_rpm(), 1500.0);
    }
}
