//! Building blocks shared by the backbone and heads.

pub mod attention;
pub mod block;
mod chunked;
pub mod cpu_attention;
pub mod cpu_conv;
pub mod cpu_gelu;
pub mod cube_rows;
pub mod gelu;
pub mod lean_attention;
pub mod norm;
pub mod qkv_attention;
pub mod recompute;
pub mod residual;
pub mod rope;

pub use attention::{Attention, QkNorm};
pub use block::{Block, BlockSpec, LayerScale, Mlp, BLOCK_NORM_EPS, DINO_NORM_EPS};
pub use rope::{frame_positions, RopeTables};

/// A tensor's values as a host `Vec<f32>` (what the CPU inference kernels compute on).
pub(crate) fn host_f32<const D: usize>(t: burn::tensor::Tensor<D>) -> Vec<f32> {
    t.into_data()
        .convert::<f32>()
        .try_into_vec::<f32>()
        .expect("f32 after convert")
}

/// A read-only strided matrix operand for [`gemm_f32`]: element `(r, c)` is at
/// `ptr + r·row_stride + c·col_stride`.
#[derive(Clone, Copy)]
pub(crate) struct Strided {
    pub ptr: *const f32,
    pub row_stride: isize,
    pub col_stride: isize,
}

/// `dst[m, n] = lhs[m, k] · rhs[k, n]` (or `+=` with `accumulate`), `dst` row-major with row
/// stride `dst_row_stride`, single-threaded (the kernels parallelise over their own jobs).
///
/// # Safety
/// Every element the shapes and strides address must lie inside live allocations, and `dst`
/// must not overlap the operands or be written by another thread meanwhile.
pub(crate) unsafe fn gemm_f32(
    [m, n, k]: [usize; 3],
    dst: *mut f32,
    dst_row_stride: isize,
    accumulate: bool,
    lhs: Strided,
    rhs: Strided,
) {
    // SAFETY: forwarded from the caller's contract.
    unsafe {
        gemm::gemm(
            m,
            n,
            k,
            dst,
            1,
            dst_row_stride,
            accumulate,
            lhs.ptr,
            lhs.col_stride,
            lhs.row_stride,
            rhs.ptr,
            rhs.col_stride,
            rhs.row_stride,
            1.0,
            1.0,
            false,
            false,
            false,
            gemm::Parallelism::None,
        );
    }
}

/// Test helpers shared by the kernels' tests.
#[cfg(test)]
pub(crate) mod test_util {
    use burn::tensor::Tensor;

    /// Seeded values in `[-amplitude, amplitude)` (an LCG; no RNG crate needed).
    pub fn values(len: usize, seed: u64, amplitude: f32) -> Vec<f32> {
        let mut s = seed;
        (0..len)
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((s >> 40) as f32 / (1u64 << 24) as f32 - 0.5) * 2.0 * amplitude
            })
            .collect()
    }

    /// `max |a - b|`.
    pub fn max_abs_diff<const D: usize>(a: Tensor<D>, b: Tensor<D>) -> f32 {
        super::host_f32((a - b).abs().max())[0]
    }
}

/// Whether the CPU inference kernels (`cpu_attention`, `cpu_conv`, `cpu_gelu`, the bilinear
/// resize) may run on `x`: an f32 tensor of the CPU backend *without* autodiff. They compute
/// on host buffers, so on an autodiff device they would cut the graph. (`Device`'s equality
/// ignores the autodiff wrapper, hence the explicit check.) They compute in f32, so a
/// reduced-precision aggregator takes Burn's ops instead, the same ops a GPU runs.
pub fn cpu_inference<const D: usize>(x: &burn::tensor::Tensor<D>) -> bool {
    let device = x.device();
    x.dtype() == burn::tensor::DType::F32
        && !device.is_autodiff()
        && device == burn::tensor::Device::flex()
}

#[cfg(test)]
mod tests {
    use burn::nn::conv::Conv2dConfig;
    use burn::nn::PaddingConfig2d;
    use burn::tensor::{Device, Distribution, Tensor};

    /// Guards the dispatch of the CPU inference kernels: on an autodiff CPU device they must
    /// not run (they compute on host buffers and would cut the graph; `Device`'s equality
    /// ignores the autodiff wrapper), nor on half tensors. Each dispatcher's input gets a
    /// non-zero gradient.
    #[test]
    fn cpu_kernels_never_cut_an_autodiff_graph() {
        let device = Device::flex().autodiff();
        let on = |d: &Device| Tensor::<1>::zeros([1], d);
        assert!(!super::cpu_inference(&on(&device)));
        assert!(super::cpu_inference(&on(&Device::flex())));
        // A half tensor takes Burn's ops too (the kernels compute in f32).
        let half = on(&Device::flex()).cast(burn::tensor::DType::F16);
        assert!(!super::cpu_inference(&half));
        let x = || {
            Tensor::<4>::random([1, 4, 6, 8], Distribution::Uniform(-1.0, 1.0), &device)
                .require_grad()
        };
        let conv = Conv2dConfig::new([4, 4], [3, 3])
            .with_padding(PaddingConfig2d::Explicit(1, 1, 1, 1))
            .init(&device);
        let attention = super::Attention::new(8, 2, super::QkNorm::On, &device);
        let ops: [(&str, Box<dyn Fn(Tensor<4>) -> Tensor<4>>); 4] = [
            ("conv", Box::new(|t| super::cpu_conv::conv2d(&conv, t))),
            ("gelu", Box::new(super::cpu_gelu::gelu)),
            (
                "bilinear",
                Box::new(|t| crate::resample::bilinear_align_corners(t, 11, 13)),
            ),
            (
                "attention",
                Box::new(|t: Tensor<4>| {
                    attention
                        .forward(t.reshape([1, 24, 8]), None)
                        .reshape([1, 4, 6, 8])
                }),
            ),
        ];
        for (name, op) in ops {
            let input = x();
            let grads = (op(input.clone()) * 1.7).sum().backward();
            let g = input
                .grad(&grads)
                .unwrap_or_else(|| panic!("{name}: no gradient reached the input"));
            let norm = super::host_f32(g.abs().sum())[0];
            assert!(norm > 0.0, "{name}: zero gradient");
        }
    }
}
