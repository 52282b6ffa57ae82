//! Rendering-loss benchmark (not a test): forward + backward of the per-frame MSE and of the
//! structural term `1 − SSIM` on one training step's renders, burn-flex autodiff, f32.
//!
//! `cargo bench -p envision4d-losses --bench ssim_loss -- [--frames N] [--size HxW] [--reps R]`
//! Default: 16 frames (batch 2 x 8 rendered views) at 56x84, the shipped model's step.

use burn::tensor::{Device, Distribution, Tensor};
use envision4d_losses::{mse_per_frame, ssim_per_frame};
use std::time::Instant;

fn arg(args: &[String], name: &str) -> Option<String> {
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1).cloned())
}

/// Mean milliseconds of `reps` forward + backward passes of `loss`, after 2 warm-up passes.
fn time_ms(
    shape: [usize; 4],
    reps: usize,
    loss: &dyn Fn(Tensor<4>, Tensor<4>) -> Tensor<1>,
) -> f64 {
    let device = Device::flex().autodiff();
    let run = || {
        let p = Tensor::<4>::random(shape, Distribution::Uniform(0.0, 1.0), &device).require_grad();
        let t = Tensor::<4>::random(shape, Distribution::Uniform(0.0, 1.0), &device);
        let grads = loss(p.clone(), t).sum().backward();
        // Reading the gradient back forces the lazy work to finish.
        let _ = p.grad(&grads).expect("gradient").into_data();
    };
    run();
    run();
    let start = Instant::now();
    for _ in 0..reps {
        run();
    }
    start.elapsed().as_secs_f64() * 1e3 / reps as f64
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let frames: usize = arg(&args, "--frames").map_or(16, |v| v.parse().expect("--frames N"));
    let reps: usize = arg(&args, "--reps").map_or(20, |v| v.parse().expect("--reps R"));
    let [h, w] = arg(&args, "--size").map_or([56, 84], |v| {
        let (a, b) = v.split_once('x').expect("--size HxW");
        [a.parse().expect("H"), b.parse().expect("W")]
    });
    let shape = [frames, 3, h, w];
    let mse = time_ms(shape, reps, &|p, t| mse_per_frame(p, t).expect("mse"));
    let ssim = time_ms(shape, reps, &|p, t| ssim_per_frame(p, t).expect("ssim"));
    println!("{frames} frames at {h}x{w}, forward + backward, mean of {reps} (burn-flex):");
    println!("  mse_per_frame   {mse:8.2} ms");
    println!("  ssim_per_frame  {ssim:8.2} ms");
}
