//! The fused Adam (`adam::FusedAdam`) against Burn's `Adam`: the same parameters after
//! several steps on wgpu (lavapipe) and on the CPU, one kernel per tensor, and records that
//! either optimiser resumes from; and the NaN guard's check, one kernel per tensor too.

use burn::module::{Module, Param};
use burn::optim::{AdamConfig, GradientsParams, ModuleOptimizer};
use burn::tensor::{Device, Tensor, TensorData};
use envision4d_model::bench::count_launches;
use envision4d_train::adam::{set_fused_adam, FusedAdam};
use envision4d_train::freeze::params_finite;
use std::collections::HashSet;
use std::sync::Mutex;

/// The launch counter and the fused switch are process-wide: these tests take turns.
static SERIAL: Mutex<()> = Mutex::new(());

/// The test GPU (wgpu, lavapipe in CI; CUDA with `ENVISION4D_TEST_GPU=cuda`) with autodiff,
/// `None` where `ENVISION4D_SKIP_WGPU=1` and no adapter exists.
fn gpu() -> Option<Device> {
    envision4d_splat::testkit::wgpu_test_device().map(Device::autodiff)
}

/// Burn's Adam until dropped, so a failing assertion cannot leave the kernel off for the
/// next test.
struct BurnsAdam;

impl BurnsAdam {
    fn new() -> Self {
        set_fused_adam(false);
        BurnsAdam
    }
}

impl Drop for BurnsAdam {
    fn drop(&mut self) {
        set_fused_adam(true);
    }
}

const EPS: f32 = 1e-8;

#[derive(Module, Debug)]
struct Toy {
    a: Param<Tensor<2>>,
    b: Param<Tensor<1>>,
}

/// Gradient values, stiff ones included: zero, 1e-20 (its square is subnormal in f32, which a
/// GPU may flush), 1e15 (its square near 1e30), mixed signs.
const GRADS: [f32; 12] = [
    0.0, 1e-20, -1e-20, 1e15, -3.0, 0.25, 1e-3, -7e4, 1.0, -1.0, 2.5e-8, 42.0,
];

fn toy(device: &Device) -> Toy {
    let a: Vec<f32> = (0..8).map(|i| 0.1 * i as f32 - 0.3).collect();
    Toy {
        a: Param::from_tensor(Tensor::from_data(TensorData::new(a, [2, 4]), device)),
        b: Param::from_tensor(Tensor::from_data(
            TensorData::new(vec![1.0f32, -2.0, 1e3, -1e-6], [4]),
            device,
        )),
    }
}

/// A parameter near 1e3 still moves by a visible step in f32 (its ulp is 6e-5), and one near
/// -1e-6 is far below the steps, so the sign of the update shows.
///
/// Gradients equal to `GRADS` scaled by `scale`: those of `Σ a·ga + Σ b·gb`.
fn grads(model: &Toy, scale: f32, device: &Device) -> GradientsParams {
    let g: Vec<f32> = GRADS.iter().map(|g| g * scale).collect();
    let ga = Tensor::<2>::from_data(TensorData::new(g[..8].to_vec(), [2, 4]), device);
    let gb = Tensor::<1>::from_data(TensorData::new(g[8..].to_vec(), [4]), device);
    let loss = (model.a.val() * ga).sum() + (model.b.val() * gb).sum();
    GradientsParams::from_grads(loss.backward(), model)
}

fn values(model: &Toy) -> Vec<f64> {
    let mut v: Vec<f64> = model
        .a
        .val()
        .into_data()
        .convert::<f64>()
        .try_to_vec()
        .unwrap();
    v.extend(
        model
            .b
            .val()
            .into_data()
            .convert::<f64>()
            .try_to_vec::<f64>()
            .unwrap(),
    );
    v
}

/// Scales and learning rates of the steps: the moments see gradients that change size and
/// sign, and the bias corrections four step counts.
const STEPS: [(f32, f64); 4] = [(1.0, 1e-2), (-0.5, 3e-3), (2.0, 1e-3), (0.1, 5e-2)];

/// The parameters after each of `STEPS` from `optim`, starting at step `from`.
fn run(
    mut model: Toy,
    optim: &mut ModuleOptimizer,
    device: &Device,
    steps: &[(f32, f64)],
) -> (Toy, Vec<Vec<f64>>) {
    let mut after = Vec::new();
    for &(scale, lr) in steps {
        let g = grads(&model, scale, device);
        model = optim.step(lr, model, g);
        after.push(values(&model));
    }
    (model, after)
}

fn fused() -> ModuleOptimizer {
    ModuleOptimizer::from(FusedAdam::new(EPS))
}

fn burns() -> ModuleOptimizer {
    AdamConfig::new().with_epsilon(EPS).init()
}

/// `max |a - b| / max(|b|, 1e-6)` elementwise (relative, with a floor for the parameters
/// that sit near zero).
fn worst(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs() / y.abs().max(1e-6))
        .fold(0.0, f64::max)
}

/// Guards the kernel's arithmetic (moments, the first step's start, bias corrections folded
/// into two scalars, the step's order): four steps on wgpu give Burn's Adam's parameters on
/// wgpu and on the CPU to f32 rounding, on stiff gradients too.
#[test]
fn fused_adam_steps_like_burns_adam() {
    let _turn = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let Some(gpu) = gpu() else {
        return;
    };
    let cpu = Device::flex().autodiff();
    assert!(FusedAdam::takes_fused(&gpu, burn::tensor::DType::F32));
    assert!(!FusedAdam::takes_fused(&cpu, burn::tensor::DType::F32));
    let (_, ours) = run(toy(&gpu), &mut fused(), &gpu, &STEPS);
    let (_, burn_gpu) = run(toy(&gpu), &mut burns(), &gpu, &STEPS);
    let (_, burn_cpu) = run(toy(&cpu), &mut burns(), &cpu, &STEPS);
    for (k, ((o, g), c)) in ours.iter().zip(&burn_gpu).zip(&burn_cpu).enumerate() {
        let (eg, ec) = (worst(o, g), worst(o, c));
        assert!(
            eg < 1e-6 && ec < 1e-6,
            "step {k}: {eg:e} vs Burn on wgpu, {ec:e} on the CPU"
        );
    }
    // The parameters moved (a step that did nothing would pass the comparison).
    assert!(worst(&ours[3], &values(&toy(&cpu))) > 1e-3);
}

/// Guards the state's format: a record of the fused optimiser resumes it bit for bit, and
/// Burn's Adam resumes from it (and it from Burn's) to rounding, the checkpoint round trip
/// of a run continued on another backend or an older binary.
#[test]
fn fused_adam_records_resume_either_optimizer() {
    let _turn = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let Some(gpu) = gpu() else {
        return;
    };
    let (head, tail) = STEPS.split_at(2);
    let mut straight = fused();
    let (_, through) = run(toy(&gpu), &mut straight, &gpu, &STEPS);

    let mut first = fused();
    let (model, _) = run(toy(&gpu), &mut first, &gpu, head);
    let mut again = fused().load_record(first.to_record());
    let (_, resumed) = run(model.clone(), &mut again, &gpu, tail);
    assert_eq!(
        resumed,
        through[2..],
        "the fused optimiser resumed from its record"
    );

    let mut burn = burns().load_record(first.to_record());
    let (_, by_burn) = run(model, &mut burn, &gpu, tail);
    assert!(
        worst(&by_burn[1], &through[3]) < 1e-6,
        "Burn's Adam from the fused record"
    );

    let mut burn_first = burns();
    let (model, _) = run(toy(&gpu), &mut burn_first, &gpu, head);
    let mut fused_after = fused().load_record(burn_first.to_record());
    let (_, by_fused) = run(model, &mut fused_after, &gpu, tail);
    assert!(
        worst(&by_fused[1], &through[3]) < 1e-6,
        "the fused optimiser from Burn's record"
    );
}

/// Guards the point of it: an update launches one kernel per tensor on a GPU backend, where
/// Burn's launches many, and the switch turns it off.
#[test]
fn fused_adam_launches_one_kernel_per_tensor() {
    let _turn = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let Some(gpu) = gpu() else {
        return;
    };
    let launches = |on: bool| {
        let _burns = (!on).then(BurnsAdam::new);
        let mut optim = fused();
        let (model, _) = run(toy(&gpu), &mut optim, &gpu, &STEPS[..1]);
        let g = grads(&model, 1.0, &gpu);
        let (_, counted) = count_launches(false, || optim.step(1e-3, model, g));
        counted.total()
    };
    let (ours, burn) = (launches(true), launches(false));
    assert_eq!(ours, 2, "two tensors, two launches");
    assert!(burn >= 10 * 2, "Burn's Adam: {burn} launches");
}

/// Guards the NaN guard's GPU check: a pass over two tensors launches its flag's fill and one
/// kernel per tensor (the sum of `x·0` took three or four each), and still finds a NaN.
#[test]
fn the_finite_check_launches_one_kernel_per_tensor() {
    let _turn = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let Some(gpu) = gpu() else {
        return;
    };
    let model = toy(&gpu);
    let (finite, counted) = count_launches(false, || params_finite(&model, &HashSet::new()));
    assert!(finite);
    assert_eq!(counted.total(), 3, "one fill, two checks");
    let mut bad = toy(&gpu);
    bad.b = Param::from_tensor((bad.b.val() * f32::NAN).detach());
    assert!(!params_finite(&bad, &HashSet::new()));
}

/// Guards the kernel's reads of strided gradients (a weight used transposed gets its gradient
/// as a transposed view): two steps on wgpu from such gradients equal Burn's Adam's, and each
/// fused step reads the view in place, the first (no moments) and the second (moments read)
/// alike: two launches for two tensors, where a copy first made three.
#[test]
fn fused_adam_takes_strided_gradients() {
    let _turn = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let Some(gpu) = gpu() else {
        return;
    };
    let transposed_grads = |model: &Toy, scale: f32| {
        let g: Vec<f32> = GRADS[..8].iter().map(|g| g * scale).collect();
        let ga = Tensor::<2>::from_data(TensorData::new(g, [4, 2]), &gpu);
        let loss = (model.a.val().swap_dims(0, 1) * ga).sum() + model.b.val().sum();
        GradientsParams::from_grads(loss.backward(), model)
    };
    let steps = |mut optim: ModuleOptimizer| {
        let mut model = toy(&gpu);
        let mut launches = Vec::new();
        for (scale, lr) in [(1.0, 1e-2), (-0.5, 3e-3)] {
            let g = transposed_grads(&model, scale);
            let (next, counted) = count_launches(false, || optim.step(lr, model, g));
            model = next;
            launches.push(counted.total());
        }
        (values(&model), launches)
    };
    let _ = steps(fused()); // compile first
    let ((ours, launches), (burn, _)) = (steps(fused()), steps(burns()));
    let e = worst(&ours, &burn);
    assert!(e < 1e-6, "{e:e} from Burn's Adam");
    assert!(worst(&ours, &values(&toy(&gpu))) > 1e-3, "the steps moved");
    assert_eq!(
        launches,
        [2, 2],
        "two tensors, two launches a step, no copy"
    );
}

/// Guards the finite check's reads of views: a column slice of a buffer whose other columns
/// are NaN is finite (a check of the raw buffer would see them), and a NaN inside it is not.
#[test]
fn the_finite_check_reads_views_not_buffers() {
    let _turn = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let Some(gpu) = gpu() else {
        return;
    };
    let with_nan_at = |at: usize| {
        let mut v = vec![0.5f32; 16];
        v[at] = f32::NAN;
        let stored = Tensor::<2>::from_data(TensorData::new(v, [2, 8]), &gpu);
        let mut model = toy(&gpu);
        model.a = Param::from_tensor(stored.narrow(1, 0, 4).detach());
        params_finite(&model, &HashSet::new())
    };
    assert!(with_nan_at(5), "a NaN outside the slice is not the slice's");
    assert!(!with_nan_at(9), "a NaN inside the slice is found");
}

/// Guards the finite check's read of transposed tensors in memory order: a transposed view
/// (as a weight's gradient arrives) is checked without a copy (one fill and two checks, where
/// the copy made four launches), and a NaN in it is still found.
#[test]
fn the_finite_check_reads_a_transposed_tensor_without_a_copy() {
    let _turn = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let Some(gpu) = gpu() else {
        return;
    };
    let transposed = |nan_at: Option<usize>| {
        let mut v = vec![0.5f32; 16];
        if let Some(at) = nan_at {
            v[at] = f32::NAN;
        }
        let stored = Tensor::<2>::from_data(TensorData::new(v, [2, 8]), &gpu);
        let mut model = toy(&gpu);
        model.a = Param::from_tensor(stored.swap_dims(0, 1).detach());
        model
    };
    let clean = transposed(None);
    let _ = params_finite(&clean, &HashSet::new()); // compile first
    let (finite, counted) = count_launches(false, || params_finite(&clean, &HashSet::new()));
    assert!(finite);
    assert_eq!(counted.total(), 3, "one fill, two checks, no copy");
    for at in [0, 7, 15] {
        let bad = transposed(Some(at));
        assert!(
            !params_finite(&bad, &HashSet::new()),
            "NaN at {at} not found"
        );
    }
}
