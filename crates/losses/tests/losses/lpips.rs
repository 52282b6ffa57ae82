//! LPIPS behaviour: identity, symmetry, availability, weight-file errors.

use std::path::Path;

use burn::tensor::{DType, Device};
use envision4d_losses::lpips::{read_lin_layers, ConvWeights, HostTensor, WeightKeys};
use envision4d_losses::{
    HostImages, LossError, Lpips, LpipsNet, LpipsStatus, LpipsWeights, RgbLoss, LPIPS_LOSS_WEIGHT,
};

use crate::common::{fixture, fixture_vgg_weights, tensor, values, Rng};

/// AlexNet LPIPS weights: a seeded He-normal-like random backbone (tests only) and the
/// shipped alex lin layers from the fixture.
pub fn random_alex_weights(seed: u64) -> LpipsWeights {
    let mut rng = Rng::new(seed);
    let shapes = [
        (64, 3, 11),
        (192, 64, 5),
        (384, 192, 3),
        (256, 384, 3),
        (256, 256, 3),
    ];
    let convs = shapes
        .iter()
        .map(|&(o, i, k)| {
            let bound = (6.0 / (i * k * k) as f64).sqrt();
            ConvWeights {
                weight: HostTensor {
                    shape: vec![o, i, k, k],
                    data: rng
                        .vec(o * i * k * k, -bound, bound)
                        .iter()
                        .map(|&v| v as f32)
                        .collect(),
                },
                bias: HostTensor {
                    shape: vec![o],
                    data: rng.vec(o, -0.01, 0.01).iter().map(|&v| v as f32).collect(),
                },
            }
        })
        .collect();
    let lins = read_lin_layers(&fixture(), "lpips_lin_shipped/alex/").unwrap();
    LpipsWeights::new(LpipsNet::Alex, convs, lins).unwrap()
}

fn images(seed: u64, shape: [usize; 4]) -> HostImages {
    let mut rng = Rng::new(seed);
    HostImages::new("test", rng.vec(shape.iter().product(), 0.0, 1.0), shape).unwrap()
}

/// Guards LPIPS(x, x) = 0 exactly (both backbones) and symmetry LPIPS(x, y) = LPIPS(y, x).
#[test]
fn identity_is_zero_and_distance_is_symmetric() {
    let device = Device::flex();
    for (weights, size) in [(fixture_vgg_weights(), 64), (random_alex_weights(5), 64)] {
        let net = Lpips::new(&weights, &device, DType::F32);
        let (x, y) = (images(1, [2, 3, size, size]), images(2, [2, 3, size, size]));
        let same = net.distance_host(&x, &x).unwrap();
        assert!(
            same.iter().all(|&d| d == 0.0),
            "{:?}: LPIPS(x,x) = {same:?}",
            net.net()
        );
        let xy = net.distance_host(&x, &y).unwrap();
        let yx = net.distance_host(&y, &x).unwrap();
        for (a, b) in xy.iter().zip(&yx) {
            assert!(
                *a > 0.0 && (a - b).abs() <= 1e-6 * a,
                "{:?}: {a} vs {b}",
                net.net()
            );
        }
    }
}

/// Guards input validation: too-small images, wrong channels and dtype are errors.
#[test]
fn bad_lpips_inputs_are_errors() {
    let device = Device::flex();
    let net = Lpips::new(&fixture_vgg_weights(), &device, DType::F32);
    let small = images(1, [1, 3, 8, 8]);
    let err = net.distance_host(&small, &small).unwrap_err().to_string();
    assert!(err.contains("too small"), "{err}");
    let gray = tensor(&[0.5; 256], [1, 1, 16, 16], &device, DType::F32);
    assert!(matches!(
        net.forward(gray.clone(), gray),
        Err(LossError::BadShape { .. })
    ));
    let f64_img = tensor(&[0.5; 768], [1, 3, 16, 16], &device, DType::F64);
    assert!(matches!(
        net.forward(f64_img.clone(), f64_img),
        Err(LossError::DtypeMismatch { .. })
    ));
}

/// Guards "never random weights": without a file LPIPS is unavailable with a one-line
/// notice, λ_lpips > 0 is refused, λ_lpips = 0 works (MSE only).
#[test]
fn missing_weights_make_lpips_unavailable() {
    let device = Device::flex();
    let status = LpipsStatus::from_path(None, LpipsNet::Vgg, &device).unwrap();
    let notice = status.notice().expect("a notice");
    assert!(
        !notice.contains('\n') && notice.contains("LPIPS unavailable"),
        "{notice}"
    );
    let err = RgbLoss::new(LPIPS_LOSS_WEIGHT, &status).unwrap_err();
    assert!(matches!(err, LossError::LpipsUnavailable { .. }), "{err}");
    let loss = RgbLoss::new(0.0, &status).unwrap();
    let p = tensor(&[0.25; 48], [1, 3, 4, 4], &device, DType::F32);
    let t = tensor(&[0.75; 48], [1, 3, 4, 4], &device, DType::F32);
    let terms = loss.per_frame(p, t).unwrap();
    assert!(terms.lpips.is_none());
    assert!((values(terms.total)[0] - 0.25).abs() < 1e-7);
    let bad = RgbLoss::new(f64::NAN, &status).unwrap_err().to_string();
    assert!(bad.contains("lambda_lpips"), "{bad}");
}

/// Guards L_rgb = MSE + λ·LPIPS per frame when LPIPS is available.
#[test]
fn rgb_loss_combines_mse_and_lpips_per_frame() {
    let device = Device::flex();
    let status = LpipsStatus::Available(Lpips::new(&fixture_vgg_weights(), &device, DType::F32));
    let loss = RgbLoss::new(LPIPS_LOSS_WEIGHT, &status).unwrap();
    let (x, y) = (images(3, [2, 3, 32, 32]), images(4, [2, 3, 32, 32]));
    let t = |im: &HostImages| tensor(im.data(), im.shape(), &device, DType::F32);
    let terms = loss.per_frame(t(&x), t(&y)).unwrap();
    let (mse, lp, total) = (
        values(terms.mse),
        values(terms.lpips.unwrap()),
        values(terms.total),
    );
    assert_eq!(total.len(), 2);
    for f in 0..2 {
        assert!((total[f] - (mse[f] + LPIPS_LOSS_WEIGHT * lp[f])).abs() < 1e-6);
    }
}

/// Guards weight-file errors: a missing file and a missing key name the path and key.
#[test]
fn weight_file_errors_name_path_and_key() {
    let device = Device::flex();
    let missing = Path::new("/nonexistent/lpips_vgg.safetensors");
    let err = LpipsStatus::from_path(Some(missing), LpipsNet::Vgg, &device)
        .unwrap_err()
        .to_string();
    assert!(err.contains("/nonexistent/lpips_vgg.safetensors"), "{err}");
    // The fixture has no un-prefixed keys.
    let err =
        LpipsWeights::from_safetensors_with(&fixture(), LpipsNet::Vgg, &WeightKeys::default())
            .unwrap_err();
    match err {
        LossError::MissingKey { key, path } => {
            assert_eq!(key, "net.slice1.0.weight");
            assert_eq!(path, fixture());
        }
        other => panic!("expected MissingKey, got {other}"),
    }
    // Alex needs keys the fixture does not have (only its lin layers are there).
    let keys = WeightKeys {
        prefix: "lpips_vgg/weights/".into(),
        quantized: None,
    };
    let err = LpipsWeights::from_safetensors_with(&fixture(), LpipsNet::Alex, &keys).unwrap_err();
    assert!(err.to_string().contains("net.slice1.0.weight"), "{err}");
}

/// LPIPS loaded from `spec` through `LpipsStatus::from_path` reproduces the fixture's
/// official values (within 1e-5 relative).
fn assert_official_lpips(spec: &Path) {
    use crate::common::{fixture_images, read};
    let status = LpipsStatus::from_path(Some(spec), LpipsNet::Vgg, &Device::flex()).unwrap();
    assert!(status.notice().is_none());
    let got = status
        .require()
        .unwrap()
        .distance_host(
            &fixture_images("input/ground_truth"),
            &fixture_images("input/predicted"),
        )
        .unwrap();
    let (want, _) = read(&fixture(), "expected/lpips");
    for (g, w) in got.iter().zip(&want) {
        assert!((g - w).abs() <= 1e-5 * w, "{g} vs {w}");
    }
}

/// Guards the export-script layout (package key names, no prefix, f32): a file written that
/// way loads through `LpipsStatus::from_path` and reproduces the fixture's LPIPS values.
#[test]
fn export_layout_file_loads_and_matches_fixture() {
    use crate::common::{export_layout, write_safetensors};
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("lpips_vgg.safetensors");
    let weights = fixture_vgg_weights();
    write_safetensors(
        &path,
        &export_layout(&weights, envision4d_losses::lpips::SCALING_SHIFT),
    );
    assert_eq!(
        LpipsWeights::from_safetensors(&path, LpipsNet::Vgg).unwrap(),
        weights
    );
    assert_official_lpips(&path);

    // A file whose ScalingLayer differs from the package constants is rejected by name.
    let bad = dir.path().join("bad_scaling.safetensors");
    write_safetensors(&bad, &export_layout(&weights, [0.0, 0.0, 0.0]));
    let err = LpipsWeights::from_safetensors(&bad, LpipsNet::Vgg)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("scaling_layer.shift") && err.contains("bad_scaling"),
        "{err}"
    );
}

/// `tensors` as a PyTorch `.pth` (a bare state_dict, `torch.save`'s zip layout) written by
/// `scripts/make_lightning_ckpt.py --plain`, standard-library Python, no torch.
fn write_pth(
    dir: &Path,
    name: &str,
    tensors: &[(String, Vec<usize>, Vec<f32>)],
) -> std::path::PathBuf {
    use crate::common::write_safetensors;
    let st = dir.join(format!("{name}.safetensors"));
    write_safetensors(&st, tensors);
    let pth = dir.join(format!("{name}.pth"));
    let script = crate::paths::manifest_dir().join("../../scripts/make_lightning_ckpt.py");
    let ok = std::process::Command::new("python3")
        .arg(script)
        .arg(&st)
        .arg(&pth)
        .arg("--plain")
        .status()
        .expect("python3 is needed to write the test .pth files");
    assert!(ok.success());
    pth
}

/// The fixture's VGG weights split as they ship: torchvision's backbone
/// (`features.{i}.weight/bias`, no scaling layer) and the lpips package's lin file.
fn torchvision_and_lins(dir: &Path) -> (std::path::PathBuf, std::path::PathBuf) {
    use crate::common::export_layout;
    let all = export_layout(
        &fixture_vgg_weights(),
        envision4d_losses::lpips::SCALING_SHIFT,
    );
    let mut backbone = Vec::new();
    let mut lins = Vec::new();
    for (key, shape, data) in all {
        if let Some(rest) = key.strip_prefix("net.slice") {
            let index_part = rest.split_once('.').unwrap().1;
            backbone.push((format!("features.{index_part}"), shape, data));
        } else if key.starts_with("lin") && !key.starts_with("lins.") {
            lins.push((key, shape, data));
        }
    }
    (
        write_pth(dir, "vgg16", &backbone),
        write_pth(dir, "vgg", &lins),
    )
}

/// Guards LPIPS from the files users have: torchvision's `vgg16-397923af.pth` layout plus
/// the lpips package's lin `.pth`, named `A,B` in either order, load to exactly the
/// fixture's weights and give the same LPIPS as the safetensors path (the official values).
#[test]
fn torchvision_and_lpips_pth_files_load_like_the_safetensors() {
    let dir = tempfile::tempdir().unwrap();
    let (backbone, lins) = torchvision_and_lins(dir.path());
    let want = fixture_vgg_weights();
    for spec in [
        format!("{},{}", backbone.display(), lins.display()),
        format!("{}, {}", lins.display(), backbone.display()),
    ] {
        let got = LpipsWeights::from_spec(Path::new(&spec), LpipsNet::Vgg).unwrap();
        assert_eq!(got, want, "{spec}");
    }
    assert_official_lpips(Path::new(&format!(
        "{},{}",
        backbone.display(),
        lins.display()
    )));
    // Two backbones: the missing lin layer is named with the file.
    let err = LpipsWeights::from_spec(
        Path::new(&format!("{},{}", backbone.display(), backbone.display())),
        LpipsNet::Vgg,
    )
    .unwrap_err()
    .to_string();
    assert!(
        err.contains("lin0.model.1.weight") && err.contains("vgg16.pth"),
        "{err}"
    );
}

/// Guards reading the lpips package's real `weights/v0.1/vgg.pth` (a legacy, pre-zip
/// `torch.save` pickle): its lin layers are exactly the fixture's. `.ci/run` installs the
/// package without torch (`pip install --no-deps lpips`); the test finds it through Python.
#[test]
fn the_lpips_package_vgg_pth_is_read_as_shipped() {
    let out = std::process::Command::new("python3")
        .args([
            "-c",
            "import importlib.util as u; s = u.find_spec('lpips'); print(s.submodule_search_locations[0] if s else '')",
        ])
        .output()
        .expect("python3 runs");
    let root = String::from_utf8_lossy(&out.stdout).trim().to_owned();
    assert!(
        !root.is_empty(),
        "the lpips package is not installed: pip install --no-deps lpips (.ci/run does)"
    );
    let real = Path::new(&root).join("weights/v0.1/vgg.pth");
    let dir = tempfile::tempdir().unwrap();
    let (backbone, _) = torchvision_and_lins(dir.path());
    let spec = format!("{},{}", backbone.display(), real.display());
    let got = LpipsWeights::from_spec(Path::new(&spec), LpipsNet::Vgg).unwrap();
    assert_eq!(got.lins, fixture_vgg_weights().lins);
}
