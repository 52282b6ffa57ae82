//! Which clips the report shows: the worst and the best by the model's future-frame PSNR,
//! chosen while the evaluation streams, so only `keep` clips' images are ever held.

use envision4d_eval::clip_images::ClipImages;
use envision4d_eval::motion_maps::PairMaps;
use envision4d_eval::report::{ClipMetrics, Method, MethodScore};

/// One shown clip: its scores, frames and (where the data has motion truth) motion maps.
pub struct Shown {
    pub clip: String,
    pub methods: Vec<MethodScore>,
    pub images: ClipImages,
    pub maps: Option<PairMaps>,
}

impl Shown {
    /// The model's future-frame PSNR.
    pub fn psnr(&self) -> f64 {
        self.methods
            .iter()
            .find(|m| m.method == Method::Model)
            .map_or(f64::NAN, |m| m.psnr)
    }

    /// The ranking key: the PSNR, with a missing or NaN one ranked worst (not best, where
    /// `total_cmp` would put it).
    fn rank(&self) -> f64 {
        let p = self.psnr();
        if p.is_nan() {
            f64::NEG_INFINITY
        } else {
            p
        }
    }
}

/// Up to `keep` clips: the `keep / 2` worst and the rest best.
pub struct Gallery {
    keep: usize,
    /// Ascending PSNR.
    clips: Vec<Shown>,
}

impl Gallery {
    pub fn new(keep: usize) -> Gallery {
        Gallery {
            keep,
            clips: Vec::new(),
        }
    }

    /// Whether clips need their images kept at all.
    pub fn wants_images(&self) -> bool {
        self.keep > 0
    }

    /// Takes `m`'s images (and a copy of its motion maps) if it ranks among the kept; a clip
    /// that would leave at once costs no copy.
    pub fn offer(&mut self, m: &mut ClipMetrics) {
        let Some(images) = m.images.take() else {
            return;
        };
        if self.keep == 0 {
            return;
        }
        let mut shown = Shown {
            clip: m.clip.clone(),
            methods: m.methods.clone(),
            images,
            maps: None,
        };
        let at = self
            .clips
            .partition_point(|c| c.rank().total_cmp(&shown.rank()).is_lt());
        // Full: the one between the worst half and the best half leaves; if that is this
        // clip, nothing changes.
        let full = self.clips.len() == self.keep;
        if full && at == self.keep / 2 {
            return;
        }
        shown.maps = m.motion_maps.clone();
        self.clips.insert(at, shown);
        if full {
            self.clips.remove(self.keep / 2);
        }
    }

    /// Worst first, then best from the best down; a single clip is neither (`only`).
    pub fn into_ordered(self) -> Vec<(&'static str, Shown)> {
        let mut clips = self.clips;
        if clips.len() == 1 {
            return clips.into_iter().map(|c| ("only", c)).collect();
        }
        // Fewer clips than `keep`: the lower half is still "worst".
        let worst = clips.len() / 2;
        let best: Vec<Shown> = clips.drain(worst..).rev().collect();
        clips
            .into_iter()
            .map(|c| ("worst", c))
            .chain(best.into_iter().map(|c| ("best", c)))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use envision4d_losses::HostImages;

    fn clip(name: &str, psnr: f64) -> ClipMetrics {
        let mut m: ClipMetrics =
            serde_json::from_value(serde_json::json!({"clip": name, "timing": {"encoder_s": 0.0, "decoder_s": 0.0, "context_decoder_s": null}, "methods": [], "context": null, "depth_rmse": null, "context_depth_rmse": null, "motion": null})).unwrap();
        let mut score: MethodScore = serde_json::from_value(serde_json::json!({"method": "model", "psnr": 0.0, "ssim": 0.0, "lpips": null, "rot_err_deg": null, "trans_err": null, "trans_err_unaligned": null, "pose_scale": null, "dynamic_psnr": null, "dynamic_ssim": null, "static_psnr": null, "static_ssim": null, "camera_auc30": null, "time_s": 0.0, "per_horizon": []})).unwrap();
        score.psnr = psnr;
        m.methods = vec![score];
        m.images = Some(ClipImages {
            context: 2,
            ground_truth: HostImages::new("t", vec![0.0; 3], [1, 3, 1, 1]).unwrap(),
            methods: Vec::new(),
            depth: vec![1.0],
            dynamic_masks: Vec::new(),
        });
        m
    }

    /// Guards the streamed choice: of eight clips arriving in any order, the report keeps
    /// the two worst (worst first; a NaN PSNR is worst, not best) and the two best (best
    /// first), and takes their images out of the metrics (which stay in the run).
    #[test]
    fn keeps_the_worst_and_best_while_streaming() {
        let mut g = Gallery::new(4);
        for (name, psnr) in [
            ("c", 15.0),
            ("n", f64::NAN),
            ("a", 10.0),
            ("g", 30.0),
            ("d", 20.0),
            ("b", 12.0),
            ("f", 25.0),
            ("e", 22.0),
        ] {
            let mut m = clip(name, psnr);
            g.offer(&mut m);
            assert!(m.images.is_none());
        }
        let got: Vec<(&str, String)> = g
            .into_ordered()
            .into_iter()
            .map(|(k, s)| (k, s.clip))
            .collect();
        let want = [("worst", "n"), ("worst", "a"), ("best", "g"), ("best", "f")];
        assert_eq!(got, want.map(|(k, c)| (k, c.to_owned())));
    }
}
