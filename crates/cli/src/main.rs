//! `envision4d`: the command-line program.
//!
//! Exit codes, the same for every subcommand and decided in one place ([`exit_code`]): 0
//! success, 2 the user's input (an unreadable or invalid file, key or argument), 1 anything
//! else (an internal failure, a failed write, a diverged run).

mod backend_choice;
mod demo_cmd;
mod eval_cmd;
mod image_out;
mod model_config;
mod plot;
mod reduce_choice;
mod render_cmd;
mod report;
mod splat_cmd;
mod synth_cmd;
mod train_cmd;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

#[derive(Parser, Debug)]
#[command(
    name = "envision4d",
    version,
    about = "Envision4D: pose-free 4D future prediction with Gaussian splatting"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Render a standard 3DGS PLY file from a camera (PNG or linear EXR).
    Splat(splat_cmd::SplatArgs),
    /// Render synthetic driving clips with exact ground truth (ray-traced).
    Synth(synth_cmd::SynthArgs),
    /// Run Envision4D on context frames and export its predictions (poses, depth, Gaussians, motion).
    Render(render_cmd::RenderArgs),
    /// Train Envision4D from a TOML config (`--dry-run` checks and summarises it).
    Train(train_cmd::TrainArgs),
    /// Score a checkpoint on held-out clips (future frames, poses, depth, baselines, timings).
    Eval(eval_cmd::EvalArgs),
    /// Generate a fresh synthetic clip, predict its future with the shipped model (or
    /// --checkpoint), score it against the truth and the baselines, and render it.
    Demo(demo_cmd::DemoArgs),
}

/// An error caused by the user's input (exit code 2) rather than by the program.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct InputError(pub String);

/// Burn creates a few tensors on its *default* device (e.g. a restored optimiser state before
/// it moves to the parameters' device); with wgpu compiled in that default is a GPU, which
/// would start a Vulkan driver in a CPU run (or fail without one). Default to the CPU backend
/// unless the user chose otherwise.
fn default_burn_device() {
    if std::env::var_os("BURN_DEVICE").is_none() {
        // SAFETY: called first thing in `main`, before any thread exists.
        unsafe { std::env::set_var("BURN_DEVICE", "flex") };
    }
}

fn main() -> ExitCode {
    // Off unless RUST_LOG asks (`RUST_LOG=warn`, `RUST_LOG=cubecl=debug`): the libraries'
    // own messages, for diagnosing a device; the program's output stays as it is otherwise.
    env_logger::Builder::from_env(env_logger::Env::default().default_filter_or("off")).init();
    envision4d_model::alloc::keep_freed_memory();
    default_burn_device();
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Splat(args) => splat_cmd::run(args),
        Command::Synth(args) => synth_cmd::run(args),
        Command::Render(args) => render_cmd::run(args),
        Command::Train(args) => train_cmd::run(args),
        Command::Eval(args) => eval_cmd::run(args),
        Command::Demo(args) => demo_cmd::run(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("error: {err:#}");
            exit_code(&err)
        }
    }
}

/// Exit code 2 when the error (or an error it wraps) is the user's input, 1 otherwise. The
/// crates' typed errors say which they are; `InputError` marks the CLI's own checks.
fn exit_code(err: &anyhow::Error) -> ExitCode {
    let input = err.chain().any(|e| {
        e.downcast_ref::<InputError>().is_some()
            || e.downcast_ref::<envision4d_train::TrainError>()
                .is_some_and(|t| t.is_input())
            || e.downcast_ref::<envision4d_eval::EvalError>()
                .is_some_and(|t| t.is_input())
            || e.downcast_ref::<envision4d_data::DataError>()
                .is_some_and(|t| t.is_input())
    });
    ExitCode::from(if input { 2 } else { 1 })
}
