//! The LayerScale residual `y = x + u ⊙ γ` as two kernels, f32, over `[rows, cols]` tokens
//! and a `[cols]` gain: the forward elementwise, and the backward by columns, each unit
//! taking one channel over a chunk of [`GAIN_ROWS`] rows so that the gain's gradient is a
//! sum in the same pass that writes `du`. Within a chunk, neighbouring units read
//! neighbouring channels of a row, so the reads stay coalesced.

use cubecl::prelude::*;

/// Rows per unit of [`scaled_residual_backward`]: the gain's partial sums come out as
/// `[chunks, cols]`, reduced once more on the device only when there is more than one.
pub const GAIN_ROWS: u32 = 256;

/// `y = x + u · gamma[c]`: the same two roundings as Burn's product then sum where the
/// compiler keeps them apart (WGSL here); CUDA's LLVM route may contract them into one
/// fused multiply-add, which rounds once.
#[cube(launch)]
pub fn scaled_residual_forward(
    x: &Tensor<f32>,
    u: &Tensor<f32>,
    gamma: &Tensor<f32>,
    y: &mut Tensor<f32>,
    cols: u32,
    len: u32,
) {
    let i = ABSOLUTE_POS as u32;
    if i >= len {
        terminate!();
    }
    y[i as usize] = x[i as usize] + u[i as usize] * gamma[(i % cols) as usize];
}

/// `du = grad · gamma[c]` and, with `gain`, each chunk's `Σ grad · u` per channel into
/// `gain_part[chunk · cols + c]`.
#[cube(launch)]
#[allow(clippy::too_many_arguments)]
pub fn scaled_residual_backward(
    grad: &Tensor<f32>,
    u: &Tensor<f32>,
    gamma: &Tensor<f32>,
    du: &mut Tensor<f32>,
    gain_part: &mut Tensor<f32>,
    rows: u32,
    cols: u32,
    chunks: u32,
    #[comptime] gain: bool,
) {
    let at = ABSOLUTE_POS as u32;
    if at >= cols * chunks {
        terminate!();
    }
    let c = at % cols;
    let first = (at / cols) * GAIN_ROWS;
    let g_c = gamma[c as usize];
    let mut sum = 0.0f32;
    for k in 0..GAIN_ROWS {
        let row = first + k;
        if row < rows {
            let i = (row * cols + c) as usize;
            let g = grad[i];
            du[i] = g * g_c;
            if gain {
                sum += g * u[i];
            }
        }
    }
    if gain {
        gain_part[at as usize] = sum;
    }
}
