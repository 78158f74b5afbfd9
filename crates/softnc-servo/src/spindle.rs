//! The spindle in a running job (paper 000 Sec. III): the tooth frequency follows it,
//! f_d = rpm · override · flutes / 60 (eq 2), and every axis's PDC must be redesigned
//! for it. Two things change the speed:
//!
//! - **S words.** The designs for every programmed speed of a job are made when the
//!   job starts, before motion and off the cycle path, and each is swapped in at the
//!   cycle where its speed takes effect; the taps it replaces go back to the table, so
//!   a speed that comes again costs nothing and the cycle allocates nothing.
//! - **The operator's spindle override.** A [`SpindleDesigner`] (a copy of the job's
//!   PDC designers, owned by a design thread) makes a new table for every programmed
//!   speed at the new override; the cycle installs it
//!   ([`crate::CycleEngine::install_spindle_designs`]) by moving vectors, swaps the
//!   running speed's design in at the next cycle boundary — where the spindle takes
//!   the new speed — and hands the replaced table back
//!   ([`crate::CycleEngine::take_replaced_spindle_designs`]) to be dropped off the
//!   cycle.

use crate::backend::MAX_AXES;
use crate::design::CompensationDesignError;
use softnc_control::compensation::PdcDesigner;

/// Taps of H = L·W for one tooth frequency, while not running.
pub type Taps = Option<Vec<f64>>;

/// The PDC designs of every spindle speed of a job at one spindle override.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SpindleDesigns {
    /// Spindle override (fraction of the programmed speed).
    pub override_frac: f64,
    /// Tooth frequency per speed, f_d = rpm · override · flutes / 60 (Hz, eq 2).
    pub fd_hz: Vec<f64>,
    /// Designed taps per speed and axis, while not running (`None` on an axis without
    /// a PDC, and for the speed whose taps run).
    pub taps: Vec<[Taps; MAX_AXES]>,
}

/// Designs a job's PDC tables (allocates: off the real-time path). Cloneable and
/// `Send`, so a design thread can own one.
#[derive(Debug, Clone, PartialEq)]
pub struct SpindleDesigner {
    /// Each axis's PDC designer (`None` without a PDC).
    pub(crate) designers: [Option<PdcDesigner>; MAX_AXES],
    /// The job's distinct programmed speeds (rpm).
    pub(crate) speeds_rpm: Vec<f64>,
    /// Flutes of the tool.
    pub(crate) flutes: f64,
}

impl SpindleDesigner {
    /// The job's distinct programmed speeds (rpm), the one running at start first.
    pub fn speeds_rpm(&self) -> &[f64] {
        &self.speeds_rpm
    }

    /// Every speed's design at spindle override `override_frac`: H = L·W for
    /// f_d = rpm · override · flutes / 60 (eq 2, 11–12), checked against eq 13.
    pub fn design(&self, override_frac: f64) -> Result<SpindleDesigns, CompensationDesignError> {
        let fd_hz: Vec<f64> = self
            .speeds_rpm
            .iter()
            .map(|rpm| rpm * override_frac * self.flutes / 60.0)
            .collect();
        let mut taps = Vec::with_capacity(fd_hz.len());
        for &fd in &fd_hz {
            let mut per_axis: [Taps; MAX_AXES] = [None, None, None];
            for (axis, d) in self.designers.iter().enumerate() {
                if let Some(d) = d {
                    let design = d.design(fd).map_err(|e| CompensationDesignError {
                        axis,
                        error: e.into(),
                    })?;
                    per_axis[axis] = Some(design.h_taps);
                }
            }
            taps.push(per_axis);
        }
        Ok(SpindleDesigns {
            override_frac,
            fd_hz,
            taps,
        })
    }
}

/// Where the taps swapped out at the last cycle boundary go back to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Retiring {
    /// Speed `k` of the running table (an S word changed the speed).
    Table(usize),
    /// Speed `k` of the replaced table (an override installed a new table).
    Replaced(usize),
}

/// The spindle speeds of a job and their PDC designs.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SpindleSchedule {
    /// (first motion, index into `speeds_rpm`) where the speed changes; stops (0 rpm)
    /// are left out: the running design stays while the spindle stands.
    pub(crate) changes: Vec<(u32, usize)>,
    /// The next change to take effect.
    pub(crate) next: usize,
    /// Distinct programmed speeds (rpm); entry 0 is the one running at start.
    pub(crate) speeds_rpm: Vec<f64>,
    /// The designs at the running override.
    pub(crate) table: SpindleDesigns,
    /// The speed whose design runs.
    pub(crate) active: usize,
    /// Where the taps the last swap retired go back to.
    pub(crate) retiring: Option<Retiring>,
    /// An installed table waits for the next cycle boundary.
    pub(crate) installed: bool,
    /// The table an override replaced, until its running taps are back in it.
    pub(crate) replaced: Option<Box<SpindleDesigns>>,
}

impl SpindleSchedule {
    /// The distinct programmed speeds and the speed changes `changes` ((first motion,
    /// rpm), 0 = stopped) of a job with `start_rpm` running at start.
    pub(crate) fn plan(start_rpm: f64, changes: &[(u32, f64)]) -> (Vec<f64>, Vec<(u32, usize)>) {
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
        (speeds_rpm, changes)
    }

    /// The distinct programmed speeds (rpm), the one running at start first.
    pub fn speeds_rpm(&self) -> &[f64] {
        &self.speeds_rpm
    }

    /// The programmed speed whose design runs now (rpm).
    pub fn active_rpm(&self) -> f64 {
        self.speeds_rpm[self.active]
    }

    /// The spindle override of the running table (fraction).
    pub fn override_frac(&self) -> f64 {
        self.table.override_frac
    }

    /// The speed the spindle turns at now: programmed × override (rpm).
    pub fn effective_rpm(&self) -> f64 {
        self.active_rpm() * self.table.override_frac
    }

    /// The tooth frequency the running design is for (Hz).
    pub fn active_fd_hz(&self) -> f64 {
        self.table.fd_hz[self.active]
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
        let (speeds_rpm, changes) = SpindleSchedule::plan(
            1500.0,
            &[
                (1, 1200.0),
                (4, 1500.0),
                (6, 1800.0),
                (9, 0.0),
                (10, 1200.0),
            ],
        );
        let mut s = SpindleSchedule {
            changes,
            speeds_rpm,
            table: SpindleDesigns {
                override_frac: 1.0,
                fd_hz: vec![50.0, 40.0, 60.0],
                taps: vec![[None, None, None]; 3],
            },
            ..Default::default()
        };
        assert_eq!(s.speeds_rpm(), &[1500.0, 1200.0, 1800.0]);
        assert_eq!(s.change_at(0), None);
        assert_eq!(s.change_at(1), Some(1));
        s.active = 1;
        assert_eq!(s.effective_rpm(), 1200.0);
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
