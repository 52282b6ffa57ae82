//! The host side shared by the kernels that sum a per-channel gradient over rows in chunks
//! of rows (the LayerScale residual's γ, `residual/`; the MLP's bias, `gelu/`): the shapes
//! they can take, and the last reduction of their partial sums.

use burn::backend::ops::FloatTensorOps;
use burn::tensor::Shape;
use burn_cubecl::tensor::CubeTensor;
use burn_cubecl::CubeBackend;

/// `(rows, cols)` of a `[.., cols]` shape when such a kernel can take it: not empty, and
/// flat indices and the backward's unit count (`chunks · cols`, chunks of `rows_per_unit`
/// rows: a little over the element count) within u32.
pub(crate) fn chunked_rows(shape: &Shape, rows_per_unit: u32) -> Option<(usize, usize)> {
    let cols = *shape.to_vec().last()?;
    let n = shape.num_elements();
    let units = cols.checked_mul(n.checked_div(cols)?.div_ceil(rows_per_unit as usize))?;
    let indexable = u32::try_from(n.max(units)).is_ok();
    (n > 0 && indexable).then_some((n / cols, cols))
}

/// The per-channel sums `[cols]` from the chunks' partial sums `[chunks · cols]`: the
/// partials themselves for one chunk, else one reduction on the device.
pub(crate) fn sum_chunks(part: CubeTensor, chunks: usize, cols: usize) -> CubeTensor {
    if chunks == 1 {
        return part;
    }
    let part = CubeBackend::float_reshape(part, Shape::new([chunks, cols]));
    CubeBackend::float_reshape(CubeBackend::float_sum_dim(part, 0), Shape::new([cols]))
}
