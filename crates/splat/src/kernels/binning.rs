//! Host side of the device tile binning ([`super::bin_tiles`]), in two halves so that a
//! render call reads back once, whatever its number of views: [`order_view`] for every view
//! (depth order, tile counts, each view's intersection total into one small buffer), then
//! one readback of the totals (they size the intersection buffers), then [`bins_of_view`].

use super::bin_tiles::{copy_total, depth_keys, emit_intersections, tile_counts, tile_ranges};
use super::sort::{empty_u32, exclusive_scan, flag_wrapped, sort_pairs};
use burn_cubecl::tensor::CubeTensor;
use cubecl::{calculate_cube_count_elemwise, CubeCount, CubeDim};

/// Key bits of the depth sort: the whole f32 pattern (and `CULLED`).
const DEPTH_BITS: u32 = 32;

/// The CSR tile lists of one view, on the device.
#[derive(Clone, Debug)]
pub struct DeviceBins {
    /// `num_tiles + 1` offsets into `items`.
    pub tile_start: CubeTensor,
    /// Gaussian indices, per tile front to back.
    pub items: CubeTensor,
    /// Number of (tile, Gaussian) intersections: the length of `items`.
    pub intersections: usize,
}

/// Bits that hold every tile id below `num_tiles`.
pub fn tile_bits(num_tiles: u32) -> u32 {
    (u32::BITS - num_tiles.saturating_sub(1).leading_zeros()).max(1)
}

/// A view's Gaussians in depth order, with every one's first intersection slot: the first
/// half of the binning, run for every view before the one readback of all their totals.
pub struct DepthOrder {
    keys: CubeTensor,
    order: CubeTensor,
    /// `n + 1` exclusive offsets; the last is the view's intersection count.
    offsets: CubeTensor,
}

impl DepthOrder {
    /// The `n` depth keys in ascending order, culled ones (`CULLED`) last.
    pub fn sorted_keys(&self) -> &CubeTensor {
        &self.keys
    }
}

/// Depth keys, the stable depth sort, tile counts and their scan for one view's `n > 0`
/// projected Gaussians; the view's intersection count goes to `totals[view]` on the device.
/// `totals[wrap_slot]` becomes 1 if the count scan wrapped past `u32::MAX` (2^32 or more
/// intersections), so the same readback that sizes the intersections also refuses them. One
/// launch of n units, next to the sort's eight passes of three; run for every view, so every
/// render test runs it too.
pub fn order_view(
    records: &CubeTensor,
    meta: &CubeTensor,
    n: usize,
    totals: &CubeTensor,
    view: usize,
    wrap_slot: usize,
) -> DepthOrder {
    let client = &records.client;
    let n_u = n as u32;
    let per_gaussian = CubeDim::new(client, n);
    let grid_n = calculate_cube_count_elemwise(client, n, per_gaussian);
    let (keys, ids) = (empty_u32(records, n), empty_u32(records, n));
    depth_keys::launch(
        client,
        grid_n.clone(),
        per_gaussian,
        records.clone().into_tensor_arg(),
        meta.clone().into_tensor_arg(),
        keys.clone().into_tensor_arg(),
        ids.clone().into_tensor_arg(),
        n_u,
    );
    let (keys, order) = sort_pairs(&keys, &ids, n, DEPTH_BITS);
    let counts = empty_u32(records, n);
    tile_counts::launch(
        client,
        grid_n,
        per_gaussian,
        keys.clone().into_tensor_arg(),
        order.clone().into_tensor_arg(),
        meta.clone().into_tensor_arg(),
        counts.clone().into_tensor_arg(),
        n_u,
    );
    let offsets = exclusive_scan(&counts, n, n + 1);
    flag_wrapped(&offsets, n + 1, totals, wrap_slot);
    copy_total::launch(
        client,
        CubeCount::new_single(),
        CubeDim::new_1d(1),
        offsets.clone().into_tensor_arg(),
        totals.clone().into_tensor_arg(),
        n_u,
        view as u32,
    );
    DepthOrder {
        keys,
        order,
        offsets,
    }
}

/// The second half: the `m` (tile, Gaussian) intersections of a view in tile order and its
/// CSR tile lists over `tiles_x x tiles_y` tiles; `None` when `m` is 0.
pub fn bins_of_view(
    depth: &DepthOrder,
    meta: &CubeTensor,
    n: usize,
    m: usize,
    tiles_x: u32,
    tiles_y: u32,
) -> Option<DeviceBins> {
    if m == 0 {
        return None;
    }
    let client = &meta.client;
    let per_gaussian = CubeDim::new(client, n);
    let (tile_ids, items) = (empty_u32(meta, m), empty_u32(meta, m));
    emit_intersections::launch(
        client,
        calculate_cube_count_elemwise(client, n, per_gaussian),
        per_gaussian,
        depth.keys.clone().into_tensor_arg(),
        depth.order.clone().into_tensor_arg(),
        meta.clone().into_tensor_arg(),
        depth.offsets.clone().into_tensor_arg(),
        tile_ids.clone().into_tensor_arg(),
        items.clone().into_tensor_arg(),
        n as u32,
        tiles_x,
    );
    let num_tiles = tiles_x * tiles_y;
    let (tile_ids, items) = sort_pairs(&tile_ids, &items, m, tile_bits(num_tiles));
    let tile_start = empty_u32(meta, num_tiles as usize + 1);
    let per_slot = CubeDim::new(client, m + 1);
    tile_ranges::launch(
        client,
        calculate_cube_count_elemwise(client, m + 1, per_slot),
        per_slot,
        tile_ids.into_tensor_arg(),
        tile_start.clone().into_tensor_arg(),
        m as u32,
        num_tiles,
    );
    Some(DeviceBins {
        tile_start,
        items,
        intersections: m,
    })
}
