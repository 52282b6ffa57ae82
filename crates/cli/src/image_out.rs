//! Writing rendered images (colour and single-channel maps such as depth) to
//! PNG or EXR, chosen by file extension, atomically: the image is written to
//! a temporary file in the destination directory and renamed into place, so
//! readers never see a half-written file and a failed write leaves any
//! existing file untouched.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use anyhow::{bail, Context};

/// Extensions accepted by [`ImageFormat::from_path`], for error messages.
const ALLOWED_EXTENSIONS: &str = ".png, .exr";
/// Largest 8-bit and 16-bit sample values.
const U8_MAX: f32 = u8::MAX as f32;
const U16_MAX: f32 = u16::MAX as f32;
/// EXR channel name for single-channel (luminance-like) data.
const GRAY_CHANNEL: &str = "Y";

/// Distinguishes temp files of concurrent writes within one process.
static TEMP_COUNTER: AtomicUsize = AtomicUsize::new(0);

/// Output image container.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ImageFormat {
    /// 8-bit RGB or 16-bit grayscale, quantised.
    Png,
    /// 32-bit float, linear, unclamped.
    Exr,
}

impl ImageFormat {
    /// The format for `path`'s extension (case-insensitive).
    pub fn from_path(path: &Path) -> anyhow::Result<ImageFormat> {
        let ext = path.extension().map(|e| e.to_string_lossy().to_lowercase());
        match ext.as_deref() {
            Some("png") => Ok(ImageFormat::Png),
            Some("exr") => Ok(ImageFormat::Exr),
            Some(other) => bail!(
                "unsupported image extension \".{other}\" for {}: use one of {ALLOWED_EXTENSIONS}",
                path.display()
            ),
            None => bail!(
                "image path {} has no extension: use one of {ALLOWED_EXTENSIONS}",
                path.display()
            ),
        }
    }
}

/// Writes a linear RGB image (`height * width * 3` values, row-major).
///
/// PNG: 8-bit, each value clamped to `[0, 1]` and rounded from `v * 255`;
/// no gamma is applied because the renderer already works in the colour
/// space of the training images. NaN becomes 0.
/// EXR: float32 R, G, B, written as is (values outside `[0, 1]` and NaN kept).
pub fn write_rgb(path: &Path, width: usize, height: usize, rgb: &[f32]) -> anyhow::Result<()> {
    let format = ImageFormat::from_path(path)?;
    check_size(path, width, height, 3, rgb.len())?;
    write_atomic(path, |tmp| match format {
        ImageFormat::Png => {
            let (w, h) = png_size(width, height)?;
            let bytes: Vec<u8> = rgb.iter().map(|&v| to_u8(v)).collect();
            let img = image::RgbImage::from_raw(w, h, bytes)
                .context("internal error: RGB buffer size mismatch")?;
            img.save_with_format(tmp, image::ImageFormat::Png)
                .context("PNG encoding failed")
        }
        ImageFormat::Exr => {
            let px = |x: usize, y: usize| {
                let i = (y * width + x) * 3;
                (rgb[i], rgb[i + 1], rgb[i + 2])
            };
            exr::prelude::write_rgb_file(tmp, width, height, px).context("EXR encoding failed")
        }
    })
}

/// Writes a single-channel image (`height * width` values, row-major), e.g.
/// depth.
///
/// PNG: 16-bit grayscale, linearly normalised so the smallest finite value
/// maps to 0 and the largest to 65535 (the absolute scale is lost; use EXR to
/// keep it). A constant image is all 0; NaN and -inf map to 0, +inf to 65535.
/// EXR: one float32 channel named `Y`, unclamped.
pub fn write_gray(path: &Path, width: usize, height: usize, values: &[f32]) -> anyhow::Result<()> {
    let format = ImageFormat::from_path(path)?;
    check_size(path, width, height, 1, values.len())?;
    write_atomic(path, |tmp| match format {
        ImageFormat::Png => {
            let (w, h) = png_size(width, height)?;
            let img = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_raw(
                w,
                h,
                normalize_u16(values),
            )
            .context("internal error: gray buffer size mismatch")?;
            img.save_with_format(tmp, image::ImageFormat::Png)
                .context("PNG encoding failed")
        }
        ImageFormat::Exr => {
            use exr::prelude::*;
            let channels = SpecificChannels::build()
                .with_channel(GRAY_CHANNEL)
                .with_pixel_fn(|pos: Vec2<usize>| (values[pos.y() * width + pos.x()],));
            Image::from_channels((width, height), channels)
                .write()
                // In order: parallel compression writes the chunks as they finish, so the same
                // image gave different bytes from run to run.
                .non_parallel()
                .to_file(tmp)
                .context("EXR encoding failed")
        }
    })
}

/// Rejects buffers whose length does not match the image size.
fn check_size(
    path: &Path,
    width: usize,
    height: usize,
    channels: usize,
    len: usize,
) -> anyhow::Result<()> {
    if width == 0 || height == 0 {
        bail!(
            "cannot write {}: image size {width}x{height} is empty",
            path.display()
        );
    }
    let expected = width
        .checked_mul(height)
        .and_then(|n| n.checked_mul(channels));
    if expected != Some(len) {
        bail!(
            "cannot write {}: {width}x{height} image with {channels} channel(s) needs {} values, got {len}",
            path.display(),
            expected.map_or("more than usize::MAX".to_owned(), |n| n.to_string())
        );
    }
    Ok(())
}

fn png_size(width: usize, height: usize) -> anyhow::Result<(u32, u32)> {
    match (u32::try_from(width), u32::try_from(height)) {
        (Ok(w), Ok(h)) => Ok((w, h)),
        _ => bail!("image size {width}x{height} is too large for PNG"),
    }
}

fn to_u8(v: f32) -> u8 {
    // NaN fails every comparison, so clamp would keep it: map it to 0 first.
    let v = if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) };
    (v * U8_MAX).round() as u8
}

/// Maps finite values linearly onto `[0, 65535]` by their min and max.
fn normalize_u16(values: &[f32]) -> Vec<u16> {
    let (lo, hi) = values
        .iter()
        .filter(|v| v.is_finite())
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &v| {
            (lo.min(v), hi.max(v))
        });
    // Computed in f64 so a range near f32::MAX cannot overflow to infinity.
    let range = hi as f64 - lo as f64;
    values
        .iter()
        .map(|&v| {
            if v == f32::INFINITY {
                u16::MAX
            } else if !v.is_finite() || range <= 0.0 {
                0
            } else {
                ((v as f64 - lo as f64) / range * U16_MAX as f64).round() as u16
            }
        })
        .collect()
}

/// Runs `write` on a temp path next to `path`, then renames it over `path`.
/// On any failure the temp file is removed and `path` is left as it was.
fn write_atomic(
    path: &Path,
    write: impl FnOnce(&Path) -> anyhow::Result<()>,
) -> anyhow::Result<()> {
    let file_name = path
        .file_name()
        .with_context(|| format!("image path {} has no file name", path.display()))?;
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        bail!(
            "cannot write {}: output directory {} does not exist",
            path.display(),
            dir.display()
        );
    }
    let tmp: PathBuf = dir.join(format!(
        ".{}.tmp-{}-{}",
        file_name.to_string_lossy(),
        std::process::id(),
        TEMP_COUNTER.fetch_add(1, Ordering::Relaxed)
    ));
    let result = write(&tmp)
        .and_then(|()| {
            std::fs::rename(&tmp, path)
                .with_context(|| format!("cannot move {} into place", tmp.display()))
        })
        .with_context(|| format!("failed to write image {}", path.display()));
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Guards PNG quantisation (clamp, round, NaN -> 0) and pixel layout.
    #[test]
    fn png_rgb_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.PNG");
        let (w, h) = (3, 2);
        let mut rgb: Vec<f32> = (0..w * h * 3).map(|i| i as f32 / 17.0).collect();
        rgb[0] = -0.5;
        rgb[1] = 2.5;
        rgb[2] = f32::NAN;
        write_rgb(&path, w, h, &rgb).unwrap();
        let img = image::open(&path).unwrap().to_rgb8();
        assert_eq!(img.dimensions(), (3, 2));
        let expected: Vec<u8> = rgb.iter().map(|&v| to_u8(v)).collect();
        assert_eq!(img.as_raw(), &expected);
        assert_eq!(&img.as_raw()[..3], &[0, 255, 0]);
        assert_eq!(
            img.get_pixel(2, 1).0[2],
            (17.0f32 / 17.0 * 255.0).round() as u8
        );
    }

    /// Guards that EXR keeps linear float values unclamped (HDR, negatives, NaN).
    #[test]
    fn exr_rgb_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.exr");
        let (w, h) = (2, 3);
        let mut rgb: Vec<f32> = (0..w * h * 3).map(|i| i as f32 * 0.25).collect();
        rgb[0] = 2.5;
        rgb[4] = -1.0;
        rgb[5] = f32::NAN;
        write_rgb(&path, w, h, &rgb).unwrap();
        let img = exr::prelude::read_first_rgba_layer_from_file(
            &path,
            |res, _| vec![[0f32; 3]; res.width() * res.height()],
            move |px: &mut Vec<[f32; 3]>, pos, (r, g, b, _a): (f32, f32, f32, f32)| {
                px[pos.y() * w + pos.x()] = [r, g, b];
            },
        )
        .unwrap();
        let layer = &img.layer_data;
        assert_eq!((layer.size.width(), layer.size.height()), (w, h));
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        let got: Vec<f32> = layer
            .channel_data
            .pixels
            .iter()
            .flatten()
            .copied()
            .collect();
        assert_eq!(bits(&got), bits(&rgb), "{got:?}");
    }

    /// Guards the single "Y" float channel of gray EXR output.
    #[test]
    fn exr_gray_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("depth.exr");
        let values = [0.5f32, -1.0, 1e6, 2.5, 0.0, 7.0];
        write_gray(&path, 3, 2, &values).unwrap();
        let img = exr::prelude::read_first_flat_layer_from_file(&path).unwrap();
        let channels = &img.layer_data.channel_data.list;
        assert_eq!(channels.len(), 1);
        assert!(channels[0].name == *GRAY_CHANNEL);
        let got: Vec<f32> = channels[0].sample_data.values_as_f32().collect();
        assert_eq!(got, values);
    }

    /// Guards the gray PNG min/max normalisation and the constant-image case.
    #[test]
    fn png_gray_normalised() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("depth.png");
        write_gray(&path, 2, 2, &[2.0, 4.0, 3.0, f32::NAN]).unwrap();
        let img = image::open(&path).unwrap().to_luma16();
        assert_eq!(img.as_raw(), &[0, 65535, 32768, 0]);
        write_gray(&path, 2, 1, &[5.0, 5.0]).unwrap();
        let img = image::open(&path).unwrap().to_luma16();
        assert_eq!(img.as_raw(), &[0, 0]);
    }

    /// Guards against panicking (or writing garbage) on a wrong-length buffer.
    #[test]
    fn wrong_length_buffer_error() {
        let dir = tempfile::tempdir().unwrap();
        let msg = write_rgb(&dir.path().join("a.png"), 4, 4, &[0.0; 47])
            .unwrap_err()
            .to_string();
        assert!(msg.contains("needs 48 values, got 47"), "{msg}");
        assert!(write_gray(&dir.path().join("a.exr"), 4, 4, &[0.0; 15]).is_err());
        assert!(write_gray(&dir.path().join("a.exr"), 0, 4, &[]).is_err());
        assert!(write_rgb(&dir.path().join("a.png"), usize::MAX, 4, &[]).is_err());
    }

    /// Guards the extension check naming the bad and the allowed extensions.
    #[test]
    fn unknown_extension_error() {
        let msg = write_rgb(Path::new("out.jpg"), 1, 1, &[0.0; 3])
            .unwrap_err()
            .to_string();
        assert!(msg.contains(".jpg") && msg.contains(".png, .exr"), "{msg}");
        assert!(ImageFormat::from_path(Path::new("out")).is_err());
        assert_eq!(
            ImageFormat::from_path(Path::new("a/b.ExR")).unwrap(),
            ImageFormat::Exr
        );
    }

    /// Guards atomicity: a failed write leaves the old file and no temp file.
    #[test]
    fn failed_write_leaves_existing_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("keep.png");
        std::fs::write(&path, b"old").unwrap();
        assert!(write_rgb(&path, 2, 2, &[0.5; 11]).is_err());
        assert_eq!(std::fs::read(&path).unwrap(), b"old");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
        write_rgb(&path, 2, 2, &[0.5; 12]).unwrap();
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
        assert_ne!(std::fs::read(&path).unwrap(), b"old");
        // A failure after the temp file was written (renaming onto a non-empty
        // directory) must remove the temp file and leave the target alone.
        let blocker = dir.path().join("blocked.exr");
        std::fs::create_dir(&blocker).unwrap();
        std::fs::write(blocker.join("inside"), b"x").unwrap();
        assert!(write_gray(&blocker, 1, 1, &[1.0]).is_err());
        assert_eq!(std::fs::read(blocker.join("inside")).unwrap(), b"x");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);
    }

    /// Guards the missing-directory error naming the directory.
    #[test]
    fn missing_directory_error() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("nope");
        let msg = write_gray(&missing.join("d.exr"), 1, 1, &[1.0])
            .unwrap_err()
            .to_string();
        assert!(
            msg.contains("does not exist") && msg.contains("nope"),
            "{msg}"
        );
    }
}
