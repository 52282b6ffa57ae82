//! Gradient norms per module group, as the training log records them.

use burn::module::{Module, ModuleVisitor, Param};
use burn::optim::GradientsParams;
use burn::tensor::{Device, Tensor};
use envision4d_model::{Envision4d, ModelConfig};
use envision4d_train::grad_clip::{grad_norms, GradGroup};

/// Sums every parameter of a module into one scalar.
struct SumAll(Option<Tensor<1>>);

impl ModuleVisitor for SumAll {
    fn visit_float<const D: usize>(&mut self, p: &Param<Tensor<D>>) {
        let s = p.val().sum();
        self.0 = Some(match self.0.take() {
            None => s,
            Some(a) => a + s,
        });
    }
}

fn sum_of<M: Module>(m: &M) -> Tensor<1> {
    let mut v = SumAll(None);
    m.visit(&mut v);
    v.0.expect("the module has parameters")
}

/// Guards the grouping of the log's `grad_norms` (a parameter filed under the wrong module
/// would hide where the rendering loss's signal goes): with loss = Σ motion-head params +
/// 2 Σ temporal-block params, every gradient is 1 or 2, so the motion head's norm is
/// sqrt(its parameter count), the temporal blocks' 2 sqrt(theirs), and no other group has a
/// gradient.
#[test]
fn gradient_norms_are_grouped_by_module() {
    let device = Device::flex().autodiff();
    let model = Envision4d::new(&ModelConfig::tiny(), &device);
    let loss = sum_of(&model.motion_head) + sum_of(&model.aggregator.time_blocks) * 2.0;
    let grads = GradientsParams::from_grads(loss.backward(), &model);
    let norms = grad_norms(&model, &grads).expect("gradients");
    let n_motion = model.motion_head.num_params() as f64;
    let n_time = model.aggregator.time_blocks.num_params() as f64;
    for (group, got) in GradGroup::ALL.into_iter().zip(norms.groups) {
        let want = match group {
            GradGroup::MotionHead => Some(n_motion.sqrt()),
            GradGroup::TimeBlocks => Some(2.0 * n_time.sqrt()),
            _ => None,
        };
        match (got, want) {
            (Some(g), Some(w)) => assert!((g - w).abs() < 1e-4 * w, "{}: {g} vs {w}", group.name()),
            (g, w) => assert_eq!(g, w, "{}", group.name()),
        }
    }
    let rms = norms.rms(GradGroup::TimeBlocks).unwrap();
    assert!(
        (rms - 2.0).abs() < 1e-4,
        "time blocks' gradient rms {rms}, every element 2"
    );
    let total = (n_motion + 4.0 * n_time).sqrt();
    assert!(
        (norms.total - total).abs() < 1e-4 * total,
        "{} vs {total}",
        norms.total
    );
}
