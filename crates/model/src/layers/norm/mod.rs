//! LayerNorm as one backend op with its own autodiff node, fused into CubeCL kernels on GPU
//! backends.
//!
//! Why: Burn 0.22 decomposes `LayerNorm` on CubeCL into nine kernels (two means, the
//! centring, the square root, the division, the affine), and autodiff differentiates each;
//! the tiny model's forward runs 306 of them (docs/PERFORMANCE.md, "Kernel launches of a
//! step on a GPU backend"). Here the forward is one kernel and the backward two (the input
//! gradient per row, the parameter gradients in chunks of rows), plus one sum each for
//! gamma and beta past one chunk; a frozen block's norm computes its input gradient only.
//! The node keeps the input and two numbers per row rather than every intermediate.
//!
//! The CPU backend keeps Burn's op ([`layer_norm`] routes it there): burn-flex has its own
//! row-wise kernel and its results are what parity with the official code is checked in.
//! The decomposed bodies below run wherever the kernels do not (other float types); the
//! tests hold the kernels and the node to them and to Burn's autodiff.

mod cube;
pub mod kernels;

use burn::backend::autodiff::checkpoint::{base::Checkpointer, strategy::CheckpointStrategy};
use burn::backend::autodiff::grads::Gradients;
use burn::backend::autodiff::ops::{Backward, Ops, OpsKind};
use burn::backend::autodiff::Autodiff;
use burn::backend::tensor::FloatTensor;
use burn::backend::Dispatch;
use burn::backend::{backend_extension, Backend, ExtensionType, Scalar, TensorMetadata};
use burn::module::{Content, DisplaySettings, ModuleDisplay};
use burn::nn::LayerNorm;
use burn::tensor::{DType, Device, Shape, Tensor};
use std::sync::atomic::{AtomicBool, Ordering};

/// Whether [`layer_norm`] takes the fused op on GPU backends (on by default; the benchmarks'
/// `--norm burn` turns it off to measure Burn's decomposition).
static FUSED: AtomicBool = AtomicBool::new(true);

/// Switches the fused op on or off for the whole process.
pub fn set_fused_layer_norm(on: bool) {
    FUSED.store(on, Ordering::Relaxed);
}

/// Whether the fused op is on ([`set_fused_layer_norm`]).
pub fn fused_layer_norm_on() -> bool {
    FUSED.load(Ordering::Relaxed)
}

/// Gradients of the input, `gamma` and `beta`.
#[derive(ExtensionType)]
pub struct NormGrads<B: Backend> {
    pub x: FloatTensor<B>,
    pub gamma: FloatTensor<B>,
    pub beta: FloatTensor<B>,
}

/// Which gradients a backward computes: a frozen block's norms need the input's only, and a
/// norm whose input is a constant its parameters' only.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NormNeeds {
    pub input: bool,
    /// gamma and beta.
    pub params: bool,
}

impl NormNeeds {
    pub const ALL: NormNeeds = NormNeeds {
        input: true,
        params: true,
    };
}

/// LayerNorm over the last axis. Shapes: x `[..., C]`, gamma and beta `[C]`; the row
/// statistics `mean` and `rstd = 1 / sqrt(var + eps)` (biased variance) are `[..., 1]`.
/// `mean` is in the form the same backend's backward reads: the decomposed bodies keep the
/// mean itself, the CubeCL kernels the mean minus each row's first value (see `kernels`).
#[backend_extension(Cube, Flex, Autodiff)]
pub trait FusedNormOps: Backend {
    /// `(y, mean, rstd)` with `y = (x - mean) · rstd · gamma + beta`.
    fn fused_layer_norm_forward(
        x: FloatTensor<Self>,
        gamma: FloatTensor<Self>,
        beta: FloatTensor<Self>,
        epsilon: f64,
    ) -> (FloatTensor<Self>, FloatTensor<Self>, FloatTensor<Self>) {
        decomposed_forward::<Self>(x, gamma, beta, epsilon)
    }

    /// Vector-Jacobian product of `y` w.r.t. x, gamma and beta, from the forward's stats;
    /// only the gradients `needs` asks for are computed (the others are placeholders of the
    /// right shape, which the caller drops).
    fn fused_layer_norm_backward(
        x: FloatTensor<Self>,
        gamma: FloatTensor<Self>,
        mean: FloatTensor<Self>,
        rstd: FloatTensor<Self>,
        grad: FloatTensor<Self>,
        needs: NormNeeds,
    ) -> NormGrads<Self> {
        decomposed_backward::<Self>(x, gamma, mean, rstd, grad, needs)
    }
}

impl FusedNormOps for burn::backend::Flex {}

/// `[C]` as `[1, ..., 1, C]` of the given rank, to broadcast over the rows.
pub(crate) fn along_last<B: Backend>(v: FloatTensor<B>, rank: usize) -> FloatTensor<B> {
    let c = v.shape().num_elements();
    let dims: Vec<usize> = (0..rank)
        .map(|i| if i + 1 == rank { c } else { 1 })
        .collect();
    B::float_reshape(v, Shape::from(dims))
}

/// `(x - mean) · rstd`.
fn normalised<B: Backend>(
    x: FloatTensor<B>,
    mean: FloatTensor<B>,
    rstd: FloatTensor<B>,
) -> FloatTensor<B> {
    B::float_mul(B::float_sub(x, mean), rstd)
}

/// Panics unless gamma and beta are as wide as the rows of `x`, naming the widths. The
/// backends do not check broadcasts, so a narrower parameter would be read past its end, by
/// the kernels and by the decomposed body alike. The backend ops check here, so callers that
/// skip [`fused_layer_norm`] (the packed attention) get the same check and message.
pub(crate) fn assert_widths(x: &Shape, gamma: &Shape, beta: &Shape) {
    let cols = x
        .to_vec()
        .last()
        .copied()
        .expect("LayerNorm of a rank-0 tensor");
    for (name, t) in [("gamma", gamma), ("beta", beta)] {
        let width = t.num_elements();
        assert_eq!(
            cols, width,
            "LayerNorm {name} of width {width} applied to rows of {cols}"
        );
    }
}

fn decomposed_forward<B: Backend>(
    x: FloatTensor<B>,
    gamma: FloatTensor<B>,
    beta: FloatTensor<B>,
    epsilon: f64,
) -> (FloatTensor<B>, FloatTensor<B>, FloatTensor<B>) {
    assert_widths(&x.shape(), &gamma.shape(), &beta.shape());
    let rank = x.shape().num_dims();
    let last = rank.checked_sub(1).expect("LayerNorm of a rank-0 tensor");
    let mean = B::float_mean_dim(x.clone(), last);
    let centred = B::float_sub(x, mean.clone());
    let var = B::float_mean_dim(B::float_mul(centred.clone(), centred.clone()), last);
    let rstd = B::float_recip(B::float_sqrt(B::float_add_scalar(
        var,
        Scalar::Float(epsilon),
    )));
    let y = B::float_add(
        B::float_mul(
            B::float_mul(centred, rstd.clone()),
            along_last::<B>(gamma, rank),
        ),
        along_last::<B>(beta, rank),
    );
    (y, mean, rstd)
}

fn decomposed_backward<B: Backend>(
    x: FloatTensor<B>,
    gamma: FloatTensor<B>,
    mean: FloatTensor<B>,
    rstd: FloatTensor<B>,
    grad: FloatTensor<B>,
    needs: NormNeeds,
) -> NormGrads<B> {
    let shape = x.shape();
    let rank = shape.num_dims();
    let last = rank.checked_sub(1).expect("LayerNorm of a rank-0 tensor");
    let cols = shape[last];
    let rows = shape.num_elements() / cols.max(1);
    let xhat = normalised::<B>(x, mean, rstd.clone());
    let dx = if needs.input {
        let g = B::float_mul(grad.clone(), along_last::<B>(gamma.clone(), rank));
        let mean_g = B::float_mean_dim(g.clone(), last);
        let mean_gx = B::float_mean_dim(B::float_mul(g.clone(), xhat.clone()), last);
        B::float_mul(
            rstd,
            B::float_sub(B::float_sub(g, mean_g), B::float_mul(xhat.clone(), mean_gx)),
        )
    } else {
        grad.clone()
    };
    let column_sum = |t: FloatTensor<B>| {
        let flat = B::float_reshape(t, Shape::new([rows, cols]));
        B::float_reshape(B::float_sum_dim(flat, 0), Shape::new([cols]))
    };
    let (dgamma, dbeta) = if needs.params {
        (
            column_sum(B::float_mul(grad.clone(), xhat)),
            column_sum(grad),
        )
    } else {
        (gamma.clone(), gamma)
    };
    NormGrads {
        x: dx,
        gamma: dgamma,
        beta: dbeta,
    }
}

#[derive(Debug)]
struct NormBackward;

impl<B: FusedNormOps> Backward<B, 3> for NormBackward {
    /// The input, gamma, and the row statistics.
    type State = [FloatTensor<B>; 4];

    fn backward(self, ops: Ops<Self::State, 3>, grads: &mut Gradients, _: &mut Checkpointer) {
        let grad = grads.consume::<B>(&ops.node);
        let [x, gamma, mean, rstd] = ops.state;
        let [input, gamma_node, beta_node] = ops.parents.each_ref().map(Option::is_some);
        let needs = NormNeeds {
            input,
            params: gamma_node || beta_node,
        };
        let g = B::fused_layer_norm_backward(x, gamma, mean, rstd, grad, needs);
        for (parent, grad) in ops.parents.into_iter().zip([g.x, g.gamma, g.beta]) {
            if let Some(node) = parent {
                grads.register::<B>(node.id, grad);
            }
        }
    }
}

impl<B: FusedNormOps, C: CheckpointStrategy> FusedNormOps for Autodiff<B, C> {
    fn fused_layer_norm_forward(
        x: FloatTensor<Self>,
        gamma: FloatTensor<Self>,
        beta: FloatTensor<Self>,
        epsilon: f64,
    ) -> (FloatTensor<Self>, FloatTensor<Self>, FloatTensor<Self>) {
        let tensors = [x, gamma, beta];
        let nodes = tensors.each_ref().map(|t| t.node());
        let [x, gamma, beta] = tensors.map(|t| t.into_primitive());
        let (y, mean, rstd) = B::fused_layer_norm_forward(x.clone(), gamma.clone(), beta, epsilon);
        let lift = <Self as burn::backend::AutodiffBackend>::from_inner;
        let (mean_out, rstd_out) = (lift(mean.clone()), lift(rstd.clone()));
        let y = match NormBackward.prepare::<C>(nodes).compute_bound().stateful() {
            OpsKind::Tracked(prep) => prep.finish([x, gamma, mean, rstd], y),
            OpsKind::UnTracked(prep) => prep.finish(y),
        };
        (y, mean_out, rstd_out)
    }

    fn fused_layer_norm_backward(
        x: FloatTensor<Self>,
        gamma: FloatTensor<Self>,
        mean: FloatTensor<Self>,
        rstd: FloatTensor<Self>,
        grad: FloatTensor<Self>,
        needs: NormNeeds,
    ) -> NormGrads<Self> {
        let g = B::fused_layer_norm_backward(
            x.into_primitive(),
            gamma.into_primitive(),
            mean.into_primitive(),
            rstd.into_primitive(),
            grad.into_primitive(),
            needs,
        );
        let lift = <Self as burn::backend::AutodiffBackend>::from_inner;
        NormGrads {
            x: lift(g.x),
            gamma: lift(g.gamma),
            beta: lift(g.beta),
        }
    }
}

/// The fused op on `(x, gamma, beta)`, through the dispatch backend: returns `y`.
///
/// # Panics
/// On a rank-0 `x`, or gamma or beta whose length is not the width of `x`'s rows, as
/// Burn's `LayerNorm` does (the kernels would read past gamma instead).
pub fn fused_layer_norm<const D: usize>(
    x: Tensor<D>,
    gamma: Tensor<1>,
    beta: Tensor<1>,
    epsilon: f64,
) -> Tensor<D> {
    assert!(D >= 1, "LayerNorm needs an input of rank 1 or more");
    assert_widths(&x.shape(), &gamma.shape(), &beta.shape());
    let (y, _mean, _rstd) = <Dispatch as FusedNormOps>::fused_layer_norm_forward(
        x.into_dispatch(),
        gamma.into_dispatch(),
        beta.into_dispatch(),
        epsilon,
    );
    Tensor::from_dispatch(y)
}

/// Whether [`layer_norm`] takes the fused op for an input of `dtype` on `device`: a GPU
/// (CubeCL) device, f32 or f16 (which Burn widens to f32 for the statistics, and so do we),
/// and the switch on.
pub fn takes_fused(device: &Device, dtype: DType) -> bool {
    fused_layer_norm_on() && *device != Device::flex() && matches!(dtype, DType::F32 | DType::F16)
}

/// `norm.forward(x)`: the fused op on GPU backends ([`takes_fused`]), Burn's elsewhere.
/// f16 inputs are normalised in f32 and narrowed back, as Burn's `LayerNorm` does.
pub fn layer_norm<const D: usize>(norm: &LayerNorm, x: Tensor<D>) -> Tensor<D> {
    let dtype = x.dtype();
    if !takes_fused(&x.device(), dtype) {
        return norm.forward(x);
    }
    let Some(epsilon) = epsilon_of(norm) else {
        return norm.forward(x);
    };
    // `fused_layer_norm` checks the widths, as Burn's forward does.
    let gamma = norm.gamma.val();
    let beta = match &norm.beta {
        Some(b) => b.val(),
        None => gamma.zeros_like(),
    };
    let wide = |t: Tensor<1>| t.cast(DType::F32);
    let y = fused_layer_norm(x.cast(DType::F32), wide(gamma), wide(beta), epsilon);
    y.cast(dtype)
}

/// The epsilon `norm` was built with. Burn keeps the field private and shows it only in the
/// module's display, as a formatted `f64` (Rust's shortest form that parses back to the same
/// value), so it is read from there; `None` if a Burn version stops showing it, and
/// [`layer_norm`] then takes Burn's op.
pub fn epsilon_of(norm: &LayerNorm) -> Option<f64> {
    let content = norm.custom_content(Content::new(DisplaySettings::new()))?;
    content
        .attributes
        .iter()
        .find(|a| a.name == "epsilon")
        .and_then(|a| a.value.parse().ok())
}
