//! Playback augmentation: reversed and held windows keep frames, cameras and depth paired,
//! and the draws are a function of (seed, sample); the `[data]` table's window keys.

use crate::common::{config_path, synth_clip, write_synth_dataset, H, W};
use envision4d_train::augment::{apply, playback, Playback};
use envision4d_train::batch::pose_encodings;
use envision4d_train::config::Augment;
use std::path::Path;

/// Guards labels drifting from their frames under reversal: a reversed window's pose labels
/// are exactly those of the forward window's cameras taken backwards (the ego then drives
/// backwards: the last camera is behind the new frame 0), and frame k holds old frame N-1-k.
#[test]
fn reversed_window_keeps_frames_cameras_and_depth_paired() {
    let clip = synth_clip(3);
    let n = clip.frames.len();
    let mut rev = clip.clone();
    apply(&mut rev, Playback::Reversed);
    for k in 0..n {
        assert_eq!(rev.frames[k], clip.frames[n - 1 - k]);
        assert_eq!(rev.depths[k], clip.depths[n - 1 - k]);
        assert_eq!(rev.cameras[k].0, clip.cameras[n - 1 - k].0);
    }
    let backwards: Vec<_> = clip.cameras.iter().rev().copied().collect();
    assert_eq!(
        pose_encodings(&rev.cameras, H, W),
        pose_encodings(&backwards, H, W)
    );
    let forward = pose_encodings(&clip.cameras, H, W);
    let reversed = pose_encodings(&rev.cameras, H, W);
    // absT_quaR_FoV: t_z of the last frame (OpenCV z forward, t = -R·c) flips sign.
    let tz = |p: &[f32]| p[(n - 1) * 9 + 2];
    assert!(
        tz(&forward) < -0.5 && tz(&reversed) > 0.5,
        "t_z forward {} reversed {}",
        tz(&forward),
        tz(&reversed)
    );
}

/// Guards a held window that still moves: every frame, camera and depth map is frame 0's,
/// so every pose label is the identity (zero translation, unit quaternion).
#[test]
fn held_window_stands_still() {
    let clip = synth_clip(4);
    let mut held = clip.clone();
    apply(&mut held, Playback::Held);
    assert!(held.frames.iter().all(|f| *f == clip.frames[0]));
    assert!(held.depths.iter().all(|d| *d == clip.depths[0]));
    let poses = pose_encodings(&held.cameras, H, W);
    for p in poses.chunks_exact(9) {
        assert!(p[..6].iter().all(|v| v.abs() < 1e-5), "{p:?}");
        assert!((p[6] - 1.0).abs() < 1e-5, "{p:?}");
    }
}

/// Guards the draws: off by default (every window forward), deterministic in (seed,
/// sample), and close to the configured fractions over many samples.
#[test]
fn playback_draws_follow_the_fractions_and_the_seed() {
    let off = Augment::default();
    assert!((0..1000).all(|k| playback(&off, 0, k) == Playback::Forward));
    let a = Augment {
        reverse: 0.4,
        hold: 0.1,
    };
    let draws: Vec<_> = (0..4000).map(|k| playback(&a, 7, k)).collect();
    let again: Vec<_> = (0..4000).map(|k| playback(&a, 7, k)).collect();
    assert_eq!(draws, again);
    let other: Vec<_> = (0..4000).map(|k| playback(&a, 8, k)).collect();
    assert_ne!(draws, other);
    let share = |p| draws.iter().filter(|&&d| d == p).count() as f64 / draws.len() as f64;
    assert!((share(Playback::Reversed) - 0.4).abs() < 0.03);
    assert!((share(Playback::Held) - 0.1).abs() < 0.02);
}

/// Guards `[data.augment]` typos and impossible fractions being accepted silently.
#[test]
fn augment_config_errors_name_the_key() {
    let text = std::fs::read_to_string(config_path("synth-tiny.toml")).unwrap();
    let with = |table: &str| format!("{text}\n[data.augment]\n{table}\n");
    let parse = |t: String| envision4d_train::parse(&t, Path::new("x.toml"));
    let ok = parse(with("reverse = 0.4\nhold = 0.1")).unwrap();
    assert_eq!(ok.data.augment.reverse, 0.4);
    let err = parse(with("revers = 0.4")).unwrap_err().to_string();
    assert!(err.contains("revers"), "{err}");
    let err = parse(with("reverse = 1.5")).unwrap_err().to_string();
    assert!(
        err.contains("data.augment.reverse") && err.contains("1.5"),
        "{err}"
    );
    let err = parse(with("reverse = 0.7\nhold = 0.5"))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("data.augment") && err.contains("at most 1"),
        "{err}"
    );
}

/// Guards `[data] frame_step` being parsed but not reaching the windows (a run that believes
/// it sees twice the motion and reads consecutive frames), and zero being accepted.
#[test]
fn frame_step_reaches_the_windows_and_zero_is_refused() {
    use envision4d_train::config::Purpose;
    let text = std::fs::read_to_string(config_path("synth-tiny.toml")).unwrap();
    let with = |v: &str| text.replace("stride = 2", &format!("stride = 1\nframe_step = {v}"));
    let parse = |t: String| envision4d_train::parse(&t, Path::new("x.toml"));
    let err = parse(with("0")).unwrap_err().to_string();
    assert!(err.contains("data.frame_step"), "{err}");
    let mut cfg = parse(with("2")).unwrap();
    assert_eq!(cfg.data.frame_step, 2);
    let dir = tempfile::tempdir().unwrap();
    write_synth_dataset(dir.path(), 1, 9);
    cfg.model.future_frames = 2;
    let ds =
        envision4d_train::dataset::open_dataset(&cfg.data, &cfg.model, dir.path(), Purpose::Train)
            .unwrap();
    let numbers: Vec<_> = ds
        .entries()
        .iter()
        .map(|e| e.frame_numbers.clone())
        .collect();
    assert_eq!(
        numbers,
        vec![vec![0, 2, 4, 6], vec![1, 3, 5, 7], vec![2, 4, 6, 8]]
    );
}
