//! Where a run's weights come from and which of them train: the frozen parameter groups,
//! the modules kept fresh, and the initialisation (§4 implementation details).

use serde::{Deserialize, Serialize};

/// Parameter groups that can be frozen (names follow the official `state_dict`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FreezeGroup {
    PatchEmbed,
    FrameBlocks,
    GlobalBlocks,
    /// `camera_token` and `register_token`.
    Tokens,
    CameraHead,
    TimeBlocks,
    /// `extra_token_offset`, `extra_blocks`, `time_embedding`.
    FuturePose,
    DepthHead,
    GsHead,
    MotionHead,
}

impl FreezeGroup {
    /// The paper's frozen set (§4; `docs/MODEL.md`); the depth head stays trainable.
    pub const PAPER: [FreezeGroup; 5] = [
        FreezeGroup::PatchEmbed,
        FreezeGroup::FrameBlocks,
        FreezeGroup::GlobalBlocks,
        FreezeGroup::Tokens,
        FreezeGroup::CameraHead,
    ];
}

/// Modules that keep their fresh initialisation although `init_checkpoint` has them: the
/// motion benchmark retrains every motion variant's motion from scratch on one trained
/// reconstruction, so none starts with the paper variant's trained motion.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FreshGroup {
    /// `motion_head`: the DPT head of the displacements.
    MotionHead,
    /// `time_blocks`: the temporal attention blocks.
    TimeBlocks,
}

pub(super) fn paper_freeze() -> Vec<FreezeGroup> {
    FreezeGroup::PAPER.to_vec()
}

/// Where a run's initial weights come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Init {
    /// `init_checkpoint`; without one, the fresh initialisation, which is allowed at small
    /// widths only (a paper-width model from random weights is almost surely a missing
    /// path, not a plan).
    #[default]
    Checkpoint,
    /// Random weights on purpose (benchmarks and memory measurements of paper-size steps):
    /// no `init_checkpoint`, and a backbone teacher or LPIPS network without weights gets
    /// random ones as well, each named in the run's output.
    Random,
}

impl Init {
    pub(super) fn is_checkpoint(&self) -> bool {
        *self == Init::Checkpoint
    }
}
