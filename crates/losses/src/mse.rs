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
