//! Diagnostics of the motion head's training signal, never part of the paper's loss
//! (docs/TRAINING.md, "Motion diagnostics"). The rendering loss is the motion head's only
//! teacher, and on the motion benchmark it reaches the head three orders of magnitude weaker
//! than the distillation terms reach the other heads (docs/RESULTS.md, "Where the gradient
//! goes"). These ask why the head still learns no object motion:
//! - `[loss] dynamic_weight` (off by default): more rendering signal on the ground-truth
//!   moving objects ([`pixel_weights`]);
//! - `[loss] lambda_flow` (off by default): the exact scene flow as a direct target
//!   ([`flow_loss`]), whether the head can represent the motion at all;
//! - [`gradient_alignment`]: whether the rendering loss's gradient points each displacement
//!   toward the truth (`examples/motion_gradient.rs`).
//!
//! All read ground truth only the synthetic world has, so they diagnose; they do not train
//! a model for real data.

use crate::batch::Batch;
use crate::error::{Result, TrainError};
use burn::tensor::{Tensor, TensorData};
use envision4d_eval::motion::{exact_motions, PredictedMotion};
use envision4d_eval::pose_error::host_extrinsics;
use envision4d_model::scene::Scene;
use glam::DVec3;

/// `[F, 1, H, W]` per-pixel weights of element `b`'s `targets`: `1 + w` on the target
/// frame's dynamic mask (where the mover must appear), 1 elsewhere. `None` without masks.
pub(crate) fn pixel_weights(
    batch: &Batch,
    b: usize,
    targets: &[usize],
    w: f64,
) -> Option<Tensor<4>> {
    let dynamic = batch.dynamic.as_ref()?;
    let [_, _, _, h, wd] = dynamic.dims();
    let frames = targets
        .iter()
        .map(|&j| {
            dynamic
                .clone()
                .slice([b..b + 1, j..j + 1, 0..1, 0..h, 0..wd])
                .reshape([1, 1, h, wd])
        })
        .collect();
    Some(Tensor::cat(frames, 0) * w + 1.0)
}

/// `λ_flow`'s term: the mean L1 distance between the predicted displacements
/// (`AdaptedGaussians::motions`, `[B, T_c, N−1, G, 3]`) and the exact ones in each element's
/// own axes and unit, averaged over the elements whose truth aligns (a clip whose scale
/// cannot be fitted adds nothing; when none does, the term is 0). Sky pixels, which have no
/// surface, get the exact displacement 0. `balanced`: the moving pixels (non-zero exact
/// displacement) and the static ones each make half of an element's mean, so the static
/// majority (~92% of the suite's pixels) cannot make zero motion the L1 optimum. Reads the
/// means and the cameras back to the host: a diagnostic's cost.
pub(crate) fn flow_loss(
    scene: &Scene,
    batch: &Batch,
    (tc, n): (usize, usize),
    balanced: bool,
) -> Result<Tensor<1>> {
    let truth = batch.motion.as_ref().ok_or_else(|| {
        TrainError::Internal("loss.lambda_flow is on but the batch carries no motion truth".into())
    })?;
    let a = &scene.adapted;
    let [bsz, _, k, g, _] = a.motions.dims();
    let [_, _, _, h, w] = batch.images.dims();
    if truth.len() != bsz {
        return Err(TrainError::Internal(format!(
            "motion truth of {} clips for a batch of {bsz}",
            truth.len()
        )));
    }
    let device = a.motions.device();
    let means: Vec<f32> = a.means.clone().detach().into_data().iter::<f32>().collect();
    let per_element = tc * g * 3;
    let mut target = Vec::with_capacity(bsz * tc * k * g * 3);
    let mut valid = Vec::with_capacity(bsz);
    let mut weights = Vec::with_capacity(bsz * tc * k * g);
    for (b, clip) in truth.iter().enumerate() {
        let extrinsics = host_extrinsics(&scene.pred.backbone.extrinsics, b)
            .map_err(|e| TrainError::Internal(format!("predicted cameras: {e}")))?;
        let pred = PredictedMotion {
            context: tc,
            frames: n,
            grid: (h, w),
            means: &means[b * per_element..(b + 1) * per_element],
            // Not read: only the alignment (scale, axes) comes from the prediction.
            motions: &[],
            extrinsics: &extrinsics,
        };
        match exact_motions(&pred, &clip.truth()) {
            Some(m) => {
                weights.extend(point_weights(&m, balanced));
                target.extend(m);
                valid.push(1.0f32);
            }
            None => {
                target.extend(std::iter::repeat_n(0.0, tc * k * g * 3));
                weights.extend(std::iter::repeat_n(0.0, tc * k * g));
                valid.push(0.0);
            }
        }
    }
    let count = valid.iter().sum::<f32>().max(1.0);
    let target = Tensor::<5>::from_data(TensorData::new(target, [bsz, tc, k, g, 3]), &device);
    let valid = Tensor::<1>::from_data(TensorData::new(valid, [bsz]), &device);
    let weights = Tensor::<5>::from_data(TensorData::new(weights, [bsz, tc, k, g, 1]), &device);
    // Each element's weights sum to 1 over its points; a point's L1 is the mean over x, y, z.
    let l1 = ((a.motions.clone() - target).abs() * weights)
        .reshape([bsz, tc * k * g * 3])
        .sum_dim(1)
        .reshape([bsz])
        / 3.0;
    Ok((l1 * valid).sum() / count as f64)
}

/// One element's weight per point (`exact` is `[.., 3]`), summing to 1: uniform, or
/// `balanced` with the moving and the static points each summing to ½ (all to the one set
/// present when the other is empty).
fn point_weights(exact: &[f32], balanced: bool) -> Vec<f32> {
    let moving: Vec<bool> = exact.chunks_exact(3).map(|d| d != [0.0; 3]).collect();
    let total = moving.len().max(1) as f32;
    if !balanced {
        return vec![1.0 / total; moving.len()];
    }
    let n_moving = moving.iter().filter(|&&m| m).count();
    let n_static = moving.len() - n_moving;
    let share = |n: usize, other: usize| match (n, other) {
        (0, _) => 0.0,
        (_, 0) => 1.0 / n as f32,
        _ => 0.5 / n as f32,
    };
    let (w_moving, w_static) = (share(n_moving, n_static), share(n_static, n_moving));
    moving
        .iter()
        .map(|&m| if m { w_moving } else { w_static })
        .collect()
}

/// How well the rendering loss's gradient points the Gaussians of one target timestamp
/// toward their exact positions ([`gradient_alignment`]).
#[derive(Debug, Clone, PartialEq)]
pub struct AlignmentRow {
    /// Target timestamp `j` (every context source `i ≠ j` pooled).
    pub target: usize,
    /// Pixels whose exact displacement is non-zero, and how many of them get any gradient.
    pub moving: usize,
    pub moving_reached: usize,
    /// `Σ (−g)·e / sqrt(Σ|g|² · Σ|e|²)` over the moving pixels, `e = exact − current`: 1
    /// when the descent direction is the way to the truth, 0 when unrelated.
    pub moving_cosine: Option<f64>,
    /// The same with `g` and `e` projected on the plane across the target camera's ray
    /// through the Gaussian (what an image can show of a displacement; the part along the
    /// ray only changes a Gaussian's size on screen).
    pub moving_image_cosine: Option<f64>,
    /// The mean per-pixel image-plane cosine over moving pixels with a gradient.
    pub moving_image_mean_cosine: Option<f64>,
    /// The aggregate image-plane cosine on the static pixels (toward rest).
    pub static_image_cosine: Option<f64>,
    /// Root mean square of the gradient per moving / static pixel.
    pub moving_grad_rms: f64,
    pub static_grad_rms: f64,
}

#[derive(Default)]
struct Sums {
    dot: f64,
    gg: f64,
    ee: f64,
    n: usize,
    reached: usize,
    cos_sum: f64,
}

impl Sums {
    fn add(&mut self, g: DVec3, e: DVec3) {
        let (dot, gg, ee) = (-g.dot(e), g.length_squared(), e.length_squared());
        self.dot += dot;
        self.gg += gg;
        self.ee += ee;
        self.n += 1;
        if gg > 0.0 && ee > 0.0 {
            self.reached += 1;
            self.cos_sum += dot / (gg * ee).sqrt();
        }
    }

    fn cosine(&self) -> Option<f64> {
        (self.gg > 0.0 && self.ee > 0.0).then(|| self.dot / (self.gg * self.ee).sqrt())
    }

    fn mean_cosine(&self) -> Option<f64> {
        (self.reached > 0).then(|| self.cos_sum / self.reached as f64)
    }

    fn rms(&self) -> f64 {
        if self.n == 0 {
            0.0
        } else {
            (self.gg / self.n as f64).sqrt()
        }
    }
}

/// One element's displacements and where they are seen from, all in the model's world:
/// `[T_c, N−1, G, 3]` buffers laid out as `AdaptedGaussians::motions`, the `[T_c, G, 3]`
/// means, and the `N` camera centres.
pub struct AlignmentInputs<'a> {
    pub grad: &'a [f32],
    pub exact: &'a [f32],
    pub current: &'a [f32],
    pub means: &'a [f32],
    pub centres: &'a [DVec3],
    pub context: usize,
}

/// Per future target `j ≥ T_c`, how the gradient of a rendering loss with respect to the
/// displacements relates to the way from the current displacements to the exact ones. A
/// pixel is moving when its exact displacement is non-zero (static scenery's is exactly 0).
pub fn gradient_alignment(x: &AlignmentInputs) -> Vec<AlignmentRow> {
    let (tc, n) = (x.context, x.centres.len());
    let g = x.means.len() / (3 * tc.max(1));
    let at =
        |s: &[f32], k: usize| DVec3::new(s[3 * k] as f64, s[3 * k + 1] as f64, s[3 * k + 2] as f64);
    (tc..n)
        .map(|j| {
            let (mut moving, mut moving_img, mut still_img) =
                (Sums::default(), Sums::default(), Sums::default());
            for i in 0..tc {
                let slot = i * (n - 1) + envision4d_model::motion::target_slot(i, j);
                for p in 0..g {
                    let k = slot * g + p;
                    let (gr, ex, cu) = (at(x.grad, k), at(x.exact, k), at(x.current, k));
                    let e = ex - cu;
                    let ray = (at(x.means, i * g + p) + cu - x.centres[j]).normalize_or_zero();
                    let across = |v: DVec3| v - ray * v.dot(ray);
                    if ex != DVec3::ZERO {
                        moving.add(gr, e);
                        moving_img.add(across(gr), across(e));
                    } else {
                        still_img.add(across(gr), across(e));
                    }
                }
            }
            AlignmentRow {
                target: j,
                moving: moving.n,
                moving_reached: moving.reached,
                moving_cosine: moving.cosine(),
                moving_image_cosine: moving_img.cosine(),
                moving_image_mean_cosine: moving_img.mean_cosine(),
                static_image_cosine: still_img.cosine(),
                moving_grad_rms: moving.rms(),
                static_grad_rms: still_img.rms(),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::tensor::Device;

    /// Guards the weight map against picking the wrong frame or element (the mask of the
    /// frame being rendered must weight its pixels) and a wrong `1 + w`: two elements of
    /// three 1x2 frames, each frame's mask marks a different pixel.
    #[test]
    fn weights_are_one_plus_w_on_the_target_frames_mask() {
        let device = Device::default();
        // Element 0: frames mark pixel (0, 0), (0, 1), none; element 1: none, none, both.
        let masks = vec![1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0];
        let batch = Batch {
            images: Tensor::zeros([2, 3, 3, 1, 2], &device),
            labels: None,
            dynamic: Some(Tensor::from_data(
                TensorData::new(masks, [2, 3, 1, 1, 2]),
                &device,
            )),
            motion: None,
        };
        let got = |b: usize, targets: &[usize]| -> Vec<f32> {
            pixel_weights(&batch, b, targets, 4.0)
                .expect("masks present")
                .into_data()
                .iter::<f32>()
                .collect()
        };
        assert_eq!(got(0, &[1, 0]), vec![1.0, 5.0, 5.0, 1.0]);
        assert_eq!(got(1, &[2]), vec![5.0, 5.0]);
        assert_eq!(got(1, &[0, 1]), vec![1.0; 4]);
        let without = Batch {
            dynamic: None,
            ..batch.clone()
        };
        assert!(pixel_weights(&without, 0, &[0], 4.0).is_none());
    }

    /// Guards the balanced flow target's weights (a static majority must not outweigh the
    /// movers; every element's weights sum to 1): 1 moving and 3 static points, and the
    /// all-static case.
    #[test]
    fn balanced_point_weights_split_moving_and_static_halves() {
        let exact = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
        assert_eq!(point_weights(&exact, false), vec![0.25; 4]);
        let b = point_weights(&exact, true);
        assert_eq!(b, vec![0.5, 0.5 / 3.0, 0.5 / 3.0, 0.5 / 3.0]);
        assert_eq!(point_weights(&[0.0; 6], true), vec![0.5, 0.5]);
    }

    /// Guards the alignment's sign, pooling and image-plane projection (a descent direction
    /// read as the gradient itself would report −1 for a perfect signal; a projection on the
    /// wrong axis would keep the part along the ray): T_c = 1, N = 2, the target camera at
    /// the origin looking down +z, three pixels at (0, 0, 10): one moving pixel whose
    /// descent points at the truth across the ray, one whose truth is along the ray, one
    /// static.
    #[test]
    fn alignment_of_a_hand_built_gradient() {
        let exact = [2.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0];
        let current = [0.0; 9];
        // Descent −g: (1,0,0) toward pixel 0's truth; (0,1,1) for pixel 1, whose truth
        // (0,0,1) lies along the ray; pixel 2 static, pushed across the ray.
        let grad = [-1.0, 0.0, 0.0, 0.0, -1.0, -1.0, 0.0, 3.0, 0.0];
        let means = [0.0, 0.0, 10.0, 0.0, 0.0, 10.0, 0.0, 0.0, 10.0];
        let centres = [DVec3::ZERO, DVec3::ZERO];
        let rows = gradient_alignment(&AlignmentInputs {
            grad: &grad,
            exact: &exact,
            current: &current,
            means: &means,
            centres: &centres,
            context: 1,
        });
        assert_eq!(rows.len(), 1);
        let r = &rows[0];
        assert_eq!((r.target, r.moving, r.moving_reached), (1, 2, 2));
        // 3D: Σ(−g)·e = 2 + 1; Σ|g|² = 1 + 2; Σ|e|² = 4 + 1.
        let want = 3.0 / (3.0f64 * 5.0).sqrt();
        assert!((r.moving_cosine.unwrap() - want).abs() < 1e-12, "{r:?}");
        // Across the ray (z dropped): pixel 0 as before; pixel 1's e vanishes, so only
        // pixel 0 has a cosine (1) and the aggregate is 2 / sqrt((1 + 1) · 4).
        assert!(
            (r.moving_image_mean_cosine.unwrap() - 1.0).abs() < 1e-12,
            "{r:?}"
        );
        let want = 2.0 / (2.0f64 * 4.0).sqrt();
        assert!(
            (r.moving_image_cosine.unwrap() - want).abs() < 1e-12,
            "{r:?}"
        );
        // Static at rest: no direction to compare, but its gradient is counted.
        assert_eq!(r.static_image_cosine, None);
        assert!((r.static_grad_rms - 3.0).abs() < 1e-12);
        assert!((r.moving_grad_rms - 1.5f64.sqrt()).abs() < 1e-12);
    }
}
