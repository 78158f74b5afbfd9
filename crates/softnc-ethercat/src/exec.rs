//! The executor the backend drives ethercrab's futures with: polled on the calling
//! thread with a no-op waker until ready or a deadline, sleeping [`POLL`] between
//! polls (a real-time thread that only yielded would keep every lower-priority
//! thread off its core — on a test machine, the emulated SubDevices). It allocates
//! nothing (the future is pinned on the stack), so the cycle stays bounded — at
//! most the deadline, plus any stall of the calling thread itself — and
//! allocation-free.

use std::future::Future;
use std::pin::pin;
use std::task::{Context, Poll, Waker};
use std::time::{Duration, Instant};

/// Sleep between polls.
pub const POLL: Duration = Duration::from_micros(10);

/// A gap between two polls longer than this is the polling thread's own stall (it
/// was not scheduled: a loaded machine, a virtual machine's CPU taken away), not
/// the bus's: the deadline moves by the gap, so that an answer that came while the
/// thread stood is not taken for a lost frame. The loop watch reports the stall
/// (`LoopLate`, `LoopStall`). Normal gaps are the sleep's timer slack, well under it.
pub const STALL: Duration = Duration::from_millis(2);

/// `f`'s output, or `None` when `deadline` (moved by the calling thread's own
/// stalls, [`STALL`]) passed first (the future is dropped, which gives its frame
/// back to ethercrab).
pub fn block_on<F: Future>(f: F, mut deadline: Instant) -> Option<F::Output> {
    let mut f = pin!(f);
    let mut cx = Context::from_waker(Waker::noop());
    let mut last = Instant::now();
    loop {
        if let Poll::Ready(v) = f.as_mut().poll(&mut cx) {
            return Some(v);
        }
        let now = Instant::now();
        let gap = now.saturating_duration_since(last);
        if gap > STALL {
            deadline += gap;
        }
        last = now;
        if now >= deadline {
            return None;
        }
        std::thread::sleep(POLL);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Pending on its first poll, during which the thread stands `stall` (as if
    /// descheduled); ready on the next.
    struct StallsOnce {
        stall: Duration,
        polled: bool,
    }

    impl Future for StallsOnce {
        type Output = ();
        fn poll(mut self: std::pin::Pin<&mut Self>, _: &mut Context<'_>) -> Poll<()> {
            if self.polled {
                return Poll::Ready(());
            }
            self.polled = true;
            std::thread::sleep(self.stall);
            Poll::Pending
        }
    }

    #[test]
    fn an_answer_that_came_while_the_thread_stood_is_taken() {
        // 20 ms standing against a 1 ms deadline: the answer is there at the next
        // poll, which the stall may not cost
        let f = StallsOnce {
            stall: Duration::from_millis(20),
            polled: false,
        };
        let deadline = Instant::now() + Duration::from_millis(1);
        assert_eq!(block_on(f, deadline), Some(()));
    }

    #[test]
    fn a_future_that_never_answers_ends_at_the_deadline() {
        let t0 = Instant::now();
        let never = std::future::pending::<()>();
        assert_eq!(block_on(never, t0 + Duration::from_millis(5)), None);
        let took = t0.elapsed();
        assert!(took >= Duration::from_millis(5), "{took:?}");
    }
}
