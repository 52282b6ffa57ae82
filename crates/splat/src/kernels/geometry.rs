//! The per-Gaussian projection geometry shared by `project_forward` and `project_backward`
//! (a `#[cube]` mirror of `geometry()` in `cpu/project.rs`).
//!
//! CubeCL functions cannot return `Option`, so every quantity is computed and `valid` says
//! whether the CPU code would have returned `Some`; invalid lanes may hold inf/NaN and must
//! not be used.

use super::math::*;
use cubecl::prelude::*;

/// Squared quaternion norms at or below this are culled, from
/// [`crate::config::QUAT_NORM2_MIN`].
const QUAT_NORM2_MIN: f32 = crate::config::QUAT_NORM2_MIN as f32;

/// Everything the projection computes that its backward pass needs again.
#[derive(CubeType, Clone, Copy)]
#[expand(derive(Clone, Copy))]
pub struct Geo {
    pub valid: bool,
    pub m: V3,
    pub q_hat: Q4,
    pub inv_qnorm: f32,
    pub rq: M3,
    pub mmat: M3,
    pub cov_w: M3,
    pub cov_c: M3,
    /// Non-zero EWA Jacobian entries `J = [[j00, 0, j02], [0, j11, j12]]`.
    pub j00: f32,
    pub j02: f32,
    pub j11: f32,
    pub j12: f32,
    pub clamped_x: bool,
    pub clamped_y: bool,
    pub tx: f32,
    pub ty: f32,
    pub cov2d: S2,
    pub conic: S2,
}

/// Geometry of Gaussian `i` (flat `[N,3]` means / scales, `[N,4]` quats) in camera `cam`.
#[cube]
pub fn geometry(
    means: &Tensor<f32>,
    quats: &Tensor<f32>,
    scales: &Tensor<f32>,
    i: usize,
    cam: Cam,
    near: f32,
    far: f32,
    eps2d: f32,
) -> Geo {
    let p = V3 {
        x: means[i * 3],
        y: means[i * 3 + 1],
        z: means[i * 3 + 2],
    };
    let s = V3 {
        x: scales[i * 3],
        y: scales[i * 3 + 1],
        z: scales[i * 3 + 2],
    };
    let inputs_ok =
        finite(p.x) && finite(p.y) && finite(p.z) && finite(s.x) && finite(s.y) && finite(s.z);

    let r = m3_mul_vec(cam.rot, p);
    let m = V3 {
        x: r.x + cam.t.x,
        y: r.y + cam.t.y,
        z: r.z + cam.t.z,
    };
    let z = m.z;
    // Positive phrasing: a NaN depth fails both comparisons.
    let depth_ok = z >= near && z <= far;

    let q = Q4 {
        w: quats[i * 4],
        x: quats[i * 4 + 1],
        y: quats[i * 4 + 2],
        z: quats[i * 4 + 3],
    };
    let n2 = q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z;
    let quat_ok = finite(n2) && n2 > QUAT_NORM2_MIN;
    let inv_qnorm = 1.0f32 / f32::sqrt(n2);
    let q_hat = Q4 {
        w: q.w * inv_qnorm,
        x: q.x * inv_qnorm,
        y: q.y * inv_qnorm,
        z: q.z * inv_qnorm,
    };
    let rq = quat_to_rotmat(q_hat);
    let mmat = m3_scale_cols(rq, s);
    let cov_w = m3_mul(mmat, m3_transpose(mmat));
    let cov_c = m3_mul(m3_mul(cam.rot, cov_w), m3_transpose(cam.rot));

    let rz = 1.0f32 / z;
    let rz2 = rz * rz;
    let ux = m.x * rz;
    let uy = m.y * rz;
    let cx_ = ux.max(0.0f32 - cam.x_neg).min(cam.x_pos);
    let cy_ = uy.max(0.0f32 - cam.y_neg).min(cam.y_pos);
    let tx = z * cx_;
    let ty = z * cy_;
    let j00 = cam.fx * rz;
    let j02 = (0.0f32 - cam.fx) * tx * rz2;
    let j11 = cam.fy * rz;
    let j12 = (0.0f32 - cam.fy) * ty * rz2;
    let c2 = congruence_2x3(j00, j02, j11, j12, cov_c);
    let cov2d = S2 {
        a: c2.a + eps2d,
        b: c2.b,
        c: c2.c + eps2d,
    };
    let det = cov2d.a * cov2d.c - cov2d.b * cov2d.b;
    // eps2d makes det >= eps² in exact arithmetic; anything else is overflow or NaN.
    let cov_ok =
        finite(cov2d.a) && finite(cov2d.b) && finite(cov2d.c) && det > 0.0f32 && finite(det);
    let inv = 1.0f32 / det;
    let conic = S2 {
        a: cov2d.c * inv,
        b: (0.0f32 - cov2d.b) * inv,
        c: cov2d.a * inv,
    };
    let conic_ok = finite(conic.a) && finite(conic.b) && finite(conic.c);

    Geo {
        valid: inputs_ok && depth_ok && quat_ok && cov_ok && conic_ok,
        m,
        q_hat,
        inv_qnorm,
        rq,
        mmat,
        cov_w,
        cov_c,
        j00,
        j02,
        j11,
        j12,
        clamped_x: cx_ != ux,
        clamped_y: cy_ != uy,
        tx,
        ty,
        cov2d,
        conic,
    }
}
