//! `metrics.md`: the report as Markdown tables (means first, then per horizon, cross-frame,
//! depth, timing, the Pareto table of a sweep, and one row per clip); and the plain-text
//! lines printed while and after evaluating (quality next to the time it cost).

use crate::report::{ClipMetrics, Method, Report, SweepPoint};
use std::fmt::Write;

/// Text for a missing value.
pub const NA: &str = "n/a";

/// A value with `digits` decimals, or [`NA`] when it is missing (no weights, no truth).
pub fn opt(v: Option<f64>, digits: usize) -> String {
    v.map_or(NA.to_owned(), |v| format!("{v:.digits$}"))
}

/// The whole Markdown report.
pub fn markdown(r: &Report) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# Envision4D evaluation\n");
    let _ = writeln!(
        s,
        "- checkpoint: `{}`\n- data: `{}` (split `{}`), {} clips evaluated, {} skipped\n\
         - backend: {} ({}); T_c = {}, T_f = {}; clips {}x{}, model input {}x{}\n\
         - crop (top, bottom, left, right): {}, {}, {}, {}; cross-frame crop: {}, {}, {}, {}; \
         depth alignment: {}\n\
         - translation error: {} alignment, in {}\n\
         - LPIPS: {}\n",
        r.checkpoint,
        r.data,
        r.split,
        r.clips_evaluated,
        r.clips_skipped,
        r.backend,
        r.precision,
        r.context_frames,
        r.future_frames,
        r.image_size[0],
        r.image_size[1],
        r.input_size[0],
        r.input_size[1],
        r.crop.top,
        r.crop.bottom,
        r.crop.left,
        r.crop.right,
        r.cross_frame_crop.top,
        r.cross_frame_crop.bottom,
        r.cross_frame_crop.left,
        r.cross_frame_crop.right,
        r.depth_alignment,
        r.translation_alignment,
        r.translation_unit,
        if r.lpips.available {
            "computed".to_owned()
        } else {
            format!(
                "not reported ({})",
                r.lpips.reason.as_deref().unwrap_or("unavailable")
            )
        }
    );
    if let Some(m) = &r.mean {
        mean_tables(&mut s, m);
    } else {
        let _ = writeln!(s, "No clip was evaluated.\n");
    }
    if let Some(points) = &r.sweep {
        sweep_table(&mut s, points);
    }
    clip_table(&mut s, &r.clips);
    s
}

fn mean_tables(s: &mut String, m: &ClipMetrics) {
    let _ = writeln!(s, "## Future frames (mean over clips)\n");
    let _ = writeln!(
        s,
        "| method | PSNR (dB) | SSIM | LPIPS | rot err (deg) | trans err (m) | AUC@30 | time (s/clip) |\n\
         |---|---|---|---|---|---|---|---|"
    );
    for x in &m.methods {
        let _ = writeln!(
            s,
            "| {} | {:.2} | {:.4} | {} | {} | {} | {} | {:.3} |",
            x.method.label(),
            x.psnr,
            x.ssim,
            opt(x.lpips, 4),
            opt(x.rot_err_deg, 2),
            opt(x.trans_err, 3),
            opt(x.camera_auc30.map(|a| a * 100.0), 1),
            x.time_s
        );
    }
    let _ = writeln!(
        s,
        "\nAUC@30 is ×100. Pose errors are relative to frame 0; the translation error is after the clip's scale alignment (see the header; `trans_err_unaligned` in metrics.json without it).\n"
    );
    if m.methods.iter().any(|x| x.dynamic_psnr.is_some()) {
        let _ = writeln!(
            s,
            "Future frames on the ground-truth dynamic mask and on the rest:\n\n\
             | method | dynamic PSNR (dB) | dynamic SSIM | static PSNR (dB) | static SSIM |\n\
             |---|---|---|---|---|"
        );
        for x in &m.methods {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} |",
                x.method.label(),
                opt(x.dynamic_psnr, 2),
                opt(x.dynamic_ssim, 4),
                opt(x.static_psnr, 2),
                opt(x.static_ssim, 4)
            );
        }
        let _ = writeln!(s);
    }
    if let Some(motion) = &m.motion {
        s.push_str(&motion.markdown());
    }
    let _ = writeln!(s, "## Per future horizon (mean over clips)\n");
    let _ = writeln!(
        s,
        "| method | horizon | frame | PSNR (dB) | SSIM | LPIPS | rot err (deg) | trans err (m) |\n\
         |---|---|---|---|---|---|---|---|"
    );
    for x in &m.methods {
        for h in &x.per_horizon {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {:.2} | {:.4} | {} | {} | {} |",
                x.method.label(),
                h.horizon,
                h.frame,
                h.psnr,
                h.ssim,
                opt(h.lpips, 4),
                opt(h.rot_err_deg, 2),
                opt(h.trans_err, 3)
            );
        }
    }
    if let Some(c) = &m.context {
        let _ = writeln!(
            s,
            "\n## Context frames rendered from the other frames' Gaussians (cross-frame)\n\n\
             | frame | PSNR (dB) | SSIM | LPIPS |\n|---|---|---|---|"
        );
        for f in &c.per_frame {
            let _ = writeln!(
                s,
                "| {} | {:.2} | {:.4} | {} |",
                f.frame,
                f.psnr,
                f.ssim,
                opt(f.lpips, 4)
            );
        }
        let _ = writeln!(
            s,
            "| mean | {:.2} | {:.4} | {} |",
            c.psnr,
            c.ssim,
            opt(c.lpips, 4)
        );
        let _ = writeln!(
            s,
            "\nOne source frame alone (`i→j`: frame j rendered from frame i's Gaussians):\n\n\
             | pair | PSNR (dB) | SSIM | LPIPS |\n|---|---|---|---|"
        );
        for p in &c.pairs {
            let _ = writeln!(
                s,
                "| {}→{} | {:.2} | {:.4} | {} |",
                p.source,
                p.target,
                p.psnr,
                p.ssim,
                opt(p.lpips, 4)
            );
        }
    }
    let _ = writeln!(s, "\n## Depth\n");
    for (what, d) in [
        ("rendered depth, scored frames (Table 1)", &m.depth_rmse),
        ("depth head, context frames", &m.context_depth_rmse),
    ] {
        let _ = match d {
            Some(d) => writeln!(
                s,
                "- D-RMSE, {what}: {:.3} m ({} alignment, truth {}, frames {:?})",
                d.rmse, d.alignment, d.source, d.frames
            ),
            None => writeln!(s, "- D-RMSE, {what}: {NA} (no ground-truth depth)"),
        };
    }
    let _ = writeln!(s);
    let t = &m.timing;
    let _ = writeln!(
        s,
        "## Timing (mean per clip)\n\nencoder {:.3} s, decoder (future frames) {:.3} s, \
         decoder (context frames) {} s\n",
        t.encoder_s,
        t.decoder_s,
        opt(t.context_decoder_s, 3)
    );
}

fn sweep_table(s: &mut String, points: &[SweepPoint]) {
    let _ = writeln!(s, "## Quality against run time (sweep; model only)\n");
    let _ = writeln!(
        s,
        "| knob | value | backend | T_f | input | PSNR (dB) | SSIM | LPIPS | rot err (deg) | \
         encoder (s) | decoder (s) | total (s/clip) | Pareto |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|---|"
    );
    for p in points {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {}x{} | {:.2} | {:.4} | {} | {} | {:.3} | {:.3} | {:.3} | {} |",
            p.knob.name(),
            p.value,
            p.backend,
            p.horizon,
            p.input_size[0],
            p.input_size[1],
            p.psnr,
            p.ssim,
            opt(p.lpips, 4),
            opt(p.rot_err_deg, 2),
            p.encoder_s,
            p.decoder_s,
            p.time_s,
            if p.pareto { "yes" } else { "" }
        );
    }
    let _ = writeln!(s);
}

fn clip_table(s: &mut String, clips: &[ClipMetrics]) {
    let _ = writeln!(
        s,
        "## Per clip (model)\n\n| clip | PSNR (dB) | SSIM | rot err (deg) | trans err (m) | \
         D-RMSE | encoder (s) | decoder (s) |\n|---|---|---|---|---|---|---|---|"
    );
    for c in clips {
        let Some(m) = c.methods.first() else { continue };
        let _ = writeln!(
            s,
            "| {} | {:.2} | {:.4} | {} | {} | {} | {:.3} | {:.3} |",
            c.clip,
            m.psnr,
            m.ssim,
            opt(m.rot_err_deg, 2),
            opt(m.trans_err, 3),
            opt(c.depth_rmse.as_ref().map(|d| d.rmse), 3),
            c.timing.encoder_s,
            c.timing.decoder_s
        );
    }
}

impl ClipMetrics {
    /// One line: the model's quality on this clip next to the time it cost.
    pub fn summary_line(&self) -> String {
        let model = self.method(Method::Model);
        format!(
            "{:<24} PSNR {:6.2} dB  SSIM {:.4}  | encoder {:.3} s + decoder {:.3} s",
            self.clip,
            model.map_or(f64::NAN, |s| s.psnr),
            model.map_or(f64::NAN, |s| s.ssim),
            self.timing.encoder_s,
            self.timing.decoder_s
        )
    }
}

/// The mean of every method (quality next to seconds per clip), the cross-frame table,
/// D-RMSE and the timing, as plain text.
pub fn summary(report: &Report) -> String {
    let mut s = String::new();
    let Some(mean) = &report.mean else {
        return "no clip was evaluated\n".into();
    };
    // Windows of one clip (`clip@start`, `eval --stride`) are not independent clips.
    let clips: std::collections::BTreeSet<&str> = report
        .clips
        .iter()
        .map(|c| c.clip.split('@').next().unwrap_or(&c.clip))
        .collect();
    let samples = if clips.len() == report.clips_evaluated {
        format!("{} clips", report.clips_evaluated)
    } else {
        let plural = if clips.len() == 1 { "" } else { "s" };
        format!(
            "{} windows of {} clip{plural}",
            report.clips_evaluated,
            clips.len()
        )
    };
    let _ = writeln!(
        s,
        "mean over {samples} (future frames, T_f = {}):",
        report.future_frames
    );
    for m in &mean.methods {
        let _ = writeln!(
            s,
            "  {:<10} PSNR {:6.2} dB  SSIM {:.4}  LPIPS {:>6}  rot {:>6} deg  trans {:>7} m  \
             AUC@30 {:>5}  | {:.3} s/clip",
            m.method.label(),
            m.psnr,
            m.ssim,
            opt(m.lpips, 4),
            opt(m.rot_err_deg, 2),
            opt(m.trans_err, 3),
            opt(m.camera_auc30.map(|a| a * 100.0), 1),
            m.time_s
        );
    }
    if let Some(c) = &mean.context {
        let _ = writeln!(
            s,
            "  context frames from the other frames' Gaussians: PSNR {:.2} dB  SSIM {:.4}",
            c.psnr, c.ssim
        );
    }
    if let Some(c) = &mean.context {
        for p in &c.pairs {
            let _ = writeln!(
                s,
                "    {}→{}: PSNR {:.2} dB  SSIM {:.4}",
                p.source, p.target, p.psnr, p.ssim
            );
        }
    }
    if let Some(d) = &mean.depth_rmse {
        let _ = writeln!(
            s,
            "  D-RMSE of the rendered future depth ({} alignment, truth {}): {:.3} m",
            d.alignment, d.source, d.rmse
        );
    }
    if let Some(d) = &mean.context_depth_rmse {
        let _ = writeln!(
            s,
            "  D-RMSE of the depth head on context frames ({} alignment): {:.3} m",
            d.alignment, d.rmse
        );
    }
    if let Some(motion) = &mean.motion {
        let _ = writeln!(s, "{}", motion.summary_line());
    }
    let _ = writeln!(
        s,
        "  time per clip: encoder {:.3} s, decoder {:.3} s",
        mean.timing.encoder_s, mean.timing.decoder_s
    );
    s
}
