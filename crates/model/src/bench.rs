//! What the benchmark binaries (this crate's `forward`, the train crate's `train_step`)
//! share: their argument lookup, device by name, the two memory figures they print, and
//! the count of kernel launches.

use burn::tensor::Device;
use cubecl::config::{type_name_format, TypeNameFormatLevel};
use cubecl::logging::{LaunchObservation, LaunchObserver};
use std::collections::HashMap;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

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

/// The kernels a pass launches on a CubeCL backend (CubeCL's launch observer; the CPU
/// backend launches none). A GPU pays a fixed host cost per launch, so their number is a
/// floor on the pass's time there whatever the device's speed. The observer runs inside the
/// timed pass, so it only counts unless asked for names (the benches' `--launches`): then
/// each launch also takes a lock and a map entry keyed by the name's address (a type name
/// is one static string).
pub struct Launches {
    total: AtomicUsize,
    by_name: Option<Mutex<HashMap<usize, (&'static str, usize)>>>,
}

impl LaunchObserver for Launches {
    fn launched(&self, kernel: &'static str) {
        self.total.fetch_add(1, Ordering::Relaxed);
        if let Some(map) = &self.by_name {
            let mut map = map.lock().unwrap();
            map.entry(kernel.as_ptr() as usize).or_insert((kernel, 0)).1 += 1;
        }
    }
}

impl Launches {
    /// Launches counted so far.
    pub fn total(&self) -> usize {
        self.total.load(Ordering::Relaxed)
    }

    /// A counter (`named`: also by kernel, for [`Self::print_top`]).
    pub fn new(named: bool) -> Self {
        Launches {
            total: AtomicUsize::new(0),
            by_name: named.then(Default::default),
        }
    }

    /// The most launched kernels, as `count name` lines: CubeCL's balanced type name up to
    /// its first generic argument (`KernelBinop | MulOp`; a matrix product's full name runs
    /// to two dozen arguments, so its variants are summed under one line). Nothing for a
    /// counter without names.
    pub fn print_top(&self, n: usize) {
        let mut rows: Vec<(usize, String)> =
            self.by_kernel().into_iter().map(|(k, n)| (n, k)).collect();
        rows.sort_by(|a, b| b.0.cmp(&a.0).then_with(|| a.1.cmp(&b.1)));
        for (count, name) in rows.into_iter().take(n) {
            println!("#   {count:>7} {name}");
        }
    }

    /// Launches of the kernels whose short name (as [`Self::print_top`] writes it) is
    /// `name`; 0 for a counter without names.
    pub fn of(&self, name: &str) -> usize {
        self.by_kernel().get(name).copied().unwrap_or(0)
    }

    /// Launches by short name: CubeCL's balanced type name up to its first generic
    /// argument.
    fn by_kernel(&self) -> HashMap<String, usize> {
        let mut rows: HashMap<String, usize> = HashMap::new();
        let Some(map) = &self.by_name else {
            return rows;
        };
        for &(name, count) in map.lock().unwrap().values() {
            let balanced = type_name_format(name, TypeNameFormatLevel::Balanced);
            let short: Vec<&str> = balanced
                .split(" | ")
                .map(str::trim)
                .filter(|part| !part.is_empty())
                .take(2)
                .collect();
            *rows.entry(short.join(" | ")).or_default() += count;
        }
        rows
    }
}

/// Runs `pass` with its kernel launches counted (`named`: by kernel too).
pub fn count_launches<T>(named: bool, pass: impl FnOnce() -> T) -> (T, Arc<Launches>) {
    let launches = Arc::new(Launches::new(named));
    let watching = LaunchObservation::new(launches.clone());
    let out = pass();
    drop(watching);
    (out, launches)
}

/// `--norm fused|burn`: the LayerNorm GPU backends run, the fused op of
/// [`crate::layers::norm`] (the default) or Burn's decomposition, to compare the two.
pub fn choose_layer_norm(args: &[String]) {
    match arg(args, "--norm").as_deref() {
        None | Some("fused") => crate::layers::norm::set_fused_layer_norm(true),
        Some("burn") => crate::layers::norm::set_fused_layer_norm(false),
        Some(other) => panic!("--norm {other}: use fused or burn"),
    }
}

/// `--softmax fused|burn`: the lean attention's score rows on the GPU backends, the
/// fused row kernels of [`crate::layers::lean_attention`] (the default) or Burn's
/// decomposition, to compare the two in one binary.
pub fn choose_softmax(args: &[String]) {
    match arg(args, "--softmax").as_deref() {
        None | Some("fused") => crate::layers::lean_attention::set_fused_softmax(true),
        Some("burn") => crate::layers::lean_attention::set_fused_softmax(false),
        Some(other) => panic!("--softmax {other}: use fused or burn"),
    }
}

/// `--rope fused|burn`: the aggregator's rotary embedding on the GPU backends, the one
/// kernel of [`crate::layers::rope`] per rotation (the default) or Burn's decomposition
/// (the quarters' flip, two products and a sum, forward and backward).
pub fn choose_rope(args: &[String]) {
    match arg(args, "--rope").as_deref() {
        None | Some("fused") => crate::layers::rope::set_fused_rope(true),
        Some("burn") => crate::layers::rope::set_fused_rope(false),
        Some(other) => panic!("--rope {other}: use fused or burn"),
    }
}

/// `--residual fused|burn`: the blocks' LayerScale residual with the projection's bias on
/// the GPU backends, the one kernel of [`crate::layers::residual`] per pass (the default)
/// or Burn's `Linear` bias sum, product and sum (and their backward: a product, and
/// reductions for the bias and the gain).
pub fn choose_residual(args: &[String]) {
    match arg(args, "--residual").as_deref() {
        None | Some("fused") => crate::layers::residual::set_fused_residual(true),
        Some("burn") => crate::layers::residual::set_fused_residual(false),
        Some(other) => panic!("--residual {other}: use fused or burn"),
    }
}

/// `--gelu fused|burn`: the MLPs' first bias and GELU on the GPU backends, the one kernel
/// of [`crate::layers::gelu`] per pass (the default) or Burn's bias sum and GELU ops (whose
/// backward differentiates the tanh approximation).
pub fn choose_gelu(args: &[String]) {
    match arg(args, "--gelu").as_deref() {
        None | Some("fused") => crate::layers::gelu::set_fused_gelu(true),
        Some("burn") => crate::layers::gelu::set_fused_gelu(false),
        Some(other) => panic!("--gelu {other}: use fused or burn"),
    }
}

/// `--qkv fused|burn`: training attention on the GPU backends as one autodiff node from the
/// q/k/v projection ([`crate::layers::qkv_attention`], the default) or as Burn's reshape,
/// permutation and three slices, then separate qk-norm, RoPE and attention nodes.
/// `--norm burn` and `--rope burn` also turn the one node off (the separate path then runs
/// Burn's LayerNorm or RoPE ops, which the node does not).
pub fn choose_qkv(args: &[String]) {
    match arg(args, "--qkv").as_deref() {
        None | Some("fused") => crate::layers::qkv_attention::set_packed_qkv(true),
        Some("burn") => crate::layers::qkv_attention::set_packed_qkv(false),
        Some(other) => panic!("--qkv {other}: use fused or burn"),
    }
}
