//! The LayerScale residual `y = x + (u + b) ⊙ γ` as two kernels, f32, over `[rows, cols]`
//! tokens `x` and `u` (the projection before the gain, without its bias), the projection's
//! `[cols]` bias `b` and a `[cols]` gain: the forward elementwise, and the backward by
//! columns, each unit taking one channel over a chunk of [`GAIN_ROWS`] rows so that the
//! gain's and the bias's gradients are sums in the same pass that writes `du`. Within a
//! chunk, neighbouring units read neighbouring channels of a row, so the reads stay
//! coalesced.

use cubecl::prelude::*;

/// Rows per unit of [`scaled_residual_backward`]: the gain's and the bias's partial sums
/// come out as `[chunks, cols]`, reduced once more on the device only when there is more
/// than one.
pub const GAIN_ROWS: u32 = 256;

/// `y = x + (u + bias[c]) · gamma[c]`: the same roundings as Burn's `Linear` bias sum,
/// product and sum where the compiler keeps them apart (WGSL here); CUDA's LLVM route may
/// contract the last two into one fused multiply-add, which rounds once.
#[cube(launch)]
#[allow(clippy::too_many_arguments)]
pub fn scaled_residual_forward(
    x: &Tensor<f32>,
    u: &Tensor<f32>,
    bias: &Tensor<f32>,
    gamma: &Tensor<f32>,
    y: &mut Tensor<f32>,
    cols: u32,
    len: u32,
) {
    let i = ABSOLUTE_POS as u32;
    if i >= len {
        terminate!();
    }
    let c = (i % cols) as usize;
    let v = u[i as usize] + bias[c];
    y[i as usize] = x[i as usize] + v * gamma[c];
}

/// `du = grad · gamma[c]` and per chunk and channel, with `gain`, `Σ grad · (u + bias[c])`
/// into `gain_part[chunk · cols + c]` and, with `bias_grad`, `Σ du` into `bias_part` (the
/// bias's gradient is the projection output's, as Burn sums it). An output whose sum is not
/// asked for is never written.
#[cube(launch)]
#[allow(clippy::too_many_arguments)]
pub fn scaled_residual_backward(
    grad: &Tensor<f32>,
    u: &Tensor<f32>,
    bias: &Tensor<f32>,
    gamma: &Tensor<f32>,
    du: &mut Tensor<f32>,
    gain_part: &mut Tensor<f32>,
    bias_part: &mut Tensor<f32>,
    rows: u32,
    cols: u32,
    chunks: u32,
    #[comptime] gain: bool,
    #[comptime] bias_grad: bool,
) {
    let at = ABSOLUTE_POS as u32;
    if at >= cols * chunks {
        terminate!();
    }
    let c = at % cols;
    let first = (at / cols) * GAIN_ROWS;
    let g_c = gamma[c as usize];
    let mut b_c = 0.0f32;
    if gain {
        b_c = bias[c as usize];
    }
    let mut gain_sum = 0.0f32;
    let mut bias_sum = 0.0f32;
    for k in 0..GAIN_ROWS {
        let row = first + k;
        if row < rows {
            let i = (row * cols + c) as usize;
            let g = grad[i];
            let d = g * g_c;
            du[i] = d;
            if gain {
                gain_sum += g * (u[i] + b_c);
            }
            if bias_grad {
                bias_sum += d;
            }
        }
    }
    if gain {
        gain_part[at as usize] = gain_sum;
    }
    if bias_grad {
        bias_part[at as usize] = bias_sum;
    }
}
