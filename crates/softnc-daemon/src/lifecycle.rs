//! How a controller's processes begin and end: one controller per instance (a lock),
//! a stop asked for by SIGTERM/SIGINT or by the parent's death (a child never runs on
//! without its `softncd`), and systemd's readiness and watchdog notifications.
//!
//! The stop request is one atomic flag that a watcher thread of its own sets: the
//! cyclic loops read it without a lock or a system call. SIGTERM and SIGINT are
//! caught by a handler of ours that sets a sticky flag ([`termination_requested`]):
//! once set it stays set, whatever signal follows (systemd and `timeout` send
//! SIGCONT right after SIGTERM; iceoryx2's own "last signal" is overwritten by it,
//! and by iceoryx2's shared-memory calls, so it is not used). The watcher polls the
//! flag every [`WATCH_PERIOD`].

use iceoryx2_bb_posix::signal::SignalHandler;
use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU8, Ordering};
use std::sync::Arc;
use std::time::Duration;

/// How often the watcher looks for a signal and at its parent.
pub const WATCH_PERIOD: Duration = Duration::from_millis(10);

/// Set by the SIGTERM/SIGINT handler, never cleared.
static TERMINATION: AtomicBool = AtomicBool::new(false);

extern "C" fn on_termination_signal(_signal: libc::c_int) {
    // async-signal-safe: one atomic store
    TERMINATION.store(true, Ordering::SeqCst);
}

/// Whether SIGTERM or SIGINT has arrived since [`catch_termination_signals`] (sticky:
/// later signals, SIGCONT included, do not clear it).
pub fn termination_requested() -> bool {
    TERMINATION.load(Ordering::SeqCst)
}

/// Catch SIGTERM and SIGINT with a handler that sets [`termination_requested`].
/// iceoryx2's signal handler (installed on first use, by it or by us) is set up
/// first so that it never replaces ours later.
#[allow(unsafe_code)] // (its SAFETY lines below)
pub fn catch_termination_signals() -> std::io::Result<()> {
    let _ = SignalHandler::last_signal();
    for sig in [libc::SIGTERM, libc::SIGINT] {
        // SAFETY: a zeroed sigaction is valid (no flags, empty mask) before we fill
        // it; the handler only stores to an atomic (async-signal-safe); sigaction
        // is given valid pointers.
        let rc = unsafe {
            let mut action: libc::sigaction = std::mem::zeroed();
            action.sa_sigaction = on_termination_signal as extern "C" fn(libc::c_int) as usize;
            action.sa_flags = libc::SA_RESTART;
            libc::sigemptyset(&mut action.sa_mask);
            libc::sigaction(sig, &action, std::ptr::null_mut())
        };
        if rc != 0 {
            return Err(std::io::Error::last_os_error());
        }
    }
    Ok(())
}

/// Why a process was asked to stop.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StopReason {
    /// SIGTERM or SIGINT.
    Signal,
    /// The process that started it has died (it was reparented).
    ParentLost,
}

impl StopReason {
    fn wire(self) -> u8 {
        match self {
            StopReason::Signal => 1,
            StopReason::ParentLost => 2,
        }
    }

    fn from_wire(v: u8) -> Option<Self> {
        match v {
            1 => Some(StopReason::Signal),
            2 => Some(StopReason::ParentLost),
            _ => None,
        }
    }
}

/// A stop request, set by the watcher thread; cloned into whoever needs to look.
#[derive(Debug, Clone)]
pub struct StopWatch {
    reason: Arc<AtomicU8>,
}

impl StopWatch {
    /// Catch SIGTERM and SIGINT from now on and start the watcher; `watch_parent`:
    /// also stop when the parent process dies (the children of `softncd`).
    pub fn start(watch_parent: bool) -> std::io::Result<StopWatch> {
        // installs the handler now, before any signal can arrive
        catch_termination_signals()?;
        let reason = Arc::new(AtomicU8::new(0));
        let parent = std::os::unix::process::parent_id();
        let r = reason.clone();
        std::thread::Builder::new()
            .name("stop-watch".into())
            .spawn(move || {
                // started by a real-time thread perhaps: not at its priority
                let _ = softnc_rt::leave_realtime();
                loop {
                    let why = if termination_requested() {
                        Some(StopReason::Signal)
                    } else if watch_parent && std::os::unix::process::parent_id() != parent {
                        Some(StopReason::ParentLost)
                    } else {
                        None
                    };
                    if let Some(why) = why {
                        let _ =
                            r.compare_exchange(0, why.wire(), Ordering::AcqRel, Ordering::Acquire);
                        return;
                    }
                    std::thread::sleep(WATCH_PERIOD);
                }
            })?;
        Ok(StopWatch { reason })
    }

    /// A watch that only [`StopWatch::request`] sets (tests, in-process tasks).
    pub fn manual() -> StopWatch {
        StopWatch {
            reason: Arc::new(AtomicU8::new(0)),
        }
    }

    /// Ask for a stop (the first reason stays).
    pub fn request(&self, why: StopReason) {
        let _ = self
            .reason
            .compare_exchange(0, why.wire(), Ordering::AcqRel, Ordering::Acquire);
    }

    /// Whether, and why, a stop was asked for: one atomic load (for the cycle).
    pub fn requested(&self) -> Option<StopReason> {
        StopReason::from_wire(self.reason.load(Ordering::Acquire))
    }
}

/// Refusals of [`InstanceLock::acquire`].
#[derive(Debug, thiserror::Error)]
pub enum LockError {
    /// Another `softncd` holds the instance.
    #[error("instance {instance:?} is already controlled by softncd pid {pid} (lock {path}); one controller per instance")]
    Held {
        /// The instance.
        instance: String,
        /// The holder's pid, as it wrote it.
        pid: String,
        /// The lock file.
        path: PathBuf,
    },
    /// The run folder is not one only this user can write.
    #[error(transparent)]
    Folder(#[from] PrivateDirError),
    /// The lock file cannot be opened or locked.
    #[error("{path}: cannot lock: {why}")]
    Io {
        /// The lock file.
        path: PathBuf,
        /// Why (said in the message, not chained again after it).
        why: std::io::Error,
    },
}

/// A folder that lock and runtime files may not go into.
#[derive(Debug, thiserror::Error)]
pub enum PrivateDirError {
    /// It cannot be read (absent, no access).
    #[error("run folder {path}: {source}")]
    Unreadable {
        /// The folder.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// A symbolic link or not a folder at all.
    #[error("run folder {path} is not a folder (a link or a file): refused")]
    NotAFolder {
        /// The path.
        path: PathBuf,
    },
    /// Owned by another user.
    #[error("run folder {path} belongs to uid {owner}, not to this user (uid {me}): refused; lock and runtime files go in a folder only softncd's user can write")]
    ForeignOwner {
        /// The folder.
        path: PathBuf,
        /// Its owner.
        owner: u32,
        /// Our effective uid.
        me: u32,
    },
    /// Group or others may write in it.
    #[error("run folder {path} is writable by group or others (mode {mode:o}): refused; lock and runtime files go in a folder only softncd's user can write (chmod go-w)")]
    Writable {
        /// The folder.
        path: PathBuf,
        /// Its permission bits.
        mode: u32,
    },
}

pub use softnc_ipc::ipc_guard::effective_uid;

/// Check that `dir` is a folder (not a link) of this user that neither its group nor
/// others may write: files opened in it cannot be planted, replaced or linked by
/// another local user.
pub fn check_private_dir(dir: &Path) -> Result<(), PrivateDirError> {
    use std::os::unix::fs::MetadataExt;
    let meta = std::fs::symlink_metadata(dir).map_err(|source| PrivateDirError::Unreadable {
        path: dir.to_path_buf(),
        source,
    })?;
    if !meta.file_type().is_dir() {
        return Err(PrivateDirError::NotAFolder {
            path: dir.to_path_buf(),
        });
    }
    let me = effective_uid();
    if meta.uid() != me {
        return Err(PrivateDirError::ForeignOwner {
            path: dir.to_path_buf(),
            owner: meta.uid(),
            me,
        });
    }
    if meta.mode() & 0o022 != 0 {
        return Err(PrivateDirError::Writable {
            path: dir.to_path_buf(),
            mode: meta.mode() & 0o7777,
        });
    }
    Ok(())
}

/// The folder of an instance's lock and runtime files: `$SOFTNC_RUN_DIR` when set,
/// else the instance's data folder `data_dir` (created by its first use; not `/tmp`,
/// where anyone can plant a file or a link).
pub fn run_dir(data_dir: &Path) -> PathBuf {
    std::env::var_os("SOFTNC_RUN_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| data_dir.to_path_buf())
}

/// One controller per instance: an exclusive lock on a file named after the
/// service prefix and instance, held for the process's life (the kernel drops it
/// when the process dies, `kill -9` included).
#[derive(Debug)]
pub struct InstanceLock {
    _file: File,
    path: PathBuf,
}

impl InstanceLock {
    /// The lock file of an instance in run folder `dir` ([`run_dir`]).
    pub fn path_of(dir: &Path, service_prefix: &str, instance: &str) -> PathBuf {
        let safe = |s: &str| {
            s.chars()
                .map(|c| {
                    if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                        c
                    } else {
                        '_'
                    }
                })
                .collect::<String>()
        };
        dir.join(format!(
            "softnc-{}-{}.lock",
            safe(service_prefix),
            safe(instance)
        ))
    }

    /// Take the instance's lock in [`run_dir`]`(data_dir)`, or say who holds it; the
    /// folder must be this user's alone ([`check_private_dir`]).
    pub fn acquire(
        data_dir: &Path,
        service_prefix: &str,
        instance: &str,
    ) -> Result<InstanceLock, LockError> {
        let dir = run_dir(data_dir);
        if std::env::var_os("SOFTNC_RUN_DIR").is_none() {
            // the data folder: made if it is not there yet (ours, from the start)
            use std::os::unix::fs::DirBuilderExt;
            let _ = std::fs::DirBuilder::new()
                .recursive(true)
                .mode(0o750)
                .create(&dir);
        }
        check_private_dir(&dir)?;
        let path = Self::path_of(&dir, service_prefix, instance);
        Self::acquire_at(&path, instance)
    }

    fn acquire_at(path: &Path, instance: &str) -> Result<InstanceLock, LockError> {
        use std::os::unix::fs::{MetadataExt, OpenOptionsExt, PermissionsExt};
        let io = |why| LockError::Io {
            path: path.to_path_buf(),
            why,
        };
        // never through a link, never inherited by the children; readable by us alone
        // (whoever can open a file can lock it)
        let mut file = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .mode(0o600)
            .custom_flags(libc::O_NOFOLLOW | libc::O_CLOEXEC | libc::O_NONBLOCK)
            .open(path)
            .map_err(|e| {
                if e.raw_os_error() == Some(libc::ELOOP) {
                    io(std::io::Error::other(
                        "it is a symbolic link (refused: a lock is never opened through a link)",
                    ))
                } else {
                    io(e)
                }
            })?;
        let meta = file.metadata().map_err(io)?;
        if !meta.file_type().is_file() || meta.uid() != effective_uid() {
            return Err(io(std::io::Error::other(
                "not a regular file of this user: refused",
            )));
        }
        if meta.mode() & 0o077 != 0 {
            file.set_permissions(std::fs::Permissions::from_mode(0o600))
                .map_err(io)?;
        }
        match file.try_lock() {
            Ok(()) => {}
            Err(std::fs::TryLockError::WouldBlock) => {
                let pid = std::fs::read_to_string(path)
                    .map(|s| s.trim().to_string())
                    .unwrap_or_default();
                return Err(LockError::Held {
                    instance: instance.to_string(),
                    pid,
                    path: path.to_path_buf(),
                });
            }
            Err(std::fs::TryLockError::Error(e)) => return Err(io(e)),
        }
        file.set_len(0).map_err(io)?;
        writeln!(file, "{}", std::process::id()).map_err(io)?;
        Ok(InstanceLock {
            _file: file,
            path: path.to_path_buf(),
        })
    }

    /// The lock file.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

/// systemd's service notifications (`Type=notify`, `WatchdogSec=`): a datagram to
/// `$NOTIFY_SOCKET`, when systemd set one; nothing otherwise.
#[derive(Debug)]
pub struct Notify {
    socket: Option<(
        std::os::unix::net::UnixDatagram,
        std::os::unix::net::SocketAddr,
    )>,
    /// Half of `$WATCHDOG_USEC`: how often to send `WATCHDOG=1`.
    watchdog_every: Option<Duration>,
}

impl Notify {
    /// From the environment systemd gives its service.
    pub fn from_env() -> Notify {
        use std::os::linux::net::SocketAddrExt;
        use std::os::unix::net::{SocketAddr, UnixDatagram};
        let socket = std::env::var("NOTIFY_SOCKET").ok().and_then(|p| {
            let addr = match p.strip_prefix('@') {
                Some(abstract_name) => SocketAddr::from_abstract_name(abstract_name.as_bytes()),
                None => SocketAddr::from_pathname(&p),
            }
            .ok()?;
            Some((UnixDatagram::unbound().ok()?, addr))
        });
        let watchdog_every = std::env::var("WATCHDOG_USEC")
            .ok()
            .and_then(|u| u.parse::<u64>().ok())
            .filter(|&u| u > 0)
            .map(|u| Duration::from_micros(u / 2));
        Notify {
            socket,
            watchdog_every,
        }
    }

    /// Send one notification (`READY=1`, `STOPPING=1`, `WATCHDOG=1`, `STATUS=…`).
    pub fn send(&self, state: &str) {
        if let Some((sock, addr)) = &self.socket {
            if let Err(e) = sock.send_to_addr(state.as_bytes(), addr) {
                tracing::warn!("systemd notification {state:?} not sent: {e}");
            }
        }
    }

    /// How often the watchdog wants `WATCHDOG=1`, if systemd watches.
    pub fn watchdog_every(&self) -> Option<Duration> {
        self.socket.as_ref().and(self.watchdog_every)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_second_lock_on_an_instance_is_refused_and_names_the_holder() {
        let dir = std::env::temp_dir().join(format!("softnc-lock-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("i.lock");
        let first = InstanceLock::acquire_at(&path, "mill9").unwrap();
        match InstanceLock::acquire_at(&path, "mill9") {
            Err(LockError::Held { pid, instance, .. }) => {
                assert_eq!(pid, std::process::id().to_string());
                assert_eq!(instance, "mill9");
            }
            other => panic!("second lock: {other:?}"),
        }
        drop(first);
        // released with its holder: the next controller takes it
        let again = InstanceLock::acquire_at(&path, "mill9");
        assert!(again.is_ok(), "{again:?}");
        drop(again);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_link_at_the_lock_path_is_refused_and_its_target_left_alone() {
        let dir = std::env::temp_dir().join(format!("softnc-locklink-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let victim = dir.join("victim");
        std::fs::write(&victim, "keep\n").unwrap();
        let path = dir.join("i.lock");
        std::os::unix::fs::symlink(&victim, &path).unwrap();
        let r = InstanceLock::acquire_at(&path, "mill9");
        assert!(
            matches!(&r, Err(LockError::Io { why, .. }) if why.to_string().contains("link")),
            "{r:?}"
        );
        assert_eq!(std::fs::read_to_string(&victim).unwrap(), "keep\n");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_lock_file_is_readable_by_its_user_alone() {
        use std::os::unix::fs::PermissionsExt;
        let dir = std::env::temp_dir().join(format!("softnc-lockmode-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("i.lock");
        // left readable by an older controller: made private again
        std::fs::write(&path, "1\n").unwrap();
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o644)).unwrap();
        let lock = InstanceLock::acquire_at(&path, "mill9").unwrap();
        let mode = std::fs::metadata(&path).unwrap().permissions().mode();
        assert_eq!(mode & 0o777, 0o600);
        drop(lock);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn only_a_folder_of_ours_that_others_cannot_write_is_a_run_folder() {
        use std::os::unix::fs::PermissionsExt;
        let dir = std::env::temp_dir().join(format!("softnc-rundir-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(dir.join("ok")).unwrap();
        std::fs::set_permissions(dir.join("ok"), std::fs::Permissions::from_mode(0o750)).unwrap();
        assert!(check_private_dir(&dir.join("ok")).is_ok());
        for mode in [0o777, 0o1777, 0o770, 0o757] {
            std::fs::set_permissions(dir.join("ok"), std::fs::Permissions::from_mode(mode))
                .unwrap();
            let r = check_private_dir(&dir.join("ok"));
            assert!(
                matches!(r, Err(PrivateDirError::Writable { .. })),
                "{mode:o}: {r:?}"
            );
        }
        std::os::unix::fs::symlink(dir.join("ok"), dir.join("link")).unwrap();
        assert!(matches!(
            check_private_dir(&dir.join("link")),
            Err(PrivateDirError::NotAFolder { .. })
        ));
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn lock_files_are_named_after_prefix_and_instance_only_with_safe_characters() {
        let p = InstanceLock::path_of(Path::new("/run/x"), "softnc", "../mill 1");
        let name = p.file_name().unwrap().to_string_lossy().to_string();
        assert_eq!(name, "softnc-softnc-___mill_1.lock");
    }

    #[allow(unsafe_code)] // (its SAFETY lines below)
    #[test]
    fn a_sigterm_is_kept_whatever_signal_follows_it() {
        catch_termination_signals().unwrap();
        // SAFETY: raise with valid signal numbers; SIGTERM is caught by our handler,
        // SIGCONT to a running process does nothing but overwrite iceoryx2's record
        unsafe {
            libc::raise(libc::SIGTERM);
            libc::raise(libc::SIGCONT);
        }
        // iceoryx2's record of the last signal no longer says termination ...
        assert!(!SignalHandler::termination_requested());
        // ... ours does, and keeps saying it
        assert!(termination_requested());
        assert!(termination_requested());
    }

    #[test]
    fn a_manual_stop_keeps_its_first_reason() {
        let w = StopWatch::manual();
        assert_eq!(w.requested(), None);
        w.request(StopReason::ParentLost);
        w.request(StopReason::Signal);
        assert_eq!(w.requested(), Some(StopReason::ParentLost));
    }

    #[test]
    fn notifications_reach_the_socket_systemd_names() {
        let dir = std::env::temp_dir().join(format!("softnc-notify-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("notify.sock");
        let _ = std::fs::remove_file(&path);
        let server = std::os::unix::net::UnixDatagram::bind(&path).unwrap();
        let n = Notify {
            socket: Some((
                std::os::unix::net::UnixDatagram::unbound().unwrap(),
                std::os::unix::net::SocketAddr::from_pathname(&path).unwrap(),
            )),
            watchdog_every: Some(Duration::from_secs(1)),
        };
        n.send("READY=1");
        let mut buf = [0u8; 64];
        let len = server.recv(&mut buf).unwrap();
        assert_eq!(&buf[..len], b"READY=1");
        assert_eq!(n.watchdog_every(), Some(Duration::from_secs(1)));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
