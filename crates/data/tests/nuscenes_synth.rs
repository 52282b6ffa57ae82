//! The synthetic world written as an official nuScenes tree and read back: the official
//! split selects its scenes, and poses, intrinsics and LiDAR decode to the world's truth.

use envision4d_data::synth::{render_clip, write_nuscenes_scenes, ClipRender, Preset, SynthConfig};
use envision4d_data::{
    ClipDataset, ClipSpec, DataError, DatasetConfig, DepthSource, Fit, FitMode, HostClip, Layout,
    NuScenesConfig,
};
use std::path::Path;

const H: usize = 48;
const W: usize = 64;

fn clip(seed: u64, frames: usize) -> ClipRender {
    let cfg = SynthConfig {
        width: W,
        height: H,
        frames,
        preset: Preset::Urban,
        seed,
        supersample: 1,
    };
    render_clip(&cfg, 0, || {}).unwrap()
}

fn open(root: &Path, split: &str) -> Result<ClipDataset, DataError> {
    ClipDataset::open(
        root,
        DatasetConfig {
            layout: Layout::NuScenes(NuScenesConfig::new(split, 1, None)),
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
}

/// Guards the nuScenes reader against the writer's truth: `mini_train` and `mini_val`
/// written by two runs into one tree select their own scenes (named by the devkit's lists),
/// keyframes chain in order, and every frame's world-to-camera and intrinsics are exact.
#[test]
fn nuscenes_poses_decode_to_the_truth() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (clip(1, 5), clip(2, 4));
    write_nuscenes_scenes(dir.path(), "mini_train", 0, std::slice::from_ref(&a)).unwrap();
    write_nuscenes_scenes(dir.path(), "mini_val", 0, std::slice::from_ref(&b)).unwrap();
    let train = open(dir.path(), "mini_train").unwrap();
    // 5 keyframes, windows of 4 every frame: 2; the 7 other mini_train scenes are absent.
    assert_eq!(train.len(), 2);
    assert_eq!(train.entries()[0].group, "mini_train/scene-0061");
    assert_eq!(train.skipped(), 1, "the absent scenes are reported once");
    let val = open(dir.path(), "mini_val").unwrap();
    assert_eq!(val.len(), 1);
    assert_eq!(val.entries()[0].group, "mini_val/scene-0103");
    let c = train.load(1).unwrap();
    for (k, gt) in c.gt.iter().enumerate() {
        let want = &a.cameras[1 + k];
        let got = gt.world_to_camera.unwrap();
        for r in 0..4 {
            for col in 0..4 {
                let d = (got.0[r][col] - want.world_to_camera.0[r][col]).abs();
                assert!(d < 1e-9, "frame {} entry ({r},{col}) off by {d}", 1 + k);
            }
        }
        assert_eq!(gt.intrinsics.unwrap(), want.intrinsics);
    }
    // A split name that is not official is an error naming the key.
    let err = open(dir.path(), "validation").unwrap_err().to_string();
    assert!(err.contains("split") && err.contains("mini_val"), "{err}");
}

/// Guards the LiDAR path (sensor frame -> ego -> global -> camera): every sweep point lands
/// on the pixel it was sampled from with that pixel's exact z-depth.
#[test]
fn nuscenes_lidar_lands_on_its_pixels() {
    let dir = tempfile::tempdir().unwrap();
    let a = clip(1, 4);
    write_nuscenes_scenes(dir.path(), "mini_train", 0, std::slice::from_ref(&a)).unwrap();
    let host =
        HostClip::from_clip(&open(dir.path(), "mini_train").unwrap().load(0).unwrap()).unwrap();
    assert_eq!(host.eval_depth_source, Some(DepthSource::LidarPoints));
    for t in 0..4 {
        let truth = &a.frames[t].depth;
        let mut hits = 0;
        for (i, &z) in host.eval_depths[t].as_ref().unwrap().iter().enumerate() {
            if z > 0.0 {
                hits += 1;
                assert!(
                    (i / W).is_multiple_of(8) && (i % W).is_multiple_of(2),
                    "pixel {i} off the scan lines"
                );
                assert!(
                    (z - truth[i]).abs() <= 1e-4 * truth[i],
                    "{z} vs {}",
                    truth[i]
                );
            }
        }
        assert!(hits > 20, "frame {t}: {hits} returns");
    }
}
