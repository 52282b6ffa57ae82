//! Per-pixel motion of the context frames, from the predicted displacements: scene flow to the
//! next timestamp (world axes, scene units, not divided by the frame interval, like the
//! synthetic ground truth) and the dynamic mask `|flow| > threshold`.

use super::colormap::flow_colors;
use super::host;
use super::outputs::{FileKind, OutDir, Plan, Step};
use crate::image_out::write_rgb;
use anyhow::{Context, Result};
use envision4d_data::exr_io::{write_xyz, FloatMap};
use envision4d_model::adapter::AdaptedGaussians;
use envision4d_model::motion::target_slot;

/// Sub-folder of the motion maps.
const MOTION_DIR: &str = "motion";
/// 8-bit mask values, as in the synthetic ground truth's `dynamic_mask/*.png`.
const MASK_ON: u8 = u8::MAX;
const MASK_OFF: u8 = 0;

/// Flow of context frame `step` to the next timestamp, `[H·W·3]` row-major (Gaussian `g` of a
/// context frame is pixel `g = y·W + x`). `None` when there is no next timestamp.
pub fn flow_to_next(
    adapted: &AdaptedGaussians,
    step: &Step,
    total: usize,
) -> Result<Option<Vec<f32>>> {
    let i = step.index;
    if i + 1 >= total {
        return Ok(None);
    }
    let [_, _, _, g, _] = adapted.motions.dims();
    let slot = target_slot(i, i + 1);
    let d = adapted
        .motions
        .clone()
        .slice([0..1, i..i + 1, slot..slot + 1, 0..g, 0..3]);
    Ok(Some(host(d)?))
}

/// 0/255 per pixel: displacement norm above `threshold`.
pub fn dynamic_mask(flow: &[f32], threshold: f64) -> Vec<u8> {
    flow.chunks_exact(3)
        .map(|d| {
            let n = d
                .iter()
                .map(|&v| (v as f64) * (v as f64))
                .sum::<f64>()
                .sqrt();
            if n > threshold {
                MASK_ON
            } else {
                MASK_OFF
            }
        })
        .collect()
}

/// Writes `motion/<step>_dynamic.png`, `_flow.exr` and `_flow.png` for every context frame;
/// returns how many frames were written.
pub fn write_motion_maps(
    adapted: &AdaptedGaussians,
    plan: &Plan,
    out: &mut OutDir,
    on_frame: impl Fn(),
) -> Result<usize> {
    let [h, w] = plan.image_size;
    let mut written = 0;
    for step in plan.steps().iter().take(plan.context) {
        let Some(flow) = flow_to_next(adapted, step, plan.total)? else {
            continue;
        };
        let mask_path = out.path(MOTION_DIR, &format!("{}_dynamic.png", step.name))?;
        let png = envision4d_data::frame::encode_png(
            w,
            h,
            image::ExtendedColorType::L8,
            &dynamic_mask(&flow, plan.dynamic_threshold),
        )
        .map_err(|e| anyhow::anyhow!("encoding {}: {e}", mask_path.display()))?;
        envision4d_data::atomic::write_bytes(&mask_path, &png)
            .with_context(|| format!("writing {}", mask_path.display()))?;
        out.record(&mask_path, FileKind::DynamicMask, Some(step));

        let exr_path = out.path(MOTION_DIR, &format!("{}_flow.exr", step.name))?;
        let colors = flow_colors(&flow, plan.dynamic_threshold as f32);
        let map = FloatMap {
            width: w,
            height: h,
            channels: 3,
            data: flow,
        };
        write_xyz(&exr_path, &map).with_context(|| format!("writing {}", exr_path.display()))?;
        out.record(&exr_path, FileKind::SceneFlow, Some(step));

        let png_path = out.path(MOTION_DIR, &format!("{}_flow.png", step.name))?;
        write_rgb(&png_path, w, h, &colors)?;
        out.record(&png_path, FileKind::SceneFlowColor, Some(step));
        written += 1;
        on_frame();
    }
    Ok(written)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Guards the mask threshold: strictly above is dynamic, at or below is static.
    #[test]
    fn mask_threshold_is_strict() {
        let flow = [0.0, 0.0, 0.0, 0.5, 0.0, 0.0, 0.0, 0.0, 0.75];
        assert_eq!(dynamic_mask(&flow, 0.5), vec![MASK_OFF, MASK_OFF, MASK_ON]);
    }
}
