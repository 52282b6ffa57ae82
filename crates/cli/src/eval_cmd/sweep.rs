//! `eval --sweep`: the quality-against-time sweep, one knob at a time from the base setting
//! (`docs/EVAL.md`), each point warmed up and timed on the same clips.

use super::shared::{backend_name, load_model, warm_up};
use super::{bar, EvalArgs, Setup};
use crate::backend_choice::BackendChoice;
use anyhow::{Context, Result};
use envision4d_data::ClipDataset;
use envision4d_eval::sweep::{mark_pareto, plan, summarize, with_horizon, SweepBase};
use envision4d_eval::{evaluate_dataset, EvalOptions, SweepPoint};
use envision4d_model::Envision4d;

/// Evaluates every setting the sweep plans (loading the model once per extra backend) and
/// returns their points with the Pareto front marked.
pub(super) fn run_sweep(
    args: &EvalArgs,
    setup: &Setup,
    model: &Envision4d,
    dataset: &ClipDataset,
    indices: &[usize],
    opts: &EvalOptions,
) -> Result<Vec<SweepPoint>> {
    let cfg = &setup.model;
    let base = SweepBase {
        backend: backend_name(args.backend),
        future_frames: model.future_frames(),
        input_size: cfg.image_size,
        patch_size: cfg.patch_size,
        raster: opts.raster,
    };
    let names: Vec<String> = args
        .sweep_backends
        .iter()
        .map(|&b| backend_name(b))
        .collect();
    let settings = plan(&base, &names);
    let mut models: Vec<(BackendChoice, Envision4d)> = vec![(args.backend, model.clone())];
    let progress = bar(settings.len() * indices.len());
    let mut points = Vec::with_capacity(settings.len());
    for s in &settings {
        let choice = std::iter::once(args.backend)
            .chain(args.sweep_backends.iter().copied())
            .find(|&b| backend_name(b) == s.backend)
            .context("sweep backend is one of the requested")?;
        if !models.iter().any(|(b, _)| *b == choice) {
            models.push((
                choice,
                load_model(cfg, &args.checkpoint, choice, args.precision)?,
            ));
        }
        let full = &models
            .iter()
            .find(|(b, _)| *b == choice)
            .context("sweep model loaded")?
            .1;
        let m = if s.horizon < base.future_frames {
            // The sweep planned this horizon itself: out of range is a bug, not input.
            with_horizon(full, s.horizon).map_err(|e| anyhow::anyhow!("internal: {e}"))?
        } else {
            full.clone()
        };
        // Every setting has new shapes or settings: warm JIT backends up per setting.
        warm_up(&m, dataset, indices, &s.options(opts), choice)?;
        let run = evaluate_dataset(&m, dataset, indices, &s.options(opts), |_| progress.inc(1))?;
        if let Some(p) = summarize(s, &run.clips) {
            progress.suspend(|| {
                println!(
                    "sweep {:<22} PSNR {:6.2} dB  SSIM {:.4}  | {:.3} s/clip (encoder {:.3} + decoder {:.3})",
                    p.value,
                    p.psnr, p.ssim, p.time_s, p.encoder_s, p.decoder_s
                );
            });
            points.push(p);
        }
    }
    progress.finish_and_clear();
    mark_pareto(&mut points);
    Ok(points)
}
