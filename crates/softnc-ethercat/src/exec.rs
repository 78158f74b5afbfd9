//! The executor the backend drives ethercrab's futures with: polled on the calling
//! thread with a no-op waker until ready or a deadline, sleeping [`POLL`] between
//! polls (a real-time thread that only yielded would keep every lower-priority
//! thread off its core — on a test machine, the emulated SubDevices). It allocates
//! nothing (the future is pinned on the stack), so the cycle stays bounded — at
//! most the deadline — and allocation-free.

use std::future::Future;
use std::pin::pin;
use std::task::{Context, Poll, Waker};
use std::time::{Duration, Instant};

/// Sleep between polls.
pub const POLL: Duration = Duration::from_micros(10);

/// `f`'s output, or `None` when `deadline` passed first (the future is dropped,
/// which gives its frame back to ethercrab).
pub fn block_on<F: Future>(f: F, deadline: Instant) -> Option<F::Output> {
    let mut f = pin!(f);
    let mut cx = Context::from_waker(Waker::noop());
    loop {
        if let Poll::Ready(v) = f.as_mut().poll(&mut cx) {
            return Some(v);
        }
        if Instant::now() >= deadline {
            return None;
        }
        std::thread::sleep(POLL);
    }
}
