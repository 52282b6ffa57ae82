//! `envision4d train --config FILE [--resume DIR] [--dry-run] [--backend ...]`.

use crate::backend_choice::{parse_device, BackendChoice};
use crate::reduce_choice::{nccl, reduce_for, ReduceChoice};
use anyhow::Result;
use clap::Args;
use envision4d_train::freeze::ParamSplit;
use envision4d_train::run::{run as run_training, Observer, RunOptions};
use envision4d_train::step::build_model;
use envision4d_train::validate::ValReport;
use envision4d_train::StepReport;
use indicatif::{ProgressBar, ProgressStyle};
use std::path::{Path, PathBuf};

mod memory;

#[derive(Args, Debug)]
pub struct TrainArgs {
    /// Training config (TOML; see configs/waymo.toml, configs/synth-tiny.toml).
    #[arg(long)]
    config: PathBuf,
    /// Continue a run: its directory (newest checkpoint) or one checkpoint directory.
    /// Restores model, optimiser state, step and data order, so the curve continues exactly.
    #[arg(long)]
    resume: Option<PathBuf>,
    /// Stop after this many steps in total (with a checkpoint), e.g. to split a long run.
    #[arg(long)]
    stop_at: Option<u64>,
    /// Validate the config, resolve every setting, build the model and optimiser, print the
    /// settings and the trainable/frozen parameter counts, and stop.
    #[arg(long)]
    dry_run: bool,
    /// Overrides the config's `seed` (model init and data order): repeated runs of one
    /// config with several seeds, as the motion benchmark trains them.
    #[arg(long)]
    seed: Option<u64>,
    /// Overrides one config key before the config is read, e.g. `--set optim.batch_size=1`
    /// or `--set model.image_size=[280,518]` (a dotted key; the value is TOML). Repeatable.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    sets: Vec<String>,
    /// Overrides `[run] out_dir`.
    #[arg(long)]
    out_dir: Option<PathBuf>,
    #[arg(long, value_enum, default_value_t = BackendChoice::Cpu)]
    backend: BackendChoice,
    /// Data-parallel devices, comma-separated: `wgpu:0,wgpu:1` (discrete GPUs by index),
    /// `wgpu` (the default GPU), `cuda:0,cuda:1` (NVIDIA GPUs, `--features cuda`), `cpu`. The batch is split evenly; see docs/TRAINING.md.
    #[arg(long, value_delimiter = ',')]
    devices: Vec<String>,
    /// How `--devices` combine their gradients: `all-reduce` (Burn's collectives, NCCL;
    /// distinct CUDA GPUs only), `gather` (summed on the first device; any backend), or `auto`
    /// (all-reduce when every device is a distinct CUDA GPU with NCCL, else gather).
    #[arg(long, value_enum, default_value_t = ReduceChoice::Auto)]
    grad_reduce: ReduceChoice,
}

pub fn run(args: TrainArgs) -> Result<()> {
    let mut cfg = envision4d_train::load::load_with_overrides(&args.config, &args.sets)?;
    if let Some(seed) = args.seed {
        cfg.seed = seed;
    }
    if let Some(dir) = &args.out_dir {
        cfg.run.out_dir = dir.clone();
    }
    // run.activation_checkpointing: Burn's balanced checkpointing on every training device.
    let autodiff = |d: burn::tensor::Device| {
        let d = d.autodiff();
        if cfg.run.activation_checkpointing {
            d.gradient_checkpointing()
        } else {
            d
        }
    };
    let devices = args
        .devices
        .iter()
        .map(|d| parse_device(d).map(autodiff))
        .collect::<Result<Vec<_>, _>>()?;
    let (reduce, note) = reduce_for(args.grad_reduce, &args.devices, nccl)?;
    if let Some(note) = note {
        eprintln!("{note}");
    }
    // With --devices the first one holds the model and the optimiser.
    let device = match devices.first() {
        Some(d) => d.clone(),
        None => autodiff(args.backend.device()?),
    };
    if args.dry_run {
        return dry_run(&args, cfg, &device);
    }
    let out = cfg.run.out_dir.clone();
    let mut bar = Bar::new();
    let summary = run_training(
        cfg,
        &device,
        RunOptions {
            resume: args.resume.clone(),
            stop_at: args.stop_at,
            devices,
            reduce,
        },
        &mut bar,
    )?;
    bar.0.finish();
    println!(
        "trained {} steps ({} skipped); model {}; last checkpoint {}; log {}",
        summary.steps,
        summary.skipped,
        summary.model.display(),
        summary.last_checkpoint.display(),
        out.join(envision4d_train::run::LOG_FILE).display()
    );
    // On the CPU backend the host's peak is the step's memory, which the model estimates
    // (one device; with several, each holds a share of the batch).
    if args.backend == BackendChoice::Cpu
        && args.devices.is_empty()
        && let Some(line) = memory::describe_peak(summary.estimated_peak_bytes)
    {
        println!("{line}");
    }
    if let Some(v) = summary.last_validation {
        println!("last validation: {}", describe(&v));
    }
    Ok(())
}

fn dry_run(
    args: &TrainArgs,
    cfg: envision4d_train::TrainConfig,
    device: &burn::tensor::Device,
) -> Result<()> {
    // Build without the init weights (they may be absent here) to count parameters, then
    // report whether the files the run needs exist.
    let mut bare = cfg.clone();
    bare.init_checkpoint = None;
    let model = build_model(&bare, device)?;
    let split = ParamSplit::new(&model, &cfg.freeze);
    println!(
        "# resolved settings ({})\n{}",
        args.config.display(),
        cfg.to_toml()
    );
    println!(
        "parameters: {} trainable, {} frozen ({} total) on {:?}",
        split.trainable_count,
        split.frozen_count,
        split.trainable_count + split.frozen_count,
        args.backend
    );
    let estimate = envision4d_train::memory::estimate(&cfg, &model, &split);
    println!("{}", memory::describe_estimate(&estimate, args.backend));
    let files = [
        ("init_checkpoint", cfg.init_checkpoint.as_deref()),
        ("teacher_checkpoint", cfg.teacher_checkpoint.as_deref()),
        ("loss.lpips_weights", cfg.loss.lpips_weights.as_deref()),
        ("data.root", Some(cfg.data.root.as_path())),
    ];
    for (key, path) in files {
        if let Some(p) = path {
            // loss.lpips_weights may name two files, `A,B`.
            let found = p.exists()
                || p.to_string_lossy()
                    .split(',')
                    .all(|part| Path::new(part.trim()).exists());
            let state = if found { "found" } else { "MISSING" };
            println!("{key}: {} ({state})", p.display());
        }
    }
    describe_data(&cfg)?;
    // Building the optimiser and the teacher would load the (possibly 5 GB) weights again:
    // the dry run stops at the resolved settings, the counts and the file checks above.
    Ok(())
}

/// What the run will read: layout, split, scenes, windows, frames, size and ground truth.
/// A refused split is the same error (exit 2) the run would give.
fn describe_data(cfg: &envision4d_train::TrainConfig) -> Result<()> {
    use envision4d_train::config::{DataLayout, Purpose};
    let data = &cfg.data;
    envision4d_train::dataset::check_training_split(data)?;
    let split = match data.layout {
        DataLayout::Waymo | DataLayout::Nuscenes => format!(
            ", split {:?}, a window every {} frame(s), windows per scene: {}",
            data.split_for(Purpose::Train),
            data.stride,
            data.windows_per_scene
                .map_or("all".to_owned(), |n| n.to_string())
        ),
        _ => format!(", stride {}", data.stride),
    };
    let split = match data.frame_step {
        1 => split,
        k => format!("{split}, frame_step {k} (every {k} source frames)"),
    };
    println!(
        "data: {} (layout {:?}{split})",
        data.root.display(),
        data.layout
    );
    if !data.root.is_dir() {
        return Ok(());
    }
    let dataset =
        envision4d_train::dataset::open_dataset(data, &cfg.model, &data.root, Purpose::Train)?;
    let scenes: std::collections::BTreeSet<&str> =
        dataset.entries().iter().map(|e| e.group.as_str()).collect();
    let [h, w] = cfg.model.image_size;
    println!(
        "windows: {} from {} scene(s), {} frames each ({} context + {} future), fitted to {h}x{w}; {} source(s) skipped",
        dataset.len(),
        scenes.len(),
        cfg.model.num_frames(),
        cfg.model.context_frames,
        cfg.model.future_frames,
        dataset.skipped(),
    );
    if let Some(clip) = (!dataset.is_empty()).then(|| dataset.load(0)).transpose()? {
        // No ground truth at all is an empty list (not "every frame has it").
        let has = |f: &dyn Fn(&envision4d_data::FrameGt) -> bool| {
            !clip.gt.is_empty() && clip.gt.iter().all(f)
        };
        let yes = |b: bool| if b { "yes" } else { "no" };
        // The real-data readers leave LiDAR out of training (no loss uses it).
        let depth = if data.has_splits() {
            "not read for training (LiDAR: eval only)"
        } else {
            yes(has(&|g| g.depth.is_some()))
        };
        println!(
            "ground truth (first window {}): intrinsics {}, poses {}, depth {depth}",
            clip.id,
            yes(has(&|g| g.intrinsics.is_some())),
            yes(has(&|g| g.world_to_camera.is_some())),
        );
    }
    Ok(())
}

fn fmt(v: Option<f64>, unit: &str) -> String {
    v.map_or("-".into(), |x| format!("{x:.3}{unit}"))
}

fn describe(v: &ValReport) -> String {
    format!(
        "step {}: future PSNR {}, context PSNR {}, camera L1 {}, depth L1 {} ({} clips, {:.1} s)",
        v.step,
        fmt(v.future_psnr, " dB"),
        fmt(v.context_psnr, " dB"),
        fmt(v.camera_l1, ""),
        fmt(v.depth_l1, " m"),
        v.clips,
        v.seconds
    )
}

/// The progress bar: loss terms, PSNR, it/s and ETA.
struct Bar(ProgressBar);

impl Bar {
    fn new() -> Bar {
        let bar = ProgressBar::new(0);
        if let Ok(style) = ProgressStyle::with_template(
            "{bar:30} {pos}/{len} {msg} [{elapsed_precise}, eta {eta}]",
        ) {
            bar.set_style(style);
        }
        Bar(bar)
    }
}

impl Observer for Bar {
    fn start(&mut self, first: u64, total: u64) {
        self.0.set_length(total);
        self.0.set_position(first);
        self.0.reset_eta();
    }
    fn step(&mut self, r: &StepReport, rate: f64) {
        self.0.set_position(r.step + 1);
        let psnr = r.psnr.map_or(String::new(), |p| format!(" psnr {p:.2}"));
        self.0.set_message(format!(
            "loss {:.4} (rgb {:.4} cam {:.4} depth {:.4}){psnr} {:?} {rate:.2} it/s",
            r.total, r.rgb, r.camera, r.depth, r.phase
        ));
        if !r.outcome.applied() {
            self.0
                .println(format!("step {}: skipped ({:?})", r.step, r.outcome));
        }
    }
    fn validation(&mut self, v: &ValReport) {
        self.0.println(format!("validation {}", describe(v)));
    }
    fn checkpoint(&mut self, dir: &Path) {
        self.0.println(format!("checkpoint {}", dir.display()));
    }
    fn note(&mut self, m: &str) {
        self.0.println(m);
    }
}
