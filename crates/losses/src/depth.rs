//! D-RMSE: depth root-mean-square error against sparse ground truth (lidar), with an
//! explicit scale alignment, because a pose-free model's depth is only defined up to scale.

use crate::error::{LossError, Result};
use crate::host::HostDepths;

/// How the predicted depth is scaled before the error is taken. The release computes no
/// D-RMSE and the paper does not say which alignment its table uses, so the choice is
/// always explicit and reported next to the number.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DepthAlignment {
    /// No scaling: `s = 1` (metric-scale predictions).
    None,
    /// `s = median(gt) / median(pred)` over the valid pixels (robust to outliers).
    Median,
    /// `s = Σ pred·gt / Σ pred²` over the valid pixels: the scale minimising the squared error.
    LeastSquares,
}

/// Over which pixels one alignment scale is fitted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AlignmentScope {
    /// One scale per depth map.
    PerFrame,
    /// One scale shared by all maps passed in (e.g. a clip).
    Shared,
}

/// Result of [`depth_rmse`].
#[derive(Debug, Clone, PartialEq)]
pub struct DepthRmse {
    /// RMSE per map; `None` for a map without valid ground-truth pixels.
    pub per_frame: Vec<Option<f64>>,
    /// The scale applied to each map's prediction (1 for maps without valid pixels).
    pub scales: Vec<f64>,
    /// Mean of the per-map RMSEs over maps that have valid pixels.
    pub mean: f64,
}

/// Depth RMSE per map.
///
/// Definition: valid pixels are those with ground truth `> 0` (lidar convention: 0 = no
/// return). With `s` from `alignment` (fitted over `scope`),
/// `rmse = sqrt(mean over valid pixels of (s·pred − gt)²)`. Inputs are `[N, H, W]`
/// ray-distance or z-depth maps, both in the same convention (the caller's choice).
/// Errors: shape mismatch, no valid pixel at all, or a degenerate alignment (median or
/// `Σ pred²` of the prediction is 0).
pub fn depth_rmse(
    pred: &HostDepths,
    gt: &HostDepths,
    alignment: DepthAlignment,
    scope: AlignmentScope,
) -> Result<DepthRmse> {
    if pred.shape() != gt.shape() {
        return Err(LossError::ShapeMismatch {
            what: "depth rmse",
            left: pred.shape().to_vec(),
            right: gt.shape().to_vec(),
        });
    }
    let n = pred.shape()[0];
    let valid: Vec<Vec<(f64, f64)>> = (0..n)
        .map(|i| {
            pred.map(i)
                .iter()
                .zip(gt.map(i))
                .filter(|&(_, &g)| g > 0.0)
                .map(|(&p, &g)| (p, g))
                .collect()
        })
        .collect();
    if valid.iter().all(|v| v.is_empty()) {
        return Err(LossError::Invalid {
            what: "depth rmse",
            reason: "no ground-truth pixel is > 0".into(),
        });
    }
    let scales: Vec<f64> = match scope {
        AlignmentScope::PerFrame => valid
            .iter()
            .map(|v| {
                if v.is_empty() {
                    Ok(1.0)
                } else {
                    fit_scale(alignment, v)
                }
            })
            .collect::<Result<_>>()?,
        AlignmentScope::Shared => {
            let all: Vec<(f64, f64)> = valid.iter().flatten().copied().collect();
            vec![fit_scale(alignment, &all)?; n]
        }
    };
    let per_frame: Vec<Option<f64>> = valid
        .iter()
        .zip(&scales)
        .map(|(v, s)| {
            (!v.is_empty()).then(|| {
                let sum: f64 = v.iter().map(|(p, g)| (s * p - g).powi(2)).sum();
                (sum / v.len() as f64).sqrt()
            })
        })
        .collect();
    let done: Vec<f64> = per_frame.iter().flatten().copied().collect();
    let mean = done.iter().sum::<f64>() / done.len() as f64;
    Ok(DepthRmse {
        per_frame,
        scales,
        mean,
    })
}

/// The alignment scale over `(pred, gt)` pairs (non-empty).
fn fit_scale(alignment: DepthAlignment, pairs: &[(f64, f64)]) -> Result<f64> {
    let degenerate = |reason: String| LossError::Invalid {
        what: "depth alignment",
        reason,
    };
    match alignment {
        DepthAlignment::None => Ok(1.0),
        DepthAlignment::Median => {
            let mp = median(pairs.iter().map(|p| p.0).collect());
            let mg = median(pairs.iter().map(|p| p.1).collect());
            if mp == 0.0 {
                return Err(degenerate(
                    "median of the predicted depth is 0; cannot align".into(),
                ));
            }
            positive_scale(mg / mp)
        }
        DepthAlignment::LeastSquares => {
            let pp: f64 = pairs.iter().map(|(p, _)| p * p).sum();
            let pg: f64 = pairs.iter().map(|(p, g)| p * g).sum();
            if pp == 0.0 {
                return Err(degenerate(
                    "predicted depth is 0 on every valid pixel; cannot align".into(),
                ));
            }
            positive_scale(pg / pp)
        }
    }
}

/// A depth scale must be finite and positive: a zero or negative one (prediction anti-
/// correlated with the ground truth) would give a plausible-looking but meaningless RMSE.
fn positive_scale(s: f64) -> Result<f64> {
    if s.is_finite() && s > 0.0 {
        Ok(s)
    } else {
        Err(LossError::Invalid {
            what: "depth alignment",
            reason: format!("alignment scale {s} is not finite and positive; the prediction does not fit the ground truth"),
        })
    }
}

/// Median (mean of the two middle values for an even count) of finite values.
fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let m = v.len() / 2;
    if v.len() % 2 == 1 {
        v[m]
    } else {
        0.5 * (v[m - 1] + v[m])
    }
}
