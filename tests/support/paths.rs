//! Where a test finds the repository's files (each crate includes this file with `#[path]`).
//! Cargo's run-time `CARGO_MANIFEST_DIR` comes first: a test binary keeps the path of the
//! clone it was compiled in, and cargo reuses it from a shared target directory (CI's warm
//! cache) for a clone at another path, where it would read that other clone's fixtures and
//! configs, or fail on a path that is gone.

use std::path::PathBuf;

/// The including crate's folder (`crates/<name>`) as cargo runs the test; the compile-time
/// one when the binary is run by hand.
pub fn manifest_dir() -> PathBuf {
    std::env::var_os("CARGO_MANIFEST_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")))
}
