//! DPT fusion blocks (`scratch.refinenet*`) and their residual conv units.

use crate::layers::cpu_conv::conv2d;
use crate::resample::bilinear_align_corners;
use burn::module::Module;
use burn::nn::conv::{Conv2d, Conv2dConfig};
use burn::nn::PaddingConfig2d;
use burn::tensor::activation::relu;
use burn::tensor::{Device, Tensor};

/// `conv2(relu(conv1(relu(x)))) + relu(x)`: the reference applies `ReLU(inplace=True)` to the
/// input itself, so the skip connection adds `relu(x)`, not `x`.
#[derive(Module, Debug)]
pub struct ResidualConvUnit {
    pub conv1: Conv2d,
    pub conv2: Conv2d,
}

pub fn conv3x3(cin: usize, cout: usize, bias: bool, device: &Device) -> Conv2d {
    Conv2dConfig::new([cin, cout], [3, 3])
        .with_padding(PaddingConfig2d::Explicit(1, 1, 1, 1))
        .with_bias(bias)
        .init(device)
}

pub fn conv1x1(cin: usize, cout: usize, device: &Device) -> Conv2d {
    Conv2dConfig::new([cin, cout], [1, 1]).init(device)
}

impl ResidualConvUnit {
    pub fn new(features: usize, device: &Device) -> Self {
        ResidualConvUnit {
            conv1: conv3x3(features, features, true, device),
            conv2: conv3x3(features, features, true, device),
        }
    }

    pub fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        let x = relu(x);
        conv2d(&self.conv2, relu(conv2d(&self.conv1, x.clone()))) + x
    }
}

/// Where a fusion block's output goes.
#[derive(Debug, Clone, Copy)]
pub enum FusionSize {
    /// To an explicit `(h, w)` (the next finer level).
    To(usize, usize),
    /// Twice the input size (the last block).
    Double,
}

/// `FeatureFusionBlock`: optional residual input, RCU, bilinear resize, 1x1 conv.
#[derive(Module, Debug)]
pub struct FeatureFusion {
    pub out_conv: Conv2d,
    pub res_conf_unit1: Option<ResidualConvUnit>,
    pub res_conf_unit2: ResidualConvUnit,
}

/// Whether a fusion block takes a skip input from its own level.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Skip {
    Yes,
    No,
}

impl FeatureFusion {
    pub fn new(features: usize, skip: Skip, device: &Device) -> Self {
        FeatureFusion {
            out_conv: conv1x1(features, features, device),
            res_conf_unit1: (skip == Skip::Yes).then(|| ResidualConvUnit::new(features, device)),
            res_conf_unit2: ResidualConvUnit::new(features, device),
        }
    }

    pub fn forward(&self, x: Tensor<4>, skip: Option<Tensor<4>>, size: FusionSize) -> Tensor<4> {
        let mut out = x;
        if let (Some(rcu), Some(s)) = (&self.res_conf_unit1, skip) {
            out = out + rcu.forward(s);
        }
        out = self.res_conf_unit2.forward(out);
        let [_, _, h, w] = out.dims();
        let (oh, ow) = match size {
            FusionSize::To(h, w) => (h, w),
            FusionSize::Double => (2 * h, 2 * w),
        };
        self.out_conv.forward(bilinear_align_corners(out, oh, ow))
    }
}
