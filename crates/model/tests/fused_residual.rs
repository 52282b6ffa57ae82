//! The fused LayerScale residual `x + u ⊙ γ` (one kernel forward, one backward) on wgpu
//! against the same sum in Burn's ops in f64 on the CPU: output and all three gradients,
//! with one chunk of rows and many (the gain's partial sums reduced again), one channel,
//! tokens near f32's range ends, a frozen gain (the backward skips its sums), constant
//! tokens, and more elements than one grid axis of workgroups holds.

use burn::tensor::{DType, Device, Tensor, TensorData};
use envision4d_model::bench::count_launches;
use envision4d_model::layers::residual::kernels::GAIN_ROWS;
use envision4d_model::layers::residual::{scaled_residual, set_fused_residual};
use support::{assert_chunked_sums, gpu, host, rel_err, turn, uniform, Unfused};

mod support;

/// Tokens `[b, n, c]` (`u` scaled by `gain`); `frozen`: γ takes no gradient; `constant`: nor
/// does `u`.
#[derive(Debug, Clone, Copy)]
struct Case {
    b: usize,
    n: usize,
    c: usize,
    gain: f64,
    frozen: bool,
    constant: bool,
}

/// `[y, dx, du, dγ]` of `sum((x + u ⊙ γ) · w)` (an absent gradient as an empty vector), and
/// `Σ_rows |w · u|` per channel, the scale of dγ's rounding.
fn run(case: Case, device: &Device, dtype: DType) -> ([Vec<f64>; 4], Vec<f64>) {
    let shape = [case.b, case.n, case.c];
    let len = shape.iter().product();
    let tensor = |v: Vec<f64>| {
        Tensor::<3>::from_data(
            TensorData::new(v, shape).convert_dtype(dtype),
            (device, dtype),
        )
    };
    let x = tensor(uniform(len, 1)).require_grad();
    let u_host: Vec<f64> = uniform(len, 2).into_iter().map(|v| v * case.gain).collect();
    let w_host = uniform(len, 3);
    let mut u = tensor(u_host.clone());
    if !case.constant {
        u = u.require_grad();
    }
    let mut gamma = Tensor::<1>::from_data(
        TensorData::new(uniform(case.c, 4), [case.c]).convert_dtype(dtype),
        (device, dtype),
    );
    if !case.frozen {
        gamma = gamma.require_grad();
    }
    let y = scaled_residual(x.clone(), u.clone(), gamma.clone());
    let g = (y.clone() * tensor(w_host.clone())).sum().backward();
    let grad3 = |t: &Tensor<3>| t.grad(&g).map(host).unwrap_or_default();
    let dgamma = gamma.grad(&g).map(host).unwrap_or_default();
    let mut scale = vec![0.0f64; case.c];
    for (i, (w, u)) in w_host.iter().zip(&u_host).enumerate() {
        scale[i % case.c] += (w * u).abs();
    }
    ([host(y), grad3(&x), grad3(&u), dgamma], scale)
}

fn cases() -> Vec<Case> {
    let case = Case {
        b: 2,
        n: 37,
        c: 48,
        gain: 1.0,
        frozen: false,
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
            frozen: true,
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

/// Guards the fused residual and its wiring (the channel of each element, the gradient of
/// the stream passed through, `u`'s gradient scaled by γ, γ's chunked sums and their second
/// reduction, the gradients skipped for a frozen gain or constant tokens, the 2-D grid): on
/// wgpu the output and `u`'s gradient equal Burn's ops bit for bit (the output to an ulp on
/// CUDA) and the f64 sums to f32 rounding; γ's gradient is within recursive summation's bound of the f64 sum.
#[test]
fn fused_residual_equals_f64_on_wgpu() {
    let _turn = turn();
    let Some(gpu) = gpu() else { return };
    let device = gpu.autodiff();
    let oracle = Device::flex().autodiff();
    for case in cases() {
        let (want, scale) = run(case, &oracle, DType::F64);
        let (fused, _) = run(case, &device, DType::F32);
        let (burn, _) = {
            let _off = Unfused::new(set_fused_residual);
            run(case, &device, DType::F32)
        };
        for (i, name) in ["y", "dx", "du", "dgamma"].into_iter().enumerate() {
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
            if name == "dgamma" {
                let rows = case.b * case.n;
                let what = format!("{case:?}: dgamma");
                let shape = [rows, GAIN_ROWS as usize, 0];
                assert_chunked_sums(&what, &fused[i], &want[i], &scale, shape);
            } else {
                assert!(e <= 1.2e-7, "{case:?}: {name} relative error {e:.3e}");
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

/// Guards the launches the op exists for: one residual forward and backward on wgpu takes
/// fewer kernels fused than in Burn's ops (a product and a sum forward; a product, and a
/// product and a reduction for γ, backward), with the same output.
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
        on + 3 <= off,
        "fused {on} launches against Burn's ops {off}"
    );
    assert_eq!(fused[0], burn[0]);
}
