//! The DPT heads' sin/cos position embedding ("pos-embed with ratio 0.1").
//!
//! A UV grid spanning the image's aspect ratio (normalised by its diagonal) is embedded per
//! coordinate as `[sin(uω) | cos(uω) | sin(vω) | cos(vω)]`, `ω_k = 100^(-k/(C/4))`, computed in
//! f64 and scaled by 0.1. It is added after each projection and after the final upsample.

use burn::tensor::{Device, Tensor, TensorData};

/// Scale of the embedding when it is added.
pub const DPT_POS_EMBED_RATIO: f64 = 0.1;
/// Frequency base of the embedding.
pub const DPT_POS_EMBED_BASE: f64 = 100.0;

fn linspace(half_span: f64, n: usize) -> Vec<f64> {
    let lim = half_span * (n as f64 - 1.0) / n as f64;
    (0..n)
        .map(|i| {
            if n == 1 {
                -lim
            } else {
                -lim + 2.0 * lim * i as f64 / (n as f64 - 1.0)
            }
        })
        .collect()
}

/// The embedding `[1, c, h, w]` (already multiplied by the ratio) for an image of
/// `image_w / image_h` aspect.
pub fn dpt_pos_embed(
    c: usize,
    h: usize,
    w: usize,
    image_h: usize,
    image_w: usize,
    device: &Device,
) -> Tensor<4> {
    let aspect = image_w as f64 / image_h as f64;
    let diag = (aspect * aspect + 1.0).sqrt();
    let u = linspace(aspect / diag, w);
    let v = linspace(1.0 / diag, h);
    let quarter = c / 4;
    let omega: Vec<f64> = (0..quarter)
        .map(|k| DPT_POS_EMBED_BASE.powf(-(k as f64) / quarter as f64))
        .collect();
    // The embedding is separable: every channel is a function of either x or y alone, so
    // the sines and cosines are taken once per (frequency, column) and (frequency, row)
    // rather than once per pixel (at 350x518 that is 1.4e4 instead of 5.8e6 per call).
    // Each value is the same f64 expression as the per-pixel form, so the result is unchanged.
    let table = |coords: &[f64]| -> [Vec<f32>; 2] {
        let (mut sin, mut cos) = (Vec::new(), Vec::new());
        for om in &omega {
            for t in coords {
                sin.push(((t * om).sin() as f32) * DPT_POS_EMBED_RATIO as f32);
                cos.push(((t * om).cos() as f32) * DPT_POS_EMBED_RATIO as f32);
            }
        }
        [sin, cos]
    };
    let [su, cu] = table(&u);
    let [sv, cv] = table(&v);
    let mut out = vec![0f32; c * h * w];
    // Channel blocks [sin(u) | cos(u) | sin(v) | cos(v)], each `quarter` frequencies deep.
    // Channels past 4·quarter (when c is not a multiple of 4) stay zero, as in the reference.
    for (plane, dst) in out.chunks_exact_mut(h * w).take(4 * quarter).enumerate() {
        let (block, k) = (plane / quarter, plane % quarter);
        for (y, row) in dst.chunks_exact_mut(w).enumerate() {
            match block {
                0 => row.copy_from_slice(&su[k * w..(k + 1) * w]),
                1 => row.copy_from_slice(&cu[k * w..(k + 1) * w]),
                2 => row.fill(sv[k * h + y]),
                _ => row.fill(cv[k * h + y]),
            }
        }
    }
    Tensor::from_data(TensorData::new(out, [1, c, h, w]), device)
}
