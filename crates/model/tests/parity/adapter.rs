//! Parity of the Gaussian adapter: the unit case and the tiny model's adapted Gaussians.

use crate::fixture::{assert_close, flat, Fixture, UNIT_ABS, UNIT_REL};
use burn::tensor::Device;
use envision4d_model::adapter::{adapt, OpacityMapping, ScaleRange};
use envision4d_model::model::Heads;

/// Guards the adapter's conventions: depth as unit-ray distance, pixel-footprint scales, the
/// rotation order mix-up with w >= 0 output, sigmoid colours, motion reshape.
#[test]
fn adapter_unit_case_matches_reference() {
    let fx = Fixture::open("blocks_tiny.safetensors");
    let device = Device::flex();
    let i = |k: &str| format!("adapter/input/{k}");
    let out = adapt(
        fx.tensor::<4>(&i("extrinsics"), &device),
        fx.tensor::<4>(&i("intrinsics_normalized"), &device),
        fx.tensor::<4>(&i("depths"), &device),
        fx.tensor::<4>(&i("opacities"), &device),
        fx.tensor::<5>(&i("raw_gaussians"), &device),
        fx.tensor::<5>(&i("motions"), &device),
        ScaleRange {
            min: 0.5,
            max: 15.0,
        },
    );
    let o = |k: &str| fx.f32s(&format!("adapter/output/{k}"));
    assert_close("means", flat(out.means), &o("means"), UNIT_REL, UNIT_ABS);
    assert_close("scales", flat(out.scales), &o("scales"), UNIT_REL, UNIT_ABS);
    assert_close(
        "rotations",
        flat(out.rotations),
        &o("rotations"),
        UNIT_REL,
        UNIT_ABS,
    );
    assert_close("colors", flat(out.colors), &o("colors"), UNIT_REL, UNIT_ABS);
    assert_close(
        "opacities",
        flat(out.opacities),
        &o("opacities"),
        UNIT_REL,
        UNIT_ABS,
    );
    assert_close(
        "motions",
        flat(out.motions),
        &o("motions"),
        UNIT_REL,
        UNIT_ABS,
    );
}

/// Guards the model → adapter wiring (first T_c cameras, intrinsics normalised by W and H,
/// opacity mapping, raw channel split) on the tiny model.
#[test]
fn tiny_adapter_matches_reference() {
    let fx = Fixture::open("envision4d_tiny.safetensors");
    let device = Device::flex();
    let model = fx.tiny_model(&device);
    let p = model.forward(fx.tensor::<5>("input/images", &device), Heads::ALL);
    let a = model
        .adapt(&p, OpacityMapping::default(), 0)
        .expect("all heads ran");
    let e = |k: &str| fx.f32s(&format!("expected/adapter/{k}"));
    let (rel, abs) = (1e-4, 1e-5);
    assert_close("means", flat(a.means), &e("means"), rel, abs);
    assert_close("scales", flat(a.scales), &e("scales"), rel, abs);
    assert_close("rotations", flat(a.rotations), &e("rotations"), rel, abs);
    assert_close("colors", flat(a.colors), &e("colors"), rel, abs);
    assert_close("opacities", flat(a.opacities), &e("opacities"), rel, abs);
    assert_close("motions", flat(a.motions), &e("motions"), rel, abs);
}
