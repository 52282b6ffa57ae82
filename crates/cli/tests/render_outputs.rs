//! `envision4d render --out` end to end with one of our own checkpoints (a tiny model with an
//! identity pose start, saved with its config): every file of the manifest exists and decodes,
//! a written PLY renders through `envision4d splat` to our own render of that step, and bad
//! checkpoints, frame folders and options exit with code 2 naming the problem.

#[path = "../../../tests/support/paths.rs"]
mod paths;

use burn::tensor::Device;
use envision4d_model::checkpoint::save_checkpoint;
use envision4d_model::Envision4d;
use envision4d_splat::camera_json::read_camera_json;
use envision4d_splat::ply::read_ply;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::OnceLock;

/// Future frames rendered by the full run (at most the config's T_f).
const FUTURE: usize = 2;
const LANE_SHIFTS: [&str; 2] = ["0.5", "-0.5"];
/// Largest difference between `envision4d splat` of a written PLY and our render: the PLY
/// stores logit opacity, log scales and SH DC in f32, so a few ulps per value are expected
/// (measured: 5e-7). A wrong quaternion order gives 1e-2.
const ROUND_TRIP_TOLERANCE: f32 = 1e-4;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_envision4d"))
}

fn run(sub: &str, args: &[&str]) -> Output {
    bin().arg(sub).args(args).output().expect("run envision4d")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).to_string()
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// A scratch folder shared by this file's tests (recreated once per test run).
fn scratch() -> &'static PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join("render_outputs");
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    })
}

/// A checkpoint of configs/synth-tiny.toml's model and frames of one synthetic clip.
struct Inputs {
    ckpt: PathBuf,
    frames: PathBuf,
    context: usize,
    future: usize,
    /// Model image size (H, W).
    size: (u32, u32),
}

/// The tiny checkpoint (identity pose start, so the renders see the scene) and a synthetic
/// clip at the model size, made once. Counts come from the config, which may change.
fn inputs() -> &'static Inputs {
    static INPUTS: OnceLock<Inputs> = OnceLock::new();
    INPUTS.get_or_init(|| {
        let dir = scratch();
        let cfg_path = paths::manifest_dir().join("../../configs/synth-tiny.toml");
        let cfg = envision4d_train::load(&cfg_path).unwrap().model;
        assert!(
            cfg.future_frames >= FUTURE,
            "the tests render {FUTURE} future frames"
        );
        // Seeded: unseeded weights made a new scene every run, and one full-suite run saw a
        // 1.5e-3 round-trip difference, most likely a Gaussian on the 1/255 alpha cut-off
        // that the PLY's f32 logit opacity flips in or out of a pixel.
        let device = Device::flex();
        let mut model = envision4d_model::seeded::seeded(&device, 2024, || {
            Ok::<_, std::convert::Infallible>(Envision4d::new(&cfg, &device))
        })
        .unwrap();
        envision4d_train::step::identity_pose_init(&mut model);
        let ckpt = dir.join("tiny.safetensors");
        save_checkpoint(&model, &cfg, &ckpt).unwrap();
        let synth = dir.join("synth");
        let [h, w] = cfg.image_size;
        let (size, frames) = (format!("{h}x{w}"), (cfg.context_frames + 2).to_string());
        let args = [
            "--out",
            s(&synth),
            "--clips",
            "1",
            "--frames",
            &frames,
            "--size",
            &size,
        ];
        let o = run("synth", &args);
        assert!(o.status.success(), "{}", stderr(&o));
        Inputs {
            ckpt,
            frames: synth.join("clip_000000/rgb"),
            context: cfg.context_frames,
            future: cfg.future_frames,
            size: (h as u32, w as u32),
        }
    })
}

/// One full render (every output, two lane shifts) shared by the tests that inspect it.
fn full_render() -> &'static PathBuf {
    static OUT: OnceLock<PathBuf> = OnceLock::new();
    OUT.get_or_init(|| {
        let inp = inputs();
        let out = scratch().join("full");
        let future = FUTURE.to_string();
        let mut args = vec!["--checkpoint", s(&inp.ckpt), "--frames", s(&inp.frames)];
        args.extend(["--future", &future, "--out", s(&out), "--outputs", "all"]);
        for shift in LANE_SHIFTS {
            args.extend(["--lane-shift", shift]);
        }
        let o = run("render", &args);
        assert!(o.status.success(), "{}", stderr(&o));
        out
    })
}

fn manifest(out: &Path) -> Vec<(String, String, Option<String>)> {
    let text = std::fs::read_to_string(out.join("manifest.json")).unwrap();
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    json["files"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| {
            (
                f["path"].as_str().unwrap().to_owned(),
                f["kind"].as_str().unwrap().to_owned(),
                f["step"].as_str().map(str::to_owned),
            )
        })
        .collect()
}

/// All channels of an EXR file by name, with its size.
fn read_exr(path: &Path) -> ((usize, usize), Vec<(String, Vec<f32>)>) {
    let img = exr::prelude::read_first_flat_layer_from_file(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let size = img.layer_data.size;
    let channels = img
        .layer_data
        .channel_data
        .list
        .iter()
        .map(|c| (c.name.to_string(), c.sample_data.values_as_f32().collect()))
        .collect();
    ((size.width(), size.height()), channels)
}

fn channel<'a>(channels: &'a [(String, Vec<f32>)], name: &str) -> &'a [f32] {
    &channels.iter().find(|(n, _)| n == name).unwrap().1
}

/// Decodes one output by extension; panics naming the file when it does not decode.
fn check_decodes(path: &Path) {
    let size = inputs().size;
    let ext = path.extension().unwrap().to_str().unwrap();
    match ext {
        "png" => {
            let img = image::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            assert_eq!((img.height(), img.width()), size, "{}", path.display());
        }
        "exr" => {
            let ((w, h), channels) = read_exr(path);
            assert_eq!((h as u32, w as u32), size, "{}", path.display());
            assert!(
                channels
                    .iter()
                    .all(|(_, v)| v.iter().all(|x| x.is_finite())),
                "{}",
                path.display()
            );
        }
        "ply" => assert!(!read_ply(path).unwrap().is_empty(), "{}", path.display()),
        "json" if path.parent().unwrap().ends_with("cameras") => {
            read_camera_json(path).unwrap();
        }
        "json" => {
            serde_json::from_str::<serde_json::Value>(&std::fs::read_to_string(path).unwrap())
                .unwrap();
        }
        other => panic!("unexpected output type {other}: {}", path.display()),
    }
}

/// Guards the `--out` contract: every output kind is written for every step (context views,
/// the requested future views, lane shifts, motion of the context frames), listed in the
/// manifest, and decodes at the model size; poses.json marks roles.
#[test]
fn all_outputs_exist_and_decode() {
    let out = full_render();
    let files = manifest(out);
    for (path, _, _) in &files {
        check_decodes(&out.join(path));
    }
    let count = |kind: &str| files.iter().filter(|(_, k, _)| k == kind).count();
    let (tc, lanes) = (inputs().context, LANE_SHIFTS.len());
    let steps = tc + FUTURE;
    // PNG + EXR for colour; every lane shift on every future step; motion per context frame.
    assert_eq!(count("rgb"), 2 * steps);
    assert_eq!(count("depth"), steps);
    assert_eq!(count("depth_color"), steps);
    assert_eq!(count("dynamic_mask"), tc);
    assert_eq!(count("scene_flow"), tc);
    assert_eq!(count("scene_flow_color"), tc);
    assert_eq!(count("lane_shift_rgb"), 2 * FUTURE * lanes);
    assert_eq!(count("gaussians"), steps);
    assert_eq!(count("camera"), steps + FUTURE * lanes);
    assert_eq!(count("poses"), 1);
    for name in [
        "views/future_01.png",
        "lane_shift/future_00_lane-0.50.exr",
        "motion/context_01_flow.exr",
    ] {
        assert!(files.iter().any(|(p, _, _)| p == name), "{name} missing");
    }
    let flow = read_exr(&out.join("motion/context_00_flow.exr")).1;
    let names: Vec<&str> = flow.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names.len(), 3, "{names:?}");
    let poses: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("poses.json")).unwrap()).unwrap();
    let roles: Vec<&str> = poses["frames"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["role"].as_str().unwrap())
        .collect();
    let want: Vec<&str> = [vec!["context"; tc], vec!["future"; inputs().future]].concat();
    assert_eq!(roles, want);
    // The rendered views must show something, or the round trip below proves little.
    let rgb = read_exr(&out.join("views/future_00.exr")).1;
    assert!(
        channel(&rgb, "R").iter().any(|&v| v > 0.01),
        "future_00 is blank"
    );
}

/// Guards the PLY layout and rotation convention: a written PLY rendered by `envision4d splat`
/// from the written camera equals our render of that step (context and future, lane shift).
#[test]
fn ply_round_trips_through_splat() {
    let out = full_render();
    let dir = scratch().join("round_trip");
    std::fs::create_dir_all(&dir).unwrap();
    let cases = [
        ("context_01", "context_01", "views/context_01.exr"),
        ("future_01", "future_01", "views/future_01.exr"),
        (
            "future_00",
            "future_00_lane+0.50",
            "lane_shift/future_00_lane+0.50.exr",
        ),
    ];
    for (ply, camera, ours) in cases {
        let img = dir.join(format!("{camera}.exr"));
        let ply_path = out.join(format!("gaussians/{ply}.ply"));
        let cam_path = out.join(format!("cameras/{camera}.json"));
        let o = run(
            "splat",
            &[
                "--ply",
                s(&ply_path),
                "--camera",
                s(&cam_path),
                "--out",
                s(&img),
            ],
        );
        assert!(o.status.success(), "{}", stderr(&o));
        let (theirs, ours) = (read_exr(&img).1, read_exr(&out.join(ours)).1);
        for c in ["R", "G", "B"] {
            let worst = channel(&theirs, c)
                .iter()
                .zip(channel(&ours, c))
                .map(|(a, b)| (a - b).abs())
                .fold(0.0f32, f32::max);
            assert!(
                worst <= ROUND_TRIP_TOLERANCE,
                "{camera} {c}: max diff {worst}"
            );
        }
    }
}

fn write_png(path: &Path, w: u32, h: u32, seed: u8) {
    image::RgbImage::from_fn(w, h, |x, y| {
        image::Rgb([
            (x as u8).wrapping_mul(7).wrapping_add(seed),
            (y as u8).wrapping_mul(3),
            seed,
        ])
    })
    .save(path)
    .unwrap();
}

/// Guards arbitrary frame folders: frames of another size are resized with a note, `--start`
/// picks the window, and a poses-only request writes poses without rendering anything.
#[test]
fn resized_frames_and_poses_only() {
    let inp = inputs();
    let dir = scratch().join("odd_size");
    let frames = dir.join("frames");
    std::fs::create_dir_all(&frames).unwrap();
    for i in 0..=inp.context {
        write_png(&frames.join(format!("img_{i}.png")), 131, 47, 50 * i as u8);
    }
    std::fs::write(frames.join("notes.txt"), "not a frame").unwrap();
    let out = dir.join("out");
    let mut args = vec![
        "--checkpoint",
        s(&inp.ckpt),
        "--frames",
        s(&frames),
        "--start",
        "1",
    ];
    args.extend(["--future", "1", "--out", s(&out), "--outputs", "poses"]);
    let o = run("render", &args);
    assert!(o.status.success(), "{}", stderr(&o));
    let err = stderr(&o);
    let note = format!("resized to the model size {}x{}", inp.size.0, inp.size.1);
    assert!(err.contains(&note) && err.contains("131"), "{err}");
    let files = manifest(&out);
    assert!(
        files.iter().all(|(_, k, _)| k == "camera" || k == "poses"),
        "{files:?}"
    );
    // One camera per context frame and one future camera, no lane shifts, poses.json.
    assert_eq!(files.len(), inp.context + 2, "{files:?}");
    assert!(!out.join("views").exists());
    for (p, _, _) in &files {
        check_decodes(&out.join(p));
    }
}

/// Guards the error paths: an unreadable, corrupt or config-less checkpoint, a missing,
/// empty or corrupt frame folder, an out-of-range --future and a file as --out all exit with
/// code 2 and name the path (or option) at fault.
#[test]
fn bad_inputs_exit_2_naming_the_path() {
    let inp = inputs();
    let (ckpt, frames) = (&inp.ckpt, &inp.frames);
    let dir = scratch().join("bad");
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("out");
    let garbage = dir.join("garbage.safetensors");
    std::fs::write(&garbage, b"this is not a checkpoint").unwrap();
    let no_config = dir.join("no_config.safetensors");
    let tensor =
        safetensors::tensor::TensorView::new(safetensors::Dtype::F32, vec![1], &[0u8; 4]).unwrap();
    safetensors::tensor::serialize_to_file([("x", tensor)], None, &no_config).unwrap();
    let missing = dir.join("missing.safetensors");
    for bad in [&missing, &garbage, &no_config] {
        expect_input_error(bad, frames, &["--out", s(&out)], s(bad));
    }

    let empty = dir.join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    let corrupt = dir.join("corrupt");
    std::fs::create_dir_all(&corrupt).unwrap();
    for i in 1..inp.context {
        let name = format!("{i:06}.png");
        std::fs::copy(frames.join(&name), corrupt.join(&name)).unwrap();
    }
    // Sorted last, so every other frame decodes first.
    let broken = corrupt.join("zz.png");
    std::fs::write(&broken, b"\x89PNG\r\n\x1a\n truncated").unwrap();
    let no_folder = dir.join("no_such_folder");
    for (folder, named) in [
        (&no_folder, &no_folder),
        (&empty, &empty),
        (&corrupt, &broken),
    ] {
        expect_input_error(ckpt, folder, &["--out", s(&out)], s(named));
    }

    let too_many = (inp.future + 1).to_string();
    let args = ["--future", &too_many, "--out", s(&out)];
    expect_input_error(ckpt, frames, &args, &format!("use 1..={}", inp.future));
    expect_input_error(ckpt, frames, &["--out", s(&garbage)], s(&garbage));
    expect_input_error(ckpt, frames, &[], "--out");
}

/// Runs `render --checkpoint ckpt --frames frames EXTRA`; expects exit 2 naming `named`.
fn expect_input_error(ckpt: &Path, frames: &Path, extra: &[&str], named: &str) {
    let args = [&["--checkpoint", s(ckpt), "--frames", s(frames)][..], extra].concat();
    let o = run("render", &args);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
    assert!(err.contains(named), "{args:?}: {named:?} not in {err}");
}
