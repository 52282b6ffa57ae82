//! Conditioned motion lifting (paper §3.3): the temporal tokens of each context frame i are
//! modulated by the refined time token of every other timestamp j, giving one token map per
//! (source, target) pair for the motion head.

use burn::tensor::Tensor;

/// The timestamps a source frame moves to: `0..n` without `i`, in order (`idx(i, ·)`).
pub fn targets_of(i: usize, n: usize) -> Vec<usize> {
    (0..n).filter(|&j| j != i).collect()
}

/// Position of target `j` in `targets_of(i, ·)` (the decoder's `t_idx`).
pub fn target_slot(i: usize, j: usize) -> usize {
    assert_ne!(i, j, "a frame has no motion to itself");
    if j < i {
        j
    } else {
        j - 1
    }
}

/// `tap: [B, T_c, P, 2C]` (a `time_list` entry; patch tokens from `patch_start`),
/// `time: [B, N, 2C]` (refined time tokens) → `[B, T_c·(N-1), hw, 2C]`, source-major:
/// `out[:, i·K + k] = tap[:, i, patches] ⊙ time[:, targets_of(i)[k]]`.
pub fn lift(tap: Tensor<4>, time: Tensor<3>, patch_start: usize) -> Tensor<4> {
    let [b, tc, p, c] = tap.dims();
    let n = time.dims()[1];
    let k = n - 1;
    let hw = p - patch_start;
    let patches = tap.slice([0..b, 0..tc, patch_start..p, 0..c]);
    let mut selected = Vec::with_capacity(tc * k);
    for i in 0..tc {
        for j in targets_of(i, n) {
            selected.push(time.clone().slice([0..b, j..j + 1, 0..c]));
        }
    }
    let e = Tensor::cat(selected, 1).reshape([b, tc * k, 1, c]);
    let x = patches
        .unsqueeze_dim::<5>(2)
        .expand([b, tc, k, hw, c])
        .reshape([b, tc * k, hw, c]);
    x * e
}
