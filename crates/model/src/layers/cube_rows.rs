//! Row reductions inside one CubeCL cube, shared by the row-wise kernels (the fused
//! LayerNorm, the lean attention's softmax): one cube handles one row, every unit folds a
//! strided share of it, and unit 0 combines the `ROW_THREADS` shares *in unit order*, so a
//! result never depends on scheduling (the same inputs give the same bits every run).
//!
//! Each reduction meets shared memory with `sync_cube`, so no unit may leave a cube early:
//! a cube past the last row leaves as a whole, and units past a row's end fold the
//! operation's identity.

use cubecl::prelude::*;

/// Units per cube (one row each): a head's 64 channels take one value per unit, the
/// aggregator's 1024 sixteen, a global attention row of 1,850 tokens twenty-nine.
pub const ROW_THREADS: u32 = 64;
/// `ROW_THREADS` as the shared-memory length (a compile-time size).
pub const SHARED_LEN: usize = ROW_THREADS as usize;

/// The sum over the cube of every unit's `own`, in unit order; `partial` and `total` are the
/// cube's shared scratch (`ROW_THREADS` and 1 values). Two barriers: a later call's write of
/// `total` comes after its own first barrier, which every unit reaches only after reading
/// this call's total.
#[cube]
pub fn cube_sum(own: f32, partial: &mut [f32], total: &mut [f32]) -> f32 {
    let t = UNIT_POS_X;
    partial[t as usize] = own;
    sync_cube();
    if t == 0 {
        let mut acc = 0.0f32;
        for i in 0..ROW_THREADS {
            acc += partial[i as usize];
        }
        total[0] = acc;
    }
    sync_cube();
    total[0]
}

/// The maximum over the cube of every unit's `own` ([`cube_sum`]'s scheme and barriers).
#[cube]
pub fn cube_max(own: f32, partial: &mut [f32], total: &mut [f32]) -> f32 {
    let t = UNIT_POS_X;
    partial[t as usize] = own;
    sync_cube();
    if t == 0 {
        let mut acc = partial[0];
        for i in 1..ROW_THREADS {
            acc = f32::max(acc, partial[i as usize]);
        }
        total[0] = acc;
    }
    sync_cube();
    total[0]
}
