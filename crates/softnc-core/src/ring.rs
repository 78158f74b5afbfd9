//! The lookahead ring of command samples between interpolation and position control.
//!
//! Paper 002's Soft-NC puts a buffer of command positions between the interpolator
//! (the *servo task*) and position control (the *position task*) so that the position
//! task can read *future* commands — what makes a zero-lag non-causal filter possible.
//! The ring checks sequence numbers on every push (a gap or a reordering is an error,
//! never absorbed), exposes the window [i−N, i+N] around the current sample, pads the
//! past with the first sample and, once the end of the job is in, the future with the
//! last. Fixed capacity, no allocation after construction.

/// One command sample as the ring stores it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RingSample<const AXES: usize> {
    /// Sequence number (consecutive within a job).
    pub seq: u64,
    /// Command position per axis (mm).
    pub pos_mm: [f64; AXES],
}

/// What went wrong when pushing into the ring.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum RingError {
    /// A sample was skipped.
    #[error("command sample sequence gap: expected {expected}, got {got}")]
    Gap {
        /// The sequence number that should have come.
        expected: u64,
        /// The one that came.
        got: u64,
    },
    /// A sample came again or out of order.
    #[error("command sample out of order: expected {expected}, got {got}")]
    Reordered {
        /// The sequence number that should have come.
        expected: u64,
        /// The one that came.
        got: u64,
    },
    /// The ring is full: the producer ran ahead of the consumer.
    #[error("lookahead ring full ({capacity} samples)")]
    Full {
        /// Capacity of the ring.
        capacity: usize,
    },
    /// A sample came after the end of the job.
    #[error("command sample after the end of the job")]
    AfterEnd,
}

/// Fixed-capacity lookahead ring: up to `CAP`/2 samples ahead of the current one and
/// `CAP`/2 behind it, so a window of ±N needs `CAP` ≥ 2·(N + 1).
#[derive(Debug, Clone)]
pub struct LookaheadRing<const AXES: usize, const CAP: usize> {
    buf: [[f64; AXES]; CAP],
    /// Sequence number of the first sample of the job (when one has come).
    first_seq: Option<u64>,
    /// Number of samples pushed.
    pushed: u64,
    /// Index (0-based, from the job's first sample) of the current sample.
    current: u64,
    ended: bool,
}

impl<const AXES: usize, const CAP: usize> Default for LookaheadRing<AXES, CAP> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const AXES: usize, const CAP: usize> LookaheadRing<AXES, CAP> {
    /// An empty ring.
    pub fn new() -> Self {
        LookaheadRing {
            buf: [[0.0; AXES]; CAP],
            first_seq: None,
            pushed: 0,
            current: 0,
            ended: false,
        }
    }

    /// Forget everything (a new job).
    pub fn reset(&mut self) {
        self.first_seq = None;
        self.pushed = 0;
        self.current = 0;
        self.ended = false;
    }

    /// Capacity in samples.
    pub const fn capacity(&self) -> usize {
        CAP
    }

    /// Samples pushed and not yet made current (the current one included).
    pub fn ahead(&self) -> u64 {
        self.pushed.saturating_sub(self.current)
    }

    /// True once the job's last sample has been pushed.
    pub fn ended(&self) -> bool {
        self.ended
    }

    /// Index of the current sample from the start of the job.
    pub fn current_index(&self) -> u64 {
        self.current
    }

    /// Push the next sample; `last` marks the job's final sample.
    pub fn push(&mut self, sample: RingSample<AXES>, last: bool) -> Result<(), RingError> {
        if self.ended {
            return Err(RingError::AfterEnd);
        }
        let expected = self
            .first_seq
            .map(|f| f + self.pushed)
            .unwrap_or(sample.seq);
        if sample.seq > expected {
            return Err(RingError::Gap {
                expected,
                got: sample.seq,
            });
        }
        if sample.seq < expected {
            return Err(RingError::Reordered {
                expected,
                got: sample.seq,
            });
        }
        // half the ring holds future samples, the other half the past window
        if self.pushed - self.current >= (CAP / 2) as u64 {
            return Err(RingError::Full { capacity: CAP });
        }
        self.first_seq.get_or_insert(sample.seq);
        self.buf[(self.pushed % CAP as u64) as usize] = sample.pos_mm;
        self.pushed += 1;
        self.ended = last;
        Ok(())
    }

    /// True when the window ±`n` around the current sample is available: `n` future
    /// samples are in, or the job's end is.
    pub fn ready(&self, n: usize) -> bool {
        self.pushed > self.current && (self.ended || self.pushed > self.current + n as u64)
    }

    /// Command position `offset` samples from the current one (−N..=N). Before the
    /// job's first sample it is the first sample; after its last (once the end is
    /// in), the last. `None` if that future sample has not arrived yet.
    pub fn at(&self, offset: i64) -> Option<[f64; AXES]> {
        if self.pushed == 0 {
            return None;
        }
        let idx = self.current as i64 + offset;
        let idx = if idx < 0 { 0 } else { idx as u64 };
        let idx = if idx >= self.pushed {
            if !self.ended {
                return None;
            }
            self.pushed - 1
        } else {
            idx
        };
        // the oldest kept sample is pushed − CAP; anything older was overwritten
        let oldest = self.pushed.saturating_sub(CAP as u64);
        let idx = idx.max(oldest);
        Some(self.buf[(idx % CAP as u64) as usize])
    }

    /// Make the next sample current. Returns false when there is none (ring dry or
    /// job done).
    pub fn advance(&mut self) -> bool {
        if self.current + 1 < self.pushed {
            self.current += 1;
            true
        } else {
            false
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn s(seq: u64, x: f64) -> RingSample<1> {
        RingSample { seq, pos_mm: [x] }
    }

    #[test]
    fn window_pads_past_and_future() {
        let mut r: LookaheadRing<1, 16> = LookaheadRing::new();
        for k in 0..3 {
            r.push(s(100 + k, k as f64), k == 2).unwrap();
        }
        assert!(r.ready(2));
        assert_eq!(r.at(-2), Some([0.0]));
        assert_eq!(r.at(0), Some([0.0]));
        assert_eq!(r.at(2), Some([2.0]));
        assert!(r.advance() && r.advance());
        assert_eq!(r.at(0), Some([2.0]));
        assert_eq!(
            r.at(5),
            Some([2.0]),
            "future padded with the final position"
        );
        assert_eq!(r.at(-1), Some([1.0]));
        assert!(!r.advance());
    }

    #[test]
    fn not_ready_until_n_future_samples() {
        let mut r: LookaheadRing<1, 16> = LookaheadRing::new();
        for k in 0..3 {
            r.push(s(k, 0.0), false).unwrap();
        }
        assert!(!r.ready(3));
        assert_eq!(r.at(3), None);
        r.push(s(3, 0.0), false).unwrap();
        assert!(r.ready(3));
    }

    #[test]
    fn gaps_reordering_overflow_and_after_end_are_errors() {
        let mut r: LookaheadRing<1, 8> = LookaheadRing::new();
        r.push(s(5, 0.0), false).unwrap();
        assert_eq!(
            r.push(s(7, 0.0), false),
            Err(RingError::Gap {
                expected: 6,
                got: 7
            })
        );
        assert_eq!(
            r.push(s(5, 0.0), false),
            Err(RingError::Reordered {
                expected: 6,
                got: 5
            })
        );
        let mut k = 6;
        let err = loop {
            match r.push(s(k, 0.0), false) {
                Ok(()) => k += 1,
                Err(e) => break e,
            }
        };
        assert_eq!(err, RingError::Full { capacity: 8 });
        assert_eq!(k, 9, "four samples ahead of the current one fit");
        assert!(r.advance());
        r.push(s(k, 0.0), true).unwrap();
        assert_eq!(r.push(s(k + 1, 0.0), false), Err(RingError::AfterEnd));
    }
}
