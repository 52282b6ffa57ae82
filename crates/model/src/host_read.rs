//! The deliberate device-to-host reads of a forward or a training step (finite checks, the
//! loss values a log shows) go through here, counted per thread, so a test can hold a step
//! to a fixed number of round trips whatever its batch size or number of views. The
//! rasterizer's own reads are counted by `envision4d_splat::kernels::readback`.

use burn::tensor::{Tensor, TensorData};
use std::cell::Cell;

thread_local! {
    static READS: Cell<usize> = const { Cell::new(0) };
}

/// Host reads this thread has made through [`read`] so far.
pub fn host_reads() -> usize {
    READS.with(Cell::get)
}

/// Reads `t` back to the host, counting the read.
pub fn read<const D: usize>(t: Tensor<D>) -> TensorData {
    READS.with(|c| c.set(c.get() + 1));
    t.into_data()
}

/// Reads several small tensors in one round trip (flattened and concatenated on the
/// device); returns their values as f64, in order.
pub fn read_all(parts: Vec<Tensor<1>>) -> Vec<f64> {
    if parts.is_empty() {
        return Vec::new();
    }
    read(Tensor::cat(parts, 0)).iter::<f64>().collect()
}
