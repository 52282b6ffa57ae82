//! Errors of the training crate; each names the file, key, clip or value at fault, and
//! [`TrainError::is_input`] says whose fault it is (the CLI's exit code 2 against 1).

use envision4d_data::DataError;
use envision4d_eval::EvalError;
use envision4d_model::SceneError;
use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum TrainError {
    /// Reading a file or folder failed (one the config or command line names, or a
    /// checkpoint or log of the run being resumed).
    #[error("{}: {source}", path.display())]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    /// TOML syntax, an unknown key (serde names it) or a wrong type.
    #[error("{}: {message}", path.display())]
    Parse { path: PathBuf, message: String },
    /// A value that parses but is not allowed.
    #[error("config key `{key}` = {value}: {reason}")]
    Invalid {
        key: &'static str,
        value: String,
        reason: String,
    },
    /// The dataset (or one of its clips) cannot be read or has no usable clip.
    #[error("{what}: {source}")]
    Data { what: String, source: DataError },
    /// An input that cannot be used as the config asks: a clip without the labels the stage
    /// needs, clips of different sizes, an empty training split, a run folder already in use.
    #[error("{0}")]
    Unusable(String),
    /// A checkpoint named by the config or `--resume` cannot be used: missing, another
    /// architecture, another config.
    #[error("{}: {reason}", path.display())]
    Checkpoint { path: PathBuf, reason: String },
    /// Writing a checkpoint, log or model file failed (not the user's input).
    #[error("{}: cannot write: {reason}", path.display())]
    Write { path: PathBuf, reason: String },
    #[error("loss: {0}")]
    Loss(#[from] envision4d_losses::LossError),
    #[error("validation: {0}")]
    Eval(#[from] EvalError),
    /// Predictions (poses, losses) were not finite: the step is skipped by the NaN guard.
    #[error("non-finite {0}")]
    NonFinite(&'static str),
    /// The NaN guard stopped the run.
    #[error("{0}")]
    Diverged(String),
    /// A broken invariant of the program (a head that should have run, a missing device).
    #[error("internal: {0}")]
    Internal(String),
}

impl From<SceneError> for TrainError {
    /// A non-finite prediction stays [`TrainError::NonFinite`], so the NaN guard sees it.
    fn from(e: SceneError) -> Self {
        match e {
            SceneError::NonFinite(what) => TrainError::NonFinite(what),
            SceneError::MissingHeads => TrainError::Internal(e.to_string()),
            SceneError::Render(r) => TrainError::Internal(format!("render: {r}")),
        }
    }
}

impl TrainError {
    pub fn invalid(
        key: &'static str,
        value: impl std::fmt::Display,
        reason: impl Into<String>,
    ) -> Self {
        TrainError::Invalid {
            key,
            value: value.to_string(),
            reason: reason.into(),
        }
    }

    /// A dataset error, with what was being read (`data.root /x`, `clip 3`).
    pub fn data(what: impl Into<String>, source: DataError) -> Self {
        TrainError::Data {
            what: what.into(),
            source,
        }
    }

    /// A checkpoint at `path` that cannot be used, and why.
    pub fn checkpoint(path: impl Into<PathBuf>, reason: impl std::fmt::Display) -> Self {
        TrainError::Checkpoint {
            path: path.into(),
            reason: reason.to_string(),
        }
    }

    /// A failed write of `path`.
    pub fn write(path: impl Into<PathBuf>, reason: impl std::fmt::Display) -> Self {
        TrainError::Write {
            path: path.into(),
            reason: reason.to_string(),
        }
    }

    /// Whether the user can fix this by changing a file, key or argument they gave (exit
    /// code 2) rather than a failure of the program or the machine (exit code 1). Reading a
    /// file the user named is their input; writing our own outputs is not.
    pub fn is_input(&self) -> bool {
        match self {
            TrainError::Read { .. }
            | TrainError::Parse { .. }
            | TrainError::Invalid { .. }
            | TrainError::Unusable(_)
            | TrainError::Checkpoint { .. } => true,
            TrainError::Data { source, .. } => source.is_input(),
            TrainError::Loss(e) => e.is_input(),
            TrainError::Eval(e) => e.is_input(),
            TrainError::Write { .. }
            | TrainError::NonFinite(_)
            | TrainError::Diverged(_)
            | TrainError::Internal(_) => false,
        }
    }
}

pub type Result<T> = std::result::Result<T, TrainError>;

/// Maps a failed read of `path` to [`TrainError::Read`] naming it (`.map_err(read(p))`).
pub fn read(path: &std::path::Path) -> impl FnOnce(std::io::Error) -> TrainError + '_ {
    move |source| TrainError::Read {
        path: path.to_path_buf(),
        source,
    }
}

/// Maps a failed write (create, rename, remove) of `path` to [`TrainError::Write`].
pub fn written(path: &std::path::Path) -> impl FnOnce(std::io::Error) -> TrainError + '_ {
    move |e| TrainError::write(path, e)
}
