//! Shared helpers: the tiny config and a tiny synthetic clip.

use burn::module::{Module, ModuleVisitor, Param};
use burn::tensor::{Device, Tensor};
use envision4d_data::synth::{render_clip, Preset, SynthConfig};
use envision4d_train::batch::{Batch, HostClip};
use envision4d_train::TrainConfig;
use std::path::PathBuf;

pub const H: usize = 56;
pub const W: usize = 84;
pub const FRAMES: usize = 4;

pub fn config_path(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../configs")
        .join(name)
}

/// `configs/synth-tiny.toml` with the caller's tweaks.
pub fn tiny_config() -> TrainConfig {
    envision4d_train::load(&config_path("synth-tiny.toml")).expect("synth-tiny.toml parses")
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
        .map(|f| {
            let mut chw = vec![0.0; 3 * H * W];
            for p in 0..H * W {
                for c in 0..3 {
                    chw[c * H * W + p] = f.rgb[p * 3 + c];
                }
            }
            chw
        })
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
