//! What `envision4d demo` prints on stdout: a header naming the run (with the seed that
//! repeats it), the future-frame scores of the model and the baselines with the time each
//! took, and every path written as `  label: path` lines.

use crate::backend_choice::BackendChoice;
use crate::eval_cmd::shared::backend_name;
use envision4d_data::synth::SynthConfig;
use envision4d_eval::markdown::opt;
use envision4d_eval::{ClipMetrics, Method, MethodScore, Report};
use envision4d_model::ModelConfig;
use std::fmt::Write;
use std::path::{Path, PathBuf};

/// Text for a number that is not available (e.g. pose errors without ground-truth poses).
/// Heading of the path list; each following line is `  label: path`.
pub const WROTE: &str = "wrote:";

/// One line: the checkpoint, the clip and how to generate the same clip again.
pub fn header(
    checkpoint: &Path,
    synth: &SynthConfig,
    cfg: &ModelConfig,
    backend: BackendChoice,
) -> String {
    format!(
        "demo: seed {seed} (repeat with --seed {seed}), preset {}, {} context + {} future frames \
         at {}x{}, checkpoint {}, backend {}",
        synth.preset.name(),
        cfg.context_frames,
        cfg.future_frames,
        synth.height,
        synth.width,
        checkpoint.display(),
        backend_name(backend),
        seed = synth.seed,
    )
}

/// Where a method's seconds went: the model's encoder and decoder, a baseline's renders.
fn time_split(m: &MethodScore, clip: &ClipMetrics) -> String {
    let enc = clip.timing.encoder_s;
    match m.method {
        Method::Model => format!("encoder {enc:.3} + decoder {:.3}", clip.timing.decoder_s),
        // They reuse the model's encoder pass and render its Gaussians again.
        Method::StaticCv
        | Method::NoMotion
        | Method::OracleMotion
        | Method::TrueCamerasNoMotion
        | Method::TrueCameras
        | Method::TrueCamerasOracleMotion => {
            format!(
                "encoder {enc:.3} + renders {:.3}",
                (m.time_s - enc).max(0.0)
            )
        }
        Method::CopyLast => "copying only".into(),
    }
}

/// The future-frame table of the (single) clip, then the cross-frame and depth numbers.
pub fn scores(report: &Report) -> String {
    let mut s = String::new();
    let Some(clip) = report.clips.first() else {
        return "no clip was evaluated\n".into();
    };
    let _ = writeln!(
        s,
        "predicted future vs the generator's truth (mean over {} future frames):",
        report.future_frames
    );
    let _ = writeln!(
        s,
        "  {:<10} {:>9}  {:>6}  {:>9}  {:>9}  {:>8}  of which (s)",
        "method", "PSNR (dB)", "SSIM", "rot (deg)", "trans (m)", "time (s)"
    );
    for m in &clip.methods {
        let _ = writeln!(
            s,
            "  {:<10} {:>9.2}  {:>6.4}  {:>9}  {:>9}  {:>8.3}  {}",
            m.method.label(),
            m.psnr,
            m.ssim,
            opt(m.rot_err_deg, 2),
            opt(m.trans_err, 3),
            m.time_s,
            time_split(m, clip)
        );
    }
    if let Some(c) = &clip.context {
        let _ = writeln!(
            s,
            "context frames from the other frames' Gaussians: PSNR {:.2} dB, SSIM {:.4}",
            c.psnr, c.ssim
        );
    }
    if let Some(d) = &clip.depth_rmse {
        let _ = writeln!(s, "D-RMSE ({} alignment): {:.3} m", d.alignment, d.rmse);
    }
    s
}

/// A written file's label: its file name.
pub fn file_label(path: &Path) -> String {
    path.file_name().map_or_else(
        || path.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    )
}

/// `wrote:` and one `  label: path` line per path.
pub fn paths(paths: &[(String, PathBuf)]) -> String {
    let mut s = format!("{WROTE}\n");
    for (label, path) in paths {
        let _ = writeln!(s, "  {label}: {}", path.display());
    }
    s
}
