//! Property tests of checkpoint reading: our own safetensors checkpoints with a damaged
//! header (thousands of cases through the header reader, fewer through a full load into the
//! model) or cut anywhere; each gives an error naming the file, or a model that loaded,
//! never a panic.

#[path = "../../../tests/support/mutate.rs"]
mod mutate;

use burn::tensor::Device;
use envision4d_model::checkpoint::{
    checkpoint_config, load_checkpoint, save_checkpoint, CheckpointKind,
};
use envision4d_model::{Envision4d, ModelConfig};
use proptest::prelude::*;
use std::path::Path;
use std::sync::OnceLock;

/// A freshly initialised tiny model's checkpoint, and where its header ends.
fn seed() -> &'static (Vec<u8>, usize) {
    static SEED: OnceLock<(Vec<u8>, usize)> = OnceLock::new();
    SEED.get_or_init(|| {
        let tmp = tempfile::tempdir().unwrap();
        let path = tmp.path().join("model.safetensors");
        let model = Envision4d::new(&ModelConfig::tiny(), &Device::flex());
        save_checkpoint(&model, &ModelConfig::tiny(), &path).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let n = u64::from_le_bytes(bytes[..8].try_into().unwrap()) as usize;
        (bytes, 8 + n)
    })
}

/// The seed with `edits` applied to its length prefix and header only; the data follows.
fn damaged_header(edits: &[mutate::Edit]) -> Vec<u8> {
    let (bytes, end) = seed();
    let mut out = mutate::apply(&bytes[..*end], edits);
    out.extend_from_slice(&bytes[*end..]);
    out
}

/// Loads `bytes` as a checkpoint into a tiny model: an error must name the file.
fn load(bytes: &[u8], dir: &Path) -> Result<(), String> {
    let path = dir.join("damaged.safetensors");
    std::fs::write(&path, bytes).unwrap();
    let mut model = Envision4d::new(&ModelConfig::tiny(), &Device::flex());
    match load_checkpoint(&mut model, &path, CheckpointKind::Full) {
        Ok(_) => Ok(()),
        Err(e) if e.to_string().contains("damaged.safetensors") => Err(e.to_string()),
        Err(e) => panic!("the error does not name the file: {e}"),
    }
}

#[test]
fn the_seed_is_valid() {
    let tmp = tempfile::tempdir().unwrap();
    load(&seed().0, tmp.path()).unwrap();
}

proptest! {
    #![proptest_config(mutate::config(2000))]

    /// Guards the header reader (`eval`/`render` read a checkpoint's config from it before
    /// building a model) against a damaged length prefix or JSON.
    #[test]
    fn a_damaged_header_never_panics_the_config_reader(edits in mutate::edits()) {
        let tmp = tempfile::tempdir().unwrap();
        let (bytes, end) = seed();
        // The header and a little data: the reader must not need more.
        let mut damaged = mutate::apply(&bytes[..*end], &edits);
        damaged.extend_from_slice(&bytes[*end..(*end + 4096).min(bytes.len())]);
        let path = tmp.path().join("damaged.safetensors");
        std::fs::write(&path, &damaged).unwrap();
        if let Err(e) = checkpoint_config(&path) {
            prop_assert!(e.to_string().contains("damaged.safetensors"), "{e}");
        }
    }
}

proptest! {
    // A full load builds a model and reads 12 MB: fewer cases.
    #![proptest_config(mutate::config(120))]

    /// Guards a full load (burn-store's reader under ours) against a damaged header: wrong
    /// offsets, dtypes and shapes are errors naming the file, never a panic.
    #[test]
    fn a_damaged_header_never_panics_a_load(edits in mutate::edits()) {
        let tmp = tempfile::tempdir().unwrap();
        let _ = load(&damaged_header(&edits), tmp.path());
    }

    /// Guards a load of a file cut anywhere (a copy interrupted, a disk that filled).
    #[test]
    fn a_cut_checkpoint_never_panics_a_load(at in 0.0..1.0f64) {
        let tmp = tempfile::tempdir().unwrap();
        let bytes = &seed().0;
        let cut = &bytes[..(at * bytes.len() as f64) as usize];
        prop_assert!(load(cut, tmp.path()).is_err());
    }
}
