//! `--backend` and `--devices`: which Burn device runs the work, chosen at run time and
//! checked before any work starts.
//!
//! A GPU backend that cannot start (no adapter, no driver) or that this binary was built
//! without is the user's to fix: an [`InputError`] naming what is missing (exit code 2),
//! never a panic halfway through a run.

use crate::InputError;
use burn::tensor::{Device, DeviceKind, Tensor};
use clap::ValueEnum;
use envision4d_model::precision::Precision;
use std::any::Any;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::{Arc, Mutex};

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum, Default)]
pub enum BackendChoice {
    /// burn-flex on the CPU (rayon-parallel); the default.
    #[default]
    Cpu,
    /// wgpu on the best available GPU (WGSL kernels; a software Vulkan driver also works).
    Wgpu,
    /// CUDA on NVIDIA GPU 0 (the same CubeCL kernels; binaries built with `--features cuda`;
    /// the driver is loaded at run time, no toolkit needed to build).
    Cuda,
}

/// `--precision`: the float format of the aggregator at inference (the heads stay f32; see
/// `docs/MODEL.md`, "Precision").
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum, Default)]
pub enum PrecisionChoice {
    /// Single precision everywhere (the default).
    #[default]
    F32,
    /// Half precision in the aggregator (CUDA; wgpu where the adapter has shader-f16).
    F16,
    /// bfloat16 in the aggregator (CUDA; not wgpu, whose shading language has no bf16).
    Bf16,
}

impl PrecisionChoice {
    pub fn precision(self) -> Precision {
        match self {
            PrecisionChoice::F32 => Precision::F32,
            PrecisionChoice::F16 => Precision::F16,
            PrecisionChoice::Bf16 => Precision::Bf16,
        }
    }

    /// Whether `device` computes in this precision: an input error naming the device and
    /// the format otherwise (checked before a checkpoint is read; then
    /// `Envision4d::with_precision`).
    pub fn check(self, device: &Device) -> Result<(), InputError> {
        let p = self.precision();
        p.check(device)
            .map_err(|e| InputError(format!("--precision {}: {e}", p.name())))
    }
}

/// What a machine needs for the wgpu backend.
const WGPU_HINT: &str = "no wgpu adapter could start; install a Vulkan, Metal or DX12 driver \
                         (on Linux without a GPU, Mesa's lavapipe: mesa-vulkan-drivers)";
/// What a machine needs for the CUDA backend: the driver alone where CubeCL lowers kernels to
/// PTX through its linked LLVM (the default), NVRTC too in a `cuda-nvrtc` build.
#[cfg(all(feature = "cuda", not(feature = "cuda-nvrtc")))]
const CUDA_HINT: &str = "CUDA could not start; it needs an NVIDIA GPU and its driver \
                         (libcuda.so.1) on the library path";
#[cfg(feature = "cuda-nvrtc")]
const CUDA_HINT: &str = "CUDA could not start; it needs an NVIDIA GPU, its driver \
                         (libcuda.so.1) and NVRTC (libnvrtc.so, this binary is a cuda-nvrtc \
                         build) on the library path";

impl BackendChoice {
    /// The device, started and checked with one tiny tensor and one kernel.
    pub fn device(self) -> Result<Device, InputError> {
        match self {
            BackendChoice::Cpu => Ok(Device::flex()),
            BackendChoice::Wgpu => probe("--backend wgpu", WGPU_HINT, || {
                Device::wgpu(DeviceKind::DefaultDevice)
            }),
            BackendChoice::Cuda => cuda(0, "--backend cuda"),
        }
    }
}

/// One `--devices` entry (`cpu`, `wgpu`, `wgpu:N`, `cuda`, `cuda:N`), started and checked.
pub fn parse_device(spec: &str) -> Result<Device, InputError> {
    let spec = spec.trim();
    let what = format!("--devices {spec}");
    let index = |prefix: &str| spec.strip_prefix(prefix).map(str::parse::<usize>);
    match spec {
        "cpu" => Ok(Device::flex()),
        "wgpu" => probe(&what, WGPU_HINT, || Device::wgpu(DeviceKind::DefaultDevice)),
        "cuda" => cuda(0, &what),
        _ => match (index("wgpu:"), index("cuda:")) {
            (Some(Ok(i)), _) => probe(&what, WGPU_HINT, || {
                Device::wgpu(DeviceKind::DiscreteGpu(i))
            }),
            (_, Some(Ok(i))) => cuda(i, &what),
            _ => Err(InputError(format!(
                "--devices: unknown device {spec:?}; use cpu, wgpu, wgpu:N, cuda or cuda:N"
            ))),
        },
    }
}

/// Whether a `--devices` entry names a CUDA device (the only kind Burn 0.22's collectives
/// run on).
pub fn is_cuda_spec(spec: &str) -> bool {
    let spec = spec.trim();
    spec == "cuda" || spec.starts_with("cuda:")
}

/// CUDA GPU `index`: the driver must report it, and (on the LLVM route) libdevice must be
/// where CubeCL will look, before the device starts; then the probe.
#[cfg(feature = "cuda")]
fn cuda(index: usize, what: &str) -> Result<Device, InputError> {
    use envision4d_splat::cuda_machine;
    let named = |e: cuda_machine::CudaMachineError| InputError(format!("{what}: {e}"));
    cuda_machine::check_device(index).map_err(named)?;
    #[cfg(not(feature = "cuda-nvrtc"))]
    cuda_machine::check_libdevice().map_err(named)?;
    probe(what, CUDA_HINT, || Device::cuda(index))
}

#[cfg(not(feature = "cuda"))]
fn cuda(_index: usize, what: &str) -> Result<Device, InputError> {
    Err(InputError(format!(
        "{what}: this binary was built without CUDA; rebuild it with \
         `cargo build --release --features cuda` (no CUDA toolkit needed to build)"
    )))
}

/// Starts a device, round-trips one tiny tensor through it and runs one kernel on it
/// (`exp`: on CUDA's LLVM route a libdevice call, so compiling, linking and loading a
/// kernel are all exercised). Backends report a missing driver by panicking deep inside;
/// the panic is caught here, kept off stderr, and turned into an error that says what to
/// install. A kernel that fails to build, or computes a wrong value, is the same error:
/// found here, not at the first real read of a run.
///
/// CubeCL's CUDA runtime starts the driver on its own server thread: the panic that names
/// the cause (cudarc failing to load libcuda) happens there, and the calling thread only sees
/// a closed channel. So the hook records every panic message during the probe, and the
/// error quotes the first one.
fn probe(what: &str, hint: &str, make: impl FnOnce() -> Device) -> Result<Device, InputError> {
    let seen: Arc<Mutex<Vec<String>>> = Arc::default();
    let quiet = std::panic::take_hook();
    let record = Arc::clone(&seen);
    std::panic::set_hook(Box::new(move |info| {
        if let Ok(mut seen) = record.lock() {
            seen.push(panic_message(info.payload()).to_owned());
        }
    }));
    let started = catch_unwind(AssertUnwindSafe(|| {
        let device = make();
        let t = Tensor::<1>::from_floats(PROBE_INPUT, &device);
        let _ = t.clone().into_data();
        let computed = t.exp().try_into_data();
        (device, computed)
    }));
    std::panic::set_hook(quiet);
    // The first panic of any thread during the probe: it names the cause.
    let cause = seen.lock().ok().and_then(|seen| seen.first().cloned());
    let (device, computed) = started.map_err(|payload| {
        let cause = cause
            .clone()
            .unwrap_or_else(|| panic_message(payload.as_ref()).to_owned());
        InputError(format!("{what}: {hint} (the backend said: {cause})"))
    })?;
    // On CUDA a compile or link error is a panic on CubeCL's server thread, which the hook
    // recorded; the read only says that it failed.
    let kernel_failed = |detail: String| {
        let cause = cause
            .as_deref()
            .map(|c| format!(" (the backend said: {c})"))
            .unwrap_or_default();
        InputError(format!(
            "{what}: the device started but its first kernel (exp) {detail}{cause}; \
             this backend cannot run the model here"
        ))
    };
    let values = computed
        .map_err(|e| kernel_failed(format!("failed: {e}")))?
        .convert::<f32>()
        .try_to_vec::<f32>()
        .map_err(|e| kernel_failed(format!("returned unreadable data: {e:?}")))?;
    check_probe(&values).map_err(kernel_failed)?;
    Ok(device)
}

/// The probe kernel's input; `exp` of it is known to f32 precision.
const PROBE_INPUT: [f32; 2] = [1.0, 2.0];

/// Whether the probe kernel's output is `exp(PROBE_INPUT)` (relative error below 1e-5: the
/// fast-math `exp` of a GPU is good to a few ulp).
fn check_probe(values: &[f32]) -> Result<(), String> {
    let want: Vec<f32> = PROBE_INPUT.iter().map(|x| x.exp()).collect();
    let close = values.len() == want.len()
        && values
            .iter()
            .zip(&want)
            .all(|(got, w)| ((got - w) / w).abs() < 1e-5);
    if close {
        Ok(())
    } else {
        Err(format!("computed {values:?} where {want:?} was expected"))
    }
}

/// The text of a panic's payload (`panic!` with a literal or a formatted message).
fn panic_message(payload: &(dyn Any + Send)) -> &str {
    payload
        .downcast_ref::<String>()
        .map(String::as_str)
        .or_else(|| payload.downcast_ref::<&str>().copied())
        .unwrap_or("no message")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Guards the probe's kernel check: a device whose `exp` returns its input (a kernel that
    /// never ran), garbage or too few values is refused; a correct one within a few ulp passes.
    #[test]
    fn probe_accepts_exp_only() {
        let exact: Vec<f32> = PROBE_INPUT.iter().map(|x| x.exp()).collect();
        assert!(check_probe(&exact).is_ok());
        let near: Vec<f32> = exact
            .iter()
            .map(|v| v * (1.0 + 4.0 * f32::EPSILON))
            .collect();
        assert!(check_probe(&near).is_ok());
        for bad in [
            vec![1.0, 2.0],
            vec![0.0, 0.0],
            vec![f32::NAN, 7.389],
            vec![1.0],
        ] {
            let err = check_probe(&bad).unwrap_err();
            assert!(err.contains("expected"), "{err}");
        }
    }

    /// Guards the wgpu probe on lavapipe: the kernel check must pass where wgpu works, so a
    /// working GPU is never refused.
    #[test]
    fn wgpu_probe_runs_a_kernel() {
        if envision4d_splat::testkit::wgpu_test_device().is_none() {
            eprintln!("ENVISION4D_SKIP_WGPU=1: skipped");
            return;
        }
        BackendChoice::Wgpu
            .device()
            .expect("wgpu starts and computes exp");
    }
}
