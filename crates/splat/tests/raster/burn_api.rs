//! The Burn tensor API on the CPU backend (burn-flex): autodiff through the custom node,
//! expected depth and background handled by ordinary tensor ops, and input validation.

use crate::common::{threshold_mask, View};
use burn::tensor::{DType, Device, Tensor, TensorData};
use envision4d_splat::testkit::{
    intrinsics, look_at, random_scene, HostScene, SceneSpec, SplitMix64,
};
use envision4d_splat::{render, Cameras, Gaussians, RasterConfig, RenderError};

const W: u32 = 24;
const H: u32 = 20;

fn t<const D: usize>(v: &[f64], shape: [usize; D], device: &Device, dtype: DType) -> Tensor<D> {
    Tensor::from_data(
        TensorData::new(v.to_vec(), shape).convert_dtype(dtype),
        (device, dtype),
    )
}

/// Tensors for a scene; `require_grad` only on an autodiff device.
fn inputs(
    scene: &HostScene,
    views: &[View],
    device: &Device,
    dtype: DType,
) -> (Gaussians, Cameras) {
    let grad = device.is_autodiff();
    let g = |x: Tensor<2>| if grad { x.require_grad() } else { x };
    let g3 = |x: Tensor<3>| if grad { x.require_grad() } else { x };
    let n = scene.len();
    let v = views.len();
    let vm: Vec<f64> = views.iter().flat_map(|(m, _)| m.to_vec()).collect();
    let ks: Vec<f64> = views.iter().flat_map(|(_, k)| k.to_vec()).collect();
    (
        Gaussians {
            means: g(t(&scene.means, [n, 3], device, dtype)),
            quats: g(t(&scene.quats, [n, 4], device, dtype)),
            scales: g(t(&scene.scales, [n, 3], device, dtype)),
            opacities: {
                let o = t(&scene.opacities, [n], device, dtype);
                if grad {
                    o.require_grad()
                } else {
                    o
                }
            },
            colors: g(t(&scene.colors, [n, 3], device, dtype)),
        },
        Cameras {
            viewmats: g3(t(&vm, [v, 4, 4], device, dtype)),
            ks: g3(t(&ks, [v, 3, 3], device, dtype)),
            width: W,
            height: H,
        },
    )
}

fn views() -> Vec<View> {
    vec![
        (
            look_at([0.0, 0.0, 0.0], [0.0, 0.0, 1.0]),
            intrinsics(W, H, 25.0),
        ),
        (
            look_at([0.2, 0.1, 0.0], [0.0, 0.0, 3.0]),
            intrinsics(W, H, 22.0),
        ),
    ]
}

/// Scalar loss over rgb, expected depth and alpha with fixed random weights (zero next to
/// thresholds so that finite differences are meaningful).
fn loss(
    g: &Gaussians,
    c: &Cameras,
    cfg: &RasterConfig,
    w: &[Vec<f64>; 3],
    dtype: DType,
) -> Tensor<1> {
    let out = render(g, c, cfg).expect("valid render");
    let device = out.rgb.device();
    let v = c.viewmats.dims()[0];
    let (h, wd) = (H as usize, W as usize);
    let w_rgb = t(&w[0], [v, h, wd, 3], &device, dtype);
    let w_d = t(&w[1], [v, h, wd], &device, dtype);
    let w_a = t(&w[2], [v, h, wd], &device, dtype);
    (out.rgb * w_rgb).sum() + (out.depth * w_d).sum() + (out.alpha * w_a).sum()
}

fn weights(scene: &HostScene, views: &[View], cfg: &RasterConfig) -> [Vec<f64>; 3] {
    let mask = threshold_mask(scene, views, W, H, cfg, 2e-4);
    let mut rng = SplitMix64::new(42);
    let mut w = [Vec::new(), Vec::new(), Vec::new()];
    for m in mask {
        let k = if m { 0.0 } else { 1.0 };
        for _ in 0..3 {
            w[0].push(k * rng.range(-1.0, 1.0));
        }
        w[1].push(k * rng.range(-0.2, 0.2));
        w[2].push(k * rng.range(-1.0, 1.0));
    }
    w
}

fn scalar(x: Tensor<1>) -> f64 {
    x.into_data()
        .convert::<f64>()
        .try_into_vec::<f64>()
        .unwrap()[0]
}

/// Guards the autodiff node and the expected-depth/background tensor ops: float64 gradients
/// of a loss over rgb, ED and alpha (with a background) match central finite differences for
/// Gaussian and camera inputs.
#[test]
fn autodiff_matches_finite_differences_through_depth_and_background() {
    let device = Device::flex().autodiff();
    let dtype = DType::F64;
    let scene = random_scene(
        6,
        17,
        SceneSpec {
            scale: (0.1, 0.3),
            ..Default::default()
        },
    );
    let views = views();
    let cfg = RasterConfig {
        background: Some([0.2, 0.5, 0.9]),
        ..Default::default()
    };
    let w = weights(&scene, &views, &cfg);
    let (g, c) = inputs(&scene, &views, &device, dtype);
    let grads = loss(&g, &c, &cfg, &w, dtype).backward();
    let grad_of = |x: &Tensor<2>| {
        x.grad(&grads)
            .unwrap()
            .into_data()
            .convert::<f64>()
            .try_into_vec::<f64>()
            .unwrap()
    };
    let g_means = grad_of(&g.means);
    let g_view = c
        .viewmats
        .grad(&grads)
        .unwrap()
        .into_data()
        .convert::<f64>()
        .try_into_vec::<f64>()
        .unwrap();
    let g_k =
        c.ks.grad(&grads)
            .unwrap()
            .into_data()
            .convert::<f64>()
            .try_into_vec::<f64>()
            .unwrap();

    let plain = Device::flex();
    let eval = |s: &HostScene, v: &[View]| {
        let (g, c) = inputs(s, v, &plain, dtype);
        scalar(loss(&g, &c, &cfg, &w, dtype))
    };
    let eps = 1e-6;
    let close = |fd: f64, an: f64, what: String| {
        assert!(
            (fd - an).abs() <= 1e-4 + 1e-4 * an.abs(),
            "{what}: finite difference {fd:e} vs autodiff {an:e}"
        );
    };
    for e in 0..scene.means.len() {
        let (mut a, mut b) = (scene.clone(), scene.clone());
        a.means[e] += eps;
        b.means[e] -= eps;
        close(
            (eval(&a, &views) - eval(&b, &views)) / (2.0 * eps),
            g_means[e],
            format!("means[{e}]"),
        );
    }
    for e in [3usize, 7, 11, 0, 5, 16 + 3, 16 + 9] {
        let (mut a, mut b) = (views.clone(), views.clone());
        a[e / 16].0[e % 16] += eps;
        b[e / 16].0[e % 16] -= eps;
        close(
            (eval(&scene, &a) - eval(&scene, &b)) / (2.0 * eps),
            g_view[e],
            format!("viewmats[{e}]"),
        );
    }
    for e in [0usize, 2, 4, 5, 9, 11, 13, 14] {
        let (mut a, mut b) = (views.clone(), views.clone());
        a[e / 9].1[e % 9] += eps;
        b[e / 9].1[e % 9] -= eps;
        close(
            (eval(&scene, &a) - eval(&scene, &b)) / (2.0 * eps),
            g_k[e],
            format!("ks[{e}]"),
        );
    }
}

/// Guards the f32 Burn path: gradients exist for all seven inputs and are finite.
#[test]
fn f32_autodiff_reaches_every_input() {
    let device = Device::flex().autodiff();
    let scene = random_scene(50, 5, SceneSpec::default());
    let views = views();
    let cfg = RasterConfig::default();
    let (g, c) = inputs(&scene, &views, &device, DType::F32);
    let out = render(&g, &c, &cfg).unwrap();
    assert_eq!(out.rgb.dims(), [2, H as usize, W as usize, 3]);
    assert_eq!(out.meta.radii.dims(), [2, 50, 2]);
    let counts = out
        .meta
        .counts
        .clone()
        .into_data()
        .convert::<i64>()
        .try_into_vec::<i64>()
        .unwrap();
    assert!(
        counts[0] > 0 && counts[1] >= counts[0],
        "visible {} intersections {}",
        counts[0],
        counts[1]
    );
    let grads = (out.rgb.sum() + out.depth.sum() * 0.1).backward();
    let finite_nonzero = |v: Vec<f64>, name: &str| {
        assert!(
            v.iter().all(|x| x.is_finite()),
            "{name} has non-finite gradient"
        );
        assert!(v.iter().any(|x| *x != 0.0), "{name} has no gradient");
    };
    let read = |x: Tensor<2>| {
        x.into_data()
            .convert::<f64>()
            .try_into_vec::<f64>()
            .unwrap()
    };
    finite_nonzero(read(g.means.grad(&grads).unwrap()), "means");
    finite_nonzero(read(g.quats.grad(&grads).unwrap()), "quats");
    finite_nonzero(read(g.scales.grad(&grads).unwrap()), "scales");
    finite_nonzero(
        g.opacities
            .grad(&grads)
            .unwrap()
            .into_data()
            .convert::<f64>()
            .try_into_vec()
            .unwrap(),
        "opacities",
    );
    finite_nonzero(read(g.colors.grad(&grads).unwrap()), "colors");
    finite_nonzero(
        c.viewmats
            .grad(&grads)
            .unwrap()
            .into_data()
            .convert::<f64>()
            .try_into_vec()
            .unwrap(),
        "viewmats",
    );
    finite_nonzero(
        c.ks.grad(&grads)
            .unwrap()
            .into_data()
            .convert::<f64>()
            .try_into_vec()
            .unwrap(),
        "ks",
    );
}

/// Guards input validation: wrong shapes and degenerate cameras are errors, not panics.
#[test]
fn bad_inputs_are_errors() {
    let device = Device::flex();
    let scene = random_scene(4, 1, SceneSpec::default());
    let (g, c) = inputs(&scene, &views(), &device, DType::F32);
    let cfg = RasterConfig::default();

    let mut bad = g.clone();
    bad.quats = Tensor::zeros([4, 3], &device);
    assert!(matches!(
        render(&bad, &c, &cfg),
        Err(RenderError::Shape { name: "quats", .. })
    ));

    let mut bad_cam = views();
    bad_cam[1].1[0] = -5.0;
    let (_, c2) = inputs(&scene, &bad_cam, &device, DType::F32);
    let err = render(&g, &c2, &cfg).unwrap_err().to_string();
    assert!(err.contains("fx") && err.contains("camera 1"), "{err}");

    let mut singular = views();
    singular[0].0 = [0.0; 16];
    let (_, c3) = inputs(&scene, &singular, &device, DType::F32);
    assert!(render(&g, &c3, &cfg)
        .unwrap_err()
        .to_string()
        .contains("singular"));

    let zero = Cameras {
        width: 0,
        ..c.clone()
    };
    assert!(render(&g, &zero, &cfg)
        .unwrap_err()
        .to_string()
        .contains("1x1"));

    let bad_cfg = RasterConfig { near: -1.0, ..cfg };
    assert!(render(&g, &c, &bad_cfg)
        .unwrap_err()
        .to_string()
        .contains("near"));
}

/// Guards the empty scene through Burn (zero-sized tensors): background only, no panic.
#[test]
fn empty_scene_through_burn() {
    let device = Device::flex();
    let (g, c) = inputs(&HostScene::default(), &views(), &device, DType::F32);
    let cfg = RasterConfig {
        background: Some([1.0, 0.0, 0.0]),
        ..Default::default()
    };
    let out = render(&g, &c, &cfg).unwrap();
    let rgb = out
        .rgb
        .into_data()
        .convert::<f32>()
        .try_into_vec::<f32>()
        .unwrap();
    assert!(rgb.chunks(3).all(|p| p == [1.0, 0.0, 0.0]));
    let depth = out
        .depth
        .into_data()
        .convert::<f32>()
        .try_into_vec::<f32>()
        .unwrap();
    assert!(depth.iter().all(|d| *d == 0.0));
}

/// Guards the one camera read: the view matrices and intrinsics come back in one transfer
/// (concatenated on the device) and are split at the right place, and cameras whose two
/// tensors differ in float type (which cannot be concatenated) are read in two, not
/// refused: both renders equal the all-f32 one.
#[test]
fn cameras_are_read_once_and_mixed_float_types_still_render() {
    use envision4d_splat::kernels::readback::host_readbacks;
    let device = Device::flex();
    let scene = random_scene(12, 5, SceneSpec::default());
    let views = views();
    let cfg = RasterConfig::default();
    let (g, c) = inputs(&scene, &views, &device, DType::F32);
    let rgb = |c: &Cameras| -> (Vec<f32>, usize) {
        let before = host_readbacks();
        let out = render(&g, c, &cfg).expect("valid render");
        let reads = host_readbacks() - before;
        let v = out
            .rgb
            .into_data()
            .convert::<f32>()
            .try_to_vec::<f32>()
            .unwrap();
        (v, reads)
    };
    let (want, reads) = rgb(&c);
    assert_eq!(reads, 1, "same float type: one read of both camera tensors");
    assert!(want.iter().any(|&x| x > 0.0), "the scene is visible");
    let (_, mixed) = inputs(&scene, &views, &device, DType::F64);
    let mixed = Cameras {
        viewmats: c.viewmats.clone(),
        ..mixed
    };
    let (got, reads) = rgb(&mixed);
    assert_eq!(reads, 2, "f32 view matrices, f64 intrinsics: two reads");
    let worst = want
        .iter()
        .zip(&got)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0f32, f32::max);
    assert!(worst <= 1e-6, "mixed-type cameras render {worst} away");
}
