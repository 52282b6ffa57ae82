//! Camera poses on the host: reading predicted extrinsics back, building extrinsic tensors,
//! and the future-pose error of one camera against ground truth.
//!
//! Every pose here is an OpenCV world-to-camera matrix. The model's world frame is context
//! frame 0's camera, so its poses are already relative to frame 0; ground truth is brought to
//! the same frame with `G_j · G_0⁻¹`. The prediction is re-expressed the same way
//! (`P_j · P_0⁻¹`) because the predicted frame-0 pose is close to, not exactly, the identity.

use crate::error::Result;
use burn::tensor::{Device, Tensor, TensorData};
use envision4d_data::geom::Mat4;
use envision4d_losses::Extrinsic;
use envision4d_model::SceneError;
use glam::DVec3;

/// Entries of one 4×4 matrix.
const MAT4_LEN: usize = 16;

/// Rotation and camera-centre error of one predicted camera.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseError {
    /// Angle of `R_pred · R_gtᵀ`, in degrees.
    pub rotation_deg: f64,
    /// Distance between the scale-aligned predicted camera centre and the true one, in
    /// frame 0's camera coordinates and the ground truth's unit (metres for every layout
    /// with poses); the scale comes from [`translation_scale`].
    pub translation: f64,
}

/// Extrinsics `[B, N, 4, 4]` of batch element `b` as host matrices (finite-checked).
pub fn host_extrinsics(extrinsics: &Tensor<4>, b: usize) -> Result<Vec<Mat4>> {
    let [_, n, _, _] = extrinsics.dims();
    let values: Vec<f64> = extrinsics
        .clone()
        .slice([b..b + 1, 0..n, 0..4, 0..4])
        .into_data()
        .iter::<f64>()
        .collect();
    if values.iter().any(|v| !v.is_finite()) {
        return Err(SceneError::NonFinite("predicted extrinsics").into());
    }
    Ok(values
        .chunks_exact(MAT4_LEN)
        .map(|c| {
            let mut m = [[0.0; 4]; 4];
            for (r, row) in m.iter_mut().enumerate() {
                row.copy_from_slice(&c[r * 4..r * 4 + 4]);
            }
            Mat4(m)
        })
        .collect())
}

/// Host matrices as an extrinsics tensor `[1, N, 4, 4]`.
pub fn extrinsics_tensor(mats: &[Mat4], device: &Device) -> Tensor<4> {
    let data: Vec<f32> = mats
        .iter()
        .flat_map(|m| m.0.iter().flatten().map(|&v| v as f32).collect::<Vec<_>>())
        .collect();
    Tensor::from_data(TensorData::new(data, [1, mats.len(), 4, 4]), device)
}

/// The `[R | t]` rows the camera-AUC metric takes.
pub fn to_extrinsic(m: &Mat4) -> Extrinsic {
    [m.0[0], m.0[1], m.0[2]]
}

/// Rotation angle of the rotation part of `m`, in degrees.
///
/// `atan2(sin θ, cos θ)` with `cos θ = (tr R − 1)/2` and `sin θ = ‖vee(R − Rᵀ)‖/2`: unlike
/// `acos` of the cosine alone it stays accurate for the tiny angles good predictions have.
pub fn rotation_angle_deg(m: &Mat4) -> f64 {
    let r = m.rotation();
    let cos = (r.x_axis.x + r.y_axis.y + r.z_axis.z - 1.0) / 2.0;
    // vee(R − Rᵀ) = (R₂₁ − R₁₂, R₀₂ − R₂₀, R₁₀ − R₀₁); glam's columns are `r.col(c)[row]`.
    let axis = DVec3::new(
        r.y_axis.z - r.z_axis.y,
        r.z_axis.x - r.x_axis.z,
        r.x_axis.y - r.y_axis.x,
    );
    let sin = axis.length() / 2.0;
    sin.atan2(cos).to_degrees()
}

/// Camera centre `−Rᵀt` of a world-to-camera matrix, in world coordinates.
pub fn camera_centre(m: &Mat4) -> DVec3 {
    m.rigid_inverse().translation()
}

/// `poses[j] · poses[0]⁻¹` for every j: the poses with frame 0's camera as the world.
pub fn relative_to_first(poses: &[Mat4]) -> Vec<Mat4> {
    let Some(first) = poses.first() else {
        return Vec::new();
    };
    let first_inv = first.rigid_inverse();
    poses.iter().map(|p| p.mul(&first_inv)).collect()
}

/// Below this `Σ‖c_pred‖²` the predicted cameras do not move and no scale can be fitted.
const STILL_CAMERAS: f64 = 1e-12;

/// The scale that maps a pose-free model's camera centres onto the true ones: least squares
/// over the clip's cameras, `s = Σ c_pred·c_gt / Σ ‖c_pred‖²` (frame 0 is the origin of
/// both, so it contributes nothing), floored at 0 because a negative scale would mirror the
/// trajectory. 1 when the predicted cameras do not move.
///
/// One scale per clip, fitted on all `T_c + T_f` cameras like the trajectory alignment of
/// ATE; it is reported next to the error (`pose_scale`).
pub fn translation_scale(pred_rel: &[Mat4], gt_rel: &[Mat4]) -> f64 {
    let (mut pg, mut pp) = (0.0, 0.0);
    for (p, g) in pred_rel.iter().zip(gt_rel) {
        let (cp, cg) = (camera_centre(p), camera_centre(g));
        pg += cp.dot(cg);
        pp += cp.length_squared();
    }
    if pp <= STILL_CAMERAS {
        1.0
    } else {
        (pg / pp).max(0.0)
    }
}

/// Error of predicted camera `j` against ground truth, both taken relative to their own
/// frame 0 (`pred_rel`, `gt_rel` from [`relative_to_first`]), the predicted centre scaled
/// by `scale` ([`translation_scale`]).
pub fn pose_error(pred_rel: &Mat4, gt_rel: &Mat4, scale: f64) -> PoseError {
    let diff = pred_rel.mul(&gt_rel.rigid_inverse());
    let translation = (camera_centre(pred_rel) * scale).distance(camera_centre(gt_rel));
    PoseError {
        rotation_deg: rotation_angle_deg(&diff),
        translation,
    }
}

/// Constant-velocity (SE(3)) extrapolation: with `Δ = last · prev⁻¹` (the motion from the
/// second-to-last to the last camera, in camera coordinates), returns `Δᵏ · last` for
/// `k = 1..=steps`.
pub fn extrapolate_constant_velocity(prev: &Mat4, last: &Mat4, steps: usize) -> Vec<Mat4> {
    let delta = last.mul(&prev.rigid_inverse());
    let mut out = Vec::with_capacity(steps);
    let mut current = *last;
    for _ in 0..steps {
        current = delta.mul(&current);
        out.push(current);
    }
    out
}

/// The clip's true intrinsics of its first `n` frames, `[1, n, 3, 3]`, at the clip's size
/// (the oracle renders' cameras, and the motion-gradient diagnostic's).
pub fn clip_intrinsics_tensor(
    clip: &envision4d_data::HostClip,
    n: usize,
    device: &Device,
) -> Tensor<4> {
    let data: Vec<f32> = clip.cameras[..n]
        .iter()
        .flat_map(|(_, k)| [k.fx, 0.0, k.cx, 0.0, k.fy, k.cy, 0.0, 0.0, 1.0])
        .map(|v| v as f32)
        .collect();
    Tensor::from_data(TensorData::new(data, [1, n, 3, 3]), device)
}
