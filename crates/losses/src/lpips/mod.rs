//! LPIPS (Zhang et al. 2018) exactly as the `lpips` package (v0.1, `spatial=False`) computes
//! `LPIPS(net=...).forward(x, y, normalize=True)`, as a differentiable Burn computation.
//!
//! Pipeline per image pair:
//! 1. `normalize=True`: `x → 2x − 1` ([0, 1] → [−1, 1]);
//! 2. `ScalingLayer`: `(x − shift) / scale` with the package's constants;
//! 3. the backbone (VGG16 or AlexNet `features`), tapped after the last ReLU of 5 slices;
//! 4. per tap, unit-normalise over channels: `f / (sqrt(Σ_c f²) + 1e-10)`;
//! 5. `(f̂x − f̂y)²`, then the learned non-negative 1×1 `lin` conv (no bias; dropout is off
//!    in eval), then the mean over H, W;
//! 6. the sum over the 5 taps.
//!
//! Weights come from a safetensors file ([`LpipsWeights`]); without one LPIPS is
//! [`LpipsStatus::Unavailable`] and is never computed with random weights.

mod arch;
mod files;
mod weight_file;
mod weights;

use std::path::Path;

use burn::tensor::activation::relu;
use burn::tensor::module::{conv2d, max_pool2d};
use burn::tensor::ops::{ConvOptions, MaxPoolOptions};
use burn::tensor::{DType, Device, Tensor, TensorData};

pub use arch::{lin_key, LpipsNet, LPIPS_LAYERS};
pub use weights::{
    read_lin_layers, ConvWeights, HostTensor, LpipsWeights, QuantizedKeys, WeightKeys,
    SCALING_SCALE, SCALING_SHIFT,
};

use crate::error::{LossError, Result};
use crate::host::HostImages;
use crate::mse::check_pair;

/// The package's `normalize_tensor` epsilon, added to the channel norm.
pub const LPIPS_NORM_EPS: f64 = 1e-10;
/// Floor on `Σ_c f²` before the square root. The package takes `sqrt` of the raw sum, whose
/// gradient is infinite (→ NaN) where a feature vector is exactly zero, which happens after
/// ReLU. Flooring at 1e-30 (a norm of 1e-15, far below the 1e-10 epsilon) changes no value
/// that matters (a zero vector still maps to zero) and keeps the gradient finite.
const NORM_SQ_FLOOR: f64 = 1e-30;

/// Hint printed with every "LPIPS unavailable" message.
pub const LPIPS_WEIGHTS_HINT: &str =
    "give torchvision's vgg16-397923af.pth and the lpips package's weights/v0.1/vgg.pth as BACKBONE,LINS, or a file from scripts/export_lpips_weights.py";

/// A conv layer on the device.
#[derive(Debug, Clone)]
struct DeviceConv {
    weight: Tensor<4>,
    bias: Tensor<1>,
    options: ConvOptions<2>,
}

/// One slice on the device.
#[derive(Debug, Clone)]
struct DeviceSlice {
    pool: Option<MaxPoolOptions<2>>,
    convs: Vec<DeviceConv>,
}

/// An LPIPS network with frozen weights on one device and dtype.
#[derive(Debug, Clone)]
pub struct Lpips {
    net: LpipsNet,
    slices: Vec<DeviceSlice>,
    /// Lin weights reshaped to `[1, C, 1, 1]`.
    lins: Vec<Tensor<4>>,
    shift: Tensor<4>,
    scale: Tensor<4>,
    dtype: DType,
}

impl Lpips {
    /// Put host weights on `device` in `dtype` (F32 for training/metrics, F64 for checks).
    /// The weights are constants: they never receive gradients.
    pub fn new(weights: &LpipsWeights, device: &Device, dtype: DType) -> Self {
        let t = |h: &HostTensor| -> Tensor<4> {
            let data = TensorData::new(h.data.clone(), h.shape.clone()).convert_dtype(dtype);
            Tensor::from_data(data, (device, dtype))
        };
        let t1 = |h: &HostTensor| -> Tensor<1> {
            let data = TensorData::new(h.data.clone(), [h.data.len()]).convert_dtype(dtype);
            Tensor::from_data(data, (device, dtype))
        };
        let mut convs = weights.convs.iter();
        let slices = weights
            .net
            .slices()
            .iter()
            .map(|s| DeviceSlice {
                pool: s
                    .pool
                    .map(|p| MaxPoolOptions::new([p.kernel; 2]).with_stride([p.stride; 2])),
                convs: s
                    .convs
                    .iter()
                    .zip(convs.by_ref())
                    .map(|(spec, w)| DeviceConv {
                        weight: t(&w.weight),
                        bias: t1(&w.bias),
                        options: ConvOptions::new([spec.stride; 2], [spec.padding; 2], [1, 1], 1),
                    })
                    .collect(),
            })
            .collect();
        let per_channel = |v: [f32; 3]| {
            let data = TensorData::new(v.to_vec(), [1, 3, 1, 1]).convert_dtype(dtype);
            Tensor::from_data(data, (device, dtype))
        };
        Self {
            net: weights.net,
            slices,
            lins: weights.lins.iter().map(t).collect(),
            shift: per_channel(SCALING_SHIFT),
            scale: per_channel(SCALING_SCALE),
            dtype,
        }
    }

    /// Load what `spec` names ([`LpipsWeights::from_spec`]: one file with the package's
    /// names, or torchvision's backbone `.pth` and the package's lin `.pth` as `A,B`), in f32.
    pub fn load(spec: &Path, net: LpipsNet, device: &Device) -> Result<Self> {
        Ok(Self::new(
            &LpipsWeights::from_spec(spec, net)?,
            device,
            DType::F32,
        ))
    }

    /// The backbone.
    pub fn net(&self) -> LpipsNet {
        self.net
    }

    /// The dtype inputs must have.
    pub fn dtype(&self) -> DType {
        self.dtype
    }

    /// Per-layer LPIPS terms `[N, 5]` (relu1_2 … relu5_3 for VGG) of `[N, 3, H, W]` images in
    /// [0, 1]. Differentiable in both inputs. Symmetric in its arguments.
    pub fn forward_layers(&self, x: Tensor<4>, y: Tensor<4>) -> Result<Tensor<2>> {
        check_pair("lpips", &x, &y)?;
        let [n, c, h, w] = x.dims();
        if c != 3 {
            return Err(LossError::BadShape {
                what: "lpips",
                expected: "RGB images [N, 3, H, W]",
                got: x.dims().to_vec(),
            });
        }
        if x.device() != self.shift.device() {
            return Err(LossError::Invalid {
                what: "lpips input",
                reason: format!(
                    "images are on {:?}, the LPIPS weights on {:?}",
                    x.device(),
                    self.shift.device()
                ),
            });
        }
        if x.dtype() != self.dtype {
            return Err(LossError::DtypeMismatch {
                what: "lpips input",
                expected: format!("{:?}", self.dtype),
                got: format!("{:?}", x.dtype()),
            });
        }
        if arch::feature_sizes(self.net, h, w).is_none() {
            return Err(LossError::Invalid {
                what: "lpips",
                reason: format!(
                    "a {h}x{w} image is too small for the {} backbone",
                    self.net.name()
                ),
            });
        }
        // Without autodiff, one backbone pass over both images halves the op launches.
        // Under autodiff, a pass over the batch would keep the activations of both halves
        // for the backward; two passes keep only those of the images that carry a graph (in
        // training the renders, not the targets: half of LPIPS's activation memory).
        let (fxs, fys) = if x.device().is_autodiff() {
            (self.features(x), self.features(y))
        } else {
            let both = self.features(Tensor::cat(vec![x, y], 0));
            let fx = both.iter().map(|f| f.clone().narrow(0, 0, n)).collect();
            let fy = both.into_iter().map(|f| f.narrow(0, n, n)).collect();
            (fx, fy)
        };
        let terms: Vec<Tensor<2>> = fxs
            .into_iter()
            .zip(fys)
            .zip(&self.lins)
            .map(|((fx, fy), lin)| {
                let (fx, fy) = (unit_normalize(fx), unit_normalize(fy));
                // 1×1 conv without bias = weighted sum over channels.
                let d = (fx - fy).square() * lin.clone();
                d.sum_dim(1).mean_dims(&[2, 3]).reshape([n, 1])
            })
            .collect();
        Ok(Tensor::cat(terms, 1))
    }

    /// LPIPS distance per image `[N]` (the sum of [`Lpips::forward_layers`]).
    pub fn forward(&self, x: Tensor<4>, y: Tensor<4>) -> Result<Tensor<1>> {
        let layers = self.forward_layers(x, y)?;
        let n = layers.dims()[0];
        Ok(layers.sum_dim(1).reshape([n]))
    }

    /// LPIPS per image of host images (the evaluation path), in this network's dtype.
    pub fn distance_host(&self, x: &HostImages, y: &HostImages) -> Result<Vec<f64>> {
        let device = self.shift.device();
        let to_tensor = |im: &HostImages| {
            let data = TensorData::new(im.data().to_vec(), im.shape()).convert_dtype(self.dtype);
            Tensor::<4>::from_data(data, (&device, self.dtype))
        };
        let d = self.forward(to_tensor(x), to_tensor(y))?;
        crate::host::read_f64("lpips", d.into_data())
    }

    fn features(&self, x: Tensor<4>) -> Vec<Tensor<4>> {
        let mut x = (x * 2.0 - 1.0 - self.shift.clone()) / self.scale.clone();
        let mut taps = Vec::with_capacity(LPIPS_LAYERS);
        for slice in &self.slices {
            if let Some(p) = &slice.pool {
                x = max_pool2d(x, p.clone());
            }
            for c in &slice.convs {
                x = relu(conv2d(
                    x,
                    c.weight.clone(),
                    Some(c.bias.clone()),
                    c.options.clone(),
                ));
            }
            taps.push(x.clone());
        }
        taps
    }
}

/// `f / (sqrt(Σ_c f²) + eps)` over the channel dimension.
fn unit_normalize(f: Tensor<4>) -> Tensor<4> {
    let norm = f
        .clone()
        .square()
        .sum_dim(1)
        .clamp_min(NORM_SQ_FLOOR)
        .sqrt();
    f / (norm + LPIPS_NORM_EPS)
}

/// Whether LPIPS can be computed in this run.
#[derive(Debug, Clone)]
pub enum LpipsStatus {
    /// Weights are loaded.
    Available(Lpips),
    /// No weights: LPIPS metrics are not reported and λ_lpips must be 0.
    Unavailable {
        /// Why (e.g. "no LPIPS weights file given").
        reason: String,
    },
}

impl LpipsStatus {
    /// `None` → unavailable (never random weights). `Some(path)` → load it; a path that is
    /// given but cannot be loaded is an error, not a silent downgrade.
    pub fn from_path(path: Option<&Path>, net: LpipsNet, device: &Device) -> Result<Self> {
        match path {
            None => Ok(Self::Unavailable {
                reason: "no LPIPS weights file given".into(),
            }),
            Some(p) => Ok(Self::Available(Lpips::load(p, net, device)?)),
        }
    }

    /// The loaded network, if any.
    pub fn get(&self) -> Option<&Lpips> {
        match self {
            Self::Available(l) => Some(l),
            Self::Unavailable { .. } => None,
        }
    }

    /// A one-line notice for logs when LPIPS is unavailable; `None` when it is available.
    pub fn notice(&self) -> Option<String> {
        match self {
            Self::Available(_) => None,
            Self::Unavailable { reason } => Some(format!(
                "LPIPS unavailable ({reason}): LPIPS is not reported and lambda_lpips must be 0; {LPIPS_WEIGHTS_HINT}"
            )),
        }
    }

    /// The network, or [`LossError::LpipsUnavailable`] for a caller that needs it.
    pub fn require(&self) -> Result<&Lpips> {
        match self {
            Self::Available(l) => Ok(l),
            Self::Unavailable { reason } => Err(LossError::LpipsUnavailable {
                reason: reason.clone(),
                hint: LPIPS_WEIGHTS_HINT,
            }),
        }
    }
}
