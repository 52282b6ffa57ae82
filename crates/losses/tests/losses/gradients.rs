//! Finite-difference gradient checks (f64 on burn-flex) of the differentiable losses.

use burn::tensor::{DType, Device, Tensor};
use envision4d_losses::{
    camera_distill, depth_distill, distill, mse_per_frame, ssim_per_frame, DistillWeights, Lpips,
    LpipsWeights,
};

use crate::common::{fixture_vgg_weights, tensor, values, Rng};
use crate::lpips::random_alex_weights;

const EPS: f64 = 1e-6;

/// Compare autodiff with central differences at a few flat indices of `x`.
fn check<const D: usize>(
    name: &str,
    x: &[f64],
    shape: [usize; D],
    indices: &[usize],
    loss: &dyn Fn(Tensor<D>) -> Tensor<1>,
) {
    let ad = Device::flex().autodiff();
    let xt = tensor(x, shape, &ad, DType::F64).require_grad();
    let grads = loss(xt.clone()).backward();
    let g = values(xt.grad(&grads).expect("gradient"));
    let plain = Device::flex();
    let eval = |v: &[f64]| values(loss(tensor(v, shape, &plain, DType::F64)))[0];
    assert!(
        indices.iter().any(|&i| g[i] != 0.0),
        "{name}: all checked gradients are zero; the check would be vacuous"
    );
    for &i in indices {
        let (mut a, mut b) = (x.to_vec(), x.to_vec());
        a[i] += EPS;
        b[i] -= EPS;
        let fd = (eval(&a) - eval(&b)) / (2.0 * EPS);
        assert!(
            (fd - g[i]).abs() <= 1e-7 + 1e-5 * g[i].abs(),
            "{name}[{i}]: finite difference {fd:e} vs autodiff {:e}",
            g[i]
        );
    }
}

/// Weighted sum of a per-frame loss, so each frame's gradient is checked separately.
fn weighted(per_frame: Tensor<1>, w: &[f64]) -> Tensor<1> {
    let device = per_frame.device();
    (per_frame * tensor(w, [w.len()], &device, DType::F64)).sum()
}

/// Guards the MSE gradient (factor 2/N per frame, target detached).
#[test]
fn mse_gradient_matches_finite_differences() {
    let mut rng = Rng::new(1);
    let shape = [2, 3, 4, 5];
    let x = rng.vec(120, 0.0, 1.0);
    let y = rng.vec(120, 0.0, 1.0);
    check("mse", &x, shape, &[0, 7, 59, 60, 119], &|p| {
        let t = tensor(&y, shape, &p.device(), DType::F64);
        weighted(mse_per_frame(p, t).unwrap(), &[0.7, 1.3])
    });
}

/// Guards the SSIM-term gradient (quotient rule through five blurred maps, reflected
/// borders feeding the cropped interior) at corner, edge, interior and last entries.
#[test]
fn ssim_gradient_matches_finite_differences() {
    let mut rng = Rng::new(9);
    let shape = [2, 3, 12, 13];
    let n: usize = shape.iter().product();
    let x = rng.vec(n, 0.0, 1.0);
    let y = rng.vec(n, 0.0, 1.0);
    check(
        "ssim",
        &x,
        shape,
        &[0, 5, 12, 80, 156, 300, 500, n - 1],
        &|p| {
            let t = tensor(&y, shape, &p.device(), DType::F64);
            weighted(ssim_per_frame(p, t).unwrap(), &[0.7, 1.3])
        },
    );
}

/// Central finite differences of LPIPS at random images; `image_weights` weights the
/// per-image distances (`None`: plain sum).
fn lpips_matches_fd(
    name: &str,
    weights: &LpipsWeights,
    seed: u64,
    shape: [usize; 4],
    entries: &[usize],
    image_weights: Option<&[f64]>,
) {
    let mut rng = Rng::new(seed);
    let n = shape.iter().product();
    let x = rng.vec(n, 0.0, 1.0);
    let y = rng.vec(n, 0.0, 1.0);
    let nets = [
        Lpips::new(weights, &Device::flex().autodiff(), DType::F64),
        Lpips::new(weights, &Device::flex(), DType::F64),
    ];
    check(name, &x, shape, entries, &|p| {
        let net = &nets[usize::from(!p.device().is_autodiff())];
        let t = tensor(&y, shape, &p.device(), DType::F64);
        let d = net.forward(p, t).unwrap();
        match image_weights {
            Some(w) => weighted(d, w),
            None => d.sum(),
        }
    });
}

/// Guards the LPIPS VGG backward through conv, ReLU, max-pool and the unit normalisation.
#[test]
fn lpips_vgg_gradient_matches_finite_differences() {
    lpips_matches_fd(
        "lpips vgg",
        &fixture_vgg_weights(),
        2,
        [2, 3, 16, 16],
        &[0, 100, 300, 767, 768, 1500],
        Some(&[1.0, 0.5]),
    );
}

/// Guards the LPIPS AlexNet backward (strided 11×11 conv, 3×3/2 pools).
#[test]
fn lpips_alex_gradient_matches_finite_differences() {
    lpips_matches_fd(
        "lpips alex",
        &random_alex_weights(11),
        3,
        [1, 3, 32, 32],
        &[0, 33, 500, 1024, 2000, 3071],
        None,
    );
}

/// Guards the distillation L1 gradients (sign/N, teacher detached) and their weighting.
#[test]
fn distillation_gradients_match_finite_differences() {
    let mut rng = Rng::new(4);
    let pshape = [1, 4, 9];
    let pose = rng.vec(36, -1.0, 1.0);
    let pose_t = rng.vec(36, -1.0, 1.0);
    let dshape = [1, 2, 3, 4, 1];
    let depth = rng.vec(24, 0.5, 2.0);
    let depth_t = rng.vec(24, 0.5, 2.0);
    check("camera distill", &pose, pshape, &[0, 8, 20, 35], &|p| {
        let t = tensor(&pose_t, pshape, &p.device(), DType::F64);
        camera_distill(p, t).unwrap()
    });
    check("depth distill", &depth, dshape, &[0, 5, 23], &|d| {
        let t = tensor(&depth_t, dshape, &d.device(), DType::F64);
        depth_distill(d, t).unwrap()
    });
    // The weighted total: d(5·L_cam)/dP through `distill`.
    check("distill total", &pose, pshape, &[3, 17], &|p| {
        let dev = p.device();
        let t = tensor(&pose_t, pshape, &dev, DType::F64);
        let d = tensor(&depth, dshape, &dev, DType::F64);
        let dt = tensor(&depth_t, dshape, &dev, DType::F64);
        distill(DistillWeights::default(), p, t, d, dt)
            .unwrap()
            .total
    });
}
