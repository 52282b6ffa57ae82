//! The Waymo layout of the official Envision4D loader, `<root>/<split>/<scene:03d>/images/
//! <t>_<cam>.<png|jpg>`, and the optional ground truth of a STORM-preprocessed scene
//! (spec §5). Timesteps are parsed from the name prefix, so STORM's `{t:03d}` names and the
//! official `{t:06d}` names both work.

use super::{read_dir_sorted, ClipEntry, GtSource, Scan};
use crate::clip::{ClipSpec, DepthMap, FrameGt};
use crate::depth_grid::read_lidar_records;
use crate::error::{DataError, Result};
use crate::exr_io::FloatMap;
use crate::frame::is_frame_file;
use crate::geom::{Intrinsics, Mat4};
use crate::npy::read_npy_f32;
use crate::resize::Fit;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Loader settings; the defaults are the official (evaluation) loader's.
#[derive(Debug, Clone, PartialEq)]
pub struct WaymoConfig {
    pub split: String,
    /// Frames between clip starts (15 at 10 Hz).
    pub interval: usize,
    /// Windows per scene at most (`usize::MAX`: every window that fits).
    pub clips_per_scene: usize,
    /// Waymo camera index in the file name (0 = FRONT).
    pub camera: u32,
    /// Whether windows may overlap (training's sliding windows). The release's clips do
    /// not: there a window longer than `interval` is refused.
    pub overlapping: bool,
    /// Whether LiDAR depth is read (`depth_flows_4/`, `lidar/*.bin`: evaluation). Training
    /// leaves it out: a Waymo sweep is ~6 MB per frame and no training loss uses LiDAR.
    pub lidar: bool,
}

impl Default for WaymoConfig {
    fn default() -> Self {
        WaymoConfig {
            split: "validation".into(),
            interval: 15,
            clips_per_scene: 10,
            camera: 0,
            overlapping: false,
            lidar: true,
        }
    }
}

impl WaymoConfig {
    /// Training windows: every `stride`-th window of every scene of `split`, up to
    /// `max_per_scene` of them (`None`: all).
    pub fn training(split: &str, stride: usize, max_per_scene: Option<usize>) -> WaymoConfig {
        WaymoConfig {
            split: split.into(),
            interval: stride,
            clips_per_scene: max_per_scene.unwrap_or(usize::MAX),
            camera: 0,
            overlapping: true,
            lidar: false,
        }
    }
}

/// STORM's `OPENCV2DATASET`: OpenCV camera axes -> Waymo camera axes (x fwd, y left, z up).
pub const OPENCV_TO_WAYMO_CAMERA: Mat4 = Mat4([
    [0.0, 0.0, 1.0, 0.0],
    [-1.0, 0.0, 0.0, 0.0],
    [0.0, -1.0, 0.0, 0.0],
    [0.0, 0.0, 0.0, 1.0],
]);

/// Rotation matrices read from files may carry float noise; beyond this they are rejected.
const RIGID_TOLERANCE: f64 = 1e-3;

pub fn scan(root: &Path, spec: &ClipSpec, cfg: &WaymoConfig) -> Result<Scan> {
    if cfg.interval == 0 {
        return Err(DataError::config("interval", 0, "must be at least 1"));
    }
    // The official clip is `interval` frames long; a longer clip would read into the next.
    if !cfg.overlapping && spec.span() > cfg.interval {
        return Err(DataError::config(
            "num_frames",
            spec.span(),
            format!(
                "source frames a window spans (frames {}, frame_step {}) must not exceed the clip interval {}",
                spec.num_frames(),
                spec.frame_step,
                cfg.interval
            ),
        ));
    }
    let split_dir = root.join(&cfg.split);
    let mut scan = Scan::default();
    let scenes = read_dir_sorted(&split_dir)?;
    for scene_dir in scenes.into_iter().filter(|p| p.is_dir()) {
        let name = scene_dir
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        if name.parse::<u32>().is_err() {
            scan.skipped.push(format!(
                "{}: scene folder name is not a number; ignored",
                scene_dir.display()
            ));
            continue;
        }
        match scene_clips(&scene_dir, &name, spec, cfg) {
            Ok(entries) => scan.entries.extend(entries),
            Err(e) => scan.skipped.push(e.to_string()),
        }
    }
    if scan.entries.is_empty() && scan.skipped.is_empty() {
        return Err(DataError::EmptyFolder { path: split_dir });
    }
    Ok(scan)
}

fn scene_clips(
    scene_dir: &Path,
    name: &str,
    spec: &ClipSpec,
    cfg: &WaymoConfig,
) -> Result<Vec<ClipEntry>> {
    let images = scene_dir.join("images");
    let mut by_t: BTreeMap<i64, PathBuf> = BTreeMap::new();
    for p in read_dir_sorted(&images)? {
        if !is_frame_file(&p) {
            continue;
        }
        let Some((t, cam)) = parse_frame_name(&p) else {
            continue;
        };
        if cam == cfg.camera {
            by_t.entry(t).or_insert(p);
        }
    }
    let (Some(&t_min), Some(&t_max)) = (by_t.keys().next(), by_t.keys().next_back()) else {
        return Err(DataError::EmptyFolder { path: images });
    };
    // The official loader lists range(min, max): the last timestep is excluded. A gap in
    // the range becomes a path that does not exist, so that clip fails at load time.
    // Only the span the clips can reach is materialised: a stray file with a huge timestamp
    // must not make this list (and memory) explode.
    let reach = cfg
        .clips_per_scene
        .saturating_sub(1)
        .saturating_mul(cfg.interval)
        .saturating_add(spec.span())
        .min(i64::MAX as usize) as i64;
    let timesteps: Vec<i64> = (t_min..t_max.min(t_min.saturating_add(reach))).collect();
    let path_of = |t: i64| {
        by_t.get(&t)
            .cloned()
            .unwrap_or_else(|| images.join(format!("{t:06}_{}.png", cfg.camera)))
    };
    let has_gt = [
        "intrinsics",
        "cam_to_world",
        "ego_to_world",
        "depth_flows_4",
        "lidar",
    ]
    .iter()
    .any(|d| scene_dir.join(d).is_dir());
    let mut out = Vec::new();
    for k in 0..cfg.clips_per_scene {
        let start = k.saturating_mul(cfg.interval);
        if start.saturating_add(spec.span()) > timesteps.len() {
            break;
        }
        let ts: Vec<i64> = spec.frames_from(start).map(|i| timesteps[i]).collect();
        out.push(ClipEntry {
            id: format!("{}/{name}#{k}", cfg.split),
            group: format!("{}/{name}", cfg.split),
            frames: ts.iter().map(|&t| path_of(t)).collect(),
            frame_numbers: ts.clone(),
            gt: if has_gt {
                GtSource::Storm {
                    scene_dir: scene_dir.to_path_buf(),
                    camera: cfg.camera,
                    timesteps: ts,
                    lidar: cfg.lidar,
                }
            } else {
                GtSource::None
            },
        });
    }
    if out.is_empty() {
        return Err(DataError::TooFewFrames {
            path: images,
            found: timesteps.len(),
            needed: spec.span(),
        });
    }
    Ok(out)
}

/// `000123_0.png` -> (123, 0).
fn parse_frame_name(path: &Path) -> Option<(i64, u32)> {
    let stem = path.file_stem()?.to_str()?;
    let (t, cam) = stem.split_once('_')?;
    Some((t.parse().ok()?, cam.parse().ok()?))
}

/// The file for timestep `t` in `dir`: STORM's `{t:03d}` name, else `{t:06d}`; None if absent.
fn find_t(dir: &Path, t: i64, suffix: &str) -> Option<PathBuf> {
    [format!("{t:03}{suffix}"), format!("{t:06}{suffix}")]
        .into_iter()
        .map(|n| dir.join(n))
        .find(|p| p.is_file())
}

/// Whitespace/comma-separated numbers from a text file.
fn read_numbers(path: &Path) -> Result<Vec<f64>> {
    let text = std::fs::read_to_string(path).map_err(|e| DataError::gt(path, e.to_string()))?;
    text.split(|c: char| c.is_whitespace() || c == ',')
        .filter(|s| !s.is_empty())
        .map(|s| {
            s.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| DataError::gt(path, format!("{s:?} is not a finite number")))
        })
        .collect()
}

fn read_rigid(path: &Path) -> Result<Mat4> {
    let v = read_numbers(path)?;
    if v.len() != 16 {
        return Err(DataError::gt(
            path,
            format!("expected 16 numbers (4x4), found {}", v.len()),
        ));
    }
    let mut m = [[0.0; 4]; 4];
    for (i, x) in v.iter().enumerate() {
        m[i / 4][i % 4] = *x;
    }
    let m = Mat4(m);
    if m.rigid_error() > RIGID_TOLERANCE {
        return Err(DataError::gt(
            path,
            "not a rigid transform (rotation not orthonormal)",
        ));
    }
    Ok(m)
}

/// Reads the optional STORM ground truth of each timestep. A missing file means "no GT of
/// that kind"; a present but unreadable one is an error naming it.
pub fn load_storm_gt(
    scene: &Path,
    cam: u32,
    timesteps: &[i64],
    read_lidar: bool,
    source_size: (usize, usize),
    fit: &Fit,
) -> Result<Vec<FrameGt>> {
    let k_path = scene.join("intrinsics").join(format!("{cam}.txt"));
    let k_source = if k_path.is_file() {
        let v = read_numbers(&k_path)?;
        if v.len() < 4 || v[0] <= 0.0 || v[1] <= 0.0 {
            return Err(DataError::gt(
                &k_path,
                "need f_u f_v c_u c_v with positive focals",
            ));
        }
        Some(Intrinsics {
            fx: v[0],
            fy: v[1],
            cx: v[2],
            cy: v[3],
        })
    } else {
        None
    };
    let c2e_path = scene.join("cam_to_ego").join(format!("{cam}.txt"));
    let cam_to_ego = c2e_path
        .is_file()
        .then(|| read_rigid(&c2e_path))
        .transpose()?;
    let mut out = Vec::with_capacity(timesteps.len());
    for &t in timesteps {
        let ego_to_world = find_t(&scene.join("ego_to_world"), t, ".txt")
            .map(|p| read_rigid(&p))
            .transpose()?;
        let cam_to_world_waymo =
            match find_t(&scene.join("cam_to_world"), t, &format!("_{cam}.txt")) {
                Some(p) => Some(read_rigid(&p)?),
                None => ego_to_world.zip(cam_to_ego).map(|(e, c)| e.mul(&c)),
            };
        let world_to_camera =
            cam_to_world_waymo.map(|c2w| c2w.mul(&OPENCV_TO_WAYMO_CAMERA).rigid_inverse());
        let grid = read_lidar
            .then(|| find_t(&scene.join("depth_flows_4"), t, &format!("_{cam}.npy")))
            .flatten();
        let depth = match (grid, k_source) {
            (Some(p), Some(k)) => Some(read_lidar_depth(&p, &k, source_size)?),
            (Some(p), None) => {
                return Err(DataError::gt(p, "LiDAR depth without intrinsics/<cam>.txt"))
            }
            _ => None,
        };
        let bin = read_lidar
            .then(|| find_t(&scene.join("lidar"), t, ".bin"))
            .flatten();
        let lidar_points = match (bin, cam_to_ego) {
            (Some(p), Some(c2e)) => Some(read_lidar_points(&p, &c2e)?),
            (Some(p), None) => {
                return Err(DataError::gt(
                    p,
                    format!(
                        "LiDAR points without cam_to_ego/{cam}.txt to bring them into the camera"
                    ),
                ))
            }
            _ => None,
        };
        out.push(FrameGt {
            intrinsics: k_source.map(|k| fit.intrinsics(&k, source_size)),
            world_to_camera,
            ego_to_world,
            depth,
            lidar_points,
            flow: None,
            dynamic_mask: None,
            instance: None,
            objects: None,
        });
    }
    Ok(out)
}

/// Columns of one STORM LiDAR record: origin xyz, point xyz, flow xyz, flow class.
pub const LIDAR_COLUMNS: usize = 10;
/// First column of the point itself within a record.
const LIDAR_POINT: usize = 3;

/// `lidar/<t>.bin` (points in the vehicle frame of that timestep) in the OpenCV camera frame.
fn read_lidar_points(path: &Path, cam_to_ego: &Mat4) -> Result<Vec<[f32; 3]>> {
    // Vehicle -> Waymo camera axes -> OpenCV camera axes.
    let ego_to_cv = OPENCV_TO_WAYMO_CAMERA
        .rigid_inverse()
        .mul(&cam_to_ego.rigid_inverse());
    read_lidar_records(path, LIDAR_COLUMNS, LIDAR_POINT, &ego_to_cv)
}

/// Channel 0 of `depth_flows_4/*.npy` (H/4, W/4, 4): mean LiDAR z-depth, 0 = no return.
fn read_lidar_depth(path: &Path, k: &Intrinsics, source_size: (usize, usize)) -> Result<DepthMap> {
    let arr = read_npy_f32(path)?;
    let [h, w, c] = arr.shape[..] else {
        return Err(DataError::gt(
            path,
            format!("shape {:?} is not (H, W, C)", arr.shape),
        ));
    };
    if c == 0 || h == 0 || w == 0 {
        return Err(DataError::gt(path, format!("empty shape {:?}", arr.shape)));
    }
    let data = arr.data.chunks_exact(c).map(|px| px[0]).collect();
    Ok(DepthMap {
        map: FloatMap {
            width: w,
            height: h,
            channels: 1,
            data,
        },
        intrinsics: k.resized(source_size, (h, w)),
        sparse: true,
    })
}
