//! Predicted cameras on the host: `poses.json`, one camera JSON per rendered view (the format
//! `envision4d splat --camera` reads), and the lane-shifted cameras.

use super::host;
use super::outputs::{lane_suffix, FileKind, OutDir, Plan, Role};
use anyhow::{Context, Result};
use envision4d_model::model::Predictions;
use envision4d_splat::camera_json::CameraJson;
use serde::Serialize;

// The 9-d pose encoding's width, from its one definition in the model crate.
use envision4d_model::pose::POSE_ENCODING_DIM as POSE_ENC_DIM;
/// Sub-folder of the camera JSONs.
pub const CAMERAS_DIR: &str = "cameras";
const POSES_FILE: &str = "poses.json";

/// Every predicted camera of batch element 0, in f64.
#[derive(Debug, Clone)]
pub struct HostCameras {
    /// World-to-camera (OpenCV axes; world = context frame 0's camera).
    pub viewmats: Vec<[[f64; 4]; 4]>,
    /// Pixel intrinsics at the model image size.
    pub ks: Vec<[[f64; 3]; 3]>,
    pub pose_enc: Vec<[f64; POSE_ENC_DIM]>,
}

impl HostCameras {
    /// Reads `pred.backbone` (extrinsics/intrinsics as rebuilt from the clamped encoding).
    pub fn from_predictions(pred: &Predictions) -> Result<HostCameras> {
        let bb = &pred.backbone;
        let n = bb.extrinsics.dims()[1];
        let e = host(bb.extrinsics.clone())?;
        let k = host(bb.intrinsics.clone())?;
        let p = host(bb.pose_enc())?;
        Ok(HostCameras {
            viewmats: (0..n)
                .map(|v| {
                    std::array::from_fn(|r| std::array::from_fn(|c| e[v * 16 + r * 4 + c] as f64))
                })
                .collect(),
            ks: (0..n)
                .map(|v| {
                    std::array::from_fn(|r| std::array::from_fn(|c| k[v * 9 + r * 3 + c] as f64))
                })
                .collect(),
            pose_enc: (0..n)
                .map(|v| std::array::from_fn(|i| p[v * POSE_ENC_DIM + i] as f64))
                .collect(),
        })
    }
}

/// `viewmat` of a camera moved by `shift` along its own x axis (OpenCV: right). A camera
/// point is `R p + t`; moving the centre by `shift · x_cam` subtracts `shift` from `t_x`.
pub fn lane_shifted(viewmat: &[[f64; 4]; 4], shift: f64) -> [[f64; 4]; 4] {
    let mut m = *viewmat;
    m[0][3] -= shift;
    m
}

/// The camera JSON of a view at the model image size `[h, w]`.
pub fn camera_json(viewmat: &[[f64; 4]; 4], k: &[[f64; 3]; 3], size: [usize; 2]) -> CameraJson {
    CameraJson {
        width: size[1] as u32,
        height: size[0] as u32,
        fx: k[0][0],
        fy: k[1][1],
        cx: k[0][2],
        cy: k[1][2],
        world_to_camera: *viewmat,
    }
}

/// Writes `cameras/<step>.json` (and `cameras/<step>_lane±S.json` for future steps).
pub fn write_cameras(cams: &HostCameras, plan: &Plan, out: &mut OutDir) -> Result<()> {
    for step in plan.steps() {
        let base = cams.viewmats[step.index];
        let k = &cams.ks[step.index];
        let mut views = vec![(step.name.clone(), base)];
        if step.role == Role::Future {
            for &s in &plan.lane_shifts {
                views.push((
                    format!("{}_{}", step.name, lane_suffix(s)),
                    lane_shifted(&base, s),
                ));
            }
        }
        for (name, vm) in views {
            let path = out.path(CAMERAS_DIR, &format!("{name}.json"))?;
            let json = serde_json::to_string_pretty(&camera_json(&vm, k, plan.image_size))?;
            write_text(&path, &json)?;
            out.record(&path, FileKind::Camera, Some(&step));
        }
    }
    Ok(())
}

#[derive(Serialize)]
struct PoseRecord {
    index: usize,
    role: Role,
    /// Whether this run rendered the timestamp (future frames beyond --future are not).
    rendered: bool,
    world_to_camera: [[f64; 4]; 4],
    intrinsics: [[f64; 3]; 3],
    pose_enc: [f64; POSE_ENC_DIM],
}

/// Writes `poses.json`: every predicted timestamp (context and future).
pub fn write_poses(cams: &HostCameras, plan: &Plan, out: &mut OutDir) -> Result<()> {
    let rendered = plan.context + plan.future;
    let frames: Vec<PoseRecord> = (0..cams.viewmats.len())
        .map(|i| PoseRecord {
            index: i,
            role: plan.step(i).role,
            rendered: i < rendered,
            world_to_camera: cams.viewmats[i],
            intrinsics: cams.ks[i],
            pose_enc: cams.pose_enc[i],
        })
        .collect();
    let json = serde_json::json!({
        "convention": "world_to_camera: OpenCV axes (x right, y down, z forward), world = \
                       context frame 0's camera; intrinsics in pixels of image_size [h, w]; \
                       pose_enc = [t(3), quaternion xyzw(4), fov_h, fov_w]",
        "image_size": plan.image_size,
        "frames": frames,
    });
    let path = out.path("", POSES_FILE)?;
    write_text(&path, &serde_json::to_string_pretty(&json)?)?;
    out.record(&path, FileKind::Poses, None);
    Ok(())
}

fn write_text(path: &std::path::Path, text: &str) -> Result<()> {
    envision4d_data::atomic::write_bytes(path, text.as_bytes())
        .with_context(|| format!("writing {}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Guards the lane-shift direction: a positive shift moves the camera centre to its right
    /// (+x of its own axes), whatever its rotation.
    #[test]
    fn lane_shift_moves_centre_along_camera_x() {
        // Camera yawed 90° about y: its x axis is world -z.
        let vm = [
            [0.0, 0.0, -1.0, 1.0],
            [0.0, 1.0, 0.0, 2.0],
            [1.0, 0.0, 0.0, 3.0],
            [0.0, 0.0, 0.0, 1.0],
        ];
        let centre = |m: &[[f64; 4]; 4]| -> [f64; 3] {
            // c = -Rᵀ t
            std::array::from_fn(|i| -(0..3).map(|k| m[k][i] * m[k][3]).sum::<f64>())
        };
        let (c0, c1) = (centre(&vm), centre(&lane_shifted(&vm, 1.5)));
        let moved: Vec<f64> = (0..3).map(|i| c1[i] - c0[i]).collect();
        assert_eq!(moved, vec![0.0, 0.0, -1.5]);
    }
}
