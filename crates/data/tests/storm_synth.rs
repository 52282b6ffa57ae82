//! The synthetic world written in STORM's Waymo layout and read back by the Waymo reader:
//! poses, intrinsics and LiDAR depth must decode to the world's exact truth.

use envision4d_data::synth::{render_clip, write_storm_scene, ClipRender, Preset, SynthConfig};
use envision4d_data::{
    ClipDataset, ClipSpec, DatasetConfig, DepthSource, Fit, FitMode, HostClip, Layout, WaymoConfig,
};
use std::path::Path;

const H: usize = 48;
const W: usize = 64;
const FRAMES: usize = 6;

fn clip() -> ClipRender {
    let cfg = SynthConfig {
        width: W,
        height: H,
        frames: FRAMES,
        preset: Preset::Urban,
        seed: 3,
        supersample: 1,
    };
    render_clip(&cfg, 0, || {}).unwrap()
}

/// The training split's windows, with the LiDAR points read or not.
fn open_with(root: &Path, lidar: bool) -> ClipDataset {
    ClipDataset::open(
        root,
        DatasetConfig {
            layout: Layout::Waymo(WaymoConfig {
                lidar,
                ..WaymoConfig::training("training", 1, None)
            }),
            spec: ClipSpec {
                context: 2,
                future: 2,
                frame_step: 1,
            },
            fit: Fit {
                mode: FitMode::Resize,
                height: H,
                width: W,
            },
            cache_clips: 0,
        },
    )
    .unwrap()
}

fn open(root: &Path) -> ClipDataset {
    open_with(root, true)
}

/// Guards the STORM writer and reader together: camera poses (through ego_to_world,
/// cam_to_ego and the OpenCV/Waymo axis change) and intrinsics come back as the world's.
#[test]
fn storm_scene_poses_decode_to_the_truth() {
    let truth = clip();
    let dir = tempfile::tempdir().unwrap();
    write_storm_scene(&dir.path().join("training/000"), &truth).unwrap();
    let ds = open(dir.path());
    // Timesteps 0..5: the reader lists range(min, max), so 5 frames give 2 windows of 4.
    assert_eq!(ds.len(), 2);
    let c = ds.load(1).unwrap();
    for (k, gt) in c.gt.iter().enumerate() {
        let want = &truth.cameras[1 + k];
        let got = gt.world_to_camera.unwrap();
        for r in 0..4 {
            for col in 0..4 {
                let d = (got.0[r][col] - want.world_to_camera.0[r][col]).abs();
                assert!(d < 1e-9, "frame {} entry ({r},{col}) off by {d}", 1 + k);
            }
        }
        assert_eq!(gt.intrinsics.unwrap(), want.intrinsics);
    }
}

/// Guards `frame_step` on the Waymo reader: timesteps 0..5 hold no window of 4 every other
/// timestep (it spans 7), so the scene is skipped, not read with consecutive timesteps; with
/// a window of 2 every other timestep, the frames are timesteps (0, 2), (1, 3), (2, 4) with
/// their own cameras.
#[test]
fn storm_frame_step_takes_every_other_timestep() {
    let truth = clip();
    let dir = tempfile::tempdir().unwrap();
    write_storm_scene(&dir.path().join("training/000"), &truth).unwrap();
    // Windows of `frames` frames, every other timestep, at the frame size.
    let every_other = |frames: usize| {
        ClipDataset::open(
            dir.path(),
            DatasetConfig {
                layout: Layout::Waymo(WaymoConfig::training("training", 1, None)),
                spec: ClipSpec {
                    context: 1,
                    future: frames - 1,
                    frame_step: 2,
                },
                fit: Fit {
                    mode: FitMode::Resize,
                    height: H,
                    width: W,
                },
                cache_clips: 0,
            },
        )
    };
    assert!(
        every_other(4).is_err(),
        "a window spanning 7 timesteps read from 5"
    );
    let ds = every_other(2).unwrap();
    let numbers: Vec<_> = ds
        .entries()
        .iter()
        .map(|e| e.frame_numbers.clone())
        .collect();
    assert_eq!(numbers, vec![vec![0, 2], vec![1, 3], vec![2, 4]]);
    let c = ds.load(2).unwrap();
    let (got, want) = (
        c.gt[1].world_to_camera.unwrap(),
        truth.cameras[4].world_to_camera,
    );
    for r in 0..4 {
        for col in 0..4 {
            assert!(
                (got.0[r][col] - want.0[r][col]).abs() < 1e-9,
                "entry ({r},{col})"
            );
        }
    }
}

/// Guards LiDAR depth on the frame grid: points land on the pixel they were taken from with
/// its exact z-depth; without `lidar/` the quarter-grid means land at the cell centres; the
/// training reader reads neither.
#[test]
fn storm_lidar_depth_lands_on_the_right_pixels() {
    let truth = clip();
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("training/000");
    write_storm_scene(&scene, &truth).unwrap();
    let host = HostClip::from_clip(&open(dir.path()).load(0).unwrap()).unwrap();
    assert_eq!(host.eval_depth_source, Some(DepthSource::LidarPoints));
    assert_eq!(host.eval_depths.len(), 4);
    let depth0 = &truth.frames[0].depth;
    let mut hits = 0;
    for (i, &z) in host.eval_depths[0].as_ref().unwrap().iter().enumerate() {
        if z > 0.0 {
            hits += 1;
            let (v, u) = (i / W, i % W);
            assert!(
                v % 8 == 0 && u % 2 == 0,
                "return at ({v}, {u}) off the scan lines"
            );
            assert!(
                (z - depth0[i]).abs() <= 1e-4 * depth0[i],
                "{z} vs {}",
                depth0[i]
            );
        }
    }
    assert!(hits > 20, "only {hits} LiDAR returns");

    // Training's reader leaves the LiDAR out altogether.
    let unread = HostClip::from_clip(&open_with(dir.path(), false).load(0).unwrap()).unwrap();
    assert_eq!(unread.eval_depth_source, None);
    std::fs::remove_dir_all(scene.join("lidar")).unwrap();
    let host = HostClip::from_clip(&open(dir.path()).load(0).unwrap()).unwrap();
    assert_eq!(host.eval_depth_source, Some(DepthSource::LidarGrid));
    let grid = host.eval_depths[0].as_ref().unwrap();
    let mut cells = 0;
    for vq in 0..H / 4 {
        for uq in 0..W / 4 {
            // Returns of this cell: scan-line rows inside it, depth in range.
            let zs: Vec<f32> = (4 * vq..4 * vq + 4)
                .filter(|v| v % 8 == 0)
                .flat_map(|v| (4 * uq..4 * uq + 4).map(move |u| depth0[v * W + u]))
                .filter(|&z| z > 0.0 && z <= 75.0)
                .collect();
            let at = grid[(4 * vq + 2) * W + 4 * uq + 2];
            if zs.is_empty() {
                assert_eq!(at, 0.0, "cell ({vq}, {uq}) has no return");
            } else {
                cells += 1;
                let mean = zs.iter().sum::<f32>() / zs.len() as f32;
                assert!(
                    (at - mean).abs() <= 1e-4 * mean,
                    "cell ({vq}, {uq}): {at} vs {mean}"
                );
            }
        }
    }
    assert!(cells > 5);
    assert_eq!(grid.iter().filter(|z| **z > 0.0).count(), cells);
}
