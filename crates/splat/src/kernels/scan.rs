//! Exclusive prefix sum of u32 on the device, work-efficient: each cube scans `SCAN_BLOCK`
//! elements (every unit sums `SCAN_ITEMS` serially, the cube scans those sums in shared
//! memory) and writes its total; the totals are scanned the same way and added back
//! (`scan_add`). O(n) work and O(log n) launches in all, where Burn's cumsum does O(n²).
//!
//! Shared memory is met with `sync_cube`, so no unit may leave early: units past the end
//! read zeros and write nothing, and a cube past the last block (the 2-D grid of a large
//! dispatch rounds up) leaves as a whole.

use cubecl::prelude::*;

/// Units per cube.
pub const SCAN_THREADS: u32 = 256;
/// Elements each unit sums serially before the cube-wide scan.
pub const SCAN_ITEMS: u32 = 4;
/// Elements one cube scans.
pub const SCAN_BLOCK: u32 = SCAN_THREADS * SCAN_ITEMS;
/// `SCAN_THREADS` as the shared-memory length (a compile-time size).
const SHARED_LEN: usize = SCAN_THREADS as usize;

/// Scans block `CUBE_POS` of `input[..len_in]` (zero past it) into `output[..len_out]`, each
/// block from 0, and writes the block's total to `block_sums`.
#[cube(launch)]
pub fn scan_blocks(
    input: &Tensor<u32>,
    output: &mut Tensor<u32>,
    block_sums: &mut Tensor<u32>,
    len_in: u32,
    len_out: u32,
    blocks: u32,
) {
    let block = CUBE_POS as u32;
    if block >= blocks {
        terminate!();
    }
    let t = UNIT_POS_X;
    let first = block * SCAN_BLOCK + t * SCAN_ITEMS;
    let mut own = 0u32;
    for k in 0..SCAN_ITEMS {
        let i = first + k;
        if i < len_in {
            own += input[i as usize];
        }
    }
    // Hillis-Steele over the cube: read the partner, meet, write, meet.
    let mut sums = Shared::<[u32]>::new_slice(SHARED_LEN);
    sums[t as usize] = own;
    sync_cube();
    let mut offset = 1u32;
    while offset < SCAN_THREADS {
        let mut add = 0u32;
        if t >= offset {
            add = sums[(t - offset) as usize];
        }
        sync_cube();
        sums[t as usize] += add;
        sync_cube();
        offset *= 2;
    }
    let inclusive = sums[t as usize];
    let mut running = inclusive - own;
    for k in 0..SCAN_ITEMS {
        let i = first + k;
        let mut x = 0u32;
        if i < len_in {
            x = input[i as usize];
        }
        if i < len_out {
            output[i as usize] = running;
        }
        running += x;
    }
    if t == SCAN_THREADS - 1 {
        block_sums[block as usize] = inclusive;
    }
}

/// Adds each block's scanned offset to its elements.
#[cube(launch)]
pub fn scan_add(output: &mut Tensor<u32>, block_offsets: &Tensor<u32>, len_out: u32) {
    let i = ABSOLUTE_POS;
    if i < len_out as usize {
        output[i] += block_offsets[i / SCAN_BLOCK as usize];
    }
}
