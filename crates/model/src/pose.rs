//! `pose_encoding_to_extri_intri`: the 9-d `absT_quaR_FoV` encoding to world-to-camera
//! extrinsics (OpenCV axes) and pixel intrinsics.
//!
//! Layout: `[t_x, t_y, t_z, q_x, q_y, q_z, q_w, fov_h, fov_w]`; the quaternion is scalar-last
//! and need not be unit (`s = 2 / |q|²` makes R a rotation); `f_y = (H/2)/tan(fov_h/2)`,
//! `f_x = (W/2)/tan(fov_w/2)`, principal point at the image centre.

use burn::tensor::Tensor;

/// `enc: [B, N, 9]` → (`extrinsics [B, N, 4, 4]` world→camera with last row `[0,0,0,1]`,
/// `intrinsics [B, N, 3, 3]` in pixels) for an image of `height x width`.
pub fn pose_encoding_to_extri_intri(
    enc: Tensor<3>,
    height: usize,
    width: usize,
) -> (Tensor<4>, Tensor<4>) {
    let [b, n, _] = enc.dims();
    let c = |i: usize| enc.clone().slice([0..b, 0..n, i..i + 1]);
    let (tx, ty, tz) = (c(0), c(1), c(2));
    let (x, y, z, w) = (c(3), c(4), c(5), c(6));
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
    let fy = half_tan(7).recip().mul_scalar(height as f64 / 2.0);
    let fx = half_tan(8).recip().mul_scalar(width as f64 / 2.0);
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
