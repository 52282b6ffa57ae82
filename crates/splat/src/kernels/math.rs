//! `#[cube]` mirrors of [`crate::math`] and of the shared geometry of `cpu/project.rs`.
//!
//! Every helper keeps the CPU code's operand order (left-to-right sums, same products) so the
//! f32 kernels agree with the f32 CPU path to rounding; the parity tests compare them.

use cubecl::prelude::*;

/// Lanes of the per-view camera record uploaded by the host (see `launch::camera_record`):
/// R (9, row-major), t (3), fx, fy, cx, cy, frustum limits (x_neg, x_pos, y_neg, y_pos).
pub const CAM_LANES: usize = 20;

/// Exponent bits of an IEEE f32: all set means inf or NaN.
const F32_EXP_MASK: u32 = 0x7f80_0000;

/// Finiteness by bit pattern, so no compiler fast-math assumption can fold it away.
#[cube]
pub fn finite(x: f32) -> bool {
    (x.to_bits() & F32_EXP_MASK) != F32_EXP_MASK
}

/// A row-major 3x3 matrix.
#[derive(CubeType, Clone, Copy)]
#[expand(derive(Clone, Copy))]
pub struct M3 {
    pub a00: f32,
    pub a01: f32,
    pub a02: f32,
    pub a10: f32,
    pub a11: f32,
    pub a12: f32,
    pub a20: f32,
    pub a21: f32,
    pub a22: f32,
}

/// A 3-vector.
#[derive(CubeType, Clone, Copy)]
#[expand(derive(Clone, Copy))]
pub struct V3 {
    pub x: f32,
    pub y: f32,
    pub z: f32,
}

/// A symmetric 2x2 `[[a, b], [b, c]]`.
#[derive(CubeType, Clone, Copy)]
#[expand(derive(Clone, Copy))]
pub struct S2 {
    pub a: f32,
    pub b: f32,
    pub c: f32,
}

/// A quaternion (w, x, y, z).
#[derive(CubeType, Clone, Copy)]
#[expand(derive(Clone, Copy))]
pub struct Q4 {
    pub w: f32,
    pub x: f32,
    pub y: f32,
    pub z: f32,
}

#[cube]
pub fn m3_new(
    a00: f32,
    a01: f32,
    a02: f32,
    a10: f32,
    a11: f32,
    a12: f32,
    a20: f32,
    a21: f32,
    a22: f32,
) -> M3 {
    M3 {
        a00,
        a01,
        a02,
        a10,
        a11,
        a12,
        a20,
        a21,
        a22,
    }
}

#[cube]
pub fn m3_transpose(m: M3) -> M3 {
    m3_new(
        m.a00, m.a10, m.a20, m.a01, m.a11, m.a21, m.a02, m.a12, m.a22,
    )
}

/// `a[i][0] b[0][j] + a[i][1] b[1][j] + a[i][2] b[2][j]`, summed left to right like `Mat3::mul`.
#[cube]
pub fn m3_mul(a: M3, b: M3) -> M3 {
    m3_new(
        a.a00 * b.a00 + a.a01 * b.a10 + a.a02 * b.a20,
        a.a00 * b.a01 + a.a01 * b.a11 + a.a02 * b.a21,
        a.a00 * b.a02 + a.a01 * b.a12 + a.a02 * b.a22,
        a.a10 * b.a00 + a.a11 * b.a10 + a.a12 * b.a20,
        a.a10 * b.a01 + a.a11 * b.a11 + a.a12 * b.a21,
        a.a10 * b.a02 + a.a11 * b.a12 + a.a12 * b.a22,
        a.a20 * b.a00 + a.a21 * b.a10 + a.a22 * b.a20,
        a.a20 * b.a01 + a.a21 * b.a11 + a.a22 * b.a21,
        a.a20 * b.a02 + a.a21 * b.a12 + a.a22 * b.a22,
    )
}

#[cube]
pub fn m3_mul_vec(m: M3, v: V3) -> V3 {
    V3 {
        x: m.a00 * v.x + m.a01 * v.y + m.a02 * v.z,
        y: m.a10 * v.x + m.a11 * v.y + m.a12 * v.z,
        z: m.a20 * v.x + m.a21 * v.y + m.a22 * v.z,
    }
}

#[cube]
pub fn m3_add(a: M3, b: M3) -> M3 {
    m3_new(
        a.a00 + b.a00,
        a.a01 + b.a01,
        a.a02 + b.a02,
        a.a10 + b.a10,
        a.a11 + b.a11,
        a.a12 + b.a12,
        a.a20 + b.a20,
        a.a21 + b.a21,
        a.a22 + b.a22,
    )
}

#[cube]
pub fn m3_scale(m: M3, s: f32) -> M3 {
    m3_new(
        m.a00 * s,
        m.a01 * s,
        m.a02 * s,
        m.a10 * s,
        m.a11 * s,
        m.a12 * s,
        m.a20 * s,
        m.a21 * s,
        m.a22 * s,
    )
}

/// `M = R_q diag(s)` (column j scaled by s_j), as in `math::covariance`.
#[cube]
pub fn m3_scale_cols(m: M3, s: V3) -> M3 {
    m3_new(
        m.a00 * s.x,
        m.a01 * s.y,
        m.a02 * s.z,
        m.a10 * s.x,
        m.a11 * s.y,
        m.a12 * s.z,
        m.a20 * s.x,
        m.a21 * s.y,
        m.a22 * s.z,
    )
}

/// Rotation matrix of a unit quaternion (`math::quat_to_rotmat`).
#[cube]
pub fn quat_to_rotmat(q: Q4) -> M3 {
    let (w, x, y, z) = (q.w, q.x, q.y, q.z);
    let two = 2.0f32;
    let one = 1.0f32;
    m3_new(
        one - two * (y * y + z * z),
        two * (x * y - w * z),
        two * (x * z + w * y),
        two * (x * y + w * z),
        one - two * (x * x + z * z),
        two * (y * z - w * x),
        two * (x * z - w * y),
        two * (y * z + w * x),
        one - two * (x * x + y * y),
    )
}

/// VJP of [`quat_to_rotmat`](fn@quat_to_rotmat) (`math::quat_to_rotmat_vjp`).
#[cube]
pub fn quat_to_rotmat_vjp(q: Q4, g: M3) -> Q4 {
    let (w, x, y, z) = (q.w, q.x, q.y, q.z);
    let two = 2.0f32;
    let four = 4.0f32;
    Q4 {
        w: two * (-z * g.a01 + y * g.a02 + z * g.a10 - x * g.a12 - y * g.a20 + x * g.a21),
        x: two * (y * g.a01 + z * g.a02 + y * g.a10 - w * g.a12 + z * g.a20 + w * g.a21)
            - four * x * (g.a11 + g.a22),
        y: two * (x * g.a01 + w * g.a02 + x * g.a10 + z * g.a12 - w * g.a20 + z * g.a21)
            - four * y * (g.a00 + g.a22),
        z: two * (-w * g.a01 + x * g.a02 + w * g.a10 + y * g.a12 + x * g.a20 + y * g.a21)
            - four * z * (g.a00 + g.a11),
    }
}

/// VJP of quaternion normalisation: `(g - (g·q̂) q̂) / |q|`.
#[cube]
pub fn normalize_quat_vjp(q_hat: Q4, inv_norm: f32, g: Q4) -> Q4 {
    let dot = g.w * q_hat.w + g.x * q_hat.x + g.y * q_hat.y + g.z * q_hat.z;
    Q4 {
        w: (g.w - dot * q_hat.w) * inv_norm,
        x: (g.x - dot * q_hat.x) * inv_norm,
        y: (g.y - dot * q_hat.y) * inv_norm,
        z: (g.z - dot * q_hat.z) * inv_norm,
    }
}

/// `A X Aᵀ` for the EWA Jacobian `A = [[j00, 0, j02], [0, j11, j12]]` and symmetric `X`
/// (`math::congruence_2x3` with the zeros written out, so the sums keep the CPU's order).
#[cube]
pub fn congruence_2x3(j00: f32, j02: f32, j11: f32, j12: f32, x: M3) -> S2 {
    let zero = 0.0f32;
    // Row r of A times X.
    let ax00 = j00 * x.a00 + zero * x.a10 + j02 * x.a20;
    let ax01 = j00 * x.a01 + zero * x.a11 + j02 * x.a21;
    let ax02 = j00 * x.a02 + zero * x.a12 + j02 * x.a22;
    let ax10 = zero * x.a00 + j11 * x.a10 + j12 * x.a20;
    let ax11 = zero * x.a01 + j11 * x.a11 + j12 * x.a21;
    let ax12 = zero * x.a02 + j11 * x.a12 + j12 * x.a22;
    S2 {
        a: ax00 * j00 + ax01 * zero + ax02 * j02,
        b: ax00 * zero + ax01 * j11 + ax02 * j12,
        c: ax10 * zero + ax11 * j11 + ax12 * j12,
    }
}

/// VJP of the conic `Q = Σ'⁻¹` given the gradients of the stored lanes (Q00, Q01, Q11); the
/// off-diagonal lane appears twice in the matrix, hence the halving (`math::conic_vjp`).
#[cube]
pub fn conic_vjp(q: S2, g0: f32, g1: f32, g2: f32) -> S2 {
    let gb = g1 * 0.5f32;
    let qg00 = q.a * g0 + q.b * gb;
    let qg01 = q.a * gb + q.b * g2;
    let qg10 = q.b * g0 + q.c * gb;
    let qg11 = q.b * gb + q.c * g2;
    S2 {
        a: -(qg00 * q.a + qg01 * q.b),
        b: -(qg00 * q.b + qg01 * q.c),
        c: -(qg10 * q.b + qg11 * q.c),
    }
}

/// One view's camera, read from its `CAM_LANES` record.
#[derive(CubeType, Clone, Copy)]
#[expand(derive(Clone, Copy))]
pub struct Cam {
    pub rot: M3,
    pub t: V3,
    pub fx: f32,
    pub fy: f32,
    pub cx: f32,
    pub cy: f32,
    pub x_neg: f32,
    pub x_pos: f32,
    pub y_neg: f32,
    pub y_pos: f32,
}

#[cube]
pub fn load_cam(c: &Tensor<f32>) -> Cam {
    Cam {
        rot: m3_new(c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7], c[8]),
        t: V3 {
            x: c[9],
            y: c[10],
            z: c[11],
        },
        fx: c[12],
        fy: c[13],
        cx: c[14],
        cy: c[15],
        x_neg: c[16],
        x_pos: c[17],
        y_neg: c[18],
        y_pos: c[19],
    }
}
