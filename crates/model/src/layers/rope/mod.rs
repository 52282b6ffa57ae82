//! 2D rotary position embedding of the VGGT aggregator (`RotaryPositionEmbedding2D`).
//!
//! Each head is split into a vertical half rotated by the token's row `y` and a horizontal
//! half rotated by its column `x`. Within a half of size `d`, frequencies are
//! `base^(-2m/d)`, angles are duplicated as `cat(a, a)`, and the rotation is the split-half
//! ("NeoX") form `v cos + rot(v) sin` with `rot(v) = cat(-v[d/2..], v[..d/2])`.
//!
//! On the GPU backends the rotation is one op with its own kernels (`ops.rs`); the CPU
//! backend runs Burn's ops.

mod cube;
pub mod kernels;
mod ops;

pub use ops::{fused_rope_on, rope_rotate, set_fused_rope, RopeOps};

use burn::tensor::{DType, Device, Tensor, TensorData};

/// RoPE frequency base of the aggregator (`rope_freq = 100`).
pub const ROPE_BASE: f32 = 100.0;

/// Precomputed cos/sin tables for one set of positions, shaped `[B, 1, N, head_dim]` so they
/// broadcast over heads. The sine carries `rot`'s signs: negated on the first quarter of
/// each half, so the rotation is a flip of quarters and two products, with no negation.
#[derive(Debug, Clone)]
pub struct RopeTables {
    pub cos: Tensor<4>,
    /// `-sin` on quarters 0 and 2 of a head, `sin` on quarters 1 and 3.
    pub signed_sin: Tensor<4>,
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
                    for sign in [-1.0f32, 1.0] {
                        for f in &inv_freq {
                            let a = p * f;
                            cos.push(a.cos());
                            sin.push(sign * a.sin());
                        }
                    }
                }
            }
        }
        let shape = [b, 1, n, head_dim];
        RopeTables {
            cos: Tensor::from_data(TensorData::new(cos, shape), device),
            signed_sin: Tensor::from_data(TensorData::new(sin, shape), device),
        }
    }

    /// The tables without autodiff tracking (the same values on an autodiff device's inner
    /// backend; unchanged elsewhere).
    pub fn inner(&self) -> Self {
        RopeTables {
            cos: self.cos.clone().inner(),
            signed_sin: self.signed_sin.clone().inner(),
        }
    }

    /// The tables in `dtype` (the dtype of the tokens they rotate).
    pub fn cast(self, dtype: DType) -> Self {
        RopeTables {
            cos: self.cos.cast(dtype),
            signed_sin: self.signed_sin.cast(dtype),
        }
    }

    /// Rotates `x` of shape `[B, heads, N, head_dim]`: on a GPU (CubeCL) device in f32 the
    /// fused op ([`rope_rotate`]), elsewhere Burn's ops.
    pub fn apply(&self, x: Tensor<4>) -> Tensor<4> {
        if fused_rope_on() && x.dtype() == DType::F32 && x.device() != Device::flex() {
            return rope_rotate(x, self.cos.clone(), self.signed_sin.clone());
        }
        let [b, h, n, d] = x.dims();
        let quarter = d / 4;
        // rot(v) per half: its two quarters q0 q1 -> (-q1, q0), i.e. the quarters swapped
        // (one flip of a [2 halves, 2 quarters] axis) and the sign taken by `signed_sin`.
        // The same products as negating first, bit for bit, in one kernel where four slices,
        // two negations and a concatenation took about eleven (and their backward as many).
        let swapped = x
            .clone()
            .reshape([b, h, n, 2, 2, quarter])
            .flip([4])
            .reshape([b, h, n, d]);
        x * self.cos.clone() + swapped * self.signed_sin.clone()
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

#[cfg(test)]
mod tests {
    use super::*;
    use burn::tensor::Distribution;

    /// The rotation written out as the reference writes it: `rot(v) = cat(-q1, q0, -q3,
    /// q2)` over a head's quarters, times the plain sine.
    fn by_concatenation(x: Tensor<4>, positions: &[Vec<[i64; 2]>], device: &Device) -> Tensor<4> {
        let [b, h, n, d] = x.dims();
        let t = RopeTables::new(positions, d, device);
        // Quarters 0 and 2 of the table hold -sin; undo it for the plain sine.
        let sign = Tensor::<1>::from_data(
            TensorData::new(
                (0..d)
                    .map(|i| if (i / (d / 4)) % 2 == 0 { -1.0f32 } else { 1.0 })
                    .collect(),
                [d],
            ),
            device,
        )
        .reshape([1, 1, 1, d]);
        let sin = t.signed_sin * sign;
        let parts = x.clone().reshape([b, h, n, 4, d / 4]);
        let q = |i: usize| parts.clone().slice([0..b, 0..h, 0..n, i..i + 1, 0..d / 4]);
        let rotated =
            Tensor::cat(vec![q(1).neg(), q(0), q(3).neg(), q(2)], 3).reshape([b, h, n, d]);
        x * t.cos + rotated * sin
    }

    /// Guards the flipped-quarter rotation: bit-identical to negating and concatenating
    /// quarters (a wrong flip axis, or a sign on the wrong quarters, changes every value),
    /// and so is its gradient.
    #[test]
    fn flipped_quarters_equal_the_concatenated_rotation() {
        let device = Device::flex().autodiff();
        let positions = vec![frame_positions(1, 3, 4), frame_positions(1, 3, 4)];
        let n = positions[0].len();
        let x = Tensor::<4>::random([2, 3, n, 16], Distribution::Normal(0.0, 1.0), &device);
        let tables = RopeTables::new(&positions, 16, &device);
        let weight = Tensor::<4>::random([2, 3, n, 16], Distribution::Normal(0.0, 1.0), &device);
        let run = |rotate: &dyn Fn(Tensor<4>) -> Tensor<4>| {
            let x = x.clone().require_grad();
            let y = rotate(x.clone());
            let grads = (y.clone() * weight.clone()).sum().backward();
            let g = x.grad(&grads).unwrap().into_data();
            (y.into_data(), g)
        };
        let (y, g) = run(&|x| tables.apply(x));
        let (y_ref, g_ref) = run(&|x| by_concatenation(x, &positions, &device));
        assert_eq!(y, y_ref, "rotation");
        assert_eq!(g, g_ref, "gradient");
    }
}
