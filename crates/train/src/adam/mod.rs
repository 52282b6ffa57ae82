//! Adam as one kernel per parameter tensor on GPU backends, with Burn's state and record.
//!
//! Why: Burn's `Adam` updates a tensor with about thirteen elementwise kernels (moments,
//! square, square root, bias corrections, the step), nearly 4,000 launches per step for the
//! 293 tensors with a gradient of the tiny model on wgpu. [`FusedAdam`] keeps Burn's
//! `AdamState` (the same moments and step count under the same record keys, so checkpoints
//! load into either optimiser: a fused run resumes bit for bit, a switch of optimiser or
//! backend to rounding) and updates each tensor with one kernel
//! ([`kernel::adam_update`](fn@kernel::adam_update)). The CPU backend keeps Burn's `Adam`
//! itself, whose updates the CPU tests and the recorded runs were made with.

mod cube;
pub mod kernel;

use burn::backend::tensor::FloatTensor;
use burn::backend::Dispatch;
use burn::backend::{backend_extension, Backend, Scalar};
use burn::optim::{Adam, AdamConfig, AdamState, AdaptiveMomentumState, LearningRate, Optimizer};
use burn::tensor::{DType, Device, Tensor};
use std::sync::atomic::{AtomicBool, Ordering};

/// Whether [`FusedAdam`] runs its kernel on GPU backends (on by default; the step bench's
/// `--adam burn` turns it off to measure Burn's).
static FUSED: AtomicBool = AtomicBool::new(true);

/// Switches the fused update on or off for the whole process.
pub fn set_fused_adam(on: bool) {
    FUSED.store(on, Ordering::Relaxed);
}

/// One update's scalars, computed on the host as Burn's `Adam` computes them (f32).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AdamStep {
    pub beta_1: f32,
    pub beta_2: f32,
    /// `sqrt(1 - β₂ᵗ) / (1 - β₁ᵗ)`.
    pub factor: f32,
    /// `ε · sqrt(1 - β₂ᵗ)`.
    pub eps_hat: f32,
    pub lr: f32,
    /// The first step (`t = 1`): no moments to read.
    pub first: bool,
}

impl AdamStep {
    /// The scalars of step `time` (1-based) of Adam with these betas and epsilon.
    pub fn new(beta_1: f32, beta_2: f32, epsilon: f32, lr: LearningRate, time: usize) -> Self {
        let t = time as i32;
        let correction_2 = (1.0 - beta_2.powi(t)).sqrt();
        AdamStep {
            beta_1,
            beta_2,
            factor: correction_2 / (1.0 - beta_1.powi(t)),
            eps_hat: epsilon * correction_2,
            lr: lr as f32,
            first: time == 1,
        }
    }
}

/// The update as a backend op: `(param, moment_1, moment_2)` after one step. On the first
/// step `moment_1` and `moment_2` are not read (callers pass the gradient).
#[backend_extension(Cube, Flex, Autodiff)]
pub trait AdamOps: Backend {
    fn adam_update(
        param: FloatTensor<Self>,
        grad: FloatTensor<Self>,
        moment_1: FloatTensor<Self>,
        moment_2: FloatTensor<Self>,
        step: AdamStep,
    ) -> (FloatTensor<Self>, FloatTensor<Self>, FloatTensor<Self>) {
        decomposed::<Self>(param, grad, moment_1, moment_2, step)
    }
}

impl AdamOps for burn::backend::Flex {}

/// Parameters are updated outside any graph: the autodiff backend runs the inner op.
impl<B: AdamOps, C: burn::backend::autodiff::checkpoint::strategy::CheckpointStrategy> AdamOps
    for burn::backend::autodiff::Autodiff<B, C>
{
    fn adam_update(
        param: FloatTensor<Self>,
        grad: FloatTensor<Self>,
        moment_1: FloatTensor<Self>,
        moment_2: FloatTensor<Self>,
        step: AdamStep,
    ) -> (FloatTensor<Self>, FloatTensor<Self>, FloatTensor<Self>) {
        let (p, m, v) = B::adam_update(
            param.into_primitive(),
            grad.into_primitive(),
            moment_1.into_primitive(),
            moment_2.into_primitive(),
            step,
        );
        let lift = <Self as burn::backend::AutodiffBackend>::from_inner;
        (lift(p), lift(m), lift(v))
    }
}

/// The update in backend ops, in the kernel's order (the reference its tests hold it to, and
/// what other float types run).
fn decomposed<B: Backend>(
    param: FloatTensor<B>,
    grad: FloatTensor<B>,
    moment_1: FloatTensor<B>,
    moment_2: FloatTensor<B>,
    s: AdamStep,
) -> (FloatTensor<B>, FloatTensor<B>, FloatTensor<B>) {
    let f = |x: f32| Scalar::Float(f64::from(x));
    let mut m = B::float_mul_scalar(grad.clone(), f(1.0 - s.beta_1));
    let mut v = B::float_mul_scalar(B::float_mul(grad.clone(), grad), f(1.0 - s.beta_2));
    if !s.first {
        m = B::float_add(B::float_mul_scalar(moment_1, f(s.beta_1)), m);
        v = B::float_add(B::float_mul_scalar(moment_2, f(s.beta_2)), v);
    }
    let denom = B::float_add_scalar(B::float_sqrt(v.clone()), f(s.eps_hat));
    let delta = B::float_mul_scalar(
        B::float_div(B::float_mul_scalar(m.clone(), f(s.factor)), denom),
        f(s.lr),
    );
    (B::float_sub(param, delta), m, v)
}

/// Adam without weight decay or AMSGrad (what training configures), with Burn's state.
#[derive(Clone)]
pub struct FusedAdam {
    beta_1: f32,
    beta_2: f32,
    epsilon: f32,
    /// Burn's Adam with the same settings, for the CPU backend.
    burn: Adam,
}

impl FusedAdam {
    /// Burn's default betas (0.9, 0.999) and this epsilon.
    pub fn new(epsilon: f32) -> Self {
        FusedAdam {
            beta_1: 0.9,
            beta_2: 0.999,
            epsilon,
            burn: AdamConfig::new().with_epsilon(epsilon).build(),
        }
    }

    /// Whether a tensor on `device` of `dtype` takes the kernel.
    pub fn takes_fused(device: &Device, dtype: DType) -> bool {
        FUSED.load(Ordering::Relaxed) && *device != Device::flex() && dtype == DType::F32
    }
}

impl Optimizer for FusedAdam {
    type State<const D: usize> = AdamState<D>;

    fn step<const D: usize>(
        &self,
        lr: LearningRate,
        tensor: Tensor<D>,
        grad: Tensor<D>,
        state: Option<Self::State<D>>,
    ) -> (Tensor<D>, Option<Self::State<D>>) {
        if !Self::takes_fused(&tensor.device(), tensor.dtype()) {
            return self.burn.step(lr, tensor, grad, state);
        }
        let (time, m, v) = match state {
            Some(s) => (
                s.momentum.time + 1,
                s.momentum.moment_1,
                s.momentum.moment_2,
            ),
            None => (1, grad.clone(), grad.clone()),
        };
        let step = AdamStep::new(self.beta_1, self.beta_2, self.epsilon, lr, time);
        let (p, m, v) = <Dispatch as AdamOps>::adam_update(
            tensor.into_dispatch(),
            grad.into_dispatch(),
            m.into_dispatch(),
            v.into_dispatch(),
            step,
        );
        let momentum =
            AdaptiveMomentumState::new(time, Tensor::from_dispatch(m), Tensor::from_dispatch(v));
        (Tensor::from_dispatch(p), Some(AdamState::new(momentum)))
    }

    fn to_device<const D: usize>(mut state: Self::State<D>, device: &Device) -> Self::State<D> {
        state.momentum = state.momentum.to_device(device);
        state
    }
}
