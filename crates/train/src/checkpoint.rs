//! Run checkpoints: `out_dir/checkpoints/step-NNNNNNNN/` holding the model (safetensors
//! with its config), the optimiser state (burnpack), and `state.json` (step, counters, the
//! parameter ids the optimiser state is keyed by). A directory is written under a temporary
//! name and renamed into place, so a crash never leaves a half checkpoint under a real name;
//! only the newest `keep` survive.

use crate::error::{Result, TrainError};
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
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> TrainError + '_ {
    move |source| TrainError::Io {
        path: path.to_path_buf(),
        source,
    }
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
    for e in std::fs::read_dir(root).map_err(io(root))? {
        let e = e.map_err(io(root))?;
        let name = e.file_name().to_string_lossy().to_string();
        if let Some(step) = name.strip_prefix(DIR_PREFIX).and_then(|s| s.parse().ok()) {
            if e.path().join(STATE_FILE).is_file() {
                out.push((step, e.path()));
            }
        }
    }
    out.sort();
    Ok(out)
}

#[derive(Default)]
struct Ids(Vec<u64>);
impl ModuleVisitor for Ids {
    fn visit_float<const D: usize>(&mut self, p: &Param<Tensor<D>>) {
        self.0.push(p.id.val());
    }
}

/// Parameter ids of `model` in visiting order.
pub fn param_ids(model: &Envision4d) -> Vec<u64> {
    let mut v = Ids::default();
    model.visit(&mut v);
    v.0
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
        return Err(TrainError::Model(format!(
            "checkpoint has {} parameter ids, the model has {have}: a different architecture",
            ids.len()
        )));
    }
    Ok(model.map(&mut SetIds { ids, next: 0 }))
}

/// Writes a checkpoint of `trainer` under `root` and keeps only the newest `keep`.
pub fn save(trainer: &Trainer, root: &Path, keep: usize) -> Result<PathBuf> {
    std::fs::create_dir_all(root).map_err(io(root))?;
    let final_dir = step_dir(root, trainer.step);
    let tmp = root.join(format!(".tmp-{DIR_PREFIX}{:08}-{}", trainer.step, std::process::id()));
    if tmp.exists() {
        std::fs::remove_dir_all(&tmp).map_err(io(&tmp))?;
    }
    std::fs::create_dir_all(&tmp).map_err(io(&tmp))?;
    let write = || -> Result<()> {
        save_checkpoint(&trainer.model, &trainer.config.model, &tmp.join(MODEL_FILE))
            .map_err(|e| TrainError::Model(e.to_string()))?;
        let opt = tmp.join(OPTIMIZER_FILE);
        trainer
            .optimizer_record()
            .save(&opt)
            .map_err(|e| TrainError::Model(format!("{}: {e:?}", opt.display())))?;
        let state = RunState {
            step: trainer.step,
            skipped: trainer.skipped,
            consecutive_nonfinite: trainer.consecutive_nonfinite,
            seed: trainer.config.seed,
            param_ids: param_ids(&trainer.model),
        };
        let json = serde_json::to_string_pretty(&state)
            .map_err(|e| TrainError::Model(e.to_string()))?;
        let sp = tmp.join(STATE_FILE);
        std::fs::write(&sp, json).map_err(io(&sp))
    };
    if let Err(e) = write() {
        let _ = std::fs::remove_dir_all(&tmp);
        return Err(e);
    }
    if final_dir.exists() {
        std::fs::remove_dir_all(&final_dir).map_err(io(&final_dir))?;
    }
    std::fs::rename(&tmp, &final_dir).map_err(io(&final_dir))?;
    let all = list(root)?;
    if all.len() > keep.max(1) {
        for (_, old) in &all[..all.len() - keep.max(1)] {
            std::fs::remove_dir_all(old).map_err(io(old))?;
        }
    }
    Ok(final_dir)
}

/// Restores model, optimiser state, step and counters from checkpoint `dir` into `trainer`.
pub fn restore(trainer: &mut Trainer, dir: &Path) -> Result<RunState> {
    let sp = dir.join(STATE_FILE);
    let text = std::fs::read_to_string(&sp).map_err(io(&sp))?;
    let state: RunState = serde_json::from_str(&text).map_err(|e| TrainError::Parse {
        path: sp.clone(),
        message: e.to_string(),
    })?;
    let mp = dir.join(MODEL_FILE);
    let mut model = trainer.model.clone();
    load_checkpoint(&mut model, &mp, CheckpointKind::Full)
        .map_err(|e| TrainError::Model(format!("{}: {e}", mp.display())))?;
    trainer.model = restore_param_ids(model, &state.param_ids)?;
    trainer.refresh_split();
    let op = dir.join(OPTIMIZER_FILE);
    let record = OptimizerRecord::load(&op)
        .map_err(|e| TrainError::Model(format!("{}: {e:?}", op.display())))?;
    trainer.load_optimizer_record(record);
    trainer.step = state.step;
    trainer.skipped = state.skipped;
    trainer.consecutive_nonfinite = state.consecutive_nonfinite;
    Ok(state)
}
