//! The MLP's first layer after its matrix product, `gelu(z + b)` (the exact, erf GELU of
//! every backbone block; paper Sec. 3), as one backend op with its own autodiff node.
//!
//! Burn's `Linear` adds the bias as a kernel of its own, and on the CubeCL backends its
//! GELU is five kernels forward (a division, erf, a sum, a product, a division) and sixteen
//! backward; that backward is, moreover, the derivative of the *tanh* approximation, not of
//! the erf GELU it follows (about 1e-3 apart). Here the forward is one kernel and the
//! backward one (a reduction more past [`kernels::BIAS_ROWS`] rows), with the exact
//! derivative, and with Φ taken from erfc so the lower tail keeps its relative accuracy
//! (`kernels.rs`). Every block's MLP does this once per pass (docs/PERFORMANCE.md, "Kernel
//! launches of a step on a GPU backend").
//!
//! The CPU backend keeps Burn's ops (burn-flex differentiates the erf GELU exactly) and its
//! own inference kernel (`cpu_gelu`); parity with the official code is checked there.

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

use super::cpu_gelu::gelu;
use super::norm::along_last;
use std::sync::atomic::{AtomicBool, Ordering};

/// Whether the CubeCL backends take the fused bias and GELU (on by default; the benchmarks'
/// `--gelu burn` turns it off to measure Burn's ops).
static FUSED: AtomicBool = AtomicBool::new(true);

/// Switches the fused bias and GELU on or off for the whole process.
pub fn set_fused_gelu(on: bool) {
    FUSED.store(on, Ordering::Relaxed);
}

/// Whether the fused bias and GELU is on ([`set_fused_gelu`]).
pub fn fused_gelu_on() -> bool {
    FUSED.load(Ordering::Relaxed)
}

/// `y = gelu(z + b)` over pre-activations `[.., C]` and a bias `[C]`.
#[backend_extension(Cube, Flex, Autodiff)]
pub trait BiasGeluOps: Backend {
    /// `gelu(z + b)`, b broadcast along the last axis.
    fn bias_gelu_forward(z: FloatTensor<Self>, bias: FloatTensor<Self>) -> FloatTensor<Self> {
        decomposed_forward::<Self>(z, bias)
    }

    /// `(grad · gelu'(z + b), Σ_rows of that)`: the gradients of `z` and, with `bias_grad`,
    /// of `b` (else a placeholder of b's shape, which the caller drops).
    fn bias_gelu_backward(
        grad: FloatTensor<Self>,
        z: FloatTensor<Self>,
        bias: FloatTensor<Self>,
        bias_grad: bool,
    ) -> (FloatTensor<Self>, FloatTensor<Self>) {
        decomposed_backward::<Self>(grad, z, bias, bias_grad)
    }
}

impl BiasGeluOps for burn::backend::Flex {}

/// `z + b` in Burn's ops.
fn pre_activation<B: Backend>(z: FloatTensor<B>, bias: FloatTensor<B>) -> FloatTensor<B> {
    let rank = z.shape().num_dims();
    B::float_add(z, along_last::<B>(bias, rank))
}

/// The op in Burn's ops: its add and GELU.
fn decomposed_forward<B: Backend>(z: FloatTensor<B>, bias: FloatTensor<B>) -> FloatTensor<B> {
    B::gelu(pre_activation::<B>(z, bias))
}

/// The VJP in Burn's ops: its GELU backward (exact on burn-flex, the tanh approximation's
/// on CubeCL, where only inputs the kernels cannot take come here) and a row sum.
fn decomposed_backward<B: Backend>(
    grad: FloatTensor<B>,
    z: FloatTensor<B>,
    bias: FloatTensor<B>,
    bias_grad: bool,
) -> (FloatTensor<B>, FloatTensor<B>) {
    let dz = B::gelu_backward(pre_activation::<B>(z, bias.clone()), grad);
    if !bias_grad {
        return (dz, bias);
    }
    let cols = bias.shape().num_elements();
    let rows = dz.shape().num_elements() / cols.max(1);
    let flat = B::float_reshape(dz.clone(), Shape::new([rows, cols]));
    let dbias = B::float_reshape(B::float_sum_dim(flat, 0), Shape::new([cols]));
    (dz, dbias)
}

#[derive(Debug)]
struct BiasGeluBackward;

impl<B: BiasGeluOps> Backward<B, 2> for BiasGeluBackward {
    /// `z` and `b` (the pre-activation is recomputed in the backward kernel: one sum).
    type State = (FloatTensor<B>, FloatTensor<B>);

    fn backward(self, ops: Ops<Self::State, 2>, grads: &mut Gradients, _: &mut Checkpointer) {
        let grad = grads.consume::<B>(&ops.node);
        let (z, bias) = ops.state;
        let [z_node, bias_node] = ops.parents;
        if z_node.is_none() && bias_node.is_none() {
            return;
        }
        let (dz, dbias) = B::bias_gelu_backward(grad, z, bias, bias_node.is_some());
        if let Some(node) = z_node {
            grads.register::<B>(node.id, dz);
        }
        if let Some(node) = bias_node {
            grads.register::<B>(node.id, dbias);
        }
    }
}

impl<B: BiasGeluOps, C: CheckpointStrategy> BiasGeluOps for Autodiff<B, C> {
    fn bias_gelu_forward(z: FloatTensor<Self>, bias: FloatTensor<Self>) -> FloatTensor<Self> {
        let tensors = [z, bias];
        let nodes = tensors.each_ref().map(|t| t.node());
        let [z, bias] = tensors.map(|t| t.into_primitive());
        let y = B::bias_gelu_forward(z.clone(), bias.clone());
        match BiasGeluBackward
            .prepare::<C>(nodes)
            .compute_bound()
            .stateful()
        {
            OpsKind::Tracked(prep) => prep.finish((z, bias), y),
            OpsKind::UnTracked(prep) => prep.finish(y),
        }
    }

    fn bias_gelu_backward(
        grad: FloatTensor<Self>,
        z: FloatTensor<Self>,
        bias: FloatTensor<Self>,
        bias_grad: bool,
    ) -> (FloatTensor<Self>, FloatTensor<Self>) {
        let (dz, dbias) = B::bias_gelu_backward(
            grad.into_primitive(),
            z.into_primitive(),
            bias.into_primitive(),
            bias_grad,
        );
        let lift = <Self as burn::backend::AutodiffBackend>::from_inner;
        (lift(dz), lift(dbias))
    }
}

/// The fused op's own conditions: the switch on, every operand in f32, a GPU (CubeCL)
/// device.
fn fuses(dtypes: &[DType], device: &Device) -> bool {
    fused_gelu_on() && dtypes.iter().all(|d| *d == DType::F32) && *device != Device::flex()
}

/// Whether [`linear_gelu`] takes the fused op for this input and layer: a bias as wide as
/// the output, and [`bias_gelu`]'s conditions for the input and parameters.
pub fn takes_fused<const D: usize>(x: &Tensor<D>, layer: &Linear) -> bool {
    let Some(bias) = &layer.bias else {
        return false;
    };
    let fits = bias.dims()[0] == layer.weight.dims()[1];
    fits && fuses(
        &[x.dtype(), layer.weight.dtype(), bias.dtype()],
        &x.device(),
    )
}

/// `gelu(z + b)` for pre-activations `z` and a bias `b` as wide as their rows: the fused op
/// on a GPU (CubeCL) device in f32 with the switch on, Burn's sum and GELU elsewhere.
pub fn bias_gelu<const D: usize>(z: Tensor<D>, bias: Tensor<1>) -> Tensor<D> {
    let fits = z.dims().last() == Some(&bias.dims()[0]);
    if fits && fuses(&[z.dtype(), bias.dtype()], &z.device()) {
        return Tensor::from_dispatch(<Dispatch as BiasGeluOps>::bias_gelu_forward(
            z.into_dispatch(),
            bias.into_dispatch(),
        ));
    }
    let mut wide = [1usize; D];
    wide[D - 1] = bias.dims()[0];
    gelu(z + bias.reshape(wide))
}

/// `gelu(layer(x))`, the exact (erf) GELU: the matrix product then [`bias_gelu`] where
/// [`takes_fused`], else Burn's `Linear` and the GELU of [`gelu`] (the CPU inference
/// kernel, or Burn's op).
pub fn linear_gelu<const D: usize>(layer: &Linear, x: Tensor<D>) -> Tensor<D> {
    match &layer.bias {
        Some(bias) if takes_fused(&x, layer) => {
            bias_gelu(linear(x, layer.weight.val(), None), bias.val())
        }
        _ => gelu(layer.forward(x)),
    }
}
