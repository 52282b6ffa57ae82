//! The run loop: resume, checkpoints, the NaN guard, the backbone stage and its teacher.

use crate::common::{flat_params, tiny_config, write_synth_dataset};
use burn::tensor::Device;
use envision4d_train::checkpoint::{list, MODEL_FILE};
use envision4d_train::config::{Stage, Teacher};
use envision4d_train::run::{run, Quiet, RunOptions, CHECKPOINT_DIR, LOG_FILE};
use envision4d_train::{StepOutcome, TrainConfig, Trainer};
use std::path::Path;

/// A config training on the dataset at `data`, writing to `out`.
fn config_at(data: &Path, out: &Path) -> TrainConfig {
    let mut c = tiny_config();
    c.data.root = data.to_path_buf();
    c.run.out_dir = out.to_path_buf();
    c.run.log_every = 1;
    c.run.checkpoint_every = 1;
    c.run.keep_checkpoints = 2;
    c.run.val_every = 0;
    c.progressive.warmup_iterations = 2;
    c.optim.iterations = 4;
    c
}

fn losses(out: &Path) -> Vec<(u64, f64)> {
    std::fs::read_to_string(out.join(LOG_FILE))
        .unwrap()
        .lines()
        .filter_map(|l| {
            let v: serde_json::Value = serde_json::from_str(l).unwrap();
            (v["kind"] == "step")
                .then(|| (v["step"].as_u64().unwrap(), v["loss"].as_f64().unwrap()))
        })
        .collect()
}

/// Guards `--resume`: model, Adam state, schedule step and data order are restored, so a run
/// split in two gives the same parameters and loss curve as one uninterrupted run (warm-up
/// to progressive switch included), and only the newest K checkpoints are kept.
#[test]
fn resume_equals_uninterrupted_run() {
    let tmp = tempfile::tempdir().unwrap();
    let data = tmp.path().join("data");
    write_synth_dataset(&data, 4, 4);
    let device = Device::flex().autodiff();
    let whole = config_at(&data, &tmp.path().join("whole"));
    let a = run(whole.clone(), &device, RunOptions::default(), &mut Quiet).unwrap();
    let split = config_at(&data, &tmp.path().join("split"));
    run(
        split.clone(),
        &device,
        RunOptions {
            stop_at: Some(2),
            ..Default::default()
        },
        &mut Quiet,
    )
    .unwrap();
    // Starting again without --resume must refuse rather than overwrite the run.
    let again = run(split.clone(), &device, RunOptions::default(), &mut Quiet);
    assert!(again.unwrap_err().to_string().contains("--resume"));
    let resume = RunOptions {
        resume: Some(split.run.out_dir.clone()),
        ..Default::default()
    };
    let b = run(split.clone(), &device, resume, &mut Quiet).unwrap();
    assert_eq!((a.steps, b.steps), (4, 4));
    assert_eq!(losses(&whole.run.out_dir), losses(&split.run.out_dir));
    let load = |p: &Path| {
        let mut m = envision4d_model::Envision4d::new(&whole.model, &device);
        envision4d_model::checkpoint::load_checkpoint(
            &mut m,
            p,
            envision4d_model::checkpoint::CheckpointKind::Full,
        )
        .unwrap();
        flat_params(&m)
    };
    assert_eq!(load(&a.model), load(&b.model), "resumed parameters differ");
    let root = split.run.out_dir.join(CHECKPOINT_DIR);
    let kept = list(&root).unwrap();
    assert_eq!(kept.iter().map(|k| k.0).collect::<Vec<_>>(), vec![3, 4]);
    // A changed hyper-parameter is refused, naming the key.
    let mut changed = split.clone();
    changed.optim.lr *= 2.0;
    let resume = || RunOptions {
        resume: Some(split.run.out_dir.clone()),
        ..Default::default()
    };
    let err = run(changed, &device, resume(), &mut Quiet)
        .unwrap_err()
        .to_string();
    assert!(err.contains("optim.lr"), "{err}");
    // Resuming from the older checkpoint sets the newer one aside (a later `--resume RUN`
    // must not pick up the abandoned timeline) and rewrites it.
    let older = RunOptions {
        resume: Some(kept[0].1.clone()),
        ..Default::default()
    };
    run(split.clone(), &device, older, &mut Quiet).unwrap();
    assert!(root.join(".abandoned-step-00000004").is_dir());
    assert_eq!(losses(&split.run.out_dir), losses(&whole.run.out_dir));
}

/// Guards the NaN guard: with a learning rate that blows the weights up, steps become
/// non-finite, are skipped (never applied), and after `max_nonfinite_steps` in a row the run
/// stops with a message naming the last good checkpoint, which stays loadable.
#[test]
fn nan_guard_stops_run_and_keeps_last_checkpoint() {
    let tmp = tempfile::tempdir().unwrap();
    let data = tmp.path().join("data");
    write_synth_dataset(&data, 2, 4);
    let device = Device::flex().autodiff();
    let mut c = config_at(&data, &tmp.path().join("out"));
    c.optim.lr = 1e30;
    c.optim.grad_clip = envision4d_train::config::ClipMode::None;
    c.optim.iterations = 50;
    c.run.max_nonfinite_steps = 3;
    let err = run(c.clone(), &device, RunOptions::default(), &mut Quiet)
        .unwrap_err()
        .to_string();
    assert!(err.contains("non-finite steps in a row"), "{err}");
    let (_, last) = list(&c.run.out_dir.join(CHECKPOINT_DIR))
        .unwrap()
        .pop()
        .unwrap();
    assert!(err.contains(&last.display().to_string()), "{err}");
    let mut m = envision4d_model::Envision4d::new(&c.model, &device);
    envision4d_model::checkpoint::load_checkpoint(
        &mut m,
        &last.join(MODEL_FILE),
        envision4d_model::checkpoint::CheckpointKind::Full,
    )
    .unwrap();
    assert!(
        flat_params(&m).iter().all(|v| v.is_finite()),
        "a checkpoint holds non-finite weights"
    );
    let log = std::fs::read_to_string(c.run.out_dir.join(LOG_FILE)).unwrap();
    assert!(
        log.contains("skipped_nonfinite"),
        "skipped steps are logged"
    );
}

/// Guards the backbone stage and the frozen teacher: stage 1 trains only what plain VGGT has
/// (the Gaussian head gets no update) and lowers its loss; its checkpoint then serves as the
/// `teacher = "backbone"` of stage 2, whose steps apply and carry a camera term; variants
/// and `init_fresh` initialise from it (an `init_fresh` that loaded the motion head anyway
/// would hand one variant a trained motion).
#[test]
fn backbone_stage_then_teacher() {
    let tmp = tempfile::tempdir().unwrap();
    let data = tmp.path().join("data");
    write_synth_dataset(&data, 3, 4);
    let device = Device::flex().autodiff();
    let mut c = config_at(&data, &tmp.path().join("backbone"));
    c.stage = Stage::Backbone;
    c.optim.iterations = 6;
    c.optim.lr = 1e-3;
    c.loss.lambda_depth = 0.1;
    let mut t = Trainer::new(c.clone(), &device).unwrap();
    let gs_before = flat_params(&t.model.gs_head);
    let hc = envision4d_data::HostClip::from_clip(
        &envision4d_train::dataset::open_dataset(
            &c.data,
            &c.model,
            &data,
            envision4d_train::config::Purpose::Train,
        )
        .unwrap()
        .load(0)
        .unwrap(),
    )
    .unwrap();
    let batch =
        envision4d_train::batch::Batch::from_clips(std::slice::from_ref(&hc), 4, true, &device)
            .unwrap();
    let mut totals = vec![];
    for _ in 0..6 {
        let r = t.train_step(&batch).unwrap();
        assert_eq!(r.outcome, StepOutcome::Applied);
        totals.push(r.total);
    }
    assert!(
        totals[5] < totals[0],
        "backbone loss did not decrease: {totals:?}"
    );
    assert_eq!(flat_params(&t.model.gs_head), gs_before);
    let ckpt = tmp.path().join("backbone.safetensors");
    envision4d_model::checkpoint::save_checkpoint(&t.model, &c.model, &ckpt).unwrap();

    // Ablation variants start from the same stage-1 weights: linear velocity keeps its own
    // 6-channel motion head, post-layer keeps every weight.
    for (motion, placement) in [
        (
            envision4d_model::config::MotionModel::LinearVelocity,
            envision4d_model::config::TemporalPlacement::InLayer,
        ),
        (
            envision4d_model::config::MotionModel::Lifting,
            envision4d_model::config::TemporalPlacement::PostLayer,
        ),
    ] {
        let mut v = c.clone();
        v.stage = Stage::Envision4d;
        v.init_checkpoint = Some(ckpt.clone());
        v.model.motion_model = motion;
        v.model.temporal_attention = placement;
        let m = envision4d_train::step::build_model(&v, &device)
            .expect("variant initialises from stage 1");
        assert_eq!(
            flat_params(&m.aggregator.frame_blocks),
            flat_params(&t.model.aggregator.frame_blocks)
        );
        assert_eq!(flat_params(&m.depth_head), flat_params(&t.model.depth_head));
        assert_eq!(m.aggregator.placement, placement);
    }

    // `init_fresh` keeps the motion head and the temporal blocks out of the checkpoint (the
    // motion benchmark's variants all retrain their motion from scratch); the rest loads.
    let mut v = c.clone();
    v.stage = Stage::Envision4d;
    v.init_checkpoint = Some(ckpt.clone());
    let kept = envision4d_train::step::build_model(&v, &device).unwrap();
    assert_eq!(
        flat_params(&kept.motion_head),
        flat_params(&t.model.motion_head)
    );
    v.init_fresh = vec![
        envision4d_train::config::FreshGroup::MotionHead,
        envision4d_train::config::FreshGroup::TimeBlocks,
    ];
    let fresh = envision4d_train::step::build_model(&v, &device).unwrap();
    assert_ne!(
        flat_params(&fresh.motion_head),
        flat_params(&t.model.motion_head)
    );
    assert_ne!(
        flat_params(&fresh.aggregator.time_blocks),
        flat_params(&t.model.aggregator.time_blocks)
    );
    assert_eq!(
        flat_params(&fresh.depth_head),
        flat_params(&t.model.depth_head)
    );

    let mut s = config_at(&data, &tmp.path().join("stage2"));
    s.teacher = Teacher::Backbone;
    s.init_checkpoint = Some(ckpt);
    s.progressive.warmup_iterations = 0;
    let mut t2 = Trainer::new(s, &device).unwrap();
    let b2 = envision4d_train::batch::Batch::from_clips(&[hc], 2, false, &device).unwrap();
    let r = t2.train_step(&b2).unwrap();
    assert_eq!(r.outcome, StepOutcome::Applied);
    assert!(r.camera.is_finite() && r.camera > 0.0 && r.psnr.is_some());
}

/// Guards `--devices` data parallelism (shards on their own threads, gradients gathered on
/// the first device): two shards of one clip each on two devices (here
/// the same CPU twice) give the gradients of one batch of both clips (Adam's first step is
/// nearly scale-invariant, so the gradients themselves are compared: a missing or doubled
/// 1/n would show), with clips of different sky fractions (the depth term's pooling).
#[test]
fn data_parallel_gradients_equal_single_device_gradients() {
    use burn::optim::GradientsParams;
    use envision4d_train::parallel::ParallelGradients;
    let device = Device::flex().autodiff();
    let mut c = tiny_config();
    c.optim.batch_size = 2;
    c.progressive.warmup_iterations = 0;
    let clips = [crate::common::synth_clip(3), crate::common::synth_clip(9)];
    let sky = |c: &envision4d_data::HostClip| c.depths[0].iter().filter(|d| **d == 0.0).count();
    assert_ne!(
        sky(&clips[0]),
        sky(&clips[1]),
        "pick clips whose sky fractions differ"
    );
    let whole = envision4d_train::batch::Batch::from_clips(&clips, 2, true, &device).unwrap();
    let shards: Vec<_> = clips
        .iter()
        .map(|c| {
            envision4d_train::batch::Batch::from_clips(std::slice::from_ref(c), 2, true, &device)
                .unwrap()
        })
        .collect();
    let mut t = Trainer::new(c, &device).unwrap();
    let single = {
        let mut g = t.loss(&whole, 0).unwrap().total.backward();
        GradientsParams::from_params(&mut g, &t.model, &t.split.trainable)
    };
    let ParallelGradients::Ready { grads: par, .. } = t
        .parallel_gradients(
            &shards,
            &[device.clone(), device.clone()],
            0,
            envision4d_train::parallel::GradientReduce::Gather,
        )
        .unwrap()
    else {
        panic!("parallel step not finite")
    };
    let (diff, largest, compared) = crate::common::grad_diff(&t.model, &single, &par);
    assert!(compared > 100, "only {compared} gradients compared");
    assert!(
        diff <= 1e-4 * largest,
        "gradients differ by {diff} (largest {largest})"
    ); // Burn's collectives: where the backend has them (CUDA) the all-reduced sum equals the
       // gathered one; where it has none (burn-flex here) the step is an error naming the
       // all-reduce, not a hang or an abort.
    match t.parallel_gradients(
        &shards,
        &[device.clone(), device.clone()],
        0,
        envision4d_train::parallel::GradientReduce::AllReduce,
    ) {
        Ok(ParallelGradients::Ready { grads: red, .. }) => {
            let (diff, largest, _) = crate::common::grad_diff(&t.model, &par, &red);
            assert!(diff <= 1e-6 * largest, "all-reduce differs by {diff}");
        }
        Ok(_) => panic!("all-reduce step not finite"),
        Err(e) => assert!(e.to_string().contains("all-reduce"), "{e}"),
    }
}

/// Guards one writer per run directory: while another holder has `run.out_dir` locked, a
/// run on it (fresh or `--resume`) is refused naming the directory and the holder, before
/// writing anything; once the holder is gone, the lock file it left behind does not block.
#[test]
fn a_locked_run_directory_is_refused() {
    use envision4d_data::lock::{DirLock, LOCK_FILE};
    let tmp = tempfile::tempdir().unwrap();
    let data = tmp.path().join("data");
    write_synth_dataset(&data, 4, 4);
    let device = Device::flex().autodiff();
    let mut cfg = config_at(&data, &tmp.path().join("run"));
    cfg.optim.iterations = 1;
    let out = cfg.run.out_dir.clone();
    std::fs::create_dir_all(&out).unwrap();
    let held = DirLock::acquire(&out, "run.out_dir").unwrap();
    for resume in [None, Some(out.clone())] {
        let opts = RunOptions {
            resume,
            ..Default::default()
        };
        let err = run(cfg.clone(), &device, opts, &mut Quiet)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("in use") && err.contains(&out.display().to_string()),
            "{err}"
        );
        assert!(
            err.contains(&format!("pid {}", std::process::id())),
            "{err}"
        );
    }
    assert!(!out.join("config.toml").exists(), "a refused run wrote");
    drop(held);
    assert!(out.join(LOCK_FILE).exists());
    run(cfg, &device, RunOptions::default(), &mut Quiet).unwrap();
}
