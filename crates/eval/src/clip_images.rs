//! The pictures behind one clip's numbers, kept when [`crate::EvalOptions::clip_images`]
//! asks (the HTML report shows them): per future frame, the ground truth, the model's
//! frame, the two image baselines' frames, the model's rendered depth and the true dynamic
//! mask. Host copies, so a caller can keep a few clips' worth after the device is reused.

use crate::error::Result;
use crate::report::Method;
use burn::tensor::Tensor;
use envision4d_losses::{HostDepths, HostImages};

/// Images of one clip's future frames (all `[T_f, 3, H, W]` in `[0, 1]`-ish linear RGB).
#[derive(Debug, Clone, PartialEq)]
pub struct ClipImages {
    /// `T_c`: future frame `k` is clip frame `context + k`, horizon `k + 1`.
    pub context: usize,
    pub ground_truth: HostImages,
    /// The model first, then copy-last and static+cv.
    pub methods: Vec<(Method, HostImages)>,
    /// The model's rendered depth `[T_f, H, W]` (scene units).
    pub depth: HostDepths,
    /// The true dynamic mask of each future frame (`None` where the clip has none).
    pub dynamic_masks: Vec<Option<Vec<bool>>>,
}

impl ClipImages {
    /// `frames`: the model's, copy-last's and static+cv's future frames, in that order;
    /// `depth` the model's rendered depth `[T_f, H, W]` on the device.
    pub fn new(
        context: usize,
        ground_truth: &HostImages,
        frames: [HostImages; 3],
        depth: &Tensor<3>,
        dynamic_masks: Vec<Option<Vec<bool>>>,
    ) -> Result<Self> {
        let [model, copy, cv] = frames;
        Ok(ClipImages {
            context,
            ground_truth: ground_truth.clone(),
            methods: vec![
                (Method::Model, model),
                (Method::CopyLast, copy),
                (Method::StaticCv, cv),
            ],
            depth: HostDepths::from_tensor("rendered depth", depth.clone())?,
            dynamic_masks,
        })
    }

    /// Number of future frames.
    pub fn frames(&self) -> usize {
        self.ground_truth.shape()[0]
    }

    /// `(H, W)`.
    pub fn size(&self) -> (usize, usize) {
        let s = self.ground_truth.shape();
        (s[2], s[3])
    }
}
