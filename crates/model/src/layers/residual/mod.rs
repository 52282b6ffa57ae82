//! The LayerScale residual of every transformer block, `x + (h W + b) ⊙ γ` (paper Sec. 3;
//! the backbone's blocks): after the matrix product of the projection before it (the
//! attention's `proj`, the MLP's `fc2`), its bias, the gain and the sum as one backend op
//! with its own autodiff node.
//!
//! Burn's ops take a bias sum, a product and a sum forward, and backward a product for the
//! projection's gradient and reductions over the broadcast axes for the bias's and `γ`'s,
//! each a launch and a pass over the tokens; every block does this twice per pass
//! (docs/PERFORMANCE.md, "Kernel launches of a step on a GPU backend"). On the CubeCL
//! backends the op is one kernel forward and one backward (`kernels.rs`; a reduction more
//! per parameter past [`kernels::GAIN_ROWS`] rows). The projection's gradient rounds
//! exactly as Burn's product, and the forward as Burn's bias sum, product and sum on wgpu
//! (CUDA may contract the last two into one fused multiply-add); the parameters' gradients
//! sum in another order. The CPU backend keeps Burn's ops.

mod cube;
pub mod kernels;

use burn::backend::autodiff::checkpoint::{base::Checkpointer, strategy::CheckpointStrategy};
use burn::backend::autodiff::grads::Gradients;
use burn::backend::autodiff::ops::{Backward, Ops, OpsKind};
use burn::backend::autodiff::Autodiff;
use burn::backend::tensor::FloatTensor;
use burn::backend::Dispatch;
use burn::backend::{backend_extension, Backend, TensorMetadata};
use burn::nn::Linear;
use burn::tensor::{module::linear, DType, Device, Shape, Tensor};

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

/// `y = x + (u + b) ⊙ γ` over tokens `[.., C]`, a bias `[C]` and a gain `[C]`.
#[backend_extension(Cube, Flex, Autodiff)]
pub trait ScaledResidualOps: Backend {
    /// `x + (u + b) · γ`, b and γ broadcast along the last axis.
    fn scaled_residual_forward(
        x: FloatTensor<Self>,
        u: FloatTensor<Self>,
        bias: FloatTensor<Self>,
        gamma: FloatTensor<Self>,
    ) -> FloatTensor<Self> {
        decomposed_forward::<Self>(x, u, bias, gamma)
    }

    /// `(grad · γ, Σ_rows grad · (u + b), Σ_rows grad · γ)`: the gradients of `u` and, when
    /// asked for (`gain`, `bias_grad`), of γ and b. `x`'s gradient is `grad` itself.
    fn scaled_residual_backward(
        grad: FloatTensor<Self>,
        u: FloatTensor<Self>,
        bias: FloatTensor<Self>,
        gamma: FloatTensor<Self>,
        gain: bool,
        bias_grad: bool,
    ) -> (
        FloatTensor<Self>,
        Option<FloatTensor<Self>>,
        Option<FloatTensor<Self>>,
    ) {
        decomposed_backward::<Self>(grad, u, bias, gamma, gain, bias_grad)
    }
}

impl ScaledResidualOps for burn::backend::Flex {}

/// A `[C]` parameter as `[1, ..., 1, C]` of `like`'s rank.
fn broadcast<B: Backend>(v: FloatTensor<B>, like: &FloatTensor<B>) -> FloatTensor<B> {
    along_last::<B>(v, like.shape().num_dims())
}

/// `u + b`, the projection's output, in Burn's op.
fn projected<B: Backend>(u: FloatTensor<B>, bias: FloatTensor<B>) -> FloatTensor<B> {
    let bias = broadcast::<B>(bias, &u);
    B::float_add(u, bias)
}

/// The residual in Burn's ops, the same three roundings as `x + (u + b) * γ` on tensors.
fn decomposed_forward<B: Backend>(
    x: FloatTensor<B>,
    u: FloatTensor<B>,
    bias: FloatTensor<B>,
    gamma: FloatTensor<B>,
) -> FloatTensor<B> {
    let gain = broadcast::<B>(gamma, &u);
    B::float_add(x, B::float_mul(projected::<B>(u, bias), gain))
}

/// Column sums `[C]` of `t` `[.., C]` in Burn's ops.
fn column_sums<B: Backend>(t: FloatTensor<B>, cols: usize) -> FloatTensor<B> {
    let rows = t.shape().num_elements() / cols.max(1);
    let t = B::float_reshape(t, Shape::new([rows, cols]));
    B::float_reshape(B::float_sum_dim(t, 0), Shape::new([cols]))
}

/// The VJP in Burn's ops.
fn decomposed_backward<B: Backend>(
    grad: FloatTensor<B>,
    u: FloatTensor<B>,
    bias: FloatTensor<B>,
    gamma: FloatTensor<B>,
    gain: bool,
    bias_grad: bool,
) -> (
    FloatTensor<B>,
    Option<FloatTensor<B>>,
    Option<FloatTensor<B>>,
) {
    let cols = gamma.shape().num_elements();
    let du = B::float_mul(grad.clone(), broadcast::<B>(gamma, &grad));
    let dgamma = gain.then(|| {
        let products = B::float_mul(grad, projected::<B>(u, bias));
        column_sums::<B>(products, cols)
    });
    let dbias = bias_grad.then(|| column_sums::<B>(du.clone(), cols));
    (du, dgamma, dbias)
}

#[derive(Debug)]
struct ScaledResidualBackward;

impl<B: ScaledResidualOps> Backward<B, 4> for ScaledResidualBackward {
    /// `u`, b and γ (the residual stream `x` is not needed: the op is a sum in it).
    type State = (FloatTensor<B>, FloatTensor<B>, FloatTensor<B>);

    fn backward(self, ops: Ops<Self::State, 4>, grads: &mut Gradients, _: &mut Checkpointer) {
        let grad = grads.consume::<B>(&ops.node);
        let (u, bias, gamma) = ops.state;
        let [x_node, u_node, bias_node, gamma_node] = ops.parents;
        if u_node.is_some() || bias_node.is_some() || gamma_node.is_some() {
            let (gain, bias_grad) = (gamma_node.is_some(), bias_node.is_some());
            let (du, dgamma, dbias) =
                B::scaled_residual_backward(grad.clone(), u, bias, gamma, gain, bias_grad);
            if let Some(node) = u_node {
                grads.register::<B>(node.id, du);
            }
            if let (Some(node), Some(d)) = (gamma_node, dgamma) {
                grads.register::<B>(node.id, d);
            }
            if let (Some(node), Some(d)) = (bias_node, dbias) {
                grads.register::<B>(node.id, d);
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
        bias: FloatTensor<Self>,
        gamma: FloatTensor<Self>,
    ) -> FloatTensor<Self> {
        let tensors = [x, u, bias, gamma];
        let nodes = tensors.each_ref().map(|t| t.node());
        let [x, u, bias, gamma] = tensors.map(|t| t.into_primitive());
        let y = B::scaled_residual_forward(x, u.clone(), bias.clone(), gamma.clone());
        match ScaledResidualBackward
            .prepare::<C>(nodes)
            .compute_bound()
            .stateful()
        {
            OpsKind::Tracked(prep) => prep.finish((u, bias, gamma), y),
            OpsKind::UnTracked(prep) => prep.finish(y),
        }
    }

    fn scaled_residual_backward(
        grad: FloatTensor<Self>,
        u: FloatTensor<Self>,
        bias: FloatTensor<Self>,
        gamma: FloatTensor<Self>,
        gain: bool,
        bias_grad: bool,
    ) -> (
        FloatTensor<Self>,
        Option<FloatTensor<Self>>,
        Option<FloatTensor<Self>>,
    ) {
        let (du, dgamma, dbias) = B::scaled_residual_backward(
            grad.into_primitive(),
            u.into_primitive(),
            bias.into_primitive(),
            gamma.into_primitive(),
            gain,
            bias_grad,
        );
        let lift = <Self as burn::backend::AutodiffBackend>::from_inner;
        (lift(du), dgamma.map(lift), dbias.map(lift))
    }
}

/// The fused op's own conditions: the switch on, every operand in f32, a GPU (CubeCL)
/// device.
fn fuses(dtypes: &[DType], device: &Device) -> bool {
    fused_residual_on() && dtypes.iter().all(|d| *d == DType::F32) && *device != Device::flex()
}

/// A `[C]` parameter's shape broadcast along the last axis of rank `D`.
fn along_last_dims<const D: usize>(c: usize) -> [usize; D] {
    let mut dims = [1usize; D];
    dims[D - 1] = c;
    dims
}

/// `x + (u + b) ⊙ γ` for tokens `x`, `u` of one shape and a bias and a gain as wide as
/// their rows: the fused op where [`fuses`] holds, Burn's ops elsewhere (the CPU, f16,
/// other shapes: the same values).
pub fn scaled_residual<const D: usize>(
    x: Tensor<D>,
    u: Tensor<D>,
    bias: Tensor<1>,
    gamma: Tensor<1>,
) -> Tensor<D> {
    let dtypes = [x.dtype(), u.dtype(), bias.dtype(), gamma.dtype()];
    let width = x.dims().last().copied();
    let fits =
        x.dims() == u.dims() && width == Some(gamma.dims()[0]) && width == Some(bias.dims()[0]);
    if fits && fuses(&dtypes, &x.device()) {
        return Tensor::from_dispatch(<Dispatch as ScaledResidualOps>::scaled_residual_forward(
            x.into_dispatch(),
            u.into_dispatch(),
            bias.into_dispatch(),
            gamma.into_dispatch(),
        ));
    }
    let wide = along_last_dims::<D>(gamma.dims()[0]);
    x + (u + bias.reshape(wide)) * gamma.reshape(wide)
}

/// `x + layer(h) ⊙ γ`, a block's residual after its projection `layer`: the matrix product
/// then [`scaled_residual`] with the layer's bias where [`fuses`] holds (every block's
/// projections have a bias); Burn's `Linear`, product and sum elsewhere.
pub fn projected_residual<const D: usize>(
    x: Tensor<D>,
    layer: &Linear,
    h: Tensor<D>,
    gamma: Tensor<1>,
) -> Tensor<D> {
    match &layer.bias {
        Some(bias)
            if fuses(
                &[
                    x.dtype(),
                    h.dtype(),
                    layer.weight.dtype(),
                    bias.dtype(),
                    gamma.dtype(),
                ],
                &x.device(),
            ) =>
        {
            scaled_residual(x, linear(h, layer.weight.val(), None), bias.val(), gamma)
        }
        _ => {
            let wide = along_last_dims::<D>(gamma.dims()[0]);
            x + layer.forward(h) * gamma.reshape(wide)
        }
    }
}
