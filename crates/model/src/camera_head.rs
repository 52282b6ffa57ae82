//! VGGT's camera head: iterative refinement of a 9-d pose encoding with an AdaLN-modulated
//! transformer trunk (4 iterations). Prefix `camera_head.`.

use crate::config::{CAMERA_ITERATIONS, CAMERA_TRUNK_DEPTH, MLP_RATIO, POSE_ENC_DIM};
use crate::layers::norm::layer_norm;
use crate::layers::{Block, BlockSpec, Mlp, QkNorm, BLOCK_NORM_EPS};
use crate::pose::{FOV, QUATERNION, TRANSLATION};
use burn::module::{Module, Param};
use burn::nn::{LayerNorm, LayerNormConfig, Linear, LinearConfig};
use burn::tensor::activation::{relu, silu};
use burn::tensor::{Device, Tensor};

/// Epsilon of the affine-free `adaln_norm`.
pub const ADALN_EPS: f64 = 1e-6;

#[derive(Module, Debug)]
pub struct CameraHead {
    pub token_norm: LayerNorm,
    pub trunk: Vec<Block>,
    pub trunk_norm: LayerNorm,
    pub empty_pose_tokens: Param<Tensor<3>>,
    pub embed_pose: Linear,
    /// `poseLN_modulation.1` in the release (index 0 is the SiLU).
    pub pose_ln_modulation: Linear,
    pub pose_branch: Mlp,
}

/// Layer norm without affine parameters over the last axis.
pub fn plain_layer_norm(x: Tensor<3>, eps: f64) -> Tensor<3> {
    let mean = x.clone().mean_dim(2);
    let centred = x - mean;
    let var = centred.clone().powf_scalar(2.0).mean_dim(2);
    centred / var.add_scalar(eps).sqrt()
}

impl CameraHead {
    pub fn new(dim: usize, num_heads: usize, device: &Device) -> Self {
        let norm = || {
            LayerNormConfig::new(dim)
                .with_epsilon(BLOCK_NORM_EPS)
                .init(device)
        };
        let spec = BlockSpec {
            dim,
            num_heads,
            mlp_ratio: MLP_RATIO,
            qk_norm: QkNorm::Off,
            norm_eps: BLOCK_NORM_EPS,
            layer_scale_init: 0.01,
        };
        CameraHead {
            token_norm: norm(),
            trunk: (0..CAMERA_TRUNK_DEPTH)
                .map(|_| Block::new(spec, device))
                .collect(),
            trunk_norm: norm(),
            empty_pose_tokens: Param::from_tensor(Tensor::zeros([1, 1, POSE_ENC_DIM], device)),
            embed_pose: LinearConfig::new(POSE_ENC_DIM, dim).init(device),
            pose_ln_modulation: LinearConfig::new(dim, 3 * dim).init(device),
            pose_branch: Mlp::with_output(dim, dim / 2, POSE_ENC_DIM, device),
        }
    }

    /// `tokens: [B, N, dim]` → the activated pose encoding after every iteration
    /// (`[B, N, 9]` each); the last one is the prediction.
    pub fn forward(&self, tokens: Tensor<3>) -> Vec<Tensor<3>> {
        let [b, n, dim] = tokens.dims();
        let tau = layer_norm(&self.token_norm, tokens);
        let tau_norm = plain_layer_norm(tau.clone(), ADALN_EPS);
        let mut acc: Option<Tensor<3>> = None;
        let mut outs = Vec::with_capacity(CAMERA_ITERATIONS);
        for _ in 0..CAMERA_ITERATIONS {
            // The previous (pre-activation) estimate conditions the next; detached as in VGGT
            // training so each iteration learns a residual.
            let u = match &acc {
                None => self
                    .embed_pose
                    .forward(self.empty_pose_tokens.val().expand([b, n, POSE_ENC_DIM])),
                Some(e) => self.embed_pose.forward(e.clone().detach()),
            };
            let modulation = self.pose_ln_modulation.forward(silu(u));
            let chunk = |i: usize| {
                modulation
                    .clone()
                    .slice([0..b, 0..n, i * dim..(i + 1) * dim])
            };
            let (shift, scale, gate) = (chunk(0), chunk(1), chunk(2));
            let m = gate * (tau_norm.clone() * scale.add_scalar(1.0) + shift) + tau.clone();
            let y = self.trunk.iter().fold(m, |x, blk| blk.forward(x, None));
            let delta = self.pose_branch.forward(layer_norm(&self.trunk_norm, y));
            let e = match acc {
                None => delta,
                Some(prev) => prev + delta,
            };
            outs.push(activate_pose(e.clone()));
            acc = Some(e);
        }
        outs
    }
}

impl CameraHead {
    /// Sets the last layer so a fresh head predicts the identity pose with both FoVs
    /// `fov_rad`: the head sums its [`CAMERA_ITERATIONS`] refinement deltas, so the bias is
    /// that share of `[t = 0, q = (0, 0, 0, 1), fov, fov]`, and the weight is scaled by
    /// `weight_scale` (small, as AdaLN-zero-style output layers are).
    pub fn init_identity_pose(&mut self, fov_rad: f32, weight_scale: f64) {
        let fc2 = &mut self.pose_branch.fc2;
        let device = fc2.weight.device();
        fc2.weight =
            Param::from_tensor(fc2.weight.val().detach().mul_scalar(weight_scale).detach());
        let k = CAMERA_ITERATIONS as f32;
        let mut bias = [0.0f32; POSE_ENC_DIM];
        bias[QUATERNION.end - 1] = 1.0 / k;
        for c in FOV {
            bias[c] = fov_rad / k;
        }
        fc2.bias = Some(Param::from_tensor(Tensor::<1>::from_floats(bias, &device)));
    }
}

/// Translation and quaternion linear, field of view ReLU.
pub fn activate_pose(e: Tensor<3>) -> Tensor<3> {
    let [b, n, _] = e.dims();
    let tq = e
        .clone()
        .slice([0..b, 0..n, TRANSLATION.start..QUATERNION.end]);
    let fov = relu(e.slice([0..b, 0..n, FOV]));
    Tensor::cat(vec![tq, fov], 2)
}
