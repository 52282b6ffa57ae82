//! Reading a training TOML: the `[model]` table (a `preset` plus field overrides) is laid
//! over the named `ModelConfig` preset, then everything is validated with messages naming
//! the key and the value.

use crate::config::*;
use crate::error::{Result, TrainError};
use envision4d_model::config::{MotionModel as ModelMotion, TemporalPlacement as ModelPlacement};
use envision4d_model::ModelConfig;
use std::path::Path;

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

/// `init`: random weights at paper widths only when asked for; `init = "random"` with a
/// checkpoint to load is a contradiction.
fn validate_init(cfg: &TrainConfig) -> Result<()> {
    match cfg.init {
        Init::Random => {
            if let Some(p) = &cfg.init_checkpoint {
                return Err(TrainError::invalid(
                    "init",
                    "\"random\"",
                    format!(
                        "but init_checkpoint = {:?} is set; remove one of the two",
                        p.display()
                    ),
                ));
            }
        }
        Init::Checkpoint => {
            let paper = envision4d_model::ModelConfig::paper();
            if cfg.init_checkpoint.is_none() && cfg.model.embed_dim >= paper.embed_dim {
                return Err(TrainError::invalid(
                    "init_checkpoint",
                    "(none)",
                    format!(
                        "a model of paper widths (embed_dim {}) would start from random \
                         weights; give init_checkpoint (VGGT-1B's model.pt), or set \
                         init = \"random\" to do this on purpose (benchmarks)",
                        cfg.model.embed_dim
                    ),
                ));
            }
        }
    }
    Ok(())
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
    positive("optim.adam_epsilon", o.adam_epsilon)?;
    let l = &cfg.loss;
    non_negative("loss.lambda_lpips", l.lambda_lpips)?;
    non_negative("loss.lambda_cam", l.lambda_cam)?;
    non_negative("loss.lambda_depth", l.lambda_depth)?;
    non_negative("loss.rotation_weight", l.rotation_weight)?;
    non_negative("loss.lambda_ssim", l.lambda_ssim)?;
    non_negative("loss.dynamic_weight", l.dynamic_weight)?;
    non_negative("loss.lambda_flow", l.lambda_flow)?;
    if l.lambda_flow > 0.0 && cfg.model.motion_model == ModelMotion::Off {
        return Err(TrainError::invalid(
            "loss.lambda_flow",
            l.lambda_flow,
            "supervises the motion head, which [ablation] motion = \"off\" removes",
        ));
    }
    if l.flow_balanced && l.lambda_flow == 0.0 {
        return Err(TrainError::invalid(
            "loss.flow_balanced",
            true,
            "weighs the flow term, which is off (set loss.lambda_flow > 0)",
        ));
    }
    if (l.lambda_flow > 0.0 || l.dynamic_weight > 0.0) && cfg.stage != Stage::Envision4d {
        return Err(TrainError::invalid(
            if l.lambda_flow > 0.0 {
                "loss.lambda_flow"
            } else {
                "loss.dynamic_weight"
            },
            l.lambda_flow.max(l.dynamic_weight),
            "applies to stage = \"envision4d\" (the backbone stage renders nothing)",
        ));
    }
    if l.lambda_lpips > 0.0 && l.lpips_weights.is_none() && cfg.init != Init::Random {
        return Err(TrainError::invalid(
            "loss.lambda_lpips",
            l.lambda_lpips,
            "needs loss.lpips_weights (torchvision's vgg16 .pth and the lpips package's vgg.pth as \"A,B\", or one exported file); set lambda_lpips = 0 to train without LPIPS",
        ));
    }
    let p = &cfg.progressive;
    if p.s_max == 0 {
        return Err(TrainError::invalid("progressive.s_max", 0, "must be >= 1"));
    }
    non_negative("progressive.alpha0", p.alpha0)?;
    // A config edited after `parse` must still train the network its ablation names.
    let (motion, placement) = ablation_switches(&cfg.ablation);
    if (cfg.model.motion_model, cfg.model.temporal_attention) != (motion, placement) {
        return Err(TrainError::invalid(
            "ablation",
            format!(
                "motion = {}, temporal_attention = {}",
                toml_name(&cfg.ablation.motion),
                toml_name(&cfg.ablation.temporal_attention)
            ),
            format!(
                "the model is built with motion_model = {}, temporal_attention = {}",
                toml_name(&cfg.model.motion_model),
                toml_name(&cfg.model.temporal_attention)
            ),
        ));
    }
    validate_init(cfg)?;
    if cfg.teacher == Teacher::Backbone
        && cfg.stage == Stage::Envision4d
        && cfg.teacher_checkpoint.is_none()
        && cfg.init_checkpoint.is_none()
        && cfg.init != Init::Random
    {
        return Err(TrainError::invalid(
            "teacher",
            "\"backbone\"",
            "needs teacher_checkpoint (or init_checkpoint): the frozen backbone's weights",
        ));
    }
    if !cfg.init_fresh.is_empty() && cfg.init_checkpoint.is_none() {
        return Err(TrainError::invalid(
            "init_fresh",
            format!("{:?}", cfg.init_fresh),
            "keeps modules out of init_checkpoint, which is not set (without it everything is fresh)",
        ));
    }
    if cfg.data.stride == 0 {
        return Err(TrainError::invalid("data.stride", 0, "must be >= 1"));
    }
    if cfg.data.frame_step == 0 {
        return Err(TrainError::invalid("data.frame_step", 0, "must be >= 1"));
    }
    let a = &cfg.data.augment;
    for (key, v) in [
        ("data.augment.reverse", a.reverse),
        ("data.augment.hold", a.hold),
    ] {
        if !(0.0..=1.0).contains(&v) {
            return Err(TrainError::invalid(key, v, "must be a fraction in [0, 1]"));
        }
    }
    if a.reverse + a.hold > 1.0 {
        return Err(TrainError::invalid(
            "data.augment",
            format!("reverse = {}, hold = {}", a.reverse, a.hold),
            "the two fractions must add up to at most 1",
        ));
    }
    if cfg.stage == Stage::Backbone {
        // Stage 1 trains exactly VGGT's parts; freezing them would silently train nothing
        // (the paper's default freeze list is stage 2's).
        let vggt = [
            FreezeGroup::PatchEmbed,
            FreezeGroup::FrameBlocks,
            FreezeGroup::GlobalBlocks,
            FreezeGroup::Tokens,
            FreezeGroup::CameraHead,
            FreezeGroup::DepthHead,
        ];
        if let Some(g) = cfg.freeze.iter().find(|g| vggt.contains(g)) {
            return Err(TrainError::invalid(
                "freeze",
                format!("{g:?}"),
                "stage = \"backbone\" trains the VGGT part; list only groups it does not use (or freeze = [])",
            ));
        }
    }
    let r = &cfg.run;
    if r.max_nonfinite_steps == 0 {
        return Err(TrainError::invalid(
            "run.max_nonfinite_steps",
            0,
            "must be >= 1",
        ));
    }
    if r.keep_checkpoints == 0 {
        return Err(TrainError::invalid(
            "run.keep_checkpoints",
            0,
            "must be >= 1",
        ));
    }
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
