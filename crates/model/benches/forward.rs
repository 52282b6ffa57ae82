//! Forward-pass benchmark (not a test): the model with random weights on the CPU backend.
//!
//! `cargo bench -p envision4d-model --bench forward -- [--preset paper|tiny] [--heads all|none]
//!  [--chunk N]` — prints time and peak resident memory. The fixtures README measured the
//! PyTorch reference on this machine: paper size, 2 frames at 350x518: ~100-130 s, 9.4 GB;
//! tiny widths: 2.2 s at 350x518.

use burn::tensor::{Device, Distribution, Tensor};
use envision4d_model::model::Heads;
use envision4d_model::{Envision4d, ModelConfig};
use std::time::Instant;

fn peak_rss_gib() -> f64 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    status
        .lines()
        .find(|l| l.starts_with("VmHWM:"))
        .and_then(|l| l.split_whitespace().nth(1))
        .and_then(|kb| kb.parse::<f64>().ok())
        .map_or(f64::NAN, |kb| kb / (1024.0 * 1024.0))
}

fn arg(args: &[String], name: &str) -> Option<String> {
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1).cloned())
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let preset = arg(&args, "--preset").unwrap_or_else(|| "paper".into());
    let mut cfg = ModelConfig::preset(&preset).expect("preset");
    // The tiny widths are also timed at the paper's image size, as the README did.
    cfg.image_size = [350, 518];
    cfg.validate().expect("valid config");
    let heads = match arg(&args, "--heads").as_deref() {
        Some("none") => Heads::NONE,
        _ => Heads::ALL,
    };
    let device = Device::flex();
    let t = Instant::now();
    let mut model = Envision4d::new(&cfg, &device);
    if let Some(c) = arg(&args, "--chunk") {
        model.dpt_frame_chunk = c.parse().expect("--chunk N");
    }
    let params = burn::module::Module::num_params(&model);
    let t_init = t.elapsed();
    let [h, w] = cfg.image_size;
    let images = Tensor::<5>::random(
        [1, cfg.context_frames, 3, h, w],
        Distribution::Uniform(0.0, 1.0),
        &device,
    );
    let t = Instant::now();
    let out = model.forward(images, heads);
    // Force every output to be computed before stopping the clock.
    let _ = out.backbone.pose_enc().into_data();
    if let Some(m) = out.motion_enc {
        let _ = m.into_data();
    }
    if let Some(g) = out.gaussians {
        let _ = g.into_data();
    }
    if let Some(d) = out.depth {
        let _ = d.into_data();
    }
    let t_fwd = t.elapsed();
    println!(
        "| preset | params | image | heads | DPT frame chunk | init s | forward s | peak RSS GiB |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    println!(
        "| {preset} | {:.3} B | {h}x{w} | {} | {} | {:.1} | {:.1} | {:.1} |",
        params as f64 / 1e9,
        if heads == Heads::ALL {
            "all"
        } else {
            "none (poses only)"
        },
        model.dpt_frame_chunk,
        t_init.as_secs_f64(),
        t_fwd.as_secs_f64(),
        peak_rss_gib()
    );
}
