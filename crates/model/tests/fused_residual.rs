//! The fused LayerScale residual `x + (u + b) ⊙ γ` (one kernel forward, one backward) on
//! wgpu against the same sum in Burn's ops in f64 on the CPU: output and all four
//! gradients, with one chunk of rows and many (the parameters' partial sums reduced again),
//! one channel, tokens near f32's range ends, a bias that cancels the tokens, a frozen gain
//! or bias (the backward skips their sums), constant tokens, and more elements than one
//! grid axis of workgroups holds; then the block's projection through it.

use burn::module::Param;
use burn::nn::{Linear, LinearConfig};
use burn::tensor::{DType, Device, Tensor, TensorData};
use envision4d_model::bench::count_launches;
use envision4d_model::layers::residual::kernels::GAIN_ROWS;
use envision4d_model::layers::residual::{projected_residual, scaled_residual, set_fused_residual};
use support::{assert_chunked_sums, gpu, host, rel_err, turn, uniform, Unfused};

mod support;

/// Tokens `[b, n, c]` (`u` scaled by `gain`); `cancel`: the bias is minus the first row of
/// `u`, so `u + b` cancels there; `frozen`: γ takes no gradient; `bias_frozen`: nor does b;
/// `constant`: nor does `u`.
#[derive(Debug, Clone, Copy)]
struct Case {
    b: usize,
    n: usize,
    c: usize,
    gain: f64,
    cancel: bool,
    frozen: bool,
    bias_frozen: bool,
    constant: bool,
}

/// The names of [`run`]'s outputs.
const OUTPUTS: [&str; 5] = ["y", "dx", "du", "db", "dgamma"];

/// `[y, dx, du, db, dγ]` of `sum((x + (u + b) ⊙ γ) · w)` (an absent gradient as an empty
/// vector), and per channel the scales of db's and dγ's roundings: `Σ_rows |w · γ|` and
/// `Σ_rows |w| · (|u| + |b|)` (`u + b` rounds relative to its terms).
fn run(case: Case, device: &Device, dtype: DType) -> ([Vec<f64>; 5], [Vec<f64>; 2]) {
    let shape = [case.b, case.n, case.c];
    let len = shape.iter().product();
    let tensor = |v: Vec<f64>| {
        Tensor::<3>::from_data(
            TensorData::new(v, shape).convert_dtype(dtype),
            (device, dtype),
        )
    };
    let param = |v: Vec<f64>, trained: bool| {
        let p = Tensor::<1>::from_data(
            TensorData::new(v, [case.c]).convert_dtype(dtype),
            (device, dtype),
        );
        if trained {
            p.require_grad()
        } else {
            p
        }
    };
    let x = tensor(uniform(len, 1)).require_grad();
    let u_host: Vec<f64> = uniform(len, 2).into_iter().map(|v| v * case.gain).collect();
    let w_host = uniform(len, 3);
    let mut u = tensor(u_host.clone());
    if !case.constant {
        u = u.require_grad();
    }
    let b_host: Vec<f64> = if case.cancel {
        u_host[..case.c].iter().map(|v| -v).collect()
    } else {
        uniform(case.c, 5)
    };
    let g_host = uniform(case.c, 4);
    let bias = param(b_host.clone(), !case.bias_frozen);
    let gamma = param(g_host.clone(), !case.frozen);
    let y = scaled_residual(x.clone(), u.clone(), bias.clone(), gamma.clone());
    let g = (y.clone() * tensor(w_host.clone())).sum().backward();
    let grad3 = |t: &Tensor<3>| t.grad(&g).map(host).unwrap_or_default();
    let grad1 = |t: &Tensor<1>| t.grad(&g).map(host).unwrap_or_default();
    let mut scales = [vec![0.0f64; case.c], vec![0.0f64; case.c]];
    for (i, (w, u)) in w_host.iter().zip(&u_host).enumerate() {
        let c = i % case.c;
        scales[0][c] += (w * g_host[c]).abs();
        scales[1][c] += w.abs() * (u.abs() + b_host[c].abs());
    }
    let outputs = [host(y), grad3(&x), grad3(&u), grad1(&bias), grad1(&gamma)];
    (outputs, scales)
}

fn cases() -> Vec<Case> {
    let case = Case {
        b: 2,
        n: 37,
        c: 48,
        gain: 1.0,
        cancel: false,
        frozen: false,
        bias_frozen: false,
        constant: false,
    };
    vec![
        case,
        // 2 · 700 rows: six chunks of the gain's partial sums, reduced once more.
        Case { n: 700, ..case },
        Case { c: 1, ..case },
        Case { gain: 1e30, ..case },
        Case {
            gain: 1e-30,
            ..case
        },
        Case {
            cancel: true,
            ..case
        },
        Case {
            frozen: true,
            ..case
        },
        Case {
            bias_frozen: true,
            ..case
        },
        Case {
            frozen: true,
            bias_frozen: true,
            ..case
        },
        Case {
            constant: true,
            ..case
        },
        // 4 · 4,100 · 1,024 = 16.8M elements: past 65,535 workgroups of 256 units.
        Case {
            b: 4,
            n: 4100,
            c: 1024,
            ..case
        },
    ]
}

/// Whether the test GPU is CUDA (`ENVISION4D_TEST_GPU=cuda`), whose kernels may contract a
/// product and a sum into one fused multiply-add.
fn cuda() -> bool {
    std::env::var("ENVISION4D_TEST_GPU").as_deref() == Ok("cuda")
}

/// Guards the fused residual and its wiring (the channel of each element, the bias added
/// before the gain, the gradient of the stream passed through, `u`'s gradient scaled by γ,
/// the parameters' chunked sums and their second reduction, the sums skipped for a frozen
/// gain or bias or constant tokens, the 2-D grid): on wgpu the output and `u`'s gradient
/// equal Burn's ops bit for bit (the output to an ulp on CUDA) and the f64 sums to f32
/// rounding; b's and γ's gradients are within recursive summation's bound of the f64 sums.
#[test]
fn fused_residual_equals_f64_on_wgpu() {
    let _turn = turn();
    let Some(gpu) = gpu() else { return };
    let device = gpu.autodiff();
    let oracle = Device::flex().autodiff();
    for case in cases() {
        let (want, scales) = run(case, &oracle, DType::F64);
        let (fused, _) = run(case, &device, DType::F32);
        let (burn, _) = {
            let _off = Unfused::new(set_fused_residual);
            run(case, &device, DType::F32)
        };
        for (i, name) in OUTPUTS.into_iter().enumerate() {
            assert_eq!(
                fused[i].len(),
                want[i].len(),
                "{case:?}: {name} present on one side only"
            );
            if want[i].is_empty() {
                continue;
            }
            let (e, e_burn) = (rel_err(&fused[i], &want[i]), rel_err(&burn[i], &want[i]));
            let apart = rel_err(&fused[i], &burn[i]);
            println!("{case:?} {name}: fused {e:.2e}, Burn's ops {e_burn:.2e}, apart {apart:.2e}");
            let rows = case.b * case.n;
            let what = format!("{case:?}: {name}");
            match name {
                // Terms rounded once (db: g·γ) or twice (dγ: u + b, then the product).
                "db" => assert_chunked_sums(
                    &what,
                    &fused[i],
                    &want[i],
                    &scales[0],
                    [rows, GAIN_ROWS as usize, 1],
                ),
                "dgamma" => assert_chunked_sums(
                    &what,
                    &fused[i],
                    &want[i],
                    &scales[1],
                    [rows, GAIN_ROWS as usize, 2],
                ),
                _ => {
                    // y: three roundings (u + b, the product, the sum).
                    assert!(e <= 2.4e-7, "{case:?}: {name} relative error {e:.3e}");
                    if name == "y" && cuda() {
                        // CUDA's LLVM route may fuse the product and sum into one rounding.
                        assert!(apart <= 1.2e-7, "{case:?}: y {apart:.3e} from Burn's ops");
                    } else {
                        assert_eq!(
                            fused[i], burn[i],
                            "{case:?}: {name} differs from Burn's ops"
                        );
                    }
                }
            }
        }
    }
}

/// Guards the block's wiring of the fused op ([`projected_residual`]: the projection's
/// product without its bias, then the bias inside the residual): on wgpu the output and
/// the gradients of the stream, the projection's input, weight and bias and the gain equal
/// the same layer's `Linear`, product and sum on the CPU, and they equal Burn's ops on
/// wgpu bit for bit for the output (to an ulp on CUDA).
#[test]
fn projected_residual_equals_linear_then_gain() {
    let _turn = turn();
    let Some(gpu) = gpu() else { return };
    let (b, n, c_in, c) = (2, 300, 24, 40);
    let layer = |device: &Device| -> Linear {
        let mut l = LinearConfig::new(c_in, c).init(device);
        let w = TensorData::new(uniform(c_in * c, 6), [c_in, c]).convert_dtype(DType::F32);
        let bias = TensorData::new(uniform(c, 7), [c]).convert_dtype(DType::F32);
        l.weight = Param::from_tensor(Tensor::from_data(w, device).require_grad());
        l.bias = Some(Param::from_tensor(
            Tensor::from_data(bias, device).require_grad(),
        ));
        l
    };
    let run = |device: &Device| -> Vec<Vec<f64>> {
        let tokens = |len: usize, seed: u64, dims: [usize; 3]| {
            let data = TensorData::new(uniform(len, seed), dims).convert_dtype(DType::F32);
            Tensor::<3>::from_data(data, device).require_grad()
        };
        let l = layer(device);
        let x = tokens(b * n * c, 1, [b, n, c]);
        let h = tokens(b * n * c_in, 2, [b, n, c_in]);
        let gamma = Tensor::<1>::from_data(
            TensorData::new(uniform(c, 4), [c]).convert_dtype(DType::F32),
            device,
        )
        .require_grad();
        let w = Tensor::<3>::from_data(
            TensorData::new(uniform(b * n * c, 3), [b, n, c]).convert_dtype(DType::F32),
            device,
        );
        let y = projected_residual(x.clone(), &l, h.clone(), gamma.clone());
        let g = (y.clone() * w).sum().backward();
        let bias = l.bias.as_ref().map(|p| p.val()).expect("a bias");
        vec![
            host(y),
            host(x.grad(&g).expect("dx")),
            host(h.grad(&g).expect("dh")),
            host(l.weight.val().grad(&g).expect("dW")),
            host(bias.grad(&g).expect("db")),
            host(gamma.grad(&g).expect("dgamma")),
        ]
    };
    let cpu = run(&Device::flex().autodiff());
    let device = gpu.autodiff();
    let fused = run(&device);
    let burn = {
        let _off = Unfused::new(set_fused_residual);
        run(&device)
    };
    for (i, name) in ["y", "dx", "dh", "dW", "db", "dgamma"]
        .into_iter()
        .enumerate()
    {
        let e = rel_err(&fused[i], &cpu[i]);
        let e_burn = rel_err(&burn[i], &cpu[i]);
        println!("{name}: fused {e:.2e} from the CPU, Burn's ops {e_burn:.2e}");
        assert!(e <= 2e-6, "{name}: {e:.3e} from the CPU");
    }
    let apart = rel_err(&fused[0], &burn[0]);
    if cuda() {
        assert!(apart <= 1.2e-7, "y {apart:.3e} from Burn's ops");
    } else {
        assert_eq!(fused[0], burn[0], "y differs from Burn's ops");
    }
}

/// Guards the launches the op exists for: one residual forward and backward on wgpu takes
/// fewer kernels fused than in Burn's ops (a bias sum, a product and a sum forward; a
/// product, a reduction for b, and a product and a reduction for γ backward), with the same
/// output.
#[test]
fn fused_residual_launches_fewer_kernels() {
    let _turn = turn();
    let Some(gpu) = gpu() else { return };
    let device = gpu.autodiff();
    let case = cases()[0];
    let _ = run(case, &device, DType::F32);
    let ((fused, _), on) = count_launches(false, || run(case, &device, DType::F32));
    let ((burn, _), off) = {
        let _off = Unfused::new(set_fused_residual);
        count_launches(false, || run(case, &device, DType::F32))
    };
    let (on, off) = (on.total(), off.total());
    println!("launches of one residual, forward and backward: fused {on}, Burn's ops {off}");
    assert!(
        on + 5 <= off,
        "fused {on} launches against Burn's ops {off}"
    );
    assert_eq!(fused[0], burn[0]);
}

/// Guards the block's use of the fused op (the wiring a kernel test cannot see: a
/// projection whose bias or shape made the block fall back to Burn's ops): one block's
/// forward and backward on wgpu launches the fused residual twice each way (after the
/// attention and after the MLP).
#[test]
fn a_block_takes_the_fused_residual_twice() {
    use envision4d_model::layers::attention::QkNorm;
    use envision4d_model::layers::block::{Block, BlockSpec};
    let _turn = turn();
    let Some(gpu) = gpu() else { return };
    let device = gpu.autodiff();
    let spec = BlockSpec {
        dim: 32,
        num_heads: 4,
        mlp_ratio: 4,
        qk_norm: QkNorm::On,
        norm_eps: 1e-5,
        layer_scale_init: 0.1,
    };
    let block = Block::new(spec, &device);
    let x = Tensor::<3>::from_data(
        TensorData::new(uniform(2 * 20 * 32, 1), [2, 20, 32]).convert_dtype(DType::F32),
        &device,
    )
    .require_grad();
    let pass = || {
        let g = block.forward(x.clone(), None).sum().backward();
        x.grad(&g).map(host).expect("dx")
    };
    let _ = pass();
    let (_, launches) = count_launches(true, pass);
    let forward = launches.of("ScaledResidualForward");
    let backward = launches.of("ScaledResidualBackward");
    println!("fused residual launches of one block: {forward} forward, {backward} backward");
    assert_eq!((forward, backward), (2, 2));
}
