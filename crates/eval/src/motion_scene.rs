//! The protocol's motion step: the scene's Gaussian means and displacements read back to the
//! host and scored against the clip's exact scene flow (`motion`, `motion_maps`), and the
//! exact displacements in the model's own units for the oracle-motion render.

use crate::error::Result;
use crate::motion::{score_aligned, Aligned, MotionScore, MotionTruth, PredictedMotion};
use crate::motion_maps::{pair_maps, PairMaps};
use crate::pose_error::{clip_intrinsics_tensor, extrinsics_tensor};
use crate::protocol::timed_render;
use crate::report::Method;
use crate::EvalOptions;
use burn::tensor::{Tensor, TensorData};
use envision4d_data::geom::Mat4;
use envision4d_data::HostClip;
use envision4d_losses::HostImages;
use envision4d_model::adapter::Exclusion;
use envision4d_model::scene::Scene;

/// What the motion truth of one clip gives the protocol.
#[derive(Default)]
pub(crate) struct MotionTruthOut {
    pub score: Option<MotionScore>,
    pub maps: Option<PairMaps>,
    pub oracle: Option<OracleInputs>,
}

/// What the oracle renders need from the truth, in the model's frame and unit.
pub(crate) struct OracleInputs {
    /// `[T_c, N−1, G, 3]` exact displacements ([`oracle_motions`]).
    pub motions: Vec<f32>,
    /// The true world-to-camera of all `N` frames ([`true_cameras`]).
    pub cameras: Vec<Mat4>,
}

/// The predicted displacements against the clip's exact scene flow, the per-pixel maps when
/// asked for, and the oracle's displacements; all `None` when the clip has no motion truth
/// (nothing is read back then).
pub(crate) fn motion_truth_score(
    scene: &Scene,
    clip: &HostClip,
    tc: usize,
    n: usize,
    input: [usize; 2],
    pred_poses: &[Mat4],
    opts: &EvalOptions,
) -> MotionTruthOut {
    if clip.motion_truth.len() < n {
        return MotionTruthOut::default();
    }
    let a = &scene.adapted;
    let [_, _, g, _] = a.means.dims();
    let [_, _, k, _, _] = a.motions.dims();
    let means: Vec<f32> = a
        .means
        .clone()
        .slice([0..1, 0..tc, 0..g, 0..3])
        .into_data()
        .iter::<f32>()
        .collect();
    let motions: Vec<f32> = a
        .motions
        .clone()
        .slice([0..1, 0..tc, 0..k, 0..g, 0..3])
        .into_data()
        .iter::<f32>()
        .collect();
    let pred = PredictedMotion {
        context: tc,
        frames: n,
        grid: (input[0], input[1]),
        means: &means,
        motions: &motions,
        extrinsics: pred_poses,
    };
    let truth = MotionTruth {
        size: (clip.height, clip.width),
        frames: &clip.motion_truth,
        masks: &clip.dynamic_masks,
    };
    // One alignment (scale, axes, grid) serves the score, the maps and the oracle.
    let Some(aligned) = Aligned::new(&pred, &truth) else {
        return MotionTruthOut::default();
    };
    MotionTruthOut {
        score: Some(score_aligned(&aligned, truth.masks)),
        maps: opts.motion_maps.then(|| pair_maps(&aligned)),
        oracle: Some(OracleInputs {
            motions: oracle_motions(&aligned),
            cameras: true_cameras(&aligned),
        }),
    }
}

/// The exact displacement of every context Gaussian to every other timestamp, in the
/// prediction's world axes and unit, laid out as one batch element of
/// `AdaptedGaussians::motions` (`[T_c, N−1, G, 3]`, targets ascending without the source):
/// each Gaussian moves as the true surface seen at its pixel does, zero where the pixel sees
/// no surface (sky). Rendering the model's Gaussians with these isolates what motion alone
/// can still gain on this reconstruction: depth, colour and pose errors stay the model's.
pub(crate) fn oracle_motions(a: &Aligned) -> Vec<f32> {
    let (tc, n, g) = (a.pred.context, a.pred.frames, a.pixels());
    let back = a.to_model_axes();
    let mut out = Vec::with_capacity(tc * (n - 1) * g * 3);
    for i in 0..tc {
        for j in (0..n).filter(|&j| j != i) {
            for d in a.truth(i, j) {
                let m = d.map_or(glam::DVec3::ZERO, |d| back * d);
                out.extend([m.x as f32, m.y as f32, m.z as f32]);
            }
        }
    }
    out
}

/// The true cameras of all `N` frames expressed in the prediction's world and unit, so the
/// model's Gaussians can be rendered where the real camera stood: the true frame-0 camera is
/// taken to be the predicted frame-0 camera (a pose-free model's origin), the true relative
/// motion `Q_j = W_j·W_0⁻¹` is applied after it, and its translation is divided by the clip's
/// scale (metres per model unit): `E_j = [R_Q·R_0 | R_Q·t_0 + t_Q/s]`. Pixels project as
/// with the metric cameras, since camera coordinates only shrink by `s`.
pub(crate) fn true_cameras(a: &Aligned) -> Vec<Mat4> {
    let e0 = a.pred.extrinsics[0].to_glam();
    let w0_inv = a.frames[0].world_to_camera.rigid_inverse().to_glam();
    a.frames
        .iter()
        .map(|f| {
            let q = f.world_to_camera.to_glam() * w0_inv;
            let rq = glam::DMat3::from_mat4(q);
            let t = rq * e0.w_axis.truncate() + q.w_axis.truncate() / a.scale;
            let r = rq * glam::DMat3::from_mat4(e0);
            Mat4::from_glam(glam::DMat4::from_mat3_translation(r, t))
        })
        .collect()
}

/// One oracle render: its method, frames, the cameras it was rendered at, and seconds.
pub(crate) struct OracleRender {
    pub method: Method,
    pub images: HostImages,
    pub poses: Vec<Mat4>,
    pub secs: f64,
}

/// The oracle renders of one clip (`EVAL.md`, "Baselines"): the model's Gaussians with the
/// exact displacements at its own cameras, and with no, its own and the exact displacements
/// at the true cameras (true intrinsics too). Together with `model` and `no_motion` they
/// split the future-frame error into what motion, and what the cameras, leave.
#[allow(clippy::too_many_arguments)]
pub(crate) fn oracle_renders(
    scene: &Scene,
    oracle: OracleInputs,
    clip: &HostClip,
    extr: &Tensor<4>,
    intr: &Tensor<4>,
    pred_poses: &[Mat4],
    future: &[usize],
    opts: &EvalOptions,
) -> Result<Vec<OracleRender>> {
    let OracleInputs { motions, cameras } = oracle;
    let cameras = &cameras;
    let size = [clip.height, clip.width];
    let device = extr.device();
    let mut exact = scene.adapted.clone();
    let [_, tc, k, g, _] = exact.motions.dims();
    let data = TensorData::new(motions, [1, tc, k, g, 3]);
    exact.motions = Tensor::from_data(data, &device);
    let still = scene.without_motion().adapted;
    let true_extr = extrinsics_tensor(cameras, &device);
    let true_intr = clip_intrinsics_tensor(clip, cameras.len(), &device);
    let runs = [
        (Method::OracleMotion, &exact, extr, intr, pred_poses),
        (
            Method::TrueCamerasNoMotion,
            &still,
            &true_extr,
            &true_intr,
            cameras,
        ),
        (
            Method::TrueCameras,
            &scene.adapted,
            &true_extr,
            &true_intr,
            cameras,
        ),
        (
            Method::TrueCamerasOracleMotion,
            &exact,
            &true_extr,
            &true_intr,
            cameras,
        ),
    ];
    let own = Exclusion::SelfExclusive;
    let mut out = Vec::with_capacity(runs.len());
    for (method, gaussians, e, i, poses) in runs {
        let (r, secs) = timed_render(gaussians, e, i, future, size, opts, own)?;
        out.push(OracleRender {
            method,
            images: r.images,
            poses: poses.to_vec(),
            secs,
        });
    }
    Ok(out)
}

#[cfg(test)]
#[path = "motion_scene_tests.rs"]
mod tests;
