//! The log files a program writes with `(LOGOPEN,name)`, `(LOGAPPEND,name)`,
//! `(LOG,text)` and `(LOGCLOSE)` (LinuxCNC's `convert_comment` and `emccanon.cc`:
//! LOGOPEN opens `name` emptied, LOGAPPEND for appending, LOG writes its text with
//! the parameters in it substituted and a newline into the open file, LOGCLOSE
//! closes it; a LOG with no file open writes nothing).
//!
//! The reader collects them ([`crate::Program::log_files`]) and writes nothing: a
//! program is read whole before it runs, so its log files are written by whoever
//! runs it, once it is accepted ([`write`]), into one folder — a name is a plain
//! file name there, and a name that would leave the folder refuses the program
//! at its line. A rejected program writes no log file.

use std::io::Write;
use std::path::Path;

/// One log file as the program leaves it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LogFile {
    /// Its name in the log folder (a plain file name).
    pub name: String,
    /// Emptied first (the program's last `LOGOPEN` of it), else appended to.
    pub truncate: bool,
    /// What the program writes into it after that, line by line.
    pub text: String,
}

/// The log files of a reading and the one open ([`LogFile`]).
#[derive(Debug, Clone, Default)]
pub(crate) struct LogFiles {
    pub(crate) files: Vec<LogFile>,
    open: Option<usize>,
}

impl LogFiles {
    /// `LOGOPEN` (`truncate`) or `LOGAPPEND` of `name` (already checked).
    pub(crate) fn open(&mut self, name: &str, truncate: bool) {
        let k = match self.files.iter().position(|f| f.name == name) {
            Some(k) => k,
            None => {
                self.files.push(LogFile {
                    name: name.to_string(),
                    truncate,
                    text: String::new(),
                });
                self.files.len() - 1
            }
        };
        if truncate {
            let f = &mut self.files[k];
            f.truncate = true;
            f.text.clear();
        }
        self.open = Some(k);
    }

    /// `LOG`: a line into the open file, if one is open.
    pub(crate) fn log(&mut self, text: &str) {
        if let Some(k) = self.open {
            let f = &mut self.files[k];
            f.text.push_str(text);
            f.text.push('\n');
        }
    }

    /// `LOGCLOSE`.
    pub(crate) fn close(&mut self) {
        self.open = None;
    }
}

/// Why a log file name is refused: `None` for a plain file name (one normal path
/// component: no `/`, not `.` or `..`, not empty).
pub fn name_problem(name: &str) -> Option<&'static str> {
    let mut parts = Path::new(name).components();
    match (parts.next(), parts.next()) {
        _ if name.is_empty() => Some("no log file name"),
        (Some(std::path::Component::Normal(_)), None) if !name.contains('/') => None,
        _ => Some("a log file name is a plain file name in the log folder (no '/', '.' or '..')"),
    }
}

/// Writes `files` into the folder `dir` (created if missing): an emptied file
/// is written whole beside its place and renamed over it (never half written),
/// an appended one gets its text at its end (created if missing).
pub fn write(dir: &Path, files: &[LogFile]) -> std::io::Result<()> {
    if files.is_empty() {
        return Ok(());
    }
    std::fs::create_dir_all(dir)?;
    for f in files {
        debug_assert!(name_problem(&f.name).is_none());
        let path = dir.join(&f.name);
        if f.truncate {
            let tmp = dir.join(format!(".{}.part-{}", f.name, std::process::id()));
            std::fs::write(&tmp, &f.text)?;
            std::fs::rename(&tmp, &path)?;
        } else {
            let mut out = std::fs::OpenOptions::new()
                .create(true)
                .append(true)
                .open(&path)?;
            out.write_all(f.text.as_bytes())?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_plain_file_names_are_taken() {
        assert_eq!(name_problem("probe-results.txt"), None);
        for bad in ["", "../x", "a/b", "/etc/passwd", ".", "..", "x/"] {
            assert!(name_problem(bad).is_some(), "{bad:?}");
        }
    }

    #[test]
    fn open_empties_append_keeps_close_stops() {
        let mut l = LogFiles::default();
        l.log("before any open");
        l.open("a.txt", false);
        l.log("one");
        l.open("a.txt", true);
        l.log("two");
        l.open("b.txt", true);
        l.log("three");
        l.open("a.txt", false);
        l.log("four");
        l.close();
        l.log("after close");
        assert_eq!(
            l.files,
            vec![
                LogFile {
                    name: "a.txt".into(),
                    truncate: true,
                    text: "two\nfour\n".into()
                },
                LogFile {
                    name: "b.txt".into(),
                    truncate: true,
                    text: "three\n".into()
                },
            ]
        );
    }

    #[test]
    fn written_into_the_folder_emptied_or_appended() {
        let dir = std::env::temp_dir().join(format!("softnc-logs-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("a.txt"), "old\n").unwrap();
        std::fs::write(dir.join("b.txt"), "old\n").unwrap();
        let files = [
            LogFile {
                name: "a.txt".into(),
                truncate: true,
                text: "new\n".into(),
            },
            LogFile {
                name: "b.txt".into(),
                truncate: false,
                text: "more\n".into(),
            },
        ];
        write(&dir, &files).unwrap();
        assert_eq!(std::fs::read_to_string(dir.join("a.txt")).unwrap(), "new\n");
        assert_eq!(
            std::fs::read_to_string(dir.join("b.txt")).unwrap(),
            "old\nmore\n"
        );
        // nothing else left beside them
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 2);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
