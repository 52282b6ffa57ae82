//! What `render` reads: the model (our checkpoint or official weights, with its config) and
//! the context frames (image files resized to the model size, or an exact float tensor).

use crate::model_config::load_model_config;
use crate::InputError;
use anyhow::Result;
use burn::tensor::{Device, Tensor, TensorData};
use clap::Args;
use envision4d_data::{decode_image, Fit, FitMode};
use envision4d_model::checkpoint::{checkpoint_config, load_checkpoint, CheckpointKind};
use envision4d_model::weights::{load_weights, Missing, Unexpected};
use envision4d_model::{Envision4d, ModelConfig};
use std::path::{Path, PathBuf};

/// Frame files a folder may hold (case-insensitive extensions).
const IMAGE_EXTENSIONS: [&str; 3] = ["png", "jpg", "jpeg"];

#[derive(Args, Debug)]
pub struct ModelArgs {
    /// Official weights: the release's Lightning `.ckpt` (or `.pt`/`.safetensors` export).
    #[arg(long, conflicts_with = "checkpoint")]
    weights: Option<PathBuf>,
    /// Key prefix of --weights (default: detected, `encoder.backbone.` for the release).
    #[arg(long, requires = "weights")]
    weights_prefix: Option<String>,
    /// One of our own checkpoints (safetensors carrying its model config).
    #[arg(long)]
    checkpoint: Option<PathBuf>,
    /// Model config: a preset (`paper`, `tiny`) or a TOML file with a `[model]` table.
    #[arg(long)]
    model_config: Option<String>,
}

#[derive(Args, Debug)]
pub struct InputArgs {
    /// Context frames: a folder (sorted by name) or image files, any size; resized to the
    /// model size with a note.
    #[arg(long, num_args = 1..)]
    frames: Vec<PathBuf>,
    /// Index (in name order) of the first context frame taken from --frames.
    #[arg(long, default_value_t = 0, conflicts_with = "input_tensor")]
    start: usize,
    /// Exact float input instead of frames: FILE.safetensors:KEY holding [1, T_c, 3, H, W].
    #[arg(long, conflicts_with = "frames")]
    input_tensor: Option<String>,
}

/// Where the parameters come from.
pub enum Source {
    Checkpoint(PathBuf),
    Weights(PathBuf, Option<String>),
}

impl Source {
    pub fn path(&self) -> &Path {
        match self {
            Source::Checkpoint(p) | Source::Weights(p, _) => p,
        }
    }
}

/// The model config and where the parameters come from, before anything heavy is loaded.
pub fn resolve(args: &ModelArgs) -> Result<(ModelConfig, Source)> {
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

/// Builds the model and loads every parameter (a missing or mis-shaped key is an input error).
pub fn load_model(cfg: &ModelConfig, source: &Source, device: &Device) -> Result<Envision4d> {
    let mut model = Envision4d::new(cfg, device);
    let loaded = match source {
        Source::Weights(p, Some(prefix)) => {
            load_weights(&mut model, p, prefix, Missing::Reject, Unexpected::Reject)
        }
        Source::Checkpoint(p) | Source::Weights(p, None) => {
            load_checkpoint(&mut model, p, CheckpointKind::Full)
        }
    };
    loaded.map_err(|e| InputError(e.to_string()))?;
    Ok(model)
}

/// Reads the context `[1, T_c, 3, H, W]`.
pub fn read_input(args: &InputArgs, cfg: &ModelConfig, device: &Device) -> Result<Tensor<5>> {
    match &args.input_tensor {
        Some(spec) => read_tensor(spec, cfg, device),
        None => read_frames(args, cfg, device),
    }
}

fn read_tensor(spec: &str, cfg: &ModelConfig, device: &Device) -> Result<Tensor<5>> {
    let [h, w] = cfg.image_size;
    let (file, key) = spec
        .rsplit_once(':')
        .ok_or_else(|| InputError(format!("--input-tensor wants FILE:KEY, got {spec:?}")))?;
    let bytes = std::fs::read(file).map_err(|e| InputError(format!("{file}: {e}")))?;
    let st = safetensors::SafeTensors::deserialize(&bytes)
        .map_err(|e| InputError(format!("{file}: {e}")))?;
    let t = st
        .tensor(key)
        .map_err(|_| InputError(format!("{file}: no tensor {key:?}")))?;
    let want = [1, cfg.context_frames, 3, h, w];
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
    Ok(Tensor::from_data(TensorData::new(v, want), device))
}

fn read_frames(args: &InputArgs, cfg: &ModelConfig, device: &Device) -> Result<Tensor<5>> {
    let [h, w] = cfg.image_size;
    let tc = cfg.context_frames;
    let files = frame_files(&args.frames)?;
    let end = args.start + tc;
    if files.len() < end {
        return Err(InputError(format!(
            "need {tc} context frames from index {}, but {} holds {} frame(s)",
            args.start,
            shown(&args.frames),
            files.len()
        ))
        .into());
    }
    if files.len() > tc {
        eprintln!(
            "note: using frames {}..{} of {} in {} as the context",
            args.start,
            end,
            files.len(),
            shown(&args.frames)
        );
    }
    let fit = Fit {
        mode: FitMode::Resize,
        height: h,
        width: w,
    };
    let mut data = Vec::with_capacity(tc * 3 * h * w);
    for f in &files[args.start..end] {
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

fn shown(paths: &[PathBuf]) -> String {
    paths
        .iter()
        .map(|p| p.display().to_string())
        .collect::<Vec<_>>()
        .join(", ")
}

/// The frame files: a single folder's PNG/JPEG files in name order, or the given files.
/// A path that does not exist is named in the error before anything is decoded.
fn frame_files(inputs: &[PathBuf]) -> Result<Vec<PathBuf>> {
    if inputs.is_empty() {
        return Err(
            InputError("give --frames (a folder or image files) or --input-tensor".into()).into(),
        );
    }
    if let Some(missing) = inputs.iter().find(|p| !p.exists()) {
        return Err(InputError(format!("{}: no such file or folder", missing.display())).into());
    }
    if inputs.len() == 1 && inputs[0].is_dir() {
        let dir = &inputs[0];
        let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
            .map_err(|e| InputError(format!("{}: {e}", dir.display())))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| {
                p.is_file()
                    && p.extension().and_then(|e| e.to_str()).is_some_and(|e| {
                        IMAGE_EXTENSIONS.contains(&e.to_ascii_lowercase().as_str())
                    })
            })
            .collect();
        files.sort();
        if files.is_empty() {
            return Err(InputError(format!("{}: no PNG or JPEG frames", dir.display())).into());
        }
        return Ok(files);
    }
    if let Some(dir) = inputs.iter().find(|p| p.is_dir()) {
        return Err(InputError(format!(
            "{}: a folder among several --frames paths; give one folder or image files",
            dir.display()
        ))
        .into());
    }
    Ok(inputs.to_vec())
}
