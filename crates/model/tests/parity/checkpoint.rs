//! Checkpoint I/O: the release's Lightning `.ckpt` layout, our own safetensors checkpoints,
//! VGGT-1B initialisation, and errors that list every bad key.

use crate::fixture::{assert_close, flat, Fixture};
use burn::tensor::Device;
use envision4d_model::checkpoint::{
    checkpoint_config, load_checkpoint, save_checkpoint, CheckpointKind,
};
use envision4d_model::model::Heads;
use envision4d_model::weights::{header_names, load_weights, Missing, Unexpected};
use envision4d_model::{Envision4d, ModelConfig};
use std::path::{Path, PathBuf};
use std::process::Command;

fn script() -> PathBuf {
    crate::paths::manifest_dir().join("../../scripts/make_lightning_ckpt.py")
}

fn pose_matches(model: &Envision4d, fx: &Fixture, device: &Device) {
    let out = model.backbone(fx.tensor::<5>("input/images", device), &[]);
    assert_close(
        "pose_enc",
        flat(out.pose_enc()),
        &fx.f32s("expected/pose_enc"),
        1e-4,
        1e-5,
    );
}

fn official_keys(fx: &Fixture) -> std::collections::BTreeSet<String> {
    header_names(&fx.path)
        .unwrap()
        .into_iter()
        .filter_map(|k| k.strip_prefix("weights/").map(str::to_owned))
        .collect()
}

/// Guards loading the release format: a PyTorch zip pickle with the weights under
/// `state_dict` and the `encoder.backbone.` prefix (detected), Sequential indices kept.
#[test]
fn lightning_ckpt_loads_and_matches() {
    let fx = Fixture::open("envision4d_tiny.safetensors");
    let dir = tempfile::tempdir().unwrap();
    let ckpt = dir.path().join("tiny.ckpt");
    let ok = Command::new("python3")
        .arg(script())
        .arg(&fx.path)
        .arg(&ckpt)
        .args(["--strip", "weights/", "--prefix", "encoder.backbone."])
        .status()
        .expect("python3 is needed to write the test checkpoint");
    assert!(ok.success());
    let device = Device::flex();
    let mut model = Envision4d::new(&ModelConfig::tiny(), &device);
    let report =
        load_checkpoint(&mut model, &ckpt, CheckpointKind::Full).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(report.applied, 1264);
    pose_matches(&model, &fx, &device);
}

/// Guards our checkpoint format: official names and layouts exactly (the key set equals the
/// reference state_dict), the config in the metadata, and a strict reload that reproduces
/// the outputs; the write is atomic (no temp file left).
#[test]
fn own_checkpoint_round_trip() {
    let fx = Fixture::open("envision4d_tiny.safetensors");
    let device = Device::flex();
    let model = fx.tiny_model(&device);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("model.safetensors");
    save_checkpoint(&model, &ModelConfig::tiny(), &path).unwrap();
    let saved: std::collections::BTreeSet<String> =
        header_names(&path).unwrap().into_iter().collect();
    assert_eq!(
        saved,
        official_keys(&fx),
        "saved names must be the official state_dict keys"
    );
    assert_eq!(checkpoint_config(&path).unwrap(), Some(ModelConfig::tiny()));
    let mut again = Envision4d::new(&ModelConfig::tiny(), &device);
    load_checkpoint(&mut again, &path, CheckpointKind::Full).unwrap();
    pose_matches(&again, &fx, &device);
    let leftovers: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(leftovers.len(), 1, "{leftovers:?}");
}

/// Guards byte-reproducible checkpoints: burn-store writes the header's metadata from a hash
/// map, so one model saved twice differed in key order; our header lists every key sorted,
/// with the metadata intact, and a second save gives the same bytes.
#[test]
fn a_checkpoint_header_is_sorted_and_a_resave_is_byte_identical() {
    let device = Device::flex();
    let model = Envision4d::new(&ModelConfig::tiny(), &device);
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (
        dir.path().join("a.safetensors"),
        dir.path().join("b.safetensors"),
    );
    save_checkpoint(&model, &ModelConfig::tiny(), &a).unwrap();
    save_checkpoint(&model, &ModelConfig::tiny(), &b).unwrap();
    let bytes = std::fs::read(&a).unwrap();
    assert!(bytes == std::fs::read(&b).unwrap(), "two saves differ");
    let n = u64::from_le_bytes(bytes[..8].try_into().unwrap()) as usize;
    let header = std::str::from_utf8(&bytes[8..8 + n]).unwrap();
    let meta = ["envision4d_model_config", "format", "producer"].map(|k| {
        header
            .find(&format!("\"{k}\""))
            .unwrap_or_else(|| panic!("{k} missing from the header"))
    });
    assert!(
        meta.windows(2).all(|w| w[0] < w[1]),
        "metadata unsorted: {header:.300}"
    );
    let st = safetensors::SafeTensors::deserialize(&bytes).unwrap();
    let mut names = st.names();
    names.sort();
    let at: Vec<usize> = names
        .iter()
        .map(|k| header.find(&format!("\"{k}\":")).unwrap())
        .collect();
    assert!(at.windows(2).all(|w| w[0] < w[1]), "tensor keys unsorted");
    assert_eq!(checkpoint_config(&a).unwrap(), Some(ModelConfig::tiny()));
}

fn write_subset(src: &Path, dst: &Path, keep: impl Fn(&str) -> bool, extra: &[&str]) {
    let bytes = std::fs::read(src).unwrap();
    let st = safetensors::SafeTensors::deserialize(&bytes).unwrap();
    let dummy = vec![0u8; 16];
    let mut views: Vec<(String, safetensors::tensor::TensorView)> =
        st.tensors().into_iter().filter(|(k, _)| keep(k)).collect();
    for k in extra {
        views.push((
            k.to_string(),
            safetensors::tensor::TensorView::new(safetensors::Dtype::F32, vec![4], &dummy).unwrap(),
        ));
    }
    safetensors::tensor::serialize_to_file(views, None, dst).unwrap();
}

/// Guards VGGT-1B initialisation: aggregator/camera/depth come from the file, Envision4D's
/// new modules stay fresh, foreign heads are ignored; a strict load of the same file lists
/// what is missing.
#[test]
fn vggt1b_initialisation() {
    let fx = Fixture::open("envision4d_tiny.safetensors");
    let device = Device::flex();
    let dir = tempfile::tempdir().unwrap();
    let own = dir.path().join("own.safetensors");
    save_checkpoint(&fx.tiny_model(&device), &ModelConfig::tiny(), &own).unwrap();
    let vggt = dir.path().join("vggt.safetensors");
    let is_new = |k: &str| {
        k.starts_with("aggregator.time_blocks.")
            || k.starts_with("extra_")
            || k.starts_with("time_embedding.")
            || k.starts_with("gs_head.")
            || k.starts_with("motion_head.")
    };
    write_subset(
        &own,
        &vggt,
        |k| !is_new(k),
        &[
            "point_head.norm.weight",
            "track_head.feature_extractor.norm.weight",
        ],
    );

    let mut model = Envision4d::new(&ModelConfig::tiny(), &device);
    let report = load_checkpoint(&mut model, &vggt, CheckpointKind::Vggt1bInit)
        .unwrap_or_else(|e| panic!("{e}"));
    assert!(
        !report.kept_init.is_empty()
            && report
                .kept_init
                .iter()
                .all(|k| k.starts_with("aggregator.time_blocks.")
                    || k.starts_with("future.")
                    || k.starts_with("gs_head.")
                    || k.starts_with("motion_head.")),
        "{:?}",
        report.kept_init
    );
    assert_eq!(
        report.ignored.len(),
        2,
        "point/track heads ignored: {:?}",
        report.ignored
    );

    let err = load_checkpoint(
        &mut Envision4d::new(&ModelConfig::tiny(), &device),
        &vggt,
        CheckpointKind::Full,
    )
    .unwrap_err()
    .to_string();
    assert!(
        err.contains("missing: aggregator.time_blocks.0")
            && err.contains("missing: gs_head.")
            && err.contains("unexpected: point_head.norm.weight"),
        "{err}"
    );
}

/// Guards "one error listing them all": a checkpoint for other widths reports every
/// mis-shaped key at once; a corrupt file names the path.
#[test]
fn mismatched_and_corrupt_checkpoints() {
    let fx = Fixture::open("envision4d_tiny.safetensors");
    let device = Device::flex();
    let mut cfg = ModelConfig::tiny();
    cfg.dpt.features = 16;
    let mut model = Envision4d::new(&cfg, &device);
    let err = load_weights(
        &mut model,
        &fx.path,
        "weights/",
        Missing::Reject,
        Unexpected::Reject,
    )
    .unwrap_err()
    .to_string();
    let lines = err.lines().filter(|l| l.contains("mis-shaped")).count();
    assert!(
        lines > 10,
        "every mis-shaped DPT key should be listed, got {lines}:\n{err}"
    );
    assert!(err.contains("depth_head.scratch.layer1_rn.weight"), "{err}");

    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.safetensors");
    std::fs::write(&bad, b"definitely not a checkpoint").unwrap();
    let err = load_checkpoint(
        &mut Envision4d::new(&ModelConfig::tiny(), &device),
        &bad,
        CheckpointKind::Full,
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("bad.safetensors"), "{err}");
    let err = load_checkpoint(
        &mut Envision4d::new(&ModelConfig::tiny(), &device),
        &dir.path().join("x.onnx"),
        CheckpointKind::Full,
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("onnx"), "{err}");
}

/// Guards `Heads`: a poses-only pass runs no DPT head.
#[test]
fn heads_can_be_skipped() {
    let fx = Fixture::open("envision4d_tiny.safetensors");
    let device = Device::flex();
    let model = fx.tiny_model(&device);
    let p = model.forward(fx.tensor::<5>("input/images", &device), Heads::NONE);
    assert!(p.depth.is_none() && p.gaussians.is_none() && p.motion_enc.is_none());
    assert_close(
        "pose_enc",
        flat(p.backbone.pose_enc()),
        &fx.f32s("expected/pose_enc"),
        1e-4,
        1e-5,
    );
}
