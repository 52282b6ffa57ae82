//! Small typed math values shared by the readers and the synthetic world. Rigid transforms
//! are computed with `glam` (f64); [`Mat4`] is the row-major form files and JSON hold.

use glam::{DMat3, DMat4, DVec3};
use serde::{Deserialize, Serialize};
use std::ops::{Add, Mul, Neg, Sub};

/// A 3-vector in metres (or a direction).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Vec3 {
    pub x: f64,
    pub y: f64,
    pub z: f64,
}

impl Vec3 {
    pub const ZERO: Vec3 = Vec3::new(0.0, 0.0, 0.0);
    pub const fn new(x: f64, y: f64, z: f64) -> Self {
        Vec3 { x, y, z }
    }
    pub fn dot(self, o: Vec3) -> f64 {
        self.x * o.x + self.y * o.y + self.z * o.z
    }
    pub fn cross(self, o: Vec3) -> Vec3 {
        Vec3::new(
            self.y * o.z - self.z * o.y,
            self.z * o.x - self.x * o.z,
            self.x * o.y - self.y * o.x,
        )
    }
    pub fn norm(self) -> f64 {
        self.dot(self).sqrt()
    }
    pub fn normalized(self) -> Vec3 {
        let n = self.norm();
        if n > 0.0 {
            self * (1.0 / n)
        } else {
            self
        }
    }
    pub fn get(self, axis: usize) -> f64 {
        match axis {
            0 => self.x,
            1 => self.y,
            _ => self.z,
        }
    }
    pub fn to_array(self) -> [f64; 3] {
        [self.x, self.y, self.z]
    }
}

impl Add for Vec3 {
    type Output = Vec3;
    fn add(self, o: Vec3) -> Vec3 {
        Vec3::new(self.x + o.x, self.y + o.y, self.z + o.z)
    }
}
impl Sub for Vec3 {
    type Output = Vec3;
    fn sub(self, o: Vec3) -> Vec3 {
        Vec3::new(self.x - o.x, self.y - o.y, self.z - o.z)
    }
}
impl Mul<f64> for Vec3 {
    type Output = Vec3;
    fn mul(self, s: f64) -> Vec3 {
        Vec3::new(self.x * s, self.y * s, self.z * s)
    }
}
impl Neg for Vec3 {
    type Output = Vec3;
    fn neg(self) -> Vec3 {
        Vec3::new(-self.x, -self.y, -self.z)
    }
}

/// A row-major 4x4 matrix (rigid transforms: world-to-camera, camera-to-ego, ...).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Mat4(pub [[f64; 4]; 4]);

impl Mat4 {
    pub const IDENTITY: Mat4 = Mat4([
        [1.0, 0.0, 0.0, 0.0],
        [0.0, 1.0, 0.0, 0.0],
        [0.0, 0.0, 1.0, 0.0],
        [0.0, 0.0, 0.0, 1.0],
    ]);

    /// Builds [R | t] from rotation rows and a translation.
    pub fn from_rt(r: [[f64; 3]; 3], t: Vec3) -> Mat4 {
        let t = t.to_array();
        let mut m = Mat4::IDENTITY;
        for i in 0..3 {
            m.0[i][..3].copy_from_slice(&r[i]);
            m.0[i][3] = t[i];
        }
        m
    }
    /// The same matrix as glam's (column-major) `DMat4`.
    pub fn to_glam(&self) -> DMat4 {
        DMat4::from_cols_array_2d(&self.0).transpose()
    }
    pub fn from_glam(m: DMat4) -> Mat4 {
        Mat4(m.transpose().to_cols_array_2d())
    }
    /// The rotation block `R` of `[R | t]`.
    pub fn rotation(&self) -> DMat3 {
        DMat3::from_mat4(self.to_glam())
    }
    /// The translation column `t` of `[R | t]`.
    pub fn translation(&self) -> DVec3 {
        DVec3::new(self.0[0][3], self.0[1][3], self.0[2][3])
    }
    pub fn mul(&self, o: &Mat4) -> Mat4 {
        Mat4::from_glam(self.to_glam() * o.to_glam())
    }
    pub fn transform_point(&self, p: Vec3) -> Vec3 {
        let m = &self.0;
        Vec3::new(
            m[0][0] * p.x + m[0][1] * p.y + m[0][2] * p.z + m[0][3],
            m[1][0] * p.x + m[1][1] * p.y + m[1][2] * p.z + m[1][3],
            m[2][0] * p.x + m[2][1] * p.y + m[2][2] * p.z + m[2][3],
        )
    }
    /// Inverse of a rigid transform [R | t] -> [R^T | -R^T t]. Callers check rigidity
    /// with [`Mat4::rigid_error`] first where the matrix comes from a file.
    pub fn rigid_inverse(&self) -> Mat4 {
        let rt = self.rotation().transpose();
        let t = -(rt * self.translation());
        Mat4::from_glam(DMat4::from_cols(
            rt.x_axis.extend(0.0),
            rt.y_axis.extend(0.0),
            rt.z_axis.extend(0.0),
            t.extend(1.0),
        ))
    }
    /// Largest deviation of R^T R from I and of the last row from (0,0,0,1); ~0 for rigid.
    pub fn rigid_error(&self) -> f64 {
        let m = &self.0;
        let mut err: f64 = 0.0;
        for i in 0..3 {
            for j in 0..3 {
                let d: f64 = (0..3).map(|k| m[k][i] * m[k][j]).sum();
                err = err.max((d - if i == j { 1.0 } else { 0.0 }).abs());
            }
        }
        for (j, want) in [0.0, 0.0, 0.0, 1.0].iter().enumerate() {
            err = err.max((m[3][j] - want).abs());
        }
        err
    }
    pub fn is_finite(&self) -> bool {
        self.0.iter().flatten().all(|v| v.is_finite())
    }
}

/// Pinhole intrinsics in pixels. Pixel (col u, row v) covers [u, u+1) x [v, v+1); its
/// centre is (u + 0.5, v + 0.5), so a centred principal point is (W/2, H/2).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Intrinsics {
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
}

impl Intrinsics {
    /// Intrinsics after resizing an image of `from` (H, W) to `to` (H, W). Exact for the
    /// pixel-edge convention above: continuous coordinates scale by the size ratio.
    pub fn resized(&self, from: (usize, usize), to: (usize, usize)) -> Intrinsics {
        let sy = to.0 as f64 / from.0 as f64;
        let sx = to.1 as f64 / from.1 as f64;
        Intrinsics {
            fx: self.fx * sx,
            fy: self.fy * sy,
            cx: self.cx * sx,
            cy: self.cy * sy,
        }
    }
    /// Intrinsics after cropping with the top-left corner at (row, col) = `offset`.
    pub fn cropped(&self, offset: (usize, usize)) -> Intrinsics {
        Intrinsics {
            cx: self.cx - offset.1 as f64,
            cy: self.cy - offset.0 as f64,
            ..*self
        }
    }
    /// Camera-frame point -> continuous pixel coordinates (x right, y down); None behind.
    pub fn project(&self, p: Vec3) -> Option<(f64, f64)> {
        (p.z > 0.0).then(|| (self.fx * p.x / p.z + self.cx, self.fy * p.y / p.z + self.cy))
    }
    /// Continuous pixel coordinates and z-depth -> camera-frame point.
    pub fn unproject(&self, x: f64, y: f64, depth: f64) -> Vec3 {
        Vec3::new(
            (x - self.cx) / self.fx * depth,
            (y - self.cy) / self.fy * depth,
            depth,
        )
    }
}
