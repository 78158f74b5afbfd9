//! Fixed-period cycles on absolute deadlines.

use std::time::{Duration, Instant};

/// Sleeps until each cycle's absolute deadline: deadline(k) = start + (k − k₀)·period,
/// in 64-bit nanoseconds (no wrap in 584 years at any period).
#[derive(Debug)]
pub struct PeriodicClock {
    start: Instant,
    period: Duration,
    cycle: u64,
    /// The cycle count at `start`.
    first_cycle: u64,
    spin: Duration,
    last_wake: Option<Instant>,
}

impl PeriodicClock {
    /// A clock whose first deadline is one period from now. `spin` is how long before
    /// a deadline the clock stops sleeping and busy-waits (0 = sleep only).
    pub fn new(period: Duration, spin: Duration) -> Self {
        Self::from_cycle(period, spin, 0)
    }

    /// A clock whose cycle count starts at `cycle` (a loop that has already run that
    /// many cycles; tests start it near a counter's limit).
    pub fn from_cycle(period: Duration, spin: Duration, cycle: u64) -> Self {
        PeriodicClock {
            start: Instant::now(),
            period,
            cycle,
            first_cycle: cycle,
            spin,
            last_wake: None,
        }
    }

    /// The absolute deadline of cycle `k`.
    fn deadline(&self, k: u64) -> Instant {
        let n = u64::try_from(self.period.as_nanos()).unwrap_or(u64::MAX);
        self.start + Duration::from_nanos(n.saturating_mul(k - self.first_cycle))
    }

    /// The period.
    pub fn period(&self) -> Duration {
        self.period
    }

    /// Cycles completed.
    pub fn cycle(&self) -> u64 {
        self.cycle
    }

    /// Wait for the next deadline. Returns the wake-up time and the period jitter
    /// |actual period − nominal| of this wake-up (zero on the first). If the loop is
    /// more than one period late, the missed deadlines are skipped (counted by the
    /// caller as overruns through the returned `late_cycles`).
    pub fn wait(&mut self) -> (Instant, Duration, u64) {
        self.cycle += 1;
        let mut deadline = self.deadline(self.cycle);
        let now = Instant::now();
        let mut late_cycles = 0;
        if now > deadline + self.period {
            late_cycles = ((now - deadline).as_nanos() / self.period.as_nanos().max(1)) as u64;
            self.cycle += late_cycles;
            deadline = self.deadline(self.cycle);
        }
        let sleep_until = deadline.checked_sub(self.spin).unwrap_or(deadline);
        let now = Instant::now();
        if sleep_until > now {
            std::thread::sleep(sleep_until - now);
        }
        while Instant::now() < deadline {
            std::hint::spin_loop();
        }
        let woke = Instant::now();
        let jitter = match self.last_wake {
            Some(prev) => (woke - prev).abs_diff(self.period),
            None => Duration::ZERO,
        };
        self.last_wake = Some(woke);
        (woke, jitter, late_cycles)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn deadlines_do_not_drift() {
        let period = Duration::from_millis(2);
        let mut c = PeriodicClock::new(period, Duration::from_micros(200));
        let t0 = c.start;
        for _ in 0..50 {
            let _ = c.wait();
        }
        // the 50th wake-up is at or after start + 50 periods, whatever each sleep cost
        assert!(Instant::now() >= t0 + period * 50);
        assert!(c.cycle() >= 50);
    }

    #[test]
    fn the_clock_keeps_sleeping_past_two_to_the_32_cycles() {
        // 49.7 days at 1 kHz, 6.2 days at 8 kHz: a 32-bit cycle product wrapped here
        // and every deadline after it lay in the past (the loop never slept again)
        let period = Duration::from_millis(2);
        let mut c = PeriodicClock::from_cycle(period, Duration::ZERO, u64::from(u32::MAX) - 3);
        let t0 = Instant::now();
        for _ in 0..10 {
            let _ = c.wait();
        }
        assert!(c.cycle() > u64::from(u32::MAX) + 5);
        assert!(
            t0.elapsed() >= period * 10,
            "10 cycles took {:?}, less than 10 periods",
            t0.elapsed()
        );
    }
}
