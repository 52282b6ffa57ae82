//! Writes a rendered clip as one scene of STORM's preprocessed Waymo layout (read by
//! `layout::waymo`, documented in docs/DATA.md), so the real-data path runs end to end
//! without the dataset:
//! `<split>/<scene:03d>/{images,intrinsics,cam_to_ego,ego_to_world,cam_to_world,
//! depth_flows_4,lidar}/`, front camera (id 0) only.
//!
//! The LiDAR is made LiDAR-like from the exact depth: returns only on every
//! [`BEAM_ROW_STEP`]-th pixel row (scan lines), none on the sky or beyond [`LIDAR_RANGE_M`].
//! `depth_flows_4` holds the mean z-depth of the returns in each quarter-grid cell (0 = no
//! return) and their mean scene flow in the vehicle frame; `lidar/*.bin` holds the same
//! returns as points, every [`POINT_COLUMN_STEP`]-th column, in STORM's 10-column records.

use super::ClipRender;
use crate::atomic::{create_dir, write_bytes};
use crate::error::{DataError, Result};
use crate::frame::{encode_png_rgb8, Image};
use crate::geom::{Mat4, Vec3};
use crate::layout::waymo::{LIDAR_COLUMNS, OPENCV_TO_WAYMO_CAMERA};
use crate::npy::encode_npy_f32;
use std::path::Path;

/// Pixel rows between two scan lines of the fake LiDAR.
pub const BEAM_ROW_STEP: usize = 8;
/// Pixel columns between two points written to `lidar/*.bin`.
pub const POINT_COLUMN_STEP: usize = 2;
/// Returns beyond this are dropped (Waymo's mid-range LiDAR is truncated at 75 m).
pub const LIDAR_RANGE_M: f32 = 75.0;
/// The camera's mount on the vehicle: 1.5 m ahead of and 1.8 m above the vehicle origin,
/// axes aligned with the vehicle's (Waymo camera axes: x forward, y left, z up).
const CAMERA_MOUNT: [f64; 3] = [1.5, 0.0, 1.8];
/// Where the fake LiDAR sits on the vehicle (the `origin` columns of each record).
const LIDAR_MOUNT: [f32; 3] = [1.2, 0.0, 2.2];
/// The front camera's id in file names.
const CAMERA: u32 = 0;
/// Channels of `depth_flows_4`: depth, then flow xyz.
const DEPTH_FLOW_CHANNELS: usize = 4;

/// `cam_to_ego/0.txt`.
pub fn camera_to_ego() -> Mat4 {
    let [x, y, z] = CAMERA_MOUNT;
    Mat4::from_rt(
        [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        Vec3::new(x, y, z),
    )
}

/// The fake LiDAR's returns of a frame's exact z-depth `depth` (`w × h`): `(u, v, z)` on every
/// [`BEAM_ROW_STEP`]-th row, where there is a surface within [`LIDAR_RANGE_M`].
pub fn lidar_returns(
    depth: &[f32],
    w: usize,
    h: usize,
) -> impl Iterator<Item = (usize, usize, f32)> + '_ {
    (0..h).step_by(BEAM_ROW_STEP).flat_map(move |v| {
        (0..w).filter_map(move |u| {
            let z = depth[v * w + u];
            (z > 0.0 && z <= LIDAR_RANGE_M).then_some((u, v, z))
        })
    })
}

fn matrix_text(m: &Mat4) -> String {
    m.0.iter()
        .map(|row| row.map(|v| v.to_string()).join(" "))
        .collect::<Vec<_>>()
        .join("\n")
        + "\n"
}

fn write_text(path: &Path, text: &str) -> Result<()> {
    write_bytes(path, text.as_bytes())
}

/// Writes `clip` as scene folder `scene_dir` (e.g. `<root>/training/003`).
pub fn write_storm_scene(scene_dir: &Path, clip: &ClipRender) -> Result<()> {
    let cfg = &clip.config;
    let (w, h) = (cfg.width, cfg.height);
    let (hq, wq) = (h / 4, w / 4);
    if hq == 0 || wq == 0 {
        return Err(DataError::config(
            "size",
            format!("{h}x{w}"),
            "the STORM layout's quarter grid needs at least 4x4 pixels",
        ));
    }
    let dirs = [
        "images",
        "intrinsics",
        "cam_to_ego",
        "ego_to_world",
        "cam_to_world",
        "depth_flows_4",
        "lidar",
    ];
    for d in dirs {
        create_dir(&scene_dir.join(d))?;
    }
    let k =
        clip.cameras.first().map(|c| c.intrinsics).ok_or_else(|| {
            DataError::config("frames", 0, "a STORM scene needs at least one frame")
        })?;
    // Waymo order f_u f_v c_u c_v k1 k2 p1 p2 k3 (no distortion here).
    write_text(
        &scene_dir.join("intrinsics").join(format!("{CAMERA}.txt")),
        &format!("{} {} {} {} 0 0 0 0 0\n", k.fx, k.fy, k.cx, k.cy),
    )?;
    let cam_to_ego = camera_to_ego();
    write_text(
        &scene_dir.join("cam_to_ego").join(format!("{CAMERA}.txt")),
        &matrix_text(&cam_to_ego),
    )?;
    let waymo_to_cv = OPENCV_TO_WAYMO_CAMERA.rigid_inverse();
    for (t, (frame, cam)) in clip.frames.iter().zip(&clip.cameras).enumerate() {
        let png = encode_png_rgb8(&Image::new(w, h, frame.rgb.clone())).map_err(|msg| {
            DataError::Write {
                path: scene_dir.join("images"),
                msg,
            }
        })?;
        write_bytes(
            &scene_dir
                .join("images")
                .join(format!("{t:03}_{CAMERA}.png")),
            &png,
        )?;
        // OpenCV c2w = Waymo-axes c2w · OPENCV_TO_WAYMO, and ego_to_world = c2w · cam_to_ego⁻¹.
        let c2w_cv = cam.world_to_camera.rigid_inverse();
        let c2w_waymo = c2w_cv.mul(&waymo_to_cv);
        let ego_to_world = c2w_waymo.mul(&cam_to_ego.rigid_inverse());
        write_text(
            &scene_dir
                .join("cam_to_world")
                .join(format!("{t:03}_{CAMERA}.txt")),
            &matrix_text(&c2w_waymo),
        )?;
        write_text(
            &scene_dir.join("ego_to_world").join(format!("{t:03}.txt")),
            &matrix_text(&ego_to_world),
        )?;
        let world_to_ego = ego_to_world.rigid_inverse();
        let cv_to_ego = cam_to_ego.mul(&OPENCV_TO_WAYMO_CAMERA);
        let mut grid = vec![0.0f32; hq * wq * DEPTH_FLOW_CHANNELS];
        let mut count = vec![0u32; hq * wq];
        let mut records: Vec<f32> = Vec::new();
        for (u, v, z) in lidar_returns(&frame.depth, w, h) {
            let i = v * w + u;
            let f = &frame.flow[i * 3..i * 3 + 3];
            let flow_world = Vec3::new(f[0] as f64, f[1] as f64, f[2] as f64);
            let flow = rotate(&world_to_ego, flow_world);
            // The quarter cell whose area holds this pixel's centre.
            let vq = (((v as f64 + 0.5) * hq as f64 / h as f64) as usize).min(hq - 1);
            let uq = (((u as f64 + 0.5) * wq as f64 / w as f64) as usize).min(wq - 1);
            let c = vq * wq + uq;
            count[c] += 1;
            let cell = &mut grid[c * DEPTH_FLOW_CHANNELS..(c + 1) * DEPTH_FLOW_CHANNELS];
            for (slot, val) in cell.iter_mut().zip([z as f64, flow.x, flow.y, flow.z]) {
                *slot += val as f32;
            }
            if u % POINT_COLUMN_STEP == 0 {
                let p_cv = k.unproject(u as f64 + 0.5, v as f64 + 0.5, z as f64);
                let p = cv_to_ego.transform_point(p_cv);
                let class = if frame.instance[i] > 0 { 1.0 } else { 0.0 };
                records.extend(LIDAR_MOUNT);
                records.extend([p.x, p.y, p.z, flow.x, flow.y, flow.z].map(|x| x as f32));
                records.push(class);
            }
        }
        for (c, &n) in count.iter().enumerate().filter(|(_, n)| **n > 0) {
            for slot in &mut grid[c * DEPTH_FLOW_CHANNELS..(c + 1) * DEPTH_FLOW_CHANNELS] {
                *slot /= n as f32;
            }
        }
        debug_assert_eq!(records.len() % LIDAR_COLUMNS, 0);
        write_bytes(
            &scene_dir
                .join("depth_flows_4")
                .join(format!("{t:03}_{CAMERA}.npy")),
            &encode_npy_f32(&[hq, wq, DEPTH_FLOW_CHANNELS], &grid),
        )?;
        let bytes: Vec<u8> = records.iter().flat_map(|x| x.to_le_bytes()).collect();
        write_bytes(&scene_dir.join("lidar").join(format!("{t:03}.bin")), &bytes)?;
    }
    Ok(())
}

/// The rotation part of `m` applied to a direction.
fn rotate(m: &Mat4, d: Vec3) -> Vec3 {
    m.transform_point(d) - m.transform_point(Vec3::ZERO)
}
