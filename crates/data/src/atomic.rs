//! Atomic file output: write to a temp file in the destination folder, then rename, so a
//! crash or a failed encode never leaves a half-written file under the final name.

use crate::error::{DataError, Result};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

static TEMP_COUNTER: AtomicUsize = AtomicUsize::new(0);

/// Writes `bytes` to `path` atomically.
pub fn write_bytes(path: &Path, bytes: &[u8]) -> Result<()> {
    write_with(path, |tmp| {
        std::fs::write(tmp, bytes).map_err(|e| e.to_string())
    })
}

/// Runs `write` on a temp path next to `path` and renames it into place; on failure the
/// temp file is removed and `path` is untouched.
pub fn write_with(
    path: &Path,
    write: impl FnOnce(&Path) -> std::result::Result<(), String>,
) -> Result<()> {
    let fail = |msg: String| DataError::Write {
        path: path.to_path_buf(),
        msg,
    };
    let name = path
        .file_name()
        .ok_or_else(|| fail("path has no file name".into()))?;
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let tmp: PathBuf = dir.join(format!(
        ".{}.tmp-{}-{}",
        name.to_string_lossy(),
        std::process::id(),
        TEMP_COUNTER.fetch_add(1, Ordering::Relaxed)
    ));
    let result = write(&tmp).and_then(|()| std::fs::rename(&tmp, path).map_err(|e| e.to_string()));
    if let Err(msg) = result {
        let _ = std::fs::remove_file(&tmp);
        return Err(fail(msg));
    }
    Ok(())
}

/// Creates a folder (and parents), naming it in the error.
pub fn create_dir(path: &Path) -> Result<()> {
    std::fs::create_dir_all(path).map_err(|e| DataError::Write {
        path: path.to_path_buf(),
        msg: e.to_string(),
    })
}
