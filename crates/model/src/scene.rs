//! The scene path, the one way from context frames to rendered views that training,
//! validation, evaluation, `render` and `demo` all take (paper §3.1-§3.4):
//!
//! 1. [`predict_scene`]: the network on the context frames (every head), its cameras rebuilt
//!    from a FoV-clamped pose encoding (so an untrained head still renders), and the
//!    Gaussians lifted to world space with their motion to every timestamp.
//! 2. [`gaussians_for`]: the Gaussians as seen at time `j`, either self-exclusive
//!    (every frame from the *other* frames' Gaussians, paper §3.4) or, for the geometric
//!    warm-up, including the target's own.
//! 3. [`Scene::render`] / [`Scene::render_batch`] / [`render_targets`]: those Gaussians
//!    through the predicted cameras with the rasterizer of `envision4d-splat`, every view of
//!    a call in one rasterizer call ([`render_pairs`]).

use crate::adapter::{gaussians_at, AdaptedGaussians, Exclusion, OpacityMapping};
use crate::host_read;
use crate::model::{Envision4d, Heads, Predictions};
use crate::motion::still_displacements;
use crate::pose::{pose_encoding_to_extri_intri, FOV};
use burn::tensor::Tensor;
use envision4d_splat::{render_each, Cameras, Gaussians, RasterConfig, RenderError};

/// Smallest FoV (radians, ~3°) a predicted camera may have.
pub const FOV_MIN_RAD: f64 = 0.05;
/// Largest FoV (radians, ~172°), wider than any real camera.
pub const FOV_MAX_RAD: f64 = 3.0;

/// Why a scene could not be predicted or rendered.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// A prediction the scene needs is NaN or infinite (an untrained or diverging model):
    /// training's NaN guard skips the step rather than ending the run.
    #[error("non-finite {0}")]
    NonFinite(&'static str),
    /// The model was built without a head the scene needs.
    #[error("the scene needs the depth, Gaussian and motion heads")]
    MissingHeads,
    #[error("render: {0}")]
    Render(#[from] RenderError),
}

pub type Result<T> = std::result::Result<T, SceneError>;

/// A predicted scene: the raw predictions (poses of all `N` frames, depth, ...) and the
/// world-space Gaussians with their motion to every timestamp.
#[derive(Debug, Clone)]
pub struct Scene {
    pub pred: Predictions,
    pub adapted: AdaptedGaussians,
}

/// Clamps the FoV channels of pose encodings `[B, N, 9]` to
/// [`FOV_MIN_RAD`, `FOV_MAX_RAD`] (the gradient passes inside the range).
///
/// The camera head's FoV activation is a ReLU, so an untrained or diverging head can
/// predict FoV 0 (an infinite focal length) that the renderer rightly refuses.
pub fn clamp_fov(pose: Tensor<3>) -> Tensor<3> {
    let [b, n, _] = pose.dims();
    let fov = pose
        .clone()
        .slice([0..b, 0..n, FOV])
        .clamp(FOV_MIN_RAD, FOV_MAX_RAD);
    pose.slice_assign([0..b, 0..n, FOV], fov)
}

/// `Σ x·0` of `t` on the device (`[1]`): 0 when every entry is finite, NaN when one is NaN
/// or infinite (`x·0` is NaN for those and exactly 0 otherwise, and no magnitude overflows
/// the total). Two or three kernels, where counting through `is_finite` takes four or five.
fn non_finite<const D: usize>(t: &Tensor<D>) -> Tensor<1> {
    t.clone().detach().mul_scalar(0.0).sum()
}

/// Forward on `context [B, T_c, 3, H, W]` with every head, cameras rebuilt from the
/// FoV-clamped pose encoding, then lifted to world space.
pub fn predict_scene(model: &Envision4d, context: Tensor<5>) -> Result<Scene> {
    predict_scene_with(model, context, Motion::Predicted)
}

/// Whether a scene's Gaussians move.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Motion {
    /// The motion head's displacements.
    Predicted,
    /// None: the motion head is not run and every displacement is zero (training's static
    /// warm-up renders nothing that moves, so the head's forward would be thrown away).
    Still,
}

/// [`predict_scene`] with the motion head run or skipped; `Motion::Still` equals
/// `predict_scene(..).without_motion()` without the head's cost.
pub fn predict_scene_with(model: &Envision4d, context: Tensor<5>, motion: Motion) -> Result<Scene> {
    let [b, tc, _, h, w] = context.dims();
    let device = context.device();
    let heads = Heads {
        motion: motion == Motion::Predicted,
        ..Heads::ALL
    };
    let mut pred = model.forward(context, heads);
    if motion == Motion::Still {
        let n = pred.backbone.extrinsics.dims()[1];
        pred.motion_enc = Some(still_displacements(b, tc, n, [h, w], &device));
    }
    let pose = pred.backbone.pose_enc();
    let (extr, intr) = renderable_cameras(pose.clone(), h, w);
    // One host read for both checks. A finite encoding can still decode to NaN cameras (a
    // zero quaternion).
    let bad = host_read::read_all(vec![
        non_finite(&pose),
        non_finite(&extr) + non_finite(&intr),
    ]);
    if bad[0] != 0.0 {
        return Err(SceneError::NonFinite("pose encoding"));
    }
    if bad[1] != 0.0 {
        return Err(SceneError::NonFinite("camera"));
    }
    pred.backbone.extrinsics = extr;
    pred.backbone.intrinsics = intr;
    // The release's opacity schedule is the identity for every shipped config, so the
    // scene path uses it at its default.
    let adapted = model
        .adapt(&pred, OpacityMapping::default(), 0)
        .ok_or(SceneError::MissingHeads)?;
    Ok(Scene { pred, adapted })
}

/// Cameras `(extrinsics [B, N, 4, 4], intrinsics [B, N, 3, 3])` of pose encodings for an
/// `h x w` image, with the FoV clamped so they always render.
pub fn renderable_cameras(pose: Tensor<3>, h: usize, w: usize) -> (Tensor<4>, Tensor<4>) {
    pose_encoding_to_extri_intri(clamp_fov(pose), h, w)
}

/// Backbone and camera head only (no dense head: what a poses-only command needs), with the
/// cameras rebuilt as [`predict_scene`] rebuilds them, so both give the same poses.
pub fn predict_cameras(model: &Envision4d, context: Tensor<5>) -> Predictions {
    let [_, _, _, h, w] = context.dims();
    let mut pred = model.forward(context, Heads::NONE);
    let (extr, intr) = renderable_cameras(pred.backbone.pose_enc(), h, w);
    pred.backbone.extrinsics = extr;
    pred.backbone.intrinsics = intr;
    pred
}

impl Scene {
    /// The same scene with every displacement zeroed (the "motion disabled" baseline, the
    /// static geometric warm-up: Gaussians stay where their frame put them).
    pub fn without_motion(&self) -> Scene {
        let mut s = self.clone();
        s.adapted.motions = s.adapted.motions.zeros_like();
        s
    }

    /// Renders frames `targets` of batch element `b` through the scene's own (predicted)
    /// cameras at `size = [H, W]`; returns `[F, 3, H, W]`.
    pub fn render(
        &self,
        b: usize,
        targets: &[usize],
        exclusion: Exclusion,
        size: [usize; 2],
        raster: &RasterConfig,
    ) -> Result<Tensor<4>> {
        let pairs: Vec<(usize, usize)> = targets.iter().map(|&j| (b, j)).collect();
        self.render_pairs(&pairs, exclusion, size, raster)
    }

    /// Renders frames `targets` of every batch element in one rasterizer call; returns
    /// `[B * F, 3, H, W]`, batch-major (element b's frames at rows `b * F .. (b + 1) * F`).
    pub fn render_batch(
        &self,
        targets: &[usize],
        exclusion: Exclusion,
        size: [usize; 2],
        raster: &RasterConfig,
    ) -> Result<Tensor<4>> {
        let bsz = self.pred.backbone.extrinsics.dims()[0];
        let pairs: Vec<(usize, usize)> = (0..bsz)
            .flat_map(|b| targets.iter().map(move |&j| (b, j)))
            .collect();
        self.render_pairs(&pairs, exclusion, size, raster)
    }

    /// [`render_pairs`] through the scene's own cameras; colour only.
    fn render_pairs(
        &self,
        pairs: &[(usize, usize)],
        exclusion: Exclusion,
        size: [usize; 2],
        raster: &RasterConfig,
    ) -> Result<Tensor<4>> {
        let bb = &self.pred.backbone;
        render_pairs(
            &self.adapted,
            &bb.extrinsics,
            &bb.intrinsics,
            pairs,
            exclusion,
            size,
            raster,
        )
        .map(|v| v.rgb)
    }
}

/// The Gaussians of batch element `b` at timestamp `j` as the rasterizer takes them.
pub fn gaussians_for(a: &AdaptedGaussians, b: usize, j: usize, exclusion: Exclusion) -> Gaussians {
    let (means, quats, scales, opacities, colors) = gaussians_at(a, b, j, exclusion);
    Gaussians {
        means,
        quats,
        scales,
        opacities,
        colors,
    }
}

/// Rendered colour `[F, 3, H, W]` and expected depth `[F, H, W]` of target frames.
#[derive(Debug, Clone)]
pub struct RenderedViews {
    pub rgb: Tensor<4>,
    pub depth: Tensor<3>,
}

/// Renders target frames `targets` of batch element `b` (each from the Gaussians at that
/// time under `exclusion`) with cameras `extrinsics [B, N, 4, 4]` / `intrinsics
/// [B, N, 3, 3]`; returns `[F, 3, H, W]`.
#[allow(clippy::too_many_arguments)]
pub fn render_targets(
    adapted: &AdaptedGaussians,
    extrinsics: &Tensor<4>,
    intrinsics: &Tensor<4>,
    b: usize,
    targets: &[usize],
    exclusion: Exclusion,
    size: [usize; 2],
    raster: &RasterConfig,
) -> Result<Tensor<4>> {
    render_views(
        adapted, extrinsics, intrinsics, b, targets, exclusion, size, raster,
    )
    .map(|v| v.rgb)
}

/// [`render_targets`] with the expected depth as well (the rasterizer computes it anyway).
#[allow(clippy::too_many_arguments)]
pub fn render_views(
    adapted: &AdaptedGaussians,
    extrinsics: &Tensor<4>,
    intrinsics: &Tensor<4>,
    b: usize,
    targets: &[usize],
    exclusion: Exclusion,
    size: [usize; 2],
    raster: &RasterConfig,
) -> Result<RenderedViews> {
    let pairs: Vec<(usize, usize)> = targets.iter().map(|&j| (b, j)).collect();
    render_pairs(
        adapted, extrinsics, intrinsics, &pairs, exclusion, size, raster,
    )
}

/// Renders view `(b, j)` of `pairs` (batch element b's Gaussians at time j, through its
/// camera j) for every pair, all in one rasterizer call: each view has its own Gaussians
/// (`render_each`), so the device is read back once for all of them, not once per view.
/// Returns `[V, 3, H, W]` colour and `[V, H, W]` depth in `pairs` order.
#[allow(clippy::too_many_arguments)]
pub fn render_pairs(
    adapted: &AdaptedGaussians,
    extrinsics: &Tensor<4>,
    intrinsics: &Tensor<4>,
    pairs: &[(usize, usize)],
    exclusion: Exclusion,
    size: [usize; 2],
    raster: &RasterConfig,
) -> Result<RenderedViews> {
    let v = pairs.len();
    let sets: Vec<Gaussians> = pairs
        .iter()
        .map(|&(b, j)| gaussians_for(adapted, b, j, exclusion))
        .collect();
    let pick = |t: &Tensor<4>, k: usize| {
        Tensor::cat(
            pairs
                .iter()
                .map(|&(b, j)| {
                    t.clone()
                        .slice([b..b + 1, j..j + 1, 0..k, 0..k])
                        .reshape([1, k, k])
                })
                .collect(),
            0,
        )
    };
    let cams = Cameras {
        viewmats: pick(extrinsics, 4),
        ks: pick(intrinsics, 3),
        width: size[1] as u32,
        height: size[0] as u32,
    };
    let out = render_each(&sets, &cams, raster)?;
    debug_assert_eq!(out.rgb.dims()[0], v);
    Ok(RenderedViews {
        rgb: out.rgb.permute([0, 3, 1, 2]),
        depth: out.depth,
    })
}

#[cfg(test)]
mod tests {
    use burn::tensor::{Device, Tensor, TensorData};

    fn check(values: Vec<f32>, device: &Device) -> f32 {
        let n = values.len();
        let t = Tensor::<1>::from_data(TensorData::new(values, [n]), device);
        super::non_finite(&t).into_scalar::<f32>()
    }

    /// Guards the scene's camera check: any NaN or infinity is caught (a NaN total), and no
    /// finite value is mistaken for one, the largest and negative zero included; on the CPU
    /// and on wgpu (lavapipe in CI), whose sums must carry the NaN through.
    #[test]
    fn non_finite_flags_nan_and_infinities_only() {
        let gpu = envision4d_splat::testkit::wgpu_test_device();
        for device in std::iter::once(Device::flex()).chain(gpu) {
            assert_eq!(
                check(vec![1.0, f32::MAX, -f32::MAX, -0.0, 1e-45], &device),
                0.0
            );
            assert_eq!(check(vec![f32::MAX; 4096], &device), 0.0);
            for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
                let total = check(vec![0.5, bad, 2.0], &device);
                assert!(total.is_nan(), "{bad} missed on {device:?}");
            }
        }
    }
}
