//! `--model-config`: a preset name (`paper`, `tiny`) or a TOML file with a `[model]` table.
//! The table may start from a preset (`preset = "tiny"`) and override fields; any unknown key
//! is an error naming it (serde `deny_unknown_fields`).

use crate::InputError;
use anyhow::Result;
use envision4d_model::ModelConfig;
use std::path::Path;

pub fn load_model_config(spec: &str) -> Result<ModelConfig> {
    let cfg = if Path::new(spec).is_file() {
        from_toml_file(Path::new(spec))?
    } else {
        ModelConfig::preset(spec).map_err(|e| {
            InputError(format!(
                "--model-config {spec:?} is neither a file nor a preset: {e}"
            ))
        })?
    };
    cfg.validate()
        .map_err(|e| InputError(format!("{spec}: {e}")))?;
    Ok(cfg)
}

fn from_toml_file(path: &Path) -> Result<ModelConfig> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| InputError(format!("{}: {e}", path.display())))?;
    let table: toml::Table =
        toml::from_str(&text).map_err(|e| InputError(format!("{}: {e}", path.display())))?;
    let Some(model) = table.get("model").and_then(|m| m.as_table()) else {
        return Err(InputError(format!("{}: no [model] table", path.display())).into());
    };
    let mut model = model.clone();
    let base = match model.remove("preset") {
        Some(toml::Value::String(name)) => ModelConfig::preset(&name)
            .map_err(|e| InputError(format!("{}: [model] preset: {e}", path.display())))?,
        Some(other) => {
            return Err(InputError(format!(
                "{}: [model] preset must be a string, got {other}",
                path.display()
            ))
            .into())
        }
        None => ModelConfig::paper(),
    };
    // Overlay the table on the preset, then let serde reject unknown keys.
    let mut value = serde_json::to_value(base)?;
    let overrides = serde_json::to_value(model)?;
    merge(&mut value, overrides);
    serde_json::from_value(value)
        .map_err(|e| InputError(format!("{}: [model]: {e}", path.display())).into())
}

fn merge(base: &mut serde_json::Value, over: serde_json::Value) {
    match (base, over) {
        (serde_json::Value::Object(b), serde_json::Value::Object(o)) => {
            for (k, v) in o {
                match b.get_mut(&k) {
                    Some(slot) if slot.is_object() && v.is_object() => merge(slot, v),
                    _ => {
                        b.insert(k, v);
                    }
                }
            }
        }
        (slot, v) => *slot = v,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Guards the TOML overlay: preset + overrides work, and a typo is rejected by name.
    #[test]
    fn toml_overlay_and_typo() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("m.toml");
        std::fs::write(
            &p,
            "[model]\npreset = \"tiny\"\nfuture_frames = 4\n[dpt]\nignored = 1\n",
        )
        .unwrap();
        let c = load_model_config(p.to_str().unwrap()).unwrap();
        assert_eq!(c.future_frames, 4);
        assert_eq!(c.embed_dim, 64);
        std::fs::write(&p, "[model]\npreset = \"tiny\"\nembed_dimm = 4\n").unwrap();
        let e = load_model_config(p.to_str().unwrap())
            .unwrap_err()
            .to_string();
        assert!(e.contains("embed_dimm"), "{e}");
        assert!(load_model_config("nonsense")
            .unwrap_err()
            .to_string()
            .contains("nonsense"));
    }
}
