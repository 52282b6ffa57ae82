//! Rasterizing the time steps: each context view from the other frames' Gaussians moved to
//! its time (self-exclusive, as the release renders at test time) and each future view from
//! all of them; colour, expected depth, lane-shifted views and the Gaussians as 3DGS PLY.

use super::colormap::depth_colors;
use super::host;
use super::outputs::{lane_suffix, FileKind, OutDir, Output, Plan, Role, Step};
use super::poses::{lane_shifted, HostCameras};
use crate::image_out::{write_gray, write_rgb};
use anyhow::{Context, Result};
use burn::tensor::Device;
use envision4d_model::adapter::{AdaptedGaussians, Exclusion};
use envision4d_model::scene::gaussians_for;
use envision4d_splat::ply::{write_ply, PlyGaussians, RenderParams};
use envision4d_splat::{render, Cameras, Gaussians, RasterConfig};

const VIEWS_DIR: &str = "views";
const DEPTH_DIR: &str = "depth";
const LANE_DIR: &str = "lane_shift";
const GAUSSIANS_DIR: &str = "gaussians";
/// The release renders every view, context ones included, without the frame's own Gaussians.
const EXCLUSION: Exclusion = Exclusion::SelfExclusive;

/// The views of one time step: the predicted camera, then one per lane shift (future only).
struct StepViews {
    names: Vec<String>,
    viewmats: Vec<[[f64; 4]; 4]>,
}

fn step_views(step: &Step, cams: &HostCameras, plan: &Plan) -> StepViews {
    let base = cams.viewmats[step.index];
    let mut v = StepViews {
        names: vec![step.name.clone()],
        viewmats: vec![base],
    };
    if step.role == Role::Future {
        for &s in &plan.lane_shifts {
            v.names.push(format!("{}_{}", step.name, lane_suffix(s)));
            v.viewmats.push(lane_shifted(&base, s));
        }
    }
    v
}

/// The steps that must be rasterized: all of them for views, depth and PLY; only the future
/// ones when lane shifts are all that is asked.
pub fn steps_to_render(plan: &Plan) -> Vec<Step> {
    let all = plan.wants(Output::Views) || plan.wants(Output::Depth) || plan.wants(Output::Ply);
    plan.steps()
        .into_iter()
        .filter(|s| all || (s.role == Role::Future && !plan.lane_shifts.is_empty()))
        .collect()
}

/// Renders and writes every step of [`steps_to_render`]; returns the number of views rendered.
pub fn render_steps(
    adapted: &AdaptedGaussians,
    cams: &HostCameras,
    plan: &Plan,
    out: &mut OutDir,
    device: &Device,
    on_step: impl Fn(),
) -> Result<usize> {
    let [h, w] = plan.image_size;
    let px = h * w;
    let raster = RasterConfig::default();
    let mut rendered = 0;
    for step in steps_to_render(plan) {
        let g = gaussians_for(adapted, 0, step.index, EXCLUSION);
        let views = step_views(&step, cams, plan);
        let ks = vec![cams.ks[step.index]; views.viewmats.len()];
        let cameras = Cameras::from_host(&views.viewmats, &ks, w as u32, h as u32, device);
        let r =
            render(&g, &cameras, &raster).with_context(|| format!("rendering {}", step.name))?;
        let (rgb, depth, alpha) = (host(r.rgb)?, host(r.depth)?, host(r.alpha)?);
        rendered += views.names.len();

        if plan.wants(Output::Views) {
            write_color(
                out,
                VIEWS_DIR,
                &step.name,
                FileKind::Rgb,
                &step,
                w,
                h,
                &rgb[..px * 3],
            )?;
        }
        if plan.wants(Output::Depth) {
            let exr = out.path(DEPTH_DIR, &format!("{}.exr", step.name))?;
            write_gray(&exr, w, h, &depth[..px])?;
            out.record(&exr, FileKind::Depth, Some(&step));
            let png = out.path(DEPTH_DIR, &format!("{}.png", step.name))?;
            write_rgb(&png, w, h, &depth_colors(&depth[..px], &alpha[..px]))?;
            out.record(&png, FileKind::DepthColor, Some(&step));
        }
        for (v, name) in views.names.iter().enumerate().skip(1) {
            let view = &rgb[v * px * 3..(v + 1) * px * 3];
            write_color(
                out,
                LANE_DIR,
                name,
                FileKind::LaneShiftRgb,
                &step,
                w,
                h,
                view,
            )?;
        }
        if plan.wants(Output::Ply) {
            write_step_ply(&g, &step, out)?;
        }
        on_step();
    }
    Ok(rendered)
}

/// `dir/name.png` (8-bit, clamped) and `dir/name.exr` (linear float).
#[allow(clippy::too_many_arguments)]
fn write_color(
    out: &mut OutDir,
    dir: &str,
    name: &str,
    kind: FileKind,
    step: &Step,
    w: usize,
    h: usize,
    rgb: &[f32],
) -> Result<()> {
    for ext in ["png", "exr"] {
        let path = out.path(dir, &format!("{name}.{ext}"))?;
        write_rgb(&path, w, h, rgb)?;
        out.record(&path, kind, Some(step));
    }
    Ok(())
}

/// Writes the step's Gaussians as standard 3DGS PLY (DC colour, logit opacity, log scales).
///
/// The rotation is written exactly as our rasterizer reads it: the adapter's xyzw quaternion
/// goes to `rot_0..3`, which every 3DGS tool (and gsplat, and `envision4d splat`) reads as
/// wxyz. That is the release's convention, so a splat viewer shows what the model renders.
/// Gaussians the rasterizer culls anyway (non-finite values) or that a PLY cannot store (a
/// scale <= 0 has no log) are left out, with a note.
fn write_step_ply(g: &Gaussians, step: &Step, out: &mut OutDir) -> Result<()> {
    let (means, quats, scales) = (
        host(g.means.clone())?,
        host(g.quats.clone())?,
        host(g.scales.clone())?,
    );
    let (opac, colors) = (host(g.opacities.clone())?, host(g.colors.clone())?);
    let mut p = RenderParams::default();
    let mut dropped = 0usize;
    for i in 0..opac.len() {
        let (m, q, s, c) = (
            &means[3 * i..3 * i + 3],
            &quats[4 * i..4 * i + 4],
            &scales[3 * i..3 * i + 3],
            &colors[3 * i..3 * i + 3],
        );
        let finite =
            m.iter().chain(q).chain(s).chain(c).all(|v| v.is_finite()) && opac[i].is_finite();
        if !finite || s.iter().any(|&v| v <= 0.0) {
            dropped += 1;
            continue;
        }
        p.means.extend_from_slice(m);
        p.quats.extend_from_slice(q);
        p.scales.extend_from_slice(s);
        p.colors.extend_from_slice(c);
        p.opacities.push(opac[i]);
    }
    if dropped > 0 {
        eprintln!(
            "note: {}: left out {dropped} Gaussians that cannot be stored or rendered",
            step.name
        );
    }
    let ply = PlyGaussians::from_render_params(&p).context("converting Gaussians to PLY")?;
    let path = out.path(GAUSSIANS_DIR, &format!("{}.ply", step.name))?;
    write_ply(&path, &ply).with_context(|| format!("writing {}", path.display()))?;
    out.record(&path, FileKind::Gaussians, Some(step));
    Ok(())
}
