//! The one error type of the crate. Every variant names the input (and, for files, the path
//! and key) it is about, so a failed evaluation says what to fix.

use std::path::PathBuf;

/// Errors from losses and metrics. Bad input never panics and never yields a NaN metric.
#[derive(Debug, thiserror::Error)]
pub enum LossError {
    /// A tensor or array had the wrong rank/layout.
    #[error("{what}: expected {expected}, got shape {got:?}")]
    BadShape {
        what: &'static str,
        expected: &'static str,
        got: Vec<usize>,
    },
    /// Two inputs that must have the same shape do not.
    #[error("{what}: shapes differ: {left:?} vs {right:?}")]
    ShapeMismatch {
        what: &'static str,
        left: Vec<usize>,
        right: Vec<usize>,
    },
    /// Two inputs that must share a dtype do not (e.g. f32 images into an f64 LPIPS).
    #[error("{what}: dtype {got} does not match {expected}")]
    DtypeMismatch {
        what: &'static str,
        expected: String,
        got: String,
    },
    /// A NaN or infinite value in an input.
    #[error("{what}: non-finite value {value} at flat index {index}")]
    NonFinite {
        what: &'static str,
        index: usize,
        value: f64,
    },
    /// An input is well-formed but cannot be evaluated (too small, empty after a crop, ...).
    #[error("{what}: {reason}")]
    Invalid { what: &'static str, reason: String },
    /// A weights file could not be read or is malformed.
    #[error("LPIPS weights file {path}: {reason}")]
    WeightsFile { path: PathBuf, reason: String },
    /// A required tensor is not in the weights file.
    #[error("LPIPS weights file {path}: missing tensor `{key}`")]
    MissingKey { path: PathBuf, key: String },
    /// A tensor in the weights file has the wrong shape.
    #[error("LPIPS weights file {path}: tensor `{key}` has shape {got:?}, expected {expected:?}")]
    WeightShape {
        path: PathBuf,
        key: String,
        got: Vec<usize>,
        expected: Vec<usize>,
    },
    /// LPIPS was asked for (λ_lpips > 0 or an LPIPS metric) but no weights are loaded.
    #[error("LPIPS is unavailable ({reason}); {hint}")]
    LpipsUnavailable { reason: String, hint: &'static str },
    /// Reading a tensor back from the device failed.
    #[error("{what}: reading tensor data failed: {reason}")]
    Readback { what: &'static str, reason: String },
}

impl LossError {
    /// Whether the user can fix this by changing a file or setting they gave (an LPIPS
    /// weights file, asking for LPIPS without weights), rather than a bug or a diverged
    /// model: the CLI's exit code 2 against 1.
    pub fn is_input(&self) -> bool {
        matches!(
            self,
            LossError::WeightsFile { .. }
                | LossError::MissingKey { .. }
                | LossError::WeightShape { .. }
                | LossError::LpipsUnavailable { .. }
        )
    }
}

/// Shorthand used throughout the crate.
pub type Result<T> = std::result::Result<T, LossError>;

/// Reject the first NaN/inf in `values`, naming the input.
pub(crate) fn ensure_finite(what: &'static str, values: &[f64]) -> Result<()> {
    match values.iter().position(|v| !v.is_finite()) {
        Some(index) => Err(LossError::NonFinite {
            what,
            index,
            value: values[index],
        }),
        None => Ok(()),
    }
}
