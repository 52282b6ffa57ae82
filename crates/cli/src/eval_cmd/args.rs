//! `eval`'s argument types: layouts, named protocols, split and alignment choices, crops.

use clap::ValueEnum;
use envision4d_losses::{DepthAlignment, EvalCrop};
use envision4d_train::config::DataLayout;

/// `--layout`: the dataset layouts `eval` reads (docs/DATA.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum LayoutChoice {
    Synth,
    Folder,
    Waymo,
    Nuscenes,
}

impl LayoutChoice {
    pub fn layout(self) -> DataLayout {
        match self {
            LayoutChoice::Synth => DataLayout::Synth,
            LayoutChoice::Folder => DataLayout::Folder,
            LayoutChoice::Waymo => DataLayout::Waymo,
            LayoutChoice::Nuscenes => DataLayout::Nuscenes,
        }
    }
}

/// A named evaluation protocol.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Protocol {
    /// The official release: 2 context frames, the next 4 scored (`images[2:]` of 6).
    Release,
    /// The paper, §4.1: T_c = T_f = 2.
    Paper,
}

impl Protocol {
    pub const CONTEXT_FRAMES: usize = 2;

    pub fn future_frames(self) -> usize {
        match self {
            Protocol::Release => 4,
            Protocol::Paper => 2,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Protocol::Release => "release",
            Protocol::Paper => "paper",
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum SplitChoice {
    Auto,
    All,
    HeldOut,
    Val,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum AlignChoice {
    None,
    Median,
    LeastSquares,
}

impl AlignChoice {
    pub fn alignment(self) -> DepthAlignment {
        match self {
            AlignChoice::None => DepthAlignment::None,
            AlignChoice::Median => DepthAlignment::Median,
            AlignChoice::LeastSquares => DepthAlignment::LeastSquares,
        }
    }
}

pub fn parse_crop(s: &str) -> Result<EvalCrop, String> {
    let v: Vec<usize> = s
        .split(',')
        .map(|p| p.trim().parse::<usize>())
        .collect::<Result<_, _>>()
        .map_err(|e| format!("{s:?}: {e}; expected TOP,BOTTOM,LEFT,RIGHT"))?;
    match v[..] {
        [top, bottom, left, right] => Ok(EvalCrop {
            top,
            bottom,
            left,
            right,
        }),
        _ => Err(format!("{s:?}: expected 4 numbers TOP,BOTTOM,LEFT,RIGHT")),
    }
}
