//! A training run: data order (decoded ahead on a worker thread), steps, JSONL log,
//! validation, checkpoints, resume and the NaN guard. Progress display is the caller's ([`Observer`]); everything a run needs to be
//! continued or audited is on disk under `run.out_dir`.

use crate::augment;
use crate::batch::Batch;
use crate::checkpoint::{self, MODEL_FILE};
use crate::config::{LossConfig, Purpose, Stage, Teacher, TrainConfig};
use crate::dataset::{open_dataset, split};
use crate::error::{Result, TrainError};
use crate::log::JsonlLog;
use crate::parallel::GradientReduce;
use crate::step::{StepReport, Trainer};
use crate::validate::{validate, ValReport};
use burn::tensor::Device;
use envision4d_data::lock::DirLock;
use envision4d_data::split::epoch_order;
use envision4d_data::{ClipDataset, DataError, HostClip, Prefetch, Split};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

pub const CONFIG_FILE: &str = "config.toml";
pub const LOG_FILE: &str = "log.jsonl";
pub const CHECKPOINT_DIR: &str = "checkpoints";

/// How a run is started.
#[derive(Debug, Clone, Default)]
pub struct RunOptions {
    /// A run directory (its newest checkpoint) or one checkpoint directory.
    pub resume: Option<PathBuf>,
    /// Stop (with a checkpoint) after this many steps in total, before `optim.iterations`.
    pub stop_at: Option<u64>,
    /// Data-parallel devices (`--devices`); empty or one = the run's device only. The batch
    /// is split evenly across them.
    pub devices: Vec<Device>,
    /// How the devices' gradients are combined (only with several devices).
    pub reduce: GradientReduce,
}

/// What the caller shows while a run goes on.
pub trait Observer {
    fn start(&mut self, _first_step: u64, _total_steps: u64) {}
    fn step(&mut self, _report: &StepReport, _steps_per_second: f64) {}
    fn validation(&mut self, _report: &ValReport) {}
    fn checkpoint(&mut self, _dir: &Path) {}
    fn note(&mut self, _message: &str) {}
}

/// An observer that shows nothing (tests, scripts).
pub struct Quiet;
impl Observer for Quiet {}

#[derive(Debug, Clone)]
pub struct RunSummary {
    /// Steps done in total (the next step to run).
    pub steps: u64,
    pub skipped: u64,
    pub last_checkpoint: PathBuf,
    /// The final model (safetensors with its config), `out_dir/model.safetensors`.
    pub model: PathBuf,
    pub last_validation: Option<ValReport>,
    /// The memory model's peak for this config's later steps (bytes of host memory on the
    /// CPU backend; `crate::memory`), to print beside the measured peak.
    pub estimated_peak_bytes: f64,
}

/// The checkpoint directory `--resume` names: `dir` itself, or the newest under
/// `dir/checkpoints`.
pub fn resolve_resume(dir: &Path) -> Result<PathBuf> {
    if dir.join(checkpoint::STATE_FILE).is_file() {
        return Ok(dir.to_path_buf());
    }
    checkpoint::list(&dir.join(CHECKPOINT_DIR))?
        .pop()
        .map(|(_, p)| p)
        .ok_or_else(|| TrainError::checkpoint(dir, "--resume: no checkpoint in it"))
}

/// Training windows decoded ahead of the step that needs them (a batch and a half: the
/// next batch is ready when a step ends, and a slow clip does not stall the one after).
const PREFETCH_BATCHES: f64 = 1.5;

/// Which training clip the `k`-th sample of the run is: a seeded shuffle per epoch, so the
/// data order is a function of (seed, step) and a resumed run sees the same clips.
fn sample_index(
    train: &[usize],
    seed: u64,
    k: u64,
    cache: &mut Option<(u64, Vec<usize>)>,
) -> usize {
    let len = train.len() as u64;
    let epoch = k / len;
    if cache.as_ref().is_none_or(|(e, _)| *e != epoch) {
        *cache = Some((epoch, epoch_order(train, seed, epoch)));
    }
    cache
        .as_ref()
        .map_or(train[0], |(_, o)| o[(k % len) as usize])
}

fn host_clip(ds: &ClipDataset, index: usize) -> Result<HostClip> {
    let clip = ds
        .load(index)
        .map_err(|e| TrainError::data(format!("clip {index}"), e))?;
    HostClip::from_clip(&clip).map_err(|e| TrainError::data(format!("clip {index}"), e))
}

/// The training windows of samples `first..end` (sample `k` is the `k % B`-th clip of step
/// `k / B`), decoded, converted and augmented on a worker thread, in order. The order and
/// the augmentation are functions of (seed, sample), exactly as without the worker.
fn training_windows(
    dataset: Arc<ClipDataset>,
    cfg: &TrainConfig,
    train: Vec<usize>,
    samples: std::ops::Range<u64>,
) -> Prefetch<Result<HostClip>> {
    let (seed, augment) = (cfg.seed, cfg.data.augment);
    let depth = (cfg.optim.batch_size as f64 * PREFETCH_BATCHES).ceil() as usize;
    let mut order_cache = None;
    Prefetch::new(samples, depth, move |k| {
        let index = sample_index(&train, seed, k, &mut order_cache);
        Some(host_clip(&dataset, index).map(|mut clip| {
            augment::apply(&mut clip, augment::playback(&augment, seed, k));
            clip
        }))
    })
}

/// The next `batch_size` windows from the prefetcher.
fn next_clips(
    windows: &mut Prefetch<Result<HostClip>>,
    batch_size: usize,
) -> Result<Vec<HostClip>> {
    (0..batch_size)
        .map(|_| {
            windows
                .next()
                .unwrap_or_else(|| Err(TrainError::Internal("the data worker stopped".into())))
        })
        .collect()
}

/// One step of `trainer` on `clips` (split across `devices` when there are several), with
/// the truth the loss's diagnostics need.
fn step_on(
    trainer: &mut Trainer,
    clips: &[HostClip],
    labels: (usize, bool, &LossConfig),
    device: &Device,
    (devices, reduce): (&[Device], GradientReduce),
) -> Result<StepReport> {
    let (depth_frames, with_gt, loss) = labels;
    if devices.len() > 1 {
        let per = clips.len() / devices.len();
        let shards = clips
            .chunks(per)
            .zip(devices)
            .map(|(c, d)| Batch::for_training(c, depth_frames, with_gt, loss, d))
            .collect::<Result<Vec<_>>>()?;
        trainer.train_step_parallel(&shards, devices, reduce)
    } else {
        let batch = Batch::for_training(clips, depth_frames, with_gt, loss, device)?;
        trainer.train_step(&batch)
    }
}

/// Runs (or resumes) the training `cfg` describes.
pub fn run(
    cfg: TrainConfig,
    device: &Device,
    opts: RunOptions,
    obs: &mut dyn Observer,
) -> Result<RunSummary> {
    // Before anything is written: a run on an evaluation split is refused outright.
    crate::dataset::check_training_split(&cfg.data)?;
    let out = cfg.run.out_dir.clone();
    let ckpt_root = out.join(CHECKPOINT_DIR);
    let config_path = out.join(CONFIG_FILE);
    // The folder the config names: failing to make it (a file in the way, no permission) is
    // the user's to fix, like `eval --out`. Then one writer: the lock is held until this
    // function returns, and the checks below run under it, so two runs started together
    // cannot both pass them.
    std::fs::create_dir_all(&out)
        .map_err(|e| TrainError::invalid("run.out_dir", out.display(), e.to_string()))?;
    let _lock = DirLock::acquire(&out, "run.out_dir").map_err(|e| match e {
        DataError::Write { path, msg } => TrainError::write(path, msg),
        other => TrainError::Unusable(other.to_string()),
    })?;
    let resume_dir = match &opts.resume {
        Some(d) => Some(resolve_resume(d)?),
        None => {
            if let Some((step, _)) = checkpoint::list(&ckpt_root)?.pop() {
                return Err(TrainError::Unusable(format!(
                    "{} already holds a run (checkpoint at step {step}): pass --resume {} or set another run.out_dir",
                    out.display(),
                    out.display()
                )));
            }
            None
        }
    };
    envision4d_data::atomic::write_bytes(&config_path, cfg.to_toml().as_bytes())
        .map_err(|e| TrainError::write(&config_path, e))?;

    let dataset = Arc::new(open_dataset(
        &cfg.data,
        &cfg.model,
        &cfg.data.root,
        Purpose::Train,
    )?);
    let train = split(&dataset, Split::Train, cfg.seed);
    if train.is_empty() {
        return Err(TrainError::Unusable(format!(
            "data.root {}: no clip in the training split ({} clips in all)",
            cfg.data.root.display(),
            dataset.len()
        )));
    }
    let val_clips = split(&dataset, Split::Val, cfg.seed)
        .into_iter()
        .take(cfg.run.val_clips)
        .map(|i| host_clip(&dataset, i))
        .collect::<Result<Vec<_>>>()?;
    if cfg.run.val_every > 0 && val_clips.is_empty() {
        obs.note("no validation clip in the split: validation skipped");
    }

    let devices = &opts.devices;
    if devices.len() > 1 && !cfg.optim.batch_size.is_multiple_of(devices.len()) {
        return Err(TrainError::invalid(
            "optim.batch_size",
            cfg.optim.batch_size,
            format!(
                "must be a multiple of the {} devices of --devices",
                devices.len()
            ),
        ));
    }
    let random = cfg.random_weights();
    if !random.is_empty() {
        obs.note(&format!(
            "init = \"random\": {} have random weights; this run measures time and memory, \
             not quality",
            random.join(", ")
        ));
    }
    let mut trainer = start_trainer(&cfg, device, resume_dir.as_deref(), &ckpt_root, obs)?;
    let estimated_peak_bytes =
        crate::memory::estimate(&cfg, &trainer.model, &trainer.split).later_steps();
    if devices.len() > 1 {
        trainer.prepare_devices(devices)?;
    }
    let identity = checkpoint::resume_identity(&cfg);
    let mut log = JsonlLog::open(&out.join(LOG_FILE), trainer.step)?;
    let (n, tc) = (cfg.model.num_frames(), cfg.model.context_frames);
    let depth_frames = match cfg.stage {
        Stage::Backbone => n,
        Stage::Envision4d => tc,
    };
    let with_gt = cfg.stage == Stage::Backbone || cfg.teacher == Teacher::GroundTruth;
    let end = opts.stop_at.unwrap_or(u64::MAX).min(cfg.optim.iterations);
    obs.start(trainer.step, cfg.optim.iterations);
    let mut last_ckpt = resume_dir.clone();
    let mut last_val = None;
    let t_start = Instant::now();
    let first = trainer.step;
    let b = cfg.optim.batch_size as u64;
    let mut windows = training_windows(
        dataset.clone(),
        &cfg,
        train,
        first.saturating_mul(b)..end.max(first).saturating_mul(b),
    );
    while trainer.step < end {
        let step = trainer.step;
        let clips = next_clips(&mut windows, cfg.optim.batch_size)?;
        let t0 = Instant::now();
        let report = step_on(
            &mut trainer,
            &clips,
            (depth_frames, with_gt, &cfg.loss),
            device,
            (devices, opts.reduce),
        )?;
        let rate = (trainer.step - first) as f64 / t_start.elapsed().as_secs_f64().max(1e-9);
        obs.step(&report, rate);
        if !report.outcome.applied() || crate::log::logged(step, cfg.run.log_every) {
            log.step(&report, t0.elapsed().as_secs_f64(), rate)?;
        }
        if trainer.consecutive_nonfinite >= cfg.run.max_nonfinite_steps {
            let keep = last_ckpt
                .as_ref()
                .map_or("none was written".into(), |p| p.display().to_string());
            return Err(TrainError::Diverged(format!(
                "stopped at step {step}: {} non-finite steps in a row (loss, gradient or update); the last good checkpoint is {keep}",
                trainer.consecutive_nonfinite
            )));
        }
        let done = trainer.step;
        // A checkpoint only after an applied step: the weights are then finite by the
        // rollback in `Trainer::apply`, and a skipped streak never displaces a good one.
        if (done % cfg.run.checkpoint_every == 0 || done == end)
            && trainer.consecutive_nonfinite == 0
        {
            let dir = checkpoint::save(&trainer, &ckpt_root, cfg.run.keep_checkpoints, &identity)?;
            log.checkpoint(done, &dir)?;
            obs.checkpoint(&dir);
            last_ckpt = Some(dir);
        }
        // Validation after the checkpoint, and never fatal: a bad validation clip must not
        // cost the steps since the last checkpoint.
        if cfg.run.val_every > 0 && done % cfg.run.val_every == 0 && !val_clips.is_empty() {
            match validate(
                &trainer.model,
                cfg.stage,
                &val_clips,
                tc,
                done,
                &trainer.raster,
            ) {
                Ok(v) => {
                    log.validation(&v)?;
                    obs.validation(&v);
                    last_val = Some(v);
                }
                Err(e) => obs.note(&format!("validation at step {done} failed: {e}")),
            }
        }
    }
    let last_checkpoint = match last_ckpt {
        Some(p) => p,
        None => checkpoint::save(&trainer, &ckpt_root, cfg.run.keep_checkpoints, &identity)?,
    };
    let model = out.join(MODEL_FILE);
    envision4d_model::checkpoint::save_checkpoint(&trainer.model, &cfg.model, &model)
        .map_err(|e| TrainError::write(&model, e))?;
    Ok(RunSummary {
        steps: trainer.step,
        skipped: trainer.skipped,
        last_checkpoint,
        model,
        last_validation: last_val,
        estimated_peak_bytes,
    })
}

/// The trainer of a new run, or of a resumed one restored from `resume`. A resumed run
/// takes its weights from the checkpoint: the init weights are not read (they may have
/// moved), but the teacher still needs its own.
fn start_trainer(
    cfg: &TrainConfig,
    device: &Device,
    resume: Option<&Path>,
    ckpt_root: &Path,
    obs: &mut dyn Observer,
) -> Result<Trainer> {
    let mut build = cfg.clone();
    if resume.is_some() {
        build.teacher_checkpoint = cfg
            .teacher_checkpoint
            .clone()
            .or(cfg.init_checkpoint.clone());
        build.init_checkpoint = None;
    }
    let mut trainer = Trainer::new(build, device)?;
    trainer.config = cfg.clone();
    if let Some(dir) = resume {
        checkpoint::restore(&mut trainer, dir)?;
        checkpoint::set_aside_newer(ckpt_root, trainer.step)?;
        obs.note(&format!(
            "resumed from {} at step {}",
            dir.display(),
            trainer.step
        ));
    }
    Ok(trainer)
}
