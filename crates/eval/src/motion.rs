//! The predicted motion against exact truth (synthetic data; `envision4d_data::motion_truth`):
//! 3D scene-flow end-point error of every context pixel's Gaussian displacement per
//! (source, target) pair, on moving and on static pixels apart, and the IoU of the dynamic
//! mask that thresholded motion gives (the paper's Fig. 5, as a number).
//!
//! A pose-free model predicts in its own frame: the world is context frame 0's camera, up to
//! scale. Both sides are therefore expressed in their own frame-0 camera axes, and the
//! prediction is brought to metres by one scale per clip, the median of true over predicted
//! z-depth of the context Gaussians (the depth the Gaussians were placed with, so a scale
//! error of the depth head is not counted as motion error).

use crate::report::mean_opt;
use envision4d_data::geom::Mat4;
use envision4d_data::synth::MOVING_EPS_M;
use envision4d_data::{FrameMotionTruth, Vec3};
use envision4d_model::motion::target_slot;
use glam::{DMat3, DVec3};
use serde::{Deserialize, Serialize};

/// A pixel whose predicted displacement to the next frame exceeds this (metres, after the
/// clip's scale) is "moving" for the mask IoU: 0.5 m/s at 10 Hz, below a walking pace, far
/// above the centimetres a static surface's predicted flow wanders.
pub const MASK_THRESHOLD_M: f64 = 0.05;

/// Scene-flow error of one (source, target) pair on the pixels with truth.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FlowPairScore {
    pub source: usize,
    pub target: usize,
    /// Pixels whose true displacement exceeds the generator's 0.1 mm, and the rest.
    pub dynamic_pixels: usize,
    pub static_pixels: usize,
    /// Mean end-point error (metres) on each set; `None` when the set is empty.
    pub epe_dynamic: Option<f64>,
    pub epe_static: Option<f64>,
    /// Mean true displacement of the dynamic pixels: the EPE of predicting no motion.
    pub true_displacement: Option<f64>,
    /// `epe_dynamic / true_displacement`: 1 is no better than predicting no motion.
    pub rel_epe_dynamic: Option<f64>,
}

/// Every motion number of one clip (or their mean over clips).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MotionScore {
    /// Metres per model unit applied to the predicted displacements.
    pub flow_scale: f64,
    /// Means over the pairs whose target is a future frame (the extrapolation the paper
    /// claims), each pair weighted equally.
    pub epe_dynamic: Option<f64>,
    pub epe_static: Option<f64>,
    pub true_displacement: Option<f64>,
    pub rel_epe_dynamic: Option<f64>,
    /// Mean over context frames of the dynamic-mask IoU (predicted displacement to the next
    /// frame above [`MASK_THRESHOLD_M`] against the true mask); frames where both masks are
    /// empty are left out.
    pub mask_iou: Option<f64>,
    pub mask_threshold_m: f64,
    /// Per context frame, `None` where both masks are empty.
    pub per_frame_iou: Vec<Option<f64>>,
    /// Every (source, target) pair, source-major.
    pub pairs: Vec<FlowPairScore>,
}

/// The model's motion of one clip, on the host.
pub struct PredictedMotion<'a> {
    pub context: usize,
    /// `N`: every timestamp, context and future.
    pub frames: usize,
    /// Prediction grid `(H, W)`: the model's input size.
    pub grid: (usize, usize),
    /// `[T_c, G, 3]` Gaussian means, model world frame.
    pub means: &'a [f32],
    /// `[T_c, N−1, G, 3]` displacements (`AdaptedGaussians::motions` of one batch element).
    pub motions: &'a [f32],
    /// Predicted world-to-camera of all `N` frames.
    pub extrinsics: &'a [Mat4],
}

/// The truth of one clip on its frame grid `size`.
pub struct MotionTruth<'a> {
    pub size: (usize, usize),
    /// Per frame (at least `N`).
    pub frames: &'a [Option<FrameMotionTruth>],
    /// Per frame, the dynamic mask (pixels moving to the next frame).
    pub masks: &'a [Option<Vec<bool>>],
}

fn dvec(v: Vec3) -> DVec3 {
    DVec3::new(v.x, v.y, v.z)
}

/// Point `k` of a flat `[.., 3]` f32 buffer.
pub(crate) fn read3(s: &[f32], k: usize) -> DVec3 {
    DVec3::new(s[3 * k] as f64, s[3 * k + 1] as f64, s[3 * k + 2] as f64)
}

/// For each prediction pixel, the frame-grid pixel whose centre it covers.
fn grid_map((hi, wi): (usize, usize), (h, w): (usize, usize)) -> Vec<usize> {
    let mut out = Vec::with_capacity(hi * wi);
    for y in 0..hi {
        let yc = (((y as f64 + 0.5) * h as f64 / hi as f64) as usize).min(h - 1);
        for x in 0..wi {
            let xc = (((x as f64 + 0.5) * w as f64 / wi as f64) as usize).min(w - 1);
            out.push(yc * w + xc);
        }
    }
    out
}

/// Median of true over predicted z-depth of the context Gaussians; `None` when no pixel has
/// both (an empty or all-behind prediction).
fn flow_scale(pred: &PredictedMotion, truth: &[&FrameMotionTruth], map: &[usize]) -> Option<f64> {
    let g = map.len();
    let mut ratios = Vec::new();
    for (i, t) in truth.iter().enumerate().take(pred.context) {
        let (e, w2c) = (pred.extrinsics[i].to_glam(), t.world_to_camera.to_glam());
        for (k, &c) in map.iter().enumerate() {
            let Some(p) = t.points[c] else { continue };
            let zp = e.transform_point3(read3(pred.means, i * g + k)).z;
            let zt = w2c.transform_point3(dvec(p)).z;
            if zp > 0.0 && zp.is_finite() && zt > 0.0 {
                ratios.push(zt / zp);
            }
        }
    }
    if ratios.is_empty() {
        return None;
    }
    ratios.sort_by(f64::total_cmp);
    Some(ratios[ratios.len() / 2])
}

/// Prediction and truth of one clip made comparable: metres (the clip's scale), each side
/// in its own frame-0 camera axes, on the prediction grid.
pub(crate) struct Aligned<'a> {
    pub pred: &'a PredictedMotion<'a>,
    pub frames: Vec<&'a FrameMotionTruth>,
    /// Frame-grid pixel of each prediction pixel.
    map: Vec<usize>,
    pub scale: f64,
    /// Predicted world → frame-0 camera axes, times the scale; true world → frame-0 axes.
    rp: DMat3,
    rt: DMat3,
}

impl<'a> Aligned<'a> {
    /// `None` when a frame lacks truth or no scale can be fitted.
    pub fn new(pred: &'a PredictedMotion<'a>, truth: &MotionTruth<'a>) -> Option<Self> {
        let n = pred.frames;
        let frames: Vec<&FrameMotionTruth> = truth
            .frames
            .iter()
            .take(n)
            .map(Option::as_ref)
            .collect::<Option<_>>()?;
        if frames.len() < n || pred.extrinsics.len() < n {
            return None;
        }
        let map = grid_map(pred.grid, truth.size);
        let scale = flow_scale(pred, &frames, &map)?;
        Some(Aligned {
            rp: pred.extrinsics[0].rotation() * scale,
            rt: frames[0].world_to_camera.rotation(),
            pred,
            frames,
            map,
            scale,
        })
    }

    pub fn pixels(&self) -> usize {
        self.map.len()
    }

    /// Predicted displacement of prediction pixel `k` of source `i` to timestamp `j`.
    pub fn predicted(&self, i: usize, j: usize, k: usize) -> DVec3 {
        let slot = (i * (self.pred.frames - 1) + target_slot(i, j)) * self.map.len() + k;
        self.rp * read3(self.pred.motions, slot)
    }

    /// A displacement in the scored axes (frame-0 camera, metres) brought back to the
    /// prediction's own world axes and unit: the inverse of the map [`Aligned::predicted`]
    /// applies.
    pub fn to_model_axes(&self) -> DMat3 {
        self.rp.inverse()
    }

    /// True displacement of every prediction pixel of source `i` to timestamp `j`; `None`
    /// where there is no truth.
    pub fn truth(&self, i: usize, j: usize) -> Vec<Option<DVec3>> {
        let flow = self.frames[i].flow_to(&self.frames[j].objects);
        self.map
            .iter()
            .map(|&c| flow[c].map(|d| self.rt * dvec(d)))
            .collect()
    }
}

/// The exact displacement of every context Gaussian to every other timestamp in `pred`'s
/// own world axes and unit, laid out as `pred.motions` (the oracle render's motion, and the
/// target of the training's flow diagnostic, docs/TRAINING.md); `pred.motions` itself is
/// not read. `None` when a frame lacks truth or no scale can be fitted.
pub fn exact_motions(pred: &PredictedMotion, truth: &MotionTruth) -> Option<Vec<f32>> {
    Aligned::new(pred, truth).map(|a| crate::motion_scene::oracle_motions(&a))
}

/// [`exact_motions`] and the true world-to-camera of all `N` frames in the same axes and
/// unit (the oracle renders' cameras), from one alignment.
pub fn exact_motions_and_cameras(
    pred: &PredictedMotion,
    truth: &MotionTruth,
) -> Option<(Vec<f32>, Vec<Mat4>)> {
    Aligned::new(pred, truth).map(|a| {
        (
            crate::motion_scene::oracle_motions(&a),
            crate::motion_scene::true_cameras(&a),
        )
    })
}

/// Scores `pred` against `truth`; `None` when a frame lacks truth or no scale can be fitted.
pub fn motion_score(pred: &PredictedMotion, truth: &MotionTruth) -> Option<MotionScore> {
    Aligned::new(pred, truth).map(|a| score_aligned(&a, truth.masks))
}

/// The score of an aligned clip; `masks` are the clip's dynamic masks per frame.
pub(crate) fn score_aligned(a: &Aligned, masks: &[Option<Vec<bool>>]) -> MotionScore {
    let (tc, n) = (a.pred.context, a.pred.frames);
    let mut pairs = Vec::with_capacity(tc * (n - 1));
    for i in 0..tc {
        for j in (0..n).filter(|&j| j != i) {
            let mut sums = PairSums::default();
            for (k, d) in a.truth(i, j).into_iter().enumerate() {
                if let Some(d) = d {
                    sums.add(a.predicted(i, j, k), d);
                }
            }
            pairs.push(sums.score(i, j));
        }
    }
    let per_frame_iou: Vec<Option<f64>> = (0..tc)
        .map(|i| {
            let mask = masks.get(i)?.as_ref()?;
            let moving =
                (0..a.pixels()).map(|k| a.predicted(i, i + 1, k).length() > MASK_THRESHOLD_M);
            iou(moving, a.map.iter().map(|&c| mask[c]))
        })
        .collect();
    let future: Vec<&FlowPairScore> = pairs.iter().filter(|p| p.target >= tc).collect();
    let over = |f: fn(&FlowPairScore) -> Option<f64>| mean_opt(future.iter().map(|p| f(p)));
    MotionScore {
        flow_scale: a.scale,
        epe_dynamic: over(|p| p.epe_dynamic),
        epe_static: over(|p| p.epe_static),
        true_displacement: over(|p| p.true_displacement),
        rel_epe_dynamic: over(|p| p.rel_epe_dynamic),
        mask_iou: mean_opt(per_frame_iou.iter().copied()),
        mask_threshold_m: MASK_THRESHOLD_M,
        per_frame_iou,
        pairs,
    }
}

/// Intersection over union of two masks; `None` when both are empty.
pub fn iou(a: impl Iterator<Item = bool>, b: impl Iterator<Item = bool>) -> Option<f64> {
    let (mut inter, mut union) = (0usize, 0usize);
    for (x, y) in a.zip(b) {
        inter += usize::from(x && y);
        union += usize::from(x || y);
    }
    (union > 0).then(|| inter as f64 / union as f64)
}

#[derive(Default)]
struct PairSums {
    dynamic: (usize, f64, f64),
    fixed: (usize, f64),
}

impl PairSums {
    fn add(&mut self, predicted: DVec3, truth: DVec3) {
        let err = (predicted - truth).length();
        if truth.length() > MOVING_EPS_M {
            self.dynamic.0 += 1;
            self.dynamic.1 += err;
            self.dynamic.2 += truth.length();
        } else {
            self.fixed.0 += 1;
            self.fixed.1 += err;
        }
    }

    fn score(&self, source: usize, target: usize) -> FlowPairScore {
        let (nd, ed, td) = self.dynamic;
        let (ns, es) = self.fixed;
        let per = |sum: f64, count: usize| (count > 0).then(|| sum / count as f64);
        FlowPairScore {
            source,
            target,
            dynamic_pixels: nd,
            static_pixels: ns,
            epe_dynamic: per(ed, nd),
            epe_static: per(es, ns),
            true_displacement: per(td, nd),
            rel_epe_dynamic: (nd > 0 && td > 0.0).then(|| ed / td),
        }
    }
}

/// The mean over clips of [`MotionScore`]s (pairs and frames matched by position: clips of
/// one run share `T_c` and `T_f`); `None` for none.
pub fn mean_motion(all: &[&MotionScore]) -> Option<MotionScore> {
    let first = all.first()?;
    let m = |f: &dyn Fn(&MotionScore) -> Option<f64>| mean_opt(all.iter().map(|s| f(s)));
    let pairs = (0..all.iter().map(|s| s.pairs.len()).min().unwrap_or(0))
        .map(|k| {
            let at: Vec<&FlowPairScore> = all.iter().map(|s| &s.pairs[k]).collect();
            let p = |f: fn(&FlowPairScore) -> Option<f64>| mean_opt(at.iter().map(|s| f(s)));
            FlowPairScore {
                source: at[0].source,
                target: at[0].target,
                dynamic_pixels: at.iter().map(|s| s.dynamic_pixels).sum(),
                static_pixels: at.iter().map(|s| s.static_pixels).sum(),
                epe_dynamic: p(|s| s.epe_dynamic),
                epe_static: p(|s| s.epe_static),
                true_displacement: p(|s| s.true_displacement),
                rel_epe_dynamic: p(|s| s.rel_epe_dynamic),
            }
        })
        .collect();
    let frames = all.iter().map(|s| s.per_frame_iou.len()).min().unwrap_or(0);
    Some(MotionScore {
        flow_scale: m(&|s| Some(s.flow_scale)).unwrap_or(1.0),
        epe_dynamic: m(&|s| s.epe_dynamic),
        epe_static: m(&|s| s.epe_static),
        true_displacement: m(&|s| s.true_displacement),
        rel_epe_dynamic: m(&|s| s.rel_epe_dynamic),
        mask_iou: m(&|s| s.mask_iou),
        mask_threshold_m: first.mask_threshold_m,
        per_frame_iou: (0..frames)
            .map(|k| mean_opt(all.iter().map(|s| s.per_frame_iou[k])))
            .collect(),
        pairs,
    })
}

impl MotionScore {
    /// The Markdown section of `metrics.md`.
    pub fn markdown(&self) -> String {
        use crate::markdown::opt;
        let mut s = format!(
            "## Motion against exact truth (synthetic)\n\n\
             Scene-flow end-point error of the context Gaussians' displacements, metres after the \
             clip's depth scale (mean {:.3} m per model unit), in frame-0 camera axes. \
             Future pairs: EPE on moving pixels {} m (predicting no motion: {} m; relative {}), \
             on static pixels {} m. Dynamic-mask IoU (predicted motion to the next frame over \
             {} m): {}.\n\n\
             | source → target | EPE moving (m) | no motion (m) | relative | EPE static (m) | moving px |\n\
             |---|---|---|---|---|---|\n",
            self.flow_scale,
            opt(self.epe_dynamic, 3),
            opt(self.true_displacement, 3),
            opt(self.rel_epe_dynamic, 3),
            opt(self.epe_static, 3),
            self.mask_threshold_m,
            opt(self.mask_iou, 3),
        );
        for p in &self.pairs {
            s.push_str(&format!(
                "| {} → {} | {} | {} | {} | {} | {} |\n",
                p.source,
                p.target,
                opt(p.epe_dynamic, 3),
                opt(p.true_displacement, 3),
                opt(p.rel_epe_dynamic, 3),
                opt(p.epe_static, 3),
                p.dynamic_pixels
            ));
        }
        s.push('\n');
        s
    }

    /// One line of the printed summary.
    pub fn summary_line(&self) -> String {
        use crate::markdown::opt;
        format!(
            "  motion vs exact flow (future pairs): EPE moving {} m (no motion {} m, relative {}), \
             static {} m; dynamic-mask IoU {}",
            opt(self.epe_dynamic, 3),
            opt(self.true_displacement, 3),
            opt(self.rel_epe_dynamic, 3),
            opt(self.epe_static, 3),
            opt(self.mask_iou, 3)
        )
    }
}

#[cfg(test)]
#[path = "motion_tests.rs"]
mod tests;
