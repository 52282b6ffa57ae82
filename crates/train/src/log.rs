//! The run's JSONL log: one JSON object per logged step, validation and checkpoint. On
//! resume, records at or after the resumed step are dropped so the log continues exactly.

use crate::error::{read, written, Result, TrainError};
use crate::grad_clip::{GradGroup, GradNorms};
use crate::step::{StepOutcome, StepReport};
use crate::validate::ValReport;
use serde_json::{json, Value};
use std::io::Write;
use std::path::{Path, PathBuf};

pub struct JsonlLog {
    path: PathBuf,
    file: std::fs::File,
}

/// JSON has no NaN: non-finite numbers are written as null.
/// Whether applied step `step` (0-based) is written to the log (every `log_every`th; skipped
/// steps always are).
pub fn logged(step: u64, log_every: u64) -> bool {
    (step + 1).is_multiple_of(log_every.max(1))
}

fn num(v: f64) -> Value {
    if v.is_finite() {
        json!(v)
    } else {
        Value::Null
    }
}

/// Step records carry the 0-based index of the step; validation and checkpoint records the
/// number of steps done. Resuming at `done` keeps what happened before it.
fn keep_record(line: &str, done: u64) -> bool {
    let Ok(v) = serde_json::from_str::<Value>(line) else {
        return false;
    };
    match (
        v.get("kind").and_then(Value::as_str),
        v.get("step").and_then(Value::as_u64),
    ) {
        (Some("step"), Some(s)) => s < done,
        (Some(_), Some(s)) => s <= done,
        _ => false,
    }
}

impl JsonlLog {
    /// Opens `path` for appending, first keeping only records of steps before `from_step`.
    pub fn open(path: &Path, from_step: u64) -> Result<JsonlLog> {
        if path.exists() {
            let text = std::fs::read_to_string(path).map_err(read(path))?;
            let kept: String = text
                .lines()
                .filter(|l| keep_record(l, from_step))
                .map(|l| format!("{l}\n"))
                .collect();
            envision4d_data::atomic::write_bytes(path, kept.as_bytes())
                .map_err(|e| TrainError::write(path, e))?;
        }
        let file = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(path)
            .map_err(written(path))?;
        Ok(JsonlLog {
            path: path.to_path_buf(),
            file,
        })
    }

    fn write(&mut self, v: Value) -> Result<()> {
        writeln!(self.file, "{v}").map_err(written(&self.path))
    }

    pub fn step(&mut self, r: &StepReport, seconds: f64, steps_per_second: f64) -> Result<()> {
        let outcome = match r.outcome {
            StepOutcome::Applied => "applied",
            StepOutcome::SkippedNonFiniteLoss => "skipped_nonfinite_loss",
            StepOutcome::SkippedNonFiniteGradient => "skipped_nonfinite_gradient",
            StepOutcome::SkippedNonFiniteUpdate => "skipped_nonfinite_update",
        };
        self.write(json!({
            "kind": "step",
            "step": r.step,
            "loss": num(r.total),
            "rgb": num(r.rgb),
            "camera": num(r.camera),
            "depth": num(r.depth),
            "psnr": r.psnr.map_or(Value::Null, num),
            "flow": r.flow.map_or(Value::Null, num),
            "grad_norm": r.grad_norms.map_or(Value::Null, |g| num(g.total)),
            "grad_norms": per_group(r.grad_norms, GradNorms::norm),
            "grad_rms": per_group(r.grad_norms, GradNorms::rms),
            "lr": r.lr,
            "phase": format!("{:?}", r.phase).to_lowercase(),
            "outcome": outcome,
            "seconds": seconds,
            "steps_per_second": steps_per_second,
        }))
    }

    pub fn validation(&mut self, v: &ValReport) -> Result<()> {
        let mut value = serde_json::to_value(v).map_err(|e| TrainError::Internal(e.to_string()))?;
        value["kind"] = json!("validation");
        self.write(value)
    }

    pub fn checkpoint(&mut self, step: u64, dir: &Path) -> Result<()> {
        self.write(json!({"kind": "checkpoint", "step": step, "path": dir.display().to_string()}))
    }
}

/// `{group name: f(norms, group)}` for the groups that have a value; null without norms.
fn per_group(norms: Option<GradNorms>, f: fn(&GradNorms, GradGroup) -> Option<f64>) -> Value {
    norms.map_or(Value::Null, |g| {
        GradGroup::ALL
            .iter()
            .filter_map(|&k| Some((k.name().to_owned(), num(f(&g, k)?))))
            .collect::<serde_json::Map<_, _>>()
            .into()
    })
}
