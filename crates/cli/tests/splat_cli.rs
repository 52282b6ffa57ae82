//! `envision4d splat` end to end: real files in, images out, and every bad-input case exits
//! with code 2 and a message naming the problem, without writing the output.

#[path = "../../../tests/support/paths.rs"]
mod paths;

use burn::tensor::Device;
use envision4d_splat::ply::{write_ply, PlyGaussians, RenderParams};
use envision4d_splat::testkit::{random_scene, SceneSpec};
use envision4d_splat::{render, Cameras, Gaussians, RasterConfig};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_envision4d"))
}

fn repo_file(rel: &str) -> PathBuf {
    paths::manifest_dir().join("../..").join(rel)
}

fn splat(args: &[&str]) -> Output {
    let mut cmd = bin();
    cmd.arg("splat").args(args);
    cmd.output().expect("run envision4d")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).to_string()
}

const CAMERA: &str = r#"{"width": 64, "height": 48, "fx": 50.0, "fy": 50.0, "cx": 32.0, "cy": 24.0,
 "world_to_camera": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}"#;

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn random_ply(dir: &Path, n: usize) -> (PathBuf, RenderParams) {
    let scene = random_scene(n, 99, SceneSpec::default());
    let [means, quats, scales, opacities, colors] = scene.to_f32();
    let params = RenderParams {
        means,
        quats,
        scales,
        opacities,
        colors,
    };
    let ply = PlyGaussians::from_render_params(&params).unwrap();
    let path = dir.join("scene.ply");
    write_ply(&path, &ply).unwrap();
    // Activations are re-applied on read: use what the file really encodes as the reference.
    (path, ply.to_render_params())
}

/// Guards the README's first command: the bundled example renders to a decodable PNG, and the
/// depth/alpha EXRs are finite.
#[test]
fn example_scene_renders_png_and_exr() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("ex.png");
    let depth = dir.path().join("depth.exr");
    let alpha = dir.path().join("alpha.exr");
    let o = splat(&[
        "--ply",
        repo_file("examples/scene.ply").to_str().unwrap(),
        "--camera",
        repo_file("examples/camera.json").to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--depth",
        depth.to_str().unwrap(),
        "--alpha",
        alpha.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let img = image::open(&out).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (518, 350));
    // The road (bottom rows) is grey and lit; the sky (top row) is the black background.
    assert!(img.get_pixel(259, 340)[0] > 40);
    assert_eq!(img.get_pixel(259, 2)[0], 0);
    let d = exr::prelude::read_first_flat_layer_from_file(&depth).unwrap();
    assert_eq!(d.layer_data.size.width(), 518);
}

/// Guards the PLY → activations → render chain: the CLI's linear EXR equals a direct library
/// render of the same activated parameters.
#[test]
fn cli_exr_equals_library_render() {
    let dir = tempfile::tempdir().unwrap();
    let (ply, params) = random_ply(dir.path(), 300);
    let cam = write(dir.path(), "cam.json", CAMERA);
    let out = dir.path().join("out.exr");
    let o = splat(&[
        "--ply",
        ply.to_str().unwrap(),
        "--camera",
        cam.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--background",
        "0.1,0.2,0.3",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));

    let device = Device::flex();
    let g = Gaussians::from_host(
        params.means,
        params.quats,
        params.scales,
        params.opacities,
        params.colors,
        &device,
    )
    .unwrap();
    let identity = [
        [1.0, 0.0, 0.0, 0.0],
        [0.0, 1.0, 0.0, 0.0],
        [0.0, 0.0, 1.0, 0.0],
        [0.0, 0.0, 0.0, 1.0],
    ];
    let k = [[50.0, 0.0, 32.0], [0.0, 50.0, 24.0], [0.0, 0.0, 1.0]];
    let c = Cameras::from_host(&[identity], &[k], 64, 48, &device);
    let cfg = RasterConfig {
        background: Some([0.1, 0.2, 0.3]),
        ..Default::default()
    };
    let want = render(&g, &c, &cfg)
        .unwrap()
        .rgb
        .into_data()
        .convert::<f32>()
        .try_into_vec::<f32>()
        .unwrap();

    let img = exr::prelude::read_first_rgba_layer_from_file(
        &out,
        |res, _| vec![[0f32; 3]; res.width() * res.height()],
        |px: &mut Vec<[f32; 3]>, pos, (r, g, b, _a): (f32, f32, f32, f32)| {
            px[pos.y() * 64 + pos.x()] = [r, g, b];
        },
    )
    .unwrap();
    let got: Vec<f32> = img
        .layer_data
        .channel_data
        .pixels
        .iter()
        .flatten()
        .copied()
        .collect();
    assert_eq!(got.len(), want.len());
    let worst = got
        .iter()
        .zip(&want)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0f32, f32::max);
    assert!(
        worst == 0.0,
        "EXR differs from the library render by {worst}"
    );
}

/// Guards bad-input handling: each case exits 2, names the problem, and writes nothing.
#[test]
fn bad_inputs_exit_2_with_a_named_problem() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (ply, _) = random_ply(d, 10);
    let good_cam = write(d, "good.json", CAMERA);
    let out = d.join("out.png");
    let ply_s = ply.to_str().unwrap().to_owned();
    let cam_s = good_cam.to_str().unwrap().to_owned();

    let garbage = write(d, "garbage.ply", "this is not a ply file");
    let header_only = write(
        d,
        "trunc.ply",
        "ply\nformat binary_little_endian 1.0\nelement vertex 5\nproperty float x\nend_header\n",
    );
    let nan_ply = write(
        d,
        "nan.ply",
        "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nproperty float f_dc_0\nproperty float f_dc_1\nproperty float f_dc_2\nproperty float opacity\nproperty float scale_0\nproperty float scale_1\nproperty float scale_2\nproperty float rot_0\nproperty float rot_1\nproperty float rot_2\nproperty float rot_3\nend_header\n0 0 nan 0 0 0 0 0 0 0 1 0 0 0\n",
    );
    let bad_fx = write(
        d,
        "fx.json",
        &CAMERA.replace("\"fx\": 50.0", "\"fx\": -3.0"),
    );
    let singular = write(
        d,
        "sing.json",
        &CAMERA.replace("[[1,0,0,0],[0,1,0,0]", "[[0,0,0,0],[0,1,0,0]"),
    );
    let zero = write(
        d,
        "zero.json",
        &CAMERA.replace("\"width\": 64", "\"width\": 0"),
    );
    let typo = write(d, "typo.json", &CAMERA.replace("\"fy\"", "\"fyy\""));
    let cases: Vec<(Vec<String>, &str)> = vec![
        (
            vec![garbage.display().to_string(), cam_s.clone()],
            "garbage.ply",
        ),
        (
            vec![header_only.display().to_string(), cam_s.clone()],
            "trunc.ply",
        ),
        (vec![nan_ply.display().to_string(), cam_s.clone()], "z"),
        (vec![ply_s.clone(), bad_fx.display().to_string()], "fx"),
        (
            vec![ply_s.clone(), singular.display().to_string()],
            "invertible",
        ),
        (vec![ply_s.clone(), zero.display().to_string()], "width"),
        (vec![ply_s.clone(), typo.display().to_string()], "fyy"),
        (
            vec![ply_s.clone(), d.join("missing.json").display().to_string()],
            "missing.json",
        ),
    ];
    for (files, needle) in cases {
        let o = splat(&[
            "--ply",
            &files[0],
            "--camera",
            &files[1],
            "--out",
            out.to_str().unwrap(),
        ]);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{files:?}: {err}");
        assert!(
            err.contains(needle),
            "{files:?}: message should name {needle:?}: {err}"
        );
        assert!(!err.contains("panicked"), "{err}");
        assert!(!out.exists(), "nothing may be written on bad input");
    }
    let o = splat(&[
        "--ply",
        &ply_s,
        "--camera",
        &cam_s,
        "--out",
        d.join("x.jpg").to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains(".jpg"));
}
