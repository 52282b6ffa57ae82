use crate::common::config_path;
use envision4d_train::config::{AnnealOrigin, FreezeGroup, Stage, Teacher};
use std::path::Path;

/// Guards against the shipped configs drifting from the paper or failing to parse.
#[test]
fn shipped_configs_parse_paper_values() {
    let c = envision4d_train::load(&config_path("waymo.toml")).unwrap();
    assert_eq!(c.stage, Stage::Envision4d);
    assert_eq!(c.teacher, Teacher::Backbone);
    assert_eq!(c.optim.lr, 1e-4);
    assert_eq!((c.optim.batch_size, c.optim.iterations), (2, 100_000));
    assert_eq!(
        (c.loss.lambda_lpips, c.loss.lambda_cam, c.loss.lambda_depth),
        (0.05, 5.0, 1.0)
    );
    assert_eq!(
        (c.progressive.warmup_iterations, c.progressive.s_max),
        (2500, 50_000)
    );
    assert_eq!(c.progressive.alpha0, 1.0);
    assert_eq!(c.progressive.anneal_origin, AnnealOrigin::AfterWarmup);
    assert_eq!(c.model.image_size, [350, 518]);
    assert_eq!(c.model.embed_dim, 1024);
    assert_eq!(c.freeze, FreezeGroup::PAPER.to_vec());
    let t = envision4d_train::load(&config_path("synth-tiny.toml")).unwrap();
    assert_eq!(t.model.image_size, [56, 84]);
    assert_eq!(t.model.depth, 4);
}

/// Guards against a typo in a config key being silently ignored.
#[test]
fn config_typo_is_rejected_naming_the_key() {
    let text = std::fs::read_to_string(config_path("synth-tiny.toml")).unwrap();
    for (from, to, key) in [
        ("lambda_cam", "lambda_camm", "lambda_camm"),
        ("embed_dim", "embed_dimm", "embed_dimm"),
        (
            "preset = \"tiny\"",
            "preset = \"tiny\"\nwarmup = 3",
            "warmup",
        ),
    ] {
        let bad = if from == "embed_dim" {
            text.replace("depth = 4", "depth = 4\nembed_dimm = 64")
        } else {
            text.replacen(from, to, 1)
        };
        let err = envision4d_train::parse(&bad, Path::new("typo.toml"))
            .unwrap_err()
            .to_string();
        assert!(
            err.contains(key) && err.contains("typo.toml"),
            "{key}: {err}"
        );
    }
}

/// Guards against invalid values passing validation without naming key and value.
#[test]
fn invalid_value_names_key_and_value() {
    let text = std::fs::read_to_string(config_path("synth-tiny.toml")).unwrap();
    let bad = text.replace("lr = 1e-3", "lr = -1.0");
    let err = envision4d_train::parse(&bad, Path::new("x.toml"))
        .unwrap_err()
        .to_string();
    assert!(err.contains("optim.lr") && err.contains("-1"), "{err}");
    let bad = text.replace("lambda_lpips = 0.0", "lambda_lpips = 0.05");
    let err = envision4d_train::parse(&bad, Path::new("x.toml"))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("loss.lambda_lpips") && err.contains("lpips_weights"),
        "{err}"
    );
}
