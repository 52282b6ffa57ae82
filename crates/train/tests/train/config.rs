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
    assert!(c.run.recompute_frozen_blocks);
    let n = envision4d_train::load(&config_path("nuscenes.toml")).unwrap();
    assert_eq!(
        (n.optim, n.loss.clone(), n.progressive),
        (c.optim, c.loss, c.progressive)
    );
    // §4.1: every dataset's frames are resized to 350x518; the official nuScenes tree, `train`.
    assert_eq!(n.model.image_size, [350, 518]);
    assert_eq!(
        n.data.layout,
        envision4d_train::config::DataLayout::Nuscenes
    );
    assert_eq!(n.data.split.as_deref(), Some("train"));
    let t = envision4d_train::load(&config_path("synth-tiny.toml")).unwrap();
    assert_eq!(t.model.image_size, [56, 84]);
    assert_eq!(t.model.depth, 4);
    let b = envision4d_train::load(&config_path("synth-backbone.toml")).unwrap();
    assert_eq!(b.stage, Stage::Backbone);
    // Stage 2 (and its continuation) must build the very network stage 1 trained.
    assert_eq!(b.model, t.model);
    let m = envision4d_train::load(&config_path("synth-mix.toml")).unwrap();
    assert_eq!(m.model, t.model);
    // The chain that made the shipped model: every link builds the same network, and only
    // the last one adds the structural term (the paper's loss has none).
    assert_eq!(n.loss.lambda_ssim, 0.0);
    for (file, ssim) in [
        ("synth-mix-long.toml", 0.0),
        ("synth-mix-pose.toml", 0.0),
        ("synth-mix-ssim.toml", 0.05),
        ("probes/ssim-probe.toml", 0.05),
        ("probes/ssim-control.toml", 0.0),
    ] {
        let link = envision4d_train::load(&config_path(file)).unwrap();
        assert_eq!(link.model, t.model, "{file}");
        assert_eq!(link.loss.lambda_ssim, ssim, "{file}");
    }
    let four = envision4d_train::load(&config_path("probes/future-iterations-4.toml")).unwrap();
    assert_eq!(four.model.future_iterations, 4);
    for v in [
        "paper",
        "linear-velocity-no-temporal",
        "linear-velocity",
        "no-temporal",
        "post-layer",
        "no-progressive",
        "no-warmup",
        "no-warmup-no-progressive",
    ] {
        envision4d_train::load(&config_path(&format!("ablation/{v}.toml"))).unwrap();
    }
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
    let bad = text.replace("\nlr = 5e-4", "\nlr = -1.0");
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
    let bad = text.replace(
        "lambda_lpips = 0.0",
        "lambda_lpips = 0.0\nlambda_ssim = -0.5",
    );
    let err = envision4d_train::parse(&bad, Path::new("x.toml"))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("loss.lambda_ssim") && err.contains("-0.5"),
        "{err}"
    );
}

/// Guards the `[ablation]` switches against being parsed but not reaching the network (they
/// used to be refused as "not implemented"): each value builds its model variant, and the
/// defaults build the paper model.
#[test]
fn ablation_switches_select_the_model_variant() {
    use envision4d_model::config::{MotionModel, TemporalPlacement};
    let text = std::fs::read_to_string(config_path("synth-tiny.toml")).unwrap();
    let paper = envision4d_train::parse(&text, Path::new("paper.toml")).unwrap();
    assert_eq!(paper.model.motion_model, MotionModel::Lifting);
    assert_eq!(paper.model.temporal_attention, TemporalPlacement::InLayer);
    for (motion, temporal, want) in [
        (
            "linear_velocity",
            "in_layer",
            (MotionModel::LinearVelocity, TemporalPlacement::InLayer),
        ),
        (
            "lifting",
            "post_layer",
            (MotionModel::Lifting, TemporalPlacement::PostLayer),
        ),
        (
            "linear_velocity",
            "post_layer",
            (MotionModel::LinearVelocity, TemporalPlacement::PostLayer),
        ),
    ] {
        let ablated = format!(
            "{text}\n[ablation]\nmotion = \"{motion}\"\ntemporal_attention = \"{temporal}\"\n"
        );
        let c = envision4d_train::parse(&ablated, Path::new("ablation.toml")).unwrap();
        assert_eq!((c.model.motion_model, c.model.temporal_attention), want);
    }
}

/// Guards against two sources of truth for the architecture: a `[model]` switch that
/// disagrees with `[ablation]` is an error naming both keys; one that agrees is accepted.
#[test]
fn model_switch_disagreeing_with_ablation_is_rejected() {
    let text = std::fs::read_to_string(config_path("synth-tiny.toml")).unwrap();
    let with = |model_line: &str, ablation: &str| {
        let t = text.replacen(
            "preset = \"tiny\"",
            &format!("preset = \"tiny\"\n{model_line}"),
            1,
        );
        envision4d_train::parse(
            &format!("{t}\n[ablation]\n{ablation}\n"),
            Path::new("x.toml"),
        )
    };
    let err = with("motion_model = \"linear_velocity\"", "motion = \"lifting\"")
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("model.motion_model") && err.contains("ablation.motion"),
        "{err}"
    );
    let err = with(
        "temporal_attention = \"post_layer\"",
        "temporal_attention = \"in_layer\"",
    )
    .unwrap_err()
    .to_string();
    assert!(
        err.contains("model.temporal_attention") && err.contains("ablation.temporal_attention"),
        "{err}"
    );
    let c = with(
        "motion_model = \"linear_velocity\"",
        "motion = \"linear_velocity\"",
    )
    .unwrap();
    assert_eq!(
        c.model.motion_model,
        envision4d_model::config::MotionModel::LinearVelocity
    );
}

/// Guards `validate` against a config whose ablation was changed after parsing: the model it
/// would build no longer matches, so it is refused instead of training the wrong network.
#[test]
fn ablation_edited_after_parse_is_refused() {
    let mut c = crate::common::tiny_config();
    c.ablation.motion = envision4d_train::config::MotionModel::LinearVelocity;
    let err = envision4d_train::load::validate(&c)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("ablation") && err.contains("motion_model"),
        "{err}"
    );
}

/// Guards the ablation coverage: every row of the paper's Tab. 3 and of its appendix table
/// of the progressive strategy has a config in `configs/ablation/` with exactly that row's
/// switches (a renamed or edited config would silently stop reproducing its row).
#[test]
fn ablation_configs_cover_every_paper_row() {
    use envision4d_train::config::{MotionModel as M, Switch, TemporalAttention as T};
    let (on, off) = (Switch::On, Switch::Off);
    let rows = [
        (
            "Tab. 3 row 1: FP, linear velocity",
            "linear-velocity-no-temporal",
            M::LinearVelocity,
            T::None,
            on,
            on,
        ),
        (
            "Tab. 3 row 2: + CML",
            "no-temporal",
            M::Lifting,
            T::None,
            on,
            on,
        ),
        (
            "Tab. 3 row 3: + post-layer TAttn",
            "post-layer",
            M::Lifting,
            T::PostLayer,
            on,
            on,
        ),
        (
            "Tab. 3 row 4 = appendix row 1: no Prog. Train",
            "no-warmup-no-progressive",
            M::Lifting,
            T::InLayer,
            off,
            off,
        ),
        (
            "Tab. 3 row 5 = appendix row 4: the paper",
            "paper",
            M::Lifting,
            T::InLayer,
            on,
            on,
        ),
        (
            "appendix row 2: warm-up only",
            "no-progressive",
            M::Lifting,
            T::InLayer,
            on,
            off,
        ),
        (
            "appendix row 3: weighting only",
            "no-warmup",
            M::Lifting,
            T::InLayer,
            off,
            on,
        ),
    ];
    for (row, file, motion, temporal, warmup, weighting) in rows {
        let c = envision4d_train::load(&config_path(&format!("ablation/{file}.toml"))).unwrap();
        let a = &c.ablation;
        assert_eq!(
            (
                a.motion,
                a.temporal_attention,
                a.warmup,
                a.progressive_weighting
            ),
            (motion, temporal, warmup, weighting),
            "{row}: configs/ablation/{file}.toml"
        );
        assert_eq!(
            c.run.out_dir,
            Path::new(&format!("runs/ablation-{file}")),
            "{row}"
        );
    }
}

/// Guards `init`: a paper-width config that lost its `init_checkpoint` is refused (it would
/// silently train from random weights), `init = "random"` allows it and names every network
/// it randomises (model, teacher, LPIPS's VGG), and `init = "random"` next to a checkpoint
/// is a contradiction naming the key. The default stays out of the saved TOML, so runs
/// started before the key existed resume.
#[test]
fn random_init_only_on_purpose() {
    let text = std::fs::read_to_string(config_path("waymo.toml")).unwrap();
    let no_init = text.replace(
        "init_checkpoint = \"weights/VGGT-1B/model.pt\"",
        "# init_checkpoint removed",
    );
    let err = envision4d_train::parse(&no_init, Path::new("x.toml"))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("init_checkpoint") && err.contains("init = \"random\""),
        "{err}"
    );
    let lpips_off = no_init.replace(
        "lpips_weights = \"weights/lpips_vgg.safetensors\"",
        "# no LPIPS weights",
    );
    let random = lpips_off.replace(
        "stage = \"envision4d\"",
        "stage = \"envision4d\"\ninit = \"random\"",
    );
    let cfg = envision4d_train::parse(&random, Path::new("x.toml")).unwrap();
    assert_eq!(
        cfg.random_weights(),
        vec!["the model", "the frozen teacher", "LPIPS's VGG"]
    );
    assert!(cfg.to_toml().contains("init = \"random\""));
    let both = text.replace(
        "stage = \"envision4d\"",
        "stage = \"envision4d\"\ninit = \"random\"",
    );
    let err = envision4d_train::parse(&both, Path::new("x.toml"))
        .unwrap_err()
        .to_string();
    assert!(err.contains("init") && err.contains("model.pt"), "{err}");
    let shipped = envision4d_train::parse(&text, Path::new("x.toml")).unwrap();
    assert!(shipped.random_weights().is_empty());
    assert!(
        !shipped.to_toml().contains("init ="),
        "default init written out"
    );
}
