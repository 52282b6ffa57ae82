//! Self-distillation losses (paper §3.4): the student's pose encodings and context depth
//! maps are pulled towards those of a frozen VGGT teacher, whose outputs are passed in.

use burn::tensor::Tensor;

use crate::error::{LossError, Result};

/// λ_cam of the paper (§4, implementation details).
pub const CAMERA_DISTILL_WEIGHT: f64 = 5.0;
/// λ_depth: the paper gives none; 1.0 (`docs/MODEL.md`, "where the paper is silent").
pub const DEPTH_DISTILL_WEIGHT: f64 = 1.0;

/// Weights of the two distillation terms.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DistillWeights {
    /// Multiplies `L_cam`.
    pub camera: f64,
    /// Multiplies `L_depth`.
    pub depth: f64,
}

impl Default for DistillWeights {
    fn default() -> Self {
        Self {
            camera: CAMERA_DISTILL_WEIGHT,
            depth: DEPTH_DISTILL_WEIGHT,
        }
    }
}

/// The unweighted terms and the weighted sum, all scalar tensors `[1]`.
#[derive(Debug, Clone)]
pub struct DistillTerms {
    /// `L_cam` (unweighted).
    pub camera: Tensor<1>,
    /// `L_depth` (unweighted).
    pub depth: Tensor<1>,
    /// `camera_weight·L_cam + depth_weight·L_depth`.
    pub total: Tensor<1>,
}

/// `L_cam = ‖P − P_teacher‖₁`, the mean absolute difference over every element of the 9-d
/// pose encodings (`absT_quaR_FoV`, `[..., 9]`, all frames of the clip; mean over frames and
/// dims, as the release). The teacher is detached. Returns a scalar `[1]`.
pub fn camera_distill<const D: usize>(pose: Tensor<D>, teacher: Tensor<D>) -> Result<Tensor<1>> {
    check_pose_shape(&pose)?;
    l1_mean("camera distillation", pose, teacher)
}

/// [`camera_distill`] with the four quaternion entries of every pose counted
/// `rotation_weight` times (the translation and FoV entries once): the mean over all
/// elements of `w·|P − P_teacher|`. At weight 1 it is exactly `L_cam`. Why a knob: a 2° yaw
/// is 0.017 in the quaternion against decimetres of translation, so in the plain L1 the
/// rotation is a sliver of the camera loss. Returns a scalar `[1]`.
pub fn camera_distill_weighted<const D: usize>(
    pose: Tensor<D>,
    teacher: Tensor<D>,
    rotation_weight: f64,
) -> Result<Tensor<1>> {
    if rotation_weight == 1.0 {
        return camera_distill(pose, teacher);
    }
    if !(rotation_weight.is_finite() && rotation_weight >= 0.0) {
        return Err(LossError::Invalid {
            what: "camera distillation rotation weight",
            reason: format!("must be finite and >= 0, got {rotation_weight}"),
        });
    }
    check_pose_shape(&pose)?;
    crate::mse::check_same("camera distillation", "a non-empty tensor", &pose, &teacher)?;
    let w: Vec<f32> = (0..POSE_ENCODING_DIM)
        .map(|i| {
            if QUATERNION_ENTRIES.contains(&i) {
                rotation_weight as f32
            } else {
                1.0
            }
        })
        .collect();
    let mut shape = [1usize; D];
    shape[D - 1] = POSE_ENCODING_DIM;
    let w = Tensor::<1>::from_floats(w.as_slice(), &pose.device()).reshape(shape);
    Ok(((pose - teacher.detach()).abs() * w).mean())
}

/// `L_depth`: the mean absolute difference between the student's and the teacher's context
/// depth maps `[B, ...]` (e.g. `[B, S, H, W, 1]`) over pixels where the teacher has a depth
/// (`> 0`: the synthetic sky and LiDAR holes have 0). The mean is taken per sample, then over
/// the batch, so a batch's loss is the mean of its samples' losses and data-parallel shards
/// add up to exactly the single-device loss whatever their sky fractions. The teacher is
/// detached. Returns a scalar `[1]`.
pub fn depth_distill<const D: usize>(depth: Tensor<D>, teacher: Tensor<D>) -> Result<Tensor<1>> {
    crate::mse::check_same("depth distillation", "a non-empty tensor", &depth, &teacher)?;
    let teacher = teacher.detach();
    let b = depth.dims()[0];
    // The mask in the inputs' dtype (a bare `float()` is the default dtype, f32).
    let mask = teacher
        .clone()
        .greater_elem(0.0)
        .float()
        .cast(teacher.dtype());
    let err = ((depth - teacher).abs() * mask.clone())
        .reshape([b as i32, -1])
        .sum_dim(1);
    let count = mask.reshape([b as i32, -1]).sum_dim(1).clamp_min(1.0);
    Ok((err / count).mean().reshape([1]))
}

/// Both terms and their weighted sum.
pub fn distill<const DP: usize, const DD: usize>(
    weights: DistillWeights,
    pose: Tensor<DP>,
    pose_teacher: Tensor<DP>,
    depth: Tensor<DD>,
    depth_teacher: Tensor<DD>,
) -> Result<DistillTerms> {
    if !(weights.camera.is_finite() && weights.depth.is_finite()) {
        return Err(LossError::Invalid {
            what: "distillation weights",
            reason: format!("weights must be finite, got {weights:?}"),
        });
    }
    let camera = camera_distill(pose, pose_teacher)?;
    let depth = depth_distill(depth, depth_teacher)?;
    let total = camera.clone() * weights.camera + depth.clone() * weights.depth;
    Ok(DistillTerms {
        camera,
        depth,
        total,
    })
}

/// Refuses anything but `[..., 9]` pose encodings.
fn check_pose_shape<const D: usize>(pose: &Tensor<D>) -> Result<()> {
    let dims = pose.dims();
    if D == 0 || dims[D - 1] != POSE_ENCODING_DIM {
        return Err(LossError::BadShape {
            what: "camera distillation pose",
            expected: "[..., 9] (absT_quaR_FoV pose encodings)",
            got: dims.to_vec(),
        });
    }
    Ok(())
}

/// Width of a pose encoding: translation 3, quaternion 4, FoV 2 (the layout of the model
/// crate's `pose` module; this crate does not depend on the model).
const POSE_ENCODING_DIM: usize = 9;
/// Where the quaternion sits in a pose encoding.
const QUATERNION_ENTRIES: std::ops::Range<usize> = 3..7;

fn l1_mean<const D: usize>(
    what: &'static str,
    student: Tensor<D>,
    teacher: Tensor<D>,
) -> Result<Tensor<1>> {
    crate::mse::check_same(what, "a non-empty tensor", &student, &teacher)?;
    Ok((student - teacher.detach()).abs().mean())
}
