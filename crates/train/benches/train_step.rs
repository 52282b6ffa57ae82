//! One real training step (not a test): the paper's loss (§3.4) through [`Trainer::train_step`]
//! — the network forward with every head the step needs, the rasterizer over every target,
//! L1 + LPIPS, distillation against the frozen teacher, backward, clipping and Adam — from a
//! training config with `init = "random"` forced, so it runs without VGGT-1B or VGG weights
//! (both get random ones: the step costs what the real one costs).
//!
//! ```text
//! cargo bench -p envision4d-train --bench train_step -- [--config configs/waymo.toml]
//!     [--preset paper|tiny] [--image HxW] [--batch B] [--step S] [--repeats N]
//!     [--device cpu|wgpu|cuda] [--checkpointing] [--launches] [--launch-sites NAME]
//!     [--norm fused|burn] [--adam fused|burn] [--softmax fused|burn] [--rope fused|burn] [--residual fused|burn]
//!     [--qkv fused|burn] [--split fused|burn] [--gelu fused|burn]
//!     [--set KEY=VALUE]...
//! ```
//!
//! `--step` is the schedule step the batch is trained at (default: the first after the
//! static warm-up, so the motion head and every target run). `--checkpointing` turns on
//! Burn's balanced activation checkpointing on the autodiff device. `--set` overrides one
//! config key before the config is read (`--set model.embed_dim=128`,
//! `--set run.recompute_frozen_blocks=true`; the value is TOML). A line `# memory model:`
//! gives the estimate of `envision4d_train::memory` (first and later steps) and the counts
//! it multiplies, which `scripts/memory_fit.sh` fits against the measured peaks; the warm-up
//! line carries the first step's peak RSS. The images are uniform
//! noise. One untimed step warms the allocator and, on a GPU, the kernel caches; each timed
//! step prints `train_step_s=<s> peak_rss_gib=<g> device_reserved_gib=<g>
//! kernel_launches=<n>`: the host's peak RSS, the device memory pool's reserved bytes after
//! the step (GPU backends; `nan` on the CPU, whose memory is the RSS), and the kernels the
//! step launched (GPU backends; 0 on the CPU). `--launches` lists the most launched ones;
//! `--launch-sites Copy` lists where the kernels whose name contains `Copy` were launched
//! from (a backtrace per such launch: slower, for finding them, not for timing).

#[path = "../../../tests/support/paths.rs"]
mod paths;

use envision4d_data::HostClip;
use envision4d_model::bench::{arg, device_reserved_gib, peak_rss_gib, watch_launches, Launches};
use envision4d_train::batch::Batch;
use envision4d_train::config::{Init, Stage, Teacher};
use envision4d_train::Trainer;
use std::path::Path;
use std::time::Instant;

/// Kernels listed by `--launches` after each timed step.
const TOP_KERNELS: usize = 16;

/// A clip of `n` frames of uniform noise in [0, 1) (a fixed generator, so runs compare).
fn noise_clip(n: usize, h: usize, w: usize, seed: u64) -> HostClip {
    let mut state = seed;
    let mut next = move || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (state >> 40) as f32 / (1u64 << 24) as f32
    };
    HostClip {
        height: h,
        width: w,
        frames: (0..n)
            .map(|_| (0..3 * h * w).map(|_| next()).collect())
            .collect(),
        cameras: Vec::new(),
        depths: Vec::new(),
        eval_depths: Vec::new(),
        eval_depth_source: None,
        dynamic_masks: Vec::new(),
        motion_truth: Vec::new(),
    }
}

fn main() {
    envision4d_model::alloc::keep_freed_memory();
    let args: Vec<String> = std::env::args().collect();
    let path = arg(&args, "--config").unwrap_or_else(|| "configs/waymo.toml".into());
    // Benches run from the crate directory; configs live at the workspace root.
    let root = paths::manifest_dir().join("../..");
    let file = if Path::new(&path).is_file() {
        Path::new(&path).to_path_buf()
    } else {
        root.join(&path)
    };
    let sets: Vec<String> = args
        .windows(2)
        .filter(|w| w[0] == "--set")
        .map(|w| w[1].clone())
        .collect();
    let mut cfg =
        envision4d_train::load::load_with_overrides(&file, &sets).unwrap_or_else(|e| panic!("{e}"));
    cfg.init = Init::Random;
    cfg.init_checkpoint = None;
    cfg.init_fresh.clear();
    cfg.teacher_checkpoint = None;
    cfg.loss.lpips_weights = None;
    if let Some(p) = arg(&args, "--preset") {
        let keep = (cfg.model.context_frames, cfg.model.future_frames);
        cfg.model = envision4d_model::ModelConfig::preset(&p).unwrap_or_else(|e| panic!("{e}"));
        (cfg.model.context_frames, cfg.model.future_frames) = keep;
    }
    if let Some(s) = arg(&args, "--image") {
        let (h, w) = s.split_once('x').expect("--image HxW");
        cfg.model.image_size = [h.parse().expect("--image H"), w.parse().expect("--image W")];
    }
    if let Some(b) = arg(&args, "--batch") {
        cfg.optim.batch_size = b.parse().expect("--batch B");
    }
    assert!(
        cfg.stage == Stage::Envision4d && cfg.teacher == Teacher::Backbone,
        "the bench measures the paper's step: stage = \"envision4d\", teacher = \"backbone\""
    );
    envision4d_train::load::validate(&cfg).unwrap_or_else(|e| panic!("{e}"));
    let step: u64 = arg(&args, "--step").map_or(cfg.progressive.warmup_iterations, |s| {
        s.parse().expect("--step S")
    });
    let repeats: usize = arg(&args, "--repeats").map_or(1, |r| r.parse().expect("--repeats N"));
    let base = envision4d_model::bench::device(arg(&args, "--device").as_deref())
        .unwrap_or_else(|e| panic!("{e}"));
    let checkpointing = args.iter().any(|a| a == "--checkpointing");
    let counter = || Launches::from_args(&args);
    envision4d_model::bench::choose_layer_norm(&args);
    envision4d_model::bench::choose_softmax(&args);
    envision4d_model::bench::choose_rope(&args);
    envision4d_model::bench::choose_residual(&args);
    envision4d_model::bench::choose_qkv(&args);
    envision4d_model::bench::choose_split(&args);
    envision4d_model::bench::choose_gelu(&args);
    // `--adam fused|burn`: the optimiser's update on GPU backends, as `--norm` chooses the
    // LayerNorm.
    match arg(&args, "--adam").as_deref() {
        None | Some("fused") => envision4d_train::adam::set_fused_adam(true),
        Some("burn") => envision4d_train::adam::set_fused_adam(false),
        Some(other) => panic!("--adam {other}: use fused or burn"),
    }
    let device = if checkpointing {
        base.autodiff().gradient_checkpointing()
    } else {
        base.autodiff()
    };

    let [h, w] = cfg.model.image_size;
    let (b, n) = (cfg.optim.batch_size, cfg.model.num_frames());
    let t = Instant::now();
    let mut trainer = Trainer::new(cfg.clone(), &device).unwrap_or_else(|e| panic!("{e}"));
    let (trainable, frozen) = (trainer.split.trainable_count, trainer.split.frozen_count);
    println!(
        "# train step: {} widths, batch {b} x {n} frames at {h}x{w}, schedule step {step}, \
         {:.1} M trainable / {:.1} M frozen parameters, checkpointing {checkpointing}, \
         recomputed frozen blocks {}, built in {:.1} s; random weights: {}",
        if cfg.model.embed_dim >= envision4d_model::ModelConfig::paper().embed_dim {
            "paper"
        } else {
            "small"
        },
        trainable as f64 / 1e6,
        frozen as f64 / 1e6,
        cfg.run.recompute_frozen_blocks,
        t.elapsed().as_secs_f64(),
        cfg.random_weights().join(", "),
    );
    let m = envision4d_train::memory::estimate(&cfg, &trainer.model, &trainer.split);
    let gib = envision4d_train::memory::GIB;
    // The exact terms of each peak (all but the process constant and the activations).
    let exact_first = m.first_step() - m.runtime - m.activations;
    let exact_later = m.later_steps() - m.runtime - m.activations;
    println!(
        "# memory model: first_gib={:.3} later_gib={:.3} exact_first_bytes={exact_first:.0} \
         exact_later_bytes={exact_later:.0} block_token_channels={:.0} \
         recomputed_token_channels={:.0} dpt_pixel_channels={:.0} rendered_pixels={:.0} lpips_pixels={:.0}",
        m.first_step() / gib,
        m.later_steps() / gib,
        m.counts.block_token_channels,
        m.counts.recomputed_token_channels,
        m.counts.dpt_pixel_channels,
        m.counts.rendered_pixels,
        m.counts.lpips_pixels,
    );
    let clips: Vec<HostClip> = (0..b as u64).map(|k| noise_clip(n, h, w, k)).collect();
    let batch = Batch::from_clips(&clips, cfg.model.context_frames, false, &device)
        .unwrap_or_else(|e| panic!("{e}"));
    for i in 0..=repeats {
        trainer.step = step;
        let t = Instant::now();
        // The warm-up only counts: its call sites would repeat the timed step's, slowly.
        let watch = if i == 0 {
            Launches::new(false)
        } else {
            counter()
        };
        let (r, launches) = watch_launches(watch, || {
            let r = trainer.train_step(&batch).unwrap_or_else(|e| panic!("{e}"));
            // The step reads its losses and checks back, but the optimizer's last update
            // may still be queued on a GPU backend: the clock stops when the device is done.
            device
                .sync()
                .unwrap_or_else(|e| panic!("the device failed during a step: {e:?}"));
            r
        });
        let s = t.elapsed().as_secs_f64();
        if i == 0 {
            println!(
                "# untimed warm-up step: {s:.2} s, outcome {:?}, loss {:.4}, \
                 first_step_peak_rss_gib={:.3}",
                r.outcome,
                r.total,
                peak_rss_gib()
            );
            continue;
        }
        println!(
            "train_step_s={s:.4} peak_rss_gib={:.2} device_reserved_gib={:.2} \
             kernel_launches={} outcome={:?}",
            peak_rss_gib(),
            device_reserved_gib(&device),
            launches.total(),
            r.outcome,
        );
        launches.print_top(TOP_KERNELS);
        launches.print_sites(TOP_KERNELS);
    }
}
