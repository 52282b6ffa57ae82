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
    let mut out = vec![0f32; c * h * w];
    for y in 0..h {
        for x in 0..w {
            for (k, om) in omega.iter().enumerate() {
                let vals = [
                    (u[x] * om).sin(),
                    (u[x] * om).cos(),
                    (v[y] * om).sin(),
                    (v[y] * om).cos(),
                ];
                for (block, val) in vals.iter().enumerate() {
                    out[((block * quarter + k) * h + y) * w + x] =
                        (*val as f32) * DPT_POS_EMBED_RATIO as f32;
                }
            }
        }
    }
    Tensor::from_data(TensorData::new(out, [1, c, h, w]), device)
}
