//! The line–arc and arc–line joins of the throughput workload ([`big_program`]) as
//! `fillet::line_arc` gets them from the builder: for the fillet benchmark and the
//! bit-identity test of `line_arc`.
#![allow(dead_code)] // each user takes what it needs

use softnc_core::{Primitive, Vec3};
use softnc_planner::build::motion_primitive;
use softnc_planner::fillet::ArcView;

/// The arguments of one `line_arc` call.
#[derive(Debug, Clone, Copy)]
pub struct Join {
    pub corner: Vec3,
    pub u: Vec3,
    pub line_avail_mm: f64,
    pub arc: ArcView,
    pub arc_avail_mm: f64,
    pub tol_mm: f64,
}

/// Largest tangent drift of an arc that is blended (rad): generous, the workload's
/// arcs have none.
const MAX_DRIFT_RAD: f64 = 0.1;

/// The joins of `program` between a line and an arc, in order, with the shares the
/// builder gives where no blend trimmed the move before (half of each move) and the
/// tolerance `tol_mm`.
pub fn joins(program: &softnc_gcode::Program, tol_mm: f64) -> Vec<Join> {
    let prims: Vec<Primitive> = program
        .motions
        .iter()
        .filter_map(motion_primitive)
        .collect();
    let mut out = Vec::new();
    for w in prims.windows(2) {
        let (a, b) = (&w[0], &w[1]);
        match (a, b) {
            (&Primitive::Line { start, end }, Primitive::Arc { .. }) => {
                let len = (end - start).norm();
                if len < 1e-9 {
                    continue;
                }
                if let Some(arc) = ArcView::of(b, false, MAX_DRIFT_RAD) {
                    out.push(Join {
                        corner: end,
                        u: (end - start) * (1.0 / len),
                        line_avail_mm: 0.5 * len,
                        arc,
                        arc_avail_mm: 0.5 * b.length(),
                        tol_mm,
                    });
                }
            }
            (Primitive::Arc { .. }, &Primitive::Line { start, end }) => {
                let len = (end - start).norm();
                if len < 1e-9 {
                    continue;
                }
                if let Some(arc) = ArcView::of(a, true, MAX_DRIFT_RAD) {
                    out.push(Join {
                        corner: start,
                        u: -((end - start) * (1.0 / len)),
                        line_avail_mm: 0.5 * len,
                        arc,
                        arc_avail_mm: 0.5 * a.length(),
                        tol_mm,
                    });
                }
            }
            _ => {}
        }
    }
    out
}
