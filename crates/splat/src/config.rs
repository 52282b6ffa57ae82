//! Every constant of the rasterizer in one place.
//!
//! The defaults reproduce gsplat 1.5.3's `rasterization(..., render_mode="RGB+ED")`, which is
//! what the official Envision4D decoder calls. Later gsplat releases changed the alpha clamp
//! (0.999 → 0.99), so that constant is an explicit, selectable mode rather than a magic number.

use serde::{Deserialize, Serialize};

/// Side of a screen tile in pixels (gsplat's `tile_size`, Brush's `TILE_WIDTH`).
pub const TILE_SIZE: u32 = 16;

/// Largest extent of a Gaussian in standard deviations (gsplat `GAUSSIAN_EXTEND`).
/// `sqrt(2 ln 255) = 3.329`, so for opacities <= 1 the opacity-aware bound is always tighter.
pub const EXTENT_CAP: f64 = 3.33;

/// A quaternion whose squared norm is below this cannot be normalised reliably and is culled
/// (gsplat would produce a NaN rotation; Brush culls at 1e-6 on the squared norm).
pub const QUAT_NORM2_MIN: f64 = 1e-12;

/// Radii are reported as `i32` (gsplat's `radii`); a footprint beyond this many pixels is
/// clamped before the integer conversion so huge-but-finite Gaussians never overflow.
pub const RADIUS_MAX: f64 = 1.0e7;

/// Which gsplat release's alpha clamp to reproduce.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum AlphaClamp {
    /// gsplat <= 1.5.3 (the PyPI release Envision4D trained with): alpha <= 0.999.
    #[default]
    Gsplat153,
    /// gsplat after commit c5ff586b (2026): alpha <= 0.99.
    GsplatHead,
}

impl AlphaClamp {
    /// The largest alpha a single Gaussian may reach at a pixel.
    pub fn max_alpha(self) -> f64 {
        match self {
            AlphaClamp::Gsplat153 => 0.999,
            AlphaClamp::GsplatHead => 0.99,
        }
    }
}

/// How the GPU backward accumulates per-Gaussian gradients across pixels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum GradAccumulation {
    /// Native float atomics where the device has them, compare-and-swap otherwise.
    #[default]
    Auto,
    /// Always the compare-and-swap loop (the path of devices without float atomics; chosen
    /// explicitly to check it on a device that has them).
    CompareAndSwap,
}

/// How the GPU compositing kernels walk a tile's Gaussians (results agree to rounding; the
/// choice is speed only).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum TileSchedule {
    /// Shared batches on a GPU; per pixel on a device that is no card (a software adapter
    /// such as Mesa's lavapipe), where shared memory is ordinary memory and every barrier
    /// suspends and resumes the cube's SIMD groups, so batching saves nothing and costs.
    #[default]
    Auto,
    /// The cube copies each batch of records into shared memory once for its 256 pixels and
    /// stops when every pixel has (two barriers per batch): the GPU schedule.
    SharedBatches,
    /// Every unit reads its records from global memory and stops on its own; no barrier.
    PerPixel,
}

/// How the units of a tile add a splat's gradient in the GPU backward (results agree to
/// rounding; the choice is speed only).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum GradCombine {
    /// Plane sums where CubeCL reports plane operations (every CUDA GPU; wgpu on a card with
    /// subgroups, never on a software adapter) and the tiles are walked in shared batches;
    /// per pixel otherwise.
    #[default]
    Auto,
    /// Every pixel's unit adds its own part: one atomic per pixel, splat and lane.
    PerPixel,
    /// The units of a plane (warp) sum their parts and one of them adds the sums (gsplat's
    /// warp sum): a plane's worth fewer atomics, 32-fold on NVIDIA. Applies with shared
    /// batches only (per pixel, the units walk their lists apart). Taken where the device
    /// runs subgroup operations, reported or not (lavapipe has them and CubeCL reports none:
    /// the device is asked once by a probe kernel); where it has none (wgpu on OpenGL) the
    /// backward adds per pixel and the kernel plan says so.
    PlaneSums,
}

/// What a GPU forward that will be differentiated keeps for its backward (results agree to
/// rounding; the choice is memory against time).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum BackwardBins {
    /// Every view's projected records and tile lists, and where each pixel stopped
    /// compositing, stay on the device until the backward, which then skips the projection,
    /// both sorts, its host read of the intersection totals and a second compositing
    /// (gsplat keeps them too). Costs 64 bytes per Gaussian and view, 4 per tile
    /// intersection and 8 per pixel and view, held from the forward to the backward.
    #[default]
    Keep,
    /// Only the inputs are held; the backward projects, bins and composites every view
    /// again.
    Recompute,
}

/// The rasterizer's numeric settings. `RasterConfig::default()` is gsplat 1.5.3.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RasterConfig {
    /// Gaussians whose camera-space depth is below this are culled (gsplat `near_plane`).
    pub near: f64,
    /// Gaussians whose camera-space depth is above this are culled (gsplat `far_plane`).
    pub far: f64,
    /// Low-pass dilation added to the 2D covariance diagonal, in pixels² (gsplat `eps2d`).
    pub eps2d: f64,
    /// Per-pixel alphas below this are skipped; opacities below it cull the Gaussian.
    pub alpha_min: f64,
    /// The alpha clamp of the gsplat release being reproduced.
    pub alpha_clamp: AlphaClamp,
    /// A pixel stops compositing when its transmittance would fall to or below this.
    pub transmittance_min: f64,
    /// Expected depth is `D / max(A, depth_eps)` (gsplat `postprocess_render_colors`).
    pub depth_eps: f64,
    /// Background colour composited behind the Gaussians (`None` = black, gsplat's default).
    pub background: Option<[f64; 3]>,
    /// Gradient accumulation of the GPU backward (results agree; not part of a report).
    #[serde(skip)]
    pub grad_accumulation: GradAccumulation,
    /// Tile walk of the GPU compositing kernels (results agree; not part of a report).
    #[serde(skip)]
    pub tile_schedule: TileSchedule,
    /// What a differentiated GPU forward keeps for its backward (results agree; not part of a
    /// report).
    #[serde(skip)]
    pub backward_bins: BackwardBins,
    /// How the GPU backward's units add a splat's gradient (results agree; not part of a
    /// report).
    #[serde(skip)]
    pub grad_combine: GradCombine,
}

impl Default for RasterConfig {
    fn default() -> Self {
        Self {
            near: 0.01,
            far: 1e10,
            eps2d: 0.3,
            alpha_min: 1.0 / 255.0,
            alpha_clamp: AlphaClamp::Gsplat153,
            transmittance_min: 1e-4,
            depth_eps: 1e-10,
            background: None,
            grad_accumulation: GradAccumulation::Auto,
            tile_schedule: TileSchedule::Auto,
            backward_bins: BackwardBins::Keep,
            grad_combine: GradCombine::Auto,
        }
    }
}

impl RasterConfig {
    /// Checks that the settings describe a usable rasterizer; the message names the field.
    pub fn validate(&self) -> Result<(), String> {
        let finite_pos = |name: &str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(format!(
                    "raster config: {name} must be finite and > 0, got {v}"
                ))
            }
        };
        finite_pos("near", self.near)?;
        finite_pos("eps2d", self.eps2d)?;
        finite_pos("alpha_min", self.alpha_min)?;
        finite_pos("transmittance_min", self.transmittance_min)?;
        finite_pos("depth_eps", self.depth_eps)?;
        if !(self.far > self.near) {
            return Err(format!(
                "raster config: far ({}) must be greater than near ({})",
                self.far, self.near
            ));
        }
        if self.alpha_min >= self.alpha_clamp.max_alpha() {
            return Err(format!(
                "raster config: alpha_min ({}) must be below the alpha clamp ({})",
                self.alpha_min,
                self.alpha_clamp.max_alpha()
            ));
        }
        if self.transmittance_min >= 1.0 {
            return Err(format!(
                "raster config: transmittance_min must be < 1, got {}",
                self.transmittance_min
            ));
        }
        if let Some(bg) = self.background
            && bg.iter().any(|c| !c.is_finite())
        {
            return Err(format!(
                "raster config: background must be finite, got {bg:?}"
            ));
        }
        Ok(())
    }
}
