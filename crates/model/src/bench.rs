//! What the benchmark binaries (this crate's `forward`, the train crate's `train_step`)
//! share: their argument lookup, device by name, and the two memory figures they print.

use burn::tensor::Device;

/// The value after `name` in `args` (`--image 350x518`), if any.
pub fn arg(args: &[String], name: &str) -> Option<String> {
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1).cloned())
}

/// The device a `--device` value names: `cpu` (default), `wgpu`, or `cuda` in a build with
/// this crate's `cuda` feature.
pub fn device(name: Option<&str>) -> Result<Device, String> {
    match name {
        None | Some("cpu") => Ok(Device::flex()),
        Some("wgpu") => Ok(Device::wgpu(burn::tensor::DeviceKind::DefaultDevice)),
        #[cfg(feature = "cuda")]
        Some("cuda") => Ok(Device::cuda(0)),
        Some(d) => Err(format!(
            "--device {d}: use cpu, wgpu or cuda (with --features cuda)"
        )),
    }
}

/// The kB value of `field` (`"VmHWM:"`, `"MemTotal:"`) in a /proc file such as
/// `/proc/self/status` or `/proc/meminfo`; `None` where it is missing.
pub fn proc_kb(path: &str, field: &str) -> Option<f64> {
    std::fs::read_to_string(path)
        .ok()?
        .lines()
        .find(|l| l.starts_with(field))?
        .split_whitespace()
        .nth(1)?
        .parse()
        .ok()
}

/// The process's peak resident memory (`VmHWM`) in GiB; NaN where /proc is missing.
pub fn peak_rss_gib() -> f64 {
    proc_kb("/proc/self/status", "VmHWM:").map_or(f64::NAN, |kb| kb / (1024.0 * 1024.0))
}

/// The device memory pool's reserved bytes in GiB (GPU backends); NaN on the CPU, whose
/// memory is the RSS.
pub fn device_reserved_gib(device: &Device) -> f64 {
    device
        .memory_pool_usage()
        .map_or(f64::NAN, |u| u.bytes_reserved as f64 / (1u64 << 30) as f64)
}
