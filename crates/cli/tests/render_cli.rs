//! `envision4d render --export-predictions` end to end: parity with the reference through the
//! binary, real frame folders, and bad inputs (exit code 2, named problem).

#[path = "../../../tests/support/paths.rs"]
mod paths;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn fixture() -> PathBuf {
    paths::manifest_dir().join("../../../shared/fixtures/envision4d_tiny.safetensors")
}

fn render(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_envision4d"))
        .arg("render")
        .args(args)
        .output()
        .expect("run envision4d")
}

fn read_f32(bytes: &[u8], key: &str) -> (Vec<usize>, Vec<f32>) {
    let st = safetensors::SafeTensors::deserialize(bytes).unwrap();
    let t = st.tensor(key).unwrap_or_else(|_| panic!("missing {key}"));
    (
        t.shape().to_vec(),
        t.data()
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect(),
    )
}

/// `render` of the fixture's weights and exact float input into `out`, with `extra`
/// arguments.
fn render_fixture(out: &Path, extra: &[&str]) -> Output {
    let fx = fixture();
    assert!(fx.is_file(), "fixture {} is required", fx.display());
    let input = format!("{}:input/images", fx.display());
    let mut args = vec![
        "--weights",
        fx.to_str().unwrap(),
        "--weights-prefix",
        "weights/",
        "--model-config",
        "tiny",
        "--input-tensor",
        &input,
        "--export-predictions",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    render(&args)
}

/// The predictions `render --export-predictions` writes for the fixture, with `extra`
/// arguments.
fn export_fixture(extra: &[&str]) -> Vec<u8> {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("preds.safetensors");
    let o = render_fixture(&out, extra);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    std::fs::read(&out).unwrap()
}

/// Exported keys with the worst `|diff|` against their references and `max|ref|`.
fn errors_against_reference(got: &[u8]) -> Vec<(&'static str, f32, f32)> {
    let want = std::fs::read(fixture()).unwrap();
    [
        "pose_enc",
        "depth",
        "depth_conf",
        "gaussians",
        "motion_enc",
        "adapter/extrinsics",
        "adapter/intrinsics",
        "adapter/means",
        "adapter/scales",
        "adapter/rotations",
        "adapter/colors",
        "adapter/opacities",
        "adapter/motions",
    ]
    .into_iter()
    .map(|key| {
        let (gs, g) = read_f32(got, key);
        let (ws, w) = read_f32(&want, &format!("expected/{key}"));
        assert_eq!(gs, ws, "{key} shape");
        let scale = w.iter().fold(0.0f32, |m, v| m.max(v.abs()));
        let worst = g
            .iter()
            .zip(&w)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f32, |m, d| if d.is_nan() { f32::NAN } else { m.max(d) });
        (key, worst, scale)
    })
    .collect()
}

/// Guards the CLI's prediction export: with the fixture's weights and exact float input, every
/// exported tensor equals the reference's under the fixture's key names.
#[test]
fn exported_predictions_match_reference() {
    for (key, worst, scale) in errors_against_reference(&export_fixture(&[])) {
        assert!(
            worst <= 1e-4 * scale + 1e-5,
            "{key}: max diff {worst} (max|ref| {scale})"
        );
    }
}

/// Guards `render --precision f16` end to end: the aggregator really runs in f16 (some
/// output moves beyond f32's error) and every export stays within 1e-2 of the reference;
/// bf16 on wgpu, whose shading language has no bf16, is an exit-2 error naming it.
#[test]
fn precision_f16_exports_near_the_reference_and_bf16_on_wgpu_is_refused() {
    let errs = errors_against_reference(&export_fixture(&["--precision", "f16"]));
    for (key, worst, scale) in &errs {
        assert!(
            *worst < 1e-2 * scale,
            "f16 {key}: max diff {worst} (max|ref| {scale})"
        );
    }
    assert!(errs.iter().any(|(_, w, s)| *w > 1e-4 * s), "{errs:?}");
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("unused.safetensors");
    let o = render_fixture(&out, &["--backend", "wgpu", "--precision", "bf16"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("--precision bf16"), "{err}");
}

fn write_png(path: &Path, w: u32, h: u32, seed: u8) {
    let img = image::RgbImage::from_fn(w, h, |x, y| {
        image::Rgb([
            (x as u8).wrapping_mul(3).wrapping_add(seed),
            (y as u8).wrapping_mul(5),
            seed,
        ])
    });
    img.save(path).unwrap();
}

/// Guards the frame-folder path: real PNGs of another size are resized (with a note) and the
/// export has the model's shapes; too few frames and a missing config are exit-2 errors.
#[test]
fn frame_folder_and_bad_inputs() {
    let fx = fixture();
    let dir = tempfile::tempdir().unwrap();
    let frames = dir.path().join("frames");
    std::fs::create_dir(&frames).unwrap();
    write_png(&frames.join("frame_000000.png"), 100, 70, 10);
    write_png(&frames.join("frame_000001.png"), 100, 70, 90);
    let out = dir.path().join("p.safetensors");
    let base = [
        "--weights",
        fx.to_str().unwrap(),
        "--weights-prefix",
        "weights/",
        "--model-config",
        "tiny",
        "--export-predictions",
        out.to_str().unwrap(),
    ];
    let mut args = base.to_vec();
    args.extend(["--frames", frames.to_str().unwrap()]);
    let o = render(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stderr).contains("resized"));
    let (shape, _) = read_f32(&std::fs::read(&out).unwrap(), "adapter/means");
    assert_eq!(shape, vec![1, 2, 56 * 84, 3]);

    let one = dir.path().join("one");
    std::fs::create_dir(&one).unwrap();
    write_png(&one.join("a.png"), 84, 56, 1);
    let mut args = base.to_vec();
    args.extend(["--frames", one.to_str().unwrap()]);
    let o = render(&args);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("need 2 context frames"));

    let o = render(&[
        "--weights",
        fx.to_str().unwrap(),
        "--frames",
        frames.to_str().unwrap(),
        "--export-predictions",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--model-config"));

    // A config whose widths do not fit the weights: every mis-shaped key is listed.
    let toml = dir.path().join("m.toml");
    std::fs::write(
        &toml,
        "[model]\npreset = \"tiny\"\n[model.dpt]\nfeatures = 16\nout_channels = [16, 32, 64, 64]\n",
    )
    .unwrap();
    let o = render(&[
        "--weights",
        fx.to_str().unwrap(),
        "--weights-prefix",
        "weights/",
        "--model-config",
        toml.to_str().unwrap(),
        "--frames",
        frames.to_str().unwrap(),
        "--export-predictions",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&o.stderr)
            .matches("mis-shaped")
            .count()
            > 10
    );
}

/// Guards `envision4d train --dry-run`: the shipped tiny config resolves and builds with a
/// parameter count, and a typo in a config is an exit-2 error naming the key.
#[test]
fn train_dry_run_and_config_typo() {
    let cfg = paths::manifest_dir().join("../../configs/synth-tiny.toml");
    let o = Command::new(env!("CARGO_BIN_EXE_envision4d"))
        .args(["train", "--config", cfg.to_str().unwrap(), "--dry-run"])
        .output()
        .unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(out.contains("trainable") && out.contains("frozen"), "{out}");

    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.toml");
    let text = std::fs::read_to_string(&cfg).unwrap();
    let first_key = text
        .lines()
        .find(|l| l.contains(" = "))
        .unwrap()
        .split(" = ")
        .next()
        .unwrap()
        .trim()
        .to_owned();
    std::fs::write(
        &bad,
        text.replacen(&format!("{first_key} = "), &format!("{first_key}x = "), 1),
    )
    .unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_envision4d"))
        .args(["train", "--config", bad.to_str().unwrap(), "--dry-run"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains(&format!("{first_key}x")),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
}

/// A Waymo-layout tree under `dir/waymo` (scene 000 of each split, frames 0..=last at 56x84)
/// and the text of `configs/synth-tiny.toml` pointed at it.
fn waymo_tree_config(dir: &Path, splits: &[&str], last: u32) -> String {
    for split in splits {
        let images = dir.join(format!("waymo/{split}/000/images"));
        std::fs::create_dir_all(&images).unwrap();
        for t in 0..=last {
            write_png(&images.join(format!("{t:06}_0.png")), 84, 56, t as u8);
        }
    }
    std::fs::read_to_string(paths::manifest_dir().join("../../configs/synth-tiny.toml"))
        .unwrap()
        .replace("layout = \"synth\"", "layout = \"waymo\"")
        .replace(
            "root = \"data/synth-train\"",
            &format!("root = {:?}", dir.join("waymo")),
        )
}

/// Guards the Waymo training split: `--dry-run` says what the run will read (split, windows,
/// scenes, frames, ground truth), and a config that would train on the validation split is
/// an exit-2 error naming `data.split` and the way out.
#[test]
fn train_dry_run_reads_the_training_split_and_refuses_validation() {
    let dir = tempfile::tempdir().unwrap();
    let base = waymo_tree_config(dir.path(), &["training", "validation"], 12);
    let run = |extra: &str| {
        let cfg = dir.path().join("cfg.toml");
        std::fs::write(&cfg, base.replace("[data]\n", &format!("[data]\n{extra}"))).unwrap();
        Command::new(env!("CARGO_BIN_EXE_envision4d"))
            .args(["train", "--config", cfg.to_str().unwrap(), "--dry-run"])
            .output()
            .unwrap()
    };
    let o = run("");
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // 12 listed timesteps, windows of 8 frames every 2 (synth-tiny's stride): starts 0, 2, 4.
    assert!(out.contains("split \"training\""), "{out}");
    assert!(
        out.contains("windows: 3 from 1 scene(s), 8 frames each"),
        "{out}"
    );
    assert!(out.contains("poses no"), "{out}");
    let o = run("split = \"validation\"\n");
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("data.split") && err.contains("allow_eval_split"),
        "{err}"
    );
    let o = run("split = \"validation\"\nallow_eval_split = true\n");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// Guards `eval --list-windows` on the Waymo layout: the release's clips of `validation/`
/// (starts 0, 15, 30; the first T_c frames are context, the rest scored), `--future 2`
/// and the named protocols scoring 2 (paper) or 4 (release) future frames, a contradicting
/// `--future` refused, and no output folder written.
#[test]
fn eval_lists_the_release_windows() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("cfg.toml");
    std::fs::write(&cfg, waymo_tree_config(dir.path(), &["validation"], 40)).unwrap();
    let ckpt = paths::manifest_dir().join("../../models/envision4d-synth-tiny.safetensors");
    let out = dir.path().join("eval-out");
    let list = |extra: &[&str]| {
        let mut args = vec![
            "eval",
            "--checkpoint",
            ckpt.to_str().unwrap(),
            "--config",
            cfg.to_str().unwrap(),
            "--split",
            "all",
            "--out",
            out.to_str().unwrap(),
            "--list-windows",
        ];
        args.extend_from_slice(extra);
        let o = Command::new(env!("CARGO_BIN_EXE_envision4d"))
            .args(&args)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stdout).into_owned()
    };
    assert_eq!(
        list(&[]).lines().collect::<Vec<_>>(),
        [
            "validation/000 start=0 context=0,1 scored=2,3,4,5,6,7",
            "validation/000 start=15 context=15,16 scored=17,18,19,20,21,22",
            "validation/000 start=30 context=30,31 scored=32,33,34,35,36,37",
        ]
    );
    assert!(list(&["--future", "2"]).starts_with("validation/000 start=0 context=0,1 scored=2,3\n"));
    assert!(list(&["--protocol", "paper"])
        .starts_with("validation/000 start=0 context=0,1 scored=2,3\n"));
    assert!(list(&["--protocol", "release"])
        .starts_with("validation/000 start=0 context=0,1 scored=2,3,4,5\n"));
    // A horizon that contradicts the protocol is an input error naming both.
    let o = Command::new(env!("CARGO_BIN_EXE_envision4d"))
        .args([
            "eval",
            "--checkpoint",
            ckpt.to_str().unwrap(),
            "--config",
            cfg.to_str().unwrap(),
        ])
        .args(["--protocol", "paper", "--future", "3", "--list-windows"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("--future 3") && err.contains("--protocol paper"),
        "{err}"
    );
    assert!(!out.exists(), "--list-windows must not write outputs");
}
