//! From a training config to clips: open the dataset its `[data]` table names, split it
//! deterministically, and turn decoded clips into [`HostClip`]s (CHW, ground truth kept).

use crate::batch::HostClip;
use crate::config::{DataConfig, DataLayout};
use crate::error::{Result, TrainError};
use envision4d_data::{
    Clip, ClipDataset, ClipSpec, DatasetConfig, Fit, FitMode, Layout, Split, SplitRatios,
    WaymoConfig,
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
        .map_err(|e| TrainError::Batch(format!("data.root {}: {e}", root.display())))
}

/// Indices of `split` (seeded, by scene group); when the dataset is too small to have a
/// validation clip, validation is empty rather than stealing the only training clips.
pub fn split(dataset: &ClipDataset, which: Split, seed: u64) -> Vec<usize> {
    dataset.split_indices(which, seed, &SplitRatios::default())
}

/// Interleaved RGB (HWC) to planar (CHW).
pub fn hwc_to_chw(hwc: &[f32], h: usize, w: usize) -> Vec<f32> {
    let mut chw = vec![0.0; 3 * h * w];
    for p in 0..h * w {
        for c in 0..3 {
            chw[c * h * w + p] = hwc[p * 3 + c];
        }
    }
    chw
}

impl HostClip {
    /// CHW frames and, when the layout has them, cameras and depth (depth must be on the
    /// frame grid: the synthetic layout writes it there).
    pub fn from_clip(clip: &Clip) -> Result<HostClip> {
        let first = clip
            .frames
            .first()
            .ok_or_else(|| TrainError::Batch(format!("clip {} has no frames", clip.id)))?;
        let (h, w) = (first.height, first.width);
        let frames = clip
            .frames
            .iter()
            .map(|f| hwc_to_chw(&f.data, h, w))
            .collect();
        let cameras = clip
            .gt
            .iter()
            .map_while(|g| Some((g.world_to_camera?, g.intrinsics?)))
            .collect::<Vec<_>>();
        let depths = clip
            .gt
            .iter()
            .map_while(|g| {
                let d = g.depth.as_ref()?;
                (d.map.height == h && d.map.width == w).then(|| d.map.data.clone())
            })
            .collect::<Vec<_>>();
        Ok(HostClip {
            height: h,
            width: w,
            frames,
            cameras,
            depths,
        })
    }
}
