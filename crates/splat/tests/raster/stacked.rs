//! Per-view Gaussian sets (`render_each`): a different scene per view, all views in one call.

use burn::tensor::{Device, Int, Tensor, TensorData};
use envision4d_splat::kernels::readback::host_readbacks;
use envision4d_splat::testkit::{
    intrinsics, look_at, random_scene, wgpu_test_device, HostScene, SceneSpec, SplitMix64,
};
use envision4d_splat::{render, render_each, Cameras, Gaussians, RasterConfig};

const W: u32 = 40;
const H: u32 = 28;

fn t<const D: usize>(v: &[f64], shape: [usize; D], device: &Device) -> Tensor<D> {
    let v: Vec<f32> = v.iter().map(|x| *x as f32).collect();
    Tensor::from_data(TensorData::new(v, shape), device)
}

fn gaussians(s: &HostScene, device: &Device) -> Gaussians {
    let n = s.len();
    Gaussians {
        means: t(&s.means, [n, 3], device).require_grad(),
        quats: t(&s.quats, [n, 4], device).require_grad(),
        scales: t(&s.scales, [n, 3], device).require_grad(),
        opacities: t(&s.opacities, [n], device).require_grad(),
        colors: t(&s.colors, [n, 3], device).require_grad(),
    }
}

fn cameras(views: &[([f64; 16], [f64; 9])], device: &Device) -> Cameras {
    let v = views.len();
    let vm: Vec<f64> = views.iter().flat_map(|(m, _)| m.to_vec()).collect();
    let ks: Vec<f64> = views.iter().flat_map(|(_, k)| k.to_vec()).collect();
    Cameras {
        viewmats: t(&vm, [v, 4, 4], device).require_grad(),
        ks: t(&ks, [v, 3, 3], device).require_grad(),
        width: W,
        height: H,
    }
}

fn host<const D: usize>(x: Tensor<D>) -> Vec<f64> {
    x.into_data().convert::<f64>().try_into_vec().unwrap()
}

fn host_int<const D: usize>(x: Tensor<D, Int>) -> Vec<i64> {
    x.into_data().convert::<i64>().try_into_vec().unwrap()
}

/// Largest difference relative to the largest entry of `a` (0 when both are all zero).
fn rel(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    let m = a.iter().fold(0.0f64, |m, x| m.max(x.abs())).max(1e-30);
    a.iter()
        .zip(b)
        .fold(0.0f64, |d, (x, y)| d.max((x - y).abs()))
        / m
}

/// The five Gaussian gradients of `g` and the two camera gradients of `c`, flattened.
fn grads(g: &Gaussians, c: &Cameras, gr: &burn::tensor::Gradients) -> Vec<Vec<f64>> {
    let mut out: Vec<Vec<f64>> = [&g.means, &g.quats, &g.scales, &g.colors]
        .iter()
        .map(|x| x.grad(gr).map(host).unwrap_or_default())
        .collect();
    out.push(g.opacities.grad(gr).map(host).unwrap_or_default());
    out.push(c.viewmats.grad(gr).map(host).unwrap_or_default());
    out.push(c.ks.grad(gr).map(host).unwrap_or_default());
    out
}

/// Renders three different scenes (sizes 60, 0 and 35) through three cameras, once per view
/// on its own and once together; returns the worst relative difference over the images,
/// radii, counts and every gradient, and the host readbacks of the joint forward+backward.
fn compare(device: &Device) -> (f64, usize) {
    let spec = SceneSpec::default();
    let scenes = [
        random_scene(60, 11, spec),
        random_scene(0, 12, spec),
        random_scene(35, 13, spec),
    ];
    let views = [
        (
            look_at([0.0, 0.0, 0.0], [0.0, 0.0, 3.0]),
            intrinsics(W, H, 30.0),
        ),
        (
            look_at([0.3, 0.0, 0.0], [0.0, 0.0, 3.0]),
            intrinsics(W, H, 28.0),
        ),
        (
            look_at([-0.2, 0.1, 0.2], [0.0, 0.0, 3.0]),
            intrinsics(W, H, 33.0),
        ),
    ];
    let cfg = RasterConfig::default();
    let mut rng = SplitMix64::new(5);
    let weights: Vec<f64> = (0..views.len() * (W * H * 3) as usize)
        .map(|_| rng.range(-1.0, 1.0))
        .collect();
    let per_view = (W * H * 3) as usize;
    let weight = |v: std::ops::Range<usize>| {
        t(
            &weights[v.start * per_view..v.end * per_view],
            [v.len(), H as usize, W as usize, 3],
            device,
        )
    };
    let mut worst = 0.0f64;
    // Each view alone.
    let mut alone = Vec::new();
    for (v, (scene, view)) in scenes.iter().zip(&views).enumerate() {
        let (g, c) = (gaussians(scene, device), cameras(&[*view], device));
        let out = render(&g, &c, &cfg).unwrap();
        let gr = (out.rgb.clone() * weight(v..v + 1)).sum().backward();
        alone.push((
            host(out.rgb),
            host_int(out.meta.radii),
            host_int(out.meta.counts),
            grads(&g, &c, &gr),
        ));
    }
    // All views in one call.
    let before = host_readbacks();
    let gs: Vec<Gaussians> = scenes.iter().map(|s| gaussians(s, device)).collect();
    let c = cameras(&views, device);
    let out = render_each(&gs, &c, &cfg).unwrap();
    let gr = (out.rgb.clone() * weight(0..views.len())).sum().backward();
    let reads = host_readbacks() - before;
    let rgb = host(out.rgb);
    let radii = host_int(out.meta.radii);
    let counts = host_int(out.meta.counts);
    let r = scenes.iter().map(HostScene::len).max().unwrap();
    let joint_cams = grads(&gs[0], &c, &gr);
    for (v, (a_rgb, a_radii, a_counts, a_grads)) in alone.iter().enumerate() {
        worst = worst.max(rel(a_rgb, &rgb[v * per_view..(v + 1) * per_view]));
        let n = scenes[v].len();
        assert_eq!(
            a_radii[..],
            radii[v * r * 2..(v * r + n) * 2],
            "radii of view {v}"
        );
        assert!(radii[(v * r + n) * 2..(v + 1) * r * 2]
            .iter()
            .all(|&x| x == 0));
        assert_eq!(a_counts[..], counts[v * 2..v * 2 + 2], "counts of view {v}");
        let g = grads(&gs[v], &c, &gr);
        for k in 0..5 {
            if n > 0 {
                worst = worst.max(rel(&a_grads[k], &g[k]));
            }
        }
        // Camera gradients: view v's rows of the joint tensors.
        for (k, lanes) in [(5, 16), (6, 9)] {
            worst = worst.max(rel(&a_grads[k], &joint_cams[k][v * lanes..(v + 1) * lanes]));
        }
    }
    (worst, reads)
}

/// Guards per-view Gaussian sets on the CPU backend: one call with a different scene per
/// view (one of them empty) must equal rendering every view on its own, bit for bit, in the
/// image, radii, counts and every gradient (a wrong row offset or radii stride would not).
#[test]
fn render_each_equals_separate_renders_cpu() {
    let (worst, _) = compare(&Device::flex().autodiff());
    assert_eq!(worst, 0.0, "joint render differs from separate renders");
}

/// A render call's two camera tensors, read together once; then one totals read in the
/// forward (the backward reuses its tile lists).
const CAMERA_READS: usize = 1;
const TOTALS_READS: usize = 1;

/// Guards per-view Gaussian sets in the GPU kernels (row offsets in projection forward and
/// backward, the radii stride): equal to separate renders on wgpu within float-atomic
/// reordering, with the joint forward+backward reading the host as often as one view
/// does (the 2 camera tensors in 1 read, then 1 read of all views' totals), not once per view.
#[test]
fn render_each_equals_separate_renders_wgpu() {
    let Some(device) = wgpu_test_device() else {
        return;
    };
    let (worst, reads) = compare(&device.autodiff());
    assert!(worst <= 1e-5, "joint render differs by {worst}");
    assert_eq!(
        reads,
        CAMERA_READS + TOTALS_READS,
        "host readbacks of the joint forward+backward"
    );
}
