//! The Gaussian adapter (`GaussianAdapter` of the release): raw per-pixel predictions of the
//! context frames → world-space 3D Gaussians, and `gaussians_at`, which moves them to a target
//! time with self-exclusion for the rasterizer.
//!
//! * means: the depth is a distance along the *unit* ray through the pixel centre;
//! * scales: `(s_min + (s_max - s_min)·σ(raw)) · depth · 0.1·(1/f_x + 1/f_y)`;
//! * rotations: the release's order mix-up is reproduced exactly (trained weights rely on
//!   it): `r = raw/(|raw|+1e-8)`, camera rotation of the xyzw quaternion `(r3, r0, r1, r2)`,
//!   rotated to world, converted back (robust, largest-component candidate) to **xyzw with
//!   w >= 0**, and handed to the rasterizer, which reads it as wxyz;
//! * colours `σ(raw)`, opacity `σ(raw)` through the (here identity) opacity mapping.

use crate::motion::target_slot;
use burn::tensor::activation::sigmoid;
use burn::tensor::{Int, Tensor};

/// Added to the quaternion norm before dividing (release: `1e-8`).
pub const QUAT_NORM_EPS: f64 = 1e-8;
/// Floor of the candidate denominators in the matrix→quaternion conversion (pytorch3d).
pub const QUAT_CANDIDATE_FLOOR: f64 = 0.1;
/// Pixel-footprint factor of the scale multiplier.
pub const SCALE_PIXEL_FACTOR: f64 = 0.1;

/// The release's opacity schedule `e = 2^(initial + min(step/warm_up, 1)(final - initial))`,
/// `opacity = 0.5 (1 - (1-p)^e + p^(1/e))`; the shipped config makes it the identity.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OpacityMapping {
    pub initial: f64,
    pub final_: f64,
    pub warm_up: f64,
}

impl Default for OpacityMapping {
    fn default() -> Self {
        OpacityMapping {
            initial: 0.0,
            final_: 0.0,
            warm_up: 1.0,
        }
    }
}

impl OpacityMapping {
    pub fn apply<const D: usize>(&self, p: Tensor<D>, step: u64) -> Tensor<D> {
        let frac = (step as f64 / self.warm_up).min(1.0);
        let e = 2f64.powf(self.initial + frac * (self.final_ - self.initial));
        if e == 1.0 {
            return p; // 0.5(1 - (1-p) + p) = p exactly; skip the pow round trip.
        }
        let a = p
            .clone()
            .neg()
            .add_scalar(1.0)
            .powf_scalar(e)
            .neg()
            .add_scalar(1.0);
        (a + p.powf_scalar(1.0 / e)).mul_scalar(0.5)
    }
}

/// World-space Gaussians of the context frames (`G = H·W` per frame, index `y·W + x`).
#[derive(Debug, Clone)]
pub struct AdaptedGaussians {
    /// `[B, T_c, G, 3]`
    pub means: Tensor<4>,
    /// `[B, T_c, G, 3]`
    pub scales: Tensor<4>,
    /// `[B, T_c, G, 4]` xyzw with w >= 0 (read as wxyz by the rasterizer, as in the release).
    pub rotations: Tensor<4>,
    /// `[B, T_c, G, 3]`
    pub colors: Tensor<4>,
    /// `[B, T_c, G]`
    pub opacities: Tensor<3>,
    /// `[B, T_c, N-1, G, 3]` displacement of source i's Gaussians to each other timestamp.
    pub motions: Tensor<5>,
}

fn col<const D: usize>(t: &Tensor<D>, i: usize) -> Tensor<D> {
    let dims = t.dims();
    let mut ranges = dims.map(|d| 0..d);
    ranges[D - 1] = i..i + 1;
    t.clone().slice(ranges)
}

/// Rotation matrix entries (row-major, 9 tensors) of xyzw quaternions with `s = 2/|q|²`.
fn quat_xyzw_to_mat(x: Tensor<4>, y: Tensor<4>, z: Tensor<4>, w: Tensor<4>) -> [Tensor<4>; 9] {
    let s = (x.clone() * x.clone()
        + y.clone() * y.clone()
        + z.clone() * z.clone()
        + w.clone() * w.clone())
    .recip()
    .mul_scalar(2.0);
    let one_minus = |t: Tensor<4>| t.neg().add_scalar(1.0);
    [
        one_minus(s.clone() * (y.clone() * y.clone() + z.clone() * z.clone())),
        s.clone() * (x.clone() * y.clone() - z.clone() * w.clone()),
        s.clone() * (x.clone() * z.clone() + y.clone() * w.clone()),
        s.clone() * (x.clone() * y.clone() + z.clone() * w.clone()),
        one_minus(s.clone() * (x.clone() * x.clone() + z.clone() * z.clone())),
        s.clone() * (y.clone() * z.clone() - x.clone() * w.clone()),
        s.clone() * (x.clone() * z.clone() - y.clone() * w.clone()),
        s.clone() * (y.clone() * z.clone() + x.clone() * w.clone()),
        one_minus(s * (x.clone() * x + y.clone() * y)),
    ]
}

/// Floor under the square root of [`mat_to_quat_xyzw`]: keeps the (masked-out) gradient
/// finite; values in (0, 1e-30) are the only ones it changes, by < 1e-15.
const SQRT_FLOOR: f64 = 1e-30;

/// Robust matrix → quaternion (pytorch3d's): four candidates, the one with the largest
/// |component| wins; returned as xyzw with w >= 0. `m`: 9 row-major entries `[.., 1]`.
fn mat_to_quat_xyzw(m: &[Tensor<4>; 9]) -> Tensor<4> {
    let [m00, m01, m02, m10, m11, m12, m20, m21, m22] = m.clone();
    // pytorch3d's `_sqrt_positive_part`: sqrt where positive, 0 elsewhere, with a ZERO
    // gradient where not positive. `clamp_min(0).sqrt()` has the same values but its
    // gradient there is 0·∞ = NaN, which poisoned every parameter upstream of the rotations.
    let sqrt_pos = |t: Tensor<4>| {
        let not_pos = t.clone().lower_equal_elem(0.0);
        t.clamp_min(SQRT_FLOOR).sqrt().mask_fill(not_pos, 0.0)
    };
    let q_abs = [
        sqrt_pos(m00.clone().add_scalar(1.0) + m11.clone() + m22.clone()),
        sqrt_pos(m00.clone().add_scalar(1.0) - m11.clone() - m22.clone()),
        sqrt_pos(m00.clone().neg().add_scalar(1.0) + m11.clone() - m22.clone()),
        sqrt_pos(m00.clone().neg().add_scalar(1.0) - m11.clone() + m22.clone()),
    ];
    // Candidates in (w, x, y, z), one per row.
    let rows = [
        [
            q_abs[0].clone().powf_scalar(2.0),
            m21.clone() - m12.clone(),
            m02.clone() - m20.clone(),
            m10.clone() - m01.clone(),
        ],
        [
            m21.clone() - m12.clone(),
            q_abs[1].clone().powf_scalar(2.0),
            m10.clone() + m01.clone(),
            m02.clone() + m20.clone(),
        ],
        [
            m02.clone() - m20.clone(),
            m10.clone() + m01.clone(),
            q_abs[2].clone().powf_scalar(2.0),
            m12.clone() + m21.clone(),
        ],
        [
            m10 - m01,
            m20 + m02,
            m21 + m12,
            q_abs[3].clone().powf_scalar(2.0),
        ],
    ];
    let abs_all = Tensor::cat(q_abs.to_vec(), 3);
    let [b, s, g, _] = abs_all.dims();
    let device = abs_all.device();
    let best = abs_all.clone().argmax(3);
    let classes = Tensor::<1, Int>::arange(0..4, &device)
        .reshape([1, 1, 1, 4])
        .expand([b, s, g, 4]);
    let onehot = best.expand([b, s, g, 4]).equal(classes).float();
    let mut q = Tensor::<4>::zeros([b, s, g, 4], &device);
    for (r, row) in rows.into_iter().enumerate() {
        let denom = col(&abs_all, r)
            .clamp_min(QUAT_CANDIDATE_FLOOR)
            .mul_scalar(2.0);
        let cand = Tensor::cat(row.to_vec(), 3) / denom;
        q = q + cand * col(&onehot, r);
    }
    // wxyz -> xyzw, then make w non-negative.
    let xyzw = Tensor::cat(vec![col(&q, 1), col(&q, 2), col(&q, 3), col(&q, 0)], 3);
    let sign = col(&xyzw, 3)
        .lower_elem(0.0)
        .float()
        .mul_scalar(-2.0)
        .add_scalar(1.0);
    xyzw * sign
}

/// Scale ranges of the adapter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScaleRange {
    pub min: f64,
    pub max: f64,
}

/// Turns raw predictions into world-space Gaussians.
///
/// `extrinsics [B, T_c, 4, 4]` world→camera; `intrinsics_norm [B, T_c, 3, 3]` (row 0 / W,
/// row 1 / H); `depth [B, T_c, H, W]`; `opacities [B, T_c, H, W]` (already mapped);
/// `raw [B, T_c, H, W, 10]` (scale 3, rotation 4, colour 3); `motions [B, T_c·K, H, W, 3]`.
pub fn adapt(
    extrinsics: Tensor<4>,
    intrinsics_norm: Tensor<4>,
    depth: Tensor<4>,
    opacities: Tensor<4>,
    raw: Tensor<5>,
    motions: Tensor<5>,
    scale: ScaleRange,
) -> AdaptedGaussians {
    let [b, s, h, w] = depth.dims();
    let g = h * w;
    let device = depth.device();
    let per_frame = |t: Tensor<4>, r: usize, c: usize| {
        t.slice([0..b, 0..s, r..r + 1, c..c + 1])
            .reshape([b, s, 1, 1])
    };
    let (fx, fy, cx, cy) = (
        per_frame(intrinsics_norm.clone(), 0, 0),
        per_frame(intrinsics_norm.clone(), 1, 1),
        per_frame(intrinsics_norm.clone(), 0, 2),
        per_frame(intrinsics_norm, 1, 2),
    );
    // Pixel centres in normalised coordinates, flattened row-major (index y·W + x).
    let u: Vec<f32> = (0..g).map(|i| ((i % w) as f32 + 0.5) / w as f32).collect();
    let v: Vec<f32> = (0..g).map(|i| ((i / w) as f32 + 0.5) / h as f32).collect();
    let u = Tensor::<1>::from_floats(u.as_slice(), &device).reshape([1, 1, g, 1]);
    let v = Tensor::<1>::from_floats(v.as_slice(), &device).reshape([1, 1, g, 1]);
    let dx = (u - cx) / fx.clone();
    let dy = (v - cy) / fy.clone();
    let dz = dx.ones_like();
    let dir = Tensor::cat(vec![dx, dy, dz], 3);
    let dir = dir.clone() / dir.powf_scalar(2.0).sum_dim(3).sqrt();
    // Camera-to-world: R_c2w = Rᵀ, origin = -Rᵀ t. Row vectors: world_dir = dir · R.
    let rot = extrinsics.clone().slice([0..b, 0..s, 0..3, 0..3]);
    let trans = extrinsics.slice([0..b, 0..s, 0..3, 3..4]);
    let origin = rot
        .clone()
        .transpose()
        .matmul(trans)
        .neg()
        .reshape([b, s, 1, 3]);
    let world_dir = dir.expand([b, s, g, 3]).matmul(rot.clone());
    let d = depth.reshape([b, s, g, 1]);
    let means = origin + world_dir * d.clone();

    let raw = raw.reshape([b, s, g, 10]);
    let ch = |a: usize, z: usize| raw.clone().slice([0..b, 0..s, 0..g, a..z]);
    // 0.1·(1/f_x + 1/f_y) with pixel focal lengths.
    let multiplier = (fx.mul_scalar(w as f64).recip() + fy.mul_scalar(h as f64).recip())
        .mul_scalar(SCALE_PIXEL_FACTOR);
    let scales = sigmoid(ch(0, 3))
        .mul_scalar(scale.max - scale.min)
        .add_scalar(scale.min)
        * d
        * multiplier;

    let r = ch(3, 7);
    let r = r.clone()
        / r.powf_scalar(2.0)
            .sum_dim(3)
            .sqrt()
            .add_scalar(QUAT_NORM_EPS);
    // The release reorders to (r3, r0, r1, r2) and reads that as xyzw.
    let cam = quat_xyzw_to_mat(col(&r, 3), col(&r, 0), col(&r, 1), col(&r, 2));
    // R_world = R_c2w · R_cam, with R_c2w[i][k] = R[k][i].
    let rc = |i: usize, k: usize| {
        rot.clone()
            .slice([0..b, 0..s, k..k + 1, i..i + 1])
            .reshape([b, s, 1, 1])
    };
    let world: [Tensor<4>; 9] = std::array::from_fn(|e| {
        let (i, j) = (e / 3, e % 3);
        (0..3)
            .map(|k| rc(i, k) * cam[k * 3 + j].clone())
            .reduce(|a, c| a + c)
            .expect("three terms")
    });
    let rotations = mat_to_quat_xyzw(&world);

    let colors = sigmoid(ch(7, 10));
    let k = motions.dims()[1] / s;
    let motions = motions.reshape([b, s, k, g, 3]);
    AdaptedGaussians {
        means,
        scales,
        rotations,
        colors,
        opacities: opacities.reshape([b, s, g]),
        motions,
    }
}

/// Whether a frame is rendered without its own Gaussians (paper §3.4).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Exclusion {
    /// Every target uses only the other frames' Gaussians, moved to the target time.
    SelfExclusive,
    /// Geometric warm-up: a context frame also uses its own Gaussians, unmoved.
    IncludeOwn,
    /// Only source frame `i`'s Gaussians, moved to the target time (the appendix's
    /// cross-frame table: `1→0` renders frame 0 from frame 1 alone).
    OnlySource(usize),
}

/// Gaussians of batch element `b` as seen at timestamp `j`: the union over source frames
/// `i` (ascending) of `means_i + motion_{i→j}`, other attributes unchanged. Returns
/// `(means [M,3], quats [M,4], scales [M,3], opacities [M], colors [M,3])`.
pub fn gaussians_at(
    a: &AdaptedGaussians,
    batch: usize,
    j: usize,
    exclusion: Exclusion,
) -> (Tensor<2>, Tensor<2>, Tensor<2>, Tensor<1>, Tensor<2>) {
    let [_, s, g, _] = a.means.dims();
    if let Exclusion::OnlySource(src) = exclusion {
        assert!(
            src < s,
            "OnlySource({src}) but there are {s} context frames"
        );
    }
    let take4 = |t: &Tensor<4>, i: usize, c: usize| {
        t.clone()
            .slice([batch..batch + 1, i..i + 1, 0..g, 0..c])
            .reshape([g, c])
    };
    let (mut means, mut quats, mut scales, mut opac, mut colors) =
        (vec![], vec![], vec![], vec![], vec![]);
    for i in 0..s {
        if matches!(exclusion, Exclusion::OnlySource(src) if src != i) {
            continue;
        }
        let moved = if i == j {
            if exclusion == Exclusion::SelfExclusive {
                continue;
            }
            take4(&a.means, i, 3)
        } else {
            let slot = target_slot(i, j);
            let m = a
                .motions
                .clone()
                .slice([batch..batch + 1, i..i + 1, slot..slot + 1, 0..g, 0..3])
                .reshape([g, 3]);
            take4(&a.means, i, 3) + m
        };
        means.push(moved);
        quats.push(take4(&a.rotations, i, 4));
        scales.push(take4(&a.scales, i, 3));
        colors.push(take4(&a.colors, i, 3));
        opac.push(
            a.opacities
                .clone()
                .slice([batch..batch + 1, i..i + 1, 0..g])
                .reshape([g]),
        );
    }
    (
        Tensor::cat(means, 0),
        Tensor::cat(quats, 0),
        Tensor::cat(scales, 0),
        Tensor::cat(opac, 0),
        Tensor::cat(colors, 0),
    )
}
