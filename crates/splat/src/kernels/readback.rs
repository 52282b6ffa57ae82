//! Every device-to-host read of the CubeCL rasterizer goes through here, so they can be
//! counted: a test holds the pipeline to the cameras once per call and one intersection count
//! per view.

use burn::backend::ops::{FloatTensorOps, IntTensorOps};
use burn::tensor::{read_sync, Slice};
use burn_cubecl::tensor::CubeTensor;
use burn_cubecl::CubeBackend;

thread_local! {
    /// Device-to-host reads made by this thread's renders (see [`host_readbacks`]).
    static READBACKS: std::cell::Cell<usize> = const { std::cell::Cell::new(0) };
}

/// How many times this thread's CubeCL renders have read the device back so far. A render
/// call reads its cameras (two tiny tensors) once, and each view its intersection count
/// (4 bytes) once per pass; nothing else comes back. Tests count with it; it is per thread
/// so parallel tests do not disturb each other.
pub fn host_readbacks() -> usize {
    READBACKS.with(|c| c.get())
}

/// Counts one device-to-host read of this thread.
fn count_readback() {
    READBACKS.with(|c| c.set(c.get() + 1));
}

/// Reads a whole f32 buffer (the cameras of a render call).
pub fn read_f32(t: CubeTensor) -> Vec<f32> {
    count_readback();
    let data = read_sync(CubeBackend::float_into_data(t))
        .unwrap_or_else(|e| panic!("splat: device readback failed: {e:?}"));
    data.convert::<f32>()
        .try_into_vec::<f32>()
        .unwrap_or_else(|e| panic!("splat: tensor conversion failed: {e:?}"))
}

/// Reads element `i` of a u32 buffer (the one readback of the binning).
pub fn read_u32_at(t: &CubeTensor, i: usize) -> u32 {
    count_readback();
    let one = CubeBackend::int_slice(t.clone(), &[Slice::from(i..i + 1)]);
    let data = read_sync(CubeBackend::int_into_data(one))
        .unwrap_or_else(|e| panic!("splat: device readback failed: {e:?}"));
    data.convert::<i64>()
        .try_into_vec::<i64>()
        .unwrap_or_else(|e| panic!("splat: tensor conversion failed: {e:?}"))[0] as u32
}
