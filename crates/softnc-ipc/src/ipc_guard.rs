//! The permissions of the controller's iceoryx2 resources against other local users.
//!
//! iceoryx2 0.10 creates its files owner-only (services, nodes, data segments: mode
//! 0600/0400, folders 0750) except one: the node-id file
//! `/dev/shm/<prefix>…_node.<version>.global_mgmt`, made 0666 so that any user's
//! node can count in it. Anyone who writes into it makes every later node creation
//! fail (`UnableToGenerateUniqueNodeId`): no client, no E-stop, no `softncd`. So:
//!
//! - [`prepare`] (every process and client, before its first node): iceoryx2's root
//!   folder must be a folder of ours (or root's) that group and others cannot write
//!   (made so, 0750, when absent); a node-id file of our prefix that is not a regular
//!   file of ours (or root's) or that others may write — planted, or left open by an
//!   older version — is removed (iceoryx2 makes a new one; its counter only tells
//!   apart nodes of one process created in the same instant); one we cannot remove
//!   is an error naming it.
//! - [`seal`] (after a node is created): the node-id file of ours is made 0600.
//!
//! What is left: the instant between iceoryx2's creation of a missing node-id file
//! and [`seal`] in the same process (microseconds, once after each boot).

use iceoryx2::config::Config;
use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};

/// Where POSIX shared memory lives on Linux (`shm_open`).
pub const SHM_DIR: &str = "/dev/shm";
/// The end of iceoryx2's node-id file name.
const NODE_ID_FILE_SUFFIX: &str = ".global_mgmt";
/// The mode of iceoryx2's root folder when we create it.
const ROOT_DIR_MODE: u32 = 0o750;

/// Refusals of [`prepare`] and [`seal`].
#[derive(Debug, thiserror::Error)]
pub enum IpcGuardError {
    /// iceoryx2's root folder is not ours alone.
    #[error("iceoryx2 folder {path}: {why}: refused (it must be a folder of this user or root that group and others cannot write; remove it or fix its owner and mode)")]
    UnsafeRoot {
        /// The folder.
        path: PathBuf,
        /// What is wrong.
        why: String,
    },
    /// A node-id file others may write, which we cannot remove.
    #[error("{path}: iceoryx2's node-id file is {why} and cannot be removed by this user ({source}); remove it as root")]
    UnsafeNodeIdFile {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        why: String,
        /// Why it stays.
        source: std::io::Error,
    },
    /// A file or folder cannot be read or changed.
    #[error("{path}: {source}")]
    Io {
        /// The path.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> IpcGuardError + '_ {
    move |source| IpcGuardError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// The effective user id of this process.
#[allow(unsafe_code)] // (its SAFETY lines below)
pub fn effective_uid() -> u32 {
    // SAFETY: geteuid has no preconditions and cannot fail
    unsafe { libc::geteuid() }
}

/// Who is at the other end of a Unix stream socket (`SO_PEERCRED`): user, group and
/// process ids as the kernel recorded them when it connected.
#[allow(unsafe_code)] // (its SAFETY line below)
pub fn peer_credentials(
    socket: &std::os::unix::net::UnixStream,
) -> std::io::Result<PeerCredentials> {
    use std::os::fd::AsRawFd;
    let mut cred = libc::ucred {
        pid: 0,
        uid: 0,
        gid: 0,
    };
    let mut len = std::mem::size_of::<libc::ucred>() as libc::socklen_t;
    // SAFETY: the descriptor is an open socket borrowed for the call; `cred` and
    // `len` are valid for writes of the size passed, as SO_PEERCRED requires
    let r = unsafe {
        libc::getsockopt(
            socket.as_raw_fd(),
            libc::SOL_SOCKET,
            libc::SO_PEERCRED,
            (&raw mut cred).cast(),
            &raw mut len,
        )
    };
    if r != 0 {
        return Err(std::io::Error::last_os_error());
    }
    Ok(PeerCredentials {
        pid: cred.pid,
        uid: cred.uid,
        gid: cred.gid,
    })
}

/// The other end of a Unix socket ([`peer_credentials`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PeerCredentials {
    /// Process id.
    pub pid: i32,
    /// Effective user id.
    pub uid: u32,
    /// Effective group id.
    pub gid: u32,
}

/// Whose files we trust: ours, and root's.
fn trusted_owner(uid: u32) -> bool {
    uid == effective_uid() || uid == 0
}

/// Make the iceoryx2 configuration file at `path` the process's global one (before
/// any node is created), then [`prepare`] it: the daemon and every operator client.
pub fn setup_global_config(path: &Path) -> Result<(), String> {
    use iceoryx2::prelude::*;
    let p = path.display().to_string();
    let fp = FilePath::new(p.as_bytes()).map_err(|e| format!("{p}: {e:?}"))?;
    let config = Config::setup_global_config_from_file(&fp).map_err(|e| format!("{p}: {e:?}"))?;
    prepare(config).map_err(|e| e.to_string())
}

/// Check (and make, when absent) iceoryx2's root folder; remove unsafe node-id files
/// of our prefix. Before the process's first node.
pub fn prepare(config: &Config) -> Result<(), IpcGuardError> {
    let root = PathBuf::from(config.global.root_path().to_string());
    check_root(&root)?;
    for f in node_id_files(config)? {
        if let Some(why) = unsafe_node_id_file(&f)? {
            tracing::warn!(
                "{}: iceoryx2's node-id file is {why}; removing it",
                f.display()
            );
            if let Err(source) = std::fs::remove_file(&f) {
                if source.kind() != std::io::ErrorKind::NotFound {
                    return Err(IpcGuardError::UnsafeNodeIdFile {
                        path: f,
                        why,
                        source,
                    });
                }
            }
        }
    }
    Ok(())
}

/// Make our node-id file owner-only (iceoryx2 leaves it 0666). After a node is created.
pub fn seal(config: &Config) -> Result<(), IpcGuardError> {
    use std::os::unix::fs::{OpenOptionsExt, PermissionsExt};
    let me = effective_uid();
    for f in node_id_files(config)? {
        let file = match std::fs::OpenOptions::new()
            .read(true)
            .custom_flags(libc::O_NOFOLLOW | libc::O_CLOEXEC | libc::O_NONBLOCK)
            .open(&f)
        {
            Ok(file) => file,
            // removed meanwhile, or a link (prepare removes those): not ours to seal
            Err(_) => continue,
        };
        let meta = file.metadata().map_err(io(&f))?;
        if meta.file_type().is_file() && meta.uid() == me && meta.mode() & 0o077 != 0 {
            file.set_permissions(std::fs::Permissions::from_mode(0o600))
                .map_err(io(&f))?;
        }
    }
    Ok(())
}

fn check_root(root: &Path) -> Result<(), IpcGuardError> {
    use std::os::unix::fs::DirBuilderExt;
    let unsafe_root = |why: String| IpcGuardError::UnsafeRoot {
        path: root.to_path_buf(),
        why,
    };
    // made by us when absent (not by iceoryx2, after a check another user could race)
    match std::fs::DirBuilder::new().mode(ROOT_DIR_MODE).create(root) {
        Ok(()) => {}
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {}
        Err(e) => return Err(io(root)(e)),
    }
    let meta = std::fs::symlink_metadata(root).map_err(io(root))?;
    if !meta.file_type().is_dir() {
        return Err(unsafe_root("not a folder (a link or a file)".into()));
    }
    if !trusted_owner(meta.uid()) {
        return Err(unsafe_root(format!("owned by uid {}", meta.uid())));
    }
    if meta.mode() & 0o022 != 0 {
        return Err(unsafe_root(format!(
            "writable by group or others (mode {:o})",
            meta.mode() & 0o7777
        )));
    }
    Ok(())
}

/// The node-id files of our prefix in [`SHM_DIR`].
fn node_id_files(config: &Config) -> Result<Vec<PathBuf>, IpcGuardError> {
    let prefix = config.global.prefix.to_string();
    let dir = Path::new(SHM_DIR);
    let entries = match std::fs::read_dir(dir) {
        Ok(e) => e,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
        Err(e) => return Err(io(dir)(e)),
    };
    Ok(entries
        .filter_map(|e| e.ok())
        .filter(|e| {
            let n = e.file_name();
            let n = n.to_string_lossy();
            n.starts_with(&prefix) && n.ends_with(NODE_ID_FILE_SUFFIX)
        })
        .map(|e| e.path())
        .collect())
}

/// Why a node-id file must go (None: it may stay).
fn unsafe_node_id_file(f: &Path) -> Result<Option<String>, IpcGuardError> {
    let meta = match std::fs::symlink_metadata(f) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(io(f)(e)),
    };
    Ok(if !meta.file_type().is_file() {
        Some("not a regular file".into())
    } else if !trusted_owner(meta.uid()) {
        Some(format!("owned by uid {}", meta.uid()))
    } else if meta.mode() & 0o022 != 0 {
        Some(format!(
            "writable by group or others (mode {:o})",
            meta.mode() & 0o7777
        ))
    } else {
        None
    })
}
