//! The offline PTX check (`examples/ptx_check.rs`) must list every kernel: it is the only
//! place a kernel meets the CUDA route before a GPU lease, and it builds only with the `cuda`
//! feature, so nothing else notices a kernel added without it.

use std::collections::BTreeSet;
use std::path::Path;

/// The names of the `#[cube(launch)]` functions in one kernel source file.
fn launched(source: &str) -> Vec<String> {
    let mut names = Vec::new();
    let mut pending = false;
    for line in source.lines().map(str::trim) {
        if line.starts_with("#[cube(launch") {
            pending = true;
        } else if let Some(rest) = line
            .strip_prefix("pub fn ")
            .or(line.strip_prefix("fn "))
            .filter(|_| pending)
        {
            let name: String = rest
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect();
            names.push(name);
            pending = false;
        }
    }
    names
}

/// Every `.rs` file under `dir`. Entries that vanish mid-walk (other tests of the suite
/// write and remove files while this one runs) are skipped: they are not sources.
fn rust_files(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for path in entries.flatten().map(|e| e.path()) {
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// Guards against a kernel (such as `scan_wrapped`, once, and the lean attention's row
/// kernels, whose files this test did not read at first) that ships without being
/// lowered to PTX offline: every launchable kernel of every crate appears in ptx_check's
/// list by name.
#[test]
fn ptx_check_lists_every_launchable_kernel() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let check = std::fs::read_to_string(root.join("examples/ptx_check.rs")).unwrap();
    // Each entry's name is the first string after `kernel!(`, on its line or, where
    // rustfmt broke a short entry over lines, the next; commented-out entries do not count.
    let code: String = check
        .lines()
        .filter(|l| !l.trim_start().starts_with("//"))
        .collect::<Vec<_>>()
        .join("\n");
    let listed: BTreeSet<String> = code
        .split("kernel!(")
        .skip(1)
        .filter_map(|entry| entry.trim_start().strip_prefix('"'))
        .filter_map(|l| l.split(['"', '<']).next())
        .map(str::to_owned)
        .collect();
    // Every source file of every crate's `src/`: a kernel file added anywhere is found.
    let mut sources = Vec::new();
    for krate in std::fs::read_dir(root.join("..")).unwrap().flatten() {
        rust_files(&krate.path().join("src"), &mut sources);
    }
    let mut kernels = BTreeSet::new();
    for path in sources {
        if let Ok(source) = std::fs::read_to_string(&path) {
            kernels.extend(launched(&source));
        }
    }
    for outside_splat in [
        "layer_norm_forward",
        "layer_norm_backward_input",
        "layer_norm_backward_params",
        "adam_update",
        "flag_non_finite",
        "softmax_rows",
        "row_dot",
        "probs_from_lse",
        "score_grad",
        "rope_rotate",
        "scaled_residual_forward",
        "scaled_residual_backward",
        "split_heads",
        "merge_heads",
    ] {
        assert!(kernels.contains(outside_splat), "{outside_splat} not found");
    }
    assert!(kernels.len() >= 20, "too few kernels found: {kernels:?}");
    let missing: Vec<_> = kernels.difference(&listed).collect();
    assert!(missing.is_empty(), "kernels not in ptx_check: {missing:?}");
}
