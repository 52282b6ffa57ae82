//! Reading a training TOML: the `[model]` table (a `preset` plus field overrides) is laid
//! over the named `ModelConfig` preset, then everything is validated with messages naming
//! the key and the value.

use crate::config::*;
use crate::error::{Result, TrainError};
use envision4d_model::ModelConfig;
use std::path::Path;

/// Parses and validates a training config file.
pub fn load(path: &Path) -> Result<TrainConfig> {
    let text = std::fs::read_to_string(path).map_err(|source| TrainError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    parse(&text, path)
}

/// Parses and validates config text; `path` only labels errors.
pub fn parse(text: &str, path: &Path) -> Result<TrainConfig> {
    let parse_err = |message: String| TrainError::Parse {
        path: path.to_path_buf(),
        message,
    };
    let raw: RawTrainConfig = toml::from_str(text).map_err(|e| parse_err(e.to_string()))?;
    let model = resolve_model(raw.model).map_err(parse_err)?;
    let cfg = TrainConfig {
        stage: raw.stage,
        seed: raw.seed,
        teacher: raw.teacher,
        freeze: raw.freeze,
        init_checkpoint: raw.init_checkpoint,
        model,
        optim: raw.optim,
        loss: raw.loss,
        progressive: raw.progressive,
        ablation: raw.ablation,
        data: raw.data,
        run: raw.run,
    };
    validate(&cfg)?;
    Ok(cfg)
}

/// `preset = "tiny" | "paper"` (default `paper`) plus overrides; unknown keys are rejected
/// by `ModelConfig`'s `deny_unknown_fields`.
fn resolve_model(mut table: toml::Table) -> std::result::Result<ModelConfig, String> {
    let base = match table.remove("preset") {
        Some(toml::Value::String(name)) => {
            ModelConfig::preset(&name).map_err(|e| format!("[model] preset: {e}"))?
        }
        Some(other) => return Err(format!("[model] preset must be a string, got {other}")),
        None => ModelConfig::paper(),
    };
    let mut merged = toml::Table::try_from(&base).map_err(|e| format!("[model]: {e}"))?;
    overlay(&mut merged, table);
    toml::Value::Table(merged)
        .try_into()
        .map_err(|e: toml::de::Error| format!("[model]: {e}"))
}

fn overlay(base: &mut toml::Table, over: toml::Table) {
    for (k, v) in over {
        match (base.get_mut(&k), v) {
            (Some(toml::Value::Table(b)), toml::Value::Table(o)) => overlay(b, o),
            (_, v) => {
                base.insert(k, v);
            }
        }
    }
}

fn positive(key: &'static str, v: f64) -> Result<()> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(TrainError::invalid(key, v, "must be finite and > 0"))
    }
}

fn non_negative(key: &'static str, v: f64) -> Result<()> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(TrainError::invalid(key, v, "must be finite and >= 0"))
    }
}

/// Every rule a resolved config must satisfy.
pub fn validate(cfg: &TrainConfig) -> Result<()> {
    cfg.model
        .validate()
        .map_err(|e| TrainError::invalid("model", "[model]", e.0))?;
    let o = &cfg.optim;
    positive("optim.lr", o.lr)?;
    non_negative("optim.min_lr", o.min_lr)?;
    if o.min_lr > o.lr {
        return Err(TrainError::invalid(
            "optim.min_lr",
            o.min_lr,
            format!("must not exceed optim.lr = {}", o.lr),
        ));
    }
    if o.batch_size == 0 {
        return Err(TrainError::invalid("optim.batch_size", 0, "must be >= 1"));
    }
    if o.iterations == 0 {
        return Err(TrainError::invalid("optim.iterations", 0, "must be >= 1"));
    }
    if o.grad_clip != ClipMode::None {
        positive("optim.grad_clip_threshold", o.grad_clip_threshold)?;
    }
    let l = &cfg.loss;
    non_negative("loss.lambda_lpips", l.lambda_lpips)?;
    non_negative("loss.lambda_cam", l.lambda_cam)?;
    non_negative("loss.lambda_depth", l.lambda_depth)?;
    if l.lambda_lpips > 0.0 && l.lpips_weights.is_none() {
        return Err(TrainError::invalid(
            "loss.lambda_lpips",
            l.lambda_lpips,
            "needs loss.lpips_weights (LPIPS-VGG safetensors); set lambda_lpips = 0 to train without LPIPS",
        ));
    }
    let p = &cfg.progressive;
    if p.s_max == 0 {
        return Err(TrainError::invalid("progressive.s_max", 0, "must be >= 1"));
    }
    non_negative("progressive.alpha0", p.alpha0)?;
    // The model crate implements only the paper's variants so far: refuse the others here
    // rather than silently training the wrong network.
    if cfg.ablation.motion != MotionModel::Lifting {
        return Err(TrainError::invalid(
            "ablation.motion",
            "\"linear_velocity\"",
            "not implemented by envision4d-model yet (only \"lifting\")",
        ));
    }
    if cfg.ablation.temporal_attention != TemporalAttention::InLayer {
        return Err(TrainError::invalid(
            "ablation.temporal_attention",
            "\"post_layer\"",
            "not implemented by envision4d-model yet (only \"in_layer\")",
        ));
    }
    if cfg.data.stride == 0 {
        return Err(TrainError::invalid("data.stride", 0, "must be >= 1"));
    }
    let r = &cfg.run;
    if r.log_every == 0 || r.checkpoint_every == 0 {
        return Err(TrainError::invalid(
            "run.log_every/run.checkpoint_every",
            format!("{}/{}", r.log_every, r.checkpoint_every),
            "must be >= 1",
        ));
    }
    Ok(())
}

impl TrainConfig {
    /// The resolved settings as TOML (for `--dry-run` and run directories).
    pub fn to_toml(&self) -> String {
        toml::to_string_pretty(self).unwrap_or_else(|e| format!("# cannot serialise: {e}"))
    }
}
