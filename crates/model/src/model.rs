//! The Envision4D network (the release's `VGGT` module inside `EncoderEnvi4D`): aggregator with
//! temporal blocks → future-pose module → camera head (→ poses), plus the DPT heads.

use crate::aggregator::{Aggregator, AggregatorOutput};
use crate::camera_head::CameraHead;
use crate::config::ModelConfig;
use crate::future::{FuturePose, FutureTokens};
use crate::pose::pose_encoding_to_extri_intri;
use burn::module::Module;
use burn::tensor::{Device, Tensor};

#[derive(Module, Debug)]
pub struct Envision4d {
    pub aggregator: Aggregator,
    pub camera_head: CameraHead,
    /// `extra_token_offset`, `extra_blocks`, `time_embedding` of the release.
    pub future: FuturePose,
}

/// Backbone outputs: tokens for the heads and the predicted cameras.
#[derive(Debug, Clone)]
pub struct BackboneOutput {
    pub aggregator: AggregatorOutput,
    pub tokens: FutureTokens,
    /// `[B, N, 9]` after each camera-head iteration; the last is the prediction.
    pub pose_enc_iters: Vec<Tensor<3>>,
    /// `[B, N, 4, 4]` world-to-camera (the first context camera is the world).
    pub extrinsics: Tensor<4>,
    /// `[B, N, 3, 3]` pixel intrinsics.
    pub intrinsics: Tensor<4>,
}

impl BackboneOutput {
    pub fn pose_enc(&self) -> Tensor<3> {
        self.pose_enc_iters.last().expect("camera head ran").clone()
    }
}

impl Envision4d {
    pub fn new(cfg: &ModelConfig, device: &Device) -> Self {
        Envision4d {
            aggregator: Aggregator::new(cfg, device),
            camera_head: CameraHead::new(2 * cfg.embed_dim, cfg.camera_heads, device),
            future: FuturePose::new(cfg, device),
        }
    }

    /// `images: [B, T_c, 3, H, W]` in [0, 1] → tokens and cameras of all `T_c + T_f` frames.
    pub fn backbone(&self, images: Tensor<5>, taps: &[usize]) -> BackboneOutput {
        let [_, _, _, h, w] = images.dims();
        let last = self.aggregator.frame_blocks.len() - 1;
        let mut keep = taps.to_vec();
        keep.push(last);
        let agg = self.aggregator.forward(images, &keep);
        let top = agg.layer(last);
        let [b, s, _, c2] = top.dims();
        let camera_tokens = top.slice([0..b, 0..s, 0..1, 0..c2]).reshape([b, s, c2]);
        let tokens = self.future.forward(camera_tokens);
        let pose_enc_iters = self.camera_head.forward(tokens.camera.clone());
        let (extrinsics, intrinsics) = pose_encoding_to_extri_intri(pose_enc_iters.last().unwrap().clone(), h, w);
        BackboneOutput { aggregator: agg, tokens, pose_enc_iters, extrinsics, intrinsics }
    }
}
