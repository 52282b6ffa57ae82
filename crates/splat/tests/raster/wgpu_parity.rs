//! Parity of the CubeCL kernels (wgpu → WGSL → lavapipe here) with the CPU path: the same
//! render through `envision4d_splat::render` with autodiff on both devices, comparing the
//! image, the meta outputs and all seven gradients.
//!
//! A machine without a wgpu adapter fails these tests loudly; set `ENVISION4D_SKIP_WGPU=1`
//! to skip them explicitly instead.

use crate::common::{threshold_mask, View};
use burn::tensor::{DType, Device, Tensor, TensorData};
use envision4d_splat::testkit::{
    intrinsics, look_at, random_scene, wgpu_test_device, HostScene, SceneSpec, SplitMix64,
};
use envision4d_splat::{
    render, BackwardBins, Cameras, Gaussians, GradAccumulation, GradCombine, RasterConfig,
    TileSchedule,
};

/// Image tolerance (absolute for colour and alpha, relative for the accumulated depth).
const IMAGE_TOL: f64 = 1e-5;
/// Gradient tolerance relative to the largest entry of each gradient tensor.
const GRAD_REL_TOL: f64 = 1e-4;
const GRAD_ABS_TOL: f64 = 1e-6;
/// Pixels where some alpha is this close to a threshold get zero loss weight: there the f32
/// paths may legitimately take different skip decisions.
const THRESHOLD_MARGIN: f64 = 1e-5;

pub(crate) fn t<const D: usize>(v: &[f64], shape: [usize; D], device: &Device) -> Tensor<D> {
    Tensor::from_data(
        TensorData::new(v.to_vec(), shape).convert_dtype(DType::F32),
        (device, DType::F32),
    )
}

fn to_vec<const D: usize>(x: Tensor<D>) -> Vec<f64> {
    x.into_data()
        .convert::<f64>()
        .try_into_vec::<f64>()
        .unwrap()
}

/// Everything one device produced for one scene.
pub(crate) struct Run {
    rgb: Vec<f64>,
    depth: Vec<f64>,
    alpha: Vec<f64>,
    radii: Vec<i64>,
    pub(crate) counts: Vec<i64>,
    grads: Vec<(&'static str, Vec<f64>)>,
}

pub(crate) fn run(
    device: &Device,
    scene: &HostScene,
    views: &[View],
    w: u32,
    h: u32,
    cfg: &RasterConfig,
    weights: &[Vec<f64>; 3],
) -> Run {
    let device = device.clone().autodiff();
    let n = scene.len();
    let v = views.len();
    let vm: Vec<f64> = views.iter().flat_map(|(m, _)| m.to_vec()).collect();
    let ks: Vec<f64> = views.iter().flat_map(|(_, k)| k.to_vec()).collect();
    let g = Gaussians {
        means: t(&scene.means, [n, 3], &device).require_grad(),
        quats: t(&scene.quats, [n, 4], &device).require_grad(),
        scales: t(&scene.scales, [n, 3], &device).require_grad(),
        opacities: t(&scene.opacities, [n], &device).require_grad(),
        colors: t(&scene.colors, [n, 3], &device).require_grad(),
    };
    let c = Cameras {
        viewmats: t(&vm, [v, 4, 4], &device).require_grad(),
        ks: t(&ks, [v, 3, 3], &device).require_grad(),
        width: w,
        height: h,
    };
    let out = render(&g, &c, cfg).expect("valid render");
    let (hh, ww) = (h as usize, w as usize);
    let loss = (out.rgb.clone() * t(&weights[0], [v, hh, ww, 3], &device)).sum()
        + (out.depth.clone() * t(&weights[1], [v, hh, ww], &device)).sum()
        + (out.alpha.clone() * t(&weights[2], [v, hh, ww], &device)).sum();
    let grads = loss.backward();
    let grad = |name: &'static str, x: Vec<f64>| (name, x);
    Run {
        rgb: to_vec(out.rgb),
        depth: to_vec(out.depth),
        alpha: to_vec(out.alpha),
        radii: out
            .meta
            .radii
            .into_data()
            .convert::<i64>()
            .try_into_vec::<i64>()
            .unwrap(),
        counts: out
            .meta
            .counts
            .into_data()
            .convert::<i64>()
            .try_into_vec::<i64>()
            .unwrap(),
        grads: vec![
            grad("means", to_vec(g.means.grad(&grads).unwrap())),
            grad("quats", to_vec(g.quats.grad(&grads).unwrap())),
            grad("scales", to_vec(g.scales.grad(&grads).unwrap())),
            grad("opacities", to_vec(g.opacities.grad(&grads).unwrap())),
            grad("colors", to_vec(g.colors.grad(&grads).unwrap())),
            grad("viewmats", to_vec(c.viewmats.grad(&grads).unwrap())),
            grad("ks", to_vec(c.ks.grad(&grads).unwrap())),
        ],
    }
}

/// Random loss weights, zero at pixels next to an alpha threshold.
pub(crate) fn weights(
    scene: &HostScene,
    views: &[View],
    w: u32,
    h: u32,
    cfg: &RasterConfig,
    seed: u64,
) -> [Vec<f64>; 3] {
    let mask = threshold_mask(scene, views, w, h, cfg, THRESHOLD_MARGIN);
    let mut rng = SplitMix64::new(seed);
    let mut out = [Vec::new(), Vec::new(), Vec::new()];
    for m in mask {
        let k = if m { 0.0 } else { 1.0 };
        for _ in 0..3 {
            out[0].push(k * rng.range(-1.0, 1.0));
        }
        out[1].push(k * rng.range(-0.2, 0.2));
        out[2].push(k * rng.range(-1.0, 1.0));
    }
    out
}

fn max_abs(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

/// Renders on wgpu and on the CPU and asserts parity; returns the worst gradient error seen
/// (relative to each tensor's largest entry) for the report. With `TileSchedule::Auto` the
/// wgpu render runs under both schedules, so lavapipe (which `Auto` gives the per-pixel
/// kernels) also checks the shared batches a GPU runs; each schedule's backward once reuses
/// the forward's tile lists and ends and once bins and composites again (`BackwardBins`), and
/// the batched one also sums per plane (`GradCombine`, forced: CubeCL reports no plane
/// operations on lavapipe, which has them).
pub(crate) fn check_parity(
    scene: &HostScene,
    views: &[View],
    w: u32,
    h: u32,
    cfg: &RasterConfig,
) -> Option<f64> {
    let gpu = wgpu_test_device()?;
    let wts = weights(scene, views, w, h, cfg, 99);
    let b = run(&Device::flex(), scene, views, w, h, cfg, &wts);
    let runs = match cfg.tile_schedule {
        // Each backward path once: plane sums and per-pixel adds, the forward's ends kept
        // and composited again, in both compositing kernels.
        TileSchedule::Auto => {
            use BackwardBins::{Keep, Recompute};
            use GradCombine::{PerPixel as Adds, PlaneSums};
            use TileSchedule::{PerPixel, SharedBatches};
            vec![
                (SharedBatches, Keep, PlaneSums),
                (SharedBatches, Recompute, Adds),
                (PerPixel, Keep, GradCombine::Auto),
                (PerPixel, Recompute, GradCombine::Auto),
            ]
        }
        one => vec![(one, cfg.backward_bins, cfg.grad_combine)],
    };
    let mut worst = 0.0f64;
    for (tile_schedule, backward_bins, grad_combine) in runs {
        eprintln!(
            "tile schedule {tile_schedule:?}, backward bins {backward_bins:?}, \
             gradient adds {grad_combine:?}:"
        );
        let cfg = RasterConfig {
            tile_schedule,
            backward_bins,
            grad_combine,
            ..*cfg
        };
        let a = run(&gpu, scene, views, w, h, &cfg, &wts);
        worst = worst.max(compare(&a, &b));
    }
    Some(worst)
}

/// Asserts that the wgpu run `a` matches the CPU run `b` (or another wgpu run); the worst
/// relative gradient error.
pub(crate) fn compare(a: &Run, b: &Run) -> f64 {
    let d_rgb = max_abs(&a.rgb, &b.rgb);
    let d_alpha = max_abs(&a.alpha, &b.alpha);
    // The kernel's channel is the accumulated depth D; expected depth D / A amplifies
    // last-bit alpha differences at nearly transparent pixels, so compare D = ED * A.
    let acc = |r: &Run| {
        r.depth
            .iter()
            .zip(&r.alpha)
            .map(|(d, a)| d * a)
            .collect::<Vec<f64>>()
    };
    let (da, db) = (acc(a), acc(b));
    let d_depth = da
        .iter()
        .zip(&db)
        .map(|(x, y)| (x - y).abs() / y.abs().max(1.0))
        .fold(0.0, f64::max);
    eprintln!("image parity: rgb {d_rgb:e}, alpha {d_alpha:e}, depth (rel) {d_depth:e}");
    assert!(
        d_rgb <= IMAGE_TOL && d_alpha <= IMAGE_TOL && d_depth <= IMAGE_TOL,
        "image differs: rgb {d_rgb:e} alpha {d_alpha:e} depth {d_depth:e}"
    );
    assert_eq!(a.counts, b.counts, "counts (visible, intersections) differ");
    assert_eq!(a.radii, b.radii, "radii differ");
    let mut worst = 0.0f64;
    for ((name, ga), (_, gb)) in a.grads.iter().zip(&b.grads) {
        assert!(
            ga.iter().all(|x| x.is_finite()),
            "{name}: non-finite wgpu gradient"
        );
        let scale = gb.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let d = max_abs(ga, gb);
        let rel = d / scale.max(f64::MIN_POSITIVE);
        eprintln!("grad {name}: max abs diff {d:e} (largest entry {scale:e})");
        assert!(
            d <= GRAD_REL_TOL * scale + GRAD_ABS_TOL,
            "{name}: wgpu vs cpu gradient differs by {d:e} (largest entry {scale:e})"
        );
        if scale > 0.0 {
            worst = worst.max(rel);
        }
    }
    worst
}

pub(crate) fn two_views(w: u32, h: u32) -> Vec<View> {
    vec![
        (
            look_at([0.0, 0.0, 0.0], [0.0, 0.0, 1.0]),
            intrinsics(w, h, 40.0),
        ),
        (
            look_at([0.3, -0.2, 0.1], [0.0, 0.1, 3.0]),
            intrinsics(w, h, 35.0),
        ),
    ]
}

/// Guards the whole GPU pipeline (projection, host binning, tile compositing, both backward
/// kernels, camera-gradient reduction) against any formula drifting from the CPU path, on a
/// 2-view scene with partial edge tiles and frustum-clamped Gaussians.
#[test]
fn wgpu_matches_cpu_two_views() {
    let (w, h) = (64, 48);
    let scene = random_scene(
        300,
        7,
        SceneSpec {
            xy: 1.6,
            ..Default::default()
        },
    );
    if let Some(worst) = check_parity(&scene, &two_views(w, h), w, h, &RasterConfig::default()) {
        eprintln!("worst relative gradient error: {worst:e}");
    }
}

/// Guards the compare-and-swap fallback for devices without float atomics: same results as
/// the native atomic path.
#[test]
fn wgpu_cas_atomics_match_cpu() {
    let (w, h) = (40, 33);
    let scene = random_scene(120, 11, SceneSpec::default());
    let cas = RasterConfig {
        grad_accumulation: GradAccumulation::CompareAndSwap,
        ..RasterConfig::default()
    };
    check_parity(&scene, &two_views(w, h)[..1], w, h, &cas);
}

/// Guards partial tiles: a 17x1 image has two tiles, each mostly outside the image, so
/// out-of-image threads must neither write nor read past the buffer.
#[test]
fn wgpu_matches_cpu_17x1() {
    let (w, h) = (17, 1);
    let scene = random_scene(
        60,
        3,
        SceneSpec {
            xy: 0.4,
            ..Default::default()
        },
    );
    let views = vec![(
        look_at([0.0, 0.0, 0.0], [0.0, 0.0, 1.0]),
        intrinsics(w, h, 12.0),
    )];
    check_parity(
        &scene,
        &views,
        w,
        h,
        &RasterConfig {
            background: Some([0.1, 0.2, 0.3]),
            ..Default::default()
        },
    );
}

/// Guards empty work: N == 0 must skip every launch (zero-size dispatch is unsupported) and
/// still return the background and correctly shaped zero gradients.
#[test]
fn wgpu_empty_scene() {
    let (w, h) = (20, 18);
    check_parity(
        &HostScene::default(),
        &two_views(w, h),
        w,
        h,
        &RasterConfig {
            background: Some([1.0, 0.0, 0.5]),
            ..Default::default()
        },
    );
}

/// Guards the culls: NaN/inf inputs, zero quaternions, transparent, behind-camera, beyond-far,
/// overflowing and off-screen Gaussians are dropped exactly like the CPU path (radius 0, zero
/// gradient) without poisoning their neighbours.
#[test]
fn wgpu_culls_poisoned_gaussians() {
    let (w, h) = (32, 24);
    let mut scene = random_scene(30, 5, SceneSpec::default());
    let q = [1.0, 0.0, 0.0, 0.0];
    let s = [0.1, 0.1, 0.1];
    let c = [0.5, 0.5, 0.5];
    scene.push([f64::NAN, 0.0, 3.0], q, s, 0.9, c);
    scene.push([0.0, 0.0, 3.0], q, [f64::INFINITY, 0.1, 0.1], 0.9, c);
    scene.push([0.0, 0.1, 3.0], [0.0, 0.0, 0.0, 0.0], s, 0.9, c);
    scene.push([0.1, 0.0, 3.0], q, s, 1e-3, c);
    scene.push([0.0, 0.0, -2.0], q, s, 0.9, c);
    scene.push([0.0, 0.0, 0.005], q, s, 0.9, c);
    scene.push([0.0, 0.0, 3.0], q, [1e30, 1e30, 1e30], 0.9, c);
    scene.push([50.0, 0.0, 3.0], q, s, 0.9, c);
    scene.push([0.0, 0.0, 3.0], q, s, f64::NAN, c);
    scene.push([0.0, 0.0, 3.0], q, s, 0.9, [f64::NAN, 0.0, 0.0]);
    let views = vec![(
        look_at([0.0, 0.0, 0.0], [0.0, 0.0, 1.0]),
        intrinsics(w, h, 30.0),
    )];
    check_parity(&scene, &views, w, h, &RasterConfig::default());
}
