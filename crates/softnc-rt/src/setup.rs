//! Real-time set-up of the calling thread: pin, SCHED_FIFO, mlockall. Each step is
//! tried when asked for; a refusal (no permission, one core) is reported and the
//! process continues without it.

use iceoryx2_bb_posix::memory_lock::{LockMode, MemoryLock};

/// What to try.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RtOptions {
    /// Pin the thread to this core.
    #[serde(default)]
    pub core: Option<usize>,
    /// SCHED_FIFO priority (1..=99).
    #[serde(default)]
    pub fifo_priority: Option<u8>,
    /// Lock all current and future memory (mlockall).
    #[serde(default)]
    pub lock_memory: bool,
}

impl RtOptions {
    /// The SCHED_FIFO priority of a thread that carries this loop's messages (its
    /// publisher): one below the loop's, none if the loop has none.
    pub fn helper_priority(&self) -> Option<u8> {
        self.fifo_priority.map(|p| p.saturating_sub(1).max(1))
    }
}

/// What worked, and warnings for what did not.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RtReport {
    /// Pinned to this core.
    pub pinned: Option<usize>,
    /// Running SCHED_FIFO at this priority.
    pub fifo: Option<u8>,
    /// Memory locked.
    pub memory_locked: bool,
    /// What was asked and refused.
    pub warnings: Vec<String>,
}

/// Apply `opts` to the calling thread (and, for memory, the process).
pub fn setup_realtime(opts: &RtOptions) -> RtReport {
    let mut r = RtReport::default();
    if let Some(core) = opts.core {
        let ids = core_affinity::get_core_ids().unwrap_or_default();
        match ids.into_iter().find(|c| c.id == core) {
            Some(id) if core_affinity::set_for_current(id) => r.pinned = Some(core),
            _ => r
                .warnings
                .push(format!("could not pin to core {core}; running unpinned")),
        }
    }
    if let Some(prio) = opts.fifo_priority {
        use thread_priority::{
            set_thread_priority_and_policy, thread_native_id, RealtimeThreadSchedulePolicy,
            ThreadPriority, ThreadSchedulePolicy,
        };
        let res = ThreadPriority::from_posix(thread_priority::ScheduleParams {
            sched_priority: prio as i32,
        });
        let ok = set_thread_priority_and_policy(
            thread_native_id(),
            res,
            ThreadSchedulePolicy::Realtime(RealtimeThreadSchedulePolicy::Fifo),
        );
        match ok {
            Ok(()) => r.fifo = Some(prio),
            Err(e) => r.warnings.push(format!(
                "SCHED_FIFO {prio} refused ({e:?}); running SCHED_OTHER"
            )),
        }
    }
    if opts.lock_memory {
        // current pages first, then every page mapped from now on
        let locked = MemoryLock::lock_all(LockMode::LockAllPagesCurrentlyMapped)
            .and_then(|()| MemoryLock::lock_all(LockMode::LockAllPagesThatBecomeMapped));
        match locked {
            Ok(()) => r.memory_locked = true,
            Err(e) => r
                .warnings
                .push(format!("mlockall refused ({e:?}); memory may page")),
        }
    }
    for w in &r.warnings {
        tracing::warn!("{w}");
    }
    r
}

/// Put the calling thread back to SCHED_OTHER: for helper threads that a real-time
/// thread starts (they inherit its SCHED_FIFO priority and core). On the real-time
/// thread's core such a helper then runs only while the real-time thread sleeps.
pub fn leave_realtime() -> Result<(), String> {
    use thread_priority::{
        set_thread_priority_and_policy, thread_native_id, NormalThreadSchedulePolicy,
        ThreadPriority, ThreadSchedulePolicy,
    };
    let normal = ThreadPriority::from_posix(thread_priority::ScheduleParams { sched_priority: 0 });
    set_thread_priority_and_policy(
        thread_native_id(),
        normal,
        ThreadSchedulePolicy::Normal(NormalThreadSchedulePolicy::Other),
    )
    .map_err(|e| format!("cannot leave SCHED_FIFO: {e:?}"))
}
