//! Compiles every CubeCL kernel of the project (the rasterizer's, the model's fused
//! LayerNorm, attention rows, q/k/v heads, RoPE, LayerScale residual and bias-GELU, the fused Adam, the NaN guard's check) to PTX for an NVIDIA architecture, on a
//! machine without a GPU, through the LLVM route the CUDA runtime takes by default
//! (`cubecl_llvm::PlironCompiler`, linked into every `cuda` build). A kernel that route
//! cannot lower fails here, before a GPU lease is spent on it (docs/PERFORMANCE.md,
//! "Building for CUDA"). It lives in the train crate, the one that sees every crate's
//! kernels.
//!
//! cargo run --release -p envision4d-train --features envision4d-train/cuda --example ptx_check -- [SM] [DIR] [--cpp]
//!
//! SM is the architecture (90 = Hopper, the default; 80 = Ampere); DIR, when given, gets one
//! `.ptx` file per kernel. With `--cpp` the kernels go through CubeCL's other route instead,
//! CUDA C++ for NVRTC (the `cuda-nvrtc` builds'), and DIR gets one `.cu` file per kernel
//! (`scripts/nvrtc_check.py` compiles them with NVRTC, offline). Exit code 1 when any kernel
//! fails to compile.

use cubecl::cuda::compiler::CudaBackend;
use cubecl::cuda::{CudaCompilationOptions, CudaCompiler};
use cubecl::ir::features::{Features, Plane};
use cubecl::ir::nvidia::SmArch;
use cubecl::ir::{DeviceIdentity, HardwareProperties, MemoryDeviceProperties};
use cubecl::prelude::*;
use cubecl::Compiler;
use cubecl_llvm::nvptx::ptx_version::PtxVersion;
use cubecl_llvm::{LlvmTarget, PlironArtifact, PlironCompiler, PlironOptions};
use envision4d_model::layers::cube_rows::ROW_THREADS;
use envision4d_model::layers::gelu::kernels as gelu;
use envision4d_model::layers::lean_attention::kernels as attention;
use envision4d_model::layers::norm::kernels as norm;
use envision4d_model::layers::qkv_attention::heads::kernels as heads;
use envision4d_model::layers::residual::kernels as residual;
use envision4d_model::layers::rope::kernels as rope;
use envision4d_splat::kernels::rasterize_forward::TILE;
use envision4d_splat::kernels::splat_grad::{CasAdd, NativeAdd};
use envision4d_splat::kernels::{
    bin_tiles, camera_grad, plane_probe, project_backward, project_forward, radix_sort,
    rasterize_backward, rasterize_backward_per_pixel, rasterize_forward,
    rasterize_forward_per_pixel, scan, view_meta,
};
use envision4d_train::adam::kernel as adam;
use envision4d_train::finite::kernel as finite;
use std::ffi::CStr;
use std::path::Path;
use std::sync::Arc;

/// Units per cube of the one-dimensional kernels (the launch code's own sizes vary; the
/// lowering does not depend on them).
const LINE: u32 = 256;
/// The newest PTX the CUDA 12.8 driver accepts, as the runtime would pick on such a driver.
const DRIVER: i32 = 12080;

/// A tensor argument, never aliased (the launch code passes none in place).
fn t() -> TensorCompilationArg {
    TensorCompilationArg {
        meta: TensorMetaCompilationArg { len: (), rank: () },
        buffer: BufferCompilationArg { inplace: None },
    }
}

/// An NVIDIA part as the kernels see it: 32-lane planes with plane operations (what CubeCL's
/// CUDA runtime reports), 48 KiB of static shared memory.
fn p() -> Arc<DeviceProperties> {
    let mut features = Features::default();
    features.plane.insert(Plane::Ops);
    features.plane.insert(Plane::Sync);
    let hardware = HardwareProperties {
        load_width: 128,
        vector_register_count: None,
        plane_size_min: 32,
        plane_size_max: 32,
        max_bindings: 32,
        max_shared_memory_size: 49152,
        max_cube_count: (u32::MAX, u16::MAX as u32, u16::MAX as u32),
        max_units_per_cube: 1024,
        max_cube_dim: (1024, 1024, 64),
        num_streaming_multiprocessors: None,
        num_tensor_cores: None,
        min_tensor_cores_dim: None,
        num_cpu_cores: None,
        last_level_cache_size: None,
        max_vector_size: VectorSize::MAX,
        cube_mma_reserved_shared_memory: 0,
    };
    Arc::new(DeviceProperties::new(
        features,
        MemoryDeviceProperties::new(u64::MAX, 256),
        hardware,
        cubecl::profile::TimingMethod::Device,
        DeviceIdentity {
            name: "offline".to_owned(),
            fingerprint: "offline".to_owned(),
            physical: None,
        },
    ))
}

fn tp() -> Arc<TargetProperties> {
    Arc::new(TargetProperties::default())
}

/// Cube shapes: one row of units, one tile of pixels (the rasterizer's), or the units that
/// reduce one row (a LayerNorm's, an attention softmax's).
#[derive(Clone, Copy)]
enum Shape {
    Line,
    Tile,
    Row,
}

fn s(shape: Shape) -> KernelSettings {
    let dim = match shape {
        Shape::Line => CubeDim::new_1d(LINE),
        Shape::Tile => CubeDim::new_1d(TILE * TILE),
        Shape::Row => CubeDim::new_1d(ROW_THREADS),
    };
    KernelSettings::new(*dim, ExecutionMode::Checked, AddressType::U32)
}

/// One kernel to compile: its name, its generated launch struct, its cube shape, its
/// runtime parameters in signature order (`T` a tensor, `s` a scalar), then the values of
/// its comptime parameters. Brackets rather than commas keep the list one line per kernel.
macro_rules! kernel {
    ($name:expr, $kernel:ty, $shape:ident, [$($arg:ident)*] $(, $comptime:expr)*) => {
        (
            $name,
            Box::new(<$kernel>::new(s(Shape::$shape), p(), tp(), $(arg!($arg),)* $($comptime),*))
                as Box<dyn CubeKernel>,
        )
    };
}

/// A runtime parameter's compilation argument: a tensor's, or nothing for a scalar.
macro_rules! arg {
    (T) => {
        t()
    };
    (s) => {
        ()
    };
}

fn main() {
    let cpp = std::env::args().any(|a| a == "--cpp");
    let mut args = std::env::args().skip(1).filter(|a| a != "--cpp");
    let sm: u32 = match args.next().map(|a| a.parse()) {
        None => 90,
        Some(Ok(sm)) => sm,
        Some(Err(e)) => {
            eprintln!("ptx_check: SM must be a number like 90: {e}");
            std::process::exit(2);
        }
    };
    let dir = args.next().map(std::path::PathBuf::from);
    let kernels: Vec<(&str, Box<dyn CubeKernel>)> = vec![
        kernel!("depth_keys", bin_tiles::depth_keys::DepthKeys, Line, [T T T T s]),
        kernel!("tile_counts", bin_tiles::tile_counts::TileCounts, Line, [T T T T s]),
        kernel!("emit_intersections", bin_tiles::emit_intersections::EmitIntersections, Line, [T T T T T T s s]),
        kernel!("tile_ranges", bin_tiles::tile_ranges::TileRanges, Line, [T T s s]),
        kernel!("copy_total", bin_tiles::copy_total::CopyTotal, Line, [T T s s]),
        kernel!("camera_grad_matrices", camera_grad::camera_grad_matrices::CameraGradMatrices, Line, [T T T s]),
        kernel!(
            "plane_probe",
            plane_probe::plane_probe::PlaneProbe,
            Line,
            [T]
        ),
        kernel!("project_backward", project_backward::project_backward::ProjectBackward, Line, [T T T T T T T T T T T T s s s s s]),
        kernel!("project_forward", project_forward::project_forward::ProjectForward, Line, [T T T T T T T T s s s s s s s s]),
        kernel!("radix_count", radix_sort::radix_count::RadixCount, Line, [T T s s s]),
        kernel!("radix_scatter", radix_sort::radix_scatter::RadixScatter, Line, [T T T T T s s s]),
        // Every comptime branch once: the backward adding per pixel or per plane (with the
        // plane barriers CUDA gets); the forward keeping its ends or not.
        kernel!("rasterize_backward<NativeAdd>", rasterize_backward::rasterize_backward::RasterizeBackward::<NativeAdd>, Tile, [T T T T T T s s s s s s], false, false),
        kernel!("rasterize_backward<CasAdd>", rasterize_backward::rasterize_backward::RasterizeBackward::<CasAdd>, Tile, [T T T T T T s s s s s s], false, false),
        kernel!("rasterize_backward<NativeAdd, plane sums>", rasterize_backward::rasterize_backward::RasterizeBackward::<NativeAdd>, Tile, [T T T T T T s s s s s s], true, true),
        kernel!("rasterize_backward<CasAdd, plane sums>", rasterize_backward::rasterize_backward::RasterizeBackward::<CasAdd>, Tile, [T T T T T T s s s s s s], true, true),
        kernel!("rasterize_forward", rasterize_forward::rasterize_forward::RasterizeForward, Tile, [T T T T T s s s s s s s], false),
        kernel!("rasterize_forward<ends>", rasterize_forward::rasterize_forward::RasterizeForward, Tile, [T T T T T s s s s s s s], true),
        kernel!("rasterize_backward_per_pixel<NativeAdd>", rasterize_backward_per_pixel::rasterize_backward_per_pixel::RasterizeBackwardPerPixel::<NativeAdd>, Tile, [T T T T T T s s s s s s]),
        kernel!("rasterize_backward_per_pixel<CasAdd>", rasterize_backward_per_pixel::rasterize_backward_per_pixel::RasterizeBackwardPerPixel::<CasAdd>, Tile, [T T T T T T s s s s s s]),
        kernel!("rasterize_forward_per_pixel", rasterize_forward_per_pixel::rasterize_forward_per_pixel::RasterizeForwardPerPixel, Tile, [T T T T T s s s s s s s], false),
        kernel!("rasterize_forward_per_pixel<ends>", rasterize_forward_per_pixel::rasterize_forward_per_pixel::RasterizeForwardPerPixel, Tile, [T T T T T s s s s s s s], true),
        kernel!("scan_blocks", scan::scan_blocks::ScanBlocks, Line, [T T T s s s]),
        kernel!("scan_add", scan::scan_add::ScanAdd, Line, [T T s]),
        kernel!("scan_add_inline", scan::scan_add_inline::ScanAddInline, Line, [T T s]),
        kernel!("scan_wrapped", scan::scan_wrapped::ScanWrapped, Line, [T T s s]),
        kernel!("view_radii", view_meta::view_radii::ViewRadii, Line, [T T s s s]),
        kernel!("view_counts", view_meta::view_counts::ViewCounts, Line, [T T s s s]),
        kernel!("layer_norm_forward", norm::layer_norm_forward::LayerNormForward, Row, [T T T T T T s s s]),
        kernel!("layer_norm_backward_input", norm::layer_norm_backward_input::LayerNormBackwardInput, Row, [T T T T T T s s]),
        kernel!("layer_norm_backward_params", norm::layer_norm_backward_params::LayerNormBackwardParams, Line, [T T T T T T s s s]),
        // Both comptime branches: the first step (no moments read) and the later ones.
        kernel!("adam_update<first>", adam::adam_update::AdamUpdate, Line, [T T T T T T T s s s s s s], true, false),
        kernel!("adam_update", adam::adam_update::AdamUpdate, Line, [T T T T T T T s s s s s s], false, false),
        kernel!("adam_update<first, strided>", adam::adam_update::AdamUpdate, Line, [T T T T T T T s s s s s s], true, true),
        kernel!("adam_update<strided>", adam::adam_update::AdamUpdate, Line, [T T T T T T T s s s s s s], false, true),
        kernel!("softmax_rows", attention::softmax_rows::SoftmaxRows, Row, [T T T s s s]),
        kernel!("row_dot", attention::row_dot::RowDot, Row, [T T T s s]),
        kernel!("probs_from_lse", attention::probs_from_lse::ProbsFromLse, Line, [T T T s s s]),
        kernel!("score_grad", attention::score_grad::ScoreGrad, Line, [T T T T s s s]),
        kernel!("rope_rotate", rope::rope_rotate::RopeRotate, Line, [T T T T s s s s s], false),
        kernel!("rope_rotate<vjp>", rope::rope_rotate::RopeRotate, Line, [T T T T s s s s s], true),
        kernel!("scaled_residual_forward", residual::scaled_residual_forward::ScaledResidualForward, Line, [T T T T T s s]),
        // Every comptime branch: the gain's and the bias's partial sums, each or neither (frozen).
        kernel!("scaled_residual_backward<gain, bias>", residual::scaled_residual_backward::ScaledResidualBackward, Line, [T T T T T T T s s s], true, true),
        kernel!("scaled_residual_backward<gain>", residual::scaled_residual_backward::ScaledResidualBackward, Line, [T T T T T T T s s s], true, false),
        kernel!("scaled_residual_backward<bias>", residual::scaled_residual_backward::ScaledResidualBackward, Line, [T T T T T T T s s s], false, true),
        kernel!("scaled_residual_backward", residual::scaled_residual_backward::ScaledResidualBackward, Line, [T T T T T T T s s s], false, false),
        kernel!("bias_gelu_forward", gelu::bias_gelu_forward::BiasGeluForward, Line, [T T T s s]),
        // Both comptime branches: with the bias's partial sums and without (a frozen bias).
        kernel!("bias_gelu_backward<bias>", gelu::bias_gelu_backward::BiasGeluBackward, Line, [T T T T T s s s], true),
        kernel!("bias_gelu_backward", gelu::bias_gelu_backward::BiasGeluBackward, Line, [T T T T T s s s], false),
        kernel!("flag_non_finite", finite::flag_non_finite::FlagNonFinite, Line, [T T s]),
        kernel!("split_heads", heads::split_heads::SplitHeads, Line, [T T T T s s s s]),
        kernel!("merge_heads", heads::merge_heads::MergeHeads, Line, [T T T T s s s s]),
    ];
    let options = PlironOptions {
        sm_arch: Some(SmArch::new(sm, sm >= 70)),
        ptx_version: PtxVersion::for_driver(DRIVER),
        ..Default::default()
    };
    if cpp {
        let failed = cpp_route(kernels, sm, dir.as_deref());
        println!("sm_{sm}, CUDA C++: {failed} kernel(s) failed");
        std::process::exit(i32::from(failed > 0));
    }
    let mut failed = 0;
    for (name, kernel) in kernels {
        let mut compiler = PlironCompiler {
            target: LlvmTarget::Nvptx,
        };
        match compiler.compile(kernel.define(), &options) {
            Ok(PlironArtifact::NvptxCode(module)) => {
                // SAFETY: the module's PTX is NUL-terminated (cubecl-llvm's contract).
                let ptx = unsafe { CStr::from_ptr(module.ptx.as_ptr()) }.to_string_lossy();
                let entries = ptx.matches(".entry").count();
                println!(
                    "ok      {name}: {} bytes of PTX, {entries} entry",
                    ptx.len()
                );
                write_out(dir.as_deref(), name, "ptx", &ptx);
            }
            Ok(_) => {
                println!("FAILED  {name}: the NVPTX target returned no PTX");
                failed += 1;
            }
            Err(e) => {
                println!("FAILED  {name}: {e:?}");
                failed += 1;
            }
        }
    }
    println!("sm_{sm}: {failed} kernel(s) failed");
    if failed > 0 {
        std::process::exit(1);
    }
}

/// The kernels through CubeCL's CUDA C++ route, as a `cuda-nvrtc` build's runtime would
/// transpile them for NVRTC (a 32-lane warp, the architecture; the device-dependent features
/// off, the plainest source); each source into `dir` as `<name>.cu`. The failures.
fn cpp_route(kernels: Vec<(&str, Box<dyn CubeKernel>)>, sm: u32, dir: Option<&Path>) -> usize {
    let mut options = CudaCompilationOptions {
        arch: Some(SmArch::new(sm, sm >= 70)),
        ..Default::default()
    };
    options.cpp.warp_size = 32;
    let mut failed = 0;
    for (name, kernel) in kernels {
        let mut compiler = CudaCompiler::new(CudaBackend::Cpp);
        match compiler.compile(kernel.define(), &options) {
            Ok(source) => {
                let source = source.to_string();
                println!("ok      {name}: {} bytes of CUDA C++", source.len());
                write_out(dir, name, "cu", &source);
            }
            Err(e) => {
                println!("FAILED  {name}: {e:?}");
                failed += 1;
            }
        }
    }
    failed
}

/// Writes one kernel's output to `dir/<name>.<ext>` when a folder was given; exit 1 when it
/// cannot.
fn write_out(dir: Option<&Path>, name: &str, ext: &str, text: &str) {
    if let Some(dir) = dir {
        let path = dir.join(format!("{name}.{ext}"));
        if let Err(e) = std::fs::create_dir_all(dir).and_then(|()| std::fs::write(&path, text)) {
            eprintln!("ptx_check: cannot write {}: {e}", path.display());
            std::process::exit(1);
        }
    }
}
