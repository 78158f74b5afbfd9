//! Running a job offline: command samples → controller stacks → simulated machine, with
//! following error per axis and contour error during feed moves (the actual
//! position's distance to the programmed path near the command:
//! [`softnc_servo::contour`]).

use crate::metrics::ErrorStats;
use softnc_core::machine_io::MachineOutputs;
use softnc_core::{CommandRing, Primitive, RingSample, Vec3, COMMAND_RING_CAPACITY};
use softnc_servo::adaptive_feed::{AdaptiveFeed, OverrideSchedule, Revolution};
use softnc_servo::{BackendError, CycleEngine, ServoBackend, TraceRow, MAX_AXES};
use std::collections::VecDeque;

pub use softnc_core::ring::CommandSample;

/// Accuracy figures of a run.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SimReport {
    /// Cycles simulated.
    pub cycles: u64,
    /// Simulated time (s).
    pub sim_time_s: f64,
    /// Contour error over all feed-move cycles (mm).
    pub contour: ErrorStats,
    /// Following error per axis over all cycles (mm).
    pub following: [ErrorStats; MAX_AXES],
}

/// Run `samples` through `engine` (reset at the first sample's position), exactly as
/// the position task runs them: through the command ring, whose window
/// [i−N, i+N] the engine's command filters read (paper 002), motion only when N
/// future samples are in, the future padded with the last sample at the end. Each
/// sample's `outputs` go to the machine's I/O while it is the one in use.
/// `path(m)` is the programmed path of motion `m` (`None` for dwells); `observe` sees
/// every cycle.
pub fn simulate<B, I, P, F>(
    engine: &mut CycleEngine<B>,
    cycle_s: f64,
    samples: I,
    path: P,
    mut observe: F,
) -> Result<SimReport, BackendError>
where
    B: ServoBackend,
    I: IntoIterator<Item = CommandSample>,
    P: Fn(u32) -> Option<Primitive>,
    F: FnMut(&TraceRow),
{
    simulate_observed(engine, cycle_s, samples, path, |row, _| observe(row))
}

/// [`simulate`], with `observe` also seeing the engine after each cycle (for what
/// the trace does not hold, e.g. the simulated table position).
pub fn simulate_observed<B, I, P, F>(
    engine: &mut CycleEngine<B>,
    cycle_s: f64,
    samples: I,
    path: P,
    mut observe: F,
) -> Result<SimReport, BackendError>
where
    B: ServoBackend,
    I: IntoIterator<Item = CommandSample>,
    P: Fn(u32) -> Option<Primitive>,
    F: FnMut(&TraceRow, &CycleEngine<B>),
{
    simulate_sequenced(engine, cycle_s, samples, path, |row, engine, _| {
        observe(row, engine)
    })
}

/// [`simulate_observed`], with `observe` also told the sequence number of the
/// sample the cycle used (0 for the job's first; the lead-in and run-out use the
/// first and the last) — the `seq` the position process reports in its status.
pub fn simulate_sequenced<B, I, P, F>(
    engine: &mut CycleEngine<B>,
    cycle_s: f64,
    samples: I,
    path: P,
    mut observe: F,
) -> Result<SimReport, BackendError>
where
    B: ServoBackend,
    I: IntoIterator<Item = CommandSample>,
    P: Fn(u32) -> Option<Primitive>,
    F: FnMut(&TraceRow, &CycleEngine<B>, u64),
{
    let mut samples = samples.into_iter().peekable();
    let mut report = SimReport::default();
    let Some(first) = samples.peek() else {
        return Ok(report);
    };
    engine.reset(first.pos_mm);
    let window = engine.filter_window();
    let mut ring = Box::new(CommandRing::new());
    // N cycles of lead-in and run-out: the filtered command starts at rest and ends
    // at the final position
    ring.reset_padded(window);
    // (motion, feed move, outputs) of the job's samples from the current one on
    let mut meta: VecDeque<(u32, bool, MachineOutputs)> =
        VecDeque::with_capacity(COMMAND_RING_CAPACITY);
    let mut seq = 0u64;
    for k in 0u64.. {
        // the window, and the next cycle's sample (so `advance` never finds it dry)
        while !ring.ended() && !ring.ready(window + 1) {
            let Some(s) = samples.next() else { break };
            let last = samples.peek().is_none();
            ring.push(
                RingSample {
                    seq,
                    pos_mm: s.pos_mm.0,
                },
                last,
            )
            .expect("the simulator fills the ring in order and within its capacity");
            meta.push_back((s.motion, s.feed_move, s.outputs));
            seq += 1;
        }
        let (motion, feed_move, outputs) = *meta.front().expect("a current sample");
        // the sample in use carries the outputs: a synchronised output switches at
        // the cycle where the next motion's first sample is in use
        engine.set_outputs(&outputs);
        let record = engine
            .step_ring(&ring, motion, feed_move)
            .expect("the window is in: N future samples or the end")?;
        // the actual position's distance to the programmed path near the command
        // (the position process measures it with the same function)
        let contour_mm = if feed_move {
            softnc_servo::contour::contour_error_near(
                &path,
                motion,
                Vec3(record.cmd_mm.xyz()),
                Vec3(record.actual_mm.xyz()),
            )
        } else {
            None
        };
        if let Some(c) = contour_mm {
            report.contour.add(c);
        }
        for (st, e) in report.following.iter_mut().zip(record.following_mm) {
            st.add(e);
        }
        observe(
            &TraceRow {
                cycle: k,
                time_s: k as f64 * cycle_s,
                motion,
                record,
                contour_mm,
                io: engine.io().trace(),
            },
            engine,
            ring.source_index(),
        );
        report.cycles += 1;
        let source = ring.source_index();
        if !ring.advance() {
            break;
        }
        if ring.source_index() > source {
            meta.pop_front();
        }
    }
    report.sim_time_s = report.cycles as f64 * cycle_s;
    Ok(report)
}

/// A command stream whose feed override can change between samples (the planner's
/// interpolator): what adaptive feed steers.
pub trait OverridableSamples: Iterator<Item = CommandSample> {
    /// The feed override (fraction) from the next sample on.
    fn set_feed_override(&mut self, override_frac: f64);
}

/// [`simulate_sequenced`] with adaptive feed (paper 003) closed as the daemon closes
/// it: `feed` steps on every cycle after the machine's; the override it gives at the
/// cycle that used sample `seq` acts from sample `seq + latency` on (the daemon's
/// `lookahead_samples`: the position process reports it, the interpolator applies it
/// to the first sample it has not sent), capped by `operator_override` (fraction),
/// and the job starts at 100 % capped the same way. `observe` also sees the
/// sample number in use (as [`simulate_sequenced`]) and each revolution the loop
/// closed.
///
/// # Panics
/// When `latency` is not beyond the samples the simulator reads ahead (the filter
/// window and one): the override would act on a sample already read.
#[allow(clippy::too_many_arguments)]
pub fn simulate_adaptive<B, I, P, F>(
    engine: &mut CycleEngine<B>,
    cycle_s: f64,
    samples: I,
    feed: &mut AdaptiveFeed,
    latency: u64,
    operator_override: f64,
    path: P,
    mut observe: F,
) -> Result<SimReport, BackendError>
where
    B: ServoBackend,
    I: OverridableSamples,
    P: Fn(u32) -> Option<Primitive>,
    F: FnMut(&TraceRow, &CycleEngine<B>, u64, Option<Revolution>),
{
    assert!(
        latency > engine.filter_window() as u64 + 1,
        "adaptive feed: a latency of {latency} samples is within the simulator's read-ahead"
    );
    let schedule = std::cell::RefCell::new(OverrideSchedule::new(latency));
    let mut samples = samples;
    feed.set_override_cap(operator_override);
    let start = operator_override.min(1.0);
    if start != 1.0 {
        samples.set_feed_override(start);
    }
    let mut next_seq = 0u64;
    let mut force_frac = 1.0f64;
    let stream = std::iter::from_fn(|| {
        if let Some(v) = schedule.borrow_mut().due(next_seq) {
            force_frac = v;
            samples.set_feed_override(force_frac.min(operator_override));
        }
        next_seq += 1;
        samples.next()
    });
    simulate_sequenced(engine, cycle_s, stream, path, |row, engine, seq| {
        let rev = feed.cycle(engine.backend());
        if let Some(r) = rev {
            schedule.borrow_mut().push(seq, r.override_frac);
        }
        observe(row, engine, seq, rev)
    })
}
