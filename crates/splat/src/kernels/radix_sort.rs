//! One pass of the stable least-significant-digit radix sort of (u32 key, u32 value) pairs:
//! `RADIX_BITS` bits of the key per pass, three launches per pass (host side in
//! [`super::sort`]):
//! 1. `radix_count`: every cube counts the digits of its `SORT_BLOCK` keys;
//! 2. an exclusive scan of those counts laid out digit-major (`hist[d * blocks + b]`), which
//!    gives every (digit, block) its first output slot ([`super::scan`]);
//! 3. `radix_scatter`: every cube walks its keys in chunks of `SORT_THREADS`, in order, and
//!    writes each pair to its slot plus its rank among the earlier keys of the same digit.
//!
//! Both kernels rank a chunk with the same packed scan (`chunk_rank`): each unit puts a one
//! in its digit's 16-bit lane of `RADIX / 2` words and the cube scans the words together,
//! so one Hillis-Steele scan ranks all sixteen digits. Ranks follow the units' order, which
//! is the input order, so each pass and the whole sort are stable. Units past the end count
//! for no digit and write nothing; shared memory is met with `sync_cube`, so none leaves
//! early.

use cubecl::prelude::*;

/// Units per cube (one key each per chunk).
pub const SORT_THREADS: u32 = 256;
/// Chunks per cube: fewer cubes, so a smaller count table to scan per pass.
pub const SORT_CHUNKS: u32 = 4;
/// Keys one cube handles.
pub const SORT_BLOCK: u32 = SORT_THREADS * SORT_CHUNKS;
/// Key bits per pass.
pub const RADIX_BITS: u32 = 4;
/// Digits per pass.
pub const RADIX: u32 = 1 << RADIX_BITS;
/// Packed words of the rank scan: two 16-bit counters each (a chunk counts at most 256).
const RANK_WORDS: usize = (RADIX / 2) as usize;
/// The rank scan's shared words.
const RANK_SHARED: usize = RANK_WORDS * SORT_THREADS as usize;
const LANE_MASK: u32 = 0xFFFF;

/// One unit's place in its chunk.
#[derive(CubeType, Clone, Copy)]
#[expand(derive(Clone, Copy))]
pub struct ChunkRank {
    /// Earlier units of the chunk with the same digit.
    pub rank: u32,
    /// For units `0..RADIX`: how many units of the chunk hold digit `UNIT_POS_X`.
    pub digit_total: u32,
}

/// Ranks `digit` (ignored where `!valid`) among the chunk's units; every unit must call it.
#[cube]
pub fn chunk_rank(digit: u32, valid: bool) -> ChunkRank {
    let t = UNIT_POS_X;
    let threads = SORT_THREADS as usize;
    let mut words = Shared::<[u32]>::new_slice(RANK_SHARED);
    let word = digit / 2;
    let one = 1u32 << ((digit % 2) * 16);
    for w in 0..RANK_WORDS {
        let mut x = 0u32;
        if valid && word as usize == w {
            x = one;
        }
        words[w * threads + t as usize] = x;
    }
    sync_cube();
    let mut partner = Array::<u32>::new(RANK_WORDS);
    let mut offset = 1u32;
    while offset < SORT_THREADS {
        for w in 0..RANK_WORDS {
            partner[w] = 0u32;
            if t >= offset {
                partner[w] = words[w * threads + (t - offset) as usize];
            }
        }
        sync_cube();
        for w in 0..RANK_WORDS {
            words[w * threads + t as usize] += partner[w];
        }
        sync_cube();
        offset *= 2;
    }
    // Inclusive counts: this unit's own one is in its lane, hence the minus one.
    let mine = (words[word as usize * threads + t as usize] >> ((digit % 2) * 16)) & LANE_MASK;
    let mut rank = 0u32;
    if valid {
        rank = mine - 1;
    }
    let mut digit_total = 0u32;
    if t < RADIX {
        let last = words[(t / 2) as usize * threads + threads - 1];
        digit_total = (last >> ((t % 2) * 16)) & LANE_MASK;
    }
    // Nobody may overwrite the words before everyone has read them.
    sync_cube();
    ChunkRank { rank, digit_total }
}

/// The digit of `key` at `shift`.
#[cube]
fn digit_of(key: u32, shift: u32) -> u32 {
    (key >> shift) & (RADIX - 1)
}

/// `hist[d * blocks + b]` = keys of block `b` whose digit at `shift` is `d`.
#[cube(launch)]
pub fn radix_count(keys: &Tensor<u32>, hist: &mut Tensor<u32>, n: u32, shift: u32, blocks: u32) {
    let block = CUBE_POS as u32;
    if block >= blocks {
        terminate!();
    }
    let t = UNIT_POS_X;
    let mut count = 0u32;
    for c in 0..SORT_CHUNKS {
        let i = block * SORT_BLOCK + c * SORT_THREADS + t;
        let valid = i < n;
        let mut digit = 0u32;
        if valid {
            digit = digit_of(keys[i as usize], shift);
        }
        let r = chunk_rank(digit, valid);
        count += r.digit_total;
    }
    if t < RADIX {
        hist[(t * blocks + block) as usize] = count;
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
    let t = UNIT_POS_X;
    // Where the block's next key of digit `t` goes (units 0..RADIX keep one each).
    let mut next = 0u32;
    if t < RADIX {
        next = offsets[(t * blocks + block) as usize];
    }
    let mut bases = Shared::<[u32]>::new_slice(RADIX as usize);
    for c in 0..SORT_CHUNKS {
        let i = block * SORT_BLOCK + c * SORT_THREADS + t;
        let valid = i < n;
        let mut key = 0u32;
        let mut digit = 0u32;
        if valid {
            key = keys[i as usize];
            digit = digit_of(key, shift);
        }
        if t < RADIX {
            bases[t as usize] = next;
        }
        let r = chunk_rank(digit, valid);
        if valid {
            let dst = (bases[digit as usize] + r.rank) as usize;
            keys_out[dst] = key;
            values_out[dst] = values[i as usize];
        }
        // Everyone has read `bases` before the next chunk overwrites it.
        sync_cube();
        next += r.digit_total;
    }
}
