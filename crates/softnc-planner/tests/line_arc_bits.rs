//! `fillet::line_arc` gives the same bits as its
//! plain reference (`common/line_arc_perp.rs`) for every argument tried: the 200,000-line throughput
//! workload's joins (and them with other tolerances and shares), millions of random
//! line–arc corners in the three planes (every turn, nearly tangent and nearly
//! reversing joins, radii from 1 µm to 1 m, coordinates up to 1e5 mm, corners off
//! the circle, lines a little out of the plane), the same with one argument replaced
//! by an extreme value (zero, subnormal, huge, infinite, NaN), and arguments of random
//! bits. The reference counts where it went (`cover!`): every one of its rarer paths
//! must have been taken, so the comparison covers them.

use softnc_core::Vec3;
use softnc_planner::fillet::{self, ArcView, Fillet};
use std::cell::RefCell;

thread_local! {
    /// How often each `cover!` point of the reference was reached.
    static COVER: RefCell<Vec<u64>> = RefCell::new(vec![0; line_arc_perp::COVER_POINTS]);
}

macro_rules! cover {
    ($i:expr) => {
        crate::COVER.with(|c| c.borrow_mut()[$i] += 1)
    };
}

#[path = "common/line_arc_perp.rs"]
mod line_arc_perp;

#[path = "../benches/common/workload.rs"]
mod workload;

#[path = "../benches/common/fillet_joins.rs"]
mod fillet_joins;

/// Cases per generator in a release build (a debug build runs a twentieth).
const CASES: usize = if cfg!(debug_assertions) {
    100_000
} else {
    2_000_000
};

/// SplitMix64 (Steele, Lea, Flood 2014): a small generator with a fixed seed, so
/// that a failure can be run again.
struct Rng(u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }
    /// Log-uniform in [lo, hi] (both > 0).
    fn log(&mut self, lo: f64, hi: f64) -> f64 {
        (lo.ln() + (hi.ln() - lo.ln()) * self.unit()).exp()
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }
    fn sign(&mut self) -> f64 {
        if self.next_u64() & 1 == 0 {
            1.0
        } else {
            -1.0
        }
    }
    /// A value from the edges of the doubles, or random bits.
    fn extreme(&mut self) -> f64 {
        const EDGES: [f64; 16] = [
            0.0,
            -0.0,
            1.0,
            -1.0,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            f64::MIN_POSITIVE,
            5e-324,
            f64::MAX,
            -f64::MAX,
            1e-300,
            1e300,
            1e-9,
            1e-12,
            2.0,
        ];
        if self.next_u64().is_multiple_of(4) {
            f64::from_bits(self.next_u64())
        } else {
            EDGES[self.below(EDGES.len())]
        }
    }
}

/// The arguments of one `line_arc` call.
#[derive(Debug, Clone, Copy)]
struct Args {
    corner: Vec3,
    u: Vec3,
    line_avail: f64,
    arc: ArcView,
    arc_avail: f64,
    tol: f64,
}

/// The planes' axes as `Plane::axes` gives them.
const AXES: [(usize, usize, usize); 3] = [(0, 1, 2), (2, 0, 1), (1, 2, 0)];

/// A line–arc corner: an arc (centre, radius, direction) in one of the planes, a
/// corner on (or within 1e-4 mm of) its circle, and a line arriving there turned
/// from the arc's tangent by an angle of any size (often nearly 0 or nearly π).
fn corner_case(rng: &mut Rng) -> Args {
    let axes = AXES[rng.below(3)];
    let (a, b, n) = axes;
    let mut normal = Vec3::ZERO;
    normal[n] = 1.0;
    let big_r = rng.log(1e-3, 1e3);
    let span = [1.0, 1e2, 1e3, 1e5][rng.below(4)];
    let mut center = Vec3::ZERO;
    for i in 0..3 {
        center[i] = rng.range(-span, span);
    }
    let theta = rng.range(-std::f64::consts::PI, std::f64::consts::PI);
    let r_corner = if rng.below(3) == 0 {
        big_r + rng.range(-1e-4, 1e-4)
    } else {
        big_r
    };
    let mut corner = center;
    corner[a] += r_corner * theta.cos();
    corner[b] += r_corner * theta.sin();
    if rng.below(8) == 0 {
        corner[n] += rng.range(-1e-6, 1e-6);
    }
    let sense = rng.sign();
    // the arc's tangent at the corner, then the line's direction turned from it
    let (ta, tb) = (-theta.sin() * sense, theta.cos() * sense);
    let phi = match rng.below(4) {
        0 => rng.range(-std::f64::consts::PI, std::f64::consts::PI),
        1 => rng.sign() * rng.log(1e-10, 1e-2),
        2 => rng.sign() * (std::f64::consts::PI - rng.log(1e-10, 1e-2)),
        _ => rng.sign() * rng.range(0.1, 2.0),
    };
    let mut u = Vec3::ZERO;
    u[a] = ta * phi.cos() - tb * phi.sin();
    u[b] = ta * phi.sin() + tb * phi.cos();
    match rng.below(6) {
        0 => u[n] = rng.range(-2e-9, 2e-9),
        1 => u = u * (1.0 + rng.range(-1e-12, 1e-12)),
        _ => {}
    }
    let line_avail = match rng.below(5) {
        0 => rng.log(1e-10, 1e-3),
        _ => rng.log(1e-3, 10.0) * big_r.max(0.01),
    };
    let arc_avail = match rng.below(5) {
        0 => rng.log(1e-10, 1e-3),
        _ => rng.log(1e-3, 10.0) * big_r,
    };
    let tol = rng.log(1e-5, 1.0);
    Args {
        corner,
        u,
        line_avail,
        arc: ArcView {
            center,
            radius: big_r,
            normal,
            sense,
            len: arc_avail * 2.0,
            axes,
            orient: 1.0,
        },
        arc_avail,
        tol,
    }
}

/// `args` with one of its numbers (or the view's axes) replaced by an extreme value.
fn mutated(rng: &mut Rng, mut args: Args) -> Args {
    let x = rng.extreme();
    match rng.below(12) {
        0 => args.corner[rng.below(3)] = x,
        1 => args.u[rng.below(3)] = x,
        2 => args.line_avail = x,
        3 => args.arc.center[rng.below(3)] = x,
        4 => args.arc.radius = x,
        5 => args.arc.sense = x,
        6 => args.arc.orient = x,
        7 => args.arc_avail = x,
        8 => args.tol = x,
        9 => args.arc.axes = (rng.below(4), rng.below(4), rng.below(4)),
        10 => args.arc.normal[rng.below(3)] = x,
        _ => {
            args.corner[rng.below(3)] = x;
            args.u[rng.below(3)] = rng.extreme();
        }
    }
    args
}

/// Arguments of random bits and extreme values throughout (the view's axes a plane's).
fn raw_case(rng: &mut Rng) -> Args {
    let axes = AXES[rng.below(3)];
    let mut v = || {
        if rng.below(2) == 0 {
            f64::from_bits(rng.next_u64())
        } else {
            rng.extreme()
        }
    };
    let corner = Vec3([v(), v(), v()]);
    let u = Vec3([v(), v(), v()]);
    let (line_avail, arc_avail, tol) = (v(), v(), v());
    let arc = ArcView {
        center: Vec3([v(), v(), v()]),
        radius: v(),
        normal: Vec3([v(), v(), v()]),
        sense: v(),
        len: v(),
        axes,
        orient: v(),
    };
    Args {
        corner,
        u,
        line_avail,
        arc,
        arc_avail,
        tol,
    }
}

/// Every number of a fillet, as bits.
fn bits(f: &Fillet) -> [u64; 16] {
    [
        f.line_trim,
        f.arc_trim,
        f.arc_trim_rad,
        f.center[0],
        f.center[1],
        f.center[2],
        f.radius,
        f.p_line[0],
        f.p_line[1],
        f.p_line[2],
        f.p_arc[0],
        f.p_arc[1],
        f.p_arc[2],
        f.sweep,
        f.cos_sweep,
        f.sin_sweep,
    ]
    .map(f64::to_bits)
}

/// Whether `line_arc`'s debug assertions may be run on `a`: in a debug build the
/// closure bound is asserted (`closure_bound_mm`), which holds for what the builder
/// passes (a unit `u`, a view as `ArcView::of` builds it: `sense` and `orient` ±1,
/// the normal a unit axis) and need not otherwise. Release builds compare every
/// argument.
fn valid_in_debug(a: &Args) -> bool {
    !cfg!(debug_assertions)
        || ((a.u.norm() - 1.0).abs() <= 1e-9
            && a.arc.sense.abs() == 1.0
            && a.arc.orient.abs() == 1.0
            && a.arc.normal.norm() == 1.0)
}

/// `fillet::line_arc` and its reference on `a`; panics where they differ. Whether a
/// fillet was found.
fn same(a: &Args) -> bool {
    if !valid_in_debug(a) {
        return false;
    }
    let got = fillet::line_arc(a.corner, a.u, a.line_avail, &a.arc, a.arc_avail, a.tol);
    let want = line_arc_perp::line_arc(a.corner, a.u, a.line_avail, &a.arc, a.arc_avail, a.tol);
    match (&got, &want) {
        (None, None) => false,
        (Some(n), Some(o)) if bits(n) == bits(o) => true,
        _ => panic!("line_arc({a:?}):\n fast {got:?}\n reference {want:?}"),
    }
}

fn reset_cover() {
    COVER.with(|c| c.borrow_mut().iter_mut().for_each(|n| *n = 0));
}

fn cover_counts() -> Vec<u64> {
    COVER.with(|c| c.borrow().clone())
}

/// The workload's joins with their tolerance, and with other tolerances and shares.
/// The 200,000-line workload's line–arc joins (with its tolerance, `G64 P0.01`), and
/// the step through them a build takes (a debug build every 37th).
fn workload_joins() -> (Vec<fillet_joins::Join>, usize) {
    let p = workload::default_profile();
    let text = workload::big_program(200_000);
    let program = softnc_gcode::read_program(&text, "big.ngc", &p).unwrap();
    let joins = fillet_joins::joins(&program, 0.01);
    assert!(joins.len() > 190_000, "{} joins", joins.len());
    (joins, if cfg!(debug_assertions) { 37 } else { 1 })
}

#[test]
fn the_workloads_joins_give_the_same_bits() {
    let (joins, step) = workload_joins();
    let mut found = 0;
    for j in joins.iter().step_by(step) {
        for (tol, line_share, arc_share) in [
            (j.tol_mm, 1.0, 1.0),
            (1e-3, 1.0, 1.0),
            (0.1, 1.0, 1.0),
            (0.05, 0.01, 1.0),
            (0.01, 1.0, 0.003),
        ] {
            let a = Args {
                corner: j.corner,
                u: j.u,
                line_avail: j.line_avail_mm * line_share,
                arc: j.arc,
                arc_avail: j.arc_avail_mm * arc_share,
                tol,
            };
            found += usize::from(same(&a));
        }
    }
    assert!(found > joins.len() / step * 3, "{found} fillets");
}

/// Random corners, the same with one extreme argument, and random bits; the
/// reference's rarer paths all taken.
#[test]
fn random_and_adversarial_arguments_give_the_same_bits() {
    reset_cover();
    let mut rng = Rng(0x5eed_f111_e714);
    let (mut found, mut found_mutated) = (0, 0);
    for _ in 0..CASES {
        let a = corner_case(&mut rng);
        found += usize::from(same(&a));
        let m = mutated(&mut rng, a);
        found_mutated += usize::from(same(&m));
        let raw = raw_case(&mut rng);
        same(&raw);
    }
    // (most corners have a fillet; the extreme values leave a few)
    assert!(found > CASES / 4, "{found} of {CASES} corners blended");
    assert!(
        found_mutated > CASES / 20,
        "{found_mutated} mutated corners blended"
    );
    let counts = cover_counts()[..line_arc_perp::COVER_POINTS].to_vec();
    println!(
        "{found} corners and {found_mutated} mutated corners blended of {CASES}; paths {counts:?}"
    );
    for (i, n) in counts.iter().enumerate() {
        // (a debug build runs a twentieth of the cases, on valid arguments only:
        // some paths need the others)
        assert!(
            *n > 0 || cfg!(debug_assertions),
            "cover point {i} of the reference never reached: {counts:?}"
        );
    }
}
