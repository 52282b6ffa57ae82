//! What `envision4d eval` and `envision4d demo` share: loading a checkpoint, the LPIPS
//! setting, assembling the report, and writing `metrics.json`, `metrics.md` and the plots,
//! so both commands produce the same files for the same numbers.

use crate::backend_choice::{BackendChoice, PrecisionChoice};
use crate::plot;
use crate::report::gallery::Gallery;
use crate::InputError;
use anyhow::{Context, Result};
use burn::tensor::Device;
use clap::ValueEnum;
use envision4d_data::{atomic, ClipDataset};
use envision4d_eval::report::{CropInfo, LpipsInfo, SCHEMA_VERSION};
use envision4d_eval::{
    evaluate_dataset, markdown, mean_metrics, protocol::alignment_name, EvalOptions, EvalRun,
    Report, SweepPoint, TRANSLATION_ALIGNMENT, TRANSLATION_UNIT,
};
use envision4d_losses::{LpipsNet, LpipsStatus};
use envision4d_model::checkpoint::{load_checkpoint, CheckpointKind};
use envision4d_model::{Envision4d, ModelConfig};
use std::path::{Path, PathBuf};

/// File names written into the output folder.
pub const METRICS_JSON: &str = "metrics.json";
pub const METRICS_MD: &str = "metrics.md";
const HORIZON_PNG: &str = "metrics_vs_horizon.png";
const TIME_PNG: &str = "metrics_vs_time.png";
const PARETO_PNG: &str = "pareto.png";

/// The name `--backend` spells (`cpu`, `wgpu`), as the report records it.
pub fn backend_name(b: BackendChoice) -> String {
    b.to_possible_value()
        .map_or_else(|| format!("{b:?}"), |v| v.get_name().to_owned())
}

/// Builds the model of `cfg`, loads every parameter of our checkpoint (a missing or
/// mis-shaped key is an input error naming the file) and puts it in `precision`.
pub fn load_model(
    cfg: &ModelConfig,
    checkpoint: &Path,
    backend: BackendChoice,
    precision: PrecisionChoice,
) -> Result<Envision4d> {
    let device = backend.device()?;
    precision.check(&device)?;
    let mut model = Envision4d::new(cfg, &device);
    load_checkpoint(&mut model, checkpoint, CheckpointKind::Full)
        .map_err(|e| InputError(e.to_string()))?;
    Ok(model.with_precision(precision.precision()))
}

/// The LPIPS network from `weights` (or the reason it is not reported, noted on stderr).
pub fn lpips_status(weights: Option<&Path>, device: &Device) -> Result<LpipsStatus> {
    let lpips = LpipsStatus::from_path(weights, LpipsNet::Vgg, device)
        .map_err(|e| InputError(e.to_string()))?;
    if let Some(note) = lpips.notice() {
        eprintln!("note: {note}");
    }
    Ok(lpips)
}

/// On a JIT backend (wgpu, CUDA) the first pass compiles kernels; one untimed clip keeps that out
/// of the reported times. The CPU backend has nothing to compile.
pub fn warm_up(
    model: &Envision4d,
    dataset: &ClipDataset,
    indices: &[usize],
    opts: &EvalOptions,
    backend: BackendChoice,
) -> Result<()> {
    if backend == BackendChoice::Cpu {
        return Ok(());
    }
    evaluate_dataset(model, dataset, &indices[..1], opts, |_| {})?;
    Ok(())
}

/// Where the scored numbers came from, as the report names it.
pub struct Provenance<'a> {
    pub checkpoint: &'a Path,
    pub data: &'a Path,
    /// `all`, `held_out` or `val`.
    pub split: String,
    pub backend: BackendChoice,
}

/// The whole report of one evaluation run (and its sweep, if any).
pub fn build_report(
    from: Provenance,
    cfg: &ModelConfig,
    model: &Envision4d,
    opts: &EvalOptions,
    run: EvalRun,
    sweep: Option<Vec<SweepPoint>>,
) -> Report {
    let lpips = LpipsInfo {
        available: opts.lpips.get().is_some(),
        reason: match &opts.lpips {
            LpipsStatus::Available(_) => None,
            LpipsStatus::Unavailable { reason } => Some(reason.clone()),
        },
    };
    Report {
        schema_version: SCHEMA_VERSION,
        checkpoint: from.checkpoint.display().to_string(),
        data: from.data.display().to_string(),
        split: from.split,
        backend: backend_name(from.backend),
        precision: model.precision().name().into(),
        context_frames: cfg.context_frames,
        future_frames: model.future_frames(),
        image_size: cfg.image_size,
        input_size: cfg.image_size,
        crop: CropInfo::from(opts.crop),
        cross_frame_crop: CropInfo::from(opts.cross_frame_crop_for(cfg.image_size)),
        depth_alignment: alignment_name(opts.depth_alignment).into(),
        translation_alignment: TRANSLATION_ALIGNMENT.into(),
        translation_unit: TRANSLATION_UNIT.into(),
        lpips,
        raster: opts.raster,
        clips_evaluated: run.clips.len(),
        clips_skipped: run.skipped,
        mean: mean_metrics(&run.clips),
        clips: run.clips,
        sweep,
    }
}

/// Writes `metrics.json`, `metrics.md`, the two plots, (with a sweep) `pareto.png` and
/// `report.html` (with `gallery`'s clips) into `out` atomically; returns the paths written,
/// in that order.
pub fn write_outputs(out: &Path, report: &Report, gallery: Gallery) -> Result<Vec<PathBuf>> {
    atomic::create_dir(out).map_err(|e| InputError(e.to_string()))?;
    let mut written = Vec::new();
    let mut write = |name: &str, bytes: &[u8]| -> Result<()> {
        let path = out.join(name);
        atomic::write_bytes(&path, bytes).with_context(|| format!("writing {}", path.display()))?;
        written.push(path);
        Ok(())
    };
    let md = markdown(report);
    write(METRICS_JSON, report.to_json().as_bytes())?;
    write(METRICS_MD, md.as_bytes())?;
    let png = |r: Result<Vec<u8>, String>| r.map_err(anyhow::Error::msg);
    write(HORIZON_PNG, &png(plot::horizon_png(report.mean.as_ref()))?)?;
    write(TIME_PNG, &png(plot::time_png(report))?)?;
    if let Some(points) = &report.sweep {
        write(PARETO_PNG, &png(plot::pareto_png(points))?)?;
    }
    let page = crate::report::write_report(out, report, &md, &written[2..], gallery)?;
    written.push(page);
    Ok(written)
}
