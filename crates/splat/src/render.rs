//! The tensor API: validate inputs, call the backend op, split its output into gsplat's
//! RGB / expected depth / alpha, and apply the background.
//!
//! Expected depth and the background are plain Burn ops on the kernel's (R, G, B, D, A)
//! output, so autodiff differentiates them exactly like gsplat's `postprocess_render_colors`.

use crate::backend::SplatOps;
use crate::camera::{Camera, CameraError};
use crate::config::RasterConfig;
use crate::kernels::plan::KernelPlan;
use crate::views::{HostCameras, ViewSets};
use burn::backend::Dispatch;
use burn::tensor::{s, DType, Device, Int, Tensor, TensorData};

/// Gaussians with activations applied (what gsplat's `rasterization` takes).
#[derive(Debug, Clone)]
pub struct Gaussians {
    /// `[N, 3]` world-space centres.
    pub means: Tensor<2>,
    /// `[N, 4]` rotations (w, x, y, z), any norm; zero-norm ones are culled.
    pub quats: Tensor<2>,
    /// `[N, 3]` linear scales.
    pub scales: Tensor<2>,
    /// `[N]` opacities in [0, 1].
    pub opacities: Tensor<1>,
    /// `[N, 3]` RGB colours.
    pub colors: Tensor<2>,
}

impl Gaussians {
    /// Builds the tensors from flat row-major host arrays (`means`/`scales`/`colors` N*3,
    /// `quats` N*4, `opacities` N, with N = `opacities.len()`) in the device's default float
    /// type; a length mismatch is an error naming the array.
    pub fn from_host(
        means: Vec<f32>,
        quats: Vec<f32>,
        scales: Vec<f32>,
        opacities: Vec<f32>,
        colors: Vec<f32>,
        device: &Device,
    ) -> Result<Self, RenderError> {
        let n = opacities.len();
        let rows = |name: &'static str, v: Vec<f32>, k: usize| -> Result<Tensor<2>, RenderError> {
            if v.len() != n * k {
                return Err(RenderError::Shape {
                    name,
                    expected: format!("[{n}, {k}] ({} values)", n * k),
                    got: vec![v.len()],
                });
            }
            Ok(Tensor::from_data(TensorData::new(v, [n, k]), device))
        };
        Ok(Gaussians {
            means: rows("means", means, 3)?,
            quats: rows("quats", quats, 4)?,
            scales: rows("scales", scales, 3)?,
            opacities: Tensor::from_data(TensorData::new(opacities, [n]), device),
            colors: rows("colors", colors, 3)?,
        })
    }
}

/// A batch of V cameras sharing one image size.
#[derive(Debug, Clone)]
pub struct Cameras {
    /// `[V, 4, 4]` world-to-camera matrices (OpenCV axes: x right, y down, z forward).
    pub viewmats: Tensor<3>,
    /// `[V, 3, 3]` pixel intrinsics.
    pub ks: Tensor<3>,
    pub width: u32,
    pub height: u32,
}

impl Cameras {
    /// Builds V cameras from row-major world-to-camera matrices and intrinsics.
    pub fn from_host(
        viewmats: &[[[f64; 4]; 4]],
        ks: &[[[f64; 3]; 3]],
        width: u32,
        height: u32,
        device: &Device,
    ) -> Self {
        let flat = |v: Vec<f64>| v.into_iter().map(|x| x as f32).collect::<Vec<f32>>();
        let vm = flat(viewmats.iter().flatten().flatten().copied().collect());
        let k = flat(ks.iter().flatten().flatten().copied().collect());
        Cameras {
            viewmats: Tensor::from_data(TensorData::new(vm, [viewmats.len(), 4, 4]), device),
            ks: Tensor::from_data(TensorData::new(k, [ks.len(), 3, 3]), device),
            width,
            height,
        }
    }
}

/// Non-differentiable by-products of a render (gsplat's `meta`).
#[derive(Debug, Clone)]
pub struct RenderMeta {
    /// `[V, N, 2]` screen-space radii in pixels; 0 = culled in that view. From
    /// [`render_each`], `[V, max N_v, 2]`, row i of view v being `gaussians[v]`'s Gaussian i.
    pub radii: Tensor<3, Int>,
    /// `[V, 2]` = (visible Gaussians, Gaussian-tile intersections) per view.
    pub counts: Tensor<2, Int>,
}

/// What [`render`] returns.
#[derive(Debug, Clone)]
pub struct RenderOutput {
    /// `[V, H, W, 3]` colour, background composited behind.
    pub rgb: Tensor<4>,
    /// `[V, H, W]` expected depth `D / max(A, depth_eps)`.
    pub depth: Tensor<3>,
    /// `[V, H, W]` accumulated opacity.
    pub alpha: Tensor<3>,
    pub meta: RenderMeta,
}

/// Why a render was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RenderError {
    #[error("splat input {name}: expected shape {expected}, got {got:?}")]
    Shape {
        name: &'static str,
        expected: String,
        got: Vec<usize>,
    },
    #[error(transparent)]
    Camera(#[from] CameraError),
    #[error("{0}")]
    Config(String),
}

fn check_shape(
    name: &'static str,
    got: &[usize],
    expected: &[Option<usize>],
) -> Result<(), RenderError> {
    let ok = got.len() == expected.len()
        && got
            .iter()
            .zip(expected)
            .all(|(g, e)| e.is_none_or(|e| e == *g));
    if ok {
        return Ok(());
    }
    let expected = expected
        .iter()
        .map(|e| e.map_or("_".to_owned(), |v| v.to_string()))
        .collect::<Vec<_>>()
        .join(", ");
    Err(RenderError::Shape {
        name,
        expected: format!("[{expected}]"),
        got: got.to_vec(),
    })
}

/// Validates shapes, the config and every camera (reading the small camera tensors back).
pub fn validate(
    gaussians: &Gaussians,
    cameras: &Cameras,
    config: &RasterConfig,
) -> Result<(), RenderError> {
    validate_sets(gaussians, cameras, &ViewSets::Shared, config).map(|_| ())
}

/// [`validate`] for Gaussians split into per-view sets; returns the camera matrices it read,
/// for the kernels.
fn validate_sets(
    gaussians: &Gaussians,
    cameras: &Cameras,
    sets: &ViewSets,
    config: &RasterConfig,
) -> Result<HostCameras, RenderError> {
    config.validate().map_err(RenderError::Config)?;
    let n = gaussians.means.dims()[0];
    check_shape("means", &gaussians.means.dims(), &[Some(n), Some(3)])?;
    check_shape("quats", &gaussians.quats.dims(), &[Some(n), Some(4)])?;
    check_shape("scales", &gaussians.scales.dims(), &[Some(n), Some(3)])?;
    check_shape("opacities", &gaussians.opacities.dims(), &[Some(n)])?;
    check_shape("colors", &gaussians.colors.dims(), &[Some(n), Some(3)])?;
    let v = cameras.viewmats.dims()[0];
    check_shape(
        "viewmats",
        &cameras.viewmats.dims(),
        &[Some(v), Some(4), Some(4)],
    )?;
    check_shape("ks", &cameras.ks.dims(), &[Some(v), Some(3), Some(3)])?;
    sets.validate(v, n).map_err(RenderError::Config)?;
    let (vm, ks) = read_cameras(cameras, v)?;
    for i in 0..v {
        Camera::from_matrices(
            i,
            &vm[16 * i..16 * i + 16],
            &ks[9 * i..9 * i + 9],
            cameras.width,
            cameras.height,
        )?;
    }
    // f32 on the GPU path (f32 tensors); f64 renders take the host path, which reads its
    // own inputs at full precision.
    let f32s = |v: Vec<f64>| v.into_iter().map(|x| x as f32).collect();
    Ok(HostCameras {
        viewmats: f32s(vm),
        ks: f32s(ks),
    })
}

/// Reads the `[V, 4, 4]` view matrices and `[V, 3, 3]` intrinsics back in one transfer: the
/// two flattened into one `[25 V]` vector on the device (detached, so no autodiff node is
/// recorded), since on a GPU every read waits for the queue to drain up to the cameras.
/// Only f32 cameras on one device are joined, the ones the GPU kernels take: other float
/// types render on the host path (and a device may lack a kernel in them, f64 on many
/// wgpu adapters), so they, and an empty set, are read as two tensors.
fn read_cameras(cameras: &Cameras, v: usize) -> Result<(Vec<f64>, Vec<f64>), RenderError> {
    let host = |d: TensorData| -> Result<Vec<f64>, RenderError> {
        d.convert::<f64>()
            .try_into_vec()
            .map_err(|e| RenderError::Config(format!("{e:?}")))
    };
    let (viewmats, ks) = (
        cameras.viewmats.clone().detach(),
        cameras.ks.clone().detach(),
    );
    let joinable = viewmats.dtype() == DType::F32
        && ks.dtype() == DType::F32
        && viewmats.device() == ks.device()
        && v > 0;
    if !joinable {
        crate::kernels::readback::count_camera_reads(2);
        return Ok((host(viewmats.to_data())?, host(ks.to_data())?));
    }
    crate::kernels::readback::count_camera_reads(1);
    let mut both =
        host(Tensor::cat(vec![viewmats.reshape([v * 16]), ks.reshape([v * 9])], 0).into_data())?;
    let ks = both.split_off(v * 16);
    Ok((both, ks))
}

/// Renders every camera of `cameras` from `gaussians`: gsplat's `rasterization(...,
/// render_mode="RGB+ED")`, differentiable w.r.t. all Gaussian tensors and both camera tensors.
pub fn render(
    gaussians: &Gaussians,
    cameras: &Cameras,
    config: &RasterConfig,
) -> Result<RenderOutput, RenderError> {
    render_sets(gaussians, cameras, ViewSets::Shared, config)
}

/// Renders camera v of `cameras` from `gaussians[v]` alone (a different scene per view, e.g.
/// one set of time-conditioned Gaussians per target frame), all views in one call: one host
/// readback of the tile-intersection totals for all of them instead of one per view.
/// Equal to rendering each view on its own; differentiable like [`render`].
pub fn render_each(
    gaussians: &[Gaussians],
    cameras: &Cameras,
    config: &RasterConfig,
) -> Result<RenderOutput, RenderError> {
    let v = cameras.viewmats.dims()[0];
    if gaussians.len() != v {
        return Err(RenderError::Config(format!(
            "render_each: {} Gaussian sets for {v} cameras",
            gaussians.len()
        )));
    }
    if v == 0 {
        return Err(RenderError::Config("render_each: no camera".into()));
    }
    let rows = gaussians.iter().map(|g| g.opacities.dims()[0]).collect();
    let field = |f: fn(&Gaussians) -> Tensor<2>| Tensor::cat(gaussians.iter().map(f).collect(), 0);
    let stacked = Gaussians {
        means: field(|g| g.means.clone()),
        quats: field(|g| g.quats.clone()),
        scales: field(|g| g.scales.clone()),
        opacities: Tensor::cat(gaussians.iter().map(|g| g.opacities.clone()).collect(), 0),
        colors: field(|g| g.colors.clone()),
    };
    render_sets(&stacked, cameras, ViewSets::Stacked(rows), config)
}

/// The compositing kernels a render with `config` runs on `device` (its `Auto` settings
/// resolved against what the device reports); `None` on the CPU backend, whose path has
/// none of these choices.
pub fn kernel_plan(device: &Device, config: &RasterConfig) -> Option<KernelPlan> {
    // Only the device's client is asked; an uninitialised one-element tensor reaches it
    // without a launch (the plane probe aside: plane sums forced on a device that reports no
    // plane operations, once per device).
    let like = Tensor::<1>::empty([1], device);
    <Dispatch as SplatOps>::splat_kernel_plan(like.into_dispatch(), *config)
}

thread_local! {
    static RENDER_CALLS: std::cell::Cell<usize> = const { std::cell::Cell::new(0) };
}

/// Rasterizer calls ([`render`], [`render_each`]) this thread has made so far. Each costs a
/// fixed number of host reads whatever its number of views (the cameras, and on GPU
/// backends one read of all views' intersection totals per pass that bins), so tests hold
/// callers to a number of calls.
pub fn render_calls() -> usize {
    RENDER_CALLS.with(std::cell::Cell::get)
}

fn render_sets(
    gaussians: &Gaussians,
    cameras: &Cameras,
    sets: ViewSets,
    config: &RasterConfig,
) -> Result<RenderOutput, RenderError> {
    RENDER_CALLS.with(|c| c.set(c.get() + 1));
    let host_cameras = validate_sets(gaussians, cameras, &sets, config)?;
    let g = gaussians.clone();
    let c = cameras.clone();
    let (image, radii, counts) = <Dispatch as SplatOps>::splat_forward(
        g.means.into_dispatch(),
        g.quats.into_dispatch(),
        g.scales.into_dispatch(),
        g.opacities.into_dispatch(),
        g.colors.into_dispatch(),
        c.viewmats.into_dispatch(),
        c.ks.into_dispatch(),
        c.width,
        c.height,
        sets,
        host_cameras,
        *config,
    );
    let image: Tensor<4> = Tensor::from_dispatch(image);
    let [v, h, w, _] = image.dims();
    let color = image.clone().slice(s![.., .., .., 0..3]);
    let accum_depth = image.clone().slice(s![.., .., .., 3..4]).reshape([v, h, w]);
    let alpha = image.slice(s![.., .., .., 4..5]).reshape([v, h, w]);
    let rgb = match config.background {
        None => color,
        Some(bg) => {
            // Same dtype as the render so f64 (oracle) renders stay f64.
            let bg = Tensor::<1>::from_data(
                TensorData::new(bg.to_vec(), [3]),
                (&color.device(), color.dtype()),
            )
            .reshape([1, 1, 1, 3]);
            let transmittance = alpha.clone().neg().add_scalar(1.0).reshape([v, h, w, 1]);
            color + transmittance * bg
        }
    };
    let depth = accum_depth / alpha.clone().clamp_min(config.depth_eps);
    Ok(RenderOutput {
        rgb,
        depth,
        alpha,
        meta: RenderMeta {
            radii: Tensor::from_dispatch(radii),
            counts: Tensor::from_dispatch(counts),
        },
    })
}
