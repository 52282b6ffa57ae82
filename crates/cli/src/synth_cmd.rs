//! `envision4d synth`: render synthetic driving clips with exact ground truth
//! (frames, cameras, z-depth, scene flow, dynamic mask, object tracks) into a folder.

use crate::InputError;
use anyhow::{Context, Result};
use clap::Args;
use envision4d_data::synth::footprint::{footprint, Footprint, PATCH_PX};
use envision4d_data::synth::{
    render_clip, write_clip, write_nuscenes_scenes, write_storm_scene, Preset, SynthConfig,
    DEFAULT_SUPERSAMPLE,
};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::PathBuf;
use std::time::Instant;

/// On-disk layout of the written clips.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum SynthLayout {
    /// Ours: DIR/clip_000000/{rgb,depth,flow,dynamic_mask,instance}, cameras.json, ...
    Synth,
    /// STORM's preprocessed Waymo: `DIR/<split>/<scene:03d>/` with `images`, `intrinsics`,
    /// `cam_to_ego`, `ego_to_world`, `cam_to_world`, `depth_flows_4` and `lidar`, LiDAR-like
    /// depth included.
    StormWaymo,
    /// The official nuScenes tree: DIR/samples/{CAM_FRONT,LIDAR_TOP}, DIR/v1.0-*/ tables;
    /// clip i becomes the i-th scene of an official split (--split), LiDAR sweeps included.
    Nuscenes,
}

#[derive(Args, Debug)]
pub struct SynthArgs {
    /// Output folder; clips go to `DIR/clip_000000`, ... (or `DIR/<split>/000`, ... with
    /// --layout storm-waymo).
    #[arg(long)]
    out: PathBuf,
    /// Layout to write.
    #[arg(long, value_enum, default_value_t = SynthLayout::Synth)]
    layout: SynthLayout,
    /// Split of the storm-waymo layout (a folder: default training) or of nuscenes (an
    /// official split: mini_train (default), mini_val, train, val).
    #[arg(long)]
    split: Option<String>,
    /// First scene of the split to write (storm-waymo: folder number; nuscenes: position in
    /// the split's scene list), to add scenes to a split over several runs.
    #[arg(long, default_value_t = 0)]
    first_scene: usize,
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
    /// winding, look-around, stopped-pan; the motion suite: motion-constant,
    /// motion-accelerating, motion-turning, motion-crossing, motion-stop-and-go.
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

/// The world stream of scene `scene` of split `split` (FNV-1a of the name, then the number).
fn scene_stream(split: &str, scene: usize) -> u64 {
    let h = split.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
        (h ^ b as u64).wrapping_mul(0x0000_0100_0000_01b3)
    });
    h.wrapping_add(scene as u64)
}

/// A split is one folder name, never a path.
fn valid_split_name(s: &str) -> bool {
    !s.is_empty()
        && s.chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
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
    let split = args.split.clone().unwrap_or_else(|| {
        match args.layout {
            SynthLayout::Nuscenes => "mini_train",
            _ => "training",
        }
        .into()
    });
    match args.layout {
        SynthLayout::StormWaymo if !valid_split_name(&split) => {
            return Err(InputError(format!(
                "--split {split:?}: need a plain folder name (letters, digits, '_' or '-')"
            ))
            .into())
        }
        SynthLayout::Nuscenes => {
            let scenes = envision4d_data::layout::nuscenes_tables::split_scenes(&split)
                .ok_or_else(|| {
                    InputError(format!(
                        "--split {split:?}: nuScenes splits are mini_train, mini_val, train, val, test"
                    ))
                })?;
            if args.first_scene + args.clips > scenes.len() {
                return Err(InputError(format!(
                    "--clips {} from --first-scene {}: split {split} has {} scenes",
                    args.clips,
                    args.first_scene,
                    scenes.len()
                ))
                .into());
            }
        }
        _ => {}
    }
    let mut sizes = Vec::with_capacity(args.clips);
    for i in 0..args.clips {
        // Our layout keeps clip i's world at stream i; a real layout's scene draws from a
        // stream of its split and scene number, so two splits written with one --seed never
        // hold the same world and --first-scene continues instead of repeating.
        let stream = match args.layout {
            SynthLayout::Synth => i as u64,
            _ => scene_stream(&split, args.first_scene + i),
        };
        let clip = render_clip(&cfg, stream, || bar.inc(1))?;
        sizes.push(footprint(&clip));
        let dir = match args.layout {
            SynthLayout::Synth => args.out.join(format!("clip_{i:06}")),
            SynthLayout::StormWaymo => args
                .out
                .join(&split)
                .join(format!("{:03}", args.first_scene + i)),
            SynthLayout::Nuscenes => args.out.clone(),
        };
        match args.layout {
            SynthLayout::Synth => write_clip(&dir, &clip),
            SynthLayout::StormWaymo => write_storm_scene(&dir, &clip),
            SynthLayout::Nuscenes => {
                write_nuscenes_scenes(&dir, &split, args.first_scene + i, &[clip])
            }
        }
        .with_context(|| format!("writing clip {i} into {}", dir.display()))?;
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
    report_footprint(&sizes);
    Ok(())
}

/// Prints how large the moving objects are on screen, the measurement that sets a motion
/// experiment's resolution (`synth::footprint`).
fn report_footprint(sizes: &[Footprint]) {
    let n: usize = sizes.iter().map(|f| f.sightings).sum();
    if n == 0 {
        eprintln!("no moving object is visible in these clips");
        return;
    }
    let mean = |f: fn(&Footprint) -> f64| {
        sizes.iter().map(|s| f(s) * s.sightings as f64).sum::<f64>() / n as f64
    };
    let px = mean(|f| f.mean_px);
    eprintln!(
        "moving objects: {n} sightings, mean {px:.0} px = {:.2} patches of {PATCH_PX}x{PATCH_PX} \
         (median per clip {:.0} px), box {:.1}x{:.1} px",
        px / (PATCH_PX * PATCH_PX) as f64,
        mean(|f| f.median_px),
        mean(|f| f.mean_box.0),
        mean(|f| f.mean_box.1),
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Guards the real-layout world streams: the same scene number in two splits, and two
    /// scene numbers in one split, are different worlds (training and evaluation scenes
    /// written with one --seed were identical).
    #[test]
    fn scene_streams_differ_across_splits_and_scenes() {
        let a = scene_stream("training", 0);
        assert_ne!(a, scene_stream("validation", 0));
        assert_ne!(a, scene_stream("training", 1));
        assert_ne!(scene_stream("mini_train", 0), scene_stream("mini_val", 0));
        assert_eq!(a, scene_stream("training", 0));
    }

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
