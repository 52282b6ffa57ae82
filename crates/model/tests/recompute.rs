//! Recomputed frozen blocks against the plain blocks: same values, same gradients.

use burn::module::{Module, ModuleMapper, Param};
use burn::tensor::{Device, DeviceKind, Distribution, Tensor};
use envision4d_model::layers::recompute::{forward_recomputed, is_frozen};
use envision4d_model::layers::{frame_positions, Block, BlockSpec, QkNorm, RopeTables};

struct Freeze;

impl ModuleMapper for Freeze {
    fn map_float<const D: usize>(&mut self, p: Param<Tensor<D>>) -> Param<Tensor<D>> {
        p.set_require_grad(false)
    }
}

fn max_rel<const D: usize>(a: Tensor<D>, b: Tensor<D>) -> f32 {
    let m = a.clone().abs().max().into_scalar::<f32>().max(1e-30);
    (a - b).abs().max().into_scalar::<f32>() / m
}

/// Gradients of the input leaf and of a trainable gain in front of two frozen blocks (the
/// second fed the first's output, as in the aggregator), plain and recomputed, from the same
/// weights and inputs (drawn once: tests share the device's generator).
fn compare(device: &Device, what: &str) {
    let spec = BlockSpec {
        dim: 32,
        num_heads: 4,
        mlp_ratio: 4,
        qk_norm: QkNorm::On,
        norm_eps: 1e-5,
        layer_scale_init: 0.5,
    };
    let blocks: Vec<Block> = (0..2)
        .map(|_| Block::new(spec, device).map(&mut Freeze))
        .collect();
    assert!(blocks.iter().all(is_frozen));
    let positions = frame_positions(2, 3, 4);
    let n = positions.len();
    let rope = RopeTables::new(&vec![positions; 2], spec.dim / spec.num_heads, device);
    let normal = || Tensor::<3>::random([2, n, spec.dim], Distribution::Normal(0.0, 1.0), device);
    let (x0, weights) = (normal(), normal());
    let run = |recompute: bool| {
        let x = x0.clone().require_grad();
        let gain = Tensor::<3>::ones([1, 1, spec.dim], device).require_grad();
        let mut y = x.clone() * gain.clone();
        for b in &blocks {
            y = if recompute {
                forward_recomputed(b, y, Some(&rope))
            } else {
                b.forward(y, Some(&rope))
            };
        }
        let grads = (y * weights.clone()).sum().backward();
        let gx = x.grad(&grads).expect("input gradient");
        let gg = gain.grad(&grads).expect("gain gradient");
        [gx, gg.expand([2, n, spec.dim])]
    };
    for (k, (a, b)) in run(false).into_iter().zip(run(true)).enumerate() {
        let e = max_rel(a, b);
        assert!(e < 1e-5, "{what}, gradient {k}: relative error {e}");
    }
}

/// Guards the recomputing backward node (the saved input, the private graph's VJP, and the
/// gradient handed back to the outer graph): the input and upstream gradients through two
/// chained frozen blocks equal the plain blocks' on the CPU, under Burn's balanced
/// checkpointing too (the node must attach under either strategy).
#[test]
fn recomputed_blocks_give_the_plain_gradients() {
    compare(&Device::flex().autodiff(), "flex");
    compare(
        &Device::flex().autodiff().gradient_checkpointing(),
        "flex, balanced checkpointing",
    );
}

/// Guards the node on the CubeCL backend (lavapipe in CI): the same gradients as the plain
/// blocks on wgpu.
#[test]
fn recomputed_blocks_give_the_plain_gradients_wgpu() {
    compare(&Device::wgpu(DeviceKind::DefaultDevice).autodiff(), "wgpu");
}

/// Guards inference: without autodiff the recomputed path is the plain forward.
#[test]
fn recomputed_blocks_are_plain_without_autodiff() {
    let device = Device::flex();
    let block = Block::new(
        BlockSpec {
            dim: 16,
            num_heads: 2,
            mlp_ratio: 4,
            qk_norm: QkNorm::On,
            norm_eps: 1e-5,
            layer_scale_init: 1.0,
        },
        &device,
    );
    let x = Tensor::<3>::random([1, 5, 16], Distribution::Normal(0.0, 1.0), &device);
    let e = max_rel(
        block.forward(x.clone(), None),
        forward_recomputed(&block, x, None),
    );
    assert_eq!(e, 0.0);
}
