//! Reduced-precision inference: the aggregator (DINO and the frame, global and temporal
//! blocks, where nearly all of a forward's multiply-adds are) runs in f16 or bf16; everything
//! after it stays f32.
//!
//! The split follows VGGT, which runs its aggregator under autocast and its heads with
//! autocast off: the camera head decodes poses through trigonometry and the DPT heads end in
//! `exp` activations, where half-precision rounding shows up in the geometry. Inside the
//! aggregator, Burn's `LayerNorm` takes its statistics in f32 for half inputs: f16 tops out at
//! 65 504, so the variance of tokens beyond about 256 would overflow (PyTorch's autocast keeps
//! `layer_norm` in f32 for the same reason; a test holds Burn to it).
//!
//! Training stays f32: Burn 0.22 has neither f32 master weights nor loss scaling, which
//! half-precision training needs (docs/TRAINING.md, "Precision").

use burn::module::{Module, ModuleMapper, Param};
use burn::tensor::{DType, Device, Tensor};

/// The float format of the aggregator's weights and activations at inference.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum Precision {
    /// IEEE single precision everywhere (the default; what parity is checked in).
    #[default]
    F32,
    /// IEEE half precision (10-bit mantissa, range ±65 504) in the aggregator.
    F16,
    /// bfloat16 (7-bit mantissa, f32's range) in the aggregator.
    Bf16,
}

impl Precision {
    /// The Burn dtype of the aggregator's tensors.
    pub fn dtype(self) -> DType {
        match self {
            Precision::F32 => DType::F32,
            Precision::F16 => DType::F16,
            Precision::Bf16 => DType::BF16,
        }
    }

    pub const ALL: [Precision; 3] = [Precision::F32, Precision::F16, Precision::Bf16];

    /// The name `--precision` spells.
    pub fn name(self) -> &'static str {
        match self {
            Precision::F32 => "f32",
            Precision::F16 => "f16",
            Precision::Bf16 => "bf16",
        }
    }

    /// The precision `name` spells ([`Precision::name`]).
    pub fn from_name(name: &str) -> Option<Precision> {
        Self::ALL.into_iter().find(|p| p.name() == name)
    }

    /// Whether `device` can compute in this precision (storage, conversion and arithmetic);
    /// `Err` names the device and the dtype. wgpu has no bf16 (WGSL has no such type), and
    /// f16 needs the adapter's `shader-f16` feature.
    pub fn check(self, device: &Device) -> Result<(), String> {
        if self == Precision::F32 || device.supports_dtype(self.dtype()) {
            Ok(())
        } else {
            Err(format!(
                "{device:?} cannot compute in {} ({:?} is not supported there); use f32{}",
                self.name(),
                self.dtype(),
                if self == Precision::Bf16 {
                    ", or f16 where the device has it"
                } else {
                    ""
                }
            ))
        }
    }
}

/// `module` with every float parameter cast to `dtype` (ids and trainability kept).
pub fn cast_params<M: Module>(module: M, dtype: DType) -> M {
    struct Cast(DType);
    impl ModuleMapper for Cast {
        fn map_float<const D: usize>(&mut self, p: Param<Tensor<D>>) -> Param<Tensor<D>> {
            let dtype = self.0;
            p.map(|t| if t.dtype() == dtype { t } else { t.cast(dtype) })
        }
    }
    module.map(&mut Cast(dtype))
}
