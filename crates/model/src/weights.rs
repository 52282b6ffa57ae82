//! Loading weights by their official `state_dict` names (burn-store, safetensors).
//!
//! Checkpoints name tensors exactly like the PyTorch modules (`aggregator.frame_blocks.0.
//! attn.qkv.weight`, ...), possibly under a prefix (`encoder.backbone.` in the Lightning
//! checkpoint, `weights/` in the fixtures). `PyTorchToBurnAdapter` transposes `nn.Linear`
//! weights and renames LayerNorm `weight/bias`, but never the LayerScale `gamma`.
//! Every problem — missing, unexpected or mis-shaped keys — is collected into one error.

use burn::module::Module;
use burn::store::{
    ApplyError, KeyRemapper, ModuleSnapshot, PyTorchToBurnAdapter, SafetensorsStore,
};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Which checkpoint keys must be consumed by the module.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Unexpected {
    /// Keys under the prefix that the module does not have are an error (strict loading).
    Reject,
    /// Keys the module does not have are ignored (e.g. VGGT-1B's `point_head`/`track_head`,
    /// or the `expected/*` tensors of a fixture).
    Ignore,
}

/// Which module parameters the checkpoint must provide.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Missing {
    /// Every parameter must be present.
    Reject,
    /// Parameters absent from the checkpoint keep their fresh initialisation (initialising
    /// Envision4D from VGGT-1B leaves the new modules fresh).
    KeepInit,
}

/// A checkpoint that does not fit the module, with every offending key listed.
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    #[error("{path}: cannot read checkpoint: {message}")]
    Read { path: PathBuf, message: String },
    #[error("{path}: checkpoint does not match the model:\n{report}")]
    Mismatch { path: PathBuf, report: String },
}

/// Outcome of a successful load.
#[derive(Debug, Clone, Default)]
pub struct LoadReport {
    pub applied: usize,
    /// Parameters left at their initial values (only with [`Missing::KeepInit`]).
    pub kept_init: Vec<String>,
    /// Checkpoint keys nobody used (only with [`Unexpected::Ignore`]).
    pub ignored: Vec<String>,
}

/// Loads `module`'s parameters from the tensors of `path` whose names start with `prefix`
/// (the prefix is stripped; other keys are never looked at).
/// PyTorch `nn.Sequential` children are numbered (`poseLN_modulation.1`, `time_embedding.0`);
/// our modules name them. Each rule is a regex on the stripped key and its replacement.
pub const KEY_RENAMES: &[(&str, &str)] = &[
    // The future-pose parameters sit on the release's model root; ours group them.
    (
        r"^(extra_token_offset$|extra_blocks\.|time_embedding\.)",
        "future.${1}",
    ),
    (r"(^|\.)poseLN_modulation\.1\.", "${1}pose_ln_modulation."),
    (r"(^|\.)time_embedding\.0\.", "${1}time_embedding.fc1."),
    (r"(^|\.)time_embedding\.2\.", "${1}time_embedding.fc2."),
    (r"(^|\.)output_conv2\.0\.", "${1}output_conv2.conv1."),
    (r"(^|\.)output_conv2\.2\.", "${1}output_conv2.conv2."),
    (r"(^|\.)input_merger\.0\.", "${1}input_merger."),
    (r"(^|\.)resize_layers\.0\.", "${1}resize0."),
    (r"(^|\.)resize_layers\.1\.", "${1}resize1."),
    (r"(^|\.)resize_layers\.3\.", "${1}resize3."),
    (r"\.resConfUnit(\d)\.", ".res_conf_unit${1}."),
];

/// The inverse of [`KEY_RENAMES`]: our parameter paths back to official names (for saving).
pub const KEY_RENAMES_BACK: &[(&str, &str)] = &[
    (r"^future\.", ""),
    (r"(^|\.)pose_ln_modulation\.", "${1}poseLN_modulation.1."),
    (r"(^|\.)time_embedding\.fc1\.", "${1}time_embedding.0."),
    (r"(^|\.)time_embedding\.fc2\.", "${1}time_embedding.2."),
    (r"(^|\.)output_conv2\.conv1\.", "${1}output_conv2.0."),
    (r"(^|\.)output_conv2\.conv2\.", "${1}output_conv2.2."),
    (r"(^|\.)input_merger\.", "${1}input_merger.0."),
    (r"(^|\.)resize0\.", "${1}resize_layers.0."),
    (r"(^|\.)resize1\.", "${1}resize_layers.1."),
    (r"(^|\.)resize3\.", "${1}resize_layers.3."),
    (r"\.res_conf_unit(\d)\.", ".resConfUnit${1}."),
];

/// Our name of an official (prefix-stripped) key.
pub fn rename_key(key: &str) -> String {
    static RULES: std::sync::OnceLock<Vec<(regex::Regex, &'static str)>> =
        std::sync::OnceLock::new();
    let rules = RULES.get_or_init(|| {
        KEY_RENAMES
            .iter()
            .map(|(f, t)| (regex::Regex::new(f).expect("valid rename regex"), *t))
            .collect()
    });
    rules.iter().fold(key.to_owned(), |k, (re, to)| {
        re.replace_all(&k, *to).into_owned()
    })
}

/// Checkpoint file formats, chosen by extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// `.safetensors` (our own checkpoints, exported official weights, fixtures).
    Safetensors,
    /// PyTorch pickles: `.pt`, `.pth`, `.bin`, and Lightning `.ckpt` (weights under `state_dict`).
    PyTorch,
}

impl Format {
    pub fn from_path(path: &Path) -> Result<Format, LoadError> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .unwrap_or_default();
        match ext.as_str() {
            "safetensors" => Ok(Format::Safetensors),
            "pt" | "pth" | "bin" | "ckpt" => Ok(Format::PyTorch),
            other => Err(LoadError::Read { path: path.to_path_buf(), message: format!("unknown checkpoint extension {other:?}: use .safetensors, .pt, .pth, .bin or .ckpt") }),
        }
    }
}

/// Lightning checkpoints keep the weights under this top-level key.
pub const LIGHTNING_STATE_DICT: &str = "state_dict";

/// The tensor names of a checkpoint, and whether they sit under a Lightning `state_dict`.
struct Listing {
    keys: Vec<String>,
    lightning: bool,
}

fn list_checkpoint(path: &Path) -> Result<Listing, LoadError> {
    match Format::from_path(path)? {
        Format::Safetensors => Ok(Listing {
            keys: header_names(path)?,
            lightning: false,
        }),
        Format::PyTorch => {
            use burn::store::pytorch_reader::PytorchReader;
            let (reader, lightning) =
                match PytorchReader::with_top_level_key(path, LIGHTNING_STATE_DICT) {
                    Ok(r) => (r, true),
                    Err(_) => (
                        PytorchReader::new(path).map_err(|e| LoadError::Read {
                            path: path.to_path_buf(),
                            message: format!("not a readable PyTorch checkpoint: {e}"),
                        })?,
                        false,
                    ),
                };
            Ok(Listing {
                keys: reader.keys(),
                lightning,
            })
        }
    }
}

/// Tensor names of a checkpoint (for PyTorch files, under `state_dict` when present).
pub fn checkpoint_keys(path: &Path) -> Result<Vec<String>, LoadError> {
    Ok(list_checkpoint(path)?.keys)
}

/// A key remapper applying `rules` (regex, replacement) in order, after an optional first rule.
pub fn remapper(
    first: Option<(&str, &str)>,
    rules: &[(&str, &str)],
) -> Result<KeyRemapper, String> {
    first
        .into_iter()
        .chain(rules.iter().copied())
        .try_fold(KeyRemapper::new(), |r, (from, to)| {
            r.add_pattern(from, to)
                .map_err(|e| format!("bad key rule {from}: {e}"))
        })
}

/// Loads `module`'s parameters from `path` (any [`Format`]), using only the tensors whose
/// names start with `prefix` (stripped) and renaming them with [`KEY_RENAMES`].
pub fn load_weights<M: Module + ModuleSnapshot>(
    module: &mut M,
    path: &Path,
    prefix: &str,
    missing: Missing,
    unexpected: Unexpected,
) -> Result<LoadReport, LoadError> {
    let read_err = |message: String| LoadError::Read {
        path: path.to_path_buf(),
        message,
    };
    let listing = list_checkpoint(path)?;
    let under_prefix = listing
        .keys
        .iter()
        .filter_map(|n| n.strip_prefix(prefix).map(rename_key))
        .collect::<std::collections::HashSet<String>>();
    let pattern = format!("^{}(.*)$", regex_escape(prefix));
    let remap = remapper(Some((&pattern, "$1")), KEY_RENAMES).map_err(read_err)?;
    // `validate(false)`: shape mismatches come back in `ApplyResult::errors` (the tensor is
    // not applied either way) so they can be reported with the missing and unexpected keys.
    let result = match Format::from_path(path)? {
        Format::Safetensors => {
            let mut store = SafetensorsStore::from_file(path)
                .remap(remap)
                .with_from_adapter(PyTorchToBurnAdapter)
                .allow_partial(true)
                .validate(false);
            module
                .load_from(&mut store)
                .map_err(|e| read_err(format!("{e:?}")))?
        }
        Format::PyTorch => {
            // Our Sequential renames need the original indices: no contiguous renumbering.
            let mut store = burn::store::PytorchStore::from_file(path)
                .remap(remap)
                .allow_partial(true)
                .validate(false)
                .map_indices_contiguous(false);
            if listing.lightning {
                store = store.with_top_level_key(LIGHTNING_STATE_DICT);
            }
            module
                .load_from(&mut store)
                .map_err(|e| read_err(format!("{e:?}")))?
        }
    };
    summarise(path, prefix, result, &under_prefix, missing, unexpected)
}

fn summarise(
    path: &Path,
    prefix: &str,
    result: burn::store::ApplyResult,
    under_prefix: &std::collections::HashSet<String>,
    missing: Missing,
    unexpected: Unexpected,
) -> Result<LoadReport, LoadError> {
    let mut report = String::new();
    for e in &result.errors {
        let line = match e {
            ApplyError::ShapeMismatch {
                path,
                expected,
                found,
            } => format!(
                "  mis-shaped: {path}: model expects {expected:?}, checkpoint has {found:?}"
            ),
            other => format!("  {other:?}"),
        };
        let _ = writeln!(report, "{line}");
    }
    if missing == Missing::Reject {
        for (key, _) in &result.missing {
            let _ = writeln!(report, "  missing: {prefix}{key}");
        }
    }
    // Only keys under the prefix count as unexpected: others were never meant for the model.
    let unused_under_prefix: Vec<String> = result
        .unused
        .iter()
        .filter(|k| under_prefix.contains(*k))
        .cloned()
        .collect();
    if unexpected == Unexpected::Reject {
        for key in &unused_under_prefix {
            let _ = writeln!(report, "  unexpected: {prefix}{key}");
        }
    }
    if !report.is_empty() {
        return Err(LoadError::Mismatch {
            path: path.to_path_buf(),
            report,
        });
    }
    Ok(LoadReport {
        applied: result.applied.len(),
        kept_init: result.missing.iter().map(|(k, _)| k.clone()).collect(),
        ignored: unused_under_prefix,
    })
}

/// Largest safetensors header we accept (the paper model's has ~1.6k entries, ~200 KB).
const MAX_HEADER_BYTES: u64 = 64 << 20;

/// Tensor names in a safetensors file, read from its header only.
pub fn header_names(path: &Path) -> Result<Vec<String>, LoadError> {
    Ok(read_header(path)?
        .into_iter()
        .map(|(k, _)| k)
        .filter(|k| k != "__metadata__")
        .collect())
}

/// The string metadata (`__metadata__`) of a safetensors file.
pub fn header_metadata(
    path: &Path,
) -> Result<std::collections::HashMap<String, String>, LoadError> {
    let header = read_header(path)?;
    Ok(header
        .get("__metadata__")
        .and_then(|m| m.as_object())
        .map(|m| {
            m.iter()
                .filter_map(|(k, v)| v.as_str().map(|v| (k.clone(), v.to_owned())))
                .collect()
        })
        .unwrap_or_default())
}

fn read_header(path: &Path) -> Result<serde_json::Map<String, serde_json::Value>, LoadError> {
    use std::io::Read;
    let read_err = |message: String| LoadError::Read {
        path: path.to_path_buf(),
        message,
    };
    let mut f = std::fs::File::open(path).map_err(|e| read_err(e.to_string()))?;
    let mut len = [0u8; 8];
    f.read_exact(&mut len)
        .map_err(|e| read_err(format!("not a safetensors file (no header length): {e}")))?;
    let n = u64::from_le_bytes(len);
    if n == 0 || n > MAX_HEADER_BYTES {
        return Err(read_err(format!(
            "not a safetensors file (header length {n})"
        )));
    }
    let mut header = vec![0u8; n as usize];
    f.read_exact(&mut header)
        .map_err(|e| read_err(format!("truncated safetensors header: {e}")))?;
    serde_json::from_slice(&header)
        .map_err(|e| read_err(format!("corrupt safetensors header: {e}")))
}

fn regex_escape(s: &str) -> String {
    s.chars().fold(String::new(), |mut out, c| {
        if "\\.+*?()|[]{}^$".contains(c) {
            out.push('\\');
        }
        out.push(c);
        out
    })
}
