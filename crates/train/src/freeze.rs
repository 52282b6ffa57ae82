//! Frozen parameter groups: their ids (whose gradients the optimiser never sees) and the
//! trainable/frozen parameter counts printed by `--dry-run`.

use crate::config::FreezeGroup;
use crate::finite;
use burn::module::{Module, ModuleMapper, ModuleVisitor, Param, ParamId};
use burn::tensor::{Gradients, Tensor};
use envision4d_model::host_read;
use envision4d_model::Envision4d;
use std::collections::HashSet;

#[derive(Default)]
struct Ids {
    ids: Vec<ParamId>,
    count: usize,
}

impl ModuleVisitor for Ids {
    fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
        self.ids.push(param.id);
        self.count += param.shape().num_elements();
    }
}

fn collect<M: Module>(m: &M, into: &mut Ids) {
    m.visit(into);
}

/// Ids and element count of one group.
fn group_ids(model: &Envision4d, group: FreezeGroup, out: &mut Ids) {
    let agg = &model.aggregator;
    match group {
        FreezeGroup::PatchEmbed => collect(&agg.patch_embed, out),
        FreezeGroup::FrameBlocks => collect(&agg.frame_blocks, out),
        FreezeGroup::GlobalBlocks => collect(&agg.global_blocks, out),
        FreezeGroup::Tokens => {
            out.visit_float(&agg.camera_token);
            out.visit_float(&agg.register_token);
        }
        FreezeGroup::CameraHead => collect(&model.camera_head, out),
        FreezeGroup::TimeBlocks => collect(&agg.time_blocks, out),
        FreezeGroup::FuturePose => collect(&model.future, out),
        FreezeGroup::DepthHead => collect(&model.depth_head, out),
        FreezeGroup::GsHead => collect(&model.gs_head, out),
        FreezeGroup::MotionHead => collect(&model.motion_head, out),
    }
}

/// The split of a model's parameters into frozen and trainable.
#[derive(Debug, Clone)]
pub struct ParamSplit {
    pub frozen: HashSet<ParamId>,
    pub trainable: Vec<ParamId>,
    pub frozen_count: usize,
    pub trainable_count: usize,
}

impl ParamSplit {
    pub fn new(model: &Envision4d, groups: &[FreezeGroup]) -> Self {
        // Walk the groups in the config's order, each once. Not a `HashSet`'s order: the walk
        // initialises lazy parameters, so its order decides which random draws each one
        // gets, and a per-process hash order made one seed give different initial weights.
        let mut frozen = Ids::default();
        let mut seen = Vec::with_capacity(groups.len());
        for &g in groups {
            if !seen.contains(&g) {
                seen.push(g);
                group_ids(model, g, &mut frozen);
            }
        }
        let mut all = Ids::default();
        collect(model, &mut all);
        let frozen_set: HashSet<ParamId> = frozen.ids.into_iter().collect();
        let trainable: Vec<ParamId> = all
            .ids
            .into_iter()
            .filter(|id| !frozen_set.contains(id))
            .collect();
        ParamSplit {
            frozen: frozen_set,
            trainable,
            frozen_count: frozen.count,
            trainable_count: all.count - frozen.count,
        }
    }
}

struct GradAbs<'a> {
    grads: &'a Gradients,
    sum: f64,
    found: bool,
}

impl ModuleVisitor for GradAbs<'_> {
    fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
        if let Some(g) = param.val().grad(self.grads) {
            self.found = true;
            self.sum += g
                .abs()
                .sum()
                .into_data()
                .iter::<f64>()
                .next()
                .unwrap_or(f64::NAN);
        }
    }
}

/// `Σ|∂L/∂θ|` over a module's parameters, `None` when none of them received a gradient.
pub fn grad_abs_sum<M: Module>(module: &M, grads: &Gradients) -> Option<f64> {
    let mut v = GradAbs {
        grads,
        sum: 0.0,
        found: false,
    };
    module.visit(&mut v);
    v.found.then_some(v.sum)
}

struct NonFinite<'a> {
    grads: Option<&'a Gradients>,
    /// Parameters not checked (the frozen ones after an update, which it cannot change).
    skip: Option<&'a HashSet<ParamId>>,
    /// The pass's flag on the device (one host sync at the end): 0 while every tensor seen
    /// is finite ([`crate::finite`]: on GPU backends one kernel per tensor sets it; on the
    /// CPU it accumulates `Σ x·0`, which is 0 for finite values and NaN otherwise, and which
    /// no magnitude can overflow). `is_finite().bool_not().float().sum()` took about nine
    /// kernels per tensor on a GPU backend, over every parameter tensor twice per step.
    bad: Option<Tensor<1>>,
}

impl NonFinite<'_> {
    fn add<const D: usize>(&mut self, t: Tensor<D>) {
        let flags = self.bad.take().unwrap_or_else(|| finite::new_flags(&t));
        self.bad = Some(finite::flag_non_finite(t, flags));
    }
    fn finite(self) -> bool {
        self.bad
            .is_none_or(|a| host_read::read(a).iter::<f64>().all(|c| c == 0.0))
    }
}

impl ModuleVisitor for NonFinite<'_> {
    fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
        if self.skip.is_some_and(|s| s.contains(&param.id)) {
            return;
        }
        let value = match self.grads {
            Some(grads) => param.val().grad(grads),
            None => Some(param.val().detach()),
        };
        if let Some(v) = value {
            self.add(v);
        }
    }
}

/// Whether every gradient of `module` in `grads` is finite.
pub fn grads_finite<M: Module>(module: &M, grads: &Gradients) -> bool {
    let mut v = NonFinite {
        grads: Some(grads),
        skip: None,
        bad: None,
    };
    module.visit(&mut v);
    v.finite()
}

/// Whether every parameter of `module` outside `frozen` is finite (checked after an
/// optimiser step, which changes only the others).
pub fn params_finite<M: Module>(module: &M, frozen: &HashSet<ParamId>) -> bool {
    let mut v = NonFinite {
        grads: None,
        skip: Some(frozen),
        bad: None,
    };
    module.visit(&mut v);
    v.finite()
}

struct NoGrad<'a>(&'a HashSet<ParamId>);

impl ModuleMapper for NoGrad<'_> {
    fn map_float<const D: usize>(&mut self, p: Param<Tensor<D>>) -> Param<Tensor<D>> {
        if self.0.contains(&p.id) {
            p.set_require_grad(false)
        } else {
            p
        }
    }
}

/// Marks the frozen parameters as not requiring gradients, so backward neither computes nor
/// stores their weight gradients (the paper config freezes 1.13 B of 1.38 B parameters).
pub fn detach_frozen(model: Envision4d, split: &ParamSplit) -> Envision4d {
    model.map(&mut NoGrad(&split.frozen))
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::tensor::{Device, TensorData};

    #[derive(Module, Debug)]
    struct Two {
        a: Param<Tensor<2>>,
        b: Param<Tensor<1>>,
    }

    fn two(a: Vec<f32>, b: Vec<f32>, device: &Device) -> Two {
        let n = a.len();
        let m = b.len();
        Two {
            a: Param::from_tensor(Tensor::from_data(TensorData::new(a, [1, n]), device)),
            b: Param::from_tensor(Tensor::from_data(TensorData::new(b, [m]), device)),
        }
    }

    /// Guards the finite checks of a step: NaN, +inf and -inf in any tensor are found, huge
    /// finite values (whose plain sum overflows f32) are not taken for infinities, and the
    /// post-update check skips exactly the frozen parameters; on the CPU (`Σ x·0`, whose sum
    /// must carry a NaN through) and on wgpu (lavapipe in CI; the flag kernel).
    #[test]
    fn finite_checks_find_every_non_finite_and_only_those() {
        let gpu = envision4d_splat::testkit::wgpu_test_device();
        for device in std::iter::once(Device::flex()).chain(gpu) {
            finite_checks_on(&device);
        }
    }

    fn finite_checks_on(device: &Device) {
        let huge = vec![f32::MAX, f32::MAX, -f32::MAX, 3.0e38];
        let none = HashSet::new();
        assert!(params_finite(
            &two(huge.clone(), vec![1.0, -0.0], device),
            &none
        ));
        for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            let mut b = vec![0.5, 2.0, -1.0];
            b[1] = bad;
            let m = two(huge.clone(), b, device);
            assert!(!params_finite(&m, &none), "{bad} in b not found");
            let frozen = HashSet::from([m.b.id]);
            assert!(params_finite(&m, &frozen), "{bad} in frozen b was checked");
            let frozen = HashSet::from([m.a.id]);
            assert!(
                !params_finite(&m, &frozen),
                "{bad} in b skipped with a frozen"
            );
        }
        // Gradients: the loss x·b reaches b only, with gradient x (here +inf at one entry).
        let ad = device.clone().autodiff();
        let m = two(vec![1.0], vec![1.0, 1.0], &ad);
        let x = Tensor::from_data(TensorData::new(vec![2.0f32, f32::INFINITY], [2]), &ad);
        let grads = (m.b.val() * x).sum().backward();
        assert!(!grads_finite(&m, &grads));
        let x = Tensor::from_data(TensorData::new(vec![2.0f32, f32::MAX], [2]), &ad);
        let grads = (m.b.val() * x).sum().backward();
        assert!(grads_finite(&m, &grads));
    }
}
