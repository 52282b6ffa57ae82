//! Shared helpers: run the CPU path on a host scene in any float type.

use envision4d_splat::camera::Camera;
use envision4d_splat::cpu::project::{project_one, Scene};
use envision4d_splat::cpu::{render_backward, render_forward, BackwardOutput, ForwardOutput};
use envision4d_splat::real::Real;
use envision4d_splat::testkit::HostScene;
use envision4d_splat::RasterConfig;

/// One camera as (row-major world-to-camera 4x4, row-major K).
pub type View = ([f64; 16], [f64; 9]);

pub fn cast<F: Real>(v: &[f64]) -> Vec<F> {
    v.iter().map(|x| F::lit(*x)).collect()
}

pub struct Owned<F> {
    pub arrays: [Vec<F>; 5],
    pub cams: Vec<Camera<F>>,
}

impl<F: Real> Owned<F> {
    pub fn new(scene: &HostScene, views: &[View], w: u32, h: u32) -> Self {
        let cams = views
            .iter()
            .enumerate()
            .map(|(i, (vm, k))| {
                Camera::from_matrices(i, &cast::<F>(vm), &cast::<F>(k), w, h).expect("valid camera")
            })
            .collect();
        Owned {
            arrays: [
                cast(&scene.means),
                cast(&scene.quats),
                cast(&scene.scales),
                cast(&scene.opacities),
                cast(&scene.colors),
            ],
            cams,
        }
    }

    pub fn scene(&self) -> Scene<'_, F> {
        let [m, q, s, o, c] = &self.arrays;
        Scene {
            means: m,
            quats: q,
            scales: s,
            opacities: o,
            colors: c,
        }
    }

    pub fn forward(&self, cfg: &RasterConfig) -> ForwardOutput<F> {
        render_forward(&self.scene(), &self.cams, cfg)
    }

    pub fn backward(&self, cfg: &RasterConfig, grad: &[F]) -> BackwardOutput<F> {
        render_backward(&self.scene(), &self.cams, cfg, grad)
    }
}

pub fn forward64(
    scene: &HostScene,
    views: &[View],
    w: u32,
    h: u32,
    cfg: &RasterConfig,
) -> ForwardOutput<f64> {
    Owned::<f64>::new(scene, views, w, h).forward(cfg)
}

/// Pixels where some Gaussian's alpha is within `margin` of a threshold (the 1/255 cutoff or
/// the clamp): finite differences are meaningless there because the image jumps.
pub fn threshold_mask(
    scene: &HostScene,
    views: &[View],
    w: u32,
    h: u32,
    cfg: &RasterConfig,
    margin: f64,
) -> Vec<bool> {
    let owned = Owned::<f64>::new(scene, views, w, h);
    let sc = owned.scene();
    let mut mask = Vec::new();
    for cam in &owned.cams {
        let lim = cam.frustum_limits();
        let proj: Vec<_> = (0..sc.len())
            .filter_map(|i| project_one(&sc, i, cam, &lim, cfg))
            .collect();
        for y in 0..h {
            for x in 0..w {
                let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
                let near = proj.iter().any(|p| {
                    let (dx, dy) = (p.mean2d[0] - px, p.mean2d[1] - py);
                    let sigma =
                        0.5 * (p.conic.a * dx * dx + p.conic.c * dy * dy) + p.conic.b * dx * dy;
                    let a = p.opacity * (-sigma).exp();
                    (a - cfg.alpha_min).abs() < margin
                        || (a - cfg.alpha_clamp.max_alpha()).abs() < margin
                });
                mask.push(near);
            }
        }
    }
    mask
}

pub fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

pub fn to64<F: Real>(v: &[F]) -> Vec<f64> {
    v.iter().map(|x| x.to_f64_lossy()).collect()
}
