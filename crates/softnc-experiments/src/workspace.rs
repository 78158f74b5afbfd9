//! Files of the workspace (machine profiles, G-code, design files): the one place
//! experiments and `softnc design` resolve a relative path.

use std::path::{Path, PathBuf};

/// A file of the workspace: `rel` itself when it is absolute or exists relative to
/// the current directory, else the same path in the workspace this crate was built
/// from when it exists there, else `rel` unchanged (so an error names the path as
/// given).
pub fn workspace_file(rel: impl AsRef<Path>) -> PathBuf {
    let rel = rel.as_ref();
    if rel.is_absolute() || rel.exists() {
        return rel.to_path_buf();
    }
    let ws = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(rel);
    if ws.exists() {
        ws
    } else {
        rel.to_path_buf()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_workspace_file_is_found_from_anywhere_and_a_missing_one_keeps_its_name() {
        let found = workspace_file("config/machines/default.ron");
        assert!(found.exists(), "{}", found.display());
        let missing = workspace_file("config/machines/no-such-machine.ron");
        assert_eq!(
            missing,
            PathBuf::from("config/machines/no-such-machine.ron")
        );
        assert_eq!(
            workspace_file("/no/such/file"),
            PathBuf::from("/no/such/file")
        );
    }
}
