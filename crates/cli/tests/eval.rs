//! `envision4d eval` end to end on a generated mini held-out set: the documented outputs
//! (JSON schema of docs/EVAL.md, Markdown, decodable PNGs, stdout summary), and clear
//! errors (exit code 2, the path named) for bad checkpoints and data folders.

#[path = "../../../tests/support/paths.rs"]
mod paths;

use burn::tensor::Device;
use envision4d_model::checkpoint::save_checkpoint;
use envision4d_model::Envision4d;
use envision4d_train::step::identity_pose_init;
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Mini held-out set: clips of T_c + T_f frames at the tiny model's size.
const CLIPS: &str = "2";
const FRAMES: &str = "4";
const SIZE: &str = "56x84";

fn repo(path: &str) -> PathBuf {
    paths::manifest_dir().join("../..").join(path)
}

fn envision4d(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_envision4d"))
        .args(args)
        .output()
        .expect("run envision4d")
}

fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 temp path")
}

/// A freshly initialised tiny model (configs/synth-tiny.toml's widths, T_f cut to the
/// mini set's clips, random init at the identity pose) saved as our checkpoint.
fn checkpoint(dir: &Path) -> PathBuf {
    let mut cfg = envision4d_train::load(&repo("configs/synth-tiny.toml"))
        .unwrap()
        .model;
    cfg.future_frames = FRAMES.parse::<usize>().unwrap() - cfg.context_frames;
    let mut model = Envision4d::new(&cfg, &Device::flex());
    identity_pose_init(&mut model);
    let path = dir.join("tiny.safetensors");
    save_checkpoint(&model, &cfg, &path).unwrap();
    path
}

fn synth_data(dir: &Path) -> PathBuf {
    synth_clips(dir, "heldout", CLIPS, FRAMES)
}

/// `clips` synthetic clips of `frames` frames at the tiny size in `dir/name`.
fn synth_clips(dir: &Path, name: &str, clips: &str, frames: &str) -> PathBuf {
    let data = dir.join(name);
    let o = envision4d(&[
        "synth",
        "--out",
        s(&data),
        "--clips",
        clips,
        "--frames",
        frames,
        "--size",
        SIZE,
        "--supersample",
        "1",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    data
}

/// `envision4d eval` of `ckpt` on `data` into `out`, with `extra` arguments.
fn eval(ckpt: &Path, data: &Path, out: &Path, extra: &[&str]) -> Output {
    let mut args = vec![
        "eval",
        "--checkpoint",
        s(ckpt),
        "--data",
        s(data),
        "--out",
        s(out),
    ];
    args.extend_from_slice(extra);
    envision4d(&args)
}

/// Every key path of a JSON value (`a.b[].c`); `mean.*` is folded onto `clips[].*`, and
/// `raster.*` (the rasterizer's own config, documented in crates/splat) is not expanded.
fn key_paths(v: &serde_json::Value, prefix: &str, out: &mut BTreeSet<String>) {
    match v {
        serde_json::Value::Object(map) => {
            for (k, child) in map {
                let path = if prefix.is_empty() {
                    k.clone()
                } else {
                    format!("{prefix}.{k}")
                };
                out.insert(path.clone());
                if path != "raster" {
                    let fold = if path == "mean" {
                        "clips[]".to_owned()
                    } else {
                        path
                    };
                    key_paths(child, &fold, out);
                }
            }
        }
        serde_json::Value::Array(items) => {
            for item in items {
                key_paths(item, &format!("{prefix}[]"), out);
            }
        }
        _ => {}
    }
}

/// The key paths documented in docs/EVAL.md: the first `code` cell of each table row
/// between the schema markers.
fn documented_keys() -> BTreeSet<String> {
    let doc = std::fs::read_to_string(repo("docs/EVAL.md")).expect("docs/EVAL.md exists");
    let start = doc
        .find("<!-- schema:begin -->")
        .expect("schema:begin marker");
    let end = doc.find("<!-- schema:end -->").expect("schema:end marker");
    doc[start..end]
        .lines()
        .filter_map(|l| l.strip_prefix("| `"))
        .filter_map(|l| l.split('`').next())
        .map(str::to_owned)
        .collect()
}

/// Guards the eval outputs against drifting from their documentation or going missing: on
/// a mini held-out set (with the sweep), metrics.json has exactly the keys docs/EVAL.md
/// lists, metrics.md has every table, all PNGs decode, and stdout shows quality next to time.
#[test]
fn eval_writes_documented_outputs() {
    let dir = tempfile::tempdir().unwrap();
    let (ckpt, data, out) = (
        checkpoint(dir.path()),
        synth_data(dir.path()),
        dir.path().join("eval"),
    );
    let o = eval(&ckpt, &data, &out, &["--sweep", "--max-clips", "1"]);
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{}\n{stdout}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(
        stdout.contains("PSNR") && stdout.contains("s/clip"),
        "{stdout}"
    );

    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("metrics.json")).unwrap()).unwrap();
    let mut got = BTreeSet::new();
    key_paths(&json, "", &mut got);
    let want = documented_keys();
    let undocumented: Vec<_> = got.difference(&want).collect();
    let missing: Vec<_> = want.difference(&got).collect();
    assert!(
        undocumented.is_empty() && missing.is_empty(),
        "undocumented keys {undocumented:?}, documented but absent {missing:?}"
    );
    assert_eq!(json["clips_evaluated"], 1);
    // The model, three baselines and, on a synthetic clip, four oracle renders.
    assert_eq!(json["mean"]["methods"].as_array().unwrap().len(), 8);
    assert!(json["lpips"]["available"] == false && json["mean"]["methods"][0]["lpips"].is_null());
    assert!(json["sweep"]
        .as_array()
        .unwrap()
        .iter()
        .any(|p| p["pareto"] == true));

    let md = std::fs::read_to_string(out.join("metrics.md")).unwrap();
    for heading in [
        "## Future frames",
        "## Per future horizon",
        "cross-frame",
        "## Depth",
        "## Timing",
        "## Quality against run time",
    ] {
        assert!(md.contains(heading), "metrics.md lacks {heading:?}");
    }
    for png in [
        "metrics_vs_horizon.png",
        "metrics_vs_time.png",
        "pareto.png",
    ] {
        let img = image::open(out.join(png)).unwrap_or_else(|e| panic!("{png}: {e}"));
        assert!(img.width() > 100 && img.height() > 100, "{png}");
    }
}

/// Guards `--stride`: a clip longer than T_c + T_f is scored once per window (`clip@start`,
/// starts a multiple of the stride), not only on its first frames, so bends and late events
/// in long held-out clips count.
#[test]
fn stride_scores_every_window_of_a_long_clip() {
    let dir = tempfile::tempdir().unwrap();
    let ckpt = checkpoint(dir.path());
    let data = synth_clips(dir.path(), "long", "1", "7");
    for (stride, want) in [("1", vec![0, 1, 2, 3]), ("2", vec![0, 2])] {
        let out = dir.path().join(format!("eval-{stride}"));
        let o = eval(&ckpt, &data, &out, &["--stride", stride]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let stdout = String::from_utf8_lossy(&o.stdout);
        let windows = format!("mean over {} windows of 1 clip ", want.len());
        assert!(stdout.contains(&windows), "{stdout}");
        let json: serde_json::Value =
            serde_json::from_slice(&std::fs::read(out.join("metrics.json")).unwrap()).unwrap();
        let names: Vec<String> = json["clips"]
            .as_array()
            .unwrap()
            .iter()
            .map(|c| c["clip"].as_str().unwrap().to_owned())
            .collect();
        let want: Vec<String> = want.iter().map(|k| format!("clip_000000@{k}")).collect();
        assert_eq!(names, want, "--stride {stride}");
    }
    let o = eval(&ckpt, &data, &dir.path().join("eval-0"), &["--stride", "0"]);
    assert_eq!(
        o.status.code(),
        Some(2),
        "--stride 0 must be refused by the parser"
    );
}

fn assert_input_error(o: &Output, path: &Path) {
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains(s(path)),
        "error does not name {}: {stderr}",
        path.display()
    );
}

/// Guards the bad-checkpoint errors: a missing file and a file that is not a checkpoint are
/// input errors (exit code 2) that name the path, not a panic or an internal error.
#[test]
fn bad_checkpoint_is_a_clear_input_error() {
    let dir = tempfile::tempdir().unwrap();
    let data = synth_data(dir.path());
    let missing = dir.path().join("nope.safetensors");
    let o = envision4d(&["eval", "--checkpoint", s(&missing), "--data", s(&data)]);
    assert_input_error(&o, &missing);
    let garbage = dir.path().join("garbage.safetensors");
    std::fs::write(&garbage, b"this is not a safetensors file").unwrap();
    let o = envision4d(&["eval", "--checkpoint", s(&garbage), "--data", s(&data)]);
    assert_input_error(&o, &garbage);
}

/// Guards the bad-data errors: a missing data folder and a folder without clips are input
/// errors that name the folder.
#[test]
fn bad_data_folder_is_a_clear_input_error() {
    let dir = tempfile::tempdir().unwrap();
    let ckpt = checkpoint(dir.path());
    let out = dir.path().join("eval");
    let missing = dir.path().join("no-such-data");
    let o = eval(&ckpt, &missing, &out, &[]);
    assert_input_error(&o, &missing);
    let empty = dir.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    let o = eval(&ckpt, &empty, &out, &[]);
    assert_input_error(&o, &empty);
}
