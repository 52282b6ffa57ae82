//! The RoPE rotation as one elementwise kernel, f32, over `[B, H, N, D]` tokens and
//! `[TB, 1, N, D]` tables (`TB` is `B`, or 1 for tables shared by the batch).
//!
//! Within each half of a head the rotation pairs quarter 0 with 1 and 2 with 3 (`swap`
//! below, an involution), so `y_i = x_i c_i + x_swap(i) s_i` and its vector-Jacobian product
//! is `dx_i = g_i c_i + g_swap(i) s_swap(i)`: the same kernel reading the sine at the
//! partner's place. (The aggregator's tables give `s_swap(i) = -s_i`, the inverse rotation,
//! but the kernel does not rely on it.)

use cubecl::prelude::*;

/// `y = x · cos + swap(x) · sin`, or with `vjp` the rotation's VJP of the gradient `x`.
#[allow(clippy::too_many_arguments)]
#[cube(launch)]
pub fn rope_rotate(
    x: &Tensor<f32>,
    cos: &Tensor<f32>,
    sin: &Tensor<f32>,
    y: &mut Tensor<f32>,
    heads: u32,
    tokens: u32,
    head_dim: u32,
    table_batches: u32,
    len: u32,
    #[comptime] vjp: bool,
) {
    let i = ABSOLUTE_POS as u32;
    if i >= len {
        terminate!();
    }
    let d = i % head_dim;
    // The element's token row, `(b · H + h) · N + n`, and its table row `(b · N + n)`.
    let row = i / head_dim;
    let n = row % tokens;
    let b = row / tokens / heads;
    let table = ((b % table_batches) * tokens + n) * head_dim;
    let quarter = head_dim / 4;
    let partner = ((d / quarter) ^ 1u32) * quarter + d % quarter;
    let swapped = x[(i - d + partner) as usize];
    let own = x[i as usize] * cos[(table + d) as usize];
    if vjp {
        y[i as usize] = own + swapped * sin[(table + partner) as usize];
    } else {
        y[i as usize] = own + swapped * sin[(table + d) as usize];
    }
}
