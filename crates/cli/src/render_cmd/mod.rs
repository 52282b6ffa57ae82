//! `envision4d render`: run Envision4D on context frames and write what it predicts.
//!
//! - `--out DIR`: rendered context and future views (PNG + linear EXR), expected depth (EXR +
//!   colour PNG), dynamic mask and scene flow of the context frames, lane-shifted future views,
//!   `poses.json` and camera JSONs, optionally the Gaussians of every step as 3DGS PLY, and a
//!   `manifest.json` listing every file (see docs/RENDER.md).
//! - `--export-predictions FILE`: raw and adapted predictions as safetensors.
//!
//! Modules: [`input`] (model and frames), [`outputs`] (options, steps, manifest), [`views`]
//! (rasterizing), [`motion_maps`], [`poses`], [`colormap`], [`export`].

pub(crate) mod colormap;
mod export;
mod input;
mod motion_maps;
mod outputs;
mod poses;
mod views;

use crate::backend_choice::{BackendChoice, PrecisionChoice};
use crate::InputError;
use anyhow::{anyhow, Result};
use burn::tensor::{Device, Tensor};
use clap::Args;
use envision4d_model::model::Predictions;
use envision4d_model::scene::{predict_cameras, predict_scene, Scene};
use envision4d_model::Envision4d;
use indicatif::{ProgressBar, ProgressStyle};
use outputs::Output;
pub use outputs::{OutDir, OutputArgs, Plan};
use poses::HostCameras;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

const PROGRESS_TEMPLATE: &str = "{bar:40} {pos}/{len} {msg}  {elapsed_precise}";

#[derive(Args, Debug)]
pub struct RenderArgs {
    #[command(flatten)]
    model: input::ModelArgs,
    #[command(flatten)]
    input: input::InputArgs,
    #[command(flatten)]
    output: outputs::OutputArgs,
    /// Write raw and adapted predictions (fixture key names) to this safetensors file.
    #[arg(long)]
    export_predictions: Option<PathBuf>,
    #[arg(long, value_enum, default_value_t = BackendChoice::Cpu)]
    backend: BackendChoice,
    /// Float format of the aggregator (the heads stay f32).
    #[arg(long, value_enum, default_value_t = PrecisionChoice::F32)]
    precision: PrecisionChoice,
}

/// What the forward pass produced: everything, or the cameras alone.
enum Pass {
    Scene(Scene),
    PosesOnly(Predictions),
}

impl Pass {
    fn pred(&self) -> &Predictions {
        match self {
            Pass::Scene(s) => &s.pred,
            Pass::PosesOnly(p) => p,
        }
    }

    fn scene(&self) -> Result<&Scene> {
        match self {
            Pass::Scene(s) => Ok(s),
            Pass::PosesOnly(_) => Err(anyhow!("internal: the Gaussians were not predicted")),
        }
    }
}

/// Reads a tensor back to the host as f32.
pub(crate) fn host<const D: usize>(t: Tensor<D>) -> Result<Vec<f32>> {
    t.into_data()
        .convert::<f32>()
        .try_into_vec::<f32>()
        .map_err(|e| anyhow!("reading a tensor back: {e:?}"))
}

pub fn run(args: RenderArgs) -> Result<()> {
    let t0 = Instant::now();
    // Everything that can be checked cheaply is checked before the model is loaded.
    let (cfg, source) = input::resolve(&args.model)?;
    let plan = Plan::new(&args.output, &cfg)?;
    if plan.out.is_none() && args.export_predictions.is_none() {
        return Err(InputError(
            "nothing to write: give --out DIR and/or --export-predictions FILE".into(),
        )
        .into());
    }
    let out_dir = plan.out.as_deref().map(OutDir::create).transpose()?;
    let device = args.backend.device()?;
    args.precision.check(&device)?;
    let model =
        input::load_model(&cfg, &source, &device)?.with_precision(args.precision.precision());
    let images = input::read_input(&args.input, &cfg, &device)?;
    let t_load = t0.elapsed();

    let export = args.export_predictions.as_deref();
    let bar = ProgressBar::new(progress_len(&plan));
    bar.set_style(ProgressStyle::with_template(PROGRESS_TEMPLATE)?);
    let request = Request {
        plan: &plan,
        out: out_dir,
        export,
        source: source.path(),
    };
    let written = predict_and_write(&model, images, request, &device, &bar)?;
    let mut summary = vec![format!(
        "loaded in {:.1} s, forward ({} context + {} future frames at {}x{}) in {:.2} s on {:?}",
        t_load.as_secs_f64(),
        cfg.context_frames,
        cfg.future_frames,
        cfg.image_size[0],
        cfg.image_size[1],
        written.forward.as_secs_f64(),
        args.backend,
    )];
    if args.precision != PrecisionChoice::F32 {
        summary.push(format!(
            "aggregator in {}",
            args.precision.precision().name()
        ));
    }
    summary.extend(written.notes);
    bar.finish_and_clear();
    println!("{}", summary.join("; "));
    Ok(())
}

/// What [`predict_and_write`] writes.
pub struct Request<'a> {
    pub plan: &'a Plan,
    /// The `--out` folder (already created), or `None` for predictions only.
    pub out: Option<OutDir>,
    /// `--export-predictions FILE`.
    pub export: Option<&'a Path>,
    /// Where the parameters came from (recorded in the manifest).
    pub source: &'a Path,
}

/// What [`predict_and_write`] did.
pub struct Written {
    /// Seconds of the forward pass (all heads, or the cameras alone).
    pub forward: Duration,
    /// One phrase per thing written, for the caller's summary line.
    pub notes: Vec<String>,
    /// `manifest.json` of the output folder, when there was one.
    pub manifest: Option<PathBuf>,
}

/// Progress units of [`predict_and_write`]: the forward pass, each rendered time step and
/// each context frame's motion maps.
pub fn progress_len(plan: &Plan) -> u64 {
    let render_steps = views::steps_to_render(plan).len();
    let motion_frames = if plan.wants(Output::Motion) {
        plan.context
    } else {
        0
    };
    (1 + render_steps + motion_frames) as u64
}

/// Runs an already loaded model on the context `images` (`[1, T_c, 3, H, W]` on `device`)
/// and writes what `request` asks for; `bar` advances by [`progress_len`] units. `render`
/// and `demo` share it, so both write the same files and manifest.
pub fn predict_and_write(
    model: &Envision4d,
    images: Tensor<5>,
    request: Request,
    device: &Device,
    bar: &ProgressBar,
) -> Result<Written> {
    let Request {
        plan,
        out,
        export,
        source,
    } = request;
    let needs_scene = plan.needs_scene() || export.is_some();
    bar.set_message(if needs_scene {
        "forward (all heads)"
    } else {
        "forward (poses only)"
    });
    let t1 = Instant::now();
    let pass = if needs_scene {
        Pass::Scene(predict_scene(model, images)?)
    } else {
        Pass::PosesOnly(predict_cameras(model, images))
    };
    // GPU backends queue the work and read back lazily: wait for it, or the time would be
    // the launches' alone.
    device
        .sync()
        .map_err(|e| anyhow!("the device failed during the forward pass: {e:?}"))?;
    let forward = t1.elapsed();
    bar.inc(1);
    let mut notes = Vec::new();
    if let Some(path) = export {
        export::export_predictions(path, pass.scene()?)?;
        notes.push(format!("predictions -> {}", path.display()));
    }
    let mut manifest = None;
    if let Some(mut out) = out {
        let t2 = Instant::now();
        let cams = HostCameras::from_predictions(pass.pred())?;
        if plan.renders() {
            bar.set_message("rendering");
            let n = views::render_steps(
                &pass.scene()?.adapted,
                &cams,
                plan,
                &mut out,
                device,
                || bar.inc(1),
            )?;
            notes.push(format!("rendered {n} views"));
        }
        if plan.wants(Output::Motion) {
            bar.set_message("motion maps");
            motion_maps::write_motion_maps(&pass.scene()?.adapted, plan, &mut out, || bar.inc(1))?;
        }
        if plan.wants_cameras() {
            poses::write_cameras(&cams, plan, &mut out)?;
        }
        if plan.wants(Output::Poses) {
            poses::write_poses(&cams, plan, &mut out)?;
        }
        let files = out.len();
        let path = out.finish(plan, source)?;
        notes.push(format!(
            "{files} files in {:.1} s -> {}",
            t2.elapsed().as_secs_f64(),
            path.display()
        ));
        manifest = Some(path);
    }
    Ok(Written {
        forward,
        notes,
        manifest,
    })
}
