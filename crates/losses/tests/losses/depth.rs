//! D-RMSE: alignment modes, scale invariance, valid-pixel masking.

use envision4d_losses::{depth_rmse, AlignmentScope, DepthAlignment, HostDepths, LossError};

use crate::common::Rng;

fn maps(v: Vec<f64>, shape: [usize; 3]) -> HostDepths {
    HostDepths::new("depth", v, shape).unwrap()
}

/// Ground truth with ~30% missing (0) pixels and a noisy prediction.
fn scene(seed: u64) -> (Vec<f64>, Vec<f64>) {
    let mut rng = Rng::new(seed);
    let n = 2 * 6 * 7;
    let gt: Vec<f64> = (0..n)
        .map(|_| {
            if rng.range(0.0, 1.0) < 0.3 {
                0.0
            } else {
                rng.range(2.0, 40.0)
            }
        })
        .collect();
    let pred: Vec<f64> = gt
        .iter()
        .map(|g| g * rng.range(0.8, 1.2) + rng.range(0.5, 1.0))
        .collect();
    (pred, gt)
}

/// Guards the alignment options: median and least-squares D-RMSE are invariant to the
/// prediction's scale; `None` is not.
#[test]
fn aligned_rmse_is_scale_invariant() {
    let shape = [2, 6, 7];
    let (pred, gt) = (scene(1).0, scene(1).1);
    for alignment in [DepthAlignment::Median, DepthAlignment::LeastSquares] {
        for scope in [AlignmentScope::PerFrame, AlignmentScope::Shared] {
            let base = depth_rmse(
                &maps(pred.clone(), shape),
                &maps(gt.clone(), shape),
                alignment,
                scope,
            )
            .unwrap();
            for k in [0.01, 0.37, 12.5] {
                let scaled: Vec<f64> = pred.iter().map(|p| p * k).collect();
                let r = depth_rmse(
                    &maps(scaled, shape),
                    &maps(gt.clone(), shape),
                    alignment,
                    scope,
                )
                .unwrap();
                assert!(
                    (r.mean - base.mean).abs() <= 1e-9 * base.mean,
                    "{alignment:?}/{scope:?} k={k}: {} vs {}",
                    r.mean,
                    base.mean
                );
            }
        }
    }
    let none = |k: f64| {
        let scaled: Vec<f64> = pred.iter().map(|p| p * k).collect();
        depth_rmse(
            &maps(scaled, shape),
            &maps(gt.clone(), shape),
            DepthAlignment::None,
            AlignmentScope::PerFrame,
        )
        .unwrap()
        .mean
    };
    assert!((none(1.0) - none(2.0)).abs() > 1.0);
}

/// Guards the definitions: a prediction that is an exact multiple of the ground truth has
/// zero aligned error with scale = 1/multiple, and invalid (0) pixels are ignored.
#[test]
fn exact_multiple_aligns_to_zero_error() {
    let shape = [2, 6, 7];
    let gt = scene(2).1;
    // Garbage where gt is missing must not matter.
    let pred: Vec<f64> = gt
        .iter()
        .map(|&g| if g > 0.0 { 0.25 * g } else { 1e6 })
        .collect();
    for alignment in [DepthAlignment::Median, DepthAlignment::LeastSquares] {
        let r = depth_rmse(
            &maps(pred.clone(), shape),
            &maps(gt.clone(), shape),
            alignment,
            AlignmentScope::Shared,
        )
        .unwrap();
        assert!(r.mean < 1e-12, "{alignment:?}: {}", r.mean);
        assert!(
            r.scales.iter().all(|s| (s - 4.0).abs() < 1e-12),
            "{:?}",
            r.scales
        );
    }
    // Without alignment: RMSE of 0.75·gt over valid pixels.
    let r = depth_rmse(
        &maps(pred, shape),
        &maps(gt.clone(), shape),
        DepthAlignment::None,
        AlignmentScope::PerFrame,
    )
    .unwrap();
    for (f, v) in r.per_frame.iter().enumerate() {
        let valid: Vec<f64> = gt[f * 42..(f + 1) * 42]
            .iter()
            .copied()
            .filter(|g| *g > 0.0)
            .collect();
        let want =
            (valid.iter().map(|g| (0.75 * g).powi(2)).sum::<f64>() / valid.len() as f64).sqrt();
        assert!((v.unwrap() - want).abs() < 1e-9 * want);
    }
}

/// Guards degenerate depth inputs: no valid pixel, zero prediction, NaN, shape mismatch.
#[test]
fn degenerate_depth_inputs_are_errors() {
    let shape = [1, 2, 2];
    let zeros = maps(vec![0.0; 4], shape);
    let ones = maps(vec![1.0; 4], shape);
    assert!(matches!(
        depth_rmse(
            &ones,
            &zeros,
            DepthAlignment::None,
            AlignmentScope::PerFrame
        ),
        Err(LossError::Invalid { .. })
    ));
    for a in [DepthAlignment::Median, DepthAlignment::LeastSquares] {
        assert!(depth_rmse(&zeros, &ones, a, AlignmentScope::PerFrame).is_err());
    }
    assert!(HostDepths::new("gt", vec![1.0, f64::NAN, 1.0, 1.0], shape).is_err());
    let other = maps(vec![1.0; 6], [1, 2, 3]);
    assert!(matches!(
        depth_rmse(
            &ones,
            &other,
            DepthAlignment::None,
            AlignmentScope::PerFrame
        ),
        Err(LossError::ShapeMismatch { .. })
    ));
    // A frame without valid pixels is reported as None, the others still count.
    let two_gt = maps(vec![0.0, 0.0, 0.0, 0.0, 2.0, 2.0, 2.0, 2.0], [2, 2, 2]);
    let two_pred = maps(vec![1.0; 8], [2, 2, 2]);
    let r = depth_rmse(
        &two_pred,
        &two_gt,
        DepthAlignment::None,
        AlignmentScope::PerFrame,
    )
    .unwrap();
    assert_eq!(r.per_frame, vec![None, Some(1.0)]);
    assert_eq!(r.mean, 1.0);
}
