//! Parity of the DPT heads: the sin/cos pos-embed and a full depth head.

use crate::fixture::{assert_close, flat, Fixture, UNIT_ABS, UNIT_REL};
use burn::tensor::{Device, Tensor};
use envision4d_model::config::DptConfig;
use envision4d_model::dpt::pos_embed::dpt_pos_embed;
use envision4d_model::dpt::{depth_activation, DptHead, DptKind};

/// Guards the DPT pos-embed (aspect from the image, diagonal normalisation, sin before cos,
/// u block before v block, 0.1 ratio) at token and image resolution.
#[test]
fn dpt_pos_embed_matches_reference() {
    let fx = Fixture::open("blocks_tiny.safetensors");
    let device = Device::flex();
    for (c, h, w, ih, iw) in [
        (16usize, 4usize, 6usize, 56usize, 84usize),
        (64, 4, 6, 56, 84),
        (16, 56, 84, 56, 84),
        (32, 25, 37, 350, 518),
    ] {
        let key = format!("dpt_pos_embed/c{c}_h{h}_w{w}_imgH{ih}_imgW{iw}");
        assert_close(
            &key,
            flat(dpt_pos_embed(c, h, w, ih, iw, &device)),
            &fx.f32s(&key),
            UNIT_REL,
            UNIT_ABS,
        );
    }
}

/// Guards the DPT depth head end to end: shared norm, projections + pos-embed, the resize
/// layers, RCU's relu-skip quirk, fusion sizes, align-corners upsampling, exp/expp1.
#[test]
fn dpt_depth_head_matches_reference() {
    let fx = Fixture::open("blocks_tiny.safetensors");
    let device = Device::flex();
    let cfg = DptConfig {
        features: 16,
        out_channels: [8, 16, 32, 32],
    };
    let mut head = DptHead::new(DptKind::Depth, 64, &cfg, 14, &device);
    fx.load(&mut head, "dpt_head/weights/");
    let taps: [Tensor<4>; 4] =
        [4, 11, 17, 23].map(|l| fx.tensor::<4>(&format!("dpt_head/input/tokens.{l}"), &device));
    let raw = head.forward_raw(&taps, 5, [56, 84], None);
    let (depth, conf) = depth_activation(raw);
    assert_close(
        "dpt depth",
        flat(depth),
        &fx.f32s("dpt_head/output/depth"),
        UNIT_REL,
        UNIT_ABS,
    );
    assert_close(
        "dpt depth_conf",
        flat(conf),
        &fx.f32s("dpt_head/output/depth_conf"),
        UNIT_REL,
        UNIT_ABS,
    );
}
