//! `--export-predictions`: raw and adapted predictions to safetensors, under the key names of
//! the reference fixture (`pose_enc`, `depth`, ..., `adapter/means`, ...), so parity can be
//! checked through the binary.

use anyhow::{Context, Result};
use burn::tensor::Tensor;
use envision4d_model::Scene;
use std::collections::HashMap;
use std::path::Path;

/// Metadata written into the export.
const PRODUCER_KEY: &str = "producer";
const PRODUCER: &str = "envision4d render";

type Named = (String, Vec<usize>, Vec<f32>);

/// Writes every prediction of `scene`. `pose_enc` is the camera head's raw output; the
/// extrinsics/intrinsics are those the Gaussians were built with (FoV clamped, which leaves a
/// sane prediction unchanged).
pub fn export_predictions(path: &Path, scene: &Scene) -> Result<()> {
    let mut out: Vec<Named> = Vec::new();
    let pred = &scene.pred;
    let bb = &pred.backbone;
    push(&mut out, "pose_enc", bb.pose_enc());
    push(&mut out, "adapter/extrinsics", bb.extrinsics.clone());
    push(&mut out, "adapter/intrinsics", bb.intrinsics.clone());
    if let (Some(d), Some(c), Some(g), Some(m)) = (
        &pred.depth,
        &pred.depth_conf,
        &pred.gaussians,
        &pred.motion_enc,
    ) {
        push(&mut out, "depth", d.clone());
        push(&mut out, "depth_conf", c.clone());
        push(&mut out, "gaussians", g.clone());
        push(&mut out, "motion_enc", m.clone());
    }
    let a = scene.adapted.clone();
    push(&mut out, "adapter/means", a.means);
    push(&mut out, "adapter/scales", a.scales);
    push(&mut out, "adapter/rotations", a.rotations);
    push(&mut out, "adapter/colors", a.colors);
    push(&mut out, "adapter/opacities", a.opacities);
    push(&mut out, "adapter/motions", a.motions);
    write_safetensors(path, &out)
}

fn push<const D: usize>(out: &mut Vec<Named>, key: &str, t: Tensor<D>) {
    let shape = t.dims().to_vec();
    let v = t
        .into_data()
        .convert::<f32>()
        .try_into_vec::<f32>()
        .expect("f32 data");
    out.push((key.to_owned(), shape, v));
}

/// Writes the tensors atomically (temporary file + rename).
fn write_safetensors(path: &Path, tensors: &[Named]) -> Result<()> {
    let bytes: Vec<Vec<u8>> = tensors
        .iter()
        .map(|(_, _, v)| v.iter().flat_map(|x| x.to_le_bytes()).collect())
        .collect();
    let views = tensors
        .iter()
        .zip(&bytes)
        .map(|((k, shape, _), b)| {
            Ok((
                k.clone(),
                safetensors::tensor::TensorView::new(safetensors::Dtype::F32, shape.clone(), b)?,
            ))
        })
        .collect::<Result<Vec<_>, safetensors::SafeTensorError>>()?;
    let meta = HashMap::from([(PRODUCER_KEY.to_owned(), PRODUCER.to_owned())]);
    let encoded = safetensors::tensor::serialize(views, Some(meta))
        .with_context(|| format!("encoding {}", path.display()))?;
    envision4d_data::atomic::write_bytes(path, &encoded)
        .with_context(|| format!("writing {}", path.display()))
}
