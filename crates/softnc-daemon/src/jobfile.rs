//! A job's program as the MMI takes it in: a regular file of an ordinary file
//! system under the configured size, read once ([`softnc_core::taken`]); once its
//! check has passed, kept as an immutable copy named by its SHA-256 in the data
//! directory, with the subroutine files the check took in and the job's checked
//! setup ([`CheckedSetup`]: the modal preamble, the parameters, those files). The
//! interpolation and position processes run from the copies and that setup, so the
//! files the operator submitted can change or vanish after the check without
//! effect: what was checked is what runs. A refused job keeps no copy.

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use softnc_core::taken::{read_regular, TakeError};
use std::io::Write;
use std::os::unix::fs::{DirBuilderExt, OpenOptionsExt, PermissionsExt};
use std::path::{Path, PathBuf};

/// Mode of a program copy: read-only, not world-readable (a root-only program
/// stays the operators' group's at most).
pub const COPY_MODE: u32 = 0o440;
/// Mode of a job's checked setup.
pub const SETUP_MODE: u32 = 0o640;
/// Mode of the folder of copies.
pub const PROGRAMS_DIR_MODE: u32 = 0o750;

/// Why a program is not taken.
#[derive(Debug, thiserror::Error)]
pub enum IntakeError {
    /// Not a file that may be run, or not readable.
    #[error("{0}; job not started")]
    Refused(TakeError),
    /// Over the configured limit.
    #[error("{0} (max_job_bytes); job not started")]
    TooLarge(TakeError),
    /// The copy cannot be stored.
    #[error("{path}: cannot keep the job's copy: {source}")]
    Store {
        /// The copy.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// The job's checked setup cannot be read back.
    #[error("{path}: the job's checked setup cannot be used: {why}")]
    Setup {
        /// The setup file.
        path: String,
        /// Why.
        why: String,
    },
}

/// A program taken in: its bytes as read once and their hash.
#[derive(Debug, Clone)]
pub struct JobFile {
    /// The program's bytes, as read once.
    pub bytes: Vec<u8>,
    /// SHA-256 of the bytes (hex).
    pub sha256: String,
}

/// SHA-256 of `bytes`, hex.
pub fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// Take `path` in: a regular file of an ordinary file system (symbolic links
/// followed; no FIFO, device or kernel file, which could block or never end) of
/// at most `limit` bytes, read once. Nothing is written.
pub fn intake(path: &str, limit: u64) -> Result<JobFile, IntakeError> {
    let bytes = read_regular(Path::new(path), limit).map_err(|e| match e {
        e @ TakeError::TooLarge { .. } => IntakeError::TooLarge(e),
        e => IntakeError::Refused(e),
    })?;
    let sha256 = sha256_hex(&bytes);
    Ok(JobFile { bytes, sha256 })
}

/// The copy of bytes with hash `sha256` in `programs`.
pub fn copy_path(programs: &Path, sha256: &str) -> PathBuf {
    programs.join(format!("{sha256}.ngc"))
}

/// Write `bytes` to `path` atomically, the file created with `mode` (never
/// readable by others, not even while written).
pub fn write_private(path: &Path, bytes: &[u8], mode: u32) -> std::io::Result<()> {
    let dir = path.parent().unwrap_or(Path::new("."));
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = dir.join(format!(".{name}.tmp{}", std::process::id()));
    let _ = std::fs::remove_file(&tmp);
    let written = (|| {
        let mut f = std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .mode(mode)
            .open(&tmp)?;
        f.write_all(bytes)?;
        // the mode asked for, whatever the umask
        f.set_permissions(std::fs::Permissions::from_mode(mode))?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if let Err(e) = written {
        let _ = std::fs::remove_file(&tmp);
        return Err(e);
    }
    std::fs::File::open(dir)?.sync_all()
}

/// Keep `bytes` (hash `sha256`) as an immutable copy in `programs`: its path, and
/// whether this call made it (a copy already there from an earlier job is shared).
pub fn keep_copy(
    programs: &Path,
    bytes: &[u8],
    sha256: &str,
) -> Result<(PathBuf, bool), IntakeError> {
    let copy = copy_path(programs, sha256);
    let store = |source| IntakeError::Store {
        path: copy.display().to_string(),
        source,
    };
    let same = std::fs::metadata(&copy).is_ok_and(|m| m.len() == bytes.len() as u64)
        && std::fs::read(&copy).is_ok_and(|have| have == bytes);
    if same {
        return Ok((copy, false));
    }
    std::fs::DirBuilder::new()
        .recursive(true)
        .mode(PROGRAMS_DIR_MODE)
        .create(programs)
        .map_err(store)?;
    if copy.exists() {
        // a damaged copy (not what its name says): replaced
        let mut perms = std::fs::metadata(&copy).map_err(store)?.permissions();
        perms.set_mode(0o640);
        std::fs::set_permissions(&copy, perms).map_err(store)?;
    }
    write_private(&copy, bytes, COPY_MODE).map_err(store)?;
    Ok((copy, true))
}

/// A subroutine file of a checked job, kept as a copy.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct KeptSubroutine {
    /// The subroutine's name as called.
    pub name: String,
    /// Where the check found it (its errors name this path).
    pub path: String,
    /// Its copy.
    pub copy: PathBuf,
    /// SHA-256 of its bytes.
    pub sha256: String,
}

/// What a job was checked with, beside its program: what its run reads it with
/// (`<data_dir>/programs/job-<id>.json`, written by the MMI before it starts the
/// job).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CheckedSetup {
    /// The job.
    pub job_id: u64,
    /// The program's copy.
    pub program: PathBuf,
    /// SHA-256 of the program.
    pub sha256: String,
    /// The modal preamble (the machine's modal state) it was checked with.
    pub preamble: Option<String>,
    /// The file the preamble came from (for its errors).
    pub preamble_file: Option<String>,
    /// The machine's parameters it was checked with (LinuxCNC's `.var` text;
    /// `None`: the profile's offsets).
    pub params: Option<String>,
    /// The subroutine files it took in.
    pub subroutines: Vec<KeptSubroutine>,
}

/// Where job `job_id`'s checked setup lives in `programs`.
pub fn setup_path(programs: &Path, job_id: u64) -> PathBuf {
    programs.join(format!("job-{job_id}.json"))
}

impl CheckedSetup {
    /// Write it (atomically, not world-readable).
    pub fn save(&self, programs: &Path) -> Result<PathBuf, IntakeError> {
        let path = setup_path(programs, self.job_id);
        let store = |source| IntakeError::Store {
            path: path.display().to_string(),
            source,
        };
        let text = serde_json::to_vec_pretty(self).map_err(|e| store(std::io::Error::other(e)))?;
        write_private(&path, &text, SETUP_MODE).map_err(store)?;
        Ok(path)
    }

    /// Job `job_id`'s setup, read back.
    pub fn load(programs: &Path, job_id: u64) -> Result<CheckedSetup, IntakeError> {
        let path = setup_path(programs, job_id);
        let bad = |why: String| IntakeError::Setup {
            path: path.display().to_string(),
            why,
        };
        let text = std::fs::read(&path).map_err(|e| bad(e.to_string()))?;
        let setup: CheckedSetup = serde_json::from_slice(&text).map_err(|e| bad(e.to_string()))?;
        if setup.job_id != job_id {
            return Err(bad(format!("it is job {}'s", setup.job_id)));
        }
        Ok(setup)
    }

    /// The subroutine files, read back from their copies and checked against their
    /// hashes.
    pub fn subroutine_files(&self) -> Result<Vec<softnc_gcode::SubroutineFile>, IntakeError> {
        self.subroutines
            .iter()
            .map(|s| {
                let bad = |why: String| IntakeError::Setup {
                    path: s.copy.display().to_string(),
                    why,
                };
                let bytes = std::fs::read(&s.copy).map_err(|e| bad(e.to_string()))?;
                if sha256_hex(&bytes) != s.sha256 {
                    return Err(bad("the copy is not what was checked".into()));
                }
                Ok(softnc_gcode::SubroutineFile {
                    name: s.name.clone(),
                    path: s.path.clone(),
                    bytes: bytes.into(),
                })
            })
            .collect()
    }
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
    fn a_program_is_read_once_and_its_copy_is_private_and_immutable() {
        let d = dir("copy");
        let p = d.join("a.ngc");
        std::fs::write(&p, "G1 X1 F100\nM2\n").unwrap();
        let j = intake(p.to_str().unwrap(), 1 << 20).unwrap();
        assert_eq!(j.bytes, b"G1 X1 F100\nM2\n");
        assert!(
            !d.join("programs").exists(),
            "nothing kept before the check"
        );
        let (copy, made) = keep_copy(&d.join("programs"), &j.bytes, &j.sha256).unwrap();
        assert!(made);
        // rewritten after the check: the copy still holds what was checked
        std::fs::write(&p, "G0 X900\nM2\n").unwrap();
        assert_eq!(std::fs::read(&copy).unwrap(), b"G1 X1 F100\nM2\n");
        assert!(copy.ends_with(format!("{}.ngc", j.sha256)));
        let mode = std::fs::metadata(&copy).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, COPY_MODE, "{mode:o}");
        // taken again: the same copy, shared
        let (again, made) = keep_copy(&d.join("programs"), &j.bytes, &j.sha256).unwrap();
        assert_eq!((again, made), (copy, false));
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
            let e = intake(fifo.to_str().unwrap(), 1 << 20).unwrap_err();
            assert!(e.to_string().contains("a FIFO"), "{e}");
        }
        let e = intake("/dev/zero", 1 << 20).unwrap_err();
        assert!(e.to_string().contains("character device"), "{e}");
        let e = intake(d.to_str().unwrap(), 1 << 20).unwrap_err();
        assert!(e.to_string().contains("a directory"), "{e}");
        let big = d.join("big.ngc");
        std::fs::write(&big, vec![b'\n'; 2000]).unwrap();
        let e = intake(big.to_str().unwrap(), 1000).unwrap_err();
        assert!(
            e.to_string()
                .contains("2000 bytes, more than the 1000 bytes allowed (max_job_bytes)"),
            "{e}"
        );
        let e = intake(d.join("none.ngc").to_str().unwrap(), 1000).unwrap_err();
        assert!(e.to_string().contains("cannot read"), "{e}");
        let _ = std::fs::remove_dir_all(&d);
    }

    #[test]
    fn a_checked_setup_round_trips_and_refuses_a_changed_copy() {
        let d = dir("setup");
        let programs = d.join("programs");
        let (copy, _) = keep_copy(
            &programs,
            b"o<s> sub\no<s> endsub\n",
            &sha256_hex(b"o<s> sub\no<s> endsub\n"),
        )
        .unwrap();
        let setup = CheckedSetup {
            job_id: 7,
            program: copy.clone(),
            sha256: "x".into(),
            preamble: Some("G21\n".into()),
            preamble_file: None,
            params: None,
            subroutines: vec![KeptSubroutine {
                name: "s".into(),
                path: "/shop/s.ngc".into(),
                copy: copy.clone(),
                sha256: sha256_hex(b"o<s> sub\no<s> endsub\n"),
            }],
        };
        setup.save(&programs).unwrap();
        let back = CheckedSetup::load(&programs, 7).unwrap();
        assert_eq!(back, setup);
        assert_eq!(back.subroutine_files().unwrap()[0].path, "/shop/s.ngc");
        assert!(CheckedSetup::load(&programs, 8).is_err());
        // a copy that is not what was checked is refused
        std::fs::set_permissions(&copy, std::fs::Permissions::from_mode(0o640)).unwrap();
        std::fs::write(&copy, "o<s> sub\nG0 X100\no<s> endsub\n").unwrap();
        let e = back.subroutine_files().unwrap_err();
        assert!(e.to_string().contains("not what was checked"), "{e}");
        let _ = std::fs::remove_dir_all(&d);
    }
}
