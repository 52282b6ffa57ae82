//! The motion benchmark's script end to end, a few steps of everything (`SMOKE=1`): the
//! suite's data, stage 1, three motion models in stage 2, an evaluation per motion type with
//! the motion metrics, and the table. Guards `scripts/motion_bench.sh` and
//! `scripts/motion_table.py` against rotting while the full benchmark stays out of CI.

#[path = "../../../tests/support/paths.rs"]
mod paths;

use std::path::PathBuf;
use std::process::Command;

fn repo(path: &str) -> PathBuf {
    paths::manifest_dir().join("../..").join(path)
}

/// Guards the benchmark pipeline: every stage runs with the binary under test, each
/// evaluation of a suite preset reports scene-flow EPE and mask IoU, the trained motion-off
/// variant predicts no motion (relative EPE 1), and the table has a block per motion type
/// with a row per variant.
#[test]
fn motion_bench_smoke_runs_every_stage() {
    let dir = tempfile::tempdir().unwrap();
    let variants = "cml linear-velocity motion-off";
    let out = Command::new("bash")
        .arg(repo("scripts/motion_bench.sh"))
        .env("SMOKE", "1")
        .env("MOTION_ROOT", dir.path())
        .env("ENVISION4D", env!("CARGO_BIN_EXE_envision4d"))
        .env("VARIANTS", variants)
        .output()
        .expect("run bash");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let runs = dir.path().join("runs/motion");
    for v in variants.split(' ') {
        let path = runs.join(format!("{v}-s0/eval-motion-turning/metrics.json"));
        let json: serde_json::Value =
            serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
        let motion = &json["mean"]["motion"];
        assert!(motion["epe_dynamic"].as_f64().is_some(), "{v}: {motion}");
        assert!(motion["mask_iou"].as_f64().is_some(), "{v}: {motion}");
        if v == "motion-off" {
            assert_eq!(motion["rel_epe_dynamic"].as_f64(), Some(1.0), "{motion}");
        }
    }
    let table = std::fs::read_to_string(runs.join("motion-table.md")).unwrap();
    for p in [
        "motion-constant",
        "motion-accelerating",
        "motion-turning",
        "motion-crossing",
        "motion-stop-and-go",
    ] {
        assert!(table.contains(&format!("### {p}")), "{table}");
    }
    for v in [
        "| cml |",
        "| linear-velocity |",
        "| motion-off |",
        "| cml-zeroed |",
        "| cml-oracle |",
    ] {
        assert!(table.contains(v), "{table}");
    }
}
