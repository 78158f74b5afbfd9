//! Files of the workspace (machine profiles, G-code, design files).

use std::path::PathBuf;

/// A file of the workspace: relative to the current directory when it exists there,
/// else to the workspace this crate was built from.
pub fn workspace_file(rel: &str) -> PathBuf {
    let p = PathBuf::from(rel);
    if p.exists() {
        return p;
    }
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(rel)
}
