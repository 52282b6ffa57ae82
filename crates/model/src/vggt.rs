//! Plain VGGT: the parts of Envision4D that the backbone stage trains and the distillation
//! teacher runs (paper §3.4, "a frozen VGGT backbone"): the aggregator without its temporal
//! blocks, the camera head on every frame's own camera token (no future-pose module) and the
//! depth head. Held on its own, it keeps none of the other heads' weights alive: the
//! teacher snapshot of a training run shares its tensors with the initial model, and after
//! the first update every trainable parameter it held would otherwise exist twice.

use crate::aggregator::{Aggregator, Temporal};
use crate::camera_head::CameraHead;
use crate::dpt::{depth_activation, DptHead};
use crate::model::Envision4d;
use burn::module::Module;
use burn::tensor::Tensor;

/// Plain VGGT (see the module docs).
#[derive(Module, Debug)]
pub struct Vggt {
    pub aggregator: Aggregator,
    pub camera_head: CameraHead,
    pub depth_head: DptHead,
    pub temporal_layers: [usize; 4],
    pub dpt_frame_chunk: usize,
}

/// Whether [`Vggt::forward`] runs the depth head.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum VggtDepth {
    Run,
    Skip,
}

/// Outputs of [`Vggt::forward`].
#[derive(Debug, Clone)]
pub struct VggtOutput {
    /// `[B, S, 9]` after each camera-head iteration; the last is the prediction.
    pub pose_enc_iters: Vec<Tensor<3>>,
    /// `([B, S, H, W, 1]` depth, `[B, S, H, W]` confidence`)`.
    pub depth: Option<(Tensor<5>, Tensor<4>)>,
}

impl VggtOutput {
    pub fn pose_enc(&self) -> Tensor<3> {
        self.pose_enc_iters.last().expect("camera head ran").clone()
    }
}

impl Vggt {
    /// The VGGT parts of `model`, sharing its tensors (the temporal blocks are dropped: plain
    /// VGGT never runs them).
    pub fn of(model: &Envision4d) -> Self {
        let mut aggregator = model.aggregator.clone();
        aggregator.time_blocks = Vec::new();
        Vggt {
            aggregator,
            camera_head: model.camera_head.clone(),
            depth_head: model.depth_head.clone(),
            temporal_layers: model.temporal_layers,
            dpt_frame_chunk: model.dpt_frame_chunk,
        }
    }

    /// Plain VGGT on `images [B, S, 3, H, W]`; the depth head only when `depth` is
    /// [`VggtDepth::Run`].
    pub fn forward(&self, images: Tensor<5>, depth: VggtDepth) -> VggtOutput {
        let [_, _, _, h, w] = images.dims();
        let last = self.aggregator.frame_blocks.len() - 1;
        let mut keep = self.temporal_layers.to_vec();
        keep.push(last);
        let agg = self.aggregator.forward_with(images, &keep, Temporal::Skip);
        let top = agg.layer(last);
        let [b, s, _, c2] = top.dims();
        let camera_tokens = top.slice([0..b, 0..s, 0..1, 0..c2]).reshape([b, s, c2]);
        let pose_enc_iters = self.camera_head.forward(camera_tokens);
        let depth = match depth {
            VggtDepth::Run => {
                let taps: [Tensor<4>; 4] = self.temporal_layers.map(|l| agg.layer(l));
                Some(run_depth_head(
                    &self.depth_head,
                    &taps,
                    agg.patch_start,
                    [h, w],
                    self.dpt_frame_chunk,
                ))
            }
            VggtDepth::Skip => None,
        };
        VggtOutput {
            pose_enc_iters,
            depth,
        }
    }
}

/// A depth head on the DPT taps, `chunk` frames per pass (0 = automatic):
/// `([B, S, H, W, 1]` depth, `[B, S, H, W]` confidence`)`.
pub(crate) fn run_depth_head(
    head: &DptHead,
    taps: &[Tensor<4>; 4],
    patch_start: usize,
    size: [usize; 2],
    chunk: usize,
) -> (Tensor<5>, Tensor<4>) {
    depth_activation(head.forward_chunked(taps, patch_start, size, None, chunk))
}
