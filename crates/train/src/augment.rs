//! Playback augmentation of training windows (`[data.augment]`).
//!
//! The synthetic presets differ in look *and* in ego speed, so a camera head can score well
//! by recognising the scene in each frame on its own and answering that scene's typical
//! motion, never comparing frames (measured on the shipped model: its frame-1 camera is the
//! same for frames (0, 1), (0, 0) and (1, 0)). Playing some windows backwards or frozen
//! gives the same frames the opposite motion or none, which only a comparison explains.

use crate::config::Augment;
use envision4d_data::rng::Rng;
use envision4d_data::HostClip;

/// Stream tag of the augmentation draws, apart from the data-order shuffle's.
const AUGMENT_STREAM: u64 = 0xA0C3_17E5_0000_0001;

/// How one training window is played.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Playback {
    Forward,
    Reversed,
    Held,
}

/// The playback of the `sample`-th training window of a run: a function of (seed, sample)
/// only, so a resumed run replays the same augmentation.
pub fn playback(augment: &Augment, seed: u64, sample: u64) -> Playback {
    if augment.reverse <= 0.0 && augment.hold <= 0.0 {
        return Playback::Forward;
    }
    let u = Rng::derive(seed ^ AUGMENT_STREAM, sample).unit();
    if u < augment.reverse {
        Playback::Reversed
    } else if u < augment.reverse + augment.hold {
        Playback::Held
    } else {
        Playback::Forward
    }
}

/// Applies `playback` to a window: frames, cameras, depth and motion truth stay paired
/// frame by frame, so pose labels (taken relative to the new frame 0), depth and scene flow
/// remain exact.
pub fn apply(clip: &mut HostClip, playback: Playback) {
    match playback {
        Playback::Forward => {}
        Playback::Reversed => {
            clip.frames.reverse();
            clip.cameras.reverse();
            clip.depths.reverse();
            clip.dynamic_masks.reverse();
            clip.motion_truth.reverse();
        }
        Playback::Held => {
            hold_first(&mut clip.frames);
            hold_first(&mut clip.cameras);
            hold_first(&mut clip.depths);
            hold_first(&mut clip.motion_truth);
            // A held window has no moving object.
            for m in clip.dynamic_masks.iter_mut().flatten() {
                m.fill(false);
            }
        }
    }
}

fn hold_first<T: Clone>(items: &mut [T]) {
    if let Some((first, rest)) = items.split_first_mut() {
        for item in rest {
            item.clone_from(first);
        }
    }
}
