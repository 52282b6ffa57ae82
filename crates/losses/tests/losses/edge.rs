//! Extreme and invalid inputs: constants, black vs white, NaN, mismatched shapes.

use burn::tensor::{DType, Device};
use envision4d_losses::{
    camera_distill, mse_per_frame, psnr, ssim, EvalCrop, HostDepths, HostImages, LossError,
};

use crate::common::tensor;

fn constant(v: f64, shape: [usize; 4]) -> HostImages {
    HostImages::new("const", vec![v; shape.iter().product()], shape).unwrap()
}

/// Guards SSIM on zero-variance images: equal constants give 1, black vs white gives
/// C1 / (1 + C1) (the stabilisers keep it finite).
#[test]
fn constant_images() {
    let shape = [1, 3, 16, 16];
    let s = ssim(&constant(0.3, shape), &constant(0.3, shape)).unwrap();
    assert!((s[0] - 1.0).abs() < 1e-12, "{s:?}");
    let c1: f64 = 1e-4;
    let s = ssim(&constant(0.0, shape), &constant(1.0, shape)).unwrap();
    assert!((s[0] - c1 / (1.0 + c1)).abs() < 1e-12, "{s:?}");
    let (a, b) = (constant(0.2, shape), constant(0.7, shape));
    let want = (2.0 * 0.2 * 0.7 + c1) / (0.04 + 0.49 + c1);
    assert!((ssim(&a, &b).unwrap()[0] - want).abs() < 1e-12);
}

/// Guards PSNR's extremes: black vs white is 0 dB, identical images are +inf, and values
/// beyond [0, 1] are clipped first (1.5 vs 1.0 is identical after clipping).
#[test]
fn psnr_extremes() {
    let shape = [1, 3, 4, 4];
    assert_eq!(
        psnr(&constant(0.0, shape), &constant(1.0, shape)).unwrap(),
        [0.0]
    );
    assert_eq!(
        psnr(&constant(0.4, shape), &constant(0.4, shape)).unwrap(),
        [f64::INFINITY]
    );
    assert_eq!(
        psnr(&constant(1.5, shape), &constant(1.0, shape)).unwrap(),
        [f64::INFINITY]
    );
    let p = psnr(&constant(-1.0, shape), &constant(0.1, shape)).unwrap();
    assert!((p[0] - 20.0).abs() < 1e-9, "{p:?}");
}

/// Guards NaN handling: a NaN in any input is an error naming the input, never a NaN metric.
#[test]
fn nan_inputs_are_errors() {
    let mut v = vec![0.5; 48];
    v[17] = f64::NAN;
    let err = HostImages::new("predicted", v.clone(), [1, 3, 4, 4]).unwrap_err();
    assert!(
        matches!(
            err,
            LossError::NonFinite {
                what: "predicted",
                index: 17,
                ..
            }
        ),
        "{err}"
    );
    let t = tensor(&v, [1, 3, 4, 4], &Device::flex(), DType::F32);
    assert!(HostImages::from_tensor("render", t).is_err());
    let mut d = vec![1.0; 16];
    d[3] = f64::INFINITY;
    assert!(HostDepths::new("depth", d, [1, 4, 4]).is_err());
}

/// Guards shape validation: mismatched or too-small inputs are errors, not panics.
#[test]
fn bad_shapes_are_errors() {
    let a = constant(0.5, [1, 3, 16, 16]);
    let b = constant(0.5, [1, 3, 16, 12]);
    assert!(matches!(psnr(&a, &b), Err(LossError::ShapeMismatch { .. })));
    assert!(matches!(ssim(&a, &b), Err(LossError::ShapeMismatch { .. })));
    let tiny = constant(0.5, [1, 3, 10, 16]);
    let err = ssim(&tiny, &tiny).unwrap_err().to_string();
    assert!(err.contains("10x16") && err.contains("11x11"), "{err}");
    assert!(HostImages::new("x", vec![0.0; 5], [1, 1, 2, 2]).is_err());
    let crop = EvalCrop {
        top: 8,
        bottom: 8,
        left: 0,
        right: 0,
    };
    assert!(crop.apply_images(&a).is_err());

    let device = Device::flex();
    let p = tensor(&[0.0; 48], [1, 3, 4, 4], &device, DType::F32);
    let q = tensor(&[0.0; 36], [1, 3, 4, 3], &device, DType::F32);
    assert!(matches!(
        mse_per_frame(p.clone(), q),
        Err(LossError::ShapeMismatch { .. })
    ));
    let q64 = tensor(&[0.0; 48], [1, 3, 4, 4], &device, DType::F64);
    assert!(matches!(
        mse_per_frame(p, q64),
        Err(LossError::DtypeMismatch { .. })
    ));
    let pose = tensor(&[0.0; 8], [1, 8], &device, DType::F32);
    assert!(matches!(
        camera_distill(pose.clone(), pose),
        Err(LossError::BadShape { .. })
    ));
}
