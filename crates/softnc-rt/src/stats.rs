//! Loop timing statistics: period jitter and compute time histograms.

use hdrhistogram::Histogram;
use std::time::Duration;

/// p50, p99, p99.9 and max of a histogram (ns).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
pub struct Percentiles {
    /// Median.
    pub p50_ns: u64,
    /// 99th percentile.
    pub p99_ns: u64,
    /// 99.9th percentile.
    pub p999_ns: u64,
    /// Maximum.
    pub max_ns: u64,
}

/// Jitter and compute-time histograms of one loop. Allocated once in `new`;
/// `record` never allocates (values are clamped into the histogram's range).
#[derive(Debug, Clone)]
pub struct LoopStats {
    jitter: Histogram<u64>,
    compute: Histogram<u64>,
    overruns: u64,
}

/// Largest value the histograms hold (ns): 10 s.
const MAX_NS: u64 = 10_000_000_000;

impl Default for LoopStats {
    fn default() -> Self {
        Self::new()
    }
}

impl LoopStats {
    /// Empty histograms, 1 ns .. 10 s at 3 significant digits.
    pub fn new() -> Self {
        let h = || Histogram::<u64>::new_with_bounds(1, MAX_NS, 3).expect("valid histogram bounds");
        LoopStats {
            jitter: h(),
            compute: h(),
            overruns: 0,
        }
    }

    /// Record one cycle.
    pub fn record(&mut self, jitter: Duration, compute: Duration, late_cycles: u64) {
        let clamp = |d: Duration| (d.as_nanos() as u64).clamp(1, MAX_NS);
        self.jitter.saturating_record(clamp(jitter));
        self.compute.saturating_record(clamp(compute));
        self.overruns += late_cycles;
    }

    /// Cycles recorded.
    pub fn cycles(&self) -> u64 {
        self.compute.len()
    }

    /// Deadlines missed.
    pub fn overruns(&self) -> u64 {
        self.overruns
    }

    fn pct(h: &Histogram<u64>) -> Percentiles {
        if h.is_empty() {
            return Percentiles::default();
        }
        Percentiles {
            p50_ns: h.value_at_quantile(0.5),
            p99_ns: h.value_at_quantile(0.99),
            p999_ns: h.value_at_quantile(0.999),
            max_ns: h.max(),
        }
    }

    /// Period jitter percentiles.
    pub fn jitter(&self) -> Percentiles {
        Self::pct(&self.jitter)
    }

    /// Compute-time percentiles.
    pub fn compute(&self) -> Percentiles {
        Self::pct(&self.compute)
    }
}

/// One latency histogram (ns), allocated once, recorded without allocating.
#[derive(Debug, Clone)]
pub struct LatencyStats {
    h: Histogram<u64>,
}

impl Default for LatencyStats {
    fn default() -> Self {
        Self::new()
    }
}

impl LatencyStats {
    /// Empty, 1 ns .. 10 s at 3 significant digits.
    pub fn new() -> Self {
        LatencyStats {
            h: Histogram::<u64>::new_with_bounds(1, MAX_NS, 3).expect("valid histogram bounds"),
        }
    }
    /// Record one latency (clamped into range).
    pub fn record_ns(&mut self, ns: u64) {
        self.h.saturating_record(ns.clamp(1, MAX_NS));
    }
    /// Percentiles so far.
    pub fn percentiles(&self) -> Percentiles {
        LoopStats::pct(&self.h)
    }
}

/// Nanoseconds since the Unix epoch (the clock both processes share).
pub fn unix_ns() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos() as u64)
        .unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_of_known_values() {
        let mut s = LoopStats::new();
        for k in 1..=1000u64 {
            s.record(Duration::from_nanos(k * 1000), Duration::from_nanos(500), 0);
        }
        let j = s.jitter();
        assert!((j.p50_ns as i64 - 500_000).abs() < 1000, "{j:?}");
        assert!((j.p99_ns as i64 - 990_000).abs() < 2000, "{j:?}");
        assert!(j.max_ns >= 999_000);
        assert_eq!(s.cycles(), 1000);
    }
}
