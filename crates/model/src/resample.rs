//! Resampling as PyTorch does it, written out as explicit weight matrices.
//!
//! * Antialiased bicubic (`F.interpolate(mode="bicubic", antialias=True, align_corners=False)`),
//!   used on the DINO pos-embed: separable, PIL-style, cubic kernel with `a = -0.5`, support
//!   widened by the scale when downsampling.
//! * Bilinear with `align_corners=True`, used throughout the DPT heads.

use burn::tensor::module::interpolate;
use burn::tensor::ops::{InterpolateMode, InterpolateOptions};
use burn::tensor::{Device, Int, Tensor, TensorData};
use rayon::prelude::*;

/// Cubic convolution coefficient of the antialiased kernel (PIL uses -0.5).
pub const AA_CUBIC_A: f64 = -0.5;

fn cubic(x: f64) -> f64 {
    let a = AA_CUBIC_A;
    let x = x.abs();
    if x < 1.0 {
        ((a + 2.0) * x - (a + 3.0)) * x * x + 1.0
    } else if x < 2.0 {
        (((x - 5.0) * x + 8.0) * x - 4.0) * a
    } else {
        0.0
    }
}

/// `[out, in]` row-stochastic weights of antialiased bicubic resampling along one axis.
pub fn aa_bicubic_weights(input: usize, output: usize) -> Vec<f64> {
    let scale = input as f64 / output as f64;
    // Downsampling widens the kernel by the scale (antialiasing); upsampling keeps it.
    let (support, inv) = if scale >= 1.0 {
        (2.0 * scale, 1.0 / scale)
    } else {
        (2.0, 1.0)
    };
    let mut w = vec![0.0; output * input];
    for i in 0..output {
        let center = scale * (i as f64 + 0.5);
        // Truncation toward zero, as the reference's integer cast.
        let xmin = ((center - support + 0.5) as i64).max(0) as usize;
        let xmax = ((center + support + 0.5) as i64).min(input as i64) as usize;
        let taps: Vec<f64> = (xmin..xmax)
            .map(|j| cubic((j as f64 - center + 0.5) * inv))
            .collect();
        let total: f64 = taps.iter().sum();
        for (k, t) in taps.iter().enumerate() {
            w[i * input + xmin + k] = if total != 0.0 { t / total } else { 0.0 };
        }
    }
    w
}

/// `[out, in]` weights of bilinear resampling with `align_corners=True` (the dense form of
/// [`bilinear_align_corners_taps`]).
pub fn bilinear_align_corners_weights(input: usize, output: usize) -> Vec<f64> {
    let mut w = vec![0.0; output * input];
    for (i, (lo, hi, w_lo, w_hi)) in bilinear_align_corners_taps(input, output)
        .into_iter()
        .enumerate()
    {
        w[i * input + lo] += w_lo;
        w[i * input + hi] += w_hi;
    }
    w
}

fn matrix(w: Vec<f64>, rows: usize, cols: usize, device: &Device) -> Tensor<2> {
    let w: Vec<f32> = w.into_iter().map(|v| v as f32).collect();
    Tensor::from_data(TensorData::new(w, [rows, cols]), device)
}

/// Applies separable row/column weights to `x: [N, C, H, W]` → `[N, C, h, w]`.
pub fn resample_separable(
    x: Tensor<4>,
    w_rows: Vec<f64>,
    w_cols: Vec<f64>,
    out_h: usize,
    out_w: usize,
) -> Tensor<4> {
    let [n, c, h, w] = x.dims();
    let device = x.device();
    let wr = matrix(w_rows, out_h, h, &device).cast(x.dtype());
    let wc = matrix(w_cols, out_w, w, &device).cast(x.dtype());
    // Columns: [N*C*H, W] @ [W, w].
    let x = x
        .reshape([n * c * h, w])
        .matmul(wc.transpose())
        .reshape([n * c, h, out_w]);
    // Rows: [h, H] @ [N*C, H, w] (broadcast over N*C).
    let x = wr.unsqueeze::<3>().expand([n * c, out_h, h]).matmul(x);
    x.reshape([n, c, out_h, out_w])
}

/// The two taps of bilinear (`align_corners=True`) resampling along one axis: for every
/// output index, `(lo, hi, w_lo, w_hi)` with the same f64 arithmetic as
/// [`bilinear_align_corners_weights`] (whose rows are exactly these two entries).
pub fn bilinear_align_corners_taps(input: usize, output: usize) -> Vec<(usize, usize, f64, f64)> {
    (0..output)
        .map(|i| {
            let src = if output > 1 {
                i as f64 * (input as f64 - 1.0) / (output as f64 - 1.0)
            } else {
                0.0
            };
            let lo = (src.floor() as usize).min(input - 1);
            let hi = (lo + 1).min(input - 1);
            let frac = src - lo as f64;
            (lo, hi, 1.0 - frac, frac)
        })
        .collect()
}

/// Bilinear (`align_corners=True`) resize of `[N, C, H, W]` to `[N, C, h, w]`. Inference on
/// the CPU backend runs [`bilinear_align_corners_host`] (separable: columns, then rows);
/// training on a GPU backend [`bilinear_align_corners_gathered`]; elsewhere Burn's
/// interpolate op. (The dense weight-matrix product [`resample_separable`] gives the same
/// values but, at the DPT heads' final 200x296 → 350x518 upsample, costs ~2 GMAC a map
/// instead of ~6 flops per output.)
pub fn bilinear_align_corners(x: Tensor<4>, out_h: usize, out_w: usize) -> Tensor<4> {
    let [n, c, h, w] = x.dims();
    if (h, w) == (out_h, out_w) {
        return x;
    }
    let device = x.device();
    if crate::layers::cpu_inference(&x) {
        let host = crate::layers::host_f32(x);
        let out = bilinear_align_corners_host(&host, [n * c, h, w], [out_h, out_w]);
        return Tensor::from_data(TensorData::new(out, [n, c, out_h, out_w]), &device);
    }
    // Burn's CubeCL backends (wgpu, CUDA) implement the interpolate backward for nearest
    // only: a bilinear resize in a training graph there panics in `backward()`.
    if device.is_autodiff() && device != Device::flex() {
        return bilinear_align_corners_gathered(x, out_h, out_w);
    }
    interpolate(
        x,
        InterpolateOptions::new(InterpolateMode::Bilinear)
            .with_align_corners(true)
            .with_output_size([out_h, out_w]),
    )
}

/// The same resize as gathers and blends along each axis (width, then height): two
/// `select`s of the neighbouring rows or columns, weighted by [`bilinear_align_corners_taps`]
/// in f32 as the host kernel has them. Every op has a backward on every backend (select's is a
/// deterministic scatter-add), at O(output) work, so a GPU trains through it.
pub fn bilinear_align_corners_gathered(x: Tensor<4>, out_h: usize, out_w: usize) -> Tensor<4> {
    let x = blend_along(x, 3, out_w);
    blend_along(x, 2, out_h)
}

/// One axis of [`bilinear_align_corners_gathered`].
fn blend_along(x: Tensor<4>, axis: usize, output: usize) -> Tensor<4> {
    let input = x.dims()[axis];
    if input == output {
        return x;
    }
    let device = x.device();
    let taps = bilinear_align_corners_taps(input, output);
    let index = |hi: bool| {
        let v: Vec<i64> = taps
            .iter()
            .map(|&(lo, up, _, _)| if hi { up } else { lo } as i64)
            .collect();
        Tensor::<1, Int>::from_data(TensorData::new(v, [output]), &device)
    };
    let mut shape = [1; 4];
    shape[axis] = output;
    let dtype = x.dtype();
    let weight = |hi: bool| {
        let v: Vec<f32> = taps
            .iter()
            .map(|&(_, _, a, b)| if hi { b } else { a } as f32)
            .collect();
        Tensor::<4>::from_data(TensorData::new(v, shape), &device).cast(dtype)
    };
    x.clone().select(axis, index(false)) * weight(false)
        + x.select(axis, index(true)) * weight(true)
}

/// The separable resize on host planes `[planes, H, W]` → `[planes, h, w]`, one plane per
/// job: each input row is resampled to the new width (two gathered taps per output), then
/// each output row is a two-row blend of those, a contiguous loop the compiler vectorises.
pub fn bilinear_align_corners_host(
    x: &[f32],
    [planes, h, w]: [usize; 3],
    [out_h, out_w]: [usize; 2],
) -> Vec<f32> {
    assert_eq!(x.len(), planes * h * w, "x is not [planes, H, W]");
    let f32_taps = |input, output| -> Vec<(usize, usize, f32, f32)> {
        bilinear_align_corners_taps(input, output)
            .into_iter()
            .map(|(lo, hi, a, b)| (lo, hi, a as f32, b as f32))
            .collect()
    };
    let (cols, rows) = (f32_taps(w, out_w), f32_taps(h, out_h));
    let mut out = vec![0f32; planes * out_h * out_w];
    if out.is_empty() {
        return out;
    }
    out.par_chunks_exact_mut(out_h * out_w)
        .zip(x.par_chunks_exact(h * w))
        .for_each(|(dst, src)| {
            let mut wide = vec![0f32; h * out_w];
            for (row, line) in wide.chunks_exact_mut(out_w).zip(src.chunks_exact(w)) {
                for (o, &(lo, hi, a, b)) in row.iter_mut().zip(&cols) {
                    *o = a * line[lo] + b * line[hi];
                }
            }
            for (row, &(lo, hi, a, b)) in dst.chunks_exact_mut(out_w).zip(&rows) {
                let (top, bottom) = (
                    &wide[lo * out_w..(lo + 1) * out_w],
                    &wide[hi * out_w..(hi + 1) * out_w],
                );
                for ((o, t), u) in row.iter_mut().zip(top).zip(bottom) {
                    *o = a * t + b * u;
                }
            }
        });
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Guards the antialiased bicubic kernel against the reference rows quoted in the spec
    /// (37 → 25, the paper's pos-embed resize).
    #[test]
    fn aa_bicubic_rows_match_reference_values() {
        let w = aa_bicubic_weights(37, 25);
        let row = |i: usize| &w[i * 37..(i + 1) * 37];
        let close =
            |got: &[f64], want: &[f64]| got.iter().zip(want).all(|(g, w)| (g - w).abs() < 1e-6);
        assert!(
            close(&row(0)[0..4], &[0.665034, 0.384516, -0.043966, -0.005583]),
            "{:?}",
            &row(0)[0..4]
        );
        assert!(close(
            &row(1)[0..5],
            &[-0.038247, 0.390445, 0.618682, 0.067460, -0.038340]
        ));
        assert!(close(
            &row(12)[16..21],
            &[-0.049445, 0.214973, 0.668943, 0.214973, -0.049445]
        ));
        // Scale 1 is the identity.
        let id = aa_bicubic_weights(37, 37);
        assert!((0..37).all(|i| (id[i * 37 + i] - 1.0).abs() < 1e-12));
    }

    /// Guards align_corners=True: end points map exactly onto end points.
    #[test]
    fn bilinear_align_corners_end_points() {
        let w = bilinear_align_corners_weights(4, 7);
        assert_eq!(w[0], 1.0);
        assert_eq!(w[6 * 4 + 3], 1.0);
        assert!((w[3 * 4 + 1] - 0.5).abs() < 1e-12 && (w[3 * 4 + 2] - 0.5).abs() < 1e-12);
    }

    /// Values of mixed sign and magnitude, `[2, 3, h, w]`.
    fn mixed(h: usize, w: usize, device: &Device) -> Tensor<4> {
        let vals: Vec<f32> = (0..2 * 3 * h * w)
            .map(|i| ((i * 7919 % 1013) as f32 - 506.0) * 10f32.powi(i as i32 % 5 - 2))
            .collect();
        Tensor::from_data(TensorData::new(vals, [2, 3, h, w]), device)
    }

    /// Up, down, unchanged and single-pixel axes.
    const CASES: [(usize, usize, usize, usize); 4] =
        [(5, 7, 9, 13), (9, 13, 4, 3), (6, 6, 6, 11), (1, 4, 3, 1)];

    fn dense(x: Tensor<4>, oh: usize, ow: usize) -> Tensor<4> {
        let [_, _, h, w] = x.dims();
        resample_separable(
            x,
            bilinear_align_corners_weights(h, oh),
            bilinear_align_corners_weights(w, ow),
            oh,
            ow,
        )
    }

    fn assert_close(got: Tensor<4>, want: Tensor<4>, tol: f32, what: &str) {
        let (f, d) = (crate::layers::host_f32(got), crate::layers::host_f32(want));
        assert_eq!(f.len(), d.len(), "{what}");
        for (i, (a, b)) in f.iter().zip(&d).enumerate() {
            assert!(
                (a - b).abs() <= tol * b.abs().max(1.0),
                "{what}, element {i}: {a} vs {b}"
            );
        }
    }

    /// Guards the three resize paths (the CPU kernel, Burn's interpolate op, and the
    /// gathered form GPU training takes) against the dense weight-matrix product they
    /// replaced.
    #[test]
    fn bilinear_paths_match_dense_product() {
        for device in [Device::flex(), Device::flex().autodiff()] {
            for (h, w, oh, ow) in CASES {
                let x = mixed(h, w, &device);
                let fast = bilinear_align_corners(x.clone(), oh, ow);
                assert_eq!(fast.dims(), [2, 3, oh, ow]);
                let what = format!("{device:?} {h}x{w} -> {oh}x{ow}");
                assert_close(fast, dense(x.clone(), oh, ow), 1e-6, &what);
                let gathered = bilinear_align_corners_gathered(x.clone(), oh, ow);
                let what = format!("gathered, {what}");
                assert_close(gathered, dense(x, oh, ow), 1e-6, &what);
            }
        }
    }

    /// Guards the gathered form's backward (select's scatter-add, with the repeated taps of
    /// an upsample and the clamped last tap): the input gradient of a weighted sum equals
    /// the dense product's, whose backward is two matmuls.
    #[test]
    fn gathered_bilinear_gradient_matches_dense_product() {
        let device = Device::flex().autodiff();
        for (h, w, oh, ow) in CASES {
            let grad = |f: &dyn Fn(Tensor<4>) -> Tensor<4>| {
                let x = mixed(h, w, &device).require_grad();
                let r = mixed(oh, ow, &device).div_scalar(100.0);
                let grads = (f(x.clone()) * r).sum().backward();
                x.grad(&grads).expect("input gradient")
            };
            assert_close(
                grad(&|x| bilinear_align_corners_gathered(x, oh, ow)),
                grad(&|x| dense(x, oh, ow)),
                // Sums of up to 4 x 13 products in another order than the matmuls'.
                1e-5,
                &format!("gradient, {h}x{w} -> {oh}x{ow}"),
            );
        }
    }
}
