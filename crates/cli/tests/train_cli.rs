//! `envision4d train` end to end on a generated mini dataset: a short run writes its log and
//! checkpoints, `--resume` continues it, and bad input is an input error (exit 2) naming
//! the key, value or path.

mod common;

use common::{bin, text, write_config};

/// Guards the run command's plumbing: `--stop-at` then `--resume` reach the configured
/// iterations with one log record per step, checkpoints on disk and the final model written.
#[test]
fn short_run_then_resume() {
    let tmp = tempfile::tempdir().unwrap();
    let data = tmp.path().join("data");
    let synth = bin(
        &[
            "synth",
            "--out",
            data.to_str().unwrap(),
            "--clips",
            "3",
            "--frames",
            "4",
            "--size",
            "56x84",
            "--supersample",
            "1",
        ],
        tmp.path(),
    );
    assert!(synth.status.success(), "{}", text(&synth));
    let out = tmp.path().join("run");
    let cfg = write_config(tmp.path(), &data, &out, 3);
    let c = cfg.to_str().unwrap();
    let first = bin(&["train", "--config", c, "--stop-at", "2"], tmp.path());
    assert!(first.status.success(), "{}", text(&first));
    let second = bin(
        &["train", "--config", c, "--resume", out.to_str().unwrap()],
        tmp.path(),
    );
    assert!(second.status.success(), "{}", text(&second));
    assert!(
        text(&second).contains("trained 3 steps"),
        "{}",
        text(&second)
    );
    let log = std::fs::read_to_string(out.join("log.jsonl")).unwrap();
    let steps = log
        .lines()
        .filter(|l| l.contains("\"kind\":\"step\""))
        .count();
    assert_eq!(steps, 3, "{log}");
    assert!(out.join("model.safetensors").is_file());
    assert!(out.join("checkpoints/step-00000003/state.json").is_file());
}

/// Guards clear errors: a config typo names the key, an unknown `--devices` entry names
/// itself, collectives asked of CPU devices name the fix, a missing data root names the path; all exit with code 2.
#[test]
fn bad_input_is_exit_2_naming_the_problem() {
    let tmp = tempfile::tempdir().unwrap();
    let missing = tmp.path().join("no-such-data");
    let cfg = write_config(tmp.path(), &missing, &tmp.path().join("run"), 3);
    let c = cfg.to_str().unwrap();
    let typo = tmp.path().join("typo.toml");
    std::fs::write(
        &typo,
        std::fs::read_to_string(&cfg)
            .unwrap()
            .replace("batch_size", "batch_sise"),
    )
    .unwrap();
    let o = bin(
        &["train", "--config", typo.to_str().unwrap(), "--dry-run"],
        tmp.path(),
    );
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("batch_sise"), "{}", text(&o));
    let o = bin(
        &["train", "--config", c, "--devices", "cpu,tpu"],
        tmp.path(),
    );
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("tpu"), "{}", text(&o));
    // Burn's collectives exist on CUDA only: asking for them on CPU devices is refused
    // before training starts (cubecl would panic mid-step).
    let o = bin(
        &[
            "train",
            "--config",
            c,
            "--devices",
            "cpu,cpu",
            "--grad-reduce",
            "all-reduce",
        ],
        tmp.path(),
    );
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("--grad-reduce gather"), "{}", text(&o));
    let o = bin(&["train", "--config", c], tmp.path());
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("no-such-data"), "{}", text(&o));
}
