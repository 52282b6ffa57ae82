//! One writer per output directory: an OS file lock (`flock`, via `std::fs::File::try_lock`)
//! on `dir/.lock`, taken before anything is written there and held until dropped. The OS
//! drops it when the holder exits, however it exits, so a lock left by a killed process never
//! blocks the next one; the file's text (pid, start time) only names the holder in the error.
//! `train` holds it on `run.out_dir`, `eval` and `render` on `--out`.

use crate::error::{DataError, Result};
use std::fs::{File, OpenOptions, TryLockError};
use std::io::{Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

/// The lock file inside a locked directory.
pub const LOCK_FILE: &str = ".lock";

/// A held directory lock (released on drop).
#[derive(Debug)]
pub struct DirLock {
    _file: File,
    pub path: PathBuf,
}

impl DirLock {
    /// Takes the lock of `dir` (which must exist), or says who holds it. `key` is how the
    /// user named the directory (`run.out_dir`, `--out`), for the error.
    pub fn acquire(dir: &Path, key: &'static str) -> Result<DirLock> {
        let path = dir.join(LOCK_FILE);
        let write_err = |e: std::io::Error| DataError::Write {
            path: path.clone(),
            msg: e.to_string(),
        };
        let mut file = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(&path)
            .map_err(write_err)?;
        match file.try_lock() {
            Ok(()) => {}
            Err(TryLockError::WouldBlock) => {
                // Read by path: flock does not stop other readers of the file.
                let holder = std::fs::read_to_string(&path).unwrap_or_default();
                let holder = holder.trim();
                return Err(DataError::InUse {
                    key,
                    dir: dir.to_path_buf(),
                    holder: if holder.is_empty() {
                        "holder unknown".into()
                    } else {
                        holder.into()
                    },
                });
            }
            Err(TryLockError::Error(e)) => return Err(write_err(e)),
        }
        // Who holds it, for the next one to be told (the lock itself is the OS's).
        let since = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_secs());
        let note = format!("pid {}, since unix time {since}\n", std::process::id());
        file.set_len(0)
            .and_then(|()| file.seek(SeekFrom::Start(0)))
            .and_then(|_| file.write_all(note.as_bytes()))
            .map_err(write_err)?;
        Ok(DirLock { _file: file, path })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Guards the lock's two promises: a second taker is refused naming the directory, the
    /// key and the holder while the first holds it; once dropped, the file left behind does
    /// not block.
    #[test]
    fn a_held_lock_refuses_a_second_taker_and_a_dropped_one_does_not() {
        let tmp = tempfile::tempdir().unwrap();
        let held = DirLock::acquire(tmp.path(), "--out").unwrap();
        let err = DirLock::acquire(tmp.path(), "--out").unwrap_err();
        assert!(err.is_input(), "{err}");
        let msg = err.to_string();
        assert!(msg.contains("--out") && msg.contains("in use"), "{msg}");
        assert!(msg.contains(&tmp.path().display().to_string()), "{msg}");
        assert!(
            msg.contains(&format!("pid {}", std::process::id())),
            "{msg}"
        );
        drop(held);
        assert!(tmp.path().join(LOCK_FILE).exists());
        DirLock::acquire(tmp.path(), "--out").unwrap();
    }
}
