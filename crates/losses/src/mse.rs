//! Differentiable per-frame MSE, the first term of `L_rgb`.

use burn::tensor::Tensor;

use crate::error::{LossError, Result};

/// Mean squared error per frame: `mean over (C, H, W) of (pred − target)²`, shape `[F]`.
///
/// `pred` and `target` are `[F, C, H, W]` on the same device and dtype; `target` is detached
/// (it is data). Per frame so that the progressive extrapolation weights `w̄_t` can be applied
/// by the caller. No clipping: the training loss sees the raw render.
pub fn mse_per_frame(pred: Tensor<4>, target: Tensor<4>) -> Result<Tensor<1>> {
    check_pair("mse", &pred, &target)?;
    let [f, c, h, w] = pred.dims();
    let diff = pred - target.detach();
    Ok(diff
        .square()
        .reshape([f, c * h * w])
        .mean_dim(1)
        .reshape([f]))
}

/// Pixel-weighted mean squared error per frame: `Σ weight·(pred − target)² / (C·Σ weight)`
/// over (C, H, W), shape `[F]`; `weight` is `[F, 1, H, W]`, ≥ 0 with a positive sum per
/// frame (the caller's contract; a constant weight gives [`mse_per_frame`]). The weights
/// are data: detached like the target. The training step uses it to put more of the
/// rendering loss on the ground-truth moving objects (`[loss] dynamic_weight`).
pub fn weighted_mse_per_frame(
    pred: Tensor<4>,
    target: Tensor<4>,
    weight: Tensor<4>,
) -> Result<Tensor<1>> {
    check_pair("weighted mse", &pred, &target)?;
    let [f, c, h, w] = pred.dims();
    if weight.dims() != [f, 1, h, w] {
        return Err(LossError::ShapeMismatch {
            what: "weighted mse weight",
            left: vec![f, 1, h, w],
            right: weight.dims().to_vec(),
        });
    }
    let weight = weight.detach();
    let norm = weight.clone().reshape([f, h * w]).sum_dim(1).reshape([f]) * c as f64;
    let diff = pred - target.detach();
    let num = (diff.square() * weight)
        .reshape([f, c * h * w])
        .sum_dim(1)
        .reshape([f]);
    Ok(num / norm)
}

/// Shape and dtype check for a (prediction, reference) image pair `[F, C, H, W]`.
pub(crate) fn check_pair(what: &'static str, a: &Tensor<4>, b: &Tensor<4>) -> Result<()> {
    check_same(what, "non-empty [F, C, H, W]", a, b)
}

/// Both tensors have the same non-empty shape and the same dtype; `expected` describes the
/// shape in the error.
pub(crate) fn check_same<const D: usize>(
    what: &'static str,
    expected: &'static str,
    a: &Tensor<D>,
    b: &Tensor<D>,
) -> Result<()> {
    let (da, db) = (a.dims(), b.dims());
    if da != db {
        return Err(LossError::ShapeMismatch {
            what,
            left: da.to_vec(),
            right: db.to_vec(),
        });
    }
    if da.contains(&0) {
        return Err(LossError::BadShape {
            what,
            expected,
            got: da.to_vec(),
        });
    }
    if a.dtype() != b.dtype() {
        return Err(LossError::DtypeMismatch {
            what,
            expected: format!("{:?}", a.dtype()),
            got: format!("{:?}", b.dtype()),
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::tensor::{Device, TensorData};

    fn t4(v: Vec<f32>, shape: [usize; 4]) -> Tensor<4> {
        Tensor::from_data(TensorData::new(v, shape), &Device::default())
    }

    /// Guards the weighted rendering loss against a wrong normaliser (per channel, per
    /// frame): hand-computed on a 1x2x1x2 pair with weights (1, 3).
    #[test]
    fn weighted_mse_matches_a_hand_count() {
        // Channel 0 errors (1, 2), channel 1 errors (0, 1).
        let pred = t4(vec![1.0, 2.0, 0.0, 1.0], [1, 2, 1, 2]);
        let target = t4(vec![0.0; 4], [1, 2, 1, 2]);
        let weight = t4(vec![1.0, 3.0], [1, 1, 1, 2]);
        let got: Vec<f32> = weighted_mse_per_frame(pred.clone(), target.clone(), weight)
            .expect("weighted")
            .into_data()
            .iter::<f32>()
            .collect();
        // (1·1 + 3·4 + 1·0 + 3·1) / (2 · 4) = 16 / 8.
        assert!((got[0] - 2.0).abs() < 1e-6, "{got:?}");
        let flat = t4(vec![5.0, 5.0], [1, 1, 1, 2]);
        let a = weighted_mse_per_frame(pred.clone(), target.clone(), flat).expect("flat");
        let b = mse_per_frame(pred, target).expect("mse");
        let d = (a - b).abs().max().into_scalar::<f32>();
        assert!(
            d < 1e-6,
            "a constant weight must give the plain MSE, off by {d}"
        );
    }

    /// Guards against a weight map of the wrong grid being broadcast silently.
    #[test]
    fn weighted_mse_refuses_a_weight_of_another_shape() {
        let pred = t4(vec![0.0; 4], [1, 1, 2, 2]);
        let weight = t4(vec![1.0; 2], [1, 1, 1, 2]);
        assert!(weighted_mse_per_frame(pred.clone(), pred, weight).is_err());
    }
}
