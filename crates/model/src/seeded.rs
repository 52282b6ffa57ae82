//! Seeded model construction that stays reproducible when several threads build models at
//! once (parallel tests, a trainer next to an evaluator).
//!
//! Burn's device RNG is shared by the whole process, and most parameters are lazy: they draw
//! their random values on first access, not when the module is built. Two threads that seed
//! and build at the same time interleave their draws, so "same seed, same weights" fails
//! under load (seen as a resume test and an init test failing while a training ran beside
//! the test suite). [`seeded`] holds one process-wide lock across seeding, building and
//! materialising every parameter.

use burn::module::{Module, ModuleVisitor, Param};
use burn::tensor::{Device, Tensor};
use std::sync::Mutex;

static SEEDED_INIT: Mutex<()> = Mutex::new(());

/// Touches every float parameter so lazy ones draw their values now.
struct Materialise;

impl ModuleVisitor for Materialise {
    fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
        let _ = param.val();
    }
}

/// Seeds `device`, runs `build` and materialises the parameters of the module it returns,
/// all under one process-wide lock, so the weights depend only on `seed`.
pub fn seeded<M: Module, E>(
    device: &Device,
    seed: u64,
    build: impl FnOnce() -> Result<M, E>,
) -> Result<M, E> {
    let _guard = SEEDED_INIT.lock().unwrap_or_else(|p| p.into_inner());
    device.seed(seed);
    let module = build()?;
    module.visit(&mut Materialise);
    Ok(module)
}
