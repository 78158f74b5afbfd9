//! The programs uploaded through the panel: each stored as
//! `<data_dir>/web/programs/<sha256>.ngc` (a name the panel makes; the name the
//! operator's file had is kept only as a label in `index.json`, never as a path).

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::io::Write;
use std::os::unix::fs::OpenOptionsExt;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// The longest label kept of an uploaded file's name (characters).
const LABEL_CHARS: usize = 80;

/// Mode of the stored programs and the index: the controller's user and its group.
const FILE_MODE: u32 = 0o640;

/// Why an upload was refused.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum UploadError {
    /// Larger than the configured limit.
    #[error("the program is {bytes} bytes, over the {limit} bytes the panel takes")]
    TooLarge {
        /// Its size.
        bytes: u64,
        /// The limit.
        limit: u64,
    },
    /// Not text: not UTF-8, or a control character other than tab, CR, LF, FF.
    #[error("not a G-code text file: {0}")]
    NotText(String),
    /// Empty.
    #[error("the program is empty")]
    Empty,
    /// Could not be stored.
    #[error("storing the program: {0}")]
    Io(String),
}

/// One stored program.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Program {
    /// Its id: the SHA-256 of its text (its file's stem).
    pub id: String,
    /// The name the uploaded file had (a label only).
    pub name: String,
    /// Its size (bytes).
    pub bytes: u64,
    /// Its lines.
    pub lines: u64,
    /// Uploaded (seconds since the Unix epoch).
    pub uploaded_unix_s: u64,
}

/// The store.
pub struct Programs {
    dir: PathBuf,
    limit_bytes: u64,
    index: Mutex<Vec<Program>>,
}

impl Programs {
    /// Open (and make) the store in `<data_dir>/web/programs`; uploads up to
    /// `limit_bytes`.
    pub fn open(data_dir: &Path, limit_bytes: u64) -> std::io::Result<Programs> {
        let dir = data_dir.join("web/programs");
        std::fs::create_dir_all(&dir)?;
        let index = std::fs::read(dir.join("index.json"))
            .ok()
            .and_then(|b| serde_json::from_slice::<Vec<Program>>(&b).ok())
            .unwrap_or_default()
            .into_iter()
            .filter(|p| is_id(&p.id) && dir.join(format!("{}.ngc", p.id)).is_file())
            .collect();
        Ok(Programs {
            dir,
            limit_bytes,
            index: Mutex::new(index),
        })
    }

    /// The largest upload taken (bytes).
    pub fn limit_bytes(&self) -> u64 {
        self.limit_bytes
    }

    /// The programs, newest first.
    pub fn list(&self) -> Vec<Program> {
        let mut l = self.index.lock().map(|i| i.clone()).unwrap_or_default();
        l.reverse();
        l
    }

    /// The file of program `id` (`None`: no such program; `id` is checked to be a
    /// hash, so nothing else is ever named).
    pub fn path(&self, id: &str) -> Option<PathBuf> {
        if !is_id(id) {
            return None;
        }
        let known = self
            .index
            .lock()
            .map(|i| i.iter().any(|p| p.id == id))
            .unwrap_or(false);
        let path = self.dir.join(format!("{id}.ngc"));
        (known && path.is_file()).then_some(path)
    }

    /// Store an upload of `body` named `name` by the operator's file.
    pub fn store(&self, name: &str, body: &[u8], now_unix_s: u64) -> Result<Program, UploadError> {
        check_text(body, self.limit_bytes)?;
        let id = format!("{:x}", Sha256::digest(body));
        let path = self.dir.join(format!("{id}.ngc"));
        if !path.is_file() {
            write_file(&path, body).map_err(|e| UploadError::Io(e.to_string()))?;
        }
        let program = Program {
            id,
            name: label(name),
            bytes: body.len() as u64,
            lines: body.split(|b| *b == b'\n').count() as u64,
            uploaded_unix_s: now_unix_s,
        };
        let mut index = self
            .index
            .lock()
            .map_err(|_| UploadError::Io("program index poisoned".into()))?;
        index.retain(|p| p.id != program.id);
        index.push(program.clone());
        let text =
            serde_json::to_vec_pretty(&*index).map_err(|e| UploadError::Io(e.to_string()))?;
        let tmp = self.dir.join("index.json.tmp");
        write_file(&tmp, &text)
            .and_then(|()| std::fs::rename(&tmp, self.dir.join("index.json")))
            .map_err(|e| UploadError::Io(e.to_string()))?;
        Ok(program)
    }
}

/// A program id: 64 lower-case hex digits.
fn is_id(id: &str) -> bool {
    id.len() == 64 && id.bytes().all(|b| matches!(b, b'0'..=b'9' | b'a'..=b'f'))
}

/// Write a new file with [`FILE_MODE`].
fn write_file(path: &Path, body: &[u8]) -> std::io::Result<()> {
    let mut f = std::fs::OpenOptions::new()
        .write(true)
        .create(true)
        .truncate(true)
        .mode(FILE_MODE)
        .open(path)?;
    f.write_all(body)?;
    f.sync_all()
}

/// An upload is text: within the limit, not empty, UTF-8, no control characters but
/// tab, CR, LF and form feed.
pub fn check_text(body: &[u8], limit_bytes: u64) -> Result<(), UploadError> {
    if body.len() as u64 > limit_bytes {
        return Err(UploadError::TooLarge {
            bytes: body.len() as u64,
            limit: limit_bytes,
        });
    }
    if body.is_empty() {
        return Err(UploadError::Empty);
    }
    let text = std::str::from_utf8(body)
        .map_err(|e| UploadError::NotText(format!("not UTF-8 at byte {}", e.valid_up_to())))?;
    if let Some((i, c)) = text
        .char_indices()
        .find(|(_, c)| c.is_control() && !matches!(c, '\t' | '\r' | '\n' | '\x0c'))
    {
        return Err(UploadError::NotText(format!(
            "control character {:#04x} at byte {i}",
            c as u32
        )));
    }
    Ok(())
}

/// The label kept of a file name: its last path component, printable characters
/// only, at most [`LABEL_CHARS`].
fn label(name: &str) -> String {
    let base = name.rsplit(['/', '\\']).next().unwrap_or("");
    let clean: String = base
        .chars()
        .filter(|c| !c.is_control())
        .take(LABEL_CHARS)
        .collect();
    if clean.trim().is_empty() {
        "program.ngc".into()
    } else {
        clean
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn store(tag: &str) -> (PathBuf, Programs) {
        let dir = std::env::temp_dir().join(format!("softnc-web-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let p = Programs::open(&dir, 1000).unwrap();
        (dir, p)
    }

    #[test]
    fn an_upload_is_stored_under_its_hash_and_its_name_is_only_a_label() {
        let (dir, p) = store("names");
        let prog = p
            .store("../../etc/passwd\u{7}.ngc", b"G0 X1\nG1 X2 F100\n", 7)
            .unwrap();
        assert_eq!(prog.name, "passwd.ngc");
        assert_eq!(prog.lines, 3);
        let path = p.path(&prog.id).unwrap();
        assert_eq!(
            path,
            dir.join("web/programs").join(format!("{}.ngc", prog.id))
        );
        assert_eq!(std::fs::read(&path).unwrap(), b"G0 X1\nG1 X2 F100\n");
        // ids are hashes: nothing else is named
        assert_eq!(p.path("../index.json"), None);
        assert_eq!(p.path(&"0".repeat(64)), None);
        // the index is read back
        let again = Programs::open(&dir, 1000).unwrap();
        assert_eq!(again.list(), vec![prog]);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn binary_empty_and_large_uploads_are_refused() {
        let (dir, p) = store("refused");
        assert!(matches!(
            p.store("a.ngc", b"G0 X1\0\x01", 0),
            Err(UploadError::NotText(_))
        ));
        assert!(matches!(
            p.store("a.ngc", &[0xff, 0xfe, b'G'], 0),
            Err(UploadError::NotText(_))
        ));
        assert_eq!(p.store("a.ngc", b"", 0), Err(UploadError::Empty));
        assert_eq!(
            p.store("a.ngc", &[b'G'; 1001], 0),
            Err(UploadError::TooLarge {
                bytes: 1001,
                limit: 1000
            })
        );
        assert!(p.list().is_empty());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
