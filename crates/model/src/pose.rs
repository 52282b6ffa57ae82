//! The 9-d `absT_quaR_FoV` pose encoding in one place: its layout, the host-side encoding of
//! a known camera, and [`pose_encoding_to_extri_intri`], the decoding to world-to-camera
//! extrinsics (OpenCV axes) and pixel intrinsics.
//!
//! Layout: `[t_x, t_y, t_z, q_x, q_y, q_z, q_w, fov_h, fov_w]`; the quaternion is scalar-last
//! and need not be unit (`s = 2 / |q|²` makes R a rotation); `f_y = (H/2)/tan(fov_h/2)`,
//! `f_x = (W/2)/tan(fov_w/2)`, principal point at the image centre.

use std::ops::Range;

use burn::tensor::Tensor;

/// Channels per frame of the encoding.
pub const POSE_ENCODING_DIM: usize = 9;
/// World-to-camera translation `t_x, t_y, t_z`.
pub const TRANSLATION: Range<usize> = 0..3;
/// Rotation quaternion, scalar last: `q_x, q_y, q_z, q_w`.
pub const QUATERNION: Range<usize> = 3..7;
/// Vertical and horizontal field of view (radians): `fov_h, fov_w`.
pub const FOV: Range<usize> = 7..9;

/// Quaternion `[x, y, z, w]` (w ≥ 0) of a rotation matrix (Shepperd's method: pick the
/// largest diagonal combination for numerical stability).
pub fn quat_xyzw(r: [[f64; 3]; 3]) -> [f64; 4] {
    let tr = r[0][0] + r[1][1] + r[2][2];
    let q = if tr > 0.0 {
        let s = (tr + 1.0).sqrt() * 2.0;
        [
            (r[2][1] - r[1][2]) / s,
            (r[0][2] - r[2][0]) / s,
            (r[1][0] - r[0][1]) / s,
            0.25 * s,
        ]
    } else if r[0][0] > r[1][1] && r[0][0] > r[2][2] {
        let s = (1.0 + r[0][0] - r[1][1] - r[2][2]).sqrt() * 2.0;
        [
            0.25 * s,
            (r[0][1] + r[1][0]) / s,
            (r[0][2] + r[2][0]) / s,
            (r[2][1] - r[1][2]) / s,
        ]
    } else if r[1][1] > r[2][2] {
        let s = (1.0 + r[1][1] - r[0][0] - r[2][2]).sqrt() * 2.0;
        [
            (r[0][1] + r[1][0]) / s,
            0.25 * s,
            (r[1][2] + r[2][1]) / s,
            (r[0][2] - r[2][0]) / s,
        ]
    } else {
        let s = (1.0 + r[2][2] - r[0][0] - r[1][1]).sqrt() * 2.0;
        [
            (r[0][2] + r[2][0]) / s,
            (r[1][2] + r[2][1]) / s,
            0.25 * s,
            (r[1][0] - r[0][1]) / s,
        ]
    };
    if q[3] < 0.0 {
        q.map(|v| -v)
    } else {
        q
    }
}

/// The encoding of one camera: `w2c` a row-major world-to-camera matrix (already relative
/// to the model's world frame, the first camera), `(fx, fy)` its focal lengths in pixels
/// for an image of `height x width`. The inverse of [`pose_encoding_to_extri_intri`].
pub fn encode_pose(w2c: &[[f64; 4]; 4], fx: f64, fy: f64, height: usize, width: usize) -> [f32; 9] {
    let r = [
        [w2c[0][0], w2c[0][1], w2c[0][2]],
        [w2c[1][0], w2c[1][1], w2c[1][2]],
        [w2c[2][0], w2c[2][1], w2c[2][2]],
    ];
    let q = quat_xyzw(r);
    let fov_h = 2.0 * ((height as f64 / 2.0) / fy).atan();
    let fov_w = 2.0 * ((width as f64 / 2.0) / fx).atan();
    [
        w2c[0][3], w2c[1][3], w2c[2][3], q[0], q[1], q[2], q[3], fov_h, fov_w,
    ]
    .map(|v| v as f32)
}

/// `enc: [B, N, 9]` → (`extrinsics [B, N, 4, 4]` world→camera with last row `[0,0,0,1]`,
/// `intrinsics [B, N, 3, 3]` in pixels) for an image of `height x width`.
pub fn pose_encoding_to_extri_intri(
    enc: Tensor<3>,
    height: usize,
    width: usize,
) -> (Tensor<4>, Tensor<4>) {
    let [b, n, _] = enc.dims();
    let c = |i: usize| enc.clone().slice([0..b, 0..n, i..i + 1]);
    let t = TRANSLATION.start;
    let (tx, ty, tz) = (c(t), c(t + 1), c(t + 2));
    let q = QUATERNION.start;
    let (x, y, z, w) = (c(q), c(q + 1), c(q + 2), c(q + 3));
    let norm2 = x.clone().powf_scalar(2.0)
        + y.clone().powf_scalar(2.0)
        + z.clone().powf_scalar(2.0)
        + w.clone().powf_scalar(2.0);
    let s = norm2.recip().mul_scalar(2.0);
    let one = |t: Tensor<3>| t.neg().add_scalar(1.0);
    let r00 = one(s.clone() * (y.clone() * y.clone() + z.clone() * z.clone()));
    let r01 = s.clone() * (x.clone() * y.clone() - z.clone() * w.clone());
    let r02 = s.clone() * (x.clone() * z.clone() + y.clone() * w.clone());
    let r10 = s.clone() * (x.clone() * y.clone() + z.clone() * w.clone());
    let r11 = one(s.clone() * (x.clone() * x.clone() + z.clone() * z.clone()));
    let r12 = s.clone() * (y.clone() * z.clone() - x.clone() * w.clone());
    let r20 = s.clone() * (x.clone() * z.clone() - y.clone() * w.clone());
    let r21 = s.clone() * (y.clone() * z.clone() + x.clone() * w.clone());
    let r22 = one(s * (x.clone() * x + y.clone() * y));
    let zero = tx.clone().zeros_like();
    let unit = zero.clone().add_scalar(1.0);
    let extr = Tensor::cat(
        vec![
            r00,
            r01,
            r02,
            tx,
            r10,
            r11,
            r12,
            ty,
            r20,
            r21,
            r22,
            tz,
            zero.clone(),
            zero.clone(),
            zero.clone(),
            unit.clone(),
        ],
        2,
    )
    .reshape([b, n, 4, 4]);
    let half_tan = |i: usize| c(i).mul_scalar(0.5).tan();
    let fy = half_tan(FOV.start).recip().mul_scalar(height as f64 / 2.0);
    let fx = half_tan(FOV.start + 1)
        .recip()
        .mul_scalar(width as f64 / 2.0);
    let cx = zero.clone().add_scalar(width as f64 / 2.0);
    let cy = zero.clone().add_scalar(height as f64 / 2.0);
    let intr = Tensor::cat(
        vec![
            fx,
            zero.clone(),
            cx,
            zero.clone(),
            fy,
            cy,
            zero.clone(),
            zero,
            unit,
        ],
        2,
    )
    .reshape([b, n, 3, 3]);
    (extr, intr)
}
