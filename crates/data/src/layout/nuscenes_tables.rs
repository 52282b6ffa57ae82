//! The nuScenes metadata tables the reader needs (`<root>/<version>/<table>.json`), as the
//! devkit's schema defines them; unknown fields are ignored. Shared by the reader and the
//! synthetic writer, so both agree on names and types.

use crate::error::{DataError, Result};
use crate::geom::{Mat4, Vec3};
use glam::{DMat3, DQuat};
use serde::{Deserialize, Serialize};
use std::path::Path;

pub const SCENE: &str = "scene";
pub const SAMPLE: &str = "sample";
pub const SAMPLE_DATA: &str = "sample_data";
pub const SENSOR: &str = "sensor";
pub const CALIBRATED_SENSOR: &str = "calibrated_sensor";
pub const EGO_POSE: &str = "ego_pose";
pub const LOG: &str = "log";
/// The tables the reader opens.
pub const TABLES: [&str; 6] = [
    SCENE,
    SAMPLE,
    SAMPLE_DATA,
    SENSOR,
    CALIBRATED_SENSOR,
    EGO_POSE,
];
/// The LiDAR channel projected into the camera.
pub const LIDAR_CHANNEL: &str = "LIDAR_TOP";
/// Floats per point of a `.pcd.bin` sweep: x, y, z, intensity, ring index.
pub const PCD_BIN_COLUMNS: usize = 5;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SceneRecord {
    pub token: String,
    #[serde(default)]
    pub log_token: String,
    #[serde(default)]
    pub nbr_samples: usize,
    pub first_sample_token: String,
    #[serde(default)]
    pub last_sample_token: String,
    pub name: String,
    #[serde(default)]
    pub description: String,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SampleRecord {
    pub token: String,
    pub timestamp: i64,
    pub prev: String,
    pub next: String,
    pub scene_token: String,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SampleDataRecord {
    pub token: String,
    pub sample_token: String,
    pub ego_pose_token: String,
    pub calibrated_sensor_token: String,
    pub timestamp: i64,
    #[serde(default)]
    pub fileformat: String,
    pub is_key_frame: bool,
    #[serde(default)]
    pub height: usize,
    #[serde(default)]
    pub width: usize,
    pub filename: String,
    #[serde(default)]
    pub prev: String,
    #[serde(default)]
    pub next: String,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SensorRecord {
    pub token: String,
    pub channel: String,
    #[serde(default)]
    pub modality: String,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CalibratedSensorRecord {
    pub token: String,
    pub sensor_token: String,
    /// Sensor -> ego, metres.
    pub translation: [f64; 3],
    /// Sensor -> ego, quaternion `[w, x, y, z]`.
    pub rotation: [f64; 4],
    /// 3x3 pixel intrinsics for cameras, empty for other sensors.
    #[serde(default)]
    pub camera_intrinsic: Vec<[f64; 3]>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EgoPoseRecord {
    pub token: String,
    pub timestamp: i64,
    /// Ego -> global, quaternion `[w, x, y, z]`.
    pub rotation: [f64; 4],
    /// Ego -> global, metres.
    pub translation: [f64; 3],
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LogRecord {
    pub token: String,
    pub logfile: String,
    pub vehicle: String,
    pub date_captured: String,
    pub location: String,
}

/// `<dir>/<name>.json` as a list of records, naming the file in errors.
pub fn read_table<T: for<'de> Deserialize<'de>>(dir: &Path, name: &str) -> Result<Vec<T>> {
    let path = dir.join(format!("{name}.json"));
    let bytes = std::fs::read(&path).map_err(|e| DataError::gt(&path, e.to_string()))?;
    serde_json::from_slice(&bytes).map_err(|e| DataError::gt(&path, e.to_string()))
}

/// Quaternions further than this from unit norm are rejected (files carry ~1e-8 noise).
const UNIT_QUATERNION_TOLERANCE: f64 = 1e-3;

/// A rigid transform from a nuScenes `[w, x, y, z]` rotation and a translation; `None` when
/// the quaternion is not (close to) unit or a value is not finite.
pub fn rigid(rotation: [f64; 4], translation: [f64; 3]) -> Option<Mat4> {
    let [w, x, y, z] = rotation;
    let q = DQuat::from_xyzw(x, y, z, w);
    let finite = rotation.iter().chain(&translation).all(|v| v.is_finite());
    if !finite || (q.length() - 1.0).abs() > UNIT_QUATERNION_TOLERANCE {
        return None;
    }
    let r = DMat3::from_quat(q.normalize());
    let rows = [0, 1, 2].map(|i| [r.x_axis[i], r.y_axis[i], r.z_axis[i]]);
    let [tx, ty, tz] = translation;
    Some(Mat4::from_rt(rows, Vec3::new(tx, ty, tz)))
}

/// The `[w, x, y, z]` quaternion of a rigid transform's rotation (for the writer).
pub fn quaternion(m: &Mat4) -> [f64; 4] {
    let q = DQuat::from_mat3(&m.rotation()).normalize();
    [q.w, q.x, q.y, q.z]
}

/// The official version folder of a split: `mini_*` in `v1.0-mini`, `test` in `v1.0-test`,
/// `train` / `val` in `v1.0-trainval`; `None` for another name.
pub fn version_of(split: &str) -> Option<&'static str> {
    match split {
        "train" | "val" => Some("v1.0-trainval"),
        "mini_train" | "mini_val" => Some("v1.0-mini"),
        "test" => Some("v1.0-test"),
        _ => None,
    }
}

/// Scene numbers of an official split (`scene-{n:04}`).
pub fn split_scenes(split: &str) -> Option<&'static [u16]> {
    use super::nuscenes_splits as s;
    Some(match split {
        "train" => &s::TRAIN,
        "val" => &s::VAL,
        "test" => &s::TEST,
        "mini_train" => &s::MINI_TRAIN,
        "mini_val" => &s::MINI_VAL,
        _ => return None,
    })
}

/// The official name of scene number `n`.
pub fn scene_name(n: u16) -> String {
    format!("scene-{n:04}")
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashSet;

    /// Guards the split lists: the devkit's counts, and no scene in two splits of a version.
    #[test]
    fn official_split_sizes_and_disjointness() {
        let n = |s| split_scenes(s).unwrap().len();
        assert_eq!((n("train"), n("val"), n("test")), (700, 150, 150));
        assert_eq!((n("mini_train"), n("mini_val")), (8, 2));
        let set = |s| {
            split_scenes(s)
                .unwrap()
                .iter()
                .copied()
                .collect::<HashSet<u16>>()
        };
        assert!(set("train").is_disjoint(&set("val")));
        assert!(set("mini_train").is_disjoint(&set("mini_val")));
        assert!(set("test").is_disjoint(&set("train")));
        // The mini scenes are trainval scenes.
        assert!(set("mini_val").is_subset(&set("val").union(&set("train")).copied().collect()));
    }

    /// Guards quaternion order ([w, x, y, z]) and the round trip through `quaternion`.
    #[test]
    fn quaternions_are_w_first() {
        // 90° about z.
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let m = rigid([h, 0.0, 0.0, h], [1.0, 2.0, 3.0]).unwrap();
        let p = m.transform_point(Vec3::new(1.0, 0.0, 0.0));
        assert!((p - Vec3::new(1.0, 3.0, 3.0)).norm() < 1e-12, "{p:?}");
        let q = quaternion(&m);
        assert!(
            (q[0] - h).abs() < 1e-12 && (q[3] - h).abs() < 1e-12,
            "{q:?}"
        );
        assert!(rigid([2.0, 0.0, 0.0, 0.0], [0.0; 3]).is_none());
    }
}
