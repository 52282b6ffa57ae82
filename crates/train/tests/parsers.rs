//! Property tests of the training config parser: every shipped config, randomly damaged
//! thousands of times (a cut file, a changed byte, a number replaced by an extreme one);
//! each gives an error naming the file or key, or a config whose schedule is usable, never a
//! panic.

#[path = "../../../tests/support/mutate.rs"]
mod mutate;
#[path = "../../../tests/support/paths.rs"]
mod paths;

use envision4d_train::load::parse;
use envision4d_train::schedule::Schedule;
use proptest::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// Every TOML under `configs/` (recursively) and its text.
fn shipped() -> &'static [(PathBuf, String)] {
    static CONFIGS: OnceLock<Vec<(PathBuf, String)>> = OnceLock::new();
    CONFIGS.get_or_init(|| {
        fn walk(dir: &Path, out: &mut Vec<(PathBuf, String)>) {
            for e in std::fs::read_dir(dir).unwrap() {
                let p = e.unwrap().path();
                if p.is_dir() {
                    walk(&p, out);
                } else if p.extension().is_some_and(|x| x == "toml") {
                    out.push((p.clone(), std::fs::read_to_string(&p).unwrap()));
                }
            }
        }
        let mut out = Vec::new();
        walk(&paths::manifest_dir().join("../../configs"), &mut out);
        out.sort();
        out
    })
}

#[test]
fn the_seeds_are_valid() {
    assert!(shipped().len() >= 10, "{} configs", shipped().len());
    for (path, text) in shipped() {
        parse(text, path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    }
}

proptest! {
    #![proptest_config(mutate::config(3000))]

    /// Guards the config parser and its validation against damaged files: an error naming
    /// the file or the key (never a panic), or a config whose schedule gives a finite
    /// learning rate and annealing weight at any step.
    #[test]
    fn a_damaged_config_never_panics(which in any::<usize>(), edits in mutate::edits()) {
        let (path, text) = &shipped()[which % shipped().len()];
        let damaged = mutate::apply(text.as_bytes(), &edits);
        match parse(&String::from_utf8_lossy(&damaged), path) {
            Ok(cfg) => {
                let s = Schedule::from_config(&cfg);
                for step in [0, 1, cfg.optim.iterations / 2, cfg.optim.iterations, u64::MAX / 2] {
                    let _ = s.phase(step);
                    prop_assert!(s.learning_rate(step).is_finite(), "lr at {step}: {cfg:?}");
                    prop_assert!(s.alpha(step).is_finite(), "alpha at {step}: {cfg:?}");
                }
            }
            Err(e) => prop_assert!(!e.to_string().is_empty()),
        }
    }
}
