//! A real-time loop's own watch over its timing (issue 34): each wake-up's period
//! against the configured bounds ([`crate::config::LoopTimingConfig`]). A stall (a
//! period beyond `stall_fault_s`: the loop was stopped or starved) is the loop's to
//! act on at once; late cycles (beyond `late_alarm_s`) are counted and reported at
//! most once per `late_alarm_period_s`, so a loop under load raises one alarm, not
//! one per cycle. Allocation-free: it runs on the cycle.

use crate::config::LoopTimingConfig;
use std::time::{Duration, Instant};

/// What a wake-up's period says.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LoopEvent {
    /// The loop stood for `period` (far beyond its bound).
    Stall {
        /// The period from the wake-up before to this one.
        period: Duration,
    },
    /// `count` late cycles since the last report, the worst off by `worst`.
    Late {
        /// Late cycles counted.
        count: u64,
        /// The largest deviation of a period from the nominal.
        worst: Duration,
        /// Over how long they were counted.
        over: Duration,
    },
}

/// The watch over one loop.
#[derive(Debug, Clone)]
pub struct LoopWatch {
    nominal: Duration,
    stall: Duration,
    late: Duration,
    report_every: Duration,
    count: u64,
    worst: Duration,
    since: Option<Instant>,
    last_report: Option<Instant>,
}

impl LoopWatch {
    /// A watch over a loop of period `nominal`, with the bounds `cfg`.
    pub fn new(cfg: &LoopTimingConfig, nominal: Duration) -> Self {
        LoopWatch {
            nominal,
            stall: Duration::from_secs_f64(cfg.stall_fault_s),
            late: Duration::from_secs_f64(cfg.late_alarm_s),
            report_every: Duration::from_secs_f64(cfg.late_alarm_period_s),
            count: 0,
            worst: Duration::ZERO,
            since: None,
            last_report: None,
        }
    }

    /// The stall bound.
    pub fn stall_bound(&self) -> Duration {
        self.stall
    }

    /// The late-cycle bound.
    pub fn late_bound(&self) -> Duration {
        self.late
    }

    /// One wake-up at `now` whose period was off the nominal by `jitter` (as
    /// `softnc_rt::PeriodicClock::wait` gives it).
    pub fn observe(&mut self, jitter: Duration, now: Instant) -> Option<LoopEvent> {
        let period = self.nominal + jitter;
        if jitter > self.stall {
            return Some(LoopEvent::Stall { period });
        }
        if jitter > self.late {
            self.count += 1;
            self.worst = self.worst.max(jitter);
            self.since.get_or_insert(now);
        }
        let due = self
            .last_report
            .is_none_or(|t| now.duration_since(t) >= self.report_every);
        if self.count > 0 && due {
            let ev = LoopEvent::Late {
                count: self.count,
                worst: self.worst,
                over: self.since.map_or(Duration::ZERO, |t| now.duration_since(t)),
            };
            self.count = 0;
            self.worst = Duration::ZERO;
            self.since = None;
            self.last_report = Some(now);
            return Some(ev);
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn watch() -> LoopWatch {
        LoopWatch::new(&LoopTimingConfig::default(), Duration::from_millis(1))
    }

    #[test]
    fn a_period_beyond_the_stall_bound_is_a_stall() {
        let mut w = watch();
        let t = Instant::now();
        assert_eq!(w.observe(Duration::from_micros(50), t), None);
        assert_eq!(
            w.observe(Duration::from_millis(999), t),
            Some(LoopEvent::Stall {
                period: Duration::from_millis(1000)
            })
        );
    }

    #[test]
    fn late_cycles_are_reported_once_then_at_most_once_per_period() {
        let mut w = watch();
        let t0 = Instant::now();
        let late = Duration::from_millis(21);
        assert!(matches!(
            w.observe(late, t0),
            Some(LoopEvent::Late { count: 1, .. })
        ));
        // a second of late cycles: counted, not reported
        for k in 1..1000 {
            let at = t0 + Duration::from_millis(k);
            assert_eq!(w.observe(late, at), None, "cycle {k}");
        }
        // on time, but the period is over: the count goes out
        let at = t0 + Duration::from_secs(10);
        match w.observe(Duration::ZERO, at) {
            Some(LoopEvent::Late { count, worst, .. }) => {
                assert_eq!((count, worst), (999, late));
            }
            other => panic!("{other:?}"),
        }
        assert_eq!(w.observe(Duration::ZERO, at), None);
    }
}
