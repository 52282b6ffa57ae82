//! `envision4d train --config FILE [--dry-run]`.

use crate::backend_choice::BackendChoice;
use crate::InputError;
use anyhow::Result;
use clap::Args;
use envision4d_train::freeze::ParamSplit;
use envision4d_train::step::build_model;
use envision4d_train::Trainer;
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct TrainArgs {
    /// Training config (TOML; see configs/waymo.toml, configs/synth-tiny.toml).
    #[arg(long)]
    config: PathBuf,
    /// Validate the config, resolve every setting, build the model and optimiser, print the
    /// settings and the trainable/frozen parameter counts, and stop.
    #[arg(long)]
    dry_run: bool,
    #[arg(long, value_enum, default_value_t = BackendChoice::Cpu)]
    backend: BackendChoice,
}

pub fn run(args: TrainArgs) -> Result<()> {
    let cfg = envision4d_train::load(&args.config).map_err(|e| InputError(e.to_string()))?;
    let device = args.backend.device().autodiff();
    if args.dry_run {
        // Resolve and build even when this build cannot train the config yet, so the
        // paper config can be inspected too.
        let model = build_model(&cfg, &device).map_err(|e| InputError(e.to_string()))?;
        let split = ParamSplit::new(&model, &cfg.freeze);
        println!(
            "# resolved settings ({})\n{}",
            args.config.display(),
            cfg.to_toml()
        );
        println!(
            "parameters: {} trainable, {} frozen ({} total) on {:?}",
            split.trainable_count,
            split.frozen_count,
            split.trainable_count + split.frozen_count,
            args.backend
        );
        if let Err(e) = Trainer::new(cfg, &device) {
            println!("note: this build cannot run this config yet: {e}");
        }
        return Ok(());
    }
    Trainer::new(cfg, &device).map_err(|e| InputError(e.to_string()))?;
    Err(InputError("training runs (progress, logs, checkpoints, resume) are not in this build yet: use --dry-run".into()).into())
}
