//! What `render` writes and where: the `--out` options, the time steps to render, and the
//! output folder with its `manifest.json` (every file written, with its kind and time step).

use crate::InputError;
use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use envision4d_data::lock::DirLock;
use envision4d_model::ModelConfig;
use serde::Serialize;
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// A context pixel is dynamic when its displacement to the next timestamp exceeds this
/// (scene units; metres for a model trained on metric ground truth). 0.1 m per 10 Hz frame is
/// 1 m/s, the speed above which the Waymo/STORM dynamic masks count an object as moving.
pub const DEFAULT_DYNAMIC_THRESHOLD: f64 = 0.1;
/// File name of the manifest in `--out`.
pub const MANIFEST: &str = "manifest.json";
const PRODUCER: &str = "envision4d render";
/// Outputs written when `--out` is given without `--outputs`.
const DEFAULT_OUTPUTS: [Output; 4] = [Output::Views, Output::Depth, Output::Motion, Output::Poses];

#[derive(Args, Debug)]
pub struct OutputArgs {
    /// Output folder for images, depth, motion maps, poses, PLYs and manifest.json.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Future frames to render, 1..=T_f of the model (default: all T_f).
    #[arg(long)]
    future: Option<usize>,
    /// What to write into --out, comma-separated (default: views,depth,motion,poses).
    #[arg(long, value_enum, value_delimiter = ',', requires = "out")]
    outputs: Vec<Output>,
    /// Also render each future view from its camera moved sideways by this much along its own
    /// x axis (right is positive; scene units). Repeatable. The release's lane-shift pass
    /// (`extrinsics @ T`, world x by +0.03) corresponds to about --lane-shift=-0.03.
    #[arg(long, allow_negative_numbers = true, requires = "out")]
    lane_shift: Vec<f64>,
    /// Displacement to the next timestamp above which a pixel is dynamic (scene units).
    #[arg(long, default_value_t = DEFAULT_DYNAMIC_THRESHOLD)]
    dynamic_threshold: f64,
}

impl OutputArgs {
    /// `--out DIR` and nothing else: the default outputs of every future frame, no lane
    /// shift, the default dynamic threshold (what `envision4d demo` renders).
    pub fn defaults_into(out: PathBuf) -> OutputArgs {
        OutputArgs {
            out: Some(out),
            future: None,
            outputs: Vec::new(),
            lane_shift: Vec::new(),
            dynamic_threshold: DEFAULT_DYNAMIC_THRESHOLD,
        }
    }
}

/// One kind of output of `--out`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, ValueEnum)]
pub enum Output {
    /// Rendered colour of every context and future view (PNG + linear EXR).
    Views,
    /// Rendered expected z-depth (EXR) and a colour-mapped PNG.
    Depth,
    /// Dynamic mask (PNG) and scene flow (EXR + colour PNG) of every context frame.
    Motion,
    /// poses.json and one camera JSON per rendered view.
    Poses,
    /// Gaussians of every rendered time step as 3DGS PLY (+ the camera JSONs).
    Ply,
    /// Everything above.
    All,
}

/// Whether a time step is an input frame or a predicted one.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Role {
    Context,
    Future,
}

/// A timestamp of the model (0..N), named `context_00`, `future_00`, ... in file names.
#[derive(Debug, Clone)]
pub struct Step {
    pub index: usize,
    pub role: Role,
    pub name: String,
}

/// The validated `--out` request.
#[derive(Debug, Clone)]
pub struct Plan {
    pub out: Option<PathBuf>,
    outputs: BTreeSet<Output>,
    pub context: usize,
    /// Future frames rendered (`--future`).
    pub future: usize,
    /// All timestamps the model predicts (T_c + T_f).
    pub total: usize,
    pub lane_shifts: Vec<f64>,
    pub dynamic_threshold: f64,
    pub image_size: [usize; 2],
}

impl Plan {
    /// Checks the options against the model config before any heavy work.
    pub fn new(args: &OutputArgs, cfg: &ModelConfig) -> Result<Plan> {
        let tf = cfg.future_frames;
        let future = args.future.unwrap_or(tf);
        if !(1..=tf).contains(&future) {
            return Err(InputError(format!(
                "--future {future}: the model predicts {tf} future frame(s), use 1..={tf}"
            ))
            .into());
        }
        let t = args.dynamic_threshold;
        if !(t.is_finite() && t >= 0.0) {
            return Err(
                InputError(format!("--dynamic-threshold {t}: need a finite value >= 0")).into(),
            );
        }
        if let Some(s) = args.lane_shift.iter().find(|s| !s.is_finite()) {
            return Err(InputError(format!("--lane-shift {s}: need a finite offset")).into());
        }
        let mut outputs: BTreeSet<Output> = if args.outputs.is_empty() {
            DEFAULT_OUTPUTS.into_iter().collect()
        } else {
            args.outputs.iter().copied().collect()
        };
        if outputs.remove(&Output::All) {
            outputs.extend([
                Output::Views,
                Output::Depth,
                Output::Motion,
                Output::Poses,
                Output::Ply,
            ]);
        }
        if let Some(out) = &args.out
            && out.exists()
            && !out.is_dir()
        {
            return Err(InputError(format!(
                "--out {}: exists and is not a folder",
                out.display()
            ))
            .into());
        }
        Ok(Plan {
            out: args.out.clone(),
            outputs,
            context: cfg.context_frames,
            future,
            total: cfg.num_frames(),
            lane_shifts: args.lane_shift.clone(),
            dynamic_threshold: t,
            image_size: cfg.image_size,
        })
    }

    pub fn wants(&self, o: Output) -> bool {
        self.out.is_some() && self.outputs.contains(&o)
    }

    /// Camera JSONs are written with the poses and next to PLYs (`envision4d splat` needs both).
    pub fn wants_cameras(&self) -> bool {
        self.wants(Output::Poses) || self.wants(Output::Ply)
    }

    /// Whether any time step has to be rasterized.
    pub fn renders(&self) -> bool {
        self.wants(Output::Views)
            || self.wants(Output::Depth)
            || self.wants(Output::Ply)
            || (self.out.is_some() && !self.lane_shifts.is_empty())
    }

    /// Whether the Gaussians (depth, Gaussian and motion heads) are needed at all; a poses-only
    /// request runs the backbone and camera head alone.
    pub fn needs_scene(&self) -> bool {
        self.renders() || self.wants(Output::Motion)
    }

    /// Context steps, then the first `future` future steps.
    pub fn steps(&self) -> Vec<Step> {
        (0..self.context + self.future)
            .map(|i| self.step(i))
            .collect()
    }

    pub fn step(&self, index: usize) -> Step {
        let (role, name) = if index < self.context {
            (Role::Context, format!("context_{index:02}"))
        } else {
            (Role::Future, format!("future_{:02}", index - self.context))
        };
        Step { index, role, name }
    }
}

/// Name suffix of a lane-shifted view, e.g. `lane+1.50`.
pub fn lane_suffix(shift: f64) -> String {
    format!("lane{shift:+.2}")
}

/// Kind of a file in the manifest.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FileKind {
    Rgb,
    Depth,
    DepthColor,
    DynamicMask,
    SceneFlow,
    SceneFlowColor,
    LaneShiftRgb,
    Gaussians,
    Camera,
    Poses,
}

#[derive(Debug, Serialize)]
struct Entry {
    path: String,
    kind: FileKind,
    #[serde(skip_serializing_if = "Option::is_none")]
    step: Option<String>,
}

/// The output folder: makes sub-folders on demand and records each written file.
pub struct OutDir {
    root: PathBuf,
    entries: Vec<Entry>,
    /// One writer: two renders into one --out would mix their files and manifests.
    _lock: DirLock,
}

impl OutDir {
    pub fn create(root: &Path) -> Result<OutDir> {
        std::fs::create_dir_all(root)
            .map_err(|e| InputError(format!("--out {}: {e}", root.display())))?;
        let lock = DirLock::acquire(root, "--out")?;
        Ok(OutDir {
            root: root.to_path_buf(),
            entries: Vec::new(),
            _lock: lock,
        })
    }

    /// `root/sub/name`, creating `root/sub`.
    pub fn path(&self, sub: &str, name: &str) -> Result<PathBuf> {
        let dir = self.root.join(sub);
        std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
        Ok(dir.join(name))
    }

    /// Records a file that was written (paths in the manifest are relative to the root).
    pub fn record(&mut self, path: &Path, kind: FileKind, step: Option<&Step>) {
        let rel = path.strip_prefix(&self.root).unwrap_or(path);
        self.entries.push(Entry {
            path: rel.to_string_lossy().replace('\\', "/"),
            kind,
            step: step.map(|s| s.name.clone()),
        });
    }

    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// Writes `manifest.json`: every file written before it (not itself).
    pub fn finish(self, plan: &Plan, source: &Path) -> Result<PathBuf> {
        let path = self.root.join(MANIFEST);
        let manifest = Manifest {
            producer: PRODUCER,
            model_source: source.display().to_string(),
            context_frames: plan.context,
            future_frames_rendered: plan.future,
            image_size: plan.image_size,
            lane_shifts: &plan.lane_shifts,
            dynamic_threshold: plan.dynamic_threshold,
            files: &self.entries,
        };
        let text = serde_json::to_string_pretty(&manifest)?;
        envision4d_data::atomic::write_bytes(&path, text.as_bytes())
            .with_context(|| format!("writing {}", path.display()))?;
        Ok(path)
    }
}

/// `manifest.json`, fields in this order.
#[derive(Serialize)]
struct Manifest<'a> {
    producer: &'static str,
    model_source: String,
    context_frames: usize,
    future_frames_rendered: usize,
    /// `[h, w]` of every image.
    image_size: [usize; 2],
    lane_shifts: &'a [f64],
    dynamic_threshold: f64,
    files: &'a [Entry],
}
