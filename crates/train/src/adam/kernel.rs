//! The fused Adam update's CubeCL kernel: one unit per element reads the parameter, its
//! gradient and both moments once and writes the three new values, where Burn's Adam runs
//! about thirteen elementwise kernels per tensor (docs/PERFORMANCE.md, "Kernel launches of a
//! step on a GPU backend").

use cubecl::prelude::*;
use envision4d_splat::kernels::strides::offset_over_axes;

/// Adam on element `i`, in the order of Burn's `Adam` (so a step differs from it only by
/// rounding): `m = β₁·m + (1-β₁)·g`, `v = β₂·v + (1-β₂)·g²` (on the first step the moments
/// start from `(1-β₁)·g` and `(1-β₂)·g²`, and `moment_1`/`moment_2` are not read), then
/// `p -= ((m · factor) / (sqrt(v) + eps_hat)) · lr`, with the bias corrections folded into
/// `factor = sqrt(1-β₂ᵗ) / (1-β₁ᵗ)` and `eps_hat = ε·sqrt(1-β₂ᵗ)` on the host.
///
/// `param` and the moments are flat; with `strided`, `grad` keeps the parameter's shape in
/// its own strides and element `i` (row-major in that shape) is found through them, so a
/// gradient that arrives as a transposed view is read in place rather than copied first.
#[cube(launch)]
#[allow(clippy::too_many_arguments)]
pub fn adam_update(
    param: &Tensor<f32>,
    grad: &Tensor<f32>,
    moment_1: &Tensor<f32>,
    moment_2: &Tensor<f32>,
    param_out: &mut Tensor<f32>,
    moment_1_out: &mut Tensor<f32>,
    moment_2_out: &mut Tensor<f32>,
    len: u32,
    beta_1: f32,
    beta_2: f32,
    factor: f32,
    eps_hat: f32,
    lr: f32,
    #[comptime] first: bool,
    #[comptime] strided: bool,
) {
    let i = ABSOLUTE_POS;
    if i < len as usize {
        let g = if strided {
            grad[offset_over_axes(grad, i as u32, grad.rank()) as usize]
        } else {
            grad[i]
        };
        let mut m = (1.0f32 - beta_1) * g;
        let mut v = (1.0f32 - beta_2) * (g * g);
        if !first {
            m += beta_1 * moment_1[i];
            v += beta_2 * moment_2[i];
        }
        moment_1_out[i] = m;
        moment_2_out[i] = v;
        param_out[i] = param[i] - ((m * factor) / (f32::sqrt(v) + eps_hat)) * lr;
    }
}
