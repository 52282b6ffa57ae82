//! From a training config to clips: open the dataset its `[data]` table names and split it
//! deterministically (the decoding itself is the data crate's).

use crate::config::{DataConfig, DataLayout};
use crate::error::{Result, TrainError};
use envision4d_data::{
    ClipDataset, ClipSpec, DatasetConfig, Fit, FitMode, Layout, Split, SplitRatios, WaymoConfig,
};
use envision4d_model::ModelConfig;
use std::path::Path;

/// Opens the dataset of `data` at `root` (the config's root unless overridden), fitting
/// frames to the model's image size and cutting clips of `T_c + T_f` frames.
pub fn open_dataset(data: &DataConfig, model: &ModelConfig, root: &Path) -> Result<ClipDataset> {
    let layout = match data.layout {
        DataLayout::Synth => Layout::Synth {
            stride: data.stride,
        },
        DataLayout::Folder => Layout::Folder {
            stride: data.stride,
        },
        DataLayout::Waymo => Layout::Waymo(WaymoConfig::default()),
    };
    let config = DatasetConfig {
        layout,
        spec: ClipSpec {
            context: model.context_frames,
            future: model.future_frames,
        },
        fit: Fit {
            mode: FitMode::Resize,
            height: model.image_size[0],
            width: model.image_size[1],
        },
        cache_clips: 64,
    };
    ClipDataset::open(root, config)
        .map_err(|e| TrainError::data(format!("data.root {}", root.display()), e))
}

/// Indices of `split` (seeded, by scene group); when the dataset is too small to have a
/// validation clip, validation is empty rather than stealing the only training clips.
pub fn split(dataset: &ClipDataset, which: Split, seed: u64) -> Vec<usize> {
    dataset.split_indices(which, seed, &SplitRatios::default())
}
