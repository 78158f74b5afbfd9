//! Taking in a file a controller runs (a job's program, a subroutine file): only a
//! regular file of an ordinary file system, of at most a given size, read once.
//!
//! What it refuses, and why: a FIFO, a socket or a device can block a reader for
//! ever (`open` of a FIFO waits for a writer, `read` of `/dev/zero` never ends); the
//! kernel's own files (`/proc`, `/sys`, `/dev`, debugfs, …) call themselves regular
//! and of size 0 but can block (`/proc/kmsg`) or never end. Anything but a regular
//! file is refused before it is opened; the file is then opened without blocking
//! (`O_NONBLOCK`) and judged again by what was opened (`fstat`,
//! `fstatfs`, the path the kernel gives the descriptor), so a path swapped between
//! a look and the open is judged as what was actually opened. Symbolic links are
//! followed: a link to `/dev/zero` is a character device.

use std::io::Read;
use std::os::fd::AsRawFd;
use std::os::unix::fs::OpenOptionsExt;
use std::path::Path;

/// Why a file is not taken.
#[derive(Debug, thiserror::Error)]
pub enum TakeError {
    /// Not there, or not readable.
    #[error("{path}: cannot read: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// A FIFO, a device, a directory, …: reading it could block or never end.
    #[error("{path}: not a regular file ({kind})")]
    NotRegular {
        /// The file.
        path: String,
        /// What it is.
        kind: &'static str,
    },
    /// A file of the kernel's pseudo file systems (`/proc`, `/sys`, `/dev`, …).
    #[error("{path}: a kernel file ({what}), not a program")]
    KernelFile {
        /// The file.
        path: String,
        /// Where it lives.
        what: String,
    },
    /// Over the limit.
    #[error("{path}: {len} bytes, more than the {limit} bytes allowed")]
    TooLarge {
        /// The file.
        path: String,
        /// Its size (or what was read of it before the limit).
        len: u64,
        /// The limit.
        limit: u64,
    },
}

impl TakeError {
    /// The file is not there (nothing else went wrong).
    pub fn is_not_found(&self) -> bool {
        matches!(self, TakeError::Io { source, .. } if source.kind() == std::io::ErrorKind::NotFound)
    }
}

/// What kind of file `ft` is, in words.
pub fn kind_of(ft: std::fs::FileType) -> &'static str {
    use std::os::unix::fs::FileTypeExt;
    if ft.is_dir() {
        "a directory"
    } else if ft.is_fifo() {
        "a FIFO"
    } else if ft.is_char_device() {
        "a character device"
    } else if ft.is_block_device() {
        "a block device"
    } else if ft.is_socket() {
        "a socket"
    } else if ft.is_file() {
        "a regular file"
    } else {
        "not a file"
    }
}

/// Folders of the kernel's own files (the path the kernel gives the opened file).
const KERNEL_DIRS: [&str; 3] = ["/proc/", "/sys/", "/dev/"];

/// `statfs` magic numbers of the kernel's pseudo file systems (`linux/magic.h`):
/// proc, sysfs, debugfs, tracefs, securityfs, cgroup, cgroup2, configfs, devpts,
/// bpf, pstore, efivarfs, binfmt_misc, fusectl.
const KERNEL_FS_MAGIC: [(i64, &str); 14] = [
    (0x9fa0, "procfs"),
    (0x6265_6572, "sysfs"),
    (0x6462_6720, "debugfs"),
    (0x7472_6163, "tracefs"),
    (0x7363_6673, "securityfs"),
    (0x0027_e0eb, "cgroup"),
    (0x6367_7270, "cgroup2"),
    (0x6265_6570, "configfs"),
    (0x1cd1, "devpts"),
    (0xcafe_4a11, "bpf"),
    (0x6165_676c, "pstore"),
    (0xf97c_ff8c, "efivarfs"),
    (0x4249_4e4d, "binfmt_misc"),
    (0x6573_5546, "fusectl"),
];

/// Whether the opened `file` is a kernel file: on one of the kernel's pseudo file
/// systems, or under `/proc`, `/sys` or `/dev` (where the kernel says it is).
#[allow(unsafe_code)] // (its SAFETY lines below)
fn kernel_file(file: &std::fs::File) -> Option<String> {
    // SAFETY: `statfs` is plain data; fstatfs fills it for an open descriptor.
    let mut st: libc::statfs = unsafe { std::mem::zeroed() };
    // SAFETY: the descriptor is open (owned by `file`) and `st` is a valid out-pointer.
    if unsafe { libc::fstatfs(file.as_raw_fd(), &mut st) } == 0 {
        #[allow(clippy::unnecessary_cast)]
        let magic = st.f_type as i64;
        if let Some((_, name)) = KERNEL_FS_MAGIC.iter().find(|(m, _)| *m == magic) {
            return Some(name.to_string());
        }
    }
    let real = std::fs::read_link(format!("/proc/self/fd/{}", file.as_raw_fd())).ok()?;
    let real = real.to_string_lossy();
    KERNEL_DIRS
        .iter()
        .find(|d| real.starts_with(*d))
        .map(|d| format!("under {}", d.trim_end_matches('/')))
}

/// Take `path` in: a regular file of an ordinary file system (symbolic links
/// followed), of at most `limit` bytes, read once. Opening never blocks and
/// nothing but a regular file is read.
pub fn read_regular(path: &Path, limit: u64) -> Result<Vec<u8>, TakeError> {
    let name = || path.display().to_string();
    let io = |source| TakeError::Io {
        path: name(),
        source,
    };
    // a device is not even opened (opening some has effects: a tape rewinds)
    let before = std::fs::metadata(path).map_err(io)?;
    if !before.file_type().is_file() {
        return Err(TakeError::NotRegular {
            path: name(),
            kind: kind_of(before.file_type()),
        });
    }
    let file = std::fs::OpenOptions::new()
        .read(true)
        // a FIFO opens at once (no writer awaited); a terminal is not taken over
        .custom_flags(libc::O_NONBLOCK | libc::O_NOCTTY)
        .open(path)
        .map_err(io)?;
    // what was opened is judged (not a path swapped for a FIFO in between)
    let meta = file.metadata().map_err(io)?;
    if !meta.file_type().is_file() {
        return Err(TakeError::NotRegular {
            path: name(),
            kind: kind_of(meta.file_type()),
        });
    }
    if let Some(what) = kernel_file(&file) {
        return Err(TakeError::KernelFile { path: name(), what });
    }
    let too_large = |len| TakeError::TooLarge {
        path: name(),
        len,
        limit,
    };
    if meta.len() > limit {
        return Err(too_large(meta.len()));
    }
    let mut bytes = Vec::with_capacity(meta.len() as usize);
    // a file growing while read stops at the limit
    file.take(limit.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(io)?;
    if bytes.len() as u64 > limit {
        return Err(too_large(bytes.len() as u64));
    }
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(tag: &str) -> std::path::PathBuf {
        let d = std::env::temp_dir().join(format!("softnc-taken-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn a_regular_file_is_read_once_under_its_limit() {
        let d = dir("ok");
        let p = d.join("a.ngc");
        std::fs::write(&p, b"G1 X1\n").unwrap();
        assert_eq!(read_regular(&p, 100).unwrap(), b"G1 X1\n");
        let e = read_regular(&p, 3).unwrap_err();
        assert!(e.to_string().contains("6 bytes, more than the 3"), "{e}");
        assert!(read_regular(&d.join("none"), 3).unwrap_err().is_not_found());
        let _ = std::fs::remove_dir_all(&d);
    }

    #[test]
    fn fifos_devices_links_to_devices_and_kernel_files_are_refused_unread() {
        let d = dir("odd");
        let fifo = d.join("fifo.ngc");
        let made = std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .is_ok_and(|s| s.success());
        assert!(made, "mkfifo");
        // (would block for ever in open or read)
        let e = read_regular(&fifo, 1 << 20).unwrap_err();
        assert!(e.to_string().contains("a FIFO"), "{e}");
        let zero = d.join("zero.ngc");
        std::os::unix::fs::symlink("/dev/zero", &zero).unwrap();
        let e = read_regular(&zero, 1 << 20).unwrap_err();
        assert!(e.to_string().contains("character device"), "{e}");
        for kernel in [
            "/proc/kmsg",
            "/proc/self/status",
            "/sys/kernel/uevent_seqnum",
        ] {
            if Path::new(kernel).exists() {
                let e = read_regular(Path::new(kernel), 1 << 20).unwrap_err();
                assert!(
                    matches!(e, TakeError::KernelFile { .. } | TakeError::Io { .. }),
                    "{kernel}: {e}"
                );
            }
        }
        let e = read_regular(&d, 1 << 20).unwrap_err();
        assert!(e.to_string().contains("a directory"), "{e}");
        let _ = std::fs::remove_dir_all(&d);
    }
}
