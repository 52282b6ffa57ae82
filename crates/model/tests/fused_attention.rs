//! The lean attention's fused row kernels (softmax, probabilities from the log-sum-exp, the
//! softmax VJP, the row dot) on wgpu against Burn's attention in f64 on the CPU: output and
//! the three gradients, on friendly, sharp and extreme rows, rows shorter and longer than a
//! cube, several query blocks, and more rows than one grid axis holds.

use burn::tensor::module::attention;
use burn::tensor::ops::AttentionModuleOptions;
use burn::tensor::{DType, Device, Tensor, TensorData};
use envision4d_model::bench::count_launches;
use envision4d_model::layers::lean_attention::{lean_attention_blocked, set_fused_softmax};
use support::{gpu, host, rel_err_floor, turn, uniform, Unfused};

mod support;

fn tensor(v: &[f64], shape: [usize; 4], device: &Device, dtype: DType) -> Tensor<4> {
    Tensor::from_data(
        TensorData::new(v.to_vec(), shape).convert_dtype(dtype),
        (device, dtype),
    )
}

/// `max |a - b| / max(1e-30, max |b|)`.
fn rel_err(a: &[f64], b: &[f64]) -> f64 {
    rel_err_floor(a, b, 1e-30)
}

/// One case: q `[b, h, nq, d]`, k and v `[b, h, nk, d]`, q scaled by `gain` (how sharp
/// the rows are), blocks of about `block` score elements; `swapped`: the loss reads the
/// output through `swap_dims(1, 2)`, as the model does, so its gradient arrives strided.
#[derive(Debug, Clone, Copy)]
struct Case {
    dims: [usize; 5],
    gain: f64,
    block: usize,
    swapped: bool,
}

/// Output and the q/k/v gradients of `sum(attn(q, k, v) · w)`: `lean` through the op,
/// otherwise Burn's attention.
fn run(case: Case, device: &Device, dtype: DType, lean: bool) -> [Vec<f64>; 4] {
    let [b, h, nq, nk, d] = case.dims;
    let q = uniform(b * h * nq * d, 1)
        .into_iter()
        .map(|x| x * case.gain)
        .collect::<Vec<_>>();
    let (qs, ks) = ([b, h, nq, d], [b, h, nk, d]);
    let q = tensor(&q, qs, device, dtype).require_grad();
    let k = tensor(&uniform(b * h * nk * d, 2), ks, device, dtype).require_grad();
    let v = tensor(&uniform(b * h * nk * d, 3), ks, device, dtype).require_grad();
    let w = tensor(&uniform(b * h * nq * d, 4), qs, device, dtype);
    let out = if lean {
        lean_attention_blocked(q.clone(), k.clone(), v.clone(), case.block)
    } else {
        let options = AttentionModuleOptions::default();
        attention(q.clone(), k.clone(), v.clone(), None, None, options)
    };
    let loss = if case.swapped {
        (out.clone().swap_dims(1, 2) * w.swap_dims(1, 2)).sum()
    } else {
        (out.clone() * w).sum()
    };
    let g = loss.backward();
    let grad = |t: &Tensor<4>| host(t.grad(&g).expect("a gradient"));
    [host(out), grad(&q), grad(&k), grad(&v)]
}

const NAMES: [&str; 4] = ["out", "dq", "dk", "dv"];

/// A case whose loss reads the output as it is (see [`Case`]).
fn case(dims: [usize; 5], gain: f64, block: usize) -> Case {
    Case {
        dims,
        gain,
        block,
        swapped: false,
    }
}

/// `run(case)` through the op in f32 and the kernels it launched, counted after one
/// untimed run has compiled them and settled the matmuls' autotune.
fn warmed_launches(case: Case, device: &Device) -> ([Vec<f64>; 4], usize) {
    let _ = run(case, device, DType::F32, true);
    let (out, launches) = count_launches(false, || run(case, device, DType::F32, true));
    (out, launches.total())
}

/// The cases, and the worst relative error each tensor may have against f64.
fn cases() -> Vec<(Case, f64)> {
    let swapped = |c: Case| Case { swapped: true, ..c };
    vec![
        // Friendly rows; one key (the softmax is 1 and every score gradient 0).
        (case([2, 3, 37, 29, 8], 1.0, 1 << 24), 2e-6),
        (swapped(case([2, 3, 37, 29, 8], 1.0, 1 << 24)), 2e-6),
        (case([1, 2, 5, 1, 4], 1.0, 1 << 24), 2e-6),
        // Rows longer than a cube (300 keys: about five per unit), three query blocks and a
        // partial fourth.
        (case([1, 2, 70, 300, 16], 1.0, 2 * 300 * 20), 2e-6),
        (swapped(case([1, 2, 70, 300, 16], 1.0, 2 * 300 * 20)), 2e-6),
        // Sharp rows (logits up to about 40) and extreme ones (up to about 4e3: exp
        // overflows f32 without the max shift, every row one-hot). An f32 logit near 4e3
        // is only known to half an ulp, 2.4e-4, so the weights of nearly tied keys, and dq
        // through them, carry relative errors of that order on any f32 path (Burn's
        // decomposition measures 4.8e-4 on this case): the bound is that conditioning.
        (case([2, 2, 33, 65, 8], 40.0, 1 << 24), 2e-5),
        (case([1, 2, 17, 64, 8], 4e3, 1 << 24), 1e-3),
        // More rows (B·H·Nq = 70,000) than one grid axis holds (65,535 cubes).
        (case([1, 1, 70_000, 3, 4], 1.0, 1 << 24), 2e-6),
    ]
}

/// Guards the fused row kernels and their wiring into the blocked recurrence (the max
/// shift, the normalised probabilities, the log-sum-exp the backward recomputes from, the
/// VJP's row term, read in place from a strided gradient, statistics rows against score
/// rows, the 2-D grid): on wgpu they equal
/// Burn's attention in f64 to f32 rounding, on extreme rows too, and so does the
/// decomposition they replace on the same device, which they never do worse than.
#[test]
fn fused_attention_rows_equal_f64_attention_on_wgpu() {
    let _turn = turn();
    let Some(gpu) = gpu() else { return };
    let device = gpu.autodiff();
    let oracle = Device::flex().autodiff();
    for (case, tolerance) in cases() {
        let want = run(case, &oracle, DType::F64, false);
        let fused = run(case, &device, DType::F32, true);
        let decomposed = {
            let _off = Unfused::new(set_fused_softmax);
            run(case, &device, DType::F32, true)
        };
        for i in 0..4 {
            let (e, e_dec) = (
                rel_err(&fused[i], &want[i]),
                rel_err(&decomposed[i], &want[i]),
            );
            println!(
                "{case:?} {}: fused {e:.2e}, decomposed {e_dec:.2e}",
                NAMES[i]
            );
            assert!(
                e <= tolerance,
                "{case:?}: {} relative error {e:.3e} over {tolerance:.0e}",
                NAMES[i]
            );
            // And no worse than the decomposition it replaces (twice its error, plus a
            // margin for a different summation order on rows it gets exactly right).
            assert!(
                e <= 2.0 * e_dec + 1e-6,
                "{case:?}: {} fused error {e:.3e} against decomposed {e_dec:.3e}",
                NAMES[i]
            );
        }
    }
}

/// Guards the launch savings the kernels exist for: one block's forward and backward on
/// wgpu launch at least ten fewer kernels fused than decomposed (the softmax's eight become
/// one, the backward's six become three), with the same output.
#[test]
fn fused_attention_rows_launch_fewer_kernels() {
    let _turn = turn();
    let Some(gpu) = gpu() else { return };
    let device = gpu.autodiff();
    let case = case([1, 2, 24, 24, 8], 1.0, 1 << 24);
    let (fused, on) = warmed_launches(case, &device);
    let (decomposed, off) = {
        let _off = Unfused::new(set_fused_softmax);
        warmed_launches(case, &device)
    };
    println!("launches of one block, forward and backward: fused {on}, decomposed {off}");
    assert!(
        on + 10 <= off,
        "fused {on} launches against decomposed {off}"
    );
    for i in 0..4 {
        let e = rel_err(&fused[i], &decomposed[i]);
        assert!(
            e < 1e-5,
            "{}: fused and decomposed differ by {e:.2e}",
            NAMES[i]
        );
    }
}

/// Guards the one relayout of a strided output gradient: the model reads the attention's
/// output through `swap_dims(1, 2)`, so its gradient arrives as a view Burn's matrix product
/// copies before reading; the backward copies it once, not in both products of each of four
/// query blocks (eight copies), so the swapped case launches at most one kernel more than the
/// same case with a contiguous gradient, and both give the same values.
#[test]
fn a_swapped_gradient_is_relaid_out_once_per_backward() {
    let _turn = turn();
    let Some(gpu) = gpu() else { return };
    let device = gpu.autodiff();
    // 70 query rows in blocks of 20: three whole blocks and a partial fourth.
    let plain = case([1, 2, 70, 300, 16], 1.0, 2 * 300 * 20);
    let swapped = Case {
        swapped: true,
        ..plain
    };
    let (want, contiguous) = warmed_launches(plain, &device);
    let (got, strided) = warmed_launches(swapped, &device);
    println!("launches, forward and backward: contiguous gradient {contiguous}, swapped {strided}");
    assert!(
        strided <= contiguous + 1,
        "swapped gradient: {strided} launches against {contiguous} for a contiguous one"
    );
    for i in 0..4 {
        let e = rel_err(&got[i], &want[i]);
        assert!(
            e < 1e-6,
            "{}: swapped and contiguous differ by {e:.2e}",
            NAMES[i]
        );
    }
}
