//! `envision4d-model`: the Envision4D network on Burn.
//!
//! VGGT backbone (DINOv2 patch embed, alternating frame/global attention with 2D RoPE) with
//! in-layer temporal attention, the future-pose module, the camera head, DPT heads for depth,
//! Gaussians and motion (on conditioned-motion-lifting tokens), and the Gaussian adapter.
//! Parameter names follow the official `state_dict`, so checkpoints load by name.
//! [`scene`] is the one path from context frames to rendered views (through
//! `envision4d-splat`) that training, evaluation and rendering share.

pub mod config;
pub mod layers;

pub use config::{ConfigError, ModelConfig};
pub use model::Envision4d;
pub use scene::{predict_scene, Scene, SceneError};
pub mod adapter;
pub mod aggregator;
pub mod alloc;
pub mod bench;
pub mod camera_head;
pub mod checkpoint;
pub mod dino;
pub mod dpt;
pub mod future;
pub mod host_read;
pub mod model;
pub mod motion;
pub mod pose;
pub mod precision;
pub mod resample;
pub mod scene;
pub mod seeded;
pub mod vggt;
pub mod weights;
