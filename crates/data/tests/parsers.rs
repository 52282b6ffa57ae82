//! Property tests of the data crate's parsers: thousands of randomly damaged `.npy` files,
//! and synthetic clip folders with one file damaged or missing (frames, depth EXR, cameras,
//! metadata, tracks); each gives an error (or a skipped clip) or a valid result, never a panic.

#[path = "../../../tests/support/mutate.rs"]
mod mutate;

use envision4d_data::npy::{encode_npy_f32, parse_npy_f32};
use envision4d_data::synth::{render_clip, write_clip, Preset, SynthConfig};
use envision4d_data::{ClipDataset, ClipSpec, DatasetConfig, Fit, FitMode, Layout};
use proptest::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

#[test]
fn the_seeds_are_valid() {
    let npy = parse_npy_f32(&encode_npy_f32(&[2, 3], &[0.0, 1.0, 2.0, 3.0, 4.0, 5.0])).unwrap();
    assert_eq!(npy.shape, [2, 3]);
    let ds = ClipDataset::open(&seed_clip().0, dataset_config()).unwrap();
    assert_eq!(ds.len(), 1);
    ds.load(0).unwrap();
}

/// One small synthetic clip (28x42, 4 frames), written once per test process under cargo's
/// temp folder for tests, and its files.
fn seed_clip() -> &'static (PathBuf, Vec<PathBuf>) {
    static SEED: OnceLock<(PathBuf, Vec<PathBuf>)> = OnceLock::new();
    SEED.get_or_init(|| {
        let root = Path::new(env!("CARGO_TARGET_TMPDIR")).join("data-parsers-seed");
        let _ = std::fs::remove_dir_all(&root);
        let cfg = SynthConfig {
            width: 42,
            height: 28,
            frames: 4,
            preset: Preset::Urban,
            seed: 3,
            supersample: 1,
        };
        let clip = render_clip(&cfg, 0, || {}).unwrap();
        write_clip(&root.join("clip_000000"), &clip).unwrap();
        let mut files = Vec::new();
        list(&root, &root, &mut files);
        files.sort();
        (root, files)
    })
}

/// Files under `dir`, relative to `root`.
fn list(root: &Path, dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            list(root, &p, out);
        } else {
            out.push(p.strip_prefix(root).unwrap().to_path_buf());
        }
    }
}

fn dataset_config() -> DatasetConfig {
    DatasetConfig {
        layout: Layout::Synth { stride: 1 },
        spec: ClipSpec {
            context: 2,
            future: 2,
            frame_step: 1,
        },
        fit: Fit {
            mode: FitMode::Resize,
            height: 28,
            width: 42,
        },
        cache_clips: 1,
    }
}

proptest! {
    #![proptest_config(mutate::config(3000))]

    /// Guards the `.npy` reader (Waymo/STORM depth and poses) against damaged headers,
    /// shapes larger than the data, and cut files.
    #[test]
    fn damaged_npy_never_panics(edits in mutate::edits()) {
        let valid = encode_npy_f32(&[2, 3, 4], &(0..24).map(|i| i as f32).collect::<Vec<_>>());
        if let Ok(n) = parse_npy_f32(&mutate::apply(&valid, &edits)) {
            prop_assert_eq!(n.shape.iter().product::<usize>(), n.data.len());
        }
    }
}

proptest! {
    // Each case copies a clip folder: fewer cases, still a few seconds.
    #![proptest_config(mutate::config(300))]

    /// Guards the clip-folder reader: one damaged or deleted file (a PNG frame, a depth
    /// EXR, cameras.json, meta.json, tracks.json, a flow or mask file) gives an error or a
    /// skipped clip naming it, never a panic.
    #[test]
    fn a_damaged_clip_folder_never_panics(
        which in any::<usize>(),
        delete in prop::bool::weighted(0.1),
        edits in mutate::edits(),
    ) {
        let (root, files) = seed_clip();
        let tmp = tempfile::tempdir().unwrap();
        for f in files {
            let to = tmp.path().join(f);
            std::fs::create_dir_all(to.parent().unwrap()).unwrap();
            std::fs::copy(root.join(f), &to).unwrap();
        }
        let target = tmp.path().join(&files[which % files.len()]);
        if delete {
            std::fs::remove_file(&target).unwrap();
        } else {
            let bytes = std::fs::read(&target).unwrap();
            std::fs::write(&target, mutate::apply(&bytes, &edits)).unwrap();
        }
        if let Ok(ds) = ClipDataset::open(tmp.path(), dataset_config()) {
            for i in 0..ds.len() {
                if let Ok(clip) = ds.load(i) {
                    prop_assert!(!clip.frames.is_empty());
                }
            }
        }
    }
}
