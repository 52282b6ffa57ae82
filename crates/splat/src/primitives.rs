//! The device sort and scan as tensor functions: what the rasterizer's binning is built on,
//! usable (and tested) on their own. Burn 0.22 has neither on the device: its argsort reads
//! back to the host and its cumsum does O(n²) work.

use crate::backend::SplatOps;
use burn::backend::Dispatch;
use burn::tensor::{DType, Int, Tensor};

/// Why a sort or scan was refused.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum PrimitiveError {
    #[error("sort_pairs: {keys} keys but {values} values (they must pair one to one)")]
    LengthMismatch { keys: usize, values: usize },
    #[error("sort_pairs: {0} key bits; keys are 32-bit, so 1 to 32")]
    Bits(u32),
    #[error("{what}: needs 32-bit integers on this path, got {dtype:?}")]
    DType { what: &'static str, dtype: DType },
}

fn check_dtype(what: &'static str, t: &Tensor<1, Int>) -> Result<(), PrimitiveError> {
    match t.dtype() {
        DType::I32 | DType::U32 | DType::I64 => Ok(()),
        dtype => Err(PrimitiveError::DType { what, dtype }),
    }
}

/// Stable sort of `(keys, values)` by the keys' low `bits` bits (rounded up to whole radix
/// passes, [`crate::kernels::sort::sorted_bits`]), keys read as 32-bit patterns: equal keys
/// keep their input order. A device radix sort on CubeCL backends, the host's stable sort
/// elsewhere; the results are identical.
pub fn sort_pairs(
    keys: Tensor<1, Int>,
    values: Tensor<1, Int>,
    bits: u32,
) -> Result<(Tensor<1, Int>, Tensor<1, Int>), PrimitiveError> {
    let (nk, nv) = (keys.dims()[0], values.dims()[0]);
    if nk != nv {
        return Err(PrimitiveError::LengthMismatch {
            keys: nk,
            values: nv,
        });
    }
    if !(1..=32).contains(&bits) {
        return Err(PrimitiveError::Bits(bits));
    }
    check_dtype("sort_pairs", &keys)?;
    check_dtype("sort_pairs", &values)?;
    let (k, v) = <Dispatch as SplatOps>::splat_sort_pairs(
        keys.into_dispatch(),
        values.into_dispatch(),
        bits,
    );
    Ok((Tensor::from_dispatch(k), Tensor::from_dispatch(v)))
}

/// Whether an exclusive scan's output wrapped past `u32::MAX` (its true total, or a running
/// sum before it, reached 2^32): some element is below the one before it. One small readback
/// on CubeCL backends; the rasterizer runs the same kernel on every view's intersection
/// offsets, its flag riding on the one read of the views' totals.
pub fn scan_wrapped(offsets: Tensor<1, Int>) -> Result<bool, PrimitiveError> {
    check_dtype("scan_wrapped", &offsets)?;
    Ok(<Dispatch as SplatOps>::splat_scan_wrapped(
        offsets.into_dispatch(),
    ))
}

/// Exclusive prefix sum with the total appended: `[a, b, c]` → `[0, a, a+b, a+b+c]`, summed
/// as u32 (wrapping; [`scan_wrapped`] tells). An i32 result holds the sums' 32-bit patterns,
/// so a sum past `i32::MAX` reads negative. A device scan on CubeCL backends.
pub fn exclusive_scan(values: Tensor<1, Int>) -> Result<Tensor<1, Int>, PrimitiveError> {
    check_dtype("exclusive_scan", &values)?;
    Ok(Tensor::from_dispatch(
        <Dispatch as SplatOps>::splat_exclusive_scan(values.into_dispatch()),
    ))
}
