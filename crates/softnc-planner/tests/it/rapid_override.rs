//! Rapid override (issue 35): traverses run at the rapid override, feed moves at the
//! feed override, as LinuxCNC's `rapid_scale` and `feed_scale`; a change acts within
//! the lookahead as the feed override does, within every limit.

use super::common;
use common::{limit_ratios, profile};
use softnc_core::{FeedProfile, MotionProfile};
use softnc_planner::{check_and_stream, PlanOptions, Sample, StreamInterpolator};

const BOTH: [FeedProfile; 2] = [FeedProfile::Trapezoidal, FeedProfile::SCurve];

/// Long traverses only (each far longer than its acceleration distance).
const RAPIDS: &str = "G21 G90 G61\nG0 X350 Y200\nG0 X-350 Y-200 Z-250\nG0 X300 Y0 Z50\nM2\n";

/// Stream `text`, calling `each` before each sample is pulled (with its number).
fn samples_of(
    text: &str,
    p: &MotionProfile,
    mut each: impl FnMut(usize, &mut StreamInterpolator),
) -> Vec<Sample> {
    check_and_stream(text, "t.ngc", p, &PlanOptions::default(), |it| {
        let mut out = Vec::new();
        loop {
            each(out.len(), it);
            match it.next() {
                Some(s) => out.push(s),
                None => break out,
            }
        }
    })
    .unwrap_or_else(|e| panic!("{e}"))
    .1
}

fn assert_within_limits(samples: &[Sample], p: &MotionProfile, what: &str) {
    let r = limit_ratios(samples, p);
    let jerk_checked = p.planner.feed_profile == FeedProfile::SCurve;
    assert!(
        r[0] <= 1.0 + 1e-9 && r[1] <= 1.0 + 1e-9 && (!jerk_checked || r[2] <= 1.0 + 1e-9),
        "{what}: limit ratios v, a, j = {r:?}"
    );
}

#[test]
fn half_rapid_override_takes_about_twice_as_long_within_the_limits() {
    for fp in BOTH {
        let p = profile(fp);
        let full = samples_of(RAPIDS, &p, |_, _| {});
        let half = samples_of(RAPIDS, &p, |n, it| {
            if n == 0 {
                it.set_rapid_override(0.5);
            }
        });
        // twice as long at half the speed, less what accelerating takes: at the
        // S-curve's lower tangential acceleration that is a larger share
        let ratio = half.len() as f64 / full.len() as f64;
        let least = match fp {
            FeedProfile::Trapezoidal => 1.85,
            FeedProfile::SCurve => 1.6,
        };
        assert!(
            (least..=2.0).contains(&ratio),
            "{fp:?}: {} / {} samples",
            half.len(),
            full.len()
        );
        let peak = |s: &[Sample]| {
            s.windows(2)
                .map(|w| (w[1].pos_mm - w[0].pos_mm).norm())
                .fold(0.0f64, f64::max)
        };
        let speed_ratio = peak(&half) / peak(&full);
        assert!(
            (speed_ratio - 0.5).abs() < 1e-6,
            "{fp:?}: peak speed ratio {speed_ratio}"
        );
        assert_eq!(half.last().unwrap().pos_mm, full.last().unwrap().pos_mm);
        assert_within_limits(&half, &p, "50 %");
        // no axis above half its limit
        let r = limit_ratios(&half, &p);
        assert!(r[0] <= 0.5 + 1e-9, "{fp:?}: speed ratio {}", r[0]);
        // the feed override leaves traverses alone
        let feed_half = samples_of(RAPIDS, &p, |n, it| {
            if n == 0 {
                it.set_feed_override(0.5);
            }
        });
        assert_eq!(feed_half.len(), full.len(), "{fp:?}");
    }
}

#[test]
fn a_rapid_override_change_acts_within_the_lookahead_and_leaves_feeds_alone() {
    let text = "G21 G90 G61\nG0 X350 Y200\nG1 X0 Y0 F6000\nG0 X-350\nM2\n";
    for fp in BOTH {
        let p = profile(fp);
        let full = samples_of(text, &p, |_, _| {});
        let mut low_at = None;
        let changed = samples_of(text, &p, |n, it| {
            // mid-rapid, down to 20 %, and back up to 100 % in the feed move
            if n == 300 {
                it.set_rapid_override(0.2);
                low_at = Some(n);
            }
        });
        assert!(low_at.is_some());
        assert!(changed.len() > full.len(), "{fp:?}");
        assert_within_limits(&changed, &p, "20 % mid-rapid");
        // the feed move in the middle runs at its feed as before: its samples'
        // speeds are the same in both (compare the longest stretch at its feed)
        let feed_speed = |s: &[Sample]| {
            s.windows(2)
                .filter(|w| w[1].feed_move && w[0].feed_move)
                .map(|w| (w[1].pos_mm - w[0].pos_mm).norm() / p.interpolation_cycle_s)
                .fold(0.0f64, f64::max)
        };
        let (a, b) = (feed_speed(&full), feed_speed(&changed));
        assert!((a - b).abs() < 1e-6 * a, "{fp:?}: feed {a} vs {b} mm/s");
        assert!((a - 100.0).abs() < 1e-6, "{fp:?}: feed {a} mm/s");
    }
}

/// A feed hold (the feed override at 0, as the daemon holds) stops traverses too.
#[test]
fn a_feed_hold_stops_traverses() {
    let p = profile(FeedProfile::Trapezoidal);
    let held = samples_of(RAPIDS, &p, |n, it| {
        if n == 100 {
            it.set_feed_override(0.0);
        }
        if n == 3000 {
            it.set_feed_override(1.0);
        }
    });
    assert!(
        (1500..2999).all(|k| held[k].pos_mm == held[k + 1].pos_mm),
        "traverses ran through the hold"
    );
}
