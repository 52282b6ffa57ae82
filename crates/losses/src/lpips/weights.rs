//! LPIPS weights on the host, read by the `lpips` package's state_dict names from a
//! safetensors file (`scripts/export_lpips_weights.py`) or a PyTorch `.pth` with those names;
//! `files.rs` reads the torchvision backbone and the package's lin file as they ship.

use std::path::{Path, PathBuf};

use super::arch::{conv_key, lin_key, LpipsNet, LPIPS_LAYERS};
use super::weight_file::WeightFile;
use crate::error::{LossError, Result};

/// The package's `ScalingLayer.shift` (ImageNet mean mapped to [−1, 1]).
pub const SCALING_SHIFT: [f32; 3] = [-0.030, -0.088, -0.188];
/// The package's `ScalingLayer.scale` (ImageNet std mapped to [−1, 1]).
pub const SCALING_SCALE: [f32; 3] = [0.458, 0.448, 0.450];
/// Allowed difference between a file's scaling buffers and the package constants.
const SCALING_TOLERANCE: f32 = 1e-6;

/// A host tensor: row-major f32 values and their shape.
#[derive(Debug, Clone, PartialEq)]
pub struct HostTensor {
    /// Dimensions.
    pub shape: Vec<usize>,
    /// Row-major values.
    pub data: Vec<f32>,
}

/// One backbone conv: weight `[out, in, k, k]`, bias `[out]`.
#[derive(Debug, Clone, PartialEq)]
pub struct ConvWeights {
    /// `[out, in, k, k]`.
    pub weight: HostTensor,
    /// `[out]`.
    pub bias: HostTensor,
}

/// Everything LPIPS needs: backbone convs (in network order) and the five lin layers
/// (`[1, C_k, 1, 1]`, non-negative in the shipped weights).
#[derive(Debug, Clone, PartialEq)]
pub struct LpipsWeights {
    /// Which backbone these are for.
    pub net: LpipsNet,
    /// Convs in forward order (13 for VGG16, 5 for AlexNet).
    pub convs: Vec<ConvWeights>,
    /// Lin layers `lin0..lin4`.
    pub lins: Vec<HostTensor>,
}

/// Where the tensors live inside a safetensors file.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct WeightKeys {
    /// Prefix before every package key (empty for files from the export script).
    pub prefix: String,
    /// Optional int8 storage of conv weights: `weight = f32(int8) × step`.
    pub quantized: Option<QuantizedKeys>,
}

/// Prefixes of int8-quantised conv weights (`[out, in, k, k]` I8) and their `[1]` f32 steps.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct QuantizedKeys {
    /// Prefix of the I8 values.
    pub values_prefix: String,
    /// Prefix of the f32 step.
    pub step_prefix: String,
}

impl LpipsWeights {
    /// Random weights of the right shapes (He-scaled convs, zero biases, lin weights uniform
    /// in [0, 1/C)): a network that costs what the real one costs, for benchmarks and memory
    /// measurements only. Its distances mean nothing, so callers must say it is random.
    pub fn random(net: LpipsNet, seed: u64) -> Self {
        // SplitMix64: a small, fixed generator so the same seed gives the same weights.
        let mut state = seed;
        let mut unit = move || {
            state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut z = state;
            z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            ((z ^ (z >> 31)) >> 11) as f32 / (1u64 << 53) as f32
        };
        let convs = net
            .slices()
            .iter()
            .flat_map(|s| s.convs.iter())
            .map(|c| {
                let fan_in = (c.in_ch * c.kernel * c.kernel) as f32;
                let bound = (6.0 / fan_in).sqrt();
                let shape = vec![c.out_ch, c.in_ch, c.kernel, c.kernel];
                let len = shape.iter().product();
                ConvWeights {
                    weight: HostTensor {
                        shape,
                        data: (0..len).map(|_| (2.0 * unit() - 1.0) * bound).collect(),
                    },
                    bias: HostTensor {
                        shape: vec![c.out_ch],
                        data: vec![0.0; c.out_ch],
                    },
                }
            })
            .collect();
        let lins = net
            .channels()
            .iter()
            .map(|&ch| HostTensor {
                shape: vec![1, ch, 1, 1],
                data: (0..ch).map(|_| unit() / ch as f32).collect(),
            })
            .collect();
        Self { net, convs, lins }
    }

    /// Check every shape against the network's table and the lin weights for finiteness.
    pub fn new(net: LpipsNet, convs: Vec<ConvWeights>, lins: Vec<HostTensor>) -> Result<Self> {
        let specs: Vec<_> = net.slices().iter().flat_map(|s| s.convs.iter()).collect();
        let bad = |what: String, got: &[usize], expected: Vec<usize>| LossError::WeightShape {
            path: PathBuf::from("<in memory>"),
            key: what,
            got: got.to_vec(),
            expected,
        };
        if convs.len() != specs.len() || lins.len() != LPIPS_LAYERS {
            return Err(LossError::Invalid {
                what: "lpips weights",
                reason: format!(
                    "{} needs {} convs and {LPIPS_LAYERS} lin layers, got {} and {}",
                    net.name(),
                    specs.len(),
                    convs.len(),
                    lins.len()
                ),
            });
        }
        for (c, s) in convs.iter().zip(&specs) {
            let w = vec![s.out_ch, s.in_ch, s.kernel, s.kernel];
            if c.weight.shape != w || c.weight.data.len() != w.iter().product::<usize>() {
                return Err(bad(format!("conv {} weight", s.index), &c.weight.shape, w));
            }
            if c.bias.shape != [s.out_ch] || c.bias.data.len() != s.out_ch {
                return Err(bad(
                    format!("conv {} bias", s.index),
                    &c.bias.shape,
                    vec![s.out_ch],
                ));
            }
        }
        for (k, (l, ch)) in lins.iter().zip(net.channels()).enumerate() {
            if l.shape != [1, ch, 1, 1] || l.data.len() != ch {
                return Err(bad(lin_key(k), &l.shape, vec![1, ch, 1, 1]));
            }
        }
        let all = convs
            .iter()
            .flat_map(|c| c.weight.data.iter().chain(&c.bias.data))
            .chain(lins.iter().flat_map(|l| &l.data));
        if let Some((index, v)) = all.enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(LossError::NonFinite {
                what: "lpips weights",
                index,
                value: *v as f64,
            });
        }
        Ok(Self { net, convs, lins })
    }

    /// Load from a file written by `scripts/export_lpips_weights.py` (package key names,
    /// no prefix).
    pub fn from_safetensors(path: &Path, net: LpipsNet) -> Result<Self> {
        Self::from_safetensors_with(path, net, &WeightKeys::default())
    }

    /// Load with explicit key prefixes (e.g. the metrics fixture's `lpips_vgg/weights/`).
    /// If the file has `scaling_layer.shift/scale`, they must equal the package constants.
    pub fn from_safetensors_with(path: &Path, net: LpipsNet, keys: &WeightKeys) -> Result<Self> {
        let mut file = WeightFile::open(path)?;
        for (name, expected) in [("shift", SCALING_SHIFT), ("scale", SCALING_SCALE)] {
            let key = format!("{}scaling_layer.{name}", keys.prefix);
            if let Some(t) = file.get_opt(&key)? {
                let ok = t.data.len() == 3
                    && t.data
                        .iter()
                        .zip(expected)
                        .all(|(a, b)| (a - b).abs() <= SCALING_TOLERANCE);
                if !ok {
                    return Err(LossError::WeightsFile {
                        path: path.to_path_buf(),
                        reason: format!(
                            "`{key}` is {:?}, not the lpips package's {expected:?}",
                            t.data
                        ),
                    });
                }
            }
        }
        let mut convs = Vec::new();
        for (s, slice) in net.slices().iter().enumerate() {
            for spec in slice.convs {
                let wkey = conv_key(s, spec, "weight");
                let weight = match file.get_opt(&format!("{}{wkey}", keys.prefix))? {
                    Some(w) => w,
                    None => match &keys.quantized {
                        Some(q) => {
                            let values = file.get(&format!("{}{wkey}", q.values_prefix))?;
                            let step = file.get(&format!("{}{wkey}", q.step_prefix))?;
                            let step = step.data.first().copied().unwrap_or(f32::NAN);
                            HostTensor {
                                shape: values.shape,
                                data: values.data.iter().map(|v| v * step).collect(),
                            }
                        }
                        None => file.get(&format!("{}{wkey}", keys.prefix))?,
                    },
                };
                let bias = file.get(&format!("{}{}", keys.prefix, conv_key(s, spec, "bias")))?;
                convs.push(ConvWeights { weight, bias });
            }
        }
        let lins = read_lins_from(&mut file, &keys.prefix)?;
        Self::new(net, convs, lins).map_err(|e| with_path(e, path))
    }
}

/// Read only the five lin layers `{prefix}lin{k}.model.1.weight` (e.g. the shipped vgg/alex
/// lin weights in the metrics fixture).
pub fn read_lin_layers(path: &Path, prefix: &str) -> Result<Vec<HostTensor>> {
    let mut file = WeightFile::open(path)?;
    read_lins_from(&mut file, prefix)
}

pub(super) fn read_lins_from(file: &mut WeightFile, prefix: &str) -> Result<Vec<HostTensor>> {
    (0..LPIPS_LAYERS)
        .map(|k| file.get(&format!("{prefix}{}", lin_key(k))))
        .collect()
}

/// Put the file path into shape errors raised by [`LpipsWeights::new`].
fn with_path(e: LossError, path: &Path) -> LossError {
    match e {
        LossError::WeightShape {
            key, got, expected, ..
        } => LossError::WeightShape {
            path: path.to_path_buf(),
            key,
            got,
            expected,
        },
        other => other,
    }
}
