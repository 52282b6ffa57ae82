//! The synthetic driving world: procedural scenes rendered by our own CPU ray tracer, with
//! exact ground truth (cameras, z-depth, scene flow, dynamic mask, object tracks).
//!
//! It shares no code with `envision4d-splat`: it is the judge of that rasterizer.

pub mod camera;
pub mod footprint;
pub mod motion;
pub mod nuscenes_writer;
pub mod preset;
pub mod preset_kind;
pub mod road;
pub mod shapes;
pub mod storm_writer;
pub mod suite;
pub mod texture;
pub mod trace;
pub mod world;
pub mod writer;

use crate::error::{DataError, Result};
use crate::layout::synth::{CameraRecord, Track, TrackState};
use crate::rng::Rng;
use camera::Camera;
pub use nuscenes_writer::write_nuscenes_scenes;
pub use preset::{Preset, FRAME_INTERVAL_S};
pub use storm_writer::write_storm_scene;
use trace::{render, FrameRender, Scene};
pub use writer::write_clip;

/// Default colour samples per pixel edge (2 x 2 = 4 per pixel): enough to tame edge
/// aliasing of windows and markings, and keeps 100 clips x 8 frames at 350x518 in minutes.
pub const DEFAULT_SUPERSAMPLE: usize = 2;
/// A track counts as moving at frame t when its box moves more than this by t+1 (metres).
pub const MOVING_EPS_M: f64 = 1e-4;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SynthConfig {
    pub width: usize,
    pub height: usize,
    pub frames: usize,
    pub preset: Preset,
    pub seed: u64,
    /// Colour samples per pixel edge.
    pub supersample: usize,
}

impl SynthConfig {
    pub fn validate(&self) -> Result<()> {
        if self.width == 0 || self.height == 0 {
            return Err(DataError::config(
                "size",
                format!("{}x{}", self.height, self.width),
                "must be positive",
            ));
        }
        if self.frames == 0 {
            return Err(DataError::config("frames", 0, "need at least one frame"));
        }
        if !(1..=8).contains(&self.supersample) {
            return Err(DataError::config(
                "supersample",
                self.supersample,
                "must be 1..=8",
            ));
        }
        Ok(())
    }
}

/// A rendered clip in memory.
pub struct ClipRender {
    pub config: SynthConfig,
    pub clip_index: u64,
    pub frames: Vec<FrameRender>,
    pub cameras: Vec<CameraRecord>,
    pub tracks: Vec<Track>,
}

/// Renders clip `clip_index` (its world comes from the RNG stream (seed, clip_index)).
/// `on_frame` is called after each frame (for progress bars).
pub fn render_clip(
    cfg: &SynthConfig,
    clip_index: u64,
    mut on_frame: impl FnMut(),
) -> Result<ClipRender> {
    cfg.validate()?;
    let mut rng = Rng::derive(cfg.seed, clip_index);
    let world = preset::build_world(cfg.preset, &mut rng, cfg.frames);
    let mut frames = Vec::with_capacity(cfg.frames);
    let mut cameras = Vec::with_capacity(cfg.frames);
    let mut tracks: Vec<Track> = world
        .objects
        .iter()
        .filter(|o| o.track_id > 0)
        .map(|o| Track {
            id: o.track_id,
            kind: o.kind.name().to_owned(),
            size: o.size,
            motion: o.label.to_owned(),
            states: Vec::with_capacity(cfg.frames),
        })
        .collect();
    for t in 0..cfg.frames {
        let time = t as f64 * world.dt;
        let cam = Camera::at(&world, time, cfg.width, cfg.height);
        let scene = Scene::at(&world, time);
        frames.push(render(&scene, &cam, cfg.width, cfg.height, cfg.supersample));
        cameras.push(CameraRecord {
            t,
            time_s: time,
            intrinsics: cam.intrinsics,
            world_to_camera: cam.world_to_camera(),
        });
        for (i, obj) in world
            .objects
            .iter()
            .enumerate()
            .filter(|(_, o)| o.track_id > 0)
        {
            let Some((now, next)) = scene.pose_of(i) else {
                continue;
            };
            let lift = crate::geom::Vec3::new(0.0, 0.0, obj.size[2] / 2.0);
            let (c0, c1) = (now.position + lift, next.position + lift);
            let v = (c1 - c0) * (1.0 / world.dt);
            let turn = road::wrap_angle(next.yaw - now.yaw).abs();
            let state = TrackState {
                t,
                position: c0.to_array(),
                yaw: now.yaw,
                velocity: v.to_array(),
                moving: (c1 - c0).norm() > MOVING_EPS_M || turn > MOVING_EPS_M,
            };
            if let Some(track) = tracks.iter_mut().find(|tr| tr.id == obj.track_id) {
                track.states.push(state);
            }
        }
        on_frame();
    }
    Ok(ClipRender {
        config: *cfg,
        clip_index,
        frames,
        cameras,
        tracks,
    })
}
