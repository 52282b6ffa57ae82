//! The differentiable SSIM term: same value as the evaluation metric, exact gradients, and
//! no NaN on the stiff inputs a render produces (flat, black, saturated, tiny variance).

use burn::tensor::{DType, Device, Tensor};
use envision4d_losses::{
    ssim, ssim_per_frame, HostImages, LossError, LpipsStatus, RgbLoss, SSIM_WIN_SIZE,
};

use crate::common::{fixture, fixture_images, read, tensor, values, Rng};

fn on_device(h: &HostImages, device: &Device) -> Tensor<4> {
    tensor(h.data(), h.shape(), device, DType::F64)
}

/// Guards the training SSIM against drifting from the metric `eval` reports (window,
/// reflect borders, covariance correction, crop), on the skimage fixture.
#[test]
fn ssim_loss_equals_the_metric_on_the_fixture() {
    let (gt, pred) = (
        fixture_images("input/ground_truth"),
        fixture_images("input/predicted"),
    );
    let d = Device::flex();
    let got = values(ssim_per_frame(on_device(&pred, &d), on_device(&gt, &d)).unwrap());
    let host = ssim(&pred, &gt).unwrap();
    let (want, _) = read(&fixture(), "expected_f64/ssim");
    for i in 0..got.len() {
        assert!(
            (got[i] - host[i]).abs() < 1e-12,
            "{i}: {} vs host {}",
            got[i],
            host[i]
        );
        assert!(
            (got[i] - want[i]).abs() < 1e-9,
            "{i}: {} vs skimage {}",
            got[i],
            want[i]
        );
    }
}

/// Guards the reflect indices on an odd, barely-large-enough, non-square image where an
/// off-by-one border shows (the host metric is the reference).
#[test]
fn ssim_loss_equals_the_metric_on_a_minimal_odd_image() {
    let mut rng = Rng::new(5);
    let shape = [2, 3, SSIM_WIN_SIZE, SSIM_WIN_SIZE + 6];
    let n = shape.iter().product();
    let a = HostImages::new("a", rng.vec(n, 0.0, 1.0), shape).unwrap();
    let b = HostImages::new("b", rng.vec(n, 0.0, 1.0), shape).unwrap();
    let d = Device::flex();
    let got = values(ssim_per_frame(on_device(&a, &d), on_device(&b, &d)).unwrap());
    let want = ssim(&a, &b).unwrap();
    for i in 0..2 {
        assert!(
            (got[i] - want[i]).abs() < 1e-12,
            "{i}: {} vs {}",
            got[i],
            want[i]
        );
    }
}

/// Guards the detached target: the SSIM term must pull the render toward the frame, never
/// the frame toward the render (the gradient itself is checked in `gradients.rs`).
#[test]
fn ssim_loss_target_gets_no_gradient() {
    let mut rng = Rng::new(9);
    let shape = [1, 3, 12, 13];
    let n: usize = shape.iter().product();
    let ad = Device::flex().autodiff();
    let p = tensor(&rng.vec(n, 0.0, 1.0), shape, &ad, DType::F64).require_grad();
    let t = tensor(&rng.vec(n, 0.0, 1.0), shape, &ad, DType::F64).require_grad();
    let grads = ssim_per_frame(p.clone(), t.clone())
        .unwrap()
        .sum()
        .backward();
    assert!(p.grad(&grads).is_some());
    assert!(t.grad(&grads).is_none(), "the target must be detached");
}

/// Guards the stabilising constants on the renders that have no variance at all (sky,
/// black, saturated): values stay finite in f32, equal images score 1, and the gradient at
/// a flat image is finite.
#[test]
fn ssim_loss_is_finite_on_flat_black_and_saturated_images() {
    let shape = [3, 3, 16, 16];
    let n: usize = shape.iter().product();
    let ad = Device::flex().autodiff();
    let flat = |v: f64| vec![v; n / 3];
    let pred: Vec<f64> = [flat(0.0), flat(1.0), flat(0.5)].concat();
    let target: Vec<f64> = [flat(0.0), flat(0.0), flat(0.5 + 1e-7)].concat();
    let p = tensor(&pred, shape, &ad, DType::F32).require_grad();
    let t = tensor(&target, shape, &ad, DType::F32);
    let s = ssim_per_frame(p.clone(), t).unwrap();
    let sv = values(s.clone());
    assert!((sv[0] - 1.0).abs() < 1e-6, "black vs black: {}", sv[0]);
    assert!(sv[1] < 1e-3, "white vs black must score ~0: {}", sv[1]);
    assert!((sv[2] - 1.0).abs() < 1e-5, "flat vs flat: {}", sv[2]);
    let g = values(p.grad(&s.sum().backward()).unwrap());
    assert!(
        g.iter().all(|v| v.is_finite()),
        "non-finite gradient on flat images"
    );
}

/// Guards the error path: too-small or mismatched images are errors naming the loss, not a
/// panic inside a slice.
#[test]
fn ssim_loss_rejects_small_and_mismatched_images() {
    let d = Device::flex();
    let small = Tensor::<4>::zeros([1, 3, 10, 40], &d);
    let err = ssim_per_frame(small.clone(), small)
        .unwrap_err()
        .to_string();
    assert!(err.contains("ssim loss") && err.contains("10x40"), "{err}");
    let a = Tensor::<4>::zeros([1, 3, 16, 16], &d);
    let b = Tensor::<4>::zeros([1, 3, 16, 17], &d);
    assert!(matches!(
        ssim_per_frame(a, b),
        Err(LossError::ShapeMismatch { .. })
    ));
}

/// Guards the optional term of `L_rgb`: off (the paper's loss) it changes nothing; on, the
/// total is `mse + λ·(1 − SSIM)`; a negative or NaN λ is refused with its name.
#[test]
fn rgb_loss_adds_the_structural_term_only_when_asked() {
    let mut rng = Rng::new(3);
    let shape = [2, 3, 14, 15];
    let n: usize = shape.iter().product();
    let d = Device::flex();
    let p = tensor(&rng.vec(n, 0.0, 1.0), shape, &d, DType::F64);
    let t = tensor(&rng.vec(n, 0.0, 1.0), shape, &d, DType::F64);
    let off = RgbLoss::new(
        0.0,
        &LpipsStatus::Unavailable {
            reason: "test".into(),
        },
    )
    .unwrap();
    let terms = off.per_frame(p.clone(), t.clone()).unwrap();
    assert!(terms.dssim.is_none());
    assert_eq!(values(terms.total), values(terms.mse));
    let on = off.clone().with_ssim(0.3).unwrap();
    let terms = on.per_frame(p.clone(), t.clone()).unwrap();
    let (mse, dssim, total) = (
        values(terms.mse),
        values(terms.dssim.expect("dssim term")),
        values(terms.total),
    );
    let s = values(ssim_per_frame(p, t).unwrap());
    for i in 0..2 {
        assert!((dssim[i] - (1.0 - s[i])).abs() < 1e-12);
        assert!((total[i] - (mse[i] + 0.3 * dssim[i])).abs() < 1e-12);
    }
    for bad in [-0.1, f64::NAN, f64::INFINITY] {
        let err = off.clone().with_ssim(bad).unwrap_err().to_string();
        assert!(err.contains("lambda_ssim"), "{err}");
    }
}

/// Guards training with `--backend wgpu` and the structural term: the reflect gather and
/// the depthwise convolutions give the CPU's values and gradients on the WGSL path.
#[test]
fn ssim_loss_on_wgpu_matches_the_cpu() {
    let Some(gpu) = envision4d_splat::testkit::wgpu_test_device() else {
        return;
    };
    let mut rng = Rng::new(21);
    let shape = [2, 3, 20, 27];
    let n: usize = shape.iter().product();
    let (x, y) = (rng.vec(n, 0.0, 1.0), rng.vec(n, 0.0, 1.0));
    let run = |device: Device| {
        let p = tensor(&x, shape, &device, DType::F32).require_grad();
        let t = tensor(&y, shape, &device, DType::F32);
        let s = ssim_per_frame(p.clone(), t).unwrap();
        let grads = (s.clone() * tensor(&[0.7, 1.3], [2], &device, DType::F32))
            .sum()
            .backward();
        (values(s), values(p.grad(&grads).unwrap()))
    };
    let (s_cpu, g_cpu) = run(Device::flex().autodiff());
    let (s_gpu, g_gpu) = run(gpu.autodiff());
    for (a, b) in s_cpu.iter().zip(&s_gpu) {
        assert!((a - b).abs() < 1e-5, "ssim cpu {a} vs wgpu {b}");
    }
    let scale = g_cpu.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    for (i, (a, b)) in g_cpu.iter().zip(&g_gpu).enumerate() {
        assert!(
            (a - b).abs() <= 1e-4 * scale,
            "grad[{i}] cpu {a} vs wgpu {b}"
        );
    }
}
