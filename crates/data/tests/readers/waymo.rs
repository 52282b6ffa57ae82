//! The Waymo layout (the official loader's rules, training windows) and STORM ground truth.

use crate::{config, write_png, write_text};
use envision4d_data::layout::waymo::OPENCV_TO_WAYMO_CAMERA;
use envision4d_data::npy::encode_npy_f32;
use envision4d_data::{ClipDataset, Layout, Vec3, WaymoConfig};

/// Guards the official Waymo loader rules: timesteps parsed from names, range(min, max)
/// (last excluded), clip k starts at k * interval, other cameras ignored, short scenes
/// skipped and counted, a gap in the range fails only its clip.
#[test]
fn waymo_layout_clips() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("validation/000/images");
    for t in 0..=20 {
        if t != 12 {
            write_png(&scene.join(format!("{t:06}_0.png")), 8, 6, t as u8);
        }
        write_png(&scene.join(format!("{t:06}_1.png")), 8, 6, 0);
    }
    for t in 0..3 {
        write_png(
            &dir.path()
                .join(format!("validation/001/images/{t:06}_0.png")),
            8,
            6,
            0,
        );
    }
    let cfg = WaymoConfig {
        interval: 5,
        ..WaymoConfig::default()
    };
    let ds = ClipDataset::open(dir.path(), config(Layout::Waymo(cfg), 6, 8)).unwrap();
    // 20 listed timesteps (0..20): starts 0, 5, 10, 15 fit 4 frames.
    assert_eq!(ds.len(), 4);
    assert_eq!(ds.skipped(), 1);
    let ids: Vec<&str> = ds.entries().iter().map(|e| e.id.as_str()).collect();
    assert_eq!(
        ids,
        [
            "validation/000#0",
            "validation/000#1",
            "validation/000#2",
            "validation/000#3"
        ]
    );
    assert!(ds.entries()[3].frames[0].ends_with("000015_0.png"));
    assert!(ds.load(0).is_ok());
    let err = ds.load(2).unwrap_err().to_string();
    assert!(err.contains("000012_0.png"), "{err}");
}

/// Guards training windows on the Waymo layout: they come from the split named (not the
/// evaluation split next to it), start every `stride` frames and may overlap, and
/// `max_per_scene` caps them; the release's rule (a clip no longer than the interval)
/// still holds for the evaluation reader.
#[test]
fn waymo_training_windows_slide_over_the_training_split() {
    let dir = tempfile::tempdir().unwrap();
    for split in ["training", "validation"] {
        for t in 0..=10 {
            write_png(
                &dir.path().join(format!("{split}/000/images/{t:06}_0.png")),
                8,
                6,
                t as u8,
            );
        }
    }
    // 10 listed timesteps (0..10), windows of 4 frames every 2: starts 0, 2, 4, 6.
    let open = |cfg| ClipDataset::open(dir.path(), config(Layout::Waymo(cfg), 6, 8));
    let ds = open(WaymoConfig::training("training", 2, None)).unwrap();
    let ids: Vec<&str> = ds.entries().iter().map(|e| e.id.as_str()).collect();
    assert_eq!(
        ids,
        [
            "training/000#0",
            "training/000#1",
            "training/000#2",
            "training/000#3"
        ]
    );
    assert!(ds.entries()[1].frames[0].ends_with("training/000/images/000002_0.png"));
    assert!(ds.entries()[1].frames[3].ends_with("000005_0.png"));
    // Every frame: 7 windows; capped at 3.
    assert_eq!(
        open(WaymoConfig::training("training", 1, None))
            .unwrap()
            .len(),
        7
    );
    assert_eq!(
        open(WaymoConfig::training("training", 1, Some(3)))
            .unwrap()
            .len(),
        3
    );
    // The evaluation reader still refuses windows longer than its interval.
    let err = open(WaymoConfig {
        interval: 2,
        ..WaymoConfig::default()
    })
    .unwrap_err()
    .to_string();
    assert!(
        err.contains("num_frames") && err.contains("interval 2"),
        "{err}"
    );
}

/// Guards a stray file with a huge timestamp: the scene must still scan without materialising
/// every timestep up to it (which exhausted memory).
#[test]
fn waymo_stray_huge_timestamp_is_harmless() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("validation/000/images");
    for t in 0..10 {
        write_png(&scene.join(format!("{t:06}_0.png")), 8, 6, t as u8);
    }
    write_png(&scene.join("99999999999999_0.png"), 8, 6, 0);
    let cfg = WaymoConfig {
        interval: 5,
        ..WaymoConfig::default()
    };
    let ds = ClipDataset::open(dir.path(), config(Layout::Waymo(cfg), 6, 8)).unwrap();
    // As the official loader (range(min, max)), the gap up to the stray file yields clips
    // whose missing frames fail at load time; only the span 10 clips can reach is listed.
    assert_eq!(ds.len(), 10);
    assert!(ds.load(0).is_ok() && ds.load(1).is_ok());
    let err = ds.load(2).unwrap_err().to_string();
    assert!(err.contains("000010_0.png"), "{err}");
}

/// Guards STORM ground truth: {t:03d} JPEG names, intrinsics scaled with the resize, the
/// OpenCV world-to-camera built as inv(ego_to_world . cam_to_ego . OPENCV2DATASET), LiDAR
/// depth from depth_flows_4 channel 0, and an unreadable GT file named in the error.
#[test]
fn storm_scene_ground_truth() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("validation/007");
    for t in 0..5 {
        let p = scene.join(format!("images/{t:03}_0.jpg"));
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        image::RgbImage::from_pixel(40, 20, image::Rgb([90, 90, 90]))
            .save(&p)
            .unwrap();
        let e2w = format!("1 0 0 {t}\n0 1 0 0\n0 0 1 0\n0 0 0 1\n");
        write_text(&scene.join(format!("ego_to_world/{t:03}.txt")), &e2w);
        let npy = encode_npy_f32(&[5, 10, 4], &vec![7.0; 200]);
        std::fs::create_dir_all(scene.join("depth_flows_4")).unwrap();
        std::fs::write(scene.join(format!("depth_flows_4/{t:03}_0.npy")), npy).unwrap();
    }
    write_text(&scene.join("intrinsics/0.txt"), "40 40 20 10 0 0 0 0 0\n");
    write_text(
        &scene.join("cam_to_ego/0.txt"),
        "1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n",
    );
    let ds = ClipDataset::open(
        dir.path(),
        config(Layout::Waymo(WaymoConfig::default()), 10, 20),
    )
    .unwrap();
    let clip = ds.load(0).unwrap();
    assert_eq!(clip.gt.len(), 4);
    let gt = &clip.gt[1];
    let k = gt.intrinsics.unwrap();
    assert_eq!((k.fx, k.cx, k.cy), (20.0, 10.0, 5.0));
    // Ego at x = 1 looking along world +x: a point 10 m ahead is at OpenCV (0, 0, 10).
    let p = gt
        .world_to_camera
        .unwrap()
        .transform_point(Vec3::new(11.0, 0.0, 0.0));
    assert!((p - Vec3::new(0.0, 0.0, 10.0)).norm() < 1e-12, "{p:?}");
    // A point to the left (world +y) is at negative OpenCV x.
    assert!(
        gt.world_to_camera
            .unwrap()
            .transform_point(Vec3::new(11.0, 1.0, 0.0))
            .x
            < 0.0
    );
    let depth = gt.depth.as_ref().unwrap();
    assert_eq!((depth.map.height, depth.map.width), (5, 10));
    assert_eq!(depth.map.data[0], 7.0);
    assert_eq!(depth.intrinsics.fx, 10.0);
    let _ = OPENCV_TO_WAYMO_CAMERA;

    write_text(&scene.join("ego_to_world/002.txt"), "1 0 zero 0\n");
    let ds = ClipDataset::open(
        dir.path(),
        config(Layout::Waymo(WaymoConfig::default()), 10, 20),
    )
    .unwrap();
    let err = ds.load(0).unwrap_err().to_string();
    assert!(
        err.contains("ego_to_world/002.txt") && err.contains("\"zero\""),
        "{err}"
    );
    write_text(
        &scene.join("ego_to_world/002.txt"),
        "2 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n",
    );
    let err = ClipDataset::open(
        dir.path(),
        config(Layout::Waymo(WaymoConfig::default()), 10, 20),
    )
    .unwrap()
    .load(0)
    .unwrap_err()
    .to_string();
    assert!(err.contains("not a rigid transform"), "{err}");
}
