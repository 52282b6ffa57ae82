//! Parity with `shared/fixtures/metrics.safetensors` (the release's `compute_psnr`,
//! `compute_ssim`, `compute_lpips`), within the fixture README's tolerances
//! (PSNR 1e-4 dB, SSIM 1e-5, LPIPS 1e-5 relative).

use burn::tensor::{DType, Device};
use envision4d_losses::lpips::{read_lin_layers, SCALING_SCALE, SCALING_SHIFT};
use envision4d_losses::{psnr, ssim, Lpips, LpipsNet};

use crate::common::{fixture, fixture_images, fixture_vgg_weights, max_diffs, read};

const PSNR_TOL_DB: f64 = 1e-4;
const SSIM_TOL: f64 = 1e-5;
const LPIPS_REL_TOL: f64 = 1e-5;

/// Guards PSNR's clipping and mean-over-(C,H,W) against the release (pair 0 has values
/// outside [0, 1], so a missing clip would fail).
#[test]
fn psnr_matches_release() {
    let (gt, pred) = (
        fixture_images("input/ground_truth"),
        fixture_images("input/predicted"),
    );
    let got = psnr(&pred, &gt).unwrap();
    for key in ["expected/psnr", "expected_f64/psnr"] {
        let (want, _) = read(&fixture(), key);
        let (abs, rel) = max_diffs(&got, &want);
        eprintln!("psnr vs {key}: max abs {abs:.3e} dB, max rel {rel:.3e}");
        assert!(abs <= PSNR_TOL_DB, "{key}: {got:?} vs {want:?}");
    }
}

/// Guards SSIM's Gaussian window, reflect padding, sample-covariance correction and
/// 5-pixel border crop against scikit-image.
#[test]
fn ssim_matches_skimage() {
    let (gt, pred) = (
        fixture_images("input/ground_truth"),
        fixture_images("input/predicted"),
    );
    let got = ssim(&pred, &gt).unwrap();
    for key in ["expected/ssim", "expected_f64/ssim"] {
        let (want, _) = read(&fixture(), key);
        let (abs, rel) = max_diffs(&got, &want);
        eprintln!("ssim vs {key}: max abs {abs:.3e}, max rel {rel:.3e}");
        assert!(abs <= SSIM_TOL, "{key}: {got:?} vs {want:?}");
    }
}

/// Guards the whole LPIPS VGG pipeline (scaling, backbone, unit-normalisation, lin layers,
/// spatial mean, layer sum) in f32 and f64 against the `lpips` package, per layer too.
#[test]
fn lpips_vgg_matches_package() {
    let weights = fixture_vgg_weights();
    let (gt, pred) = (
        fixture_images("input/ground_truth"),
        fixture_images("input/predicted"),
    );
    let (want, _) = read(&fixture(), "expected/lpips");
    let (want64, _) = read(&fixture(), "expected_f64/lpips");
    let (want_layers, _) = read(&fixture(), "expected/lpips_per_layer");
    for (dtype, reference, name) in [
        (DType::F32, &want, "expected/lpips"),
        (DType::F64, &want64, "expected_f64/lpips"),
    ] {
        let net = Lpips::new(&weights, &Device::flex(), dtype);
        let got = net.distance_host(&gt, &pred).unwrap();
        let (abs, rel) = max_diffs(&got, reference);
        eprintln!("lpips {dtype:?} vs {name}: max abs {abs:.3e}, max rel {rel:.3e}");
        assert!(rel <= LPIPS_REL_TOL, "{name}: {got:?} vs {reference:?}");
    }
    let net = Lpips::new(&weights, &Device::flex(), DType::F32);
    let to_t = |im: &envision4d_losses::HostImages| {
        crate::common::tensor(im.data(), im.shape(), &Device::flex(), DType::F32)
    };
    let layers = crate::common::values(net.forward_layers(to_t(&gt), to_t(&pred)).unwrap());
    let (abs, rel) = max_diffs(&layers, &want_layers);
    eprintln!("lpips per layer f32: max abs {abs:.3e}, max rel {rel:.3e}");
    assert!(rel <= 10.0 * LPIPS_REL_TOL, "{layers:?} vs {want_layers:?}");
}

/// Guards the weight layout: the fixture's VGG lin layers are the shipped ones, all lin
/// weights are non-negative, and the scaling buffers are the package constants.
#[test]
fn fixture_lin_layers_and_scaling_constants() {
    let path = fixture();
    let weights = fixture_vgg_weights();
    let shipped_vgg = read_lin_layers(&path, "lpips_lin_shipped/vgg/").unwrap();
    assert_eq!(weights.lins, shipped_vgg);
    let shipped_alex = read_lin_layers(&path, "lpips_lin_shipped/alex/").unwrap();
    for (lins, net) in [
        (&shipped_vgg, LpipsNet::Vgg),
        (&shipped_alex, LpipsNet::Alex),
    ] {
        for (l, ch) in lins.iter().zip(net.channels()) {
            assert_eq!(l.shape, vec![1, ch, 1, 1], "{net:?}");
            assert!(
                l.data.iter().all(|&v| v >= 0.0),
                "{net:?} lin has a negative weight"
            );
        }
    }
    let (shift, _) = read(&path, "lpips_vgg/weights/scaling_layer.shift");
    let (scale, _) = read(&path, "lpips_vgg/weights/scaling_layer.scale");
    for k in 0..3 {
        assert!((shift[k] - SCALING_SHIFT[k] as f64).abs() < 1e-7);
        assert!((scale[k] - SCALING_SCALE[k] as f64).abs() < 1e-7);
    }
}
