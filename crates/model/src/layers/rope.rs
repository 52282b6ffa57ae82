//! 2D rotary position embedding of the VGGT aggregator (`RotaryPositionEmbedding2D`).
//!
//! Each head is split into a vertical half rotated by the token's row `y` and a horizontal
//! half rotated by its column `x`. Within a half of size `d`, frequencies are
//! `base^(-2m/d)`, angles are duplicated as `cat(a, a)`, and the rotation is the split-half
//! ("NeoX") form `v cos + rot(v) sin` with `rot(v) = cat(-v[d/2..], v[..d/2])`.

use burn::tensor::{DType, Device, Tensor, TensorData};

/// RoPE frequency base of the aggregator (`rope_freq = 100`).
pub const ROPE_BASE: f32 = 100.0;

/// Precomputed cos/sin tables for one set of positions, shaped `[B, 1, N, head_dim]` so they
/// broadcast over heads.
#[derive(Debug, Clone)]
pub struct RopeTables {
    pub cos: Tensor<4>,
    pub sin: Tensor<4>,
}

impl RopeTables {
    /// Tables for integer positions `(y, x)` of shape `[B][N]`, computed on the host in f32
    /// exactly as the reference does (f32 inverse frequencies, f32 angles).
    pub fn new(positions: &[Vec<[i64; 2]>], head_dim: usize, device: &Device) -> Self {
        let half = head_dim / 2;
        let inv_freq: Vec<f32> = (0..half)
            .step_by(2)
            .map(|k| 1.0 / ROPE_BASE.powf(k as f32 / half as f32))
            .collect();
        let b = positions.len();
        let n = positions.first().map_or(0, |p| p.len());
        let mut cos = Vec::with_capacity(b * n * head_dim);
        let mut sin = Vec::with_capacity(b * n * head_dim);
        for batch in positions {
            for &[y, x] in batch {
                // Vertical half first (rotated by y), then horizontal (rotated by x).
                for p in [y as f32, x as f32] {
                    for _ in 0..2 {
                        for f in &inv_freq {
                            let a = p * f;
                            cos.push(a.cos());
                            sin.push(a.sin());
                        }
                    }
                }
            }
        }
        let shape = [b, 1, n, head_dim];
        RopeTables {
            cos: Tensor::from_data(TensorData::new(cos, shape), device),
            sin: Tensor::from_data(TensorData::new(sin, shape), device),
        }
    }

    /// The tables without autodiff tracking (the same values on an autodiff device's inner
    /// backend; unchanged elsewhere).
    pub fn inner(&self) -> Self {
        RopeTables {
            cos: self.cos.clone().inner(),
            sin: self.sin.clone().inner(),
        }
    }

    /// The tables in `dtype` (the dtype of the tokens they rotate).
    pub fn cast(self, dtype: DType) -> Self {
        RopeTables {
            cos: self.cos.cast(dtype),
            sin: self.sin.cast(dtype),
        }
    }

    /// Rotates `x` of shape `[B, heads, N, head_dim]`.
    pub fn apply(&self, x: Tensor<4>) -> Tensor<4> {
        let [b, h, n, d] = x.dims();
        let quarter = d / 4;
        // rot(v) per half: split every half into two quarters q0 q1 -> (-q1, q0).
        let parts = x.clone().reshape([b, h, n, 4, quarter]);
        let q = |i: usize| {
            parts
                .clone()
                .slice([0..b, 0..h, 0..n, i..i + 1, 0..quarter])
        };
        let rotated =
            Tensor::cat(vec![q(1).neg(), q(0), q(3).neg(), q(2)], 3).reshape([b, h, n, d]);
        x * self.cos.clone() + rotated * self.sin.clone()
    }
}

/// The aggregator's token positions for one frame: `(0, 0)` for the `special` camera and
/// register tokens, then `(row + 1, col + 1)` for the patches, row-major.
pub fn frame_positions(special: usize, rows: usize, cols: usize) -> Vec<[i64; 2]> {
    let mut p = vec![[0i64, 0]; special];
    for y in 0..rows {
        for x in 0..cols {
            p.push([y as i64 + 1, x as i64 + 1]);
        }
    }
    p
}
