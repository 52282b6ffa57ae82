//! Helpers shared by the CLI's end-to-end tests: running the binary, a tiny training config,
//! a generated mini dataset, and small real file systems (tmpfs) that fill up or turn
//! read-only on demand.

#![allow(dead_code)] // each test file uses its own subset

#[path = "../../../../tests/support/paths.rs"]
pub mod paths;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs `envision4d args` in `cwd`, to completion.
pub fn bin(args: &[&str], cwd: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_envision4d"))
        .args(args)
        .current_dir(cwd)
        .output()
        .expect("envision4d runs")
}

/// Stdout then stderr, for assertion messages and searches.
pub fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

pub fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 temp path")
}

/// `clips` synthetic clips of `frames` frames at 56x84 (the tiny model's size) in `dir/name`.
pub fn synth(dir: &Path, name: &str, clips: usize, frames: usize) -> PathBuf {
    let data = dir.join(name);
    let (c, f) = (clips.to_string(), frames.to_string());
    let o = bin(
        &[
            "synth",
            "--out",
            s(&data),
            "--clips",
            &c,
            "--frames",
            &f,
            "--size",
            "56x84",
            "--supersample",
            "1",
        ],
        dir,
    );
    assert!(o.status.success(), "{}", text(&o));
    data
}

/// `configs/synth-tiny.toml` as a table, trained from random init with nothing frozen.
pub fn shipped_tiny() -> toml::Table {
    let shipped = paths::manifest_dir().join("../../configs/synth-tiny.toml");
    let text = std::fs::read_to_string(shipped).unwrap();
    let mut cfg: toml::Table = toml::from_str(&text).unwrap();
    cfg.remove("init_checkpoint");
    cfg.insert("freeze".into(), toml::Value::Array(vec![]));
    cfg
}

/// Sets `[table] key = v` of a config table.
pub fn set(cfg: &mut toml::Table, table: &str, key: &str, v: toml::Value) {
    cfg.get_mut(table)
        .and_then(|t| t.as_table_mut())
        .unwrap()
        .insert(key.into(), v);
}

/// A tiny stage-2 config (random init, exact labels, T_f = 2) of `iterations` steps on
/// `data`, writing to `out` and checkpointing every step; saved as `dir/cfg.toml`.
pub fn write_config(dir: &Path, data: &Path, out: &Path, iterations: i64) -> PathBuf {
    let mut cfg = shipped_tiny();
    set(&mut cfg, "model", "future_frames", 2.into());
    set(&mut cfg, "optim", "batch_size", 1.into());
    set(&mut cfg, "optim", "iterations", iterations.into());
    set(&mut cfg, "progressive", "warmup_iterations", 1.into());
    set(&mut cfg, "data", "root", data.display().to_string().into());
    set(&mut cfg, "data", "stride", 1.into());
    set(&mut cfg, "run", "out_dir", out.display().to_string().into());
    set(&mut cfg, "run", "log_every", 1.into());
    set(&mut cfg, "run", "checkpoint_every", 1.into());
    set(&mut cfg, "run", "val_every", 2.into());
    let path = dir.join("cfg.toml");
    std::fs::write(&path, toml::to_string(&cfg).unwrap()).unwrap();
    path
}

/// The step records of a run's log.
pub fn logged_steps(out: &Path) -> Vec<u64> {
    let log = std::fs::read_to_string(out.join("log.jsonl")).unwrap();
    log.lines()
        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .filter(|v| v["kind"] == "step")
        .map(|v| v["step"].as_u64().unwrap())
        .collect()
}

/// Whether this process may mount (CAP_SYS_ADMIN in its effective set: root on a machine,
/// not root in an unprivileged container).
pub fn can_mount() -> bool {
    const CAP_SYS_ADMIN: u32 = 21;
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("CapEff:"))
                .and_then(|l| l.split_whitespace().nth(1))
                .and_then(|hex| u64::from_str_radix(hex, 16).ok())
        })
        .is_some_and(|caps| (caps >> CAP_SYS_ADMIN) & 1 == 1)
}

/// A real, small file system (tmpfs) mounted on a folder, so a full disk gives a genuine
/// ENOSPC and a read-only one a genuine EROFS; unmounted on drop, even when a test fails.
pub struct Tmpfs {
    pub dir: PathBuf,
}

impl Tmpfs {
    /// Mounts `bytes` of tmpfs on `dir` (created). Mounting needs root (CI runs as root): as
    /// another user the test fails saying so, unless `ENVISION4D_SKIP_MOUNT=1` asks to skip
    /// it (`None`, with a note); a failed mount as root fails the test.
    pub fn mount(dir: &Path, bytes: u64) -> Option<Tmpfs> {
        if !can_mount() {
            let skip = std::env::var("ENVISION4D_SKIP_MOUNT").is_ok_and(|v| v == "1");
            assert!(
                skip,
                "this test mounts a small tmpfs for a genuine full or read-only disk and needs \
                 root with CAP_SYS_ADMIN; run as root (as CI does) or set \
                 ENVISION4D_SKIP_MOUNT=1 to skip it"
            );
            eprintln!("skipped (ENVISION4D_SKIP_MOUNT=1): mounting a tmpfs needs root");
            return None;
        }
        std::fs::create_dir_all(dir).unwrap();
        mount(&[
            "-t",
            "tmpfs",
            "-o",
            &format!("size={bytes}"),
            "tmpfs",
            s(dir),
        ]);
        Some(Tmpfs {
            dir: dir.to_path_buf(),
        })
    }

    /// Grows (or shrinks) the file system to `bytes`, keeping its files.
    pub fn resize(&self, bytes: u64) {
        mount(&["-o", &format!("remount,size={bytes}"), s(&self.dir)]);
    }

    /// Turns the file system read-only, keeping its files.
    pub fn read_only(&self) {
        mount(&["-o", "remount,ro", s(&self.dir)]);
    }

    /// Fills the file system to the last byte with a filler file.
    pub fn fill(&self) {
        use std::io::Write;
        let mut f = std::fs::File::create(self.dir.join("filler")).unwrap();
        let chunk = vec![0u8; 4096];
        while f.write_all(&chunk).is_ok() {}
        let one = [0u8; 1];
        while f.write_all(&one).is_ok() {}
    }
}

impl Drop for Tmpfs {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg("-l").arg(&self.dir).status();
    }
}

fn mount(args: &[&str]) {
    let o = Command::new("mount")
        .args(args)
        .output()
        .expect("mount runs");
    assert!(o.status.success(), "mount {args:?}: {}", text(&o));
}

/// Every file under `dir` (recursively).
pub fn walk(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            out.extend(walk(&p));
        } else {
            out.push(p);
        }
    }
    out
}

/// Total size of the files under `dir`.
pub fn tree_bytes(dir: &Path) -> u64 {
    walk(dir)
        .iter()
        .map(|p| std::fs::metadata(p).unwrap().len())
        .sum()
}
