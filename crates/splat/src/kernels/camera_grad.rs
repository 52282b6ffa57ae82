//! The camera gradients of one view laid out as the camera tensors, on the device:
//! `sums` (the per-Gaussian camera partials summed, `CAM_GRAD_LANES` = rotation (9, row-major),
//! translation (3), fx, fy, cx, cy) → row `view` of `viewmats_grad [V, 4, 4]` (bottom row
//! zero) and `ks_grad [V, 3, 3]` (only fx, fy, cx, cy non-zero), as
//! [`crate::camera::CameraGrad::to_matrices`] does on the host. One unit; nothing read back.

use cubecl::prelude::*;

#[cube(launch)]
pub fn camera_grad_matrices(
    sums: &Tensor<f32>,
    viewmats_grad: &mut Tensor<f32>,
    ks_grad: &mut Tensor<f32>,
    view: u32,
) {
    if ABSOLUTE_POS == 0 {
        let vm = view as usize * 16;
        for row in 0..3usize {
            for col in 0..3usize {
                viewmats_grad[vm + row * 4 + col] = sums[row * 3 + col];
            }
            viewmats_grad[vm + row * 4 + 3] = sums[9 + row];
        }
        let k = view as usize * 9;
        ks_grad[k] = sums[12];
        ks_grad[k + 4] = sums[13];
        ks_grad[k + 2] = sums[14];
        ks_grad[k + 5] = sums[15];
    }
}
