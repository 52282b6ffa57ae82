//! `envision4d synth`: render synthetic driving clips with exact ground truth
//! (frames, cameras, z-depth, scene flow, dynamic mask, object tracks) into a folder.

use crate::InputError;
use anyhow::{Context, Result};
use clap::Args;
use envision4d_data::synth::{render_clip, write_clip, Preset, SynthConfig, DEFAULT_SUPERSAMPLE};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::PathBuf;
use std::time::Instant;

#[derive(Args, Debug)]
pub struct SynthArgs {
    /// Output folder; clips go to DIR/clip_000000, DIR/clip_000001, ...
    #[arg(long)]
    out: PathBuf,
    /// Number of clips.
    #[arg(long, default_value_t = 1)]
    clips: usize,
    /// Frames per clip (10 Hz).
    #[arg(long, default_value_t = 8)]
    frames: usize,
    /// Image size as HxW.
    #[arg(long, default_value = "350x518", value_parser = parse_size)]
    size: (usize, usize),
    /// urban, static, sharp-turn, fast-approach, far-small-movers, crossing-truck, low-light,
    /// winding, look-around, stopped-pan.
    #[arg(long, default_value = "urban", value_parser = parse_preset)]
    preset: Preset,
    /// World seed: the same seed gives byte-identical files.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Anti-aliasing: colour samples per pixel edge (n x n per pixel).
    #[arg(long, default_value_t = DEFAULT_SUPERSAMPLE)]
    supersample: usize,
}

/// Largest side accepted, to catch typos like 3500x5180 before hours of rendering.
const MAX_SIDE: usize = 8192;

fn parse_size(s: &str) -> Result<(usize, usize), String> {
    let (h, w) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("expected HxW, e.g. 350x518, got {s:?}"))?;
    let side = |v: &str| {
        v.trim()
            .parse::<usize>()
            .ok()
            .filter(|n| (1..=MAX_SIDE).contains(n))
            .ok_or_else(|| format!("bad side {v:?} in {s:?}: need an integer in 1..={MAX_SIDE}"))
    };
    Ok((side(h)?, side(w)?))
}

fn parse_preset(s: &str) -> Result<Preset, String> {
    Preset::from_name(s).ok_or_else(|| {
        let names: Vec<&str> = Preset::ALL.iter().map(|p| p.name()).collect();
        format!("unknown preset {s:?}; one of: {}", names.join(", "))
    })
}

pub fn run(args: SynthArgs) -> Result<()> {
    let cfg = SynthConfig {
        width: args.size.1,
        height: args.size.0,
        frames: args.frames,
        preset: args.preset,
        seed: args.seed,
        supersample: args.supersample,
    };
    cfg.validate().map_err(|e| InputError(e.to_string()))?;
    if args.clips == 0 {
        return Err(InputError("--clips must be at least 1".into()).into());
    }
    if args.out.is_file() {
        return Err(InputError(format!(
            "--out {} is a file, not a folder",
            args.out.display()
        ))
        .into());
    }
    std::fs::create_dir_all(&args.out).map_err(|e| {
        InputError(format!(
            "cannot create output folder {}: {e}",
            args.out.display()
        ))
    })?;

    let bar = ProgressBar::new((args.clips * args.frames) as u64);
    if let Ok(style) =
        ProgressStyle::with_template("{bar:40} {pos}/{len} frames  {elapsed_precise} (eta {eta})")
    {
        bar.set_style(style);
    }
    let start = Instant::now();
    for i in 0..args.clips {
        let clip = render_clip(&cfg, i as u64, || bar.inc(1))?;
        let dir = args.out.join(format!("clip_{i:06}"));
        write_clip(&dir, &clip).with_context(|| format!("writing clip {}", dir.display()))?;
    }
    bar.finish_and_clear();
    let secs = start.elapsed().as_secs_f64();
    eprintln!(
        "wrote {} clips x {} frames ({}x{}, preset {}, seed {}, supersample {}) to {} in {secs:.1} s ({:.3} s/frame)",
        args.clips,
        args.frames,
        cfg.height,
        cfg.width,
        cfg.preset.name(),
        cfg.seed,
        cfg.supersample,
        args.out.display(),
        secs / (args.clips * args.frames) as f64
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Guards argument parsing: sizes are HxW with sane bounds; unknown presets list names.
    #[test]
    fn parses_size_and_preset() {
        assert_eq!(parse_size("350x518"), Ok((350, 518)));
        assert!(parse_size("350").is_err());
        assert!(parse_size("0x5").is_err());
        assert!(parse_size("10x99999").is_err());
        assert_eq!(parse_preset("low-light"), Ok(Preset::LowLight));
        assert!(parse_preset("night")
            .unwrap_err()
            .contains("crossing-truck"));
    }
}
