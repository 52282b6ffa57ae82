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
    /// Call sites of the kernels whose short name contains the pattern (`--launch-sites`).
    sites: Option<(String, Mutex<HashMap<String, usize>>)>,
}

impl LaunchObserver for Launches {
    fn launched(&self, kernel: &'static str) {
        self.total.fetch_add(1, Ordering::Relaxed);
        if let Some(map) = &self.by_name {
            let mut map = map.lock().unwrap();
            map.entry(kernel.as_ptr() as usize).or_insert((kernel, 0)).1 += 1;
        }
        if let Some((pattern, map)) = &self.sites
            && short_name(kernel).contains(pattern.as_str())
        {
            // Launches are recorded on the thread that issues the op, so its stack names
            // the model code (or the autodiff node's backward) that asked for the kernel.
            let trace = std::backtrace::Backtrace::force_capture().to_string();
            let mut site = call_site(&trace);
            if trace.contains(MATMUL_FRAME) {
                site.insert_str(0, MATMUL_ROUTINE);
            }
            *map.lock().unwrap().entry(site).or_default() += 1;
        }
    }
}

/// The `n` largest counts as `count key` lines, ties by key.
fn print_counts(counts: HashMap<String, usize>, n: usize) {
    let mut rows: Vec<(usize, String)> = counts.into_iter().map(|(k, c)| (c, k)).collect();
    rows.sort_by(|a, b| b.0.cmp(&a.0).then_with(|| a.1.cmp(&b.1)));
    for (count, key) in rows.into_iter().take(n) {
        println!("#   {count:>7} {key}");
    }
}

/// Frames of the backend's own plumbing (and of this counter), skipped to reach the caller.
const PLUMBING: [&str; 14] = [
    "std::",
    "core::",
    "alloc::",
    "cubecl",
    "burn_cubecl",
    "burn_backend",
    "burn_std",
    "burn_ir",
    "burn_tensor::tensor::ops",
    "envision4d_model::bench",
    "__rust",
    "rust_begin",
    "backtrace",
    "<unknown>",
];

/// A frame of the matrix product's routines (cubek's matmul crate): those relay an operand
/// out along k when the candidate autotune picked wants it so (`make_k_contiguous`).
const MATMUL_FRAME: &str = "cubek_matmul::";

/// The prefix of a site whose launch came from inside a matrix product's routine. Which
/// candidate wins autotune is a matter of timing, so such copies come and go between runs
/// of the same code, and a test of our own copies leaves them out.
pub const MATMUL_ROUTINE: &str = "(inside a matmul routine) ";

/// Frames of a call site shown per line of [`Launches::print_sites`].
const SITE_FRAMES: usize = 3;

/// The first [`SITE_FRAMES`] frames of a printed backtrace outside [`PLUMBING`], innermost
/// first, without their symbol hashes, and the first frame of this project's crates where
/// those are all Burn's.
fn call_site(trace: &str) -> String {
    let frames = trace.lines().filter_map(|line| {
        let (index, symbol) = line.trim_start().split_once(": ")?;
        index.parse::<usize>().ok()?;
        let symbol = symbol.trim();
        let plain = symbol.trim_start_matches('<');
        let plumbing = PLUMBING.iter().any(|p| plain.starts_with(p));
        (!plumbing).then(|| strip_hash(symbol).to_owned())
    });
    let frames: Vec<String> = frames.collect();
    let mut site: Vec<String> = frames.iter().take(SITE_FRAMES).cloned().collect();
    // Burn's API frames alone do not say which of our calls it was: add the first of ours.
    let ours = |f: &String| f.trim_start_matches('<').starts_with("envision4d");
    if !site.iter().any(ours) {
        site.extend(frames.iter().find(|f| ours(f)).cloned());
    }
    if site.is_empty() {
        "(no frame outside the backend; a release build without symbols?)".to_owned()
    } else {
        site.join(" <- ")
    }
}

/// `path::name::h0123456789abcdef` without its `::h…` hash suffix.
fn strip_hash(symbol: &str) -> &str {
    match symbol.rsplit_once("::h") {
        Some((head, hash)) if hash.len() == 16 && hash.bytes().all(|b| b.is_ascii_hexdigit()) => {
            head
        }
        _ => symbol,
    }
}

/// CubeCL's balanced type name up to its first generic argument (`KernelBinop | MulOp`).
fn short_name(kernel: &str) -> String {
    let balanced = type_name_format(kernel, TypeNameFormatLevel::Balanced);
    let short: Vec<&str> = balanced
        .split(" | ")
        .map(str::trim)
        .filter(|part| !part.is_empty())
        .take(2)
        .collect();
    short.join(" | ")
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
            sites: None,
        }
    }

    /// The counter the benches' flags ask for: by kernel with `--launches`, and with the call
    /// sites of `--launch-sites NAME`'s kernels.
    pub fn from_args(args: &[String]) -> Self {
        let launches = Launches::new(args.iter().any(|a| a == "--launches"));
        match arg(args, "--launch-sites") {
            Some(pattern) => launches.with_sites(&pattern),
            None => launches,
        }
    }

    /// Also records where each launch of a kernel whose short name (as [`Self::print_top`]
    /// writes it) contains `pattern` came from: a backtrace per launch, so slow, for finding
    /// which code launches, say, `Copy` kernels.
    pub fn with_sites(mut self, pattern: &str) -> Self {
        self.sites = Some((pattern.to_owned(), Mutex::default()));
        self
    }

    /// The `n` call sites of [`Self::with_sites`]'s kernels with the most launches, as
    /// `count site` lines; nothing without sites.
    pub fn print_sites(&self, n: usize) {
        let Some((pattern, map)) = &self.sites else {
            return;
        };
        let sites = map.lock().unwrap().clone();
        let total: usize = sites.values().sum();
        println!("# launches of kernels named like {pattern:?}: {total}, by call site");
        print_counts(sites, n);
    }

    /// Launches of [`Self::with_sites`]'s kernels at the sites `keep` accepts; 0 without
    /// sites.
    pub fn at_sites(&self, keep: impl Fn(&str) -> bool) -> usize {
        let Some((_, map)) = &self.sites else {
            return 0;
        };
        let map = map.lock().unwrap();
        map.iter()
            .filter(|(site, _)| keep(site))
            .map(|(_, n)| n)
            .sum()
    }

    /// The most launched kernels, as `count name` lines: CubeCL's balanced type name up to
    /// its first generic argument (`KernelBinop | MulOp`; a matrix product's full name runs
    /// to two dozen arguments, so its variants are summed under one line). Nothing for a
    /// counter without names.
    pub fn print_top(&self, n: usize) {
        print_counts(self.by_kernel(), n);
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
            *rows.entry(short_name(name)).or_default() += count;
        }
        rows
    }
}

/// Runs `pass` with its kernel launches counted (`named`: by kernel too).
pub fn count_launches<T>(named: bool, pass: impl FnOnce() -> T) -> (T, Arc<Launches>) {
    watch_launches(Launches::new(named), pass)
}

/// Runs `pass` with its kernel launches recorded by `launches`.
pub fn watch_launches<T>(launches: Launches, pass: impl FnOnce() -> T) -> (T, Arc<Launches>) {
    let launches = Arc::new(launches);
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

/// `--split fused|burn`: the one node's split into heads and merge back, by the kernels of
/// [`crate::layers::qkv_attention::heads`] (the default) or Burn's views and slices.
pub fn choose_split(args: &[String]) {
    match arg(args, "--split").as_deref() {
        None | Some("fused") => crate::layers::qkv_attention::heads::set_heads_kernels(true),
        Some("burn") => crate::layers::qkv_attention::heads::set_heads_kernels(false),
        Some(other) => panic!("--split {other}: use fused or burn"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Guards the call-site parser of `--launch-sites`: the backend's frames are skipped,
    /// the caller's kept innermost first without their hashes, our first frame added where
    /// the first three are Burn's API, and a trace of plumbing only says so rather than
    /// printing an empty site.
    #[test]
    fn a_launch_site_is_the_first_frames_outside_the_backend() {
        let trace = "\
   0: std::backtrace::Backtrace::force_capture::h0123456789abcdef
   1: <envision4d_model::bench::Launches as cubecl_runtime::LaunchObserver>::launched
   2: cubecl_runtime::client::ComputeClient::launch::h00000000000000aa
   3: burn_cubecl::kernel::contiguous::into_contiguous::h1111111111111111
   4: <burn_autodiff::ops::base::OpsStep<B,T,SB> as burn_autodiff::graph::Step>::step::h2222222222222222
   5: envision4d_model::layers::attention::Attention::heads::h3333333333333333
   6: envision4d_model::layers::block::Block::forward
   7: main";
        assert_eq!(
            call_site(trace),
            "<burn_autodiff::ops::base::OpsStep<B,T,SB> as burn_autodiff::graph::Step>::step \
             <- envision4d_model::layers::attention::Attention::heads \
             <- envision4d_model::layers::block::Block::forward"
        );
        let api = "\
   0: burn_dispatch::ops::float_reshape
   1: burn_tensor::bridge::reshape
   2: burn_tensor::tensor::api::base::Tensor<_,K>::reshape
   3: burn_tensor::other
   4: envision4d_model::dpt::head::Dpt::forward::h3333333333333333
   5: envision4d_model::model::Model::forward";
        assert_eq!(
            call_site(api),
            "burn_dispatch::ops::float_reshape <- burn_tensor::bridge::reshape \
             <- burn_tensor::tensor::api::base::Tensor<_,K>::reshape \
             <- envision4d_model::dpt::head::Dpt::forward"
        );
        let plumbing = "   0: std::rt::lang_start\n   1: core::ops::function::FnOnce::call_once";
        assert!(call_site(plumbing).starts_with("(no frame"));
        assert_eq!(strip_hash("a::b::hxyz"), "a::b::hxyz");
    }
}
