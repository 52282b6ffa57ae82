//! From a training config to clips: open the dataset its `[data]` table names and split it
//! deterministically (the decoding itself is the data crate's).

use crate::config::{DataConfig, DataLayout, Purpose};
use crate::error::{Result, TrainError};
use envision4d_data::{
    ClipDataset, ClipSpec, DatasetConfig, Fit, FitMode, Layout, NuScenesConfig, Split, SplitRatios,
    WaymoConfig,
};
use envision4d_model::ModelConfig;
use std::path::Path;

/// Opens the dataset of `data` at `root` (the config's root unless overridden) for
/// `purpose`, fitting frames to the model's image size and cutting clips of `T_c + T_f`
/// frames.
pub fn open_dataset(
    data: &DataConfig,
    model: &ModelConfig,
    root: &Path,
    purpose: Purpose,
) -> Result<ClipDataset> {
    let layout = match data.layout {
        DataLayout::Synth => Layout::Synth {
            stride: data.stride,
        },
        DataLayout::Folder => Layout::Folder {
            stride: data.stride,
        },
        DataLayout::Waymo => Layout::Waymo(waymo_config(data, purpose)),
        DataLayout::Nuscenes => Layout::NuScenes(NuScenesConfig {
            // No training loss uses LiDAR: only evaluation reads the sweeps.
            lidar: purpose == Purpose::Eval,
            ..NuScenesConfig::new(
                &data.split_for(purpose),
                data.stride,
                data.windows_per_scene,
            )
        }),
    };
    let config = DatasetConfig {
        layout,
        spec: ClipSpec {
            context: model.context_frames,
            future: model.future_frames,
            frame_step: data.frame_step,
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

/// Refuses to train on an evaluation split (see [`DataConfig::trains_on_eval_split`]),
/// naming the key and the way out. The training entry points call it (`run` before it
/// writes anything, `train --dry-run`), not [`open_dataset`], which evaluation shares.
pub fn check_training_split(data: &DataConfig) -> Result<()> {
    if data.trains_on_eval_split() {
        return Err(TrainError::invalid(
            "data.split",
            format!("{:?}", data.split_for(Purpose::Train)),
            "is an evaluation split: training on it trains on the clips it is scored on \
             (use \"training\", or set data.allow_eval_split = true to do it anyway)",
        ));
    }
    if !data.has_splits() && (data.split.is_some() || data.windows_per_scene.is_some()) {
        return Err(TrainError::invalid(
            if data.split.is_some() {
                "data.split"
            } else {
                "data.windows_per_scene"
            },
            format!("{:?}", data.layout),
            "applies to layout = \"waymo\" or \"nuscenes\" only",
        ));
    }
    Ok(())
}

/// The Waymo reader's settings for `purpose`: training reads every `stride`-th window of
/// the training split; evaluation the release's clips of the validation split.
pub fn waymo_config(data: &DataConfig, purpose: Purpose) -> WaymoConfig {
    let split = data.split_for(purpose);
    match purpose {
        Purpose::Train => WaymoConfig::training(&split, data.stride, data.windows_per_scene),
        Purpose::Eval => {
            let release = WaymoConfig::default();
            WaymoConfig {
                split,
                clips_per_scene: data.windows_per_scene.unwrap_or(release.clips_per_scene),
                ..release
            }
        }
    }
}

/// Indices of `split` (seeded, by scene group); when the dataset is too small to have a
/// validation clip, validation is empty rather than stealing the only training clips.
pub fn split(dataset: &ClipDataset, which: Split, seed: u64) -> Vec<usize> {
    dataset.split_indices(which, seed, &SplitRatios::default())
}
