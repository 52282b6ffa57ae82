//! Writes rendered clips as scenes of the official nuScenes layout (read by
//! `layout::nuscenes`, documented in docs/DATA.md): keyframe images in
//! `samples/CAM_FRONT/`, LiDAR sweeps in `samples/LIDAR_TOP/*.pcd.bin`, and the metadata
//! tables of `<version>/`. Each clip becomes the scene of an official split named by that
//! split's list (`scene-0061`, … for `mini_train`), so the official split selects it. Tables
//! already in the folder are kept and extended: several runs build one tree.
//!
//! Every frame is a keyframe (our clips are 10 Hz; the timestamps say so). The LiDAR is the
//! STORM writer's scan-line pattern, as points in the LiDAR's own frame.

use super::storm_writer::{lidar_returns, POINT_COLUMN_STEP};
use super::{ClipRender, FRAME_INTERVAL_S};
use crate::atomic::{create_dir, write_bytes};
use crate::error::{DataError, Result};
use crate::frame::{encode_png_rgb8, Image};
use crate::geom::Mat4;
use crate::layout::nuscenes::PIXEL_CENTRE;
use crate::layout::nuscenes_tables::{
    quaternion, read_table, rigid, scene_name, split_scenes, version_of, CalibratedSensorRecord,
    EgoPoseRecord, LogRecord, SampleDataRecord, SampleRecord, SceneRecord, SensorRecord,
    CALIBRATED_SENSOR, EGO_POSE, LIDAR_CHANNEL, LOG, SAMPLE, SAMPLE_DATA, SCENE, SENSOR,
};
use crate::layout::waymo::OPENCV_TO_WAYMO_CAMERA;
use serde::{de::DeserializeOwned, Serialize};
use std::path::Path;

const CAMERA: &str = "CAM_FRONT";
/// Camera mount on the ego (nuScenes ego axes: x forward, y left, z up).
const CAMERA_MOUNT: [f64; 3] = [1.7, 0.0, 1.5];
/// LiDAR mount, turned 90° about z as nuScenes' LIDAR_TOP is (w, x, y, z).
const LIDAR_MOUNT: [f64; 3] = [0.9, 0.0, 1.85];
const LIDAR_ROTATION: [f64; 4] = [
    std::f64::consts::FRAC_1_SQRT_2,
    0.0,
    0.0,
    std::f64::consts::FRAC_1_SQRT_2,
];
/// Microseconds of the first frame of scene `n`: 1 000 s between scene numbers.
const EPOCH_US: i64 = 1_533_000_000_000_000;

/// A deterministic 32-hex-digit token for record `index` of `kind` in scene `scene`.
fn token(kind: u32, scene: u16, index: usize) -> String {
    format!("{kind:08x}{scene:08x}{index:016x}")
}

/// The records of one table: those already on disk, then ours.
fn extend<T: Serialize + DeserializeOwned>(dir: &Path, name: &str, mut ours: Vec<T>) -> Result<()> {
    let path = dir.join(format!("{name}.json"));
    let mut all: Vec<T> = if path.is_file() {
        read_table(dir, name)?
    } else {
        Vec::new()
    };
    all.append(&mut ours);
    let bytes = serde_json::to_vec_pretty(&all).map_err(|e| DataError::Write {
        path: path.clone(),
        msg: e.to_string(),
    })?;
    write_bytes(&path, &bytes)
}

/// Writes `clips` into the nuScenes tree at `root` as scenes `first_scene..` of `split`.
pub fn write_nuscenes_scenes(
    root: &Path,
    split: &str,
    first_scene: usize,
    clips: &[ClipRender],
) -> Result<()> {
    let (Some(version), Some(names)) = (version_of(split), split_scenes(split)) else {
        return Err(DataError::config(
            "split",
            split,
            "nuScenes splits are train, val, test, mini_train, mini_val",
        ));
    };
    if first_scene + clips.len() > names.len() {
        return Err(DataError::config(
            "clips",
            clips.len(),
            format!("split {split} has {} scenes", names.len()),
        ));
    }
    let tables = root.join(version);
    if tables.join(format!("{SCENE}.json")).is_file() {
        let existing: Vec<SceneRecord> = read_table(&tables, SCENE)?;
        let ours: Vec<String> = (0..clips.len())
            .map(|i| scene_name(names[first_scene + i]))
            .collect();
        if let Some(dup) = existing.iter().find(|s| ours.contains(&s.name)) {
            return Err(DataError::config(
                "first_scene",
                first_scene,
                format!(
                    "{} already holds {:?}: pass a --first-scene past the scenes written",
                    tables.display(),
                    dup.name
                ),
            ));
        }
    }
    for d in [
        tables.clone(),
        root.join("samples").join(CAMERA),
        root.join("samples").join(LIDAR_CHANNEL),
    ] {
        create_dir(&d)?;
    }
    let (cam_sensor, lidar_sensor) = (
        "00000000000000000000000000000c01",
        "00000000000000000000000000000c02",
    );
    let sensors_path = tables.join(format!("{SENSOR}.json"));
    if !sensors_path.is_file() {
        extend(
            &tables,
            SENSOR,
            vec![
                SensorRecord {
                    token: cam_sensor.into(),
                    channel: CAMERA.into(),
                    modality: "camera".into(),
                },
                SensorRecord {
                    token: lidar_sensor.into(),
                    channel: LIDAR_CHANNEL.into(),
                    modality: "lidar".into(),
                },
            ],
        )?;
    }
    let cam_to_ego = camera_to_ego();
    let lidar_to_ego = rigid(LIDAR_ROTATION, LIDAR_MOUNT).expect("unit quaternion");
    let (mut scenes, mut samples, mut data, mut calib, mut poses, mut logs) =
        (vec![], vec![], vec![], vec![], vec![], vec![]);
    for (i, clip) in clips.iter().enumerate() {
        let n = names[first_scene + i];
        let name = scene_name(n);
        let k = clip.cameras[0].intrinsics;
        let (w, h) = (clip.config.width, clip.config.height);
        let frames = clip.frames.len();
        let sample_tok = |t: usize| token(2, n, t);
        calib.push(CalibratedSensorRecord {
            token: token(7, n, 0),
            sensor_token: cam_sensor.into(),
            translation: CAMERA_MOUNT,
            rotation: quaternion(&cam_to_ego),
            // nuScenes' convention: pixel centres at integers (the reader adds the half back).
            camera_intrinsic: vec![
                [k.fx, 0.0, k.cx - PIXEL_CENTRE],
                [0.0, k.fy, k.cy - PIXEL_CENTRE],
                [0.0, 0.0, 1.0],
            ],
        });
        calib.push(CalibratedSensorRecord {
            token: token(8, n, 0),
            sensor_token: lidar_sensor.into(),
            translation: LIDAR_MOUNT,
            rotation: LIDAR_ROTATION,
            camera_intrinsic: vec![],
        });
        logs.push(LogRecord {
            token: token(9, n, 0),
            logfile: format!("envision4d-synth-{name}"),
            vehicle: "synthetic".into(),
            date_captured: "2018-08-01".into(),
            location: "synthetic".into(),
        });
        scenes.push(SceneRecord {
            token: token(1, n, 0),
            log_token: token(9, n, 0),
            nbr_samples: frames,
            first_sample_token: sample_tok(0),
            last_sample_token: sample_tok(frames - 1),
            name: name.clone(),
            description: format!("envision4d synth, preset {}", clip.config.preset.name()),
        });
        let lidar_from_ego = lidar_to_ego.rigid_inverse();
        for (t, (frame, cam)) in clip.frames.iter().zip(&clip.cameras).enumerate() {
            let ts =
                EPOCH_US + n as i64 * 1_000_000_000 + (t as f64 * FRAME_INTERVAL_S * 1e6) as i64;
            let link = |kind: u32, j: Option<usize>| j.map_or(String::new(), |j| token(kind, n, j));
            let (prev, next) = (t.checked_sub(1), (t + 1 < frames).then_some(t + 1));
            samples.push(SampleRecord {
                token: sample_tok(t),
                timestamp: ts,
                prev: link(2, prev),
                next: link(2, next),
                scene_token: token(1, n, 0),
            });
            let ego_to_world = cam
                .world_to_camera
                .rigid_inverse()
                .mul(&cam_to_ego.rigid_inverse());
            for kind in [5, 6] {
                poses.push(EgoPoseRecord {
                    token: token(kind, n, t),
                    timestamp: ts,
                    rotation: quaternion(&ego_to_world),
                    translation: ego_to_world.translation().to_array(),
                });
            }
            // nuScenes names files `<log>__<CHANNEL>__<microseconds>`.
            let img = format!("samples/{CAMERA}/{name}__{CAMERA}__{ts}.png");
            let png = encode_png_rgb8(&Image::new(w, h, frame.rgb.clone())).map_err(|msg| {
                DataError::Write {
                    path: root.join(&img),
                    msg,
                }
            })?;
            write_bytes(&root.join(&img), &png)?;
            let pcd = format!("samples/{LIDAR_CHANNEL}/{name}__{LIDAR_CHANNEL}__{ts}.pcd.bin");
            let cv_to_lidar = lidar_from_ego.mul(&cam_to_ego);
            let mut points: Vec<f32> = Vec::new();
            for (u, v, z) in lidar_returns(&frame.depth, w, h) {
                if u % POINT_COLUMN_STEP == 0 {
                    let p = cv_to_lidar.transform_point(k.unproject(
                        u as f64 + 0.5,
                        v as f64 + 0.5,
                        z as f64,
                    ));
                    points.extend([p.x as f32, p.y as f32, p.z as f32, 0.0, v as f32]);
                }
            }
            let bytes: Vec<u8> = points.iter().flat_map(|x| x.to_le_bytes()).collect();
            write_bytes(&root.join(&pcd), &bytes)?;
            for (kind, pose, cs, file, fmt) in [(3, 5, 7, img, "png"), (4, 6, 8, pcd, "pcd")] {
                data.push(SampleDataRecord {
                    token: token(kind, n, t),
                    sample_token: sample_tok(t),
                    ego_pose_token: token(pose, n, t),
                    calibrated_sensor_token: token(cs, n, 0),
                    timestamp: ts,
                    fileformat: fmt.into(),
                    is_key_frame: true,
                    height: if kind == 3 { h } else { 0 },
                    width: if kind == 3 { w } else { 0 },
                    filename: file,
                    prev: link(kind, prev),
                    next: link(kind, next),
                });
            }
        }
    }
    extend(&tables, CALIBRATED_SENSOR, calib)?;
    extend(&tables, EGO_POSE, poses)?;
    extend(&tables, SAMPLE_DATA, data)?;
    extend(&tables, SAMPLE, samples)?;
    extend(&tables, LOG, logs)?;
    // The scene table last: a tree interrupted before it lists no half-written scene.
    extend(&tables, SCENE, scenes)
}

/// The writer's camera-to-ego transform: the mount, OpenCV camera axes turned into the
/// ego's (x forward, y left, z up).
pub fn camera_to_ego() -> Mat4 {
    rigid([1.0, 0.0, 0.0, 0.0], CAMERA_MOUNT)
        .expect("unit quaternion")
        .mul(&OPENCV_TO_WAYMO_CAMERA)
}
