//! The motion diagnostics of `[loss]` (`dynamic_weight`, `lambda_flow`): the truth they
//! read, the errors without it, and that the flow term reaches the motion head.

use crate::common::{batch, synth_clip, tiny_config, write_synth_dataset, FRAMES};
use burn::tensor::Device;
use envision4d_data::HostClip;
use envision4d_train::batch::Batch;
use envision4d_train::config::{LossConfig, Purpose};
use envision4d_train::{StepOutcome, Trainer};
use std::path::Path;

/// Clips of the synthetic layout read back from disk, with their masks and motion truth.
fn truth_clips(root: &Path, n: u64) -> Vec<HostClip> {
    write_synth_dataset(root, n, FRAMES);
    let c = tiny_config();
    let ds = envision4d_train::dataset::open_dataset(&c.data, &c.model, root, Purpose::Train)
        .expect("dataset opens");
    (0..n as usize)
        .map(|i| HostClip::from_clip(&ds.load(i).expect("clip loads")).expect("host clip"))
        .collect()
}

fn loss_with(dynamic_weight: f64, lambda_flow: f64) -> LossConfig {
    LossConfig {
        dynamic_weight,
        lambda_flow,
        ..LossConfig::default()
    }
}

/// Guards the mask tensor the weighted rendering loss reads: it must hold exactly the
/// clips' dynamic masks, frame by frame (a shifted or transposed mask would weight the
/// wrong pixels), and a dataset without masks must be an error naming the key, not a
/// silently unweighted loss.
#[test]
fn dynamic_masks_reach_the_batch_or_the_key_is_named() {
    let tmp = tempfile::tempdir().unwrap();
    let clips = truth_clips(tmp.path(), 2);
    let device = Device::flex();
    let b = Batch::for_training(&clips, 2, true, &loss_with(3.0, 0.0), &device).unwrap();
    let dynamic = b.dynamic.expect("masks asked for");
    let [bsz, n, one, h, w] = dynamic.dims();
    assert_eq!((bsz, n, one), (2, FRAMES, 1));
    let got: Vec<f32> = dynamic.into_data().iter::<f32>().collect();
    let mut want = vec![];
    for c in &clips {
        for t in 0..n {
            let m = c.dynamic_masks[t].as_ref();
            want.extend((0..h * w).map(|p| m.map_or(0.0, |m| f32::from(u8::from(m[p])))));
        }
    }
    assert_eq!(got, want);
    assert!(
        want.iter().any(|&v| v > 0.0),
        "no moving pixel: the test proves nothing"
    );
    assert!(b.motion.is_none(), "flow truth built without lambda_flow");
    let err = Batch::for_training(&[synth_clip(7)], 2, true, &loss_with(3.0, 0.0), &device)
        .unwrap_err()
        .to_string();
    assert!(err.contains("loss.dynamic_weight"), "{err}");
    let err = Batch::for_training(&[synth_clip(7)], 2, true, &loss_with(0.0, 1.0), &device)
        .unwrap_err()
        .to_string();
    assert!(err.contains("loss.lambda_flow"), "{err}");
}

/// Guards the flow diagnostic end to end (a target in the wrong axes or unit, or a term
/// that never reaches the motion head, would leave it flat): with only the motion head
/// training, a few steps on one batch must shrink its mean L1 distance to the exact flow,
/// and the paper's loss alone must not report the term.
#[test]
fn the_flow_term_pulls_the_motion_head_to_the_exact_flow() {
    let tmp = tempfile::tempdir().unwrap();
    let clips = truth_clips(tmp.path(), 1);
    let device = Device::flex().autodiff();
    let mut cfg = tiny_config();
    cfg.progressive.warmup_iterations = 0;
    cfg.loss = loss_with(0.0, 1.0);
    cfg.loss.lambda_lpips = 0.0;
    cfg.optim.lr = 3e-3;
    use envision4d_train::config::FreezeGroup::*;
    cfg.freeze = vec![
        PatchEmbed,
        FrameBlocks,
        GlobalBlocks,
        Tokens,
        CameraHead,
        DepthHead,
        GsHead,
        FuturePose,
    ];
    let b = Batch::for_training(&clips, 2, true, &cfg.loss, &device).unwrap();
    let mut t = Trainer::new(cfg.clone(), &device).unwrap();
    let mut flows = vec![];
    for _ in 0..8 {
        let r = t.train_step(&b).unwrap();
        assert_eq!(r.outcome, StepOutcome::Applied);
        flows.push(r.flow.expect("the flow term is on"));
    }
    assert!(
        flows[7] < 0.8 * flows[0],
        "the flow term did not fall: {flows:?}"
    );
    cfg.loss = loss_with(0.0, 0.0);
    cfg.loss.lambda_lpips = 0.0;
    let mut plain = Trainer::new(cfg, &device).unwrap();
    let r = plain.train_step(&batch(2, true, &device)).unwrap();
    assert_eq!(r.flow, None);
}

/// Guards the config checks of the diagnostics: the flow term on a model without motion,
/// or either on the backbone stage (which renders nothing), is refused naming the key.
#[test]
fn motion_diagnostics_refused_where_they_cannot_act() {
    let text = std::fs::read_to_string(crate::common::config_path("synth-tiny.toml")).unwrap();
    let parse = |t: &str| envision4d_train::parse(t, Path::new("x.toml"));
    let ok = text.replace(
        "lambda_lpips = 0.0",
        "lambda_lpips = 0.0\nlambda_flow = 0.5",
    );
    assert!(parse(&ok).is_ok(), "{:?}", parse(&ok).err());
    assert!(
        !text.contains("[ablation]"),
        "the test appends its own table"
    );
    let err = parse(&format!("{ok}\n[ablation]\nmotion = \"off\"\n"))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("loss.lambda_flow") && err.contains("off"),
        "{err}"
    );
    let err = parse(&ok.replace("stage = \"envision4d\"", "stage = \"backbone\""))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("loss.lambda_flow") && err.contains("backbone"),
        "{err}"
    );
    let lone = text.replace(
        "lambda_lpips = 0.0",
        "lambda_lpips = 0.0\nflow_balanced = true",
    );
    let err = parse(&lone).unwrap_err().to_string();
    assert!(err.contains("loss.flow_balanced"), "{err}");
    let neg = text.replace(
        "lambda_lpips = 0.0",
        "lambda_lpips = 0.0\ndynamic_weight = -1.0",
    );
    let err = parse(&neg).unwrap_err().to_string();
    assert!(
        err.contains("loss.dynamic_weight") && err.contains("-1"),
        "{err}"
    );
}

/// Guards playback augmentation against desynchronising the diagnostics' truth from the
/// frames: a reversed window reverses the masks and the motion truth with the frames, and a
/// held window has no moving pixel and the same truth on every frame (so zero flow).
#[test]
fn playback_keeps_masks_and_motion_truth_with_their_frames() {
    use envision4d_train::augment::{apply, Playback};
    let tmp = tempfile::tempdir().unwrap();
    let clip = truth_clips(tmp.path(), 1).remove(0);
    let n = clip.frames.len();
    assert_eq!((clip.dynamic_masks.len(), clip.motion_truth.len()), (n, n));
    let mut rev = clip.clone();
    apply(&mut rev, Playback::Reversed);
    for k in 0..n {
        assert_eq!(rev.dynamic_masks[k], clip.dynamic_masks[n - 1 - k]);
        assert_eq!(rev.motion_truth[k], clip.motion_truth[n - 1 - k]);
    }
    let mut held = clip.clone();
    apply(&mut held, Playback::Held);
    assert!(held.motion_truth.iter().all(|t| *t == clip.motion_truth[0]));
    assert!(held.dynamic_masks.iter().flatten().flatten().all(|&on| !on));
}
