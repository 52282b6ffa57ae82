//! One writer per run directory: an OS file lock (`flock`, via `std::fs::File::try_lock`)
//! on `out_dir/.lock`, taken before anything is written and held for the run's life. The OS
//! drops it when the holder exits, however it exits, so a lock left by a killed run never
//! blocks `--resume`; the file's text (pid, start time) only names the holder in the error.

use crate::error::{Result, TrainError};
use std::fs::{File, OpenOptions, TryLockError};
use std::io::{Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

/// The lock file inside a run directory.
pub const LOCK_FILE: &str = ".lock";

/// A held run-directory lock (released on drop).
#[derive(Debug)]
pub struct RunLock {
    _file: File,
    pub path: PathBuf,
}

impl RunLock {
    /// Takes the lock of `dir` (which must exist), or says who holds it.
    pub fn acquire(dir: &Path) -> Result<RunLock> {
        let path = dir.join(LOCK_FILE);
        let mut file = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(&path)
            .map_err(|e| TrainError::write(&path, e))?;
        match file.try_lock() {
            Ok(()) => {}
            Err(TryLockError::WouldBlock) => {
                // Read by path: flock does not stop other readers of the file.
                let holder = std::fs::read_to_string(&path).unwrap_or_default();
                let holder = holder.trim();
                return Err(TrainError::Unusable(format!(
                    "run.out_dir {} is in use by another envision4d process ({}); wait for it \
                     to finish or choose another run.out_dir",
                    dir.display(),
                    if holder.is_empty() {
                        "holder unknown"
                    } else {
                        holder
                    }
                )));
            }
            Err(TryLockError::Error(e)) => return Err(TrainError::write(&path, e)),
        }
        // Who holds it, for the next one to be told (the lock itself is the OS's).
        let since = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_secs());
        let note = format!("pid {}, since unix time {since}\n", std::process::id());
        file.set_len(0)
            .and_then(|()| file.seek(SeekFrom::Start(0)))
            .and_then(|_| file.write_all(note.as_bytes()))
            .map_err(|e| TrainError::write(&path, e))?;
        Ok(RunLock { _file: file, path })
    }
}
