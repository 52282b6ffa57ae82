//! Camera description files: a pinhole camera as JSON (intrinsics plus a
//! world-to-camera matrix), parsed strictly and validated so that a typo or a
//! degenerate camera is reported by name instead of rendering garbage.
//!
//! Conventions: OpenCV camera axes (x right, y down, z forward), pixel
//! coordinates with the origin at the top-left corner, and `world_to_camera`
//! row-major with the translation in the last column.

use std::path::{Path, PathBuf};

/// Largest accepted image side, in pixels.
pub const MAX_IMAGE_SIDE: u32 = 16384;
/// Tolerance for the last matrix row being `[0, 0, 0, 1]`.
const LAST_ROW_TOLERANCE: f64 = 1e-6;
/// Smallest accepted `|det|` of the rotation block. Orthonormality is not
/// required (gsplat does not require it either), only invertibility.
const MIN_ROTATION_DET: f64 = 1e-9;

/// A pinhole camera as stored in a camera JSON file.
#[derive(Debug, Clone, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct CameraJson {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Focal length along x, in pixels.
    pub fx: f64,
    /// Focal length along y, in pixels.
    pub fy: f64,
    /// Principal point x, in pixels.
    pub cx: f64,
    /// Principal point y, in pixels.
    pub cy: f64,
    /// Row-major 4x4 world-to-camera transform (OpenCV axes).
    pub world_to_camera: [[f64; 4]; 4],
}

/// Why a camera file could not be used.
#[derive(Debug, thiserror::Error)]
pub enum CameraError {
    #[error("cannot read camera file {}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// JSON syntax error, missing field or unknown field; serde's message
    /// names the field and the line and column.
    #[error("invalid camera JSON: {0}")]
    Json(#[source] serde_json::Error),
    /// A value that parsed but makes no sense as a camera.
    #[error("camera {field} {problem}")]
    Invalid { field: String, problem: String },
    /// Any of the above, with the file it came from.
    #[error("{}: {source}", path.display())]
    InFile {
        path: PathBuf,
        #[source]
        source: Box<CameraError>,
    },
}

/// Reads, parses and validates a camera JSON file.
pub fn read_camera_json(path: &Path) -> Result<CameraJson, CameraError> {
    let text = std::fs::read_to_string(path).map_err(|source| CameraError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    parse_camera_json(&text).map_err(|e| CameraError::InFile {
        path: path.to_path_buf(),
        source: Box::new(e),
    })
}

/// Parses and validates camera JSON text.
pub fn parse_camera_json(text: &str) -> Result<CameraJson, CameraError> {
    let camera: CameraJson = serde_json::from_str(text).map_err(CameraError::Json)?;
    camera.validate()?;
    Ok(camera)
}

fn invalid(field: impl Into<String>, problem: String) -> CameraError {
    CameraError::Invalid {
        field: field.into(),
        problem,
    }
}

impl CameraJson {
    /// Checks the image size, the intrinsics and the world-to-camera matrix.
    pub fn validate(&self) -> Result<(), CameraError> {
        for (name, side) in [("width", self.width), ("height", self.height)] {
            if side == 0 || side > MAX_IMAGE_SIDE {
                return Err(invalid(
                    name,
                    format!("must be in 1..={MAX_IMAGE_SIDE}, got {side}"),
                ));
            }
        }
        for (name, f) in [("fx", self.fx), ("fy", self.fy)] {
            if !(f.is_finite() && f > 0.0) {
                return Err(invalid(name, format!("must be finite and > 0, got {f}")));
            }
        }
        for (name, c) in [("cx", self.cx), ("cy", self.cy)] {
            if !c.is_finite() {
                return Err(invalid(name, format!("must be finite, got {c}")));
            }
        }
        let m = &self.world_to_camera;
        for (r, row) in m.iter().enumerate() {
            for (c, v) in row.iter().enumerate() {
                if !v.is_finite() {
                    return Err(invalid(
                        format!("world_to_camera[{r}][{c}]"),
                        format!("must be finite, got {v}"),
                    ));
                }
            }
        }
        let expected = [0.0, 0.0, 0.0, 1.0];
        if m[3]
            .iter()
            .zip(expected)
            .any(|(v, e)| (v - e).abs() > LAST_ROW_TOLERANCE)
        {
            return Err(invalid(
                "world_to_camera[3]",
                format!("(last row) must be [0, 0, 0, 1], got {:?}", m[3]),
            ));
        }
        let det = self.rotation_det();
        if det.abs() <= MIN_ROTATION_DET {
            return Err(invalid(
                "world_to_camera",
                format!(
                    "rotation block (upper-left 3x3) must be invertible, \
                     got determinant {det:e}"
                ),
            ));
        }
        Ok(())
    }

    /// Intrinsic matrix `[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]`.
    pub fn k_matrix(&self) -> [[f64; 3]; 3] {
        [
            [self.fx, 0.0, self.cx],
            [0.0, self.fy, self.cy],
            [0.0, 0.0, 1.0],
        ]
    }

    /// Determinant of the upper-left 3x3 block of `world_to_camera`.
    fn rotation_det(&self) -> f64 {
        let m = &self.world_to_camera;
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const VALID: &str = r#"{
        "width": 640, "height": 480,
        "fx": 500.0, "fy": 510.0, "cx": 320.0, "cy": 240.5,
        "world_to_camera": [[1, 0, 0, 0.5], [0, 1, 0, -1], [0, 0, 1, 3], [0, 0, 0, 1]]
    }"#;

    fn valid() -> CameraJson {
        parse_camera_json(VALID).unwrap()
    }

    /// Returns the message of the validation error for a modified camera.
    fn problem(edit: impl FnOnce(&mut CameraJson)) -> String {
        let mut c = valid();
        edit(&mut c);
        let err = c.validate().unwrap_err();
        assert!(matches!(err, CameraError::Invalid { .. }), "{err}");
        err.to_string()
    }

    /// Guards the field mapping of a valid file (translation in column 3).
    #[test]
    fn valid_parse() {
        let c = valid();
        assert_eq!((c.width, c.height), (640, 480));
        assert_eq!((c.fx, c.fy, c.cx, c.cy), (500.0, 510.0, 320.0, 240.5));
        assert_eq!(c.world_to_camera[2][3], 3.0);
        assert_eq!(c.world_to_camera[0][3], 0.5);
    }

    /// Guards the image size bounds.
    #[test]
    fn bad_image_size_rejected() {
        assert!(problem(|c| c.width = 0).contains("width must be in 1..=16384, got 0"));
        assert!(problem(|c| c.height = 16385).contains("height"));
    }

    /// Guards the focal length checks, naming the field and value.
    #[test]
    fn bad_focal_rejected() {
        let msg = problem(|c| c.fx = -3.0);
        assert!(
            msg.contains("camera fx") && msg.contains("> 0, got -3"),
            "{msg}"
        );
        assert!(problem(|c| c.fy = 0.0).contains("fy"));
        assert!(problem(|c| c.fy = f64::NAN).contains("fy"));
        assert!(problem(|c| c.fx = f64::INFINITY).contains("fx"));
    }

    /// Guards the principal point finiteness check.
    #[test]
    fn non_finite_principal_point_rejected() {
        assert!(problem(|c| c.cx = f64::NAN).contains("cx"));
        assert!(problem(|c| c.cy = f64::NEG_INFINITY).contains("cy"));
    }

    /// Guards matrix entry finiteness, naming the entry.
    #[test]
    fn non_finite_matrix_entry_rejected() {
        let msg = problem(|c| c.world_to_camera[1][3] = f64::INFINITY);
        assert!(msg.contains("world_to_camera[1][3]"), "{msg}");
    }

    /// Guards the homogeneous last row check (e.g. a 3x4 padded wrongly).
    #[test]
    fn bad_last_row_rejected() {
        let msg = problem(|c| c.world_to_camera[3] = [0.0, 0.0, 1.0, 1.0]);
        assert!(msg.contains("last row"), "{msg}");
        let mut c = valid();
        c.world_to_camera[3][3] = 1.0 + 1e-9; // within tolerance
        c.validate().unwrap();
    }

    /// Guards the singular rotation check, while non-orthonormal is allowed.
    #[test]
    fn singular_rotation_rejected() {
        let msg = problem(|c| c.world_to_camera[2] = [0.0, 0.0, 0.0, 3.0]);
        assert!(msg.contains("invertible"), "{msg}");
        let mut c = valid();
        c.world_to_camera[0][0] = 2.0; // scaled, not orthonormal: accepted
        c.validate().unwrap();
    }

    /// Guards strict parsing: a typo'd field is an error naming it.
    #[test]
    fn unknown_field_rejected() {
        let text = VALID.replace("\"fy\"", "\"fyy\"");
        let msg = parse_camera_json(&text).unwrap_err().to_string();
        assert!(msg.contains("fyy") && msg.contains("line"), "{msg}");
    }

    /// Guards missing-field and syntax errors reporting field and position.
    #[test]
    fn missing_field_and_syntax_errors() {
        let text = VALID.replace("\"cy\": 240.5,", "");
        let msg = parse_camera_json(&text).unwrap_err().to_string();
        assert!(msg.contains("missing field `cy`"), "{msg}");
        let msg = parse_camera_json("{\n \"width\": 640,,\n}")
            .unwrap_err()
            .to_string();
        assert!(msg.contains("line 2"), "{msg}");
        assert!(parse_camera_json(&VALID.replace("640", "-640")).is_err());
    }

    /// Guards validation being applied on parse and errors naming the file.
    #[test]
    fn read_camera_json_names_path() {
        let dir = std::env::temp_dir().join(format!("envision4d-cam-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("cam.json");
        std::fs::write(&path, VALID.replace("500.0", "-3")).unwrap();
        let msg = read_camera_json(&path).unwrap_err().to_string();
        std::fs::write(&path, VALID).unwrap();
        let ok = read_camera_json(&path);
        std::fs::remove_dir_all(&dir).unwrap();
        assert!(
            msg.contains("cam.json") && msg.contains("fx must be"),
            "{msg}"
        );
        assert_eq!(ok.unwrap(), valid());
        let err = read_camera_json(&dir.join("missing.json")).unwrap_err();
        assert!(matches!(err, CameraError::Io { .. }));
    }

    /// Guards the intrinsic matrix layout (cx, cy in the last column).
    #[test]
    fn k_matrix_layout() {
        let k = valid().k_matrix();
        assert_eq!(
            k,
            [[500.0, 0.0, 320.0], [0.0, 510.0, 240.5], [0.0, 0.0, 1.0]]
        );
    }

    /// Guards serialisation staying compatible with parsing.
    #[test]
    fn serialize_round_trip() {
        let c = valid();
        let text = serde_json::to_string(&c).unwrap();
        assert_eq!(parse_camera_json(&text).unwrap(), c);
    }
}
