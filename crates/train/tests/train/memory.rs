//! `train --set` overrides and the memory model's counts.

use crate::common::config_path;

/// Guards `train --set`: a dotted key reaches a nested table (`model.dino.depth`), a value is
/// TOML (arrays, numbers, booleans) or else a bare string, the result is validated like the
/// file, and a malformed override is a parse error naming it.
#[test]
fn set_overrides_reach_nested_keys() {
    use envision4d_train::load::load_with_overrides;
    let sets = |v: &[&str]| v.iter().map(|s| s.to_string()).collect::<Vec<_>>();
    let c = load_with_overrides(
        &config_path("waymo.toml"),
        &sets(&[
            "optim.batch_size=1",
            "model.preset=tiny",
            "model.dino.depth=3",
            "model.image_size=[112,168]",
            "run.recompute_frozen_blocks=false",
        ]),
    )
    .unwrap();
    assert_eq!(c.optim.batch_size, 1);
    assert_eq!((c.model.embed_dim, c.model.dino.depth), (64, 3));
    assert_eq!(c.model.image_size, [112, 168]);
    assert!(!c.run.recompute_frozen_blocks);
    let err = load_with_overrides(&config_path("waymo.toml"), &sets(&["optim.batch_size"]))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("optim.batch_size") && err.contains("KEY=VALUE"),
        "{err}"
    );
    let err = load_with_overrides(&config_path("waymo.toml"), &sets(&["optim.batch_size=0"]))
        .unwrap_err()
        .to_string();
    assert!(err.contains("batch_size"), "{err}");
}

/// Guards the memory model's counts (what the fitted coefficients multiply) on the paper's
/// config at batch 1, computed by hand: 2 context frames of 1 + 4 + 25·37 = 930 tokens; kept
/// are the 4 temporal blocks (4·1024 channels), recomputed the frozen frame and global blocks
/// after the first temporal layer (layers 5..23: 2·19·1024 channels); DPT maps: depth 2 +
/// Gaussians 2 + motion 2·3 at 350·518 pixels and 256 channels; 4 rendered frames.
#[test]
fn memory_counts_of_the_paper_config() {
    let mut c = envision4d_train::load(&config_path("waymo.toml")).unwrap();
    c.optim.batch_size = 1;
    let n = envision4d_train::memory::counts(&c);
    let tokens = 2.0 * 930.0;
    assert_eq!(n.block_token_channels, tokens * 4.0 * 1024.0);
    assert_eq!(n.recomputed_token_channels, tokens * 38.0 * 1024.0);
    assert_eq!(n.dpt_pixel_channels, 10.0 * 350.0 * 518.0 * 256.0);
    assert_eq!(n.rendered_pixels, 4.0 * 350.0 * 518.0);
    assert_eq!(n.lpips_pixels, n.rendered_pixels);
    c.run.recompute_frozen_blocks = false;
    let kept = envision4d_train::memory::counts(&c);
    assert_eq!(kept.block_token_channels, tokens * 42.0 * 1024.0);
    assert_eq!(kept.recomputed_token_channels, 0.0);
    c.loss.lambda_lpips = 0.0;
    assert_eq!(envision4d_train::memory::counts(&c).lpips_pixels, 0.0);
    // Global blocks trainable, frame blocks frozen: frame block 0 runs before anything that
    // trains, so 23 frame + 24 global + 4 temporal blocks keep their activations.
    c.freeze
        .retain(|g| *g != envision4d_train::config::FreezeGroup::GlobalBlocks);
    let global = envision4d_train::memory::counts(&c);
    assert_eq!(global.block_token_channels, tokens * 51.0 * 1024.0);
}

/// Guards the GPU estimate's kept tile lists, which the CPU-fitted terms cannot see: the
/// paper's config at batch 1 renders 4 views of at most 2 context frames' per-pixel
/// Gaussians, each 64 bytes plus 2.3 intersections of 4, and 8 bytes per pixel of where it
/// stopped; the device estimate adds them, and
/// `run.recompute_raster_bins` (settable with `--set`) drops them and switches the trainer's
/// rasterizer to binning again in the backward.
#[test]
fn device_estimate_holds_the_kept_raster_bins() {
    use envision4d_splat::BackwardBins;
    use envision4d_train::load::load_with_overrides;
    use envision4d_train::memory::{raster_bins, StepMemory};
    use envision4d_train::step::raster_config;
    let set = |v: &[&str]| {
        let v: Vec<String> = v.iter().map(|s| s.to_string()).collect();
        load_with_overrides(&config_path("waymo.toml"), &v).unwrap()
    };
    let c = set(&["optim.batch_size=1"]);
    let want = 4.0 * 350.0 * 518.0 * (2.0 * (64.0 + 4.0 * 2.3) + 8.0);
    assert!(
        (raster_bins(&c) - want).abs() <= 1e-9 * want,
        "{}",
        raster_bins(&c)
    );
    assert_eq!(raster_config(&c).backward_bins, BackwardBins::Keep);
    let m = StepMemory {
        runtime: 5.0,
        parameters: 7.0,
        lpips_weights: 0.0,
        gradients: 0.0,
        optimizer: 0.0,
        teacher_first: 0.0,
        teacher_later: 0.0,
        activations: 11.0,
        raster_bins: 13.0,
        counts: Default::default(),
    };
    assert_eq!((m.later_steps(), m.device_tensors()), (23.0, 31.0));
    let r = set(&["optim.batch_size=1", "run.recompute_raster_bins=true"]);
    assert_eq!(raster_bins(&r), 0.0);
    assert_eq!(raster_config(&r).backward_bins, BackwardBins::Recompute);
    // The switch is a `[run]` key: a resume may change it.
    assert_eq!(
        envision4d_train::checkpoint::resume_identity(&c),
        envision4d_train::checkpoint::resume_identity(&r)
    );
}
