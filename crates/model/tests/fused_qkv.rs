//! Training attention as one autodiff node from the q/k/v projection (`qkv_attention`) on
//! wgpu against the separate nodes it replaces (Burn's reshape, permutation and three
//! slices, then the qk-norm, RoPE and lean-attention nodes): the same kernels in the same
//! order, so the output and every gradient must be the same values, with and without norms
//! and RoPE, frozen norms, several query blocks, and through `Attention` itself.

use burn::module::Param;
use burn::nn::LayerNormConfig;
use burn::tensor::{Device, Distribution, Tensor};
use envision4d_model::bench::count_launches;
use envision4d_model::layers::lean_attention::lean_attention_blocked;
use envision4d_model::layers::norm::fused_layer_norm;
use envision4d_model::layers::qkv_attention::{
    qkv_attention, set_packed_qkv, takes_packed, QkvLayout,
};
use envision4d_model::layers::rope::rope_rotate;
use envision4d_model::layers::{frame_positions, Attention, QkNorm, RopeTables};
use support::{gpu, host, turn, uniform, Unfused};

mod support;

const EPS: f64 = 1e-5;

/// `b` batches of one frame of `1 + rows · cols` tokens, `heads` heads of `d` channels.
#[derive(Debug, Clone, Copy)]
struct Case {
    b: usize,
    rows: usize,
    cols: usize,
    heads: usize,
    d: usize,
    norms: bool,
    rope: bool,
    /// The norms' parameters take no gradient (a frozen block).
    frozen: bool,
    /// The projection takes no gradient (only the norms' parameters do).
    constant: bool,
    /// Score elements per block of query rows.
    block: usize,
}

impl Case {
    fn n(&self) -> usize {
        1 + self.rows * self.cols
    }
}

/// The op's inputs: the projection, the norms' four parameters, RoPE's tables.
struct Inputs {
    qkv: Tensor<3>,
    norms: Option<[Tensor<1>; 4]>,
    rope: Option<(Tensor<4>, Tensor<4>)>,
}

fn inputs(case: Case, device: &Device) -> Inputs {
    let (b, n, c) = (case.b, case.n(), case.heads * case.d);
    let mut qkv = Tensor::<3>::from_data(
        burn::tensor::TensorData::new(uniform(b * n * 3 * c, 1), [b, n, 3 * c]),
        device,
    );
    if !case.constant {
        qkv = qkv.require_grad();
    }
    let norms = case.norms.then(|| {
        [11, 12, 13, 14].map(|seed| {
            // Gammas near 1, betas near 0: both matter to the output.
            let v = uniform(case.d, seed).into_iter().map(|x| {
                if seed % 2 == 1 {
                    1.0 + 0.5 * x
                } else {
                    0.3 * x
                }
            });
            let t = Tensor::<1>::from_data(
                burn::tensor::TensorData::new(v.collect::<Vec<f64>>(), [case.d]),
                device,
            );
            if case.frozen {
                t
            } else {
                t.require_grad()
            }
        })
    });
    let rope = case.rope.then(|| {
        let positions = vec![frame_positions(1, case.rows, case.cols); b];
        let t = RopeTables::new(&positions, case.d, device);
        (t.cos, t.signed_sin)
    });
    Inputs { qkv, norms, rope }
}

/// The separate nodes, as `Attention::forward` records them without the one node.
fn separate(i: &Inputs, case: Case) -> Tensor<4> {
    let [b, n, _] = i.qkv.dims();
    let (h, d) = (case.heads, case.d);
    let packed = i
        .qkv
        .clone()
        .reshape([b, n, 3, h, d])
        .permute([2, 0, 3, 1, 4]);
    let part = |k: usize| {
        packed
            .clone()
            .slice([k..k + 1, 0..b, 0..h, 0..n, 0..d])
            .reshape([b, h, n, d])
    };
    let (mut q, mut k, v) = (part(0), part(1), part(2));
    if let Some([qg, qb, kg, kb]) = &i.norms {
        q = fused_layer_norm(q, qg.clone(), qb.clone(), EPS);
        k = fused_layer_norm(k, kg.clone(), kb.clone(), EPS);
    }
    if let Some((cos, sin)) = &i.rope {
        q = rope_rotate(q, cos.clone(), sin.clone());
        k = rope_rotate(k, cos.clone(), sin.clone());
    }
    lean_attention_blocked(q, k, v, case.block)
}

/// `[out, d qkv, d q_gamma, d q_beta, d k_gamma, d k_beta]` of `sum(out · w)` (absent
/// gradients as empty vectors), by the one node or the separate ones.
fn run(case: Case, device: &Device, one_node: bool) -> Vec<Vec<f64>> {
    let i = inputs(case, device);
    let out = if one_node {
        let layout = QkvLayout {
            heads: case.heads,
            epsilon: EPS,
            block: case.block,
        };
        qkv_attention(i.qkv.clone(), i.norms.clone(), i.rope.clone(), layout)
    } else {
        separate(&i, case)
    };
    let w = Tensor::<4>::from_data(
        burn::tensor::TensorData::new(uniform(out.shape().num_elements(), 5), out.dims()),
        device,
    );
    let g = (out.clone() * w).sum().backward();
    let mut all = vec![host(out), i.qkv.grad(&g).map(host).unwrap_or_default()];
    for p in i.norms.iter().flatten() {
        all.push(p.grad(&g).map(host).unwrap_or_default());
    }
    all
}

fn cases() -> Vec<Case> {
    let case = Case {
        b: 2,
        rows: 5,
        cols: 7,
        heads: 3,
        d: 16,
        norms: true,
        rope: true,
        frozen: false,
        constant: false,
        block: 1 << 24,
    };
    vec![
        case,
        // The DINO encoder's attention: neither norms nor RoPE.
        Case {
            norms: false,
            rope: false,
            ..case
        },
        Case {
            rope: false,
            ..case
        },
        Case {
            norms: false,
            ..case
        },
        Case {
            frozen: true,
            ..case
        },
        // The node tracked through the norms' parameters only: no projection gradient.
        Case {
            constant: true,
            ..case
        },
        // Blocks of 2 · 3 · 8 · 36 score elements: query rows in five blocks.
        Case {
            block: 2 * 3 * 8 * 36,
            ..case
        },
        // One batch, one head of 4, 401 tokens.
        Case {
            b: 1,
            rows: 20,
            cols: 20,
            heads: 1,
            d: 4,
            ..case
        },
    ]
}

/// Guards the one node's bookkeeping (the split's layout, each third of the merged
/// gradient, the norms' parameters registered to the right parents and absent when frozen,
/// their gradients without the projection's when it is untracked,
/// RoPE's tables and the block size passed through): on wgpu it equals the separate nodes
/// in value, output and gradients (compared as f64, where `-0.0 == 0.0`: the old sum with
/// zeros made negative zeros positive).
#[test]
fn one_node_equals_the_separate_nodes_on_wgpu() {
    let _turn = turn();
    let Some(gpu) = gpu() else { return };
    let device = gpu.autodiff();
    for case in cases() {
        let one = run(case, &device, true);
        let separate = run(case, &device, false);
        let names = ["out", "dqkv", "dq_gamma", "dq_beta", "dk_gamma", "dk_beta"];
        assert_eq!(one.len(), separate.len(), "{case:?}");
        for (k, (a, b)) in one.iter().zip(&separate).enumerate() {
            assert_eq!(
                a.len(),
                b.len(),
                "{case:?}: {} present on one side only",
                names[k]
            );
            if (case.frozen && k >= 2) || (case.constant && k == 1) {
                assert!(
                    a.is_empty(),
                    "{case:?}: an untracked {} has a gradient",
                    names[k]
                );
            } else {
                assert!(!a.is_empty(), "{case:?}: no {}", names[k]);
            }
            assert!(
                a == b,
                "{case:?}: {} differs from the separate nodes",
                names[k]
            );
        }
    }
}

/// `Attention` `[b, n, c]` with random weights and perturbed norm parameters.
fn attention(qk_norm: QkNorm, device: &Device) -> Attention {
    let mut a = Attention::new(48, 3, qk_norm, device);
    if qk_norm == QkNorm::On {
        // Not the default epsilon, so a node that ignored the norms' own would differ.
        let norm = || Some(LayerNormConfig::new(16).with_epsilon(1e-3).init(device));
        (a.q_norm, a.k_norm) = (norm(), norm());
    }
    let perturb = |p: &Param<Tensor<1>>, offset: f64| {
        let noise = p.val().random_like(Distribution::Uniform(-0.5, 0.5)) + offset;
        Param::from_tensor(noise.detach().require_grad())
    };
    for norm in [&mut a.q_norm, &mut a.k_norm].into_iter().flatten() {
        norm.gamma = perturb(&norm.gamma, 1.0);
        norm.beta = norm.beta.as_ref().map(|b| perturb(b, 0.0));
    }
    a
}

/// `[y, dx, d qkv.weight, d proj.weight, d q_norm.gamma, d k_norm.beta]` of `sum(y · w)`.
fn attend(a: &Attention, x: &Tensor<3>, rope: Option<&RopeTables>) -> Vec<Vec<f64>> {
    let x = x.clone().require_grad();
    let y = a.forward(x.clone(), rope);
    let w = Tensor::<3>::from_data(
        burn::tensor::TensorData::new(uniform(y.shape().num_elements(), 9), y.dims()),
        &y.device(),
    );
    let g = (y.clone() * w).sum().backward();
    let mut all = vec![
        host(y),
        x.grad(&g).map(host).unwrap_or_default(),
        a.qkv.weight.val().grad(&g).map(host).unwrap_or_default(),
        a.proj.weight.val().grad(&g).map(host).unwrap_or_default(),
    ];
    if let (Some(qn), Some(kn)) = (&a.q_norm, &a.k_norm) {
        all.push(qn.gamma.val().grad(&g).map(host).unwrap_or_default());
        let beta = kn.beta.as_ref().expect("beta");
        all.push(beta.val().grad(&g).map(host).unwrap_or_default());
    }
    all
}

/// Guards the wiring in `Attention::forward` (the norms' epsilon and parameters, the tables,
/// the heads, the projection after): the aggregator's attention (norms and RoPE) and the
/// encoder's (neither) give the same values by the one node as by the separate nodes, and the
/// one node launches fewer kernels (so it was taken).
#[test]
fn attention_takes_the_one_node_with_the_same_values_and_fewer_launches() {
    let _turn = turn();
    let Some(gpu) = gpu() else { return };
    let device = gpu.autodiff();
    let (b, rows, cols) = (2, 4, 6);
    let n = 1 + rows * cols;
    let positions = vec![frame_positions(1, rows, cols); b];
    let rope = RopeTables::new(&positions, 16, &device);
    let x = Tensor::<3>::from_data(
        burn::tensor::TensorData::new(uniform(b * n * 48, 7), [b, n, 48]),
        &device,
    );
    for (qk_norm, rope) in [(QkNorm::On, Some(&rope)), (QkNorm::Off, None)] {
        let a = attention(qk_norm, &device);
        let _ = attend(&a, &x, rope); // compile and tune the kernels first
        let (one, on) = count_launches(false, || attend(&a, &x, rope));
        let (separate, off) = {
            let _off = Unfused::new(set_packed_qkv);
            let _ = attend(&a, &x, rope);
            count_launches(false, || attend(&a, &x, rope))
        };
        let (on, off) = (on.total(), off.total());
        println!("{qk_norm:?}: launches of one attention forward and backward: one node {on}, separate {off}");
        assert!(
            one.iter().all(|v| !v.is_empty()),
            "{qk_norm:?}: a gradient is missing"
        );
        assert!(
            one == separate,
            "{qk_norm:?}: the one node differs from the separate nodes"
        );
        assert!(
            on + 4 <= off,
            "{qk_norm:?}: one node {on} launches against {off}"
        );
    }
}

/// Guards where the one node applies: training on a GPU backend only. The CPU backend keeps
/// the separate nodes (Burn's LayerNorm for the qk-norm, in which parity with the official
/// code was checked), and inference needs no node.
#[test]
fn only_training_on_a_gpu_takes_the_one_node() {
    let f32 = burn::tensor::DType::F32;
    let cpu = Device::flex();
    assert!(!takes_packed(&cpu.clone().autodiff(), f32, true, true));
    assert!(!takes_packed(&cpu, f32, false, false));
    let Some(gpu) = gpu() else { return };
    let _turn = turn();
    assert!(takes_packed(&gpu.clone().autodiff(), f32, true, true));
    assert!(takes_packed(&gpu.clone().autodiff(), f32, false, false));
    assert!(!takes_packed(&gpu, f32, true, true));
    assert!(!takes_packed(
        &gpu.clone().autodiff(),
        burn::tensor::DType::F16,
        true,
        true
    ));
    let _off = Unfused::new(set_packed_qkv);
    assert!(!takes_packed(&gpu.autodiff(), f32, true, true));
}

/// Guards `Attention`'s packed path on a GPU: a module whose k-norm beta is narrower than its
/// heads (built by hand; checkpoints are shape-checked on load) stops with the widths named
/// instead of training on values read past the parameter.
#[test]
fn an_attention_with_a_narrow_norm_parameter_stops_on_wgpu() {
    let _turn = turn();
    let Some(gpu) = gpu() else { return };
    let device = gpu.autodiff();
    let mut a = attention(QkNorm::On, &device);
    if let Some(kn) = a.k_norm.as_mut() {
        kn.beta = Some(Param::from_tensor(
            Tensor::<1>::zeros([12], &device).require_grad(),
        ));
    }
    let x = Tensor::<3>::zeros([1, 5, 48], &device);
    let run = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| attend(&a, &x, None)));
    let message = run.expect_err("a narrow beta was accepted");
    let text = message
        .downcast_ref::<String>()
        .cloned()
        .unwrap_or_default();
    assert!(
        text.contains("k_norm.beta of width 12 applied to heads of 16"),
        "unexpected message: {text}"
    );
}
