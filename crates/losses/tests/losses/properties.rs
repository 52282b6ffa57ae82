//! Metric properties: SSIM(x, x) = 1, symmetry, crops applied consistently.

use burn::tensor::{DType, Device};
use envision4d_losses::{evaluate_images, psnr, ssim, EvalCrop, HostImages, Lpips, LpipsStatus};

use crate::common::{fixture_images, fixture_vgg_weights, tensor, Rng};

fn images(seed: u64, shape: [usize; 4]) -> HostImages {
    let mut rng = Rng::new(seed);
    HostImages::new("test", rng.vec(shape.iter().product(), 0.0, 1.0), shape).unwrap()
}

/// Guards SSIM(x, x) = 1 and the symmetry of SSIM and PSNR.
#[test]
fn ssim_identity_and_symmetry() {
    let (x, y) = (images(1, [2, 3, 20, 24]), images(2, [2, 3, 20, 24]));
    for s in ssim(&x, &x).unwrap() {
        assert!((s - 1.0).abs() < 1e-12, "SSIM(x,x) = {s}");
    }
    let (a, b) = (ssim(&x, &y).unwrap(), ssim(&y, &x).unwrap());
    for (p, q) in a.iter().zip(&b) {
        assert!((p - q).abs() < 1e-12 && *p < 0.5, "{p} vs {q}");
    }
    let (a, b) = (psnr(&x, &y).unwrap(), psnr(&y, &x).unwrap());
    assert_eq!(a, b);
}

/// Guards the evaluation crop: every metric sees the same cropped pixels (equal to cropping
/// by hand), and the tensor crop keeps the right window.
#[test]
fn crop_is_applied_consistently() {
    let (gt, pred) = (
        fixture_images("input/ground_truth"),
        fixture_images("input/predicted"),
    );
    let crop = EvalCrop::RELEASE_MAIN;
    let lpips = LpipsStatus::Available(Lpips::new(
        &fixture_vgg_weights(),
        &Device::flex(),
        DType::F32,
    ));
    let m = evaluate_images(&pred, &gt, crop, &lpips).unwrap();
    let (cp, cg) = (
        crop.apply_images(&pred).unwrap(),
        crop.apply_images(&gt).unwrap(),
    );
    assert_eq!(cp.shape(), [3, 3, 64 - 12, 96 - 16]);
    assert_eq!(m.psnr, psnr(&cp, &cg).unwrap());
    assert_eq!(m.ssim, ssim(&cp, &cg).unwrap());
    let direct = lpips.get().unwrap().distance_host(&cg, &cp).unwrap();
    assert_eq!(m.lpips.unwrap(), direct);
    let uncropped = evaluate_images(&pred, &gt, EvalCrop::default(), &lpips).unwrap();
    assert_ne!(uncropped.psnr, m.psnr);

    let t = tensor(pred.data(), pred.shape(), &Device::flex(), DType::F64);
    let ct = crop.apply_tensor(t).unwrap();
    assert_eq!(ct.dims(), [3, 3, 52, 80]);
    assert_eq!(crate::common::values(ct), cp.data().to_vec());
    assert_eq!(
        EvalCrop::from_ranges([6, 6], [10, 6]),
        EvalCrop::RELEASE_MAIN
    );
}

/// Guards the scaled release crop: unchanged at the release's 350x518, the same border
/// fractions (rounded) at other sizes, so a small image keeps most of its pixels.
#[test]
fn release_crop_scales_with_the_image() {
    let c = EvalCrop::RELEASE_MAIN;
    assert_eq!(c.scaled_to([350, 518]), c);
    assert_eq!(
        c.scaled_to([56, 84]),
        EvalCrop {
            top: 1,
            bottom: 1,
            left: 2,
            right: 1
        }
    );
    assert_eq!(
        c.scaled_to([700, 1036]),
        EvalCrop {
            top: 12,
            bottom: 12,
            left: 20,
            right: 12
        }
    );
}

/// Guards metrics without LPIPS weights: no LPIPS number is produced.
#[test]
fn evaluation_without_lpips_reports_none() {
    let (x, y) = (images(1, [1, 3, 16, 16]), images(2, [1, 3, 16, 16]));
    let status = LpipsStatus::Unavailable {
        reason: "test".into(),
    };
    let m = evaluate_images(&x, &y, EvalCrop::default(), &status).unwrap();
    assert!(m.lpips.is_none());
    assert_eq!(m.psnr.len(), 1);
}

/// Guards the camera loss's rotation weight: at 1 it is exactly the paper's L1, and at w a
/// difference in the quaternion entries alone costs w times as much while one in the
/// translation alone costs the same; a negative or NaN weight is refused.
#[test]
fn rotation_weight_scales_only_the_quaternion_entries() {
    use envision4d_losses::{camera_distill, camera_distill_weighted};
    let device = Device::flex();
    let value = |t: burn::tensor::Tensor<1>| t.into_data().iter::<f32>().next().unwrap();
    let base: Vec<f64> = (0..18).map(|i| i as f64 * 0.1).collect();
    let pose = |v: &[f64]| tensor::<3>(v, [1, 2, 9], &device, DType::F32);
    let mut rot = base.clone();
    rot[4] += 0.2; // quaternion y of frame 0
    let mut trans = base.clone();
    trans[11] += 0.2; // translation z of frame 1
    let plain = value(camera_distill(pose(&rot), pose(&base)).unwrap());
    assert_eq!(
        plain,
        value(camera_distill_weighted(pose(&rot), pose(&base), 1.0).unwrap())
    );
    let w = value(camera_distill_weighted(pose(&rot), pose(&base), 20.0).unwrap());
    assert!((w - 20.0 * plain).abs() < 1e-6, "{w} vs 20 x {plain}");
    let t1 = value(camera_distill(pose(&trans), pose(&base)).unwrap());
    let t20 = value(camera_distill_weighted(pose(&trans), pose(&base), 20.0).unwrap());
    assert!((t1 - t20).abs() < 1e-7, "{t1} vs {t20}");
    for bad in [-1.0, f64::NAN] {
        let err = camera_distill_weighted(pose(&rot), pose(&base), bad).unwrap_err();
        assert!(err.to_string().contains("rotation weight"), "{err}");
    }
}

/// Guards the region metrics against hand-computed values: PSNR over a mask uses only its
/// pixels (an error confined outside it gives +inf inside, the exact dB outside), and SSIM
/// over the whole image equals the mean of the per-pixel map inside the border.
#[test]
fn region_metrics_by_hand() {
    use envision4d_losses::{masked_psnr, masked_ssim};
    let (h, w) = (12, 12);
    let gt = HostImages::new("gt", vec![0.5; 3 * h * w], [1, 3, h, w]).unwrap();
    let mut p = vec![0.5; 3 * h * w];
    // Pixel (0, 0) of every channel off by 0.1: outside the mask below.
    for ch in 0..3 {
        p[ch * h * w] = 0.6;
    }
    let pred = HostImages::new("pred", p, [1, 3, h, w]).unwrap();
    let inside: Vec<bool> = (0..h * w).map(|i| i >= w).collect();
    let outside: Vec<bool> = inside.iter().map(|b| !b).collect();
    let psnr_in = masked_psnr(&pred, &gt, std::slice::from_ref(&inside)).unwrap()[0].unwrap();
    assert!(psnr_in.is_infinite());
    // Outside: 12 pixels x 3 channels, one of each channel off by 0.1: mse = 0.01 / 12.
    let psnr_out = masked_psnr(&pred, &gt, std::slice::from_ref(&outside)).unwrap()[0].unwrap();
    assert!(
        (psnr_out - (-10.0 * (0.01f64 / 12.0).log10())).abs() < 1e-9,
        "{psnr_out}"
    );
    assert_eq!(
        masked_psnr(&pred, &gt, &[vec![false; h * w]]).unwrap(),
        vec![None]
    );
    let all = vec![true; h * w];
    let whole = masked_ssim(&pred, &gt, std::slice::from_ref(&all)).unwrap()[0].unwrap();
    assert!((whole - ssim(&pred, &gt).unwrap()[0]).abs() < 1e-12);
    // Row 0 lies wholly in SSIM's 5-pixel border: no score.
    assert_eq!(masked_ssim(&pred, &gt, &[outside]).unwrap(), vec![None]);
}
