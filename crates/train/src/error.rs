//! Errors of the training crate; each names the file, key or value at fault.

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum TrainError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    /// TOML syntax, an unknown key (serde names it) or a wrong type.
    #[error("{path}: {message}")]
    Parse { path: PathBuf, message: String },
    /// A value that parses but is not allowed.
    #[error("config key `{key}` = {value}: {reason}")]
    Invalid {
        key: &'static str,
        value: String,
        reason: String,
    },
    #[error("model: {0}")]
    Model(String),
    #[error("render: {0}")]
    Render(#[from] envision4d_splat::RenderError),
    #[error("loss: {0}")]
    Loss(#[from] envision4d_losses::LossError),
    /// Predictions (poses) were not finite: the step is skipped by the NaN guard.
    #[error("non-finite {0}")]
    NonFinite(&'static str),
    #[error("batch: {0}")]
    Batch(String),
    /// A file or folder the config or the command line names is missing or unreadable.
    #[error("{0}")]
    Input(String),
    /// The NaN guard stopped the run.
    #[error("{0}")]
    Diverged(String),
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
}

pub type Result<T> = std::result::Result<T, TrainError>;

/// Maps an I/O error on `path` to [`TrainError::Io`] naming the path (`.map_err(io(p))`).
pub fn io(path: &std::path::Path) -> impl FnOnce(std::io::Error) -> TrainError + '_ {
    move |source| TrainError::Io {
        path: path.to_path_buf(),
        source,
    }
}
