//! Small typed math values for the projection and its vector-Jacobian products (VJPs).
//!
//! Every forward formula sits next to its VJP so the two cannot drift apart; the CPU path
//! (and the f64 oracle) use these, and the CubeCL kernels mirror them line for line.

use crate::real::Real;

/// A 3-vector.
pub type Vec3<F> = [F; 3];

/// A row-major 3x3 matrix.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Mat3<F>(pub [[F; 3]; 3]);

impl<F: Real> Mat3<F> {
    pub fn zero() -> Self {
        Mat3([[F::zero(); 3]; 3])
    }

    pub fn transpose(&self) -> Self {
        let m = &self.0;
        Mat3([
            [m[0][0], m[1][0], m[2][0]],
            [m[0][1], m[1][1], m[2][1]],
            [m[0][2], m[1][2], m[2][2]],
        ])
    }

    pub fn mul(&self, o: &Self) -> Self {
        let mut r = Self::zero();
        for i in 0..3 {
            for j in 0..3 {
                r.0[i][j] =
                    self.0[i][0] * o.0[0][j] + self.0[i][1] * o.0[1][j] + self.0[i][2] * o.0[2][j];
            }
        }
        r
    }

    pub fn mul_vec(&self, v: &Vec3<F>) -> Vec3<F> {
        let m = &self.0;
        [
            m[0][0] * v[0] + m[0][1] * v[1] + m[0][2] * v[2],
            m[1][0] * v[0] + m[1][1] * v[1] + m[1][2] * v[2],
            m[2][0] * v[0] + m[2][1] * v[1] + m[2][2] * v[2],
        ]
    }

    pub fn add(&self, o: &Self) -> Self {
        let mut r = *self;
        for i in 0..3 {
            for j in 0..3 {
                r.0[i][j] += o.0[i][j];
            }
        }
        r
    }

    pub fn scale(&self, s: F) -> Self {
        let mut r = *self;
        for row in r.0.iter_mut() {
            for v in row.iter_mut() {
                *v *= s;
            }
        }
        r
    }

    pub fn det(&self) -> F {
        let m = &self.0;
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    }

    pub fn is_finite(&self) -> bool {
        self.0.iter().all(|r| r.iter().all(|v| v.is_finite()))
    }
}

/// A symmetric 2x2 matrix `[[a, b], [b, c]]` (2D covariances and conics).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Sym2<F> {
    pub a: F,
    pub b: F,
    pub c: F,
}

impl<F: Real> Sym2<F> {
    pub fn det(&self) -> F {
        self.a * self.c - self.b * self.b
    }

    /// Inverse given a precomputed determinant (callers cull `det <= 0` first).
    pub fn inverse_with_det(&self, det: F) -> Self {
        let inv = F::one() / det;
        Sym2 {
            a: self.c * inv,
            b: -self.b * inv,
            c: self.a * inv,
        }
    }

    pub fn is_finite(&self) -> bool {
        self.a.is_finite() && self.b.is_finite() && self.c.is_finite()
    }
}

/// Rotation matrix of a *unit* quaternion given as (w, x, y, z).
pub fn quat_to_rotmat<F: Real>(q: [F; 4]) -> Mat3<F> {
    let [w, x, y, z] = q;
    let two = F::lit(2.0);
    let one = F::one();
    Mat3([
        [
            one - two * (y * y + z * z),
            two * (x * y - w * z),
            two * (x * z + w * y),
        ],
        [
            two * (x * y + w * z),
            one - two * (x * x + z * z),
            two * (y * z - w * x),
        ],
        [
            two * (x * z - w * y),
            two * (y * z + w * x),
            one - two * (x * x + y * y),
        ],
    ])
}

/// VJP of [`quat_to_rotmat`]: gradient w.r.t. the unit quaternion given `g = dL/dR`.
pub fn quat_to_rotmat_vjp<F: Real>(q: [F; 4], g: &Mat3<F>) -> [F; 4] {
    let [w, x, y, z] = q;
    let g = &g.0;
    let two = F::lit(2.0);
    let four = F::lit(4.0);
    [
        two * (-z * g[0][1] + y * g[0][2] + z * g[1][0] - x * g[1][2] - y * g[2][0] + x * g[2][1]),
        two * (y * g[0][1] + z * g[0][2] + y * g[1][0] - w * g[1][2] + z * g[2][0] + w * g[2][1])
            - four * x * (g[1][1] + g[2][2]),
        two * (x * g[0][1] + w * g[0][2] + x * g[1][0] + z * g[1][2] - w * g[2][0] + z * g[2][1])
            - four * y * (g[0][0] + g[2][2]),
        two * (-w * g[0][1] + x * g[0][2] + w * g[1][0] + y * g[1][2] + x * g[2][0] + y * g[2][1])
            - four * z * (g[0][0] + g[1][1]),
    ]
}

/// Normalises a quaternion; `None` when its norm is too small or not finite (then culled).
pub fn normalize_quat<F: Real>(q: [F; 4]) -> Option<([F; 4], F)> {
    let n2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
    // Positive phrasing: a NaN norm fails this test too.
    if !(n2.is_finite() && n2 > F::lit(crate::config::QUAT_NORM2_MIN)) {
        return None;
    }
    let inv = F::one() / n2.sqrt();
    Some(([q[0] * inv, q[1] * inv, q[2] * inv, q[3] * inv], inv))
}

/// VJP of normalisation: `dL/dq = (g - (g·q̂) q̂) / |q|` (no radial component).
pub fn normalize_quat_vjp<F: Real>(q_hat: [F; 4], inv_norm: F, g: [F; 4]) -> [F; 4] {
    let dot = g[0] * q_hat[0] + g[1] * q_hat[1] + g[2] * q_hat[2] + g[3] * q_hat[3];
    [
        (g[0] - dot * q_hat[0]) * inv_norm,
        (g[1] - dot * q_hat[1]) * inv_norm,
        (g[2] - dot * q_hat[2]) * inv_norm,
        (g[3] - dot * q_hat[3]) * inv_norm,
    ]
}

/// World covariance `Σ = (R_q S)(R_q S)ᵀ`; also returns `M = R_q S` for the backward pass.
pub fn covariance<F: Real>(rq: &Mat3<F>, s: Vec3<F>) -> (Mat3<F>, Mat3<F>) {
    let mut m = *rq;
    for row in m.0.iter_mut() {
        for (j, v) in row.iter_mut().enumerate() {
            *v *= s[j];
        }
    }
    (m.mul(&m.transpose()), m)
}

/// `A X Aᵀ` for a 2x3 `A` and symmetric 3x3 `X`, as a `Sym2`.
pub fn congruence_2x3<F: Real>(a: &[[F; 3]; 2], x: &Mat3<F>) -> Sym2<F> {
    let ax0 = row_times(&a[0], x);
    let ax1 = row_times(&a[1], x);
    Sym2 {
        a: dot3(&ax0, &a[0]),
        b: dot3(&ax0, &a[1]),
        c: dot3(&ax1, &a[1]),
    }
}

fn row_times<F: Real>(r: &[F; 3], x: &Mat3<F>) -> [F; 3] {
    [
        r[0] * x.0[0][0] + r[1] * x.0[1][0] + r[2] * x.0[2][0],
        r[0] * x.0[0][1] + r[1] * x.0[1][1] + r[2] * x.0[2][1],
        r[0] * x.0[0][2] + r[1] * x.0[1][2] + r[2] * x.0[2][2],
    ]
}

pub fn dot3<F: Real>(a: &[F; 3], b: &[F; 3]) -> F {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// VJP of the conic `Q = Σ'⁻¹` w.r.t. `Σ'`, given the gradient of the three stored conic
/// lanes `(Q00, Q01, Q11)`. `Q01` appears once in the stored form but twice in the matrix,
/// hence the halving of the off-diagonal (the classic bug this guards against).
pub fn conic_vjp<F: Real>(q: &Sym2<F>, g: [F; 3]) -> Sym2<F> {
    let half = F::lit(0.5);
    let gq = Sym2 {
        a: g[0],
        b: g[1] * half,
        c: g[2],
    };
    // dΣ' = -Q G Q, with Q, G symmetric.
    let qg00 = q.a * gq.a + q.b * gq.b;
    let qg01 = q.a * gq.b + q.b * gq.c;
    let qg10 = q.b * gq.a + q.c * gq.b;
    let qg11 = q.b * gq.b + q.c * gq.c;
    Sym2 {
        a: -(qg00 * q.a + qg01 * q.b),
        b: -(qg00 * q.b + qg01 * q.c),
        c: -(qg10 * q.b + qg11 * q.c),
    }
}
