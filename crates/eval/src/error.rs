//! Errors of an evaluation; each names the clip, setting or value at fault.

use envision4d_data::DataError;
use envision4d_losses::LossError;
use envision4d_model::SceneError;

#[derive(Debug, thiserror::Error)]
pub enum EvalError {
    /// An error while scoring one clip, with the clip's id.
    #[error("clip {clip}: {source}")]
    Clip {
        clip: String,
        source: Box<EvalError>,
    },
    /// The clip cannot be scored as asked (too few frames, a missing frame).
    #[error("{0}")]
    Unscorable(String),
    /// A sweep or protocol setting out of range.
    #[error("{key} = {value}: {reason}")]
    Invalid {
        key: &'static str,
        value: String,
        reason: String,
    },
    /// The model predicted NaN or infinite values.
    #[error(transparent)]
    Scene(#[from] SceneError),
    #[error("metric: {0}")]
    Metric(#[from] LossError),
    #[error(transparent)]
    Data(#[from] DataError),
    /// The backend failed (a device sync).
    #[error("device: {0}")]
    Device(String),
}

impl EvalError {
    /// Wraps `self` with the id of the clip it happened on.
    pub fn in_clip(self, clip: &str) -> EvalError {
        EvalError::Clip {
            clip: clip.to_owned(),
            source: Box::new(self),
        }
    }

    /// Whether the error comes from the user's input (a clip, a setting) rather than from
    /// the model or the machine: the CLI's exit code 2 against 1.
    pub fn is_input(&self) -> bool {
        match self {
            EvalError::Clip { source, .. } => source.is_input(),
            EvalError::Unscorable(_) | EvalError::Invalid { .. } => true,
            EvalError::Data(e) => e.is_input(),
            EvalError::Metric(e) => e.is_input(),
            EvalError::Scene(_) | EvalError::Device(_) => false,
        }
    }
}

pub type Result<T> = std::result::Result<T, EvalError>;
