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
            (v["kind"] == "step").then(|| (v["step"].as_u64().unwrap(), v["loss"].as_f64().unwrap()))
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
    run(split.clone(), &device, RunOptions { stop_at: Some(2), ..Default::default() }, &mut Quiet).unwrap();
    // Starting again without --resume must refuse rather than overwrite the run.
    let again = run(split.clone(), &device, RunOptions::default(), &mut Quiet);
    assert!(again.unwrap_err().to_string().contains("--resume"));
    let resume = RunOptions { resume: Some(split.run.out_dir.clone()), ..Default::default() };
    let b = run(split.clone(), &device, resume, &mut Quiet).unwrap();
    assert_eq!((a.steps, b.steps), (4, 4));
    assert_eq!(losses(&whole.run.out_dir), losses(&split.run.out_dir));
    let load = |p: &Path| {
        let mut m = envision4d_model::Envision4d::new(&whole.model, &device);
        envision4d_model::checkpoint::load_checkpoint(&mut m, p, envision4d_model::checkpoint::CheckpointKind::Full).unwrap();
        flat_params(&m)
    };
    assert_eq!(load(&a.model), load(&b.model), "resumed parameters differ");
    let kept = list(&split.run.out_dir.join(CHECKPOINT_DIR)).unwrap();
    assert_eq!(kept.iter().map(|k| k.0).collect::<Vec<_>>(), vec![3, 4]);
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
    let (_, last) = list(&c.run.out_dir.join(CHECKPOINT_DIR)).unwrap().pop().unwrap();
    assert!(err.contains(&last.display().to_string()), "{err}");
    let mut m = envision4d_model::Envision4d::new(&c.model, &device);
    envision4d_model::checkpoint::load_checkpoint(&mut m, &last.join(MODEL_FILE), envision4d_model::checkpoint::CheckpointKind::Full).unwrap();
    let log = std::fs::read_to_string(c.run.out_dir.join(LOG_FILE)).unwrap();
    assert!(log.contains("skipped_nonfinite"), "skipped steps are logged");
}

/// Guards the backbone stage and the frozen teacher: stage 1 trains only what plain VGGT has
/// (the Gaussian head gets no update) and lowers its loss; its checkpoint then serves as the
/// `teacher = "backbone"` of stage 2, whose steps apply and carry a camera term.
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
    let hc = envision4d_train::batch::HostClip::from_clip(
        &envision4d_train::data::open_dataset(&c.data, &c.model, &data).unwrap().load(0).unwrap(),
    )
    .unwrap();
    let batch = envision4d_train::batch::Batch::from_clips(&[hc.clone()], 4, true, &device).unwrap();
    let mut totals = vec![];
    for _ in 0..6 {
        let r = t.train_step(&batch).unwrap();
        assert_eq!(r.outcome, StepOutcome::Applied);
        totals.push(r.total);
    }
    assert!(totals[5] < totals[0], "backbone loss did not decrease: {totals:?}");
    assert_eq!(flat_params(&t.model.gs_head), gs_before);
    let ckpt = tmp.path().join("backbone.safetensors");
    envision4d_model::checkpoint::save_checkpoint(&t.model, &c.model, &ckpt).unwrap();

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

/// Guards `--devices` data parallelism: two shards of one clip each on two devices (here
/// the same CPU twice) give the same update as one step on the batch of both clips.
#[test]
fn data_parallel_step_equals_single_device_step() {
    let device = Device::flex().autodiff();
    let mut c = tiny_config();
    c.optim.batch_size = 2;
    c.progressive.warmup_iterations = 0;
    let clips = [crate::common::synth_clip(3), crate::common::synth_clip(4)];
    let whole = envision4d_train::batch::Batch::from_clips(&clips, 2, true, &device).unwrap();
    let shards: Vec<_> = clips
        .iter()
        .map(|c| envision4d_train::batch::Batch::from_clips(std::slice::from_ref(c), 2, true, &device).unwrap())
        .collect();
    let mut single = Trainer::new(c.clone(), &device).unwrap();
    let mut multi = Trainer::new(c, &device).unwrap();
    multi.model = single.model.clone();
    multi.refresh_split();
    let a = single.train_step(&whole).unwrap();
    let b = multi
        .train_step_parallel(&shards, &[device.clone(), device.clone()])
        .unwrap();
    assert_eq!((a.outcome, b.outcome), (StepOutcome::Applied, StepOutcome::Applied));
    assert!((a.total - b.total).abs() < 1e-5 * a.total.abs().max(1.0), "{} vs {}", a.total, b.total);
    let (pa, pb) = (flat_params(&single.model), flat_params(&multi.model));
    let worst = pa.iter().zip(&pb).map(|(x, y)| (x - y).abs()).fold(0.0f32, f32::max);
    // Adam divides by sqrt(v): where a gradient is near zero, summation-order rounding of
    // the shard sums moves the update by a small fraction of lr (1e-3) — not a real difference.
    assert!(worst < 5e-5, "parameters differ by {worst}");
}
