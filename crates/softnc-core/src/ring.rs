//! The command ring between interpolation and position control: the stack's
//! instance of paper 002's lookahead ring (`softnc_control::ring`, generic) and its
//! sizing rule.

pub use softnc_control::ring::{LookaheadRing, RingError, RingSample};

/// Capacity of the command ring between interpolation and position control: a window
/// of ±[`softnc_control::config::MAX_COMMAND_FILTER_ORDER`] samples fits with room to spare.
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
