//! `GradCombine::PlaneSums` asked of a device: taken where the device runs subgroup
//! operations, whether CubeCL reports them or not (lavapipe reports none and has them),
//! and refused, with the backward adding per pixel, where it has none (wgpu on OpenGL).

use crate::common::View;
use crate::wgpu_parity::{compare, run, two_views, weights};
use burn::tensor::wgpu::WgpuBackend;
use burn::tensor::Device;
use envision4d_splat::testkit::{random_scene, wgpu_test_device, SceneSpec};
use envision4d_splat::{kernel_plan, GradCombine, RasterConfig, TileSchedule};

/// Plane sums forced under the batched schedule, whatever the device reports.
fn forced() -> RasterConfig {
    RasterConfig {
        tile_schedule: TileSchedule::SharedBatches,
        grad_combine: GradCombine::PlaneSums,
        ..RasterConfig::default()
    }
}

/// wgpu on OpenGL (Mesa's llvmpipe here), an adapter without subgroups; `None` where the
/// wgpu tests are skipped on purpose (`ENVISION4D_SKIP_WGPU=1`) or the test GPU is CUDA
/// (`ENVISION4D_TEST_GPU=cuda`: this is a wgpu case). Panics with what to install where
/// none can be made.
fn opengl_device() -> Option<Device> {
    if std::env::var("ENVISION4D_TEST_GPU").as_deref() == Ok("cuda") {
        eprintln!("SKIP OpenGL fallback: ENVISION4D_TEST_GPU=cuda");
        return None;
    }
    wgpu_test_device()?;
    match Device::wgpu_options().graphics_api(WgpuBackend::Gl).init() {
        Ok(device) => Some(device),
        Err(e) if std::env::var("ENVISION4D_SKIP_WGPU").as_deref() == Ok("1") => {
            eprintln!("SKIP OpenGL fallback: no adapter ({e}) and ENVISION4D_SKIP_WGPU=1");
            None
        }
        Err(e) => panic!(
            "no wgpu adapter on OpenGL ({e}); install Mesa's EGL and GL drivers \
             (libegl1, libegl-mesa0, libgl1-mesa-dri) or set ENVISION4D_SKIP_WGPU=1"
        ),
    }
}

/// Renders forward and backward on `device` under `cfg` and holds it to the CPU.
fn matches_cpu(device: &Device, cfg: &RasterConfig) {
    let (w, h) = (40, 33);
    let scene = random_scene(150, 23, SceneSpec::default());
    let views: Vec<View> = two_views(w, h);
    let wts = weights(&scene, &views, w, h, cfg, 5);
    let cpu = run(&Device::flex(), &scene, &views, w, h, cfg, &wts);
    let gpu = run(device, &scene, &views, w, h, cfg, &wts);
    compare(&gpu, &cpu);
}

/// Guards the forced plane sums on an adapter without subgroups: the batched backward's
/// `subgroupAny` made the shader fail at launch ("Shader requires capability SUBGROUP"), so
/// the render's read back panicked. The plan now asks the device, adds per pixel, says so,
/// and the render matches the CPU.
#[test]
fn plane_sums_refused_without_subgroups() {
    let Some(gl) = opengl_device() else { return };
    let plan = kernel_plan(&gl, &forced()).expect("a CubeCL device has a plan");
    eprintln!("OpenGL, plane sums forced: {}", plan.describe());
    assert!(!plan.plane_sums && plan.plane_sums_refused, "{plan:?}");
    assert!(plan.describe().contains("plane sums asked; no subgroups"));
    matches_cpu(&gl, &forced());
}

/// Guards the other side of the probe: a software adapter that has subgroups but reports
/// no plane operations (lavapipe) still runs the forced plane sums, so the parity tests
/// cover the plane-sum kernel there, and the answer agrees with the render.
#[test]
fn plane_sums_taken_where_subgroups_run() {
    let Some(gpu) = wgpu_test_device() else {
        return;
    };
    let plan = kernel_plan(&gpu, &forced()).expect("a CubeCL device has a plan");
    eprintln!(
        "default wgpu adapter, plane sums forced: {}",
        plan.describe()
    );
    assert!(plan.plane_sums && !plan.plane_sums_refused, "{plan:?}");
    matches_cpu(&gpu, &forced());
}
