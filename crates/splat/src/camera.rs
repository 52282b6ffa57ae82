//! Pinhole cameras: world-to-camera extrinsics (OpenCV axes: x right, y down, z forward) and
//! pixel intrinsics, plus the EWA frustum clamp limits shared by the forward and backward passes.

use crate::math::{Mat3, Vec3};
use crate::real::Real;

/// Fraction of the half field of view by which gsplat lets the EWA Jacobian look past the image
/// edge before clamping (`persp_proj`: `lim = (W - cx)/fx + 0.3 * tan_fov`).
pub const FRUSTUM_CLAMP_MARGIN: f64 = 0.3;

/// One view: `m = R p + t`, `u = fx m.x / m.z + cx`, `v = fy m.y / m.z + cy`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera<F> {
    pub rot: Mat3<F>,
    pub trans: Vec3<F>,
    pub fx: F,
    pub fy: F,
    pub cx: F,
    pub cy: F,
    pub width: u32,
    pub height: u32,
}

/// Why a camera was rejected.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CameraError {
    #[error("camera {view}: image size must be at least 1x1, got {width}x{height}")]
    EmptyImage {
        view: usize,
        width: u32,
        height: u32,
    },
    #[error("camera {view}: {name} must be finite and > 0, got {value}")]
    BadFocal {
        view: usize,
        name: &'static str,
        value: f64,
    },
    #[error("camera {view}: {name} must be finite, got {value}")]
    NonFinite {
        view: usize,
        name: &'static str,
        value: f64,
    },
    #[error("camera {view}: world_to_camera rotation block is singular (det = {det:e})")]
    Singular { view: usize, det: f64 },
}

/// Clamp limits of `m.x / m.z` (and y) used by the EWA Jacobian.
#[derive(Debug, Clone, Copy)]
pub struct FrustumLimits<F> {
    pub x_neg: F,
    pub x_pos: F,
    pub y_neg: F,
    pub y_pos: F,
}

impl<F: Real> Camera<F> {
    /// Builds a camera from a row-major 4x4 world-to-camera matrix and a row-major 3x3 `K`
    /// (skew and the last row of `K` are ignored, as in gsplat), validating it.
    pub fn from_matrices(
        view: usize,
        viewmat: &[F],
        k: &[F],
        width: u32,
        height: u32,
    ) -> Result<Self, CameraError> {
        if width == 0 || height == 0 {
            return Err(CameraError::EmptyImage {
                view,
                width,
                height,
            });
        }
        let cam = Camera {
            rot: Mat3([
                [viewmat[0], viewmat[1], viewmat[2]],
                [viewmat[4], viewmat[5], viewmat[6]],
                [viewmat[8], viewmat[9], viewmat[10]],
            ]),
            trans: [viewmat[3], viewmat[7], viewmat[11]],
            fx: k[0],
            fy: k[4],
            cx: k[2],
            cy: k[5],
            width,
            height,
        };
        cam.validate(view)?;
        Ok(cam)
    }

    fn validate(&self, view: usize) -> Result<(), CameraError> {
        for (name, v) in [("fx", self.fx), ("fy", self.fy)] {
            if !(v.is_finite() && v > F::zero()) {
                return Err(CameraError::BadFocal {
                    view,
                    name,
                    value: v.to_f64_lossy(),
                });
            }
        }
        for (name, v) in [("cx", self.cx), ("cy", self.cy)] {
            if !v.is_finite() {
                return Err(CameraError::NonFinite {
                    view,
                    name,
                    value: v.to_f64_lossy(),
                });
            }
        }
        if !self.rot.is_finite() || !self.trans.iter().all(|v| v.is_finite()) {
            return Err(CameraError::NonFinite {
                view,
                name: "world_to_camera",
                value: f64::NAN,
            });
        }
        let det = self.rot.det().to_f64_lossy();
        if !(det.abs() > 1e-12) {
            return Err(CameraError::Singular { view, det });
        }
        Ok(())
    }

    /// gsplat's `persp_proj` clamp limits: the Jacobian sees points at most 30% of the half
    /// field of view beyond each image edge, which keeps far off-screen splats from exploding.
    pub fn frustum_limits(&self) -> FrustumLimits<F> {
        let w = F::lit(self.width as f64);
        let h = F::lit(self.height as f64);
        let margin = F::lit(FRUSTUM_CLAMP_MARGIN * 0.5);
        FrustumLimits {
            x_pos: (w - self.cx) / self.fx + margin * w / self.fx,
            x_neg: self.cx / self.fx + margin * w / self.fx,
            y_pos: (h - self.cy) / self.fy + margin * h / self.fy,
            y_neg: self.cy / self.fy + margin * h / self.fy,
        }
    }

    pub fn tiles_x(&self) -> u32 {
        self.width.div_ceil(crate::config::TILE_SIZE)
    }

    pub fn tiles_y(&self) -> u32 {
        self.height.div_ceil(crate::config::TILE_SIZE)
    }
}

/// Gradient of a loss w.r.t. one camera: the rotation block and translation of the
/// world-to-camera matrix, and the four used entries of `K`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct CameraGrad<F> {
    pub rot: Mat3<F>,
    pub trans: Vec3<F>,
    pub fx: F,
    pub fy: F,
    pub cx: F,
    pub cy: F,
}

impl<F: Real> CameraGrad<F> {
    pub fn zero() -> Self {
        CameraGrad {
            rot: Mat3::zero(),
            trans: [F::zero(); 3],
            fx: F::zero(),
            fy: F::zero(),
            cx: F::zero(),
            cy: F::zero(),
        }
    }

    pub fn accumulate(&mut self, o: &Self) {
        self.rot = self.rot.add(&o.rot);
        for i in 0..3 {
            self.trans[i] += o.trans[i];
        }
        self.fx += o.fx;
        self.fy += o.fy;
        self.cx += o.cx;
        self.cy += o.cy;
    }

    /// The gradient laid out like the inputs: a row-major 4x4 (bottom row zero) and 3x3 `K`.
    pub fn to_matrices(&self) -> ([F; 16], [F; 9]) {
        let r = &self.rot.0;
        let t = &self.trans;
        let z = F::zero();
        (
            [
                r[0][0], r[0][1], r[0][2], t[0], r[1][0], r[1][1], r[1][2], t[1], r[2][0], r[2][1],
                r[2][2], t[2], z, z, z, z,
            ],
            [self.fx, z, self.cx, z, self.fy, self.cy, z, z, z],
        )
    }
}
