//! S words in a running job (paper 000 Sec. III): the tooth frequency follows the
//! spindle, f_d = rpm · flutes / 60 (eq 2), and every axis's PDC must be redesigned for
//! it. The designs for every spindle speed of a job are made when the job starts —
//! before motion, off the cycle path — and each is swapped in at the cycle where its
//! speed takes effect; the taps it replaces go back to the pool, so a speed that comes
//! again costs nothing and the cycle allocates nothing.

use crate::backend::MAX_AXES;

/// Taps of H = L·W for one tooth frequency, while not running.
pub type Taps = Option<Vec<f64>>;

/// The spindle speeds of a job and their PDC designs.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SpindleSchedule {
    /// (first motion, index into `speeds_rpm`) where the speed changes; stops (0 rpm)
    /// are left out: the running design stays while the spindle stands.
    pub(crate) changes: Vec<(u32, usize)>,
    /// The next change to take effect.
    pub(crate) next: usize,
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
    /// The speed changes `changes` ((first motion, rpm), 0 = stopped) of a job, with
    /// `start_rpm` running now, on a tool of `flutes` flutes.
    pub fn new(start_rpm: f64, flutes: f64, changes: &[(u32, f64)]) -> Self {
        let mut speeds_rpm = vec![start_rpm];
        let changes = changes
            .iter()
            .filter(|c| c.1 > 0.0)
            .map(|&(motion, rpm)| {
                let k = match speeds_rpm.iter().position(|&s| s == rpm) {
                    Some(k) => k,
                    None => {
                        speeds_rpm.push(rpm);
                        speeds_rpm.len() - 1
                    }
                };
                (motion, k)
            })
            .collect();
        let taps = speeds_rpm.iter().map(|_| [None, None, None]).collect();
        let fd_hz = speeds_rpm.iter().map(|rpm| rpm * flutes / 60.0).collect();
        SpindleSchedule {
            changes,
            next: 0,
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

    /// The speed to switch to when motion `motion` runs, if it changes now.
    pub(crate) fn change_at(&mut self, motion: u32) -> Option<usize> {
        let mut to = None;
        while let Some(&(m, k)) = self.changes.get(self.next) {
            if m > motion {
                break;
            }
            to = Some(k);
            self.next += 1;
        }
        to.filter(|&k| k != self.active)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distinct_speeds_and_changes_in_motion_order() {
        let mut s = SpindleSchedule::new(
            1500.0,
            2.0,
            &[
                (1, 1200.0),
                (4, 1500.0),
                (6, 1800.0),
                (9, 0.0),
                (10, 1200.0),
            ],
        );
        assert_eq!(s.speeds_rpm(), &[1500.0, 1200.0, 1800.0]);
        assert_eq!(s.fd_hz, vec![50.0, 40.0, 60.0]);
        assert_eq!(s.change_at(0), None);
        assert_eq!(s.change_at(1), Some(1));
        s.active = 1;
        assert_eq!(s.change_at(3), None);
        assert_eq!(
            s.change_at(7),
            Some(2),
            "a change passed over lands on the latest"
        );
        s.active = 2;
        assert_eq!(s.change_at(9), None, "a stop keeps the running design");
        assert_eq!(s.change_at(10), Some(1));
    }
}
