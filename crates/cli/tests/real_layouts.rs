//! The real-data paths end to end on synthetic trees in the real layouts (`synth --layout
//! storm-waymo|nuscenes`): training reads only the training split, evaluation scores the
//! evaluation split with LiDAR D-RMSE, cross-frame pairs and scale-aligned pose errors.

mod common;

use common::text;
use std::path::{Path, PathBuf};
use std::process::Output;

/// `envision4d args` in the test's working directory.
fn bin(args: &[&str]) -> Output {
    common::bin(args, Path::new("."))
}

/// Writes `frames` frames of one synthetic scene as `<root>/<split>/000`.
fn storm_split(root: &Path, split: &str, frames: usize, seed: u64) {
    let o = bin(&[
        "synth",
        "--layout",
        "storm-waymo",
        "--split",
        split,
        "--out",
        root.to_str().unwrap(),
        "--frames",
        &frames.to_string(),
        "--size",
        "56x84",
        "--supersample",
        "1",
        "--seed",
        &seed.to_string(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
}

/// `configs/synth-tiny.toml` on the STORM tree: random init, no distillation (the tree's
/// LiDAR is sparse, so exact dense labels do not exist), T_f = 2, `steps` iterations.
fn config(dir: &Path, root: &Path, steps: i64) -> PathBuf {
    let mut cfg = common::shipped_tiny();
    cfg.insert("teacher".into(), "none".into());
    let set = common::set;
    set(&mut cfg, "model", "future_frames", 2.into());
    set(&mut cfg, "optim", "batch_size", 1.into());
    set(&mut cfg, "optim", "iterations", steps.into());
    set(&mut cfg, "progressive", "warmup_iterations", 2.into());
    set(&mut cfg, "progressive", "s_max", 10.into());
    set(&mut cfg, "data", "layout", "waymo".into());
    set(&mut cfg, "data", "root", root.display().to_string().into());
    set(&mut cfg, "data", "stride", 1.into());
    let out = dir.join("run");
    set(&mut cfg, "run", "out_dir", out.display().to_string().into());
    set(&mut cfg, "run", "log_every", 5.into());
    set(&mut cfg, "run", "checkpoint_every", 10.into());
    set(&mut cfg, "run", "val_every", 10.into());
    set(&mut cfg, "run", "val_clips", 1.into());
    let path = dir.join("storm.toml");
    std::fs::write(&path, toml::to_string(&cfg).unwrap()).unwrap();
    path
}

/// Guards the training side: `--dry-run` reports the training split with its poses (LiDAR
/// left to eval) and refuses `split = "validation"`, a 20-step run on it finishes, and nothing of `validation/` is read (its
/// frames are made undecodable, so reading one would be a warning or an error).
#[test]
fn storm_tree_trains_on_training_only() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("waymo");
    storm_split(&root, "training", 10, 1);
    storm_split(&root, "validation", 8, 2);
    for entry in std::fs::read_dir(root.join("validation/000/images")).unwrap() {
        std::fs::write(entry.unwrap().path(), b"not an image").unwrap();
    }
    let cfg = config(dir.path(), &root, 20);
    let c = cfg.to_str().unwrap();
    let dry = bin(&["train", "--config", c, "--dry-run"]);
    let out = text(&dry);
    assert!(dry.status.success(), "{out}");
    assert!(out.contains("split \"training\""), "{out}");
    // 9 listed timesteps (range(min, max)), windows of 4 every frame: starts 0..=5.
    assert!(
        out.contains("windows: 6 from 1 scene(s), 4 frames each"),
        "{out}"
    );
    assert!(
        out.contains("poses yes") && out.contains("depth not read for training"),
        "{out}"
    );
    // The same tree with split = "validation" is refused, naming the key.
    let bad = dir.path().join("bad.toml");
    let toml_text = std::fs::read_to_string(&cfg).unwrap();
    std::fs::write(
        &bad,
        toml_text.replace("[data]\n", "[data]\nsplit = \"validation\"\n"),
    )
    .unwrap();
    let refused = bin(&["train", "--config", bad.to_str().unwrap(), "--dry-run"]);
    assert_eq!(refused.status.code(), Some(2), "{}", text(&refused));
    assert!(text(&refused).contains("data.split"), "{}", text(&refused));
    let run = bin(&["train", "--config", c]);
    let out = text(&run);
    assert!(run.status.success(), "{out}");
    assert!(out.contains("trained 20 steps"), "{out}");
    assert!(
        !out.contains("validation/000"),
        "training touched validation/: {out}"
    );
    assert!(dir.path().join("run/model.safetensors").is_file());
}

/// Guards the evaluation side on `validation/` with the release protocol: `--list-windows`
/// of `release` (4 scored frames) and `paper` (2), one window of the release's clips, D-RMSE of the rendered future depth against the projected LiDAR points
/// (and of the depth head, kept apart), the cross-frame pairs 1→0 and 0→1 after the
/// release's crop (scaled to the frame size), and scale-aligned translation errors in metres.
#[test]
fn storm_tree_evaluates_with_lidar_and_pairs() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("waymo");
    // The checkpoint predicts T_f = 6: its windows are 8 frames (9 files: range(min, max)).
    storm_split(&root, "validation", 9, 2);
    let ckpt = common::paths::manifest_dir().join("../../models/envision4d-synth-tiny.safetensors");
    let out = dir.path().join("eval");
    let list = |protocol: &str| {
        let o = bin(&[
            "eval",
            "--checkpoint",
            ckpt.to_str().unwrap(),
            "--data",
            root.to_str().unwrap(),
            "--layout",
            "waymo",
            "--protocol",
            protocol,
            "--list-windows",
        ]);
        assert!(o.status.success(), "{}", text(&o));
        String::from_utf8_lossy(&o.stdout).into_owned()
    };
    assert_eq!(
        list("release"),
        "validation/000 start=0 context=0,1 scored=2,3,4,5\n"
    );
    assert_eq!(
        list("paper"),
        "validation/000 start=0 context=0,1 scored=2,3\n"
    );
    let o = bin(&[
        "eval",
        "--checkpoint",
        ckpt.to_str().unwrap(),
        "--data",
        root.to_str().unwrap(),
        "--layout",
        "waymo",
        "--protocol",
        "release",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("metrics.json")).unwrap()).unwrap();
    assert_eq!(json["clips_evaluated"], 1);
    let clip = &json["clips"][0];
    let depth = &clip["depth_rmse"];
    assert_eq!(depth["source"], "lidar_points", "{depth}");
    assert_eq!(depth["frames"], serde_json::json!([2, 3, 4, 5]));
    assert!(depth["rmse"].as_f64().unwrap() > 0.0, "{depth}");
    assert_eq!(
        clip["context_depth_rmse"]["frames"],
        serde_json::json!([0, 1])
    );
    let pairs: Vec<(u64, u64)> = clip["context"]["pairs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| (p["source"].as_u64().unwrap(), p["target"].as_u64().unwrap()))
        .collect();
    assert_eq!(pairs, vec![(1, 0), (0, 1)]);
    assert_eq!(
        json["cross_frame_crop"],
        // The release's 6, 6, 10, 6 at 350x518, scaled to these 56x84 frames.
        serde_json::json!({"top": 1, "bottom": 1, "left": 2, "right": 1})
    );
    assert_eq!(json["translation_unit"], "m");
    let model = &clip["methods"][0];
    assert!(model["trans_err"].as_f64().unwrap() >= 0.0, "{model}");
    assert!(model["pose_scale"].as_f64().unwrap() >= 0.0, "{model}");
    assert!(model["camera_auc30"].as_f64().is_some(), "{model}");
}

/// Guards the nuScenes path: `synth --layout nuscenes` writes `mini_train` and `mini_val`
/// into one official-layout tree; `train --dry-run` reads `mini_train` with poses (and not
/// the LiDAR, which no training loss uses) and refuses `mini_val`; `eval --layout nuscenes --dataset-split mini_val` scores it with
/// LiDAR-point D-RMSE.
#[test]
fn nuscenes_tree_trains_on_mini_train_and_evaluates_mini_val() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("nuscenes");
    for (split, frames, seed) in [("mini_train", "6", "1"), ("mini_val", "8", "2")] {
        let o = bin(&[
            "synth",
            "--layout",
            "nuscenes",
            "--split",
            split,
            "--out",
            root.to_str().unwrap(),
            "--frames",
            frames,
            "--size",
            "56x84",
            "--supersample",
            "1",
            "--seed",
            seed,
        ]);
        assert!(o.status.success(), "{}", text(&o));
    }
    let cfg = config(dir.path(), &root, 1);
    let with = |extra: &str| {
        let text = std::fs::read_to_string(&cfg).unwrap().replace(
            "layout = \"waymo\"",
            &format!("layout = \"nuscenes\"\n{extra}"),
        );
        let p = dir.path().join("nu.toml");
        std::fs::write(&p, text).unwrap();
        p
    };
    let dry = bin(&[
        "train",
        "--config",
        with("split = \"mini_train\"").to_str().unwrap(),
        "--dry-run",
    ]);
    let out = text(&dry);
    assert!(dry.status.success(), "{out}");
    assert!(out.contains("split \"mini_train\""), "{out}");
    // 6 keyframes, windows of 4 every frame: 3, from scene-0061.
    assert!(
        out.contains("windows: 3 from 1 scene(s), 4 frames each"),
        "{out}"
    );
    assert!(
        out.contains("poses yes") && out.contains("depth not read for training"),
        "{out}"
    );
    let dry = bin(&[
        "train",
        "--config",
        with("split = \"mini_val\"").to_str().unwrap(),
        "--dry-run",
    ]);
    assert_eq!(dry.status.code(), Some(2), "{}", text(&dry));
    assert!(text(&dry).contains("data.split"), "{}", text(&dry));

    let ckpt = common::paths::manifest_dir().join("../../models/envision4d-synth-tiny.safetensors");
    let out = dir.path().join("eval");
    // The checkpoint predicts T_f = 6 (8-frame windows; mini_val has 8 keyframes).
    let o = bin(&[
        "eval",
        "--checkpoint",
        ckpt.to_str().unwrap(),
        "--data",
        root.to_str().unwrap(),
        "--layout",
        "nuscenes",
        "--dataset-split",
        "mini_val",
        "--protocol",
        "paper",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("metrics.json")).unwrap()).unwrap();
    assert_eq!(json["clips"][0]["clip"], "mini_val/scene-0103#0");
    assert_eq!(json["clips"][0]["depth_rmse"]["source"], "lidar_points");
    assert_eq!(
        json["clips"][0]["depth_rmse"]["frames"],
        serde_json::json!([2, 3])
    );
}
