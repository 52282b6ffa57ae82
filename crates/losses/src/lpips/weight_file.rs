//! One weights file read through burn-store, safetensors or PyTorch pickle (`.pth`, `.pt`,
//! `.bin`, `.ckpt`; zip or the legacy pre-1.6 format, which the `lpips` package's own
//! `weights/v0.1/*.pth` use), decided by the extension.

use std::path::{Path, PathBuf};

use burn::store::{ModuleStore, PytorchStore, SafetensorsStore};

use super::weights::HostTensor;
use crate::error::{LossError, Result};

/// Extensions read as PyTorch pickles; everything else is safetensors.
const PYTORCH_EXTENSIONS: [&str; 4] = ["pth", "pt", "bin", "ckpt"];

enum Store {
    Safetensors(SafetensorsStore),
    Pytorch(PytorchStore),
}

pub(super) struct WeightFile {
    pub path: PathBuf,
    store: Store,
}

impl WeightFile {
    /// Opens `path` and reads its key list now, so a corrupt file fails here, naming itself.
    pub fn open(path: &Path) -> Result<Self> {
        let fail = |reason: String| LossError::WeightsFile {
            path: path.to_path_buf(),
            reason,
        };
        if !path.is_file() {
            return Err(fail("no such file".into()));
        }
        let pytorch = path
            .extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| PYTORCH_EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()));
        let store = if pytorch {
            // Our keys are the file's own: no renumbering of Sequential indices.
            let mut s = PytorchStore::from_file(path).map_indices_contiguous(false);
            s.keys().map_err(|e| fail(e.to_string()))?;
            Store::Pytorch(s)
        } else {
            let mut s = SafetensorsStore::from_file(path);
            s.keys().map_err(|e| fail(e.to_string()))?;
            Store::Safetensors(s)
        };
        Ok(Self {
            path: path.to_path_buf(),
            store,
        })
    }

    /// Whether the file holds `key`.
    pub fn has(&mut self, key: &str) -> Result<bool> {
        let keys = match &mut self.store {
            Store::Safetensors(s) => s.keys().map_err(|e| e.to_string()),
            Store::Pytorch(s) => s.keys().map_err(|e| e.to_string()),
        };
        let keys = keys.map_err(|reason| LossError::WeightsFile {
            path: self.path.clone(),
            reason,
        })?;
        Ok(keys.iter().any(|k| k == key))
    }

    pub fn get(&mut self, key: &str) -> Result<HostTensor> {
        self.get_opt(key)?.ok_or_else(|| LossError::MissingKey {
            path: self.path.clone(),
            key: key.to_owned(),
        })
    }

    pub fn get_opt(&mut self, key: &str) -> Result<Option<HostTensor>> {
        let path = self.path.clone();
        let fail = |reason: String| LossError::WeightsFile {
            path: path.clone(),
            reason: format!("tensor `{key}`: {reason}"),
        };
        let tensor = match &mut self.store {
            Store::Safetensors(s) => s.get_tensor(key).map_err(|e| e.to_string()),
            Store::Pytorch(s) => s.get_tensor(key).map_err(|e| e.to_string()),
        }
        .map_err(&fail)?;
        let Some(t) = tensor else {
            return Ok(None);
        };
        let data = burn::store::bridge::to_data(t).map_err(|e| fail(format!("{e:?}")))?;
        let shape = data.shape().to_vec();
        let data = data
            .try_into_vec_as::<f32>()
            .map_err(|e| fail(format!("{e:?}")))?;
        Ok(Some(HostTensor { shape, data }))
    }
}
