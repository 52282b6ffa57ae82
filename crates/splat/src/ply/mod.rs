//! Reading and writing 3D Gaussian Splatting scenes as PLY files in the layout
//! of the original INRIA implementation (`x y z nx ny nz f_dc_* f_rest_*
//! opacity scale_* rot_*`), and converting between the stored (pre-activation)
//! parameters and the activated values the rasterizer consumes.
//!
//! The parser is hand-written so that it never panics on untrusted input and
//! never allocates more than the file can actually hold.
//!
//! Layout of this module:
//! - `header`: the text header (format, elements, typed properties);
//! - `read`: the data section (ascii / binary little / big endian);
//! - [`write`]: binary little-endian output, written atomically.

mod header;
mod read;
mod write;

#[cfg(test)]
mod tests;

use std::path::PathBuf;

pub use read::{parse_ply, read_ply};
pub use write::{to_ply_bytes, write_ply};

/// Zeroth-order real spherical-harmonics constant, `1 / (2 * sqrt(pi))`: the
/// factor between the stored DC coefficient and an RGB colour offset.
pub const SH_C0: f64 = 0.282_094_791_773_878_14;

/// Opacities are clamped to `[OPACITY_EPS, 1 - OPACITY_EPS]` before taking the
/// logit, so that fully (in)visible Gaussians get a finite stored value.
pub const OPACITY_EPS: f64 = 1e-6;

/// Gaussians exactly as stored in a PLY file (before activation).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PlyGaussians {
    /// Centres, world space.
    pub means: Vec<[f32; 3]>,
    /// Degree-0 SH coefficients (`f_dc_0..2`), one per colour channel.
    pub f_dc: Vec<[f32; 3]>,
    /// Higher-order SH coefficients (`f_rest_0..K-1`) per Gaussian, in index
    /// order; empty for a degree-0 scene. Every Gaussian has the same `K`.
    pub f_rest: Vec<Vec<f32>>,
    /// Opacity before the sigmoid.
    pub opacity_logit: Vec<f32>,
    /// Natural log of the per-axis scales.
    pub log_scales: Vec<[f32; 3]>,
    /// Rotation quaternion `w x y z` as stored (`rot_0..3`), not normalised.
    pub rotations: Vec<[f32; 4]>,
}

/// Activated per-Gaussian values in the flat layout the rasterizer takes.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RenderParams {
    /// `N * 3` centres.
    pub means: Vec<f32>,
    /// `N * 4` unit quaternions `w x y z`; a zero quaternion stays all zero so
    /// the rasterizer culls that Gaussian instead of inventing a rotation.
    pub quats: Vec<f32>,
    /// `N * 3` scales, `exp(log_scale)`.
    pub scales: Vec<f32>,
    /// `N` opacities, `sigmoid(logit)`.
    pub opacities: Vec<f32>,
    /// `N * 3` RGB colours, `max(0, 0.5 + SH_C0 * f_dc)`.
    pub colors: Vec<f32>,
}

/// Everything that can go wrong reading, writing or converting Gaussians.
#[derive(Debug, thiserror::Error)]
pub enum PlyError {
    #[error("I/O error on {}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("not a PLY file: it does not start with the line \"ply\"")]
    NotPly,
    #[error(
        "unsupported PLY format {format:?}: expected \"ascii 1.0\", \
         \"binary_little_endian 1.0\" or \"binary_big_endian 1.0\""
    )]
    UnsupportedFormat { format: String },
    #[error("malformed PLY header line {line_no} ({reason}): {line:?}")]
    MalformedHeader {
        line_no: usize,
        line: String,
        reason: String,
    },
    #[error("PLY header is not terminated by an \"end_header\" line")]
    UnterminatedHeader,
    #[error("PLY file has no \"vertex\" element (elements present: {found})")]
    MissingVertexElement { found: String },
    #[error("PLY vertex element lacks required property `{name}` (present: {present})")]
    MissingProperty { name: String, present: String },
    #[error("PLY vertex property `{name}` is a list, expected a scalar")]
    UnexpectedList { name: String },
    #[error(
        "PLY f_rest properties must be numbered contiguously from 0: \
         f_rest_{missing} is missing or duplicated (found indices {found:?})"
    )]
    NonContiguousFRest { missing: usize, found: Vec<usize> },
    #[error("truncated PLY data: {element} {index} of {count}: {what}")]
    Truncated {
        element: String,
        index: usize,
        count: usize,
        what: String,
    },
    #[error("PLY {element} {index}: list property `{property}` has invalid length {value}")]
    InvalidListCount {
        element: String,
        index: usize,
        property: String,
        value: f64,
    },
    #[error("PLY line {line}, vertex {vertex}: cannot parse {text:?} as a number for property `{property}`")]
    AsciiNumber {
        line: usize,
        vertex: usize,
        property: String,
        text: String,
    },
    #[error("PLY line {line}, vertex {vertex}: missing value for property `{property}`")]
    AsciiMissingValue {
        line: usize,
        vertex: usize,
        property: String,
    },
    #[error("PLY line {line}, vertex {vertex}: more values than the declared properties")]
    AsciiExtraValues { line: usize, vertex: usize },
    #[error(
        "value {value} in property `{property}` at vertex {vertex} is not a finite 32-bit float"
    )]
    NonFinite {
        property: String,
        vertex: usize,
        value: f64,
    },
    #[error("inconsistent Gaussian data: {0}")]
    Inconsistent(String),
    #[error("cannot store Gaussian {index}: {message}")]
    InvalidRenderParam { index: usize, message: String },
}

impl PlyGaussians {
    /// Number of Gaussians.
    pub fn len(&self) -> usize {
        self.means.len()
    }

    /// True when the scene holds no Gaussian.
    pub fn is_empty(&self) -> bool {
        self.means.is_empty()
    }

    /// Checks that every per-Gaussian vector has `len()` entries and that all
    /// Gaussians have the same number of `f_rest` coefficients.
    pub fn check_consistent(&self) -> Result<(), PlyError> {
        let n = self.len();
        let lens = [
            ("f_dc", self.f_dc.len()),
            ("f_rest", self.f_rest.len()),
            ("opacity_logit", self.opacity_logit.len()),
            ("log_scales", self.log_scales.len()),
            ("rotations", self.rotations.len()),
        ];
        for (name, len) in lens {
            if len != n {
                return Err(PlyError::Inconsistent(format!(
                    "{name} has {len} entries but means has {n}"
                )));
            }
        }
        let k = self.f_rest.first().map_or(0, Vec::len);
        if let Some(i) = self.f_rest.iter().position(|r| r.len() != k) {
            return Err(PlyError::Inconsistent(format!(
                "Gaussian {i} has {} f_rest coefficients, Gaussian 0 has {k}",
                self.f_rest[i].len()
            )));
        }
        Ok(())
    }

    /// Applies the activations the rasterizer expects.
    ///
    /// Colour comes from the DC term only: the higher-order coefficients in
    /// `f_rest` are kept for round trips but ignored here, since we render
    /// view-independent RGB. Scales that would overflow `f32` are clamped to
    /// `f32::MAX` so the rasterizer never sees an infinity.
    pub fn to_render_params(&self) -> RenderParams {
        let n = self.len();
        let mut p = RenderParams {
            means: Vec::with_capacity(n * 3),
            quats: Vec::with_capacity(n * 4),
            scales: Vec::with_capacity(n * 3),
            opacities: Vec::with_capacity(n),
            colors: Vec::with_capacity(n * 3),
        };
        for m in &self.means {
            p.means.extend_from_slice(m);
        }
        for q in &self.rotations {
            p.quats.extend_from_slice(&normalize_quat(*q));
        }
        for s in &self.log_scales {
            p.scales.extend(
                s.iter()
                    .map(|&l| (l as f64).exp().min(f32::MAX as f64) as f32),
            );
        }
        p.opacities
            .extend(self.opacity_logit.iter().map(|&l| sigmoid(l as f64) as f32));
        for c in &self.f_dc {
            p.colors
                .extend(c.iter().map(|&d| (0.5 + SH_C0 * d as f64).max(0.0) as f32));
        }
        p
    }

    /// Inverts [`to_render_params`](Self::to_render_params): logit of the
    /// clamped opacity, log of the scale, DC coefficient from the colour;
    /// quaternions are copied. `f_rest` is left empty (degree 0).
    pub fn from_render_params(p: &RenderParams) -> Result<Self, PlyError> {
        let n = p.opacities.len();
        for (name, len, per) in [
            ("means", p.means.len(), 3),
            ("quats", p.quats.len(), 4),
            ("scales", p.scales.len(), 3),
            ("colors", p.colors.len(), 3),
        ] {
            if Some(len) != n.checked_mul(per) {
                return Err(PlyError::Inconsistent(format!(
                    "render params {name} has {len} values, expected {per} per Gaussian \
                     for {n} opacities"
                )));
            }
        }
        let bad = |index: usize, message: String| PlyError::InvalidRenderParam { index, message };
        let mut g = PlyGaussians {
            f_rest: vec![Vec::new(); n],
            ..Default::default()
        };
        for i in 0..n {
            let three = |v: &[f32]| [v[3 * i], v[3 * i + 1], v[3 * i + 2]];
            let (m, s, c) = (three(&p.means), three(&p.scales), three(&p.colors));
            let q = [
                p.quats[4 * i],
                p.quats[4 * i + 1],
                p.quats[4 * i + 2],
                p.quats[4 * i + 3],
            ];
            let o = p.opacities[i];
            if m.iter().chain(&q).chain(&c).any(|v| !v.is_finite()) || !o.is_finite() {
                return Err(bad(
                    i,
                    "non-finite mean, rotation, colour or opacity".into(),
                ));
            }
            if let Some(v) = s.iter().find(|v| !(v.is_finite() && **v > 0.0)) {
                return Err(bad(i, format!("scale must be finite and > 0, got {v}")));
            }
            let o = (o as f64).clamp(OPACITY_EPS, 1.0 - OPACITY_EPS);
            g.means.push(m);
            g.f_dc.push(c.map(|c| ((c as f64 - 0.5) / SH_C0) as f32));
            g.opacity_logit.push((o / (1.0 - o)).ln() as f32);
            g.log_scales.push(s.map(|s| (s as f64).ln() as f32));
            g.rotations.push(q);
        }
        Ok(g)
    }
}

/// Logistic function in the two-branch form, so `exp` only ever sees a
/// non-positive argument: no overflow, no `inf / inf = NaN` for huge `|x|`.
fn sigmoid(x: f64) -> f64 {
    if x >= 0.0 {
        1.0 / (1.0 + (-x).exp())
    } else {
        let e = x.exp();
        e / (1.0 + e)
    }
}

/// Unit quaternion, or all zeros when the input has no direction.
fn normalize_quat(q: [f32; 4]) -> [f32; 4] {
    let norm = q
        .iter()
        .map(|&v| (v as f64) * (v as f64))
        .sum::<f64>()
        .sqrt();
    if norm > 0.0 && norm.is_finite() {
        q.map(|v| (v as f64 / norm) as f32)
    } else {
        [0.0; 4]
    }
}
