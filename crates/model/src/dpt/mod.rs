//! DPT heads (`depth_head.`, `gs_head.`, `motion_head.`): four token taps → projected,
//! resized pyramid → top-down fusion → full-resolution prediction.
//!
//! Per level: LayerNorm, reshape to the patch grid, 1x1 projection, + 0.1·pos-embed, resize
//! (ConvT x4, ConvT x2, identity, conv stride 2), 3x3 conv to `features`. Fusion runs coarse to
//! fine; the result is bilinearly upsampled to the image (align_corners=True), gets the
//! pos-embed again and goes through the head-specific output convolutions.

pub mod fusion;
pub mod pos_embed;

use crate::config::{DptConfig, MotionModel};
use crate::layers::cpu_conv::conv2d;
use crate::layers::norm::layer_norm;
use crate::resample::bilinear_align_corners;
use burn::module::Module;
use burn::nn::conv::{Conv2d, Conv2dConfig, ConvTranspose2d, ConvTranspose2dConfig};
use burn::nn::{LayerNorm, LayerNormConfig, PaddingConfig2d};
use burn::tensor::activation::relu;
use burn::tensor::{Device, Tensor};
use fusion::{conv1x1, conv3x3, FeatureFusion, FusionSize, Skip};
use pos_embed::dpt_pos_embed;

/// Channels of the last hidden conv of every head (`head_features_2`, hard-wired).
pub const HEAD_FEATURES_2: usize = 32;

/// Which head: decides the output convolutions and activations.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DptKind {
    /// 2 channels: depth = exp, confidence = 1 + exp; `output_conv1` halves the features.
    Depth,
    /// 11 raw channels, with the image merged in through `input_merger`.
    Gaussians,
    /// Raw motion channels, no activation: 3 (displacements) for conditioned motion lifting,
    /// 6 (forward | backward velocity) for the linear-velocity baseline.
    Motion(MotionModel),
}

impl DptKind {
    pub fn output_dim(self) -> usize {
        match self {
            DptKind::Depth => 2,
            DptKind::Gaussians => crate::config::GAUSSIAN_DIM,
            DptKind::Motion(m) => m.head_channels(),
        }
    }
}

/// `scratch.output_conv2` (`.0` 3x3 conv, `.1` ReLU, `.2` 1x1 conv).
#[derive(Module, Debug)]
pub struct OutputConv2 {
    pub conv1: Conv2d,
    pub conv2: Conv2d,
}

#[derive(Module, Debug)]
pub struct Scratch {
    pub layer1_rn: Conv2d,
    pub layer2_rn: Conv2d,
    pub layer3_rn: Conv2d,
    pub layer4_rn: Conv2d,
    pub refinenet1: FeatureFusion,
    pub refinenet2: FeatureFusion,
    pub refinenet3: FeatureFusion,
    pub refinenet4: FeatureFusion,
    pub output_conv1: Conv2d,
    pub output_conv2: OutputConv2,
}

#[derive(Module, Debug)]
pub struct DptHead {
    pub norm: LayerNorm,
    pub projects: Vec<Conv2d>,
    /// `resize_layers.0`: ConvTranspose2d k4 s4.
    pub resize0: ConvTranspose2d,
    /// `resize_layers.1`: ConvTranspose2d k2 s2 (`.2` is the identity).
    pub resize1: ConvTranspose2d,
    /// `resize_layers.3`: Conv2d k3 s2 p1.
    pub resize3: Conv2d,
    pub scratch: Scratch,
    /// `input_merger.0` of the Gaussian head: 7x7 conv of the normalised image.
    pub input_merger: Option<Conv2d>,
    pub patch_size: usize,
    /// What the head predicts; kept (not a parameter) so the forward pass can read the motion
    /// head's motion model without a second source of truth.
    #[module(skip)]
    pub kind: DptKind,
}

impl DptHead {
    pub fn new(
        kind: DptKind,
        dim_in: usize,
        cfg: &DptConfig,
        patch_size: usize,
        device: &Device,
    ) -> Self {
        let oc = cfg.out_channels;
        let f = cfg.features;
        let conv1_out = if kind == DptKind::Depth { f / 2 } else { f };
        DptHead {
            norm: LayerNormConfig::new(dim_in).init(device),
            projects: oc.iter().map(|&c| conv1x1(dim_in, c, device)).collect(),
            resize0: ConvTranspose2dConfig::new([oc[0], oc[0]], [4, 4])
                .with_stride([4, 4])
                .init(device),
            resize1: ConvTranspose2dConfig::new([oc[1], oc[1]], [2, 2])
                .with_stride([2, 2])
                .init(device),
            resize3: Conv2dConfig::new([oc[3], oc[3]], [3, 3])
                .with_stride([2, 2])
                .with_padding(PaddingConfig2d::Explicit(1, 1, 1, 1))
                .init(device),
            scratch: Scratch {
                layer1_rn: conv3x3(oc[0], f, false, device),
                layer2_rn: conv3x3(oc[1], f, false, device),
                layer3_rn: conv3x3(oc[2], f, false, device),
                layer4_rn: conv3x3(oc[3], f, false, device),
                refinenet1: FeatureFusion::new(f, Skip::Yes, device),
                refinenet2: FeatureFusion::new(f, Skip::Yes, device),
                refinenet3: FeatureFusion::new(f, Skip::Yes, device),
                refinenet4: FeatureFusion::new(f, Skip::No, device),
                output_conv1: conv3x3(f, conv1_out, true, device),
                output_conv2: OutputConv2 {
                    conv1: conv3x3(conv1_out, HEAD_FEATURES_2, true, device),
                    conv2: Conv2dConfig::new([HEAD_FEATURES_2, kind.output_dim()], [1, 1])
                        .init(device),
                },
            },
            input_merger: (kind == DptKind::Gaussians).then(|| {
                Conv2dConfig::new([3, f], [7, 7])
                    .with_padding(PaddingConfig2d::Explicit(3, 3, 3, 3))
                    .init(device)
            }),
            patch_size,
            kind,
        }
    }

    /// The motion model of a motion head; `None` for the depth and Gaussian heads.
    pub fn motion_model(&self) -> Option<MotionModel> {
        match self.kind {
            DptKind::Motion(m) => Some(m),
            DptKind::Depth | DptKind::Gaussians => None,
        }
    }

    /// Like [`DptHead::forward_raw`], `frame_chunk` frames at a time (0 = automatic,
    /// [`crate::model::dpt_chunk_frames`]): every frame is processed
    /// independently by the head, so chunking is exact and bounds the full-resolution
    /// activations (a 3x3 conv at 350x518x256 needs ~1.7 GB of im2col per frame on CPU).
    pub fn forward_chunked(
        &self,
        taps: &[Tensor<4>; 4],
        patch_start: usize,
        image_hw: [usize; 2],
        images: Option<Tensor<5>>,
        frame_chunk: usize,
    ) -> Tensor<5> {
        let [b, s, p, d] = taps[0].dims();
        let chunk = crate::model::dpt_chunk_frames(frame_chunk, image_hw);
        if s <= chunk {
            return self.forward_raw(taps, patch_start, image_hw, images);
        }
        let mut parts = Vec::with_capacity(s.div_ceil(chunk));
        for s0 in (0..s).step_by(chunk) {
            let s1 = (s0 + chunk).min(s);
            let sub: [Tensor<4>; 4] =
                std::array::from_fn(|k| taps[k].clone().slice([0..b, s0..s1, 0..p, 0..d]));
            let img = images.as_ref().map(|i| {
                let [_, _, c, h, w] = i.dims();
                i.clone().slice([0..b, s0..s1, 0..c, 0..h, 0..w])
            });
            parts.push(self.forward_raw(&sub, patch_start, image_hw, img));
        }
        Tensor::cat(parts, 1)
    }

    /// `taps`: four `[B, S, P, dim_in]` token tensors whose patch tokens start at
    /// `patch_start`; `image_hw` the input image size; `images` (`[B, S, 3, H, W]`,
    /// normalised) only for the Gaussian head. Returns the raw `[B, S, H, W, out]` prediction.
    pub fn forward_raw(
        &self,
        taps: &[Tensor<4>; 4],
        patch_start: usize,
        image_hw: [usize; 2],
        images: Option<Tensor<5>>,
    ) -> Tensor<5> {
        let [b, s, p, dim] = taps[0].dims();
        let (rows, cols) = (image_hw[0] / self.patch_size, image_hw[1] / self.patch_size);
        let device = taps[0].device();
        let mut levels = Vec::with_capacity(4);
        for (k, tap) in taps.iter().enumerate() {
            let x = tap
                .clone()
                .slice([0..b, 0..s, patch_start..p, 0..dim])
                .reshape([b * s, rows * cols, dim]);
            let x = layer_norm(&self.norm, x)
                .reshape([b * s, rows, cols, dim])
                .permute([0, 3, 1, 2]);
            let x = self.projects[k].forward(x);
            let c = x.dims()[1];
            let x = x + dpt_pos_embed(c, rows, cols, image_hw[0], image_hw[1], &device);
            let x = match k {
                0 => self.resize0.forward(x),
                1 => self.resize1.forward(x),
                2 => x,
                _ => self.resize3.forward(x),
            };
            levels.push(x);
        }
        let sc = &self.scratch;
        let l1 = conv2d(&sc.layer1_rn, levels[0].clone());
        let l2 = conv2d(&sc.layer2_rn, levels[1].clone());
        let l3 = conv2d(&sc.layer3_rn, levels[2].clone());
        let l4 = conv2d(&sc.layer4_rn, levels[3].clone());
        let hw = |t: &Tensor<4>| (t.dims()[2], t.dims()[3]);
        let (h3, w3) = hw(&l3);
        let (h2, w2) = hw(&l2);
        let (h1, w1) = hw(&l1);
        let o = sc.refinenet4.forward(l4, None, FusionSize::To(h3, w3));
        let o = sc.refinenet3.forward(o, Some(l3), FusionSize::To(h2, w2));
        let o = sc.refinenet2.forward(o, Some(l2), FusionSize::To(h1, w1));
        let o = sc.refinenet1.forward(o, Some(l1), FusionSize::Double);
        let o = conv2d(&sc.output_conv1, o);
        let (oh, ow) = (rows * self.patch_size, cols * self.patch_size);
        let o = bilinear_align_corners(o, oh, ow);
        let c = o.dims()[1];
        let mut o = o + dpt_pos_embed(c, oh, ow, image_hw[0], image_hw[1], &device);
        if let (Some(merger), Some(img)) = (&self.input_merger, images) {
            o = o + relu(conv2d(merger, img.reshape([b * s, 3, oh, ow])));
        }
        let o = sc
            .output_conv2
            .conv2
            .forward(relu(conv2d(&sc.output_conv2.conv1, o)));
        let out = o.dims()[1];
        o.permute([0, 2, 3, 1]).reshape([b, s, oh, ow, out])
    }
}

/// Depth head activations: `(depth [B,S,H,W,1] = exp(ch0), conf [B,S,H,W] = 1 + exp(ch1))`.
pub fn depth_activation(raw: Tensor<5>) -> (Tensor<5>, Tensor<4>) {
    let [b, s, h, w, _] = raw.dims();
    let depth = raw.clone().slice([0..b, 0..s, 0..h, 0..w, 0..1]).exp();
    let conf = raw
        .slice([0..b, 0..s, 0..h, 0..w, 1..2])
        .exp()
        .add_scalar(1.0)
        .reshape([b, s, h, w]);
    (depth, conf)
}
