//! The DPT heads' bilinear resize in a training graph on the CubeCL backend (lavapipe in CI).

use burn::tensor::{Device, Tensor, TensorData};
use envision4d_model::resample::bilinear_align_corners;

/// Values of mixed sign, `[1, 2, h, w]`.
fn mixed(h: usize, w: usize, device: &Device) -> Tensor<4> {
    let v: Vec<f32> = (0..2 * h * w)
        .map(|i| ((i * 7919 % 1013) as f32 - 506.0) / 100.0)
        .collect();
    Tensor::from_data(TensorData::new(v, [1, 2, h, w]), device)
}

/// The resized values and the input gradient of a weighted sum of them, on `device`.
fn resize_and_gradient(
    device: &Device,
    (h, w): (usize, usize),
    (oh, ow): (usize, usize),
) -> [Vec<f32>; 2] {
    let x = mixed(h, w, device).require_grad();
    let y = bilinear_align_corners(x.clone(), oh, ow);
    let grads = (y.clone() * mixed(oh, ow, device)).sum().backward();
    let g = x.grad(&grads).expect("the input gets a gradient");
    let host = |t: Tensor<4>| t.into_data().iter::<f32>().collect::<Vec<_>>();
    [host(y.inner()), host(g)]
}

/// Guards GPU training through the DPT heads: Burn's CubeCL backends have no backward for
/// their bilinear interpolate (only nearest), so `backward()` of a graph holding one panicked
/// ("Bilinear interpolation backward is not supported by JIT backend") and no training step
/// ran on wgpu or CUDA. The resize and its gradient on wgpu equal the CPU's: upsample (the
/// heads' ×2 and final sizes), downsample, one axis unchanged.
#[test]
fn bilinear_resize_trains_on_wgpu_like_the_cpu() {
    let Some(gpu) = envision4d_splat::testkit::wgpu_test_device() else {
        return;
    };
    let cpu = Device::flex().autodiff();
    for (from, to) in [
        ((4, 6), (8, 12)),
        ((5, 7), (28, 42)),
        ((9, 13), (4, 3)),
        ((6, 6), (6, 11)),
    ] {
        let want = resize_and_gradient(&cpu, from, to);
        let got = resize_and_gradient(&gpu.clone().autodiff(), from, to);
        for (what, (g, w)) in ["values", "gradient"].iter().zip(got.iter().zip(&want)) {
            assert_eq!(g.len(), w.len());
            for (i, (a, b)) in g.iter().zip(w).enumerate() {
                assert!(
                    (a - b).abs() <= 1e-5 * b.abs().max(1.0),
                    "{from:?} -> {to:?}, {what} {i}: wgpu {a} vs cpu {b}"
                );
            }
        }
    }
}
