//! Reading a training TOML: the `[model]` table (a `preset` plus field overrides) is laid
//! over the named `ModelConfig` preset, then everything is validated with messages naming
//! the key and the value.

use crate::config::*;
use crate::error::{Result, TrainError};
use envision4d_model::config::{MotionModel as ModelMotion, TemporalPlacement as ModelPlacement};
use envision4d_model::ModelConfig;
use std::path::Path;

mod rules;
pub use rules::validate;

/// Parses and validates a training config file.
pub fn load(path: &Path) -> Result<TrainConfig> {
    let text = std::fs::read_to_string(path).map_err(crate::error::read(path))?;
    parse(&text, path)
}

/// [`load`] with `KEY=VALUE` overrides written over the file first (`train --set`): a
/// dotted key names nested tables (`model.image_size=[280,518]`, `optim.batch_size=1`);
/// the value is TOML, and a bare word is taken as a string (`model.preset=tiny`).
pub fn load_with_overrides(path: &Path, sets: &[String]) -> Result<TrainConfig> {
    let text = std::fs::read_to_string(path).map_err(crate::error::read(path))?;
    if sets.is_empty() {
        // Parse the file as written, so errors point at its own lines.
        return parse(&text, path);
    }
    parse(&with_overrides(&text, sets, path)?, path)
}

/// `text` with `sets` laid over it (see [`load_with_overrides`]).
pub fn with_overrides(text: &str, sets: &[String], path: &Path) -> Result<String> {
    let err = |message: String| TrainError::Parse {
        path: path.to_path_buf(),
        message,
    };
    let mut doc: toml::Table = toml::from_str(text).map_err(|e| err(e.to_string()))?;
    for set in sets {
        let (key, value) = set
            .split_once('=')
            .ok_or_else(|| err(format!("--set {set:?}: expected KEY=VALUE")))?;
        let value = value.trim();
        let value = match toml::from_str::<toml::Table>(&format!("v = {value}")) {
            Ok(mut t) if t.len() == 1 => t
                .remove("v")
                .ok_or_else(|| err(format!("--set {set:?}: one value expected")))?,
            Ok(_) => return Err(err(format!("--set {set:?}: one value expected"))),
            Err(_) => toml::Value::String(value.to_owned()),
        };
        let mut over = value;
        for part in key.trim().rsplit('.') {
            if part.is_empty() {
                return Err(err(format!("--set {set:?}: empty key part")));
            }
            over = toml::Value::Table(toml::Table::from_iter([(part.to_owned(), over)]));
        }
        if let toml::Value::Table(t) = over {
            overlay(&mut doc, t);
        }
    }
    toml::to_string(&doc).map_err(|e| err(e.to_string()))
}

/// Parses and validates config text; `path` only labels errors.
pub fn parse(text: &str, path: &Path) -> Result<TrainConfig> {
    let parse_err = |message: String| TrainError::Parse {
        path: path.to_path_buf(),
        message,
    };
    let raw: RawTrainConfig = toml::from_str(text).map_err(|e| parse_err(e.to_string()))?;
    let model_sets = ModelSets {
        motion: raw.model.contains_key(MODEL_MOTION_KEY),
        temporal: raw.model.contains_key(MODEL_TEMPORAL_KEY),
    };
    let mut model = resolve_model(raw.model).map_err(parse_err)?;
    apply_ablation(&mut model, &raw.ablation, model_sets)?;
    let cfg = TrainConfig {
        stage: raw.stage,
        seed: raw.seed,
        teacher: raw.teacher,
        freeze: raw.freeze,
        init: raw.init,
        init_checkpoint: raw.init_checkpoint,
        init_fresh: raw.init_fresh,
        teacher_checkpoint: raw.teacher_checkpoint,
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

/// `[model]` keys of the two architecture ablations; `[ablation]` decides them.
const MODEL_MOTION_KEY: &str = "motion_model";
const MODEL_TEMPORAL_KEY: &str = "temporal_attention";

/// Which ablation keys the `[model]` table set itself (they must then agree).
#[derive(Debug, Clone, Copy)]
struct ModelSets {
    motion: bool,
    temporal: bool,
}

/// The model's architecture switches that `[ablation]` names.
fn ablation_switches(a: &AblationConfig) -> (ModelMotion, ModelPlacement) {
    let motion = match a.motion {
        MotionModel::Lifting => ModelMotion::Lifting,
        MotionModel::LinearVelocity => ModelMotion::LinearVelocity,
        MotionModel::Off => ModelMotion::Off,
    };
    let placement = match a.temporal_attention {
        TemporalAttention::InLayer => ModelPlacement::InLayer,
        TemporalAttention::PostLayer => ModelPlacement::PostLayer,
        TemporalAttention::None => ModelPlacement::None,
    };
    (motion, placement)
}

/// A value as the TOML file spells it (`"linear_velocity"`).
fn toml_name<T: serde::Serialize + std::fmt::Debug>(v: &T) -> String {
    toml::Value::try_from(v).map_or_else(|_| format!("{v:?}"), |t| t.to_string())
}

/// Sets the model's architecture switches from `[ablation]`, the one place a run names its
/// ablation. A `[model]` value that disagrees is an error naming both keys, rather than one
/// silently winning.
fn apply_ablation(model: &mut ModelConfig, a: &AblationConfig, sets: ModelSets) -> Result<()> {
    let (motion, placement) = ablation_switches(a);
    if sets.motion && model.motion_model != motion {
        return Err(TrainError::invalid(
            "model.motion_model",
            toml_name(&model.motion_model),
            format!(
                "disagrees with ablation.motion = {}; set only ablation.motion",
                toml_name(&a.motion)
            ),
        ));
    }
    if sets.temporal && model.temporal_attention != placement {
        return Err(TrainError::invalid(
            "model.temporal_attention",
            toml_name(&model.temporal_attention),
            format!(
                "disagrees with ablation.temporal_attention = {}; \
                 set only ablation.temporal_attention",
                toml_name(&a.temporal_attention)
            ),
        ));
    }
    model.motion_model = motion;
    model.temporal_attention = placement;
    Ok(())
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

impl TrainConfig {
    /// The resolved settings as TOML (for `--dry-run` and run directories).
    pub fn to_toml(&self) -> String {
        toml::to_string_pretty(self).unwrap_or_else(|e| format!("# cannot serialise: {e}"))
    }
}
