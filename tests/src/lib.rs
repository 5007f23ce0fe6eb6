//! End-to-end tests live in `tests/tests/*.rs`; this library only holds helpers they share.

use std::path::PathBuf;

/// The workspace root (the folder holding the top-level `Cargo.toml`).
pub fn workspace_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// `../shared` beside the checkout, where the papers, spec and real logs live.
pub fn shared_dir() -> PathBuf {
    workspace_root().join("..").join("shared")
}
