//! The GPU settings the bench times, each a speed-only knob of `RasterConfig` (results agree
//! to rounding): the tile schedule (`--schedules`), what the forward keeps for the backward
//! (`--backward-bins`) and how the backward's units add a splat's gradient (`--grad-adds`).
//! Every combination of the lists is one row set ([`variants`]), unless it runs the kernels
//! of an earlier one.

use burn::tensor::{Device, DeviceKind};
use envision4d_splat::{BackwardBins, GradCombine, KernelPlan, RasterConfig, TileSchedule};

/// One combination of the three knobs, with the names the command line used.
#[derive(Clone, Copy)]
pub struct Variant {
    schedule: (&'static str, TileSchedule),
    bins: (&'static str, BackwardBins),
    adds: (&'static str, GradCombine),
}

impl Variant {
    /// The rasterizer settings of this combination (the rest default).
    pub fn config(&self) -> RasterConfig {
        RasterConfig {
            tile_schedule: self.schedule.1,
            backward_bins: self.bins.1,
            grad_combine: self.adds.1,
            ..RasterConfig::default()
        }
    }

    /// `shared`, `shared, recompute`, `shared, plane sums`: the knobs left at their default
    /// are not named, so rows read as they did before each knob existed.
    pub fn label(&self) -> String {
        let mut label = self.schedule.0.to_owned();
        if self.bins.1 != BackwardBins::Keep {
            label += &format!(", {}", self.bins.0);
        }
        if self.adds.1 != GradCombine::Auto {
            label += &format!(", {}", self.adds.0);
        }
        label
    }

    /// [`Self::label`], with what an `auto` resolved to on the device:
    /// `auto → per pixel, per-pixel adds, native atomics`.
    pub fn label_with(&self, plan: &KernelPlan) -> String {
        let auto = self.schedule.1 == TileSchedule::Auto || self.adds.1 == GradCombine::Auto;
        if auto {
            format!("{} → {}", self.label(), plan.describe())
        } else {
            self.label()
        }
    }

    /// The JSON fields of this combination and the kernels it ran (`null` for the CPU,
    /// which has none of the knobs).
    pub fn json(this: Option<&Self>, plan: Option<&KernelPlan>) -> String {
        let field = |v: Option<&str>| v.map_or("null".to_owned(), |s| format!("\"{s}\""));
        format!(
            "\"schedule\":{},\"backward_bins\":{},\"grad_adds\":{},\"kernels\":{}",
            field(this.map(|v| v.schedule.0)),
            field(this.map(|v| v.bins.0)),
            field(this.map(|v| v.adds.0)),
            field(plan.map(KernelPlan::describe).as_deref()),
        )
    }
}

/// Every combination of the three lists on the command line (defaults `auto`, `keep`,
/// `auto`). Combinations that run the same kernels on a device (plane sums under the
/// per-pixel schedule, which never applies them; an `auto` that resolves to an explicit
/// row) are timed once: the bench compares their [`KernelPlan`]s.
pub fn variants(arg: impl Fn(&str) -> Option<String>) -> Vec<Variant> {
    let list = |flag: &str, default: &str| arg(flag).unwrap_or_else(|| default.into());
    let schedules: Vec<_> = list("--schedules", "auto")
        .split(',')
        .map(schedule)
        .collect();
    let bins: Vec<_> = list("--backward-bins", "keep")
        .split(',')
        .map(backward_bins)
        .collect();
    let adds: Vec<_> = list("--grad-adds", "auto")
        .split(',')
        .map(grad_adds)
        .collect();
    let mut all = Vec::new();
    for &schedule in &schedules {
        for &bins in &bins {
            for &adds in &adds {
                all.push(Variant {
                    schedule,
                    bins,
                    adds,
                });
            }
        }
    }
    all
}

/// A name of `--schedules` as its tile schedule.
fn schedule(name: &str) -> (&'static str, TileSchedule) {
    match name {
        "auto" => ("auto", TileSchedule::Auto),
        "shared" => ("shared", TileSchedule::SharedBatches),
        "per-pixel" => ("per pixel", TileSchedule::PerPixel),
        other => panic!("--schedules: {other} is not a tile schedule (auto, shared, per-pixel)"),
    }
}

/// A name of `--backward-bins` as what the forward keeps for the backward.
fn backward_bins(name: &str) -> (&'static str, BackwardBins) {
    match name {
        "keep" => ("keep", BackwardBins::Keep),
        "recompute" => ("recompute", BackwardBins::Recompute),
        other => panic!("--backward-bins: {other} is not keep or recompute"),
    }
}

/// A name of `--grad-adds` as how the backward's units add a splat's gradient.
fn grad_adds(name: &str) -> (&'static str, GradCombine) {
    match name {
        "auto" => ("auto", GradCombine::Auto),
        "per-pixel" => ("per-pixel adds", GradCombine::PerPixel),
        "plane" => ("plane sums", GradCombine::PlaneSums),
        other => panic!("--grad-adds: {other} is not auto, per-pixel or plane"),
    }
}

/// A backend name of `--backends` as its device.
pub fn device(name: &str) -> (&'static str, Device) {
    match name {
        "cpu" => ("cpu (burn-flex + rayon)", Device::flex()),
        "wgpu" => ("wgpu", Device::wgpu(DeviceKind::DefaultDevice)),
        #[cfg(feature = "cuda")]
        "cuda" => ("cuda", Device::cuda(0)),
        other => {
            panic!("--backends: {other} is not built in (cpu, wgpu, cuda with --features cuda)")
        }
    }
}
