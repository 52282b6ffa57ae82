//! Host side of the device scan and radix sort: launches only, nothing read back.
//!
//! Both work on flat contiguous u32 buffers (`CubeTensor`s of dtype `U32`, or `I32`
//! reinterpreted bit for bit: same size, same bits).

use super::radix_sort::{radix_count, radix_scatter, RADIX, RADIX_BITS, SORT_BLOCK, SORT_THREADS};
use super::scan::{
    scan_add, scan_add_inline, scan_blocks, scan_wrapped, INLINE_BLOCKS, SCAN_BLOCK, SCAN_THREADS,
};
use burn::backend::TensorMetadata;
use burn::tensor::{DType, Shape};
use burn_cubecl::ops::numeric::empty_device_dtype;
use burn_cubecl::tensor::CubeTensor;
use cubecl::{calculate_cube_count_elemwise, CubeCount, CubeDim};

/// The most cubes one grid axis takes (WebGPU's and CUDA's common limit).
const MAX_GRID_AXIS: u32 = 65_535;

/// A grid of at least `cubes` cubes, two-dimensional past one axis' limit (kernels index
/// with `CUBE_POS` and skip cubes past the end).
pub fn grid(cubes: u32) -> CubeCount {
    if cubes <= MAX_GRID_AXIS {
        CubeCount::Static(cubes, 1, 1)
    } else {
        CubeCount::Static(MAX_GRID_AXIS, cubes.div_ceil(MAX_GRID_AXIS), 1)
    }
}

/// A new uninitialised u32 buffer of `len` elements on `like`'s device.
pub fn empty_u32(like: &CubeTensor, len: usize) -> CubeTensor {
    empty_u32_for(like, "sort/scan", len)
}

/// [`empty_u32`] for a buffer that the size check's message calls `what`.
pub fn empty_u32_for(like: &CubeTensor, what: &str, len: usize) -> CubeTensor {
    super::buffers::check_binding(like, what, len);
    empty_device_dtype(
        like.client.clone(),
        like.device.clone(),
        Shape::new([len]),
        DType::U32,
    )
}

/// A contiguous 32-bit integer buffer seen as `dtype` (`I32` or `U32`: the same handle, the
/// same bits).
pub fn retype(t: CubeTensor, dtype: DType) -> CubeTensor {
    match (t.dtype(), dtype) {
        (from, to) if from == to => t,
        (DType::I32 | DType::U32, DType::I32 | DType::U32) => CubeTensor::new_contiguous(
            t.client.clone(),
            t.device.clone(),
            t.shape(),
            t.handle,
            dtype,
        ),
        (from, to) => {
            panic!("splat: the device sort and scan take 32-bit integers, not {from:?} as {to:?}")
        }
    }
}

fn u32_len(n: usize, what: &str) -> u32 {
    u32::try_from(n).unwrap_or_else(|_| panic!("splat: {what} of {n} elements exceeds u32"))
}

/// Exclusive prefix sum of `input[..len_in]` (zeros past it) into a new buffer of
/// `len_out` elements; with `len_out = len_in + 1` the last element is the total.
pub fn exclusive_scan(input: &CubeTensor, len_in: usize, len_out: usize) -> CubeTensor {
    let output = empty_u32(input, len_out);
    if len_out == 0 {
        return output;
    }
    let (len_in, len_out_u) = (u32_len(len_in, "scan"), u32_len(len_out, "scan"));
    let blocks = len_out_u.div_ceil(SCAN_BLOCK);
    let sums = empty_u32(input, blocks as usize);
    let client = &input.client;
    scan_blocks::launch(
        client,
        grid(blocks),
        CubeDim::new_1d(SCAN_THREADS),
        input.clone().into_tensor_arg(),
        output.clone().into_tensor_arg(),
        sums.clone().into_tensor_arg(),
        len_in,
        len_out_u,
        blocks,
    );
    if blocks > 1 {
        let dim = CubeDim::new(client, len_out);
        let count = calculate_cube_count_elemwise(client, len_out, dim);
        if blocks <= INLINE_BLOCKS {
            scan_add_inline::launch(
                client,
                count,
                dim,
                output.clone().into_tensor_arg(),
                sums.into_tensor_arg(),
                len_out_u,
            );
        } else {
            let offsets = exclusive_scan(&sums, blocks as usize, blocks as usize);
            scan_add::launch(
                client,
                count,
                dim,
                output.clone().into_tensor_arg(),
                offsets.into_tensor_arg(),
                len_out_u,
            );
        }
    }
    output
}

/// Sets `flags[slot]` to 1 when the exclusive scan `offsets[..len]` wrapped past `u32::MAX`
/// ([`scan_wrapped`](fn@super::scan::scan_wrapped)); leaves it as it was otherwise. Needs `len >= 2`.
pub fn flag_wrapped(offsets: &CubeTensor, len: usize, flags: &CubeTensor, slot: usize) {
    let client = &offsets.client;
    let dim = CubeDim::new(client, len);
    scan_wrapped::launch(
        client,
        calculate_cube_count_elemwise(client, len, dim),
        dim,
        offsets.clone().into_tensor_arg(),
        flags.clone().into_tensor_arg(),
        u32_len(len, "scan"),
        u32_len(slot, "scan flag slot"),
    );
}

/// Key bits a sort of keys below `2^bits` visits: whole passes of `RADIX_BITS`, at least one
/// (so every sort writes new buffers).
pub fn sorted_bits(bits: u32) -> u32 {
    bits.clamp(1, 32).div_ceil(RADIX_BITS) * RADIX_BITS
}

/// Stable sort of the first `n` (key, value) pairs by the key's low [`sorted_bits`]`(bits)`
/// bits; returns new buffers of `n` elements each (the inputs are not changed).
pub fn sort_pairs(
    keys: &CubeTensor,
    values: &CubeTensor,
    n: usize,
    bits: u32,
) -> (CubeTensor, CubeTensor) {
    let mut k = empty_u32(keys, n);
    let mut v = empty_u32(keys, n);
    if n == 0 {
        return (k, v);
    }
    let n_u = u32_len(n, "sort");
    let blocks = n_u.div_ceil(SORT_BLOCK);
    let hist_len = (RADIX * blocks) as usize;
    let client = &keys.client;
    let (mut src_k, mut src_v) = (keys.clone(), values.clone());
    let passes = sorted_bits(bits) / RADIX_BITS;
    for pass in 0..passes {
        let shift = pass * RADIX_BITS;
        let hist = empty_u32(keys, hist_len);
        radix_count::launch(
            client,
            grid(blocks),
            CubeDim::new_1d(SORT_THREADS),
            src_k.clone().into_tensor_arg(),
            hist.clone().into_tensor_arg(),
            n_u,
            shift,
            blocks,
        );
        let offsets = exclusive_scan(&hist, hist_len, hist_len);
        radix_scatter::launch(
            client,
            grid(blocks),
            CubeDim::new_1d(SORT_THREADS),
            src_k.clone().into_tensor_arg(),
            src_v.clone().into_tensor_arg(),
            offsets.into_tensor_arg(),
            k.clone().into_tensor_arg(),
            v.clone().into_tensor_arg(),
            n_u,
            shift,
            blocks,
        );
        // Ping-pong: this pass' output is the next one's input. The first pass reads the
        // caller's buffers, which are never written.
        if pass + 1 < passes {
            let (next_k, next_v) = if pass == 0 {
                (empty_u32(keys, n), empty_u32(keys, n))
            } else {
                (src_k, src_v)
            };
            src_k = std::mem::replace(&mut k, next_k);
            src_v = std::mem::replace(&mut v, next_v);
        }
    }
    (k, v)
}
