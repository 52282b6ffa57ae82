//! The device pipeline's limits and shapes on wgpu (lavapipe here), against the CPU path
//! where there is one: a buffer past the binding limit, depth ties across many tiles, an
//! opaque stack that stops early, the render's host readbacks counted, and the compositing
//! kernels each tile schedule launches.

use crate::common::View;
use crate::wgpu_parity::{check_parity, compare, run, t, two_views, weights};
use burn::tensor::Device;
use cubecl::logging::{LaunchObservation, LaunchObserver};
use envision4d_splat::testkit::{
    intrinsics, look_at, random_scene, wgpu_test_device, HostScene, SceneSpec,
};
use envision4d_splat::{
    kernel_plan, render, BackwardBins, Cameras, Gaussians, RasterConfig, TileSchedule,
};
use std::collections::BTreeSet;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::{Arc, Mutex};

/// Guards the storage-binding limit: a render whose output cannot be bound on the device
/// (16384² x 5 floats = 5.4 GB, past any WebGPU per-binding limit) must stop with a message
/// naming the buffer and the limit, never silently truncate or corrupt.
#[test]
fn wgpu_oversized_buffer_fails_loudly() {
    let Some(device) = wgpu_test_device() else {
        return;
    };
    let mut scene = HostScene::default();
    scene.push(
        [0.0, 0.0, 2.0],
        [1.0, 0.0, 0.0, 0.0],
        [0.1; 3],
        0.9,
        [1.0; 3],
    );
    let side = 16384u32;
    let view: View = (
        look_at([0.0, 0.0, 0.0], [0.0, 0.0, 1.0]),
        intrinsics(side, side, 8000.0),
    );
    let n = scene.len();
    let g = Gaussians {
        means: t(&scene.means, [n, 3], &device),
        quats: t(&scene.quats, [n, 4], &device),
        scales: t(&scene.scales, [n, 3], &device),
        opacities: t(&scene.opacities, [n], &device),
        colors: t(&scene.colors, [n, 3], &device),
    };
    let c = Cameras {
        viewmats: t(&view.0, [1, 4, 4], &device),
        ks: t(&view.1, [1, 3, 3], &device),
        width: side,
        height: side,
    };
    let result = catch_unwind(AssertUnwindSafe(|| {
        render(&g, &c, &RasterConfig::default()).map(|o| o.alpha.dims())
    }));
    let err = result.expect_err("a 5.4 GB output buffer cannot be bound");
    let msg = err.downcast_ref::<String>().cloned().unwrap_or_default();
    assert!(
        msg.contains("output buffer") && msg.contains("bytes per storage buffer"),
        "unclear message: {msg}"
    );
}

/// Guards the device binning's order: 2 500 Gaussians (three sort blocks) at one shared depth
/// over 104 tiles, so every overlap is a depth tie that only the stable (depth, index) order
/// of the radix sorts resolves as the CPU does.
#[test]
fn wgpu_equal_depths_over_many_tiles_match_cpu() {
    let (w, h) = (200, 120);
    let mut scene = random_scene(
        2_500,
        21,
        SceneSpec {
            xy: 2.0,
            ..Default::default()
        },
    );
    for z in scene.means.iter_mut().skip(2).step_by(3) {
        *z = 3.0;
    }
    check_parity(
        &scene,
        &two_views(w, h)[..1],
        w,
        h,
        &RasterConfig::default(),
    );
}

/// Guards the shared-memory batches and the per-tile early exit: 700 large, nearly opaque
/// Gaussians cover every pixel, so each tile lists them all (three batches) and every pixel
/// stops within the first; the rest must be skipped, not composited.
#[test]
fn wgpu_opaque_stack_stops_like_cpu() {
    let (w, h) = (48, 40);
    let scene = random_scene(
        700,
        33,
        SceneSpec {
            xy: 0.3,
            z: (2.0, 6.0),
            scale: (0.8, 1.5),
            opacity: (0.9, 0.99),
        },
    );
    check_parity(
        &scene,
        &two_views(w, h)[..1],
        w,
        h,
        &RasterConfig::default(),
    );
}

/// Guards the device-resident pipeline (no per-Gaussian or per-pixel data, no camera
/// gradient and no per-view round trip crossing to the host): a forward and backward of three
/// views reads back the two camera tensors once (validation hands them to the kernels, so
/// neither pass reads them again) and one buffer of the views' intersection totals in the
/// forward. The backward reads nothing when it reuses the forward's tile lists
/// (`BackwardBins::Keep`, the default) and bins again with one read of its own under
/// `Recompute`; both give the same render and gradients.
#[test]
fn wgpu_render_reads_back_only_cameras_and_counts() {
    let Some(gpu) = wgpu_test_device() else {
        return;
    };
    let (w, h) = (40, 30);
    let scene = random_scene(200, 5, SceneSpec::default());
    let mut views = two_views(w, h);
    views.push((
        look_at([0.1, 0.1, 0.0], [0.0, 0.0, 2.0]),
        intrinsics(w, h, 30.0),
    ));
    let wts = weights(&scene, &views, w, h, &RasterConfig::default(), 3);
    let mut runs = Vec::new();
    // The 2 camera tensors in 1 read, then 1 read of all views' totals per pass that bins.
    for (backward_bins, want) in [
        (BackwardBins::Keep, 1 + 1),
        (BackwardBins::Recompute, 1 + 2),
    ] {
        let cfg = RasterConfig {
            backward_bins,
            ..RasterConfig::default()
        };
        let before = envision4d_splat::kernels::readback::host_readbacks();
        let r = run(&gpu, &scene, &views, w, h, &cfg, &wts);
        let reads = envision4d_splat::kernels::readback::host_readbacks() - before;
        assert!(
            r.counts.iter().skip(1).step_by(2).all(|&c| c > 0),
            "every view has tiles"
        );
        assert_eq!(
            reads, want,
            "host readbacks of one forward+backward, {backward_bins:?}"
        );
        runs.push(r);
    }
    compare(&runs[0], &runs[1]);
}

/// The compositing kernels launched on this thread while it was installed, by type name.
#[derive(Default)]
struct Composited {
    thread: Option<std::thread::ThreadId>,
    kernels: Mutex<BTreeSet<String>>,
}

impl LaunchObserver for Composited {
    fn launched(&self, kernel: &'static str) {
        // Other tests launch on their own threads at the same time; only ours count.
        if Some(std::thread::current().id()) == self.thread && kernel.contains("Rasterize") {
            // `path::RasterizeBackward<path::NativeAdd>`: the last segment before the generics.
            let path = kernel.split('<').next().unwrap_or(kernel);
            let name = path.rsplit("::").next().unwrap_or(path);
            self.kernels.lock().unwrap().insert(name.to_owned());
        }
    }
}

/// Guards the tile schedule's plumbing: `Auto` on lavapipe (a device that is no card) must
/// run the per-pixel compositing kernels, about twice as fast there, and `SharedBatches` the
/// batched ones a GPU runs, in the forward and the backward alike; and `kernel_plan`, which
/// the bench reports, says what ran (on the autodiff device too; `None` on the CPU).
#[test]
fn wgpu_tile_schedule_picks_the_compositing_kernels() {
    let Some(gpu) = wgpu_test_device() else {
        return;
    };
    let (w, h) = (40, 30);
    let scene = random_scene(150, 8, SceneSpec::default());
    let views = &two_views(w, h)[..1];
    let wts = weights(&scene, views, w, h, &RasterConfig::default(), 4);
    let per_pixel = ["RasterizeBackwardPerPixel", "RasterizeForwardPerPixel"];
    let batched = ["RasterizeBackward", "RasterizeForward"];
    for (schedule, want) in [
        (TileSchedule::Auto, per_pixel),
        (TileSchedule::PerPixel, per_pixel),
        (TileSchedule::SharedBatches, batched),
    ] {
        let seen = Arc::new(Composited {
            thread: Some(std::thread::current().id()),
            ..Default::default()
        });
        let watching = LaunchObservation::new(seen.clone());
        let cfg = RasterConfig {
            tile_schedule: schedule,
            ..RasterConfig::default()
        };
        run(&gpu, &scene, views, w, h, &cfg, &wts);
        drop(watching);
        let kernels: Vec<String> = seen.kernels.lock().unwrap().iter().cloned().collect();
        assert_eq!(kernels, want, "{schedule:?} launched {kernels:?}");
        let plan = kernel_plan(&gpu, &cfg).expect("a plan on wgpu");
        assert_eq!(
            plan.shared_batches,
            want == batched,
            "{schedule:?}: {plan:?}"
        );
        assert_eq!(kernel_plan(&gpu.clone().autodiff(), &cfg), Some(plan));
        assert_eq!(kernel_plan(&Device::flex(), &cfg), None);
    }
}
