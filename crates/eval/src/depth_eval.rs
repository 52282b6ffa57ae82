//! D-RMSE against the clip's evaluation depth (LiDAR moved onto the frame grid, or the
//! synthetic world's dense depth; see `envision4d_data::depth_grid`).
//!
//! Two numbers, kept apart because they measure different things:
//! - the paper's Table 1 D-RMSE: the *rendered* expected depth of the scored (future)
//!   frames, what the splats put at each LiDAR return;
//! - the depth head's own maps on the context frames (what the distillation trains).
//!
//! A pose-free model's depth has no metric scale, so the prediction is scaled per frame
//! (`EvalOptions::depth_alignment`, median by default) before the error is taken. If the
//! alignment is degenerate for one frame (a render that is empty at most LiDAR returns has a
//! zero median), that frame is scored without scaling and its scale is reported as 1: an
//! empty render must cost, not vanish from the mean.

use crate::error::{EvalError, Result};
use crate::protocol::alignment_name;
use crate::report::{mean, DepthScore};
use envision4d_data::DepthSource;
use envision4d_losses::{
    depth_rmse, AlignmentScope, DepthAlignment, EvalCrop, HostDepths, LossError,
};

/// Ground truth of a clip's frames on the frame grid (`H·W` each, 0 = none; `None` for a
/// frame without depth).
pub struct DepthTruth<'a> {
    pub maps: &'a [Option<Vec<f32>>],
    pub source: DepthSource,
}

/// D-RMSE of predicted maps `pred` (`[F, H, W]`, one per entry of `frames`) against
/// `truth.maps[frames[k]]`, after `crop`. A frame without truth (or without a valid pixel
/// left) scores `None` alone; `None` overall when no frame has one.
pub fn depth_score(
    pred: &HostDepths,
    truth: &DepthTruth,
    frames: &[usize],
    crop: EvalCrop,
    alignment: DepthAlignment,
) -> Result<Option<DepthScore>> {
    let [f, h, w] = pred.shape();
    if f != frames.len() {
        return Err(EvalError::Unscorable(format!(
            "{f} predicted depth maps for {} scored frames",
            frames.len()
        )));
    }
    let gt: Vec<f64> = frames
        .iter()
        .flat_map(|&j| match truth.maps.get(j).and_then(Option::as_ref) {
            Some(map) if map.len() == h * w => map.iter().map(|&v| v as f64).collect(),
            _ => vec![0.0; h * w],
        })
        .collect();
    let gt = crop.apply_depths(&HostDepths::new("ground-truth depth", gt, [f, h, w])?)?;
    let pred = crop.apply_depths(pred)?;
    let [_, ch, cw] = gt.shape();
    let (mut per_frame, mut scales) = (Vec::with_capacity(f), Vec::with_capacity(f));
    for k in 0..f {
        let one = |d: &HostDepths, what| HostDepths::new(what, d.map(k).to_vec(), [1, ch, cw]);
        let (p, g) = (
            one(&pred, "predicted depth")?,
            one(&gt, "ground-truth depth")?,
        );
        if g.map(0).iter().all(|&v| v <= 0.0) {
            per_frame.push(None);
            scales.push(None);
            continue;
        }
        let r = match depth_rmse(&p, &g, alignment, AlignmentScope::PerFrame) {
            Err(LossError::Invalid {
                what: "depth alignment",
                ..
            }) => depth_rmse(&p, &g, DepthAlignment::None, AlignmentScope::PerFrame)?,
            other => other?,
        };
        per_frame.push(r.per_frame[0]);
        scales.push(Some(r.scales[0]));
    }
    if per_frame.iter().all(Option::is_none) {
        return Ok(None);
    }
    Ok(Some(DepthScore {
        rmse: mean(per_frame.iter().flatten().copied()),
        alignment: alignment_name(alignment).into(),
        source: truth.source.name().into(),
        frames: frames.to_vec(),
        scales,
        per_frame,
    }))
}

/// Upsamples `[F, hi, wi]` maps to `[F, h, w]` nearest-neighbour (a depth head run at a
/// smaller input size), so the crop and the truth pixels are those of the images.
pub fn upsample_nearest(data: &[f64], f: usize, from: [usize; 2], to: [usize; 2]) -> Vec<f64> {
    let ([hi, wi], [h, w]) = (from, to);
    let mut up = Vec::with_capacity(f * h * w);
    for j in 0..f {
        let map = &data[j * hi * wi..(j + 1) * hi * wi];
        for y in 0..h {
            let sy = (y * hi / h).min(hi - 1);
            up.extend((0..w).map(|x| map[sy * wi + (x * wi / w).min(wi - 1)]));
        }
    }
    up
}

#[cfg(test)]
mod tests {
    use super::*;

    fn depths(data: Vec<f64>, shape: [usize; 3]) -> HostDepths {
        HostDepths::new("test", data, shape).unwrap()
    }

    /// Guards the Table 1 number on a hand-computed case: rendered depth known, LiDAR on
    /// three pixels of frame 2, frame 3's depth file missing (it must not drop frame 2's
    /// score); median alignment, one scale per frame.
    #[test]
    fn rendered_depth_against_known_lidar() {
        // Rendered 2x2 depth for frames 2 and 3 of a clip.
        let pred = depths(vec![1.0, 2.0, 4.0, 9.0, 5.0, 5.0, 5.0, 5.0], [2, 2, 2]);
        let empty = vec![0.0f32; 4];
        // LiDAR at pixels 0, 1, 2 of frame 2: 2, 4, 10 (pixel 3 has no return).
        // Frame 3 has no depth file at all: it alone scores nothing.
        let maps = vec![
            Some(empty.clone()),
            Some(empty),
            Some(vec![2.0, 4.0, 10.0, 0.0]),
            None,
        ];
        let truth = DepthTruth {
            maps: &maps,
            source: DepthSource::LidarGrid,
        };
        let s = depth_score(
            &pred,
            &truth,
            &[2, 3],
            EvalCrop::default(),
            DepthAlignment::Median,
        )
        .unwrap()
        .unwrap();
        // Valid pairs (1,2), (2,4), (4,10): medians 2 and 4, s = 2; errors 0, 0, 2.
        let want = (4.0f64 / 3.0).sqrt();
        assert!((s.rmse - want).abs() < 1e-12, "{s:?}");
        assert_eq!(s.per_frame.len(), 2);
        assert!(s.per_frame[1].is_none());
        assert_eq!(s.scales, vec![Some(2.0), None]);
        assert_eq!(
            (s.source.as_str(), s.frames.clone()),
            ("lidar_grid", vec![2, 3])
        );
    }

    /// Guards the degenerate case: an empty render at the LiDAR returns is scored unscaled
    /// (its error is the full depth), not dropped from the mean.
    #[test]
    fn empty_render_is_scored_without_scaling() {
        let pred = depths(vec![0.0; 4], [1, 2, 2]);
        let maps = vec![Some(vec![3.0f32, 0.0, 0.0, 0.0])];
        let truth = DepthTruth {
            maps: &maps,
            source: DepthSource::LidarPoints,
        };
        let s = depth_score(
            &pred,
            &truth,
            &[0],
            EvalCrop::default(),
            DepthAlignment::Median,
        )
        .unwrap()
        .unwrap();
        assert_eq!((s.rmse, s.scales.clone()), (3.0, vec![Some(1.0)]));
    }

    /// Guards the crop: truth only in the cropped border gives no score rather than a number.
    #[test]
    fn truth_only_in_the_crop_gives_none() {
        let pred = depths(vec![1.0; 9], [1, 3, 3]);
        let mut map = vec![0.0f32; 9];
        map[0] = 5.0;
        let maps = vec![Some(map)];
        let truth = DepthTruth {
            maps: &maps,
            source: DepthSource::Dense,
        };
        let crop = EvalCrop {
            top: 1,
            bottom: 1,
            left: 1,
            right: 1,
        };
        let s = depth_score(&pred, &truth, &[0], crop, DepthAlignment::Median).unwrap();
        assert!(s.is_none());
    }
}
