//! One pass of the stable least-significant-digit radix sort of (u32 key, u32 value) pairs:
//! `RADIX_BITS` bits of the key per pass, three launches per pass (host side in
//! [`super::sort`]):
//! 1. `radix_count`: every cube counts the digits of its `SORT_BLOCK` keys;
//! 2. an exclusive scan of those counts laid out digit-major (`hist[d * blocks + b]`), which
//!    gives every (digit, block) its first output slot ([`super::scan`]);
//! 3. `radix_scatter`: every cube sends each pair to its digit's slot plus the number of
//!    keys of that digit before it in the block.
//!
//! Each unit owns `SORT_ITEMS` consecutive keys and counts their digits privately; the
//! cube shares the per-unit counts (digit-major), and in the scatter units `0..RADIX` turn
//! their digit's row into running offsets, serially. Units then place their own keys in
//! order. Input order is (unit, item) order, so each pass and the whole sort are stable.
//! Two barriers per cube and pass, where a cube-wide parallel scan would need sixteen: a
//! barrier is cheap on a GPU but costly where a CPU runs the cube (lavapipe), and the
//! serial rows are 128 shared reads. Shared memory is met with `sync_cube`, so no unit
//! leaves early; units past the end count nothing and write nothing.

use cubecl::prelude::*;

/// Units per cube.
pub const SORT_THREADS: u32 = 128;
/// Consecutive keys per unit.
pub const SORT_ITEMS: u32 = 8;
/// Keys one cube handles.
pub const SORT_BLOCK: u32 = SORT_THREADS * SORT_ITEMS;
/// Key bits per pass.
pub const RADIX_BITS: u32 = 4;
/// Digits per pass.
pub const RADIX: u32 = 1 << RADIX_BITS;
/// Per-unit digit counts of a cube, digit-major (8 KiB).
const COUNTS_SHARED: usize = (RADIX * SORT_THREADS) as usize;

/// The digit of `key` at `shift`.
#[cube]
fn digit_of(key: u32, shift: u32) -> u32 {
    (key >> shift) & (RADIX - 1)
}

/// Counts the digits of this unit's keys into `counts[d * SORT_THREADS + unit]`.
#[cube]
fn count_own(keys: &Tensor<u32>, counts: &mut [u32], first: u32, n: u32, shift: u32) {
    let unit = UNIT_POS_X;
    let mut own = Array::<u32>::new(RADIX as usize);
    for d in 0..RADIX {
        own[d as usize] = 0u32;
    }
    for k in 0..SORT_ITEMS {
        let i = first + k;
        if i < n {
            let d = digit_of(keys[i as usize], shift);
            own[d as usize] += 1u32;
        }
    }
    for d in 0..RADIX {
        counts[(d * SORT_THREADS + unit) as usize] = own[d as usize];
    }
}

/// `hist[d * blocks + b]` = keys of block `b` whose digit at `shift` is `d`.
#[cube(launch)]
pub fn radix_count(keys: &Tensor<u32>, hist: &mut Tensor<u32>, n: u32, shift: u32, blocks: u32) {
    let block = CUBE_POS as u32;
    if block >= blocks {
        terminate!();
    }
    let unit = UNIT_POS_X;
    let mut counts = Shared::<[u32]>::new_slice(COUNTS_SHARED);
    count_own(
        keys,
        &mut counts,
        block * SORT_BLOCK + unit * SORT_ITEMS,
        n,
        shift,
    );
    sync_cube();
    if unit < RADIX {
        let mut total = 0u32;
        for v in 0..SORT_THREADS {
            total += counts[(unit * SORT_THREADS + v) as usize];
        }
        hist[(unit * blocks + block) as usize] = total;
    }
}

/// Moves every pair to `offsets[digit * blocks + block]` plus its rank in the block.
#[cube(launch)]
#[allow(clippy::too_many_arguments)]
pub fn radix_scatter(
    keys: &Tensor<u32>,
    values: &Tensor<u32>,
    offsets: &Tensor<u32>,
    keys_out: &mut Tensor<u32>,
    values_out: &mut Tensor<u32>,
    n: u32,
    shift: u32,
    blocks: u32,
) {
    let block = CUBE_POS as u32;
    if block >= blocks {
        terminate!();
    }
    let unit = UNIT_POS_X;
    let first = block * SORT_BLOCK + unit * SORT_ITEMS;
    let mut counts = Shared::<[u32]>::new_slice(COUNTS_SHARED);
    count_own(keys, &mut counts, first, n, shift);
    sync_cube();
    // Row `d` becomes the first slot of each unit's keys of digit `d`.
    if unit < RADIX {
        let mut running = offsets[(unit * blocks + block) as usize];
        for v in 0..SORT_THREADS {
            let at = (unit * SORT_THREADS + v) as usize;
            let c = counts[at];
            counts[at] = running;
            running += c;
        }
    }
    sync_cube();
    let mut next = Array::<u32>::new(RADIX as usize);
    for d in 0..RADIX {
        next[d as usize] = counts[(d * SORT_THREADS + unit) as usize];
    }
    for k in 0..SORT_ITEMS {
        let i = first + k;
        if i < n {
            let key = keys[i as usize];
            let d = digit_of(key, shift) as usize;
            let dst = next[d] as usize;
            next[d] += 1u32;
            keys_out[dst] = key;
            values_out[dst] = values[i as usize];
        }
    }
}
