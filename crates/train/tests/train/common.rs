//! Shared helpers: the tiny config and a tiny synthetic clip.

use burn::module::{Module, ModuleVisitor, Param};
use burn::tensor::{Device, Tensor};
use envision4d_data::synth::{render_clip, Preset, SynthConfig};
use envision4d_data::HostClip;
use envision4d_train::batch::Batch;
use envision4d_train::config::Teacher;
use envision4d_train::TrainConfig;
use std::path::PathBuf;

pub const H: usize = 56;
pub const W: usize = 84;
pub const FRAMES: usize = 4;

pub fn config_path(name: &str) -> PathBuf {
    crate::paths::manifest_dir()
        .join("../../configs")
        .join(name)
}

/// `configs/synth-tiny.toml` made self-contained for tests: random init (no stage-1
/// checkpoint on a fresh machine), exact labels, nothing frozen, T_f = 2, short warm-up.
pub fn tiny_config() -> TrainConfig {
    let mut c =
        envision4d_train::load(&config_path("synth-tiny.toml")).expect("synth-tiny.toml parses");
    c.init_checkpoint = None;
    c.teacher_checkpoint = None;
    c.teacher = Teacher::GroundTruth;
    c.freeze = vec![];
    c.model.future_frames = FRAMES - c.model.context_frames;
    c.optim.batch_size = 1;
    c.optim.lr = 1e-3;
    c.progressive.warmup_iterations = 20;
    c.progressive.s_max = 100;
    c.loss.lambda_depth = 1.0;
    c
}

pub fn synth_clip(seed: u64) -> HostClip {
    let cfg = SynthConfig {
        width: W,
        height: H,
        frames: FRAMES,
        preset: Preset::Urban,
        seed,
        supersample: 1,
    };
    let r = render_clip(&cfg, 0, || {}).expect("synthetic clip renders");
    let frames = r
        .frames
        .iter()
        .map(|f| envision4d_data::hwc_to_chw(&f.rgb, H, W))
        .collect();
    HostClip {
        height: H,
        width: W,
        frames,
        cameras: r
            .cameras
            .iter()
            .map(|c| (c.world_to_camera, c.intrinsics))
            .collect(),
        depths: r.frames.iter().map(|f| f.depth.clone()).collect(),
        eval_depths: r.frames.iter().map(|f| Some(f.depth.clone())).collect(),
        eval_depth_source: Some(envision4d_data::DepthSource::Dense),
        dynamic_masks: Vec::new(),
        motion_truth: Vec::new(),
    }
}

pub fn batch(context: usize, teacher: bool, device: &Device) -> Batch {
    Batch::from_clips(&[synth_clip(7)], context, teacher, device).expect("batch builds")
}

struct Flat(Vec<f32>);
impl ModuleVisitor for Flat {
    fn visit_float<const D: usize>(&mut self, p: &Param<Tensor<D>>) {
        self.0.extend(p.val().into_data().iter::<f32>());
    }
}

/// Every parameter value of a module, flattened in visiting order.
pub fn flat_params<M: Module>(m: &M) -> Vec<f32> {
    let mut f = Flat(vec![]);
    m.visit(&mut f);
    f.0
}

/// Writes `clips` synthetic clips of `frames` frames (tiny size) under `root` as the
/// synthetic layout, so a run can open them as a dataset.
pub fn write_synth_dataset(root: &std::path::Path, clips: u64, frames: usize) {
    use envision4d_data::synth::write_clip;
    for i in 0..clips {
        let cfg = SynthConfig {
            width: W,
            height: H,
            frames,
            preset: Preset::Urban,
            seed: 11,
            supersample: 1,
        };
        let r = render_clip(&cfg, i, || {}).expect("synthetic clip renders");
        write_clip(&root.join(format!("clip_{i:06}")), &r).expect("clip written");
    }
}

/// `(largest |a − b|, largest |a|, gradients compared)` over `model`'s parameters that have
/// a gradient in both.
pub fn grad_diff<M: Module>(
    model: &M,
    a: &burn::optim::GradientsParams,
    b: &burn::optim::GradientsParams,
) -> (f32, f32, usize) {
    struct Cmp<'a>(
        &'a burn::optim::GradientsParams,
        &'a burn::optim::GradientsParams,
        f32,
        f32,
        usize,
    );
    impl ModuleVisitor for Cmp<'_> {
        fn visit_float<const D: usize>(&mut self, p: &Param<Tensor<D>>) {
            if let (Some(a), Some(b)) = (self.0.get::<D>(p.id), self.1.get::<D>(p.id)) {
                let d = (a.clone() - b).abs().max().into_scalar::<f32>();
                let m = a.abs().max().into_scalar::<f32>();
                self.2 = self.2.max(d);
                self.3 = self.3.max(m);
                self.4 += 1;
            }
        }
    }
    let mut cmp = Cmp(a, b, 0.0, 0.0, 0);
    model.visit(&mut cmp);
    (cmp.2, cmp.3, cmp.4)
}

/// `model`'s gradients in `g`, in the model's parameter order (to compare two models whose
/// parameter ids differ), flattened.
pub fn ordered_grads<M: Module>(model: &M, g: &burn::optim::GradientsParams) -> Vec<Vec<f32>> {
    struct Collect<'a>(&'a burn::optim::GradientsParams, Vec<Vec<f32>>);
    impl ModuleVisitor for Collect<'_> {
        fn visit_float<const D: usize>(&mut self, p: &Param<Tensor<D>>) {
            if let Some(t) = self.0.get::<D>(p.id) {
                self.1
                    .push(t.into_data().convert::<f32>().try_to_vec::<f32>().unwrap());
            }
        }
    }
    let mut c = Collect(g, Vec::new());
    model.visit(&mut c);
    c.1
}
