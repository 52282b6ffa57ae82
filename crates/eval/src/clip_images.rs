//! The pictures behind one clip's numbers, kept when [`crate::EvalOptions::clip_images`]
//! asks (the HTML report shows them): per future frame, the ground truth, the model's
//! frame, the two image baselines' frames, the model's rendered depth and the true dynamic
//! mask. Host copies, so a caller can keep a few clips' worth after the device is reused.

use crate::error::{EvalError, Result};
use crate::report::Method;
use burn::tensor::Tensor;
use envision4d_losses::HostImages;

/// Images of one clip's future frames (all `[T_f, 3, H, W]` in `[0, 1]`-ish linear RGB).
#[derive(Debug, Clone, PartialEq)]
pub struct ClipImages {
    /// `T_c`: future frame `k` is clip frame `context + k`, horizon `k + 1`.
    pub context: usize,
    pub ground_truth: HostImages,
    /// The model first, then copy-last and static+cv.
    pub methods: Vec<(Method, HostImages)>,
    /// The model's rendered depth, `T_f * H * W` row-major (scene units; may hold
    /// non-finite values where nothing was rendered: a picture, not a score).
    pub depth: Vec<f32>,
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
            depth: depth
                .clone()
                .into_data()
                .convert::<f32>()
                .try_into_vec::<f32>()
                .map_err(|e| EvalError::Device(format!("reading the rendered depth: {e:?}")))?,
            dynamic_masks,
        })
    }

    /// Number of future frames.
    pub fn frames(&self) -> usize {
        self.ground_truth.shape()[0]
    }

    /// Depth map of future frame `k`.
    pub fn depth_map(&self, k: usize) -> &[f32] {
        let (h, w) = self.size();
        &self.depth[k * h * w..(k + 1) * h * w]
    }

    /// `(H, W)`.
    pub fn size(&self) -> (usize, usize) {
        let s = self.ground_truth.shape();
        (s[2], s[3])
    }
}
