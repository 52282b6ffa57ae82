//! The MLP's bias and exact GELU, `y = gelu(z + b)` with `gelu(x) = x Φ(x)`, as two kernels,
//! f32, over `[rows, cols]` pre-activations and a `[cols]` bias: the forward elementwise,
//! and the backward by columns (as the LayerScale residual's, `residual/kernels.rs`), each
//! unit taking one channel over a chunk of [`BIAS_ROWS`] rows so that the bias gradient is
//! a sum in the same pass that writes `dz`.
//!
//! Φ comes from `erfc` rather than `1 + erf`: in the lower tail `1 + erf(x/√2)` cancels (in
//! f32 it is 0 below x ≈ -5.5, and Burn's polynomial erf, accurate to 1.5e-7 absolute, is
//! off by 10% at x = -5), while `Φ(x) = ½ erfc(-x/√2)` keeps its relative accuracy there.
//! The derivative is the exact `Φ(x) + x φ(x)`: Burn's CubeCL backward is the tanh
//! approximation's, about 1e-3 from the erf forward it differentiates.

use cubecl::prelude::*;

/// Rows per unit of [`bias_gelu_backward`]: the bias's partial sums come out as
/// `[chunks, cols]`, reduced once more on the device only when there is more than one.
pub const BIAS_ROWS: u32 = 256;

/// `1/√2`.
const FRAC_1_SQRT_2: f32 = std::f32::consts::FRAC_1_SQRT_2;
/// `1/√(2π)`, the standard normal density at 0.
const INV_SQRT_2PI: f32 = 0.398_942_3;

/// `ln(erfc(z) / t) + z²` for `t = 1 / (1 + z/2)`, `z >= 0`: the Chebyshev fit of Press et al.
/// (Numerical Recipes, `erfcc`), whose `erfc = t · exp(-z² + this)` has a fractional error
/// below 1.2e-7 for every `z >= 0`, the far tail included.
#[cube]
fn erfc_log_fit(t: f32) -> f32 {
    let mut p = 0.170_872_77f32;
    p = p * t - 0.822_152_23;
    p = p * t + 1.488_515_9;
    p = p * t - 1.135_204;
    p = p * t + 0.278_868_07;
    p = p * t - 0.186_288_06;
    p = p * t + 0.096_784_18;
    p = p * t + 0.374_091_96;
    p = p * t + 1.000_023_7;
    p * t - 1.265_512_2
}

/// `Φ(x)` and `e^{-x²/2}`, the standard normal CDF and its unnormalised density, sharing
/// the one `x²/2`. The smaller tail `Φ(-|x|) = ½ erfc(|x|/√2)` is computed directly, the
/// other as its complement.
#[cube]
fn normal_cdf_and_gauss(x: f32) -> (f32, f32) {
    let mut z = x * FRAC_1_SQRT_2;
    if x < 0.0f32 {
        z = 0.0f32 - z;
    }
    let t = 1.0f32 / (1.0f32 + 0.5f32 * z);
    let half_sq = 0.5f32 * x * x;
    let gauss = f32::exp(0.0f32 - half_sq);
    let tail = 0.5f32 * t * f32::exp(erfc_log_fit(t)) * gauss;
    let mut cdf = 1.0f32 - tail;
    if x < 0.0f32 {
        cdf = tail;
    }
    (cdf, gauss)
}

/// `y = gelu(z + bias[c])`.
#[cube(launch)]
pub fn bias_gelu_forward(
    z: &Tensor<f32>,
    bias: &Tensor<f32>,
    y: &mut Tensor<f32>,
    cols: u32,
    len: u32,
) {
    let i = ABSOLUTE_POS as u32;
    if i >= len {
        terminate!();
    }
    let x = z[i as usize] + bias[(i % cols) as usize];
    let (cdf, _gauss) = normal_cdf_and_gauss(x);
    y[i as usize] = x * cdf;
}

/// `dz = grad · gelu'(z + bias[c])` with `gelu'(x) = Φ(x) + x φ(x)` and, with `bias_grad`,
/// each chunk's `Σ dz` per channel into `bias_part[chunk · cols + c]`.
#[cube(launch)]
#[allow(clippy::too_many_arguments)]
pub fn bias_gelu_backward(
    grad: &Tensor<f32>,
    z: &Tensor<f32>,
    bias: &Tensor<f32>,
    dz: &mut Tensor<f32>,
    bias_part: &mut Tensor<f32>,
    rows: u32,
    cols: u32,
    chunks: u32,
    #[comptime] bias_grad: bool,
) {
    let at = ABSOLUTE_POS as u32;
    if at >= cols * chunks {
        terminate!();
    }
    let c = at % cols;
    let first = (at / cols) * BIAS_ROWS;
    let b_c = bias[c as usize];
    let mut sum = 0.0f32;
    for k in 0..BIAS_ROWS {
        let row = first + k;
        if row < rows {
            let i = (row * cols + c) as usize;
            let x = z[i] + b_c;
            let (cdf, gauss) = normal_cdf_and_gauss(x);
            let d = grad[i] * (cdf + x * (gauss * INV_SQRT_2PI));
            dz[i] = d;
            if bias_grad {
                sum += d;
            }
        }
    }
    if bias_grad {
        bias_part[at as usize] = sum;
    }
}
