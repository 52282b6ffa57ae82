//! The ablation variants of the paper's `tab:ablation` (§4.3): the linear bidirectional
//! velocity baseline instead of conditioned motion lifting, post-layer instead of in-layer
//! temporal attention, and the serialised config that selects them. Small random models on
//! Flex: these tests check structure and exact relations, the fixtures check numbers.

use burn::tensor::{Device, Tensor, TensorData};
use envision4d_model::aggregator::{AggregatorOutput, Temporal};
use envision4d_model::checkpoint::{
    checkpoint_config, load_checkpoint, save_checkpoint, CheckpointKind,
};
use envision4d_model::config::{
    MotionModel, TemporalPlacement, DISPLACEMENT_DIM, VELOCITY_DIRECTIONS,
};
use envision4d_model::model::Heads;
use envision4d_model::motion::{
    linear_displacements, motion_tokens, targets_of, BACKWARD_VELOCITY, FORWARD_VELOCITY,
};
use envision4d_model::{Envision4d, ModelConfig};

const MOTION_ONLY: Heads = Heads {
    depth: false,
    gaussians: false,
    motion: true,
};

/// The tiny widths with 4 layers (a temporal block after each), so a forward pass is cheap.
fn small_config(motion: MotionModel, temporal: TemporalPlacement) -> ModelConfig {
    ModelConfig {
        depth: 4,
        temporal_layers: [0, 1, 2, 3],
        future_iterations: 1,
        motion_model: motion,
        temporal_attention: temporal,
        ..ModelConfig::tiny()
    }
}

/// Deterministic images in [0, 1], `[1, T_c, 3, H, W]`.
fn images(cfg: &ModelConfig, device: &Device) -> Tensor<5> {
    let [h, w] = cfg.image_size;
    let shape = [1, cfg.context_frames, 3, h, w];
    let n: usize = shape.iter().product();
    let v: Vec<f32> = (0..n).map(|i| ((i * 7919) % 1000) as f32 / 999.0).collect();
    Tensor::from_data(TensorData::new(v, shape), device)
}

fn host<const D: usize>(t: Tensor<D>) -> Vec<f32> {
    t.into_data()
        .convert::<f32>()
        .try_into_vec::<f32>()
        .unwrap()
}

/// Frame `f` of a `[B, F, ...]` map, flattened.
fn frame(t: &Tensor<5>, f: usize) -> Vec<f32> {
    let [b, _, h, w, c] = t.dims();
    host(t.clone().slice([0..b, f..f + 1, 0..h, 0..w, 0..c]))
}

fn scaled(v: &[f32], k: f32) -> Vec<f32> {
    v.iter().map(|x| x * k).collect()
}

/// Guards the baseline's motion law against a wrong direction pick, a missing or mis-signed
/// `(j − i)` factor, or a layout other than the adapter's source-major `[B, T_c·K, ..]`.
#[test]
fn linear_displacements_scale_the_direction_velocity_by_the_time_gap() {
    let device = Device::flex();
    let (tc, n, h, w) = (2, 4, 2, 3);
    let ch = VELOCITY_DIRECTIONS * DISPLACEMENT_DIM;
    let len = tc * h * w * ch;
    // Distinct values everywhere, so swapping forward and backward cannot go unnoticed.
    let v: Vec<f32> = (0..len).map(|i| 0.25 + i as f32 * 0.5).collect();
    let vel = Tensor::<5>::from_data(TensorData::new(v, [1, tc, h, w, ch]), &device);
    let out = linear_displacements(vel.clone(), n);
    assert_eq!(out.dims(), [1, tc * (n - 1), h, w, DISPLACEMENT_DIM]);
    for i in 0..tc {
        let src = vel.clone().slice([0..1, i..i + 1, 0..h, 0..w, 0..ch]);
        let fwd = host(
            src.clone()
                .slice([0..1, 0..1, 0..h, 0..w, FORWARD_VELOCITY]),
        );
        let bwd = host(src.slice([0..1, 0..1, 0..h, 0..w, BACKWARD_VELOCITY]));
        assert_ne!(fwd, bwd);
        for (k, j) in targets_of(i, n).into_iter().enumerate() {
            let gap = j as f32 - i as f32;
            let want = if j > i {
                scaled(&fwd, gap)
            } else {
                scaled(&bwd, gap)
            };
            assert_eq!(
                frame(&out, i * (n - 1) + k),
                want,
                "source {i} → target {j}"
            );
        }
    }
}

/// Guards the LinearVelocity forward pass: a 6-channel motion head read once per context
/// frame on unmodulated motion tokens, and displacements exactly linear in `(j − i)` with
/// `v_fwd` ahead and `−v_bwd` one frame back (a wrong wiring of head, tokens or law fails).
#[test]
fn linear_velocity_model_moves_gaussians_linearly_in_time() {
    let device = Device::flex();
    let cfg = small_config(MotionModel::LinearVelocity, TemporalPlacement::InLayer);
    cfg.validate().unwrap();
    let model = Envision4d::new(&cfg, &device);
    let head_out = model.motion_head.scratch.output_conv2.conv2.weight.dims()[0];
    assert_eq!(head_out, VELOCITY_DIRECTIONS * DISPLACEMENT_DIM);
    let p = model.forward(images(&cfg, &device), MOTION_ONLY);
    let (tc, n) = (cfg.context_frames, cfg.num_frames());
    let (k, [h, w]) = (n - 1, cfg.image_size);
    let enc = p.motion_enc.expect("motion head ran");
    assert_eq!(enc.dims(), [1, tc * k, h, w, DISPLACEMENT_DIM]);
    let tokens = p.motion_tokens.expect("motion tokens kept");
    assert_eq!(
        tokens[0].dims()[1],
        tc,
        "one unmodulated map per context frame"
    );

    // The velocities, straight from the head on the returned tokens.
    let agg = &p.backbone.aggregator;
    let expected_tokens = motion_tokens(
        MotionModel::LinearVelocity,
        &agg.time_list,
        p.backbone.tokens.time.clone(),
        agg.patch_start,
    );
    for (got, want) in tokens.iter().zip(expected_tokens) {
        assert_eq!(host(got.clone()), host(want));
    }
    let vel = model
        .motion_head
        .forward_chunked(&tokens, 0, [h, w], None, model.dpt_frame_chunk);
    let velocity = |i: usize, dir| host(vel.clone().slice([0..1, i..i + 1, 0..h, 0..w, dir]));
    for i in 0..tc {
        let (fwd, bwd) = (
            velocity(i, FORWARD_VELOCITY),
            velocity(i, BACKWARD_VELOCITY),
        );
        for (slot, j) in targets_of(i, n).into_iter().enumerate() {
            let got = frame(&enc, i * k + slot);
            let gap = j as f32 - i as f32;
            let want = if j > i {
                scaled(&fwd, gap)
            } else {
                scaled(&bwd, gap)
            };
            assert_eq!(got, want, "source {i} → target {j}");
        }
    }
    // Frame 1 one step back moves against its backward velocity, one step ahead with its
    // forward velocity: opposite directions from two different predictions.
    assert_eq!(
        frame(&enc, k),
        scaled(&velocity(1, BACKWARD_VELOCITY), -1.0)
    );
    assert_eq!(frame(&enc, k + 1), velocity(1, FORWARD_VELOCITY));
}

fn global_half(t: Tensor<4>) -> Vec<f32> {
    let [b, s, p, c2] = t.dims();
    host(t.slice([0..b, 0..s, 0..p, c2 / 2..c2]))
}

fn temporal_half(t: &Tensor<4>) -> Tensor<4> {
    let [b, s, p, c2] = t.dims();
    t.clone().slice([0..b, 0..s, 0..p, c2 / 2..c2])
}

fn taps(agg: &AggregatorOutput, layers: &[usize]) -> Vec<Vec<f32>> {
    layers.iter().map(|&l| host(agg.layer(l))).collect()
}

/// Guards PostLayer against leaking temporal attention into the frozen layers (its DPT taps
/// and camera tokens must be plain VGGT, i.e. `Temporal::Skip`, bit for bit), against motion
/// tokens that ignore the appended stack (they must differ from in-layer's), and against a
/// stack that is not `Y_0 = T_0(G_last)`, `Y_t = T_t(Y_{t−1})` with global halves `G_{ℓ_t}`.
#[test]
fn post_layer_keeps_vggt_taps_and_stacks_temporal_blocks_after_the_last_layer() {
    let device = Device::flex();
    let cfg = small_config(MotionModel::Lifting, TemporalPlacement::PostLayer);
    let mut model = Envision4d::new(&cfg, &device);
    assert_eq!(model.aggregator.placement, TemporalPlacement::PostLayer);
    let imgs = images(&cfg, &device);
    let last = cfg.depth - 1;
    let keep: Vec<usize> = (0..cfg.depth).collect();
    let post = model.aggregator.forward(imgs.clone(), &keep);
    let vggt = model
        .aggregator
        .forward_with(imgs.clone(), &keep, Temporal::Skip);
    assert!(vggt.time_list.is_empty(), "plain VGGT has no motion tokens");
    assert_eq!(taps(&post, &keep), taps(&vggt, &keep));
    assert_eq!(post.time_list.len(), 4);

    let [b, s, p, c2] = post.time_list[0].dims();
    let c = c2 / 2;
    let mut y = vggt.layer(last).slice([0..b, 0..s, 0..p, c..c2]);
    for (t, &l) in cfg.temporal_layers.iter().enumerate() {
        let entry = post.time_list[t].clone();
        let global = entry.clone().slice([0..b, 0..s, 0..p, 0..c]);
        assert_eq!(
            host(global),
            global_half(vggt.layer(l)),
            "time_list[{t}] global half"
        );
        let seq = y.swap_dims(1, 2).reshape([b * p, s, c]);
        y = model.aggregator.time_blocks[t]
            .forward(seq, None)
            .reshape([b, p, s, c])
            .swap_dims(1, 2);
        assert_eq!(
            host(temporal_half(&entry)),
            host(y.clone()),
            "time_list[{t}] temporal half"
        );
    }

    // The same weights in-layer: its taps leave VGGT and its motion tokens differ.
    model.aggregator.placement = TemporalPlacement::InLayer;
    let inl = model.aggregator.forward(imgs, &keep);
    assert_ne!(taps(&inl, &[last]), taps(&vggt, &[last]));
    for t in 0..4 {
        assert_ne!(
            host(temporal_half(&inl.time_list[t])),
            host(temporal_half(&post.time_list[t])),
            "time_list[{t}]"
        );
    }
}

/// Guards the ablation without temporal attention: no temporal block is built, the taps and
/// camera tokens are plain VGGT's bit for bit, every motion token is `cat(G_ℓ, G_ℓ)` at the
/// temporal layers, and the full forward (all heads) runs and stays finite.
#[test]
fn no_temporal_attention_builds_no_blocks_and_lifts_the_global_tokens() {
    let device = Device::flex();
    let cfg = small_config(MotionModel::Lifting, TemporalPlacement::None);
    let model = Envision4d::new(&cfg, &device);
    assert!(model.aggregator.time_blocks.is_empty());
    let imgs = images(&cfg, &device);
    let keep: Vec<usize> = (0..cfg.depth).collect();
    let none = model.aggregator.forward(imgs.clone(), &keep);
    let vggt = model
        .aggregator
        .forward_with(imgs.clone(), &keep, Temporal::Skip);
    assert_eq!(taps(&none, &keep), taps(&vggt, &keep));
    assert_eq!(none.time_list.len(), 4);
    for (t, &l) in cfg.temporal_layers.iter().enumerate() {
        let entry = none.time_list[t].clone();
        let [b, s, p, c2] = entry.dims();
        let first = host(entry.clone().slice([0..b, 0..s, 0..p, 0..c2 / 2]));
        assert_eq!(
            first,
            global_half(vggt.layer(l)),
            "time_list[{t}] first half"
        );
        assert_eq!(
            host(temporal_half(&entry)),
            first,
            "time_list[{t}] second half"
        );
    }
    let out = model.forward(imgs, Heads::ALL);
    let motion = host(out.motion_enc.expect("motion head ran"));
    assert!(motion.iter().all(|v| v.is_finite()));
}

/// Guards old configs and checkpoint metadata (written before the switches existed) against
/// changing meaning: without the keys they are the paper model, and the paper model still
/// serialises without them, so older readers (`deny_unknown_fields`) keep reading it.
#[test]
fn configs_without_the_switches_mean_the_paper_model() {
    for cfg in [ModelConfig::paper(), ModelConfig::tiny()] {
        assert_eq!(cfg.motion_model, MotionModel::Lifting);
        assert_eq!(cfg.temporal_attention, TemporalPlacement::InLayer);
        let json = serde_json::to_value(&cfg).unwrap();
        let obj = json.as_object().unwrap();
        assert!(!obj.contains_key("motion_model") && !obj.contains_key("temporal_attention"));
        assert_eq!(serde_json::from_value::<ModelConfig>(json).unwrap(), cfg);
    }
    let model = Envision4d::new(
        &small_config(Default::default(), Default::default()),
        &Device::flex(),
    );
    let head_out = model.motion_head.scratch.output_conv2.conv2.weight.dims()[0];
    assert_eq!(
        head_out, DISPLACEMENT_DIM,
        "the paper's motion head predicts displacements"
    );
    assert_eq!(model.aggregator.placement, TemporalPlacement::InLayer);
}

/// Guards the serialised names (snake_case, as the training TOML spells them) and rejects an
/// unknown value by name instead of falling back to the paper model.
#[test]
fn switch_names_are_snake_case_and_unknown_values_are_rejected() {
    let cfg = small_config(MotionModel::LinearVelocity, TemporalPlacement::PostLayer);
    let json = serde_json::to_value(&cfg).unwrap();
    assert_eq!(json["motion_model"], "linear_velocity");
    assert_eq!(json["temporal_attention"], "post_layer");
    assert_eq!(
        serde_json::from_value::<ModelConfig>(json.clone()).unwrap(),
        cfg
    );
    let mut bad = json;
    bad["motion_model"] = serde_json::json!("linear");
    let err = serde_json::from_value::<ModelConfig>(bad)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("linear") && err.contains("linear_velocity"),
        "{err}"
    );
}

/// Guards checkpoints of the variants: the metadata round-trips the switches, and weights of
/// the paper's 3-channel motion head never load silently into the 6-channel baseline.
#[test]
fn variant_checkpoints_carry_their_switches_and_refuse_the_other_head() {
    let device = Device::flex();
    let dir = tempfile::tempdir().unwrap();
    let variant = small_config(MotionModel::LinearVelocity, TemporalPlacement::PostLayer);
    let path = dir.path().join("variant.safetensors");
    save_checkpoint(&Envision4d::new(&variant, &device), &variant, &path).unwrap();
    assert_eq!(checkpoint_config(&path).unwrap(), Some(variant.clone()));

    let paper = small_config(MotionModel::Lifting, TemporalPlacement::InLayer);
    let paper_path = dir.path().join("paper.safetensors");
    save_checkpoint(&Envision4d::new(&paper, &device), &paper, &paper_path).unwrap();
    let mut baseline = Envision4d::new(&variant, &device);
    let err = load_checkpoint(&mut baseline, &paper_path, CheckpointKind::Full)
        .unwrap_err()
        .to_string();
    assert!(err.contains("motion_head"), "{err}");
}

/// Guards the trained "motion off" control: every displacement is exactly zero with the
/// lifting layout `[B, T_c·(N−1), H, W, 3]`, the head is skipped (no motion tokens), the
/// checkpoint keeps the lifting head's keys (a paper checkpoint loads into it), and the
/// serialised name is `off`.
#[test]
fn motion_off_predicts_no_motion_and_skips_the_head() {
    let device = Device::flex();
    let cfg = small_config(MotionModel::Off, TemporalPlacement::InLayer);
    let model = Envision4d::new(&cfg, &device);
    let out = model.forward(images(&cfg, &device), MOTION_ONLY);
    assert!(out.motion_tokens.is_none(), "the head ran");
    let motion = out.motion_enc.expect("displacements");
    let n = cfg.context_frames + cfg.future_frames;
    let [h, w] = cfg.image_size;
    assert_eq!(
        motion.dims(),
        [1, cfg.context_frames * (n - 1), h, w, DISPLACEMENT_DIM]
    );
    assert!(host(motion).iter().all(|&v| v == 0.0));
    assert_eq!(
        serde_json::to_value(MotionModel::Off).unwrap(),
        serde_json::json!("off")
    );
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("paper.safetensors");
    let paper_cfg = small_config(MotionModel::Lifting, TemporalPlacement::InLayer);
    save_checkpoint(&Envision4d::new(&paper_cfg, &device), &paper_cfg, &path).unwrap();
    let mut off = Envision4d::new(&cfg, &device);
    load_checkpoint(&mut off, &path, CheckpointKind::Full).expect("same keys and shapes");
}

/// Guards training's warm-up skip: a scene predicted without running the motion head
/// (`Motion::Still`) is the full scene with its motion zeroed, Gaussian for Gaussian, so the
/// warm-up's renders and loss do not change.
#[test]
fn still_scene_equals_the_full_scene_without_motion() {
    use envision4d_model::scene::{predict_scene, predict_scene_with, Motion};
    let device = Device::flex();
    let cfg = small_config(MotionModel::Lifting, TemporalPlacement::InLayer);
    let model = Envision4d::new(&cfg, &device);
    let imgs = images(&cfg, &device);
    let full = predict_scene(&model, imgs.clone())
        .unwrap()
        .without_motion();
    let still = predict_scene_with(&model, imgs, Motion::Still).unwrap();
    assert!(still.pred.motion_tokens.is_none(), "the motion head ran");
    let (a, b) = (&full.adapted, &still.adapted);
    assert_eq!(a.motions.dims(), b.motions.dims());
    assert_eq!(host(a.motions.clone()), host(b.motions.clone()));
    assert_eq!(host(a.means.clone()), host(b.means.clone()));
    assert_eq!(host(a.colors.clone()), host(b.colors.clone()));
    assert_eq!(host(a.opacities.clone()), host(b.opacities.clone()));
}
