//! The crate's one error type. Every message names the file (or key) and the problem.

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum DataError {
    #[error("{}: cannot read: {source}", path.display())]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{}: cannot decode image: {msg}", path.display())]
    Decode { path: PathBuf, msg: String },
    #[error(
        "{}: image is {found_w}x{found_h} (WxH) but the clip's first frame is {want_w}x{want_h}: mixed sizes in one clip",
        path.display()
    )]
    MixedSizes {
        path: PathBuf,
        found_w: usize,
        found_h: usize,
        want_w: usize,
        want_h: usize,
    },
    #[error("{}: {found} frames, but a clip needs {needed}", path.display())]
    TooFewFrames {
        path: PathBuf,
        found: usize,
        needed: usize,
    },
    #[error("{}: folder has no image files (.png, .jpg, .jpeg)", path.display())]
    EmptyFolder { path: PathBuf },
    #[error("{}: bad ground-truth file: {msg}", path.display())]
    BadGt { path: PathBuf, msg: String },
    #[error("{}: image {w}x{h} (WxH) is smaller than the crop {crop_w}x{crop_h}", path.display())]
    CropTooLarge {
        path: PathBuf,
        w: usize,
        h: usize,
        crop_w: usize,
        crop_h: usize,
    },
    #[error("invalid {key} = {value}: {msg}")]
    Config {
        key: &'static str,
        value: String,
        msg: String,
    },
    #[error("{}: no usable clips ({skipped} skipped; see the warnings above)", root.display())]
    NoClips { root: PathBuf, skipped: usize },
    #[error("clip {clip} has no frames")]
    EmptyClip { clip: String },
    #[error("{}: cannot write: {msg}", path.display())]
    Write { path: PathBuf, msg: String },
    /// Another process holds the directory's lock ([`crate::lock::DirLock`]).
    #[error(
        "{key} {} is in use by another envision4d process ({holder}); wait for it to finish or choose another {key}",
        dir.display()
    )]
    InUse {
        key: &'static str,
        dir: PathBuf,
        holder: String,
    },
}

pub type Result<T> = std::result::Result<T, DataError>;

impl DataError {
    /// Whether the user can fix this by changing a file or setting they gave (everything but
    /// a failed write of our own output): the CLI's exit code 2 against 1.
    pub fn is_input(&self) -> bool {
        !matches!(self, DataError::Write { .. })
    }
}

impl DataError {
    pub(crate) fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        DataError::Io {
            path: path.into(),
            source,
        }
    }
    pub(crate) fn gt(path: impl Into<PathBuf>, msg: impl Into<String>) -> Self {
        DataError::BadGt {
            path: path.into(),
            msg: msg.into(),
        }
    }
    pub(crate) fn config(key: &'static str, value: impl ToString, msg: impl Into<String>) -> Self {
        DataError::Config {
            key,
            value: value.to_string(),
            msg: msg.into(),
        }
    }
}
