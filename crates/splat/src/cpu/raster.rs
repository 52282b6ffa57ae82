//! Front-to-back alpha compositing of one 16x16 tile (gsplat `rasterize_to_pixels`) and its
//! backward pass.
//!
//! Channels are (R, G, B, D): the camera-space depth of each centre is composited as a fourth
//! colour, exactly gsplat's "RGB+ED" mode; the expected-depth division and the background are
//! applied later in ordinary tensor ops. Per pixel the output is (R, G, B, D, A) with A = 1 - T.

use super::project::{Projected, PROJECTED_GRAD_LANES};
use crate::config::{RasterConfig, TILE_SIZE};
use crate::real::Real;

/// Channels written per pixel: R, G, B, accumulated depth, alpha.
pub const OUT_CHANNELS: usize = 5;

/// A projected Gaussian packed for the per-pixel loop (one cache-friendly record).
#[derive(Debug, Clone, Copy)]
pub struct Splat<F> {
    pub mx: F,
    pub my: F,
    pub q00: F,
    pub q01: F,
    pub q11: F,
    pub opacity: F,
    /// (R, G, B, depth).
    pub feat: [F; 4],
    /// Beyond this Mahalanobis half-distance alpha is certainly below the cutoff, so the pixel
    /// can skip the `exp` (see [`SIGMA_CUT_MARGIN`]).
    pub sigma_cut: F,
}

/// Safety margin on the early-reject distance: at `sigma = ln(o / alpha_min) + margin`, alpha
/// is `alpha_min * exp(-margin)`, below the cutoff by a relative 1e-4, far more than any rounding
/// in `exp`. Skipping there therefore never changes a decision: results are bit-identical to
/// evaluating every pixel, and most far-away pixels of a tile avoid the `exp` entirely.
pub const SIGMA_CUT_MARGIN: f64 = 1e-4;

impl<F: Real> Splat<F> {
    pub fn from_projected(p: &Projected<F>, alpha_min: f64) -> Self {
        let cut = (p.opacity.to_f64_lossy() / alpha_min).ln() + SIGMA_CUT_MARGIN;
        Splat {
            sigma_cut: F::lit(cut),
            mx: p.mean2d[0],
            my: p.mean2d[1],
            q00: p.conic.a,
            q01: p.conic.b,
            q11: p.conic.c,
            opacity: p.opacity,
            feat: [p.color[0], p.color[1], p.color[2], p.depth],
        }
    }

    /// `(sigma, vis, alpha)` at pixel centre `(px, py)`; `None` when the splat is skipped there.
    /// Forward and backward both call this, so their skip decisions cannot diverge.
    #[inline(always)]
    fn eval(&self, px: F, py: F, alpha_min: F, alpha_max: F) -> Option<(F, F, F, F)> {
        let dx = self.mx - px;
        let dy = self.my - py;
        let half = F::lit(0.5);
        let sigma = half * (self.q00 * dx * dx + self.q11 * dy * dy) + self.q01 * dx * dy;
        if sigma > self.sigma_cut {
            return None;
        }
        let vis = (-sigma).exp();
        let alpha = alpha_max.min(self.opacity * vis);
        if sigma < F::zero() || alpha < alpha_min {
            return None;
        }
        Some((dx, dy, vis, alpha))
    }
}

/// Numeric thresholds in the working float type.
#[derive(Debug, Clone, Copy)]
pub struct Thresholds<F> {
    pub alpha_min: F,
    pub alpha_max: F,
    pub t_min: F,
}

impl<F: Real> Thresholds<F> {
    pub fn new(cfg: &RasterConfig) -> Self {
        Thresholds {
            alpha_min: F::lit(cfg.alpha_min),
            alpha_max: F::lit(cfg.alpha_clamp.max_alpha()),
            t_min: F::lit(cfg.transmittance_min),
        }
    }
}

/// Pixel range covered by tile `(tx, ty)` in an image of `width x height`.
pub fn tile_pixels(tx: u32, ty: u32, width: u32, height: u32) -> (u32, u32, u32, u32) {
    let x0 = tx * TILE_SIZE;
    let y0 = ty * TILE_SIZE;
    (
        x0,
        y0,
        (x0 + TILE_SIZE).min(width),
        (y0 + TILE_SIZE).min(height),
    )
}

/// Composites one pixel; returns (R, G, B, D) and the final transmittance.
#[inline]
fn composite_pixel<F: Real>(splats: &[Splat<F>], px: F, py: F, th: &Thresholds<F>) -> ([F; 4], F) {
    let mut t = F::one();
    let mut acc = [F::zero(); 4];
    for s in splats {
        let Some((_, _, _, alpha)) = s.eval(px, py, th.alpha_min, th.alpha_max) else {
            continue;
        };
        let next_t = t * (F::one() - alpha);
        // Exclusive stop: the splat that would drive T below the threshold is not composited.
        if next_t <= th.t_min {
            break;
        }
        let fac = alpha * t;
        for c in 0..4 {
            acc[c] += s.feat[c] * fac;
        }
        t = next_t;
    }
    (acc, t)
}

/// Forward pass of one tile: writes `OUT_CHANNELS` values per pixel of the tile, row-major
/// within the tile rectangle, into `out` (length = tile pixels * OUT_CHANNELS).
pub fn raster_tile_forward<F: Real>(
    splats: &[Splat<F>],
    rect: (u32, u32, u32, u32),
    th: &Thresholds<F>,
    out: &mut Vec<F>,
) {
    let (x0, y0, x1, y1) = rect;
    out.clear();
    let half = F::lit(0.5);
    for y in y0..y1 {
        for x in x0..x1 {
            let (acc, t) =
                composite_pixel(splats, F::lit(x as f64) + half, F::lit(y as f64) + half, th);
            out.extend_from_slice(&[acc[0], acc[1], acc[2], acc[3], F::one() - t]);
        }
    }
}

/// One composited splat of a pixel, remembered for the reverse sweep.
#[derive(Debug, Clone, Copy)]
struct Contribution<F> {
    k: usize,
    dx: F,
    dy: F,
    vis: F,
    alpha: F,
    t: F,
}

/// Backward pass of one tile. `grad_out` holds `OUT_CHANNELS` gradients per tile pixel (same
/// layout as the forward output); `grads` (one `[F; PROJECTED_GRAD_LANES]` per splat) is
/// accumulated into.
///
/// The forward is replayed to record each contributing splat's alpha and transmittance, then
/// swept back to front (gsplat's order). Recording T instead of recovering it by division keeps
/// the result exact near opacity 1, where gsplat's `T / (1 - alpha)` loses precision.
pub fn raster_tile_backward<F: Real>(
    splats: &[Splat<F>],
    rect: (u32, u32, u32, u32),
    th: &Thresholds<F>,
    grad_out: &[F],
    grads: &mut [[F; PROJECTED_GRAD_LANES]],
) {
    let (x0, y0, x1, y1) = rect;
    let half = F::lit(0.5);
    let mut stack: Vec<Contribution<F>> = Vec::new();
    let mut pix = 0usize;
    for y in y0..y1 {
        for x in x0..x1 {
            let g = &grad_out[pix * OUT_CHANNELS..(pix + 1) * OUT_CHANNELS];
            pix += 1;
            if g.iter().all(|v| *v == F::zero()) {
                continue;
            }
            let (px, py) = (F::lit(x as f64) + half, F::lit(y as f64) + half);
            stack.clear();
            let mut t = F::one();
            for (k, s) in splats.iter().enumerate() {
                let Some((dx, dy, vis, alpha)) = s.eval(px, py, th.alpha_min, th.alpha_max) else {
                    continue;
                };
                let next_t = t * (F::one() - alpha);
                if next_t <= th.t_min {
                    break;
                }
                stack.push(Contribution {
                    k,
                    dx,
                    dy,
                    vis,
                    alpha,
                    t,
                });
                t = next_t;
            }
            let t_final = t;
            let g_feat = [g[0], g[1], g[2], g[3]];
            let g_alpha_out = g[4];
            let mut behind = [F::zero(); 4];
            for c in stack.iter().rev() {
                let s = &splats[c.k];
                let fac = c.alpha * c.t;
                let lane = &mut grads[c.k];
                for ch in 0..3 {
                    lane[6 + ch] += fac * g_feat[ch];
                }
                lane[9] += fac * g_feat[3];
                let one_minus = F::one() - c.alpha;
                let mut v_alpha = g_alpha_out * t_final / one_minus;
                for ch in 0..4 {
                    v_alpha += g_feat[ch] * (s.feat[ch] * c.t - behind[ch] / one_minus);
                }
                // When the clamp is active alpha no longer depends on opacity or geometry.
                if s.opacity * c.vis <= th.alpha_max {
                    let v_sigma = -s.opacity * c.vis * v_alpha;
                    lane[0] += v_sigma * (s.q00 * c.dx + s.q01 * c.dy);
                    lane[1] += v_sigma * (s.q01 * c.dx + s.q11 * c.dy);
                    lane[2] += half * c.dx * c.dx * v_sigma;
                    lane[3] += c.dx * c.dy * v_sigma;
                    lane[4] += half * c.dy * c.dy * v_sigma;
                    lane[5] += c.vis * v_alpha;
                }
                for ch in 0..4 {
                    behind[ch] += s.feat[ch] * fac;
                }
            }
        }
    }
}
