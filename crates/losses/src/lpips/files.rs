//! LPIPS weights from the files users already have: torchvision's ImageNet backbone
//! (`vgg16-397923af.pth`, `alexnet-owt-7be5be79.pth`: `features.{i}.weight/bias`) plus the
//! `lpips` package's learned linear layers (`weights/v0.1/vgg.pth`: `lin{k}.model.1.weight`),
//! read as they ship; or one file with the package's own names (safetensors from
//! `scripts/export_lpips_weights.py`, or a `.pth`).

use std::path::{Path, PathBuf};

use super::arch::{conv_key, lin_key, LpipsNet};
use super::weight_file::WeightFile;
use super::weights::{read_lins_from, ConvWeights, LpipsWeights};
use crate::error::{LossError, Result};

/// torchvision's key of backbone conv `index` (its position in `features`).
fn torchvision_key(index: usize, part: &str) -> String {
    format!("features.{index}.{part}")
}

impl LpipsWeights {
    /// Loads what `spec` names: one file with the package's key names, or
    /// `BACKBONE,LINS` (two files, either order: the one holding `lin0.model.1.weight` is the
    /// lin file). A path that is itself a file is never split, even with a comma in its name.
    pub fn from_spec(spec: &Path, net: LpipsNet) -> Result<Self> {
        if spec.is_file() {
            return Self::from_safetensors(spec, net);
        }
        let text = spec.to_string_lossy();
        let parts: Vec<PathBuf> = text
            .split(',')
            .map(str::trim)
            .filter(|p| !p.is_empty())
            .map(PathBuf::from)
            .collect();
        match parts.as_slice() {
            [one] => Self::from_safetensors(one, net),
            [a, b] => {
                let mut fa = WeightFile::open(a)?;
                let mut fb = WeightFile::open(b)?;
                if fa.has(&lin_key(0))? && !fb.has(&lin_key(0))? {
                    Self::from_backbone_and_lins(fb, fa, net)
                } else {
                    Self::from_backbone_and_lins(fa, fb, net)
                }
            }
            _ => Err(LossError::WeightsFile {
                path: spec.to_path_buf(),
                reason: format!(
                    "expected one weights file or BACKBONE,LINS (two files), got {} paths",
                    parts.len()
                ),
            }),
        }
    }

    /// The backbone's convs from `backbone` under torchvision's names (or the package's
    /// `net.slice{s}.{i}` names), the five lin layers from `lins`.
    fn from_backbone_and_lins(
        mut backbone: WeightFile,
        mut lins: WeightFile,
        net: LpipsNet,
    ) -> Result<Self> {
        let mut convs = Vec::new();
        for (s, slice) in net.slices().iter().enumerate() {
            for spec in slice.convs {
                let mut part = |name: &str| {
                    let tv = torchvision_key(spec.index, name);
                    match backbone.get_opt(&tv)? {
                        Some(t) => Ok(t),
                        None => backbone.get(&conv_key(s, spec, name)).map_err(|_| {
                            LossError::MissingKey {
                                path: backbone.path.clone(),
                                key: tv,
                            }
                        }),
                    }
                };
                let weight = part("weight")?;
                let bias = part("bias")?;
                convs.push(ConvWeights { weight, bias });
            }
        }
        let lin = read_lins_from(&mut lins, "")?;
        let path = backbone.path.clone();
        Self::new(net, convs, lin).map_err(|e| match e {
            LossError::WeightShape {
                key, got, expected, ..
            } => LossError::WeightShape {
                path,
                key,
                got,
                expected,
            },
            other => other,
        })
    }
}
