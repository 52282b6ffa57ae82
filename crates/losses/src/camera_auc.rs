//! Camera pose AUC@30 as VGGT's `evaluation/test_co3d.py` computes it (paper §4).

use crate::error::{LossError, Result};
use glam::{DMat3, DMat4, DVec3};

/// A world-to-camera extrinsic `[R | t]` (3 rows of 4, OpenCV axes), as returned by
/// `pose_encoding_to_extri_intri`.
pub type Extrinsic = [[f64; 4]; 3];

/// Largest threshold of the paper's metric, in degrees.
pub const AUC_MAX_THRESHOLD_DEG: usize = 30;
/// VGGT's floor on `1 − ⟨·,·⟩²` before the arccos (keeps the angle finite at 0).
const ANGLE_EPS: f64 = 1e-15;
/// VGGT's value for a translation angle that came out NaN/inf.
const INVALID_ANGLE_DEG: f64 = 1e6;

/// Errors of one frame pair `(i, j)`, `i < j`, in degrees.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PairError {
    /// First frame index.
    pub i: usize,
    /// Second frame index.
    pub j: usize,
    /// Relative rotation angle error.
    pub rotation_deg: f64,
    /// Relative translation direction angle error (sign-ambiguity folded).
    pub translation_deg: f64,
}

impl PairError {
    /// `max(rotation, translation)`, the value the AUC histogram counts.
    pub fn max_deg(&self) -> f64 {
        self.rotation_deg.max(self.translation_deg)
    }
}

/// Relative pose errors of every unordered frame pair `(i < j)`.
///
/// Definition (VGGT `evaluation/test_co3d.py`, `se3_to_relative_pose_error`): for
/// world-to-camera `E`, the relative pose of a pair is `E_i · E_j⁻¹` (camera j's frame
/// expressed in camera i's), for prediction and ground truth alike. It does not depend on
/// the world frame (`E_i W · (E_j W)⁻¹ = E_i E_j⁻¹`), so no alignment to the first camera is
/// needed, and its translation is camera j's centre seen from camera i.
/// * Rotation: `err_R = arccos(1 − 2·max(1 − ⟨q_pred, q_gt⟩², 1e-15))`, where
///   `⟨q_pred, q_gt⟩² = (1 + tr(R_gtᵀ R_pred)) / 4` is the squared quaternion dot product
///   (identical to VGGT's `mat_to_quat` route for rotation matrices, without its branches).
/// * Translation: unit vectors `t/(‖t‖ + 1e-15)`,
///   `err_t = arccos(sqrt(1 − max(1 − ⟨t̂, t̂_gt⟩², 1e-15)))`, NaN/inf → 1e6, then
///   `min(err_t, |180 − err_t|)`. Direction only, so the metric is scale-free.
///
/// Errors on different frame counts, fewer than 2 frames or a non-finite matrix entry.
pub fn relative_pose_errors(pred: &[Extrinsic], gt: &[Extrinsic]) -> Result<Vec<PairError>> {
    if pred.len() != gt.len() {
        return Err(LossError::ShapeMismatch {
            what: "camera auc extrinsics",
            left: vec![pred.len(), 3, 4],
            right: vec![gt.len(), 3, 4],
        });
    }
    if pred.len() < 2 {
        return Err(LossError::Invalid {
            what: "camera auc",
            reason: format!("needs at least 2 frames, got {}", pred.len()),
        });
    }
    for (what, set) in [
        ("predicted extrinsics", pred),
        ("ground-truth extrinsics", gt),
    ] {
        let flat: Vec<f64> = set.iter().flatten().flatten().copied().collect();
        crate::error::ensure_finite(what, &flat)?;
    }
    let (pred, gt): (Vec<DMat4>, Vec<DMat4>) = (
        pred.iter().map(homogeneous).collect(),
        gt.iter().map(homogeneous).collect(),
    );
    let mut out = Vec::new();
    for i in 0..pred.len() {
        for j in i + 1..pred.len() {
            let (rg, tg) = relative(&gt[i], &gt[j]);
            let (rp, tp) = relative(&pred[i], &pred[j]);
            out.push(PairError {
                i,
                j,
                rotation_deg: rotation_error_deg(&rg, &rp),
                translation_deg: translation_error_deg(&tg, &tp),
            });
        }
    }
    Ok(out)
}

/// AUC over thresholds 1..=`max_threshold` degrees of `max(err_R, err_t)` per pair, in [0, 1]
/// (the paper's tables show ×100).
///
/// Definition (VGGT `calculate_auc_np`): `numpy.histogram(errors, bins=[0, 1, ..., T])`
/// (bins `[k, k+1)`, the last one closed; errors above `T` are not counted), divided by the
/// number of pairs, cumulated; the AUC is the mean of the `T` cumulative values. So all
/// errors equal to 15° give 0.5 at T = 30. Pool pairs from several clips by concatenating
/// their errors. Errors on an empty list or a non-finite or negative error.
pub fn auc_from_errors(max_errors_deg: &[f64], max_threshold: usize) -> Result<f64> {
    if max_errors_deg.is_empty() || max_threshold == 0 {
        return Err(LossError::Invalid {
            what: "camera auc",
            reason: format!(
                "needs at least one pair and a positive threshold (got {} pairs, threshold {max_threshold})",
                max_errors_deg.len()
            ),
        });
    }
    crate::error::ensure_finite("camera auc errors", max_errors_deg)?;
    if let Some(&e) = max_errors_deg.iter().find(|&&e| e < 0.0) {
        return Err(LossError::Invalid {
            what: "camera auc",
            reason: format!("negative angular error {e}"),
        });
    }
    let top = max_threshold as f64;
    let mut hist = vec![0usize; max_threshold];
    for &e in max_errors_deg {
        if e < top {
            hist[e.floor() as usize] += 1;
        } else if e == top {
            // numpy's last bin includes its right edge.
            hist[max_threshold - 1] += 1;
        }
    }
    let pairs = max_errors_deg.len() as f64;
    let mut cumulative = 0.0;
    let mut total = 0.0;
    for count in hist {
        cumulative += count as f64 / pairs;
        total += cumulative;
    }
    Ok(total / max_threshold as f64)
}

/// AUC@30 of one sequence: all pairs, [`relative_pose_errors`] then [`auc_from_errors`].
pub fn camera_auc30(pred: &[Extrinsic], gt: &[Extrinsic]) -> Result<f64> {
    let errors: Vec<f64> = relative_pose_errors(pred, gt)?
        .iter()
        .map(PairError::max_deg)
        .collect();
    auc_from_errors(&errors, AUC_MAX_THRESHOLD_DEG)
}

/// `[R | t]` as a homogeneous transform.
fn homogeneous(e: &Extrinsic) -> DMat4 {
    DMat4::from_cols_array_2d(&[e[0], e[1], e[2], [0.0, 0.0, 0.0, 1.0]]).transpose()
}

/// VGGT's `closed_form_inverse_se3`: `[Rᵀ | −Rᵀt]`.
fn inverse_se3(m: &DMat4) -> DMat4 {
    let rt = DMat3::from_mat4(*m).transpose();
    let t = -(rt * m.w_axis.truncate());
    DMat4::from_cols(
        rt.x_axis.extend(0.0),
        rt.y_axis.extend(0.0),
        rt.z_axis.extend(0.0),
        t.extend(1.0),
    )
}

/// `E_a · E_b⁻¹` as rotation and translation. The translation `t_a − R_a R_bᵀ t_b` is
/// computed as `R_a (c_b − c_a)` with camera centres `c = −Rᵀt`: equal for rigid transforms,
/// but exact for two identical cameras, where the literal product of float matrices that are
/// not quite orthonormal leaves a rounding residue `(I − R Rᵀ) t` parallel to `t`, which the
/// direction metric would read as a perfect translation (a copy-last baseline then scored
/// AUC 100).
fn relative(a: &DMat4, b: &DMat4) -> (DMat3, DVec3) {
    let m = *a * inverse_se3(b);
    let centre = |e: &DMat4| inverse_se3(e).w_axis.truncate();
    (
        DMat3::from_mat4(m),
        DMat3::from_mat4(*a) * (centre(b) - centre(a)),
    )
}

fn rotation_error_deg(gt: &DMat3, pred: &DMat3) -> f64 {
    // tr(gtᵀ·pred) = Σ gt ⊙ pred, summed row by row (VGGT's order).
    let (g, p) = (
        gt.transpose().to_cols_array(),
        pred.transpose().to_cols_array(),
    );
    let trace: f64 = g.iter().zip(&p).map(|(a, b)| a * b).sum();
    let dot_sq = ((1.0 + trace) / 4.0).clamp(0.0, 1.0);
    let loss = (1.0 - dot_sq).max(ANGLE_EPS);
    (1.0 - 2.0 * loss).clamp(-1.0, 1.0).acos().to_degrees()
}

fn translation_error_deg(gt: &DVec3, pred: &DVec3) -> f64 {
    // VGGT divides by `|t| + ε` (not glam's `normalize`), so a zero translation stays finite.
    let unit = |t: &DVec3| *t / (t.length() + ANGLE_EPS);
    let dot = unit(gt).dot(unit(pred));
    let loss = (1.0 - dot * dot).max(ANGLE_EPS);
    let err = (1.0 - loss).sqrt().acos().to_degrees();
    let err = if err.is_finite() {
        err
    } else {
        INVALID_ANGLE_DEG
    };
    err.min((180.0 - err).abs())
}
