//! Gradients through the Gaussian adapter on rotations where a quaternion candidate of the
//! matrix→quaternion conversion is exactly zero or negative (the common case).

use burn::tensor::{Device, Tensor, TensorData};
use envision4d_model::adapter::{adapt, ScaleRange};

/// Guards the NaN that poisoned training: `sqrt(clamp_min(x, 0))` has gradient 0·∞ = NaN
/// where x ≤ 0, and identity camera rotations with identity Gaussian rotations give
/// exactly such candidates, so every parameter upstream of the rotations got NaN.
#[test]
fn rotation_gradients_finite_when_candidates_vanish() {
    let device = Device::flex().autodiff();
    let (b, s, h, w) = (1, 2, 2, 3);
    let eye: Vec<f32> = (0..b * s)
        .flat_map(|_| {
            [
                1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1.,
            ]
        })
        .collect();
    let extr = Tensor::<4>::from_data(TensorData::new(eye, [b, s, 4, 4]), &device).require_grad();
    let k: Vec<f32> = (0..b * s)
        .flat_map(|_| [1.0, 0., 0.5, 0., 1.0, 0.5, 0., 0., 1.])
        .collect();
    let intr = Tensor::<4>::from_data(TensorData::new(k, [b, s, 3, 3]), &device);
    let depth = Tensor::<4>::ones([b, s, h, w], &device).mul_scalar(5.0);
    let opac = Tensor::<4>::ones([b, s, h, w], &device).mul_scalar(0.5);
    // Raw rotation (r0..r3) = (1, 0, 0, 0): the identity, read as (w, x, y, z) → three of
    // the four candidates are exactly 0 and the rest negative-free.
    let raw: Vec<f32> = (0..b * s * h * w)
        .flat_map(|_| [0., 0., 0., 1., 0., 0., 0., 0.2, 0.4, 0.6])
        .collect();
    let raw =
        Tensor::<5>::from_data(TensorData::new(raw, [b, s, h, w, 10]), &device).require_grad();
    let motion = Tensor::<5>::zeros([b, s, h, w, 3], &device);
    let a = adapt(
        extr.clone(),
        intr,
        depth,
        opac,
        raw.clone(),
        motion,
        ScaleRange {
            min: 0.5,
            max: 15.0,
        },
    );
    let loss = a.rotations.sum() + a.means.sum();
    let grads = loss.backward();
    for (name, g) in [("raw", raw.grad(&grads)), ("extrinsics", None)] {
        if let Some(g) = g {
            assert!(
                g.into_data().iter::<f32>().all(f32::is_finite),
                "{name} gradient not finite"
            );
        }
    }
    let ge = extr.grad(&grads).expect("extrinsics get a gradient");
    assert!(
        ge.into_data().iter::<f32>().all(f32::is_finite),
        "extrinsics gradient not finite"
    );
}
