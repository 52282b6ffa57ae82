//! The protocol's motion step: the scene's Gaussian means and displacements read back to the
//! host and scored against the clip's exact scene flow (`motion`, `motion_maps`).

use crate::motion::{score_aligned, Aligned, MotionScore, MotionTruth, PredictedMotion};
use crate::motion_maps::{pair_maps, PairMaps};
use crate::EvalOptions;
use envision4d_data::geom::Mat4;
use envision4d_data::HostClip;
use envision4d_model::scene::Scene;

/// The predicted displacements against the clip's exact scene flow (`motion`), and the
/// per-pixel maps when asked for; `None` when the clip has no motion truth (nothing is read
/// back then).
pub(crate) fn motion_truth_score(
    scene: &Scene,
    clip: &HostClip,
    tc: usize,
    n: usize,
    input: [usize; 2],
    pred_poses: &[Mat4],
    opts: &EvalOptions,
) -> (Option<MotionScore>, Option<PairMaps>) {
    if clip.motion_truth.len() < n {
        return (None, None);
    }
    let a = &scene.adapted;
    let [_, _, g, _] = a.means.dims();
    let [_, _, k, _, _] = a.motions.dims();
    let means: Vec<f32> = a
        .means
        .clone()
        .slice([0..1, 0..tc, 0..g, 0..3])
        .into_data()
        .iter::<f32>()
        .collect();
    let motions: Vec<f32> = a
        .motions
        .clone()
        .slice([0..1, 0..tc, 0..k, 0..g, 0..3])
        .into_data()
        .iter::<f32>()
        .collect();
    let pred = PredictedMotion {
        context: tc,
        frames: n,
        grid: (input[0], input[1]),
        means: &means,
        motions: &motions,
        extrinsics: pred_poses,
    };
    let truth = MotionTruth {
        size: (clip.height, clip.width),
        frames: &clip.motion_truth,
        masks: &clip.dynamic_masks,
    };
    // One alignment (scale, axes, grid) serves the score and the maps.
    let Some(aligned) = Aligned::new(&pred, &truth) else {
        return (None, None);
    };
    let maps = opts.motion_maps.then(|| pair_maps(&aligned));
    (Some(score_aligned(&aligned, truth.masks)), maps)
}
