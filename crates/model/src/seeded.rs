//! Seeded model construction that stays reproducible when several threads build models at
//! once (parallel tests, a trainer next to an evaluator).
//!
//! Burn's device RNG is shared by the whole process. Some parameters draw their values when
//! the module is built, most are lazy and draw on first access. Two threads that seed and
//! build at the same time interleave their draws, so "same seed, same weights" failed under
//! load (a resume test and an init test, while a training ran beside the test suite).
//! One process-wide lock therefore covers every [`Envision4d::new`](crate::Envision4d::new)
//! (its eager draws), and [`seeded`] holds it across seeding, building and materialising
//! every lazy parameter. Draws made elsewhere without the lock (a lazy parameter of an
//! unseeded model touched later, `Tensor::random` in a caller) can still interleave; seeded
//! builds are exact as long as nothing else draws while they run.

use burn::module::{Module, ModuleVisitor, Param};
use burn::tensor::{Device, Tensor};
use std::cell::Cell;
use std::sync::Mutex;

static INIT_LOCK: Mutex<()> = Mutex::new(());

thread_local! {
    /// Whether this thread holds [`INIT_LOCK`] (so a nested build does not deadlock).
    static HELD: Cell<bool> = const { Cell::new(false) };
}

/// Resets [`HELD`] even if the build panics.
struct Release;

impl Drop for Release {
    fn drop(&mut self) {
        HELD.with(|h| h.set(false));
    }
}

/// Runs `f` holding the process-wide model-initialisation lock (re-entrant per thread).
pub fn with_init_lock<T>(f: impl FnOnce() -> T) -> T {
    if HELD.with(Cell::get) {
        return f();
    }
    let _guard = INIT_LOCK.lock().unwrap_or_else(|p| p.into_inner());
    HELD.with(|h| h.set(true));
    let _release = Release;
    f()
}

/// Touches every float parameter so lazy ones draw their values now.
struct Materialise;

impl ModuleVisitor for Materialise {
    fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
        let _ = param.val();
    }
}

/// Seeds `device`, runs `build` and materialises the parameters of the module it returns,
/// all under the initialisation lock, so the weights depend only on `seed`.
pub fn seeded<M: Module, E>(
    device: &Device,
    seed: u64,
    build: impl FnOnce() -> Result<M, E>,
) -> Result<M, E> {
    with_init_lock(|| {
        device.seed(seed);
        let module = build()?;
        module.visit(&mut Materialise);
        Ok(module)
    })
}
