//! Every device-to-host read of the CubeCL rasterizer goes through here, so they can be
//! counted: a test holds a render call to its cameras (two tiny tensors, read together once
//! by validation and handed to the kernels) and one read of its views' intersection totals in
//! the forward (and one more in a backward that bins again, `BackwardBins::Recompute`).

use burn::backend::ops::{FloatTensorOps, IntTensorOps};
use burn::tensor::read_sync;
use burn_cubecl::tensor::CubeTensor;
use burn_cubecl::CubeBackend;

thread_local! {
    /// Device-to-host reads made by this thread's renders (see [`host_readbacks`]).
    static READBACKS: std::cell::Cell<usize> = const { std::cell::Cell::new(0) };
}

/// How many times this thread's renders have read the device back so far. A render call
/// reads its cameras once (two tiny tensors in one read, while validating) and, per pass
/// that bins (the forward; the backward too under `BackwardBins::Recompute`), its views'
/// intersection totals and wrap flags (8 bytes per view, one read); nothing else comes back
/// but the plane probe's one read (see the module's note).
/// Tests count with it; it is per thread so parallel tests do not disturb each other.
pub fn host_readbacks() -> usize {
    READBACKS.with(|c| c.get())
}

/// Counts the reads of a render call's camera tensors, which validation makes: one (both
/// flattened into one vector), or two when their float types differ. On the host path it is
/// a copy; counted all the same, so the count does not depend on the backend.
pub fn count_camera_reads(reads: usize) {
    READBACKS.with(|c| c.set(c.get() + reads));
}

/// Counts one device-to-host read of this thread.
fn count_readback() {
    READBACKS.with(|c| c.set(c.get() + 1));
}

/// Reads a whole u32 buffer (the intersection totals of a render call's views).
pub fn read_u32s(t: CubeTensor) -> Vec<u32> {
    count_readback();
    let data = read_sync(CubeBackend::int_into_data(t))
        .unwrap_or_else(|e| panic!("splat: device readback failed: {e:?}"));
    data.convert::<i64>()
        .try_into_vec::<i64>()
        .unwrap_or_else(|e| panic!("splat: tensor conversion failed: {e:?}"))
        .into_iter()
        .map(|x| x as u32)
        .collect()
}

/// Reads a whole f32 buffer, or `None` where the work that wrote it failed (a launch the
/// device rejected): the plane probe's answer.
pub(crate) fn try_read_f32s(t: CubeTensor) -> Option<Vec<f32>> {
    count_readback();
    read_sync(CubeBackend::float_into_data(t))
        .ok()?
        .convert::<f32>()
        .try_to_vec::<f32>()
        .ok()
}
