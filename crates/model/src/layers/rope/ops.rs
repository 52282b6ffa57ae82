//! The rotation as one backend op with its own autodiff node: on the CubeCL backends one
//! kernel forward and one backward (`cube.rs`), where Burn's ops take a flip, two products
//! and a sum forward and as many backward (a flip, two products, the accumulation), each a
//! launch and a pass over the tokens. Every frame and global block rotates q and k, so the
//! op runs four times per block and pass (docs/PERFORMANCE.md, "Kernel launches of a step on
//! a GPU backend"). The CPU backend keeps Burn's ops, whose results the reference parity was
//! checked on (`RopeTables::apply` routes there).

use burn::backend::autodiff::checkpoint::{base::Checkpointer, strategy::CheckpointStrategy};
use burn::backend::autodiff::grads::Gradients;
use burn::backend::autodiff::ops::{Backward, Ops, OpsKind};
use burn::backend::autodiff::Autodiff;
use burn::backend::tensor::FloatTensor;
use burn::backend::Dispatch;
use burn::backend::{backend_extension, Backend, TensorMetadata};
use burn::tensor::{Shape, Tensor};
use std::sync::atomic::{AtomicBool, Ordering};

/// Whether the CubeCL backends take the fused rotation (on by default; the benchmarks'
/// `--rope burn` turns it off to measure Burn's ops).
static FUSED: AtomicBool = AtomicBool::new(true);

/// Switches the fused rotation on or off for the whole process.
pub fn set_fused_rope(on: bool) {
    FUSED.store(on, Ordering::Relaxed);
}

/// Whether the fused rotation is on ([`set_fused_rope`]).
pub fn fused_rope_on() -> bool {
    FUSED.load(Ordering::Relaxed)
}

/// The rotation of `x [B, H, N, D]` by tables `cos` and `sin` of shape `[TB, 1, N, D]`
/// (`TB` = B or 1), `sin` signed per quarter as `RopeTables` keeps it.
#[backend_extension(Cube, Flex, Autodiff)]
pub trait RopeOps: Backend {
    /// `x · cos + swap(x) · sin`, `swap` exchanging quarters 0 and 1, 2 and 3 of each head.
    fn rope_forward(
        x: FloatTensor<Self>,
        cos: FloatTensor<Self>,
        sin: FloatTensor<Self>,
    ) -> FloatTensor<Self> {
        decomposed_forward::<Self>(x, cos, sin)
    }

    /// Its vector-Jacobian product: `grad · cos + swap(grad · sin)`.
    fn rope_backward(
        grad: FloatTensor<Self>,
        cos: FloatTensor<Self>,
        sin: FloatTensor<Self>,
    ) -> FloatTensor<Self> {
        decomposed_backward::<Self>(grad, cos, sin)
    }
}

impl RopeOps for burn::backend::Flex {}

/// `t` with quarters 0 and 1, 2 and 3 of its last axis exchanged: one flip of a
/// `[2 halves, 2 quarters]` view.
pub(super) fn swap_quarters<B: Backend>(t: FloatTensor<B>) -> FloatTensor<B> {
    let shape = t.shape();
    let dims = shape.to_vec();
    let (lead, d) = dims.split_at(dims.len() - 1);
    let quarter = d[0] / 4;
    let view: Vec<usize> = lead.iter().copied().chain([2, 2, quarter]).collect();
    let axis = view.len() - 2;
    let flipped = B::float_flip(B::float_reshape(t, Shape::from(view)), &[axis]);
    B::float_reshape(flipped, shape)
}

/// The rotation in Burn's ops, the same products as `RopeTables::apply` on the CPU.
pub(super) fn decomposed_forward<B: Backend>(
    x: FloatTensor<B>,
    cos: FloatTensor<B>,
    sin: FloatTensor<B>,
) -> FloatTensor<B> {
    let swapped = swap_quarters::<B>(x.clone());
    B::float_add(B::float_mul(x, cos), B::float_mul(swapped, sin))
}

/// The VJP in Burn's ops, as autodiff forms it from [`decomposed_forward`].
pub(super) fn decomposed_backward<B: Backend>(
    grad: FloatTensor<B>,
    cos: FloatTensor<B>,
    sin: FloatTensor<B>,
) -> FloatTensor<B> {
    let through_sin = swap_quarters::<B>(B::float_mul(grad.clone(), sin));
    B::float_add(B::float_mul(grad, cos), through_sin)
}

#[derive(Debug)]
struct RopeBackward;

impl<B: RopeOps> Backward<B, 1> for RopeBackward {
    /// The tables: the tokens themselves are not needed (the op is linear in them).
    type State = (FloatTensor<B>, FloatTensor<B>);

    fn backward(self, ops: Ops<Self::State, 1>, grads: &mut Gradients, _: &mut Checkpointer) {
        let grad = grads.consume::<B>(&ops.node);
        let (cos, sin) = ops.state;
        let [parent] = ops.parents;
        if let Some(node) = parent {
            grads.register::<B>(node.id, B::rope_backward(grad, cos, sin));
        }
    }
}

impl<B: RopeOps, C: CheckpointStrategy> RopeOps for Autodiff<B, C> {
    fn rope_forward(
        x: FloatTensor<Self>,
        cos: FloatTensor<Self>,
        sin: FloatTensor<Self>,
    ) -> FloatTensor<Self> {
        let nodes = [x.node()];
        let (x, cos, sin) = (
            x.into_primitive(),
            cos.into_primitive(),
            sin.into_primitive(),
        );
        let y = B::rope_forward(x, cos.clone(), sin.clone());
        // Tables are constants of the graph: no gradient flows to them.
        match RopeBackward.prepare::<C>(nodes).compute_bound().stateful() {
            OpsKind::Tracked(prep) => prep.finish((cos, sin), y),
            OpsKind::UnTracked(prep) => prep.finish(y),
        }
    }

    fn rope_backward(
        grad: FloatTensor<Self>,
        cos: FloatTensor<Self>,
        sin: FloatTensor<Self>,
    ) -> FloatTensor<Self> {
        let g = B::rope_backward(
            grad.into_primitive(),
            cos.into_primitive(),
            sin.into_primitive(),
        );
        <Self as burn::backend::AutodiffBackend>::from_inner(g)
    }
}

/// The op on `x [B, H, N, D]` through the dispatch backend.
pub fn rope_rotate(x: Tensor<4>, cos: Tensor<4>, sin: Tensor<4>) -> Tensor<4> {
    Tensor::from_dispatch(<Dispatch as RopeOps>::rope_forward(
        x.into_dispatch(),
        cos.into_dispatch(),
        sin.into_dispatch(),
    ))
}
