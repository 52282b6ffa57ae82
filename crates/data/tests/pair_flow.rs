//! The pairwise scene-flow truth (`motion_truth`) read back from a written synthetic clip must
//! agree with the ray tracer's own next-frame flow, and its far-pair flow must carry each
//! object's pixels onto that object in the later frame.

use envision4d_data::synth::{render_clip, write_clip, Preset, SynthConfig};
use envision4d_data::{
    Clip, ClipDataset, ClipSpec, DatasetConfig, Fit, FitMode, HostClip, Layout, Vec3,
};
use std::path::Path;
use std::sync::Arc;

const H: usize = 48;
const W: usize = 64;
const FRAMES: usize = 5;

fn dataset_config(fit: (usize, usize)) -> DatasetConfig {
    DatasetConfig {
        layout: Layout::Synth { stride: 1 },
        spec: ClipSpec {
            context: 1,
            future: FRAMES - 1,
            frame_step: 1,
        },
        fit: Fit {
            mode: FitMode::Resize,
            height: fit.0,
            width: fit.1,
        },
        cache_clips: 0,
    }
}

/// Writes one clip of `preset` and reads it back at `fit` size: the decoded clip (its raw
/// ground truth) and the host clip (the truth on the frame grid).
fn written_clip(
    dir: &Path,
    preset: Preset,
    seed: u64,
    fit: (usize, usize),
) -> (Arc<Clip>, HostClip) {
    let cfg = SynthConfig {
        width: W,
        height: H,
        frames: FRAMES,
        preset,
        seed,
        supersample: 1,
    };
    let clip = render_clip(&cfg, 0, || {}).unwrap();
    write_clip(&dir.join("clip_000000"), &clip).unwrap();
    let clip = ClipDataset::open(dir, dataset_config(fit))
        .unwrap()
        .load(0)
        .unwrap();
    let host = HostClip::from_clip(&clip).unwrap();
    (clip, host)
}

/// Guards the pair flow against the stored flow: from frame t to t+1 it equals the tracer's
/// `flow/*.exr` on every pixel with a surface (within the f32 depth round trip), and sky has
/// no truth.
#[test]
fn next_frame_pair_flow_equals_the_stored_flow() {
    let dir = tempfile::tempdir().unwrap();
    let (raw, clip) = written_clip(dir.path(), Preset::Urban, 5, (H, W));
    assert_eq!(clip.motion_truth.len(), FRAMES);
    let mut moving = 0;
    for t in 0..FRAMES - 1 {
        let truth = clip.motion_truth[t]
            .as_ref()
            .expect("synthetic frames have truth");
        let to = &clip.motion_truth[t + 1].as_ref().unwrap().objects;
        let flow = truth.flow_to(to);
        let stored = raw.gt[t].flow.as_ref().unwrap();
        let depth = &raw.gt[t].depth.as_ref().unwrap().map;
        for v in 0..H {
            for u in 0..W {
                let z = depth.get(v, u, 0) as f64;
                let got = flow[v * W + u];
                if z <= 0.0 {
                    assert_eq!(got, None, "sky pixel ({v},{u}) has flow truth");
                    continue;
                }
                let want = Vec3::new(
                    stored.get(v, u, 0) as f64,
                    stored.get(v, u, 1) as f64,
                    stored.get(v, u, 2) as f64,
                );
                let got = got.expect("a surface pixel has truth");
                moving += usize::from(want.norm() > 1e-4);
                let tol = 2e-3 + 1e-5 * z * z;
                assert!(
                    (got - want).norm() < tol,
                    "({v},{u}) t {t}: pair flow {got:?}, stored {want:?}"
                );
            }
        }
    }
    assert!(moving > 20, "too few moving pixels to test: {moving}");
}

/// Guards the far pairs (0 → 4, four frames of non-linear motion): each object pixel moved by
/// its truth and projected with frame 4's true camera lands, where it is visible at the depth
/// it should have, on a pixel of the same object.
#[test]
fn far_pair_flow_lands_on_the_same_object() {
    let dir = tempfile::tempdir().unwrap();
    let (_, clip) = written_clip(dir.path(), Preset::Urban, 11, (H, W));
    let (a, b) = (
        clip.motion_truth[0].as_ref().unwrap(),
        clip.motion_truth[FRAMES - 1].as_ref().unwrap(),
    );
    let (w2c, k) = clip.cameras[FRAMES - 1];
    let flow = a.flow_to(&b.objects);
    let (mut visible, mut same) = (0, 0);
    for (g, (p, f)) in a.points.iter().zip(&flow).enumerate() {
        let (Some(p), Some(f), id) = (p, f, a.instance[g]) else {
            continue;
        };
        if id == 0 || f.norm() < 0.05 {
            continue;
        }
        let q = w2c.transform_point(*p + *f);
        let Some((x, y)) = k.project(q) else { continue };
        if x < 0.0 || y < 0.0 || x >= W as f64 || y >= H as f64 {
            continue;
        }
        let at = y as usize * W + x as usize;
        let z = clip.depths[FRAMES - 1][at] as f64;
        if (z - q.z).abs() > 0.05 * q.z {
            continue; // occluded at frame 4
        }
        visible += 1;
        same += usize::from(b.instance[at] == id);
    }
    assert!(visible > 20, "too few visible moving pixels: {visible}");
    assert!(
        same * 10 >= visible * 9,
        "{same} of {visible} moved pixels land on their own object"
    );
}

/// Guards the resampling to a smaller frame grid: every frame pixel takes the point and id of
/// one source pixel, so the truth keeps the frame's size and its ids stay those of objects.
#[test]
fn truth_follows_the_frame_grid() {
    let dir = tempfile::tempdir().unwrap();
    let (_, clip) = written_clip(dir.path(), Preset::Urban, 5, (H / 2, W / 2));
    let t = clip.motion_truth[0].as_ref().unwrap();
    assert_eq!(t.points.len(), (H / 2) * (W / 2));
    assert_eq!(t.instance.len(), (H / 2) * (W / 2));
    assert!(t
        .instance
        .iter()
        .all(|&id| id == 0 || t.objects.iter().any(|o| o.id == id)));
    assert!(t.points.iter().any(Option::is_some));
}

/// Guards `frame_step`: a window of every other frame reads frames 0, 2, 4 with *their*
/// cameras and object poses (not 0, 1, 2's), so the pair flow of its frames 0 → 1 is the
/// clip's 0 → 2 flow; a step whose span exceeds the clip gives no window, an error naming
/// the frames needed.
#[test]
fn frame_step_windows_take_every_kth_frame_with_its_truth() {
    let dir = tempfile::tempdir().unwrap();
    let (raw, full) = written_clip(dir.path(), Preset::Urban, 7, (H, W));
    let stepped = |step: usize, frames: usize| DatasetConfig {
        spec: ClipSpec {
            context: 1,
            future: frames - 1,
            frame_step: step,
        },
        ..dataset_config((H, W))
    };
    let ds = ClipDataset::open(dir.path(), stepped(2, 3)).unwrap();
    assert_eq!(ds.len(), 1, "5 frames hold one window spanning 5");
    assert_eq!(ds.entries()[0].frame_numbers, vec![0, 2, 4]);
    let clip = ds.load(0).unwrap();
    assert_eq!(clip.frame_paths[1], raw.frame_paths[2]);
    assert_eq!(clip.gt[1].world_to_camera, raw.gt[2].world_to_camera);
    let host = HostClip::from_clip(&clip).unwrap();
    let (a, b) = (
        host.motion_truth[0].as_ref().unwrap(),
        host.motion_truth[1].as_ref().unwrap(),
    );
    let want = full.motion_truth[0]
        .as_ref()
        .unwrap()
        .flow_to(&full.motion_truth[2].as_ref().unwrap().objects);
    let got = a.flow_to(&b.objects);
    assert_eq!(got, want);
    assert!(
        got.iter().flatten().any(|f| f.norm() > 1e-3),
        "no motion to test"
    );

    let err = ClipDataset::open(dir.path(), stepped(3, 3)).unwrap_err();
    assert!(err.to_string().contains("no usable clips"), "{err}");
    let err = ClipDataset::open(dir.path(), stepped(0, 3)).unwrap_err();
    assert!(err.to_string().contains("frame_step"), "{err}");
}
