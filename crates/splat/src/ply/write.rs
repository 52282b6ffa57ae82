//! Encoding Gaussians as PLY in the INRIA property order, and writing the
//! file atomically so a crash mid-write never leaves a half-written scene.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use super::header::Format;
use super::{PlyError, PlyGaussians};

/// Distinguishes temp files of concurrent writes within one process.
static TEMP_COUNTER: AtomicUsize = AtomicUsize::new(0);

/// Encodes `g` as a binary little-endian PLY file.
///
/// # Panics
/// If `g` is internally inconsistent (see [`PlyGaussians::check_consistent`]);
/// that is a programming error, not an input error. [`write_ply`] checks first
/// and returns an error instead.
pub fn to_ply_bytes(g: &PlyGaussians) -> Vec<u8> {
    encode(g, Format::BinaryLittleEndian)
}

/// Writes `g` to `path` as binary little-endian PLY, atomically: the data goes
/// to a temporary file in the same directory which is then renamed over
/// `path`. Rejects inconsistent lengths and non-finite values, since a file
/// holding them could not be read back.
pub fn write_ply(path: &Path, g: &PlyGaussians) -> Result<(), PlyError> {
    g.check_consistent()?;
    check_finite(g)?;
    write_atomic(path, &to_ply_bytes(g))
}

/// Property names in INRIA order, with the number of `f_rest` coefficients.
pub(super) fn property_names(rest: usize) -> Vec<String> {
    let mut names: Vec<String> = [
        "x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    names.extend((0..rest).map(|k| format!("f_rest_{k}")));
    names.extend(
        [
            "opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3",
        ]
        .iter()
        .map(|s| s.to_string()),
    );
    names
}

/// All float values of Gaussian `i`, in the order of [`property_names`]
/// (normals are written as zeros, as the reference implementation does).
pub(super) fn vertex_values(g: &PlyGaussians, i: usize) -> impl Iterator<Item = f32> + '_ {
    g.means[i]
        .into_iter()
        .chain([0.0; 3])
        .chain(g.f_dc[i])
        .chain(g.f_rest[i].iter().copied())
        .chain([g.opacity_logit[i]])
        .chain(g.log_scales[i])
        .chain(g.rotations[i])
}

/// Encodes in any of the three formats (ascii and big endian serve tests).
pub(crate) fn encode(g: &PlyGaussians, format: Format) -> Vec<u8> {
    if let Err(e) = g.check_consistent() {
        panic!("to_ply_bytes: {e}");
    }
    let rest = g.f_rest.first().map_or(0, Vec::len);
    let names = property_names(rest);
    let format_name = match format {
        Format::Ascii => "ascii",
        Format::BinaryLittleEndian => "binary_little_endian",
        Format::BinaryBigEndian => "binary_big_endian",
    };
    let mut out = format!(
        "ply\nformat {format_name} 1.0\ncomment written by envision4d\nelement vertex {}\n",
        g.len()
    );
    for name in &names {
        out.push_str(&format!("property float {name}\n"));
    }
    out.push_str("end_header\n");
    let mut out = out.into_bytes();
    out.reserve(g.len() * names.len() * 4);
    for i in 0..g.len() {
        match format {
            Format::Ascii => {
                let line: Vec<String> = vertex_values(g, i).map(|v| v.to_string()).collect();
                out.extend_from_slice(line.join(" ").as_bytes());
                out.push(b'\n');
            }
            Format::BinaryLittleEndian => {
                vertex_values(g, i).for_each(|v| out.extend_from_slice(&v.to_le_bytes()));
            }
            Format::BinaryBigEndian => {
                vertex_values(g, i).for_each(|v| out.extend_from_slice(&v.to_be_bytes()));
            }
        }
    }
    out
}

fn check_finite(g: &PlyGaussians) -> Result<(), PlyError> {
    let names = property_names(g.f_rest.first().map_or(0, Vec::len));
    for i in 0..g.len() {
        if let Some((name, v)) = names
            .iter()
            .zip(vertex_values(g, i))
            .find(|(_, v)| !v.is_finite())
        {
            return Err(PlyError::NonFinite {
                property: name.clone(),
                vertex: i,
                value: v as f64,
            });
        }
    }
    Ok(())
}

/// Writes `bytes` to a temp file next to `path`, then renames it into place.
/// On failure the temp file is removed and an existing `path` is untouched.
fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), PlyError> {
    let io_err = |p: &Path| {
        let p = p.to_path_buf();
        move |source| PlyError::Io { path: p, source }
    };
    let file_name = path.file_name().ok_or_else(|| PlyError::Io {
        path: path.to_path_buf(),
        source: std::io::Error::new(std::io::ErrorKind::InvalidInput, "path has no file name"),
    })?;
    let tmp: PathBuf = path.with_file_name(format!(
        ".{}.tmp-{}-{}",
        file_name.to_string_lossy(),
        std::process::id(),
        TEMP_COUNTER.fetch_add(1, Ordering::Relaxed)
    ));
    let result = (|| {
        let mut f = std::fs::File::create(&tmp).map_err(io_err(&tmp))?;
        f.write_all(bytes).map_err(io_err(&tmp))?;
        f.sync_all().map_err(io_err(&tmp))?;
        drop(f);
        std::fs::rename(&tmp, path).map_err(io_err(path))
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}
