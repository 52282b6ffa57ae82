//! The fused LayerNorm (`layers::norm`) against Burn's, in f64 on the CPU as the oracle: values
//! and the three gradients, on friendly and stiff rows, through the CubeCL kernels (wgpu on
//! lavapipe) and through the node's decomposed bodies.

use burn::module::Param;
use burn::nn::{LayerNorm, LayerNormConfig};
use burn::tensor::{DType, Device, Tensor, TensorData};
use envision4d_model::bench::count_launches;
use envision4d_model::layers::norm::{
    epsilon_of, fused_layer_norm, layer_norm, set_fused_layer_norm, takes_fused,
};
use support::{gpu, host, rel_err_floor, turn, uniform_f64 as uniform, Unfused};

mod support;

/// What the rows hold.
#[derive(Debug, Clone, Copy)]
enum Rows {
    /// Uniform in [-2, 2).
    Friendly,
    /// 1e4 plus uniform in [-1, 1): a mean far above the spread.
    Offset,
    /// Every row one repeated value: zero variance, `rstd = 1/sqrt(eps)`.
    Constant,
    /// Uniform in [-1e-4, 1e-4): a variance below epsilon.
    Tiny,
}

/// The input rows, rounded to f32 (both sides see the same values).
fn rows_of(kind: Rows, rows: usize, cols: usize, seed: u64) -> Vec<f64> {
    let u = uniform(rows * cols, seed);
    let v: Vec<f64> = match kind {
        Rows::Friendly => u.iter().map(|x| 2.0 * x).collect(),
        Rows::Offset => u.iter().map(|x| 1e4 + x).collect(),
        Rows::Constant => (0..rows * cols).map(|i| u[i / cols * cols] * 3.0).collect(),
        Rows::Tiny => u.iter().map(|x| 1e-4 * x).collect(),
    };
    v.into_iter().map(|x| x as f32 as f64).collect()
}

fn tensor<const D: usize>(
    v: &[f64],
    shape: [usize; D],
    device: &Device,
    dtype: DType,
) -> Tensor<D> {
    Tensor::from_data(
        TensorData::new(v.to_vec(), shape).convert_dtype(dtype),
        (device, dtype),
    )
}

/// `max |a - b| / max(1, max |b|)`.
fn rel_err(a: &[f64], b: &[f64]) -> f64 {
    rel_err_floor(a, b, 1.0)
}

/// `y`, dx, dgamma, dbeta of `sum(y · w)` for a LayerNorm of `[2, rows/2 or 1, cols]`
/// (a rank-3 input, as the blocks give it) on `device` in `dtype`; `fused` calls
/// [`fused_layer_norm`] directly, otherwise [`layer_norm`] (which routes by device).
fn run(
    data: &[f64],
    [a, b, cols]: [usize; 3],
    eps: f64,
    device: &Device,
    dtype: DType,
    fused: bool,
) -> [Vec<f64>; 4] {
    let params = uniform(3 * cols, 7);
    let gamma = tensor(
        &params[..cols]
            .iter()
            .map(|g| 1.0 + 0.5 * g)
            .collect::<Vec<_>>(),
        [cols],
        device,
        dtype,
    );
    let beta = tensor(&params[cols..2 * cols], [cols], device, dtype);
    let w = tensor(&uniform(a * b * cols, 11), [a, b, cols], device, dtype);
    let mut norm = LayerNormConfig::new(cols).with_epsilon(eps).init(device);
    norm.gamma = Param::from_tensor(gamma.clone());
    norm.beta = Some(Param::from_tensor(beta));
    let x = tensor(data, [a, b, cols], device, dtype).require_grad();
    let y = if fused {
        let beta = norm.beta.as_ref().expect("beta").val();
        fused_layer_norm(x.clone(), norm.gamma.val(), beta, eps)
    } else {
        layer_norm(&norm, x.clone())
    };
    let grads = (y.clone() * w).sum().backward();
    [
        host(y),
        host(x.grad(&grads).expect("x gradient")),
        host(norm.gamma.grad(&grads).expect("gamma gradient")),
        host(
            norm.beta
                .as_ref()
                .expect("beta")
                .grad(&grads)
                .expect("beta gradient"),
        ),
    ]
}

const NAMES: [&str; 4] = ["y", "dx", "dgamma", "dbeta"];

/// Compares `device` (through [`layer_norm`] or the op itself) with Burn's LayerNorm in f64
/// on the CPU for every shape and kind of row; returns the worst error of each output.
fn worst_errors(device: &Device, dtype: DType, fused: bool) -> [f64; 4] {
    let oracle = Device::flex().autodiff();
    let mut worst = [0.0f64; 4];
    let shapes = [
        [1, 1, 1],
        [2, 3, 5],
        [2, 2, 64],
        [1, 7, 65],
        [2, 150, 200],
        [2, 300, 64],
        [1, 3, 1024],
    ];
    for (k, shape) in shapes.into_iter().enumerate() {
        let [a, b, cols] = shape;
        for kind in [Rows::Friendly, Rows::Offset, Rows::Constant, Rows::Tiny] {
            for eps in [1e-6, 1e-5] {
                let data = rows_of(kind, a * b, cols, k as u64 + 1);
                let want = run(&data, shape, eps, &oracle, DType::F64, false);
                let got = run(&data, shape, eps, device, dtype, fused);
                for (i, (g, w)) in got.iter().zip(&want).enumerate() {
                    let e = rel_err(g, w);
                    assert!(
                        e.is_finite(),
                        "{} of {shape:?}, {kind:?}, eps {eps}: not finite",
                        NAMES[i]
                    );
                    worst[i] = worst[i].max(e);
                }
            }
        }
    }
    worst
}

/// Guards the fused kernels (the forward's two-pass statistics around a shifted mean, the
/// input gradient, the parameter gradients summed over row chunks, rows longer than a cube
/// and shorter ones, more rows than one chunk): values and gradients on wgpu equal Burn's
/// LayerNorm in f64 within f32 rounding, on rows near 1e4, constant rows and rows below
/// epsilon too. Rows near 1e4 need the centring on each row's first value: through an f32
/// mean, as Burn's own decomposition takes them (printed for comparison), y is off by about
/// 5e-3 and dgamma by 2e-2.
#[test]
fn fused_kernels_equal_burns_layer_norm_on_wgpu() {
    let _turn = turn();
    let Some(device) = gpu().map(Device::autodiff) else {
        return;
    };
    assert!(takes_fused(&device, DType::F32));
    let worst = worst_errors(&device, DType::F32, false);
    let burns = {
        let _burns = Unfused::new(set_fused_layer_norm);
        worst_errors(&device, DType::F32, false)
    };
    eprintln!(
        "worst relative errors (y, dx, dgamma, dbeta): fused {worst:?}, Burn's f32 {burns:?}"
    );
    for (i, e) in worst.into_iter().enumerate() {
        assert!(e < 1e-5, "{}: relative error {e}", NAMES[i]);
    }
}

/// Guards the autodiff node and the decomposed bodies (what the kernels are held to, and what
/// other float types run): in f64 on the CPU they equal Burn's LayerNorm and its autodiff to
/// rounding.
#[test]
fn the_node_equals_burns_autodiff_in_f64() {
    let _turn = turn();
    let worst = worst_errors(&Device::flex().autodiff(), DType::F64, true);
    for (i, e) in worst.into_iter().enumerate() {
        assert!(e < 1e-9, "{}: relative error {e}", NAMES[i]);
    }
}

/// Guards the routing: the CPU keeps Burn's op bit for bit, a GPU device runs one kernel for
/// the forward (Burn's decomposition launches several), the switch turns it off, and the
/// epsilon a norm was built with is read back exactly.
#[test]
fn layer_norm_routes_by_device_and_reads_the_epsilon() {
    let _turn = turn();
    for eps in [1e-6, 1e-5, 1e-12, 0.1, 3.0e-7] {
        let norm = LayerNormConfig::new(4)
            .with_epsilon(eps)
            .init(&Device::flex());
        assert_eq!(epsilon_of(&norm), Some(eps));
    }
    let cpu = Device::flex();
    assert!(!takes_fused(&cpu, DType::F32) && !takes_fused(&cpu.clone().autodiff(), DType::F32));
    let data = rows_of(Rows::Friendly, 6, 48, 3);
    let norm = LayerNormConfig::new(48).init(&cpu);
    let x = tensor(&data, [2, 3, 48], &cpu, DType::F32);
    assert_eq!(host(layer_norm(&norm, x.clone())), host(norm.forward(x)));

    let Some(gpu) = gpu() else {
        return;
    };
    let norm: LayerNorm = LayerNormConfig::new(48).init(&gpu);
    let x = tensor(&data, [2, 3, 48], &gpu, DType::F32);
    // The first call initialises the lazy parameters (two fills); count a second.
    let _ = layer_norm(&norm, x.clone());
    let launches = |on: bool| {
        let _burns = (!on).then(|| Unfused::new(set_fused_layer_norm));
        let (y, counted) = count_launches(false, || layer_norm(&norm, x.clone()));
        (host(y), counted.total())
    };
    let (fused, fused_launches) = launches(true);
    let (burn, burn_launches) = launches(false);
    assert_eq!(fused_launches, 1, "the fused forward is one kernel");
    assert!(
        burn_launches >= 5,
        "Burn's decomposition: {burn_launches} launches"
    );
    assert!(rel_err(&fused, &burn) < 1e-5);
}

/// Guards half-precision inputs on the fused path: f16 tokens in the hundreds (whose squares
/// overflow f16) are normalised in f32 and narrowed back, like Burn's LayerNorm does. Skipped
/// where the adapter has no f16.
#[test]
fn fused_layer_norm_of_large_f16_tokens_is_finite() {
    let _turn = turn();
    let Some(gpu) = gpu() else {
        return;
    };
    if !gpu.supports_dtype(DType::F16) {
        eprintln!("skipped: this wgpu adapter has no f16");
        return;
    }
    let data: Vec<f64> = uniform(16 * 64, 5).iter().map(|u| 2000.0 * u).collect();
    let norm = LayerNormConfig::new(64).init(&gpu);
    let want = host(norm.forward(tensor(&data, [2, 8, 64], &gpu, DType::F32)));
    let got = layer_norm(&norm, tensor(&data, [2, 8, 64], &gpu, DType::F16));
    assert_eq!(got.dtype(), DType::F16);
    let e = rel_err(&host(got), &want);
    assert!(e.is_finite() && e < 1e-2, "f16 LayerNorm off by {e}");
}

/// Guards the cases the comparison above does not reach: more rows than one grid axis holds
/// (65,535 cubes; the q/k norms of a paper-size step have more), so the launch grid turns
/// two-dimensional; a norm without beta; and a frozen norm (gamma and beta without
/// gradients), whose backward computes the input gradient alone, in one launch.
#[test]
fn many_rows_no_beta_and_frozen_parameters() {
    let _turn = turn();
    let Some(gpu) = gpu() else {
        return;
    };
    let cpu = Device::flex();
    let rows = 70_000;
    let data = rows_of(Rows::Friendly, rows, 8, 9);
    let norm_on = |device: &Device, bias: bool| {
        let mut norm = LayerNormConfig::new(8).with_bias(bias).init(device);
        let g: Vec<f64> = uniform(8, 4).iter().map(|u| 1.0 + 0.5 * u).collect();
        norm.gamma = Param::from_tensor(tensor(&g, [8], device, DType::F32));
        norm
    };
    for bias in [true, false] {
        let want = norm_on(&cpu, bias).forward(tensor(&data, [1, rows, 8], &cpu, DType::F32));
        let got = layer_norm(
            &norm_on(&gpu, bias),
            tensor(&data, [1, rows, 8], &gpu, DType::F32),
        );
        let e = rel_err(&host(got), &host(want));
        assert!(e < 1e-5, "{rows} rows, bias {bias}: relative error {e}");
    }

    // Frozen: the input gradient equals Burn's, without the parameter kernel's launch.
    let backward = |device: &Device, trainable: bool| {
        let mut norm = norm_on(device, true);
        norm.gamma = norm.gamma.clone().set_require_grad(trainable);
        norm.beta = norm.beta.clone().map(|b| b.set_require_grad(trainable));
        let x = tensor(&data[..64 * 8], [1, 64, 8], device, DType::F32).require_grad();
        let y = layer_norm(&norm, x.clone());
        let w = tensor(&uniform(64 * 8, 2), [1, 64, 8], device, DType::F32);
        let loss = (y * w).sum();
        let (grads, counted) = count_launches(false, || loss.backward());
        (host(x.grad(&grads).expect("x gradient")), counted.total())
    };
    let (want, _) = backward(&cpu.autodiff(), false);
    let (got, frozen) = backward(&gpu.clone().autodiff(), false);
    let (_, trainable) = backward(&gpu.autodiff(), true);
    assert!(rel_err(&got, &want) < 1e-5);
    assert_eq!(
        frozen + 1,
        trainable,
        "a frozen norm's backward skips the parameter kernel"
    );
}

/// Guards the kernels' flat indexing on inputs that are views, not fresh buffers (the q/k
/// norms take slices of the qkv projection; a transposed tensor is strided): values and the
/// input gradient of a transposed input and of a column slice equal the CPU's, and so do
/// the input gradients of 70,000 rows, whose backward launches on a two-dimensional grid.
#[test]
fn strided_inputs_and_a_two_dimensional_backward_grid() {
    let _turn = turn();
    let Some(gpu) = gpu() else {
        return;
    };
    let cpu = Device::flex();
    let cols = 24;
    let g: Vec<f64> = uniform(cols, 5).iter().map(|u| 1.0 + 0.5 * u).collect();
    let b = uniform(cols, 6);
    // `view` makes `[rows, cols]` out of a stored tensor of `stored` shape.
    let check = |rows: usize, stored: [usize; 2], view: &dyn Fn(Tensor<2>) -> Tensor<2>| {
        let data = rows_of(Rows::Friendly, stored[0], stored[1], 3);
        let w = uniform(rows * cols, 8);
        let on = |device: &Device| {
            let x = tensor(&data, stored, device, DType::F32).require_grad();
            let y = fused_layer_norm(
                view(x.clone()),
                tensor(&g, [cols], device, DType::F32),
                tensor(&b, [cols], device, DType::F32),
                1e-6,
            );
            let grads = (y.clone() * tensor(&w, [rows, cols], device, DType::F32))
                .sum()
                .backward();
            [host(y), host(x.grad(&grads).expect("x gradient"))]
        };
        let (want, got) = (on(&cpu.clone().autodiff()), on(&gpu.clone().autodiff()));
        for (name, (got, want)) in ["y", "dx"].iter().zip(got.iter().zip(&want)) {
            let e = rel_err(got, want);
            assert!(e < 1e-4, "{stored:?} as {rows} rows: {name} off by {e}");
        }
    };
    check(40, [cols, 40], &|x| x.swap_dims(0, 1));
    check(40, [40, 3 * cols], &|x| x.narrow(1, cols, cols));
    check(70_000, [70_000, cols], &|x| x);
}

/// Guards the public op's width check: a gamma narrower than the rows is refused with the
/// widths named, as Burn's LayerNorm refuses it, rather than read past its end on a GPU.
#[test]
#[should_panic(expected = "LayerNorm gamma of width 4 applied to rows of 8")]
fn a_gamma_of_the_wrong_width_is_refused() {
    let cpu = Device::flex();
    let x = tensor(&uniform(16, 1), [2, 8], &cpu, DType::F32);
    let ones = |n: usize| tensor(&vec![1.0; n], [n], &cpu, DType::F32);
    let _ = fused_layer_norm(x, ones(4), ones(8), 1e-5);
}

/// Guards the GPU op's own check of beta (which the packed attention calls without the public
/// wrapper): a beta narrower than the rows is refused with the widths named, where the
/// forward kernel read past its end and returned a result (and so did the decomposed body:
/// the backends do not check broadcasts).
#[test]
fn the_gpu_op_refuses_a_narrow_beta() {
    use burn::backend::Dispatch;
    use envision4d_model::layers::norm::FusedNormOps;
    let _turn = turn();
    let Some(gpu) = gpu() else { return };
    let x = tensor(&uniform(16, 1), [2, 8], &gpu, DType::F32);
    let ones = |n: usize| tensor(&vec![1.0; n], [n], &gpu, DType::F32);
    let (gamma, beta) = (ones(8), ones(4));
    let run = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        let (y, _, _) = <Dispatch as FusedNormOps>::fused_layer_norm_forward(
            x.into_dispatch(),
            gamma.into_dispatch(),
            beta.into_dispatch(),
            1e-5,
        );
        host(Tensor::<2>::from_dispatch(y))
    }));
    let message = run.expect_err("a beta of 4 was applied to rows of 8");
    let text = message
        .downcast_ref::<String>()
        .cloned()
        .unwrap_or_default();
    assert!(
        text.contains("LayerNorm beta of width 4 applied to rows of 8"),
        "unexpected message: {text}"
    );
}
