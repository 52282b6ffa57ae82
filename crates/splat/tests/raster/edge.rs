//! Edge scenes from the design spec: empty, closed form, planes, extreme scales and
//! opacities, poisoned inputs, long stacks, ties, and odd image sizes.

use crate::common::{forward64, Owned, View};
use envision4d_splat::cpu::project::project_one;
use envision4d_splat::cpu::raster::OUT_CHANNELS;
use envision4d_splat::testkit::{identity_view, intrinsics, random_scene, HostScene, SceneSpec};
use envision4d_splat::RasterConfig;

fn view(w: u32, h: u32, f: f64) -> Vec<View> {
    vec![(identity_view(), intrinsics(w, h, f))]
}

const ID: [f64; 4] = [1.0, 0.0, 0.0, 0.0];

/// Untiled reference: every culled-in Gaussian, sorted by (depth, index), for every pixel.
fn brute_force(scene: &HostScene, views: &[View], w: u32, h: u32, cfg: &RasterConfig) -> Vec<f64> {
    let owned = Owned::<f64>::new(scene, views, w, h);
    let sc = owned.scene();
    let mut out = Vec::new();
    for cam in &owned.cams {
        let lim = cam.frustum_limits();
        let mut proj: Vec<_> = (0..sc.len())
            .filter_map(|i| project_one(&sc, i, cam, &lim, cfg))
            .collect();
        proj.sort_by(|a, b| a.depth.partial_cmp(&b.depth).unwrap());
        for y in 0..h {
            for x in 0..w {
                let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
                let mut t = 1.0;
                let mut acc = [0.0; 4];
                for p in &proj {
                    let (dx, dy) = (p.mean2d[0] - px, p.mean2d[1] - py);
                    let sigma =
                        0.5 * (p.conic.a * dx * dx + p.conic.c * dy * dy) + p.conic.b * dx * dy;
                    let alpha = cfg.alpha_clamp.max_alpha().min(p.opacity * (-sigma).exp());
                    if sigma < 0.0 || alpha < cfg.alpha_min {
                        continue;
                    }
                    if t * (1.0 - alpha) <= cfg.transmittance_min {
                        break;
                    }
                    let f = [p.color[0], p.color[1], p.color[2], p.depth];
                    for c in 0..4 {
                        acc[c] += f[c] * alpha * t;
                    }
                    t *= 1.0 - alpha;
                }
                out.extend_from_slice(&[acc[0], acc[1], acc[2], acc[3], 1.0 - t]);
            }
        }
    }
    out
}

fn assert_close(a: &[f64], b: &[f64], tol: f64, what: &str) {
    assert_eq!(a.len(), b.len(), "{what}: lengths");
    for (i, (x, y)) in a.iter().zip(b).enumerate() {
        assert!(
            (x - y).abs() <= tol,
            "{what}: value {i} (pixel {}, channel {}): {x} vs {y}",
            i / OUT_CHANNELS,
            i % OUT_CHANNELS
        );
    }
}

/// Guards the empty-scene path (N = 0): background only, zero gradients, no panic.
#[test]
fn empty_scene_renders_nothing() {
    let cfg = RasterConfig::default();
    let o = Owned::<f64>::new(&HostScene::default(), &view(20, 10, 20.0), 20, 10);
    let out = o.forward(&cfg);
    assert!(out.image.iter().all(|v| *v == 0.0));
    assert_eq!(out.visible, vec![0]);
    let g = o.backward(&cfg, &vec![1.0; out.image.len()]);
    assert!(g.means.is_empty() && g.viewmats.iter().all(|v| *v == 0.0));
}

/// Guards the projection and compositing formulas against the closed form of one isotropic
/// Gaussian on the optical axis (where the EWA Jacobian is isotropic):
/// alpha(p) = o exp(-|p - mu|² / (2 (f² s² / z² + eps2d))).
#[test]
fn single_gaussian_matches_closed_form() {
    let (w, h, f, s, z, o) = (33u32, 21u32, 30.0, 0.2, 2.0, 0.7);
    let mut scene = HostScene::default();
    scene.push([0.0, 0.0, z], ID, [s, s, s], o, [0.2, 0.4, 0.6]);
    let cfg = RasterConfig::default();
    let out = forward64(&scene, &view(w, h, f), w, h, &cfg);
    let (mu_x, mu_y) = (w as f64 / 2.0, h as f64 / 2.0);
    let var = f * f * s * s / (z * z) + cfg.eps2d;
    for y in 0..h {
        for x in 0..w {
            let d2 = (x as f64 + 0.5 - mu_x).powi(2) + (y as f64 + 0.5 - mu_y).powi(2);
            let a = o * (-0.5 * d2 / var).exp();
            let expect = if a < cfg.alpha_min { 0.0 } else { a };
            let px = ((y * w + x) as usize) * OUT_CHANNELS;
            assert!(
                (out.image[px + 4] - expect).abs() < 1e-12,
                "alpha at ({x},{y})"
            );
            assert!(
                (out.image[px] - 0.2 * expect).abs() < 1e-12,
                "red at ({x},{y})"
            );
            assert!(
                (out.image[px + 3] - z * expect).abs() < 1e-12,
                "depth at ({x},{y})"
            );
        }
    }
}

/// Guards the near/far cull: behind the camera, on the camera plane and just before the near
/// plane are culled; exactly on the near plane is kept (gsplat culls only z < near).
#[test]
fn camera_plane_and_near_plane_culling() {
    let cfg = RasterConfig::default();
    for (z, kept) in [
        (-1.0, false),
        (0.0, false),
        (-0.0, false),
        (0.0099, false),
        (0.01, true),
        (1e11, false),
    ] {
        let mut scene = HostScene::default();
        scene.push([0.0, 0.0, z], ID, [1e-3, 1e-3, 1e-3], 0.9, [1.0, 1.0, 1.0]);
        let out = forward64(&scene, &view(8, 8, 8.0), 8, 8, &cfg);
        assert_eq!(out.visible[0] == 1, kept, "z = {z}");
        assert!(out.image.iter().all(|v| v.is_finite()));
    }
}

/// Guards overflow on huge scales and underflow on tiny ones: huge → culled (non-finite
/// covariance), never NaN pixels; tiny → the eps2d footprint still renders a finite dot.
#[test]
fn extreme_scales() {
    let cfg = RasterConfig::default();
    for s in [1e30, 1e38, f64::MAX] {
        let mut scene = HostScene::default();
        scene.push([0.0, 0.0, 2.0], ID, [s, s, s], 0.9, [1.0, 1.0, 1.0]);
        let out = Owned::<f32>::new(&scene, &view(16, 16, 16.0), 16, 16).forward(&cfg);
        assert!(out.image.iter().all(|v| v.is_finite()), "scale {s}");
    }
    let mut scene = HostScene::default();
    scene.push(
        [0.0, 0.0, 2.0],
        ID,
        [1e-30, 1e-30, 1e-30],
        0.9,
        [1.0, 1.0, 1.0],
    );
    let out = forward64(&scene, &view(16, 16, 16.0), 16, 16, &cfg);
    let centre = (8 * 16 + 8) * OUT_CHANNELS + 4;
    assert!(out.image[centre] > 0.1 && out.image.iter().all(|v| v.is_finite()));
    // A scale big enough to cover the image but finite still renders a flat, finite wash.
    let mut scene = HostScene::default();
    scene.push([0.0, 0.0, 2.0], ID, [1e6, 1e6, 1e6], 0.5, [1.0, 1.0, 1.0]);
    let out = forward64(&scene, &view(16, 16, 16.0), 16, 16, &cfg);
    assert!(out.image.iter().all(|v| v.is_finite()) && out.radii[0] > 0);
}

/// Guards the opacity cull at exactly 1/255 (zero extent) and the alpha clamp at opacity 1:
/// clamped pixels give no opacity/geometry gradient, only colour gradient.
#[test]
fn opacity_limits() {
    let cfg = RasterConfig::default();
    let mut scene = HostScene::default();
    scene.push(
        [0.0, 0.0, 2.0],
        ID,
        [0.5, 0.5, 0.5],
        1.0 / 255.0,
        [1.0, 1.0, 1.0],
    );
    assert_eq!(
        forward64(&scene, &view(8, 8, 8.0), 8, 8, &cfg).visible[0],
        0
    );

    let mut scene = HostScene::default();
    scene.push(
        [0.0, 0.0, 2.0],
        ID,
        [0.01, 0.01, 0.01],
        1.0,
        [1.0, 0.5, 0.25],
    );
    let o = Owned::<f64>::new(&scene, &view(9, 9, 9.0), 9, 9);
    let out = o.forward(&cfg);
    // The centre of a 9x9 image is pixel (4, 4) at (4.5, 4.5) = the projected mean.
    let c = (4 * 9 + 4) * OUT_CHANNELS;
    assert!((out.image[c + 4] - 0.999).abs() < 1e-12, "alpha clamp");
    let mut grad = vec![0.0; out.image.len()];
    grad[c + 4] = 1.0;
    grad[c] = 1.0;
    let g = o.backward(&cfg, &grad);
    assert_eq!(
        g.opacities[0], 0.0,
        "clamped alpha must not pass gradient to opacity"
    );
    assert!(g.means.iter().all(|v| *v == 0.0));
    assert!((g.colors[0] - 0.999).abs() < 1e-12);
}

/// Guards NaN/Inf/zero-quaternion poisoning: such Gaussians are culled and must not change
/// any other pixel (Brush's fuzz list, reduced).
#[test]
fn poisoned_gaussians_are_culled_without_side_effects() {
    let cfg = RasterConfig::default();
    let clean = random_scene(40, 4, SceneSpec::default());
    let mut poisoned = clean.clone();
    let nan = f64::NAN;
    let inf = f64::INFINITY;
    poisoned.push(
        [0.0, 0.0, 2.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.1; 3],
        0.9,
        [1.0; 3],
    );
    poisoned.push(
        [0.0, 0.0, 2.0],
        [nan, 0.0, 0.0, 1.0],
        [0.1; 3],
        0.9,
        [1.0; 3],
    );
    poisoned.push([nan, 0.0, 2.0], ID, [0.1; 3], 0.9, [1.0; 3]);
    poisoned.push([0.0, 0.0, inf], ID, [0.1; 3], 0.9, [1.0; 3]);
    poisoned.push([0.0, 0.0, 2.0], ID, [inf, 0.1, 0.1], 0.9, [1.0; 3]);
    poisoned.push([0.0, 0.0, 2.0], ID, [0.1; 3], nan, [1.0; 3]);
    poisoned.push([0.0, 0.0, 2.0], ID, [0.1; 3], 0.9, [nan, 0.0, 0.0]);
    poisoned.push(
        [0.0, 0.0, 2.0],
        [1e-30, 0.0, 0.0, 0.0],
        [0.1; 3],
        0.9,
        [1.0; 3],
    );
    let views = view(48, 40, 40.0);
    let a = Owned::<f32>::new(&clean, &views, 48, 40).forward(&cfg);
    let ob = Owned::<f32>::new(&poisoned, &views, 48, 40);
    let b = ob.forward(&cfg);
    assert_eq!(a.image, b.image);
    assert_eq!(b.visible, a.visible);
    let g = ob.backward(&cfg, &vec![1.0; b.image.len()]);
    assert!(g
        .means
        .iter()
        .chain(&g.quats)
        .chain(&g.scales)
        .chain(&g.viewmats)
        .chain(&g.ks)
        .all(|v| v.is_finite()));
    assert!(
        g.means[3 * 40..].iter().all(|v| *v == 0.0),
        "culled Gaussians get zero gradient"
    );
}

/// Guards the exclusive transmittance stop: in a stack of 30 opaque Gaussians only the front
/// ones are composited and the ones behind the stop get exactly zero gradient.
#[test]
fn stack_of_thirty_opaque_gaussians() {
    let cfg = RasterConfig::default();
    let mut scene = HostScene::default();
    for i in 0..30 {
        scene.push(
            [0.0, 0.0, 2.0 + 0.1 * i as f64],
            ID,
            [0.5; 3],
            0.99,
            [i as f64 / 30.0, 0.5, 0.5],
        );
    }
    let o = Owned::<f64>::new(&scene, &view(8, 8, 4.0), 8, 8);
    let out = o.forward(&cfg);
    // Loss on the four centre pixels only: each layer has alpha = 0.99 exp(-0.25 / 1.3) = 0.817
    // there, so T after five layers is 2.0e-4 and the sixth (index 5) would cross 1e-4.
    let mut grad = vec![0.0; out.image.len()];
    for (x, y) in [(3, 3), (3, 4), (4, 3), (4, 4)] {
        for c in 0..OUT_CHANNELS {
            grad[(y * 8 + x) * OUT_CHANNELS + c] = 1.0;
        }
    }
    let g = o.backward(&cfg, &grad);
    for i in 5..30 {
        assert_eq!(g.colors[3 * i], 0.0, "Gaussian {i} is behind the stop");
        assert_eq!(g.opacities[i], 0.0);
    }
    assert!(g.colors[3 * 4] > 0.0, "the fifth layer is still composited");
    assert!(g.colors[0] > 0.0);
    assert_close(
        &out.image,
        &brute_force(&scene, &view(8, 8, 4.0), 8, 8, &cfg),
        1e-12,
        "stack",
    );
}

/// Guards tie-breaking at equal depths: Gaussian index order decides, deterministically.
#[test]
fn equal_depths_composite_in_index_order() {
    let cfg = RasterConfig::default();
    let mut ab = HostScene::default();
    ab.push([0.0, 0.0, 2.0], ID, [0.3; 3], 0.8, [1.0, 0.0, 0.0]);
    ab.push([0.0, 0.0, 2.0], ID, [0.3; 3], 0.8, [0.0, 0.0, 1.0]);
    let out = forward64(&ab, &view(8, 8, 8.0), 8, 8, &cfg);
    let c = (4 * 8 + 4) * OUT_CHANNELS;
    assert!(
        out.image[c] > out.image[c + 2],
        "first index in front: red dominates"
    );
    let mut ba = HostScene::default();
    ba.push([0.0, 0.0, 2.0], ID, [0.3; 3], 0.8, [0.0, 0.0, 1.0]);
    ba.push([0.0, 0.0, 2.0], ID, [0.3; 3], 0.8, [1.0, 0.0, 0.0]);
    let out2 = forward64(&ba, &view(8, 8, 8.0), 8, 8, &cfg);
    assert!(out2.image[c + 2] > out2.image[c]);
}

/// Guards tile bookkeeping on sizes that are not multiples of 16 (partial tiles, 1x1, 17x1,
/// 1x17): tiled output must equal the untiled brute force.
#[test]
fn odd_image_sizes_match_untiled_reference() {
    let cfg = RasterConfig::default();
    for (w, h) in [(1u32, 1u32), (17, 1), (1, 17), (33, 19), (16, 16)] {
        let scene = random_scene(
            60,
            w as u64 * 100 + h as u64,
            SceneSpec {
                scale: (0.05, 0.5),
                ..Default::default()
            },
        );
        let views = vec![(identity_view(), intrinsics(w, h, 0.8 * w.max(h) as f64))];
        let out = forward64(&scene, &views, w, h, &cfg);
        assert_close(
            &out.image,
            &brute_force(&scene, &views, w, h, &cfg),
            1e-12,
            &format!("{w}x{h}"),
        );
    }
}

/// Guards "culled Gaussians must not matter": appending Gaussians behind the camera or
/// off-screen leaves every pixel bit-identical.
#[test]
fn appending_culled_gaussians_changes_nothing() {
    let cfg = RasterConfig::default();
    let scene = random_scene(100, 77, SceneSpec::default());
    let mut more = scene.clone();
    more.push([0.0, 0.0, -3.0], ID, [1.0; 3], 0.9, [1.0; 3]);
    more.push([500.0, 0.0, 2.0], ID, [0.1; 3], 0.9, [1.0; 3]);
    more.push([0.0, 0.0, 2.0], ID, [0.1; 3], 0.001, [1.0; 3]);
    let views = view(40, 30, 30.0);
    let a = Owned::<f32>::new(&scene, &views, 40, 30).forward(&cfg);
    let b = Owned::<f32>::new(&more, &views, 40, 30).forward(&cfg);
    assert_eq!(a.image, b.image);
}
