//! Layout readers on small generated trees, and every bad-input case.

use envision4d_data::layout::waymo::OPENCV_TO_WAYMO_CAMERA;
use envision4d_data::npy::encode_npy_f32;
use envision4d_data::{
    decode_image, ClipDataset, ClipSpec, DataError, DatasetConfig, Fit, FitMode, Layout,
    Prefetcher, Vec3, WaymoConfig,
};
use std::path::Path;
use std::sync::Arc;

fn write_png(path: &Path, w: u32, h: u32, shade: u8) {
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    let img = image::RgbImage::from_fn(w, h, |x, y| {
        image::Rgb([shade, (x * 10) as u8, (y * 10) as u8])
    });
    img.save(path).unwrap();
}

fn config(layout: Layout, h: usize, w: usize) -> DatasetConfig {
    DatasetConfig {
        layout,
        spec: ClipSpec {
            context: 2,
            future: 2,
            frame_step: 1,
        },
        fit: Fit {
            mode: FitMode::Resize,
            height: h,
            width: w,
        },
        cache_clips: 4,
    }
}

/// Guards the plain-folder reader: sorted frames, windows by stride, short videos skipped
/// and counted, frames fitted to the configured size.
#[test]
fn folder_layout_windows_and_skips() {
    let dir = tempfile::tempdir().unwrap();
    for i in 0..6 {
        write_png(
            &dir.path().join("a").join(format!("frame_{i:06}.png")),
            20,
            16,
            i as u8 * 40,
        );
    }
    for i in 0..2 {
        write_png(
            &dir.path().join("b").join(format!("frame_{i:06}.png")),
            20,
            16,
            0,
        );
    }
    let ds = ClipDataset::open(dir.path(), config(Layout::Folder { stride: 2 }, 8, 10)).unwrap();
    assert_eq!(ds.len(), 2);
    assert_eq!(ds.skipped(), 1);
    assert!(
        ds.skip_messages()[0].contains("2 frames, but a clip needs 4"),
        "{:?}",
        ds.skip_messages()
    );
    let clip = ds.load(1).unwrap();
    assert_eq!(clip.id, "a@2");
    assert_eq!(clip.frames.len(), 4);
    assert_eq!((clip.frames[0].height, clip.frames[0].width), (8, 10));
    assert_eq!(clip.source_size, (16, 20));
    assert!(clip.frame_paths[0].ends_with("frame_000002.png"));
    // Red channel is constant per frame, so it survives resizing exactly.
    assert!((clip.frames[1].pixel(3, 3)[0] - 120.0 / 255.0).abs() < 1e-5);
}

/// Guards the real-data case: a root that directly holds frames is one video.
#[test]
fn folder_layout_reads_real_clip_if_present() {
    let real = Path::new("/work/shared/data/real/street_taxi_pan");
    if !real.is_dir() {
        return;
    }
    let ds = ClipDataset::open(real, config(Layout::Folder { stride: 4 }, 35, 52)).unwrap();
    assert_eq!(ds.len(), 4);
    assert_eq!(ds.load(0).unwrap().source_size, (272, 640));
}

/// Guards empty folders: an error that names the folder, not a panic or an empty dataset.
#[test]
fn empty_folder_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let err =
        ClipDataset::open(dir.path(), config(Layout::Folder { stride: 1 }, 8, 8)).unwrap_err();
    assert!(matches!(err, DataError::EmptyFolder { .. }), "{err}");
    assert!(err.to_string().contains(&dir.path().display().to_string()));
    let missing = dir.path().join("nope");
    let err = ClipDataset::open(&missing, config(Layout::Folder { stride: 1 }, 8, 8)).unwrap_err();
    assert!(err.to_string().contains("nope"), "{err}");
}

/// Guards each bad-image case: corrupt, truncated, empty and mixed-size frames fail their
/// clip with a message naming the file; the dataset skips and counts it; good clips load.
#[test]
fn bad_images_name_the_file_and_are_skipped() {
    let dir = tempfile::tempdir().unwrap();
    let make = |name: &str| {
        for i in 0..4 {
            write_png(&dir.path().join(name).join(format!("f{i}.png")), 12, 10, 50);
        }
    };
    for v in ["corrupt", "empty", "good", "mixed", "truncated"] {
        make(v);
    }
    std::fs::write(dir.path().join("corrupt/f1.png"), b"this is not a png").unwrap();
    std::fs::write(dir.path().join("empty/f2.png"), b"").unwrap();
    write_png(&dir.path().join("mixed/f3.png"), 14, 10, 50);
    let bytes = std::fs::read(dir.path().join("truncated/f0.png")).unwrap();
    std::fs::write(
        dir.path().join("truncated/f0.png"),
        &bytes[..bytes.len() / 2],
    )
    .unwrap();

    let ds = Arc::new(
        ClipDataset::open(dir.path(), config(Layout::Folder { stride: 4 }, 10, 12)).unwrap(),
    );
    assert_eq!(ds.len(), 5);
    let expect = [
        (0, "corrupt/f1.png", "cannot decode"),
        (1, "empty/f2.png", "file is empty"),
        (3, "mixed/f3.png", "mixed sizes"),
        (4, "truncated/f0.png", "cannot decode"),
    ];
    for (i, file, what) in expect {
        let msg = ds.load(i).unwrap_err().to_string();
        assert!(msg.contains(file) && msg.contains(what), "clip {i}: {msg}");
    }
    // Through the prefetcher: only the good clip arrives, the four bad ones are counted.
    let got: Vec<String> = Prefetcher::new(ds.clone(), (0..5).collect(), 2)
        .map(|c| c.id.clone())
        .collect();
    assert_eq!(got, vec!["good@0".to_owned()]);
    assert_eq!(ds.skipped(), 4);
    // Asking again does not count twice.
    assert!(ds.get(0).is_none());
    assert_eq!(ds.skipped(), 4);
}

/// Guards decoding of 16-bit gray, gray+alpha-free RGBA and JPEG to RGB in [0, 1].
#[test]
fn decodes_16bit_gray_rgba_and_jpeg() {
    let dir = tempfile::tempdir().unwrap();
    let p16 = dir.path().join("g16.png");
    image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_pixel(3, 2, image::Luma([65535 / 4]))
        .save(&p16)
        .unwrap();
    let img = decode_image(&p16).unwrap();
    assert_eq!((img.width, img.height), (3, 2));
    assert!(
        img.data.iter().all(|v| (v - 0.25).abs() < 1e-3),
        "{:?}",
        img.data
    );
    let prgba = dir.path().join("rgba.png");
    image::RgbaImage::from_pixel(2, 2, image::Rgba([255, 0, 51, 10]))
        .save(&prgba)
        .unwrap();
    let img = decode_image(&prgba).unwrap();
    assert_eq!(img.pixel(1, 1), [1.0, 0.0, 0.2]);
    let pjpg = dir.path().join("x.jpg");
    image::RgbImage::from_pixel(16, 8, image::Rgb([200, 100, 50]))
        .save(&pjpg)
        .unwrap();
    let img = decode_image(&pjpg).unwrap();
    assert!((img.pixel(4, 4)[0] - 200.0 / 255.0).abs() < 0.03);
}

fn write_text(path: &Path, text: &str) {
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    std::fs::write(path, text).unwrap();
}

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

/// Guards centre-crop mode end to end: too-small frames fail naming the file.
#[test]
fn center_crop_too_large_names_file() {
    let dir = tempfile::tempdir().unwrap();
    for i in 0..4 {
        write_png(&dir.path().join(format!("f{i}.png")), 12, 10, 0);
    }
    let mut cfg = config(Layout::Folder { stride: 1 }, 8, 8);
    cfg.fit.mode = FitMode::CenterCrop;
    assert_eq!(
        ClipDataset::open(dir.path(), cfg.clone())
            .unwrap()
            .load(0)
            .unwrap()
            .frames[0]
            .width,
        8
    );
    cfg.fit.height = 11;
    let err = ClipDataset::open(dir.path(), cfg)
        .unwrap()
        .load(0)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("f0.png") && err.contains("smaller than the crop"),
        "{err}"
    );
}
