//! Model checkpoints: the official Envision4D release (Lightning `.ckpt`, weights under
//! `state_dict` with the `encoder.backbone.` prefix, or the same exported to safetensors),
//! VGGT-1B's `model.pt` for initialising training, and our own safetensors checkpoints, which
//! use the official names and carry their model config in the metadata.

use crate::config::ModelConfig;
use crate::model::Envision4d;
use crate::weights::{
    checkpoint_keys, header_metadata, load_weights, remapper, LoadError, LoadReport, Missing,
    Unexpected, KEY_RENAMES_BACK,
};
use burn::store::{BurnToPyTorchAdapter, ModuleSnapshot, SafetensorsStore};
use std::path::{Path, PathBuf};

/// Prefix of the model's keys inside the released Lightning checkpoint.
pub const RELEASE_PREFIX: &str = "encoder.backbone.";
/// Metadata key holding the model config (JSON) in our checkpoints.
pub const CONFIG_METADATA_KEY: &str = "envision4d_model_config";

/// What a checkpoint is expected to contain.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CheckpointKind {
    /// Every parameter of Envision4D, nothing else (release checkpoints, our own).
    Full,
    /// VGGT-1B: aggregator, camera and depth heads. Envision4D's new modules (temporal blocks,
    /// future-pose module, Gaussian and motion heads) keep their fresh initialisation; the
    /// point and track heads are ignored.
    Vggt1bInit,
}

/// Envision4D parameters that VGGT-1B does not have.
fn is_new_module(key: &str) -> bool {
    key.starts_with("aggregator.time_blocks.")
        || key.starts_with("future.")
        || key.starts_with("gs_head.")
        || key.starts_with("motion_head.")
}

/// The key prefix of a checkpoint: `encoder.backbone.` for the release, none otherwise.
pub fn detect_prefix(path: &Path) -> Result<String, LoadError> {
    let keys = checkpoint_keys(path)?;
    Ok(if keys.iter().any(|k| k.starts_with(RELEASE_PREFIX)) {
        RELEASE_PREFIX.to_owned()
    } else {
        String::new()
    })
}

/// Loads `path` into `model`, with one error listing every missing, unexpected or
/// mis-shaped key.
pub fn load_checkpoint(
    model: &mut Envision4d,
    path: &Path,
    kind: CheckpointKind,
) -> Result<LoadReport, LoadError> {
    let prefix = detect_prefix(path)?;
    match kind {
        CheckpointKind::Full => {
            load_weights(model, path, &prefix, Missing::Reject, Unexpected::Reject)
        }
        CheckpointKind::Vggt1bInit => {
            let report = load_weights(model, path, &prefix, Missing::KeepInit, Unexpected::Ignore)?;
            let absent: Vec<&String> = report
                .kept_init
                .iter()
                .filter(|k| !is_new_module(k))
                .collect();
            if !absent.is_empty() {
                let list = absent
                    .iter()
                    .map(|k| format!("  missing: {prefix}{k}"))
                    .collect::<Vec<_>>()
                    .join("\n");
                return Err(LoadError::Mismatch { path: path.to_path_buf(), report: format!("{list}\n(a VGGT-1B checkpoint must provide the aggregator, camera head and depth head)") });
            }
            Ok(report)
        }
    }
}

/// The model config stored in one of our checkpoints (`None` for files without one).
pub fn checkpoint_config(path: &Path) -> Result<Option<ModelConfig>, LoadError> {
    let meta = header_metadata(path)?;
    let Some(json) = meta.get(CONFIG_METADATA_KEY) else {
        return Ok(None);
    };
    let cfg: ModelConfig = serde_json::from_str(json).map_err(|e| LoadError::Read {
        path: path.to_path_buf(),
        message: format!("bad model config in metadata: {e}"),
    })?;
    cfg.validate().map_err(|e| LoadError::Read {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    Ok(Some(cfg))
}

/// Saves `model` as safetensors under the official parameter names (PyTorch layouts), with
/// `config` in the metadata. Written to a temporary file then renamed, so an existing
/// checkpoint is never left half-written.
pub fn save_checkpoint(
    model: &Envision4d,
    config: &ModelConfig,
    path: &Path,
) -> Result<(), LoadError> {
    let err = |message: String| LoadError::Read {
        path: path.to_path_buf(),
        message,
    };
    let remap = remapper(None, KEY_RENAMES_BACK).map_err(err)?;
    let json = serde_json::to_string(config).map_err(|e| err(e.to_string()))?;
    let tmp = temp_path(path);
    let mut store = SafetensorsStore::from_file(&tmp)
        .with_to_adapter(BurnToPyTorchAdapter)
        .remap(remap)
        .metadata(CONFIG_METADATA_KEY, json)
        .overwrite(true);
    let written = model
        .save_into(&mut store)
        .map_err(|e| format!("writing checkpoint: {e:?}"))
        .and_then(|()| canonical_header(&tmp).map_err(|e| format!("writing checkpoint: {e}")));
    if let Err(e) = written {
        let _ = std::fs::remove_file(&tmp);
        return Err(err(e));
    }
    std::fs::rename(&tmp, path).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        err(format!("moving checkpoint into place: {e}"))
    })
}

/// Rewrites a safetensors header in place with its keys in sorted order. burn-store writes
/// the metadata from a hash map, so two identical models gave files that differed in the
/// header's key order; sorted, the same weights are the same bytes (a seed reproduces a
/// file's checksum). Only the header is read and written: sorting keeps its length, and a
/// shorter one is padded with spaces, as the format allows.
fn canonical_header(path: &Path) -> std::io::Result<()> {
    use std::io::{Read, Seek, SeekFrom, Write};
    let bad = |m: String| std::io::Error::new(std::io::ErrorKind::InvalidData, m);
    let mut f = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .open(path)?;
    let mut len = [0u8; 8];
    f.read_exact(&mut len)?;
    let n = usize::try_from(u64::from_le_bytes(len)).map_err(|e| bad(e.to_string()))?;
    let mut header = vec![0u8; n];
    f.read_exact(&mut header)?;
    // serde_json's map is ordered by key (no `preserve_order`): parsing sorts.
    let value: serde_json::Value =
        serde_json::from_slice(&header).map_err(|e| bad(format!("header: {e}")))?;
    let mut sorted = serde_json::to_vec(&value).map_err(|e| bad(e.to_string()))?;
    if sorted.len() > n {
        return Err(bad(format!(
            "sorted header grew from {n} to {} bytes",
            sorted.len()
        )));
    }
    sorted.resize(n, b' ');
    f.seek(SeekFrom::Start(8))?;
    f.write_all(&sorted)
}

fn temp_path(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_default();
    path.with_file_name(format!(".{name}.tmp-{}", std::process::id()))
}
