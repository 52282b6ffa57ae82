//! Reading a strided view in place: where a row-major index of a tensor's shape sits in the
//! tensor's own strides. The model's attention backward (its swapped gradients) and the
//! optimiser (gradients of weights used transposed) read such views without copying them
//! first.

use cubecl::prelude::*;

/// The offset in `t`'s strides of `index`, a row-major index over `t`'s first `axes` axes
/// (the later axes held at 0): `axes = rank` finds an element, `axes = rank - 1` the start
/// of a row along the last axis. The last of the walked axes varies fastest.
#[cube]
pub fn offset_over_axes(t: &Tensor<f32>, index: u32, axes: usize) -> u32 {
    let mut rest = index;
    let mut at = 0u32;
    let mut axis = axes;
    while axis > 0 {
        axis -= 1;
        let len = t.shape(axis) as u32;
        at += (rest % len) * t.stride(axis) as u32;
        rest /= len;
    }
    at
}
