//! The default bodies of the sort and scan ops: host copies, the standard library's stable
//! sort, a running sum. They define what the device kernels must reproduce.

use crate::kernels::sort::sorted_bits;
use burn::backend::tensor::IntTensor;
use burn::backend::{Backend, TensorMetadata};
use burn::tensor::{read_sync, TensorData};

fn to_host<B: Backend>(t: IntTensor<B>) -> Vec<i64> {
    let data = read_sync(B::int_into_data(t))
        .unwrap_or_else(|e| panic!("splat: reading a tensor back from the device failed: {e:?}"));
    data.convert::<i64>()
        .try_into_vec::<i64>()
        .unwrap_or_else(|e| panic!("splat: tensor conversion failed: {e:?}"))
}

/// `v` as a tensor of `like`'s dtype and device. An i32 tensor holds 32-bit patterns, as the
/// device writes them: a value past `i32::MAX` (a u32 sum) is stored as its bits, read
/// negative, where the checked conversion would refuse it.
fn back<B: Backend>(mut v: Vec<i64>, like: &IntTensor<B>) -> IntTensor<B> {
    let len = v.len();
    if like.dtype() == burn::tensor::DType::I32 {
        for x in &mut v {
            *x = i64::from(bits32(*x) as i32);
        }
    }
    B::int_from_data(
        TensorData::new(v, [len]).convert_dtype(like.dtype()),
        &like.device(),
    )
}

/// The low 32 bits of `x`, as the device reads a 32-bit integer.
fn bits32(x: i64) -> u32 {
    x as u32
}

/// Whether the exclusive scan `offsets` wrapped past `u32::MAX`: some element (as the
/// device reads it, 32 bits) below the one before it.
pub fn scan_wrapped<B: Backend>(offsets: IntTensor<B>) -> bool {
    let v = to_host::<B>(offsets);
    v.windows(2).any(|w| bits32(w[1]) < bits32(w[0]))
}

pub fn sort_pairs<B: Backend>(
    keys: IntTensor<B>,
    values: IntTensor<B>,
    bits: u32,
) -> (IntTensor<B>, IntTensor<B>) {
    let sorted = sorted_bits(bits);
    let mask = if sorted >= 32 {
        u32::MAX
    } else {
        (1u32 << sorted) - 1
    };
    let (k, v) = (to_host::<B>(keys.clone()), to_host::<B>(values.clone()));
    let mut order: Vec<usize> = (0..k.len()).collect();
    order.sort_by_key(|&i| bits32(k[i]) & mask);
    (
        back::<B>(order.iter().map(|&i| k[i]).collect(), &keys),
        back::<B>(order.iter().map(|&i| v[i]).collect(), &values),
    )
}

pub fn exclusive_scan<B: Backend>(values: IntTensor<B>) -> IntTensor<B> {
    let v = to_host::<B>(values.clone());
    let mut out = Vec::with_capacity(v.len() + 1);
    let mut total = 0u32;
    out.push(0);
    for &x in &v {
        // The device sums in u32 and wraps; so does this.
        total = total.wrapping_add(bits32(x));
        out.push(i64::from(total));
    }
    back::<B>(out, &values)
}
