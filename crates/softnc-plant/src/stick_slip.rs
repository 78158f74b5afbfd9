//! Karnopp stick–slip friction (Karnopp 1985, cited by paper 001): inside a tiny band
//! around zero velocity the friction balances the drive up to the breakaway level,
//! so an axis at rest stays at rest while the drive is below breakaway.

/// Half-width of the zero-velocity band, in the plant's velocity unit. Numerical, not
/// physical: the plants also stop an axis exactly where its velocity changes sign, so
/// a velocity in the band means "at rest".
pub const STICK_BAND: f64 = 1e-9;

/// What the friction does this step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Contact {
    /// At rest and the drive is below breakaway: no motion, velocity held at zero.
    Stuck,
    /// Moving (or breaking away): the net drive (drive minus friction) accelerates the axis.
    Slip {
        /// Drive minus friction, in plant-input units.
        net: f64,
    },
}

/// Breakaway levels of one axis (plant-input units, both positive).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Breakaway {
    /// Drive needed to start moving in the + direction.
    pub pos: f64,
    /// Drive needed (as a magnitude) to start moving in the − direction.
    pub neg: f64,
}

/// Karnopp's rule: `vel` the current velocity, `drive` the force-like input,
/// `kinetic` the sliding friction at `vel` (signed, opposing motion).
#[inline]
pub fn karnopp(vel: f64, drive: f64, breakaway: Breakaway, kinetic: f64) -> Contact {
    if vel.abs() < STICK_BAND {
        let level = if drive >= 0.0 {
            breakaway.pos
        } else {
            breakaway.neg
        };
        if drive.abs() <= level {
            Contact::Stuck
        } else {
            Contact::Slip {
                net: drive - level.copysign(drive),
            }
        }
    } else {
        Contact::Slip {
            net: drive - kinetic,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sticks_below_breakaway_and_slips_above() {
        let b = Breakaway {
            pos: 20.49,
            neg: 18.27,
        };
        assert_eq!(karnopp(0.0, 20.0, b, 0.0), Contact::Stuck);
        assert_eq!(karnopp(0.0, -18.0, b, 0.0), Contact::Stuck);
        match karnopp(0.0, 25.0, b, 0.0) {
            Contact::Slip { net } => assert!((net - 4.51).abs() < 1e-12),
            c => panic!("{c:?}"),
        }
        match karnopp(0.0, -20.0, b, 0.0) {
            Contact::Slip { net } => assert!((net + 1.73).abs() < 1e-12),
            c => panic!("{c:?}"),
        }
        // moving: kinetic friction, whatever the drive
        assert_eq!(
            karnopp(5.0, 1.0, b, 15.0),
            Contact::Slip { net: 1.0 - 15.0 }
        );
    }
}
