//! Layout readers on small generated trees, and every bad-input case: the plain-folder
//! reader and image decoding (`folder`), the Waymo and STORM layouts (`waymo`).

mod folder;
mod waymo;

use envision4d_data::{ClipSpec, DatasetConfig, Fit, FitMode, Layout};
use std::path::Path;

pub fn write_png(path: &Path, w: u32, h: u32, shade: u8) {
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    let img = image::RgbImage::from_fn(w, h, |x, y| {
        image::Rgb([shade, (x * 10) as u8, (y * 10) as u8])
    });
    img.save(path).unwrap();
}

pub fn config(layout: Layout, h: usize, w: usize) -> DatasetConfig {
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

pub fn write_text(path: &Path, text: &str) {
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    std::fs::write(path, text).unwrap();
}
