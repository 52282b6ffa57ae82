//! Gradient norms per module group (logged every step) and global gradient-norm clipping
//! (PyTorch's `clip_grad_norm_`, which STORM's loop uses): one norm over every trainable
//! gradient, all scaled by the same factor. Burn's own `GradientClipping::Norm` clips each
//! parameter tensor separately, which changes the update's direction; both are offered
//! (`optim.grad_clip = "global_norm" | "norm"`).

use burn::module::{Module, ModuleVisitor, Param};
use burn::optim::GradientsParams;
use burn::tensor::Tensor;
use envision4d_model::host_read;

/// Added to the norm before dividing, as PyTorch does, so a zero gradient stays finite.
const NORM_EPS: f64 = 1e-6;

/// The parts of the network whose gradient norms the log keeps apart: the paper's trainable
/// modules, so a run shows where the rendering loss's signal goes (the motion head's share
/// against the Gaussian and depth heads'). Declared in [`GradGroup::ALL`]'s order, so a
/// group's index in the per-group arrays is its discriminant.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GradGroup {
    /// The temporal blocks inside the aggregator (`aggregator.time_blocks`).
    TimeBlocks,
    /// The future-pose module (`future`).
    FuturePose,
    CameraHead,
    DepthHead,
    GaussianHead,
    MotionHead,
    /// Everything else (the backbone, when a config trains it).
    Other,
}

impl GradGroup {
    pub const ALL: [GradGroup; 7] = [
        GradGroup::TimeBlocks,
        GradGroup::FuturePose,
        GradGroup::CameraHead,
        GradGroup::DepthHead,
        GradGroup::GaussianHead,
        GradGroup::MotionHead,
        GradGroup::Other,
    ];

    /// The key of the group in `log.jsonl`'s `grad_norms`.
    pub fn name(self) -> &'static str {
        match self {
            GradGroup::TimeBlocks => "time_blocks",
            GradGroup::FuturePose => "future",
            GradGroup::CameraHead => "camera_head",
            GradGroup::DepthHead => "depth_head",
            GradGroup::GaussianHead => "gs_head",
            GradGroup::MotionHead => "motion_head",
            GradGroup::Other => "other",
        }
    }

    /// The group of a parameter from the module path it sits under (official names).
    fn of(path: &[String]) -> GradGroup {
        match (
            path.first().map(String::as_str),
            path.get(1).map(String::as_str),
        ) {
            (Some("aggregator"), Some("time_blocks")) => GradGroup::TimeBlocks,
            (Some("future"), _) => GradGroup::FuturePose,
            (Some("camera_head"), _) => GradGroup::CameraHead,
            (Some("depth_head"), _) => GradGroup::DepthHead,
            (Some("gs_head"), _) => GradGroup::GaussianHead,
            (Some("motion_head"), _) => GradGroup::MotionHead,
            _ => GradGroup::Other,
        }
    }
}

/// The number of [`GradGroup`]s.
const GROUPS: usize = GradGroup::ALL.len();

/// L2 norms of one step's gradients, per [`GradGroup`] (in [`GradGroup::ALL`]'s order;
/// `None` for a group without any gradient) and over all of them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GradNorms {
    pub groups: [Option<f64>; GROUPS],
    /// Gradient elements per group.
    pub elements: [usize; GROUPS],
    pub total: f64,
}

impl GradNorms {
    /// A group's L2 norm (`None` without a gradient).
    pub fn norm(&self, group: GradGroup) -> Option<f64> {
        self.groups[group as usize]
    }

    /// The root mean square of a group's gradient elements (`norm / sqrt(elements)`), the
    /// scale Adam's ε is compared with.
    pub fn rms(&self, group: GradGroup) -> Option<f64> {
        Some(self.norm(group)? / (self.elements[group as usize].max(1) as f64).sqrt())
    }
}

struct SquaredNorms<'a> {
    grads: &'a GradientsParams,
    path: Vec<String>,
    acc: [Option<Tensor<1>>; GROUPS],
    elements: [usize; GROUPS],
}

impl ModuleVisitor for SquaredNorms<'_> {
    fn enter_module(&mut self, name: &str, _container_type: &str) {
        self.path.push(name.to_owned());
    }

    fn exit_module(&mut self, _name: &str, _container_type: &str) {
        self.path.pop();
    }

    fn visit_float<const D: usize>(&mut self, p: &Param<Tensor<D>>) {
        if let Some(g) = self.grads.get::<D>(p.id) {
            let elements = g.shape().num_elements();
            let s = g.powf_scalar(2.0).sum();
            let slot = GradGroup::of(&self.path) as usize;
            self.elements[slot] += elements;
            self.acc[slot] = Some(match self.acc[slot].take() {
                None => s,
                Some(a) => a + s,
            });
        }
    }
}

/// The gradient norms of `module`'s parameters in `grads`, in one host read (`None` when
/// there is no gradient).
pub fn grad_norms<M: Module>(module: &M, grads: &GradientsParams) -> Option<GradNorms> {
    let mut sq = SquaredNorms {
        grads,
        path: Vec::new(),
        acc: Default::default(),
        elements: [0; GROUPS],
    };
    module.visit(&mut sq);
    let present: Vec<usize> = (0..sq.acc.len()).filter(|&i| sq.acc[i].is_some()).collect();
    let parts: Vec<Tensor<1>> = sq.acc.into_iter().flatten().collect();
    if parts.is_empty() {
        return None;
    }
    let squares = host_read::read_all(parts);
    let mut groups = [None; GROUPS];
    for (&slot, s) in present.iter().zip(&squares) {
        groups[slot] = Some(s.sqrt());
    }
    Some(GradNorms {
        groups,
        elements: sq.elements,
        total: squares.iter().sum::<f64>().sqrt(),
    })
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

/// Scales `grads`, whose global L2 norm is `norm` ([`grad_norms`]), so that it is at most
/// `max_norm`.
pub fn clip_global_norm<M: Module>(
    module: &M,
    grads: &mut GradientsParams,
    norm: f64,
    max_norm: f64,
) {
    let factor = max_norm / (norm + NORM_EPS);
    if factor < 1.0 {
        module.visit(&mut Scale { grads, factor });
    }
}
