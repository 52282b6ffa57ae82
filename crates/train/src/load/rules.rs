//! The rules a resolved training config must satisfy, each failure an error naming the
//! key and the value (and, where two keys conflict, both).

use super::{ablation_switches, toml_name};
use crate::config::*;
use crate::error::{Result, TrainError};
use envision4d_model::config::MotionModel as ModelMotion;

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
