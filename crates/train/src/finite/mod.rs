//! The NaN guard's finiteness check as a backend op: a pass over many tensors shares one
//! flag on the device and reads it once.
//!
//! Why: checked as `Σ x·0` in backend ops (`x·0` is 0 for every finite `x`, NaN otherwise,
//! and no magnitude overflows the sum), each tensor costs a product, a sum (one or two
//! kernels) and the accumulation, three or four launches, for every gradient and every
//! trainable parameter of a step. On GPU backends [`FiniteOps::flag_non_finite`] is one
//! kernel per tensor writing into the shared flag
//! ([`kernel::flag_non_finite`](fn@kernel::flag_non_finite)); the CPU keeps the sum, which is
//! what the decomposed body computes.

mod cube;
pub mod kernel;

use burn::backend::tensor::FloatTensor;
use burn::backend::Dispatch;
use burn::backend::{backend_extension, Backend, Scalar, TensorMetadata};
use burn::tensor::Tensor;

/// `flags` after checking `x`: unchanged when every entry of `x` is finite, non-zero (1, or
/// NaN on the decomposed path) otherwise. `flags` is `[1]` and starts at 0.
#[backend_extension(Cube, Flex, Autodiff)]
pub trait FiniteOps: Backend {
    fn flag_non_finite(x: FloatTensor<Self>, flags: FloatTensor<Self>) -> FloatTensor<Self> {
        decomposed::<Self>(x, flags)
    }
}

impl FiniteOps for burn::backend::Flex {}

/// The check reads values outside any graph: the autodiff backend runs the inner op.
impl<B: FiniteOps, C: burn::backend::autodiff::checkpoint::strategy::CheckpointStrategy> FiniteOps
    for burn::backend::autodiff::Autodiff<B, C>
{
    fn flag_non_finite(x: FloatTensor<Self>, flags: FloatTensor<Self>) -> FloatTensor<Self> {
        let out = B::flag_non_finite(x.into_primitive(), flags.into_primitive());
        <Self as burn::backend::AutodiffBackend>::from_inner(out)
    }
}

/// `flags + Σ x·0`, the sum cast to the flag's float type (backend ops do not convert).
fn decomposed<B: Backend>(x: FloatTensor<B>, flags: FloatTensor<B>) -> FloatTensor<B> {
    let zeroed = B::float_sum(B::float_mul_scalar(x, Scalar::Float(0.0)));
    let zeroed = if zeroed.dtype() == flags.dtype() {
        zeroed
    } else {
        B::float_cast(zeroed, flags.dtype().into())
    };
    B::float_add(flags, zeroed)
}

/// The flag of a new pass: `[1]` zero on `like`'s device.
pub fn new_flags<const D: usize>(like: &Tensor<D>) -> Tensor<1> {
    Tensor::zeros([1], &like.device())
}

/// [`FiniteOps::flag_non_finite`] on tensors: `flags` after checking `x` (detached first).
pub fn flag_non_finite<const D: usize>(x: Tensor<D>, flags: Tensor<1>) -> Tensor<1> {
    let out =
        <Dispatch as FiniteOps>::flag_non_finite(x.detach().into_dispatch(), flags.into_dispatch());
    Tensor::from_dispatch(out)
}
