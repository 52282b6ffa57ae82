//! `envision4d eval`: score a checkpoint on held-out clips (future frames, cross-frame
//! context, depth, poses, baselines, timings; optionally the quality-vs-time sweep) and write
//! `metrics.json`, `metrics.md` and PNG plots. See `docs/EVAL.md`.

pub mod args;
pub mod motion_images;
pub mod shared;
mod sweep;

use crate::backend_choice::{BackendChoice, PrecisionChoice};
use crate::report::gallery::Gallery;
use crate::InputError;
use anyhow::Result;
use args::{parse_crop, AlignChoice, LayoutChoice, Protocol, SplitChoice};
use clap::Args;
use envision4d_data::lock::DirLock;
use envision4d_data::{atomic, Split};
use envision4d_eval::sweep::with_horizon;
use envision4d_eval::{evaluate_dataset, summary, EvalOptions, Report};
use envision4d_losses::EvalCrop;
use envision4d_model::checkpoint::checkpoint_config;
use envision4d_model::ModelConfig;
use envision4d_train::config::{DataConfig, DataLayout, Purpose};
use indicatif::{ProgressBar, ProgressStyle};
use shared::{build_report, load_model, lpips_status, warm_up, Provenance};
use std::path::{Path, PathBuf};

#[derive(Args, Debug)]
pub struct EvalArgs {
    /// One of our checkpoints (safetensors; carries its model config).
    #[arg(long)]
    checkpoint: PathBuf,
    /// Training config (TOML): its `[model]` and `[data]` (layout, root, seed). Optional when the
    /// checkpoint carries its model config; the data is then read as the synthetic layout.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Held-out data folder (overrides the config's data.root; required without --config).
    #[arg(long)]
    data: Option<PathBuf>,
    /// Layout of the data (overrides the config's data.layout; default without --config:
    /// synth). `waymo` reads STORM's / the release's `<root>/validation/<scene>/images`.
    #[arg(long, value_enum)]
    layout: Option<LayoutChoice>,
    /// The dataset's own split to read (overrides data.split): a Waymo split folder
    /// (default `validation`) or an official nuScenes split (default `val`; `mini_val` for
    /// v1.0-mini). Not to be confused with --split, which picks clips within it.
    #[arg(long)]
    dataset_split: Option<String>,
    /// Output folder: metrics.json, metrics.md, metrics_vs_horizon.png, metrics_vs_time.png
    /// (and pareto.png with --sweep), report.html with its images in report/.
    #[arg(long, default_value = "eval")]
    out: PathBuf,
    #[arg(long, value_enum, default_value_t = BackendChoice::Cpu)]
    backend: BackendChoice,
    /// Float format of the aggregator (the heads stay f32); recorded in metrics.json.
    #[arg(long, value_enum, default_value_t = PrecisionChoice::F32)]
    precision: PrecisionChoice,
    /// Clips to score: `auto` = every clip of --data (a held-out folder), or the held-out
    /// split of the config's data.root when no --data is given.
    #[arg(long, value_enum, default_value_t = SplitChoice::Auto)]
    split: SplitChoice,
    /// Score at most this many clips (dataset order).
    #[arg(long)]
    max_clips: Option<usize>,
    /// LPIPS (VGG) weights: torchvision's backbone and the lpips package's lin layers as
    /// `vgg16-397923af.pth,vgg.pth`, or one file with the package's names (safetensors from
    /// scripts/export_lpips_weights.py, or .pth); without them LPIPS is reported as null.
    #[arg(long)]
    lpips_weights: Option<PathBuf>,
    /// Border crop before every metric: TOP,BOTTOM,LEFT,RIGHT (the release's main config: 6,6,10,6).
    #[arg(long, value_parser = parse_crop)]
    crop: Option<EvalCrop>,
    /// Border crop of the cross-frame scores, TOP,BOTTOM,LEFT,RIGHT (default the release's
    /// 6,6,10,6 at 350x518, scaled to the image size: backward renders leave the borders
    /// uncovered).
    #[arg(long, value_parser = parse_crop)]
    cross_frame_crop: Option<EvalCrop>,
    /// Scale alignment of the predicted depth before D-RMSE.
    #[arg(long, value_enum, default_value_t = AlignChoice::Median)]
    depth_align: AlignChoice,
    /// Also evaluate the knobs that trade quality for time (horizon, input size, backend,
    /// culling thresholds) and write the Pareto table and plot.
    #[arg(long)]
    sweep: bool,
    /// Predict and score only the first N future frames (1..=T_f): the model keeps its first
    /// N learned future seeds, so it does less work; the baselines are scored on the same N.
    #[arg(long)]
    future: Option<usize>,
    /// Backends of the sweep's backend knob (comma-separated; default: only --backend).
    #[arg(long, value_enum, value_delimiter = ',')]
    sweep_backends: Vec<BackendChoice>,
    /// Score every window of T_c + T_f frames that starts a multiple of S frames into a clip,
    /// each as its own sample (`clip@start`). Default: the config's data.stride, or 1 with
    /// --data alone; a clip of exactly T_c + T_f frames has one window whatever S is.
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..))]
    stride: Option<u64>,
    /// Take every K-th source frame into a window (K = 2: a 10 Hz clip at 5 Hz, motion
    /// between the model's frames twice as large). Default: the config's data.frame_step, or
    /// 1 with --data alone.
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..))]
    frame_step: Option<u64>,
    /// A named protocol (docs/EVAL.md): `release` scores the 4 future frames of the official
    /// release's Waymo clips (num_frames 6), `paper` the 2 of §4.1 (T_c = T_f = 2). A
    /// checkpoint that predicts more future frames predicts only those (as `--future`).
    #[arg(long, value_enum)]
    protocol: Option<Protocol>,
    /// Print each window that would be scored, one line each (`<scene> start=<t0>
    /// context=<t,..> scored=<t,..>`, frame numbers as the source numbers them), and exit.
    #[arg(long)]
    list_windows: bool,
    /// On synthetic clips: for the first N scored clips, write `motion/<clip>_<i>to<j>.png`
    /// (true displacement | predicted | end-point error, metres, one colour scale; pair: the
    /// newest context frame to the last future frame) and its .json sidecar.
    #[arg(long, default_value_t = 0)]
    motion_images: usize,
    /// Clips shown in report.html (half the worst, half the best by the model's PSNR), each
    /// as strips of ground truth | model | copy-last | static+cv per horizon with depth,
    /// dynamic mask and motion panels; 0 = tables and plots only.
    #[arg(long, default_value_t = crate::report::DEFAULT_CLIPS)]
    report_clips: usize,
}

/// The horizon to score: `--future`, or the protocol's, checked against the checkpoint.
fn horizon(args: &EvalArgs, model: &ModelConfig) -> Result<Option<usize>> {
    let Some(p) = args.protocol else {
        return Ok(args.future);
    };
    let (name, want) = (p.name(), p.future_frames());
    if let Some(f) = args.future.filter(|&f| f != want) {
        return Err(InputError(format!(
            "--future {f} contradicts --protocol {name}, which scores {want} future frames"
        ))
        .into());
    }
    if model.context_frames != Protocol::CONTEXT_FRAMES {
        return Err(InputError(format!(
            "--protocol {name} needs {} context frames; the checkpoint takes {}",
            Protocol::CONTEXT_FRAMES,
            model.context_frames
        ))
        .into());
    }
    if model.future_frames < want {
        return Err(InputError(format!(
            "--protocol {name} scores {want} future frames; the checkpoint predicts only {}",
            model.future_frames
        ))
        .into());
    }
    Ok(Some(want))
}

/// What the arguments resolve to.
struct Setup {
    model: ModelConfig,
    data: DataConfig,
    seed: u64,
    clips: Selection,
}

/// Which clips of the dataset are scored.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Selection {
    /// Every clip (the folder itself is held out).
    All,
    /// One split of the seeded hash split (`envision4d_data::split`), as training splits.
    Split(Split),
}

fn resolve(args: &EvalArgs) -> Result<Setup> {
    if !args.checkpoint.is_file() {
        return Err(InputError(format!(
            "{}: checkpoint file not found",
            args.checkpoint.display()
        ))
        .into());
    }
    let (model, mut data, seed) = match &args.config {
        Some(path) => {
            let cfg = envision4d_train::load(path).map_err(|e| InputError(e.to_string()))?;
            (cfg.model, cfg.data, cfg.seed)
        }
        None => {
            let model = checkpoint_config(&args.checkpoint)
                .map_err(|e| InputError(e.to_string()))?
                .ok_or_else(|| {
                    InputError(format!(
                        "{} carries no model config: pass --config",
                        args.checkpoint.display()
                    ))
                })?;
            let root = args.data.clone().ok_or_else(|| {
                InputError(
                    "pass --data DIR (held-out clips) or --config (a training config with [data])"
                        .into(),
                )
            })?;
            (model, DataConfig::new(DataLayout::Synth, root, 1), 0)
        }
    };
    if let Some(root) = &args.data {
        data.root = root.clone();
    }
    if let Some(layout) = args.layout {
        data.layout = layout.layout();
    }
    if let Some(split) = &args.dataset_split {
        if !data.has_splits() {
            return Err(InputError(format!(
                "--dataset-split {split:?}: layout {:?} has no named splits (waymo and nuscenes do)",
                data.layout
            ))
            .into());
        }
        data.split = Some(split.clone());
    }
    if let Some(stride) = args.stride {
        data.stride = stride as usize;
    }
    if let Some(step) = args.frame_step {
        data.frame_step = step as usize;
    }
    if !data.root.is_dir() {
        return Err(InputError(format!("{}: data folder not found", data.root.display())).into());
    }
    let clips = match args.split {
        SplitChoice::Auto if args.data.is_some() => Selection::All,
        SplitChoice::All => Selection::All,
        SplitChoice::Auto | SplitChoice::HeldOut => Selection::Split(Split::HeldOut),
        SplitChoice::Val => Selection::Split(Split::Val),
    };
    Ok(Setup {
        model,
        data,
        seed,
        clips,
    })
}

fn bar(len: usize) -> ProgressBar {
    let bar = ProgressBar::new(len as u64);
    if let Ok(style) =
        ProgressStyle::with_template("{bar:40} {pos}/{len} clips  {elapsed_precise} (eta {eta})")
    {
        bar.set_style(style);
    }
    bar
}

pub fn run(args: EvalArgs) -> Result<()> {
    let setup = resolve(&args)?;
    let model = load_model(&setup.model, &args.checkpoint, args.backend, args.precision)?;
    // The dataset keeps the checkpoint's T_c + T_f windows; a shorter horizon scores fewer.
    let dataset_cfg = setup.model.clone();
    let (model, horizon_cfg) = match horizon(&args, &setup.model)? {
        Some(h) => {
            let m = with_horizon(&model, h).map_err(|e| InputError(format!("--future: {e}")))?;
            let mut c = setup.model.clone();
            c.future_frames = h;
            (m, c)
        }
        None => (model, setup.model.clone()),
    };
    let cfg = &horizon_cfg;
    let dataset = envision4d_train::dataset::open_dataset(
        &setup.data,
        &dataset_cfg,
        &setup.data.root,
        Purpose::Eval,
    )
    .map_err(|e| InputError(e.to_string()))?;
    let mut indices: Vec<usize> = match setup.clips {
        Selection::All => (0..dataset.len()).collect(),
        Selection::Split(split) => envision4d_train::dataset::split(&dataset, split, setup.seed),
    };
    if indices.is_empty() {
        return Err(InputError(format!(
            "{}: none of its {} clips falls in the {:?} (seed {}); pass --split all to score every clip",
            setup.data.root.display(),
            dataset.len(),
            setup.clips,
            setup.seed
        ))
        .into());
    }
    indices.truncate(args.max_clips.unwrap_or(usize::MAX).max(1));
    if args.list_windows {
        for &i in &indices {
            println!(
                "{}",
                window_line(&dataset.entries()[i], cfg.context_frames, cfg.future_frames)
            );
        }
        return Ok(());
    }
    let device = args.backend.device()?;
    let lpips = lpips_status(args.lpips_weights.as_deref(), &device)?;
    let mut opts = EvalOptions::new(cfg.context_frames, lpips);
    opts.crop = args.crop.unwrap_or_default();
    opts.cross_frame_crop = args.cross_frame_crop;
    opts.depth_alignment = args.depth_align.alignment();
    let mut gallery = Gallery::new(args.report_clips);
    opts.motion_maps = args.motion_images > 0 || gallery.wants_images();
    opts.clip_images = gallery.wants_images();
    atomic::create_dir(&args.out).map_err(|e| InputError(e.to_string()))?;
    // One writer: two evals into one --out would mix their reports.
    let _lock = DirLock::acquire(&args.out, "--out")?;

    warm_up(&model, &dataset, &indices, &opts, args.backend)?;
    let progress = bar(indices.len());
    // Only the first --motion-images clips' maps are kept: a map set is 3 floats a pixel.
    let mut maps = Vec::new();
    let run = evaluate_dataset(&model, &dataset, &indices, &opts, |m| {
        progress.suspend(|| println!("{}", m.summary_line()));
        progress.inc(1);
        gallery.offer(m);
        if let Some(pair) = m.motion_maps.take()
            && maps.len() < args.motion_images
        {
            maps.push((m.clip.clone(), pair));
        }
    })?;
    progress.finish_and_clear();
    let images = motion_images::write_motion_images(&args.out, &maps)?;
    if args.motion_images > 0 {
        eprintln!(
            "motion images: {images} written to {} (clips with motion truth only)",
            args.out.join(motion_images::MOTION_IMAGES_DIR).display()
        );
    }
    let sweep = if args.sweep {
        Some(sweep::run_sweep(
            &args, &setup, &model, &dataset, &indices, &opts,
        )?)
    } else {
        None
    };
    let from = Provenance {
        checkpoint: &args.checkpoint,
        data: &setup.data.root,
        split: match setup.clips {
            Selection::All => "all".into(),
            Selection::Split(Split::HeldOut) => "held_out".into(),
            Selection::Split(other) => format!("{other:?}").to_lowercase(),
        },
        backend: args.backend,
    };
    let report = build_report(from, cfg, &model, &opts, run, sweep);
    shared::write_outputs(&args.out, &report, gallery)?;
    print_summary(&report, &args.out);
    Ok(())
}

/// `<scene> start=<t0> context=<t,..> scored=<t,..>` for one window: the times are the
/// leading integers of the frame file names (`000015_0.png` → 15), or the frame's place in
/// the window where a name has none. `scored` is the first `future` frames after the
/// context (with `--future N` the window stays as long as the checkpoint's, as scored).
fn window_line(entry: &envision4d_data::ClipEntry, context: usize, future: usize) -> String {
    let times: Vec<String> = entry.frame_numbers.iter().map(i64::to_string).collect();
    let (ctx, rest) = times.split_at(context.min(times.len()));
    let scored = &rest[..future.min(rest.len())];
    format!(
        "{} start={} context={} scored={}",
        entry.group,
        times.first().map_or("-", String::as_str),
        ctx.join(","),
        scored.join(",")
    )
}

fn print_summary(report: &Report, out: &Path) {
    print!("{}", summary(report));
    println!(
        "wrote {}/metrics.json, metrics.md, plots and report.html",
        out.display()
    );
}
