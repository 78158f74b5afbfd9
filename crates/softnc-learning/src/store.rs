//! The learning store: one correction per (job content, machine profile, feed
//! override), persisted as a file written atomically (temp file, fsync, rename), so a
//! crash leaves the old entry or the new one, never a corrupt one. A changed job or
//! profile has a different key: its old entry is never applied.

use serde::{de::DeserializeOwned, Deserialize, Serialize};
use sha2::{Digest, Sha256};
use softnc_core::store::write_atomic;
use std::path::PathBuf;

/// Why the store failed.
#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    /// File system.
    #[error("{path}: {source}")]
    Io {
        /// File.
        path: String,
        /// Cause.
        source: std::io::Error,
    },
    /// A stored entry does not parse (written by another version).
    #[error("{path}: unreadable entry: {message}")]
    Corrupt {
        /// File.
        path: String,
        /// Parser message.
        message: String,
    },
}

/// What a learned correction belongs to.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct LearningKey {
    /// SHA-256 of the job's text.
    pub job_sha256: String,
    /// SHA-256 of the machine profile's text.
    pub profile_sha256: String,
    /// Feed override in percent.
    pub override_pct: u32,
}

impl LearningKey {
    /// The key of a job text on a profile text at an override.
    pub fn new(job_text: &[u8], profile_text: &[u8], override_pct: u32) -> Self {
        LearningKey {
            job_sha256: hex(&Sha256::digest(job_text)),
            profile_sha256: hex(&Sha256::digest(profile_text)),
            override_pct,
        }
    }

    /// File name of the entry.
    pub fn file_name(&self) -> String {
        format!(
            "{}-{}-{}.json",
            &self.job_sha256[..16],
            &self.profile_sha256[..16],
            self.override_pct
        )
    }
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

#[derive(Serialize, Deserialize)]
struct Entry<T> {
    key: LearningKey,
    value: T,
}

/// A folder of learned corrections.
#[derive(Debug, Clone)]
pub struct LearningStore {
    dir: PathBuf,
}

impl LearningStore {
    /// A store in `dir` (created on first write).
    pub fn new(dir: impl Into<PathBuf>) -> Self {
        LearningStore { dir: dir.into() }
    }

    fn path(&self, key: &LearningKey) -> PathBuf {
        self.dir.join(key.file_name())
    }

    /// Write `value` for `key`, atomically.
    pub fn put<T: Serialize>(&self, key: &LearningKey, value: &T) -> Result<(), StoreError> {
        let path = self.path(key);
        let io = |source| StoreError::Io {
            path: path.display().to_string(),
            source,
        };
        let bytes = serde_json::to_vec(&Entry {
            key: key.clone(),
            value,
        })
        .expect("serialisable entry");
        write_atomic(&path, &bytes).map_err(io)
    }

    /// The entry for `key`, if there is one for exactly this key.
    pub fn get<T: DeserializeOwned>(&self, key: &LearningKey) -> Result<Option<T>, StoreError> {
        let path = self.path(key);
        let bytes = match std::fs::read(&path) {
            Ok(b) => b,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(source) => {
                return Err(StoreError::Io {
                    path: path.display().to_string(),
                    source,
                })
            }
        };
        let entry: Entry<T> = serde_json::from_slice(&bytes).map_err(|e| StoreError::Corrupt {
            path: path.display().to_string(),
            message: e.to_string(),
        })?;
        Ok((entry.key == *key).then_some(entry.value))
    }

    /// Keys of all entries.
    pub fn list(&self) -> Result<Vec<LearningKey>, StoreError> {
        let rd = match std::fs::read_dir(&self.dir) {
            Ok(rd) => rd,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(vec![]),
            Err(source) => {
                return Err(StoreError::Io {
                    path: self.dir.display().to_string(),
                    source,
                })
            }
        };
        let mut keys = vec![];
        for ent in rd.flatten() {
            let p = ent.path();
            if p.extension().is_some_and(|e| e == "json")
                && !p
                    .file_name()
                    .is_some_and(|n| n.to_string_lossy().starts_with('.'))
            {
                if let Ok(bytes) = std::fs::read(&p) {
                    if let Ok(e) = serde_json::from_slice::<Entry<serde_json::Value>>(&bytes) {
                        keys.push(e.key);
                    }
                }
            }
        }
        Ok(keys)
    }

    /// The folder.
    pub fn dir(&self) -> &std::path::Path {
        &self.dir
    }

    /// All readable entries with their keys, oldest file name first (unreadable
    /// files are skipped: they are not entries of this store).
    pub fn entries<T: DeserializeOwned>(&self) -> Result<Vec<(LearningKey, T)>, StoreError> {
        let mut out = vec![];
        for key in self.list()? {
            if let Some(v) = self.get(&key)? {
                out.push((key, v));
            }
        }
        out.sort_by_key(|(k, _)| k.file_name());
        Ok(out)
    }

    /// Remove temporary files left by writers that were killed mid-write; returns how
    /// many. Only call it when no other process writes to this store.
    pub fn remove_leftovers(&self) -> Result<usize, StoreError> {
        let rd = match std::fs::read_dir(&self.dir) {
            Ok(rd) => rd,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(0),
            Err(source) => {
                return Err(StoreError::Io {
                    path: self.dir.display().to_string(),
                    source,
                })
            }
        };
        let mut n = 0;
        for ent in rd.flatten() {
            let name = ent.file_name().to_string_lossy().into_owned();
            if name.starts_with('.')
                && name.contains(".json.tmp")
                && std::fs::remove_file(ent.path()).is_ok()
            {
                n += 1;
            }
        }
        Ok(n)
    }

    /// Remove the entry for `key` (or all entries when `None`).
    pub fn clear(&self, key: Option<&LearningKey>) -> Result<usize, StoreError> {
        let keys = match key {
            Some(k) => vec![k.clone()],
            None => self.list()?,
        };
        let mut n = 0;
        for k in keys {
            if std::fs::remove_file(self.path(&k)).is_ok() {
                n += 1;
            }
        }
        Ok(n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tmpdir(tag: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("softnc-learn-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        d
    }

    /// Removes the test's folder when the test ends, also when it fails.
    struct Cleanup(PathBuf);

    impl Drop for Cleanup {
        fn drop(&mut self) {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }

    #[test]
    fn keyed_by_job_profile_and_override() {
        let store = LearningStore::new(tmpdir("key"));
        let _cleanup = Cleanup(store.dir().to_path_buf());
        let k = LearningKey::new(b"G1 X1\n", b"profile", 100);
        store.put(&k, &vec![1.0, 2.0]).unwrap();
        assert_eq!(store.get::<Vec<f64>>(&k).unwrap(), Some(vec![1.0, 2.0]));
        assert_eq!(
            store
                .get::<Vec<f64>>(&LearningKey::new(b"G1 X2\n", b"profile", 100))
                .unwrap(),
            None
        );
        assert_eq!(
            store
                .get::<Vec<f64>>(&LearningKey::new(b"G1 X1\n", b"profile2", 100))
                .unwrap(),
            None
        );
        assert_eq!(
            store
                .get::<Vec<f64>>(&LearningKey::new(b"G1 X1\n", b"profile", 120))
                .unwrap(),
            None
        );
        assert_eq!(store.list().unwrap(), vec![k.clone()]);
        assert_eq!(store.clear(None).unwrap(), 1);
        assert!(store.list().unwrap().is_empty());
    }
}
