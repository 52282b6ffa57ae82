//! Parity of the backbone path: sinusoid, pose decoding, camera head, DINO (with pos-embed
//! interpolation), and the tiny model's aggregator, future-pose module and poses.

use crate::fixture::{assert_close, flat, Fixture, UNIT_ABS, UNIT_REL};
use burn::tensor::{Device, Tensor};
use envision4d_model::camera_head::CameraHead;
use envision4d_model::config::{DinoConfig, ModelConfig};
use envision4d_model::dino::Dino;
use envision4d_model::future::sinusoid;
use envision4d_model::pose::pose_encoding_to_extri_intri;

/// Aggregator-intermediate tolerance of the fixtures README (`5e-5 * max|ref|`).
const AGG_REL: f32 = 5e-5;
/// Final-output tolerance of the README (`1e-4 * max|ref| + 1e-5`).
const OUT_REL: f32 = 1e-4;
const OUT_ABS: f32 = 1e-5;

/// Guards the time sinusoid (cos first, base 10000, 0-based positions, f64 then f32).
#[test]
fn sinusoid_matches_reference() {
    let fx = Fixture::open("blocks_tiny.safetensors");
    let pos: Vec<f64> = fx
        .f32s("sinusoid/positions")
        .iter()
        .map(|p| *p as f64)
        .collect();
    let got = sinusoid(&pos, 256);
    let t = Tensor::<1>::from_floats(got.as_slice(), &Device::flex());
    assert_close(
        "sinusoid",
        t,
        &fx.f32s("sinusoid/output_f32"),
        UNIT_REL,
        UNIT_ABS,
    );
}

/// Guards pose decoding: scalar-last unnormalised quaternion, fov_h before fov_w, fy from H.
#[test]
fn pose_encoding_matches_reference() {
    let fx = Fixture::open("blocks_tiny.safetensors");
    let device = Device::flex();
    for (h, w) in [(56usize, 84usize), (350, 518)] {
        let (extr, intr) =
            pose_encoding_to_extri_intri(fx.tensor::<3>("pose_enc/input", &device), h, w);
        let [b, n, _, _] = extr.dims();
        let extr34 = extr.slice([0..b, 0..n, 0..3, 0..4]);
        assert_close(
            &format!("extrinsics {h}x{w}"),
            flat(extr34),
            &fx.f32s(&format!("pose_enc/H{h}_W{w}/extrinsics")),
            UNIT_REL,
            UNIT_ABS,
        );
        assert_close(
            &format!("intrinsics {h}x{w}"),
            flat(intr),
            &fx.f32s(&format!("pose_enc/H{h}_W{w}/intrinsics")),
            UNIT_REL,
            UNIT_ABS,
        );
    }
}

/// Guards the camera head (AdaLN modulation order shift|scale|gate, affine-free adaln norm,
/// accumulation of pre-activation deltas, ReLU on FoV) on raw tokens and on extra tokens.
#[test]
fn camera_head_matches_reference() {
    let fx = Fixture::open("blocks_tiny.safetensors");
    let device = Device::flex();
    let mut head = CameraHead::new(32, 8, &device);
    fx.load(&mut head, "camera_head/weights/");
    let agg = fx.tensor::<4>("camera_head/case_tokens/aggregated_last", &device);
    let [b, s, _, c] = agg.dims();
    let cases = [
        (
            "case_tokens",
            agg.slice([0..b, 0..s, 0..1, 0..c]).reshape([b, s, c]),
        ),
        (
            "case_extra",
            fx.tensor::<3>("camera_head/case_extra/extra_tokens", &device),
        ),
    ];
    for (case, tokens) in cases {
        let iters = head.forward(tokens);
        let got = Tensor::stack::<4>(iters, 0);
        assert_close(
            case,
            flat(got),
            &fx.f32s(&format!("camera_head/{case}/pose_enc_iters")),
            UNIT_REL,
            UNIT_ABS,
        );
    }
}

/// Guards DINO: register insertion after cls, no pos-embed on registers, eps 1e-6, and the
/// antialiased bicubic pos-embed resize (downsampling, upsampling, identity axis).
#[test]
fn dino_matches_reference() {
    let fx = Fixture::open("blocks_tiny.safetensors");
    let device = Device::flex();
    let mut dino = Dino::new(
        &DinoConfig {
            embed_dim: 32,
            depth: 2,
            num_heads: 2,
            img_size: 518,
        },
        14,
        4,
        &device,
    );
    fx.load(&mut dino, "dino/weights/");
    for (h, w) in [
        (56usize, 84usize),
        (350, 518),
        (70, 42),
        (546, 280),
        (28, 28),
    ] {
        let pe = dino.interpolate_pos_embed(h / 14, w / 14);
        assert_close(
            &format!("pos_embed {h}x{w}"),
            flat(pe),
            &fx.f32s(&format!("dino/pos_embed_interp/H{h}_W{w}")),
            UNIT_REL,
            UNIT_ABS,
        );
    }
    for case in ["case0", "case1"] {
        let out = dino.forward(fx.tensor::<4>(&format!("dino/{case}/input"), &device));
        let key = |k: &str| format!("dino/{case}/{k}");
        assert_close(
            &key("x_prenorm"),
            flat(out.prenorm),
            &fx.f32s(&key("x_prenorm")),
            UNIT_REL,
            UNIT_ABS,
        );
        assert_close(
            &key("x_norm_patchtokens"),
            flat(out.patch_tokens),
            &fx.f32s(&key("x_norm_patchtokens")),
            UNIT_REL,
            UNIT_ABS,
        );
        assert_close(
            &key("x_norm_clstoken"),
            flat(out.cls_token),
            &fx.f32s(&key("x_norm_clstoken")),
            UNIT_REL,
            UNIT_ABS,
        );
        assert_close(
            &key("x_norm_regtokens"),
            flat(out.reg_tokens),
            &fx.f32s(&key("x_norm_regtokens")),
            UNIT_REL,
            UNIT_ABS,
        );
    }
}

/// Guards the whole backbone of the tiny model: every aggregator layer (frame/global halves,
/// temporal blocks feeding later layers), the time list, the future-pose tokens and poses.
#[test]
fn tiny_backbone_matches_reference() {
    let fx = Fixture::open("envision4d_tiny.safetensors");
    let device = Device::flex();
    let cfg = ModelConfig::tiny();
    let model = fx.tiny_model(&device);
    let images = fx.tensor::<5>("input/images", &device);
    let all: Vec<usize> = (0..cfg.depth).collect();
    let out = model.backbone(images, &all);
    let agg = &out.aggregator;
    fx.expect(
        "images_normalized",
        agg.norm_images.clone(),
        UNIT_REL,
        UNIT_ABS,
    );
    for l in 0..cfg.depth {
        let key = format!("expected/aggregator/output_list.{l}");
        assert_close(&key, flat(agg.layer(l)), &fx.f32s(&key), AGG_REL, 0.0);
    }
    for (t, tensor) in agg.time_list.iter().enumerate() {
        let key = format!("expected/aggregator/time_list.{t}");
        assert_close(&key, flat(tensor.clone()), &fx.f32s(&key), AGG_REL, 0.0);
    }
    assert_close(
        "time_mlp",
        flat(model.future.time_tokens(4, &device)),
        &fx.f32s("expected/extra/time_mlp"),
        OUT_REL,
        OUT_ABS,
    );
    assert_close(
        "camera_tokens",
        flat(out.tokens.camera.clone()),
        &fx.f32s("expected/extra/camera_tokens"),
        OUT_REL,
        OUT_ABS,
    );
    assert_close(
        "time_tokens",
        flat(out.tokens.time.clone()),
        &fx.f32s("expected/extra/time_tokens"),
        OUT_REL,
        OUT_ABS,
    );
    let iters = Tensor::stack::<4>(out.pose_enc_iters.clone(), 0);
    assert_close(
        "pose_enc_iters",
        flat(iters),
        &fx.f32s("expected/camera_head/pose_enc_iters"),
        OUT_REL,
        OUT_ABS,
    );
    fx.expect("pose_enc", out.pose_enc(), OUT_REL, OUT_ABS);
    fx.expect(
        "adapter/extrinsics",
        out.extrinsics.clone(),
        OUT_REL,
        OUT_ABS,
    );
    fx.expect(
        "adapter/intrinsics",
        out.intrinsics.clone(),
        OUT_REL,
        OUT_ABS,
    );
}

/// Guards the complete tiny forward pass with strict loading of every checkpoint key: depth
/// and confidence, raw Gaussians (image merger on normalised images), the conditioned motion
/// lifting tokens (source-major, refined time tokens) and the motion head.
#[test]
fn tiny_full_forward_matches_reference() {
    let fx = Fixture::open("envision4d_tiny.safetensors");
    let device = Device::flex();
    let model = fx.tiny_model(&device);
    let out = model.forward(
        fx.tensor::<5>("input/images", &device),
        envision4d_model::model::Heads::ALL,
    );
    fx.expect("depth", out.depth.unwrap(), OUT_REL, OUT_ABS);
    fx.expect("depth_conf", out.depth_conf.unwrap(), OUT_REL, OUT_ABS);
    fx.expect("gaussians", out.gaussians.unwrap(), OUT_REL, OUT_ABS);
    for (t, m) in out.motion_tokens.unwrap().into_iter().enumerate() {
        let key = format!("expected/motion_head/motion_tokens.{t}");
        assert_close(&key, flat(m), &fx.f32s(&key), AGG_REL, 0.0);
    }
    fx.expect("motion_enc", out.motion_enc.unwrap(), OUT_REL, OUT_ABS);
}

/// Guards the tiny model's remaining intermediates: the aggregator's DINO outputs, the RoPE
/// positions of the 5 special tokens and the patches, and the time sinusoid.
#[test]
fn tiny_intermediates_match_reference() {
    let fx = Fixture::open("envision4d_tiny.safetensors");
    let device = Device::flex();
    let model = fx.tiny_model(&device);
    let norm =
        envision4d_model::aggregator::normalize_images(fx.tensor::<5>("input/images", &device));
    let [b, s, c, h, w] = norm.dims();
    let dino = model
        .aggregator
        .patch_embed
        .forward(norm.reshape([b * s, c, h, w]));
    let e = |k: &str| fx.f32s(&format!("expected/aggregator/{k}"));
    assert_close(
        "dino patch",
        flat(dino.patch_tokens),
        &e("dino_x_norm_patchtokens"),
        AGG_REL,
        0.0,
    );
    assert_close(
        "dino cls",
        flat(dino.cls_token),
        &e("dino_x_norm_clstoken"),
        AGG_REL,
        0.0,
    );
    assert_close(
        "dino regs",
        flat(dino.reg_tokens),
        &e("dino_x_norm_regtokens"),
        AGG_REL,
        0.0,
    );
    let pos = envision4d_model::layers::frame_positions(5, 4, 6);
    let want = fx.i64s("expected/aggregator/pos");
    for f in 0..2 {
        let got: Vec<i64> = pos.iter().flat_map(|p| p.to_vec()).collect();
        assert_eq!(
            got,
            want[f * 58..(f + 1) * 58].to_vec(),
            "positions of frame {f}"
        );
    }
    let sin = Tensor::<1>::from_floats(sinusoid(&[0.0, 1.0, 2.0, 3.0], 256).as_slice(), &device);
    assert_close(
        "time_sinusoid",
        sin,
        &fx.f32s("expected/extra/time_sinusoid"),
        UNIT_REL,
        UNIT_ABS,
    );
}
