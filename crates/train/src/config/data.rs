//! `[data]`: which dataset a run reads, its splits, clip windows and playback augmentation
//! (`docs/DATA.md`).

use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// How the files under `root` are laid out (`docs/DATA.md`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DataLayout {
    Synth,
    Folder,
    Waymo,
    /// The official nuScenes tree (`samples/`, `v1.0-*/` tables, official scene splits).
    Nuscenes,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DataConfig {
    pub layout: DataLayout,
    pub root: PathBuf,
    /// Frames between consecutive clip windows.
    #[serde(default = "one")]
    pub stride: usize,
    /// Source frames between a window's frames: 1 (the default) consecutive, 2 every other
    /// frame (motion between the model's frames twice as large; the time embedding still
    /// counts window frames).
    #[serde(default = "one", skip_serializing_if = "is_one")]
    pub frame_step: usize,
    /// Playback augmentation of training windows (`[data.augment]`); off by default.
    #[serde(default)]
    pub augment: Augment,
    /// `layout = "waymo"`: the split folder read. Training defaults to `training` (every
    /// `stride`-th window of every scene); evaluation to `validation` with the release's
    /// clips (10 per scene, starts 0, 15, …). `layout = "nuscenes"`: an official split,
    /// `train` / `val` (v1.0-trainval), `mini_train` / `mini_val` (v1.0-mini) or `test`;
    /// training defaults to `train`, evaluation to `val`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub split: Option<String>,
    /// Training refuses a split named like an evaluation split (validation, test) unless
    /// this is set: a run on it would train on the clips it is scored on.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub allow_eval_split: bool,
    /// `layout = "waymo"` / `"nuscenes"`: windows per scene at most (training: all;
    /// evaluation: the release's 10 on Waymo, all on nuScenes).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub windows_per_scene: Option<usize>,
}

/// Split names that hold evaluation data (case-insensitive).
pub const EVAL_SPLITS: [&str; 5] = ["validation", "val", "test", "testing", "mini_val"];

/// What a dataset is opened for: the Waymo layout reads different splits and windows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Purpose {
    Train,
    Eval,
}

impl DataConfig {
    /// A config with only a layout and a root (every other key at its default).
    pub fn new(layout: DataLayout, root: PathBuf, stride: usize) -> DataConfig {
        DataConfig {
            layout,
            root,
            stride,
            frame_step: 1,
            augment: Augment::default(),
            split: None,
            allow_eval_split: false,
            windows_per_scene: None,
        }
    }

    /// The split `purpose` reads (Waymo, nuScenes), with the defaults above.
    pub fn split_for(&self, purpose: Purpose) -> String {
        let nuscenes = self.layout == DataLayout::Nuscenes;
        self.split.clone().unwrap_or_else(|| {
            match (purpose, nuscenes) {
                (Purpose::Train, false) => "training",
                (Purpose::Eval, false) => "validation",
                (Purpose::Train, true) => "train",
                (Purpose::Eval, true) => "val",
            }
            .into()
        })
    }

    /// Whether the layout has named splits (`data.split`, `data.windows_per_scene`).
    pub fn has_splits(&self) -> bool {
        matches!(self.layout, DataLayout::Waymo | DataLayout::Nuscenes)
    }

    /// Whether training would read an evaluation split (see [`EVAL_SPLITS`]).
    pub fn trains_on_eval_split(&self) -> bool {
        self.has_splits()
            && !self.allow_eval_split
            && EVAL_SPLITS.contains(&self.split_for(Purpose::Train).to_lowercase().as_str())
    }
}

/// How often a training window is played other than forwards. Both take away the shortcut
/// of reading a camera's motion off one frame's appearance (scene type → typical speed):
/// the same frames then come with the opposite motion, or with none.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Augment {
    /// Fraction of windows played backwards: frames, cameras and depth reversed together.
    pub reverse: f64,
    /// Fraction of windows frozen on their first frame: every frame, camera and depth map is
    /// frame 0's (the ego stands still and so does the world).
    pub hold: f64,
}

fn one() -> usize {
    1
}

fn is_one(v: &usize) -> bool {
    *v == 1
}
