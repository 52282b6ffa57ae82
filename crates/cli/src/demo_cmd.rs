//! `envision4d demo`: the whole pipeline on one fresh synthetic clip. It generates a clip
//! (new seed each run unless `--seed`), runs a checkpoint (the shipped model by default) on
//! its context frames, scores the predicted future against the generator's exact truth and
//! the three baselines, renders the future views, depth, motion and poses, and prints a
//! table and every path it wrote. See the "Demo" section of docs/EVAL.md.
//!
//! It reuses the other commands' machinery so its files mean what theirs do: `synth`'s
//! generator and writer, `eval`'s report and files ([`crate::eval_cmd::shared`]) and
//! `render`'s writer ([`crate::render_cmd::predict_and_write`]).

mod print;

use crate::backend_choice::{BackendChoice, PrecisionChoice};
use crate::eval_cmd::shared::{self, Provenance};
use crate::render_cmd::{self, OutDir, OutputArgs, Plan, Request};
use crate::report::gallery::Gallery;
use crate::InputError;
use anyhow::{Context, Result};
use burn::tensor::{Tensor, TensorData};
use clap::Args;
use envision4d_data::atomic;
use envision4d_data::synth::{render_clip, write_clip, Preset, SynthConfig, DEFAULT_SUPERSAMPLE};
use envision4d_data::HostClip;
use envision4d_eval::{evaluate_dataset, EvalOptions};
use envision4d_model::checkpoint::checkpoint_config;
use envision4d_model::ModelConfig;
use envision4d_train::config::{DataConfig, DataLayout, Purpose};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::{Path, PathBuf};
use std::time::{SystemTime, UNIX_EPOCH};

/// The shipped model, relative to the repository root (and, as a fallback, to the current
/// folder: a copied-out binary run next to a `models/` folder).
const SHIPPED_MODEL: &str = "models/envision4d-synth-tiny.safetensors";
/// Where docs explain how the shipped model is made.
const TRAINING_DOC: &str = "docs/TRAINING.md";
/// Sub-folder of `--out` holding the clip, in the synthetic layout of `envision4d synth`
/// (so `envision4d eval --data OUT/clip` and `render --frames OUT/clip/clip_000000/rgb` work).
const CLIP_ROOT: &str = "clip";
/// The demo's clip is clip 0 of its seed, named as `envision4d synth` names it.
const CLIP_INDEX: u64 = 0;
const CLIP_NAME: &str = "clip_000000";
/// Sub-folder of `--out` with the render outputs and their `manifest.json`.
const RENDER_DIR: &str = "render";
/// Fresh seeds are drawn below this, so they are short enough to retype.
const FRESH_SEED_RANGE: u64 = 1_000_000;
const PROGRESS_TEMPLATE: &str = "{bar:40} {pos}/{len} {msg}  {elapsed_precise}";

#[derive(Args, Debug)]
pub struct DemoArgs {
    /// One of our checkpoints (safetensors carrying its model config). Default: the shipped
    /// model, models/envision4d-synth-tiny.safetensors.
    #[arg(long)]
    checkpoint: Option<PathBuf>,
    /// World seed of the clip. Default: a fresh one each run (printed, to repeat the run).
    #[arg(long)]
    seed: Option<u64>,
    /// Scene of the clip: urban, static, sharp-turn, fast-approach, far-small-movers,
    /// crossing-truck, low-light, winding, look-around, stopped-pan.
    #[arg(long, default_value = "urban", value_parser = parse_preset)]
    preset: Preset,
    /// Output folder: clip/, metrics.json, metrics.md, plots, render/ (files in it are
    /// replaced).
    #[arg(long, default_value = "demo-out")]
    out: PathBuf,
    #[arg(long, value_enum, default_value_t = BackendChoice::Cpu)]
    backend: BackendChoice,
    /// Float format of the aggregator (the heads stay f32).
    #[arg(long, value_enum, default_value_t = PrecisionChoice::F32)]
    precision: PrecisionChoice,
}

fn parse_preset(s: &str) -> Result<Preset, String> {
    Preset::from_name(s).ok_or_else(|| {
        let names: Vec<&str> = Preset::ALL.iter().map(|p| p.name()).collect();
        format!("unknown preset {s:?}; one of: {}", names.join(", "))
    })
}

/// The shipped model's two candidate locations: in the repository this binary was built
/// from, then under the current folder.
fn shipped_candidates() -> [PathBuf; 2] {
    // crates/cli -> the repository root.
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"))
        .ancestors()
        .nth(2)
        .unwrap_or(Path::new("."));
    [
        repo.join(SHIPPED_MODEL),
        PathBuf::from(".").join(SHIPPED_MODEL),
    ]
}

/// `--checkpoint`, or the first shipped-model location that exists.
fn resolve_checkpoint(arg: Option<&Path>) -> Result<PathBuf> {
    if let Some(path) = arg {
        if !path.is_file() {
            return Err(
                InputError(format!("{}: checkpoint file not found", path.display())).into(),
            );
        }
        return Ok(path.to_path_buf());
    }
    let candidates = shipped_candidates();
    if let Some(found) = candidates.iter().find(|p| p.is_file()) {
        return Ok(found.clone());
    }
    Err(InputError(format!(
        "the shipped model is missing: neither {} nor {} exists. Make it as {TRAINING_DOC} \
         describes (configs/synth-tiny.toml), or pass --checkpoint FILE",
        candidates[0].display(),
        candidates[1].display()
    ))
    .into())
}

/// A seed that differs from run to run: the clock's nanoseconds, mixed (the first draw of
/// the project's seeded RNG from them) so that a coarse clock still spreads over the range.
fn fresh_seed() -> u64 {
    let nanos = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64);
    envision4d_data::rng::Rng::new(nanos).next_u64() % FRESH_SEED_RANGE
}

/// Everything the run resolved before any heavy work.
struct Setup {
    checkpoint: PathBuf,
    cfg: ModelConfig,
    synth: SynthConfig,
    plan: Plan,
}

fn resolve(args: &DemoArgs) -> Result<Setup> {
    let checkpoint = resolve_checkpoint(args.checkpoint.as_deref())?;
    let cfg = checkpoint_config(&checkpoint)
        .map_err(|e| InputError(e.to_string()))?
        .ok_or_else(|| {
            InputError(format!(
                "{} carries no model config (is it one of our checkpoints?)",
                checkpoint.display()
            ))
        })?;
    if args.out.exists() && !args.out.is_dir() {
        return Err(InputError(format!(
            "--out {}: exists and is not a folder",
            args.out.display()
        ))
        .into());
    }
    let synth = SynthConfig {
        width: cfg.image_size[1],
        height: cfg.image_size[0],
        frames: cfg.num_frames(),
        preset: args.preset,
        seed: args.seed.unwrap_or_else(fresh_seed),
        supersample: DEFAULT_SUPERSAMPLE,
    };
    synth.validate().map_err(|e| InputError(e.to_string()))?;
    let plan = Plan::new(&OutputArgs::defaults_into(args.out.join(RENDER_DIR)), &cfg)?;
    Ok(Setup {
        checkpoint,
        cfg,
        synth,
        plan,
    })
}

pub fn run(args: DemoArgs) -> Result<()> {
    let setup = resolve(&args)?;
    let (cfg, synth) = (&setup.cfg, &setup.synth);
    // Printed first, so a run that fails half-way can still be repeated.
    println!(
        "{}",
        print::header(&setup.checkpoint, synth, cfg, args.backend)
    );
    // A backend that cannot start fails before anything is written.
    let device = args.backend.device()?;
    atomic::create_dir(&args.out)
        .map_err(|e| InputError(format!("--out {}: {e}", args.out.display())))?;
    // One writer: two demos into one --out would mix their clips and reports.
    let _lock = envision4d_data::lock::DirLock::acquire(&args.out, "--out")?;

    // Load + one unit per generated frame + evaluation + the render's own units.
    let units = 1 + synth.frames as u64 + 1 + render_cmd::progress_len(&setup.plan);
    let bar = ProgressBar::new(units);
    bar.set_style(ProgressStyle::with_template(PROGRESS_TEMPLATE)?);

    bar.set_message("loading the model");
    let model = shared::load_model(cfg, &setup.checkpoint, args.backend, args.precision)?;
    bar.inc(1);

    bar.set_message("generating the clip");
    let clip_root = args.out.join(CLIP_ROOT);
    let clip_dir = clip_root.join(CLIP_NAME);
    let clip = render_clip(synth, CLIP_INDEX, || bar.inc(1))?;
    write_clip(&clip_dir, &clip).with_context(|| format!("writing {}", clip_dir.display()))?;

    bar.set_message("evaluating");
    // Read back through the dataset, as `eval` reads it: the model sees the 8-bit PNGs.
    let data = DataConfig::new(DataLayout::Synth, clip_root.clone(), 1);
    // The clip was written a moment ago: failing to open, score or read it back is our bug,
    // not the user's input, so these errors are flattened (exit code 1).
    let ours = |e: &dyn std::fmt::Display| anyhow::anyhow!("internal: the generated clip: {e}");
    let dataset = envision4d_train::dataset::open_dataset(&data, cfg, &clip_root, Purpose::Eval)
        .map_err(|e| ours(&e))?;
    // Window 0 is the clip's first T_c + T_f frames (the only window the demo writes).
    let indices = [0];
    let mut opts = EvalOptions::new(cfg.context_frames, shared::lpips_status(None, &device)?);
    // The one clip is shown in report.html.
    let mut gallery = Gallery::new(1);
    (opts.clip_images, opts.motion_maps) = (true, true);
    shared::warm_up(&model, &dataset, &indices, &opts, args.backend).map_err(|e| ours(&e))?;
    let run = evaluate_dataset(&model, &dataset, &indices, &opts, |m| {
        gallery.offer(m);
        bar.inc(1);
    })
    .map_err(|e| ours(&e))?;
    if run.clips.is_empty() {
        // The clip was written a moment ago: failing to read it back is our bug, not input.
        anyhow::bail!(
            "{}: the generated clip could not be read back: {}",
            clip_dir.display(),
            dataset.skip_messages().join("; ")
        );
    }
    let from = Provenance {
        checkpoint: &setup.checkpoint,
        data: &clip_root,
        split: "all".into(),
        backend: args.backend,
    };
    let report = shared::build_report(from, cfg, &model, &opts, run, None);
    let metrics = shared::write_outputs(&args.out, &report, gallery)?;

    let clip = dataset.load(indices[0]).map_err(|e| ours(&e))?;
    let host = HostClip::from_clip(&clip).map_err(|e| ours(&e))?;
    let request = Request {
        plan: &setup.plan,
        out: Some(OutDir::create(&args.out.join(RENDER_DIR))?),
        export: None,
        source: &setup.checkpoint,
    };
    let written = render_cmd::predict_and_write(
        &model,
        context_tensor(&host, cfg.context_frames, &device),
        request,
        &device,
        &bar,
    )?;
    bar.finish_and_clear();

    print!("{}", print::scores(&report));
    let mut paths = vec![(CLIP_ROOT.to_owned(), clip_dir)];
    paths.extend(metrics.into_iter().map(|p| (print::file_label(&p), p)));
    paths.push((RENDER_DIR.to_owned(), args.out.join(RENDER_DIR)));
    if let Some(manifest) = written.manifest {
        paths.push((print::file_label(&manifest), manifest));
    }
    print!("{}", print::paths(&paths));
    Ok(())
}

/// The first `tc` frames of a clip as the model's `[1, T_c, 3, H, W]` input (the clip is
/// already at the model size: it was generated there).
fn context_tensor(clip: &HostClip, tc: usize, device: &burn::tensor::Device) -> Tensor<5> {
    let data: Vec<f32> = clip.frames[..tc].concat();
    Tensor::from_data(
        TensorData::new(data, [1, tc, 3, clip.height, clip.width]),
        device,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Guards the default seed: it stays in the short, retypeable range the output promises.
    #[test]
    fn fresh_seed_is_short() {
        assert!((0..5).all(|_| fresh_seed() < FRESH_SEED_RANGE));
    }

    /// Guards the shipped-model lookup: the repository candidate is the models/ folder at
    /// the workspace root (two levels above this crate), not under crates/.
    #[test]
    fn shipped_model_is_looked_up_at_the_repository_root() {
        let [repo, local] = shipped_candidates();
        assert!(repo.ends_with(SHIPPED_MODEL));
        assert!(repo
            .parent()
            .unwrap()
            .parent()
            .unwrap()
            .join("Cargo.toml")
            .is_file());
        assert_eq!(local, Path::new(".").join(SHIPPED_MODEL));
    }
}
