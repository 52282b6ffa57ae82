//! Global gradient-norm clipping (PyTorch's `clip_grad_norm_`, which STORM's loop uses):
//! one norm over every trainable gradient, all scaled by the same factor. Burn's own
//! `GradientClipping::Norm` clips each parameter tensor separately, which changes the
//! update's direction; both are offered (`optim.grad_clip = "global_norm" | "norm"`).

use burn::module::{Module, ModuleVisitor, Param};
use burn::optim::GradientsParams;
use burn::tensor::Tensor;
use envision4d_model::host_read;

/// Added to the norm before dividing, as PyTorch does, so a zero gradient stays finite.
const NORM_EPS: f64 = 1e-6;

struct SquaredNorm<'a> {
    grads: &'a GradientsParams,
    acc: Option<Tensor<1>>,
}

impl ModuleVisitor for SquaredNorm<'_> {
    fn visit_float<const D: usize>(&mut self, p: &Param<Tensor<D>>) {
        if let Some(g) = self.grads.get::<D>(p.id) {
            let s = g.powf_scalar(2.0).sum();
            self.acc = Some(match self.acc.take() {
                None => s,
                Some(a) => a + s,
            });
        }
    }
}

struct Scale<'a> {
    grads: &'a mut GradientsParams,
    factor: f64,
}

impl ModuleVisitor for Scale<'_> {
    fn visit_float<const D: usize>(&mut self, p: &Param<Tensor<D>>) {
        if let Some(g) = self.grads.remove::<D>(p.id) {
            self.grads.register(p.id, g.mul_scalar(self.factor));
        }
    }
}

/// Scales `grads` so their global L2 norm is at most `max_norm`; returns the norm before
/// clipping (`None` when there is no gradient).
pub fn clip_global_norm<M: Module>(
    module: &M,
    grads: &mut GradientsParams,
    max_norm: f64,
) -> Option<f64> {
    let mut sq = SquaredNorm { grads, acc: None };
    module.visit(&mut sq);
    let norm = host_read::read(sq.acc?).iter::<f64>().next()?.sqrt();
    let factor = max_norm / (norm + NORM_EPS);
    if factor < 1.0 {
        module.visit(&mut Scale { grads, factor });
    }
    Some(norm)
}
