//! GELU (`x · Φ(x)`, the erf form PyTorch's `nn.GELU()` computes) for inference on the CPU
//! backend, vectorised.
//!
//! Why our own: burn-flex evaluates `erf` with scalar libm calls, ~5% of the tiny forward
//! (docs/PERFORMANCE.md, "What made the tiny widths fast"). Here `erf` is Abramowitz &
//! Stegun 7.1.26 (absolute error below 1.5e-7) on top of the softmax's polynomial `exp`,
//! written lane-wise and compiled for AVX-512 and AVX2 + FMA, picked at run time like the
//! attention kernel.
//! Autodiff devices keep Burn's op, whose backward is defined.

use super::cpu_attention::{exp, Isa};
use burn::tensor::activation;
use burn::tensor::{Tensor, TensorData};
use rayon::prelude::*;

/// Elements per parallel job.
const CHUNK: usize = 1 << 14;

/// `gelu(x)`, through the vectorised kernel on the CPU backend without autodiff.
pub fn gelu<const D: usize>(x: Tensor<D>) -> Tensor<D> {
    let device = x.device();
    if !super::cpu_inference(&x) {
        return activation::gelu(x);
    }
    let dims = x.dims();
    let mut v = super::host_f32(x);
    gelu_host(&mut v, Isa::detect());
    Tensor::from_data(TensorData::new(v, dims), &device)
}

/// In place on a host buffer.
pub fn gelu_host(v: &mut [f32], isa: Isa) {
    v.par_chunks_mut(CHUNK).for_each(|c| match isa {
        // SAFETY: the variant is only chosen when the CPU reports the features.
        #[cfg(target_arch = "x86_64")]
        Isa::Avx512 => unsafe { gelu_avx512(c) },
        // SAFETY: as above.
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2Fma => unsafe { gelu_avx2(c) },
        _ => gelu_lanes(c),
    });
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn gelu_avx512(v: &mut [f32]) {
    gelu_lanes(v);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn gelu_avx2(v: &mut [f32]) {
    gelu_lanes(v);
}

#[inline(always)]
fn gelu_lanes(v: &mut [f32]) {
    for x in v.iter_mut() {
        *x = gelu_scalar(*x);
    }
}

/// `0.5 x (1 + erf(x / √2))`.
#[inline(always)]
pub fn gelu_scalar(x: f32) -> f32 {
    // A&S 7.1.26: erf(z) = 1 − (a1 t + … + a5 t⁵) e^(−z²), t = 1 / (1 + p z), z >= 0.
    const P: f32 = 0.327_591_1;
    const A: [f32; 5] = [
        0.254_829_6,
        -0.284_496_74,
        1.421_413_7,
        -1.453_152_1,
        1.061_405_4,
    ];
    let z = (x * std::f32::consts::FRAC_1_SQRT_2).abs();
    let t = 1.0 / (1.0 + P * z);
    let poly = ((((A[4] * t + A[3]) * t + A[2]) * t + A[1]) * t + A[0]) * t;
    let erf_abs = 1.0 - poly * exp(-z * z);
    let erf = if x < 0.0 { -erf_abs } else { erf_abs };
    0.5 * x * (1.0 + erf)
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::tensor::Device;

    /// Guards the vectorised GELU against Burn's (libm erf) over [-12, 12], including the
    /// far tails (where 1 + erf cancels) and signed zero, on every instruction set here: the
    /// bound is the approximation's 1.5e-7 in erf plus a few ulp of rounding.
    #[test]
    fn matches_burns_gelu() {
        let n = 48_001;
        let xs: Vec<f32> = (0..n)
            .map(|i| -12.0 + 24.0 * i as f32 / (n - 1) as f32)
            .collect();
        let device = Device::flex().autodiff();
        let want = super::super::host_f32(activation::gelu(Tensor::<1>::from_data(
            TensorData::new(xs.clone(), [n]),
            &device,
        )));
        let mut isas = vec![Isa::Portable, Isa::detect()];
        isas.dedup();
        for isa in isas {
            let mut got = xs.clone();
            gelu_host(&mut got, isa);
            for ((x, g), w) in xs.iter().zip(&got).zip(&want) {
                assert!(
                    (g - w).abs() <= 4e-7 * x.abs().max(1.0),
                    "{isa:?} gelu({x}) = {g}, want {w}"
                );
            }
        }
        let mut zero = [0.0f32, -0.0];
        gelu_host(&mut zero, Isa::detect());
        assert_eq!(zero, [0.0, 0.0]);
    }
}
