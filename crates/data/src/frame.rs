//! Decoded RGB frames: `Image` (f32 in [0, 1], HWC) and decoding with the `image` crate.

use crate::error::{DataError, Result};
use std::io::Cursor;
use std::path::Path;

/// File extensions (lower case) treated as frames.
pub const FRAME_EXTENSIONS: [&str; 3] = ["png", "jpg", "jpeg"];

/// An RGB image, row-major HWC, values in [0, 1].
#[derive(Debug, Clone, PartialEq)]
pub struct Image {
    pub width: usize,
    pub height: usize,
    pub data: Vec<f32>,
}

impl Image {
    pub fn new(width: usize, height: usize, data: Vec<f32>) -> Image {
        debug_assert_eq!(data.len(), width * height * 3);
        Image {
            width,
            height,
            data,
        }
    }
    pub fn filled(width: usize, height: usize, rgb: [f32; 3]) -> Image {
        let data = (0..width * height).flat_map(|_| rgb).collect();
        Image::new(width, height, data)
    }
    pub fn pixel(&self, row: usize, col: usize) -> [f32; 3] {
        let i = (row * self.width + col) * 3;
        [self.data[i], self.data[i + 1], self.data[i + 2]]
    }
    /// The same values as CHW (what a tensor (3, H, W) expects).
    pub fn to_chw(&self) -> Vec<f32> {
        crate::host_clip::hwc_to_chw(&self.data, self.height, self.width)
    }
}

/// True when `path` has a frame extension (case-insensitive).
pub fn is_frame_file(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| FRAME_EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()))
}

/// Decodes a PNG or JPEG (8 or 16 bit; gray, gray+alpha, RGB or RGBA) to RGB in [0, 1].
/// Alpha is dropped (frames are opaque video; compositing would invent a background).
pub fn decode_image(path: &Path) -> Result<Image> {
    let bytes = std::fs::read(path).map_err(|e| DataError::io(path, e))?;
    let decode_err = |msg: String| DataError::Decode {
        path: path.to_path_buf(),
        msg,
    };
    if bytes.is_empty() {
        return Err(decode_err("file is empty".into()));
    }
    // Guess from the bytes, not the extension: a mislabelled JPEG still decodes.
    let reader = image::ImageReader::new(Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| decode_err(e.to_string()))?;
    if reader.format().is_none() {
        return Err(decode_err("not a PNG or JPEG file".into()));
    }
    let img = reader.decode().map_err(|e| decode_err(e.to_string()))?;
    let (w, h) = (img.width() as usize, img.height() as usize);
    if w == 0 || h == 0 {
        return Err(decode_err(format!("zero size {w}x{h}")));
    }
    Ok(Image::new(w, h, img.to_rgb32f().into_raw()))
}

/// Encodes an RGB image as 8-bit PNG bytes (rounded, clamped to [0, 1]).
pub fn encode_png_rgb8(img: &Image) -> std::result::Result<Vec<u8>, String> {
    let bytes: Vec<u8> = img.data.iter().map(|&v| to_u8(v)).collect();
    encode_png(
        img.width,
        img.height,
        image::ExtendedColorType::Rgb8,
        &bytes,
    )
}

/// Encodes raw samples (already in the layout `color` says) as PNG bytes.
pub fn encode_png(
    width: usize,
    height: usize,
    color: image::ExtendedColorType,
    bytes: &[u8],
) -> std::result::Result<Vec<u8>, String> {
    use image::ImageEncoder;
    let mut out = Vec::new();
    image::codecs::png::PngEncoder::new(&mut out)
        .write_image(bytes, width as u32, height as u32, color)
        .map_err(|e| e.to_string())?;
    Ok(out)
}

/// [0, 1] -> u8 with rounding; NaN -> 0.
pub fn to_u8(v: f32) -> u8 {
    if v.is_nan() {
        0
    } else {
        (v.clamp(0.0, 1.0) * 255.0).round() as u8
    }
}
