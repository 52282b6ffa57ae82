//! The fused LayerNorm's CubeCL kernels, f32 over the last axis of a `[rows, cols]` view.
//!
//! One cube normalises one row, its sums those of `layers::cube_rows` (in a fixed order, so
//! the result does not depend on scheduling). The mean and the variance are two passes, as
//! in Burn's decomposition, and every row is centred on its first value first (see the
//! forward): a row far from zero (a mean of 1e4, a spread of 1) keeps its variance and its
//! centred values to f32 rounding of the spread, not of the offset.
//!
//! Shared memory is met with `sync_cube`, so no unit may leave early: a cube past the last
//! row (the 2-D grid of many rows rounds up) leaves as a whole, and units past a row's end
//! add zeros.

use crate::layers::cube_rows::{cube_sum, ROW_THREADS, SHARED_LEN};
use cubecl::prelude::*;

/// Units per cube (one row each; the shared reductions' width).
pub const NORM_THREADS: u32 = ROW_THREADS;
/// Rows whose parameter gradients one unit of
/// [`layer_norm_backward_params`](fn@layer_norm_backward_params) sums, one partial row of
/// `[chunks, cols]` per chunk.
pub const PARAM_ROWS: u32 = 256;

/// `y = (x - mean) · rstd · gamma + beta` for each row, `rstd = 1 / sqrt(var + eps)` with
/// the biased variance; writes each row's mean *relative to its first value* (`rel_mean`)
/// and `rstd` for the backward.
#[cube(launch)]
#[allow(clippy::too_many_arguments)]
pub fn layer_norm_forward(
    x: &Tensor<f32>,
    gamma: &Tensor<f32>,
    beta: &Tensor<f32>,
    y: &mut Tensor<f32>,
    mean: &mut Tensor<f32>,
    rstd: &mut Tensor<f32>,
    rows: u32,
    cols: u32,
    eps: f32,
) {
    let row = CUBE_POS as u32;
    if row >= rows {
        terminate!();
    }
    let t = UNIT_POS_X;
    let base = row * cols;
    let per_unit = cols.div_ceil(NORM_THREADS);
    let n = f32::cast_from(cols);
    let mut partial = Shared::<[f32]>::new_slice(SHARED_LEN);
    let mut total = Shared::<[f32]>::new_slice(1usize);

    // Every row is centred on its first value: `x - shift` is exact for values within a
    // factor of two of it, so a row far from zero sums and squares small differences, and
    // the centred values are never rounded through an f32 mean near 1e4 (half an ulp there
    // is 5e-4, which a spread of 1 would carry into every output).
    let shift = x[base as usize];
    let mut own = 0.0f32;
    for k in 0..per_unit {
        let c = t + k * NORM_THREADS;
        if c < cols {
            own += x[(base + c) as usize] - shift;
        }
    }
    let rel_mean = cube_sum(own, &mut partial, &mut total) / n;

    let mut own_sq = 0.0f32;
    for k in 0..per_unit {
        let c = t + k * NORM_THREADS;
        if c < cols {
            let d = (x[(base + c) as usize] - shift) - rel_mean;
            own_sq += d * d;
        }
    }
    let var = cube_sum(own_sq, &mut partial, &mut total) / n;
    let r = 1.0f32 / f32::sqrt(var + eps);

    for k in 0..per_unit {
        let c = t + k * NORM_THREADS;
        if c < cols {
            let i = (base + c) as usize;
            y[i] = ((x[i] - shift) - rel_mean) * r * gamma[c as usize] + beta[c as usize];
        }
    }
    if t == 0 {
        mean[row as usize] = rel_mean;
        rstd[row as usize] = r;
    }
}

/// The input gradient of each row (`mean` relative to the row's first value, as the forward
/// wrote it): with `x̂ = (x - mean) · rstd` and `g = dy · gamma`,
/// `dx = rstd · (g - mean(g) - x̂ · mean(g · x̂))`.
#[cube(launch)]
#[allow(clippy::too_many_arguments)]
pub fn layer_norm_backward_input(
    x: &Tensor<f32>,
    gamma: &Tensor<f32>,
    dy: &Tensor<f32>,
    mean: &Tensor<f32>,
    rstd: &Tensor<f32>,
    dx: &mut Tensor<f32>,
    rows: u32,
    cols: u32,
) {
    let row = CUBE_POS as u32;
    if row >= rows {
        terminate!();
    }
    let t = UNIT_POS_X;
    let base = row * cols;
    let per_unit = cols.div_ceil(NORM_THREADS);
    let n = f32::cast_from(cols);
    let shift = x[base as usize];
    let rel_mean = mean[row as usize];
    let r = rstd[row as usize];
    let mut partial = Shared::<[f32]>::new_slice(SHARED_LEN);
    let mut total = Shared::<[f32]>::new_slice(1usize);

    let mut own_g = 0.0f32;
    let mut own_gx = 0.0f32;
    for k in 0..per_unit {
        let c = t + k * NORM_THREADS;
        if c < cols {
            let i = (base + c) as usize;
            let g = dy[i] * gamma[c as usize];
            own_g += g;
            own_gx += g * ((x[i] - shift) - rel_mean) * r;
        }
    }
    let mean_g = cube_sum(own_g, &mut partial, &mut total) / n;
    let mean_gx = cube_sum(own_gx, &mut partial, &mut total) / n;

    for k in 0..per_unit {
        let c = t + k * NORM_THREADS;
        if c < cols {
            let i = (base + c) as usize;
            let xhat = ((x[i] - shift) - rel_mean) * r;
            dx[i] = r * (dy[i] * gamma[c as usize] - mean_g - xhat * mean_gx);
        }
    }
}

/// Partial parameter gradients: unit `(c, chunk)` sums `dy · x̂` and `dy` of column `c` over
/// the chunk's `PARAM_ROWS` rows into `dgamma[chunk, c]` and `dbeta[chunk, c]` (adjacent
/// units read adjacent columns of a row). The chunks are summed by the caller.
#[cube(launch)]
#[allow(clippy::too_many_arguments)]
pub fn layer_norm_backward_params(
    x: &Tensor<f32>,
    dy: &Tensor<f32>,
    mean: &Tensor<f32>,
    rstd: &Tensor<f32>,
    dgamma: &mut Tensor<f32>,
    dbeta: &mut Tensor<f32>,
    rows: u32,
    cols: u32,
    chunks: u32,
) {
    let at = ABSOLUTE_POS as u32;
    if at >= cols * chunks {
        terminate!();
    }
    let c = at % cols;
    let chunk = at / cols;
    let first = chunk * PARAM_ROWS;
    let mut sum_g = 0.0f32;
    let mut sum_b = 0.0f32;
    for k in 0..PARAM_ROWS {
        let row = first + k;
        if row < rows {
            let i = (row * cols + c) as usize;
            let shift = x[(row * cols) as usize];
            let d = dy[i];
            sum_g += d * ((x[i] - shift) - mean[row as usize]) * rstd[row as usize];
            sum_b += d;
        }
    }
    dgamma[at as usize] = sum_g;
    dbeta[at as usize] = sum_b;
}
