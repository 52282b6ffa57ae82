//! Softmax attention for inference on the CPU backend: `softmax(q kᵀ / sqrt(d)) v`.
//!
//! Why our own: burn-flex's fused attention evaluates the softmax one score at a time with the
//! scalar `expf` of libm. At the widths the CPU runs (head dim 16, 1,860 tokens in the global
//! blocks) that exponential, not the two matrix products, was the largest single cost of the
//! whole forward (docs/PERFORMANCE.md, "What made the tiny widths fast"). Here the products
//! go to `gemm` (the kernels burn-flex itself calls, AVX-512 where the CPU has it) and the
//! softmax runs 16 lanes at a time, compiled for AVX-512 and AVX2 + FMA and picked when the
//! process starts.
//!
//! Each job is a block of [`QUERY_BLOCK`] query rows of one (batch, head): their full score
//! rows are materialised (at most `QUERY_BLOCK x keys` floats, L2-sized), so the softmax is
//! the exact two-pass form with no online rescaling. Autodiff devices keep Burn's op, whose
//! backward is defined; see [`super::attention::Attention::forward`].

use super::{gemm_f32, Strided};
use burn::tensor::{Tensor, TensorData};
use rayon::prelude::*;

/// Query rows per job: 32 rows of scores over 1,860 keys is 238 KB, which stays in L2.
pub const QUERY_BLOCK: usize = 32;
/// SIMD lanes the softmax loops are written for (one AVX-512 register of f32).
const LANES: usize = 16;
/// Below this argument `exp` is under f32's smallest normal number and is flushed to zero.
const EXP_MIN_ARG: f32 = -87.336_55;

/// Instruction set for the softmax loops, detected once per call.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Isa {
    Avx512,
    Avx2Fma,
    Portable,
}

impl Isa {
    pub fn detect() -> Isa {
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx512f") {
                return Isa::Avx512;
            }
            if std::arch::is_x86_feature_detected!("avx2")
                && std::arch::is_x86_feature_detected!("fma")
            {
                return Isa::Avx2Fma;
            }
        }
        Isa::Portable
    }
}

/// `q: [B, H, N, d]`, `k: [B, H, M, d]`, `v: [B, H, M, dv]` on the CPU backend (no
/// autodiff) → `[B, H, N, dv]` on the same device.
pub fn attention(q: Tensor<4>, k: Tensor<4>, v: Tensor<4>) -> Tensor<4> {
    let device = q.device();
    let [b, h, n, d] = q.dims();
    let m = k.dims()[2];
    let dv = v.dims()[3];
    let (q, k, v) = (super::host_f32(q), super::host_f32(k), super::host_f32(v));
    let out = attention_host(&q, &k, &v, [b * h, n, m, d, dv], Isa::detect());
    Tensor::from_data(TensorData::new(out, [b, h, n, dv]), &device)
}

/// The kernel on contiguous host buffers; `dims = [heads, N, M, d, dv]` (batch folded into
/// heads). Public for the tests and the benchmark.
pub fn attention_host(q: &[f32], k: &[f32], v: &[f32], dims: [usize; 5], isa: Isa) -> Vec<f32> {
    let [heads, n, m, d, dv] = dims;
    assert_eq!(q.len(), heads * n * d, "q is not [heads, N, d]");
    assert_eq!(k.len(), heads * m * d, "k is not [heads, M, d]");
    assert_eq!(v.len(), heads * m * dv, "v is not [heads, M, dv]");
    let mut out = vec![0f32; heads * n * dv];
    // No keys: nothing to attend to, zeros as Burn's op returns.
    if out.is_empty() || m == 0 {
        return out;
    }
    let scale = 1.0 / (d as f32).sqrt();
    out.par_chunks_exact_mut(n * dv)
        .enumerate()
        .for_each(|(head, out_head)| {
            let (qh, kh, vh) = (
                &q[head * n * d..(head + 1) * n * d],
                &k[head * m * d..(head + 1) * m * d],
                &v[head * m * dv..(head + 1) * m * dv],
            );
            out_head
                .par_chunks_mut(QUERY_BLOCK * dv)
                .enumerate()
                .for_each_init(Vec::new, |scores, (blk, out_blk)| {
                    let rows = out_blk.len() / dv;
                    let q0 = blk * QUERY_BLOCK;
                    block(
                        &qh[q0 * d..(q0 + rows) * d],
                        kh,
                        vh,
                        out_blk,
                        [rows, m, d, dv],
                        scale,
                        isa,
                        scores,
                    );
                });
        });
    out
}

/// One block of `rows` queries against all `m` keys of a head.
fn block(
    q: &[f32],
    k: &[f32],
    v: &[f32],
    out: &mut [f32],
    [rows, m, d, dv]: [usize; 4],
    scale: f32,
    isa: Isa,
    scores: &mut Vec<f32>,
) {
    scores.clear();
    scores.resize(rows * m, 0.0);
    // scores[rows, m] = q[rows, d] · k[m, d]ᵀ
    // SAFETY: the operands address exactly q (rows x d), k (m x d, read transposed) and
    // `scores` (rows x m), all live; `scores` is this job's own buffer.
    unsafe {
        gemm_f32(
            [rows, m, d],
            scores.as_mut_ptr(),
            m as isize,
            false,
            Strided {
                ptr: q.as_ptr(),
                row_stride: d as isize,
                col_stride: 1,
            },
            Strided {
                ptr: k.as_ptr(),
                row_stride: 1,
                col_stride: d as isize,
            },
        );
    }
    let mut inv_sums = vec![0f32; rows];
    for (row, inv) in scores.chunks_exact_mut(m).zip(&mut inv_sums) {
        let sum = softmax_row(row, scale, isa);
        // A row whose exponentials all underflow (or are all masked) yields zeros.
        *inv = if sum > 0.0 { 1.0 / sum } else { 0.0 };
    }
    // out[rows, dv] = p[rows, m] · v[m, dv]
    // SAFETY: as above; `out` is this job's own rows x dv slice.
    unsafe {
        gemm_f32(
            [rows, dv, m],
            out.as_mut_ptr(),
            dv as isize,
            false,
            Strided {
                ptr: scores.as_ptr(),
                row_stride: m as isize,
                col_stride: 1,
            },
            Strided {
                ptr: v.as_ptr(),
                row_stride: dv as isize,
                col_stride: 1,
            },
        );
    }
    for (row, inv) in out.chunks_exact_mut(dv).zip(&inv_sums) {
        for o in row.iter_mut() {
            *o *= inv;
        }
    }
}

/// Replaces `row` (raw scores) by `exp(scale·(s − max s))` and returns the sum.
pub fn softmax_row(row: &mut [f32], scale: f32, isa: Isa) -> f32 {
    match isa {
        // SAFETY: the variant is only chosen when the CPU reports the features.
        #[cfg(target_arch = "x86_64")]
        Isa::Avx512 => unsafe { softmax_row_avx512(row, scale) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as above.
        Isa::Avx2Fma => unsafe { softmax_row_avx2(row, scale) },
        _ => softmax_row_lanes(row, scale),
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn softmax_row_avx512(row: &mut [f32], scale: f32) -> f32 {
    softmax_row_lanes(row, scale)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn softmax_row_avx2(row: &mut [f32], scale: f32) -> f32 {
    softmax_row_lanes(row, scale)
}

/// The softmax loops, written lane-wise so that the compiler vectorises them for whichever
/// instruction set the caller was compiled for.
#[inline(always)]
fn softmax_row_lanes(row: &mut [f32], scale: f32) -> f32 {
    let mut lane_max = [f32::NEG_INFINITY; LANES];
    let mut chunks = row.chunks_exact(LANES);
    for c in &mut chunks {
        for i in 0..LANES {
            lane_max[i] = if c[i] > lane_max[i] {
                c[i]
            } else {
                lane_max[i]
            };
        }
    }
    let mut max = f32::NEG_INFINITY;
    for &x in lane_max.iter().chain(chunks.remainder()) {
        max = if x > max { x } else { max };
    }
    // All scores -inf (masked): exp(-inf - 0) = 0 everywhere rather than NaN.
    let shift = if max == f32::NEG_INFINITY {
        0.0
    } else {
        max * scale
    };
    let mut lane_sum = [0f32; LANES];
    let mut chunks = row.chunks_exact_mut(LANES);
    for c in &mut chunks {
        for i in 0..LANES {
            let e = exp(c[i] * scale - shift);
            c[i] = e;
            lane_sum[i] += e;
        }
    }
    let mut sum = 0f32;
    for x in chunks.into_remainder() {
        let e = exp(*x * scale - shift);
        *x = e;
        sum += e;
    }
    sum + lane_sum.iter().sum::<f32>()
}

/// `e^x` for the softmax's arguments (`x <= 0` in exact arithmetic, a rounding above 0 at
/// most), to ~2 ulp: Cody-Waite reduction `x = n ln 2 + r`, `|r| <= ln 2 / 2`, then Cephes'
/// minimax polynomial for `e^r` and `2^n` put into the exponent bits. Branch-free, so it
/// vectorises. Arguments below [`EXP_MIN_ARG`] (including `-inf`) give exactly 0; NaN stays NaN.
#[inline(always)]
pub fn exp(x: f32) -> f32 {
    const LOG2E: f32 = std::f32::consts::LOG2_E;
    // ln 2 split so that n · LN2_HI is exact for the |n| <= 127 used here.
    const LN2_HI: f32 = 0.693_359_4;
    const LN2_LO: f32 = -2.121_944_4e-4;
    // Adding and subtracting 1.5 · 2^23 rounds to the nearest integer (|t| < 2^22).
    const ROUND: f32 = 12_582_912.0;
    // Clamped so that n stays in [-127, 127]; NaN passes through (`clamp` keeps NaN).
    let xc = x.clamp(-88.0, 88.0);
    let shifted = xc * LOG2E + ROUND;
    let n = shifted - ROUND;
    let r = xc - n * LN2_HI - n * LN2_LO;
    let r2 = r * r;
    let mut p = 1.987_569_2e-4_f32;
    p = p * r + 1.398_199_9e-3;
    p = p * r + 8.333_452e-3;
    p = p * r + 4.166_579_6e-2;
    p = p * r + 1.666_666_5e-1;
    p = p * r + 0.5; // Cephes' 5.0000001201e-1, which is 0.5 in f32
    let e_r = p * r2 + r + 1.0;
    // The integer n sits in the low mantissa bits of `shifted`; reading it there (instead of a
    // saturating float-to-int cast, which does not vectorise) keeps the loop in SIMD.
    let ni = shifted.to_bits() as i32 - ROUND.to_bits() as i32;
    // 2^n with n in [-126, 127]: the biased exponent n + 127 in [1, 254].
    let two_n = f32::from_bits(((ni.clamp(-126, 127) + 127) as u32) << 23);
    if x < EXP_MIN_ARG {
        0.0
    } else {
        e_r * two_n
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_util::{max_abs_diff, values};
    use super::*;
    use burn::tensor::Device;

    fn isas() -> Vec<Isa> {
        let mut v = vec![Isa::Portable];
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx2")
                && std::arch::is_x86_feature_detected!("fma")
            {
                v.push(Isa::Avx2Fma);
            }
            if std::arch::is_x86_feature_detected!("avx512f") {
                v.push(Isa::Avx512);
            }
        }
        v
    }

    /// Guards the polynomial exponential: relative error against f64 over the whole range
    /// the softmax feeds it, and the edges (underflow to exactly 0, -inf, NaN, 0).
    #[test]
    fn exp_is_accurate_over_the_softmax_range() {
        let mut worst = 0f64;
        let steps = 2_000_000;
        for i in 0..=steps {
            let x = -87.0f32 + 87.5 * i as f32 / steps as f32;
            let got = exp(x) as f64;
            let want = (x as f64).exp();
            worst = worst.max((got - want).abs() / want);
        }
        assert!(worst < 3.0e-7, "worst relative error {worst:e}");
        assert_eq!(exp(0.0), 1.0);
        assert_eq!(exp(f32::NEG_INFINITY), 0.0);
        assert_eq!(exp(-100.0), 0.0);
        assert!(exp(f32::NAN).is_nan());
    }

    fn reference(q: &[f32], k: &[f32], v: &[f32], [heads, n, m, d, dv]: [usize; 5]) -> Vec<f64> {
        let mut out = vec![0f64; heads * n * dv];
        let scale = 1.0 / (d as f64).sqrt();
        for h in 0..heads {
            for i in 0..n {
                let s: Vec<f64> = (0..m)
                    .map(|j| {
                        (0..d)
                            .map(|c| q[(h * n + i) * d + c] as f64 * k[(h * m + j) * d + c] as f64)
                            .sum::<f64>()
                            * scale
                    })
                    .collect();
                let max = s.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                let e: Vec<f64> = s.iter().map(|x| (x - max).exp()).collect();
                let z: f64 = e.iter().sum();
                for c in 0..dv {
                    out[(h * n + i) * dv + c] = (0..m)
                        .map(|j| e[j] * v[(h * m + j) * dv + c] as f64)
                        .sum::<f64>()
                        / z;
                }
            }
        }
        out
    }

    /// Guards the blocked kernel against an f64 softmax, on every instruction set this CPU
    /// has: ragged sizes (N not a multiple of the query block, M not of the lanes) and stiff
    /// logits (scores of ±100, so each row is nearly one-hot and a wrong max would overflow).
    #[test]
    fn matches_an_f64_softmax_on_ragged_and_stiff_inputs() {
        for (dims, amp) in [
            ([3, 37, 45, 16, 16], 1.0f32),
            ([2, 70, 129, 8, 12], 6.0),
            ([1, 5, 3, 4, 4], 20.0),
        ] {
            let [heads, n, m, d, dv] = dims;
            let q = values(heads * n * d, 1, amp);
            let k = values(heads * m * d, 2, amp);
            let v = values(heads * m * dv, 3, 1.0);
            let want = reference(&q, &k, &v, dims);
            for isa in isas() {
                let got = attention_host(&q, &k, &v, dims, isa);
                for (i, (g, w)) in got.iter().zip(&want).enumerate() {
                    assert!(
                        (*g as f64 - w).abs() < 2e-5,
                        "{isa:?} {dims:?} amp {amp}: element {i}: {g} vs {w}"
                    );
                }
            }
        }
    }

    /// Guards the tensor entry point against Burn's own attention op (what autodiff devices
    /// still use), including non-contiguous (permuted) inputs.
    #[test]
    fn agrees_with_burns_attention_op() {
        use burn::tensor::module::attention as burn_attention;
        use burn::tensor::ops::AttentionModuleOptions;
        let device = Device::flex();
        let t = |seed, shape: [usize; 4]| {
            Tensor::<4>::from_data(
                TensorData::new(values(shape.iter().product(), seed, 2.0), shape),
                &device,
            )
        };
        // [B, N, H, d] permuted to [B, H, N, d], as the attention module hands them over.
        let q = t(4, [2, 50, 3, 16]).swap_dims(1, 2);
        let k = t(5, [2, 50, 3, 16]).swap_dims(1, 2);
        let v = t(6, [2, 50, 3, 16]).swap_dims(1, 2);
        let ours = attention(q.clone(), k.clone(), v.clone());
        let theirs = burn_attention(q, k, v, None, None, AttentionModuleOptions::default());
        let diff = max_abs_diff(ours, theirs);
        assert!(diff < 1e-5, "max difference {diff}");
    }
}
