//! Frozen transformer blocks that keep nothing for the backward but their input.
//!
//! In the paper's training (§3.2, §3.4) the VGGT blocks are frozen, yet the in-layer
//! temporal blocks feed their outputs into the next frozen layer, so the gradient of every
//! later head flows back through the frozen frame and global blocks after the first temporal
//! layer (layers 5–23 of 24). Autodiff keeps every intermediate of those blocks: for the
//! 1 860 tokens of a clip's 2 context frames at 350x518, well over 100 MB per block and
//! several GB over the 38 blocks (docs/PERFORMANCE.md, "Memory model").
//!
//! A recomputed block runs its forward without a graph and records one node that keeps the
//! block's input. Its backward runs the block's forward again on a private graph, from that
//! input, and takes the vector-Jacobian product there (one block's intermediates live at a
//! time). The weights are frozen, so the input gradient is all the outer graph needs. This is
//! block-level activation checkpointing (what PyTorch's `torch.utils.checkpoint` does per
//! block), which Burn's own strategies do not offer: its balanced strategy recomputes
//! memory-bound ops only and keeps every matmul output.

use super::block::Block;
use super::rope::RopeTables;
use burn::backend::autodiff::checkpoint::base::Checkpointer;
use burn::backend::autodiff::checkpoint::strategy::{
    BalancedCheckpointing, CheckpointStrategy, NoCheckpointing,
};
use burn::backend::autodiff::grads::Gradients;
use burn::backend::autodiff::ops::{Backward, Ops, OpsKind};
use burn::backend::{Autodiff, Backend, BackendTensor, DispatchKindConversion, DispatchTensor};
use burn::module::{Module, ModuleVisitor, Param};
use burn::tensor::Tensor;

/// Whether no parameter of `block` takes a gradient (the training freeze list marks them).
pub fn is_frozen(block: &Block) -> bool {
    struct AnyTrainable(bool);
    impl ModuleVisitor for AnyTrainable {
        fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
            self.0 |= param.val().is_require_grad();
        }
    }
    let mut v = AnyTrainable(false);
    block.visit(&mut v);
    !v.0
}

/// What the backward needs: the block's weights and RoPE tables (inner, non-autodiff tensors:
/// shared with the model, not copies) and the block's input.
#[derive(Clone, Debug)]
struct Recompute {
    block: Block,
    rope: Option<RopeTables>,
    input: Tensor<3>,
}

impl Recompute {
    /// `∂⟨block(x), grad⟩/∂x` at the kept input, on a graph of its own.
    fn input_gradient(&self, grad: Tensor<3>) -> Tensor<3> {
        let x = Tensor::from_inner(self.input.clone()).require_grad();
        let y = self.block.forward(x.clone(), self.rope.as_ref());
        let grads = (y * Tensor::from_inner(grad)).sum().backward();
        x.grad(&grads)
            .expect("a recomputed block's output depends on its input")
    }
}

#[derive(Debug)]
struct RecomputeBackward;

impl<B: Backend> Backward<B, 1> for RecomputeBackward
where
    DispatchTensor: DispatchKindConversion<B>,
{
    type State = Recompute;

    fn backward(self, ops: Ops<Recompute, 1>, grads: &mut Gradients, _: &mut Checkpointer) {
        let grad = grads.consume::<B>(&ops.node);
        let [parent] = ops.parents;
        let Some(node) = parent else {
            return;
        };
        let grad = Tensor::from_dispatch(
            <DispatchTensor as DispatchKindConversion<B>>::from_backend(BackendTensor::Float(grad)),
        );
        let dx = ops.state.input_gradient(grad);
        let dx =
            <DispatchTensor as DispatchKindConversion<B>>::try_into_backend(dx.into_dispatch())
                .expect("the recomputed gradient lives on the block's backend")
                .float();
        grads.register::<B>(node.id, dx);
    }
}

/// Attaches `output` (computed without a graph) to `input` through a [`RecomputeBackward`]
/// node, when `input` is an autodiff tensor of backend `B` with strategy `C`; `None`
/// otherwise.
fn attach<B: Backend, C: CheckpointStrategy>(
    input: &DispatchTensor,
    output: &DispatchTensor,
    state: &Recompute,
) -> Option<DispatchTensor>
where
    DispatchTensor: DispatchKindConversion<B> + DispatchKindConversion<Autodiff<B, C>>,
{
    let x =
        <DispatchTensor as DispatchKindConversion<Autodiff<B, C>>>::try_into_backend(input.clone())
            .ok()?
            .float();
    let y = <DispatchTensor as DispatchKindConversion<B>>::try_into_backend(output.clone())
        .expect("the block's output lives on its input's backend")
        .float();
    let out = match RecomputeBackward
        .prepare::<C>([x.node()])
        .compute_bound()
        .stateful()
    {
        OpsKind::Tracked(prep) => prep.finish(state.clone(), y),
        OpsKind::UnTracked(prep) => prep.finish(y),
    };
    Some(
        <DispatchTensor as DispatchKindConversion<Autodiff<B, C>>>::from_backend(
            BackendTensor::Float(out),
        ),
    )
}

/// `block.forward(x, rope)` keeping only `x` for the backward (see the module docs). For a
/// block whose parameters take no gradient, on an autodiff device; elsewhere it is the plain
/// forward. Values and input gradients equal the plain forward's to float rounding.
pub fn forward_recomputed(block: &Block, x: Tensor<3>, rope: Option<&RopeTables>) -> Tensor<3> {
    if !x.is_autodiff() {
        return block.forward(x, rope);
    }
    let state = Recompute {
        block: block.clone().valid(),
        rope: rope.map(RopeTables::inner),
        input: x.clone().inner(),
    };
    let output = state
        .block
        .forward(state.input.clone(), state.rope.as_ref())
        .into_dispatch();
    let x = x.into_dispatch();
    let y = attach::<burn::backend::Flex, NoCheckpointing>(&x, &output, &state)
        .or_else(|| attach::<burn::backend::Flex, BalancedCheckpointing>(&x, &output, &state))
        .or_else(|| attach::<burn::backend::Cube, NoCheckpointing>(&x, &output, &state))
        .or_else(|| attach::<burn::backend::Cube, BalancedCheckpointing>(&x, &output, &state))
        .unwrap_or_else(|| {
            panic!(
                "recomputed block on an unsupported backend: {:?}",
                Tensor::<3>::from_dispatch(x.clone()).device()
            )
        });
    Tensor::from_dispatch(y)
}
