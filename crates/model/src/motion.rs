//! Conditioned motion lifting (paper §3.3): the temporal tokens of each context frame i are
//! modulated by the refined time token of every other timestamp j, giving one token map per
//! (source, target) pair for the motion head.
//!
//! Also the ablation baseline without lifting ([`MotionModel::LinearVelocity`]). Our reading
//! of the paper (§4.3: "linear bidirectional velocity estimation"; §3.3: "unlike bidirectional
//! motion in STORM"; §2: "instantaneous motion vectors … with a simplified linear motion
//! assumption"): the motion head sees each context frame's motion tokens once, unmodulated,
//! and predicts per pixel a forward velocity `v_fwd` and a backward velocity `v_bwd` (world
//! units per frame, both in forward-time orientation). Eq. 1, `μ_{i→j} = μ_i + v·(j − i)`,
//! then holds with a velocity that depends only on the direction of j: `v_fwd` for `j > i`,
//! `v_bwd` for `j < i`. So displacements are exactly linear in `(j − i)` on each side, and a
//! target behind the source moves against `v_bwd`. The output keeps the lifting layout
//! (`[B, T_c·(N−1), H, W, 3]`, source-major), so the adapter and renderer are unchanged.

use crate::config::{MotionModel, DISPLACEMENT_DIM, VELOCITY_DIRECTIONS};
use burn::tensor::{Device, Tensor};

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

/// Displacements of a scene where nothing moves: zeros in the lifting layout
/// `[B, T_c·(N−1), H, W, 3]` (batch `b`, `tc` context frames, `n` timestamps, `hw` pixels).
pub fn still_displacements(
    b: usize,
    tc: usize,
    n: usize,
    hw: [usize; 2],
    device: &Device,
) -> Tensor<5> {
    Tensor::zeros([b, tc * (n - 1), hw[0], hw[1], DISPLACEMENT_DIM], device)
}

/// Channels `[FORWARD_VELOCITY]` of the linear-velocity head output: velocity towards later
/// timestamps; `[BACKWARD_VELOCITY]`: towards earlier ones.
pub const FORWARD_VELOCITY: std::ops::Range<usize> = 0..DISPLACEMENT_DIM;
pub const BACKWARD_VELOCITY: std::ops::Range<usize> =
    DISPLACEMENT_DIM..VELOCITY_DIRECTIONS * DISPLACEMENT_DIM;

/// The four token maps the motion head reads, all patch tokens only (so the head is called
/// with `patch_start = 0`). `time_list`: the aggregator's four `[B, T_c, P, 2C]` maps;
/// `time: [B, N, 2C]` the refined time tokens.
/// * `Lifting`: `[B, T_c·(N−1), hw, 2C]`, one map per (source, target) pair ([`lift`]);
/// * `LinearVelocity`: `[B, T_c, hw, 2C]`, the motion tokens themselves, once per frame.
pub fn motion_tokens(
    model: MotionModel,
    time_list: &[Tensor<4>],
    time: Tensor<3>,
    patch_start: usize,
) -> [Tensor<4>; 4] {
    assert_eq!(time_list.len(), 4, "the motion head reads four maps");
    std::array::from_fn(|t| match model {
        MotionModel::Lifting => lift(time_list[t].clone(), time.clone(), patch_start),
        // `Off` never runs the head; its tokens would be the plain motion tokens.
        MotionModel::LinearVelocity | MotionModel::Off => {
            let [b, tc, p, c] = time_list[t].dims();
            time_list[t]
                .clone()
                .slice([0..b, 0..tc, patch_start..p, 0..c])
        }
    })
}

/// The motion head's raw output → displacements `[B, T_c·(N−1), H, W, 3]`, source-major
/// (`n` = N, all timestamps). Lifting already predicts displacements (the release adds them
/// with no `(j − i)` factor); the baseline's velocities go through [`linear_displacements`].
pub fn displacements(model: MotionModel, head_out: Tensor<5>, n: usize) -> Tensor<5> {
    match model {
        MotionModel::Lifting => head_out,
        MotionModel::LinearVelocity => linear_displacements(head_out, n),
        MotionModel::Off => head_out.zeros_like(),
    }
}

/// `velocities: [B, T_c, H, W, 6]` (`[v_fwd | v_bwd]`) → `[B, T_c·(N−1), H, W, 3]` with
/// `out[:, i·K + k] = v_dir(i) · (j − i)`, `j = targets_of(i, n)[k]`, `dir` forward for
/// `j > i` and backward for `j < i` (the module docs give the reading of the paper).
pub fn linear_displacements(velocities: Tensor<5>, n: usize) -> Tensor<5> {
    let [b, tc, h, w, ch] = velocities.dims();
    assert_eq!(
        ch,
        VELOCITY_DIRECTIONS * DISPLACEMENT_DIM,
        "linear-velocity head output must hold a forward and a backward velocity"
    );
    let velocity = |i: usize, dir: std::ops::Range<usize>| {
        velocities.clone().slice([0..b, i..i + 1, 0..h, 0..w, dir])
    };
    let mut out = Vec::with_capacity(tc * (n - 1));
    for i in 0..tc {
        for j in targets_of(i, n) {
            let dir = if j > i {
                FORWARD_VELOCITY
            } else {
                BACKWARD_VELOCITY
            };
            // Frame indices are small integers, so the gap is exact in f64 and in f32.
            let gap = j as f64 - i as f64;
            out.push(velocity(i, dir).mul_scalar(gap));
        }
    }
    Tensor::cat(out, 1)
}
