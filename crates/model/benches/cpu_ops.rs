//! The CPU inference kernels against the Burn ops they replace, one op at a time, at the
//! shapes of the tiny model at 350x518 (not a test).
//!
//! `cargo bench -p envision4d-model --bench cpu_ops` — prints a Markdown table of
//! milliseconds per call (best of 5 after one warm-up) for each pair, and the largest
//! difference between the two outputs.

use burn::nn::conv::{Conv2d, Conv2dConfig};
use burn::nn::PaddingConfig2d;
use burn::tensor::module::{attention, interpolate};
use burn::tensor::ops::{AttentionModuleOptions, InterpolateMode, InterpolateOptions};
use burn::tensor::{activation, Device, Distribution, Tensor};
use envision4d_model::layers::{cpu_attention, cpu_conv, cpu_gelu};
use envision4d_model::resample::bilinear_align_corners;
use std::time::Instant;

fn best_ms<const D: usize>(mut f: impl FnMut() -> Tensor<D>) -> (f64, Tensor<D>) {
    let out = f();
    let _ = out.clone().into_data();
    let mut best = f64::INFINITY;
    for _ in 0..5 {
        let t = Instant::now();
        let _ = f().into_data().as_bytes().len();
        best = best.min(t.elapsed().as_secs_f64() * 1e3);
    }
    (best, out)
}

fn max_diff<const D: usize>(a: Tensor<D>, b: Tensor<D>) -> f32 {
    (a - b)
        .abs()
        .max()
        .into_data()
        .convert::<f32>()
        .try_into_vec::<f32>()
        .unwrap()[0]
}

fn row<const D: usize>(
    name: &str,
    burn: impl FnMut() -> Tensor<D>,
    ours: impl FnMut() -> Tensor<D>,
) {
    let (tb, b) = best_ms(burn);
    let (to, o) = best_ms(ours);
    println!(
        "| {name} | {tb:.1} | {to:.1} | {:.2}x | {:.1e} |",
        tb / to,
        max_diff(b, o)
    );
}

fn conv(cin: usize, cout: usize, k: usize, device: &Device) -> Conv2d {
    Conv2dConfig::new([cin, cout], [k, k])
        .with_padding(PaddingConfig2d::Explicit(k / 2, k / 2, k / 2, k / 2))
        .init(device)
}

fn main() {
    envision4d_model::alloc::keep_freed_memory();
    let d = Device::flex();
    let rand = |shape: [usize; 4]| Tensor::<4>::random(shape, Distribution::Uniform(-1.0, 1.0), &d);
    println!("| op (tiny model at 350x518) | Burn ms | ours ms | speed-up | max difference |");
    println!("|---|---|---|---|---|");
    let (c32, c16, merger) = (conv(32, 32, 3, &d), conv(16, 32, 3, &d), conv(3, 32, 7, &d));
    let x32 = rand([1, 32, 350, 518]);
    let x16 = rand([1, 16, 350, 518]);
    let img = rand([1, 3, 350, 518]);
    row(
        "conv 3x3 32→32, 350x518",
        || c32.forward(x32.clone()),
        || cpu_conv::conv2d(&c32, x32.clone()),
    );
    row(
        "conv 3x3 16→32, 350x518",
        || c16.forward(x16.clone()),
        || cpu_conv::conv2d(&c16, x16.clone()),
    );
    row(
        "conv 7x7 3→32 (input merger), 350x518",
        || merger.forward(img.clone()),
        || cpu_conv::conv2d(&merger, img.clone()),
    );
    let h32 = rand([1, 32, 200, 296]);
    row(
        "bilinear 200x296 → 350x518, 32 channels",
        || {
            interpolate(
                h32.clone(),
                InterpolateOptions::new(InterpolateMode::Bilinear)
                    .with_align_corners(true)
                    .with_output_size([350, 518]),
            )
        },
        || bilinear_align_corners(h32.clone(), 350, 518),
    );
    // A global block: 2 frames x 930 tokens, 4 heads of 16.
    let (q, k, v) = (
        rand([1, 4, 1860, 16]),
        rand([1, 4, 1860, 16]),
        rand([1, 4, 1860, 16]),
    );
    row(
        "attention, 4 heads x 1860 tokens x 16",
        || {
            attention(
                q.clone(),
                k.clone(),
                v.clone(),
                None,
                None,
                AttentionModuleOptions::default(),
            )
        },
        || cpu_attention::attention(q.clone(), k.clone(), v.clone()),
    );
    let mlp = rand([1, 2, 930, 256]);
    row(
        "GELU, 2 x 930 x 256",
        || activation::gelu(mlp.clone()),
        || cpu_gelu::gelu(mlp.clone()),
    );
}
