//! The plain-folder reader, image decoding and fitting.

use crate::{config, write_png};
use envision4d_data::{decode_image, ClipDataset, DataError, FitMode, Layout, Prefetcher};
use std::path::Path;
use std::sync::Arc;

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
