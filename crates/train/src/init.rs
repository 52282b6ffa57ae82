//! How a training run's model starts: from a checkpoint (VGGT-1B or stage 1), or from
//! scratch with a camera head that predicts sane first poses.

use crate::config::{FreshGroup, Stage, TrainConfig};
use crate::error::{Result, TrainError};
use burn::tensor::Device;
use envision4d_model::aggregator::Aggregator;
use envision4d_model::checkpoint::CheckpointKind;
use envision4d_model::config::{MotionModel, TemporalPlacement};
use envision4d_model::Envision4d;
use std::path::Path;

/// Field of view (radians, both axes) a from-scratch camera head starts at (~57°).
pub const INITIAL_FOV_RAD: f32 = 1.0;
/// Scale of the camera head's last layer at a from-scratch start: small, so the first poses
/// are close to the identity but gradients still reach the whole head.
pub const POSE_OUTPUT_INIT_SCALE: f64 = 1e-3;

/// Starts a freshly initialised camera head at the identity pose with a plausible FoV.
///
/// With random weights the head predicts random poses: the Gaussians then land behind or
/// beside every camera, the renders are blank and no gradient reaches anything (and a ReLU'd
/// FoV of 0 is an infinite focal length). The head sums its 4 refinement deltas, so the last
/// layer's bias is a quarter of `[t = 0, q = (0, 0, 0, 1), fov_h, fov_w]` and its weight is
/// shrunk (as AdaLN-zero-style output layers are).
pub fn identity_pose_init(model: &mut Envision4d) {
    model
        .camera_head
        .init_identity_pose(INITIAL_FOV_RAD, POSE_OUTPUT_INIT_SCALE);
}

/// The model of a config, from `init_checkpoint` when given.
pub fn build_model(config: &TrainConfig, device: &Device) -> Result<Envision4d> {
    let mut model = Envision4d::new(&config.model, device);
    // Only a from-scratch *rendering* run needs sane first poses; the backbone stage regresses
    // poses directly and learns them better from the plain init (the shrunk output layer
    // left its first run predicting one mean pose for every non-first frame).
    if config.init_checkpoint.is_none() && config.stage == Stage::Envision4d {
        identity_pose_init(&mut model);
    }
    if let Some(path) = &config.init_checkpoint {
        model = init_from(model, config, path, device)?;
    }
    Ok(model)
}

/// Loads `path` (VGGT-1B or one of our checkpoints; the VGGT part must be present, new
/// modules keep their init) into the paper variant of the model, then carries it over to
/// the configured ablation variant: the post-layer placement keeps every weight (same
/// shapes, other wiring), linear velocity keeps its own fresh motion head (6 output
/// channels where the checkpoint has the 3 of conditioned motion lifting). Groups in
/// `init_fresh` keep the fresh init of `model` whatever the variant.
fn init_from(
    model: Envision4d,
    config: &TrainConfig,
    path: &Path,
    device: &Device,
) -> Result<Envision4d> {
    let mut paper = config.model.clone();
    paper.motion_model = MotionModel::default();
    paper.temporal_attention = TemporalPlacement::default();
    let mut base = Envision4d::new(&paper, device);
    envision4d_model::checkpoint::load_checkpoint(&mut base, path, CheckpointKind::Vggt1bInit)
        .map_err(|e| TrainError::checkpoint(path, format!("init_checkpoint: {e}")))?;
    let fresh = |g| config.init_fresh.contains(&g);
    if paper == config.model && config.init_fresh.is_empty() {
        return Ok(base);
    }
    let motion_head =
        if config.model.motion_model == paper.motion_model && !fresh(FreshGroup::MotionHead) {
            base.motion_head
        } else {
            model.motion_head
        };
    // Without temporal attention the variant has no temporal blocks: keep its (empty) list.
    let time_blocks =
        if model.aggregator.placement == TemporalPlacement::None || fresh(FreshGroup::TimeBlocks) {
            model.aggregator.time_blocks
        } else {
            base.aggregator.time_blocks
        };
    Ok(Envision4d {
        aggregator: Aggregator {
            placement: model.aggregator.placement,
            time_blocks,
            ..base.aggregator
        },
        motion_head,
        ..base
    })
}
