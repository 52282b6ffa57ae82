//! The backbone's frame-1 camera must be able to learn from frame 0. The trained tiny
//! models read each camera off its own frame's look (docs/TRAINING.md); this keeps that
//! failure a matter of training, not of a network that cannot compare frames at all.

use burn::optim::{AdamConfig, GradientsParams};
use burn::tensor::{Device, Tensor, TensorData};
use envision4d_model::model::VggtDepth;
use envision4d_model::{Envision4d, ModelConfig};

/// A seeded LCG (the model crate does not depend on the data crate's RNG).
struct Rng(u64);

impl Rng {
    /// Uniform in [0, 1).
    fn unit(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }
}

/// Pairs per step: half brighten, half darken.
const BATCH: usize = 4;
const STEPS: usize = 300;
const LR: f64 = 1e-3;
/// Brightness change from frame 0 to frame 1 (×(1 ± GAIN_STEP)).
const GAIN_STEP: f32 = 0.3;

/// Frame pairs whose frame 1 is frame 0 brightened (label +1) or darkened (label −1); the
/// overall brightness of frame 0 is random, so neither frame alone tells the label.
fn pairs(rng: &mut Rng, h: usize, w: usize, device: &Device) -> (Tensor<5>, Tensor<1>) {
    let (mut img, mut labels) = (Vec::new(), Vec::new());
    for b in 0..BATCH {
        let sign = if b % 2 == 0 { 1.0f32 } else { -1.0 };
        let gain = rng.range(0.5, 1.5) as f32;
        let f0: Vec<f32> = (0..3 * h * w)
            .map(|_| ((0.2 + 0.6 * rng.unit()) as f32 * gain).min(1.0))
            .collect();
        let f1: Vec<f32> = f0
            .iter()
            .map(|v| (v * (1.0 + GAIN_STEP * sign)).min(1.0))
            .collect();
        img.extend(f0);
        img.extend(f1);
        labels.push(sign);
    }
    (
        Tensor::from_data(TensorData::new(img, [BATCH, 2, 3, h, w]), device),
        Tensor::from_data(TensorData::new(labels, [BATCH]), device),
    )
}

/// L1 of frame 1's forward translation against the label, summed over the camera head's
/// refinement iterations (what a blind network can do: ~1 per iteration).
fn loss(model: &Envision4d, images: Tensor<5>, labels: Tensor<1>) -> Tensor<1> {
    let out = model.vggt(images, VggtDepth::Skip);
    let device = labels.device();
    out.pose_enc_iters
        .iter()
        .fold(Tensor::zeros([1], &device), |acc, p| {
            let tz = p.clone().slice([0..BATCH, 1..2, 2..3]).reshape([BATCH]);
            acc + (tz - labels.clone()).abs().mean()
        })
}

fn scalar(t: Tensor<1>) -> f32 {
    t.into_data().iter::<f32>().next().expect("a scalar")
}

/// Guards a frame-1 camera that cannot see frame 0 (a global attention that stays within
/// frames, a camera trunk that ignores the other cameras, gradients cut between frames): a
/// brightness change between two frames, invisible to either frame alone, is learnt from a
/// random init within 300 Adam steps (the blind optimum stays at ~1 per iteration).
#[test]
fn frame_one_camera_learns_a_change_only_frame_zero_reveals() {
    let device = Device::flex().autodiff();
    let cfg = ModelConfig {
        depth: 4,
        temporal_layers: [0, 1, 2, 3],
        context_frames: 2,
        ..ModelConfig::tiny()
    };
    let [h, w] = cfg.image_size;
    let mut model = envision4d_model::seeded::seeded(&device, 11, || {
        Ok::<_, std::convert::Infallible>(Envision4d::new(&cfg, &device))
    })
    .unwrap();
    let mut optim = AdamConfig::new().with_epsilon(1e-5).init();
    let mut rng = Rng(5);
    let iterations = model.vggt(pairs(&mut rng, h, w, &device).0, VggtDepth::Skip);
    let blind = iterations.pose_enc_iters.len() as f32;
    let mut recent = Vec::new();
    for step in 0..STEPS {
        let (images, labels) = pairs(&mut rng, h, w, &device);
        let l = loss(&model, images, labels);
        if step + 20 >= STEPS {
            recent.push(scalar(l.clone()));
        }
        let grads = GradientsParams::from_grads(l.backward(), &model);
        model = optim.step(LR, model, grads);
    }
    let last = recent.iter().sum::<f32>() / recent.len() as f32;
    assert!(
        last < 0.3 * blind,
        "after {STEPS} steps the loss is {last:.3} (blind: ~{blind}): frame 1's camera did not learn what only frame 0 shows"
    );
}
