//! Projection of 3D Gaussians into one camera (gsplat `fully_fused_projection`, EWA splatting)
//! and its exact backward pass, including the gradient w.r.t. the camera itself.

use crate::camera::{Camera, CameraGrad, FrustumLimits};
use crate::config::{RasterConfig, EXTENT_CAP, RADIUS_MAX, TILE_SIZE};
use crate::math::{
    congruence_2x3, conic_vjp, covariance, normalize_quat, normalize_quat_vjp, quat_to_rotmat,
    quat_to_rotmat_vjp, Mat3, Sym2, Vec3,
};
use crate::real::Real;

/// Gaussian parameters as flat row-major slices (activations already applied).
#[derive(Debug, Clone, Copy)]
pub struct Scene<'a, F> {
    /// `[N, 3]` world-space centres.
    pub means: &'a [F],
    /// `[N, 4]` rotations as (w, x, y, z), any norm.
    pub quats: &'a [F],
    /// `[N, 3]` linear scales.
    pub scales: &'a [F],
    /// `[N]` opacities in [0, 1].
    pub opacities: &'a [F],
    /// `[N, 3]` RGB colours (used as given, not clamped, like gsplat without SH).
    pub colors: &'a [F],
}

impl<'a, F: Real> Scene<'a, F> {
    pub fn len(&self) -> usize {
        self.opacities.len()
    }

    /// Rows `first .. first + n` as a scene of their own (one view's set of stacked
    /// Gaussians).
    pub fn rows(&self, first: usize, n: usize) -> Scene<'a, F> {
        Scene {
            means: &self.means[3 * first..3 * (first + n)],
            quats: &self.quats[4 * first..4 * (first + n)],
            scales: &self.scales[3 * first..3 * (first + n)],
            opacities: &self.opacities[first..first + n],
            colors: &self.colors[3 * first..3 * (first + n)],
        }
    }

    pub fn is_empty(&self) -> bool {
        self.opacities.is_empty()
    }

    fn mean(&self, i: usize) -> Vec3<F> {
        [
            self.means[3 * i],
            self.means[3 * i + 1],
            self.means[3 * i + 2],
        ]
    }
    fn quat(&self, i: usize) -> [F; 4] {
        [
            self.quats[4 * i],
            self.quats[4 * i + 1],
            self.quats[4 * i + 2],
            self.quats[4 * i + 3],
        ]
    }
    fn scale(&self, i: usize) -> Vec3<F> {
        [
            self.scales[3 * i],
            self.scales[3 * i + 1],
            self.scales[3 * i + 2],
        ]
    }
    pub fn color(&self, i: usize) -> Vec3<F> {
        [
            self.colors[3 * i],
            self.colors[3 * i + 1],
            self.colors[3 * i + 2],
        ]
    }
}

/// Half-open range of tiles `[x0, x1) x [y0, y1)` a Gaussian may touch.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct TileRect {
    pub x0: u32,
    pub y0: u32,
    pub x1: u32,
    pub y1: u32,
}

impl TileRect {
    pub fn count(&self) -> u32 {
        (self.x1 - self.x0) * (self.y1 - self.y0)
    }
}

/// A Gaussian as seen by one camera, ready for compositing.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Projected<F> {
    pub mean2d: [F; 2],
    pub conic: Sym2<F>,
    /// Camera-space depth of the centre (also the 4th composited channel, "ED").
    pub depth: F,
    pub opacity: F,
    pub color: Vec3<F>,
    pub radius: [i32; 2],
    pub tiles: TileRect,
}

/// Everything the projection computes that its backward pass needs again.
struct Geometry<F> {
    m: Vec3<F>,
    q_hat: [F; 4],
    inv_qnorm: F,
    rq: Mat3<F>,
    mmat: Mat3<F>,
    cov_w: Mat3<F>,
    cov_c: Mat3<F>,
    j: [[F; 3]; 2],
    clamped: [bool; 2],
    t_xy: [F; 2],
    cov2d: Sym2<F>,
    conic: Sym2<F>,
}

fn geometry<F: Real>(
    scene: &Scene<F>,
    i: usize,
    cam: &Camera<F>,
    lim: &FrustumLimits<F>,
    cfg: &RasterConfig,
) -> Option<Geometry<F>> {
    let p = scene.mean(i);
    let s = scene.scale(i);
    if !p.iter().chain(s.iter()).all(|v| v.is_finite()) {
        return None;
    }
    let m = {
        let r = cam.rot.mul_vec(&p);
        [
            r[0] + cam.trans[0],
            r[1] + cam.trans[1],
            r[2] + cam.trans[2],
        ]
    };
    let z = m[2];
    // Cull behind/at the camera plane and beyond far before any division (positive phrasing:
    // NaN depth fails too).
    if !(z >= F::lit(cfg.near) && z <= F::lit(cfg.far)) {
        return None;
    }
    let (q_hat, inv_qnorm) = normalize_quat(scene.quat(i))?;
    let rq = quat_to_rotmat(q_hat);
    let (cov_w, mmat) = covariance(&rq, s);
    let cov_c = cam.rot.mul(&cov_w).mul(&cam.rot.transpose());

    let rz = F::one() / z;
    let rz2 = rz * rz;
    let ux = m[0] * rz;
    let uy = m[1] * rz;
    let cx_ = ux.max(-lim.x_neg).min(lim.x_pos);
    let cy_ = uy.max(-lim.y_neg).min(lim.y_pos);
    let clamped = [cx_ != ux, cy_ != uy];
    let t_xy = [z * cx_, z * cy_];
    let j = [
        [cam.fx * rz, F::zero(), -cam.fx * t_xy[0] * rz2],
        [F::zero(), cam.fy * rz, -cam.fy * t_xy[1] * rz2],
    ];
    let mut cov2d = congruence_2x3(&j, &cov_c);
    let eps = F::lit(cfg.eps2d);
    cov2d.a += eps;
    cov2d.c += eps;
    let det = cov2d.det();
    // eps2d makes det >= eps² in exact arithmetic; anything else is overflow or NaN.
    if !(cov2d.is_finite() && det > F::zero() && det.is_finite()) {
        return None;
    }
    let conic = cov2d.inverse_with_det(det);
    if !conic.is_finite() {
        return None;
    }
    Some(Geometry {
        m,
        q_hat,
        inv_qnorm,
        rq,
        mmat,
        cov_w,
        cov_c,
        j,
        clamped,
        t_xy,
        cov2d,
        conic,
    })
}

/// Projects Gaussian `i`; `None` when it is culled (behind the camera, transparent, degenerate,
/// non-finite or off-screen). Culled Gaussians get radius 0 and no gradient, as in gsplat.
pub fn project_one<F: Real>(
    scene: &Scene<F>,
    i: usize,
    cam: &Camera<F>,
    lim: &FrustumLimits<F>,
    cfg: &RasterConfig,
) -> Option<Projected<F>> {
    let opacity = scene.opacities[i];
    let color = scene.color(i);
    if !(opacity >= F::lit(cfg.alpha_min)
        && opacity.is_finite()
        && color.iter().all(|c| c.is_finite()))
    {
        return None;
    }
    let g = geometry(scene, i, cam, lim, cfg)?;
    // Same arithmetic as gsplat (`fx * x * rz + cx`) so f32 results agree to the last bit.
    let rz = F::one() / g.m[2];
    let mean2d = [cam.fx * g.m[0] * rz + cam.cx, cam.fy * g.m[1] * rz + cam.cy];
    if !(mean2d[0].is_finite() && mean2d[1].is_finite()) {
        return None;
    }
    // Opacity-aware extent: beyond `sqrt(2 ln(255 o))` sigmas alpha < 1/255 anyway.
    let o = opacity.to_f64_lossy();
    let extent = EXTENT_CAP.min((2.0 * (o / cfg.alpha_min).ln()).max(0.0).sqrt());
    let rx = (extent * g.cov2d.a.to_f64_lossy().sqrt())
        .ceil()
        .min(RADIUS_MAX);
    let ry = (extent * g.cov2d.c.to_f64_lossy().sqrt())
        .ceil()
        .min(RADIUS_MAX);
    if !(rx > 0.0 || ry > 0.0) {
        return None;
    }
    let (mx, my) = (mean2d[0].to_f64_lossy(), mean2d[1].to_f64_lossy());
    let (w, h) = (cam.width as f64, cam.height as f64);
    if mx + rx <= 0.0 || mx - rx >= w || my + ry <= 0.0 || my - ry >= h {
        return None;
    }
    let tiles = tile_rect(mx, my, rx, ry, cam.tiles_x(), cam.tiles_y());
    if tiles.count() == 0 {
        return None;
    }
    Some(Projected {
        mean2d,
        conic: g.conic,
        depth: g.m[2],
        opacity,
        color,
        radius: [rx as i32, ry as i32],
        tiles,
    })
}

/// gsplat 1.5.3's conservative tile AABB: `floor((mu - r)/16) .. ceil((mu + r)/16)`, clamped.
/// Any conservative test gives the same image (pixels outside have alpha < 1/255).
pub fn tile_rect(mx: f64, my: f64, rx: f64, ry: f64, tiles_x: u32, tiles_y: u32) -> TileRect {
    let t = TILE_SIZE as f64;
    let clampu = |v: f64, hi: u32| v.max(0.0).min(hi as f64) as u32;
    TileRect {
        x0: clampu(((mx - rx) / t).floor(), tiles_x),
        y0: clampu(((my - ry) / t).floor(), tiles_y),
        x1: clampu(((mx + rx) / t).ceil(), tiles_x),
        y1: clampu(((my + ry) / t).ceil(), tiles_y),
    }
}

/// Number of gradient lanes per projected Gaussian coming out of the compositing backward:
/// mean2d (2), conic (3: Q00, Q01, Q11), opacity, colour (3), depth channel.
pub const PROJECTED_GRAD_LANES: usize = 10;

/// Gradient of a loss w.r.t. one Gaussian's inputs.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct GaussianGrad<F> {
    pub mean: Vec3<F>,
    pub quat: [F; 4],
    pub scale: Vec3<F>,
    pub opacity: F,
    pub color: Vec3<F>,
}

/// Backward of [`project_one`] given the compositing gradient lanes `g` (see
/// [`PROJECTED_GRAD_LANES`]). Returns the Gaussian's gradient and its contribution to the
/// camera's gradient. Must only be called for Gaussians `project_one` kept.
pub fn project_one_vjp<F: Real>(
    scene: &Scene<F>,
    i: usize,
    cam: &Camera<F>,
    lim: &FrustumLimits<F>,
    cfg: &RasterConfig,
    g: &[F; PROJECTED_GRAD_LANES],
) -> (GaussianGrad<F>, CameraGrad<F>) {
    let mut gg = GaussianGrad {
        opacity: g[5],
        color: [g[6], g[7], g[8]],
        ..Default::default()
    };
    let mut cg = CameraGrad::zero();
    let Some(geo) = geometry(scene, i, cam, lim, cfg) else {
        return (gg, cg);
    };
    let two = F::lit(2.0);
    let (x, y, z) = (geo.m[0], geo.m[1], geo.m[2]);
    let rz = F::one() / z;
    let rz2 = rz * rz;
    let rz3 = rz2 * rz;
    let (gu, gv) = (g[0], g[1]);

    // Conic -> 2D covariance (the eps2d blur is additive, so it passes the gradient through).
    let g_cov2d = conic_vjp(&geo.conic, [g[2], g[3], g[4]]);
    // Σ2 = J Σc Jᵀ.
    let g2 = [[g_cov2d.a, g_cov2d.b], [g_cov2d.b, g_cov2d.c]];
    let j = &geo.j;
    // dΣc = Jᵀ G2 J
    let mut g_cov_c = Mat3::zero();
    for a in 0..3 {
        for b in 0..3 {
            let mut acc = F::zero();
            for r in 0..2 {
                for c in 0..2 {
                    acc += j[r][a] * g2[r][c] * j[c][b];
                }
            }
            g_cov_c.0[a][b] = acc;
        }
    }
    // dJ = 2 G2 J Σc
    let mut g_j = [[F::zero(); 3]; 2];
    for r in 0..2 {
        for b in 0..3 {
            let mut acc = F::zero();
            for c in 0..2 {
                for k in 0..3 {
                    acc += g2[r][c] * j[c][k] * geo.cov_c.0[k][b];
                }
            }
            g_j[r][b] = two * acc;
        }
    }

    // Camera-space mean gradient from mu, J and the depth channel.
    let mut gm = [
        cam.fx * rz * gu,
        cam.fy * rz * gv,
        -(cam.fx * x * gu + cam.fy * y * gv) * rz2,
    ];
    cg.fx += x * rz * gu;
    cg.fy += y * rz * gv;
    cg.cx += gu;
    cg.cy += gv;
    gm[2] += g[9];
    // J00 = fx/z, J11 = fy/z.
    gm[2] -= cam.fx * rz2 * g_j[0][0] + cam.fy * rz2 * g_j[1][1];
    cg.fx += rz * g_j[0][0];
    cg.fy += rz * g_j[1][1];
    // J02 = -fx tx/z², J12 = -fy ty/z², with tx = x unless the frustum clamp is active, where
    // tx = z·L and fx·L depends only on cx and the image size.
    let axis = [(0usize, cam.fx, x), (1usize, cam.fy, y)];
    for (k, f, mk) in axis {
        let gjk = g_j[k][2];
        if geo.clamped[k] {
            gm[2] += f * geo.t_xy[k] * rz3 * gjk;
            if k == 0 {
                cg.cx += rz * gjk;
            } else {
                cg.cy += rz * gjk;
            }
        } else {
            gm[k] -= f * rz2 * gjk;
            gm[2] += two * f * mk * rz3 * gjk;
            if k == 0 {
                cg.fx -= mk * rz2 * gjk;
            } else {
                cg.fy -= mk * rz2 * gjk;
            }
        }
    }

    // m = R p + t.
    let p = scene.mean(i);
    let rt = cam.rot.transpose();
    gg.mean = rt.mul_vec(&gm);
    cg.trans = gm;
    for a in 0..3 {
        for b in 0..3 {
            cg.rot.0[a][b] += gm[a] * p[b];
        }
    }
    // Σc = R Σw Rᵀ: dΣw = Rᵀ dΣc R, dR += 2 dΣc R Σw (both symmetric).
    let g_cov_w = rt.mul(&g_cov_c).mul(&cam.rot);
    cg.rot = cg
        .rot
        .add(&g_cov_c.mul(&cam.rot).mul(&geo.cov_w).scale(two));
    // Σw = M Mᵀ: dM = 2 dΣw M; M = Rq diag(s).
    let g_m = g_cov_w.mul(&geo.mmat).scale(two);
    let s = scene.scale(i);
    let mut g_rq = Mat3::zero();
    for a in 0..3 {
        for b in 0..3 {
            g_rq.0[a][b] = g_m.0[a][b] * s[b];
            gg.scale[b] += geo.rq.0[a][b] * g_m.0[a][b];
        }
    }
    let g_qhat = quat_to_rotmat_vjp(geo.q_hat, &g_rq);
    gg.quat = normalize_quat_vjp(geo.q_hat, geo.inv_qnorm, g_qhat);
    (gg, cg)
}
