//! Running a job offline: command samples → controller stacks → simulated machine, with
//! following error per axis and contour error during feed moves.

use crate::backend::{BackendError, ServoBackend, MAX_AXES};
use crate::engine::{CycleEngine, CycleRecord};
use crate::metrics::ErrorStats;
use softnc_core::{Primitive, Vec3};

/// One interpolated command sample (the planner's `Sample`, decoupled).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CommandSample {
    /// Command position (mm).
    pub pos_mm: [f64; MAX_AXES],
    /// Index of the program motion being executed.
    pub motion: u32,
    /// True during feed moves (G1/G2/G3): the tool cuts, contour error is measured.
    pub feed_move: bool,
}

/// What one simulated cycle produced, for traces and plots.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TraceRow {
    /// Cycle index from the start of the job.
    pub cycle: u64,
    /// Time (s) = cycle · T.
    pub time_s: f64,
    /// The sample's motion index.
    pub motion: u32,
    /// Command, measured position, following error, drive commands.
    pub record: CycleRecord,
    /// Signed contour error against the active feed move's programmed path (mm);
    /// `None` outside feed moves.
    pub contour_mm: Option<f64>,
}

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

/// Run `samples` through `engine` (reset at the first sample's position). `path(m)` is
/// the programmed path of motion `m` (`None` for dwells); `observe` sees every cycle.
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
    let mut samples = samples.into_iter().peekable();
    let mut report = SimReport::default();
    if let Some(first) = samples.peek() {
        engine.reset(first.pos_mm);
    }
    for (k, s) in samples.enumerate() {
        let record = engine.step(s.pos_mm, s.feed_move)?;
        let contour_mm = if s.feed_move {
            path(s.motion).map(|p| p.contour_error(Vec3(record.actual_mm)))
        } else {
            None
        };
        if let Some(c) = contour_mm {
            report.contour.add(c);
        }
        for (st, e) in report.following.iter_mut().zip(record.following_mm) {
            st.add(e);
        }
        observe(&TraceRow {
            cycle: k as u64,
            time_s: k as f64 * cycle_s,
            motion: s.motion,
            record,
            contour_mm,
        });
        report.cycles += 1;
    }
    report.sim_time_s = report.cycles as f64 * cycle_s;
    Ok(report)
}
