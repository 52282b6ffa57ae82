//! What survives what, with real processes and real file systems: two writers on one run
//! directory, a `kill -9` mid-run, a disk that fills during a checkpoint, an eval or render
//! into a full or read-only disk. Each promise is in `docs/TRAINING.md` "What survives what".

mod common;

use common::{bin, logged_steps, s, synth, text, tree_bytes, walk, write_config, Tmpfs};
use std::os::unix::process::ExitStatusExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// Sends `kill -SIG pid`.
fn signal(pid: u32, sig: &str) {
    let ok = Command::new("kill")
        .args([format!("-{sig}"), pid.to_string()])
        .status()
        .expect("kill runs");
    assert!(ok.success(), "kill -{sig} {pid}");
}

/// A run's final weights: the bytes every interrupted-then-resumed run must reproduce.
fn reference_model(dir: &Path, data: &Path, iterations: i64) -> Vec<u8> {
    let out = dir.join("reference");
    let cfg = write_config(dir, data, &out, iterations);
    let o = bin(&["train", "--config", s(&cfg)], dir);
    assert!(o.status.success(), "{}", text(&o));
    std::fs::read(out.join("model.safetensors")).unwrap()
}

/// `envision4d train --config cfg` started in the background.
fn spawn_train(cfg: &Path, cwd: &Path) -> Child {
    Command::new(env!("CARGO_BIN_EXE_envision4d"))
        .args(["train", "--config", s(cfg)])
        .current_dir(cwd)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("envision4d starts")
}

/// Waits (at most two minutes) until `path` exists, failing if `child` ends first.
fn wait_for(path: &Path, child: &mut Child) {
    let t0 = Instant::now();
    while !path.exists() {
        if let Some(status) = child.try_wait().unwrap() {
            panic!(
                "the run ended ({status}) before {} appeared",
                path.display()
            );
        }
        assert!(
            t0.elapsed() < Duration::from_secs(120),
            "{} never appeared",
            path.display()
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Guards the race of two `train`s on one `run.out_dir` (both used to run to the end,
/// interleaving log and checkpoints): while the first runs, a second (fresh or `--resume`)
/// exits 2 naming the directory and the first's pid, and the first ends unharmed, with the
/// weights of a run nobody disturbed.
#[test]
fn a_second_writer_is_refused_and_the_first_is_unharmed() {
    let tmp = tempfile::tempdir().unwrap();
    let data = synth(tmp.path(), "data", 3, 4);
    let reference = reference_model(tmp.path(), &data, 6);
    let out = tmp.path().join("run");
    let cfg = write_config(tmp.path(), &data, &out, 6);
    let mut first = spawn_train(&cfg, tmp.path());
    // config.toml is written under the lock: from then on the first holds it. Paused
    // (SIGSTOP) while the others try, so it cannot finish first however fast it is.
    wait_for(&out.join("config.toml"), &mut first);
    signal(first.id(), "STOP");
    for extra in [&[][..], &["--resume", s(&out)][..]] {
        let mut args = vec!["train", "--config", s(&cfg)];
        args.extend_from_slice(extra);
        let second = bin(&args, tmp.path());
        let t = text(&second);
        assert_eq!(second.status.code(), Some(2), "{t}");
        assert!(t.contains("in use") && t.contains(s(&out)), "{t}");
        assert!(t.contains(&format!("pid {}", first.id())), "{t}");
    }
    signal(first.id(), "CONT");
    let first = first.wait_with_output().unwrap();
    assert!(first.status.success(), "{}", text(&first));
    assert_eq!(logged_steps(&out), (0..6).collect::<Vec<_>>());
    assert!(
        std::fs::read(out.join("model.safetensors")).unwrap() == reference,
        "the first run's weights differ from an undisturbed run's"
    );
}

/// Guards resuming after `kill -9`: the lock file the killed run left behind does not
/// block `--resume`, and the resumed run ends with the uninterrupted run's exact weights.
#[test]
fn a_killed_run_resumes_past_its_stale_lock_to_the_same_weights() {
    let tmp = tempfile::tempdir().unwrap();
    let data = synth(tmp.path(), "data", 3, 4);
    let reference = reference_model(tmp.path(), &data, 6);
    let out = tmp.path().join("run");
    let cfg = write_config(tmp.path(), &data, &out, 6);
    let mut run = spawn_train(&cfg, tmp.path());
    wait_for(&out.join("checkpoints/step-00000002/state.json"), &mut run);
    run.kill().unwrap(); // SIGKILL: no destructor, no unlock by the program
    let status = run.wait().unwrap();
    // Killed, not finished: otherwise the resume below would test nothing.
    assert_eq!(
        status.signal(),
        Some(9),
        "the run ended before the kill: {status}"
    );
    let lock = std::fs::read_to_string(out.join(".lock")).unwrap();
    assert!(lock.contains(&format!("pid {}", run.id())), "{lock}");
    let resumed = bin(
        &["train", "--config", s(&cfg), "--resume", s(&out)],
        tmp.path(),
    );
    assert!(resumed.status.success(), "{}", text(&resumed));
    assert_eq!(logged_steps(&out), (0..6).collect::<Vec<_>>());
    assert!(
        std::fs::read(out.join("model.safetensors")).unwrap() == reference,
        "the resumed weights differ from the uninterrupted run's"
    );
}

/// Guards a full disk during a checkpoint (a genuine ENOSPC on a small tmpfs): the run
/// exits 1 naming the path and the cause, the last complete checkpoint stays whole with no
/// half-written one beside it, and once there is room `--resume` ends with the
/// uninterrupted run's exact weights.
#[test]
fn a_full_disk_during_a_checkpoint_fails_cleanly_and_resumes_exactly() {
    let tmp = tempfile::tempdir().unwrap();
    let data = synth(tmp.path(), "data", 3, 4);
    let reference = reference_model(tmp.path(), &data, 3);
    let checkpoint = tree_bytes(&tmp.path().join("reference/checkpoints/step-00000003"));
    // Room for one checkpoint and a half: the second one cannot be written.
    let Some(disk) = Tmpfs::mount(&tmp.path().join("disk"), checkpoint * 3 / 2 + (1 << 16)) else {
        return;
    };
    let out = disk.dir.join("run");
    let cfg = write_config(tmp.path(), &data, &out, 3);
    let full = bin(&["train", "--config", s(&cfg)], tmp.path());
    let t = text(&full);
    assert_eq!(full.status.code(), Some(1), "{t}");
    assert!(t.contains("No space left on device"), "{t}");
    assert!(t.contains(s(&out.join("checkpoints"))), "{t}");
    let kept: Vec<String> = std::fs::read_dir(out.join("checkpoints"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(
        kept,
        ["step-00000001"],
        "a partial checkpoint was left behind"
    );
    assert!(out.join("checkpoints/step-00000001/state.json").is_file());
    disk.resize(checkpoint * 4);
    let resumed = bin(
        &["train", "--config", s(&cfg), "--resume", s(&out)],
        tmp.path(),
    );
    assert!(resumed.status.success(), "{}", text(&resumed));
    assert_eq!(logged_steps(&out), [0, 1, 2]);
    assert!(
        std::fs::read(out.join("model.safetensors")).unwrap() == reference,
        "the resumed weights differ from the uninterrupted run's"
    );
}

/// A trained tiny checkpoint and held-out clips for the eval/render cases.
fn model_and_clips(dir: &Path) -> (PathBuf, PathBuf) {
    let data = synth(dir, "data", 2, 4);
    reference_model(dir, &data, 1);
    (dir.join("reference/model.safetensors"), data)
}

/// Guards eval and render outputs on a disk that fills or turns read-only after a first
/// good run: the second run exits 1 naming a path under `--out` and the cause, and the
/// first run's report and manifest stay byte-identical, with no temp file left behind.
#[test]
fn eval_and_render_on_a_full_or_read_only_disk_keep_earlier_outputs() {
    let tmp = tempfile::tempdir().unwrap();
    let (model, data) = model_and_clips(tmp.path());
    let Some(disk) = Tmpfs::mount(&tmp.path().join("disk"), 8 << 20) else {
        return;
    };
    let ev = disk.dir.join("eval");
    let rd = disk.dir.join("render");
    let eval = || {
        bin(
            &[
                "eval",
                "--checkpoint",
                s(&model),
                "--data",
                s(&data),
                "--out",
                s(&ev),
            ],
            tmp.path(),
        )
    };
    let frames = data.join("clip_000000/rgb");
    let render = || {
        bin(
            &[
                "render",
                "--checkpoint",
                s(&model),
                "--frames",
                s(&frames),
                "--out",
                s(&rd),
            ],
            tmp.path(),
        )
    };
    for o in [eval(), render()] {
        assert!(o.status.success(), "{}", text(&o));
    }
    let metrics = std::fs::read(ev.join("metrics.json")).unwrap();
    let manifest = std::fs::read(rd.join("manifest.json")).unwrap();
    disk.fill();
    for (o, dir, cause) in [
        (eval(), &ev, "No space left on device"),
        (render(), &rd, "No space left on device"),
    ] {
        let t = text(&o);
        assert_eq!(o.status.code(), Some(1), "{t}");
        assert!(t.contains(cause) && t.contains(s(dir)), "{t}");
    }
    std::fs::remove_file(disk.dir.join("filler")).unwrap();
    disk.read_only();
    for (o, dir) in [(eval(), &ev), (render(), &rd)] {
        let t = text(&o);
        assert_eq!(o.status.code(), Some(1), "{t}");
        assert!(
            t.contains("Read-only file system") && t.contains(s(dir)),
            "{t}"
        );
    }
    assert!(std::fs::read(ev.join("metrics.json")).unwrap() == metrics);
    assert!(std::fs::read(rd.join("manifest.json")).unwrap() == manifest);
    for dir in [&ev, &rd] {
        let temps: Vec<_> = walk(dir)
            .into_iter()
            .filter(|p| p.to_string_lossy().contains(".tmp-"))
            .collect();
        assert!(temps.is_empty(), "temp files left behind: {temps:?}");
    }
}
