//! The LayerScale residual of every transformer block, `x + u ⊙ γ` (paper Sec. 3; the
//! backbone's blocks), as one backend op with its own autodiff node.
//!
//! Burn's ops take a product and a sum forward, and backward a product for `u`'s gradient
//! and a product and reductions over the broadcast axes for `γ`'s, each a launch and a
//! pass over the tokens; every block does this twice per pass (docs/PERFORMANCE.md, "Kernel
//! launches of a step on a GPU backend"). On the CubeCL backends the op is one kernel
//! forward and one backward (`kernels.rs`; a reduction more past [`kernels::GAIN_ROWS`]
//! rows). `u`'s gradient rounds exactly as Burn's product, and the forward as Burn's
//! product then sum on wgpu (CUDA may contract the two into one fused multiply-add);
//! `γ`'s sums in another order. The CPU backend keeps Burn's ops.

mod cube;
pub mod kernels;

use burn::backend::autodiff::checkpoint::{base::Checkpointer, strategy::CheckpointStrategy};
use burn::backend::autodiff::grads::Gradients;
use burn::backend::autodiff::ops::{Backward, Ops, OpsKind};
use burn::backend::autodiff::Autodiff;
use burn::backend::tensor::FloatTensor;
use burn::backend::Dispatch;
use burn::backend::{backend_extension, Backend, TensorMetadata};
use burn::tensor::{DType, Device, Shape, Tensor};

use super::norm::along_last;
use std::sync::atomic::{AtomicBool, Ordering};

/// Whether the CubeCL backends take the fused residual (on by default; the benchmarks'
/// `--residual burn` turns it off to measure Burn's ops).
static FUSED: AtomicBool = AtomicBool::new(true);

/// Switches the fused residual on or off for the whole process.
pub fn set_fused_residual(on: bool) {
    FUSED.store(on, Ordering::Relaxed);
}

/// Whether the fused residual is on ([`set_fused_residual`]).
pub fn fused_residual_on() -> bool {
    FUSED.load(Ordering::Relaxed)
}

/// `y = x + u ⊙ γ` over tokens `[.., C]` and a gain `[C]`.
#[backend_extension(Cube, Flex, Autodiff)]
pub trait ScaledResidualOps: Backend {
    /// `x + u · γ`, γ broadcast along the last axis.
    fn scaled_residual_forward(
        x: FloatTensor<Self>,
        u: FloatTensor<Self>,
        gamma: FloatTensor<Self>,
    ) -> FloatTensor<Self> {
        decomposed_forward::<Self>(x, u, gamma)
    }

    /// `(grad · γ, Σ_rows grad · u)`: the gradients of `u` and, with `gain`, of `γ` (else a
    /// placeholder of γ's shape, which the caller drops). `x`'s gradient is `grad` itself.
    fn scaled_residual_backward(
        grad: FloatTensor<Self>,
        u: FloatTensor<Self>,
        gamma: FloatTensor<Self>,
        gain: bool,
    ) -> (FloatTensor<Self>, FloatTensor<Self>) {
        decomposed_backward::<Self>(grad, u, gamma, gain)
    }
}

impl ScaledResidualOps for burn::backend::Flex {}

/// `γ [C]` as `[1, ..., 1, C]` of `like`'s rank.
fn broadcast_gain<B: Backend>(gamma: FloatTensor<B>, like: &FloatTensor<B>) -> FloatTensor<B> {
    along_last::<B>(gamma, like.shape().num_dims())
}

/// The residual in Burn's ops, the same two roundings as `x + u * γ` on tensors.
fn decomposed_forward<B: Backend>(
    x: FloatTensor<B>,
    u: FloatTensor<B>,
    gamma: FloatTensor<B>,
) -> FloatTensor<B> {
    let gain = broadcast_gain::<B>(gamma, &u);
    B::float_add(x, B::float_mul(u, gain))
}

/// The VJP in Burn's ops.
fn decomposed_backward<B: Backend>(
    grad: FloatTensor<B>,
    u: FloatTensor<B>,
    gamma: FloatTensor<B>,
    gain: bool,
) -> (FloatTensor<B>, FloatTensor<B>) {
    let du = B::float_mul(grad.clone(), broadcast_gain::<B>(gamma.clone(), &grad));
    if !gain {
        return (du, gamma);
    }
    let cols = gamma.shape().num_elements();
    let rows = grad.shape().num_elements() / cols.max(1);
    let products = B::float_reshape(B::float_mul(grad, u), Shape::new([rows, cols]));
    let dgamma = B::float_reshape(B::float_sum_dim(products, 0), Shape::new([cols]));
    (du, dgamma)
}

#[derive(Debug)]
struct ScaledResidualBackward;

impl<B: ScaledResidualOps> Backward<B, 3> for ScaledResidualBackward {
    /// `u` and γ (the residual stream `x` is not needed: the op is a sum in it).
    type State = (FloatTensor<B>, FloatTensor<B>);

    fn backward(self, ops: Ops<Self::State, 3>, grads: &mut Gradients, _: &mut Checkpointer) {
        let grad = grads.consume::<B>(&ops.node);
        let (u, gamma) = ops.state;
        let [x_node, u_node, gamma_node] = ops.parents;
        if u_node.is_some() || gamma_node.is_some() {
            let gain = gamma_node.is_some();
            let (du, dgamma) = B::scaled_residual_backward(grad.clone(), u, gamma, gain);
            if let Some(node) = u_node {
                grads.register::<B>(node.id, du);
            }
            if let Some(node) = gamma_node {
                grads.register::<B>(node.id, dgamma);
            }
        }
        if let Some(node) = x_node {
            grads.register::<B>(node.id, grad);
        }
    }
}

impl<B: ScaledResidualOps, C: CheckpointStrategy> ScaledResidualOps for Autodiff<B, C> {
    fn scaled_residual_forward(
        x: FloatTensor<Self>,
        u: FloatTensor<Self>,
        gamma: FloatTensor<Self>,
    ) -> FloatTensor<Self> {
        let tensors = [x, u, gamma];
        let nodes = tensors.each_ref().map(|t| t.node());
        let [x, u, gamma] = tensors.map(|t| t.into_primitive());
        let y = B::scaled_residual_forward(x, u.clone(), gamma.clone());
        match ScaledResidualBackward
            .prepare::<C>(nodes)
            .compute_bound()
            .stateful()
        {
            OpsKind::Tracked(prep) => prep.finish((u, gamma), y),
            OpsKind::UnTracked(prep) => prep.finish(y),
        }
    }

    fn scaled_residual_backward(
        grad: FloatTensor<Self>,
        u: FloatTensor<Self>,
        gamma: FloatTensor<Self>,
        gain: bool,
    ) -> (FloatTensor<Self>, FloatTensor<Self>) {
        let (du, dgamma) = B::scaled_residual_backward(
            grad.into_primitive(),
            u.into_primitive(),
            gamma.into_primitive(),
            gain,
        );
        let lift = <Self as burn::backend::AutodiffBackend>::from_inner;
        (lift(du), lift(dgamma))
    }
}

/// `x + u ⊙ γ` for tokens `x`, `u` of one shape and a gain `γ` as wide as their rows: the
/// fused op on a GPU (CubeCL) device in f32 with the switch on, Burn's ops elsewhere (the
/// CPU, f16, other shapes: the same values).
pub fn scaled_residual<const D: usize>(x: Tensor<D>, u: Tensor<D>, gamma: Tensor<1>) -> Tensor<D> {
    let f32s = [x.dtype(), u.dtype(), gamma.dtype()] == [DType::F32; 3];
    let fits = x.dims() == u.dims() && x.dims().last() == Some(&gamma.dims()[0]);
    if fused_residual_on() && f32s && fits && x.device() != Device::flex() {
        return Tensor::from_dispatch(<Dispatch as ScaledResidualOps>::scaled_residual_forward(
            x.into_dispatch(),
            u.into_dispatch(),
            gamma.into_dispatch(),
        ));
    }
    let mut gain = [1usize; D];
    gain[D - 1] = gamma.dims()[0];
    x + u * gamma.reshape(gain)
}
