//! What the fused-kernel tests share: the test GPU, their turn-taking, a guard that turns a
//! fused op off for one measurement, seeded inputs, and reading results back.

#![allow(dead_code)] // each test binary uses its own subset

use burn::tensor::{Device, Tensor};
use std::sync::{Mutex, MutexGuard};

/// The launch counter and the fused switches are process-wide: a binary's tests take turns.
static SERIAL: Mutex<()> = Mutex::new(());

/// This test's turn (a failed test's poisoned lock still serialises the rest).
pub fn turn() -> MutexGuard<'static, ()> {
    SERIAL.lock().unwrap_or_else(|e| e.into_inner())
}

/// The test GPU (wgpu, lavapipe in CI; CUDA with `ENVISION4D_TEST_GPU=cuda`), `None` where
/// `ENVISION4D_SKIP_WGPU=1` and no adapter exists.
pub fn gpu() -> Option<Device> {
    envision4d_splat::testkit::wgpu_test_device()
}

/// A fused op switched off until dropped (`set` is its `set_fused_*`), so a failing
/// assertion cannot leave it off for the next test.
pub struct Unfused(fn(bool));

impl Unfused {
    pub fn new(set: fn(bool)) -> Self {
        set(false);
        Unfused(set)
    }
}

impl Drop for Unfused {
    fn drop(&mut self) {
        (self.0)(true);
    }
}

/// Seeded values in [-1, 1) (an LCG), not rounded.
pub fn uniform_f64(len: usize, seed: u64) -> Vec<f64> {
    let mut s = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    (0..len)
        .map(|_| {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        })
        .collect()
}

/// [`uniform_f64`] rounded to f32, so an f64 oracle and an f32 run see the same inputs.
pub fn uniform(len: usize, seed: u64) -> Vec<f64> {
    uniform_f64(len, seed)
        .into_iter()
        .map(|v| v as f32 as f64)
        .collect()
}

/// A tensor's values as f64.
pub fn host<const D: usize>(t: Tensor<D>) -> Vec<f64> {
    t.into_data()
        .convert::<f64>()
        .try_to_vec::<f64>()
        .expect("f64")
}

/// `max |a - b| / max(floor, max |b|)`.
pub fn rel_err_floor(a: &[f64], b: &[f64], floor: f64) -> f64 {
    let scale = b.iter().fold(floor, |m, x| m.max(x.abs()));
    a.iter()
        .zip(b)
        .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()))
        / scale
}

/// `max |a - b| / max |b|` (floored at 1e-300: an all-zero `b` gives the absolute error
/// scaled up, which fails any tolerance unless `a` is zero too).
pub fn rel_err(a: &[f64], b: &[f64]) -> f64 {
    rel_err_floor(a, b, 1e-300)
}

/// Holds per-channel sums of `rows` terms, summed in chunks of `chunk` rows then over the
/// chunks, to recursive summation's bound `n·ε·Σ|terms|` (`scale` per channel, `n` a chunk
/// plus the chunks, plus `slack` for roundings of the terms themselves).
pub fn assert_chunked_sums(
    what: &str,
    got: &[f64],
    want: &[f64],
    scale: &[f64],
    [rows, chunk, slack]: [usize; 3],
) {
    let n = chunk.min(rows) + rows.div_ceil(chunk) + slack;
    for (c, ((f, w), s)) in got.iter().zip(want).zip(scale).enumerate() {
        let bound = n as f64 * f64::from(f32::EPSILON) * s + 1e-37;
        assert!(
            (f - w).abs() <= bound,
            "{what}[{c}] = {f:e}, f64 {w:e}, bound {bound:e}"
        );
    }
}
