//! The CPU rasterizer: plain Rust, rayon-parallel, generic over the float type.
//!
//! With `f32` it is the CPU backend's implementation; with `f64` it is the oracle the f32 paths
//! (CPU and CubeCL) are checked against. Results are bit-identical run to run: parallel work
//! writes disjoint outputs and every floating-point reduction runs in a fixed order.

pub mod bins;
pub mod project;
pub mod raster;

use crate::camera::{Camera, CameraGrad};
use crate::config::RasterConfig;
use crate::real::Real;
use crate::views::ViewSets;
use bins::{bin_tiles, TileBins};
use project::{project_one, project_one_vjp, Projected, Scene, PROJECTED_GRAD_LANES};
use raster::{
    raster_tile_backward, raster_tile_forward, tile_pixels, Splat, Thresholds, OUT_CHANNELS,
};
use rayon::prelude::*;

/// Gaussians per rayon task in the per-Gaussian passes (large enough to amortise scheduling,
/// fixed so that chunked reductions are deterministic).
const GAUSSIANS_PER_TASK: usize = 4096;

/// What the forward pass produces for V views of one image size.
#[derive(Debug, Clone)]
pub struct ForwardOutput<F> {
    /// `[V, H, W, 5]` = (R, G, B, accumulated depth, alpha), background not applied.
    pub image: Vec<F>,
    /// `[V, R, 2]` footprint radii in pixels (0 = culled), as gsplat's `radii`; R is
    /// [`ViewSets::radii_rows`].
    pub radii: Vec<i32>,
    /// Gaussians that survived culling, per view.
    pub visible: Vec<usize>,
    /// Gaussian-tile intersections, per view.
    pub intersections: Vec<usize>,
}

/// Gradients of a loss w.r.t. every input of [`render_forward`].
#[derive(Debug, Clone)]
pub struct BackwardOutput<F> {
    pub means: Vec<F>,
    pub quats: Vec<F>,
    pub scales: Vec<F>,
    pub opacities: Vec<F>,
    pub colors: Vec<F>,
    /// `[V, 4, 4]`, bottom rows zero.
    pub viewmats: Vec<F>,
    /// `[V, 3, 3]`, only fx, fy, cx, cy non-zero.
    pub ks: Vec<F>,
}

/// Projection and tile lists of one view.
struct ViewState<F> {
    projected: Vec<Option<Projected<F>>>,
    bins: TileBins,
}

fn prepare_view<F: Real>(scene: &Scene<F>, cam: &Camera<F>, cfg: &RasterConfig) -> ViewState<F> {
    let lim = cam.frustum_limits();
    let projected: Vec<Option<Projected<F>>> = (0..scene.len())
        .into_par_iter()
        .with_min_len(GAUSSIANS_PER_TASK)
        .map(|i| project_one(scene, i, cam, &lim, cfg))
        .collect();
    let bins = bin_tiles(&projected, cam.tiles_x(), cam.tiles_y());
    ViewState { projected, bins }
}

fn tile_splats<F: Real>(state: &ViewState<F>, t: usize, cfg: &RasterConfig) -> Vec<Splat<F>> {
    state
        .bins
        .tile(t)
        .iter()
        .filter_map(|&i| {
            state.projected[i as usize]
                .as_ref()
                .map(|p| Splat::from_projected(p, cfg.alpha_min))
        })
        .collect()
}

/// Renders `cams.len()` views of the scene (all cameras must share one image size).
pub fn render_forward<F: Real>(
    scene: &Scene<F>,
    cams: &[Camera<F>],
    cfg: &RasterConfig,
) -> ForwardOutput<F> {
    render_forward_sets(scene, cams, &ViewSets::Shared, cfg)
}

/// [`render_forward`] where view v renders the rows `sets` gives it.
pub fn render_forward_sets<F: Real>(
    scene: &Scene<F>,
    cams: &[Camera<F>],
    sets: &ViewSets,
    cfg: &RasterConfig,
) -> ForwardOutput<F> {
    let n = scene.len();
    let r = sets.radii_rows(n);
    let mut out = ForwardOutput {
        image: Vec::new(),
        radii: vec![0; cams.len() * r * 2],
        visible: Vec::new(),
        intersections: Vec::new(),
    };
    for (v, cam) in cams.iter().enumerate() {
        let (w, h) = (cam.width as usize, cam.height as usize);
        let mut image = vec![F::zero(); w * h * OUT_CHANNELS];
        let (first, rows) = sets.range(v, n);
        let state = prepare_view(&scene.rows(first, rows), cam, cfg);
        for (i, p) in state.projected.iter().enumerate() {
            if let Some(p) = p {
                out.radii[(v * r + i) * 2] = p.radius[0];
                out.radii[(v * r + i) * 2 + 1] = p.radius[1];
            }
        }
        out.visible.push(state.bins.visible);
        out.intersections.push(state.bins.intersections());
        let th = Thresholds::new(cfg);
        let tiles_x = cam.tiles_x();
        // Tiles with no splats keep the zero image (T = 1): skip them entirely.
        let tiles: Vec<(usize, Vec<F>)> = (0..state.bins.num_tiles())
            .into_par_iter()
            .filter(|&t| !state.bins.tile(t).is_empty())
            .map(|t| {
                let rect = tile_pixels(
                    t as u32 % tiles_x,
                    t as u32 / tiles_x,
                    cam.width,
                    cam.height,
                );
                let mut buf = Vec::new();
                raster_tile_forward(&tile_splats(&state, t, cfg), rect, &th, &mut buf);
                (t, buf)
            })
            .collect();
        for (t, buf) in tiles {
            let (x0, y0, x1, y1) = tile_pixels(
                t as u32 % tiles_x,
                t as u32 / tiles_x,
                cam.width,
                cam.height,
            );
            let tw = (x1 - x0) as usize;
            for (r, y) in (y0..y1).enumerate() {
                let dst = (y as usize * w + x0 as usize) * OUT_CHANNELS;
                image[dst..dst + tw * OUT_CHANNELS]
                    .copy_from_slice(&buf[r * tw * OUT_CHANNELS..(r + 1) * tw * OUT_CHANNELS]);
            }
        }
        out.image.extend_from_slice(&image);
    }
    out
}

/// Gradients of `sum(grad_image * image)` where `image` is [`render_forward`]'s output, i.e.
/// the vector-Jacobian product of the whole renderer, camera included.
pub fn render_backward<F: Real>(
    scene: &Scene<F>,
    cams: &[Camera<F>],
    cfg: &RasterConfig,
    grad_image: &[F],
) -> BackwardOutput<F> {
    render_backward_sets(scene, cams, &ViewSets::Shared, cfg, grad_image)
}

/// [`render_backward`] where view v renders the rows `sets` gives it.
pub fn render_backward_sets<F: Real>(
    scene: &Scene<F>,
    cams: &[Camera<F>],
    sets: &ViewSets,
    cfg: &RasterConfig,
    grad_image: &[F],
) -> BackwardOutput<F> {
    let n = scene.len();
    let mut g = BackwardOutput {
        means: vec![F::zero(); n * 3],
        quats: vec![F::zero(); n * 4],
        scales: vec![F::zero(); n * 3],
        opacities: vec![F::zero(); n],
        colors: vec![F::zero(); n * 3],
        viewmats: Vec::with_capacity(cams.len() * 16),
        ks: Vec::with_capacity(cams.len() * 9),
    };
    let th = Thresholds::new(cfg);
    let mut offset = 0usize;
    for (v, cam) in cams.iter().enumerate() {
        let (w, h) = (cam.width as usize, cam.height as usize);
        let view_grad = &grad_image[offset..offset + w * h * OUT_CHANNELS];
        offset += w * h * OUT_CHANNELS;
        let (first, rows) = sets.range(v, n);
        let view_scene = scene.rows(first, rows);
        let scene = &view_scene;
        let state = prepare_view(scene, cam, cfg);
        let tiles_x = cam.tiles_x();
        // Per-tile partial gradients, reduced below in tile order for determinism.
        let partials: Vec<(usize, Vec<[F; PROJECTED_GRAD_LANES]>)> = (0..state.bins.num_tiles())
            .into_par_iter()
            .filter(|&t| !state.bins.tile(t).is_empty())
            .map(|t| {
                let rect = tile_pixels(
                    t as u32 % tiles_x,
                    t as u32 / tiles_x,
                    cam.width,
                    cam.height,
                );
                let (x0, y0, x1, y1) = rect;
                let mut local_grad =
                    Vec::with_capacity(((x1 - x0) * (y1 - y0)) as usize * OUT_CHANNELS);
                for y in y0..y1 {
                    let src = (y as usize * w + x0 as usize) * OUT_CHANNELS;
                    local_grad.extend_from_slice(
                        &view_grad[src..src + (x1 - x0) as usize * OUT_CHANNELS],
                    );
                }
                let splats = tile_splats(&state, t, cfg);
                let mut lanes = vec![[F::zero(); PROJECTED_GRAD_LANES]; splats.len()];
                raster_tile_backward(&splats, rect, &th, &local_grad, &mut lanes);
                (t, lanes)
            })
            .collect();
        let mut lanes = vec![[F::zero(); PROJECTED_GRAD_LANES]; rows];
        for (t, tile_lanes) in partials {
            for (&i, l) in state.bins.tile(t).iter().zip(tile_lanes.iter()) {
                for (acc, v) in lanes[i as usize].iter_mut().zip(l.iter()) {
                    *acc += *v;
                }
            }
        }
        let lim = cam.frustum_limits();
        // Per-Gaussian projection backward in fixed chunks; each chunk also returns its share of
        // the camera gradient, summed in chunk order.
        let end = first + rows;
        let cam_partials: Vec<CameraGrad<F>> = g.means[3 * first..3 * end]
            .par_chunks_mut(3 * GAUSSIANS_PER_TASK)
            .zip(g.quats[4 * first..4 * end].par_chunks_mut(4 * GAUSSIANS_PER_TASK))
            .zip(g.scales[3 * first..3 * end].par_chunks_mut(3 * GAUSSIANS_PER_TASK))
            .zip(g.opacities[first..end].par_chunks_mut(GAUSSIANS_PER_TASK))
            .zip(g.colors[3 * first..3 * end].par_chunks_mut(3 * GAUSSIANS_PER_TASK))
            .enumerate()
            .map(|(chunk, ((((gm, gq), gs), go), gc))| {
                let mut cg = CameraGrad::zero();
                for local in 0..go.len() {
                    let i = chunk * GAUSSIANS_PER_TASK + local;
                    if state.projected[i].is_none() {
                        continue;
                    }
                    let (gg, cgi) = project_one_vjp(scene, i, cam, &lim, cfg, &lanes[i]);
                    for k in 0..3 {
                        gm[3 * local + k] += gg.mean[k];
                        gs[3 * local + k] += gg.scale[k];
                        gc[3 * local + k] += gg.color[k];
                    }
                    for k in 0..4 {
                        gq[4 * local + k] += gg.quat[k];
                    }
                    go[local] += gg.opacity;
                    cg.accumulate(&cgi);
                }
                cg
            })
            .collect();
        let mut cg = CameraGrad::zero();
        for p in &cam_partials {
            cg.accumulate(p);
        }
        let (vm, k) = cg.to_matrices();
        g.viewmats.extend_from_slice(&vm);
        g.ks.extend_from_slice(&k);
    }
    g
}
