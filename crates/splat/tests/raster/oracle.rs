//! The f32 CPU path against the f64 oracle, and run-to-run determinism.

use crate::common::{max_abs_diff, to64, Owned, View};
use envision4d_splat::testkit::{intrinsics, look_at, random_scene, SceneSpec, SplitMix64};
use envision4d_splat::RasterConfig;

const W: u32 = 96;
const H: u32 = 64;

fn views() -> Vec<View> {
    vec![
        (
            look_at([0.0, 0.0, 0.0], [0.0, 0.0, 1.0]),
            intrinsics(W, H, 80.0),
        ),
        (
            look_at([0.3, 0.1, -0.2], [0.0, 0.0, 3.0]),
            intrinsics(W, H, 70.0),
        ),
    ]
}

/// Guards precision loss in the f32 path (transmittance products, conic inversion, depth
/// channel) by comparing image and gradients with the f64 oracle on a busy scene.
#[test]
fn f32_matches_f64_oracle() {
    let scene = random_scene(
        400,
        3,
        SceneSpec {
            scale: (0.02, 0.15),
            ..Default::default()
        },
    );
    let cfg = RasterConfig::default();
    let o64 = Owned::<f64>::new(&scene, &views(), W, H);
    let o32 = Owned::<f32>::new(&scene, &views(), W, H);
    let f64out = o64.forward(&cfg);
    let f32out = o32.forward(&cfg);
    assert_eq!(
        f64out.radii, f32out.radii,
        "culling/radii must agree away from thresholds"
    );
    assert_eq!(f64out.intersections, f32out.intersections);
    // Colour and alpha channels are O(1); the depth channel is O(z) so compare it relatively.
    let img32 = to64(&f32out.image);
    let mut worst_rgba: f64 = 0.0;
    let mut worst_depth: f64 = 0.0;
    for (k, (a, b)) in f64out.image.iter().zip(&img32).enumerate() {
        if k % 5 == 3 {
            worst_depth = worst_depth.max((a - b).abs() / a.abs().max(1.0));
        } else {
            worst_rgba = worst_rgba.max((a - b).abs());
        }
    }
    assert!(worst_rgba < 2e-5, "rgb/alpha differ by {worst_rgba:e}");
    assert!(
        worst_depth < 2e-5,
        "depth channel differs by {worst_depth:e} (relative)"
    );

    let mut rng = SplitMix64::new(1);
    let grad: Vec<f64> = (0..f64out.image.len())
        .map(|_| rng.range(-1.0, 1.0))
        .collect();
    let grad32: Vec<f32> = grad.iter().map(|v| *v as f32).collect();
    let g64 = o64.backward(&cfg, &grad);
    let g32 = o32.backward(&cfg, &grad32);
    let pairs: [(&str, &[f64], Vec<f64>); 7] = [
        ("means", &g64.means, to64(&g32.means)),
        ("quats", &g64.quats, to64(&g32.quats)),
        ("scales", &g64.scales, to64(&g32.scales)),
        ("opacities", &g64.opacities, to64(&g32.opacities)),
        ("colors", &g64.colors, to64(&g32.colors)),
        ("viewmats", &g64.viewmats, to64(&g32.viewmats)),
        ("ks", &g64.ks, to64(&g32.ks)),
    ];
    for (name, a, b) in pairs {
        let scale = a.iter().fold(0.0f64, |m, v| m.max(v.abs())).max(1e-3);
        let err = max_abs_diff(a, &b) / scale;
        assert!(
            err < 5e-4,
            "{name}: f32 gradient differs from f64 by {err:e} of its largest entry"
        );
    }
}

/// Guards nondeterministic reductions (rayon work stealing reordering float sums): two runs
/// must agree bit for bit, images and gradients.
#[test]
fn cpu_path_is_bitwise_deterministic() {
    let scene = random_scene(3000, 8, SceneSpec::default());
    let cfg = RasterConfig::default();
    let o = Owned::<f32>::new(&scene, &views(), W, H);
    let a = o.forward(&cfg);
    let b = o.forward(&cfg);
    assert_eq!(a.image, b.image);
    let grad = vec![0.5f32; a.image.len()];
    let ga = o.backward(&cfg, &grad);
    let gb = o.backward(&cfg, &grad);
    assert_eq!(ga.means, gb.means);
    assert_eq!(ga.viewmats, gb.viewmats);
    assert_eq!(ga.ks, gb.ks);
}
