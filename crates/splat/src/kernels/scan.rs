//! Exclusive prefix sum of u32 on the device, work-efficient: each cube scans `SCAN_BLOCK`
//! elements (every unit sums `SCAN_ITEMS` serially, the cube scans those sums in shared
//! memory, [`scan_blocks`](fn@scan_blocks)) and writes its total; the totals are scanned the same way and added back
//! (`scan_add`), or, for a few blocks, summed where they are added (`scan_add_inline`).
//! O(n) work and O(log n) launches in all, where Burn's cumsum does O(n²).
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
/// Scans of at most this many blocks add the block totals in place
/// ([`scan_add_inline`](fn@scan_add_inline)) rather than scanning them first.
pub const INLINE_BLOCKS: u32 = 16;
/// `SCAN_THREADS` as the shared-memory length (a compile-time size).
const SHARED_LEN: usize = SCAN_THREADS as usize;
/// Units whose sums one unit scans serially.
const GROUP: u32 = 16;
/// Groups per cube.
const GROUPS: u32 = SCAN_THREADS / GROUP;

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
    // The cube's exclusive offsets in two serial levels (groups of `GROUP` units, then the
    // groups): three barriers, where a parallel scan needs two per doubling step; barriers
    // are what a CPU running the cube (lavapipe) pays for.
    let mut sums = Shared::<[u32]>::new_slice(SHARED_LEN);
    let mut groups = Shared::<[u32]>::new_slice(GROUPS as usize);
    sums[t as usize] = own;
    sync_cube();
    if t < GROUPS {
        let mut running = 0u32;
        for v in 0..GROUP {
            let at = (t * GROUP + v) as usize;
            let c = sums[at];
            sums[at] = running;
            running += c;
        }
        groups[t as usize] = running;
    }
    sync_cube();
    if t == 0 {
        let mut running = 0u32;
        for g in 0..GROUPS {
            let c = groups[g as usize];
            groups[g as usize] = running;
            running += c;
        }
        block_sums[block as usize] = running;
    }
    sync_cube();
    let mut running = sums[t as usize] + groups[(t / GROUP) as usize];
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
}

/// Adds each block's scanned offset to its elements.
#[cube(launch)]
pub fn scan_add(output: &mut Tensor<u32>, block_offsets: &Tensor<u32>, len_out: u32) {
    let i = ABSOLUTE_POS;
    if i < len_out as usize {
        output[i] += block_offsets[i / SCAN_BLOCK as usize];
    }
}

/// [`scan_add`](fn@scan_add) for a scan of at most [`INLINE_BLOCKS`] blocks, without scanning the block
/// totals first: each element sums the totals of the blocks before its own (at most
/// `INLINE_BLOCKS - 1` reads, the same for every unit of a cube). One launch instead of two;
/// the radix sort's digit tables of up to a million keys take this path in every pass.
#[cube(launch)]
pub fn scan_add_inline(output: &mut Tensor<u32>, block_sums: &Tensor<u32>, len_out: u32) {
    let i = ABSOLUTE_POS;
    if i < len_out as usize {
        let block = (i / SCAN_BLOCK as usize) as u32;
        let mut offset = 0u32;
        for b in 0..block {
            offset += block_sums[b as usize];
        }
        output[i] += offset;
    }
}

/// Sets `flags[slot]` to 1 when the exclusive scan `offsets[..len]` wrapped past `u32::MAX`.
/// Each step adds one u32, so the running sum crosses a multiple of 2^32 at most once per
/// step, and exactly where it does the output falls below the element before it; no fall,
/// no wrap. Units that find one all store the same 1, so the race is benign.
#[cube(launch)]
pub fn scan_wrapped(offsets: &Tensor<u32>, flags: &mut Tensor<u32>, len: u32, slot: u32) {
    let i = ABSOLUTE_POS;
    if i + 1 < len as usize && offsets[i + 1] < offsets[i] {
        flags[slot as usize] = 1u32;
    }
}
