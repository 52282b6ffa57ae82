//! Unit parity: RoPE, aggregator Block (frame and global attention), temporal block.

use crate::fixture::{assert_close, flat, Fixture, UNIT_ABS, UNIT_REL};
use burn::tensor::Device;
use envision4d_model::layers::{Block, BlockSpec, QkNorm, RopeTables, BLOCK_NORM_EPS};

fn positions(fx: &Fixture, key: &str) -> Vec<Vec<[i64; 2]>> {
    let shape = fx.shape(key);
    let v = fx.i64s(key);
    (0..shape[0])
        .map(|b| {
            (0..shape[1])
                .map(|n| [v[(b * shape[1] + n) * 2], v[(b * shape[1] + n) * 2 + 1]])
                .collect()
        })
        .collect()
}

/// Guards the 2D RoPE conventions (y half first, split-half rotation, base 100, duplicated
/// angles) at the tiny head dim and at the real head dim 64 with random positions.
#[test]
fn rope_matches_reference() {
    let fx = Fixture::open("blocks_tiny.safetensors");
    let device = Device::flex();
    for (case, pos_key) in [
        ("rope/case0", "rope/positions_frame"),
        ("rope/case1", "rope/case1/positions"),
    ] {
        let tokens = fx.tensor::<4>(&format!("{case}/tokens"), &device);
        let d = tokens.dims()[3];
        let rope = RopeTables::new(&positions(&fx, pos_key), d, &device);
        assert_close(
            case,
            flat(rope.apply(tokens)),
            &fx.f32s(&format!("{case}/output")),
            UNIT_REL,
            UNIT_ABS,
        );
    }
}

fn aggregator_block(dim: usize, heads: usize, device: &Device) -> Block {
    Block::new(
        BlockSpec {
            dim,
            num_heads: heads,
            mlp_ratio: 4,
            qk_norm: QkNorm::On,
            norm_eps: BLOCK_NORM_EPS,
            layer_scale_init: 0.01,
        },
        device,
    )
}

/// Guards the aggregator block (qk-norm, RoPE after qk-norm, LayerScale named `gamma`, GELU
/// erf) in frame attention (per image) and global attention (all frames in one sequence).
#[test]
fn block_frame_and_global_match_reference() {
    let fx = Fixture::open("blocks_tiny.safetensors");
    let device = Device::flex();
    let mut block = aggregator_block(64, 4, &device);
    fx.load(&mut block, "block/weights/");
    for (mode, pos_key) in [
        ("frame", "rope/positions_frame"),
        ("global", "rope/positions_global"),
    ] {
        let x = fx.tensor::<3>(&format!("block/{mode}/input"), &device);
        let rope = RopeTables::new(&positions(&fx, pos_key), 16, &device);
        let y = block.forward(x, Some(&rope));
        assert_close(
            &format!("block/{mode}"),
            flat(y),
            &fx.f32s(&format!("block/{mode}/output")),
            UNIT_REL,
            UNIT_ABS,
        );
    }
}

/// Guards the temporal block: same block without RoPE, attending over time per token slot.
#[test]
fn time_block_matches_reference() {
    let fx = Fixture::open("blocks_tiny.safetensors");
    let device = Device::flex();
    let mut block = aggregator_block(64, 4, &device);
    fx.load(&mut block, "time_block/weights/");
    let y = block.forward(fx.tensor::<3>("time_block/input", &device), None);
    assert_close(
        "time_block",
        flat(y),
        &fx.f32s("time_block/output"),
        UNIT_REL,
        UNIT_ABS,
    );
}
