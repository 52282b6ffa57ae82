//! Central finite differences (float64) against the analytic backward, for every input:
//! means, quaternions, scales, opacities, colours, the world-to-camera matrix and K.

use crate::common::{forward64, threshold_mask, Owned, View};
use envision4d_splat::cpu::raster::OUT_CHANNELS;
use envision4d_splat::testkit::{
    intrinsics, look_at, random_scene, HostScene, SceneSpec, SplitMix64,
};
use envision4d_splat::RasterConfig;

const W: u32 = 40;
const H: u32 = 32;

/// Loss weights per output value (random, zero on pixels next to a threshold).
fn weights(
    scene: &HostScene,
    views: &[View],
    cfg: &RasterConfig,
    seed: u64,
    channel_scale: [f64; 5],
) -> Vec<f64> {
    let mask = threshold_mask(scene, views, W, H, cfg, 2e-4);
    let mut rng = SplitMix64::new(seed);
    let mut w = Vec::with_capacity(mask.len() * OUT_CHANNELS);
    for m in mask {
        for s in channel_scale {
            let r = rng.range(-1.0, 1.0) * s;
            w.push(if m { 0.0 } else { r });
        }
    }
    w
}

fn loss(scene: &HostScene, views: &[View], cfg: &RasterConfig, w: &[f64]) -> f64 {
    forward64(scene, views, W, H, cfg)
        .image
        .iter()
        .zip(w)
        .map(|(a, b)| a * b)
        .sum()
}

/// Checks one parameter array by central differences; `get` picks the array out of the
/// (scene, views) pair so cameras and Gaussians share one driver.
fn check(
    name: &str,
    scene: &HostScene,
    views: &[View],
    cfg: &RasterConfig,
    w: &[f64],
    analytic: &[f64],
    entries: &[usize],
    perturb: &dyn Fn(&mut HostScene, &mut Vec<View>, usize, f64),
) {
    let mut worst = 0.0f64;
    for &e in entries {
        let eps = 1e-6;
        let (mut s1, mut v1) = (scene.clone(), views.to_vec());
        perturb(&mut s1, &mut v1, e, eps);
        let (mut s2, mut v2) = (scene.clone(), views.to_vec());
        perturb(&mut s2, &mut v2, e, -eps);
        let fd = (loss(&s1, &v1, cfg, w) - loss(&s2, &v2, cfg, w)) / (2.0 * eps);
        let an = analytic[e];
        let err = (fd - an).abs() / (1e-4 + 1e-4 * an.abs().max(fd.abs()));
        worst = worst.max(err);
        assert!(
            err <= 1.0,
            "{name}[{e}]: finite difference {fd:.9e} vs analytic {an:.9e}"
        );
    }
    eprintln!(
        "{name}: {} entries, worst normalised error {worst:.3e}",
        entries.len()
    );
}

fn run_all(
    scene: &HostScene,
    views: &[View],
    cfg: &RasterConfig,
    seed: u64,
    channel_scale: [f64; 5],
) {
    let w = weights(scene, views, cfg, seed, channel_scale);
    let g = Owned::<f64>::new(scene, views, W, H).backward(cfg, &w);
    let n = scene.len();
    let all = |k: usize| (0..k).collect::<Vec<_>>();
    check(
        "means",
        scene,
        views,
        cfg,
        &w,
        &g.means,
        &all(3 * n),
        &|s, _, e, d| s.means[e] += d,
    );
    check(
        "quats",
        scene,
        views,
        cfg,
        &w,
        &g.quats,
        &all(4 * n),
        &|s, _, e, d| s.quats[e] += d,
    );
    check(
        "scales",
        scene,
        views,
        cfg,
        &w,
        &g.scales,
        &all(3 * n),
        &|s, _, e, d| s.scales[e] += d,
    );
    check(
        "opacities",
        scene,
        views,
        cfg,
        &w,
        &g.opacities,
        &all(n),
        &|s, _, e, d| s.opacities[e] += d,
    );
    check(
        "colors",
        scene,
        views,
        cfg,
        &w,
        &g.colors,
        &all(3 * n),
        &|s, _, e, d| s.colors[e] += d,
    );
    check(
        "viewmats",
        scene,
        views,
        cfg,
        &w,
        &g.viewmats,
        &all(16 * views.len()),
        &|_, v, e, d| v[e / 16].0[e % 16] += d,
    );
    check(
        "ks",
        scene,
        views,
        cfg,
        &w,
        &g.ks,
        &all(9 * views.len()),
        &|_, v, e, d| v[e / 9].1[e % 9] += d,
    );
    // Only the tangential part of a quaternion matters: its radial gradient must vanish.
    for i in 0..n {
        let q = &scene.quats[4 * i..4 * i + 4];
        let radial: f64 = (0..4).map(|k| q[k] * g.quats[4 * i + k]).sum();
        assert!(
            radial.abs() < 1e-9,
            "quaternion {i} has radial gradient {radial:e}"
        );
    }
}

fn two_views() -> Vec<View> {
    vec![
        (
            look_at([0.0, 0.0, 0.0], [0.0, 0.0, 1.0]),
            intrinsics(W, H, 45.0),
        ),
        (
            look_at([0.4, -0.2, 0.3], [0.05, 0.1, 3.0]),
            [50.0, 0.0, 18.5, 0.0, 47.0, 17.0, 0.0, 0.0, 1.0],
        ),
    ]
}

/// Guards sign/transposition slips in any VJP (mean, conic, EWA, covariance, quaternion) and
/// in the camera gradient, on two views (rotated camera, off-centre principal point).
#[test]
fn finite_differences_every_input_two_views() {
    let scene = random_scene(
        7,
        11,
        SceneSpec {
            scale: (0.08, 0.3),
            ..Default::default()
        },
    );
    run_all(
        &scene,
        &two_views(),
        &RasterConfig::default(),
        5,
        [1.0, 1.0, 1.0, 0.3, 1.0],
    );
}

/// Guards the depth channel and alpha output gradients (the expected-depth division needs
/// both), by weighting only D and A.
#[test]
fn finite_differences_depth_and_alpha_channels() {
    let scene = random_scene(5, 23, SceneSpec::default());
    run_all(
        &scene,
        &two_views()[..1],
        &RasterConfig::default(),
        9,
        [0.0, 0.0, 0.0, 1.0, 3.0],
    );
}

/// Guards the frustum-clamp branch of the EWA Jacobian (Gaussians far off to the side whose
/// footprint still reaches into the image) including its K gradient.
#[test]
fn finite_differences_frustum_clamp_branch() {
    let mut scene = HostScene::default();
    // Off-screen centres (x/z beyond the clamp limit) with wide footprints reaching in.
    scene.push(
        [2.2, 0.1, 2.0],
        [0.9, 0.1, 0.3, -0.2],
        [1.2, 0.3, 0.4],
        0.8,
        [0.9, 0.2, 0.1],
    );
    scene.push(
        [-0.3, -2.0, 2.5],
        [0.5, -0.4, 0.2, 0.7],
        [0.3, 1.4, 0.5],
        0.7,
        [0.1, 0.8, 0.3],
    );
    scene.push(
        [0.1, 0.05, 3.0],
        [1.0, 0.0, 0.0, 0.0],
        [0.2, 0.15, 0.1],
        0.6,
        [0.5, 0.5, 0.9],
    );
    let views = two_views();
    let cfg = RasterConfig::default();
    // Make sure the scene really exercises the clamp.
    let out = forward64(&scene, &views[..1], W, H, &cfg);
    assert!(
        out.radii[0] > 0 && out.radii[2] > 0,
        "clamped Gaussians must be visible: {:?}",
        out.radii
    );
    run_all(&scene, &views[..1], &cfg, 3, [1.0, 1.0, 1.0, 0.2, 1.0]);
}
