//! "Report error against run time": the knobs that trade quality for time, one at a time
//! from the base setting, and the Pareto front of (time, PSNR).
//!
//! Knobs: the future horizon (the model keeps its first `h` learned future seeds, so the
//! future-pose stack, the motion head and the renderer all do less work), the input
//! resolution (renders stay at the clip's size so every point is scored on the same
//! pixels), the backend, and the rasterizer's culling thresholds (`alpha_min`,
//! `transmittance_min`).

use crate::error::{EvalError, Result};
use crate::report::{mean, mean_opt, ClipMetrics, Method};
use crate::{EvalOptions, Extent};
use envision4d_model::Envision4d;
use envision4d_splat::RasterConfig;
use serde::{Deserialize, Serialize};

/// Input-size scales tried besides the base (sizes rounded to whole patches).
pub const RESOLUTION_SCALES: [f64; 2] = [0.75, 0.5];
/// `alpha_min` values tried besides the base (gsplat's 1/255): fewer, larger splats count.
pub const ALPHA_MIN_VALUES: [f64; 2] = [0.02, 0.1];
/// `transmittance_min` values tried besides the base (1e-4): compositing stops earlier.
pub const TRANSMITTANCE_MIN_VALUES: [f64; 2] = [0.01, 0.1];

/// Which knob a sweep point moved away from the base setting.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Knob {
    Base,
    Horizon,
    InputSize,
    Backend,
    AlphaMin,
    TransmittanceMin,
}

/// One evaluated sweep point: the model's mean future-frame quality and time per clip.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SweepPoint {
    pub knob: Knob,
    pub value: String,
    pub backend: String,
    pub horizon: usize,
    pub input_size: [usize; 2],
    pub alpha_min: f64,
    pub transmittance_min: f64,
    pub clips: usize,
    pub psnr: f64,
    pub ssim: f64,
    pub lpips: Option<f64>,
    pub rot_err_deg: Option<f64>,
    pub trans_err: Option<f64>,
    pub encoder_s: f64,
    pub decoder_s: f64,
    /// `encoder_s + decoder_s`, the x axis of the Pareto plot.
    pub time_s: f64,
    /// No other point is at least as fast and at least as good (PSNR), and better in one.
    pub pareto: bool,
}

/// One setting to evaluate.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepSetting {
    pub knob: Knob,
    pub backend: String,
    /// Future frames predicted and scored (`<= T_f`).
    pub horizon: usize,
    pub input_size: [usize; 2],
    pub raster: RasterConfig,
}

/// The base setting of a sweep.
#[derive(Debug, Clone)]
pub struct SweepBase {
    pub backend: String,
    pub future_frames: usize,
    pub input_size: [usize; 2],
    pub patch_size: usize,
    pub raster: RasterConfig,
}

/// The base, then each knob's other values (`backends` besides the base one).
pub fn plan(base: &SweepBase, backends: &[String]) -> Vec<SweepSetting> {
    let b = SweepSetting {
        knob: Knob::Base,
        backend: base.backend.clone(),
        horizon: base.future_frames,
        input_size: base.input_size,
        raster: base.raster,
    };
    let mut out = vec![b.clone()];
    let with = |knob, f: &dyn Fn(&mut SweepSetting)| {
        let mut s = b.clone();
        s.knob = knob;
        f(&mut s);
        s
    };
    for h in 1..base.future_frames {
        out.push(with(Knob::Horizon, &|s| s.horizon = h));
    }
    let mut sizes = vec![base.input_size];
    for scale in RESOLUTION_SCALES {
        let size = base
            .input_size
            .map(|d| patch_round(d as f64 * scale, base.patch_size));
        if !sizes.contains(&size) {
            sizes.push(size);
            out.push(with(Knob::InputSize, &|s| s.input_size = size));
        }
    }
    for name in backends.iter().filter(|n| **n != base.backend) {
        out.push(with(Knob::Backend, &|s| s.backend = name.clone()));
    }
    for a in ALPHA_MIN_VALUES {
        out.push(with(Knob::AlphaMin, &|s| s.raster.alpha_min = a));
    }
    for t in TRANSMITTANCE_MIN_VALUES {
        out.push(with(Knob::TransmittanceMin, &|s| {
            s.raster.transmittance_min = t;
        }));
    }
    out
}

/// `v` rounded to the nearest whole number of patches (at least one).
fn patch_round(v: f64, patch: usize) -> usize {
    ((v / patch as f64).round() as usize).max(1) * patch
}

impl Knob {
    /// The knob's name as in the JSON (`snake_case`).
    pub fn name(self) -> &'static str {
        match self {
            Knob::Base => "base",
            Knob::Horizon => "horizon",
            Knob::InputSize => "input_size",
            Knob::Backend => "backend",
            Knob::AlphaMin => "alpha_min",
            Knob::TransmittanceMin => "transmittance_min",
        }
    }
}

impl SweepSetting {
    /// The value of this point's knob, as a table cell.
    pub fn value(&self) -> String {
        match self.knob {
            Knob::Base => "base".into(),
            Knob::Horizon => format!("T_f={}", self.horizon),
            Knob::InputSize => format!("{}x{}", self.input_size[0], self.input_size[1]),
            Knob::Backend => self.backend.clone(),
            Knob::AlphaMin => format!("alpha_min={}", self.raster.alpha_min),
            Knob::TransmittanceMin => format!("T_min={}", self.raster.transmittance_min),
        }
    }

    /// Options for this point: `base` with the knob applied, future frames only.
    pub fn options(&self, base: &EvalOptions) -> EvalOptions {
        let mut o = base.clone();
        o.raster = self.raster;
        o.input_size = Some(self.input_size);
        o.extent = Extent::FutureOnly;
        o
    }
}

/// A model that predicts only its first `horizon` future frames (its first `horizon`
/// learned future seeds; the rest of the network is shared).
pub fn with_horizon(model: &Envision4d, horizon: usize) -> Result<Envision4d> {
    model
        .with_horizon(horizon)
        .ok_or_else(|| EvalError::Invalid {
            key: "horizon",
            value: horizon.to_string(),
            reason: format!(
                "must be in 1..={} (the model's future frames)",
                model.future_frames()
            ),
        })
}

/// The sweep point of `setting` from its clips' metrics; `None` when no clip was scored.
pub fn summarize(setting: &SweepSetting, clips: &[ClipMetrics]) -> Option<SweepPoint> {
    let scores: Vec<_> = clips
        .iter()
        .filter_map(|c| c.method(Method::Model))
        .collect();
    if scores.is_empty() {
        return None;
    }
    let encoder_s = mean(clips.iter().map(|c| c.timing.encoder_s));
    let decoder_s = mean(clips.iter().map(|c| c.timing.decoder_s));
    Some(SweepPoint {
        knob: setting.knob,
        value: setting.value(),
        backend: setting.backend.clone(),
        horizon: setting.horizon,
        input_size: setting.input_size,
        alpha_min: setting.raster.alpha_min,
        transmittance_min: setting.raster.transmittance_min,
        clips: scores.len(),
        psnr: mean(scores.iter().map(|s| s.psnr)),
        ssim: mean(scores.iter().map(|s| s.ssim)),
        lpips: mean_opt(scores.iter().map(|s| s.lpips)),
        rot_err_deg: mean_opt(scores.iter().map(|s| s.rot_err_deg)),
        trans_err: mean_opt(scores.iter().map(|s| s.trans_err)),
        encoder_s,
        decoder_s,
        time_s: encoder_s + decoder_s,
        pareto: false,
    })
}

/// Sets `pareto` on every point that no other point dominates in (lower time, higher PSNR).
pub fn mark_pareto(points: &mut [SweepPoint]) {
    let flags: Vec<bool> = points
        .iter()
        .map(|p| {
            !points.iter().any(|q| {
                q.time_s <= p.time_s && q.psnr >= p.psnr && (q.time_s < p.time_s || q.psnr > p.psnr)
            })
        })
        .collect();
    for (p, f) in points.iter_mut().zip(flags) {
        p.pareto = f;
    }
}
