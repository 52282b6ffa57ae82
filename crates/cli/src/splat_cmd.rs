//! `envision4d splat`: render a 3DGS PLY file from a JSON camera.

use crate::backend_choice::BackendChoice;
use crate::image_out::{write_gray, write_rgb, ImageFormat};
use crate::InputError;
use anyhow::{Context, Result};
use burn::tensor::Tensor;
use clap::Args;
use envision4d_splat::camera_json::read_camera_json;
use envision4d_splat::ply::read_ply;
use envision4d_splat::{render, AlphaClamp, Cameras, Gaussians, RasterConfig};
use std::path::PathBuf;
use std::time::Instant;

#[derive(Args, Debug)]
pub struct SplatArgs {
    /// 3DGS PLY file (INRIA layout: x y z f_dc_* opacity scale_* rot_*).
    #[arg(long)]
    ply: PathBuf,
    /// Camera JSON: {"width","height","fx","fy","cx","cy","world_to_camera":[[..4],[..4],[..4],[..4]]}.
    #[arg(long)]
    camera: PathBuf,
    /// Colour output: .png (8-bit, clamped) or .exr (linear float, unclamped).
    #[arg(long)]
    out: PathBuf,
    /// Expected depth (accumulated depth / alpha) as EXR (or 16-bit PNG, min-max normalised).
    #[arg(long)]
    depth: Option<PathBuf>,
    /// Accumulated alpha as EXR or PNG.
    #[arg(long)]
    alpha: Option<PathBuf>,
    /// Where to run.
    #[arg(long, value_enum, default_value_t = BackendChoice::Cpu)]
    backend: BackendChoice,
    /// Background colour behind the splats, as r,g,b in `[0, 1]` (default black).
    #[arg(long, value_parser = parse_rgb)]
    background: Option<[f64; 3]>,
    /// Which gsplat release's alpha clamp to reproduce.
    #[arg(long, value_enum, default_value_t = ClampChoice::Gsplat153)]
    alpha_clamp: ClampChoice,
}

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
enum ClampChoice {
    /// gsplat 1.5.3 (alpha <= 0.999), what Envision4D trained with.
    Gsplat153,
    /// later gsplat (alpha <= 0.99).
    GsplatHead,
}

fn parse_rgb(s: &str) -> Result<[f64; 3], String> {
    let parts: Vec<&str> = s.split(',').collect();
    if parts.len() != 3 {
        return Err(format!("expected r,g,b, got {s:?}"));
    }
    let mut rgb = [0.0; 3];
    for (slot, p) in rgb.iter_mut().zip(parts) {
        *slot = p
            .trim()
            .parse::<f64>()
            .map_err(|e| format!("bad colour component {p:?}: {e}"))?;
        if !slot.is_finite() {
            return Err(format!("colour component {p:?} is not finite"));
        }
    }
    Ok(rgb)
}

/// Prefixes an error with the file it concerns, unless the message already names it.
fn name_file(path: &std::path::Path, msg: String) -> String {
    let shown = path.display().to_string();
    if msg.contains(&shown) {
        msg
    } else {
        format!("{shown}: {msg}")
    }
}

pub fn run(args: SplatArgs) -> Result<()> {
    // Check every output path before the (possibly long) render.
    let out_format =
        ImageFormat::from_path(&args.out).map_err(|e| InputError(format!("--out: {e}")))?;
    for (flag, p) in [("--depth", &args.depth), ("--alpha", &args.alpha)] {
        if let Some(p) = p {
            ImageFormat::from_path(p).map_err(|e| InputError(format!("{flag}: {e}")))?;
        }
    }
    let ply = read_ply(&args.ply).map_err(|e| InputError(name_file(&args.ply, e.to_string())))?;
    let cam = read_camera_json(&args.camera)
        .map_err(|e| InputError(name_file(&args.camera, e.to_string())))?;
    cam.validate()
        .map_err(|e| InputError(format!("{}: {e}", args.camera.display())))?;
    let params = ply.to_render_params();
    let n = ply.len();

    let device = args.backend.device()?;
    let gaussians = Gaussians::from_host(
        params.means,
        params.quats,
        params.scales,
        params.opacities,
        params.colors,
        &device,
    )
    .map_err(|e| InputError(e.to_string()))?;
    let k = cam.k_matrix();
    let cameras = Cameras::from_host(&[cam.world_to_camera], &[k], cam.width, cam.height, &device);
    let config = RasterConfig {
        background: args.background,
        alpha_clamp: match args.alpha_clamp {
            ClampChoice::Gsplat153 => AlphaClamp::Gsplat153,
            ClampChoice::GsplatHead => AlphaClamp::GsplatHead,
        },
        ..Default::default()
    };

    let start = Instant::now();
    let out = render(&gaussians, &cameras, &config).map_err(|e| InputError(e.to_string()))?;
    let (w, h) = (cam.width as usize, cam.height as usize);
    let read = |t: Tensor<3>| -> Result<Vec<f32>> {
        t.into_data()
            .convert::<f32>()
            .try_into_vec::<f32>()
            .map_err(|e| anyhow::anyhow!("reading the render back: {e:?}"))
    };
    let rgb = out
        .rgb
        .reshape([h, w, 3])
        .into_data()
        .convert::<f32>()
        .try_into_vec::<f32>()
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let counts = out
        .meta
        .counts
        .into_data()
        .convert::<i64>()
        .try_into_vec::<i64>()
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let elapsed = start.elapsed();

    write_rgb(&args.out, w, h, &rgb).with_context(|| format!("writing {}", args.out.display()))?;
    if let Some(p) = &args.depth {
        write_gray(p, w, h, &read(out.depth)?)
            .with_context(|| format!("writing {}", p.display()))?;
    }
    if let Some(p) = &args.alpha {
        write_gray(p, w, h, &read(out.alpha)?)
            .with_context(|| format!("writing {}", p.display()))?;
    }
    println!(
        "rendered {n} Gaussians ({} visible, {} tile intersections) at {w}x{h} on {:?} in {:.1} ms -> {} ({out_format:?})",
        counts[0],
        counts[1],
        args.backend,
        elapsed.as_secs_f64() * 1e3,
        args.out.display()
    );
    Ok(())
}
