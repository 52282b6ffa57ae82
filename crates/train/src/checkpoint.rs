//! Run checkpoints: `out_dir/checkpoints/step-NNNNNNNN/` holding the model (safetensors
//! with its config), the optimiser state (burnpack), and `state.json` (step, counters, the
//! parameter ids the optimiser state is keyed by). A directory is written under a temporary
//! name and renamed into place, so a crash never leaves a half checkpoint under a real name;
//! only the newest `keep` survive.

use crate::error::{read, written, Result, TrainError};
use crate::step::Trainer;
use burn::module::{Module, ModuleMapper, ModuleVisitor, Param, ParamId};
use burn::optim::OptimizerRecord;
use burn::tensor::Tensor;
use envision4d_model::checkpoint::{load_checkpoint, save_checkpoint, CheckpointKind};
use envision4d_model::Envision4d;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

pub const MODEL_FILE: &str = "model.safetensors";
pub const OPTIMIZER_FILE: &str = "optimizer.bpk";
pub const STATE_FILE: &str = "state.json";
const DIR_PREFIX: &str = "step-";

/// What a checkpoint records besides tensors.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunState {
    /// The next step to run.
    pub step: u64,
    pub skipped: u64,
    pub consecutive_nonfinite: u64,
    pub seed: u64,
    /// Parameter ids in module visiting order (Adam's state is keyed by them).
    pub param_ids: Vec<u64>,
    /// Parameter shapes in the same order: a resume into another architecture with the
    /// same parameter count must not bind Adam moments to the wrong tensors.
    pub param_shapes: Vec<Vec<usize>>,
    /// The run's config as TOML with `optim.iterations` and `[run]` normalised away (what a
    /// resume must match).
    pub config: String,
}

/// The checkpoint directory of `step` under `root` (= `out_dir/checkpoints`).
pub fn step_dir(root: &Path, step: u64) -> PathBuf {
    root.join(format!("{DIR_PREFIX}{step:08}"))
}

/// Complete checkpoints under `root`, oldest first.
pub fn list(root: &Path) -> Result<Vec<(u64, PathBuf)>> {
    if !root.exists() {
        return Ok(vec![]);
    }
    let mut out = vec![];
    for e in std::fs::read_dir(root).map_err(read(root))? {
        let e = e.map_err(read(root))?;
        let name = e.file_name().to_string_lossy().to_string();
        if let Some(step) = name.strip_prefix(DIR_PREFIX).and_then(|s| s.parse().ok())
            && e.path().join(STATE_FILE).is_file()
        {
            out.push((step, e.path()));
        }
    }
    out.sort();
    Ok(out)
}

#[derive(Default)]
struct Ids(Vec<u64>, Vec<Vec<usize>>);
impl ModuleVisitor for Ids {
    fn visit_float<const D: usize>(&mut self, p: &Param<Tensor<D>>) {
        self.0.push(p.id.val());
        self.1.push(p.shape().dims::<D>().to_vec());
    }
}

/// Parameter ids of `model` in visiting order.
pub fn param_ids(model: &Envision4d) -> Vec<u64> {
    let mut v = Ids::default();
    model.visit(&mut v);
    v.0
}

/// Parameter shapes of `model` in visiting order.
pub fn param_shapes(model: &Envision4d) -> Vec<Vec<usize>> {
    let mut v = Ids::default();
    model.visit(&mut v);
    v.1
}

/// The part of a config a resumed run must share with the original.
pub fn resume_identity(cfg: &crate::TrainConfig) -> String {
    let mut c = cfg.clone();
    c.optim.iterations = 0;
    c.run = Default::default();
    c.to_toml()
}

struct SetIds<'a> {
    ids: &'a [u64],
    next: usize,
}
impl ModuleMapper for SetIds<'_> {
    fn map_float<const D: usize>(&mut self, mut p: Param<Tensor<D>>) -> Param<Tensor<D>> {
        if let Some(&id) = self.ids.get(self.next) {
            p.id = ParamId::from(id);
        }
        self.next += 1;
        p
    }
}

/// Gives `model`'s parameters the saved ids (same architecture ⇒ same visiting order), so
/// a restored optimiser state finds its parameters.
pub fn restore_param_ids(model: Envision4d, ids: &[u64]) -> Result<Envision4d> {
    let have = param_ids(&model).len();
    if have != ids.len() {
        return Err(TrainError::Unusable(format!(
            "checkpoint has {} parameter ids, the model has {have}: a different architecture",
            ids.len()
        )));
    }
    Ok(model.map(&mut SetIds { ids, next: 0 }))
}

/// Writes a checkpoint of `trainer` under `root` and keeps only the newest `keep` (the one
/// just written always stays; only older steps are pruned). `config_identity` is
/// [`resume_identity`] of the run's config.
pub fn save(trainer: &Trainer, root: &Path, keep: usize, config_identity: &str) -> Result<PathBuf> {
    std::fs::create_dir_all(root).map_err(written(root))?;
    let final_dir = step_dir(root, trainer.step);
    let tmp = root.join(format!(
        ".tmp-{DIR_PREFIX}{:08}-{}",
        trainer.step,
        std::process::id()
    ));
    if tmp.exists() {
        std::fs::remove_dir_all(&tmp).map_err(written(&tmp))?;
    }
    std::fs::create_dir_all(&tmp).map_err(written(&tmp))?;
    let write = || -> Result<()> {
        let mp = tmp.join(MODEL_FILE);
        save_checkpoint(&trainer.model, &trainer.config.model, &mp)
            .map_err(|e| TrainError::write(&mp, e))?;
        let opt = tmp.join(OPTIMIZER_FILE);
        trainer
            .optimizer_record()
            .save(&opt)
            .map_err(|e| TrainError::write(&opt, format!("{e:?}")))?;
        let state = RunState {
            step: trainer.step,
            skipped: trainer.skipped,
            consecutive_nonfinite: trainer.consecutive_nonfinite,
            seed: trainer.config.seed,
            param_ids: param_ids(&trainer.model),
            param_shapes: param_shapes(&trainer.model),
            config: config_identity.to_owned(),
        };
        let json = serde_json::to_string_pretty(&state)
            .map_err(|e| TrainError::Internal(e.to_string()))?;
        let sp = tmp.join(STATE_FILE);
        std::fs::write(&sp, json).map_err(written(&sp))
    };
    if let Err(e) = write() {
        let _ = std::fs::remove_dir_all(&tmp);
        return Err(e);
    }
    if final_dir.exists() {
        // A same-step directory from an abandoned timeline: moved aside before the new one
        // takes its name, removed only once the new one is in place.
        let aside = root.join(format!(
            ".replaced-{DIR_PREFIX}{:08}-{}",
            trainer.step,
            std::process::id()
        ));
        std::fs::rename(&final_dir, &aside).map_err(written(&final_dir))?;
        std::fs::rename(&tmp, &final_dir).map_err(written(&final_dir))?;
        let _ = std::fs::remove_dir_all(&aside);
    } else {
        std::fs::rename(&tmp, &final_dir).map_err(written(&final_dir))?;
    }
    let older: Vec<PathBuf> = list(root)?
        .into_iter()
        .filter(|(s, _)| *s < trainer.step)
        .map(|(_, p)| p)
        .collect();
    let excess = (older.len() + 1).saturating_sub(keep.max(1));
    for old in older.iter().take(excess) {
        std::fs::remove_dir_all(old).map_err(written(old))?;
    }
    Ok(final_dir)
}

/// Restores model, optimiser state, step and counters from checkpoint `dir` into `trainer`.
pub fn restore(trainer: &mut Trainer, dir: &Path) -> Result<RunState> {
    let sp = dir.join(STATE_FILE);
    let text = std::fs::read_to_string(&sp).map_err(read(&sp))?;
    let state: RunState = serde_json::from_str(&text).map_err(|e| TrainError::Parse {
        path: sp.clone(),
        message: e.to_string(),
    })?;
    if state.config != resume_identity(&trainer.config) {
        return Err(TrainError::checkpoint(
            dir,
            format!(
                "--resume: the config differs from the run's:\n{}",
                config_diff(&resume_identity(&trainer.config), &state.config)
            ),
        ));
    }
    let mp = dir.join(MODEL_FILE);
    let mut model = trainer.model.clone();
    load_checkpoint(&mut model, &mp, CheckpointKind::Full)
        .map_err(|e| TrainError::checkpoint(&mp, e))?;
    let shapes = param_shapes(&model);
    if shapes != state.param_shapes {
        return Err(TrainError::checkpoint(
            dir,
            "--resume: the checkpoint's parameter shapes differ from this model's (another architecture)",
        ));
    }
    trainer.model = restore_param_ids(model, &state.param_ids)?;
    trainer.refresh_split();
    let op = dir.join(OPTIMIZER_FILE);
    let record =
        OptimizerRecord::load(&op).map_err(|e| TrainError::checkpoint(&op, format!("{e:?}")))?;
    trainer.load_optimizer_record(record);
    trainer.step = state.step;
    trainer.skipped = state.skipped;
    trainer.consecutive_nonfinite = state.consecutive_nonfinite;
    Ok(state)
}

fn flatten(prefix: &str, v: &toml::Value, out: &mut Vec<(String, String)>) {
    match v {
        toml::Value::Table(t) => {
            for (k, v) in t {
                let key = if prefix.is_empty() {
                    k.clone()
                } else {
                    format!("{prefix}.{k}")
                };
                flatten(&key, v, out);
            }
        }
        other => out.push((prefix.to_owned(), other.to_string())),
    }
}

/// The dotted keys whose values differ between two config TOMLs (`now` vs `was`).
pub fn config_diff(now: &str, was: &str) -> String {
    let keys = |t: &str| {
        let mut out = vec![];
        if let Ok(v) = t.parse::<toml::Table>() {
            flatten("", &toml::Value::Table(v), &mut out);
        }
        out.into_iter()
            .collect::<std::collections::BTreeMap<_, _>>()
    };
    let (a, b) = (keys(now), keys(was));
    let mut all: Vec<&String> = a.keys().chain(b.keys()).collect();
    all.sort();
    all.dedup();
    all.into_iter()
        .filter(|k| a.get(*k) != b.get(*k))
        .map(|k| {
            let show = |m: &std::collections::BTreeMap<String, String>| {
                m.get(k).cloned().unwrap_or_else(|| "(unset)".into())
            };
            format!("  {k}: now {}, the run had {}", show(&a), show(&b))
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// Moves checkpoints newer than `step` (an abandoned timeline after resuming from an older
/// one) aside as `.abandoned-step-N`, so a later `--resume RUN_DIR` cannot pick them up.
pub fn set_aside_newer(root: &Path, step: u64) -> Result<()> {
    for (s, p) in list(root)? {
        if s > step {
            let aside = root.join(format!(".abandoned-{DIR_PREFIX}{s:08}"));
            if aside.exists() {
                std::fs::remove_dir_all(&aside).map_err(written(&aside))?;
            }
            std::fs::rename(&p, &aside).map_err(written(&p))?;
        }
    }
    Ok(())
}
