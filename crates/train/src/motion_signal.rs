//! Two diagnostics of the motion head's training signal, off by default and never part of
//! the paper's loss (docs/TRAINING.md, "Motion diagnostics"). The rendering loss is the
//! motion head's only teacher, and on the motion benchmark it reaches the head three orders
//! of magnitude weaker than the distillation terms reach the other heads (docs/RESULTS.md,
//! "Where the gradient goes"). These ask why the head still learns no object motion:
//! - `[loss] dynamic_weight`: more rendering signal on the ground-truth moving objects
//!   ([`pixel_weights`]);
//! - `[loss] lambda_flow`: the exact scene flow as a direct target ([`flow_loss`]), whether
//!   the head can represent the motion at all.
//!
//! Both read ground truth only the synthetic world has, so they diagnose; they do not train
//! a model for real data.

use crate::batch::Batch;
use crate::error::{Result, TrainError};
use burn::tensor::{Tensor, TensorData};
use envision4d_eval::motion::{exact_motions, PredictedMotion};
use envision4d_eval::pose_error::host_extrinsics;
use envision4d_model::scene::Scene;

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
/// surface, get the exact displacement 0. Reads the means and the cameras back to the host:
/// a diagnostic's cost.
pub(crate) fn flow_loss(scene: &Scene, batch: &Batch, tc: usize, n: usize) -> Result<Tensor<1>> {
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
                target.extend(m);
                valid.push(1.0f32);
            }
            None => {
                target.extend(std::iter::repeat_n(0.0, tc * k * g * 3));
                valid.push(0.0);
            }
        }
    }
    let count = valid.iter().sum::<f32>().max(1.0);
    let target = Tensor::<5>::from_data(TensorData::new(target, [bsz, tc, k, g, 3]), &device);
    let valid = Tensor::<1>::from_data(TensorData::new(valid, [bsz]), &device);
    let l1 = (a.motions.clone() - target)
        .abs()
        .reshape([bsz, tc * k * g * 3])
        .mean_dim(1)
        .reshape([bsz]);
    Ok((l1 * valid).sum() / count as f64)
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
}
