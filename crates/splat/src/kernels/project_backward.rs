//! Backward of the projection for one view (`project_one_vjp` in `cpu/project.rs`): one thread
//! per Gaussian, no atomics.
//!
//! The view's Gaussians are input rows `first .. first + n` (as in the forward); their
//! gradients are *added* into the flat `[N,3] / [N,4] / [N,3] / [N] / [N,3]` buffers
//! (views run one after another on the same stream, so the read-modify-write is race free);
//! the camera partials of this view are *written* to `cam_part [N, CAM_GRAD_LANES]`
//! (R row-major 9, t 3, fx, fy, cx, cy; zero for culled Gaussians) and reduced by the host.

use super::geometry::geometry;
use super::math::*;
use super::project_forward::{META_LANES, RECORD_LANES};
use cubecl::prelude::*;

/// Lanes of one camera-gradient partial.
pub const CAM_GRAD_LANES: usize = 16;

/// `Σ_r Σ_c J[r][a] G2[r][c] J[c][b]` in the CPU's loop order (column a of J is
/// `(ja0, ja1)`, column b is `(jb0, jb1)`).
#[cube]
fn jt_g_j(ja0: f32, ja1: f32, jb0: f32, jb1: f32, g: S2) -> f32 {
    let mut acc = 0.0f32;
    acc += ja0 * g.a * jb0;
    acc += ja0 * g.b * jb1;
    acc += ja1 * g.b * jb0;
    acc += ja1 * g.c * jb1;
    acc
}

/// `2 Σ_c Σ_k G2[r][c] J[c][k] Σc[k][b]` for row `(gr0, gr1)` of G2 and column b of Σc.
#[cube]
fn g_j_cov(
    gr0: f32,
    gr1: f32,
    j00: f32,
    j02: f32,
    j11: f32,
    j12: f32,
    c0: f32,
    c1: f32,
    c2: f32,
) -> f32 {
    let zero = 0.0f32;
    let mut acc = 0.0f32;
    acc += gr0 * j00 * c0;
    acc += gr0 * zero * c1;
    acc += gr0 * j02 * c2;
    acc += gr1 * zero * c0;
    acc += gr1 * j11 * c1;
    acc += gr1 * j12 * c2;
    2.0f32 * acc
}

#[cube(launch)]
#[allow(clippy::too_many_arguments)]
pub fn project_backward(
    means: &Tensor<f32>,
    quats: &Tensor<f32>,
    scales: &Tensor<f32>,
    cam_rec: &Tensor<f32>,
    meta: &Tensor<f32>,
    v_proj: &Tensor<f32>,
    g_means: &mut Tensor<f32>,
    g_quats: &mut Tensor<f32>,
    g_scales: &mut Tensor<f32>,
    g_opacities: &mut Tensor<f32>,
    g_colors: &mut Tensor<f32>,
    cam_part: &mut Tensor<f32>,
    first: u32,
    n: u32,
    near: f32,
    far: f32,
    eps2d: f32,
) {
    let i = ABSOLUTE_POS;
    if i >= n as usize {
        terminate!();
    }
    let cp = i * CAM_GRAD_LANES;
    let mo = i * META_LANES;
    let visible = meta[mo + 2] > meta[mo] && meta[mo + 3] > meta[mo + 1];
    let gi = first as usize + i;
    let cam = load_cam(cam_rec);
    let geo = geometry(means, quats, scales, gi, cam, near, far, eps2d);
    if !(visible && geo.valid) {
        // Culled: no gradient from this view.
        for k in 0..CAM_GRAD_LANES {
            cam_part[cp + k] = 0.0f32;
        }
        terminate!();
    }
    let l = i * RECORD_LANES;
    let (gu, gv) = (v_proj[l], v_proj[l + 1]);
    g_opacities[gi] += v_proj[l + 5];
    g_colors[gi * 3] += v_proj[l + 6];
    g_colors[gi * 3 + 1] += v_proj[l + 7];
    g_colors[gi * 3 + 2] += v_proj[l + 8];

    let two = 2.0f32;
    let (x, y, z) = (geo.m.x, geo.m.y, geo.m.z);
    let rz = 1.0f32 / z;
    let rz2 = rz * rz;
    let rz3 = rz2 * rz;
    let zero = 0.0f32;

    // Conic -> 2D covariance (the eps2d blur is additive and passes the gradient through).
    let g2 = conic_vjp(geo.conic, v_proj[l + 2], v_proj[l + 3], v_proj[l + 4]);
    // dΣc = Jᵀ G2 J; columns of J: (j00, 0), (0, j11), (j02, j12).
    let (j00, j02, j11, j12) = (geo.j00, geo.j02, geo.j11, geo.j12);
    let g_cov_c = m3_new(
        jt_g_j(j00, zero, j00, zero, g2),
        jt_g_j(j00, zero, zero, j11, g2),
        jt_g_j(j00, zero, j02, j12, g2),
        jt_g_j(zero, j11, j00, zero, g2),
        jt_g_j(zero, j11, zero, j11, g2),
        jt_g_j(zero, j11, j02, j12, g2),
        jt_g_j(j02, j12, j00, zero, g2),
        jt_g_j(j02, j12, zero, j11, g2),
        jt_g_j(j02, j12, j02, j12, g2),
    );
    // dJ = 2 G2 J Σc (only the entries that are not structurally zero are needed).
    let cc = geo.cov_c;
    let gj00 = g_j_cov(g2.a, g2.b, j00, j02, j11, j12, cc.a00, cc.a10, cc.a20);
    let gj02 = g_j_cov(g2.a, g2.b, j00, j02, j11, j12, cc.a02, cc.a12, cc.a22);
    let gj11 = g_j_cov(g2.b, g2.c, j00, j02, j11, j12, cc.a01, cc.a11, cc.a21);
    let gj12 = g_j_cov(g2.b, g2.c, j00, j02, j11, j12, cc.a02, cc.a12, cc.a22);

    // Camera-space mean gradient from mu, J and the depth channel.
    let mut gm_x = cam.fx * rz * gu;
    let mut gm_y = cam.fy * rz * gv;
    let mut gm_z = (zero - (cam.fx * x * gu + cam.fy * y * gv)) * rz2;
    let mut c_fx = x * rz * gu;
    let mut c_fy = y * rz * gv;
    let mut c_cx = gu;
    let mut c_cy = gv;
    gm_z += v_proj[l + 9];
    gm_z -= cam.fx * rz2 * gj00 + cam.fy * rz2 * gj11;
    c_fx += rz * gj00;
    c_fy += rz * gj11;
    // J02 = -fx tx/z²: tx = x unless the frustum clamp is active (then tx = z·L).
    if geo.clamped_x {
        gm_z += cam.fx * geo.tx * rz3 * gj02;
        c_cx += rz * gj02;
    } else {
        gm_x -= cam.fx * rz2 * gj02;
        gm_z += two * cam.fx * x * rz3 * gj02;
        c_fx -= x * rz2 * gj02;
    }
    if geo.clamped_y {
        gm_z += cam.fy * geo.ty * rz3 * gj12;
        c_cy += rz * gj12;
    } else {
        gm_y -= cam.fy * rz2 * gj12;
        gm_z += two * cam.fy * y * rz3 * gj12;
        c_fy -= y * rz2 * gj12;
    }

    // m = R p + t.
    let gm = V3 {
        x: gm_x,
        y: gm_y,
        z: gm_z,
    };
    let rt = m3_transpose(cam.rot);
    let g_mean = m3_mul_vec(rt, gm);
    g_means[gi * 3] += g_mean.x;
    g_means[gi * 3 + 1] += g_mean.y;
    g_means[gi * 3 + 2] += g_mean.z;
    let p = V3 {
        x: means[gi * 3],
        y: means[gi * 3 + 1],
        z: means[gi * 3 + 2],
    };
    let outer = m3_new(
        gm.x * p.x,
        gm.x * p.y,
        gm.x * p.z,
        gm.y * p.x,
        gm.y * p.y,
        gm.y * p.z,
        gm.z * p.x,
        gm.z * p.y,
        gm.z * p.z,
    );
    // Σc = R Σw Rᵀ: dΣw = Rᵀ dΣc R, dR += 2 dΣc R Σw.
    let g_cov_w = m3_mul(m3_mul(rt, g_cov_c), cam.rot);
    let g_rot = m3_add(
        outer,
        m3_scale(m3_mul(m3_mul(g_cov_c, cam.rot), geo.cov_w), two),
    );
    cam_part[cp] = g_rot.a00;
    cam_part[cp + 1] = g_rot.a01;
    cam_part[cp + 2] = g_rot.a02;
    cam_part[cp + 3] = g_rot.a10;
    cam_part[cp + 4] = g_rot.a11;
    cam_part[cp + 5] = g_rot.a12;
    cam_part[cp + 6] = g_rot.a20;
    cam_part[cp + 7] = g_rot.a21;
    cam_part[cp + 8] = g_rot.a22;
    cam_part[cp + 9] = gm.x;
    cam_part[cp + 10] = gm.y;
    cam_part[cp + 11] = gm.z;
    cam_part[cp + 12] = c_fx;
    cam_part[cp + 13] = c_fy;
    cam_part[cp + 14] = c_cx;
    cam_part[cp + 15] = c_cy;

    // Σw = M Mᵀ: dM = 2 dΣw M; M = Rq diag(s).
    let g_m = m3_scale(m3_mul(g_cov_w, geo.mmat), two);
    let s = V3 {
        x: scales[gi * 3],
        y: scales[gi * 3 + 1],
        z: scales[gi * 3 + 2],
    };
    let g_rq = m3_scale_cols(g_m, s);
    let rq = geo.rq;
    g_scales[gi * 3] += rq.a00 * g_m.a00 + rq.a10 * g_m.a10 + rq.a20 * g_m.a20;
    g_scales[gi * 3 + 1] += rq.a01 * g_m.a01 + rq.a11 * g_m.a11 + rq.a21 * g_m.a21;
    g_scales[gi * 3 + 2] += rq.a02 * g_m.a02 + rq.a12 * g_m.a12 + rq.a22 * g_m.a22;
    let g_qhat = quat_to_rotmat_vjp(geo.q_hat, g_rq);
    let g_q = normalize_quat_vjp(geo.q_hat, geo.inv_qnorm, g_qhat);
    g_quats[gi * 4] += g_q.w;
    g_quats[gi * 4 + 1] += g_q.x;
    g_quats[gi * 4 + 2] += g_q.y;
    g_quats[gi * 4 + 3] += g_q.z;
}
