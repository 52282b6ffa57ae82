//! Host side of the device tile binning ([`super::bin_tiles`]): launches, and one readback
//! of four bytes per view (the intersection count, which sizes the intersection buffers).

use super::bin_tiles::{depth_keys, emit_intersections, tile_counts, tile_ranges};
use super::readback::read_u32_at;
use super::sort::{empty_u32, exclusive_scan, sort_pairs};
use burn_cubecl::tensor::CubeTensor;
use cubecl::{calculate_cube_count_elemwise, CubeDim};

/// Key bits of the depth sort: the whole f32 pattern (and `CULLED`).
const DEPTH_BITS: u32 = 32;

/// The CSR tile lists of one view, on the device.
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

/// Bins the `n` projected Gaussians of one view (`records`, `meta` from `project_forward`)
/// into the `tiles_x x tiles_y` tiles; `None` when no Gaussian touches a tile.
pub fn bin_on_device(
    records: &CubeTensor,
    meta: &CubeTensor,
    n: usize,
    tiles_x: u32,
    tiles_y: u32,
) -> Option<DeviceBins> {
    if n == 0 {
        return None;
    }
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
        grid_n.clone(),
        per_gaussian,
        keys.clone().into_tensor_arg(),
        order.clone().into_tensor_arg(),
        meta.clone().into_tensor_arg(),
        counts.clone().into_tensor_arg(),
        n_u,
    );
    let offsets = exclusive_scan(&counts, n, n + 1);
    let m = read_u32_at(&offsets, n) as usize;
    if m == 0 {
        return None;
    }
    let (tile_ids, items) = (empty_u32(records, m), empty_u32(records, m));
    emit_intersections::launch(
        client,
        grid_n,
        per_gaussian,
        keys.into_tensor_arg(),
        order.into_tensor_arg(),
        meta.clone().into_tensor_arg(),
        offsets.into_tensor_arg(),
        tile_ids.clone().into_tensor_arg(),
        items.clone().into_tensor_arg(),
        n_u,
        tiles_x,
    );
    let num_tiles = tiles_x * tiles_y;
    let (tile_ids, items) = sort_pairs(&tile_ids, &items, m, tile_bits(num_tiles));
    let tile_start = empty_u32(records, num_tiles as usize + 1);
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
