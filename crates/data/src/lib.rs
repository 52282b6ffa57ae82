//! `envision4d-data`: clip datasets (plain frame folders, the Waymo/STORM layout, our
//! synthetic layout), image decoding and fitting, deterministic splits, prefetch, and a
//! ray-traced synthetic driving world with exact ground truth (`synth`).
//!
//! The crate stands alone: it depends on no other envision4d crate and not on burn. Images
//! are plain `Vec<f32>` (HWC, RGB in [0, 1]); the training crate makes tensors of them.
//! The synthetic world has its own ray tracer because it judges our rasterizer.

pub mod atomic;
pub mod clip;
pub mod dataset;
pub mod depth_grid;
pub mod error;
pub mod exr_io;
pub mod frame;
pub mod geom;
pub mod host_clip;
pub mod layout;
pub mod lock;
pub mod motion_truth;
pub mod npy;
pub mod prefetch;
pub mod resize;
pub mod rng;
pub mod split;
pub mod synth;

pub use clip::{Clip, ClipSpec, DepthMap, FrameGt};
pub use dataset::{ClipDataset, DatasetConfig, Layout};
pub use depth_grid::DepthSource;
pub use error::{DataError, Result};
pub use frame::{decode_image, Image};
pub use geom::{Intrinsics, Mat4, Vec3};
pub use host_clip::{hwc_to_chw, HostClip};
pub use layout::nuscenes::NuScenesConfig;
pub use layout::waymo::WaymoConfig;
pub use layout::ClipEntry;
pub use motion_truth::{FrameMotionTruth, ObjectPose};
pub use prefetch::{Prefetch, Prefetcher};
pub use resize::{Fit, FitMode, MODEL_SIZE};
pub use split::{Split, SplitRatios};
