//! The official nuScenes layout: `<root>/samples/<CAMERA>/*`, `<root>/samples/LIDAR_TOP/
//! *.pcd.bin` and the metadata tables of `<root>/<version>/` (`nuscenes_tables`), with the
//! devkit's official scene splits (`nuscenes_splits`).
//!
//! A scene's frames are its keyframes (samples, 2 Hz) in order, following `next` from
//! `first_sample_token`; each keyframe contributes the camera's keyframe image. Ground truth
//! comes with every frame: intrinsics, the camera pose (`ego_pose · calibrated_sensor`; the
//! nuScenes camera frame is already OpenCV's, x right, y down, z forward) and the keyframe
//! LiDAR sweep, brought into the camera through the global frame so the ego motion between
//! the two sensors' timestamps is accounted for (the devkit's `map_pointcloud_to_image`).

use super::nuscenes_tables::{
    read_table, rigid, scene_name, split_scenes, version_of, CalibratedSensorRecord, EgoPoseRecord,
    SampleDataRecord, SampleRecord, SceneRecord, SensorRecord, CALIBRATED_SENSOR, EGO_POSE,
    LIDAR_CHANNEL, PCD_BIN_COLUMNS, SAMPLE, SAMPLE_DATA, SCENE, SENSOR,
};
use super::{window_starts, ClipEntry, GtSource, Scan};
use crate::clip::{ClipSpec, FrameGt};
use crate::depth_grid::read_lidar_records;
use crate::error::{DataError, Result};
use crate::geom::{Intrinsics, Mat4};
use crate::resize::Fit;
use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};

/// Offset from an integer-centred (OpenCV) pixel coordinate to ours (centre at u + 0.5).
pub const PIXEL_CENTRE: f64 = 0.5;

/// Reader settings.
#[derive(Debug, Clone, PartialEq)]
pub struct NuScenesConfig {
    /// An official split: `train`, `val`, `test`, `mini_train` or `mini_val`.
    pub split: String,
    /// Camera channel (the paper uses the front camera).
    pub camera: String,
    /// Keyframes between window starts.
    pub stride: usize,
    /// Windows per scene at most (`None`: all).
    pub windows_per_scene: Option<usize>,
    /// Whether the LiDAR sweeps are read (evaluation); training leaves them out.
    pub lidar: bool,
}

impl NuScenesConfig {
    pub fn new(split: &str, stride: usize, windows_per_scene: Option<usize>) -> NuScenesConfig {
        NuScenesConfig {
            split: split.into(),
            camera: "CAM_FRONT".into(),
            stride,
            windows_per_scene,
            lidar: true,
        }
    }
}

/// One keyframe's ground truth, resolved from the tables at scan time.
#[derive(Debug, Clone, PartialEq)]
pub struct NuFrame {
    /// Intrinsics of the source image.
    pub intrinsics: Intrinsics,
    /// OpenCV world(global)-to-camera.
    pub world_to_camera: Mat4,
    pub ego_to_world: Mat4,
    /// The keyframe LiDAR sweep and the transform from the LiDAR frame into the camera.
    pub lidar: Option<(PathBuf, Mat4)>,
}

/// Tables indexed for the scan.
struct Index {
    scenes: Vec<SceneRecord>,
    samples: HashMap<String, SampleRecord>,
    /// (sample token, channel) -> keyframe sample_data.
    keyframes: HashMap<(String, String), SampleDataRecord>,
    calibrated: HashMap<String, CalibratedSensorRecord>,
    ego: HashMap<String, EgoPoseRecord>,
}

fn load_index(dir: &Path, channels: &[&str]) -> Result<Index> {
    let sensors: Vec<SensorRecord> = read_table(dir, SENSOR)?;
    let channel_of: HashMap<String, String> =
        sensors.into_iter().map(|s| (s.token, s.channel)).collect();
    let calibrated: HashMap<String, CalibratedSensorRecord> =
        read_table::<CalibratedSensorRecord>(dir, CALIBRATED_SENSOR)?
            .into_iter()
            .map(|c| (c.token.clone(), c))
            .collect();
    let mut keyframes = HashMap::new();
    for sd in read_table::<SampleDataRecord>(dir, SAMPLE_DATA)? {
        if !sd.is_key_frame {
            continue;
        }
        let channel = calibrated
            .get(&sd.calibrated_sensor_token)
            .and_then(|c| channel_of.get(&c.sensor_token))
            .ok_or_else(|| {
                DataError::gt(
                    dir.join(format!("{SAMPLE_DATA}.json")),
                    format!(
                        "sample_data {}: calibrated_sensor {:?} or its sensor is not in the tables",
                        sd.token, sd.calibrated_sensor_token
                    ),
                )
            })?;
        if channels.contains(&channel.as_str()) {
            keyframes.insert((sd.sample_token.clone(), channel.clone()), sd);
        }
    }
    Ok(Index {
        scenes: read_table(dir, SCENE)?,
        samples: read_table::<SampleRecord>(dir, SAMPLE)?
            .into_iter()
            .map(|s| (s.token.clone(), s))
            .collect(),
        keyframes,
        calibrated,
        ego: read_table::<EgoPoseRecord>(dir, EGO_POSE)?
            .into_iter()
            .map(|e| (e.token.clone(), e))
            .collect(),
    })
}

pub fn scan(root: &Path, spec: &ClipSpec, cfg: &NuScenesConfig) -> Result<Scan> {
    if cfg.stride == 0 {
        return Err(DataError::config("stride", 0, "must be at least 1"));
    }
    let (Some(version), Some(wanted)) = (version_of(&cfg.split), split_scenes(&cfg.split)) else {
        return Err(DataError::config(
            "split",
            &cfg.split,
            "nuScenes splits are train, val, test (v1.0-trainval / v1.0-test), mini_train, mini_val (v1.0-mini)",
        ));
    };
    let dir = root.join(version);
    if !dir.is_dir() {
        let found: Vec<String> = super::read_dir_sorted(root)
            .unwrap_or_default()
            .iter()
            .filter_map(|p| p.file_name()?.to_str().map(str::to_owned))
            .filter(|n| n.starts_with("v1.0-"))
            .collect();
        return Err(DataError::config(
            "split",
            &cfg.split,
            format!(
                "needs the {version} tables in {}; found {}",
                root.display(),
                if found.is_empty() {
                    "no v1.0-* folder".to_owned()
                } else {
                    found.join(", ")
                }
            ),
        ));
    }
    let index = load_index(&dir, &[cfg.camera.as_str(), LIDAR_CHANNEL])?;
    let wanted: HashSet<String> = wanted.iter().map(|&n| scene_name(n)).collect();
    let mut scan = Scan::default();
    let mut scenes: Vec<&SceneRecord> = index
        .scenes
        .iter()
        .filter(|s| wanted.contains(&s.name))
        .collect();
    scenes.sort_by(|a, b| a.name.cmp(&b.name));
    // Two records of one scene would yield its clips twice (and mix their tokens).
    if let Some(pair) = scenes.windows(2).find(|p| p[0].name == p[1].name) {
        return Err(DataError::gt(
            dir.join(format!("{SCENE}.json")),
            format!("scene {:?} is listed twice", pair[0].name),
        ));
    }
    let absent = wanted.len().saturating_sub(scenes.len());
    if absent > 0 {
        scan.skipped.push(format!(
            "{}: {absent} of the {} scenes of split {:?} are not in its scene table",
            dir.display(),
            wanted.len(),
            cfg.split
        ));
    }
    for scene in scenes {
        match scene_clips(root, &dir, &index, scene, spec, cfg) {
            Ok(entries) => scan.entries.extend(entries),
            Err(e) => scan.skipped.push(e.to_string()),
        }
    }
    if scan.entries.is_empty() && scan.skipped.is_empty() {
        return Err(DataError::EmptyFolder { path: dir });
    }
    Ok(scan)
}

fn scene_clips(
    root: &Path,
    dir: &Path,
    index: &Index,
    scene: &SceneRecord,
    spec: &ClipSpec,
    cfg: &NuScenesConfig,
) -> Result<Vec<ClipEntry>> {
    let table = |name: &str| dir.join(format!("{name}.json"));
    let mut frames: Vec<(PathBuf, NuFrame)> = Vec::new();
    let mut token = scene.first_sample_token.clone();
    // A `next` cycle in a corrupt table must not loop forever.
    let mut seen = HashSet::new();
    while !token.is_empty() && seen.insert(token.clone()) {
        let sample = index.samples.get(&token).ok_or_else(|| {
            DataError::gt(
                table(SAMPLE),
                format!("{}: no sample {token:?}", scene.name),
            )
        })?;
        let key = |ch: &str| (token.clone(), ch.to_owned());
        let cam = index.keyframes.get(&key(&cfg.camera)).ok_or_else(|| {
            DataError::gt(
                table(SAMPLE_DATA),
                format!(
                    "{}: sample {token} has no {} keyframe",
                    scene.name, cfg.camera
                ),
            )
        })?;
        let lidar = index
            .keyframes
            .get(&key(LIDAR_CHANNEL))
            .filter(|_| cfg.lidar);
        frames.push((
            root.join(&cam.filename),
            frame_gt(dir, index, cam, lidar, root)?,
        ));
        token = sample.next.clone();
    }
    let starts = window_starts(frames.len(), spec.span(), cfg.stride);
    if starts.is_empty() {
        return Err(DataError::TooFewFrames {
            path: PathBuf::from(format!("{}/{}", dir.display(), scene.name)),
            found: frames.len(),
            needed: spec.span(),
        });
    }
    let cap = cfg.windows_per_scene.unwrap_or(usize::MAX);
    Ok(starts
        .into_iter()
        .take(cap)
        .enumerate()
        .map(|(k, s)| {
            let window: Vec<_> = spec.frames_from(s).map(|i| &frames[i]).collect();
            ClipEntry {
                id: format!("{}/{}#{k}", cfg.split, scene.name),
                group: format!("{}/{}", cfg.split, scene.name),
                frames: window.iter().map(|(p, _)| p.clone()).collect(),
                frame_numbers: spec.frames_from(s).map(|i| i as i64).collect(),
                gt: GtSource::NuScenes {
                    frames: window.iter().map(|(_, g)| g.clone()).collect(),
                },
            }
        })
        .collect())
}

/// Pose, intrinsics and LiDAR transform of one camera keyframe.
fn frame_gt(
    dir: &Path,
    index: &Index,
    cam: &SampleDataRecord,
    lidar: Option<&SampleDataRecord>,
    root: &Path,
) -> Result<NuFrame> {
    let table = |name: &str| dir.join(format!("{name}.json"));
    let sensor_to_world = |sd: &SampleDataRecord| -> Result<(Mat4, Mat4, &CalibratedSensorRecord)> {
        let cs = index
            .calibrated
            .get(&sd.calibrated_sensor_token)
            .ok_or_else(|| {
                DataError::gt(
                    table(CALIBRATED_SENSOR),
                    format!("no record {:?}", sd.calibrated_sensor_token),
                )
            })?;
        let ego = index.ego.get(&sd.ego_pose_token).ok_or_else(|| {
            DataError::gt(
                table(EGO_POSE),
                format!("no record {:?}", sd.ego_pose_token),
            )
        })?;
        let s2e = rigid(cs.rotation, cs.translation).ok_or_else(|| {
            DataError::gt(
                table(CALIBRATED_SENSOR),
                format!("{}: not a rigid transform", cs.token),
            )
        })?;
        let e2w = rigid(ego.rotation, ego.translation).ok_or_else(|| {
            DataError::gt(
                table(EGO_POSE),
                format!("{}: not a rigid transform", ego.token),
            )
        })?;
        Ok((e2w.mul(&s2e), e2w, cs))
    };
    let (cam_to_world, ego_to_world, cs) = sensor_to_world(cam)?;
    // nuScenes calibrations put pixel centres at integer coordinates (OpenCV); ours put
    // them at u + 0.5, so the principal point moves by half a pixel.
    let k = match cs.camera_intrinsic[..] {
        [r0, r1, _] if r0[0] > 0.0 && r1[1] > 0.0 => Intrinsics {
            fx: r0[0],
            fy: r1[1],
            cx: r0[2] + PIXEL_CENTRE,
            cy: r1[2] + PIXEL_CENTRE,
        },
        _ => {
            return Err(DataError::gt(
                table(CALIBRATED_SENSOR),
                format!(
                    "{}: camera_intrinsic is not a 3x3 matrix with positive focals",
                    cs.token
                ),
            ))
        }
    };
    let world_to_camera = cam_to_world.rigid_inverse();
    let lidar = lidar
        .map(|sd| -> Result<(PathBuf, Mat4)> {
            let (lidar_to_world, _, _) = sensor_to_world(sd)?;
            Ok((
                root.join(&sd.filename),
                world_to_camera.mul(&lidar_to_world),
            ))
        })
        .transpose()?;
    Ok(NuFrame {
        intrinsics: k,
        world_to_camera,
        ego_to_world,
        lidar,
    })
}

/// Ground truth of a window's frames; the LiDAR sweeps are read here (a bad one fails the
/// clip, naming the file).
pub fn load_nuscenes_gt(
    frames: &[NuFrame],
    source_size: (usize, usize),
    fit: &Fit,
) -> Result<Vec<FrameGt>> {
    frames
        .iter()
        .map(|f| {
            let lidar_points = f
                .lidar
                .as_ref()
                .map(|(path, to_cam)| read_pcd_bin(path, to_cam))
                .transpose()?;
            Ok(FrameGt {
                intrinsics: Some(fit.intrinsics(&f.intrinsics, source_size)),
                world_to_camera: Some(f.world_to_camera),
                ego_to_world: Some(f.ego_to_world),
                depth: None,
                lidar_points,
                flow: None,
                dynamic_mask: None,
                instance: None,
                objects: None,
            })
        })
        .collect()
}

/// A `.pcd.bin` sweep (records of [`PCD_BIN_COLUMNS`] floats, LiDAR frame) in the camera frame.
fn read_pcd_bin(path: &Path, to_cam: &Mat4) -> Result<Vec<[f32; 3]>> {
    read_lidar_records(path, PCD_BIN_COLUMNS, 0, to_cam)
}
