//! Stride-1 "same" convolutions for inference on the CPU backend, without im2col.
//!
//! Why our own: the DPT heads' full-resolution 3x3 convolution (32 → 32 channels at 350x518)
//! ran ten times per forward and was the largest cost of the heads. burn-flex lowers a
//! convolution to im2col + gemm, and building the im2col tiles (nine shifted copies of the
//! input, element by element) cost about as much as the products. Here the input is padded
//! once and each kernel tap becomes one matrix product on a *shifted flat view* of it: with
//! the padded row length `Wp = W + 2p`, output pixel `(y, x)` of tap `(ky, kx)` reads padded
//! element `(y + ky)·Wp + (x + kx)`, i.e. a contiguous view starting at `ky·Wp + kx`, if the
//! output is computed `Wp` wide and the `2p` extra columns of each row are dropped at the end.
//! gemm packs those views with vector loads, so no im2col buffer exists at all.
//!
//! Work is split into bands of output rows; each band accumulates all taps while its output
//! tile is in cache. Autodiff devices keep Burn's convolution, whose backward is defined.

use super::{gemm_f32, Strided};
use burn::nn::conv::Conv2d;
use burn::nn::PaddingConfig2d;
use burn::tensor::{Tensor, TensorData};
use rayon::prelude::*;

/// Output columns per job (rows of `Wp` each, at least one row): ~2k columns keep a
/// 32-channel output tile and its inputs within L2.
pub const BAND_COLUMNS: usize = 2048;

/// The convolution, through our kernel when it applies (CPU backend, no autodiff, stride 1,
/// dilation 1, one group, symmetric padding `(k - 1) / 2`), otherwise through Burn's.
pub fn conv2d(conv: &Conv2d, x: Tensor<4>) -> Tensor<4> {
    let device = x.device();
    let [kh, kw] = conv.kernel_size;
    let same = kh == kw
        && kh % 2 == 1
        && conv.padding == PaddingConfig2d::Explicit(kh / 2, kh / 2, kh / 2, kh / 2);
    if !super::cpu_inference(&x)
        || !same
        || conv.stride != [1, 1]
        || conv.dilation != [1, 1]
        || conv.groups != 1
    {
        return conv.forward(x);
    }
    let [n, ci, h, w] = x.dims();
    let weight = conv.weight.val();
    let co = weight.dims()[0];
    let bias = conv.bias.as_ref().map(|b| super::host_f32(b.val()));
    let out = conv_same_host(
        &super::host_f32(x),
        &super::host_f32(weight),
        bias.as_deref(),
        [n, ci, h, w, co, kh],
    );
    Tensor::from_data(TensorData::new(out, [n, co, h, w]), &device)
}

/// The kernel on host buffers: `x [N, Ci, H, W]`, `weight [Co, Ci, k, k]`, optional
/// `bias [Co]`; `dims = [N, Ci, H, W, Co, k]`. Returns `[N, Co, H, W]`.
pub fn conv_same_host(
    x: &[f32],
    weight: &[f32],
    bias: Option<&[f32]>,
    [n, ci, h, w, co, k]: [usize; 6],
) -> Vec<f32> {
    assert_eq!(x.len(), n * ci * h * w, "x is not [N, Ci, H, W]");
    assert_eq!(
        weight.len(),
        co * ci * k * k,
        "weight is not [Co, Ci, k, k]"
    );
    let p = k / 2;
    let (hp, wp) = (h + 2 * p, w + 2 * p);
    // Each channel's padded plane, plus 2p trailing zeros: the last tap's view of the last
    // band reads up to 2p elements past the plane.
    let plane = hp * wp + 2 * p;
    let mut out = vec![0f32; n * co * h * w];
    if out.is_empty() {
        return out;
    }
    let mut padded = vec![0f32; n * ci * plane];
    padded
        .par_chunks_exact_mut(plane)
        .zip(x.par_chunks_exact(h * w))
        .for_each(|(dst, src)| {
            for (y, row) in src.chunks_exact(w).enumerate() {
                let at = (y + p) * wp + p;
                dst[at..at + w].copy_from_slice(row);
            }
        });
    let band_rows = (BAND_COLUMNS / wp).clamp(1, h);
    let bands = h.div_ceil(band_rows);
    // One job per (image, band of rows); each writes its own [Co, rows·Wp] tile.
    let tiles: Vec<(usize, usize, Vec<f32>)> = (0..n * bands)
        .into_par_iter()
        .map(|job| {
            let (img, band) = (job / bands, job % bands);
            let y0 = band * band_rows;
            let rows = band_rows.min(h - y0);
            let cols = rows * wp;
            let mut tile = vec![0f32; co * cols];
            let src = &padded[img * ci * plane..(img + 1) * ci * plane];
            for ky in 0..k {
                for kx in 0..k {
                    let tap = ky * k + kx;
                    let view = (y0 + ky) * wp + kx;
                    // tile[Co, cols] += weight[:, :, ky, kx] · src[Ci, view .. view + cols]
                    // SAFETY: lhs reads co x ci elements at strides (ci·k², k²) from offset
                    // `tap` of `weight` (in bounds: the last is
                    // (co-1)·ci·k² + (ci-1)·k² + tap);
                    // rhs reads ci rows of `cols` contiguous floats at stride `plane` from
                    // `view`, and view + cols <= (h + 2p)·wp + 2p = plane by construction; the
                    // destination is this job's own tile.
                    unsafe {
                        gemm_f32(
                            [co, cols, ci],
                            tile.as_mut_ptr(),
                            cols as isize,
                            tap > 0,
                            Strided {
                                ptr: weight.as_ptr().add(tap),
                                row_stride: (ci * k * k) as isize,
                                col_stride: (k * k) as isize,
                            },
                            Strided {
                                ptr: src.as_ptr().add(view),
                                row_stride: plane as isize,
                                col_stride: 1,
                            },
                        );
                    }
                }
            }
            (img, y0, tile)
        })
        .collect();
    // Drop the 2p padding columns of every row and add the bias, one output plane per job.
    out.par_chunks_exact_mut(h * w)
        .enumerate()
        .for_each(|(plane_idx, dst)| {
            let (img, c) = (plane_idx / co, plane_idx % co);
            let b = bias.map_or(0.0, |b| b[c]);
            for (_, y0, tile) in &tiles[img * bands..(img + 1) * bands] {
                let cols = tile.len() / co;
                let t = &tile[c * cols..(c + 1) * cols];
                for (r, src) in t.chunks_exact(wp).enumerate() {
                    let row = &mut dst[(y0 + r) * w..(y0 + r + 1) * w];
                    for (d, s) in row.iter_mut().zip(&src[..w]) {
                        *d = s + b;
                    }
                }
            }
        });
    out
}

#[cfg(test)]
mod tests {
    use super::super::test_util::{max_abs_diff, values};
    use super::*;
    use burn::nn::conv::Conv2dConfig;
    use burn::tensor::Device;

    /// Guards the shifted-view kernel against Burn's convolution: 3x3 and 7x7 kernels, with
    /// and without bias, several images, one row, and images tall enough to split into
    /// several bands (the band edges are where an off-by-one in the views would show).
    #[test]
    fn matches_burns_convolution() {
        let device = Device::flex();
        for (n, ci, h, w, co, k, bias) in [
            (2, 5, 9, 11, 7, 3, true),
            (1, 3, 70, 40, 4, 3, false),
            (1, 3, 13, 17, 6, 7, true),
            (3, 2, 1, 6, 3, 3, true),
        ] {
            let mut conv = Conv2dConfig::new([ci, co], [k, k])
                .with_padding(PaddingConfig2d::Explicit(k / 2, k / 2, k / 2, k / 2))
                .with_bias(bias)
                .init(&device);
            conv.weight = burn::module::Param::from_tensor(Tensor::from_data(
                TensorData::new(values(co * ci * k * k, 7, 0.5), [co, ci, k, k]),
                &device,
            ));
            let x = Tensor::<4>::from_data(
                TensorData::new(values(n * ci * h * w, 9, 0.5), [n, ci, h, w]),
                &device,
            );
            let ours = conv2d(&conv, x.clone());
            let theirs = conv.forward(x);
            assert_eq!(ours.dims(), theirs.dims());
            let diff = max_abs_diff(ours, theirs);
            assert!(
                diff < 1e-5,
                "{n}x{ci}x{h}x{w} -> {co}, k {k}: max difference {diff}"
            );
        }
    }
}
