//! The packed projection's split into heads and the merge of the heads' gradients back into
//! its layout, as backend ops so the CubeCL backends can take each in one kernel
//! ([`kernels`]); elsewhere Burn's views, slices and slice assignments, as below.

mod cube;
pub mod kernels;

use burn::backend::tensor::FloatTensor;
use burn::backend::{Backend, TensorMetadata};
use burn::tensor::{Shape, Slice};
use std::sync::atomic::{AtomicBool, Ordering};

/// Whether the CubeCL backends take the kernels (on by default; the benchmarks' `--split
/// burn` turns them off to measure Burn's views and slices in the same binary).
static KERNELS: AtomicBool = AtomicBool::new(true);

/// Switches the kernels on or off for the whole process.
pub fn set_heads_kernels(on: bool) {
    KERNELS.store(on, Ordering::Relaxed);
}

/// Whether the kernels are on ([`set_heads_kernels`]).
pub fn heads_kernels_on() -> bool {
    KERNELS.load(Ordering::Relaxed)
}

/// Split and merge of the packed `[B, N, 3C]` projection (the 3C axis `[q | k | v]`, each
/// H heads of d) and the three head tensors `[B, H, N, d]`. Both only move values, so every
/// backend gives the same values.
pub trait HeadsOps: Backend {
    /// q, k, v `[B, H, N, d]` from `qkv` `[B, N, 3C]`.
    fn split_heads(qkv: FloatTensor<Self>, heads: usize) -> [FloatTensor<Self>; 3] {
        split::<Self>(qkv, heads)
    }

    /// `[B, N, 3C]` from the three `[B, H, N, d]` parts.
    fn merge_heads(parts: [FloatTensor<Self>; 3]) -> FloatTensor<Self> {
        merge::<Self>(parts)
    }
}

impl HeadsOps for burn::backend::Flex {}
impl HeadsOps for burn::backend::Dispatch {}
impl<B: Backend, C: burn::backend::autodiff::checkpoint::strategy::CheckpointStrategy> HeadsOps
    for burn::backend::Autodiff<B, C>
{
}

/// `[B, N, 3C]` → q, k, v `[B, H, N, d]`: the views and copies the separate nodes make
/// (a reshape, a permutation to `[3, B, H, N, d]`, a slice and a reshape each).
pub(crate) fn split<B: Backend>(qkv: FloatTensor<B>, heads: usize) -> [FloatTensor<B>; 3] {
    let s = qkv.shape();
    let (b, n, d) = (s[0], s[1], s[2] / 3 / heads);
    let packed = B::float_permute(
        B::float_reshape(qkv, Shape::new([b, n, 3, heads, d])),
        &[2, 0, 3, 1, 4],
    );
    [0, 1, 2].map(|i| {
        let part = B::float_slice(
            packed.clone(),
            &[
                Slice::from(i..i + 1),
                Slice::from(0..b),
                Slice::from(0..heads),
                Slice::from(0..n),
                Slice::from(0..d),
            ],
        );
        B::float_reshape(part, Shape::new([b, heads, n, d]))
    })
}

/// The gradients of q, k and v `[B, H, N, d]` in the projection's layout `[B, N, 3C]`: each
/// assigned, through a permuted view, into its third of one uninitialised buffer (which the
/// three cover), where the separate nodes fill three zero buffers and sum them.
pub(crate) fn merge<B: Backend>(parts: [FloatTensor<B>; 3]) -> FloatTensor<B> {
    let s = parts[0].shape();
    let (b, h, n, d) = (s[0], s[1], s[2], s[3]);
    let device = parts[0].device();
    let dtype = parts[0].dtype().into();
    let mut out = B::float_empty(Shape::new([b, n, 3, h, d]), &device, dtype);
    for (i, part) in parts.into_iter().enumerate() {
        let view = B::float_permute(
            B::float_reshape(part, Shape::new([b, 1, h, n, d])),
            &[0, 3, 1, 2, 4],
        );
        let slot = [
            Slice::from(0..b),
            Slice::from(0..n),
            Slice::from(i..i + 1),
            Slice::from(0..h),
            Slice::from(0..d),
        ];
        out = B::float_slice_assign(out, &slot, view);
    }
    B::float_reshape(out, Shape::new([b, n, 3 * h * d]))
}
