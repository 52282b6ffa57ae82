//! `envision4d demo` end to end with a freshly initialised tiny checkpoint: every printed
//! path exists, metrics.json scores the model and the three baselines, the render manifest
//! lists files that exist, a seed repeats its clip byte for byte, a missing checkpoint is an
//! input error naming the path, and with no arguments the shipped model runs.

#[path = "../../../tests/support/paths.rs"]
mod paths;

use burn::tensor::Device;
use envision4d_model::checkpoint::save_checkpoint;
use envision4d_model::Envision4d;
use envision4d_train::step::identity_pose_init;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::OnceLock;

/// Future frames of the test checkpoint (the config's T_f cut down, to keep the runs short).
const FUTURE_FRAMES: usize = 2;
const SEED: &str = "5";
const OTHER_SEED: &str = "6";
/// The shipped model, relative to the repository root.
const SHIPPED_MODEL: &str = "models/envision4d-synth-tiny.safetensors";
/// What metrics.json must score, in its order.
/// The protocol's methods; a synthetic clip has motion truth, so the oracle renders too.
const METHODS: [&str; 8] = [
    "model",
    "copy_last",
    "static_cv",
    "no_motion",
    "oracle_motion",
    "true_cameras_no_motion",
    "true_cameras",
    "true_cameras_oracle_motion",
];
/// Heading before the `  label: path` lines of stdout.
const WROTE: &str = "wrote:";

fn repo(path: &str) -> PathBuf {
    paths::manifest_dir().join("../..").join(path)
}

fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 temp path")
}

fn demo(args: &[&str], cwd: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_envision4d"))
        .arg("demo")
        .args(args)
        .current_dir(cwd)
        .output()
        .expect("run envision4d demo")
}

fn text(o: &Output) -> (String, String) {
    (
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// A scratch folder shared by this file's tests (recreated once per test run).
fn scratch() -> &'static PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join("demo");
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    })
}

/// configs/synth-tiny.toml's model, randomly initialised at the identity pose (so renders
/// see the scene), saved as our checkpoint with its config.
fn checkpoint() -> &'static PathBuf {
    static CKPT: OnceLock<PathBuf> = OnceLock::new();
    CKPT.get_or_init(|| {
        let mut cfg = envision4d_train::load(&repo("configs/synth-tiny.toml"))
            .unwrap()
            .model;
        cfg.future_frames = FUTURE_FRAMES;
        let mut model = Envision4d::new(&cfg, &Device::flex());
        identity_pose_init(&mut model);
        let path = scratch().join("tiny.safetensors");
        save_checkpoint(&model, &cfg, &path).unwrap();
        path
    })
}

/// `demo --checkpoint C --seed SEED --out scratch/NAME`, asserted to succeed; returns the
/// out folder and stdout.
fn run_demo(seed: &str, name: &str) -> (PathBuf, String) {
    let out = scratch().join(name);
    let o = demo(
        &[
            "--checkpoint",
            s(checkpoint()),
            "--seed",
            seed,
            "--out",
            s(&out),
        ],
        scratch(),
    );
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stderr}\n{stdout}");
    (out, stdout)
}

/// The seed-5 run, shared by the tests that inspect it.
fn first_run() -> &'static (PathBuf, String) {
    static RUN: OnceLock<(PathBuf, String)> = OnceLock::new();
    RUN.get_or_init(|| run_demo(SEED, "seed5-a"))
}

/// The `  label: path` lines after `wrote:`.
fn printed_paths(stdout: &str) -> BTreeMap<String, PathBuf> {
    stdout
        .lines()
        .skip_while(|l| l.trim() != WROTE)
        .skip(1)
        .filter_map(|l| l.trim_start().split_once(": "))
        .map(|(label, path)| (label.to_owned(), PathBuf::from(path)))
        .collect()
}

/// Every PNG of a clip folder, by path relative to it.
fn clip_pngs(clip: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut files = BTreeMap::new();
    let mut stack = vec![clip.to_path_buf()];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).unwrap() {
            let p = entry.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|e| e == "png") {
                let rel = p.strip_prefix(clip).unwrap().to_path_buf();
                files.insert(rel, std::fs::read(&p).unwrap());
            }
        }
    }
    files
}

/// Guards the demo's promise to print where everything went and to write what it printed:
/// every printed path exists, the seed is shown for repeating the run, metrics.json holds
/// the model and the three baselines, and render/manifest.json lists only existing files.
#[test]
fn demo_writes_everything_it_prints() {
    let (out, stdout) = first_run();
    assert!(stdout.contains(&format!("--seed {SEED}")), "{stdout}");
    assert!(
        stdout.contains("PSNR") && stdout.contains("encoder"),
        "{stdout}"
    );
    let paths = printed_paths(stdout);
    for label in [
        "clip",
        "metrics.json",
        "metrics.md",
        "render",
        "manifest.json",
    ] {
        assert!(
            paths.contains_key(label),
            "stdout lacks {label:?}:\n{stdout}"
        );
    }
    for (label, path) in &paths {
        assert!(path.exists(), "{label}: {} does not exist", path.display());
    }
    assert!(paths["clip"].join("rgb").is_dir());

    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&paths["metrics.json"]).unwrap()).unwrap();
    assert_eq!(json["clips_evaluated"], 1);
    let methods: Vec<&str> = json["clips"][0]["methods"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m["method"].as_str().unwrap())
        .collect();
    assert_eq!(methods, METHODS);
    // The generator's truth has poses, so every method has pose errors.
    assert!(json["mean"]["methods"][0]["rot_err_deg"].is_number());

    let manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&paths["manifest.json"]).unwrap()).unwrap();
    let files = manifest["files"].as_array().unwrap();
    assert!(!files.is_empty());
    for f in files {
        let rel = f["path"].as_str().unwrap();
        assert!(
            out.join("render").join(rel).is_file(),
            "manifest lists missing {rel}"
        );
    }
}

/// Guards `--seed` as the way to repeat a run: the same seed gives byte-identical clip PNGs
/// (frames, masks, instances), and another seed gives another clip.
#[test]
fn same_seed_repeats_the_clip() {
    let clip = |out: &Path| clip_pngs(&out.join("clip").join("clip_000000"));
    let (first, _) = first_run();
    let (again, _) = run_demo(SEED, "seed5-b");
    let (a, b) = (clip(first), clip(&again));
    assert!(!a.is_empty());
    assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>());
    for (name, bytes) in &a {
        assert!(bytes == &b[name], "{} differs between runs", name.display());
    }
    let (other, _) = run_demo(OTHER_SEED, "seed6");
    let rgb = Path::new("rgb").join("000000.png");
    assert_ne!(
        a[&rgb],
        clip(&other)[&rgb],
        "seed {OTHER_SEED} repeats seed {SEED}'s clip"
    );
}

/// Guards the missing-checkpoint error: an absent `--checkpoint` is an input error (exit
/// code 2) naming the path, not a panic or an internal error.
#[test]
fn missing_checkpoint_is_an_input_error() {
    let missing = scratch().join("nope.safetensors");
    let o = demo(&["--checkpoint", s(&missing)], scratch());
    let (_, stderr) = text(&o);
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains(s(&missing)),
        "error does not name the path: {stderr}"
    );
}

/// Guards a GPU backend the binary lacks (or cannot start): an input error (exit code 2)
/// saying how to get it, raised before the output folder exists, not a panic mid-run. A
/// CUDA build on a machine without the NVIDIA driver must name the driver the same way
/// (cudarc panics when it cannot load libcuda; the probe must catch that); with a driver,
/// the demo runs.
#[test]
fn unavailable_backend_is_an_input_error_before_any_output() {
    let out = scratch().join("no-cuda");
    let o = demo(&["--backend", "cuda", "--out", s(&out)], scratch());
    let (stdout, stderr) = text(&o);
    if cfg!(feature = "cuda") && o.status.success() {
        assert!(out.is_dir(), "CUDA ran but wrote nothing: {stdout}");
        return;
    }
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    let way_out = if cfg!(feature = "cuda") {
        "libcuda.so.1"
    } else {
        "--features cuda"
    };
    assert!(stderr.contains(way_out), "no way out named: {stderr}");
    assert!(!stderr.contains("panicked"), "a panic leaked: {stderr}");
    assert!(
        !out.exists(),
        "the demo wrote {} before failing",
        out.display()
    );
}

/// Guards the README's first command, `envision4d demo` with no arguments: the shipped model
/// is in the repository, and the demo runs with it from any folder and writes what it prints.
#[test]
fn no_arguments_use_the_shipped_model() {
    assert!(
        repo(SHIPPED_MODEL).is_file(),
        "{SHIPPED_MODEL} is missing: it ships with the repository (docs/TRAINING.md)"
    );
    let cwd = scratch().join("no-args");
    std::fs::create_dir_all(&cwd).unwrap();
    let o = demo(&[], &cwd);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stderr}\n{stdout}");
    let printed = printed_paths(&stdout);
    assert!(!printed.is_empty(), "{stdout}");
    for (label, path) in printed {
        assert!(
            cwd.join(&path).exists(),
            "{label}: {} does not exist",
            path.display()
        );
    }
}
