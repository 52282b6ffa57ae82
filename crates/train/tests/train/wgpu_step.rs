//! One training step on the CubeCL backend (lavapipe in CI) against the same step on the CPU.

use crate::common::{batch, tiny_config};
use burn::module::Module;
use burn::tensor::Device;
use envision4d_model::host_read::host_reads;
use envision4d_splat::kernels::readback::host_readbacks;
use envision4d_train::config::ClipMode;
use envision4d_train::grad_clip::GradGroup;
use envision4d_train::step::{StepOutcome, StepReport};
use envision4d_train::Trainer;

/// Relative difference of two host values.
fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs().max(1e-12)
}

/// One step of `t` on the tests' clip, with the host reads it made: (the step's own, the
/// rasterizer's).
fn step(t: &mut Trainer, device: &Device) -> (StepReport, usize, usize) {
    let batch = batch(2, true, device);
    let (reads, raster) = (host_reads(), host_readbacks());
    let r = t.train_step(&batch).expect("the step runs");
    (r, host_reads() - reads, host_readbacks() - raster)
}

/// Guards training on a GPU backend, which no test had run: every step on wgpu or CUDA
/// panicked in `backward()` (the DPT resize has no bilinear backward there), and nothing
/// held a GPU step to the CPU's numbers or its host round trips. One step of the tiny
/// config with the motion head on, from the CPU trainer's initial weights moved to wgpu:
/// the loss terms and every module's gradient norm equal the CPU's (the norms to 2e-5: with
/// Burn's CubeCL GELU, whose backward is the tanh approximation's, the time blocks' was
/// 1.8e-4 off; with the exact one at most 1.8e-6), and the step reads the
/// host as often as on the CPU (its five checks) plus the rasterizer's fixed two (both
/// camera tensors in one read, the intersection totals in the forward; the backward reuses
/// its tile lists), not once per view.
#[test]
fn a_training_step_on_wgpu_equals_the_cpu_step() {
    let Some(gpu) = envision4d_splat::testkit::wgpu_test_device() else {
        return;
    };
    let (cpu, gpu) = (Device::flex().autodiff(), gpu.autodiff());
    let mut c = tiny_config();
    c.progressive.warmup_iterations = 0;
    c.optim.grad_clip = ClipMode::GlobalNorm;
    let mut on_cpu = Trainer::new(c.clone(), &cpu).expect("cpu trainer");
    let mut on_gpu = Trainer::new(c, &gpu).expect("wgpu trainer");
    // The same weights and parameter ids on both (the split names parameters by id).
    on_gpu.model = on_cpu.model.clone().fork(&gpu);
    on_gpu.split = on_cpu.split.clone();

    let (want, cpu_reads, _) = step(&mut on_cpu, &cpu);
    let (got, gpu_reads, raster_reads) = step(&mut on_gpu, &gpu);
    assert_eq!(want.outcome, StepOutcome::Applied);
    assert_eq!(got.outcome, StepOutcome::Applied);
    for (what, g, w) in [
        ("total", got.total, want.total),
        ("rgb", got.rgb, want.rgb),
        ("camera", got.camera, want.camera),
        ("depth", got.depth, want.depth),
    ] {
        assert!(rel(g, w) < 1e-4, "{what}: wgpu {g} vs cpu {w}");
    }
    let (gn, wn) = (
        got.grad_norms.expect("wgpu gradient norms"),
        want.grad_norms.expect("cpu gradient norms"),
    );
    let mut compared = 0;
    for group in GradGroup::ALL {
        match (gn.norm(group), wn.norm(group)) {
            (Some(g), Some(w)) => {
                let (name, apart) = (group.name(), rel(g, w));
                println!("{name} gradient norm: wgpu {g} vs cpu {w}, {apart:.2e} apart");
                assert!(
                    rel(g, w) < 2e-5,
                    "{} gradient norm: wgpu {g} vs cpu {w}",
                    group.name()
                );
                compared += 1;
            }
            (g, w) => assert_eq!(g, w, "{}", group.name()),
        }
    }
    assert!(compared >= 5, "only {compared} module groups had gradients");
    assert_eq!(gpu_reads, cpu_reads, "the step's own host reads");
    assert_eq!(
        raster_reads, 2,
        "the rasterizer's host reads in a wgpu step"
    );
}
