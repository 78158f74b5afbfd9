//! The lookahead ring of command samples between interpolation and position control.
//!
//! Paper 002's Soft-NC puts a buffer of command positions between the interpolator
//! (the *servo task*) and position control (the *position task*) so that the position
//! task can read *future* commands — what makes a zero-lag non-causal filter possible.
//! The ring checks sequence numbers on every push (a gap or a reordering is an error,
//! never absorbed), exposes the window [i−N, i+N] around the current sample, pads the
//! past with the first sample and, once the end of the job is in, the future with the
//! last. Fixed capacity, no allocation after construction.
//!
//! A filter of order N must start at rest and end at the job's final position, so a
//! ring made with [`LookaheadRing::reset_padded`]`(N)` runs N cycles of the first
//! sample before the job's first sample and N of the last after its last: the
//! current index counts those cycles ([`LookaheadRing::current_index`]), the job's
//! sample under it is [`LookaheadRing::source_index`].
//!
//! The ring is generic over the axis count and capacity ([`LookaheadRing`]); the
//! stack's instance ([`CommandRing`]) and its sizing rule follow it.

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
    /// Index of the current cycle: `pad` lead-in cycles, then the job's samples, then
    /// `pad` run-out cycles.
    current: u64,
    /// Lead-in and run-out cycles (the filter order N).
    pad: u64,
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
            pad: 0,
            ended: false,
        }
    }

    /// Forget everything (a new job), keeping the padding.
    pub fn reset(&mut self) {
        self.first_seq = None;
        self.pushed = 0;
        self.current = 0;
        self.ended = false;
    }

    /// Forget everything (a new job) and run `pad` cycles of the first sample before
    /// it and `pad` of the last after it (a filter of order `pad` then starts at rest
    /// and ends at the final position).
    pub fn reset_padded(&mut self, pad: usize) {
        self.reset();
        self.pad = pad as u64;
    }

    /// The job's sample (0-based) under the current cycle: the first during the
    /// lead-in, the last during the run-out.
    pub fn source_index(&self) -> u64 {
        self.current
            .saturating_sub(self.pad)
            .min(self.pushed.saturating_sub(1))
    }

    /// Capacity in samples.
    pub const fn capacity(&self) -> usize {
        CAP
    }

    /// Cycles whose command is in the ring from the current one on (the current one
    /// included; lead-in cycles count).
    pub fn ahead(&self) -> u64 {
        self.end_cycle().saturating_sub(self.current)
    }

    /// True once the job's last sample has been pushed.
    pub fn ended(&self) -> bool {
        self.ended
    }

    /// Index of the current cycle from the start of the job (lead-in included).
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
        if self.pushed - self.source_index() >= (CAP / 2) as u64 {
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
        self.pushed > 0
            && if self.ended {
                self.current < self.end_cycle()
            } else {
                self.pushed + self.pad > self.current + n as u64
            }
    }

    /// One past the last cycle whose sample is in: the job's end and its run-out once
    /// the end is in.
    fn end_cycle(&self) -> u64 {
        if self.ended {
            self.pushed + 2 * self.pad
        } else {
            self.pushed + self.pad
        }
    }

    /// Command position `offset` samples from the current one (−N..=N). Before the
    /// job's first sample it is the first sample; after its last (once the end is
    /// in), the last. `None` if that future sample has not arrived yet.
    pub fn at(&self, offset: i64) -> Option<[f64; AXES]> {
        if self.pushed == 0 {
            return None;
        }
        let idx = self.current as i64 - self.pad as i64 + offset;
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

    /// Make the next cycle current. Returns false when there is none (ring dry, or
    /// the job done: its last sample and the run-out passed).
    pub fn advance(&mut self) -> bool {
        if self.current + 1 < self.end_cycle() {
            self.current += 1;
            true
        } else {
            false
        }
    }
}

/// One interpolated command sample (the planner's `Sample`, decoupled): what the
/// offline simulator runs and a learned job's correction is added to.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CommandSample {
    /// Command position (mm).
    pub pos_mm: crate::Axes<f64>,
    /// Index of the program motion being executed.
    pub motion: u32,
    /// True during feed moves (G1/G2/G3): the tool cuts, contour error is measured.
    pub feed_move: bool,
    /// What the machine around the axes is told while this sample is in use
    /// (spindle, coolant, outputs); `MachineOutputs::default()` for a program that
    /// says nothing of them.
    pub outputs: crate::machine_io::MachineOutputs,
}

/// Capacity of the command ring between interpolation and position control: a window
/// of ±`MAX_COMMAND_FILTER_ORDER` (softnc-control) samples fits with room to spare.
pub const COMMAND_RING_CAPACITY: usize = 2048;

/// The ring of command samples (every axis the stack carries) the position task (daemon and simulator) reads.
pub type CommandRing = LookaheadRing<{ crate::MAX_AXES }, COMMAND_RING_CAPACITY>;

/// Largest lookahead the interpolator may keep in flight: the ring holds twice this
/// (a window's past and future).
pub const MAX_LOOKAHEAD_SAMPLES: usize = 1000;
const _: () = assert!(2 * MAX_LOOKAHEAD_SAMPLES <= COMMAND_RING_CAPACITY);

/// The ring sizing rule: the window of future samples the position task needs before
/// and during motion when the interpolator keeps `lookahead_samples` in flight — the
/// lookahead less a quarter of slack for the interpolator's latency.
pub fn window_for_lookahead(lookahead_samples: usize) -> usize {
    (lookahead_samples - lookahead_samples / 4).max(1)
}

/// The smallest lookahead whose [`window_for_lookahead`] holds `window` samples.
pub fn lookahead_for_window(window: usize) -> usize {
    (window..)
        .find(|&l| window_for_lookahead(l) >= window)
        .unwrap_or(window)
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
    fn padding_runs_lead_in_and_run_out_cycles() {
        let mut r: LookaheadRing<1, 16> = LookaheadRing::new();
        r.reset_padded(2);
        r.push(s(0, 1.0), false).unwrap();
        // lead-in: the window sees the first sample on both sides of the cycle
        assert!(!r.ready(3));
        assert!(r.ready(2));
        assert_eq!(r.at(-2), Some([1.0]));
        assert_eq!(r.at(2), Some([1.0]));
        assert_eq!(r.at(3), None, "the job's second sample is not in");
        r.push(s(1, 2.0), false).unwrap();
        r.push(s(2, 3.0), true).unwrap();
        assert_eq!(r.at(3), Some([2.0]));
        let mut seen = vec![(r.current_index(), r.source_index(), r.at(0).unwrap()[0])];
        while r.advance() {
            // the end is in: every cycle to the end of the run-out has its window
            assert!(r.ready(2), "cycle {}", r.current_index());
            assert_eq!(r.ahead(), 7 - r.current_index());
            seen.push((r.current_index(), r.source_index(), r.at(0).unwrap()[0]));
        }
        let expect = [
            (0, 0, 1.0),
            (1, 0, 1.0),
            (2, 0, 1.0),
            (3, 1, 2.0),
            (4, 2, 3.0),
            (5, 2, 3.0),
            (6, 2, 3.0),
        ];
        assert_eq!(seen, expect);
        assert_eq!(r.at(-2), Some([3.0]), "run-out: the last sample");
        assert_eq!(r.at(-3), Some([2.0]));
        assert_eq!(r.at(2), Some([3.0]));
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
