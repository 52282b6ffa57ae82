//! Reduced-precision inference (`Envision4d::with_precision`) against the official f32
//! reference outputs of the tiny fixture, on the CPU backend (the GPU backends run the same
//! Burn ops). Prints the worst relative error per output; `docs/MODEL.md` ("Precision")
//! quotes these lines.

#[path = "parity/fixture.rs"]
#[allow(dead_code)]
mod fixture;
#[path = "../../../tests/support/paths.rs"]
mod paths;

use burn::nn::LayerNormConfig;
use burn::tensor::{DType, Device, Distribution, Tensor};
use envision4d_model::model::Heads;
use envision4d_model::precision::Precision;
use fixture::Fixture;

/// `max |got − want| / max |want|` over one output (NaN if any value is not finite).
fn rel_error<const D: usize>(fx: &Fixture, key: &str, got: Tensor<D>) -> f64 {
    assert_eq!(
        got.dtype(),
        DType::F32,
        "{key}: the heads' outputs stay f32"
    );
    let got: Vec<f64> = got.into_data().iter::<f64>().collect();
    let want = fx.f32s(&format!("expected/{key}"));
    assert_eq!(got.len(), want.len(), "{key}: length");
    let scale = want.iter().fold(0.0f64, |m, v| m.max(v.abs() as f64));
    got.iter().zip(&want).fold(0.0, |m, (g, w)| {
        let d = (g - *w as f64).abs() / scale;
        if d.is_nan() || m.is_nan() {
            f64::NAN
        } else {
            m.max(d)
        }
    })
}

/// The worst relative error of each output of the tiny forward in `precision`.
fn errors(precision: Precision) -> Vec<(&'static str, f64)> {
    let fx = Fixture::open("envision4d_tiny.safetensors");
    let device = Device::flex();
    let model = fx.tiny_model(&device).with_precision(precision);
    assert_eq!(model.precision(), precision);
    let out = model.forward(fx.tensor::<5>("input/images", &device), Heads::ALL);
    let errs = vec![
        (
            "pose_enc",
            rel_error(&fx, "pose_enc", out.backbone.pose_enc()),
        ),
        ("depth", rel_error(&fx, "depth", out.depth.unwrap())),
        (
            "depth_conf",
            rel_error(&fx, "depth_conf", out.depth_conf.unwrap()),
        ),
        (
            "gaussians",
            rel_error(&fx, "gaussians", out.gaussians.unwrap()),
        ),
        (
            "motion_enc",
            rel_error(&fx, "motion_enc", out.motion_enc.unwrap()),
        ),
    ];
    for (k, e) in &errs {
        eprintln!(
            "precision {}: {k} max|diff|/max|ref| = {e:.2e}",
            precision.name()
        );
    }
    errs
}

/// Holds every output of the tiny forward in `precision` under `bound`, and above f32's
/// error (below 1e-4 in the parity tests), which a cast that never happened would give.
fn assert_half_errors(precision: Precision, bound: f64) {
    let name = precision.name();
    for (k, e) in errors(precision) {
        assert!(e < bound, "{name} {k}: error {e:e} above {bound:e}");
        assert!(
            e > 1e-4,
            "{name} {k}: error {e:e} is f32's: nothing ran in {name}"
        );
    }
}

/// Guards the f16 aggregator: a dtype mismatch inside it (a table or weight left in f32)
/// panics on the CPU backend, an overflow gives NaN, and a cast that never happened gives
/// f32's error instead of half precision's.
#[test]
fn f16_aggregator_stays_near_the_reference() {
    assert_half_errors(Precision::F16, 1e-2);
}

/// Guards the bf16 aggregator the same way (bf16 keeps 8 significant bits, f16 11: its
/// error is larger, its range f32's).
#[test]
fn bf16_aggregator_stays_near_the_reference() {
    assert_half_errors(Precision::Bf16, 6e-2);
}

/// Guards the LayerNorm statistics of half tokens: DINO's residual stream reaches hundreds,
/// whose squares overflow f16 (max 65 504) unless the variance is taken in f32.
#[test]
fn layer_norm_of_large_f16_tokens_is_finite() {
    let device = Device::flex();
    let norm = LayerNormConfig::new(64).init(&device);
    let x = Tensor::<3>::random([2, 8, 64], Distribution::Uniform(-2000.0, 2000.0), &device);
    let want = norm.forward(x.clone());
    let got = norm.forward(x.cast(DType::F16)).cast(DType::F32);
    let worst = (got - want).abs().max().into_scalar::<f32>();
    assert!(
        worst.is_finite() && worst < 1e-2,
        "f16 LayerNorm off by {worst}"
    );
}

/// Guards the device check of `--precision`: f32 runs anywhere, the check agrees with the
/// device's own dtype support, and a refusal names the format (the CLI test checks the
/// refusal of bf16 on wgpu end to end).
#[test]
fn the_check_names_what_a_device_lacks() {
    let device = Device::flex();
    assert!(Precision::F32.check(&device).is_ok());
    for p in [Precision::F16, Precision::Bf16] {
        match p.check(&device) {
            Ok(()) => assert!(device.supports_dtype(p.dtype())),
            Err(e) => assert!(e.contains(p.name()), "{e}"),
        }
    }
}
