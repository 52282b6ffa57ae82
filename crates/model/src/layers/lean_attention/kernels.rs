//! The lean attention's row kernels, f32 over `[rows, cols]` views of a block of scores
//! (`rows = B · H · query rows`, `cols = N` keys) and its `[rows]` statistics.
//!
//! The softmax and the row dot product run one cube per row (the row dot on strided views) with the ordered reductions of
//! `layers::cube_rows`; the two backward steps are elementwise, one unit per score.

use crate::layers::cube_rows::{cube_max, cube_sum, ROW_THREADS, SHARED_LEN};
use cubecl::prelude::*;
use envision4d_splat::kernels::strides::offset_over_axes;

/// `p = softmax(s · scale)` of each row, and its log-sum-exp `lse = m + ln Σ exp(s · scale
/// - m)` with `m` the row's maximum (so no exponent is positive: rows of logits in the
/// hundreds neither overflow nor lose their largest term).
#[cube(launch)]
pub fn softmax_rows(
    s: &Tensor<f32>,
    p: &mut Tensor<f32>,
    lse: &mut Tensor<f32>,
    rows: u32,
    cols: u32,
    scale: f32,
) {
    let row = CUBE_POS as u32;
    if row >= rows {
        terminate!();
    }
    let t = UNIT_POS_X;
    let base = row * cols;
    let per_unit = cols.div_ceil(ROW_THREADS);
    let mut partial = Shared::<[f32]>::new_slice(SHARED_LEN);
    let mut total = Shared::<[f32]>::new_slice(1usize);

    // Every unit starts from the row's first score, a value of the row, so a unit with no
    // share (a row shorter than the cube) leaves the maximum unchanged.
    let mut own_max = s[base as usize] * scale;
    for k in 0..per_unit {
        let c = t + k * ROW_THREADS;
        if c < cols {
            own_max = f32::max(own_max, s[(base + c) as usize] * scale);
        }
    }
    let m = cube_max(own_max, &mut partial, &mut total);

    let mut own_sum = 0.0f32;
    for k in 0..per_unit {
        let c = t + k * ROW_THREADS;
        if c < cols {
            own_sum += f32::exp(s[(base + c) as usize] * scale - m);
        }
    }
    // At least exp(0) = 1 from the maximum itself: the division and the logarithm are safe.
    let l = cube_sum(own_sum, &mut partial, &mut total);
    let inv = 1.0f32 / l;

    for k in 0..per_unit {
        let c = t + k * ROW_THREADS;
        if c < cols {
            let i = (base + c) as usize;
            p[i] = f32::exp(s[i] * scale - m) * inv;
        }
    }
    if t == 0 {
        lse[row as usize] = m + f32::ln(l);
    }
}

/// `out[row] = Σ_c a[row, c] · b[row, c]`: the softmax VJP's row term `Δ = Σ dO · O`. `a`
/// and `b` share their shape, each in its own strides; `out` is flat.
#[cube(launch)]
pub fn row_dot(a: &Tensor<f32>, b: &Tensor<f32>, out: &mut Tensor<f32>, rows: u32, cols: u32) {
    let row = CUBE_POS as u32;
    if row >= rows {
        terminate!();
    }
    let t = UNIT_POS_X;
    let last = a.rank() - 1;
    // Where the row starts: the row index spread over every axis but the last, in each
    // view's own strides, so a strided view (the swapped gradient attention receives) is
    // read in place rather than copied first.
    let (a0, b0) = (
        offset_over_axes(a, row, last),
        offset_over_axes(b, row, last),
    );
    let (a_step, b_step) = (a.stride(last) as u32, b.stride(last) as u32);
    let per_unit = cols.div_ceil(ROW_THREADS);
    let mut partial = Shared::<[f32]>::new_slice(SHARED_LEN);
    let mut total = Shared::<[f32]>::new_slice(1usize);
    let mut own = 0.0f32;
    for k in 0..per_unit {
        let c = t + k * ROW_THREADS;
        if c < cols {
            own += a[(a0 + c * a_step) as usize] * b[(b0 + c * b_step) as usize];
        }
    }
    let sum = cube_sum(own, &mut partial, &mut total);
    if t == 0 {
        out[row as usize] = sum;
    }
}

/// `p = exp(s · scale - lse[row])`: the forward's probabilities again, from its statistics.
#[cube(launch)]
pub fn probs_from_lse(
    s: &Tensor<f32>,
    lse: &Tensor<f32>,
    p: &mut Tensor<f32>,
    cols: u32,
    len: u32,
    scale: f32,
) {
    let i = ABSOLUTE_POS as u32;
    if i >= len {
        terminate!();
    }
    p[i as usize] = f32::exp(s[i as usize] * scale - lse[(i / cols) as usize]);
}

/// `ds = p · (dp - delta[row]) · scale`: the softmax VJP carried back through the scale.
#[cube(launch)]
pub fn score_grad(
    p: &Tensor<f32>,
    dp: &Tensor<f32>,
    delta: &Tensor<f32>,
    ds: &mut Tensor<f32>,
    cols: u32,
    len: u32,
    scale: f32,
) {
    let i = ABSOLUTE_POS as u32;
    if i >= len {
        terminate!();
    }
    let at = i as usize;
    ds[at] = p[at] * (dp[at] - delta[(i / cols) as usize]) * scale;
}
