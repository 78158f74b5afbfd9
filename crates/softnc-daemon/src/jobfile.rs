//! A job's program as the MMI takes it in: a regular file under the configured size,
//! read once, and kept as an immutable copy named by its SHA-256 in the data
//! directory. The interpolation and position processes run that copy, so the file
//! the operator submitted can change or vanish after the check without effect.

use sha2::{Digest, Sha256};
use std::io::Read;
use std::path::{Path, PathBuf};

/// Why a program is not taken.
#[derive(Debug, thiserror::Error)]
pub enum IntakeError {
    /// Not there, or not readable.
    #[error("{path}: cannot read: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// A FIFO, a device, a directory, …: reading it could block or never end.
    #[error("{path}: not a regular file ({kind}); job not started")]
    NotRegular {
        /// The file.
        path: String,
        /// What it is.
        kind: &'static str,
    },
    /// Over the configured limit.
    #[error(
        "{path}: {len} bytes, more than the {limit} bytes allowed (max_job_bytes); job not started"
    )]
    TooLarge {
        /// The file.
        path: String,
        /// Its size.
        len: u64,
        /// The limit.
        limit: u64,
    },
    /// The copy cannot be stored.
    #[error("{path}: cannot keep the job's copy: {source}")]
    Store {
        /// The copy.
        path: String,
        /// Why.
        source: std::io::Error,
    },
}

/// A program taken in: its bytes and the copy the other processes run.
#[derive(Debug, Clone)]
pub struct JobFile {
    /// The program's bytes, as read once.
    pub bytes: Vec<u8>,
    /// SHA-256 of the bytes (hex).
    pub sha256: String,
    /// The immutable copy: `<programs>/<sha256>.ngc`.
    pub copy: PathBuf,
}

fn kind_of(ft: std::fs::FileType) -> &'static str {
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
    } else {
        "not a file"
    }
}

/// Take `path` in: a regular file (symbolic links followed) of at most `limit`
/// bytes, read once, its copy kept in `programs` (written atomically, once).
pub fn intake(path: &str, limit: u64, programs: &Path) -> Result<JobFile, IntakeError> {
    let io = |source| IntakeError::Io {
        path: path.to_string(),
        source,
    };
    // stat before open: opening a FIFO blocks until a writer comes
    let meta = std::fs::metadata(path).map_err(io)?;
    if !meta.file_type().is_file() {
        return Err(IntakeError::NotRegular {
            path: path.to_string(),
            kind: kind_of(meta.file_type()),
        });
    }
    let too_large = |len| IntakeError::TooLarge {
        path: path.to_string(),
        len,
        limit,
    };
    if meta.len() > limit {
        return Err(too_large(meta.len()));
    }
    let file = std::fs::File::open(path).map_err(io)?;
    // what was opened is what was checked (not swapped for a FIFO in between)
    let opened = file.metadata().map_err(io)?;
    if !opened.file_type().is_file() {
        return Err(IntakeError::NotRegular {
            path: path.to_string(),
            kind: kind_of(opened.file_type()),
        });
    }
    let mut bytes = Vec::with_capacity(opened.len() as usize);
    // a file growing while read stops at the limit
    file.take(limit + 1).read_to_end(&mut bytes).map_err(io)?;
    if bytes.len() as u64 > limit {
        return Err(too_large(bytes.len() as u64));
    }
    let sha256: String = Sha256::digest(&bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    let copy = programs.join(format!("{sha256}.ngc"));
    let store = |source| IntakeError::Store {
        path: copy.display().to_string(),
        source,
    };
    let same = std::fs::read(&copy).is_ok_and(|have| have == bytes);
    if !same {
        std::fs::create_dir_all(programs).map_err(store)?;
        softnc_core::store::write_atomic(&copy, &bytes).map_err(store)?;
        let mut perms = std::fs::metadata(&copy).map_err(store)?.permissions();
        perms.set_readonly(true);
        std::fs::set_permissions(&copy, perms).map_err(store)?;
    }
    Ok(JobFile {
        bytes,
        sha256,
        copy,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(tag: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("softnc-intake-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn a_program_is_read_once_and_run_from_its_copy() {
        let d = dir("copy");
        let p = d.join("a.ngc");
        std::fs::write(&p, "G1 X1 F100\nM2\n").unwrap();
        let j = intake(p.to_str().unwrap(), 1 << 20, &d.join("programs")).unwrap();
        assert_eq!(j.bytes, b"G1 X1 F100\nM2\n");
        // rewritten after the check: the copy still holds what was checked
        std::fs::write(&p, "G0 X900\nM2\n").unwrap();
        assert_eq!(std::fs::read(&j.copy).unwrap(), b"G1 X1 F100\nM2\n");
        assert!(j.copy.ends_with(format!("{}.ngc", j.sha256)));
        // taken again: the same copy, still fine read-only
        std::fs::write(&p, "G1 X1 F100\nM2\n").unwrap();
        let again = intake(p.to_str().unwrap(), 1 << 20, &d.join("programs")).unwrap();
        assert_eq!(again.copy, j.copy);
        let _ = std::fs::remove_dir_all(&d);
    }

    #[test]
    fn fifos_devices_directories_and_large_files_are_refused_without_reading() {
        let d = dir("odd");
        let fifo = d.join("fifo.ngc");
        let ok = std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .is_ok_and(|s| s.success());
        if ok {
            // would block for ever if opened
            let e = intake(fifo.to_str().unwrap(), 1 << 20, &d).unwrap_err();
            assert!(e.to_string().contains("a FIFO"), "{e}");
        }
        let e = intake("/dev/zero", 1 << 20, &d).unwrap_err();
        assert!(e.to_string().contains("character device"), "{e}");
        let e = intake(d.to_str().unwrap(), 1 << 20, &d).unwrap_err();
        assert!(e.to_string().contains("a directory"), "{e}");
        let big = d.join("big.ngc");
        std::fs::write(&big, vec![b'\n'; 2000]).unwrap();
        let e = intake(big.to_str().unwrap(), 1000, &d).unwrap_err();
        assert!(
            e.to_string().contains("2000 bytes, more than the 1000"),
            "{e}"
        );
        let e = intake(d.join("none.ngc").to_str().unwrap(), 1000, &d).unwrap_err();
        assert!(e.to_string().contains("cannot read"), "{e}");
        let _ = std::fs::remove_dir_all(&d);
    }
}
