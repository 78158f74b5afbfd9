//! A G-code program's bytes for `softnc plan` and `softnc sim`: a regular file is
//! mapped read-only (iceoryx2's safe `mmap` wrapper), anything else is read.
//!
//! Why: the summary's two threads (`check_program_parallel`) start only once the
//! text is there, so reading it is a serial prefix of the whole process. Read with
//! `read(2)`, the 5.0 MB benchmark program (docs/perf-log/planner-figures.md) costs a fresh 5 MB
//! buffer's page faults and zeroing and the kernel's copy, about 2.3 ms with the
//! UTF-8 check; mapped, the UTF-8 check touches the page cache's own pages and the
//! two take about 0.5 ms.
//!
//! The cost, as for ripgrep's `--mmap`: a file cut shorter by another process while
//! it is read ends the process with SIGBUS (a file replaced by a rename, as editors
//! and CAM posts save, is not affected: the mapping keeps the old one). Both commands
//! are short-lived; the daemon reads its jobs with `read(2)`.

use iceoryx2_bb_posix::file_descriptor::FileDescriptor;
use iceoryx2_bb_posix::memory_mapping::{
    MappingBehavior, MappingPermission, MemoryMapping, MemoryMappingBuilder,
};
use std::os::fd::IntoRawFd;
use std::path::Path;

/// Smallest file mapped rather than read (bytes): below it the mapping's set-up and
/// teardown cost more than the copy saves.
const MAP_MIN_BYTES: u64 = 256 * 1024;

/// The bytes of a program file, mapped or read.
pub enum ProgramBytes {
    /// A regular file of at least [`MAP_MIN_BYTES`], mapped private and read-only
    /// (boxed: the mapping's record is about 300 bytes).
    Mapped(Box<MemoryMapping>),
    /// Anything else (small files, pipes, `/dev/stdin`, files that cannot be mapped).
    Read(Vec<u8>),
}

impl std::ops::Deref for ProgramBytes {
    type Target = [u8];
    fn deref(&self) -> &[u8] {
        match self {
            ProgramBytes::Mapped(m) => m.as_slice(),
            ProgramBytes::Read(v) => v,
        }
    }
}

/// The bytes of the file at `path`: mapped where it is a regular file of at least
/// [`MAP_MIN_BYTES`] and the mapping succeeds, else read whole (`std::fs::read`, with
/// its errors).
pub fn read(path: &Path) -> std::io::Result<ProgramBytes> {
    let file = std::fs::File::open(path)?;
    let meta = file.metadata()?;
    if meta.is_file() && meta.len() >= MAP_MIN_BYTES {
        if let Ok(len) = usize::try_from(meta.len()) {
            // (the descriptor goes to the mapping, which closes it when dropped)
            if let Some(fd) = FileDescriptor::new(file.into_raw_fd()) {
                let mapped = MemoryMappingBuilder::from_file_descriptor(fd)
                    .mapping_behavior(MappingBehavior::Private)
                    .initial_mapping_permission(MappingPermission::Read)
                    .size(len)
                    .create();
                if let Ok(m) = mapped {
                    return Ok(ProgramBytes::Mapped(Box::new(m)));
                }
            }
        }
    }
    std::fs::read(path).map(ProgramBytes::Read)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `bytes` in a file `name` of a folder of its own (removed with [`gone`]).
    fn temp(name: &str, bytes: &[u8]) -> std::path::PathBuf {
        let dir =
            std::env::temp_dir().join(format!("softnc-program-file-{}-{name}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join(name);
        std::fs::write(&p, bytes).unwrap();
        p
    }

    #[test]
    fn a_large_file_is_mapped_with_its_exact_bytes() {
        let text: Vec<u8> = (0..MAP_MIN_BYTES as usize + 12_345)
            .map(|i| "G1 X1.5 Y-2\n(é)".as_bytes()[i % 16])
            .collect();
        let p = temp("large.ngc", &text);
        let got = read(&p).unwrap();
        assert!(matches!(got, ProgramBytes::Mapped(_)));
        assert_eq!(&*got, &text[..]);
        gone(&p);
    }

    /// Remove the folder of a file [`temp`] made.
    fn gone(p: &Path) {
        let _ = std::fs::remove_dir_all(p.parent().unwrap());
    }

    #[test]
    fn small_and_empty_files_and_pipes_are_read() {
        let p = temp("small.ngc", b"G0 X1\nM2\n");
        let got = read(&p).unwrap();
        assert!(matches!(got, ProgramBytes::Read(_)));
        assert_eq!(&*got, b"G0 X1\nM2\n");
        let e = temp("empty.ngc", b"");
        assert_eq!(read(&e).unwrap().len(), 0);
        // a character device: not a regular file, read as it comes
        let null = read(Path::new("/dev/null")).unwrap();
        assert!(matches!(null, ProgramBytes::Read(_)));
        assert_eq!(null.len(), 0);
        gone(&p);
        gone(&e);
    }

    #[test]
    fn missing_files_and_directories_are_errors() {
        let dir = std::env::temp_dir();
        assert!(read(&dir.join("softnc-no-such-program.ngc")).is_err());
        assert!(read(&dir).is_err());
    }
}
