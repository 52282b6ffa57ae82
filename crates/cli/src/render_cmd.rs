//! `envision4d render`: run Envision4D on context frames and export its predictions.

use crate::backend_choice::BackendChoice;
use crate::model_config::load_model_config;
use crate::InputError;
use anyhow::{Context, Result};
use burn::tensor::{Device, Tensor, TensorData};
use clap::Args;
use envision4d_data::{decode_image, Fit, FitMode};
use envision4d_model::adapter::OpacityMapping;
use envision4d_model::checkpoint::{checkpoint_config, load_checkpoint, CheckpointKind};
use envision4d_model::model::Heads;
use envision4d_model::weights::{load_weights, Missing, Unexpected};
use envision4d_model::{Envision4d, ModelConfig};
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Args, Debug)]
pub struct RenderArgs {
    /// Official weights: the release's Lightning `.ckpt` (or `.pt`/`.safetensors` export).
    #[arg(long, conflicts_with = "checkpoint")]
    weights: Option<PathBuf>,
    /// Key prefix of --weights (default: detected, `encoder.backbone.` for the release).
    #[arg(long, requires = "weights")]
    weights_prefix: Option<String>,
    /// One of our own checkpoints (safetensors carrying its model config).
    #[arg(long)]
    checkpoint: Option<PathBuf>,
    /// Model config: a preset (`paper`, `tiny`) or a TOML file with a [model] table.
    #[arg(long)]
    model_config: Option<String>,
    /// Context frames: a folder (sorted by name) or image files; resized to the model size.
    #[arg(long, num_args = 1..)]
    frames: Vec<PathBuf>,
    /// Exact float input instead of frames: FILE.safetensors:KEY holding [1, T_c, 3, H, W].
    #[arg(long, conflicts_with = "frames")]
    input_tensor: Option<String>,
    /// Write raw and adapted predictions (fixture key names) to this safetensors file.
    #[arg(long)]
    export_predictions: PathBuf,
    #[arg(long, value_enum, default_value_t = BackendChoice::Cpu)]
    backend: BackendChoice,
}

pub fn run(args: RenderArgs) -> Result<()> {
    let t0 = Instant::now();
    let (cfg, source) = resolve(&args)?;
    let device = args.backend.device();
    let mut model = Envision4d::new(&cfg, &device);
    match &source {
        Source::Checkpoint(p) => {
            load_checkpoint(&mut model, p, CheckpointKind::Full)
                .map_err(|e| InputError(e.to_string()))?;
        }
        Source::Weights(p, Some(prefix)) => {
            load_weights(&mut model, p, prefix, Missing::Reject, Unexpected::Reject)
                .map_err(|e| InputError(e.to_string()))?;
        }
        Source::Weights(p, None) => {
            load_checkpoint(&mut model, p, CheckpointKind::Full)
                .map_err(|e| InputError(e.to_string()))?;
        }
    }
    let t_load = t0.elapsed();
    let images = read_input(&args, &cfg, &device)?;
    let t1 = Instant::now();
    let pred = model.forward(images, Heads::ALL);
    let adapted = model
        .adapt(&pred, OpacityMapping::default(), 0)
        .context("all heads ran")?;
    let mut out: Vec<(String, Vec<usize>, Vec<f32>)> = Vec::new();
    let bb = &pred.backbone;
    push(&mut out, "pose_enc", bb.pose_enc());
    push(&mut out, "adapter/extrinsics", bb.extrinsics.clone());
    push(&mut out, "adapter/intrinsics", bb.intrinsics.clone());
    if let (Some(d), Some(c), Some(g), Some(m)) = (
        &pred.depth,
        &pred.depth_conf,
        &pred.gaussians,
        &pred.motion_enc,
    ) {
        push(&mut out, "depth", d.clone());
        push(&mut out, "depth_conf", c.clone());
        push(&mut out, "gaussians", g.clone());
        push(&mut out, "motion_enc", m.clone());
    }
    push(&mut out, "adapter/means", adapted.means);
    push(&mut out, "adapter/scales", adapted.scales);
    push(&mut out, "adapter/rotations", adapted.rotations);
    push(&mut out, "adapter/colors", adapted.colors);
    push(&mut out, "adapter/opacities", adapted.opacities);
    push(&mut out, "adapter/motions", adapted.motions);
    let t_forward = t1.elapsed();
    write_safetensors(&args.export_predictions, &out)?;
    println!(
        "loaded in {:.1} s, forward ({} context + {} future frames at {}x{}) in {:.2} s on {:?} -> {}",
        t_load.as_secs_f64(),
        cfg.context_frames,
        cfg.future_frames,
        cfg.image_size[0],
        cfg.image_size[1],
        t_forward.as_secs_f64(),
        args.backend,
        args.export_predictions.display()
    );
    Ok(())
}

enum Source {
    Checkpoint(PathBuf),
    Weights(PathBuf, Option<String>),
}

fn resolve(args: &RenderArgs) -> Result<(ModelConfig, Source)> {
    match (&args.checkpoint, &args.weights) {
        (Some(ckpt), None) => {
            let cfg = match &args.model_config {
                Some(spec) => load_model_config(spec)?,
                None => checkpoint_config(ckpt)
                    .map_err(|e| InputError(e.to_string()))?
                    .ok_or_else(|| {
                        InputError(format!(
                            "{} carries no model config: pass --model-config",
                            ckpt.display()
                        ))
                    })?,
            };
            Ok((cfg, Source::Checkpoint(ckpt.clone())))
        }
        (None, Some(w)) => {
            let spec = args.model_config.as_deref().ok_or_else(|| {
                InputError("--weights needs --model-config (a preset or a TOML file)".into())
            })?;
            Ok((
                load_model_config(spec)?,
                Source::Weights(w.clone(), args.weights_prefix.clone()),
            ))
        }
        _ => Err(InputError("give --checkpoint or --weights".into()).into()),
    }
}

fn read_input(args: &RenderArgs, cfg: &ModelConfig, device: &Device) -> Result<Tensor<5>> {
    let [h, w] = cfg.image_size;
    let tc = cfg.context_frames;
    if let Some(spec) = &args.input_tensor {
        let (file, key) = spec
            .rsplit_once(':')
            .ok_or_else(|| InputError(format!("--input-tensor wants FILE:KEY, got {spec:?}")))?;
        let bytes = std::fs::read(file).map_err(|e| InputError(format!("{file}: {e}")))?;
        let st = safetensors::SafeTensors::deserialize(&bytes)
            .map_err(|e| InputError(format!("{file}: {e}")))?;
        let t = st
            .tensor(key)
            .map_err(|_| InputError(format!("{file}: no tensor {key:?}")))?;
        let want = [1, tc, 3, h, w];
        if t.shape() != want || t.dtype() != safetensors::Dtype::F32 {
            return Err(InputError(format!(
                "{file}:{key}: expected F32 {want:?}, got {:?} {:?}",
                t.dtype(),
                t.shape()
            ))
            .into());
        }
        let v: Vec<f32> = t
            .data()
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect();
        return Ok(Tensor::from_data(TensorData::new(v, want), device));
    }
    let files = frame_files(&args.frames)?;
    if files.len() < tc {
        return Err(InputError(format!(
            "need {tc} context frames, got {} ({:?})",
            files.len(),
            args.frames
        ))
        .into());
    }
    let fit = Fit {
        mode: FitMode::Resize,
        height: h,
        width: w,
    };
    let mut data = Vec::with_capacity(tc * 3 * h * w);
    for f in &files[..tc] {
        let img = decode_image(f).map_err(|e| InputError(e.to_string()))?;
        if (img.height, img.width) != (h, w) {
            eprintln!(
                "note: {} is {}x{}, resized to the model size {h}x{w}",
                f.display(),
                img.height,
                img.width
            );
        }
        let img = fit.apply(&img, f).map_err(|e| InputError(e.to_string()))?;
        data.extend(img.to_chw());
    }
    Ok(Tensor::from_data(
        TensorData::new(data, [1, tc, 3, h, w]),
        device,
    ))
}

const IMAGE_EXTENSIONS: [&str; 3] = ["png", "jpg", "jpeg"];

fn frame_files(inputs: &[PathBuf]) -> Result<Vec<PathBuf>> {
    if inputs.is_empty() {
        return Err(
            InputError("give --frames (a folder or image files) or --input-tensor".into()).into(),
        );
    }
    if inputs.len() == 1 && inputs[0].is_dir() {
        let dir = &inputs[0];
        let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
            .map_err(|e| InputError(format!("{}: {e}", dir.display())))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| {
                p.extension()
                    .and_then(|e| e.to_str())
                    .is_some_and(|e| IMAGE_EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()))
            })
            .collect();
        files.sort();
        if files.is_empty() {
            return Err(InputError(format!("{}: no PNG or JPEG frames", dir.display())).into());
        }
        return Ok(files);
    }
    Ok(inputs.to_vec())
}

fn push<const D: usize>(out: &mut Vec<(String, Vec<usize>, Vec<f32>)>, key: &str, t: Tensor<D>) {
    let shape = t.dims().to_vec();
    let v = t
        .into_data()
        .convert::<f32>()
        .try_into_vec::<f32>()
        .expect("f32 data");
    out.push((key.to_string(), shape, v));
}

/// Writes the tensors atomically (temporary file + rename).
fn write_safetensors(path: &Path, tensors: &[(String, Vec<usize>, Vec<f32>)]) -> Result<()> {
    let bytes: Vec<Vec<u8>> = tensors
        .iter()
        .map(|(_, _, v)| v.iter().flat_map(|x| x.to_le_bytes()).collect())
        .collect();
    let views = tensors
        .iter()
        .zip(&bytes)
        .map(|((k, shape, _), b)| {
            Ok((
                k.clone(),
                safetensors::tensor::TensorView::new(safetensors::Dtype::F32, shape.clone(), b)?,
            ))
        })
        .collect::<Result<Vec<_>, safetensors::SafeTensorError>>()?;
    let tmp = path.with_file_name(format!(
        ".{}.tmp-{}",
        path.file_name()
            .map(|n| n.to_string_lossy().to_string())
            .unwrap_or_default(),
        std::process::id()
    ));
    let meta = std::collections::HashMap::from([(
        "producer".to_string(),
        "envision4d render".to_string(),
    )]);
    safetensors::tensor::serialize_to_file(views, Some(meta), &tmp)
        .with_context(|| format!("writing {}", path.display()))?;
    std::fs::rename(&tmp, path).with_context(|| format!("moving {} into place", path.display()))
}
