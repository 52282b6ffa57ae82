//! The lean attention op against Burn's decomposed attention.

use burn::tensor::module::attention;
use burn::tensor::ops::AttentionModuleOptions;
use burn::tensor::{Device, Distribution, Tensor};
use envision4d_model::layers::lean_attention::lean_attention_blocked;

fn max_rel(a: Tensor<4>, b: Tensor<4>) -> f32 {
    let m = a.clone().abs().max().into_scalar::<f32>().max(1e-30);
    (a - b).abs().max().into_scalar::<f32>() / m
}

/// Output and q/k/v gradients of `sum(attn(q·gain, k, v) * w)` by both ops.
fn both(gain: f64, block: usize) -> [(Tensor<4>, Tensor<4>); 4] {
    let device = Device::flex().autodiff();
    device.seed(7);
    let shape = [2, 3, 37, 8];
    let r = |s: [usize; 4]| Tensor::<4>::random(s, Distribution::Normal(0.0, 1.0), &device);
    let (q0, k0, v0, w) = (r(shape), r(shape), r(shape), r(shape));
    let run = |lean: bool| {
        let (q, k, v) = (
            q0.clone().require_grad(),
            k0.clone().require_grad(),
            v0.clone().require_grad(),
        );
        let qs = q.clone() * gain;
        let out = if lean {
            lean_attention_blocked(qs, k.clone(), v.clone(), block)
        } else {
            attention(
                qs,
                k.clone(),
                v.clone(),
                None,
                None,
                AttentionModuleOptions::default(),
            )
        };
        let g = (out.clone() * w.clone()).sum().backward();
        [
            out.inner(),
            q.grad(&g).unwrap(),
            k.grad(&g).unwrap(),
            v.grad(&g).unwrap(),
        ]
    };
    let (a, b) = (run(true), run(false));
    let mut it = a.into_iter().zip(b);
    std::array::from_fn(|_| it.next().unwrap())
}

/// Guards the blocked forward and the recomputing backward (the log-sum-exp recurrence, the
/// softmax VJP's row term, dK/dV summed over query blocks, a partial last block): output and
/// every gradient equal Burn's attention to float tolerance, with 2, 5 and all rows per block.
#[test]
fn lean_attention_equals_burns_attention() {
    for block in [2 * 3 * 37 * 2, 2 * 3 * 37 * 5, 1 << 24] {
        for (k, (lean, burn)) in both(1.0, block).into_iter().enumerate() {
            let e = max_rel(burn, lean);
            assert!(e < 1e-5, "block {block}, tensor {k}: relative error {e}");
        }
    }
}

/// Guards stiff softmax: logits scaled 40x (rows nearly one-hot, exp overflowing without the
/// max shift) still give finite outputs and gradients equal to Burn's.
#[test]
fn lean_attention_is_stable_on_sharp_rows() {
    for (k, (lean, burn)) in both(40.0, 2 * 3 * 37 * 4).into_iter().enumerate() {
        let finite = lean.clone().is_finite().all().into_scalar::<bool>();
        assert!(finite, "tensor {k} not finite");
        let e = max_rel(burn, lean);
        assert!(e < 1e-4, "tensor {k}: relative error {e}");
    }
}
